"""VoxelMap M_3D: set semantics, OctoMap .bt files, mesh voxelisation."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from are_stats import VoxelMap
from are_stats.inputs import InputError, LimitError, limits


def test_insert_remove_query_against_python_set(rng):
    vm = VoxelMap(0.25)
    ref: set[tuple[int, int, int]] = set()
    for _ in range(20):
        pts = rng.uniform(-3, 3, (rng.integers(1, 40), 3))
        keys = [tuple(int(v) for v in np.floor(p / 0.25)) for p in pts]
        if rng.random() < 0.6:
            vm.insert_points(pts)
            ref |= set(keys)
        else:
            vm.remove_points(pts)
            ref -= set(keys)
        assert len(vm) == len(ref)
        assert {tuple(k) for k in vm.keys.tolist()} == ref
    q = rng.uniform(-3, 3, (200, 3))
    expect = [tuple(int(v) for v in np.floor(p / 0.25)) in ref for p in q]
    assert vm.query(q).tolist() == expect
    assert np.allclose(vm.centres(), (vm.keys + 0.5) * 0.25)


def _bt(res, payload, size=17):
    head = f"# Octomap OcTree binary file\n# a comment\nid OcTree\nsize {size}\nres {res}\ndata\n"
    return head.encode() + bytes(payload)


def test_read_hand_made_bt(tmp_path):
    # one voxel with key (32768, 32768, 32768), i.e. the voxel [0, res)^3:
    # root: child 7 inner (bits 14, 15 set: second byte 0xC0); depths 1-14: child 0 inner
    # (0x03); depth 15: child 0 occupied leaf (bit 1: 0x02)
    payload = [0x00, 0xC0] + [0x03, 0x00] * 14 + [0x02, 0x00]
    p = tmp_path / "one.bt"
    p.write_bytes(_bt(0.1, payload))
    vm = VoxelMap.from_octomap_bt(p)
    assert vm.resolution == 0.1
    assert vm.keys.tolist() == [[0, 0, 0]]
    # a pruned occupied leaf at depth 15 covers 2 x 2 x 2 voxels; a free leaf adds nothing
    payload = [0x00, 0xC0] + [0x03, 0x00] * 13 + [0x02 | (0x01 << 2), 0x00]
    p.write_bytes(_bt(0.1, payload))
    keys = VoxelMap.from_octomap_bt(p).keys
    assert sorted(map(tuple, keys.tolist())) == [
        (x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)
    ]


def test_bt_round_trip(tmp_path, rng):
    vm = VoxelMap(0.05)
    vm.insert_points(rng.uniform(-4, 4, (700, 3)))
    p = vm.to_octomap_bt(tmp_path / "r.bt")
    back = VoxelMap.from_octomap_bt(p)
    assert back.resolution == 0.05
    assert (back.keys == vm.keys).all()


def test_bt_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="none.bt: no such file: expected an OctoMap"):
        VoxelMap.from_octomap_bt(tmp_path / "none.bt")
    p = tmp_path / "x.bt"
    p.write_bytes(b"# something else\n")
    with pytest.raises(ValueError, match="not an OctoMap"):
        VoxelMap.from_octomap_bt(p)
    p.write_bytes(_bt(0.1, [0x00, 0xC0, 0x03]))
    with pytest.raises(InputError, match="x.bt: byte .*: expected more tree data"):
        VoxelMap.from_octomap_bt(p)
    p.write_bytes(b"# Octomap OcTree binary file\nid OcTree\nsize 1\ndata\n\x00\x00")
    with pytest.raises(InputError, match="x.bt: header: expected a line 'res R'"):
        VoxelMap.from_octomap_bt(p)
    with pytest.raises(InputError, match="expected an OctoMap .bt file, got a directory"):
        VoxelMap.from_octomap_bt(tmp_path)


@pytest.mark.parametrize(
    ("header", "match"),
    [
        (b"res 1e300\nsize 1\n", r"header 'res': expected a resolution in \[1e-06, 10000\] m"),
        (b"res nan\nsize 1\n", r"header 'res': expected a resolution"),
        (b"res -0.1\nsize 1\n", r"header 'res': expected a resolution"),
        (b"res 0.1\nsize -4\n", r"header 'size': expected a node count >= 0"),
        (b"res 0.1\nsize many\n", r"header 'size': expected a node count >= 0"),
    ],
)
def test_bt_header_values(tmp_path, header, match):
    p = tmp_path / "h.bt"
    p.write_bytes(b"# Octomap OcTree binary file\nid OcTree\n" + header + b"data\n\x00\x00")
    with pytest.raises(InputError, match=match):
        VoxelMap.from_octomap_bt(p)


def test_bt_pruned_blocks_are_checked_against_the_memory_limit(tmp_path):
    p = tmp_path / "big.bt"
    # child 0 of the root an occupied leaf: a pruned block of 32768^3 voxels
    p.write_bytes(b"# Octomap OcTree binary file\nid OcTree\nsize 1\nres 0.1\ndata\n\x02\x00")
    with pytest.raises(LimitError, match=r"big.bt: expected the 35184372088832 occupied voxels"):
        VoxelMap.from_octomap_bt(p)


def test_mesh_voxelisation_covers_the_surface(rng):
    box = trimesh.creation.box(extents=[1.0, 0.6, 0.4])
    box.apply_translation([0.13, -0.27, 0.2])
    res = 0.1
    vm = VoxelMap.from_mesh(box, res)
    pts, _ = trimesh.sample.sample_surface(box, 3000, seed=1)
    # points strictly inside voxels (not on voxel boundaries) must have their voxel marked
    frac = pts / res - np.floor(pts / res)
    interior = ((frac > 1e-6) & (frac < 1 - 1e-6)).all(axis=1)
    assert vm.query(pts[interior]).all()
    # and every marked voxel touches the surface
    c = vm.centres()
    lo, hi = box.bounds
    d_out = np.maximum(np.maximum(lo - c, c - hi), 0)
    inside_d = np.minimum(c - lo, hi - c).min(axis=1)
    dist = np.where((d_out > 0).any(1), np.linalg.norm(d_out, axis=1), inside_d)
    assert (dist <= res * np.sqrt(3) / 2 + 1e-9).all()


def test_voxel_errors():
    with pytest.raises(ValueError, match="resolution"):
        VoxelMap(-1.0)
    with pytest.raises(ValueError, match="points"):
        VoxelMap(0.1).insert_points([[1.0, 2.0]])


def test_bt_voxel_count_is_checked_cumulatively(tmp_path):
    vm = VoxelMap(0.1, np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3))
    p = vm.to_octomap_bt(tmp_path / "cube.bt")
    with limits(memory=f"{96 * 300}"), pytest.raises(LimitError, match="occupied voxels"):
        VoxelMap.from_octomap_bt(p)
    assert len(VoxelMap.from_octomap_bt(p)) == 512
