"""``logs/_tf.py``: a transform read from a bag is the matrix SciPy's rotation gave, bit for
bit (the reader converts every /tf transform and pose, so it is written without SciPy)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from are_stats.inputs import InputError
from are_stats.logs import transform_matrix, unit_quaternion


def _xyz(x, y, z):
    return SimpleNamespace(x=x, y=y, z=z)


def _quat(q):
    return SimpleNamespace(x=q[0], y=q[1], z=q[2], w=q[3])


def test_transform_matrix_is_scipys_rotation_bit_for_bit():
    rng = np.random.default_rng(11)
    qs = rng.normal(size=(3000, 4))
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    near = rng.normal(0, 1e-4, (300, 4)) + [0.0, 0.0, 0.0, 1.0]  # nearly unit: renormalised
    yaw = rng.uniform(-4, 4, 300)
    planar = np.column_stack([0 * yaw, 0 * yaw, np.sin(yaw / 2), np.cos(yaw / 2)])
    exact = [[0, 0, 0, 1], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, -1, 1e-17], [0.5, 0.5, 0.5, 0.5]]
    for q in np.vstack([qs, near[np.abs((near**2).sum(1) - 1) < 1e-3], planar, exact]):
        t = rng.uniform(-100, 100, 3)
        got = transform_matrix(_xyz(*t), _quat(q))
        want = np.eye(4)
        want[:3, :3] = Rotation.from_quat(unit_quaternion(_quat(q), "t", "")).as_matrix()
        want[:3, 3] = t
        assert np.array_equal(got.view(np.int64), want.view(np.int64)), q


def test_transform_matrix_refuses_what_it_refused():
    with pytest.raises(InputError, match="a finite position"):
        transform_matrix(_xyz(0.0, math.nan, 0.0), _quat([0, 0, 0, 1]))
    with pytest.raises(InputError, match="a unit quaternion"):
        transform_matrix(_xyz(0.0, 0.0, 0.0), _quat([0, 0, 0, 0]))
    with pytest.raises(InputError, match="a finite quaternion"):
        transform_matrix(_xyz(0.0, 0.0, 0.0), _quat([0, 0, math.inf, 1]))
