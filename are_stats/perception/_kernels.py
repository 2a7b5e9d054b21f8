"""NVIDIA Warp kernels for the occlusion test of paper section 3.3 (eq. 2 and A_f).

Kernels live at module level with typed arguments; the host functions below are thin
launchers that take ``device=`` (``"cpu"`` by default, ``"cuda"`` where present) and a
``base`` offset so that a CPU launch can be split across host threads (a Warp CPU launch
runs on one thread and releases the GIL, so two threads use two cores). Warp's CPU atomics
are plain read-modify-writes, so each host thread scatters into its own buffers.

Work items
----------
The pixels an artefact can cover are enumerated as *segments*: one segment per
(frame, artefact) pair, holding the artefact's projected pixel rectangle
``[x0, x0 + w) x [y0, y0 + h)``. Item ``i`` of a pair launch belongs to the segment ``s``
with ``offsets[s] <= i < offsets[s + 1]`` (binary search), and to pixel
``(x0 + k % w, y0 + k // w)`` with ``k = i - offsets[s]``. CPU launches take one
rectangle row per work item instead (``row_seg``, ``row_y``): its items are consecutive.
"""

from __future__ import annotations

import itertools
import os
import sys
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import warp as wp

from are_stats.perception._frustum_bvh import BRANCH, LEAF, FrustumBVH

__all__ = [
    "Depths",
    "Segments",
    "View",
    "block_stride",
    "launch_dynamic",
    "launch_env_blocks",
    "launch_pair_counts",
    "launch_pair_depths",
    "launch_split",
    "make_boxes",
    "make_depths",
    "make_segments",
    "make_view",
    "split_bounds",
]

# Warp's greeting on first use would clutter every CLI run and test log.
if wp.config.log_level <= wp.LOG_INFO:
    wp.config.log_level = wp.LOG_WARNING

#: What Warp's native start-up writes to stderr on every machine without an NVIDIA driver.
CUDA_PROBE_WARNING = "Could not find or load the NVIDIA CUDA driver"


def init_warp() -> None:
    """``wp.init()`` without the CUDA probe's warning on a CPU-only machine.

    Warp's native library prints ``Warp CUDA warning: Could not find or load the NVIDIA
    CUDA driver`` straight to file descriptor 2 (not through Python's warnings) whenever
    ``libcuda`` is absent: noise on every CPU run, which is what this package runs on. The
    descriptor is captured while Warp starts and everything else it wrote is passed on.
    Idempotent and cheap (about 60 ms once).
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable stderr: nothing to keep clean
        wp.init()
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode(errors="replace")
    kept = [line for line in text.splitlines(True) if CUDA_PROBE_WARNING not in line]
    if kept:
        sys.stderr.write("".join(kept))


init_warp()

# No gradients are taken through these kernels; skipping the adjoint code halves the
# first-use compile time.
wp.set_module_options({"enable_backward": False})

_INF = wp.constant(wp.float32(np.inf))


@wp.struct
class View:
    """The layout of a launch's frames (``npix = width height``) and the camera intrinsics."""

    width: int
    height: int
    npix: int
    fx: float
    fy: float
    cx: float
    cy: float


@wp.struct
class Segments:
    """A pair launch's segments (see the module docstring): ``offsets`` (n + 1,) the first
    item of each segment then the item count, ``frame`` (n,), ``rect`` (n,) ``(x0, y0, w)``,
    the rectangle rows of CPU launches ``row_seg``, ``row_y`` (R,), and ``n``."""

    offsets: wp.array(dtype=wp.int64)
    frame: wp.array(dtype=wp.int32)
    rect: wp.array(dtype=wp.vec3i)
    row_seg: wp.array(dtype=wp.int32)
    row_y: wp.array(dtype=wp.int32)
    n: int


@wp.struct
class Depths:
    """The box depths of a pair launch (:func:`make_depths`): Z_a per pair item
    (``pair_z``) and, per pixel of the launch's frames, the largest finite Z_a (``z_max``,
    -1 where no box covers it) and the smallest (``z_min``, +inf)."""

    pair_z: wp.array(dtype=wp.float32)
    z_max: wp.array(dtype=wp.float32)
    z_min: wp.array(dtype=wp.float32)


@wp.func
def _pixel_ray_cam(px: int, py: int, view: View) -> wp.vec3:
    """Optical-frame direction (not normalised, z = 1) through the centre of pixel (px, py)."""
    return wp.vec3(
        (wp.float32(px) + 0.5 - view.cx) / view.fx, (wp.float32(py) + 0.5 - view.cy) / view.fy, 1.0
    )


@wp.func
def _pixel_dir_cam(px: int, py: int, view: View) -> wp.vec3:
    """Unit optical-frame direction of the ray through the centre of pixel (px, py)."""
    return wp.normalize(_pixel_ray_cam(px, py, view))


@wp.func
def _block_uv(view: View, blk: wp.vec4i) -> wp.vec4:
    """``(u0, u1, v0, v1)``: optical-frame x / z of the first and last pixel-centre columns
    of the block ``blk = (x0, x1, y0, y1)`` (pixels ``[x0, x1) x [y0, y1)``), and y / z of
    its first and last rows."""
    return wp.vec4(
        (wp.float32(blk[0]) + 0.5 - view.cx) / view.fx,
        (wp.float32(blk[1]) - 0.5 - view.cx) / view.fx,
        (wp.float32(blk[2]) + 0.5 - view.cy) / view.fy,
        (wp.float32(blk[3]) - 0.5 - view.cy) / view.fy,
    )


@wp.func
def _block_pad(c: wp.vec3, top: float) -> float:
    """A margin far above the float32 rounding of points near ``c`` up to depth ``top``."""
    scale = wp.max(wp.max(wp.abs(c[0]), wp.abs(c[1])), wp.abs(c[2])) + top
    return 1.0e-3 + 1.0e-4 * scale


@wp.func
def _slab_axis(o: float, d: float, h: float, span: wp.vec2) -> wp.vec2:
    """Intersect the parameter interval ``span`` with one slab ``-h <= o + t d <= h``."""
    if wp.abs(d) < 1.0e-30:
        if o < -h or o > h:
            return wp.vec2(1.0, -1.0)  # empty for good
        return span
    inv = 1.0 / d
    t1 = (-h - o) * inv
    t2 = (h - o) * inv
    return wp.vec2(wp.max(span[0], wp.min(t1, t2)), wp.min(span[1], wp.max(t1, t2)))


@wp.func
def _slab(o: wp.vec3, d: wp.vec3, h: wp.vec3, d_max: float) -> float:
    """First root of a ray with the box [-h, h] (box frame), as a distance; inf if none.

    ``d`` need not be a unit vector: the slab parameters are in units of ``|d|`` and the
    root ``max(t_near, 0)`` is scaled by ``|d|`` only for a hit (one square root per hit
    instead of a normalisation per ray).
    """
    span = wp.vec2(-_INF, _INF)
    span = _slab_axis(o[0], d[0], h[0], span)
    span = _slab_axis(o[1], d[1], h[1], span)
    span = _slab_axis(o[2], d[2], h[2], span)
    result = float(_INF)
    if span[0] <= span[1] and span[1] >= 0.0:
        t = wp.max(span[0], 0.0) * wp.length(d)
        if t <= d_max:
            result = t
    return result


@wp.func
def _counts_for(z: float, z_env: float, z_min: float, use_min: int) -> int:
    """1 when the box depth ``z`` of a pixel counts towards its artefact (A_f), else 0.

    The pixel counts when ``Z_a <= Z_env`` and, with ``use_min == 1`` (artefacts occluding
    each other), when no other box of the pixel is nearer (ties count for both).
    """
    ok = z <= z_env
    if use_min == 1:
        ok = ok and z <= z_min
    if ok:
        return 1
    return 0


@wp.func
def _find_segment(offsets: wp.array(dtype=wp.int64), n_seg: int, i: wp.int64) -> int:
    lo = wp.int32(0)
    hi = wp.int32(n_seg)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if offsets[mid] <= i:
            lo = mid
        else:
            hi = mid
    return lo


@wp.func
def _run_of(seg: Segments, rows: int, t: wp.int64) -> wp.vec4i:
    """``(s, x0, y, n)``: the pair items of work item ``t``, pixels ``x0 .. x0 + n - 1`` of
    image row ``y`` in segment ``s`` (consecutive items).

    With ``rows == 1`` (CPU launches) a work item is rectangle row ``t``: row
    ``seg.row_y[t]`` of segment ``seg.row_seg[t]``, walked without a per-item segment
    search. Otherwise it is the single item ``t``, found by binary search over the offsets.
    """
    if rows == 1:
        s = seg.row_seg[t]
        r = seg.rect[s]
        return wp.vec4i(s, r[0], r[1] + seg.row_y[t], r[2])
    s = _find_segment(seg.offsets, seg.n, t)
    k = int(t - seg.offsets[s])
    r = seg.rect[s]
    return wp.vec4i(s, r[0] + k % r[2], r[1] + k // r[2], 1)


@wp.func
def _first_item(seg: Segments, run: wp.vec4i) -> wp.int64:
    """The pair item of the first pixel of ``run`` (see :func:`_run_of`)."""
    r = seg.rect[run[0]]
    return seg.offsets[run[0]] + wp.int64((run[2] - r[1]) * r[2] + run[1] - r[0])


@wp.kernel
def pair_depth_kernel(
    seg: Segments,
    origin: wp.array(dtype=wp.vec3),
    rot: wp.array(dtype=wp.mat33),
    half: wp.array(dtype=wp.vec3),
    view: View,
    d_max: float,
    rows: int,
    base: wp.int64,
    out: Depths,
):
    """Z_a of every (artefact, pixel-in-rectangle) item into ``out.pair_z``; scatter its
    max and min per pixel into ``out.z_max`` and ``out.z_min``.

    ``seg`` holds the segments (:class:`Segments`). Per segment,
    ``origin`` is the camera centre in the box frame, ``rot`` the rotation from the
    optical frame to the box frame and ``half`` the box's half extents. Work item
    ``tid + base`` is a run of items (:func:`_run_of`): a rectangle row when ``rows == 1``
    (CPU launches), else one item (CUDA launches).
    """
    run = _run_of(seg, rows, wp.int64(wp.tid()) + base)
    s = run[0]
    i0 = _first_item(seg, run)
    o = origin[s]
    m = rot[s]
    h = half[s]
    g0 = seg.frame[s] * view.npix + run[2] * view.width
    for j in range(run[3]):
        px = run[1] + j
        z = _slab(o, m * _pixel_ray_cam(px, run[2], view), h, d_max)
        out.pair_z[i0 + wp.int64(j)] = z
        if z < _INF:
            wp.atomic_max(out.z_max, g0 + px, z)
            wp.atomic_min(out.z_min, g0 + px, z)


@wp.func
def _block_is_clear(
    mesh: wp.uint64, c: wp.vec3, rot: wp.mat33, blk: wp.vec4i, t_top: float, view: View
) -> bool:
    """Whether no mesh triangle can meet a ray of the pixel block ``blk`` before ``t_top``.

    Every ray segment ``{c + t d : 0 <= t < t_top}`` of the block's pixels lies in the
    pyramid with apex at the camera centre ``c`` spanned by the block's pixel-centre
    directions up to optical depth ``t_top`` (a unit ray's optical depth is at most its
    length). When no triangle's bounding box meets the pyramid's bounding box (widened
    well beyond float32 rounding), no ray query of the block can hit anything.
    """
    uv = _block_uv(view, blk)
    lo = c
    hi = c
    for k in range(4):
        u = uv[0]
        if k % 2 == 1:
            u = uv[1]
        v = uv[2]
        if k >= 2:
            v = uv[3]
        q = c + rot * wp.vec3(u * t_top, v * t_top, t_top)
        lo = wp.min(lo, q)
        hi = wp.max(hi, q)
    pad = _block_pad(c, t_top)
    padv = wp.vec3(pad, pad, pad)
    query = wp.mesh_query_aabb(mesh, lo - padv, hi + padv)
    face = wp.int32(0)
    return not wp.mesh_query_aabb_next(query, face)


@wp.func
def _tri_hit_interior(mesh: wp.uint64, face: int, o: wp.vec3, d: wp.vec3) -> float:
    """Distance along ``d`` (unit) from ``o`` to triangle ``face``, or +inf.

    Moeller-Trumbore, accepting only clear interior hits (every barycentric coordinate
    above ``1e-3``) at ``t > 0``: a ray near an edge reports +inf, so callers may use a
    finite answer as a certain hit and fall back to the BVH query otherwise.
    """
    p0 = wp.mesh_get_point(mesh, 3 * face)
    e1 = wp.mesh_get_point(mesh, 3 * face + 1) - p0
    e2 = wp.mesh_get_point(mesh, 3 * face + 2) - p0
    pv = wp.cross(d, e2)
    det = wp.dot(e1, pv)
    result = float(_INF)
    if wp.abs(det) > 1.0e-20:
        inv = 1.0 / det
        tv = o - p0
        u = wp.dot(tv, pv) * inv
        qv = wp.cross(tv, e1)
        v = wp.dot(d, qv) * inv
        eps = 1.0e-3
        if u > eps and v > eps and u + v < 1.0 - eps:
            t = wp.dot(e2, qv) * inv
            if t > 0.0:
                result = t
    return result


_LEAF = wp.constant(LEAF)
_BRANCH = wp.constant(BRANCH)


@wp.func
def _box_outside(lo: wp.vec3, hi: wp.vec3, pl: wp.vec4) -> bool:
    """Whether the box ``[lo, hi]`` lies wholly on the outer side ``n . p < off`` of ``pl``."""
    x = wp.where(pl[0] >= 0.0, hi[0], lo[0])
    y = wp.where(pl[1] >= 0.0, hi[1], lo[1])
    z = wp.where(pl[2] >= 0.0, hi[2], lo[2])
    return pl[0] * x + pl[1] * y + pl[2] * z < pl[3]


@wp.func
def _tri_outside(a: wp.vec3, b: wp.vec3, c: wp.vec3, pl: wp.vec4) -> bool:
    """Whether the triangle ``abc`` lies wholly on the outer side of ``pl``."""
    n = wp.vec3(pl[0], pl[1], pl[2])
    return wp.max(wp.max(wp.dot(n, a), wp.dot(n, b)), wp.dot(n, c)) < pl[3]


@wp.func
def _plane(n: wp.vec3, c: wp.vec3, pad: float) -> wp.vec4:
    """Inner side ``m . p >= m . c - pad`` of the plane through ``c`` with normal ``n``."""
    m = wp.normalize(n)
    return wp.vec4(m[0], m[1], m[2], wp.dot(m, c) - pad)


@wp.func
def _tri_rect(
    a: wp.vec3, b: wp.vec3, c: wp.vec3, cam: wp.vec3, rot: wp.mat33, view: View, blk: wp.vec4i
) -> int:
    """Pixels of the block ``blk = (x0, x1, y0, y1)`` whose centre rays can meet triangle ``abc``.

    The rectangle ``[xa, xb] x [ya, yb]`` (relative to ``x0, y0``) of pixel centres inside
    the triangle's projected bounding box, widened by 0.05 px (far above the rounding of
    the projection), packed as ``xa | xb << 8 | ya << 16 | yb << 24``; the whole block when
    a vertex lies less than 1 mm in front of the camera. Empty (``xa > xb`` or ``ya > yb``)
    when no pixel centre of the block can see the triangle.
    """
    x0, x1, y0, y1 = blk[0], blk[1], blk[2], blk[3]
    fx, fy, cx, cy = view.fx, view.fy, view.cx, view.cy
    rt = wp.transpose(rot)
    qa = rt * (a - cam)
    qb = rt * (b - cam)
    qc = rt * (c - cam)
    xa = int(0)  # noqa: UP018 (Warp: mutable variables, not constants)
    xb = x1 - x0 - 1
    ya = int(0)  # noqa: UP018
    yb = y1 - y0 - 1
    if wp.min(wp.min(qa[2], qb[2]), qc[2]) > 1.0e-3:
        ua = fx * qa[0] / qa[2]
        ub = fx * qb[0] / qb[2]
        uc = fx * qc[0] / qc[2]
        va = fy * qa[1] / qa[2]
        vb = fy * qb[1] / qb[2]
        vc = fy * qc[1] / qc[2]
        # pixel x sees u = x + 0.5 - cx; clamp before converting to int
        lo = wp.clamp(wp.min(wp.min(ua, ub), uc) + cx - 0.55, float(x0 - 1), float(x1 + 1))
        hi = wp.clamp(wp.max(wp.max(ua, ub), uc) + cx - 0.45, float(x0 - 1), float(x1 + 1))
        xa = wp.max(xa, int(wp.ceil(lo)) - x0)
        xb = wp.min(xb, int(wp.floor(hi)) - x0)
        lo = wp.clamp(wp.min(wp.min(va, vb), vc) + cy - 0.55, float(y0 - 1), float(y1 + 1))
        hi = wp.clamp(wp.max(wp.max(va, vb), vc) + cy - 0.45, float(y0 - 1), float(y1 + 1))
        ya = wp.max(ya, int(wp.ceil(lo)) - y0)
        yb = wp.min(yb, int(wp.floor(hi)) - y0)
    if xa > xb or ya > yb:
        return -1
    return xa | (xb << 8) | (ya << 16) | (yb << 24)


@wp.func
def _gather(
    tree: FrustumBVH,
    cand: wp.array(dtype=wp.int32),
    cand_z: wp.array(dtype=wp.float32),
    start: wp.int64,
    cap: int,
    cam: wp.vec3,
    rot: wp.mat33,
    view: View,
    blk: wp.vec4i,
    top: float,
) -> wp.vec2:
    """The nearest triangles (at most ``cap``) that the block's ray pyramid can meet.

    Walks the implicit tree (:mod:`._frustum_bvh`) depth first without a stack (node ``j``
    of level ``k`` has the children ``BRANCH j + i`` of level ``k - 1``), skipping every
    node that lies outside one of the four side planes ``pl0..pl3`` of the block's ray
    pyramid (through the camera centre ``cam`` and the pixel centres of the block's edges),
    behind the camera (``pl4``) or beyond the optical depth ``far``. A triangle passing
    the same tests that some pixel centre of the block can see is stored with its pixel rectangle
    (:func:`_tri_rect`) in ``cand[start + 2 i]``, ``cand[start + 2 i + 1]`` and its
    nearest optical depth in ``cand_z[start / 2 + i]``.

    ``far`` starts just beyond ``top``. When the list is full, the triangle with the
    largest nearest depth ``z`` is dropped and ``far`` becomes ``z``: the list then holds
    every triangle of the pyramid whose nearest optical depth is below ``far``.

    Returns ``(n, far_lim)``: the number of triangles and the optical depth below which
    a hit found among them is the first hit of its ray (+inf when nothing was dropped;
    otherwise ``far`` less ``pad``, far above the rounding of depths).
    """
    uv = _block_uv(view, blk)
    pad = _block_pad(cam, top)
    axis = rot * wp.vec3(0.0, 0.0, 1.0)  # optical axis
    pl0 = _plane(rot * wp.vec3(1.0, 0.0, -uv[0]), cam, pad)
    pl1 = _plane(rot * wp.vec3(-1.0, 0.0, uv[1]), cam, pad)
    pl2 = _plane(rot * wp.vec3(0.0, 1.0, -uv[2]), cam, pad)
    pl3 = _plane(rot * wp.vec3(0.0, -1.0, uv[3]), cam, pad)
    pl4 = _plane(axis, cam, pad)
    k = int(tree.n_levels - 1)
    j = int(0)  # noqa: UP018 (Warp: mutable loop variables, not constants)
    n = int(0)  # noqa: UP018
    zs = start // wp.int64(2)
    ac = wp.dot(axis, cam)
    far = top + pad
    full = bool(False)  # noqa: UP018
    done = bool(False)  # noqa: UP018
    while not done:
        node = tree.level_start[k] + j
        lo = tree.lower[node]
        hi = tree.upper[node]
        pl5 = wp.vec4(-axis[0], -axis[1], -axis[2], -(ac + far + pad))
        inside = not (
            _box_outside(lo, hi, pl0)
            or _box_outside(lo, hi, pl1)
            or _box_outside(lo, hi, pl2)
            or _box_outside(lo, hi, pl3)
            or _box_outside(lo, hi, pl4)
            or _box_outside(lo, hi, pl5)
        )
        if inside and k > 0:
            k -= 1
            j = j * _BRANCH
        else:
            if inside:
                for ti in range(j * _LEAF, wp.min(j * _LEAF + _LEAF, tree.n_tri)):
                    a = tree.p0[ti]
                    b = a + tree.e1[ti]
                    c = a + tree.e2[ti]
                    z = wp.min(wp.min(wp.dot(axis, a), wp.dot(axis, b)), wp.dot(axis, c)) - ac
                    keep = z < far and not (
                        _tri_outside(a, b, c, pl0)
                        or _tri_outside(a, b, c, pl1)
                        or _tri_outside(a, b, c, pl2)
                        or _tri_outside(a, b, c, pl3)
                        or _tri_outside(a, b, c, pl4)
                    )
                    rect = int(-1)  # noqa: UP018
                    if keep:
                        rect = _tri_rect(a, b, c, cam, rot, view, blk)
                    if rect >= 0:
                        slot = n
                        if n == cap:
                            # full: drop the farthest of the list and this one
                            full = True
                            slot = int(0)  # noqa: UP018
                            z_far = cand_z[zs]
                            for q in range(1, cap):
                                zq = cand_z[zs + wp.int64(q)]
                                if zq > z_far:
                                    z_far = zq
                                    slot = q
                            if z < z_far:
                                far = z_far
                            else:
                                far = wp.min(far, z)
                                slot = -1
                        else:
                            n += 1
                        if slot >= 0:
                            cand[start + wp.int64(2 * slot)] = ti
                            cand[start + wp.int64(2 * slot + 1)] = rect
                            cand_z[zs + wp.int64(slot)] = z
            # next sibling, climbing while this node is its parent's last child
            while k < tree.n_levels - 1:
                size = tree.level_start[k + 1] - tree.level_start[k]
                if j % _BRANCH == _BRANCH - 1 or j == size - 1:
                    j = j // _BRANCH
                    k += 1
                else:
                    break
            if k == tree.n_levels - 1:
                done = True
            j += 1
    far_lim = float(_INF)
    if full:
        far_lim = far - pad
    return wp.vec2(float(n), far_lim)


@wp.func
def _cast_candidates(
    p0: wp.array(dtype=wp.vec3),
    e1: wp.array(dtype=wp.vec3),
    e2: wp.array(dtype=wp.vec3),
    cand: wp.array(dtype=wp.int32),
    start: wp.int64,
    n: int,
    far_lim: float,
    axis: wp.vec3,
    o: wp.vec3,
    d: wp.vec3,
    t_max: float,
    z_lo: float,
    px: int,
    py: int,
) -> float:
    """Nearest hit in ``[0, t_max)`` of the ray ``o + t d`` with the gathered triangles.

    Moeller-Trumbore against the gathered triangles whose pixel rectangle holds the ray's
    pixel ``(px, py)`` (relative to the block). Returns the hit distance, +inf for no hit,
    -1 as soon as a hit below ``z_lo`` is found (it hides every box depth of the pixel),
    or -2 when the list cannot tell: a hit within ``1e-3`` (barycentric) of a triangle edge
    is nearer than every clear hit, or the answer lies at an optical depth of at least
    ``far_lim`` (see :func:`_gather`). The caller then asks Warp's watertight query.
    """
    best = t_max
    amb = t_max
    eps = 1.0e-3
    result = float(0.0)  # noqa: UP018 (Warp: a mutable variable, not a constant)
    for k in range(n):
        rect = cand[start + wp.int64(2 * k + 1)]
        if px < (rect & 255) or px > ((rect >> 8) & 255):
            continue
        if py < ((rect >> 16) & 255) or py > (rect >> 24):
            continue
        ti = cand[start + wp.int64(2 * k)]
        a = e1[ti]
        b = e2[ti]
        pv = wp.cross(d, b)
        det = wp.dot(a, pv)
        if wp.abs(det) > 1.0e-20:
            inv = 1.0 / det
            tv = o - p0[ti]
            u = wp.dot(tv, pv) * inv
            if u >= -eps and u <= 1.0 + eps:
                qv = wp.cross(tv, a)
                v = wp.dot(d, qv) * inv
                if v >= -eps and u + v <= 1.0 + eps:
                    t = wp.dot(b, qv) * inv
                    if t >= 0.0 and t < best:
                        if u > eps and v > eps and u + v < 1.0 - eps:
                            best = t
                            if t < z_lo:
                                result = -1.0
                                break
                        else:
                            amb = wp.min(amb, t)
    if result == 0.0:
        # optical depth per unit of t along this ray
        dz = wp.dot(axis, d)
        if amb < best or best * dz >= far_lim:
            result = -2.0
        elif best < t_max:
            result = best
        else:
            result = _INF
    return result


@wp.func
def _cast_bvh(
    mesh: wp.uint64,
    face: int,
    coherent: int,
    any_hit: int,
    all_pixels: int,
    c: wp.vec3,
    d: wp.vec3,
    t_max: float,
    z_lo: float,
    z_env: wp.array(dtype=wp.float32),
    g: int,
) -> int:
    """Z_env of pixel ``g`` by Warp's BVH queries (the path without gathering).

    ``face`` is the triangle hit by the block's last cast ray (-1: none yet); returns the
    one to try next (see :func:`env_block_kernel`).
    """
    if coherent == 1 and face >= 0:
        t_c = _tri_hit_interior(mesh, face, c, d)
        if t_c < t_max:
            slack = 1.0e-4 * t_c + 1.0e-5  # far above float32 rounding of t
            if all_pixels == 0 and t_c + slack < z_lo:
                z_env[g] = -1.0  # occluded before every box depth
                return face
            q = wp.mesh_query_ray(mesh, c, d, wp.min(t_max, t_c + slack))
            if q.result and q.t >= 0.0:
                z_env[g] = q.t
                return q.face
    if all_pixels == 0 and any_hit == 1 and z_lo == t_max and face < 0:
        if wp.mesh_query_ray_anyhit(mesh, c, d, t_max):
            z_env[g] = -1.0
        return face
    q = wp.mesh_query_ray(mesh, c, d, t_max)
    if q.result and q.t >= 0.0 and q.t < t_max:
        z_env[g] = q.t
        return q.face
    return face


@wp.kernel
def env_block_kernel(
    mesh: wp.uint64,
    has_mesh: int,
    cam_pos: wp.array(dtype=wp.vec3),
    cam_rot: wp.array(dtype=wp.mat33),
    view: View,
    block: int,
    bw: int,
    bh: int,
    n_blocks: wp.int64,
    stride: wp.int64,
    all_pixels: int,
    t_all: float,
    any_hit: int,
    coherent: int,
    gather: int,
    cap: int,
    tree: FrustumBVH,
    cand: wp.array(dtype=wp.int32),
    cand_z: wp.array(dtype=wp.float32),
    base: wp.int64,
    z_max: wp.array(dtype=wp.float32),
    z_min: wp.array(dtype=wp.float32),
    z_env: wp.array(dtype=wp.float32),
    status: wp.array(dtype=wp.int32),
):
    """Z_env (eq. 2) of one ``block`` x ``block`` pixel block, cast only where needed.

    Work items run along rows of blocks, and row ``r`` of items takes the block row
    ``(r * stride) % n_rows`` (``stride`` coprime with the ``n_rows`` block rows of all
    frames): any run of consecutive items is spread over the image, so the host threads
    get similar ray loads, while neighbouring items stay neighbouring blocks. Every pixel
    ``g`` of the block starts at ``Z_env = +inf``; unless a ray is cast below, that is the
    answer. ``z_max[g]`` is the largest finite ``Z_a`` of the pixel (-1 when no box covers
    it) and ``z_min[g]`` the smallest.

    A ray is then cast for every pixel under a box (``z_max >= 0``), or for every pixel
    when ``all_pixels == 1`` (a depth image, up to ``t_all``), accepting triangle hits at
    ``0 <= t < max_t`` (a hit beyond the farthest box depth occludes nothing). Where all
    box depths of a pixel are equal (usually one box) and ``any_hit == 1``, Warp's
    any-hit query answers "is anything hit before Z_a" exactly: occluded pixels get
    ``Z_env = -1`` (below every box depth). No ray is cast in a block whose ray pyramid
    meets no triangle bounding box (:func:`_block_is_clear`).

    Occluders are coherent: the triangle hit by the block's last cast ray is tried first
    (``coherent == 1``). A clear interior hit nearer than every box depth of the pixel
    settles it (``Z_env = -1``) without a BVH query; a hit at ``t_c`` otherwise bounds the
    query to ``t_c`` (plus a margin far above float32 rounding).

    With ``gather == 1`` (the default launch) the block's rays are first traced together:
    the (at most ``cap``) nearest triangles the block's ray pyramid can meet are gathered
    from the mesh's implicit tree ``tree`` (:func:`_gather`, into the block's slots of ``cand`` and
    ``cand_z``), and every ray tests only those whose pixel rectangle holds it
    (:func:`_cast_candidates`, about 10 triangles per ray instead of a BVH walk). A ray the
    list cannot settle exactly (a hit near a triangle edge, or an answer beyond the depth
    the list covers) asks Warp's watertight query; so does every ray of the other path.

    ``status[key]``: 0 no pixel needs a ray, 1 cleared (pyramid test, or nothing
    gathered), 2 rays cast.
    """
    i = wp.int64(wp.tid()) + base
    row = i // wp.int64(bw)
    key = ((row * stride) % (n_blocks // wp.int64(bw))) * wp.int64(bw) + (i - row * wp.int64(bw))
    nb = wp.int64(bw * bh)
    f = int(key // nb)
    b = int(key - wp.int64(f) * nb)
    x0 = (b % bw) * block
    y0 = (b // bw) * block
    blk = wp.vec4i(x0, wp.min(x0 + block, view.width), y0, wp.min(y0 + block, view.height))
    top = float(-1.0)  # noqa: UP018 (Warp: a mutable loop variable, not a constant)
    for y in range(blk[2], blk[3]):
        g0 = f * view.npix + y * view.width
        for x in range(blk[0], blk[1]):
            g = g0 + x
            z_env[g] = _INF
            top = wp.max(top, z_max[g])
    if all_pixels == 1:
        top = t_all
    if top < 0.0 or has_mesh == 0:
        status[key] = 0
        return
    c = cam_pos[f]
    rot = cam_rot[f]
    if _block_is_clear(mesh, c, rot, blk, top, view):
        status[key] = 1
        return
    status[key] = 2
    n_cand = int(-1)  # noqa: UP018 (Warp: mutable variables, not constants)
    far_lim = float(_INF)  # noqa: UP018
    start = key * wp.int64(2 * cap)
    if gather == 1:
        g_out = _gather(tree, cand, cand_z, start, cap, c, rot, view, blk, top)
        n_cand = int(g_out[0])
        far_lim = g_out[1]
        if n_cand == 0:
            status[key] = 1
            return
    axis = rot * wp.vec3(0.0, 0.0, 1.0)  # optical axis
    face = int(-1)  # noqa: UP018 (Warp: a mutable loop variable, not a constant)
    for y in range(blk[2], blk[3]):
        g0 = f * view.npix + y * view.width
        for x in range(blk[0], blk[1]):
            g = g0 + x
            t_max = t_all
            z_lo = float(-1.0)  # noqa: UP018 (a depth image needs the nearest hit itself)
            if all_pixels == 0:
                t_max = z_max[g]
                z_lo = z_min[g]
            if t_max >= 0.0:
                d = rot * _pixel_dir_cam(x, y, view)
                if n_cand > 0:
                    r = _cast_candidates(
                        tree.p0,
                        tree.e1,
                        tree.e2,
                        cand,
                        start,
                        n_cand,
                        far_lim,
                        axis,
                        c,
                        d,
                        t_max,
                        z_lo,
                        x - x0,
                        y - y0,
                    )
                    if r == -2.0:
                        q = wp.mesh_query_ray(mesh, c, d, t_max)
                        if q.result and q.t >= 0.0 and q.t < t_max:
                            z_env[g] = q.t
                    else:
                        z_env[g] = r
                else:
                    face = _cast_bvh(
                        mesh, face, coherent, any_hit, all_pixels, c, d, t_max, z_lo, z_env, g
                    )


@wp.kernel
def pair_count_kernel(
    seg: Segments,
    box: wp.array(dtype=wp.int32),
    view: View,
    n_box: int,
    use_min: int,
    rows: int,
    base: wp.int64,
    depths: Depths,
    z_env: wp.array(dtype=wp.float32),
    counts: wp.array(dtype=wp.int32),
):
    """count((Z_a - Z_env)_ij <= 0) per (frame, artefact): the left side of A_f.

    Work items as in :func:`pair_depth_kernel`, whose ``depths`` they read (``pair_z``
    and ``z_min``); ``box[s]`` is the artefact of segment ``s``, in ``[0, n_box)``.
    """
    t = wp.int64(wp.tid()) + base
    pair_z = depths.pair_z
    if rows == 0 and pair_z[t] == _INF:
        return  # a single item that no box covers: no segment search
    run = _run_of(seg, rows, t)
    s = run[0]
    i0 = _first_item(seg, run)
    f = seg.frame[s]
    g0 = f * view.npix + run[2] * view.width + run[1]
    n = wp.int32(0)
    for j in range(run[3]):
        z = pair_z[i0 + wp.int64(j)]
        if z < _INF:
            g = g0 + j
            n += _counts_for(z, z_env[g], depths.z_min[g], use_min)
    if n > 0:
        wp.atomic_add(counts, f * n_box + box[s], n)


# ---------------------------------------------------------------------- host launchers

_CHUNKS_PER_THREAD = 4
# Every multi-threaded launch ends in a barrier; when another process holds a core, the
# barrier waits for a descheduled helper (milliseconds). Launches cheaper than that stay on
# the calling thread: block culling and counting always, box depths below this many items.
_MIN_SPLIT_ITEMS = 1 << 16


def split_bounds(n: int, device: str, threads: int) -> list[tuple[int, int]]:
    """Contiguous item ranges, one per host thread (one range on CUDA or for small n)."""
    if threads <= 1 or not str(device).startswith("cpu") or n < 8192:
        return [(0, n)]
    b = np.linspace(0, n, threads + 1).astype(np.int64)
    return [(int(lo), int(hi)) for lo, hi in zip(b[:-1], b[1:], strict=True) if hi > lo]


def launch_split(kernel, bounds, make_inputs, device: str = "cpu") -> None:
    """Launch ``kernel`` once per range in ``bounds``, each range on its own host thread.

    ``make_inputs(base, j)`` returns the kernel inputs for range ``j`` starting at item
    ``base``. Warp's CPU atomics are plain read-modify-writes, so every range that scatters
    must write to its own output buffers (index ``j``); the caller combines them.
    """
    bounds = [(lo, hi) for lo, hi in bounds if hi > lo]
    if not bounds:
        return
    if len(bounds) == 1:
        lo, hi = bounds[0]
        wp.launch(kernel, dim=hi - lo, inputs=make_inputs(lo, 0), device=device)
        return
    errors: list[BaseException] = []

    def run(j: int, lo: int, hi: int) -> None:
        try:
            wp.launch(kernel, dim=hi - lo, inputs=make_inputs(lo, j), device=device)
        except BaseException as err:  # re-raised in the calling thread
            errors.append(err)

    workers = [threading.Thread(target=run, args=(j, lo, hi)) for j, (lo, hi) in enumerate(bounds)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    if errors:
        raise errors[0]


_POOL: ThreadPoolExecutor | None = None
_POOL_SIZE = 0
_POOL_LOCK = threading.Lock()


def _pool(n: int) -> ThreadPoolExecutor:
    """A process-wide pool of at least ``n`` helper threads (spawning costs ~60 us each)."""
    global _POOL, _POOL_SIZE
    with _POOL_LOCK:
        if _POOL is None or _POOL_SIZE < n:
            _POOL = ThreadPoolExecutor(max_workers=n, thread_name_prefix="are-stats-warp")
            _POOL_SIZE = n
        return _POOL


def launch_dynamic(
    kernel, n: int, workers: int, make_inputs, device: str = "cpu", edges=None
) -> None:
    """Launch ``kernel`` over items ``[0, n)`` in chunks pulled by ``workers`` host threads.

    ``make_inputs(base, j)`` returns the inputs of a launch over the chunk starting at
    item ``base`` by worker ``j`` (which scatters into its own buffers ``j``, if any). The
    items are cut into ``_CHUNKS_PER_THREAD`` contiguous chunks per worker (or at the
    increasing item indices ``edges``, from 0 to ``n``) and each worker takes the next free
    chunk, so a worker slowed down by a busy core (or by costly rays) simply takes fewer
    chunks; contiguous chunks keep the threads off each other's cache lines. The calling
    thread is worker 0; the others come from a persistent pool.
    """
    if n <= 0:
        return
    if workers <= 1:
        wp.launch(kernel, dim=n, inputs=make_inputs(0, 0), device=device)
        return
    if edges is None:
        edges = np.linspace(0, n, workers * _CHUNKS_PER_THREAD + 1).astype(np.int64)
    chunks = [(int(lo), int(hi)) for lo, hi in zip(edges[:-1], edges[1:], strict=True) if hi > lo]
    ticket = itertools.count()  # next() is atomic under the GIL

    base_at = [a.label for a in kernel.adj.args].index("base")
    # Each worker packs the ~20 arguments once (25 us) and replays the recorded launch for
    # every chunk (9 us). The records are made here, on the calling thread: recording
    # loads the kernel's module, and two threads loading it at once crash Warp.
    cmds = [
        wp.launch(kernel, 1, inputs=make_inputs(0, j), device=device, record_cmd=True)
        for j in range(workers)
    ]

    def run(j: int) -> None:
        cmd = cmds[j]
        while (c := next(ticket)) < len(chunks):
            lo, hi = chunks[c]
            cmd.set_dim(hi - lo)
            cmd.set_param_at_index(base_at, lo)
            cmd.launch()

    futures = [_pool(workers - 1).submit(run, j) for j in range(1, workers)]
    try:
        run(0)
    finally:
        for f in futures:
            f.result()


def _is_cpu(device) -> bool:
    return str(device).startswith("cpu")


def row_chunk_edges(row_key: np.ndarray, row_work: np.ndarray, n_chunks: int) -> np.ndarray:
    """Chunk edges over rows sorted by ``row_key`` that never split a run of equal keys.

    The edges aim at equal ``row_work`` per chunk and are then moved to the next change of
    key, so two chunks never hold rows of the same image row: chunks running at once on
    different host threads write disjoint pixels.
    """
    n = len(row_key)
    if n == 0:
        return np.zeros(1, np.int64)
    cum = np.cumsum(row_work)
    targets = np.linspace(0, cum[-1], n_chunks + 1)[1:-1]
    idx = np.minimum(np.searchsorted(cum, targets, side="left"), n - 1)
    cut = np.searchsorted(row_key, row_key[idx], side="right")
    return np.unique(np.concatenate([[0], cut, [n]])).astype(np.int64)


def _array(x: np.ndarray, dtype, device: str) -> wp.array:
    return wp.array(np.ascontiguousarray(x), dtype=dtype, device=device)


def make_view(fx: float, fy: float, cx: float, cy: float, width: int, height: int) -> View:
    """The :class:`View` of frames ``width`` x ``height`` seen with intrinsics ``fx .. cy``."""
    view = View()
    view.fx, view.fy, view.cx, view.cy = float(fx), float(fy), float(cx), float(cy)
    view.width, view.height, view.npix = int(width), int(height), int(width) * int(height)
    return view


def make_segments(
    offsets: np.ndarray,
    frame: np.ndarray,
    rect: np.ndarray,
    row_seg: np.ndarray,
    row_y: np.ndarray,
    device: str,
) -> Segments:
    """The segments of the pair kernels (:class:`Segments`), on ``device``.

    Parameters
    ----------
    offsets : (n + 1,) int
        First item of each segment, then the item count.
    frame : (n,) int
        Frame of each segment.
    rect : (n, 3) int
        ``(x0, y0, w)`` of each segment's pixel rectangle.
    row_seg, row_y : (R,) int
        Segment and row (within the rectangle) of each rectangle row.
    device : str
        Warp device of the arrays.
    """
    seg = Segments()
    seg.offsets = _array(offsets.astype(np.int64), wp.int64, device)
    seg.frame = _array(frame.astype(np.int32), wp.int32, device)
    seg.rect = _array(rect.astype(np.int32), wp.vec3i, device)
    seg.row_seg = _array(row_seg.astype(np.int32), wp.int32, device)
    seg.row_y = _array(row_y.astype(np.int32), wp.int32, device)
    seg.n = len(frame)
    return seg


def make_boxes(origin: np.ndarray, rot: np.ndarray, half: np.ndarray, device: str) -> list:
    """The box arguments of :func:`pair_depth_kernel`, ``[origin (n, 3), rot (n, 3, 3),
    half (n, 3)]``, as device arrays."""
    return [
        _array(origin.astype(np.float32), wp.vec3, device),
        _array(rot.astype(np.float32), wp.mat33, device),
        _array(half.astype(np.float32), wp.vec3, device),
    ]


def make_depths(n_items: int, n_pixels: int, device: str) -> Depths:
    """Fresh buffers of the box depths (:class:`Depths`): ``pair_z`` (``n_items``,) unset,
    ``z_max`` (``n_pixels``,) -1 and ``z_min`` (``n_pixels``,) +inf."""
    out = Depths()
    out.pair_z = wp.empty(max(n_items, 1), dtype=wp.float32, device=device)
    out.z_max = wp.full(n_pixels, -1.0, dtype=wp.float32, device=device)
    out.z_min = wp.full(n_pixels, np.inf, dtype=wp.float32, device=device)
    return out


def launch_pair_depths(seg: dict, view: View, d_max: float, out: Depths, bounds, device: str):
    """Host side of :func:`pair_depth_kernel`, writing ``out``'s ``pair_z``, ``z_max``
    and ``z_min`` (:func:`make_depths`).

    ``seg["segments"]`` are the launch's segments (:func:`make_segments`), ``seg["boxes"]``
    their boxes (:func:`make_boxes`). On the CPU the work items are the rectangle rows,
    sorted by frame and image row, run by ``len(bounds)`` workers (:func:`launch_dynamic`)
    in chunks that never share an image row (:func:`row_chunk_edges`): Warp's CPU atomics
    are plain read-modify-writes, and this way no two threads touch the same pixel.
    Elsewhere a work item is one pair item.
    """
    rows = 1 if _is_cpu(device) else 0

    def inputs(base, j):
        return [seg["segments"], *seg["boxes"], view, float(d_max), rows, base, out]

    if rows:
        workers = len(bounds) if seg["n_items"] >= _MIN_SPLIT_ITEMS else 1
        edges = None
        if workers > 1:
            n_chunks = workers * _CHUNKS_PER_THREAD
            edges = row_chunk_edges(seg["row_key"], seg["row_work"], n_chunks)
        launch_dynamic(pair_depth_kernel, seg["n_rows"], workers, inputs, device, edges)
        return
    wp.launch(pair_depth_kernel, dim=seg["n_items"], inputs=inputs(0, 0), device=device)


# Try the block's last-hit triangle before a BVH query (env_block_kernel); 0 turns it off.
COHERENT = 1


def block_stride(n_rows: int) -> int:
    """A prime near ``0.618 n_rows`` that does not divide ``n_rows`` (1 for tiny n)."""
    if n_rows < 4:
        return 1
    p = max(2, int(n_rows * 0.6180339887))
    while True:
        if n_rows % p and all(p % q for q in range(2, int(p**0.5) + 1)):
            return p
        p += 1


# Most triangles gathered per pixel block (env_block_kernel); 0 turns gathering off. Measured
# on the benchmark frames (one thread): 8-24 all beat the BVH-only path by 25-45 %; 12-16
# are best overall, larger lists cost more per ray than they save.
GATHER_CAP = 16

_EMPTY: dict[str, FrustumBVH] = {}


def _empty_tree(device: str) -> FrustumBVH:
    """Placeholder tree arrays for launches without a mesh or without gathering."""
    key = str(device)
    if key not in _EMPTY:
        v = wp.zeros(1, dtype=wp.vec3, device=device)
        t = FrustumBVH()
        t.p0, t.e1, t.e2, t.lower, t.upper = v, v, v, v, v
        t.level_start = wp.zeros(2, dtype=wp.int32, device=device)
        t.n_levels, t.n_tri = 1, 0
        t.order = wp.zeros(1, dtype=wp.int64, device=device)
        _EMPTY[key] = t
    return _EMPTY[key]


def launch_env_blocks(
    mesh_id: int,
    tree: FrustumBVH | None,
    cams: dict,
    view: View,
    block: int,
    n_frames: int,
    all_pixels: int,
    t_all: float,
    any_hit: int,
    out: Depths,
    z_env: wp.array,
    status: wp.array,
    device: str,
    threads: int,
) -> None:
    """Host side of :func:`env_block_kernel` over every pixel block of ``n_frames`` frames.

    ``tree`` is the mesh's :class:`~._frustum_bvh.FrustumBVH` (None: no gathering). Ray
    costs vary across the image (sky, ground, far walls); the blocks are visited in a
    scattered order and handed to the threads in chunks on demand (:func:`launch_dynamic`).
    """
    bw, bh = -(-view.width // block), -(-view.height // block)
    n = n_frames * bw * bh
    stride = block_stride(n_frames * bh)
    k = len(split_bounds(n * block * block, device, threads))
    # _tri_rect packs a block's pixel rectangle into 8-bit fields of a signed int32
    cap = GATHER_CAP if tree is not None and mesh_id != 0 and block < 128 else 0
    arrays = tree if cap > 0 else _empty_tree(device)
    cand = wp.empty(max(2 * n * cap, 1), dtype=wp.int32, device=device)
    cand_z = wp.empty(max(n * cap, 1), dtype=wp.float32, device=device)

    def inputs(base, j):
        return [
            mesh_id,
            0 if mesh_id == 0 else 1,
            cams["pos"],
            cams["rot"],
            view,
            block,
            bw,
            bh,
            n,
            stride,
            all_pixels,
            float(t_all),
            any_hit,
            COHERENT,
            1 if cap > 0 else 0,
            cap,
            arrays,
            cand,
            cand_z,
            base,
            out.z_max,
            out.z_min,
            z_env,
            status,
        ]

    launch_dynamic(env_block_kernel, n, k, inputs, device)


def launch_pair_counts(
    seg: dict,
    view: View,
    n_box: int,
    use_min: int,
    out: Depths,
    z_env: wp.array,
    counts: list,
    bounds,
    device: str,
) -> None:
    """Host side of :func:`pair_count_kernel`; ``counts[j]`` is range j's buffer,
    ``seg["box"]`` the artefact of each segment.

    On the CPU, the rectangle rows run on the calling thread (about 3 ns per item) and fill
    ``counts[0]``; elsewhere the pair items are split at ``bounds``.
    """
    rows = 1 if _is_cpu(device) else 0

    def inputs(base, j):
        args = [seg["segments"], seg["box"], view, n_box, use_min, rows, base]
        return [*args, out, z_env, counts[j]]

    if rows:
        launch_dynamic(pair_count_kernel, seg["n_rows"], 1, inputs, device)
        return
    launch_split(pair_count_kernel, bounds, inputs, device)
