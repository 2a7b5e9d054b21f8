"""Sweeps of navigation experiments (paper Sect. 4, Fig. 7) defined in YAML, run on Dask.

A sweep config is a base experiment plus ``factors``: each factor is a dotted key of the
config (``scenario.arrival_rate``, ``planner``, ``planner.range``, ``mission.time_limit`` ...)
with a list of levels; a ``planner`` level is a whole planner (its optional ``name`` labels
it). Tasks are the full factor grid times ``replicates``. Replicate ``r`` draws its scenario
and goals from ``SeedSequence([seed, r])`` whatever the factor levels (common random
numbers), so planner settings are compared on the same scenarios.

Example (the shipped ``fig7``: ``are-stats experiment fig7``)::

    name: fig7
    map: courtyard
    seed: 0
    replicates: 2
    scenario: {arrival_rate: 0.0005, leave_rate: 0.02, mix_weights: [0.6, 0.4],
               mix_rates: [0.5, 3.0], start: stationary}
    robot: {radius: 0.3, speed: 0.5}
    mission: {n_goals: 4, time_limit: 120, perception: all}
    planner: {algorithm: RRTConnect, range: 2.0}
    factors:
      scenario.arrival_rate: [0.0002, 0.001]
      planner:
        - {name: RRT*, algorithm: RRTstar, range: 2.0, goal_bias: 0.05, max_iterations: 300}
        - {name: A*, algorithm: astar}

Schema (every key optional; unknown keys are errors that list the known ones):

* ``name``: letters, digits, ``.``, ``_``, ``-`` (the default results folder
  ``results/<name>``); ``map``: a shipped map name or a ROS map YAML path; ``catalogue``:
  an artefact catalogue YAML or a shipped catalogue name (default the shipped one,
  :func:`~are_stats.load_catalogue`);
  ``behaviours``: true/false (artefacts move along behaviour tracks); ``avoid_robot``:
  true/false (default true: moving artefacts detour around the robot's footprint or wait
  for it, see :func:`~are_stats.experiments.run_mission`); ``seed``: integer in
  ``[0, 2**32 - 1]``; ``replicates``: integer >= 1.
* ``scenario``: one source of artefacts. Hand-set rates: ``arrival_rate`` (> 0, per m^2
  per s), ``leave_rate`` (> 0, per s), ``mix_weights`` (1 to 64 numbers > 0 summing to 1),
  ``mix_rates`` (as many numbers in ``(0, 1e6]``), ``start`` (``stationary`` or
  ``empty``). Or ``fit`` (a fit file of ``are-stats fit``; optional ``start``): replicate
  ``r`` generates its scenario from one posterior draw chosen by its seed. Or
  ``scenarios`` (a folder of ``are-stats generate``): replicate ``r`` uses scenario
  ``r mod n`` (and the folder's tracks with ``behaviours``). The source is not a factor.
* ``robot``: ``radius``, ``speed`` (> 0), ``camera_xyz``, ``camera_rpy`` (3 numbers),
  ``camera_fov`` (in ``(0, pi)``), ``image_size`` (2 integers in ``[1, 10000]``).
* ``mission``: ``n_goals`` (integer in ``[1, 100000]``), ``time_limit``,
  ``perception_period``, ``d_max`` (> 0), ``tau``, ``min_goal_separation`` (>= 0),
  ``perception`` (``all`` or ``camera``; ``camera`` needs the map's mesh ``<map>.ply``),
  ``behaviour_cell`` (m, > 0: the coarse grid behaviours move on), ``behaviour_dt`` (s per
  behaviour epoch, > 0).
* ``planner``: ``name`` (a label), ``algorithm`` (``astar`` or one of
  :data:`~are_stats.experiments.OMPL_ALGORITHMS`), ``range`` (> 0), ``goal_bias``
  (``[0, 1]``), ``time_limit`` (``(0, 3600]`` s), ``max_iterations`` (integer >= 1),
  ``simplify`` (true/false), ``motion_resolution`` (``[0.01, 1000]`` cells); options an
  algorithm lacks are errors (A* takes none).
* ``factors``: ``planner``, ``planner.<option>`` or ``<section>.<key>`` -> a non-empty list
  of distinct levels, each checked as the key it replaces.

Paths (``map``, ``catalogue``, ``scenario.fit``, ``scenario.scenarios``) relative to a config
file are taken from its folder (from the working directory for a dict, and for a shipped
config such as ``fig7_fit``, whose folder is inside the install), made absolute, and the
files are read and checked on the client before any Dask worker starts. ``map`` and
``catalogue`` may also name shipped files (:func:`~are_stats.environment.resolve_shipped`:
an existing file wins), and the config itself may be a shipped name (``fig7``).

Before anything runs, the expected work of the sweep (artefacts drawn, replans, grid passes,
motion steps, camera rays) and the memory of its largest task are estimated and refused past
:func:`are_stats.inputs.work_limit` / :func:`~are_stats.inputs.memory_limit` (raise them
with ``are-stats --max-work/--max-memory`` or ``ARE_STATS_MAX_WORK/ARE_STATS_MAX_MEMORY``).

Every task writes ``runs/<task>.parquet`` (one summary row, with the ``sweep`` digest of the
config), ``replans/<task>.parquet`` and ``goals/<task>.parquet`` atomically, ``runs`` last,
as soon as it finishes: an interrupted sweep resumes and skips every task whose ``runs``
file exists. With ``force`` the sweep runs into a hidden sibling folder that replaces the
results folder as a whole only once every task is done.

Same config, same bytes: ``sweep.yaml`` and every table are reproduced exactly, except the
wall-clock columns ``rho_t`` and ``rho`` (``replans``) and ``rho_mean`` and ``rho_t_mean``
(``runs``), and except the paths of OMPL planners that stop on their time budget rather
than at a first solution or ``max_iterations`` (PRM, or RRT* without ``max_iterations``).
"""

from __future__ import annotations

import asyncio
import contextlib
import copy
import functools
import hashlib
import itertools
import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Literal, NotRequired, TypedDict

import jax
import numpy as np
import pandas as pd
import pyarrow
import yaml

from are_stats._atomic import OutputExistsError, atomic_path, replace_folder
from are_stats.environment import (
    SHIPPED_DATA,
    ArtefactCatalogue,
    OccupancyGrid,
    load_catalogue,
    load_mesh,
    resolve_shipped,
    shipped_names,
    shipped_path,
)
from are_stats.experiments._loop import random_goals, run_mission
from are_stats.experiments._planners import OMPL_ALGORITHMS
from are_stats.experiments._robot import Robot
from are_stats.inputs import (  # Described: a ``got`` already worded, shown as is
    MAX_SEED,
    Described,
    InputError,
    check_keys,
    check_memory,
    check_work,
    get_bool,
    get_float,
    get_int,
    get_list,
    get_str,
    load_yaml,
)
from are_stats.scenarios import (
    AssemblyOptions,
    Scene,
    ScenesFolder,
    move_scenes,
    read_scenes,
    scenes_from_fit,
    scenes_from_tables,
)

if TYPE_CHECKING:
    import trimesh
    from distributed import Client, LocalCluster

    from are_stats.experiments._loop import MissionTrace
    from are_stats.fitting import Fit

__all__ = [
    "expand_tasks",
    "load_results",
    "load_sweep_config",
    "run_sweep",
    "run_task",
]


class ScenarioSection(TypedDict, total=False):
    """A sweep's ``scenario`` section, checked: hand-set rates (``arrival_rate`` ..
    ``start``), or a source, ``fit`` (with ``start``) or ``scenarios``, as an absolute
    path. See the module docstring for their ranges."""

    #: Arrivals per m^2 per s, and leaves per s.
    arrival_rate: float
    leave_rate: float
    #: The mixture's weights (summing to 1) and rates, as many of each (1 to 64).
    mix_weights: list[float]
    mix_rates: list[float]
    #: ``stationary`` or ``empty``.
    start: str
    #: A fit file of ``are-stats fit``, or a scenarios folder of ``are-stats generate``.
    fit: str
    scenarios: str


class RobotSection(TypedDict, total=False):
    """A sweep's ``robot`` section: the keywords of :class:`~are_stats.experiments.Robot`."""

    radius: float
    speed: float
    camera_xyz: list[float]
    camera_rpy: list[float]
    camera_fov: float
    image_size: list[int]


class MissionSection(TypedDict, total=False):
    """A sweep's ``mission`` section (times in s, distances in m)."""

    n_goals: int
    time_limit: float
    #: ``all`` or ``camera``.
    perception: str
    perception_period: float
    d_max: float
    tau: float
    min_goal_separation: float
    behaviour_cell: float
    behaviour_dt: float


class PlannerSection(TypedDict, total=False):
    """A sweep's ``planner`` section: a label, the algorithm and the options it takes."""

    name: str
    #: ``astar`` or one of :data:`~are_stats.experiments.OMPL_ALGORITHMS`.
    algorithm: str
    range: float
    goal_bias: float
    time_limit: float
    max_iterations: int
    simplify: bool
    motion_resolution: float


class Sections(TypedDict):
    """The four sections of a config or of one point of its factor grid."""

    scenario: ScenarioSection
    robot: RobotSection
    mission: MissionSection
    planner: PlannerSection


class SweepConfig(TypedDict):
    """A checked sweep config (:func:`load_sweep_config`): defaults filled in, paths
    absolute (a shipped map's name kept), values plain Python types."""

    name: str
    map: str
    #: An artefact catalogue YAML, or None for the shipped one.
    catalogue: str | None
    behaviours: bool
    avoid_robot: bool
    seed: int
    replicates: int
    scenario: ScenarioSection
    robot: RobotSection
    mission: MissionSection
    planner: PlannerSection
    #: Factor key -> its checked levels (numbers, lists, strings, planner sections).
    factors: dict[str, list[object]]


class SweepTask(TypedDict):
    """One task of a sweep (:func:`expand_tasks`): self-contained, one point of the factor
    grid and one replicate."""

    map: str
    catalogue: str | None
    behaviours: bool
    avoid_robot: bool
    replicate: int
    #: The replicate's integer seed, from ``SeedSequence([config seed, replicate])``.
    seed: int
    #: Factor key -> the label of its level.
    levels: dict[str, str]
    scenario: ScenarioSection
    robot: RobotSection
    mission: MissionSection
    planner: PlannerSection
    #: A file-name stem (index and a digest of the settings), and the config's digest.
    task: str
    sweep: str


class TaskResult(TypedDict):
    """The tables of one task (:func:`run_task`)."""

    runs: pd.DataFrame
    replans: pd.DataFrame
    goals: pd.DataFrame
    #: The mission's trace, when recorded.
    trace: NotRequired[MissionTrace]


class _TaskSource(TypedDict):
    """Where a task's scene came from (:func:`_task_scenario`)."""

    draw: int
    arrival_rate: float
    n_artefacts: int
    n_arrivals: int


_DEFAULTS: SweepConfig = {
    "name": "sweep",
    "map": "courtyard",
    "catalogue": None,
    "behaviours": False,
    "avoid_robot": True,
    "seed": 0,
    "replicates": 1,
    "scenario": {
        "arrival_rate": 0.0005,
        "leave_rate": 0.02,
        "mix_weights": [1.0],
        "mix_rates": [0.5],
        "start": "stationary",
    },
    "robot": {"radius": 0.3, "speed": 0.5},
    "mission": {
        "n_goals": 4,
        "time_limit": 120.0,
        "perception": "all",
        "perception_period": 1.0,
        "d_max": 10.0,
        "tau": 10.0,
        "min_goal_separation": 5.0,
        "behaviour_cell": 1.0,
        "behaviour_dt": 2.0,
    },
    "planner": {"algorithm": "RRTConnect", "range": 2.0},
    "factors": {},
}
_SECTIONS = ("scenario", "robot", "mission", "planner")
_TOP = (
    "name",
    "map",
    "catalogue",
    "behaviours",
    "avoid_robot",
    "seed",
    "replicates",
    *_SECTIONS,
    "factors",
)
#: Scenario keys that name where the artefacts come from instead of hand-set rates.
_SOURCES = ("fit", "scenarios")
_RATES = ("arrival_rate", "leave_rate", "mix_weights", "mix_rates")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
#: Most mixture components of a scenario.
MAX_COMPONENTS = 64

# ---- the schema: one checker per key ------------------------------------------------------

_Checker = Callable[[object, str, str], object]


def _number(**bounds: float | bool | None) -> _Checker:
    return lambda v, s, w: get_float(v, s, w, **bounds)


def _integer(lo: int, hi: int) -> _Checker:
    return lambda v, s, w: get_int(v, s, w, lo=lo, hi=hi)


def _choice(*choices: str) -> _Checker:
    return lambda v, s, w: get_str(v, s, w, choices=choices)


def _numbers(n_min: int, n_max: int, item: _Checker) -> _Checker:
    def check(v: object, s: str, w: str) -> list:
        return [
            item(x, s, f"{w}[{i}]")
            for i, x in enumerate(get_list(v, s, w, min_len=n_min, max_len=n_max))
        ]

    return check


def _ints(n: int, lo: int, hi: int) -> _Checker:
    return _numbers(n, n, _integer(lo, hi))


_POSITIVE = _number(lo=0.0, lo_open=True)
_NONNEG = _number(lo=0.0)
_SCHEMA: dict[str, dict[str, _Checker]] = {
    "scenario": {
        "arrival_rate": _POSITIVE,
        "leave_rate": _POSITIVE,
        "mix_weights": _numbers(1, MAX_COMPONENTS, _POSITIVE),
        "mix_rates": _numbers(1, MAX_COMPONENTS, _number(lo=0.0, lo_open=True, hi=1e6)),
        "start": _choice("stationary", "empty"),
        "fit": lambda v, s, w: _path_string(v, s, w),
        "scenarios": lambda v, s, w: _path_string(v, s, w),
    },
    "robot": {
        "radius": _POSITIVE,
        "speed": _POSITIVE,
        "camera_xyz": _numbers(3, 3, _number()),
        "camera_rpy": _numbers(3, 3, _number()),
        "camera_fov": _number(lo=0.0, hi=math.pi, lo_open=True, hi_open=True),
        "image_size": _ints(2, 1, 10_000),
    },
    "mission": {
        "n_goals": _integer(1, 100_000),
        "time_limit": _POSITIVE,
        "perception": _choice("all", "camera"),
        "perception_period": _POSITIVE,
        "d_max": _POSITIVE,
        "tau": _NONNEG,
        "min_goal_separation": _NONNEG,
        "behaviour_cell": _POSITIVE,
        "behaviour_dt": _POSITIVE,
    },
    "planner": {
        "name": lambda v, s, w: get_str(v, s, w),
        "algorithm": _choice("astar", *OMPL_ALGORITHMS),
        "range": _POSITIVE,
        "goal_bias": _number(lo=0.0, hi=1.0),
        "time_limit": _number(lo=0.0, lo_open=True, hi=3600.0),
        "max_iterations": _integer(1, 2**62),
        "simplify": lambda v, s, w: get_bool(v, s, w),
        "motion_resolution": _number(lo=0.01, hi=1000.0),
    },
}
# options each planner algorithm takes besides name and algorithm
_PLANNER_OPTIONS = {
    "astar": (),
    "RRT": ("range", "goal_bias", "time_limit", "max_iterations", "simplify", "motion_resolution"),
    "RRTConnect": ("range", "time_limit", "max_iterations", "simplify", "motion_resolution"),
    "RRTstar": (
        "range", "goal_bias", "time_limit", "max_iterations", "simplify", "motion_resolution"
    ),
    "PRM": ("time_limit", "simplify", "motion_resolution"),
}  # fmt: skip


def _path_string(value: object, src: str, where: str) -> str:
    v = get_str(value, src, where)
    if not v or "\x00" in v:
        raise InputError(src, where, "a file or folder path", v)
    return v


def _resolve(value: str, base: Path) -> str:
    """``value`` as an absolute path, a relative one taken from the folder ``base`` (the
    config file's)."""
    return str((base / Path(value).expanduser()).resolve())


def _resolve_map(name: str, base: Path) -> str:
    """A map path relative to ``base`` made absolute; a shipped map name kept as is."""
    p = base / Path(name).expanduser()
    if not p.is_file() and name == Path(name).name and name in shipped_names("map"):
        return name
    return str(p.resolve())


def _resolve_catalogue(value: str, base: Path, src: str) -> str:
    """A catalogue path relative to ``base`` made absolute, or a shipped catalogue's file."""
    return str(resolve_shipped(value, "catalogue", base=base, source=src, where="catalogue"))


def _scenario(given: Mapping[str, object], src: str, base: Path) -> ScenarioSection:
    """The scenario section: hand-set rates merged over the defaults, or one source (a fit
    or a scenarios folder, its path resolved against ``base``) with nothing it replaces."""
    sources = [k for k in _SOURCES if k in given]
    if not sources:
        return {**copy.deepcopy(_DEFAULTS["scenario"]), **given}
    if len(sources) > 1:
        raise InputError(
            src,
            "scenario.scenarios",
            "either scenario.fit or scenario.scenarios, not both",
            Described(f"scenarios: {given['scenarios']!r}"),
        )
    key = sources[0]
    allowed = ("fit", "start") if key == "fit" else ("scenarios",)
    for k in given:
        if k not in allowed:
            gives = "the rates and mixture" if key == "fit" else "the artefacts"
            raise InputError(
                src,
                f"scenario.{k}",
                f"no {k} beside scenario.{key} (it gives {gives}; keys: {', '.join(allowed)})",
                Described(f"{k}: {given[k]!r}"),
            )
    out = {key: _resolve(given[key], base)}
    if key == "fit":
        out["start"] = given.get("start", _DEFAULTS["scenario"]["start"])
    return out


def _section(sec: str, value: object, src: str, where: str) -> dict[str, object]:
    """Check every key of one section (a mapping); values normalised to plain types."""
    schema = _SCHEMA[sec]
    raw = check_keys(value, src, where, schema)
    return {k: schema[k](v, src, f"{where}.{k}") for k, v in raw.items()}


def _cross(sections: Sections, src: str, where: str) -> None:
    """Constraints between keys of the resolved sections (``where`` names the task)."""
    pre = f"{where}: " if where else ""
    sc = sections["scenario"]
    w, r = sc.get("mix_weights", ()), sc.get("mix_rates", ())
    if len(w) != len(r):
        raise InputError(
            src,
            f"{pre}scenario.mix_rates",
            f"as many rates as scenario.mix_weights has weights ({len(w)})",
            r,
        )
    if w and abs(math.fsum(w) - 1.0) > 1e-6:
        raise InputError(src, f"{pre}scenario.mix_weights", "weights summing to 1", w)
    pl = sections["planner"]
    algo = pl.get("algorithm", "RRTConnect")
    allowed = _PLANNER_OPTIONS[algo]
    for key in pl:
        if key not in ("name", "algorithm") and key not in allowed:
            takes = ", ".join(allowed) if allowed else "no option"
            raise InputError(
                src,
                f"{pre}planner.{key}",
                f"only options that planner {algo!r} takes ({takes})",
                Described(f"{key}: {pl[key]!r}"),
            )


def _factor_checker(key: object, src: str) -> tuple[str, str, _Checker | None]:
    """``(section, option, checker)`` of a factor key; ``checker`` None for ``planner``."""
    where = f"factors.{key}"
    expected = (
        "a factor key 'planner', 'planner.<option>' or '<section>.<key>' with a section in "
        + ", ".join(_SECTIONS[:3])
    )
    if not isinstance(key, str):
        raise InputError(src, "factors", expected, Described(f"the key {key!r}"))
    sec, dot, sub = key.partition(".")
    if key == "planner":
        return "planner", "", None
    if sec not in _SCHEMA or not dot:
        raise InputError(src, where, expected, Described(f"the key {key!r}"))
    if sub not in _SCHEMA[sec]:
        raise InputError(
            src,
            where,
            f"a key of {sec}: one of " + ", ".join(_SCHEMA[sec]),
            Described(f"an unknown key {sub!r}"),
        )
    return sec, sub, _SCHEMA[sec][sub]


def _label(level: object) -> str:
    if isinstance(level, Mapping):
        if "name" in level:
            return str(level["name"])
        return ",".join(f"{k}={v}" for k, v in level.items())
    return str(level)


def _validate(raw: object, src: str, base: Path | None = None) -> SweepConfig:
    """The schema check of a whole config (no file other than the config is read); relative
    paths (map, catalogue, scenario.fit, scenario.scenarios) are made absolute from the
    folder ``base`` (default: the working directory)."""
    base = Path.cwd() if base is None else Path(base)
    top = check_keys(raw, src, "", _TOP)
    cfg: SweepConfig = {}  # filled in key by key below
    name = top.get("name", _DEFAULTS["name"])
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(
            src,
            "name",
            "a name of 1 to 100 letters, digits, '.', '_' or '-' (not starting with '.', '_' "
            "or '-')",
            name,
        )
    cfg["name"] = name
    cfg["map"] = get_str(top.get("map", _DEFAULTS["map"]), src, "map")
    if not cfg["map"] or "\x00" in cfg["map"]:
        raise InputError(src, "map", "a shipped map name or a ROS map YAML path", cfg["map"])
    cfg["map"] = _resolve_map(cfg["map"], base)
    cat = top.get("catalogue")
    cfg["catalogue"] = (
        None if cat is None else _resolve_catalogue(_path_string(cat, src, "catalogue"), base, src)
    )
    cfg["behaviours"] = get_bool(top.get("behaviours", False), src, "behaviours")
    cfg["avoid_robot"] = get_bool(top.get("avoid_robot", True), src, "avoid_robot")
    cfg["seed"] = get_int(top.get("seed", _DEFAULTS["seed"]), src, "seed", lo=0, hi=MAX_SEED)
    cfg["replicates"] = get_int(
        top.get("replicates", _DEFAULTS["replicates"]), src, "replicates", lo=1, hi=2**62
    )
    for sec in _SECTIONS:
        # an empty section (``robot:`` with nothing, or only comments, below) is no section
        present = top.get(sec) is not None
        given = _section(sec, top[sec], src, sec) if present else {}
        if sec == "scenario":
            cfg[sec] = _scenario(given, src, base)
            continue
        # the planner is replaced as a whole; the other sections are merged over defaults
        merged = {} if sec == "planner" and present else copy.deepcopy(_DEFAULTS[sec])
        cfg[sec] = {**merged, **given}
    _cross(cfg, src, "")
    factors = top.get("factors")
    factors = {} if factors is None else factors  # ``factors:`` with nothing below: none
    if not isinstance(factors, Mapping):
        raise InputError(src, "factors", "a mapping of factor key -> list of levels", factors)
    cfg["factors"] = {}
    for key, levels in factors.items():
        sec, sub, checker = _factor_checker(key, src)
        where = f"factors.{key}"
        if sec == "scenario" and sub in _SOURCES:
            raise InputError(
                src,
                where,
                "a factor other than the scenario source (one sweep, one source)",
                Described(f"the key {key!r}"),
            )
        source = next((k for k in _SOURCES if k in cfg["scenario"]), None)
        if sec == "scenario" and source is not None and sub not in cfg["scenario"]:
            raise InputError(
                src,
                where,
                f"no scenario rate factor beside scenario.{source} (it gives them)",
                Described(f"the key {key!r}"),
            )
        if not isinstance(levels, list | tuple) or not levels:
            raise InputError(src, where, "a non-empty list of levels", levels)
        clean, labels = [], {}
        for i, level in enumerate(levels):
            if checker is None:
                level = _section("planner", level, src, f"{where}[{i}]")
            else:
                level = checker(level, src, f"{where}[{i}]")
            label = _label(level)
            if label in labels:
                raise InputError(
                    src,
                    f"{where}[{i}]",
                    f"levels with distinct labels (level {labels[label]} is labelled the same)",
                    Described(repr(label)),
                )
            labels[label] = i
            clean.append(level)
        cfg["factors"][key] = clean
    return cfg


def _combos(cfg: SweepConfig) -> Iterator[tuple[Sections, dict[str, str]]]:
    """Sections and level labels of each point of the factor grid (replicates aside)."""
    factors = cfg["factors"]
    keys = list(factors)
    for combo in itertools.product(*[factors[k] for k in keys]):
        base = {k: copy.deepcopy(cfg[k]) for k in _SECTIONS}
        levels = {}
        for key, level in zip(keys, combo, strict=True):
            sec, _, sub = key.partition(".")
            if sub:
                base[sec][sub] = copy.deepcopy(level)
            else:
                base[sec] = copy.deepcopy(level)
            levels[key] = _label(level)
        yield base, levels


def _n_combos(cfg: SweepConfig) -> int:
    return math.prod(len(v) for v in cfg["factors"].values())


# ---- cost estimates -----------------------------------------------------------------------

# Rough per-unit costs, in the elementary steps of are_stats.inputs.work_limit and bytes.
_STEPS_PER_ARTEFACT = 3_000  # drawing it and building its box (Python per artefact)
_STEPS_PER_LIVE = 3_000  # re-registering a live artefact on the AR grid at each update
_STEPS_PER_CELL = 100  # grid passes of one replan (distance transform, masks, A*)
_STEPS_PER_MOTION = 200  # one footprint test along the path
_STEPS_PER_RAY = 2_000  # one camera ray against the mesh and the boxes
_STEPS_PER_TASK = 1_000_000  # fixed cost of a task (map, catalogue, goals, tables)
_BYTES_PER_ARTEFACT = 1_000
_BYTES_PER_CELL = 200
_BYTES_PER_MOTION = 200
_BYTES_PER_RAY = 500
_BYTES_PER_TASK = 8_192  # a task dict of the task list


def _map_file(name: str) -> Path | None:
    p = Path(name)
    if p.is_file():
        return p
    if p.name == name and name in shipped_names("map"):
        return shipped_path(name, "map")
    return None


def _shipped_maps() -> list[str]:
    return shipped_names("map")


def _stamp(path: str | os.PathLike | None) -> tuple[tuple[str, int, int], ...] | None:
    """What identifies the content of a file or a folder for the caches below: size and
    modification time of the file and of the files beside it (a map's image, a
    catalogue's meshes), or of every file of a folder. A cache keyed by it never serves a
    file that was edited or replaced since (a damaged catalogue is read, and refused)."""
    if path is None:
        return None
    p = Path(path)
    try:
        if p.is_dir():
            files = sorted(c for c in p.iterdir() if c.is_file())
        elif p.is_file():
            beside = sorted(c for c in itertools.islice(p.parent.iterdir(), 257) if c.is_file())
            files = [p] if len(beside) > 256 else beside
        else:
            return None
        return tuple((c.name, c.stat().st_mtime_ns, c.stat().st_size) for c in files)
    except OSError:
        return None


def _cached(
    locate: Callable[[str | None], str | os.PathLike | None] = lambda a: a,
) -> Callable[[Callable], Callable]:
    """``functools.lru_cache`` (4 entries) of a one-argument reader, keyed by the argument
    and the :func:`_stamp` of the file it names (``locate`` finds that file)."""

    def wrap(fn: Callable) -> Callable:
        @functools.lru_cache(maxsize=4)
        def by_content(arg: str | None, stamp: tuple | None) -> object:
            return fn(arg)

        @functools.wraps(fn)
        def read(arg: str | None) -> object:
            return by_content(arg, _stamp(locate(arg)))

        read.cache_clear = by_content.cache_clear  # type: ignore[attr-defined]
        return read

    return wrap


@_cached()
def _grid(path: str) -> OccupancyGrid:
    return OccupancyGrid.from_ros_yaml(path)


@_cached()
def _fit(path: str) -> Fit:
    """The fit at ``path``, read and checked once (:func:`~are_stats.fitting.read_fit`)."""
    # lazy: fitting (NumPyro) adds 1.0 s CPU to `import are_stats.experiments`
    from are_stats.fitting import read_fit

    return read_fit(path)


@_cached()
def _scenario_folder(path: str) -> ScenesFolder:
    """A scenarios folder (artefacts, manifest and behaviour tracks), all checked
    (:func:`~are_stats.scenarios.read_scenes`)."""
    return read_scenes(path)


@_cached()
def _load_catalogue(path: str | None) -> ArtefactCatalogue:
    return load_catalogue(path)


#: The scenario sources read from disk: whether each is a folder, and what it must be.
_SOURCES = {
    "scenarios": (True, "a scenarios folder written by are-stats generate"),
    "fit": (False, "a fit file written by are-stats fit"),
}


def _source_path(sc: ScenarioSection, key: Literal["scenarios", "fit"], src: str, pre: str) -> Path:
    """The scenario section's source ``key`` (``scenarios`` or ``fit``), which must exist."""
    p = Path(sc[key])
    folder, expected = _SOURCES[key]
    if not (p.is_dir() if folder else p.is_file()):
        kind = "folder" if folder else "file"
        raise InputError(src, f"{pre}scenario.{key}", expected, Described(f"no such {kind} {p}"))
    return p


def _scenario_size(
    sections: Sections, grid: OccupancyGrid, src: str, pre: str
) -> tuple[float, float, float]:
    """``(artefacts, live at once, arrivals and leaves)`` expected in one task; reads (and
    so checks) the scenario source, naming its key in errors."""
    sc, horizon = sections["scenario"], float(sections["mission"]["time_limit"])
    if "scenarios" in sc:
        p = _source_path(sc, "scenarios", src, pre)
        folder = _scenario_folder(str(p))
        df, h = folder.artefacts, folder.horizon
        if h is not None and horizon > h * (1 + 1e-9):
            raise InputError(
                src,
                f"{pre}mission.time_limit",
                f"at most the horizon {h} of the scenarios {p}",
                horizon,
            )
        n = float(df.groupby("scenario").size().max()) if len(df) else 0.0
        return n, n, 2.0 * n
    if "fit" in sc:
        p = _source_path(sc, "fit", src, pre)
        draws = _fit(str(p)).traffic("chosen")[0]
        lam, mu = float(np.mean(draws["arrival_rate"])), float(np.mean(draws["leave_rate"]))
    else:
        lam, mu = float(sc["arrival_rate"]), float(sc["leave_rate"])
    lam_nu = lam * grid.n_free * grid.resolution**2
    stationary = sc["start"] == "stationary"
    n_art = lam_nu / mu * stationary + lam_nu * horizon
    n_live = lam_nu / mu if stationary else lam_nu * min(horizon, 1.0 / mu)
    return n_art, n_live, 2.0 * lam_nu * horizon


def _task_cost(
    sections: Sections,
    grid: OccupancyGrid,
    size: tuple[float, float, float],
    behaviours: bool,
) -> tuple[float, float, str]:
    """``(bytes, steps, description)`` of one task, from its expected artefact, event,
    motion-step, camera-ray and behaviour-policy counts."""
    ms, rb = sections["mission"], sections["robot"]
    n_art, n_live, n_events = size
    horizon = ms["time_limit"]
    camera = ms["perception"] == "camera"
    n_checks = horizon / ms["perception_period"] if camera else 0.0
    n_epochs = horizon / ms["behaviour_dt"] if behaviours else 0.0
    # a camera check replans only when A_f changes: about twice per artefact
    n_plans = n_events + min(n_checks, 2.0 * n_art) + n_epochs + ms["n_goals"] + 1.0
    step = min(grid.resolution, rb["radius"] / 2.0)
    n_motion = rb["speed"] * horizon / step + n_plans
    w, h = rb.get("image_size", (64, 48))
    rays = float(w) * float(h) if camera else 0.0
    cells = float(grid.data.size)
    # the MDP policy of the artefacts' behaviours: artefacts x epochs (padded to 64) x cells
    f = max(1.0, round(ms["behaviour_cell"] / grid.resolution))
    policy = n_art * 64.0 * math.ceil(max(n_epochs, 1.0) / 64.0) * cells / f**2 * 4.0
    policy *= behaviours
    n_bytes = (
        n_art * _BYTES_PER_ARTEFACT
        + cells * _BYTES_PER_CELL
        + n_motion * _BYTES_PER_MOTION
        + rays * _BYTES_PER_RAY
        + policy
    )
    steps = (
        _STEPS_PER_TASK
        + n_art * _STEPS_PER_ARTEFACT
        + n_plans * (cells * _STEPS_PER_CELL + n_live * _STEPS_PER_LIVE)
        + n_motion * _STEPS_PER_MOTION
        + n_checks * rays * _STEPS_PER_RAY
        + policy * 10.0
    )
    what = f"about {n_art:.3g} artefacts, {n_motion:.3g} motion steps, {cells:.3g} map cells"
    if camera:
        what += f", {n_checks * rays:.3g} camera rays"
    if behaviours:
        what += f", {n_epochs:.3g} behaviour epochs"
    return n_bytes, steps, what


def _check_cost(cfg: SweepConfig, src: str, concurrent: int = 1) -> None:
    """Refuse a sweep whose task list, largest task (times ``concurrent`` tasks at once) or
    total work is past the limits; also checks every grid point's cross-key constraints."""
    n_combos = _n_combos(cfg)
    n_tasks = n_combos * cfg["replicates"]
    check_memory(n_tasks * _BYTES_PER_TASK, f"the task list of {n_tasks} tasks", src)
    check_work(n_tasks * _STEPS_PER_TASK, f"a sweep of {n_tasks} tasks", src)
    path = _map_file(cfg["map"])
    if path is None:
        raise InputError(
            src,
            "map",
            "a shipped map name (" + ", ".join(_shipped_maps()) + ") or the path of a ROS map YAML",
            cfg["map"],
        )
    grid = _grid(str(path))
    has_mesh = path.with_suffix(".ply").is_file()
    if cfg["catalogue"] is not None:
        if not Path(cfg["catalogue"]).is_file():
            raise InputError(
                src,
                "catalogue",
                "an artefact catalogue YAML",
                Described(f"no such file {cfg['catalogue']}"),
            )
        _load_catalogue(cfg["catalogue"])
    if cfg["behaviours"] and abs(float(grid.origin[2])) > 1e-9 and _rolls_out(cfg["scenario"]):
        raise InputError(
            src,
            "behaviours",
            "a map whose origin yaw is 0 (behaviours move on its cells)",
            Described(f"true, with the map's origin yaw {grid.origin[2]}"),
        )
    worst_bytes, total, worst = 0.0, 0.0, ""
    for sections, levels in _combos(cfg):
        where = "factors " + ", ".join(f"{k}={v}" for k, v in levels.items()) if levels else ""
        _cross(sections, src, where)
        if sections["mission"]["perception"] == "camera" and not has_mesh:
            raise InputError(
                src,
                (f"{where}: " if where else "") + "mission.perception",
                f"'all', or 'camera' with the map's mesh {path.with_suffix('.ply')}",
                Described("'camera' and no such mesh"),
            )
        size = _scenario_size(sections, grid, src, f"{where}: " if where else "")
        n_bytes, steps, what = _task_cost(sections, grid, size, cfg["behaviours"])
        if n_bytes > worst_bytes:
            worst_bytes, worst = n_bytes, (f"{where}: " if where else "") + what
        total += steps * cfg["replicates"]
    what = f"one task ({worst})"
    if concurrent > 1:
        what = f"{concurrent} tasks at once like {what}"
    check_memory(worst_bytes * concurrent, what, src)
    check_work(total, f"the {n_tasks} tasks of the sweep", src)


def _rolls_out(scenario: ScenarioSection) -> bool:
    """Whether ``behaviours`` roll tracks out on the map's cells for this scenario source:
    not when a scenarios folder brings its own tracks, nor when a fit brings its fitted
    behaviour (which moves in the plane)."""
    if "scenarios" in scenario and Path(scenario["scenarios"]).is_dir():
        return _scenario_folder(str(scenario["scenarios"])).tracks is None
    if "fit" in scenario and Path(scenario["fit"]).is_file():
        return _fit(str(scenario["fit"])).behaviour is None
    return True  # (a missing source is named by the checks of each task)


def load_sweep_config(config: str | os.PathLike | Mapping[str, object]) -> SweepConfig:
    """Read and validate a sweep config (a YAML path, a shipped config's name such as
    ``fig7``, or a dict), with defaults filled in.

    The whole config is checked against the schema of the module docstring (known keys per
    section, types, ranges, every factor level), the map is read, and the sweep's memory
    and work are estimated and checked against the limits of :mod:`are_stats.inputs`.

    Returns
    -------
    dict
        The config with defaults filled in and values as plain Python types.

    Raises
    ------
    FileNotFoundError
        If the YAML file or the map does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) naming the config and the key path, on any bad key or value.
    are_stats.inputs.LimitError
        If the sweep needs more memory or work than the limits.
    """
    if isinstance(config, Mapping):
        raw, src, base = config, "config", Path.cwd()
    elif isinstance(config, str | os.PathLike):
        p = resolve_shipped(config, "experiment", source="sweep config")  # or a shipped name
        if not p.exists():
            raise FileNotFoundError(f"{p}: sweep config not found")
        # a shipped config's folder is inside the install: its relative paths (a fit to
        # make first) are taken from the working directory
        shipped = p.resolve().is_relative_to(SHIPPED_DATA.resolve())
        raw, src = load_yaml(p, "sweep config"), str(p)
        base = Path.cwd() if shipped else p.resolve().parent
    else:
        raise InputError("config", "", "a sweep config path or mapping", config)
    cfg = _validate(raw, src, base)
    _check_cost(cfg, src)
    return cfg


def _digest(obj: object) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:10]


def _expand(cfg: SweepConfig) -> list[SweepTask]:
    sweep = _digest(cfg)
    tasks = []
    idx = 0
    for base, levels in _combos(cfg):
        for r in range(cfg["replicates"]):
            seed = int(np.random.SeedSequence([cfg["seed"], r]).generate_state(1)[0])
            task: SweepTask = {  # task and sweep added below
                "map": cfg["map"],
                "catalogue": cfg["catalogue"],
                "behaviours": cfg["behaviours"],
                "avoid_robot": cfg["avoid_robot"],
                "replicate": r,
                "seed": seed,
                "levels": levels,
                **base,
            }
            task["task"] = f"{idx:05d}-{_digest(task)}"
            task["sweep"] = sweep
            tasks.append(task)
            idx += 1
    return tasks


def expand_tasks(config: str | os.PathLike | Mapping[str, object]) -> list[SweepTask]:
    """The tasks of a sweep: factor grid x replicates, each a self-contained dict.

    Each task has ``task`` (a file-name stem: index and a digest of its settings),
    ``sweep`` (a digest of the whole config), ``replicate``, ``seed`` (the replicate's
    integer seed), ``levels`` (factor -> label) and the resolved ``scenario``, ``robot``,
    ``mission``, ``planner``, ``map``, ``catalogue`` (an absolute path or None),
    ``behaviours`` and ``avoid_robot``.
    """
    return _expand(load_sweep_config(config))


@_cached(lambda name: _map_file(name))
def _load_map(name: str) -> tuple[OccupancyGrid, trimesh.Trimesh | None]:
    p = _map_file(name)
    if p is None:
        raise InputError("map", "", "a shipped map name or the path of a ROS map YAML", name)
    grid = _grid(str(p))
    mesh_path = p.with_suffix(".ply")
    mesh = load_mesh(mesh_path) if mesh_path.is_file() else None
    return grid, mesh


def _task_scenario(
    task: SweepTask, grid: OccupancyGrid, catalogue: ArtefactCatalogue
) -> tuple[Scene, _TaskSource]:
    """The task's Scene (with behaviour tracks when asked) and the columns that describe
    where it came from: ``draw`` (posterior draw, scenario of the folder, or -1),
    ``arrival_rate``, ``n_artefacts`` and ``n_arrivals`` (arrivals in ``(0, time_limit]``).

    The scene comes from the one assembly that ``generate`` and ``augment`` use
    (:func:`~are_stats.scenarios.scenes_from_fit` at one posterior draw; hand-set rates
    as a fit of one draw, :meth:`~are_stats.fitting.Fit.from_draws`), moved by
    the fit's behaviour when it has one, else the catalogue's, then the social force. A
    scenarios folder brings its own scenes (and tracks; without them, the same behaviour
    rule moves its artefacts).
    """
    sc, ms = task["scenario"], task["mission"]
    seed, horizon = int(task["seed"]), float(ms["time_limit"])
    options = AssemblyOptions(
        behaviours=bool(task.get("behaviours")),
        start=sc.get("start", "stationary"),
        behaviour_cell=float(ms.get("behaviour_cell", 1.0)),
        behaviour_dt=float(ms.get("behaviour_dt", 2.0)),
        cell_source="mission.behaviour_cell",
    )
    behave = options.behaviours
    if "scenarios" in sc:
        folder = _scenario_folder(str(sc["scenarios"]))
        table, all_tracks = folder.artefacts, folder.tracks
        n = int(table["scenario"].max()) + 1 if len(table) else 1
        n = max(n, int(folder.manifest.get("n_scenarios", n) or n))
        draw = int(task["replicate"]) % n
        labels = folder.class_labels
        art = table[table["scenario"] == draw].reset_index(drop=True)
        tracks = None
        if behave and all_tracks is not None:
            tracks = all_tracks[all_tracks["scenario"] == draw].reset_index(drop=True)
        (scene,) = scenes_from_tables(art, tracks, catalogue, labels, [draw])
        if behave and tracks is None:  # a folder without tracks: the catalogue's behaviours
            (scene,) = move_scenes(
                jax.random.key(seed),
                [scene],
                grid,
                catalogue,
                horizon,
                options,
                source=str(sc["scenarios"]),
                behaviours="catalogue",
            )
        rate = float("nan")
    else:
        if "fit" in sc:
            fit = _fit(str(sc["fit"]))
            # one posterior draw per replicate, chosen by the replicate's seed alone
            rates = np.asarray(fit.traffic("chosen")[0]["arrival_rate"])
            draw = int(np.random.default_rng([seed, 1]).integers(rates.shape[0]))
            (scene,) = scenes_from_fit(
                seed,
                fit,
                grid,
                catalogue,
                1,
                horizon,
                options,
                posterior_draw=draw,
                source=str(sc["fit"]),
            )
            rate = float(rates[draw])
        else:  # hand-set rates: a fit of one draw
            # lazy: fitting (NumPyro) adds 1.0 s CPU to `import are_stats.experiments`
            from are_stats.fitting import Fit

            params = {
                "arrival_rate": np.atleast_1d(float(sc["arrival_rate"])),
                "leave_rate": np.atleast_1d(float(sc["leave_rate"])),
                "mix_weights": np.asarray(sc["mix_weights"], float)[None, :],
                "mix_rates": np.asarray(sc["mix_rates"], float)[None, :],
            }
            draw, rate = -1, float(params["arrival_rate"][0])
            (scene,) = scenes_from_fit(
                seed,
                Fit.from_draws(params, source="scenario"),
                grid,
                catalogue,
                1,
                horizon,
                options,
                source="scenario",
            )
    t_arr = scene.t_arrive
    info: _TaskSource = {
        "draw": draw,
        "arrival_rate": rate,
        "n_artefacts": len(scene),
        "n_arrivals": int(((t_arr > 0) & (t_arr <= horizon)).sum()),
    }
    return scene, info


def run_task(task: SweepTask, record: bool = False) -> TaskResult:
    """Run one task of :func:`expand_tasks`: build its scenario, run the mission.

    The scenario is drawn from the hand-set rates, or from one posterior draw of the fit
    (chosen by the replicate's seed), or is scenario ``replicate mod n`` of the scenarios
    folder; with ``behaviours`` its artefacts move along behaviour tracks (the folder's, else
    rolled out on the map coarsened to ``mission.behaviour_cell``).

    Returns
    -------
    dict
        ``runs`` (one row: task, sweep digest, replicate, seed, factor levels as
        ``level:<factor>`` columns, the planner label, ``arrival_rate`` (NaN for a scenarios
        folder), ``draw``, ``n_artefacts``, ``n_arrivals`` and the mission summary),
        ``replans`` and ``goals`` (the mission tables with the task's identifying columns);
        with ``record``, also ``trace`` (the :class:`~are_stats.experiments.MissionTrace`).
    """
    grid, mesh = _load_map(str(task["map"]))
    catalogue = _load_catalogue(task.get("catalogue"))
    ms = dict(task["mission"])
    seed = int(task["seed"])
    horizon = float(ms["time_limit"])
    scene, source = _task_scenario(task, grid, catalogue)
    robot = Robot(**task["robot"])
    goals = random_goals(
        grid,
        int(ms["n_goals"]) + 1,
        robot.radius + grid.resolution,
        seed,
        min_separation=float(ms.get("min_goal_separation", 5.0)),
    )
    planner = dict(task["planner"])
    label = str(planner.get("name", _label({k: v for k, v in planner.items() if k != "name"})))
    res = run_mission(
        grid,
        scene,
        goals,
        planner,
        robot=robot,
        time_limit=horizon,
        perception=ms.get("perception", "all"),
        env_mesh=mesh,
        perception_period=float(ms.get("perception_period", 1.0)),
        d_max=float(ms.get("d_max", 10.0)),
        tau=float(ms.get("tau", 10.0)),
        seed=seed,
        move_period=float(ms.get("behaviour_dt", 2.0)),
        avoid_robot=bool(task.get("avoid_robot", True)),
        record=record,
    )
    ident = {
        "task": task["task"],
        "sweep": str(task.get("sweep", "")),
        "replicate": int(task["replicate"]),
        "seed": seed,
    }
    ident.update({f"level:{k}": v for k, v in task["levels"].items()})
    ident["planner"] = label
    ident["arrival_rate"] = source["arrival_rate"]
    ident["draw"] = source["draw"]
    runs = pd.DataFrame(
        [
            {
                **ident,
                **res.summary,
                "n_artefacts": source["n_artefacts"],
                "n_arrivals": source["n_arrivals"],
            }
        ]
    )
    out: TaskResult = {"runs": runs}  # tables added below
    for name, df in (("replans", res.replans), ("goals", res.goals)):
        df = df.copy()
        for k, v in reversed(list(ident.items())):
            df.insert(0, k, v)
        out[name] = df
    if record:
        out["trace"] = res.trace
    return out


_TABLES = ("replans", "goals", "runs")  # runs last: it marks the task as done


def _write(out: Path, name: str, tables: TaskResult, force: bool) -> None:
    for t in _TABLES:
        with atomic_path(out / t / f"{name}.parquet", force=True if t != "runs" else force) as tmp:
            tables[t].to_parquet(tmp, index=False)


def _folder_state(out: Path) -> str:
    """``"missing"``, ``"empty"`` or ``"sweep"`` (holds ``sweep.yaml``); anything else is an
    error, so that a sweep never writes into, or replaces, a folder of other files."""
    if not out.exists():
        return "missing"
    if not out.is_dir():
        raise InputError(out, "", "a results folder", Described("a file"))
    if (out / "sweep.yaml").is_file():
        return "sweep"
    entries = sorted(p.name for p in out.iterdir())
    if not entries:
        return "empty"
    raise InputError(
        out,
        "",
        "a new or empty folder, or a sweep's results folder (with sweep.yaml); a sweep does "
        "not write into or replace other folders",
        Described(f"{len(entries)} other entries such as {entries[0]!r}"),
    )


def _cluster_kwargs(workers: int, processes: bool, host: str) -> dict[str, int | bool | str]:
    """Keyword arguments of the local Dask cluster: the scheduler and workers (processes)
    and the dashboard all listen on ``host`` (loopback by default), never on every
    interface; thread workers talk in-process and listen on no network interface."""
    address = f"[{host}]:0" if ":" in host else f"{host}:0"
    kwargs: dict[str, int | bool | str] = {
        "n_workers": int(workers),
        "threads_per_worker": 1,
        "processes": processes,
        "dashboard_address": address,
        # workers serve /metrics and /health too; left alone they bind every interface
        "worker_dashboard_address": address,
    }
    if processes:
        kwargs["host"] = host
    return kwargs


def run_sweep(
    config: str | os.PathLike | Mapping[str, object],
    out: str | os.PathLike,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    processes: bool = True,
    force: bool = False,
    progress: bool = True,
    host: str = "127.0.0.1",
    mcap: str | os.PathLike | None = None,
    start_time: float = 0.0,
) -> Path:
    """Run a sweep on Dask, writing one set of Parquet files per task as it finishes.

    Parameters
    ----------
    config : path or dict
        The sweep config (see module docstring).
    out : path
        Results folder: ``sweep.yaml`` (the resolved config), ``runs/``, ``replans/``,
        ``goals/``. It must be new, empty or a sweep's results folder.
    workers : int
        Local Dask workers (one thread each) when no ``scheduler`` is given.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port``); results are gathered
        and written by this process, so workers need no shared file system.
    processes : bool
        Local workers as processes (default) or threads of this process.
    force : bool
        Redo every task: the sweep runs into a hidden sibling folder that replaces ``out``
        as a whole once it is complete (an interrupted forced run leaves ``out`` as it
        was). Otherwise finished tasks are skipped (resume), and a folder holding a
        different sweep is an error.
    progress : bool
        Show a progress bar over tasks.
    host : str
        Interface the local cluster's scheduler, workers and dashboard listen on
        (default loopback only).
    mcap : path, optional
        Folder for one MCAP per mission run, ``<task>.mcap``
        (:func:`~are_stats.export.export_mcap`: REP-105 ``/tf``, class-labelled markers,
        maps); tasks skipped on resume write none.
    start_time : float
        Wall-clock time (s since the epoch) of each mission's t = 0 in the MCAPs.

    Returns
    -------
    Path
        The results folder.

    Raises
    ------
    OutputExistsError
        If ``out`` holds results of a different sweep config and ``force`` is false.
    are_stats.inputs.InputError
        On a bad config or argument, or an ``out`` that is not a results folder.
    """
    cfg = load_sweep_config(config)
    workers = get_int(workers, "--workers", "", lo=1, hi=1024)
    host = get_str(host, "--host", "")
    if not host or any(c in host for c in "/ \x00"):
        raise InputError("--host", "", "a host name or IP address such as 127.0.0.1", host)
    if scheduler is None and workers > 1:
        src = str(config) if not isinstance(config, Mapping) else "config"
        _check_cost(cfg, src, concurrent=workers)
    tasks = _expand(cfg)
    out = Path(out)
    text = yaml.safe_dump(cfg, sort_keys=False).encode()
    state = _folder_state(out)
    resume = state == "sweep" and not force
    if resume and (out / "sweep.yaml").read_bytes() != text:
        raise OutputExistsError(
            f"{out}: holds results of a different sweep config",
            "to replace them, or choose another folder",
        )
    todo = [t for t in tasks if not (resume and (out / "runs" / f"{t['task']}.parquet").exists())]
    if not todo:
        return out
    with _client(workers, scheduler, processes, host) as client:
        try:
            if state == "sweep" and force:
                target = Path(
                    tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
                )
            else:
                out.mkdir(parents=True, exist_ok=True)
                target = out
        except OSError as err:
            raise InputError(
                out, "", "a results folder that can be created", Described(err.strerror or str(err))
            ) from None
        try:
            with atomic_path(target / "sweep.yaml", force=True) as tmp:
                tmp.write_bytes(text)
            _run(client, todo, target, len(tasks), progress, mcap, float(start_time))
        except BaseException:
            if target != out:  # a forced run that did not finish: out stays as it was
                shutil.rmtree(target, ignore_errors=True)
            raise
    if target != out:
        replace_folder(target, out)
    return out


#: Seconds a local worker process is given to exit once asked to (then it is killed). A
#: nanny's own close gives it 4 s, which the interpreter teardown of a process that ran a
#: task (JAX, XLA, Warp and the rest of its modules) overran on a loaded machine: the
#: worker was killed and "Worker process still alive after 4.0 seconds, killing" logged
#: after every sweep.
_WORKER_EXIT_GRACE = 60.0


async def _close_workers(cluster: LocalCluster, grace: float) -> None:
    """Close ``cluster``'s workers, giving each ``grace`` seconds to exit (80 % of it to
    its process before the nanny kills it); the cluster's own close then finds them closed."""
    await asyncio.gather(*(w.close(timeout=grace) for w in cluster.workers.values()))


@contextlib.contextmanager
def _client(workers: int, scheduler: str | None, processes: bool, host: str) -> Iterator[Client]:
    """A Dask client of the given scheduler, or of a local cluster listening on ``host``."""
    # lazy: Dask's distributed adds 0.49 s CPU to `import are_stats.experiments`
    from distributed import Client, LocalCluster

    # set_as_default=False: a client (or a failed attempt at one) must not switch the whole
    # process's dask config to "dask.distributed" -- xarray then takes distributed locks for
    # every later netCDF write, which fail once the client is gone.
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError(
                "--scheduler",
                "",
                "the address of a running Dask scheduler (tcp://host:port)",
                Described(f"{scheduler!r} ({err})"),
            ) from None
        cluster = None
    else:
        cluster = LocalCluster(**_cluster_kwargs(workers, processes, host))
        client = Client(cluster, set_as_default=False)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.sync(_close_workers, cluster, _WORKER_EXIT_GRACE)
            cluster.close()


def _run(
    client: Client,
    todo: list[SweepTask],
    target: Path,
    n_tasks: int,
    progress: bool,
    mcap: str | os.PathLike | None = None,
    start_time: float = 0.0,
) -> None:
    """Run ``todo`` on ``client``, writing each task's tables into ``target`` as it ends
    (and its MCAP into ``mcap`` when given)."""
    # lazy: distributed +0.49 s CPU on `import are_stats.experiments`; export (+0.04 s) is
    # downstream: it imports this room's traces (both at the top would be a cycle)
    from distributed import as_completed

    from are_stats.export import export_mcap

    record = mcap is not None
    futures = {client.submit(run_task, t, record, pure=False): t for t in todo}
    bar = _progress(progress, n_tasks, n_tasks - len(todo))
    try:
        for fut in as_completed(futures, loop=client.loop):
            task = futures[fut]
            res = fut.result()
            if record:
                # lazy: perception (Warp) adds 0.75 s CPU to `import are_stats.experiments`
                from are_stats.perception import optical_from_base

                grid = _load_map(str(task["map"]))[0]
                robot = Robot(**task["robot"])
                export_mcap(
                    Path(mcap) / f"{task['task']}.mcap",
                    grid,
                    res.pop("trace"),
                    force=True,
                    start_time=start_time,
                    mount=optical_from_base(robot.camera_xyz, robot.camera_rpy),
                )
            _write(target, task["task"], res, force=True)
            bar.advance()
    finally:
        bar.close()


class _progress:
    """A rich progress bar over tasks (a no-op when disabled)."""

    def __init__(self, enabled: bool, total: int, done: int) -> None:
        self._p = None
        if enabled:
            # lazy: rich.progress adds 0.10 s CPU to `import are_stats.experiments`
            from rich.progress import Progress

            self._p = Progress(transient=False)
            self._p.start()
            self._id = self._p.add_task("tasks", total=total, completed=done)

    def advance(self) -> None:
        if self._p is not None:
            self._p.advance(self._id)

    def close(self) -> None:
        if self._p is not None:
            self._p.stop()


# columns the plots and tables need, by table: numeric ones are checked as numbers
_COLUMNS = {
    "runs": {
        "task": False,
        "sweep": False,
        "planner": False,
        "arrival_rate": True,
        "update_rate": True,
        "rho_mean": True,
        "nu_mean": True,
        "mission_time": True,
        "goals_total": True,
    },
    "replans": {"task": False},
    "goals": {"task": False, "t_reached": True},
}


def _read_table(path: Path, table: str, task: str) -> pd.DataFrame:
    if not path.is_file():
        raise InputError(
            path,
            "",
            f"the {table} table of finished task {task} (written before its runs file)",
            Described("no such file"),
        )
    try:
        df = pd.read_parquet(path)
    except (OSError, ValueError, pyarrow.ArrowException) as err:
        problem = str(err).splitlines()[0][:200] if str(err) else type(err).__name__
        raise InputError(
            path, "", "a Parquet table written by run_sweep", Described(problem)
        ) from None
    for col, numeric in _COLUMNS[table].items():
        if col not in df.columns:
            raise InputError(path, f"column {col!r}", "this column", Described("no such column"))
        if numeric and not pd.api.types.is_numeric_dtype(df[col]):
            raise InputError(
                path, f"column {col!r}", "numbers", Described(f"dtype {df[col].dtype}")
            )
    bad = df["task"] != task
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(path, f"row {row}, column 'task'", repr(task), df["task"].iloc[row])
    return df


def load_results(out: str | os.PathLike) -> dict[str, pd.DataFrame]:
    """Read a sweep's results folder: ``runs``, ``replans`` and ``goals`` tables (finished
    tasks only), concatenated and sorted by task.

    The folder must hold one sweep: every ``runs`` file must be a task of the config in
    ``sweep.yaml``, with its digest, and every table well formed.

    Raises
    ------
    FileNotFoundError
        If ``out`` has no finished task.
    are_stats.inputs.InputError
        Naming the file, on a missing or malformed ``sweep.yaml`` or table, or a task of
        another sweep.
    """
    out = Path(out)
    runs_dir = out / "runs"
    done = sorted(runs_dir.glob("*.parquet")) if runs_dir.is_dir() else []
    if not done:
        raise FileNotFoundError(f"{out}: no finished sweep tasks (runs/*.parquet)")
    meta = out / "sweep.yaml"
    if not meta.is_file():
        raise InputError(
            meta, "", "the sweep config of the results folder", Described("no such file")
        )
    cfg = _validate(load_yaml(meta, "sweep config"), str(meta), out)
    n_tasks = _n_combos(cfg) * cfg["replicates"]
    check_memory(n_tasks * _BYTES_PER_TASK, f"the task list of {n_tasks} tasks", meta)
    check_work(n_tasks * _STEPS_PER_TASK, f"a sweep of {n_tasks} tasks", meta)
    tasks = {t["task"]: t for t in _expand(cfg)}
    sweep = _digest(cfg)
    for p in done:
        if p.stem not in tasks:
            raise InputError(
                p,
                "",
                f"a task of the sweep in {meta} (a results folder holds one sweep)",
                Described("a file of another sweep"),
            )
    res = {}
    for t in _TABLES:
        parts = []
        for p in done:
            df = _read_table(out / t / p.name, t, p.stem)
            if t == "runs" and len(df) != 1:
                raise InputError(
                    p, "", "one row (the task's summary)", Described(f"{len(df)} rows")
                )
            if t == "runs" and df["sweep"].iloc[0] != sweep:
                raise InputError(
                    p,
                    "row 0, column 'sweep'",
                    f"the digest {sweep!r} of {meta}",
                    df["sweep"].iloc[0],
                )
            parts.append(df)
        res[t] = pd.concat(parts, ignore_index=True)
    return res
