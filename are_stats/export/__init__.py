"""What leaves the package, with ROS conventions (REP-103/105): MCAP files of missions,
the augmentation of a robot's recorded bag, the live view (a scenario replay streamed
to Foxglove), and a top-down picture of what such a file shows.

The last room of the one-way flow fit -> scenes -> mission -> export: it reads scenes and
mission traces and writes them out; nothing upstream imports it (the sweep writes a task's
MCAP through :func:`export_mcap`, imported where it is used)."""

from are_stats.export._augment import AUGMENT_TOPICS, AugmentOptions, AugmentResult, augment_bag
from are_stats.export._live import (
    LIVE_TOPICS,
    LiveMessage,
    LiveRobot,
    ServeInfo,
    ServeOptions,
    replay_messages,
    robot_from_bag,
    serve_robot,
    serve_scenario,
)
from are_stats.export._mcap import MCAP_TOPICS, export_mcap
from are_stats.export._ros import ROS_FRAMES, artefact_frame, parse_start_time
from are_stats.export._view import BagView, plot_mcap, read_view

__all__ = [
    "AUGMENT_TOPICS",
    "LIVE_TOPICS",
    "MCAP_TOPICS",
    "ROS_FRAMES",
    "AugmentOptions",
    "AugmentResult",
    "BagView",
    "LiveMessage",
    "LiveRobot",
    "ServeInfo",
    "ServeOptions",
    "artefact_frame",
    "augment_bag",
    "export_mcap",
    "parse_start_time",
    "plot_mcap",
    "read_view",
    "replay_messages",
    "robot_from_bag",
    "serve_robot",
    "serve_scenario",
]
