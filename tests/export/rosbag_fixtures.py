"""Small robot bags written with rosbags (ROS 1 ``.bag``, ROS 2 folder, MCAP) for the
augmentation tests: a robot driving along the courtyard's free corridor, as ``/tf``
(``map -> odom -> base_link``), as pose topics and with a camera on ``/tf_static``.

Variants: header stamps on a simulation clock (``header_start``) while the recording times
stay on the wall clock (as Nav2's simulation tutorials record), one message stamped in 1970
(``outlier``), one pose or transform with a given orientation or position (``bad``)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

#: Wall-clock time of the bags' first message (s since the epoch).
START = 1_732_480_000.0
#: Seconds of driving.
DURATION = 12.0
#: Camera intrinsics of the ``/camera/camera_info`` topic (small, for fast tests).
CAMERA = {"k": [60.0, 0.0, 40.0, 0.0, 60.0, 30.0, 0.0, 0.0, 1.0], "width": 80, "height": 60}
#: The camera mount of ``/tf_static``: base_link -> camera_link -> camera_optical_frame.
CAMERA_XYZ = (0.2, 0.0, 1.2)
#: ``T_parent_base`` of the static parent a ``base_parent`` bag gives ``base_link``
#: (``base_footprint -> base_link``): offset, lifted and turned, so that a wrong
#: composition shows.
BASE_PARENT_XYZ = (0.05, -0.02, 0.1)
BASE_PARENT_YAW = 0.3
#: A simulation clock's start (s): Gazebo's clock, some minutes after it started.
SIM_START = 1234.5
#: The index ``k`` (a tenth of a second) of the message an ``outlier`` or ``bad`` variant
#: changes, and the 1970 stamp (s) an outlier gets.
ODD_K = 37
OUTLIER_STAMP = 5.25


@contextmanager
def fit_read_once(fit: Path) -> Iterator[None]:
    """While open, ``are_stats.fitting.read_fit`` reads the file ``fit`` once and then
    returns that same (frozen) :class:`~are_stats.fitting.Fit` while the file is unchanged
    (same size and modification time); any other path is read as always.

    The augment tests run ``augment`` some 70 times on one fixture fit, most of them to see
    a bag refused: each run read the fit again (0.6 s CPU, most of such a run). What is
    tested of reading fits is tested in ``tests/fitting``; a test here that reads another fit
    (an older format, no area) still reads it.
    """
    import are_stats.fitting as fitting

    real = fitting.read_fit
    target = fit.resolve()
    cache: dict[tuple[int, int], object] = {}

    def read_fit(path):
        p = Path(path)
        if not (p.is_file() and p.resolve() == target):
            return real(path)
        st = p.stat()
        key = (st.st_mtime_ns, st.st_size)
        if key not in cache:
            cache.clear()
            cache[key] = real(path)
        return cache[key]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fitting, "read_fit", read_fit)
        yield


def robot_pose(t: float) -> tuple[float, float, float]:
    """Map pose ``(x, y, yaw)`` of the robot ``t`` seconds after :data:`START`."""
    return -15.0 + 0.5 * t, -10.0 + 0.05 * t, 0.1


#: Header stamps are ``header_start + t`` (:func:`bag_messages` sets it per bag).
_CLOCK = {"start": START}


def stamp_ns(t: float, start: float = START) -> int:
    """Integer nanoseconds of ``start + t`` (the fixture's stamps and recording times)."""
    return int(round((start + t) * 1e9))


def _time(T, t: float, absolute: bool = False):
    n = int(round(t * 1e9)) if absolute else stamp_ns(t, _CLOCK["start"])
    return T["builtin_interfaces/msg/Time"](sec=n // 10**9, nanosec=n % 10**9)


def _header(T, t: float, frame: str, ros1: bool, absolute: bool = False):
    if ros1:
        return T["std_msgs/msg/Header"](seq=0, stamp=_time(T, t, absolute), frame_id=frame)
    return T["std_msgs/msg/Header"](stamp=_time(T, t, absolute), frame_id=frame)


def _quat(T, yaw: float, pitch: float = 0.0, roll: float = 0.0, q=None):
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_quat() if q is None else q
    return T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)


def _tf(T, t, parent, child, xyz, yaw=0.0, pitch=0.0, roll=0.0, ros1=False, q=None, at=None):
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(T, t, parent, ros1) if at is None else _header(T, at, parent, ros1, True),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=_quat(T, yaw, pitch, roll, q),
        ),
    )


def _pose(T, x, y, yaw, q=None):
    return T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=_quat(T, yaw, q=q)
    )


def bag_messages(
    T,
    ros1: bool = False,
    tf: bool = True,
    poses: bool = True,
    camera: bool = True,
    pose_frame: str = "map",
    header_start: float = START,
    outlier: bool = False,
    bad: tuple | None = None,
    map_tf: bool = True,
    extra: str | None = None,
    decoy: bool = False,
    base_parent: str | None = None,
):
    """``(t, topic, msgtype, message)`` of the test bag, in time order (``t`` s after
    :data:`START`, the recording time).

    ``header_start``: header stamps are ``header_start + t`` (a simulation clock when it
    differs from :data:`START`). ``outlier``: message :data:`ODD_K` of ``/tf`` (its
    ``odom -> base_link``) and of the pose topics is stamped :data:`OUTLIER_STAMP` (1970).
    ``bad``: ``(x, y, quaternion)`` of that message's pose and transform. ``map_tf``:
    ``/tf`` has ``map -> odom`` (else odometry only). ``extra``: a ``std_msgs/String``
    topic of that name besides. ``decoy``: ``/tf_static`` first mounts another optical
    frame, ``left_camera_optical_frame`` (an OAK-D's left mono camera), 0.1 m left of
    the base, before the ``CameraInfo``'s camera. ``base_parent``: ``/tf_static`` also gives
    ``base_link`` that static parent (:data:`BASE_PARENT_XYZ`, :data:`BASE_PARENT_YAW`; a
    TurtleBot's ``base_footprint``); with ``drop=("/tf",)`` of :func:`write_bag` (else
    ``/tf``'s ``odom -> base_link`` would be a second parent).
    """
    _CLOCK["start"] = header_start
    out = []
    odom = (1.0, -0.5, 0.0)  # map -> odom offset: the composition must undo it
    if tf:
        out.append(
            (
                0.0,
                "/tf_static",
                "tf2_msgs/msg/TFMessage",
                T["tf2_msgs/msg/TFMessage"](
                    transforms=[
                        *(
                            [
                                _tf(
                                    T,
                                    0.0,
                                    "base_link",
                                    "left_camera_optical_frame",
                                    (0, 0.1, 0.3),
                                    -math.pi / 2,
                                    0,
                                    -math.pi / 2,
                                    ros1=ros1,
                                )
                            ]
                            if decoy
                            else []
                        ),
                        *(
                            [
                                _tf(
                                    T,
                                    0.0,
                                    base_parent,
                                    "base_link",
                                    BASE_PARENT_XYZ,
                                    BASE_PARENT_YAW,
                                    ros1=ros1,
                                )
                            ]
                            if base_parent is not None
                            else []
                        ),
                        _tf(T, 0.0, "base_link", "camera_link", CAMERA_XYZ, ros1=ros1),
                        _tf(
                            T,
                            0.0,
                            "camera_link",
                            "camera_optical_frame",
                            (0, 0, 0),
                            -math.pi / 2,
                            0,
                            -math.pi / 2,
                            ros1=ros1,
                        ),
                    ]
                ),
            )
        )
    for k in range(int(DURATION * 10) + 1):
        t = k / 10.0
        x, y, yaw = robot_pose(t)
        q, at = None, None
        if k == ODD_K and bad is not None:
            x, y, q = bad
        if k == ODD_K and outlier:
            at = OUTLIER_STAMP
        if tf:
            tfs = [
                _tf(T, t, "odom", "base_link", (x - odom[0], y - odom[1], 0.0), yaw, ros1=ros1,
                    q=q, at=at)
            ]  # fmt: skip
            if k % 10 == 0 and map_tf:
                tfs.append(_tf(T, t, "map", "odom", odom, ros1=ros1))
            out.append(
                (t, "/tf", "tf2_msgs/msg/TFMessage", T["tf2_msgs/msg/TFMessage"](transforms=tfs))
            )
        if poses:
            hdr = (
                _header(T, t, pose_frame, ros1)
                if at is None
                else _header(T, at, pose_frame, ros1, True)
            )
            out.append(
                (
                    t,
                    "/robot_pose",
                    "geometry_msgs/msg/PoseStamped",
                    T["geometry_msgs/msg/PoseStamped"](header=hdr, pose=_pose(T, x, y, yaw, q)),
                )
            )
            cov = T["geometry_msgs/msg/PoseWithCovariance"](
                pose=_pose(T, x, y, yaw, q), covariance=np.zeros(36)
            )
            out.append(
                (
                    t,
                    "/amcl_pose",
                    "geometry_msgs/msg/PoseWithCovarianceStamped",
                    T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=hdr, pose=cov),
                )
            )
        if extra is not None and k % 10 == 0:
            out.append((t, extra, "std_msgs/msg/String", T["std_msgs/msg/String"](data=f"{k}")))
        if camera and k % 5 == 0:
            out.append(
                (t, "/camera/camera_info", "sensor_msgs/msg/CameraInfo", _camera_info(T, t, ros1))
            )
    return out


def _camera_info(T, t: float, ros1: bool):
    roi = T["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    k = np.asarray(CAMERA["k"], float)
    p = np.zeros(12)
    p[[0, 1, 2, 4, 5, 6, 8, 9, 10]] = k
    common = dict(
        header=_header(T, t, "camera_optical_frame", ros1),
        height=CAMERA["height"],
        width=CAMERA["width"],
        distortion_model="plumb_bob",
        binning_x=0,
        binning_y=0,
        roi=roi,
    )
    if ros1:
        return T["sensor_msgs/msg/CameraInfo"](
            **common, D=np.zeros(5), K=k, R=np.eye(3).ravel(), P=p
        )
    return T["sensor_msgs/msg/CameraInfo"](**common, d=np.zeros(5), k=k, r=np.eye(3).ravel(), p=p)


def write_bag(
    path: Path,
    kind: str,
    outlier_log: bool = False,
    damaged: str | None = None,
    drop: tuple[str, ...] = (),
    **which,
) -> Path:
    """Write the test bag as ``kind`` ``"ros1"`` (``path`` a ``.bag``), ``"ros2"`` (a folder,
    sqlite3) or ``"mcap"`` (a ROS 2 folder with MCAP storage; its ``.mcap`` file is
    returned). ``which`` goes to :func:`bag_messages`; ``outlier_log`` also records the
    outlier messages at :data:`OUTLIER_STAMP` (1970); ``damaged`` (ROS 1 only) adds a
    ``std_msgs/String`` topic of that name whose one message is undecodable bytes;
    ``drop``: topics left out (``("/tf",)``: ``/tf_static`` without ``/tf``)."""
    from rosbags.typesys import Stores, get_typestore

    def log_ns(t: float, topic: str) -> int:
        odd = outlier_log and round(t * 10) == ODD_K and topic != "/camera/camera_info"
        return stamp_ns(OUTLIER_STAMP, 0.0) if odd else stamp_ns(t)

    ros1 = kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:  # the Noetic store has no tf2_msgs: register it as a ROS 1 robot bag has it
        from rosbags.typesys import get_types_from_msg

        ts.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    msgs = [m for m in bag_messages(ts.types, ros1=ros1, **which) if m[1] not in drop]
    if ros1:
        from rosbags.rosbag1 import Writer

        with Writer(path) as w:
            conns = {}
            for t, topic, typ, msg in msgs:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=ts)
                w.write(conns[topic], log_ns(t, topic), ts.serialize_ros1(msg, typ))
            if damaged is not None:  # a string of length 2^31 - 1 in 7 bytes
                c = w.add_connection(damaged, "std_msgs/msg/String", typestore=ts)
                w.write(c, stamp_ns(1.0), b"\xff\xff\xff\x7fabc")
        return path
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for t, topic, typ, msg in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], log_ns(t, topic), ts.serialize_cdr(msg, typ))
    if kind == "mcap":
        return next(Path(path).glob("*.mcap"))
    return path


_HUMBLE_QOS = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
    "  deadline: {sec: 2147483647, nsec: 4294967295}\n"
    "  lifespan: {sec: 2147483647, nsec: 4294967295}\n  liveliness: 1\n"
    "  liveliness_lease_duration: {sec: 2147483647, nsec: 4294967295}\n"
    "  avoid_ros_namespace_conventions: false\n"
)


def jazzy_mcap(src: Path, dst: Path) -> Path:
    """A copy of the MCAP ``src`` as a Jazzy recorder writes it: QoS spelt with names
    (``reliable``, ``transient_local``) and a ``topic_type_hash`` per channel."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    names = {
        "reliability: 1": "reliability: reliable",
        "reliability: 2": "reliability: best_effort",
        "durability: 1": "durability: transient_local",
        "durability: 2": "durability: volatile",
    }
    with open(src, "rb") as fi, open(dst, "wb") as fo:
        r = make_reader(fi)
        summary = r.get_summary()
        w = Writer(fo)
        w.start(profile="ros2", library="jazzy-like")
        sid = {k: w.register_schema(s.name, s.encoding, s.data) for k, s in summary.schemas.items()}
        cid = {}
        for k, c in summary.channels.items():
            latched = c.topic == "/tf_static"
            qos = c.metadata.get("offered_qos_profiles", "")
            if qos.strip() in ("", "[]"):  # rosbags writes none
                qos = _HUMBLE_QOS.replace(
                    "durability: 2", "durability: 1" if latched else "durability: 2"
                )
            for a, b in names.items():
                qos = qos.replace(a, b)
            name = summary.schemas[c.schema_id].name
            meta = {"offered_qos_profiles": qos, "topic_type_hash": ts.hash_rihs01(name)}
            cid[k] = w.register_channel(c.topic, c.message_encoding, sid[c.schema_id], meta)
        for _, c, m in r.iter_messages(log_time_order=True):
            w.add_message(cid[c.id], m.log_time, m.data, m.publish_time, m.sequence)
        w.finish()
    return dst
