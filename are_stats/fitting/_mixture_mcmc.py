"""Bayesian fit of the Poisson mixture of eq. (1) by NUTS, class assignments marginalised.

The likelihood runs over the histogram of distinct marks: ``sum_j c_j log p(v_j)`` with
``p`` the mixture pmf, ``v_j`` the distinct marks and ``c_j`` their counts, so the cost of
one gradient is O(distinct marks x components), whatever the number of marks.

Priors (documented defaults, overridable):

* ``mix_weights ~ Dirichlet(alpha, ..., alpha)`` with ``alpha = 1`` (uniform on the simplex);
* ``mix_rates``: the order statistics of ``n`` independent ``Gamma(a, b)`` draws, with
  ``a = 1`` and ``b = 1 / mean(marks)`` (an exponential prior with the data's mean scale).
  Ordering the rates removes label switching. For one component this is exactly the
  ``Gamma(a, b)`` prior, whose posterior is ``Gamma(a + sum k, b + N)``.
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import numpyro
import numpyro.distributions as dist
from jax import random
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to

from are_stats._checks import check_in, check_positive
from are_stats._lazy import arviz as az
from are_stats.fitting._em import _check_positive_int, fit_mixture_em, marks_histogram
from are_stats.fitting._nuts import run_nuts
from are_stats.traffic import PoissonMixture

__all__ = ["fit_mixture_nuts", "mixture_model"]


def mixture_model(
    values: npt.ArrayLike,
    counts: npt.ArrayLike,
    n_components: int,
    weight_concentration: float = 1.0,
    rate_prior: tuple[float, float] = (1.0, 1.0),
) -> None:
    """numpyro model of eq. (1) over a histogram of marks.

    Parameters
    ----------
    values : (m,) float
        Distinct marks.
    counts : (m,) float
        Their counts.
    n_components : int
        Number of components ``n``.
    weight_concentration : float
        Dirichlet concentration ``alpha`` of the weights.
    rate_prior : (float, float)
        Shape ``a`` and rate ``b`` of the Gamma law whose ``n`` ordered draws are the rates.

    Notes
    -----
    Sites: ``mix_weights`` (n,), ``mix_rates`` (n,) increasing, and the factor ``marks``
    holding ``sum_j counts_j log p(values_j)``.
    """
    a, b = rate_prior
    weights = numpyro.sample(
        "mix_weights", dist.Dirichlet(jnp.full(n_components, weight_concentration))
    )
    rates = numpyro.sample(
        "mix_rates",
        dist.ImproperUniform(constraints.positive_ordered_vector, (), (n_components,)),
    )
    # density of the order statistics of n iid Gamma(a, b) draws: n! prod Gamma(rates_i)
    numpyro.factor(
        "mix_rates_prior",
        jnp.sum(dist.Gamma(a, b).log_prob(rates)) + math.lgamma(n_components + 1),
    )
    log_p = PoissonMixture(weights, rates).log_prob(values)
    numpyro.factor("marks", jnp.sum(counts * log_p))


def _pointwise_loglik(weights: jax.Array, rates: jax.Array, values: jax.Array) -> jax.Array:
    """log p(values_j | draw) for every draw: (chain, draw, m)."""

    def one(w: jax.Array, r: jax.Array) -> jax.Array:
        return PoissonMixture(w, r).log_prob(values)

    return jax.vmap(jax.vmap(one))(weights, rates)


def fit_mixture_nuts(
    key: jax.Array,
    marks: npt.ArrayLike,
    n_components: int,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 2,
    chain_method: str = "parallel",
    *,
    counts: npt.ArrayLike | None = None,
    weight_concentration: float = 1.0,
    rate_prior: tuple[float, float] | None = None,
    init: str = "em",
    target_accept_prob: float = 0.9,
) -> az.InferenceData:
    """Posterior of the Poisson mixture of eq. (1) by NUTS over the histogram of marks.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    marks : (N,) int
        Non-negative integer marks. With ``counts``: the values of a histogram.
    n_components : int
        Number of components ``n`` (at most the number of distinct marks).
    num_warmup, num_samples : int
        Warm-up and kept draws per chain.
    num_chains : int
        Number of chains.
    chain_method : {"parallel", "vectorized", "sequential"}
        How the chains run (:func:`run_nuts`). ``"parallel"`` spreads them over the
        JAX devices (on CPU set ``XLA_FLAGS=--xla_force_host_platform_device_count=N``
        before JAX starts), each device vectorising its share when there are fewer
        devices than chains. The method used is stored in
        ``idata.posterior.attrs["chain_method"]``.
    counts : (N,) float, optional
        Multiplicity of each entry of ``marks``.
    weight_concentration : float
        Dirichlet concentration of the weights (default 1: uniform on the simplex).
    rate_prior : (float, float), optional
        Shape and rate of the Gamma law whose ordered draws are the rates; default
        ``(1, 1 / mean(marks))``.
    init : {"em", "prior"}
        ``"em"``: start every chain at the EM estimate (jittered per chain, in the
        unconstrained space); ``"prior"``: numpyro's ``init_to_uniform``.
    target_accept_prob : float
        NUTS target acceptance probability.

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (``mix_weights``, ``mix_rates`` with dim ``component``),
        ``sample_stats``, ``log_likelihood`` (``marks``: log p of each DISTINCT mark per draw,
        dim ``mark_value``) and ``constant_data`` (``mark_value``, ``mark_count``). Use
        :func:`are_stats.fitting.mixture_waic` / :func:`are_stats.fitting.mixture_loo`,
        which weight each distinct mark by its count; arviz's own ``az.waic``/``az.loo``
        would treat every distinct mark as one observation.

    Raises
    ------
    ValueError
        On bad marks or counts, ``n_components < 1`` or above the number of distinct
        marks, non-positive sampler sizes, an unknown ``chain_method`` or ``init``, or a
        bad prior.

    Examples
    --------
    >>> import jax, numpy as np
    >>> from are_stats import fit_mixture_nuts
    >>> marks = np.random.default_rng(21).poisson(4.0, 2000)
    >>> idata = fit_mixture_nuts(jax.random.key(0), marks, 1, num_warmup=400, num_samples=1000)
    >>> round(float(idata.posterior["mix_rates"].mean()), 0)
    4.0
    """
    n_components = _check_positive_int("n_components", n_components)
    num_warmup = _check_positive_int("num_warmup", num_warmup)
    num_samples = _check_positive_int("num_samples", num_samples)
    num_chains = _check_positive_int("num_chains", num_chains)
    check_in("chain_method", chain_method, ("parallel", "vectorized", "sequential"))
    check_in("init", init, ("em", "prior"))
    alpha = float(check_positive("weight_concentration", weight_concentration, ndim=0))
    if not 0 < target_accept_prob < 1:
        raise ValueError(
            f"target_accept_prob: expected a number in (0, 1), got {target_accept_prob!r}"
        )
    hist = marks_histogram(marks, counts)
    if n_components > hist.n_distinct:
        raise ValueError(
            f"n_components: expected at most the number of distinct marks "
            f"({hist.n_distinct}), got {n_components}"
        )
    mean = float(np.sum(hist.counts * hist.values) / hist.n_marks)
    if rate_prior is None:
        rate_prior = (1.0, 1.0 / max(mean, 1e-3))
    prior = check_positive("rate_prior", rate_prior, ndim=1)
    if prior.shape != (2,):
        raise ValueError(f"rate_prior: expected (shape, rate), got {len(prior)} numbers")
    rate_prior = (float(prior[0]), float(prior[1]))

    values = jnp.asarray(hist.values)
    cnts = jnp.asarray(hist.counts)
    key_init, key_run = random.split(key)
    init_params = None
    if init == "em":
        em = fit_mixture_em(
            hist.values, n_components, random.fold_in(key_init, 1), counts=hist.counts
        )
        w = np.clip(em.weights, 1e-6, None)
        w = w / w.sum()
        r = np.maximum(em.rates, 1e-6)
        r = r + 1e-6 * np.arange(n_components)  # strictly increasing
        u_w = biject_to(constraints.simplex).inv(jnp.asarray(w))
        u_r = biject_to(constraints.positive_ordered_vector).inv(jnp.asarray(r))
        k1, k2 = random.split(key_init)
        init_params = {
            "mix_weights": u_w + 0.05 * random.normal(k1, (num_chains,) + u_w.shape),
            "mix_rates": u_r + 0.05 * random.normal(k2, (num_chains,) + u_r.shape),
        }
        if num_chains == 1:
            init_params = {k: v[0] for k, v in init_params.items()}

    model = partial(
        mixture_model,
        n_components=n_components,
        weight_concentration=alpha,
        rate_prior=rate_prior,
    )
    run = run_nuts(
        key_run,
        model,
        {"values": values, "counts": cnts},
        None,
        num_warmup=num_warmup,
        num_samples=num_samples,
        num_chains=num_chains,
        target_accept_prob=target_accept_prob,
        init_params=init_params,
        chain_method=chain_method,
        extra_fields=("num_steps", "energy", "accept_prob"),
        name="mixture",
    )
    method = run.chain_method
    samples = run.samples
    weights = samples["mix_weights"]
    rates = samples["mix_rates"]
    loglik = np.asarray(_pointwise_loglik(weights, rates, values))
    extra = {**run.extra, "diverging": run.diverging}
    coords = {
        "component": np.arange(n_components),
        "mark_value": hist.values.astype(np.int64),
    }
    idata = az.from_dict(
        posterior={"mix_weights": np.asarray(weights), "mix_rates": np.asarray(rates)},
        sample_stats={
            "diverging": np.asarray(extra["diverging"]),
            "n_steps": np.asarray(extra["num_steps"]),
            "energy": np.asarray(extra["energy"]),
            "acceptance_rate": np.asarray(extra["accept_prob"]),
        },
        log_likelihood={"marks": loglik},
        constant_data={"mark_count": hist.counts},
        coords=coords,
        dims={
            "mix_weights": ["component"],
            "mix_rates": ["component"],
            "marks": ["mark_value"],
            "mark_count": ["mark_value"],
        },
    )
    attrs = {
        "model": "Poisson mixture, eq. (1) of the ARE paper",
        "chain_method": method,
        "n_marks": float(hist.n_marks),
        "weight_concentration": alpha,
        "rate_prior_shape": rate_prior[0],
        "rate_prior_rate": rate_prior[1],
        "init": init,
    }
    idata.posterior.attrs.update(attrs)
    return idata
