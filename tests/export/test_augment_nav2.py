"""``augment`` on a Nav2-like bag: one that records ``/map`` (as ``map_server`` latches it)
beside ``/tf`` (``map -> odom -> base_footprint``), ``/tf_static``, ``/odom`` and ``/scan``.

The input's ``/map`` passes through unchanged when it is ``--map``'s map (same size,
resolution and origin) and is refused, naming both, when it cannot be; ``--topics`` that
leaves it out still gives the output a ``/map`` (``--map``'s). Errors give times into the
bag with the stamp read in brackets."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import DEFAULT_MODELS, OccupancyGrid, read_map
from are_stats.export import read_view
from tests.export.rosbag_fixtures import DURATION, START, fit_read_once, robot_pose, stamp_ns

runner = CliRunner()
MAP = DEFAULT_MODELS / "courtyard.yaml"
#: ``map -> odom`` of the bag (AMCL's correction): the composition must undo it.
ODOM = (0.4, -0.3)
#: A keep-out area the bag's ``/map`` marks occupied (cells ``[row0:row1, col0:col1]``) and
#: ``--map`` does not: the same map, edited, so that the output shows which one passed.
KEEPOUT = (slice(20, 24), slice(300, 310))


@pytest.fixture(scope="module")
def fit_and_camera(tmp_path_factory):
    """A small EM fit (labelled classes) and a small camera (80 x 60 pixels)."""
    from tests.export.test_augment import write_fit_and_camera

    fit, cam = write_fit_and_camera(tmp_path_factory.mktemp("nav2"))
    with fit_read_once(fit):  # the module's augment runs read the fit once
        yield fit, cam


def _grid() -> OccupancyGrid:
    return read_map(MAP)[1]


def _edited(grid: OccupancyGrid) -> OccupancyGrid:
    data = np.array(grid.data, np.int8)
    data[KEEPOUT] = 100
    return OccupancyGrid(data, grid.resolution, grid.origin)


def write_nav2_bag(
    path: Path, kind: str, maps: list[OccupancyGrid] | None = None, empty_map: bool = False
) -> Path:
    """A Nav2-like ROS 2 bag of the fixtures' 12 s drive (``kind`` ``"ros2"``: sqlite3,
    Humble's default; ``"mcap"``: Jazzy's, the ``.mcap`` returned): ``/map`` (one message
    per grid of ``maps``, a second apart from t = 0; none when ``maps`` is None),
    ``/tf_static`` ``base_footprint -> base_link -> base_scan``, ``/tf`` ``odom ->
    base_footprint`` at 10 Hz and ``map -> odom`` at 1 Hz, ``/odom`` at 10 Hz and ``/scan``
    at 5 Hz; header stamps and recording times ``START + t``. ``empty_map``: a ``/map``
    channel without messages (a recorder subscribed, no map was published)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types

    def stamp(t):
        n = stamp_ns(t)
        return T["builtin_interfaces/msg/Time"](sec=n // 10**9, nanosec=n % 10**9)

    def header(t, frame):
        return T["std_msgs/msg/Header"](stamp=stamp(t), frame_id=frame)

    def quat(yaw):
        return T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        )

    def point(x, y, z=0.0):
        return T["geometry_msgs/msg/Point"](x=x, y=y, z=z)

    def tf(t, parent, child, x, y, z=0.0, yaw=0.0):
        v = T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)
        return T["geometry_msgs/msg/TransformStamped"](
            header=header(t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](translation=v, rotation=quat(yaw)),
        )

    def grid_msg(t, g):
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=stamp(t),
            resolution=float(g.resolution),
            width=g.width,
            height=g.height,
            origin=T["geometry_msgs/msg/Pose"](
                position=point(g.origin[0], g.origin[1]), orientation=quat(g.origin[2])
            ),
        )
        data = np.asarray(g.data, np.int8).ravel()
        return T["nav_msgs/msg/OccupancyGrid"](header=header(t, "map"), info=info, data=data)

    TF = "tf2_msgs/msg/TFMessage"
    static = [
        tf(0.0, "base_footprint", "base_link", 0.0, 0.0, 0.01),
        tf(0.0, "base_link", "base_scan", -0.03, 0.0, 0.17),
    ]
    msgs = [(0.0, "/tf_static", TF, T[TF](transforms=static))]
    for k, g in enumerate(maps or []):
        msgs.append((float(k), "/map", "nav_msgs/msg/OccupancyGrid", grid_msg(float(k), g)))
    for k in range(int(DURATION * 10) + 1):
        t = k / 10.0
        x, y, yaw = robot_pose(t)
        ox, oy = x - ODOM[0], y - ODOM[1]
        tfs = [tf(t, "odom", "base_footprint", ox, oy, 0.0, yaw)]
        if k % 10 == 0:
            tfs.append(tf(t, "map", "odom", *ODOM))
        msgs.append((t, "/tf", TF, T[TF](transforms=tfs)))
        pose = T["geometry_msgs/msg/Pose"](position=point(ox, oy), orientation=quat(yaw))
        odom = T["nav_msgs/msg/Odometry"](
            header=header(t, "odom"),
            child_frame_id="base_footprint",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](
                    linear=T["geometry_msgs/msg/Vector3"](x=0.5, y=0.0, z=0.0),
                    angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                ),
                covariance=np.zeros(36),
            ),
        )
        msgs.append((t, "/odom", "nav_msgs/msg/Odometry", odom))
        if k % 2 == 0:
            scan = T["sensor_msgs/msg/LaserScan"](
                header=header(t, "base_scan"),
                angle_min=-math.pi,
                angle_max=math.pi - math.pi / 18,
                angle_increment=math.pi / 18,
                time_increment=0.0,
                scan_time=0.2,
                range_min=0.12,
                range_max=12.0,
                ranges=np.full(36, 5.0, np.float32),
                intensities=np.zeros(36, np.float32),
            )
            msgs.append((t, "/scan", "sensor_msgs/msg/LaserScan", scan))
    msgs.sort(key=lambda m: m[0])  # stable: the map before the drive's first messages
    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        if empty_map:
            w.add_connection("/map", "nav_msgs/msg/OccupancyGrid", typestore=ts)
        for t, topic, typ, msg in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], stamp_ns(t), ts.serialize_cdr(msg, typ))
    return next(Path(path).glob("*.mcap")) if kind == "mcap" else path


def _augment(fit_and_camera, bag, out, *extra, map_path=MAP):
    fit, cam = fit_and_camera
    args = ["augment", bag, "--fit", fit, "--map", map_path, "--out", out, "--seed", "1"]
    return runner.invoke(app, [str(a) for a in [*args, "--camera", cam, *extra]])


def _channels(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """``{topic: [(log time, bytes), ...]}`` of every channel of an MCAP (or bag) read with
    rosbags, one list per channel (a topic of two channels appears twice as ``topic#k``)."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list] = defaultdict(list)
    with AnyReader([path]) as reader:
        names = {}
        for c in reader.connections:
            k = sum(n.split("#")[0] == c.topic for n in names.values())
            names[c.id] = c.topic if k == 0 else f"{c.topic}#{k}"
        for c, t, raw in reader.messages():
            out[names[c.id]].append((int(t), bytes(raw)))
    return dict(out)


def _artefact_paths(path: Path) -> dict[str, list[tuple[float, float]]]:
    """The ``map -> artefact_<id>`` positions of an augmented MCAP, per artefact frame."""
    from rosbags.highlevel import AnyReader

    paths: dict[str, list] = defaultdict(list)
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == "/tf"]
        for c, _, raw in reader.messages(connections=conns):
            for tr in reader.deserialize(raw, c.msgtype).transforms:
                if tr.child_frame_id.startswith("artefact_"):
                    assert tr.header.frame_id == "map"
                    v = tr.transform.translation
                    paths[tr.child_frame_id].append((v.x, v.y))
    return dict(paths)


def test_a_nav2_bags_map_passes_through_and_the_output_shows(fit_and_camera, tmp_path):
    """Fails before this change ("topic /map: expected input topics other than the ones
    augment writes"). The bag's own ``/map`` (``--map``'s map with a keep-out area) is the
    output's only ``/map``, byte for byte; ``show`` reads it, the robot's path through
    ``map -> odom -> base_footprint -> base_link``, and the artefacts walk."""
    bag = write_nav2_bag(tmp_path / "nav2", "ros2", maps=[_edited(_grid())])
    out = tmp_path / "nav2_are.mcap"
    res = _augment(fit_and_camera, bag, out)
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "passed through: /tf_static 1, /map 1" in text, text
    got, want = _channels(out), _channels(bag)
    assert [k for k in got if k.startswith("/map")] == ["/map"]
    assert got["/map"] == want["/map"]  # the input's, unchanged: log time and bytes
    view = read_view(out)
    np.testing.assert_array_equal(view.grid.data, _edited(_grid()).data)
    assert view.grid.resolution == pytest.approx(0.1)
    np.testing.assert_array_equal(view.grid.origin, [-20.0, -15.0, 0.0])
    # the robot, through the Nav2 tree: base_link at the fixture's pose (+ 0 offset)
    x, y, _ = robot_pose(0.0)
    assert view.path is not None and len(view.path) == int(DURATION * 10) + 1
    np.testing.assert_allclose(view.path[0, :2], [x, y], atol=1e-9)
    paths = _artefact_paths(out)
    assert paths, "no artefact frame on /tf"
    moved = [np.ptp(np.asarray(p), axis=0).max() for p in paths.values() if len(p) > 1]
    assert any(d > 0.5 for d in moved), moved  # they walk (behaviour tracks)
    res = runner.invoke(app, ["show", str(out), "--out", str(tmp_path / "v.png")])
    assert res.exit_code == 0, res.output


def test_topics_that_leave_out_the_map_still_give_the_output_a_map(fit_and_camera, tmp_path):
    """Fails before this change: the output had no ``/map`` (and ``show`` refused it).
    With ``/map`` left out the output's ``/map`` is ``--map``'s (not the bag's edit)."""
    bag = write_nav2_bag(tmp_path / "nav2", "mcap", maps=[_edited(_grid())])
    out = tmp_path / "o.mcap"
    res = _augment(fit_and_camera, bag, out, "--topics", "/tf,/tf_static,/odom,/scan")
    assert res.exit_code == 0, res.output
    got = _channels(out)
    assert [k for k in got if k.startswith("/map")] == ["/map"] and len(got["/map"]) == 1
    assert got["/odom"] == _channels(bag)["/odom"]
    np.testing.assert_array_equal(read_view(out).grid.data, _grid().data)


def test_an_empty_bag_map_still_gives_the_output_a_map(fit_and_camera, tmp_path):
    """A ``/map`` channel without messages passes through (empty) and the output's ``/map``
    message is ``--map``'s."""
    bag = write_nav2_bag(tmp_path / "nav2", "ros2", empty_map=True)
    out = tmp_path / "o.mcap"
    res = _augment(fit_and_camera, bag, out)
    assert res.exit_code == 0, res.output
    got = _channels(out)
    assert sum(len(v) for k, v in got.items() if k.startswith("/map")) == 1
    np.testing.assert_array_equal(read_view(out).grid.data, _grid().data)


def _shifted(grid: OccupancyGrid, dx: float) -> OccupancyGrid:
    o = grid.origin
    return OccupancyGrid(grid.data, grid.resolution, (o[0] + dx, o[1], o[2]))


def _coarser(grid: OccupancyGrid) -> OccupancyGrid:
    return OccupancyGrid(np.asarray(grid.data)[::2, ::2], 2 * grid.resolution, grid.origin)


@pytest.mark.parametrize("kind", ["ros2", "mcap"])
@pytest.mark.parametrize(
    ("maps", "which", "theirs"),
    [
        # the origin 1 m east: the same cells would stand 1 m apart
        (lambda g: [_shifted(g, 1.0)], "its one message", "origin (-19, -15, yaw 0)"),
        # the same area in cells twice as large
        (lambda g: [_coarser(g)], "its one message", "200 x 150 cells of 0.2 m"),
        # a SLAM run's final map decides: the first agrees, the last does not
        (
            lambda g: [g, _shifted(g, -0.5)],
            "the last of its 2 messages",
            "origin (-20.5, -15, yaw 0)",
        ),
    ],
    ids=["origin", "resolution", "last-message"],
)
def test_a_bag_map_that_cannot_be_the_maps_is_refused_naming_both(
    fit_and_camera, tmp_path, kind, maps, which, theirs
):
    bag = write_nav2_bag(tmp_path / "nav2", kind, maps=maps(_grid()))
    out = tmp_path / "o.mcap"
    res = _augment(fit_and_camera, bag, out)
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert f"topic /map ({which}): expected the map of --map {MAP}" in text, text
    assert "(400 x 300 cells of 0.1 m, origin (-20, -15, yaw 0))" in text, text
    assert theirs in text and "leave /map out with --topics" in text, text
    assert not out.exists()


def test_a_bag_map_of_another_type_is_refused(fit_and_camera, tmp_path):
    from tests.export.rosbag_fixtures import write_bag

    bag = write_bag(tmp_path / "strmap", "mcap", extra="/map")  # a std_msgs/String /map
    res = _augment(fit_and_camera, bag, tmp_path / "o.mcap")
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert "topic /map: expected a nav_msgs/msg/OccupancyGrid" in text, text
    assert "got std_msgs/msg/String; leave /map out with --topics" in text, text


def _moved_map(tmp_path: Path, x0: float, name: str = "moved.yaml") -> Path:
    far = tmp_path / name
    far.write_text(
        MAP.read_text()
        .replace("image: courtyard.pgm", f"image: {MAP.with_suffix('.pgm')}")
        .replace("[-20.0, -15.0, 0.0]", f"[{x0}, -15.0, 0.0]")
    )
    return far


def test_a_trajectory_partly_outside_the_map_is_a_warning_with_its_times_into_the_bag(
    fit_and_camera, tmp_path
):
    """The map's east edge at x = -10.5 m: the robot (x = -15 + 0.5 t) leaves it 9 s into
    the bag. A robot at a map's edge: augment warns, as perceive does, naming the bag, how
    many poses and their times into the bag (the header stamps, s since the epoch, in
    brackets), and goes on. Fails before this change: it refused the bag."""
    bag = write_nav2_bag(tmp_path / "nav2", "ros2")
    moved = _moved_map(tmp_path, -50.5)
    grid = read_map(moved)[1]
    ts = np.arange(int(DURATION * 10) + 1) / 10.0
    xy = np.array([robot_pose(t)[:2] for t in ts])
    outside = ~grid.in_bounds(grid.world_to_cell(xy))
    first = ts[np.argmax(outside)]
    assert 0.0 < first < DURATION  # a pose inside the bag, not its first
    out = tmp_path / "o.mcap"
    res = _augment(fit_and_camera, bag, out, map_path=moved)
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    want = (
        f"warning: {int(outside.sum())} of {len(ts)} robot poses of {bag} lie outside the map "
        f"{moved} (corners [[-50.5, -15.0], [-10.5, 15.0]]), from {first:.3f} to "
        f"{DURATION:.3f} s into the bag (header stamps {START + first:.3f} to "
        f"{START + DURATION:.3f} s)"
    )
    assert want in text, text
    assert out.is_file()


def test_a_trajectory_wholly_outside_the_map_is_refused(fit_and_camera, tmp_path):
    """The map moved 85 m west of the drive: nothing along it could be seen; refused, as
    perceive refuses a path wholly outside its map, with the first pose and the times."""
    bag = write_nav2_bag(tmp_path / "nav2", "ros2")
    far = _moved_map(tmp_path, -100.0)
    out = tmp_path / "o.mcap"
    res = _augment(fit_and_camera, bag, out, map_path=far)
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert f"expected robot poses inside the map {far} (corners [[-100.0, -15.0]" in text, text
    n = int(DURATION * 10) + 1
    want = (
        f"got all {n} outside, the first at (-15.000, -10.000), from 0.000 to {DURATION:.3f} "
        f"s into the bag (header stamps {START:.3f} to {START + DURATION:.3f} s)"
    )
    assert want in text, text
    assert not out.exists()


def test_times_into_the_bag_are_on_the_recording_clock_with_the_stamp_read(tmp_path):
    """A bag stamped on a simulation clock (header 1234.5 s + t, recorded at START + t):
    a header stamp is placed into the bag through the recording clock; without the bag
    (gone since) the time is counted from the trajectory's start."""
    from are_stats.export._augment import _into_bag
    from are_stats.logs import read_trajectory
    from tests.export.rosbag_fixtures import SIM_START, write_bag

    bag = write_bag(tmp_path / "sim", "ros2", header_start=SIM_START)
    traj = read_trajectory(bag)
    assert traj.clock == "header"
    at = stamp_ns(2.5, SIM_START)
    want = f"2.500 s into the bag (header stamp {SIM_START + 2.5:.3f} s)"
    assert _into_bag(bag, traj, at) == want
    two = _into_bag(bag, traj, at, stamp_ns(4.0, SIM_START))
    assert (
        two == f"2.500 to 4.000 s into the bag (header stamps {SIM_START + 2.5:.3f} to 1238.500 s)"
    )
    gone = _into_bag(tmp_path / "gone.bag", traj, at)
    assert gone == f"2.500 s after the trajectory's start (header stamp {SIM_START + 2.5:.3f} s)"
