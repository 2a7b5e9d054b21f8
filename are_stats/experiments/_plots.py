"""Fig. 7-style plots of a sweep: rho against scene-update frequency (7a) and goals reached
against mission time for increasing clutter nu (7b), with 95% bands over replicates."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from are_stats._atomic import check_writable, save_figure
from are_stats._lazy import scipy_stats as stats
from are_stats.experiments._sweep import load_results
from are_stats.inputs import Described, InputError

# scipy.stats (are_stats._lazy) loads on the first band.

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_goals", "plot_results", "plot_rho"]


def _band(values: np.ndarray) -> tuple[float, float]:
    """Mean and half-width of a 95% t confidence interval (0 for one value)."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return np.nan, np.nan
    if v.size == 1:
        return float(v[0]), 0.0
    return float(v.mean()), float(stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size))


def _clutter(runs: pd.DataFrame, hue: str) -> tuple[pd.DataFrame, str]:
    """The runs and the column that groups them by clutter level: ``arrival_rate`` for
    hand-set rates; for scenarios drawn from a fit or read from a folder (every run its own
    rate, or none), the levels of the factors other than ``hue`` (one group without)."""
    if "draw" not in runs.columns or (runs["draw"].to_numpy() < 0).all():
        return runs, "arrival_rate"
    cols = [c for c in runs.columns if c.startswith("level:") and c not in (hue, f"level:{hue}")]
    label = (
        runs[cols].astype(str).agg(", ".join, axis=1)
        if cols
        else pd.Series("all runs", index=runs.index)
    )
    return runs.assign(clutter=label), "clutter"


def plot_rho(runs: pd.DataFrame, hue: str = "planner", ax: Axes | None = None) -> Figure:
    """Fig. 7a: mean rho per run (eq. 3) against the scene-update frequency.

    Runs are grouped by ``hue`` (planner settings) and by arrival rate (for scenarios from
    a fit or a folder: by the levels of the other factors); x is the mean
    measured update frequency (updates per minute) of the group, y the geometric mean of
    the runs' ``rho_mean`` with a 95% t band over replicates computed on ``log10(rho)``
    (rho spans decades: the axis is logarithmic).

    Returns
    -------
    matplotlib.figure.Figure
    """
    # lazy: matplotlib adds 0.63 s CPU to `import are_stats.experiments`
    import matplotlib.pyplot as plt

    for c in (hue, "arrival_rate", "update_rate", "rho_mean"):
        if c not in runs.columns:
            raise ValueError(f"runs: expected a column {c!r}, got {list(runs.columns)}")
    runs, key = _clutter(runs, hue)
    fig, ax = plt.subplots(figsize=(6, 4)) if ax is None else (ax.figure, ax)
    for name, grp in runs.groupby(hue, sort=True):
        rows = []
        for _, g in grp.groupby(key, sort=True):
            r = g["rho_mean"].to_numpy(float)
            m, h = _band(np.log10(r[r > 0]))
            rows.append((60.0 * g["update_rate"].mean(), m, h))
        x, m, h = (np.array(v) for v in zip(*rows, strict=True))
        (line,) = ax.plot(x, 10**m, marker="o", label=str(name))
        hi = np.minimum(10 ** (m + h), 1.0)  # rho <= 1
        ax.fill_between(x, 10 ** (m - h), hi, color=line.get_color(), alpha=0.2)
    ax.set_xlabel("scene-update frequency (updates / min)")
    ax.set_ylabel(r"mean $\rho = \rho_t / (\rho_t + g_t)$ (eq. 3)")
    ax.set_title("Replanning ratio vs scene-update frequency")
    ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(title=hue, fontsize="small")
    fig.tight_layout()
    return fig


def plot_goals(
    runs: pd.DataFrame, goals: pd.DataFrame, by: str | None = None, ax: Axes | None = None
) -> Figure:
    """Fig. 7b: goals reached against mission time, one line per level of ``by``.

    ``by`` defaults to ``arrival_rate`` for hand-set rates and, for scenarios from a fit or
    a folder, to the levels of the factors other than the planner.

    For a mission time ``T`` a run has reached ``count(t_reached <= T)`` goals; lines show
    the mean over the runs of a level (95% t band), labelled by the level's mean nu (eq. 4).

    Returns
    -------
    matplotlib.figure.Figure
    """
    # lazy: matplotlib adds 0.63 s CPU to `import are_stats.experiments`
    import matplotlib.pyplot as plt

    if by is None:
        runs, by = _clutter(runs, "planner")
    for c in (by, "task", "nu_mean", "mission_time"):
        if c not in runs.columns:
            raise ValueError(f"runs: expected a column {c!r}, got {list(runs.columns)}")
    fig, ax = plt.subplots(figsize=(6, 4)) if ax is None else (ax.figure, ax)
    t_max = float(runs["mission_time"].max())
    grid_t = np.linspace(0.0, t_max, 200)
    levels = runs.groupby(by, sort=True)
    for level, grp in sorted(levels, key=lambda kv: kv[1]["nu_mean"].mean()):
        curves = []
        for task in grp["task"]:
            t = goals.loc[goals["task"] == task, "t_reached"].to_numpy(float)
            t = np.sort(t[np.isfinite(t)])
            curves.append(np.searchsorted(t, grid_t, side="right"))
        c = np.array(curves, float)
        band = np.array([_band(c[:, k]) for k in range(c.shape[1])])
        nu = grp["nu_mean"].mean()
        (line,) = ax.step(
            grid_t / 60.0, band[:, 0], where="post", label=f"nu = {nu:.3f} ({by} {level})"
        )
        lo = np.maximum(band[:, 0] - band[:, 1], 0.0)
        hi = np.minimum(band[:, 0] + band[:, 1], float(runs["goals_total"].max()))
        ax.fill_between(grid_t / 60.0, lo, hi, step="post", color=line.get_color(), alpha=0.2)
    ax.set_xlabel("mission time (min)")
    ax.set_ylabel("goals reached")
    ax.set_title(r"Goals reached vs mission time, by clutter $\nu$ (eq. 4)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    return fig


def plot_results(
    results: str | os.PathLike, out: str | os.PathLike | None = None, force: bool = False
) -> list[Path]:
    """Draw ``fig7a_rho.png`` and ``fig7b_goals.png`` from a sweep's results folder.

    Parameters
    ----------
    results : path
        Folder written by :func:`~are_stats.experiments.run_sweep`.
    out : path, optional
        Folder for the PNGs (default: ``results``).
    force : bool
        Overwrite existing PNGs.

    Returns
    -------
    list of Path

    Raises
    ------
    FileNotFoundError
        If ``results`` holds no finished task.
    are_stats.inputs.InputError
        Naming the file, on a results folder that is malformed or mixes sweeps (see
        :func:`~are_stats.experiments.load_results`), or an ``out`` that is a file.
    are_stats._atomic.OutputExistsError
        If a PNG exists and ``force`` is false.
    """
    # lazy: matplotlib adds 0.63 s CPU to `import are_stats.experiments`
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:  # headless default; never switch a live
        matplotlib.use("Agg")  # session's backend (a notebook's inline one)

    res = load_results(results)
    out = Path(results if out is None else out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "", "a folder for the PNGs", Described("a file"))
    paths = [out / "fig7a_rho.png", out / "fig7b_goals.png"]
    for p in paths:
        check_writable(p, force)
    figs = [plot_rho(res["runs"]), plot_goals(res["runs"], res["goals"])]
    for fig, p in zip(figs, paths, strict=True):
        save_figure(fig, p, force, dpi=120, tight=False, close=True)
    return paths
