"""Criticism for motion (issue 16): does the fitted behaviour walk like the people in the log?

Three kinds of numbers, like the traffic checks (:func:`~are_stats.fitting.traffic_checks`):

* **Posterior-predictive statistics** (:func:`motion_checks`). The observed people (same
  entries, arrivals, classes and groups) are walked again ``n_replicates`` times as
  generation walks people (:func:`_replicate_tracks`): the model's exit and route
  (:func:`~are_stats.behaviour.simulate_behaviour_tracks`), a preferred speed drawn from
  the fitted between-person law, the social force among the others with the groups in
  formation (:func:`~are_stats.behaviour.social_force_tracks`), leaving at the exit;
  sampled at the log's rate and measured with the log's position noise added
  (:func:`~are_stats.behaviour.tracker_noise`). Per
  track (:func:`track_statistics`) the speed over the walking part (from setting off to
  reaching the exit), the straightness (net displacement / path length), whether it stays
  still (net displacement below ``still_distance``) and the time from entry to exit over
  the stay (reaching within ``exit_radius`` of the last position, over the duration) are
  summarised per replicate by :data:`MOTION_STATISTICS`; each row holds the observed
  value, the 5/50/95% predictive quantiles and a flag where the observed value is outside
  the 90% band by more than the difference that matters (:data:`MOTION_TOLERANCE`).
* **Held-out log-likelihood** (:func:`heldout_log_likelihood`, :func:`score_moves`). Tracks
  are split by id (``train_fraction`` fitted, the rest scored); the held-out tracks are
  discretised as in the fit and their moves scored under the fitted soft policy and under a
  **random walk**: the same hidden-Markov likelihood with the policy uniform over the allowed
  actions (``stay, forward, left, right``; the ``beta -> 0`` limit of the soft policy) and
  the same slip. Both are reported per move with their difference and its standard error
  (a ratio estimator over held-out tracks).
* **Displacement errors** (:func:`~are_stats.fitting.displacement_errors`) live in
  ``_prediction.py``.
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import TYPE_CHECKING, Any  # Any: fit_behaviour's keyword arguments, passed on

import jax
import numpy as np
import pandas as pd

from are_stats.behaviour import (
    GOAL_BUCKET,
    BehaviourFit,
    SocialForce,
    arrival_velocities,
    formation,
    move_observations,
    path_free,
    preferred_speeds,
    simulate_behaviour_tracks,
    social_force_tracks,
    track_log_likelihoods,
    tracker_noise,
)
from are_stats.environment import OccupancyGrid
from are_stats.fitting._behaviour import discretise_tracks, fit_behaviour
from are_stats.inputs import LimitError, check_memory
from are_stats.logs import track_groups
from are_stats.traffic import fold_in_key, key_from_seed, key_uniform, split_key

if TYPE_CHECKING:
    import numpy.typing as npt
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "MOTION_STATISTICS",
    "MOTION_TOLERANCE",
    "band_flags",
    "heldout_log_likelihood",
    "motion_checks",
    "plot_motion_checks",
    "score_moves",
    "track_statistics",
    "tracker_noise",
]

#: The statistics of :func:`motion_checks`, in table order.
MOTION_STATISTICS = (
    "median speed (m/s)",
    "speed spread (m/s)",
    "median straightness",
    "fraction still",
    "median time to exit / stay",
)
#: The smallest difference between observed and model that matters, per statistic: an
#: observed value outside the 90% band by less is not flagged. Without it, statistics that
#: barely vary between replicates (the straightness of open crossings, the time to the exit
#: over the stay) were flagged for thousandths that no user could see in a track.
MOTION_TOLERANCE = {
    "median speed (m/s)": 0.05,
    "speed spread (m/s)": 0.05,
    "median straightness": 0.01,
    "fraction still": 0.02,
    "median time to exit / stay": 0.02,
}


def band_flags(
    statistics: Sequence[str], observed: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """Observed values outside the model's band by more than :data:`MOTION_TOLERANCE`.

    Parameters
    ----------
    statistics : sequence of str
        ``(n,)`` statistic of each value (one without a tolerance gets 0).
    observed, lo, hi : (n,) float
        The observed values and the band's ends (5% and 95% predictive quantiles).

    Returns
    -------
    (n,) bool
        ``observed < lo - tol`` or ``observed > hi + tol``; False where ``observed`` is NaN.

    Examples
    --------
    >>> band_flags(["median straightness"] * 2, np.array([0.996, 0.97]),
    ...            np.array([0.990, 0.990]), np.array([0.995, 0.995])).tolist()
    [False, True]
    """
    tol = np.array([MOTION_TOLERANCE.get(s, 0.0) for s in statistics], float)
    o = np.asarray(observed, float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(o) & ((o < np.asarray(lo) - tol) | (o > np.asarray(hi) + tol))


def _rng(key: int | jax.Array) -> np.random.Generator:
    if isinstance(key, int | np.integer):
        return np.random.default_rng(int(key))
    return np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel().tolist())


def _key(key: int | jax.Array) -> jax.Array:
    return key_from_seed(int(key)) if isinstance(key, int | np.integer) else key


def track_statistics(
    tracks: pd.DataFrame, *, still_distance: float = 1.0, exit_radius: float = 0.5
) -> pd.DataFrame:
    """Per-track motion statistics.

    The **walking part** of a track runs from where it first gets farther than
    ``exit_radius`` from where it entered (it has set off) to where it first comes within
    ``exit_radius`` of where it left (it has reached its exit), both crossings interpolated
    linearly between the samples either side (not rounded to the sampling period): the
    time a person stands before setting off or at its exit before leaving is not walking,
    so the speed is that of the walk, not of the stay.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (m, s); with a ``scenario`` column, tracks are ``(scenario, id)``.
    still_distance : float
        A track whose net displacement is below this (m) is still.
    exit_radius : float
        The track has set off when farther than this (m) from its first position, and has
        reached its exit when first within this of its last position.

    Returns
    -------
    pandas.DataFrame
        One row per track (indexed by ``id``, or ``(scenario, id)``): ``duration`` (s, the
        stay), ``path`` and ``net`` (m), ``walk_time`` (s, the walking part's duration; 0
        for a track that never sets off or reaches its exit as it sets off), ``speed`` (the
        walking part's path length over ``walk_time``, m/s; NaN for a zero ``walk_time``),
        ``straightness`` (net / path; NaN for a zero path), ``still`` (bool) and
        ``exit_fraction`` (time from entry to the exit over ``duration``).
    """
    keys = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    tab = tracks.sort_values(keys + ["t"], kind="stable")
    kid = tab.groupby(keys, sort=False).ngroup().to_numpy()
    t = tab["t"].to_numpy(float)
    xy = tab[["x", "y"]].to_numpy(float)
    n = int(kid.max()) + 1 if kid.size else 0
    first = np.r_[True, kid[1:] != kid[:-1]] if kid.size else np.zeros(0, bool)
    start = np.flatnonzero(first)
    stop = np.r_[start[1:], kid.size] - 1
    seg = np.hypot(*np.diff(xy, axis=0).T) if kid.size > 1 else np.zeros(0)
    seg = np.where(first[1:], 0.0, seg)
    csum = np.r_[0.0, np.cumsum(seg)]
    path = csum[stop] - csum[start]
    net = np.hypot(*(xy[stop] - xy[start]).T)
    dur = t[stop] - t[start]
    row = np.arange(kid.size)
    # where each track reaches its exit (first within exit_radius of its last position) and
    # sets off (first farther than that from its first), at the crossing of the circle
    # interpolated between the samples either side: not rounded to the sampling period
    d_end = np.hypot(*(xy - xy[stop][kid]).T)
    d_start = np.hypot(*(xy - xy[start][kid]).T)
    first_near = (
        np.minimum.reduceat(np.where(d_end <= exit_radius, row, kid.size), start) if n else start
    )
    set_off = (
        np.minimum.reduceat(np.where(d_start > exit_radius, row, kid.size), start) if n else start
    )
    set_off = np.minimum(set_off, stop)  # one that never sets off: its last sample

    def crossing(j: np.ndarray, d: np.ndarray, inward: bool) -> tuple[np.ndarray, np.ndarray]:
        """Time and path length where the track crosses the circle between ``j - 1``
        and ``j`` (at ``j`` itself for a track's first sample)."""
        i = np.maximum(j - 1, start)
        a, b = d[i], d[j]
        gap = (a - b) if inward else (b - a)
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(
                (j > start) & (gap > 0),
                ((a - exit_radius) if inward else (exit_radius - a)) / gap,
                1.0,
            )
        f = np.clip(f, 0.0, 1.0)
        return t[i] + f * (t[j] - t[i]), csum[i] + f * (csum[j] - csum[i])

    t_exit, s_exit = crossing(first_near, d_end, True)
    t_off, s_off = crossing(set_off, d_start, False)
    walk = np.maximum(t_exit - t_off, 0.0)
    walked = np.where(walk > 0, s_exit - s_off, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = pd.DataFrame(
            {
                "duration": dur,
                "path": path,
                "net": net,
                "walk_time": walk,
                "speed": np.where(walk > 0, walked / np.where(walk > 0, walk, 1.0), np.nan),
                "straightness": np.where(path > 0, net / np.where(path > 0, path, 1.0), np.nan),
                "still": net < still_distance,
                "exit_fraction": np.where(
                    dur > 0, (t_exit - t[start]) / np.where(dur > 0, dur, 1.0), np.nan
                ),
            }
        )
    index = tab.iloc[start][keys]
    if len(keys) > 1:
        out.index = pd.MultiIndex.from_frame(index)
    else:
        out.index = pd.Index(index["id"], name="id")
    return out


def _summary(st: pd.DataFrame) -> list[float]:
    """The :data:`MOTION_STATISTICS` of one set of tracks (NaN where undefined): speeds,
    straightness and time to exit of the moving tracks, the fraction still of all."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        moving = ~st["still"].to_numpy(bool)
        sp = st["speed"].to_numpy(float)[moving]
        sp = sp[np.isfinite(sp)]
        s = st["straightness"].to_numpy(float)[moving]
        e = st["exit_fraction"].to_numpy(float)[moving]
        q = np.quantile(sp, [0.25, 0.75]) if sp.size else [np.nan, np.nan]
        return [
            float(np.median(sp)) if sp.size else math.nan,
            float(q[1] - q[0]),
            float(np.nanmedian(s)) if np.isfinite(s).any() else math.nan,
            float(np.mean(st["still"])) if len(st) else math.nan,
            float(np.nanmedian(e)) if np.isfinite(e).any() else math.nan,
        ]


def _sampling_period(tracks: pd.DataFrame) -> float:
    g = tracks.sort_values(["id", "t"], kind="stable")
    same = g["id"].to_numpy()[1:] == g["id"].to_numpy()[:-1]
    d = np.diff(g["t"].to_numpy(float))[same]
    d = d[d > 0]
    return float(np.median(d)) if d.size else 1.0


#: Sampling period (s) of the planned routes that :func:`_replicate_tracks` re-times (their
#: vertices are rows whatever the period).
PLAN_PERIOD = 60.0

#: Distance (m) from its route's end within which a replicated walker has reached its
#: exit, and leaves (about a step: the log's period times a walking speed).
ARRIVED = 0.5
#: Seconds a replicated walker's life-cycle lasts past its path's walking time at its
#: preferred speed: the social force's start from rest (its relaxation time) and a little
#: give-and-take on the way; it leaves where it reaches its exit (or, held up longer, when
#: its time is up).
SLACK = 2.0

#: Integration step (s) of the social force that walks the model's people, as generation's
#: (:func:`~are_stats.behaviour.social_force_tracks`' default).
WALK_DT = 0.1


def _social(interaction: bool | SocialForce | None) -> SocialForce | None:
    """The social force's parameters of ``interaction`` (``True``: the published ones; a
    :class:`~are_stats.behaviour.SocialForce`: itself), None for no interaction."""
    if interaction is None or interaction is False:
        return None
    return interaction if isinstance(interaction, SocialForce) else SocialForce()


def _walk(
    plan: pd.DataFrame,
    params: SocialForce | None,
    grid: OccupancyGrid | None,
    *,
    kinematic: np.ndarray | None = None,
    groups: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
    variation: tuple | None = None,
) -> pd.DataFrame:
    """Planned tracks walked again as generation walks people: the social force
    (:func:`~are_stats.behaviour.social_force_tracks`) with ``params`` on ``grid``, the
    arrival groups in formation (``groups``, per row; their planned tracks already on the
    leader's route, :func:`~are_stats.behaviour.group_tracks`), the fitted within-person
    variation of the speed and heading as generation walks it (``variation``:
    :func:`_variation`'s, per row). The one path by which the
    criticism moves the model's people: the replicates of :func:`motion_checks` and the
    continuations of :func:`displacement_errors`. ``progress(done, total)`` is told the
    social force's windows (those of the parts, one after the other, when walked in parts:
    the parts not yet begun counted as long as the current one)."""
    pace = turn = None
    if variation is not None:
        key, sd, time, h_sd, h_time = variation
        if (np.nan_to_num(sd) > 0).any():
            pace = (fold_in_key(key, 0), sd, time)
        if (np.nan_to_num(h_sd) > 0).any():
            turn = (fold_in_key(key, 1), h_sd, h_time)
    try:
        return social_force_tracks(
            plan,
            params,
            grid,
            dt=WALK_DT,
            kinematic=kinematic,
            groups=groups,
            progress=progress,
            speed_variation=pace,
            heading_variation=turn,
        )
    except LimitError:
        # the replicates of a large log together exceed the work or memory limit that guards
        # one user-sized call: walk them in halves (scenarios never meet, so each half walks
        # as it would have together); one scenario over the limit is refused as before
        if "scenario" not in plan.columns:
            raise
        scen = plan["scenario"].to_numpy()
        names = np.sort(pd.unique(scen))
        if names.size < 2:
            raise
        parts: list[pd.DataFrame] = []
        halves = np.array_split(names, 2)
        before = [0]  # the windows of the parts already walked
        for h, half in enumerate(halves):
            rows = np.isin(scen, half)

            def part_step(done: int, total: int, h: int = h) -> None:
                if progress is not None:
                    progress(before[0] + done, before[0] + total * (len(halves) - h))
                if done == total:
                    before[0] += total

            parts.append(
                _walk(
                    plan[rows].reset_index(drop=True),
                    params,
                    grid,
                    kinematic=None if kinematic is None else kinematic[rows],
                    groups=None if groups is None else groups[rows],
                    progress=part_step,
                    variation=None
                    if variation is None
                    else (  # each half its own processes
                        fold_in_key(variation[0], 2 + h),
                        *(np.asarray(a)[rows] for a in variation[1:]),
                    ),
                )
            )
        return pd.concat(parts, ignore_index=True)


def _variation(key: jax.Array, fit: BehaviourFit, cls: np.ndarray) -> tuple | None:
    """The fit's within-person variation for rows of classes ``cls`` (n,) as :func:`_walk`
    takes it: ``(key, speed sd, speed time, heading sd, heading time)``, per row; None
    when the fit has none (an older file: the walk as before)."""
    sd, h_sd = fit.speed_within_sd[cls], fit.heading_within_sd[cls]
    if not ((np.nan_to_num(sd) > 0).any() or (np.nan_to_num(h_sd) > 0).any()):
        return None
    return key, sd, fit.speed_within_time[cls], h_sd, fit.heading_within_time[cls]


def _log_groups(tracks: pd.DataFrame) -> dict[Hashable, str]:
    """:func:`~are_stats.logs.track_groups` keyed by the log's own ids (not their text)."""
    by_text = {str(i): i for i in pd.unique(tracks["id"])}
    return {by_text[i]: g for i, g in track_groups(tracks).items() if i in by_text}


def _draw_speeds(key: jax.Array, fit: BehaviourFit, cls: np.ndarray) -> np.ndarray:
    """Each artefact's preferred speed ``(n,)`` from its class's fitted between-person law:
    running with probability ``run_fraction``, then lognormal (walking or running ``mu,
    sigma``; :func:`~are_stats.behaviour.preferred_speeds`)."""
    k_run, k_speed = split_key(key)
    u = key_uniform(k_run, cls.shape)
    run = u < np.nan_to_num(np.asarray(fit.run_fraction, float)[cls])
    mu = np.where(run, fit.run_mu[cls], fit.speed_mu[cls])
    sd = np.nan_to_num(np.where(run, fit.run_sigma[cls], fit.speed_sigma[cls]))
    return preferred_speeds(k_speed, np.exp(mu), sd)


def _at_speed(
    plan: pd.DataFrame, t0: np.ndarray, stay: np.ndarray, speed: np.ndarray, step: float
) -> pd.DataFrame:
    """Planned paths walked at constant speeds: track ``i`` walks its path at ``speed[i]``
    from ``t0[i]``, sampled every ``step`` seconds for ``stay[i]`` seconds (and at its end),
    standing at the path's end once there.

    Parameters
    ----------
    plan : pandas.DataFrame
        ``scenario, id, x, y``: each track's rows together, in the order of its path.
    t0, stay, speed : (n_tracks,) float
        Start (s), duration (s) and speed (m/s, > 0) of each track, in the plan's order.
    step : float
        Sampling period (s).

    Returns
    -------
    pandas.DataFrame
        ``scenario, id, t, x, y, yaw`` (``yaw`` 0: the walk sets the heading).
    """
    sc, ids = plan["scenario"].to_numpy(), plan["id"].to_numpy()
    new = np.r_[True, (sc[1:] != sc[:-1]) | (ids[1:] != ids[:-1])]
    start = np.flatnonzero(new)
    stop = np.r_[start[1:], len(plan)] - 1
    xy = plan[["x", "y"]].to_numpy(float)
    seg = np.r_[0.0, np.hypot(*np.diff(xy, axis=0).T)]
    seg[start] = 0.0
    arc = np.cumsum(seg)
    arc -= np.repeat(arc[start], stop - start + 1)  # arc length along each track
    length = arc[stop]
    n_at = np.floor(stay / step + 1e-9).astype(np.int64) + 1
    tail = (n_at - 1) * step < stay - 1e-9  # the stay ends between two samples
    n_at += tail
    total = int(n_at.sum())
    check_memory(total * 80.0, f"the motion checks' {total} replicated samples", "n_replicates")
    track = np.repeat(np.arange(start.size), n_at)
    first_at = np.r_[0, np.cumsum(n_at)[:-1]]
    tau = (np.arange(total) - first_at[track]) * step
    tau[(first_at + n_at - 1)[tail]] = stay[tail]
    # the point at arc length min(speed tau, length): every track's arcs on one increasing
    # key, the segment of each sample by one binary search
    s_at = np.minimum(speed[track] * tau, length[track])
    offset = np.r_[0.0, np.cumsum(length + 1.0)[:-1]]
    owner = np.repeat(np.arange(start.size), stop - start + 1)
    k = np.searchsorted(arc + offset[owner], s_at + offset[track], side="right") - 1
    k = np.clip(k, start[track], np.maximum(stop[track] - 1, start[track]))
    k1 = np.minimum(k + 1, stop[track])
    span = arc[k1] - arc[k]
    frac = np.where(span > 0, (s_at - arc[k]) / np.where(span > 0, span, 1.0), 0.0)
    pos = xy[k] + np.clip(frac, 0.0, 1.0)[:, None] * (xy[k1] - xy[k])
    return pd.DataFrame(
        {
            "scenario": sc[start][track],
            "id": ids[start][track],
            "t": t0[track] + tau,
            "x": pos[:, 0],
            "y": pos[:, 1],
            "yaw": 0.0,
        }
    )


def _until_arrived(tracks: pd.DataFrame, end: np.ndarray, tol: float) -> pd.DataFrame:
    """Each track cut at its first sample within ``tol`` of its exit ``end`` (it has
    arrived, and leaves), whole where it never gets there (NaN: never cut).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``scenario, id, t, x, y, ...``, sorted by ``scenario, id, t``.
    end : (n_tracks, 2) float
        Each track's exit, in the tracks' order.
    tol : float
        Metres.
    """
    sc, ids = tracks["scenario"].to_numpy(), tracks["id"].to_numpy()
    new = np.r_[True, (sc[1:] != sc[:-1]) | (ids[1:] != ids[:-1])]
    start = np.flatnonzero(new)
    kid = np.cumsum(new) - 1
    xy = tracks[["x", "y"]].to_numpy(float)
    row = np.arange(len(tracks))
    with np.errstate(invalid="ignore"):
        there = np.hypot(*(xy - end[kid]).T) <= tol
    arrived = np.minimum.reduceat(np.where(there, row, len(tracks)), start)
    return tracks[row <= arrived[kid]].reset_index(drop=True)


def _replicate_tracks(
    key: int | jax.Array,
    behaviour_fit: BehaviourFit,
    observed_tracks: pd.DataFrame,
    n_replicates: int,
    *,
    dt_out: float | None = None,
    interaction: bool | SocialForce = True,
    grid: OccupancyGrid | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> pd.DataFrame:
    """The observed people walked again ``n_replicates`` times by the fitted model.

    A replicate keeps what the checks do not test: every observed person's entry, arrival
    time, label and arrival group (the log's groups, as
    :func:`~are_stats.logs.tracks_to_lifecycle` infers them). The model decides the rest, as
    generation does (:func:`~are_stats.scenarios.scene_tracks`): the exit, drawn given the
    entry and the observed stay, and the route to it
    (:func:`~are_stats.behaviour.simulate_behaviour_tracks`); the walk among the others
    under the social force (:func:`~are_stats.behaviour.social_force_tracks`: the fit's
    interaction parameters, the members of a group on their leader's route, in formation).
    Each person (each group: one pace) walks at a **preferred speed** drawn from the
    fitted between-person law (:func:`~are_stats.behaviour.preferred_speeds`), varied
    within the person as the fit says (its speed's and heading's OU processes,
    ``speed_within_sd`` .. ``heading_within_time``, as generation walks them), and leaves
    when it reaches its exit (:data:`ARRIVED`); a person without a reachable exit stands
    through its stay. Generation instead times a path to end with its stay: there the
    stay is the traffic model's, a draw from the model; here it is the log's, and that
    timing would copy the observed speeds into the replicates (a band of width 0).

    Parameters
    ----------
    key : int or jax PRNG key
    behaviour_fit : BehaviourFit
    observed_tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``].
    n_replicates : int
    dt_out : float or None
        Sampling period (default: the observed median period).
    interaction : bool or SocialForce
        The social force people walk with (``True``: the published parameters; ``False``:
        the planned paths at the preferred speeds, nobody giving way).
    grid : OccupancyGrid, optional
        The map whose walls repel (default: the behaviour's cells, occupied where not free).
    progress : callable, optional
        ``progress(done, total, what)`` after each step: the routes' chunks of exits solved
        (:func:`~are_stats.behaviour.simulate_behaviour_tracks`), then the social force's
        windows (:func:`~are_stats.behaviour.social_force_tracks`); until the walk begins,
        it counts as one step.

    Returns
    -------
    pandas.DataFrame
        ``scenario, id, t, x, y, yaw``, sorted by ``scenario, id, t``: ``scenario`` is the
        replicate.
    """
    fit = behaviour_fit
    n_rep = int(n_replicates)
    if n_rep < 1:
        raise ValueError(f"n_replicates: expected an integer >= 1, got {n_replicates!r}")
    params = _social(interaction)
    if grid is None:
        origin = np.asarray(fit.origin, float)
        grid = OccupancyGrid(np.where(fit.free, 0, 100), fit.cell, (origin[0], origin[1], 0.0))
    g = observed_tracks.sort_values(["id", "t"], kind="stable").groupby("id", sort=True)
    first, last = g.first(), g.last()
    base = pd.DataFrame(
        {
            "id": first.index.to_numpy(),
            "t_arrive": first["t"].to_numpy(float),
            "t_leave": last["t"].to_numpy(float),
            "x": first["x"].to_numpy(float),
            "y": first["y"].to_numpy(float),
        }
    )
    m = len(base)
    if "label" in observed_tracks.columns:
        base["label"] = first["label"].astype(str).to_numpy()
    names = {c: i for i, c in enumerate(fit.classes)}
    cls = np.array([names.get(str(v), 0) for v in base.get("label", [""] * m)], np.int64)
    # the log's groups: a member takes its leader's route and pace (no plan of its own)
    label = _log_groups(observed_tracks) if params is not None else {}
    code = pd.factorize(pd.Series([label.get(i) for i in base["id"]], dtype=object))[0]
    leader = formation(np.zeros(m), np.where(code >= 0, code, None), base["t_arrive"])[0]
    leads = leader == np.arange(m)
    step = float(dt_out) if dt_out is not None else _sampling_period(observed_tracks)
    k_plan, k_speed = split_key(_key(key))
    arts = pd.concat([base[leads].assign(scenario=r) for r in range(n_rep)], ignore_index=True)
    # the routes: the plan's timing (its path ending at the stay's end) is replaced, so it
    # is sampled coarsely (its rows keep every vertex whatever the period)
    say = progress or (lambda done, total, what: None)
    walks = params is not None
    planned = [0]

    def plan_step(done: int, total: int) -> None:
        planned[0] = total
        say(done, total + walks, f"routes, {done} of {total}")

    def walk_step(done: int, total: int) -> None:
        say(planned[0] + done, planned[0] + total, f"social force, window {done} of {total}")

    plan = simulate_behaviour_tracks(
        k_plan, fit, arts, dt_out=max(step, PLAN_PERIOD), progress=plan_step
    )
    plan = plan[["scenario", "id", "x", "y"]]
    if not leads.all():  # a member: from its own entry along its leader's planned path
        mem = np.flatnonzero(~leads)
        pairs = pd.DataFrame(
            {"lead": base["id"].to_numpy()[leader[mem]], "member": base["id"].to_numpy()[mem]}
        )
        follow = plan.merge(pairs, left_on="id", right_on="lead").drop(columns=["id", "lead"])
        entry = base.iloc[mem][["id", "x", "y"]].rename(columns={"id": "member"})
        entry = pd.concat([entry.assign(scenario=r) for r in range(n_rep)], ignore_index=True)
        members = pd.concat([entry.assign(seq=0), follow.assign(seq=1)], ignore_index=True)
        members = members.sort_values(["scenario", "member", "seq"], kind="stable")
        plan = pd.concat(
            [plan, members.rename(columns={"member": "id"})[["scenario", "id", "x", "y"]]],
            ignore_index=True,
        )
        pos = pd.Index(base["id"]).get_indexer(plan["id"])
        order = np.lexsort((np.arange(len(plan)), pos, plan["scenario"].to_numpy()))
        plan = plan.iloc[order].reset_index(drop=True)
    # per track of the plan (replicate-major, then the observed order): who it is
    sc, ids = plan["scenario"].to_numpy(), plan["id"].to_numpy()
    new = np.r_[True, (sc[1:] != sc[:-1]) | (ids[1:] != ids[:-1])]
    who = pd.Index(base["id"]).get_indexer(ids[new])
    rep = sc[new].astype(np.int64)
    drawn = _draw_speeds(k_speed, fit, np.tile(cls, n_rep)).reshape(n_rep, m)
    speed = drawn[rep, leader[who]]  # a group walks at its leader's pace
    xy = plan[["x", "y"]].to_numpy(float)
    seg = np.r_[0.0, np.hypot(*np.diff(xy, axis=0).T)]
    seg[new] = 0.0
    length = np.add.reduceat(seg, np.flatnonzero(new))
    moving = length > 0
    stay_obs = (base["t_leave"] - base["t_arrive"]).to_numpy(float)[who]
    # long enough to reach the exit; cut where it arrives
    stay = np.where(moving, length / speed + SLACK, stay_obs)
    walked = _at_speed(plan, base["t_arrive"].to_numpy(float)[who], stay, speed, step)
    if params is not None:
        group = np.where(code >= 0, code, -1)[pd.Index(base["id"]).get_indexer(walked["id"])]
        # each walker's pace and heading vary as the fit says (its own processes: the key
        # folded with 26, the routes and speeds drawn as before)
        row_cls = cls[pd.Index(base["id"]).get_indexer(walked["id"])]
        variation = _variation(fold_in_key(_key(key), 26), fit, row_cls)
        # arriving walking, as generation's people do (arrival_velocities)
        walked = _walk(
            arrival_velocities(walked),
            params,
            grid,
            groups=group,
            progress=walk_step,
            variation=variation,
        ).drop(columns=["vx", "vy"])
    # each walker's exit (its route's end; a member's: its leader's), by (replicate,
    # person); NaN for one that stands
    end = np.full((n_rep * m, 2), np.nan)
    last = np.r_[np.flatnonzero(new)[1:], len(plan)] - 1
    end[rep * m + who] = np.where(moving[:, None], xy[last], np.nan)
    w_sc, w_ids = walked["scenario"].to_numpy(), walked["id"].to_numpy()
    w_new = np.r_[True, (w_sc[1:] != w_sc[:-1]) | (w_ids[1:] != w_ids[:-1])]
    w_key = w_sc[w_new].astype(np.int64) * m + pd.Index(base["id"]).get_indexer(w_ids[w_new])
    return _until_arrived(walked, end[w_key], ARRIVED)


def motion_checks(
    key: int | jax.Array,
    behaviour_fit: BehaviourFit,
    observed_tracks: pd.DataFrame,
    n_replicates: int = 50,
    *,
    dt_out: float | None = None,
    still_distance: float = 1.0,
    exit_radius: float = 0.5,
    interaction: bool | SocialForce = True,
    grid: OccupancyGrid | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> tuple[pd.DataFrame, dict[str, np.ndarray | pd.DataFrame]]:
    """Observed motion statistics against their posterior-predictive bands.

    The observed people are walked again ``n_replicates`` times by the model as generation
    walks people (:func:`_replicate_tracks`: their entries, arrivals, stays, labels and
    groups kept; exits, routes and preferred speeds drawn from the fit; the walk under the
    social force among the others, groups in formation), sampled at the log's period. They
    are measured as the tracker measured the log: with its position noise added
    (:func:`tracker_noise`), so that the jitter, which lengthens a path, does not pass for a
    model that walks too straight or too slowly (the fitted speeds are free of it:
    :func:`~are_stats.fitting.fit_behaviour`).

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicated tracks.
    behaviour_fit : BehaviourFit
        The fitted behaviour (:func:`~are_stats.fitting.fit_behaviour`).
    observed_tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``]: the tracks (``M`` of them) the fit is criticised on.
    n_replicates : int
        Replicated sets of ``M`` tracks.
    dt_out : float or None
        Sampling period of the replicated tracks (default: the observed median period).
    still_distance, exit_radius : float
        See :func:`track_statistics`.
    interaction : bool or SocialForce
        The social force the replicates walk with (``True``: the published parameters; pass
        the fit's, :attr:`~are_stats.fitting.Fit.interaction`, to check what generation
        makes; ``False``: nobody gives way).
    grid : OccupancyGrid, optional
        The map whose walls repel the walkers (default: the behaviour's cells).
    progress : callable, optional
        ``progress(done, total, what)`` after each step of the replicates (as
        :meth:`~are_stats._stage_clock.StageClock.steps` takes them): their routes' chunks of
        exits solved, then the social force's windows (``total`` grows by the windows
        when the walk begins).

    Returns
    -------
    table : pandas.DataFrame
        Indexed by statistic (:data:`MOTION_STATISTICS`): ``observed``, ``model_5%``,
        ``model_50%``, ``model_95%`` and ``model_flag`` (observed outside the 90% band by
        more than :data:`MOTION_TOLERANCE`, :func:`band_flags`).
    replicates : dict
        ``"summary"``: ``(R, 5)`` replicated statistics (columns in table order);
        ``"tracks"``: per-track statistics of every replicate (:func:`track_statistics`, the
        ``scenario`` level is the replicate); ``"observed"``: those of the observed tracks.
    """
    kw = {"still_distance": still_distance, "exit_radius": exit_radius}
    obs_st = track_statistics(observed_tracks, **kw)
    observed = _summary(obs_st)
    sim = _replicate_tracks(
        key,
        behaviour_fit,
        observed_tracks,
        n_replicates,
        dt_out=dt_out,
        interaction=interaction,
        grid=grid,
        progress=progress,
    )
    # the replicates as the tracker would measure them: with the log's position noise,
    # which lengthens an observed path (straighter and slower people than the log's
    # otherwise); the fitted preferred speeds are free of that noise (fit_behaviour)
    noise = tracker_noise(observed_tracks)
    if noise > 0:
        jitter = noise * np.asarray(
            jax.random.normal(fold_in_key(_key(key), 7), (len(sim), 2)), float
        )
        sim = sim.assign(
            x=sim["x"].to_numpy(float) + jitter[:, 0], y=sim["y"].to_numpy(float) + jitter[:, 1]
        )
    rep_st = track_statistics(sim, **kw)
    scen = rep_st.index.get_level_values("scenario").to_numpy()
    summary = np.asarray([_summary(rep_st[scen == r]) for r in range(int(n_replicates))], float)
    table = pd.DataFrame(index=pd.Index(MOTION_STATISTICS, name="statistic"))
    table["observed"] = observed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        q = np.nanquantile(summary, [0.05, 0.5, 0.95], axis=0)
    table["model_5%"], table["model_50%"], table["model_95%"] = q
    table["model_flag"] = band_flags(MOTION_STATISTICS, table["observed"].to_numpy(), q[0], q[2])
    return table, {"summary": summary, "tracks": rep_st, "observed": obs_st}


# ---------------------------------------------------------------------- held-out likelihood
def _policies(fit: BehaviourFit, c: int, goals: np.ndarray, tol: float = 1e-3) -> np.ndarray:
    """Soft policies ``(G, 4, 5, H, W)`` of class ``c`` to the cells ``goals (G, 2)``: those
    of :func:`~are_stats.behaviour.soft_policy` (at most ``10 x`` the longest geodesic
    distance plus 20 epochs, stopped at ``tol``), computed by one program for any cap,
    tolerance and ``G`` up to :data:`~are_stats.behaviour.GOAL_BUCKET`, the program of
    generation's solves (``soft_policy``'s ``bucket``: the padding goals repeat the last
    one, so the largest change that stops the solve, and every real goal's policy, are the
    same)."""
    goals = np.asarray(goals, np.int64).reshape(-1, 2)
    dist = fit.geodesic(goals)
    finite = dist[np.isfinite(dist)]
    k = int(math.ceil(10 * (finite.max() if finite.size else 1.0))) + 20
    sol = fit.soft_policy(
        c,
        ~np.asarray(fit.free, bool),
        goals,
        n_epochs=k,
        tol=tol,
        bucket=GOAL_BUCKET,
    )
    return np.asarray(sol.policy)


def score_moves(behaviour_fit: BehaviourFit, tracks: pd.DataFrame) -> pd.DataFrame:
    """Log-likelihood of each track's moves under the fitted policy and a random walk.

    Tracks are discretised as in the fit (:func:`~are_stats.fitting.discretise_tracks` on
    the fit's grid at its class epoch ``dt``); the goal of a track is its last cell. The
    random walk is the same hidden-Markov likelihood with the policy uniform over ``stay,
    forward, left, right`` and the fitted slip.

    Parameters
    ----------
    behaviour_fit : BehaviourFit
    tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``]; labels the fit does not know use its first class.

    Returns
    -------
    pandas.DataFrame
        One row per track with at least one move: ``id``, ``label``, ``n_moves``,
        ``loglik_policy``, ``loglik_random_walk``.
    """
    fit = behaviour_fit
    names = {c: i for i, c in enumerate(fit.classes)}
    labels = (
        tracks["label"].astype(str)
        if "label" in tracks.columns
        else pd.Series(fit.classes[0], tracks.index)
    )
    cls = labels.map(lambda v: names.get(v, 0)).to_numpy()
    ok = path_free(~fit.free)
    rows = []
    for c in np.unique(cls):
        tab = tracks[cls == c]
        paths, ids = discretise_tracks(tab, fit.free, fit.cell, fit.origin, float(fit.dt[c]))
        keep = [i for i, p in enumerate(paths) if len(p) >= 2]
        if not keep:
            continue
        paths = [paths[i] for i in keep]
        ids = ids[keep]
        obs = move_observations(paths)
        pol = _policies(fit, int(c), obs.goals)
        uniform = np.zeros_like(pol)
        uniform[:, :, [0, 1, 3, 4]] = 0.25
        slip = float(fit.slip[c])
        ll_p = track_log_likelihoods(pol, ok, slip, obs)
        ll_u = track_log_likelihoods(uniform, ok, slip, obs)
        n_mv = (obs.move >= 0).sum(axis=1)
        rows.append(
            pd.DataFrame(
                {
                    "id": ids,
                    "label": fit.classes[c],
                    "n_moves": n_mv,
                    "loglik_policy": ll_p.astype(float),
                    "loglik_random_walk": ll_u.astype(float),
                }
            )
        )
    cols = ["id", "label", "n_moves", "loglik_policy", "loglik_random_walk"]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=cols)


def _per_move(scores: pd.DataFrame) -> dict[str, float]:
    m = scores["n_moves"].to_numpy(float)
    lp = scores["loglik_policy"].to_numpy(float)
    lu = scores["loglik_random_walk"].to_numpy(float)
    d = lp - lu
    n, tot = len(m), m.sum()
    r = d.sum() / tot if tot > 0 else math.nan
    se = (
        math.sqrt(n / (n - 1) * float(((d - r * m) ** 2).sum())) / tot
        if n > 1 and tot > 0
        else math.nan
    )
    return {
        "n_tracks": float(n),
        "n_moves": float(tot),
        "policy_per_move": float(lp.sum() / tot) if tot > 0 else math.nan,
        "random_walk_per_move": float(lu.sum() / tot) if tot > 0 else math.nan,
        "difference_per_move": float(r),
        "difference_se": float(se),
    }


def heldout_log_likelihood(
    key: int | jax.Array,
    tracks: pd.DataFrame,
    free_mask: npt.ArrayLike,
    resolution: float,
    origin: npt.ArrayLike,
    *,
    train_fraction: float = 0.7,
    **fit_kwargs: Any,
) -> tuple[dict[str, float], BehaviourFit]:
    """Held-out log-likelihood per move of the fitted policy beside a random walk.

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the split by track id.
    tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``].
    free_mask : (H, W) bool
        Free cells of the map.
    resolution : float
        Map cell side (m).
    origin : (2,) float
        World ``(x, y)`` of the map's corner.
    train_fraction : float
        Fraction of the track ids fitted (the rest is scored).
    **fit_kwargs
        Passed to :func:`~are_stats.fitting.fit_behaviour`.

    Returns
    -------
    result : dict of str to float
        ``n_tracks``, ``n_moves`` (held out), ``policy_per_move``, ``random_walk_per_move``,
        ``difference_per_move`` (policy minus random walk; positive: the policy predicts the
        held-out moves better) and ``difference_se`` (standard error over held-out tracks).
    fit : BehaviourFit
        The fit of the training tracks.
    """
    if not 0.0 < train_fraction < 1.0:
        raise ValueError(f"train_fraction: expected a float in (0, 1), got {train_fraction!r}")
    ids = np.unique(tracks["id"].to_numpy())
    rng = _rng(key)
    n_train = min(max(1, round(train_fraction * len(ids))), len(ids) - 1)
    train = rng.permutation(len(ids))[:n_train]
    is_train = tracks["id"].isin(ids[train])
    fit = fit_behaviour(tracks[is_train], free_mask, resolution, origin, **fit_kwargs)
    scores = score_moves(fit, tracks[~is_train])
    return _per_move(scores), fit


# ---------------------------------------------------------------------- figure
def plot_motion_checks(
    table: pd.DataFrame,
    replicates: Mapping[str, np.ndarray | pd.DataFrame],
    *,
    heldout: dict[str, float] | None = None,
    displacement: pd.DataFrame | None = None,
) -> Figure:
    """Observed vs replicated motion: speeds, straightness, still fraction, time to exit.

    Parameters
    ----------
    table, replicates
        From :func:`motion_checks`.
    heldout : dict, optional
        From :func:`heldout_log_likelihood` (shown as text).
    displacement : pandas.DataFrame, optional
        From :func:`displacement_errors` (shown as text).

    Returns
    -------
    matplotlib.figure.Figure
        Six panels: per-track speed, straightness and time-to-exit/stay distributions
        (observed histogram vs the pooled replicates), the replicated still fraction and
        median speed with the observed value, and the numbers.
    """
    import matplotlib  # lazy: figures only (pyplot +0.7 s CPU on `import are_stats.fitting`)

    if "matplotlib.pyplot" not in sys.modules:  # headless default; never switch a live
        matplotlib.use("Agg")  # session's backend (a notebook's inline one)
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    obs, rep = replicates["observed"], replicates["tracks"]
    summary = replicates["summary"]
    fig, axes = plt.subplots(2, 3, figsize=(12.5, 7.5), constrained_layout=True)

    def flag(ax: Axes, stat: str) -> None:
        if bool(table.loc[stat, "model_flag"]):
            ax.set_title(
                ax.get_title() + "\nobserved outside the 90% band", fontsize=10, color="tab:red"
            )

    def say(ax: Axes, text: str) -> None:  # a panel with nothing to draw says why
        ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.35")
        ax.set_xticks([])

    def dist(ax: Axes, col: str, title: str, xlabel: str, stat: str, moving_only: bool) -> None:
        o, r = obs, rep
        if moving_only:
            o, r = o[~o["still"]], r[~r["still"]]
        ov = o[col].to_numpy(float)
        rv = r[col].to_numpy(float)
        ov, rv = ov[np.isfinite(ov)], rv[np.isfinite(rv)]
        allv = np.concatenate([ov, rv])
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel, fontsize=9)
        ax.set_yticks([])
        if not allv.size:
            say(ax, "not defined: no moving tracks" if moving_only else "not defined")
            return
        ax.set_ylabel("density of tracks", fontsize=9)
        lo, hi = np.quantile(allv, [0.002, 0.998])
        lo, hi = min(lo, ov.min(initial=lo)), max(hi, ov.max(initial=hi))
        pad = 0.05 * (hi - lo) if hi > lo else 0.5
        bins = np.linspace(lo - pad, hi + pad, 30)
        ax.hist(
            rv, bins=bins, density=True, color="tab:blue", alpha=0.5, label="model: tracks pooled"
        )
        ax.hist(
            ov,
            bins=bins,
            density=True,
            histtype="step",
            color="black",
            lw=2,
            label="observed tracks",
        )
        ax.axvline(
            table.loc[stat, "observed"], color="black", ls="--", lw=1, label="observed median"
        )
        ax.axvspan(
            table.loc[stat, "model_5%"],
            table.loc[stat, "model_95%"],
            color="tab:blue",
            alpha=0.12,
            label="model: 90% band of the median",
        )
        flag(ax, stat)

    n_rep = len(summary)
    dist(
        axes[0, 0],
        "speed",
        "walking speed per track (m/s)",
        "walking speed (m/s)",
        MOTION_STATISTICS[0],
        False,
    )
    dist(
        axes[0, 1],
        "straightness",
        "straightness (net / path), moving tracks",
        "net displacement / path length",
        MOTION_STATISTICS[2],
        True,
    )
    dist(
        axes[0, 2],
        "exit_fraction",
        "time from entry to exit / stay, moving tracks",
        "time to exit / stay (fraction of the stay)",
        MOTION_STATISTICS[4],
        True,
    )
    for ax, j, title, xlabel in (
        (
            axes[1, 0],
            3,
            "fraction still (net < 1 m) per replicate",
            "share of tracks with net displacement < 1 m",
        ),
        (
            axes[1, 1],
            1,
            "speed spread (IQR, m/s) per replicate",
            "IQR of the tracks' walking speeds (m/s)",
        ),
    ):
        stat = MOTION_STATISTICS[j]
        v = summary[:, j][np.isfinite(summary[:, j])]
        o = table.loc[stat, "observed"]
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel, fontsize=9)
        ax.set_yticks([])
        if not v.size and not np.isfinite(o):
            say(ax, "not defined")
            continue
        if v.size and np.isfinite(o) and v.min() == v.max() == o:  # a lone bar says nothing
            what = (
                f"no track still (net < 1 m)\nin the log or in any\nof the {n_rep} replicates"
                if j == 3 and o == 0
                else f"the log and all {n_rep} replicates:\n{o:.3g}"
            )
            say(ax, what)
            continue
        ax.set_ylabel("replicates", fontsize=9)
        if v.size:
            lo, hi = min(v.min(), o), max(v.max(), o)
            pad = 0.05 * (hi - lo) if hi > lo else 0.05
            ax.hist(
                v,
                bins=np.linspace(lo - pad, hi + pad, 25),
                color="tab:blue",
                alpha=0.55,
                label="model: one value per replicate",
            )
        if np.isfinite(o):
            ax.axvline(o, color="black", lw=2, label="observed value")
        flag(ax, stat)
    ax = axes[1, 2]
    entries: dict[str, Artist] = {}  # one legend for every panel, under them
    for a in axes.flat[:5]:
        for handle, label in zip(*a.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if entries:
        fig.legend(
            list(entries.values()),
            list(entries),
            fontsize=8,
            frameon=False,
            loc="outside lower center",
            ncols=3,
        )
    ax.axis("off")
    lines = ["statistic: observed [model 5%, 95%]"]
    for stat, r in table.iterrows():
        mark = "  outside" if r["model_flag"] else ""
        band = f"[{r['model_5%']:.3g}, {r['model_95%']:.3g}]"
        lines.append(f"{stat}: {r['observed']:.3g} {band}{mark}")
    if heldout is not None:
        lines += [
            "",
            f"held-out log-lik per move ({int(heldout['n_moves'])} moves, "
            f"{int(heldout['n_tracks'])} tracks):",
            f"  policy {heldout['policy_per_move']:.3f}, "
            f"random walk {heldout['random_walk_per_move']:.3f}",
            f"  difference {heldout['difference_per_move']:.3f} +/- {heldout['difference_se']:.3f}",
        ]
    if displacement is not None:
        lines += ["", f"ADE / FDE (m), {int(displacement['n_windows'].iloc[0])} windows 8 + 12:"]
        for m, r in displacement.iterrows():
            k = f" (K={int(r['K'])})" if r["K"] > 1 else ""
            lines.append(f"  {m}{k}: {r['ADE']:.2f} / {r['FDE']:.2f}")
    ax.text(
        0.0,
        1.0,
        "\n".join(lines),
        ha="left",
        va="top",
        fontsize=7.5,
        family="monospace",
        transform=ax.transAxes,
    )
    fig.suptitle(f"Motion checks: observed tracks vs {n_rep} replicates of the fitted behaviour")
    return fig
