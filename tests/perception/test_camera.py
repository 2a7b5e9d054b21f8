"""PinholeCamera: P = K [R | t], rays through pixel centres, YAML / camera_info loading."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from are_stats.environment import shipped_path
from are_stats.inputs import InputError, LimitError, limits
from are_stats.perception import PinholeCamera, optical_from_base, read_camera
from are_stats.perception._camera import fov_cone
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


@pytest.mark.parametrize("declared", [False, True])
def test_fov_cone_corners_are_on_the_image_boundary(declared):
    """The method, and fov_cone of a camera with only CameraModel's attributes."""
    cam = PinholeCamera(200.0, 210.0, 40.0, 30.0, 80, 60, _pose(3))
    bare = SimpleNamespace(K=cam.K, width=cam.width, height=cam.height, pose=cam.pose)
    cone = fov_cone(bare, 5.0) if declared else cam.fov_cone(5.0)
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


def test_read_camera_takes_a_file_or_a_shipped_name(tmp_path):
    shipped = PinholeCamera.from_yaml(shipped_path("front_camera", "camera"))
    assert read_camera("front_camera").to_dict() == shipped.to_dict()
    path = tmp_path / "cam.yaml"
    path.write_text(
        yaml.safe_dump({"fx": 1.0, "fy": 1.0, "cx": 1.0, "cy": 1.0, "width": 2, "height": 2})
    )
    assert read_camera(path).fx == 1.0
    with pytest.raises(FileNotFoundError, match="none.yaml: no such file"):
        read_camera(tmp_path / "none.yaml")
    with pytest.raises(InputError, match=r"--source: .*front_camera"):
        read_camera("back_camera", source="--source")


def test_bad_cameras(tmp_path):
    with pytest.raises(ValueError, match="cx: expected a principal point inside the image"):
        PinholeCamera(100.0, 100.0, 700.0, 24.0, 640, 48)
    with pytest.raises(ValueError, match="fx: expected a focal length > 0"):
        PinholeCamera(0.0, 100.0, 32.0, 24.0, 64, 48)
    with pytest.raises(ValueError, match=r"fx: expected a focal length > 0 .*True \(a bool\)"):
        PinholeCamera(True, 100.0, 32.0, 24.0, 64, 48)
    with pytest.raises(ValueError, match="width: expected a positive integer"):
        PinholeCamera(100.0, 100.0, 32.0, 24.0, 64.5, 48)
    with pytest.raises(ValueError, match="pose: expected an orthonormal"):
        PinholeCamera(100.0, 100.0, 32.0, 24.0, 64, 48, np.diag([1.0, 1.0, 2.0, 1.0]))
    with pytest.raises(FileNotFoundError, match="missing.yaml: no such file: expected a camera"):
        PinholeCamera.from_yaml(tmp_path / "missing.yaml")
    with pytest.raises(InputError, match="expected a camera YAML, got a directory"):
        PinholeCamera.from_yaml(tmp_path)
    bad = tmp_path / "bad.yaml"
    bad.write_text("fx: [1, 2\n")
    with pytest.raises(ValueError, match="bad.yaml: expected a camera YAML in valid YAML"):
        PinholeCamera.from_yaml(bad)


_K = "[525, 0, 320, 0, 525, 240, 0, 0, 1]"
_SIZE = "image_width: 640\nimage_height: 480\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        # a negative fy was accepted and flipped the image
        (_SIZE + "K: [525, 0, 320, 0, -525, 240, 0, 0, 1]\n", r"fy .*: expected .* got -525"),
        # skew and the bottom row of K were silently ignored
        (_SIZE + "K: [525, 3, 320, 0, 525, 240, 0, 0, 1]\n", r"K\[0\]\[1\] \(skew\): expected 0"),
        (_SIZE + "K: [525, 0, 320, 0, 525, 240, 0, 0, 2]\n", r"K: expected an intrinsic matrix"),
        (_SIZE + "K: [525, 0, 320, 1, 525, 240, 0, 0, 1]\n", r"K: expected an intrinsic matrix"),
        (_SIZE + "K: [true, 0, 320, 0, 525, 240, 0, 0, 1]\n", r"K\[0\]: .*True \(a bool\)"),
        (_SIZE + "K: [1, 2, 3]\n", r"K: expected 9 numbers \(3 x 3, row-major or nested\), got 3"),
        (_SIZE + "K: abc\n", r"K: expected 9 numbers, got 'abc' \(a string\)"),
        (_SIZE + "K: [1e-300, 0, 320, 0, 525, 240, 0, 0, 1]\n", r"fx \(focal length in pixels\)"),
        (_SIZE + f"K: {_K}\nfx: 3\n", r"exactly one of fx/fy/cx/cy, K, k or camera_matrix, got 2"),
        (_SIZE, r"exactly one of fx/fy/cx/cy, K, k or camera_matrix, got none"),
        (_SIZE + "fx: 1\nfy: 1\ncx: 1\n", r"cy: expected this key to be present"),
        (
            _SIZE + "camera_matrix: {rows: 3, cols: 4, data: [1]}\n",
            r"camera_matrix.cols: expected 3",
        ),
        (_SIZE + "camera_matrix: {data: " + _K + ", extra: 1}\n", r"camera_matrix.extra: expected"),
        (_SIZE + f"K: {_K}\nfoo: 1\n", r"foo: expected one of the known keys fx, fy"),
        (_SIZE + f"K: {_K}\nD: [0.1, 0, 0, 0, 0]\n", r"D\[0\]: expected 0 \(the pinhole model"),
        (_SIZE + f"K: {_K}\nR: [1, 0, 0, 0, 0, 1, 0, 1, 0]\n", r"R: expected the identity"),
        (_SIZE + f"K: {_K}\nP: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]\n", r"P: expected \[K \| 0\]"),
        (_SIZE + f"K: {_K}\nbinning_x: 2\n", r"binning_x: expected 0 or 1"),
        (f"K: {_K}\nimage_width: 0\nimage_height: 480\n", r"image_width: expected an integer >= 1"),
        (f"K: {_K}\nimage_width: true\nimage_height: 480\n", r"image_width: .*True \(a bool\)"),
        (f"K: {_K}\nimage_width: 640.5\nimage_height: 480\n", r"image_width: expected an integer"),
        (f"K: {_K}\nwidth: 640\nimage_width: 640\nimage_height: 480\n", r"only one of width"),
        (f"K: {_K}\nimage_width: 640\n", r"height: expected this key \(or image_height\)"),
        (f"K: {_K}\nimage_width: 100\nimage_height: 480\n", r"cx \(principal point\): expected"),
        (_SIZE + f"K: {_K}\npose: [[1, 0], [0]]\n", r"pose: expected 16 numbers"),
        (
            _SIZE + f"K: {_K}\npose: [2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n",
            r"pose: expected a rigid",
        ),
        (
            _SIZE + f"K: {_K}\npose: [.nan, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n",
            r"pose\[0\]",
        ),
        # a huge image is refused before any ray buffer is allocated
        (f"K: {_K}\nimage_width: 1000000\nimage_height: 1000000\n", r"memory limit"),
        ("- 1\n", r"expected a mapping of fx, fy"),
        ("", r"expected a mapping of fx, fy"),
    ],
)
def test_bad_camera_files_name_file_and_key(tmp_path, text, match):
    path = tmp_path / "cam.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as err:
        PinholeCamera.from_yaml(path)
    assert str(err.value).startswith(str(path))


def test_ideal_ros_calibration_fields_are_accepted(tmp_path):
    path = tmp_path / "cam.yaml"
    path.write_text(
        _SIZE + "camera_name: front\ncamera_matrix: {rows: 3, cols: 3, data: " + _K + "}\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
        "rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\n"
        "projection_matrix: {rows: 3, cols: 4, "
        "data: [525, 0, 320, 0, 0, 525, 240, 0, 0, 0, 1, 0]}\n"
    )
    cam = PinholeCamera.from_yaml(path)
    assert (cam.fx, cam.cy, cam.width) == (525.0, 240.0, 640)
    with limits(memory="1M"), pytest.raises(LimitError, match="640 x 480 camera image"):
        cam.directions_camera()


def test_camera_mount_tree_then_pose_then_height():
    """One rule for every command: the robot's tree wins, then the camera file's pose, then
    a forward-looking camera ``height`` m above the base (optical z along base x, optical x
    along -base y, optical y along -base z)."""
    from are_stats.perception import camera_mount

    forward = np.array(
        [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.2], [0, 0, 0, 1.0]]
    )
    assert_allclose(camera_mount(np.eye(4), 1.2), forward)
    posed = forward.copy()
    posed[:3, 3] = [0.3, -0.1, 0.8]
    assert_allclose(camera_mount(posed, 1.2), posed)
    tree = np.eye(4)
    tree[:3, 3] = [1.0, 2.0, 3.0]
    assert_allclose(camera_mount(posed, 1.2, tree), tree)
    assert_allclose(camera_mount(np.eye(4), 1.2, np.eye(4)), np.eye(4))  # the tree's own
