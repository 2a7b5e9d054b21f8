"""Export a mission to MCAP with ROS 2 message types, for Foxglove Studio or rviz replays.

Messages are built and CDR-serialised with ``rosbags`` (ROS 2 Humble typestore) and written
with the ``mcap`` writer, one ``ros2msg`` schema per type (the full definition with its
dependencies, as ``ros2 bag`` records it). Topics (frame ``map``):

=====================  ================================  =====================================
topic                  type                              when
=====================  ================================  =====================================
``/map``               ``nav_msgs/msg/OccupancyGrid``     once, at t = 0 (the real M_2D)
``/augmented_map``     ``nav_msgs/msg/OccupancyGrid``     each scene update (planner's grid)
``/artefacts``         ``visualization_msgs/msg/MarkerArray``  each scene update (boxes: green
                                                         perceived, grey occluded / unseen)
``/robot_pose``        ``geometry_msgs/msg/PoseStamped``  each sampled robot pose
``/plan``              ``nav_msgs/msg/Path``              each successful (re)plan
``/goals``             ``visualization_msgs/msg/MarkerArray``  once (goal spheres)
=====================  ================================  =====================================
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from are_stats._atomic import atomic_path

__all__ = ["MCAP_TOPICS", "export_mcap"]

#: Topic -> ROS 2 message type written by :func:`export_mcap`.
MCAP_TOPICS = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/augmented_map": "nav_msgs/msg/OccupancyGrid",
    "/artefacts": "visualization_msgs/msg/MarkerArray",
    "/robot_pose": "geometry_msgs/msg/PoseStamped",
    "/plan": "nav_msgs/msg/Path",
    "/goals": "visualization_msgs/msg/MarkerArray",
}

_PERCEIVED = (0.2, 0.8, 0.2, 0.8)
_OCCLUDED = (0.5, 0.5, 0.5, 0.5)


def export_mcap(
    path: str | os.PathLike, grid: Any, trace: Any, *, force: bool = False, frame: str = "map"
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
        ``frame_id`` of every message.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        If ``trace`` is not a recorded trace.
    """
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    from are_stats.experiments._loop import MissionTrace

    if not isinstance(trace, MissionTrace):
        raise ValueError(
            f"trace: expected a MissionTrace (run_mission(..., record=True).trace), "
            f"got {type(trace).__name__}"
        )
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]
    Header = T["std_msgs/msg/Header"]
    Pose = T["geometry_msgs/msg/Pose"]
    Point = T["geometry_msgs/msg/Point"]
    Quat = T["geometry_msgs/msg/Quaternion"]
    Vec3 = T["geometry_msgs/msg/Vector3"]
    Color = T["std_msgs/msg/ColorRGBA"]
    Duration = T["builtin_interfaces/msg/Duration"]

    def stamp(t: float) -> Any:
        sec = int(math.floor(t))
        return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)

    def header(t: float) -> Any:
        return Header(stamp=stamp(t), frame_id=frame)

    def pose(x: float, y: float, yaw: float, z: float = 0.0) -> Any:
        return Pose(
            position=Point(x=float(x), y=float(y), z=float(z)),
            orientation=Quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        )

    def occ_grid(t: float, g: Any) -> Any:
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=stamp(t), resolution=float(g.resolution), width=g.width,
            height=g.height, origin=pose(g.origin[0], g.origin[1], g.origin[2]),
        )  # fmt: skip
        return T["nav_msgs/msg/OccupancyGrid"](
            header=header(t), info=info, data=g.data.ravel().astype(np.int8)
        )

    def marker(t: float, ns: str, mid: int, mtype: int, p: Any, scale, rgba, action=0) -> Any:
        return T["visualization_msgs/msg/Marker"](
            header=header(t), ns=ns, id=int(mid), type=mtype, action=action, pose=p,
            scale=Vec3(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])),
            color=Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
            lifetime=Duration(sec=0, nanosec=0), frame_locked=False, points=[], colors=[],
            texture_resource="", texture=T["sensor_msgs/msg/CompressedImage"](
                header=header(t), format="", data=np.zeros(0, np.uint8)),
            uv_coordinates=[], text="", mesh_resource="",
            mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
            mesh_use_embedded_materials=False,
        )  # fmt: skip

    MarkerArray = T["visualization_msgs/msg/MarkerArray"]
    messages: list[tuple[float, str, Any]] = [(0.0, "/map", occ_grid(0.0, grid))]
    goals = [
        marker(0.0, "goals", k, 2, pose(x, y, 0.0, 0.1), (0.4, 0.4, 0.4), (0.9, 0.2, 0.2, 1.0))
        for k, (x, y) in enumerate(trace.goals)
    ]
    messages.append((0.0, "/goals", MarkerArray(markers=goals)))
    for sc in trace.scenes:
        t = float(sc["t"])
        messages.append((t, "/augmented_map", occ_grid(t, sc["grid"])))
        ms = [marker(t, "artefacts", 0, 0, pose(0, 0, 0), (1, 1, 1), (0, 0, 0, 0), action=3)]
        for k in range(len(sc["ids"])):
            c, h = sc["centres"][k], sc["half"][k]
            rgba = _PERCEIVED if sc["perceived"][k] else _OCCLUDED
            ms.append(
                marker(t, "artefacts", int(sc["ids"][k]), 1, pose(c[0], c[1], sc["yaws"][k], c[2]),
                       2 * h, rgba)
            )  # fmt: skip
        messages.append((t, "/artefacts", MarkerArray(markers=ms)))
    PoseStamped = T["geometry_msgs/msg/PoseStamped"]
    for t, x, y, yaw in trace.poses:
        messages.append(
            (float(t), "/robot_pose", PoseStamped(header=header(t), pose=pose(x, y, yaw)))
        )
    for t, p in trace.plans:
        yaw = np.r_[np.arctan2(np.diff(p[:, 1]), np.diff(p[:, 0])), 0.0]
        poses = [
            PoseStamped(header=header(t), pose=pose(x, y, a))
            for (x, y), a in zip(p, yaw, strict=True)
        ]
        messages.append((float(t), "/plan", T["nav_msgs/msg/Path"](header=header(t), poses=poses)))
    messages.sort(key=lambda m: m[0])

    target = Path(path)
    with atomic_path(target, force=force) as tmp, open(tmp, "wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="are_stats")
        channels = {}
        for topic, typ in MCAP_TOPICS.items():
            sid = w.register_schema(
                name=typ,
                encoding="ros2msg",
                data=ts.generate_msgdef(typ, ros_version=2)[0].encode(),
            )
            channels[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        for seq, (t, topic, msg) in enumerate(messages):
            ns = int(round(t * 1e9))
            w.add_message(
                channel_id=channels[topic], log_time=ns, publish_time=ns, sequence=seq,
                data=bytes(ts.serialize_cdr(msg, MCAP_TOPICS[topic])),
            )  # fmt: skip
        w.finish()
    return target
