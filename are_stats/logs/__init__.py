"""Field-log formats: life-cycle logs, tracks tables, ROS bags / MCAP, count panels.

Every reader validates cell by cell and raises ``ValueError("<file>: row <r>, column
'<col>': expected ..., got ...")``; nothing is dropped silently (see ``docs/src/logs.md``).
"""

from are_stats.logs._lifecycle_log import (
    LIFECYCLE_COLUMNS,
    LifecycleLog,
    lifecycle_log_from_frame,
    read_lifecycle_log,
    read_manifest,
)
from are_stats.logs._panel import read_count_panel
from are_stats.logs._rosbag import (
    DETECTION3D_MSGS,
    SUPPORTED_TRACK_TYPES,
    read_tracks_bag,
    vision_msgs_typestore,
)
from are_stats.logs._tracks import (
    TRACK_COLUMNS,
    read_tracks,
    tracks_to_lifecycle,
    validate_tracks,
)

__all__ = [
    "DETECTION3D_MSGS",
    "LIFECYCLE_COLUMNS",
    "SUPPORTED_TRACK_TYPES",
    "TRACK_COLUMNS",
    "LifecycleLog",
    "lifecycle_log_from_frame",
    "read_count_panel",
    "read_lifecycle_log",
    "read_manifest",
    "read_tracks",
    "read_tracks_bag",
    "tracks_to_lifecycle",
    "validate_tracks",
    "vision_msgs_typestore",
]
