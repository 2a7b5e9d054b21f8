"""The Poisson mixture of the ARE paper, eq. (1): the law of an artefact's mark X.

    Pr(X = k | pi, lambda) = sum_i pi_i lambda_i^k exp(-lambda_i) / k!

Each arrival draws its mark from this law; the component that produced it is the
artefact's class (DECISIONS.md item 5).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import random
from jax.scipy.special import gammaln, xlogy
from numpyro.distributions import Distribution, constraints
from numpyro.distributions.util import promote_shapes, validate_sample

from are_stats._checks import check_finite, check_positive, describe

__all__ = ["PoissonMixture"]


def _is_concrete(x: npt.ArrayLike) -> bool:
    """True when ``x`` holds values (not a JAX tracer inside ``jit``/``grad``/``vmap``)."""
    return not isinstance(x, jax.core.Tracer)


def _validate_parameters(weights: npt.ArrayLike, rates: npt.ArrayLike) -> None:
    """Reject bad concrete parameters with ``ValueError("<arg>: expected ..., got ...")``."""
    w = check_finite("weights", weights)
    r = check_positive("rates", rates)
    if w.ndim == 0:
        raise ValueError(f"weights: expected a vector of mixture weights, got {describe(w)}")
    if r.ndim == 0:
        raise ValueError(f"rates: expected a vector of Poisson rates, got {describe(r)}")
    if w.shape[-1] == 0:
        raise ValueError("weights: expected at least one component, got an empty array")
    if w.shape[-1] != r.shape[-1]:
        raise ValueError(
            f"rates: expected as many rates as weights ({w.shape[-1]}), got {r.shape[-1]}"
        )
    neg = w < 0
    if neg.any():
        idx = tuple(int(i) for i in np.argwhere(neg)[0])
        raise ValueError(f"weights: expected non-negative weights, got {w[idx]!r} at index {idx}")
    sums = w.sum(axis=-1)
    bad = np.abs(sums - 1.0) > 1e-6
    if np.any(bad):
        s = float(np.asarray(sums)[np.unravel_index(int(np.argmax(bad)), np.shape(sums))])
        raise ValueError(f"weights: expected weights summing to 1 (within 1e-6), got sum {s!r}")


@partial(jax.jit, static_argnums=3)
def _sample_with_class(
    key: jax.Array, weights: jax.Array, rates: jax.Array, shape: tuple[int, ...]
) -> tuple[jax.Array, jax.Array]:
    """Classes (categorical on ``log weights``), then marks (Poisson of the class's rate),
    of shape ``shape``, as one compiled program per shape (issue 29: op by op, each of its
    nine operations was compiled on its own for every sample shape)."""
    key_class, key_mark = random.split(key)
    log_w = jnp.log(weights)
    classes = random.categorical(key_class, log_w, axis=-1, shape=shape)
    rates = jnp.broadcast_to(rates, shape + (rates.shape[-1],))
    lam = jnp.take_along_axis(rates, classes[..., None], axis=-1)[..., 0]
    marks = random.poisson(key_mark, lam, shape=shape)
    return marks, classes


class PoissonMixture(Distribution):
    """Finite mixture of Poisson laws, eq. (1) of the ARE paper.

    A ``numpyro`` distribution over the non-negative integers. The last axis of
    ``weights`` and ``rates`` indexes the components; leading axes are batch axes
    (broadcast against each other). The event shape is ``()``.

    Parameters
    ----------
    weights : (..., n) float
        Mixture weights ``pi_i``: non-negative, summing to one. Zero weights are allowed
        (the component contributes nothing).
    rates : (..., n) float
        Poisson rates ``lambda_i``: finite and > 0.
    validate_args : bool, optional
        numpyro's own argument validation. Independently of it, concrete (non-traced)
        parameters are always checked in the constructor.

    Raises
    ------
    ValueError
        If ``weights`` is not a simplex (tolerance 1e-6), ``rates`` are not finite and
        positive, or their last axes differ in length (only when the inputs are concrete;
        inside ``jit`` the parameters are not inspected).

    Examples
    --------
    >>> import jax, jax.numpy as jnp
    >>> from are_stats import PoissonMixture
    >>> mix = PoissonMixture(jnp.full(5, 0.2), jnp.array([15.0, 7.0, 3.0, 21.0, 5.0]))
    >>> float(mix.mean)
    10.2
    >>> marks = mix.sample(jax.random.key(0), (1000,))
    >>> marks.shape
    (1000,)
    """

    arg_constraints = {
        "weights": constraints.simplex,
        "rates": constraints.independent(constraints.positive, 1),
    }
    support = constraints.nonnegative_integer
    pytree_data_fields = ("weights", "rates")

    def __init__(
        self, weights: npt.ArrayLike, rates: npt.ArrayLike, *, validate_args: bool | None = None
    ) -> None:
        if _is_concrete(weights) and _is_concrete(rates):
            _validate_parameters(weights, rates)
        weights = jnp.asarray(weights)
        rates = jnp.asarray(rates)
        dtype = jnp.result_type(weights.dtype, rates.dtype, jnp.float32)
        self.weights, self.rates = promote_shapes(
            weights.astype(dtype), rates.astype(dtype), shape=()
        )
        batch_shape = jax.lax.broadcast_shapes(
            jnp.shape(self.weights)[:-1], jnp.shape(self.rates)[:-1]
        )
        n = jnp.shape(self.weights)[-1]
        self.weights = jnp.broadcast_to(self.weights, batch_shape + (n,))
        self.rates = jnp.broadcast_to(self.rates, batch_shape + (n,))
        super().__init__(batch_shape=batch_shape, event_shape=(), validate_args=validate_args)

    @property
    def n_components(self) -> int:
        """Number of mixture components ``n``."""
        return int(jnp.shape(self.weights)[-1])

    def component_log_probs(self, value: npt.ArrayLike) -> jax.Array:
        """Joint log-probabilities ``log pi_i + log Poisson(value | lambda_i)``.

        Parameters
        ----------
        value : (...) int
            Marks, broadcastable against the batch shape.

        Returns
        -------
        (..., n) float
            One column per component; ``-inf`` for components with zero weight or for
            negative marks.
        """
        k = jnp.asarray(value)[..., None].astype(self.rates.dtype)
        lp = xlogy(k, self.rates) - self.rates - gammaln(k + 1.0)
        lp = jnp.log(self.weights) + lp
        return jnp.where(k < 0, -jnp.inf, lp)

    @validate_sample
    def log_prob(self, value: npt.ArrayLike) -> jax.Array:
        """Exact log-pmf of eq. (1), computed with a log-sum-exp over components.

        Parameters
        ----------
        value : (...) int
            Marks ``k >= 0``.

        Returns
        -------
        (...) float
            ``log sum_i pi_i lambda_i^k e^{-lambda_i} / k!``.
        """
        return jax.nn.logsumexp(self.component_log_probs(value), axis=-1)

    def responsibilities(self, value: npt.ArrayLike) -> jax.Array:
        """Posterior class probabilities ``P(class = i | X = value)`` of marks ``value (...)``
        (int, ``k >= 0``).

        Returns
        -------
        (..., n) float
            Rows sum to one.
        """
        return jax.nn.softmax(self.component_log_probs(value), axis=-1)

    def sample_with_class(
        self, key: jax.Array, sample_shape: tuple[int, ...] = ()
    ) -> tuple[jax.Array, jax.Array]:
        """Draw classes (categorical) and then marks (Poisson of the class's rate).

        Parameters
        ----------
        key : jax.Array
            PRNG key.
        sample_shape : tuple of int
            Leading shape of the draw.

        Returns
        -------
        marks : (*sample_shape, *batch_shape) int
            The marks X.
        classes : (*sample_shape, *batch_shape) int
            Index of the component that produced each mark.
        """
        shape = tuple(int(d) for d in sample_shape) + tuple(self.batch_shape)
        return _sample_with_class(key, self.weights, self.rates, shape)

    def sample(self, key: jax.Array, sample_shape: tuple[int, ...] = ()) -> jax.Array:
        """Draw marks: a class from the weights, then a Poisson count with its rate.

        Parameters
        ----------
        key : jax.Array
            PRNG key.
        sample_shape : tuple of int
            Leading shape of the draw.

        Returns
        -------
        (*sample_shape, *batch_shape) int
            The marks X.
        """
        return self.sample_with_class(key, sample_shape)[0]

    @property
    def mean(self) -> jax.Array:
        """``sum_i pi_i lambda_i``."""
        return jnp.sum(self.weights * self.rates, axis=-1)

    @property
    def variance(self) -> jax.Array:
        """``sum_i pi_i (lambda_i + lambda_i^2) - mean^2``."""
        second = jnp.sum(self.weights * (self.rates + self.rates**2), axis=-1)
        return second - self.mean**2
