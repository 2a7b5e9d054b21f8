"""The implicit tree used to gather triangles per pixel block (_frustum_bvh)."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.perception._frustum_bvh import BRANCH, LEAF, build_frustum_bvh, morton_codes


@pytest.mark.parametrize("n_faces", [1, LEAF, LEAF * BRANCH + 3, 1000])
def test_tree_bounds_hold_their_triangles(n_faces):
    rng = np.random.default_rng(n_faces)
    v = rng.normal(size=(3 * n_faces, 3)).astype(np.float32) * [10.0, 10.0, 1.0]
    v = v.astype(np.float32)
    f = rng.permutation(3 * n_faces).reshape(n_faces, 3).astype(np.int32)
    tree = build_frustum_bvh(v, f, "cpu")
    assert tree.n_tri == n_faces
    order = tree.order.numpy()
    np.testing.assert_array_equal(np.sort(order), np.arange(n_faces))
    tri = v[f[order]]
    np.testing.assert_array_equal(tree.p0.numpy(), tri[:, 0])
    np.testing.assert_allclose(tree.e1.numpy(), tri[:, 1] - tri[:, 0], rtol=0, atol=0)
    np.testing.assert_allclose(tree.e2.numpy(), tri[:, 2] - tri[:, 0], rtol=0, atol=0)
    lo, hi = tree.lower.numpy(), tree.upper.numpy()
    start = tree.level_start.numpy()
    assert start[-1] == len(lo) and start[-1] - start[-2] == 1  # a single root
    assert len(start) == tree.n_levels + 1
    # level 0: node j bounds triangles LEAF j ... LEAF j + LEAF - 1, exactly
    for j in range(start[1]):
        t = tri[j * LEAF : (j + 1) * LEAF].reshape(-1, 3)
        np.testing.assert_array_equal(lo[j], t.min(axis=0))
        np.testing.assert_array_equal(hi[j], t.max(axis=0))
    # level k: node j bounds children BRANCH j ... of level k - 1, exactly
    for k in range(1, tree.n_levels):
        n_child = start[k] - start[k - 1]
        for j in range(start[k + 1] - start[k]):
            ch = np.arange(BRANCH * j, min(BRANCH * j + BRANCH, n_child)) + start[k - 1]
            assert len(ch) > 0
            np.testing.assert_array_equal(lo[start[k] + j], lo[ch].min(axis=0))
            np.testing.assert_array_equal(hi[start[k] + j], hi[ch].max(axis=0))
    np.testing.assert_array_equal(lo[-1], v[f].reshape(-1, 3).min(axis=0))


def test_morton_order_follows_space():
    g = np.arange(4.0)
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    codes = morton_codes(pts)
    assert len(np.unique(codes)) == len(pts)
    # the first 8 codes fill the first 2x2x2 octant
    first = pts[np.argsort(codes)[:8]]
    assert first.max() <= 1.0
