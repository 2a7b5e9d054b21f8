"""Tracks of artefacts that walk like the people in the log (issue 16).

:func:`simulate_behaviour_tracks` is the generator behind ``are-stats generate --behaviours``
with a fitted :class:`~are_stats.behaviour.BehaviourFit`. An artefact of a class the log
showed standing (:attr:`BehaviourFit.standing <are_stats.behaviour.BehaviourFit.standing>`:
none of its tracks walked) stands at its entry for its whole stay. Each other artefact

1. gets its class's walking (or, with probability ``run_fraction``, running) speed law,
   lognormal ``(mu, sigma)``, and a reach: the path length its fast walkers
   (``exp(mu + 2 sigma)``) cover in its stay;
2. gets an exit drawn from the exit density given its entry **and its stay**, reachable
   within ``0.9`` of the reach (:meth:`BehaviourFit.draw_exits` with ``stays``): people
   leave when they reach their exit, so a stay ``s`` and a path of length ``L`` mean a
   walking speed ``L / s``, and exits are weighted by the speed law at ``L / s``; without
   a reachable exit it stays where it entered;
3. walks there with the stationary soft policy of its class (:func:`soft_backward_induction`,
   ``beta``, ``slip`` and the cell reward of any fitted feature weights,
   :meth:`BehaviourFit.cell_reward`), sampled epoch by epoch (:func:`sample_soft_paths`);
4. becomes a continuous track: the distinct cells of its path, smoothed by a centred moving
   average of ``smooth`` cells (ends fixed), walked at the speed that ends the path at
   ``t_leave``, within the class's slow and fast walkers (``exp(mu -+ 2 sigma)``: beyond
   them the artefact reaches its exit early and stands there, or leaves while still
   walking); turning in place takes no time, a ``stay`` or a blocked move a pause of one
   epoch. Positions are sampled every ``dt_out`` seconds from ``t_arrive`` to
   ``t_leave``. ``yaw`` follows the direction of motion (any angle).

5. plans alone: artefacts do not see each other here. Generated people give way to each
   other while they walk, under the social force of the one assembly
   (:func:`~are_stats.scenarios.scene_tracks`, :func:`social_force_tracks`); moving
   artefacts without a social force of their own are kept apart by the AR-builder's rule
   (DECISIONS 9, :meth:`~are_stats.builder.ARBuilder.resolve_scene`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_positive
from are_stats.behaviour._mdp import path_free
from are_stats.behaviour._model import BehaviourFit
from are_stats.behaviour._motion import string_pull_many, walk_times_many
from are_stats.behaviour._rewards import FORWARD, HEADINGS, LEFT, RIGHT, RUN, STAY
from are_stats.behaviour._social import _interp_runs
from are_stats.behaviour._soft import GOAL_BUCKET

__all__ = [
    "continuous_path",
    "continuous_paths",
    "path_points",
    "positions_at",
    "sample_soft_paths",
    "simulate_behaviour_tracks",
    "smooth_path",
]

_DROW = np.array([d[0] for d in HEADINGS])
_DCOL = np.array([d[1] for d in HEADINGS])
_COLUMNS = ("scenario", "id", "t", "x", "y", "yaw")


def sample_soft_paths(
    rng: np.random.Generator,
    policy: np.ndarray,
    occupied: np.ndarray,
    slip: float,
    starts: np.ndarray,
    goal_index: np.ndarray,
    goals: np.ndarray,
    horizons: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample state paths from stationary soft policies (slip and blocking as in the MDP).

    Parameters
    ----------
    rng : numpy.random.Generator
    policy : (G, 4, 5, H, W) float
        ``pi(a | row, col, h)`` per goal.
    occupied : (H, W) bool
    slip : float
    starts : (B, 3) int
        ``(row, col, heading)``.
    goal_index : (B,) int
        Goal (index into ``policy`` and ``goals``) of each artefact.
    goals : (G, 2) int
    horizons : (B,) int
        Epochs each artefact may act; it stops acting on reaching its goal.

    Returns
    -------
    states : (B, D + 1, 3) int
        ``(row, col, heading)`` per epoch, ``D = max(horizons)``; after the horizon or the
        goal the last state repeats.
    actions : (B, D) int
        The action of each epoch, ``-1`` once the artefact no longer acts.
    """
    pol = np.asarray(policy, np.float64)
    ok = path_free(np.asarray(occupied, bool))
    b = len(starts)
    d = int(np.max(horizons, initial=0))
    states = np.zeros((b, d + 1, 3), np.int64)
    actions = np.full((b, d), -1, np.int64)
    cur = np.asarray(starts, np.int64).copy()
    states[:, 0] = cur
    gi = np.asarray(goal_index, np.int64)
    gl = np.asarray(goals, np.int64)
    for e in range(d):
        active = (e < horizons) & ~(cur[:, :2] == gl[gi]).all(axis=1)
        p = pol[gi, cur[:, 2], :, cur[:, 0], cur[:, 1]]  # (B, 5)
        cdf = np.cumsum(p, axis=1)
        u = rng.random(b) * cdf[:, -1]
        a = np.minimum((u[:, None] > cdf).sum(axis=1), 4)
        a = np.where(active, a, -1)
        nxt = cur.copy()
        mv = (a == FORWARD) | (a == RUN)
        k = np.where(a == RUN, 2, 1)
        v = rng.random(b)
        side = np.where(v < 1 - slip, 0, np.where(v < 1 - slip / 2, 1, -1))
        direction = (cur[:, 2] + side) % 4
        free = ok[direction, k - 1, cur[:, 0], cur[:, 1]]
        go = mv & free
        nxt[go, 0] += k[go] * _DROW[direction[go]]
        nxt[go, 1] += k[go] * _DCOL[direction[go]]
        nxt[a == LEFT, 2] = (cur[a == LEFT, 2] + 1) % 4
        nxt[a == RIGHT, 2] = (cur[a == RIGHT, 2] - 1) % 4
        actions[:, e] = a
        cur = nxt
        states[:, e + 1] = cur
    return states, actions


def smooth_path(points: np.ndarray, window: int = 5) -> np.ndarray:
    """Centred moving average with the window shrunk near the ends (which stay fixed).

    Parameters
    ----------
    points : (n, 2) float
    window : int
        Odd window length (points).

    Returns
    -------
    (n, 2) float
    """
    p = np.asarray(points, float)
    n = len(p)
    half = max(int(window) // 2, 0)
    if n < 3 or half == 0:
        return p.copy()
    c = np.concatenate([np.zeros((1, 2)), np.cumsum(p, axis=0)])
    i = np.arange(n)
    k = np.minimum(np.minimum(i, n - 1 - i), half)
    return (c[i + k + 1] - c[i - k]) / (2 * k + 1)[:, None]


def continuous_path(
    states: np.ndarray,
    actions: np.ndarray,
    fit: BehaviourFit,
    speed: float,
    start_xy: np.ndarray,
    end_xy: np.ndarray | None,
    smooth: int = 0,
    *,
    rng: np.random.Generator | None = None,
    within_sd: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """One artefact's continuous path from its sampled MDP states and actions.

    The route (the cells the artefact moves through, from ``start_xy``) becomes an
    any-angle path (:func:`~are_stats.behaviour.string_pull` over ``fit.free``: straight
    wherever the walker sees far enough, so an open crossing is one segment), walked at
    ``speed`` with the within-person variation ``within_sd``
    (:func:`~are_stats.behaviour.walk_times`): the MDP decides the route, not the timing,
    so its stays and blocked moves are not pauses. :func:`continuous_paths` does the same
    for many artefacts at once.

    With ``smooth > 1`` the path of the grid version is returned instead: each move goes to
    the centre of the next cell, a pause (stay, or a blocked move) holds for one epoch, and
    the distinct vertices are smoothed (:func:`smooth_path`, ``smooth`` vertices) and
    re-timed at ``speed``.

    Parameters
    ----------
    states : (T + 1, 3) int
        Sampled states ``(row, col, heading)`` (:func:`sample_soft_paths`).
    actions : (T,) int
        The actions taken (``-1`` after the path ends).
    fit : BehaviourFit
        Grid (cell size, origin and free cells) of the states.
    speed : float
        Walking speed (m/s).
    start_xy : (2,) float
        World position of the first vertex.
    end_xy : (2,) float or None
        World position of the last vertex (default: its cell's centre).
    smooth : int
        ``0`` or ``1``: the any-angle path; more: the smoothed grid path (window in
        vertices).
    rng : numpy.random.Generator, optional
        For ``within_sd > 0``.
    within_sd : float
        Within-person standard deviation of the log speed.

    Returns
    -------
    t : (m,) float
        Vertex times (s) from 0.
    xy : (m, 2) float
        Vertex positions (m).
    """
    return continuous_paths(
        [(states, actions)],
        fit,
        [speed],
        np.reshape(np.asarray(start_xy, float), (1, 2)),
        [end_xy],
        smooth,
        rng=rng,
        within_sd=within_sd,
    )[0]


def continuous_paths(
    paths: Sequence[tuple[np.ndarray, np.ndarray]],
    fit: BehaviourFit,
    speeds: npt.ArrayLike,
    starts: npt.ArrayLike,
    ends: Sequence[np.ndarray | None] | None = None,
    smooth: int = 0,
    *,
    rng: np.random.Generator | None = None,
    within_sd: float = 0.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`continuous_path` of many artefacts, the same as one after another.

    The any-angle paths are string-pulled together
    (:func:`~are_stats.behaviour.string_pull_many`), then timed in order, so ``rng`` is
    drawn from as by successive :func:`continuous_path` calls and the paths are the same.

    Parameters
    ----------
    paths : sequence of ((T_i + 1, 3) int, (T_i,) int)
        Each artefact's sampled states and actions (:func:`sample_soft_paths`).
    fit : BehaviourFit
        Grid of the states.
    speeds : (P,) float
        Walking speeds (m/s).
    starts : (P, 2) float
        World positions of the first vertices.
    ends : sequence of (2,) float or None, optional
        World positions of the last vertices (None: the last cell's centre).
    smooth, rng, within_sd
        As :func:`continuous_path`.

    Returns
    -------
    list of ((m_i,) float, (m_i, 2) float)
        Each artefact's vertex times (s, from 0) and positions (m).
    """
    speeds = np.asarray(speeds, float).reshape(-1)
    starts = np.asarray(starts, float).reshape(-1, 2)
    ends = [None] * len(paths) if ends is None else list(ends)
    if not len(paths) == len(speeds) == len(starts) == len(ends):
        raise ValueError(
            f"paths, speeds, starts, ends: expected one each per artefact, got {len(paths)}, "
            f"{len(speeds)}, {len(starts)}, {len(ends)}"
        )
    if int(smooth) > 1:
        return [
            _grid_path(st, ac, fit, float(v), p0, end, int(smooth))
            for (st, ac), v, p0, end in zip(paths, speeds, starts, ends, strict=True)
        ]
    # each route: its start, then the centres of the cells it moves through (one
    # cell_to_world for all of them)
    cells = []
    for st, ac in paths:
        ac = np.asarray(ac)
        done = np.flatnonzero(ac < 0)
        cells.append(np.asarray(st)[: (int(done[0]) if done.size else len(ac)) + 1, :2])
    count = np.array([len(c) for c in cells], np.int64)
    flat = np.empty((int(count.sum()), 2))
    first = np.cumsum(count) - count
    flat[first] = starts
    later = np.ones(len(flat), bool)
    later[first] = False
    if later.any():
        flat[later] = fit.cell_to_world(np.concatenate([c[1:] for c in cells]))
    routes = np.split(flat, first[1:])
    for pts, end in zip(routes, ends, strict=True):
        if end is not None and len(pts) > 1:
            pts[-1] = end
    origin = (float(fit.origin[0]), float(fit.origin[1]))
    free = np.asarray(fit.free, bool)
    pulled: list[np.ndarray] = []
    weighted = bool(np.any(np.asarray(fit.weights) != 0.0))
    for b0 in range(0, len(routes), _ROUTE_BLOCK if weighted else max(len(routes), 1)):
        block = slice(b0, b0 + (_ROUTE_BLOCK if weighted else len(routes)))
        grids = _route_grids(free, cells[block]) if weighted else free
        pulled += string_pull_many(routes[block], grids, origin, fit.cell)
    times = walk_times_many(pulled, speeds, rng, within_sd)
    return list(zip(times, pulled, strict=True))


def positions_at(paths: Sequence[tuple[np.ndarray, np.ndarray]], t: npt.ArrayLike) -> np.ndarray:
    """Each timed path's position at the times ``t``, all paths at once.

    Parameters
    ----------
    paths : sequence of ((m_i,) float, (m_i, 2) float)
        Vertex times (s, increasing, ``m_i >= 1``) and positions (m) of each path
        (:func:`continuous_paths`).
    t : (T,) float
        Times (s).

    Returns
    -------
    (P, T, 2) float
        ``np.interp(t, times_i, positions_i[:, k])`` of each path ``i`` and coordinate
        ``k``, bit for bit (a path's first or last vertex before or after its times);
        one pass over all paths instead of a call per path and coordinate (issue 29).
    """
    t = np.asarray(t, float).reshape(-1)
    if not len(paths):
        return np.zeros((0, t.size, 2))
    count = np.array([len(tv) for tv, _ in paths], np.int64)
    bounds = np.r_[0, np.cumsum(count)]
    times = np.concatenate([np.asarray(tv, float) for tv, _ in paths])
    points = np.concatenate([np.asarray(pv, float).reshape(-1, 2) for _, pv in paths])
    run = np.repeat(np.arange(len(paths)), t.size)
    return _interp_runs(np.tile(t, len(paths)), run, times, points, bounds).reshape(-1, t.size, 2)


#: Routes whose own grids (:func:`_route_grids`) are made at once.
_ROUTE_BLOCK = 256


def _route_grids(free: np.ndarray, cells: Sequence[np.ndarray]) -> np.ndarray:
    """``(P, H, W)``: fitted cell rewards make cells unequal, so shortcuts stay within one
    cell of the route (the cells it chose) and the learned preferences shape the path."""
    from scipy import ndimage  # lazy: scipy.ndimage adds 0.2 s CPU to import are_stats.behaviour

    route = np.zeros((len(cells), *free.shape), bool)
    for r, c in zip(route, cells, strict=True):
        r[c[:, 0], c[:, 1]] = True
    near = ndimage.binary_dilation(route, np.ones((1, 3, 3), bool))
    return free[None] & near


def _grid_path(
    states: np.ndarray,
    actions: np.ndarray,
    fit: BehaviourFit,
    speed: float,
    start_xy: np.ndarray,
    end_xy: np.ndarray | None,
    smooth: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`continuous_path` with ``smooth > 1``: the smoothed grid path."""
    step = fit.cell / speed
    pts = [np.asarray(start_xy, float)]
    times = [0.0]
    tnow = 0.0
    cells = states[:, :2]
    for e, a in enumerate(actions):
        if a < 0:
            break
        if (cells[e + 1] != cells[e]).any():
            pts.append(fit.cell_to_world(cells[e + 1])[0])
            tnow += step * float(np.abs(cells[e + 1] - cells[e]).sum())
            times.append(tnow)
        elif a in (STAY, FORWARD, RUN):
            tnow += step  # a pause (stay, or a blocked move)
            pts.append(pts[-1])
            times.append(tnow)
    xy = np.asarray(pts)
    if end_xy is not None and len(xy) > 1:
        xy[-1] = end_xy
    # smooth the geometry of the distinct vertices, then re-time at speed v
    keep = np.concatenate([[True], (np.diff(xy, axis=0) != 0).any(axis=1)])
    geo = smooth_path(xy[keep], smooth)
    xy_s = geo[np.cumsum(keep) - 1]
    seg = np.hypot(*np.diff(xy_s, axis=0).T)
    moving = np.concatenate([[False], (np.diff(xy, axis=0) != 0).any(axis=1)])
    dt_v = np.where(moving[1:], seg / speed, np.diff(np.asarray(times)))
    return np.concatenate([[0.0], np.cumsum(dt_v)]), xy_s


def simulate_behaviour_tracks(
    key: jax.Array,
    fit: BehaviourFit,
    artefacts: pd.DataFrame,
    *,
    dt_out: float | None = None,
    smooth: int = 0,
    chunk: int = GOAL_BUCKET,
    class_labels: Sequence[str] | None = None,
    horizon: float | None = None,
    within_sd: float = 0.05,
    progress: Callable[[int, int], object] | None = None,
) -> pd.DataFrame:
    """Tracks of scenario artefacts from a fitted behaviour (see the module docstring).

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    fit : BehaviourFit
        The fitted behaviour.
    artefacts : pandas.DataFrame
        One row per artefact: ``scenario, id, t_arrive, t_leave, x, y`` (entry, world m),
        optionally ``label`` (a class of ``fit``; a class of ``fit.standing`` stands at its
        entry for its whole stay; other labels and a missing column use the first
        class). A scenarios table (:func:`~are_stats.generate_scenarios`) is taken as it
        is: ``artefact`` serves as ``id``, and with ``class_labels`` its ``class`` column
        gives the labels.
    dt_out : float or None
        Sampling period of the output (default: the artefact's class epoch ``fit.dt``).
    smooth : int
        ``0`` (default): any-angle paths walked at the preferred speed
        (:func:`continuous_path`); more: the grid path smoothed over that many cells and
        re-timed to end at ``t_leave`` (the motion before issue 26).
    chunk : int
        Goals solved together (a last, smaller chunk is padded to it: one compiled soft
        solve for every chunk; the default is :data:`GOAL_BUCKET`, the fit criticism's).
    class_labels : sequence of str, optional
        Label of each mixture component (the fit's ``class_labels``), for tables with a
        ``class`` column and no ``label``.
    horizon : float, optional
        Leaving times are cut at it (the end of a mission).
    within_sd : float
        Within-person standard deviation of the log walking speed (:func:`walk_times`).
    progress : callable, optional
        ``progress(done, total)`` after each chunk of goals solved and its paths sampled
        (one soft solve, the long part), then once more when the paths are timed: ``total``
        is the chunks (of every class) plus one; the last call has ``done == total``.

    Returns
    -------
    pandas.DataFrame
        ``scenario, id, t, x, y, yaw`` (as :func:`scenario_tracks`), sorted by scenario, id, t.

    Raises
    ------
    ValueError
        On missing columns or ``t_leave < t_arrive``.
    """
    if "id" not in artefacts.columns and "artefact" in artefacts.columns:
        artefacts = artefacts.rename(columns={"artefact": "id"})
    if "label" not in artefacts.columns and class_labels is not None and "class" in artefacts:
        labels = list(class_labels)
        artefacts = artefacts.assign(
            label=[labels[c] if 0 <= c < len(labels) else "" for c in artefacts["class"]]
        )
    need = ("scenario", "id", "t_arrive", "t_leave", "x", "y")
    missing = [c for c in need if c not in artefacts.columns]
    if missing:
        raise ValueError(f"artefacts: expected columns {list(need)}, missing {missing}")
    if dt_out is not None:
        dt_out = float(check_positive("dt_out", dt_out))
    n = len(artefacts)
    if n == 0:
        return pd.DataFrame({c: [] for c in _COLUMNS})
    t_arr = artefacts["t_arrive"].to_numpy(float)
    t_lv = artefacts["t_leave"].to_numpy(float)
    if horizon is not None:
        t_lv = np.minimum(t_lv, float(horizon))
    if not (np.isfinite(t_arr) & np.isfinite(t_lv) & (t_lv >= t_arr)).all():
        raise ValueError("artefacts: expected finite t_arrive <= t_leave in every row")
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel().tolist())
    names = {c: i for i, c in enumerate(fit.classes)}
    if "label" in artefacts.columns:
        cls = np.array([names.get(str(v), 0) for v in artefacts["label"]], np.int64)
        # the classes the log showed standing stand (they draw as before: other draws keep)
        stands = artefacts["label"].astype(str).isin(fit.standing).to_numpy()
    else:
        cls = np.zeros(n, np.int64)
        stands = np.zeros(n, bool)
    run = rng.random(n) < np.nan_to_num(fit.run_fraction[cls])
    mu = np.where(run, fit.run_mu[cls], fit.speed_mu[cls])
    sg = np.where(run, fit.run_sigma[cls], fit.speed_sigma[cls])
    speed = np.clip(np.exp(mu + np.nan_to_num(sg) * rng.standard_normal(n)), 0.2, 10.0)
    xy0 = artefacts[["x", "y"]].to_numpy(float)
    entry = fit.world_to_cell(xy0)
    stay = t_lv - t_arr
    sg0 = np.nan_to_num(sg)
    slowest, fastest = np.exp(mu - 2.0 * sg0), np.exp(mu + 2.0 * sg0)
    # the exit is drawn given the stay (people leave when they reach it): paths that a
    # walker of the class covers in the stay, up to its fast walkers (2 sd above); the
    # reach is a length (cells) and exits are counted in 4-connected moves, up to sqrt(2)
    # times as many as the length of an any-angle path; the smoothed grid path (smooth > 1)
    # walks those moves, so there a move is a cell of length
    moves_per_cell = math.sqrt(2.0) if int(smooth) <= 1 else 1.0
    reach = np.floor(stay * np.maximum(speed, fastest) / fit.cell) * moves_per_cell
    horizon = np.floor(1.25 * reach).astype(np.int64) + 2
    exits = fit.draw_exits(
        rng, cls, entry, np.floor(0.9 * reach), stays=stay, speed_mu=mu, speed_sigma=sg
    )
    moving = (exits[:, 0] >= 0) & ~stands
    occ = ~fit.free
    paths: list[tuple[np.ndarray, np.ndarray] | None] = [None] * n
    # one soft solve per (class, exit); chunks of goals keep the policies small
    by_class = []
    for c in np.unique(cls[moving]):
        idx = np.flatnonzero(moving & (cls == c))
        goals, ginv = np.unique(exits[idx], axis=0, return_inverse=True)
        by_class.append((c, idx, goals, ginv.ravel()))
    total = sum(-(-len(goals) // chunk) for _, _, goals, _ in by_class) + 1
    done = 0
    for c, idx, goals, ginv in by_class:
        dist = fit.geodesic(goals)
        for g0 in range(0, len(goals), chunk):
            gsel = np.arange(g0, min(g0 + chunk, len(goals)))
            members = idx[np.isin(ginv, gsel)]
            local = ginv[np.isin(ginv, gsel)] - g0
            longest = max(
                float(dist[g0 + gl, entry[m, 0], entry[m, 1]])
                for m, gl in zip(members, local, strict=True)
            )
            k = int(math.ceil(10 * longest)) + 20
            sol = fit.soft_policy(
                c,
                occ,
                goals[gsel],
                n_epochs=k,
                tol=1e-2,
                bucket=chunk,  # one compiled program for every chunk, cap and class
            )
            pol = np.asarray(sol.policy)
            v = np.asarray(sol.values)
            head = np.argmax(v[local, :, entry[members, 0], entry[members, 1]], axis=1)
            starts = np.column_stack([entry[members], head])
            st, ac = sample_soft_paths(
                rng, pol, occ, float(fit.slip[c]), starts, local, goals[gsel], horizon[members]
            )
            for j, m in enumerate(members):
                paths[m] = (st[j], ac[j])
            done += 1
            if progress is not None:
                progress(done, total)
    curves: list[tuple[np.ndarray, np.ndarray]] = []
    walking = [i for i in range(n) if paths[i] is not None]
    walked = iter(
        continuous_paths(
            [paths[i] for i in walking],
            fit,
            speed[walking],
            xy0[walking],
            None,
            smooth,
            rng=rng,
            within_sd=within_sd,
        )
    )
    for i in range(n):
        if paths[i] is None:
            curves.append((np.zeros(1), xy0[i][None, :].copy()))
            continue
        tv, pv = next(walked)
        # people leave when they reach their exit: the person's speed, one for its whole
        # path, is the one that ends the path at t_leave, within the class's slow and fast
        # walkers (2 sd around the median speed); beyond them it reaches its exit early
        # and stands there, or leaves while still walking. With the exit drawn given the
        # stay and weighted by the speed law at L / s, that speed is a draw from the
        # fitted between-person law given the entry and the stay
        if 0.0 < tv[-1]:
            v_end = float(np.clip(speed[i] * tv[-1] / stay[i], slowest[i], fastest[i]))
            tv = tv * (float(speed[i]) / v_end)
        curves.append((tv, pv))
    steps = np.array([dt_out if dt_out is not None else float(fit.dt[c]) for c in cls])
    rows = _track_rows(
        curves,
        artefacts["scenario"].to_numpy(),
        artefacts["id"].to_numpy(),
        t_arr,
        stay,
        steps,
        np.zeros(n),
    )
    out = pd.concat(rows, ignore_index=True)
    if progress is not None:
        progress(total, total)
    return out.sort_values(["scenario", "id", "t"], kind="stable").reset_index(drop=True)


def _track_rows(
    curves: list[tuple[np.ndarray, np.ndarray]],
    scen: np.ndarray,
    ids: np.ndarray,
    t_arr: np.ndarray,
    stay: np.ndarray,
    steps: np.ndarray,
    yaw0: np.ndarray,
) -> list[pd.DataFrame]:
    """Every artefact's track rows, in one table (a list of it; none without artefacts):
    its timed path sampled every ``steps[i]`` seconds and at every vertex, so that the
    piecewise-linear track is the path. ``yaw`` follows the motion; an artefact keeps
    ``yaw0`` until it first moves and its last heading while standing.

    All artefacts at once (one table, not one per artefact: 15,000 replicated people took
    36 s in tables of one track), with each track's arithmetic as it was track by track:
    the sample times ``0, step, 2 step, ..`` (as ``np.arange``) and the stay, merged with
    the vertex times inside it, one per instant (1e-6 s); the point on the segment that
    holds each time (the segment found exactly, per track); ``np.gradient``'s differences.
    """
    n = len(curves)
    if n == 0:
        return []
    stay = np.asarray(stay, float)
    steps = np.asarray(steps, float)
    # the regular samples: ceil(stop / step) of them, as np.arange(0, stop, step) makes
    n_reg = np.ceil((stay + 1e-9) / steps).astype(np.int64)
    last = (n_reg - 1) * steps
    tail = (n_reg == 0) | (last < stay - 1e-9)  # the stay ends between two samples
    tvs = [np.asarray(tv, float) for tv, _ in curves]
    pvs = [np.asarray(pv, float).reshape(-1, 2) for _, pv in curves]
    n_vert = np.array([len(tv) for tv in tvs], np.int64)
    tv_all = np.concatenate(tvs)
    pv_all = np.concatenate(pvs)
    v_first = np.r_[0, np.cumsum(n_vert)[:-1]]
    v_owner = np.repeat(np.arange(n), n_vert)
    # the inner vertices (not a path's first or last) reached within the stay
    pos_in = np.arange(tv_all.size) - v_first[v_owner]
    inner = (pos_in > 0) & (pos_in < n_vert[v_owner] - 1) & (n_vert[v_owner] > 2)
    inner &= (tv_all > 0.0) & (tv_all < stay[v_owner])
    reg_owner = np.repeat(np.arange(n), n_reg)
    reg_t = (np.arange(reg_owner.size) - np.r_[0, np.cumsum(n_reg)[:-1]][reg_owner]) * steps[
        reg_owner
    ]
    owner = np.concatenate([reg_owner, np.flatnonzero(tail), v_owner[inner]])
    ts = np.concatenate([reg_t, stay[tail], tv_all[inner]])
    order = np.lexsort((ts, owner))
    owner, ts = owner[order], ts[order]
    new = np.r_[True, owner[1:] != owner[:-1]]
    keep = new | np.r_[True, np.diff(ts) > 1e-6]  # one sample per instant
    owner, ts, new = owner[keep], ts[keep], new[keep]
    # the segment of each sample, exactly per track: vertices and samples merged by
    # (track, time), a vertex before a sample at its time (searchsorted side "right")
    lo, hi = v_first[owner], v_first[owner] + n_vert[owner] - 1
    tau = np.clip(ts, tv_all[lo], tv_all[hi])
    is_v = np.r_[np.ones(tv_all.size, bool), np.zeros(ts.size, bool)]
    merged = np.lexsort((~is_v, np.r_[tv_all, tau], np.r_[v_owner, owner]))
    seen = np.cumsum(is_v[merged])
    k = np.empty(ts.size, np.int64)
    k[merged[~is_v[merged]] - tv_all.size] = seen[~is_v[merged]] - 1
    k = np.clip(k, lo, np.maximum(hi - 1, lo))
    k1 = np.minimum(k + 1, hi)
    t0, t1 = tv_all[k], tv_all[k1]
    span = t1 - t0
    frac = np.where(span > 0, (tau - t0) / np.where(span > 0, span, 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    xy = pv_all[k] + frac[:, None] * (pv_all[k1] - pv_all[k])
    x, y = xy[:, 0], xy[:, 1]
    # yaw: np.gradient per track (one-sided at its ends), still samples keep the last
    start = np.flatnonzero(new)
    size = np.diff(np.r_[start, ts.size])
    end = start + size - 1
    moves = np.array([len(pv) > 1 and bool((np.diff(pv, axis=0) != 0).any()) for pv in pvs], bool)
    moves &= size > 1
    yaw = np.asarray(yaw0, float)[owner].copy()
    if moves.any():
        dx, dy = np.empty_like(x), np.empty_like(y)
        for d, f in ((dx, x), (dy, y)):
            d[1:-1] = (f[2:] - f[:-2]) / 2.0
            d[start] = (f[np.minimum(start + 1, end)] - f[start]) / 1.0
            d[end] = (f[end] - f[np.maximum(end - 1, start)]) / 1.0
        still = np.hypot(dx, dy) < 1e-9
        heading = np.where(still, np.nan, np.mod(np.arctan2(dy, dx), 2 * np.pi))
        at_first = np.isnan(heading[start])
        heading[start[at_first]] = yaw[start[at_first]]
        valid = np.where(np.isnan(heading), 0, np.arange(ts.size))
        heading = heading[np.maximum.accumulate(valid)]  # the last heading while standing
        yaw = np.where(moves[owner], heading, yaw)
    table = pd.DataFrame(
        {
            "scenario": np.asarray(scen)[owner],
            "id": np.asarray(ids)[owner],
            "t": np.asarray(t_arr, float)[owner] + ts,
            "x": x,
            "y": y,
            "yaw": yaw,
        }
    )
    return [table]


def path_points(
    tv: np.ndarray, pv: np.ndarray, tau: npt.ArrayLike, side: npt.ArrayLike
) -> np.ndarray:
    """Points of a timed path, side-stepped along its left normal.

    Parameters
    ----------
    tv : (m,) float
        Increasing times of the path's vertices.
    pv : (m, 2) float
        The vertices (world m).
    tau : (k,) float
        Times on the path (clamped to its ends).
    side : (k,) float
        Offsets (m) along the left normal of the segment walked at ``tau`` (in a pause:
        of the last segment walked before it; none on a path that never moves).

    Returns
    -------
    (k, 2) float
    """
    tau = np.asarray(tau, float).reshape(-1)
    return _PathSet([(tv, pv)]).points(np.zeros(tau.size, np.int64), tau, side)


class _PathSet:
    """Many timed paths, for :func:`path_points` of many artefacts in one call."""

    def __init__(self, curves: list[tuple[np.ndarray, np.ndarray]]) -> None:
        tvs = [np.asarray(tv, float) for tv, _ in curves]
        pvs = [np.asarray(pv, float).reshape(-1, 2) for _, pv in curves]
        self.end = np.array([tv[-1] for tv in tvs])
        span = np.array([tv[-1] - tv[0] for tv in tvs]) + 1.0
        self.start = np.array([tv[0] for tv in tvs])
        self.offset = np.concatenate([[0.0], np.cumsum(span)[:-1]]) - self.start
        counts = np.array([len(tv) for tv in tvs])
        self.first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self.last = self.first + counts - 1
        self.keys = np.concatenate([tv + o for tv, o in zip(tvs, self.offset, strict=True)])
        self.pts = np.concatenate(pvs)
        # each vertex's outgoing unit direction: its own segment's, or that of the last
        # moving segment before it on the same path (the first moving one at the start)
        nrm = np.zeros_like(self.pts)
        for i, pv in enumerate(pvs):
            if len(pv) < 2:
                continue
            seg = np.diff(pv, axis=0)
            length = np.hypot(*seg.T)
            moving = length > 0
            if not moving.any():
                continue
            last = np.maximum.accumulate(np.where(moving, np.arange(len(seg)), -1))
            last[last < 0] = int(np.argmax(moving))
            unit = seg[last] / length[last][:, None]
            rows = slice(self.first[i], self.first[i] + len(seg))
            nrm[rows] = np.column_stack([-unit[:, 1], unit[:, 0]])
        self.nrm = nrm

    def points(self, ids: np.ndarray, tau: np.ndarray, side: np.ndarray) -> np.ndarray:
        """``(k, 2)``: path ``ids[k]`` at ``tau[k]`` side-stepped by ``side[k]``."""
        ids = np.asarray(ids, np.int64)
        tau = np.clip(np.asarray(tau, float), self.start[ids], self.end[ids])
        k = np.searchsorted(self.keys, tau + self.offset[ids], side="right") - 1
        k = np.clip(k, self.first[ids], np.maximum(self.last[ids] - 1, self.first[ids]))
        k1 = np.minimum(k + 1, self.last[ids])
        t0, t1 = self.keys[k] - self.offset[ids], self.keys[k1] - self.offset[ids]
        span = t1 - t0
        frac = np.where(span > 0, (tau - t0) / np.where(span > 0, span, 1.0), 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        base = self.pts[k] + frac[:, None] * (self.pts[k1] - self.pts[k])
        return base + np.asarray(side, float)[:, None] * self.nrm[k]
