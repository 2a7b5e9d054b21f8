"""Perception: camera model, Warp occlusion kernels and the perceived set A_f (section 3.3)."""

from are_stats.perception._camera import (
    CameraModel,
    PinholeCamera,
    camera_mount,
    optical_from_base,
    read_camera,
)
from are_stats.perception._folder import FolderPlan, PerceiveFolderOptions, perceive_folder
from are_stats.perception._perceive import (
    PerceptionResult,
    TraceOptions,
    box_rois,
    clear_mesh_cache,
    perceive_frames,
    perceived_counts,
    perceived_counts_batch,
    sample_perceived,
)
from are_stats.perception._plots import (
    PerceivedFrame,
    plot_camera_view,
    plot_top_view,
    save_figure,
)
from are_stats.perception._scenario import (
    check_path_times,
    check_poses_inside,
    perceive_scenario,
    perceive_scene,
    perceived_grid,
    poses_outside,
    read_robot_path,
    yaw_rotations,
)

__all__ = [
    "FolderPlan",
    "PerceiveFolderOptions",
    "PerceivedFrame",
    "PerceptionResult",
    "CameraModel",
    "PinholeCamera",
    "TraceOptions",
    "box_rois",
    "camera_mount",
    "check_path_times",
    "check_poses_inside",
    "clear_mesh_cache",
    "optical_from_base",
    "perceive_folder",
    "perceive_frames",
    "perceived_counts",
    "perceived_counts_batch",
    "perceive_scenario",
    "perceive_scene",
    "perceived_grid",
    "plot_camera_view",
    "plot_top_view",
    "poses_outside",
    "read_camera",
    "read_robot_path",
    "sample_perceived",
    "save_figure",
    "yaw_rotations",
]
