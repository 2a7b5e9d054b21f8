"""The one assembly from a fit to moving scenes (issue 25): ``Fit in, Scenes out``.

Every command that puts artefacts on a map (``generate``, the experiment sweeps,
``augment``) calls :func:`scenes_from_fit` (hand-set rates as a fit too:
:meth:`~are_stats.fitting.Fit.from_draws`), so a change to traffic, behaviour or motion
reaches all of them at once.

The behaviour rule (``behaviours=``, :func:`~are_stats.scenarios.behaviour_source`), one for
every command:

* ``False`` / ``"none"``: artefacts stand at their arrival pose for their whole stay;
* ``True`` / ``"auto"``: the fit's behaviour when the fit has one (speeds, exits and
  rationality learned from the log's tracks:
  :func:`~are_stats.behaviour.simulate_behaviour_tracks`; the classes that only stood in
  them, ``BehaviourFit.standing``, stand), otherwise the catalogue's
  (each class's behaviours, walk / run / follow / stop, solved as the finite-horizon MDP
  of the paper on the map coarsened to ``behaviour_cell``:
  :func:`~are_stats.behaviour.behaviour_tracks`);
* ``"fitted"`` or ``"catalogue"``: that one (``"fitted"`` without a fitted behaviour is an
  error).

Tracks end at the scenario's horizon (the scenario is defined on ``[0, horizon]``; its
artefacts' ``t_leave`` may lie beyond, right-censored there).

**Groups** (issue 26): the members of an arrival group (the scenarios table's ``group``,
drawn by the ``groups`` arrival model) take their leader's planned route in formation at
the group spacing (:func:`~are_stats.behaviour.group_tracks`: the fit's, else the
published 0.75 m), pedestrians only; the interaction then keeps the formation while they
walk.

**Behaviour is Scene -> Scene.** The assembly draws the scenarios and builds their standing
scenes first (:func:`scenes_from_tables`); :func:`move_scenes` then moves them, each step
(planning, groups, the AR-builder's resolution, the social force) a
:meth:`~are_stats.scenarios.Scene.with_tracks` (or ``with_track``) of the scenes before it.

**Collisions: one story.** The behaviours plan each artefact alone (routes on free cells).
Then:

* the **AR-builder** (DECISIONS 9, :meth:`~are_stats.builder.ARBuilder.resolve_scene`)
  resolves the moves of the artefacts that have no social force of their own (vehicles,
  carts: catalogue ``kind`` other than ``pedestrian``) against each other and against
  every artefact standing: a move whose box would hit another box is reverted, so the
  mover waits on its route and goes on later (earlier arrivals first). With
  ``interaction=False`` it resolves every mover, people included;
* the **interaction** (``interaction=``): the tracks of walking people are walked again
  under the social force (:func:`~are_stats.behaviour.social_force_tracks`), so people
  give way to each other, to artefacts standing and to vehicles (on their resolved
  tracks) instead of walking through them, continuously and without stopping. The
  parameters are the fit's when it estimated them from tracks, else the published ones
  (:class:`SocialForce`).

In a mission the robot's own footprint is avoided by the moving artefacts
(:func:`~are_stats.experiments.run_mission`, ``avoid_robot``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Unpack

import jax
import numpy as np
import pandas as pd

from are_stats.behaviour import (
    BehaviourFit,
    SocialForce,
    arrival_velocities,
    behaviour_tracks,
    group_tracks,
    simulate_behaviour_tracks,
    social_force_tracks,
)
from are_stats.builder import ARBuilder
from are_stats.environment import ArtefactCatalogue, OccupancyGrid, coarse_free
from are_stats.inputs import Described, InputError, check_memory, check_work, get_str
from are_stats.scenarios._behaviour_rule import behaviour_source
from are_stats.scenarios._generate import ScenarioSize, check_scenario_size, generate_scenarios
from are_stats.scenarios._options import POSITION_CHOICES, AssemblyOptions, AssemblySettings
from are_stats.scenarios._scene import Scene

if TYPE_CHECKING:
    import arviz as az

    from are_stats.fitting import Fit

__all__ = [
    "check_tracks_size",
    "move_scenes",
    "scene_tracks",
    "scenes_from_fit",
    "scenes_from_tables",
    "scenes_tables",
]


#: ``progress(done, total, what)``: the assembly's steps done so far, of ``total``, and
#: the last one done (``done`` grows by one a step and ends at ``total``).
_Progress = Callable[[int, int, str], object]

#: :func:`move_scenes`' default options: the scenes move by the rule's ``True``.
_MOVING = AssemblyOptions(behaviours=True)
#: :func:`scenes_from_fit`'s default options: the scenes stand.
_STANDING = AssemblyOptions()


class _Moves(AssemblySettings, total=False):
    """The keywords of :func:`move_scenes` after its positional arguments (what
    :func:`scene_tracks` forwards)."""

    fitted: BehaviourFit | None
    source: str
    progress: _Progress | None


def check_tracks_size(artefacts: pd.DataFrame, shape: tuple[int, int], dt: float, source: str):
    """Refuse catalogue (MDP) behaviour tracks past the memory or work limit, before solving.

    Per scenario the MDP is solved for its artefacts at once over the longest stay (epochs
    padded to 64): a policy of ``artefacts x epochs x cells x 4`` bytes and about ten times
    as many steps; the tracks hold one row per artefact and epoch.

    Parameters
    ----------
    artefacts : pandas.DataFrame
        Scenarios table (``scenario``, ``t_arrive``, ``t_leave``).
    shape : (int, int)
        The coarse behaviour grid.
    dt : float
        Seconds per decision epoch.
    source : str
        Options or file named in the error.

    Raises
    ------
    are_stats.inputs.LimitError
    """
    cells = float(shape[0]) * float(shape[1])
    with np.errstate(over="ignore", invalid="ignore"):
        epochs = (artefacts["t_leave"].to_numpy(float) - artefacts["t_arrive"].to_numpy(float)) / dt
    epochs = np.where(np.isfinite(epochs), np.maximum(epochs, 0.0), np.inf)
    sc = pd.factorize(artefacts["scenario"])[0] if len(artefacts) else np.zeros(0, np.int64)
    n_sc = int(sc.max()) + 1 if sc.size else 0
    longest = np.zeros(n_sc)
    np.maximum.at(longest, sc, epochs)
    per = np.bincount(sc, minlength=n_sc).astype(float)
    bucket = 64.0 * np.ceil(np.maximum(longest, 1.0) / 64.0)
    policy = per * bucket * cells * 4.0
    rows = float(np.sum(epochs + 1.0))
    what = (
        f"MDP tracks of {len(artefacts)} artefacts on a {shape[0]} x {shape[1]} grid, dt {dt:g} s"
    )
    check_memory(float(policy.max(initial=0.0)), f"the MDP policy of one scenario ({what})", source)
    check_memory(rows * 64.0, f"the tracks table ({what})", source)
    check_work(float(policy.sum()) * 10.0 + rows * 50.0, what, source)


def scenes_from_tables(
    artefacts: pd.DataFrame,
    tracks: pd.DataFrame | None,
    catalogue: ArtefactCatalogue,
    class_labels: Sequence[str] | None = None,
    scenarios: Iterable[int] | None = None,
) -> list[Scene]:
    """Scenes of a scenarios table and its tracks: the one place where table rows become
    :class:`Scene` s (every reader of a scenarios folder and every assembly comes here).

    Parameters
    ----------
    artefacts : pandas.DataFrame
        Scenarios table (``scenario`` column; without it, one scenario 0).
    tracks : pandas.DataFrame or None
        ``scenario, id, t, x, y, yaw``.
    catalogue : ArtefactCatalogue
    class_labels : sequence of str, optional
        Label of each mixture component.
    scenarios : sequence of int, optional
        The scenario indices to build, in order (default ``0..max``: empty scenarios
        included).

    Returns
    -------
    list of Scene
    """
    if "scenario" not in artefacts.columns:
        artefacts = artefacts.assign(scenario=0)
    if tracks is not None and len(tracks) and "scenario" not in tracks.columns:
        present = pd.unique(artefacts["scenario"])
        if present.size > 1:
            raise ValueError(
                "tracks: expected a 'scenario' column for a table of several scenarios"
            )
        tracks = tracks.assign(scenario=present[0] if present.size else 0)
    by_sc = dict(tuple(artefacts.groupby("scenario", sort=True))) if len(artefacts) else {}
    tr_by = {}
    if tracks is not None and len(tracks):
        tr_by = dict(tuple(tracks.groupby("scenario", sort=True)))
    if scenarios is None:
        scenarios = range(int(artefacts["scenario"].max()) + 1 if len(artefacts) else 1)
    empty = artefacts.iloc[:0]
    out = []
    for k in scenarios:
        part = by_sc.get(k, empty).copy()
        part.attrs = dict(artefacts.attrs)  # the generation settings, for the folder
        out.append(Scene.from_scenarios(part, catalogue, tr_by.get(k), class_labels=class_labels))
    return out


def scenes_tables(scenes: list[Scene]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The scenarios table and the tracks table of scenes made by :func:`scenes_from_fit`
    (what :func:`~are_stats.scenarios.write_scenes` writes).

    Returns
    -------
    artefacts : pandas.DataFrame
        The scenes' tables, scenario after scenario, with the generation settings in
        ``attrs``.
    tracks : pandas.DataFrame
        ``scenario, id, t, x, y, yaw`` (empty without tracks).
    """
    cols = ["scenario", "id", "t", "x", "y", "yaw"]
    if not scenes:
        return pd.DataFrame(), pd.DataFrame(columns=cols)
    art = pd.concat([s.artefacts for s in scenes], ignore_index=True)
    art.attrs = dict(scenes[0].artefacts.attrs)
    tracks = pd.concat(
        [s.tracks_table().assign(scenario=k) for k, s in enumerate(scenes)], ignore_index=True
    )[cols]
    return art, tracks


def scene_tracks(
    key: int | jax.Array,
    artefacts: pd.DataFrame,
    grid: OccupancyGrid | None,
    catalogue: ArtefactCatalogue,
    horizon: float,
    *,
    class_labels: Sequence[str] | None = None,
    n: int | None = None,
    **moves: Unpack[_Moves],
) -> pd.DataFrame | None:
    """The tracks of a scenarios table moved by :func:`move_scenes`: its standing scenes
    (:func:`scenes_from_tables`, scenarios ``0 .. n - 1``) moved, as a table.

    Parameters
    ----------
    key : jax.Array
        PRNG key of the tracks.
    artefacts : pandas.DataFrame
        Scenarios table (``scenario`` column).
    grid, catalogue, horizon
        See :func:`move_scenes`.
    class_labels : sequence of str, optional
        Label of each mixture component.
    n : int, optional
        Number of scenarios (default: the table's).
    **moves
        The keywords of :func:`move_scenes` (``behaviours``, default ``True``,
        ``fitted``, ``behaviour_cell``, ``behaviour_dt``, ``source``, ``cell_source``,
        ``interaction``, ``progress``).

    Returns
    -------
    pandas.DataFrame or None
        ``scenario, id, t, x, y, yaw`` (by scenario, artefacts in table order, epochs in
        time order); None when nothing moves (no behaviours, or no artefact).
    """
    if n is None:
        n = int(artefacts["scenario"].max()) + 1 if len(artefacts) else 1
    standing = scenes_from_tables(artefacts, None, catalogue, class_labels, range(n))
    moved = move_scenes(key, standing, grid, catalogue, horizon, **moves)
    kind = behaviour_source(
        moves.get("behaviours", True), moves.get("fitted"), grid, moves.get("source", "scenario")
    )
    if kind == "none" or not len(artefacts):
        return None
    return _tracks_of(moved, _numbers(moved))


def move_scenes(
    key: jax.Array,
    scenes: Sequence[Scene],
    grid: OccupancyGrid | None,
    catalogue: ArtefactCatalogue,
    horizon: float,
    options: AssemblyOptions | None = None,
    *,
    fitted: BehaviourFit | None = None,
    source: str = "scenario",
    progress: _Progress | None = None,
    **settings: Unpack[AssemblySettings],
) -> list[Scene]:
    """Standing scenes moved by the module's one behaviour rule, then the AR-builder's
    resolution and the interaction (the module's collision story): behaviour is
    Scene -> Scene, each step a ``scene.with_tracks(...)`` of the step before.

    The steps: the tracks planned (the fitted behaviour,
    :func:`~are_stats.behaviour.simulate_behaviour_tracks`, or the catalogue's,
    :func:`~are_stats.behaviour.behaviour_tracks`), arrival groups put on their leader's
    route (:func:`~are_stats.behaviour.group_tracks`), the AR-builder's resolution
    (:meth:`~are_stats.builder.ARBuilder.resolve_scene`), the social force
    (:func:`~are_stats.behaviour.social_force_tracks`). The scenes are moved together
    (one key for all, as the behaviours draw them); artefacts of different scenes never
    meet.

    Parameters
    ----------
    key : jax.Array
        PRNG key of the tracks.
    scenes : sequence of Scene
        The standing scenes (:func:`scenes_from_tables`); a scene's scenario number is its
        table's ``scenario`` value, else its position in ``scenes``. Their tracks, if any,
        are replaced.
    grid, catalogue, horizon
        See :func:`scenes_from_fit`. Class labels are the scenes' own.
    options : AssemblyOptions, optional
        Its ``behaviours``, ``behaviour_cell``, ``behaviour_dt``, ``cell_source`` and
        ``interaction`` (default: ``AssemblyOptions(behaviours=True)``).
    fitted : BehaviourFit, optional
        The fit's behaviour (``"auto"`` uses it when given).
    source : str
        What errors name (the fit file, the options).
    progress : callable, optional
        ``progress(done, total, what)`` after each step: the tracks planned (the
        catalogue's behaviour one step per scenario, the fitted one per chunk of exits
        solved, :func:`~are_stats.behaviour.simulate_behaviour_tracks`), then (with
        ``interaction``) walked under the social force, one step per window of its
        simulation (:func:`~are_stats.behaviour.social_force_tracks`); ``done == total`` at
        the end. ``total`` is known once the first step of the planning is done, and grows
        when the social force starts (counted as one step until then).
    **settings
        Fields of :class:`AssemblyOptions` that replace those of ``options``.

    Returns
    -------
    list of Scene
        Scene ``i`` is ``scenes[i]`` with the tracks of its artefacts (the same life-cycle,
        classes and boxes); without behaviours (``"none"``), the scenes standing.

    Raises
    ------
    ValueError
        For catalogue behaviours without a map, or two scenes of one scenario number.
    """
    opts = (options or _MOVING).with_settings(settings)
    interaction, cell_source = opts.interaction, opts.cell_source
    kind = behaviour_source(opts.behaviours, fitted, grid, source)
    scenes = list(scenes)
    numbers = _numbers(scenes)
    labels = next((s.class_labels for s in scenes if s.class_labels is not None), None)
    parts = [
        s.artefacts if "scenario" in s.artefacts else s.artefacts.assign(scenario=k)
        for s, k in zip(scenes, numbers, strict=True)
        if len(s)
    ]
    art = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    say = progress or (lambda done, total, what: None)
    social = int(interaction is not False)  # the social force's steps (1 until it starts)
    planned = [0]  # the planning's steps (per scenario, or per chunk of exits)
    walked = [0, 0]  # the social force's windows: done, total

    def plan_step(done: int, total: int) -> None:
        planned[0] = total
        if kind == "catalogue":
            words = f" ({done} of {total} scenarios)" if total > 1 else ""
        else:  # the chunks of exits solved, then the paths timed
            words = f" ({done} of {total - 1} exit batches)" if done < total else ""
        say(done, total + social, f"tracks planned{words}")

    def walk_step(done: int, total: int) -> None:
        walked[:] = [done, total]
        base = max(planned[0], 1)
        say(base + done, base + total, f"walked with the social force ({done} of {total} windows)")

    tracks = None
    if kind == "fitted" and len(art):
        tracks = pd.DataFrame(
            simulate_behaviour_tracks(
                key, fitted, art, class_labels=labels, horizon=horizon, progress=plan_step
            )
        )
    elif kind == "catalogue" and len(art):
        free, _ = coarse_free(grid.free, grid.resolution, opts.behaviour_cell, source=cell_source)
        cut = art.assign(t_leave=np.minimum(art["t_leave"].to_numpy(float), horizon))
        check_tracks_size(cut, free.shape, opts.behaviour_dt, f"{source}, {cell_source}")
        tracks = pd.DataFrame(
            behaviour_tracks(
                key,
                art,
                np.concatenate([s.classes for s in scenes]),
                grid,
                catalogue,
                cell=opts.behaviour_cell,
                dt=opts.behaviour_dt,
                horizon=horizon,
                source=cell_source,
                progress=plan_step,
            )
        )
    steps = max(planned[0], 1) + social
    if not planned[0]:
        say(1, steps, "tracks planned")
    if tracks is not None and len(tracks):
        scenes = _with_tracks(scenes, numbers, tracks)  # planned
        walks = [_pedestrians(s, catalogue) for s in scenes]
        scenes, groups = _groups(scenes, numbers, art, walks, grid, interaction)
        scenes = _resolve(scenes, walks, interaction)
        if interaction is not False:
            pace = _speed_variation(key, fitted, art, labels) if kind == "fitted" else None
            scenes = _interact(scenes, numbers, walks, grid, interaction, groups, walk_step, pace)
    else:  # nothing moves
        scenes = [s.with_tracks(None) if s.has_tracks.any() else s for s in scenes]
    if social and not (walked[1] and walked[0] == walked[1]):
        say(steps, steps, "walked with the social force")
    return scenes


def _numbers(scenes: Sequence[Scene]) -> list[int]:
    """The scenario number of each scene: its table's ``scenario`` value, else its
    position in ``scenes``."""
    out = []
    for k, s in enumerate(scenes):
        if not isinstance(s, Scene) or s.artefacts is None:
            raise ValueError(
                f"scenes: expected scenes of a scenarios table (Scene.from_scenarios), got "
                f"{type(s).__name__} at position {k}"
            )
        table = s.artefacts
        out.append(int(table["scenario"].iloc[0]) if "scenario" in table and len(table) else k)
    if len(set(out)) != len(out):
        raise ValueError(f"scenes: expected one scene per scenario number, got {out}")
    return out


def _tracks_of(scenes: Sequence[Scene], numbers: Sequence[int]) -> pd.DataFrame:
    """``scenario, id, t, x, y, yaw``: the scenes' tracks, scene after scene (artefacts in
    table order, epochs in time order)."""
    parts = [s.tracks_table().assign(scenario=k) for s, k in zip(scenes, numbers, strict=True)]
    return pd.concat(parts, ignore_index=True)[["scenario", "id", "t", "x", "y", "yaw"]]


def _with_tracks(
    scenes: Sequence[Scene], numbers: Sequence[int], tracks: pd.DataFrame
) -> list[Scene]:
    """Each scene with the rows of ``tracks`` of its scenario number as its tracks."""
    by = dict(tuple(tracks.groupby("scenario", sort=True))) if len(tracks) else {}
    return [s.with_tracks(by.get(k)) for s, k in zip(scenes, numbers, strict=True)]


def _pedestrians(scene: Scene, catalogue: ArtefactCatalogue) -> np.ndarray:
    """(N,) bool: whether each artefact's class walks (its catalogue ``kind`` is
    ``pedestrian``, the default)."""
    kinds = [catalogue.row(int(c)).features.get("kind", "pedestrian") for c in scene.classes]
    return np.array([k == "pedestrian" for k in kinds], bool)


def _groups(
    scenes: list[Scene],
    numbers: Sequence[int],
    art: pd.DataFrame,
    walks: list[np.ndarray],
    grid: OccupancyGrid,
    interaction: bool | SocialForce,
) -> tuple[list[Scene], pd.Series | None]:
    """The scenes with the members of each arrival group on their leader's route
    (:func:`~are_stats.behaviour.group_tracks`; pedestrians only) and each artefact's
    group label, indexed by ``(scenario, id)`` (None without a ``group`` column);
    ``art`` is the scenes' tables, scene after scene."""
    if "group" not in art.columns:
        return scenes, None
    spacing = (interaction if isinstance(interaction, SocialForce) else SocialForce()).group_spacing
    id_col = "artefact" if "artefact" in art.columns else "id"
    if id_col not in art.columns:
        return scenes, None
    ids = art[id_col].to_numpy()
    sc = art["scenario"].to_numpy()
    walking = np.concatenate(walks)
    group = np.where(walking, art["group"].to_numpy(np.int64), -1)
    tracks = group_tracks(_tracks_of(scenes, numbers), art.assign(group=group), spacing, grid)
    groups = pd.Series(group, index=pd.MultiIndex.from_arrays([sc, ids]))
    return _with_tracks(scenes, numbers, tracks), groups


def _resolve(
    scenes: list[Scene], walks: list[np.ndarray], interaction: bool | SocialForce
) -> list[Scene]:
    """The scenes with the moves left to the AR-builder resolved by its rule
    (DECISIONS 9, :meth:`~are_stats.builder.ARBuilder.resolve_scene`): with the
    interaction on, the movers without a social force of their own (vehicles, carts)
    against each other and against everything standing (walking people give way to them
    afterwards); without it, every mover against everybody. The environment is the
    route planner's (routes keep to free cells), so the builder's map is open ground."""
    xy = np.concatenate([s.tracks_table()[["x", "y"]].to_numpy(float) for s in scenes])
    lo = xy.min(axis=0) - 10.0
    shape = np.ceil((xy.max(axis=0) + 10.0 - lo) / 0.5).astype(int) + 1
    ground = OccupancyGrid(np.zeros((shape[1], shape[0]), np.int8), 0.5, (lo[0], lo[1], 0.0))
    builder = ARBuilder(ground)
    out = []
    for scene, walking in zip(scenes, walks, strict=True):
        moving = np.array(
            [
                np.ptp(scene.track(i)[1][:, :2], axis=0).max(initial=0.0) > 1e-9
                if scene.has_tracks[i]
                else False
                for i in range(len(scene))
            ],
            bool,
        )
        movers = moving & ~walking if interaction is not False else moving
        if movers.any():
            resolved = builder.resolve_scene(scene, movers, others=~(moving & ~movers))
            for i in np.flatnonzero(movers):
                t, pose = resolved.track(int(i))
                planned = scene.track(int(i))[0]
                if t.shape != planned.shape or (t != planned).any():  # it had to wait
                    scene = scene.with_track(int(i), t, pose)
        out.append(scene)
    return out


def _interact(
    scenes: list[Scene],
    numbers: Sequence[int],
    walks: list[np.ndarray],
    grid: OccupancyGrid,
    interaction: bool | SocialForce,
    groups: pd.Series | None = None,
    progress: Callable[[int, int], None] | None = None,
    pace: tuple | None = None,
) -> list[Scene]:
    """The scenes walked again under the social force; non-pedestrians stay kinematic;
    arrival groups (labels by ``(scenario, id)``) walk together; ``progress(done, total)``
    after each window of its simulation; ``pace``: :func:`_speed_variation`'s."""
    params = interaction if isinstance(interaction, SocialForce) else SocialForce()
    tracks = _tracks_of(scenes, numbers)
    kinematic = np.concatenate(
        [
            ~w[pd.Index(s.ids).get_indexer(s.tracks_table()["id"])]
            for s, w in zip(scenes, walks, strict=True)
        ]
    )
    rows = None
    if groups is not None:
        at = pd.MultiIndex.from_arrays([tracks["scenario"].to_numpy(), tracks["id"].to_numpy()])
        rows = groups.reindex(at).fillna(-1).to_numpy(np.int64)
    speed_variation = heading_variation = None
    if pace is not None:
        from are_stats.traffic import fold_in_key  # lazy: NumPyro (+0.75 s on the import)

        key, by_artefact = pace
        at = pd.MultiIndex.from_arrays([tracks["scenario"].to_numpy(), tracks["id"].to_numpy()])
        per_row = by_artefact.reindex(at)
        if (np.nan_to_num(per_row["sd"].to_numpy(float)) > 0).any():
            speed_variation = (key, per_row["sd"].to_numpy(float), per_row["time"].to_numpy(float))
        if (np.nan_to_num(per_row["heading_sd"].to_numpy(float)) > 0).any():
            heading_variation = (
                fold_in_key(key, 1),  # its own processes, the pace's drawn as before
                per_row["heading_sd"].to_numpy(float),
                per_row["heading_time"].to_numpy(float),
            )
    # people arrive walking, at their plan's first velocity (arrival_velocities)
    walked = social_force_tracks(
        arrival_velocities(tracks),
        params,
        grid,
        kinematic=kinematic,
        groups=rows,
        progress=progress,
        speed_variation=speed_variation,
        heading_variation=heading_variation,
    ).drop(columns=["vx", "vy"])
    return _with_tracks(scenes, numbers, walked)


def _speed_variation(
    key: int | jax.Array,
    fitted: BehaviourFit | None,
    art: pd.DataFrame,
    labels: Sequence[str] | None,
) -> tuple | None:
    """The fitted within-person variation of the walking speed and heading of each
    artefact (its class's ``speed_within_sd`` and ``speed_within_time`` as ``sd`` and
    ``time``, ``heading_within_sd`` and ``heading_within_time`` as ``heading_sd`` and
    ``heading_time``; the class as :func:`~are_stats.behaviour.simulate_behaviour_tracks`
    takes it), indexed by ``(scenario, id)``, with the key of its processes (``key``
    folded with 26, so the planned tracks draw as before; the heading's folded once
    more); None when the fit has neither (an older fit file)."""
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
    from are_stats.traffic import fold_in_key, key_from_seed

    if (
        fitted is None
        or not len(art)
        or not (
            (np.nan_to_num(fitted.speed_within_sd) > 0).any()
            or (np.nan_to_num(fitted.heading_within_sd) > 0).any()
        )
    ):
        return None
    names = {c: i for i, c in enumerate(fitted.classes)}
    if "label" in art.columns:
        lab = art["label"].astype(str).to_numpy()
    elif labels is not None and "class" in art.columns:
        known = list(labels)
        lab = np.array([known[c] if 0 <= c < len(known) else "" for c in art["class"]])
    else:
        lab = np.full(len(art), "")
    cls = np.array([names.get(str(v), 0) for v in lab], np.int64)
    ids = art["artefact" if "artefact" in art.columns else "id"].to_numpy()
    index = pd.MultiIndex.from_arrays([art["scenario"].to_numpy(), ids])
    table = pd.DataFrame(
        {
            "sd": fitted.speed_within_sd[cls],
            "time": fitted.speed_within_time[cls],
            "heading_sd": fitted.heading_within_sd[cls],
            "heading_time": fitted.heading_within_time[cls],
        },
        index=index,
    )
    k = key_from_seed(int(key)) if isinstance(key, int | np.integer) else key
    return fold_in_key(k, 26), table


def scenes_from_fit(
    key: int | jax.Array,
    fit: Fit | az.InferenceData | str | os.PathLike[str],
    grid: OccupancyGrid | None,
    catalogue: ArtefactCatalogue,
    n: int,
    horizon: float,
    options: AssemblyOptions | None = None,
    *,
    posterior_draw: int | None = None,
    area: float | None = None,
    source: str | None = None,
    behaviours_source: str | None = None,
    map_source: str | None = None,
    progress: _Progress | None = None,
    **settings: Unpack[AssemblySettings],
) -> list[Scene]:
    """The one assembly: ``n`` posterior-predictive scenes of a fit, moved by the module's
    behaviour rule.

    Hand-set rates come as a fit too (:meth:`~are_stats.fitting.Fit.from_draws`).

    Parameters
    ----------
    key : int or jax.Array
        An int seed >= 0 (the scenarios use it, the tracks ``jax.random.key(seed)``: the
        command line's ``--seed``) or a JAX PRNG key (split in two).
    fit : Fit or str or PathLike
        A fit (:func:`~are_stats.fitting.read_fit`, or its path; an InferenceData of
        :func:`~are_stats.fitting.fit_log` is decoded by :func:`~are_stats.fitting.as_fit`;
        hand-set rates: :meth:`~are_stats.fitting.Fit.from_draws`).
    grid : OccupancyGrid or None
        The map (``M2D``); None places artefacts on a square of ``area`` (no behaviours).
    catalogue : ArtefactCatalogue
        The property table ``Q``.
    n : int
        Number of scenarios.
    horizon : float
        Length of each scenario (s).
    options : AssemblyOptions, optional
        The behaviour rule (``behaviours``: see the module docstring; default ``False``,
        standing scenes), ``start``, the catalogue behaviours' ``behaviour_cell`` (m),
        ``behaviour_dt`` (s per decision epoch) and ``cell_source`` (named in errors);
        ``interaction``: walk the tracks again with the social force (see the module
        docstring), ``True`` with the fit's parameters when it estimated them from the
        log's tracks (:func:`~are_stats.fitting.fit_interaction`), else the published ones,
        a :class:`~are_stats.behaviour.SocialForce` with those, ``False`` keeps the planned
        tracks, every mover's collisions resolved by the AR-builder's rule; ``model``,
        ``"chosen"`` generates from the models the fit chose, ``"paper"`` from the paper's
        Poisson / exponential / uniform model (:meth:`~are_stats.fitting.Fit.traffic`);
        ``positions``, where artefacts enter: ``"chosen"`` as ``model`` says (the entry
        density the fit learned, when it chose ``learned`` positions), or ``"uniform"``
        over the free cells of ``grid`` (the paper's positions; per-class entry densities
        dropped too) while the arrivals and stays stay the ones ``model`` gives: for a fit
        whose learned entries belong to another map (uniform positions with the paper's
        arrivals and stays are the paper's model, drawn as ``model="paper"`` draws it).
    posterior_draw : int, optional
        Use this one posterior draw for every scenario (the sweeps draw one per
        replicate); default: scenario ``i`` uses draw ``i mod S``.
    area : float, optional
        ``nu(M2D)`` (m^2) when it differs from the map's free area; without a map, default
        the fit's area.
    source : str, optional
        What errors name (default: where the fit came from,
        :attr:`~are_stats.fitting.Fit.source`: the file :func:`~are_stats.fitting.read_fit`
        read, the ``source`` given to :meth:`~are_stats.fitting.Fit.from_draws`; ``"fit"``
        for an InferenceData).
    behaviours_source, map_source : str, optional
        The options of ``behaviours`` and ``grid`` (e.g. ``"--behaviours"``, ``"--map"``),
        named when the behaviours need a map and there is none
        (:func:`behaviour_source`; default: ``source`` and the rule's own words). The rule
        is checked first, before the fit's draws or sizes.
    progress : callable, optional
        ``progress(done, total, what)`` after each step of the assembly: the scenarios
        drawn, then with behaviours the tracks planned and walked (:func:`move_scenes`: the
        catalogue's planning one step per scenario, the fitted behaviour's per chunk of
        exits, the social force per window); the last call has ``done == total``.
    **settings
        Fields of :class:`AssemblyOptions` that replace those of ``options`` (e.g.
        ``behaviours=True``).

    Returns
    -------
    list of Scene
        Scene ``i`` is scenario ``i``; ``scene.artefacts`` its table and
        :meth:`Scene.tracks_table` its tracks.

    Raises
    ------
    are_stats.inputs.InputError
        Naming ``--positions`` when ``positions`` is neither ``chosen`` nor ``uniform``.
    ValueError
        When the behaviour rule refuses ``behaviours`` (:func:`behaviour_source`).
    """
    # lazy: a cycle (fitting imports scenarios) and +1.0 s CPU on `import are_stats.scenarios`
    from are_stats.fitting import as_fit

    opts = (options or _STANDING).with_settings(settings)
    positions = get_str(opts.positions, "--positions", "", choices=POSITION_CHOICES)
    fit = as_fit(fit, source)
    source = fit.source if source is None else source
    kind = behaviour_source(
        opts.behaviours, fit.behaviour, grid, behaviours_source or source, map_source=map_source
    )
    draws, laws = fit.traffic(opts.model)
    if positions == "uniform":  # the fit's arrivals and stays, the paper's positions
        laws = replace(laws, positions="uniform", entry=None, class_entry=None)
    if "class_weights" in draws:  # a labelled log's classes: catalogue rows by name
        catalogue.rows_of_labels(
            list(fit.class_labels or ()), source, "posterior.attrs.class_labels"
        )
    if posterior_draw is not None:
        s = int(posterior_draw)
        draws = {k: np.asarray(v)[s : s + 1] for k, v in draws.items()}
    if opts.interaction is True and fit.interaction is not None:
        opts = replace(opts, interaction=fit.interaction)  # the log's own interaction
    nu = area
    if nu is None:
        if grid is not None:
            nu = float(np.count_nonzero(grid.free)) * grid.resolution**2
        elif fit.area is None:
            raise InputError(
                source,
                "posterior.attrs.area",
                "the fit's area (m^2; a fit of are-stats fit), or a map",
                Described("none"),
            )
        else:
            nu = fit.area
    check_scenario_size(draws, ScenarioSize(n, horizon, nu, opts.start), source)
    labels = None if fit.class_labels is None else list(fit.class_labels)
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
    from are_stats.traffic import key_from_seed, split_key

    if isinstance(key, int | np.integer) and not isinstance(key, bool):
        seed, k_tracks = int(key), None
    else:
        seed, k_tracks = split_key(key)
    art = generate_scenarios(
        seed,
        draws,
        n,
        horizon,
        free_mask=grid,
        area=nu if grid is None else area,
        start=opts.start,
        laws=laws,
    )
    standing = scenes_from_tables(art, None, catalogue, labels, range(n))
    say = progress or (lambda done, total, what: None)
    if kind == "none":
        say(1, 1, "scenarios drawn")
        return standing
    moves = 1 if opts.interaction is False else 2
    say(1, 1 + moves, "scenarios drawn")
    if k_tracks is None:
        k_tracks = key_from_seed(seed)
    return move_scenes(
        k_tracks,
        standing,
        grid,
        catalogue,
        horizon,
        replace(opts, behaviours=kind),
        fitted=fit.behaviour,
        source=source,
        progress=lambda done, total, what: say(1 + done, 1 + total, what),
    )
