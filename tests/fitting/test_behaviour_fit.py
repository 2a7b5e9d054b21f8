"""fit_behaviour: recovery from the model's own tracks; generated pedestrians that cross.

Recovery checks are k-sigma checks with k = 4 on asymptotically normal maximum-likelihood
estimates: the false-failure rate of each is about 6e-5 for a random seed (the seeds are
fixed, so the outcome is deterministic).
"""

from __future__ import annotations

import functools

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
    wall_distance_feature,
)
from are_stats.fitting import behaviour_log_likelihood, discretise_tracks, fit_behaviour
from tests.helpers import assert_allclose, crossing_world

K_SIGMA = 4.0


def _model_tracks(
    seed: int, beta: float, slip: float, dt: float, n: int = 130, wall_weight: float = 0.0
):
    """Tracks of the soft policy itself on a 30 x 30 grid with 6 exits (cell 1 m), with a
    cell reward ``wall_weight`` times the closeness to walls (the fit's ``"walls"``)."""
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
    sol = soft_policy(
        occ, exits, beta, slip, n_epochs=2000, time_cost=1.0, tol=1e-7,
        cell_reward=wall_weight * wall_distance_feature(occ, 1.0),
    )  # fmt: skip
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


@pytest.fixture(scope="module")
def crossing() -> tuple[pd.DataFrame, BehaviourFit]:
    """The crossing room's walkers and their behaviour fitted on 10 of them: the padded
    shapes (8 goals, 16 tracks, 64 steps) of the held-out fits of the same walkers in
    test_motion_checks, test_prediction and scenarios/test_realism, so that the suite
    compiles the fit's programs once for all four files."""
    tracks, free = crossing_world(3, n=40)
    tracks["label"] = "person"
    return tracks, fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)


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


def _three_door_world(seed: int, n: int = 60):
    """The crossing room with a third door in the north wall: paths of 6-20 m, so a
    pedestrian's stay says which exit it took (people leave when they reach it)."""
    rng = np.random.default_rng(seed)
    free = np.zeros((24, 40), bool)
    free[1:-1, 1:-1] = True
    free[9:15, 0] = free[9:15, -1] = True  # west and east doors, y in [4.5, 7.5]
    free[-1, 4:10] = True  # north door, x in [2, 5]
    doors = (
        lambda: np.array([0.3, rng.uniform(4.7, 7.3)]),
        lambda: np.array([19.7, rng.uniform(4.7, 7.3)]),
        lambda: np.array([rng.uniform(2.2, 4.8), 11.7]),
    )
    rows = []
    for i in range(n):
        a, b = rng.choice(3, 2, replace=False)
        a, b = doors[a](), doors[b]()
        v = 1.2 * np.exp(0.1 * rng.standard_normal())
        dist = np.hypot(*(b - a))
        t = np.append(np.arange(0.0, dist / v, 0.4), dist / v)
        xy = a + np.outer(t / t[-1], b - a) + rng.normal(0, 0.03, (t.size, 2))
        rows.append(pd.DataFrame({"id": i, "t": 100.0 * i + t, "x": xy[:, 0], "y": xy[:, 1]}))
    return pd.concat(rows, ignore_index=True), free


def test_exits_drawn_given_the_stay_keep_the_walking_speed() -> None:
    """Entries and stays of the log walked again: an exit drawn from the entry alone made
    people arrive early (median speed 0.7 of the observed 1.2 m/s, exit at 0.8 of the stay);
    drawn given the stay too, speed and time to exit match the log. Nobody stands: a stay
    too short for every exit the density draws (person 34: 5.6 m to the north door in
    4.4 s, 13 moves of the grid path against a reach of 10) walks as far towards the
    likeliest as its reach allows (:meth:`BehaviourFit.draw_exits`); it used to take the
    reachable cell nearest to the last draw, which could be beside its entry (it stood
    there once the exits at the map's edge were no longer redrawn, which changed the draws
    that followed)."""
    from are_stats.fitting import track_statistics

    tracks, free = _three_door_world(1)
    # 10 fitted tracks: the crossing fixture's padded shapes (its programs, compiled once)
    fit = fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    g = tracks.groupby("id", sort=True)
    first, last = g.first(), g.last()
    arts = pd.DataFrame({
        "scenario": 0, "id": first.index, "t_arrive": first["t"].to_numpy(),
        "t_leave": last["t"].to_numpy(), "x": first["x"].to_numpy(), "y": first["y"].to_numpy(),
    })  # fmt: skip
    # the log is the grid MDP's own cell paths (staircases): replayed like for like with
    # the grid motion (smooth > 1); any-angle paths are shorter than these staircases
    out = simulate_behaviour_tracks(jax.random.key(2), fit, arts, dt_out=0.4, smooth=5)
    obs = track_statistics(tracks)
    gen = track_statistics(out.drop(columns="scenario"))
    assert abs(gen["speed"].median() / obs["speed"].median() - 1) < 0.1
    assert gen["exit_fraction"].median() > 0.93
    assert not gen["still"].any()


def test_generated_walkers_plan_alone_and_give_way_under_the_social_force(crossing) -> None:
    """Many pedestrians entering by the same doors: the fitted generator plans each alone
    (no holds: they pass through each other on their plans, issue 26 drops the
    after-the-fact separation); walked under the social force, as every command walks
    them, no two come within a body diameter less 0.2 m, and they still cross."""
    from are_stats.behaviour import social_force_tracks

    _, fit = crossing
    n = 40
    rng = np.random.default_rng(8)
    west = rng.uniform(5.0, 7.0, n)
    arts = pd.DataFrame({
        "scenario": 0, "id": np.arange(n), "t_arrive": np.arange(n) * 1.5,
        "t_leave": np.arange(n) * 1.5 + 25.0, "x": np.where(np.arange(n) % 2, 19.7, 0.3),
        "y": west, "yaw": 0.0,
    })  # fmt: skip
    plan = simulate_behaviour_tracks(jax.random.key(1), fit, arts, dt_out=0.2)
    assert "holds" not in plan.attrs
    walked = social_force_tracks(plan, None, None)

    def closest(tr):
        wide = tr.pivot_table(index="t", columns="id", values=["x", "y"])
        x, y = wide["x"].to_numpy(), wide["y"].to_numpy()
        d = np.hypot(x[:, :, None] - x[:, None, :], y[:, :, None] - y[:, None, :])
        d[:, np.arange(n), np.arange(n)] = np.inf
        return np.nanmin(d)

    assert closest(plan) < 0.3  # planned alone, they do pass through each other
    assert closest(walked) >= 0.5 - 0.2
    ends = walked.groupby("id").last()
    crossed = np.abs(ends["x"] - np.where(ends.index % 2, 0.3, 19.7)) < 2.0
    assert crossed.mean() >= 0.7


def test_path_points_against_a_point_by_point_reference() -> None:
    """path_points (the vectorised timed paths of the generators) against a point-by-point
    reference: the interpolated point plus the side-step along the left normal of the
    segment walked then (in a pause, of the last segment walked before it)."""
    from are_stats.behaviour import path_points

    def reference(tv, pv, t, sd):
        t = min(max(t, tv[0]), tv[-1])
        k = min(max(int(np.searchsorted(tv, t, side="right")) - 1, 0), len(tv) - 2)
        frac = (t - tv[k]) / (tv[k + 1] - tv[k])
        base = pv[k] + frac * (pv[k + 1] - pv[k])
        j = k
        while j > 0 and not (pv[j + 1] - pv[j]).any():
            j -= 1
        if not (pv[j + 1] - pv[j]).any():  # a pause at the start: the first segment walked
            j = next(m for m in range(len(pv) - 1) if (pv[m + 1] - pv[m]).any())
        d = (pv[j + 1] - pv[j]) / np.hypot(*(pv[j + 1] - pv[j]))
        return base + sd * np.array([-d[1], d[0]])

    rng = np.random.default_rng(3)
    for m in (2, 5, 9):
        tv = np.cumsum(np.r_[0.0, rng.choice([0.25, 0.5, 1.0], m - 1)])
        pv = rng.uniform(0, 5, (m, 2))
        if m > 3:
            pv[2] = pv[1]  # a pause
            pv[1] = pv[0]  # and one at the start
        tau = rng.uniform(-1.0, tv[-1] + 1.0, 50)
        side = rng.uniform(-1, 1, 50)
        want = np.array([reference(tv, pv, t, sd) for t, sd in zip(tau, side, strict=True)])
        assert_allclose(path_points(tv, pv, tau, side), want, atol=1e-12)
    one = path_points(np.zeros(1), np.array([[2.0, 3.0]]), [0.0, 4.0], [1.0, -1.0])
    assert_allclose(one, [[2.0, 3.0], [2.0, 3.0]])  # a path that never moves: no normal


# make test: test_likelihood_with_features_split_across_devices_equals_one_device keeps the
# claim (the same three goals padded to four on one and two devices, with two reward
# features: programs the padded test compiles anyway); this one compiles a program of its
# own (no features, one device) that no other test uses
@pytest.mark.slow
def test_likelihood_with_goals_split_across_devices_equals_one_device() -> None:
    """The fit's likelihood and forward-mode gradient with three goals (padded to four) on
    two XLA host devices are those of one device."""
    if jax.local_device_count() < 2:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    free, paths, _ = _small_world()
    th = np.array([np.log(1.7), -2.0])
    out = []
    for n_devices in (1, 2):
        obs, (g, v) = _fit_value_and_gradient(paths, free, th, n_devices)
        assert len(obs.goals) == 3
        out.append((g, v))
    (g1, v1), (g2, v2) = out
    assert np.isfinite(float(v1)) and np.abs(np.asarray(g1)).min() > 1e-3
    assert_allclose(v2, v1, rtol=1e-12)
    assert_allclose(g2, g1, rtol=1e-10)


#: The soft solve's tolerance as :func:`~are_stats.fitting._behaviour._mle` hands it to the
#: fit's program: a float64 array. A Python float is a weakly typed argument, whose program
#: is another one than the fit's: the round-trip test's fit compiled its own (about 10 s of
#: CPU cold) until 2026-11-28.
TOL = np.asarray(1e-3, np.float64)


def _fit_value_and_gradient(paths, free, theta, n_devices, features=None):
    """The fit's compiled ``(gradient, value)`` program (float64, ``tol = 1e-3``) on the
    padded data of ``paths``: one program per shape bucket, so the likelihood tests on
    :func:`_small_world` (three goals, four tracks, eight steps: buckets (4, 4, 8)) and the
    float64 fit of :func:`test_feature_weights_round_trip_and_old_files_load_without_them`
    share it. Returns the data's move observations and ``(gradient, value)``."""
    import are_stats.fitting._behaviour as fb

    data, obs, _, n_dev = fb._likelihood_data(
        paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, dtype=np.float64,
        n_devices=n_devices, features=features,
    )  # fmt: skip
    assert n_dev == n_devices
    th = np.asarray(theta, np.float64)
    return obs, fb._gradient_value_epochs(th, data, TOL, n_dev)[:2]


# two devices: the slow tier (its unpadded program, compiled for this case alone: about
# 10 s of CPU cold); make test keeps the claim by two steps, on programs other tests compile
# anyway: the padded likelihood on two devices equals one device's
# (test_likelihood_with_features_split_across_devices_equals_one_device, rtol 1e-12), and
# one device's padded equals its unpadded (the case [1] here)
@pytest.mark.parametrize("n_devices", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_padded_likelihood_equals_the_unpadded_one(monkeypatch, n_devices: int) -> None:
    """The fit's likelihood pads goals, tracks and steps to shape buckets (issue 29: one
    compiled program for the fit and the held-out fit); its value and gradient are those
    of the unpadded data. Float64; the padding steps are factors of exactly 1, the padding
    goals copies of the last one."""
    import are_stats.fitting._behaviour as fb

    if jax.local_device_count() < n_devices:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    free, paths, phi = _small_world()
    paths = [paths[1], paths[2][:6], paths[3]]  # 3 goals, 3 tracks, at most 7 steps
    opts = dict(
        goal_reward=1.0, step_cost=1e-3, time_cost=1.0, dtype=np.float64,
        n_devices=n_devices, features=phi,
    )  # fmt: skip
    th = np.array([np.log(1.7), -2.0, -0.4, 0.3])
    out = []
    for pad in (True, False):
        if not pad:  # every bucket the exact size (a multiple of the devices for the goals)
            monkeypatch.setattr(fb, "_bucket", _bucket_exact)
        data, obs, _, n_dev = fb._likelihood_data(paths, free, **opts)
        shapes = (data.keep.shape[0], *data.move.shape)
        assert shapes == ((4, 4, 8) if pad else (_bucket_exact(3, n_dev), 3, 7))
        out.append(fb._gradient_value_epochs(th, data, TOL, n_dev)[:2])
    (g_pad, v_pad), (g, v) = out
    assert np.isfinite(float(v)) and np.abs(np.asarray(g)).min() > 1e-3
    assert_allclose(v_pad, v, rtol=1e-13)
    assert_allclose(g_pad, g, rtol=1e-11)


def _bucket_exact(n: int, multiple: int = 1) -> int:
    """No padding: the smallest multiple of ``multiple`` that holds ``n``."""
    return -(-n // multiple) * multiple


# ---------------------------------------------------------------------- reward features
# -0.5: the slow tier (a third fit of the model's tracks on the 30 x 30 grid, about 10 s of
# CPU of solves with the program compiled); make test recovers the weight of +0.5 (case
# [0.5], the same program and checks) and walks a negative one
# (test_generated_walkers_keep_off_walls_with_a_negative_wall_weight)
@pytest.mark.parametrize("wall_weight", [0.5, pytest.param(-0.5, marks=pytest.mark.slow)])
def test_recovers_a_wall_weight_of_either_sign_from_model_tracks(wall_weight: float) -> None:
    """+0.5: walkers hug walls, -0.5: they avoid them (reward per epoch, time cost 1). Each of
    the k-sigma checks fails with probability about 6e-5 at a random seed; at these fixed
    seeds |w - w_true| / se was 1.3 (+0.5) and 0.4 (-0.5) when written."""
    beta, slip, dt = 2.0, 0.1, 0.8
    tracks, free = _model_tracks(1, beta, slip, dt, wall_weight=wall_weight)
    fit = fit_behaviour(
        tracks, free, 1.0, (0.0, 0.0), cell=1.0, dt=dt, max_fit_tracks=None, features=("walls",)
    )
    assert fit.feature_names == ("walls",) and fit.weights.shape == (1, 1)
    assert_allclose(fit.features[0], wall_distance_feature(~free, 1.0))
    w, se = fit.weights[0, 0], fit.weights_se[0, 0]
    assert 0 < se < 0.1
    assert abs(w - wall_weight) < K_SIGMA * se
    assert abs(fit.beta[0] - beta) < K_SIGMA * fit.beta_se[0]
    assert abs(fit.slip[0] - slip) < K_SIGMA * fit.slip_se[0]
    assert not fit.warnings


def _small_world():
    """A 10 x 12 grid with a wall, four cell paths (one move or none per epoch) to three
    goals, and two reward features (closeness to walls, and noise)."""
    free = np.ones((10, 12), bool)
    free[4, 3:9] = False
    paths = [  # cell paths (one move or none per epoch) to three goals
        np.array([[0, 0], [0, 1], [0, 1], [0, 2], [1, 2], [1, 3], [1, 4], [0, 4], [0, 5]]),
        np.array([[9, 11], [8, 11], [7, 11], [7, 10], [6, 10], [5, 10], [5, 9], [5, 8]]),
        np.array([[9, 0], [8, 0], [8, 1], [7, 1], [6, 1], [5, 1], [5, 2], [5, 3], [5, 4]]),
        np.array([[2, 8], [2, 7], [1, 7], [1, 6], [1, 5], [0, 5]]),
    ]
    rng = np.random.default_rng(3)
    phi = np.stack([wall_distance_feature(~free, 1.0), rng.uniform(0, 1, free.shape)])
    return free, paths, phi


@jax.jit
@functools.partial(jax.value_and_grad, argnums=1)
def _weighted_log_likelihood(beta, weights):
    """behaviour_log_likelihood of :func:`_small_world`'s paths (60 epochs, slip 0.1) with
    its two features weighted by ``weights``, and its gradient in the weights: one program
    for the tests below (until 2026-11-29 the value and the gradient were two)."""
    free, paths, phi = _small_world()
    return behaviour_log_likelihood(paths, free, beta, 0.1, n_epochs=60, features=phi,
                                    weights=weights)[0]  # fmt: skip


def test_log_likelihood_gradient_in_the_weights_matches_finite_differences() -> None:
    w0 = np.array([-0.4, 0.3])
    beta = np.float64(1.5)
    grad = np.asarray(_weighted_log_likelihood(beta, w0)[1])
    h = 1e-5
    fd = [
        (float(_weighted_log_likelihood(beta, w0 + h * e)[0])
         - float(_weighted_log_likelihood(beta, w0 - h * e)[0])) / (2 * h)
        for e in np.eye(2)
    ]  # fmt: skip
    assert np.abs(grad).min() > 1e-2  # the weights do move the likelihood
    assert_allclose(grad, fd, rtol=1e-6, atol=1e-8)


def test_zero_weights_give_exactly_the_likelihood_without_features() -> None:
    free, paths, phi = _small_world()
    beta = np.float64(1.5)

    @jax.jit
    def plain(b):
        return behaviour_log_likelihood(paths, free, b, 0.1, n_epochs=60)[0]

    np.testing.assert_array_equal(_weighted_log_likelihood(beta, np.zeros(2))[0], plain(beta))
    assert float(_weighted_log_likelihood(beta, np.array([-0.5, 0.0]))[0]) != float(plain(beta))
    # the fit's own likelihood (early stop, goals split over the devices there are)
    n_dev = min(jax.local_device_count(), 2)
    th = np.array([np.log(1.7), -2.0])
    v0 = _fit_value_and_gradient(paths, free, th, n_dev)[1][1]
    v2 = _fit_value_and_gradient(paths, free, np.r_[th, 0.0, 0.0], n_dev, phi)[1][1]
    np.testing.assert_array_equal(v2, v0)
    v2w = _fit_value_and_gradient(paths, free, np.r_[th, -0.5, 0.0], n_dev, phi)[1][1]
    assert float(v2w) != float(v0)


def test_likelihood_with_features_split_across_devices_equals_one_device() -> None:
    """As with three goals above, with two reward features: the program of the padded test
    (the same shape buckets)."""
    if jax.local_device_count() < 2:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    free, paths, phi = _small_world()
    th = np.array([np.log(1.7), -2.0, -0.4, 0.3])
    out = [_fit_value_and_gradient(paths, free, th, n, phi)[1] for n in (1, 2)]
    (g1, v1), (g2, v2) = out
    assert_allclose(v2, v1, rtol=1e-12)
    assert_allclose(g2, g1, rtol=1e-10)


def test_features_on_the_map_are_averaged_over_mdp_cells_and_bad_ones_named() -> None:
    from are_stats.fitting._behaviour import _feature_maps

    free_fine = np.ones((8, 12), bool)
    free = free_fine.reshape(4, 2, 6, 2).all(axis=(1, 3))
    ramp = np.tile(np.arange(12.0), (8, 1))
    names, maps = _feature_maps({"east": ramp, "walls": "walls"}, free, free_fine, 2)
    assert names == ("east", "walls")
    assert_allclose(maps[0], np.tile(np.arange(0.5, 12, 2.0), (4, 1)))
    assert_allclose(maps[1], wall_distance_feature(~free, 1.0))
    assert _feature_maps(None, free, free_fine, 2) == ((), None)
    with pytest.raises(ValueError, match=r"features\['doors'\]: expected one of \['walls'\]"):
        _feature_maps(("doors",), free, free_fine, 2)
    with pytest.raises(ValueError, match=r"features\['x'\]: expected an array on the MDP grid"):
        _feature_maps({"x": np.ones((5, 5))}, free, free_fine, 2)


def test_feature_weights_round_trip_and_old_files_load_without_them(tmp_path) -> None:
    import dataclasses

    import arviz as az

    from are_stats.fitting import attach_behaviour

    free, paths, phi = _small_world()
    tracks = pd.concat(
        [pd.DataFrame({"id": i, "t": 0.8 * np.arange(len(p)), "x": p[:, 1] + 0.5,
                       "y": p[:, 0] + 0.5}) for i, p in enumerate(paths)],
        ignore_index=True,
    )  # fmt: skip
    # float64: the fit's value-and-gradient program is then the padded test's (the same
    # shape buckets and two features, the goals split over the devices there are),
    # compiled once: the fit compiles none of its own
    import are_stats.fitting._behaviour as fb

    th = np.array([np.log(1.7), -2.0, -0.4, 0.3])
    _fit_value_and_gradient(paths, free, th, jax.local_device_count(), phi)
    programs = fb._gradient_value_epochs._cache_size()
    fit = fit_behaviour(
        tracks, free, 1.0, (0.0, 0.0), cell=1.0, dt=0.8, features={"walls": "walls", "r": phi[1]},
        dtype="float64",
    )  # fmt: skip
    assert fb._gradient_value_epochs._cache_size() == programs
    assert fit.weights.shape == fit.weights_se.shape == (1, 2)
    assert np.isfinite(fit.weights).all()
    path = tmp_path / "b.nc"
    attach_behaviour(az.InferenceData(), fit).to_netcdf(path)
    back = BehaviourFit.from_dataset(az.from_netcdf(path).behaviour)
    assert back.feature_names == ("walls", "r")
    for name in ("weights", "weights_se", "features", "beta", "slip"):
        np.testing.assert_array_equal(getattr(back, name), getattr(fit, name))
    w = fit.weights[0]
    assert_allclose(back.cell_reward(0), w[0] * phi[0] + w[1] * np.where(free, phi[1], 0.0))
    # a fit without features writes no feature variables, and such files load with F = 0
    plain = dataclasses.replace(fit, feature_names=(), features=None, weights=None,
                                weights_se=None)  # fmt: skip
    ds = plain.to_dataset()
    assert not {"feature_weight", "feature_weight_se", "feature_map"} & set(ds.variables)
    old = BehaviourFit.from_dataset(ds)
    assert old.feature_names == () and old.weights.shape == (1, 0)
    assert old.features.shape == (0, *free.shape) and old.cell_reward(0) == 0.0


def test_generated_walkers_keep_off_walls_with_a_negative_wall_weight(crossing) -> None:
    """The same entries, stays and key with the crossing fit's wall weight set to -2 and to
    0: walkers entering near the north and south walls move away from them sooner."""
    import dataclasses

    from scipy import ndimage

    _, fit = crossing
    phi = wall_distance_feature(~fit.free, 1.0)[None]
    n = 24
    rng = np.random.default_rng(4)
    arts = pd.DataFrame({
        "scenario": 0, "id": np.arange(n), "t_arrive": np.arange(n) * 40.0,
        "t_leave": np.arange(n) * 40.0 + 30.0, "x": rng.uniform(4.0, 16.0, n),
        "y": np.where(np.arange(n) % 2, 1.0, 11.0), "yaw": 0.0,
    })  # fmt: skip
    dist = ndimage.distance_transform_edt(np.pad(fit.free, 1))[1:-1, 1:-1] * fit.cell
    mean_dist = {}
    for w in (0.0, -2.0):
        f = dataclasses.replace(
            fit, feature_names=("walls",), features=phi, weights=np.full((1, 1), w),
            weights_se=np.zeros((1, 1)),
        )  # fmt: skip
        out = simulate_behaviour_tracks(jax.random.key(2), f, arts, dt_out=0.4)
        cells = f.world_to_cell(out[["x", "y"]].to_numpy())
        mean_dist[w] = float(dist[cells[:, 0], cells[:, 1]].mean())
    assert mean_dist[-2.0] > mean_dist[0.0] + 0.5, mean_dist


@pytest.mark.slow  # two soft-policy fits (about 60 s on a busy 2-core machine)
def test_progress_counts_the_classes_fitted() -> None:
    """``progress(done, total)`` after each class (two here), not before: the class is the
    fit's one loop with a count known in advance."""
    tracks, free = _model_tracks(1, 2.0, 0.1, 0.8, n=24)
    tracks["label"] = np.where(tracks["id"] % 2 == 0, "person", "child")
    said = []
    fit = fit_behaviour(
        tracks, free, 1.0, (0.0, 0.0), cell=1.0, dt=0.8, max_fit_tracks=3,
        progress=lambda done, total: said.append((done, total)),
    )  # fmt: skip
    assert fit.classes == ("child", "person")
    assert said == [(1, 2), (2, 2)]
