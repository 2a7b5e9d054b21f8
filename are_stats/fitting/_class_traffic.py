"""Where and when each class of a labelled log comes (issue 31): entry and exit densities
per class, and class shares by time of day.

**Entry and exit densities per class** (partial pooling). Class ``c``'s density is the
Dirichlet-smoothed kernel density of :func:`~are_stats.traffic.fit_position_density` whose
prior base measure is not uniform but the density of the *other* classes' points (learned
the same way, uniform base):

``p_c(cell) = (alpha_c b_c(cell) + sum_{i in c} K_h(cell, x_i) / Z_h(x_i)) / (alpha_c + n_c)``

with ``alpha_c`` and ``h_c`` chosen by leave-one-out log-likelihood of the class's points.
A class seen a few times gets a large ``alpha_c`` and borrows the others' density; one with
fewer than :data:`MIN_CLASS_POINTS` points takes the pooled density as it is. The pool is
left-class-out, so the leave-one-out density of a point never sees that point. The
per-class densities and the pooled one (all points, uniform base) are compared by the
leave-one-out log density of the entry points, the units of the pooled position choice
(:func:`~are_stats.fitting.choose_simplest`). Exit densities (last sightings) follow the
entry choice.

**Class shares by time of day** (a log with a wall clock). The arrivals inside the window
are binned into :data:`N_SHARE_PERIODS` periods of the day; period ``p``'s shares are
``w_p ~ Dirichlet(kappa w)``, pooled toward the day's shares ``w``, with ``kappa``
log-uniform on a grid and ``w`` flat. The hyper-mean ``w`` is drawn by
sampling-importance-resampling from the overall shares' posterior ``Dirichlet(1 + n)``,
weighted by the Dirichlet-multinomial marginal of the periods' counts (summed over
``kappa``) over the proposal's likelihood (so the counts are not used twice); then
``kappa`` from its exact conditional on the grid, and ``w_p ~ Dirichlet(kappa w + n_p)``
(conjugate). A period without arrivals keeps draws around ``w``. The constant shares and
the time-of-day shares are compared by PSIS-LOO over the arrivals' classes
(``log w[c_i]`` against ``log w_{p_i}[c_i]``).

Class arrival rates follow: arrivals of class ``c`` in period ``p`` come at
``event_rate x area x tod_p x w_{p,c}`` (the pooled arrival law thinned by the shares).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.special import gammaln, logsumexp

from are_stats.fitting._traffic import choose_simplest, loo_pointwise
from are_stats.inputs import check_memory
from are_stats.traffic import DAY, PositionDensity, fit_position_density, numpy_rng, period_of

if TYPE_CHECKING:
    import arviz as az

__all__ = [
    "CLASS_POSITION_MODELS",
    "CLASS_SHARE_MODELS",
    "MIN_CLASS_POINTS",
    "MIN_ELPD_GAIN",
    "N_SHARE_PERIODS",
    "ClassPositions",
    "ClassShareClock",
    "attach_class_positions",
    "attach_class_shares_by_time",
    "class_position_densities",
    "fit_class_positions",
    "fit_class_shares_by_time",
]

#: Position models of a labelled log, simplest first.
CLASS_POSITION_MODELS = ("pooled", "per-class")
#: Share models of a labelled log with a clock, simplest first.
CLASS_SHARE_MODELS = ("constant", "time-of-day")
#: Fewest entry points of a class fitted on its own (fewer: the pooled density).
MIN_CLASS_POINTS = 2
#: Fewest nats of elpd by which a per-class or time-of-day model must beat the simpler one.
MIN_ELPD_GAIN = 4.0
#: Periods of the day of the time-of-day shares (hours, as the arrival model's).
N_SHARE_PERIODS = 24
#: Dirichlet prior masses tried per class: up to 1e5 (the others' density as it is).
_CLASS_ALPHAS = (0.1, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5)
#: Concentrations ``kappa`` of the time-of-day shares around the overall ones.
_KAPPAS = np.geomspace(0.3, 3e4, 41)


@dataclass(frozen=True)
class ClassPositions:
    """Entry (and exit) densities per class (see the module docstring).

    Attributes
    ----------
    labels : tuple of str
        Class names.
    model : {"pooled", "per-class"}
        The leave-one-out choice.
    entry : (K, H, W) float
        Each class's entry density (the pooled one for a class with few points).
    exit : (K, H, W) float or None
        Each class's exit density (None without exits).
    resolution : float
        Cell side (m).
    origin : (2,) float
        Map-frame corner of cell (0, 0).
    n_points : (K,) int
        Entry points of each class.
    alpha, bandwidth : (K,) float
        Each class's prior mass and bandwidth (``nan`` where the pooled density was taken).
    table : pandas.DataFrame
        The comparison (``elpd``, ``se``, ``elpd_diff``, ``dse``, ``chosen``).
    """

    labels: tuple[str, ...]
    model: str
    entry: np.ndarray
    exit: np.ndarray | None
    resolution: float
    origin: tuple[float, float]
    n_points: np.ndarray
    alpha: np.ndarray
    bandwidth: np.ndarray
    table: pd.DataFrame


def _per_class(
    xy: np.ndarray,
    cls: np.ndarray,
    k: int,
    free: np.ndarray,
    res: float,
    origin: npt.ArrayLike,
    pooled: PositionDensity,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(K, H, W)`` densities, ``(n,)`` leave-one-out log densities, alphas, bandwidths,
    points per class."""
    dens = np.empty((k, *free.shape))
    loo = np.array(pooled.loo_logpdf, float, copy=True)
    alpha = np.full(k, np.nan)
    bw = np.full(k, np.nan)
    n_c = np.bincount(cls, minlength=k)
    for c in range(k):
        mine = cls == c
        if n_c[c] < MIN_CLASS_POINTS:
            dens[c] = pooled.prob  # too few points: the pool (its LOO units are the pool's)
            continue
        others = xy[~mine]
        base = fit_position_density(others, free, res, origin).prob if others.size else None
        d = fit_position_density(xy[mine], free, res, origin, alphas=_CLASS_ALPHAS, base=base)
        dens[c], alpha[c], bw[c] = d.prob, d.alpha, d.bandwidth
        loo[mine] = d.loo_logpdf
    return dens, loo, alpha, bw, n_c


def fit_class_positions(
    entry_xy: npt.ArrayLike,
    entry_classes: npt.ArrayLike,
    labels: Sequence[str],
    free_mask: npt.ArrayLike,
    resolution: float,
    origin: npt.ArrayLike,
    *,
    exit_xy: npt.ArrayLike | None = None,
    exit_classes: npt.ArrayLike | None = None,
) -> ClassPositions:
    """Fit per-class entry (and exit) densities pooled toward the other classes'.

    Parameters
    ----------
    entry_xy : (n, 2) float
        Entry points (one per arriving group), map frame.
    entry_classes : (n,) int
        Class of each entry point, ``0..K-1``.
    labels : sequence of str
        The K class names.
    free_mask : (H, W) bool
        Free cells of the (coarse) grid the densities live on.
    resolution : float
        Its cell side (m).
    origin : (2,) float
        Map-frame corner of its cell (0, 0).
    exit_xy : (m, 2) float, optional
        Last sightings of the artefacts that left.
    exit_classes : (m,) int, optional
        Their classes.

    Returns
    -------
    ClassPositions

    Raises
    ------
    ValueError
        If the points and classes disagree in length, a class is outside ``0..K-1`` or
        there are fewer than two entry points.

    Examples
    --------
    >>> import numpy as np
    >>> free = np.ones((10, 10), bool)
    >>> xy = np.array([[0.5, 0.5], [0.6, 0.4], [9.5, 9.5], [9.4, 9.6]])
    >>> f = fit_class_positions(xy, [0, 0, 1, 1], ["a", "b"], free, 1.0, (0.0, 0.0))
    >>> f.entry.shape
    (2, 10, 10)
    """
    names = tuple(str(v) for v in labels)
    k = len(names)
    xy = np.asarray(entry_xy, float).reshape(-1, 2)
    cls = np.asarray(entry_classes)
    if cls.shape != (xy.shape[0],) or (cls.size and cls.dtype.kind not in "iu"):
        raise ValueError(f"entry_classes: expected ({xy.shape[0]},) integers, got {cls.shape}")
    if cls.size and (cls.min() < 0 or cls.max() >= k):
        raise ValueError(f"entry_classes: expected codes in 0..{k - 1}, got others")
    if xy.shape[0] < 2:
        raise ValueError(f"entry_xy: expected at least two entry points, got {xy.shape[0]}")
    free = np.asarray(free_mask, bool)
    # each class's entry and exit densities, the others' base and the kernel sums
    check_memory(8.0 * free.size * (2 * k + 8), f"the entry densities of {k} classes")
    pooled = fit_position_density(xy, free, resolution, origin)
    dens, loo, alpha, bw, n_c = _per_class(xy, cls, k, free, resolution, origin, pooled)
    base = np.asarray(pooled.loo_logpdf, float)
    on = np.isfinite(base) & np.isfinite(loo)
    model, table = _choose({"pooled": base[on], "per-class": loo[on]}, list(CLASS_POSITION_MODELS))
    exits = None
    if exit_xy is not None:
        exy = np.asarray(exit_xy, float).reshape(-1, 2)
        ecls = np.asarray(exit_classes, np.int64)
        if ecls.shape != (exy.shape[0],):
            raise ValueError(f"exit_classes: expected ({exy.shape[0]},) integers, got {ecls.shape}")
        if exy.shape[0] >= 2:
            pooled_exit = fit_position_density(exy, free, resolution, origin)
            if model == "per-class":
                exits = _per_class(exy, ecls, k, free, resolution, origin, pooled_exit)[0]
            else:
                exits = np.broadcast_to(pooled_exit.prob, (k, *free.shape)).copy()
    if model == "pooled":
        dens = np.broadcast_to(pooled.prob, dens.shape).copy()
    o = np.asarray(origin, float).ravel()
    return ClassPositions(
        labels=names,
        model=model,
        entry=dens,
        exit=exits,
        resolution=float(resolution),
        origin=(float(o[0]), float(o[1])),
        n_points=n_c,
        alpha=alpha,
        bandwidth=bw,
        table=table,
    )


def attach_class_positions(idata: az.InferenceData, fit: ClassPositions) -> az.InferenceData:
    """Store a :class:`ClassPositions` in a fit.

    ``constant_data`` gains ``class_entry_density`` (and ``class_exit_density``) over
    ``(class, pos_y, pos_x)`` with the attributes ``class_position_resolution`` and
    ``class_position_origin``; ``posterior.attrs`` gains ``class_position_model`` and
    ``loo_class_positions`` (CSV text).
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    dens = {"class_entry_density": fit.entry}
    if fit.exit is not None:
        dens["class_exit_density"] = fit.exit
    ds = xr.Dataset(
        {
            n: xr.DataArray(np.asarray(v, np.float64), dims=("class", "pos_y", "pos_x"))
            for n, v in dens.items()
        }
    )
    attrs = {
        "class_position_resolution": float(fit.resolution),
        "class_position_origin": np.asarray(fit.origin, np.float64),
    }
    if "constant_data" in idata.groups():
        merged = idata.constant_data.merge(ds)
        merged.attrs.update(idata.constant_data.attrs | attrs)
        idata.constant_data = merged
    else:
        ds.attrs.update(attrs)
        idata.add_groups({"constant_data": ds})
    idata.posterior.attrs["class_position_model"] = fit.model
    idata.posterior.attrs["loo_class_positions"] = fit.table.to_csv(float_format="%.6g")
    return idata


def class_position_densities(idata: az.InferenceData) -> tuple[PositionDensity, ...] | None:
    """The per-class entry densities of a fit whose LOO kept them, or None.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit (:func:`attach_class_positions`).

    Returns
    -------
    tuple of PositionDensity or None
        One per class (class ``c`` is ``fit_class_labels(idata)[c]``); None when the fit has
        no per-class densities or PSIS-LOO kept the pooled one.
    """
    if "constant_data" not in idata.groups() or "class_entry_density" not in idata.constant_data:
        return None
    if idata.posterior.attrs.get("class_position_model") != "per-class":
        return None
    cd = idata.constant_data
    res = float(np.asarray(cd.attrs["class_position_resolution"]).ravel()[0])
    o = np.asarray(cd.attrs["class_position_origin"], float).ravel()
    probs = np.asarray(cd["class_entry_density"].values, float)
    return tuple(
        PositionDensity(p, res, (float(o[0]), float(o[1])), 0.0, float("nan")) for p in probs
    )


@dataclass(frozen=True)
class ClassShareClock:
    """Class shares by time of day (see the module docstring).

    Attributes
    ----------
    weights : (S, P, K) float
        Draws of each period's shares (rows sum to 1).
    kappa : (S,) float
        Draws of the concentration around the overall shares.
    counts : (P, K) int
        Arrivals of each class in each period.
    model : {"constant", "time-of-day"}
        The PSIS-LOO choice.
    table : pandas.DataFrame
        The comparison.
    ess : float
        Effective sample size of the importance weights of the hyper-mean ``w``.
    """

    weights: np.ndarray
    kappa: np.ndarray
    counts: np.ndarray
    model: str
    table: pd.DataFrame
    ess: float = float("nan")


def _dm_marginal(kw: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Dirichlet-multinomial log marginal (up to the multinomial coefficient), summed over
    periods: ``kw (..., P, K)`` concentrations, ``n (P, K)`` counts."""
    a0 = kw.sum(-1)
    return np.sum(
        gammaln(a0) - gammaln(a0 + n.sum(-1)) + np.sum(gammaln(kw + n) - gammaln(kw), -1), -1
    )


def _log_dirichlet(w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Log density of ``Dirichlet(a)`` at the rows of ``w (S, K)``."""
    return gammaln(a.sum()) - gammaln(a).sum() + np.log(w) @ (a - 1.0)


def _choose(elpd: dict[str, np.ndarray], order: list[str]) -> tuple[str, pd.DataFrame]:
    """:func:`~are_stats.fitting.choose_simplest`, the richer model kept only when it is
    also better by more than :data:`MIN_ELPD_GAIN` nats (below that the difference is
    small and its standard error unreliable: two nearly equal models, e.g. the shares of
    a log inside one hour, have a tiny ``dse``)."""
    chosen, table = choose_simplest(elpd, order)
    if chosen != order[0] and float(table.loc[order[0], "elpd_diff"]) <= MIN_ELPD_GAIN:
        chosen = order[0]
        table["chosen"] = table.index == chosen
    return chosen, table


def uncompared(order: Sequence[str]) -> tuple[str, pd.DataFrame]:
    """The simplest model and a comparison table of zeros with it chosen: the outcome of
    :func:`_choose` when there is nothing to compare (one class, or no draws to compare on)."""
    table = pd.DataFrame(
        {
            "elpd": 0.0,
            "se": 0.0,
            "elpd_diff": 0.0,
            "dse": 0.0,
            "chosen": [True] + [False] * (len(order) - 1),
        },
        index=pd.Index(list(order), name="model"),
    )
    return order[0], table


def fit_class_shares_by_time(
    key: jax.Array,
    t_arrive: npt.ArrayLike,
    classes: npt.ArrayLike,
    overall: npt.ArrayLike,
    clock_offset: float,
    *,
    n_periods: int = N_SHARE_PERIODS,
    period: float = DAY,
    n_loo_draws: int = 1000,
) -> ClassShareClock:
    """Fit class shares per period of the day, pooled toward the overall shares.

    Parameters
    ----------
    key : jax PRNG key
        All randomness.
    t_arrive : (n,) float
        Arrival times of the artefacts that arrived inside the window (log time).
    classes : (n,) int
        Their classes, ``0..K-1``.
    overall : (S, K) float
        Draws of the constant shares (:attr:`ClassFit.weights`): the simpler model of the
        comparison; S draws are returned.
    clock_offset : float
        Time of day of ``t = 0`` (:func:`~are_stats.traffic.clock_offset`).
    n_periods : int
        Periods of the day.
    period : float
        Length of a day in the time unit.
    n_loo_draws : int
        Draws used by PSIS-LOO.

    Returns
    -------
    ClassShareClock

    Raises
    ------
    ValueError
        If times and classes disagree, or the overall draws are not (S, K) shares.
    """
    w = np.asarray(overall, float)
    if w.ndim != 2 or not np.allclose(w.sum(1), 1.0):
        raise ValueError(f"overall: expected (S, K) shares summing to 1, got {w.shape}")
    s, k = w.shape
    t = np.asarray(t_arrive, float).ravel()
    cls = np.asarray(classes)
    if cls.shape != t.shape or (cls.size and (cls.dtype.kind not in "iu" or cls.max() >= k)):
        raise ValueError(f"classes: expected ({t.size},) codes in 0..{k - 1}, got {cls.shape}")
    p_n = int(n_periods)
    check_memory(
        8.0 * 6 * 512 * _KAPPAS.size * p_n * k
        + 8.0 * s * p_n * k * 3
        + 8.0 * s * (_KAPPAS.size + 4 * k),
        f"the class shares by time of day of {t.size} arrivals",
    )
    per = period_of(t, float(clock_offset), p_n, float(period))
    counts = np.zeros((p_n, k), np.int64)
    np.add.at(counts, (per, cls.astype(np.int64)), 1)
    rng = numpy_rng(key)
    # the hyper-mean w: sampling-importance-resampling (flat prior), the target the
    # Dirichlet-multinomial marginal of the periods' counts summed over kappa's grid; the
    # proposal half the overall shares' posterior Dirichlet(1 + n), half a wider
    # Dirichlet(1 + eps n) (where the periods differ, or kappa is small, w is wide)
    n_tot = counts.sum(0).astype(float)
    eps = min(1.0, (k + 10.0) / max(float(n_tot.sum()), 1.0))
    a_near, a_wide = 1.0 + n_tot, 1.0 + eps * n_tot
    wide = rng.random(s) < 0.5
    prop = np.where(wide[:, None], rng.dirichlet(a_wide, s), rng.dirichlet(a_near, s))
    prop = np.maximum(prop, 1e-300)
    prop /= prop.sum(1, keepdims=True)
    log_prior = np.zeros(_KAPPAS.size)  # log-uniform: the grid is uniform in log kappa
    lp_all = np.empty((s, _KAPPAS.size))
    for j in range(0, s, 512):
        wb = prop[j : j + 512]  # (B, K)
        kw = _KAPPAS[None, :, None, None] * wb[:, None, None, :]  # (B, T, 1, K)
        lp_all[j : j + 512] = _dm_marginal(kw, counts[None, None]) + log_prior  # (B, T)
    log_q = np.logaddexp(_log_dirichlet(prop, a_near), _log_dirichlet(prop, a_wide))
    log_iw = logsumexp(lp_all, axis=1) - log_q
    iw = np.exp(log_iw - logsumexp(log_iw))
    ess = float(1.0 / np.sum(iw * iw))
    pick_w = rng.choice(s, size=s, p=iw)
    w_h, lp = prop[pick_w], lp_all[pick_w]
    # kappa given w from its exact conditional on the grid, then w_p (conjugate)
    lp = lp - logsumexp(lp, axis=1, keepdims=True)
    u = rng.random(s)
    pick = np.minimum(np.sum(np.cumsum(np.exp(lp), 1) < u[:, None], 1), _KAPPAS.size - 1)
    kappa = _KAPPAS[pick]
    conc = kappa[:, None, None] * w_h[:, None, :] + counts[None]  # (S, P, K)
    g = rng.gamma(np.maximum(conc, 1e-12))
    tot = g.sum(-1, keepdims=True)
    weights = np.where(tot > 0, g / np.where(tot > 0, tot, 1.0), w_h[:, None, :])
    d = min(int(n_loo_draws), s)
    if t.size:
        with np.errstate(divide="ignore"):
            lw = np.log(w[:d][:, cls])  # (D, n)
            lt = np.log(weights[:d][:, per, cls])
        elpd = {
            "constant": loo_pointwise(lw[None])[0],
            "time-of-day": loo_pointwise(lt[None])[0],
        }
        model, table = _choose(elpd, list(CLASS_SHARE_MODELS))
    else:
        model, table = uncompared(CLASS_SHARE_MODELS)
    return ClassShareClock(
        weights=weights, kappa=kappa, counts=counts, model=model, table=table, ess=ess
    )


def attach_class_shares_by_time(idata: az.InferenceData, fit: ClassShareClock) -> az.InferenceData:
    """Store a :class:`ClassShareClock` in a fit's ``posterior``.

    ``class_tod_weights`` over ``(chain, draw, period, class)``, ``class_share_kappa`` over
    ``(chain, draw)``; attributes ``class_share_model`` (the PSIS-LOO choice),
    ``class_tod_counts`` (arrivals per period and class, flattened), ``class_share_ess``
    (the importance sampler's effective sample size) and
    ``loo_class_shares`` (CSV text).
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

    post = idata.posterior
    c, d = post.sizes["chain"], post.sizes["draw"]
    s, p, k = fit.weights.shape
    if s != c * d:
        raise ValueError(f"fit: expected {c * d} draws (the posterior's), got {s}")
    post["class_tod_weights"] = xr.DataArray(
        fit.weights.reshape(c, d, p, k), dims=("chain", "draw", "period", "class")
    )
    post["class_share_kappa"] = xr.DataArray(fit.kappa.reshape(c, d), dims=("chain", "draw"))
    post.attrs["class_share_model"] = fit.model
    post.attrs["class_tod_counts"] = np.asarray(fit.counts, np.int64).ravel()
    post.attrs["class_share_ess"] = float(fit.ess)
    post.attrs["loo_class_shares"] = fit.table.to_csv(float_format="%.6g")
    return idata
