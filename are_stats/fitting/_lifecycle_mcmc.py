"""Posterior of the life-cycle model by NUTS, returned as ArviZ ``InferenceData``.

The model is :func:`are_stats.traffic.lifecycle_model`; its likelihood is vectorised (one
count term per window, one vector of stay terms, one term per distinct mark), so a gradient
costs microseconds and NUTS time is dominated by compilation and tree building. numpyro
samples positive parameters on the log scale (``biject_to``), which is the natural scale of
the rates; chains start near crude data estimates, jittered per chain.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any  # Any: lifecycle_model's keywords (arrays, sizes, flags)

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
from numpyro.distributions import biject_to
from numpyro.distributions.transforms import Transform
from numpyro.infer.util import log_likelihood

from are_stats._checks import check_in, check_nonneg_int, check_probability, describe
from are_stats._lazy import arviz as az
from are_stats.fitting._nuts import NutsRun, nuts_warnings, resolve_chain_method, run_nuts
from are_stats.traffic import (
    LifecycleData,
    LifecyclePriors,
    LifecycleSummary,
    check_components,
    lifecycle_model,
    numpy_rng,
    prior_predictive,
)

__all__ = ["fit_lifecycle_nuts"]

_LATENT = ("arrival_rate", "leave_rate", "mix_weights", "mix_rates")


def _start_values(data: LifecycleData, k: int | None) -> dict[str, np.ndarray]:
    """Crude estimates of the latent sites (constrained scale)."""
    n_arr = float((~data.truncated).sum())
    departures = float((~data.censored).sum())
    exposure = float(data.dwell.sum())
    values = {
        "arrival_rate": np.asarray(max(n_arr, 1.0) / (data.area * data.duration)),
        "leave_rate": np.asarray(max(departures, 1.0) / max(exposure, 1e-12 * data.duration)),
    }
    if k is not None and data.marks is not None and data.n:
        if data.labels is not None:
            counts = np.bincount(data.labels, minlength=k).astype(float)
            sums = np.bincount(data.labels, weights=data.marks, minlength=k)
            values["mix_rates"] = (sums + 1.0) / (counts + 1.0)
            weights = counts + 1.0
        else:
            q = np.quantile(data.marks, (np.arange(k) + 0.5) / k) + 0.5
            values["mix_rates"] = q + 1e-3 * np.arange(k)  # strictly increasing
            weights = np.ones(k)
        if k > 1:
            values["mix_weights"] = weights / weights.sum()
    return values


def _latent_sites(model_kwargs: dict, start: dict[str, np.ndarray]) -> dict[str, Transform]:
    """Support transforms of the latent sites, from one abstract trace at the start values.

    The model is traced under :func:`jax.eval_shape` (issue 29: run eagerly, each of its
    operations compiled a program of its own, about 35 per fit); only the sites' supports
    are kept, which hold no array.
    """
    supports: dict[str, Any] = {}

    def trace_supports() -> None:
        values = {name: jnp.asarray(v) for name, v in start.items()}
        model = numpyro.handlers.substitute(lifecycle_model, data=values)
        trace = numpyro.handlers.trace(model).get_trace(**model_kwargs)
        supports.update(
            (name, site["fn"].support)
            for name, site in trace.items()
            if site["type"] == "sample" and not site["is_observed"]
        )

    jax.eval_shape(trace_supports)
    return {name: biject_to(support) for name, support in supports.items()}


def _bucket(n: int) -> int:
    """Padded length: the next power of two, at least 16 (bounds the number of compilations)."""
    return max(16, 1 << max(0, int(n) - 1).bit_length())


def _padded_summary(s: LifecycleSummary) -> LifecycleSummary:
    """The summary as float64/int arrays padded with zero-weight rows to bucketed lengths.

    Padded stays have dwell 0 and no departure (log-likelihood term 0); padded marks and
    (class, mark) pairs have count 0.
    """

    def pad(x, dtype):
        x = np.asarray(x, dtype=dtype)
        return np.concatenate([x, np.zeros(_bucket(x.size) - x.size, dtype=dtype)])

    return LifecycleSummary(
        duration=np.asarray(s.duration, dtype=np.float64),
        area=np.asarray(s.area, dtype=np.float64),
        n_arrivals=np.asarray(s.n_arrivals, dtype=np.float64),
        n_present=np.asarray(s.n_present, dtype=np.float64),
        dwell=pad(s.dwell, np.float64),
        departed=pad(s.departed, bool),
        mark_values=pad(s.mark_values, np.int64),
        mark_counts=pad(s.mark_counts, np.float64),
        pair_labels=pad(s.pair_labels, np.int64),
        pair_marks=pad(s.pair_marks, np.int64),
        pair_counts=pad(s.pair_counts, np.float64),
    )


def _pointwise_loglik(draw: dict, **model_kwargs: Any) -> dict[str, jax.Array]:
    """Log-likelihood terms of one draw: window counts and the mark histogram.

    The per-artefact stays would be draws x rows: left out (XLA then never computes them);
    :func:`are_stats.fitting.fit_loo` recomputes them on demand.
    """
    one = {name: v[None] for name, v in draw.items()}
    loglik = log_likelihood(lifecycle_model, one, **model_kwargs)
    loglik.pop("stays", None)
    return {name: v[0] for name, v in loglik.items()}


#: sample_stats names of the sampler fields kept (ArviZ's names on the left).
_STATS = {
    "n_steps": "num_steps",
    "acceptance_rate": "accept_prob",
    "energy": "energy",
    "lp": "potential_energy",
    "step_size": "step_size",
}


def _predictive_counts(
    rng: np.random.Generator, posterior: dict, data: LifecycleData, stationary_start: bool
) -> dict[str, np.ndarray]:
    """Replicated window counts of :func:`lifecycle_model` given the posterior draws.

    ``n_arrivals`` ~ Poisson(lambda * area * T) and ``n_present`` ~ Poisson(lambda * area / mu),
    drawn with NumPy: a compiled Poisson sampler would cost seconds of compilation for
    microseconds of work.
    """
    lam, mu = posterior["arrival_rate"], posterior["leave_rate"]
    out = {"n_arrivals": rng.poisson(lam * data.area * data.duration)}
    if stationary_start:
        out["n_present"] = rng.poisson(lam * data.area / mu)
    return out


def fit_lifecycle_nuts(
    key: jax.Array,
    data: LifecycleData,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    *,
    n_components: int | None = None,
    num_warmup: int = 1000,
    num_samples: int = 1000,
    num_chains: int = 4,
    chain_method: str | None = None,
    progress_bar: bool = False,
    stationary_start: bool = True,
    target_accept_prob: float = 0.8,
    num_prior_draws: int = 1000,
) -> az.InferenceData:
    """Sample the life-cycle posterior with NUTS and return ArviZ ``InferenceData``.

    Posterior variables: ``arrival_rate`` (lambda, per m^2 per time unit), ``leave_rate``
    (mu, per time unit) and, for logs with marks, ``mix_weights`` and ``mix_rates`` of eq. (1)
    (ordered rates without labels, complete-data likelihood with labels).

    The sampler is the toolkit's one NUTS driver, :func:`~are_stats.fitting.run_nuts`
    (numpyro's NUTS kernel, step size and diagonal mass matrix adapted during warm-up, in
    one ahead-of-time compiled XLA program for all chains, warm-up and sampling together;
    a second small program computes the constrained draws and pointwise log-likelihood).
    The log's summary is padded to bucketed sizes and passed as an argument of both
    programs, so later fits of logs of similar size in the same process compile nothing,
    and a new process reads them from disk (traced programs kept by :mod:`jax.export`,
    compiled ones in JAX's persistent cache). Chains start at crude data
    estimates moved by U(-0.5, 0.5) on the unconstrained (log) scale, independently per
    chain.

    Parameters
    ----------
    key : jax PRNG key
        Randomness (chains' starting points, NUTS, prior and predictive draws).
    data : LifecycleData
        The observed window (censored and truncated artefacts included).
    priors : LifecyclePriors
        The priors.
    n_components : int, optional
        Number of mixture components; required for marks without labels.
    num_warmup, num_samples : int
        Warm-up (adaptation) and kept draws per chain.
    num_chains : int
        Number of chains (>= 1).
    chain_method : {"parallel", "vectorized", "sequential"} or None
        ``"parallel"`` spreads the chains over the JAX devices (``jax.shard_map``; several chains
        per device are vectorised), ``"vectorized"`` runs them in lock-step on one device
        (``jax.vmap``), ``"sequential"`` one after another with one compilation. ``None``:
        see :func:`resolve_chain_method`.
    progress_bar : bool
        Accepted for numpyro compatibility; the compiled program has no progress bar.
    stationary_start : bool
        Include the stationary count of artefacts present at ``t0``,
        Poisson(lambda * area / mu): more information on lambda / mu, but the posterior is then
        no longer the product of the conjugate Gammas.
    target_accept_prob : float
        NUTS target acceptance probability in (0, 1).
    num_prior_draws : int
        Draws from the prior (and prior predictive) stored in the ``prior`` groups (0: none).

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior``, ``sample_stats`` (``diverging``, ``n_steps``,
        ``acceptance_rate``, ``energy``, ``lp``, ``step_size``; attributes
        ``n_divergent``, ``max_r_hat``, ``r_hat_<site>`` (split-``r_hat``) and
        ``nuts_warnings``, the words of :func:`~are_stats.fitting.nuts_warnings`, empty
        when clean), ``log_likelihood``
        (``n_arrivals``, ``n_present``, ``mark_histogram`` per distinct mark or (class,
        mark) pair: sizes that scale with the distinct data; the per-artefact ``stays``
        terms are recomputed on demand by :func:`are_stats.fitting.pointwise_log_likelihood`
        and :func:`are_stats.fitting.fit_loo`), ``posterior_predictive`` (window counts),
        ``prior``, ``prior_predictive`` and ``observed_data`` (the log's columns, counts and
        mark histogram). Posterior attributes record the chain method, priors and settings.

    Raises
    ------
    ValueError
        Naming the argument when an input is invalid.

    Examples
    --------
    A log without marks (with marks, ``n_components`` adds ``mix_weights`` and
    ``mix_rates``), two chains one after the other:

    >>> import jax
    >>> from are_stats.traffic import LifecycleData, simulate_lifecycle
    >>> d = simulate_lifecycle(jax.random.key(4), 2.0, 0.05, [1.0], [5.0], (0.0, 100.0),
    ...                        area=1.0)
    >>> d = LifecycleData(d.t_arrive, d.t_leave, d.window, d.area)
    >>> idata = fit_lifecycle_nuts(jax.random.key(1), d, num_warmup=100, num_samples=100,
    ...                            num_chains=2, chain_method="sequential", num_prior_draws=0)
    >>> sorted(idata.posterior.data_vars)
    ['arrival_rate', 'leave_rate']
    """
    if not isinstance(data, LifecycleData):
        raise ValueError(f"data: expected a LifecycleData, got {type(data).__name__}")
    if not isinstance(priors, LifecyclePriors):
        raise ValueError(f"priors: expected a LifecyclePriors, got {type(priors).__name__}")
    warmup = int(check_nonneg_int("num_warmup", num_warmup, ndim=0))
    samples = int(check_nonneg_int("num_samples", num_samples, ndim=0))
    chains = int(check_nonneg_int("num_chains", num_chains, ndim=0))
    prior_draws = int(check_nonneg_int("num_prior_draws", num_prior_draws, ndim=0))
    if samples < 1:
        raise ValueError(f"num_samples: expected an integer >= 1, got {num_samples!r}")
    if chains < 1:
        raise ValueError(f"num_chains: expected an integer >= 1, got {num_chains!r}")
    accept = float(check_probability("target_accept_prob", target_accept_prob, ndim=0))
    if not 0.0 < accept < 1.0:
        raise ValueError(f"target_accept_prob: expected a value in (0, 1), got {accept!r}")
    check_in("stationary_start", stationary_start, (True, False))
    check_in("progress_bar", progress_bar, (True, False))
    method = resolve_chain_method(chain_method, chains)
    k = check_components(n_components, data)
    if data.marks is None:
        k = None  # no marks: the mixture is not part of this fit
    try:
        key_mcmc, key_post, key_prior = jax.random.split(key, 3)
    except (TypeError, ValueError) as err:
        raise ValueError(f"key: expected a JAX PRNG key, got {describe(key)}") from err

    static = {
        "priors": priors,
        "n_components": k,
        "stationary_start": stationary_start,
        "labelled": data.labels is not None,
    }
    start = _start_values(data, k)
    transforms = _latent_sites({**static, "data": data}, start)
    rng = numpy_rng(key_mcmc)
    noise = {
        name: rng.uniform(-0.5, 0.5, size=(chains,) + t.inverse_shape(np.shape(start[name])))
        for name, t in transforms.items()
    }
    # one program for the inverse transforms (op by op, each operation compiled its own)
    start_u = jax.jit(lambda v: {name: t.inv(v[name]) for name, t in transforms.items()})(
        {name: start[name] for name in transforms}
    )
    start_u = {name: np.asarray(v) for name, v in start_u.items()}
    init_params = {name: start_u[name] + noise[name] for name in transforms}
    if chains == 1:  # numpyro's convention: no chain axis for one chain
        init_params = {name: v[0] for name, v in init_params.items()}
    run = run_nuts(
        key_mcmc,
        lifecycle_model,
        {**static, "data": _padded_summary(data.summary)},
        None,
        num_warmup=warmup,
        num_samples=samples,
        num_chains=chains,
        pointwise=_pointwise_loglik,
        pointwise_kwargs=True,
        name="life-cycle",
        target_accept_prob=accept,
        init_params=init_params,
        chain_method=method,
        extra_fields=tuple(_STATS.values()),
        cheap_compile=True,  # a gradient costs microseconds: compilation dominates
    )
    posterior, loglik = run.samples, dict(run.loglik)
    stats = {"diverging": run.diverging, **{n: run.extra[f] for n, f in _STATS.items()}}
    stats["lp"] = -stats["lp"]
    timing = dict(run.timing)
    s = data.summary
    if "mark_histogram" in loglik:
        m = s.mark_values.size if data.labels is None else s.pair_counts.size
        loglik["mark_histogram"] = loglik["mark_histogram"][..., :m]
    post_pred = _predictive_counts(numpy_rng(key_post), posterior, data, stationary_start)
    prior = {}
    if prior_draws:
        tic = time.perf_counter()
        prior = prior_predictive(
            key_prior,
            priors,
            data.window,
            data.area,
            prior_draws,
            n_components=k,
            stationary_start=stationary_start,
            labelled=data.labels is not None,
        )
        timing["prior"] = time.perf_counter() - tic
    idata = _inference_data(
        data,
        priors,
        k,
        stationary_start,
        run.chain_method,
        posterior,
        stats,
        loglik,
        post_pred,
        prior,
        timing,
    )
    _diagnostics(idata, run)
    return idata


def _diagnostics(idata: az.InferenceData, run: NutsRun) -> None:
    """Divergences, split-``r_hat`` and their warnings (:func:`nuts_warnings`) as attributes."""
    words = nuts_warnings(run)
    idata.sample_stats.attrs.update(
        n_divergent=run.n_divergent,
        max_r_hat=run.max_r_hat,
        nuts_warnings="\n".join(words),
        **{f"r_hat_{site}": value for site, value in run.r_hat.items()},
    )


def _inference_data(
    data: LifecycleData,
    priors: LifecyclePriors,
    k: int | None,
    stationary_start: bool,
    method: str,
    posterior: dict,
    stats: dict,
    loglik: dict,
    post_pred: dict,
    prior: dict,
    timing: dict[str, float],
) -> az.InferenceData:
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    counts = ("n_arrivals", "n_present") if stationary_start else ("n_arrivals",)
    observed: dict[str, np.ndarray] = {"n_arrivals": np.asarray(int((~data.truncated).sum()))}
    if stationary_start:
        observed["n_present"] = np.asarray(int(data.truncated.sum()))
    observed.update(
        t_arrive=data.t_arrive,
        t_leave=data.t_leave,
        dwell=data.dwell,
        censored=data.censored,
        truncated=data.truncated,
    )
    for name in ("marks", "labels", "x", "y", "yaw", "group", "x_exit", "y_exit"):
        value = getattr(data, name)
        if value is not None:
            observed[name] = value
    dims = {name: ["artefact"] for name in ("stays", "t_arrive", "t_leave", "dwell")}
    dims.update({name: ["artefact"] for name in ("censored", "truncated", "marks", "labels")})
    dims.update({name: ["artefact"] for name in ("x", "y", "yaw", "group", "x_exit", "y_exit")})
    dims.update(mix_weights=["component"], mix_rates=["component"])
    coords: dict[str, np.ndarray] = {}
    if data.marks is not None and data.n:
        # the mark likelihood runs over distinct marks (or (class, mark) pairs): its
        # observed counterpart is the histogram
        s = data.summary
        if data.labels is None:
            dims["mark_histogram"] = ["mark_value"]
            coords["mark_value"] = s.mark_values
            observed["mark_histogram"] = s.mark_counts
        else:
            dims["mark_histogram"] = ["class_mark_pair"]
            observed["mark_histogram"] = s.pair_counts
            observed["pair_class"] = s.pair_labels
            observed["pair_mark"] = s.pair_marks
            dims["pair_class"] = dims["pair_mark"] = ["class_mark_pair"]
    prior_group = {n: v[None] for n, v in prior.items() if n not in counts}
    prior_pred = {n: v[None] for n, v in prior.items() if n in counts}
    idata = az.from_dict(
        posterior=posterior,
        sample_stats=stats,
        log_likelihood=loglik,
        posterior_predictive=post_pred,
        prior=prior_group or None,
        prior_predictive=prior_pred or None,
        coords=coords,
        dims=dims,
    )
    # scalars stay 0-d (from_dict would give them a length-1 dimension)
    idata.add_groups(
        observed_data=xr.Dataset(
            {name: (dims.get(name, []), np.asarray(v)) for name, v in observed.items()},
            coords=coords,
            attrs={"t0": data.window[0], "t1": data.window[1], "area": data.area},
        )
    )
    idata.posterior.attrs.update(
        {
            "model": "are_stats.traffic.lifecycle_model",
            "inference_library": "numpyro",
            "inference_library_version": numpyro.__version__,
            "chain_method": method,
            "stationary_start": int(stationary_start),
            "n_components": -1 if k is None else k,
            **{f"prior_{name}": value for name, value in dataclasses.asdict(priors).items()},
        }
    )
    idata.sample_stats.attrs.update({f"{name}_time": value for name, value in timing.items()})
    return idata
