"""The top-down view of an MCAP (``are-stats show OUT.mcap``): what it reads is what the
mission wrote, checked against the mission's own trace."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.experiments import run_mission
from are_stats.export import export_mcap, plot_mcap, read_view
from are_stats.inputs import InputError
from are_stats.scenarios import Scene

runner = CliRunner()


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    d = tmp_path_factory.mktemp("view")
    grid = OccupancyGrid(np.zeros((40, 60)), 0.5, (1.0, -2.0, 0.0))
    art = pd.DataFrame(
        [
            [0.0, 8.0, 10.0, 3.0, 0.3, 0],
            [0.0, 60.0, 20.0, 12.0, 0.0, 3],
            [5.0, 60.0, 6.0, 14.0, 1.0, 1],
        ],
        columns=["t_arrive", "t_leave", "x", "y", "yaw", "mark"],
    )
    scene = Scene.from_scenarios(art, load_catalogue())
    res = run_mission(grid, scene, [[28.0, 6.0], [4.0, 14.0]], "astar", record=True, time_limit=60)
    return grid, res, export_mcap(d / "run.mcap", grid, res.trace)


def test_view_reads_back_the_scene_of_the_mission(mission):
    grid, res, path = mission
    for sc in res.trace.scenes:
        v = read_view(path, float(sc["t"]))
        assert v.t == pytest.approx(float(sc["t"]), abs=1e-6)
        np.testing.assert_array_equal(v.grid.data, grid.data)
        np.testing.assert_allclose(v.grid.origin, grid.origin)
        order = np.argsort(v.boxes[:, 0])
        want = np.argsort(sc["centres"][:, 0])
        np.testing.assert_allclose(v.boxes[order, :2], sc["centres"][want, :2], atol=1e-9)
        np.testing.assert_allclose(v.boxes[order, 3:5], 2 * sc["half"][want, :2], atol=1e-9)
        np.testing.assert_array_equal(v.perceived[order], sc["perceived"][want])
        assert all(lab.split()[0] in set(sc["labels"]) for lab in v.labels)
        # /augmented_map: the live boxes' cells on the map
        assert (v.augmented.data == 100).sum() > 0
    # the robot from /tf map -> base_link, at the last pose at or before the time asked
    p = res.trace.poses
    t = float(p[len(p) // 2, 0])
    v = read_view(path, t)
    k = np.searchsorted(p[:, 0], t, side="right") - 1
    np.testing.assert_allclose(v.pose[:2], p[k, 1:3], atol=1e-6)
    assert v.path.shape[0] >= 2 and v.camera.shape == (3, 2)


def test_show_draws_the_view_and_refuses_bad_input(mission, tmp_path):
    _, res, path = mission
    out = tmp_path / "view.png"
    r = runner.invoke(app, ["show", str(path), "--out", str(out), "--at", "3"])
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = runner.invoke(app, ["show", str(path), "--out", str(out), "--at", "3"])
    assert r.exit_code == 2 and "--force" in r.output  # never overwritten silently
    r = runner.invoke(app, ["show", str(path), "--out", str(tmp_path / "x.png"), "--at", "1e6"])
    assert r.exit_code == 2 and "--at" in r.output and "Traceback" not in r.output
    assert plot_mcap(path, tmp_path / "default.png").is_file()


def test_a_bag_without_a_map_is_refused(tmp_path):
    from tests.export.rosbag_fixtures import write_bag

    bag = write_bag(tmp_path / "robot", "mcap")
    with pytest.raises(InputError, match="/map"):
        read_view(bag)


def test_a_slam_bag_is_drawn_on_its_last_map(tmp_path):
    """A SLAM bag publishes its map as it grows: the view draws the last ``/map`` (the
    finished map, the one ``augment`` checks ``--map`` against) and says which. Fails
    before this change: it drew the first."""
    from tests.export.test_augment_nav2 import _edited, _grid, write_nav2_bag

    first, last = _grid(), _edited(_grid())
    bag = write_nav2_bag(tmp_path / "slam", "mcap", maps=[first, last])
    v = read_view(bag)
    np.testing.assert_array_equal(v.grid.data, last.data)
    assert (v.n_maps, v.map_t) == (2, pytest.approx(1.0))  # a second apart from t = 0
    out = plot_mcap(bag, tmp_path / "slam.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
