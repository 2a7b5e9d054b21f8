"""Brute-force float64 NumPy reference for eq. 2 and A_f (independent of the package)."""

from __future__ import annotations

import numpy as np


def pixel_rays(k: np.ndarray, width: int, height: int, pose: np.ndarray):
    """Unit world rays through pixel centres, row-major (v * width + u)."""
    kinv = np.linalg.inv(k)
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    pix = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1)
    d = pix @ kinv.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d @ pose[:3, :3].T
    return pose[:3, 3], d


def ray_mesh_depth(origin, dirs, vertices, faces, d_max):
    """First hit in [0, d_max] of each ray with the triangles (Moller-Trumbore), else inf."""
    z = np.full(len(dirs), np.inf)
    if len(faces) == 0:
        return z
    tri = vertices[faces]  # (F, 3, 3)
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    for lo in range(0, len(dirs), 512):
        d = dirs[lo : lo + 512][:, None, :]  # (R, 1, 3)
        p = np.cross(d, e2[None])
        det = np.einsum("rfk,fk->rf", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = origin - tri[:, 0]  # (F, 3)
            u = np.einsum("rfk,fk->rf", p, s) * inv
            q = np.cross(s, e1)  # (F, 3)
            v = np.einsum("rk,fk->rf", d[:, 0], q) * inv
            t = np.einsum("fk,fk->f", e2, q)[None] * inv
        ok = (np.abs(det) > 1e-14) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= d_max)
        t = np.where(ok, t, np.inf)
        z[lo : lo + 512] = t.min(axis=1)
    return z


def ray_box_depth(origin, dirs, center, half, rot, d_max):
    """First root max(t_near, 0) of each ray with an oriented box, in [0, d_max], else inf."""
    o = rot.T @ (origin - center)
    d = dirs @ rot  # box frame
    t_near = np.full(len(d), -np.inf)
    t_far = np.full(len(d), np.inf)
    hit = np.ones(len(d), bool)
    for k in range(3):
        par = np.abs(d[:, k]) < 1e-30
        hit &= ~(par & ((o[k] < -half[k]) | (o[k] > half[k])))
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half[k] - o[k]) / d[:, k]
            t2 = (half[k] - o[k]) / d[:, k]
        t_near = np.where(par, t_near, np.maximum(t_near, np.minimum(t1, t2)))
        t_far = np.where(par, t_far, np.minimum(t_far, np.maximum(t1, t2)))
    hit &= (t_near <= t_far) & (t_far >= 0)
    t = np.maximum(t_near, 0.0)
    return np.where(hit & (t <= d_max), t, np.inf)


def reference_counts(
    k,
    width,
    height,
    pose,
    vertices,
    faces,
    centers,
    halves,
    rots,
    d_max,
    occlusion=False,
    z_env=None,
):
    """Counts per artefact, Z_env and the box depths (n, P)."""
    origin, dirs = pixel_rays(k, width, height, pose)
    if z_env is None:
        z_env = ray_mesh_depth(origin, dirs, vertices, faces, d_max)
    za = np.array(
        [
            ray_box_depth(origin, dirs, c, h, r, d_max)
            for c, h, r in zip(centers, halves, rots, strict=True)
        ]
    ).reshape(len(centers), -1)
    ok = np.isfinite(za) & (za <= z_env[None])
    if occlusion and len(centers):
        ok &= za <= za.min(axis=0)[None]
    return ok.sum(axis=1), z_env, za
