"""End to end from a tracker's output: tracks -> fit (traffic + behaviour) -> generate.

Synthetic tracks only (public pedestrian datasets are held out): people walk in groups of
1-3 across a 20 x 10 m room, door to door, at about 1.2 m/s, seen at 2.5 Hz. The fit must
find the groups, the regular stays and the doors, and the generated people must walk.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.cli import app

runner = CliRunner()


def _room(folder: Path) -> Path:
    """A 20 x 10 m room at 0.1 m, walls around, a door in the left and right walls."""
    h, w = 100, 200
    img = np.full((h, w), 254, np.uint8)
    img[:3, :] = img[-3:, :] = 0
    img[:, :3] = img[:, -3:] = 0
    img[40:60, :3] = img[40:60, -3:] = 254
    with open(folder / "room.pgm", "wb") as f:
        f.write(f"P5\n{w} {h}\n255\n".encode())
        f.write(img.tobytes())
    meta = {"image": "room.pgm", "resolution": 0.1, "origin": [0.0, 0.0, 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}  # fmt: skip
    (folder / "room.yaml").write_text(yaml.safe_dump(meta))
    return folder / "room.yaml"


def _tracks(folder: Path, horizon: float = 400.0) -> Path:
    rng = np.random.default_rng(0)
    rows, t, k = [], 0.0, 0
    while True:
        t += rng.exponential(8.0)
        if t > horizon - 30:
            break
        size = rng.choice([1, 2, 3], p=[0.5, 0.3, 0.2])
        speed = rng.lognormal(np.log(1.2), 0.1)
        x0, x1 = (0.4, 19.6) if rng.random() < 0.5 else (19.6, 0.4)
        y0, y1 = rng.uniform(4.3, 5.7, 2)
        n = int(abs(x1 - x0) / speed * 2.5)
        for m in range(size):
            tt = t + np.arange(n) / 2.5
            xs = np.linspace(x0, x1, n) + rng.normal(0, 0.05, n)
            ys = np.linspace(y0, y1, n) + 0.2 * m + rng.normal(0, 0.05, n)
            rows += [(f"p{k}", round(a, 1), round(b, 3), round(c, 3))
                     for a, b, c in zip(tt, xs, ys, strict=True) if a < horizon]  # fmt: skip
            k += 1
    path = folder / "tracks.csv"
    pd.DataFrame(rows, columns=["id", "t", "x", "y"]).to_csv(path, index=False)
    meta = {"window": [0.0, horizon], "map": "room.yaml", "time_unit": "s"}
    (folder / "tracks.yaml").write_text(yaml.safe_dump(meta))
    return path


@pytest.mark.slow
def test_tracks_fit_and_generated_people_walk(tmp_path):
    room = _room(tmp_path)
    log = _tracks(tmp_path)
    fit = tmp_path / "f.nc"
    args = ["fit", str(log), "--out", str(fit), "--method", "em", "--samples", "150",
            "--chains", "2", "--warmup", "150", "--no-figures",
            "--behaviour-features", "walls"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    import arviz as az

    idata = az.from_netcdf(fit)
    a = idata.posterior.attrs
    assert (a["arrival_model"], a["position_model"]) == ("groups", "learned")
    assert a["lifetime_model"] != "exponential"  # crossing times are regular
    assert "behaviour" in idata.groups()
    # the wall weight is fitted, stored and printed beside beta and slip
    b = idata.behaviour
    assert list(b["feature"].values) == ["walls"] and b["feature_weight"].shape == (1, 1)
    assert np.isfinite(b["feature_weight"].values).all()
    assert re.search(r"behaviour '\w*': beta .* slip .* walls weight [-+]", res.output), res.output
    # these people walk through each other: the fit keeps no repulsion and says why
    said = " ".join(res.output.split())
    assert "interaction (social force): strength A 0 m/s^2" in said, said
    assert "(no repulsion: the published one fits the tracks worse than none)" in said, said
    # the realism and displacement tables are stored with the behaviour, and report shows
    # them without the tracks (issue 26)
    res = runner.invoke(app, ["report", str(fit), "--out", str(tmp_path / "rep"),
                              "--replicates", "20"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "realism against the log" in res.output and "realism (weighted)" in res.output
    assert re.search(r"ADE/FDE .* model mean of K: [\d.]+ / [\d.]+ m", res.output), res.output
    assert (tmp_path / "rep" / "realism.png").stat().st_size > 10_000
    real = pd.read_csv(tmp_path / "rep" / "realism.csv", index_col=0)
    assert {"constant velocity", "catalogue", "fitted"} <= set(real.columns)
    errors = pd.read_csv(tmp_path / "rep" / "displacement_errors.csv", index_col=0)
    assert list(errors.index) == ["constant velocity", "model mean of K", "model best of K"]
    observed = pd.read_csv(tmp_path / "rep" / "realism_observed.csv", index_col=0)
    assert 1.0 < observed.loc["speed (m/s)", "50%"] < 1.4  # the log's people: about 1.2 m/s
    out = tmp_path / "scen"
    res = runner.invoke(app, ["generate", str(fit), "--scenarios", "2", "--horizon", "200",
                              "--seed", "1", "--out", str(out), "--map", str(room),
                              "--behaviours"])  # fmt: skip
    assert res.exit_code == 0, res.output
    tracks = pd.read_parquet(out / "tracks.parquet")
    speeds, net = [], []
    for _, g in tracks.groupby(["scenario", "id"]):
        g = g.sort_values("t")
        if len(g) < 3 or g["t"].iloc[-1] <= g["t"].iloc[0]:
            continue
        step = np.hypot(np.diff(g["x"]), np.diff(g["y"])).sum()
        speeds.append(step / (g["t"].iloc[-1] - g["t"].iloc[0]))
        net.append(np.hypot(g["x"].iloc[-1] - g["x"].iloc[0], g["y"].iloc[-1] - g["y"].iloc[0]))
    assert len(speeds) > 10
    assert 0.7 < np.median(speeds) < 1.6  # they walk (the log's people: about 1.2 m/s)
    assert np.mean(np.asarray(net) < 1.0) < 0.1  # almost nobody stands still
    artefacts = pd.read_parquet(out / "artefacts.parquet")
    assert artefacts.groupby(["scenario", "group"]).size().max() > 1
    _experiment_walks_the_fitted_people(tmp_path, fit, room)


def _straightness_and_speeds(tracks: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Net over walked distance, and walked distance over time, of each track that moves."""
    straight, speeds = [], []
    for _, g in tracks.groupby("id"):
        g = g.sort_values("t")
        xy = g[["x", "y"]].to_numpy()
        walked = np.hypot(*np.diff(xy, axis=0).T).sum()
        if len(g) < 3 or walked < 2.0:
            continue
        straight.append(np.hypot(*(xy[-1] - xy[0])) / walked)
        speeds.append(walked / (g["t"].iloc[-1] - g["t"].iloc[0]))
    return np.asarray(straight), np.asarray(speeds)


def _experiment_walks_the_fitted_people(tmp_path: Path, fit: Path, room: Path) -> None:
    """``experiment`` with ``behaviours: true`` walks the fit's people with the motion that
    ``generate --behaviours`` gives them (issue 26: one motion in every command): the
    mission's scene is the one assembly's (``scenes_from_fit`` with the task's options),
    its people walk smoothly at about the log's 1.2 m/s (net over walked distance near 1,
    where grid headings zig-zag at about 0.74), and the sweep moves them."""
    from are_stats.environment import load_catalogue, read_map
    from are_stats.experiments import expand_tasks, load_results
    from are_stats.experiments._sweep import _task_scenario
    from are_stats.fitting import read_fit
    from are_stats.scenarios import AssemblyOptions, scenes_from_fit

    cfg = {"name": "walkers", "map": str(room), "seed": 4, "replicates": 1,
           "scenario": {"fit": str(fit)}, "behaviours": True,
           "robot": {"radius": 0.3, "speed": 1.0},
           "mission": {"n_goals": 10, "time_limit": 120.0, "min_goal_separation": 3.0},
           "planner": {"algorithm": "astar"}}  # fmt: skip
    (tmp_path / "walkers.yaml").write_text(yaml.safe_dump(cfg))
    res = runner.invoke(app, ["experiment", str(tmp_path / "walkers.yaml"), "--out",
                              str(tmp_path / "results")])  # fmt: skip
    assert res.exit_code == 0, res.output
    runs = load_results(tmp_path / "results")["runs"]
    assert len(runs) == 1 and runs["n_move_updates"].iloc[0] > 0
    (task,) = expand_tasks(cfg)
    (_, grid), catalogue = read_map(str(room)), load_catalogue()
    scene, cols = _task_scenario(task, grid, catalogue)
    options = AssemblyOptions(behaviours=True, cell_source="mission.behaviour_cell")
    (alone,) = scenes_from_fit(
        int(task["seed"]), read_fit(fit), grid, catalogue, 1, 120.0, options,
        posterior_draw=int(cols["draw"]),
    )  # fmt: skip
    pd.testing.assert_frame_equal(scene.tracks_table(), alone.tracks_table())
    straight, speeds = _straightness_and_speeds(scene.tracks_table())
    assert len(speeds) >= 5, len(speeds)
    assert np.median(straight) > 0.9, np.median(straight)
    assert 0.9 < np.median(speeds) < 1.5, np.median(speeds)


def test_fit_names_an_unknown_behaviour_feature(tmp_path):
    log = _tracks(tmp_path)
    res = runner.invoke(app, ["fit", str(log), "--out", str(tmp_path / "f.nc"),
                              "--behaviour-features", "walls,doors"])  # fmt: skip
    assert res.exit_code != 0
    assert "--behaviour-features" in res.output and "'walls'" in res.output
    assert not (tmp_path / "f.nc").exists()


def test_fit_refuses_behaviour_features_without_the_behaviour(tmp_path):
    log = _tracks(tmp_path)
    res = runner.invoke(app, ["fit", str(log), "--out", str(tmp_path / "f.nc"),
                              "--behaviour-features", "walls", "--no-behaviour"])  # fmt: skip
    assert res.exit_code != 0
    assert "--behaviour-features" in res.output and "--no-behaviour" in res.output
    assert not (tmp_path / "f.nc").exists()


def test_fit_names_its_log_by_file_name_and_hash_not_folder(tmp_path):
    """A shared fit must not carry the user's folder layout: attrs.log is the file name,
    attrs.log_sha256 the hash of the bytes fitted, and no attribute holds the folder."""
    import hashlib

    import arviz as az

    _room(tmp_path)
    log = _tracks(tmp_path, horizon=120.0)
    fit = tmp_path / "f.nc"
    args = ["fit", str(log), "--out", str(fit), "--method", "em", "--samples", "50",
            "--chains", "1", "--no-figures", "--no-behaviour", "--arrivals", "poisson",
            "--lifetimes", "exponential", "--positions", "uniform"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    a = az.from_netcdf(fit).posterior.attrs
    assert a["log"] == "tracks.csv"
    assert a["log_sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()
    assert yaml.safe_load(a["log_report"])["source"] == "tracks.csv"
    assert str(tmp_path).encode() not in fit.read_bytes()
    assert tmp_path.name.encode() not in fit.read_bytes()


@pytest.mark.slow
def test_the_motion_checks_are_drawn_once_and_handed_to_the_report(tmp_path, monkeypatch):
    """fit_log draws the motion checks for the per-class rows; the report uses the fit's
    (the same draws) instead of simulating the 50 replicates again (issue 29)."""
    import jax

    from are_stats.environment import load_catalogue
    from are_stats.fitting import FitSettings, _motion_report, fit_log, motion_checks
    from are_stats.logs import read_field_log

    _room(tmp_path)
    log = read_field_log(_tracks(tmp_path, horizon=80.0))
    fit = fit_log(3, log, FitSettings(method="em", positions="uniform"))
    assert fit.motion_checks is not None
    key = jax.random.fold_in(jax.random.key(3), 1)
    # as the fit draws them: its interaction (the published one where it learned none), its map
    walk = fit.interaction if fit.interaction is not None else True
    table, _ = motion_checks(
        key, fit.behaviour, log.tracks, n_replicates=50, interaction=walk, grid=fit.grid
    )
    pd.testing.assert_frame_equal(fit.motion_checks[0], table)

    def again(*args, **kwargs):
        raise AssertionError("the report drew the motion checks again")

    monkeypatch.setattr(_motion_report, "motion_checks", again)
    (tmp_path / "rep").mkdir()
    told = []
    report = _motion_report.write_motion_report(
        3, fit, log.tracks, tmp_path / "rep", False, load_catalogue(),
        progress=lambda done, total, what: told.append((done, total, what)),
    )  # fmt: skip
    pd.testing.assert_frame_equal(report.checks, table)
    assert told == [(1, 2, "held-out moves"), (2, 2, "figure")]
    # an unlabelled log's report draws them itself, and tells their steps (issue 29: every
    # stage over 2 s shows progress)
    monkeypatch.setattr(_motion_report, "motion_checks", motion_checks)
    told.clear()
    (tmp_path / "rep2").mkdir()
    report = _motion_report.write_motion_report(
        3, dataclasses.replace(fit, motion_checks=None), log.tracks, tmp_path / "rep2", False,
        load_catalogue(), progress=lambda done, total, what: told.append((done, total, what)),
    )  # fmt: skip
    pd.testing.assert_frame_equal(report.checks, table)
    whats = [w for _, _, w in told]
    assert any(w.startswith("motion checks, routes") for w in whats)
    assert any(w.startswith("motion checks, social force") for w in whats)
    assert whats[-2:] == ["held-out moves", "figure"]
    assert all(0 < d <= t for d, t, _ in told) and told[-1][0] == told[-1][1]
    assert [d for d, _, _ in told] == sorted(d for d, _, _ in told)
