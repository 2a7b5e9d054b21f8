"""Benchmark: the perceived set A_f per frame (640x480, ~100k-triangle mesh, 200 boxes).

Ours: ``are_stats.perceived_counts`` (Warp CPU kernels, ROI culling, environment rays cast
only under a box, only up to the farthest box depth and only in 8x8 pixel blocks whose ray
pyramid meets a triangle's bounding box, each block's rays traced against the few
triangles gathered for its pyramid, launches split over the host's cores). Peer: the
strongest simple pipeline a user would write: Open3D's RaycastingScene (Embree, all
threads) for the full-frame environment depth, then a NumPy float32 slab test per box over
only the pixels of its projected rectangle.

Run ``python -m tests.benchmarks.bench_perception`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import sys
import time

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from are_stats.perception import (
    PinholeCamera,
    box_rois,
    optical_from_base,
    perceive_frames,
    perceived_counts,
    perceived_counts_batch,
)

D_MAX = 40.0
TAU = 20


def _height(x, y):
    return 0.6 * np.sin(0.21 * x) * np.cos(0.17 * y) + 0.3 * np.sin(0.5 * x + 0.3 * y)


def build_scene(seed: int = 0, grid: int = 219, n_boxes: int = 200):
    """Seeded terrain (grid x grid vertices) + 60 buildings; 200 random artefact boxes."""
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.linspace(-10, 60, grid), np.linspace(-35, 35, grid))
    v = np.column_stack([xs.ravel(), ys.ravel(), _height(xs, ys).ravel()])
    i, j = np.meshgrid(np.arange(grid - 1), np.arange(grid - 1), indexing="ij")
    a = (i * grid + j).ravel()
    f = np.concatenate(
        [np.column_stack([a, a + 1, a + grid + 1]), np.column_stack([a, a + grid + 1, a + grid])]
    )
    parts = [trimesh.Trimesh(v, f, process=False)]
    for _ in range(60):
        t = np.eye(4)
        t[:3, :3] = Rotation.from_euler("z", rng.uniform(0, np.pi)).as_matrix()
        x, y = rng.uniform(3, 55), rng.uniform(-30, 30)
        size = rng.uniform([1.0, 1.0, 2.0], [6.0, 6.0, 8.0])
        t[:3, 3] = [x, y, _height(x, y) + size[2] / 2 - 0.3]
        parts.append(trimesh.creation.box(size, t))
    env = trimesh.util.concatenate(parts)
    x = rng.uniform(1.0, 38.0, n_boxes)
    y = rng.uniform(-20.0, 20.0, n_boxes)
    half = rng.uniform([0.2, 0.2, 0.3], [0.8, 0.8, 0.9], (n_boxes, 3))
    centers = np.column_stack([x, y, _height(x, y) + half[:, 2]])
    rots = Rotation.from_euler("z", rng.uniform(0, 2 * np.pi, (n_boxes, 1))).as_matrix()
    cam = PinholeCamera(525.0, 525.0, 319.5, 239.5, 640, 480)
    return env, centers, half, rots, cam


def camera_pose(x: float, yaw: float) -> np.ndarray:
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("z", yaw).as_matrix()
    base[:3, 3] = [x, 0.0, _height(x, 0.0)]
    return base @ optical_from_base([0.0, 0.0, 1.5], [0.0, 0.08, 0.0])


def peer_counts(scene, cam, centers, half, rots):
    """Open3D full-frame Z_env, then a NumPy float32 slab test per box over its rectangle."""
    import open3d as o3d

    o, d = cam.rays()
    rays = o3d.core.Tensor(np.hstack([o, d]).astype(np.float32))
    z_env = scene.cast_rays(rays)["t_hit"].numpy().reshape(cam.height, cam.width)
    z_env = np.where(z_env <= D_MAX, z_env, np.float32(np.inf))
    intr = (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
    rois = box_rois(centers, half, rots, intr, cam.pose[None], D_MAX)[0]
    dcam = cam.directions_camera().astype(np.float32)
    counts = np.zeros(len(centers), np.int64)
    r_cam, c_cam = cam.pose[:3, :3], cam.pose[:3, 3]
    for a in range(len(centers)):
        x0, y0, w, h = rois[a]
        if w == 0 or h == 0:
            continue
        m = (rots[a].T @ r_cam).astype(np.float32)  # camera-frame dirs to box frame
        ob = (rots[a].T @ (c_cam - centers[a])).astype(np.float32)
        sub = dcam[y0 : y0 + h, x0 : x0 + w]
        t_near = np.full((h, w), -np.inf, np.float32)
        t_far = np.full((h, w), np.inf, np.float32)
        for k in range(3):
            dk = sub[..., 0] * m[k, 0] + sub[..., 1] * m[k, 1] + sub[..., 2] * m[k, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = np.float32(1.0) / dk
                t1 = (-half[a, k] - ob[k]) * inv
                t2 = (half[a, k] - ob[k]) * inv
            np.maximum(t_near, np.minimum(t1, t2), out=t_near)
            np.minimum(t_far, np.maximum(t1, t2), out=t_far)
        t = np.maximum(t_near, 0)
        hit = (t_near <= t_far) & (t_far >= 0) & (t <= D_MAX)
        counts[a] = int((hit & (t <= z_env[y0 : y0 + h, x0 : x0 + w])).sum())
    return counts


_SETTLE_S = 0.02


def _paired_times(fns, repeats: int) -> list[float]:
    """Median times of several functions run alternately (fair under a fluctuating load).

    Each timed call starts after a short pause: Open3D's worker threads keep spinning for
    a few milliseconds after a parallel call and would otherwise take the cores from
    whichever function runs next. For the same reason BLAS is held to one thread: the
    peer's 3x3 matrix products wake OpenBLAS's pool, whose idle threads then spin for
    tens of milliseconds (measured: our next frame 27 ms instead of 16 ms); no function
    timed here gains anything from BLAS threads.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        for fn in fns:
            fn()  # warm-up (compiles Warp kernels, builds the BVH)
        times = [[] for _ in fns]
        for _ in range(repeats):
            for k, fn in enumerate(fns):
                time.sleep(_SETTLE_S)
                t0 = time.perf_counter()
                fn()
                times[k].append(time.perf_counter() - t0)
    return [float(np.median(t)) for t in times]


def _median_time(fn, repeats: int) -> float:
    fn()  # warm-up (compiles Warp kernels, builds the BVH)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _rate(label: str, n_rays: int, seconds: float) -> None:
    print(
        f"  full-frame Z_env, {label}: {n_rays / seconds / 1e6:.1f} Mray/s ({seconds * 1e3:.1f} ms)"
    )


def main(quick: bool = False) -> None:
    import open3d as o3d

    repeats = 3 if quick else 7
    env, centers, half, rots, cam0 = build_scene(grid=60 if quick else 219)
    poses = [camera_pose(x, yaw) for x, yaw in [(-8.0, 0.0), (-5.0, 0.25), (0.0, -0.3)]]
    n_rays = cam0.width * cam0.height
    print(
        f"perception: {cam0.width}x{cam0.height} camera, {len(env.faces)} triangles, "
        f"{len(centers)} boxes, d_max {D_MAX}, tau {TAU}; median of {repeats} after warm-up"
    )
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(env.vertices, np.float32)),
        o3d.core.Tensor(np.asarray(env.faces, np.uint32)),
    )
    rows = []
    for p in poses:
        cam = cam0.with_pose(p)
        ours = perceived_counts(env, centers, half, rots, cam, D_MAX, TAU)[0]
        peer = peer_counts(scene, cam, centers, half, rots)
        t_ours, t_peer = _paired_times(
            [
                lambda c=cam: perceived_counts(env, centers, half, rots, c, D_MAX, TAU),
                lambda c=cam: peer_counts(scene, c, centers, half, rots),
            ],
            repeats,
        )
        diff = np.abs(ours - peer)
        rows.append((t_ours, t_peer))
        print(
            f"  frame at x={p[0, 3]:+.1f}: ours {t_ours * 1e3:7.1f} ms  peer {t_peer * 1e3:7.1f} ms"
            f"  ratio {t_peer / t_ours:5.1f}x  | visible boxes {int((ours > 0).sum())}, "
            f"perceived {int((ours > TAU).sum())}, count differences: {int((diff > 0).sum())} "
            f"boxes (max {int(diff.max())} px), perceived-set differences "
            f"{int(((ours > TAU) != (peer > TAU)).sum())}"
        )
    t_o, t_p = np.median([r[0] for r in rows]), np.median([r[1] for r in rows])
    print(
        f"  A_f per frame (median over frames): ours {t_o * 1e3:.1f} ms ({1 / t_o:.1f} frames/s), "
        f"peer {t_p * 1e3:.1f} ms; ratio {t_p / t_o:.1f}x"
    )
    pose_stack = np.stack(poses * 4)
    t_b = _median_time(
        lambda: perceived_counts_batch(env, centers, half, rots, cam0, pose_stack, D_MAX, TAU), 3
    )
    per = t_b / len(pose_stack) * 1e3
    print(f"  batched trajectory of {len(pose_stack)} poses: {per:.1f} ms per frame")
    # full-frame environment depth (eq. 2) alone
    cam = cam0.with_pose(poses[0])
    empty = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    o, d = cam.rays()
    rays = o3d.core.Tensor(np.hstack([o, d]).astype(np.float32))
    fns = {
        "Warp 1 thread": lambda: perceive_frames(
            env, *empty, cam, None, D_MAX, 0, return_depth=True, threads=1
        ),
        "Warp 2 threads": lambda: perceive_frames(
            env, *empty, cam, None, D_MAX, 0, return_depth=True, threads=2
        ),
        "Open3D 1 thread": lambda: scene.cast_rays(rays, nthreads=1),
        "Open3D all threads": lambda: scene.cast_rays(rays, nthreads=0),
    }
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        inter = RayMeshIntersector(env)
        fns["trimesh+embreex"] = lambda: inter.intersects_first(o, d)
    except ImportError:
        print("  trimesh+embreex: not installed")
    for label, t in zip(fns, _paired_times(list(fns.values()), repeats), strict=True):
        _rate(label, n_rays, t)
    # Mray/s of our A_f pipeline counted as full-frame-equivalent rays
    print(
        f"  A_f throughput (full-frame equivalent): ours {n_rays / t_o / 1e6:.1f} Mray/s, "
        f"peer {n_rays / t_p / 1e6:.1f} Mray/s"
    )


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
