"""One NUTS driver for the traffic models: robust start, diagnostics, pointwise log-likelihood.

:func:`run_nuts` samples a numpyro model from a stated starting point (the traffic models
are parameterised so that ``z = 0`` is the empirical estimate, whatever the data's time
scale), and returns the draws by chain, the divergences, split-``r_hat`` of every latent
scalar and, through a caller's pure function, the pointwise log-likelihood of every draw
(for PSIS-LOO). Nothing is hidden: divergences and ``r_hat`` are part of the result and
:func:`nuts_warnings` words them for the CLI and the summary table.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.diagnostics import split_gelman_rubin
from numpyro.infer import MCMC, NUTS, init_to_value

from are_stats.fitting._lifecycle_mcmc import resolve_chain_method

__all__ = ["NutsRun", "nuts_warnings", "run_nuts"]


class NutsRun(NamedTuple):
    """Draws and diagnostics of :func:`run_nuts`.

    Attributes
    ----------
    samples : dict of str to (chains, draws, ...) ndarray
        Latent and deterministic sites.
    diverging : (chains, draws) bool
    r_hat : dict of str to float
        Largest split-``r_hat`` over each site's scalars (NaN with one chain).
    loglik : (chains, draws, units) ndarray or None
        Pointwise log-likelihood.
    name : str
        The model's name (in warnings).
    extra : dict of str to (chains, draws) ndarray
        The sampler's extra fields asked for (``num_steps``, ``energy``, ...).
    chain_method : str
        How the chains ran (``parallel``, ``vectorized`` or ``sequential``).
    """

    samples: dict
    diverging: np.ndarray
    r_hat: dict
    loglik: np.ndarray | None
    name: str
    extra: dict = {}  # noqa: RUF012 (NamedTuple default, never mutated)
    chain_method: str = "sequential"

    @property
    def n_divergent(self) -> int:
        """Divergent transitions after warm-up."""
        return int(self.diverging.sum())

    @property
    def max_r_hat(self) -> float:
        """Largest ``r_hat`` over the sites (NaN with one chain)."""
        vals = [v for v in self.r_hat.values() if np.isfinite(v)]
        return float(max(vals)) if vals else float("nan")


def run_nuts(
    key: Any,
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    *,
    num_warmup: int = 1000,
    num_samples: int = 1000,
    num_chains: int = 4,
    pointwise: Callable[[dict], Any] | None = None,
    name: str = "",
    target_accept_prob: float = 0.85,
    init_params: dict | None = None,
    chain_method: str | None = None,
    extra_fields: tuple[str, ...] = (),
) -> NutsRun:
    """Sample ``model(**model_kwargs)`` by NUTS from ``init``.

    Parameters
    ----------
    key : jax PRNG key
    model : callable
        A numpyro model.
    model_kwargs : dict
        Its arguments.
    init : dict or None
        Starting values of the latent sites, on their constrained scale (the traffic
        models start at ``z = 0``, the empirical estimate); None: numpyro's default.
    num_warmup, num_samples, num_chains : int
    pointwise : callable, optional
        ``pointwise(sample_dict) -> (units,)`` for ONE draw (vmapped over draws).
    name : str
        Model name for the warnings.
    target_accept_prob : float
        NUTS step-size adaptation target.
    init_params : dict, optional
        Starting values on the unconstrained scale, with a leading chain axis (e.g. an EM
        fit jittered per chain); they win over ``init``.
    chain_method : {"parallel", "vectorized", "sequential"}, optional
        Default: parallel when there is a device per chain
        (:func:`~are_stats.fitting.resolve_chain_method`).
    extra_fields : tuple of str
        numpyro extra fields to keep (``diverging`` is always kept).

    Returns
    -------
    NutsRun
    """
    kw = {} if init is None else {"init_strategy": init_to_value(values=init)}
    kernel = NUTS(model, target_accept_prob=target_accept_prob, **kw)
    method = resolve_chain_method(chain_method, int(num_chains))
    if method == "parallel" and jax.local_device_count() < int(num_chains):
        method = "vectorized"  # numpyro would run "parallel" chains one after another
    mcmc = MCMC(
        kernel,
        num_warmup=int(num_warmup),
        num_samples=int(num_samples),
        num_chains=int(num_chains),
        chain_method=method,
        progress_bar=False,
    )
    fields = tuple(dict.fromkeys(("diverging", *extra_fields)))
    mcmc.run(key, init_params=init_params, extra_fields=fields, **model_kwargs)
    samples = {k: np.asarray(v) for k, v in mcmc.get_samples(group_by_chain=True).items()}
    got = {k: np.asarray(v) for k, v in mcmc.get_extra_fields(group_by_chain=True).items()}
    diverging = got.pop("diverging").astype(bool)
    r_hat = {}
    for site, v in samples.items():
        if v.shape[0] < 2 or v.shape[1] < 4:
            r_hat[site] = float("nan")
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.asarray(split_gelman_rubin(v))
        r_hat[site] = float(np.nanmax(r)) if np.isfinite(r).any() else float("nan")
    loglik = None
    if pointwise is not None:
        c, d = diverging.shape
        flat = {k: jnp.asarray(v.reshape((c * d,) + v.shape[2:])) for k, v in samples.items()}
        ll = jax.jit(jax.vmap(pointwise))(flat)
        loglik = np.asarray(ll).reshape(c, d, -1)
    return NutsRun(samples, diverging, r_hat, loglik, name, got, method)


def nuts_warnings(run: NutsRun, r_hat_limit: float = 1.01) -> list[str]:
    """Words for the divergences and large ``r_hat`` of a run (empty when clean)."""
    out = []
    total = run.diverging.size
    if run.n_divergent:
        out.append(
            f"{run.name}: {run.n_divergent} of {total} draws divergent: the posterior may be "
            "biased (more --warmup, or the model does not suit the data)"
        )
    if np.isfinite(run.max_r_hat) and run.max_r_hat > r_hat_limit:
        bad = sorted(k for k, v in run.r_hat.items() if np.isfinite(v) and v > r_hat_limit)
        out.append(
            f"{run.name}: r_hat {run.max_r_hat:.3f} > {r_hat_limit} for {', '.join(bad)}: the "
            "chains disagree (run longer chains: --samples, --warmup)"
        )
    return out
