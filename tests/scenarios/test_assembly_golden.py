"""The moving scenes of the one assembly, held to the bit (issue 25).

The assembly moves its standing scenes through the behaviour as Scene -> Scene steps;
these digests were taken from the table -> table assembly before that change (commit
07438ab, same seeds): the scenes' life-cycle and every track pose must stay identical
for the catalogue behaviour (with the AR-builder's resolution, with and without the
social force), arrival groups, the fitted behaviour, one scenario of a folder moved
alone (the sweep), and ``are-stats generate --behaviours``'s folder.

Retaken when walkers began to arrive walking (at their plan's first velocity, issue 26:
from rest they lagged their plan by the relaxation time, so that a fitted walker timed to
reach its exit with its stay had not reached it) and the fitted behaviour's exits came
within reach as any-angle lengths (the reach had counted 4-connected moves): every digest
with the social force changed; the catalogue's without it did not.

Retaken on 2026-11-28, every digest: they had been taken on an AVX-512 host, whose NumPy
trigonometry and XLA kernels give other last bits than the AVX2 kernels the suite now pins
on every x86-64 host (``tests/conftest.py``: ``PINNED_ISA``; the catalogue's scenes without
the social force differed too on an AVX2 AMD EPYC, with the same code and packages);
nothing else changed.

Retaken on 2026-11-28 when a walker's first step of the social force began to cover only
the time since its arrival (not a whole ``dt``, which put every walker up to ``v0 dt``
ahead of its plan): every digest with the social force changed; the catalogue's without
it ("catalogue, no interaction") did not, as it should.
"""

from __future__ import annotations

import hashlib

import jax
import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from are_stats._lazy import arviz as az
from are_stats.behaviour import BehaviourFit
from are_stats.cli import app
from are_stats.environment import OccupancyGrid
from are_stats.fitting import Fit
from are_stats.scenarios import (
    read_scenes,
    scene_tracks,
    scenes_from_fit,
    scenes_tables,
)
from are_stats.traffic import TrafficLaws

HORIZON = 120.0

#: sha256 of the scenarios and tracks tables (columns, dtypes, values), computed from
#: the assembly before the Scene -> Scene change ("fitted" retaken on 2026-11-28, issue 26:
#: BehaviourFit.draw_exits keeps one of the draws moved into reach by a weighted draw
#: where none is within reach, which moves the generator's later draws; the exits' law
#: in this room is as before, 2,000 draws of it side by side).
WANT = {
    "catalogue": "33ae63a0dfba6ba7ace819751235505cd8e018e509db070560bf9381165c07fc",
    "catalogue, no interaction": "eaa791c8f2e8954c1353051c986e0fa9343a21edcbc99c11737ddf8a722369ed",
    "groups": "1125ccbb3b8d7c44f98bf46fd96408dead29efece5fb6b6f6e2ebb598ff49017",
    "fitted": "75c853340bae7b3bec5c9a7bd418bc7057a7eaef6b2343a4ba34abe8215964ea",
    "folder scenario": "8da74fd97184202fc4bab0a7cd10fb67eb4da2abf160a4be1614eb72ce14cf82",
    "generate": "cc462462b9505b1d665552eaf92871679fea10f80ad69049d9d5beb302aa284d",
}


def _digest(*tables: pd.DataFrame | None) -> str:
    h = hashlib.sha256()
    for df in tables:
        if df is None:
            h.update(b"none")
            continue
        h.update(repr([(c, str(df[c].dtype)) for c in df.columns]).encode())
        h.update(pd.util.hash_pandas_object(df, index=False).to_numpy().tobytes())
    return h.hexdigest()


def _idata() -> object:
    """A small paper-model fit: 2 chains of 3 posterior draws, five classes (eq. 1)."""
    rng = np.random.default_rng(3)
    shape = (2, 3)
    idata = az.from_dict(
        posterior={
            "arrival_rate": rng.uniform(2e-4, 4e-4, shape),
            "leave_rate": rng.uniform(1 / 200, 1 / 100, shape),
            "mix_weights": rng.dirichlet(np.ones(5), size=shape),
            "mix_rates": np.broadcast_to([15.0, 7, 3, 21, 5], (*shape, 5)).copy(),
        },
        dims={"mix_weights": ["component"], "mix_rates": ["component"]},
    )
    idata.posterior.attrs.update({"area": 800.0, "window": [0.0, 3600.0]})
    return idata


def _room_fit() -> tuple[BehaviourFit, OccupancyGrid]:
    """A hand-made behaviour on a 12 x 24 m room (cell 1 m): people cross west to east."""
    occ = np.zeros((12, 24), bool)
    occ[[0, -1], :] = occ[:, [0, -1]] = True
    rows = np.arange(2, 10)
    one = np.ones(1)
    fit = BehaviourFit(
        classes=("person",), cell=1.0, origin=np.zeros(2), free=~occ, dt=one / 1.2,
        speed_mu=np.log(1.2) * one, speed_sigma=0.12 * one, run_fraction=0 * one,
        run_mu=np.nan * one, run_sigma=np.nan * one, beta=4.0 * one, beta_se=0 * one,
        slip=0.1 * one, slip_se=0 * one, loglik=0 * one, n_moves=one.astype(int),
        n_tracks=one.astype(int) * rows.size, n_fit_tracks=one.astype(int),
        n_epochs=200 * one.astype(int), bandwidth_entry=0.3 * one, bandwidth_exit=0.1 * one,
        fit_seconds=0 * one, track_class=np.zeros(rows.size, int),
        entry_xy=np.column_stack([np.full(rows.size, 1.5), rows + 0.5]),
        exit_xy=np.column_stack([np.full(rows.size, 22.5), (11 - rows) + 0.5]),
    )  # fmt: skip
    return fit, OccupancyGrid(np.where(occ, 100, 0).astype(np.int8), 1.0)


def _scenes_digest(scenes) -> str:
    return _digest(*scenes_tables(scenes))


# make test: tests/scenarios/test_assembly.py::test_the_catalogue_scenes_are_the_pinned_ones
# checks both digests on the same scenes (its fixtures walked and unwalked)
@pytest.mark.slow
@pytest.mark.parametrize("interaction", [True, False], ids=["catalogue", "no interaction"])
def test_catalogue_scenes_are_unchanged(grid, catalogue, interaction):
    scenes = scenes_from_fit(
        11, _idata(), grid, catalogue, 2, HORIZON, behaviours=True, interaction=interaction
    )
    assert any(s.has_tracks.any() for s in scenes)
    name = "catalogue" if interaction else "catalogue, no interaction"
    assert _scenes_digest(scenes) == WANT[name]


# make test: tests/scenarios/test_assembly.py::test_arrival_groups_walk_together_in_every_assembly
# checks this digest on the same scene
@pytest.mark.slow
def test_group_scenes_are_unchanged(grid, catalogue):
    draws = {
        "arrival_rate": np.array([3e-4]), "leave_rate": np.array([1 / 60]),
        "event_rate": np.array([1e-4]), "stay_mean": np.array([60.0]),
        "group_size_probs": np.array([[0.0, 0.0, 1.0]]),
        "mix_weights": np.array([[1.0, 0, 0, 0, 0]]),
        "mix_rates": np.array([[15.0, 7, 3, 21, 5]]),
    }  # fmt: skip
    laws = TrafficLaws(arrivals="groups")
    scenes = scenes_from_fit(
        3, Fit.from_draws(draws, laws=laws), grid, catalogue, 1, HORIZON, behaviours=True
    )
    assert scenes[0].has_tracks.any()
    assert _scenes_digest(scenes) == WANT["groups"]


def test_fitted_scenes_are_unchanged(catalogue):
    fit, room = _room_fit()
    draws = {
        "arrival_rate": np.array([0.05]), "leave_rate": np.array([1 / 20]),
        "mix_weights": np.array([[1.0]]), "mix_rates": np.array([[1.0]]),
    }  # fmt: skip
    rates = Fit.from_draws(draws, behaviour=fit, class_labels=["person"])
    scenes = scenes_from_fit(jax.random.key(4), rates, room, catalogue, 2, 60.0,
                             behaviours="fitted")  # fmt: skip
    assert any(s.has_tracks.any() for s in scenes)
    assert _scenes_digest(scenes) == WANT["fitted"]


def test_one_folder_scenario_moved_alone_is_unchanged(grid, catalogue):
    """The sweep moves scenario ``draw`` of a folder without tracks on its own."""
    (standing,) = scenes_from_fit(5, _idata(), grid, catalogue, 2, HORIZON)[1:]
    art = standing.artefacts.reset_index(drop=True)
    tracks = scene_tracks(
        jax.random.key(5), art, grid, catalogue, HORIZON, behaviours="catalogue", n=2
    )
    assert tracks is not None and len(tracks)
    assert _digest(tracks) == WANT["folder scenario"]


def test_generate_folder_is_unchanged(tmp_path):
    from tests.test_cli_jobs import _quick_em_fit, _write_log

    log, _ = _write_log(tmp_path, labels=True)
    fit = tmp_path / "f.nc"
    _quick_em_fit(log, fit, samples=20)
    out = tmp_path / "scen"
    args = ["generate", fit, "--scenarios", "2", "--horizon", "90", "--seed", "2", "--out", out,
            "--map", "courtyard", "--behaviours"]  # fmt: skip
    res = CliRunner().invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    art, _, tracks = read_scenes(out)
    assert tracks is not None and len(tracks)
    assert _digest(art, tracks) == WANT["generate"]
