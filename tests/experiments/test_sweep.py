"""Sweeps: a small end-to-end experiment on Dask, tidy tables, resume, CLI, plots, MCAP."""

from __future__ import annotations

from collections import Counter

import dask
import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml
from distributed import LocalCluster
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from are_stats._atomic import OutputExistsError
from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, load_catalogue
from are_stats.experiments import (
    expand_tasks,
    load_results,
    load_sweep_config,
    run_mission,
    run_sweep,
    run_task,
)
from are_stats.export import MCAP_TOPICS, export_mcap
from are_stats.inputs import InputError
from are_stats.scenarios import Scene

CONFIG = {
    "name": "tiny",
    "map": "courtyard",
    "seed": 3,
    "replicates": 2,
    "scenario": {
        "arrival_rate": 0.0005,
        "leave_rate": 0.05,
        "mix_weights": [0.5, 0.5],
        "mix_rates": [0.5, 3.0],
    },
    "mission": {"n_goals": 2, "time_limit": 25.0},
    "planner": {"algorithm": "astar"},
    "factors": {"scenario.arrival_rate": [0.0002, 0.001]},
}


def test_expand_tasks_grid_and_common_seeds():
    cfg = {
        **CONFIG,
        "factors": {
            **CONFIG["factors"],
            "planner": [
                {"name": "A*", "algorithm": "astar"},
                {"name": "RRT", "algorithm": "RRT", "range": 2.0, "goal_bias": 0.05},
            ],
        },
    }
    tasks = expand_tasks(cfg)
    assert len(tasks) == 2 * 2 * 2
    assert len({t["task"] for t in tasks}) == 8
    # replicate r has the same seed at every factor level (common random numbers)
    seeds = {(t["replicate"], t["seed"]) for t in tasks}
    assert len(seeds) == 2
    assert {t["levels"]["planner"] for t in tasks} == {"A*", "RRT"}
    assert {t["scenario"]["arrival_rate"] for t in tasks} == {0.0002, 0.001}
    # artefacts avoid the robot unless the config says not to
    assert all(t["avoid_robot"] is True for t in tasks)
    assert all(t["avoid_robot"] is False for t in expand_tasks({**cfg, "avoid_robot": False}))


def test_run_task_is_deterministic_but_rho_t():
    task = expand_tasks(CONFIG)[1]
    a, b = run_task(task), run_task(task)
    drop = {"runs": ["rho_mean", "rho_t_mean"], "replans": ["rho", "rho_t"], "goals": []}
    for name, cols in drop.items():
        pd.testing.assert_frame_equal(a[name].drop(columns=cols), b[name].drop(columns=cols))


def test_sweep_end_to_end_and_resume(tmp_path):
    out = tmp_path / "res"
    run_sweep(CONFIG, out, workers=1, processes=False, progress=False)
    res = load_results(out)
    runs, replans, goals = res["runs"], res["replans"], res["goals"]
    assert len(runs) == 4 and runs["task"].is_unique
    assert set(runs["level:scenario.arrival_rate"]) == {"0.0002", "0.001"}
    assert (runs["goals_reached"] <= runs["goals_total"]).all()
    assert (runs["mission_time"] <= 25.0).all()
    assert ((replans["rho"] >= 0) & (replans["rho"] <= 1) | replans["rho"].isna()).all()
    ok = replans["success"]
    np.testing.assert_allclose(
        replans.loc[ok, "rho"],
        replans.loc[ok, "rho_t"] / (replans.loc[ok, "rho_t"] + replans.loc[ok, "g_t"]),
    )
    grid = OccupancyGrid.from_ros_yaml(DEFAULT_MODELS / "courtyard.yaml")
    np.testing.assert_allclose(replans["nu"], replans["n_A"] / grid.n_free)
    assert len(goals) == 4 * 2
    # more arrivals -> more clutter, on average over the replicates
    nu = runs.groupby("arrival_rate")["nu_mean"].mean()
    assert nu[0.001] > nu[0.0002]
    # interrupt: two tasks lost their result; the rerun redoes exactly those
    stat = {p.name: p.stat() for p in (out / "runs").glob("*.parquet")}
    lost = sorted(stat)[:2]
    for name in lost:
        (out / "runs" / name).unlink()
    run_sweep(CONFIG, out, workers=1, processes=False, progress=False)
    for p in (out / "runs").glob("*.parquet"):
        same = (
            p.stat().st_ino == stat[p.name].st_ino
            and p.stat().st_mtime_ns == stat[p.name].st_mtime_ns
        )
        assert same == (p.name not in lost)
    again = load_results(out)["runs"]
    pd.testing.assert_frame_equal(
        again.drop(columns=["rho_mean", "rho_t_mean"]),
        runs.drop(columns=["rho_mean", "rho_t_mean"]),
    )
    # a different sweep into the same folder is refused without force
    with pytest.raises(OutputExistsError):
        run_sweep({**CONFIG, "seed": 4}, out, workers=1, processes=False, progress=False)


def test_cli_experiment_and_plot(tmp_path):
    cfg = {**CONFIG, "replicates": 1, "factors": {"scenario.arrival_rate": [0.0002]}}
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(cfg))
    runner = CliRunner()
    out = tmp_path / "r"
    r = runner.invoke(app, ["experiment", str(path), "--out", str(out), "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert len(list((out / "runs").glob("*.parquet"))) == 1
    r = runner.invoke(app, ["plot", str(out)])
    assert r.exit_code == 0, r.output
    assert (out / "fig7a_rho.png").stat().st_size > 0 and (out / "fig7b_goals.png").is_file()
    r = runner.invoke(app, ["plot", str(out)])
    assert r.exit_code == 2 and "already exists" in r.output
    r = runner.invoke(app, ["experiment", str(tmp_path / "missing.yaml")])
    assert r.exit_code == 2 and "not found" in r.output
    r = runner.invoke(app, ["plot", str(tmp_path / "nothing")])
    assert r.exit_code == 2 and "no finished" in r.output


@pytest.mark.parametrize(
    ("cfg", "match"),
    [
        ({"replicates": 0}, "replicates"),
        ({"factors": {"scenario.speed": [1]}}, "unknown key"),
        ({"factors": {"robot": [1]}}, "planner"),
        ({"factors": {"scenario.arrival_rate": []}}, "non-empty"),
        ({"colour": 1}, "unknown key"),
        ({"mission": 3}, "mapping"),
        ({"avoid_robot": "maybe"}, "avoid_robot"),
    ],
)
def test_bad_configs(cfg, match):
    with pytest.raises(ValueError, match=match):
        load_sweep_config(cfg)


def test_shipped_config_loads():
    cfg = load_sweep_config(DEFAULT_MODELS / "experiments" / "fig7.yaml")
    assert len(expand_tasks(cfg)) == 2 * 2 * cfg["replicates"]


def test_mcap_export_reads_back(tmp_path):
    grid = OccupancyGrid(np.zeros((20, 20)), 1.0)
    art = pd.DataFrame(
        [[2.0, 4.0, 10.0, 5.0, 0.0, 0], [0.0, 50.0, 10.0, 15.0, 0.0, 3]],
        columns=["t_arrive", "t_leave", "x", "y", "yaw", "mark"],
    )
    scene = Scene.from_scenarios(art, load_catalogue())
    res = run_mission(grid, scene, [[2.0, 10.0], [18.0, 10.0]], "astar", record=True, time_limit=60)
    path = export_mcap(tmp_path / "run.mcap", grid, res.trace)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    counts: Counter = Counter()
    last = {}
    with open(path, "rb") as fh:
        for schema, channel, msg in make_reader(fh).iter_messages():
            assert schema.name == MCAP_TOPICS[channel.topic]
            counts[channel.topic] += 1
            last[channel.topic] = ts.deserialize_cdr(msg.data, schema.name)
    n_scenes = len(res.trace.scenes)
    assert counts["/map"] == 1 and counts["/goals"] == 1
    assert counts["/augmented_map"] == n_scenes == 3
    # the artefacts at every scene update and every 0.1 s between (tests/export/
    # test_mcap_motion.py checks where)
    end = max(res.trace.poses[-1, 0], res.trace.scenes[-1]["t"])
    assert counts["/artefacts"] == int(np.floor(end * 10 + 1e-9)) + 1
    assert counts["/planner_map"] == n_scenes
    # /augmented_map is M_2D with every live box (as augment publishes it), /planner_map
    # what the planner saw; here both boxes are perceived, so the two agree cell for cell
    sc = res.trace.scenes[-1]
    assert len(sc["ids"]) == 1 and sc["perceived"].all()
    aug = np.asarray(last["/augmented_map"].data).reshape(20, 20)
    assert (aug == 100).sum() > 0 and np.array_equal(
        aug, np.asarray(last["/planner_map"].data).reshape(20, 20)
    )
    assert np.array_equal(aug, sc["grid"].data)
    assert counts["/plan"] == int(res.replans["success"].sum())
    assert counts["/robot_pose"] == len(res.trace.poses)
    assert last["/map"].info.width == 20 and len(last["/map"].data) == 400
    # the last scene: one box live (the one at t 2..4 has left), drawn perceived (green)
    boxes = [m for m in last["/artefacts"].markers if m.action == 0 and m.ns == "artefacts"]
    assert len(boxes) == 1 and boxes[0].color.g > boxes[0].color.r
    texts = [m for m in last["/artefacts"].markers if m.ns == "labels"]
    assert [m.type for m in texts] == [9] and texts[0].text.startswith(boxes[0].text or "")
    assert counts["/tf_static"] == 1 and counts["/tf"] >= len(res.trace.poses)
    with pytest.raises(OutputExistsError):
        export_mcap(path, grid, res.trace)
    with pytest.raises(ValueError, match="trace"):
        export_mcap(tmp_path / "x.mcap", grid, None)


def test_sweep_on_an_existing_scheduler(tmp_path):
    cfg = {**CONFIG, "replicates": 1, "factors": {"scenario.arrival_rate": [0.0002]}}
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        out = run_sweep(cfg, tmp_path / "r", scheduler=cluster.scheduler_address, progress=False)
    assert len(load_results(out)["runs"]) == 1
    assert dask.config.get("scheduler", None) is None  # the client did not become the default


def test_bad_scheduler_leaves_dask_config_alone(tmp_path):
    """A refused ``--scheduler`` must not leave dask set to "dask.distributed": xarray would
    then take a distributed lock for every later netCDF write, and fail (the CI failure)."""
    cfg = {**CONFIG, "replicates": 1, "factors": {"scenario.arrival_rate": [0.0002]}}
    with pytest.raises(InputError, match="--scheduler"):
        run_sweep(cfg, tmp_path / "r", scheduler="not-an-address", progress=False)
    assert dask.config.get("scheduler", None) is None
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(tmp_path / "after.nc")
