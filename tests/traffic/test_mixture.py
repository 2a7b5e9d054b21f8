"""PoissonMixture (eq. 1) against scipy: log-pmf, sampling, moments, constraints."""

from __future__ import annotations

import logging

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats
from scipy.special import logsumexp

from are_stats import PoissonMixture
from tests.helpers import assert_allclose, chisquare_gof

FIG2_RATES = np.array([15.0, 7.0, 3.0, 21.0, 5.0])


def scipy_logpmf(k, weights, rates):
    k = np.asarray(k, dtype=np.float64)[..., None]
    with np.errstate(divide="ignore"):
        return logsumexp(np.log(weights) + stats.poisson.logpmf(k, rates), axis=-1)


#: The mixture's log-pmf as one compiled program per shapes (op by op, every primitive of
#: it was compiled on its own for each shape the tests below use)
_log_prob = jax.jit(lambda w, r, k: PoissonMixture(w, r).log_prob(k))


def test_log_prob_matches_scipy_random_parameters(rng):
    log_prob = _log_prob
    for n in (1, 2, 5):
        for _ in range(6):
            weights = rng.dirichlet(np.ones(n))
            rates = 10.0 ** rng.uniform(-3, 4, n)  # up to 1e4
            near = np.round(rates[rng.integers(0, n, 8)] * rng.uniform(0.8, 1.2, 8))
            marks = np.concatenate(
                [[0, 1, 2, 10**6], rng.integers(0, 100, 20), rng.integers(0, 10**6, 20), near]
            ).astype(np.int64)
            got = np.asarray(log_prob(weights, rates, marks))
            assert_allclose(got, scipy_logpmf(marks, weights, rates), rtol=1e-10)


@pytest.mark.parametrize(
    ("weights", "rates", "marks"),
    [
        ([1.0], [1e4], [0, 1, 9_999, 10_000, 10_001, 10**6]),
        ([0.5, 0.5], [1e-3, 1e4], [0, 1, 5, 10_000, 10**6]),
        ([1e-12, 1 - 1e-12], [1e4, 1.0], [0, 50, 10_000, 10**6]),
        ([0.2] * 5, FIG2_RATES, [0, 3, 100, 1000, 10**6]),
    ],
)
def test_log_prob_extreme_cases(weights, rates, marks):
    w, r = np.asarray(weights), np.asarray(rates)
    got = np.asarray(_log_prob(w, r, np.asarray(marks)))
    assert np.all(np.isfinite(got))
    assert_allclose(got, scipy_logpmf(marks, w, r), rtol=1e-10)


def test_zero_weight_component_contributes_nothing():
    marks = np.arange(60)
    with_zero = PoissonMixture(np.array([0.4, 0.0, 0.6]), np.array([3.0, 1e4, 30.0]))
    without = PoissonMixture(np.array([0.4, 0.6]), np.array([3.0, 30.0]))
    got = np.asarray(_log_prob(with_zero.weights, with_zero.rates, marks))
    assert not np.isnan(got).any()
    assert_allclose(got, np.asarray(_log_prob(without.weights, without.rates, marks)), rtol=1e-13)
    resp = np.asarray(with_zero.responsibilities(marks))
    assert not np.isnan(resp).any() and np.all(resp[:, 1] == 0)


def test_pmf_sums_to_one_and_moments_match_scipy():
    w = np.array([0.1, 0.3, 0.6])
    r = np.array([0.5, 12.0, 140.0])
    mix = PoissonMixture(w, r)
    k = np.arange(2000)
    pmf = np.exp(np.asarray(mix.log_prob(k)))
    assert_allclose(pmf.sum(), 1.0, rtol=1e-12)
    mean = float(np.sum(k * pmf))
    var = float(np.sum(k**2 * pmf) - mean**2)
    assert_allclose(mix.mean, mean, rtol=1e-10)
    assert_allclose(mix.variance, var, rtol=1e-10)


def test_responsibilities_are_bayes_rule():
    w, r = np.full(5, 0.2), FIG2_RATES
    k = np.arange(40)
    joint = w * stats.poisson.pmf(k[:, None], r)
    got = np.asarray(PoissonMixture(w, r).responsibilities(k))
    assert_allclose(got, joint / joint.sum(axis=1, keepdims=True), rtol=1e-10)
    assert_allclose(
        PoissonMixture(w, r).component_log_probs(k), np.log(joint), rtol=1e-11, atol=1e-12
    )


def test_sampling_matches_pmf_chisquare():
    """Chi-square goodness of fit, false-failure rate ALPHA = 1e-3 (fixed seed)."""
    w, r = np.full(5, 0.2), FIG2_RATES
    marks = np.asarray(PoissonMixture(w, r).sample(jax.random.key(3), (50_000,)))
    assert marks.dtype.kind == "i" and marks.min() >= 0
    chisquare_gof(marks, lambda k: np.exp(scipy_logpmf(k, w, r)))


def test_sampling_extreme_rates_chisquare():
    """Rates 0.01 and 5000 with unequal weights; false-failure rate ALPHA = 1e-3."""
    w, r = np.array([0.7, 0.3]), np.array([0.01, 5000.0])
    marks = np.asarray(PoissonMixture(w, r).sample(jax.random.key(4), (50_000,)))
    chisquare_gof(marks, lambda k: np.exp(scipy_logpmf(k, w, r)))


def test_sample_with_class_and_batch_shapes():
    weights = jnp.array([[0.5, 0.5], [1.0, 0.0], [0.0, 1.0]])
    rates = jnp.array([1.0, 1000.0])
    mix = PoissonMixture(weights, rates)
    assert mix.batch_shape == (3,) and mix.event_shape == ()
    marks, classes = mix.sample_with_class(jax.random.key(0), (400,))
    assert marks.shape == (400, 3) and classes.shape == (400, 3)
    assert np.all(np.asarray(classes[:, 1]) == 0) and np.all(np.asarray(classes[:, 2]) == 1)
    assert np.asarray(marks[:, 2]).min() > 800  # every draw from the rate-1000 component
    assert mix.log_prob(jnp.arange(3)).shape == (3,)
    assert mix.log_prob(jnp.zeros((7, 3), dtype=int)).shape == (7, 3)


def test_a_draw_at_a_new_size_compiles_one_program(caplog):
    """Sampling is one compiled program per sample shape (issue 29: op by op, a draw of a
    new size compiled nine programs, the categorical's Gumbel and the Poisson sampler
    among them). The shape is one no other test draws, so the process has not compiled
    it yet."""
    mix = PoissonMixture(np.full(5, 0.2), FIG2_RATES)
    key = jax.random.key(5)
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        marks, classes = mix.sample_with_class(key, (13, 7))
    compiled = [r.getMessage() for r in caplog.records if r.getMessage().startswith("Compiling")]
    assert [m.split()[1] for m in compiled] == ["jit(_sample_with_class)"]
    assert marks.shape == classes.shape == (13, 7)
    np.testing.assert_array_equal(np.asarray(mix.sample(key, (13, 7))), np.asarray(marks))


def test_negative_marks_have_zero_probability():
    mix = PoissonMixture(np.array([0.5, 0.5]), np.array([1.0, 2.0]), validate_args=False)
    assert float(mix.log_prob(-1)) == -np.inf


def test_traced_parameters_and_gradients():
    w, r = jnp.full(5, 0.2), jnp.asarray(FIG2_RATES)
    f = jax.jit(lambda w, r: jnp.sum(PoissonMixture(w, r).log_prob(jnp.arange(30))))
    assert_allclose(f(w, r), scipy_logpmf(np.arange(30), np.asarray(w), FIG2_RATES).sum())
    g = jax.grad(lambda r: jnp.sum(PoissonMixture(w, r).log_prob(jnp.arange(30))))(r)
    assert np.all(np.isfinite(np.asarray(g)))


@pytest.mark.parametrize(
    ("weights", "rates", "match"),
    [
        ([0.5, 0.6], [1.0, 2.0], "weights: expected weights summing to 1"),
        ([0.5, 0.4], [1.0, 2.0], "weights: expected weights summing to 1"),
        ([1.5, -0.5], [1.0, 2.0], "weights: expected non-negative"),
        ([0.5, np.nan], [1.0, 2.0], "weights: expected finite"),
        ([0.5, 0.5], [1.0, -2.0], "rates: expected finite numbers > 0"),
        ([0.5, 0.5], [0.0, 2.0], "rates: expected finite numbers > 0"),
        ([0.5, 0.5], [1.0, np.inf], "rates: expected finite numbers"),
        ([0.5, 0.5], [1.0, 2.0, 3.0], "rates: expected as many rates as weights"),
        ([], [], "weights: expected at least one component"),
        (1.0, [1.0], "weights: expected a vector"),
        ([1.0], 1.0, "rates: expected a vector"),
        (["a"], [1.0], "weights: expected numbers"),
    ],
)
def test_bad_parameters_raise(weights, rates, match):
    with pytest.raises(ValueError, match=match):
        PoissonMixture(weights, rates)


def test_bad_parameters_raise_without_numpyro_validation():
    with pytest.raises(ValueError, match="weights"):
        PoissonMixture([0.2, 0.2], [1.0, 2.0], validate_args=False)
