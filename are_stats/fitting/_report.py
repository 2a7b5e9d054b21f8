"""Summary table and posterior-predictive checks of a life-cycle fit (``are-stats report``).

Real traffic is rarely Poisson, so every fit is criticised against replicated windows drawn
from its own posterior: the same window and area, a stationary start, one posterior draw
per replicate (:func:`are_stats.scenarios.generate_scenarios`). The checks compare

* ``N(t)``, the artefacts present over the window, with the predictive 50% / 90% bands;
* inter-arrival times (ECDF against the predictive ECDF band);
* dwell times: the Kaplan-Meier curve of the observed stays (right-censored at ``t1``)
  against the fitted exponential survival band;
* arrivals per hour of the day (the paper's homogeneous rate predicts a flat profile);
* the dispersion index of arrival counts per bin (1 for Poisson) against its predictive
  distribution, with the posterior-predictive p-value;
* the histogram of marks against the fitted mixture of eq. (1).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np
import pandas as pd

from are_stats._atomic import atomic_path, check_writable
from are_stats._lazy import arviz as az
from are_stats.fitting._class_report import (
    class_share_checks,
    plot_class_checks,
    plot_class_entries,
    plot_class_shares_by_hour,
)
from are_stats.fitting._classes import class_checks
from are_stats.fitting._criticism import count_path, hour_of_day_counts, kaplan_meier
from are_stats.fitting._fit import posterior_draws
from are_stats.fitting._motion_store import motion_tables
from are_stats.fitting._png import write_png
from are_stats.fitting._traffic_checks import plot_traffic_checks, traffic_checks
from are_stats.inputs import check_memory, get_int
from are_stats.scenarios import ScenarioSize, check_scenario_size, generate_scenarios
from are_stats.traffic import clock_offset

if TYPE_CHECKING:
    import jax
    from matplotlib.axes import Axes
    from matplotlib.backend_bases import RendererBase
    from matplotlib.figure import Figure

    from are_stats.inputs import Source

    class _Observed(TypedDict):
        """The observed log of a fit as the checks read it (:func:`_observed`)."""

        t_arrive: np.ndarray
        t_leave: np.ndarray
        censored: np.ndarray
        truncated: np.ndarray
        marks: np.ndarray | None
        window: tuple[float, float]
        area: float


__all__ = [
    "PARAMETERS",
    "sampler_warnings",
    "check_report_outputs",
    "check_report_size",
    "fit_summary",
    "predictive_windows",
    "PredictiveChecks",
    "predictive_checks",
    "plot_checks",
    "read_traffic_checks",
    "write_report",
]

PARAMETERS = ("arrival_rate", "leave_rate", "mix_weights", "mix_rates")


def sampler_warnings(idata: az.InferenceData, summary: pd.DataFrame) -> list[str]:
    """What a user must know about the sampler of a fit: divergences and r_hat.

    The NUTS driver's own words when the fit stored them (``nuts_warnings``:
    divergences and split-r_hat of every latent site); otherwise the divergent
    transitions and the parameters of ``summary`` with r_hat > 1.01.

    Parameters
    ----------
    idata : arviz.InferenceData or Fit
    summary : pandas.DataFrame
        :func:`fit_summary` of the fit.

    Returns
    -------
    list of str
    """
    idata = getattr(idata, "idata", idata)
    if "sample_stats" in idata.groups() and "nuts_warnings" in idata.sample_stats.attrs:
        text = str(idata.sample_stats.attrs["nuts_warnings"])
        return [w for w in text.splitlines() if w.strip()]
    out = []
    if "sample_stats" in idata.groups() and "diverging" in idata.sample_stats:
        n_div = int(idata.sample_stats["diverging"].sum())
        if n_div:
            out.append(f"{n_div} divergent transitions: the posterior may be biased")
    r_hat = summary["r_hat"].to_numpy(dtype=float) if "r_hat" in summary else np.array([])
    bad = summary.index[np.isfinite(r_hat) & (r_hat > 1.01)].tolist()
    if bad:
        out.append(f"r_hat > 1.01 for {', '.join(bad)}: run longer chains (--samples)")
    return out


def fit_summary(idata: az.InferenceData) -> pd.DataFrame:
    """Posterior summary: mean, sd, 94% HDI, MCSE, bulk/tail ESS and r_hat per parameter.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit written by :func:`are_stats.fitting.fit_log` / ``are-stats fit``.

    Returns
    -------
    pandas.DataFrame
        ArviZ's summary, one row per scalar parameter. For single-chain fits (the ``em``
        method) r_hat is undefined (NaN).
    """
    names = [n for n in PARAMETERS if n in idata.posterior]
    # r_hat of a single chain / bootstrap draws: ArviZ warns through both warnings and its
    # logger ("Shape validation failed" for one chain), which printed on every em fit; the
    # logger is ArviZ's own instance, not registered with logging.getLogger
    log = getattr(az, "_log", None)
    if not isinstance(log, logging.Logger):
        log = logging.getLogger("arviz")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), _numpy_paths():
            warnings.simplefilter("ignore")
            return az.summary(idata, var_names=names, round_to="none")
    finally:
        log.setLevel(level)


@contextlib.contextmanager
def _numpy_paths() -> Iterator[None]:
    """ArviZ's NumPy code paths, not its numba ones, inside the block.

    Where numba is installed (PyMC brings it), ArviZ's summary compiles its variance kernel
    in every new process: 0.15-0.35 s, several times what the summary of a fit costs in
    NumPy. The values agree to rounding (1e-10 relative in ``ess_tail``). ArviZ's own flag
    is restored on exit, so a user's later ArviZ calls keep numba.
    """
    flags = getattr(az, "Numba", None)
    before = bool(getattr(flags, "numba_flag", False))
    if before:
        flags.numba_flag = False
    try:
        yield
    finally:
        if before:
            flags.numba_flag = True


def _observed(idata: az.InferenceData) -> _Observed:
    obs = idata.observed_data
    out = {n: np.asarray(obs[n].values) for n in ("t_arrive", "t_leave", "censored", "truncated")}
    out["marks"] = np.asarray(obs["marks"].values) if "marks" in obs else None
    window = np.asarray(idata.posterior.attrs["window"], dtype=float)
    out["window"] = (float(window[0]), float(window[1]))
    out["area"] = float(idata.posterior.attrs["area"])
    return out


#: Mark values drawn at most in the marks panel's mixture band (draws x components x marks).
_MARK_PANEL_DRAWS = 200


def check_report_size(idata: az.InferenceData, n_replicates: int, source: Source = "fit") -> None:
    """Refuse, before drawing anything, a report past the memory or work limit.

    The replicated windows hold about ``n_replicates x lambda x area x (t1 - t0 + 1/mu)``
    artefacts; the marks panel evaluates the mixture at every mark up to the largest
    observed one for up to 200 draws; the dwell panel the survival of every draw at 200
    times.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit (validated by :func:`are_stats.fitting.read_fit`).
    n_replicates : int
        Replicated windows.
    source : str
        What the user gave (the fit file and option), named in the error.

    Raises
    ------
    are_stats.inputs.LimitError
        If the report would need more memory or work than the limits.
    """
    n_replicates = get_int(n_replicates, "n_replicates", "", lo=1)
    obs = _observed(idata)
    t0, t1 = obs["window"]
    draws = posterior_draws(idata)
    check_scenario_size(draws, ScenarioSize(n_replicates, t1 - t0, obs["area"]), str(source))
    n_draws = draws["leave_rate"].shape[0]
    check_memory(n_draws * 200 * 8.0 * 3, f"the dwell panel of {n_draws} draws", source)
    check_memory(n_replicates * 201 * 8.0 * 4, "the N(t) replicates", source)
    marks = obs["marks"]
    if marks is not None and marks.size and "mix_rates" in draws:
        k = draws["mix_rates"].shape[-1]
        n_k = float(np.max(marks)) + 6.0
        sub = min(_MARK_PANEL_DRAWS, n_draws)
        check_memory(
            sub * k * n_k * 8.0 * 3,
            f"the marks panel (marks up to {int(np.max(marks))}, {k} components)",
            source,
        )


def predictive_windows(
    key: int | jax.Array, idata: az.InferenceData, n_replicates: int = 200
) -> pd.DataFrame:
    """Replicated observation windows from the posterior (stationary start).

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicates.
    idata : arviz.InferenceData
        The fit.
    n_replicates : int
        Number of replicated windows (posterior draws taken at random).

    Returns
    -------
    pandas.DataFrame
        The scenario table of :func:`are_stats.scenarios.generate_scenarios` with times
        shifted to the fit's window ``[t0, t1]``.
    """
    obs = _observed(idata)
    t0, t1 = obs["window"]
    df = generate_scenarios(
        key,
        posterior_draws(idata),
        n_scenarios=n_replicates,
        horizon=t1 - t0,
        area=obs["area"],
        start="stationary",
        draw="random",
        headings=0,
    )
    df["t_arrive"] = df["t_arrive"] + t0
    df["t_leave"] = df["t_leave"] + t0
    return df


class PredictiveChecks:
    """Observed summaries and their posterior-predictive replicates.

    Attributes
    ----------
    times : (m,) float
        Grid of the ``N(t)`` check.
    counts_obs : (m,) int
        Observed ``N(t)``.
    counts_rep : (R, m) int
        Replicated ``N(t)``.
    gaps_obs : (g,) float
        Observed inter-arrival times.
    gaps_rep : list of arrays
        Replicated inter-arrival times.
    km : KaplanMeier
        Kaplan-Meier curve of the observed stays (arrival observed).
    leave_rate : (S,) float
        Posterior draws of ``mu`` for the survival band.
    hours_obs : (24,) int
        Observed arrivals per hour of the day.
    hours_rep : (R, 24) int
        Replicated arrivals per hour of the day.
    dispersion_obs : float
        Observed dispersion index of arrivals per bin.
    dispersion_rep : (R,) float
        Replicated dispersion indices.
    dispersion_pvalue : float
        Two-sided posterior-predictive p-value of the dispersion index.
    bin_width : float
        Width of the count bins of the dispersion check (seconds).
    marks_obs : (n,) int or None
        Observed marks.
    mix_weights, mix_rates : (S, K) float or None
        Posterior draws of the mixture.
    """

    def __init__(self, **kw: object) -> None:
        self.__dict__.update(kw)


def fit_clock_offset(idata: az.InferenceData) -> float | None:
    """Time of day (s) of ``t = 0`` from the fit's ``traffic_clock_start``; None without."""
    clock = idata.posterior.attrs.get("traffic_clock_start")
    return None if clock is None else clock_offset(str(clock))


def _dispersion(t: np.ndarray, t0: float, t1: float, width: float) -> float:
    n_bins = int((t1 - t0) // width)
    c = np.bincount(((t - t0) // width).astype(np.int64), minlength=n_bins)[:n_bins]
    return float(c.var(ddof=1) / c.mean()) if c.mean() > 0 else float("nan")


def predictive_checks(
    key: int | jax.Array,
    idata: az.InferenceData,
    n_replicates: int = 200,
    clock_offset: float | None = None,
    n_bins: int = 60,
) -> PredictiveChecks:
    """Compute every posterior-predictive check of the module docstring.

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicates.
    idata : arviz.InferenceData
        The fit.
    n_replicates : int
        Replicated windows.
    clock_offset : float, optional
        Time of day (seconds after midnight) at ``t = 0`` of the log; None: the fit's
        ``clock_start`` when it has one, else no hour-of-day check (a log without a clock
        says nothing about the time of day).
    n_bins : int
        Number of equal bins of the window for the dispersion index.

    Returns
    -------
    PredictiveChecks
    """
    obs = _observed(idata)
    t0, t1 = obs["window"]
    if clock_offset is None:
        clock_offset = fit_clock_offset(idata)
    hour_clock = 0.0 if clock_offset is None else float(clock_offset)
    rep = predictive_windows(key, idata, n_replicates)
    times = np.linspace(t0, t1, 201)
    counts_obs = count_path(obs["t_arrive"], obs["t_leave"], times)
    arrive_rep = np.where(rep["truncated"].to_numpy(), np.nan, rep["t_arrive"].to_numpy())
    leave_rep = rep["t_leave"].to_numpy()
    sid = rep["scenario"].to_numpy()
    groups = np.split(np.arange(sid.size), np.flatnonzero(np.diff(sid)) + 1)
    present = np.unique(sid)
    counts_rep = np.zeros((n_replicates, times.size), dtype=np.int64)
    gaps_rep, hours_rep, disp_rep = [], np.zeros((n_replicates, 24), np.int64), []
    width = (t1 - t0) / n_bins
    for s, idx in zip(present, groups, strict=True):
        counts_rep[s] = count_path(arrive_rep[idx], leave_rep[idx], times)
        a = arrive_rep[idx]
        a = np.sort(a[np.isfinite(a)])
        gaps_rep.append(np.diff(a))
        hours_rep[s] = hour_of_day_counts(a, 86400.0, 24, hour_clock)
        disp_rep.append(_dispersion(a, t0, t1, width))
    for _ in np.setdiff1d(np.arange(n_replicates), present):  # empty replicate windows
        gaps_rep.append(np.array([]))
        disp_rep.append(float("nan"))
    arrived = np.sort(obs["t_arrive"][~obs["truncated"]])
    stays = ~obs["truncated"]
    dwell = np.where(obs["censored"], t1, obs["t_leave"]) - obs["t_arrive"]
    km = kaplan_meier(dwell[stays], obs["censored"][stays]) if stays.any() else None
    disp_obs = _dispersion(arrived, t0, t1, width)
    d = np.asarray(disp_rep)
    d = d[np.isfinite(d)]
    p = 2 * min((d >= disp_obs).mean(), (d <= disp_obs).mean()) if d.size else float("nan")
    draws = posterior_draws(idata)
    return PredictiveChecks(
        times=times,
        counts_obs=counts_obs,
        counts_rep=counts_rep,
        gaps_obs=np.diff(arrived),
        gaps_rep=gaps_rep,
        km=km,
        leave_rate=draws["leave_rate"],
        hours_obs=hour_of_day_counts(arrived, 86400.0, 24, hour_clock),
        clock_offset=clock_offset,
        hours_rep=hours_rep,
        dispersion_obs=disp_obs,
        dispersion_rep=np.asarray(disp_rep),
        dispersion_pvalue=float(min(p, 1.0)),
        bin_width=width,
        marks_obs=obs["marks"],
        mix_weights=draws.get("mix_weights"),
        mix_rates=draws.get("mix_rates"),
        window=(t0, t1),
    )


def _no_data(ax: Axes, why: str) -> None:
    ax.text(0.5, 0.5, why, ha="center", va="center", transform=ax.transAxes, color="0.4")
    ax.plot([], [], " ", label="no data")


def _band(ax, x, reps, color, label, step=False):
    # np.nanquantile goes column by column (apply_along_axis: 0.05-0.1 s of CPU for the
    # overview's four bands); without NaN np.quantile gives the same values in one call
    reps = np.asarray(reps)
    quantile = np.nanquantile if np.isnan(reps).any() else np.quantile
    q = quantile(reps, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    kw = {"step": "post"} if step else {}
    ax.fill_between(x, q[0], q[4], color=color, alpha=0.18, lw=0, label=f"{label} 90%", **kw)
    ax.fill_between(x, q[1], q[3], color=color, alpha=0.35, lw=0, label=f"{label} 50%", **kw)


def plot_checks(checks: PredictiveChecks) -> dict[str, Figure]:
    """Draw the six posterior-predictive checks, one matplotlib figure each.

    Parameters
    ----------
    checks : PredictiveChecks
        Output of :func:`predictive_checks`.

    Returns
    -------
    dict
        ``{name: matplotlib.figure.Figure}`` with names ``ppc_counts``,
        ``ppc_interarrival``, ``ppc_dwell``, ``ppc_hour_of_day``, ``ppc_dispersion`` and,
        for logs with marks, ``ppc_marks``; plus ``criticism`` with all panels.
    """
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    overview, panels = _overview(checks)
    overview.tight_layout()  # a figure to show: laid out to its labels, whatever they are
    figs: dict[str, Figure] = {}
    for name in panels:
        fig, ax = plt.subplots(figsize=(6, 4))
        _draw_panel(name, ax, checks, checks.window[0])
        fig.tight_layout()
        figs[f"ppc_{name}"] = fig
    figs["criticism"] = overview
    return figs


def _overview(checks: PredictiveChecks) -> tuple[Figure, dict[str, Axes]]:
    """The ``criticism`` figure: every check's panel on one page, on a fixed grid
    (:data:`_OVERVIEW_GRID`; :func:`plot_checks` and, where labels do not fit,
    :func:`_overview_images` lay it out to its labels).

    Returns
    -------
    figure, panels
        The figure and ``{check name: its axes}`` in the order drawn.
    """
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    c = checks
    names = ["counts", "interarrival", "dwell", "hour_of_day", "dispersion"]
    if getattr(c, "clock_offset", 0.0) is None:  # no clock: the time of day is unknown
        names.remove("hour_of_day")
    if c.marks_obs is not None and c.mix_rates is not None:
        names.append("marks")
    overview, axes = plt.subplots(2, 3, figsize=(15, 8))
    overview.subplots_adjust(**_OVERVIEW_GRID)  # the figure's: tight_layout may change it
    panels = dict(zip(names, axes.ravel(), strict=False))
    for name, ax in panels.items():
        _draw_panel(name, ax, c, c.window[0])
    for a in axes.ravel()[len(panels) :]:
        a.set_axis_off()
    overview.suptitle(
        "Posterior-predictive checks of the paper's model (the chosen models: traffic_checks.png)"
    )
    return overview, panels


#: The overview's fixed grid (figure fractions of its 15 x 8 inches): room for tick labels
#: of five characters and an axis label left of each panel, a title above and tick labels
#: and an axis label below (``tight_layout`` found 0.048, 0.986, 0.073, 0.915, 0.18 and
#: 0.27 on the shipped log). ``tight_layout`` and the panels' ``get_tightbbox`` lay every
#: tick out again: 0.32-0.46 s and 0.17-0.34 s of CPU against the page's drawing's 0.55 s
#: (2026-11-28, the shipped log's overview, load 12). A log whose labels do not fit is
#: laid out by ``tight_layout`` after all (:func:`_panel_boxes` finds it out from the
#: drawing).
_OVERVIEW_GRID = {
    "left": 0.055,
    "right": 0.985,
    "bottom": 0.075,
    "top": 0.91,
    "wspace": 0.2,
    "hspace": 0.3,
}


def _panel_boxes(overview: Figure, panels: dict[str, Axes], renderer: RendererBase) -> dict | None:
    """Each panel's extent in pixels of the drawn ``overview`` (``(x0, y0, x1, y1)``, origin
    at the bottom left): its axes, title, axis labels and the tick labels drawn, with
    :data:`_PANEL_MARGIN` around them; None when two extents meet or one leaves the page.

    The texts are those of the last drawing (their layout is cached by then): the ticks
    are not laid out again, as ``Axes.get_tightbbox`` does for every axis.
    """
    width, height = overview.bbox.width, overview.bbox.height
    boxes = {}
    for name, ax in panels.items():
        texts = [ax.title]  # the panels set the centre title only
        for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            texts += [axis.label, axis.offsetText]
            lo, hi = min(lo, hi), max(lo, hi)
            for tick in axis.majorTicks + axis.minorTicks:
                if lo <= tick.get_loc() <= hi:  # the ticks drawn (Axis._update_ticks)
                    texts += [tick.label1, tick.label2]
        ext = [ax.bbox.extents]
        ext += [
            t.get_window_extent(renderer).extents for t in texts if t.get_visible() and t.get_text()
        ]
        e = np.asarray(ext)
        box = (
            e[:, 0].min() - _PANEL_MARGIN,
            e[:, 1].min() - _PANEL_MARGIN,
            e[:, 2].max() + _PANEL_MARGIN,
            e[:, 3].max() + _PANEL_MARGIN,
        )
        if box[0] < 0 or box[1] < 0 or box[2] > width or box[3] > height:
            return None
        boxes[name] = box
    for a, b in itertools.combinations(boxes.values(), 2):
        if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
            return None
    return boxes


#: Resolution of the report's figures (dots per inch).
REPORT_DPI = 110
#: Margin kept around a panel cut out of the overview (pixels).
_PANEL_MARGIN = 6


def _overview_images(checks: PredictiveChecks) -> dict[str, np.ndarray]:
    """``criticism`` and each ``ppc_<check>`` as ``(h, w, 4)`` uint8 RGBA images, from one
    rendering: each panel is cut out of the overview along its axes' extent (title, tick
    labels and legend included), instead of being drawn and laid out again in a figure
    of its own (two renderings and a layout per panel: most of a report's time)."""
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    overview, panels = _overview(checks)
    # each title at its place above its axes, given (y = 1), not found by matplotlib at
    # every drawing: it lays the y ticks out again to see whether an offset text ("1e6")
    # is in the way (0.1-0.2 s of CPU for the six panels); the same pixels where none is
    for ax in panels.values():
        ax.set_title(ax.get_title(), y=1.0)
    try:
        overview.set_dpi(REPORT_DPI)
        canvas = FigureCanvasAgg(overview)  # Agg whatever the session's backend
        canvas.draw()
        if any(ax.yaxis.offsetText.get_text() for ax in panels.values()):
            plt.close(overview)  # an offset text: drawn again with matplotlib's titles
            overview, panels = _overview(checks)
            overview.set_dpi(REPORT_DPI)
            canvas = FigureCanvasAgg(overview)
            canvas.draw()
        renderer = canvas.get_renderer()
        boxes = _panel_boxes(overview, panels, renderer)
        if boxes is None:  # labels past the fixed grid: laid out to fit, drawn again
            overview.tight_layout()
            canvas.draw()
            boxes = {n: ax.get_tightbbox(renderer).extents for n, ax in panels.items()}
            boxes = {
                n: (
                    b[0] - _PANEL_MARGIN,
                    b[1] - _PANEL_MARGIN,
                    b[2] + _PANEL_MARGIN,
                    b[3] + _PANEL_MARGIN,
                )
                for n, b in boxes.items()
            }
        full = np.asarray(canvas.buffer_rgba()).copy()
        height, width = full.shape[:2]
        images = {}
        for name, box in boxes.items():  # pixels, origin at the bottom left
            x0 = max(int(np.floor(box[0])), 0)
            x1 = min(int(np.ceil(box[2])), width)
            y0 = max(height - int(np.ceil(box[3])), 0)
            y1 = min(height - int(np.floor(box[1])), height)
            images[f"ppc_{name}"] = full[y0:y1, x0:x1]
        images["criticism"] = full
    finally:
        plt.close(overview)
    return images


def _draw_panel(name: str, ax: Axes, c: PredictiveChecks, t0: float) -> None:
    from scipy import stats  # lazy: scipy.stats adds 0.46 s CPU to import are_stats.fitting

    if name == "counts":
        x = (c.times - t0) / 60.0
        _band(ax, x, c.counts_rep, "C0", "predictive", step=True)
        ax.step(x, c.counts_obs, where="post", color="k", lw=1.2, label="observed")
        ax.set(xlabel="time in window [min]", ylabel="N(t) artefacts present")
        ax.set_title("Artefacts present N(t)")
    elif name == "interarrival":
        if c.gaps_obs.size:
            grid = np.quantile(c.gaps_obs, np.linspace(0, 0.995, 100))
            reps = np.array(
                [np.searchsorted(np.sort(g), grid, "right") / max(g.size, 1) for g in c.gaps_rep]
            )
            _band(ax, grid, reps, "C0", "predictive")
            ecdf = np.searchsorted(np.sort(c.gaps_obs), grid, "right") / c.gaps_obs.size
            ax.plot(grid, ecdf, "k", lw=1.2, label="observed")
        else:  # fewer than two arrivals inside the window: nothing to compare
            _no_data(ax, "fewer than two arrivals observed")
        ax.set(xlabel="inter-arrival time [s]", ylabel="ECDF")
        ax.set_title("Inter-arrival times")
    elif name == "dwell":
        if c.km is None:
            _no_data(ax, "no stay observed from its arrival")
        else:
            tmax = c.km.time.max() if c.km.time.size else 1.0
            grid = np.linspace(0, tmax, 200)
            surv = np.exp(-np.outer(c.leave_rate, grid))
            _band(ax, grid / 60.0, surv, "C1", "fitted exponential")
            x = np.concatenate([[0.0], c.km.time]) / 60.0
            ax.step(
                x,
                np.concatenate([[1.0], c.km.survival]),
                where="post",
                color="k",
                lw=1.2,
                label="Kaplan-Meier (observed)",
            )
            ax.fill_between(
                x,
                np.concatenate([[1.0], c.km.lower]),
                np.concatenate([[1.0], c.km.upper]),
                step="post",
                color="k",
                alpha=0.12,
                lw=0,
                label="KM 95% band",
            )
        ax.set(xlabel="dwell time [min]", ylabel="survival S(t)", ylim=(0, 1.02))
        ax.set_title("Dwell times (censored at window end)")
    elif name == "hour_of_day":
        hours = np.arange(24)
        q = np.quantile(c.hours_rep, [0.05, 0.5, 0.95], axis=0)
        ax.bar(hours, c.hours_obs, color="0.6", width=0.8, label="observed arrivals")
        ax.errorbar(
            hours,
            q[1],
            yerr=[q[1] - q[0], q[2] - q[1]],
            fmt="o",
            color="C0",
            ms=3,
            capsize=2,
            label="predictive median, 90%",
        )
        ax.set(xlabel="hour of day", ylabel="arrivals", xticks=range(0, 24, 3))
        covered = np.flatnonzero((c.hours_rep.sum(0) > 0) | (c.hours_obs > 0))
        if covered.size:  # a window shorter than a day: show only the hours it covers
            ax.set_xlim(covered.min() - 0.6, covered.max() + 0.6)
            ax.set_xticks(covered)
        ax.set_title("Arrivals per hour of day")
    elif name == "dispersion":
        d = c.dispersion_rep[np.isfinite(c.dispersion_rep)]
        ax.hist(d, bins=30, color="C0", alpha=0.5, label="predictive", histtype="stepfilled")
        ax.axvline(c.dispersion_obs, color="k", lw=1.5, label="observed")
        ax.axvline(1.0, color="C3", ls=":", lw=1, label="Poisson (1)")
        ax.set(
            xlabel=f"variance / mean of arrivals per {c.bin_width / 60:.3g} min",
            ylabel="replicates",
        )
        ax.set_title(f"Dispersion index (pp p-value {c.dispersion_pvalue:.2f})")
    elif name == "marks":
        k = np.arange(int(c.marks_obs.max()) + 6)
        sub = np.linspace(0, c.mix_rates.shape[0] - 1, min(_MARK_PANEL_DRAWS, c.mix_rates.shape[0]))
        sub = sub.astype(int)
        pmf = np.einsum(
            "sk,skn->sn",
            c.mix_weights[sub],
            stats.poisson.pmf(k[None, None, :], c.mix_rates[sub][:, :, None]),
        )
        ax.bar(
            k,
            np.bincount(c.marks_obs, minlength=k.size)[: k.size] / c.marks_obs.size,
            color="0.6",
            width=0.85,
            label="observed marks",
        )
        _band(ax, k, pmf, "C3", "posterior mixture")
        ax.set(xlabel="mark X", ylabel="Pr(X = k)")
        ax.set_title("Marks vs Poisson mixture (eq. 1)")
    ax.legend(fontsize=7, loc="best")


def _class_figures(
    key: int | jax.Array,
    idata: az.InferenceData,
    per_class: pd.DataFrame,
    n_replicates: int,
    out: Path,
    force: bool,
    written: dict[str, Path],
) -> dict[str, Figure]:
    """The per-class figures of a labelled log's fit (issue 31): the checks (with the
    motion rows the fit stored), the shares by hour (with a clock), the entry densities."""
    motion = None
    if "behaviour" in idata.groups():
        with contextlib.suppress(ValueError):  # a damaged table: the CLI names it
            stored = motion_tables(idata.behaviour.attrs).get("class_motion")
            if stored is not None and {"class", "statistic"} <= set(stored.columns):
                motion = stored.set_index(["class", "statistic"])
                with atomic_path(out / "class_motion_checks.csv", force=force) as tmp:
                    motion.to_csv(tmp, float_format="%.6g")
                written["class_motion_checks"] = out / "class_motion_checks.csv"
    figures = {"ppc_classes": plot_class_checks(per_class, motion)}
    by_hour = class_share_checks(key, idata, n_replicates)
    if by_hour is not None:
        with atomic_path(out / "class_shares_by_hour.csv", force=force) as tmp:
            by_hour.to_csv(tmp, float_format="%.6g")
        written["class_shares_by_hour"] = out / "class_shares_by_hour.csv"
        model = str(idata.posterior.attrs.get("class_share_model", "constant"))
        figures["ppc_class_shares_by_hour"] = plot_class_shares_by_hour(by_hour, model)
    entries = plot_class_entries(idata)
    if entries is not None:
        figures["class_entries"] = entries
    return figures


#: The file of :func:`write_report`'s traffic checks table (:func:`read_traffic_checks`).
_TRAFFIC_CHECKS = "traffic_checks.csv"


def read_traffic_checks(folder: str | os.PathLike) -> pd.DataFrame | None:
    """The posterior-predictive traffic checks that :func:`write_report` wrote in ``folder``
    (``traffic_checks.csv``: the table of :func:`~are_stats.fitting.traffic_checks`), or
    None when it holds none.

    Parameters
    ----------
    folder : str or PathLike
        A criticism folder (``are-stats fit --figures``, ``are-stats report --out``).

    Returns
    -------
    pandas.DataFrame or None
        One row per statistic: ``observed`` and, per model (``paper``, ``chosen``), the
        90% band ``<model>_5%``, ``<model>_95%`` and ``<model>_flag`` (observed outside
        it).
    """
    path = Path(folder) / _TRAFFIC_CHECKS
    return pd.read_csv(path, index_col=0) if path.exists() else None


#: The factors whose PSIS-LOO comparison a fit may hold (``loo_<factor>`` attributes), each
#: written as ``loo_<factor>.csv``.
_LOO_FACTORS = (
    "arrivals",
    "lifetimes",
    "positions",
    "class_stays",
    "class_positions",
    "class_shares",
)

#: Every file :func:`write_report` may write (which of them depends on the fit).
_REPORT_FILES = (
    "summary.csv",
    "criticism.png",
    *(
        f"ppc_{name}.png"
        for name in ("counts", "interarrival", "dwell", "hour_of_day", "dispersion", "marks")
    ),
    _TRAFFIC_CHECKS,
    "traffic_checks.png",
    "class_checks.csv",
    "ppc_classes.png",
    "class_motion_checks.csv",
    "class_shares_by_hour.csv",
    "ppc_class_shares_by_hour.png",
    "class_entries.png",
    *(f"loo_{factor}.csv" for factor in _LOO_FACTORS),
)


def check_report_outputs(out_dir: str | os.PathLike, force: bool) -> None:
    """Refuse a report folder that holds any of :func:`write_report`'s files, unless
    ``force``: before anything is computed or written (no half-replaced report).

    Parameters
    ----------
    out_dir : str or PathLike
        The report's folder (need not exist).
    force : bool
        Overwrite: nothing is refused.

    Raises
    ------
    OutputExistsError
        Naming the first such file.
    """
    if force:
        return
    out = Path(out_dir)
    for name in _REPORT_FILES:
        check_writable(out / name, force)


def write_report(
    idata: az.InferenceData,
    out_dir: str | Path,
    key: int | jax.Array = 0,
    n_replicates: int = 200,
    clock_offset: float | None = None,
    force: bool = False,
    source: Source = "fit",
    summary: pd.DataFrame | None = None,
) -> dict[str, Path]:
    """Write the summary table (CSV) and every check figure (PNG) of a fit.

    Parameters
    ----------
    idata : arviz.InferenceData
        The fit.
    out_dir : str or Path
        Folder for ``summary.csv`` and ``ppc_*.png`` / ``criticism.png``.
    key : int or jax PRNG key
        Seed of the replicated windows.
    n_replicates : int
        Replicated windows.
    clock_offset : float, optional
        Time of day (s) at ``t = 0`` of the log (default: from the fit's ``clock_start``;
        without one there is no hour-of-day figure).
    force : bool
        Overwrite existing files.
    source : str
        The fit's name in errors (see :func:`check_report_size`, run first).
    summary : pandas.DataFrame, optional
        ``fit_summary(idata)`` when the caller has it already (``are-stats fit`` prints
        it before the report): not computed a second time.

    Returns
    -------
    dict
        ``{name: path}`` of everything written: also ``traffic_checks.csv`` / ``.png`` (the
        chosen models beside the paper's, :func:`~are_stats.fitting.traffic_checks`), the
        model comparison tables ``loo_*.csv`` and, for a log that names its classes,
        ``class_checks.csv`` (per class: share, stay median and cv,
        :func:`~are_stats.fitting.class_checks`), its figure ``ppc_classes.png`` (with the
        per-class speed and stillness the fit stored), ``loo_class_stays.csv`` and, as the
        fit has them, ``class_shares_by_hour.csv`` / ``ppc_class_shares_by_hour.png``,
        ``class_entries.png``, ``loo_class_positions.csv``, ``loo_class_shares.csv``
        (:mod:`are_stats.fitting` class figures).
    """
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    check_report_size(idata, n_replicates, source)
    check_report_outputs(out_dir, force)
    out = Path(out_dir)
    written: dict[str, Path] = {}
    if summary is None:
        summary = fit_summary(idata)
    with atomic_path(out / "summary.csv", force=force) as tmp:
        summary.to_csv(tmp)
    written["summary"] = out / "summary.csv"
    checks = predictive_checks(key, idata, n_replicates, clock_offset)
    images = _overview_images(checks)
    figures: dict[str, Figure] = {}
    table, reps = traffic_checks(key, idata, n_replicates)
    with atomic_path(out / _TRAFFIC_CHECKS, force=force) as tmp:
        table.to_csv(tmp, float_format="%.6g")
    written["traffic_checks_table"] = out / _TRAFFIC_CHECKS
    figures["traffic_checks"] = plot_traffic_checks(table, reps)
    per_class = class_checks(key, idata, n_replicates)  # a labelled log's classes (issue 31)
    if per_class is not None:
        with atomic_path(out / "class_checks.csv", force=force) as tmp:
            per_class.to_csv(tmp, float_format="%.6g")
        written["class_checks"] = out / "class_checks.csv"
        figures.update(_class_figures(key, idata, per_class, n_replicates, out, force, written))
    for factor in _LOO_FACTORS:
        text = idata.posterior.attrs.get(f"loo_{factor}")
        if text:
            path = out / f"loo_{factor}.csv"
            with atomic_path(path, force=force) as tmp:
                Path(tmp).write_text(str(text))
            written[f"loo_{factor}"] = path
    for name, fig in figures.items():  # drawn once, written as the overview's images
        fig.set_dpi(REPORT_DPI)
        canvas = FigureCanvasAgg(fig)  # Agg whatever the figure's canvas was
        canvas.draw()
        images[name] = np.asarray(canvas.buffer_rgba())
        plt.close(fig)
    for name, image in images.items():
        path = out / f"{name}.png"
        with atomic_path(path, force=force) as tmp:
            write_png(tmp, image, dpi=REPORT_DPI)
        written[name] = path
    return written
