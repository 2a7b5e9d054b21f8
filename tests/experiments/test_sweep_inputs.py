"""Sweep inputs: the config schema, YAML hazards, work/memory limits, the Dask listen
address, whole-folder replacement with --force and results folders holding one sweep."""

from __future__ import annotations

import atexit
import logging
import pathlib
import re
import shutil
import time

import numpy as np
import pandas as pd
import pytest
import yaml
from distributed import LocalCluster
from distributed.comm.utils import get_tcp_server_addresses
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, load_catalogue
from are_stats.experiments import (
    Robot,
    _sweep,
    expand_tasks,
    load_results,
    load_sweep_config,
    make_planner,
    plot_results,
    run_mission,
    run_sweep,
)
from are_stats.inputs import InputError, LimitError, limits
from are_stats.scenarios import Scene

# one short task: A* on the courtyard, one goal, a few artefacts
TINY = {
    "name": "tiny",
    "seed": 1,
    "scenario": {"arrival_rate": 0.0002, "leave_rate": 0.05},
    "mission": {"n_goals": 1, "time_limit": 10.0},
    "planner": {"algorithm": "astar"},
}


@pytest.mark.parametrize(
    ("cfg", "where", "expected"),
    [
        # a list where a number belongs (was a TypeError deep in the run)
        ({"scenario": {"arrival_rate": [1, 2]}}, "scenario.arrival_rate", "a finite number > 0"),
        # an unknown robot key (was TypeError: Robot.__init__() got an unexpected keyword)
        ({"robot": {"wheels": 4}}, "robot.wheels", "known keys radius, speed"),
        # unknown keys were silently ignored
        ({"scenario": {"unknown": 1}}, "scenario.unknown", "known keys arrival_rate"),
        ({"colour": "red"}, "colour", "known keys name, map"),
        ({"planner": {"algorithm": "RRT", "bogus": 1}}, "planner.bogus", "known keys name"),
        # bools are not numbers, strings are not integers
        ({"scenario": {"leave_rate": True}}, "scenario.leave_rate", "a finite number > 0"),
        ({"replicates": True}, "replicates", "an integer >= 1"),
        ({"mission": {"n_goals": "3"}}, "mission.n_goals", "an integer >= 1"),
        ({"mission": {"time_limit": float("nan")}}, "mission.time_limit", "finite"),
        ({"robot": {"image_size": [64.5, 48]}}, "robot.image_size[0]", "an integer"),
        ({"planner": {"algorithm": "RRT", "simplify": 1}}, "planner.simplify", "true or false"),
        ({"seed": 2**40}, "seed", "<= 4294967295"),
        ({"mission": {"perception": "lidar"}}, "mission.perception", "'all', 'camera'"),
        ({"mission": 3}, "mission", "a mapping"),
        ({"name": "../elsewhere"}, "name", "letters, digits"),
        ({"map": "no-such-map"}, "map", "a shipped map name (courtyard"),
        # keys that depend on each other
        ({"scenario": {"mix_weights": [0.5, 0.5]}}, "scenario.mix_rates", "as many rates"),
        ({"scenario": {"mix_weights": [0.5, 0.6], "mix_rates": [1, 2]}}, "mix_weights", "sum"),
        ({"planner": {"algorithm": "astar", "range": 2.0}}, "planner.range", "'astar' takes"),
        ({"planner": {"algorithm": "PRM", "max_iterations": 9}}, "planner.max_iterations", "PRM"),
        # factors: keys and every level
        ({"factors": {"robot": [1]}}, "factors.robot", "'planner'"),
        ({"factors": {"scenario.speed": [1]}}, "factors.scenario.speed", "arrival_rate"),
        ({"factors": {"planner.bogus": [1]}}, "factors.planner.bogus", "range"),
        ({"factors": {"scenario.arrival_rate": []}}, "factors.scenario.arrival_rate", "non-empty"),
        ({"factors": {"scenario.arrival_rate": [1e-4, [2]]}}, "arrival_rate[1]", "number"),
        ({"factors": {"robot.radius": [0.3, False]}}, "factors.robot.radius[1]", "number"),
        ({"factors": {"scenario.arrival_rate": [1e-4, 1e-4]}}, "arrival_rate[1]", "distinct"),
        ({"factors": {"planner": [{"algorithm": "RRT", "wings": 2}]}}, "planner[0].wings", "known"),
        (
            {
                "factors": {
                    "planner": [
                        {"name": "a", "algorithm": "astar"},
                        {"name": "a", "algorithm": "RRT"},
                    ]
                }
            },
            "planner[1]",
            "distinct",
        ),
        (
            {"planner": {"algorithm": "astar"}, "factors": {"planner.range": [1.0]}},
            "planner.range=1.0: planner.range",
            "'astar' takes",
        ),
    ],
)
def test_bad_config_is_named_with_its_key_path(cfg, where, expected):
    with pytest.raises(InputError) as info:
        load_sweep_config({**TINY, **cfg})
    msg = str(info.value)
    assert msg.startswith(f"config: {where}") or f" {where}" in msg or f"{where}:" in msg, msg
    assert expected in msg, msg


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("seed: 1\nseed: 2\n", "line 2: expected each key once"),
        ("robot: {radius: " + "{a: " * 100 + "1" + "}" * 100 + "}\n", "nested at most"),
        ("scenario: " + "[" * 500 + "]" * 500 + "\n", "nested at most"),
        (
            "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
            + "".join(
                f"{chr(98 + i)}: &{chr(98 + i)} [" + ", ".join([f"*{chr(97 + i)}"] * 10) + "]\n"
                for i in range(7)
            ),
            "alias",
        ),
        ("- 1\n- 2\n", "expected a mapping"),
        ("", "expected a mapping"),
        ("scenario: {arrival_rate: yes}\n", "scenario.arrival_rate: expected a finite number"),
        ("scenario: {arrival_rate: 1e-4\n", "valid YAML"),
    ],
)
def test_bad_yaml_is_named(tmp_path, text, expected):
    path = tmp_path / "fig7.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_sweep_config(path)
    assert str(info.value).startswith(str(path)) and expected in str(info.value)


def test_yaml_12_numbers_and_undecodable_file(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("scenario: {arrival_rate: 1e-4}\n")
    assert load_sweep_config(path)["scenario"]["arrival_rate"] == 1e-4
    path.write_bytes(b"name: \xff\n")
    with pytest.raises(InputError, match="UTF-8"):
        load_sweep_config(path)
    with pytest.raises(InputError, match="a directory"):
        load_sweep_config(tmp_path)


@pytest.mark.parametrize(
    ("cfg", "expected"),
    [
        ({"scenario": {"leave_rate": 1e-9}}, "artefacts"),  # was 3 GiB .. 209 TiB
        ({"scenario": {"arrival_rate": 1e9}}, "artefacts"),
        ({"mission": {"time_limit": 1e12}}, "artefacts"),
        ({"replicates": 10**9}, "tasks"),
        ({"replicates": 10**18}, "tasks"),
        ({"robot": {"radius": 1e-300}}, "motion steps"),
        ({"robot": {"image_size": [10000, 10000]}, "mission": {"perception": "camera"}}, "rays"),
        (
            {
                "factors": {
                    "scenario.arrival_rate": [1e-4 * (k + 1) for k in range(300)],
                    "mission.time_limit": [10.0 * (k + 1) for k in range(300)],
                }
            },
            "tasks",
        ),
    ],
)
def test_runaway_sweeps_are_refused_before_running(cfg, expected):
    with pytest.raises(LimitError) as info:
        load_sweep_config({**TINY, **cfg})
    assert info.value.source == "config" and expected in str(info.value)
    assert "--max-" in str(info.value)


def test_limits_can_be_raised():
    cfg = {**TINY, "scenario": {"leave_rate": 1e-8}}
    with pytest.raises(LimitError):
        load_sweep_config(cfg)
    with limits(memory="64G", work="1e16"):
        assert load_sweep_config(cfg)["scenario"]["leave_rate"] == 1e-8


def test_shipped_config_is_within_the_default_limits():
    cfg = load_sweep_config(DEFAULT_MODELS / "experiments" / "fig7.yaml")
    assert len(expand_tasks(cfg)) == 12


def test_local_cluster_listens_on_loopback_only():
    kw = _sweep._cluster_kwargs(2, True, "127.0.0.1")
    assert kw["host"] == "127.0.0.1" and kw["dashboard_address"] == "127.0.0.1:0"
    assert _sweep._cluster_kwargs(1, False, "::1")["dashboard_address"] == "[::1]:0"
    # process workers: the scheduler, its dashboard / HTTP server on loopback
    with LocalCluster(**{**kw, "n_workers": 0}) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        hosts = {a[0] for a in get_tcp_server_addresses(cluster.scheduler.http_server)}
        assert hosts == {"127.0.0.1"}
    # thread workers (as in the tests): the HTTP servers of scheduler and workers too
    with LocalCluster(**_sweep._cluster_kwargs(1, False, "127.0.0.1")) as cluster:
        servers = [cluster.scheduler.http_server]
        servers += [w.http_server for w in cluster.workers.values()]
        hosts = {a[0] for s in servers for a in get_tcp_server_addresses(s)}
        assert hosts == {"127.0.0.1"}


def test_local_worker_processes_exit_on_their_own(tmp_path):
    """A worker process whose interpreter teardown is slow (5 s here, as a worker that ran
    JAX and Warp takes on a loaded machine) is let finish, not killed: the nanny's own 4 s
    killed it and logged "Worker process still alive after 4.0 seconds, killing" after
    every `are-stats experiment`. The marker is written by the worker's last exit handler."""
    marker = tmp_path / "exited"
    seen = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = lambda record: seen.append(record.getMessage())
    nanny_log = logging.getLogger("distributed.nanny")
    nanny_log.addHandler(handler)
    try:
        with _sweep._client(1, None, True, "127.0.0.1") as client:
            # exit handlers run last-registered first: the sleep, then the marker
            client.run(atexit.register, pathlib.Path.touch, marker)
            client.run(atexit.register, time.sleep, 5.0)
    finally:
        nanny_log.removeHandler(handler)
    assert not [m for m in seen if "still alive" in m], seen
    assert marker.is_file()


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "res"
    run_sweep({**TINY, "replicates": 2}, out, processes=False, progress=False)
    return out


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_force_replaces_the_folder_as_a_whole(results, tmp_path):
    out = tmp_path / "res"
    shutil.copytree(results, out)
    (out / "fig7a_rho.png").write_bytes(b"old plot")
    other = {**TINY, "seed": 2}
    run_sweep(other, out, processes=False, progress=False, force=True)
    names = {t["task"] for t in expand_tasks(other)}
    assert {p.stem for p in (out / "runs").glob("*.parquet")} == names
    assert not (out / "fig7a_rho.png").exists()
    assert load_results(out)["runs"]["task"].tolist() == sorted(names)
    assert not [p for p in tmp_path.iterdir() if p.name != "res"]  # no temporary left


def test_interrupted_forced_run_leaves_the_old_results(results, tmp_path, monkeypatch):
    out = tmp_path / "res"
    shutil.copytree(results, out)
    before = _snapshot(out)

    def killed(client, todo, target, *args):
        run = _sweep.run_task(todo[0])
        _sweep._write(target, todo[0]["task"], run, force=True)
        raise KeyboardInterrupt

    monkeypatch.setattr(_sweep, "_run", killed)
    with pytest.raises(KeyboardInterrupt):
        run_sweep({**TINY, "seed": 2}, out, processes=False, progress=False, force=True)
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["res"]  # the unfinished copy is removed


def test_results_folder_must_hold_one_sweep(results, tmp_path):
    out = tmp_path / "res"
    shutil.copytree(results, out)
    stray = tmp_path / "other"
    run_sweep({**TINY, "seed": 5}, stray, processes=False, progress=False)
    foreign = next((stray / "runs").glob("*.parquet"))
    shutil.copy(foreign, out / "runs" / foreign.name)
    with pytest.raises(InputError, match=f"{foreign.name}: expected a task of the sweep"):
        load_results(out)
    # a file of this sweep's name holding another sweep's row
    (out / "runs" / foreign.name).unlink()
    mine = sorted((out / "runs").glob("*.parquet"))[0]
    df = pd.read_parquet(mine)
    df.assign(sweep="0123456789").to_parquet(mine, index=False)
    with pytest.raises(InputError, match="column 'sweep': expected the digest"):
        load_results(out)


@pytest.mark.parametrize(
    "damage", ["garbage", "no_goals", "no_column", "no_meta", "bad_meta", "huge_meta"]
)
def test_malformed_results_are_named(results, tmp_path, damage):
    out = tmp_path / "res"
    shutil.copytree(results, out)
    name = sorted((out / "runs").glob("*.parquet"))[0].name
    if damage == "garbage":
        bad = out / "replans" / name
        bad.write_bytes(b"not parquet")
    elif damage == "no_goals":
        bad = out / "goals" / name
        bad.unlink()
    elif damage == "no_column":
        bad = out / "runs" / name
        pd.read_parquet(bad).drop(columns=["rho_mean"]).to_parquet(bad, index=False)
    elif damage == "no_meta":
        bad = out / "sweep.yaml"
        bad.unlink()
    elif damage == "bad_meta":
        bad = out / "sweep.yaml"
        bad.write_text("seed: [1]\n")
    else:
        bad = out / "sweep.yaml"
        bad.write_text("replicates: 1000000000000000\n")
    with pytest.raises(InputError) as info:
        load_results(out)
    assert str(info.value).startswith(str(bad)), str(info.value)
    r = CliRunner().invoke(app, ["plot", str(out)])
    assert r.exit_code == 2 and str(bad) in r.output, r.output


def test_out_must_be_a_results_folder(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    for force in (False, True):
        with pytest.raises(InputError, match="other entries such as 'notes.txt'"):
            run_sweep(TINY, tmp_path, processes=False, progress=False, force=force)
    assert (tmp_path / "notes.txt").read_text() == "mine"
    with pytest.raises(InputError, match="a file"):
        run_sweep(TINY, tmp_path / "notes.txt", processes=False, progress=False)
    with pytest.raises(InputError, match="--workers"):
        run_sweep(TINY, tmp_path / "r", workers=0, processes=False, progress=False)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("scenario: {arrival_rate: [1, 2]}\n", "scenario.arrival_rate: expected a finite number"),
        ("robot: {wheels: 4}\n", "robot.wheels: expected one of the known keys"),
        ("scenario: {leave_rate: 1.0e-9}\n", "memory limit"),
        ("seed: 1\nseed: 1\n", "each key once"),
        ("factors: {planner: [{algorithm: astar, range: 1}]}\n", "planner.range"),
    ],
)
def test_cli_experiment_exits_2_naming_the_config(tmp_path, text, expected):
    path = tmp_path / "fig7.yaml"
    path.write_text(text)
    r = CliRunner().invoke(app, ["experiment", str(path), "--out", str(tmp_path / "r")])
    assert r.exit_code == 2, r.output
    assert f"{path}: " in r.output and expected in r.output, r.output
    assert not (tmp_path / "r").exists()


def test_resolved_config_round_trips():
    cfg = load_sweep_config({**TINY, "factors": {"planner.algorithm": ["astar"]}})
    again = load_sweep_config(yaml.safe_load(yaml.safe_dump(cfg)))
    assert again == cfg


def test_run_mission_refuses_runaway_motion_before_driving():
    grid = OccupancyGrid(np.zeros((20, 20)), 1.0)
    empty = pd.DataFrame(columns=["t_arrive", "t_leave", "x", "y", "yaw"], dtype=float)
    art = Scene.from_scenarios(empty, load_catalogue())
    goals = [[2.0, 10.0], [18.0, 10.0]]
    with pytest.raises(LimitError, match="run_mission: expected the robot's"):
        run_mission(grid, art, goals, "astar", robot=Robot(radius=1e-12), time_limit=1e9)
    res = run_mission(grid, art, goals, "astar", robot=Robot(radius=0.3), time_limit=60.0)
    assert res.summary["goals_reached"] == 1


def test_plot_out_must_be_a_folder(results, tmp_path):
    (tmp_path / "png").write_text("a file")
    with pytest.raises(InputError, match="expected a folder for the PNGs"):
        plot_results(results, tmp_path / "png")


@pytest.mark.parametrize(
    ("kw", "where"),
    [
        ({"radius": True}, "radius"),
        ({"speed": "fast"}, "speed"),
        ({"camera_xyz": [0.0, 0.0]}, "camera_xyz"),
        ({"camera_rpy": [0.0, float("inf"), 0.0]}, "camera_rpy[1]"),
        ({"image_size": (64, 48.5)}, "image_size[1]"),
        ({"camera_fov": 4.0}, "camera_fov"),
    ],
)
def test_robot_fields_are_strict(kw, where):
    with pytest.raises(InputError, match=rf"^Robot: {re.escape(where)}: expected"):
        Robot(**kw)


@pytest.mark.parametrize(
    ("spec", "where"),
    [
        ({"algorithm": "RRT", "range": True}, "range"),
        ({"algorithm": "RRT", "simplify": "no"}, "simplify"),
        ({"algorithm": "RRT", "time_limit": 1e9}, "time_limit"),
        ({"algorithm": "RRT", "motion_resolution": 1e-300}, "motion_resolution"),
        ({"algorithm": "RRT", "max_iterations": 2.5}, "max_iterations"),
    ],
)
def test_planner_options_are_strict(spec, where):
    with pytest.raises(InputError, match=rf"^planner: {where}: expected"):
        make_planner(spec)
