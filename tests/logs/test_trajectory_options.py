"""TrajectoryOptions: the bag-reading options augment and serve --bag pass down whole."""

import pytest

from are_stats.inputs import InputError
from are_stats.logs import TrajectoryOptions, read_trajectory


def test_keywords_are_read_trajectorys_with_base_link_when_not_given():
    import inspect

    opts = TrajectoryOptions("/amcl_pose", None, "odom", "/cam/info", "log", "cam_optical")
    kw = opts.keywords()
    assert kw == {
        "pose_topic": "/amcl_pose",
        "base_frame": "base_link",
        "map_frame": "odom",
        "camera_info_topic": "/cam/info",
        "clock": "log",
        "camera_frame": "cam_optical",
    }
    # every field is a keyword of the reader, with the reader's default (base_frame aside)
    params = inspect.signature(read_trajectory).parameters
    for name, value in TrajectoryOptions().keywords().items():
        assert params[name].default == value


def test_given_names_the_flags_set_away_from_their_defaults():
    assert TrajectoryOptions().given() == {}
    opts = TrajectoryOptions(base_frame="base_footprint", map_frame="world", clock="header")
    assert opts.given() == {
        "--base-frame": "base_footprint",
        "--map-frame": "world",
        "--clock": "header",
    }


def test_two_sources_of_poses_are_refused():
    assert TrajectoryOptions(pose_topic="/amcl_pose").checked().pose_topic == "/amcl_pose"
    with pytest.raises(InputError, match="either --pose-topic or --base-frame"):
        TrajectoryOptions(pose_topic="/amcl_pose", base_frame="base_link").checked()
