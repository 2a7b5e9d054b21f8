"""A_f along a robot path for scenario tables, and the augmented grid the planner sees.

The paper's augmented real environment "comprises only the artefacts which are not
occluded, with respect to the robot field of view" (section 3.3): :func:`perceived_grid`
marks on M_2D the footprints of the perceived artefacts only, and
:func:`perceive_scenario` adds perceived flags to a scenarios table given the robot's path
(the library side of ``are-stats perceive``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from are_stats._checks import check_finite, describe
from are_stats.inputs import Described, InputError, check_memory, check_work, get_list, get_str
from are_stats.perception._camera import check_pose
from are_stats.perception._perceive import perceived_counts_batch

__all__ = [
    "perceive_scenario",
    "perceived_grid",
    "read_robot_path",
    "read_scenario_folder",
    "yaw_rotations",
    "MAX_POSITION",
]

#: Largest ``|x|``, ``|y|`` of a robot pose or an artefact accepted (metres).
MAX_POSITION = 1e7
#: Memory per (robot pose, artefact of one scenario) pair while perceiving (bytes): the
#: active mask, the counts and the perceived flags.
PAIR_BYTES = 24
_SCENARIO_FLOATS = ("t_arrive", "t_leave", "x", "y", "yaw")


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
    from are_stats.logs._table import read_raw_table

    table = read_raw_table(path, "robot path")
    table.require(["t", "x", "y", "yaw"], "robot path")
    cols = {c: table.floats(c, allow_empty=False)[0] for c in ("t", "x", "y", "yaw")}
    for c in ("x", "y"):
        big = np.abs(cols[c]) > MAX_POSITION
        if big.any():
            i = int(np.argmax(big))
            raise table.error(
                i, c, f"a position within {MAX_POSITION:g} m of the origin", repr(float(cols[c][i]))
            )
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


def read_scenario_folder(folder: str | os.PathLike) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read and check a scenarios folder for perception (``are-stats perceive SCENARIO``).

    The folder must hold ``manifest.yaml`` (a mapping; ``map`` a string or null,
    ``class_labels`` a list of strings or null) and ``artefacts.parquet`` with integer
    columns ``scenario`` (>= 0), ``class`` and ``mark`` (>= -1; ``mark`` optional) and
    finite ``t_arrive <= t_leave``, ``x``, ``y``, ``yaw`` (other columns are kept as
    they are).

    Returns
    -------
    (pandas.DataFrame, dict)
        The artefacts table and the manifest.

    Raises
    ------
    FileNotFoundError
        If the folder does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) naming the file, and the key or the row and column.
    """
    import pyarrow.parquet as pq

    from are_stats.inputs import load_yaml
    from are_stats.logs._table import read_raw_table

    d = Path(folder)
    if not d.exists():
        raise FileNotFoundError(f"{d}: no such scenarios folder")
    if not d.is_dir():
        raise InputError(
            d, "", "a scenarios folder written by are-stats generate", Described("a file")
        )
    for name in ("manifest.yaml", "artefacts.parquet"):
        if not (d / name).is_file():
            raise InputError(
                d, name, "a scenarios folder with manifest.yaml and artefacts.parquet",
                Described(f"no file {name}"),
            )  # fmt: skip
    mpath = d / "manifest.yaml"
    manifest = load_yaml(mpath, "scenarios manifest")
    if not isinstance(manifest, dict):
        raise InputError(mpath, "", "a mapping (a scenarios manifest)", manifest)
    if manifest.get("map") is not None:
        get_str(manifest["map"], mpath, "map")
    if manifest.get("class_labels") is not None:
        labels = get_list(manifest["class_labels"], mpath, "class_labels")
        for i, lab in enumerate(labels):
            get_str(lab, mpath, f"class_labels[{i}]")
    table = read_raw_table(d / "artefacts.parquet", "scenarios table")
    table.require(["scenario", "class", *_SCENARIO_FLOATS], "scenarios table")
    num = {c: table.floats(c, allow_empty=False)[0] for c in _SCENARIO_FLOATS}
    for c in ("x", "y"):
        big = np.abs(num[c]) > MAX_POSITION
        if big.any():
            i = int(np.argmax(big))
            raise table.error(
                i, c, f"a position within {MAX_POSITION:g} m of the origin", repr(float(num[c][i]))
            )
    early = num["t_leave"] < num["t_arrive"]
    if early.any():
        i = int(np.argmax(early))
        raise table.error(
            i,
            "t_leave",
            f"t_leave >= t_arrive ({float(num['t_arrive'][i])!r})",
            repr(float(num["t_leave"][i])),
        )
    ints = {"scenario": table.nonneg_ints("scenario", allow_empty=False)[0]}
    for c in ("class", "mark"):
        if c not in table.columns:
            continue
        v = table.floats(c, allow_empty=False)[0]
        bad = (v < -1) | (v != np.round(v)) | (v > 2**53)
        if bad.any():
            i = int(np.argmax(bad))
            raise table.error(i, c, "an integer >= -1", repr(float(v[i])))
        ints[c] = v.astype(np.int64)
    try:
        df = pq.read_table(d / "artefacts.parquet").to_pandas()
    except (OSError, ValueError) as err:  # pyarrow's ArrowInvalid is a ValueError
        raise InputError(
            d / "artefacts.parquet", "", "a readable Parquet table", Described(str(err))
        ) from None
    for c, v in {**num, **ints}.items():
        df[c] = v
    return df, manifest


def yaw_rotations(yaw: Any) -> np.ndarray:
    """Box-to-world rotations (n, 3, 3) of upright boxes with heading ``yaw`` (n,)."""
    a = check_finite("yaw", yaw).reshape(-1)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.size, 3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1.0
    return r


def perceived_grid(grid: Any, centers: Any, half_extents: Any, yaws: Any, perceived: Any) -> Any:
    """The augmented occupancy grid with only the perceived artefacts (what the planner sees).

    Footprints are rasterised exactly (cells sharing positive area with the box's
    footprint) by the AR-builder's :func:`are_stats.builder.rasterise_convex`.

    Parameters
    ----------
    grid : are_stats.environment.OccupancyGrid
        The real environment M_2D.
    centers : (n, 2) or (n, 3) float
        Box centres (x, y[, z]) in the world frame.
    half_extents : (n, 2) or (n, 3) float
        Half sizes along the box's x and y axes (z ignored).
    yaws : (n,) float
        Headings (rad).
    perceived : (n,) bool
        Membership in A_f.

    Returns
    -------
    OccupancyGrid
        A copy of ``grid`` with the perceived footprints set to occupied (100).
    """
    from are_stats.builder import box_corners, rasterise_convex

    if not hasattr(grid, "world_to_local") or not hasattr(grid, "copy"):
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
    if (h < 0).any():
        raise ValueError(f"half_extents: expected values >= 0, got {describe(h)}")
    p = np.asarray(perceived)
    if p.dtype != bool or p.shape != (n,):
        raise ValueError(f"perceived: expected a ({n},) bool array, got {describe(perceived)}")
    out = grid.copy()
    if p.any():
        poly = box_corners(c[p, :2], h[p, :2], y[p])
        _, flat, _ = rasterise_convex(grid.world_to_local(poly), grid.shape)
        out.data.ravel()[flat] = 100
    return out


def _sizes(classes: Any, labels: np.ndarray) -> np.ndarray:
    """(n, 3) full sizes (length, width, height) per artefact from a class table."""
    if isinstance(classes, pd.DataFrame):
        need = ["class", "length", "width", "height"]
        missing = [k for k in need if k not in classes.columns]
        if missing:
            raise ValueError(f"classes: expected columns {need}, missing {missing}")
        table = {r["class"]: (r["length"], r["width"], r["height"]) for _, r in classes.iterrows()}
    elif isinstance(classes, Mapping):
        table = dict(classes)
    else:
        raise ValueError(
            "classes: expected a DataFrame (class, length, width, height) or a mapping "
            f"class -> (length, width, height), got {type(classes).__name__}"
        )
    out = np.empty((labels.size, 3))
    for i, lab in enumerate(labels.tolist()):
        if lab not in table:
            raise ValueError(f"classes: no size for class {lab!r} (artefact row {i})")
        size = check_finite(f"classes[{lab!r}]", table[lab]).reshape(-1)
        if size.shape != (3,) or (size <= 0).any():
            raise ValueError(
                f"classes[{lab!r}]: expected (length, width, height) > 0, got {describe(size)}"
            )
        out[i] = size
    return out


def perceive_scenario(
    artefacts: pd.DataFrame,
    robot_path: pd.DataFrame,
    classes: Any,
    env_mesh: Any,
    camera: Any,
    d_max: float,
    tau: float,
    *,
    mount: Any | None = None,
    occlusion_between_artefacts: bool = False,
    threads: int | None = None,
) -> pd.DataFrame:
    """Add perceived flags to a scenarios table, for a robot following ``robot_path``.

    Every row of ``robot_path`` is a frame: the camera pose is
    ``T_world_base(x, y, yaw) @ mount``. An artefact takes part in a frame when
    ``t_arrive <= t < t_leave``; it stands upright at its ``(x, y, yaw)`` on the ground
    (box centre at half its height). A(t) is computed per scenario with
    :func:`perceived_counts_batch`.

    Parameters
    ----------
    artefacts : pandas.DataFrame
        Columns ``scenario, class, t_arrive, t_leave, x, y, yaw`` (other columns kept).
    robot_path : pandas.DataFrame
        Columns ``t, x, y, yaw``: the robot base pose over time.
    classes : DataFrame or mapping
        Box sizes per class: columns ``class, length, width, height`` or a mapping
        ``class -> (length, width, height)`` (metres).
    env_mesh : trimesh.Trimesh
        Environment mesh S_3D.
    camera : PinholeCamera
        Intrinsics; its ``pose`` is the base-to-optical mount unless ``mount`` is given.
    d_max, tau : float
        Range and partial-occlusion threshold of A_f.
    mount : (4, 4) float, optional
        ``T_base_optical`` (see :func:`optical_from_base`).
    occlusion_between_artefacts : bool
        Nearer artefacts hide farther ones (beyond the paper).
    threads : int, optional
        Host threads for the Warp CPU launches.

    Returns
    -------
    pandas.DataFrame
        ``artefacts`` with columns ``perceived`` (bool: in A_f in at least one frame),
        ``n_frames_perceived`` (int64), ``max_count`` (int64: largest pixel count) and
        ``first_perceived_t`` (float64, NaN if never).
    """
    need = ["scenario", "class", "t_arrive", "t_leave", "x", "y", "yaw"]
    if not isinstance(artefacts, pd.DataFrame):
        raise ValueError(f"artefacts: expected a DataFrame, got {type(artefacts).__name__}")
    missing = [k for k in need if k not in artefacts.columns]
    if missing:
        raise ValueError(f"artefacts: expected columns {need}, missing {missing}")
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
    cols = artefacts[["t_arrive", "t_leave", "x", "y", "yaw"]]
    num = check_finite("artefacts", cols.to_numpy(float))
    sizes = _sizes(classes, artefacts["class"].to_numpy())
    out = artefacts.copy()
    perceived = np.zeros(len(out), bool)
    n_frames = np.zeros(len(out), np.int64)
    max_count = np.zeros(len(out), np.int64)
    first = np.full(len(out), np.nan)
    scen = artefacts["scenario"].to_numpy()
    _check_size(scen, num, t, camera)
    for s in pd.unique(scen):
        rows = np.flatnonzero(scen == s)
        ta, tl, x, y, yaw = num[rows].T
        half = sizes[rows] / 2.0
        centers = np.column_stack([x, y, half[:, 2]])
        active = (t[:, None] >= ta[None]) & (t[:, None] < tl[None])
        counts, seen = perceived_counts_batch(
            env_mesh, centers, half, yaw_rotations(yaw), camera, poses, d_max, tau,
            active=active, occlusion_between_artefacts=occlusion_between_artefacts,
            threads=threads,
        )  # fmt: skip
        perceived[rows] = seen.any(axis=0)
        n_frames[rows] = seen.sum(axis=0)
        max_count[rows] = counts.max(axis=0) if len(t) else 0
        idx = np.argmax(seen, axis=0) if len(t) else np.zeros(len(rows), int)
        first[rows] = np.where(seen.any(axis=0), t[idx] if len(t) else np.nan, np.nan)
    out["perceived"] = perceived
    out["n_frames_perceived"] = n_frames
    out["max_count"] = max_count
    out["first_perceived_t"] = first
    return out


def _check_size(scen: np.ndarray, num: np.ndarray, t: np.ndarray, camera: Any) -> None:
    """Refuse, before tracing, work past the work limit (a ray per pixel of every frame in
    which an artefact of the scenario is present) or pair buffers past the memory limit."""
    if len(scen) == 0 or len(t) == 0:
        return
    _, n_per = np.unique(scen, return_counts=True)
    check_memory(
        float(len(t)) * float(n_per.max()) * PAIR_BYTES,
        f"the {len(t)} robot poses x {int(n_per.max())} artefacts of a scenario",
        "robot_path",
    )
    order = np.argsort(scen, kind="stable")
    bounds = np.flatnonzero(np.diff(scen[order])) + 1
    frames = 0
    for rows in np.split(order, bounds):
        ta, tl = num[rows, 0], num[rows, 1]
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
