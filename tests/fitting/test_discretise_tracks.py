"""``discretise_tracks`` for all tracks at once (issue 29) against the per-track loop it
replaced, kept here as the reference: the same paths and ids, bit for bit.

Deterministic (seeded tables, exact comparisons).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import ndimage

from are_stats.fitting import discretise_tracks


def _line_cells(a, b):
    out = []
    r, c = int(a[0]), int(a[1])
    dr, dc = int(b[0]) - r, int(b[1]) - c
    nr, nc = abs(dr), abs(dc)
    sr, sc = int(np.sign(dr)), int(np.sign(dc))
    i = j = 0
    while i < nr or j < nc:
        if j >= nc or (i < nr and (i + 0.5) / nr <= (j + 0.5) / nc):
            r += sr
            i += 1
        else:
            c += sc
            j += 1
        out.append((r, c))
    return out


def _reference(tracks, free, cell, origin, dt):
    """The per-track loop of the code before (commit 81043a8)."""
    free = np.asarray(free, bool)
    h, w = free.shape
    o = np.asarray(origin, float)
    _, (ri, ci) = ndimage.distance_transform_edt(~free, return_indices=True)
    paths, ids = [], []
    for tid, g in tracks.groupby("id", sort=True):
        g = g.sort_values("t", kind="stable")
        t = g["t"].to_numpy(float)
        xy = g[["x", "y"]].to_numpy(float)
        n_ep = int(np.floor((t[-1] - t[0]) / dt + 1e-9))
        te = t[0] + dt * np.arange(n_ep + 1)
        if t[-1] - te[-1] > 1e-9 * max(1.0, abs(t[-1])):
            te = np.append(te, t[-1])
        x = np.interp(te, t, xy[:, 0])
        y = np.interp(te, t, xy[:, 1])
        col = np.clip(np.floor((x - o[0]) / cell), 0, w - 1).astype(np.int64)
        row = np.clip(np.floor((y - o[1]) / cell), 0, h - 1).astype(np.int64)
        row, col = ri[row, col], ci[row, col]
        path = [(int(row[0]), int(col[0]))]
        for r, c in zip(row[1:].tolist(), col[1:].tolist(), strict=True):
            if (r, c) == path[-1]:
                path.append((r, c))
            else:
                path.extend(_line_cells(np.array(path[-1]), np.array((r, c))))
        p = np.asarray(path, np.int64)
        first = int(np.flatnonzero((p == p[-1]).all(axis=1))[0])
        paths.append(p[: first + 1])
        ids.append(tid)
    return paths, np.asarray(ids)


def _table(rng: np.random.Generator, n: int, int_ids: bool) -> pd.DataFrame:
    """``n`` tracks in shuffled rows: walks, jumps across the map, tracks that leave it,
    single sightings, repeated times and times off the epochs."""
    rows = []
    for i in range(n):
        m = int(rng.integers(1, 40))
        t = np.sort(rng.choice(np.arange(0.0, 60.0, 0.1), m, replace=False)) + rng.uniform(0, 5)
        if m > 3 and i % 7 == 0:
            t[2] = t[1]  # a repeated time
        xy = rng.uniform(-1.0, 21.0, 2) + np.cumsum(rng.normal(0.0, 0.6, (m, 2)), axis=0)
        if i % 5 == 0:
            xy[m // 2 :] += rng.uniform(-8.0, 8.0, 2)  # a jump of many cells
        ident = (
            int(rng.integers(0, 10 * n)) * 1000 + i if int_ids else f"p{rng.integers(0, 99)}-{i}"
        )
        rows.append(pd.DataFrame({"id": ident, "t": t, "x": xy[:, 0], "y": xy[:, 1]}))
    tab = pd.concat(rows, ignore_index=True)
    return tab.iloc[rng.permutation(len(tab))].reset_index(drop=True)


@pytest.mark.parametrize(
    ("seed", "int_ids", "dt"), [(0, False, 0.4), (1, True, 0.7), (2, False, 1.3)]
)
def test_all_tracks_at_once_give_the_per_track_paths(seed, int_ids, dt):
    rng = np.random.default_rng(seed)
    free = np.ones((40, 42), bool)
    free[:, :1] = free[:, -1:] = free[:1, :] = free[-1:, :] = False
    free[15:25, 18:22] = False  # a pillar: cells snap to the nearest free one
    tracks = _table(rng, 80, int_ids)
    got, ids = discretise_tracks(tracks, free, 0.5, (0.3, -0.2), dt)
    want, want_ids = _reference(tracks, free, 0.5, (0.3, -0.2), dt)
    assert ids.dtype == want_ids.dtype and np.array_equal(ids, want_ids)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and np.array_equal(g, w)


def test_no_tracks():
    empty = pd.DataFrame({"id": [], "t": [], "x": [], "y": []})
    paths, ids = discretise_tracks(empty, np.ones((3, 3), bool), 1.0, (0.0, 0.0), 1.0)
    want, want_ids = _reference(empty, np.ones((3, 3), bool), 1.0, (0.0, 0.0), 1.0)
    assert paths == want == [] and ids.dtype == want_ids.dtype and ids.size == 0
