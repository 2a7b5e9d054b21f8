"""A scenarios folder drawn from a fit: the library side of ``are-stats generate``.

:func:`generate_folder` checks the options, refuses an existing folder (unless ``force``),
reads the fit and the map, draws the scenes by the one assembly
(:func:`~are_stats.scenarios.scenes_from_fit`) and writes them with what the folder records
of them (:func:`~are_stats.scenarios.generate_manifest`,
:func:`~are_stats.scenarios.write_scenes`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TypedDict

import pandas as pd

from are_stats.environment import load_catalogue, read_map
from are_stats.inputs import get_float, get_int, get_seed
from are_stats.scenarios._assembly import scenes_from_fit, scenes_tables
from are_stats.scenarios._folder import generate_manifest, write_scenes
from are_stats.scenarios._generate import check_folder
from are_stats.scenarios._options import AssemblyOptions

__all__ = ["GenerateFolderOptions", "generate_folder"]

#: ``progress(done, total, what)`` of the assembly's steps (see :func:`scenes_from_fit`).
Progress = Callable[[int, int, str], object]


class GenerateFolderOptions(TypedDict, total=False):
    """The options of :func:`generate_folder` (its keywords after ``map_path``, but
    ``on_start``), as a caller passes them on: ``are-stats generate``'s job. See
    :func:`generate_folder` for their meaning and defaults."""

    area: float | None
    behaviours: bool
    force: bool
    behaviour_cell: float
    behaviour_dt: float
    model: str
    positions: str


def generate_folder(
    fit: str | os.PathLike,
    n_scenarios: int,
    horizon: float,
    seed: int,
    out: str | os.PathLike,
    map_path: str | os.PathLike | None = None,
    area: float | None = None,
    behaviours: bool = False,
    force: bool = False,
    behaviour_cell: float = 1.0,
    behaviour_dt: float = 2.0,
    model: str = "chosen",
    positions: str = "chosen",
    on_start: Callable[[], Progress | None] | None = None,
) -> pd.DataFrame:
    """Posterior-predictive scenarios from a saved fit, written as a scenarios folder.

    ``model="chosen"`` draws from the arrival, stay and position models the fit chose,
    ``"paper"`` from the paper's Poisson / exponential / uniform model;
    ``positions="uniform"`` keeps the arrivals and stays ``model`` gives and places
    artefacts uniformly on the map's free cells (:func:`scenes_from_fit`); with
    ``behaviours`` the artefacts move (the module's behaviour rule, on the map coarsened to
    ``behaviour_cell`` m, ``behaviour_dt`` s per epoch).

    The options are checked first, named as the command's (the assembly's,
    :meth:`~are_stats.scenarios.AssemblyOptions.from_command`, then ``--scenarios`` an
    integer >= 1, ``--horizon``, ``--area`` finite and > 0, ``--seed`` in
    ``[0, 2**32 - 1]``), then ``out`` (refused if it exists, unless
    ``force``), the fit and the map; the size of the output is checked against the memory
    and work limits before anything is drawn. The folder (scenarios, manifest and tracks)
    is written beside ``out`` and put in place as a whole.

    Parameters
    ----------
    fit : str or PathLike
        A fit written by ``are-stats fit`` (:func:`~are_stats.fitting.read_fit`).
    n_scenarios, horizon, seed
        Number of scenarios, their length (s) and the seed (same seed, same bytes).
    out : str or PathLike
        The folder to write.
    map_path : str or PathLike, optional
        A ROS map YAML or a shipped map's name: positions on its free cells.
    area : float, optional
        Free area (m^2; default the fit's or the map's).
    behaviours, behaviour_cell, behaviour_dt, model, positions
        As above.
    force : bool
        Replace an existing ``out``.
    on_start : callable, optional
        Called once the inputs are read and checked, before drawing; what it returns (if
        not None) is given each step of the assembly as ``progress(done, total, what)``.

    Returns
    -------
    pandas.DataFrame
        The scenarios table written (``attrs["generation"]``: what it was drawn from).
    """
    # lazy: a cycle (fitting imports scenarios) and +1.0 s CPU on `import are_stats.scenarios`
    from are_stats.fitting import read_fit

    # what the scenes are drawn with, and what the folder records of them
    options = AssemblyOptions.from_command(
        behaviours, model, positions, behaviour_cell, behaviour_dt
    )
    n_scenarios = get_int(n_scenarios, "--scenarios", "", lo=1)
    horizon = get_float(horizon, "--horizon", "", lo=0.0, lo_open=True)
    seed = get_seed(seed)
    if area is not None:
        area = get_float(area, "--area", "", lo=0.0, lo_open=True)
    out = Path(out)
    check_folder(out, force)
    fitted = read_fit(fit)
    grid = None
    if map_path is not None:
        map_path, grid = read_map(map_path)  # a map file, or a shipped map's name
    # the size follows from the options and from the fit's rates (and its area or the map's)
    named = [str(fit), "--scenarios", "--horizon", "--area" if area is not None else ""]
    source = ", ".join(x for x in [*named, str(map_path or "")] if x)
    progress = on_start() if on_start is not None else None
    scenes = scenes_from_fit(
        seed,
        fitted,
        grid,
        load_catalogue(),
        n_scenarios,
        horizon,
        options,
        area=area,
        source=source,
        behaviours_source="--behaviours",
        map_source="--map",
        progress=progress,
    )
    df, tracks = scenes_tables(scenes)
    manifest, tracks = generate_manifest(
        df, tracks, fitted, grid, options, fit_file=fit, map_file=map_path, seed=seed
    )
    write_scenes(df, out, manifest, tracks=tracks, force=force)
    return df
