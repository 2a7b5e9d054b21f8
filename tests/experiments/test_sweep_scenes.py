"""Scenario folders and catalogues in sweep configs are checked in the parent, before any
worker starts, through the one reader (issue 30); valid configs are accepted."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest
import yaml

from are_stats.environment import SHIPPED_DATA, OccupancyGrid, shipped_path
from are_stats.experiments import expand_tasks, load_sweep_config, run_task
from are_stats.export._live import _replay
from are_stats.inputs import InputError, load_yaml
from are_stats.scenarios import SCENARIO_COLUMNS, generate_scenarios, read_scenes, write_scenes

SIDE = 20
HORIZON = 20.0
PARAMS = {
    "arrival_rate": np.array([0.5 / SIDE**2]),
    "leave_rate": np.array([0.1]),
    "mix_weights": np.array([[1.0]]),
    "mix_rates": np.array([[1.0]]),
}


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    root = tmp_path_factory.mktemp("scenes")
    OccupancyGrid(np.zeros((SIDE, SIDE)), 1.0).to_ros_yaml(root / "square.yaml")
    # the same square turned by 90 degrees
    OccupancyGrid(np.zeros((SIDE, SIDE)), 1.0, origin=(20.0, 0.0, np.pi / 2)).to_ros_yaml(
        root / "turned.yaml"
    )
    return root


def _artefacts(n=2):
    grid = OccupancyGrid(np.zeros((SIDE, SIDE)), 1.0)
    return generate_scenarios(3, PARAMS, n, HORIZON, free_mask=grid)


def _tracks(df):
    rows = [
        {
            "scenario": r.scenario,
            "id": r.artefact,
            "t": r.t_arrive + k,
            "x": r.x,
            "y": r.y,
            "yaw": r.yaw,
        }
        for r in df.itertuples()
        for k in (1.0, 2.0)
    ]
    return pd.DataFrame(rows)


def _config(root, folder, **over):
    cfg = {
        "map": str(root / "square.yaml"),
        "seed": 1,
        "replicates": 1,
        "scenario": {"scenarios": str(folder)},
        "robot": {"radius": 0.3, "speed": 1.0},
        "mission": {"n_goals": 1, "time_limit": HORIZON, "min_goal_separation": 3.0},
        "planner": {"algorithm": "astar"},
    }
    cfg.update(over)
    return cfg


def test_empty_artefacts_with_behaviours_runs(root, tmp_path):
    # a folder where no artefact arrived: valid; behaviours roll out nothing
    empty = pd.DataFrame(
        {c: np.zeros(0, SCENARIO_COLUMNS[c].split(",")[0]) for c in SCENARIO_COLUMNS}
    )
    folder = tmp_path / "empty"
    write_scenes(empty, folder, {"n_scenarios": 2, "generation": {"horizon": HORIZON}})
    tasks = expand_tasks(_config(root, folder, behaviours=True, replicates=2))
    for task in tasks:
        runs = run_task(task)["runs"].iloc[0]
        assert runs["n_artefacts"] == 0 and runs["n_move_updates"] == 0
        assert runs["draw"] == task["replicate"]
    # serve: an empty scene of scenario 1
    replay = _replay(folder, read_scenes(folder), 1)
    assert len(replay["scene"]) == 0 and replay["horizon"] == HORIZON


def _damaged(tmp_path, manifest=None, edit=None, tracks=False):
    df = _artefacts()
    folder = tmp_path / "scen"
    write_scenes(df, folder, manifest, tracks=_tracks(df) if tracks else None, force=True)
    if edit is not None:
        name, column, value = edit
        table = pd.read_parquet(folder / name)
        table[column] = table[column].astype(float)
        table.loc[1, column] = value
        table.to_parquet(folder / name, index=False)
    return folder


@pytest.mark.parametrize(
    ("manifest", "edit", "tracks", "match"),
    [
        # gave "TypeError: 'int' object is not iterable" in the task
        ({"class_labels": 3}, None, False, r"manifest\.yaml: class_labels: expected a list"),
        ({"class_labels": [1, 2]}, None, False, r"class_labels\[0\]: expected a string"),
        # accepted: an artefact 1e300 m away
        (None, ("artefacts.parquet", "x", 1e300), False, r"row 2, column 'x': expected a pos"),
        # the tracks were read unchecked
        (None, ("tracks.parquet", "y", 1e300), True, r"tracks\.parquet: row 2, column 'y'"),
        (None, ("tracks.parquet", "id", 99.0), True, r"row 2, column 'id': expected an artefact"),
        ({"generation": "x"}, None, False, r"manifest\.yaml: generation: expected a mapping"),
    ],
)
def test_bad_scenario_folders_are_refused_before_any_task(
    root, tmp_path, manifest, edit, tracks, match
):
    folder = _damaged(tmp_path, manifest, edit, tracks)
    with pytest.raises(InputError, match=match):
        load_sweep_config(_config(root, folder, behaviours=True))


@pytest.mark.parametrize(
    "damage",
    [
        "classes: [\n",  # truncated YAML
        "classes: []\n",
        "classes:\n  - {label: a, mesh: cart.obj, speeds: {walk: -1}, behaviours: [walk]}\n",
        "classes:\n  - {label: a, mesh: broken.obj, speeds: {walk: 1}, behaviours: [walk]}\n",
        "version: 2\nclasses: [{label: a, mesh: cart.obj, speeds: {walk: 1}, behaviours: [stop]}]",
    ],
)
def test_damaged_catalogue_in_a_sweep_is_refused(root, tmp_path, damage):
    shutil.copy(SHIPPED_DATA / "artefacts" / "cart.obj", tmp_path / "cart.obj")
    (tmp_path / "broken.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    cat = tmp_path / "catalogue.yaml"
    cat.write_text(damage)
    folder = _damaged(tmp_path)
    cfg = _config(root, folder, catalogue=str(cat))
    with pytest.raises(InputError, match=r"catalogue\.yaml"):
        load_sweep_config(cfg)
    # the same catalogue undamaged is accepted; damaged again in the same process (a
    # notebook), it is refused again: no reader serves an earlier read of an edited file
    good = "classes:\n  - {label: a, mesh: cart.obj, speeds: {walk: 1}, behaviours: [walk]}\n"
    cat.write_text(good)
    assert load_sweep_config(cfg)["catalogue"] == str(cat)
    cat.write_text(damage)
    with pytest.raises(InputError, match=r"catalogue\.yaml"):
        load_sweep_config(cfg)


def test_empty_sections_are_no_sections(root, tmp_path):
    """``factors:`` or ``robot:`` with nothing (or only comments) below is valid YAML for
    "none": it was refused."""
    folder = _damaged(tmp_path)
    path = tmp_path / "sweep.yaml"
    text = yaml.safe_dump(_config(root, folder))
    path.write_text(text + "factors:\n  # planner: [...]\n")
    cfg = load_sweep_config(path)
    assert cfg["factors"] == {}
    path.write_text(text.replace("robot:", "robot_old:") + "robot:\nfactors: {}\n")
    raw = yaml.safe_load(path.read_text())
    del raw["robot_old"]
    path.write_text(yaml.safe_dump(raw))
    assert load_sweep_config(path)["robot"] == {"radius": 0.3, "speed": 0.5}


def test_folder_tracks_move_on_a_turned_map(root, tmp_path):
    """The folder brings its tracks: nothing is rolled out on the map's cells, so a map
    with a turned origin is valid with behaviours (it was refused)."""
    folder = _damaged(tmp_path, tracks=True)
    cfg = _config(root, folder, behaviours=True, map=str(root / "turned.yaml"))
    task = expand_tasks(cfg)[0]
    assert run_task(task)["runs"].iloc[0]["n_move_updates"] > 0
    # without tracks they would be rolled out on the cells: refused
    plain = _damaged(tmp_path)
    with pytest.raises(InputError, match=r"behaviours: expected a map whose origin yaw is 0"):
        load_sweep_config(_config(root, plain, behaviours=True, map=str(root / "turned.yaml")))


VALID = {
    "scenario from the folder": {},
    "folder, time_limit factor": {"factors": {"mission.time_limit": [10.0, HORIZON]}},
    "folder with a trailing slash": {"scenario": "slash"},
    "hand-set rates": {"scenario": {"arrival_rate": 0.001, "leave_rate": 0.1}},
    "rates as integers": {"scenario": {"arrival_rate": 1e-3, "leave_rate": 1}},
    "rates, start factor": {
        "scenario": {"arrival_rate": 0.001, "leave_rate": 0.1},
        "factors": {"scenario.start": ["stationary", "empty"]},
    },
    "shipped catalogue by name": {"catalogue": "catalogue"},
    "catalogue null": {"catalogue": None},
    "behaviours and avoid_robot": {"behaviours": True, "avoid_robot": False},
    "behaviour_cell factor": {"behaviours": True, "factors": {"mission.behaviour_cell": [1, 2]}},
    "camera keys": {
        "robot": {
            "radius": 0.3,
            "speed": 1.0,
            "camera_xyz": [0.1, 0.0, 1.0],
            "camera_rpy": [0, 0, 0],
            "camera_fov": 1.2,
            "image_size": [64, 48],
        },
    },
    "planner factor": {
        "planner": {"algorithm": "RRTConnect", "range": 2.0},
        "factors": {"planner.range": [1.0, 2.0]},
    },
    "planner levels": {
        "factors": {"planner": [{"name": "A*", "algorithm": "astar"}, {"algorithm": "PRM"}]}
    },
    "empty sections": {"robot": None, "factors": None, "planner": None},
}


@pytest.mark.parametrize("over", list(VALID.values()), ids=list(VALID))
def test_documented_shapes_are_accepted(root, tmp_path, over):
    folder = _damaged(tmp_path)
    over = dict(over)
    if over.get("scenario") == "slash":
        over["scenario"] = {"scenarios": str(folder) + "/"}
    cfg = load_sweep_config(_config(root, folder, **over))
    assert cfg["map"] == str(root / "square.yaml")


@pytest.mark.parametrize("name", ["fig7", "fig7_fit"])
def test_shipped_configs_are_accepted(tmp_path, monkeypatch, name):
    raw = load_yaml(shipped_path(name, "experiment"), "sweep config")
    if "fit" in raw["scenario"]:  # the shipped fit config, on a scenarios folder instead
        df = generate_scenarios(3, PARAMS, 3, 90.0, free_mask=OccupancyGrid(np.zeros((4, 4)), 1.0))
        write_scenes(df, tmp_path / "scen", {"generation": {"horizon": 90.0}})
        raw["scenario"] = {"scenarios": "scen"}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert load_sweep_config(path)["name"] == raw["name"]
    if name == "fig7":
        monkeypatch.chdir(tmp_path)
        assert load_sweep_config(name)["name"] == raw["name"]
