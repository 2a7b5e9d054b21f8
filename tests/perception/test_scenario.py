"""Scenario hook, augmented grid of perceived artefacts, sampled sets and pictures."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import jax
import numpy as np
import pandas as pd
import pytest
import trimesh
from scipy import stats

from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.inputs import InputError, LimitError, limits
from are_stats.perception import (
    PerceivedFrame,
    PinholeCamera,
    optical_from_base,
    perceive_frames,
    perceive_scenario,
    perceive_scene,
    perceived_counts,
    perceived_counts_batch,
    perceived_grid,
    plot_camera_view,
    plot_top_view,
    sample_perceived,
    save_figure,
    yaw_rotations,
)
from are_stats.perception._scenario import read_robot_path
from are_stats.scenarios import Scene, scenes_from_tables
from tests.helpers import ALPHA


def _camera():
    return PinholeCamera(60.0, 60.0, 40.0, 30.0, 80, 60, optical_from_base([0.0, 0.0, 0.5]))


@pytest.fixture(scope="module")
def catalogue():
    return load_catalogue()


def _by_hand(cat, table):
    """Boxes of a scenarios table straight from the catalogue rows (DECISIONS 5)."""
    half, centres = [], []
    for _, r in table.iterrows():
        row = cat.select(int(r["class"]), int(r["mark"]))
        off = (row.bounds[0] + row.bounds[1]) / 2
        c, s = np.cos(r["yaw"]), np.sin(r["yaw"])
        half.append(row.half_extents)
        centres.append([r["x"] + c * off[0] - s * off[1], r["y"] + s * off[0] + c * off[1],
                        off[2]])  # fmt: skip
    return np.array(centres), np.array(half)


def test_perceive_scenario_matches_direct_batch(catalogue):
    wall = trimesh.creation.box([0.2, 3.0, 2.0])
    wall.apply_translation([4.0, 0.0, 1.0])  # hides x > 4 near y = 0
    art = pd.DataFrame(
        {
            "scenario": [0, 0, 0, 1],
            "artefact": [0, 1, 2, 0],
            "class": [0, 0, 0, 2],
            "mark": [0, 1, 5, 0],
            "t_arrive": [0.0, 0.0, 5.0, 0.0],
            "t_leave": [10.0, 10.0, 6.0, 1.0],
            "x": [2.0, 6.0, 2.0, 2.5],
            "y": [0.0, 0.0, 0.5, -0.5],
            "yaw": [0.0, 0.3, 1.0, 0.0],
        }
    )
    path = pd.DataFrame({"t": [0.0, 2.0, 4.0], "x": [0.0, 0.0, 0.0], "y": [0.0, 0.0, 0.0],
                         "yaw": [0.0, 0.0, 0.0]})  # fmt: skip
    cam = _camera()
    scenes = scenes_from_tables(art, None, catalogue, None, [0, 1])
    out = perceive_scenario(scenes, path, wall, cam, 20.0, 5)
    assert list(out.columns[: len(art.columns)]) == list(art.columns)
    assert out.index.tolist() == art.index.tolist()  # the table's rows, in order
    # scenario 0 by hand, boxes from the catalogue rows
    centers, half = _by_hand(catalogue, art.iloc[:3])
    poses = np.stack([cam.pose] * 3)
    active = np.array([[True, True, False]] * 3)
    counts, seen = perceived_counts_batch(
        wall, centers, half, yaw_rotations([0.0, 0.3, 1.0]), cam, poses, 20.0, 5, active=active,
    )  # fmt: skip
    s0 = out[out["scenario"] == 0]
    np.testing.assert_array_equal(s0["perceived"], seen.any(axis=0))
    np.testing.assert_array_equal(s0["max_count"], counts.max(axis=0))
    assert s0["perceived"].tolist() == [True, False, False]  # behind the wall / not yet there
    assert out["first_perceived_t"].iloc[0] == 0.0 and np.isnan(out["first_perceived_t"].iloc[1])
    # scenario 1: present only at t = 0
    assert out["n_frames_perceived"].iloc[3] == 1
    # the Scene of scenario 0 alone gives the same flags; a Scene without its table gives
    # its ids, labels and life-cycle
    one = perceive_scenario(scenes[0], path, wall, cam, 20.0, 5)
    pd.testing.assert_frame_equal(one, s0)
    bare = copy.copy(scenes[0])
    bare.artefacts = None
    flags = ["perceived", "n_frames_perceived", "max_count", "first_perceived_t"]
    got = perceive_scenario(bare, path, wall, cam, 20.0, 5)
    assert list(got.columns) == ["artefact", "label", "t_arrive", "t_leave", *flags]
    assert got["artefact"].tolist() == [0, 1, 2]
    assert got["label"].tolist() == scenes[0].labels.tolist() == ["person"] * 3
    pd.testing.assert_frame_equal(got[flags], s0[flags])
    with pytest.raises(ValueError, match="scenes: expected a Scene or a sequence of Scenes"):
        perceive_scenario(art, path, wall, cam, 20.0, 5)
    with pytest.raises(ValueError, match="scenes: expected a Scene or a sequence of Scenes"):
        perceive_scenario([scenes[0], art], path, wall, cam, 20.0, 5)
    with pytest.raises(ValueError, match="robot_path: expected columns"):
        perceive_scenario(scenes, path.drop(columns="t"), wall, cam, 20.0, 5)
    assert len(perceive_scenario([], path, wall, cam, 20.0, 5)) == 0


def _walkers(catalogue):
    """Three artefacts: 0 walks across the view behind a wall's edge, 1 turns on the spot,
    2 stands; the robot drives forward meanwhile."""
    table = pd.DataFrame(
        {
            "artefact": [0, 1, 2],
            "class": [0, 2, 3],
            "mark": [0, 0, 0],
            "t_arrive": [0.0, 1.0, 0.0],
            "t_leave": [20.0, 20.0, 7.0],
            "x": [6.0, 5.0, 7.0],
            "y": [-4.0, 1.5, 2.5],
            "yaw": [1.0, 0.0, 0.0],
        }
    )
    tracks = pd.DataFrame(
        {
            "id": [0, 0, 0, 1, 1],
            "t": [0.0, 4.0, 8.0, 2.0, 6.0],
            "x": [6.0, 6.0, 6.0, 5.0, 5.0],
            "y": [-4.0, 0.0, 4.0, 1.5, 1.5],
            "yaw": [1.0, 1.5, 1.6, 6.0, 0.5],  # 1 turns the short way through 0
        }
    )
    return table, tracks


def test_moving_boxes_equal_static_frames(catalogue):
    wall = trimesh.creation.box([0.2, 2.0, 2.0])
    wall.apply_translation([4.0, -0.5, 1.0])
    table, tracks = _walkers(catalogue)
    scene = Scene.from_scenarios(table, catalogue, tracks)
    cam = _camera()
    times = np.array([0.0, 1.5, 3.0, 4.5, 6.0, 7.5, 9.0])
    base = np.stack([np.eye(4)] * times.size)
    base[:, 0, 3] = 0.1 * times  # the robot drives forward
    poses = base @ cam.pose
    counts, seen = perceive_scene(scene, times, poses, wall, cam, 20.0, 5)
    assert counts.shape == (times.size, 3) and (seen == (counts > 5)).all()
    for i, t in enumerate(times):
        b = scene.at(t)  # the same boxes, perceived as a static scene in this one frame
        still = PinholeCamera(60.0, 60.0, 40.0, 30.0, 80, 60, poses[i])
        c_i, _ = perceived_counts(wall, b.centres, b.half_extents, yaw_rotations(b.yaws), still,
                                  20.0, 5)  # fmt: skip
        want = np.zeros(3, np.int64)
        want[np.searchsorted(scene.ids, b.ids)] = c_i
        np.testing.assert_array_equal(counts[i], want)
    # not vacuous: the walker is hidden, then seen, and the standing box leaves at 7
    assert seen[:, 0].any() and not seen[:, 0].all()
    assert counts[times >= 7.0, 2].sum() == 0 and counts[times < 7.0, 2].any()
    # the table with its tracks, and the Scene, give the same flags
    path = pd.DataFrame({"t": times, "x": 0.1 * times, "y": 0.0, "yaw": 0.0})
    for out in (
        perceive_scenario(scene, path, wall, cam, 20.0, 5),
        perceive_scenario(scenes_from_tables(table, tracks, catalogue), path, wall, cam, 20.0, 5),
    ):
        np.testing.assert_array_equal(out["n_frames_perceived"], seen.sum(axis=0))
        np.testing.assert_array_equal(out["max_count"], counts.max(axis=0))


def test_moving_boxes_shapes_are_checked():
    cam = _camera()
    poses = np.stack([cam.pose] * 2)
    c = np.zeros((3, 1, 3))  # three frames of boxes for two poses
    r = np.broadcast_to(np.eye(3), (3, 1, 3, 3))
    with pytest.raises(ValueError, match=r"centers: expected one box pose per frame, \(T=2"):
        perceived_counts_batch(None, c, [[0.5] * 3], r, cam, poses, 9.0, 4)
    with pytest.raises(ValueError, match=r"rotations: expected shape \(2, 1, 3, 3\)"):
        perceived_counts_batch(None, c[:2], [[0.5] * 3], np.eye(3)[None], cam, poses, 9.0, 4)
    bad = np.array(r[:2])
    bad[1, 0] *= 2.0
    with pytest.raises(ValueError, match="got frame 1, box 0"):
        perceived_counts_batch(None, c[:2], [[0.5] * 3], bad, cam, poses, 9.0, 4)


def test_perceived_grid_marks_only_perceived_footprints():
    grid = OccupancyGrid(np.zeros((20, 30)), 0.1, (-1.0, -1.0, 0.0))
    centers = np.array([[0.0, 0.0, 0.5], [0.5, 0.3, 0.5]])
    half = np.array([[0.2, 0.1, 0.5], [0.15, 0.15, 0.5]])
    out = perceived_grid(grid, centers, half, [0.0, 0.4], np.array([True, False]))
    assert (grid.data == 0).all()  # input untouched
    occ = np.argwhere(out.data == 100)
    # the axis-aligned 0.4 x 0.2 box centred at (0, 0) covers x in [-0.2, 0.2], y in [-0.1, 0.1]:
    # columns 8..11 and rows 9..10 of a grid whose cell (0, 0) starts at (-1, -1)
    assert sorted({int(j) for j in occ[:, 1]}) == [8, 9, 10, 11]
    assert sorted({int(i) for i in occ[:, 0]}) == [9, 10]
    with pytest.raises(ValueError, match="perceived: expected a \\(2,\\) bool array"):
        perceived_grid(grid, centers, half, [0.0, 0.4], [1, 0])


def test_sample_perceived_is_seeded_and_has_the_right_law():
    per = np.ones((400, 50), bool)
    per[:, 0] = False
    key = jax.random.PRNGKey(3)
    a = sample_perceived(key, per, detection_prob=0.3, existence_prob=0.8)
    b = sample_perceived(key, per, detection_prob=0.3, existence_prob=0.8)
    np.testing.assert_array_equal(a, b)
    assert not a[:, 0].any()  # never more than the deterministic set
    exists = a.any(axis=0)[1:]
    # existence: one draw per artefact; detection per frame among existing artefacts
    p_exist = stats.binomtest(int(exists.sum()), exists.size, 0.8).pvalue
    det = a[:, 1:][:, exists]
    p_det = stats.binomtest(int(det.sum()), det.size, 0.3).pvalue
    assert p_exist > ALPHA and p_det > ALPHA  # false-failure rate ALPHA each
    one = sample_perceived(key, np.array([True, True]), detection_prob=[1.0, 0.0])
    assert one.tolist() == [True, False]
    with pytest.raises(ValueError, match="detection_prob: expected values in"):
        sample_perceived(key, per, detection_prob=1.5)


def test_pictures(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    wall = trimesh.creation.box([0.2, 3.0, 2.0])
    wall.apply_translation([4.0, 0.0, 1.0])
    cam = _camera()
    c = np.array([[2.0, 0.0, 0.5], [6.0, 0.0, 0.5], [0.2, 0.0, 0.5]])
    h = np.full((3, 3), 0.3)
    r = yaw_rotations([0.0, 0.5, 0.0])
    res = perceive_frames(wall, c, h, r, cam, None, 20.0, 5, return_depth=True)
    frame = PerceivedFrame.from_result(res, 0, cam, c, h, r, 20.0)
    assert frame.perceived.tolist() == res.perceived[0].tolist()
    fig = plot_camera_view(frame)
    save_figure(fig, tmp_path / "cam.png")
    grid = OccupancyGrid(np.zeros((40, 100)), 0.1, (-1.0, -2.0, 0.0))
    fig2 = plot_top_view(frame, grid=grid)
    save_figure(fig2, tmp_path / "top.png")
    assert (tmp_path / "cam.png").stat().st_size > 1000
    # the pictures read only what CameraModel declares (K, width, height, pose): the same
    # bytes from a camera that has nothing else
    bare = SimpleNamespace(K=cam.K, width=cam.width, height=cam.height, pose=cam.pose)
    declared = frame._replace(camera=bare)
    save_figure(plot_camera_view(declared), tmp_path / "cam_declared.png")
    save_figure(plot_top_view(declared, grid=grid), tmp_path / "top_declared.png")
    for name in ("cam", "top"):
        want = (tmp_path / f"{name}.png").read_bytes()
        assert (tmp_path / f"{name}_declared.png").read_bytes() == want, name
    with pytest.raises(FileExistsError):
        save_figure(fig2, tmp_path / "top.png")
    with pytest.raises(ValueError, match="depth: expected shape"):
        plot_camera_view(frame._replace(depth=frame.depth[:5]))
    with pytest.raises(ValueError, match="return_depth=True"):
        PerceivedFrame.from_result(res._replace(depth=None), 0, cam, c, h, r, 20.0)
    with pytest.raises(ValueError, match=r"t: expected a frame in \[0, 1\), got 1"):
        PerceivedFrame.from_result(res, 1, cam, c, h, r, 20.0)


def test_perceive_scenario_refuses_unsorted_paths_and_runaway_work():
    wall = trimesh.creation.box([0.2, 3.0, 2.0])
    art = pd.DataFrame({"scenario": [0, 1], "class": [0, 0], "t_arrive": [0.0, 0.0],
                        "t_leave": [10.0, 3.0], "x": [2.0, 2.0], "y": [0.0, 0.0],
                        "yaw": [0.0, 0.0]})  # fmt: skip
    scenes = scenes_from_tables(art, None, load_catalogue())
    path = pd.DataFrame({"t": [0.0, 4.0, 2.0], "x": 0.0, "y": 0.0, "yaw": 0.0})
    with pytest.raises(ValueError, match=r"robot_path: row 2: expected times in non-decreasing"):
        perceive_scenario(scenes, path, wall, _camera(), 20.0, 5)
    path = pd.DataFrame({"t": [0.0, 2.0, 4.0], "x": 0.0, "y": 0.0, "yaw": 0.0})
    # frames with an artefact present: 3 in scenario 0, 2 in scenario 1; 80 x 60 pixels each
    with limits(work=5 * 4800 - 1), pytest.raises(LimitError, match="tracing 5 frames of 4800"):
        perceive_scenario(scenes, path, wall, _camera(), 20.0, 5)
    with limits(work=5 * 4800):
        assert len(perceive_scenario(scenes, path, wall, _camera(), 20.0, 5)) == 2


def test_read_robot_path(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("t,x,y,yaw,extra\n0,1,2,0.5,a\n1,1.5,2,0.5,b\n1,2,2,0.5,c\n")
    df = read_robot_path(p)
    assert list(df.columns) == ["t", "x", "y", "yaw"] and df["x"].tolist() == [1.0, 1.5, 2.0]
    p.write_text("t,x,y,yaw\n0,1,2,0.5\n-1,1,2,0.5\n")
    with pytest.raises(InputError, match=r"r.csv: row 2 \(line 3\), column 't': expected times"):
        read_robot_path(p)
    p.write_text("t,x,y,yaw\n0,1,2,0.5\n1,1,2e8,0.5\n")
    with pytest.raises(
        InputError, match=r"row 2 \(line 3\), column 'y': expected a position within"
    ):
        read_robot_path(p)
    with pytest.raises(FileNotFoundError):
        read_robot_path(tmp_path / "none.csv")


def test_check_poses_inside_takes_the_map_else_the_mesh_bounds():
    """The robot's area is the map's cells when there is a map (a mesh given too does not
    widen it), else the mesh's x-y bounds; every pose inside gives no warning, some outside
    a warning naming the first to the last outside, all outside an error."""
    from are_stats.perception import check_poses_inside

    grid = OccupancyGrid(np.zeros((10, 20)), 0.5)  # x in [0, 10), y in [0, 5) m
    mesh = trimesh.creation.box(extents=(40.0, 40.0, 2.0))  # x, y in [-20, 20] m
    xy = [[1.0, 1.0], [12.0, 1.0], [-3.0, 2.0], [30.0, 0.0]]
    got = check_poses_inside("path.csv", xy, grid, mesh, "map.yaml")
    assert got == (
        "3 of 4 robot poses of path.csv lie outside the map map.yaml "
        "(corners [[0.0, 0.0], [10.0, 5.0]]), rows 2 to 4"
    )
    got = check_poses_inside("path.csv", xy, None, mesh)
    assert got == (
        "1 of 4 robot poses of path.csv lie outside the mesh's x-y bounds [-20.0, -20.0] to "
        "[20.0, 20.0], row 4"
    )
    got = check_poses_inside("p.csv", xy, grid, when=lambda i, j: f"at t = {i} to {j} s")
    assert got.endswith("[10.0, 5.0]]), at t = 1 to 3 s")
    assert check_poses_inside("path.csv", xy[:3], None, mesh) is None
    assert check_poses_inside("path.csv", xy[:1], grid, mesh, "map.yaml") is None
    with pytest.raises(InputError) as err:
        check_poses_inside("path.csv", xy[1:], grid, mesh, "map.yaml", field="columns 'x', 'y'")
    assert str(err.value) == (
        "path.csv: columns 'x', 'y': expected robot poses inside the map map.yaml "
        "(corners [[0.0, 0.0], [10.0, 5.0]]), got all 3 outside, the first at "
        "(12.000, 1.000), rows 1 to 3: is the path in the map's frame and metres?"
    )
