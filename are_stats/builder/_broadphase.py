"""Broad phase of collision detection: a uniform spatial hash over axis-aligned boxes.

Every box is entered in the hash cells its AABB covers; two boxes are candidates when they
share a cell and their AABBs overlap. A pair sharing several cells is reported once: only in
the cell holding the lower-left corner of the two AABBs' intersection. All steps are sorts
and ``np.repeat`` expansions, so ``n`` boxes cost ``O(n log n + pairs)`` instead of the
``n^2 / 2`` narrow tests of brute force.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["aabb_pairs", "aabb_pairs_brute", "SpatialHash"]

_SHIFT = np.int64(1 << 31)


def _cells(lo: np.ndarray, hi: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Entries ``(owner, key)`` of every hash cell covered by each AABB."""
    i0 = np.floor(lo / cell).astype(np.int64)
    i1 = np.floor(hi / cell).astype(np.int64)
    nx = i1[:, 0] - i0[:, 0] + 1
    ny = i1[:, 1] - i0[:, 1] + 1
    cnt = nx * ny
    owner = np.repeat(np.arange(lo.shape[0]), cnt)
    local = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    nyo = ny[owner]
    cx = i0[owner, 0] + local // nyo
    cy = i0[owner, 1] + local % nyo
    return owner, cx * _SHIFT + cy


def _default_cell(lo: np.ndarray, hi: np.ndarray) -> float:
    ext = (hi - lo).max(axis=1)
    c = float(np.max(ext)) if ext.size else 1.0
    return c if c > 0 else 1.0


def _check_boxes(lo: npt.ArrayLike, hi: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    if lo.ndim != 2 or lo.shape[1] != 2 or lo.shape != hi.shape:
        raise ValueError(f"lo, hi: expected two (n, 2) arrays, got {lo.shape} and {hi.shape}")
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()) or (hi < lo).any():
        raise ValueError("lo, hi: expected finite boxes with hi >= lo")
    return lo, hi


def aabb_pairs(lo: npt.ArrayLike, hi: npt.ArrayLike, cell: float | None = None) -> np.ndarray:
    """All pairs of overlapping axis-aligned boxes (touching counts as overlapping).

    Parameters
    ----------
    lo, hi : (n, 2) float
        Lower-left and upper-right corners.
    cell : float, optional
        Hash cell size; default the largest box extent (each box then covers at most 4
        cells).

    Returns
    -------
    (m, 2) int64
        Pairs ``(a, b)`` with ``a < b``, sorted.
    """
    lo, hi = _check_boxes(lo, hi)
    n = lo.shape[0]
    if n < 2:
        return np.zeros((0, 2), np.int64)
    s = _default_cell(lo, hi) if cell is None else float(cell)
    owner, key = _cells(lo, hi, s)
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    m = key.size
    start = np.r_[True, key[1:] != key[:-1]]
    gstart = np.flatnonzero(start)
    gend = np.r_[gstart[1:], m]
    gid = np.cumsum(start) - 1
    end_of = gend[gid]
    cnt = end_of - np.arange(m) - 1
    total = int(cnt.sum())
    if total == 0:
        return np.zeros((0, 2), np.int64)
    ia = np.repeat(np.arange(m), cnt)
    ib = ia + 1 + (np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    a, b = owner[ia], owner[ib]
    ck = key[ia]
    ok = (lo[a] <= hi[b]).all(axis=1) & (lo[b] <= hi[a]).all(axis=1)
    # report each pair once: in the cell holding the corner max(lo_a, lo_b)
    corner = np.maximum(lo[a], lo[b])
    cc = np.floor(corner / s).astype(np.int64)
    ok &= (cc[:, 0] * _SHIFT + cc[:, 1]) == ck
    a, b = a[ok], b[ok]
    pairs = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def aabb_pairs_brute(lo: npt.ArrayLike, hi: npt.ArrayLike) -> np.ndarray:
    """Reference: all overlapping pairs by testing every pair (``O(n^2)``)."""
    lo, hi = _check_boxes(lo, hi)
    a, b = np.triu_indices(lo.shape[0], k=1)
    ok = (lo[a] <= hi[b]).all(axis=1) & (lo[b] <= hi[a]).all(axis=1)
    return np.stack([a[ok], b[ok]], axis=1).astype(np.int64)


class SpatialHash:
    """A static hash of AABBs (e.g. environment triangles) queried with moving boxes.

    Parameters
    ----------
    lo, hi : (n, 2) float
        The static boxes.
    cell : float
        Hash cell size.
    """

    def __init__(self, lo: npt.ArrayLike, hi: npt.ArrayLike, cell: float) -> None:
        self.lo, self.hi = _check_boxes(lo, hi)
        if not cell > 0:
            raise ValueError(f"cell: expected a size > 0, got {cell!r}")
        self.cell = float(cell)
        owner, key = _cells(self.lo, self.hi, self.cell)
        order = np.argsort(key, kind="stable")
        self._key, self._owner = key[order], owner[order]

    def query(self, lo: npt.ArrayLike, hi: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pairs ``(query_index, static_index)`` whose AABBs overlap, each reported once."""
        qlo, qhi = _check_boxes(lo, hi)
        if qlo.shape[0] == 0 or self._key.size == 0:
            z = np.zeros(0, np.int64)
            return z, z
        qowner, qkey = _cells(qlo, qhi, self.cell)
        left = np.searchsorted(self._key, qkey, "left")
        right = np.searchsorted(self._key, qkey, "right")
        cnt = right - left
        total = int(cnt.sum())
        qa = np.repeat(qowner, cnt)
        ck = np.repeat(qkey, cnt)
        pos = np.repeat(left - (np.cumsum(cnt) - cnt), cnt) + np.arange(total)
        sb = self._owner[pos]
        ok = (qlo[qa] <= self.hi[sb]).all(axis=1) & (self.lo[sb] <= qhi[qa]).all(axis=1)
        corner = np.maximum(qlo[qa], self.lo[sb])
        cc = np.floor(corner / self.cell).astype(np.int64)
        ok &= (cc[:, 0] * _SHIFT + cc[:, 1]) == ck
        return qa[ok], sb[ok]
