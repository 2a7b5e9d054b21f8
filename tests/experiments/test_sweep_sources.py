"""Sweeps whose artefacts come from a fit or a scenarios folder, with paths relative to the
config file, and with moving artefacts (issue 15)."""

from __future__ import annotations

import os
import shutil

import arviz as az
import jax
import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

import are_stats.experiments._sweep as sweep_module
from are_stats import FitSettings, fit_log, load_catalogue, simulate_lifecycle, write_fit
from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, shipped_path
from are_stats.experiments import (
    Robot,
    expand_tasks,
    load_results,
    load_sweep_config,
    plot_goals,
    plot_results,
    run_mission,
    run_sweep,
    run_task,
)
from are_stats.experiments._sweep import _task_scenario, _validate
from are_stats.fitting import posterior_draws
from are_stats.inputs import InputError, load_yaml
from are_stats.scenarios import generate_scenarios, scene_tracks, scenes_from_tables, write_scenes

SIDE = 20  # a 20 m x 20 m free square at 1 m cells
AREA = float(SIDE * SIDE)
HORIZON = 20.0
LAMBDA, MU = 1.5 / AREA, 0.1  # 1.5 arrivals per s on the map, mean stay 10 s
QUIET = {"workers": 1, "processes": False, "progress": False}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A map, a fit of a simulated log (EM) and a scenarios folder, in one folder."""
    root = tmp_path_factory.mktemp("sources")
    grid = OccupancyGrid(np.zeros((SIDE, SIDE)), 1.0)
    grid.to_ros_yaml(root / "maps" / "square.yaml")
    data = simulate_lifecycle(
        jax.random.key(0), LAMBDA, MU, [0.6, 0.4], [1.0, 4.0], (0.0, 600.0), area=AREA
    )
    paper = {"arrivals": "poisson", "lifetimes": "exponential", "positions": "uniform"}
    settings = FitSettings(
        method="em", num_samples=40, num_chains=2, n_bootstrap=8, k_max=2, **paper
    )
    idata = fit_log(jax.random.key(1), data, settings).idata
    write_fit(idata, root / "fits" / "fit.nc")
    draws = posterior_draws(idata)
    df = generate_scenarios(5, draws, 2, HORIZON, free_mask=grid)
    write_scenes(df, root / "scen", {"class_labels": None})
    return root, grid, draws, df


def _config(root, **over):
    cfg = {
        "name": "fromfit",
        "map": str(root / "maps" / "square.yaml"),
        "seed": 7,
        "replicates": 2,
        "scenario": {"fit": str(root / "fits" / "fit.nc")},
        "robot": {"radius": 0.3, "speed": 1.0},
        "mission": {"n_goals": 1, "time_limit": HORIZON, "min_goal_separation": 3.0},
        "planner": {"algorithm": "astar"},
    }
    cfg.update(over)
    return cfg


def test_sweep_from_a_fit_matches_its_posterior_and_resumes(files, tmp_path):
    root, grid, draws, _ = files
    # the arrivals' law on one level of 24 replicates (it needs them: the 4 standard errors
    # below), common random numbers, Fig. 7's grouping and resume on two levels of 4
    # (a sweep of both levels of 24 replicates ran twice the missions the law needs)
    n_rep = 24
    run_sweep(_config(root, replicates=n_rep), tmp_path / "one", **QUIET)
    one = load_results(tmp_path / "one")["runs"]
    assert len(one) == n_rep
    # the draw's rate is the posterior's
    lam = draws["arrival_rate"]
    np.testing.assert_array_equal(one["arrival_rate"], lam[one["draw"].to_numpy()])
    # arrivals per replicate: Poisson(lambda A T) with lambda a posterior draw; its mean
    # E[lambda] A T and variance E[lambda] A T + Var[lambda] (A T)^2 come from the draws.
    # |mean - expected| < 4 standard errors: false-failure rate about 6e-5 (normal approx.)
    at = grid.free_area * HORIZON
    expected = lam.mean() * at
    se = np.sqrt((expected + lam.var() * at**2) / n_rep)
    got = one["n_arrivals"].mean()
    assert abs(got - expected) < 4 * se, (got, expected, se)
    n_rep = 4
    cfg = _config(root, replicates=n_rep, factors={"robot.speed": [0.5, 1.0]})
    out = tmp_path / "res"
    run_sweep(cfg, out, **QUIET)
    runs = load_results(out)["runs"]
    assert len(runs) == 2 * n_rep
    # common random numbers: a replicate has the same draw and artefacts at every level
    per = runs.groupby("replicate")[["draw", "n_arrivals", "n_artefacts", "arrival_rate"]]
    assert (per.nunique() == 1).all().all()
    level = runs[runs["level:robot.speed"] == "1.0"]
    np.testing.assert_array_equal(level["arrival_rate"], lam[level["draw"].to_numpy()])
    # Fig. 7: every run has its own drawn rate, so the plots group by the speed factor
    fig = plot_goals(runs, load_results(out)["goals"])
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert len(labels) == 2 and all("clutter" in t for t in labels)
    # resume: lost results are redone identically, the others are kept
    lost = sorted((out / "runs").glob("*.parquet"))[:3]
    for p in lost:
        p.unlink()
    run_sweep(cfg, out, **QUIET)
    again = load_results(out)["runs"]
    volatile = ["rho_mean", "rho_t_mean"]
    pd.testing.assert_frame_equal(again.drop(columns=volatile), runs.drop(columns=volatile))


def test_sweep_from_a_scenarios_folder(files, tmp_path):
    root, _, _, df = files
    cfg = _config(root, replicates=3, scenario={"scenarios": str(root / "scen")})
    out = run_sweep(cfg, tmp_path / "res", workers=1, processes=False, progress=False)
    runs = load_results(out)["runs"].sort_values("replicate")
    # replicate r uses scenario r mod 2 of the folder
    assert runs["draw"].tolist() == [0, 1, 0]
    sizes = df.groupby("scenario").size()
    assert runs["n_artefacts"].tolist() == [sizes[0], sizes[1], sizes[0]]
    assert runs["arrival_rate"].isna().all()
    # the Fig. 7 plots group such runs by their factor levels (here: all runs together)

    assert all(p.is_file() for p in plot_results(out))
    # a mission longer than the scenarios is refused, naming the key
    long = _config(
        root,
        scenario={"scenarios": str(root / "scen")},
        mission={"n_goals": 1, "time_limit": 2 * HORIZON},
    )
    with pytest.raises(InputError, match="mission.time_limit"):
        expand_tasks(long)


def test_relative_paths_resolve_against_the_config_file(files, tmp_path, monkeypatch):
    root, *_ = files
    cfg_dir = tmp_path / "configs"
    cfg_dir.mkdir()
    shutil.copytree(root / "maps", cfg_dir / "maps")
    cat = os.path.relpath(DEFAULT_MODELS / "artefacts" / "catalogue.yaml", cfg_dir)
    fit = os.path.relpath(root / "fits" / "fit.nc", cfg_dir)
    cfg = _config(root, map="maps/square.yaml", catalogue=cat, scenario={"fit": fit})
    path = cfg_dir / "sweep.yaml"
    path.write_text(yaml.safe_dump(cfg))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    tasks = expand_tasks(path)
    assert tasks[0]["map"] == str((cfg_dir / "maps" / "square.yaml").resolve())
    assert tasks[0]["scenario"]["fit"] == str((root / "fits" / "fit.nc").resolve())
    # the workers run in this other working directory: they read the resolved files
    out = run_sweep(path, "res", workers=1, processes=False, progress=False)
    assert len(load_results(out)["runs"]) == 2
    # a missing relative file is named with the config and its key, before any worker

    def no_workers(*args, **kwargs):
        raise AssertionError("a Dask client was started")

    monkeypatch.setattr(sweep_module, "_client", no_workers)
    for key, value, where in [
        ("scenario", {"fit": "nowhere.nc"}, "scenario.fit"),
        ("scenario", {"scenarios": "nowhere"}, "scenario.scenarios"),
        ("catalogue", "nowhere.yaml", "catalogue"),
    ]:
        path.write_text(yaml.safe_dump({**cfg, key: value}))
        with pytest.raises(InputError, match=where) as err:
            run_sweep(path, "res2", workers=1, processes=False, progress=False)
        assert str(path) in str(err.value) and str(cfg_dir / "nowhere") in str(err.value)


@pytest.mark.parametrize(
    ("scenario", "factors", "where"),
    [
        ({"fit": "a.nc", "arrival_rate": 0.1}, {}, "scenario.arrival_rate"),
        ({"fit": "a.nc", "scenarios": "d"}, {}, "scenario.scenarios"),
        ({"scenarios": "d", "start": "empty"}, {}, "scenario.start"),
        ({"fit": "a.nc"}, {"scenario.arrival_rate": [0.1, 0.2]}, "factors.scenario.arrival_rate"),
        ({"arrival_rate": 0.1}, {"scenario.fit": ["a.nc", "b.nc"]}, "factors.scenario.fit"),
    ],
)
def test_scenario_sources_are_exclusive(scenario, factors, where):
    with pytest.raises(InputError, match=where.replace(".", r"\.")):
        _validate({"scenario": scenario, "factors": factors}, "cfg.yaml")


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("scenarios", "a scenarios folder written by are-stats generate, got no such folder"),
        ("fit", "a fit file written by are-stats fit, got no such file"),
    ],
)
def test_a_missing_scenario_source_is_named(tmp_path, key, expected):
    missing = tmp_path / "missing"
    cfg = {"name": "gone", "map": "courtyard", "scenario": {key: str(missing)}}
    with pytest.raises(InputError, match=f"scenario.{key}: expected {expected} {missing}$"):
        load_sweep_config(cfg)


def test_behaviours_move_the_artefacts(files):
    root, *_ = files
    cfg = _config(root, replicates=1, behaviours=True)
    task = expand_tasks(cfg)[0]
    runs = run_task(task)["runs"].iloc[0]
    assert runs["n_move_updates"] > 0
    still = run_task({**task, "behaviours": False})["runs"].iloc[0]
    assert still["n_move_updates"] == 0
    # the same artefacts, standing or moving
    assert still["n_artefacts"] == runs["n_artefacts"]


def test_shipped_fit_config_is_valid(tmp_path, monkeypatch):
    path = shipped_path("fig7_fit", "experiment")
    cfg = _validate(load_yaml(path, "sweep config"), str(path), tmp_path)
    assert cfg["behaviours"] is True and cfg["map"] == "courtyard"
    # a shipped config's relative paths are taken from the working directory (its own
    # folder is inside the install): the fit to make first is named there
    monkeypatch.chdir(tmp_path)
    fit = tmp_path / "fits" / "courtyard_traffic.nc"
    with pytest.raises(InputError, match=f"scenario.fit.*no such file {fit}"):
        load_sweep_config("fig7_fit")


def test_behaviour_tracks_stay_on_free_cells_and_a_walled_in_artefact_stops():
    data = np.zeros((12, 12))
    data[3:8, 3:8] = 100  # a block of walls ...
    data[5, 5] = 0  # ... with a one-cell pocket at (5.5, 5.5)
    grid = OccupancyGrid(data, 1.0)
    art = pd.DataFrame(
        {
            "scenario": 0,
            "artefact": [0, 1],
            "class": 0,
            "mark": 0,
            "t_arrive": [0.0, 0.0],
            "t_leave": [30.0, 30.0],
            "x": [5.5, 1.5],
            "y": [5.5, 1.5],
            "yaw": 0.0,
        }
    )
    cat = load_catalogue()
    tracks = scene_tracks(
        jax.random.key(3),
        art,
        grid,
        cat,
        30.0,
        behaviours="catalogue",
        behaviour_dt=1.0,
        interaction=False,
    )
    pocket, walker = tracks[tracks["id"] == 0], tracks[tracks["id"] == 1]
    assert len(pocket) > 1 and (pocket["x"] == 5.5).all() and (pocket["y"] == 5.5).all()
    xy = walker[["x", "y"]].to_numpy()
    assert (np.abs(np.diff(xy, axis=0)).sum() > 0) and len(walker) > 1
    ij = grid.world_to_cell(xy)
    assert grid.free[ij[:, 0], ij[:, 1]].all()
    # steps of at most two cells per epoch (walk one, run two): no jump through a wall
    assert np.abs(np.diff(xy, axis=0)).max() <= 2.0
    # in the mission, the moving one makes move updates at its epochs
    res = run_mission_on(grid, scenes_from_tables(art, tracks, cat)[0])
    assert (res.timeline["kind"] == "move").any()


def run_mission_on(grid, scene):
    return run_mission(
        grid,
        scene,
        [[10.5, 1.5], [10.5, 10.5]],
        "astar",
        robot=Robot(radius=0.3, speed=1.0),
        time_limit=30.0,
    )


def test_scenarios_folder_tracks_are_used_with_behaviours(files, tmp_path):
    root, grid, _, df = files
    folder = tmp_path / "scen"
    write_scenes(df, folder, {"tracks": {"file": "tracks.parquet"}})
    # every artefact steps 0.5 m along x one and two seconds after it arrives
    rows = [
        {
            "scenario": r.scenario,
            "id": r.artefact,
            "t": r.t_arrive + k,
            "x": r.x + 0.5 * k,
            "y": r.y,
            "yaw": r.yaw,
        }
        for r in df.itertuples()
        for k in (1.0, 2.0)
    ]
    pd.DataFrame(rows).to_parquet(folder / "tracks.parquet", index=False)
    cfg = _config(root, replicates=1, scenario={"scenarios": str(folder)})
    task = expand_tasks({**cfg, "behaviours": True})[0]
    moving = run_task(task)["runs"].iloc[0]
    assert moving["n_move_updates"] > 0
    assert {"n_detours", "n_yields", "avoid_delay"} <= set(moving.index)
    still = run_task({**task, "behaviours": False})["runs"].iloc[0]
    assert still["n_move_updates"] == 0 and still["n_detours"] == still["n_yields"] == 0


def test_a_folder_without_tracks_moves_its_scene_as_the_table_route_did(files, monkeypatch):
    """A scenarios folder without tracks, with behaviours: the task's Scene is moved by
    move_scenes (Scene -> Scene), and is the scene the table route made (scene_tracks of
    the scenario's rows, keyed by the task's seed, then scenes_from_tables): same poses at
    every time, same life-cycle."""
    root, grid, _, df = files
    cfg = _config(root, replicates=2, scenario={"scenarios": str(root / "scen")})
    cat = load_catalogue()

    def table_view(*args, **kwargs):
        raise AssertionError("the sweep moved its scene through the table view scene_tracks")

    for task in expand_tasks({**cfg, "behaviours": True}):
        with monkeypatch.context() as m:
            m.setattr(sweep_module, "scene_tracks", table_view, raising=False)
            scene, info = _task_scenario(task, grid, cat)
        draw = info["draw"]
        art = df[df["scenario"] == draw].reset_index(drop=True)
        tracks = scene_tracks(
            jax.random.key(int(task["seed"])),
            art,
            grid,
            cat,
            HORIZON,
            behaviours="catalogue",
            n=draw + 1,
        )
        (want,) = scenes_from_tables(art, tracks, cat, None, [draw])
        assert scene.has_tracks.any() and len(scene) == len(want)
        np.testing.assert_array_equal(scene.ids, want.ids)
        np.testing.assert_array_equal(scene.t_arrive, want.t_arrive)
        for t in np.linspace(0.0, HORIZON, 41):
            np.testing.assert_array_equal(scene.poses(t), want.poses(t))


def test_a_fit_with_groups_sends_groups_through_the_mission(files, tmp_path):
    """A fit whose chosen arrival model is groups: the mission's artefacts arrive in groups."""
    root, grid, _, _ = files
    idata = az.from_netcdf(root / "fits" / "fit.nc")
    post = idata.posterior
    shape = post["arrival_rate"].shape
    # groups of exactly three at a third of the artefact rate (a stated truth, not a fit)
    post["event_rate"] = xr.DataArray(post["arrival_rate"].values / 3.0, dims=("chain", "draw"))
    probs = np.zeros(shape + (3,))
    probs[..., 2] = 1.0
    post["group_size_probs"] = xr.DataArray(probs, dims=("chain", "draw", "group_size"))
    post.attrs["arrival_model"] = "groups"
    fit = tmp_path / "groups.nc"
    write_fit(idata, fit)
    cfg = _config(root, replicates=1, scenario={"fit": str(fit)})
    task = expand_tasks(cfg)[0]

    scene, _ = _task_scenario(task, grid, load_catalogue())
    # arrivals come three at a time: arrival times repeat in threes
    arrived = scene.t_arrive[scene.t_arrive > 0]
    _, counts = np.unique(arrived, return_counts=True)
    assert arrived.size > 0 and set(counts.tolist()) == {3}
