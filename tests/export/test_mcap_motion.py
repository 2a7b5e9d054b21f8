"""The mission MCAP shows the artefacts walking: between scene updates their ``/tf`` frames
and ``/artefacts`` markers are published every ``1 / rate`` seconds, where the mission's
scene has them then (``trace.scene.at(t)``), while the planner's maps keep the updates'
cadence."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.experiments import run_mission
from are_stats.export import export_mcap
from are_stats.export._ros import RosMessages
from are_stats.scenarios import Scene

START = 1.7e9
PALLET, PERSON = 0, 1  # artefact ids (the table's row order)


@pytest.fixture(scope="module")
def mission():
    occ = np.zeros((40, 60), np.int8)
    occ[[0, -1], :] = occ[:, [0, -1]] = 100
    grid = OccupancyGrid(occ, 0.5, (-1.0, -2.0, 0.0))
    art = pd.DataFrame(
        [[0.0, 99.0, 22.0, 4.0, 2.5, 0, 3], [10.0, 50.0, 10.0, 2.0, 1.6, 0, 0]],
        columns=["t_arrive", "t_leave", "x", "y", "yaw", "mark", "class"],
    )  # fmt: skip
    t = 10.0 + 2.0 * np.arange(13)  # a person walking north at 0.5 m/s across the robot's way
    tracks = pd.DataFrame(
        {"id": PERSON, "t": t, "x": 10.0, "y": 2.0 + 0.5 * (t - 10.0), "yaw": np.pi / 2}
    )
    scene = Scene.from_scenarios(art, load_catalogue(), tracks)
    res = run_mission(
        grid, scene, [[2.0, 2.0], [25.0, 15.0], [3.0, 14.0]], "astar", record=True, time_limit=90
    )
    # the person detours around the robot: its track in the trace's scene is not the input's
    assert res.summary["n_detours"] >= 1
    assert not np.array_equal(res.trace.scene.track(1)[0], scene.track(1)[0])
    return grid, res


def _read(path):
    """Artefact transforms ``{t: {id: (x, y, z, yaw)}}``, marker boxes ``{t: {id: (x, y, z,
    green)}}`` (t: ns after START, the stamps' resolution) and the message count per
    topic."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    tfs, boxes, counts = defaultdict(dict), defaultdict(dict), defaultdict(int)
    raw = {}
    with open(path, "rb") as fh:
        for schema, channel, msg in make_reader(fh).iter_messages():
            counts[channel.topic] += 1
            t = msg.log_time - int(START * 1e9)
            if channel.topic == "/tf":
                for tr in ts.deserialize_cdr(msg.data, schema.name).transforms:
                    if tr.child_frame_id.startswith("artefact_"):
                        p, q = tr.transform.translation, tr.transform.rotation
                        yaw = 2.0 * math.atan2(q.z, q.w)
                        aid = int(tr.child_frame_id.removeprefix("artefact_"))
                        tfs[t][aid] = (p.x, p.y, p.z, yaw)
            elif channel.topic == "/artefacts":
                boxes[t]  # a frame with no live artefact still clears the old ones
                raw[t] = bytes(msg.data)
                for m in ts.deserialize_cdr(msg.data, schema.name).markers:
                    if m.ns == "artefacts":
                        p = m.pose.position
                        boxes[t][m.id] = (p.x, p.y, p.z, m.color.g > m.color.r)
    return tfs, boxes, counts, raw


def _expected_times(trace, rate):
    """Every scene update and every k / rate s in between, to the mission's end: mission
    times (s) and their stamps (ns after START)."""
    t_up = np.array([sc["t"] for sc in trace.scenes])
    t_end = max(t_up[-1], trace.poses[-1, 0])
    ticks = np.arange(int(np.floor(t_end * rate + 1e-9)) + 1) / rate
    ticks = ticks[np.abs(ticks[:, None] - t_up[None]).min(axis=1) >= 1e-6]
    t = np.sort(np.r_[t_up, ticks])
    return t, np.round(t * 1e9).astype(np.int64)


@pytest.fixture(scope="module")
def exported(mission, tmp_path_factory):
    grid, res = mission
    path = export_mcap(
        tmp_path_factory.mktemp("motion") / "run.mcap", grid, res.trace, start_time=START
    )
    return _read(path)


def test_artefacts_walk_at_ten_hertz_where_the_scene_has_them(mission, exported):
    _, res = mission
    trace = res.trace
    tfs, boxes, counts, _ = exported
    times, stamps = _expected_times(trace, 10.0)
    # the pallet stands for the whole mission, so every frame has a /tf
    np.testing.assert_array_equal(np.array(sorted(tfs)), stamps)
    np.testing.assert_array_equal(np.array(sorted(boxes)), stamps)
    assert np.diff(times).max() <= 0.1 + 1e-9 and times.size > 10 * trace.poses[-1, 0]
    for t, ns in zip(times.tolist(), stamps.tolist(), strict=True):
        b = trace.scene.at(t)
        assert sorted(tfs[ns]) == sorted(b.ids.tolist()) == sorted(boxes[ns])
        got = np.array([tfs[ns][a] for a in b.ids.tolist()])
        np.testing.assert_allclose(got[:, :3], b.centres, rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.mod(got[:, 3], 2 * np.pi), b.yaws, rtol=0, atol=1e-9)
        mk = np.array([boxes[ns][a][:3] for a in b.ids.tolist()])
        np.testing.assert_allclose(mk, b.centres, rtol=0, atol=1e-9)
    # the planner's maps keep the scene updates' cadence, the robot its poses'
    assert counts["/augmented_map"] == counts["/planner_map"] == len(trace.scenes)
    assert counts["/robot_pose"] == len(trace.poses)


def test_the_person_walks_and_the_pallet_stays_put(mission, exported):
    _, res = mission
    trace = res.trace
    tfs, boxes, _, _ = exported
    times, stamps = _expected_times(trace, 10.0)
    # the updates' records (the scene as the loop had it then, before later avoidances
    # changed tracks) agree with the final scene: an avoidance keeps the past of a track
    for sc in trace.scenes:
        b = trace.scene.at(float(sc["t"]))
        np.testing.assert_array_equal(b.ids, sc["ids"])
        np.testing.assert_allclose(b.centres, sc["centres"], rtol=0, atol=1e-9)
    # the person: on its (detoured) track, linearly between its epochs (np.interp,
    # independent of Scene.poses_at), in steps no longer than its speed allows in 0.1 s
    tt, pp = trace.scene.track(PERSON)
    on = np.array([PERSON in tfs[ns] for ns in stamps.tolist()])
    xy = np.array([tfs[ns][PERSON][:2] for ns in stamps[on].tolist()])
    np.testing.assert_allclose(xy[:, 0], np.interp(times[on], tt, pp[:, 0]), rtol=0, atol=1e-9)
    np.testing.assert_allclose(xy[:, 1], np.interp(times[on], tt, pp[:, 1]), rtol=0, atol=1e-9)
    speed = (np.linalg.norm(np.diff(pp[:, :2], axis=0), axis=1) / np.diff(tt)).max()
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert step.max() <= speed * np.diff(times[on]).max() + 1e-9
    assert (step > 0.01).sum() > 100  # it walks: a hundred 10 Hz steps of more than 1 cm
    assert times[on][0] == 10.0 and times[on][-1] < 50.0  # alive from 10 s until 50 s
    # the pallet: the same pose in every frame, its arrival pose
    pallet = np.array([tfs[ns][PALLET] for ns in stamps.tolist()])
    assert np.ptp(pallet, axis=0).max() == 0.0
    np.testing.assert_allclose(pallet[0, [0, 1, 3]], [22.0, 4.0, 2.5], rtol=0, atol=1e-12)
    # markers are green (perceived) exactly when the last scene update had them so
    t_up = np.array([sc["t"] for sc in trace.scenes])
    for t, ns in zip(times.tolist(), stamps.tolist(), strict=True):
        sc = trace.scenes[int(np.searchsorted(t_up, t, side="right")) - 1]
        seen = dict(zip(sc["ids"].tolist(), sc["perceived"].tolist(), strict=True))
        assert {a: v[3] for a, v in boxes[ns].items()} == seen


def test_rate_and_a_trace_without_its_scene(mission, tmp_path):
    grid, res = mission
    trace = res.trace
    tfs = _read(export_mcap(tmp_path / "r2.mcap", grid, trace, start_time=START, rate=2))[0]
    np.testing.assert_array_equal(np.array(sorted(tfs)), _expected_times(trace, 2.0)[1])
    # a trace built without its scene: the artefacts at the scene updates only, as recorded
    old = trace._replace(scene=None)
    tfs = _read(export_mcap(tmp_path / "old.mcap", grid, old, start_time=START))[0]
    t_up = [int(round(sc["t"] * 1e9)) for sc in trace.scenes]
    assert sorted(tfs) == t_up
    for sc, ns in zip(trace.scenes, t_up, strict=True):
        got = np.array([tfs[ns][a][:3] for a in sc["ids"].tolist()])
        np.testing.assert_allclose(got, sc["centres"], rtol=0, atol=1e-12)
    for bad in (0, -1.0, float("nan"), True, "10"):
        with pytest.raises(ValueError, match="rate: expected a finite number > 0"):
            export_mcap(tmp_path / "bad.mcap", grid, trace, rate=bad)


def test_markers_between_updates_are_what_artefact_markers_writes(mission, tmp_path):
    # the trace cut after 45 s: the person leaves at 50 s with no update recorded, so the
    # frames after it hold a live set other than the last update's
    grid, res = mission
    cut = res.trace._replace(scenes=[sc for sc in res.trace.scenes if sc["t"] < 45.0])
    tfs, _, _, raw = _read(export_mcap(tmp_path / "cut.mcap", grid, cut, start_time=START))
    times, stamps = _expected_times(cut, 10.0)
    assert any(PERSON not in tfs[ns] for ns in stamps.tolist()[-10:])
    R = RosMessages(START)
    t_up = np.array([sc["t"] for sc in cut.scenes])
    for t, ns in zip(times.tolist(), stamps.tolist(), strict=True):
        if np.isin(t, t_up):
            continue
        b = cut.scene.at(t)
        sc = cut.scenes[int(np.searchsorted(t_up, t, side="right")) - 1]
        last = dict(zip(sc["ids"].tolist(), sc["perceived"].tolist(), strict=True))
        seen = [last.get(a, False) for a in b.ids.tolist()]
        want = R.artefact_markers(t, b.ids, b.centres, b.half_extents, b.yaws, b.labels, seen)
        ser = R.ts.serialize_cdr(want, "visualization_msgs/msg/MarkerArray")
        assert raw[ns] == bytes(ser), t
