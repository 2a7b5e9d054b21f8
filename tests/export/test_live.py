"""Live view (are-stats serve): the timed messages, a WebSocket client on loopback, errors."""

from __future__ import annotations

import base64
import inspect
import json
import math
import os
import re
import socket
import struct
import threading
import time
from typing import get_type_hints

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")

from are_stats import Scene, load_catalogue  # noqa: E402
from are_stats.cli import app  # noqa: E402
from are_stats.environment import DEFAULT_MODELS  # noqa: E402
from are_stats.export import ServeOptions  # noqa: E402
from are_stats.export._live import (  # noqa: E402
    LIVE_TOPICS,
    replay_messages,
    serve_scenario,
)

runner = CliRunner()
# foxglove-sdk 0.30 speaks the protocol under the name foxglove.sdk.v1 (the Foxglove
# WebSocket protocol formerly named foxglove.websocket.v1); offer both, as the app does.
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def _artefacts():
    return pd.DataFrame(
        {
            "scenario": np.array([0, 0, 1], np.int64),
            "artefact": np.array([0, 1, 0], np.int64),
            "class": np.array([0, 1, 0], np.int64),
            "mark": np.array([0, 0, 0], np.int64),
            "t_arrive": [0.0, 10.0, 0.0],
            "t_leave": [40.0, 60.0, 20.0],
            "x": [-12.0, -8.0, -11.0],
            "y": [-8.0, -4.0, -6.0],
            "yaw": [0.0, 1.0, 2.0],
        }
    )


def _tracks():  # artefact 0 of scenario 0 walks 10 m along x in 20 s
    return pd.DataFrame(
        {
            "scenario": [0, 0, 0],
            "id": [0, 0, 0],
            "t": [0.0, 10.0, 20.0],
            "x": [-12.0, -7.0, -2.0],
            "y": [-8.0, -8.0, -8.0],
            "yaw": [0.0, 0.0, 0.0],
        }
    )


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "scen"
    d.mkdir()
    _artefacts().to_parquet(d / "artefacts.parquet", index=False)
    _tracks().to_parquet(d / "tracks.parquet", index=False)
    manifest = {
        "map": str(DEFAULT_MODELS / "courtyard.yaml"),
        "generation": {"horizon": 60.0},
        "tracks": {"file": "tracks.parquet"},
    }
    (d / "manifest.yaml").write_text(yaml.safe_dump(manifest))
    return d


def _decoder(schema_name: str, schema: bytes):
    """A protobuf message class from a FileDescriptorSet (as advertised by the server)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    fds = descriptor_pb2.FileDescriptorSet.FromString(schema)
    pool = descriptor_pool.DescriptorPool()
    pending = list(fds.file)
    while pending:  # add files after their dependencies
        left = []
        for f in pending:
            try:
                pool.Add(f)
            except TypeError:
                left.append(f)
        assert len(left) < len(pending), "unresolvable schema"
        pending = left
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def _decode(msg):
    s = type(msg).get_schema()
    return _decoder(s.name, s.data).FromString(msg.encode())


def _scene():
    df = _artefacts()
    part = df[df["scenario"] == 0]
    return Scene.from_scenarios(part, load_catalogue(), _tracks().drop(columns="scenario"))


def test_replay_messages_follow_the_scene():
    msgs = list(replay_messages(_scene(), horizon=60.0, speed=50.0, fps=10.0, start_ns=10**9))
    scene_msgs = [m for m in msgs if m.topic == "/scene"]
    assert [m.t for m in scene_msgs] == pytest.approx(np.minimum(np.arange(13) * 5.0, 60.0))
    assert [m.wall for m in scene_msgs] == pytest.approx(np.arange(13) / 10.0)
    assert {m.topic for m in msgs} == {"/scene", "/tf"}  # no grid given
    by_t = {m.t: _decode(m.message) for m in scene_msgs}
    # t = 5: artefact 0 only, walked 2.5 m along x from -12
    ents = by_t[5.0].entities
    assert [e.id for e in ents] == ["artefact_0"]
    assert ents[0].frame_id == "map" and ents[0].cubes[0].pose.position.x == pytest.approx(-9.5)
    assert ents[0].texts[0].text.startswith(load_catalogue().labels[0])
    # t = 15: both; t = 40: artefact 0 left (deleted), artefact 1 stays
    assert sorted(e.id for e in by_t[15.0].entities) == ["artefact_0", "artefact_1"]
    assert [d.id for d in by_t[40.0].deletions] == ["artefact_0"]
    assert [e.id for e in by_t[40.0].entities] == ["artefact_1"]
    assert not by_t[35.0].deletions
    tf = _decode(next(m for m in msgs if m.topic == "/tf" and m.t == 15.0).message)
    assert sorted(t.child_frame_id for t in tf.transforms) == ["artefact_0", "artefact_1"]
    assert {t.parent_frame_id for t in tf.transforms} == {"map"}
    t0 = next(t for t in tf.transforms if t.child_frame_id == "artefact_0")
    assert t0.translation.x == pytest.approx(-4.5)
    assert t0.timestamp.seconds == 16 and t0.timestamp.nanos == 0  # start 1 s + 15 s


def test_replay_messages_loop_keeps_the_clock_growing():
    from are_stats.environment import OccupancyGrid

    grid = OccupancyGrid.from_ros_yaml(DEFAULT_MODELS / "courtyard.yaml")
    it = replay_messages(_scene(), grid, horizon=60.0, speed=100.0, fps=4.0, loop=True)
    msgs = [next(it) for _ in range(80)]
    stamps = [m.stamp_ns for m in msgs]
    assert stamps == sorted(stamps) and max(m.t for m in msgs) < 60.0
    assert stamps[-1] > 60 * 10**9  # past one round
    maps = [m for m in msgs if m.topic == "/map"]
    assert [m.wall for m in maps][:3] == pytest.approx([0.0, 1.0, 2.0])
    g = _decode(maps[0].message)
    assert g.column_count == grid.width and len(g.data) == grid.width * grid.height
    assert g.cell_size.x == pytest.approx(grid.resolution)
    assert g.pose.position.x == pytest.approx(grid.origin[0])
    assert g.fields[0].name == "occupancy"


def _recv_json(ws, deadline, op):
    while True:
        left = deadline - time.monotonic()
        assert left > 0, f"no {op} message from the server in time"
        raw = ws.recv(timeout=left)
        if isinstance(raw, str):
            msg = json.loads(raw)
            if msg.get("op") == op:
                return msg


def test_serve_streams_to_a_websocket_client(folder):
    ws_client = pytest.importorskip("websockets.sync.client")
    ready, stop, box = threading.Event(), threading.Event(), {}

    def run():
        try:
            box["info"] = serve_scenario(
                folder, scenario=0, speed=40.0, port=0, loop=True, duration=15.0,
                on_ready=lambda info: (box.update(ready=info), ready.set()), stop=stop,
            )  # fmt: skip
        except BaseException as err:  # pragma: no cover - reported below
            box["error"] = err
            ready.set()

    th = threading.Thread(target=run, daemon=True)
    th.start()
    try:
        assert ready.wait(10), "the server did not start"
        assert "error" not in box, box.get("error")
        info = box["ready"]
        assert info["host"] == "127.0.0.1" and info["port"] > 0 and info["moving"] == 1
        deadline = time.monotonic() + 10
        with ws_client.connect(
            f"ws://127.0.0.1:{info['port']}", subprotocols=SUBPROTOCOLS, open_timeout=5,
            max_size=None,
        ) as ws:  # fmt: skip
            assert ws.subprotocol in SUBPROTOCOLS
            server_info = _recv_json(ws, deadline, "serverInfo")
            assert "time" in server_info["capabilities"]
            adv = _recv_json(ws, deadline, "advertise")
            chans = {c["topic"]: c for c in adv["channels"]}
            assert {t: chans[t]["schemaName"] for t in chans} == LIVE_TOPICS
            assert all(c["encoding"] == "protobuf" for c in chans.values())
            subs = [{"id": k, "channelId": c["id"]} for k, c in enumerate(chans.values())]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            topic_of = {k: t for k, t in enumerate(chans)}
            decoders = {
                t: _decoder(c["schemaName"], base64.b64decode(c["schema"]))
                for t, c in chans.items()
            }
            got: dict[str, list] = {t: [] for t in chans}
            clock = []
            while min(len(v) - (t == "/map") for t, v in got.items()) < 2:  # one map
                left = deadline - time.monotonic()
                assert left > 0, f"messages so far: { {t: len(v) for t, v in got.items()} }"
                raw = ws.recv(timeout=left)
                if isinstance(raw, str):
                    continue
                if raw[0] == 1:  # messageData: sub id, log time, payload
                    _, sub, log_time = struct.unpack_from("<BIQ", raw)
                    t = topic_of[sub]
                    got[t].append((log_time, decoders[t].FromString(raw[13:])))
                elif raw[0] == 2:  # time
                    clock.append(struct.unpack_from("<BQ", raw)[1])
    finally:
        stop.set()
        th.join(10)
    assert not th.is_alive() and "error" not in box, box.get("error")
    assert box["info"]["messages"] > 0 and clock
    grid = got["/map"][0][1]
    assert grid.frame_id == "map" and grid.column_count > 0 and len(grid.data) > 0
    scenes = [m for _, m in got["/scene"]]
    ids = {e.id for m in scenes for e in m.entities}
    assert ids <= {"artefact_0", "artefact_1"}
    assert all(e.frame_id == "map" and len(e.cubes) == 1 for m in scenes for e in m.entities)
    for log_time, tf in got["/tf"]:
        assert {t.parent_frame_id for t in tf.transforms} == {"map"}
        assert {t.child_frame_id for t in tf.transforms} <= ids | {"artefact_0", "artefact_1"}
        ts = tf.transforms[0].timestamp
        assert ts.seconds * 10**9 + ts.nanos == log_time
    log_times = [lt for lt, _ in got["/scene"]]
    assert log_times == sorted(log_times)


def test_serve_stops_after_duration(folder):
    t = time.monotonic()
    info = serve_scenario(folder, speed=1000.0, port=0, loop=True, duration=0.5)
    assert 0.3 < time.monotonic() - t < 5
    assert info["frames"] >= 3 and info["messages"] > info["frames"]


def test_cli_serve_runs_and_reports(folder):
    res = runner.invoke(
        app, ["serve", str(folder), "--port", "0", "--speed", "100", "--duration", "0.3"]
    )
    assert res.exit_code == 0, res.output
    assert "serving scenario 0" in res.output and "ws://127.0.0.1:" in res.output
    assert "1 moving" in res.output and "sent " in res.output


@pytest.mark.parametrize(
    ("args", "pattern"),
    [
        (["--scenario", "7"], r"--scenario: expected a scenario of .*\(0 to 1\), got 7"),
        (["--speed", "0"], r"--speed: expected"),
        (["--duration", "-1"], r"--duration: expected"),
        (["--duration", "inf"], r"--duration: expected a finite number"),
        (["--speed", "nan"], r"--speed: expected a finite number"),
        (["--speed", "1e7"], r"--speed: expected a finite number .*<= 1e\+06"),
        (["--port", "70000"], r"--port: expected a TCP port 0 to 65535, got 70000"),
        (["--port", "-1"], r"--port: expected a TCP port 0 to 65535"),
        (["--scenario", "-1"], r"--scenario: expected a scenario of .*\(0 to 1\), got -1"),
        # a bad host was reported as a port in use
        (["--host", "a b"], r"--host: expected an address to listen on"),
        (["--host", "x/y"], r"--host: expected an address to listen on"),
    ],
)
def test_cli_serve_bad_options(folder, args, pattern):
    import re

    res = runner.invoke(app, ["serve", str(folder), "--port", "0", "--duration", "0.1", *args])
    assert res.exit_code == 2, res.output
    assert re.search(pattern, res.output), res.output


def test_cli_serve_bad_folder(tmp_path, folder):
    res = runner.invoke(app, ["serve", str(tmp_path / "nope")])
    assert res.exit_code == 2 and "no such scenarios folder" in res.output, res.output
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    res = runner.invoke(app, ["serve", str(fifo)])
    assert res.exit_code == 2 and "neither a folder nor a file" in res.output, res.output
    (folder / "artefacts.parquet").unlink()
    res = runner.invoke(app, ["serve", str(folder)])
    assert res.exit_code == 2 and "artefacts.parquet" in res.output, res.output


def test_cli_serve_port_in_use(folder):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        res = runner.invoke(app, ["serve", str(folder), "--port", str(port), "--duration", "1"])
    assert res.exit_code == 2, res.output
    assert "--port: expected a free TCP port on 127.0.0.1" in res.output, res.output
    assert str(port) in res.output


def test_replay_streams_the_robot_and_its_camera_frustum(tmp_path):
    from are_stats.export._live import load_robot

    path = tmp_path / "robot.csv"
    path.write_text("t,x,y,yaw\n0,0,0,0\n60,6,0,0\n")
    robot = load_robot(path, d_max=8.0)
    msgs = list(
        replay_messages(_scene(), horizon=60.0, speed=50.0, fps=10.0, start_ns=0, robot=robot)
    )
    bodies = [m for m in msgs if m.topic == "/robot"]
    scenes = [m for m in msgs if m.topic == "/scene"]
    assert len(bodies) == len(scenes) > 0  # the robot in every frame
    first = _decode(bodies[0].message)
    assert {e.id for e in first.entities} == {"robot", "camera_frustum"}
    frustum = next(e for e in first.entities if e.id == "camera_frustum")
    far = max(math.hypot(p.x, p.y, p.z) for p in frustum.lines[0].points)
    assert far == pytest.approx(8.0)
    for m in (m for m in msgs if m.topic == "/tf"):
        by_child = {tf.child_frame_id: tf for tf in _decode(m.message).transforms}
        base = by_child["base_link"]
        assert base.parent_frame_id == "map"
        assert base.translation.x == pytest.approx(m.t / 10.0)  # 6 m in 60 s
        assert by_child["camera_optical_frame"].parent_frame_id == "base_link"


# ---- the robot from a bag (issue 27): the reader and clock of augment -------------------


def _bag_robot(tmp_path, kind="mcap", **which):
    from tests.export.rosbag_fixtures import write_bag

    name = "robot.bag" if kind == "ros1" else f"robot_{kind}"
    return write_bag(tmp_path / name, kind, **which)


def _robot_tfs(msgs):
    """(scene time, stamp ns, {child: transform}) of every /tf message."""
    out = []
    for m in msgs:
        if m.topic == "/tf":
            tfs = {tf.child_frame_id: tf for tf in _decode(m.message).transforms}
            out.append((m.t, m.stamp_ns, tfs))
    return out


@pytest.mark.parametrize("kind", ["mcap", "ros1"])
def test_replay_streams_the_robot_of_a_bag_on_its_clock(tmp_path, kind):
    from are_stats.export import robot_from_bag
    from are_stats.logs import TrajectoryOptions
    from tests.export.rosbag_fixtures import CAMERA, CAMERA_XYZ, SIM_START, robot_pose, stamp_ns

    # header stamps on a simulation clock, recording times on the wall clock (as Nav2's
    # simulation tutorials record): the robot is read on the header clock, as augment does
    bag = _bag_robot(tmp_path, kind, header_start=SIM_START)
    info = TrajectoryOptions(camera_info_topic="/camera/camera_info")
    robot = robot_from_bag(bag, info, d_max=5.0)
    assert robot["frame"] == "map" and robot["start_ns"] == stamp_ns(0.0, SIM_START)
    assert robot["camera_frame"] == "camera_optical_frame"
    # the options reach the reader whole: the clock too (the replay's stamps stay on the
    # header clock)
    on_log = robot_from_bag(bag, info._replace(clock="log"))
    assert on_log["clock_note"].startswith("recording times (--clock log")
    assert on_log["base_frame"] == "base_link" and on_log["start_ns"] == robot["start_ns"]
    msgs = list(
        replay_messages(
            _scene(), horizon=12.0, speed=40.0, fps=10.0, start_ns=robot["start_ns"], robot=robot
        )
    )
    seen = _robot_tfs(msgs)
    assert len(seen) == 4  # t = 0, 4, 8, 12
    for t, ns, tfs in seen:
        assert ns == stamp_ns(t, SIM_START)  # stamps on the bag's header clock
        base = tfs["base_link"]
        assert base.parent_frame_id == "map"
        x, y, yaw = robot_pose(t)  # map -> odom -> base_link composed
        assert (base.translation.x, base.translation.y) == pytest.approx((x, y), abs=1e-9)
        assert 2 * math.atan2(base.rotation.z, base.rotation.w) == pytest.approx(yaw)
        cam = tfs["camera_optical_frame"]  # the mount from the bag's /tf_static
        assert cam.parent_frame_id == "base_link"
        xyz = (cam.translation.x, cam.translation.y, cam.translation.z)
        assert xyz == pytest.approx(CAMERA_XYZ)
        # optical z (forward) along the base's x: q rotates (0, 0, 1) onto (1, 0, 0)
        q = cam.rotation
        fwd_x = 2 * (q.x * q.z + q.w * q.y)
        assert fwd_x == pytest.approx(1.0)
    # the frustum from the bag's CameraInfo (80 x 60, fx = 60, cx = 40): its corner rays
    body = _decode(next(m for m in msgs if m.topic == "/robot").message)
    frustum = next(e for e in body.entities if e.id == "camera_frustum")
    assert frustum.frame_id == "camera_optical_frame"
    pts = frustum.lines[0].points
    corners = {(round(p.x / p.z, 6), round(p.y / p.z, 6)) for p in pts if p.z > 0}
    fx, cx, cy = CAMERA["k"][0], CAMERA["k"][2], CAMERA["k"][5]
    want = {
        (round(-cx / fx, 6), round(-cy / fx, 6)),
        (round((80 - cx) / fx, 6), round(-cy / fx, 6)),
    }
    assert want <= corners
    assert max(math.hypot(p.x, p.y, p.z) for p in pts) == pytest.approx(5.0)


@pytest.mark.parametrize(
    "rot",
    [
        [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]],  # forward (trace 0)
        [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]],  # straight down (trace -1)
    ],
)
def test_replay_mount_rotation_is_the_mounts_quaternion(tmp_path, rot):
    from scipy.spatial.transform import Rotation

    from are_stats.export import robot_from_bag

    mount = np.eye(4)
    mount[:3, :3] = rot
    mount[:3, 3] = [0.1, 0.0, 1.2]
    robot = {**robot_from_bag(_bag_robot(tmp_path)), "mount": mount}
    msgs = list(replay_messages(_scene(), horizon=4.0, speed=40.0, fps=10.0, robot=robot))
    q = _robot_tfs(msgs)[0][2]["camera_optical_frame"].rotation
    got = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    np.testing.assert_allclose(got, rot, atol=1e-9)


def test_robot_of_an_odometry_only_bag_lives_in_odom(tmp_path):
    from are_stats.export import robot_from_bag
    from tests.export.rosbag_fixtures import robot_pose

    bag = _bag_robot(tmp_path, "ros2", map_tf=False, camera=False)
    robot = robot_from_bag(bag)
    assert robot["frame"] == "odom" and "odom" in robot["frame_note"]
    msgs = list(
        replay_messages(_scene(), horizon=12.0, speed=120.0, fps=10.0, robot=robot, frame="odom")
    )
    (_, _, tfs), *_ = _robot_tfs(msgs)
    x, y, _ = robot_pose(0.0)
    base = tfs["base_link"]
    assert base.parent_frame_id == "odom"
    assert (base.translation.x, base.translation.y) == pytest.approx((x - 1.0, y + 0.5))
    assert {tf.parent_frame_id for tf in tfs.values()} == {"odom", "base_link"}


def test_cli_serve_streams_the_robot_of_a_bag(folder, tmp_path):
    bag = _bag_robot(tmp_path)
    args = ["serve", str(folder), "--port", "0", "--speed", "100", "--duration", "0.3"]
    res = runner.invoke(app, [*args, "--bag", str(bag), "--pose-topic", "/amcl_pose"])
    assert res.exit_code == 0, res.output
    said = " ".join(res.output.split())  # the console wraps long lines
    assert f"robot from {bag}: /amcl_pose, 121 poses over 12.0 s" in said, said
    assert "camera frame camera_optical_frame, fixed frame map" in said


def test_cli_serve_refuses_a_bag_without_a_usable_pose(folder, tmp_path):
    args = ["serve", str(folder), "--port", "0", "--duration", "0.1"]
    bare = _bag_robot(tmp_path, "ros2", tf=False, poses=False)
    res = runner.invoke(app, [*args, "--bag", str(bare)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bare}"), res.output
    assert "robot poses" in res.output and "/camera/camera_info" in res.output
    bag = _bag_robot(tmp_path)
    for extra, pattern in (
        (["--pose-topic", "/nope"], r"--pose-topic /nope: expected a topic of the bag"),
        (["--base-frame", "robot"], r"map -> \.\.\. -> robot"),
        (["--camera-frame", "nope"], r"--camera-frame nope: expected a frame"),
        (["--pose-topic", "/amcl_pose", "--base-frame", "b"], "either --pose-topic or"),
        (["--robot-path", str(tmp_path / "p.csv")], "either --robot-path or --bag"),
        (["--clock", "sun"], r"--clock: expected one of"),
    ):
        res = runner.invoke(app, [*args, "--bag", str(bag), *extra])
        assert res.exit_code == 2, (extra, res.output)
        assert re.search(pattern, res.output), (extra, res.output)
    res = runner.invoke(app, [*args, "--pose-topic", "/amcl_pose"])
    assert res.exit_code == 2 and "--pose-topic: expected --bag" in res.output, res.output


def test_serve_sends_the_bag_robot_on_the_bags_clock(folder, tmp_path):
    """On the wire: /robot advertised, and the frames stamped (and logged) from the bag's
    start on its header clock (a simulation clock here), not from the wall clock's now."""
    ws_client = pytest.importorskip("websockets.sync.client")
    from are_stats.export import robot_from_bag
    from tests.export.rosbag_fixtures import SIM_START, stamp_ns

    robot = robot_from_bag(_bag_robot(tmp_path, header_start=SIM_START))
    ready, stop, box = threading.Event(), threading.Event(), {}

    def run():
        try:
            box["info"] = serve_scenario(
                folder, speed=10.0, port=0, loop=True, duration=15.0, robot=robot,
                on_ready=lambda info: (box.update(ready=info), ready.set()), stop=stop,
            )  # fmt: skip
        except BaseException as err:  # pragma: no cover - reported below
            box["error"] = err
            ready.set()

    th = threading.Thread(target=run, daemon=True)
    th.start()
    try:
        assert ready.wait(10) and "error" not in box, box.get("error")
        deadline = time.monotonic() + 10
        url = f"ws://127.0.0.1:{box['ready']['port']}"
        with ws_client.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=5) as ws:
            adv = _recv_json(ws, deadline, "advertise")
            chans = {c["topic"]: c for c in adv["channels"]}
            assert chans["/robot"]["schemaName"] == "foxglove.SceneUpdate"
            subs = [{"id": k, "channelId": chans[t]["id"]} for k, t in enumerate(["/robot"])]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            log_times = []
            while len(log_times) < 2:
                raw = ws.recv(timeout=max(deadline - time.monotonic(), 0.01))
                if isinstance(raw, bytes) and raw[0] == 1:
                    log_times.append(struct.unpack_from("<BIQ", raw)[2])
    finally:
        stop.set()
        th.join(10)
    assert not th.is_alive() and "error" not in box, box.get("error")
    start = stamp_ns(0.0, SIM_START)
    assert all(start <= lt < start + 60 * 10**9 for lt in log_times), (start, log_times)


def test_serve_robot_refuses_bag_options_without_a_bag_and_two_robots(tmp_path):
    """The bag-robot rules of ``serve`` (before any bag is opened: none exists here)."""
    from are_stats.export import serve_robot
    from are_stats.inputs import InputError
    from are_stats.logs import TrajectoryOptions

    assert serve_robot(None) is None and serve_robot(None, TrajectoryOptions()) is None
    assert serve_robot(None, robot_path=tmp_path / "p.csv") is None  # the path's robot
    given = TrajectoryOptions(pose_topic="/amcl_pose", clock="log")
    with pytest.raises(InputError, match=r"^--pose-topic: expected --bag \(the bag it reads\)"):
        serve_robot(None, given)
    with pytest.raises(InputError, match=r"^--bag: expected either --robot-path or --bag"):
        serve_robot(tmp_path / "no.bag", robot_path=tmp_path / "p.csv")
    both = TrajectoryOptions(pose_topic="/amcl_pose", base_frame="base_link")
    with pytest.raises(InputError, match=r"^--pose-topic: expected either --pose-topic or"):
        serve_robot(tmp_path / "no.bag", both)


def test_serve_options_are_its_keywords():
    """ServeOptions (the job's ``**options``) names serve_scenario's keywords, but the hooks
    (on_ready, stop) and the robot (robot_path, robot), with their types: a keyword added to
    one is added to the other."""
    hints = get_type_hints(serve_scenario)
    params = inspect.signature(serve_scenario).parameters.values()
    left = {"on_ready", "stop", "robot_path", "robot"}
    keywords = [p.name for p in params if p.kind is p.KEYWORD_ONLY and p.name not in left]
    assert list(ServeOptions.__annotations__) == keywords
    assert get_type_hints(ServeOptions) == {k: hints[k] for k in keywords}
