"""Live view: stream a scenario replay over Foxglove's WebSocket protocol (``are-stats serve``).

A scenario (one ``scenario`` of a folder written by ``are-stats generate``, with its
behaviour tracks when the folder has them) is replayed on a clock that runs ``speed`` times
faster than the wall clock and published with ``foxglove-sdk`` (the optional ``live``
extra: ``pip install are_stats[live]``) to any Foxglove viewer (app or desktop: *Open
connection* -> ``ws://127.0.0.1:8765``). Frames are sent ``fps`` times per wall-clock second:

===========  ==========================  ====================================================
topic        Foxglove schema             content
===========  ==========================  ====================================================
``/scene``   ``foxglove.SceneUpdate``    each frame: one entity ``artefact_<id>`` per live
                                         artefact (its box, coloured by class, and a
                                         ``label id`` text above it) in frame ``map``;
                                         deletions of the artefacts that left
``/tf``      ``foxglove.FrameTransforms``  each frame: ``map -> artefact_<id>`` (box centre
                                         and heading, as in the MCAP exports' ``/tf``)
``/map``     ``foxglove.Grid``           the occupancy map (one ``uint8`` field
                                         ``occupancy``: 0-100, 255 unknown), at the start
                                         and again every second, so late viewers get it
``/robot``   ``foxglove.SceneUpdate``    with a robot path (``--robot-path``) or a robot's
                                         bag (``--bag``): the robot's footprint and its
                                         camera's viewing frustum (to ``d_max``), with
                                         ``map -> base_link`` and ``base_link ->
                                         camera_optical_frame`` on ``/tf`` (the bag's own
                                         frame names with ``--bag``)
===========  ==========================  ====================================================

With a bag (:func:`robot_from_bag`) the robot's path and camera come from the bag, read by
:func:`~are_stats.logs.read_trajectory` as ``are-stats augment`` reads them (the same
``--pose-topic``, ``--base-frame``, ``--map-frame``, ``--camera-frame``,
``--camera-info-topic`` and ``--clock``): scene time 0 is the bag's start and the replay's
stamps are on the bag's header clock, so the robot is shown where the bag has it at each
stamp; in an odometry-only bag the fixed frame is ``odom``.

The server speaks the protocol foxglove-sdk serves, ``foxglove.sdk.v1`` (the Foxglove app
and desktop connect to it; clients must offer that subprotocol).

Frame names are the REP-105 names of :mod:`are_stats.export._ros`. Stamps and log
times follow the replay clock: ``start + tau`` where ``tau`` is replay time since the start
(it keeps growing across ``--loop`` rounds, the scene time being ``tau`` modulo the
horizon); the server also advertises the ``time`` capability and broadcasts that clock.

:func:`replay_messages` is the pure part (the timed messages, no server);
:func:`serve_scenario` reads the folder, starts the server and plays them in real time.
"""

from __future__ import annotations

import functools
import math
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, NotRequired, TypedDict

import numpy as np

from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.export._ros import ROS_FRAMES, _quat, artefact_frame
from are_stats.inputs import Described, InputError, get_float
from are_stats.logs import BagTrajectory, TrajectoryOptions, interpolate_poses
from are_stats.scenarios import Scene, ScenesFolder, read_scenes, scenes_from_tables

if TYPE_CHECKING:
    from foxglove.messages import (
        FrameTransform,
        FrameTransforms,
        Grid,
        Quaternion,
        SceneUpdate,
        Timestamp,
    )

    from are_stats.perception import PinholeCamera

__all__ = [
    "LIVE_TOPICS",
    "ROBOT_TOPICS",
    "LiveMessage",
    "LiveRobot",
    "ServeInfo",
    "ServeOptions",
    "load_robot",
    "replay_messages",
    "robot_from_bag",
    "serve_robot",
    "serve_scenario",
]

#: Topic -> Foxglove schema name published by :func:`serve_scenario`.
LIVE_TOPICS = {
    "/scene": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransforms",
    "/map": "foxglove.Grid",
}
#: Topic -> schema added with a robot path (``--robot-path``) or bag (``--bag``).
ROBOT_TOPICS = {"/robot": "foxglove.SceneUpdate"}

#: Box colours (r, g, b, a) by catalogue class position (cycled).
CLASS_RGBA = (
    (0.95, 0.55, 0.1, 0.8),
    (0.2, 0.55, 0.95, 0.8),
    (0.3, 0.8, 0.3, 0.8),
    (0.85, 0.3, 0.75, 0.8),
    (0.9, 0.85, 0.2, 0.8),
)


@dataclass(frozen=True)
class LiveMessage:
    """One timed message of a replay.

    Attributes
    ----------
    wall : float
        Wall-clock seconds after the start of the replay at which it is sent.
    t : float
        Scene time (s) it shows.
    stamp_ns : int
        Its stamp and log time: ``start_ns`` + replay time, in ns.
    topic : str
        A key of :data:`LIVE_TOPICS`.
    message : foxglove.messages.Grid, SceneUpdate or FrameTransforms
        The ``foxglove.messages`` object.
    """

    wall: float
    t: float
    stamp_ns: int
    topic: str
    message: Grid | SceneUpdate | FrameTransforms


class LiveRobot(TypedDict):
    """A robot to replay with a scene (:func:`load_robot`, :func:`robot_from_bag`)."""

    #: (m,) float: times of the poses (s of scene time).
    t: np.ndarray
    #: (m, 4, 4) float: ``T_frame_base`` at ``t``.
    poses: np.ndarray
    #: (4, 4) float: ``T_base_optical``.
    mount: np.ndarray
    camera: PinholeCamera
    #: Frustum depth (m).
    d_max: float
    #: Footprint radius (m).
    radius: float
    #: A bag's frame names (default ``base_link``, ``camera_optical_frame``), its fixed
    #: frame, the stamp of scene time 0 on its header clock (ns), its length (s), where
    #: its poses came from and notes on its clock and frames.
    base_frame: NotRequired[str]
    camera_frame: NotRequired[str]
    frame: NotRequired[str]
    start_ns: NotRequired[int]
    duration: NotRequired[float]
    source: NotRequired[str]
    clock_note: NotRequired[str]
    frame_note: NotRequired[str]


class ServeInfo(TypedDict):
    """What :func:`serve_scenario` served (and tells ``on_ready`` once it listens)."""

    host: str
    port: int
    url: str
    #: The scenario's index, its artefacts and those with tracks, its horizon (s).
    scenario: int
    artefacts: int
    moving: int
    horizon: float
    #: The fixed frame.
    frame: str
    #: The replay's settings: replay seconds per wall-clock second, whether it starts
    #: again after the horizon, the wall-clock seconds it stops after (None: no limit).
    speed: float
    loop: bool
    duration: float | None
    #: Frames and messages sent, wall seconds served.
    frames: int
    messages: int
    wall: float


class ServeOptions(TypedDict, total=False):
    """The options of :func:`serve_scenario` (its keywords but ``on_ready`` and ``stop``,
    the caller's hooks, and the robot, ``robot_path`` or ``robot``), as a caller passes them
    on: ``are-stats serve``'s job. See :func:`serve_scenario` for their meaning and
    defaults."""

    scenario: int | None
    speed: float
    host: str
    port: int
    loop: bool
    duration: float | None
    fps: float


class _Replay(TypedDict):
    """What :func:`serve_scenario` replays of a scenarios folder (:func:`_replay`)."""

    scene: Scene
    grid: OccupancyGrid | None
    horizon: float
    scenario: int
    moving: int
    map: str | None


def _fm() -> ModuleType:
    try:
        # lazy: foxglove is the optional extra 'live' (+0.03 s CPU on `import are_stats.export`)
        import foxglove.messages as fm
    except ImportError:  # pragma: no cover - depends on the environment
        raise InputError(
            "are-stats serve",
            "",
            "foxglove-sdk installed (pip install 'are_stats[live]')",
            Described("no module foxglove"),
        ) from None
    return fm


def _ts(fm: ModuleType, ns: int) -> Timestamp:
    return fm.Timestamp(sec=ns // 10**9, nsec=ns % 10**9)


def _yaw_quat(fm: ModuleType, yaw: float) -> Quaternion:
    return fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def grid_message(grid: OccupancyGrid, stamp_ns: int, frame: str = "map") -> Grid:
    """``foxglove.Grid`` of an :class:`~are_stats.environment.OccupancyGrid` (row 0 at the
    origin, one ``uint8`` field ``occupancy``: 0-100 and 255 for unknown)."""
    fm = _fm()
    data = np.ascontiguousarray(np.asarray(grid.data).astype(np.int8)).view(np.uint8)
    ox, oy, oyaw = (float(v) for v in grid.origin[:3])
    res = float(grid.resolution)
    return fm.Grid(
        timestamp=_ts(fm, stamp_ns),
        frame_id=frame,
        pose=fm.Pose(position=fm.Vector3(x=ox, y=oy, z=0.0), orientation=_yaw_quat(fm, oyaw)),
        column_count=int(grid.width),
        cell_size=fm.Vector2(x=res, y=res),
        row_stride=int(grid.width),
        cell_stride=1,
        fields=[
            fm.PackedElementField(
                name="occupancy", offset=0, type=fm.PackedElementFieldNumericType.Uint8
            )
        ],
        data=data.tobytes(),
    )


def _frame(
    fm: ModuleType, scene: Scene, t: float, ns: int, gone: list[int], frame: str
) -> tuple[SceneUpdate, list[FrameTransform], list[int]]:
    """(SceneUpdate, transforms, alive ids) of the scene at time ``t``."""
    boxes = scene.at(t)
    stamp = _ts(fm, ns)
    cls_of = dict(zip(scene.ids.tolist(), scene.classes.tolist(), strict=True))
    entities, tfs = [], []
    for aid, c, h, yaw, lab in zip(
        boxes.ids.tolist(),
        boxes.centres,
        boxes.half_extents,
        boxes.yaws.tolist(),
        boxes.labels.tolist(),
        strict=True,
    ):
        q = _yaw_quat(fm, yaw)
        r, g, b, a = CLASS_RGBA[int(cls_of[aid]) % len(CLASS_RGBA)]
        cx, cy, cz = (float(v) for v in c)
        entities.append(
            fm.SceneEntity(
                timestamp=stamp,
                frame_id=frame,
                id=artefact_frame(aid),
                cubes=[
                    fm.CubePrimitive(
                        pose=fm.Pose(position=fm.Vector3(x=cx, y=cy, z=cz), orientation=q),
                        size=fm.Vector3(x=2 * float(h[0]), y=2 * float(h[1]), z=2 * float(h[2])),
                        color=fm.Color(r=r, g=g, b=b, a=a),
                    )
                ],
                texts=[
                    fm.TextPrimitive(
                        pose=fm.Pose(
                            position=fm.Vector3(x=cx, y=cy, z=cz + float(h[2]) + 0.3),
                            orientation=fm.Quaternion(w=1.0),
                        ),
                        billboard=True,
                        font_size=14.0,
                        scale_invariant=True,
                        color=fm.Color(r=1.0, g=1.0, b=1.0, a=1.0),
                        text=f"{lab} {aid}",
                    )
                ],
            )
        )
        tfs.append(
            fm.FrameTransform(
                timestamp=stamp,
                parent_frame_id=frame,
                child_frame_id=artefact_frame(aid),
                translation=fm.Vector3(x=cx, y=cy, z=cz),
                rotation=q,
            )
        )
    deletions = [
        fm.SceneEntityDeletion(
            timestamp=stamp, type=fm.SceneEntityDeletionType.MatchingId, id=artefact_frame(a)
        )
        for a in gone
    ]
    return fm.SceneUpdate(deletions=deletions, entities=entities), tfs, boxes.ids.tolist()


def _robot_frame(
    fm: ModuleType, robot: LiveRobot, t: float, ns: int, frame: str
) -> tuple[SceneUpdate, list[FrameTransform]]:
    """(SceneUpdate, transforms) of the robot at ``t``: footprint and camera frustum."""
    base_at = interpolate_poses(robot["t"], robot["poses"], np.array([t]))[0]
    mount = robot["mount"]
    cam = robot["camera"]
    stamp = _ts(fm, ns)
    x, y = float(base_at[0, 3]), float(base_at[1, 3])
    yaw = math.atan2(base_at[1, 0], base_at[0, 0])
    base = robot.get("base_frame", ROS_FRAMES["F_R"])
    optical = robot.get("camera_frame", ROS_FRAMES["F_C"])
    # the frustum's corners in the optical frame at d_max: pixel corners through the pinhole
    d = robot["d_max"]
    corners = []
    for u, v in ((0, 0), (cam.width, 0), (cam.width, cam.height), (0, cam.height)):
        ray = np.array([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0])
        corners.append(d * ray / np.linalg.norm(ray))
    pts = [fm.Point3(x=0.0, y=0.0, z=0.0)]
    for c in corners:
        pts.append(fm.Point3(x=float(c[0]), y=float(c[1]), z=float(c[2])))
    order = [0, 1, 0, 2, 0, 3, 0, 4, 1, 2, 2, 3, 3, 4, 4, 1]
    entity = functools.partial(fm.SceneEntity, timestamp=stamp)  # both drawn at t
    frustum = entity(
        frame_id=optical,
        id="camera_frustum",
        lines=[
            fm.LinePrimitive(
                type=fm.LinePrimitiveLineType.LineList,
                thickness=2.0,
                scale_invariant=True,
                points=[pts[i] for i in order],
                color=fm.Color(r=0.2, g=0.9, b=1.0, a=0.9),
            )
        ],
    )
    body = entity(
        frame_id=base,
        id="robot",
        cylinders=[
            fm.CylinderPrimitive(
                pose=fm.Pose(
                    position=fm.Vector3(x=0.0, y=0.0, z=0.2), orientation=fm.Quaternion(w=1.0)
                ),
                size=fm.Vector3(x=2 * robot["radius"], y=2 * robot["radius"], z=0.4),
                bottom_scale=1.0,
                top_scale=1.0,
                color=fm.Color(r=0.9, g=0.9, b=0.9, a=0.9),
            )
        ],
    )
    qx, qy, qz, qw = _quat(mount[:3, :3])  # as the MCAP writer's /tf (any rotation)
    quat = fm.Quaternion(x=qx, y=qy, z=qz, w=qw)
    tfs = [
        fm.FrameTransform(
            timestamp=stamp,
            parent_frame_id=frame,
            child_frame_id=base,
            translation=fm.Vector3(x=x, y=y, z=0.0),
            rotation=_yaw_quat(fm, yaw),
        ),
        fm.FrameTransform(
            timestamp=stamp,
            parent_frame_id=base,
            child_frame_id=optical,
            translation=fm.Vector3(
                x=float(mount[0, 3]), y=float(mount[1, 3]), z=float(mount[2, 3])
            ),
            rotation=quat,
        ),
    ]
    return fm.SceneUpdate(entities=[body, frustum]), tfs


def replay_messages(
    scene: Scene,
    grid: OccupancyGrid | None = None,
    *,
    horizon: float,
    speed: float = 1.0,
    fps: float = 10.0,
    loop: bool = False,
    start_ns: int = 0,
    map_period: float = 1.0,
    frame: str = ROS_FRAMES["F_E"],
    robot: LiveRobot | None = None,
) -> Iterator[LiveMessage]:
    """The timed messages of a replay of ``scene`` (pure: no server, no clock).

    Frame ``k`` is sent at wall time ``k / fps`` and shows replay time
    ``tau = speed * k / fps``; without ``loop`` the last frame shows ``horizon`` and the
    iterator ends, with ``loop`` it never ends (scene time ``tau mod horizon``). Each frame
    gives ``/tf`` (when artefacts are alive) and ``/scene``; ``/map`` comes first and again
    every ``map_period`` wall seconds.

    Parameters
    ----------
    scene : Scene
        :meth:`~are_stats.Scene.from_scenarios` of one scenario.
    grid : OccupancyGrid, optional
        The map (no ``/map`` without it).
    horizon : float
        Length of the scenario (s, > 0).
    speed : float
        Replay seconds per wall-clock second (> 0).
    fps : float
        Frames per wall-clock second (> 0).
    loop : bool
        Start again at t = 0 after the horizon, forever.
    start_ns : int
        Stamp of replay time 0 (ns since the epoch).
    map_period : float
        Wall seconds between two ``/map`` messages.
    frame : str
        The fixed frame.
    robot : LiveRobot, optional
        ``t`` (m,), ``poses`` (m, 4, 4) ``T_map_base``, ``mount`` (4, 4) ``T_base_optical``,
        ``camera`` (PinholeCamera), ``d_max`` and ``radius``, optionally ``base_frame``
        and ``camera_frame`` (default ``base_link``, ``camera_optical_frame``): the robot
        on ``/robot`` and ``/tf`` (:func:`load_robot`, :func:`robot_from_bag`).

    Yields
    ------
    LiveMessage
        In order of ``wall``.

    Examples
    --------
    >>> import pandas as pd
    >>> from are_stats import Scene, load_catalogue
    >>> table = pd.DataFrame({"t_arrive": [0.0], "t_leave": [5.0], "x": [1.0], "y": [2.0],
    ...                       "yaw": [0.0]})
    >>> scene = Scene.from_scenarios(table, load_catalogue())
    >>> msgs = list(replay_messages(scene, horizon=10.0, speed=20.0, fps=4.0))
    >>> [(m.t, m.topic) for m in msgs[:3]], len(msgs)
    ([(0.0, '/tf'), (0.0, '/scene'), (5.0, '/scene')], 4)
    """
    fm = _fm()
    if not (horizon > 0 and math.isfinite(horizon)):
        raise ValueError(f"horizon: expected a finite time > 0, got {horizon!r}")
    if not (speed > 0 and math.isfinite(speed)) or not (fps > 0 and math.isfinite(fps)):
        raise ValueError(f"speed, fps: expected finite values > 0, got {speed!r}, {fps!r}")
    dt = speed / fps
    last_map = -math.inf
    alive: list[int] = []
    k = 0
    while True:
        wall = k / fps
        tau = min(k * dt, horizon) if not loop else k * dt
        t = math.fmod(tau, horizon) if loop else tau
        ns = int(start_ns) + int(round(tau * 1e9))
        if grid is not None and wall - last_map >= map_period - 1e-9:
            last_map = wall
            yield LiveMessage(wall, t, ns, "/map", grid_message(grid, ns, frame))
        now = set(scene.ids[scene.alive(t)].tolist())
        gone = [a for a in alive if a not in now]
        upd, tfs, alive = _frame(fm, scene, t, ns, gone, frame)
        if robot is not None:
            body, robot_tfs = _robot_frame(fm, robot, t, ns, frame)
            tfs = [*tfs, *robot_tfs]
        if tfs:
            yield LiveMessage(wall, t, ns, "/tf", fm.FrameTransforms(transforms=tfs))
        yield LiveMessage(wall, t, ns, "/scene", upd)
        if robot is not None:
            yield LiveMessage(wall, t, ns, "/robot", body)
        if not loop and tau >= horizon:
            return
        k += 1


def load_robot(
    path: str | os.PathLike,
    camera: PinholeCamera | str | os.PathLike[str] | None = None,
    *,
    height: float = 1.0,
    d_max: float = 10.0,
    radius: float = 0.3,
) -> LiveRobot:
    """A robot path (CSV/Parquet ``t, x, y, yaw``: :func:`~are_stats.perception.read_robot_path`)
    and its camera for :func:`replay_messages`.

    Parameters
    ----------
    path : path
        The robot path.
    camera : PinholeCamera or path, optional
        Intrinsics and mount (default the shipped ``front_camera``; a camera without a
        mount is ``height`` m above the base looking forward).
    height, d_max, radius : float
        Camera height (m) when the camera has no mount, frustum depth (m), footprint
        radius (m).

    Returns
    -------
    LiveRobot
        ``t``, ``poses``, ``mount``, ``camera``, ``d_max``, ``radius``.
    """
    # lazy: perception (Warp) adds 0.85 s CPU to `import are_stats.export`
    from are_stats.perception import read_robot_path

    table = read_robot_path(path)
    cam, mount = camera_and_mount(camera, height)
    t = table["t"].to_numpy(float)
    c, s = np.cos(table["yaw"].to_numpy(float)), np.sin(table["yaw"].to_numpy(float))
    poses = np.zeros((t.size, 4, 4))
    poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = c, -s, s, c
    poses[:, 2, 2] = poses[:, 3, 3] = 1.0
    poses[:, 0, 3], poses[:, 1, 3] = table["x"].to_numpy(float), table["y"].to_numpy(float)
    return {
        "t": t,
        "poses": poses,
        "mount": np.asarray(mount, float),
        "camera": cam,
        "d_max": float(d_max),
        "radius": float(radius),
    }


def camera_and_mount(
    camera: PinholeCamera | str | os.PathLike[str] | None,
    height: float,
    tree_mount: np.ndarray | None = None,
) -> tuple[PinholeCamera, np.ndarray]:
    """The camera (default the shipped ``front_camera``) and its mount ``T_base_optical``:
    the robot's own tree (``tree_mount``, a bag's static chain from the base to the camera
    frame) wins, else the camera's pose, else ``height`` m above the base looking forward
    (:func:`are_stats.perception.camera_mount`)."""
    # lazy: perception (Warp) adds 0.85 s CPU to `import are_stats.export`
    from are_stats.perception import PinholeCamera, camera_mount, read_camera

    if isinstance(camera, PinholeCamera):
        cam = camera
    else:  # a file, or a shipped camera's name
        cam = read_camera("front_camera" if camera is None else camera, source="camera")
    return cam, camera_mount(cam.pose, height, tree_mount)


def bag_camera(
    bag: str | os.PathLike,
    traj: BagTrajectory,
    camera: PinholeCamera | str | os.PathLike[str] | None,
    camera_info_topic: str | None,
    height: float,
) -> tuple[PinholeCamera, np.ndarray]:
    """The camera of a robot's bag and its mount ``T_base_optical`` (4, 4), for ``augment``
    and ``serve --bag``: the intrinsics of the ``CameraInfo`` topic read into ``traj`` when
    ``camera_info_topic`` is given, else ``camera``; the mount by :func:`camera_and_mount`
    (the bag's tree first)."""
    # lazy: perception (Warp) adds 0.85 s CPU to `import are_stats.export`
    from are_stats.perception import PinholeCamera

    if camera_info_topic is not None:
        camera = PinholeCamera.from_dict(traj.camera_info, f"{bag}: {camera_info_topic}")
    return camera_and_mount(camera, height, traj.mount)


def robot_from_bag(
    bag: str | os.PathLike,
    trajectory: TrajectoryOptions | None = None,
    *,
    camera: PinholeCamera | str | os.PathLike[str] | None = None,
    height: float = 1.0,
    d_max: float = 10.0,
    radius: float = 0.3,
) -> LiveRobot:
    """A robot's recorded path and camera from its bag, for :func:`replay_messages`.

    The bag is read by :func:`~are_stats.logs.read_trajectory` (the reader of ``are-stats
    augment``, with its options and clock rule). Scene time 0 is the bag's start (its first
    pose or camera time on the clock read), as in ``augment``; ``start_ns`` is that start
    on the bag's header clock, the replay's stamp of scene time 0.

    Parameters
    ----------
    bag : path
        ROS 1 ``.bag``, ROS 2 bag folder or ``.mcap``.
    trajectory : TrajectoryOptions, optional
        How the bag's robot is read (``serve``'s ``--pose-topic`` ... ``--clock``, as
        ``augment``'s); default :class:`~are_stats.logs.TrajectoryOptions` ``()``: ``/tf``
        from ``map`` to ``base_link``, the ``auto`` clock.
    camera : PinholeCamera or path, optional
        Intrinsics when ``trajectory.camera_info_topic`` is not given (default the shipped
        ``front_camera``).
    height, d_max, radius : float
        Camera height (m) when neither the bag's tree nor the camera gives a mount, frustum
        depth (m), footprint radius (m).

    Returns
    -------
    LiveRobot
        ``t`` (m,) scene times (s after the bag's start), ``poses`` (m, 4, 4)
        ``T_frame_base``, ``mount`` (4, 4) ``T_base_optical`` (the bag's static chain to
        the camera frame when it has one, else the camera's), ``camera``, ``d_max``,
        ``radius``, ``base_frame``, ``camera_frame`` (the bag's names), ``frame`` (the
        fixed frame: ``map_frame``, or ``odom`` in an odometry-only bag), ``start_ns``,
        ``duration`` (s), ``source``, ``clock_note``, ``frame_note``.

    Raises
    ------
    are_stats.inputs.InputError
        Naming the bag and topic when it holds no usable pose (no ``/tf`` chain from the
        map frame to the base, a missing or empty pose topic) and for the other errors of
        :func:`~are_stats.logs.read_trajectory`.
    """
    opts = trajectory or TrajectoryOptions()
    traj = opts.read(bag)
    cam, mount = bag_camera(bag, traj, camera, opts.camera_info_topic, height)
    # the header clock's start (augment's rule): stamps of the replay as the bag's
    off = traj.offset_ns if traj.clock == "log" else 0
    return {
        "t": traj.since_start,
        "poses": np.asarray(traj.poses, float),
        "mount": np.asarray(mount, float),
        "camera": cam,
        "d_max": float(d_max),
        "radius": float(radius),
        "base_frame": opts.keywords()["base_frame"].lstrip("/"),
        "camera_frame": traj.camera_frame or ROS_FRAMES["F_C"],
        "frame": traj.frame,
        "start_ns": int(traj.start_ns) + int(off),
        "duration": traj.end - traj.start,
        "source": traj.source,
        "clock_note": traj.clock_note,
        "frame_note": traj.frame_note,
    }


def serve_robot(
    bag: str | os.PathLike | None,
    trajectory: TrajectoryOptions | None = None,
    *,
    robot_path: str | os.PathLike | None = None,
) -> LiveRobot | None:
    """The robot ``serve`` streams from a bag (:func:`robot_from_bag`), or None without one.

    Parameters
    ----------
    bag : path or None
        ROS 1 ``.bag``, ROS 2 bag folder or ``.mcap`` (``--bag``).
    trajectory : TrajectoryOptions, optional
        How the bag's robot is read (``--pose-topic`` ... ``--clock``); they need a bag.
    robot_path : path, optional
        A robot path given too (``--robot-path``): the two are exclusive.

    Returns
    -------
    LiveRobot or None
        The bag's robot; None when no bag is given (the replay then streams the robot of
        ``robot_path``, if any, :func:`serve_scenario`).

    Raises
    ------
    are_stats.inputs.InputError
        Naming the first of ``trajectory``'s options given without a bag, ``--bag`` when a
        robot path is given too, ``--pose-topic`` with ``--base-frame``
        (:meth:`~are_stats.logs.TrajectoryOptions.checked`), and the errors of
        :func:`robot_from_bag`; all before anything is served.
    """
    trajectory = trajectory or TrajectoryOptions()
    if bag is None:
        for name in trajectory.given():
            raise InputError(name, "", "--bag (the bag it reads)", Described("no --bag"))
        return None
    if robot_path is not None:
        raise InputError("--bag", "", "either --robot-path or --bag", "both")
    return robot_from_bag(bag, trajectory.checked())


def _resolves(host: str) -> bool:
    """Whether ``host`` names an address (so that a failed bind is the port's fault)."""
    try:
        socket.getaddrinfo(host, None)
    except (OSError, UnicodeError, ValueError):
        return False
    return True


def _port_error(host: str, port: int, err: BaseException) -> InputError:
    return InputError(
        "--port",
        "",
        f"a free TCP port on {host} (or 0 for any free port)",
        Described(f"{port}: {err}"),
    )


def _replay(d: Path, folder: ScenesFolder, scenario: int | None = None) -> _Replay:
    """What :func:`serve_scenario` replays of a scenarios folder read by
    :func:`~are_stats.scenarios.read_scenes`: the scene of one scenario, the map (when the
    manifest names one) and the horizon.

    Parameters
    ----------
    d : Path
        The folder (named in errors).
    folder : ScenesFolder
        Its content.
    scenario : int, optional
        Which scenario (default the first).

    Returns
    -------
    _Replay
        ``scene``, ``grid`` (or None), ``horizon``, ``scenario`` (its index), ``moving``
        (artefacts with tracks), ``map`` (the map file or None).
    """
    df, manifest, tracks = folder
    present = folder.scenario_numbers
    if not present:
        raise InputError(
            d,
            "",
            "a scenarios folder with at least one scenario",
            Described(
                "none (no artefact, and no n_scenarios in manifest.yaml)"
                if manifest.get("n_scenarios") is None
                else "n_scenarios: 0 in manifest.yaml"
            ),
        )
    if scenario is None:
        k = present[0]
    else:
        if (
            isinstance(scenario, bool)
            or not isinstance(scenario, int | np.integer)
            or scenario not in present
        ):
            lo, hi = present[0], present[-1]
            within = f"{lo}" if lo == hi else f"{lo} to {hi}"
            raise InputError(
                "--scenario", "", f"a scenario of {d / 'artefacts.parquet'} ({within})", scenario
            )
        k = int(scenario)
    (scene,) = scenes_from_tables(df, tracks, load_catalogue(), folder.class_labels, [k])
    grid = folder.grid()
    horizon = folder.horizon
    if horizon is not None:  # the replay needs a scene of some length
        horizon = get_float(horizon, folder.manifest_path, "generation.horizon", lo=0, lo_open=True)
    else:  # a hand-made folder: until the last leaving (or the last track epoch)
        ends = [scene.t_leave]
        if scene.has_tracks.any():
            ends.append(scene.tracks_table()["t"].to_numpy(float))
        ends_all = np.concatenate(ends)
        horizon = float(ends_all.max()) if ends_all.size else 0.0
        if not horizon > 0:
            raise InputError(
                d / "artefacts.parquet",
                f"scenario {k}",
                "artefacts leaving after t = 0",
                Described(f"horizon {horizon:g} s"),
            )
    return {
        "scene": scene,
        "grid": grid,
        "horizon": float(horizon),
        "scenario": k,
        "moving": int(np.count_nonzero(scene.has_tracks)),
        "map": folder.map_file,
    }


def serve_scenario(
    folder: str | os.PathLike,
    *,
    scenario: int | None = None,
    speed: float = 1.0,
    host: str = "127.0.0.1",
    port: int = 8765,
    loop: bool = False,
    duration: float | None = None,
    fps: float = 10.0,
    on_ready: Callable[[ServeInfo], None] | None = None,
    stop: threading.Event | None = None,
    robot_path: str | os.PathLike | None = None,
    robot: LiveRobot | None = None,
) -> ServeInfo:
    """Stream a scenario replay live over Foxglove's WebSocket protocol.

    Reads the folder (:func:`~are_stats.scenarios.read_scenes`), starts a ``foxglove-sdk``
    WebSocket server on ``host:port`` with its own logging context, and sends
    :func:`replay_messages` at their wall times until the replay ends (never with ``loop``),
    ``duration`` wall seconds have passed or ``stop`` (a ``threading.Event``) is set; then
    stops the server.

    Parameters
    ----------
    folder : path
        Scenarios folder written by ``are-stats generate``.
    scenario : int, optional
        Which scenario (the ``scenario`` column); default the first.
    speed : float
        Replay seconds per wall-clock second (> 0, at most 1e6).
    host, port : str, int
        Address to listen on (default loopback only); port 0 picks a free port.
    loop : bool
        Replay again from t = 0 after the horizon.
    duration : float, optional
        Stop after this many wall-clock seconds.
    fps : float
        Frames per wall-clock second.
    on_ready : callable, optional
        Called with the summary (``port`` filled in) once the server listens.
    robot_path : path, optional
        A robot path (``t, x, y, yaw``) to stream with the scene (:func:`load_robot`:
        ``/robot`` and its ``/tf``).
    robot : LiveRobot, optional
        A robot already read (:func:`robot_from_bag`, :func:`load_robot`), instead of
        ``robot_path``. With a ``start_ns`` (a bag's) the replay is stamped from it instead
        of the wall clock's now, and with a ``frame`` that is the fixed frame.

    Returns
    -------
    ServeInfo
        ``host``, ``port``, ``url``, ``scenario``, ``artefacts``, ``moving``, ``horizon``,
        ``frame``, ``speed``, ``loop``, ``duration`` (as checked), ``frames`` and
        ``messages`` (counts sent), ``wall`` (seconds served).

    Raises
    ------
    are_stats.inputs.InputError
        For a bad folder, scenario, speed, duration or port (one in use included).
    """
    speed = get_float(speed, "--speed", "", lo=0, lo_open=True, hi=1e6)
    fps = get_float(fps, "fps", "", lo=0, lo_open=True, hi=1000)
    if duration is not None:
        duration = get_float(duration, "--duration", "", lo=0, lo_open=True)
    if isinstance(port, bool) or not isinstance(port, int | np.integer) or not 0 <= port < 65536:
        raise InputError("--port", "", "a TCP port 0 to 65535", port)
    if (
        not isinstance(host, str)
        or not host
        or len(host) > 253
        or any(c.isspace() or c in "/\\\x00" for c in host)
    ):
        raise InputError("--host", "", "an address to listen on, such as 127.0.0.1", host)
    if robot_path is not None and robot is not None:
        raise InputError("--robot-path", "", "either --robot-path or --bag", "both")
    replay = _replay(Path(folder), read_scenes(folder), scenario)
    if robot_path is not None:
        robot = load_robot(robot_path)
    fixed = str(robot.get("frame", ROS_FRAMES["F_E"])) if robot is not None else ROS_FRAMES["F_E"]
    _fm()
    # lazy: the optional extra 'live' (foxglove, +0.03 s CPU on `import are_stats.export`)
    import foxglove
    from foxglove.channels import FrameTransformsChannel, GridChannel, SceneUpdateChannel
    from foxglove.websocket import Capability

    ctx = foxglove.Context()
    channels = {
        "/scene": SceneUpdateChannel("/scene", context=ctx),
        "/tf": FrameTransformsChannel("/tf", context=ctx),
    }
    if replay["grid"] is not None:
        channels["/map"] = GridChannel("/map", context=ctx)
    if robot is not None:
        channels["/robot"] = SceneUpdateChannel("/robot", context=ctx)
    try:
        server = foxglove.start_server(
            name="are-stats serve",
            host=host,
            port=int(port),
            context=ctx,
            capabilities=[Capability.Time],
        )
    except Exception as err:  # the SDK raises its own error types for bind failures
        if _resolves(host):
            raise _port_error(host, int(port), err) from None
        raise InputError(
            "--host",
            "",
            "an address of this machine to listen on, such as 127.0.0.1",
            Described(f"{host!r} ({err})"),
        ) from None
    info: ServeInfo = {
        "host": host,
        "port": int(server.port),
        "url": f"ws://{host}:{int(server.port)}",
        "scenario": replay["scenario"],
        "artefacts": len(replay["scene"]),
        "moving": replay["moving"],
        "horizon": replay["horizon"],
        "frame": fixed,
        "speed": speed,
        "loop": bool(loop),
        "duration": duration,
        "frames": 0,
        "messages": 0,
        "wall": 0.0,
    }
    start_ns = time.time_ns() if robot is None else int(robot.get("start_ns", time.time_ns()))
    t0 = time.monotonic()
    try:
        if on_ready is not None:
            on_ready(info.copy())
        msgs = replay_messages(
            replay["scene"],
            replay["grid"],
            horizon=replay["horizon"],
            speed=speed,
            fps=fps,
            loop=loop,
            start_ns=start_ns,
            frame=fixed,
            robot=None if robot is None else LiveRobot(**robot),
        )
        last_stamp = None
        for m in msgs:
            if duration is not None and m.wall > duration:
                break
            wait = t0 + m.wall - time.monotonic()
            if wait > 0:
                if stop is not None:
                    if stop.wait(wait):
                        break
                else:
                    time.sleep(wait)
            elif stop is not None and stop.is_set():
                break
            if m.stamp_ns != last_stamp:
                server.broadcast_time(m.stamp_ns)
                last_stamp = m.stamp_ns
                info["frames"] += 1
            channels[m.topic].log(m.message, log_time=m.stamp_ns)
            info["messages"] += 1
    finally:
        info["wall"] = time.monotonic() - t0
        server.stop()
    return info
