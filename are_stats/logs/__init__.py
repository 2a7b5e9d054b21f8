"""Field-log formats: life-cycle logs, tracks tables, ROS bags / MCAP, count panels.

:func:`read_field_log` reads a life-cycle log or a tracks table, told apart by columns.

Every reader validates cell by cell and raises ``ValueError("<file>: row <r>, column
'<col>': expected ..., got ...")``; nothing is dropped silently (see ``docs/src/logs.md``).
"""

from are_stats.logs._bag_reader import STORES_KEPT, bag_reader
from are_stats.logs._field_log import (
    LIFECYCLE_KIND_COLUMNS,
    TRACK_OPTIONS,
    TRACKS_KIND_COLUMNS,
    FieldLogOptions,
    read_field_log,
    read_field_tracks,
)
from are_stats.logs._lifecycle_log import (
    LIFECYCLE_COLUMNS,
    LifecycleLog,
    ManifestOverrides,
    find_manifest,
    lifecycle_log_from_frame,
    read_lifecycle_log,
    read_manifest,
)
from are_stats.logs._panel import read_count_panel
from are_stats.logs._rosbag import (
    BAG_SUFFIXES,
    DETECTION3D_MSGS,
    OUTLIER_SHARE,
    STAMP_GAP,
    SUPPORTED_TRACK_TYPES,
    PassChannel,
    PassThrough,
    bag_messages,
    bag_passthrough,
    bag_read_errors,
    check_bag_path,
    check_stamps,
    is_bag_path,
    read_tracks_bag,
    vision_msgs_typestore,
)
from are_stats.logs._table import RawTable, read_raw_table
from are_stats.logs._tf import (
    QUATERNION_TOLERANCE,
    TF_TYPE,
    TF_TYPES,
    TfBuffer,
    interpolate_poses,
    transform_matrix,
    unit_quaternion,
)
from are_stats.logs._tracks import (
    GROUP_DISTANCE,
    GROUP_HORIZON_STEPS,
    GROUP_TIME_STEPS,
    TRACK_COLUMNS,
    read_tracks,
    sampling_step,
    track_groups,
    tracks_to_lifecycle,
    validate_tracks,
)
from are_stats.logs._trajectory import (
    CLOCK_TOLERANCE,
    CLOCKS,
    POSE_TYPES,
    BagTrajectory,
    TrajectoryOptions,
    read_trajectory,
)

__all__ = [
    "STORES_KEPT",
    "bag_reader",
    "BAG_SUFFIXES",
    "is_bag_path",
    "CLOCKS",
    "CLOCK_TOLERANCE",
    "POSE_TYPES",
    "BagTrajectory",
    "read_trajectory",
    "TrajectoryOptions",
    "DETECTION3D_MSGS",
    "GROUP_DISTANCE",
    "GROUP_HORIZON_STEPS",
    "GROUP_TIME_STEPS",
    "LIFECYCLE_COLUMNS",
    "LIFECYCLE_KIND_COLUMNS",
    "OUTLIER_SHARE",
    "QUATERNION_TOLERANCE",
    "STAMP_GAP",
    "SUPPORTED_TRACK_TYPES",
    "TRACKS_KIND_COLUMNS",
    "TRACK_COLUMNS",
    "TRACK_OPTIONS",
    "TF_TYPE",
    "TF_TYPES",
    "FieldLogOptions",
    "LifecycleLog",
    "ManifestOverrides",
    "PassChannel",
    "PassThrough",
    "RawTable",
    "TfBuffer",
    "bag_messages",
    "bag_passthrough",
    "bag_read_errors",
    "check_bag_path",
    "check_stamps",
    "find_manifest",
    "interpolate_poses",
    "lifecycle_log_from_frame",
    "read_count_panel",
    "read_field_log",
    "read_field_tracks",
    "read_lifecycle_log",
    "read_manifest",
    "read_raw_table",
    "read_tracks",
    "read_tracks_bag",
    "sampling_step",
    "track_groups",
    "tracks_to_lifecycle",
    "transform_matrix",
    "unit_quaternion",
    "validate_tracks",
    "vision_msgs_typestore",
]
