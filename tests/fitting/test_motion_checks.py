"""Criticism for motion (issue 16): statistics, predictive bands, held-out likelihood, ADE/FDE.

Synthetic tracks only. The band checks are 90% bands on 5 statistics with fixed seeds (so
deterministic); "at most one flag" on tracks of the model itself allows one 10% miss.
"""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.fitting import (
    MOTION_STATISTICS,
    displacement_errors,
    heldout_log_likelihood,
    motion_checks,
    plot_motion_checks,
    track_statistics,
    tracker_noise,
)
from tests.helpers import assert_allclose, crossing_world


def _straight(n: int = 6, rate: float = 2.5, seconds: float = 12.0) -> pd.DataFrame:
    """Straight tracks at constant speeds ``0.8 .. 1.6`` m/s in various directions."""
    rows = []
    t = np.arange(0.0, seconds + 1e-9, 1.0 / rate)
    for i in range(n):
        v = 0.8 + 0.8 * i / max(n - 1, 1)
        a = 0.7 * i
        x = 3.0 + v * t * np.cos(a)
        y = -2.0 + v * t * np.sin(a)
        rows.append(pd.DataFrame({"id": i, "t": 50.0 * i + t, "x": x, "y": y}))
    return pd.concat(rows, ignore_index=True)


def test_statistics_of_straight_constant_speed_tracks_are_exact() -> None:
    tracks = _straight()
    standing = pd.DataFrame({"id": 99, "t": [0.0, 1.0, 2.0], "x": 1.0, "y": 2.0})
    st = track_statistics(pd.concat([tracks, standing], ignore_index=True))
    moving = st.loc[range(6)]
    assert_allclose(moving["speed"], 0.8 + 0.8 * np.arange(6) / 5, rtol=1e-12)
    assert_allclose(moving["straightness"], 1.0, rtol=1e-12)
    assert_allclose(moving["duration"], 12.0, rtol=1e-12)
    assert not moving["still"].any()
    # within 0.5 m of the end 0.5 / v seconds before it (the crossing interpolated)
    v = moving["speed"].to_numpy()
    assert_allclose(moving["exit_fraction"], (12.0 - 0.5 / v) / 12.0, rtol=1e-12)
    assert_allclose(moving["walk_time"], 12.0 - 1.0 / v, rtol=1e-12)
    assert st.loc[99, "still"] and st.loc[99, "walk_time"] == 0.0
    assert np.isnan(st.loc[99, "speed"]) and np.isnan(st.loc[99, "straightness"])


def test_speed_times_the_walk_not_the_stay() -> None:
    """A person who stands 6 s where it enters and 8 s at its exit walks at 1.25 m/s: the
    speed is the walk's (from setting off, 0.5 m from the entry, to reaching the exit, 0.5 m
    from the end), not path / stay (0.74 m/s)."""
    t = np.arange(0.0, 34.0 + 1e-9, 0.4)
    x = np.clip(1.25 * (t - 6.0), 0.0, 25.0)  # walks from 6 s to 26 s
    st = track_statistics(pd.DataFrame({"id": 0, "t": t, "x": x, "y": 1.0}))
    assert_allclose(st.loc[0, "speed"], 1.25, rtol=1e-9)
    assert_allclose(st.loc[0, "walk_time"], 25.0 / 1.25 - 2 * 0.4, rtol=1e-9)
    assert st.loc[0, "path"] / st.loc[0, "duration"] < 0.75


@pytest.fixture(scope="module")
def crossing():
    """Door-to-door tracks; the behaviour fitted on 70% of them, the rest scored."""
    tracks, free = crossing_world(3, n=40)
    res, fit = heldout_log_likelihood(0, tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    return tracks, free, res, fit


def test_policy_beats_the_random_walk_on_held_out_tracks(crossing) -> None:
    _, _, res, fit = crossing
    assert res["n_tracks"] == 12 and fit.n_tracks[0] == 28
    assert res["n_moves"] > 200
    assert res["policy_per_move"] > res["random_walk_per_move"]
    assert res["difference_per_move"] > 5 * res["difference_se"] > 0


def test_policies_share_one_program_and_equal_soft_policy(crossing, caplog) -> None:
    """The soft solves of the criticism (held-out moves, displacement errors' goals) run one
    compiled program for any epoch cap and up to GOAL_BUCKET goals (issue 29: each cap and
    goal count compiled its own), with the policies of soft_policy bit for bit."""
    import logging

    from are_stats.behaviour import soft_policy
    from are_stats.fitting._motion_checks import _policies

    _, free, _, fit = crossing
    cells = np.argwhere(free)
    rng = np.random.default_rng(0)
    _policies(fit, 0, cells[:3])  # compiled once
    got = {}
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        for g in (1, 5, 16):  # other goal counts, and caps from their geodesic distances
            goals = cells[rng.choice(len(cells), g, replace=False)]
            got[g] = (goals, _policies(fit, 0, goals))
    compiled = [r.getMessage() for r in caplog.records if "Compiling" in r.getMessage()]
    assert compiled == []
    for goals, pol in got.values():
        dist = fit.geodesic(goals)
        k = int(np.ceil(10 * dist[np.isfinite(dist)].max())) + 20
        want = soft_policy(
            ~fit.free, goals, float(fit.beta[0]), float(fit.slip[0]), n_epochs=k,
            goal_reward=fit.goal_reward, step_cost=fit.step_cost, time_cost=fit.time_cost,
            cell_reward=fit.cell_reward(0), tol=1e-3,
        ).policy  # fmt: skip
        np.testing.assert_array_equal(pol, np.asarray(want))


def test_held_out_fit_runs_the_fits_compiled_likelihood(crossing, caplog) -> None:
    """The behaviour fit's program (value, gradient, and the Hessian by its differences)
    takes the tracks as data padded to shape buckets (issue 29: the report's held-out fit
    compiled it again, with its own tracks closed over): the held-out fit after a fit on
    the same grid compiles nothing of it, and its split is scored as before."""
    import logging

    from are_stats.fitting import fit_behaviour
    from are_stats.fitting._behaviour import _gradient_value_epochs

    tracks, free, res, _ = crossing
    # a fit of other tracks, of another count (9 of all 40; the held-out fit: 10 of another
    # split than the fixture's): the same buckets, so the padding, too, spares a compile
    fit_behaviour(tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=9)
    size = _gradient_value_epochs._cache_size()
    assert size >= 1
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        again, fit = heldout_log_likelihood(5, tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    assert _gradient_value_epochs._cache_size() == size
    compiled = [r.getMessage() for r in caplog.records if "Compiling" in r.getMessage()]
    assert not [m for m in compiled if "_gradient_value_epochs" in m]
    assert again["n_tracks"] == res["n_tracks"] and fit.n_fit_tracks[0] == 10
    assert again["difference_per_move"] > 5 * again["difference_se"] > 0


def test_tracker_noise_is_the_position_noise_of_steady_walks() -> None:
    """Straight walks at steady speeds with 5 cm of noise per coordinate: the estimate is
    the noise's sd within 5% (3,600 second differences: the robust scale's relative
    standard error is about 1.1 / sqrt(3600) = 2%)."""
    rng = np.random.default_rng(3)
    tracks = _straight(n=6, seconds=120.0)
    tracks[["x", "y"]] += rng.normal(0.0, 0.05, (len(tracks), 2))
    assert tracker_noise(tracks) == pytest.approx(0.05, rel=0.05)
    assert tracker_noise(_straight()) < 1e-9  # no noise


@pytest.fixture(scope="module")
def own(crossing):
    """Tracks of the model itself: the crossing's people, arriving every 4 s from either
    door (so that they meet head-on), walked by the fitted behaviour with known parameters
    as the checks walk it (preferred speeds, the social force); and the checks of the
    fitted behaviour on them."""
    from are_stats.fitting._motion_checks import _replicate_tracks

    tracks, _, _, fit = crossing
    dense = tracks.assign(t=tracks["t"] - 96.0 * tracks["id"])
    own = _replicate_tracks(jax.random.key(9), fit, dense, 1).drop(columns=["scenario", "yaw"])
    table, reps = motion_checks(jax.random.key(1), fit, own, 40)
    return own, table, reps


def test_checks_pass_on_the_models_own_tracks(own) -> None:
    """5 statistics, 90% bands, 40 replicates: a right model gets 2 or more flags with
    probability about 1 - 0.9^5 - 5 (0.1) 0.9^4 = 8% (independent statistics), so "at most
    one" fails for about one seed in 12; the seeds are fixed. Before the replicates walked
    as generation does, the model's own tracks got 4 flags (the straightness of people who
    give way, a median speed band of width 0)."""
    _, table, reps = own
    assert reps["summary"].shape == (40, 5)
    assert int(table["model_flag"].sum()) <= 1, table


def test_speed_band_is_as_wide_as_the_models_speed_spread(own, crossing) -> None:
    """The replicates' median speed varies as the median of M people's preferred speeds
    drawn from the fitted law: its 90% band is about 2 (1.645) 1.2533 sigma v / sqrt(M)
    wide (the median's large-sample sd). Timed by the observed stays it was 0 wide."""
    fit = crossing[3]
    tracks, table, _ = own
    m = tracks["id"].nunique()
    v, sigma = np.exp(fit.speed_mu[0]), fit.speed_sigma[0]
    expected = 2 * 1.645 * 1.2533 * sigma * v / np.sqrt(m)
    width = (
        table.loc["median speed (m/s)", "model_95%"] - table.loc["median speed (m/s)", "model_5%"]
    )
    assert 0.5 * expected < width < 2.0 * expected, (width, expected)


def test_progress_counts_the_routes_and_the_walk_and_changes_nothing(own, crossing) -> None:
    """``progress(done, total, what)`` after each chunk of routes solved and each window of
    the social force, to the end (``done == total`` once, last); the checks are those drawn
    without it (``own``'s: the same key, tracks and 40 replicates, on the programs that
    fixture compiled; until 2026-11-29 two runs of 6 replicates, on shapes of their own)."""
    fit = crossing[3]
    tracks, plain, plain_reps = own
    said = []
    table, reps = motion_checks(
        jax.random.key(1), fit, tracks, 40, progress=lambda *c: said.append(c)
    )
    pd.testing.assert_frame_equal(table, plain)
    np.testing.assert_array_equal(reps["summary"], plain_reps["summary"])
    done = [d for d, _, _ in said]
    assert done == sorted(done) and said[-1][0] == said[-1][1], said
    assert [d == t for d, t, _ in said].count(True) == 1, said
    assert any("routes" in w for *_, w in said) and any("social force" in w for *_, w in said)
    # every window of the walk is a step: far more than the routes' chunks
    assert said[-1][1] > 2 + sum("routes" in w for *_, w in said), said


def test_replicates_are_measured_with_the_logs_noise(own, crossing) -> None:
    """The model's own tracks seen by a tracker with 0.15 m of position noise at 2.5 Hz:
    each noisy path is longer (a 0.5 m step reads about 8% longer), so the observed path
    speeds and straightness move. The replicates get the same noise before they are
    measured, so the median speed band moves with the observation and the speed is not
    flagged; measured without it, the band stayed at the noise-free speeds, below the
    noisy observation."""
    fit = crossing[3]
    tracks, clean, _ = own
    rng = np.random.default_rng(11)
    noisy = tracks.assign(
        x=tracks["x"] + rng.normal(0.0, 0.15, len(tracks)),
        y=tracks["y"] + rng.normal(0.0, 0.15, len(tracks)),
    )
    table, _ = motion_checks(jax.random.key(1), fit, noisy, 40)
    speed = "median speed (m/s)"
    assert table.loc[speed, "observed"] > 1.04 * clean.loc[speed, "observed"], table
    assert not table.loc[speed, "model_flag"], table
    assert table.loc[speed, "model_50%"] == pytest.approx(table.loc[speed, "observed"], rel=0.04)


def test_checks_flag_a_model_that_walks_too_fast(own, crossing) -> None:
    """The same tracks checked against the behaviour with preferred speeds 1.6 times the
    fitted ones: the median speed is flagged (observed below the band). Timed by the
    observed stays, the replicates walked the observed speeds whatever the model's."""
    import dataclasses

    fit = crossing[3]
    tracks, _, _ = own
    fast = dataclasses.replace(fit, speed_mu=fit.speed_mu + np.log(1.6))
    table, _ = motion_checks(jax.random.key(1), fast, tracks, 40)
    row = table.loc["median speed (m/s)"]
    assert row["model_flag"] and row["observed"] < row["model_5%"], table
    assert row["model_50%"] == pytest.approx(
        1.6 * own[1].loc["median speed (m/s)", "model_50%"], rel=0.1
    )


def _artefacts(tracks: pd.DataFrame) -> pd.DataFrame:
    g = tracks.groupby("id", sort=True)
    first, last = g.first(), g.last()
    return pd.DataFrame(
        {
            "scenario": 0,
            "id": first.index,
            "t_arrive": first["t"].to_numpy(),
            "t_leave": last["t"].to_numpy(),
            "x": first["x"].to_numpy(),
            "y": first["y"].to_numpy(),
        }
    )


def test_checks_flag_a_random_walk(crossing, own, tmp_path) -> None:
    """A slow random walk from the entries of the model's own tracks (``own``), for their
    stays, is flagged. Its replicates walk as ``own``'s (the same entries, arrivals, stays
    and key; measured with the walk's own noise): on the programs ``own`` compiled (until
    2026-11-29 the walk started from the crossing's entries, whose replicates compiled
    walks of their own shapes: 7.8 s of CPU for these checks, 3.2 s now)."""
    tracks, _, res, fit = crossing
    arts = _artefacts(own[0])
    table = own[1]
    assert list(table.index) == list(MOTION_STATISTICS)
    assert list(table.columns) == ["observed", "model_5%", "model_50%", "model_95%",
                                   "model_flag"]  # fmt: skip
    # a slow random walk from the same entries for the same stays
    rng = np.random.default_rng(4)
    rows = []
    for _, a in arts.iterrows():
        t = np.arange(a["t_arrive"], a["t_leave"] + 1e-9, 0.4)
        xy = np.array([a["x"], a["y"]]) + np.cumsum(rng.normal(0, 0.12, (t.size, 2)), axis=0)
        xy[0] = a["x"], a["y"]
        rows.append(pd.DataFrame({"id": a["id"], "t": t, "x": xy[:, 0], "y": xy[:, 1]}))
    walk = pd.concat(rows, ignore_index=True)
    table_w, reps_w = motion_checks(jax.random.key(1), fit, walk, 40)
    flags = table_w["model_flag"]
    assert flags["median straightness"] and flags["fraction still"], table_w
    de = displacement_errors(3, fit, tracks.iloc[:600], n_samples=8)
    assert list(de.index) == ["constant velocity", "model mean of K", "model best of K"]
    assert de.loc["model best of K", "ADE"] <= de.loc["model mean of K", "ADE"] + 1e-9
    fig = plot_motion_checks(table_w, reps_w, heldout=res, displacement=de)
    fig.savefig(tmp_path / "motion.png", dpi=60)
    assert (tmp_path / "motion.png").stat().st_size > 10_000


def test_flags_need_a_difference_that_matters():
    from are_stats.fitting import MOTION_STATISTICS, MOTION_TOLERANCE, band_flags

    assert set(MOTION_TOLERANCE) == set(MOTION_STATISTICS)
    stats = list(MOTION_STATISTICS)
    lo, hi = np.full(5, 0.5), np.full(5, 0.6)
    tol = np.array([MOTION_TOLERANCE[s] for s in stats])
    # just inside the tolerance on either side: not flagged; just beyond: flagged
    assert not band_flags(stats, hi + 0.9 * tol, lo, hi).any()
    assert not band_flags(stats, lo - 0.9 * tol, lo, hi).any()
    assert band_flags(stats, hi + 1.1 * tol, lo, hi).all()
    assert band_flags(stats, lo - 1.1 * tol, lo, hi).all()
    # an unknown statistic has no tolerance, a missing observation no flag
    assert band_flags(["other"], np.array([0.6001]), lo[:1], hi[:1]).tolist() == [True]
    assert band_flags(stats[:1], np.array([np.nan]), lo[:1], hi[:1]).tolist() == [False]


def test_replicates_over_the_work_limit_walk_in_parts():
    """A large log's replicates together exceed the limit that guards one call: they are
    walked in parts, as they would have walked together (scenarios never meet)."""
    from are_stats.behaviour import SocialForce
    from are_stats.environment import OccupancyGrid
    from are_stats.fitting._motion_checks import _walk
    from are_stats.inputs import LimitError, limits

    rows = []
    for s in range(4):
        for i in range(6):
            t = np.arange(0.0, 20.0, 0.5)
            y0 = 2.0 + i
            rows.append(
                pd.DataFrame(
                    {"scenario": s, "id": i, "t": t, "x": 1.0 + 0.6 * t + 0.1 * s,
                     "y": np.full_like(t, y0 if i % 2 else 9.0 - y0), "yaw": 0.0}
                )
            )  # fmt: skip
    plan = pd.concat(rows, ignore_index=True)
    grid = OccupancyGrid(np.zeros((24, 32), np.int8), 0.5)
    whole = _walk(plan, SocialForce(), grid)
    one = _walk(plan[plan["scenario"] == 0].reset_index(drop=True), SocialForce(), grid)
    # a work limit one scenario fits in and the four together do not
    from are_stats.behaviour import social_force_tracks

    with limits(work="1e4"), pytest.raises(LimitError) as err:
        social_force_tracks(plan, SocialForce(), grid, dt=0.1)
    need = float(str(err.value).split("got about ")[1].split(" ")[0])
    with limits(work=f"{need / 3:.0f}"):
        with pytest.raises(LimitError):
            social_force_tracks(plan, SocialForce(), grid, dt=0.1)
        said = []
        parts = _walk(plan, SocialForce(), grid, progress=lambda *c: said.append(c))
    pd.testing.assert_frame_equal(parts, whole)
    # the windows of both parts, counted one after the other to the end
    done = [d for d, _ in said]
    assert done == sorted(done) and said[-1][0] == said[-1][1] == len(said), said
    assert len(one) == len(plan) // 4
