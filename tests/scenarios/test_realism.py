"""Realism scores (distribution matching, as the Waymo sim agents challenge scores them)
against closed forms and a known generating model."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.environment import OccupancyGrid, load_catalogue, shipped_path
from are_stats.scenarios import (
    REALISM_FEATURES,
    realism_features,
    realism_score,
    realism_table,
    scene_tracks,
)
from tests.helpers import crossing_artefacts


def _line(i, t0, a, b, v, dt=0.1):
    a, b = np.asarray(a, float), np.asarray(b, float)
    dur = np.hypot(*(b - a)) / v
    t = t0 + np.arange(0, round(dur / dt) + 1) * dt
    xy = a + (b - a) * ((t - t0) / dur)[:, None]
    return pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1]})


def test_features_of_two_head_on_walkers_match_their_closed_forms():
    # 1 m/s each, 10 m apart: they close at 2 m/s; discs of 0.3 m touch at a gap of 0.6 m
    tr = pd.concat([_line(0, 0.0, (0, 0), (10, 0), 1.0), _line(1, 0.0, (10, 0), (0, 0), 1.0)])
    f = realism_features(tr, 0.1, radius=0.3)
    np.testing.assert_allclose(f["speed (m/s)"], 1.0, atol=1e-9)
    np.testing.assert_allclose(f["acceleration (m/s^2)"], 0.0, atol=1e-6)
    np.testing.assert_allclose(f["straightness"], 1.0)
    np.testing.assert_allclose(f["time to exit / stay"], 0.95, atol=1e-9)  # within 0.5 m
    # at a gap of 8 m while approaching (t = 1 s) the time to collision is (8 - 0.6) / 2 =
    # 3.7 s; at the same gap moving apart again (t = 9 s) they never collide (the 10 s cap)
    ttc, near = f["time to collision (s)"], f["nearest person (m)"]
    k = np.flatnonzero(np.isclose(near, 8.0))
    np.testing.assert_allclose(np.sort(ttc[k]), [3.7, 3.7, 10.0, 10.0], atol=1e-6)
    assert f["collision"].sum() == (near < 0.6).sum() > 0
    assert set(f) == set(REALISM_FEATURES)


def test_the_score_is_highest_for_the_same_distribution():
    rng = np.random.default_rng(0)
    obs = {f: rng.normal(1.3, 0.2, 2000) for f in REALISM_FEATURES}
    same = {f: rng.normal(1.3, 0.2, 4000) for f in REALISM_FEATURES}
    off = {f: rng.normal(1.0, 0.4, 4000) for f in REALISM_FEATURES}
    s_same, s_off = realism_score(obs, same), realism_score(obs, off)
    for f in ("speed (m/s)", "straightness"):
        assert s_same[f] > s_off[f]
        # a perfect match scores the mean bin mass of the distribution itself: about 1/12
        # for a normal over 20 bins spanning its 1-99% range
        assert 0.05 < s_same[f] < 0.12


@pytest.mark.slow
def test_the_generating_model_is_more_realistic_than_constant_velocity():
    """Tracks of the catalogue behaviour (MDP + social force) on the courtyard, scored as
    the log: the catalogue model that made them beats constant velocity."""
    grid = OccupancyGrid.from_ros_yaml(shipped_path("courtyard", "map"))
    cat = load_catalogue()
    free = np.argwhere(grid.free)
    rng = np.random.default_rng(4)
    cells = free[rng.choice(len(free), 12, replace=False)]
    xy = np.asarray(grid.cell_to_world(cells))
    art = pd.DataFrame({
        "scenario": 0, "artefact": np.arange(12), "class": 0, "mark": 0,
        "t_arrive": rng.uniform(0, 60, 12), "t_leave": rng.uniform(150, 240, 12),
        "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0,
    })  # fmt: skip
    observed = scene_tracks(jax.random.key(21), art, grid, cat, 300.0, behaviours="catalogue")
    tracks = observed.drop(columns="scenario")
    tracks = _resample_like_a_log(tracks, 0.4)
    table = realism_table(jax.random.key(5), tracks, grid, catalogue=cat, n_replicates=2)
    realism = table.loc["realism (weighted)"]
    assert realism["catalogue"] > realism["constant velocity"]
    assert (
        table.loc["on free cells", "catalogue"] >= table.loc["on free cells", "constant velocity"]
    )


def _resample_like_a_log(tracks, dt):
    out = []
    for i, g in tracks.groupby("id"):
        t = np.arange(np.ceil(g["t"].min() / dt), np.floor(g["t"].max() / dt) + 1) * dt
        out.append(pd.DataFrame({
            "id": i, "t": t, "x": np.interp(t, g["t"], g["x"]), "y": np.interp(t, g["t"], g["y"]),
        }))  # fmt: skip
    return pd.concat(out, ignore_index=True)


@pytest.fixture(scope="module")
def crossings_fit():
    """Door-to-door walkers (:func:`tests.helpers.crossing_world`), their map and the
    behaviour fitted on them."""
    from are_stats.fitting import heldout_log_likelihood
    from tests.helpers import crossing_world

    walkers, free = crossing_world(3, n=40)
    _, fit = heldout_log_likelihood(0, walkers, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    return walkers, OccupancyGrid(np.where(free, 0, 100), 0.5), fit


def _own_tracks_table(walkers, grid, fit, seed, noise=0.0):
    """Tracks of ``fit`` walked by :func:`scene_tracks` (MDP route, continuous motion,
    social force, the fit's within-person variation) for the walkers' entries and stays,
    arriving every 6 s (they meet on the way), seen at 2.5 Hz with ``noise`` (m) of
    position noise, and the realism table of that log with the same fit."""
    cat = load_catalogue()
    art, horizon = crossing_artefacts(walkers)
    log = scene_tracks(
        jax.random.key(11 + seed), art, grid, cat, horizon, behaviours="fitted", fitted=fit
    )
    log = _resample_like_a_log(log.drop(columns="scenario"), 0.4)
    rng = np.random.default_rng(1 + seed)
    log = log.assign(
        x=log["x"] + rng.normal(0.0, noise, len(log)), y=log["y"] + rng.normal(0.0, noise, len(log))
    )
    return realism_table(
        jax.random.key(5 + seed), log, grid, behaviour=fit, catalogue=cat, n_replicates=2
    )


@pytest.mark.slow
def test_the_fitted_model_beats_constant_velocity_and_the_catalogue_on_its_own_tracks(
    crossings_fit,
):
    """Issue 26's claim on synthetic tracks simulated by the model: door-to-door walkers,
    the behaviour fitted on them, then tracks of that fitted model (MDP route, continuous
    motion, social force) scored as the log: the fitted model's realism score is above both
    baselines (0.441 against 0.411 and 0.412 with these seeds).

    The margins' spread over seeds 0-5 of the log and the table: 0.027-0.034 above
    constant velocity (mean 0.031, sd 0.003) and 0.028-0.035 above the catalogue (mean
    0.031, sd 0.003); the bounds asserted, 0.02 and 0.015, lie 3.5 and 5.7 sd below the
    means. Above constant velocity it was 0.033-0.046 (mean 0.039) while every walker's
    first step ran a whole ``dt`` ahead of its plan (fixed 2026-11-28): constant
    velocity keeps each person's velocity of the first second, which then held the
    first step's extra ``v0 dt`` (up to 10% too fast), and it scored lower for it (on free
    cells 0.955 against 0.992 now, time to exit 0.161 against 0.225, seed 0); the fitted
    model's own score moved by -0.005 to +0.001."""
    walkers, grid, fit = crossings_fit
    table = _own_tracks_table(walkers, grid, fit, 0)
    realism = table.loc["realism (weighted)"]
    assert realism["fitted"] > realism["constant velocity"] + 0.02
    assert realism["fitted"] > realism["catalogue"] + 0.015
    assert table.loc["straightness", "fitted"] > table.loc["straightness", "catalogue"]


@pytest.mark.slow
def test_a_generating_model_whose_people_vary_beats_constant_velocity_on_its_own_tracks(
    crossings_fit,
):
    """The same on a log whose people vary as the fitted model's can: the fit given a
    between-person spread of the preferred speed (log-sd 0.15), a within-person pace
    (log-sd 0.1, 3 s) and a heading wander (0.12 rad, 2 s), its tracks seen at 2.5 Hz
    with 5 cm of noise. The generating model scores above constant velocity and the
    catalogue (0.431 against 0.421 and 0.420 here; seeds 0-4 of the log and the table
    gave it 0.010-0.014 above constant velocity and 0.011-0.013 above the catalogue), and
    above the catalogue on straightness (above constant velocity too on four of those
    five seeds, tied on one: 40 tracks' straightness in 20 bins is a noisy score)."""
    walkers, grid, fit = crossings_fit
    one = np.ones(1)
    varying = dataclasses.replace(
        fit, speed_sigma=0.15 * one, speed_within_sd=0.1 * one, speed_within_time=3.0 * one,
        heading_within_sd=0.12 * one, heading_within_time=2.0 * one,
    )  # fmt: skip
    table = _own_tracks_table(walkers, grid, varying, 0, noise=0.05)
    realism = table.loc["realism (weighted)"]
    assert realism["fitted"] > realism["constant velocity"]
    assert realism["fitted"] > realism["catalogue"]
    assert table.loc["straightness", "fitted"] > table.loc["straightness", "catalogue"]


def test_group_spacing_is_the_distance_between_walking_members():
    # a pair 0.7 m abreast and a trio in a line 0.5 m apart walk at 1 m/s; a lone walker
    # 0.2 m from the pair's member and a standing member count for nothing
    pair = [_line(i, 0.0, (0, y), (10, y), 1.0) for i, y in ((0, 0.0), (1, 0.7))]
    trio = [_line(i, 0.0, (0, y), (10, y), 1.0) for i, y in ((2, 20.0), (3, 20.5), (4, 21.0))]
    lone = _line(5, 0.0, (0, 0.9), (10, 0.9), 1.0)
    still = pd.DataFrame({"id": 6, "t": np.arange(0, 10.01, 0.1), "x": 0.0, "y": 20.3})
    tr = pd.concat([*pair, *trio, lone, still], ignore_index=True)
    groups = {0: "a", 1: "a", 2: "b", 3: "b", 4: "b", 5: "", 6: "b"}
    f = realism_features(tr, 0.1, groups=groups)
    g = f["group spacing (m)"]
    # 100 walking samples (the first has no velocity) of 2 + 3 members
    assert g.size == 500
    np.testing.assert_allclose(np.sort(g), np.r_[np.full(300, 0.5), np.full(200, 0.7)], atol=1e-9)
    assert realism_features(tr, 0.1)["group spacing (m)"].size == 0  # no groups given


def test_group_spacing_enters_the_realism_score():
    """Pairs walking 0.7 m abreast in an open room: the table has a group spacing row,
    weighted as one of the interactive features, and constant velocity (which keeps the
    pairs' spacing) scores it well; a log without pairs has no group values."""
    rows = []
    for k in range(6):
        t0, y = 12.0 * k, 2.0 + 1.5 * k
        rows += [_line(2 * k, t0, (1, y), (15, y), 1.2, 0.4),
                 _line(2 * k + 1, t0, (1, y + 0.7), (15, y + 0.7), 1.2, 0.4)]  # fmt: skip
    log = pd.concat(rows, ignore_index=True)
    table = realism_table(jax.random.key(0), log, None, n_replicates=1)
    row = table.loc["group spacing (m)"]
    assert row["kind"] == "interactive"
    interactive = table[table["kind"] == "interactive"]
    assert np.isclose(row["weight"], 0.5 / len(interactive))
    assert row["constant velocity"] > 0.5
    alone = realism_table(jax.random.key(0), log[log["id"] % 2 == 0], None, n_replicates=1)
    assert np.isnan(alone.loc["group spacing (m)", "constant velocity"])


def test_interactive_features_match_a_brute_force_over_every_frame():
    """Nearest person, collision and time to collision of a crowd in two scenarios against
    every pair of each (scenario, time) frame computed directly; a person alone in its
    frame has no value."""
    rng = np.random.default_rng(7)
    rows = []
    for scen in (0, 1):
        for i in range(12):
            t0 = rng.integers(0, 20) * 0.4
            t = t0 + 0.4 * np.arange(rng.integers(3, 30))
            p0, v = rng.uniform(0, 15, 2), rng.normal(0, 1.0, 2)
            xy = p0 + (t - t0)[:, None] * v
            rows.append(
                pd.DataFrame({"scenario": scen, "id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1]})
            )
    tracks = pd.concat(rows, ignore_index=True)
    from are_stats.scenarios._realism import _resample

    got = realism_features(tracks, 0.4, radius=0.3)
    near, hit, ttc = [], [], []
    tab = _resample(tracks, 0.4)
    vel = np.full((len(tab), 2), np.nan)
    for _, g in tab.groupby(["scenario", "id"]):
        vel[g.index[1:]] = np.diff(g[["x", "y"]].to_numpy(), axis=0) / 0.4
    ok = np.isfinite(vel).all(axis=1)
    for _, g in tab[ok].groupby(["scenario", "t"]):
        if len(g) < 2:
            continue
        xy, v = g[["x", "y"]].to_numpy(), vel[g.index]
        for a in range(len(g)):
            d = np.hypot(*(xy - xy[a]).T)
            d[a] = np.inf
            near.append(min(d.min(), 10.0))
            hit.append(float(d.min() < 0.6))
            best = 10.0
            for b in np.flatnonzero(d <= 10.0):
                p, w = xy[b] - xy[a], v[b] - v[a]
                qa, qb, qc = w @ w, 2 * p @ w, p @ p - 0.36
                disc = qb * qb - 4 * qa * qc
                t_hit = (-qb - np.sqrt(max(disc, 0))) / (2 * qa) if qa > 1e-12 else 10.0
                if qc <= 0:
                    t_hit = 0.0
                elif not (disc >= 0 and qa > 1e-12 and t_hit >= 0):
                    t_hit = 10.0
                best = min(best, t_hit, 10.0)
            ttc.append(best)
    assert len(near) > 100
    for name, want in (("nearest person (m)", near), ("collision", hit),
                       ("time to collision (s)", ttc)):  # fmt: skip
        np.testing.assert_allclose(np.sort(got[name]), np.sort(want), atol=1e-9)


def test_group_spacing_matches_a_brute_force_over_every_group_and_frame():
    """Groups of one to four walkers in two scenarios (the same labels in both, some
    members standing for a while): the distance of each walking member to its nearest
    walking co-member of the same (scenario, group, time), computed frame by frame."""
    rng = np.random.default_rng(3)
    rows, groups = [], {}
    for scen in (0, 1):
        for i in range(14):
            t0 = rng.integers(0, 10) * 0.4
            t = t0 + 0.4 * np.arange(rng.integers(3, 25))
            v = rng.normal(0, 1.0, 2) * (rng.random(t.size) < 0.8)[:, None]  # some stand
            xy = rng.uniform(0, 12, 2) + np.cumsum(v * 0.4, axis=0)
            rows.append(
                pd.DataFrame({"scenario": scen, "id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1]})
            )
            groups[(scen, i)] = "abcd"[rng.integers(4)] if i < 12 else ""
    tracks = pd.concat(rows, ignore_index=True)
    from are_stats.scenarios._realism import _resample

    got = realism_features(tracks, 0.4, groups=groups)["group spacing (m)"]
    tab = _resample(tracks, 0.4)
    vel = np.full((len(tab), 2), np.nan)
    for _, g in tab.groupby(["scenario", "id"]):
        vel[g.index[1:]] = np.diff(g[["x", "y"]].to_numpy(), axis=0) / 0.4
    lab = np.array([groups[(s, i)] for s, i in zip(tab["scenario"], tab["id"], strict=True)])
    walking = np.isfinite(vel).all(axis=1) & (np.hypot(*np.nan_to_num(vel).T) >= 0.2)
    walking &= lab != ""
    want = []
    sel = tab[walking].assign(g=lab[walking], t=np.round(tab["t"][walking], 6))
    for _, f in sel.groupby(["scenario", "g", "t"]):
        xy = f[["x", "y"]].to_numpy()
        for a in range(len(f) if len(f) >= 2 else 0):
            d = np.hypot(*(xy - xy[a]).T)
            d[a] = np.inf
            want.append(min(d.min(), 10.0))
    assert len(want) > 100
    np.testing.assert_allclose(np.sort(got), np.sort(want), atol=1e-9)


def test_the_models_are_seen_with_the_logs_position_noise():
    """Walkers at constant velocity seen with 5 cm of noise at 2.5 Hz: the noise is
    estimated from the log (0 for the exact lines), and constant velocity, the model that
    made the log, scores on its accelerations and turning rates as the log's own
    distribution does (about 1/12), not near 0 as exact positions against noisy ones."""
    from are_stats.scenarios._realism import _observation_noise

    rng = np.random.default_rng(3)
    rows = []
    for k in range(12):
        y = 1.0 + 1.5 * k
        a, b = ((1, y), (19, y + 1)) if k % 2 else ((19, y), (1, y - 1))
        rows.append(_line(k, 2.4 * k, a, b, rng.uniform(1.0, 1.5), 0.4))
    exact = pd.concat(rows, ignore_index=True)
    noisy = exact.assign(
        x=exact["x"] + rng.normal(0, 0.05, len(exact)),
        y=exact["y"] + rng.normal(0, 0.05, len(exact)),
    )
    assert _observation_noise(exact, 0.4) == pytest.approx(0.0, abs=1e-6)
    assert _observation_noise(noisy, 0.4) == pytest.approx(0.05, rel=0.1)
    table = realism_table(jax.random.key(0), noisy, None, n_replicates=1)
    assert table.attrs["observation_noise"] == pytest.approx(0.05, rel=0.1)
    exact_cv = realism_table(jax.random.key(0), noisy, None, n_replicates=1, noise=0.0)
    for f in ("acceleration (m/s^2)", "turning rate (rad/s)"):
        assert table.loc[f, "constant velocity"] > 0.04  # 0.058 and 0.065
        assert exact_cv.loc[f, "constant velocity"] < 0.01  # 0.002 and 0.004
    with pytest.raises(ValueError, match="noise: expected a finite number >= 0"):
        realism_table(jax.random.key(0), noisy, None, n_replicates=1, noise=-1.0)


@pytest.mark.slow
def test_the_fitted_model_beats_both_baselines_on_an_independent_crowd():
    """Issue 26's target on a crowd the package did not simulate (:mod:`tests.crowd`: door
    to door round a pillar, velocity-obstacle avoidance, groups abreast at 0.7 m, 5 cm
    noise at 2.5 Hz): fitted as ``are-stats fit`` fits a tracks table with its map, the
    fitted behaviour's weighted realism is above constant velocity's and the catalogue's
    (0.295 against 0.273 and 0.289 with this seed, on the log's bins; 0.343, 0.323 and
    0.310 on bins over every model's values, whose straightness bins the catalogue's
    winding paths made about 18 times wider than the log's spread; its interaction, learned as
    ``are-stats fit`` learns it, is none: the noise of 5 cm at 2.5 Hz hides the avoidance
    from the evidence), and so is its group spacing (the fitted spacing walked in
    formation)."""
    from tests.crowd import crowd_realism

    r = crowd_realism(0, 300.0, n_replicates=2, errors=False)
    table = r["table"]
    realism = table.loc["realism (weighted)"]
    assert realism["fitted"] > realism["constant velocity"] + 0.01
    assert realism["fitted"] > realism["catalogue"]
    spacing = table.loc["group spacing (m)"]
    assert spacing["fitted"] > spacing["constant velocity"]
    assert r["interaction"].group_spacing == pytest.approx(0.7, abs=0.05)
    assert r["table"].attrs["observation_noise"] == pytest.approx(0.05, rel=0.15)


def test_progress_counts_the_replicates_and_changes_nothing():
    """``progress(done, total)`` after each replicate of each behaviour walked (here the
    catalogue's, twice), ``done`` rising by one to ``total``; the same table without it."""
    occ = np.zeros((40, 80), np.int8)
    occ[[0, -1], :] = occ[:, [0, -1]] = 100
    grid = OccupancyGrid(occ, 0.25, (0.0, 0.0, 0.0))
    log = pd.concat(
        [_line(k, 6.0 * k, (1.5, 2.0 + 2.0 * k), (18.0, 2.5 + 2.0 * k), 1.2, 0.4)
         for k in range(4)], ignore_index=True,
    )  # fmt: skip
    said = []
    table = realism_table(
        jax.random.key(3), log, grid, n_replicates=2,
        progress=lambda done, total: said.append((done, total)),
    )  # fmt: skip
    assert said == [(1, 2), (2, 2)]
    alone = realism_table(jax.random.key(3), log, grid, n_replicates=2)
    assert "catalogue" in table.columns
    pd.testing.assert_frame_equal(table, alone)


def test_a_models_score_does_not_depend_on_the_other_models_in_the_table():
    """Every model is scored on the log's bins: constant velocity's column is the same
    whether the catalogue behaviour beside it walked one replicate or two (on bins over
    the pooled values of every model, the catalogue's second replicate moved them and
    constant velocity's scores with them), and a model's score alone
    (:func:`realism_score`'s default bins) is its column of the table."""
    occ = np.zeros((40, 80), np.int8)
    occ[[0, -1], :] = occ[:, [0, -1]] = 100
    grid = OccupancyGrid(occ, 0.25, (0.0, 0.0, 0.0))
    rng = np.random.default_rng(2)
    log = pd.concat(
        [_line(k, 3.0 * k, (1.5, 2.0 + 1.2 * k), (18.0, 2.5 + 1.0 * k), rng.uniform(0.9, 1.5), 0.4)
         for k in range(6)], ignore_index=True,
    )  # fmt: skip
    one = realism_table(jax.random.key(3), log, grid, n_replicates=1, noise=0.0)
    two = realism_table(jax.random.key(3), log, grid, n_replicates=2, noise=0.0)
    assert not np.allclose(
        one["catalogue"].to_numpy(float), two["catalogue"].to_numpy(float), equal_nan=True
    )  # the catalogue's column did change
    pd.testing.assert_series_equal(one["constant velocity"], two["constant velocity"])
    from are_stats.scenarios._realism import _constant_velocity

    alone = realism_score(
        realism_features(log, 0.4, grid), realism_features(_constant_velocity(log, 0.4), 0.4, grid)
    )
    for f, v in alone.items():
        assert v == pytest.approx(one.loc[f, "constant velocity"], nan_ok=True)


def test_a_log_whose_feature_never_varies_still_tells_the_right_value_from_a_wrong_one():
    """A feature the log has at one value (walkers exactly 0.7 m apart): its bins are
    widened round that value, so a model at the value scores 1 less the pseudo-counts'
    share and a model 0.2 m off only the pseudo-count of its bin."""
    obs = {"group spacing (m)": np.full(200, 0.7)}
    right = realism_score(obs, {"group spacing (m)": np.full(400, 0.7)})
    wrong = realism_score(obs, {"group spacing (m)": np.full(400, 0.5)})
    assert right["group spacing (m)"] == pytest.approx(401 / 420)
    assert wrong["group spacing (m)"] == pytest.approx(1 / 420)


def _resample_by_groups(tracks: pd.DataFrame, dt: float) -> pd.DataFrame:
    """The independent reference: a table per ``groupby`` track, interpolated, concatenated."""
    cols = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    out = []
    for key, g in tracks.sort_values([*cols, "t"], kind="stable").groupby(cols, sort=False):
        t = g["t"].to_numpy(float)
        grid_t = np.arange(np.ceil(t[0] / dt - 1e-9), np.floor(t[-1] / dt + 1e-9) + 1) * dt
        if grid_t.size:
            key = key if isinstance(key, tuple) else (key,)
            part = {c: np.full(grid_t.size, k) for c, k in zip(cols, key, strict=True)}
            part["t"] = grid_t
            part["x"] = np.interp(grid_t, t, g["x"].to_numpy(float))
            part["y"] = np.interp(grid_t, t, g["y"].to_numpy(float))
            out.append(pd.DataFrame(part))
    if not out:
        return pd.DataFrame(columns=[*cols, "t", "x", "y"])
    res = pd.concat(out, ignore_index=True)
    return res if "scenario" in res.columns else res.assign(scenario=0)


@pytest.mark.parametrize("kind", ["names", "scenarios", "missing ids", "one row", "empty"])
def test_resampling_from_arrays_is_the_groupby_tables_exactly(kind: str) -> None:
    """The resampled table (issue 29: runs of one sorted table, not a table per track) is
    the per-track tables' concatenation bit for bit, dtypes included: shuffled rows,
    string or integer ids, scenarios, ids missing (left out), tracks shorter than a step."""
    from are_stats.scenarios._realism import _resample

    rng = np.random.default_rng(11)
    ids = [f"p{k}" for k in range(25)] if kind != "scenarios" else list(range(15))
    rows = []
    for s in (2, 0, 1) if kind == "scenarios" else (None,):
        for i in ids:
            n = int(rng.integers(1, 30))
            t = np.sort(rng.uniform(0, 20, n)).round(1)
            part = {"id": i, "t": t, "x": rng.normal(size=n), "y": rng.normal(size=n)}
            rows.append(pd.DataFrame(part if s is None else {"scenario": s, **part}))
    tracks = pd.concat(rows, ignore_index=True).sample(frac=1, random_state=0)
    if kind == "missing ids":
        tracks.loc[tracks.index[:7], "id"] = np.nan
    elif kind == "one row":
        tracks = tracks.iloc[:1]
    elif kind == "empty":
        tracks = tracks.iloc[:0]
    for dt in (0.1, 0.4, 1.0):
        want = _resample_by_groups(tracks, dt)
        pd.testing.assert_frame_equal(_resample(tracks, dt), want, check_exact=True)
        assert kind in ("empty", "one row") or len(want) > 0
