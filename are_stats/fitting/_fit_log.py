"""Fit the artefact priors of a field log: the engine behind ``are-stats fit``.

One call turns a validated life-cycle log into an ArviZ ``InferenceData`` whose posterior
holds ``arrival_rate`` (lambda, per m^2 per second), ``leave_rate`` (mu, per second) and the
mark mixture ``mix_weights`` / ``mix_rates`` of eq. (1):

* ``method="nuts"``: the joint life-cycle model (:func:`are_stats.traffic.lifecycle_model`)
  sampled by NUTS, censoring and truncation included (DECISIONS 3);
* ``method="em"``: the fast path. ``arrival_rate`` and ``leave_rate`` are exact draws from
  their conjugate Gamma posteriors (:func:`are_stats.traffic.conjugate_arrival_rate`,
  :func:`~are_stats.traffic.conjugate_leave_rate`, which leave out the stationary count
  present at ``t0``); the mixture is the EM maximum-likelihood fit, and its uncertainty is
  the nonparametric bootstrap of EM over the histogram of marks (a sampling distribution,
  not a Bayesian posterior: the ``posterior`` attrs say so). Logs with class labels use the
  conjugate complete-data posterior of the mixture instead (DECISIONS 5).

A count panel (``t``, ``count``), when given, adds the exact birth-death MLE of
:func:`are_stats.fit_birth_death` to the attributes.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
import numpyro
from numpyro.infer import Predictive
from numpyro.infer.util import log_likelihood

from are_stats import __version__
from are_stats._checks import check_in, check_nonneg_int, describe
from are_stats.fitting._em import fit_mixture_em, marks_histogram
from are_stats.fitting._lifecycle_mcmc import _inference_data, fit_lifecycle_nuts
from are_stats.traffic import (
    LifecycleData,
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    fit_birth_death,
    lifecycle_model,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)  # arviz 0.23 announces its 1.0 refactor
    import arviz as az

__all__ = ["FitSettings", "fit_log", "choose_n_components"]


@dataclass(frozen=True)
class FitSettings:
    """Settings of :func:`fit_log` (recorded in the fit's attributes).

    Parameters
    ----------
    method : {"nuts", "em"}
        Joint NUTS posterior, or conjugate rates + EM/bootstrap mixture.
    n_components : int or None
        Mixture components; None: the number of labels, else chosen by BIC over
        ``1..k_max`` (EM).
    k_max : int
        Largest number of components tried by the BIC choice.
    num_warmup, num_samples, num_chains : int
        NUTS settings (``method="em"`` draws ``num_samples * num_chains`` conjugate draws and
        ``n_bootstrap`` bootstrap replicates).
    n_bootstrap : int
        Bootstrap replicates of the EM mixture fit.
    stationary_start : bool
        NUTS only: include the Poisson(lambda * area / mu) count present at ``t0``.
    """

    method: str = "nuts"
    n_components: int | None = None
    k_max: int = 5
    num_warmup: int = 1000
    num_samples: int = 1000
    num_chains: int = 4
    n_bootstrap: int = 200
    stationary_start: bool = True

    def __post_init__(self) -> None:
        check_in("method", self.method, ("nuts", "em"))
        for name in ("k_max", "num_samples", "num_chains", "n_bootstrap"):
            if int(check_nonneg_int(name, getattr(self, name), ndim=0)) < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {getattr(self, name)!r}")
        check_nonneg_int("num_warmup", self.num_warmup, ndim=0)
        if self.n_components is not None:
            if int(check_nonneg_int("n_components", self.n_components, ndim=0)) < 1:
                raise ValueError(f"n_components: expected an integer >= 1, got {self.n_components}")


def choose_n_components(key: Any, marks: np.ndarray, k_max: int) -> tuple[int, list[float]]:
    """Number of mixture components with the smallest BIC among ``1..k_max`` (EM fits).

    Parameters
    ----------
    key : jax PRNG key
        Restarts of EM.
    marks : (n,) int
        Marks of the log.
    k_max : int
        Largest number of components tried (capped by the number of distinct marks).

    Returns
    -------
    k : int
        The chosen number of components.
    bics : list of float
        BIC of each ``k = 1..k_max``.
    """
    k_max = min(int(k_max), int(np.unique(marks).size))
    bics = [fit_mixture_em(marks, k, jax.random.fold_in(key, k)).bic for k in range(1, k_max + 1)]
    return int(np.argmin(bics)) + 1, bics


def _em_posterior(
    key: Any, data: LifecycleData, priors: LifecyclePriors, k: int | None, s: FitSettings
) -> tuple[dict, dict, dict]:
    """Conjugate rate draws and bootstrap (or conjugate) mixture draws, shaped (1, S, ...)."""
    n_draws = s.num_samples * s.num_chains
    k_rate, k_mix, k_boot = jax.random.split(key, 3)
    rng = np.random.default_rng(np.asarray(jax.random.key_data(k_rate)).ravel().tolist())
    arr = conjugate_arrival_rate(data, priors)
    lea = conjugate_leave_rate(data, priors)
    post: dict[str, np.ndarray] = {
        "arrival_rate": rng.gamma(arr.shape, 1.0 / arr.rate, n_draws),
        "leave_rate": rng.gamma(lea.shape, 1.0 / lea.rate, n_draws),
    }
    stats: dict[str, np.ndarray] = {}
    attrs: dict[str, Any] = {}
    if k is not None and data.marks is not None:
        if data.labels is not None:
            mix = conjugate_mixture(data, priors, n_components=k)
            w = rng.dirichlet(np.asarray(mix.concentration), n_draws)
            r = rng.gamma(np.asarray(mix.shape), 1.0 / np.asarray(mix.rate), (n_draws, k))
            post["mix_weights"], post["mix_rates"] = w, r
            attrs["mixture_method"] = "conjugate complete-data posterior (labels)"
        else:
            hist = marks_histogram(data.marks)
            values, counts = np.asarray(hist.values), np.asarray(hist.counts)
            best = fit_mixture_em(data.marks, k, k_mix)
            n = int(counts.sum())
            ws, rs, lls, iters = [], [], [], []
            for b in range(s.n_bootstrap):
                resampled = rng.multinomial(n, counts / n)
                fit = fit_mixture_em(
                    values, k, jax.random.fold_in(k_boot, b), counts=resampled, n_restarts=4
                )
                ws.append(fit.weights)
                rs.append(fit.rates)
                lls.append(fit.loglik)
                iters.append(fit.n_iter)
            idx = rng.integers(0, s.n_bootstrap, n_draws)
            post["mix_weights"] = np.asarray(ws)[idx]
            post["mix_rates"] = np.asarray(rs)[idx]
            stats["bootstrap_loglik"] = np.asarray(lls)[idx]
            stats["bootstrap_n_iter"] = np.asarray(iters)[idx]
            attrs.update(
                mixture_method="EM maximum likelihood, nonparametric bootstrap draws",
                em_weights=best.weights,
                em_rates=best.rates,
                em_loglik=best.loglik,
                em_n_iter=best.n_iter,
            )
    shaped = {name: v[None] for name, v in post.items()}
    return shaped, {name: v[None] for name, v in stats.items()}, attrs


def fit_log(
    key: Any,
    data: LifecycleData,
    settings: FitSettings = FitSettings(),  # noqa: B008 (frozen, immutable)
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    counts_panel: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Any = None,
    class_labels: Any = None,
) -> az.InferenceData:
    """Fit arrival rate, leave rate and mark mixture of a life-cycle log.

    Parameters
    ----------
    key : jax PRNG key
        All randomness of the fit (reproducible from it).
    data : LifecycleData
        The validated log (see :meth:`are_stats.logs.LifecycleLog.to_lifecycle_data`).
    settings : FitSettings
        Method and sampler settings.
    priors : LifecyclePriors
        Priors of the life-cycle model.
    counts_panel : (times, counts), optional
        A panel of counts for the birth-death MLE (stored in the posterior attributes as
        ``birth_death_*``).
    progress : callable, optional
        ``progress(message)`` is called at each stage (the CLI shows it).
    class_labels : sequence of str, optional
        Names of the classes ``0..K-1`` of a labelled log (stored as the comma-separated
        attribute ``class_labels``; see ``LifecycleLog.to_arrays()["label_names"]``).

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (``arrival_rate``, ``leave_rate``, ``mix_weights``,
        ``mix_rates``), ``sample_stats``, ``log_likelihood``, ``observed_data``, ``prior``
        (and ``posterior_predictive`` / ``prior_predictive`` window counts); attributes
        ``model``, ``method``, ``window``, ``area``, ``are_stats_version``, ``n_components``.
    """
    if not isinstance(data, LifecycleData):
        raise ValueError(f"data: expected a LifecycleData, got {describe(data)}")
    say = progress or (lambda _msg: None)
    k_choice, k_fit, k_post = jax.random.split(key, 3)
    k: int | None = None
    bics: list[float] = []
    if data.marks is not None and data.n:
        if settings.n_components is not None:
            k = settings.n_components
        elif data.labels is not None:
            k = int(np.max(data.labels)) + 1
        else:
            say(f"choosing the number of mixture components by BIC (1..{settings.k_max})")
            k, bics = choose_n_components(k_choice, data.marks, settings.k_max)
    if settings.method == "nuts":
        say(
            f"NUTS: {settings.num_chains} chains x ({settings.num_warmup} warm-up + "
            f"{settings.num_samples} draws)"
        )
        idata = fit_lifecycle_nuts(
            k_fit,
            data,
            priors,
            n_components=k,
            num_warmup=settings.num_warmup,
            num_samples=settings.num_samples,
            num_chains=settings.num_chains,
            stationary_start=settings.stationary_start,
        )
    else:
        say("conjugate rate posteriors and EM mixture with bootstrap")
        post, stats, mix_attrs = _em_posterior(k_fit, data, priors, k, settings)
        model_kwargs = dict(data=data, priors=priors, n_components=k, stationary_start=False)
        gen_kwargs = dict(
            data=None,
            priors=priors,
            n_components=k,
            window=data.window,
            area=data.area,
            stationary_start=False,
        )
        flat = {name: v[0] for name, v in post.items()}
        loglik = log_likelihood(lifecycle_model, flat, **model_kwargs)
        loglik = {name: np.asarray(v)[None] for name, v in loglik.items()}
        # total log-likelihood of each draw (a diagnostic; these draws are not MCMC)
        stats["log_likelihood_total"] = sum(
            v.reshape(v.shape[:2] + (-1,)).sum(-1) for v in loglik.values()
        )
        kp, kq = jax.random.split(k_post)
        latent = {n: flat[n] for n in ("arrival_rate", "leave_rate", "mix_weights", "mix_rates")}
        latent = {n: v for n, v in latent.items() if n in flat}
        pred = Predictive(lifecycle_model, posterior_samples=latent, return_sites=["n_arrivals"])
        post_pred = {n: np.asarray(v)[None] for n, v in pred(kp, **gen_kwargs).items()}
        prior = Predictive(lifecycle_model, num_samples=1000)(kq, **gen_kwargs)
        prior = {n: np.asarray(v) for n, v in prior.items()}
        arviz_log = logging.getLogger("arviz")
        level = arviz_log.level
        arviz_log.setLevel(logging.ERROR)  # one "chain" of draws is expected here
        try:
            idata = _inference_data(
                data, priors, k, False, "em", post, stats, loglik, post_pred, prior, {}
            )
        finally:
            arviz_log.setLevel(level)
        idata.posterior.attrs.update(mix_attrs)
        idata.posterior.attrs["model"] = "are_stats.traffic.lifecycle_model (conjugate + EM)"
    attrs = {
        "method": settings.method,
        "window": np.asarray(data.window, dtype=float),
        "area": float(data.area),
        "are_stats_version": __version__,
        "numpyro_version": numpyro.__version__,
        "n_components": -1 if k is None else int(k),
        **{
            f"setting_{n}": (-1 if v is None else v)
            for n, v in dataclasses.asdict(settings).items()
        },
    }
    attrs = {n: (int(v) if isinstance(v, bool) else v) for n, v in attrs.items()}
    if bics:
        attrs["bic_by_k"] = np.asarray(bics)
    if class_labels is not None:
        labels = [str(v) for v in class_labels]
        if any("," in v for v in labels):
            raise ValueError(f"class_labels: expected names without commas, got {labels}")
        attrs["class_labels"] = ",".join(labels)
    if counts_panel is not None:
        say("exact birth-death MLE of the count panel")
        times, counts = counts_panel
        bd = fit_birth_death(times, counts)
        attrs.update(
            birth_death_birth_rate=bd.birth_rate,
            birth_death_death_rate=bd.death_rate,
            birth_death_stderr=np.asarray(bd.stderr, dtype=float),
            birth_death_loglik=bd.loglik,
            birth_death_n_obs=int(bd.n_obs),
        )
    idata.posterior.attrs.update(attrs)
    return idata


def write_fit(idata: az.InferenceData, out: str | Any, force: bool = False) -> Any:
    """Write a fit as NetCDF atomically (temporary file + rename); refuse to overwrite.

    Parameters
    ----------
    idata : arviz.InferenceData
        The fit.
    out : str or Path
        Destination ``.nc`` file.
    force : bool
        Overwrite an existing file.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    from pathlib import Path

    from are_stats._atomic import atomic_path

    path = Path(out)
    with atomic_path(path, force=force) as tmp:
        idata.to_netcdf(str(tmp))
    return path


def read_fit(path: str | Any) -> az.InferenceData:
    """Read a fit written by :func:`write_fit` / ``are-stats fit``.

    Parameters
    ----------
    path : str or Path
        The ``.nc`` file.

    Returns
    -------
    arviz.InferenceData

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If it is not a life-cycle fit (no ``arrival_rate`` / ``leave_rate`` posterior).
    """
    from pathlib import Path

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such fit file")
    try:
        idata = az.from_netcdf(str(p))
    except Exception as err:  # netCDF/HDF5 raise many types for a non-NetCDF file
        raise ValueError(f"{p}: expected an ArviZ NetCDF fit, could not read it ({err})") from err
    if "posterior" not in idata.groups() or "arrival_rate" not in idata.posterior:
        raise ValueError(f"{p}: expected a life-cycle fit with an 'arrival_rate' posterior")
    return idata
