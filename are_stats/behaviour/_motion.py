"""Continuous motion between the MDP's decisions (issue 26): straight paths, steady speeds.

The MDP decides where an artefact goes (its route: a sequence of grid cells); the motion
between decisions is continuous:

- :func:`string_pull` turns the route into an any-angle path: from each kept vertex the
  path goes straight to the farthest later cell of the route it can see over free cells
  (line of sight with a small clearance), so an open crossing is one straight segment and
  only the corners the walls force remain;
- :func:`preferred_speeds` draws each artefact's preferred speed once, lognormal around
  its median (the between-person spread);
- :func:`walk_times` times a path at that speed with a small, slowly varying within-person
  variation (a stationary AR(1) in log speed over the path's segments) instead of a speed
  per epoch.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from are_stats._checks import check_nonnegative, check_positive

__all__ = ["line_of_sight", "preferred_speeds", "string_pull", "walk_times"]


def _crossed(free: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Whether each segment ``p0[k] -> p1[k]`` (``(row, col)`` in cell units) crosses only
    free cells: the cells between successive crossings of grid lines, and both end cells.

    ``p0, p1 : (m, 2)``; returns ``(m,)`` bool (exact, vectorised over the segments)."""
    p0 = np.atleast_2d(p0)
    p1 = np.atleast_2d(p1)
    d = p1 - p0
    parts = [np.zeros((len(d), 1)), np.ones((len(d), 1))]
    for axis in (0, 1):
        lo = np.minimum(p0[:, axis], p1[:, axis])
        hi = np.maximum(p0[:, axis], p1[:, axis])
        first = np.floor(lo) + 1.0
        count = np.maximum(np.ceil(hi) - first, 0.0).astype(np.int64)
        width = int(count.max(initial=0))
        if width == 0:
            continue
        k = first[:, None] + np.arange(width)[None, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (k - p0[:, axis, None]) / d[:, axis, None]
        parts.append(np.where(np.arange(width)[None, :] < count[:, None], t, np.inf))
    t = np.sort(np.concatenate(parts, axis=1), axis=1)
    mid = np.concatenate([np.zeros((len(d), 1)), 0.5 * (t[:, 1:] + t[:, :-1]), t[:, 1:2]], 1)
    valid = np.isfinite(mid)
    mid = np.where(valid, np.clip(mid, 0.0, 1.0), 0.0)
    mid[:, -1] = 1.0
    cells = np.floor(p0[:, None, :] + mid[..., None] * d[:, None, :]).astype(np.int64)
    h, w = free.shape
    inside = (cells[..., 0] >= 0) & (cells[..., 0] < h) & (cells[..., 1] >= 0)
    inside &= cells[..., 1] < w
    ok = np.zeros(cells.shape[:2], bool)
    ok[inside] = free[cells[..., 0][inside], cells[..., 1][inside]]
    return (ok | ~valid).all(axis=1) & (inside | ~valid).all(axis=1)


def _sight(free: np.ndarray, p0: np.ndarray, p1: np.ndarray, clearance: float) -> np.ndarray:
    """:func:`line_of_sight` from one point ``p0 (2,)`` to each of ``p1 (m, 2)``."""
    p0 = np.broadcast_to(np.asarray(p0, float), np.shape(p1))
    ok = _crossed(free, p0, p1)
    if clearance <= 0.0:
        return ok
    d = p1 - p0
    length = np.hypot(d[:, 0], d[:, 1])
    safe = np.where(length > 0, length, 1.0)
    n = np.column_stack([-d[:, 1], d[:, 0]]) / safe[:, None] * float(clearance)
    n[length == 0] = 0.0
    return ok & _crossed(free, p0 + n, p1 + n) & _crossed(free, p0 - n, p1 - n)


def line_of_sight(free: Any, p0: Any, p1: Any, clearance: float = 0.2) -> bool:
    """Whether a walker of half-width ``clearance`` goes straight from ``p0`` to ``p1``.

    The segment and its two copies shifted sideways by ``+-clearance`` must cross only
    free cells (a segment through a cell's corner thus keeps off an occupied neighbour).

    Parameters
    ----------
    free : (H, W) bool
        Free cells, ``free[row, col]``.
    p0, p1 : (2,) float
        End points ``(row, col)`` in cell units (cell ``(r, c)`` covers
        ``[r, r + 1) x [c, c + 1)``; its centre is ``(r + 0.5, c + 0.5)``).
    clearance : float
        Half-width in cells (``0``: the segment alone).

    Returns
    -------
    bool
    """
    free = np.asarray(free, bool)
    a = np.asarray(p0, float).reshape(2)
    b = np.asarray(p1, float).reshape(1, 2)
    return bool(_sight(free, a, b, float(clearance))[0])


def string_pull(
    points: Any,
    free: Any,
    origin: tuple[float, float] = (0.0, 0.0),
    cell: float = 1.0,
    clearance: float = 0.2,
) -> np.ndarray:
    """Any-angle path through a route: line-of-sight shortcuts over free cells.

    From the first point, the path goes straight to the farthest later point of the route
    that it can see (:func:`line_of_sight`, extended one point at a time), which becomes
    the next vertex; and so on to the last point. Consecutive repeats are dropped first. In
    an open room a route of grid cells becomes one straight segment; around walls only the
    corners remain. Every segment of the result crosses only free cells (where the route's
    own steps do).

    Parameters
    ----------
    points : (n, 2) float
        The route in world coordinates ``(x, y)`` (e.g. its cells' centres).
    free : (H, W) bool
        Free cells (row along +y, column along +x).
    origin : tuple of float
        World ``(x, y)`` of the corner of cell ``(0, 0)``.
    cell : float
        Cell side (m).
    clearance : float
        Half-width of the walker in cells (see :func:`line_of_sight`).

    Returns
    -------
    (m, 2) float
        The kept vertices, the first and last points included (``m <= n``).

    Examples
    --------
    >>> import numpy as np
    >>> stairs = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [2.5, 1.5], [2.5, 2.5]])
    >>> string_pull(stairs, np.ones((4, 4), bool)).tolist()
    [[0.5, 0.5], [2.5, 2.5]]
    """
    p = np.asarray(points, float).reshape(-1, 2)
    if len(p) > 1:
        p = p[np.concatenate([[True], (np.diff(p, axis=0) != 0).any(axis=1)])]
    if len(p) < 3:
        return p.copy()
    free = np.asarray(free, bool)
    cell = float(check_positive("cell", cell))
    rc = np.column_stack([(p[:, 1] - origin[1]) / cell, (p[:, 0] - origin[0]) / cell])
    keep = [0]
    a, n = 0, len(p)
    while a < n - 1:
        j = a + 1  # the next point is always kept reachable (the route's own step)
        while j + 1 < n:
            ahead = np.arange(j + 1, min(j + 1 + 64, n))
            ok = _sight(free, rc[a], rc[ahead], float(clearance))
            run = int(np.argmin(ok)) if not ok.all() else ok.size
            j += run
            if run < ok.size:
                break
        keep.append(j)
        a = j
    return p[keep].copy()


def preferred_speeds(key: jax.Array, median: Any, sd_log: Any) -> np.ndarray:
    """Each artefact's preferred speed, drawn once: ``median * exp(sd_log * z)``.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    median : (n,) float
        Median speed of each artefact's class and mode (m/s, > 0).
    sd_log : float or (n,) float
        Between-person standard deviation of the log speed (>= 0).

    Returns
    -------
    (n,) float64
    """
    med = np.asarray(median, float).reshape(-1)
    if (~np.isfinite(med) | (med <= 0)).any():
        raise ValueError(f"median: expected speeds > 0, got {med[~(med > 0)][:3].tolist()}")
    sd = np.broadcast_to(np.asarray(sd_log, float), med.shape)
    if (~np.isfinite(sd) | (sd < 0)).any():
        raise ValueError(f"sd_log: expected values >= 0, got {sd[~(sd >= 0)][:3].tolist()}")
    z = np.asarray(jax.random.normal(key, med.shape, dtype=np.float32), float)
    return med * np.exp(sd * z)


def walk_times(
    points: Any,
    speed: float,
    rng: np.random.Generator | None = None,
    within_sd: float = 0.0,
    correlation: float = 10.0,
) -> np.ndarray:
    """Times at which a walker reaches each vertex of its path.

    Segment ``k`` is walked at ``speed * exp(e_k)``, with ``e`` a stationary AR(1) over the
    segments, ``sd within_sd`` and correlation ``exp(-L_{k-1} / correlation)`` across the
    previous segment's length ``L_{k-1}`` (m): a small, slowly varying within-person
    variation. ``within_sd = 0`` walks at exactly ``speed``.

    Parameters
    ----------
    points : (m, 2) float
        Vertices (m).
    speed : float
        Preferred speed (m/s, > 0).
    rng : numpy.random.Generator, optional
        Needed when ``within_sd > 0``.
    within_sd : float
        Standard deviation of the log speed within the walk.
    correlation : float
        Correlation length (m) of the log speed.

    Returns
    -------
    (m,) float
        Times from 0 (a zero-length segment takes no time).
    """
    p = np.asarray(points, float).reshape(-1, 2)
    speed = float(check_positive("speed", speed))
    within_sd = float(check_nonnegative("within_sd", within_sd))
    seg = np.hypot(*np.diff(p, axis=0).T) if len(p) > 1 else np.zeros(0)
    e = np.zeros(seg.size)
    if within_sd > 0.0 and seg.size:
        if rng is None:
            raise ValueError("rng: expected a numpy Generator with within_sd > 0, got None")
        z = rng.standard_normal(seg.size)
        rho = np.exp(-np.concatenate([[0.0], seg[:-1]]) / float(correlation))
        e[0] = within_sd * z[0]
        for k in range(1, seg.size):
            e[k] = rho[k] * e[k - 1] + np.sqrt(1.0 - rho[k] ** 2) * within_sd * z[k]
    return np.concatenate([[0.0], np.cumsum(seg / (speed * np.exp(e)))])
