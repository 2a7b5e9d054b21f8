"""The motion criticism files of a fit from tracks: what ``fit --figures`` and ``report``
write about how the fitted people move (issues 16, 26, 31).

:func:`write_motion_tables` writes the tables the fit stored (realism, observed features,
displacement errors); :func:`write_motion_report` draws the motion checks of the behaviour
against the log's tracks (speeds, straightness, stillness, held-out moves), which need the
tracks and so run at fit time only. The command line prints what they return.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pandas as pd

from are_stats._atomic import atomic_path
from are_stats.behaviour import BehaviourFit
from are_stats.fitting._classes import class_motion_checks
from are_stats.fitting._fit import Fit
from are_stats.fitting._motion_checks import (
    heldout_log_likelihood,
    motion_checks,
    plot_motion_checks,
)
from are_stats.traffic import fold_in_key, key_from_seed

if TYPE_CHECKING:
    import os

    from are_stats.environment import ArtefactCatalogue

__all__ = [
    "MotionReport",
    "can_check_motion",
    "variation_table",
    "write_motion_report",
    "write_motion_tables",
]


class MotionReport(NamedTuple):
    """What :func:`write_motion_report` wrote and found.

    Attributes
    ----------
    written : dict of str to Path
        The files, by name.
    checks : pandas.DataFrame
        The motion statistics: observed, the model's 90% band, ``model_flag``.
    per_class : pandas.DataFrame or None
        Speed and stillness per label (labelled tracks), when not already stored in the fit.
    heldout : dict of str to float
        ``policy_per_move`` and ``random_walk_per_move`` (nats) of held-out moves.
    """

    written: dict[str, Path]
    checks: pd.DataFrame
    per_class: pd.DataFrame | None
    heldout: dict[str, float]


def write_motion_tables(
    tables: Mapping[str, pd.DataFrame], folder: str | os.PathLike[str], force: bool
) -> dict:
    """realism.csv / .png, realism_observed.csv and displacement_errors.csv of the motion
    tables a fit stored (:attr:`Fit.motion`), written atomically into ``folder``.

    Returns
    -------
    dict of str to Path
    """
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    from are_stats.scenarios import plot_realism  # the criticism's exception to the flow

    out: dict[str, Path] = {}
    writers = []
    if "displacement" in tables:
        d = tables["displacement"]
        writers.append(("displacement_errors.csv", lambda p: d.to_csv(p, float_format="%.6g")))
    fig = None
    if "realism" in tables:
        real = tables["realism"]
        fig = plot_realism(real)
        writers += [
            ("realism.csv", lambda p: real.to_csv(p, float_format="%.6g")),
            ("realism.png", lambda p: fig.savefig(p, dpi=110, format="png")),
        ]
    if "observed" in tables:
        obs = tables["observed"]
        writers.append(("realism_observed.csv", lambda p: obs.to_csv(p, float_format="%.6g")))
    for name, write in writers:
        with atomic_path(Path(folder) / name, force=force) as tmp:
            write(tmp)
        out[name] = Path(folder) / name
    if fig is not None:
        plt.close(fig)
    return out


def can_check_motion(fit: Fit, tracks: pd.DataFrame | None) -> bool:
    """Whether :func:`write_motion_report` has what it checks: the log's tracks and a
    behaviour fitted from them, with its map (:func:`~are_stats.fitting.fit_log` of a tracks
    table, its behaviour not switched off and not refused for want of walkers).

    Parameters
    ----------
    fit : Fit
        The fit (:func:`~are_stats.fitting.fit_log`).
    tracks : pandas.DataFrame or None
        The log's tracks (``LifecycleLog.tracks``; None for a life-cycle table).

    Returns
    -------
    bool
    """
    return tracks is not None and fit.behaviour is not None and fit.grid is not None


def write_motion_report(
    seed: int,
    fit: Fit,
    tracks: pd.DataFrame,
    folder: str | os.PathLike[str],
    force: bool,
    catalogue: ArtefactCatalogue,
    *,
    progress: Callable[[int, int, str], None] | None = None,
) -> MotionReport:
    """Motion checks of a fit's behaviour against the log's tracks: table and figure, with
    the stored motion tables (:func:`write_motion_tables`).

    Parameters
    ----------
    seed : int
        The fit's seed (the draws of :func:`~are_stats.fitting.fit_log`'s per-class rows).
    fit : Fit
        A fit from tracks (:func:`~are_stats.fitting.fit_log`: ``fit.behaviour`` and
        ``fit.grid``, the map the behaviour used).
    tracks : pandas.DataFrame
        The log's tracks (``LifecycleLog.tracks``).
    folder : str or Path
        Where the files go.
    force : bool
        Overwrite existing files.
    catalogue : ArtefactCatalogue
        The property table Q (the classes' run speeds, as the fit's).
    progress : callable, optional
        ``progress(done, total, what)`` after each step (as
        :meth:`~are_stats._stage_clock.StageClock.steps` takes them): the motion checks'
        steps where the fit did not hand them on (an unlabelled log: their routes' chunks
        and social force windows, :func:`~are_stats.fitting.motion_checks`), then the
        held-out fit and the figure; the last call has ``done == total``.

    Returns
    -------
    MotionReport
    """
    import matplotlib.pyplot as plt  # lazy: pyplot adds 0.6-0.9 s CPU to import are_stats.fitting

    bfit, grid, stored = fit.behaviour, fit.grid, fit.motion
    if not can_check_motion(fit, tracks):
        raise ValueError("fit: expected a fit from tracks with its behaviour and map (fit_log)")
    key = key_from_seed(seed)
    say = progress or (lambda done, total, what: None)
    after = 2  # the held-out fit, the figure
    checked = [0]  # the motion checks' steps

    def check_step(done: int, total: int, what: str) -> None:
        checked[0] = total
        say(done, total + after, f"motion checks, {what}")

    # the held-out fit (its own key, the tracks alone) runs in a thread beside the motion
    # checks (issue 29): its soft solves are the one program here with a collective across
    # the devices, the checks' walks have none, so the two cannot wait on each other
    with ThreadPoolExecutor(1, "are-stats-heldout") as pool:
        heldout = pool.submit(
            heldout_log_likelihood,
            fold_in_key(key, 2),
            tracks,
            grid.free,
            grid.resolution,
            grid.origin[:2],
            max_fit_tracks=16,
            features=bfit.feature_names or None,  # the CLI's: built-in names
            run_speed=catalogue.run_thresholds(),  # as the fit's (cyclists ride)
        )
        # the same draws as fit_log's per-class motion rows (the same key): the fit's own
        # when fit_log computed them (a labelled table), else drawn here
        if fit.motion_checks is not None:
            table, reps = fit.motion_checks
        else:
            table, reps = motion_checks(
                fold_in_key(key, 1),
                bfit,
                tracks,
                n_replicates=50,
                interaction=fit.interaction if fit.interaction is not None else True,
                grid=grid,
                progress=check_step,
            )
        held, _ = heldout.result()
    say(checked[0] + 1, checked[0] + after, "held-out moves")
    fig = plot_motion_checks(table, reps, heldout=held, displacement=stored.get("displacement"))
    out = {}
    for name, write in (
        ("motion_checks.csv", lambda p: table.to_csv(p, float_format="%.6g")),
        ("motion_checks.png", lambda p: fig.savefig(p, dpi=110, format="png")),
    ):
        with atomic_path(Path(folder) / name, force=force) as tmp:
            write(tmp)
        out[name] = Path(folder) / name
    plt.close(fig)
    per_class = class_motion_checks(tracks, reps)  # speed and stillness per label (issue 31)
    if per_class is not None and "class_motion" in stored:
        per_class = None  # the report wrote and shows the stored rows
    if per_class is not None:
        with atomic_path(Path(folder) / "class_motion_checks.csv", force=force) as tmp:
            per_class.to_csv(tmp, float_format="%.6g")
        out["class_motion_checks.csv"] = Path(folder) / "class_motion_checks.csv"
    out.update(write_motion_tables(stored, folder, force))
    say(checked[0] + after, checked[0] + after, "figure")
    return MotionReport(out, table, per_class, dict(held))


def variation_table(fit: BehaviourFit) -> pd.DataFrame:
    """The within-person variations of a behaviour fit as the report prints them: per
    class, the pace (log-sd) and the heading wander (rad) with their correlation times
    (s), each ``value +- standard error``; ``none`` where the tracks show no variation,
    ``not identified`` where they do not identify it (generation walks neither: issue 26),
    the value alone where the file holds no standard error (written before 2026-11-28).

    Parameters
    ----------
    fit : BehaviourFit

    Returns
    -------
    pandas.DataFrame
        Index: the classes; columns ``pace (log-sd)``, ``pace time (s)``, ``wander (rad)``,
        ``wander time (s)``; str cells.
    """

    def cell(value: float, se: float, sd: float) -> str:
        if not np.isfinite(sd):
            return "not identified"
        if sd <= 0.0:
            return "none"
        return f"{value:.3g} +- {se:.2g}" if np.isfinite(se) else f"{value:.3g}"

    rows = {}
    for c, name in enumerate(fit.classes):
        row = {}
        for label, what in (("pace (log-sd)", "speed"), ("wander (rad)", "heading")):
            sd = float(getattr(fit, f"{what}_within_sd")[c])
            for part, unit in (("sd", label), ("time", f"{label.split()[0]} time (s)")):
                value = float(getattr(fit, f"{what}_within_{part}")[c])
                se = float(getattr(fit, f"{what}_within_{part}_se")[c])
                row[unit] = cell(value, se, sd)
        rows[str(name)] = row
    return pd.DataFrame.from_dict(rows, orient="index")
