"""Catalogue walkers (issue 26): MDP legs to reachable goals, continuous motion between them.

:func:`walk_tracks` moves the artefacts of scenarios without a fitted behaviour (the
catalogue behaviour of :func:`~are_stats.behaviour.behaviour_tracks`):

1. each artefact gets a preferred speed, drawn once (:func:`preferred_speeds`): its class's
   catalogue speed for its mode (walk, or run) times ``exp(speed_sd z)``;
2. **walk** and **run** artefacts go from goal to goal while they are alive. Each leg's goal
   is drawn uniformly among the free cells whose 4-connected path length ``d`` from where
   the artefact stands is at most what it walks in the rest of its stay at its preferred
   speed (so every goal can be reached), and at least half of that reach or of the
   farthest cell, whichever is less (crossings rather than short hops); the paper's MDP
   (:class:`GridMDP`, the artefact's behaviour, slip, a horizon of twice the path length
   plus ten epochs) decides the route, one rollout of its policy samples it; on arrival a
   new goal is drawn. An artefact with no reachable cell left stands;
3. **follow** artefacts walk (MDP leg) to the cell the nearest walking or running artefact
   present at their arrival is heading to, then along that artefact's path at their own
   speed, then on from goal to goal; without anybody to follow they walk;
4. **stop** artefacts stand where they arrived;
5. each route becomes an any-angle path (:func:`string_pull`) timed at the preferred speed
   with a small within-person variation (:func:`walk_times`);
6. the walkers plan alone: people give way to each other while they walk, under the
   social force of the one assembly (:func:`~are_stats.scenarios.scene_tracks`), and moving
   artefacts without a social force of their own are kept apart by the AR-builder's rule
   (DECISIONS 9).

Tracks are sampled every ``dt`` seconds and at every vertex of the path (so the piecewise
linear track is the path: it never crosses an occupied cell).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, NotRequired, TypedDict

import jax
import numpy as np
import pandas as pd

from are_stats._checks import check_nonnegative, check_positive
from are_stats.behaviour._generate import _track_rows
from are_stats.behaviour._mdp import GridMDP
from are_stats.behaviour._model import grid_geodesic
from are_stats.behaviour._motion import (
    preferred_speeds,
    string_pull,
    string_pull_many,
    walk_times,
)
from are_stats.behaviour._rewards import BEHAVIOURS
from are_stats.behaviour._rollout import check_on_free_cells, rollout

if TYPE_CHECKING:
    import numpy.typing as npt

    from are_stats.environment import OccupancyGrid

__all__ = ["walk_tracks"]

_NEED = ("scenario", "id", "t_arrive", "t_leave", "x", "y", "yaw", "behaviour", "speed")
_COLUMNS = ("scenario", "id", "t", "x", "y", "yaw")


class _Geo(TypedDict):
    """What :func:`_legs` needs of the map besides the MDP."""

    #: Cell side (m), the grid's origin (m), the within-walk sd of the log walking speed
    #: (:func:`~are_stats.behaviour.walk_times`).
    cell: float
    origin: tuple[float, float]
    within_sd: float
    #: :func:`~are_stats.behaviour._model.grid_geodesic`.
    geodesic: Callable[[npt.ArrayLike, npt.ArrayLike], np.ndarray]
    #: Path lengths from each start cell, filled by :func:`_legs` as it goes.
    cache: NotRequired[dict[tuple[int, int], np.ndarray]]


class _Walkers:
    """The growing continuous paths of one scenario's artefacts."""

    def __init__(self, xy: np.ndarray, heads: np.ndarray) -> None:
        self.pts = [[p.copy()] for p in xy]
        self.times = [[0.0] for _ in xy]
        self.heads = heads.copy()

    def extend(self, i: int, pts: np.ndarray, times: np.ndarray) -> None:
        t0 = self.times[i][-1]
        self.pts[i].extend(pts[1:])
        self.times[i].extend(t0 + times[1:])

    def curve(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.times[i]), np.asarray(self.pts[i])


def _pow2(n: int) -> int:
    return max(4, 1 << (int(n) - 1).bit_length())


def _leg_route(st: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """A leg's rolled-out states ``st`` ``(h + 1, 3)`` up to its goal's first visit (the
    whole roll-out when it misses it): the route's cells ``(m, 2)``, the index of its last
    state and whether it reached the goal."""
    at_goal = np.flatnonzero((st[:, :2] == goal).all(axis=1))
    end = int(at_goal[0]) if at_goal.size else len(st) - 1
    return st[: end + 1, :2], end, bool(at_goal.size)


def _route_xy(route: np.ndarray, origin: tuple[float, float], cell: float) -> np.ndarray:
    """The cells' centres ``(m, 2)`` of a route of ``(row, col)`` cells, world ``(x, y)``."""
    return np.column_stack(
        [origin[0] + (route[:, 1] + 0.5) * cell, origin[1] + (route[:, 0] + 0.5) * cell]
    )


def _pulled_legs(
    part: list[tuple[int, np.ndarray, np.ndarray, int]],
    states: np.ndarray,
    walkers: _Walkers,
    cur: np.ndarray,
    stay: np.ndarray,
    stopped: set[int],
    free: np.ndarray,
    geo: _Geo,
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The any-angle paths of a chunk's legs, string-pulled together
    (:func:`string_pull_many`, each exactly as :func:`string_pull` alone): ``{j: (xy,
    path)}`` for the legs that :func:`_legs` will walk unless an earlier leg of the same
    artefact uses up its stay (the one thing that needs the earlier legs' times, drawn
    after the pulling; such a leg's path is not used). A leg starts where the artefact's
    previous one ended, its route's last point (``string_pull`` keeps it), so every route
    is known before any is pulled; ``_legs`` uses a path only for the very route it pulls
    (issue 29: 1,248 one-route calls on a realism table of 302 people)."""
    at: dict[int, np.ndarray] = {}  # each artefact's cell after its legs so far
    last: dict[int, np.ndarray] = {}  # and its last point
    halted: set[int] = set(stopped)
    legs: dict[int, np.ndarray] = {}
    for j, (i, c, g, h) in enumerate(part):
        if i in halted or (at.get(i, cur[i]) != c).any() or walkers.times[i][-1] >= stay[i]:
            halted.add(i)
            continue
        route, _, at_goal = _leg_route(states[j, : h + 1], g)
        xy = _route_xy(route, geo["origin"], geo["cell"])
        xy[0] = last.get(i, walkers.pts[i][-1])
        legs[j] = xy
        at[i], last[i] = route[-1], xy[-1]
        if not at_goal:
            halted.add(i)
    paths = string_pull_many(list(legs.values()), free, geo["origin"], geo["cell"])
    return {j: (xy, path) for (j, xy), path in zip(legs.items(), paths, strict=True)}


def _legs(
    rng: np.random.Generator,
    key: jax.Array,
    mdp: GridMDP,
    walkers: _Walkers,
    idx: np.ndarray,
    cur: np.ndarray,
    stay: np.ndarray,
    speed: np.ndarray,
    modes: list[str],
    geo: _Geo,
    fixed: dict[int, np.ndarray] | None = None,
    max_rounds: int = 50,
    chunk: int = 256,
) -> None:
    """Walk artefacts ``idx`` from goal to goal until their stays are used up.

    Each round plans, for every artefact still walking, a chain of goals from where it
    stands: each goal drawn uniformly among the cells whose 4-connected path length from
    the previous one is at most what the artefact walks in its remaining time, and at
    least half of that or of the farthest cell, whichever is less (which the
    chain then uses up at that length: any-angle paths are shorter, so a later round adds
    more legs). All legs of the round are solved (:meth:`GridMDP.solve`, in chunks of
    ``chunk``) and rolled out together; a leg that misses its goal ends the artefact's
    chain for the round. ``cur`` (n, 2) holds every artefact's cell and is updated;
    ``fixed`` gives some artefacts the goal of their first leg (with ``max_rounds=1``,
    that leg alone: a follower's approach)."""
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.behaviour`)
    from are_stats.traffic import split_key

    occ, cell, origin, within = mdp.occupied, geo["cell"], geo["origin"], geo["within_sd"]
    free = ~occ
    cache: dict[tuple[int, int], np.ndarray] = geo.setdefault("cache", {})

    def dist_from(c: np.ndarray) -> np.ndarray:
        k = (int(c[0]), int(c[1]))
        if k not in cache:
            cache[k] = geo["geodesic"](free, np.array([k]))[0]
        return cache[k]

    active = [int(i) for i in np.asarray(idx, np.int64)]
    fixed = dict(fixed or {})
    for _ in range(max_rounds):
        items: list[tuple[int, np.ndarray, np.ndarray, int]] = []
        for i in active:
            c, budget = cur[i].copy(), stay[i] - walkers.times[i][-1]
            while budget > 0.0:
                d = dist_from(c)
                if i in fixed:
                    g = fixed.pop(i)
                    if not (1 <= d[g[0], g[1]] < np.inf):
                        break
                    items.append((i, c, g, int(2 * d[g[0], g[1]]) + 10))
                    break
                reach = np.floor(speed[i] * budget / cell)
                far = d[np.isfinite(d)].max(initial=0.0)
                # the farther half of what it can reach: crossings, not short hops
                ok = np.argwhere((d >= max(1.0, 0.5 * min(reach, far))) & (d <= reach))
                if not len(ok):
                    break  # nothing reachable in the rest of the stay: it stands
                g = ok[rng.integers(len(ok))]
                items.append((i, c, g, int(2 * d[g[0], g[1]]) + 10))
                budget -= d[g[0], g[1]] * cell / speed[i]
                c = g
        if not items:
            return
        stopped: set[int] = set()
        for c0 in range(0, len(items), chunk):
            part = items[c0 : c0 + chunk]
            b = _pow2(len(part))
            pad = b - len(part)
            hor = np.array([it[3] for it in part] + [0] * pad, np.int64)
            goals = np.concatenate([np.array([it[2] for it in part]), np.full((pad, 2), -1)])
            beh = [modes[it[0]] for it in part] + ["stop"] * pad
            n_ep = 64 * math.ceil(int(hor.max()) / 64)
            sol = mdp.solve(goals, beh, hor, n_epochs=n_ep, store_values=False)
            cells = np.concatenate(
                [np.array([it[1] for it in part]), np.repeat(part[0][1][None], pad, 0)]
            )
            heads = np.zeros(b, np.int64)
            heads[: len(part)] = [walkers.heads[it[0]] for it in part]
            key, k_roll = split_key(key)
            states = rollout(k_roll, sol, np.column_stack([cells, heads]), n_ep, resolve=None)
            pulled = _pulled_legs(part, states, walkers, cur, stay, stopped, free, geo)
            for j, (i, c, g, h) in enumerate(part):
                if i in stopped or (cur[i] != c).any() or walkers.times[i][-1] >= stay[i]:
                    stopped.add(i)
                    continue
                # heading of the previous leg's end (the chain planned heading 0 after it)
                st = states[j, : h + 1]
                route, end, at_goal = _leg_route(st, g)
                xy = _route_xy(route, origin, cell)
                xy[0] = walkers.pts[i][-1]
                ahead = pulled.get(j)
                path = ahead[1] if ahead is not None and np.array_equal(ahead[0], xy) else None
                if path is None:  # not foreseen (_pulled_legs): pulled alone, the same way
                    path = string_pull(xy, free, origin, cell)
                walkers.extend(i, path, walk_times(path, float(speed[i]), rng, within))
                cur[i] = route[-1]
                walkers.heads[i] = st[end, 2]
                if not at_goal:
                    stopped.add(i)  # missed its goal: the next round plans from here
        progressed = {it[0] for it in items}
        active = [i for i in active if i in progressed and walkers.times[i][-1] < stay[i]]
        if not active:
            return


def _position(curve: tuple[np.ndarray, np.ndarray], tau: float) -> tuple[np.ndarray, int]:
    """Position on a timed path at ``tau`` and the index of the next vertex."""
    tv, pv = curve
    k = int(np.searchsorted(tv, tau, side="right"))
    if k >= len(tv):
        return pv[-1], len(tv) - 1
    f = (tau - tv[k - 1]) / max(tv[k] - tv[k - 1], 1e-12) if k > 0 else 0.0
    return pv[max(k - 1, 0)] + f * (pv[k] - pv[max(k - 1, 0)]), k


def walk_tracks(
    key: jax.Array,
    artefacts: pd.DataFrame,
    occupied: npt.ArrayLike | OccupancyGrid,
    *,
    resolution: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    dt: float = 2.0,
    speed_sd: float = 0.12,
    within_sd: float = 0.05,
    slip: float = 0.1,
    step_cost: float = 1e-3,
    progress: Callable[[int, int], object] | None = None,
) -> pd.DataFrame:
    """Tracks of catalogue artefacts that keep walking while alive (module docstring).

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    artefacts : pandas.DataFrame
        One row per artefact: ``scenario, id, t_arrive, t_leave, x, y, yaw, behaviour,
        speed``; positions on free cells (world m), ``behaviour`` one of walk, run, follow,
        stop, ``speed`` the class's catalogue speed for that behaviour's mode (m/s; run for
        runners, walk otherwise).
    occupied : (H, W) bool
        The grid the artefacts move on (row along +y, column along +x).
    resolution : float
        Cell side (m).
    origin : tuple of float
        World ``(x, y)`` of the corner of cell ``(0, 0)``.
    dt : float
        Seconds between track samples (vertices of the path are sampled too).
    speed_sd : float
        Between-person standard deviation of the log preferred speed (``0.12``: about 12%
        around the catalogue speed).
    within_sd : float
        Within-person standard deviation of the log speed (:func:`walk_times`).
    slip, step_cost : float
        MDP parameters (:class:`GridMDP`).
    progress : callable, optional
        ``progress(done, total)`` after each scenario's tracks (``total`` scenarios): the
        planning runs one scenario at a time, so a caller can tell the time left.

    Returns
    -------
    pandas.DataFrame
        ``scenario, id, t, x, y, yaw`` sorted by scenario, id and t.

    Raises
    ------
    ValueError
        On missing columns, ``t_leave < t_arrive``, positions off the free cells, unknown
        behaviours or speeds that are not > 0.
    """
    missing = [c for c in _NEED if c not in artefacts.columns]
    if missing:
        raise ValueError(f"artefacts: expected columns {list(_NEED)}, missing {missing}")
    dt = float(check_positive("dt", dt))
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.behaviour`)
    from are_stats.traffic import split_key

    cell = float(check_positive("resolution", resolution))
    speed_sd = float(check_nonnegative("speed_sd", speed_sd))
    within_sd = float(check_nonnegative("within_sd", within_sd))
    occ = GridMDP(occupied, slip=slip, step_cost=step_cost).occupied
    ox, oy = float(origin[0]), float(origin[1])
    out = []
    scenarios = artefacts.groupby("scenario", sort=True)
    for k_scen, (s_label, table) in enumerate(scenarios):
        if progress is not None and k_scen:
            progress(k_scen, scenarios.ngroups)
        table = table.reset_index(drop=True)
        n = len(table)
        t_arr = table["t_arrive"].to_numpy(float)
        t_lv = table["t_leave"].to_numpy(float)
        if not (np.isfinite(t_arr) & np.isfinite(t_lv) & (t_lv >= t_arr)).all():
            i = int(np.argmax(~(np.isfinite(t_arr) & np.isfinite(t_lv) & (t_lv >= t_arr))))
            raise ValueError(
                f"artefacts: expected finite t_arrive <= t_leave, got row {i} of scenario "
                f"{s_label!r} with {t_arr[i]!r} and {t_lv[i]!r}"
            )
        stay = t_lv - t_arr
        xy = table[["x", "y"]].to_numpy(float)
        cols = np.floor((xy[:, 0] - ox) / cell).astype(np.int64)
        rows = np.floor((xy[:, 1] - oy) / cell).astype(np.int64)
        check_on_free_cells(rows, cols, occ, xy, s_label)
        modes = [str(b) for b in table["behaviour"]]
        unknown = sorted(set(modes) - set(BEHAVIOURS))
        if unknown:
            raise ValueError(f"behaviour: expected one of {list(BEHAVIOURS)}, got {unknown}")
        key, k_speed, k_lead, k_rng = split_key(key, 4)
        speed = preferred_speeds(k_speed, table["speed"].to_numpy(float), speed_sd)
        rng = np.random.default_rng(np.asarray(jax.random.key_data(k_rng)).ravel().tolist())
        yaw = table["yaw"].to_numpy(float)
        heads = np.round(yaw / (np.pi / 2)).astype(np.int64) % 4
        walkers = _Walkers(xy, heads)
        cur = np.column_stack([rows, cols])
        # routes keep off the cells of artefacts that stand (their own start cells aside)
        route_occ = occ.copy()
        stand = np.array([m == "stop" for m in modes])
        route_occ[rows[stand], cols[stand]] = True
        route_occ[rows[~stand], cols[~stand]] = False
        mdp = GridMDP(route_occ, slip=slip, step_cost=step_cost)
        geo: _Geo = {
            "cell": cell,
            "origin": (ox, oy),
            "within_sd": within_sd,
            "geodesic": grid_geodesic,
        }
        leads = np.flatnonzero([m in ("walk", "run") for m in modes])
        _legs(rng, k_lead, mdp, walkers, leads, cur, stay, speed, modes, geo)
        # followers: an approach leg to the cell their target is heading to, then the
        # target's path at their own speed, then on from goal to goal like walkers
        fixed: dict[int, np.ndarray] = {}
        tails: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        followers = np.flatnonzero([m == "follow" for m in modes])
        for i in followers:
            best, target = np.inf, None
            for j in leads:
                tau = t_arr[i] - t_arr[j]
                if not (0.0 <= tau < stay[j]) or len(walkers.times[j]) < 2:
                    continue
                p, _ = _position(walkers.curve(j), tau)
                d = float(np.hypot(*(p - xy[i])))
                if d < best:
                    best, target = d, j
            modes[i] = "walk"
            if target is None:
                continue
            tv, pv = walkers.curve(target)
            _, k = _position((tv, pv), t_arr[i] - t_arr[target])
            g = np.floor((pv[k][::-1] - np.array([oy, ox])) / cell).astype(np.int64)
            tails[i] = (g, pv[k:])
            if (g != cur[i]).any():
                fixed[i] = g
        if fixed:
            key, k_app = split_key(key)
            _legs(
                rng,
                k_app,
                mdp,
                walkers,
                np.array(sorted(fixed), np.int64),
                cur,
                stay,
                speed,
                modes,
                geo,
                fixed,
                max_rounds=1,
            )
        for i, (g, tail) in tails.items():
            if (cur[i] != g).any() or walkers.times[i][-1] >= stay[i]:
                continue  # the approach did not reach the target's path, or no time left
            path = np.concatenate([np.asarray(walkers.pts[i][-1])[None, :], tail])
            path = path[np.concatenate([[True], (np.diff(path, axis=0) != 0).any(axis=1)])]
            walkers.extend(i, path, walk_times(path, float(speed[i]), rng, within_sd))
            cur[i] = np.floor((tail[-1][::-1] - np.array([oy, ox])) / cell).astype(np.int64)
        key, k_on = split_key(key)
        _legs(rng, k_on, mdp, walkers, followers, cur, stay, speed, modes, geo)
        curves = [walkers.curve(i) for i in range(n)]
        out.extend(
            _track_rows(
                curves,
                table["scenario"].to_numpy(),
                table["id"].to_numpy(),
                t_arr,
                stay,
                np.full(n, dt),
                yaw,
            )
        )
    if progress is not None and scenarios.ngroups:
        progress(scenarios.ngroups, scenarios.ngroups)
    if not out:
        return pd.DataFrame({c: [] for c in _COLUMNS})
    res = pd.concat(out, ignore_index=True)
    return res.sort_values(["scenario", "id", "t"], kind="stable").reset_index(drop=True)
