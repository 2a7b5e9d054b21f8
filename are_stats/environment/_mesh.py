"""The environment mesh S_E (paper Sect. 3.1): loading, and extrusion of a 2D map.

Every ROS map yields a mesh for occlusion tests: the occupied cells are merged into polygons
(row runs, then a polygon union), collinear vertices are dropped, and each polygon is
extruded to a prism of the given height. The result is compact (vertices only at polygon
corners) and watertight (every edge is shared by exactly two faces).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from are_stats._checks import check_positive
from are_stats.inputs import InputError, _Text, check_memory, check_work, format_bytes

if TYPE_CHECKING:
    import trimesh

    from are_stats.environment._grid import OccupancyGrid

__all__ = ["load_mesh", "extrude_grid", "occupied_polygons", "MAX_COORDINATE"]

#: Largest ``|coordinate|`` of a mesh vertex accepted (metres).
MAX_COORDINATE = 1e9
#: Memory estimate of parsing a mesh file: bytes per byte of file.
MESH_BYTES_PER_BYTE = 32
# Work of merging one occupied rectangle into the wall polygons (a shapely union: ~20 us).
_STEPS_PER_RECT = 2000


def load_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Load any mesh trimesh reads (OBJ, PLY, STL, GLB, ...) as one ``Trimesh``.

    Scenes are flattened (their transforms applied) into a single mesh. Before parsing, the
    memory the parser needs is estimated from the file size (:data:`MESH_BYTES_PER_BYTE`)
    and checked against :func:`are_stats.inputs.memory_limit`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) if it is not a file, cannot be parsed, holds no triangles, has
        face indices outside its vertices, or vertex coordinates that are not finite or
        beyond :data:`MAX_COORDINATE` metres; :class:`are_stats.inputs.LimitError` if it
        is too large for the memory limit.
    """
    import trimesh

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: mesh file not found")
    if not p.is_file():
        raise InputError(p, "", "a mesh file (OBJ, PLY, STL, GLB, ...)", _Text("not a file"))
    size = p.stat().st_size
    if size == 0:
        raise InputError(p, "", "a mesh with triangles", _Text("an empty file"))
    check_memory(size * MESH_BYTES_PER_BYTE, f"parsing the {format_bytes(size)} mesh", p)
    try:
        obj = trimesh.load(p, force="mesh", process=False)
    except MemoryError:
        raise
    except Exception as err:  # trimesh raises many exception types for bad files
        raise InputError(
            p, "", "a mesh file trimesh can read", _Text(f"{type(err).__name__}: {err}")
        ) from None
    if not isinstance(obj, trimesh.Trimesh) or len(obj.faces) == 0:
        raise InputError(p, "", "a mesh with triangles", _Text("none"))
    faces = np.asarray(obj.faces)
    n_v = len(obj.vertices)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(p, "faces", "triangles", _Text(f"faces of shape {faces.shape}"))
    bad = (faces < 0) | (faces >= n_v)
    if bad.any():
        f = int(np.argwhere(bad)[0, 0])
        raise InputError(
            p, f"face {f}", f"vertex indices in [0, {n_v - 1}]", _Text(str(faces[f].tolist()))
        )
    v = np.asarray(obj.vertices, dtype=float)
    bad_v = ~np.isfinite(v) | (np.abs(v) > MAX_COORDINATE)
    if bad_v.any():
        i = int(np.argwhere(bad_v)[0, 0])
        raise InputError(
            p,
            f"vertex {i}",
            f"finite coordinates within {MAX_COORDINATE:g} m of the origin",
            _Text(str(v[i].tolist())),
        )
    return obj


def occupied_polygons(grid: OccupancyGrid, cells: np.ndarray | None = None) -> list[Any]:
    """Shapely polygons (in F_E, metres) covering the occupied cells of ``grid``.

    Parameters
    ----------
    grid : OccupancyGrid
    cells : (height, width) bool, optional
        Which cells to cover; default ``grid.occupied``.
    """
    import shapely
    from shapely import affinity

    mask = grid.occupied if cells is None else np.asarray(cells, bool)
    if mask.shape != grid.shape:
        raise ValueError(f"cells: expected a mask of shape {grid.shape}, got {mask.shape}")
    rects = _row_runs_merged(mask)
    if len(rects) == 0:
        return []
    check_work(
        len(rects) * _STEPS_PER_RECT,
        f"merging {len(rects)} occupied rectangles of the map into wall polygons",
        "map",
    )
    boxes = shapely.box(rects[:, 0], rects[:, 1], rects[:, 2], rects[:, 3])
    union = shapely.union_all(boxes)
    union = shapely.simplify(union, 0.0)
    polys = list(union.geoms) if hasattr(union, "geoms") else [union]
    x0, y0, yaw = grid.origin
    r = grid.resolution
    c, s = np.cos(yaw), np.sin(yaw)
    out = []
    for poly in polys:
        if poly.is_empty or poly.area <= 0:
            continue
        out.append(affinity.affine_transform(poly, [r * c, -r * s, r * s, r * c, x0, y0]))
    return out


def _row_runs_merged(mask: np.ndarray) -> np.ndarray:
    """Rectangles ``(u0, v0, u1, v1)`` in cell units covering ``mask``: runs of each row,
    merged with identical runs of the rows above."""
    h, w = mask.shape
    padded = np.zeros((h, w + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    rs, cs = np.nonzero(d == 1)
    re, ce = np.nonzero(d == -1)
    # np.nonzero is row-major, so starts and ends pair up in order
    runs = np.stack([rs, cs, ce], axis=1)
    if runs.size == 0:
        return np.zeros((0, 4))
    # merge vertically: a run continues a rectangle if the row below had the same run
    order = np.lexsort((runs[:, 0], runs[:, 2], runs[:, 1]))
    runs = runs[order]
    same = (
        (runs[1:, 1] == runs[:-1, 1])
        & (runs[1:, 2] == runs[:-1, 2])
        & (runs[1:, 0] == runs[:-1, 0] + 1)
    )
    start = np.r_[True, ~same]
    gid = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    last = np.r_[first[1:] - 1, len(runs) - 1]
    del gid
    return np.stack(
        [runs[first, 1], runs[first, 0], runs[first, 2], runs[last, 0] + 1], axis=1
    ).astype(float)


def extrude_grid(grid: OccupancyGrid, height: float) -> trimesh.Trimesh:
    """Extrude the occupied cells of ``grid`` into walls of ``height`` metres.

    Parameters
    ----------
    grid : OccupancyGrid
        The 2D map M_2D (origin and yaw respected).
    height : float
        Wall height in metres; walls stand on ``z = 0``.

    Returns
    -------
    trimesh.Trimesh
        A compact, watertight mesh S_E (each connected wall block is a closed prism; blocks
        that touch only at a corner keep separate vertices there). Empty when no cell is
        occupied.

    Examples
    --------
    >>> from are_stats import OccupancyGrid
    >>> g = OccupancyGrid(np.pad(np.full((2, 3), 100), 1), 0.5)
    >>> m = extrude_grid(g, 2.0)
    >>> bool(m.is_watertight), round(float(m.volume), 6)
    (True, 3.0)
    """
    import trimesh

    h = float(check_positive("height", height))
    polys = occupied_polygons(grid)
    verts, faces, offset = [], [], 0
    for poly in polys:
        m = trimesh.creation.extrude_polygon(poly, h, engine="earcut")
        verts.append(np.asarray(m.vertices))
        faces.append(np.asarray(m.faces) + offset)
        offset += len(m.vertices)
    if not verts:
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), process=False)
    return trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)
