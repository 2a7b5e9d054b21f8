"""The Laplace approximation's start: the inits taken to the unconstrained scale in NumPy
give numpyro's own inverse transforms (the truth), and map back to the inits."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to

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
