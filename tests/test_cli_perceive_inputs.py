"""``are-stats perceive``: every input (scenario folder, camera, robot path, mesh, options)
gives exit code 2 and a message naming it, never a traceback or a silent wrong answer."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS
from tests.helpers import courtyard_artefacts as _artefacts

runner = CliRunner()
CAMERA = DEFAULT_MODELS / "cameras" / "front_camera.yaml"
ROBOT = "t,x,y,yaw\n0,-15,-10,0.6\n100,-10,-5,0.6\n200,-5,0,0.6\n"


def _folder(tmp_path, df=None, manifest=None, robot=ROBOT):
    scen = tmp_path / "scen"
    scen.mkdir(exist_ok=True)
    (df if df is not None else _artefacts()).to_parquet(scen / "artefacts.parquet", index=False)
    if manifest is None:
        manifest = yaml.safe_dump({"map": str(DEFAULT_MODELS / "courtyard.yaml")})
    (scen / "manifest.yaml").write_text(manifest)
    path = tmp_path / "robot.csv"
    path.write_text(robot)
    return scen, path


def _perceive(scen, robot, *extra, camera=CAMERA):
    args = ["perceive", scen, "--camera", camera, "--robot-path", robot, "--force", *extra]
    return runner.invoke(app, [str(a) for a in args])


def test_perceive_on_a_hand_made_folder(tmp_path):
    scen, robot = _folder(tmp_path)
    res = _perceive(scen, robot, "--tau", "20")
    assert res.exit_code == 0, res.output
    out = pd.read_parquet(scen / "perceived.parquet")
    assert len(out) == 3 and (out["perceived"] == (out["max_count"] > 20)).all()
    assert "warning" not in res.output


@pytest.mark.parametrize(
    ("robot", "match"),
    [
        # an unsorted path silently changed first_perceived_t
        (
            "t,x,y,yaw\n0,-15,-10,0.6\n200,-5,0,0.6\n100,-10,-5,0.6\n",
            r"row 3 \(line 4\), "
            r"column 't': expected times in non-decreasing order \(the row before has t = 200",
        ),
        ("t,x,y,yaw\n0,nan,-10,0.6\n", r"row 1 \(line 2\), column 'x': expected a finite number"),
        ("t,x,y,yaw\n0,inf,-10,0.6\n", r"column 'x': expected a finite number"),
        ("t,x,y,yaw\n0,1e300,-10,0.6\n", r"column 'x': expected a position within 1e\+07 m"),
        ("t,x,y,yaw\n0,True,-10,0.6\n", r"column 'x': expected a number"),
        ("t,x,y,yaw\n0,,-10,0.6\n", r"column 'x': expected a number, got an empty cell"),
        ("t,x,y\n0,1,2\n", r"missing column\(s\) 'yaw'"),
        ("t,x,y,yaw\n", r"empty robot path"),
        # a path whose times miss the scenarios' window answered "0 of 3 perceived"
        (
            "t,x,y,yaw\n1000,-15,-10,0.6\n2000,-10,-5,0.6\n",
            r"robot.csv: column 't': expected "
            r"times within the scenarios' artefact presence \[0, 250\) .*got times 1000 to 2000",
        ),
    ],
)
def test_bad_robot_paths(tmp_path, robot, match):
    scen, path = _folder(tmp_path, robot=robot)
    res = _perceive(scen, path)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert str(path) in res.output
    assert re.search(match, res.output.replace("\n", "")), res.output


def test_robot_path_parquet_booleans_and_directory(tmp_path):
    scen, _ = _folder(tmp_path)
    pq = tmp_path / "robot.parquet"
    pd.DataFrame(
        {"t": [0.0, 1.0], "x": [True, False], "y": [0.0, 0.0], "yaw": [0.0, 0.0]}
    ).to_parquet(pq)
    res = _perceive(scen, pq)
    assert res.exit_code == 2 and "column 'x'" in res.output and "boolean" in res.output
    res = _perceive(scen, tmp_path)
    assert res.exit_code == 2 and "got a directory" in res.output


def test_poses_outside_the_map_are_reported(tmp_path):
    scen, path = _folder(tmp_path, robot="t,x,y,yaw\n0,-15,-10,0.6\n100,500,-5,0.6\n")
    res = _perceive(scen, path)
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())  # rich wraps long paths (a tmp folder under xdist)
    assert "warning: 1 of 2 robot poses" in text and "outside the map" in text
    assert "(corners [[-20.0, -15.0], [20.0, 15.0]]), at t = 100 s (row 2)" in text, text


@pytest.mark.parametrize(
    ("manifest", "df", "match"),
    [
        # an empty manifest, a list or invalid YAML gave AttributeError
        ("", None, r"manifest.yaml: expected a mapping \(a scenarios manifest\), got nothing"),
        ("- 1\n- 2\n", None, r"manifest.yaml: expected a mapping .*got a list"),
        ("map: [\n", None, r"manifest.yaml: expected a scenarios manifest in valid YAML"),
        ("map: 3\n", None, r"manifest.yaml: map: expected a string, got 3"),
        ("map: null\n", None, r"manifest.yaml: map: expected a map for the environment mesh"),
        ("map: nowhere.yaml\n", None, r"manifest.yaml: map: expected an existing ROS map YAML"),
        ("map: m.yaml\nclass_labels: [1]\n", None, r"class_labels\[0\]: expected a string"),
        (
            f"map: {DEFAULT_MODELS / 'courtyard.yaml'}\ngeneration: {{horizon: .nan}}\n",
            None,
            r"manifest.yaml: generation.horizon: expected a finite number",
        ),
        (None, _artefacts().drop(columns="class"), r"missing column\(s\) 'class'"),
        (
            None,
            _artefacts(t_leave=[150.0, 10.0, 120.0]),
            r"row 2, column 't_leave': expected "
            r"t_leave >= t_arrive",
        ),
        (None, _artefacts(x=[np.inf, 0.0, 0.0]), r"row 1, column 'x': expected a finite number"),
        (None, _artefacts(mark=[0, -5, 1]), r"row 2, column 'mark': expected an integer >= -1"),
        (None, _artefacts(scenario=[0.5, 0.0, 1.0]), r"column 'scenario': expected a non-negative"),
        # the ids that behaviour tracks name: a float id reached the Scene as a bare error
        (None, _artefacts(artefact=[0.5, 1.0, 0.0]), r"column 'artefact': expected a non-negative"),
    ],
)
def test_bad_scenario_folders(tmp_path, manifest, df, match):
    scen, robot = _folder(tmp_path, df=df, manifest=manifest)
    res = _perceive(scen, robot)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert re.search(match, res.output.replace("\n", "")), res.output


def test_missing_files_and_options(tmp_path):
    scen, robot = _folder(tmp_path)
    (scen / "artefacts.parquet").write_bytes(b"not parquet")
    res = _perceive(scen, robot)
    assert res.exit_code == 2 and "artefacts.parquet" in res.output
    (scen / "artefacts.parquet").unlink()
    res = _perceive(scen, robot)
    assert res.exit_code == 2 and "no file artefacts.parquet" in res.output
    scen, robot = _folder(tmp_path)
    for opt, value, match in [
        ("--d-max", "0", "--d-max: expected a finite number > 0"),
        ("--d-max", "nan", "--d-max: expected a finite number > 0"),
        ("--tau", "-1", "--tau: expected a finite number >= 0"),
        ("--camera-height", "inf", "--camera-height: expected a finite number"),
    ]:
        res = _perceive(scen, robot, opt, value)
        assert res.exit_code == 2 and match in res.output, res.output
    bad_mesh = tmp_path / "m.obj"
    bad_mesh.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    res = _perceive(scen, robot, "--mesh", bad_mesh)
    assert res.exit_code == 2 and "m.obj: vertex 0: expected finite" in res.output
    cam = tmp_path / "cam.yaml"
    cam.write_text("image_width: 640\nimage_height: 480\nK: [525, 4, 320, 0, 525, 240, 0, 0, 1]\n")
    res = _perceive(scen, robot, camera=cam)
    assert res.exit_code == 2 and "K[0][1] (skew)" in res.output


def test_missing_values_in_the_scenarios_table(tmp_path):
    scen, robot = _folder(tmp_path, df=_artefacts(x=[np.nan, 0.0, 0.0]))
    res = _perceive(scen, robot)
    assert res.exit_code == 2 and "row 1, column 'x': expected a number, got an empty" in res.output


def test_path_between_the_artefacts_is_an_error(tmp_path):
    # inside [min t_arrive, max t_leave) but no artefact present at any pose time
    df = _artefacts(t_arrive=[0.0, 200.0, 0.0], t_leave=[10.0, 250.0, 5.0])
    scen, robot = _folder(tmp_path, df=df, robot="t,x,y,yaw\n50,-15,-10,0\n60,-14,-10,0\n")
    res = _perceive(scen, robot)
    assert res.exit_code == 2 and "no artefact would be seen" in res.output, res.output


def test_classes_missing_from_the_catalogue_are_reported(tmp_path):
    manifest = yaml.safe_dump(
        {"map": str(DEFAULT_MODELS / "courtyard.yaml"), "class_labels": ["forklift", "person"]}
    )
    scen, robot = _folder(tmp_path, manifest=manifest)
    res = _perceive(scen, robot)
    assert res.exit_code == 0, res.output
    assert "classes ['forklift'] of the scenarios are not in the catalogue" in res.output.replace(
        "\n", " "
    )


def _tracks_folder(tmp_path, tracks, spec=None, **manifest):
    manifest = {"map": str(DEFAULT_MODELS / "courtyard.yaml"), **manifest}
    manifest["tracks"] = {"file": "tracks.parquet"} if spec is None else spec
    scen, robot = _folder(tmp_path, manifest=yaml.safe_dump(manifest))
    tracks.to_parquet(scen / "tracks.parquet", index=False)
    return scen, robot


def test_behaviour_tracks_move_the_artefacts(tmp_path):
    scen, robot = _folder(tmp_path)
    res = _perceive(scen, robot, "--tau", "20")
    assert res.exit_code == 0, res.output
    still = pd.read_parquet(scen / "perceived.parquet")
    assert still["perceived"].iloc[0]  # in view where it arrived
    # with a track, artefact 0 of scenario 0 walks off behind the robot before the first pose
    far = pd.DataFrame({"scenario": [0, 0], "id": [0, 0], "t": [-1.0, 300.0],
                        "x": [-40.0, -40.0], "y": [-35.0, -35.0], "yaw": [0.0, 0.0]})  # fmt: skip
    scen, robot = _tracks_folder(tmp_path, far)
    res = _perceive(scen, robot, "--tau", "20")
    assert res.exit_code == 0, res.output
    assert "(1 moving)" in res.output
    moved = pd.read_parquet(scen / "perceived.parquet")
    assert not moved["perceived"].iloc[0] and moved["max_count"].iloc[0] == 0
    # the others stand where they arrived: the same flags as without tracks
    np.testing.assert_array_equal(moved["max_count"].iloc[1:], still["max_count"].iloc[1:])


@pytest.mark.parametrize(
    ("tracks", "spec", "match"),
    [
        (
            pd.DataFrame(
                {"scenario": [0], "id": [7], "t": [0.0], "x": [0.0], "y": [0.0], "yaw": [0.0]}
            ),
            None,
            r"tracks.parquet: row 1, column 'id': expected an artefact of scenario 0 in "
            r"artefacts.parquet, got 7",
        ),
        (
            pd.DataFrame(
                {
                    "scenario": [0, 0],
                    "id": [1, 1],
                    "t": [60.0, 60.0],
                    "x": [0.0, 1.0],
                    "y": [0.0, 0.0],
                    "yaw": [0.0, 0.0],
                }
            ),
            None,
            r"row 2, column 't': expected one pose per artefact and time",
        ),
        (
            pd.DataFrame(
                {"scenario": [0], "id": [0], "t": [0.0], "x": [np.nan], "y": [0.0], "yaw": [0.0]}
            ),
            None,
            r"tracks.parquet: row 1, column 'x'",
        ),
        (pd.DataFrame({"scenario": [0]}), "tracks.parquet", r"tracks: expected a mapping"),
        (pd.DataFrame({"scenario": [0]}), {"file": "none.parquet"}, r"no file none.parquet"),
        (pd.DataFrame({"scenario": [0]}), {"file": "../x.parquet"}, r"a file name inside"),
    ],
)
def test_bad_behaviour_tracks(tmp_path, tracks, spec, match):
    scen, robot = _tracks_folder(tmp_path, tracks, spec)
    res = _perceive(scen, robot)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert re.search(match, res.output.replace("\n", "")), res.output


def test_path_outside_the_scenario_window_is_an_error(tmp_path):
    # an artefact still present after the horizon used to be "perceived" by a path that
    # starts after the scenario ended
    df = _artefacts(t_leave=[150.0, 250.0, 5000.0])
    manifest = yaml.safe_dump(
        {"map": str(DEFAULT_MODELS / "courtyard.yaml"), "generation": {"horizon": 300.0}}
    )
    robot = "t,x,y,yaw\n400,-15,-10,0.6\n500,-10,-5,0.6\n"
    scen, path = _folder(tmp_path, df=df, manifest=manifest, robot=robot)
    res = _perceive(scen, path)
    assert res.exit_code == 2, res.output
    text = res.output.replace("\n", "")
    assert str(path) in text
    assert re.search(r"expected times overlapping the scenario window \[0, 300\].*got times "
                     r"400 to 500: no artefact would be seen", text), res.output  # fmt: skip


def test_duplicate_artefact_ids_are_named(tmp_path):
    scen, robot = _folder(tmp_path, df=_artefacts(artefact=np.array([0, 0, 0], np.int32)))
    res = _perceive(scen, robot)
    assert res.exit_code == 2
    assert "row 2, column 'artefact': expected artefact ids unique" in res.output.replace("\n", "")
