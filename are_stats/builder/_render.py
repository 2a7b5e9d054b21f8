"""Pictures of M_2D: grid, inflation and registered artefacts (``are-stats show``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from are_stats._atomic import check_writable, save_figure
from are_stats.builder._builder import ARBuilder
from are_stats.builder._geometry import box_corners
from are_stats.environment import OccupancyGrid, load_catalogue, read_map
from are_stats.inputs import InputError, get_float, get_int, get_seed

__all__ = ["render_map", "show_map", "MAX_INFLATE", "MAX_SHOW_ARTEFACTS"]

#: Largest inflation radius ``are-stats show --inflate`` draws (metres).
MAX_INFLATE = 1000.0
#: Most artefacts ``are-stats show --artefacts`` places (each is a polygon in the picture).
MAX_SHOW_ARTEFACTS = 1000
_TRIES = 200


def render_map(
    grid: OccupancyGrid,
    out: str | os.PathLike,
    *,
    inflate: float | None = None,
    builder: ARBuilder | None = None,
    force: bool = False,
    title: str | None = None,
) -> Path:
    """Render the grid (free white, occupied black, unknown grey), the inflated band and
    the artefact footprints to a PNG.

    Parameters
    ----------
    grid : OccupancyGrid
    out : str or PathLike
        PNG to write.
    inflate : float, optional
        Inflation radius (m) drawn as an orange band around occupied cells.
    builder : ARBuilder, optional
        Artefacts to draw (footprint outlines, coloured by class).
    force : bool
        Overwrite ``out``.

    Returns
    -------
    Path
    """
    # lazy: matplotlib adds 0.59 s CPU to `import are_stats.builder`
    import matplotlib.pyplot as plt
    import matplotlib.transforms
    from matplotlib.patches import Patch, Polygon

    if inflate is not None:
        inflate = get_float(inflate, "inflate", "", lo=0, hi=MAX_INFLATE)
    target = check_writable(out, force)
    rgb = np.full(grid.shape + (3,), 0.55)
    rgb[grid.free] = 1.0
    rgb[grid.occupied] = 0.0
    if inflate is not None and inflate > 0:
        band = grid.inflate(inflate) & ~grid.occupied
        rgb[band] = 0.65 * rgb[band] + 0.35 * np.array([1.0, 0.55, 0.0])
    x0, y0, yaw = grid.origin
    w, h = grid.width * grid.resolution, grid.height * grid.resolution
    # a very long and thin map must not ask for a figure thousands of inches tall
    fig, ax = plt.subplots(figsize=(8, float(np.clip(8 * h / w + 0.8, 2.0, 40.0))), dpi=120)
    tr = matplotlib.transforms.Affine2D().rotate(yaw).translate(x0, y0) + ax.transData
    ax.imshow(rgb, origin="lower", extent=(0, w, 0, h), interpolation="nearest", transform=tr)
    handles = [
        Patch(facecolor="white", edgecolor="k", label="free"),
        Patch(facecolor="black", label="occupied"),
        Patch(facecolor=(0.55,) * 3, label="unknown"),
    ]
    if inflate is not None and inflate > 0:
        handles.append(Patch(facecolor=(1.0, 0.72, 0.36), label=f"inflated {inflate:g} m"))
    if builder is not None and len(builder):
        centre, half, yaw_a = builder.boxes()
        corners = box_corners(centre[:, :2], half[:, :2], yaw_a)
        cmap = plt.get_cmap("tab10")
        labels = sorted(set(builder.labels))
        for k, poly in enumerate(corners):
            col = cmap(labels.index(builder.labels[k]) % 10)
            ax.add_patch(Polygon(poly, closed=True, facecolor=col, edgecolor="k", lw=0.4))
        handles += [Patch(facecolor=cmap(i % 10), label=lab) for i, lab in enumerate(labels)]
    cx = grid.corners_world
    ax.set_xlim(cx[:, 0].min(), cx[:, 0].max())
    ax.set_ylim(cx[:, 1].min(), cx[:, 1].max())
    ax.set_aspect("equal")
    ax.set_xlabel("x in F_E (m)")
    ax.set_ylabel("y in F_E (m)")
    ax.set_title(
        title
        or f"M_2D {grid.width}x{grid.height} cells @ {grid.resolution:g} m, "
        f"free area {grid.free_area:.1f} m$^2$"
    )
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return save_figure(fig, target, force, dpi=120, close=True)


def show_map(
    map_path: str | os.PathLike,
    out: str | os.PathLike | None = None,
    *,
    inflate: float | None = None,
    artefacts: int = 0,
    seed: int = 0,
    force: bool = False,
) -> Path:
    """Read a ROS map (a YAML path, or the name of a shipped map), place ``artefacts``
    random catalogue artefacts on it and render it (``are-stats show``).

    Parameters
    ----------
    map_path : str or PathLike
        The map YAML or the name of a shipped map (``courtyard``;
        :func:`~are_stats.environment.resolve_shipped`).
    out : str or PathLike, optional
        The PNG (default ``<map name>.png`` in the working directory).
    inflate : float, optional
        Inflation radius to draw, in ``[0, MAX_INFLATE]`` metres.
    artefacts : int
        Random artefacts to place, in ``[0, MAX_SHOW_ARTEFACTS]`` and no more than fit on
        the free area (its area over the smallest catalogue footprint).
    seed : int
        Seed of the placement (``0 .. 2**32 - 1``).
    force : bool
        Overwrite ``out``.

    Raises
    ------
    are_stats.inputs.InputError
        (a ``ValueError``) naming the option or the map file, also when the artefacts do
        not all find room (200 tries each).
    """
    if inflate is not None:
        inflate = get_float(inflate, "--inflate", "", lo=0, hi=MAX_INFLATE)
    n_art = get_int(artefacts, "--artefacts", "", lo=0, hi=MAX_SHOW_ARTEFACTS)
    seed = get_seed(seed, "--seed")
    p, grid = read_map(map_path, source="MAP")  # a map file, or a shipped map's name
    target = Path(out) if out is not None else Path(f"{p.stem}.png")
    check_writable(target, force)
    builder = None
    if n_art:
        cat = load_catalogue()
        smallest = min(float(np.prod(2 * c.half_extents[:2])) for c in cat.classes)
        room = int(grid.free_area / smallest)
        if n_art > room:
            raise InputError(
                "--artefacts",
                "",
                f"at most {room} artefacts (the {grid.free_area:.1f} m^2 free in {p.name} over "
                f"the smallest footprint, {smallest:.2f} m^2)",
                n_art,
            )
        builder = ARBuilder(grid, cat)
        rng = np.random.default_rng(seed)
        for k in range(n_art):
            label = cat.row(int(rng.integers(len(cat)))).label
            if not builder.place(label, rng, max_tries=_TRIES).ok:
                raise InputError(
                    "--artefacts",
                    "",
                    f"artefacts that fit on {p.name} ({k} placed, no room for a {label!r} "
                    f"in {_TRIES} random tries)",
                    n_art,
                )
    return render_map(grid, target, inflate=inflate, builder=builder, force=force)
