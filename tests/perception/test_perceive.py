"""perceived_counts and friends against a brute-force float64 reference (exact counts)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from are_stats.perception import (
    PinholeCamera,
    box_rois,
    clear_mesh_cache,
    optical_from_base,
    perceive_frames,
    perceived_counts,
    perceived_counts_batch,
)
from tests.helpers import assert_allclose
from tests.perception._reference import pixel_rays, ray_box_depth, reference_counts

W, H = 48, 36


def make_camera(x=0.0, y=0.0, z=1.0, yaw=0.0, pitch=0.0, w=W, h=H, f=40.0):
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("z", yaw).as_matrix()
    base[:3, 3] = [x, y, 0.0]
    mount = optical_from_base([0.0, 0.0, z], [0.0, pitch, 0.0])
    return PinholeCamera(f, f * 1.1, w / 2 + 0.3, h / 2 - 0.2, w, h, base @ mount)


def make_env(rng, n_boxes=4):
    """A jittered ground grid plus a few rotated boxes (walls)."""
    xs, ys = np.meshgrid(np.linspace(-2, 12, 9), np.linspace(-7, 7, 9))
    zs = rng.uniform(-0.05, 0.05, xs.shape)
    v = np.column_stack([xs.ravel(), ys.ravel(), zs.ravel()])
    f = []
    for i in range(8):
        for j in range(8):
            a, b, c, d = i * 9 + j, i * 9 + j + 1, (i + 1) * 9 + j, (i + 1) * 9 + j + 1
            f += [[a, b, d], [a, d, c]]
    parts = [trimesh.Trimesh(v, np.array(f), process=False)]
    for _ in range(n_boxes):
        t = np.eye(4)
        t[:3, :3] = Rotation.from_euler("z", rng.uniform(0, np.pi)).as_matrix()
        t[:3, 3] = [rng.uniform(3, 9), rng.uniform(-3, 3), 0.6]
        parts.append(trimesh.creation.box(rng.uniform([0.2, 0.8, 1.0], [0.5, 2.0, 1.4]), t))
    return trimesh.util.concatenate(parts)


def make_boxes(rng, n):
    c = np.column_stack([rng.uniform(0.5, 11, n), rng.uniform(-4, 4, n), rng.uniform(0.1, 1.5, n)])
    h = rng.uniform(0.1, 0.6, (n, 3))
    r = Rotation.random(n, random_state=rng.integers(2**31)).as_matrix()
    return c, h, r


def reference(cam, env, c, h, r, d_max, occlusion=False):
    v = np.asarray(env.vertices) if env is not None else np.zeros((0, 3))
    f = np.asarray(env.faces) if env is not None else np.zeros((0, 3), int)
    return reference_counts(cam.K, cam.width, cam.height, cam.pose, v, f, c, h, r, d_max, occlusion)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_counts_small_scenes(seed):
    rng = np.random.default_rng(seed)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 25)
    for yaw in (-0.3, 0.0, 0.4):
        cam = make_camera(yaw=yaw, pitch=0.15)
        ref, _, za = reference(cam, env, c, h, r, 9.0)
        assert (ref > 0).sum() >= 3  # the scene is not trivial
        assert (ref < np.isfinite(za).sum(axis=1)).any()  # something is occluded
        counts, seen = perceived_counts(env, c, h, r, cam, 9.0, 5)
        np.testing.assert_array_equal(counts, ref)
        np.testing.assert_array_equal(seen, ref > 5)


@pytest.mark.parametrize("seed", [3, 4])
def test_occlusion_between_artefacts_and_depth(seed):
    rng = np.random.default_rng(seed)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 30)
    cam = make_camera(yaw=0.1, pitch=0.1)
    ref, z_env, za = reference(cam, env, c, h, r, 8.0, occlusion=True)
    res = perceive_frames(
        env, c, h, r, cam, None, 8.0, 3, occlusion_between_artefacts=True, return_depth=True
    )
    np.testing.assert_array_equal(res.counts[0], ref)
    ref_plain = reference(cam, env, c, h, r, 8.0)[0]
    assert (ref < ref_plain).any()  # boxes do hide each other here
    np.testing.assert_array_equal(np.isfinite(res.depth_env[0].ravel()), np.isfinite(z_env))
    fin = np.isfinite(z_env)
    assert_allclose(res.depth_env[0].ravel()[fin], z_env[fin], rtol=1e-5)
    aug = np.minimum(z_env, za.min(axis=0))
    fin = np.isfinite(aug)
    assert_allclose(res.depth[0].ravel()[fin], aug[fin], rtol=1e-5)


def test_against_trimesh_ray_casts_larger_scene():
    rng = np.random.default_rng(7)
    terrain = trimesh.creation.icosphere(subdivisions=4, radius=30.0)  # 5k faces, inside view
    terrain.vertices += rng.normal(0, 0.05, terrain.vertices.shape)
    env = trimesh.util.concatenate([terrain, make_env(rng, 8)])
    c, h, r = make_boxes(rng, 60)
    cam = make_camera(yaw=0.2, pitch=0.05, w=120, h=90, f=90.0)
    origin, dirs = pixel_rays(cam.K, cam.width, cam.height, cam.pose)
    locs, idx_ray, _ = trimesh.ray.ray_triangle.RayMeshIntersector(env).intersects_location(
        np.broadcast_to(origin, dirs.shape), dirs, multiple_hits=False
    )
    z_env = np.full(len(dirs), np.inf)
    z_env[idx_ray] = np.linalg.norm(locs - origin, axis=1)
    z_env[z_env > 40.0] = np.inf
    ref = reference_counts(
        cam.K, cam.width, cam.height, cam.pose, None, None, c, h, r, 40.0, z_env=z_env
    )[0]
    res = perceive_frames(env, c, h, r, cam, None, 40.0, 10, return_depth=True)
    fin = np.isfinite(z_env)
    np.testing.assert_array_equal(np.isfinite(res.depth_env[0].ravel()), fin)
    assert_allclose(res.depth_env[0].ravel()[fin], z_env[fin], rtol=1e-4)
    # ties between float32 and float64 hits may flip a pixel or two per artefact
    assert np.abs(res.counts[0] - ref).max() <= 2
    assert ref.sum() > 1000


def test_batch_equals_frames_and_active_mask():
    rng = np.random.default_rng(11)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 20)
    cams = [make_camera(x=x, yaw=yaw, pitch=0.1) for x, yaw in [(0, 0), (1, 0.3), (2, -0.4)]]
    poses = np.stack([cm.pose for cm in cams])
    active = rng.random((3, 20)) < 0.7
    counts, seen = perceived_counts_batch(env, c, h, r, cams[0], poses, 9.0, 4, active=active)
    assert counts.shape == (3, 20)
    for t, cam in enumerate(cams):
        ref = reference(cam, env, c, h, r, 9.0)[0]
        np.testing.assert_array_equal(counts[t], np.where(active[t], ref, 0))
    np.testing.assert_array_equal(seen, counts > 4)


def test_threads_give_same_counts():
    rng = np.random.default_rng(5)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 40)
    cam = make_camera(pitch=0.1, w=200, h=150, f=150.0)
    one = perceived_counts(env, c, h, r, cam, 9.0, 0, threads=1)[0]
    two = perceived_counts(env, c, h, r, cam, 9.0, 0, threads=2)[0]
    three = perceived_counts(env, c, h, r, cam, 9.0, 0, threads=3)[0]
    np.testing.assert_array_equal(one, two)
    np.testing.assert_array_equal(one, three)
    assert one.sum() > 10000  # large enough that the launches are really split


def test_split_box_depths_are_exact(monkeypatch):
    """Host threads that take chunks of whole image rows give the exact counts and depths."""
    from are_stats.perception import _kernels

    rng = np.random.default_rng(8)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 30)
    cam = make_camera(pitch=0.1, yaw=-0.2, w=96, h=72, f=80.0)
    seen = []
    inner = _kernels.launch_dynamic

    def spy(kernel, n, workers, make_inputs, device="cpu", edges=None):
        if kernel is _kernels.pair_depth_kernel:
            seen.append((workers, edges))
        inner(kernel, n, workers, make_inputs, device, edges)

    monkeypatch.setattr(_kernels, "_MIN_SPLIT_ITEMS", 0)
    monkeypatch.setattr(_kernels, "launch_dynamic", spy)
    monkeypatch.setattr(_kernels, "split_bounds", lambda n, device, threads: [(0, 1), (1, n)])
    ref, z_env, za = reference(cam, env, c, h, r, 9.0)
    res = perceive_frames(env, c, h, r, cam, None, 9.0, 0, return_depth=True, threads=2)
    np.testing.assert_array_equal(res.counts[0], ref)
    assert seen and seen[0][0] == 2 and len(seen[0][1]) > 3  # really split into chunks
    aug = np.minimum(z_env, za.min(axis=0))
    fin = np.isfinite(aug)
    np.testing.assert_array_equal(np.isfinite(res.depth[0].ravel()), fin)
    assert_allclose(res.depth[0].ravel()[fin], aug[fin], rtol=1e-5)


@pytest.mark.parametrize("occlusion", [False, True])
def test_per_item_kernels_are_exact(monkeypatch, occlusion):
    """The pair kernels with one work item per pair item (the CUDA launches), run here on
    the CPU, give the reference counts and depths, like their per-row CPU launches."""
    from are_stats.perception import _kernels

    rng = np.random.default_rng(8)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 30)
    cam = make_camera(pitch=0.1, yaw=-0.2, w=96, h=72, f=80.0)
    ref, z_env, za = reference(cam, env, c, h, r, 9.0, occlusion=occlusion)
    rows = perceive_frames(
        env, c, h, r, cam, None, 9.0, 0, occlusion_between_artefacts=occlusion, return_depth=True
    )
    launched = []
    inner = _kernels.wp.launch

    def spy(kernel, *args, **kwargs):
        if kernel in (_kernels.pair_depth_kernel, _kernels.pair_count_kernel):
            rows_at = [a.label for a in kernel.adj.args].index("rows")
            launched.append((kernel, kwargs["inputs"][rows_at]))
        return inner(kernel, *args, **kwargs)

    monkeypatch.setattr(_kernels, "_is_cpu", lambda device: False)
    monkeypatch.setattr(_kernels.wp, "launch", spy)
    monkeypatch.setattr(_kernels, "split_bounds", lambda n, device, threads: [(0, 7), (7, n)])
    items = perceive_frames(
        env,
        c,
        h,
        r,
        cam,
        None,
        9.0,
        0,
        occlusion_between_artefacts=occlusion,
        return_depth=True,
        threads=2,
    )
    assert {k for k, _ in launched} == {_kernels.pair_depth_kernel, _kernels.pair_count_kernel}
    assert all(rows == 0 for _, rows in launched)  # one work item per pair item
    assert ref.sum() > 300
    np.testing.assert_array_equal(items.counts[0], ref)
    np.testing.assert_array_equal(items.counts, rows.counts)
    np.testing.assert_array_equal(items.depth, rows.depth)
    aug = np.minimum(z_env, za.min(axis=0))
    fin = np.isfinite(aug)
    np.testing.assert_array_equal(np.isfinite(items.depth[0].ravel()), fin)
    assert_allclose(items.depth[0].ravel()[fin], aug[fin], rtol=1e-5)


def test_first_call_split_over_threads_in_a_fresh_process():
    """The first launch of the kernels may be a multi-threaded one (it loads the module)."""
    import subprocess
    import sys

    code = (
        "from tests.benchmarks.bench_perception import build_scene, camera_pose\n"
        "from are_stats.perception import perceived_counts\n"
        "env, c, h, r, cam = build_scene(grid=60)\n"
        "cam = cam.with_pose(camera_pose(-8.0, 0.0))\n"
        "a = perceived_counts(env, c, h, r, cam, 40.0, 20, threads=2)[0]\n"
        "b = perceived_counts(env, c, h, r, cam, 40.0, 20, threads=1)[0]\n"
        "assert (a == b).all() and a.sum() > 40000, a.sum()  # 120k box pixels: split\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]


def test_row_chunk_edges_never_split_an_image_row():
    from are_stats.perception._kernels import row_chunk_edges

    rng = np.random.default_rng(2)
    key = np.sort(rng.integers(0, 40, 500))
    work = rng.integers(1, 50, 500)
    edges = row_chunk_edges(key, work, 8)
    assert edges[0] == 0 and edges[-1] == 500 and np.all(np.diff(edges) > 0)
    for e in edges[1:-1]:
        assert key[e - 1] != key[e]  # a chunk boundary is a change of image row
    assert len(edges) >= 6  # 40 rows are enough for most of the 8 chunks
    np.testing.assert_array_equal(row_chunk_edges(np.zeros(0, int), np.zeros(0, int), 4), [0])
    np.testing.assert_array_equal(row_chunk_edges(np.zeros(9, int), np.ones(9, int), 4), [0, 9])


@pytest.mark.parametrize("block", [1, 5, 8, 64])
def test_block_culling_is_exact(monkeypatch, block):
    """Pixel blocks cleared without casting rays change no count (W, H not multiples)."""
    from are_stats.perception import _perceive

    rng = np.random.default_rng(3)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 25)
    cam = make_camera(pitch=0.1, yaw=0.2)
    flags = []
    inner = _perceive.kern.launch_env_blocks

    def spy(*args):
        inner(*args)
        status = inspect.signature(inner).bind(*args).arguments["status"]
        flags.append(status.numpy().copy())  # per-block status: 0 idle, 1 cleared, 2 rays

    monkeypatch.setattr(_perceive, "_BLOCK", block)
    monkeypatch.setattr(_perceive.kern, "launch_env_blocks", spy)
    counts = perceived_counts(env, c, h, r, cam, 9.0, 0)[0]
    ref = reference(cam, env, c, h, r, 9.0)[0]
    np.testing.assert_array_equal(counts, ref)
    assert ref.sum() > 500
    if block <= 8:  # small blocks: some are cleared, some need rays
        assert flags and (flags[0] == 1).any() and (flags[0] == 2).any()


def test_last_hit_triangle_shortcut_is_exact(monkeypatch):
    """Trying the block's last-hit triangle first changes no count and no depth."""
    from are_stats.perception import _kernels

    rng = np.random.default_rng(11)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 30)
    cam = make_camera(pitch=0.1, yaw=-0.2)
    runs = {}
    for flag in (0, 1):
        monkeypatch.setattr(_kernels, "COHERENT", flag)
        runs[flag] = perceive_frames(env, c, h, r, cam, None, 9.0, 0, return_depth=True)
        runs[flag, "counts"] = perceived_counts(env, c, h, r, cam, 9.0, 0)[0]
    np.testing.assert_array_equal(runs[0, "counts"], runs[1, "counts"])
    np.testing.assert_array_equal(runs[1, "counts"], reference(cam, env, c, h, r, 9.0)[0])
    np.testing.assert_array_equal(runs[0].depth_env, runs[1].depth_env)
    assert runs[1, "counts"].sum() > 500


@pytest.mark.parametrize("cap", [1, 3, 32])
def test_frustum_gathering_is_exact(monkeypatch, cap):
    """Rays tested against the triangles gathered per block: exact counts, same depths.

    Small caps make many blocks overflow to the per-ray BVH query, so both paths and their
    mix within one frame are exercised; the camera stands on the ground grid, whose
    triangles reach behind it (the whole-block pixel rectangle of _tri_rect).
    """
    from are_stats.perception import _kernels

    rng = np.random.default_rng(21)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 30)
    for yaw, pitch in ((0.2, 0.1), (-0.5, 0.3)):
        cam = make_camera(yaw=yaw, pitch=pitch)
        ref, z_ref, _ = reference(cam, env, c, h, r, 9.0)
        monkeypatch.setattr(_kernels, "GATHER_CAP", 0)
        plain = perceive_frames(env, c, h, r, cam, None, 9.0, 0, return_depth=True)
        monkeypatch.setattr(_kernels, "GATHER_CAP", cap)
        got = perceive_frames(env, c, h, r, cam, None, 9.0, 0, return_depth=True)
        np.testing.assert_array_equal(perceived_counts(env, c, h, r, cam, 9.0, 0)[0], ref)
        occ = perceived_counts(env, c, h, r, cam, 9.0, 0, occlusion_between_artefacts=True)[0]
        np.testing.assert_array_equal(occ, reference(cam, env, c, h, r, 9.0, occlusion=True)[0])
        np.testing.assert_array_equal(got.counts[0], ref)
        assert ref.sum() > 300
        # depth images: Moeller-Trumbore and Warp's watertight test agree to rounding
        z_got, z_plain = got.depth_env[0], plain.depth_env[0]
        np.testing.assert_array_equal(np.isfinite(z_got), np.isfinite(z_plain))
        fin = np.isfinite(z_got)
        assert fin.mean() > 0.5
        assert_allclose(z_got[fin], z_plain[fin], rtol=1e-5, atol=1e-6)
        assert_allclose(z_got[fin], z_ref.reshape(z_got.shape)[fin], rtol=1e-4, atol=1e-5)


# ---------------------------------------------------------------------- edge cases


def _box(center, half=(0.5, 0.5, 0.5), rot=None):
    return (
        np.array([center], float),
        np.array([half], float),
        np.array([np.eye(3) if rot is None else rot]),
    )


def test_camera_inside_box_sees_it_everywhere():
    cam = make_camera()
    c, h, r = _box(
        cam.center, (0.3, 0.3, 0.3), Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix()
    )
    env = make_env(np.random.default_rng(0))
    counts, seen = perceived_counts(env, c, h, r, cam, 9.0, W * H - 1)
    assert counts.tolist() == [W * H] and seen.tolist() == [True]


def test_box_behind_camera_and_beyond_dmax():
    cam = make_camera()  # looking along +x from (0, 0, 1)
    c = np.array([[-3.0, 0.0, 1.0], [8.0, 0.0, 1.0], [4.0, 0.0, 1.0]])
    h = np.full((3, 3), 0.5)
    r = np.stack([np.eye(3)] * 3)
    counts, _ = perceived_counts(trimesh.Trimesh(), c, h, r, cam, 6.0, 0)
    ref = reference(cam, None, c, h, r, 6.0)[0]
    np.testing.assert_array_equal(counts, ref)
    assert counts[0] == 0 and counts[1] == 0 and counts[2] > 0


def test_box_straddling_dmax_and_camera_plane():
    cam = make_camera()
    # long box from behind the camera to beyond d_max, offset sideways and up
    rng = np.random.default_rng(2)
    c = np.array([[2.0, 0.6, 1.3], [0.0, -0.4, 1.0], [5.8, 0.0, 1.0], [0.01, 0.0, 1.0]])
    h = np.array([[6.0, 0.2, 0.2], [0.3, 0.3, 2.0], [0.5, 3.0, 0.4], [0.02, 0.5, 0.5]])
    r = Rotation.from_euler("z", rng.uniform(-0.2, 0.2, (4, 1))).as_matrix()
    counts, _ = perceived_counts(None, c, h, r, cam, 6.0, 0)
    ref = reference(cam, None, c, h, r, 6.0)[0]
    np.testing.assert_array_equal(counts, ref)
    assert (ref > 0).all()


def test_rois_are_conservative():
    rng = np.random.default_rng(9)
    cam = make_camera(pitch=0.2)
    c = cam.center + rng.normal(0, 2.0, (300, 3)) + 1.5 * cam.R[:, 2]  # around and ahead
    h = rng.uniform(0.05, 1.0, (300, 3))
    r = Rotation.random(300, random_state=3).as_matrix()
    intr = (cam.fx, cam.fy, cam.cx, cam.cy, W, H)
    rois = box_rois(c, h, r, intr, cam.pose[None], 4.0)[0]
    origin, dirs = pixel_rays(cam.K, W, H, cam.pose)
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    u, v = u.ravel(), v.ravel()
    n_hit = 0
    for i in range(300):
        hit = np.isfinite(ray_box_depth(origin, dirs, c[i], h[i], r[i], 4.0))
        x0, y0, w, hh = rois[i]
        inside = (u >= x0) & (u < x0 + w) & (v >= y0) & (v < y0 + hh)
        assert not (hit & ~inside).any(), f"box {i}: a hit pixel lies outside its ROI"
        n_hit += hit.any()
    assert n_hit > 50


def test_box_partly_out_of_image():
    cam = make_camera()
    c, h, r = _box([3.0, 1.5, 1.0], (0.5, 0.6, 0.4))
    counts, _ = perceived_counts(None, c, h, r, cam, 9.0, 0)
    ref, _, za = reference(cam, None, c, h, r, 9.0)
    np.testing.assert_array_equal(counts, ref)
    cols = np.isfinite(za[0]).reshape(H, W).any(axis=0)
    assert cols[0] and not cols[-1]  # clipped at the image's left edge


def test_count_exactly_tau_is_not_perceived():
    rng = np.random.default_rng(0)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 15)
    cam = make_camera(pitch=0.1)
    counts, _ = perceived_counts(env, c, h, r, cam, 9.0, 0)
    a = int(np.argmax(counts))
    k = int(counts[a])
    assert not perceived_counts(env, c, h, r, cam, 9.0, k)[1][a]
    assert perceived_counts(env, c, h, r, cam, 9.0, k - 1)[1][a]
    assert perceived_counts(env, c, h, r, cam, 9.0, k - 0.5)[1][a]


def test_empty_mesh_and_zero_artefacts():
    rng = np.random.default_rng(1)
    c, h, r = make_boxes(rng, 10)
    cam = make_camera()
    counts, _ = perceived_counts(trimesh.Trimesh(), c, h, r, cam, 9.0, 0)
    np.testing.assert_array_equal(counts, reference(cam, None, c, h, r, 9.0)[0])
    empty = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    counts, seen = perceived_counts(make_env(rng), *empty, cam, 9.0, 0)
    assert counts.shape == (0,) and seen.shape == (0,) and seen.dtype == bool
    res = perceive_frames(trimesh.Trimesh(), *empty, cam, None, 9.0, 0, return_depth=True)
    assert res.depth_env.shape == (1, H, W) and np.isinf(res.depth_env).all()


def test_bvh_cache_reused_and_refitted():
    clear_mesh_cache()
    rng = np.random.default_rng(4)
    env = make_env(rng)
    c, h, r = make_boxes(rng, 20)
    cam = make_camera(pitch=0.1)
    first = perceived_counts(env, c, h, r, cam, 9.0, 0)[0]
    from are_stats.perception import _perceive

    mesh_id = _perceive._warp_mesh(env, "cpu")
    assert _perceive._warp_mesh(env, "cpu") == mesh_id  # built once
    np.testing.assert_array_equal(perceived_counts(env, c, h, r, cam, 9.0, 0)[0], first)
    env.vertices[:, 2] += 0.4  # move the environment in place: refit
    assert _perceive._warp_mesh(env, "cpu") == mesh_id
    moved = perceived_counts(env, c, h, r, cam, 9.0, 0)[0]
    np.testing.assert_array_equal(moved, reference(cam, env, c, h, r, 9.0)[0])
    assert not np.array_equal(moved, first)


# ---------------------------------------------------------------------- bad input


class _Cam:
    def __init__(self, k, width=W, height=H, pose=None):
        self.K, self.width, self.height = np.asarray(k, float), width, height
        self.pose = np.eye(4) if pose is None else pose


def test_bad_input_errors():
    c, h, r = _box([3.0, 0.0, 0.0])
    cam = make_camera()
    with pytest.raises(ValueError, match="rotations: expected orthonormal"):
        perceived_counts(None, c, h, r * 1.5, cam, 9.0, 0)
    with pytest.raises(ValueError, match="rotations: expected orthonormal"):
        perceived_counts(None, c, h, -r, cam, 9.0, 0)  # a reflection
    with pytest.raises(ValueError, match="half_extents: expected finite numbers >= 0"):
        perceived_counts(None, c, -h, r, cam, 9.0, 0)
    with pytest.raises(ValueError, match=r"centers: expected shape \(n, 3\)"):
        perceived_counts(None, c[:, :2], h, r, cam, 9.0, 0)
    with pytest.raises(ValueError, match="half_extents: expected shape"):
        perceived_counts(None, c, h[:, :2], r, cam, 9.0, 0)
    with pytest.raises(ValueError, match="principal point inside"):
        perceived_counts(None, c, h, r, _Cam([[40, 0, 80], [0, 40, 10], [0, 0, 1]]), 9.0, 0)
    with pytest.raises(ValueError, match="focal lengths > 0"):
        perceived_counts(None, c, h, r, _Cam([[-40, 0, 20], [0, 40, 10], [0, 0, 1]]), 9.0, 0)
    with pytest.raises(ValueError, match="camera: expected an object with K"):
        perceived_counts(None, c, h, r, object(), 9.0, 0)
    with pytest.raises(ValueError, match="d_max: expected a finite number > 0"):
        perceived_counts(None, c, h, r, cam, 0.0, 0)
    with pytest.raises(ValueError, match="tau: expected a finite number >= 0"):
        perceived_counts(None, c, h, r, cam, 9.0, -1)
    with pytest.raises(ValueError, match="camera.pose: expected rigid transforms"):
        bad = np.eye(4)
        bad[0, 0] = 2.0
        perceived_counts(None, c, h, r, _Cam(cam.K, pose=bad), 9.0, 0)
    with pytest.raises(ValueError, match="env_mesh: expected a trimesh.Trimesh"):
        perceived_counts("mesh.ply", c, h, r, cam, 9.0, 0)
    with pytest.raises(ValueError, match=r"active: expected a \(1, 1\) boolean array"):
        perceive_frames(None, c, h, r, cam, None, 9.0, 0, active=np.ones((2, 1), bool))


@pytest.mark.parametrize("moving", [False, True])
def test_roi_cull_drops_only_boxes_the_exact_test_gives_nothing(moving):
    """box_rois skips the boxes beyond d_max or behind the camera before the exact
    rectangles: its output equals the exact rectangles of every (frame, box) pair, the
    skipped ones included (which are all empty)."""
    from are_stats.perception._perceive import _pair_rois

    rng = np.random.default_rng(11)
    cams = [make_camera(pitch=p) for p in (0.0, 0.2, -0.1)]
    poses = np.stack([c.pose for c in cams])
    n = 400
    # around the cameras, in front, behind, beside, beyond d_max and straddling the camera
    c = cams[0].center + rng.normal(0.0, 4.0, (n, 3))
    c[:5] = cams[0].center + rng.normal(0.0, 0.05, (5, 3))
    h = rng.uniform(0.05, 1.5, (n, 3))
    r = Rotation.random(n, random_state=5).as_matrix()
    if moving:
        c = c[None] + rng.normal(0.0, 0.3, (3, n, 3))
        r = np.stack([r, r[::-1], r])
    intr = (cams[0].fx, cams[0].fy, cams[0].cx, cams[0].cy, W, H)
    got = box_rois(c, h, r, intr, poses, 4.0)
    ft, fb = np.meshgrid(np.arange(3), np.arange(n), indexing="ij")
    ft, fb = ft.ravel(), fb.ravel()
    want = _pair_rois(
        c[ft, fb] if moving else c[fb], h[fb], r[ft, fb] if moving else r[fb],
        poses[ft, :3, 3], poses[ft, :3, :3], intr, 4.0,
    ).reshape(3, n, 4)  # fmt: skip
    empty = (want[..., 2] == 0) | (want[..., 3] == 0)
    assert empty.sum() > n and (~empty).sum() > 20  # both kinds are there
    np.testing.assert_array_equal(got[~empty], want[~empty])
    assert ((got[empty, 2] == 0) | (got[empty, 3] == 0)).all()
