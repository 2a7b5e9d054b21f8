"""The arrival models' tick likelihoods against brute-force probabilities of the same data.

Every model scores the counts of artefacts per tick of the log's resolution; the truth here
is a direct computation over every tick of the window (empty ones included) with scipy.
"""

from __future__ import annotations

import functools

import jax
import numpy as np
import pytest
from scipy import stats
from scipy.special import gammaln

from are_stats.traffic import (
    ArrivalSpec,
    arrival_unit_loglik,
    arrival_units,
    exponential_unit_loglik,
    poisson_unit_loglik,
    stay_loglik,
    stay_unit_loglik,
    stay_units,
)

AREA = 50.0
WINDOW = (0.0, 100.0)
DELTA = 0.5
WIDTH = 10.0


def _ticks(t: np.ndarray) -> np.ndarray:
    """Counts per tick over the whole window (the data every model scores)."""
    n = int(round((WINDOW[1] - WINDOW[0]) / DELTA))
    idx = np.floor((t - WINDOW[0]) / DELTA + 1e-9).astype(int)
    return np.bincount(idx, minlength=n)


@pytest.fixture(scope="module")
def times() -> np.ndarray:
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(*WINDOW, 40))
    # a few artefacts arriving in the same tick (a group)
    t = np.floor(np.concatenate([t, t[:6], t[:2]]) / DELTA) * DELTA + 0.1
    assert t.max() < WINDOW[1]
    return t


def _total(params, units, spec) -> float:
    p = {**params, "log_area": np.log(AREA)}
    return float(_total_program(p, units, spec))


@functools.partial(jax.jit, static_argnames="spec")
def _total_program(p, units, spec):
    """The summed unit log-likelihood as one compiled program per spec and shapes (op by
    op, every primitive of the likelihood was compiled on its own)."""
    return jax.numpy.sum(arrival_unit_loglik(p, units, spec))


#: The unit log-likelihood as one compiled program per spec and shapes
_unit_program = jax.jit(arrival_unit_loglik, static_argnames="spec")


def test_poisson_is_the_product_of_tick_poissons(times):
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    rate = 0.004
    c = _ticks(times)
    truth = stats.poisson.logpmf(c, rate * AREA * DELTA).sum()
    got = _total({"event_rate": rate}, units, ArrivalSpec())
    assert got == pytest.approx(truth, rel=1e-10)


def test_negbin_is_nb_totals_times_multinomial(times):
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    rate, phi = 0.004, 2.5
    c = _ticks(times).reshape(-1, int(WIDTH / DELTA))  # ticks of each bin
    mu = rate * AREA * WIDTH
    n = c.sum(axis=1)
    nb = stats.nbinom.logpmf(n, phi, phi / (phi + mu))
    k = c.shape[1]
    multi = gammaln(n + 1) - gammaln(c + 1).sum(axis=1) - n * np.log(k)
    got = _total({"event_rate": rate, "arrival_phi": phi}, units, ArrivalSpec(negbin=True))
    assert got == pytest.approx(float((nb + multi).sum()), rel=1e-10)


def _compound_logpmf(c: int, lam: float, probs: np.ndarray) -> float:
    """log P(C = c) of a compound Poisson(lam) sum of sizes ~ probs on 1..K, by brute force."""
    p = np.concatenate([[0.0], probs])
    conv = np.zeros(c + 1)
    conv[0] = 1.0
    total = stats.poisson.pmf(0, lam) * (c == 0)
    for k in range(1, c + 1):
        conv = np.convolve(conv, p)[: c + 1]
        total += stats.poisson.pmf(k, lam) * conv[c]
    return float(np.log(total))


def test_groups_is_the_compound_poisson_of_every_tick(times):
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    c = _ticks(times)
    # the size law must cover the largest count of a tick (fit_traffic takes K = that count)
    probs = np.zeros(max(3, int(c.max())))
    probs[:3] = [0.5, 0.3, 0.2]
    rate = 0.002
    lam = rate * AREA * DELTA
    truth = sum(_compound_logpmf(int(ci), lam, probs) for ci in c)
    got = _total({"event_rate": rate, "group_size_probs": probs}, units, ArrivalSpec(groups=True))
    assert got == pytest.approx(truth, rel=1e-9)


def test_groups_of_one_are_the_poisson_model(times):
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    one = np.zeros(int(_ticks(times).max()))
    one[0] = 1.0
    a = _total({"event_rate": 0.004, "group_size_probs": one}, units, ArrivalSpec(groups=True))
    b = _total({"event_rate": 0.004}, units, ArrivalSpec())
    assert a == pytest.approx(b, rel=1e-9)


def test_time_of_day_is_the_piecewise_poisson_process(times):
    # a 100 s window cut into periods of 25 s (4 periods per 100 s "day")
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH, clock_offset=0.0, n_periods=4,
                          period=100.0)  # fmt: skip
    tod = np.array([0.5, 1.5, 1.0, 1.0])
    rate = 0.004
    c = _ticks(times)
    mid = (np.arange(c.size) + 0.5) * DELTA
    lam = rate * AREA * DELTA * tod[(mid // 25).astype(int)]
    truth = stats.poisson.logpmf(c, lam).sum()
    got = _total({"event_rate": rate, "arrival_tod": tod}, units, ArrivalSpec(tod=True))
    assert got == pytest.approx(truth, rel=1e-10)


def test_recorded_groups_arrive_at_their_first_member():
    t = np.array([1.2, 3.7, 3.9, 8.1])
    g = np.array([0, 1, 1, 2])
    units = arrival_units(t, WINDOW, AREA, DELTA, WIDTH, group=g)
    counts = np.asarray(units.tick_count)[np.asarray(units.tick_weight) > 0]
    assert sorted(counts.tolist()) == [1.0, 1.0, 2.0]


def test_units_are_padded_and_differentiable(times):
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    assert units.tick_count.shape[0] & (units.tick_count.shape[0] - 1) == 0  # power of two
    spec = ArrivalSpec(negbin=True)

    def f(log_rate):
        return _total_jax(jax.numpy.exp(log_rate), units, spec)

    # the value and the gradient from one compiled program (op by op, the gradient and
    # the two values compiled every primitive on its own)
    value_and_grad = jax.jit(jax.value_and_grad(f))
    g = value_and_grad(np.log(0.004))[1]
    eps = 1e-6
    up, down = (value_and_grad(np.log(0.004) + d)[0] for d in (eps, -eps))
    assert float(g) == pytest.approx(float((up - down) / (2 * eps)), rel=1e-5)


def _total_jax(rate, units, spec):
    p = {"event_rate": rate, "arrival_phi": 3.0, "log_area": np.log(AREA)}
    return jax.numpy.sum(arrival_unit_loglik(p, units, spec))


def test_stay_units_match_stay_loglik():
    rng = np.random.default_rng(2)
    stay = rng.exponential(10.0, 37)
    cen = rng.random(37) < 0.2
    tru = rng.random(37) < 0.2
    u = stay_units(stay, cen, tru)
    # each a compiled program: op by op, the incomplete gamma's loops compiled every
    # primitive on its own (8 s of CPU cold, 2026-11-28)
    p = {"stay_mean": 9.0, "stay_shape": 2.0}
    got = np.asarray(jax.jit(lambda p: stay_unit_loglik(p, u, "gamma", 0.1))(p))

    @jax.jit
    def per_term(p):
        return stay_loglik("gamma", stay, cen, tru, p["stay_mean"], p["stay_shape"], 0.1)

    want = np.asarray(per_term(p))
    np.testing.assert_allclose(got[:37], want, rtol=1e-12)
    assert np.all(got[37:] == 0)


def test_poisson_draws_in_numpy_are_the_tick_poissons_and_the_jax_units(times):
    """The paper's arrival model scored for many draws without a compiled program: per bin
    the product of its ticks' Poissons (scipy, every tick of the window), and equal to
    :func:`arrival_unit_loglik` draw by draw."""
    units = arrival_units(times, WINDOW, AREA, DELTA, WIDTH)
    rates = np.array([0.001, 0.004, 0.02])
    got = poisson_unit_loglik(rates, units, np.log(AREA))
    n_bins = int(np.sum(units.bin_weight))
    assert got.shape == (3, units.bin_weight.shape[0])
    assert np.all(got[:, n_bins:] == 0)
    c = _ticks(times).reshape(n_bins, -1)  # WIDTH / DELTA ticks a bin
    for rate, row in zip(rates, got, strict=True):
        truth = stats.poisson.logpmf(c, rate * AREA * DELTA).sum(axis=1)
        np.testing.assert_allclose(row[:n_bins], truth, rtol=1e-10)
        p = {"event_rate": rate, "log_area": np.log(AREA)}
        jax_row = np.asarray(_unit_program(p, units, ArrivalSpec()))
        np.testing.assert_allclose(row, jax_row, rtol=1e-11, atol=1e-11)


def test_exponential_draws_in_numpy_match_the_stay_likelihood():
    """The paper's stay law scored for many draws without a compiled program: equal to
    :func:`stay_loglik` (every kind of row: seen whole, below the resolution, censored,
    truncated, both) and to scipy's exponential law on the rows seen whole."""
    rng = np.random.default_rng(3)
    stay = np.concatenate([rng.exponential(10.0, 40), [0.05, 0.02]])  # two below 0.1
    n = stay.size
    cen = rng.random(n) < 0.25
    tru = rng.random(n) < 0.25
    cen[-2:] = tru[-2:] = False
    assert (cen & tru).any() and (cen ^ tru).any()
    u = stay_units(stay, cen, tru)
    means = np.array([4.0, 9.0, 30.0])
    got = exponential_unit_loglik(means, u, 0.1)
    assert got.shape == (3, u.stay.shape[0])
    assert np.all(got[:, n:] == 0)
    whole = ~cen & ~tru & (stay >= 0.1)

    @jax.jit
    def references(m):
        """Both JAX references for one mean, one compiled program for every mean (op by
        op, each primitive was compiled on its own)."""
        return (
            stay_loglik("exponential", stay, cen, tru, m, resolution=0.1),
            stay_unit_loglik({"stay_mean": m}, u, "exponential", 0.1),
        )

    for m, row in zip(means, got, strict=True):
        want, units_row = (np.asarray(r) for r in references(m))
        np.testing.assert_allclose(row[:n], want, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(row, units_row, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(
            row[:n][whole], stats.expon.logpdf(stay[whole], scale=m), rtol=1e-12
        )
        short = stats.expon.logcdf(0.1, scale=m)
        np.testing.assert_allclose(row[n - 2 : n], short, rtol=1e-12)
