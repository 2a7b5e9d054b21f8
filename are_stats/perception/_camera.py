"""Pinhole camera P = K [R | t] and the view model F_view = {P, (W, d_max)} (paper section 3.3).

Conventions (DECISIONS 8): ROS optical frame (z forward, x right, y down), one ray per pixel
through its centre ``(u + 0.5, v + 0.5)``, unit directions so that depths are Euclidean
distances. ``pose`` is the camera-to-world transform (4, 4) of the optical frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from are_stats._checks import check_finite, describe

__all__ = ["PinholeCamera", "check_pose", "optical_from_base"]

# Rotation taking optical-frame axes (z forward, x right, y down) to a body frame
# (x forward, y left, z up): the columns are the optical x, y, z axes in body coordinates.
_BODY_FROM_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def check_pose(name: str, pose: Any, atol: float = 1e-6) -> np.ndarray:
    """Validate a rigid transform (4, 4) with an orthonormal, right-handed rotation block."""
    p = check_finite(name, pose)
    if p.shape != (4, 4):
        raise ValueError(f"{name}: expected a (4, 4) rigid transform, got shape {p.shape}")
    if not np.allclose(p[3], [0.0, 0.0, 0.0, 1.0], atol=atol):
        raise ValueError(f"{name}: expected last row [0, 0, 0, 1], got {describe(p[3])}")
    r = p[:3, :3]
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    if err > atol or np.linalg.det(r) < 0:
        raise ValueError(
            f"{name}: expected an orthonormal right-handed rotation block, "
            f"got max |R^T R - I| = {err:.3g}, det = {np.linalg.det(r):.3g}"
        )
    return p


def optical_from_base(xyz: Any = (0.0, 0.0, 0.0), rpy: Any = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Base-to-optical mount transform (4, 4): the camera link at ``xyz`` with roll-pitch-yaw.

    The camera link follows the ROS body convention (x forward, z up); the returned
    transform maps optical-frame coordinates (z forward, x right, y down) into the base
    frame, i.e. ``T_base_optical``. Compose with a robot pose ``T_world_base`` to get the
    camera pose: ``T_world_base @ optical_from_base(...)``.

    Parameters
    ----------
    xyz : (3,) float
        Camera link origin in the base frame (metres).
    rpy : (3,) float
        Roll, pitch, yaw of the camera link in the base frame (radians, extrinsic XYZ).

    Returns
    -------
    (4, 4) float64
        ``T_base_optical``.
    """
    xyz = check_finite("xyz", xyz, ndim=1)
    rpy = check_finite("rpy", rpy, ndim=1)
    if xyz.shape != (3,) or rpy.shape != (3,):
        raise ValueError(f"xyz, rpy: expected 3 numbers each, got {xyz.shape}, {rpy.shape}")
    cr, sr = np.cos(rpy[0]), np.sin(rpy[0])
    cp, sp = np.cos(rpy[1]), np.sin(rpy[1])
    cy, sy = np.cos(rpy[2]), np.sin(rpy[2])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    t = np.eye(4)
    t[:3, :3] = rz @ ry @ rx @ _BODY_FROM_OPTICAL
    t[:3, 3] = xyz
    return t


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """Pinhole camera with intrinsics ``(fx, fy, cx, cy)``, image size and a pose.

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels (> 0).
    cx, cy : float
        Principal point in pixels, inside ``[0, width] x [0, height]``.
    width, height : int
        Image size in pixels (> 0).
    pose : (4, 4) float
        Camera-to-world transform of the optical frame (z forward, x right, y down).

    Raises
    ------
    ValueError
        If the intrinsics do not fit the image or the pose is not a rigid transform.

    Examples
    --------
    >>> cam = PinholeCamera(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> cam.K.shape, cam.P.shape
    ((3, 3), (3, 4))
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):
            v = float(check_finite(name, getattr(self, name), ndim=0))
            if v <= 0:
                raise ValueError(f"{name}: expected a focal length > 0 pixels, got {v!r}")
            object.__setattr__(self, name, v)
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not float(v).is_integer() or v <= 0:
                raise ValueError(f"{name}: expected a positive integer number of pixels, got {v!r}")
            object.__setattr__(self, name, int(v))
        for name, size in (("cx", self.width), ("cy", self.height)):
            v = float(check_finite(name, getattr(self, name), ndim=0))
            if not 0.0 <= v <= size:
                raise ValueError(
                    f"{name}: expected a principal point inside the image [0, {size}], got {v!r}"
                )
            object.__setattr__(self, name, v)
        object.__setattr__(self, "pose", check_pose("pose", self.pose))

    # ------------------------------------------------------------------ matrices
    @property
    def K(self) -> np.ndarray:  # noqa: N802 (the paper's symbol)
        """Intrinsic matrix (3, 3)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def R(self) -> np.ndarray:  # noqa: N802
        """Camera-to-world rotation (3, 3)."""
        return self.pose[:3, :3].copy()

    @property
    def center(self) -> np.ndarray:
        """Camera centre C in the world frame (3,)."""
        return self.pose[:3, 3].copy()

    @property
    def P(self) -> np.ndarray:  # noqa: N802
        """Camera matrix P = K [R^T | -R^T C] (3, 4), world points to homogeneous pixels."""
        r = self.pose[:3, :3]
        ext = np.hstack([r.T, -(r.T @ self.pose[:3, 3])[:, None]])
        return self.K @ ext

    @property
    def principal_axis(self) -> np.ndarray:
        """Unit vector of the principal axis in the world frame, ``det(M) m^3`` of the paper."""
        p = self.P
        m = p[:, :3]
        v = np.linalg.det(m) * m[2]
        return v / np.linalg.norm(v)

    def with_pose(self, pose: Any) -> PinholeCamera:
        """The same intrinsics at another camera-to-world pose (4, 4)."""
        return PinholeCamera(self.fx, self.fy, self.cx, self.cy, self.width, self.height, pose)

    # ------------------------------------------------------------------ rays
    def directions_camera(self) -> np.ndarray:
        """Unit ray directions in the optical frame, (height, width, 3) float64."""
        u = (np.arange(self.width) + 0.5 - self.cx) / self.fx
        v = (np.arange(self.height) + 0.5 - self.cy) / self.fy
        d = np.empty((self.height, self.width, 3))
        d[..., 0] = u[None, :]
        d[..., 1] = v[:, None]
        d[..., 2] = 1.0
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """One ray per pixel centre in the world frame.

        Returns
        -------
        origins : (height * width, 3) float64
            The camera centre repeated, row-major pixel order (``v * width + u``).
        directions : (height * width, 3) float64
            Unit directions, so that ray parameters are Euclidean distances.
        """
        d = self.directions_camera().reshape(-1, 3) @ self.pose[:3, :3].T
        o = np.broadcast_to(self.pose[:3, 3], d.shape).copy()
        return o, d

    def project(self, points: Any) -> tuple[np.ndarray, np.ndarray]:
        """Project world points (n, 3) to pixel coordinates (n, 2) and optical depth z (n,)."""
        x = check_finite("points", points)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"points: expected shape (n, 3), got {x.shape}")
        r = self.pose[:3, :3]
        xc = (x - self.pose[:3, 3]) @ r
        z = xc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([self.fx * xc[:, 0] / z + self.cx, self.fy * xc[:, 1] / z + self.cy], 1)
        return uv, z

    def fov_cone(self, d_max: float) -> np.ndarray:
        """Corners of the field-of-view pyramid W cut at range ``d_max`` (world frame).

        Returns
        -------
        (5, 3) float64
            The camera centre followed by the four far corners (image corners at
            Euclidean distance ``d_max`` along their rays), in the order top-left,
            top-right, bottom-right, bottom-left.
        """
        d_max = float(check_finite("d_max", d_max, ndim=0))
        if d_max <= 0:
            raise ValueError(f"d_max: expected a range > 0, got {d_max!r}")
        corners = np.array(
            [[0.0, 0.0], [self.width, 0.0], [self.width, self.height], [0.0, self.height]]
        )
        d = np.column_stack(
            [(corners[:, 0] - self.cx) / self.fx, (corners[:, 1] - self.cy) / self.fy, np.ones(4)]
        )
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        far = self.pose[:3, 3] + d_max * (d @ self.pose[:3, :3].T)
        return np.vstack([self.pose[:3, 3], far])

    # ------------------------------------------------------------------ YAML
    @classmethod
    def from_dict(cls, data: dict, source: str = "camera") -> PinholeCamera:
        """Build a camera from a mapping (plain fields or ROS ``camera_info`` fields).

        Accepted keys: ``fx, fy, cx, cy`` or ``K`` / ``k`` (9 numbers, row-major, as in ROS
        ``sensor_msgs/CameraInfo``) or ``camera_matrix: {data: [9 numbers]}`` (the
        ``camera_calibration`` YAML); ``width``/``image_width`` and
        ``height``/``image_height``; optional ``pose`` (4x4 nested list or 16 numbers,
        camera-to-world of the optical frame).
        """
        if not isinstance(data, dict):
            raise ValueError(f"{source}: expected a mapping of camera fields, got {describe(data)}")
        k = None
        for key in ("K", "k"):
            if key in data:
                k = data[key]
        if "camera_matrix" in data:
            cm = data["camera_matrix"]
            k = cm.get("data") if isinstance(cm, dict) else cm
        if k is not None:
            k = check_finite(f"{source}: field K", k).ravel()
            if k.size != 9:
                raise ValueError(f"{source}: field K: expected 9 numbers, got {k.size}")
            fx, fy, cx, cy = k[0], k[4], k[2], k[5]
        else:
            missing = [f for f in ("fx", "fy", "cx", "cy") if f not in data]
            if missing:
                raise ValueError(
                    f"{source}: expected fields fx, fy, cx, cy or K, missing {missing}"
                )
            fx, fy, cx, cy = (data[f] for f in ("fx", "fy", "cx", "cy"))
        size = {}
        for name, alts in (
            ("width", ("width", "image_width")),
            ("height", ("height", "image_height")),
        ):
            for a in alts:
                if a in data:
                    size[name] = data[a]
            if name not in size:
                raise ValueError(f"{source}: expected field {alts[0]} (or {alts[1]}), missing")
        pose = np.eye(4)
        if data.get("pose") is not None:
            pose = check_finite(f"{source}: field pose", data["pose"]).reshape(-1)
            if pose.size != 16:
                raise ValueError(f"{source}: field pose: expected 16 numbers, got {pose.size}")
            pose = pose.reshape(4, 4)
        try:
            return cls(fx, fy, cx, cy, size["width"], size["height"], pose)
        except ValueError as err:
            raise ValueError(f"{source}: {err}") from err

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> PinholeCamera:
        """Load a camera from a YAML file (see :meth:`from_dict` for the accepted fields).

        Raises
        ------
        FileNotFoundError
            If ``path`` does not exist.
        ValueError
            If the YAML cannot be parsed or the fields are missing or invalid.
        """
        import yaml

        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: camera file not found")
        try:
            data = yaml.safe_load(p.read_text())
        except yaml.YAMLError as err:
            raise ValueError(f"{p}: not valid YAML ({err})") from err
        return cls.from_dict(data, source=str(p))

    def to_dict(self) -> dict:
        """Plain fields (the inverse of :meth:`from_dict`), suitable for YAML."""
        return {
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "width": self.width,
            "height": self.height,
            "pose": self.pose.tolist(),
        }
