"""Tracks of artefacts that walk like the people in the log (issue 16).

:func:`simulate_behaviour_tracks` is the generator behind ``are-stats generate --behaviours``
with a fitted :class:`~are_stats.behaviour.BehaviourFit`. Each artefact

1. gets its class's walking (or, with probability ``run_fraction``, running) speed law,
   lognormal ``(mu, sigma)``, and a reach: the path length its fast walkers
   (``exp(mu + 2 sigma)``) cover in its stay;
2. gets an exit drawn from the exit density given its entry **and its stay**, reachable
   within ``0.9`` of the reach (:meth:`BehaviourFit.draw_exits` with ``stays``): people
   leave when they reach their exit, so a stay ``s`` and a path of length ``L`` mean a
   walking speed ``L / s``, and exits are weighted by the speed law at ``L / s``; without
   a reachable exit it stays where it entered;
3. walks there with the stationary soft policy of its class (:func:`soft_backward_induction`,
   ``beta`` and ``slip`` fitted), sampled epoch by epoch (:func:`sample_soft_paths`);
4. becomes a continuous track: the distinct cells of its path, smoothed by a centred moving
   average of ``smooth`` cells (ends fixed), walked at the speed that ends the path at
   ``t_leave``, within the class's slow and fast walkers (``exp(mu -+ 2 sigma)``: beyond
   them the artefact reaches its exit early and stands there, or leaves while still
   walking); turning in place takes no time, a ``stay`` or a blocked move a pause of one
   epoch. Positions are sampled every ``dt_out`` seconds from ``t_arrive`` to
   ``t_leave``. ``yaw`` follows the direction of motion (any angle).

Artefacts do not see each other (no collision resolution).
"""

from __future__ import annotations

import math
from typing import Any

import jax
import numpy as np
import pandas as pd

from are_stats._checks import check_positive
from are_stats.behaviour._mdp import _path_free
from are_stats.behaviour._model import BehaviourFit
from are_stats.behaviour._rewards import FORWARD, HEADINGS, LEFT, RIGHT, RUN, STAY
from are_stats.behaviour._soft import soft_policy

__all__ = ["sample_soft_paths", "simulate_behaviour_tracks", "smooth_path"]

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
    ok = _path_free(np.asarray(occupied, bool))
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


def _continuous(
    states: np.ndarray,
    actions: np.ndarray,
    fit: BehaviourFit,
    speed: float,
    start_xy: np.ndarray,
    end_xy: np.ndarray | None,
    smooth: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Vertex times ``(m,)`` and positions ``(m, 2)`` of one artefact's continuous path."""
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
    smooth: int = 5,
    chunk: int = 16,
    class_labels: Any = None,
    horizon: float | None = None,
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
        optionally ``label`` (a class of ``fit``; other labels and a missing column use the
        first class). A scenarios table (:func:`~are_stats.generate_scenarios`) is taken as
        it is: ``artefact`` serves as ``id``, and with ``class_labels`` its ``class``
        column gives the labels.
    dt_out : float or None
        Sampling period of the output (default: the artefact's class epoch ``fit.dt``).
    smooth : int
        Moving-average window (cells) of the continuous path.
    chunk : int
        Goals solved together.
    class_labels : sequence of str, optional
        Label of each mixture component (the fit's ``class_labels``), for tables with a
        ``class`` column and no ``label``.
    horizon : float, optional
        Leaving times are cut at it (the end of a mission).

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
    else:
        cls = np.zeros(n, np.int64)
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
    # walker of the class covers in the stay, up to its fast walkers (2 sd above)
    reach = np.floor(stay * np.maximum(speed, fastest) / fit.cell)
    horizon = np.floor(1.25 * reach).astype(np.int64) + 2
    exits = fit.draw_exits(
        rng, cls, entry, np.floor(0.9 * reach), stays=stay, speed_mu=mu, speed_sigma=sg
    )
    moving = exits[:, 0] >= 0
    occ = ~fit.free
    paths: list[tuple[np.ndarray, np.ndarray] | None] = [None] * n
    # one soft solve per (class, exit); chunks of goals keep the policies small
    for c in np.unique(cls[moving]):
        idx = np.flatnonzero(moving & (cls == c))
        goals, ginv = np.unique(exits[idx], axis=0, return_inverse=True)
        ginv = ginv.ravel()
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
            sol = soft_policy(
                occ, goals[gsel], float(fit.beta[c]), float(fit.slip[c]), n_epochs=k,
                goal_reward=fit.goal_reward, step_cost=fit.step_cost, time_cost=fit.time_cost,
                tol=1e-2,
            )  # fmt: skip
            pol = np.asarray(sol.policy)
            v = np.asarray(sol.values)
            head = np.argmax(v[local, :, entry[members, 0], entry[members, 1]], axis=1)
            starts = np.column_stack([entry[members], head])
            st, ac = sample_soft_paths(
                rng, pol, occ, float(fit.slip[c]), starts, local, goals[gsel], horizon[members]
            )
            for j, m in enumerate(members):
                paths[m] = (st[j], ac[j])
    rows = []
    ids = artefacts["id"].to_numpy()
    scen = artefacts["scenario"].to_numpy()
    for i in range(n):
        step_out = dt_out if dt_out is not None else float(fit.dt[cls[i]])
        ts = np.arange(0.0, stay[i] + 1e-9, step_out)
        if ts.size == 0 or ts[-1] < stay[i] - 1e-9:
            ts = np.append(ts, stay[i])
        if paths[i] is None:
            x = np.full(ts.size, xy0[i, 0])
            y = np.full(ts.size, xy0[i, 1])
            yaw = np.zeros(ts.size)
        else:
            tv, pv = _continuous(*paths[i], fit, float(speed[i]), xy0[i], None, smooth)
            # people leave when they reach their exit: the path is walked at the speed that
            # ends it at t_leave, within the class's slow and fast walkers (2 sd around
            # the median speed); beyond them the artefact arrives early and stands there,
            # or is still walking when it leaves
            if 0.0 < tv[-1]:
                v_end = float(np.clip(speed[i] * tv[-1] / stay[i], slowest[i], fastest[i]))
                tv = tv * (float(speed[i]) / v_end)
            x = np.interp(ts, tv, pv[:, 0])
            y = np.interp(ts, tv, pv[:, 1])
            dx, dy = np.gradient(x), np.gradient(y)
            still = np.hypot(dx, dy) < 1e-9
            yaw = np.mod(np.arctan2(dy, dx), 2 * np.pi)
            # keep the last heading while standing
            for j in range(1, yaw.size):
                if still[j]:
                    yaw[j] = yaw[j - 1]
        rows.append(
            pd.DataFrame(
                {"scenario": scen[i], "id": ids[i], "t": t_arr[i] + ts, "x": x, "y": y, "yaw": yaw}
            )
        )
    out = pd.concat(rows, ignore_index=True)
    return out.sort_values(["scenario", "id", "t"], kind="stable").reset_index(drop=True)
