"""``perceive`` (:func:`~are_stats.perception.perceive_folder`) refuses a robot path wholly
outside the map, as ``augment`` refuses a trajectory outside its map, naming the path file
and the map; a path partly outside stays a warning (tests/test_cli_perceive_inputs.py)."""

from __future__ import annotations

import pytest
import trimesh
import yaml
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS
from are_stats.inputs import InputError
from are_stats.perception import perceive_folder
from tests.helpers import courtyard_artefacts

runner = CliRunner()
MAP = DEFAULT_MODELS / "courtyard.yaml"
#: Three poses east of the courtyard (x in [-20, 20] m): millimetres read as metres.
AWAY = "t,x,y,yaw\n0,-15000,-10,0.6\n100,-10000,-5,0.6\n200,-5000,0,0.6\n"


def _folder(tmp_path, manifest):
    scen = tmp_path / "scen"
    scen.mkdir()
    courtyard_artefacts().to_parquet(scen / "artefacts.parquet", index=False)
    (scen / "manifest.yaml").write_text(yaml.safe_dump(manifest))
    robot = tmp_path / "robot.csv"
    robot.write_text(AWAY)
    return scen, robot


def test_perceive_refuses_a_path_wholly_outside_the_map(tmp_path):
    """Fails before this change: it warned "3 of 3 robot poses ... lie outside" and wrote a
    table of nothing perceived."""
    scen, robot = _folder(tmp_path, {"map": str(MAP)})
    args = ["perceive", scen, "--camera", "front_camera", "--robot-path", robot]
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())  # rich wraps long paths
    assert f"{robot}: columns 'x', 'y': expected robot poses inside the map {MAP}" in text
    assert "(corners [[-20.0, -15.0], [20.0, 15.0]])" in text
    assert "got all 3 outside, the first at (-15000.000, -10.000)" in text
    assert not (scen / "perceived.parquet").exists()


def test_perceive_refuses_a_path_wholly_outside_the_meshs_bounds(tmp_path):
    """Without a map, the mesh's x-y bounds are the area (as the warning's)."""
    scen, robot = _folder(tmp_path, {})
    mesh = tmp_path / "box.ply"
    trimesh.creation.box(extents=(10.0, 8.0, 2.0)).export(mesh)  # x in [-5, 5], y in [-4, 4]
    with pytest.raises(InputError, match=r"inside the mesh's x-y bounds \[-5.0, -4.0\] to"):
        perceive_folder(scen, "front_camera", robot, mesh=mesh)
    assert not (scen / "perceived.parquet").exists()
