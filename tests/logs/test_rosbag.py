"""ROS 1 / ROS 2 (sqlite3, MCAP) bags written with rosbags' writers and read back as tracks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2

from are_stats.logs import read_tracks_bag, tracks_to_lifecycle, vision_msgs_typestore


def _stamp(ts, t):
    sec = int(math.floor(t))
    return ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)))


def _header(ts, t, ros1):
    h = ts.types["std_msgs/msg/Header"]
    kw = {"seq": 0} if ros1 else {}
    return h(**kw, stamp=_stamp(ts, t), frame_id="map")


def _pose(ts, x, y, yaw):
    P = ts.types["geometry_msgs/msg/Pose"]
    Pt = ts.types["geometry_msgs/msg/Point"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    return P(
        position=Pt(x=x, y=y, z=0.0),
        orientation=Q(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )


def _marker(ts, t, ns, mid, x, y, yaw, action, ros1):
    M = ts.types["visualization_msgs/msg/Marker"]
    V = ts.types["geometry_msgs/msg/Vector3"]
    C = ts.types["std_msgs/msg/ColorRGBA"]
    D = ts.types["builtin_interfaces/msg/Duration"]
    kw = dict(
        header=_header(ts, t, ros1),
        ns=ns,
        id=mid,
        type=1,
        action=action,
        pose=_pose(ts, x, y, yaw),
        scale=V(x=1.0, y=1.0, z=1.0),
        color=C(r=1.0, g=0.0, b=0.0, a=1.0),
        lifetime=D(sec=0, nanosec=0),
        frame_locked=False,
        points=[],
        colors=[],
        text="",
        mesh_resource="",
        mesh_use_embedded_materials=False,
    )
    if not ros1:
        kw.update(
            texture_resource="",
            uv_coordinates=[],
            mesh_file=ts.types["visualization_msgs/msg/MeshFile"](
                filename="", data=np.zeros(0, np.uint8)
            ),
            texture=ts.types["sensor_msgs/msg/CompressedImage"](
                header=_header(ts, t, ros1), format="", data=np.zeros(0, np.uint8)
            ),
        )
    return M(**kw)


# (t, [(ns, id, x, y, yaw, action)])  action 0 ADD, 2 DELETE, 3 DELETEALL
MARKER_FRAMES = [
    (1.0, [("people", 1, 0.0, 0.0, 0.0, 0), ("carts", 4, 5.0, 5.0, math.pi / 2, 0)]),
    (2.0, [("people", 1, 1.0, 0.0, 0.0, 0), ("carts", 4, 5.0, 6.0, math.pi / 2, 0)]),
    (3.0, [("people", 1, 0.0, 0.0, 0.0, 2)]),  # person 1 leaves
    (4.0, [("people", 1, 9.0, 9.0, math.pi, 0), ("carts", 4, 5.0, 7.0, math.pi / 2, 0)]),
    (5.0, [("carts", 0, 0.0, 0.0, 0.0, 3)]),  # DELETEALL of the carts namespace
    (6.0, [("people", 1, 9.5, 9.0, math.pi, 0), ("carts", 4, 1.0, 1.0, 0.0, 0)]),
]

# (t, [(det_id, class_id, x, y, yaw)])
DET_FRAMES = [
    (1.5, [("trk7", "forklift", 2.0, 3.0, 0.25), ("", "pallet", 4.0, 4.0, 0.0)]),
    (2.5, [("trk7", "forklift", 2.5, 3.0, 0.25)]),
]


def _marker_array(ts, t, items, ros1):
    MA = ts.types["visualization_msgs/msg/MarkerArray"]
    return MA(markers=[_marker(ts, t, ns, i, x, y, yaw, a, ros1) for ns, i, x, y, yaw, a in items])


def _detections(ts, t, items, ros1):
    T = ts.types
    dets = []
    for did, cls, x, y, yaw in items:
        hyp = T["vision_msgs/msg/ObjectHypothesisWithPose"](
            hypothesis=T["vision_msgs/msg/ObjectHypothesis"](class_id=cls, score=0.9),
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=_pose(ts, x, y, yaw), covariance=np.zeros(36)
            ),
        )
        bbox = T["vision_msgs/msg/BoundingBox3D"](
            center=_pose(ts, x, y, yaw), size=T["geometry_msgs/msg/Vector3"](x=1.0, y=1.0, z=1.0)
        )
        # detection headers left at zero: the array's stamp is used
        zero = T["std_msgs/msg/Header"](
            **({"seq": 0} if ros1 else {}), stamp=_stamp(ts, 0.0), frame_id=""
        )
        dets.append(T["vision_msgs/msg/Detection3D"](header=zero, results=[hyp], bbox=bbox, id=did))
    return T["vision_msgs/msg/Detection3DArray"](header=_header(ts, t, ros1), detections=dets)


def _write(path, kind):
    ros1 = kind == "ros1"
    ts = vision_msgs_typestore(1 if ros1 else 2)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    if ros1:
        w = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        w = Writer2(path, version=9, storage_plugin=plugin)
    with w:
        cm = w.add_connection("/markers", "visualization_msgs/msg/MarkerArray", typestore=ts)
        cd = w.add_connection("/detections", "vision_msgs/msg/Detection3DArray", typestore=ts)
        cs = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        w.write(cs, 10, ser(ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))
        msgs = [
            (t, cm, _marker_array(ts, t, it, ros1), "visualization_msgs/msg/MarkerArray")
            for t, it in MARKER_FRAMES
        ]
        msgs += [
            (t, cd, _detections(ts, t, it, ros1), "vision_msgs/msg/Detection3DArray")
            for t, it in DET_FRAMES
        ]
        for t, conn, msg, typ in sorted(msgs, key=lambda m: m[0]):
            w.write(conn, int(t * 1e9), ser(msg, typ))


@pytest.fixture(scope="module", params=["ros1", "ros2-sqlite3", "mcap"])
def bag(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    path = d / ("field.bag" if request.param == "ros1" else "field")
    _write(path, request.param)
    return request.param, path


def test_marker_array_tracks(bag):
    _, path = bag
    df = read_tracks_bag(path, topics=["/markers"])
    got = {tid: g["t"].tolist() for tid, g in df.groupby("id")}
    assert got == {
        "people/1": [1.0, 2.0],
        "people/1@2": [4.0, 6.0],
        "carts/4": [1.0, 2.0, 4.0],
        "carts/4@2": [6.0],
    }
    row = df[(df["id"] == "carts/4") & (df["t"] == 2.0)].iloc[0]
    assert (row.x, row.y) == (5.0, 6.0)
    assert row.yaw == pytest.approx(math.pi / 2)
    assert row.label == "carts" and row.frame_id == "map" and row.topic == "/markers"


def test_detection3d_tracks(bag):
    _, path = bag
    df = read_tracks_bag(path, topics=["/detections"])
    assert df["id"].tolist() == ["trk7", "pallet/1", "trk7"]
    assert df["t"].tolist() == [1.5, 1.5, 2.5]
    assert df["label"].tolist() == ["forklift", "pallet", "forklift"]
    assert df["yaw"].iloc[0] == pytest.approx(0.25)
    assert df["x"].tolist() == [2.0, 4.0, 2.5]


def test_all_supported_topics_and_lifecycle(bag):
    _, path = bag
    df = read_tracks_bag(path)
    assert set(df["topic"]) == {"/markers", "/detections"}
    assert np.all(np.diff(df["t"].to_numpy()) >= 0)
    life = tracks_to_lifecycle(df, window=(0.0, 7.0), gap_tolerance=2.5, edge_tolerance=0.5)
    r = {x.id: x for x in life.itertuples()}
    assert (r["people/1"].t_arrive, r["people/1"].t_leave) == (1.0, 2.0)
    assert (r["trk7"].t_arrive, r["trk7"].t_leave) == (1.5, 2.5)


def test_standalone_mcap_file(tmp_path):
    _write(tmp_path / "b", "mcap")
    (mcap,) = sorted((tmp_path / "b").glob("*.mcap"))
    df = read_tracks_bag(mcap, topics=["/markers"])
    assert len(df) == 8  # every ADD marker


def test_bag_errors(bag, tmp_path):
    _, path = bag
    with pytest.raises(ValueError, match=r"topic '/nope': expected a topic of the bag"):
        read_tracks_bag(path, topics=["/nope"])
    with pytest.raises(
        ValueError,
        match=r"topic '/chatter': expected a message type in "
        r"visualization_msgs/msg/MarkerArray.*got std_msgs/msg/String",
    ):
        read_tracks_bag(path, topics=["/chatter"])
    with pytest.raises(FileNotFoundError, match=r"missing\.bag: no such bag file"):
        read_tracks_bag(tmp_path / "missing.bag")


def test_unreadable_bag(tmp_path):
    p = tmp_path / "junk.bag"
    p.write_bytes(b"not a bag at all")
    with pytest.raises(ValueError, match=r"junk\.bag: expected a readable ROS 1 / ROS 2 bag"):
        read_tracks_bag(p)


def _damaged(data: bytes, rnd) -> bytes:
    b = bytearray(data)
    op = rnd.randrange(3)
    if op == 0:
        for _ in range(rnd.randrange(1, 6)):
            b[rnd.randrange(len(b))] = rnd.randrange(256)
    elif op == 1:
        b = b[: rnd.randrange(len(b))]
    else:
        i = rnd.randrange(len(b) - 8)
        b[i : i + 4] = rnd.choice([b"\xff\xff\xff\x7f", b"\x00\x00\x00\x80", b"\xff\xff\xff\xff"])
    return bytes(b)


def test_damaged_bags_give_clean_errors(bag, tmp_path):
    # byte flips, truncations and absurd size fields: every read either succeeds or raises
    # a ValueError naming the file (rosbags' own KeyError / AssertionError / MemoryError /
    # apsw errors on damaged bytes no longer escape)
    import random

    kind, path = bag
    if kind == "ros1":
        src, suffix = path, ".bag"
    else:
        (src,) = sorted(path.glob("*.mcap" if kind == "mcap" else "*.db3"))
        suffix = src.suffix
    data = src.read_bytes()
    rnd = random.Random(13)
    target = tmp_path / f"damaged{suffix}"
    for _ in range(25):
        target.write_bytes(_damaged(data, rnd))
        try:
            df = read_tracks_bag(target)
        except ValueError as err:
            assert str(target) in str(err)
        else:
            assert np.isfinite(df[["t", "x", "y"]].to_numpy()).all()


def test_non_finite_position_and_bad_topics(tmp_path):
    ts = vision_msgs_typestore(1)
    p = tmp_path / "nan.bag"
    with Writer1(p) as w:
        cm = w.add_connection("/markers", "visualization_msgs/msg/MarkerArray", typestore=ts)
        for t, x in ((1.0, 0.0), (2.0, float("nan"))):
            msg = _marker_array(ts, t, [("people", 1, x, 0.0, 0.0, 0)], True)
            w.write(cm, int(t * 1e9), ts.serialize_ros1(msg, "visualization_msgs/msg/MarkerArray"))
    with pytest.raises(
        ValueError, match=r"nan\.bag: topic '/markers', track 'people/1', .*x: expected a finite"
    ):
        read_tracks_bag(p)
    with pytest.raises(ValueError, match=r"^topics: expected a list of topic names"):
        read_tracks_bag(p, topics="/markers")
    with pytest.raises(ValueError, match=r"^topics: \[0\]: expected a string, got 3"):
        read_tracks_bag(p, topics=[3])


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (b"Header header", b"Header headxr", r"with its standard fields, got a message whose"),
        (b"Pose pose", b"PoAe pose", r"message 1 .*expected a valid .*got undecodable bytes"),
    ],
)
def test_mcap_with_damaged_type_definitions(tmp_path, old, new, message):
    # an MCAP file carries its own message definitions: a damaged one must not leak a
    # KeyError / AttributeError from rosbags or from the track extraction
    _write(tmp_path / "b", "mcap")
    (mcap,) = sorted((tmp_path / "b").glob("*.mcap"))
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(mcap.read_bytes().replace(old, new))
    with pytest.raises(ValueError, match=r"damaged\.mcap: topic '/markers'.*" + message):
        read_tracks_bag(damaged, topics=["/markers"])


def test_tracks_in_other_frames_are_moved_into_map_through_tf(tmp_path):
    """Markers published in ``odom`` while ``map -> odom`` drifts and turns (on /tf), and in
    ``lidar`` (``odom -> lidar`` on /tf_static): positions come back in ``map``."""
    import dataclasses

    ts = vision_msgs_typestore(2)
    T = ts.types

    def tf(t, parent, child, x, y, yaw):
        return T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=_stamp(ts, t), frame_id=parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                rotation=_pose(ts, 0, 0, yaw).orientation,
            ),
        )

    def markers(t, frame, x, y, yaw):
        m = _marker(ts, t, "people", 1, x, y, yaw, 0, False)
        m = dataclasses.replace(m, header=dataclasses.replace(m.header, frame_id=frame))
        return T["visualization_msgs/msg/MarkerArray"](markers=[m])

    def map_odom(t):  # drifts 0.2 m/s along x, turned a quarter turn
        return 1.0 + 0.2 * t, 2.0, math.pi / 2

    path = tmp_path / "tf_bag"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c_tf = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
        c_st = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=ts)
        c_m = w.add_connection("/markers", "visualization_msgs/msg/MarkerArray", typestore=ts)
        st = T["tf2_msgs/msg/TFMessage"](transforms=[tf(0.0, "odom", "lidar", 0.5, 0.0, 0.0)])
        w.write(c_st, 0, ts.serialize_cdr(st, "tf2_msgs/msg/TFMessage"))
        for k in range(11):
            msg = T["tf2_msgs/msg/TFMessage"](transforms=[tf(k, "map", "odom", *map_odom(k))])
            w.write(c_tf, int(k * 1e9) + 1, ts.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))
        for t, frame in ((2.5, "odom"), (5.0, "lidar"), (7.0, "map")):
            msg = markers(t, frame, 1.0, 0.0, 0.1)
            w.write(
                c_m, int(t * 1e9) + 2, ts.serialize_cdr(msg, "visualization_msgs/msg/MarkerArray")
            )
    df = read_tracks_bag(path)
    assert df["frame_id"].tolist() == ["map"] * 3
    # odom (1, 0) turned a quarter: (0, 1) + map_odom(2.5) = (1.5, 3.0)
    x0, y0, _ = map_odom(2.5)
    np.testing.assert_allclose(df[["x", "y"]].iloc[0], [x0, y0 + 1.0], atol=1e-9)
    x1, y1, _ = map_odom(5.0)
    np.testing.assert_allclose(df[["x", "y"]].iloc[1], [x1, y1 + 1.5], atol=1e-9)
    np.testing.assert_allclose(df[["x", "y", "yaw"]].iloc[2], [1.0, 0.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(df["yaw"].iloc[:2], [0.1 + math.pi / 2] * 2, atol=1e-9)
    with pytest.raises(
        ValueError, match=r"frame 'lidar': expected a /tf chain world -> ... -> lidar, got frames"
    ):
        read_tracks_bag(path, map_frame="world")


def _marker_bag(path, frames, kind="ros1"):
    """A bag of ``/markers`` only: ``frames`` is ``[(t, x, quaternion or None)]``."""
    import dataclasses

    ros1 = kind == "ros1"
    ts = vision_msgs_typestore(1 if ros1 else 2)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    typ = "visualization_msgs/msg/MarkerArray"
    w = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    with w:
        cm = w.add_connection("/markers", typ, typestore=ts)
        for t, x, q in frames:
            m = _marker(ts, t, "people", 1, x, 0.0, 0.0, 0, ros1)
            if q is not None:
                pose = dataclasses.replace(m.pose, orientation=Q(x=q[0], y=q[1], z=q[2], w=q[3]))
                m = dataclasses.replace(m, pose=pose)
            msg = ts.types[typ](markers=[m])
            w.write(cm, int(t * 1e9) if t > 0 else 1, ser(msg, typ))
    return path


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_marker_orientations_are_unit_quaternions(tmp_path, kind):
    nan = float("nan")
    for i, (q, message) in enumerate(
        [
            ((0.0, 0.0, nan, 1.0), r"expected a finite quaternion, got \[0.0, 0.0, nan, 1.0\]"),
            ((0.0, 0.0, 0.0, 2.0), r"expected a unit quaternion .*of norm 2"),
        ]
    ):
        p = _marker_bag(tmp_path / f"q{i}{'.bag' if kind == 'ros1' else ''}", [
            (1.0, 0.0, None), (2.0, 0.5, q), (3.0, 1.0, None)
        ], kind)  # fmt: skip
        with pytest.raises(
            ValueError, match=r"topic '/markers', message 2, marker 0, orientation: " + message
        ):
            read_tracks_bag(p)
    # an orientation left at zero is the identity (as RViz draws it); near-unit is renormalised
    p = _marker_bag(
        tmp_path / f"ok{'.bag' if kind == 'ros1' else ''}",
        [(1.0, 0.0, (0.0, 0.0, 0.0, 0.0)), (2.0, 0.5, (0.0, 0.0, 0.0, 1.003))],
        kind,
    )
    df = read_tracks_bag(p)
    np.testing.assert_allclose(df["yaw"], [0.0, 0.0])


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_a_1970_sighting_among_2026_ones_is_refused(tmp_path, kind):
    t0 = 1_782_000_000.0  # 2026
    frames = [(t0 + k, 0.1 * k, None) for k in range(30)] + [(5.0, 0.0, None)]
    p = _marker_bag(tmp_path / f"b{'.bag' if kind == 'ros1' else ''}", frames, kind)
    with pytest.raises(
        ValueError,
        match=r"topic '/markers', sighting 1, stamp 5\.000000000 s \(1970-01-01T00:00:05Z\): "
        r"expected stamps on the clock of the other 30 sightings",
    ):
        read_tracks_bag(p)
    # a recording paused for two hours, with many sightings on both sides, is kept
    frames = [(t0 + k, 0.1 * k, None) for k in range(30)]
    frames += [(t0 + 7200.0 + k, 0.1 * k, None) for k in range(30)]
    p = _marker_bag(tmp_path / f"c{'.bag' if kind == 'ros1' else ''}", frames, kind)
    assert len(read_tracks_bag(p)) == 60
