"""Robot bag in, augmented bag out: the ARE loop along a recorded robot trajectory.

:func:`~are_stats.logs.read_trajectory` reads the robot's base poses in the map frame
and its camera from the bag, on one clock.

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
import warnings
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, TypedDict

import numpy as np
import numpy.typing as npt

from are_stats._atomic import check_writable
from are_stats.builder import ARBuilder
from are_stats.environment import (
    ArtefactCatalogue,
    OccupancyGrid,
    extrude_grid,
    load_catalogue,
    read_map,
)
from are_stats.export._live import bag_camera
from are_stats.export._ros import ROS_FRAMES, RosMessages, artefact_frame
from are_stats.inputs import (
    Described,
    InputError,
    Source,
    check_memory,
    check_work,
    get_float,
    get_seed,
    get_str,
)
from are_stats.logs import (
    CLOCKS,
    STAMP_GAP,
    BagTrajectory,
    PassChannel,
    TrajectoryOptions,
    bag_messages,
    bag_passthrough,
    bag_read_errors,
    bag_reader,
    check_bag_path,
    interpolate_poses,
    vision_msgs_typestore,
)
from are_stats.scenarios import AssemblyOptions, Scene, scenes_from_fit

if TYPE_CHECKING:
    from are_stats.perception import CameraModel, PinholeCamera

__all__ = [
    "AUGMENT_TOPICS",
    "AugmentOptions",
    "AugmentResult",
    "augment_bag",
]

_TF = "tf2_msgs/msg/TFMessage"  # are_stats.logs.TF_TYPE

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

#: Topics of :data:`AUGMENT_TOPICS` that an input may hold: ``/tf`` and ``/tf_static`` get
#: channels of their own beside the input's, ``/map`` is written only when the input passes
#: none through (a Nav2 bag's ``/map`` passes through, checked against ``--map``).
_BESIDE_THE_INPUTS = frozenset({"/tf", "/tf_static", "/map"})

#: How far the input's ``/map`` may be from ``--map`` and still be the same map: the
#: resolution relatively (``nav_msgs`` spells it as a float32), the origin as a share of a
#: cell, and its yaw (rad).
MAP_RESOLUTION_RTOL = 1e-6
MAP_ORIGIN_CELLS = 0.01
MAP_YAW_TOL = 1e-4


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
    camera_note : str
        Why the camera mount is not the bag's tree (the camera file's pose or the default
        mount instead), and how to use the bag's camera; ``""`` when it is the tree's.
    """

    path: Path
    times: np.ndarray
    start: float
    camera_poses: np.ndarray
    scene: Scene
    counts: np.ndarray
    perceived: np.ndarray
    contacts: np.ndarray
    topics: dict
    clock: str = "log"
    clock_note: str = ""
    frame: str = "map"
    frame_note: str = ""
    passed: dict = {}  # noqa: RUF012 (a NamedTuple default, never mutated)
    camera_note: str = ""


class AugmentOptions(TypedDict, total=False):
    """The options of :func:`augment_bag` (its keywords but how the bag's robot is read,
    :class:`~are_stats.logs.TrajectoryOptions`, and ``topics``), as a caller passes them on:
    ``are-stats augment``'s job. See :func:`augment_bag` for their meaning and defaults."""

    camera: PinholeCamera | str | os.PathLike[str] | None
    mount: npt.ArrayLike | None
    period: float
    d_max: float
    tau: float
    robot_radius: float
    behaviour_cell: float
    behaviour_dt: float
    wall_height: float
    catalogue: ArtefactCatalogue | None
    force: bool
    model: str
    positions: str


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
    camera: PinholeCamera | str | os.PathLike[str] | None = None,
    camera_info_topic: str | None = None,
    mount: npt.ArrayLike | None = None,
    period: float = 0.5,
    d_max: float = 10.0,
    tau: float = 10.0,
    robot_radius: float = 0.3,
    behaviour_cell: float = 1.0,
    behaviour_dt: float = 2.0,
    wall_height: float = 2.5,
    catalogue: ArtefactCatalogue | None = None,
    force: bool = False,
    clock: str = "auto",
    model: str = "chosen",
    positions: str = "chosen",
    topics: Sequence[str] | None = None,
    camera_frame: str | None = None,
) -> AugmentResult:
    """Augment a robot's recorded run with generated artefacts and write an MCAP.

    The output carries the input's channels unchanged (:func:`~are_stats.logs.bag_passthrough`:
    same schemas, bytes, counts and log times; a ROS 1 bag converted to
    ROS 2 CDR) plus only what is new: ``map -> artefact_<id>`` on ``/tf``, the markers of
    ``/artefacts`` (living until the next camera frame and a bit), ``/augmented_map``,
    ``/perceived`` and ``/map`` (``map_path``'s) when none passes through (the input has
    none, or ``topics`` leaves it out); an input ``/map`` passes through, checked against
    ``map_path`` (same width, height, resolution and origin). The robot's tree is the input's;
    only a bag without ``/tf`` (a pose topic) gets ``map -> base_link`` and the static
    camera mount published, so that the output can still be viewed; when the bag's
    ``/tf_static`` gives the base a parent (``base_footprint -> base_link``),
    ``map -> base_footprint`` (the root of that static chain, composed so that the base's
    pose is the pose topic's) instead, so that every frame keeps one parent. The new channels
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
        Pose topic instead of ``/tf`` (see :func:`~are_stats.logs.read_trajectory`).
    base_frame, map_frame : str
        Frames of the ``/tf`` chain.
    camera : PinholeCamera or path, optional
        Intrinsics: a camera YAML, or a shipped camera's name (``front_camera``, as
        ``perceive --camera``); with neither ``camera`` nor ``camera_info_topic`` the
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
        (:func:`~are_stats.logs.read_trajectory`); the output keeps the input's stamps on
        that clock.
    model : {"chosen", "paper"}
        Generate from the traffic models the fit chose or from the paper's (Poisson,
        exponential, uniform positions: for a fit whose learned entries belong to another
        map), as ``generate --model``.
    positions : {"chosen", "uniform"}
        Entry points as ``model`` says, or uniform over the free cells of the map with the
        arrivals and stays ``model`` gives (for a fit whose learned entries belong to
        another map), as ``generate --positions``
        (:func:`~are_stats.scenarios.scenes_from_fit`).
    topics : sequence of str, optional
        The input topics passed through (default all of them).

    Returns
    -------
    AugmentResult

    Raises
    ------
    are_stats.inputs.InputError
        ``model``, ``positions``, ``behaviour_cell`` or ``behaviour_dt`` out of range,
        named as ``--model``, ``--positions``, ``--behaviour-cell``, ``--behaviour-dt``
        (:meth:`~are_stats.scenarios.AssemblyOptions.from_command`, before any file is
        read), a bag without poses, an unknown topic, a bad pose or stamp (see
        :func:`~are_stats.logs.read_trajectory`), a trajectory wholly outside the map
        (partly outside: a ``UserWarning`` naming the bag, how many poses and their times
        into the bag; :func:`~are_stats.perception.check_poses_inside`, perceive's rule), a fit
        without area, no artefact alive in any camera frame (with why and what to try),
        an existing ``out`` without ``force`` (``OutputExistsError``), a bag without
        ``/tf`` whose ``/tf_static`` chain above the base holds the map frame, an input
        ``/map`` passed through that is not ``map_path``'s map (its type, or its last
        message's width, height, resolution or origin: both named). Times are given as
        seconds into the bag, with the stamp read in brackets.
    are_stats.inputs.LimitError
        Camera frames (``period``), tracing or messages past the memory or work limits,
        checked before anything of that size is allocated.
    """
    # lazy: experiments +0.10 s, fitting (NumPyro) +1.1 s, perception (Warp) +0.85 s
    # CPU on `import are_stats.export`, which every CLI job imports
    from are_stats.experiments import circle_box_overlap
    from are_stats.fitting import read_fit
    from are_stats.perception import check_poses_inside, perceive_scene, read_camera

    if isinstance(camera, str | os.PathLike):  # a file, or a shipped camera's name
        camera = read_camera(camera)
    seed = get_seed(seed)
    # the one assembly's options (as generate's): the fit's behaviour when it learned one
    # from tracks, else the catalogue's, then the social force
    options = AssemblyOptions.from_command(True, model, positions, behaviour_cell, behaviour_dt)
    period = get_float(period, "--period", "", lo=0.0, lo_open=True)
    d_max = get_float(d_max, "--d-max", "", lo=0.0, lo_open=True, hi=1e6)
    tau = get_float(tau, "--tau", "", lo=0.0)
    clock = get_str(clock, "--clock", "", choices=CLOCKS)
    if camera is not None and camera_info_topic is not None:
        raise InputError("--camera", "", "either --camera or --camera-info-topic", "both")
    out = check_writable(out, force)
    map_file, grid = read_map(map_path)
    fitted = read_fit(fit)

    opts = TrajectoryOptions(pose_topic, base_frame, map_frame, camera_info_topic, clock)
    traj = opts._replace(camera_frame=camera_frame).read(bag)
    passthrough = bag_passthrough(bag, None if topics is None else list(topics))
    passed_topics = {c.topic for c in passthrough.channels}
    clash = sorted(passed_topics & (set(AUGMENT_TOPICS) - _BESIDE_THE_INPUTS))
    if clash:
        new = ", ".join(t for t in AUGMENT_TOPICS if t not in _BESIDE_THE_INPUTS)
        raise InputError(
            bag,
            f"topic {clash[0]}",
            f"input topics other than the ones augment writes ({new})",
            Described(f"{', '.join(clash)} in the bag; leave them out with --topics"),
        )
    # a Nav2 bag's map passes through (an empty channel gives no map): it must be --map's
    bag_map = any(c.topic == "/map" and c.count > 0 for c in passthrough.channels)
    if "/map" in passed_topics:
        _check_bag_map(bag, passthrough.channels, grid, map_path)
    fixed = traj.frame
    xy = traj.poses[:, :2, 3]

    def when(i: int, j: int) -> str:
        at = (_pose_ns(traj, i),) if i == j else (_pose_ns(traj, i), _pose_ns(traj, j))
        return ("at " if i == j else "from ") + _into_bag(bag, traj, *at)

    # perceive's rule: refused wholly outside, a warning partly outside (a map's edge)
    outside = check_poses_inside(bag, xy, grid, None, map_file, field=traj.source, when=when)
    if outside is not None:
        warnings.warn(outside, UserWarning, stacklevel=2)
    # times on the scenario clock: seconds after the trajectory's start, from exact stamps
    start, start_ns = traj.start, traj.start_ns
    pose_t = traj.since_start
    # the camera: intrinsics, frame times, mount (the bag's tree wins: serve's rule)
    cam, tree_mount = bag_camera(bag, traj, camera, camera_info_topic, 1.0)
    if camera_info_topic is not None:
        cam_ns = traj.camera_ns
        if cam_ns is None:
            cam_ns = np.round(traj.camera_times * 1e9).astype(np.int64)
        frames = (cam_ns - start_ns) * 1e-9
    else:
        frames = _period_frames(pose_t, period, cam, grid, bag, STAMP_GAP)
    camera_note = (
        "" if mount is not None else _camera_note(traj, base_frame, camera, cam, passthrough.topics)
    )
    mount = np.asarray(tree_mount if mount is None else mount, float)
    times = frames[(frames >= pose_t[0] - 1e-6) & (frames <= pose_t[-1] + 1e-6)]
    if times.size == 0:
        raise InputError(
            bag,
            camera_info_topic or "--period",
            f"camera frames within the trajectory's times "
            f"{_into_bag(bag, traj, _pose_ns(traj, 0), _pose_ns(traj, -1))} "
            f"({traj.clock_note})",
            Described(f"none of {frames.size} (try --clock header or --clock log)"),
        )
    horizon = max(traj.end - start, float(times[-1]), 1e-3)
    # the scenario over the bag's time span, with behaviour tracks
    catalogue = load_catalogue() if catalogue is None else catalogue
    # the one assembly (as generate and the sweeps)
    (scene,) = scenes_from_fit(seed, fitted, grid, catalogue, 1, horizon, options, source=str(fit))
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
    if not bag_map:  # none in the bag, or --topics leaves it out
        R.add(0.0, "/map", AUGMENT_TOPICS["/map"], R.occupancy_grid(0.0, grid), latched=True)
    if "/tf" not in passthrough.topics:  # no robot tree in the input: publish the pose
        base, camf = base_frame, traj.camera_frame or ROS_FRAMES["F_C"]
        if traj.mount is None:  # the input's /tf_static mounts the camera already
            tf = R.tf([R.transform(0.0, base, camf, mount)])
            R.add(0.0, "/tf_static", _TF, tf, latched=True)
        # one parent per frame: a base with a static parent in the output's /tf_static
        # (base_footprint -> base_link) is placed through the root of that chain
        child, below = _robot_child(traj, base_frame, "/tf_static" in passthrough.topics, bag)
        placed = np.stack([m @ below for m in traj.poses])  # one product per pose, as read
        tfs = R.transforms(0.0, fixed, [child] * len(placed), placed, times=pose_t)
        for tk, tf in zip(pose_t.tolist(), tfs, strict=True):
            R.add(tk, "/tf", _TF, R.tf([tf]))
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
                    R.planars(
                        t, fixed, [artefact_frame(a) for a in boxes.ids], boxes.centres, boxes.yaws
                    )
                ),
            )
        doc = {
            "t": round(start + t, 9),
            "live": [int(a) for a in boxes.ids],
            "perceived": [int(a) for a, k in zip(boxes.ids, idx, strict=True) if seen[f, k]],
            "counts": {str(int(a)): int(counts[f, k]) for a, k in zip(boxes.ids, idx, strict=True)},
            "labels": {str(int(a)): str(lb) for a, lb in zip(boxes.ids, boxes.labels, strict=True)},
            "contacts": [int(a) for a, k in zip(boxes.ids, idx, strict=True) if contacts[f, k]],
            "d_max": d_max,
            "tau": tau,
        }
        R.add(t, "/perceived", AUGMENT_TOPICS["/perceived"], String(data=json.dumps(doc)))
    written = dict(R.counts())
    passed: dict[str, int] = {}
    for c in passthrough.channels:
        passed[c.topic] = passed.get(c.topic, 0) + c.count
    path = R.write(out, force=force, passthrough=passthrough)
    return AugmentResult(
        path,
        times,
        start,
        cam_poses,
        scene,
        counts,
        seen,
        contacts,
        written,
        traj.clock,
        traj.clock_note,
        traj.frame,
        traj.frame_note,
        passed,
        camera_note,
    )


def _pose_ns(traj: BagTrajectory, i: int) -> int:
    """The exact stamp (ns, on the trajectory's clock) of pose ``i``."""
    if traj.t_ns is not None:
        return int(traj.t_ns[i])
    return int(round(float(traj.t[i]) * 1e9))


def _bag_start_ns(bag: Source) -> int | None:
    """The bag's first recording time (ns), as ``ros2 bag info`` and a player count from;
    None when the bag cannot tell."""
    try:
        with bag_reader([check_bag_path(bag)]) as reader:
            return int(reader.start_time)
    except (*bag_read_errors(), ValueError, OSError):  # gone since, or not a bag's name
        return None


def _into_bag(bag: Source, traj: BagTrajectory, *stamps_ns: int) -> str:
    """``"24.000 s into the bag (header stamp 1764300024.000 s)"``: stamps on the
    trajectory's clock as seconds after the bag's first recording time (moved onto the
    recording clock by :attr:`~are_stats.logs.BagTrajectory.offset_ns` for header stamps),
    then as read. One stamp, or a range ``"a to b s ..."``."""
    header = traj.clock == "header"
    shift = traj.offset_ns if header else 0
    start = _bag_start_ns(bag)
    raw = " to ".join(f"{n * 1e-9:.3f}" for n in stamps_ns)
    what = ("header stamp" if header else "recording time") + ("s" if len(stamps_ns) > 1 else "")
    if start is None:  # an unreadable start: from the trajectory's first stamp instead
        start, into = traj.start_ns - shift, "after the trajectory's start"
    else:
        into = "into the bag"
    rel = " to ".join(f"{(n - shift - start) * 1e-9:.3f}" for n in stamps_ns)
    return f"{rel} s {into} ({what} {raw} s)"


def _grid_text(width: int, height: int, resolution: float, origin: Sequence[float]) -> str:
    x, y, yaw = (float(v) for v in origin)
    return (
        f"{width} x {height} cells of {resolution:.6g} m, origin ({x:.6g}, {y:.6g}, yaw {yaw:.6g})"
    )


def _check_bag_map(
    bag: Source, channels: Sequence[PassChannel], grid: OccupancyGrid, map_path: Source
) -> None:
    """Refuse an input ``/map`` that passes through but cannot be ``--map`` (``grid``):
    a type other than ``nav_msgs/msg/OccupancyGrid``, or a last message (a SLAM run's final
    map, the one ``map_saver`` writes) of another width, height, resolution or origin. Its
    cells are not compared: an edited map (keep-out areas) or a SLAM update is the same map.

    Raises
    ------
    are_stats.inputs.InputError
        Naming the bag's ``/map`` and ``--map`` with both geometries, and what to do.
    """
    want = AUGMENT_TOPICS["/map"]
    types = sorted({c.msgtype for c in channels if c.topic == "/map"})
    if types != [want]:
        raise InputError(
            bag,
            "topic /map",
            f"a {want} (passed through as the output's /map, the map of --map {map_path})",
            Described(
                f"{', '.join(types)}; leave /map out with --topics and the output's /map is --map's"
            ),
        )
    p = check_bag_path(bag)
    last, count = None, 0
    with bag_reader(
        [p], default_typestore=partial(vision_msgs_typestore, 1 if p.suffix == ".bag" else 2)
    ) as reader:
        conns = [c for c in reader.connections if c.topic == "/map"]
        for _, _, msg in bag_messages(reader, conns, p):
            last, count = msg, count + 1
    if last is None:  # a channel without messages: nothing passes through to disagree
        return
    info, o = last.info, last.info.origin
    q = o.orientation
    yaw = float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
    theirs = (int(info.width), int(info.height), float(info.resolution))
    origin = (float(o.position.x), float(o.position.y), yaw)
    res = float(grid.resolution)
    turn = float(np.angle(np.exp(1j * (yaw - float(grid.origin[2])))))
    same = (
        theirs[:2] == (grid.width, grid.height)
        and abs(theirs[2] - res) <= MAP_RESOLUTION_RTOL * res
        and bool(np.all(np.abs(np.subtract(origin[:2], grid.origin[:2])) <= MAP_ORIGIN_CELLS * res))
        and abs(turn) <= MAP_YAW_TOL
    )
    if not same:
        which = "its one message" if count == 1 else f"the last of its {count} messages"
        raise InputError(
            bag,
            f"topic /map ({which})",
            f"the map of --map {map_path} "
            f"({_grid_text(grid.width, grid.height, res, grid.origin)}): the input's /map "
            "passes through beside the /augmented_map drawn on --map",
            Described(
                f"{_grid_text(*theirs, origin)}; pass the bag's map as --map, or leave /map "
                "out with --topics (the output's /map is then --map's)"
            ),
        )


def _robot_child(
    traj: BagTrajectory, base_frame: str, static_out: bool, bag: Source
) -> tuple[str, np.ndarray]:
    """The frame ``augment`` places in the fixed frame for a bag without ``/tf``, and
    ``T_base_child``: the base itself, or the root of its static chain when the output's
    ``/tf_static`` (``static_out``) gives the base a parent, so that no frame gets two.

    Raises
    ------
    are_stats.inputs.InputError
        When the fixed frame is itself in the base's static chain (the bag's
        ``/tf_static`` already fixes the base in it, against the pose topic).
    """
    if not static_out or not traj.base_parents:
        return base_frame, np.eye(4)
    chain = " -> ".join([*traj.base_parents[::-1], base_frame])
    if traj.frame in traj.base_parents:
        raise InputError(
            bag,
            "topic /tf_static",
            f"a static chain above {base_frame} that does not hold the fixed frame "
            f"{traj.frame!r} (the poses of {traj.source} place {base_frame} in it)",
            Described(f"{chain}; leave /tf_static out with --topics"),
        )
    return traj.base_parents[-1], np.linalg.inv(np.asarray(traj.root_from_base, float))


def _camera_note(
    traj: BagTrajectory, base_frame: str, camera: object, cam: CameraModel, topics: dict[str, str]
) -> str:
    """Where the camera mount comes from when it is not the bag's tree (``""`` when it
    is): the camera file's pose or 1 m above the base, and how to use the bag's camera."""
    if traj.mount is not None:
        return ""
    posed = not np.allclose(getattr(cam, "pose", np.eye(4)), np.eye(4))
    what = "the camera file's pose" if posed else "default, 1 m above the base looking forward"
    if traj.camera_frame:
        return (
            f"the bag's tree has no static chain {base_frame} -> ... -> {traj.camera_frame} "
            f"(/tf_static): the camera is mounted by {what}"
        )
    name = "the shipped front_camera" if camera is None else "the --camera file"
    infos = sorted(t for t, typ in topics.items() if typ.split("/")[-1] == "CameraInfo")
    hint = f"--camera-info-topic {infos[0]}" if infos else "--camera-frame FRAME"
    return f"camera: {name}, mounted by {what}, not from the bag's tree; {hint} uses the bag's"


def _period_frames(
    pose_t: np.ndarray,
    period: float,
    cam: CameraModel,
    grid: OccupancyGrid,
    bag: Source,
    gap: float,
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
    scene: Scene, times: np.ndarray, horizon: float, traj: BagTrajectory, bag: Source, seed: int
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
                f"{times[0]:.3f} to {times[-1]:.3f} s and meet none of them (scenario time 0 "
                f"is the trajectory's start, {_into_bag(bag, traj, traj.start_ns)}); try "
                "--clock header or --clock log, another --seed, or more camera frames"
            ),
        )
