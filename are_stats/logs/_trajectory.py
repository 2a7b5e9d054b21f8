"""A robot's recorded trajectory from a bag: base poses on one clock, and its camera.

:func:`read_trajectory` reads the robot's base poses in the map frame from a ROS 1 bag,
a ROS 2 bag or an MCAP file (``rosbags``, no ROS install): either the ``/tf`` tree (the
``map -> ... -> base_link`` chain composed at the stamps of its moving links, each link
interpolated linearly in translation and by slerp in rotation, static links from
``/tf_static``), or a pose topic of type ``geometry_msgs/PoseStamped``,
``geometry_msgs/PoseWithCovarianceStamped`` or ``nav_msgs/Odometry``. The camera mount
``T_base_optical`` is read from ``/tf_static`` when the bag holds a static chain from the
base to the camera's optical frame (the ``CameraInfo`` frame, or ``camera_frame``).
Header stamps and recording times are put on one clock (:data:`CLOCKS`).
"""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple  # Any: a bag message's header (rosbags builds its class)

import numpy as np

from are_stats.inputs import Described, InputError, check_memory, get_str
from are_stats.logs._bag_reader import bag_reader
from are_stats.logs._rosbag import (
    bag_messages,
    bag_read_errors,
    check_bag_path,
    check_stamps,
    vision_msgs_typestore,
)
from are_stats.logs._tf import TF_TYPES, TfBuffer, transform_matrix

__all__ = [
    "CLOCKS",
    "CLOCK_TOLERANCE",
    "POSE_TYPES",
    "BagTrajectory",
    "TrajectoryOptions",
    "read_trajectory",
]

_POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
_POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"
_ODOM = "nav_msgs/msg/Odometry"
_TF = "tf2_msgs/msg/TFMessage"  # are_stats.logs.TF_TYPE
_CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
#: Message types a ``pose_topic`` may have.
POSE_TYPES = (_POSE_STAMPED, _POSE_COV, _ODOM)
#: ``--clock`` choices: ``auto`` (header stamps when the messages have them), ``header``
#: (header stamps) or ``log`` (the recording times).
CLOCKS = ("auto", "header", "log")
#: Header stamps and recording times further apart than this (s) are two clocks.
CLOCK_TOLERANCE = 5.0
#: Bytes held per pose, transform or camera stamp read from a bag (limits check).
BYTES_PER_RECORD = 600.0


class BagTrajectory(NamedTuple):
    """A robot's recorded trajectory and what the bag says about its camera.

    Attributes
    ----------
    t : (m,) float
        Pose times, seconds since the epoch on :attr:`clock`, increasing.
    poses : (m, 4, 4) float
        ``T_map_base`` at each time.
    start, end : float
        The first and last pose or camera times (s since the epoch, on :attr:`clock`).
    mount : (4, 4) float or None
        ``T_base_optical`` from ``/tf_static``, when the bag has it.
    camera_frame : str or None
        The optical frame's name (from ``CameraInfo`` or ``/tf_static``).
    camera_times : (k,) float or None
        Times of the ``CameraInfo`` messages (the camera's frames, on :attr:`clock`,
        sorted), when a topic was read.
    camera_info : dict or None
        ``k``, ``width``, ``height`` of the first ``CameraInfo`` message.
    source : str
        Where the poses came from (``/tf map -> base_link`` or the topic).
    start_ns : int
        ``start`` in nanoseconds, exact.
    t_ns : (m,) int64 or None
        ``t`` in nanoseconds, exact (the input's stamps).
    camera_ns : (k,) int64 or None
        ``camera_times`` in nanoseconds, exact.
    clock : str
        ``"header"`` (header stamps) or ``"log"`` (recording times).
    clock_note : str
        Which clock was read and why (and how far apart the two are).
    frame : str
        The fixed frame the poses are in: ``map_frame``, or ``odom`` for a bag whose tree
        has no map frame (odometry only).
    frame_note : str
        Why the poses are in :attr:`frame` when it is not ``map_frame`` (else ``""``).
    offset_ns : int
        Header stamps minus recording times (ns, the median over the stamped messages):
        the shift from the recording clock onto the header clock.
    base_parents : tuple of str
        The frames above the base frame through ``/tf_static`` links, nearest first
        (``("base_footprint",)`` for a TurtleBot's ``base_footprint -> base_link``); empty
        when the base has no static parent. The last one is the root of the base's static
        chain.
    root_from_base : (4, 4) float or None
        ``T_root_base``: the static transform from that root down to the base (None when
        :attr:`base_parents` is empty). ``poses @ inv(root_from_base)`` places the root.
    """

    t: np.ndarray
    poses: np.ndarray
    start: float
    end: float
    mount: np.ndarray | None
    camera_frame: str | None
    camera_times: np.ndarray | None
    camera_info: dict | None
    source: str
    start_ns: int = 0
    t_ns: np.ndarray | None = None
    camera_ns: np.ndarray | None = None
    clock: str = "log"
    clock_note: str = ""
    frame: str = "map"
    frame_note: str = ""
    offset_ns: int = 0
    base_parents: tuple[str, ...] = ()
    root_from_base: np.ndarray | None = None

    @property
    def since_start(self) -> np.ndarray:
        """(m,) float: the pose times in seconds after :attr:`start`, from the exact
        nanosecond stamps (:attr:`t_ns`, else :attr:`t` rounded to nanoseconds)."""
        t_ns = self.t_ns if self.t_ns is not None else np.round(self.t * 1e9).astype(np.int64)
        return (t_ns - self.start_ns) * 1e-9


def _ns(header: Any) -> int:
    """A header's stamp in integer nanoseconds (0: unset)."""
    st = header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def _topics_text(by_topic: dict[str, str]) -> str:
    return ", ".join(f"{t} ({ty})" for t, ty in sorted(by_topic.items())) or "none"


def _clock_choice(p: Path, clock: str, hdr: np.ndarray, log: np.ndarray) -> tuple[str, int, str]:
    """``(clock, offset_ns, note)``: the clock read (``header`` or ``log``), the median of
    header stamp minus recording time (ns, over the stamped messages) and why."""
    stamped = hdr != 0
    offset = int(np.median(hdr[stamped] - log[stamped])) if stamped.any() else 0
    gap = offset * 1e-9
    apart = abs(gap) > CLOCK_TOLERANCE
    differ = (
        f"header stamps and recording times differ by {gap:+.6g} s"
        + (" (simulation time?)" if abs(gap) > 86400.0 else "")
        if apart
        else f"header stamps within {CLOCK_TOLERANCE:g} s of the recording times"
    )
    if clock == "log":
        return "log", offset, f"recording times (--clock log; {differ})"
    if not stamped.any():
        if clock == "header":
            raise InputError(
                p,
                "--clock header",
                "header stamps on the poses (or --clock log)",
                Described("only zero stamps"),
            )
        return "log", 0, "recording times (the messages carry no header stamps)"
    why = "--clock header" if clock == "header" else "the default"
    other = "; --clock log reads the recording times instead" if apart else ""
    return "header", offset, f"header stamps ({why}; {differ}{other})"


class TrajectoryOptions(NamedTuple):
    """How a bag's robot is read: the options ``augment`` and ``serve --bag`` share.

    The fields are :func:`read_trajectory`'s keywords, in the order the commands declare
    them, so a command builds one from its parsed options in one line and every layer below
    (``run_augment`` -> :func:`~are_stats.export.augment_bag`, ``run_serve`` ->
    :func:`~are_stats.export.serve_robot` -> :func:`~are_stats.export.robot_from_bag` ->
    :func:`read_trajectory`) passes it on
    whole instead of repeating six keywords.

    Attributes
    ----------
    pose_topic : str or None
        Poses from this topic instead of ``/tf`` (``--pose-topic``).
    base_frame : str or None
        The robot's ``/tf`` frame (``--base-frame``); ``None``: not given, ``base_link``.
    map_frame : str
        The fixed frame (``--map-frame``).
    camera_info_topic : str or None
        The ``CameraInfo`` topic (``--camera-info-topic``).
    clock : {"auto", "header", "log"}
        The one clock (``--clock``, :data:`CLOCKS`).
    camera_frame : str or None
        The camera's frame in the bag's tree (``--camera-frame``).

    Examples
    --------
    >>> TrajectoryOptions(None, None, "map", "/camera/camera_info").keywords()["base_frame"]
    'base_link'
    >>> TrajectoryOptions(clock="log").given()
    {'--clock': 'log'}
    """

    pose_topic: str | None = None
    base_frame: str | None = None
    map_frame: str = "map"
    camera_info_topic: str | None = None
    clock: str = "auto"
    camera_frame: str | None = None

    def given(self) -> dict[str, str]:
        """The options set away from their defaults, by command-line flag.

        Returns
        -------
        dict
            ``{"--pose-topic": ..., ...}`` for each option given (for a command that
            refuses bag options without a bag).
        """
        default = TrajectoryOptions()
        return {
            "--" + name.replace("_", "-"): value
            for name, value in self._asdict().items()
            if value != getattr(default, name)
        }

    def checked(self) -> TrajectoryOptions:
        """These options, when they name one source of poses.

        Raises
        ------
        are_stats.inputs.InputError
            When both ``pose_topic`` and ``base_frame`` are given (``--pose-topic`` and
            ``--base-frame``: two sources of the robot's poses).
        """
        if self.pose_topic is not None and self.base_frame is not None:
            raise InputError("--pose-topic", "", "either --pose-topic or --base-frame", "both")
        return self

    def keywords(self) -> dict[str, str | None]:
        """:func:`read_trajectory`'s keywords (``base_frame`` ``base_link`` when not given)."""
        return {**self._asdict(), "base_frame": self.base_frame or "base_link"}

    def read(self, bag: str | os.PathLike) -> BagTrajectory:
        """:func:`read_trajectory` of ``bag`` with these options."""
        return read_trajectory(bag, **self.keywords())


def read_trajectory(
    bag: str | os.PathLike,
    *,
    pose_topic: str | None = None,
    base_frame: str = "base_link",
    map_frame: str = "map",
    camera_info_topic: str | None = None,
    clock: str = "auto",
    camera_frame: str | None = None,
) -> BagTrajectory:
    """The robot's base poses in the map frame, from a ROS 1 / ROS 2 bag or an MCAP file.

    Parameters
    ----------
    bag : path
        ``*.bag`` (ROS 1), a ROS 2 bag folder or a ``*.mcap`` / ``*.db3`` file (a regular
        file: a FIFO or a device is refused at once).
    pose_topic : str, optional
        Read the poses from this topic (:data:`POSE_TYPES`; its ``frame_id`` should be the
        map frame; in a bag without a ``map`` frame, ``odom`` reads it in ``odom``, as
        :attr:`BagTrajectory.frame_note` says) instead of ``/tf``.
    base_frame, map_frame : str
        The ``/tf`` frames composed into ``T_map_base`` (``map -> ... -> base_link``). A
        tree without the default ``map`` frame but with ``odom -> ... -> base_frame``
        (odometry only) is read in ``odom`` (:attr:`BagTrajectory.frame_note` says so).
    camera_info_topic : str, optional
        A ``sensor_msgs/CameraInfo`` topic: its intrinsics, frame and stamps.
    camera_frame : str, optional
        The camera's optical frame in the bag's tree (default the ``CameraInfo``'s
        ``header.frame_id``); :attr:`BagTrajectory.mount` is the static chain from the base
        to it. Without either the bag's tree gives no mount (no frame is guessed by name).
    clock : {"auto", "header", "log"}
        The one clock of poses, ``/tf`` and camera frames: ``header`` their header stamps
        (a zero stamp reads as its recording time moved onto the header clock), ``log`` the
        recording times; ``auto`` (default) the header stamps when the messages have them.
        When the two disagree by more than :data:`CLOCK_TOLERANCE` seconds (simulation time
        recorded on the wall clock) :attr:`BagTrajectory.clock_note` says so.

    Returns
    -------
    BagTrajectory

    Raises
    ------
    FileNotFoundError
        If ``bag`` does not exist.
    are_stats.inputs.InputError
        Naming the bag and topic: not a regular file or ROS 2 bag folder, a missing topic
        (the topics present are listed), a topic of the wrong type, a bag without poses (no
        ``/tf`` chain from ``map_frame`` to ``base_frame``), a camera-info topic without
        messages, a non-finite pose or transform, a quaternion that is not a unit one
        (:data:`~are_stats.logs.QUATERNION_TOLERANCE`), a stamp far off the others of its
        topic (:func:`~are_stats.logs.check_stamps`: a header stamp's message placed by its
        recording time into the bag, the stamps with their dates), more messages than the
        memory limit.
    """
    clock = get_str(clock, "--clock", "", choices=CLOCKS)
    p = check_bag_path(bag)
    errors = bag_read_errors()
    # (header stamp ns, 0 when unset; recording time ns) of every pose and camera message;
    # every /tf transform as (parent, child, header ns, recording ns, matrix, static, message)
    pose_hl: list[tuple[int, int]] = []
    pose_m: list[np.ndarray] = []
    cam_hl: list[tuple[int, int]] = []
    tfs: list[tuple[str, str, int, int, np.ndarray, bool, int]] = []
    cam_info: dict | None = None
    cam_frame: str | None = None
    pose_frames: set[str] = set()  # the pose topic's frames: the map's, or odom's
    try:
        with bag_reader(
            [p], default_typestore=partial(vision_msgs_typestore, 1 if p.suffix == ".bag" else 2)
        ) as reader:
            bag_start = int(reader.start_time)  # recording times into the bag in errors
            by_topic: dict[str, str] = {}
            for c in reader.connections:
                by_topic.setdefault(c.topic, c.msgtype)
            wanted: list[str] = []
            for topic, types, what in (
                (pose_topic, POSE_TYPES, "--pose-topic"),
                (camera_info_topic, (_CAMERA_INFO,), "--camera-info-topic"),
            ):
                if topic is None:
                    continue
                if topic not in by_topic:
                    raise InputError(
                        p,
                        f"{what} {topic}",
                        "a topic of the bag",
                        Described(f"no such topic; topics: {_topics_text(by_topic)}"),
                    )
                if by_topic[topic] not in types:
                    raise InputError(
                        p,
                        f"topic {topic}",
                        f"a message type in {', '.join(types)}",
                        by_topic[topic],
                    )
                wanted.append(topic)
            tf_topics = [t for t in ("/tf", "/tf_static") if by_topic.get(t) in TF_TYPES]
            if pose_topic is None and "/tf" not in tf_topics:
                raise InputError(
                    p,
                    "",
                    f"robot poses: a /tf topic ({_TF}) or --pose-topic with a topic of "
                    f"type {', '.join(POSE_TYPES)}",
                    Described(f"topics: {_topics_text(by_topic)}"),
                )
            conns = [c for c in reader.connections if c.topic in (*wanted, *tf_topics)]
            n_index = float(sum(max(int(c.msgcount or 0), 0) for c in conns))
            what = "the poses, transforms and camera stamps read from the bag"
            check_memory(n_index * BYTES_PER_RECORD, f"{what} ({n_index:.0f} messages)", p)
            counts: dict[str, int] = {}
            for conn, ts, msg in bag_messages(reader, conns, p):
                n = counts[conn.topic] = counts.get(conn.topic, 0) + 1
                where = f"topic {conn.topic}, message {n}"
                if n % 100_000 == 0:  # the index may undercount: check as the lists grow
                    held = len(pose_hl) + len(cam_hl) + len(tfs)
                    check_memory(held * BYTES_PER_RECORD, f"{what} ({held} records)", p)
                if conn.topic in tf_topics:
                    static = conn.topic == "/tf_static"
                    for k, tr in enumerate(msg.transforms):
                        parent = str(tr.header.frame_id).lstrip("/")
                        child = str(tr.child_frame_id).lstrip("/")
                        m = transform_matrix(
                            tr.transform.translation,
                            tr.transform.rotation,
                            p,
                            f"{where}, transform {k} ({parent} -> {child})",
                        )
                        tfs.append((parent, child, _ns(tr.header), int(ts), m, static, n))
                elif conn.topic == pose_topic:
                    pose = msg.pose.pose if conn.msgtype in (_POSE_COV, _ODOM) else msg.pose
                    frame = str(msg.header.frame_id).lstrip("/")
                    if frame and frame != map_frame and (frame, map_frame) != ("odom", "map"):
                        raise InputError(
                            p,
                            f"topic {pose_topic}, header.frame_id",
                            f"poses in the map frame {map_frame!r} (or read /tf with --base-frame)",
                            frame,
                        )
                    pose_frames.add(frame or map_frame)
                    pose_hl.append((_ns(msg.header), int(ts)))
                    pose_m.append(transform_matrix(pose.position, pose.orientation, p, where))
                else:  # camera info
                    cam_hl.append((_ns(msg.header), int(ts)))
                    if cam_info is None:
                        cam_frame = str(msg.header.frame_id).lstrip("/") or None
                        k = getattr(msg, "k", None)  # ROS 1 spells it K
                        k = msg.K if k is None else k
                        cam_info = {
                            "k": [float(v) for v in np.asarray(k).ravel()],
                            "width": int(msg.width),
                            "height": int(msg.height),
                        }
    except errors as err:
        raise ValueError(
            f"{p}: expected a readable ROS 1 / ROS 2 bag or MCAP file, got: "
            f"{type(err).__name__}: {err}"
        ) from None
    if camera_info_topic is not None and not cam_hl:
        raise InputError(
            p, f"topic {camera_info_topic}", "at least one CameraInfo message", Described("none")
        )
    if pose_topic is not None and not pose_hl:
        raise InputError(p, f"topic {pose_topic}", "at least one pose message", Described("none"))
    # one clock for everything: the poses (or moving transforms) and camera frames decide
    moving_tf = [r for r in tfs if not r[5]]
    hl = np.array([*pose_hl, *cam_hl, *((r[2], r[3]) for r in moving_tf)], np.int64).reshape(-1, 2)
    clock, offset, note = _clock_choice(p, clock, hl[:, 0], hl[:, 1])

    def on_clock(h: int, lg: int) -> int:
        return lg if clock == "log" else (h if h else lg + offset)

    fixed, frame_note = map_frame, ""
    tf = TfBuffer()
    link_ns: dict[tuple[str, str], list[int]] = {}
    link_msg: dict[tuple[str, str], list[int]] = {}
    link_log: dict[tuple[str, str], list[int]] = {}
    for parent, child, h, lg, m, static, n in tfs:
        t_ns = on_clock(h, lg)
        tf.add(parent, child, t_ns * 1e-9, m, static)
        if tf.parents.get(child) == parent:
            link_ns.setdefault((parent, child), []).append(t_ns)
            link_msg.setdefault((parent, child), []).append(n)
            link_log.setdefault((parent, child), []).append(lg)

    def into_bag(log_ns: list[int] | np.ndarray) -> np.ndarray | None:
        """Recording times (ns) as seconds into the bag, to place a header stamp refused by
        :func:`check_stamps`; None on the recording clock, where the recording time is the
        stamp refused (a bag whose start is then an outlier's: its date says more)."""
        if clock == "log":
            return None
        return (np.asarray(log_ns, np.int64) - bag_start) * 1e-9

    del tfs, moving_tf
    if pose_topic is not None:
        if map_frame == "map" and "odom" in pose_frames:  # odometry: an odometry-only bag
            if len(pose_frames) > 1 or "map" in tf.frames:
                raise InputError(
                    p,
                    f"topic {pose_topic}, header.frame_id",
                    f"poses in the map frame {fixed!r} (or read /tf with --base-frame, or "
                    "--map-frame odom for odometry)",
                    Described(
                        f"'odom' in a bag whose tree has a frame {fixed!r}"
                        if len(pose_frames) == 1
                        else f"frames {', '.join(sorted(pose_frames))} mixed"
                    ),
                )
            map_frame = "odom"
            frame_note = (
                f"the bag has no frame {fixed!r} and {pose_topic} is in 'odom': poses and "
                "artefacts in 'odom' (odometry only; pass --map-frame to name another fixed frame)"
            )
        ns = np.array([on_clock(h, lg) for h, lg in pose_hl], np.int64)
        rec = into_bag([lg for _, lg in pose_hl])
        check_stamps(ns * 1e-9, p, f"topic {pose_topic}", recorded=rec)
        order = np.argsort(ns, kind="stable")
        t_ns = ns[order]
        poses = np.stack(pose_m)[order]
        source = pose_topic
    else:
        links = tf.chain(map_frame, base_frame)
        if links is None and map_frame == "map" and "map" not in tf.frames:
            odom = tf.chain("odom", base_frame)
            if odom is not None:  # odometry only: no map frame in the tree
                links, map_frame = odom, "odom"
                frame_note = (
                    f"the bag's tree has no frame {fixed!r}: poses and artefacts in 'odom' "
                    "(odometry only; pass --map-frame to name another fixed frame)"
                )
        if links is None:
            raise InputError(
                p,
                "topic /tf",
                f"a chain of transforms {map_frame} -> ... -> {base_frame} "
                "(or pass --pose-topic / --base-frame)",
                Described(f"frames {', '.join(tf.frames) or 'none'}"),
            )
        moving = [k for k in links if k not in tf.static]
        for k in moving:
            check_stamps(
                np.asarray(link_ns[k]) * 1e-9,
                p,
                f"topic /tf, {k[0]} -> {k[1]}",
                link_msg[k],
                recorded=into_bag(link_log[k]),
            )
        # the stamps of the moving link nearest the base (odom -> base_link, usually)
        t_ns = np.unique(np.asarray(link_ns[moving[-1] if moving else links[-1]], np.int64))
        poses = tf.lookup(map_frame, base_frame, t_ns * 1e-9)
        source = f"/tf {map_frame} -> {base_frame}"
    keep = np.r_[True, np.diff(t_ns) > 0]
    t_ns, poses = t_ns[keep], poses[keep]
    cam_ns = None
    if cam_hl:
        cam_ns = np.array([on_clock(h, lg) for h, lg in cam_hl], np.int64)
        rec = into_bag([lg for _, lg in cam_hl])
        check_stamps(cam_ns * 1e-9, p, f"topic {camera_info_topic}", recorded=rec)
        cam_ns = np.sort(cam_ns)
    ends = [t_ns[[0, -1]]] + ([cam_ns[[0, -1]]] if cam_ns is not None else [])
    start_ns, end_ns = int(min(e[0] for e in ends)), int(max(e[1] for e in ends))
    above = tf.static_parents(base_frame)
    mount = None
    cam_frame = camera_frame.lstrip("/") if camera_frame else cam_frame
    if cam_frame:
        links = tf.chain(base_frame, cam_frame)
        if links and tf.is_static(links):
            mount = tf.lookup(base_frame, cam_frame, 0.0)[0]
        elif camera_frame:
            raise InputError(
                p,
                f"--camera-frame {camera_frame}",
                f"a frame of the bag's tree with a static chain {base_frame} -> ... -> "
                f"{cam_frame} (/tf_static)",
                Described(f"frames {', '.join(tf.frames) or 'none'}"),
            )
    return BagTrajectory(
        t_ns * 1e-9,
        poses,
        start_ns * 1e-9,
        end_ns * 1e-9,
        mount,
        cam_frame,
        None if cam_ns is None else cam_ns * 1e-9,
        cam_info,
        source,
        start_ns,
        t_ns,
        cam_ns,
        clock,
        note,
        map_frame,
        frame_note,
        int(offset),
        tuple(above),
        tf.lookup(above[-1], base_frame, 0.0)[0] if above else None,
    )
