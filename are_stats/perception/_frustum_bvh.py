"""An implicit bounding-volume tree over the environment triangles, for frustum gathering.

The environment kernel (:func:`~are_stats.perception._kernels.env_block_kernel`) traces
the rays of an 8x8 pixel block together: it first walks this tree with the block's ray
pyramid (four side planes through the camera centre and the pixel centres of the block's
edges, plus the optical depth range ``[0, top]``) and collects the few triangles that can
meet any of the block's rays; each ray then tests only those. Warp's mesh BVH answers one
ray at a time and does not expose its nodes, hence this second, simpler tree.

Layout
------
Triangles are sorted along a Morton curve of their centroids. Level 0 holds one node per
``LEAF`` consecutive triangles, level ``k + 1`` one node per ``BRANCH`` consecutive nodes
of level ``k``, up to a single root: node ``j`` of level ``k`` has the children
``BRANCH * j ... BRANCH * j + BRANCH - 1`` of level ``k - 1`` (those that exist), so the
walk needs no pointers and no stack. The bounds of a node are exact float32 min/max over
its triangles' vertices.

Every triangle is stored as ``p0, e1 = p1 - p0, e2 = p2 - p0`` (float32, the same rounded
vertices as Warp's mesh) in the sorted order; ``order`` maps a sorted position back to the
face index.
"""

from __future__ import annotations

import numpy as np
import warp as wp

__all__ = ["BRANCH", "LEAF", "FrustumBVH", "build_frustum_bvh", "morton_codes"]

LEAF = 4  # triangles per leaf
BRANCH = 4  # children per inner node


@wp.struct
class FrustumBVH:
    """Device arrays of the implicit tree (see the module docstring); a kernel argument."""

    p0: wp.array(dtype=wp.vec3)  # (F,) first vertex of each sorted triangle
    e1: wp.array(dtype=wp.vec3)  # (F,) second minus first vertex
    e2: wp.array(dtype=wp.vec3)  # (F,) third minus first vertex
    lower: wp.array(dtype=wp.vec3)  # (N,) node lower bounds, level 0 first
    upper: wp.array(dtype=wp.vec3)  # (N,) node upper bounds
    level_start: wp.array(dtype=wp.int32)  # (L + 1,) first node of each level (and the total)
    n_levels: int
    n_tri: int
    order: wp.array(dtype=wp.int64)  # (F,) face index of each sorted triangle


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Insert two zero bits between the low 10 bits of ``v`` (uint64)."""
    v = v & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v


def morton_codes(points: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of ``points (n, 3)`` on a grid of 1024^3 cubic cells.

    The cells are cubes (the longest side of the points' box over 1024), so that a run of
    consecutive codes is compact in space even for a flat terrain: cells scaled per axis
    would split the thin axis first.
    """
    lo = points.min(axis=0)
    span = max(float((points.max(axis=0) - lo).max()), 1e-30)
    q = np.clip((points - lo) / span * 1024.0, 0, 1023).astype(np.uint64)
    return (_spread_bits(q[:, 0]) << 2) | (_spread_bits(q[:, 1]) << 1) | _spread_bits(q[:, 2])


def build_frustum_bvh(vertices: np.ndarray, faces: np.ndarray, device: str) -> FrustumBVH:
    """Build the implicit tree of a triangle mesh.

    Parameters
    ----------
    vertices : (V, 3) float32
        Vertex positions (already checked finite).
    faces : (F, 3) int32
        Triangles (already checked to index ``vertices``), F >= 1.
    device : str
        Warp device of the arrays.

    Returns
    -------
    FrustumBVH
    """
    tri = vertices[faces]  # (F, 3, 3) float32
    order = np.argsort(morton_codes(tri.astype(np.float64).mean(axis=1)), kind="stable")
    tri = tri[order]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    lowers, uppers = [], []
    size = LEAF
    while True:
        starts = np.arange(0, len(lo), size)
        lo, hi = np.minimum.reduceat(lo, starts), np.maximum.reduceat(hi, starts)
        lowers.append(lo)
        uppers.append(hi)
        if len(lo) == 1:
            break
        size = BRANCH
    level_start = np.zeros(len(lowers) + 1, np.int32)
    np.cumsum([len(x) for x in lowers], out=level_start[1:])

    def vec3(a: np.ndarray) -> wp.array:
        return wp.array(np.ascontiguousarray(a, np.float32), dtype=wp.vec3, device=device)

    tree = FrustumBVH()
    tree.p0, tree.e1, tree.e2 = (
        vec3(tri[:, 0]),
        vec3(tri[:, 1] - tri[:, 0]),
        vec3(tri[:, 2] - tri[:, 0]),
    )
    tree.lower, tree.upper = vec3(np.concatenate(lowers)), vec3(np.concatenate(uppers))
    tree.level_start = wp.array(level_start, dtype=wp.int32, device=device)
    tree.n_levels, tree.n_tri = len(lowers), len(tri)
    tree.order = wp.array(order.astype(np.int64), dtype=wp.int64, device=device)
    return tree
