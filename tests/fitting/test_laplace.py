"""The Laplace approximation's start: the inits taken to the unconstrained scale in NumPy
give numpyro's own inverse transforms (the truth), and map back to the inits; its program
compiles on a jaxlib without one of its XLA options (against a conjugate posterior)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to

from are_stats.fitting import _laplace
from are_stats.fitting._laplace import _unconstrain

CASES = [
    (constraints.real, np.array(0.7)),
    (constraints.independent(constraints.real, 1), np.array([-1.5, 0.0, 2.0])),
    (constraints.positive, np.array(5.0)),
    (constraints.positive, np.array([1e-3, 2.0, 40.0])),
    (constraints.unit_interval, np.array(0.3)),
    (constraints.unit_interval, np.array([0.01, 0.5, 0.99])),
    (constraints.simplex, np.full(4, 0.25)),
    (constraints.simplex, np.array([0.1, 0.6, 0.05, 0.25])),
    (constraints.interval(2.0, 5.0), np.array(3.0)),  # not in NumPy: numpyro's inverse
]


@pytest.mark.parametrize(("support", "value"), CASES)
def test_unconstrain_is_numpyros_inverse(support, value):
    t = biject_to(support)
    got = _unconstrain(t, value)
    want = np.asarray(t.inv(jnp.asarray(value, jnp.float64)))
    assert got.dtype == np.float64 and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(t(jnp.asarray(got))), value, rtol=1e-12, atol=1e-14)


def _normal_mean_model(y):
    mu = numpyro.sample("mu", dist.Normal(0.0, 10.0))
    numpyro.sample("y", dist.Normal(mu, 1.0), obs=y)


def _normal_mean_pointwise(sample, y):
    return dist.Normal(sample["mu"], 1.0).log_prob(y)


def test_laplace_compiles_without_an_xla_option_this_jaxlib_lacks(monkeypatch):
    """An XLA option of the programs' set that this jaxlib does not know (a later one may
    drop ``xla_cpu_use_fusion_emitters``) is left out, not an error; the approximation of
    a Gaussian posterior is then that posterior: normal mean, prior N(0, 10^2), unit
    noise, ``n`` observations: mean ``sum(y) / (n + 0.01)``, sd ``1 / sqrt(n + 0.01)``."""
    bogus = "xla_no_such_option_for_this_test"
    monkeypatch.setattr(_laplace, "_CHEAP_OPTIONS", {**_laplace._CHEAP_OPTIONS, bogus: True})
    monkeypatch.setattr(_laplace, "_UNKNOWN_OPTIONS", set())
    y = np.array([0.5, 1.5, 2.5, -0.3, 1.1])
    run = _laplace.run_laplace(
        jax.random.key(0), _normal_mean_model, {"y": y}, None, num_draws=4000,
        pointwise=_normal_mean_pointwise,
    )  # fmt: skip
    assert _laplace._UNKNOWN_OPTIONS == {bogus}
    assert run.converged
    mean, sd = y.sum() / (y.size + 0.01), 1.0 / np.sqrt(y.size + 0.01)
    np.testing.assert_allclose(run.mode["mu"], mean, atol=1e-4)
    draws = run.samples["mu"]
    assert abs(draws.mean() - mean) < 4.0 * sd / np.sqrt(draws.size)
    np.testing.assert_allclose(draws.std(), sd, rtol=0.06)
    want = -0.5 * np.log(2 * np.pi) - 0.5 * (y[None, :] - draws[:, None]) ** 2
    np.testing.assert_allclose(run.loglik, want, rtol=1e-12, atol=1e-12)
