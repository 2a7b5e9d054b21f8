"""A_f for a scenarios folder along a robot path: the library side of ``are-stats perceive``.

:func:`perceive_folder` reads and checks every input (the options, the folder with its
behaviour tracks, the camera, the robot path, the mesh or map) before any tracing, perceives
the folder's scenes along the path (:func:`~are_stats.perception.perceive_scenario`) and
writes the flags beside the folder.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple, TypedDict

import pandas as pd

from are_stats._atomic import atomic_path, check_writable
from are_stats.environment import environment_mesh, load_catalogue
from are_stats.inputs import get_float
from are_stats.perception._camera import camera_mount, read_camera
from are_stats.perception._scenario import (
    check_path_times,
    check_poses_inside,
    perceive_scenario,
    read_robot_path,
)
from are_stats.scenarios import read_scenes, scenes_from_tables

__all__ = ["FolderPlan", "PerceiveFolderOptions", "perceive_folder"]


class FolderPlan(NamedTuple):
    """What :func:`perceive_folder` is about to perceive, once every input is checked."""

    #: Artefacts of the folder (rows of its table).
    artefacts: int
    #: Artefacts with behaviour tracks (they move).
    moving: int
    #: Robot poses of the path.
    poses: int
    #: The checked ``d_max`` (m) and ``tau`` (pixels).
    d_max: float
    tau: float
    #: Warnings about the inputs, in words: poses outside the map, classes not in the
    #: catalogue.
    warnings: tuple[str, ...]


class PerceiveFolderOptions(TypedDict, total=False):
    """The options of :func:`perceive_folder` (its keywords, but ``on_start``), as a caller
    passes them on: ``are-stats perceive``'s job. See :func:`perceive_folder` for their
    meaning and defaults."""

    mesh: str | os.PathLike | None
    wall_height: float
    d_max: float
    tau: float
    camera_height: float
    occlusion_between_artefacts: bool
    out: str | os.PathLike | None
    force: bool


def perceive_folder(
    scenario: str | os.PathLike,
    camera: str | os.PathLike,
    robot_path: str | os.PathLike,
    *,
    mesh: str | os.PathLike | None = None,
    wall_height: float = 2.5,
    d_max: float = 30.0,
    tau: float = 50.0,
    camera_height: float = 1.0,
    occlusion_between_artefacts: bool = False,
    out: str | os.PathLike | None = None,
    force: bool = False,
    on_start: Callable[[FolderPlan], None] | None = None,
) -> tuple[Path, pd.DataFrame]:
    """Add perceived flags (A_f, eq. 2) to a scenario folder for a robot path.

    Every input is checked before any tracing: the options (``d_max`` > 0, ``tau`` >= 0,
    ``camera_height`` and ``wall_height`` within 1 km, named as the options ``--d-max``,
    ...), the output (refused if it exists, unless ``force``), the scenario folder
    (:func:`are_stats.scenarios.read_scenes`, its behaviour tracks included), the camera
    (:func:`read_camera`), the robot path (:func:`read_robot_path`: sorted times, finite
    poses) and the mesh or map. With behaviour tracks the artefacts move: each robot pose
    sees them where they are at its time.

    Parameters
    ----------
    scenario : str or PathLike
        A scenarios folder (:func:`are_stats.scenarios.write_scenes`).
    camera : str or PathLike
        A camera YAML or a shipped camera's name (``front_camera``).
    robot_path : str or PathLike
        Robot base poses over time: CSV/Parquet with ``t, x, y, yaw`` (s, m, m, rad).
    mesh : str or PathLike, optional
        The environment mesh (default: the folder's map's walls, ``wall_height`` m high).
    wall_height, d_max, tau, camera_height : float
        Wall height (m), maximum viewing distance (m), pixels needed to perceive (count >
        tau), camera height above the base (m) when the camera has no pose.
    occlusion_between_artefacts : bool
        Artefacts also occlude each other.
    out : str or PathLike, optional
        The Parquet to write (default ``SCENARIO/perceived.parquet``).
    force : bool
        Overwrite ``out``.
    on_start : callable, optional
        Called with the :class:`FolderPlan` once the inputs are checked, before perceiving
        (a command shows the warnings and its progress there); without it each warning is
        issued as a :class:`UserWarning`.

    Returns
    -------
    path : Path
        The Parquet written.
    perceived : pandas.DataFrame
        The folder's artefacts in its row order, with ``perceived``, ``n_frames_perceived``,
        ``max_count`` and ``first_perceived_t``
        (:func:`~are_stats.perception.perceive_scenario`).

    Raises
    ------
    are_stats.inputs.InputError
        A bad option, folder, camera, robot path or mesh; a robot path whose times miss the
        scenario window ``[0, horizon]`` or every artefact's presence (naming both time
        ranges); a robot path wholly outside the map (or the mesh's x-y bounds): the rule
        ``augment`` shares (:func:`~are_stats.perception.check_poses_inside`: some poses
        outside are a warning, with their times); an existing ``out`` without ``force``.
    """
    d_max = get_float(d_max, "--d-max", "", lo=0, lo_open=True, hi=1e6)
    tau = get_float(tau, "--tau", "", lo=0)
    camera_height = get_float(camera_height, "--camera-height", "", lo=-1e3, hi=1e3)
    wall_height = get_float(wall_height, "--wall-height", "", lo=0, lo_open=True, hi=1e3)
    scenario = Path(scenario)
    target = Path(out) if out is not None else scenario / "perceived.parquet"
    check_writable(target, force)
    folder = read_scenes(scenario)
    df = folder.artefacts
    cam = read_camera(camera)
    path = Path(robot_path)
    robot = read_robot_path(path)
    grid = folder.grid(missing_ok=mesh is not None, or_else="pass --mesh MESH")
    env = environment_mesh(grid, wall_height, mesh, source=folder.manifest_path)
    window = None if folder.horizon is None else (0.0, folder.horizon)
    check_path_times(
        path,
        robot["t"].to_numpy(),
        df["t_arrive"].to_numpy(),
        df["t_leave"].to_numpy(),
        window,
        scenario,
    )
    t = robot["t"].to_numpy()

    def when(i: int, j: int) -> str:
        rows = f"row {i + 1}" if i == j else f"rows {i + 1} to {j + 1}"
        return f"at t = {t[i]:g}" + ("" if i == j else f" to {t[j]:g}") + f" s ({rows})"

    xy = robot[["x", "y"]].to_numpy()
    notes = []
    outside = check_poses_inside(path, xy, grid, env, folder.map_file, when=when)
    if outside is not None:
        notes.append(outside)
    cat = load_catalogue()
    unknown = folder.unknown_classes(cat)
    if unknown:
        notes.append(
            f"classes {unknown} of the scenarios are not in the catalogue "
            f"({', '.join(cat.labels)}): they are sized as the catalogue class in their "
            "position"
        )
    plan = FolderPlan(len(df), folder.n_moving, len(robot), d_max, tau, tuple(notes))
    if on_start is not None:
        on_start(plan)
    else:
        for note in plan.warnings:
            warnings.warn(note, UserWarning, stacklevel=2)
    scenes = scenes_from_tables(
        df, folder.tracks, cat, folder.class_labels, df["scenario"].unique()
    )
    res = perceive_scenario(
        scenes,
        robot,
        env,
        cam,
        d_max,
        tau,
        mount=camera_mount(cam.pose, camera_height),
        occlusion_between_artefacts=occlusion_between_artefacts,
    ).loc[df.index]  # the folder's row order
    with atomic_path(target, force=force) as tmp:
        res.to_parquet(tmp, index=False)
    return target, res
