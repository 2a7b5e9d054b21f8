"""Posterior-predictive checks with numbers: does the chosen model look like the log?

The paper's model fits a log's averages; the checks here ask whether the world it
generates looks like the one it was fitted on. For the fit's chosen traffic models and for
the paper's, replicated windows (same window, area and map; a stationary start; one
posterior draw each, drawn by the one sampler) are summarised by

* ``N(t) var/mean``: the variance-to-mean ratio of the number present over the window
  (1 for the paper's Poisson; groups and bursts make it larger);
* ``N(t) peak``: the most artefacts present at once;
* ``zero gaps``: the fraction of gaps between consecutive arrivals that are zero at the
  log's time resolution (artefacts first seen in the same frame);
* ``stay cv``: the coefficient of variation of the stays seen from arrival to departure
  inside the window (1 for the exponential);
* ``entry to boundary (m)``: the mean distance of entry points to the nearest non-free
  cell or map edge (small when people enter through doors);
* burst statistics (times in seconds, the log's unit): ``arrivals var/mean (1 s)``,
  ``(10 s)`` and ``(60 s)``, the index of dispersion of the number of arrivals in
  consecutive bins of 1, 10 and 60 s (the counting process ``N(t)`` of arrivals; 1 for
  Poisson arrivals at every width, growing with the width for bursts that last longer
  than a bin, large at 1 s for groups); ``longest N(t) = 0 (s)``, the longest stretch with
  no one present; ``arrivals autocorr (30 s)``, the correlation of the number of arrivals
  in 10 s bins 30 s apart (0 for Poisson arrivals; positive when busy spells last).

Each row holds the observed value, the 5%, 50% and 95% predictive quantiles of each model
and a flag where the observed value falls outside the 90% band.
"""

from __future__ import annotations

import sys
import warnings
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from are_stats.fitting._criticism import count_path
from are_stats.fitting._fit import as_fit, traffic_draws
from are_stats.fitting._traffic import time_resolution
from are_stats.scenarios import generate_scenarios
from are_stats.traffic import boundary_distance, fold_in_key, key_from_seed

if TYPE_CHECKING:
    import arviz as az
    import jax
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.backend_bases import RendererBase
    from matplotlib.figure import Figure

__all__ = [
    "CROWDING_STATISTICS",
    "TRAFFIC_STATISTICS",
    "burst_statistics",
    "crowding_statistics",
    "plot_traffic_checks",
    "traffic_checks",
    "window_statistics",
]

#: The statistics of :func:`window_statistics`, in table order.
TRAFFIC_STATISTICS = (
    "N(t) var/mean",
    "N(t) peak",
    "zero gaps",
    "stay cv",
    "entry to boundary (m)",
    "arrivals var/mean (1 s)",
    "arrivals var/mean (10 s)",
    "arrivals var/mean (60 s)",
    "longest N(t) = 0 (s)",
    "arrivals autocorr (30 s)",
)

#: Bin widths (s) of the arrivals' index of dispersion.
DISPERSION_BINS = (1.0, 10.0, 60.0)
#: Bin width and lag (s) of the arrivals' autocorrelation.
AUTOCORR_BIN, AUTOCORR_LAG = 10.0, 30.0


def burst_statistics(
    t_arrive: np.ndarray, t_leave: np.ndarray, window: tuple[float, float]
) -> dict[str, float]:
    """The burst statistics of the module docstring for one window.

    Parameters
    ----------
    t_arrive : (n,) float
        Arrival times inside the window (``t0`` or earlier for those present at ``t0``;
        only those after ``t0`` count as arrivals).
    t_leave : (n,) float
        Leaving times (``inf`` when still present at the end).
    window : (t0, t1)

    Returns
    -------
    dict of str to float
        NaN where undefined (fewer than two bins, no arrivals, constant counts).
    """
    t0, t1 = float(window[0]), float(window[1])
    out: dict[str, float] = {}
    arrived = t_arrive[(t_arrive > t0) & (t_arrive < t1)] - t0
    for w in DISPERSION_BINS:
        n_bins = int((t1 - t0) // w)
        key = f"arrivals var/mean ({w:g} s)"
        out[key] = float("nan")
        if n_bins >= 2:
            c = np.bincount((arrived // w).astype(np.int64), minlength=n_bins)[:n_bins]
            if c.mean() > 0:
                out[key] = float(c.var(ddof=1) / c.mean())
    out["arrivals autocorr (30 s)"] = float("nan")
    n_bins = int((t1 - t0) // AUTOCORR_BIN)
    lag = int(round(AUTOCORR_LAG / AUTOCORR_BIN))
    if n_bins >= lag + 3:
        c = np.bincount((arrived // AUTOCORR_BIN).astype(np.int64), minlength=n_bins)[:n_bins]
        a, b = c[:-lag].astype(float), c[lag:].astype(float)
        if a.std() > 0 and b.std() > 0:
            out["arrivals autocorr (30 s)"] = float(np.corrcoef(a, b)[0, 1])
    # longest stretch with no one present: gaps in the union of [arrive, leave)
    lo = np.clip(np.asarray(t_arrive, float), t0, t1)
    hi = np.clip(np.asarray(t_leave, float), t0, t1)
    order = np.argsort(lo, kind="stable")
    lo, hi = lo[order], hi[order]
    covered = np.maximum.accumulate(np.concatenate([[t0], hi]))  # [i]: max(t0, hi[:i])
    gaps = np.concatenate([lo - covered[:-1], [t1 - covered[-1]]])
    out["longest N(t) = 0 (s)"] = float(max(np.max(gaps), 0.0))
    return out


def window_statistics(
    t_arrive: np.ndarray,
    t_leave: np.ndarray,
    truncated: np.ndarray,
    window: tuple[float, float],
    resolution: float,
    entry_xy: np.ndarray | None = None,
    free: tuple[np.ndarray, float, tuple[float, float]] | None = None,
) -> dict[str, float]:
    """The statistics of the module docstring for one window.

    Parameters
    ----------
    t_arrive : (n,) float
        Arrival times (any value where ``truncated``).
    t_leave : (n,) float
        Leaving times (NaN or beyond ``t1`` when still present at the end).
    truncated : (n,) bool
        Present at ``t0``.
    window : (t0, t1)
    resolution : float
        The log's time resolution (zero gaps are gaps below it).
    entry_xy : (n, 2) float, optional
        Entry points (rows of truncated artefacts are ignored).
    free : (mask, resolution, origin), optional
        The free cells the boundary distance is measured on.

    Returns
    -------
    dict of str to float
        NaN where a statistic is undefined (no arrivals, no complete stay, no positions).
    """
    t0, t1 = window
    ta = np.where(truncated, t0, t_arrive)
    tl = np.where(np.isfinite(t_leave), t_leave, np.inf)
    times = np.linspace(t0, t1, 241)[1:-1]
    n = count_path(ta, tl, times).astype(float)
    out = {s: float("nan") for s in TRAFFIC_STATISTICS}
    if n.mean() > 0:
        out["N(t) var/mean"] = float(n.var(ddof=1) / n.mean())
    out["N(t) peak"] = float(n.max()) if n.size else float("nan")
    arrived = np.sort(ta[~truncated & (ta < t1)])
    if arrived.size >= 2:
        ticks = np.floor((arrived - t0) / max(resolution, 1e-12) + 1e-9)
        out["zero gaps"] = float(np.mean(np.diff(ticks) == 0))
    whole = ~truncated & (tl < t1)
    stays = (tl - ta)[whole]
    if stays.size >= 3 and stays.mean() > 0:
        out["stay cv"] = float(stays.std(ddof=1) / stays.mean())
    out.update(burst_statistics(ta, tl, (t0, t1)))
    if entry_xy is not None and free is not None and (~truncated).any():
        mask, res, origin = free
        xy = np.asarray(entry_xy, float)[~truncated]
        ok = np.isfinite(xy).all(axis=1)
        if ok.any():
            out["entry to boundary (m)"] = float(
                np.mean(boundary_distance(xy[ok], mask, res, origin))
            )
    return out


def _replicate_statistics(
    t_arrive: np.ndarray,
    t_leave: np.ndarray,
    truncated: np.ndarray,
    bounds: np.ndarray,
    window: tuple[float, float],
    resolution: float,
) -> np.ndarray:
    """:func:`window_statistics` of many windows at once, without entry points.

    The replicated windows of :func:`traffic_checks` (400 in a report) took 0.3-0.5 s of
    CPU as one call each, most of it NumPy's per-call overhead on a few dozen rows. Here
    each statistic is one pass over all rows with the same arithmetic per window, so that
    every value is :func:`window_statistics`' bit for bit
    (tests/fitting/test_traffic_checks_batch.py): counts by ``bincount``; means and
    variances by NumPy's ``mean``/``var`` along each window's row of counts (a row's
    reduction is the 1-d one); the stays' mean and deviation window by window
    (:func:`_run_mean_std`); the autocorrelation by ``np.corrcoef``'s own steps, its
    product of each window's centred counts by ``np.dot`` as there.

    Parameters
    ----------
    t_arrive, t_leave : (n,) float
        The windows' rows one window after another (as :func:`window_statistics`).
    truncated : (n,) bool
    bounds : (R + 1,) int
        Window ``r`` is rows ``bounds[r]:bounds[r + 1]`` (empty windows allowed).
    window : (t0, t1)
    resolution : float

    Returns
    -------
    (R, S) float
        Columns in :data:`TRAFFIC_STATISTICS` order; ``entry to boundary (m)`` is NaN.
    """
    t0, t1 = window
    bounds = np.asarray(bounds, np.int64)
    n_win = bounds.size - 1
    seg = np.repeat(np.arange(n_win), np.diff(bounds))
    col = {s: i for i, s in enumerate(TRAFFIC_STATISTICS)}
    out = np.full((n_win, len(TRAFFIC_STATISTICS)), np.nan)
    ta = np.where(truncated, t0, t_arrive)
    tl = np.where(np.isfinite(t_leave), t_leave, np.inf)

    def per_window(values: np.ndarray, index: np.ndarray, width: int) -> np.ndarray:
        """(R, width) int: how many of each window's ``index`` fall in each column."""
        flat = np.bincount(seg[values] * (width + 1) + index, minlength=n_win * (width + 1))
        return flat.reshape(n_win, width + 1)[:, :width]

    # N(t) on count_path's grid: arrived (a <= t) less left (b <= t), as counts of rows
    times = np.linspace(t0, t1, 241)[1:-1]
    everyone = np.ones(ta.size, bool)
    ia = np.where(np.isnan(ta), 0, np.searchsorted(times, ta, side="left"))
    il = np.searchsorted(times, tl, side="left")  # NaN and inf: past the grid
    n = np.cumsum(per_window(everyone, ia, times.size), axis=1)
    n = (n - np.cumsum(per_window(everyone, il, times.size), axis=1)).astype(float)
    mean = n.mean(axis=1)
    ok = mean > 0
    out[ok, col["N(t) var/mean"]] = n[ok].var(axis=1, ddof=1) / mean[ok]
    out[:, col["N(t) peak"]] = n.max(axis=1)
    # zero gaps: consecutive arrivals (sorted in each window) in one tick of the log
    arrived = ~truncated & (ta < t1)
    order = np.lexsort((ta[arrived], seg[arrived]))
    a_seg, a_t = seg[arrived][order], ta[arrived][order]
    k = np.bincount(a_seg, minlength=n_win)
    ticks = np.floor((a_t - t0) / max(resolution, 1e-12) + 1e-9)
    same = (np.diff(ticks) == 0) & (a_seg[1:] == a_seg[:-1])
    zeros = np.bincount(a_seg[1:][same], minlength=n_win)
    ok = k >= 2
    out[ok, col["zero gaps"]] = zeros[ok] / (k[ok] - 1)
    # stay cv of the whole stays, each window's run of rows in row order
    whole = ~truncated & (tl < t1)
    m, sd = _run_mean_std((tl - ta)[whole], seg[whole], n_win, 3)
    ok = m > 0  # False where NaN
    out[ok, col["stay cv"]] = sd[ok] / m[ok]
    # burst statistics: arrivals after t0 in bins of each width
    after = (ta > t0) & (ta < t1)
    rel = ta[after] - t0
    for w in DISPERSION_BINS:
        n_bins = int((t1 - t0) // w)
        if n_bins >= 2:
            c = per_window(after, (rel // w).astype(np.int64), n_bins)
            mean = c.mean(axis=1)
            ok = mean > 0
            out[ok, col[f"arrivals var/mean ({w:g} s)"]] = c[ok].var(axis=1, ddof=1) / mean[ok]
    n_bins = int((t1 - t0) // AUTOCORR_BIN)
    lag = int(round(AUTOCORR_LAG / AUTOCORR_BIN))
    if n_bins >= lag + 3:
        c = per_window(after, (rel // AUTOCORR_BIN).astype(np.int64), n_bins)
        a, b = c[:, :-lag], c[:, lag:]
        ok = (a.max(axis=1) > a.min(axis=1)) & (b.max(axis=1) > b.min(axis=1))  # std > 0
        if ok.any():
            out[ok, col["arrivals autocorr (30 s)"]] = _corrcoefs(a[ok], b[ok])
    # longest stretch with no one present: each window's gaps in the union of its stays
    lo = np.clip(np.asarray(ta, float), t0, t1)
    hi = np.clip(np.asarray(tl, float), t0, t1)
    order = np.lexsort((lo, seg))  # stable in lo within each window, as argsort's
    lo, hi, s = lo[order], hi[order], seg[order]
    # covered[i]: max(t0, hi of the window's earlier rows), by exact integer ranks of hi
    rank = np.empty(hi.size, np.int64)
    by_hi = np.argsort(hi, kind="stable")
    rank[by_hi] = np.arange(1, hi.size + 1)
    key = s * (hi.size + 1) + rank
    first = np.ones(hi.size, bool)
    first[1:] = s[1:] != s[:-1]
    prev = np.empty(hi.size, np.int64)
    prev[1:] = key[:-1]
    prev[first] = s[first] * (hi.size + 1)  # rank 0: t0
    best = np.maximum.accumulate(prev)
    hi_of = np.concatenate([[t0], hi[by_hi]])
    gaps = lo - hi_of[best - s * (hi.size + 1)]
    last = np.full(n_win, float(t0))
    if hi.size:
        np.maximum.at(last, s, hi)
    longest = t1 - last
    if gaps.size:
        np.maximum.at(longest, s, gaps)
    out[:, col["longest N(t) = 0 (s)"]] = np.maximum(longest, 0.0)
    return out


def _run_mean_std(
    x: np.ndarray, seg: np.ndarray, n_win: int, min_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each window's ``x.mean()`` and ``x.std(ddof=1)`` of its run of ``x`` (``seg``
    non-decreasing), NaN for runs shorter than ``min_size`` (at least 1).

    NumPy's own, one run at a time: ``np.add.reduceat`` sums a run sequentially, not
    pairwise as ``sum`` does (other last bits from about 100 values on).
    """
    starts = np.searchsorted(seg, np.arange(n_win + 1))
    mean, sd = np.full(n_win, np.nan), np.full(n_win, np.nan)
    for r in np.flatnonzero(np.diff(starts) >= min_size):
        run = x[starts[r] : starts[r + 1]]
        mean[r] = run.mean()
        if run.size > 1:
            sd[r] = run.std(ddof=1)
    return mean, sd


def _corrcoefs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.corrcoef(a[r], b[r])[0, 1]`` of each row pair of ``a``, ``b`` ((R, m) counts),
    by its own steps: rows centred on their means, each pair's product by ``np.dot`` (the
    one call per row left), scaled by ``1 / (m - 1)``, divided by both deviations."""
    x = np.stack([a, b], axis=1).astype(float)  # (R, 2, m)
    x -= x.mean(axis=2)[:, :, None]
    c = np.stack([np.dot(xr, xr.T.conj()) for xr in x])
    c *= np.true_divide(1, x.shape[2] - 1)
    sd = np.sqrt(np.diagonal(c, axis1=1, axis2=2))
    return np.clip(c[:, 0, 1] / sd[:, 0] / sd[:, 1], -1, 1)


#: The statistics :func:`crowding_statistics` summarises: how crowded a window is.
CROWDING_STATISTICS = ("N(t) var/mean", "N(t) peak", "zero gaps", "stay cv")


def crowding_statistics(
    scenarios: pd.DataFrame, window: tuple[float, float], resolution: float
) -> dict[str, float]:
    """The median over scenarios of :data:`CROWDING_STATISTICS`, as the checks compute them.

    Each scenario of the table is one window (:func:`window_statistics`, all at once); a
    scenario without artefacts has no row and does not count.

    Parameters
    ----------
    scenarios : pandas.DataFrame
        Columns ``scenario``, ``t_arrive``, ``t_leave`` (float), ``truncated`` (bool): a
        scenarios table (:func:`~are_stats.scenarios.generate_scenarios`).
    window : (t0, t1)
        The scenarios' window (``(0, horizon)`` for generated ones).
    resolution : float
        The time resolution of the zero gaps (the fit's ``time_resolution``).

    Returns
    -------
    dict of str to float
        Keyed by :data:`CROWDING_STATISTICS`: the median over scenarios (NaN-skipping; NaN
        when no scenario defines it).

    Examples
    --------
    >>> table = pd.DataFrame(
    ...     {"scenario": [0, 0], "t_arrive": [10.0, 10.0], "t_leave": [30.0, 50.0],
    ...      "truncated": [False, False]}
    ... )
    >>> crowding_statistics(table, (0.0, 100.0), 1.0)["N(t) peak"]
    2.0
    """
    # the scenarios as groupby gives them (ids sorted, rows in table order), summarised
    # in one pass (_replicate_statistics: window_statistics' values, bit for bit)
    sid = scenarios["scenario"].to_numpy()
    order = np.argsort(sid, kind="stable")
    new_id = np.ones(sid.size, bool)
    new_id[1:] = sid[order][1:] != sid[order][:-1]
    bounds = np.append(np.flatnonzero(new_id), sid.size)
    stats = _replicate_statistics(
        scenarios["t_arrive"].to_numpy()[order],
        scenarios["t_leave"].to_numpy()[order],
        scenarios["truncated"].to_numpy()[order],
        bounds,
        window,
        resolution,
    )
    frame = pd.DataFrame(stats, columns=list(TRAFFIC_STATISTICS))
    return {k: float(frame[k].median()) for k in CROWDING_STATISTICS}


def _free_of(idata: az.InferenceData) -> tuple[np.ndarray, float, tuple[float, float]] | None:
    """The free cells the fit's position densities live on (None without a map)."""
    if "constant_data" not in idata.groups() or "entry_density" not in idata.constant_data:
        return None
    cd = idata.constant_data
    mask = np.asarray(cd["entry_density"].values) > 0
    res = float(np.asarray(cd.attrs["position_resolution"]).ravel()[0])
    o = np.asarray(cd.attrs["position_origin"], float).ravel()
    return mask, res, (float(o[0]), float(o[1]))


def traffic_checks(
    key: int | jax.Array, idata: az.InferenceData, n_replicates: int = 200
) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """Observed statistics against the chosen and the paper's predictive bands.

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicated windows.
    idata : arviz.InferenceData
        A fit written by ``are-stats fit`` (:func:`~are_stats.fitting.read_fit`).
    n_replicates : int
        Replicated windows per model.

    Returns
    -------
    table : pandas.DataFrame
        Indexed by statistic: ``observed``, and per model (``paper``, ``chosen``) the
        ``*_5%``, ``*_50%``, ``*_95%`` quantiles and ``*_flag`` (observed outside the band).
    replicates : dict of str to (R, S) ndarray
        The replicated statistics of each model (columns in table order).
    """
    post = idata.posterior
    obs = idata.observed_data
    w = np.asarray(post.attrs["window"], float)
    t0, t1 = float(w[0]), float(w[1])
    area = float(post.attrs["area"])
    res = float(np.asarray(post.attrs.get("traffic_time_resolution", 0.0)).ravel()[0])
    if not res > 0:
        res = time_resolution(obs["t_arrive"].values, obs["t_leave"].values, [t0, t1]) or 1e-6
    free = _free_of(idata)
    xy = None
    if "x" in obs and "y" in obs:
        xy = np.column_stack([obs["x"].values, obs["y"].values])
    observed = window_statistics(
        np.asarray(obs["t_arrive"].values, float),
        np.asarray(obs["t_leave"].values, float),
        np.asarray(obs["truncated"].values, bool),
        (t0, t1),
        res,
        xy,
        free,
    )
    base_key = key_from_seed(int(key)) if isinstance(key, int | np.integer) else key
    reps: dict[str, np.ndarray] = {}
    fit = as_fit(idata)  # decoded once for both models
    sources = {"paper": traffic_draws(fit, "paper")}
    chosen = traffic_draws(fit, "chosen")
    if not chosen[1].is_paper:
        sources["chosen"] = chosen
    for i, (model, (draws, laws)) in enumerate(sources.items()):
        grid = None if free is None else free[0]
        kw = {} if free is None else {"resolution": free[1], "origin": free[2]}
        df = generate_scenarios(
            fold_in_key(base_key, i),
            draws,
            n_replicates,
            t1 - t0,
            free_mask=grid,
            area=area,
            draw="random",
            headings=0,
            laws=laws,
            **kw,
        )
        sc = df["scenario"].to_numpy()
        order = np.argsort(sc, kind="stable")
        bounds = np.searchsorted(sc[order], np.arange(n_replicates + 1))
        ta = df["t_arrive"].to_numpy()[order] + t0
        tl = df["t_leave"].to_numpy()[order] + t0
        tr = df["truncated"].to_numpy()[order]
        pts = np.column_stack([df["x"].to_numpy(), df["y"].to_numpy()])[order]
        # every replicate's entry distances at once: boundary_distance is pointwise, and
        # its distance transform of the map took most of a window's statistics (400 of
        # them in a report); the means are window_statistics' own, on the same values
        entry = xy is not None and free is not None
        near = None
        if entry:
            keep = ~tr & np.isfinite(pts).all(axis=1)
            near = np.full(len(pts), np.nan)
            if keep.any():
                near[keep] = boundary_distance(pts[keep], *free)
        ta = np.ceil((ta - t0) / res - 1e-9) * res + t0  # the log's quantisation
        rows = _replicate_statistics(ta, tl, tr, bounds, (t0, t1), res)
        if entry:  # the windows with an entry point: the mean of their distances
            j = TRAFFIC_STATISTICS.index("entry to boundary (m)")
            seg = np.repeat(np.arange(n_replicates), np.diff(bounds))
            mean = _run_mean_std(near[keep], seg[keep], n_replicates, 1)[0]
            rows[~np.isnan(mean), j] = mean[~np.isnan(mean)]
        reps[model] = rows
    table = pd.DataFrame(index=pd.Index(TRAFFIC_STATISTICS, name="statistic"))
    table["observed"] = [observed[s] for s in TRAFFIC_STATISTICS]
    for model, r in reps.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a statistic undefined everywhere
            q = np.nanquantile(np.where(np.isfinite(r), r, np.nan), [0.05, 0.5, 0.95], axis=0)
        table[f"{model}_5%"], table[f"{model}_50%"], table[f"{model}_95%"] = q
        o = table["observed"].to_numpy()
        table[f"{model}_flag"] = np.isfinite(o) & ((o < q[0]) | (o > q[2]))
    return table, reps


#: Subplot parameters of :func:`plot_traffic_checks`'s 2 x 5 panels (figure fractions):
#: what constrained layout found for the shipped log; the sides and the gaps between
#: panels widen where an x tick label reaches past its panel (:func:`_widen_for_labels`).
_GRID = {
    "left": 0.003,
    "right": 0.997,
    "bottom": 0.078,
    "top": 0.925,
    "wspace": 0.045,
    "hspace": 0.32,
}
#: Pixels kept between two panels' tick labels, and between a label and the page's edge.
_LABEL_GAP = 4.0
#: Each statistic's x axis: what is counted, in which unit (the panel titles are the
#: table's row names, kept short).
_XLABELS = {
    "N(t) var/mean": "variance / mean of N(t) over the window",
    "N(t) peak": "most artefacts present at once",
    "zero gaps": "share of arrival gaps of 0 s (same frame)",
    "stay cv": "sd / mean of the stays seen whole",
    "entry to boundary (m)": "mean distance of entries to a wall (m)",
    "arrivals var/mean (1 s)": "variance / mean of arrivals per 1 s",
    "arrivals var/mean (10 s)": "variance / mean of arrivals per 10 s",
    "arrivals var/mean (60 s)": "variance / mean of arrivals per 60 s",
    "longest N(t) = 0 (s)": "longest time with no one present (s)",
    "arrivals autocorr (30 s)": "corr. of arrivals per 10 s, 30 s apart",
}
#: What a panel says when the log and every replicate have one value (nothing to compare),
#: where that value has a plain reading; others say the value.
_ALL_EQUAL = {
    ("longest N(t) = 0 (s)", 0.0): "never empty: someone is present\nthroughout the log and "
    "every\nreplicated window (nothing to compare)",
    ("zero gaps", 0.0): "no two arrivals in one frame\nin the log or any replicate\n"
    "(nothing to compare)",
}
#: The y axis of the first panel of each row (the panels' bars count replicated windows).
_YLABEL = "replicated windows"


def _overhangs(fig: Figure, ax: Axes, renderer: RendererBase) -> tuple[float, float]:
    """Pixels by which ``ax``'s x tick labels reach past its left and right edges.

    The labels' positions and texts come from the axis' locator and formatter, their
    widths from ``renderer``'s font metrics: no tick objects, nothing drawn.
    """
    # lazy: matplotlib.pyplot +0.7 s CPU on `import are_stats.fitting` (figures only)
    from matplotlib.font_manager import FontProperties
    from matplotlib.pyplot import rcParams

    lo, hi = sorted(ax.get_xlim())
    locs = [v for v in ax.xaxis.get_major_locator()() if lo - 1e-9 * (hi - lo) <= v <= hi]
    if not locs or hi <= lo:
        return 0.0, 0.0
    labels = ax.xaxis.get_major_formatter().format_ticks(locs)
    prop = FontProperties(size=rcParams["xtick.labelsize"])
    box = ax.get_position().transformed(fig.transFigure)  # pixels
    left = right = 0.0
    for v, text in zip(locs, labels, strict=True):
        if not text:
            continue
        w = renderer.get_text_width_height_descent(text, prop, ismath=False)[0]
        x = box.x0 + (v - lo) / (hi - lo) * box.width
        left = max(left, box.x0 - (x - w / 2))
        right = max(right, x + w / 2 - box.x1)
    return left, right


def _ylabel_room(ax: Axes, renderer: RendererBase) -> float:
    """Pixels that ``ax``'s y label (the panels have no y ticks) takes left of the panel:
    its rotated text's height and its pad; 0 without a label."""
    from matplotlib.font_manager import FontProperties  # lazy: as in _overhangs

    label = ax.yaxis.label
    if not label.get_text():
        return 0.0
    prop = FontProperties(size=label.get_fontsize())
    height = renderer.get_text_width_height_descent(label.get_text(), prop, ismath=False)[1]
    return height + renderer.points_to_pixels(ax.yaxis.labelpad)


def _say(ax: Axes, text: str) -> None:
    """Write ``text`` in the middle of a panel that has nothing to draw (and no x ticks)."""
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.35")
    ax.set_xticks([])


def _widen_for_labels(fig: Figure, axes: np.ndarray) -> None:
    """Widen the sides and the gaps of ``fig``'s grid of ``axes`` (rows x columns) where
    x tick labels reach past their panels, so that no two panels' labels meet and none
    leaves the page (a layout engine's guarantee, for the figure's only variable text)."""
    from matplotlib.backends.backend_agg import RendererAgg  # lazy: as in plot_traffic_checks

    renderer = RendererAgg(1, 1, fig.dpi)
    rows, cols = axes.shape
    hang = np.zeros((rows, cols, 2))
    for r in range(rows):
        for c in range(cols):
            if axes[r, c].get_visible():
                hang[r, c] = _overhangs(fig, axes[r, c], renderer)
    width = fig.bbox.width
    ylabel = max((_ylabel_room(ax, renderer) for ax in axes[:, 0] if ax.get_visible()), default=0.0)
    left = max(_GRID["left"], (max(hang[:, 0, 0].max(), ylabel) + _LABEL_GAP) / width)
    right = min(_GRID["right"], 1.0 - (hang[:, -1, 1].max() + _LABEL_GAP) / width)
    plain = (
        _GRID["wspace"] * (_GRID["right"] - _GRID["left"]) / (cols + _GRID["wspace"] * (cols - 1))
    )
    gap = max(plain * width, float((hang[:, :-1, 1] + hang[:, 1:, 0]).max()) + _LABEL_GAP)
    if left == _GRID["left"] and right == _GRID["right"] and gap == plain * width:
        return
    panel = ((right - left) * width - (cols - 1) * gap) / cols
    axes[0, 0].get_gridspec().update(left=left, right=right, wspace=gap / panel)


def _add_outline(ax: Axes, values: np.ndarray, bins: np.ndarray, colour: str, label: str) -> None:
    """Draw the histogram of ``values`` over ``bins`` on ``ax`` as one filled outline: the
    polygon, colours and limits of ``ax.hist(values, bins, histtype="stepfilled",
    alpha=0.55)``.

    The data limits come from the polygon's vertices at once; ``Axes.add_patch`` (which
    ``hist`` calls) walks the outline as Bezier segments in Python, 9 ms a panel.
    """
    from matplotlib.patches import Polygon  # lazy: as in plot_traffic_checks

    counts = np.histogram(values, bins)[0].astype(np.float64)
    n = len(bins)
    x = np.zeros(4 * n - 3)  # the outline hist draws: up and across the bins, back on y = 0
    y = np.zeros(4 * n - 3)
    x[0 : 2 * n - 1 : 2], x[1 : 2 * n - 1 : 2] = bins, bins[:-1]
    x[2 * n - 1 :] = x[1 : 2 * n - 1][::-1]
    y[1 : 2 * n - 1 : 2] = y[2 : 2 * n : 2] = counts
    y[0] = y[-1]
    patch = Polygon(np.column_stack([x[:-1], y[:-1]]), closed=True, facecolor=colour)
    patch.set(alpha=0.55, label=label)
    patch.sticky_edges.y.append(0)  # the bars stand on the axis, as hist's do
    ax.add_artist(patch)
    ax.update_datalim(patch.get_xy())


def plot_traffic_checks(table: pd.DataFrame, reps: dict[str, np.ndarray]) -> Figure:
    """One panel per statistic: each model's replicated distribution and the observed value.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib  # lazy: figures only (pyplot +0.7 s CPU on `import are_stats.fitting`)

    if "matplotlib.pyplot" not in sys.modules:  # headless default; never switch a live
        matplotlib.use("Agg")  # session's backend (a notebook's inline one)
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    colours = {"paper": "tab:grey", "chosen": "tab:blue"}
    n = len(TRAFFIC_STATISTICS)
    cols = (n + 1) // 2
    # a fixed grid: the panels carry no y ticks and their titles, x tick labels and x
    # labels have one height, so only the x tick labels' widths (and the first column's y
    # labels) vary (_widen_for_labels); constrained
    # layout's solver cost a repeated fit 0.2-0.4 s of CPU for the same picture
    fig, axes = plt.subplots(2, cols, figsize=(3.2 * cols, 6.4), gridspec_kw=_GRID)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for j, (ax, stat) in enumerate(zip(axes.ravel()[:n], TRAFFIC_STATISTICS, strict=True)):
        o = table.loc[stat, "observed"]
        values = [r[:, j][np.isfinite(r[:, j])] for r in reps.values()]
        allv = np.concatenate([v for v in values if v.size] + [np.array([o])])
        allv = allv[np.isfinite(allv)]
        ax.set_title(stat, fontsize=10)
        ax.set_xlabel(_XLABELS.get(stat, stat), fontsize=8, labelpad=2)
        ax.set_yticks([])  # bar heights are counts of replicates: the label says so
        if allv.size == 0:
            _say(ax, "not defined\nfor this log")
            continue
        lo, hi = float(allv.min()), float(allv.max())
        if lo == hi:  # the log and every replicate agree: a lone bar would say nothing
            value = f"{lo:g}"
            _say(ax, _ALL_EQUAL.get((stat, lo), f"the log and every replicate:\n{value}"))
            continue
        pad = 0.05 * (hi - lo)
        bins = np.linspace(lo - pad, hi + pad, 30)
        for model, v in zip(reps, values, strict=True):
            if v.size:  # one filled outline per model, not a rectangle per bin (the same
                # picture: the figure's 580 bars took 0.4 s of a repeated fit's CPU)
                _add_outline(ax, v, bins, colours.get(model, "tab:orange"), model)
        if np.isfinite(o):
            ax.axvline(o, color="black", lw=2, label="observed")
        ax.autoscale_view()
        misfit = [m for m in reps if bool(table.loc[stat, f"{m}_flag"])]
        if misfit:
            ax.text(
                0.98,
                0.97,
                "outside 90%:\n" + ", ".join(misfit),
                ha="right",
                va="top",
                transform=ax.transAxes,
                fontsize=8,
                color="tab:red",
            )
        if j % cols == 0:
            ax.set_ylabel(_YLABEL, fontsize=8, labelpad=2)
    # one row in the title band, left of the title: a fixed place (no search for the
    # emptiest corner of a panel at every draw), clear of every panel's data
    entries: dict[str, Artist] = {}  # label -> handle, in the panels' order
    for ax in axes.flat[:n]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if entries:
        fig.legend(
            list(entries.values()),
            list(entries),
            loc="upper left",
            bbox_to_anchor=(0.0, 1.0),
            ncols=len(entries),
            fontsize=8,
            frameon=False,
            borderaxespad=0.2,
        )
    fig.suptitle(
        "Posterior-predictive checks: replicated windows of each model vs the log", y=0.994
    )
    _widen_for_labels(fig, axes)
    return fig
