"""Environment mesh S_E: loading and extrusion of 2D maps."""

from __future__ import annotations

import os

import numpy as np
import pytest
import shapely
import trimesh

from are_stats import OccupancyGrid, extrude_grid, load_mesh
from are_stats.environment import DEFAULT_MODELS
from are_stats.inputs import InputError, LimitError, limits


@pytest.mark.parametrize("yaw", [0.0, 0.6])
def test_extrusion_volume_footprint_watertight(rng, yaw):
    data = np.where(rng.random((40, 30)) < 0.3, 100, rng.choice([0, -1], size=(40, 30)))
    g = OccupancyGrid(data, 0.1, (2.0, -1.0, yaw))
    m = extrude_grid(g, 2.5)
    assert m.is_watertight
    n = int(g.occupied.sum())
    assert m.volume == pytest.approx(n * 0.01 * 2.5, rel=1e-9)
    assert m.bounds[0, 2] == 0.0 and m.bounds[1, 2] == pytest.approx(2.5)
    # the footprint equals the union of the occupied cells (shapely oracle)
    cells = np.argwhere(g.occupied)
    squares = [
        shapely.Polygon(
            g.local_to_world(np.array([[j, i], [j + 1, i], [j + 1, i + 1], [j, i + 1]], float))
        )
        for i, j in cells
    ]
    ref = shapely.union_all(squares)
    top = m.vertices[m.vertices[:, 2] > 1.0][:, :2]
    assert shapely.contains_xy(ref.buffer(1e-9), top[:, 0], top[:, 1]).all()
    assert shapely.area(ref) == pytest.approx(n * 0.01, rel=1e-9)
    # compact: far fewer vertices than 8 per cell
    assert len(m.vertices) < 8 * n


def test_extrusion_of_empty_map():
    m = extrude_grid(OccupancyGrid(np.zeros((3, 3)), 0.1), 1.0)
    assert len(m.faces) == 0


def test_extrusion_bad_height():
    with pytest.raises(ValueError, match="height"):
        extrude_grid(OccupancyGrid(np.zeros((3, 3)), 0.1), 0.0)


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "glb"])
def test_load_mesh_formats(tmp_path, ext):
    box = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    path = tmp_path / f"b.{ext}"
    box.export(path)
    m = load_mesh(path)
    assert m.volume == pytest.approx(6.0)


def test_load_mesh_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="none.obj: no such file: expected a mesh file"):
        load_mesh(tmp_path / "none.obj")
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nend_header\n\x00")
    with pytest.raises(ValueError, match="bad.ply"):
        load_mesh(bad)
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\n")
    with pytest.raises(ValueError, match="empty.obj"):
        load_mesh(empty)


def test_shipped_courtyard_matches_its_map():
    g = OccupancyGrid.from_ros_yaml(DEFAULT_MODELS / "courtyard.yaml")
    m = load_mesh(DEFAULT_MODELS / "courtyard.ply")
    assert (DEFAULT_MODELS / "courtyard.ply").stat().st_size < 1_000_000
    assert g.shape == (300, 400) and g.free_area > 500
    cx = g.corners_world
    assert (m.bounds[0, :2] >= cx.min(0) - 1e-9).all()
    assert (m.bounds[1, :2] <= cx.max(0) + 1e-9).all()


_PLY_HEAD = (
    b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
)


@pytest.mark.parametrize(
    ("name", "data", "match"),
    [
        ("e.obj", b"", "expected a mesh with triangles, got an empty file"),
        ("g.obj", b"\x00\xff garbage", "expected a mesh with triangles, got none"),
        ("p.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "expected a mesh with triangles, got none"),
        ("n.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"vertex 0: expected finite"),
        ("h.obj", b"v 1e300 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"vertex 0: .*within 1e\+09 m"),
        ("i.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "expected a mesh file trimesh can"),
        ("i.ply", _PLY_HEAD + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", r"face 0: expected vertex"),
        ("u.xyz", b"v 0 0 0\n", "expected a mesh file trimesh can read"),
        (
            "big.ply",
            _PLY_HEAD.replace(b"face 1", b"face 4000000000").replace(
                b"ascii", b"binary_little_endian"
            )
            + bytes(64),
            "expected a mesh file trimesh can read",
        ),
    ],
)
def test_bad_meshes_name_the_file(tmp_path, name, data, match):
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(InputError, match=match) as err:
        load_mesh(p)
    assert str(p) in str(err.value)


def test_mesh_directory_and_memory_limit(tmp_path):
    with pytest.raises(InputError, match=r"expected a mesh file \(OBJ.*\), got a directory"):
        load_mesh(tmp_path)
    fifo = tmp_path / "fifo.ply"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="fifo.ply: expected a mesh .* in a regular file"):
        load_mesh(fifo)
    with limits(memory="1K"), pytest.raises(LimitError, match="courtyard.ply"):
        load_mesh(DEFAULT_MODELS / "courtyard.ply")


def test_extrusion_work_is_bounded():
    checker = np.indices((60, 60)).sum(axis=0) % 2 * 100  # 1800 separate occupied cells
    g = OccupancyGrid(checker, 0.1)
    with limits(work=1800 * 2000 - 1), pytest.raises(LimitError, match="1800 occupied rect"):
        extrude_grid(g, 2.0)


# ------------------------------------------------------------- watertight at diagonal pinches
def _assert_closed_walls(g, height, m):
    """Watertight, consistently wound outwards, no degenerate face, volume = area x height."""
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume == pytest.approx(g.occupied.sum() * g.resolution**2 * height, rel=1e-9)
    tri = m.vertices[m.faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    assert area.min() > 1e-9 * g.resolution**2
    # every edge in exactly two faces, once in each direction
    e = np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]])
    _, counts = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    assert (counts == 2).all()
    assert len(np.unique(e, axis=0)) == len(e)


_RING = np.pad(np.zeros((3, 3), int), 1, constant_values=1)
_ISLAND = _RING.copy()
_ISLAND[2, 2] = _ISLAND[3, 3] = 1  # an island touching the ring's inner corner diagonally
_TWO_HOLES = np.array(
    [[1, 1, 1, 0, 0], [1, 0, 1, 0, 0], [1, 1, 1, 1, 1], [0, 0, 1, 0, 1], [0, 0, 1, 1, 1]]
)  # two holes whose corners line up (an earcut cap left T-junctions there)


@pytest.mark.parametrize(
    ("name", "cells"),
    [
        ("single cell", [[1]]),
        ("two diagonal cells", [[1, 0], [0, 1]]),
        ("the other diagonal", [[0, 1], [1, 0]]),
        ("checkerboard 4x4", np.indices((4, 4)).sum(axis=0) % 2),
        ("ring with a hole", _RING),
        ("island pinched to a ring", _ISLAND),
        ("two Ls touching twice", [[1, 1, 0], [1, 0, 1], [0, 1, 1]]),
        ("two holes", _TWO_HOLES),
    ],
)
@pytest.mark.parametrize("yaw", [0.0, 2.2])
def test_extrusion_watertight_where_cells_touch_diagonally(name, cells, yaw):
    g = OccupancyGrid(np.asarray(cells) * 100, 0.25, (1.5, -2.0, yaw))
    m = extrude_grid(g, 3.0)
    _assert_closed_walls(g, 3.0, m)


def test_diagonal_pinch_gets_a_vertex_per_solid():
    m = extrude_grid(OccupancyGrid([[100, 0], [0, 100]], 1.0), 1.0)
    # two separate cubes: 8 vertices each, the shared corner (1, 1) at both heights twice
    assert len(m.vertices) == 16
    at_pinch = np.all(np.isclose(m.vertices[:, :2], [1.0, 1.0]), axis=1)
    assert at_pinch.sum() == 4
    assert len(m.split(only_watertight=True)) == 2


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("density", [0.2, 0.5, 0.8])
def test_extrusion_of_random_maps_is_watertight(seed, density):
    rng = np.random.default_rng(seed)
    g = OccupancyGrid(
        np.where(rng.random((30, 30)) < density, 100, 0), 0.1, (0.0, 0.0, rng.uniform(-3, 3))
    )
    _assert_closed_walls(g, 2.0, extrude_grid(g, 2.0))


def test_shipped_courtyard_extrudes_watertight():
    g = OccupancyGrid.from_ros_yaml(DEFAULT_MODELS / "courtyard.yaml")
    _assert_closed_walls(g, 2.5, extrude_grid(g, 2.5))
    shipped = load_mesh(DEFAULT_MODELS / "courtyard.ply")
    assert shipped.is_watertight and shipped.is_winding_consistent


def test_environment_mesh_file_wins_else_walls_of_the_grid(tmp_path):
    """A mesh file wins over the map; else the map's 6 occupied 0.5 m cells become walls of
    2 m (volume 6 x 0.25 x 2 = 3 m^3); with neither, an error names the source."""
    from are_stats.environment import environment_mesh

    grid = OccupancyGrid(np.pad(np.full((2, 3), 100), 1), 0.5)
    walls = environment_mesh(grid, 2.0)
    assert walls.volume == pytest.approx(3.0)
    assert walls.bounds[1][2] == pytest.approx(2.0)
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    path = tmp_path / "box.stl"
    box.export(path)
    loaded = environment_mesh(grid, 2.0, path)
    assert loaded.volume == pytest.approx(6.0)
    np.testing.assert_allclose(loaded.bounds, [[-0.5, -1.0, -1.5], [0.5, 1.0, 1.5]])
    assert environment_mesh(None, 2.0, path).volume == pytest.approx(6.0)
    with pytest.raises(InputError, match="scen/manifest.yaml: map: expected a map for the"):
        environment_mesh(None, 2.0, source="scen/manifest.yaml")
