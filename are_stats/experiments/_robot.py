"""The simulated robot of the navigation experiments (paper Sect. 4): a circular footprint
moving at constant speed, with a camera mounted on its base.

Frames follow the AR-builder (Sect. 3.3): the robot base F_R in the environment frame F_E
(a planar pose ``(x, y, yaw)``), the camera's optical frame F_C fixed on F_R (ROS optical
convention, DECISIONS 8). :meth:`Robot.frames` builds the :class:`TransformTree`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from are_stats._checks import check_finite, check_positive

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
        Image ``(width, height)`` in pixels.

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
        object.__setattr__(self, "radius", float(check_positive("radius", self.radius)))
        object.__setattr__(self, "speed", float(check_positive("speed", self.speed)))
        fov = float(check_positive("camera_fov", self.camera_fov))
        if fov >= np.pi:
            raise ValueError(f"camera_fov: expected a field of view in (0, pi) rad, got {fov}")
        object.__setattr__(self, "camera_fov", fov)
        for name in ("camera_xyz", "camera_rpy"):
            v = check_finite(name, getattr(self, name), ndim=1)
            if v.shape != (3,):
                raise ValueError(f"{name}: expected 3 numbers, got {v.tolist()}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        size = np.asarray(self.image_size)
        if size.shape != (2,) or (size < 1).any() or (size != np.round(size)).any():
            raise ValueError(f"image_size: expected (width, height) >= 1, got {self.image_size}")
        object.__setattr__(self, "image_size", (int(size[0]), int(size[1])))

    def frames(self, pose: Any = (0.0, 0.0, 0.0)) -> Any:
        """A :class:`~are_stats.environment.TransformTree` ``F_E -> F_R -> F_C`` at ``pose``."""
        from are_stats.environment import TransformTree
        from are_stats.perception import optical_from_base

        p = check_finite("pose", pose, ndim=1)
        if p.shape != (3,):
            raise ValueError(f"pose: expected (x, y, yaw), got {p.tolist()}")
        tree = TransformTree()
        tree.set_static("F_R", "F_E", p)
        tree.set_static("F_C", "F_R", optical_from_base(self.camera_xyz, self.camera_rpy))
        return tree

    def camera(self, pose: Any) -> Any:
        """The :class:`~are_stats.perception.PinholeCamera` seen from base pose ``(x, y, yaw)``."""
        from are_stats.perception import PinholeCamera

        w, h = self.image_size
        f = (w / 2.0) / np.tan(self.camera_fov / 2.0)
        T = self.frames(pose).lookup("F_E", "F_C")
        return PinholeCamera(f, f, w / 2.0, h / 2.0, w, h, T)


def circle_box_overlap(
    centre: Any, radius: float, box_xy: Any, half_xy: Any, yaw: Any
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
    c = np.asarray(centre, float)
    b = np.asarray(box_xy, float).reshape(-1, 2)
    h = np.asarray(half_xy, float).reshape(-1, 2)
    y = np.asarray(yaw, float).reshape(-1)
    d = c[None, :] - b
    cs, sn = np.cos(y), np.sin(y)
    local = np.stack([cs * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + cs * d[:, 1]], axis=1)
    q = np.abs(local) - h
    dist = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return dist <= float(radius)
