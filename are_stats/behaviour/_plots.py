"""Pictures of the MDP: value function with policy arrows, small multiples of a rollout."""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_positive, describe
from are_stats.behaviour._mdp import MDPSolution
from are_stats.behaviour._rewards import FORWARD, LEFT, RIGHT, RUN

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_values", "plot_tracks"]


_DX = np.array([1.0, 0.0, -1.0, 0.0])  # heading -> unit vector along x (columns)
_DY = np.array([0.0, 1.0, 0.0, -1.0])  # heading -> unit vector along y (rows)


def plot_values(
    solution: MDPSolution,
    item: int = 0,
    t: int = 0,
    *,
    heading: int | None = None,
    ax: Axes | None = None,
    arrows: bool = True,
) -> Axes:
    """Heat map of ``V_t`` over the grid with the policy ``pi_t`` as arrows.

    For each free cell the heading shown is ``heading`` or, by default, the best heading
    ``argmax_h V_t(cell, h)``; the arrow points where the action takes the artefact (forward:
    one cell, run: two cells, left / right: the new heading, short), and ``stay`` draws a dot.
    Rows grow upwards (+y), columns to the right (+x), as in the MDP.

    Parameters
    ----------
    solution : MDPSolution
        A solved batch.
    item : int
        Batch item to draw.
    t : int
        Epoch (0: whole horizon to go).
    heading : int or None
        Draw this heading's values and actions instead of the best heading.
    ax : matplotlib Axes or None
        Axes to draw on (a new figure if None).
    arrows : bool
        Draw the policy arrows.

    Returns
    -------
    matplotlib.axes.Axes
    """
    import matplotlib.pyplot as plt  # lazy: +0.6 s CPU on `import are_stats.behaviour`

    n_items = len(solution.behaviours)
    if not 0 <= item < n_items:
        raise ValueError(f"item: expected an index in 0..{n_items - 1}, got {item!r}")
    horizon = int(solution.horizons[item])
    if not 0 <= t <= horizon:
        raise ValueError(f"t: expected an epoch in 0..{horizon}, got {t!r}")
    if heading is not None and heading not in (0, 1, 2, 3):
        raise ValueError(f"heading: expected 0, 1, 2, 3 or None, got {heading!r}")
    occ = solution.mdp.occupied
    v = solution.v0[item] if t == 0 else solution.values[item, t]
    best_h = np.argmax(v, axis=-1) if heading is None else np.full(occ.shape, heading)
    rows, cols = np.indices(occ.shape)
    vmap = v[rows, cols, best_h].astype(float)
    shown = np.ma.masked_where(occ, vmap)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6 * occ.shape[0] / max(occ.shape[1], 1) + 0.5))
    ax.imshow(np.where(occ, 1.0, np.nan), origin="lower", cmap="Greys", vmin=0, vmax=1.5)
    g = solution.goals[item]
    scale = vmap[~occ]
    if g[0] >= 0 and scale.size > 1:  # the absorbing goal (value 0) would flatten the colours
        scale = np.delete(vmap, g[0] * occ.shape[1] + g[1])[
            np.delete(~occ.ravel(), g[0] * occ.shape[1] + g[1])
        ]
    lo, hi = (float(scale.min()), float(scale.max())) if scale.size else (0.0, 1.0)
    im = ax.imshow(shown, origin="lower", cmap="viridis", vmin=lo, vmax=max(hi, lo + 1e-12))
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label=f"value $V_{{{t}}}$")
    if arrows and t < horizon:
        act = solution.policy[item, t][rows, cols, best_h]
        new_h = np.where(
            act == LEFT, (best_h + 1) % 4, np.where(act == RIGHT, (best_h - 1) % 4, best_h)
        )
        length = np.select(
            [act == FORWARD, act == RUN, (act == LEFT) | (act == RIGHT)], [0.8, 1.6, 0.4], 0.0
        )
        moving = (length > 0) & ~occ
        ax.quiver(
            cols[moving],
            rows[moving],
            (_DX[new_h] * length)[moving],
            (_DY[new_h] * length)[moving],
            angles="xy",
            scale_units="xy",
            scale=1,
            color="white",
            width=0.004,
        )
        stay = (length == 0) & ~occ
        ax.plot(cols[stay], rows[stay], ".", color="white", markersize=2)
    if g[0] >= 0:
        ax.plot(g[1], g[0], "r*", markersize=12)
    ax.set_xlabel("column (+x)")
    ax.set_ylabel("row (+y)")
    goal = "" if g[0] < 0 else ", goal: red star"
    ax.set_title(
        f"{solution.behaviours[item]}: $V_{{{t}}}$ and $\\pi_{{{t}}}$ (horizon {horizon}{goal})"
    )
    return ax


def plot_tracks(
    tracks: pd.DataFrame,
    occupied: npt.ArrayLike,
    times: Sequence[float],
    *,
    resolution: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    ncols: int = 4,
    scenario: Hashable | None = None,
) -> Figure:
    """Small multiples of a rollout: artefacts (arrows along yaw) and their trails.

    Parameters
    ----------
    tracks : pandas.DataFrame
        Columns ``scenario, id, t, x, y, yaw`` (see :func:`cells_to_tracks`).
    occupied : (H, W) bool
        The occupancy grid drawn underneath.
    times : sequence of float
        Times of the panels.
    resolution : float
        Cell size in metres.
    origin : tuple of float
        World coordinates of the grid's corner.
    ncols : int
        Panels per row.
    scenario : hashable
        Scenario to draw (default: the first one in the table).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt  # lazy: +0.6 s CPU on `import are_stats.behaviour`

    need = {"scenario", "id", "t", "x", "y", "yaw"}
    if not isinstance(tracks, pd.DataFrame) or not need <= set(tracks.columns):
        raise ValueError(
            f"tracks: expected a table with columns {sorted(need)}, got {describe(tracks)}"
        )
    resolution = float(check_positive("resolution", resolution))
    occ = np.asarray(occupied, dtype=bool)
    if scenario is None and len(tracks):
        scenario = tracks["scenario"].iloc[0]
    tr = tracks[tracks["scenario"] == scenario]
    times = list(times)
    if not times:
        raise ValueError("times: expected at least one time, got none")
    nrows = -(-len(times) // ncols)
    ncols = min(ncols, len(times))
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.2 * ncols, 3.2 * nrows + 0.4), squeeze=False)
    extent = (
        origin[0],
        origin[0] + occ.shape[1] * resolution,
        origin[1],
        origin[1] + occ.shape[0] * resolution,
    )
    ids = np.unique(tr["id"])
    colours = plt.cm.tab10(np.arange(len(ids)) % 10)
    for ax, when in zip(axes.ravel(), times, strict=False):
        ax.imshow(occ, origin="lower", cmap="Greys", extent=extent, vmin=0, vmax=1.3)
        for colour, i in zip(colours, ids, strict=True):
            mine = tr[(tr["id"] == i) & (tr["t"] <= when + 1e-9)]
            if mine.empty or mine["t"].iloc[-1] < when - 1e-9:
                continue  # not present at this time
            ax.plot(mine["x"], mine["y"], "-", color=colour, lw=1, alpha=0.6)
            last = mine.iloc[-1]
            ax.quiver(
                last["x"],
                last["y"],
                np.cos(last["yaw"]),
                np.sin(last["yaw"]),
                color=colour,
                angles="xy",
                scale_units="xy",
                scale=1 / resolution,
                width=0.02,
            )
        ax.set_title(f"t = {when:g} s", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in axes.ravel()[len(times) :]:
        ax.axis("off")
    fig.suptitle(f"scenario {scenario}: artefact tracks (x right, y up)")
    fig.tight_layout()
    return fig
