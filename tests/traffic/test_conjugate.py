"""Conjugate closed forms against brute numerical integration of the unnormalised posterior.

The unnormalised posteriors are written independently with scipy densities (Gamma prior,
Poisson count, exponential density / survival for observed / censored stays, Poisson marks)
and integrated with ``scipy.integrate.quad``. Deterministic: no false failures.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy import integrate, stats

from are_stats.traffic import (
    GammaPosterior,
    LifecycleData,
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    simulate_lifecycle,
)
from tests.helpers import assert_allclose

PRIORS = LifecyclePriors(arrival_shape=1.7, arrival_rate=0.6, leave_shape=2.2, leave_rate=3.0)


@pytest.fixture(scope="module")
def data() -> LifecycleData:
    d = simulate_lifecycle(
        jax.random.key(11), 0.05, 0.3, [0.4, 0.6], [2.0, 9.0], window=(5.0, 45.0), area=60.0
    )
    assert d.truncated.sum() > 3 and d.censored.sum() > 3 and (~d.censored).sum() > 10
    return d


def _moments_by_quad(log_post, lo, hi):
    """Mean and sd of the density proportional to exp(log_post) on [lo, hi]."""
    peak = max(log_post(x) for x in np.linspace(lo, hi, 2001))

    def f(x, p):
        return x**p * np.exp(log_post(x) - peak)

    z = integrate.quad(f, lo, hi, args=(0,), epsabs=0, epsrel=1e-11, limit=200)[0]
    m1 = integrate.quad(f, lo, hi, args=(1,), epsabs=0, epsrel=1e-11, limit=200)[0] / z
    m2 = integrate.quad(f, lo, hi, args=(2,), epsabs=0, epsrel=1e-11, limit=200)[0] / z
    return m1, np.sqrt(m2 - m1**2), z, peak


def _check(post: GammaPosterior, log_post, lo, hi):
    mean, sd, z, peak = _moments_by_quad(log_post, lo, hi)
    assert_allclose(post.mean, mean, rtol=1e-7)
    assert_allclose(post.sd, sd, rtol=1e-6)
    # the density itself, at a few points
    for x in np.linspace(lo + (hi - lo) * 0.2, hi - (hi - lo) * 0.2, 5):
        assert_allclose(post.frozen().pdf(x), np.exp(log_post(x) - peak) / z, rtol=1e-6)


def test_arrival_rate_posterior_matches_quadrature(data):
    n = int((~data.truncated).sum())
    exposure = data.area * data.duration

    def log_post(lam):
        prior = stats.gamma.logpdf(lam, PRIORS.arrival_shape, scale=1 / PRIORS.arrival_rate)
        return prior + stats.poisson.logpmf(n, lam * exposure)

    post = conjugate_arrival_rate(data, PRIORS)
    assert post == GammaPosterior(PRIORS.arrival_shape + n, PRIORS.arrival_rate + exposure)
    _check(post, log_post, 1e-9, 20.0 * (n + 2) / exposure)


def test_leave_rate_posterior_matches_quadrature(data):
    t0, t1 = data.window
    start = np.where(data.truncated, t0, data.t_arrive)
    observed = ~data.censored

    def log_post(mu):
        prior = stats.gamma.logpdf(mu, PRIORS.leave_shape, scale=1 / PRIORS.leave_rate)
        ex = stats.expon(scale=1 / mu)
        lik = ex.logpdf(data.t_leave[observed] - start[observed]).sum()
        lik += ex.logsf(t1 - start[~observed]).sum()  # right-censored at t1
        return prior + lik

    post = conjugate_leave_rate(data, PRIORS)
    _check(post, log_post, 1e-9, 5.0 * post.mean)


def test_mixture_posterior_matches_quadrature(data):
    post = conjugate_mixture(data, PRIORS)
    assert post.concentration.shape == (2,)
    assert_allclose(post.concentration, PRIORS.weights_concentration + np.bincount(data.labels))
    for c in (0, 1):
        x = data.marks[data.labels == c]

        def log_post(r, x=x):
            prior = stats.gamma.logpdf(r, PRIORS.mix_rate_shape, scale=1 / PRIORS.mix_rate_rate)
            return prior + stats.poisson.logpmf(x, r).sum()

        g = GammaPosterior(post.shape[c], post.rate[c])
        _check(g, log_post, 1e-9, 4.0 * g.mean)
    wider = conjugate_mixture(data, PRIORS, n_components=4)
    assert_allclose(wider.rate[2:], PRIORS.mix_rate_rate)


def test_bad_inputs_name_the_argument(data):
    with pytest.raises(ValueError, match="data: expected a LifecycleData"):
        conjugate_arrival_rate({"t_arrive": []})
    with pytest.raises(ValueError, match="priors: expected a LifecyclePriors"):
        conjugate_leave_rate(data, priors=(1.0, 1.0))
    unlabelled = LifecycleData(data.t_arrive, data.t_leave, data.window, data.area)
    with pytest.raises(ValueError, match="data.labels: expected class labels"):
        conjugate_mixture(unlabelled)
    with pytest.raises(ValueError, match="n_components: expected at least"):
        conjugate_mixture(data, n_components=1)
