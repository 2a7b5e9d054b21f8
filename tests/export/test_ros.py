"""The ROS message builders of the exports (``export/_ros.py``): the vectorised rotations
and transforms are bit for bit what SciPy and the per-message builders gave."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from are_stats.export._ros import RosMessages, quaternions

START = 1_732_480_000.0


def _planar_matrices(yaw: np.ndarray) -> np.ndarray:
    """The (n, 3, 3) rotations ``RosMessages.planar`` built, one ``math`` call per yaw."""
    m = np.zeros((yaw.size, 3, 3))
    for k, a in enumerate(yaw.tolist()):
        c, s = math.cos(a), math.sin(a)
        m[k] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    return m


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.all(a.view(np.int64) == b.view(np.int64)))


def test_quaternions_are_scipys_bit_for_bit():
    rng = np.random.default_rng(3)
    yaws = np.r_[rng.uniform(-7, 7, 400), np.arange(-8, 9) * math.pi / 4, 0.0, -0.0, 1e-300]
    cases = [
        Rotation.random(400, rng=4).as_matrix(),  # every branch of Markley's method
        _planar_matrices(yaws),
        np.array([np.diag(d) for d in [(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)]], float),
        # rounded to float32 (a bag's floats) and slightly off: SciPy orthogonalises
        Rotation.random(50, rng=5).as_matrix().astype(np.float32).astype(float),
        Rotation.random(50, rng=6).as_matrix() + rng.normal(0, 1e-9, (50, 3, 3)),
    ]
    for m in cases:
        assert _same_bits(quaternions(m), Rotation.from_matrix(m).as_quat())
        for k in range(0, len(m), 37):  # one at a time (Python floats), as a message's
            assert _same_bits(quaternions(m[k]), Rotation.from_matrix(m[k]).as_quat())
            few = m[k : k + 5]  # a few at once: one at a time too
            assert _same_bits(quaternions(few), Rotation.from_matrix(few).as_quat())
    assert quaternions(np.zeros((0, 3, 3))).shape == (0, 4)
    with pytest.raises(ValueError, match="determinant"):  # SciPy's refusal of a mirror
        quaternions(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match=r"expected shape \(\.\.\., 3, 3\)"):
        quaternions(np.eye(4))


def _old_transform(R: RosMessages, t, parent, child, matrix):
    """``RosMessages.transform`` as it was: a SciPy call per message."""
    T = R.T
    m = np.asarray(matrix, float)
    qx, qy, qz, qw = (float(v) for v in Rotation.from_matrix(m[:3, :3]).as_quat())
    return T["geometry_msgs/msg/TransformStamped"](
        header=R.header(t, parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](
                x=float(m[0, 3]), y=float(m[1, 3]), z=float(m[2, 3])
            ),
            rotation=T["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        ),
    )


def _old_planar(R: RosMessages, t, parent, child, x, y, yaw, z=0.0):
    m = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = [x, y, z]
    return _old_transform(R, t, parent, child, m)


def _bytes(R: RosMessages, tfs) -> bytes:
    return bytes(R.ts.serialize_cdr(R.tf(tfs), "tf2_msgs/msg/TFMessage"))


def test_transforms_and_planars_serialise_as_the_per_message_builders():
    R = RosMessages(START, start_ns=int(START * 1e9))
    rng = np.random.default_rng(7)
    n = 23
    xyz = rng.uniform(-50, 50, (n, 3))
    yaws = rng.uniform(-4, 4, n)
    times = np.sort(rng.uniform(0, 100, n))
    kids = [f"artefact_{k}" for k in range(n)]
    want = [
        _old_planar(R, 2.5, "map", c, *p[:2], a, p[2])
        for c, p, a in zip(kids, xyz, yaws, strict=True)
    ]
    assert _bytes(R, R.planars(2.5, "map", kids, xyz, yaws)) == _bytes(R, want)
    assert _bytes(R, [R.planar(2.5, "map", kids[0], *xyz[0, :2], yaws[0], xyz[0, 2])]) == _bytes(
        R, want[:1]
    )
    mats = np.tile(np.eye(4), (n, 1, 1))
    mats[:, :3, :3] = Rotation.random(n, rng=8).as_matrix()
    mats[:, :3, 3] = xyz
    want = [
        _old_transform(R, tk, "odom", "base_link", m) for tk, m in zip(times, mats, strict=True)
    ]
    got = R.transforms(0.0, "odom", ["base_link"] * n, mats, times=times)
    assert _bytes(R, got) == _bytes(R, want)
    assert _bytes(R, [R.transform(1.0, "a", "b", mats[3])]) == _bytes(
        R, [_old_transform(R, 1.0, "a", "b", mats[3])]
    )
    assert R.planars(0.0, "map", [], np.zeros((0, 3)), []) == []


def _old_artefact_markers(R: RosMessages, t, ids, centres, half, yaws, labels, perceived, life):
    """``RosMessages.artefact_markers`` as it was: every marker built by ``marker``."""
    from are_stats.export._ros import OCCLUDED_RGBA, PERCEIVED_RGBA

    ms = [R.marker(t, "", 0, 0, R.pose(0, 0, 0), (1, 1, 1), (0, 0, 0, 0), action=3)]
    for k in range(len(ids)):
        c, h = np.asarray(centres[k], float), np.asarray(half[k], float)
        seen = bool(perceived[k])
        rgba = PERCEIVED_RGBA if seen else OCCLUDED_RGBA
        aid = int(ids[k])
        pose = R.pose(c[0], c[1], yaws[k], c[2])
        ms.append(R.marker(t, "artefacts", aid, 1, pose, 2 * h, rgba, lifetime=life))
        label = f"{labels[k]} {aid}" + ("" if seen else " (occluded)")
        ms.append(
            R.marker(
                t,
                "labels",
                aid,
                9,
                R.pose(c[0], c[1], 0.0, c[2] + h[2] + 0.3),
                (0.0, 0.0, 0.4),
                (1.0, 1.0, 1.0, 1.0),
                text=label,
                lifetime=life,
            )
        )
    return R.T["visualization_msgs/msg/MarkerArray"](markers=ms)


@pytest.mark.parametrize("n", [0, 1, 9])
def test_artefact_markers_serialise_as_marker_by_marker(n):
    R = RosMessages(START, frame="odom")
    rng = np.random.default_rng(n)
    ids = rng.permutation(100)[:n]
    centres = rng.uniform(-30, 30, (n, 3))
    half = rng.uniform(0.1, 2, (n, 3))
    labels = [f"class{k % 3}" for k in range(n)]
    seen = rng.random(n) < 0.5
    for yaws in (rng.uniform(-4, 4, n), rng.uniform(-4, 4, n).astype(np.float32)):
        for t, life in ((0.0, 0.0), (12.345678901, 1.25)):
            args = (t, ids, centres, half, yaws, labels, seen)
            got = R.artefact_markers(*args, lifetime=life)
            want = _old_artefact_markers(R, *args, life)
            typ = "visualization_msgs/msg/MarkerArray"
            assert bytes(R.ts.serialize_cdr(got, typ)) == bytes(R.ts.serialize_cdr(want, typ))
