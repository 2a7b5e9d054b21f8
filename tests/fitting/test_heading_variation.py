"""fit_behaviour's within-person heading variation: the sd and correlation time of a
walker's heading deviation from its route's direction, recovered from tracks seen through a
noisy tracker, and walked by the social force.

People of the model (a preferred speed drawn once per person from a lognormal law, the
heading ``theta(t)`` off the bearing to a goal, ``theta`` a stationary Ornstein-Uhlenbeck
process of sd ``SD`` (rad) and correlation time ``TIME``, simulated by its exact AR(1) on a
20 ms grid: the package's walker, which keeps aiming at its route's next corner) walk
towards goals in the open, sampled at 10 Hz with white position noise. Over 6 replicates of
100 such tracks of 40 s (seeds 100-105; the estimator of 2026-11-28, read off the bearing
from each window's middle to the route's next corner) the estimates had means 0.1191 /
0.1185 rad and 1.98 / 2.03 s and Monte Carlo sd 0.0020 / 0.0021 rad and 0.10 / 0.12 s
without / with 5 cm of noise (bootstrap standard errors 0.0023 / 0.0023 rad and 0.12 /
0.16 s: the spread). Read off the bearing from the window's start the noisy sd was 7% low
(0.1120: the 1 s window the noise asks for swept the bearing; see
``test_the_bearing_swept_over_the_window_is_not_read_as_less_wander``). The checks allow
``TOL_SD`` (about 5 Monte Carlo sd) and ``TOL_TIME`` (about 4).
"""

from __future__ import annotations

import math

import arviz as az
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import BehaviourFit, social_force_tracks
from are_stats.behaviour._social import _pace
from are_stats.fitting import attach_behaviour, fit_behaviour
from are_stats.fitting._behaviour import _heading_variation, _ou_fit, _ou_window_terms
from tests.fitting.test_speed_variation import _inner, _lanes
from tests.helpers import variation_inputs

SD, TIME = 0.12, 2.0
TOL_SD, TOL_TIME = 0.012, 0.44
ROOM = 80.0  # m, open


def ou_heading_tracks(
    seed: int, n: int, sd: float, time: float, noise: float, duration: float = 40.0
) -> pd.DataFrame:
    """``n`` walks of ``duration`` s at ``v_i`` (``log v_i ~ N(log 1.3, 0.15^2)``) from the
    room's centre towards a goal ``v_i duration`` away in a uniform direction, heading
    ``theta(t)`` off the bearing to the goal (``theta`` a stationary OU of sd ``sd`` and
    correlation time ``time``: the package's walker, which keeps aiming at its route's
    next corner), one after the other, sampled at 10 Hz with white position noise of sd
    ``noise`` (m)."""
    rng = np.random.default_rng(seed)
    fine = 0.02
    v0 = np.exp(math.log(1.3) + 0.15 * rng.standard_normal(n))
    k = round(duration / fine)
    phi = math.exp(-fine / time)
    z = rng.standard_normal((k, n))
    alpha = rng.uniform(0.0, 2.0 * np.pi, n)
    goal = 0.5 * (v0 * duration)[:, None] * np.column_stack([np.cos(alpha), np.sin(alpha)])
    walked = np.zeros((k + 1, n, 2)) - goal  # the walk centred in the room
    theta = sd * z[0]
    for j in range(k):
        if j:
            theta = phi * theta + sd * math.sqrt(1.0 - phi**2) * z[j]
        to = goal - walked[j]
        ang = np.arctan2(to[:, 1], to[:, 0]) + theta
        walked[j + 1] = walked[j] + (v0 * fine)[:, None] * np.column_stack(
            [np.cos(ang), np.sin(ang)]
        )
    t_fine = fine * np.arange(k + 1)
    t = np.arange(0.0, duration + 1e-9, 0.1)
    rows = []
    for i in range(n):
        xy = ROOM / 2 + np.column_stack(
            [np.interp(t, t_fine, walked[:, i, 0]), np.interp(t, t_fine, walked[:, i, 1])]
        )
        xy = xy + rng.normal(0.0, noise, xy.shape)
        t_i = i * (duration + 5.0) + t  # one after the other: nobody near anybody
        rows.append(pd.DataFrame({"id": i, "t": t_i, "x": xy[:, 0], "y": xy[:, 1]}))
    return pd.concat(rows, ignore_index=True)


def _variation(tracks: pd.DataFrame, route_map: tuple | None = None) -> dict[str, float]:
    """The estimate as fit_behaviour makes it (``route_map``: the map's free cells, origin
    and resolution, which fit_behaviour passes; default an open area)."""
    seen, speeds, noise, crowded = variation_inputs(tracks)
    return _heading_variation(seen, speeds, noise, crowded, route_map)


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_heading_variation_recovered_through_tracker_noise(noise: float) -> None:
    got = _variation(ou_heading_tracks(int(noise * 1000) + 7, 100, SD, TIME, noise))
    assert abs(got["heading_within_sd"] - SD) < TOL_SD
    assert abs(got["heading_within_time"] - TIME) < TOL_TIME


@pytest.mark.parametrize(
    ("step", "time", "n", "tol"), [(1.2, 1.0, 300, 0.0095), (2.0, 2.0, 450, 0.015)]
)
def test_the_bearing_swept_over_the_window_is_not_read_as_less_wander(
    step: float, time: float, n: int, tol: float
) -> None:
    """Walkers aiming at their goals (``n`` of 20 s, no noise, wander ``SD`` over ``time``)
    seen every ``step`` s: one window is one step (``W = step``), over which a walker ``D``
    from its goal and turned ``theta`` off it sweeps the bearing to the goal by about
    ``v W theta / D``. Read off the bearing at the window's start (the estimator until
    2026-11-28) its residual is about ``theta_bar (1 - v W / (2 D))``
    (:func:`~are_stats.fitting._behaviour._heading_variation`) and the wander read low;
    off the bearing at the chord's middle it does not. Six pooled logs (seeds 300, 310,
    .., 350 and the next ``n / 150 - 1``) read, from the start / the middle: W = 1.2 s,
    T = 1 s: 0.1083 +- 0.0023 / 0.1169 +- 0.0022 rad; W = 2.0 s, T = 2 s: 0.0989 +- 0.0034
    / 0.1136 +- 0.0027 (mean +- sd). The middle's remaining 3-5% is second order (``v W /
    D`` times ``W / T``) and these walks' ends: their last sample, the route's corner, is
    short of the goal they aimed at (docs/src/behaviour.md). ``tol`` is 2.9 and 3.2 sd
    from the middle's mean (a false failure about once in 400 runs for the two) and
    fails the start's reading on 83% and 96% of such logs."""
    pooled = []
    for s in range(n // 150):
        tracks = ou_heading_tracks(300 + s, 150, SD, time, 0.0, duration=20.0)
        tracks = tracks[np.round(tracks["t"] * 10).astype(int) % round(step * 10) == 0]
        pooled.append(tracks.assign(id=tracks["id"] + 1000 * s, t=tracks["t"] + 1e5 * s))
    got = _variation(pd.concat(pooled, ignore_index=True))
    assert abs(got["heading_within_sd"] - SD) < tol, got


def test_straight_walkers_show_no_heading_variation() -> None:
    """Walkers straight along their route, seen through 10 cm noise: the noise's moment
    is taken out, leaving (nearly) none."""
    got = _variation(ou_heading_tracks(3, 100, 0.0, TIME, 0.1))
    assert got["heading_within_sd"] < 0.02


def test_a_route_corner_is_not_wander() -> None:
    """Each walker turns a right angle half-way: the differences across the corner are
    left out (HEADING_CLIP) and the windows cut by it barely move the median, so the
    wander around the two legs reads within 25% of the straight walks' (15% here;
    without the clip, 5 rad)."""
    tracks = ou_heading_tracks(9, 100, SD, TIME, 0.05)
    straight = _variation(tracks)
    turned = []
    for _, g in tracks.groupby("id"):
        xy = g[["x", "y"]].to_numpy() - g[["x", "y"]].to_numpy()[len(g) // 2]
        after = np.arange(len(g)) > len(g) // 2
        xy[after] = xy[after] @ np.array([[0.0, 1.0], [-1.0, 0.0]])  # a left turn of 90 deg
        turned.append(g.assign(x=xy[:, 0], y=xy[:, 1]))
    got = _variation(pd.concat(turned, ignore_index=True))
    assert abs(got["heading_within_sd"] - straight["heading_within_sd"]) < 0.25 * SD


@pytest.fixture(scope="module")
def fitted() -> tuple[pd.DataFrame, BehaviourFit]:
    """100 wandering walkers seen through 5 cm of noise and the behaviour fitted on them:
    one fit for every test of this module that needs one (each fit costs seconds), on
    the grid and padded shapes of test_speed_variation's fit (its ``FIT_ROOM``): one
    program for both files."""
    tracks = ou_heading_tracks(11, 100, SD, TIME, 0.05)
    free = np.ones((int(ROOM / 0.5), int(ROOM / 0.5)), bool)
    return tracks, fit_behaviour(tracks, free, 0.5, (0.0, 0.0), cell=1.0, max_fit_tracks=2)


def test_fit_behaviour_stores_the_heading_variation_and_old_files_read_without_it(
    tmp_path, fitted: tuple[pd.DataFrame, BehaviourFit]
) -> None:
    _, fit = fitted
    assert abs(fit.heading_within_sd[0] - SD) < TOL_SD
    assert abs(fit.heading_within_time[0] - TIME) < TOL_TIME
    path = tmp_path / "b.nc"
    attach_behaviour(az.InferenceData(), fit).to_netcdf(path)
    back = BehaviourFit.from_dataset(az.from_netcdf(path).behaviour)
    for name in ("heading_within_sd", "heading_within_time"):
        np.testing.assert_array_equal(getattr(back, name), getattr(fit, name))
    old = BehaviourFit.from_dataset(
        fit.to_dataset().drop_vars(["heading_within_sd", "heading_within_time"])
    )
    assert old.heading_within_sd.tolist() == [0.0]
    assert np.isnan(old.heading_within_time).all()
    np.testing.assert_array_equal(old.speed_within_sd, fit.speed_within_sd)


def test_zero_heading_variation_walks_exactly_as_without() -> None:
    """sd 0 (or NaN: unknown) is today's motion, bit for bit, groups and a speed
    variation included."""
    plan = _lanes(4, 30.0)
    groups = np.where(plan["id"] < 2, 1, -1)
    plan.loc[plan["id"] == 1, "y"] = 0.75  # walks beside 0, in its group
    pace = (1, 0.1, 3.0)
    before = social_force_tracks(plan, dt=0.1, groups=groups, speed_variation=pace)
    for sd, time in ((0.0, TIME), (np.full(len(plan), np.nan), np.full(len(plan), np.nan))):
        after = social_force_tracks(
            plan, dt=0.1, groups=groups, speed_variation=pace, heading_variation=(0, sd, time)
        )
        pd.testing.assert_frame_equal(after, before, check_exact=True)


@pytest.mark.parametrize(("time", "window"), [(2.0, 1.2), (2.0, 2.0), (4.0, 1.2)])
def test_generation_compensates_the_lag_as_the_fit_reads_it(time: float, window: float) -> None:
    """The walked heading is generation's desired OU (``sd_d``, ``T_d``: what ``_pace``
    draws) through the social force's first-order lag ``tau``, whose autocovariance is
    ``A e^{-L/T_d} + B e^{-L/tau}`` (``A = sd_d^2 T_d^2 / (T_d^2 - tau^2)``, ``B = -sd_d^2
    T_d tau / (T_d^2 - tau^2)``): the semivariogram of its window means is exactly ``A
    g(T_d) + B g(tau)`` (``g``: :func:`_ou_window_terms`). The fit's own OU least squares
    on it, at a crossing log's lags (walks of 20 s at 2.5 Hz, pairs as weights), reads the
    sd asked for within 2% (measured: 0.995, 1.010, 1.008 of it) and the time within
    15% (0.93, 0.87, 1.03). Deterministic; the whole-variance rule (until 2026-11-28)
    read 1.063, 1.080, 1.041 and the slow part's (the pace's) 0.912, 0.923, 0.972: both
    fail (docs/src/behaviour.md)."""
    tau, dt, period, n = 0.5, 0.1, 0.4, 50
    drawn = _pace((0, SD, time), 1, np.zeros(1, np.int64), tau, dt, "heading_variation", "rad")
    phi = float(drawn.phi[0])
    t_d, sd_d = -dt / math.log(phi), float(drawn.innovation[0]) / math.sqrt(1.0 - phi**2)
    m = round(window / period)
    lags = np.unique(np.geomspace(m + 1, 75, 40).round().astype(np.int64))
    lags = lags[lags < n - m]
    lag_s = lags * period
    a = sd_d**2 * t_d**2 / (t_d**2 - tau**2)
    b = -(sd_d**2) * t_d * tau / (t_d**2 - tau**2)
    gamma = a * _ou_window_terms(t_d, window, lag_s) + b * _ou_window_terms(tau, window, lag_s)
    var, got_time = _ou_fit(gamma, (n - m - lags).astype(float), lag_s, period, window)
    assert math.sqrt(var) == pytest.approx(SD, rel=0.02)
    assert got_time == pytest.approx(time, rel=0.15)


def test_walked_heading_seen_like_a_crossing_log_reads_its_truth() -> None:
    """200 walkers of the social force, each alone on its lane (wander ``SD`` over
    ``TIME``), their middle 20 s seen at 2.5 Hz with 5 cm of noise (the fit's window
    1.2 s, past the relaxation time): the wander reads back within 0.0085 rad. Seeds 0-7
    read 0.1217 +- 0.0025 (a false failure about once in 300 runs); generation's
    compensation until 2026-11-28 (the walked variance ``SD^2``) read 0.1301 +- 0.0027
    and fails this on about 70% of seeds (5 of those 8)."""
    walked = social_force_tracks(_lanes(200, 1.3 * 24.0), dt=0.1, heading_variation=(0, SD, TIME))
    seen = _inner(walked)
    seen = seen[np.round(seen["t"] * 10).astype(int) % 4 == 0]
    rng = np.random.default_rng(0)
    seen = seen.assign(
        x=seen["x"] + rng.normal(0.0, 0.05, len(seen)),
        y=seen["y"] + rng.normal(0.0, 0.05, len(seen)),
    )
    assert abs(_variation(seen)["heading_within_sd"] - SD) < 0.0085


def test_walked_heading_has_the_given_variation_and_stays_on_route() -> None:
    """The social force turns each walker's desired heading by the OU it is given: the
    walked heading's sd and correlation time, read back by the fit's estimator from 60
    walks of 77 s, are the given ones (seeds 5 and 6 read sd 0.114-0.115 and time
    2.08 s: generation compensates the social force's lag as the fit reads it through
    windows of 0.4-2 s, and this 10 Hz log's 0.1 s window reads it 5% low; until
    2026-11-28 0.123-0.124, docs/src/behaviour.md), and the walkers keep about their
    lanes, straight (they aim at the lane's end all the while)."""
    walked = social_force_tracks(_lanes(60), dt=0.1, heading_variation=(5, SD, TIME))
    got = _variation(_inner(walked))
    assert abs(got["heading_within_sd"] - SD) < TOL_SD + 0.03 * SD
    assert abs(got["heading_within_time"] - TIME) < TOL_TIME + 0.2 * TIME
    off = np.abs(walked["y"].to_numpy() - 10.0 * walked["id"].to_numpy())
    assert 0.2 < off.max() < 6.0  # they do wander, about their lanes
    straight = []
    for _, g in walked.groupby("id"):
        xy = g[["x", "y"]].to_numpy()
        straight.append(np.hypot(*(xy[-1] - xy[0])) / np.hypot(*np.diff(xy, axis=0).T).sum())
    assert np.median(straight) > 0.98
    steady = social_force_tracks(_lanes(60), dt=0.1)
    assert _variation(_inner(steady))["heading_within_sd"] < 0.01


def test_group_members_turn_with_their_leader() -> None:
    """A pair walking abreast: the member keeps its slot beside the wandering leader."""
    plan = _lanes(2, 60.0)
    plan.loc[plan["id"] == 1, "y"] = 0.75
    groups = np.ones(len(plan), np.int64)
    walked = social_force_tracks(plan, dt=0.1, groups=groups, heading_variation=(2, 0.2, 2.0))
    a = walked[walked["id"] == 0][["x", "y"]].to_numpy()
    b = walked[walked["id"] == 1][["x", "y"]].to_numpy()
    gap = np.hypot(*(a - b).T)[30:-30]
    assert np.abs(np.diff(a[:, 1])).max() > 0  # the leader wanders
    assert gap.max() < 1.5


@pytest.mark.parametrize(
    ("variation", "words"),
    [((0, -0.1, 3.0), "sd >= 0 (rad)"), ((0, 0.1, 0.0), "time > 0"),
     ((0, [0.1, 0.1], 3.0), "one per"), ((0, 0.1), "expected (key, sd, time)")],
)  # fmt: skip
def test_bad_heading_variation_is_named(variation, words) -> None:
    with pytest.raises(ValueError, match="heading_variation") as err:
        social_force_tracks(_lanes(2, 5.0), dt=0.1, heading_variation=variation)
    assert words in str(err.value)


# test_generation_walks_the_fits_heading_variation_and_an_older_fit_as_before is in
# test_speed_variation: it shares that file's walks (the older fit's and sd 0's).


@pytest.mark.slow  # the criticism's replicate walks
def test_motion_checks_replicates_walk_the_fits_variation() -> None:
    """The criticism's replicates walk people as generation does, with the fit's
    within-person variation: an older fit (none) replicates exactly as a fit of sd 0, and
    the fitted one's replicates show the fitted heading wander again (read back within
    25%)."""
    import dataclasses

    import jax

    from are_stats.fitting._motion_checks import _replicate_tracks

    tracks = ou_heading_tracks(4, 40, SD, TIME, 0.0, duration=30.0)
    free = np.ones((int(ROOM / 0.5), int(ROOM / 0.5)), bool)
    fit = fit_behaviour(tracks, free, 0.5, (0.0, 0.0), cell=1.0, max_fit_tracks=2)
    assert abs(fit.heading_within_sd[0] - SD) < 0.02

    def replicate(f):
        return _replicate_tracks(jax.random.key(2), f, tracks, 1)

    older = BehaviourFit.from_dataset(
        fit.to_dataset().drop_vars(
            ["speed_within_sd", "speed_within_time", "heading_within_sd", "heading_within_time"]
        )
    )
    none = replicate(
        dataclasses.replace(fit, speed_within_sd=np.zeros(1), heading_within_sd=np.zeros(1))
    )
    pd.testing.assert_frame_equal(replicate(older), none, check_exact=True)
    varied = replicate(fit)
    got = _variation(_inner(varied))["heading_within_sd"]
    assert abs(got - fit.heading_within_sd[0]) < 0.25 * fit.heading_within_sd[0]
    assert _variation(_inner(none))["heading_within_sd"] < 0.02


def _one_class_fit(**within) -> BehaviourFit:
    """A one-class BehaviourFit on an open 10 x 10 grid, walkers at ``exp(mu) = 1`` m/s
    with no spread between people."""
    one = np.ones(1)
    return BehaviourFit(
        classes=("all",), cell=1.0, origin=np.zeros(2), free=np.ones((10, 10), bool),
        dt=one, speed_mu=np.zeros(1), speed_sigma=np.zeros(1), run_fraction=np.zeros(1),
        run_mu=np.full(1, np.nan), run_sigma=np.full(1, np.nan), beta=one, beta_se=one,
        slip=0.1 * one, slip_se=one, loglik=one, n_moves=one.astype(int),
        n_tracks=one.astype(int), n_fit_tracks=one.astype(int), n_epochs=one.astype(int),
        bandwidth_entry=one, bandwidth_exit=one, fit_seconds=one,
        track_class=np.zeros(1, np.int64), entry_xy=np.zeros((1, 2)), exit_xy=np.ones((1, 2)),
        **within,
    )  # fmt: skip


def test_rollouts_walk_the_pace_back_to_the_preferred_speed() -> None:
    """The displacement errors' continuations walk the fitted pace: a person of a class
    with no spread between people (everybody prefers 1 m/s), seen at 2 m/s, is in a fast
    spell that passes with the correlation time, so the distance it walks by t is
    ``int_0^t exp(log 2 e^{-s/T}) ds`` (the spell's innovations made negligible: sd 1e-9);
    without the variation (an older fit) the continuation is the one given, untouched."""
    from are_stats.fitting._prediction import _paced

    rate, n_pred, T = 2.5, 12, 3.0
    path = (np.array([0.0, 100.0]), np.array([[0.0, 0.0], [200.0, 0.0]]))  # at 2 m/s
    timed = np.empty((1, 2), dtype=object)
    timed[0, 0], timed[0, 1] = path, None  # the second stands
    speed = np.full((1, 2), 2.0)
    given = np.zeros((1, 2, n_pred, 2))
    old = _paced(np.random.default_rng(0), _one_class_fit(), np.zeros(1, int), given, timed,
                 speed, speed, n_pred, rate)  # fmt: skip
    assert old is given
    fit = _one_class_fit(speed_within_sd=np.full(1, 1e-9), speed_within_time=np.full(1, T))
    got = _paced(np.random.default_rng(0), fit, np.zeros(1, int), given, timed, speed, speed,
                 n_pred, rate)  # fmt: skip
    fine = np.linspace(0.0, n_pred / rate, 100001)
    v = np.exp(math.log(2.0) * np.exp(-fine / T))
    dist = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(fine))]
    want = np.interp(np.arange(1, n_pred + 1) / rate, fine, dist)
    np.testing.assert_allclose(got[0, 0, :, 0], want, rtol=2e-3)
    assert (got[0, 0, :, 1] == 0.0).all() and (got[0, 1] == 0.0).all()
    assert want[-1] < 0.9 * 2.0 * n_pred / rate  # slower than at the seen speed throughout


#: A heading wander (rad) of note in the pooled crowd logs of :func:`_crowd_logs`: the
#: crowd without any reads under it, the crowd with 0.2 rad over it (measured spreads in
#: :func:`test_a_crowd_without_wander_reads_none`).
CROWD_NOTE = 0.15


def _crowd_logs(wander: float, seeds: range = range(4)) -> pd.DataFrame:
    """The independent crowd of :mod:`tests.crowd` (300 s logs, ``seeds``) with a heading
    wander of sd ``wander`` (rad) over 2 s, its logs pooled as one (ids and times apart)."""
    from tests.crowd import crowd_tracks

    logs = []
    for j, seed in enumerate(seeds):
        tracks, _ = crowd_tracks(seed, 300.0, wander=(wander, 2.0))
        logs.append(tracks.assign(id=f"s{seed}" + tracks["id"], t=tracks["t"] + 1000.0 * j))
    return pd.concat(logs, ignore_index=True)


def _crowd_wander(tracks: pd.DataFrame) -> float:
    """The heading wander read off crowd tracks on the crowd's map."""
    from tests.crowd import RESOLUTION, crowd_grid

    return _variation(tracks, (crowd_grid(), (0.0, 0.0), RESOLUTION))["heading_within_sd"]


def test_a_crowd_without_wander_reads_none() -> None:
    """The independent crowd of :mod:`tests.crowd` (no within-person variation of its own:
    door to door round a pillar, velocity-obstacle avoidance, 5 cm noise at 2.5 Hz) reads
    neither a wander nor a pace of note. Its bends round the pillar are the route's: the
    tracks string-pulled over the crowd's map bend there, and the wander is read off the
    bearing to those corners (issue 26).

    Four logs pooled (seeds 0-3). Any one log is a draw of a chaotic simulation (the
    velocity-obstacle choice is an argmin): one ulp more in the crowd's trigonometry
    moves people by up to 3.7 m and reads seed 0 0.111 rad instead of 0.121, seed 4 not
    identified instead of 0.123, so which draw a seed gives depends on the machine's
    libm and SIMD paths. Until 2026-11-28 this test read seeds 0 and 1 alone against 0.1
    rad: seed 0 read 0.097 rad on the host it was written on and 0.121 on an AVX2 host
    with the same packages, and 0.1 is the middle of the crowd's readings, not their
    edge. Measured on that AVX2 host: single logs (seeds 0-29) are not identified on 18
    and read 0.104 +- 0.013 rad (0.085-0.123, over 1.9-6.9 s) on 12, a pace of 0 or
    none on 29 and 0.019 on one; pooled fours (seeds 0-3, 4-7, .., 36-39) are not
    identified on 3 and read 0.108 +- 0.009 rad (0.099-0.123, over 4.6-7.4 s) on 7 and a
    pace of at most 0.006; the same fours with a wander of 0.2 rad over 2 s read 0.212
    +- 0.016 rad (0.186-0.235) on all 10 (:func:`test_a_crowd_with_a_wander_reads_it`).
    ``CROWD_NOTE`` (0.15 rad) is 4.6 sd over the crowd's mean reading (a false failure
    under 1 in 10^4 for a Gaussian spread) and 3.8 sd under the wandering crowd's. What
    the crowd does read, about 0.1 rad over 4-7 s on some logs, is its avoidance and its
    bends round the pillar, slower than a wander: the estimator does not tell it from a
    slow wander of that size."""
    from tests.fitting.test_speed_variation import _variation as _pace

    tracks = _crowd_logs(0.0)
    assert not _crowd_wander(tracks) >= CROWD_NOTE  # NaN: not identified
    assert not _pace(tracks)["speed_within_sd"] >= 0.02


# make test: test_heading_variation_recovered_through_tracker_noise and
# test_walked_heading_seen_like_a_crossing_log_reads_its_truth read a true wander back; this
# one walks four more crowd logs (about 3 s of CPU each, 2026-11-28)
@pytest.mark.slow
def test_a_crowd_with_a_wander_reads_it() -> None:
    """The same crowd with a wander of 0.2 rad over 2 s (each person's desired heading
    turned by its own OU, group members keeping their slots) reads it, over
    :data:`CROWD_NOTE`: the check above fails for a crowd that does wander. Pooled fours
    (seeds 0-3, .., 36-39) read 0.212 +- 0.016 rad (0.186-0.235; seeds 0-3: 0.186), over
    1.0-4.5 s; single logs read 0 or are not identified on 2 of 10, hence the pool.
    0.3 rad is 5.5 sd over the mean. The default tier's cheaper checks that the estimator
    reads a wander that is there: :func:`test_heading_variation_recovered_through_tracker_noise`
    and :func:`test_walked_heading_seen_like_a_crossing_log_reads_its_truth`."""
    got = _crowd_wander(_crowd_logs(0.2))
    assert CROWD_NOTE < got < 0.3, got


def test_a_variation_read_past_a_third_of_the_longest_lag_is_kept_a_rise_without_sill_is_not():
    """Issue 26: on walks of 16-20 s (lags up to 8.8 s at 2.5 Hz) a 2 s wander read 2.94 s,
    past a third of the longest lag (the limit before), and so read 0 on about half the
    crossing logs. The OU's own semivariogram (:func:`_ou_window_terms`) with that
    correlation time is now read back exactly (the grid's 1%); one whose time is past half
    the longest lag (its variogram more than 14% under its sill there) and a rise without
    a sill (a straight line in the lag: the route's slow turn) are not identified: NaN,
    not the 0 of a variogram that shows no variation."""
    from are_stats.fitting._behaviour import _ou_fit, _ou_window_terms

    period = window = 0.4
    lag_s = period * np.unique(np.geomspace(2, 22, 18).round())
    w = np.linspace(400.0, 40.0, lag_s.size)  # pairs: fewer at the long lags

    def ou(tau: float) -> np.ndarray:
        return 0.12**2 * _ou_window_terms(tau, window, lag_s)

    var, tau = _ou_fit(ou(2.94), w, lag_s, period, window)
    assert lag_s.max() / 3.0 < 2.94 < lag_s.max() / 2.0
    assert var == pytest.approx(0.12**2, rel=0.02) and tau == pytest.approx(2.94, rel=0.01)
    assert all(math.isnan(v) for v in _ou_fit(ou(6.0), w, lag_s, period, window))
    assert all(math.isnan(v) for v in _ou_fit(0.003 * lag_s, w, lag_s, period, window))
    assert _ou_fit(np.zeros(lag_s.size), w, lag_s, period, window)[0] == 0.0
