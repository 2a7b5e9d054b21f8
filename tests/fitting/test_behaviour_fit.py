"""fit_behaviour: recovery from the model's own tracks; generated pedestrians that cross.

Recovery checks are k-sigma checks with k = 4 on asymptotically normal maximum-likelihood
estimates: the false-failure rate of each is about 6e-5 for a random seed (the seeds are
fixed, so the outcome is deterministic).
"""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import (
    BehaviourFit,
    grid_geodesic,
    sample_soft_paths,
    simulate_behaviour_tracks,
    soft_policy,
)
from are_stats.fitting import discretise_tracks, fit_behaviour
from tests.helpers import assert_allclose

K_SIGMA = 4.0


def _model_tracks(seed: int, beta: float, slip: float, dt: float, n: int = 130):
    """Tracks of the soft policy itself on a 30 x 30 grid with 6 exits (cell 1 m)."""
    rng = np.random.default_rng(seed)
    occ = np.zeros((30, 30), bool)
    occ[10, 5:20] = True
    occ[18:25, 22] = True
    exits = np.array([[0, 5], [0, 20], [29, 10], [29, 25], [15, 0], [12, 29]])
    free = np.argwhere(~occ)
    starts = free[rng.choice(len(free), n)]
    gi = rng.integers(0, len(exits), n)
    far = grid_geodesic(~occ, exits)[gi, starts[:, 0], starts[:, 1]] >= 6
    starts, gi = starts[far], gi[far]
    sol = soft_policy(occ, exits, beta, slip, n_epochs=2000, time_cost=1.0, tol=1e-7)
    heads = rng.integers(0, 4, len(starts))
    st, _ = sample_soft_paths(
        rng, np.asarray(sol.policy), occ, slip, np.column_stack([starts, heads]), gi, exits,
        np.full(len(starts), 400),
    )  # fmt: skip
    rows = []
    for i in range(len(starts)):
        at = np.flatnonzero((st[i, :, :2] == exits[gi[i]]).all(axis=1))
        c = st[i, : at[0] + 1, :2]
        t = np.arange(len(c)) * dt
        rows.append(pd.DataFrame({"id": i, "t": t, "x": c[:, 1] + 0.5, "y": c[:, 0] + 0.5}))
    return pd.concat(rows, ignore_index=True), ~occ


def test_recovers_beta_slip_and_speed_from_model_tracks() -> None:
    beta, slip, dt = 2.0, 0.1, 0.8
    tracks, free = _model_tracks(0, beta, slip, dt)
    fit = fit_behaviour(tracks, free, 1.0, (0.0, 0.0), cell=1.0, dt=dt, max_fit_tracks=None)
    assert fit.n_tracks[0] >= 100
    assert abs(fit.beta[0] - beta) < K_SIGMA * fit.beta_se[0]
    assert abs(fit.slip[0] - slip) < K_SIGMA * fit.slip_se[0]
    assert fit.beta_se[0] < 0.25 and fit.slip_se[0] < 0.025
    # every step moves one cell (1 m) per 0.8 s or none: the median step speed is 1.25 m/s
    assert abs(np.exp(np.median(fit.speed_mu)) - 1.25) < 0.15


def test_discretise_fills_gaps_and_cuts_at_the_goal() -> None:
    free = np.ones((10, 10), bool)
    t = np.array([0.0, 1.0, 2.0, 3.0])
    tr = pd.DataFrame({"id": 0, "t": t, "x": [0.5, 2.5, 4.5, 4.5], "y": [0.5, 1.5, 3.5, 3.5]})
    (path,), ids = discretise_tracks(tr, free, 1.0, (0.0, 0.0), 1.0)
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    assert set(steps.tolist()) <= {1}  # one 4-adjacent move per step; the repeat is cut
    assert_allclose(path[[0, -1]], [[0, 0], [3, 4]])
    assert ids.tolist() == [0]


def _crossing_world(seed: int, n: int = 60):
    """A 20 m x 12 m room (0.5 m map cells) with a door in the west and the east wall;
    people walk straight from door to door at about 1.2 m/s, sampled at 2.5 Hz."""
    rng = np.random.default_rng(seed)
    free = np.zeros((24, 40), bool)
    free[1:-1, 1:-1] = True
    free[9:15, 0] = True  # west door, y in [4.5, 7.5]
    free[9:15, -1] = True  # east door
    rows = []
    for i in range(n):
        y0, y1 = rng.uniform(4.7, 7.3, 2)
        a, b = np.array([0.3, y0]), np.array([19.7, y1])
        if i % 2:
            a, b = b, a
        v = 1.2 * np.exp(0.05 * rng.standard_normal())
        dist = np.hypot(*(b - a))
        t = np.arange(0.0, dist / v, 0.4)
        t = np.append(t, dist / v)
        xy = a + np.outer(t / t[-1], b - a) + rng.normal(0, 0.03, (t.size, 2))
        rows.append(pd.DataFrame({"id": i, "t": 100.0 * i + t, "x": xy[:, 0], "y": xy[:, 1]}))
    return pd.concat(rows, ignore_index=True), free


@pytest.fixture(scope="module")
def crossing() -> tuple[pd.DataFrame, BehaviourFit]:
    tracks, free = _crossing_world(3, n=40)
    tracks["label"] = "person"
    return tracks, fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=20)


def test_generated_pedestrians_cross_at_the_fitted_speed(crossing) -> None:
    tracks, fit = crossing
    v_fit = float(np.exp(fit.speed_mu[0]))
    assert abs(v_fit - 1.2) < 0.1
    firsts = tracks.groupby("id").first()
    n = 30
    arts = pd.DataFrame(
        {
            "scenario": 0,
            "id": np.arange(n),
            "t_arrive": np.arange(n) * 5.0,
            "t_leave": np.arange(n) * 5.0 + 30.0,
            "x": firsts["x"].to_numpy()[:n],
            "y": firsts["y"].to_numpy()[:n],
            "yaw": 0.0,
        }
    )
    out = simulate_behaviour_tracks(jax.random.key(0), fit, arts, dt_out=0.4)
    assert list(out.columns) == ["scenario", "id", "t", "x", "y", "yaw"]
    speeds, straight, reached = [], [], []
    for i, g in out.groupby("id"):
        xy = g[["x", "y"]].to_numpy()
        step = np.hypot(*np.diff(xy, axis=0).T)
        moving = np.flatnonzero(step > 1e-9)
        assert moving.size, f"artefact {i} stood still"
        seg = xy[moving[0] : moving[-1] + 2]
        speeds.append(np.median(step[moving]) / 0.4)
        length = np.hypot(*np.diff(seg, axis=0).T).sum()
        straight.append(np.hypot(*(seg[-1] - seg[0])) / length)
        start_x = xy[0, 0]
        reached.append(abs(xy[-1, 0] - (19.7 if start_x < 10 else 0.3)) < 1.0)
    assert abs(np.median(speeds) / v_fit - 1) < 0.15
    assert np.mean(reached) >= 0.9
    assert np.median(straight) > 0.85


def test_fit_round_trips_through_xarray(crossing) -> None:
    _, fit = crossing
    assert fit.classes == ("person",)
    back = BehaviourFit.from_dataset(fit.to_dataset())
    for name in ("beta", "slip", "dt", "speed_mu", "entry_xy", "exit_xy", "free", "track_class"):
        np.testing.assert_array_equal(getattr(back, name), getattr(fit, name))
    assert back.cell == fit.cell and back.classes == fit.classes


def test_drawn_exits_are_reachable_within_the_stay(crossing) -> None:
    _, fit = crossing
    rng = np.random.default_rng(5)
    entries = fit.world_to_cell(fit.entry_xy[:20])
    reach = np.r_[np.full(10, 6.0), np.full(10, 200.0)]
    exits = fit.draw_exits(rng, np.zeros(20, int), entries, reach)
    dist = fit.geodesic(entries)[np.arange(20), exits[:, 0], exits[:, 1]]
    assert (exits[:, 0] >= 0).all()
    assert (dist <= reach).all() and (dist >= 1).all()
    # with the whole stay, exits are at the other door (the tracks cross the room)
    far = np.abs(fit.cell_to_world(exits[10:])[:, 0] - fit.entry_xy[10:20, 0]) > 15.0
    assert far.mean() >= 0.9


def test_likelihood_with_goals_split_across_devices_equals_one_device() -> None:
    """The fit's likelihood and forward-mode gradient with three goals (padded to four) on
    two XLA host devices are those of one device."""
    from are_stats.fitting._behaviour import _likelihood

    if jax.local_device_count() < 2:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    free = np.ones((10, 12), bool)
    free[4, 3:9] = False
    paths = [  # cell paths (one move or none per epoch) to three goals
        np.array([[0, 0], [0, 1], [0, 1], [0, 2], [1, 2], [1, 3], [1, 4], [0, 4], [0, 5]]),
        np.array([[9, 11], [8, 11], [7, 11], [7, 10], [6, 10], [5, 10], [5, 9], [5, 8]]),
        np.array([[9, 0], [8, 0], [8, 1], [7, 1], [6, 1], [5, 1], [5, 2], [5, 3], [5, 4]]),
        np.array([[2, 8], [2, 7], [1, 7], [1, 6], [1, 5], [0, 5]]),
    ]
    out = []
    for n_devices in (1, 2):
        f, obs, _ = _likelihood(
            paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, dtype=np.float64,
            tol=1e-3, n_devices=n_devices,
        )  # fmt: skip
        assert len(obs.goals) == 3
        th = np.array([np.log(1.7), -2.0])
        out.append(jax.jit(jax.jacfwd(lambda t, f=f: (f(t), f(t)), has_aux=True))(th))
    (g1, v1), (g2, v2) = out
    assert np.isfinite(float(v1)) and np.abs(np.asarray(g1)).min() > 1e-3
    assert_allclose(v2, v1, rtol=1e-12)
    assert_allclose(g2, g1, rtol=1e-10)
