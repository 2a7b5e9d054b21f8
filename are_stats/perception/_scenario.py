"""A_f along a robot path for scenes, and the augmented grid the planner sees.

The paper's augmented real environment "comprises only the artefacts which are not
occluded, with respect to the robot field of view" (section 3.3): :func:`perceived_grid`
marks on M_2D the footprints of the perceived artefacts only, and
:func:`perceive_scenario` gives the perceived flags of a scene's artefacts (or several
scenes') along the robot's path (the library side of ``are-stats perceive``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Unpack

import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_finite, describe
from are_stats.builder import ARBuilder, box_centres
from are_stats.environment import OccupancyGrid
from are_stats.inputs import Described, InputError, Source, check_memory, check_work
from are_stats.logs import read_raw_table
from are_stats.perception._camera import CameraModel, check_pose
from are_stats.perception._perceive import TraceOptions, perceived_counts_batch
from are_stats.scenarios import MAX_POSITION, Scene, check_positions

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "check_path_times",
    "check_poses_inside",
    "perceive_scene",
    "perceive_scenario",
    "poses_outside",
    "perceived_grid",
    "read_robot_path",
    "yaw_rotations",
    "MAX_POSITION",
]

#: Memory per (robot pose, artefact of one scenario) pair while perceiving (bytes): the
#: active mask, the counts and the perceived flags.
PAIR_BYTES = 24
#: More memory per pair when boxes move: a centre, a yaw and a rotation per frame.
MOVING_PAIR_BYTES = 104


def read_robot_path(path: str | os.PathLike) -> pd.DataFrame:
    """Read a robot path: a CSV or Parquet table with columns ``t, x, y, yaw``.

    Every cell must be a finite number (no booleans, no empty cells), ``|x|, |y|`` at most
    :data:`MAX_POSITION` metres and the times in non-decreasing order (a path out of order
    would silently change which frame first perceives an artefact).

    Parameters
    ----------
    path : str or PathLike
        The file (``.csv``, ``.tsv``, ``.txt``, ``.parquet`` or ``.pq``).

    Returns
    -------
    pandas.DataFrame
        Columns ``t, x, y, yaw`` (float64), one row per pose, in file order.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) naming the file, the row and the column of the first bad cell
        (``LimitError`` when the table is too large for the memory limit).
    """
    table = read_raw_table(path, "robot path")
    table.require(["t", "x", "y", "yaw"], "robot path")
    cols = {c: table.floats(c, allow_empty=False)[0] for c in ("t", "x", "y", "yaw")}
    check_positions(table, cols)
    t = cols["t"]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise table.error(
            i,
            "t",
            f"times in non-decreasing order (the row before has t = {float(t[i - 1])!r})",
            repr(float(t[i])),
        )
    return pd.DataFrame(cols)


def yaw_rotations(yaw: npt.ArrayLike) -> np.ndarray:
    """Box-to-world rotations (n, 3, 3) of upright boxes with heading ``yaw`` (n,)."""
    a = check_finite("yaw", yaw).reshape(-1)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.size, 3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1.0
    return r


def perceived_grid(
    grid: OccupancyGrid,
    centers: npt.ArrayLike,
    half_extents: npt.ArrayLike,
    yaws: npt.ArrayLike,
    perceived: npt.ArrayLike,
) -> OccupancyGrid:
    """The augmented occupancy grid with only the perceived artefacts (what the planner sees).

    The boxes are held by an AR-builder on ``grid`` and the map is its
    :meth:`~are_stats.builder.ARBuilder.augmented_grid` with ``perceived``: the one
    producer of the augmented map (the mission's planner map and every ``/augmented_map``
    published), footprints rasterised exactly (cells sharing positive area with the box's
    footprint).

    Parameters
    ----------
    grid : are_stats.environment.OccupancyGrid
        The real environment M_2D.
    centers : (n, 2) or (n, 3) float
        Box centres (x, y[, z]) in the world frame.
    half_extents : (n, 2) or (n, 3) float
        Half sizes (> 0) along the box's x and y axes (z ignored).
    yaws : (n,) float
        Headings (rad).
    perceived : (n,) bool
        Membership in A_f.

    Returns
    -------
    OccupancyGrid
        A copy of ``grid`` with the perceived footprints set to occupied (100).
    """
    if not isinstance(grid, OccupancyGrid):
        raise ValueError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    c = check_finite("centers", centers, ndim=2)
    h = check_finite("half_extents", half_extents, ndim=2)
    y = check_finite("yaws", yaws, ndim=1)
    n = c.shape[0]
    if c.shape[1] < 2 or h.shape[0] != n or h.shape[1] < 2 or y.shape != (n,):
        raise ValueError(
            f"centers, half_extents, yaws: expected (n, 2|3), (n, 2|3), (n,), got "
            f"{c.shape}, {h.shape}, {y.shape}"
        )
    if (h[:, :2] <= 0).any():
        raise ValueError(f"half_extents: expected values > 0, got {describe(h)}")
    p = np.asarray(perceived)
    if p.dtype != bool or p.shape != (n,):
        raise ValueError(f"perceived: expected a ({n},) bool array, got {describe(perceived)}")
    builder = ARBuilder(grid)
    # each box (footprint) at its centre: F_A at the centre of its base
    sizes = np.column_stack([2.0 * h[:, :2], np.ones(n)])
    poses = np.column_stack([c[:, :2], y])
    builder.register_many([None] * n, poses, sizes=sizes, artefact_ids=np.arange(n), check=False)
    return builder.augmented_grid(perceived=p)


def _scene_frames(
    scene: Scene, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The boxes of ``scene`` in frames at ``times`` (T,), all taken from :meth:`Scene.at`.

    Returns
    -------
    centres : (N, 3) float, or (T, N, 3) when an artefact has a behaviour track
    half_extents : (N, 3) float
    rotations : (N, 3, 3) float, or (T, N, 3, 3)
    active : (T, N) bool
        The artefact is alive in the frame (``t_arrive <= t < t_leave``).
    """
    n, n_t = len(scene), times.size
    active = scene.alive(times[:, None]) if n_t else np.zeros((0, n), bool)
    cols = np.flatnonzero(active.any(axis=0))  # the artefacts alive in some frame
    if not scene.has_tracks.any():  # every box stands at its arrival pose: one box each
        centres, yaws = np.zeros((n, 3)), np.zeros(n)
        pose = scene.poses(0.0, cols)  # (without tracks, the same at every time)
        centres[cols] = box_centres(pose, scene.offsets[cols])
        yaws[cols] = np.mod(pose[:, 2], 2.0 * np.pi)
        return centres, scene.half_extents, yaw_rotations(yaws), active
    centres, yaws = np.zeros((n_t, n, 3)), np.zeros((n_t, n))
    if cols.size:  # the boxes of Scene.at at every frame, in one pass (zero where not alive)
        pose = scene.poses_at(times, cols)  # (T, c, 3)
        c = box_centres(pose.reshape(-1, 3), np.tile(scene.offsets[cols], (n_t, 1)))
        live = active[:, cols]
        centres[:, cols] = np.where(live[..., None], c.reshape(n_t, cols.size, 3), 0.0)
        yaws[:, cols] = np.where(live, np.mod(pose[..., 2], 2.0 * np.pi), 0.0)
    rots = yaw_rotations(yaws.reshape(-1)).reshape(n_t, n, 3, 3)
    return centres, scene.half_extents, rots, active


def perceive_scene(
    scene: Scene,
    times: npt.ArrayLike,
    poses: npt.ArrayLike,
    env_mesh: trimesh.Trimesh | None,
    camera: CameraModel,
    d_max: float,
    tau: float,
    **options: Unpack[TraceOptions],
) -> tuple[np.ndarray, np.ndarray]:
    """A_f of a :class:`~are_stats.Scene`'s artefacts along a camera trajectory.

    Frame ``i`` shows the boxes ``scene.at(times[i])``: the artefacts alive at that time,
    where they are then (moving along their behaviour tracks, else at their arrival pose),
    each with the box of its row of Q (DECISIONS 5). The counts are those of
    :func:`~are_stats.perception.perceived_counts_batch` with one box pose per frame (or
    one box per artefact when nothing moves): the same as perceiving each frame's boxes on
    their own.

    Parameters
    ----------
    scene : Scene
        One scenario's artefacts (:meth:`Scene.from_scenarios`).
    times : (T,) float
        Frame times on the scenario's clock (s).
    poses : (T, 4, 4) float
        Camera-to-world transforms of the optical frame, one per frame.
    env_mesh : trimesh.Trimesh
        Environment mesh S_3D.
    camera : PinholeCamera
        Intrinsics.
    d_max, tau : float
        Range and partial-occlusion threshold of A_f.
    **options
        :class:`~are_stats.perception.TraceOptions`: ``occlusion_between_artefacts``
        (nearer artefacts hide farther ones, beyond the paper), ``device``, ``threads``.

    Returns
    -------
    counts : (T, N) int64
        Unoccluded box pixels per frame and artefact, in scene order (``scene.ids``); 0
        where the artefact is not alive.
    perceived : (T, N) bool
        ``counts > tau``.

    Examples
    --------
    >>> import numpy as np, pandas as pd, trimesh
    >>> from are_stats import Scene, load_catalogue
    >>> from are_stats.perception import PinholeCamera, optical_from_base
    >>> table = pd.DataFrame({"t_arrive": [0.0], "t_leave": [5.0], "x": [4.0], "y": [0.0],
    ...                       "yaw": [0.0]})
    >>> tracks = pd.DataFrame({"id": [0, 0], "t": [0.0, 4.0], "x": [4.0, 4.0],
    ...                        "y": [0.0, 40.0], "yaw": [0.0, 0.0]})  # walks out of view
    >>> scene = Scene.from_scenarios(table, load_catalogue(), tracks)
    >>> cam = PinholeCamera(60.0, 60.0, 40.0, 30.0, 80, 60)
    >>> poses = np.stack([optical_from_base([0.0, 0.0, 1.0])] * 3)
    >>> counts, seen = perceive_scene(scene, [0.0, 2.0, 4.0], poses, None, cam, 30.0, 5)
    >>> seen[:, 0].tolist()
    [True, False, False]
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a Scene, got {type(scene).__name__}")
    t = check_finite("times", times, ndim=1)
    p = np.asarray(poses, dtype=float)
    if p.ndim != 3 or p.shape[0] != t.size:
        raise ValueError(
            f"poses: expected ({t.size}, 4, 4) camera poses, one per time, got {p.shape}"
        )
    centres, half, rots, active = _scene_frames(scene, t)
    # only the artefacts alive in some frame reach the kernels (a long scenario holds many
    # more artefacts than are ever alive at once); the others count 0
    cols = np.flatnonzero(active.any(axis=0))
    moving = centres.ndim == 3
    counts, seen = perceived_counts_batch(
        env_mesh,
        centres[:, cols] if moving else centres[cols],
        half[cols],
        rots[:, cols] if moving else rots[cols],
        camera,
        p,
        d_max,
        tau,
        active=active[:, cols],
        **options,
    )
    all_counts = np.zeros(active.shape, np.int64)
    all_seen = np.zeros(active.shape, bool)
    all_counts[:, cols], all_seen[:, cols] = counts, seen
    return all_counts, all_seen


def perceive_scenario(
    scenes: Scene | Sequence[Scene],
    robot_path: pd.DataFrame,
    env_mesh: trimesh.Trimesh | None,
    camera: CameraModel,
    d_max: float,
    tau: float,
    *,
    mount: npt.ArrayLike | None = None,
    **options: Unpack[TraceOptions],
) -> pd.DataFrame:
    """Perceived flags of the artefacts of one scene (or several), for a robot on a path.

    Every row of ``robot_path`` is a frame at its time ``t``: the camera pose is
    ``T_world_base(x, y, yaw) @ mount``. A frame shows the boxes alive at ``t`` where they
    are at ``t`` (moving along their behaviour tracks, else standing at their arrival
    pose), as :func:`perceive_scene` computes. The work and memory of all the scenes
    together are checked before any tracing.

    Parameters
    ----------
    scenes : Scene or sequence of Scene
        The artefacts as boxes (:func:`~are_stats.scenarios.scenes_from_fit`, or
        :func:`~are_stats.scenarios.scenes_from_tables` for a scenarios table and its
        tracks): each artefact's box is that of its row of Q (DECISIONS 5).
    robot_path : pandas.DataFrame
        Columns ``t, x, y, yaw``: the robot base pose over time.
    env_mesh : trimesh.Trimesh
        Environment mesh S_3D.
    camera : PinholeCamera
        Intrinsics; its ``pose`` is the base-to-optical mount unless ``mount`` is given.
    d_max, tau : float
        Range and partial-occlusion threshold of A_f.
    mount : (4, 4) float, optional
        ``T_base_optical`` (see :func:`optical_from_base`).
    **options
        :class:`~are_stats.perception.TraceOptions`: ``occlusion_between_artefacts``
        (nearer artefacts hide farther ones, beyond the paper), ``device``, ``threads``.

    Returns
    -------
    pandas.DataFrame
        One row per artefact, scene after scene: the scene's table (``scene.artefacts``,
        the rows it was built from, their index kept; a scene built without one gives
        columns ``artefact, label, t_arrive, t_leave``), then columns ``perceived`` (bool:
        in A_f in at least one frame), ``n_frames_perceived`` (int64), ``max_count``
        (int64: largest pixel count) and ``first_perceived_t`` (float64, NaN if never).

    Raises
    ------
    ValueError
        If ``scenes`` holds anything but Scenes, or on a malformed robot path.
    """
    one = isinstance(scenes, Scene)
    scene_list = [scenes] if one else list(scenes) if isinstance(scenes, Sequence) else None
    if scene_list is None or not all(isinstance(sc, Scene) for sc in scene_list):
        got = type(scenes).__name__ if scene_list is None else "a sequence holding other values"
        raise ValueError(
            f"scenes: expected a Scene or a sequence of Scenes (scenes_from_fit, or "
            f"scenes_from_tables for a scenarios table), got {got}"
        )
    tables = [_scene_table(sc) for sc in scene_list]
    out = pd.concat(tables) if tables else pd.DataFrame(columns=list(_BARE_COLUMNS))
    ends = np.cumsum([0] + [len(sc) for sc in scene_list])
    scenes_rows = [
        (np.arange(a, b), sc) for a, b, sc in zip(ends[:-1], ends[1:], scene_list, strict=True)
    ]
    if not isinstance(robot_path, pd.DataFrame):
        raise ValueError(f"robot_path: expected a DataFrame, got {type(robot_path).__name__}")
    missing = [k for k in ("t", "x", "y", "yaw") if k not in robot_path.columns]
    if missing:
        raise ValueError(f"robot_path: expected columns ['t', 'x', 'y', 'yaw'], missing {missing}")
    m = check_pose("mount", camera.pose if mount is None else mount)
    path = check_finite("robot_path", robot_path[["t", "x", "y", "yaw"]].to_numpy(float))
    t = path[:, 0]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise ValueError(
            f"robot_path: row {i}: expected times in non-decreasing order, got t = {t[i]!r} "
            f"after t = {t[i - 1]!r}"
        )
    base = np.zeros((len(path), 4, 4))
    base[:, :3, :3] = yaw_rotations(path[:, 3])
    base[:, 0, 3], base[:, 1, 3], base[:, 3, 3] = path[:, 1], path[:, 2], 1.0
    poses = base @ m
    _check_size(scene_list, t, camera)
    n_out = len(out)
    perceived = np.zeros(n_out, bool)
    n_frames = np.zeros(n_out, np.int64)
    max_count = np.zeros(n_out, np.int64)
    first = np.full(n_out, np.nan)
    for rows, scene in scenes_rows:
        counts, seen = perceive_scene(scene, t, poses, env_mesh, camera, d_max, tau, **options)
        perceived[rows] = seen.any(axis=0)
        n_frames[rows] = seen.sum(axis=0)
        max_count[rows] = counts.max(axis=0) if len(t) else 0
        idx = np.argmax(seen, axis=0) if len(t) else np.zeros(len(rows), int)
        first[rows] = np.where(seen.any(axis=0), t[idx] if len(t) else np.nan, np.nan)
    out = out.copy()
    out["perceived"] = perceived
    out["n_frames_perceived"] = n_frames
    out["max_count"] = max_count
    out["first_perceived_t"] = first
    return out


#: Columns of :func:`perceive_scenario`'s rows for a scene built without a table.
_BARE_COLUMNS = ("artefact", "label", "t_arrive", "t_leave")


def _scene_table(scene: Scene) -> pd.DataFrame:
    """The rows of ``scene`` in :func:`perceive_scenario`'s output (before the flags)."""
    if scene.artefacts is not None:
        return scene.artefacts
    cols = (scene.ids, scene.labels, scene.t_arrive, scene.t_leave)
    return pd.DataFrame(dict(zip(_BARE_COLUMNS, cols, strict=True)))


def _check_size(scenes: list[Scene], t: np.ndarray, camera: CameraModel) -> None:
    """Refuse, before tracing, work past the work limit (a ray per pixel of every frame in
    which an artefact of the scenario is present) or pair buffers past the memory limit."""
    if not scenes or len(t) == 0:
        return
    n_max = max(len(sc) for sc in scenes)
    moving = any(bool(sc.has_tracks.any()) for sc in scenes)
    check_memory(
        float(len(t)) * float(n_max) * (PAIR_BYTES + (MOVING_PAIR_BYTES if moving else 0)),
        f"the {len(t)} robot poses x {n_max} artefacts of a scenario"
        + (" (boxes that move: a pose per frame)" if moving else ""),
        "robot_path",
    )
    frames = 0
    for sc in scenes:
        ta, tl = sc.t_arrive, sc.t_leave
        # frames with at least one artefact present: t in the union of [t_arrive, t_leave)
        i0 = np.searchsorted(t, ta, side="left")
        i1 = np.maximum(np.searchsorted(t, tl, side="left"), i0)
        cover = np.zeros(len(t) + 1, np.int64)
        np.add.at(cover, i0, 1)
        np.add.at(cover, i1, -1)
        frames += int(np.count_nonzero(np.cumsum(cover)[:-1] > 0))
    pixels = float(camera.width) * float(camera.height)
    check_work(
        frames * pixels,
        f"tracing {frames} frames of {int(pixels)} pixels",
        "robot_path",
    )


def check_path_times(
    source: Source,
    t: np.ndarray,
    t_arrive: np.ndarray,
    t_leave: np.ndarray,
    window: tuple[float, float] | None = None,
    scenarios: Source = "",
) -> None:
    """Refuse a robot path on which no artefact could be seen.

    Parameters
    ----------
    source : str or PathLike
        The robot-path file (named in the error).
    t : (T,) float
        The path's times, sorted.
    t_arrive, t_leave : (n,) float
        The artefacts' presence.
    window : (2,) float, optional
        The scenarios' time window ``[0, horizon]``.
    scenarios : str or PathLike
        The scenarios folder (named in the error).

    Raises
    ------
    are_stats.inputs.InputError
        When the path's times ``[t_min, t_max]`` miss the window, or no time of the path
        falls in an artefact's presence ``[t_arrive, t_leave)``; the message names both
        time ranges.
    """
    t = np.asarray(t, float)
    if t.size == 0 or t_arrive.size == 0:
        return
    got = f"times {t.min():g} to {t.max():g}"
    of = f" of {scenarios}" if str(scenarios) else ""
    if window is not None and (t.max() < window[0] or t.min() > window[1]):
        raise InputError(
            source,
            "column 't'",
            f"times overlapping the scenario window [{window[0]:g}, {window[1]:g}]{of}",
            Described(f"{got}: no artefact would be seen"),
        )
    seen_by = np.searchsorted(t, t_leave, side="left") - np.searchsorted(t, t_arrive, side="left")
    if not (seen_by > 0).any():  # no pose with t_arrive <= t < t_leave
        raise InputError(
            source,
            "column 't'",
            f"times within the scenarios' artefact presence [{t_arrive.min():g}, "
            f"{t_leave.max():g}){of}",
            Described(f"{got}: no artefact would be seen"),
        )


def poses_outside(
    xy: npt.ArrayLike, grid: OccupancyGrid | None = None, bounds: npt.ArrayLike | None = None
) -> np.ndarray:
    """(n,) bool: robot positions ``xy (n, 2)`` outside the map ``grid`` (an
    OccupancyGrid), else outside ``bounds`` ``((x0, y0), (x1, y1))``; none without either."""
    p = check_finite("xy", xy, ndim=2)
    if grid is not None:
        return ~grid.in_bounds(grid.world_to_cell(p))
    if bounds is not None:
        lo, hi = np.asarray(bounds, float)
        return ((p < lo) | (p > hi)).any(axis=1)
    return np.zeros(p.shape[0], bool)


def check_poses_inside(
    source: Source,
    xy: npt.ArrayLike,
    grid: OccupancyGrid | None,
    env_mesh: trimesh.Trimesh | None = None,
    map_source: Source = "",
    *,
    field: str = "columns 'x', 'y'",
    when: Callable[[int, int], str] | None = None,
) -> str | None:
    """The one rule of ``perceive`` and ``augment`` for a robot path and its map: a path
    wholly outside the robot's area is refused (nothing along it could be seen, whatever
    the scenes: a path in another frame or unit), a path partly outside is a warning (the
    robot at a map's edge) and goes on. The area is the map's cells when there is a map,
    else the x-y bounds of the environment mesh (:func:`poses_outside`).

    Parameters
    ----------
    source : str or PathLike
        The robot-path file or bag (named in the error and the warning).
    xy : (n, 2) float
        The robot's positions (m), in time order.
    grid : OccupancyGrid or None
        The map (None: the mesh alone).
    env_mesh : trimesh.Trimesh, optional
        The environment mesh (its x-y bounds are the area without a map).
    map_source : str or PathLike
        The map's file (named in the error and the warning).
    field : str
        Where in ``source`` the positions are (named in the error).
    when : callable, optional
        ``when(i, j)``: the times of poses ``i`` to ``j`` in words (``"at t = 1 to 3 s"``);
        default their rows, counted from 1 (``"row 2"``, ``"rows 2 to 5"``).

    Returns
    -------
    str or None
        ``"k of n robot poses of SOURCE lie outside AREA, WHEN"`` (the first to the last
        pose outside), None when every pose lies inside.

    Raises
    ------
    are_stats.inputs.InputError
        Every pose outside (naming ``source``, ``field``, the area and the first pose).

    Examples
    --------
    >>> grid = OccupancyGrid(np.zeros((10, 10)), 1.0)
    >>> check_poses_inside("path.csv", [[1.0, 1.0], [12.0, 1.0]], grid, None, "map.yaml")
    '1 of 2 robot poses of path.csv lie outside the map map.yaml (corners [[0.0, 0.0], [10.0, 10.0]]), row 2'
    """  # noqa: E501
    p = check_finite("xy", xy, ndim=2)
    bounds = None if grid is not None or env_mesh is None else np.asarray(env_mesh.bounds)[:, :2]
    outside = poses_outside(p, grid=grid, bounds=bounds)
    if not outside.any():
        return None
    if grid is not None:
        corners = np.round(grid.corners_world[[0, 2]], 3).tolist()
        area = f"the map {map_source} (corners {corners})"
    else:
        area = f"the mesh's x-y bounds {bounds[0].tolist()} to {bounds[1].tolist()}"
    if when is None:

        def when(i: int, j: int) -> str:
            return f"row {i + 1}" if i == j else f"rows {i + 1} to {j + 1}"

    rows = np.flatnonzero(outside)
    first, last = int(rows[0]), int(rows[-1])
    if outside.all():
        raise InputError(
            source,
            field,
            f"robot poses inside {area}",
            Described(
                f"all {len(p)} outside, the first at ({p[0, 0]:.3f}, {p[0, 1]:.3f}), "
                f"{when(first, last)}: is the path in the map's frame and metres?"
            ),
        )
    return (
        f"{len(rows)} of {len(p)} robot poses of {source} lie outside {area}, {when(first, last)}"
    )
