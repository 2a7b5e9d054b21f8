"""EM for the Poisson mixture of eq. (1) against an independent optimiser and the truth."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy import optimize, stats
from scipy.special import gammaln, logsumexp, softmax, xlogy

from are_stats import MixtureEMResult, PoissonMixture, fit_mixture_em
from are_stats.fitting import em_init, em_step, marks_histogram, squarem_step
from tests.helpers import assert_allclose

FIG2_RATES = np.array([15.0, 7.0, 3.0, 21.0, 5.0])


def fig2_marks(n, seed):
    rng = np.random.default_rng(seed)
    return rng.poisson(FIG2_RATES[rng.integers(0, 5, n)])


def scipy_loglik(values, counts, weights, rates):
    """Mixture log-likelihood from scipy's Poisson log-pmf (independent of the package)."""
    with np.errstate(divide="ignore"):
        lp = logsumexp(np.log(weights) + stats.poisson.logpmf(values[:, None], rates), axis=1)
    return float(np.sum(counts * lp))


def reference_optimum(marks, n_components, n_starts, seed):
    """Best of many L-BFGS runs (analytic gradient) on the log-likelihood.

    Parametrised by (logits, log rates); written with scipy.special only, independent of
    the package's EM.
    """
    values, counts = np.unique(marks, return_counts=True)
    v = values.astype(np.float64)
    log_fact = gammaln(v + 1.0)
    n = n_components
    rng = np.random.default_rng(seed)

    def neg_and_grad(theta):
        w, lam = softmax(theta[:n]), np.exp(theta[n:])
        joint = np.log(w) + xlogy(v[:, None], lam) - lam - log_fact[:, None]
        lse = logsumexp(joint, axis=1)
        resp = np.exp(joint - lse[:, None])
        g_logit = counts @ resp - counts.sum() * w
        g_lograte = (counts[:, None] * resp * (v[:, None] - lam)).sum(axis=0)
        return -float(counts @ lse), -np.concatenate([g_logit, g_lograte])

    best = -np.inf
    q = np.quantile(marks, (np.arange(n) + 0.5) / n)
    for i in range(n_starts):
        rates0 = np.maximum(q, 0.5) if i == 0 else rng.uniform(v.min() + 0.5, v.max(), n)
        theta0 = np.concatenate([rng.normal(0, 0.3, n), np.log(np.sort(rates0))])
        res = optimize.minimize(
            neg_and_grad,
            theta0,
            jac=True,
            method="L-BFGS-B",
            options={"ftol": 1e-15, "gtol": 1e-9, "maxiter": 20_000},
        )
        best = max(best, -res.fun)
    return best


@pytest.fixture(scope="module")
def fig2():
    marks = fig2_marks(1_000_000, seed=7)
    return marks, fit_mixture_em(marks, 5, jax.random.key(0))


def test_fig2_reaches_global_optimum(fig2):
    marks, fit = fig2
    # five starts: the first five of the thirty this test ran until 2026-11-29, when all
    # thirty ended within 1e-14 relative of their best (the quantile start among them), so
    # the reference is the same value at a sixth of the cost (about 10 s of CPU less)
    ref = reference_optimum(marks, 5, n_starts=5, seed=1)
    # the likelihood is very flat along a ridge: EM stops (tol 1e-8 per mark) within
    # 1e-6 relative of the best of five independent quasi-Newton runs
    assert fit.loglik >= ref - 1e-6 * abs(ref), (fit.loglik, ref)
    assert fit.converged


def test_fig2_loglik_is_total_over_all_marks(fig2):
    marks, fit = fig2
    direct = float(np.sum(PoissonMixture(fit.weights, fit.rates).log_prob(marks)))
    values, counts = np.unique(marks, return_counts=True)
    assert_allclose(fit.loglik, scipy_loglik(values, counts, fit.weights, fit.rates), rtol=1e-12)
    assert_allclose(fit.loglik, direct, rtol=1e-10)


def test_result_fields(fig2):
    marks, fit = fig2
    assert isinstance(fit, MixtureEMResult)
    assert np.all(np.diff(fit.rates) > 0)
    assert_allclose(fit.weights.sum(), 1.0, rtol=1e-12)
    assert fit.restarts_logliks.shape == (16,)
    assert fit.loglik == pytest.approx(fit.restarts_logliks.max(), rel=1e-15)
    assert fit.n_marks == marks.size and fit.n_distinct == np.unique(marks).size
    assert_allclose(fit.bic, -2 * fit.loglik + 9 * np.log(marks.size), rtol=1e-14)
    assert fit.n_iter > 0
    with pytest.raises(AttributeError):
        fit.loglik = 0.0  # frozen
    assert isinstance(fit.distribution(), PoissonMixture)


def test_well_separated_recovers_truth():
    """Rates (2, 20, 80), weights (.3, .3, .4), n = 20000: within 4 standard errors.

    Standard errors from the complete-data Fisher information (the components barely
    overlap); false-failure rate below 1e-3 over the 6 comparisons.
    """
    rng = np.random.default_rng(11)
    w, r, n = np.array([0.3, 0.3, 0.4]), np.array([2.0, 20.0, 80.0]), 20_000
    marks = rng.poisson(r[rng.choice(3, n, p=w)])
    fit = fit_mixture_em(marks, 3, jax.random.key(1))
    se_rate = np.sqrt(r / (n * w))
    se_w = np.sqrt(w * (1 - w) / n)
    assert np.all(np.abs(fit.rates - r) < 4 * se_rate), (fit.rates, r)
    assert np.all(np.abs(fit.weights - w) < 4 * se_w), (fit.weights, w)


def test_one_component_is_the_sample_mean():
    marks = np.random.default_rng(2).poisson(6.5, 5000)
    fit = fit_mixture_em(marks, 1)
    assert_allclose(fit.rates, [marks.mean()], rtol=1e-12)
    assert_allclose(fit.loglik, stats.poisson.logpmf(marks, marks.mean()).sum(), rtol=1e-12)


def test_counts_and_histogram_give_the_same_fit():
    marks = fig2_marks(20_000, seed=3)
    values, counts = np.unique(marks, return_counts=True)
    a = fit_mixture_em(marks, 3, jax.random.key(5))
    b = fit_mixture_em(values, 3, jax.random.key(5), counts=counts)
    assert_allclose(b.loglik, a.loglik, rtol=1e-13)
    assert_allclose(b.rates, a.rates, rtol=1e-10)
    h = marks_histogram(marks)
    assert_allclose(h.values, values) and assert_allclose(h.counts, counts)


@pytest.mark.parametrize("step", ["em", "squarem"])
def test_em_is_monotone(step):
    hist = marks_histogram(fig2_marks(50_000, seed=4))
    state = em_init(hist, np.full(5, 0.2), np.array([1.0, 2.0, 3.0, 40.0, 50.0]))
    lls = [float(state.mean_loglik)]
    em, squarem = jax.jit(em_step), jax.jit(squarem_step)
    for _ in range(150):
        if step == "em":
            state, info = em(state, hist)
        else:
            state, info, _ = squarem(state, hist)
        lls.append(float(info.mean_loglik))
    d = np.diff(lls)
    assert np.all(d >= -1e-12 * abs(lls[0])), d.min()
    assert lls[-1] > lls[0]
    ref = scipy_loglik(hist.values, hist.counts, np.asarray(state.weights), np.asarray(state.rates))
    assert_allclose(lls[-1] * hist.n_marks, ref, rtol=1e-12)


@pytest.mark.parametrize(
    ("marks", "kwargs", "match"),
    [
        ([], {}, "marks: expected at least one mark"),
        ([1, -2, 3], {}, "marks: expected non-negative integers"),
        ([1.0, 2.5], {}, "marks: expected non-negative integers"),
        ([1.0, np.nan], {}, "marks: expected finite"),
        (["a", "b"], {}, "marks: expected numbers"),
        ([1, 2, 3], {"n_components": 0}, "n_components: expected an integer >= 1"),
        ([1, 2, 2], {"n_components": 3}, "n_components: expected at most the number of distinct"),
        ([1, 2, 3], {"counts": [1, -1, 2]}, "counts: expected finite numbers >= 0"),
        ([1, 2, 3], {"counts": [1, 2]}, "counts: expected 3 counts"),
        ([1, 2, 3], {"counts": [0, 0, 0]}, "counts: expected a positive total"),
        ([1, 2, 3], {"tol": 0.0}, "tol: expected a finite number > 0"),
        ([1, 2, 3], {"n_restarts": 0}, "n_restarts: expected an integer >= 1"),
        ([1, 2, 3], {"max_iter": 1.5}, "max_iter: expected an integer >= 1"),
    ],
)
def test_bad_input_raises(marks, kwargs, match):
    kwargs = {"n_components": 1, **kwargs}
    with pytest.raises(ValueError, match=match):
        fit_mixture_em(marks, **kwargs)
