"""Environment mesh S_E: loading and extrusion of 2D maps."""

from __future__ import annotations

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
    with pytest.raises(FileNotFoundError, match="mesh file not found"):
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
    with pytest.raises(InputError, match="expected a mesh file .*, got not a file"):
        load_mesh(tmp_path)
    with limits(memory="1K"), pytest.raises(LimitError, match="courtyard.ply"):
        load_mesh(DEFAULT_MODELS / "courtyard.ply")


def test_extrusion_work_is_bounded():
    checker = np.indices((60, 60)).sum(axis=0) % 2 * 100  # 1800 separate occupied cells
    g = OccupancyGrid(checker, 0.1)
    with limits(work=1800 * 2000 - 1), pytest.raises(LimitError, match="1800 occupied rect"):
        extrude_grid(g, 2.0)
