"""Arrival laws: exact samplers against their laws, likelihoods against scipy, N(t) truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from are_stats.traffic._arrivals import (
    DAY,
    arrival_loglik,
    clock_offset,
    period_exposure,
    period_of,
    sample_arrivals,
    stationary_count_moments,
)
from are_stats.traffic._stays import stay_sample

# Each seeded goodness-of-fit check below uses alpha = 1e-4; with 8 such checks the
# suite's false-failure rate is below 1e-3.
ALPHA = 1e-4


def test_clock_offset_and_periods():
    assert clock_offset("2024-05-02T07:30:00") == 7.5 * 3600
    assert clock_offset("2024-05-02T07:30:00+02:00") == 7.5 * 3600  # local time of day
    assert clock_offset("2024-05-02T00:01:00", time_unit=60.0) == 1.0
    with pytest.raises(ValueError, match="ISO 8601"):
        clock_offset("half past seven")
    # t = 0 at 23:00, 24 periods: t = 3600 s is period 0 (midnight to 1 am)
    assert period_of([0.0, 3599.0, 3600.0, 7200.0], 23 * 3600.0, 24).tolist() == [23, 23, 0, 1]


@pytest.mark.parametrize(
    "window, offset, n",
    [((0.0, DAY), 0.0, 24), ((100.0, 3 * DAY + 17.0), 5000.0, 7), ((10.0, 20.0), 86390.0, 4)],
)
def test_period_exposure_is_exact(window, offset, n):
    expo = period_exposure(window, offset, n)
    assert expo.sum() == pytest.approx(window[1] - window[0], rel=1e-12)
    # brute force on a fine grid
    t = np.linspace(*window, 2_000_001)[:-1] + (window[1] - window[0]) / 4_000_000
    ref = np.bincount(period_of(t, offset, n), minlength=n) * (window[1] - window[0]) / t.size
    np.testing.assert_allclose(expo, ref, atol=(window[1] - window[0]) * 2e-6)


def test_poisson_counts_and_uniform_times():
    rng = np.random.default_rng(1)
    counts = [sample_arrivals(rng, 0.01, 50.0, (0, 100)).t.size for _ in range(2000)]
    # chi-square of the count histogram against Poisson(50)
    k = np.arange(30, 71)
    obs = np.array([np.sum(np.asarray(counts) == v) for v in k])
    exp = stats.poisson(50).pmf(k) * len(counts)
    keep = exp > 5
    chi = np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep])
    assert stats.chi2(keep.sum() - 1).sf(chi) > ALPHA
    t = sample_arrivals(rng, 0.5, 50.0, (10, 110)).t
    assert np.all(np.diff(t) >= 0)
    assert stats.kstest(t, stats.uniform(10, 100).cdf).pvalue > ALPHA


def test_time_of_day_counts_follow_the_multipliers():
    rng = np.random.default_rng(2)
    tod = np.array([0.2, 0.5, 1.8, 1.5])  # mean 1
    offset = 6 * 3600.0  # t = 0 at 06:00: starts in period 1
    draw = sample_arrivals(
        rng, 1e-3, 100.0, (0, 4 * DAY), model="time-of-day", tod=tod, offset=offset
    )
    per = np.bincount(period_of(draw.t, offset, 4), minlength=4)
    exp = 1e-3 * 100.0 * tod * period_exposure((0, 4 * DAY), offset, 4)
    chi = np.sum((per - exp) ** 2 / exp)
    assert stats.chi2(4).sf(chi) > ALPHA


def test_negbin_bins_are_overdispersed_as_stated():
    rng = np.random.default_rng(3)
    phi, width, rate, area = 2.0, 10.0, 0.05, 20.0
    draw = sample_arrivals(rng, rate, area, (0, 20000), model="negbin", phi=phi, bin_width=width)
    c = np.bincount((draw.t // width).astype(int), minlength=2000)
    mu = rate * area * width
    ref = stats.nbinom(phi, phi / (phi + mu))
    k = np.arange(0, 40)
    obs = np.array([np.sum(c == v) for v in k])
    exp = ref.pmf(k) * c.size
    keep = exp > 5
    chi = np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep])
    assert stats.chi2(keep.sum() - 1).sf(chi) > ALPHA


def test_groups_share_times_and_follow_the_size_law():
    rng = np.random.default_rng(4)
    probs = np.array([0.5, 0.3, 0.15, 0.05])
    draw = sample_arrivals(rng, 0.02, 100.0, (0, 2000), model="groups", size_probs=probs)
    n_groups = draw.group.max() + 1
    sizes = np.bincount(draw.group)
    assert np.all(sizes == draw.size[np.searchsorted(draw.group, np.arange(n_groups))])
    for g in range(min(n_groups, 50)):
        assert np.ptp(draw.t[draw.group == g]) == 0
    obs = np.bincount(sizes, minlength=5)[1:]
    exp = probs * n_groups
    assert stats.chi2(3).sf(np.sum((obs - exp) ** 2 / exp)) > ALPHA


def test_poisson_loglik_matches_scipy():
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0, 100, 37))
    rate, area = 0.02, 30.0
    ll = float(arrival_loglik(t, np.ones(37, int), (0, 100), area, rate))
    # Poisson count times uniform order statistics: log P(n) + log n! - n log T
    ref = (
        stats.poisson(rate * area * 100).logpmf(37)
        + np.sum(np.log(np.arange(1, 38)))
        - 37 * np.log(100)
    )
    assert ll == pytest.approx(ref, rel=1e-12)


def test_negbin_and_group_loglik_match_scipy():
    counts = np.array([0, 3, 1, 7])
    width, area, rate, phi = 5.0, 10.0, 0.04, 1.5
    expo = np.full(4, area * width)
    t = np.concatenate([b * width + np.linspace(0.5, 4.5, c) for b, c in enumerate(counts)])
    probs = np.array([0.6, 0.3, 0.1])
    sizes = np.array([1, 2, 1, 3, 1, 1, 2, 1, 1, 1, 2])
    ll = float(
        arrival_loglik(
            t,
            sizes,
            (0, 20),
            area,
            rate,
            bin_counts=counts,
            bin_exposure=expo,
            phi=phi,
            size_probs=probs,
        )
    )
    mu = rate * area * width
    ref = stats.nbinom(phi, phi / (phi + mu)).logpmf(counts).sum()
    ref += -np.sum(counts * np.log(width))  # uniform times within bins
    ref += np.log(probs[sizes - 1]).sum()
    assert ll == pytest.approx(ref, rel=1e-12)


def test_time_of_day_loglik_is_the_inhomogeneous_poisson_one():
    tod = np.array([0.5, 1.5])
    offset, window, rate, area = 0.0, (0.0, 1.5 * DAY), 1e-4, 10.0
    t = np.array([100.0, 50000.0, 90000.0])
    ll = float(arrival_loglik(t, np.ones(3, int), window, area, rate, tod=tod, offset=offset))
    lam = rate * area * tod[period_of(t, offset, 2)]
    integral = rate * area * (0.5 * DAY / 2 + 1.5 * DAY / 2 + 0.5 * DAY / 2)
    assert ll == pytest.approx(np.log(lam).sum() - integral, rel=1e-12)


@pytest.mark.parametrize("probs", [None, np.array([0.4, 0.3, 0.2, 0.1])])
def test_stationary_count_of_groups_with_shared_stays(probs):
    """Simulated N(t) of groups staying together (gamma stays) against the closed form."""
    rng = np.random.default_rng(6)
    import jax

    rate, area, m, t_obs = 0.004, 50.0, 30.0, 500.0
    # gamma(shape 3) stays of mean m, drawn once (one compiled sampler call)
    stays_pool = np.asarray(stay_sample(jax.random.key(6), "gamma", m, 3.0, (600, 200)))
    draws = []
    for rep in range(600):
        a = sample_arrivals(
            rng,
            rate,
            area,
            (0, t_obs),
            model="groups" if probs is not None else "poisson",
            size_probs=probs,
        )
        n_groups = int(a.group.max()) + 1 if a.t.size else 0
        stays = stays_pool[rep, : max(n_groups, 1)]
        leave = a.t + stays[a.group] if a.t.size else a.t
        draws.append(int(np.sum(leave > t_obs)))
    mean, var = stationary_count_moments(rate, area, m, probs)
    x = np.asarray(draws, float)
    # mean within 4 standard errors; variance/mean within 25 % (600 replicates)
    assert abs(x.mean() - mean) < 4 * np.sqrt(var / x.size)
    assert x.var(ddof=1) / x.mean() == pytest.approx(var / mean, rel=0.25)
