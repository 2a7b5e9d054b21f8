"""Pinhole camera P = K [R | t] and the view model F_view = {P, (W, d_max)} (paper section 3.3).

Conventions (DECISIONS 8): ROS optical frame (z forward, x right, y down), one ray per pixel
through its centre ``(u + 0.5, v + 0.5)``, unit directions so that depths are Euclidean
distances. ``pose`` is the camera-to-world transform (4, 4) of the optical frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
import numpy.typing as npt

from are_stats import inputs
from are_stats._checks import check_finite, describe
from are_stats.environment import resolve_shipped
from are_stats.inputs import Described, InputError, Source

__all__ = [
    "CameraModel",
    "PinholeCamera",
    "camera_mount",
    "check_pose",
    "fov_cone",
    "optical_from_base",
    "read_camera",
    "MIN_FOCAL",
    "MAX_FOCAL",
    "MAX_SIDE",
    "PIXEL_BYTES",
]

#: Focal lengths accepted (pixels): below, ray directions overflow; above, nothing is seen.
MIN_FOCAL = 1e-3
MAX_FOCAL = 1e9
#: Largest image side accepted (pixels).
MAX_SIDE = 1 << 20
#: Memory estimate of perception per image pixel and frame (bytes): ray origins and
#: directions in float64, depth buffers and per-pixel artefact ids.
PIXEL_BYTES = 128
_MAX_VECTOR = 64

# Rotation taking optical-frame axes (z forward, x right, y down) to a body frame
# (x forward, y left, z up): the columns are the optical x, y, z axes in body coordinates.
_BODY_FROM_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def check_pose(name: str, pose: npt.ArrayLike, atol: float = 1e-6) -> np.ndarray:
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


def optical_from_base(
    xyz: npt.ArrayLike = (0.0, 0.0, 0.0), rpy: npt.ArrayLike = (0.0, 0.0, 0.0)
) -> np.ndarray:
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


def camera_mount(
    pose: npt.ArrayLike, height: float, tree_mount: npt.ArrayLike | None = None
) -> np.ndarray:
    """The one rule for where a robot's camera sits: its mount ``T_base_optical`` (4, 4).

    The robot's own tree (``tree_mount``, e.g. a bag's static chain from the base to the
    camera frame) wins; else the camera file's ``pose`` when it has one (any pose but the
    identity, which a camera file without a pose gets); else ``height`` m above the base,
    looking forward (:func:`optical_from_base` at ``(0, 0, height)``). ``are-stats
    perceive``, ``augment`` and ``serve`` all mount their camera by it.

    Parameters
    ----------
    pose : (4, 4) float
        The camera's ``pose`` (:attr:`PinholeCamera.pose`).
    height : float
        Height (m) of the forward-looking default.
    tree_mount : (4, 4) float, optional
        The mount the robot's own frames give.

    Returns
    -------
    (4, 4) float64
        ``T_base_optical``.

    Examples
    --------
    >>> camera_mount(np.eye(4), 1.5)[:3].round(6).tolist()
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.5]]
    """
    if tree_mount is not None:
        return np.asarray(tree_mount, float)
    if not np.allclose(pose, np.eye(4)):
        return np.asarray(pose, float)
    return optical_from_base((0.0, 0.0, float(height)))


class CameraModel(Protocol):
    """What the perception functions read of a camera: :class:`PinholeCamera`, or any
    object with these attributes."""

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float: the intrinsic matrix."""
        ...

    @property
    def width(self) -> int:
        """Image width in pixels."""
        ...

    @property
    def height(self) -> int:
        """Image height in pixels."""
        ...

    @property
    def pose(self) -> np.ndarray:
        """(4, 4) float: camera-to-world transform of the optical frame."""
        ...


def fov_cone(camera: CameraModel, d_max: float) -> np.ndarray:
    """Corners of the field-of-view pyramid W of a camera cut at range ``d_max`` (world
    frame), from its intrinsic matrix ``K``, image size and ``pose``.

    Parameters
    ----------
    camera : CameraModel
    d_max : float
        The range (m, > 0).

    Returns
    -------
    (5, 3) float64
        The camera centre followed by the four far corners (image corners at Euclidean
        distance ``d_max`` along their rays), in the order top-left, top-right,
        bottom-right, bottom-left.

    Raises
    ------
    ValueError
        If ``d_max`` is not a finite range > 0.
    """
    d_max = float(check_finite("d_max", d_max, ndim=0))
    if d_max <= 0:
        raise ValueError(f"d_max: expected a range > 0, got {d_max!r}")
    k, pose = camera.K, camera.pose
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    w, h = camera.width, camera.height
    corners = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    d = np.column_stack([(corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fy, np.ones(4)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    far = pose[:3, 3] + d_max * (d @ pose[:3, :3].T)
    return np.vstack([pose[:3, 3], far])


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
            v = getattr(self, name)
            v = v.item() if isinstance(v, np.ndarray) and v.ndim == 0 else v
            if not _is_real(v) or not MIN_FOCAL <= float(v) <= MAX_FOCAL:
                raise ValueError(
                    f"{name}: expected a focal length > 0 pixels (in [{MIN_FOCAL:g}, "
                    f"{MAX_FOCAL:g}]), got {_show(v)}"
                )
            object.__setattr__(self, name, float(v))
        for name in ("width", "height"):
            v = getattr(self, name)
            v = v.item() if isinstance(v, np.ndarray) and v.ndim == 0 else v
            if not _is_real(v) or not float(v).is_integer() or not 1 <= v <= MAX_SIDE:
                raise ValueError(
                    f"{name}: expected a positive integer number of pixels (at most "
                    f"{MAX_SIDE}), got {_show(v)}"
                )
            object.__setattr__(self, name, int(v))
        for name, size in (("cx", self.width), ("cy", self.height)):
            v = getattr(self, name)
            v = v.item() if isinstance(v, np.ndarray) and v.ndim == 0 else v
            if not _is_real(v) or not 0.0 <= float(v) <= size:
                raise ValueError(
                    f"{name}: expected a principal point inside the image [0, {size}], "
                    f"got {_show(v)}"
                )
            object.__setattr__(self, name, float(v))
        object.__setattr__(self, "pose", check_pose("pose", self.pose))

    def check_memory(self, source: Source = "") -> None:
        """Refuse a camera whose per-frame ray buffers (:data:`PIXEL_BYTES` bytes a pixel)
        exceed :func:`are_stats.inputs.memory_limit` (``LimitError``)."""
        inputs.check_memory(
            float(self.width) * float(self.height) * PIXEL_BYTES,
            f"the rays of a {self.width} x {self.height} camera image",
            source or "camera",
        )

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

    def with_pose(self, pose: npt.ArrayLike) -> PinholeCamera:
        """The same intrinsics at another camera-to-world pose (4, 4)."""
        return PinholeCamera(self.fx, self.fy, self.cx, self.cy, self.width, self.height, pose)

    # ------------------------------------------------------------------ rays
    def directions_camera(self) -> np.ndarray:
        """Unit ray directions in the optical frame, (height, width, 3) float64."""
        self.check_memory()
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

    def project(self, points: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
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
        """Corners of the field-of-view pyramid W cut at range ``d_max`` (world frame):
        :func:`fov_cone` of this camera."""
        return fov_cone(self, d_max)

    # ------------------------------------------------------------------ YAML
    @classmethod
    def from_dict(cls, data: object, source: str = "camera") -> PinholeCamera:
        """Build a camera from a mapping (plain fields or ROS ``camera_info`` fields).

        Accepted keys: exactly one of ``fx, fy, cx, cy`` / ``K`` / ``k`` (9 numbers,
        row-major, as in ROS ``sensor_msgs/CameraInfo``) / ``camera_matrix:
        {rows: 3, cols: 3, data: [9 numbers]}`` (the ``camera_calibration`` YAML); one of
        ``width``/``image_width`` and one of ``height``/``image_height``; optional ``pose``
        (4x4 nested list or 16 numbers, camera-to-world of the optical frame). The ROS
        calibration fields ``camera_name``, ``distortion_model``,
        ``distortion_coefficients``/``D``/``d``, ``rectification_matrix``/``R``/``r``,
        ``projection_matrix``/``P``/``p`` and ``binning_x``/``binning_y`` are accepted when
        they describe an ideal pinhole camera (all distortion coefficients 0, identity
        rectification, ``P = [K | 0]``, no binning); anything else would be silently ignored
        by the pinhole model and is an error, as are unknown keys, a non-zero skew
        ``K[0][1]`` or a bottom row of ``K`` other than ``[0, 0, 1]``.

        Raises
        ------
        are_stats.inputs.InputError
            (a ``ValueError``) naming ``source`` and the key; ``LimitError`` if the image
            is too large for the memory limit (:meth:`check_memory`).
        """
        d = inputs.check_keys(data, source, "", _CAMERA_KEYS)
        groups = (("fx", "fy", "cx", "cy"), ("K",), ("k",), ("camera_matrix",))
        given = [g for g in groups if any(k in d for k in g)]
        if len(given) != 1:
            raise InputError(
                source,
                "",
                "the intrinsics as exactly one of fx/fy/cx/cy, K, k or camera_matrix",
                Described(f"{len(given)} of them" if given else "none"),
            )
        (group,) = given
        if group[0] == "fx":
            missing = [k for k in group if k not in d]
            if missing:
                raise InputError(
                    source, missing[0], "this key to be present", Described("no such key")
                )
            fx, fy, cx, cy = (inputs.get_float(d[k], source, k) for k in group)
        else:
            k = _matrix(d[group[0]], source, group[0], 3, 3)
            fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
            if abs(k[0, 1]) > 1e-12 * max(abs(fx), 1.0):
                raise InputError(
                    source,
                    f"{group[0]}[0][1] (skew)",
                    "0 (the pinhole model has no skew)",
                    float(k[0, 1]),
                )
            if k[1, 0] != 0.0 or not np.array_equal(k[2], [0.0, 0.0, 1.0]):
                raise InputError(
                    source,
                    group[0],
                    "an intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]",
                    Described(f"rows 2-3 {k[1:].tolist()}"),
                )
        size = {}
        for name, alts in (
            ("width", ("width", "image_width")),
            ("height", ("height", "image_height")),
        ):
            present = [a for a in alts if a in d]
            if not present:
                raise InputError(
                    source, alts[0], f"this key (or {alts[1]})", Described("no such key")
                )
            if len(present) > 1:
                raise InputError(source, alts[1], f"only one of {alts[0]}, {alts[1]}", d[alts[1]])
            size[name] = inputs.get_int(d[present[0]], source, present[0], lo=1, hi=MAX_SIDE)
        for key, lo, hi in (("fx", MIN_FOCAL, MAX_FOCAL), ("fy", MIN_FOCAL, MAX_FOCAL)):
            v = fx if key == "fx" else fy
            inputs.get_float(float(v), source, f"{key} (focal length in pixels)", lo=lo, hi=hi)
        inputs.get_float(float(cx), source, "cx (principal point)", lo=0, hi=size["width"])
        inputs.get_float(float(cy), source, "cy (principal point)", lo=0, hi=size["height"])
        _check_ideal(d, source, np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]))
        pose = np.eye(4)
        if d.get("pose") is not None:
            pose = _matrix(d["pose"], source, "pose", 4, 4)
        try:
            pose = check_pose("pose", pose)
        except ValueError as err:
            detail = str(err).partition(", got ")[2] or str(err)
            raise InputError(
                source,
                "pose",
                "a rigid camera-to-world transform (orthonormal right-handed rotation, last "
                "row [0, 0, 0, 1])",
                Described(detail),
            ) from None
        cam = cls(float(fx), float(fy), float(cx), float(cy), size["width"], size["height"], pose)
        cam.check_memory(source)
        return cam

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> PinholeCamera:
        """Load a camera from a YAML file (see :meth:`from_dict` for the accepted fields).

        Raises
        ------
        FileNotFoundError
            If ``path`` does not exist.
        are_stats.inputs.InputError
            (a ``ValueError``) if the YAML cannot be parsed or the fields are missing,
            unknown or invalid.
        """
        p = Path(path)
        return cls.from_dict(inputs.load_yaml(p, "camera YAML"), source=str(p))

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


def read_camera(name_or_path: str | os.PathLike, *, source: str = "--camera") -> PinholeCamera:
    """A camera where a command or config takes one, as :func:`~are_stats.environment.read_map`
    reads a map: ``name_or_path`` is a camera YAML (ROS ``camera_info`` fields,
    :meth:`PinholeCamera.from_dict`; an existing file wins) or the name of a shipped camera
    (``front_camera``; :func:`~are_stats.environment.resolve_shipped`), ``source`` the option
    or key it came from, named when it is neither (``"--camera"``).

    Raises
    ------
    are_stats.inputs.InputError
        Naming ``source`` and the shipped cameras when ``name_or_path`` is neither a file
        nor a shipped camera's name; the errors of :meth:`PinholeCamera.from_yaml`.

    Examples
    --------
    >>> cam = read_camera("front_camera")
    >>> cam.width, cam.height
    (640, 480)
    """
    return PinholeCamera.from_yaml(resolve_shipped(name_or_path, "camera", source=source))


_CAMERA_KEYS = (
    "fx",
    "fy",
    "cx",
    "cy",
    "K",
    "k",
    "camera_matrix",
    "width",
    "image_width",
    "height",
    "image_height",
    "pose",
    "camera_name",
    "distortion_model",
    "distortion_coefficients",
    "D",
    "d",
    "rectification_matrix",
    "R",
    "r",
    "projection_matrix",
    "P",
    "p",
    "binning_x",
    "binning_y",
)


def _is_real(v: object) -> bool:
    return (
        isinstance(v, int | float | np.integer | np.floating)
        and not isinstance(v, bool | np.bool_)
        and bool(np.isfinite(v))
    )


def _show(v: object) -> str:
    return f"{v!r} (a {type(v).__name__})" if isinstance(v, bool | str) else describe(v)


def _matrix(value: object, source: Source, key: str, rows: int, cols: int | None) -> np.ndarray:
    """A ``rows x cols`` matrix given flat, nested or as ``{rows, cols, data}``; ``cols``
    ``None`` means a vector of any length up to :data:`_MAX_VECTOR`."""
    if isinstance(value, dict):
        m = inputs.check_keys(value, source, key, ("rows", "cols", "data"), ("data",))
        for name, want in (("rows", rows), ("cols", cols)):
            if name in m and want is not None:
                if inputs.get_int(m[name], source, f"{key}.{name}") != want:
                    raise InputError(source, f"{key}.{name}", str(want), m[name])
        value, key = m["data"], f"{key}.data"
    n = rows * cols if cols is not None else None
    if not isinstance(value, list | tuple):
        what = f"{n} numbers" if n is not None else f"a list of at most {_MAX_VECTOR} numbers"
        raise InputError(source, key, what, value)
    items = inputs.get_list(value, source, key, max_len=_MAX_VECTOR if n is None else None)
    if n is not None and len(items) == rows and all(isinstance(r, list | tuple) for r in items):
        flat = []
        for i, r in enumerate(items):
            flat += inputs.get_list(r, source, f"{key}[{i}]", min_len=cols, max_len=cols)
        items = flat
    if n is not None and len(items) != n:
        raise InputError(
            source,
            key,
            f"{n} numbers ({rows} x {cols}, row-major or nested)",
            Described(f"{len(items)} values"),
        )
    out = np.array([inputs.get_float(v, source, f"{key}[{i}]") for i, v in enumerate(items)])
    return out if cols is None else out.reshape(rows, cols)


def _check_ideal(d: dict, source: Source, k: np.ndarray) -> None:
    """The ROS calibration fields must describe the ideal pinhole camera ``k``."""
    if "camera_name" in d:
        inputs.get_str(d["camera_name"], source, "camera_name")
    if "distortion_model" in d:
        inputs.get_str(d["distortion_model"], source, "distortion_model")
    for key in ("distortion_coefficients", "D", "d"):
        if key in d:
            c = _matrix(d[key], source, key, 1, None)
            if (c != 0).any():
                i = int(np.flatnonzero(c)[0])
                raise InputError(
                    source,
                    f"{key}[{i}]",
                    "0 (the pinhole model has no lens distortion: rectify the images and give "
                    "the rectified intrinsics)",
                    float(c[i]),
                )
    for key in ("rectification_matrix", "R", "r"):
        if key in d:
            r = _matrix(d[key], source, key, 3, 3)
            if not np.allclose(r, np.eye(3), rtol=0, atol=1e-9):
                raise InputError(
                    source, key, "the identity (a monocular, unrectified camera)", r.tolist()
                )
    for key in ("projection_matrix", "P", "p"):
        if key in d:
            pm = _matrix(d[key], source, key, 3, 4)
            want = np.hstack([k, np.zeros((3, 1))])
            if not np.allclose(pm, want, rtol=1e-9, atol=1e-9):
                raise InputError(
                    source,
                    key,
                    f"[K | 0] = {want.tolist()} (the pinhole model projects with K)",
                    pm.tolist(),
                )
    for key in ("binning_x", "binning_y"):
        if key in d and inputs.get_int(d[key], source, key, lo=0) > 1:
            raise InputError(source, key, "0 or 1 (no binning)", d[key])
