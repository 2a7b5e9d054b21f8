"""A small tf2-like transform buffer for bags: ``/tf`` and ``/tf_static`` without ROS.

Each link ``parent -> child`` keeps its stamped transforms; a lookup composes the chain
between two frames of the tree and interpolates every moving link at the asked times
(translation linearly, rotation by slerp, held constant outside its stamps, as a tf2
lookup with extrapolation clamped). A frame has one parent, as in tf2: a second parent for
a frame is ignored.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["TF_TYPE", "TF_TYPES", "TfBuffer", "interpolate_poses", "transform_matrix"]

#: Message type of ``/tf`` and ``/tf_static``.
TF_TYPE = "tf2_msgs/msg/TFMessage"
#: Types read as tf messages: tf2's and the old ROS 1 ``tf/tfMessage`` (same fields).
TF_TYPES = (TF_TYPE, "tf/msg/tfMessage")


def transform_matrix(translation: Any, rotation: Any) -> np.ndarray:
    """(4, 4) transform of a ROS translation (``x, y, z``) and quaternion (``x, y, z, w``)
    (a ``geometry_msgs/Transform``'s fields or a ``Pose``'s ``position, orientation``)."""
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    q = np.array([rotation.x, rotation.y, rotation.z, rotation.w], float)
    n = np.linalg.norm(q)
    m[:3, :3] = Rotation.from_quat(q / n if n > 0 else [0, 0, 0, 1]).as_matrix()
    m[:3, 3] = [translation.x, translation.y, translation.z]
    return m


def interpolate_poses(t: Any, poses: Any, times: Any) -> np.ndarray:
    """Poses ``(T, 4, 4)`` at ``times`` from stamped poses ``t`` (m,), ``poses`` (m, 4, 4):
    translation linear, rotation slerp, clamped at the ends."""
    from scipy.spatial.transform import Rotation, Slerp

    t = np.asarray(t, float)
    m = np.asarray(poses, float)
    times = np.atleast_1d(np.asarray(times, float))
    order = np.argsort(t, kind="stable")
    t, m = t[order], m[order]
    t, first = np.unique(t, return_index=True)
    m = m[first]
    out = np.broadcast_to(np.eye(4), (times.size, 4, 4)).copy()
    if t.size == 1:
        out[:] = m[0]
        return out
    tc = np.clip(times, t[0], t[-1])
    for j in range(3):
        out[:, j, 3] = np.interp(tc, t, m[:, j, 3])
    out[:, :3, :3] = Slerp(t, Rotation.from_matrix(m[:, :3, :3]))(tc).as_matrix()
    return out


class TfBuffer:
    """Stamped links of a tf tree, filled from ``tf2_msgs/TFMessage`` messages.

    Examples
    --------
    >>> import numpy as np
    >>> buf = TfBuffer()
    >>> a = np.eye(4); a[0, 3] = 1.0
    >>> buf.add("map", "odom", 0.0, a, static=True)
    >>> b = np.eye(4); b[1, 3] = 2.0
    >>> buf.add("odom", "base_link", 0.0, b)
    >>> buf.lookup("map", "base_link", [0.0])[0, :2, 3].tolist()
    [1.0, 2.0]
    """

    def __init__(self) -> None:
        self.parents: dict[str, str] = {}
        self.static: set[tuple[str, str]] = set()
        self._t: dict[tuple[str, str], list[float]] = {}
        self._m: dict[tuple[str, str], list[np.ndarray]] = {}

    def add(self, parent: str, child: str, t: float, matrix: Any, static: bool = False) -> None:
        """Add ``T_parent_child`` (4, 4) stamped ``t`` (s); leading ``/`` are dropped."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if self.parents.setdefault(child, parent) != parent:
            return  # a second parent: tf2 rejects it too
        key = (parent, child)
        self._t.setdefault(key, []).append(float(t))
        self._m.setdefault(key, []).append(np.asarray(matrix, float))
        if static:
            self.static.add(key)

    def add_message(self, msg: Any, fallback_t: float, static: bool = False) -> None:
        """Add every transform of a ``TFMessage`` (a zero stamp reads as ``fallback_t``)."""
        for tr in msg.transforms:
            st = tr.header.stamp
            t = int(st.sec) + int(st.nanosec) * 1e-9
            self.add(
                str(tr.header.frame_id), str(tr.child_frame_id), t if t else fallback_t,
                transform_matrix(tr.transform.translation, tr.transform.rotation), static,
            )  # fmt: skip

    @property
    def frames(self) -> list[str]:
        """Every frame named by a link, sorted."""
        return sorted({f for k in self._t for f in k})

    def chain(self, target: str, source: str) -> list[tuple[str, str]] | None:
        """Links ``(parent, child)`` from ``target`` down to ``source``, or None when
        ``target`` is not an ancestor of ``source``."""
        links = []
        f = source
        seen = set()
        while f != target:
            if f not in self.parents or f in seen:
                return None
            seen.add(f)
            links.append((self.parents[f], f))
            f = self.parents[f]
        return links[::-1]

    def stamps(self, link: tuple[str, str]) -> np.ndarray:
        """Sorted distinct stamps (s) of a link."""
        return np.unique(np.asarray(self._t[link], float))

    def is_static(self, links: list[tuple[str, str]]) -> bool:
        return all(k in self.static for k in links)

    def lookup(self, target: str, source: str, times: Any) -> np.ndarray:
        """``T_target_source`` at ``times``: (T, 4, 4).

        Raises
        ------
        KeyError
            If no chain of links leads from ``target`` down to ``source``.
        """
        links = self.chain(target, source)
        if links is None:
            raise KeyError(f"no transform chain {target} -> ... -> {source}")
        times = np.atleast_1d(np.asarray(times, float))
        out = np.broadcast_to(np.eye(4), (times.size, 4, 4)).copy()
        for key in links:
            out = out @ interpolate_poses(self._t[key], np.stack(self._m[key]), times)
        return out
