"""Export a mission to MCAP with ROS 2 message types, for Foxglove Studio, rviz or
``ros2 bag play``.

Messages use the REP-105 frames of :data:`~are_stats.export.ROS_FRAMES` (``map``,
``base_link``, ``camera_optical_frame``, ``artefact_<id>``) and are stamped ``start + t``,
so a file lines up with a real recording (see :mod:`are_stats.export._ros`). Topics:

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
``/artefacts``         ``visualization_msgs/msg/MarkerArray``  each scene update: boxes (green
                                                             perceived, grey occluded) and
                                                             class-label text markers
``/robot_pose``        ``geometry_msgs/msg/PoseStamped``     each sampled robot pose
``/tf``                ``tf2_msgs/msg/TFMessage``            each robot pose (``map ->
                                                             base_link``) and scene update
                                                             (``map -> artefact_<id>``)
``/tf_static``         ``tf2_msgs/msg/TFMessage``            once (``base_link ->
                                                             camera_optical_frame``)
``/plan``              ``nav_msgs/msg/Path``                 each successful (re)plan
``/goals``             ``visualization_msgs/msg/MarkerArray``  once (goal spheres)
=====================  ====================================  ===============================
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from are_stats.environment import OccupancyGrid
from are_stats.export._ros import ROS_FRAMES, RosMessages, artefact_frame, parse_start_time

if TYPE_CHECKING:
    from are_stats.experiments import MissionTrace

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

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        If ``trace`` is not a recorded trace or ``start_time`` is not a time.
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
        R.add(
            t,
            "/artefacts",
            MCAP_TOPICS["/artefacts"],
            R.artefact_markers(
                t, sc["ids"], sc["centres"], sc["half"], sc["yaws"], sc["labels"], sc["perceived"]
            ),
        )
        tfs = [
            R.planar(t, frame, artefact_frame(a), c[0], c[1], yaw, c[2])
            for a, c, yaw in zip(sc["ids"], sc["centres"], sc["yaws"], strict=True)
        ]
        if tfs:
            R.add(t, "/tf", MCAP_TOPICS["/tf"], R.tf(tfs))
    PoseStamped = T["geometry_msgs/msg/PoseStamped"]
    for t, x, y, yaw in trace.poses:
        R.add(
            float(t),
            "/robot_pose",
            MCAP_TOPICS["/robot_pose"],
            PoseStamped(header=R.header(t), pose=R.pose(x, y, yaw)),
        )
        R.add(float(t), "/tf", MCAP_TOPICS["/tf"], R.tf([R.planar(t, frame, base, x, y, yaw)]))
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
