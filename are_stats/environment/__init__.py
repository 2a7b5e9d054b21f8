"""The real environment (paper Sect. 3.1): occupancy grid M_2D, voxel map M_3D, mesh S_E,
frames F_E/F_R/F_L/F_C/F_A, the artefact catalogue Q and the data shipped in the package."""

from are_stats.environment._catalogue import (
    BEHAVIOURS,
    DEFAULT_MODELS,
    ArtefactCatalogue,
    ArtefactClass,
    PropertyRow,
    load_catalogue,
)
from are_stats.environment._frames import (
    OPTICAL_IN_BODY,
    TransformTree,
    planar_pose_matrix,
    pose_matrix,
)
from are_stats.environment._grid import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    OccupancyGrid,
    coarse_cell,
    coarse_free,
    read_map,
)
from are_stats.environment._mesh import (
    environment_mesh,
    extrude_grid,
    load_mesh,
    occupied_polygons,
)
from are_stats.environment._shipped import (
    SHIPPED_DATA,
    SHIPPED_KINDS,
    resolve_shipped,
    shipped_names,
    shipped_path,
)
from are_stats.environment._voxels import VoxelMap, surface_points

__all__ = [
    "BEHAVIOURS",
    "DEFAULT_MODELS",
    "FREE",
    "OCCUPIED",
    "OPTICAL_IN_BODY",
    "SHIPPED_DATA",
    "SHIPPED_KINDS",
    "UNKNOWN",
    "ArtefactCatalogue",
    "ArtefactClass",
    "coarse_cell",
    "coarse_free",
    "OccupancyGrid",
    "PropertyRow",
    "TransformTree",
    "VoxelMap",
    "environment_mesh",
    "extrude_grid",
    "load_catalogue",
    "load_mesh",
    "occupied_polygons",
    "planar_pose_matrix",
    "pose_matrix",
    "read_map",
    "resolve_shipped",
    "shipped_names",
    "shipped_path",
    "surface_points",
]
