"""Robot bag in, augmented bag out (issue 17): bags written with rosbags (ROS 1, ROS 2,
MCAP) on the courtyard map, ``augment`` through Python and the CLI, the output read back
with the ``mcap`` reader and rosbags; exports of ``experiment --mcap`` follow REP-105."""

from __future__ import annotations

import inspect
import json
from collections import Counter, defaultdict
from pathlib import Path
from typing import get_type_hints

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, extrude_grid
from are_stats.export import (
    AUGMENT_TOPICS,
    MCAP_TOPICS,
    AugmentOptions,
    augment_bag,
    parse_start_time,
)
from are_stats.logs import BagTrajectory, TrajectoryOptions, read_trajectory
from are_stats.perception import PinholeCamera, optical_from_base, perceive_scene
from tests.export.rosbag_fixtures import (
    CAMERA,
    CAMERA_XYZ,
    DURATION,
    ODD_K,
    START,
    fit_read_once,
    robot_pose,
    write_bag,
)
from tests.helpers import assert_allclose

runner = CliRunner()
MAP = DEFAULT_MODELS / "courtyard.yaml"
START_NS = int(START * 1e9)


def write_fit_and_camera(d: Path) -> tuple[Path, Path]:
    """A small EM fit of a labelled log (``small.nc``) and a small camera (``cam.yaml``,
    :data:`CAMERA`) written in ``d``: the augment tests' inputs besides the bags."""
    from tests.test_cli_jobs import _quick_em_fit, _write_log

    log, _ = _write_log(d, labels=True)
    fit = d / "small.nc"
    _quick_em_fit(log, fit, samples=20)
    cam = d / "cam.yaml"
    cam.write_text(
        yaml.safe_dump(
            {"image_width": CAMERA["width"], "image_height": CAMERA["height"], "K": CAMERA["k"]}
        )
    )
    return fit, cam


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A small EM fit (labelled classes), the bags in three formats and a small camera."""
    d = tmp_path_factory.mktemp("augment")
    fit, cam = write_fit_and_camera(d)
    with fit_read_once(fit):  # the module's augment runs read this fit once, not 70 times
        yield {
            "dir": d,
            "fit": fit,
            "camera": cam,
            "ros1": write_bag(d / "robot.bag", "ros1"),
            "ros2": write_bag(d / "robot_ros2", "ros2"),
            "mcap": write_bag(d / "robot_mcap", "mcap"),
        }


def _read_mcap(path: Path) -> tuple[dict, dict, list]:
    """``{topic: [(log_time, message)]}``, ``{topic: schema name}`` and the channels."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs: dict = defaultdict(list)
    types: dict = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        channels = list(reader.get_summary().channels.values())
        for schema, channel, msg in reader.iter_messages():
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            types[channel.topic] = schema.name
            msgs[channel.topic].append((msg.log_time, ts.deserialize_cdr(msg.data, schema.name)))
    return msgs, types, channels


def _input_types(bag: Path) -> dict[str, str]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def _truth(times: np.ndarray) -> np.ndarray:
    """``T_map_base`` (T, 4, 4) of the fixture's robot at scenario times."""
    out = np.tile(np.eye(4), (len(times), 1, 1))
    for k, t in enumerate(times):
        x, y, yaw = robot_pose(float(t))
        out[k, :2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        out[k, :2, 3] = [x, y]
    return out


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
@pytest.mark.parametrize("topic", [None, "/robot_pose", "/amcl_pose"])
def test_read_trajectory_from_tf_and_pose_topics(files, kind, topic):
    tr = read_trajectory(files[kind], pose_topic=topic, camera_info_topic="/camera/camera_info")
    assert tr.start == pytest.approx(START) and tr.end == pytest.approx(START + DURATION)
    assert tr.t.size == int(DURATION * 10) + 1
    # map -> odom -> base_link composed (the odom offset undone), or the topic's poses
    np.testing.assert_allclose(tr.poses, _truth(tr.t - START), atol=1e-9)
    assert tr.camera_frame == "camera_optical_frame"
    np.testing.assert_allclose(tr.mount, optical_from_base(CAMERA_XYZ), atol=1e-12)
    assert tr.camera_info == {**CAMERA, "k": CAMERA["k"]}
    np.testing.assert_allclose(tr.camera_times - START, np.arange(0, DURATION + 0.01, 0.5))


def test_the_camera_mount_is_the_camera_infos_frame_not_the_first_optical_one(tmp_path):
    """An OAK-D-like tree mounts several optical frames: the mount is the chain to the
    ``CameraInfo``'s frame (or ``--camera-frame``), never a frame guessed by its name."""
    bag = write_bag(tmp_path / "oakd", "mcap", decoy=True)
    tr = read_trajectory(bag, camera_info_topic="/camera/camera_info")
    assert tr.camera_frame == "camera_optical_frame"
    np.testing.assert_allclose(tr.mount, optical_from_base(CAMERA_XYZ), atol=1e-12)
    left = read_trajectory(bag, camera_frame="left_camera_optical_frame")
    np.testing.assert_allclose(left.mount, optical_from_base((0, 0.1, 0.3)), atol=1e-12)
    assert read_trajectory(bag).mount is None  # no CameraInfo, no --camera-frame: no guess


def test_augment_reads_back_and_matches_perceive_scene(files, tmp_path):
    out = tmp_path / "aug.mcap"
    res = augment_bag(
        files["ros2"],
        files["fit"],
        MAP,
        out,
        5,
        camera_info_topic="/camera/camera_info",
        d_max=15.0,
        tau=5.0,
    )
    msgs, types, channels = _read_mcap(out)
    # the input's topics (passed through) and the new ones; the input has no /map
    assert types == {**_input_types(files["ros2"]), **AUGMENT_TOPICS}
    # times start at the bag's start and line up with its camera frames
    first = min(m[0][0] for m in msgs.values())
    assert first == START_NS
    stamps = [m.header.stamp for _, m in msgs["/augmented_map"]]
    assert stamps[0].sec * 10**9 + stamps[0].nanosec == START_NS
    n_frames = int(DURATION / 0.5) + 1
    np.testing.assert_allclose(res.times, np.arange(n_frames) * 0.5)
    assert len(msgs["/perceived"]) == len(msgs["/artefacts"]) == n_frames
    assert 1 <= len(msgs["/augmented_map"]) <= n_frames and len(msgs["/map"]) == 1
    # the grids have the map's size
    grid = OccupancyGrid.from_ros_yaml(MAP)
    for _, g in msgs["/map"] + msgs["/augmented_map"]:
        assert (g.info.width, g.info.height) == (grid.width, grid.height)
        assert len(g.data) == grid.width * grid.height
    assert (msgs["/augmented_map"][0][1].data == 100).sum() > (grid.data == 100).sum()
    # REP-105 frames: the robot's tree is the input's (odom -> base_link at every bag pose,
    # its static camera), the new frames map -> artefact_<id>
    parents = Counter()
    children = set()
    for _, m in msgs["/tf"]:
        for tr in m.transforms:
            parents[(tr.header.frame_id, tr.child_frame_id.split("_")[0])] += 1
            children.add(tr.child_frame_id)
    assert parents[("odom", "base")] == int(DURATION * 10) + 1
    assert parents[("map", "base")] == 0
    assert {f"artefact_{int(a)}" for a in res.scene.ids} >= children - {"base_link", "odom"}
    assert parents[("map", "artefact")] > 0
    ((_, static),) = msgs["/tf_static"]  # the input's
    assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
        ("base_link", "camera_link"),
        ("camera_link", "camera_optical_frame"),
    ]
    qos = {c.topic: c.metadata["offered_qos_profiles"] for c in channels}  # the new ones last
    (latched,) = yaml.safe_load(qos["/augmented_map"])  # the profile list ros2 bag play reads
    (volatile,) = yaml.safe_load(qos["/tf"])
    assert (latched["durability"], volatile["durability"]) == (1, 2)  # transient local, volatile
    assert latched["reliability"] == volatile["reliability"] == 1  # reliable
    # markers: a box and a class-label text per live artefact, coloured by A_f
    labels = set(res.scene.at(0.0).labels)
    _, arr = msgs["/artefacts"][0]
    text = [m.text for m in arr.markers if m.ns == "labels" and m.type == 9]
    cubes = [m for m in arr.markers if m.ns == "artefacts"]
    assert len(text) == len(cubes) == len(res.scene.at(0.0).ids) > 0
    assert {t.split()[0] for t in text} == labels
    # the perceived set equals a direct perceive_scene at the same times, from the truth
    cam = PinholeCamera.from_dict(CAMERA)
    poses = _truth(res.times) @ optical_from_base(CAMERA_XYZ)
    counts, seen = perceive_scene(
        res.scene, res.times, poses, extrude_grid(grid, 2.5), cam, 15.0, 5.0
    )
    assert seen.any(), "the test scenario should show the camera some artefacts"
    ids = res.scene.ids
    for f, (t_ns, m) in enumerate(msgs["/perceived"]):
        doc = json.loads(m.data)
        assert t_ns == START_NS + round(res.times[f] * 1e9)
        assert doc["perceived"] == [int(a) for a in ids[seen[f]] if a in doc["live"]]
        for a, c in doc["counts"].items():
            assert c == counts[f, list(ids).index(int(a))]
        assert set(doc["labels"].values()) <= set(res.scene.labels)
    for (_, arr), row in zip(msgs["/artefacts"], seen, strict=True):
        green = {m.id for m in arr.markers if m.ns == "artefacts" and m.color.g > m.color.r}
        assert green == {int(a) for a in ids[row]}


def test_augment_cli_ros1_mcap_reproducible(files, tmp_path):
    from rosbags.highlevel import AnyReader

    out = tmp_path / "a.mcap"
    args = [
        "augment",
        files["ros1"],
        "--fit",
        files["fit"],
        "--map",
        "courtyard",
        "--out",
        out,
        "--seed",
        "2",
        "--pose-topic",
        "/amcl_pose",
        "--camera",
        files["camera"],
        "--period",
        "1.0",
    ]
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output
    first = out.read_bytes()
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2 and "already exists" in res.output and "--force" in res.output
    res = runner.invoke(app, [str(a) for a in [*args, "--force"]])
    assert res.exit_code == 0, res.output
    assert out.read_bytes() == first  # same seed, same bytes
    # rosbags (as ros2 bag play would) reads it as a ROS 2 bag
    with AnyReader([out]) as reader:
        assert reader.start_time == START_NS
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics == {**_input_types(files["ros1"]), **AUGMENT_TOPICS}
        n = Counter(c.topic for c, _, _ in reader.messages())
    assert n["/perceived"] == int(DURATION) + 1 and n["/map"] == 1
    # from the MCAP bag's /tf with a named base frame, camera frames every 0.5 s
    out2 = tmp_path / "b.mcap"
    args2 = [
        "augment",
        files["mcap"],
        "--fit",
        files["fit"],
        "--map",
        MAP,
        "--out",
        out2,
        "--seed",
        "2",
        "--base-frame",
        "base_link",
        "--camera",
        files["camera"],
    ]
    res = runner.invoke(app, [str(a) for a in args2])
    assert res.exit_code == 0, res.output


def test_augment_errors(files, tmp_path, monkeypatch):
    import arviz as az

    def run(*extra, bag=files["ros2"]):
        args = [
            "augment",
            bag,
            "--fit",
            files["fit"],
            "--map",
            MAP,
            "--out",
            tmp_path / "o.mcap",
            "--seed",
            "1",
            *extra,
        ]
        return runner.invoke(app, [str(a) for a in args])

    bare = write_bag(tmp_path / "bare", "ros2", tf=False, poses=False)
    res = run(bag=bare)
    assert res.exit_code == 2
    assert "robot poses" in res.output and "/camera/camera_info" in res.output
    res = run("--pose-topic", "/nope")
    assert res.exit_code == 2 and "/nope" in res.output and "/amcl_pose" in res.output
    res = run("--pose-topic", "/camera/camera_info")
    assert res.exit_code == 2 and "sensor_msgs/msg/CameraInfo" in res.output
    odom = write_bag(tmp_path / "odom", "ros2", camera=False, pose_frame="odom")
    res = run("--pose-topic", "/robot_pose", bag=odom)  # odom poses, a tree with a map frame
    assert res.exit_code == 2 and "'map'" in res.output and "got 'odom' in a bag" in res.output
    assert "--map-frame odom" in res.output
    res = run("--base-frame", "robot")
    assert res.exit_code == 2 and "map -> ... -> robot" in res.output
    res = run("--pose-topic", "/amcl_pose", "--base-frame", "base_link")
    assert res.exit_code == 2 and "either --pose-topic or --base-frame" in res.output
    res = run("--camera", files["camera"], "--camera-info-topic", "/camera/camera_info")
    assert res.exit_code == 2 and "either --camera or --camera-info-topic" in res.output
    far = tmp_path / "far.yaml"
    far.write_text(
        MAP.read_text()
        .replace("image: courtyard.pgm", f"image: {MAP.with_suffix('.pgm')}")
        .replace("[-20.0, -15.0, 0.0]", "[100.0, 100.0, 0.0]")
    )
    args = [
        "augment",
        files["ros2"],
        "--fit",
        files["fit"],
        "--map",
        far,
        "--out",
        tmp_path / "o.mcap",
        "--seed",
        "1",
    ]
    res = runner.invoke(app, [str(a) for a in args])
    # the one rule perceive shares (perception.check_poses_inside): wholly outside refuses
    assert res.exit_code == 2 and "inside the map" in res.output and "all 121 outside" in res.output
    idata = az.from_netcdf(files["fit"])
    del idata.posterior.attrs["area"]
    nofit = tmp_path / "noarea.nc"
    idata.to_netcdf(str(nofit))
    args[3] = nofit
    args[5] = MAP
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2 and "area" in res.output
    monkeypatch.setenv("ARE_STATS_MAX_WORK", "1e6")  # what --max-work 1e6 sets
    res = run()
    assert res.exit_code == 2 and "tracing 25 camera frames of 307200 pixels" in res.output
    assert not (tmp_path / "o.mcap").exists()


def test_parse_start_time():
    assert parse_start_time("2024-11-24T20:26:40Z") == START
    assert parse_start_time("2024-11-24T21:26:40+01:00") == START
    assert parse_start_time(str(START)) == START
    for bad in ("yesterday", "-1", True, "nan"):
        with pytest.raises(ValueError, match="--start-time"):
            parse_start_time(bad)


def test_experiment_mcap_has_tf_and_text_markers(tmp_path):
    """``experiment --mcap`` writes REP-105 frames and text markers; its mission runs on
    ``--scheduler``, a cluster of threads in this process (the mission is the same;
    ``tests/experiments/test_sweep.py::test_cli_experiment_and_plot`` runs the command's
    own local worker processes), so the test does not start and import a worker process."""
    from distributed import LocalCluster

    cfg = {
        "name": "tiny",
        "map": "courtyard",
        "seed": 3,
        "replicates": 1,
        "scenario": {
            "arrival_rate": 0.001,
            "leave_rate": 0.05,
            "mix_weights": [1.0],
            "mix_rates": [0.5],
        },
        "mission": {"n_goals": 1, "time_limit": 15.0},
        "planner": {"algorithm": "astar"},
    }
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(cfg))
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        res = runner.invoke(
            app,
            [
                "experiment",
                str(config),
                "--out",
                str(tmp_path / "res"),
                "--mcap",
                str(tmp_path / "mcap"),
                "--start-time",
                "2024-11-24T20:26:40Z",
                "--scheduler",
                cluster.scheduler_address,
            ],
        )
    assert res.exit_code == 0, res.output
    (path,) = sorted((tmp_path / "mcap").glob("*.mcap"))
    msgs, types, _ = _read_mcap(path)
    assert set(types) <= set(MCAP_TOPICS) and {"/tf", "/tf_static", "/artefacts"} <= set(types)
    assert min(m[0][0] for m in msgs.values()) == START_NS
    frames = {(t.header.frame_id, t.child_frame_id) for _, m in msgs["/tf"] for t in m.transforms}
    assert ("map", "base_link") in frames
    assert any(c.startswith("artefact_") for _, c in frames)
    texts = [m for _, a in msgs["/artefacts"] for m in a.markers if m.type == 9]
    assert texts and all(m.text for m in texts)


# ---- the bag door (issue 30) and one clock (issue 27) -------------------------------------


def _augment(files, bag, out, *extra, seed=1):
    args = ["augment", bag, "--fit", files["fit"], "--map", MAP, "--out", out]
    return runner.invoke(app, [str(a) for a in [*args, "--seed", str(seed), *extra]])


@pytest.fixture(scope="module")
def augmented(files, tmp_path_factory):
    """``augmented(bag, *extra, seed=1)``: the CLI result and output ``.mcap`` of
    :func:`_augment` with those arguments, run once per module: tests that only read the
    same run's output share it (each had run it again)."""
    runs: dict = {}
    folder = tmp_path_factory.mktemp("shared_runs")

    def run(bag, *extra, seed=1):
        key = (str(bag), tuple(str(e) for e in extra), seed)
        if key not in runs:
            out = folder / f"run{len(runs)}.mcap"
            runs[key] = (_augment(files, bag, out, *extra, seed=seed), out)
        return runs[key]

    return run


def _in_thread(fn, seconds=60.0):
    """``fn()`` in a daemon thread; fails (instead of hanging the suite) if it blocks."""
    import threading

    out: dict = {}

    def target():
        try:
            out["value"] = fn()
        except Exception as err:  # noqa: BLE001 (re-raised in the caller's thread)
            out["error"] = err

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(seconds)
    assert not th.is_alive(), f"still blocked after {seconds} s"
    if "error" in out:
        raise out["error"]
    return out["value"]


def test_augment_refuses_special_files_at_once(files, tmp_path):
    import os
    import shutil

    from are_stats.logs import read_tracks_bag

    fifo = tmp_path / "pipe.bag"
    os.mkfifo(fifo)
    zero = tmp_path / "zero.mcap"
    zero.symlink_to("/dev/zero")
    folder = tmp_path / "folder.bag"
    folder.mkdir()
    (folder / "notes.txt").write_text("not a bag")
    inner = tmp_path / "inner"  # a ROS 2 bag folder whose storage file is a FIFO
    shutil.copytree(files["ros2"], inner)
    (db3,) = inner.glob("*.db3")
    db3.unlink()
    os.mkfifo(db3)
    cases = [
        (fifo, "got a FIFO, a device or a socket"),
        (zero, "got a FIFO, a device or a socket"),
        (folder, "got a folder without metadata.yaml"),
        (inner, f"{db3.name}: expected a regular file in the bag folder, got a special file"),
    ]
    for bag, got in cases:
        res = _in_thread(lambda bag=bag: _augment(files, bag, tmp_path / "o.mcap"))
        assert res.exit_code == 2, res.output
        assert str(bag) in res.output and got in res.output
        with pytest.raises(ValueError, match=got.split(":")[-1].strip()):
            _in_thread(lambda bag=bag: read_tracks_bag(bag))
    assert not (tmp_path / "o.mcap").exists()
    # a ROS 2 bag folder stays a bag
    assert read_trajectory(files["ros2"]).t.size == int(DURATION * 10) + 1


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
def test_augment_refuses_a_1970_stamp_among_2026_ones(files, tmp_path, kind):
    path = tmp_path / ("b.bag" if kind == "ros1" else "b")
    bag = write_bag(path, kind, outlier=True)
    for extra, where in (
        ((), "topic /tf, odom -> base_link, message 38"),
        (("--pose-topic", "/amcl_pose"), "topic /amcl_pose, message 38"),
    ):
        res = _augment(files, bag, tmp_path / "o.mcap", *extra)
        assert res.exit_code == 2, res.output
        text = " ".join(res.output.split())
        # placed by its recording time into the bag (as augment's errors), dates in brackets
        want = (
            f"{where} (recorded 3.700 s into the bag), stamp 5.250000000 s (1970-01-01T00:00:05Z)"
        )
        assert want in text, text
        assert "other 120 messages (recorded 0.000 to 12.000 s into the bag, stamped 20" in text
        assert "a stamp of another clock or a damaged one" in text
    # the recording time in 1970 too: refused on the recording clock as well
    path2 = tmp_path / ("c.bag" if kind == "ros1" else "c")
    bag2 = write_bag(path2, kind, outlier_log=True, outlier=True)
    res = _augment(files, bag2, tmp_path / "o.mcap", "--clock", "log")
    assert res.exit_code == 2 and "(1970-01-01T00:00:05Z)" in res.output, res.output
    assert not (tmp_path / "o.mcap").exists()


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
def test_augment_refuses_non_finite_poses_and_non_unit_quaternions(files, tmp_path, kind):
    x, y, _ = robot_pose(ODD_K / 10)
    nan = float("nan")
    cases = [
        ((x, y, (nan, 0.0, 0.0, 1.0)), "expected a finite quaternion"),
        ((x, y, (0.0, 0.0, 0.5, 0.5)), "expected a unit quaternion"),
        ((x, y, (0.0, 0.0, 0.0, 0.0)), "of norm 0"),
        ((nan, y, (0.0, 0.0, 0.0, 1.0)), "expected a finite position"),
        ((x, float("inf"), (0.0, 0.0, 0.0, 1.0)), "expected a finite position"),
    ]
    for i, (bad, expected) in enumerate(cases):
        for j, (which, extra, where) in enumerate(
            (
                ({"poses": False}, (), "topic /tf, message 38, transform 0 (odom -> base_link)"),
                ({"tf": False}, ("--pose-topic", "/amcl_pose"), "topic /amcl_pose, message 38"),
            )
        ):
            path = tmp_path / (f"b{i}{j}.bag" if kind == "ros1" else f"b{i}{j}")
            bag = write_bag(path, kind, bad=bad, **which)
            res = _augment(files, bag, tmp_path / "o.mcap", *extra)
            assert res.exit_code == 2, res.output
            assert str(bag) in res.output and where in res.output and expected in res.output


def test_nearly_unit_quaternions_are_renormalised(tmp_path):
    # float32 round-off and tf2's tolerance: accepted, renormalised to the same rotation
    x, y, yaw = robot_pose(ODD_K / 10)
    q = 1.004 * np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    bag = write_bag(tmp_path / "near", "mcap", bad=(x, y, tuple(q)))
    for topic in (None, "/amcl_pose"):
        tr = read_trajectory(bag, pose_topic=topic)
        np.testing.assert_allclose(tr.poses, _truth(tr.t - START), atol=1e-9)


def test_since_start_without_exact_stamps_rounds_the_times_to_nanoseconds():
    t = np.array([10.0, 10.25, 10.5])
    poses = np.tile(np.eye(4), (3, 1, 1))
    tr = BagTrajectory(t, poses, 10.0, 10.5, None, None, None, None, "test", 10_000_000_000)
    np.testing.assert_allclose(tr.since_start, [0.0, 0.25, 0.5], rtol=0, atol=1e-12)


def test_augment_sim_time_bag_uses_one_clock(files, tmp_path):
    from tests.export.rosbag_fixtures import SIM_START, stamp_ns

    bag = write_bag(tmp_path / "sim", "mcap", header_start=SIM_START)
    topic = "/camera/camera_info"
    tr = read_trajectory(bag, camera_info_topic=topic)
    assert tr.clock == "header" and "simulation time" in tr.clock_note
    poses_ns = [stamp_ns(k / 10, SIM_START) for k in range(int(DURATION * 10) + 1)]
    np.testing.assert_array_equal(tr.t_ns, poses_ns)
    assert tr.start_ns == poses_ns[0] and tr.camera_ns[0] == poses_ns[0]
    np.testing.assert_allclose(tr.poses, _truth(tr.t - SIM_START), atol=1e-9)
    # scene times from the exact stamps: k / 10 s after the start, not the float epoch's
    # round-off (1e-7 s at 1.7e9 s)
    np.testing.assert_allclose(tr.since_start, np.arange(len(poses_ns)) / 10, rtol=0, atol=1e-12)
    log = read_trajectory(bag, camera_info_topic=topic, clock="log")
    assert log.clock == "log" and log.start_ns == START_NS
    np.testing.assert_allclose(log.poses, tr.poses, atol=1e-12)
    # the CLI: header stamps by default, said in the summary; artefacts alive in the frames
    out = tmp_path / "sim_are.mcap"
    res = _augment(files, bag, out, "--camera-info-topic", topic, "--d-max", "15", seed=5)
    assert res.exit_code == 0, res.output
    assert "clock: header stamps" in res.output and "simulation time" in res.output
    msgs, _, _ = _read_mcap(out)
    docs = [json.loads(m.data) for _, m in msgs["/perceived"]]
    assert all(d["live"] for d in docs), "every camera frame should see live artefacts"
    assert any(d["perceived"] for d in docs)
    # the input's messages passed through with their stamps and recording times; the new
    # ones stamped on the header clock, logged on the recording clock beside them
    base = [
        (ns, tr_.header.stamp.sec * 10**9 + tr_.header.stamp.nanosec)
        for ns, m in msgs["/tf"]
        for tr_ in m.transforms
        if tr_.child_frame_id == "base_link"
    ]
    logs = [stamp_ns(k / 10) for k in range(int(DURATION * 10) + 1)]
    assert [s for _, s in base] == poses_ns and [n for n, _ in base] == logs
    cam_ns = [stamp_ns(k / 2, SIM_START) for k in range(int(DURATION * 2) + 1)]
    assert [ns for ns, _ in msgs["/perceived"]] == [stamp_ns(k / 2) for k in range(25)]
    art = [(ns, m.header.stamp) for ns, a in msgs["/artefacts"] for m in a.markers[:1]]
    assert [s.sec * 10**9 + s.nanosec for _, s in art] == cam_ns
    ((ns, grid),) = msgs["/map"]
    assert (
        ns == START_NS
        and grid.header.stamp.sec * 10**9 + grid.header.stamp.nanosec == (poses_ns[0])
    )
    # --clock log: the recording times for all
    res = _augment(
        files, bag, tmp_path / "log.mcap", "--camera-info-topic", topic, "--clock", "log", seed=5
    )
    assert res.exit_code == 0 and "clock: recording times (--clock log" in res.output
    msgs, _, _ = _read_mcap(tmp_path / "log.mcap")
    assert msgs["/perceived"][0][0] == START_NS
    assert all(json.loads(m.data)["live"] for _, m in msgs["/perceived"])
    st = msgs["/artefacts"][0][1].markers[0].header.stamp  # still on the header clock
    assert st.sec * 10**9 + st.nanosec == stamp_ns(0.0, SIM_START)
    res = _augment(files, bag, tmp_path / "x.mcap", "--clock", "wall")
    assert res.exit_code == 2 and "--clock: expected one of 'auto', 'header', 'log'" in res.output


def test_augment_period_past_the_limits_is_refused_before_allocating(files, tmp_path):
    res = _augment(
        files, files["ros2"], tmp_path / "o.mcap", "--camera", files["camera"], "--period", "1e-9"
    )
    assert res.exit_code == 2, res.output
    assert "1.2e+10 camera frames" in res.output and "memory limit" in res.output
    assert not (tmp_path / "o.mcap").exists()


def test_augment_refuses_a_run_without_live_artefacts(files, tmp_path):
    import pandas as pd

    from tests.test_cli_jobs import _quick_em_fit

    # 20 artefacts of 2 s each over 1e6 s: a 12 s bag almost surely meets none
    n = 20
    t0 = np.arange(n) * 50_000.0 + 1000.0
    pd.DataFrame(
        {
            "id": [f"r{i}" for i in range(n)],
            "t_arrive": t0,
            "t_leave": t0 + 2.0,
            "mark": np.arange(n) % 3 + 1,
            "label": ["small"] * n,
        }
    ).to_csv(tmp_path / "rare.csv", index=False)
    (tmp_path / "rare.yaml").write_text(yaml.safe_dump({"window": [0.0, 1e6], "area": 400.0}))
    fit = tmp_path / "rare.nc"
    _quick_em_fit(tmp_path / "rare.csv", fit, samples=20)
    out = tmp_path / "o.mcap"
    args = ["augment", files["ros2"], "--fit", fit, "--map", MAP, "--out", out, "--seed", "1"]
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2, res.output
    assert "expected at least one artefact over the bag's 12.000 s" in res.output
    assert "try another --seed" in res.output and not out.exists()


def test_no_artefact_alive_in_any_frame_is_refused_against_brute_force(files):
    """The refusal agrees with ``Scene.alive`` at every frame (random scenes, seeded), and
    says why and what to try."""
    import pandas as pd

    from are_stats.environment import load_catalogue
    from are_stats.export._augment import _check_alive
    from are_stats.scenarios import Scene

    catalogue = load_catalogue()
    traj = read_trajectory(files["ros2"])
    rng = np.random.default_rng(30)
    times = np.arange(0.0, 12.01, 0.5)
    refused = 0
    for _ in range(200):
        n = int(rng.integers(1, 4))
        arrive = rng.choice(np.r_[rng.uniform(-1.0, 13.0, 8), times], n)
        stay = rng.choice([0.05, 0.2, 0.5, 1.0, 40.0], n)
        art = pd.DataFrame(
            {"t_arrive": arrive, "t_leave": arrive + stay, "x": 0.0, "y": 0.0, "yaw": 0.0}
        )
        scene = Scene.from_scenarios(art, catalogue)
        truth = any(scene.alive(float(t)).any() for t in times)
        if truth:
            _check_alive(scene, times, 12.0, traj, "b.bag", 1)
        else:
            refused += 1
            with pytest.raises(ValueError, match="alive in a camera frame") as err:
                _check_alive(scene, times, 12.0, traj, "b.bag", 1)
            assert "try --clock header or --clock log, another --seed" in str(err.value)
    assert 0 < refused < 200


# ---- pass-through and REP-105 (issue 27) --------------------------------------------------

NEW = ("/augmented_map", "/artefacts", "/perceived", "/map")


def _raw_channels(path: Path) -> list[tuple[str, dict, list]]:
    """The MCAP's channels in registration order: ``(topic, metadata, [(log_time,
    publish_time, bytes)])``."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        chans = reader.get_summary().channels
        out = {k: (c.topic, dict(c.metadata), []) for k, c in sorted(chans.items())}
        for _, c, m in reader.iter_messages(log_time_order=True):
            out[c.id][2].append((m.log_time, m.publish_time, bytes(m.data)))
    return list(out.values())


def _input_raw(bag: Path) -> dict[str, list]:
    """``{topic: [(log_time, bytes)]}`` of a ROS 2 bag, the bytes as stored (rosbags)."""
    from rosbags.highlevel import AnyReader

    out: dict = defaultdict(list)
    with AnyReader([bag]) as reader:
        for c, ts, raw in reader.messages():
            out[c.topic].append((ts, bytes(raw)))
    return out


def _tf_links(msgs: dict) -> set[tuple[str, str]]:
    return {
        (t.header.frame_id, t.child_frame_id)
        for topic in ("/tf", "/tf_static")
        for _, m in msgs.get(topic, [])
        for t in m.transforms
    }


@pytest.mark.parametrize("kind", ["mcap", "ros2"])
def test_augment_passes_every_input_channel_through_unchanged(files, augmented, kind):
    topic = "/camera/camera_info"
    res, out = augmented(files[kind], "--camera-info-topic", topic, "--d-max", "15", seed=5)
    assert res.exit_code == 0, res.output
    assert "passed through: /tf_static 1, /tf 121" in res.output
    ins = _input_raw(files[kind])
    chans = _raw_channels(out)
    # the input's channels first: same topic, count, log times and bytes, in order
    assert [c[0] for c in chans[: len(ins)]] == list(ins)
    for t, meta, rows in chans[: len(ins)]:
        assert [(lg, data) for lg, _, data in rows] == ins[t], t
        assert meta["offered_qos_profiles"]  # the input's QoS kept
    # plus only new channels: artefact frames on /tf, no /tf_static, the new topics
    new = chans[len(ins) :]
    assert sorted(c[0] for c in new) == sorted(["/tf", *NEW])
    msgs, _, _ = _read_mcap(out)
    links = _tf_links(msgs)
    in_links = _tf_links(_read_mcap(next(Path(files["mcap"]).parent.glob("*.mcap")))[0])
    assert in_links and {("map", "odom"), ("odom", "base_link")} <= in_links
    added = links - in_links
    assert added and all(p == "map" and c.startswith("artefact_") for p, c in added)
    # every child frame has one parent across input and output together
    parents = defaultdict(set)
    for p, c in links | in_links:
        parents[c].add(p)
    assert all(len(v) == 1 for v in parents.values()), dict(parents)
    # artefacts alive, their markers with a lifetime (no ghosts in a partial replay)
    docs = [json.loads(m.data) for _, m in msgs["/perceived"]]
    assert any(d["live"] for d in docs) and any(d["perceived"] for d in docs)
    cubes = [m for _, a in msgs["/artefacts"] for m in a.markers if m.ns == "artefacts"]
    assert cubes and all(m.lifetime.sec * 10**9 + m.lifetime.nanosec == 10**9 for m in cubes)


def test_augment_ros1_bag_is_converted_to_ros2_cdr(files, tmp_path):
    from rosbags.highlevel import AnyReader

    out = tmp_path / "aug.mcap"
    res = _augment(files, files["ros1"], out, "--camera-info-topic", "/camera/camera_info")
    assert res.exit_code == 0, res.output
    ref, _, _ = _read_mcap(next(Path(files["mcap"]).parent.glob("*.mcap")))
    msgs, types, _ = _read_mcap(out)  # every message decodes as ROS 2 CDR
    with AnyReader([files["ros1"]]) as reader:
        n_in = {c.topic: c.msgcount for c in reader.connections}

    def theirs(topic):  # the input's messages (the /tf channel also holds the artefacts')
        return [
            (lg, m)
            for lg, m in msgs[topic]
            if topic != "/tf" or not m.transforms[0].child_frame_id.startswith("artefact_")
        ]

    for t, n in n_in.items():
        mine = theirs(t)
        assert len(mine) == n and [lg for lg, _ in mine] == [lg for lg, _ in ref[t]], t
    # the same transforms and camera intrinsics as the ROS 2 recording of the same run
    added = _tf_links(msgs) - _tf_links(ref)
    assert added and all(p == "map" and c.startswith("artefact_") for p, c in added)
    k = [list(m.k) for _, m in msgs["/camera/camera_info"]]
    assert k == [list(m.k) for _, m in ref["/camera/camera_info"]]
    assert types["/tf"] == "tf2_msgs/msg/TFMessage"


def test_augment_topics_selects_what_passes_through(files, tmp_path):
    out = tmp_path / "sel.mcap"
    res = _augment(
        files, files["mcap"], out, "--camera", files["camera"], "--topics", "/tf,/tf_static"
    )
    assert res.exit_code == 0, res.output
    chans = _raw_channels(out)
    assert sorted(c[0] for c in chans) == sorted(["/tf", "/tf_static", "/tf", *NEW])
    res = _augment(files, files["mcap"], tmp_path / "x.mcap", "--topics", "/tf,/nope")
    assert res.exit_code == 2 and "--topics /nope" in res.output and "/amcl_pose" in res.output
    assert not (tmp_path / "x.mcap").exists()


def test_augment_odom_only_bag_puts_artefacts_in_odom(files, tmp_path):
    bag = write_bag(tmp_path / "odom", "mcap", map_tf=False, poses=False)
    out = tmp_path / "odom.mcap"
    res = _augment(files, bag, out, "--camera-info-topic", "/camera/camera_info", "--d-max", "15")
    assert res.exit_code == 0, res.output
    assert "note: the bag's tree has no frame 'map'" in res.output and "'odom'" in res.output
    msgs, _, _ = _read_mcap(out)
    links = _tf_links(msgs)
    assert ("map", "odom") not in links and ("odom", "base_link") in links
    art = {p for p, c in links if c.startswith("artefact_")}
    assert art == {"odom"}
    assert {m.header.frame_id for _, a in msgs["/artefacts"] for m in a.markers} == {"odom"}
    # --map-frame names the fixed frame: a bag with a map frame read in odom, no note
    out2 = tmp_path / "o2.mcap"
    res = _augment(files, files["mcap"], out2, "--map-frame", "odom", "--camera", files["camera"])
    assert res.exit_code == 0 and "no frame" not in res.output, res.output  # no frame note
    assert {p for p, c in _tf_links(_read_mcap(out2)[0]) if c.startswith("artefact_")} == {"odom"}
    res = _augment(files, files["mcap"], tmp_path / "o3.mcap", "--map-frame", "nowhere")
    assert res.exit_code == 2 and "nowhere -> ... -> base_link" in res.output


@pytest.mark.parametrize("tf", [False, True])
def test_augment_odom_only_bag_from_its_odometry_topic(files, tmp_path, tf):
    """``--pose-topic`` with poses in ``odom`` in a bag without a ``map`` frame (no /tf, or
    a tree ``odom -> base_link`` only): read in ``odom`` with a note, as from /tf."""
    bag = write_bag(tmp_path / "odom", "mcap", tf=tf, map_tf=False, pose_frame="odom")
    out = tmp_path / "odom.mcap"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera", files["camera"])
    assert res.exit_code == 0, res.output
    said = " ".join(res.output.split())
    assert "note: the bag has no frame 'map' and /amcl_pose is in 'odom'" in said, said
    msgs, _, _ = _read_mcap(out)
    links = _tf_links(msgs)
    assert {p for p, c in links if c.startswith("artefact_")} == {"odom"}
    assert {m.header.frame_id for _, a in msgs["/artefacts"] for m in a.markers} == {"odom"}
    assert ("odom", "base_link") in links and not any(p == "map" for p, _ in links)
    tr = read_trajectory(bag, pose_topic="/amcl_pose")
    assert tr.frame == "odom"
    np.testing.assert_allclose(tr.poses, _truth(tr.t - START), atol=1e-9)


def test_augment_qos_in_the_input_bags_form(files, augmented, tmp_path):
    from tests.export.rosbag_fixtures import jazzy_mcap

    src = next(Path(files["mcap"]).parent.glob("*.mcap"))
    assert src == Path(files["mcap"])  # the run the camera-mount test reads too
    for bag, form in ((src, "int"), (jazzy_mcap(src, tmp_path / "jazzy.mcap"), "string")):
        res, out = augmented(bag, "--camera", files["camera"])
        assert res.exit_code == 0, res.output
        n_in = len(_raw_channels(bag))
        for topic, meta, _ in _raw_channels(out)[n_in:]:
            (qos,) = yaml.safe_load(meta["offered_qos_profiles"])
            latched = topic in ("/map", "/augmented_map")
            if form == "int":
                assert (qos["reliability"], qos["durability"]) == (1, 1 if latched else 2)
                assert "topic_type_hash" not in meta
            else:
                durability = "transient_local" if latched else "volatile"
                assert (qos["reliability"], qos["durability"]) == ("reliable", durability)
                assert meta["topic_type_hash"].startswith("RIHS01_")


def test_augment_refuses_a_bag_holding_the_new_topics(files, tmp_path):
    bag = write_bag(tmp_path / "clash", "mcap", extra="/perceived")
    out = tmp_path / "o.mcap"
    res = _augment(files, bag, out, "--camera", files["camera"])
    assert res.exit_code == 2, res.output
    assert "topic /perceived" in res.output and "leave them out with --topics" in res.output
    assert not out.exists()
    keep = "/tf,/tf_static,/camera/camera_info"
    res = _augment(files, bag, out, "--camera", files["camera"], "--topics", keep)
    assert res.exit_code == 0, res.output


def test_augment_pose_topic_only_bag_still_publishes_the_robot(files, tmp_path):
    bag = write_bag(tmp_path / "poses", "mcap", tf=False)
    out = tmp_path / "p.mcap"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera", files["camera"])
    assert res.exit_code == 0, res.output
    msgs, _, _ = _read_mcap(out)
    links = _tf_links(msgs)
    assert ("map", "base_link") in links and ("base_link", "camera_optical_frame") in links
    assert len(msgs["/amcl_pose"]) == int(DURATION * 10) + 1


def test_augment_pose_topic_bag_with_a_static_tree_keeps_one_parent_per_frame(files, tmp_path):
    """A bag with ``/tf_static`` (the camera's chain) but no ``/tf``: ``map -> base_link``
    is published, the camera mount is not (the input's chain has it), so every frame keeps
    one parent across the input and the output."""
    bag = write_bag(tmp_path / "static", "mcap", drop=("/tf",))
    out = tmp_path / "s.mcap"
    cam = "/camera/camera_info"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera-info-topic", cam)
    assert res.exit_code == 0 and "note:" not in res.output, res.output
    msgs, _, _ = _read_mcap(out)
    ins, _, _ = _read_mcap(next(Path(bag).parent.glob("*.mcap")) if Path(bag).is_dir() else bag)
    parents = defaultdict(set)
    for p, c in _tf_links(msgs) | _tf_links(ins):
        parents[c].add(p)
    assert parents["base_link"] == {"map"}
    assert parents["camera_optical_frame"] == {"camera_link"}
    assert all(len(v) == 1 for v in parents.values()), dict(parents)
    assert len(msgs["/tf_static"]) == 1  # the input's


def _matrix(translation, rotation) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([rotation.x, rotation.y, rotation.z, rotation.w]).as_matrix()
    m[:3, 3] = [translation.x, translation.y, translation.z]
    return m


def _stamp(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def test_augment_places_the_root_of_the_bases_static_chain(files, tmp_path):
    """A TurtleBot's bag: ``/tf_static`` has ``base_footprint -> base_link``, the poses come
    from a topic. ``map -> base_footprint`` is published (not a second parent of
    ``base_link``), and ``base_link`` composed through it is the pose topic's pose."""
    bag = write_bag(tmp_path / "footprint", "mcap", drop=("/tf",), base_parent="base_footprint")
    out = tmp_path / "f.mcap"
    cam = "/camera/camera_info"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera-info-topic", cam)
    assert res.exit_code == 0 and "note:" not in res.output, res.output
    msgs, _, _ = _read_mcap(out)
    ins, _, _ = _read_mcap(bag)
    parents = defaultdict(set)
    for p, c in _tf_links(msgs) | _tf_links(ins):
        parents[c].add(p)
    assert parents["base_link"] == {"base_footprint"} and parents["base_footprint"] == {"map"}
    assert all(len(v) == 1 for v in parents.values()), dict(parents)
    (static,) = [t for _, m in ins["/tf_static"] for t in m.transforms
                 if t.child_frame_id == "base_link"]  # fmt: skip
    fp_base = _matrix(static.transform.translation, static.transform.rotation)
    truth = {
        _stamp(m.header): _matrix(m.pose.pose.position, m.pose.pose.orientation)
        for _, m in ins["/amcl_pose"]
    }
    placed = [
        (t, _stamp(t.header))
        for _, m in msgs["/tf"]
        for t in m.transforms
        if t.child_frame_id == "base_footprint"
    ]
    assert sorted(s for _, s in placed) == sorted(truth)  # one transform per pose
    for t, ns in placed:
        map_fp = _matrix(t.transform.translation, t.transform.rotation)
        assert_allclose(map_fp @ fp_base, truth[ns], atol=1e-9)


def test_augment_refuses_a_static_chain_that_holds_the_map_frame(files, tmp_path):
    bag = write_bag(tmp_path / "pinned", "mcap", drop=("/tf",), base_parent="map")
    out = tmp_path / "p.mcap"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera", files["camera"])
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "topic /tf_static" in errors[0], res.output
    assert "map -> base_link" in errors[0] and "--topics" in errors[0]
    assert not out.exists()


def test_augment_refuses_a_ros1_topic_it_cannot_convert(files, tmp_path):
    bag = write_bag(tmp_path / "damaged.bag", "ros1", damaged="/note")
    out = tmp_path / "o.mcap"
    res = _augment(files, bag, out, "--camera", files["camera"])
    assert res.exit_code == 2, res.output
    assert "topic '/note', message" in res.output and "convertible to ROS 2 CDR" in res.output
    assert "--topics" in res.output and not out.exists()
    keep = "/tf,/tf_static,/camera/camera_info"
    res = _augment(files, bag, out, "--camera", files["camera"], "--topics", keep)
    assert res.exit_code == 0, res.output
    assert "/note" not in {c[0] for c in _raw_channels(out)}


def test_augment_says_when_the_camera_mount_is_not_the_bags_tree(files, augmented, tmp_path):
    """The mount is the bag's tree (the CameraInfo's frame) or a note says what it is and
    how to use the bag's camera: never a silent shortcut."""
    cam = "/camera/camera_info"
    res = _augment(files, files["mcap"], tmp_path / "a.mcap", "--camera-info-topic", cam)
    assert res.exit_code == 0 and "note:" not in res.output, res.output
    res, _ = augmented(files["mcap"], "--camera", files["camera"])
    said = " ".join(res.output.split())
    assert res.exit_code == 0, res.output
    assert "note: camera: the --camera file, mounted by default, 1 m above the base" in said
    assert f"--camera-info-topic {cam} uses the bag's" in said
    # a CameraInfo whose frame has no static chain from the base (no /tf_static at all)
    bag = write_bag(tmp_path / "notree", "mcap", tf=False)
    out = tmp_path / "c.mcap"
    res = _augment(files, bag, out, "--pose-topic", "/amcl_pose", "--camera-info-topic", cam)
    said = " ".join(res.output.split())
    assert res.exit_code == 0, res.output
    assert (
        "note: the bag's tree has no static chain base_link -> ... -> camera_optical_frame" in said
    )
    msgs, _, _ = _read_mcap(out)  # the mount published is the one the note names
    ((_, static),) = msgs["/tf_static"]
    (mount,) = static.transforms
    assert (mount.header.frame_id, mount.child_frame_id) == ("base_link", "camera_optical_frame")
    assert mount.transform.translation.z == pytest.approx(1.0)


def test_augment_moves_the_artefacts_as_generate_does(files, tmp_path):
    """``augment`` assembles and moves its scene as ``generate --behaviours`` does (same
    fit, seed and horizon: the bag's 12 s): every ``map -> artefact_<id>`` of the output
    is the generated scene's box at that camera frame, and the artefacts walk."""
    from are_stats.environment import load_catalogue
    from are_stats.scenarios import read_scenes, scenes_from_tables

    out = tmp_path / "aug.mcap"
    res = _augment(files, files["mcap"], out, "--camera", files["camera"], seed=5)
    assert res.exit_code == 0, res.output
    gen = tmp_path / "gen"
    args = ["generate", files["fit"], "--scenarios", "1", "--horizon", "12", "--seed", "5"]
    res = runner.invoke(app, [str(a) for a in [*args, "--out", gen, "--map", MAP, "--behaviours"]])
    assert res.exit_code == 0, res.output
    df, manifest, tracks = read_scenes(gen)
    (scene,) = scenes_from_tables(df, tracks, load_catalogue(), manifest["class_labels"], [0])
    msgs, _, _ = _read_mcap(out)
    path: dict = defaultdict(list)
    frames = 0
    for _, m in msgs["/tf"]:
        art = [tr for tr in m.transforms if tr.child_frame_id.startswith("artefact_")]
        if not art:
            continue
        st = art[0].header.stamp
        t = (st.sec * 10**9 + st.nanosec - START_NS) * 1e-9
        boxes = scene.at(t)
        want = {f"artefact_{int(a)}": c for a, c in zip(boxes.ids, boxes.centres, strict=True)}
        assert {tr.child_frame_id for tr in art} == set(want), t
        for tr in art:
            xyz = tr.transform.translation
            np.testing.assert_allclose([xyz.x, xyz.y], want[tr.child_frame_id][:2], atol=1e-6)
            path[tr.child_frame_id].append((xyz.x, xyz.y))
        frames += 1
    assert frames == int(DURATION / 0.5) + 1
    moved = [np.ptp(np.asarray(p), axis=0).max() for p in path.values() if len(p) > 1]
    assert sum(d > 0.5 for d in moved) >= len(moved) // 2, moved  # most of them walk


def test_show_draws_the_camera_view_to_the_range_augment_perceived_with(files, augmented):
    """``are-stats show`` of an augmented bag draws the camera's field of view out to the
    ``d_max`` of A_f (said by ``/perceived``), so that a perceived box is never drawn
    beyond it; the half-angle is the CameraInfo's ``atan(width / 2 / fx)``."""
    from are_stats.export import read_view

    cam = "/camera/camera_info"
    res, out = augmented(files["mcap"], "--camera-info-topic", cam, "--d-max", "15", seed=5)
    assert res.exit_code == 0, res.output
    msgs, _, _ = _read_mcap(out)
    assert {json.loads(m.data)["d_max"] for _, m in msgs["/perceived"]} == {15.0}
    v = read_view(out)
    assert v.perceived.any()
    apex, ends = v.camera[0], v.camera[1:]
    np.testing.assert_allclose(np.linalg.norm(ends - apex, axis=1), 15.0, atol=1e-9)
    half = np.arctan2(CAMERA["width"] / 2, CAMERA["k"][0])
    a, b = ends - apex
    assert np.arccos(a @ b / (a @ a)) == pytest.approx(2 * half)
    near = (
        np.linalg.norm(v.boxes[v.perceived, :2] - apex, axis=1)
        - np.hypot(v.boxes[v.perceived, 3], v.boxes[v.perceived, 4]) / 2
    )
    assert (near <= 15.0).all()


def test_a_fit_of_the_older_format_is_read_with_a_note_line(capsys):
    """``are-stats`` shows a fit read as format 1 (no ``format_version``) as one ``note:``
    line, not a Python warning quoting our source; other warnings as Python shows them."""
    import warnings

    from are_stats.cli import _note_fit_formats
    from are_stats.fitting import FitFormatWarning

    shown = []
    show = _note_fit_formats(lambda *a, **k: shown.append(a[:2]))
    text = "old.nc: the fit has no format_version (written before fits carried one)"
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        warnings.warn(text, FitFormatWarning, stacklevel=1)
        warnings.warn("other", UserWarning, stacklevel=1)
    err = capsys.readouterr().err
    assert err == f"note: {text}\n"
    assert [(str(m), c) for m, c in shown] == [("other", UserWarning)]


def test_augment_bag_reads_a_shipped_cameras_name_as_the_command_does(tmp_path):
    """``camera=`` takes a camera YAML or a shipped camera's name (``augment --camera``);
    an unknown name is refused at once, naming ``--camera`` and the shipped cameras,
    before the bag or the fit is read (neither exists here)."""
    from are_stats.environment import shipped_names

    with pytest.raises(ValueError, match="--camera: expected an existing camera YAML") as err:
        augment_bag(
            tmp_path / "no.bag",
            tmp_path / "no.nc",
            "courtyard",
            tmp_path / "o.mcap",
            1,
            camera="no_such_camera",
        )
    assert all(name in str(err.value) for name in shipped_names("camera"))
    assert not (tmp_path / "o.mcap").exists()


def test_augment_options_are_its_keywords():
    """AugmentOptions (the job's ``**options``) names augment_bag's keywords, but the
    trajectory's (TrajectoryOptions) and ``topics``, with their types: a keyword added to one
    is added to the other."""
    names = {"PinholeCamera": PinholeCamera}  # imported for type checkers only there
    hints = get_type_hints(augment_bag, localns=names)
    params = inspect.signature(augment_bag).parameters.values()
    left = {*TrajectoryOptions._fields, "topics"}
    keywords = [p.name for p in params if p.kind is p.KEYWORD_ONLY and p.name not in left]
    assert list(AugmentOptions.__annotations__) == keywords
    assert get_type_hints(AugmentOptions, localns=names) == {k: hints[k] for k in keywords}
