"""The AR-builder (paper Sect. 3.3): oriented boxes, exact footprints, broad phase,
registration, collision detection and resolution (DECISIONS 9)."""

from are_stats.builder._broadphase import SpatialHash, aabb_pairs, aabb_pairs_brute
from are_stats.builder._builder import ARBuilder, Placement, Resolution
from are_stats.builder._geometry import (
    OrientedBox,
    box_centres,
    box_corners,
    box_runs,
    footprint_runs,
    obb_overlap,
    obb_overlap_2d,
    obb_overlap_3d,
    point_box_distance,
    polygon_cell_coverage,
    rasterise_convex,
    runs_to_cells,
    triangle_box_overlap,
)
from are_stats.builder._render import render_map, show_map

__all__ = [
    "ARBuilder",
    "OrientedBox",
    "Placement",
    "Resolution",
    "SpatialHash",
    "aabb_pairs",
    "aabb_pairs_brute",
    "box_centres",
    "box_corners",
    "box_runs",
    "footprint_runs",
    "obb_overlap",
    "obb_overlap_2d",
    "obb_overlap_3d",
    "point_box_distance",
    "polygon_cell_coverage",
    "rasterise_convex",
    "render_map",
    "runs_to_cells",
    "show_map",
    "triangle_box_overlap",
]
