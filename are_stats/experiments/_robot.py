"""The simulated robot of the navigation experiments (paper Sect. 4): a circular footprint
moving at constant speed, with a camera mounted on its base.

Frames follow the AR-builder (Sect. 3.3): the robot base F_R in the environment frame F_E
(a planar pose ``(x, y, yaw)``), the camera's optical frame F_C fixed on F_R (ROS optical
convention, DECISIONS 8). :meth:`Robot.frames` builds the :class:`TransformTree`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite
from are_stats.builder import point_box_distance
from are_stats.environment import TransformTree
from are_stats.inputs import InputError, get_float, get_int, get_list

if TYPE_CHECKING:
    from are_stats.perception import PinholeCamera

__all__ = ["Robot", "circle_box_overlap"]


@dataclass(frozen=True)
class Robot:
    """Robot model: footprint, speed and camera.

    Parameters
    ----------
    radius : float
        Footprint radius (m): the planner inflates the augmented grid by it, and a
        collision is the footprint disc meeting an artefact box.
    speed : float
        Cruise speed along the path (m/s).
    camera_xyz : (3,) float
        Camera position on the base (m).
    camera_rpy : (3,) float
        Camera roll, pitch, yaw on the base (rad); ``0`` looks along the base's x axis.
    camera_fov : float
        Horizontal field of view (rad).
    image_size : (2,) int
        Image ``(width, height)`` in pixels, each in ``[1, 10000]``.

    Raises
    ------
    are_stats.inputs.InputError
        (a ``ValueError``) on a bad field: bools, strings or non-finite values as numbers,
        non-integral image sizes.

    Examples
    --------
    >>> r = Robot(radius=0.3, speed=0.5)
    >>> r.camera([1.0, 2.0, 0.0]).center.round(3).tolist()
    [1.2, 2.0, 0.5]
    """

    radius: float = 0.3
    speed: float = 0.5
    camera_xyz: tuple[float, float, float] = (0.2, 0.0, 0.5)
    camera_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    camera_fov: float = float(np.deg2rad(90.0))
    image_size: tuple[int, int] = field(default=(64, 48))

    def __post_init__(self) -> None:
        src = "Robot"
        pos = {"lo": 0.0, "lo_open": True}
        object.__setattr__(self, "radius", get_float(self.radius, src, "radius", **pos))
        object.__setattr__(self, "speed", get_float(self.speed, src, "speed", **pos))
        fov = get_float(self.camera_fov, src, "camera_fov", hi=float(np.pi), hi_open=True, **pos)
        object.__setattr__(self, "camera_fov", fov)
        for name in ("camera_xyz", "camera_rpy"):
            v = _items(getattr(self, name), src, name, 3)
            object.__setattr__(
                self, name, tuple(get_float(x, src, f"{name}[{i}]") for i, x in enumerate(v))
            )
        size = _items(self.image_size, src, "image_size", 2)
        object.__setattr__(
            self,
            "image_size",
            tuple(get_int(x, src, f"image_size[{i}]", lo=1, hi=10_000) for i, x in enumerate(size)),
        )

    def frames(self, pose: npt.ArrayLike = (0.0, 0.0, 0.0)) -> TransformTree:
        """A :class:`~are_stats.environment.TransformTree` ``F_E -> F_R -> F_C`` at ``pose``."""
        # lazy: perception (Warp) adds 0.75 s CPU to `import are_stats.experiments`
        from are_stats.perception import optical_from_base

        p = check_finite("pose", pose, ndim=1)
        if p.shape != (3,):
            raise ValueError(f"pose: expected (x, y, yaw), got {p.tolist()}")
        tree = TransformTree()
        tree.set_static("F_R", "F_E", p)
        tree.set_static("F_C", "F_R", optical_from_base(self.camera_xyz, self.camera_rpy))
        return tree

    def camera_poses(self, poses: npt.ArrayLike) -> np.ndarray:
        """Camera-to-world transforms ``T_E_C = T_E_R(pose) @ T_R_C`` of many base poses.

        The same chain as :meth:`frames` (``F_E -> F_R -> F_C``), composed directly: the
        experiment loop asks for a camera at 10 Hz, where building a transform tree per
        frame cost more than the perception itself.

        Parameters
        ----------
        poses : (T, 3) or (3,) float
            Planar base poses ``(x, y, yaw)`` in F_E.

        Returns
        -------
        (T, 4, 4) float64
            Optical-frame-to-world transforms (one per pose).
        """
        # lazy: perception (Warp) adds 0.75 s CPU to `import are_stats.experiments`
        from are_stats.perception import optical_from_base

        p = check_finite("poses", poses).reshape(-1, 3) if np.size(poses) else np.zeros((0, 3))
        mount = optical_from_base(self.camera_xyz, self.camera_rpy)
        c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
        base = np.zeros((p.shape[0], 4, 4))
        base[:, 0, 0], base[:, 0, 1], base[:, 1, 0], base[:, 1, 1] = c, -s, s, c
        base[:, 2, 2] = base[:, 3, 3] = 1.0
        base[:, 0, 3], base[:, 1, 3] = p[:, 0], p[:, 1]
        return base @ mount

    def intrinsics(self) -> tuple[float, float, float, float, int, int]:
        """``(fx, fy, cx, cy, width, height)`` of the camera (square pixels, ``camera_fov``
        across the width)."""
        w, h = self.image_size
        f = (w / 2.0) / np.tan(self.camera_fov / 2.0)
        return f, f, w / 2.0, h / 2.0, w, h

    def camera(self, pose: npt.ArrayLike) -> PinholeCamera:
        """The :class:`~are_stats.perception.PinholeCamera` seen from base pose ``(x, y, yaw)``."""
        # lazy: perception (Warp) adds 0.75 s CPU to `import are_stats.experiments`
        from are_stats.perception import PinholeCamera

        p = check_finite("pose", pose, ndim=1)
        if p.shape != (3,):
            raise ValueError(f"pose: expected (x, y, yaw), got {p.tolist()}")
        return PinholeCamera(*self.intrinsics(), self.camera_poses(p)[0])


def _items(value: object, source: str, where: str, n: int) -> list:
    """``n`` values of a list, tuple or 1-d array."""
    if isinstance(value, np.ndarray):
        if value.ndim != 1:
            raise InputError(source, where, f"{n} numbers", value)
        value = value.tolist()
    return get_list(value, source, where, min_len=n, max_len=n)


def circle_box_overlap(
    centre: npt.ArrayLike,
    radius: float,
    box_xy: npt.ArrayLike,
    half_xy: npt.ArrayLike,
    yaw: npt.ArrayLike,
) -> np.ndarray:
    """Whether a disc meets each oriented rectangle (the robot footprint vs artefacts).

    Parameters
    ----------
    centre : (2,) float
    radius : float
    box_xy : (n, 2) float
        Rectangle centres.
    half_xy : (n, 2) float
        Half sizes along the rectangle's own axes.
    yaw : (n,) float

    Returns
    -------
    (n,) bool
        True where the closest point of the rectangle is within ``radius`` (touching counts).

    Examples
    --------
    >>> circle_box_overlap([0.0, 0.0], 1.0, [[1.5, 0.0], [3.0, 0.0]], [[0.5, 0.5]] * 2,
    ...                    [0.0, 0.0]).tolist()
    [True, False]
    """
    return point_box_distance(centre, box_xy, half_xy, yaw) <= float(radius)
