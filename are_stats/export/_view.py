"""A picture of an exported or augmented MCAP, as RViz or Foxglove show it from above.

:func:`plot_mcap` reads what a viewer subscribes to (``/map``, ``/augmented_map``, the
``/artefacts`` markers and the robot's ``/tf`` tree) from an MCAP file or ROS bag written by
:func:`~are_stats.export.augment_bag` or :func:`~are_stats.export.export_mcap` and draws
the scene at one time: the map (the last ``/map``, a SLAM run's finished map), the
augmented cells, each artefact's box (green perceived, grey occluded, as the markers are
coloured) with its label, the robot's path and pose and its camera's optical axis. It
needs no ROS install, so a user can check an augmented bag
before replaying it (``are-stats show OUT.mcap``).
"""

from __future__ import annotations

import json
import os
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple, TypeVar

import numpy as np

from are_stats._atomic import check_writable, save_figure
from are_stats.builder import box_corners
from are_stats.environment import OccupancyGrid
from are_stats.export._ros import ROS_FRAMES
from are_stats.inputs import Described, InputError, get_float
from are_stats.logs import (
    bag_messages,
    bag_read_errors,
    bag_reader,
    check_bag_path,
    read_trajectory,
    vision_msgs_typestore,
)

__all__ = ["BagView", "plot_mcap", "read_view"]

_GRID = ("nav_msgs/msg/OccupancyGrid", "nav_msgs/OccupancyGrid")
_MARKERS = ("visualization_msgs/msg/MarkerArray", "visualization_msgs/MarkerArray")
_CAMERA_INFO = ("sensor_msgs/msg/CameraInfo", "sensor_msgs/CameraInfo")
_STRING = ("std_msgs/msg/String", "std_msgs/String")
#: Length (m) of the camera's horizontal field of view as drawn when the bag does not say
#: the range of A_f (``d_max`` of ``/perceived``, written by ``augment``).
_FRUSTUM_DRAWN = 6.0


class BagView(NamedTuple):
    """What a top-down viewer shows of a bag at one time (see :func:`read_view`).

    Attributes
    ----------
    t : float
        Seconds after the bag's first message (recording clock).
    grid : OccupancyGrid
        ``/map``: its last message, the finished map of a SLAM run (the one ``map_saver``
        writes and ``augment`` checks ``--map`` against), whatever ``t``.
    augmented : OccupancyGrid or None
        The last ``/augmented_map`` at or before ``t``.
    boxes : (n, 5) float
        ``x, y, yaw, length, width`` of each artefact box of the last ``/artefacts`` message
        at or before ``t``.
    labels : list of str
        Each box's text marker (label and id), ``""`` without one.
    perceived : (n,) bool
        The box is drawn perceived (green) rather than occluded (grey).
    path : (m, 3) float or None
        The robot's base poses ``x, y, yaw`` over the bag (``/tf``), None without a tree.
    pose : (3,) float or None
        The robot's pose at ``t``.
    camera : (3, 2) float or None
        The camera's optical centre and the ends of its horizontal field of view at the
        range of A_f (``d_max`` of the ``/perceived`` message then; 6 m out without one),
        from the ``CameraInfo`` intrinsics (60 degrees without), in the plane.
    n_boxes : (k,) int
        Boxes in each ``/artefacts`` message (its length is the number of messages).
    frame : str
        The fixed frame of the picture.
    map_t : float
        Seconds after the bag's first message of the ``/map`` message drawn.
    n_maps : int
        ``/map`` messages in the bag (more than one: a map built as the robot went).
    """

    t: float
    grid: OccupancyGrid
    augmented: OccupancyGrid | None
    boxes: np.ndarray
    labels: list
    perceived: np.ndarray
    path: np.ndarray | None
    pose: np.ndarray | None
    camera: np.ndarray | None
    n_boxes: np.ndarray
    frame: str
    map_t: float = 0.0
    n_maps: int = 1


#: A bag's message (any ROS 1 or ROS 2 type store's class: read by duck typing).
_Msg = Any
#: Boxes of one ``/artefacts`` message: (n, 5) ``x, y, yaw, length, width``, labels, seen.
_Boxes = tuple[np.ndarray, list[str], np.ndarray]
_T = TypeVar("_T")


def _last(items: list[tuple[int, _T]], at_ns: int) -> _T | None:
    """The value of the last ``(stamp, value)`` at or before ``at_ns``, else None."""
    before = [v for ts, v in items if ts <= at_ns]
    return before[-1] if before else None


def _yaw(q: _Msg) -> float:
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))


def _grid(msg: _Msg) -> OccupancyGrid:
    info = msg.info
    h, w = int(info.height), int(info.width)
    data = np.asarray(msg.data, np.int8).reshape(h, w)
    o = info.origin
    return OccupancyGrid(
        data, float(info.resolution), (o.position.x, o.position.y, _yaw(o.orientation))
    )


def _reach(text: str) -> float | None:
    """``d_max`` (m) of a ``/perceived`` document, None when it has no finite one."""
    try:
        d = float(json.loads(text).get("d_max"))
    except (ValueError, TypeError, AttributeError):
        return None
    return d if np.isfinite(d) and d > 0 else None


def _boxes(msg: _Msg) -> _Boxes:
    """Cubes of ns ``artefacts`` (added) with their text markers of ns ``labels``."""
    text = {int(m.id): str(m.text) for m in msg.markers if m.ns == "labels" and m.action == 0}
    rows, labels, seen = [], [], []
    for m in msg.markers:
        if m.ns != "artefacts" or m.action != 0 or m.type != 1:
            continue
        p = m.pose
        rows.append([p.position.x, p.position.y, _yaw(p.orientation), m.scale.x, m.scale.y])
        labels.append(text.get(int(m.id), ""))
        seen.append(m.color.g > m.color.r)
    return np.asarray(rows, float).reshape(-1, 5), labels, np.asarray(seen, bool)


def read_view(
    path: str | os.PathLike,
    at: float | None = None,
    *,
    map_frame: str = "map",
    base_frame: str = "base_link",
) -> BagView:
    """What a top-down viewer shows of an MCAP or bag at one time.

    Parameters
    ----------
    path : path
        An MCAP file or bag holding ``/map`` (``nav_msgs/OccupancyGrid``), as the outputs
        of ``are-stats augment`` and ``are-stats experiment --mcap`` do.
    at : float, optional
        Seconds after the bag's first message; default the ``/artefacts`` message with the
        most perceived boxes (then the most boxes).
    map_frame, base_frame : str
        The ``/tf`` frames of the robot's pose (a bag without the chain shows no robot);
        the camera is the frame of the bag's first ``CameraInfo`` topic (without one, the
        ``camera_optical_frame`` of :func:`~are_stats.export.export_mcap`), when
        ``/tf_static`` mounts it on the base.

    Returns
    -------
    BagView

    Raises
    ------
    are_stats.inputs.InputError
        Naming the file: not a bag, no ``/map`` message, ``at`` outside the bag.
    """
    p = check_bag_path(path)
    last_map: tuple[int, _Msg] | None = None  # the finished map: only the last is decoded
    n_maps = 0
    augmented: list[tuple[int, _Msg]] = []
    markers: list[tuple[int, _Boxes]] = []
    reach: list[tuple[int, float | None]] = []  # the range of A_f, from /perceived
    try:
        with bag_reader([p], default_typestore=partial(vision_msgs_typestore, 2)) as reader:
            t0 = int(reader.start_time)
            t1 = int(reader.end_time)
            info = sorted(c.topic for c in reader.connections if c.msgtype in _CAMERA_INFO)
            conns = [
                c
                for c in reader.connections
                if (c.topic in ("/map", "/augmented_map") and c.msgtype in _GRID)
                or (c.topic == "/artefacts" and c.msgtype in _MARKERS)
                or (c.topic == "/perceived" and c.msgtype in _STRING)
            ]
            # (rosbags reads every connection when given none)
            for conn, ts, msg in bag_messages(reader, conns, p) if conns else ():
                if conn.topic == "/map":
                    last_map, n_maps = (int(ts), msg), n_maps + 1
                elif conn.topic == "/augmented_map":
                    augmented.append((int(ts), msg))
                elif conn.topic == "/perceived":
                    reach.append((int(ts), _reach(msg.data)))
                else:
                    markers.append((int(ts), _boxes(msg)))
    except bag_read_errors() as err:
        raise ValueError(
            f"{p}: expected a readable ROS 1 / ROS 2 bag or MCAP file, got: "
            f"{type(err).__name__}: {err}"
        ) from None
    if last_map is None:
        raise InputError(p, "topic /map", "a nav_msgs/OccupancyGrid message", Described("none"))
    grid = _grid(last_map[1])
    span = (t1 - t0) * 1e-9
    n_boxes = np.array([len(b[0]) for _, b in markers], np.int64)
    if at is None:  # the most perceived artefacts, then the most artefacts
        score = [(int(b[2].sum()), len(b[0])) for _, b in markers]
        at_ns = markers[max(range(len(score)), key=score.__getitem__)][0] if markers else t0
    else:
        at = get_float(at, "--at", "", lo=0.0, hi=span)
        at_ns = t0 + int(round(at * 1e9))

    aug_msg = _last(augmented, at_ns)
    boxes, labels, seen = _last(markers, at_ns) or (np.zeros((0, 5)), [], np.zeros(0, bool))
    path_xy = pose = camera = None
    frame = map_frame
    # the camera: the CameraInfo's frame, else the optical frame of our own MCAP exports
    tries = [{"camera_info_topic": info[0]}] if info else [{"camera_frame": ROS_FRAMES["F_C"]}]
    traj = None
    for kw in [*tries, {}]:
        try:
            traj = read_trajectory(p, map_frame=map_frame, base_frame=base_frame, clock="log", **kw)
            break
        except (InputError, ValueError):
            continue
    if traj is not None:
        frame = traj.frame
        yaw = np.arctan2(traj.poses[:, 1, 0], traj.poses[:, 0, 0])
        path_xy = np.column_stack([traj.poses[:, 0, 3], traj.poses[:, 1, 3], yaw])
        k = int(np.clip(np.searchsorted(traj.t_ns, at_ns, side="right") - 1, 0, len(yaw) - 1))
        pose = path_xy[k]
        if traj.mount is not None:
            cam = traj.poses[k] @ traj.mount
            axis = cam[:3, 2]
            heading = float(np.arctan2(axis[1], axis[0]))
            half = np.deg2rad(30.0)  # without intrinsics: a 60 degree field of view
            if traj.camera_info is not None and traj.camera_info["k"][0] > 0:
                fx, width = traj.camera_info["k"][0], traj.camera_info["width"]
                half = float(np.arctan2(width / 2.0, fx))
            ends = heading + np.array([-half, half])
            d = _last(reach, at_ns) or _FRUSTUM_DRAWN
            camera = np.vstack(
                [cam[:2, 3], cam[:2, 3] + d * np.column_stack([np.cos(ends), np.sin(ends)])]
            )
    return BagView(
        (at_ns - t0) * 1e-9,
        grid,
        None if aug_msg is None else _grid(aug_msg),
        boxes,
        labels,
        seen,
        path_xy,
        pose,
        camera,
        n_boxes,
        frame,
        (last_map[0] - t0) * 1e-9,
        n_maps,
    )


def plot_mcap(
    path: str | os.PathLike,
    out: str | os.PathLike | None = None,
    *,
    at: float | None = None,
    force: bool = False,
    map_frame: str = "map",
    base_frame: str = "base_link",
) -> Path:
    """Draw an MCAP or bag from above at one time, as RViz's Map, TF and MarkerArray
    displays (or Foxglove's 3D panel) show it (``are-stats show OUT.mcap``).

    Parameters
    ----------
    path : path
        See :func:`read_view`.
    out : path, optional
        The PNG (default ``<bag name>.png`` in the working directory).
    at, map_frame, base_frame
        See :func:`read_view`.
    force : bool
        Overwrite ``out``.

    Returns
    -------
    Path
        The PNG written (atomically).
    """
    # lazy: matplotlib adds 0.65 s CPU to `import are_stats.export` (the four imports)
    import matplotlib.pyplot as plt
    import matplotlib.transforms
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon

    target = check_writable(Path(out) if out is not None else Path(f"{Path(path).stem}.png"), force)
    v = read_view(path, at, map_frame=map_frame, base_frame=base_frame)
    g = v.grid
    rgb = np.full(g.shape + (3,), 0.55)
    rgb[g.free] = 1.0
    rgb[g.occupied] = 0.0
    if v.augmented is not None and v.augmented.shape == g.shape:
        added = v.augmented.occupied & ~g.occupied
        rgb[added] = (0.95, 0.6, 0.6)
    x0, y0, yaw = g.origin
    w, h = g.width * g.resolution, g.height * g.resolution
    fig, ax = plt.subplots(figsize=(8.5, float(np.clip(8 * h / w + 0.8, 2.0, 20.0))), dpi=120)
    tr = matplotlib.transforms.Affine2D().rotate(yaw).translate(x0, y0) + ax.transData
    ax.imshow(rgb, origin="lower", extent=(0, w, 0, h), interpolation="nearest", transform=tr)
    if v.boxes.shape[0]:
        corners = box_corners(v.boxes[:, :2], v.boxes[:, 3:5] / 2, v.boxes[:, 2])
        for poly, seen, text in zip(corners, v.perceived, v.labels, strict=True):
            col = (0.1, 0.75, 0.2) if seen else (0.5, 0.5, 0.5)
            ax.add_patch(Polygon(poly, closed=True, facecolor=col, edgecolor="k", lw=0.5))
            if text:  # the colour says occluded: the label alone; the perceived ones on top
                ax.annotate(
                    text.removesuffix(" (occluded)"),
                    poly.mean(axis=0),
                    xytext=(3, 3),
                    textcoords="offset points",
                    fontsize=7 if seen else 6,
                    fontweight="bold" if seen else "normal",
                    color="k" if seen else (0.25, 0.25, 0.25),
                    zorder=4 if seen else 3,
                    bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7}
                    if seen
                    else None,
                )
    if v.path is not None:
        ax.plot(v.path[:, 0], v.path[:, 1], "-", color=(0.2, 0.4, 0.9), lw=1.0)
    if v.pose is not None:
        x, y, th = v.pose
        ax.plot([x], [y], "o", color=(0.1, 0.25, 0.8), ms=7)
        ax.annotate(
            "",
            (x + 0.6 * np.cos(th), y + 0.6 * np.sin(th)),
            (x, y),
            arrowprops={"arrowstyle": "->", "color": (0.1, 0.25, 0.8)},
        )
    if v.camera is not None:
        ax.add_patch(
            Polygon(
                v.camera,
                closed=True,
                facecolor=(1.0, 0.6, 0.0, 0.25),
                edgecolor=(0.9, 0.5, 0.0),
                lw=1.0,
            )
        )
    cw = g.corners_world
    ax.set_xlim(cw[:, 0].min(), cw[:, 0].max())
    ax.set_ylim(cw[:, 1].min(), cw[:, 1].max())
    ax.set_aspect("equal")
    ax.set_xlabel(f"x in {v.frame} (m)")
    ax.set_ylabel(f"y in {v.frame} (m)")
    n_seen = int(v.perceived.sum())
    which = f"\n/map: the last of {v.n_maps}, at {v.map_t:.1f} s" if v.n_maps > 1 else ""
    ax.set_title(
        f"{Path(path).name} at {v.t:.1f} s: {v.boxes.shape[0]} artefacts, {n_seen} perceived"
        + which,
        fontsize=10,
    )
    handles = [
        Patch(facecolor="white", edgecolor="k", label="/map free"),
        Patch(facecolor="black", label="/map occupied"),
        Patch(facecolor=(0.95, 0.6, 0.6), label="/augmented_map artefact cells"),
        Patch(facecolor=(0.1, 0.75, 0.2), edgecolor="k", label="/artefacts perceived"),
        Patch(facecolor=(0.5, 0.5, 0.5), edgecolor="k", label="/artefacts occluded"),
    ]
    if v.path is not None:
        handles.append(Line2D([], [], color=(0.2, 0.4, 0.9), marker="o", label="/tf base_link"))
    if v.camera is not None:
        handles.append(
            Patch(facecolor=(1.0, 0.6, 0.0, 0.25), edgecolor=(0.9, 0.5, 0.0), label="camera view")
        )
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return save_figure(fig, target, force, dpi=120, close=True)
