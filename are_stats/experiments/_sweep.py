"""Sweeps of navigation experiments (paper Sect. 4, Fig. 7) defined in YAML, run on Dask.

A sweep config is a base experiment plus ``factors``: each factor is a dotted key of the
config (``scenario.arrival_rate``, ``planner``, ``mission.time_limit`` ...) with a list of
levels; a dict level is merged into the dict it replaces (its optional ``name`` labels it).
Tasks are the full factor grid times ``replicates``. Replicate ``r`` draws its scenario and
goals from ``SeedSequence([seed, r])`` whatever the factor levels (common random numbers),
so planner settings are compared on the same scenarios.

Example (``models/experiments/fig7.yaml``)::

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

Every task writes ``runs/<task>.parquet`` (one summary row), ``replans/<task>.parquet`` and
``goals/<task>.parquet`` atomically, ``runs`` last, as soon as it finishes: an interrupted
sweep resumes and skips every task whose ``runs`` file exists.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import itertools
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from are_stats._atomic import OutputExistsError, atomic_path
from are_stats._checks import describe

__all__ = [
    "expand_tasks",
    "load_results",
    "load_sweep_config",
    "run_sweep",
    "run_task",
]

_DEFAULTS: dict[str, Any] = {
    "name": "sweep",
    "map": "courtyard",
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
    },
    "planner": {"algorithm": "RRTConnect", "range": 2.0},
    "factors": {},
}
_SECTIONS = ("scenario", "robot", "mission", "planner")


def _merge(base: dict, new: Mapping, where: str) -> dict:
    out = copy.deepcopy(base)
    for k, v in new.items():
        if k not in base:
            raise ValueError(f"{where}: unknown key {k!r} (known: {sorted(base)})")
        if isinstance(base[k], dict) and k != "planner":
            if not isinstance(v, Mapping):
                raise ValueError(f"{where}.{k}: expected a mapping, got {describe(v)}")
            out[k] = {**base[k], **v}
        else:
            out[k] = copy.deepcopy(v)
    return out


def load_sweep_config(config: str | os.PathLike | Mapping[str, Any]) -> dict[str, Any]:
    """Read and validate a sweep config (a YAML path or a dict), with defaults filled in.

    Raises
    ------
    FileNotFoundError
        If the YAML file does not exist.
    ValueError
        On unknown keys, bad factors (not a dotted key with a non-empty list of levels) or
        bad ``replicates`` / ``seed``.
    """
    if isinstance(config, Mapping):
        raw, where = dict(config), "config"
    else:
        p = Path(config)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: sweep config not found")
        try:
            raw = yaml.safe_load(p.read_text())
        except yaml.YAMLError as err:
            raise ValueError(f"{p}: not valid YAML ({err})") from None
        where = str(p)
        if not isinstance(raw, Mapping):
            raise ValueError(f"{p}: expected a mapping at the top level, got {describe(raw)}")
    cfg = _merge(_DEFAULTS, raw, where)
    for name in ("replicates", "seed"):
        v = cfg[name]
        low = 1 if name == "replicates" else 0
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise ValueError(f"{where}: {name}: expected an integer >= {low}, got {v!r}")
    factors = cfg["factors"]
    if not isinstance(factors, Mapping):
        raise ValueError(
            f"{where}: factors: expected a mapping key -> levels, got {describe(factors)}"
        )
    for key, levels in factors.items():
        parts = str(key).split(".")
        if (
            parts[0] not in _SECTIONS
            or (len(parts) == 1 and parts[0] != "planner")
            or len(parts) > 2
        ):
            raise ValueError(
                f"{where}: factors: {key!r}: expected 'planner' or '<section>.<key>' with "
                f"section in {list(_SECTIONS)}"
            )
        if len(parts) == 2 and parts[1] not in _DEFAULTS[parts[0]] and parts[0] != "planner":
            raise ValueError(
                f"{where}: factors: {key!r}: unknown key {parts[1]!r} "
                f"(known: {sorted(_DEFAULTS[parts[0]])})"
            )
        if not isinstance(levels, list) or not levels:
            raise ValueError(f"{where}: factors: {key!r}: expected a non-empty list of levels")
    return cfg


def _label(level: Any) -> str:
    if isinstance(level, Mapping):
        if "name" in level:
            return str(level["name"])
        return ",".join(f"{k}={v}" for k, v in level.items())
    return str(level)


def _digest(obj: Any) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:10]


def expand_tasks(config: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The tasks of a sweep: factor grid x replicates, each a self-contained dict.

    Each task has ``task`` (a file-name stem: index and a digest of its settings),
    ``replicate``, ``seed`` (the replicate's integer seed), ``levels`` (factor ->
    label) and the resolved ``scenario``, ``robot``, ``mission``, ``planner``, ``map``.
    """
    cfg = load_sweep_config(config)
    factors = cfg["factors"]
    keys = list(factors)
    tasks = []
    combos = list(itertools.product(*[factors[k] for k in keys])) if keys else [()]
    idx = 0
    for combo in combos:
        base = {k: copy.deepcopy(cfg[k]) for k in _SECTIONS}
        levels = {}
        for key, level in zip(keys, combo, strict=True):
            sec, _, sub = key.partition(".")
            if not sub:
                if isinstance(level, Mapping):
                    base[sec] = dict(level)
                else:
                    raise ValueError(
                        f"factors: {key!r}: expected dict levels, got {describe(level)}"
                    )
            elif isinstance(base[sec].get(sub), Mapping) and isinstance(level, Mapping):
                base[sec][sub] = {**base[sec][sub], **level}
            else:
                base[sec][sub] = level
            levels[key] = _label(level)
        for r in range(cfg["replicates"]):
            seed = int(np.random.SeedSequence([cfg["seed"], r]).generate_state(1)[0])
            task = {"map": cfg["map"], "replicate": r, "seed": seed, "levels": levels, **base}
            task["task"] = f"{idx:05d}-{_digest(task)}"
            tasks.append(task)
            idx += 1
    return tasks


@functools.lru_cache(maxsize=4)
def _load_map(name: str) -> tuple[Any, Any]:
    from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, load_mesh

    p = Path(name)
    if not p.exists() and (DEFAULT_MODELS / f"{p.name}.yaml").is_file():
        p = DEFAULT_MODELS / f"{p.name}.yaml"
    grid = OccupancyGrid.from_ros_yaml(p)
    mesh_path = p.with_suffix(".ply")
    mesh = load_mesh(mesh_path) if mesh_path.is_file() else None
    return grid, mesh


def run_task(task: Mapping[str, Any]) -> dict[str, pd.DataFrame]:
    """Run one task of :func:`expand_tasks`: generate its scenario, run the mission.

    Returns
    -------
    dict
        ``runs`` (one row: task, replicate, seed, factor levels as ``level:<factor>``
        columns, the planner label and the mission summary), ``replans`` and ``goals``
        (the mission tables with the task's identifying columns).
    """
    from are_stats.experiments._loop import random_goals, run_mission
    from are_stats.experiments._robot import Robot
    from are_stats.scenarios import generate_scenarios

    grid, mesh = _load_map(str(task["map"]))
    sc, ms = dict(task["scenario"]), dict(task["mission"])
    params = {
        "arrival_rate": np.atleast_1d(float(sc["arrival_rate"])),
        "leave_rate": np.atleast_1d(float(sc["leave_rate"])),
        "mix_weights": np.asarray(sc["mix_weights"], float)[None, :],
        "mix_rates": np.asarray(sc["mix_rates"], float)[None, :],
    }
    seed = int(task["seed"])
    horizon = float(ms["time_limit"])
    art = generate_scenarios(
        seed, params, 1, horizon, free_mask=grid, start=sc.get("start", "stationary")
    )
    robot = Robot(**task["robot"])
    goals = random_goals(
        grid, int(ms["n_goals"]) + 1, robot.radius + grid.resolution, seed,
        min_separation=float(ms.get("min_goal_separation", 5.0)),
    )  # fmt: skip
    planner = dict(task["planner"])
    label = str(planner.get("name", _label({k: v for k, v in planner.items() if k != "name"})))
    res = run_mission(
        grid, art, goals, planner, robot=robot, time_limit=horizon,
        perception=ms.get("perception", "all"), env_mesh=mesh,
        perception_period=float(ms.get("perception_period", 1.0)),
        d_max=float(ms.get("d_max", 10.0)), tau=float(ms.get("tau", 10.0)), seed=seed,
    )  # fmt: skip
    ident = {"task": task["task"], "replicate": int(task["replicate"]), "seed": seed}
    ident.update({f"level:{k}": v for k, v in task["levels"].items()})
    ident["planner"] = label
    ident["arrival_rate"] = float(sc["arrival_rate"])
    runs = pd.DataFrame([{**ident, **res.summary}])
    out = {"runs": runs}
    for name, df in (("replans", res.replans), ("goals", res.goals)):
        df = df.copy()
        for k, v in reversed(list(ident.items())):
            df.insert(0, k, v)
        out[name] = df
    return out


_TABLES = ("replans", "goals", "runs")  # runs last: it marks the task as done


def _write(out: Path, name: str, tables: Mapping[str, pd.DataFrame], force: bool) -> None:
    for t in _TABLES:
        with atomic_path(out / t / f"{name}.parquet", force=True if t != "runs" else force) as tmp:
            tables[t].to_parquet(tmp, index=False)


def run_sweep(
    config: str | os.PathLike | Mapping[str, Any],
    out: str | os.PathLike,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    processes: bool = True,
    force: bool = False,
    progress: bool = True,
) -> Path:
    """Run a sweep on Dask, writing one set of Parquet files per task as it finishes.

    Parameters
    ----------
    config : path or dict
        The sweep config (see module docstring).
    out : path
        Results folder: ``sweep.yaml`` (the resolved config), ``runs/``, ``replans/``,
        ``goals/``.
    workers : int
        Local Dask workers (one thread each) when no ``scheduler`` is given.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port``); results are gathered
        and written by this process, so workers need no shared file system.
    processes : bool
        Local workers as processes (default) or threads of this process.
    force : bool
        Redo every task and overwrite the results; otherwise finished tasks are skipped
        (resume), and a folder holding a different sweep is an error.
    progress : bool
        Show a progress bar over tasks.

    Returns
    -------
    Path
        The results folder.

    Raises
    ------
    OutputExistsError
        If ``out`` holds results of a different sweep config and ``force`` is false.
    """
    cfg = load_sweep_config(config)
    tasks = expand_tasks(cfg)
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ValueError(f"workers: expected an integer >= 1, got {workers!r}")
    out = Path(out)
    meta = out / "sweep.yaml"
    text = yaml.safe_dump(cfg, sort_keys=False)
    if meta.exists() and not force and meta.read_text() != text:
        raise OutputExistsError(
            f"{out}: holds results of a different sweep config; pass --force (force=True) "
            "to overwrite them, or choose another folder"
        )
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(meta, force=True) as tmp:
        tmp.write_text(text)
    todo = [t for t in tasks if force or not (out / "runs" / f"{t['task']}.parquet").exists()]
    if not todo:
        return out
    from distributed import Client, LocalCluster, as_completed

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise ValueError(f"scheduler: cannot connect to {scheduler!r} ({err})") from None
        cluster = None
    else:
        cluster = LocalCluster(
            n_workers=int(workers), threads_per_worker=1, processes=processes,
            dashboard_address=":0",
        )  # fmt: skip
        client = Client(cluster)
    try:
        futures = {client.submit(run_task, t, pure=False): t["task"] for t in todo}
        bar = _progress(progress, len(tasks), len(tasks) - len(todo))
        try:
            for fut in as_completed(futures):
                _write(out, futures[fut], fut.result(), force=True)
                bar.advance()
        finally:
            bar.close()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return out


class _progress:
    """A rich progress bar over tasks (a no-op when disabled)."""

    def __init__(self, enabled: bool, total: int, done: int) -> None:
        self._p = None
        if enabled:
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


def load_results(out: str | os.PathLike) -> dict[str, pd.DataFrame]:
    """Read a sweep's results folder: ``runs``, ``replans`` and ``goals`` tables (finished
    tasks only), concatenated and sorted by task.

    Raises
    ------
    FileNotFoundError
        If ``out`` has no finished task.
    """
    out = Path(out)
    done = sorted((out / "runs").glob("*.parquet")) if (out / "runs").is_dir() else []
    if not done:
        raise FileNotFoundError(f"{out}: no finished sweep tasks (runs/*.parquet)")
    names = [p.stem for p in done]
    res = {}
    for t in _TABLES:
        parts = [pd.read_parquet(out / t / f"{n}.parquet") for n in names]
        res[t] = pd.concat(parts, ignore_index=True)
    return res
