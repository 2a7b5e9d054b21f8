"""Oriented boxes: exact footprints and separating-axis tests against independent oracles
(shapely polygon areas, a linear program for triangle/box intersection)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from are_stats.builder import (
    OrientedBox,
    box_corners,
    obb_overlap,
    obb_overlap_2d,
    obb_overlap_3d,
    point_box_distance,
    polygon_cell_coverage,
    rasterise_convex,
    triangle_box_overlap,
)

coord = st.floats(-6.0, 6.0, allow_nan=False)
size = st.floats(0.05, 4.0, allow_nan=False)
angle = st.floats(-7.0, 7.0, allow_nan=False)
TOL = 1e-9  # below this area / distance the oracle cannot tell touching from overlapping


def _cell_areas(poly: shapely.Polygon, shape, offset=(0, 0)):
    h, w = shape
    i, j = np.mgrid[0:h, 0:w]
    boxes = shapely.box(j + offset[1], i + offset[0], j + 1 + offset[1], i + 1 + offset[0])
    return shapely.area(shapely.intersection(boxes, poly))


@settings(max_examples=60, deadline=None)
@given(coord, coord, size, size, angle)
def test_rasterisation_equals_exact_polygon_area(x, y, hx, hy, yaw):
    P = box_corners([[x + 8, y + 8]], [[hx, hy]], [yaw])
    owner, flat, outside = rasterise_convex(P, (16, 16))
    areas = _cell_areas(shapely.Polygon(P[0]), (16, 16)).ravel()
    mask = np.zeros(256, bool)
    mask[flat] = True
    sure = (areas > TOL) | (areas == 0)
    assert (mask[sure] == (areas[sure] > 0)).all()
    assert (owner == 0).all() and np.unique(flat).size == flat.size
    spill = shapely.Polygon(P[0]).difference(shapely.box(0, 0, 16, 16)).area
    if spill > TOL or spill == 0:
        assert outside[0] == (spill > 0)


@settings(max_examples=60, deadline=None)
@given(coord, coord, size, size, angle)
def test_coverage_fractions_equal_shapely(x, y, hx, hy, yaw):
    P = box_corners([[x, y]], [[hx, hy]], [yaw])[0]
    i0, j0, cov = polygon_cell_coverage(P)
    areas = _cell_areas(shapely.Polygon(P), cov.shape, (i0, j0))
    np.testing.assert_allclose(cov, areas, atol=1e-10)
    assert cov.sum() == pytest.approx(4 * hx * hy, rel=1e-9)


def test_coverage_non_convex_polygon():
    V = np.array([[0.2, 0.3], [3.7, 0.1], [3.9, 2.6], [2.1, 1.2], [0.4, 2.9]])
    i0, j0, cov = polygon_cell_coverage(V[::-1])  # clockwise works too
    areas = _cell_areas(shapely.Polygon(V), cov.shape, (i0, j0))
    np.testing.assert_allclose(cov, areas, atol=1e-12)


def test_rasterisation_clips_at_the_border():
    P = box_corners([[0.5, 2.0]], [[1.0, 0.5]], [0.0])
    owner, flat, outside = rasterise_convex(P, (4, 4))
    assert outside[0]
    # u in -0.5..1.5 (cols 0, 1 after clipping), v in 1.5..2.5 (rows 1, 2)
    assert sorted(flat.tolist()) == [4, 5, 8, 9]
    del owner


@settings(max_examples=200, deadline=None)
@given(coord, coord, size, size, angle, coord, coord, size, size, angle)
def test_obb_2d_against_shapely(x1, y1, a1, b1, t1, x2, y2, a2, b2, t2):
    p1 = shapely.Polygon(box_corners([[x1, y1]], [[a1, b1]], [t1])[0])
    p2 = shapely.Polygon(box_corners([[x2, y2]], [[a2, b2]], [t2])[0])
    hit = obb_overlap_2d([[x1, y1]], [[a1, b1]], [t1], [[x2, y2]], [[a2, b2]], [t2], eps=0.0)[0]
    area = p1.intersection(p2).area
    if area > TOL:
        assert hit
    elif p1.distance(p2) > TOL or area == 0 and not p1.intersects(p2):
        assert not hit


def test_obb_3d_and_box_class():
    a = OrientedBox([0, 0, 0.5], [1, 1, 0.5], 0.3)
    b = OrientedBox([1.5, 0, 0.5], [1, 0.2, 0.5], -0.2)
    c = OrientedBox([1.5, 0, 2.0], [1, 0.2, 0.5], -0.2)
    assert a.overlaps(b) and not a.overlaps(c)
    assert a.corners_2d().shape == (4, 2)
    with pytest.raises(ValueError, match="OrientedBox"):
        OrientedBox([0, 0, 0], [1, -1, 1], 0.0)
    r = obb_overlap_3d([[0, 0, 0]], [[1, 1, 1]], [0], [[0, 0, 2.0]], [[1, 1, 1]], [0])
    assert not r[0]  # faces touching in z


@settings(max_examples=200, deadline=None)
@given(coord, coord, size, size, angle, coord, coord, size, size, angle, coord, size, coord, size)
def test_upright_boxes_overlap_where_footprints_and_heights_do(
    x1, y1, a1, b1, t1, x2, y2, a2, b2, t2, z1, c1, z2, c2
):
    """The one box test on upright boxes against shapely's footprints and the z intervals
    (an independent oracle: positive area in the plane and positive length along z)."""
    p1 = shapely.Polygon(box_corners([[x1, y1]], [[a1, b1]], [t1])[0])
    p2 = shapely.Polygon(box_corners([[x2, y2]], [[a2, b2]], [t2])[0])
    hit = obb_overlap(
        [[x1, y1, z1]], [[a1, b1, c1]], [t1], [[x2, y2, z2]], [[a2, b2, c2]], [t2], eps=0.0
    )[0]
    area = p1.intersection(p2).area
    depth = min(z1 + c1, z2 + c2) - max(z1 - c1, z2 - c2)  # shared length along z
    if area > TOL and depth > TOL:
        assert hit
    elif depth < -TOL or p1.distance(p2) > TOL or area == 0 and not p1.intersects(p2):
        assert not hit
    assert obb_overlap_3d is obb_overlap and obb_overlap_2d is obb_overlap  # one test


def _lp_depth(tri, c, h, yaw):
    """Largest delta such that a point of the triangle lies delta inside every box face."""
    R = np.array([[np.cos(yaw), np.sin(yaw), 0], [-np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    V = (tri - c) @ R.T  # (3, 3) in the box frame
    # variables: lambda_0..2, delta ; maximise delta
    A, b = [], []
    for k in range(3):
        A.append(list(V[:, k]) + [1.0])
        b.append(h[k])
        A.append(list(-V[:, k]) + [1.0])
        b.append(h[k])
    res = linprog(
        [0, 0, 0, -1],
        A_ub=A,
        b_ub=b,
        A_eq=[[1, 1, 1, 0]],
        b_eq=[1],
        bounds=[(0, None)] * 3 + [(None, None)],
    )
    return -res.fun


def test_triangle_box_against_linear_program(rng):
    n = 400
    tri = rng.uniform(-2, 2, (n, 3, 3))
    c = rng.uniform(-0.5, 0.5, (n, 3))
    h = rng.uniform(0.1, 1.0, (n, 3))
    yaw = rng.uniform(-3, 3, n)
    got = triangle_box_overlap(tri, c, h, yaw, eps=0.0)
    depth = np.array([_lp_depth(tri[k], c[k], h[k], yaw[k]) for k in range(n)])
    sure = np.abs(depth) > 1e-7
    assert (got[sure] == (depth[sure] > 0)).all()
    assert 0.1 < got.mean() < 0.9  # both outcomes are exercised


def test_box_runs_equal_general_polygon_runs(rng):
    from are_stats.builder import box_runs, runs_to_cells

    n = 400
    c = rng.uniform(-5, 45, (n, 2))
    h = rng.uniform(0.05, 9.0, (n, 2))
    yaw = rng.uniform(-7, 7, n)
    yaw[:100] = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2], 100)  # axis-aligned
    yaw[100:120] = rng.choice([1e-13, -1e-11, np.pi / 2 + 1e-12], 20)  # nearly so
    c[120:160] = np.round(c[120:160])  # sides on cell lines
    h[120:160] = np.round(h[120:160]) + 0.5
    o1, f1, out1 = rasterise_convex(box_corners(c, h, yaw), (40, 44))
    owner, rows, jlo, jhi, out2 = box_runs(c, h, yaw, (40, 44))
    o2, f2 = runs_to_cells(rows, jlo, jhi, 44, owner)
    assert set(zip(o1.tolist(), f1.tolist(), strict=True)) == set(
        zip(o2.tolist(), f2.tolist(), strict=True)
    )
    assert (out1 == out2).all()


def test_box_centres_carry_the_offset_with_the_pose():
    """pose -> box centre against the homogeneous transform T(x, y, yaw) applied to the
    offset (independent of the package)."""
    from are_stats.builder import box_centres

    rng = np.random.default_rng(7)
    pose = np.column_stack([rng.uniform(-50, 50, (20, 2)), rng.uniform(-7, 7, 20)])
    off = rng.uniform(-2, 2, (20, 3))
    want = []
    for (x, y, a), o in zip(pose, off, strict=True):
        T = np.array(
            [
                [np.cos(a), -np.sin(a), 0, x],
                [np.sin(a), np.cos(a), 0, y],
                [0, 0, 1, 0],
                [0, 0, 0, 1],
            ]
        )
        want.append((T @ np.r_[o, 1.0])[:3])
    np.testing.assert_allclose(box_centres(pose, off), np.array(want), atol=1e-12)
    # one offset for every pose, and a single pose
    np.testing.assert_allclose(box_centres(pose, off[0])[3], box_centres(pose[3], off[0])[0])


def test_rasterisation_drops_a_row_run_right_of_the_grid():
    """A row whose part of the box lies wholly beyond the grid's right edge marks nothing
    (both rasterisers used to clip it to the last column; hypothesis found x=6, y=0,
    1.25 x 3 m, yaw 1.875)."""
    from are_stats.builder import box_runs, runs_to_cells

    P = box_corners([[14.0, 8.0]], [[1.25, 3.0]], [1.875])
    _, flat, outside = rasterise_convex(P, (16, 16))
    exact = np.flatnonzero(_cell_areas(shapely.Polygon(P[0]), (16, 16)).ravel() > 0)
    assert outside[0]
    assert sorted(flat.tolist()) == exact.tolist()
    owner, rows, jlo, jhi, out = box_runs([[14.0, 8.0]], [[1.25, 3.0]], [1.875], (16, 16))
    assert out[0]
    assert sorted(runs_to_cells(rows, jlo, jhi, 16, owner)[1].tolist()) == exact.tolist()


def test_point_box_distance_is_shapelys_distance_to_the_rectangle():
    """The one point-to-box distance (robot clearance, avoidance) against shapely's
    distance from the point to the rotated rectangle polygon (0 inside), one point per box
    and one point for all boxes."""
    rng = np.random.default_rng(5)
    n = 300
    c = rng.uniform(-5, 5, (n, 2))
    h = rng.uniform(0.05, 2.0, (n, 2))
    y = rng.uniform(-np.pi, np.pi, n)
    p = rng.uniform(-8, 8, (n, 2))
    got = point_box_distance(p, c, h, y)
    corners = box_corners(c, h, y)
    polys = shapely.polygons(corners)
    want = shapely.distance(shapely.points(p), polys)
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert (got == 0).sum() == shapely.contains(polys, shapely.points(p)).sum() > 0
    one = point_box_distance(p[0], c, h, y)
    np.testing.assert_allclose(one, shapely.distance(shapely.points(p[0]), polys), atol=1e-9)
