"""Behaviour fitted from tracks (issue 16): speeds, exits, and a soft policy's beta and slip.

Per class (the ``label`` column; one class ``"all"`` without it):

* **Speeds.** Each track's walking speed, free of the tracker's position noise: the median
  net displacement per second over windows long enough that the noise
  (:func:`~are_stats.fitting.tracker_noise`) adds at most 1% (:func:`_track_speed`; a
  noise-free log's windows are single steps: the median step speed); tracks faster than
  ``run_speed`` are runners. Walking (and running) speeds get a lognormal law, ``mu`` the
  log of their median and ``sigma`` the sd of their logs (:func:`_lognormal`): the
  between-person law of preferred speeds.
* **Within-person variation** (:func:`_speed_variation`). Around its own preferred speed a
  walker's log speed drifts as a stationary Ornstein-Uhlenbeck process: its sd
  (``speed_within_sd``, log units) and correlation time (``speed_within_time``, s) are
  fitted to the semivariogram of the walkers' windowed log speeds within tracks, with the
  tracker's noise subtracted as a known moment. Generation walks it
  (:func:`~are_stats.behaviour.social_force_tracks`' ``speed_variation``). Likewise the
  heading (:func:`_heading_variation`): a walker's heading wanders around the bearing to
  its route's next corner as a stationary OU process (``heading_within_sd``, rad;
  ``heading_within_time``, s), fitted to the semivariogram of its windows' chord
  directions off that bearing (the route string-pulled from the track over the map)
  with the tracker's noise subtracted (``heading_variation``). Each comes with bootstrap
  standard errors over the tracks (``*_se``); NaN is a variation the tracks do not
  identify, 0 none. The accelerations and turning rates that follow are checked, not
  fitted (the realism table).
* **Scale.** The MDP cell is ``cell`` (default: about 0.5 m, coarser when the map would
  exceed ``max_side`` cells a side); the decision epoch is ``dt = cell / median walking
  speed``, so that an artefact at walking speed moves one cell per epoch.
* **Discretisation** (:func:`discretise_tracks`): positions interpolated at epoch times ->
  cells (snapped to free cells) -> gaps of more than one cell filled with the 4-connected
  cells along the straight line (one move per epoch). The goal is the last cell; a path is
  cut at its first visit of its goal (goals are absorbing).
* **Rationality and slip.** Maximum likelihood of the observed steps under the stationary
  soft policy (:func:`~are_stats.behaviour.moves_log_likelihood`, headings marginalised),
  with rewards ``time_cost = 1`` per epoch off the goal (so ``beta`` is per epoch lost), by
  L-BFGS-B on ``(log beta, logit slip)`` with forward-mode JAX gradients; standard errors
  from the inverse Hessian (delta method), NaN with a warning (:func:`_standard_errors`)
  where the information along a direction is within the Hessian's error (in float32,
  round-off: tracks that do not identify beta or a weight). At most ``max_fit_tracks``
  tracks per class enter this likelihood (a random subset; each track's goal costs one soft
  solve per evaluation).
  With several local XLA devices (``XLA_FLAGS=--xla_force_host_platform_device_count=N``,
  which the CLI sets: one per core) the goals are split across them; every split stops at
  the epoch of the whole batch, so value and gradient are those of one device (500 tracks,
  8 goals, 100 x 100, on 2 shared cores: 0.9 s against 3.2 s per value and gradient when
  the other load left room, no gain when it did not).
* **Reward features** (optional, ``features``; maximum-entropy inverse RL on the grid,
  Ziebart et al. 2008). Cell rewards ``sum_k w_k phi_k(cell)`` earned at every epoch off the
  goal (e.g. ``phi`` = closeness to walls, :func:`~are_stats.behaviour.wall_distance_feature`)
  enter the same soft solve, and the weights ``w_k`` are fitted jointly with ``beta`` and
  ``slip`` by the same likelihood (``theta = (log beta, logit slip, w_1, .., w_F)``),
  gradients and Hessian. The reward scale is fixed by ``time_cost``: a weight is a reward
  per epoch in those units (``w = -0.5`` next to a wall costs half an epoch lost per epoch
  spent there), and ``beta`` the rationality in them.
* **Standing classes.** A class none of whose tracks walks (pallets parked in the log) has
  no walking to fit: it is left out of the fitted classes and named in
  :attr:`~are_stats.behaviour.BehaviourFit.standing`, and stands in generated scenes; only
  when no class walks does the fit raise :class:`NoWalkersError`.
* **Exits.** Each track's first and last positions: the exit density given an entry is a
  kernel mixture over them (:meth:`~are_stats.behaviour.BehaviourFit.draw_exits`).
"""

from __future__ import annotations

import functools
import math
import time
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import TYPE_CHECKING, NamedTuple, TypedDict

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import pandas as pd
from jax.sharding import Mesh
from jax.sharding import PartitionSpec as P
from scipy import ndimage
from scipy.optimize import minimize
from scipy.spatial import cKDTree

from are_stats._checks import check_finite, check_positive, describe
from are_stats.behaviour import (
    BehaviourFit,
    grid_geodesic,
    jit_with_options,
    move_observations,
    moves_log_likelihood,
    path_free,
    soft_backward_induction,
    string_pull_many,
    tracker_noise,
    wall_distance_feature,
)
from are_stats.environment import coarse_free
from are_stats.inputs import check_memory

if TYPE_CHECKING:
    from are_stats.behaviour import MoveObservations
    from are_stats.inputs import Source

__all__ = [
    "BEHAVIOUR_FEATURES",
    "discretise_tracks",
    "fit_behaviour",
    "behaviour_log_likelihood",
    "open_area_grid",
    "NoWalkersError",
]


class NoWalkersError(ValueError):
    """A tracks table in which no track of a class walks: there is no walking to fit."""


_MAX_SIDE = 128
#: Built-in reward features of :func:`fit_behaviour` (name -> what it is).
BEHAVIOUR_FEATURES = {
    "walls": "closeness to walls, exp(-(d - 1)), d the distance (cells) to an obstacle or the "
    "map's border (wall_distance_feature with scale 1 cell)",
}
#: Bounds of a fitted feature weight (reward per epoch, in units of time_cost).
_WEIGHT_BOUND = 10.0


#: A window of :func:`_track_speed` is long enough that a slow walker
#: (:data:`SLOW_WALK`) covers this many times the sd of the position noise in it.
NOISE_WINDOW = 10.0
#: Speed (m/s) of a slow walker, the one the windows of :func:`_track_speed` are sized for.
SLOW_WALK = 0.5


def _track_speed(t: np.ndarray, xy: np.ndarray, noise: float) -> float:
    """A track's walking speed (m/s) free of the tracker's position noise.

    A step of a person walking at ``v`` observed with white position noise of sd ``s`` has
    length ``|v dt + e_1 - e_2|`` (``e ~ N(0, s^2 I)``): its median overstates ``v`` by a
    factor of about ``1 + (s / (v dt))^2`` where the noise is small against the step, and by
    far more where it is not (10 Hz, ``s = 0.1`` m: a 1.2 m/s walker's median step speed is
    2.0 m/s). So the speed is the median of the net displacement over windows of ``m``
    samples, over their duration (``W``), with ``m`` the fewest samples in which a slow
    walker (:data:`SLOW_WALK`) covers :data:`NOISE_WINDOW` times ``s``: the noise then adds
    at most 1% (0.2% at 1.2 m/s), and a turn within a window (its chord shorter than its
    arc) is mostly outvoted by the straight windows (a 12 m track with a 90-degree turn
    half-way reads about 1% slow at 10 Hz, ``s = 0.1`` m). The noise level only sizes the
    windows, so an estimate of it that is somewhat off changes little. Without noise
    ``m = 1``: the median step speed. A track shorter than one window is one window (net
    displacement over duration). A track whose speed is within the noise (below
    ``3 sqrt(2) s / W``, above 99% of the windows of a person standing still) stands: 0.

    Parameters
    ----------
    t : (n,) float
        Sample times (s), sorted.
    xy : (n, 2) float
        Positions (m).
    noise : float
        Sd (m) of the position noise per coordinate (:func:`tracker_noise`).

    Returns
    -------
    float
        NaN for a track of one sample (or no time between its samples).
    """
    dt = np.diff(t)
    if dt.size == 0 or not (dt > 0).any():
        return math.nan
    period = float(np.median(dt[dt > 0]))
    m = max(1, math.ceil(NOISE_WINDOW * noise / (SLOW_WALK * period) - 1e-9))
    m = min(m, len(t) - 1)
    span = t[m:] - t[:-m]
    ok = span > 0
    v = np.hypot(*(xy[m:] - xy[:-m]).T)[ok] / span[ok]
    speed = float(np.median(v))
    if noise > 0 and speed <= 3.0 * math.sqrt(2.0) * noise / float(np.median(span[ok])):
        return 0.0
    return speed


#: Longest lag (s) of the variogram of the within-person log speed (:func:`_speed_variation`).
VARIATION_LAG = 30.0
#: A walker's own pace is read only where nobody else is within this distance (m) of it
#: (:func:`_speed_variation`): near others, speed changes are the interaction's, which
#: generation adds by itself (the social force).
VARIATION_ALONE = 3.0
#: Windows whose speed is not within this factor of their track's speed are left out of
#: :func:`_speed_variation`: a stop or a burst is not the slow drift of the pace.
VARIATION_CLIP = 3.0


def _ou_window_terms(tau: float, window: float, lags: np.ndarray) -> np.ndarray:
    """``g0 - h(L)``: the semivariogram, per unit variance, of the averages over windows
    of ``window`` s of a stationary OU process of correlation time ``tau``, at lags
    ``L >= window`` (s). ``g0 = 2 (r - 1 + e^-r) / r^2`` is the variance of a window
    average (``r = window / tau``), ``h(L) = e^{(window - L) / tau} (tau / window)^2
    (1 - e^-r)^2`` the covariance of two averages ``L`` apart (windows that do not
    overlap)."""
    r = window / tau
    g0 = 2.0 * (r - 1.0 + math.exp(-r)) / r**2
    h = np.exp((window - lags) / tau) * (tau / window) ** 2 * (1.0 - math.exp(-r)) ** 2
    return g0 - h


def _crowded(tracks: pd.DataFrame, radius: float = VARIATION_ALONE) -> np.ndarray:
    """(n_rows,) bool: whether another track is within ``radius`` (m) of the row's position
    at its time (the same step of the log's median sampling step), per row of ``tracks``
    (``id, t, x, y``, any order)."""
    ids = tracks["id"].to_numpy()
    t = tracks["t"].to_numpy(float)
    xy = tracks[["x", "y"]].to_numpy(float)
    if len(t) < 2:
        return np.zeros(len(t), bool)
    order = np.lexsort((t, ids))
    same = ids[order][1:] == ids[order][:-1]
    steps = np.diff(t[order])[same]
    steps = steps[steps > 0]
    period = float(np.median(steps)) if steps.size else 1.0
    # one point per row in (x, y, time bin * far): rows of different bins never meet
    far = 4.0 * radius + float(np.ptp(xy, axis=0).max())
    pts = np.column_stack([xy, np.round(t / period) * far])
    # counts, not pairs (a dense crowd has many): the row itself is one, and a track has
    # one sample per time bin (two only where it is sampled faster than the median)
    check_memory(64.0 * len(t), f"the neighbours of {len(t)} track samples")
    return cKDTree(pts).query_ball_point(pts, radius, return_length=True) > 1


def _speed_variation(
    tracks: list[tuple[np.ndarray, np.ndarray]],
    speeds: np.ndarray,
    noise: float,
    crowded: list[np.ndarray] | None = None,
) -> dict[str, float]:
    """The within-person variation of the walking speed: a stationary Ornstein-Uhlenbeck
    process of the log speed around each person's own (sd and correlation time), pooled
    over a class's walkers.

    Model: person ``i`` walks at ``v_i(t) = v_i exp(u_i(t))``, ``u_i`` a stationary OU
    process of sd ``sigma`` and correlation time ``T`` (``cov u(t) u(t + L) = sigma^2
    e^{-L / T}``), independent across people; ``v_i`` is the preferred speed of the
    between-person law (:func:`_speed_law`).

    Estimator. Each track is resampled at the class's median sampling step ``dt``; its
    speed is measured over windows of ``m`` samples (``W = m dt``), as many as
    :func:`_track_speed` uses to keep the tracker's noise small, as the sum of the two
    half-window chords over ``W`` (so that a corner costs the window less than its
    chord; along the walk, the middle sample's noise cancels from the sum). The log of
    that speed, ``y_j``, is ``log v_i + (average of u over the window) + noise``. Its
    semivariogram within tracks, ``gamma(L) = E (y_{j+L} - y_j)^2 / 2`` at lags ``L > W``
    (windows sharing no sample: their noise is independent), needs no person's mean (the
    between-person speed drops out of the differences) and is, to first order in the
    noise,

    ``gamma(L) = n0 + sigma^2 (g0(T) - h(L; T))``  (:func:`_ou_window_terms`),

    ``n0 = 2 s^2 / (W v_i)^2`` the noise of a window's log speed (``s`` the tracker's
    position sd, :func:`~are_stats.fitting.tracker_noise`; the along-walk noise of the
    two end samples), averaged over the pairs. So the noise is not made small by the
    windows only: its known moment is subtracted (a moment correction), and the windows
    keep it from dominating. ``sigma^2`` is then a weighted least-squares line through
    the pooled semivariogram (weights: the pairs at each lag) for each ``T`` of a grid
    (``dt / 2`` to 300 s, 1% apart), and ``T`` the one of least residual; where ``T`` is
    not identified (longer than half the longest lag: :func:`_ou_fit`) the variation
    reads NaN, and 0 where it is shorter than half the window (white). Lags run up to
    :data:`VARIATION_LAG` (s). Windows whose speed is not within a factor
    :data:`VARIATION_CLIP` of the track's are left out (stops and bursts are not the
    pace's drift), and so are windows with someone within :data:`VARIATION_ALONE` of the
    walker at any of their samples (``crowded``): there the speed changes are the
    interaction's, which generation adds by itself. Turns that remain inside a half
    window read as a slower window: real logs with many corners overstate ``sigma``
    somewhat.

    Parameters
    ----------
    tracks : list of ((n_k,) float, (n_k, 2) float)
        Each walking track's sorted times (s) and positions (m).
    speeds : (n_tracks,) float
        Each track's walking speed (m/s, :func:`_track_speed`).
    noise : float
        Sd (m) of the position noise per coordinate.
    crowded : list of (n_k,) bool, optional
        Per track, its samples with somebody else near (:func:`_crowded`); default none.

    Returns
    -------
    dict
        ``speed_within_sd`` (``sigma``, log units; 0 when the variogram shows no lasting
        variation, NaN when it is not identified: ``T`` past half the longest lag, or no
        track long enough), ``speed_within_time`` (``T``, s; NaN with ``sigma`` 0 or NaN),
        and their bootstrap standard errors over the tracks, ``speed_within_sd_se`` and
        ``speed_within_time_se`` (:func:`_within_variation`).
    """
    return _within_variation(tracks, speeds, noise, crowded)["speed"]


def _heading_variation(
    tracks: list[tuple[np.ndarray, np.ndarray]],
    speeds: np.ndarray,
    noise: float,
    crowded: list[np.ndarray] | None = None,
    route_map: tuple[np.ndarray, npt.ArrayLike, float] | None = None,
    seed: int | Sequence[int] = 0,
) -> dict[str, float]:
    """The within-person variation of the walking heading: a stationary Ornstein-Uhlenbeck
    process of the heading's deviation from the route's direction (sd and correlation
    time), pooled over a class's walkers.

    Model: person ``i`` walks towards the next corner of its route with its heading
    turned by ``theta_i(t)`` (rad), a stationary OU process of sd ``sigma`` and
    correlation time ``T``, independent across people and of the pace (generation:
    :func:`~are_stats.behaviour.social_force_tracks`' ``heading_variation``). The
    deviation is bounded (its sd) because people keep aiming at where they go: a heading
    *rate* noise, a random walk of the heading, would carry them ever further off their
    routes, and a log's straightness (about 0.97 on real crossings) says they are not.

    Estimator (issue 26: detrended by the route). Each track's route is rebuilt from the
    track itself (:func:`_route_corners`): its positions string-pulled over the map
    (``route_map``; the corners that walls force), plus the corners of its own path that
    stand more than :data:`ROUTE_TOLERANCE` off a straight line (turns in the open, which
    no map explains). With the same resampling and windows as :func:`_speed_variation`
    (crowded and stopped windows left out), each window's residual is the direction of its
    chord (its two end samples) minus the bearing from the chord's middle to the route's
    next corner: ``r_j = (average of theta over the window) + noise``, the wander itself,
    where the route's direction is gone (the heading's variogram used to keep rising at
    the walks' long lags, where the route bends, and a 2 s wander was identified on 4 of
    8 crossing logs; now 8 of 8: docs/src/behaviour.md).

    Why from the middle: a walker ``D`` from the corner and turned ``theta`` off it
    sweeps the bearing to it at ``d beta / dt = -v sin(theta) / D``, so over a window
    ``[0, W]`` the bearing is ``beta(s) = beta(0) - (v / D) int_0^s theta`` and the
    chord's direction ``beta(0) + (1 / W) int_0^W (theta(s) + beta(s) - beta(0)) ds``.
    Off the bearing at the window's start (the estimator until 2026-11-28) the residual
    is then ``r_j = theta_bar - (v / (D W)) int_0^W (W - s) theta(s) ds``, about
    ``theta_bar (1 - v W / (2 D))`` for a window short against ``T``: its variogram, and
    ``sigma^2``, read low by the mean of ``(1 - v W / (2 D))^2`` over the windows (a 5 cm
    log at 2.5 Hz, ``W = 1.2`` s, walkers of 20 s: 0.108 rad for 0.12; the noise-free
    one, ``W = 0.4`` s, 0.117). Off the bearing at the middle, ``s = W / 2``, the
    first-order term is ``-(v / (D W)) int_0^W (W / 2 - s) theta(s) ds``, which is 0 for
    a ``theta`` constant over the window and of order ``(v W / D) (W / T)`` otherwise
    (the same walkers: 0.120 rad; docs/src/behaviour.md). Windows whose middle is within
    :data:`ROUTE_NEAR` of the next corner (where the bearing turns fast) and residuals
    over :data:`HEADING_CLIP` (a corner missed) are left out. The semivariogram of the
    residuals within tracks is that of the speed's, ``n0 + sigma^2 (g0 - h(L))``
    (:func:`_ou_window_terms`), with the noise moment ``n0 = 2 s^2 / (W v_i)^2``: a chord
    of length ``W v_i`` whose ends are moved sideways by the tracker's noise (``s`` per
    coordinate) turns by ``(e_2 - e_1) / (W v_i)`` to first order (the middle's own noise
    turns the bearing by ``(e_1 + e_2) / (2 D)``, uncorrelated with the chord's turn: it
    adds ``s^2 / (2 D^2)``, a fraction ``(W v_i / (2 D))^2`` of ``n0``, at most 15% at
    the nearest windows of a 5 cm log at 2.5 Hz and well under 1% of ``sigma^2``:
    neglected; from the window's start, ``e_1`` turned both alike). Each lag's
    semivariogram is the median of the squared differences over ``2`` :data:`MEDIAN_CHI2_1`
    (robust to the few windows a missed corner turns); the moment is subtracted and
    ``sigma``, ``T`` fitted as for the speed (:func:`_ou_fit`), with bootstrap standard
    errors (:func:`_within_variation`).

    Parameters
    ----------
    tracks, speeds, noise, crowded
        As :func:`_speed_variation`.
    route_map : ((H, W) bool, (2,) float, float), optional
        The map's free cells, origin (m) and resolution (m) the routes are string-pulled
        over; default none (an open area: only the tracks' own corners).
    seed
        Seed of the bootstrap (:func:`numpy.random.default_rng`).

    Returns
    -------
    dict
        ``heading_within_sd`` (``sigma``, rad; 0 when the variogram shows no lasting
        variation, NaN when it is not identified), ``heading_within_time`` (``T``, s; NaN
        with ``sigma`` 0 or NaN), and their bootstrap standard errors
        ``heading_within_sd_se``, ``heading_within_time_se`` (NaN where not identified).
    """
    return _within_variation(tracks, speeds, noise, crowded, route_map, seed)["heading"]


#: The median of a chi-square of one degree of freedom (of a standard normal's square).
MEDIAN_CHI2_1 = 0.454936423119572
#: Heading residuals (rad) off the route's next corner larger than this are a corner the
#: route missed, not the wander around it (:func:`_heading_variation`).
HEADING_CLIP = 1.0
#: A track's own corner (m): a point of its path this far off the straight line between
#: its neighbouring corners is one (:func:`_route_corners`). An aiming walker with the
#: crossings' wander (0.12 rad over 2 s at 1.2 m/s) strays about 0.3 m (sd) off its line.
ROUTE_TOLERANCE = 3.0
#: Windows that start within this distance (m) of their route's next corner are left out
#: of the heading's wander (the bearing to the corner turns fast there).
ROUTE_NEAR = 2.0
#: Bootstrap replicates (over tracks) of the within-person variations' standard errors.
VARIATION_BOOTSTRAP = 100
#: A within-person correlation time is identified from at least this fraction of the
#: window up to the longest lag over this factor (:func:`_ou_fit`): shorter, the
#: variation reads 0 (no lasting variation); longer, NaN (not identified).
IDENTIFIED = (0.5, 2.0)


def _route_corners(
    points: list[np.ndarray], route_map: tuple[np.ndarray, npt.ArrayLike, float] | None
) -> list[np.ndarray]:
    """Per track ``(n_k, 2)`` positions (m), the indices of its route's corners, first and
    last sample included, sorted: the track string-pulled over the map
    (:func:`~are_stats.behaviour.string_pull_many`, where ``route_map = (free, origin,
    resolution)`` is given; one point per :data:`ROUTE_NEAR` / 4 of its path) and the
    points of its own path that a Douglas-Peucker simplification with
    :data:`ROUTE_TOLERANCE` keeps."""
    pulled: list[np.ndarray | None] = [None] * len(points)
    # the points pulled: one per ROUTE_NEAR / 4 of the path (a corner is placed to that)
    thin = []
    for p in points:
        walked = np.r_[0.0, np.cumsum(np.hypot(*np.diff(p, axis=0).T))]
        step = np.floor(walked / (ROUTE_NEAR / 4.0))
        thin.append(np.flatnonzero(np.r_[True, step[1:] > step[:-1]] | (walked == walked[-1])))
    if route_map is not None:
        free, origin, res = route_map
        o = np.asarray(origin, float)[:2]
        pulled = string_pull_many(
            [p[k] for p, k in zip(points, thin, strict=True)],
            free,
            (float(o[0]), float(o[1])),
            float(res),
        )
    out = []
    for p, v, k in zip(points, pulled, thin, strict=True):
        keep = {0, len(p) - 1}
        if v is not None:
            at = 0
            for corner in v:  # the kept vertices are points of the thinned track, in order
                at += int(np.argmin(np.hypot(*(p[k[at:]] - corner).T)))
                keep.add(int(k[at]))
        stack = [(0, len(p) - 1)]
        while stack:
            a, b = stack.pop()
            if b <= a + 1:
                continue
            d = p[b] - p[a]
            q = p[a + 1 : b] - p[a]
            span = math.hypot(*d)
            off = np.abs(q[:, 0] * d[1] - q[:, 1] * d[0]) / span if span > 0 else np.hypot(*q.T)
            k = int(np.argmax(off))
            if off[k] > ROUTE_TOLERANCE:
                keep.add(a + 1 + k)
                stack += [(a, a + 1 + k), (a + 1 + k, b)]
        out.append(np.array(sorted(keep), np.int64))
    return out


@functools.lru_cache(maxsize=16)
def _ou_terms_grid(period: float, window: float, lag_s: tuple[float, ...]) -> tuple:
    """The correlation-time grid of :func:`_ou_fit` (``period / 2`` to 300 s, 1% apart)
    and the OU window terms (:func:`_ou_window_terms`) at ``lag_s`` for each: ``(taus,
    (n_tau, n_lag) terms)``."""
    taus = np.geomspace(period / 2.0, 300.0, 1 + math.ceil(math.log(600.0 / period) / 0.01))
    lags = np.asarray(lag_s, float)
    return taus, np.stack([_ou_window_terms(float(tau), window, lags) for tau in taus])


def _ou_fit(
    gamma: np.ndarray,
    w: np.ndarray,
    lag_s: np.ndarray,
    period: float,
    window: float,
) -> tuple[float, float]:
    """``(sigma^2, T)`` of the OU window semivariogram :func:`_ou_window_terms` fitted to
    ``gamma`` at the lags ``lag_s`` (s) by weighted least squares (weights ``w``):
    ``sigma^2`` in closed form for each ``T`` of a grid (``period / 2`` to 300 s, 1%
    apart), ``T`` the one of least residual. ``sigma^2`` is 0 where the variogram shows
    no variation (``T`` then NaN), and so it is where ``T`` is shorter than half the
    window (:data:`IDENTIFIED`: the excess is independent between windows, white: a
    variation that fast is averaged out within the window, and what is read is noise or
    the interaction's jolts, not a pace that lasts). Where ``T`` is longer than half the
    longest lag (an OU's variogram is within 14% of its sill by ``2 T``: one still rising
    at the longest lag is the route's own turning or speed changes, or the
    interaction's, not a variation around the route) the variation is not identified:
    ``(NaN, NaN)``, told apart from none (issue 26)."""
    taus, k = _ou_terms_grid(float(period), float(window), tuple(np.asarray(lag_s, float)))
    gamma, w = np.asarray(gamma, float), np.asarray(w, float)
    var = np.maximum(0.0, (k * (w * gamma)).sum(axis=1) / (k * (w * k)).sum(axis=1))
    sse = ((gamma - var[:, None] * k) ** 2 * w).sum(axis=1)
    best = int(np.argmin(sse))
    v, tau = float(var[best]), float(taus[best])
    lo, hi = IDENTIFIED
    if tau > float(np.max(lag_s)) / hi:
        return (math.nan, math.nan)
    if tau < lo * window or v <= 0.0:
        return (0.0, math.nan)
    return (v, tau)


def _within_variation(
    tracks: list[tuple[np.ndarray, np.ndarray]],
    speeds: np.ndarray,
    noise: float,
    crowded: list[np.ndarray] | None = None,
    route_map: tuple[np.ndarray, npt.ArrayLike, float] | None = None,
    seed: int | Sequence[int] = 0,
    n_boot: int = VARIATION_BOOTSTRAP,
) -> dict[str, dict[str, float]]:
    """Both within-person variations in one pass over the tracks: ``{"speed": ..,
    "heading": ..}`` as :func:`_speed_variation` and :func:`_heading_variation` return
    them (the windows, their noise moment and the OU fit are shared).

    Standard errors: ``n_boot`` bootstrap replicates over the tracks (drawn with
    ``seed``; each replicate the whole estimator, its noise moment and median included,
    on tracks drawn with replacement), the sd of the replicates' ``sigma`` and ``T``
    over those that identify it (a ``sigma`` of 0 counts, a NaN does not); NaN where the
    estimate itself is not identified or fewer than 10 replicates are."""
    names = {"speed": "speed_within", "heading": "heading_within"}
    nan = {
        k: {f"{v}{s}": math.nan for s in ("_sd", "_time", "_sd_se", "_time_se")}
        for k, v in names.items()
    }
    steps = [np.diff(t) for t, _ in tracks]
    steps = np.concatenate(steps) if steps else np.zeros(0)
    steps = steps[steps > 0]
    if steps.size == 0:
        return nan
    period = float(np.median(steps))
    m = max(1, math.ceil(NOISE_WINDOW * noise / (SLOW_WALK * period) - 1e-9))
    half = m // 2
    window = m * period
    max_lag = math.ceil(VARIATION_LAG / period)
    n_samples = sum(
        int((t[-1] - t[0]) / period) + 1 for t, _ in tracks if t.size
    )  # resampled, each track once
    lags = np.unique(np.geomspace(m + 1, max(m + 1, max_lag), 40).round().astype(np.int64))
    check_memory(
        8.0 * (8.0 + 2.0 * lags.size) * n_samples,
        f"the within-person paces of {len(tracks)} tracks",
    )
    near_of = [None] * len(tracks) if crowded is None else crowded
    used = [
        i
        for i, ((t, _), v) in enumerate(zip(tracks, speeds, strict=True))
        if np.isfinite(v)
        and v > 0
        and t.size >= 2
        and int((t[-1] - t[0]) / period + 1e-9) + 1 > m + lags[0]
    ]
    resampled = []
    for i in used:
        t, xy = tracks[i]
        tt = t[0] + period * np.arange(int((t[-1] - t[0]) / period + 1e-9) + 1)
        p = np.column_stack([np.interp(tt, t, xy[:, 0]), np.interp(tt, t, xy[:, 1])])
        resampled.append((tt, p))
    corners = _route_corners([p for _, p in resampled], route_map)
    n_tr = len(used)
    # per track and lag: the pace's half squared differences, pairs and noise moments;
    # the heading's squared differences (for their median), their track, pairs and moments
    sq = np.zeros((n_tr, lags.size))
    cnt = {k: np.zeros((n_tr, lags.size)) for k in names}
    n0s = np.zeros(n_tr)
    turns: list[list[np.ndarray]] = [[] for _ in lags]
    owner: list[list[np.ndarray]] = [[] for _ in lags]
    for j, (i, (tt, p), corner) in enumerate(zip(used, resampled, corners, strict=True)):
        t, v, near = tracks[i][0], float(speeds[i]), near_of[i]
        if half:
            chord = np.hypot(*(p[half : -m + half or None] - p[:-m]).T) + np.hypot(
                *(p[m:] - p[half : -m + half or None]).T
            )
        else:
            chord = np.hypot(*(p[m:] - p[:-m]).T)
        speed = chord / window
        # stops and bursts are not the pace's drift: their windows are left out
        y = np.where(
            np.abs(np.log(np.maximum(speed, 1e-12) / v)) <= math.log(VARIATION_CLIP),
            np.log(np.maximum(speed, 1e-12)),
            np.nan,
        )
        if near is not None and np.any(near):
            # a window with somebody near at any of its samples (the log's nearest)
            busy = np.interp(tt, t, np.asarray(near, float)) > 0
            c = np.r_[0, np.cumsum(busy)]
            y[(c[m + 1 :] - c[: -m - 1]) > 0] = np.nan
        # the heading of the same windows (their chord's) off the bearing from the chord's
        # middle to the route's next corner (after the window's first sample), where their
        # speed is read: from the middle, the bearing's sweep over the window cancels
        nxt = corner[
            np.minimum(np.searchsorted(corner, np.arange(y.size), "right"), corner.size - 1)
        ]
        to = p[nxt] - 0.5 * (p[:-m] + p[m:])
        d_xy = p[m:] - p[:-m]
        r = np.arctan2(d_xy[:, 1], d_xy[:, 0]) - np.arctan2(to[:, 1], to[:, 0])
        r = np.mod(r + math.pi, 2.0 * math.pi) - math.pi
        keep = np.isfinite(y) & (np.hypot(*to.T) >= ROUTE_NEAR) & (np.abs(r) <= HEADING_CLIP)
        r = np.where(keep, r, np.nan)
        n0s[j] = 2.0 * noise**2 / (window * v) ** 2
        for k, lag in enumerate(lags):
            if lag >= y.size:
                break
            d = y[lag:] - y[:-lag]
            d = d[np.isfinite(d)]
            sq[j, k] = 0.5 * float(d @ d)
            cnt["speed"][j, k] = d.size
            d = r[lag:] - r[:-lag]
            d = d[np.isfinite(d)]
            turns[k].append(d * d)
            owner[k].append(np.full(d.size, j))
            cnt["heading"][j, k] = d.size
    # each lag's squared heading differences sorted once, with their tracks: a
    # replicate's median is then a weighted one (weights: how often it drew each track)
    turn, whose = [], []
    for d2, w in zip(turns, owner, strict=True):
        v, o = (np.concatenate(d2), np.concatenate(w)) if d2 else (np.zeros(0), np.zeros(0, int))
        order = np.argsort(v, kind="stable")
        turn.append(v[order])
        whose.append(o[order])
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, n_tr, (n_boot if n_tr > 1 else 0, n_tr))
    counts = np.stack([np.bincount(d, minlength=n_tr) for d in draws]) if len(draws) else None

    def medians(k: int) -> np.ndarray:
        """(n_boot,) the medians of lag ``k``'s squared differences, each replicate's
        values repeated as often as it drew their track (numpy's median of them). The
        cumulative counts run over the central 40% of the values only (a replicate's
        median falls there unless the tracks are very few; those run over all)."""
        v, who = turn[k], whose[k]
        a, b = int(0.3 * v.size), max(int(0.7 * v.size), int(0.3 * v.size) + 1)
        below = np.bincount(who[:a], minlength=n_tr).astype(float)
        out = np.empty(len(counts))
        for rows in np.array_split(np.arange(len(counts)), max(1, len(counts) // 10)):
            block = counts[rows]
            ranks = [(n - 1) // 2 for n in [block @ cnt["heading"][:, k]]]
            ranks.append(ranks[0] + (block @ cnt["heading"][:, k] + 1) % 2)  # n // 2
            for lo_, hi_ in ((a, b), (0, v.size)):  # the central values, else all
                first = block @ below if lo_ else np.zeros(len(rows))  # counts before
                cw = first[:, None] + np.cumsum(block[:, who[lo_:hi_]], axis=1)
                if lo_ == 0 or all(((first <= r) & (cw[:, -1] > r)).all() for r in ranks):
                    at = [
                        lo_ + np.minimum((cw <= r[:, None]).sum(axis=1), hi_ - lo_ - 1)
                        for r in ranks
                    ]
                    out[rows] = 0.5 * (v[at[0]] + v[at[1]])
                    break
        return out

    def estimate(c: np.ndarray, meds: dict[int, np.ndarray] | None) -> dict:
        """``(sigma^2, T)`` of both with track weights ``c``, the heading's medians
        ``meds`` (None: each track once, numpy's median)."""
        est = {}
        for what in names:
            pairs = c @ cnt[what]
            use = pairs > 0
            if not use.any():
                est[what] = (math.nan, math.nan)
                continue
            if what == "speed":
                raw = (c @ sq)[use] / pairs[use]
            else:
                # the median of a Gaussian's square is 0.4549 times its variance: robust
                # to the few windows per track that a missed corner turns
                raw = np.array(
                    [
                        float(np.median(turn[k])) if meds is None else float(meds[k])
                        for k in np.flatnonzero(use)
                    ]
                ) / (2.0 * MEDIAN_CHI2_1)
            gamma = raw - (c @ (cnt[what] * n0s[:, None]))[use] / pairs[use]
            est[what] = _ou_fit(gamma, pairs[use], lags[use] * period, period, window)
        return est

    point = estimate(np.ones(n_tr), None)
    reps = []
    if counts is not None:
        meds = {k: medians(k) for k in range(lags.size) if turn[k].size}
        for b, c in enumerate(counts):
            reps.append(estimate(c.astype(float), {k: v[b] for k, v in meds.items()}))
    out = {}
    for what, name in names.items():
        var, tau = point[what]
        boot = np.array([r[what] for r in reps]).reshape(-1, 2)
        ok = np.isfinite(boot[:, 0])
        sd_se = time_se = math.nan
        if math.isfinite(var) and ok.sum() >= 10:
            sd_se = float(np.std(np.sqrt(boot[ok, 0]), ddof=1))
            times = boot[np.isfinite(boot[:, 1]), 1]
            time_se = float(np.std(times, ddof=1)) if times.size >= 10 else math.nan
        out[what] = {
            f"{name}_sd": math.sqrt(var),
            f"{name}_time": tau,
            f"{name}_sd_se": sd_se,
            f"{name}_time_se": time_se if var > 0 else math.nan,
        }
    return out


def _line_steps(r0: np.ndarray, c0: np.ndarray, r1: np.ndarray, c1: np.ndarray) -> tuple:
    """The 4-connected cells of every straight move ``(r0, c0) -> (r1, c1)`` ((K,) int):
    the start excluded, the end included (a move of none: its end once), each step along
    the axis that lags the line most (a row step first on a tie). Returns the cells
    ``(rows, cols)`` of all moves in order and the number ``(K,)`` of each."""
    dr, dc = r1 - r0, c1 - c0
    nr, nc = np.abs(dr), np.abs(dc)
    count = np.maximum(nr + nc, 1)
    first = np.r_[0, np.cumsum(count)[:-1]]
    move = np.repeat(np.arange(r0.size), count)
    at = np.arange(move.size) - first[move]  # the step's place in its move
    # step i of the rows lands at (i + 0.5) / nr of the line, step j of the columns at
    # (j + 0.5) / nc: a move's steps in that order, the rows' first on a tie
    is_row = at < nr[move]
    i = np.where(is_row, at, at - nr[move])
    key = (i + 0.5) / np.where(is_row, nr[move], np.maximum(nc[move], 1))
    order = np.lexsort((~is_row, key, move))
    is_row = is_row[order]
    done = np.cumsum(is_row)
    rows_done = done - np.r_[0, done][first][move]
    cols_done = (at + 1) - rows_done
    none = (nr + nc == 0)[move]  # a stay: its one cell, the end
    rows = np.where(none, r1[move], r0[move] + np.sign(dr)[move] * rows_done)
    cols = np.where(none, c1[move], c0[move] + np.sign(dc)[move] * cols_done)
    return rows, cols, count


def discretise_tracks(
    tracks: pd.DataFrame,
    free: npt.ArrayLike,
    cell: float,
    origin: npt.ArrayLike,
    dt: float,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Continuous tracks -> cell paths with one move (or none) per epoch.

    Parameters
    ----------
    tracks : pandas.DataFrame
        Columns ``id, t, x, y`` (world metres, seconds).
    free : (H, W) bool
        Free cells of the MDP grid (cells of ``cell`` metres from ``origin``).
    cell : float
        Cell side (m).
    origin : (2,) float
        World ``(x, y)`` of the corner of cell ``(0, 0)``.
    dt : float
        Epoch (s): positions are interpolated at ``t_0 + k dt`` and at the track's end.

    Returns
    -------
    paths : list of (T_n + 1, 2) int
        Cells ``(row, col)`` per epoch, consecutive cells equal or 4-adjacent; the goal is
        the last cell, visited only there. Tracks of fewer than two distinct cells give
        one-cell paths.
    ids : (N,) array
        Track ids in the order of ``paths``.
    """
    free = np.asarray(free, bool)
    h, w = free.shape
    cell = float(check_positive("cell", cell))
    dt = float(check_positive("dt", dt))
    o = np.asarray(origin, float)
    _, (ri, ci) = ndimage.distance_transform_edt(~free, return_indices=True)
    # every track's rows at once (issue 29: a table and a sort per track were most of
    # the time): grouped by id in groupby's order, each by time, stable
    codes, uniques = pd.factorize(tracks["id"].to_numpy(), sort=True)
    t_all = tracks["t"].to_numpy(float)
    xy_all = tracks[["x", "y"]].to_numpy(float)
    order = np.lexsort((t_all, codes))
    order = order[codes[order] >= 0]  # no id: no track (as groupby)
    if order.size == 0:
        return [], np.asarray([])
    codes, t_all, xy_all = codes[order], t_all[order], xy_all[order]
    n = len(uniques)
    start = np.searchsorted(codes, np.arange(n))
    stop = np.r_[start[1:], codes.size]
    t0, t1 = t_all[start], t_all[stop - 1]
    # the epochs t0 + k dt of each track, and its end where that falls between epochs
    n_ep = np.floor((t1 - t0) / dt + 1e-9).astype(np.int64)
    tail = t1 - (t0 + dt * n_ep) > 1e-9 * np.maximum(1.0, np.abs(t1))
    size = n_ep + 1 + tail
    owner = np.repeat(np.arange(n), size)
    bound = np.r_[0, np.cumsum(size)]
    k = np.arange(owner.size) - bound[owner]
    te = t0[owner] + dt * k
    te[bound[1:][tail] - 1] = t1[tail]
    x, y = np.empty(te.size), np.empty(te.size)
    for j in range(n):  # np.interp per track: a few microseconds each
        e, a, b = slice(bound[j], bound[j + 1]), start[j], stop[j]
        x[e] = np.interp(te[e], t_all[a:b], xy_all[a:b, 0])
        y[e] = np.interp(te[e], t_all[a:b], xy_all[a:b, 1])
    col = np.clip(np.floor((x - o[0]) / cell), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor((y - o[1]) / cell), 0, h - 1).astype(np.int64)
    row, col = ri[row, col], ci[row, col]
    # after a track's first cell, the cells of the straight move from each epoch's cell to
    # the next's (_line_steps)
    later = k > 0
    prev = np.flatnonzero(later) - 1
    rows, cols, count = _line_steps(row[prev], col[prev], row[later], col[later])
    per_track = np.bincount(owner[later], weights=count, minlength=n).astype(np.int64)
    begin = np.r_[0, np.cumsum(per_track + 1)[:-1]]
    end = begin + per_track + 1
    cells = np.empty((int(end[-1]), 2), np.int64)
    cells[begin] = np.column_stack([row[bound[:-1]], col[bound[:-1]]])
    body = np.ones(cells.shape[0], bool)
    body[begin] = False
    cells[body] = np.column_stack([rows, cols])
    # each path up to its first visit of its last cell (the goal)
    track = np.repeat(np.arange(n), end - begin)
    goal = (cells == cells[end - 1][track]).all(axis=1)
    first_goal = np.minimum.reduceat(np.where(goal, np.arange(track.size), track.size), begin)
    paths = [cells[a : g + 1] for a, g in zip(begin.tolist(), first_goal.tolist(), strict=True)]
    return paths, np.asarray(list(uniques))


def _lognormal(v: np.ndarray) -> tuple[float, float]:
    """A lognormal law ``(mu, sigma)`` (log units) of the positive speeds ``v``: ``mu`` the
    log of their median, ``sigma`` the sd of their logs.

    The law's median ``exp(mu)`` is the generated crowd's median speed, so ``mu`` is the
    sample median of the log speeds (the log of the median speed) rather than their mean:
    both estimate ``mu`` when the speeds are lognormal (the median with Monte Carlo sd
    ``sqrt(pi / 2) sigma / sqrt(n)``, 1.25 times the mean's), but walking speeds are
    often closer to normal (Weidmann's ``N(1.34, 0.26)`` m/s), and for normal speeds
    ``N(m, s^2)`` the mean log is ``log m - s^2 / (2 m^2) - 3 s^4 / (4 m^4) - ..``: 1.2%
    below the median at ``m = 1.3``, ``s = 0.2``, a crowd generated that much too slow.
    The median of the logs is ``log m`` for any law (the log keeps the order)."""
    lv = np.log(v[v > 0])
    if lv.size == 0:
        return math.nan, math.nan
    return float(np.median(lv)), float(lv.std()) if lv.size > 1 else 0.0


def _speed_law(speeds: np.ndarray, run_speed: float, name: str) -> dict[str, float]:
    """The between-person speed laws of a class from its tracks' speeds.

    Parameters
    ----------
    speeds : (n_tracks,) float
        Each track's walking speed (m/s, :func:`_track_speed`; 0: stands, NaN: unknown).
    run_speed : float
        Tracks faster than this (m/s) run.
    name : str
        The class (for the error).

    Returns
    -------
    dict
        ``speed_mu, speed_sigma``: the lognormal law (log m/s) of the walkers' speeds,
        ``mu`` the log of their median (:func:`_lognormal`); ``run_fraction`` (runners
        over tracks); ``run_mu, run_sigma``: the runners' law (NaN with fewer than two
        runners).

    Raises
    ------
    NoWalkersError
        When no track of the class walks.
    """
    runner = speeds > float(run_speed)
    walk = np.isfinite(speeds) & (speeds > 0) & ~runner
    if not walk.any():
        raise NoWalkersError(f"tracks: expected moving walkers in class {name!r}, got none")
    mu, sigma = _lognormal(speeds[walk])
    rmu, rsig = _lognormal(speeds[runner]) if runner.sum() >= 2 else (math.nan, math.nan)
    return {
        "speed_mu": mu,
        "speed_sigma": sigma,
        "run_fraction": float(runner.mean()),
        "run_mu": rmu,
        "run_sigma": rsig,
    }


def _bandwidth(xy: np.ndarray, floor: float) -> float:
    """Median distance to the ``k``-th nearest other point (``k ~ sqrt(n) / 2``), at least
    ``floor``: local, so that entries at different doors do not mix."""
    n = len(xy)
    if n < 2:
        return floor
    k = max(1, round(math.sqrt(n) / 2))
    d = np.sqrt(((xy[:, None] - xy[None]) ** 2).sum(axis=-1))
    kth = np.sort(d, axis=1)[:, min(k, n - 1)]
    return max(floor, float(np.median(kth)))


class _LikelihoodData(NamedTuple):
    """The data of the fit's log-likelihood (:func:`_loglik`): arguments, not constants, of
    its compiled program (:func:`_gradient_value_epochs`: gradient, value and the soft
    solve's epochs; the Hessian differences it at fixed epochs), padded
    to shape buckets (:func:`_bucket`) so that another fit on the same grid (the report's
    held-out fit, a refit) runs the programs already compiled.

    Attributes
    ----------
    ok : (4, 2, H, W) bool
        Free paths of the grid (:func:`~are_stats.behaviour.path_free`).
    keep : (G, H, W) bool
        Non-absorbing cells per goal; the padding goals repeat the last goal.
    bonus : (G, H, W) float
        ``goal_reward`` on each goal's cell.
    tol_mask : (G, H, W) bool
        Cells on which the soft solve's convergence is measured.
    goal_index : (N,) int
        Each track's goal; the padding tracks have goal 0 and no move.
    rows, cols, move : (N, T) int
        :class:`~are_stats.behaviour.MoveObservations`' steps, padded with ``move = -1``
        (no step: a factor of exactly 1 in the likelihood).
    n_epochs : () int32
        The soft solve's epoch cap (data: with ``tol`` it only bounds the loop).
    step_cost, time_cost : () float
        Rewards of the soft MDP.
    phi : (F, H, W) float or None
        Reward features (``None``: no cell reward).

    The arrays are NumPy's, of the computation's dtypes, and stay on the host: the
    compiled program takes them as arguments, each call placing them (split by goals
    across the devices where there are several) as it needs. JAX arrays here would each
    have compiled a program to be made (``jnp.asarray`` of a float64 table to float32:
    ``convert_element_type``) and two more to be split across the devices
    (``_multi_slice``; issue 29).
    """

    ok: np.ndarray
    keep: np.ndarray
    bonus: np.ndarray
    tol_mask: np.ndarray
    goal_index: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    move: np.ndarray
    n_epochs: np.ndarray
    step_cost: np.ndarray
    time_cost: np.ndarray
    phi: np.ndarray | None


def _bucket(n: int, multiple: int = 1) -> int:
    """The padded size of a dimension of ``n >= 1``: the next power of two, rounded up to a
    multiple of ``multiple`` (few shapes, so few compiled programs; at most twice the
    work)."""
    size = 1 << max(0, int(n) - 1).bit_length()
    return -(-size // multiple) * multiple


def _loglik(
    theta: jax.Array, data: _LikelihoodData, tol: float | jax.Array, n_devices: int = 1
) -> jax.Array:
    """Log-likelihood at ``theta = (log beta, logit slip, w_1, .., w_F)`` of the moves in
    ``data`` (``F`` features ``data.phi``; without them ``theta`` has two entries and the
    cell reward is 0); the soft solve stops at ``tol`` (a float or a traced scalar; a
    negative ``tol`` runs ``data.n_epochs - 1`` epochs). With ``n_devices > 1`` the goals
    are split across that many local devices (results identical to one device)."""
    return _loglik_epochs(theta, data, tol, n_devices)[0]


def _loglik_epochs(
    theta: jax.Array, data: _LikelihoodData, tol: float | jax.Array, n_devices: int = 1
) -> tuple[jax.Array, jax.Array]:
    """:func:`_loglik` and the epochs its soft solve iterated (``()`` int; the solve with
    ``n_epochs = epochs + 1`` and ``tol < 0`` is the same, epoch for epoch)."""
    beta = jnp.exp(theta[0])
    slip = jax.nn.sigmoid(theta[1])
    reward = 0.0 if data.phi is None else jnp.tensordot(theta[2:], data.phi, axes=1)
    opts: _SolveOptions = dict(
        n_epochs=data.n_epochs, step_cost=data.step_cost, time_cost=data.time_cost, tol=tol
    )
    if n_devices < 2:
        sol = soft_backward_induction(
            data.ok,
            data.keep,
            data.bonus,
            beta,
            slip,
            tol_mask=data.tol_mask,
            cell_reward=reward,
            with_epochs=True,
            **opts,
        )
        policy, epochs = sol.policy, sol.epochs
    else:
        policy, epochs = _sharded_policy(
            data.ok,
            data.keep,
            data.bonus,
            beta,
            slip,
            data.tol_mask,
            n_devices,
            opts,
            jnp.asarray(reward, beta.dtype),
        )
    obs = (data.goal_index, data.rows, data.cols, data.move)
    return moves_log_likelihood(policy, data.ok, slip, obs), epochs


class _SolveOptions(TypedDict):
    """The numbers :func:`_loglik_epochs` passes to
    :func:`~are_stats.behaviour.soft_backward_induction`: ``()`` arrays of
    :class:`_LikelihoodData` (NumPy's, or traced inside the compiled program) and the
    stopping tolerance (a float or a traced scalar)."""

    n_epochs: np.ndarray | jax.Array
    step_cost: np.ndarray | jax.Array
    time_cost: np.ndarray | jax.Array
    tol: float | jax.Array


def _sharded_policy(
    ok: jax.Array,
    keep: jax.Array,
    bonus: jax.Array,
    beta: jax.Array,
    slip: jax.Array,
    tol_mask: jax.Array | None,
    n_devices: int,
    opts: _SolveOptions,
    reward: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """The soft policy ``(G, 4, 5, H, W)`` with the goals split across ``n_devices`` and the
    epochs the solve iterated (``()`` int) (``reward``: the cell reward, a scalar or
    ``(H, W)``, the same for every goal; ``opts``:
    :func:`~are_stats.behaviour.soft_backward_induction`'s ``n_epochs``, ``step_cost``,
    ``time_cost`` and ``tol``, numbers or traced scalars).

    The goals are padded to a multiple of ``n_devices`` by repeating the last one (a copy
    changes by exactly as much per epoch, so the shared stopping rule is unaffected); every
    shard stops at the epoch the whole batch would (``axis_name``).
    """
    g = keep.shape[0]
    pad = -g % n_devices
    mask = jnp.ones(keep.shape, bool) if tol_mask is None else tol_mask

    def padded(x: jax.Array) -> jax.Array:
        return jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) if pad else x

    mesh = Mesh(np.array(jax.local_devices()[:n_devices]), ("g",))
    # the traced numbers enter as replicated arguments (not closed over by the shards)
    numbers = tuple(jnp.asarray(opts[k]) for k in ("n_epochs", "step_cost", "time_cost", "tol"))

    def solve(
        keep_s: jax.Array,
        bonus_s: jax.Array,
        mask_s: jax.Array,
        ok_: jax.Array,
        beta_: jax.Array,
        slip_: jax.Array,
        reward_: jax.Array,
        k_: jax.Array,
        sc_: jax.Array,
        tc_: jax.Array,
        tol_: jax.Array,
    ) -> tuple[jax.Array, jax.Array]:
        sol = soft_backward_induction(
            ok_,
            keep_s,
            bonus_s,
            beta_,
            slip_,
            tol_mask=mask_s,
            axis_name="g",
            cell_reward=reward_,
            n_epochs=k_,
            step_cost=sc_,
            time_cost=tc_,
            tol=tol_,
            with_epochs=True,
        )
        return sol.policy, sol.epochs  # every shard stops at the same epoch

    split = jax.shard_map(
        solve,
        mesh=mesh,
        in_specs=(P("g"), P("g"), P("g")) + (P(),) * 8,
        out_specs=(P("g"), P()),
        check_vma=False,
    )
    policy, epochs = split(
        padded(keep), padded(bonus), padded(mask), ok, beta, slip, reward, *numbers
    )
    return policy[:g], epochs


def behaviour_log_likelihood(
    paths: list[np.ndarray],
    free: npt.ArrayLike,
    beta: float | jax.Array,
    slip: float | jax.Array,
    *,
    n_epochs: int | None = None,
    goal_reward: float = 1.0,
    step_cost: float = 1e-3,
    time_cost: float = 1.0,
    features: npt.ArrayLike | None = None,
    weights: npt.ArrayLike | None = None,
) -> tuple[jax.Array, int]:
    """Log-likelihood of cell paths under the stationary soft policy (differentiable).

    Parameters
    ----------
    paths : list of (T_n + 1, 2) int
        Cell paths (:func:`discretise_tracks`); the goal of each is its last cell.
    free : (H, W) bool
        Free cells.
    beta, slip : scalar (float or JAX tracer)
        Rationality and slip; the dtype of ``beta`` is the computation's.
    n_epochs : int or None
        Time-to-go ``K`` of the policy (default: 3 times the longest shortest path from a
        start to its goal, plus 20).
    goal_reward, step_cost, time_cost : float
        Rewards of the soft MDP.
    features : (F, H, W) float or None
        Reward features ``phi_k`` on the grid (``None``: no cell reward).
    weights : (F,) float or JAX tracer, or None
        Their weights ``w_k`` (reward per epoch, units of ``time_cost``): every epoch on a
        non-absorbing cell earns ``sum_k w_k phi_k(cell)``. Required with ``features``.

    Returns
    -------
    loglik : scalar
    n_epochs : int

    Raises
    ------
    ValueError
        On ``features`` that are not ``(F, H, W)`` on the grid, or weights that are not
        ``(F,)``.
    """
    free = np.asarray(free, bool)
    obs = move_observations(paths)
    if n_epochs is None:
        n_epochs = _n_epochs(free, paths, obs.goals)
    ok = jnp.asarray(path_free(~free))
    keep, bonus = _goal_masks(free, obs.goals, goal_reward)
    keep = jnp.asarray(keep)
    dtype = jnp.result_type(beta)
    reward: float | jax.Array = 0.0
    if features is not None:
        phi = np.asarray(features, float)
        if phi.ndim != 3 or phi.shape[1:] != free.shape:
            raise ValueError(
                f"features: expected an (F, {free.shape[0]}, {free.shape[1]}) array on the "
                f"grid, got {describe(phi)}"
            )
        if weights is None or jnp.shape(weights) != (phi.shape[0],):
            raise ValueError(
                f"weights: expected ({phi.shape[0]},) weights, one per feature, got "
                + ("None" if weights is None else f"shape {tuple(jnp.shape(weights))}")
            )
        reward = jnp.tensordot(jnp.asarray(weights, dtype), jnp.asarray(phi, dtype), axes=1)
    sol = soft_backward_induction(
        ok,
        keep,
        jnp.asarray(bonus, dtype),
        beta,
        jnp.asarray(slip, dtype),
        n_epochs=n_epochs,
        step_cost=step_cost,
        time_cost=time_cost,
        cell_reward=reward,
    )
    return moves_log_likelihood(sol.policy, ok, slip, obs), n_epochs


def _goal_masks(
    free: np.ndarray, goals: np.ndarray, goal_reward: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(keep (G, H, W) bool, bonus (G, H, W) float64)``: each goal's non-absorbing cells
    and ``goal_reward`` on its cell (NumPy arrays)."""
    g = len(goals)
    mask = np.zeros((g,) + free.shape, bool)
    mask[np.arange(g), goals[:, 0], goals[:, 1]] = True
    return free[None] & ~mask, np.where(mask, goal_reward, 0.0)


def _n_epochs(
    free: np.ndarray, paths: list[np.ndarray], goals: np.ndarray, factor: float = 3.0
) -> int:
    dist = grid_geodesic(free, goals)
    longest = 0.0
    index = {tuple(g): i for i, g in enumerate(goals.tolist())}
    for p in paths:
        if len(p) < 2:
            continue
        d = dist[index[tuple(p[-1].tolist())], p[0, 0], p[0, 1]]
        longest = max(longest, float(d) if np.isfinite(d) else len(p))
    return int(math.ceil(factor * longest)) + 20


def _feature_maps(
    features: str | Sequence[str] | Mapping[str, str | npt.ArrayLike] | None,
    free: np.ndarray,
    free_fine: np.ndarray,
    factor: int,
) -> tuple[tuple[str, ...], np.ndarray | None]:
    """Names and ``(F, H, W)`` maps on the MDP grid ``free`` of :func:`fit_behaviour`'s
    ``features`` (``None`` without features). ``factor``: map cells per MDP cell side."""
    if features is None:
        return (), None
    h, w = free.shape
    if isinstance(features, str):
        features = (features,)
    if isinstance(features, dict):
        items = list(features.items())
    elif isinstance(features, (list, tuple)):
        items = [(f, f) for f in features]
    else:
        raise ValueError(
            "features: expected a sequence of feature names or a mapping name -> (H, W) "
            f"array, got {type(features).__name__}"
        )
    names, maps = [], []
    for name, spec in items:
        if not isinstance(name, str) or not name:
            raise ValueError(f"features: expected non-empty string names, got {name!r}")
        if name in names:
            raise ValueError(f"features: expected distinct names, got {name!r} twice")
        if isinstance(spec, str):
            if spec != "walls":
                raise ValueError(
                    f"features[{name!r}]: expected one of {sorted(BEHAVIOUR_FEATURES)} or an "
                    f"(H, W) array, got {spec!r}"
                )
            phi = wall_distance_feature(~free, 1.0)
        else:
            a = np.asarray(spec, float)
            fine = (free_fine.shape[0] // factor * factor, free_fine.shape[1] // factor * factor)
            if a.shape == (h, w):
                phi = a
            elif a.shape == free_fine.shape and fine == (h * factor, w * factor):
                # on the map's grid: the mean over each MDP cell's map cells
                phi = a[: fine[0], : fine[1]].reshape(h, factor, w, factor).mean(axis=(1, 3))
            else:
                raise ValueError(
                    f"features[{name!r}]: expected an array on the MDP grid ({h}, {w}) or on "
                    f"the map {free_fine.shape}, got {describe(a)}"
                )
            if not np.isfinite(phi[free]).all():
                raise ValueError(f"features[{name!r}]: expected finite values on free cells")
            phi = np.where(free, phi, 0.0)
        names.append(name)
        maps.append(phi)
    if not names:
        return (), None
    return tuple(names), np.stack(maps)


def _likelihood_data(
    paths: list[np.ndarray],
    free: np.ndarray,
    *,
    goal_reward: float,
    step_cost: float,
    time_cost: float,
    dtype: npt.DTypeLike,
    n_devices: int | None = None,
    features: np.ndarray | None = None,
) -> tuple[_LikelihoodData, MoveObservations, int, int]:
    """The arguments of the fit's log-likelihood (:func:`_loglik`) for ``paths`` on the grid
    ``free``, padded to shape buckets; their :class:`MoveObservations`, the epoch cap ``K``
    and the number of local devices the goals are split across (default: all of them, at
    most one per padded goal).

    Padding: the goals to :func:`_bucket` of their number (a multiple of the devices),
    repeating the last goal (its copies change by exactly as much per epoch, so the solve
    stops at the same epoch and every real goal's policy is the same); the tracks and their
    steps to :func:`_bucket` of their numbers with steps ``move = -1`` (factors of exactly
    1). The likelihood is that of the unpadded data.

    Raises
    ------
    LimitError
        If the soft policies of the padded goals would pass the memory limit.
    """
    obs = move_observations(paths)
    k = _n_epochs(free, paths, obs.goals, factor=10.0)
    g, (n, t) = len(obs.goals), obs.move.shape
    if n_devices is None:
        n_devices = jax.local_device_count()
    n_devices = max(1, min(int(n_devices), _bucket(g)))
    gb, nb, tb = _bucket(g, n_devices), _bucket(n), _bucket(t)
    n_theta = 2 + (0 if features is None else len(features))
    check_memory(
        float(gb) * 4 * 5 * free.size * jnp.dtype(dtype).itemsize * (2 + n_theta),
        f"the soft policies of {gb} goals on the {free.shape[0]} x {free.shape[1]} grid and "
        f"their derivatives",
    )
    pad_g = np.minimum(np.arange(gb), g - 1)  # the padding goals repeat the last one
    keep, bonus = _goal_masks(free, obs.goals[pad_g], goal_reward)
    # convergence is measured on the visited cells and their neighbours
    seen = np.zeros((g,) + free.shape, bool)
    valid = obs.move >= 0
    seen[
        np.broadcast_to(obs.goal_index[:, None], obs.move.shape)[valid],
        obs.rows[valid],
        obs.cols[valid],
    ] = True
    seen = ndimage.binary_dilation(seen, np.ones((1, 5, 5), bool))[pad_g]

    def steps(x: np.ndarray, fill: int) -> np.ndarray:
        out = np.full((nb, tb), fill, np.int64)
        out[:n, :t] = x
        return out

    # NumPy arrays (host): see _LikelihoodData (the casts as jnp.asarray's, to nearest)
    real = np.dtype(dtype)
    data = _LikelihoodData(
        ok=np.asarray(path_free(~free)),
        keep=keep,
        bonus=np.asarray(bonus, real),
        tol_mask=seen,
        goal_index=np.r_[obs.goal_index, np.zeros(nb - n, np.int64)].astype(np.int64),
        rows=steps(obs.rows, 0),
        cols=steps(obs.cols, 0),
        move=steps(obs.move, -1),
        n_epochs=np.asarray(k, np.int32),
        step_cost=np.asarray(step_cost, real),
        time_cost=np.asarray(time_cost, real),
        phi=None if features is None else np.asarray(features, real),
    )
    return data, obs, k, n_devices


def _likelihood(
    paths: list[np.ndarray],
    free: np.ndarray,
    *,
    goal_reward: float,
    step_cost: float,
    time_cost: float,
    dtype: npt.DTypeLike,
    tol: float,
    n_devices: int | None = None,
    features: np.ndarray | None = None,
) -> tuple[Callable[[jax.Array], jax.Array], MoveObservations, int]:
    """The fit's log-likelihood ``f(theta)`` of ``paths`` (pure JAX, not jitted), their
    :class:`MoveObservations` and the epoch cap ``K``; with ``features (F, H, W)``, ``theta``
    ends with their ``F`` weights.

    The goals are split across ``n_devices`` local devices (default: all of them, at most
    one per goal); results are identical for any split. ``f`` is :func:`_loglik` on the
    padded data of :func:`_likelihood_data`.
    """
    data, obs, k, n_devices = _likelihood_data(
        paths,
        free,
        goal_reward=goal_reward,
        step_cost=step_cost,
        time_cost=time_cost,
        dtype=dtype,
        n_devices=n_devices,
        features=features,
    )
    return partial(_loglik, data=data, tol=_check_tol(tol), n_devices=n_devices), obs, k


def _check_tol(tol: object) -> float:
    """The soft solve's stopping tolerance of the fit: a positive float (it makes the epoch
    cap data rather than a compiled-in loop length)."""
    try:
        value = float(tol)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(tol, bool) or not value > 0:
        raise ValueError(f"tol: expected a positive float, got {tol!r}")
    return value


#: XLA options of :func:`_gradient_value_epochs`: XLA's CPU fusion emitters off (as the
#: Laplace programs'; its compile is most of a first fit). ``fit_behaviour`` on the
#: 302-person tracks table of ``bench_fit_cold`` (process CPU, fresh process and cache,
#: issue 29): the first call 15.8 -> 10.9 s, the next ones alike (3.3, 3.2 -> 3.5, 3.1 s);
#: float32 results move in the 6th digit (beta 1.89825845 -> 1.89825579, its se
#: 0.16416075 -> 0.16415785).
_GRADIENT_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


@jit_with_options(static_argnames=("n_devices",), compiler_options=_GRADIENT_OPTIONS)
def _gradient_value_epochs(
    theta: jax.Array, data: _LikelihoodData, tol: jax.Array, n_devices: int
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(gradient (n,), value (), epochs ())`` of :func:`_loglik_epochs` at ``theta (n,)``,
    forward mode: one compiled program per shape bucket of ``data`` (the data and the
    solve's ``tol`` are arguments), which also gives the Hessian (:func:`_hessian`)."""

    def twice(th: jax.Array) -> tuple[jax.Array, tuple[jax.Array, jax.Array]]:
        v, epochs = _loglik_epochs(th, data, tol, n_devices)
        return v, (v, epochs)

    g, (v, epochs) = jax.jacfwd(twice, has_aux=True)(theta)
    return g, v, epochs


#: Difference step of :func:`_hessian` on ``theta`` (log beta, logit slip, weights per
#: ``time_cost``), per dtype: the five-point stencil's error is ``O(h^4)`` against float32's
#: round-off over ``h``.
HESSIAN_STEP = {"float32": 1e-2, "float64": 1e-3}


class _DifferencedHessian(NamedTuple):
    """:func:`_hessian`'s result with its error: the Hessian and the standard deviation of
    the error in each of its entries (:func:`_standard_errors` reads them together)."""

    hessian: np.ndarray
    error: float


def _hessian(
    theta: jax.Array,
    data: _LikelihoodData,
    epochs: int,
    n_devices: int,
    *,
    with_error: bool = False,
) -> np.ndarray | _DifferencedHessian:
    """The Hessian ``(n, n)`` of :func:`_loglik` at ``theta (n,)``, whose soft solve iterated
    ``epochs``: five-point differences of the gradient (:func:`_gradient_value_epochs`'
    program: no program of its own to compile) with the solve held at those epochs
    (``tol < 0``, cap ``epochs + 1``), so that the differenced function is the smooth one
    whose second derivatives forward mode through the stopped solve gives (with the early
    stop free to move between the difference points they jumped); symmetrised.

    With ``with_error``, a :class:`_DifferencedHessian` that also holds the standard
    deviation of the error in each entry, from the gradient's own round-off: the fourth
    differences ``g(2h) - 4 g(h) + 6 g(0) - 4 g(-h) + g(-2h)`` of the points the stencil
    evaluates (and the gradient at ``theta``, one evaluation more) are round-off of variance
    ``70 sigma^2`` for a gradient round-off of sd ``sigma``, plus ``h^4`` times a fifth
    derivative; the stencil's entries then have sd ``sqrt(130) sigma / (12 h)``. On
    smooth likelihoods the fifth derivatives are far below the round-off; where one is not
    (a nearly hard soft-max at a large beta bends the likelihood over about ``1 / beta``),
    the stencil's own error is of that order too and the estimate takes it in. Measured:
    1.8e-3 (float32) and 3e-8 (float64) on the 28 moves of
    ``tests/fitting/test_behaviour_hessian.py``'s world at float32's optimum, whose two
    smaller eigenvalues of ``-H`` are 8.2e-4 and 7.0e-3; 0.028 and 1.4e-7 on the 130
    tracks of ``test_behaviour_fit``'s model world, eigenvalues 315 and 872.
    """
    dtype = jnp.result_type(theta)
    fixed = data._replace(n_epochs=np.asarray(int(epochs) + 1, np.int32))
    never = np.asarray(-1.0, dtype)
    h = HESSIAN_STEP[jnp.dtype(dtype).name]
    th = np.asarray(theta, np.float64)
    n = len(th)

    def grad(j: int, s: float) -> np.ndarray:
        x = th.copy()
        if s:
            x[j] += s * h
        g = _gradient_value_epochs(np.asarray(x, dtype), fixed, never, n_devices)[0]
        return np.asarray(g, np.float64)

    cols, fourth = [], []
    g0 = grad(0, 0) if with_error else None
    for j in range(n):
        gj = {s: grad(j, s) for s in (1, -1, 2, -2)}
        cols.append((8.0 * (gj[1] - gj[-1]) - (gj[2] - gj[-2])) / (12.0 * h))
        if with_error:
            fourth.append(gj[2] - 4.0 * gj[1] + 6.0 * g0 - 4.0 * gj[-1] + gj[-2])
    hess = np.stack(cols, axis=1)
    hess = 0.5 * (hess + hess.T)
    if not with_error:
        return hess
    sigma = math.sqrt(float(np.mean(np.square(fourth))) / 70.0)
    return _DifferencedHessian(hess, sigma * math.sqrt(130.0) / (12.0 * h))


#: :func:`_standard_errors`: an eigenvalue of the information ``-H`` is resolved when it
#: exceeds this many times the sd of the Hessian's error per entry (an eigenvalue moves
#: by about that sd: a resolved one is then within 10% at 1 sd, its variance too).
RESOLVED_EIGENVALUE = 10.0
#: :func:`_standard_errors`: a standard error is reported when the unresolved directions, at
#: the most information the error leaves them, add at most this share of its variance.
UNRESOLVED_SHARE = 0.01


class _StandardErrors(NamedTuple):
    """:func:`_standard_errors`' result.

    Attributes
    ----------
    se : (n,) float
        Standard errors of ``theta``; NaN where the information does not determine them.
    eigenvalues : (n,) float
        Eigenvalues of ``-H``, ascending.
    resolved : (n,) bool
        Which of them exceed the error (:data:`RESOLVED_EIGENVALUE`).
    error : float
        The sd of the Hessian's error per entry.
    """

    se: np.ndarray
    eigenvalues: np.ndarray
    resolved: np.ndarray
    error: float


def _standard_errors(hess: np.ndarray, error: float) -> _StandardErrors:
    """Standard errors ``sqrt(diag(inv(-H)))`` of the Hessian ``hess (n, n)`` whose entries
    carry errors of sd ``error`` (:func:`_hessian`), NaN where those errors decide them.

    An eigenvalue ``lambda_k`` of the information ``-H`` is resolved when it exceeds
    :data:`RESOLVED_EIGENVALUE` ``* error``; one below (near 0, or negative: no maximum
    along it, or error) is information the Hessian cannot tell from none. When every one
    is resolved the standard errors are those of ``inv(-H)``. Otherwise parameter ``i``'s
    variance is ``sum_k v_ik^2 / lambda_k`` over the resolved directions, reported only where
    the unresolved ones, at the most information the error leaves them (the threshold),
    would add at most :data:`UNRESOLVED_SHARE` of it; elsewhere NaN (a parameter the
    tracks do not identify at this precision: beta running to infinity, a flat weight).

    Returns
    -------
    _StandardErrors
    """
    hess = np.asarray(hess, np.float64)
    n = len(hess)
    lam, vec = np.linalg.eigh(-hess) if np.isfinite(hess).all() else (np.full(n, np.nan), None)
    tau = RESOLVED_EIGENVALUE * float(error)
    resolved = lam > tau
    if resolved.all():
        se = np.sqrt(np.diag(np.linalg.inv(-hess)))
    elif vec is None:
        se = np.full(n, np.nan)
    else:
        var = (vec[:, resolved] ** 2 / lam[resolved]).sum(axis=1)
        least = (vec[:, ~resolved] ** 2).sum(axis=1) / tau
        ok = (var > 0) & (least <= UNRESOLVED_SHARE * var)
        se = np.where(ok, np.sqrt(np.where(ok, var, 1.0)), np.nan)
    return _StandardErrors(se, lam, resolved, float(error))


class _MaximumLikelihood(TypedDict):
    """:func:`_mle`'s estimates: ``beta``, ``slip`` and their standard errors, the
    ``(F,)`` feature ``weights`` and theirs, the maximised log-likelihood, the moves and
    epoch cap ``K`` it is of, whether the optimiser converged, and why standard errors are
    NaN (``se_unresolved``, :func:`_unresolved_note`; "" when none is)."""

    beta: float
    beta_se: float
    slip: float
    slip_se: float
    weights: np.ndarray
    weights_se: np.ndarray
    loglik: float
    n_moves: int
    n_epochs: int
    converged: bool
    se_unresolved: str


def _mle(
    paths: list[np.ndarray],
    free: np.ndarray,
    *,
    goal_reward: float,
    step_cost: float,
    time_cost: float,
    beta0: float,
    slip0: float,
    dtype: npt.DTypeLike,
    tol: float,
    features: np.ndarray | None = None,
) -> _MaximumLikelihood:
    """Maximum likelihood of ``(beta, slip[, weights])`` with inverse-Hessian standard
    errors (the weights of ``features (F, H, W)`` start at 0). The value, gradient and
    Hessian (:func:`_hessian`) are one program, :func:`_gradient_value_epochs`, compiled
    once per shape bucket of the data."""
    tol = _check_tol(tol)
    data, obs, k, n_devices = _likelihood_data(
        paths,
        free,
        goal_reward=goal_reward,
        step_cost=step_cost,
        time_cost=time_cost,
        dtype=dtype,
        features=features,
    )
    n_f = 0 if features is None else len(features)
    scale = 1.0 / max(obs.n_moves, 1)
    tol_a = np.asarray(tol, dtype)
    epochs_at: dict[bytes, int] = {}  # the solve's epochs at each point evaluated

    def fun(th: np.ndarray) -> tuple[float, np.ndarray]:
        g, v, epochs = _gradient_value_epochs(np.asarray(th, dtype), data, tol_a, n_devices)
        epochs_at[np.asarray(th, float).tobytes()] = int(epochs)
        return -float(v) * scale, -np.asarray(g, float) * scale

    th0 = np.r_[math.log(beta0), math.log(slip0 / (1 - slip0)), np.zeros(n_f)]
    wb = _WEIGHT_BOUND * abs(time_cost) if time_cost else _WEIGHT_BOUND
    # float32 values carry ~1e-7 relative noise (and the early stop of the soft solve more):
    # tolerances below that make the line search fail
    single = jnp.dtype(dtype) == jnp.float32
    res = minimize(
        fun,
        th0,
        jac=True,
        method="L-BFGS-B",
        bounds=[(-6.0, 8.0), (-10.0, 6.0)] + [(-wb, wb)] * n_f,
        options={
            "maxiter": 60,
            "maxfun": 80,
            "ftol": 1e-6 if single else 1e-10,
            "gtol": 1e-4 if single else 1e-7,
        },
    )
    converged = bool(res.success) or bool(np.max(np.abs(res.jac)) < (1e-3 if single else 1e-5))
    th = np.asarray(res.x, dtype)
    epochs = epochs_at.get(np.asarray(res.x, float).tobytes())
    if epochs is None:  # the optimum is a point evaluated (L-BFGS-B): never, to be safe
        epochs = int(_gradient_value_epochs(th, data, tol_a, n_devices)[2])
    hess = _hessian(th, data, epochs, n_devices, with_error=True)
    errors = _standard_errors(hess.hessian, hess.error)
    se = errors.se
    beta = math.exp(res.x[0])
    slip = 1.0 / (1.0 + math.exp(-res.x[1]))
    return {
        "beta": beta,
        "beta_se": beta * se[0],
        "slip": slip,
        "slip_se": slip * (1 - slip) * se[1],
        "weights": np.asarray(res.x[2:], float),
        "weights_se": np.asarray(se[2:], float),
        "loglik": -res.fun / scale,
        "n_moves": obs.n_moves,
        "n_epochs": k,
        "converged": converged,
        "se_unresolved": _unresolved_note(errors, jnp.dtype(dtype).name),
    }


def _unresolved_note(errors: _StandardErrors, dtype: str) -> str:
    """Why some of :func:`_standard_errors`' are NaN, for the fit's warnings ("" when none
    is): the eigenvalues of the information it could not resolve against the Hessian's
    error in ``dtype``."""
    if np.isfinite(errors.se).all():
        return ""
    low = errors.eigenvalues[~errors.resolved]
    lam = ", ".join(f"{v:.2g}" for v in low)
    if not np.isfinite(errors.error) or not np.isfinite(low).all():
        return "the Hessian is not finite"
    hint = " (float64's round-off is about 1e-6 of float32's)" if dtype == "float32" else ""
    return (
        f"the information's eigenvalues {lam} are below {RESOLVED_EIGENVALUE:g} times the "
        f"{dtype} Hessian's error per entry ({errors.error:.2g}){hint}: the tracks do not "
        "identify these directions at this precision (the likelihood flat, or not at a "
        "maximum, along them; e.g. beta rising without bound)"
    )


def open_area_grid(
    tracks: pd.DataFrame, resolution: float = 0.1, margin: float = 1.0, source: Source = "tracks"
) -> tuple[np.ndarray, float, np.ndarray]:
    """The open area tracks cover, as a map for :func:`fit_behaviour` without one (issue 26).

    The bounding box of every track position plus ``margin`` on each side, every cell free
    (the box's edge is the only wall: nothing in the log says where walls are).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``x, y`` (m).
    resolution : float
        Cell side (m).
    margin : float
        Free border around the box (m, >= 0).
    source : str
        The input named in errors.

    Returns
    -------
    free_mask : (H, W) bool
        All true.
    resolution : float
    origin : (2,) float
        World ``(x, y)`` of the box's corner.

    Raises
    ------
    ValueError
        Without finite positions.
    LimitError
        If the grid would pass the memory limit (checked before allocating).
    """
    resolution = float(check_positive("resolution", resolution))
    margin = float(margin)
    if not (np.isfinite(margin) and margin >= 0.0):
        raise ValueError(f"margin: expected a finite number >= 0, got {margin!r}")
    xy = tracks[["x", "y"]].to_numpy(float)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        raise ValueError(f"{source}: expected finite x, y positions to span an open area")
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    w, h = np.maximum(np.ceil((hi - lo) / resolution - 1e-9), 2.0)
    check_memory(float(h) * float(w), f"the {h:.0f} x {w:.0f} open-area grid of the tracks", source)
    return np.ones((int(h), int(w)), bool), resolution, lo


def fit_behaviour(
    tracks: pd.DataFrame,
    free_mask: npt.ArrayLike,
    resolution: float,
    origin: npt.ArrayLike,
    *,
    cell: float | None = None,
    dt: float | None = None,
    run_speed: float | Mapping[str, float] = 2.5,
    max_fit_tracks: int | None = 16,
    max_side: int = _MAX_SIDE,
    time_cost: float = 1.0,
    goal_reward: float = 1.0,
    step_cost: float = 1e-3,
    beta0: float = 2.0,
    slip0: float = 0.1,
    seed: int = 0,
    dtype: str = "float32",
    tol: float = 1e-3,
    features: str | Sequence[str] | Mapping[str, str | npt.ArrayLike] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> BehaviourFit:
    """Fit speeds, exits, rationality, slip (and reward weights) per class from tracks.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``]: positions (m) of each track at times (s).
    free_mask : (H, W) bool
        Free cells of the map (row along +y, column along +x).
    resolution : float
        Map cell side (m).
    origin : (2,) float
        World ``(x, y)`` of the map's corner.
    cell : float or None
        MDP cell side (m), rounded to whole map cells (default: about 0.5 m, coarser so that
        the grid has at most ``max_side`` cells a side).
    dt : float or None
        Decision epoch (s) for every class (default per class: ``cell`` over its median
        walking speed).
    run_speed : float or mapping of str to float
        Tracks whose walking speed (module docstring: free of the tracker's noise) exceeds
        this (m/s) are runners; a mapping gives it per class label (classes it lacks:
        2.5 m/s), so that a class of fast movers (cyclists at 4 m/s) is not all runners
        (``are-stats fit`` takes it from the catalogue:
        :meth:`are_stats.environment.ArtefactCatalogue.run_thresholds`).
    max_fit_tracks : int or None
        Largest number of tracks per class in the likelihood of ``beta`` and ``slip`` (a
        random subset drawn with ``seed``; ``None``: all). Each track's goal costs a soft
        solve over the whole grid per likelihood evaluation.
    max_side : int
        Largest side (cells) of the default MDP grid.
    time_cost, goal_reward, step_cost : float
        Rewards of the soft MDP.
    beta0, slip0 : float
        Starting values.
    seed : int
        Seed of the subset.
    dtype : str
        ``"float32"`` (default, faster) or ``"float64"`` for the soft solves.
    tol : float
        The soft values are iterated until they change by at most ``tol`` per epoch on the
        cells the tracks visit (and their 2-cell neighbourhoods): the stationary policy, with
        at most 10 times the longest start-goal path plus 20 epochs.
    features : sequence of str, or mapping of str to str or (H, W) float, optional
        Reward features whose weights are fitted with ``beta`` and ``slip`` (default: none;
        the fit is then exactly the one without this option). A name of
        :data:`BEHAVIOUR_FEATURES` (``"walls"``: closeness to walls, 1 next to an obstacle,
        ``exp(-(d - 1))`` at ``d`` cells), or ``{name: phi}`` with ``phi`` an array on the
        MDP grid or on the map (averaged over each MDP cell) or a built-in name. Every epoch
        off the goal on a cell earns ``sum_k w_k phi_k(cell)``. The reward scale is fixed by
        ``time_cost``: ``w_k`` is a reward per epoch in its units (``w < 0``: the cells are
        avoided, ``w > 0``: sought; ``w = -time_cost`` doubles the cost of an epoch spent
        where ``phi = 1``). Weights are bounded to ``+-10 time_cost``.
    progress : callable, optional
        ``progress(done, total)`` after each class fitted (``total``: the classes). The
        class is the only loop with a count known in advance: its maximum likelihood is
        one L-BFGS-B run that stops when it converges (at most 80 evaluations), so a log
        of one class reports its one step at the end. The fit does not depend on it.

    Returns
    -------
    BehaviourFit
        The classes that walk, fitted; a class none of whose tracks walks (no walking
        speed: every track stands, or runs, or none leaves its MDP cell) is left out of
        ``classes`` and named in ``standing`` (it stands in generated scenes:
        :func:`~are_stats.behaviour.simulate_behaviour_tracks`).

    Raises
    ------
    NoWalkersError
        When no class walks: there is no walking to fit.
    ValueError
        On missing columns, or unknown or misshapen ``features``.
    """
    if not isinstance(tracks, pd.DataFrame):
        raise ValueError(f"tracks: expected a pandas DataFrame, got {type(tracks).__name__}")
    missing = [c for c in ("id", "t", "x", "y") if c not in tracks.columns]
    if missing:
        raise ValueError(f"tracks: expected columns id, t, x, y, missing {missing}")
    free_fine = np.asarray(free_mask, bool)
    if free_fine.ndim != 2:
        raise ValueError(f"free_mask: expected a 2-d bool array, got {describe(free_fine)}")
    res = float(check_positive("resolution", resolution))
    if cell is None:
        f = max(1, round(0.5 / res), math.ceil(max(free_fine.shape) / max_side))
        cell = f * res
    free, cell = coarse_free(free_fine, res, float(check_positive("cell", cell)))
    origin_a = np.asarray(check_finite("origin", origin, ndim=1), float)[:2]
    factor = max(1, round(cell / res))
    feature_names, phi = _feature_maps(features, free, free_fine, factor)
    weights, weights_se = [], []
    rng = np.random.default_rng(seed)
    labels = (
        tracks["label"].astype(str) if "label" in tracks.columns else pd.Series("all", tracks.index)
    )
    classes = tuple(sorted(labels.unique()))
    # per-class values, one list per field of the class fits (the keys of ``vals`` below)
    per: defaultdict[str, list[float]] = defaultdict(list)
    track_class, entry_xy, exit_xy = [], [], []
    warnings: list[str] = []
    standing: list[str] = []  # classes none of whose tracks walk (BehaviourFit.standing)
    # the speeds, measured through the log's tracker noise (one tracker for every class)
    noise = tracker_noise(tracks[["id", "t", "x", "y"]])
    # where each walker has somebody near (any class): its own pace is read elsewhere
    near_all = _crowded(tracks[["id", "t", "x", "y"]])
    for ci, name in enumerate(classes):
        in_class = (labels == name).to_numpy()
        tab = tracks[in_class]
        near_class = near_all[in_class]
        speeds, ent, ext, seen, near = [], [], [], [], []
        # each track (ids in sorted order, a missing id none) its rows by time, ties in
        # the table's order: the groups and stable sorts of pandas, from one sort of the
        # columns (issue 29: a table per track was most of this loop's CPU)
        codes, _ = pd.factorize(tab["id"], sort=True)
        t_c, xy_c = tab["t"].to_numpy(float), tab[["x", "y"]].to_numpy(float)
        order = np.lexsort((t_c, codes))
        order = order[codes[order] >= 0]
        bounds = np.r_[np.flatnonzero(np.diff(codes[order], prepend=-1)), order.size]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            rows = order[a:b]
            xy = xy_c[rows]
            seen.append((t_c[rows], xy))
            near.append(near_class[rows])
            speeds.append(_track_speed(seen[-1][0], xy, noise))
            ent.append(xy[0])
            ext.append(xy[-1])
        threshold = run_speed.get(name, 2.5) if isinstance(run_speed, Mapping) else run_speed
        sp = np.asarray(speeds, float)
        try:
            law = _speed_law(sp, float(threshold), name)
        except NoWalkersError:  # nobody of the class walks: it stands in the scenes
            standing.append(name)
            if progress is not None:
                progress(ci + 1, len(classes))
            continue
        # one cell per epoch at the (noise-free) median walking speed
        dt_c = float(dt) if dt is not None else cell / math.exp(law["speed_mu"])
        paths, _ = discretise_tracks(tab, free, cell, origin_a, dt_c)
        paths = [p for p in paths if len(p) >= 2]
        if not paths:  # its walkers never leave their cell: it stands too
            standing.append(name)
            if progress is not None:
                progress(ci + 1, len(classes))
            continue
        # the within-person variation of the walkers' pace (runners left out)
        walkers = np.flatnonzero(np.isfinite(sp) & (sp > 0) & (sp <= float(threshold)))
        within = _within_variation(
            [seen[i] for i in walkers],
            sp[walkers],
            noise,
            [near[i] for i in walkers],
            route_map=(free_fine, origin_a, res),
            seed=(seed, 26, ci),
        )
        law |= within["speed"] | within["heading"]
        n_all = len(paths)
        if max_fit_tracks is not None and len(paths) > max_fit_tracks:
            pick = rng.choice(len(paths), max_fit_tracks, replace=False)
            paths = [paths[i] for i in np.sort(pick)]
        t0 = time.perf_counter()
        mle = _mle(
            paths,
            free,
            goal_reward=goal_reward,
            step_cost=step_cost,
            time_cost=time_cost,
            beta0=beta0,
            slip0=slip0,
            dtype=jnp.dtype(dtype),
            tol=tol,
            features=phi,
        )
        weights.append(mle["weights"])
        weights_se.append(mle["weights_se"])
        if not mle["converged"]:
            what = "beta/slip/weights" if feature_names else "beta/slip"
            warnings.append(f"class {name!r}: the {what} optimiser did not report convergence")
        if mle["se_unresolved"]:
            ses = {"beta": mle["beta_se"], "slip": mle["slip_se"]}
            ses |= {f"{f} weight": v for f, v in zip(feature_names, mle["weights_se"], strict=True)}
            nan = ", ".join(k for k, v in ses.items() if not np.isfinite(v))
            warnings.append(
                f"class {name!r}: standard errors of {nan} are NaN: {mle['se_unresolved']}"
            )
        ent_a, ext_a = np.asarray(ent), np.asarray(ext)
        vals = {
            "dt": dt_c,
            **law,
            "beta": mle["beta"],
            "beta_se": mle["beta_se"],
            "slip": mle["slip"],
            "slip_se": mle["slip_se"],
            "loglik": mle["loglik"],
            "n_moves": mle["n_moves"],
            "n_tracks": n_all,
            "n_fit_tracks": len(paths),
            "n_epochs": mle["n_epochs"],
            "bandwidth_entry": _bandwidth(ent_a, 2 * cell),
            "bandwidth_exit": _bandwidth(ext_a, cell),
            "fit_seconds": time.perf_counter() - t0,
        }
        for k, v in vals.items():
            per[k].append(v)
        track_class.extend([len(per["dt"]) - 1] * len(ent_a))  # its place among the walking
        entry_xy.append(ent_a)
        exit_xy.append(ext_a)
        if progress is not None:
            progress(ci + 1, len(classes))
    if len(standing) == len(classes):
        which = ", ".join(repr(c) for c in classes)
        raise NoWalkersError(
            f"tracks: expected moving walkers in class {which}, got none"
            if len(classes) == 1
            else f"tracks: expected moving walkers in one of the classes {which}, got none"
        )
    walking = tuple(c for c in classes if c not in standing)
    arrays = {k: np.asarray(v) for k, v in per.items()}
    for k in ("n_moves", "n_tracks", "n_fit_tracks", "n_epochs"):
        arrays[k] = arrays[k].astype(np.int64)
    return BehaviourFit(
        classes=walking,
        standing=tuple(standing),
        cell=float(cell),
        origin=origin_a,
        free=free,
        track_class=np.asarray(track_class, np.int64),
        entry_xy=np.concatenate(entry_xy),
        exit_xy=np.concatenate(exit_xy),
        time_cost=float(time_cost),
        goal_reward=float(goal_reward),
        step_cost=float(step_cost),
        warnings=warnings,
        feature_names=feature_names,
        features=phi,
        weights=np.asarray(weights, float).reshape(len(walking), len(feature_names)),
        weights_se=np.asarray(weights_se, float).reshape(len(walking), len(feature_names)),
        **arrays,
    )
