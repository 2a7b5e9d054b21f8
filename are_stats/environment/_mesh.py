"""The environment mesh S_E (paper Sect. 3.1): loading, and extrusion of a 2D map.

Every ROS map yields a mesh for occlusion tests: the occupied cells are merged into polygons
(row runs, then a polygon union), collinear vertices are dropped, and each polygon is
extruded to a prism of the given height. The result is compact (vertices only at polygon
corners) and watertight with consistent winding (every edge is shared by exactly two faces),
also where occupied cells touch only at a corner: each solid gets its own copy of the
corner's vertices there.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely import affinity

from are_stats import inputs
from are_stats._checks import check_positive
from are_stats.environment._grid import OccupancyGrid
from are_stats.inputs import Described, InputError

# shapely is imported at the top (about 20 ms of import CPU); trimesh where a mesh is made.

if TYPE_CHECKING:
    import trimesh

__all__ = ["load_mesh", "extrude_grid", "environment_mesh", "occupied_polygons", "MAX_COORDINATE"]

#: Largest ``|coordinate|`` of a mesh vertex accepted (metres).
MAX_COORDINATE = 1e9
#: Memory estimate of parsing a mesh file: bytes per byte of file.
MESH_BYTES_PER_BYTE = 32
# Work of merging one occupied rectangle into the wall polygons (a shapely union: ~20 us).
_STEPS_PER_RECT = 2000


def _mesh_file_size(path: str | os.PathLike) -> int:
    """The size (bytes) of a mesh file, refused unless it is a regular file whose parse fits
    the memory limit (:data:`MESH_BYTES_PER_BYTE`): the check of every mesh reader
    (:func:`load_mesh`, the catalogue's plain-OBJ bounds)."""
    size = inputs.check_file(path, "a mesh file (OBJ, PLY, STL, GLB, ...)")
    inputs.check_memory(
        size * MESH_BYTES_PER_BYTE, f"parsing the {inputs.format_bytes(size)} mesh", path
    )
    return size


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
    # lazy: trimesh adds 2.7 s CPU to `import are_stats.environment`
    import trimesh

    p = Path(path)
    if _mesh_file_size(p) == 0:
        raise InputError(p, "", "a mesh with triangles", Described("an empty file"))
    try:
        obj = trimesh.load(p, force="mesh", process=False)
    except MemoryError:
        raise
    except Exception as err:  # trimesh raises many exception types for bad files
        raise InputError(
            p, "", "a mesh file trimesh can read", Described(f"{type(err).__name__}: {err}")
        ) from None
    if not isinstance(obj, trimesh.Trimesh) or len(obj.faces) == 0:
        raise InputError(p, "", "a mesh with triangles", Described("none"))
    faces = np.asarray(obj.faces)
    n_v = len(obj.vertices)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(p, "faces", "triangles", Described(f"faces of shape {faces.shape}"))
    bad = (faces < 0) | (faces >= n_v)
    if bad.any():
        f = int(np.argwhere(bad)[0, 0])
        raise InputError(
            p, f"face {f}", f"vertex indices in [0, {n_v - 1}]", Described(str(faces[f].tolist()))
        )
    v = np.asarray(obj.vertices, dtype=float)
    bad_v = ~np.isfinite(v) | (np.abs(v) > MAX_COORDINATE)
    if bad_v.any():
        i = int(np.argwhere(bad_v)[0, 0])
        raise InputError(
            p,
            f"vertex {i}",
            f"finite coordinates within {MAX_COORDINATE:g} m of the origin",
            Described(str(v[i].tolist())),
        )
    return obj


def occupied_polygons(
    grid: OccupancyGrid, cells: np.ndarray | None = None
) -> list[shapely.Polygon]:
    """Shapely polygons (in F_E, metres) covering the occupied cells of ``grid``.

    Parameters
    ----------
    grid : OccupancyGrid
    cells : (height, width) bool, optional
        Which cells to cover; default ``grid.occupied``.

    Returns
    -------
    list of shapely.Polygon
        Valid polygons, exteriors counter-clockwise and holes clockwise. Cells that touch
        only at a corner meet at a single point: as two polygons, or as a hole touching its
        shell (or another hole) there.
    """
    mask = grid.occupied if cells is None else np.asarray(cells, bool)
    if mask.shape != grid.shape:
        raise ValueError(f"cells: expected a mask of shape {grid.shape}, got {mask.shape}")
    x0, y0, yaw = grid.origin
    r = grid.resolution
    c, s = np.cos(yaw), np.sin(yaw)
    return [
        affinity.affine_transform(poly, [r * c, -r * s, r * s, r * c, x0, y0])
        for poly in _cell_polygons(mask)
    ]


def _cell_polygons(mask: np.ndarray) -> list[shapely.Polygon]:
    """Oriented polygons covering ``mask`` in cell units (integer corner coordinates)."""
    rects = _row_runs_merged(mask)
    if len(rects) == 0:
        return []
    inputs.check_work(
        len(rects) * _STEPS_PER_RECT,
        f"merging {len(rects)} occupied rectangles of the map into wall polygons",
        "map",
    )
    boxes = shapely.box(rects[:, 0], rects[:, 1], rects[:, 2], rects[:, 3])
    union = shapely.simplify(shapely.union_all(boxes), 0.0)
    polys = shapely.get_parts(union)
    polys = polys[~shapely.is_empty(polys) & (shapely.area(polys) > 0)]
    return list(shapely.orient_polygons(polys, exterior_cw=False))


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
        A compact mesh S_E (vertices only at the corners of the wall polygons, unprocessed),
        watertight with consistent outward winding: every edge lies in exactly two faces,
        once in each direction, and its volume is the occupied area times ``height``. Where
        occupied cells touch only at a corner (a diagonal pinch), each of the two solids
        gets its own copy of the corner's vertices, so the mesh stays a closed 2-manifold
        there (merging vertices by position, e.g. ``merge_vertices``, undoes this). Empty
        when no cell is occupied.

    Notes
    -----
    Each polygon of :func:`occupied_polygons` gets a cap at ``z = 0`` and at ``z = height``
    (GEOS's constrained Delaunay triangulation, which is conforming: no vertex lies inside a
    triangle's edge) and one quad (two triangles) per boundary edge. Vertices are identified
    by their integer cell-corner position, plus, at a pinch, by which of the two diagonal
    solid quadrants around it the face lies in (a cap triangle by its centroid, a wall quad
    by the side of its edge the solid is on).

    Examples
    --------
    >>> from are_stats import OccupancyGrid
    >>> g = OccupancyGrid(np.pad(np.full((2, 3), 100), 1), 0.5)
    >>> m = extrude_grid(g, 2.0)
    >>> bool(m.is_watertight), round(float(m.volume), 6)
    (True, 3.0)
    >>> diagonal = OccupancyGrid([[100, 0], [0, 100]], 1.0)
    >>> m = extrude_grid(diagonal, 1.0)
    >>> bool(m.is_watertight), bool(m.is_winding_consistent), round(float(m.volume), 6)
    (True, True, 2.0)
    """
    # lazy: trimesh adds 2.7 s CPU to `import are_stats.environment`
    import trimesh

    h = float(check_positive("height", height))
    mask = grid.occupied
    polys = _cell_polygons(mask)
    if not polys:
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), process=False)
    tri, wall_a, wall_b = _caps_and_walls(polys)
    # cell-corner keys: 2 * (v * (width + 1) + u) + (solid quadrant east of u, at pinches)
    stride = mask.shape[1] + 1
    pinch = _diagonal_pinches(mask)

    def keys(pts: np.ndarray, east: np.ndarray) -> np.ndarray:
        u, v = pts[..., 0], pts[..., 1]
        return 2 * (v * stride + u) + (pinch[v, u] & east)

    centroid_x3 = tri[..., 0].sum(axis=1, keepdims=True)  # 3 x the centroid's u
    k_tri = keys(tri, centroid_x3 > 3 * tri[..., 0])
    d = np.sign(wall_b - wall_a)  # solid on the left of a -> b: quadrant d + n at a, -d + n at b
    k_a = keys(wall_a, d[:, 0] - d[:, 1] > 0)
    k_b = keys(wall_b, -d[:, 0] - d[:, 1] > 0)
    uniq, inv = np.unique(np.concatenate([k_tri.ravel(), k_a, k_b]), return_inverse=True)
    n_t = k_tri.size
    t = inv[:n_t].reshape(-1, 3)
    a, b = inv[n_t : n_t + len(k_a)], inv[n_t + len(k_a) :]
    n = len(uniq)
    faces = np.concatenate(
        [
            t + n,  # top, counter-clockwise seen from above
            t[:, ::-1],  # bottom, facing down
            np.stack([a, b, b + n], axis=1),  # walls, facing right of a -> b (outwards)
            np.stack([a, b + n, a + n], axis=1),
        ]
    )
    corner = uniq // 2
    uv = np.stack([corner % stride, corner // stride], axis=1).astype(float)
    xy = grid.local_to_world(uv)
    verts = np.concatenate(
        [np.column_stack([xy, np.zeros(n)]), np.column_stack([xy, np.full(n, h)])]
    )
    return trimesh.Trimesh(verts, faces.astype(np.int64), process=False)


def _diagonal_pinches(mask: np.ndarray) -> np.ndarray:
    """``(height + 1, width + 1)`` bool: cell corners where exactly two diagonally opposite
    cells of the four around them are occupied (indexed ``[v, u]``)."""
    m = np.pad(np.asarray(mask, bool), 1)
    sw, se, nw, ne = m[:-1, :-1], m[:-1, 1:], m[1:, :-1], m[1:, 1:]
    return (sw == ne) & (se == nw) & (sw != se)


def _caps_and_walls(polys: list[shapely.Polygon]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cap triangles ``(T, 3, 2)`` (counter-clockwise) and boundary edges ``a -> b``
    (``(E, 2)`` each, solid on the left) of oriented cell-unit polygons, as int64."""
    rings = shapely.get_rings(np.asarray(polys, dtype=object))
    coords, ring_of = shapely.get_coordinates(rings, return_index=True)
    pts = np.rint(coords).astype(np.int64)
    # drop each ring's closing point
    last = np.r_[ring_of[1:] != ring_of[:-1], True]
    pts, ring_of = pts[~last], ring_of[~last]
    ring_start = np.r_[0, np.flatnonzero(ring_of[1:] != ring_of[:-1]) + 1]
    ring_end = np.r_[ring_start[1:], len(pts)]
    nxt = np.arange(1, len(pts) + 1)
    nxt[ring_end - 1] = ring_start
    wall_a, wall_b = pts, pts[nxt]
    # caps: GEOS's constrained Delaunay triangulation uses every polygon vertex and puts
    # none inside a triangle's edge (earcut does, which leaves T-junctions between holes)
    tris = shapely.get_parts(
        shapely.constrained_delaunay_triangles(np.asarray(polys, dtype=object))
    )
    tri = np.rint(shapely.get_coordinates(tris)).astype(np.int64).reshape(-1, 4, 2)[:, :3]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tri[cw] = tri[cw][:, ::-1]
    return tri, wall_a, wall_b


def environment_mesh(
    grid: OccupancyGrid | None,
    wall_height: float,
    mesh: str | os.PathLike | None = None,
    *,
    source: str | os.PathLike = "",
) -> trimesh.Trimesh:
    """The environment mesh S_E a command traces against: the one rule for its source.

    A mesh file (``mesh``, :func:`load_mesh`) wins; else the grid's occupied cells are
    extruded into walls of ``wall_height`` m (:func:`extrude_grid`).

    Parameters
    ----------
    grid : OccupancyGrid or None
        The map M_2D, when there is one.
    wall_height : float
        Height (m) of the walls extruded from ``grid``.
    mesh : str or PathLike, optional
        A mesh file of the environment.
    source : str or PathLike
        Where the map was to come from (e.g. a scenarios folder's manifest), named by the
        error when there is neither a mesh nor a map.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    are_stats.inputs.InputError
        With neither ``mesh`` nor ``grid``.

    Examples
    --------
    >>> from are_stats import OccupancyGrid
    >>> walls = environment_mesh(OccupancyGrid(np.pad(np.full((2, 3), 100), 1), 0.5), 2.0)
    >>> round(float(walls.volume), 6)  # 6 cells of 0.25 m^2, 2 m high
    3.0
    """
    if mesh is not None:
        return load_mesh(mesh)
    if grid is None:
        raise InputError(
            source, "map", "a map for the environment mesh (or pass --mesh MESH)", Described("none")
        )
    return extrude_grid(grid, wall_height)
