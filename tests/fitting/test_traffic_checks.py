"""The replicated windows' statistics at once (``_replicate_statistics``) against
:func:`window_statistics` of each window, bit for bit."""

import numpy as np
import pytest

from are_stats.fitting import TRAFFIC_STATISTICS, window_statistics
from are_stats.fitting._traffic_checks import _replicate_statistics


def _windows(rng: np.random.Generator) -> tuple:
    """Windows of 0 to hundreds of rows: arrivals before, inside and after the window on
    the log's tick grid, stays still open (inf) or unknown (NaN), truncated rows with and
    without an arrival time, and some windows with tied arrivals."""
    t0 = float(rng.choice([0.0, 12.5, -30.0]))
    t1 = t0 + float(rng.choice([5.0, 45.0, 600.0, 3600.0, 7300.3]))
    sizes = rng.poisson(rng.choice([0.5, 5.0, 60.0, 400.0]), int(rng.integers(1, 30)))
    n = int(sizes.sum())
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    res = float(rng.choice([1e-6, 0.1, 1.0, 5.0]))
    ta = t0 + rng.uniform(-0.1, 1.05, n) * (t1 - t0)
    ta = np.ceil((ta - t0) / res - 1e-9) * res + t0
    if rng.random() < 0.2:
        ta = np.round(ta)
    tl = ta + rng.exponential(rng.choice([1.0, 50.0, 1000.0]), n)
    tl[rng.random(n) < 0.2] = np.inf
    tl[rng.random(n) < 0.05] = np.nan
    tr = rng.random(n) < 0.15
    ta[tr & (rng.random(n) < 0.5)] = np.nan
    return ta, tl, tr, bounds, (t0, t1), res


@pytest.mark.parametrize("seed", range(4))
def test_replicate_statistics_are_each_windows_own(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        ta, tl, tr, bounds, window, res = _windows(rng)
        got = _replicate_statistics(ta, tl, tr, bounds, window, res)
        assert got.shape == (bounds.size - 1, len(TRAFFIC_STATISTICS))
        for r in range(bounds.size - 1):
            a, b = bounds[r], bounds[r + 1]
            st = window_statistics(ta[a:b], tl[a:b], tr[a:b], window, res)
            want = np.array([st[s] for s in TRAFFIC_STATISTICS])
            np.testing.assert_array_equal(got[r], want, err_msg=f"window {r} of {window}")


def test_replicate_statistics_of_a_small_case_by_hand():
    # window (0, 100): one window with arrivals at 10 (stays to 30) and 50 (stays to 70),
    # then an empty window
    got = _replicate_statistics(
        np.array([10.0, 50.0]),
        np.array([30.0, 70.0]),
        np.array([False, False]),
        np.array([0, 2, 2]),
        (0.0, 100.0),
        1.0,
    )
    col = {s: i for i, s in enumerate(TRAFFIC_STATISTICS)}
    assert got[0, col["N(t) peak"]] == 1.0
    assert got[0, col["zero gaps"]] == 0.0
    assert got[0, col["longest N(t) = 0 (s)"]] == 30.0  # from 70 to 100
    assert np.isnan(got[0, col["stay cv"]])  # two stays: fewer than three
    assert got[1, col["longest N(t) = 0 (s)"]] == 100.0  # nobody: the whole window
    assert got[1, col["N(t) peak"]] == 0.0 and np.isnan(got[1, col["N(t) var/mean"]])
    assert np.isnan(got[:, col["entry to boundary (m)"]]).all()
