"""Robot bag in, augmented bag out: the ARE loop along a recorded robot trajectory.

:func:`read_trajectory` reads the robot's base poses in the map frame from a ROS 1 bag,
a ROS 2 bag or an MCAP file (``rosbags``, no ROS install): either the ``/tf`` tree (the
``map -> ... -> base_link`` chain composed at the stamps of its moving links, each link
interpolated linearly in translation and by slerp in rotation, static links from
``/tf_static``), or a pose topic of type ``geometry_msgs/PoseStamped``,
``geometry_msgs/PoseWithCovarianceStamped`` or ``nav_msgs/Odometry``. The camera mount
``T_base_optical`` is read from ``/tf_static`` when the bag holds a static chain from the
base to an optical frame (the ``CameraInfo`` frame, or a frame named ``*optical*``).

:func:`augment_bag` generates a scenario from a fit over the bag's time span (the models
the fit chose, with behaviour tracks so that artefacts move), and at every camera frame
registers the artefacts alive then with the AR-builder (the augmented grid), computes A_f
from the recorded camera pose (DECISIONS 8) and the robot's contacts with the boxes. It
writes an MCAP holding the input's channels unchanged
(:func:`~are_stats.logs.bag_passthrough`) and only what is new (:data:`AUGMENT_TOPICS`:
``map -> artefact_<id>`` on ``/tf``, markers, maps, A_f), stamped on the input's header
clock and logged on its recording clock, so that ``ros2 bag play`` replays the one file.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from are_stats._atomic import check_writable
from are_stats.experiments._ros import ROS_FRAMES, RosMessages, artefact_frame
from are_stats.inputs import (
    Described,
    InputError,
    check_memory,
    check_work,
    get_float,
    get_seed,
    get_str,
)

__all__ = [
    "AUGMENT_TOPICS",
    "CLOCKS",
    "CLOCK_TOLERANCE",
    "POSE_TYPES",
    "AugmentResult",
    "BagTrajectory",
    "augment_bag",
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
#: Bytes held per camera frame besides the maps (times, poses, markers, messages).
BYTES_PER_FRAME = 2000.0

#: Topic -> ROS 2 message type written by :func:`augment_bag`.
AUGMENT_TOPICS = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/augmented_map": "nav_msgs/msg/OccupancyGrid",
    "/artefacts": "visualization_msgs/msg/MarkerArray",
    "/perceived": "std_msgs/msg/String",
    "/tf": _TF,
    "/tf_static": _TF,
}


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


class AugmentResult(NamedTuple):
    """Outcome of :func:`augment_bag`.

    Attributes
    ----------
    path : Path
        The MCAP written.
    times : (T,) float
        Camera frame times on the scenario clock (s after ``start``).
    start : float
        The bag's start (s since the epoch): scenario time 0.
    camera_poses : (T, 4, 4) float
        ``T_map_optical`` at each frame.
    scene : Scene
        The generated artefacts (with their behaviour tracks).
    counts : (T, N) int64
        Unoccluded pixels per frame and artefact (scene order).
    perceived : (T, N) bool
        A_f per frame.
    contacts : (T, N) bool
        The robot's footprint overlaps the artefact's box.
    topics : dict of str to int
        Messages written per topic.
    clock : str
        The clock read (``"header"`` or ``"log"``).
    clock_note : str
        Which clock was read and why.
    frame : str
        The fixed frame of the artefacts (``map``, or ``odom`` in an odometry-only bag).
    frame_note : str
        Why it is not the map frame (else ``""``).
    passed : dict of str to int
        Messages copied from the input per topic (pass-through).
    """

    path: Path
    times: np.ndarray
    start: float
    camera_poses: np.ndarray
    scene: Any
    counts: np.ndarray
    perceived: np.ndarray
    contacts: np.ndarray
    topics: dict
    clock: str = "log"
    clock_note: str = ""
    frame: str = "map"
    frame_note: str = ""
    passed: dict = {}  # noqa: RUF012 (a NamedTuple default, never mutated)


# ---- reading ------------------------------------------------------------------------------


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
        map frame) instead of ``/tf``.
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
        topic (:func:`~are_stats.logs.check_stamps`), more messages than the memory limit.
    """
    from rosbags.highlevel import AnyReader

    from are_stats.logs import (
        TF_TYPES,
        TfBuffer,
        bag_messages,
        bag_read_errors,
        check_bag_path,
        check_stamps,
        transform_matrix,
        vision_msgs_typestore,
    )

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
    try:
        with AnyReader(
            [p], default_typestore=vision_msgs_typestore(1 if p.suffix == ".bag" else 2)
        ) as reader:
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
                    if frame and frame != map_frame:
                        raise InputError(
                            p,
                            f"topic {pose_topic}, header.frame_id",
                            f"poses in the map frame {map_frame!r} (or read /tf with --base-frame)",
                            frame,
                        )
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
    for parent, child, h, lg, m, static, n in tfs:
        t_ns = on_clock(h, lg)
        tf.add(parent, child, t_ns * 1e-9, m, static)
        if tf.parents.get(child) == parent:
            link_ns.setdefault((parent, child), []).append(t_ns)
            link_msg.setdefault((parent, child), []).append(n)
    del tfs, moving_tf
    if pose_topic is not None:
        ns = np.array([on_clock(h, lg) for h, lg in pose_hl], np.int64)
        check_stamps(ns * 1e-9, p, f"topic {pose_topic}")
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
                np.asarray(link_ns[k]) * 1e-9, p, f"topic /tf, {k[0]} -> {k[1]}", link_msg[k]
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
        check_stamps(cam_ns * 1e-9, p, f"topic {camera_info_topic}")
        cam_ns = np.sort(cam_ns)
    ends = [t_ns[[0, -1]]] + ([cam_ns[[0, -1]]] if cam_ns is not None else [])
    start_ns, end_ns = int(min(e[0] for e in ends)), int(max(e[1] for e in ends))
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
    )


# ---- the loop -----------------------------------------------------------------------------


def augment_bag(
    bag: str | os.PathLike,
    fit: str | os.PathLike,
    map_path: str | os.PathLike,
    out: str | os.PathLike,
    seed: int,
    *,
    pose_topic: str | None = None,
    base_frame: str = "base_link",
    map_frame: str = "map",
    camera: Any = None,
    camera_info_topic: str | None = None,
    mount: Any = None,
    period: float = 0.5,
    d_max: float = 10.0,
    tau: float = 10.0,
    robot_radius: float = 0.3,
    behaviour_cell: float = 1.0,
    behaviour_dt: float = 2.0,
    wall_height: float = 2.5,
    catalogue: Any = None,
    force: bool = False,
    clock: str = "auto",
    model: str = "chosen",
    topics: Any = None,
    camera_frame: str | None = None,
) -> AugmentResult:
    """Augment a robot's recorded run with generated artefacts and write an MCAP.

    The output carries the input's channels unchanged (:func:`~are_stats.logs.bag_passthrough`:
    same schemas, bytes, counts and log times; a ROS 1 bag converted to
    ROS 2 CDR) plus only what is new: ``map -> artefact_<id>`` on ``/tf``, the markers of
    ``/artefacts`` (living until the next camera frame and a bit), ``/augmented_map``,
    ``/perceived`` and ``/map`` when the input has none. The robot's tree is the input's;
    only a bag without ``/tf`` (a pose topic) gets ``map -> base_link`` and the static
    camera mount published, so that the output can still be viewed. The new channels
    spell QoS as the input does and carry ``topic_type_hash`` when the input's do.

    Parameters
    ----------
    bag : path
        The robot's bag (ROS 1 ``.bag``, ROS 2 folder or ``.mcap``).
    fit : path
        A fit written by ``are-stats fit`` (its chosen models generate the scenario).
    map_path : path
        ROS map YAML of the map the trajectory is in.
    out : path
        The ``.mcap`` to write (atomically).
    seed : int
        Seed of the scenario and behaviour tracks (same seed, same file).
    pose_topic : str, optional
        Pose topic instead of ``/tf`` (see :func:`read_trajectory`).
    base_frame, map_frame : str
        Frames of the ``/tf`` chain.
    camera : PinholeCamera or path, optional
        Intrinsics (a camera YAML); with neither ``camera`` nor ``camera_info_topic`` the
        shipped ``front_camera``.
    camera_info_topic : str, optional
        ``sensor_msgs/CameraInfo`` topic: intrinsics and frame times from the bag.
    camera_frame : str, optional
        The camera's optical frame in the bag's tree (default the ``CameraInfo``'s frame);
        the mount is the bag's static chain from the base to it.
    mount : (4, 4) float, optional
        ``T_base_optical``; default the bag's ``/tf_static``, else the camera file's pose
        when it has one, else :func:`~are_stats.perception.optical_from_base` 1 m above
        the base looking forward.
    period : float
        Seconds between camera frames when the bag gives none (``camera`` from a file);
        frames cover the stretches of the trajectory, not the gaps of more than
        :data:`~are_stats.logs.STAMP_GAP` seconds between them.
    d_max, tau : float
        Range and threshold of A_f.
    robot_radius : float
        Footprint radius (m) for the robot's contacts with artefacts.
    behaviour_cell, behaviour_dt : float
        Grid cell (m) and epoch (s) of the behaviour tracks.
    wall_height : float
        Height (m) of the walls extruded from the map (environment mesh S_3D).
    catalogue : ArtefactCatalogue, optional
        The property table Q (default the shipped one).
    force : bool
        Overwrite ``out``.
    clock : {"auto", "header", "log"}
        The one clock of poses, camera frames and the scenario's start
        (:func:`read_trajectory`); the output keeps the input's stamps on that clock.
    model : {"chosen", "paper"}
        Generate from the traffic models the fit chose or from the paper's (Poisson,
        exponential, uniform positions: for a fit whose learned entries belong to another
        map), as ``generate --model``.
    topics : sequence of str, optional
        The input topics passed through (default all of them).

    Returns
    -------
    AugmentResult

    Raises
    ------
    are_stats.inputs.InputError
        A bag without poses, an unknown topic, a bad pose or stamp (see
        :func:`read_trajectory`), a trajectory outside the map, a fit without area, no
        artefact alive in any camera frame (with why and what to try), an existing ``out``
        without ``force`` (``OutputExistsError``).
    are_stats.inputs.LimitError
        Camera frames (``period``), tracing or messages past the memory or work limits,
        checked before anything of that size is allocated.
    """

    from are_stats.builder import ARBuilder
    from are_stats.environment import OccupancyGrid, extrude_grid, load_catalogue
    from are_stats.experiments._robot import circle_box_overlap
    from are_stats.experiments._sweep import _map_file
    from are_stats.fitting import read_fit
    from are_stats.logs import STAMP_GAP, interpolate_poses
    from are_stats.perception import PinholeCamera, optical_from_base, perceive_scene
    from are_stats.scenarios import scenes_from_fit

    seed = get_seed(seed)
    model = get_str(model, "--model", "", choices=("chosen", "paper"))
    period = get_float(period, "--period", "", lo=0.0, lo_open=True)
    d_max = get_float(d_max, "--d-max", "", lo=0.0, lo_open=True, hi=1e6)
    tau = get_float(tau, "--tau", "", lo=0.0)
    clock = get_str(clock, "--clock", "", choices=CLOCKS)
    if camera is not None and camera_info_topic is not None:
        raise InputError("--camera", "", "either --camera or --camera-info-topic", "both")
    out = check_writable(out, force)
    map_file = _map_file(str(map_path))
    if map_file is None:
        raise InputError(
            "--map", "", "a ROS map YAML or a shipped map name (courtyard)", str(map_path)
        )
    grid = OccupancyGrid.from_ros_yaml(map_file)
    idata = read_fit(fit)
    if "area" not in idata.posterior.attrs:
        raise InputError(
            fit,
            "posterior.attrs",
            "the fit's area (m^2; a fit of are-stats fit)",
            Described("none"),
        )
    from are_stats.logs import bag_passthrough

    traj = read_trajectory(
        bag,
        pose_topic=pose_topic,
        base_frame=base_frame,
        map_frame=map_frame,
        camera_info_topic=camera_info_topic,
        clock=clock,
        camera_frame=camera_frame,
    )
    passthrough = bag_passthrough(bag, None if topics is None else list(topics))
    clash = sorted(
        {c.topic for c in passthrough.channels} & (set(AUGMENT_TOPICS) - {"/tf", "/tf_static"})
    )
    if clash:
        raise InputError(
            bag,
            f"topic {clash[0]}",
            f"input topics other than the ones augment writes ({', '.join(AUGMENT_TOPICS)})",
            Described(f"{', '.join(clash)} in the bag; leave them out with --topics"),
        )
    fixed = traj.frame
    xy = traj.poses[:, :2, 3]
    outside = ~grid.in_bounds(grid.world_to_cell(xy))
    if outside.any():
        i = int(np.argmax(outside))
        raise InputError(
            bag,
            f"{traj.source}, pose at {traj.t[i]:.3f} s",
            f"robot poses inside the map {map_path} (corners "
            f"{np.round(grid.corners_world[[0, 2]], 3).tolist()})",
            Described(
                f"({xy[i, 0]:.3f}, {xy[i, 1]:.3f}); {int(outside.sum())} of {len(xy)} poses outside"
            ),
        )
    # times on the scenario clock: seconds after the trajectory's start, from exact stamps
    start, start_ns = traj.start, traj.start_ns
    t_ns = traj.t_ns if traj.t_ns is not None else np.round(traj.t * 1e9).astype(np.int64)
    pose_t = (t_ns - start_ns) * 1e-9
    # the camera: intrinsics, frame times, mount
    if camera_info_topic is not None:
        cam = PinholeCamera.from_dict(traj.camera_info, f"{bag}: {camera_info_topic}")
        cam_ns = traj.camera_ns
        if cam_ns is None:
            cam_ns = np.round(traj.camera_times * 1e9).astype(np.int64)
        frames = (cam_ns - start_ns) * 1e-9
    else:
        if camera is None:
            from are_stats.environment import DEFAULT_MODELS

            camera = DEFAULT_MODELS / "cameras" / "front_camera.yaml"
        cam = camera if isinstance(camera, PinholeCamera) else PinholeCamera.from_yaml(camera)
        frames = _period_frames(pose_t, period, cam, grid, bag, STAMP_GAP)
    if mount is None:
        if traj.mount is not None:
            mount = traj.mount
        elif not np.allclose(cam.pose, np.eye(4)):
            mount = cam.pose
        else:
            mount = optical_from_base((0.0, 0.0, 1.0))
    mount = np.asarray(mount, float)
    times = frames[(frames >= pose_t[0] - 1e-6) & (frames <= pose_t[-1] + 1e-6)]
    if times.size == 0:
        raise InputError(
            bag,
            camera_info_topic or "--period",
            f"camera frames within the trajectory's times {traj.t[0]:.3f} to "
            f"{traj.t[-1]:.3f} s ({traj.clock_note})",
            Described(f"none of {frames.size} (try --clock header or --clock log)"),
        )
    horizon = max(traj.end - start, float(times[-1]), 1e-3)
    # the scenario over the bag's time span, with behaviour tracks
    catalogue = load_catalogue() if catalogue is None else catalogue
    # the one assembly (as generate and the sweeps): the fit's behaviour when it learned
    # one from tracks, else the catalogue's, then the social force
    (scene,) = scenes_from_fit(
        seed, idata, grid, catalogue, 1, horizon, behaviours=True, model=model,
        behaviour_cell=behaviour_cell, behaviour_dt=behaviour_dt, source=str(fit),
        cell_source="--behaviour-cell",
    )  # fmt: skip
    _check_alive(scene, times, horizon, traj, bag, seed)
    # refuse runaway sizes before tracing: a ray per pixel of every frame, and the output
    # held in memory (a grid per frame at most, markers and a pose per artefact and frame)
    pixels = float(cam.width) * float(cam.height)
    what = f"{times.size} camera frames of {int(pixels)} pixels and {len(scene)} artefacts"
    check_work(float(times.size) * pixels * (1.0 + len(scene) / 8.0), f"tracing {what}", bag)
    check_memory(
        float(times.size) * (grid.data.size + 2000.0 * len(scene)) + traj.t.size * 400.0,
        f"the MCAP messages of {what}",
        bag,
    )
    base_at = interpolate_poses(pose_t, traj.poses, times)
    cam_poses = base_at @ mount
    env = extrude_grid(grid, wall_height)
    n = len(scene)
    if n:
        counts, seen = perceive_scene(scene, times, cam_poses, env, cam, d_max, tau)
    else:
        counts, seen = np.zeros((times.size, 0), np.int64), np.zeros((times.size, 0), bool)
    contacts = np.zeros((times.size, n), bool)

    # one clock in the file: the new messages' header stamps on the input's header clock
    # (as the stamps of the messages passed through), their log times on its recording
    # clock (as their log times), whichever clock the poses were read on
    off = traj.offset_ns
    R = RosMessages(
        start,
        fixed,
        start_ns=start_ns + (off if traj.clock == "log" else 0),
        log_offset_ns=-off,
    )
    if "/map" not in passthrough.topics:
        R.add(0.0, "/map", AUGMENT_TOPICS["/map"], R.occupancy_grid(0.0, grid), latched=True)
    if "/tf" not in passthrough.topics:  # no robot tree in the input: publish the pose
        base, camf = base_frame, traj.camera_frame or ROS_FRAMES["F_C"]
        R.add(0.0, "/tf_static", _TF, R.tf([R.transform(0.0, base, camf, mount)]), latched=True)
        for tk, m in zip(pose_t, traj.poses, strict=True):
            R.add(float(tk), "/tf", _TF, R.tf([R.transform(float(tk), fixed, base, m)]))
    # markers live until the next camera frame and a bit: a replay stopped half-way (or
    # started) shows no artefact that is not alive then
    gaps = np.diff(times)
    lifetime = 2.0 * float(np.median(gaps)) if gaps.size else 1.0
    builder = ARBuilder(grid, catalogue)
    last = None
    String = R.T["std_msgs/msg/String"]
    order = {int(a): k for k, a in enumerate(scene.ids)}
    for f, t in enumerate(times):
        t = float(t)
        boxes = scene.at(t)
        idx = np.array([order[int(a)] for a in boxes.ids], np.int64)
        builder.register_scene(scene, t)
        aug = builder.augmented_grid()
        if last is None or not np.array_equal(aug.data, last):
            R.add(
                t,
                "/augmented_map",
                AUGMENT_TOPICS["/augmented_map"],
                R.occupancy_grid(t, aug),
                latched=True,
            )
            last = aug.data.copy()
        if idx.size:
            rb = base_at[f]
            hit = circle_box_overlap(
                rb[:2, 3], robot_radius, boxes.centres[:, :2], boxes.half_extents[:, :2], boxes.yaws
            )
            contacts[f, idx] = np.asarray(hit, bool)
        R.add(
            t,
            "/artefacts",
            AUGMENT_TOPICS["/artefacts"],
            R.artefact_markers(
                t,
                boxes.ids,
                boxes.centres,
                boxes.half_extents,
                boxes.yaws,
                boxes.labels,
                seen[f, idx],
                lifetime=lifetime,
            ),
        )
        if idx.size:
            R.add(
                t,
                "/tf",
                _TF,
                R.tf(
                    [
                        R.planar(t, fixed, artefact_frame(a), c[0], c[1], y, c[2])
                        for a, c, y in zip(boxes.ids, boxes.centres, boxes.yaws, strict=True)
                    ]
                ),
            )
        doc = {
            "t": round(start + t, 9),
            "live": [int(a) for a in boxes.ids],
            "perceived": [int(a) for a, k in zip(boxes.ids, idx, strict=True) if seen[f, k]],
            "counts": {str(int(a)): int(counts[f, k]) for a, k in zip(boxes.ids, idx, strict=True)},
            "labels": {str(int(a)): str(lb) for a, lb in zip(boxes.ids, boxes.labels, strict=True)},
            "contacts": [int(a) for a, k in zip(boxes.ids, idx, strict=True) if contacts[f, k]],
        }
        R.add(t, "/perceived", AUGMENT_TOPICS["/perceived"], String(data=json.dumps(doc)))
    written = dict(R.counts())
    passed: dict[str, int] = {}
    for c in passthrough.channels:
        passed[c.topic] = passed.get(c.topic, 0) + c.count
    path = R.write(out, force=force, passthrough=passthrough)
    return AugmentResult(
        path, times, start, cam_poses, scene, counts, seen, contacts, written,
        traj.clock, traj.clock_note, traj.frame, traj.frame_note, passed,
    )  # fmt: skip


def _period_frames(
    pose_t: np.ndarray, period: float, cam: Any, grid: Any, bag: Any, gap: float
) -> np.ndarray:
    """Frame times every ``period`` seconds over the stretches of ``pose_t`` (split at gaps
    longer than ``gap``), after checking their count against the limits."""
    cuts = np.flatnonzero(np.diff(pose_t) > gap) + 1
    lo = pose_t[np.r_[0, cuts]]
    hi = pose_t[np.r_[cuts, pose_t.size] - 1]
    n = np.floor((hi - lo + 1e-6) / period) + 1.0
    total = float(n.sum())
    pixels = float(cam.width) * float(cam.height)
    what = f"{total:.6g} camera frames of {int(pixels)} pixels (--period {period:g} s)"
    check_memory(total * (BYTES_PER_FRAME + grid.data.size), f"the frames of {what}", bag)
    check_work(total * pixels, f"tracing {what}", bag)
    return np.concatenate([a + np.arange(int(k)) * period for a, k in zip(lo, n, strict=True)])


def _check_alive(
    scene: Any, times: np.ndarray, horizon: float, traj: BagTrajectory, bag: Any, seed: int
) -> None:
    """Refuse a run in which no artefact is alive in any camera frame, saying why."""
    n = len(scene)
    if n == 0:
        raise InputError(
            bag,
            "",
            f"at least one artefact over the bag's {horizon:.3f} s (clock: {traj.clock_note})",
            Described(
                f"none: the fit's arrivals gave no artefact with --seed {seed} over so short "
                "a span; try another --seed, a longer bag or a fit of busier traffic"
            ),
        )
    arrive = np.asarray(scene.t_arrive, float)
    leave = np.asarray(scene.t_leave, float)
    i = np.searchsorted(times, arrive, side="left")
    alive = (i < times.size) & (times[np.minimum(i, times.size - 1)] < leave)
    if not alive.any():
        raise InputError(
            bag,
            "",
            f"at least one artefact alive in a camera frame (clock: {traj.clock_note})",
            Described(
                f"none: the {n} artefacts live between {arrive.min():.3f} and "
                f"{leave.max():.3f} s of the scenario, the {times.size} camera frames lie at "
                f"{times[0]:.3f} to {times[-1]:.3f} s and meet none of them; try --clock "
                "header or --clock log, another --seed, or more camera frames"
            ),
        )
