"""fit_behaviour on a log in which a class only stands (pallets parked among walkers).

The walking class is fitted, the standing one is recorded as standing (``BehaviourFit.standing``)
and stands in generated scenes; only a log in which nobody walks has no behaviour. The checks
are deterministic (fixed seeds); the walking check (median displacement of 30 generated
walkers over 30 s above 5 m, against 1.2 m/s fitted) has a false-failure rate far below 1e-6
for a random seed.
"""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import BehaviourFit, simulate_behaviour_tracks
from are_stats.fitting import NoWalkersError, fit_behaviour
from tests.helpers import crossing_world


def _pallets(seed: int, n: int, t_end: float, noise: float = 0.03) -> pd.DataFrame:
    """``n`` pallets standing in the crossing room for ``[0, t_end]`` s, seen at 2.5 Hz
    through the crossing's tracker noise (``noise`` m)."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        t = np.arange(0.0, t_end, 0.4)
        at = rng.uniform([3.0, 2.0], [17.0, 10.0])
        xy = at + noise * rng.standard_normal((t.size, 2))
        rows.append(pd.DataFrame({"id": 1000 + i, "t": t, "x": xy[:, 0], "y": xy[:, 1]}))
    return pd.concat(rows, ignore_index=True).assign(label="pallet")


@pytest.fixture(scope="module")
def site() -> tuple[pd.DataFrame, BehaviourFit]:
    """40 people crossing the room and 4 pallets standing in it: the behaviour fitted on 10
    of the people (the shapes of test_behaviour_fit's crossing fixture)."""
    people, free = crossing_world(3, n=40)
    tracks = pd.concat([people.assign(label="person"), _pallets(1, 4, 60.0)], ignore_index=True)
    return tracks, fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)


def test_the_walkers_are_fitted_and_the_standing_class_recorded(site) -> None:
    tracks, fit = site
    assert fit.classes == ("person",) and fit.standing == ("pallet",)
    assert abs(float(np.exp(fit.speed_mu[0])) - 1.2) < 0.1  # the people's 1.2 m/s
    assert fit.n_tracks.tolist() == [40] and np.isfinite(fit.beta).all()
    # the exits are the people's: every observed track of the fit is a walking one
    assert (fit.track_class == 0).all() and len(fit.entry_xy) == 40
    # the file keeps it; a fit without standing classes writes the file as before
    back = BehaviourFit.from_dataset(fit.to_dataset())
    assert back.standing == ("pallet",) and back.classes == ("person",)
    ds = fit.to_dataset()
    del ds.attrs["standing"]  # a file written before the attribute: nothing stands
    assert BehaviourFit.from_dataset(ds).standing == ()
    assert "standing" not in BehaviourFit.from_dataset(ds).to_dataset().attrs


def test_generated_pallets_stand_and_people_walk(site) -> None:
    tracks, fit = site
    firsts = tracks.groupby("id").first()
    people = firsts[firsts["label"] == "person"].iloc[:30]
    pallets = firsts[firsts["label"] == "pallet"]
    both = pd.concat([people, pallets])
    n = len(both)
    arts = pd.DataFrame(
        {
            "scenario": 0,
            "id": np.arange(n),
            "t_arrive": 0.0,
            "t_leave": 30.0,
            "x": both["x"].to_numpy(),
            "y": both["y"].to_numpy(),
            "yaw": 0.0,
            "label": both["label"].to_numpy(),
        }
    )
    out = simulate_behaviour_tracks(jax.random.key(0), fit, arts, dt_out=0.4)
    start = out.groupby("id")[["x", "y"]].first().to_numpy()
    far = np.hypot(*(out[["x", "y"]].to_numpy() - start[out["id"].to_numpy()]).T)
    moved = pd.Series(far).groupby(out["id"].to_numpy()).max().to_numpy()
    is_pallet = arts["label"].to_numpy() == "pallet"
    assert moved[is_pallet].max() < 0.1  # the pallets stand
    assert np.median(moved[~is_pallet]) > 5.0  # the people walk (30 s at about 1.2 m/s)


def test_a_log_in_which_nobody_walks_has_no_behaviour() -> None:
    _, free = crossing_world(3, n=2)
    tracks = pd.concat(
        [_pallets(1, 3, 60.0), _pallets(2, 3, 60.0).assign(id=lambda d: d["id"] + 10)]
    )
    tracks.loc[tracks["id"] >= 1010, "label"] = "crate"
    with pytest.raises(NoWalkersError, match=r"one of the classes 'crate', 'pallet'"):
        fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    with pytest.raises(NoWalkersError, match=r"in class 'pallet', got none"):  # as before
        fit_behaviour(tracks[tracks["label"] == "pallet"], free, 0.5, (0.0, 0.0))


def test_a_class_that_creeps_within_its_cell_stands() -> None:
    # carts nudged 0.1 m in a minute: a walking speed (no tracker noise) but no track
    # leaves its MDP cell, which used to end the whole fit with a ValueError
    people, free = crossing_world(3, n=12, noise=0.0)
    t = np.arange(0.0, 60.0, 0.4)
    carts = pd.concat(
        pd.DataFrame({"id": 500 + i, "t": t, "x": 5.2 + 4 * i + t / 600, "y": 3.2, "label": "cart"})
        for i in range(3)
    )
    tracks = pd.concat([people.assign(label="person"), carts], ignore_index=True)
    fit = fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    assert fit.classes == ("person",) and fit.standing == ("cart",)
    with pytest.raises(NoWalkersError, match=r"in class 'cart', got none"):
        fit_behaviour(carts, free, 0.5, (0.0, 0.0), max_fit_tracks=10)


def test_standing_and_fitted_classes_are_apart(site) -> None:
    _, fit = site
    with pytest.raises(ValueError, match=r"BehaviourFit.standing: .*\['person'\]"):
        BehaviourFit(**{**fit.__dict__, "standing": ("person",)})
