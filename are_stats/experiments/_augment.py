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
writes an MCAP with ROS 2 types (:data:`AUGMENT_TOPICS`) stamped on the bag's clock, so the
file lines up with the recording and ``ros2 bag play`` replays both.
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
)

__all__ = [
    "AUGMENT_TOPICS",
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
        Pose times, seconds since the epoch (the bag's clock), increasing.
    poses : (m, 4, 4) float
        ``T_map_base`` at each time.
    start, end : float
        The bag's first and last message times (s since the epoch).
    mount : (4, 4) float or None
        ``T_base_optical`` from ``/tf_static``, when the bag has it.
    camera_frame : str or None
        The optical frame's name (from ``CameraInfo`` or ``/tf_static``).
    camera_times : (k,) float or None
        Stamps of the ``CameraInfo`` topic (the camera's frames), when one was read.
    camera_info : dict or None
        ``k``, ``width``, ``height`` of the first ``CameraInfo`` message.
    source : str
        Where the poses came from (``/tf map -> base_link`` or the topic).
    start_ns : int
        ``start`` in nanoseconds, exact.
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


# ---- reading ------------------------------------------------------------------------------


def _stamp(header: Any, fallback_ns: int) -> float:
    st = header.stamp
    sec, nsec = int(st.sec), int(st.nanosec)
    return fallback_ns * 1e-9 if sec == 0 and nsec == 0 else sec + nsec * 1e-9


def _topics_text(by_topic: dict[str, str]) -> str:
    return ", ".join(f"{t} ({ty})" for t, ty in sorted(by_topic.items())) or "none"


def read_trajectory(
    bag: str | os.PathLike,
    *,
    pose_topic: str | None = None,
    base_frame: str = "base_link",
    map_frame: str = "map",
    camera_info_topic: str | None = None,
) -> BagTrajectory:
    """The robot's base poses in the map frame, from a ROS 1 / ROS 2 bag or an MCAP file.

    Parameters
    ----------
    bag : path
        ``*.bag`` (ROS 1), a ROS 2 bag folder or a ``*.mcap`` / ``*.db3`` file.
    pose_topic : str, optional
        Read the poses from this topic (:data:`POSE_TYPES`; its ``frame_id`` should be the
        map frame) instead of ``/tf``.
    base_frame, map_frame : str
        The ``/tf`` frames composed into ``T_map_base`` (``map -> ... -> base_link``).
    camera_info_topic : str, optional
        A ``sensor_msgs/CameraInfo`` topic: its intrinsics, frame and stamps.

    Returns
    -------
    BagTrajectory

    Raises
    ------
    FileNotFoundError
        If ``bag`` does not exist.
    are_stats.inputs.InputError
        Naming the bag and topic: a missing topic (the topics present are listed), a topic of
        the wrong type, a bag without poses (no ``/tf`` chain from ``map_frame`` to
        ``base_frame``), a camera-info topic without messages.
    """
    from rosbags.highlevel import AnyReader

    from are_stats.logs import (
        TF_TYPES,
        TfBuffer,
        bag_messages,
        bag_read_errors,
        transform_matrix,
        vision_msgs_typestore,
    )

    p = Path(bag)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such bag file or directory")
    errors = bag_read_errors()
    tf = TfBuffer()
    pose_t: list[float] = []
    pose_m: list[np.ndarray] = []
    cam_t: list[float] = []
    cam_info: dict | None = None
    cam_frame: str | None = None
    try:
        with AnyReader(
            [p], default_typestore=vision_msgs_typestore(1 if p.suffix == ".bag" else 2)
        ) as reader:
            by_topic: dict[str, str] = {}
            for c in reader.connections:
                by_topic.setdefault(c.topic, c.msgtype)
            start_ns = int(reader.start_time)
            start, end = start_ns * 1e-9, reader.end_time * 1e-9
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
            for conn, ts, msg in bag_messages(reader, conns, p):
                if conn.topic in tf_topics:
                    tf.add_message(msg, ts * 1e-9, static=conn.topic == "/tf_static")
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
                    pose_t.append(_stamp(msg.header, ts))
                    pose_m.append(transform_matrix(pose.position, pose.orientation))
                else:  # camera info
                    cam_t.append(_stamp(msg.header, ts))
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
    if camera_info_topic is not None and not cam_t:
        raise InputError(
            p, f"topic {camera_info_topic}", "at least one CameraInfo message", Described("none")
        )
    if pose_topic is not None:
        if not pose_t:
            raise InputError(
                p, f"topic {pose_topic}", "at least one pose message", Described("none")
            )
        order = np.argsort(pose_t, kind="stable")
        t = np.asarray(pose_t, float)[order]
        poses = np.stack(pose_m)[order]
        source = pose_topic
    else:
        links = tf.chain(map_frame, base_frame)
        if links is None:
            raise InputError(
                p,
                "topic /tf",
                f"a chain of transforms {map_frame} -> ... -> {base_frame} "
                "(or pass --pose-topic / --base-frame)",
                Described(f"frames {', '.join(tf.frames) or 'none'}"),
            )
        moving = [k for k in links if k not in tf.static]
        # the stamps of the moving link nearest the base (odom -> base_link, usually)
        t = tf.stamps(moving[-1] if moving else links[-1])
        poses = tf.lookup(map_frame, base_frame, t)
        source = f"/tf {map_frame} -> {base_frame}"
    keep = np.r_[True, np.diff(t) > 0]
    t, poses = t[keep], poses[keep]
    mount = None
    candidates = [cam_frame] if cam_frame else [f for f in tf.frames if "optical" in f]
    for f in candidates:
        links = tf.chain(base_frame, f)
        if links and tf.is_static(links):
            mount = tf.lookup(base_frame, f, 0.0)[0]
            cam_frame = f
            break
    return BagTrajectory(
        t,
        poses,
        float(start),
        float(end),
        mount,
        cam_frame,
        np.asarray(sorted(cam_t), float) if cam_t else None,
        cam_info,
        source,
        start_ns,
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
) -> AugmentResult:
    """Augment a robot's recorded run with generated artefacts and write an MCAP.

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
    mount : (4, 4) float, optional
        ``T_base_optical``; default the bag's ``/tf_static``, else the camera file's pose
        when it has one, else :func:`~are_stats.perception.optical_from_base` 1 m above
        the base looking forward.
    period : float
        Seconds between camera frames when the bag gives none (``camera`` from a file).
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

    Returns
    -------
    AugmentResult

    Raises
    ------
    are_stats.inputs.InputError
        A bag without poses, an unknown topic, a trajectory outside the map, a fit without
        area, an existing ``out`` without ``force`` (``OutputExistsError``).
    """
    import jax

    from are_stats.behaviour import behaviour_tracks
    from are_stats.builder import ARBuilder
    from are_stats.environment import OccupancyGrid, extrude_grid, load_catalogue
    from are_stats.experiments._robot import circle_box_overlap
    from are_stats.experiments._sweep import _map_file
    from are_stats.fitting import read_fit
    from are_stats.logs import interpolate_poses
    from are_stats.perception import PinholeCamera, optical_from_base, perceive_scene
    from are_stats.scenarios import Scene, generate_scenarios, traffic_draws

    seed = get_seed(seed)
    period = get_float(period, "--period", "", lo=0.0, lo_open=True)
    d_max = get_float(d_max, "--d-max", "", lo=0.0, lo_open=True, hi=1e6)
    tau = get_float(tau, "--tau", "", lo=0.0)
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
    traj = read_trajectory(
        bag,
        pose_topic=pose_topic,
        base_frame=base_frame,
        map_frame=map_frame,
        camera_info_topic=camera_info_topic,
    )
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
    # the camera: intrinsics, frame times, mount
    if camera_info_topic is not None:
        cam = PinholeCamera.from_dict(traj.camera_info, f"{bag}: {camera_info_topic}")
        frames = traj.camera_times
    else:
        if camera is None:
            from are_stats.environment import DEFAULT_MODELS

            camera = DEFAULT_MODELS / "cameras" / "front_camera.yaml"
        cam = camera if isinstance(camera, PinholeCamera) else PinholeCamera.from_yaml(camera)
        frames = traj.t[0] + np.arange(0.0, traj.t[-1] - traj.t[0] + 1e-6, period)
    if mount is None:
        if traj.mount is not None:
            mount = traj.mount
        elif not np.allclose(cam.pose, np.eye(4)):
            mount = cam.pose
        else:
            mount = optical_from_base((0.0, 0.0, 1.0))
    mount = np.asarray(mount, float)
    frames = frames[(frames >= traj.t[0] - 1e-6) & (frames <= traj.t[-1] + 1e-6)]
    if frames.size == 0:
        raise InputError(
            bag,
            camera_info_topic or "--period",
            f"camera frames within the trajectory's times {traj.t[0]:.3f} to {traj.t[-1]:.3f} s",
            Described("none"),
        )
    start = traj.start
    horizon = max(traj.end - start, float(frames[-1] - start), 1e-3)
    times = frames - start
    # the scenario over the bag's time span, with behaviour tracks
    catalogue = load_catalogue() if catalogue is None else catalogue
    draws, laws = traffic_draws(idata, "chosen")
    art = generate_scenarios(seed, draws, 1, horizon, free_mask=grid, laws=laws)
    names = idata.posterior.attrs.get("class_labels")
    labels = str(names).split(",") if names else None
    scene = Scene.from_scenarios(art, catalogue, class_labels=labels)
    if len(art):
        tracks = behaviour_tracks(
            jax.random.key(seed),
            art,
            scene.classes,
            grid,
            catalogue,
            cell=behaviour_cell,
            dt=behaviour_dt,
            horizon=horizon,
            source="--behaviour-cell",
        )
        scene = Scene.from_scenarios(art, catalogue, tracks, class_labels=labels)
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
    base_at = interpolate_poses(traj.t, traj.poses, frames)
    cam_poses = base_at @ mount
    env = extrude_grid(grid, wall_height)
    n = len(scene)
    if n:
        counts, seen = perceive_scene(scene, times, cam_poses, env, cam, d_max, tau)
    else:
        counts, seen = np.zeros((times.size, 0), np.int64), np.zeros((times.size, 0), bool)
    contacts = np.zeros((times.size, n), bool)

    R = RosMessages(start, map_frame, start_ns=traj.start_ns)
    base, camf = ROS_FRAMES["F_R"], traj.camera_frame or ROS_FRAMES["F_C"]
    R.add(0.0, "/map", AUGMENT_TOPICS["/map"], R.occupancy_grid(0.0, grid), latched=True)
    R.add(0.0, "/tf_static", _TF, R.tf([R.transform(0.0, base, camf, mount)]), latched=True)
    for tk, m in zip(traj.t - start, traj.poses, strict=True):
        R.add(float(tk), "/tf", _TF, R.tf([R.transform(float(tk), map_frame, base, m)]))
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
            ),
        )
        if idx.size:
            R.add(
                t,
                "/tf",
                _TF,
                R.tf(
                    [
                        R.planar(t, map_frame, artefact_frame(a), c[0], c[1], y, c[2])
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
    topics = dict(R.counts())
    path = R.write(out, force=force)
    return AugmentResult(path, times, start, cam_poses, scene, counts, seen, contacts, topics)
