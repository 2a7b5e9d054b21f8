"""Fit and choose the traffic models the data support (``are-stats fit --arrivals ...``).

Beside the paper's model (homogeneous Poisson arrivals, exponential stays, uniform
positions: its posterior is the fit's ``arrival_rate`` / ``leave_rate``), the toolkit fits

* arrival models (:data:`are_stats.traffic.ARRIVAL_SPECS`) on the log's quantised arrivals;
* stay laws (:data:`are_stats.traffic.STAY_LAWS`) through the observation window;
* the entry (and exit) density over the map's free cells (uniform or learned),

each by the one NUTS driver (:func:`~are_stats.fitting.run_nuts`; the Poisson and
exponential candidates reuse the paper's posterior draws, and the learned density is a
closed-form Dirichlet posterior mean), and compares the candidates of each factor by
PSIS-LOO over the same pointwise units (time bins, artefacts, entry points).

**Without NUTS** (``approximation="laplace"``, what ``are-stats fit --method em`` uses):
each candidate beyond the paper's is approximated by a Gaussian at its posterior mode on
the unconstrained scale (the Laplace approximation, :func:`~are_stats.fitting.run_laplace`)
and its pointwise ``elpd`` is importance-sampled PSIS-LOO from that Gaussian
(:func:`~are_stats.fitting.laplace_loo`); the choice rule below is the same, and the
chosen model's draws are the Gaussian's. No NUTS program is compiled. The fit's attribute
``traffic_model_choice`` says which was used.

**Ranked, then resampled** (``approximation="ranked"``, what ``are-stats fit`` uses by
default): the candidates are compared as without NUTS (Laplace approximation and
importance-sampled PSIS-LOO, one small derivative-free program each). The chosen model's
posterior is then drawn by importance resampling of its Laplace draws
(:func:`~are_stats.fitting.importance_resample`: Pareto-smoothed weights
``p(theta, y) / q(theta)``, accepted when their Pareto ``k`` is below 0.7); where they are
refused, of draws from the Student-t with the Gaussian's mode and scale
(:data:`RESAMPLE_T_DF` degrees of freedom: heavier tails, the same rule for ``k``); and by
NUTS where both are refused (the Poisson and exponential candidates' draws are the
paper's posterior). The
attributes ``arrival_posterior`` and ``lifetime_posterior`` say which ran, with ``k`` and
the effective sample size. A candidate with more than :data:`LAPLACE_MAX_PARAMETERS`
parameters is sampled by NUTS for the comparison. A cold fit thus compiles no NUTS program
where the weights are reliable (tests check that the choices agree with the all-NUTS
comparison on the shipped log and on logs drawn from each candidate, and the resampled
posteriors with NUTS's). ``approximation="nuts"`` samples every candidate.

**The choice.** Candidates are ordered from simple to complex. The candidate with the
highest ``elpd`` is the best; the chosen one is the *simplest* candidate whose ``elpd`` is
within two standard errors of the difference from the best (a richer model must earn its
place). A bursty arrival candidate (below), compared by its Laplace approximation only,
whose importance-sampled PSIS-LOO has a Pareto ``k`` above 0.7 on more than
:data:`UNRELIABLE_K_SHARE` of its units has an ``elpd`` estimate that is too optimistic
(Vehtari, Gelman and Gabry 2017): it does not set the bar for the others (it may still be
chosen, where it is the simplest within the bar), and the arrivals' notes name it. The
other candidates' LOO is kept where its ``k`` is high (a poor Laplace proposal for a
right model, e.g. Weibull stays of shape 0.6, must not lose to a worse model). The table
reports every candidate with ``elpd``, its standard error, the difference from the best
and its standard error, ``p_loo``, Pareto-k counts and the sampler's divergences and
``r_hat``; it presents no stacking weights (they are not model probabilities).

**The bursty candidates** (``mmpp``, ``hawkes``, their ``groups+`` variants and, where the
log has a clock and two days, ``mmpp+time-of-day`` and ``hawkes+time-of-day``: forward
recursions over the log's ticks, slow to sample where the data do not support them; the
``groups+`` variants with a time of day, each a Laplace search over 25 or more parameters
through such a recursion, are fitted only when named) are compared by the
Laplace approximation also in the all-NUTS comparison (``approximation="nuts"``, while the
other candidates' NUTS programs compile): a bursty candidate is sampled by NUTS only when
the rule chooses it, and the choice is then made again with its NUTS ``elpd``. The others
stay in the table with their Laplace ``elpd`` (``r_hat`` blank); ``arrival_notes`` says so.
A candidate named by ``--arrivals`` is sampled by NUTS.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Collection, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple  # Any: a NumPyro model's keyword arguments

import numpy as np
import pandas as pd
from numpyro.diagnostics import effective_sample_size
from scipy.special import logsumexp

from are_stats._checks import check_in
from are_stats.environment import coarse_free
from are_stats.fitting._laplace import (
    RESAMPLE_MAX_K,
    importance_resample,
    laplace_dimension,
    laplace_loo,
    laplace_program,
    run_laplace,
)
from are_stats.fitting._nuts import (
    NutsPrefetch,
    NutsRun,
    clock_progress,
    nuts_warnings,
    run_nuts,
)
from are_stats.fitting._psis import psislw
from are_stats.traffic import (
    ARRIVAL_SPECS,
    DAY,
    STAY_LAWS,
    ArrivalSpec,
    LifecycleData,
    PositionDensity,
    arrival_model,
    arrival_unit_loglik,
    arrival_units,
    clock_offset,
    exponential_unit_loglik,
    fit_position_density,
    fold_in_key,
    poisson_unit_loglik,
    split_key,
    stay_model,
    stay_unit_loglik,
    stay_units,
    uniform_position_density,
)

if TYPE_CHECKING:
    import jax
    import numpy.typing as npt

    from are_stats.environment import OccupancyGrid
    from are_stats.fitting._laplace import LaplaceRun
    from are_stats.fitting._nuts import NutsSettings
    from are_stats.traffic import ArrivalUnits, StayUnits

__all__ = [
    "APPROXIMATIONS",
    "ARRIVAL_CHOICES",
    "LIFETIME_CHOICES",
    "POSITION_CHOICES",
    "TrafficFit",
    "LaplaceAhead",
    "choose_simplest",
    "compile_laplace_ahead",
    "fit_traffic",
    "loo_pointwise",
    "time_resolution",
]

#: ``--arrivals`` choices (``auto`` compares the candidates the log supports).
ARRIVAL_CHOICES = ("auto", *ARRIVAL_SPECS)
#: ``--lifetimes`` choices.
LIFETIME_CHOICES = ("auto", *STAY_LAWS)
#: ``--positions`` choices.
POSITION_CHOICES = ("auto", "uniform", "learned")

#: ``approximation`` of :func:`fit_traffic`: the posterior each candidate is compared by.
APPROXIMATIONS = ("nuts", "laplace", "ranked")
#: Most latent parameters a candidate may have for the Laplace approximation (its mode
#: search and Hessian grow with the square of the number); larger ones are not offered.
LAPLACE_MAX_PARAMETERS = 64
#: Draws of each candidate's Laplace approximation when it ranks the candidates (and the
#: chosen model's draws are importance-resampled from them, or sampled by NUTS): the
#: draws' evaluation is most of a candidate's time. On the shipped log every candidate's
#: total elpd from 1,000 draws was within 0.3 nat of that from 4,000 (as close as two
#: seeds of 4,000 draws), with the same choices.
#: ``approximation="laplace"`` keeps the posterior's size (its draws are the Gaussian's).
RANKING_DRAWS = 1000
#: Degrees of freedom of the Student-t proposal (at the Laplace mode, with its scale) whose
#: draws the chosen model's posterior is importance-resampled from where the Gaussian's
#: weights are refused (Pareto ``k`` 0.7 or more), before NUTS. Heavier tails than the
#: Gaussian's cover a skewed posterior (the group sizes' simplex of a 302-person tracks
#: log: the Gaussian's k 0.71-0.88, the t's 0.24-0.54 with 3-5 degrees of freedom, 0.33-0.66
#: with 8, over 3 seeds each).
RESAMPLE_T_DF = 4.0
#: What ``traffic_model_choice`` records for each.
MODEL_CHOICE = {
    "nuts": "PSIS-LOO over NUTS draws",
    "laplace": "importance-sampled PSIS-LOO over Laplace-approximation draws (no NUTS)",
    "ranked": "importance-sampled PSIS-LOO over Laplace-approximation draws; the chosen "
    "model's posterior by importance resampling of those draws, or NUTS where their Pareto "
    "k is too high (traffic_arrival_posterior, traffic_lifetime_posterior)",
}

#: Cell side (m) of the grid the entry/exit densities live on (the map is coarsened to it).
POSITION_CELL = 0.5


@dataclass
class TrafficFit:
    """The chosen traffic models of a log and what led to them.

    Attributes
    ----------
    arrival_model, lifetime_model, position_model : str
        The chosen models.
    tables : dict of str to pandas.DataFrame
        ``arrivals``, ``lifetimes``, ``positions``: one row per candidate (see the module
        docstring), the chosen one flagged.
    posterior : dict of str to (chains, draws, ...) ndarray
        Posterior draws of the chosen models' parameters that the paper's posterior does
        not hold (``event_rate``, ``arrival_phi``, ``arrival_tod``, ``group_size_probs``,
        ``stay_mean``, ``stay_shape``).
    dims : dict of str to list of str
        Extra dimensions of those variables.
    attrs : dict
        Settings the generator needs (``arrival_bin_width``, ``time_resolution``,
        ``clock_start``, ``group_stay_sd``, ``group_spread``, ...).
    entry, exit : PositionDensity or None
        The chosen entry density and the exit density (learned when there are exits and
        ``position_model == "learned"``).
    warnings : list of str
        Sampler diagnostics and choices worth a word.
    """

    arrival_model: str
    lifetime_model: str
    position_model: str
    tables: dict = field(default_factory=dict)
    posterior: dict = field(default_factory=dict)
    dims: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    entry: PositionDensity | None = None
    exit: PositionDensity | None = None
    warnings: list = field(default_factory=list)


def time_resolution(*times: npt.ArrayLike) -> float:
    """Smallest positive gap between distinct recorded times (NaN ignored); 0 if none."""
    allt = np.concatenate([np.asarray(t, float).ravel() for t in times] or [np.zeros(0)])
    u = np.unique(allt[np.isfinite(allt)])
    if u.size < 2:
        return 0.0
    d = np.diff(u)
    # gaps from float rounding of one time (1e-12 s) are not a resolution
    scale = max(float(np.max(np.abs(u))), 1.0)
    d = d[d > 1e-9 * scale]
    return float(d.min()) if d.size else 0.0


def loo_pointwise(loglik: np.ndarray, reff: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """PSIS-LOO pointwise ``elpd_i`` and Pareto ``k_i`` of a ``(chains, draws, n)`` log-lik."""
    c, d, n = loglik.shape
    if n == 0:
        return np.zeros(0), np.zeros(0)
    flat = loglik.reshape(c * d, n)
    log_w, k = psislw(-flat.T, reff)
    elpd = logsumexp(log_w + flat.T, axis=1)
    return np.asarray(elpd, float), np.atleast_1d(np.asarray(k, float))


def _loo_results(futures: dict[str, Future]) -> tuple[dict, dict]:
    """``elpd_i`` and Pareto ``k_i`` per candidate from :func:`loo_pointwise` futures."""
    done = {name: f.result() for name, f in futures.items()}
    return {n: r[0] for n, r in done.items()}, {n: r[1] for n, r in done.items()}


def _reff(run: NutsRun | None) -> float:
    """Relative efficiency for PSIS (mean bulk ESS of the latent scalars over the draws)."""
    if run is None:
        return 1.0
    c, d = run.diverging.shape
    if c < 2:
        return 1.0
    vals = []
    for name, v in run.samples.items():
        if name.endswith("_z") or name.endswith("_eta") or v.ndim == 2:
            flat = v.reshape(c, d, -1)
            with np.errstate(invalid="ignore", divide="ignore"):
                ess = np.asarray(effective_sample_size(flat))
            vals.extend(ess[np.isfinite(ess)].tolist())
    return float(np.clip(np.mean(vals) / (c * d), 0.05, 1.0)) if vals else 1.0


#: Share of a candidate's units with Pareto ``k > 0.7`` above which its PSIS-LOO ``elpd``
#: is not trusted to be the best (module doc, "The choice").
UNRELIABLE_K_SHARE = 0.05


def unreliable_loo(ks: Mapping[str, np.ndarray]) -> list[str]:
    """The candidates whose PSIS-LOO has ``k > 0.7`` on more than
    :data:`UNRELIABLE_K_SHARE` of their units."""
    return [
        n for n, k in ks.items() if np.size(k) and np.mean(np.asarray(k) > 0.7) > UNRELIABLE_K_SHARE
    ]


def choose_simplest(
    elpd: dict[str, np.ndarray], order: list[str], unreliable: Collection[str] = ()
) -> tuple[str, pd.DataFrame]:
    """The simplest candidate within two standard errors of the best (see the module doc).

    Parameters
    ----------
    elpd : dict of str to (n,) float
        Pointwise ``elpd_i`` of each candidate over the same units.
    order : list of str
        Candidates from simplest to most complex.
    unreliable : collection of str
        Candidates whose ``elpd`` may not be the best (:func:`unreliable_loo`); they are
        compared, and may be chosen, against the best of the others.

    Returns
    -------
    chosen : str
    table : pandas.DataFrame
        Indexed by candidate: ``elpd``, ``se``, ``elpd_diff`` (best minus this), ``dse``.
    """
    names = [n for n in order if n in elpd]
    tot = {n: float(np.sum(elpd[n])) for n in names}
    trusted = [n for n in names if n not in unreliable] or names
    best = max(trusted, key=lambda n: tot[n])
    rows = []
    chosen = None
    for n in names:
        e = elpd[n]
        diff = elpd[best] - e
        dse = float(np.sqrt(e.size * np.var(diff))) if e.size > 1 else 0.0
        se = float(np.sqrt(e.size * np.var(e))) if e.size > 1 else 0.0
        rows.append((n, tot[n], se, tot[best] - tot[n], dse))
        if chosen is None and tot[best] - tot[n] <= 2.0 * dse:
            chosen = n
    table = pd.DataFrame(rows, columns=["model", "elpd", "se", "elpd_diff", "dse"])
    table = table.set_index("model")
    table["chosen"] = table.index == chosen
    return str(chosen), table


def _pareto_cols(table: pd.DataFrame, ks: dict[str, np.ndarray]) -> None:
    table["k>0.7"] = [int(np.sum(ks[n] > 0.7)) if n in ks else 0 for n in table.index]
    table["k_max"] = [
        float(np.max(ks[n])) if n in ks and ks[n].size else np.nan for n in table.index
    ]


def _diag_cols(table: pd.DataFrame, runs: dict[str, NutsRun | None]) -> None:
    table["divergent"] = [
        runs[n].n_divergent if runs.get(n) is not None else 0 for n in table.index
    ]
    table["r_hat"] = [runs[n].max_r_hat if runs.get(n) is not None else np.nan for n in table.index]


def _arrival_draw_loglik(p: dict, **model_kwargs: Any) -> jax.Array:
    """``(B,)`` pointwise arrival log-likelihood of one draw, given ``arrival_model``'s
    arguments (module level: :func:`run_nuts` reuses its compiled program)."""
    kw = model_kwargs
    return arrival_unit_loglik({**p, "log_area": kw["log_area"]}, kw["units"], kw["spec"])


def _stay_draw_loglik(p: dict, **model_kwargs: Any) -> jax.Array:
    """``(n,)`` pointwise stay log-likelihood of one draw, given ``stay_model``'s arguments."""
    kw = model_kwargs
    return stay_unit_loglik(p, kw["units"], kw["law"], kw["resolution"])


def _likelihood(factor: str) -> tuple[Callable[..., jax.Array], str | None]:
    """A factor's pointwise log-likelihood of one draw, and the model's factor site whose
    value is its sum where the Laplace program computes the likelihood once
    (:func:`run_laplace`'s ``likelihood``): ``stay_model``'s ``stays`` (its last site).

    The arrival models keep their own factor: XLA's common-subexpression pass already
    merges the model's and the pointwise recursions (the same loops in the compiled MMPP
    and Hawkes programs either way, the compile CPU within noise), and the smaller
    program rounded the MMPP candidates' values differently by 1-2e-16 (2026-11-28). The
    gamma law's program, the same bits either way, compiled in about 0.3 s less CPU.
    """
    if factor == "arrivals":
        return _arrival_draw_loglik, None
    return _stay_draw_loglik, "stays"


def _bin_width(data: LifecycleData) -> float:
    """Pointwise units of the arrivals: bins about a median stay long, 10 to 500 per window."""
    t0, t1 = data.window
    dur = t1 - t0
    seen = ~data.truncated & ~data.censored
    stays = (data.t_leave - data.t_arrive)[seen]
    stays = stays[stays > 0]
    w = float(np.median(stays)) if stays.size else dur / 48.0
    return float(np.clip(w, dur / 500.0, dur / 10.0))


def _group_stats(data: LifecycleData) -> dict[str, float]:
    """Spread of members' stays (sd of log stay) and entry points (m) around their group's.

    Pooled within-group variances: each group of ``n >= 2`` members gives ``n - 1``
    degrees of freedom (stays: those seen whole and positive, when two or more are).
    Sums per group by ``bincount`` (linear in the artefacts, whatever the number of groups).
    """
    out = {"group_stay_sd": 0.0, "group_spread": 0.0}
    if data.group is None:
        return out
    _, codes = np.unique(np.asarray(data.group), return_inverse=True)
    codes = codes.ravel()
    n_groups = int(codes.max()) + 1 if codes.size else 0
    size = np.bincount(codes, minlength=n_groups)
    member = size[codes] >= 2
    seen = ~data.truncated & ~data.censored
    stay = np.where(seen, data.t_leave - data.t_arrive, np.nan)
    ok = member & np.isfinite(stay) & (stay > 0)
    ls = np.log(np.where(ok, stay, 1.0))
    m_ok = np.bincount(codes[ok], minlength=n_groups)
    use = ok & (m_ok[codes] >= 2)
    if use.any():
        mean = np.bincount(codes[use], ls[use], n_groups) / np.maximum(m_ok, 1)
        ss_stay = float(np.sum((ls[use] - mean[codes[use]]) ** 2))
        df_stay = float(np.sum(m_ok[m_ok >= 2] - 1))
        out["group_stay_sd"] = float(np.sqrt(ss_stay / df_stay))
    if data.x is not None and data.y is not None and member.any():
        ss_xy = 0.0
        for v in (np.asarray(data.x, float), np.asarray(data.y, float)):
            mean = np.bincount(codes[member], v[member], n_groups) / np.maximum(size, 1)
            ss_xy += float(np.sum((v[member] - mean[codes[member]]) ** 2))
        df_xy = 2.0 * float(np.sum(size[size >= 2] - 1))
        out["group_spread"] = float(np.sqrt(ss_xy / df_xy))
    return out


def _arrival_candidates(
    arrivals: str, max_tick: int, clock: float | None, duration: float
) -> tuple[list[str], list[str]]:
    """Candidates to fit, and notes on those not offered."""
    notes = []
    if arrivals != "auto":
        spec = ArrivalSpec.from_name(arrivals)
        if spec.tod and clock is None:
            raise ValueError(
                f"--arrivals {arrivals}: expected the log's clock (manifest key clock_start "
                "or --clock-start: the wall-clock time of t = 0), got none"
            )
        if spec.groups and max_tick < 2:
            raise ValueError(
                f"--arrivals {arrivals}: expected artefacts arriving together (a group column "
                "or equal arrival times), got none"
            )
        return sorted({"poisson", arrivals}, key=ARRIVAL_SPECS.index), notes
    out = ["poisson", "negbin", "mmpp", "hawkes"]
    if max_tick >= 2:
        out += ["groups", "groups+mmpp", "groups+hawkes"]
    else:
        notes.append("groups not offered: no two artefacts arrived together")
    if clock is None:
        notes.append("time-of-day not offered: the log has no clock_start")
    elif duration < 2.0 * DAY:
        notes.append(
            f"time-of-day not offered: the window ({duration:g} s) is shorter than two days"
        )
    else:
        out += ["time-of-day", "negbin+time-of-day", "mmpp+time-of-day", "hawkes+time-of-day"]
        if max_tick >= 2:
            out.append("groups+time-of-day")
            notes.append(
                "groups+mmpp+time-of-day, groups+hawkes+time-of-day not offered by auto "
                "(costly: name one with --arrivals)"
            )
    return out, notes


def _empirical_rate(units_count: float, data: LifecycleData, groups: bool, n_events: int) -> float:
    t0, t1 = data.window
    n = max(float(n_events if groups else units_count), 0.5)
    return n / (data.area * (t1 - t0))


def fit_traffic(
    key: jax.Array,
    data: LifecycleData,
    *,
    paper: dict[str, np.ndarray],
    arrivals: str = "auto",
    lifetimes: str = "auto",
    positions: str = "auto",
    grid: OccupancyGrid | None = None,
    clock_start: str | None = None,
    num_warmup: int = 500,
    num_samples: int = 1000,
    num_chains: int = 4,
    progress: Callable[[str], object] | None = None,
    approximation: str = "nuts",
) -> TrafficFit:
    """Fit the candidate traffic models of a log and choose one per factor by PSIS-LOO.

    Parameters
    ----------
    key : jax PRNG key
    data : LifecycleData
        The log (``group``, ``x``/``y`` and ``x_exit``/``y_exit`` used when present).
    paper : dict
        The paper's posterior, ``arrival_rate`` and ``leave_rate`` as ``(chains, draws)``:
        the draws of the ``poisson`` and ``exponential`` candidates (same layout is used
        for every candidate, so that the chosen draws sit beside them in one posterior).
    arrivals : {"auto", "poisson", "negbin", "groups", "time-of-day", ...}
    lifetimes : {"auto", "exponential", "gamma", "weibull", "lognormal"}
    positions : {"auto", "uniform", "learned"}
    grid : OccupancyGrid, optional
        The scene's map (needed for the learned densities).
    clock_start : str, optional
        ISO 8601 wall-clock time of ``t = 0`` (time-of-day models need it).
    num_warmup, num_samples, num_chains : int
        NUTS settings; the draws are reshaped to the paper posterior's ``(chains, draws)``.
    progress : callable, optional
        ``progress(message)`` at each stage.
    approximation : {"nuts", "laplace", "ranked"}
        The candidates' posteriors: NUTS draws; the Laplace approximation with
        importance-sampled PSIS-LOO (no NUTS program is compiled); or ranked by the
        Laplace approximation and the chosen model sampled by NUTS (see the module
        docstring). Recorded in ``attrs["model_choice"]``.

    Returns
    -------
    TrafficFit
    """
    check_in("approximation", approximation, APPROXIMATIONS)
    check_in("arrivals", arrivals, ARRIVAL_CHOICES)
    check_in("lifetimes", lifetimes, LIFETIME_CHOICES)
    check_in("positions", positions, POSITION_CHOICES)
    say = progress or (lambda _m: None)
    lam = np.asarray(paper["arrival_rate"], float)
    mu = np.asarray(paper["leave_rate"], float)
    shape = lam.shape
    n_draws = lam.size
    # draws of each Laplace approximation: the posterior's size when they are the chosen
    # model's posterior (laplace), fewer when they rank the candidates
    n_lap = n_draws if approximation == "laplace" else min(n_draws, RANKING_DRAWS)
    out = TrafficFit("poisson", "exponential", "uniform")
    nuts = {"num_warmup": num_warmup, "num_samples": num_samples, "num_chains": num_chains}
    setup = _setup(key, data, arrivals, lifetimes, clock_start, out)
    out.attrs["model_choice"] = MODEL_CHOICE[approximation]
    laplace, ranked = approximation == "laplace", approximation == "ranked"
    if laplace:
        setup = _laplace_sized(setup, arrivals, lifetimes, out)
    # the candidates compared by their Laplace approximation (all of them but the paper's
    # with "laplace"; with "ranked" those small enough, the others sampled by NUTS)
    approx = set(setup.calls) if laplace else set()
    if ranked:
        approx = {
            c
            for c, (_, model, kwargs, init) in setup.calls.items()
            if laplace_dimension(model, kwargs, init) <= LAPLACE_MAX_PARAMETERS
        }
    # all-NUTS comparison: the bursty candidates (but one named by --arrivals) are ranked
    # by Laplace too, and sampled by NUTS only when chosen (then the choice is made again)
    bursty = set()
    if approximation == "nuts":
        bursty = {
            c
            for c in setup.calls
            if c[0] == "arrivals" and c[1] != arrivals and ArrivalSpec.from_name(c[1]).bursts
        }
        approx = set(bursty)
    calls, cands, laws = setup.calls, setup.cands, setup.laws
    plain, units, res = setup.plain, setup.units, setup.res
    n_real_bins = int(np.sum(plain.bin_weight))
    log_area, n = float(np.log(data.area)), data.n
    runs: dict[str, dict] = {"arrivals": {}, "stays": {}}
    draws: dict[str, dict] = {"arrivals": {}, "stays": {}}
    laps: dict[tuple[str, str], LaplaceRun] = {}  # the Laplace runs (ranked: resampled if chosen)
    loo: dict[str, dict] = {"arrivals": {}, "stays": {}}  # PSIS-LOO futures

    def reshape(v: np.ndarray) -> np.ndarray:
        flat = v.reshape((-1,) + v.shape[2:])
        if flat.shape[0] != n_draws:  # thin or repeat to the paper posterior's draws
            idx = np.linspace(0, flat.shape[0] - 1, n_draws).round().astype(int)
            flat = flat[idx]
        return flat.reshape(shape + flat.shape[1:])

    # PSIS-LOO of a candidate runs in its own thread while the next candidate samples
    # (NumPy releases the GIL in its array work; the sampler waits on the devices)
    # The Laplace approximations run two at a time (LAPLACE_THREADS) and are taken in
    # the candidates' order, so the fit is the same as one at a time
    with (
        NutsPrefetch() as ahead,
        ThreadPoolExecutor(1, "are-stats-loo") as psis,
        ThreadPoolExecutor(LAPLACE_THREADS, "are-stats-laplace-run") as lap_pool,
        ThreadPoolExecutor(1, "are-stats-positions") as positions_pool,
    ):
        lap_runs: dict[tuple[str, str], Future[LaplaceRun]] = {}
        # with one run thread, two more compile the candidates' programs ahead of it; with
        # two, each run loads (or compiles) its own program: more threads only contended
        # for the GIL (a repeated fit of the shipped log: 0.9 s more CPU at load 15-20)
        if approx and LAPLACE_THREADS < 2:
            prefetch = ThreadPoolExecutor(2, "are-stats-laplace")
            for factor, name in _laplace_order(approx):
                _, model, kwargs, init = calls[factor, name]
                pw, site = _likelihood(factor)
                prefetch.submit(
                    laplace_program, model, kwargs, init, pw, _optimise((factor, name)), site
                )
            prefetch.shutdown(wait=False)
        # when the runs started and finished: the Laplace stages' time left on a first fit
        lap_queue: tuple[float, list[float]] = (time.perf_counter(), [])
        # each finished run's PSIS-LOO starts at once, in the PSIS thread, not when the fit
        # comes to the candidate (the runs finish longest-compile first, not in order)
        lap_loo: dict[tuple[str, str], Future[tuple[np.ndarray, np.ndarray]]] = {}
        loo_lock = threading.Lock()

        def loo_of(which: tuple[str, str], lap: LaplaceRun) -> Future:
            with loo_lock:  # once a candidate: from its run's thread or the fit's
                if which not in lap_loo:
                    cut = n_real_bins if which[0] == "arrivals" else n
                    lap_loo[which] = psis.submit(
                        laplace_loo, lap._replace(loglik=lap.loglik[:, :cut])
                    )
                return lap_loo[which]

        def finished(which: tuple[str, str], f: Future[LaplaceRun]) -> None:
            lap_queue[1].append(time.perf_counter())
            if f.exception() is None:  # a failed run raises where the fit waits on it
                loo_of(which, f.result())

        # the longest compiles first (as compile_laplace_ahead compiles them): the runs are
        # pure functions of their calls, so their order does not change the fit
        for which in _laplace_order(calls):
            if which in approx:
                lap_runs[which] = lap_pool.submit(_run_candidate, calls, which, n_lap)
                lap_runs[which].add_done_callback(functools.partial(finished, which))
        for which, call in calls.items():
            if which not in approx:
                ahead.add(*call, **nuts)
        if "exponential" in laws:
            # the paper's stay law in closed form (NumPy): its PSIS-LOO queued now, not
            # behind the arrival candidates' (it was the last thing a repeated fit of the
            # shipped log waited on)
            ll = exponential_unit_loglik(1.0 / mu.ravel(), units, res).reshape(shape + (-1,))
            loo["stays"]["exponential"] = psis.submit(loo_pointwise, ll[..., :n], _reff(None))
        # the entry and exit densities need the log and the map alone: fitted in a thread
        # of their own while the candidates run, not after them (an error is raised where
        # the fit takes the result, as before); not in the PSIS thread, whose queue would
        # wait behind them while they wait on scipy.signal's import beside ArviZ's
        fitted_positions = positions_pool.submit(_fit_positions, data, positions, grid)
        for name in cands:
            if name == "poisson":
                # the paper's draws in closed form (NumPy: no program to compile)
                ll = poisson_unit_loglik(lam.ravel(), plain, log_area).reshape(shape + (-1,))
                run = None
            elif ("arrivals", name) in approx:
                lap = _laplace_candidate(("arrivals", name), lap_runs, say, out, lap_queue)
                draws["arrivals"][name] = {k: v[None] for k, v in lap.samples.items()}
                runs["arrivals"][name] = None
                laps["arrivals", name] = lap
                loo["arrivals"][name] = loo_of(("arrivals", name), lap)
                continue
            else:
                run = _sample_candidate(
                    calls, ("arrivals", name), _arrival_draw_loglik, nuts, say, out
                )
                ll, draws["arrivals"][name] = run.loglik, run.samples
            runs["arrivals"][name] = run
            loo["arrivals"][name] = psis.submit(loo_pointwise, ll[..., :n_real_bins], _reff(run))
        for law in laws:
            if law == "exponential":
                runs["stays"][law] = None
                continue
            if ("stays", law) in approx:
                lap = _laplace_candidate(("stays", law), lap_runs, say, out, lap_queue)
                draws["stays"][law] = {k: v[None] for k, v in lap.samples.items()}
                runs["stays"][law] = None
                laps["stays", law] = lap
                loo["stays"][law] = loo_of(("stays", law), lap)
                continue
            else:
                run = _sample_candidate(calls, ("stays", law), _stay_draw_loglik, nuts, say, out)
                ll, draws["stays"][law] = run.loglik, run.samples
            runs["stays"][law] = run
            loo["stays"][law] = psis.submit(loo_pointwise, ll[..., :n], _reff(run))
        elpd, ks = _loo_results(loo["arrivals"])
        chosen = _choose_arrivals(out, arrivals, cands, elpd, ks, runs["arrivals"])
        while ("arrivals", chosen) in bursty:  # chosen by its Laplace elpd: NUTS decides
            which = ("arrivals", chosen)
            run = _sample_candidate(calls, which, _arrival_draw_loglik, nuts, say, out)
            runs["arrivals"][chosen], draws["arrivals"][chosen] = run, run.samples
            elpd[chosen], ks[chosen] = loo_pointwise(run.loglik[..., :n_real_bins], _reff(run))
            bursty.discard(which)
            approx.discard(which)
            chosen = _choose_arrivals(out, arrivals, cands, elpd, ks, runs["arrivals"])
        if bursty:
            names = ", ".join(sorted(c[1] for c in bursty))
            note = (
                f"{names}: compared by the Laplace approximation only (importance-sampled "
                "PSIS-LOO; NUTS samples a bursty candidate only when it is chosen)"
            )
            notes = (out.attrs.get("arrival_notes"), note)
            out.attrs["arrival_notes"] = "; ".join(v for v in notes if v)
        elpd, ks = _loo_results(loo["stays"])
        if lifetimes == "auto":
            law, table = choose_simplest(elpd, laws)
        else:
            _, table = choose_simplest(elpd, laws)
            law = lifetimes if lifetimes in laws else "exponential"
            table["chosen"] = table.index == law
        # ranked: the chosen models' posteriors by importance resampling of their Laplace
        # draws where the weights are reliable, else by NUTS (the second program compiling
        # in a thread while the first samples)
        chosen_calls = [("arrivals", chosen), ("stays", law)] if ranked else []
        chosen_calls = [c for c in chosen_calls if c in approx]
        _posterior_words(out, chosen, law, runs)
        resampled = {
            which: importance_resample(
                fold_in_key(key, 101 + i), laps[which], n_draws, max_k=RESAMPLE_MAX_K
            )
            for i, which in enumerate(chosen_calls)
        }
        for i, ((factor, name), r) in enumerate(resampled.items()):
            words = f"Pareto k {r.k_hat:.2f}, effective sample size {r.ess:.0f} of {n_lap}"
            how = "importance-resampled Laplace"
            lap = laps[factor, name]
            if r.samples is None and lap.converged and lap.redraw is not None:
                # the Gaussian's tails too light: the Student-t at its mode and scale
                k_t = fold_in_key(key, 201 + i)
                t = importance_resample(
                    k_t, lap.redraw(k_t, n_lap, RESAMPLE_T_DF), n_draws, max_k=RESAMPLE_MAX_K
                )
                words += (
                    f"; Student-t ({RESAMPLE_T_DF:g} degrees of freedom): Pareto k "
                    f"{t.k_hat:.2f}, effective sample size {t.ess:.0f} of {n_lap}"
                )
                if t.samples is not None:
                    r, how = t, "importance-resampled Laplace-t"
                resampled[factor, name] = r
            if r.samples is not None:
                draws[factor][name] = {k: v[None] for k, v in r.samples.items()}
                out.attrs[_POSTERIOR_ATTR[factor]] = f"{how} ({words})"
            else:
                out.attrs[_POSTERIOR_ATTR[factor]] = (
                    f"nuts (the Laplace draws' importance weights: {words}; accepted below "
                    f"{RESAMPLE_MAX_K})"
                )
        chosen_calls = [c for c in chosen_calls if resampled[c].samples is None]
        for which in chosen_calls:
            ahead.add(*calls[which], **nuts)
        for factor, name in chosen_calls:
            run = _sample_candidate(calls, (factor, name), None, nuts, say, out)
            runs[factor][name] = run
            if _mixed(run):
                draws[factor][name] = run.samples
            else:  # chains stuck (a Weibull of shape 0.6 did): keep the Laplace draws
                out.warnings.append(
                    f"{factor} {name}: NUTS did not mix (r_hat {run.max_r_hat:.3g}, "
                    f"{run.n_divergent} divergent transitions); the posterior kept is the "
                    "chosen model's Laplace approximation (as --method em gives)"
                )
                out.attrs[_POSTERIOR_ATTR[factor]] = (
                    "laplace (the Gaussian's draws: NUTS did not mix; "
                    + out.attrs[_POSTERIOR_ATTR[factor]]
                    + ")"
                )
        _diag_cols(out.tables["arrivals"], runs["arrivals"])
        if chosen != "poisson":
            _store_arrival_draws(out, chosen, draws["arrivals"][chosen], reshape)
        out.attrs.update(_group_stats(data))
    runs, draws, chosen = runs["stays"], draws["stays"], law
    _pareto_cols(table, ks)
    _diag_cols(table, runs)
    out.tables["lifetimes"] = table
    out.lifetime_model = chosen
    if chosen != "exponential":
        out.posterior["stay_mean"] = reshape(draws[chosen]["stay_mean"])
        out.posterior["stay_shape"] = reshape(draws[chosen]["stay_shape"])

    # ---------------- positions ----------------
    out.position_model, out.entry, out.exit, table = fitted_positions.result()
    out.tables["positions"] = table
    if table is None:
        out.tables.pop("positions")
    return out


#: The attribute that says how the chosen model's posterior was drawn, per factor.
_POSTERIOR_ATTR = {"arrivals": "arrival_posterior", "stays": "lifetime_posterior"}


def _posterior_words(out: TrafficFit, arrival: str, law: str, runs: dict) -> None:
    """``out.attrs["arrival_posterior"]`` / ``["lifetime_posterior"]``: how the chosen
    models' draws were made (``fit_traffic`` overwrites a ranked, resampled one)."""
    for factor, name in (("arrivals", arrival), ("stays", law)):
        if name in ("poisson", "exponential"):
            words = "the paper's posterior"
        elif runs[factor].get(name) is not None:
            words = "nuts"
        else:
            words = "laplace (the Gaussian's draws)"
        out.attrs[_POSTERIOR_ATTR[factor]] = words


class _Setup(NamedTuple):
    """What the candidates of :func:`fit_traffic` are fitted on, and their NUTS calls."""

    calls: dict  # ("arrivals" | "stays", name) -> (key, model, model_kwargs, init)
    cands: list  # arrival candidates
    laws: list  # stay candidates
    plain: ArrivalUnits  # the arrival ticks without periods of the day
    units: StayUnits  # the stays
    res: float  # the log's time resolution


def _setup(
    key: jax.Array,
    data: LifecycleData,
    arrivals: str,
    lifetimes: str,
    clock_start: str | None,
    out: TrafficFit,
) -> _Setup:
    """The data and NUTS calls of every candidate (attributes and warnings into ``out``)."""
    t0, t1 = data.window
    res = time_resolution(data.t_arrive, data.t_leave, [t0, t1])
    if res <= 0:
        res = (t1 - t0) * 1e-6
    out.attrs["time_resolution"] = res
    k_arr, k_life = split_key(key)
    clock = None if clock_start is None else clock_offset(clock_start)
    if clock_start is not None:
        out.attrs["clock_start"] = str(clock_start)
    width = _bin_width(data)
    out.attrs["arrival_bin_width"] = width
    plain = arrival_units(data.t_arrive, data.window, data.area, res, width, group=data.group)
    max_tick = int(np.max(plain.tick_count)) if plain.tick_count.size else 0
    cands, notes = _arrival_candidates(arrivals, max_tick, clock, t1 - t0)
    out.attrs["arrival_notes"] = "; ".join(notes)
    n_ticks = int(np.sum(plain.tick_weight))
    log_area = float(np.log(data.area))
    by_clock = None  # the same ticks with their periods of the day, for time-of-day models
    if any(ArrivalSpec.from_name(n).tod for n in cands):
        by_clock = arrival_units(
            data.t_arrive, data.window, data.area, res, width, group=data.group, clock_offset=clock
        )
    calls: dict[tuple[str, str], tuple] = {}
    for i, name in enumerate(cands):
        spec = ArrivalSpec.from_name(name)
        if name != "poisson":
            units = by_clock if spec.tod else plain
            centre = _empirical_rate(np.sum(units.tick_count), data, spec.groups, n_ticks)
            init: dict[str, float | np.ndarray] = {"event_rate_z": 0.0}
            if spec.negbin:
                init["arrival_phi"] = 5.0
            if spec.tod:
                init["tod_eta"] = np.zeros(units.bin_exposure.shape[1])
            if spec.groups:
                init["group_size_probs"] = np.full(max_tick, 1.0 / max_tick)
            if spec.mmpp:
                init["mmpp_contrast"] = 1.0
                init["mmpp_switch_z"] = np.zeros(2)
            if spec.hawkes:
                init["hawkes_branching"] = 0.3
                init["hawkes_decay_z"] = 0.0
            # the centre and area are arrays: arguments of the compiled program, not
            # constants of it (logs of similar size share one program)
            kwargs = {
                "units": units,
                "spec": spec,
                "rate_centre": np.asarray(centre, float),
                "log_area": np.asarray(log_area, float),
                "max_group": max(max_tick, 1),
            }
            if spec.bursts:  # the time scale of the switching rates' and decay's priors
                kwargs["time_centre"] = np.asarray(width, float)
            calls["arrivals", name] = (fold_in_key(k_arr, i), arrival_model, kwargs, init)
    units = stay_units(data.dwell, data.censored, data.truncated)
    n = data.n
    departed = int(np.sum(~data.censored))
    mean_centre = float(np.sum(data.dwell)) / max(departed, 1) if n else 1.0
    mean_centre = mean_centre if mean_centre > 0 else res
    laws = (
        list(STAY_LAWS)
        if lifetimes == "auto"
        else sorted({"exponential", lifetimes}, key=STAY_LAWS.index)
    )
    if n == 0 or departed == 0:
        out.warnings.append("lifetimes: no departure seen; the exponential law is kept")
        laws = ["exponential"]
    for i, law in enumerate(laws):
        if law != "exponential":
            kwargs = {
                "units": units,
                "law": law,
                "mean_centre": np.asarray(mean_centre, float),
                # an argument, not a constant: logs whose measured resolutions differ
                # in the last digits share the program
                "resolution": np.asarray(res, float),
            }
            init = {"stay_mean_z": 0.0, "stay_shape_eta": 0.0}
            calls["stays", law] = (fold_in_key(k_life, i), stay_model, kwargs, init)
    return _Setup(calls, cands, laws, plain, units, res)


#: Largest split r_hat of a chosen model's NUTS run whose draws are kept (ranked mode).
MIXED_R_HAT = 1.05


def _mixed(run: NutsRun) -> bool:
    """Whether a NUTS run's chains agree (every split ``r_hat`` at most
    :data:`MIXED_R_HAT`) and at most 1% of its transitions diverged."""
    first = next(iter(run.samples.values()), None)
    n = int(np.prod(np.shape(first)[:2])) if first is not None else 1
    return bool(run.max_r_hat <= MIXED_R_HAT and run.n_divergent <= 0.01 * n)


def _sample_candidate(
    calls: dict,
    which: tuple[str, str],
    pointwise: Callable[..., jax.Array] | None,
    nuts: NutsSettings,
    say: Callable[[str], object],
    out: TrafficFit,
) -> NutsRun:
    """NUTS for one candidate model (its warnings added to ``out``)."""
    factor, name = which
    say(f"{factor}: NUTS for {name}")
    run = run_nuts(
        *calls[which],
        pointwise=pointwise,
        pointwise_kwargs=True,
        name=f"{factor} {name}",
        progress=clock_progress(say),
        **nuts,
    )
    out.warnings.extend(nuts_warnings(run))
    return run


def _laplace_sized(setup: _Setup, arrivals: str, lifetimes: str, out: TrafficFit) -> _Setup:
    """Leave out the candidates with more than :data:`LAPLACE_MAX_PARAMETERS` latent
    parameters (a group-size law over thousands of sizes, when thousands of artefacts
    arrived in one tick): their mode search and Hessian would cost the square of that.
    A candidate named on the command line is an error instead (NUTS samples it)."""
    calls, cands, laws = dict(setup.calls), list(setup.cands), list(setup.laws)
    for (factor, name), (_, model, kwargs, init) in setup.calls.items():
        d = laplace_dimension(model, kwargs, init)
        if d <= LAPLACE_MAX_PARAMETERS:
            continue
        option = "--arrivals" if factor == "arrivals" else "--lifetimes"
        if name in (arrivals, lifetimes):
            raise ValueError(
                f"{option} {name}: expected at most {LAPLACE_MAX_PARAMETERS} parameters for "
                f"--method em (the Laplace approximation), got {d}; use --method nuts"
            )
        del calls[factor, name]
        (cands if factor == "arrivals" else laws).remove(name)
        note = (
            f"{name} not offered: {d} parameters, more than the {LAPLACE_MAX_PARAMETERS} "
            "of the Laplace approximation (--method nuts compares it)"
        )
        key = "arrival_notes" if factor == "arrivals" else "lifetime_notes"
        out.attrs[key] = "; ".join(v for v in (out.attrs.get(key, ""), note) if v)
    return setup._replace(calls=calls, cands=cands, laws=laws)


def _optimise(which: tuple[str, str]) -> bool | str:
    """Whether a candidate's Laplace program is compiled with XLA's default optimisation:
    a likelihood whose loop runs several times longer at the cheap level (every run pays
    that; the compile is paid once per machine). The MMPP arrival models' forward pass over
    every tick (the shipped log: 7.6 ms a batch of 16 points instead of 1.2 ms, for about
    110 batches; the compile 0.3-0.9 s longer), the gamma stays' incomplete gammas (138
    batches: 0.22-0.29 s of CPU instead of 0.71-0.85 s; the compile 1.5-2 s longer, as long
    as the cheap one's with XLA's fusion emitters) and the Hawkes recursion with group sizes
    (groups+hawkes: 3.7-5.9 ms a batch of 32 points instead of 9.0-14.1 ms, 51 batches, so
    0.3-0.4 s of CPU less in every fit; the compile 0.5-1.0 s longer). The Hawkes recursion
    alone gains 0.03-0.16 s a fit for 0.5-0.8 s more compile, the group sizes alone 0.04 s
    (2026-11-28, the shipped log, the loaded 2-core machine). The gamma law's is compiled
    at XLA's first level (``"light"``): the same bits, 0.4-0.5 s less compile, under 0.1 s
    more a fit (2026-11-29)."""
    factor, name = which
    if factor == "stays":
        return "light" if name == "gamma" else False
    spec = ArrivalSpec.from_name(name)
    return spec.mmpp or (spec.hawkes and spec.groups)


#: Laplace approximations of the candidates run at once (threads): each waits mostly on
#: its program's XLA calls, which release the GIL, so two keep the two cores busy.
LAPLACE_THREADS = 2


def _laplace_order(whiches: Collection[tuple[str, str]]) -> list[tuple[str, str]]:
    """The candidates in the order their Laplace programs are compiled and run: those at
    XLA's default optimisation first (:func:`_optimise`), the stay laws before the arrival
    models, otherwise as given.

    The longest compiles first, so that the two threads that compile them finish together
    instead of one compiling the gamma law's incomplete gammas alone at the end (the
    shipped log's nine programs, CPU seconds one after the other: gamma 5.2, of it XLA
    4.3-4.7, now 2.0-2.3 since its incomplete gammas are one loop; groups+mmpp,
    groups+hawkes, mmpp 1.6-2.0; lognormal, weibull 0.9-1.0; hawkes, negbin, groups
    0.45-0.55; each with 0.3-0.8 s of tracing).
    """
    return sorted(whiches, key=lambda w: (not _optimise(w), w[0] != "stays"))


#: Threads of :func:`compile_laplace_ahead`: XLA compiles outside the GIL, so two keep
#: two cores busy while the fit's own thread goes on.
AHEAD_THREADS = 2


class LaplaceAhead:
    """The candidates' Laplace programs compiling in the background
    (:func:`compile_laplace_ahead`); a context manager that, on leaving, drops the
    programs not started yet (those compiling finish)."""

    def __init__(self, pool: ThreadPoolExecutor | None) -> None:
        self._pool = pool

    def cancel(self) -> None:
        """Drop the programs whose compile has not started."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)

    def wait(self) -> None:
        """Wait until every program is compiled (or failed: ``fit_traffic`` compiles it
        again and raises the error)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    def __enter__(self) -> LaplaceAhead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


def compile_laplace_ahead(
    key: jax.Array,
    data: LifecycleData,
    *,
    arrivals: str = "auto",
    lifetimes: str = "auto",
    clock_start: str | None = None,
) -> LaplaceAhead:
    """Start compiling the Laplace programs of :func:`fit_traffic`'s candidates, so that
    a fit's first run compiles them while the fit does its other work.

    ``fit_traffic(key, data, arrivals=..., lifetimes=..., clock_start=...,
    approximation="laplace" | "ranked")`` then finds each program compiled, or waits for
    the thread compiling it (the programs are kept in the process, as the NUTS programs of
    :class:`~are_stats.fitting.NutsPrefetch`). :data:`AHEAD_THREADS` threads compile
    them, the longest first (:func:`_laplace_order`), each with its model's abstract trace
    for its sites (which a fit would otherwise make on its own thread). Nothing is
    computed that the fit would not compute: the same candidates, programs and keys, so
    the fit is the same bit for bit. A candidate too large for the approximation is left
    out; an error (a log the fit refuses) is left to ``fit_traffic`` to raise.

    Parameters
    ----------
    key : jax PRNG key
        ``fit_traffic``'s key.
    data : LifecycleData
    arrivals, lifetimes : str
        As for ``fit_traffic``.
    clock_start : str, optional

    Returns
    -------
    LaplaceAhead
        Leaving it (``with``) drops the programs not started (a fit that failed).
    """
    out = TrafficFit("poisson", "exponential", "uniform")  # _setup's notes: not kept
    try:
        calls = _setup(key, data, arrivals, lifetimes, clock_start, out).calls
    except Exception:  # noqa: BLE001 - fit_traffic raises it, with its context
        return LaplaceAhead(None)
    pool = ThreadPoolExecutor(AHEAD_THREADS, "are-stats-laplace-ahead")
    for which in _laplace_order(calls):
        pool.submit(_ahead_program, calls[which], which)
    pool.shutdown(wait=False)
    return LaplaceAhead(pool)


def _ahead_program(call: tuple, which: tuple[str, str]) -> None:
    """Compile (or load) one candidate's Laplace program, as :func:`_run_candidate` will
    ask for it; a candidate past :data:`LAPLACE_MAX_PARAMETERS` is skipped."""
    _, model, kwargs, init = call
    if laplace_dimension(model, kwargs, init) > LAPLACE_MAX_PARAMETERS:
        return
    pointwise, site = _likelihood(which[0])
    laplace_program(model, kwargs, init, pointwise, _optimise(which), site)


def _run_candidate(calls: dict, which: tuple[str, str], n_draws: int) -> LaplaceRun:
    """Laplace approximation of one candidate model (:func:`run_laplace`), ``n_draws``
    draws; a pure function of the candidate's call, so candidates may run in threads."""
    factor, name = which
    key, model, kwargs, init = calls[which]
    pointwise, site = _likelihood(factor)
    return run_laplace(
        key,
        model,
        kwargs,
        init,
        num_draws=n_draws,
        pointwise=pointwise,
        name=f"{factor} {name}",
        optimise=_optimise(which),
        likelihood=site,
    )


#: Seconds between two updates of a Laplace stage's time left while it waits on its run.
LAPLACE_POLL = 0.5


def _queue_left(now: float, start: float, finished: list[float], ahead: int) -> float | None:
    """Seconds until ``ahead`` more runs of a queue finish, at the rate measured so far.

    The candidates' Laplace approximations run :data:`LAPLACE_THREADS` at a time, in
    order; their throughput is the runs finished per second since the queue started
    (compiling included: on a first fit each run compiles its program). The time left
    of the ``ahead``-th run still to finish is ``ahead`` runs at that rate from the last
    one finished, less the time since.

    Parameters
    ----------
    now, start : float
        Seconds now and when the queue started (:func:`time.perf_counter`).
    finished : list of float
        When each finished run finished.
    ahead : int
        Runs still to finish, the one waited for included (at least 1).

    Returns
    -------
    float or None
        Seconds left; None before a run has finished (no rate yet) and once the runs are
        overdue at that rate (the candidates' programs compile in 0.5-3 s of CPU each, so
        a rate is rough: an overdue run is not "about 1 s" from its end).
    """
    if not finished:
        return None
    last = max(finished)
    rate = (last - start) / len(finished)  # seconds per run
    left = last + ahead * rate - now
    return left if left > 0 else None


def _wait_laplace(
    which: tuple[str, str],
    runs: Mapping[tuple[str, str], Future[LaplaceRun]],
    say: Callable[[str], object],
    queue: tuple,
) -> LaplaceRun:
    """``runs[which].result()``, telling a stage clock (``say.left``) the time left while
    the fit waits on it, from the runs' throughput so far (:func:`_queue_left`), where the
    clock has no record of the stage (a first fit; a later one shows the record's)."""
    future = runs[which]
    left = getattr(say, "left", None)
    last = getattr(say, "last", None)
    factor, name = which
    recorded = last is not None and last(f"{factor}: Laplace approximation of {name}") is not None
    if left is None or recorded:
        return future.result()
    start, finished = queue
    order = list(runs)
    while True:
        try:
            return future.result(timeout=LAPLACE_POLL)
        except TimeoutError:
            done = sum(f.done() for f in runs.values())
            ahead = sum(not runs[w].done() for w in order[: order.index(which) + 1])
            words = f"{done}/{len(runs)} Laplace candidates done"
            left(_queue_left(time.perf_counter(), start, list(finished), max(ahead, 1)), words)


def _laplace_candidate(
    which: tuple[str, str],
    runs: Mapping[tuple[str, str], Future[LaplaceRun]],
    say: Callable[[str], object],
    out: TrafficFit,
    queue: tuple = (0.0, []),
) -> LaplaceRun:
    """The Laplace approximation of one candidate model from its run (``runs[which]``, a
    future of :func:`_run_candidate`; ``queue``: when the runs started and when each
    finished, for the time left, :func:`_wait_laplace`), with a word in ``out`` if its
    mode search did not converge."""
    factor, name = which
    say(f"{factor}: Laplace approximation of {name}")
    run = _wait_laplace(which, runs, say, queue)
    if not run.converged:
        out.warnings.append(
            f"{factor} {name}: the mode search of the Laplace approximation did not converge "
            "(its comparison may be off; --method nuts samples it instead)"
        )
    return run


def _choose_arrivals(
    out: TrafficFit, arrivals: str, cands: list[str], elpd: dict, ks: dict, runs: dict
) -> str:
    """Choose the arrival model by PSIS-LOO and store its table in ``out``; the choice."""
    order = sorted(cands, key=lambda n: (ArrivalSpec.from_name(n).n_params, ARRIVAL_SPECS.index(n)))
    # the bursty candidates are only ever compared by their Laplace approximation: where
    # its importance-sampled PSIS-LOO is unreliable, the (optimistic) elpd sets no bar
    shaky = unreliable_loo(
        {n: k for n, k in ks.items() if n in elpd and ArrivalSpec.from_name(n).bursts}
    )
    if arrivals == "auto":
        chosen, table = choose_simplest(elpd, order, shaky)
    else:
        _, table = choose_simplest(elpd, order, shaky)
        chosen = arrivals
        table["chosen"] = table.index == chosen
    _pareto_cols(table, ks)
    _diag_cols(table, runs)
    if shaky:
        note = (
            f"{', '.join(shaky)}: Pareto k > 0.7 on more than {UNRELIABLE_K_SHARE:.0%} of "
            "the bins, so its PSIS-LOO elpd (too optimistic there) did not set the bar"
        )
        out.attrs["arrival_notes"] = "; ".join(
            v for v in (out.attrs.get("arrival_notes"), note) if v
        )
    out.tables["arrivals"] = table
    out.arrival_model = chosen
    return chosen


def _store_arrival_draws(
    out: TrafficFit, chosen: str, s: dict, reshape: Callable[[np.ndarray], np.ndarray]
) -> None:
    """The chosen arrival model's draws into ``out.posterior`` (not the paper's Poisson)."""
    spec = ArrivalSpec.from_name(chosen)
    out.posterior["event_rate"] = reshape(s["event_rate"])
    if spec.negbin:
        out.posterior["arrival_phi"] = reshape(s["arrival_phi"])
    if spec.tod:
        out.posterior["arrival_tod"] = reshape(s["arrival_tod"])
        out.dims["arrival_tod"] = ["period"]
    if spec.groups:
        out.posterior["group_size_probs"] = reshape(s["group_size_probs"])
        out.dims["group_size_probs"] = ["group_size"]
    if spec.mmpp:
        for name in ("mmpp_factor", "mmpp_switch"):
            out.posterior[name] = reshape(s[name])
            out.dims[name] = ["mmpp_state"]
    if spec.hawkes:
        out.posterior["hawkes_branching"] = reshape(s["hawkes_branching"])
        out.posterior["hawkes_decay"] = reshape(s["hawkes_decay"])


def _fit_positions(
    data: LifecycleData, positions: str, grid: OccupancyGrid | None
) -> tuple[str, PositionDensity | None, PositionDensity | None, pd.DataFrame | None]:
    """Uniform or learned entry density (LOO over entry points), and the exit density."""
    if grid is None:
        if positions == "learned":
            raise ValueError(
                "--positions learned: expected the scene's map (manifest key 'map'), got none"
            )
        return "uniform", None, None, None
    if abs(float(grid.origin[2])) > 1e-9:
        if positions == "learned":
            raise ValueError(
                f"--positions learned: expected a map origin yaw of 0, got {grid.origin[2]}"
            )
        return "uniform", None, None, None
    free, res = coarse_free(grid.free, grid.resolution, POSITION_CELL)
    origin = (float(grid.origin[0]), float(grid.origin[1]))
    uni = uniform_position_density(free, res, origin)
    entered = ~data.truncated
    if data.x is None or data.y is None or entered.sum() < 2:
        if positions == "learned":
            raise ValueError(
                "--positions learned: expected entry positions (columns x, y) of at least two "
                "artefacts seen arriving"
            )
        return "uniform", uni, None, None
    xy = np.column_stack([data.x, data.y])[entered]
    if data.group is not None:  # one entry point per group: members are not independent
        _, first = np.unique(np.asarray(data.group)[entered], return_index=True)
        xy = xy[np.sort(first)]
    learned = fit_position_density(xy, free, res, origin)
    loo = learned.loo_logpdf
    on = np.isfinite(loo)
    base = np.full(loo.size, -np.log(free.sum()) - 2.0 * np.log(res))  # every cell alike
    elpd = {"uniform": base[on], "learned": loo[on]}
    if positions == "auto":
        chosen, table = choose_simplest(elpd, ["uniform", "learned"])
    else:
        _, table = choose_simplest(elpd, ["uniform", "learned"])
        chosen = positions
        table["chosen"] = table.index == chosen
    table["bandwidth_m"] = [0.0, learned.bandwidth]
    exit_density = None
    if data.x_exit is not None and data.y_exit is not None:
        ok = np.isfinite(data.x_exit) & np.isfinite(data.y_exit)
        if ok.sum() >= 2:
            exy = np.column_stack([data.x_exit, data.y_exit])[ok]
            exit_density = (
                fit_position_density(exy, free, res, origin) if chosen == "learned" else uni
            )
    return chosen, learned if chosen == "learned" else uni, exit_density, table
