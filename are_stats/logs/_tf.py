"""A small tf2-like transform buffer for bags: ``/tf`` and ``/tf_static`` without ROS.

Each link ``parent -> child`` keeps its stamped transforms; a lookup composes the chain
between two frames of the tree and interpolates every moving link at the asked times
(translation linearly, rotation by slerp, held constant outside its stamps, as a tf2
lookup with extrapolation clamped). A frame has one parent, as in tf2: a second parent for
a frame is ignored. Transforms are checked as tf2 checks them: finite translations and
rotations, quaternions of unit norm within :data:`QUATERNION_TOLERANCE` (renormalised);
anything else is an :class:`~are_stats.inputs.InputError` naming the message.
"""

from __future__ import annotations

import math
from typing import Any  # Any: a TFMessage of a bag, a class rosbags builds at run time

import numpy as np
import numpy.typing as npt

from are_stats.inputs import Described, InputError, Source

__all__ = [
    "QUATERNION_TOLERANCE",
    "TF_TYPE",
    "TF_TYPES",
    "TfBuffer",
    "interpolate_poses",
    "transform_matrix",
    "unit_quaternion",
]

#: Message type of ``/tf`` and ``/tf_static``.
TF_TYPE = "tf2_msgs/msg/TFMessage"
#: Types read as tf messages: tf2's and the old ROS 1 ``tf/tfMessage`` (same fields).
TF_TYPES = (TF_TYPE, "tf/msg/tfMessage")


#: A quaternion ``q`` is a rotation when ``| |q|^2 - 1 | < QUATERNION_TOLERANCE`` (tf2's
#: ``QUATERNION_NORMALIZATION_TOLERANCE``: beyond it tf2 refuses the transform as
#: ``TF_DENORMALIZED_QUATERNION``); within it, ``q`` is renormalised.
QUATERNION_TOLERANCE = 1e-2


def unit_quaternion(
    rotation: npt.ArrayLike, source: Source = "transform", where: str = ""
) -> np.ndarray:
    """``(x, y, z, w)`` (4,) float of a ROS quaternion, renormalised.

    Parameters
    ----------
    rotation : object
        With fields ``x, y, z, w`` (a ``geometry_msgs/Quaternion``).
    source, where : str
        The input and the place in it (a topic and message), named in errors.

    Raises
    ------
    are_stats.inputs.InputError
        If a component is not finite, or ``| |q|^2 - 1 |`` is not below
        :data:`QUATERNION_TOLERANCE`.
    """
    q = np.array([rotation.x, rotation.y, rotation.z, rotation.w], float)
    if not np.isfinite(q).all():
        raise InputError(source, where, "a finite quaternion", Described(f"{q.tolist()}"))
    n2 = float(q @ q)
    if not abs(n2 - 1.0) < QUATERNION_TOLERANCE:
        raise InputError(
            source,
            where,
            f"a unit quaternion (| |q|^2 - 1 | < {QUATERNION_TOLERANCE:g}, as tf2 checks)",
            Described(f"{q.tolist()} of norm {math.sqrt(n2):.6g}"),
        )
    return q / math.sqrt(n2)


def transform_matrix(
    translation: npt.ArrayLike,
    rotation: npt.ArrayLike,
    source: Source = "transform",
    where: str = "",
) -> np.ndarray:
    """(4, 4) transform of a ROS translation (``x, y, z``) and quaternion (``x, y, z, w``)
    (a ``geometry_msgs/Transform``'s fields or a ``Pose``'s ``position, orientation``).

    Raises
    ------
    are_stats.inputs.InputError
        Naming ``source`` and ``where``, if the translation is not finite or the
        quaternion is not a unit one (:func:`unit_quaternion`).
    """
    xyz = np.array([translation.x, translation.y, translation.z], float)
    if not np.isfinite(xyz).all():
        raise InputError(source, where, "a finite position", Described(f"{xyz.tolist()}"))
    m = np.eye(4)
    m[:3, :3] = _quaternion_matrix(unit_quaternion(rotation, source, where))
    m[:3, 3] = xyz
    return m


def _quaternion_matrix(q: npt.ArrayLike) -> list[list[float]]:
    """Rotation matrix of a nonzero quaternion ``(x, y, z, w)``, bit for bit SciPy's
    ``Rotation.from_quat(q).as_matrix()`` (normalised as it does, then its formula and
    order of operations) in Python floats: a bag's reader calls it per transform, where
    SciPy's per-call overhead was most of the reading.

    Parameters
    ----------
    q : (4,) float
        Finite, nonzero.

    Returns
    -------
    (3, 3) list of float
    """
    x, y, z, w = (float(v) for v in np.asarray(q, float).reshape(4))
    n = math.sqrt(0.0 + x * x + y * y + z * z + w * w)
    if not (n > 0.0 and math.isfinite(n)):
        raise ValueError(f"quaternion: expected finite and nonzero, got {[x, y, z, w]}")
    x, y, z, w = x / n, y / n, z / n, w / n
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return [
        [x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
        [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
        [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2],
    ]


def interpolate_poses(t: npt.ArrayLike, poses: npt.ArrayLike, times: npt.ArrayLike) -> np.ndarray:
    """Poses ``(T, 4, 4)`` at ``times`` from stamped poses ``t`` (m,), ``poses`` (m, 4, 4):
    translation linear, rotation slerp, clamped at the ends."""
    # lazy: SciPy's Rotation adds 0.54 s CPU to `import are_stats.logs`
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

    def add(
        self, parent: str, child: str, t: float, matrix: npt.ArrayLike, static: bool = False
    ) -> None:
        """Add ``T_parent_child`` (4, 4) stamped ``t`` (s); leading ``/`` are dropped."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if self.parents.setdefault(child, parent) != parent:
            return  # a second parent: tf2 rejects it too
        key = (parent, child)
        self._t.setdefault(key, []).append(float(t))
        self._m.setdefault(key, []).append(np.asarray(matrix, float))
        if static:
            self.static.add(key)

    def add_message(
        self,
        msg: Any,
        fallback_t: float,
        static: bool = False,
        source: Source = "tf",
        where: str = "",
    ) -> None:
        """Add every transform of a ``TFMessage`` (a zero stamp reads as ``fallback_t``).

        Raises
        ------
        are_stats.inputs.InputError
            Naming ``source``, ``where`` (the topic and message) and the link, if a
            transform is not finite or its quaternion is not a unit one.
        """
        for k, tr in enumerate(msg.transforms):
            st = tr.header.stamp
            t = int(st.sec) + int(st.nanosec) * 1e-9
            parent, child = str(tr.header.frame_id), str(tr.child_frame_id)
            place = f"{where + ', ' if where else ''}transform {k} ({parent} -> {child})"
            m = transform_matrix(tr.transform.translation, tr.transform.rotation, source, place)
            self.add(parent, child, t if t else fallback_t, m, static)

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

    def static_parents(self, frame: str) -> list[str]:
        """The frames above ``frame`` through static links (``/tf_static``), nearest first:
        ``["base_footprint"]`` for ``base_footprint -> base_link``; empty when ``frame``
        has no static parent. The last one is the root of the static chain (its own parent,
        if any, is a moving link)."""
        f = start = frame.lstrip("/")
        out: list[str] = []
        while (p := self.parents.get(f)) is not None and (p, f) in self.static:
            if p == start or p in out:  # a loop of static links
                break
            out.append(p)
            f = p
        return out

    def stamps(self, link: tuple[str, str]) -> np.ndarray:
        """Sorted distinct stamps (s) of a link."""
        return np.unique(np.asarray(self._t[link], float))

    def is_static(self, links: list[tuple[str, str]]) -> bool:
        return all(k in self.static for k in links)

    def lookup(self, target: str, source: str, times: npt.ArrayLike) -> np.ndarray:
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
