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
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import jax
import numpy as np
import numpyro
from scipy.special import gammaln, logsumexp, xlogy

from are_stats import __version__
from are_stats._atomic import atomic_path
from are_stats._checks import check_in, check_nonneg_int, describe
from are_stats._lazy import LazyModule, import_xarray_dask
from are_stats._lazy import arviz as az
from are_stats.environment import coarse_free
from are_stats.fitting._class_traffic import (
    attach_class_positions,
    attach_class_shares_by_time,
    fit_class_positions,
    fit_class_shares_by_time,
)
from are_stats.fitting._classes import attach_classes, fit_classes
from are_stats.fitting._em import fit_mixture_em, marks_histogram
from are_stats.fitting._fit import Fit, fit_from_idata
from are_stats.fitting._lifecycle_exact import exact_lifecycle_draws, has_exact_posterior
from are_stats.fitting._lifecycle_mcmc import (
    _inference_data,
    _predictive_counts,
    fit_lifecycle_nuts,
)
from are_stats.fitting._psis import psislw
from are_stats.fitting._select import InformationCriterion, _weighted_total
from are_stats.fitting._traffic import (
    ARRIVAL_CHOICES,
    LIFETIME_CHOICES,
    POSITION_CELL,
    POSITION_CHOICES,
    LaplaceAhead,
    compile_laplace_ahead,
    fit_traffic,
    time_resolution,
)
from are_stats.inputs import (
    Described,
    InputError,
    check_memory,
    check_work,
    get_float,
    get_int,
    get_list,
    get_str,
)
from are_stats.traffic import (
    ARRIVAL_SPECS,
    STAY_LAWS,
    ArrivalSpec,
    LifecycleData,
    LifecyclePriors,
    clock_offset,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    fit_birth_death,
    fold_in_key,
    numpy_rng,
    prior_predictive,
    split_key,
)

if TYPE_CHECKING:
    import os

    import numpy.typing as npt
    import xarray as xr

    from are_stats.behaviour import BehaviourFit
    from are_stats.environment import OccupancyGrid
    from are_stats.fitting._traffic import TrafficFit

__all__ = [
    "FitSettings",
    "attach_behaviour",
    "check_fit_size",
    "attach_traffic",
    "fit_lifecycle_data",
    "choose_n_components",
    "fit_loo",
    "pointwise_log_likelihood",
    "read_fit",
    "write_fit",
]


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
    exact : bool
        ``method="nuts"``: draw the paper's model from its exact posterior where it has one
        (:func:`~are_stats.fitting.exact_lifecycle_draws`: Gamma priors, Poisson counts and
        exponential stays, censoring, truncation and the stationary count included; the
        mixture with class labels or one component), independent draws without NUTS; a
        mixture of several latent classes is sampled by NUTS. ``False``: always NUTS. The
        posterior attribute ``paper_posterior`` says which ran.
    arrivals, lifetimes, positions : str
        Traffic models beside the paper's (:func:`~are_stats.fitting.fit_traffic`):
        ``"auto"`` compares the candidates by PSIS-LOO and keeps the simplest within two
        standard errors of the best; a name fits that model. ``poisson``, ``exponential``
        and ``uniform`` together are the paper's model alone (nothing more is fitted).
        With ``method="em"`` no NUTS program is compiled: each candidate is a Laplace
        approximation at its posterior mode and PSIS-LOO is importance-sampled from it;
        with ``method="nuts"`` see ``compare`` (the fit's attribute
        ``traffic_model_choice`` says which ran).
    compare : {"laplace", "nuts"}
        ``method="nuts"``: how the traffic candidates are compared. ``"laplace"``: by
        importance-sampled PSIS-LOO from each one's Laplace approximation, then the chosen
        model's Laplace draws importance-resampled (NUTS samples it instead where their
        Pareto k is 0.7 or more; ``traffic_arrival_posterior`` and
        ``traffic_lifetime_posterior`` say which ran); ``"nuts"``: every candidate
        sampled by NUTS and compared by PSIS-LOO over its draws. ``method="em"`` always
        compares by the Laplace approximation.
    """

    method: str = "nuts"
    n_components: int | None = None
    k_max: int = 5
    num_warmup: int = 1000
    num_samples: int = 1000
    num_chains: int = 4
    n_bootstrap: int = 200
    stationary_start: bool = True
    exact: bool = True
    arrivals: str = "auto"
    lifetimes: str = "auto"
    positions: str = "auto"
    compare: str = "laplace"

    def __post_init__(self) -> None:

        check_in("method", self.method, ("nuts", "em"))
        check_in("compare", self.compare, ("laplace", "nuts"))
        check_in("exact", self.exact, (True, False))
        check_in("arrivals", self.arrivals, ARRIVAL_CHOICES)
        check_in("lifetimes", self.lifetimes, LIFETIME_CHOICES)
        check_in("positions", self.positions, POSITION_CHOICES)
        for name in ("k_max", "num_samples", "num_chains", "n_bootstrap"):
            if int(check_nonneg_int(name, getattr(self, name), ndim=0)) < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {getattr(self, name)!r}")
        check_nonneg_int("num_warmup", self.num_warmup, ndim=0)
        if self.n_components is not None:
            if int(check_nonneg_int("n_components", self.n_components, ndim=0)) < 1:
                raise ValueError(f"n_components: expected an integer >= 1, got {self.n_components}")


#: Bytes a posterior draw of the life-cycle model holds while a fit builds its InferenceData
#: (its variables, sampler statistics and copies; 64 float64 values).
BYTES_PER_DRAW = 8.0 * 64
#: Leapfrog steps per NUTS draw assumed by the work estimate (tree depth about 4).
LEAPFROG_STEPS_PER_DRAW = 16.0
#: Work per leapfrog step beyond one per artefact (the priors, the mixture's marks).
STEP_OVERHEAD = 64.0


def check_fit_size(
    settings: FitSettings, n_rows: int, names: Mapping[str, str] | None = None
) -> None:
    """Refuse a fit whose draws or NUTS work pass the limits of :mod:`are_stats.inputs`,
    before anything is sampled.

    The posterior holds ``S = num_samples * num_chains`` draws of about
    :data:`BYTES_PER_DRAW` bytes each (both methods). ``method="nuts"`` also runs
    ``num_chains * (num_warmup + num_samples)`` NUTS iterations of about
    :data:`LEAPFROG_STEPS_PER_DRAW` leapfrog steps, each over the ``n_rows`` stays and
    marks plus :data:`STEP_OVERHEAD`:

    ``work = num_chains * (num_warmup + num_samples) * 16 * (n_rows + 64)``.

    Parameters
    ----------
    settings : FitSettings
        The sampler settings.
    n_rows : int
        Artefacts (rows) of the log (``LifecycleData.n``).
    names : mapping of str to str, optional
        What the error calls ``num_samples``, ``num_warmup`` and ``num_chains`` (the CLI
        passes its options ``--samples``, ``--warmup``, ``--chains``); default the field
        names.

    Raises
    ------
    are_stats.inputs.LimitError
        Naming the settings and the estimate (``check_memory`` / ``check_work``).

    Examples
    --------
    >>> check_fit_size(FitSettings(num_samples=10, num_chains=2, num_warmup=5), 36)
    """
    named = {f: f for f in ("num_samples", "num_warmup", "num_chains")}
    named.update(names or {})
    draws = float(settings.num_samples) * float(settings.num_chains)
    check_memory(
        draws * BYTES_PER_DRAW,
        f"{draws:.3g} posterior draws",
        f"{named['num_samples']}, {named['num_chains']}",
    )
    if settings.method == "nuts":
        iterations = float(settings.num_chains) * float(settings.num_warmup + settings.num_samples)
        check_work(
            iterations * LEAPFROG_STEPS_PER_DRAW * (float(n_rows) + STEP_OVERHEAD),
            f"NUTS on {n_rows} artefacts",
            f"{named['num_samples']}, {named['num_warmup']}, {named['num_chains']}",
        )


def choose_n_components(key: jax.Array, marks: np.ndarray, k_max: int) -> tuple[int, list[float]]:
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
    key: jax.Array, data: LifecycleData, priors: LifecyclePriors, k: int | None, s: FitSettings
) -> tuple[dict, dict, dict]:
    """Conjugate rate draws and bootstrap (or conjugate) mixture draws, shaped (1, S, ...)."""
    n_draws = s.num_samples * s.num_chains
    k_rate, k_mix, k_boot = split_key(key, 3)
    rng = np.random.default_rng(np.asarray(jax.random.key_data(k_rate)).ravel().tolist())
    arr = conjugate_arrival_rate(data, priors)
    lea = conjugate_leave_rate(data, priors)
    post: dict[str, np.ndarray] = {
        "arrival_rate": rng.gamma(arr.shape, 1.0 / arr.rate, n_draws),
        "leave_rate": rng.gamma(lea.shape, 1.0 / lea.rate, n_draws),
    }
    stats: dict[str, np.ndarray] = {}
    attrs: dict[str, object] = {}
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
                    values, k, fold_in_key(k_boot, b), counts=resampled, n_restarts=4
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


def _em_log_likelihood(
    data: LifecycleData, post: dict, k: int | None, stationary_start: bool = False
) -> dict[str, np.ndarray]:
    """Log-likelihood terms of :func:`~are_stats.traffic.lifecycle_model` without the stays.

    ``n_arrivals``: Poisson(lambda * area * T) of the observed count, per draw;
    ``n_present`` (``stationary_start``): Poisson(lambda * area / mu) of the count at ``t0``;
    ``mark_histogram``: count x log-probability of each distinct mark (mixture of eq. 1) or,
    with labels, of each distinct (class, mark) pair (complete data), per draw.
    """
    s = data.summary
    lam = np.asarray(post["arrival_rate"], dtype=float)
    rate = lam * (s.area * s.duration)
    n = float(s.n_arrivals)
    out = {"n_arrivals": xlogy(n, rate) - rate - gammaln(n + 1.0)}
    if stationary_start:
        present = lam * s.area / np.asarray(post["leave_rate"], dtype=float)
        n0 = float(s.n_present)
        out["n_present"] = xlogy(n0, present) - present - gammaln(n0 + 1.0)
    if k is None or not s.mark_values.size:
        return out
    w = np.asarray(post["mix_weights"], dtype=float)
    r = np.asarray(post["mix_rates"], dtype=float)
    if data.labels is not None:
        lab, x = np.asarray(s.pair_labels), np.asarray(s.pair_marks, dtype=float)
        check_memory(w.shape[0] * w.shape[1] * x.size * 8.0 * 4, "the mark log-likelihood")
        rl = r[..., lab]
        logp = np.log(w[..., lab]) + xlogy(x, rl) - rl - gammaln(x + 1.0)
        out["mark_histogram"] = np.asarray(s.pair_counts, dtype=float) * logp
    else:
        x = np.asarray(s.mark_values, dtype=float)
        check_memory(r.size * x.size * 8.0 * 4, "the mark log-likelihood")
        joint = (
            np.log(w)[..., None, :]
            + xlogy(x[:, None], r[..., None, :])
            - r[..., None, :]
            - gammaln(x + 1.0)[:, None]
        )
        out["mark_histogram"] = np.asarray(s.mark_counts, dtype=float) * logsumexp(joint, -1)
    return out


def _stays_total(data: LifecycleData, leave_rate: np.ndarray) -> np.ndarray:
    """Sum over artefacts of the stays log-likelihood, for every draw of ``leave_rate``."""
    n_departed = float(np.sum(~data.censored))
    exposure = float(np.sum(data.dwell))
    mu = np.asarray(leave_rate, dtype=float)
    return n_departed * np.log(mu) - mu * exposure


def _em_inference_data(
    key: jax.Array,
    data: LifecycleData,
    priors: LifecyclePriors,
    k: int | None,
    post: dict[str, np.ndarray],
    stats: dict[str, np.ndarray],
    mix_attrs: Mapping[str, object],
    stationary_start: bool = False,
    label: str = "em",
) -> az.InferenceData:
    """The InferenceData of closed-form draws (the em fit's, or the exact posterior's of
    ``method="nuts"``, ``label="exact"``): draws, likelihood terms and predictive counts."""
    # the likelihood without its per-artefact stays: what is stored scales with the
    # distinct data (window counts, distinct marks), not draws x rows; the stays are
    # recomputed on demand from leave_rate and the observed dwell times (fit_loo). The
    # terms and the predictive counts are closed forms in NumPy: numpyro's Predictive
    # and log_likelihood would compile an XLA program per fit for microseconds of work.
    loglik = _em_log_likelihood(data, post, k, stationary_start)
    # total log-likelihood of each draw (a diagnostic; these draws are not MCMC); the
    # stays add n_departed log(mu) - mu sum(dwell), never expanded per artefact
    stays = _stays_total(data, post["leave_rate"])
    stats = dict(stats)
    stats["log_likelihood_total"] = stays + sum(
        v.reshape(v.shape[:2] + (-1,)).sum(-1) for v in loglik.values()
    )
    kp, kq = split_key(key)
    post_pred = _predictive_counts(numpy_rng(kp), post, data, stationary_start)
    prior = prior_predictive(
        kq,
        priors,
        data.window,
        data.area,
        1000,
        n_components=k,
        stationary_start=stationary_start,
        labelled=data.labels is not None,
    )
    arviz_log = logging.getLogger("arviz")
    level = arviz_log.level
    arviz_log.setLevel(logging.ERROR)  # one "chain" of draws is expected here
    try:
        idata = _inference_data(
            data, priors, k, stationary_start, label, post, stats, loglik, post_pred, prior, {}
        )
    finally:
        arviz_log.setLevel(level)
    idata.posterior.attrs.update(mix_attrs)
    idata.posterior.attrs["model"] = (
        "are_stats.traffic.lifecycle_model (conjugate + EM)"
        if label == "em"
        else "are_stats.traffic.lifecycle_model (exact posterior draws)"
    )
    return idata


def fit_lifecycle_data(
    key: jax.Array,
    data: LifecycleData,
    settings: FitSettings = FitSettings(),  # noqa: B008 (frozen, immutable)
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    counts_panel: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Callable[[str], object] | None = None,
    class_labels: Sequence[str] | None = None,
    grid: OccupancyGrid | None = None,
    clock_start: str | None = None,
    classes: npt.ArrayLike | None = None,
    *,
    setting_names: Mapping[str, str] | None = None,
) -> az.InferenceData:
    """Fit arrival rate, leave rate and mark mixture of a validated life-cycle log, with
    the chosen traffic models and the classes of a labelled log (the statistics of
    :func:`~are_stats.fitting.fit_log`).

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
        ``birth_death_*``: model-based ``birth_death_stderr``, robust
        ``birth_death_stderr_robust`` with ``birth_death_log_cov_robust`` (4,) and
        ``birth_death_stderr_method``; :func:`~are_stats.fitting.compare_panel` compares
        them with the life-cycle posterior).
    progress : callable, optional
        ``progress(message)`` is called at each stage (the CLI shows it). One with a
        ``left(seconds, words)`` method (:class:`~are_stats._stage_clock.StageClock`) is
        also told the NUTS fits' estimated time left (:func:`~are_stats.fitting.clock_progress`).
    class_labels : sequence of str, optional
        Names of the classes ``0..K-1`` of a labelled log (stored as the comma-separated
        attribute ``class_labels``; see ``LifecycleLog.to_arrays()["label_names"]``).
    grid : OccupancyGrid, optional
        The scene's map: the learned entry/exit densities live on its free cells.
    clock_start : str, optional
        ISO 8601 wall-clock time of ``t = 0`` (time-of-day models need it).
    classes : (n,) int, optional
        The class of each row of a log that names its classes but has no marks
        (:meth:`are_stats.logs.LifecycleLog.label_classes`; ``class_labels`` names them):
        the class shares and per-class stays are fitted (:func:`fit_classes`, stored by
        :func:`attach_classes`) after the pooled model, under its stay law. A log with
        marks keeps the mixture, its labels as components (``data.labels``).
    setting_names : mapping of str to str, optional
        What a size error calls the sampler settings (:func:`check_fit_size`: the draws
        and the NUTS work are checked against the limits first).

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (``arrival_rate``, ``leave_rate``, ``mix_weights``,
        ``mix_rates``), ``sample_stats``, ``log_likelihood``, ``observed_data``, ``prior``
        (and ``posterior_predictive`` / ``prior_predictive`` window counts); attributes
        ``model``, ``method``, ``window``, ``area``, ``are_stats_version``, ``n_components``,
        and the chosen traffic models ``arrival_model``, ``lifetime_model``,
        ``position_model`` with their comparison tables (``loo_arrivals``, ...: CSV text);
        the chosen models' parameters sit beside the paper's in ``posterior``, the entry
        and exit densities in ``constant_data`` (see :func:`attach_traffic`).
    """
    if not isinstance(data, LifecycleData):
        raise ValueError(f"data: expected a LifecycleData, got {describe(data)}")
    check_fit_size(settings, data.n, setting_names)
    say = progress or (lambda _msg: None)
    paper_only = (settings.arrivals, settings.lifetimes, settings.positions) == (
        "poisson",
        "exponential",
        "uniform",
    )
    # em compiles no NUTS program: the candidates by the Laplace approximation; nuts ranks
    # them so too (unless told otherwise) and samples the chosen
    approximation = (
        "laplace"
        if settings.method == "em"
        else "ranked"
        if settings.compare == "laplace"
        else "nuts"
    )
    # the candidates' Laplace programs compile in two threads from here, while the paper's
    # model is drawn (a first fit of the shipped log: most of its CPU is those compiles)
    ahead = LaplaceAhead(None)
    if not paper_only and approximation != "nuts":
        ahead = compile_laplace_ahead(
            fold_in_key(key, 14),
            data,
            arrivals=settings.arrivals,
            lifetimes=settings.lifetimes,
            clock_start=clock_start,
        )
    with ahead:
        k_choice, k_fit, k_post = split_key(key, 3)
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
        em_draws = None  # closed-form draws whose InferenceData is built later (a thread)
        exact = settings.method == "nuts" and settings.exact and has_exact_posterior(data, k)
        if exact:
            say("the paper's model: exact posterior draws (closed form, no NUTS)")
            post = exact_lifecycle_draws(
                k_fit,
                data,
                priors,
                n_components=k,
                num_samples=settings.num_samples,
                num_chains=settings.num_chains,
                stationary_start=settings.stationary_start,
            )
            words = "exact: Gamma conditionals, leave_rate by rejection from a log-concave envelope"
            em_draws = (
                k_post,
                data,
                priors,
                k,
                post,
                {},
                {} if k is None else {"mixture_method": "conjugate posterior (closed form)"},
                settings.stationary_start,
                "exact",
            )
        elif settings.method == "nuts":
            words = "nuts"
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
            em_draws = (k_post, data, priors, k, post, stats, mix_attrs)
        attrs = {
            "method": settings.method,
            "paper_posterior": words if settings.method == "nuts" else "conjugate + EM",
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
                # robust (HAC) errors and the log-rate covariance: see compare_panel
                birth_death_stderr_robust=np.asarray(bd.stderr_robust, dtype=float),
                birth_death_log_cov_robust=np.asarray(bd.log_cov_robust, dtype=float).ravel(),
                birth_death_stderr_method=f"{bd.stderr_method}, {bd.bandwidth} lags",
                birth_death_loglik=bd.loglik,
                birth_death_n_obs=int(bd.n_obs),
            )
        traffic = None
        if paper_only and em_draws is not None:
            idata = _em_inference_data(*em_draws)
        elif not paper_only:
            # the em fit's InferenceData (ArviZ's import, its groups) is built in a thread while
            # the traffic models sample: the devices wait on neither. xarray's dask support is
            # imported first, in this thread alone (two threads importing it race)
            import_xarray_dask()
            with ThreadPoolExecutor(1, "are-stats-idata") as pool:
                pending = None
                if em_draws is not None:
                    paper = em_draws[4]
                    pending = pool.submit(_em_inference_data, *em_draws)
                else:
                    paper = idata.posterior
                traffic = fit_traffic(
                    fold_in_key(key, 14),
                    data,
                    paper={n: np.asarray(paper[n]) for n in ("arrival_rate", "leave_rate")},
                    arrivals=settings.arrivals,
                    lifetimes=settings.lifetimes,
                    positions=settings.positions,
                    grid=grid,
                    clock_start=clock_start,
                    num_warmup=settings.num_warmup,
                    num_samples=settings.num_samples,
                    num_chains=settings.num_chains,
                    progress=say,
                    approximation=approximation,
                )
                if pending is not None:
                    idata = pending.result()
        idata.posterior.attrs.update(attrs)
        if clock_start is not None:
            idata.posterior.attrs["traffic_clock_start"] = str(clock_start)
        if traffic is None:
            idata.posterior.attrs.update(
                arrival_model="poisson", lifetime_model="exponential", position_model="uniform"
            )
        else:
            idata = attach_traffic(idata, traffic)
        if classes is not None:
            idata = _fit_classes(fold_in_key(key, 31), idata, data, classes, class_labels, say)
            idata = _fit_class_traffic(
                fold_in_key(key, 32),
                idata,
                data,
                np.asarray(classes, np.int64),
                class_labels,
                grid,
                clock_start,
                say,
            )
    return idata


def _fit_classes(
    key: jax.Array,
    idata: az.InferenceData,
    data: LifecycleData,
    classes: npt.ArrayLike,
    labels: Sequence[str] | None,
    say: Callable[[str], object],
) -> az.InferenceData:
    """The class shares and per-class stays of a labelled log, under the pooled stay law."""
    if labels is None:
        raise ValueError("class_labels: expected the names of the classes given by classes=")
    if data.marks is not None:
        raise ValueError("classes: expected a log without marks (marks keep the mixture)")
    post = idata.posterior
    law = str(post.attrs.get("lifetime_model", "exponential"))
    res = post.attrs.get("traffic_time_resolution")
    if res is None:
        res = time_resolution(data.t_arrive, data.t_leave, list(data.window))
    say(f"class shares and per-class stays ({len(labels)} classes, {law} stays)")
    n_draws = post.sizes["chain"] * post.sizes["draw"]
    cfit = fit_classes(
        key,
        data,
        np.asarray(classes, np.int64),
        labels,
        law=law,
        n_draws=n_draws,
        resolution=float(np.asarray(res).ravel()[0]),
    )
    return attach_classes(idata, cfit)


def _fit_class_traffic(
    key: jax.Array,
    idata: az.InferenceData,
    data: LifecycleData,
    classes: np.ndarray,
    labels: Sequence[str],
    grid: OccupancyGrid | None,
    clock_start: str | None,
    say: Callable[[str], object],
) -> az.InferenceData:
    """Where (entry/exit densities per class, with a map and positions) and when (shares by
    time of day, with a clock) each class of a labelled log comes (issue 31)."""
    entered = ~data.truncated
    if (
        grid is not None
        and abs(float(grid.origin[2])) <= 1e-9
        and data.x is not None
        and data.y is not None
        and entered.sum() >= 2
    ):
        say(f"entry and exit densities per class ({len(labels)} classes)")
        free, res = coarse_free(grid.free, grid.resolution, POSITION_CELL)
        origin = (float(grid.origin[0]), float(grid.origin[1]))
        xy = np.column_stack([data.x, data.y])[entered]
        cls = classes[entered]
        if data.group is not None:  # one entry point per group, as the pooled density's
            _, first = np.unique(np.asarray(data.group)[entered], return_index=True)
            xy, cls = xy[np.sort(first)], cls[np.sort(first)]
        exy = ecls = None
        if data.x_exit is not None and data.y_exit is not None:
            ok = np.isfinite(data.x_exit) & np.isfinite(data.y_exit)
            exy, ecls = np.column_stack([data.x_exit, data.y_exit])[ok], classes[ok]
        pos = fit_class_positions(
            xy, cls, labels, free, res, origin, exit_xy=exy, exit_classes=ecls
        )
        idata = attach_class_positions(idata, pos)
    if clock_start is not None:
        say("class shares by time of day")
        w = idata.posterior["class_weights"].values
        shares = fit_class_shares_by_time(
            key,
            data.t_arrive[entered],
            classes[entered],
            w.reshape(-1, w.shape[-1]),
            clock_offset(clock_start),
        )
        idata = attach_class_shares_by_time(idata, shares)
    return idata


def attach_behaviour(idata: az.InferenceData, behaviour: BehaviourFit) -> az.InferenceData:
    """Store a :class:`~are_stats.behaviour.BehaviourFit` as the fit's ``behaviour`` group.

    ``are-stats generate --behaviours`` reads it back
    (:meth:`~are_stats.behaviour.BehaviourFit.from_dataset`) and walks the artefacts with
    the fitted speeds, exits and soft policy.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a group beyond ArviZ's schema
        # the fit's wall-clock seconds would make the same seed give other bytes
        ds = behaviour.to_dataset().drop_vars("fit_seconds", errors="ignore")
        idata.add_groups({"behaviour": ds})
    return idata


def attach_traffic(idata: az.InferenceData, traffic: TrafficFit) -> az.InferenceData:
    """Store a :class:`~are_stats.fitting.TrafficFit` in a fit.

    ``posterior`` gains the chosen models' variables (``event_rate``, ``arrival_phi``,
    ``arrival_tod`` over ``period``, ``group_size_probs`` over ``group_size``,
    ``stay_mean``, ``stay_shape``) and the attributes ``arrival_model``,
    ``lifetime_model``, ``position_model``, the generator's settings (``traffic_*``) and
    the comparison tables ``loo_arrivals``, ``loo_lifetimes``, ``loo_positions`` (CSV
    text) and ``traffic_warnings``; ``constant_data`` gains ``entry_density`` and
    ``exit_density`` over ``(pos_y, pos_x)`` with their ``position_resolution`` and
    ``position_origin``.
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    post = idata.posterior
    for name, v in traffic.posterior.items():
        dims = ("chain", "draw", *traffic.dims.get(name, []))
        post[name] = xr.DataArray(np.asarray(v, dtype=np.float64), dims=dims)
    a = post.attrs
    a["arrival_model"] = traffic.arrival_model
    a["lifetime_model"] = traffic.lifetime_model
    a["position_model"] = traffic.position_model
    for k, v in traffic.attrs.items():
        a[f"traffic_{k}"] = v
    for k, table in traffic.tables.items():
        a[f"loo_{k}"] = table.to_csv(float_format="%.6g")
    a["traffic_warnings"] = "\n".join(traffic.warnings)
    dens = {}
    for name, d in (("entry_density", traffic.entry), ("exit_density", traffic.exit)):
        if d is not None:
            dens[name] = xr.DataArray(np.asarray(d.prob, np.float64), dims=("pos_y", "pos_x"))
    if dens:
        ref = traffic.entry if traffic.entry is not None else traffic.exit
        ds = xr.Dataset(dens)
        ds.attrs.update(
            position_resolution=float(ref.resolution),
            position_origin=np.asarray(ref.origin, np.float64),
            position_bandwidth=float(traffic.entry.bandwidth) if traffic.entry else 0.0,
        )
        if "constant_data" in idata.groups():
            merged = idata.constant_data.merge(ds)
            merged.attrs.update(idata.constant_data.attrs | ds.attrs)
            idata.constant_data = merged
        else:
            idata.add_groups({"constant_data": ds})
    return idata


#: Attributes that record when or how fast a fit ran, not what it is: :func:`write_fit`
#: leaves them out so that the same seed gives the same bytes (``created_at`` of every
#: group, ArviZ's; ``*_time`` of ``sample_stats``, the NUTS timings kept in memory).
VOLATILE_ATTRS = ("created_at", "*_time")


def _stable(idata: az.InferenceData) -> az.InferenceData:
    """A shallow copy of ``idata`` without :data:`VOLATILE_ATTRS`."""
    groups = {}
    for name in idata.groups():
        ds = getattr(idata, name).copy(deep=False)
        ds.attrs = {
            k: v for k, v in ds.attrs.items() if k != "created_at" and not k.endswith("_time")
        }
        groups[name] = ds
    return az.InferenceData(**groups)


#: The NetCDF layer under xarray (h5netcdf with h5py, 0.13-0.21 s of CPU to import; ``import
#: are_stats.fitting`` has no xarray yet), opened with its HDF5 look-ups memoised
#: (:func:`~are_stats.fitting._netcdf_file.open_netcdf`): imported when a fit is written or
#: read.
_netcdf_file = LazyModule("are_stats.fitting._netcdf_file")
_xr_backends = LazyModule("xarray.backends")


def _compressible(dtype: np.dtype) -> bool:
    """Whether a variable of ``dtype`` is stored zlib-compressed: ArviZ's rule in
    ``InferenceData.to_netcdf(compress=True)`` (booleans, numbers, byte strings)."""
    if dtype.kind == "V":
        return all(_compressible(field) for field, _ in dtype.fields.values())
    return dtype.kind in {"b", "i", "u", "f", "c", "S"}


def _write_groups(idata: az.InferenceData, path: Path) -> None:
    """Write ``idata``'s groups to the NetCDF file ``path`` through one open file.

    The file is what ``idata.to_netcdf(path)`` writes (one NetCDF group per
    InferenceData group, in order, compressed by ArviZ's rule, no root attributes when
    ``idata`` has none): ArviZ reopens the file for each group, and h5netcdf walks it at
    every open.
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    with _netcdf_file.open_netcdf(path, "w") as f:
        if idata.attrs:  # the InferenceData's own attributes, on the root group
            xr.Dataset(attrs=idata.attrs).dump_to_store(_xr_backends.H5NetCDFStore(f, mode="a"))
        for name in idata.groups():
            ds = getattr(idata, name)
            encoding = {
                k: {"zlib": True} for k, v in ds.variables.items() if _compressible(v.dtype)
            }
            ds.dump_to_store(_xr_backends.H5NetCDFStore(f, group=name, mode="a"), encoding=encoding)


#: The groups :func:`read_fit` checks (:func:`_check_fit`): read before the others, so
#: that a fit it refuses (a newer format, a bad posterior) is refused without them.
_CHECKED_GROUPS = ("posterior", "observed_data", "constant_data")


def _root_attrs(f: object) -> dict[str, object]:
    """The root group's attributes of the open NetCDF file ``f`` (InferenceData's own)."""
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    return dict(xr.open_dataset(_xr_backends.H5NetCDFStore(f, mode="r")).attrs)


def _load_group(f: object, name: str) -> xr.Dataset:
    """Group ``name`` of the open NetCDF file ``f``, loaded into memory."""
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    return xr.open_dataset(_xr_backends.H5NetCDFStore(f, group=name, mode="r")).load()


def _read_groups(path: Path) -> az.InferenceData:
    """Read every group of the NetCDF fit ``path`` through one open file, into memory.

    The same InferenceData as ``arviz.from_netcdf(path)`` (groups in the file's order,
    the root group's attributes as its ``attrs``), loaded: the file is closed on return.
    """
    with _netcdf_file.open_netcdf(path) as f:
        attrs = _root_attrs(f)
        groups = {name: _load_group(f, name) for name in f.groups}
    return az.InferenceData(attrs=attrs, **groups)


#: Format of the fits this version writes (the posterior attribute ``format_version``).
#: :func:`read_fit` refuses a newer one and reads a fit without one as format 1, with a
#: :class:`FitFormatWarning`.
FIT_FORMAT_VERSION = 1


class FitFormatWarning(FutureWarning):
    """A fit file without a format version (written before fits carried one)."""


def write_fit(
    idata: az.InferenceData | Fit, out: str | os.PathLike[str], force: bool = False
) -> Path:
    """Write a fit as NetCDF atomically (temporary file + rename); refuse to overwrite.

    The posterior carries ``format_version`` (:data:`FIT_FORMAT_VERSION`).

    The file holds no wall-clock attribute (:data:`VOLATILE_ATTRS` are left out), so the
    same fit gives the same bytes. An interrupted or failed write (a full disk) leaves no
    file under the final name and an existing one intact.

    Parameters
    ----------
    idata : Fit or arviz.InferenceData
        The fit (:func:`~are_stats.fitting.fit_log`).
    out : str or Path
        Destination ``.nc`` file.
    force : bool
        Overwrite an existing file.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    path = Path(out)
    stable = _stable(idata.idata if isinstance(idata, Fit) else idata)
    stable.posterior.attrs["format_version"] = FIT_FORMAT_VERSION
    with atomic_path(path, force=force) as tmp:
        _write_groups(stable, tmp)
    return path


def _check_format(attrs: Mapping[str, object], source: str) -> None:
    """Refuse a fit of a newer format; warn about a fit written before formats had numbers."""
    if "format_version" not in attrs:
        warnings.warn(
            f"{source}: the fit has no format_version (written before fits carried one): read "
            f"as format 1; fit the log again to stamp it",
            FitFormatWarning,
            stacklevel=3,
        )
        return
    v = np.asarray(attrs["format_version"]).ravel()
    if v.size != 1 or v.dtype.kind not in "iu":
        raise InputError(
            source,
            "posterior.attrs.format_version",
            "an integer",
            Described(f"{attrs['format_version']!r}"),
        )
    if int(v[0]) > FIT_FORMAT_VERSION or int(v[0]) < 1:
        raise InputError(
            source,
            "posterior.attrs.format_version",
            f"a fit format are_stats {__version__} reads (1 to {FIT_FORMAT_VERSION}; a newer "
            "format was written by a newer are_stats: upgrade it, or fit the log again)",
            int(v[0]),
        )


def _var(
    ds: xr.Dataset, name: str, source: str, group: str, dims: tuple[str, ...] | None
) -> np.ndarray:
    """Variable ``name`` of ``ds`` as an array, checked for presence and dimensions."""
    if name not in ds.data_vars:
        raise InputError(
            source,
            f"{group}.{name}",
            "this variable (a fit written by are-stats fit)",
            Described(f"variables {sorted(ds.data_vars)}"),
        )
    var = ds[name]
    if dims is not None and tuple(var.dims) != dims:
        raise InputError(
            source,
            f"{group}.{name}",
            f"dimensions {dims}",
            Described(f"dimensions {tuple(var.dims)}"),
        )
    return np.asarray(var.values)


#: Largest Poisson rate NumPy draws from (marks beyond would overflow int64).
MAX_MARK_RATE = 1e18


def _check_real(
    a: np.ndarray, source: str, where: str, *, lo: float, lo_open: bool, hi: float = np.inf
) -> None:

    word = ">" if lo_open else ">="
    word_hi = f" and <= {hi:g}" if np.isfinite(hi) else ""
    if a.dtype.kind not in "fiu" or a.dtype.kind == "b":
        raise InputError(
            source, where, f"finite numbers {word} {lo:g}{word_hi}", Described(f"dtype {a.dtype}")
        )
    bad = ~np.isfinite(a) | (a <= lo if lo_open else a < lo) | (a > hi)
    if bad.any():
        idx = np.unravel_index(int(np.argmax(bad)), a.shape)
        raise InputError(
            source,
            f"{where}{[int(i) for i in idx]}",
            f"finite numbers {word} {lo:g}{word_hi}",
            Described(f"{a[idx].item()!r} (in {describe(a)})"),
        )


def _check_fit(idata: az.InferenceData, source: str, groups: Sequence[str] | None = None) -> None:
    """Validate a fit read from ``source`` (groups, variables, attributes).

    ``idata`` needs only the groups of :data:`_CHECKED_GROUPS`; ``groups`` names all the
    file's groups (for the error of a missing one; default: ``idata``'s).
    """
    groups = list(idata.groups()) if groups is None else list(groups)
    for group in ("posterior", "observed_data"):
        if group not in groups:
            raise InputError(
                source,
                group,
                "this group (a fit written by are-stats fit)",
                Described(f"groups {groups}"),
            )
    post = idata.posterior
    _check_format(post.attrs, source)
    rates = {}
    for name in ("arrival_rate", "leave_rate"):
        rates[name] = _var(post, name, source, "posterior", ("chain", "draw"))
        _check_real(rates[name], source, f"posterior.{name}", lo=0.0, lo_open=True)
    if rates["arrival_rate"].size == 0:
        raise InputError(source, "posterior.arrival_rate", "at least one draw", Described("none"))
    has_w, has_r = "mix_weights" in post.data_vars, "mix_rates" in post.data_vars
    if has_w != has_r:
        raise InputError(
            source,
            "posterior",
            "both mix_weights and mix_rates or neither",
            Described(f"variables {sorted(post.data_vars)}"),
        )
    k = None
    if has_w:
        dims = ("chain", "draw", "component")
        w = _var(post, "mix_weights", source, "posterior", dims)
        r = _var(post, "mix_rates", source, "posterior", dims)
        _check_real(w, source, "posterior.mix_weights", lo=0.0, lo_open=False)
        _check_real(r, source, "posterior.mix_rates", lo=0.0, lo_open=True, hi=MAX_MARK_RATE)
        k = w.shape[-1]
        if k < 1 or r.shape[-1] != k:
            raise InputError(
                source, "posterior.mix_rates", f"{k} components (as mix_weights)", r.shape[-1]
            )
        sums = w.sum(axis=-1)
        bad = np.abs(sums - 1.0) > 1e-6
        if bad.any():
            c, d = np.unravel_index(int(np.argmax(bad)), bad.shape)
            raise InputError(
                source,
                f"posterior.mix_weights[{c}, {d}]",
                "weights summing to 1",
                Described(f"a sum of {float(sums[c, d])!r}"),
            )
    attrs = post.attrs
    for name in ("window", "area"):
        if name not in attrs:
            raise InputError(
                source,
                f"posterior.attrs.{name}",
                "this attribute (a fit written by are-stats fit)",
                Described(f"attributes {sorted(attrs)}"),
            )
    win = np.asarray(attrs["window"]).ravel().tolist()
    win = get_list(win, source, "posterior.attrs.window", min_len=2, max_len=2)
    t0 = get_float(win[0], source, "posterior.attrs.window[0]")
    get_float(win[1], source, "posterior.attrs.window[1]", lo=t0, lo_open=True)
    area = attrs["area"]
    area = area.item() if isinstance(area, np.ndarray) and area.size == 1 else area
    get_float(area, source, "posterior.attrs.area", lo=0.0, lo_open=True)
    if "method" in attrs:
        get_str(attrs["method"], source, "posterior.attrs.method", choices=("nuts", "em"))
    if "n_components" in attrs:
        get_int(attrs["n_components"], source, "posterior.attrs.n_components", lo=-1)
    if "class_labels" in attrs:
        labels = get_str(attrs["class_labels"], source, "posterior.attrs.class_labels")
        if k is not None and len(labels.split(",")) != k:
            raise InputError(
                source,
                "posterior.attrs.class_labels",
                f"{k} comma-separated names (one per mixture component)",
                labels,
            )
    _check_traffic(idata, source)
    _check_classes(idata, source)
    obs = idata.observed_data
    cols = {
        name: _var(obs, name, source, "observed_data", ("artefact",))
        for name in ("t_arrive", "t_leave", "censored", "truncated")
    }
    if "marks" in obs.data_vars:
        cols["marks"] = _var(obs, "marks", source, "observed_data", ("artefact",))
    for name in ("censored", "truncated"):
        if cols[name].dtype.kind != "b":
            raise InputError(
                source, f"observed_data.{name}", "booleans", Described(f"dtype {cols[name].dtype}")
            )
    for name in ("t_arrive", "t_leave"):
        if cols[name].dtype.kind != "f":
            raise InputError(
                source,
                f"observed_data.{name}",
                "floats (NaN where unobserved)",
                Described(f"dtype {cols[name].dtype}"),
            )
    if "marks" in cols:
        _check_real(cols["marks"], source, "observed_data.marks", lo=0.0, lo_open=False)
        if cols["marks"].dtype.kind not in "iu":
            raise InputError(
                source, "observed_data.marks", "integers", Described(f"dtype {cols['marks'].dtype}")
            )
    for name, flag in (("t_arrive", "truncated"), ("t_leave", "censored")):
        mismatch = np.isnan(cols[name]) != cols[flag]
        if mismatch.any():
            i = int(np.argmax(mismatch))
            raise InputError(
                source,
                f"observed_data.{flag}[{i}]",
                f"{flag} exactly where {name} is NaN",
                Described(f"{bool(cols[flag][i])} with {name} {float(cols[name][i])!r}"),
            )
    try:  # the value checks of a log (times inside the window, leave after arrival)
        LifecycleData(
            t_arrive=cols["t_arrive"],
            t_leave=cols["t_leave"],
            window=(float(win[0]), float(win[1])),
            area=float(area),
            marks=cols.get("marks"),
        )
    except ValueError as err:
        raise InputError(source, "observed_data", f"a valid life-cycle log ({err})") from None


def _check_traffic(idata: az.InferenceData, source: str) -> None:
    """The chosen traffic models of a fit and the variables they need (when recorded)."""
    post = idata.posterior
    attrs = post.attrs
    arr = get_str(
        attrs.get("arrival_model", "poisson"),
        source,
        "posterior.attrs.arrival_model",
        choices=ARRIVAL_SPECS,
    )
    life = get_str(
        attrs.get("lifetime_model", "exponential"),
        source,
        "posterior.attrs.lifetime_model",
        choices=STAY_LAWS,
    )
    pos = get_str(
        attrs.get("position_model", "uniform"),
        source,
        "posterior.attrs.position_model",
        choices=("uniform", "learned"),
    )
    spec = ArrivalSpec.from_name(arr)
    need: dict[str, tuple[str, ...]] = {}
    if arr != "poisson":
        need["event_rate"] = ("chain", "draw")
    if spec.negbin:
        need["arrival_phi"] = ("chain", "draw")
    if spec.tod:
        need["arrival_tod"] = ("chain", "draw", "period")
    if spec.groups:
        need["group_size_probs"] = ("chain", "draw", "group_size")
    if spec.mmpp:
        need["mmpp_factor"] = ("chain", "draw", "mmpp_state")
        need["mmpp_switch"] = ("chain", "draw", "mmpp_state")
    if spec.hawkes:
        need["hawkes_branching"] = ("chain", "draw")
        need["hawkes_decay"] = ("chain", "draw")
    if life != "exponential":
        need["stay_mean"] = ("chain", "draw")
        need["stay_shape"] = ("chain", "draw")
    for name, dims in need.items():
        v = _var(post, name, source, "posterior", dims)
        _check_real(v, source, f"posterior.{name}", lo=0.0, lo_open=name != "group_size_probs")
    if spec.groups:
        v = np.asarray(post["group_size_probs"].values)
        sums = v.sum(axis=-1)
        if v.shape[-1] < 1 or np.any(np.abs(sums - 1.0) > 1e-6):
            raise InputError(
                source,
                "posterior.group_size_probs",
                "probabilities summing to 1",
                Described(f"sums from {sums.min()!r} to {sums.max()!r}"),
            )
    if spec.negbin:
        get_float_attr(attrs, "traffic_arrival_bin_width", source)
    if spec.tod:
        try:
            clock_offset(str(attrs.get("traffic_clock_start", "")))
        except ValueError as err:
            raise InputError(
                source,
                "posterior.attrs.traffic_clock_start",
                "an ISO 8601 time (the log's clock)",
                Described(str(err)),
            ) from None
    if pos == "learned":
        if "constant_data" not in idata.groups() or "entry_density" not in idata.constant_data:
            raise InputError(
                source,
                "constant_data.entry_density",
                "the learned entry density (position_model is 'learned')",
                Described("none"),
            )
    if "constant_data" in idata.groups():
        cd = idata.constant_data
        for name in ("entry_density", "exit_density"):
            if name in cd:
                v = _var(cd, name, source, "constant_data", ("pos_y", "pos_x"))
                _check_real(v, source, f"constant_data.{name}", lo=0.0, lo_open=False)
                if not abs(float(v.sum()) - 1.0) < 1e-6:
                    raise InputError(
                        source,
                        f"constant_data.{name}",
                        "cell masses summing to 1",
                        Described(f"a sum of {float(v.sum())!r}"),
                    )
        if "entry_density" in cd or "exit_density" in cd:
            get_float_attr(cd.attrs, "position_resolution", source, "constant_data")
            o = np.asarray(cd.attrs.get("position_origin", [np.nan])).ravel()
            if o.size != 2 or not np.isfinite(o).all():
                where = "constant_data.attrs.position_origin"
                raise InputError(
                    source, where, "two finite numbers (x, y)", Described(repr(o.tolist()))
                )


def _check_classes(idata: az.InferenceData, source: str) -> None:
    """The class shares and per-class stays of a labelled log (when recorded)."""
    post = idata.posterior
    if "class_weights" not in post.data_vars:
        return
    dims = ("chain", "draw", "class")
    w = _var(post, "class_weights", source, "posterior", dims)
    m = _var(post, "class_stay_mean", source, "posterior", dims)
    _check_real(w, source, "posterior.class_weights", lo=0.0, lo_open=False)
    _check_real(m, source, "posterior.class_stay_mean", lo=0.0, lo_open=True)
    if "class_stay_shape" in post.data_vars:
        v = _var(post, "class_stay_shape", source, "posterior", ("chain", "draw"))
        _check_real(v, source, "posterior.class_stay_shape", lo=0.0, lo_open=True)
    k = w.shape[-1]
    if m.shape != w.shape:
        raise InputError(
            source,
            "posterior.class_stay_mean",
            f"shape {w.shape} (as class_weights)",
            Described(f"shape {m.shape}"),
        )
    sums = w.sum(axis=-1)
    if np.any(np.abs(sums - 1.0) > 1e-6):
        raise InputError(
            source,
            "posterior.class_weights",
            "shares summing to 1",
            Described(f"sums from {sums.min()!r} to {sums.max()!r}"),
        )
    names = get_str(post.attrs.get("class_labels", ""), source, "posterior.attrs.class_labels")
    if len(names.split(",")) != k or not names:
        raise InputError(
            source,
            "posterior.attrs.class_labels",
            f"{k} comma-separated names (one per class)",
            names,
        )
    get_str(
        post.attrs.get("class_stay_model", ""),
        source,
        "posterior.attrs.class_stay_model",
        choices=("pooled", "per-class"),
    )
    if "class_tod_weights" in post.data_vars:  # shares by time of day (issue 31)
        t = _var(
            post, "class_tod_weights", source, "posterior", ("chain", "draw", "period", "class")
        )
        _check_real(t, source, "posterior.class_tod_weights", lo=0.0, lo_open=False)
        if t.shape[-1] != k or np.any(np.abs(t.sum(axis=-1) - 1.0) > 1e-6):
            raise InputError(
                source,
                "posterior.class_tod_weights",
                f"{k} shares summing to 1 in each period",
                Described(f"{t.shape}"),
            )
        share_model = get_str(
            post.attrs.get("class_share_model", ""),
            source,
            "posterior.attrs.class_share_model",
            choices=("constant", "time-of-day"),
        )
        if share_model == "time-of-day" and "traffic_clock_start" not in post.attrs:
            raise InputError(
                source,
                "posterior.attrs.traffic_clock_start",
                "the log's clock (time-of-day class shares)",
                Described("none"),
            )
    cd = idata.constant_data if "constant_data" in idata.groups() else {}
    if "class_entry_density" in cd:  # entry/exit densities per class (issue 31)
        for name in ("class_entry_density", "class_exit_density"):
            if name not in cd:
                continue
            v = _var(cd, name, source, "constant_data", ("class", "pos_y", "pos_x"))
            _check_real(v, source, f"constant_data.{name}", lo=0.0, lo_open=False)
            if v.shape[0] != k or np.any(np.abs(v.sum(axis=(1, 2)) - 1.0) > 1e-6):
                raise InputError(
                    source,
                    f"constant_data.{name}",
                    f"{k} densities (one per class) summing to 1",
                    Described(f"shape {v.shape}"),
                )
        get_float_attr(cd.attrs, "class_position_resolution", source, "constant_data")
        o = np.asarray(cd.attrs.get("class_position_origin", [np.nan])).ravel()
        if o.size != 2 or not np.isfinite(o).all():
            raise InputError(
                source,
                "constant_data.attrs.class_position_origin",
                "two finite numbers (x, y)",
                Described(repr(o.tolist())),
            )
        get_str(
            post.attrs.get("class_position_model", ""),
            source,
            "posterior.attrs.class_position_model",
            choices=("pooled", "per-class"),
        )


def get_float_attr(
    attrs: Mapping[str, object], name: str, source: str, group: str = "posterior"
) -> float:
    """A finite attribute > 0 of a fit group, named in the error when missing or bad."""
    if name not in attrs:
        raise InputError(
            source,
            f"{group}.attrs.{name}",
            "this attribute",
            Described(f"attributes {sorted(attrs)}"),
        )
    v = attrs[name]
    v = v.item() if isinstance(v, np.ndarray) and v.size == 1 else v
    return get_float(v, source, f"{group}.attrs.{name}", lo=0.0, lo_open=True)


def read_fit(path: str | os.PathLike[str]) -> Fit:
    """Read and validate a fit written by :func:`write_fit` / ``are-stats fit``: the one
    way a fit file enters.

    Everything ``are-stats report`` and ``generate`` use is checked where the file enters:
    the ``posterior`` (positive finite ``arrival_rate`` / ``leave_rate`` over ``(chain,
    draw)``, and ``mix_weights`` summing to 1 with positive ``mix_rates`` over ``(chain,
    draw, component)`` when there is a mixture), its attributes ``window`` (``t0 < t1``)
    and ``area`` (> 0), ``method``, ``n_components``, ``class_labels`` when present, and
    the ``observed_data`` log (``t_arrive``, ``t_leave``, ``censored``, ``truncated``,
    ``marks``).

    Parameters
    ----------
    path : str or Path
        The ``.nc`` file.

    Returns
    -------
    Fit
        The decoded fit (:class:`~are_stats.fitting.Fit`: chosen laws, class labels,
        behaviour, interaction, area, provenance, format version), with the checked
        InferenceData as ``Fit.idata``.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    are_stats.inputs.InputError
        (a ValueError) naming the file, the group/variable/attribute and what was expected,
        if it is not a readable NetCDF fit or any of the above is missing or bad.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such fit file")
    if p.is_dir():
        raise InputError(p, "", "an ArviZ NetCDF fit file, not a directory")
    if not p.is_file():  # a FIFO or a device would block the NetCDF reader
        raise InputError(p, "", "an ArviZ NetCDF fit in a regular file, not a special file")
    source = str(p)
    # the checked groups first (_CHECKED_GROUPS), the posterior's format before them all:
    # opening a group's variables is most of a read (h5netcdf's per-variable dimension
    # lookups), so a refused fit (a newer format, a bad posterior) is refused without the
    # groups it does not need (an unversioned posterior warns once, in _check_fit)
    with _open_fit(p) as f:
        with _unreadable(p):
            attrs = _root_attrs(f)
            names = list(f.groups)
            groups = {"posterior": _load_group(f, "posterior")} if "posterior" in names else {}
        post_attrs = groups["posterior"].attrs if groups else {}
        if "format_version" in post_attrs:  # a newer format is refused before the rest
            _check_format(post_attrs, source)
        with _unreadable(p):
            groups |= {n: _load_group(f, n) for n in names if n in _CHECKED_GROUPS[1:]}
        groups = {n: groups[n] for n in names if n in groups}  # the file's order
        _check_fit(az.InferenceData(attrs=attrs, **groups), source, names)
        with _unreadable(p):
            groups = {n: groups[n] if n in groups else _load_group(f, n) for n in names}
    return fit_from_idata(az.InferenceData(attrs=attrs, **groups), source)


@contextmanager
def _unreadable(path: Path) -> Iterator[None]:
    """An error reading the fit file ``path`` (netCDF/HDF5 raise many types for a file that
    is not a NetCDF fit) as the :class:`~are_stats.inputs.InputError` that names it."""
    try:
        yield
    except Exception as err:
        raise InputError(
            path, "", f"an ArviZ NetCDF fit written by are-stats fit (could not read it: {err})"
        ) from err


@contextmanager
def _open_fit(path: Path) -> Iterator[object]:
    """The fit file ``path`` open for reading (an ``h5netcdf.File``), closed on exit."""
    with ExitStack() as stack:
        with _unreadable(path):
            f = stack.enter_context(_netcdf_file.open_netcdf(path))
        yield f


def _stays_columns(idata: az.InferenceData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct ``(departed, dwell)`` pairs of the observed log, their counts and inverse."""
    obs = idata.observed_data
    dwell = np.asarray(obs["dwell"].values, dtype=np.float64)
    departed = ~np.asarray(obs["censored"].values, dtype=bool)
    pairs, inverse, counts = np.unique(
        np.stack([departed.astype(np.float64), dwell], axis=1),
        axis=0,
        return_inverse=True,
        return_counts=True,
    )
    return pairs, counts.astype(np.float64), inverse.ravel()


def _stays_loglik(mu: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``departed log(mu) - mu dwell`` for (chain, draw) ``mu`` and (m, 2) pairs."""
    return pairs[:, 0] * np.log(mu)[..., None] - mu[..., None] * pairs[:, 1]


def _distinct_loglik(
    idata: az.InferenceData, var_name: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(chain, draw, m) log-likelihood of the m distinct observations, counts and inverse."""
    if var_name == "stays":
        pairs, counts, inverse = _stays_columns(idata)
        mu = np.asarray(idata.posterior["leave_rate"].values, dtype=np.float64)
        check_memory(mu.size * pairs.shape[0] * 8.0 * 3, "the stays log-likelihood per draw")
        return _stays_loglik(mu, pairs), counts, inverse
    if var_name == "marks":
        if "log_likelihood" not in idata.groups() or "mark_histogram" not in idata.log_likelihood:
            raise ValueError("idata: expected log_likelihood.mark_histogram (a fit with marks)")
        hist = np.asarray(idata.log_likelihood["mark_histogram"].values, dtype=np.float64)
        counts = np.asarray(idata.observed_data["mark_histogram"].values, dtype=np.float64)
        obs = idata.observed_data
        if "pair_class" in obs:
            keys = np.stack([obs["labels"].values, obs["marks"].values], axis=1)
            ref = np.stack([obs["pair_class"].values, obs["pair_mark"].values], axis=1)
        else:
            keys = np.asarray(obs["marks"].values)[:, None]
            ref = np.asarray(obs["mark_value"].values)[:, None]
        _, inverse = np.unique(np.concatenate([ref, keys]), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        order = np.empty(ref.shape[0], np.int64)
        order[inverse[: ref.shape[0]]] = np.arange(ref.shape[0])
        return hist / counts, counts, order[inverse[ref.shape[0] :]]
    raise ValueError(f"var_name: expected 'stays' or 'marks', got {var_name!r}")


def pointwise_log_likelihood(idata: az.InferenceData, var_name: str = "stays") -> xr.DataArray:
    """The per-artefact log-likelihood of a fit, recomputed from its posterior and its log.

    Fits store only what scales with the distinct data; this expands one term to
    ``(chain, draw, artefact)`` (memory checked against :func:`are_stats.inputs.memory_limit`),
    e.g. for ``arviz.loo``. :func:`fit_loo` gives the same PSIS-LOO without expanding.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit of :func:`fit_log` / :func:`~are_stats.fitting.fit_lifecycle_nuts`.
    var_name : {"stays", "marks"}
        ``stays``: ``log mu - mu * dwell`` (departed) or ``- mu * dwell`` (censored) per
        artefact; ``marks``: the log-probability of each artefact's mark (with labels, of its
        (class, mark) pair).

    Returns
    -------
    xarray.DataArray
        Dims ``(chain, draw, artefact)``.
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    ll, _, inverse = _distinct_loglik(idata, var_name)
    check_memory(ll.shape[0] * ll.shape[1] * inverse.size * 8.0, f"the {var_name} log-likelihood")
    return xr.DataArray(ll[..., inverse], dims=("chain", "draw", "artefact"), name=var_name)


#: Log-likelihood values :func:`fit_loo` holds at a time (2**24 float64: 128 MiB).
_LOO_BLOCK = 2**24


def fit_loo(idata: az.InferenceData, var_name: str = "stays") -> InformationCriterion:
    """PSIS-LOO of one likelihood term of a fit, over artefacts, without expanding it.

    Artefacts with the same observation (same dwell and departure flag; same mark) have the
    same leave-one-out density, so Pareto-smoothed importance sampling runs once per
    DISTINCT observation and the sums weight each by its count: the result equals
    ``arviz.loo`` of :func:`pointwise_log_likelihood` (same relative efficiency), at a cost
    of draws x distinct observations.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit.
    var_name : {"stays", "marks"}
        The term (see :func:`pointwise_log_likelihood`).

    Returns
    -------
    are_stats.fitting.InformationCriterion
        ``elpd``, ``se``, ``p_eff`` (p_loo), ``deviance``, the pointwise elpd of each
        distinct observation, their counts and Pareto k.
    """
    if var_name == "stays":  # distinct stays may be as many as rows: computed in blocks
        pairs, counts, _ = _stays_columns(idata)
        mu = np.asarray(idata.posterior["leave_rate"].values, dtype=np.float64)
        n_chains, n_draws = mu.shape
        m = pairs.shape[0]
    else:
        ll, counts, _ = _distinct_loglik(idata, var_name)
        n_chains, n_draws, m = ll.shape
    s = n_chains * n_draws
    check_work(float(s) * m * 60.0, f"PSIS-LOO over {m} distinct observations and {s} draws")
    reff = 1.0
    if n_chains > 1:  # as arviz.loo: mean ESS of the posterior over the number of draws
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ess = az.ess(idata.posterior, method="mean")
        reff = float(np.hstack([ess[v].values.ravel() for v in ess.data_vars]).mean()) / s
    if m == 0:
        raise ValueError(f"idata: expected at least one observation for {var_name!r}, got none")
    block = max(1, _LOO_BLOCK // s)  # about 128 MiB of log-likelihood at a time
    parts = []
    for j in range(0, m, block):
        if var_name == "stays":
            flat = _stays_loglik(mu, pairs[j : j + block]).reshape(s, -1)
        else:
            flat = ll.reshape(s, m)[:, j : j + block]
        log_w, k_block = psislw(-flat.T, reff)
        parts.append(
            (
                logsumexp(log_w + flat.T, axis=1),
                logsumexp(flat, axis=0) - np.log(s),
                np.atleast_1d(np.asarray(k_block, dtype=np.float64)),
            )
        )
    e, lppd, k_hat = (np.concatenate(x) for x in zip(*parts, strict=True))
    elpd, se = _weighted_total(e, counts)
    p_loo = float(np.sum(counts * (lppd - e)))
    return InformationCriterion(
        elpd, se, p_loo, -2.0 * elpd, e, counts, np.asarray(k_hat, dtype=np.float64)
    )
