"""perceive_folder: a scenarios folder perceived along a robot path, inputs checked first."""

from __future__ import annotations

import inspect
import warnings
from typing import get_type_hints

import pandas as pd
import pytest
import yaml

from are_stats.environment import DEFAULT_MODELS, environment_mesh, load_catalogue, read_map
from are_stats.inputs import InputError
from are_stats.perception import (
    FolderPlan,
    PerceiveFolderOptions,
    camera_mount,
    perceive_folder,
    perceive_scenario,
    read_camera,
    read_robot_path,
)
from are_stats.scenarios import read_scenes, scenes_from_tables
from tests.helpers import courtyard_artefacts

CAMERA = DEFAULT_MODELS / "cameras" / "front_camera.yaml"
# the last pose lies outside the courtyard map: a warning, not an error
ROBOT = "t,x,y,yaw\n0,-15,-10,0.6\n100,-10,-5,0.6\n200,500,0,0.6\n"


def _folder(tmp_path):
    scen = tmp_path / "scen"
    scen.mkdir()
    courtyard_artefacts().to_parquet(scen / "artefacts.parquet", index=False)
    (scen / "manifest.yaml").write_text(
        yaml.safe_dump({"map": str(DEFAULT_MODELS / "courtyard.yaml")})
    )
    robot = tmp_path / "robot.csv"
    robot.write_text(ROBOT)
    return scen, robot


def test_perceive_folder_is_perceive_scenario_on_the_folder_and_writes_it(tmp_path):
    scen, robot = _folder(tmp_path)
    plans = []
    path, res = perceive_folder(scen, "front_camera", robot, tau=20.0, on_start=plans.append)
    # the plan: what the folder and the path hold, and the pose outside the map
    assert len(plans) == 1 and isinstance(plans[0], FolderPlan)
    assert plans[0][:3] == (3, 0, 3)
    assert len(plans[0].warnings) == 1 and "1 of 3 robot poses" in plans[0].warnings[0]
    assert path == scen / "perceived.parquet"
    pd.testing.assert_frame_equal(pd.read_parquet(path), res.reset_index(drop=True))
    # the same flags as the steps done by hand: the folder's scenes, the shipped camera
    # mounted 1 m above the base, the map's walls 2.5 m high
    folder = read_scenes(scen)
    cat = load_catalogue()
    cam = read_camera(CAMERA)
    scenes = scenes_from_tables(folder.artefacts, None, cat, None, [0, 1])
    env = environment_mesh(read_map(DEFAULT_MODELS / "courtyard.yaml")[1], 2.5)
    want = perceive_scenario(
        scenes, read_robot_path(robot), env, cam, 30.0, 20.0, mount=camera_mount(cam.pose, 1.0)
    )
    pd.testing.assert_frame_equal(res, want.loc[folder.artefacts.index])
    assert (res["perceived"] == (res["max_count"] > 20)).all()


def test_perceive_folder_warns_without_on_start_and_keeps_an_existing_output(tmp_path):
    scen, robot = _folder(tmp_path)
    with pytest.warns(UserWarning, match="robot poses of .*robot.csv lie outside the map"):
        perceive_folder(scen, CAMERA, robot, d_max=5.0)
    before = (scen / "perceived.parquet").read_bytes()
    with pytest.raises(FileExistsError, match="already exists"), warnings.catch_warnings():
        warnings.simplefilter("error")  # refused before anything is read or warned
        perceive_folder(scen, CAMERA, robot, d_max=5.0)
    assert (scen / "perceived.parquet").read_bytes() == before
    with pytest.raises(InputError, match="--tau: expected a finite number >= 0"):
        perceive_folder(scen, CAMERA, robot, tau=-1.0, force=True)


def test_perceive_folder_options_are_its_keywords():
    """PerceiveFolderOptions (the job's ``**options``) names perceive_folder's keywords, but
    on_start, with their types: a keyword added to one is added to the other."""
    hints = get_type_hints(perceive_folder)
    params = inspect.signature(perceive_folder).parameters.values()
    keywords = [p.name for p in params if p.kind is p.KEYWORD_ONLY and p.name != "on_start"]
    assert list(PerceiveFolderOptions.__annotations__) == keywords
    assert get_type_hints(PerceiveFolderOptions) == {k: hints[k] for k in keywords}
