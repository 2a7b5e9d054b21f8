"""PinholeCamera: P = K [R | t], rays through pixel centres, YAML / camera_info loading."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from are_stats.perception import PinholeCamera, optical_from_base
from tests.helpers import assert_allclose


def _pose(seed=0):
    p = np.eye(4)
    p[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    p[:3, 3] = [1.0, -2.0, 0.5]
    return p


def test_rays_project_to_pixel_centres():
    cam = PinholeCamera(410.0, 395.0, 30.5, 21.0, 64, 40, _pose())
    o, d = cam.rays()
    assert o.shape == d.shape == (64 * 40, 3)
    assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
    x = o + 3.7 * d
    h = np.hstack([x, np.ones((len(x), 1))]) @ cam.P.T
    uv = h[:, :2] / h[:, 2:]
    u, v = np.meshgrid(np.arange(64) + 0.5, np.arange(40) + 0.5)
    assert_allclose(uv, np.column_stack([u.ravel(), v.ravel()]), rtol=0, atol=1e-9)
    # depth z of the optical frame: positive in front
    _, z = cam.project(x)
    assert (z > 0).all()
    assert_allclose(cam.P[:, :3], cam.K @ cam.R.T, rtol=1e-12)


def test_principal_axis_and_mount():
    cam = PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48, optical_from_base([0, 0, 1.2]))
    assert_allclose(cam.principal_axis, [1.0, 0.0, 0.0], atol=1e-12)  # base x forward
    assert_allclose(cam.center, [0.0, 0.0, 1.2], atol=1e-12)
    # optical x (right) is base -y, optical y (down) is base -z
    assert_allclose(cam.R[:, 0], [0.0, -1.0, 0.0], atol=1e-12)
    assert_allclose(cam.R[:, 1], [0.0, 0.0, -1.0], atol=1e-12)
    tilted = PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48, optical_from_base(rpy=[0, 0.3, 0]))
    assert tilted.principal_axis[2] < 0  # positive pitch looks down


def test_fov_cone_corners_are_on_the_image_boundary():
    cam = PinholeCamera(200.0, 200.0, 40.0, 30.0, 80, 60, _pose(3))
    cone = cam.fov_cone(5.0)
    assert cone.shape == (5, 3)
    assert_allclose(np.linalg.norm(cone[1:] - cam.center, axis=1), 5.0, rtol=1e-12)
    uv, _ = cam.project(cone[1:])
    assert_allclose(uv, [[0, 0], [80, 0], [80, 60], [0, 60]], atol=1e-9)


def test_from_yaml_plain_ros1_ros2_and_calibration(tmp_path):
    k = [500.0, 0.0, 320.0, 0.0, 510.0, 240.0, 0.0, 0.0, 1.0]
    pose = _pose(1)
    variants = {
        "plain": {"fx": 500.0, "fy": 510.0, "cx": 320.0, "cy": 240.0, "width": 640, "height": 480},
        "ros1": {"K": k, "width": 640, "height": 480, "distortion_model": "plumb_bob"},
        "ros2": {"k": k, "width": 640, "height": 480, "pose": pose.tolist()},
        "calib": {"camera_matrix": {"rows": 3, "cols": 3, "data": k},
                  "image_width": 640, "image_height": 480},
    }  # fmt: skip
    for name, data in variants.items():
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(data))
        cam = PinholeCamera.from_yaml(path)
        assert_allclose(cam.K, np.array(k).reshape(3, 3), rtol=0)
        assert (cam.width, cam.height) == (640, 480)
        assert_allclose(cam.pose, pose if name == "ros2" else np.eye(4), atol=1e-12)
    # round trip
    path = tmp_path / "rt.yaml"
    path.write_text(yaml.safe_dump(cam.to_dict()))
    assert_allclose(PinholeCamera.from_yaml(path).P, cam.P, rtol=1e-12)


def test_bad_cameras(tmp_path):
    with pytest.raises(ValueError, match="cx: expected a principal point inside the image"):
        PinholeCamera(100.0, 100.0, 700.0, 24.0, 640, 48)
    with pytest.raises(ValueError, match="fx: expected a focal length > 0"):
        PinholeCamera(0.0, 100.0, 32.0, 24.0, 64, 48)
    with pytest.raises(ValueError, match="width: expected a positive integer"):
        PinholeCamera(100.0, 100.0, 32.0, 24.0, 64.5, 48)
    with pytest.raises(ValueError, match="pose: expected an orthonormal"):
        PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48, np.diag([1.0, 1.0, 2.0, 1.0]))
    with pytest.raises(FileNotFoundError, match="camera file not found"):
        PinholeCamera.from_yaml(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"K": [1, 2, 3], "width": 10, "height": 10}))
    with pytest.raises(ValueError, match="field K: expected 9 numbers"):
        PinholeCamera.from_yaml(bad)
    bad.write_text(yaml.safe_dump({"fx": 10.0, "fy": 10.0, "cx": 5.0, "cy": 5.0, "width": 10}))
    with pytest.raises(ValueError, match="expected field height"):
        PinholeCamera.from_yaml(bad)
    bad.write_text(yaml.safe_dump({"fx": 10.0, "fy": 10.0, "cx": 50.0, "cy": 5.0,
                                   "width": 10, "height": 10}))  # fmt: skip
    with pytest.raises(ValueError, match=r"bad.yaml: cx: expected a principal point"):
        PinholeCamera.from_yaml(bad)
    bad.write_text("fx: [1, 2\n")
    with pytest.raises(ValueError, match="not valid YAML"):
        PinholeCamera.from_yaml(bad)
