"""The traffic checks' replicated windows are summarised in one pass over all of them
(``_replicate_statistics``): every value must be :func:`window_statistics`' of that window
alone, bit for bit, whatever the windows hold (none, one, many rows; arrivals at the
log's resolution, ties, stays past the window, truncated rows, NaN and inf leaving times;
windows longer than NumPy's 8,192-element reduction buffer)."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.fitting import TRAFFIC_STATISTICS, window_statistics
from are_stats.fitting._traffic_checks import _replicate_statistics


def _windows(seed: int, span: float, big: int) -> tuple:
    rng = np.random.default_rng(seed)
    t0 = float(rng.choice([0.0, 5.0]))
    t1 = t0 + span
    sizes = rng.integers(0, big, int(rng.integers(1, 10)))
    sizes[0] = 0  # an empty window first
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    n = int(bounds[-1])
    ta = np.round(t0 + rng.uniform(-0.1, 1.0, n) * span, int(rng.integers(0, 3)))
    tl = ta + rng.exponential(float(rng.choice([5.0, span / 20])), n)
    tl[rng.random(n) < 0.2] = np.nan
    tl[rng.random(n) < 0.1] = np.inf
    truncated = rng.random(n) < 0.15
    return ta, tl, truncated, bounds, (t0, t1), float(rng.choice([0.2, 1.0]))


@pytest.mark.parametrize("span", [100.0, 650.0, 14400.0, 20000.0])
@pytest.mark.parametrize("big", [3, 40, 400])
def test_replicate_statistics_are_window_statistics(span, big):
    for seed in range(4):
        ta, tl, tr, bounds, window, res = _windows(seed, span, big)
        got = _replicate_statistics(ta, tl, tr, bounds, window, res)
        want = np.array(
            [
                [window_statistics(ta[a:b], tl[a:b], tr[a:b], window, res)[s]
                 for s in TRAFFIC_STATISTICS]
                for a, b in zip(bounds[:-1], bounds[1:], strict=True)
            ]
        )  # fmt: skip
        assert got.shape == (len(bounds) - 1, len(TRAFFIC_STATISTICS))
        np.testing.assert_array_equal(got, want)  # NaN where NaN, else the same bits
        # entry points are the caller's (traffic_checks'): never filled here
        assert np.isnan(got[:, TRAFFIC_STATISTICS.index("entry to boundary (m)")]).all()


def test_replicate_statistics_by_hand():
    """Two windows of [0, 120): a burst of three arrivals in one tick, and nothing."""
    ta = np.array([10.0, 10.0, 10.0, 70.0])
    tl = np.array([20.0, 40.0, np.nan, 75.0])
    tr = np.zeros(4, bool)
    got = _replicate_statistics(ta, tl, tr, np.array([0, 4, 4]), (0.0, 120.0), 1.0)
    col = {s: i for i, s in enumerate(TRAFFIC_STATISTICS)}
    assert got[0, col["N(t) peak"]] == 3.0
    assert got[0, col["zero gaps"]] == pytest.approx(2 / 3)  # 10-10, 10-10, 10-70
    # whole stays of 10, 30 and 5 s (the NaN one runs past the window): sd 175**0.5, mean 15
    assert got[0, col["stay cv"]] == pytest.approx(175**0.5 / 15)
    assert got[0, col["longest N(t) = 0 (s)"]] == 10.0  # [0, 10) before anyone comes
    # the empty window: no one present, never an arrival
    assert got[1, col["N(t) peak"]] == 0.0
    assert got[1, col["longest N(t) = 0 (s)"]] == 120.0
    assert np.isnan(got[1, col["N(t) var/mean"]]) and np.isnan(got[1, col["zero gaps"]])


def test_crowding_statistics_are_the_median_of_each_scenarios_statistics():
    """crowding_statistics summarises all scenarios in one pass; the medians must be those
    of window_statistics scenario by scenario (rows of a scenario interleaved with
    others', ids out of order and with gaps), and NaN for an empty table."""
    import pandas as pd

    from are_stats.fitting import CROWDING_STATISTICS, crowding_statistics

    ta, tl, tr, bounds, window, res = _windows(5, 3600.0, 60)
    sid = np.repeat(np.arange(len(bounds) - 1) * 3 + 7, np.diff(bounds))
    rows = np.random.default_rng(0).permutation(sid.size)
    table = pd.DataFrame(
        {"scenario": sid[rows], "t_arrive": ta[rows], "t_leave": tl[rows], "truncated": tr[rows]}
    )
    got = crowding_statistics(table, window, res)
    per = [
        window_statistics(sc["t_arrive"].to_numpy(), sc["t_leave"].to_numpy(),
                          sc["truncated"].to_numpy(), window, res)
        for _, sc in table.groupby("scenario")
    ]  # fmt: skip
    want = {k: float(np.nanmedian([p[k] for p in per])) for k in CROWDING_STATISTICS}
    assert got.keys() == want.keys()
    for k in CROWDING_STATISTICS:
        assert got[k] == want[k] or (np.isnan(got[k]) and np.isnan(want[k])), k
    empty = crowding_statistics(table.iloc[:0], window, res)
    assert all(np.isnan(v) for v in empty.values())
