"""ROS 2 conventions shared by the MCAP exports: REP-105 frame names, start times, messages.

The paper's frames keep their names in the Python API (``F_E``, ``F_R``, ``F_C``,
``F_A/<id>``); files meant for ROS tools use REP-105 names instead (:data:`ROS_FRAMES`):

===============  =========================  ============================================
paper            ROS (exports)              transform published on
===============  =========================  ============================================
``F_E``          ``map``                    (the fixed frame)
``F_R``          ``base_link``              ``/tf``: ``map -> base_link`` (moving)
``F_C``          ``camera_optical_frame``   ``/tf_static``: ``base_link -> camera``
``F_A/<id>``     ``artefact_<id>``          ``/tf``: ``map -> artefact_<id>`` (moving)
===============  =========================  ============================================

Messages are built with the ``rosbags`` ROS 2 Humble typestore, CDR-serialised and written
with the ``mcap`` writer, one ``ros2msg`` schema per type (the full definition with its
dependencies, as ``ros2 bag record`` writes it) and the ``offered_qos_profiles`` channel
metadata that ``ros2 bag play`` reads (transient local for ``/tf_static`` and maps, so
late subscribers such as rviz still get them).
"""

from __future__ import annotations

import datetime as _dt
import functools
import heapq
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from are_stats._atomic import atomic_path
from are_stats.environment import OccupancyGrid
from are_stats.inputs import InputError
from are_stats.logs import PassThrough

if TYPE_CHECKING:
    # the message classes of the type store the writer builds from (ROS 2 Humble)
    import rosbags.typesys.stores.ros2_humble as humble
    from rosbags.typesys.store import Typestore

__all__ = [
    "ROS_FRAMES",
    "RosMessages",
    "artefact_frame",
    "parse_start_time",
    "qos_profile",
    "quaternions",
]

#: Paper frame -> REP-105 frame name used in exports (``F_A/<id>`` -> :func:`artefact_frame`).
ROS_FRAMES: dict[str, str] = {
    "F_E": "map",
    "F_R": "base_link",
    "F_C": "camera_optical_frame",
}

#: Marker colours (r, g, b, a): perceived artefacts green, the others grey.
PERCEIVED_RGBA = (0.2, 0.8, 0.2, 0.8)
OCCLUDED_RGBA = (0.5, 0.5, 0.5, 0.5)

_QOS_VOLATILE = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
    "  deadline: {sec: 2147483647, nsec: 4294967295}\n"
    "  lifespan: {sec: 2147483647, nsec: 4294967295}\n  liveliness: 1\n"
    "  liveliness_lease_duration: {sec: 2147483647, nsec: 4294967295}\n"
    "  avoid_ros_namespace_conventions: false\n"
)
_QOS_LATCHED = _QOS_VOLATILE.replace("durability: 2", "durability: 1")
# Jazzy's spelling: names instead of enum integers, durations of rmw's infinity
_QOS_VOLATILE_STR = (
    "- history: unknown\n  depth: 0\n  reliability: reliable\n  durability: volatile\n"
    "  deadline: {sec: 9223372036, nsec: 854775807}\n"
    "  lifespan: {sec: 9223372036, nsec: 854775807}\n  liveliness: automatic\n"
    "  liveliness_lease_duration: {sec: 9223372036, nsec: 854775807}\n"
    "  avoid_ros_namespace_conventions: false\n"
)
_QOS_LATCHED_STR = _QOS_VOLATILE_STR.replace("durability: volatile", "durability: transient_local")


def qos_profile(latched: bool, form: str = "int") -> str:
    """The ``offered_qos_profiles`` channel metadata ``ros2 bag play`` reads: reliable,
    transient local when ``latched`` (late subscribers such as rviz still get the message)
    else volatile, spelt as Humble (``form="int"``, enum integers) or Jazzy (``"string"``)
    bags spell it."""
    if form == "string":
        return _QOS_LATCHED_STR if latched else _QOS_VOLATILE_STR
    return _QOS_LATCHED if latched else _QOS_VOLATILE


def artefact_frame(artefact_id: int) -> str:
    """REP-105-style frame name of artefact ``F_A/<id>``: ``artefact_<id>``."""
    return f"artefact_{int(artefact_id)}"


def parse_start_time(value: object, source: str = "--start-time") -> float:
    """A start time in seconds since the Unix epoch, from seconds or ISO 8601.

    Parameters
    ----------
    value : float, int or str
        Seconds (``1732480000.5``) or an ISO 8601 date-time (``2026-11-24T20:00:00Z``;
        without a zone it is read as UTC).
    source : str
        The option named in errors.

    Returns
    -------
    float
        Seconds since 1970-01-01 UTC (>= 0).

    Examples
    --------
    >>> parse_start_time("1970-01-01T00:01:00Z"), parse_start_time("12.5")
    (60.0, 12.5)
    """
    if isinstance(value, bool):
        raise InputError(source, "", "seconds or an ISO 8601 date-time", value)
    t: float | None = None
    if isinstance(value, int | float | np.integer | np.floating):
        t = float(value)
    elif isinstance(value, str):
        try:
            t = float(value)
        except ValueError:
            try:
                d = _dt.datetime.fromisoformat(value.strip().replace("Z", "+00:00"))
            except ValueError:
                raise InputError(
                    source, "", "seconds or an ISO 8601 date-time (2026-11-24T20:00:00Z)", value
                ) from None
            if d.tzinfo is None:
                d = d.replace(tzinfo=_dt.UTC)
            t = d.timestamp()
    if t is None or not math.isfinite(t) or t < 0 or t > 2**32:
        raise InputError(source, "", "a time between 1970 and 2106 (seconds or ISO 8601)", value)
    return t


def quaternions(rot: npt.ArrayLike) -> np.ndarray:
    """Unit quaternions ``(x, y, z, w)`` of rotation matrices, bit for bit SciPy's
    ``Rotation.from_matrix(rot).as_quat()`` (Markley's method, its branch and its order
    of operations) without its per-call overhead (a SciPy call per message was most of an
    export's CPU).

    Matrices that are not rotations to SciPy's tolerance (Gramian within ``1e-12`` of the
    identity, positive determinant) go to SciPy itself, which orthogonalises them (or
    refuses a left-handed one), as do those near its tolerance, so every input gives what
    SciPy gives.

    Parameters
    ----------
    rot : (..., 3, 3) float
        Rotation matrices.

    Returns
    -------
    (..., 4) float
        ``(x, y, z, w)``, scalar last.
    """
    m = np.array(rot, dtype=float)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices: expected shape (..., 3, 3), got {m.shape}")
    lead = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    if m.shape[0] <= _FEW:  # NumPy's per-call overhead would be most of it
        return np.array([_quaternion(r) for r in m.tolist()], float).reshape(*lead, 4)
    gram = m @ np.transpose(m, (0, 2, 1))
    # SciPy orthogonalises unless isclose(gram, I, atol=1e-12) (rtol 1e-5): a tenth of its
    # tolerances here, so that no rounding of the Gramian makes the two disagree
    eye = np.eye(3)
    valid = (np.abs(gram - eye) <= 1e-13 + 1e-6 * eye).all(axis=(1, 2))
    valid &= np.linalg.det(m) > 0
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    d = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], trace], 1)
    choice = np.argmax(d, axis=1)  # the first largest of the diagonal and the trace
    cand = np.empty((m.shape[0], 4, 4))  # each choice's quaternion
    for i in range(3):  # a diagonal entry leads
        j, k = (i + 1) % 3, (i + 2) % 3
        cand[:, i, i] = 1 - trace + 2 * m[:, i, i]
        cand[:, i, j] = m[:, j, i] + m[:, i, j]
        cand[:, i, k] = m[:, k, i] + m[:, i, k]
        cand[:, i, 3] = m[:, k, j] - m[:, j, k]
    cand[:, 3, 0] = m[:, 2, 1] - m[:, 1, 2]  # the trace leads
    cand[:, 3, 1] = m[:, 0, 2] - m[:, 2, 0]
    cand[:, 3, 2] = m[:, 1, 0] - m[:, 0, 1]
    cand[:, 3, 3] = 1 + trace
    q = cand[np.arange(m.shape[0]), choice]
    # SciPy's norm: the squares summed in order from 0, then one division per entry
    sq = q * q
    norm = np.sqrt(0.0 + sq[:, 0] + sq[:, 1] + sq[:, 2] + sq[:, 3])
    q /= norm[:, None]
    if not valid.all():
        # lazy: SciPy's Rotation adds 0.35 s CPU to `import are_stats.export`
        from scipy.spatial.transform import Rotation

        q[~valid] = Rotation.from_matrix(m[~valid]).as_quat()
    return q.reshape(*lead, 4)


#: Up to this many matrices, :func:`quaternions` converts one at a time in Python floats.
_FEW = 8


def _quaternion(m: list[list[float]]) -> tuple[float, float, float, float]:
    """:func:`quaternions` of one matrix in Python floats (the same operations in the same
    order, so the same bits); SciPy for one that is not a rotation to a tenth of its
    tolerance."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = m
    rows = ((a00, a01, a02), (a10, a11, a12), (a20, a21, a22))
    valid = True
    for i in range(3):
        for j in range(3):
            g = rows[i][0] * rows[j][0] + rows[i][1] * rows[j][1] + rows[i][2] * rows[j][2]
            eye = 1.0 if i == j else 0.0
            valid = valid and abs(g - eye) <= 1e-13 + 1e-6 * eye
    det = a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20)
    det += a02 * (a10 * a21 - a11 * a20)
    if not (valid and det > 0):
        # lazy: SciPy's Rotation adds 0.35 s CPU to `import are_stats.export`
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(np.array(m, float)).as_quat().tolist()
        return x, y, z, w
    trace = a00 + a11 + a22
    choice, top = 0, a00  # the first largest of the diagonal and the trace, as argmax
    for c, v in ((1, a11), (2, a22), (3, trace)):
        if v > top:
            choice, top = c, v
    q = [0.0, 0.0, 0.0, 0.0]
    if choice == 3:
        q = [a21 - a12, a02 - a20, a10 - a01, 1 + trace]
    else:
        i = choice
        j, k = (i + 1) % 3, (i + 2) % 3
        q[i] = 1 - trace + 2 * rows[i][i]
        q[j] = rows[j][i] + rows[i][j]
        q[k] = rows[k][i] + rows[i][k]
        q[3] = rows[k][j] - rows[j][k]
    norm = math.sqrt(0.0 + q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm


def _quat(rot: np.ndarray) -> tuple[float, float, float, float]:
    x, y, z, w = quaternions(rot)
    return float(x), float(y), float(z), float(w)


@functools.cache
def _humble() -> Typestore:
    """The ROS 2 Humble type store of every :class:`RosMessages`, one per process: rosbags
    generates a type's (de)serialiser code on its first use in a store (some 0.3 s CPU for an
    export's types), so a store per export paid it again every time. Only read (messages
    built from its classes, serialised); nothing registers types in it."""
    # lazy: rosbags' type store adds 0.07 s CPU to `import are_stats.export`
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


class RosMessages:
    """Collects ROS 2 messages by topic and time, then writes them to one MCAP file.

    Parameters
    ----------
    start : float
        Wall-clock time (s since the epoch) of the scenario clock's ``t = 0``: every stamp
        and log time is ``start + t``.
    frame : str
        Fixed frame (``header.frame_id`` of maps and markers).
    start_ns : int, optional
        ``start`` in integer nanoseconds, exact (a bag's start time); default
        ``round(start * 1e9)``.
    log_offset_ns : int
        Log times are the stamps plus this (ns): a bag's recording clock when the stamps
        are on another one (simulation time); default 0, the same clock.
    """

    def __init__(
        self,
        start: float = 0.0,
        frame: str = "map",
        start_ns: int | None = None,
        log_offset_ns: int = 0,
    ) -> None:
        self.start = float(start)
        self.start_ns = int(round(self.start * 1e9)) if start_ns is None else int(start_ns)
        self.frame = frame
        self.log_offset_ns = int(log_offset_ns)
        self.ts = _humble()
        self.T = self.ts.types
        self.topics: dict[str, str] = {}
        self.latched: set[str] = set()
        self._msgs: list[tuple[int, int, str, object]] = []

    # ---- building blocks --------------------------------------------------------------
    def ns(self, t: float) -> int:
        """Nanoseconds since the epoch of scenario time ``t``."""
        return self.start_ns + int(round(float(t) * 1e9))

    def stamp(self, t: float) -> humble.builtin_interfaces__msg__Time:
        n = self.ns(t)
        return self.T["builtin_interfaces/msg/Time"](sec=n // 10**9, nanosec=n % 10**9)

    def header(self, t: float, frame: str | None = None) -> humble.std_msgs__msg__Header:
        return self.T["std_msgs/msg/Header"](
            stamp=self.stamp(t), frame_id=self.frame if frame is None else frame
        )

    def pose(
        self, x: float, y: float, yaw: float, z: float = 0.0
    ) -> humble.geometry_msgs__msg__Pose:
        T = self.T
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z)),
            orientation=T["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
            ),
        )

    def transform(
        self, t: float, parent: str, child: str, matrix: npt.ArrayLike
    ) -> humble.geometry_msgs__msg__TransformStamped:
        """``geometry_msgs/TransformStamped`` of a (4, 4) parent-from-child transform."""
        return self.transforms(t, parent, [child], np.asarray(matrix, float)[None])[0]

    def transforms(
        self,
        t: float,
        parent: str,
        children: Sequence[str],
        matrices: npt.ArrayLike,
        times: npt.ArrayLike | None = None,
    ) -> list[humble.geometry_msgs__msg__TransformStamped]:
        """:meth:`transform` of every child, bit for bit, with the rotations of all
        converted at once (:func:`quaternions`).

        Parameters
        ----------
        t : float
            Stamp of all of them (scenario time), unless ``times`` is given.
        parent : str
        children : (n,) str
        matrices : (n, 4, 4) float
            Parent-from-child transforms.
        times : (n,) float, optional
            One stamp per child instead of ``t``.
        """
        T = self.T
        m = np.asarray(matrices, float).reshape(-1, 4, 4)
        if not m.shape[0]:
            return []
        q = quaternions(m[:, :3, :3]).tolist()
        xyz = m[:, :3, 3].tolist()
        if times is None:  # one header for all
            hdrs = [self.header(t, parent)] * m.shape[0]
        else:
            hdrs = [self.header(tk, parent) for tk in np.asarray(times, float).tolist()]
        TS, Tr = T["geometry_msgs/msg/TransformStamped"], T["geometry_msgs/msg/Transform"]
        V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        return [
            TS(
                header=hdr,
                child_frame_id=child,
                transform=Tr(translation=V(x=x, y=y, z=z), rotation=Q(x=qx, y=qy, z=qz, w=qw)),
            )
            for hdr, child, (x, y, z), (qx, qy, qz, qw) in zip(hdrs, children, xyz, q, strict=True)
        ]

    def planar(
        self, t: float, parent: str, child: str, x: float, y: float, yaw: float, z: float = 0.0
    ) -> humble.geometry_msgs__msg__TransformStamped:
        """``TransformStamped`` of a planar pose ``(x, y, yaw)`` at height ``z``."""
        return self.planars(t, parent, [child], [[x, y, z]], [yaw])[0]

    def planars(
        self,
        t: float,
        parent: str,
        children: Sequence[str],
        xyz: npt.ArrayLike,
        yaws: npt.ArrayLike,
        times: npt.ArrayLike | None = None,
    ) -> list[humble.geometry_msgs__msg__TransformStamped]:
        """:meth:`planar` of every child (``xyz`` (n, 3) m, ``yaws`` (n,) rad; ``times``
        (n,) s, one per child, instead of ``t``), bit for bit (:meth:`transforms`)."""
        p = np.asarray(xyz, float).reshape(-1, 3)
        yaw = np.asarray(yaws, float).reshape(-1)
        # math.cos/sin, as before (NumPy's may differ in the last bit)
        c = np.array([math.cos(a) for a in yaw.tolist()])
        s = np.array([math.sin(a) for a in yaw.tolist()])
        m = np.zeros((yaw.size, 4, 4))
        m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1] = c, -s, s, c
        m[:, 2, 2] = m[:, 3, 3] = 1.0
        m[:, :3, 3] = p
        return self.transforms(t, parent, children, m, times)

    def occupancy_grid(self, t: float, grid: OccupancyGrid) -> humble.nav_msgs__msg__OccupancyGrid:
        T = self.T
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=self.stamp(t),
            resolution=float(grid.resolution),
            width=grid.width,
            height=grid.height,
            origin=self.pose(grid.origin[0], grid.origin[1], grid.origin[2]),
        )
        return T["nav_msgs/msg/OccupancyGrid"](
            header=self.header(t), info=info, data=np.asarray(grid.data).ravel().astype(np.int8)
        )

    def marker(
        self,
        t: float,
        ns: str,
        mid: int,
        mtype: int,
        pose: npt.ArrayLike,
        scale: npt.ArrayLike,
        rgba: npt.ArrayLike,
        *,
        action: int = 0,
        text: str = "",
        frame: str | None = None,
        lifetime: float = 0.0,
    ) -> humble.visualization_msgs__msg__Marker:
        """``visualization_msgs/Marker`` (type 1 cube, 2 sphere, 9 text; action 3 deletes
        all; ``lifetime`` seconds, 0 for ever)."""
        T = self.T
        life = int(round(max(float(lifetime), 0.0) * 1e9))
        empty = np.zeros(0, np.uint8)
        return T["visualization_msgs/msg/Marker"](
            header=self.header(t, frame),
            ns=ns,
            id=int(mid),
            type=int(mtype),
            action=action,
            pose=pose,
            scale=T["geometry_msgs/msg/Vector3"](
                x=float(scale[0]), y=float(scale[1]), z=float(scale[2])
            ),
            color=T["std_msgs/msg/ColorRGBA"](
                r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3])
            ),
            lifetime=T["builtin_interfaces/msg/Duration"](sec=life // 10**9, nanosec=life % 10**9),
            frame_locked=False,
            points=[],
            colors=[],
            texture_resource="",
            texture=T["sensor_msgs/msg/CompressedImage"](
                header=self.header(t, frame), format="", data=empty
            ),
            uv_coordinates=[],
            text=str(text),
            mesh_resource="",
            mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=empty),
            mesh_use_embedded_materials=False,
        )

    def artefact_markers(
        self,
        t: float,
        ids: npt.ArrayLike,
        centres: npt.ArrayLike,
        half: npt.ArrayLike,
        yaws: npt.ArrayLike,
        labels: Sequence[str],
        perceived: npt.ArrayLike,
        lifetime: float = 0.0,
    ) -> humble.visualization_msgs__msg__MarkerArray:
        """``MarkerArray``: a DELETEALL, then per artefact a cube (ns ``artefacts``; green
        perceived, grey otherwise) and its class label as text above it (ns ``labels``),
        both living ``lifetime`` seconds (0: until replaced), so that a replay stopped or
        started half-way leaves no ghost.

        Parameters
        ----------
        ids : (n,) int
        centres : (n, 3) float
        half : (n, 3) float
            Half extents.
        yaws : (n,) float
        labels : (n,) str
        perceived : (n,) bool
        """
        # built as :meth:`marker` builds each (the same fields, values and bytes), with what
        # every marker of the array shares made once: the header (stamp and frame), the
        # empty texture and mesh, the lifetime, the labels' size and colour
        T = self.T
        ms = [self.marker(t, "", 0, 0, self.pose(0, 0, 0), (1, 1, 1), (0, 0, 0, 0), action=3)]
        n = len(ids)
        if not n:
            return T["visualization_msgs/msg/MarkerArray"](markers=ms)
        Marker, Pose = T["visualization_msgs/msg/Marker"], T["geometry_msgs/msg/Pose"]
        Point, Quat = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
        Vector3, Color = T["geometry_msgs/msg/Vector3"], T["std_msgs/msg/ColorRGBA"]
        hdr = self.header(t)
        empty = np.zeros(0, np.uint8)
        texture = T["sensor_msgs/msg/CompressedImage"](header=hdr, format="", data=empty)
        mesh = T["visualization_msgs/msg/MeshFile"](filename="", data=empty)
        life = int(round(max(float(lifetime), 0.0) * 1e9))
        duration = T["builtin_interfaces/msg/Duration"](sec=life // 10**9, nanosec=life % 10**9)
        colours = {
            seen: Color(r=float(c[0]), g=float(c[1]), b=float(c[2]), a=float(c[3]))
            for seen, c in ((True, PERCEIVED_RGBA), (False, OCCLUDED_RGBA))
        }
        text_scale = Vector3(x=0.0, y=0.0, z=0.4)
        white = Color(r=1.0, g=1.0, b=1.0, a=1.0)
        upright = Quat(x=0.0, y=0.0, z=math.sin(0.0 / 2), w=math.cos(0.0 / 2))

        def marker(
            ns: str, mid: int, mtype: int, pose: object, scale: object, colour: object, text: str
        ) -> object:
            return Marker(
                header=hdr,
                ns=ns,
                id=mid,
                type=mtype,
                action=0,
                pose=pose,
                scale=scale,
                color=colour,
                lifetime=duration,
                frame_locked=False,
                points=[],
                colors=[],
                texture_resource="",
                texture=texture,
                uv_coordinates=[],
                text=text,
                mesh_resource="",
                mesh_file=mesh,
                mesh_use_embedded_materials=False,
            )

        c_all = np.asarray(centres, float).reshape(n, 3).tolist()
        h_all = np.asarray(half, float).reshape(n, 3).tolist()
        for k in range(n):
            (cx, cy, cz), (hx, hy, hz) = c_all[k], h_all[k]
            yaw = yaws[k]  # as given: a float32 yaw is halved in float32, as pose() did
            seen = bool(perceived[k])
            aid = int(ids[k])
            cube = Pose(
                position=Point(x=cx, y=cy, z=cz),
                orientation=Quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
            )
            size = Vector3(x=2 * hx, y=2 * hy, z=2 * hz)
            ms.append(marker("artefacts", aid, 1, cube, size, colours[seen], ""))
            label = f"{labels[k]} {aid}" + ("" if seen else " (occluded)")
            above = Pose(position=Point(x=cx, y=cy, z=cz + hz + 0.3), orientation=upright)
            ms.append(marker("labels", aid, 9, above, text_scale, white, label))
        return T["visualization_msgs/msg/MarkerArray"](markers=ms)

    def tf(
        self, transforms: list[humble.geometry_msgs__msg__TransformStamped]
    ) -> humble.tf2_msgs__msg__TFMessage:
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)

    # ---- collecting and writing -------------------------------------------------------
    def add(
        self, t: float, topic: str, msgtype: str, msg: object, *, latched: bool = False
    ) -> None:
        """Queue ``msg`` on ``topic`` at scenario time ``t`` (log time ``start + t`` plus
        the log offset)."""
        if self.topics.setdefault(topic, msgtype) != msgtype:
            raise ValueError(f"topic {topic}: expected {self.topics[topic]}, got {msgtype}")
        if latched:
            self.latched.add(topic)
        self._msgs.append((self.ns(t) + self.log_offset_ns, len(self._msgs), topic, msg))

    def counts(self) -> Mapping[str, int]:
        out: dict[str, int] = {}
        for _, _, topic, _ in self._msgs:
            out[topic] = out.get(topic, 0) + 1
        return out

    def write(
        self,
        path: str | os.PathLike,
        *,
        force: bool = False,
        passthrough: PassThrough | None = None,
    ) -> Path:
        """Write the queued messages, sorted by time, to ``path`` (atomically).

        ``passthrough`` (:class:`~are_stats.logs.PassThrough`): an input bag's channels,
        copied first and unchanged (schemas, metadata, bytes, log and publish times,
        sequences), its messages streamed and merged by log time with the queued ones;
        the new channels then spell QoS as the input does and carry a ``topic_type_hash``
        when its channels do.
        """
        # lazy: mcap's writer adds 0.06 s CPU to `import are_stats.export`
        from mcap.writer import Writer

        form = "int" if passthrough is None else passthrough.qos_form
        hashed = passthrough is not None and passthrough.type_hash
        target = Path(path)
        with atomic_path(target, force=force) as tmp, open(tmp, "wb") as fh:
            w = Writer(fh)
            w.start(profile="ros2", library="are_stats")
            schemas: dict[tuple[str, str, bytes], int] = {}

            def schema(name: str, encoding: str, data: bytes) -> int:
                if not encoding:
                    return 0
                key = (name, encoding, data)
                if key not in schemas:
                    schemas[key] = w.register_schema(name=name, encoding=encoding, data=data)
                return schemas[key]

            inputs: list[int] = []
            for ch in [] if passthrough is None else passthrough.channels:
                meta = dict(ch.metadata)
                if not meta.get("offered_qos_profiles"):
                    meta["offered_qos_profiles"] = qos_profile(ch.latched, form)
                inputs.append(
                    w.register_channel(
                        topic=ch.topic,
                        message_encoding=ch.message_encoding,
                        schema_id=schema(ch.msgtype, ch.schema_encoding, ch.schema),
                        metadata=meta,
                    )
                )
            channels: dict[str, int] = {}
            for topic, typ in self.topics.items():
                sid = schema(
                    typ, "ros2msg", self.ts.generate_msgdef(typ, ros_version=2)[0].encode()
                )
                meta = {"offered_qos_profiles": qos_profile(topic in self.latched, form)}
                if hashed:
                    meta["topic_type_hash"] = self.ts.hash_rihs01(typ)
                channels[topic] = w.register_channel(
                    topic=topic, message_encoding="cdr", schema_id=sid, metadata=meta
                )
            ours = (
                (ns, 1, seq, channels[topic], msg, topic)
                for seq, (ns, _, topic, msg) in enumerate(sorted(self._msgs, key=lambda m: m[:2]))
            )
            theirs = (
                (log, 0, seq, inputs[k], (pub, data), None)
                for log, pub, seq, k, data in (
                    () if passthrough is None else passthrough.messages()
                )
            )
            for ns, mine, seq, cid, msg, topic in heapq.merge(
                theirs, ours, key=lambda r: (r[0], r[1])
            ):
                if mine:
                    pub, data = ns, bytes(self.ts.serialize_cdr(msg, self.topics[topic]))
                else:
                    pub, data = msg
                w.add_message(
                    channel_id=cid, log_time=ns, publish_time=pub, sequence=seq, data=data
                )
            w.finish()
        return target
