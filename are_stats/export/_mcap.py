"""Export a mission to MCAP with ROS 2 message types, for Foxglove Studio, rviz or
``ros2 bag play``.

Messages use the REP-105 frames of :data:`~are_stats.export.ROS_FRAMES` (``map``,
``base_link``, ``camera_optical_frame``, ``artefact_<id>``) and are stamped ``start + t``,
so a file lines up with a real recording (see :mod:`are_stats.export._ros`). The
artefacts move as they did in the mission: between scene updates their poses are sampled
every ``1 / rate`` s (10 Hz, as ``serve`` publishes and the robot's poses come) from the
mission's scene, ``trace.scene.at(t)`` (:meth:`~are_stats.Scene.at`, the sampler ``serve``
and ``augment`` use too); what the planner saw stays at the scene updates. Topics:

=====================  ====================================  ===============================
topic                  type                                  when
=====================  ====================================  ===============================
``/map``               ``nav_msgs/msg/OccupancyGrid``        once, at t = 0 (the real M_2D)
``/augmented_map``     ``nav_msgs/msg/OccupancyGrid``        each scene update: M_2D with
                                                             every live artefact (Fig. 4b,
                                                             as ``augment`` publishes it)
``/planner_map``       ``nav_msgs/msg/OccupancyGrid``        each scene update: what the
                                                             planner saw (the perceived
                                                             artefacts, moving ones also at
                                                             their next pose)
``/artefacts``         ``visualization_msgs/msg/MarkerArray``  each scene update and every
                                                             0.1 s between (``rate``):
                                                             boxes (green perceived, grey
                                                             occluded, as at the last
                                                             update) and class-label texts
``/robot_pose``        ``geometry_msgs/msg/PoseStamped``     each sampled robot pose
``/tf``                ``tf2_msgs/msg/TFMessage``            each robot pose (``map ->
                                                             base_link``); each scene update
                                                             and every 0.1 s between
                                                             (``map -> artefact_<id>``)
``/tf_static``         ``tf2_msgs/msg/TFMessage``            once (``base_link ->
                                                             camera_optical_frame``)
``/plan``              ``nav_msgs/msg/Path``                 each successful (re)plan
``/goals``             ``visualization_msgs/msg/MarkerArray``  once (goal spheres)
=====================  ====================================  ===============================
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from are_stats.environment import OccupancyGrid
from are_stats.export._ros import ROS_FRAMES, RosMessages, artefact_frame, parse_start_time
from are_stats.inputs import get_float

if TYPE_CHECKING:
    from are_stats.experiments import MissionTrace
    from are_stats.scenarios import Boxes

__all__ = ["MCAP_TOPICS", "export_mcap"]

#: Topic -> ROS 2 message type written by :func:`export_mcap`.
MCAP_TOPICS = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/augmented_map": "nav_msgs/msg/OccupancyGrid",
    "/planner_map": "nav_msgs/msg/OccupancyGrid",
    "/artefacts": "visualization_msgs/msg/MarkerArray",
    "/robot_pose": "geometry_msgs/msg/PoseStamped",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/plan": "nav_msgs/msg/Path",
    "/goals": "visualization_msgs/msg/MarkerArray",
}


def export_mcap(
    path: str | os.PathLike,
    grid: OccupancyGrid,
    trace: MissionTrace,
    *,
    force: bool = False,
    frame: str = "map",
    start_time: float | str = 0.0,
    mount: npt.ArrayLike | None = None,
    rate: float = 10.0,
) -> Path:
    """Write a recorded mission (``run_mission(..., record=True).trace``) to an MCAP file.

    Parameters
    ----------
    path : path
        The ``.mcap`` file to write (atomically).
    grid : OccupancyGrid
        The real map M_2D.
    trace : MissionTrace
        The mission's trace.
    force : bool
        Overwrite an existing file.
    frame : str
        The fixed frame (``map``): ``frame_id`` of maps, markers and poses.
    start_time : float or str
        Wall-clock time of the mission's t = 0, seconds since the epoch or ISO 8601
        (:func:`~are_stats.export.parse_start_time`); default 0 (1970).
    mount : (4, 4) float, optional
        ``T_base_optical`` of the camera on ``/tf_static`` (default: the default
        :class:`~are_stats.experiments.Robot`'s camera,
        ``optical_from_base(Robot().camera_xyz, Robot().camera_rpy)``).
    rate : float
        Hz: between scene updates the artefacts' poses (``/tf`` ``map -> artefact_<id>``
        and ``/artefacts``) are published every ``1 / rate`` s of the mission's clock, as
        the mission's scene has them then (``trace.scene.at(t)``); default 10 Hz, the rate
        of ``serve``'s frames and of the robot's poses at the default
        :class:`~are_stats.experiments.Robot` (0.05 m steps at 0.5 m/s). A trace without
        its scene (``trace.scene`` None) publishes them at the scene updates only.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        If ``trace`` is not a recorded trace, ``start_time`` is not a time or ``rate`` is
        not a finite number > 0.
    """
    # lazy: experiments +0.10 s (whose sweep imports export lazily), perception (Warp) +0.85 s
    # CPU on `import are_stats.export`
    from are_stats.experiments import MissionTrace, Robot
    from are_stats.perception import optical_from_base, perceived_grid

    if not isinstance(trace, MissionTrace):
        raise ValueError(
            f"trace: expected a MissionTrace (run_mission(..., record=True).trace), "
            f"got {type(trace).__name__}"
        )
    rate = get_float(rate, "rate", "", lo=0.0, lo_open=True)
    base, cam = ROS_FRAMES["F_R"], ROS_FRAMES["F_C"]

    if mount is None:
        mount = optical_from_base(Robot().camera_xyz, Robot().camera_rpy)
    mount = np.asarray(mount, float)
    R = RosMessages(parse_start_time(start_time, "start_time"), frame)
    T = R.T
    R.add(0.0, "/map", MCAP_TOPICS["/map"], R.occupancy_grid(0.0, grid), latched=True)
    R.add(
        0.0,
        "/tf_static",
        MCAP_TOPICS["/tf_static"],
        R.tf([R.transform(0.0, base, cam, mount)]),
        latched=True,
    )
    goals = [
        R.marker(0.0, "goals", k, 2, R.pose(x, y, 0.0, 0.1), (0.4, 0.4, 0.4), (0.9, 0.2, 0.2, 1))
        for k, (x, y) in enumerate(trace.goals)
    ]
    R.add(
        0.0,
        "/goals",
        MCAP_TOPICS["/goals"],
        T["visualization_msgs/msg/MarkerArray"](markers=goals),
        latched=True,
    )
    for sc in trace.scenes:
        t = float(sc["t"])
        everyone = np.ones(len(sc["ids"]), bool)
        # the AR-builder's augmented_grid of the live boxes (perceived_grid holds them in
        # one): the map augment publishes and the planner's map is made of
        aug = perceived_grid(grid, sc["centres"], sc["half"], sc["yaws"], everyone)
        R.add(t, "/augmented_map", MCAP_TOPICS["/augmented_map"], R.occupancy_grid(t, aug))
        R.add(t, "/planner_map", MCAP_TOPICS["/planner_map"], R.occupancy_grid(t, sc["grid"]))
    update = None  # the last scene update's /artefacts
    for t, k, boxes in _artefact_frames(trace, rate):
        sc = trace.scenes[k]
        if boxes is None:  # a scene update: its record
            ids, centres, yaws = sc["ids"], sc["centres"], sc["yaws"]
            markers = update = R.artefact_markers(
                t, ids, centres, sc["half"], yaws, sc["labels"], sc["perceived"]
            )
        else:  # between updates: the scene at t, perceived as at the last update
            ids, centres, yaws = boxes.ids, boxes.centres, boxes.yaws
            if update is not None and np.array_equal(ids, sc["ids"]):
                markers = _moved(R, t, update, centres, yaws)
            else:  # the live set differs from the last update's (a trace cut short)
                last = dict(zip(sc["ids"].tolist(), sc["perceived"].tolist(), strict=True))
                seen = [last.get(a, False) for a in ids.tolist()]
                markers = R.artefact_markers(
                    t, ids, centres, boxes.half_extents, yaws, boxes.labels, seen
                )
        R.add(t, "/artefacts", MCAP_TOPICS["/artefacts"], markers)
        if len(ids):
            tfs = R.planars(t, frame, [artefact_frame(a) for a in ids], centres, yaws)
            R.add(t, "/tf", MCAP_TOPICS["/tf"], R.tf(tfs))
    PoseStamped = T["geometry_msgs/msg/PoseStamped"]
    poses = np.asarray(trace.poses, float).reshape(-1, 4)
    xyz = np.column_stack([poses[:, 1:3], np.zeros(len(poses))])
    base_tfs = R.planars(0.0, frame, [base] * len(poses), xyz, poses[:, 3], poses[:, 0])
    for (t, x, y, yaw), tf in zip(trace.poses, base_tfs, strict=True):
        R.add(
            float(t),
            "/robot_pose",
            MCAP_TOPICS["/robot_pose"],
            PoseStamped(header=R.header(t), pose=R.pose(x, y, yaw)),
        )
        R.add(float(t), "/tf", MCAP_TOPICS["/tf"], R.tf([tf]))
    for t, p in trace.plans:
        yaw = np.r_[np.arctan2(np.diff(p[:, 1]), np.diff(p[:, 0])), 0.0]
        poses = [
            PoseStamped(header=R.header(t), pose=R.pose(x, y, a))
            for (x, y), a in zip(p, yaw, strict=True)
        ]
        R.add(
            float(t),
            "/plan",
            MCAP_TOPICS["/plan"],
            T["nav_msgs/msg/Path"](header=R.header(t), poses=poses),
        )
    return R.write(path, force=force)


def _moved(
    R: RosMessages, t: float, update: object, centres: np.ndarray, yaws: np.ndarray
) -> object:
    """``R.artefact_markers(t, ...)`` of the artefacts of a scene update's ``update`` (its
    MarkerArray: a DELETEALL, then a cube and a label per artefact) at their boxes' poses at
    ``t``, ``centres`` (n, 3) m and ``yaws`` (n,) rad, the same bytes: the update's markers
    (their sizes, colours and labels) restamped and moved, the labels at their height
    above the box, a third of the CPU of building them anew."""
    hdr = R.header(t)
    ms = update.markers
    tex = type(ms[0].texture)(**{**vars(ms[0].texture), "header": hdr})

    def at(m: object, pose: object) -> object:
        return type(m)(**{**vars(m), "header": hdr, "texture": tex, "pose": pose})

    out = [at(ms[0], ms[0].pose)]
    for (x, y, z), yaw, cube, label in zip(
        centres.tolist(), yaws.tolist(), ms[1::2], ms[2::2], strict=True
    ):
        out.append(at(cube, R.pose(x, y, yaw, z)))
        out.append(at(label, R.pose(x, y, 0.0, label.pose.position.z)))
    return type(update)(markers=out)


def _artefact_frames(trace: MissionTrace, rate: float) -> Iterator[tuple[float, int, Boxes | None]]:
    """The times the artefacts are published at, in order: every scene update and, between
    them, every ``1 / rate`` seconds of the mission's clock (``k / rate``, up to its last
    robot pose or scene update; ticks within 1 us of an update are left to it).

    Yields
    ------
    t : float
        Mission time (s).
    k : int
        Index in ``trace.scenes`` of the last scene update at or before ``t``.
    boxes : Boxes or None
        None at a scene update (its record holds the boxes), else the mission's scene at
        ``t`` (``trace.scene.at(t)``, as ``serve`` and ``augment`` sample theirs).
    """
    t_up = np.array([float(sc["t"]) for sc in trace.scenes])
    if trace.scene is None or not t_up.size:  # a trace without its scene: updates only
        yield from ((float(t), k, None) for k, t in enumerate(t_up))
        return
    poses = np.asarray(trace.poses, float).reshape(-1, 4)
    t_end = max(float(t_up[-1]), float(poses[:, 0].max()) if poses.size else 0.0)
    ticks = np.arange(int(np.floor(t_end * rate + 1e-9)) + 1) / rate
    i = np.searchsorted(t_up, ticks)  # the updates are in time order
    gap = np.minimum(
        np.abs(ticks - t_up[np.maximum(i - 1, 0)]),
        np.abs(t_up[np.minimum(i, t_up.size - 1)] - ticks),
    )
    near = gap < 1e-6
    ticks = ticks[~near & (ticks >= t_up[0])]
    times = np.concatenate([t_up, ticks])
    is_update = np.r_[np.ones(t_up.size, bool), np.zeros(ticks.size, bool)]
    order = np.argsort(times, kind="stable")
    last = np.searchsorted(t_up, times, side="right") - 1
    for j in order.tolist():
        t = float(times[j])
        yield t, int(last[j]), None if is_update[j] else trace.scene.at(t)
