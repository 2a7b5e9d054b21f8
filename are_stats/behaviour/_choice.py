"""Which behaviour each artefact gets, and its tracks over a scenario on the coarse grid.

The catalogue row of an artefact (its class, DECISIONS 5) lists the behaviours the class
allows (walk, run, follow, stop); its mark picks one (``mark mod`` the number allowed; the
first without a mark). :func:`behaviour_tracks` is the one path from a scenario's
artefacts to behaviour tracks, used by ``are-stats generate --behaviours`` and by the
experiment sweeps: the map is coarsened to the behaviour cell (the cells that
:func:`are_stats.environment.coarse_free` leaves blocked), starts on a coarse obstacle move to
the nearest free coarse cell, and :func:`~are_stats.behaviour.walk_tracks` moves them: the MDP
picks each route to a goal reachable in the rest of the stay (a new goal on arrival, while
alive), and the artefact walks it in continuous space, straight wherever it sees, at its
own preferred speed (issue 26).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats.behaviour._walk import walk_tracks
from are_stats.environment import ArtefactCatalogue, OccupancyGrid, coarse_free

__all__ = ["TRACK_COLUMNS", "behaviour_tracks", "choose_behaviours"]

#: Columns of a behaviour tracks table.
TRACK_COLUMNS = ("scenario", "id", "t", "x", "y", "yaw")


def choose_behaviours(
    classes: npt.ArrayLike, marks: npt.ArrayLike, catalogue: ArtefactCatalogue
) -> list[str]:
    """The behaviour of each artefact from its catalogue class and its mark.

    Parameters
    ----------
    classes : (n,) int
        Catalogue class position of each artefact (``Scene.classes``).
    marks : (n,) int
        Marks (negative: none).
    catalogue : ArtefactCatalogue

    Returns
    -------
    list of str
    """
    out = []
    for c, x in zip(np.asarray(classes, np.int64), np.asarray(marks, np.int64), strict=True):
        allowed = list(catalogue.row(int(c)).behaviours)
        out.append(allowed[int(x) % len(allowed)] if x >= 0 else allowed[0])
    return out


def behaviour_tracks(
    key: jax.Array,
    artefacts: pd.DataFrame,
    classes: npt.ArrayLike,
    grid: OccupancyGrid,
    catalogue: ArtefactCatalogue,
    *,
    cell: float = 1.0,
    dt: float = 2.0,
    horizon: float | None = None,
    source: str = "cell",
    speed_sd: float = 0.12,
    within_sd: float = 0.05,
    progress: Callable[[int, int], object] | None = None,
) -> pd.DataFrame:
    """Behaviour tracks of scenario artefacts on ``grid`` coarsened to ``cell`` metres.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    artefacts : pandas.DataFrame
        ``scenario`` (optional, default 0), ``artefact`` or ``id``, ``t_arrive``,
        ``t_leave``, ``x``, ``y``, ``yaw``, ``mark`` (optional).
    classes : (n,) int
        Catalogue class position of each row (from the scenario's ``Scene``).
    grid : OccupancyGrid
        The map.
    catalogue : ArtefactCatalogue
    cell : float
        Behaviour grid cell (m).
    dt : float
        Seconds between track samples (the path's vertices are sampled too).
    horizon : float, optional
        Leaving times are cut at it (artefacts arriving after it are left out).
    source : str
        The option or key of ``cell``, named in errors.
    speed_sd : float
        Between-person standard deviation of the log preferred speed around the catalogue
        speed of the class (walk, or run for runners).
    within_sd : float
        Within-person standard deviation of the log speed.
    progress : callable, optional
        ``progress(done, total)`` after each scenario planned (:func:`walk_tracks`).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`TRACK_COLUMNS`.
    """
    from scipy import ndimage  # lazy: +0.2 s CPU on `import are_stats.behaviour`

    if abs(float(grid.origin[2])) > 1e-9:
        raise ValueError(
            f"{grid.source or 'map'}: expected an origin yaw of 0 for "
            f"behaviours, got {grid.origin[2]}"
        )
    free, res = coarse_free(grid.free, grid.resolution, cell, source=source)
    occ = ~free
    if occ.all():
        raise ValueError(f"{source}: the coarse behaviour grid has no free cell")
    x0, y0 = float(grid.origin[0]), float(grid.origin[1])
    art = artefacts.reset_index(drop=True)
    n = len(art)
    classes = np.asarray(classes, np.int64)
    if classes.shape != (n,):
        raise ValueError(f"classes: expected one class per artefact ({n}), got {classes.shape}")
    keep = np.ones(n, bool) if horizon is None else art["t_arrive"].to_numpy(float) < horizon
    marks = art["mark"].to_numpy(np.int64) if "mark" in art.columns else np.zeros(n, np.int64)
    ids = art["artefact"] if "artefact" in art.columns else art["id"]
    xy = art[["x", "y"]].to_numpy(float)
    col = np.clip(((xy[:, 0] - x0) // res).astype(int), 0, occ.shape[1] - 1)
    row = np.clip(((xy[:, 1] - y0) // res).astype(int), 0, occ.shape[0] - 1)
    # starts snap to the nearest coarse cell that is free and whose centre lies on a free
    # map cell: a majority-free coarse cell can have a wall at its centre, and the social
    # force never walks out of a wall (a group placed there stood its whole stay)
    f = max(1, int(round(res / grid.resolution)))
    centre = grid.free[
        np.ix_(np.arange(occ.shape[0]) * f + f // 2, np.arange(occ.shape[1]) * f + f // 2)
    ]
    start_ok = ~occ & centre if (~occ & centre).any() else ~occ
    _, (ri, ci) = ndimage.distance_transform_edt(~start_ok, return_indices=True)
    row, col = ri[row, col], ci[row, col]
    t_leave = art["t_leave"].to_numpy(float)
    if horizon is not None:
        t_leave = np.minimum(t_leave, horizon)
    table = pd.DataFrame(
        {
            "scenario": art["scenario"].to_numpy() if "scenario" in art.columns else 0,
            "id": ids.to_numpy(),
            "t_arrive": art["t_arrive"].to_numpy(float),
            "t_leave": t_leave,
            "x": x0 + (col + 0.5) * res,
            "y": y0 + (row + 0.5) * res,
            "yaw": art["yaw"].to_numpy(float),
            "behaviour": choose_behaviours(classes, marks, catalogue),
        }
    )[keep]
    if table.empty:
        return pd.DataFrame(columns=list(TRACK_COLUMNS))
    speeds = [catalogue.row(int(c)).speeds for c in classes[keep]]
    table["speed"] = [
        sp.get("run", sp["walk"]) if b == "run" else sp["walk"]
        for sp, b in zip(speeds, table["behaviour"], strict=True)
    ]
    return pd.DataFrame(
        walk_tracks(
            key,
            table,
            occ,
            resolution=res,
            origin=(x0, y0),
            dt=dt,
            speed_sd=speed_sd,
            within_sd=within_sd,
            progress=progress,
        )
    )
