"""fitting.crowding_statistics: the demo's crowding medians over scenarios, against N(t)
counted by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.fitting import CROWDING_STATISTICS, crowding_statistics


def test_crowding_statistics_are_medians_over_scenarios_of_hand_counted_windows():
    """Window (0, 240): N(t) is read at t = 1, 2, ..., 239. Scenario 0 holds two people
    from 0.5 s (to 120.5 and 60.5 s) and one from 200.5 s to the end; scenario 1 four
    arriving 10 s apart from 10.5 s, three of them leaving inside the window after 40, 60
    and 60 s. Counted by hand (N(t) per stretch of whole seconds), then the median over
    the two scenarios (stay cv: scenario 0 has two complete stays, too few: NaN, skipped)."""
    table = pd.DataFrame(
        {
            "scenario": [0, 0, 0, 1, 1, 1, 1],
            "t_arrive": [0.5, 0.5, 200.5, 10.5, 20.5, 30.5, 40.5],
            "t_leave": [120.5, 60.5, np.nan, 50.5, 80.5, 90.5, 250.0],
            "truncated": [False] * 7,
        }
    )
    n0 = np.repeat([2, 1, 0, 1], [60, 60, 80, 39])  # t = 1..60, 61..120, 121..200, 201..239
    n1 = np.repeat([0, 1, 2, 3, 4, 3, 2, 1], [10, 10, 10, 10, 10, 30, 10, 149])
    assert n0.size == n1.size == 239
    ratio = [n.var(ddof=1) / n.mean() for n in (n0, n1)]
    stays = np.array([40.0, 60.0, 60.0])
    got = crowding_statistics(table, (0.0, 240.0), 1.0)
    assert tuple(got) == CROWDING_STATISTICS
    assert got["N(t) var/mean"] == pytest.approx(np.mean(ratio))
    assert got["N(t) peak"] == 3.0  # peaks 2 and 4
    assert got["zero gaps"] == 0.25  # 1 of 2 gaps is zero (0.5, 0.5), none of 3
    assert got["stay cv"] == pytest.approx(stays.std(ddof=1) / stays.mean())
