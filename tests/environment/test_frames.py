"""TransformTree: composition, inversion, interpolation and errors."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats import TransformTree
from are_stats.environment import OPTICAL_IN_BODY, planar_pose_matrix
from tests.helpers import assert_allclose


def _rot(axis, a):
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i] = R[j, j] = c
    R[i, j], R[j, i] = -s, s
    return R


def _T(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _robot_tree():
    tree = TransformTree()
    T_er = planar_pose_matrix(3.0, -1.0, 0.8)
    T_rl = _T(_rot(2, 0.1), [0.3, 0.0, 0.4])
    T_rc = _T(_rot(1, 0.2) @ OPTICAL_IN_BODY, [0.2, 0.05, 1.1])
    T_ea = _T(_rot(2, -2.0), [7.0, 4.0, 0.0])
    tree.set_static("F_R", "F_E", T_er)
    tree.set_static("F_L", "F_R", T_rl)
    tree.set_static("F_C", "F_R", T_rc)
    tree.set_static("F_A", "F_E", T_ea)
    return tree, T_er, T_rl, T_rc, T_ea


def test_compose_and_invert_against_matrices():
    tree, T_er, T_rl, T_rc, T_ea = _robot_tree()
    assert_allclose(tree.lookup("F_E", "F_L"), T_er @ T_rl, atol=1e-12)
    # the artefact seen from the camera: T_CE T_EA
    T_ca = np.linalg.inv(T_er @ T_rc) @ T_ea
    assert_allclose(tree.lookup("F_C", "F_A"), T_ca, atol=1e-12)
    assert_allclose(tree.lookup("F_A", "F_C"), np.linalg.inv(T_ca), atol=1e-12)
    assert_allclose(tree.lookup("F_L", "F_L"), np.eye(4))
    pts = np.random.default_rng(0).normal(size=(5, 3))
    assert_allclose(
        tree.transform_points("F_E", "F_C", pts),
        pts @ (T_er @ T_rc)[:3, :3].T + (T_er @ T_rc)[:3, 3],
        atol=1e-12,
    )


def test_optical_convention():
    # optical z (forward) is body x, optical x (right) is body -y, optical y (down) is -z
    assert_allclose(OPTICAL_IN_BODY @ [0, 0, 1], [1, 0, 0])
    assert_allclose(OPTICAL_IN_BODY @ [1, 0, 0], [0, -1, 0])
    assert_allclose(OPTICAL_IN_BODY @ [0, 1, 0], [0, 0, -1])
    assert np.linalg.det(OPTICAL_IN_BODY) == pytest.approx(1.0)


def test_time_series_interpolation():
    tree, *_ = _robot_tree()
    tree.remove("F_R")
    times = [0.0, 1.0, 3.0]
    poses = [[0.0, 0.0, 0.0], [1.0, 2.0, 0.0], [1.0, 2.0, np.pi / 2]]
    tree.set_series("F_R", "F_E", times, poses)
    assert_allclose(tree.lookup("F_E", "F_R", 1.0), planar_pose_matrix(1, 2, 0), atol=1e-12)
    # pure translation interpolates linearly
    assert_allclose(tree.lookup("F_E", "F_R", 0.25)[:3, 3], [0.25, 0.5, 0.0], atol=1e-12)
    # pure rotation about the robot's own origin: half the angle at the midpoint
    assert_allclose(tree.lookup("F_E", "F_R", 2.0), planar_pose_matrix(1, 2, np.pi / 4), atol=1e-12)
    # static children of a moving frame follow it
    T = tree.lookup("F_E", "F_L", 2.0)
    assert_allclose(T, planar_pose_matrix(1, 2, np.pi / 4) @ tree.lookup("F_R", "F_L"), atol=1e-12)


def test_errors():
    tree, *_ = _robot_tree()
    with pytest.raises(ValueError, match="unknown frame 'F_X'"):
        tree.lookup("F_E", "F_X")
    with pytest.raises(ValueError, match="close a loop"):
        tree.set_static("F_E", "F_C", np.eye(4))
    with pytest.raises(ValueError, match="already has parent"):
        tree.set_static("F_L", "F_A", np.eye(4))
    with pytest.raises(ValueError, match="own parent"):
        tree.set_static("F_Z", "F_Z", np.eye(4))
    tree.set_static("G", "H", np.eye(4))
    with pytest.raises(ValueError, match="not connected"):
        tree.lookup("F_E", "G")
    tree.set_series("F_M", "F_E", [0.0, 1.0], [[0, 0, 0], [1, 0, 0]])
    with pytest.raises(ValueError, match="give a time"):
        tree.lookup("F_E", "F_M")
    with pytest.raises(ValueError, match="out of range"):
        tree.lookup("F_E", "F_M", 2.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        tree.set_series("F_N", "F_E", [1.0, 0.0], [[0, 0, 0], [1, 0, 0]])
    with pytest.raises(ValueError, match="rigid"):
        tree.set_static("F_N", "F_E", np.ones((4, 4)))
    with pytest.raises(ValueError, match="pose"):
        tree.set_static("F_N", "F_E", [1.0, 2.0])
