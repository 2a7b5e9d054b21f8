"""Artefacts that avoid the robot (issue 15): a pedestrian detours around a robot standing
or driving on its track, waits when walled in, never meets the robot, a wall or another
box; with ``avoid_robot=False`` the artefacts ignore the robot as before."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from are_stats import Scene
from are_stats.environment import ArtefactCatalogue, ArtefactClass, OccupancyGrid
from are_stats.experiments import Robot, run_mission
from are_stats.experiments._avoid import plan_avoidance

#: one class: a 0.6 m x 0.6 m pedestrian centred on its pose
CATALOGUE = ArtefactCatalogue([
    ArtefactClass(
        label="person", row=0, mesh_path=Path("person.ply"),
        bounds=np.array([[-0.3, -0.3, 0.0], [0.3, 0.3, 1.7]]), speeds={"walk": 1.0},
        behaviours=("walk", "stop"),
    )
])  # fmt: skip
HALF = 0.3
OPEN = OccupancyGrid(np.zeros((100, 100)), 0.2)  # 20 m x 20 m, nothing in it
ROBOT = Robot(radius=0.3, speed=0.5)
COLS = ["t_arrive", "t_leave", "x", "y", "yaw", "mark"]
KEYS = ["artefact_contacts", "collisions", "n_detours", "n_yields", "avoid_delay"]


def _never(free, start, goal, params):  # a planner that finds nothing: the robot stands
    return None


def _north(t_leave=60.0):
    """A pedestrian walking north along x = 10 from y = 2 to y = 18 at 1 m/s (epochs 1 s
    apart), through (10, 10) at t = 8."""
    t = np.arange(0.0, 17.0)
    tracks = pd.DataFrame({"id": 0, "t": t, "x": 10.0, "y": 2.0 + t, "yaw": np.pi / 2})
    return pd.DataFrame([[0.0, t_leave, 10.0, 2.0, np.pi / 2, 0]], columns=COLS), tracks


def _box_points(centre, yaw, half=HALF, n=13):
    """(n*n, 2) points filling a box (sampled by hand, independent of the package)."""
    u = np.linspace(-half, half, n)
    a, b = (g.ravel() for g in np.meshgrid(u, u))
    c, s = np.cos(yaw), np.sin(yaw)
    return np.column_stack([centre[0] + c * a - s * b, centre[1] + s * a + c * b])


def _robot_xy(trace, t):
    p = trace.poses
    return np.array([np.interp(t, p[:, 0], p[:, 1]), np.interp(t, p[:, 0], p[:, 2])])


def _first_time_at(trace, art_id, xy):
    for sc in trace.scenes:
        k = np.flatnonzero(sc["ids"] == art_id)
        if k.size and np.allclose(sc["centres"][k[0], :2], xy, atol=1e-9):
            return sc["t"]
    return np.inf


def test_pedestrian_detours_around_a_standing_robot_and_arrives_later():
    art, tracks = _north()
    scene = _scene(tracks, art)
    kw = dict(robot=ROBOT, start=[10.0, 10.0, 0.0], time_limit=30.0, record=True)  # fmt: skip
    off = run_mission(OPEN, scene, [[15.0, 15.0]], _never, avoid_robot=False, **kw)
    assert off.summary["artefact_contacts"] == 1  # it walks into the robot, as before
    assert off.summary["n_detours"] == off.summary["n_yields"] == 0
    assert _first_time_at(off.trace, 0, [10.0, 18.0]) == 16.0
    on = run_mission(OPEN, scene, [[15.0, 15.0]], _never, **kw)
    s = on.summary
    assert s["artefact_contacts"] == 0 and s["collisions"] == 0 and s["n_detours"] >= 1
    assert (on.timeline["kind"] == "move+detour").sum() == s["n_detours"]
    # it reaches the end of its track later, by the delay its detour added
    t_end = _first_time_at(on.trace, 0, [10.0, 18.0])
    assert s["avoid_delay"] > 0 and t_end == pytest.approx(16.0 + s["avoid_delay"])
    # independent truth: the box (sampled by hand) never comes within the robot's radius
    for sc in on.trace.scenes:
        pts = _box_points(sc["centres"][0, :2], sc["yaws"][0])
        assert np.linalg.norm(pts - [10.0, 10.0], axis=1).min() > ROBOT.radius
    # it left its straight line (a detour, not a wait)
    assert max(abs(sc["centres"][0, 0] - 10.0) for sc in on.trace.scenes) > 0.5


def test_pedestrian_overtaking_a_driving_robot_goes_round_it():
    """The robot drives east at 0.25 m/s; the pedestrian walks along the same line at 1 m/s
    from behind it (its track crosses the robot's footprint)."""
    slow = Robot(radius=0.3, speed=0.25)
    t = np.arange(0.0, 19.0)
    behind = pd.DataFrame({"id": 0, "t": t, "x": 0.5 + t, "y": 10.0, "yaw": 0.0})
    art = pd.DataFrame([[0.0, 25.0, 0.5, 10.0, 0.0, 0]], columns=COLS)
    scene = _scene(behind, art)
    kw = dict(robot=slow, start=[4.0, 10.0, 0.0], time_limit=60.0, record=True)  # fmt: skip
    off = run_mission(OPEN, scene, [[16.0, 10.0]], "astar", avoid_robot=False, **kw)
    assert off.summary["artefact_contacts"] == 1
    on = run_mission(OPEN, scene, [[16.0, 10.0]], "astar", **kw)
    s = on.summary
    assert s["artefact_contacts"] == 0 and s["collisions"] == 0 and s["goals_reached"] == 1
    assert s["n_detours"] + s["n_yields"] >= 1 and s["avoid_delay"] > 0
    assert on.timeline["kind"].str.contains("detour|yield").any()
    assert _first_time_at(on.trace, 0, [18.5, 10.0]) == pytest.approx(18.0 + s["avoid_delay"])
    for sc in on.trace.scenes:
        k = np.flatnonzero(sc["ids"] == 0)
        if k.size:
            pts = _box_points(sc["centres"][k[0], :2], sc["yaws"][k[0]])
            gap = np.linalg.norm(pts - _robot_xy(on.trace, sc["t"]), axis=1).min()
            assert gap > slow.radius


def test_detour_keeps_clear_of_another_artefact():
    """A second pedestrian stands just east of the robot: the walker goes round the west
    side and never overlaps it (boxes sampled by hand)."""
    art, tracks = _north()
    art = pd.concat([art, pd.DataFrame([[0.0, 60.0, 10.9, 10.0, 0.0, 0]], columns=COLS)])
    art["artefact"] = [0, 1]
    res = run_mission(OPEN, _scene(tracks, art), [[15.0, 15.0]], _never, robot=ROBOT,
                      start=[10.0, 10.0, 0.0], time_limit=30.0, record=True)  # fmt: skip
    assert res.summary["artefact_contacts"] == 0 and res.summary["n_detours"] >= 1
    xs = []
    for sc in res.trace.scenes:
        walker = _box_points(sc["centres"][0, :2], sc["yaws"][0])
        still = _box_points(sc["centres"][1, :2], sc["yaws"][1])
        # two 0.6 m squares overlap only if some sampled points come closer than a sample step
        gap = np.linalg.norm(walker[:, None] - still[None], axis=2).min()
        assert gap > 0.05
        xs.append(sc["centres"][0, 0])
    assert min(xs) < 9.5  # round the west side


# moves on a 0.1 s / 0.7 s clock: k * p / p can round above k, and the wait must still end
# on the tick that checks it again
@pytest.mark.parametrize("move_period", [None, 0.1, 0.7])
def test_walled_in_pedestrian_waits_and_never_meets_the_robot_or_a_wall(move_period):
    data = np.full((100, 100), 100)
    data[:, 47:53] = 0  # a corridor x in [9.4, 10.6): no way round a robot standing in it
    grid = OccupancyGrid(data, 0.2)
    art, tracks = _north()
    scene = _scene(tracks, art)
    kw = dict(robot=ROBOT, start=[10.0, 10.0, 0.0], time_limit=30.0, record=True,
              move_period=move_period)  # fmt: skip
    off = run_mission(grid, scene, [[10.0, 15.0]], _never, avoid_robot=False, **kw)
    assert off.summary["artefact_contacts"] == 1
    on = run_mission(grid, scene, [[10.0, 15.0]], _never, **kw)
    s = on.summary
    assert s["artefact_contacts"] == 0 and s["n_detours"] == 0 and s["n_yields"] > 5
    assert (on.timeline["kind"] == "move+yield").sum() == s["n_yields"]
    ys = []
    for sc in on.trace.scenes:
        pts = _box_points(sc["centres"][0, :2], sc["yaws"][0])
        assert np.linalg.norm(pts - [10.0, 10.0], axis=1).min() > ROBOT.radius
        ij = grid.world_to_cell(pts)
        assert (grid.data[ij[:, 0], ij[:, 1]] == 0).all()  # inside the corridor
        ys.append(sc["centres"][0, 1])
    # it stops short of the robot (box edge at least radius + margin from its centre) and
    # stays there: the rest of its track waits
    assert max(ys) <= 10.0 - ROBOT.radius - 0.2 - HALF + 1e-9
    assert max(ys) > 10.0 - ROBOT.radius - 0.2 - HALF - 0.2


def _scene(tracks, art):
    return Scene.from_scenarios(art, CATALOGUE, tracks)


def test_plan_avoidance_none_when_clear_and_closed_form_yield():
    art, tracks = _north()
    scene = _scene(tracks, art)
    wall = OPEN.distance_to_occupied()
    # robot far east: nothing to do; robot behind the walker: it walks away, nothing to do
    assert plan_avoidance(scene, 0, 7.0, 8.0, [15.0, 10.0], 0.5, OPEN, wall) is None
    assert plan_avoidance(scene, 0, 7.0, 8.0, [10.0, 8.0], 0.5, OPEN, wall) is None
    # corridor: no detour; it stops at the last sample (spaced 1/9 m, ds = 0.125) whose box
    # edge keeps 0.5 m from the robot at (10, 10): y = 9 + 1/9, and waits until t = 8
    data = np.full((100, 100), 100)
    data[:, 47:53] = 0
    grid = OccupancyGrid(data, 0.2)
    got = plan_avoidance(scene, 0, 7.0, 8.0, [10.0, 10.0], 0.5, grid, grid.distance_to_occupied())
    assert got is not None and got.kind == "yield"
    t_stop = 7.0 + 1.0 / 9.0
    assert got.delay == pytest.approx(8.0 - t_stop)
    i = int(np.searchsorted(got.t, t_stop - 1e-9))
    np.testing.assert_allclose(got.t[i : i + 2], [t_stop, 8.0])
    np.testing.assert_allclose(got.pose[i : i + 2, :2], [[10.0, 9.0 + 1 / 9]] * 2)
    # the rest of the track: the same poses, later by the delay
    np.testing.assert_allclose(got.t[i + 2 :], np.arange(8.0, 17.0) + got.delay)
    np.testing.assert_allclose(got.pose[i + 2 :, 1], 2.0 + np.arange(8.0, 17.0))
    # the epochs before now are untouched
    np.testing.assert_allclose(got.t[:i], np.arange(0.0, 7.0 + 1e-9))


def test_plan_avoidance_detour_rejoins_its_track_late():
    art, tracks = _north()
    scene = _scene(tracks, art)
    got = plan_avoidance(scene, 0, 7.0, 8.0, [10.0, 10.0], 0.5, OPEN, OPEN.distance_to_occupied())
    assert got is not None and got.kind == "detour" and got.delay > 0
    # from the rejoin epoch on: the original epochs, later by the delay
    tail = got.t > 7.0 + 1e-9
    t_new, p_new = got.t[tail], got.pose[tail]
    n = int(np.sum(np.isclose(p_new[:, 0], 10.0) & (p_new[:, 1] > 10.0)))
    np.testing.assert_allclose(t_new[-n:], np.arange(17.0 - n, 17.0) + got.delay)
    # the detour's vertices keep the box clear of the robot's disc plus margin
    off = np.abs(p_new[:-n, :2] - [10.0, 10.0]) - HALF
    assert (np.linalg.norm(np.maximum(off, 0.0), axis=1) >= 0.5 - 1e-9).all()


def test_detour_by_a_wall_keeps_the_box_inside_the_corridor():
    """A 3 m corridor; the robot stands 0.7 m from its east wall in the way of a walker a
    little east of it: the shorter way round is east, through the wall; it goes west, and
    its box never covers a wall cell (sampled by hand)."""
    data = np.full((100, 100), 100)
    data[:, 40:55] = 0  # x in [8.0, 11.0)
    grid = OccupancyGrid(data, 0.2)
    art, tracks = _north()
    art, tracks = art.assign(x=10.5), tracks.assign(x=10.5)
    res = run_mission(grid, _scene(tracks, art), [[10.0, 15.0]], _never, robot=ROBOT,
                      start=[10.3, 10.0, 0.0], time_limit=30.0, record=True)  # fmt: skip
    assert res.summary["artefact_contacts"] == 0 and res.summary["n_detours"] >= 1
    xs = []
    for sc in res.trace.scenes:
        pts = _box_points(sc["centres"][0, :2], sc["yaws"][0])
        ij = grid.world_to_cell(pts)
        assert (grid.data[ij[:, 0], ij[:, 1]] == 0).all()
        assert np.linalg.norm(pts - [10.3, 10.0], axis=1).min() > ROBOT.radius
        xs.append(sc["centres"][0, 0])
    assert min(xs) <= 10.3 - 0.5 - HALF + 1e-9 and max(xs) == 10.5  # west, never east


def test_clear_of_walls_against_sampled_boxes():
    from are_stats.experiments._avoid import _clear_of_walls

    rng = np.random.default_rng(5)
    data = np.where(rng.random((30, 30)) < 0.05, 100, 0)
    data[3, :] = -1  # unknown cells count as walls too
    grid = OccupancyGrid(data, 0.2)
    u = np.linspace(-1.0, 1.0, 41)
    a, b = (g.ravel() for g in np.meshgrid(u, u))
    n_hit = 0
    for _ in range(300):
        c, half, yaw = rng.uniform(1.0, 5.0, 2), rng.uniform(0.05, 0.6, 2), rng.uniform(0, 7)

        def sampled(h, c=c, yaw=yaw):
            x, y = a * h[0], b * h[1]
            pts = c + np.column_stack([np.cos(yaw) * x - np.sin(yaw) * y,
                                       np.sin(yaw) * x + np.cos(yaw) * y])  # fmt: skip
            ij = grid.world_to_cell(pts)
            ij = ij[grid.in_bounds(ij)]
            return bool((grid.data[ij[:, 0], ij[:, 1]] != 0).any())

        clear = _clear_of_walls(grid, c[None], half, np.array([yaw]))
        assert not (clear and sampled(half - 0.01))  # a wall cell inside: not clear
        assert clear or sampled(half + 0.02)  # not clear: a wall cell at the edge at most
        n_hit += not clear
    assert 30 < n_hit < 270  # both answers were checked


def test_plan_avoidance_sees_where_the_robot_drives():
    """The robot is 2 m east of the walker's line now, driving west at 2 m/s: it will be on
    the line when the walker gets there. Standing where it is, it would be no obstacle."""
    art, tracks = _north()
    scene = _scene(tracks, art)
    wall = OPEN.distance_to_occupied()
    robot = ([7.0, 8.0], [[12.0, 10.0], [10.0, 10.0]])
    assert plan_avoidance(scene, 0, 7.0, 8.0, [12.0, 10.0], 0.5, OPEN, wall) is None
    got = plan_avoidance(scene, 0, 7.0, 8.0, [12.0, 10.0], 0.5, OPEN, wall, robot_track=robot)
    assert got is not None and got.delay > 0
    # a robot driving away from the walker's way is no obstacle either
    away = ([7.0, 8.0], [[12.0, 10.0], [14.0, 10.0]])
    assert (
        plan_avoidance(scene, 0, 7.0, 8.0, [12.0, 10.0], 0.5, OPEN, wall, robot_track=away) is None
    )


def test_motion_samples_equal_the_scene_poses():
    from are_stats.experiments._avoid import _sample

    rng = np.random.default_rng(0)
    t = np.r_[0.0, np.sort(rng.uniform(0, 20, 11))]
    tr = pd.DataFrame({"id": 0, "t": t, "x": rng.uniform(0, 5, 12), "y": rng.uniform(0, 5, 12),
                       "yaw": rng.uniform(0, 7, 12)})  # fmt: skip
    scene = _scene(tr, pd.DataFrame([[0.0, 60.0, 1.0, 1.0, 0.0, 0]], columns=COLS))
    times, pose, _ = _sample(scene, 0, 0.5, 25.0, 0.2)
    ref = np.array([scene.poses(u, [0])[0] for u in times])
    np.testing.assert_allclose(pose[:, :2], ref[:, :2], atol=1e-12)
    turn = np.mod(pose[:, 2] - ref[:, 2] + np.pi, 2 * np.pi) - np.pi
    np.testing.assert_allclose(turn, 0.0, atol=1e-12)
    assert np.linalg.norm(np.diff(pose[:, :2], axis=0), axis=1).max() <= 0.2 + 1e-12


#: the robot's goals in the replan mission: two it can reach, then one it cannot
REPLAN_GOALS = np.array([[11.5, 10.0], [10.0, 10.0], [18.0, 18.0]])


def _two_goals_then_none(free, start, goal, params):
    """A planner that drives straight at its first two goals and finds no way to the last:
    the robot waits at the second, on the walker's line."""
    if np.allclose(goal, REPLAN_GOALS[2] - OPEN.origin[:2], atol=0.3):
        return None
    return np.vstack([start, goal])


def test_walker_decides_again_when_the_robot_replans_into_its_way():
    """A walker checks the robot every 4 s (north at 1 m/s along x = 10). At t = 4 the
    robot's plan keeps it at (11.5, 10), clear of the walker's line; at t = 4.5 it reaches
    that goal and replans to (10, 10), where it waits from t = 6: the walker, deciding only
    at t = 8, would walk into it (at t = 7.4); it must decide again at the replan."""
    t = np.arange(0.0, 17.0, 4.0)
    tracks = pd.DataFrame({"id": 0, "t": t, "x": 10.0, "y": 2.0 + t, "yaw": np.pi / 2})
    art = pd.DataFrame([[0.0, 60.0, 10.0, 2.0, np.pi / 2, 0]], columns=COLS)
    robot = Robot(radius=0.3, speed=1.0)
    scene = _scene(tracks, art)
    kw = dict(robot=robot, start=[16.0, 10.0, np.pi], time_limit=20.0, record=True)  # fmt: skip
    off = run_mission(OPEN, scene, REPLAN_GOALS, _two_goals_then_none, avoid_robot=False, **kw)
    assert off.summary["artefact_contacts"] == 1
    on = run_mission(OPEN, scene, REPLAN_GOALS, _two_goals_then_none, **kw)
    s = on.summary
    assert s["goals_reached"] == 2 and s["artefact_contacts"] == 0 and s["collisions"] == 0
    # at t = 4 the walker had nothing to avoid; the replan at 4.5 made it detour
    kinds = on.timeline.set_index("t")["kind"]
    assert kinds[4.0] == "move" and kinds[4.5] == "replan+detour"
    assert s["n_detours"] == 1 and s["n_yields"] == 0 and s["avoid_delay"] > 0
    assert s["n_updates"] == len(on.timeline) - 1
    # independent truth at every update: the box (sampled by hand) against the robot
    for sc in on.trace.scenes:
        pts = _box_points(sc["centres"][0, :2], sc["yaws"][0])
        assert np.linalg.norm(pts - _robot_xy(on.trace, sc["t"]), axis=1).min() > robot.radius
    # it went round the robot's west or east side and reached its track's end late
    assert max(abs(sc["centres"][0, 0] - 10.0) for sc in on.trace.scenes) > 0.5
    assert _first_time_at(on.trace, 0, [10.0, 18.0]) == pytest.approx(16.0 + s["avoid_delay"])
    # deterministic: the same mission gives the same result
    again = run_mission(OPEN, scene, REPLAN_GOALS, _two_goals_then_none, **kw)
    wall = {"rho_mean", "rho_t_mean"}  # measured on the wall clock
    assert {k: v for k, v in again.summary.items() if k not in wall} == {
        k: v for k, v in s.items() if k not in wall
    }
    pd.testing.assert_frame_equal(again.timeline, on.timeline)
    np.testing.assert_array_equal(again.trace.poses, on.trace.poses)


def _same_motion_until(old, new, t_end):
    """The two scenes put artefact 0 at the same pose at every instant up to ``t_end``."""
    for u in np.linspace(0.0, t_end, 97):
        np.testing.assert_allclose(new.poses(u, [0]), old.poses(u, [0]), atol=1e-9)


def test_plan_avoidance_between_epochs_yields_in_closed_form():
    """Now is between the walker's epochs 8 and 9 (a replan): at t = 8.3 it is at y = 10.3;
    the robot at (10, 11.55), clearance 0.5, in a corridor. Motion samples 0.1 m apart
    (ds = 0.125 m, 0.7 m to go): the first whose box edge comes within 0.5 m is y = 10.8,
    so it stops at y = 10.7 (t = 8.7) and waits until its next epoch, t = 9."""
    art, tracks = _north()
    scene = _scene(tracks, art)
    data = np.full((100, 100), 100)
    data[:, 47:53] = 0
    grid = OccupancyGrid(data, 0.2)
    wall = grid.distance_to_occupied()
    got = plan_avoidance(scene, 0, 8.3, 9.0, [10.0, 11.55], 0.5, grid, wall)
    assert got is not None and got.kind == "yield"
    assert got.delay == pytest.approx(0.3)
    # epochs 0..8 untouched, then now, the stop, the end of the wait, the rest 0.3 s late
    np.testing.assert_allclose(
        got.t, np.r_[np.arange(0.0, 9.0), 8.3, 8.7, 9.0, np.arange(9.0, 17.0) + 0.3]
    )
    y = np.r_[2.0 + np.arange(0.0, 9.0), 10.3, 10.7, 10.7, 2.0 + np.arange(9.0, 17.0)]
    np.testing.assert_allclose(got.pose[:, 1], y)
    np.testing.assert_allclose(got.pose[:, 0], 10.0)
    # it goes on from where it is now: the same motion up to t = 8.3
    new = scene.with_track(0, got.t, got.pose)
    _same_motion_until(scene, new, 8.3)
    # until the loop checks it again (t = 9) its box's edge keeps 0.5 m from the robot
    for u in np.linspace(8.3, 9.0, 41):
        assert new.poses(u, [0])[0, 1] + HALF <= 11.55 - 0.5 + 1e-9


def test_plan_avoidance_between_epochs_detours_from_where_it_is():
    """The robot stands at (10, 10.5) on the open map; decided at t = 7.5 (between epochs 7
    and 8, the walker at y = 9.5, its box 0.7 m from the robot): the detour starts at the
    walker's pose now, keeps its box clear of the robot's disc plus margin (sampled by
    hand) and rejoins the track late."""
    art, tracks = _north()
    scene = _scene(tracks, art)
    robot = np.array([10.0, 10.5])
    got = plan_avoidance(scene, 0, 7.5, 8.0, robot, 0.5, OPEN, OPEN.distance_to_occupied())
    assert got is not None and got.kind == "detour" and got.delay > 0
    new = scene.with_track(0, got.t, got.pose)
    _same_motion_until(scene, new, 7.5)
    assert np.sum(got.t < 7.5 - 1e-9) == 8  # epochs 0..7 kept, then now
    np.testing.assert_allclose(got.t[8], 7.5)
    np.testing.assert_allclose(got.pose[8, :2], [10.0, 9.5])
    # the box, sampled by hand, along the new track until it is back on its line past y = 12
    back = (np.abs(got.pose[:, 0] - 10.0) < 1e-9) & (got.pose[:, 1] > 11.0)
    t_back = got.t[np.flatnonzero(back)[0]]
    for u in np.linspace(7.5, t_back, 200):
        p = new.poses(u, [0])[0]
        pts = _box_points(p[:2], p[2])
        assert np.linalg.norm(pts - robot, axis=1).min() >= 0.5 - 0.02
    # the rest of its track: the original epochs, late by the delay
    tail = got.t > t_back - 1e-9
    k = int(np.sum(tail))
    np.testing.assert_allclose(got.t[tail], np.arange(17.0 - k, 17.0) + got.delay)


def test_plan_avoidance_between_epochs_in_the_cell_of_its_next_epoch(monkeypatch):
    """At t = 6.92 the walker (y = 2.1 + t) is 0.08 m short of its epoch at t = 7, in the
    same grid cell; the robot passes just ahead of it at 3 m/s along y = 9.8. A detour to
    that epoch is a one-cell search path (it used to fail on it); the answer starts where
    the walker is and keeps its box clear of the passing robot (sampled by hand) until the
    walker's next check."""
    import are_stats.experiments._avoid as avoid

    lengths = []

    def spy(ok, start, goal):
        path = astar(ok, start, goal)
        lengths.append(None if path is None else len(path))
        return path

    astar = avoid.astar_cells
    monkeypatch.setattr(avoid, "astar_cells", spy)
    t = np.arange(0.0, 17.0)
    tracks = pd.DataFrame({"id": 0, "t": t, "x": 10.0, "y": 2.1 + t, "yaw": np.pi / 2})
    scene = _scene(tracks, pd.DataFrame([[0.0, 60.0, 10.0, 2.1, np.pi / 2, 0]], columns=COLS))
    now = 6.92
    assert (OPEN.world_to_cell([10.0, 2.1 + now]) == OPEN.world_to_cell([10.0, 9.1])).all()
    rt, rxy = np.array([now, now + 2.0]), np.array([[10.6, 9.8], [4.6, 9.8]])
    got = plan_avoidance(scene, 0, now, 7.0, rxy[0], 0.5, OPEN, OPEN.distance_to_occupied(),
                         robot_track=(rt, rxy))  # fmt: skip
    assert 1 in lengths  # the one-cell path was searched
    assert got is not None and got.delay > 0
    new = scene.with_track(0, got.t, got.pose)
    _same_motion_until(scene, new, now)
    t_end = 7.0 if got.kind == "yield" else now + (got.t > now).sum()
    # the decision tests samples ds = 0.125 m apart relative to the robot: between two, the
    # box may come up to ds / 2 closer than the clearance
    for u in np.linspace(now, min(t_end, now + 2.0), 401):
        p = new.poses(u, [0])[0]
        robot = rxy[0] + (rxy[1] - rxy[0]) * (u - now) / 2.0
        assert np.linalg.norm(_box_points(p[:2], p[2]) - robot, axis=1).min() >= 0.5 - 0.0625


def test_within_reach_drops_only_artefacts_that_would_not_avoid():
    """The loop's vectorised distance bound (_loop._within_reach) drops an artefact only
    when plan_avoidance, which samples its motion, finds nothing to do: walkers zig-zagging
    at up to 1.5 m/s around a robot standing or driving."""
    from types import SimpleNamespace

    import are_stats.experiments._loop as loop

    rng = np.random.default_rng(7)
    rows, tracks = [], []
    for i in range(40):
        t = np.arange(0.0, 30.0)
        step = rng.normal(0.0, 1.0, (t.size, 2))
        step *= rng.uniform(0.2, 1.5, (t.size, 1)) / np.linalg.norm(step, axis=1, keepdims=True)
        xy = np.clip(rng.uniform(7.0, 13.0, 2) + np.cumsum(step, axis=0), 1.0, 19.0)
        yaw = np.r_[np.arctan2(*np.diff(xy, axis=0)[:, ::-1].T), 0.0]
        rows.append([0.0, 60.0, xy[0, 0], xy[0, 1], yaw[0], 0])
        tracks.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": yaw}))
    scene = _scene(pd.concat(tracks, ignore_index=True), pd.DataFrame(rows, columns=COLS))
    m = SimpleNamespace(
        clearance=0.5, art_speed=loop._track_speeds(scene),
        art_radius=np.hypot(*scene.offsets[:, :2].T) + np.hypot(*scene.half_extents[:, :2].T),
    )  # fmt: skip
    wall = OPEN.distance_to_occupied()
    dropped = kept_avoiding = 0
    for k in range(40):
        t = float(rng.uniform(0.0, 27.0))
        pose = np.r_[rng.uniform(8.0, 12.0, 2), 0.0]
        track = None
        if k % 2:  # driving at 0.5 m/s through two waypoints
            way = np.vstack([pose[:2], pose[:2] + rng.normal(0.0, 2.0, (2, 2))])
            arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(way, axis=0), axis=1))]
            track = (t + arc / 0.5, way)
        s = SimpleNamespace(t=t, pose=pose, scene=scene)
        cand = np.arange(len(scene))
        t_check = scene.next_epoch(t, cand)
        got, _ = loop._within_reach(m, s, cand, t_check, track)
        assert np.all(np.diff(got) > 0)  # the order is kept
        for i in cand:
            answer = plan_avoidance(
                scene, int(i), t, float(t_check[i]), pose[:2], m.clearance, OPEN, wall,
                robot_track=track,
            )  # fmt: skip
            if i not in got:
                dropped += 1
                assert answer is None, (k, i)
            elif answer is not None:
                kept_avoiding += 1
    assert dropped > 500 and kept_avoiding > 5


def test_clear_of_walls_of_many_boxes_is_every_box_clear():
    """The boxes' windows are gathered and tested in one pass: a set of boxes is clear
    exactly when each of them is (each tested alone)."""
    from are_stats.experiments._avoid import _clear_of_walls

    rng = np.random.default_rng(6)
    data = np.where(rng.random((30, 30)) < 0.03, 100, 0)
    data[:, 0] = -1
    grid = OccupancyGrid(data, 0.2, origin=(-1.0, 0.5, 0.3))
    answers = set()
    for _ in range(200):
        k = int(rng.integers(1, 12))
        half = rng.uniform(0.05, 0.5, 2)
        # centres inside the map, near its edge or past it
        centres = grid.cell_to_world(rng.uniform(-3.0, 33.0, (k, 2)))
        yaws = rng.uniform(0.0, 7.0, k)
        alone = [_clear_of_walls(grid, centres[j : j + 1], half, yaws[j : j + 1]) for j in range(k)]
        got = _clear_of_walls(grid, centres, half, yaws)
        assert got == all(alone)
        answers.add(got)
    assert answers == {True, False}


def test_string_pull_equals_one_chord_at_a_time():
    """The detour's string-pulling tests every chord from a vertex in one pass: the same
    vertices as testing one chord at a time (each sampled with np.linspace every quarter
    cell), on cell-centred paths (chords a whole number of samples long) and others."""
    from are_stats.experiments._avoid import _string_pull
    from are_stats.experiments._planners import astar_cells

    def one_at_a_time(pts, ok, grid, lo):
        step = grid.resolution / 4.0
        out, a = [pts[0]], 0
        while a < len(pts) - 1:
            b = a + 1
            for j in range(a + 2, len(pts)):
                d = pts[j] - pts[a]
                k = int(np.ceil(np.linalg.norm(d) / step)) + 1
                ij = grid.world_to_cell(pts[a] + d * np.linspace(0.0, 1.0, k)[:, None]) - lo
                inside = (ij >= 0).all(axis=1) & (ij < ok.shape).all(axis=1)
                if inside.all() and ok[ij[:, 0], ij[:, 1]].all():
                    b = j
            out.append(pts[b])
            a = b
        return np.array(out)

    rng = np.random.default_rng(8)
    dropped = 0
    for trial in range(80):
        # an unrotated grid (cells from the origin's offset alone) and a rotated one
        grid = OccupancyGrid(np.zeros((60, 60)), 0.1, origin=(-2.0, 1.0, 0.7 * (trial % 4 == 3)))
        ok = rng.random((40, 40)) > 0.25 * (trial % 3)
        lo = np.array([int(rng.integers(0, 20)), int(rng.integers(0, 20))])
        a, b = rng.integers(0, 40, (2, 2))
        ok[tuple(a)] = ok[tuple(b)] = True
        path = astar_cells(ok, tuple(a), tuple(b))
        if path is None:
            continue
        pts = grid.cell_to_world(path + lo)
        if trial % 2:  # off-centre ends, as the artefact's position and its epoch's pose
            pts = np.vstack([pts[0] + rng.uniform(-0.05, 0.05, 2), pts[1:]])
        want = one_at_a_time(pts, ok, grid, lo)
        np.testing.assert_array_equal(_string_pull(pts, ok, grid, lo), want)
        dropped += len(pts) - len(want)
    assert dropped > 100


def test_cells_near_a_disc_are_those_a_kd_tree_finds():
    """The detour blocks the window's cells within a radius of points (the robot's sweep)
    by the cells around each point: the same cells as a k-d tree of every cell centre of
    the window finds (scipy's query_ball_point), on a rotated grid, with radii of zero and
    points on cell centres."""
    from scipy.spatial import cKDTree

    from are_stats.experiments._avoid import _cells_near, _sq_distance

    rng = np.random.default_rng(9)
    grid = OccupancyGrid(np.zeros((80, 90)), 0.1, origin=(-3.0, 2.0, 0.4))
    n_found = 0
    for _ in range(40):
        lo = rng.integers(0, 30, 2)
        shape = (int(rng.integers(5, 50)), int(rng.integers(5, 60)))
        ij = np.indices(shape).reshape(2, -1).T + lo
        tree = cKDTree(grid.cell_to_world(ij))
        m = int(rng.integers(1, 30))
        pts = grid.cell_to_world(rng.uniform(-5.0, 85.0, (m, 2)))
        on = rng.random(m) < 0.3  # some exactly on a cell centre
        pts[on] = grid.cell_to_world(ij[rng.integers(0, len(ij), on.sum())])
        radii = np.where(rng.random(m) < 0.2, 0.0, rng.uniform(0.0, 1.2, m))
        want = np.zeros(len(ij), bool)
        for found in tree.query_ball_point(pts, radii):
            want[found] = True
        cells, disc, xy = _cells_near(grid, lo, shape, pts, radii)
        got = np.zeros(len(ij), bool)
        got[cells[_sq_distance(xy, pts[disc]) <= radii[disc] ** 2]] = True
        np.testing.assert_array_equal(got, want)
        n_found += int(want.sum())
    assert n_found > 1000


def test_robot_plans_again_when_an_artefact_waits_on_its_new_plan():
    """At a crossing of two corridors, moves on a 2 s clock: the robot, stopped by a box in
    its corridor, plans east when the box leaves (t = 4); the walker coming south, which
    had decided against the standing robot, meets the new plan in the crossing and waits
    there, on the plan, until the next tick. The robot plans again instead of driving into
    it (before, a collision at about t = 5)."""
    data = np.full((100, 100), 100)
    data[47:53, :] = 0  # an east-west corridor, y in [9.4, 10.6)
    data[:, 47:53] = 0  # a north-south one, x in [9.4, 10.6)
    grid = OccupancyGrid(data, 0.2)
    t = np.arange(0.0, 40.0, 4.0)  # south at 1 m/s, epochs 4 s apart: y = 16, 12, 8, ...
    tracks = pd.DataFrame({"id": 0, "t": t, "x": 10.0, "y": 16.0 - t, "yaw": -np.pi / 2})
    art = pd.DataFrame(
        [[0.0, 60.0, 10.0, 16.0, -np.pi / 2, 0], [0.0, 4.0, 13.0, 10.0, 0.0, 0]], columns=COLS
    )
    art["artefact"] = [0, 1]
    robot = Robot(radius=0.3, speed=1.0)
    res = run_mission(grid, _scene(tracks, art), [[16.0, 10.0]], "astar", robot=robot,
                      start=[7.8, 10.0, 0.0], time_limit=40.0, move_period=2.0,
                      record=True)  # fmt: skip
    s = res.summary
    assert s["collisions"] == 0 and s["artefact_contacts"] == 0
    assert s["n_yields"] >= 1 and s["goals_reached"] == 1
    # the plan at the leave was answered by a wait on it: the robot planned again then
    at4 = res.replans[res.replans["t"] == 4.0]
    assert len(at4) == 2 and at4["reason"].tolist() == ["leave+move", "replan+yield"]
    # independent truth: the walker's box (sampled by hand) never within the robot's radius
    for sc in res.trace.scenes:
        k = np.flatnonzero(sc["ids"] == 0)
        if k.size:
            pts = _box_points(sc["centres"][k[0], :2], sc["yaws"][k[0]])
            gap = np.linalg.norm(pts - _robot_xy(res.trace, sc["t"]), axis=1).min()
            assert gap > robot.radius


def _ring():
    """Three pedestrians 0.6 m from a robot at (5, 5) (their boxes' near edges), 120
    degrees apart, each walking through the robot's position at 0.5 m/s (epochs 2 s
    apart): they ring it."""
    rows, tracks = [], []
    t = np.arange(0.0, 41.0, 2.0)
    for k, angle in enumerate(np.deg2rad([0.0, 120.0, 240.0])):
        u = np.array([np.cos(angle), np.sin(angle)])
        xy = 5.0 + 0.9 * u - (0.5 * t)[:, None] * u
        yaw = float(np.arctan2(-u[1], -u[0]))
        rows.append([0.0, 60.0, xy[0, 0], xy[0, 1], yaw, 0])
        tracks.append(pd.DataFrame({"id": k, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": yaw}))
    art = pd.DataFrame(rows, columns=COLS)
    art["artefact"] = [0, 1, 2]
    return _scene(pd.concat(tracks, ignore_index=True), art)


def test_people_ringing_a_standing_robot_give_way_after_the_patience():
    """Three people walking at a robot ring it, each waiting for it (its plans fail: no way
    out between them); without the patience rule they wait for it as it waits for them and
    the robot never leaves (the deadlock that stalled the one-hour RRT-Connect benchmark
    mission). With it, after ``avoid_patience`` (2 s) of the robot standing and them
    waiting, they step back out of its safety margin, once each, and the robot reaches its
    goal, no box ever within its radius (sampled by hand)."""
    grid = OccupancyGrid(np.zeros((100, 100)), 0.1)
    robot = Robot(radius=0.3, speed=0.5)
    kw = dict(robot=robot, start=[5.0, 5.0, 0.0], time_limit=30.0, move_period=2.0)
    stuck = run_mission(grid, _ring(), [[5.0, 8.0]], "astar", avoid_patience=1e9, **kw)
    s = stuck.summary
    assert s["goals_reached"] == 0 and s["distance"] == 0.0 and s["n_give_ways"] == 0
    assert s["n_yields"] >= 3 * 10 and s["n_failed_plans"] == s["n_replans"]
    res = run_mission(grid, _ring(), [[5.0, 8.0]], "astar", record=True, **kw)
    s = res.summary
    assert s["goals_reached"] == 1 and s["n_give_ways"] == 3
    assert s["collisions"] == s["artefact_contacts"] == s["arrival_contacts"] == 0
    # they gave way at their first check at least 2 s after the robot stood (t = 0)
    gave = res.timeline[res.timeline["kind"].str.contains("give_way")]
    assert gave["t"].tolist() == [2.0]
    assert not res.replans["success"].iloc[0] and res.replans["success"].iloc[-1]
    # each stepped back until its box was 0.5 m past the clearance from the robot
    for sc in res.trace.scenes:
        robot_xy = _robot_xy(res.trace, sc["t"])
        for k in range(len(sc["ids"])):
            pts = _box_points(sc["centres"][k, :2], sc["yaws"][k])
            gap = np.linalg.norm(pts - robot_xy, axis=1).min()
            assert gap > robot.radius
            if sc["t"] == 4.0:  # standing at their spots, the robot where it stood
                gap = np.linalg.norm(pts - [5.0, 5.0], axis=1).min()
                assert gap >= robot.radius + 0.2 + 0.5 - 1e-6


def test_people_give_way_once_while_the_robot_stands():
    """The ring of three, the robot's plans failing for the whole mission (a planner that
    finds nothing): each person gives way once in that standing spell, walks back and then
    waits for the robot again instead of stepping back and forth (each give way is a new
    track and new scene events); without patience none gives way."""
    kw = dict(robot=ROBOT, start=[5.0, 5.0, 0.0], time_limit=30.0, move_period=2.0)
    grid = OccupancyGrid(np.zeros((100, 100)), 0.1)
    res = run_mission(grid, _ring(), [[5.0, 8.0]], _never, **kw)
    s = res.summary
    assert s["n_give_ways"] == 3 and s["goals_reached"] == 0 and s["distance"] == 0.0
    gave = res.timeline[res.timeline["kind"].str.contains("give_way")]
    assert gave["t"].tolist() == [2.0]
    # back from their spots they wait for it again, every check to the end
    later = res.timeline[res.timeline["t"] > 12.0]
    assert later["kind"].str.contains("yield").sum() >= 5
    assert s["collisions"] == s["artefact_contacts"] == 0
    none = run_mission(grid, _ring(), [[5.0, 8.0]], _never, avoid_patience=1e9, **kw).summary
    assert none["n_give_ways"] == 0 and none["n_yields"] >= 3 * 10
