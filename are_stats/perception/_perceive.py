"""The perceived set A_f of paper section 3.3 (eq. 2 and A_f), batched over camera poses.

For a frame with camera matrix P and range ``d_max`` the paper defines per pixel (i, j)
``Z_env`` (eq. 2: the first root of the pixel's ray with the environment mesh S_3D in
``[0, d_max]``, else +inf) and, for every artefact a, ``Z_a`` (the first root with a's
bounding box). Then

    A_f = {a | count((Z_a - Z_env)_ij <= 0) > tau}.

Following DECISIONS 8, a pixel counts for a when ``Z_a`` is finite and ``Z_a <= Z_env``.
The first root of a box is ``max(t_near, 0)``: a camera inside a box sees it at depth 0 in
every pixel.

Only the rays that can hit an artefact are cast: every box is clipped to the slab of
optical depths it can be seen at and projected to a pixel rectangle (ROI culling); a
kernel computes ``Z_a`` over the (artefact, pixel-in-rectangle) items and keeps, per pixel,
the largest and smallest finite ``Z_a``; the environment ray of a pixel is cast only where
some ``Z_a`` is finite, and only up to that largest ``Z_a`` (a farther environment hit
occludes nothing). Where all box depths of a pixel are equal (usually one box), Warp's
any-hit query answers "is anything hit before Z_a" exactly. Before any ray is cast, 8x8
pixel blocks whose ray pyramid meets no triangle bounding box are cleared (their rays
could hit nothing), which removes most rays to near boxes. The rays of the other blocks
are traced together: the nearest triangles of the block's ray pyramid are gathered from a
second, implicit tree over the mesh (:mod:`._frustum_bvh`) and each ray tests only those,
with Warp's watertight BVH query wherever that short list cannot settle a ray exactly.
"""

from __future__ import annotations

import os
import weakref
from typing import TYPE_CHECKING, NamedTuple, TypedDict, Unpack

import jax
import numpy as np
import numpy.typing as npt
import warp as wp

from are_stats._checks import check_finite, check_nonnegative, check_probability, describe
from are_stats.perception import _kernels as kern
from are_stats.perception._camera import CameraModel
from are_stats.perception._frustum_bvh import FrustumBVH, build_frustum_bvh

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "PerceptionResult",
    "TraceOptions",
    "perceived_counts",
    "perceived_counts_batch",
    "perceive_frames",
    "sample_perceived",
    "box_rois",
    "clear_mesh_cache",
]

_ITEMS_PER_CHUNK = 1 << 24  # (artefact, pixel) items per launch group
_PIXELS_PER_CHUNK = 1 << 23  # frame pixels per launch group (bounds the per-pixel buffers)


class TraceOptions(TypedDict, total=False):
    """How the rays are traced: the keywords that :func:`perceived_counts`,
    :func:`perceived_counts_batch`, :func:`~are_stats.perception.perceive_scene` and
    :func:`~are_stats.perception.perceive_scenario` pass on to :func:`perceive_frames`,
    whose defaults they keep (no occlusion between artefacts, the CPU, the CPUs this
    process may use, at most 8).

    Attributes
    ----------
    occlusion_between_artefacts : bool
        Beyond the paper: a pixel counts for a only if no other box is nearer (ties count
        for both).
    device : str
        Warp device, ``"cpu"`` or ``"cuda"``.
    threads : int or None
        Host threads for CPU launches.
    """

    occlusion_between_artefacts: bool
    device: str
    threads: int | None


class PerceptionResult(NamedTuple):
    """Per-frame outputs of :func:`perceive_frames`.

    Attributes
    ----------
    counts : (T, n) int64
        ``count((Z_a - Z_env)_ij <= 0)`` per frame and artefact.
    perceived : (T, n) bool
        ``counts > tau``: membership of each artefact in A_f, per frame.
    depth_env : (T, height, width) float32 or None
        ``Z_env`` of eq. 2 over the full frame (``return_depth=True``), +inf where nothing
        is hit within ``d_max``.
    depth : (T, height, width) float32 or None
        The augmented depth image ``min(Z_env, min_a Z_a)`` (``return_depth=True``).
    """

    counts: np.ndarray
    perceived: np.ndarray
    depth_env: np.ndarray | None
    depth: np.ndarray | None


# ---------------------------------------------------------------------- validation


def _det3(m: np.ndarray) -> np.ndarray:
    """Determinants of (..., 3, 3) matrices by cofactors.

    ``np.linalg.det`` would go through LAPACK, whose OpenBLAS threads then spin for a while
    and take the cores from the Warp launches that follow.
    """
    return (
        m[..., 0, 0] * (m[..., 1, 1] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 1])
        - m[..., 0, 1] * (m[..., 1, 0] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 0])
        + m[..., 0, 2] * (m[..., 1, 0] * m[..., 2, 1] - m[..., 1, 1] * m[..., 2, 0])
    )


def _check_boxes(centers: npt.ArrayLike, half_extents: npt.ArrayLike, rotations: npt.ArrayLike):
    """Checked boxes: ``(n, 3)`` centres and ``(n, 3, 3)`` rotations, or per-frame
    ``(T, n, 3)`` and ``(T, n, 3, 3)`` for boxes that move; ``(n, 3)`` half extents."""
    c = check_finite("centers", centers)
    if c.ndim not in (2, 3) or c.shape[-1] != 3:
        raise ValueError(f"centers: expected shape (n, 3) or (T, n, 3), got {c.shape}")
    n = c.shape[-2]
    h = check_nonnegative("half_extents", half_extents)
    if h.shape != (n, 3):
        raise ValueError(f"half_extents: expected shape ({n}, 3) like centers, got {h.shape}")
    r = check_finite("rotations", rotations)
    if r.shape != (*c.shape[:-1], 3, 3):
        raise ValueError(
            f"rotations: expected shape {(*c.shape[:-1], 3, 3)} like centers, got {r.shape}"
        )
    if r.size:
        flat = r.reshape(-1, 3, 3)
        err = np.abs(np.einsum("nji,njk->nik", flat, flat) - np.eye(3)).max(axis=(1, 2))
        det = _det3(flat)
        bad = (err > 1e-5) | (det < 0)
        if bad.any():
            i = int(np.argmax(bad))
            at = f"row {i}" if r.ndim == 3 else f"frame {i // n}, box {i % n}"
            raise ValueError(
                f"rotations: expected orthonormal right-handed box-to-world "
                f"rotations, got {at} with max |R^T R - I| = {err[i]:.3g}, det = {det[i]:.3g}"
            )
    return c, h, r


def _check_camera(camera: CameraModel):
    """(fx, fy, cx, cy, width, height) from any object with K, width, height (and pose)."""
    for attr in ("K", "width", "height"):
        if not hasattr(camera, attr):
            raise ValueError(
                f"camera: expected an object with K, width, height and pose, lacks {attr!r}"
            )
    k = check_finite("camera.K", camera.K)
    if k.shape != (3, 3):
        raise ValueError(f"camera.K: expected a (3, 3) intrinsic matrix, got shape {k.shape}")
    w, h = camera.width, camera.height
    for name, v in (("camera.width", w), ("camera.height", h)):
        if isinstance(v, bool) or not float(v).is_integer() or v <= 0:
            raise ValueError(f"{name}: expected a positive integer number of pixels, got {v!r}")
    w, h = int(w), int(h)
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    if fx <= 0 or fy <= 0:
        raise ValueError(f"camera.K: expected focal lengths > 0, got fx={fx!r}, fy={fy!r}")
    if abs(k[0, 1]) > 0 or k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise ValueError(f"camera.K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], got {k}")
    if not (0 <= cx <= w and 0 <= cy <= h):
        raise ValueError(
            f"camera.K: expected the principal point inside the {w}x{h} image, "
            f"got cx={cx!r}, cy={cy!r}"
        )
    return float(fx), float(fy), float(cx), float(cy), w, h


def _check_poses(name: str, poses: npt.ArrayLike) -> np.ndarray:
    p = check_finite(name, poses)
    if p.ndim == 2:
        p = p[None]
    if p.ndim != 3 or p.shape[1:] != (4, 4):
        raise ValueError(f"{name}: expected (T, 4, 4) camera-to-world transforms, got {p.shape}")
    r = p[:, :3, :3]
    err = np.abs(np.einsum("tji,tjk->tik", r, r) - np.eye(3)).max(axis=(1, 2))
    bad = (err > 1e-5) | (_det3(r) < 0) | (np.abs(p[:, 3] - [0, 0, 0, 1]).max(1) > 1e-9)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{name}: expected rigid transforms (orthonormal rotation, last row [0, 0, 0, 1]), "
            f"got pose {i} with max |R^T R - I| = {err[i]:.3g}"
        )
    return p


def _check_scalar(name: str, x: float, positive: bool) -> float:
    v = float(check_finite(name, x, ndim=0))
    if (positive and v <= 0) or v < 0:
        what = "> 0" if positive else ">= 0"
        raise ValueError(f"{name}: expected a finite number {what}, got {v!r}")
    return v


# ---------------------------------------------------------------------- environment BVH

_MESH_CACHE: dict[tuple[int, str], dict] = {}


def clear_mesh_cache() -> None:
    """Forget every cached Warp BVH (they are otherwise kept while their mesh lives)."""
    _MESH_CACHE.clear()


def _warp_mesh(env_mesh: trimesh.Trimesh | None, device: str) -> int:
    """Warp mesh id of ``env_mesh`` (0 for an empty mesh), built once and refitted on change.

    The BVH is cached per (mesh object, device). It is rebuilt when the faces change and
    refitted in place when only the vertex positions change (trimesh tracks both).
    """
    if env_mesh is None:
        return 0
    if not (hasattr(env_mesh, "vertices") and hasattr(env_mesh, "faces")):
        raise ValueError(f"env_mesh: expected a trimesh.Trimesh, got {type(env_mesh).__name__}")
    faces = env_mesh.faces
    if len(faces) == 0:
        return 0
    key = (id(env_mesh), str(device))
    fh, vh = hash(faces), hash(env_mesh.vertices)
    entry = _MESH_CACHE.get(key)
    if entry is not None and entry["ref"]() is env_mesh and entry["faces"] == fh:
        if entry["verts"] != vh:
            v = np.ascontiguousarray(env_mesh.vertices, dtype=np.float32)
            if not np.isfinite(v).all():
                raise ValueError("env_mesh: expected finite vertex coordinates")
            entry["points"].assign(wp.array(v, dtype=wp.vec3, device=device))
            entry["mesh"].refit()
            entry["tree"] = build_frustum_bvh(v, entry["faces_i32"], device)
            entry["verts"] = vh
        return entry["mesh"].id
    v = np.ascontiguousarray(env_mesh.vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    if not np.isfinite(v).all():
        raise ValueError("env_mesh: expected finite vertex coordinates")
    if f.ndim != 2 or f.shape[1] != 3 or f.min() < 0 or f.max() >= len(v):
        raise ValueError("env_mesh: expected triangle faces indexing its vertices")
    points = wp.array(v, dtype=wp.vec3, device=device)
    mesh = wp.Mesh(points=points, indices=wp.array(f.ravel(), dtype=wp.int32, device=device))
    entry = {
        "ref": weakref.ref(env_mesh),
        "faces": fh,
        "verts": vh,
        "points": points,
        "mesh": mesh,
        "faces_i32": f,
        "tree": build_frustum_bvh(v, f, device),
    }
    _MESH_CACHE[key] = entry
    weakref.finalize(env_mesh, _MESH_CACHE.pop, key, None)
    return mesh.id


def _mesh_and_tree(env_mesh: trimesh.Trimesh | None, device: str) -> tuple[int, FrustumBVH | None]:
    """:func:`_warp_mesh` and the mesh's frustum-gathering tree (None for an empty mesh)."""
    mesh_id = _warp_mesh(env_mesh, device)
    if mesh_id == 0:
        return 0, None
    return mesh_id, _MESH_CACHE[(id(env_mesh), str(device))]["tree"]


# ---------------------------------------------------------------------- ROI culling

_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
_EDGES = np.array(
    [(i, j) for i in range(8) for j in range(i + 1, 8) if np.abs(_SIGNS[i] - _SIGNS[j]).sum() == 2]
)


def box_rois(
    centers: np.ndarray,
    half_extents: np.ndarray,
    rotations: np.ndarray,
    intrinsics: tuple[float, float, float, float, int, int],
    poses: np.ndarray,
    d_max: float,
) -> np.ndarray:
    """Conservative pixel rectangles of every box in every frame (ROI culling).

    A pixel's ray can only meet box a within ``[0, d_max]`` at a point whose optical depth
    lies in ``[z_near, d_max]``, where ``z_near`` is the box's distance from the camera
    centre times the smallest z-component of an in-image unit ray. The box is clipped to
    that slab (its corners inside plus the 12 edges cut by the two planes) and the clipped
    polytope is projected: the bounding rectangle of the projected vertices, widened by one
    pixel, contains every pixel whose ray can hit the box. A camera inside (or on) a box
    gets the whole image; a box farther than ``d_max`` gets nothing.

    Parameters
    ----------
    centers : (n, 3) float64, or (T, n, 3) for boxes that move (one pose per frame)
    half_extents : (n, 3) float64
    rotations : (n, 3, 3) float64, or (T, n, 3, 3)
        Box-to-world rotations.
    intrinsics : tuple
        ``(fx, fy, cx, cy, width, height)``.
    poses : (T, 4, 4) float64
        Camera-to-world transforms of the optical frame.
    d_max : float

    Returns
    -------
    (T, n, 4) int64
        ``x0, y0, w, h`` per frame and box; ``w == 0`` or ``h == 0`` when culled.
    """
    fx, fy, cx, cy, width, height = intrinsics
    moving = centers.ndim == 3
    t_frames, n = poses.shape[0], centers.shape[-2]
    out = np.zeros((t_frames, n, 4), dtype=np.int64)
    if n == 0 or t_frames == 0:
        return out
    cam_c = poses[:, :3, 3]
    cam_r = poses[:, :3, :3]
    # cheap cull first: a box whose circumscribed sphere lies beyond d_max or wholly behind
    # the image plane gets nothing (the exact test below would give it w = h = 0)
    c_all = centers if moving else np.broadcast_to(centers[None], (t_frames, n, 3))
    rel = c_all - cam_c[:, None, :]  # (T, n, 3)
    reach = np.linalg.norm(half_extents, axis=-1)[None] * (1.0 + 1e-9) + 1e-9
    depth = np.einsum("tji,tnj->tn", cam_r[..., 2:3], rel)  # optical z of the centres
    keep = (np.linalg.norm(rel, axis=-1) - reach <= d_max) & (depth + reach >= 0.0)
    ft, fb = np.nonzero(keep)
    if not ft.size:
        return out
    rot = rotations[ft, fb] if moving else rotations[fb]
    out[ft, fb] = _pair_rois(
        c_all[ft, fb], half_extents[fb], rot, cam_c[ft], cam_r[ft], intrinsics, d_max
    )
    return out


def _pair_rois(
    centers: np.ndarray,
    half_extents: np.ndarray,
    rotations: np.ndarray,
    cam_c: np.ndarray,
    cam_r: np.ndarray,
    intrinsics: tuple[float, float, float, float, int, int],
    d_max: float,
) -> np.ndarray:
    """:func:`box_rois` of (m,) (box, camera) pairs: centres (m, 3), half extents (m, 3),
    rotations (m, 3, 3), camera centres (m, 3) and optical-to-world rotations (m, 3, 3);
    returns (m, 4) ``x0, y0, w, h``."""
    fx, fy, cx, cy, width, height = intrinsics
    # (m, 8, 3) corners and (m, 3) camera centres in the box frames
    corners = centers[:, None, :] + np.einsum(
        "mij,mkj->mki", rotations, _SIGNS[None] * half_extents[:, None, :]
    )
    q = np.einsum("mji,mj->mi", rotations, cam_c - centers)
    dist = np.linalg.norm(np.maximum(np.abs(q) - half_extents, 0.0), axis=-1)
    img = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
    dz = 1.0 / np.linalg.norm(
        np.column_stack([(img[:, 0] - cx) / fx, (img[:, 1] - cy) / fy, np.ones(4)]), axis=1
    )
    z_near = np.maximum(dist * dz.min() * (1.0 - 1e-9), 1e-12)  # (m,)
    # corners in the optical frame: (m, 8, 3)
    pc = np.einsum("mji,mkj->mki", cam_r, corners - cam_c[:, None, :])
    z = pc[..., 2]
    cand = [pc]
    valid = [(z >= z_near[:, None]) & (z <= d_max)]
    a, b = pc[:, _EDGES[:, 0]], pc[:, _EDGES[:, 1]]  # (m, 12, 3)
    za, zb = a[..., 2], b[..., 2]
    for plane in (z_near[:, None], np.full_like(za, d_max)):
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (plane - za) / (zb - za)
        ok = np.isfinite(s) & (s >= 0) & (s <= 1)
        s = np.where(ok, s, 0.0)
        p = a + s[..., None] * (b - a)
        p[..., 2] = np.where(ok, plane, p[..., 2])
        cand.append(p)
        valid.append(ok)
    pts = np.concatenate(cand, axis=1)
    ok = np.concatenate(valid, axis=1)
    zz = np.where(ok, pts[..., 2], 1.0)
    big = 4.0 * (width + height) + 8.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        u = np.clip(fx * pts[..., 0] / zz + cx, -big, big)
        v = np.clip(fy * pts[..., 1] / zz + cy, -big, big)
    any_ok = ok.any(axis=1)
    umin = np.where(ok, u, np.inf).min(axis=1)
    umax = np.where(ok, u, -np.inf).max(axis=1)
    vmin = np.where(ok, v, np.inf).min(axis=1)
    vmax = np.where(ok, v, -np.inf).max(axis=1)
    x0 = np.floor(np.where(any_ok, umin, 0.0)) - 1
    x1 = np.ceil(np.where(any_ok, umax, -1.0)) + 1
    y0 = np.floor(np.where(any_ok, vmin, 0.0)) - 1
    y1 = np.ceil(np.where(any_ok, vmax, -1.0)) + 1
    x0, y0 = np.clip(x0, 0, width), np.clip(y0, 0, height)
    x1, y1 = np.clip(x1, 0, width), np.clip(y1, 0, height)  # exclusive ends
    w = np.where(any_ok, np.maximum(x1 - x0, 0), 0)
    h = np.where(any_ok, np.maximum(y1 - y0, 0), 0)
    inside = dist <= 1e-9
    far = dist > d_max
    x0 = np.where(inside, 0, x0)
    y0 = np.where(inside, 0, y0)
    w = np.where(inside, width, np.where(far, 0, w))
    h = np.where(inside, height, np.where(far, 0, h))
    return np.stack([x0, y0, w, h], axis=-1).astype(np.int64)


# ---------------------------------------------------------------------- driver


def _default_threads() -> int:
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        n = os.cpu_count() or 1
    return max(1, min(n, 8))


_BLOCK = 8  # pixel block side of the environment-ray kernel (and its culling)


def _run(
    mesh_id: int,
    tree: FrustumBVH | None,
    centers: np.ndarray,
    half: np.ndarray,
    rots: np.ndarray,
    intr: tuple,
    poses: np.ndarray,
    d_max: float,
    active: np.ndarray,
    occlusion: bool,
    return_depth: bool,
    device: str,
    threads: int,
):
    fx, fy, cx, cy, width, height = intr
    npix = width * height
    t_frames, n = poses.shape[0], centers.shape[-2]
    counts = np.zeros((t_frames, n), dtype=np.int64)
    depth_env = np.full((t_frames, height, width), np.inf, np.float32) if return_depth else None
    depth = np.full((t_frames, height, width), np.inf, np.float32) if return_depth else None
    if t_frames == 0 or (n == 0 and not return_depth):
        return counts, depth_env, depth
    rois = box_rois(centers, half, rots, intr, poses, d_max)
    rois[~active] = 0
    items = rois[..., 2] * rois[..., 3]  # (T, n)
    per_frame = items.sum(axis=1)
    view = kern.make_view(fx, fy, cx, cy, width, height)
    use_min = 1 if occlusion else 0
    # group frames so that items and per-frame buffers stay bounded
    groups, start, acc = [], 0, 0
    for t in range(t_frames):
        if t > start and (
            acc + per_frame[t] > _ITEMS_PER_CHUNK or (t - start + 1) * npix > _PIXELS_PER_CHUNK
        ):
            groups.append((start, t))
            start, acc = t, 0
        acc += int(per_frame[t])
    groups.append((start, t_frames))
    for g0, g1 in groups:
        tc = g1 - g0
        sel = items[g0:g1] > 0
        fr, bx = np.nonzero(sel)
        rect = rois[g0:g1][fr, bx]
        n_items_seg = items[g0:g1][fr, bx]
        offsets = np.zeros(len(fr) + 1, np.int64)
        np.cumsum(n_items_seg, out=offsets[1:])
        n_items = int(offsets[-1])
        cams = {
            "pos": wp.array(poses[g0:g1, :3, 3].astype(np.float32), dtype=wp.vec3, device=device),
            "rot": wp.array(poses[g0:g1, :3, :3].astype(np.float32), dtype=wp.mat33, device=device),
        }
        item_bounds = kern.split_bounds(n_items, device, threads)
        n_buf = len(item_bounds)
        # Z_a per item; largest and smallest finite Z_a per pixel
        out = kern.make_depths(n_items, tc * npix, device)
        # per segment: camera centre in the box frame, optical-to-box rotation, half extents
        cam_c, cam_r = poses[g0:g1, :3, 3][fr], poses[g0:g1, :3, :3][fr]
        if centers.ndim == 3:  # boxes that move: their pose in the segment's frame
            box_c, box_r = centers[g0 + fr, bx], rots[g0 + fr, bx]
        else:
            box_c, box_r = centers[bx], rots[bx]
        seg_origin = np.einsum("sji,sj->si", box_r, cam_c - box_c)
        seg_rot = np.einsum("sji,sjk->sik", box_r, cam_r)
        # the rows of every rectangle: (segment, row within the rectangle)
        h_seg = rect[:, 3]
        row_seg = np.repeat(np.arange(len(fr), dtype=np.int32), h_seg)
        row_y = (np.arange(row_seg.shape[0]) - np.repeat(np.cumsum(h_seg) - h_seg, h_seg)).astype(
            np.int32
        )
        # rows in image-row order (frame, y): host threads then take chunks of whole
        # image rows and never write the same pixel (kern.launch_pair_depths)
        row_key = fr[row_seg] * np.int64(height) + rect[row_seg, 1] + row_y
        order = np.argsort(row_key, kind="stable")
        row_seg, row_y, row_key = row_seg[order], row_y[order], row_key[order]
        seg = {
            "segments": kern.make_segments(offsets, fr, rect[:, :3], row_seg, row_y, device),
            "boxes": kern.make_boxes(seg_origin, seg_rot, half[bx], device),
            "box": wp.array(bx.astype(np.int32), dtype=wp.int32, device=device),
            "n_items": n_items,
            "n_rows": int(row_seg.shape[0]),
            "row_key": row_key,
            "row_work": rect[row_seg, 2],
        }
        if n_items:
            kern.launch_pair_depths(seg, view, d_max, out, item_bounds, device)
        # environment rays: every pixel for a depth image, else only under a finite Z_a
        z_env = wp.empty(tc * npix, dtype=wp.float32, device=device)
        status = wp.empty(
            tc * (-(-width // _BLOCK)) * (-(-height // _BLOCK)), dtype=wp.int32, device=device
        )
        kern.launch_env_blocks(
            mesh_id,
            tree,
            cams,
            view,
            _BLOCK,
            tc,
            1 if return_depth else 0,
            # Warp accepts hits with t < max_t; eq. 2 keeps t == d_max
            np.nextafter(np.float32(d_max), np.float32(np.inf)),
            0 if return_depth else 1,
            out,
            z_env,
            status,
            device,
            threads,
        )
        if n_items:
            cnt = [wp.zeros(tc * max(n, 1), dtype=wp.int32, device=device) for _ in range(n_buf)]
            kern.launch_pair_counts(seg, view, n, use_min, out, z_env, cnt, item_bounds, device)
            total = sum(c.numpy().astype(np.int64) for c in cnt)
            counts[g0:g1] = total[: tc * n].reshape(tc, n)
        if return_depth:
            ze = z_env.numpy().reshape(tc, height, width)
            depth_env[g0:g1] = ze
            depth[g0:g1] = np.minimum(ze, out.z_min.numpy().reshape(tc, height, width))
    return counts, depth_env, depth


def perceive_frames(
    env_mesh: trimesh.Trimesh | None,
    centers: npt.ArrayLike,
    half_extents: npt.ArrayLike,
    rotations: npt.ArrayLike,
    camera: CameraModel,
    poses: npt.ArrayLike | None,
    d_max: float,
    tau: float,
    *,
    active: npt.ArrayLike | None = None,
    occlusion_between_artefacts: bool = False,
    return_depth: bool = False,
    device: str = "cpu",
    threads: int | None = None,
) -> PerceptionResult:
    """Occlusion counts and the perceived set A_f for many camera poses in one go.

    Implements eq. 2 and ``A_f = {a | count((Z_a - Z_S3D)_ij <= 0) > tau}`` of paper
    section 3.3 with the conventions of DECISIONS 8, batched over a robot trajectory.

    Parameters
    ----------
    env_mesh : trimesh.Trimesh or None
        Environment mesh S_3D (world frame). An empty mesh (or None) hides nothing. Its
        BVH is built once and reused across calls; it is refitted when the vertices change.
    centers : (n, 3) float, or (T, n, 3)
        Box centres (world frame); per frame for boxes that move (see
        :func:`~are_stats.perception.perceive_scene`, which takes them from a Scene).
    half_extents : (n, 3) float
        Box half extents along the box axes (>= 0).
    rotations : (n, 3, 3) float, or (T, n, 3, 3)
        Box-to-world rotations (orthonormal, det +1), per frame when ``centers`` is.
    camera : PinholeCamera or object with ``K``, ``width``, ``height`` and ``pose``
        Intrinsics; its ``pose`` is used when ``poses`` is None.
    poses : (T, 4, 4) float or None
        Camera-to-world transforms of the optical frame, one per frame.
    d_max : float
        Maximum ray length (> 0).
    tau : float
        Partial-occlusion threshold (>= 0): perceived iff count > tau.
    active : (T, n) bool, optional
        Which artefacts exist in each frame (default: all).
    occlusion_between_artefacts : bool
        Beyond the paper: a pixel counts for a only if no other box is nearer
        (ties count for both).
    return_depth : bool
        Also return the full-frame ``Z_env`` and the augmented depth image.
    device : str
        Warp device, ``"cpu"`` or ``"cuda"``.
    threads : int, optional
        Host threads for CPU launches (default: the CPUs this process may use, at most 8).

    Returns
    -------
    PerceptionResult
        ``counts (T, n)``, ``perceived (T, n)``, and the depth images when asked.

    Raises
    ------
    ValueError
        On malformed boxes (shapes, negative extents, non-orthonormal rotations), a camera
        whose intrinsics do not fit its image, bad poses, ``d_max <= 0`` or ``tau < 0``.
    """
    c, h, r = _check_boxes(centers, half_extents, rotations)
    intr = _check_camera(camera)
    if poses is None:
        if not hasattr(camera, "pose"):
            raise ValueError("camera: expected a pose attribute (or pass poses)")
        poses = camera.pose
        name = "camera.pose"
    else:
        name = "poses"
    p = _check_poses(name, poses)
    d_max = _check_scalar("d_max", d_max, positive=True)
    tau = _check_scalar("tau", tau, positive=False)
    t_frames, n = p.shape[0], c.shape[-2]
    if c.ndim == 3 and c.shape[0] != t_frames:
        raise ValueError(
            f"centers: expected one box pose per frame, (T={t_frames}, n, 3), got {c.shape}"
        )
    if active is None:
        act = np.ones((t_frames, n), dtype=bool)
    else:
        act = np.asarray(active)
        if act.dtype != bool or act.shape != (t_frames, n):
            raise ValueError(
                f"active: expected a ({t_frames}, {n}) boolean array, got {describe(active)}"
            )
    if threads is None:
        threads = _default_threads()
    elif isinstance(threads, bool) or not float(threads).is_integer() or threads < 1:
        raise ValueError(f"threads: expected a positive integer, got {threads!r}")
    mesh_id, tree = _mesh_and_tree(env_mesh, device)
    counts, depth_env, depth = _run(
        mesh_id,
        tree,
        c,
        h,
        r,
        intr,
        p,
        d_max,
        act,
        bool(occlusion_between_artefacts),
        bool(return_depth),
        device,
        int(threads),
    )
    return PerceptionResult(counts, counts > tau, depth_env, depth)


def perceived_counts_batch(
    env_mesh: trimesh.Trimesh | None,
    centers: npt.ArrayLike,
    half_extents: npt.ArrayLike,
    rotations: npt.ArrayLike,
    camera: CameraModel,
    poses: npt.ArrayLike,
    d_max: float,
    tau: float,
    *,
    active: npt.ArrayLike | None = None,
    **options: Unpack[TraceOptions],
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`perceived_counts` over a trajectory of camera poses (T, 4, 4).

    The boxes stand still (``centers (n, 3)``, ``rotations (n, 3, 3)``) or move, one pose
    per frame (``centers (T, n, 3)``, ``rotations (T, n, 3, 3)``); ``active (T, n)`` says
    which exist in each frame; ``options`` are :class:`TraceOptions`. The boxes of a
    :class:`~are_stats.Scene` along a robot path are perceived by
    :func:`~are_stats.perception.perceive_scene`.

    Returns
    -------
    counts : (T, n) int64
    perceived : (T, n) bool
        ``counts > tau``.

    Examples
    --------
    >>> import numpy as np, trimesh
    >>> from are_stats.perception import PinholeCamera
    >>> cam = PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48)
    >>> poses = np.stack([np.eye(4)] * 3)
    >>> counts, seen = perceived_counts_batch(
    ...     trimesh.Trimesh(), [[0.0, 0.0, 5.0]], [[0.5, 0.5, 0.5]], [np.eye(3)],
    ...     cam, poses, d_max=10.0, tau=10)
    >>> counts.shape, bool(seen.all())
    ((3, 1), True)
    """
    res = perceive_frames(
        env_mesh,
        centers,
        half_extents,
        rotations,
        camera,
        poses,
        d_max,
        tau,
        active=active,
        **options,
    )
    return res.counts, res.perceived


def perceived_counts(
    env_mesh: trimesh.Trimesh | None,
    centers: npt.ArrayLike,
    half_extents: npt.ArrayLike,
    rotations: npt.ArrayLike,
    camera: CameraModel,
    d_max: float,
    tau: float,
    **options: Unpack[TraceOptions],
) -> tuple[np.ndarray, np.ndarray]:
    """Per-artefact pixel counts and the perceived set A_f for one frame (section 3.3).

    ``counts[a] = count((Z_a - Z_env)_ij <= 0)`` over the pixels where ``Z_a`` is finite,
    with ``Z_env`` of eq. 2 and ``Z_a`` the first root ``max(t_near, 0)`` of the pixel's ray
    with the oriented box a within ``[0, d_max]``; ``a`` is perceived iff ``counts[a] > tau``.

    Parameters
    ----------
    env_mesh : trimesh.Trimesh
        Environment mesh S_3D in the world frame (may be empty).
    centers : (n, 3) float
        Box centres.
    half_extents : (n, 3) float
        Box half extents (>= 0).
    rotations : (n, 3, 3) float
        Box-to-world rotations.
    camera : PinholeCamera or object with ``K``, ``width``, ``height``, ``pose``
        ``pose`` is the camera-to-world transform (4, 4) of the optical frame.
    d_max : float
        Maximum ray length (> 0).
    tau : float
        Threshold for partial occlusions (>= 0).
    **options
        :class:`TraceOptions`: ``occlusion_between_artefacts`` (beyond the paper: nearer
        boxes hide farther ones), ``device``, ``threads``.

    Returns
    -------
    counts : (n,) int64
    perceived : (n,) bool

    Raises
    ------
    ValueError
        On malformed input (see :func:`perceive_frames`).

    Examples
    --------
    >>> import numpy as np, trimesh
    >>> from are_stats.perception import PinholeCamera
    >>> cam = PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48)
    >>> wall = trimesh.creation.box([4.0, 4.0, 0.1])
    >>> _ = wall.apply_translation([0.0, 0.0, 3.0])
    >>> counts, seen = perceived_counts(
    ...     wall, [[0.0, 0.0, 5.0], [0.0, 0.0, 1.0]], [[0.5] * 3] * 2, [np.eye(3)] * 2,
    ...     cam, d_max=10.0, tau=0)
    >>> seen.tolist()
    [False, True]
    """
    res = perceive_frames(
        env_mesh, centers, half_extents, rotations, camera, None, d_max, tau, **options
    )
    return res.counts[0], res.perceived[0]


def sample_perceived(
    key: jax.Array,
    perceived: npt.ArrayLike,
    detection_prob: npt.ArrayLike = 1.0,
    existence_prob: npt.ArrayLike = 1.0,
) -> np.ndarray:
    """A sampled perceived set: detection and existence uncertainty (beyond the paper).

    The paper's conclusion tunes "a degree of certainty" of the artefacts' existence. An
    artefact in A_f is reported in frame t when it exists (one Bernoulli(existence_prob)
    draw per artefact, shared by all frames) and is detected in that frame (an independent
    Bernoulli(detection_prob) draw per frame, e.g. a per-class detector recall).

    Parameters
    ----------
    key : jax.random.PRNGKey
        Random key (seeded, reproducible).
    perceived : (T, n) or (n,) bool
        The deterministic perceived sets.
    detection_prob : float or (n,) float
        Per-artefact detection probability in [0, 1].
    existence_prob : float or (n,) float
        Per-artefact existence confidence in [0, 1].

    Returns
    -------
    (T, n) or (n,) bool
        ``perceived & exists & detected``.
    """
    per = np.asarray(perceived)
    if per.dtype != bool or per.ndim not in (1, 2):
        raise ValueError(f"perceived: expected a (T, n) or (n,) bool array, got {describe(per)}")
    per2 = per[None] if per.ndim == 1 else per
    n = per2.shape[1]
    pd = np.broadcast_to(check_probability("detection_prob", detection_prob), (n,)) if n else []
    pe = np.broadcast_to(check_probability("existence_prob", existence_prob), (n,)) if n else []
    k_exist, k_detect = jax.random.split(key)
    exists = np.asarray(jax.random.uniform(k_exist, (n,))) < np.asarray(pe)
    detected = np.asarray(jax.random.uniform(k_detect, per2.shape)) < np.asarray(pd)
    out = per2 & exists[None] & detected
    return out[0] if per.ndim == 1 else out
