"""Model-criticism summaries against scipy and hand computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from are_stats.fitting._criticism import (
    count_path,
    dispersion_index,
    hour_of_day_counts,
    kaplan_meier,
)
from tests.helpers import ALPHA, assert_allclose


def test_kaplan_meier_matches_scipy_ecdf(rng):
    d = rng.exponential(3.0, 300)
    c = rng.uniform(size=300) < 0.3
    km = kaplan_meier(d, c)
    ref = stats.ecdf(stats.CensoredData(uncensored=d[~c], right=d[c])).sf
    assert_allclose(km.survival, ref.evaluate(km.time), rtol=1e-12)
    lo, hi = ref.confidence_interval(0.95, method="log-log")
    assert_allclose(km.lower, lo.evaluate(km.time), rtol=1e-9, atol=1e-12)
    assert_allclose(km.upper, hi.evaluate(km.time), rtol=1e-9, atol=1e-12)


def test_kaplan_meier_hand_example():
    # stays 1, 2+, 3, 3, 4+: S(1)=4/5, S(3)=4/5*(1-2/3)
    km = kaplan_meier([1, 2, 3, 3, 4], [False, True, False, False, True])
    assert_allclose(km.time, [1, 3])
    assert_allclose(km.survival, [0.8, 0.8 / 3])
    assert_allclose(km([0.5, 1.0, 2.5, 10]), [1.0, 0.8, 0.8, 0.8 / 3])


def test_dispersion_index_poisson_and_overdispersed(rng):
    # under Poisson the two-sided test rejects with probability ALPHA
    assert dispersion_index(rng.poisson(4.0, 500)).pvalue > ALPHA
    nb = rng.negative_binomial(2, 2 / 6, 500)  # mean 4, variance 12
    res = dispersion_index(nb)
    assert res.pvalue < ALPHA and res.index > 2


def test_count_path_by_hand():
    a = [np.nan, 1.0, 2.0, 5.0]
    b = [3.0, np.nan, 2.5, 6.0]
    assert count_path(a, b, [0.0, 1.0, 2.2, 3.0, 5.5, 7.0]).tolist() == [1, 2, 3, 1, 2, 1]


def test_hour_of_day_counts():
    t = np.array([0.5, 1.5, 25.2, 47.9])
    assert hour_of_day_counts(t)[[0, 1, 23]].tolist() == [1, 2, 1]
    assert hour_of_day_counts(t, clock_offset=1.0)[[1, 2, 0]].tolist() == [1, 2, 1]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: kaplan_meier([], []), "durations: expected at least one"),
        (lambda: kaplan_meier([1.0, -1.0], [False, False]), "durations: expected finite"),
        (lambda: kaplan_meier([1.0, 2.0], [False]), "censored: expected shape"),
        (lambda: dispersion_index([1, 2.5]), "counts: expected non-negative integers"),
        (lambda: dispersion_index([0, 0, 0]), "counts: expected at least one non-zero"),
        (lambda: count_path([1.0], [2.0, 3.0], [1.0]), "t_leave: expected a 1-d array"),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()
