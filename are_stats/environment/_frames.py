"""Frames of the AR-builder (paper Sect. 3.3): F_E, F_R, F_L, F_C and one F_A per artefact.

:class:`TransformTree` is a thin, strict layer over pytransform3d's
``TemporalTransformManager`` (the SE(3) algebra, graph search and ScLERP interpolation of
time-stamped poses come from the library). The layer adds what tf guarantees and the library
does not check: every frame has exactly one parent (so adding an edge that would close a
loop is an error), unknown frames are reported by name, and a lookup through a moving frame
must give a time.

Conventions follow ROS: ``lookup(target, source)`` returns the 4x4 matrix ``T`` that maps
points expressed in ``source`` to ``target`` (``p_target = T @ p_source``); a transform is
added as the pose of ``child`` in ``parent``. Camera frames use the optical convention
(z forward, x right, y down; DECISIONS 8): :data:`OPTICAL_IN_BODY` is the rotation of an
optical frame relative to a body frame (x forward, y left, z up).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite

__all__ = ["TransformTree", "pose_matrix", "planar_pose_matrix", "OPTICAL_IN_BODY"]

#: Rotation of a ROS optical frame in its body frame: columns are the optical axes.
OPTICAL_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def planar_pose_matrix(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """4x4 matrix of a planar pose ``(x, y, yaw)`` lifted to height ``z``."""
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = [x, y, z]
    return T


def pose_matrix(pose: npt.ArrayLike, name: str = "pose") -> np.ndarray:
    """A 4x4 matrix from a 4x4 matrix, a ``(7,)`` ``[x, y, z, qw, qx, qy, qz]`` or a planar
    ``(3,)`` ``[x, y, yaw]`` pose."""
    # lazy: pytransform3d adds 0.57 s CPU to `import are_stats.environment`
    from pytransform3d import transformations as pt

    a = check_finite(name, pose)
    if a.shape == (4, 4):
        try:
            pt.check_transform(a)
        except ValueError as err:
            raise ValueError(f"{name}: expected a rigid 4x4 transform ({err})") from err
        return a
    if a.shape == (7,):
        q = a[3:]
        n = np.linalg.norm(q)
        if n < 1e-12:
            raise ValueError(f"{name}: expected a non-zero quaternion, got {q.tolist()}")
        return pt.transform_from_pq(np.r_[a[:3], q / n])
    if a.shape == (3,):
        return planar_pose_matrix(*a)
    raise ValueError(
        f"{name}: expected a 4x4 matrix, [x, y, z, qw, qx, qy, qz] or [x, y, yaw], "
        f"got shape {a.shape}"
    )


class TransformTree:
    """A tf-like tree of frames with static and time-stamped (interpolated) poses.

    Examples
    --------
    >>> tree = TransformTree()
    >>> tree.set_static("base_link", "map", [1.0, 2.0, np.pi / 2])
    >>> tree.set_static("laser", "base_link", [0.2, 0.0, 0.0])
    >>> tree.transform_points("map", "laser", [[1.0, 0.0, 0.0]]).round(6).tolist()
    [[1.0, 3.2, 0.0]]
    """

    def __init__(self) -> None:
        # lazy: pytransform3d adds 0.57 s CPU to `import are_stats.environment`
        from pytransform3d.transform_manager import TemporalTransformManager

        self._tm = TemporalTransformManager(strict_check=True, check=False)
        self._parent: dict[str, str] = {}
        self._moving: set[str] = set()
        self._frames: set[str] = set()

    @property
    def frames(self) -> list[str]:
        """All frame names, sorted."""
        return sorted(self._frames)

    def parent(self, frame: str) -> str | None:
        """Parent of ``frame`` (``None`` for a root)."""
        self._check_frame(frame)
        return self._parent.get(frame)

    def _check_frame(self, frame: str) -> None:
        if frame not in self._frames:
            known = ", ".join(self.frames) or "none"
            raise ValueError(f"frame: unknown frame {frame!r} (known frames: {known})")

    def _root_path(self, frame: str) -> list[str]:
        path = [frame]
        while path[-1] in self._parent:
            path.append(self._parent[path[-1]])
        return path

    def _check_edge(self, child: str, parent: str) -> None:
        for name, v in (("child", child), ("parent", parent)):
            if not isinstance(v, str) or not v:
                raise ValueError(f"{name}: expected a non-empty frame name, got {v!r}")
        if child == parent:
            raise ValueError(f"child: a frame cannot be its own parent ({child!r})")
        old = self._parent.get(child)
        if old is not None and old != parent:
            raise ValueError(
                f"child: frame {child!r} already has parent {old!r}; a second parent "
                f"{parent!r} would make the tree a graph"
            )
        if parent in self._frames and child in self._root_path(parent):
            raise ValueError(
                f"parent: attaching {child!r} under {parent!r} would close a loop "
                f"({' -> '.join(self._root_path(parent))})"
            )

    def set_static(self, child: str, parent: str, pose: npt.ArrayLike) -> None:
        """Set the fixed pose of ``child`` in ``parent`` (see :func:`pose_matrix`)."""
        # lazy: pytransform3d adds 0.57 s CPU to `import are_stats.environment`
        from pytransform3d.transform_manager import StaticTransform

        self._check_edge(child, parent)
        T = pose_matrix(pose)
        self._tm.add_transform(child, parent, StaticTransform(T))
        self._parent[child] = parent
        self._moving.discard(child)
        self._frames.update((child, parent))

    def set_series(
        self, child: str, parent: str, times: npt.ArrayLike, poses: npt.ArrayLike
    ) -> None:
        """Set time-stamped poses of a moving ``child`` in ``parent``.

        Parameters
        ----------
        child, parent : str
        times : (n,) float
            Strictly increasing time stamps (n >= 2).
        poses : (n, 4, 4), (n, 7) or (n, 3)
            Matrices, ``[x, y, z, qw, qx, qy, qz]`` or planar ``[x, y, yaw]`` poses.
            Lookups between stamps use screw linear interpolation (ScLERP).
        """
        # lazy: pytransform3d adds 0.57 s CPU to `import are_stats.environment`
        from pytransform3d import transformations as pt
        from pytransform3d.transform_manager import NumpyTimeseriesTransform

        self._check_edge(child, parent)
        t = check_finite("times", times, ndim=1)
        if t.size < 2 or (np.diff(t) <= 0).any():
            raise ValueError(
                f"times: expected at least 2 strictly increasing stamps, got {t.tolist()[:6]}"
            )
        P = check_finite("poses", poses)
        if P.ndim < 2 or P.shape[0] != t.size:
            raise ValueError(f"poses: expected {t.size} poses, got shape {P.shape}")
        mats = np.stack([pose_matrix(P[k], f"poses[{k}]") for k in range(t.size)])
        pqs = np.stack([pt.pq_from_transform(m) for m in mats])
        self._tm.add_transform(child, parent, NumpyTimeseriesTransform(t, pqs))
        self._parent[child] = parent
        self._moving.add(child)
        self._frames.update((child, parent))

    def remove(self, child: str) -> None:
        """Remove the edge from ``child`` to its parent (and ``child`` if it becomes isolated)."""
        self._check_frame(child)
        parent = self._parent.pop(child, None)
        if parent is None:
            raise ValueError(f"child: frame {child!r} is a root and has no parent edge")
        self._tm.remove_transform(child, parent)
        self._moving.discard(child)
        for f in (child, parent):
            if f not in self._parent and f not in self._parent.values():
                self._frames.discard(f)

    def lookup(self, target: str, source: str, time: float | None = None) -> np.ndarray:
        """4x4 transform mapping points in ``source`` to ``target`` (at ``time``).

        Raises
        ------
        ValueError
            Unknown frames, frames in different trees, a moving frame on the path without
            ``time``, or ``time`` outside a moving frame's stamps.
        """
        self._check_frame(target)
        self._check_frame(source)
        if target == source:
            return np.eye(4)
        pa, pb = self._root_path(source), self._root_path(target)
        if pa[-1] != pb[-1]:
            raise ValueError(
                f"target: frames {source!r} and {target!r} are not connected "
                f"(roots {pa[-1]!r} and {pb[-1]!r})"
            )
        common = set(pa) & set(pb)
        on_path = [f for f in pa + pb if f not in common or f == ""]
        moving = [f for f in on_path if f in self._moving]
        if moving and time is None:
            raise ValueError(f"time: frame {moving[0]!r} moves; give a time for the lookup")
        t = 0.0 if time is None else float(check_finite("time", time))
        try:
            return np.asarray(self._tm.get_transform_at_time(source, target, t))
        except ValueError as err:
            raise ValueError(
                f"time: cannot look up {source!r} -> {target!r} at {t} ({err})"
            ) from err

    def transform_points(
        self, target: str, source: str, points: npt.ArrayLike, time: float | None = None
    ) -> np.ndarray:
        """Map ``(n, 3)`` points from ``source`` to ``target``."""
        p = check_finite("points", points)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points: expected an (n, 3) array, got shape {p.shape}")
        T = self.lookup(target, source, time)
        return p @ T[:3, :3].T + T[:3, 3]
