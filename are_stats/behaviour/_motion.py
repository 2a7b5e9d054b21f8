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
  per epoch;
- :func:`arrival_velocities` gives each planned track the velocity of its first planned
  move, so that a person walks on arrival (people come into a map walking) instead of
  setting off from rest.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_nonnegative, check_positive

__all__ = [
    "arrival_velocities",
    "line_of_sight",
    "preferred_speeds",
    "string_pull",
    "string_pull_many",
    "walk_times",
    "walk_times_many",
]


def _crossed(
    free: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    grid: np.ndarray | None = None,
    table: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each segment ``p0[k] -> p1[k]`` (``(row, col)`` in cell units) crosses only
    free cells: the cells between successive crossings of grid lines, and both end cells.

    ``p0, p1 : (m, 2)``; ``free : (H, W)`` bool, or ``(G, H, W)`` with ``grid : (m,)`` int
    naming each segment's grid; ``table``, optional: ``free``'s :func:`_blocked_table`
    (made here without it); returns ``(m,)`` bool (exact, vectorised over the segments;
    a segment's answer does not depend on the others it is tested with).

    A segment whose bounding box of cells (widened by 1e-9 of a cell, more than the
    round-off of the cells' coordinates) lies on the map with no blocked cell in it
    crosses only free cells: it is answered by four look-ups in the summed table of
    blocked cells, and only the others are traced cell by cell (issue 29: in an open
    room most of string pulling's tests are long segments through free space, each
    traced over every cell it crosses). Segments are traced in blocks of similar length
    (the grid lines each crosses, within a factor of 2): a block pads every segment to
    its longest, so one long segment among many short ones no longer makes all of them
    as wide."""
    p0 = np.atleast_2d(p0)
    p1 = np.atleast_2d(p1)
    if table is None:
        table = _blocked_table(free)
    clear = _box_clear(table, p0, p1, grid)
    out = clear.copy()
    rest = np.flatnonzero(~clear)
    if rest.size == 0:
        return out
    p0, p1 = p0[rest], p1[rest]
    grid = None if grid is None else np.asarray(grid)[rest]
    if len(p0) > _CROSS_BLOCK:
        lo, hi = np.minimum(p0, p1), np.maximum(p0, p1)
        lines = np.maximum(np.ceil(hi) - np.floor(lo) - 1.0, 0.0).sum(axis=1)
        band = np.ceil(np.log2(lines + 1.0)).astype(np.int64)
        if np.unique(band).size > 1:
            for b in np.unique(band):
                sel = np.flatnonzero(band == b)
                out[rest[sel]] = _crossed_block(
                    free, p0[sel], p1[sel], None if grid is None else grid[sel]
                )
            return out
    out[rest] = _crossed_block(free, p0, p1, grid)
    return out


def _blocked_table(free: np.ndarray) -> np.ndarray:
    """Summed-area table of the blocked (not free) cells: ``(..., H + 1, W + 1)`` int, the
    blocked cells of ``free[..., :r, :c]`` at ``[..., r, c]``."""
    blocked = (~np.asarray(free, bool)).astype(np.int32)
    pad = [(0, 0)] * (blocked.ndim - 2) + [(1, 0), (1, 0)]
    return np.pad(blocked, pad).cumsum(axis=-2).cumsum(axis=-1)


#: Summed tables (:func:`_blocked_table`) of the last grids :func:`line_of_sight` saw, by
#: ``(shape, packed mask)``: one segment a call, the table cost a quarter of a call.
_TABLES: dict[tuple[tuple[int, ...], bytes], np.ndarray] = {}
_TABLES_MAX = 8
_TABLES_LOCK = threading.Lock()  # the eviction iterates the dict: one thread at a time


def _blocked_table_of(free: np.ndarray) -> np.ndarray:
    """:func:`_blocked_table` of ``free`` (bool), kept for the next call with the same mask
    (read-only)."""
    key = (free.shape, np.packbits(free).tobytes())
    table = _TABLES.get(key)
    if table is None:
        table = _blocked_table(free)
        table.flags.writeable = False
        with _TABLES_LOCK:
            if len(_TABLES) >= _TABLES_MAX:
                del _TABLES[next(iter(_TABLES))]
            _TABLES[key] = table
    return table


def _box_clear(
    table: np.ndarray, p0: np.ndarray, p1: np.ndarray, grid: np.ndarray | None
) -> np.ndarray:
    """``(m,)`` bool: the segments whose box of cells (:func:`_crossed`) is on the map and
    free of blocked cells (``table``: :func:`_blocked_table`; ``grid`` as :func:`_crossed`'s).
    False says nothing: such a segment must be traced."""
    h, w = table.shape[-2] - 1, table.shape[-1] - 1
    lo = np.floor(np.minimum(p0, p1) - _BOX_EPS)
    hi = np.floor(np.maximum(p0, p1) + _BOX_EPS)
    on = (lo[:, 0] >= 0) & (lo[:, 1] >= 0) & (hi[:, 0] < h) & (hi[:, 1] < w)
    on &= np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1)
    r0 = np.where(on, lo[:, 0], 0).astype(np.int64)
    c0 = np.where(on, lo[:, 1], 0).astype(np.int64)
    r1 = np.where(on, hi[:, 0], 0).astype(np.int64) + 1
    c1 = np.where(on, hi[:, 1], 0).astype(np.int64) + 1
    g = () if grid is None else (np.asarray(grid, np.int64),)  # each segment's own grid
    n = table[(*g, r1, c1)] - table[(*g, r0, c1)] - table[(*g, r1, c0)] + table[(*g, r0, c0)]
    return on & (n == 0)


#: Widening (cells) of a segment's box in :func:`_box_clear`: far above the round-off of
#: the traced points ``p0 + s (p1 - p0)`` (about 1e-13 of a cell on maps of 1,000 cells).
_BOX_EPS = 1e-9


#: Segments above which :func:`_crossed` tests them in blocks of similar length.
_CROSS_BLOCK = 256


def _crossed_block(
    free: np.ndarray, p0: np.ndarray, p1: np.ndarray, grid: np.ndarray | None
) -> np.ndarray:
    """:func:`_crossed` of one block of segments (each padded to the block's longest)."""
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
    h, w = free.shape[-2:]
    inside = (cells[..., 0] >= 0) & (cells[..., 0] < h) & (cells[..., 1] >= 0)
    inside &= cells[..., 1] < w
    ok = np.zeros(cells.shape[:2], bool)
    if grid is None:
        ok[inside] = free[cells[..., 0][inside], cells[..., 1][inside]]
    else:
        g = np.broadcast_to(np.asarray(grid, np.int64)[:, None], inside.shape)
        ok[inside] = free[g[inside], cells[..., 0][inside], cells[..., 1][inside]]
    return (ok | ~valid).all(axis=1) & (inside | ~valid).all(axis=1)


def _sight(
    free: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    clearance: float,
    grid: np.ndarray | None = None,
    table: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`line_of_sight` from ``p0 (2,)`` (or one ``(m, 2)`` per segment) to each of
    ``p1 (m, 2)``; ``grid`` and ``table`` as in :func:`_crossed`."""
    p0 = np.broadcast_to(np.asarray(p0, float), np.shape(p1))
    if table is None:
        table = _blocked_table(free)
    if clearance <= 0.0:
        return _crossed(free, p0, p1, grid, table)
    d = p1 - p0
    length = np.hypot(d[:, 0], d[:, 1])
    safe = np.where(length > 0, length, 1.0)
    n = np.column_stack([-d[:, 1], d[:, 0]]) / safe[:, None] * float(clearance)
    n[length == 0] = 0.0
    # the segment and its two shifted copies in one test (a segment's answer does not
    # depend on the others tested with it): one pass of _crossed's Python, not three
    m = len(d)
    g3 = None if grid is None else np.tile(np.asarray(grid), 3)
    ok = _crossed(
        free, np.concatenate([p0, p0 + n, p0 - n]), np.concatenate([p1, p1 + n, p1 - n]), g3, table
    )
    return ok[:m] & ok[m : 2 * m] & ok[2 * m :]


def line_of_sight(
    free: npt.ArrayLike, p0: npt.ArrayLike, p1: npt.ArrayLike, clearance: float = 0.2
) -> bool:
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
    return bool(_sight(free, a, b, float(clearance), table=_blocked_table_of(free))[0])


def string_pull(
    points: npt.ArrayLike,
    free: npt.ArrayLike,
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
    return string_pull_many([points], free, origin, cell, clearance)[0]


#: Route points tested for sight at once from an anchor (a window; the next one follows
#: while all are seen).
_AHEAD = 64
#: Routes walked in lockstep at once (bounds the segments tested together to
#: ``_BLOCK * _AHEAD``).
_BLOCK = 256


def string_pull_many(
    routes: Sequence[npt.ArrayLike],
    free: npt.ArrayLike,
    origin: tuple[float, float] = (0.0, 0.0),
    cell: float = 1.0,
    clearance: float = 0.2,
) -> list[np.ndarray]:
    """:func:`string_pull` of many routes at once, each exactly as alone.

    The routes are walked in lockstep, a block of them at a time: at every step each
    unfinished route tests the next window of its points for sight from its current
    vertex, and the segments of all of them go through one vectorised test, so the
    Python work is per step, not per route and vertex. A segment's test does not depend
    on the others tested with it, so the kept vertices are those of :func:`string_pull`.

    Parameters
    ----------
    routes : sequence of (n_i, 2) float
        The routes in world coordinates ``(x, y)``.
    free : (H, W) bool or (P, H, W) bool
        Free cells: one grid for every route, or one per route (``P = len(routes)``).
    origin : tuple of float
        World ``(x, y)`` of the corner of cell ``(0, 0)``.
    cell : float
        Cell side (m).
    clearance : float
        Half-width of the walker in cells (see :func:`line_of_sight`).

    Returns
    -------
    list of (m_i, 2) float
        Each route's kept vertices, first and last points included (``m_i <= n_i``).
    """
    free = np.asarray(free, bool)
    cell = float(check_positive("cell", cell))
    if free.ndim == 3 and len(free) != len(routes):
        raise ValueError(
            f"free: expected one (H, W) grid or one per route ({len(routes)}), got "
            f"{free.shape[0]} grids"
        )
    # every route less its repeated points, in one pass over all of them
    routes = [np.asarray(r, float).reshape(-1, 2) for r in routes]
    count = np.array([len(r) for r in routes], np.int64)
    flat = np.concatenate(routes) if routes else np.zeros((0, 2))
    keep = np.ones(len(flat), bool)
    keep[1:] = (np.diff(flat, axis=0) != 0).any(axis=1)
    keep[(np.cumsum(count) - count)[count > 0]] = True  # a route's first point
    owner = np.repeat(np.arange(len(routes)), count)
    kept = np.cumsum(np.bincount(owner[keep], minlength=len(routes)))
    pts = np.split(flat[keep], kept[:-1]) if routes else []
    out = list(pts)
    todo = np.flatnonzero([len(p) >= 3 for p in pts])
    for b0 in range(0, todo.size, _BLOCK):
        block = todo[b0 : b0 + _BLOCK]
        grids = free if free.ndim == 2 else free[block]
        keep = _pull_block([pts[i] for i in block], grids, origin, cell, float(clearance))
        for i, k in zip(block, keep, strict=True):
            out[i] = pts[i][k]
    return out


def _pull_block(
    pts: list[np.ndarray],
    free: np.ndarray,
    origin: tuple[float, float],
    cell: float,
    clearance: float,
) -> list[np.ndarray]:
    """Indices of the kept vertices of each route (``(n_i, 2)`` world points without
    consecutive repeats, ``n_i >= 3``); ``free`` one ``(H, W)`` grid or one per route."""
    n = np.array([len(p) for p in pts], np.int64)
    off = np.concatenate([[0], np.cumsum(n)[:-1]])
    xy = np.concatenate(pts)
    rc = np.column_stack([(xy[:, 1] - origin[1]) / cell, (xy[:, 0] - origin[0]) / cell])
    a = np.zeros(len(n), np.int64)  # current vertex of each route
    j = np.ones(len(n), np.int64)  # farthest point seen from it so far (its next point)
    kept_route, kept_point = [np.arange(len(n))], [np.zeros(len(n), np.int64)]
    active = np.ones(len(n), bool)
    table = _blocked_table(free)
    while active.any():
        idx = np.flatnonzero(active)
        cnt = np.minimum(_AHEAD, n[idx] - 1 - j[idx])  # >= 1: j + 1 < n for the active
        start = np.concatenate([[0], np.cumsum(cnt)[:-1]])
        route = np.repeat(idx, cnt)
        local = np.arange(int(cnt.sum())) - np.repeat(start, cnt)
        p0 = rc[off[route] + a[route]]
        p1 = rc[off[route] + j[route] + 1 + local]
        ok = _sight(free, p0, p1, clearance, None if free.ndim == 2 else route, table)
        # the points seen before the first one that is not, in each window
        run = np.minimum.reduceat(np.where(ok, _AHEAD, local), start)
        run = np.minimum(run, cnt)
        j[idx] += run
        ended = idx[(run < cnt) | (j[idx] == n[idx] - 1)]
        kept_route.append(ended)
        kept_point.append(j[ended].copy())
        a[ended] = j[ended]
        j[ended] = a[ended] + 1
        # a vertex next to the last point: the last point is kept at once
        last = ended[j[ended] == n[ended] - 1]
        kept_route.append(last)
        kept_point.append(j[last].copy())
        a[last] = j[last]
        active = a < n - 1
    r, k = np.concatenate(kept_route), np.concatenate(kept_point)
    order = np.lexsort((k, r))
    r, k = r[order], k[order]
    return np.split(k, np.cumsum(np.bincount(r, minlength=len(n)))[:-1])


#: :func:`preferred_speeds` draws at least this many normals, else the next power of two:
#: one XLA program for the few hundred people of a scene and the 15,100 of the motion
#: checks' 50 replicates alike (issue 29: each shape compiled its own, 1-3 s on a busy
#: core); a draw is the prefix of a longer one (threefry's counters, partitionable).
_NORMAL_BUCKET = 16384


def _normals32(key: jax.Array, n: int) -> np.ndarray:
    """``jax.random.normal(key, (n,), float32)`` as float64, drawn in a bucket's shape
    where the prefix is the same draw (threefry keys, partitionable; else as asked)."""
    try:
        prefix = bool(jax.config.jax_threefry_partitionable) and (
            str(jax.random.key_impl(key)) == "threefry2x32"
        )
    except (TypeError, ValueError):  # a raw key: drawn as asked
        prefix = False
    m = max(_NORMAL_BUCKET, 1 << max(n - 1, 0).bit_length()) if prefix else n
    # (to NumPy before the cut: slicing the JAX array would be a program of its own)
    return np.asarray(jax.random.normal(key, (m,), dtype=np.float32))[:n].astype(float)


def preferred_speeds(key: jax.Array, median: npt.ArrayLike, sd_log: npt.ArrayLike) -> np.ndarray:
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
    z = _normals32(key, med.size)
    return med * np.exp(sd * z)


def walk_times(
    points: npt.ArrayLike,
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
    # a plain number checked as such: continuous_paths times tens of thousands of paths
    # (issue 29), the array checks cost more than the timing
    if not (type(speed) is float and 0.0 < speed < math.inf):
        speed = float(check_positive("speed", speed))
    if not (type(within_sd) is float and 0.0 <= within_sd < math.inf):
        within_sd = float(check_nonnegative("within_sd", within_sd))
    seg = np.hypot(p[1:, 0] - p[:-1, 0], p[1:, 1] - p[:-1, 1])
    if within_sd == 0.0:  # speed * exp(0) is speed: the same times
        return np.concatenate(([0.0], np.cumsum(seg / speed)))
    e = np.zeros(seg.size)
    if seg.size:
        if rng is None:
            raise ValueError("rng: expected a numpy Generator with within_sd > 0, got None")
        z = rng.standard_normal(seg.size)
        rho = np.exp(-np.concatenate([[0.0], seg[:-1]]) / float(correlation))
        e[0] = within_sd * z[0]
        for k in range(1, seg.size):
            e[k] = rho[k] * e[k - 1] + np.sqrt(1.0 - rho[k] ** 2) * within_sd * z[k]
    return np.concatenate([[0.0], np.cumsum(seg / (speed * np.exp(e)))])


def walk_times_many(
    paths: Sequence[npt.ArrayLike],
    speeds: npt.ArrayLike,
    rng: np.random.Generator | None = None,
    within_sd: float = 0.0,
    correlation: float = 10.0,
) -> list[np.ndarray]:
    """:func:`walk_times` of many paths, the same as one after another.

    The paths' normals are one draw from ``rng`` (successive draws of a generator are the
    prefixes of one larger draw), and each step of the AR(1) is taken for every path with
    as many segments at once, with the same operations, so the times are those of
    :func:`walk_times` path after path, to the bit, and ``rng`` ends in the same state.

    Parameters
    ----------
    paths : sequence of (m_i, 2) float
        Vertices (m).
    speeds : (P,) float
        Preferred speeds (m/s, > 0).
    rng, within_sd, correlation
        As :func:`walk_times`.

    Returns
    -------
    list of (max(m_i, 1),) float
        Each path's vertex times from 0.
    """
    pts = [np.asarray(p, float).reshape(-1, 2) for p in paths]
    speeds = np.asarray(speeds, float).reshape(-1)
    if len(speeds) != len(pts):
        raise ValueError(f"speeds: expected one per path ({len(pts)}), got {len(speeds)}")
    bad = ~((speeds > 0.0) & (speeds < math.inf))
    if bad.any():  # as walk_times checks one: an error, or its value
        speeds = speeds.copy()
        speeds[bad] = [float(check_positive("speed", v)) for v in speeds[bad]]
    if not (type(within_sd) is float and 0.0 <= within_sd < math.inf):
        within_sd = float(check_nonnegative("within_sd", within_sd))
    count = np.array([len(p) for p in pts], np.int64)
    n_seg = np.maximum(count - 1, 0)
    if not pts:
        return []
    flat = np.concatenate(pts)
    # segment j of path i: from flat vertex first[i] + j, at flat segment seg0[i] + j
    first = np.cumsum(count) - count
    seg0 = np.cumsum(n_seg) - n_seg
    owner = np.repeat(np.arange(len(pts)), n_seg)
    at = first[owner] + np.arange(owner.size) - seg0[owner]
    seg = np.hypot(flat[at + 1, 0] - flat[at, 0], flat[at + 1, 1] - flat[at, 1])
    z = None
    if within_sd != 0.0 and seg.size:
        if rng is None:
            raise ValueError("rng: expected a numpy Generator with within_sd > 0, got None")
        z = rng.standard_normal(seg.size)
    out: list[np.ndarray] = [np.zeros(1)] * len(pts)
    for k in np.unique(n_seg):
        rows = np.flatnonzero(n_seg == k)
        if k == 0:
            for r in rows:
                out[r] = np.zeros(1)
            continue
        cols = seg0[rows][:, None] + np.arange(k)
        s = seg[cols]
        v = speeds[rows][:, None]
        if z is None:  # speed * exp(0) is speed: the same times
            step = s / v
        else:
            zz = z[cols]
            prev = np.zeros_like(s)
            prev[:, 1:] = s[:, :-1]
            rho = np.exp(-prev / float(correlation))
            # walk_times' rho[k] ** 2 is a scalar power (libm's pow): not always x * x
            rho2 = np.array([math.pow(r, 2.0) for r in rho[:, 1:].ravel().tolist()])
            scale = np.sqrt(1.0 - rho2.reshape(len(rows), k - 1)) * within_sd
            e = np.empty_like(s)
            e[:, 0] = within_sd * zz[:, 0]
            for j in range(1, k):
                e[:, j] = rho[:, j] * e[:, j - 1] + scale[:, j - 1] * zz[:, j]
            step = s / (v * np.exp(e))
        t = np.zeros((len(rows), k + 1))
        t[:, 1:] = np.cumsum(step, axis=1)
        for r, tr in zip(rows, t, strict=True):
            out[r] = tr
    return out


def arrival_velocities(tracks: pd.DataFrame) -> pd.DataFrame:
    """Planned tracks with the velocity each one arrives with: that of its first planned
    move.

    People come into a map walking (through a door, into a sensor's view), so a walker
    whose plan moves from its first sample arrives at the velocity of that first move (its
    preferred speed, along its route's first leg) rather than from rest; one whose plan
    first stands (a stay, a turn in place) arrives standing. The social force
    (:func:`~are_stats.behaviour.social_force_tracks`) reads these columns as the velocity
    at each track's first row: without them every walker set off from rest and lagged its
    plan by the relaxation time (0.5 s, 0.6 m at 1.2 m/s), so that a walker timed to reach
    its exit at the end of its stay had not reached it by then.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (m, s), optionally ``scenario`` (tracks are ``(scenario, id)``);
        each track's rows in time order (any track order).

    Returns
    -------
    pandas.DataFrame
        ``tracks`` with columns ``vx, vy`` (m/s): on every row of a track, the velocity of
        its first move (its second position less its first over their time apart; 0 for a
        track of one row or one whose first two rows are at one place or one time).
    """
    keys = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    code = tracks.groupby(keys, sort=False).ngroup().to_numpy()
    t = tracks["t"].to_numpy(float)
    xy = tracks[["x", "y"]].to_numpy(float)
    n = int(code.max()) + 1 if code.size else 0
    # each track's first two rows (the table's order within a track is its time order)
    order = np.argsort(code, kind="stable")
    start = np.searchsorted(code[order], np.arange(n))
    two = np.bincount(code, minlength=n) > 1
    a, b = order[start[two]], order[start[two] + 1]
    span = t[b] - t[a]
    v = np.zeros((a.size, 2))
    ok = span > 0
    v[ok] = (xy[b[ok]] - xy[a[ok]]) / span[ok, None]
    vel = np.zeros((n, 2))
    vel[two] = v
    return tracks.assign(vx=vel[code, 0], vy=vel[code, 1])
