"""Broad phase: the spatial hash returns exactly the pairs of brute force."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from are_stats.builder import SpatialHash, aabb_pairs, aabb_pairs_brute


@settings(max_examples=80, deadline=None)
@given(
    st.integers(0, 150),
    st.floats(0.01, 15.0),
    st.one_of(st.none(), st.floats(0.2, 20.0)),
    st.integers(0, 2**31),
)
def test_hash_equals_brute_force(n, max_size, cell, seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-20, 20, (n, 2))
    hi = lo + rng.uniform(0, max_size, (n, 2))
    if n > 3:  # exact touching and duplicate boxes
        lo[1], hi[1] = lo[0], hi[0]
        lo[2] = [hi[0][0], lo[0][1]]
        hi[2] = lo[2] + 1.0
    got = aabb_pairs(lo, hi, cell)
    ref = aabb_pairs_brute(lo, hi)
    assert got.tolist() == ref.tolist()


def test_static_hash_query(rng):
    lo = rng.uniform(0, 50, (300, 2))
    hi = lo + rng.uniform(0, 8, (300, 2))
    q = rng.uniform(0, 50, (80, 2))
    qh = q + rng.uniform(0, 3, (80, 2))
    qa, sb = SpatialHash(lo, hi, 2.0).query(q, qh)
    got = sorted(zip(qa.tolist(), sb.tolist(), strict=True))
    ok = (q[:, None, :] <= hi[None]).all(-1) & (lo[None] <= qh[:, None, :]).all(-1)
    assert got == sorted(map(tuple, np.argwhere(ok).tolist()))


def test_bad_boxes():
    with pytest.raises(ValueError, match="hi >= lo"):
        aabb_pairs([[0, 0]], [[-1, 1]])
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        aabb_pairs([0, 0], [1, 1])
