"""Oriented boxes: corners, exact footprint rasterisation and separating-axis tests.

An artefact's bounding box ``b`` (paper Sect. 3.2) is an upright box: a centre, half sizes
and a yaw about the z axis. Its footprint is a rectangle on M_2D; the AR-builder projects it
on the grid (Fig. 4a) by *exact polygon-cell coverage*:

* :func:`rasterise_convex` marks every cell whose open square shares positive area with the
  footprint (coverage > 0). For a convex polygon the covered cells of a row form one
  contiguous run: the x-extent of the polygon clipped to the row strip (from the edge
  crossings of the strip's two lines and the vertices inside it) gives the run exactly.
  Vectorised over boxes and rows, its cost is one pass over the covered cells.
* :func:`polygon_cell_coverage` returns the covered *fraction* of every cell (any simple
  polygon) from Green's theorem: with ``F(x, y)`` the area of the polygon below-left of
  ``(x, y)``, cell ``[x0, x1] x [y0, y1]`` has area ``F(x1,y1) - F(x0,y1) - F(x1,y0) +
  F(x0,y0)``, and ``F`` is a sum over edges of closed-form integrals of ``min(Y(X), y)``.

Overlap tests are strict: two shapes collide when they share positive area (penetration
larger than ``eps`` along every separating axis); shapes that only touch do not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite

__all__ = [
    "OrientedBox",
    "box_centres",
    "box_corners",
    "obb_overlap",
    "obb_overlap_2d",
    "obb_overlap_3d",
    "point_box_distance",
    "footprint_runs",
    "runs_to_cells",
    "box_runs",
    "rasterise_convex",
    "polygon_cell_coverage",
    "triangle_box_overlap",
]


@dataclass(frozen=True)
class OrientedBox:
    """An upright oriented box, one at a time: its footprint corners and a strict overlap
    test with another box (the functions below take arrays of boxes).

    Attributes
    ----------
    centre : (3,) float
        Box centre in F_E.
    half : (3,) float
        Half sizes along the box's own x, y, z axes.
    yaw : float
        Rotation about z (radians).
    """

    centre: np.ndarray
    half: np.ndarray
    yaw: float

    def __post_init__(self) -> None:
        c = check_finite("centre", self.centre, ndim=1)
        h = check_finite("half", self.half, ndim=1)
        if c.shape != (3,) or h.shape != (3,) or (h <= 0).any():
            raise ValueError(
                f"OrientedBox: expected centre (3,) and half sizes (3,) > 0, got "
                f"{c.tolist()} and {h.tolist()}"
            )
        object.__setattr__(self, "centre", c)
        object.__setattr__(self, "half", h)
        object.__setattr__(self, "yaw", float(check_finite("yaw", self.yaw)))

    def corners_2d(self) -> np.ndarray:
        """``(4, 2)`` footprint corners, counter-clockwise."""
        return box_corners(self.centre[None, :2], self.half[None, :2], np.array([self.yaw]))[0]

    def overlaps(self, other: OrientedBox, eps: float = 1e-9) -> bool:
        """Whether the two boxes share positive volume."""
        return bool(
            obb_overlap(
                self.centre[None],
                self.half[None],
                np.array([self.yaw]),
                other.centre[None],
                other.half[None],
                np.array([other.yaw]),
                eps,
            )[0]
        )


def box_centres(pose: npt.ArrayLike, offset: npt.ArrayLike) -> np.ndarray:
    """Centres of artefact boxes from the artefacts' poses: pose -> box, for everyone
    (:meth:`Scene.at <are_stats.Scene.at>`, the mission's footprints and avoidance, the
    AR-builder).

    An artefact's frame F_A sits at ``(x, y)`` on the ground with heading ``yaw``; its box
    centre is ``offset`` in F_A (the row of Q's box centre), so the centre in the world is
    ``(x, y) + R(yaw) offset_xy`` at height ``offset_z``.

    Parameters
    ----------
    pose : (n, 3) float
        ``x, y, yaw`` of F_A.
    offset : (n, 3) or (3,) float
        Box centre in F_A.

    Returns
    -------
    (n, 3) float
    """
    p = np.asarray(pose, float).reshape(-1, 3)
    o = np.asarray(offset, float)
    if o.shape != p.shape:
        o = np.broadcast_to(o, p.shape)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    out = np.empty(p.shape)
    out[:, 0] = p[:, 0] + c * o[:, 0] - s * o[:, 1]
    out[:, 1] = p[:, 1] + s * o[:, 0] + c * o[:, 1]
    out[:, 2] = o[:, 2]
    return out


def box_corners(centre: npt.ArrayLike, half: npt.ArrayLike, yaw: npt.ArrayLike) -> np.ndarray:
    """Footprint corners of oriented rectangles.

    Parameters
    ----------
    centre : (n, 2) float
    half : (n, 2) float
    yaw : (n,) float

    Returns
    -------
    (n, 4, 2) float
        Corners counter-clockwise, starting at ``centre - half`` (in the box frame).
    """
    c = np.asarray(centre, float)
    h = np.asarray(half, float)
    a = np.asarray(yaw, float)
    cs, sn = np.cos(a), np.sin(a)
    sx = np.array([-1.0, 1.0, 1.0, -1.0])
    sy = np.array([-1.0, -1.0, 1.0, 1.0])
    lx = sx[None, :] * h[:, :1]
    ly = sy[None, :] * h[:, 1:2]
    x = c[:, :1] + cs[:, None] * lx - sn[:, None] * ly
    y = c[:, 1:2] + sn[:, None] * lx + cs[:, None] * ly
    return np.stack([x, y], axis=-1)


def point_box_distance(
    point: npt.ArrayLike, box_xy: npt.ArrayLike, half_xy: npt.ArrayLike, yaw: npt.ArrayLike
) -> np.ndarray:
    """Distance ``(n,)`` from a point to each oriented rectangle (0 inside): the one
    point-to-box distance of the package (the robot's clearance, the avoidance's detours
    and waits).

    Parameters
    ----------
    point : (2,) or (n, 2) float
        One point, or one point per rectangle.
    box_xy : (n, 2) or (2,) float
        Rectangle centres.
    half_xy : (n, 2) or (2,) float
        Half sizes along the rectangle's own axes (one for all, or one each).
    yaw : (n,) float or float
        Headings (rad).

    Returns
    -------
    (n,) float

    Examples
    --------
    >>> point_box_distance([0.0, 0.0], [[3.0, 4.0]], [[0.0, 0.0]], [0.3]).tolist()
    [5.0]
    """
    c = np.asarray(point, float)
    b = np.asarray(box_xy, float).reshape(-1, 2)
    h = np.asarray(half_xy, float).reshape(-1, 2)
    y = np.asarray(yaw, float).reshape(-1)
    d = c.reshape(-1, 2) - b
    cs, sn = np.cos(y), np.sin(y)
    local = np.stack([cs * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + cs * d[:, 1]], axis=1)
    q = np.abs(local) - h
    return np.linalg.norm(np.maximum(q, 0.0), axis=1)


def obb_overlap(
    ca: npt.ArrayLike,
    ha: npt.ArrayLike,
    ya: npt.ArrayLike,
    cb: npt.ArrayLike,
    hb: npt.ArrayLike,
    yb: npt.ArrayLike,
    eps: float = 1e-9,
) -> np.ndarray:
    """Separating-axis test of pairs of oriented rectangles, or of upright boxes: the one
    box-versus-box test of the package.

    Upright boxes (a z column in all four of ``ca``, ``ha``, ``cb``, ``hb``) separate
    either in the plane (the test of their footprints) or along z.

    Parameters
    ----------
    ca, cb : (n, 2) or (n, 3) float
        Centres.
    ha, hb : (n, 2) or (n, 3) float
        Half sizes.
    ya, yb : (n,) float
        Yaws.
    eps : float
        Overlaps shallower than ``eps`` (touching) do not count.

    Returns
    -------
    (n,) bool
        Whether pair ``k`` shares positive area (volume, for upright boxes).

    Examples
    --------
    >>> obb_overlap([[0, 0]], [[1, 1]], [0], [[1.5, 0]], [[1, 1]], [0.3]).tolist()
    [True]
    >>> obb_overlap([[0, 0, 0]], [[1, 1, 1]], [0], [[1.5, 0, 2]], [[1, 1, 1]], [0.3]).tolist()
    [False]
    """
    ca, cb = np.asarray(ca, float), np.asarray(cb, float)
    ha, hb = np.asarray(ha, float), np.asarray(hb, float)
    ya, yb = np.asarray(ya, float), np.asarray(yb, float)
    # the axes u = (cos, sin), v = (-sin, cos) of each box, component by component
    d0, d1 = cb[:, 0] - ca[:, 0], cb[:, 1] - ca[:, 1]
    ua0, ua1 = np.cos(ya), np.sin(ya)
    ub0, ub1 = np.cos(yb), np.sin(yb)
    # |cos| / |sin| of the relative rotation: |u_a . u_b|, |u_a . v_b|
    c = np.abs(ua0 * ub0 + ua1 * ub1)
    s = np.abs(ua0 * -ub1 + ua1 * ub0)
    hax, hay, hbx, hby = ha[:, 0], ha[:, 1], hb[:, 0], hb[:, 1]
    sep = np.abs(d0 * ua0 + d1 * ua1) >= hax + c * hbx + s * hby - eps
    sep |= np.abs(d0 * -ua1 + d1 * ua0) >= hay + s * hbx + c * hby - eps
    sep |= np.abs(d0 * ub0 + d1 * ub1) >= hbx + c * hax + s * hay - eps
    sep |= np.abs(d0 * -ub1 + d1 * ub0) >= hby + s * hax + c * hay - eps
    if min(ca.shape[1], cb.shape[1], ha.shape[1], hb.shape[1]) > 2:  # upright boxes: and z
        sep |= ~(np.abs(cb[:, 2] - ca[:, 2]) < ha[:, 2] + hb[:, 2] - eps)
    return ~sep


#: :func:`obb_overlap` under the names its callers know: rectangles (``(n, 2)`` halves) and
#: upright boxes (``(n, 3)``).
obb_overlap_2d = obb_overlap
obb_overlap_3d = obb_overlap


def footprint_runs(
    poly: npt.ArrayLike, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Row runs of the cells with positive-area overlap with convex polygons.

    Parameters
    ----------
    poly : (n, k, 2) float
        Convex polygons in grid cell units ``(u, v)`` (cell ``(i, j)`` is
        ``[j, j + 1] x [i, i + 1]``); vertex order may be either orientation.
    shape : (height, width)
        Grid shape.

    Returns
    -------
    rows : (n, R) int64
        Row index of run ``r`` of polygon ``k``.
    jlo, jhi : (n, R) int64
        First and last column of the run, clipped to the grid (``jhi < jlo`` for an empty
        run: padding rows, rows outside the grid).
    outside : (n,) bool
        Whether polygon ``k`` covers area outside the grid.
    """
    P = np.asarray(poly, float)
    n = P.shape[0]
    H, W = int(shape[0]), int(shape[1])
    if n == 0:
        z = np.zeros((0, 1), np.int64)
        return z, z, z - 1, np.zeros(0, bool)
    x, y = P[..., 0], P[..., 1]
    vlo = np.floor(y.min(axis=1))
    vhi = np.ceil(y.max(axis=1))
    nrows = np.maximum((vhi - vlo).astype(np.int64), 1)
    R = int(nrows.max())
    lines = vlo[:, None] + np.arange(R + 1)[None, :]  # (n, R+1)
    xb, yb = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    ylo_e, yhi_e = np.minimum(y, yb), np.maximum(y, yb)
    dy = yb - y
    nz = dy != 0
    slope = np.where(nz, (xb - x) / np.where(nz, dy, 1.0), 0.0)
    L = lines[:, :, None]  # (n, R+1, 1)
    hit = (L >= ylo_e[:, None, :]) & (L <= yhi_e[:, None, :]) & nz[:, None, :]
    xc = x[:, None, :] + (L - y[:, None, :]) * slope[:, None, :]
    lo_l = np.where(hit, xc, np.inf).min(axis=2)
    hi_l = np.where(hit, xc, -np.inf).max(axis=2)
    # vertices inside each strip
    inside = (y[:, None, :] >= lines[:, :-1, None]) & (y[:, None, :] <= lines[:, 1:, None])
    xmin = np.minimum(
        np.minimum(lo_l[:, :-1], lo_l[:, 1:]), np.where(inside, x[:, None, :], np.inf).min(2)
    )
    xmax = np.maximum(
        np.maximum(hi_l[:, :-1], hi_l[:, 1:]), np.where(inside, x[:, None, :], -np.inf).max(2)
    )
    rows = lines[:, :-1].astype(np.int64)  # (n, R)
    valid = (np.arange(R)[None, :] < nrows[:, None]) & (xmax > xmin)
    jlo = np.floor(np.where(valid, xmin, 0.0))
    jhi = np.ceil(np.where(valid, xmax, 0.0)) - 1
    outside = (valid & ((rows < 0) | (rows >= H) | (jlo < 0) | (jhi > W - 1))).any(axis=1)
    keep = valid & (rows >= 0) & (rows < H)
    # a run wholly right of the grid clips to jlo = W > jhi = W - 1: empty, not column W - 1
    jlo_c = np.where(keep, np.clip(jlo, 0, W), 0).astype(np.int64)
    jhi_c = np.where(keep, np.clip(jhi, -1, W - 1), -1).astype(np.int64)
    return np.clip(rows, 0, H - 1), jlo_c, jhi_c, outside


def runs_to_cells(
    rows: np.ndarray,
    jlo: np.ndarray,
    jhi: np.ndarray,
    width: int,
    owner: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Expand row runs to ``(owner, flat)`` cell indices.

    Parameters
    ----------
    rows, jlo, jhi : (n, R) or (m,) int
        Runs as returned by :func:`footprint_runs` (padded, owner = row index) or by
        :func:`box_runs` (flat, with ``owner``).
    width : int
        Grid width.
    owner : (m,) int, optional
        Owner of each flat run.
    """
    if owner is None:
        n, R = rows.shape
        owner = np.repeat(np.arange(n), R)
    rows, jlo, jhi = rows.ravel(), jlo.ravel(), jhi.ravel()
    cnt = np.maximum(jhi - jlo + 1, 0)
    total = int(cnt.sum())
    start = rows * width + jlo
    cells_owner = np.repeat(np.asarray(owner).ravel(), cnt)
    flat = np.repeat(start - (np.cumsum(cnt) - cnt), cnt) + np.arange(total)
    return cells_owner, flat


def box_runs(
    centre: npt.ArrayLike, half: npt.ArrayLike, yaw: npt.ArrayLike, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Row runs of the cells with positive-area overlap with oriented rectangles.

    The same cells as :func:`footprint_runs`, specialised to rectangles: the left boundary
    of a rectangle is the maximum of (at most) two lines ``x = l(y)``, convex in ``y``, so
    its minimum over a row strip lies at a strip end or at the leftmost corner (and
    symmetrically on the right). Boxes are processed in buckets of similar row counts so
    that padding stays small.

    Parameters
    ----------
    centre : (n, 2) float
        Centres in grid cell units ``(u, v)``.
    half : (n, 2) float
        Half sizes in cell units.
    yaw : (n,) float
        Yaws relative to the grid axes.
    shape : (height, width)

    Returns
    -------
    owner, rows, jlo, jhi : (m,) int64
        One entry per non-empty run inside the grid.
    outside : (n,) bool
        Whether box ``k`` covers area outside the grid.
    """
    c = np.asarray(centre, float)
    h = np.asarray(half, float)
    a = np.asarray(yaw, float)
    n = c.shape[0]
    H, W = int(shape[0]), int(shape[1])
    outside = np.zeros(n, bool)
    if n == 0:
        z = np.zeros(0, np.int64)
        return z, z, z, z, outside
    cs, sn = np.cos(a), np.sin(a)
    ext_y = h[:, 0] * np.abs(sn) + h[:, 1] * np.abs(cs)
    ext_x = h[:, 0] * np.abs(cs) + h[:, 1] * np.abs(sn)
    ymin, ymax = c[:, 1] - ext_y, c[:, 1] + ext_y
    vlo = np.floor(ymin)
    nrows = np.maximum((np.ceil(ymax) - vlo).astype(np.int64), 1)
    # the two edge normals with a negative x component (outward, left side): +-u, +-v
    uv = np.stack([np.stack([cs, sn], -1), np.stack([-sn, cs], -1)], axis=1)  # (n, face, xy)
    nrm = uv * np.where(uv[:, :, :1] > 0, -1.0, 1.0)  # the outward normals facing left
    off = (h[:, :2] + np.einsum("nfi,ni->nf", nrm, c))[:, :, None]  # (n, face, 1)
    nrm = nrm[..., None]  # (n, face, xy, 1)
    opp = 2 * h[:, :2, None] - off  # the opposite faces: -n.p <= h - n.c
    has_line = np.abs(nrm[:, :, 0]) >= 1e-9  # (n, face, 1)
    left_x = np.where(has_line, nrm[:, :, 0], -1.0)
    right_x = np.where(has_line, -nrm[:, :, 0], 1.0)
    corners = box_corners(c, h, a)
    il = np.argmin(corners[..., 0], axis=1)
    ir = np.argmax(corners[..., 0], axis=1)
    ar = np.arange(n)
    xl, yl = corners[ar, il, 0], corners[ar, il, 1]
    xr, yr = corners[ar, ir, 0], corners[ar, ir, 1]
    out = ([], [], [], [])
    for idx in _row_buckets(nrows):
        R = int(nrows[idx].max())
        lines = vlo[idx, None] + np.arange(R + 1)[None, :]
        yc = np.clip(lines, ymin[idx, None], ymax[idx, None])[:, None, :]  # (m, 1, R+1)
        ny, ok = nrm[idx, :, 1], has_line[idx]
        # left faces n.p <= o with nx < 0: x >= (o - ny y) / nx; right: the opposite faces
        left = np.where(ok, (off[idx] - ny * yc) / left_x[idx], -np.inf).max(axis=1)
        right = np.where(ok, (opp[idx] + ny * yc) / right_x[idx], np.inf).min(axis=1)
        # axis-aligned sides (no line): the side is the vertical edge at c -+ ext_x
        left = np.where(np.isfinite(left), left, (c[idx, 0] - ext_x[idx])[:, None])
        right = np.where(np.isfinite(right), right, (c[idx, 0] + ext_x[idx])[:, None])
        y0, y1 = lines[:, :-1], lines[:, 1:]
        xmin = np.minimum(left[:, :-1], left[:, 1:])
        xmax = np.maximum(right[:, :-1], right[:, 1:])
        inl = (yl[idx, None] >= y0) & (yl[idx, None] <= y1)
        inr = (yr[idx, None] >= y0) & (yr[idx, None] <= y1)
        xmin = np.where(inl, np.minimum(xmin, xl[idx, None]), xmin)
        xmax = np.where(inr, np.maximum(xmax, xr[idx, None]), xmax)
        rows = y0.astype(np.int64)
        valid = (np.arange(R)[None, :] < nrows[idx, None]) & (xmax > xmin)
        jlo = np.floor(np.where(valid, xmin, 0.0))
        jhi = np.ceil(np.where(valid, xmax, 0.0)) - 1
        outside[idx] = (valid & ((rows < 0) | (rows >= H) | (jlo < 0) | (jhi > W - 1))).any(axis=1)
        keep = valid & (rows >= 0) & (rows < H)
        jlo_c = np.clip(jlo[keep], 0, W).astype(np.int64)  # wholly right of the grid: empty
        jhi_c = np.clip(jhi[keep], -1, W - 1).astype(np.int64)
        good = jhi_c >= jlo_c
        out[0].append(np.broadcast_to(idx[:, None], keep.shape)[keep][good])
        out[1].append(rows[keep][good])
        out[2].append(jlo_c[good])
        out[3].append(jhi_c[good])
    owner, rows, jlo, jhi = (np.concatenate(x) for x in out)
    return owner, rows, jlo, jhi, outside


def _row_buckets(nrows: np.ndarray, small: int = 4096) -> list[np.ndarray]:
    """Boxes grouped by row count ``(n,)``: by ``ceil(log2(rows))``, so that padding stays
    under half a group, with neighbouring groups merged while the merged group holds at
    most ``small`` padded rows (each group costs a fixed number of array operations, which
    dominate for a few boxes). Groups of box indices, by increasing row count; a box's runs
    do not depend on its group."""
    if nrows.size * int(nrows.max()) <= small:
        return [np.arange(nrows.size)]
    bucket = np.ceil(np.log2(nrows)).astype(np.int64)
    groups: list[np.ndarray] = []
    for bk in np.unique(bucket):
        idx = np.flatnonzero(bucket == bk)
        if groups and (groups[-1].size + idx.size) * int(nrows[idx].max()) <= small:
            groups[-1] = np.concatenate([groups[-1], idx])
        else:
            groups.append(idx)
    return groups


def rasterise_convex(
    poly: npt.ArrayLike, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cells with positive-area overlap with convex polygons (exact, not centre sampling).

    Parameters
    ----------
    poly : (n, k, 2) float
        Convex polygons in grid cell units, as for :func:`footprint_runs`.
    shape : (height, width)
        Grid shape; cells outside are dropped.

    Returns
    -------
    owner : (m,) int64
        Polygon index of each covered cell.
    flat : (m,) int64
        Flat index ``i * width + j`` of each covered cell inside the grid.
    outside : (n,) bool
        Whether polygon ``k`` covers area outside the grid.
    """
    rows, jlo, jhi, outside = footprint_runs(poly, shape)
    owner, flat = runs_to_cells(rows, jlo, jhi, int(shape[1]))
    return owner, flat, outside


def _relu_mean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean of ``max(t, 0)`` for ``t`` linear from ``a`` to ``b`` (exact, no cancellation)."""
    both_pos = (a >= 0) & (b >= 0)
    mixed = (a > 0) != (b > 0)
    d = np.abs(b - a)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = (np.maximum(a, 0) ** 2 + np.maximum(b, 0) ** 2) / (2 * d)
    return np.where(both_pos, 0.5 * (a + b), np.where(mixed & (d > 0), m, 0.0))


def polygon_cell_coverage(vertices: npt.ArrayLike) -> tuple[int, int, np.ndarray]:
    """Exact area fraction of every grid cell covered by a simple polygon.

    Parameters
    ----------
    vertices : (k, 2) float
        Polygon in grid cell units ``(u, v)``, either orientation.

    Returns
    -------
    i0, j0 : int
        Row and column of the window's lower-left cell.
    coverage : (h, w) float
        Covered fraction of cell ``(i0 + r, j0 + c)`` in ``[0, 1]``.

    Examples
    --------
    >>> i0, j0, cov = polygon_cell_coverage([[0.5, 0.0], [1.5, 0.0], [1.5, 1.0], [0.5, 1.0]])
    >>> (i0, j0), cov.tolist()
    ((0, 0), [[0.5, 0.5]])
    """
    V = check_finite("vertices", vertices, ndim=2)
    if V.shape[0] < 3 or V.shape[1] != 2:
        raise ValueError(f"vertices: expected (k >= 3, 2) polygon vertices, got {V.shape}")
    j0, i0 = np.floor(V.min(axis=0)).astype(int)
    j1, i1 = np.ceil(V.max(axis=0)).astype(int)
    j1, i1 = max(j1, j0 + 1), max(i1, i0 + 1)
    X = np.arange(j0, j1 + 1, dtype=float)[None, :, None]
    Y = np.arange(i0, i1 + 1, dtype=float)[:, None, None]
    xa, ya = V[:, 0], V[:, 1]
    xb, yb = np.roll(xa, -1), np.roll(ya, -1)
    left = np.minimum(xa, xb)
    right = np.maximum(xa, xb)
    y_left = np.where(xa <= xb, ya, yb)
    y_right = np.where(xa <= xb, yb, ya)
    span = right - left
    hi = np.minimum(right, X)  # (1, nx, k)
    length = np.maximum(hi - left, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(span > 0, length / np.where(span > 0, span, 1.0), 0.0)
    y_hi = y_left + t * (y_right - y_left)
    integral = length * (0.5 * (y_left + y_hi) - _relu_mean(y_left - Y, y_hi - Y))
    sign = -np.sign(xb - xa)
    F = (sign * integral).sum(axis=-1)  # (ny+1, nx+1)
    cov = F[1:, 1:] - F[:-1, 1:] - F[1:, :-1] + F[:-1, :-1]
    area2 = np.sum(xa * yb - xb * ya)
    if area2 < 0:
        cov = -cov
    return int(i0), int(j0), np.clip(cov, 0.0, 1.0)


def triangle_box_overlap(
    tri: npt.ArrayLike,
    centre: npt.ArrayLike,
    half: npt.ArrayLike,
    yaw: npt.ArrayLike,
    eps: float = 1e-9,
) -> np.ndarray:
    """Separating-axis test of triangles against upright oriented boxes (13 axes).

    Parameters
    ----------
    tri : (n, 3, 3) float
        Triangle vertices in F_E.
    centre, half : (n, 3) float
        Box centres and half sizes.
    yaw : (n,) float
        Box yaws.
    eps : float
        Contacts shallower than ``eps`` do not count.

    Returns
    -------
    (n,) bool
        Whether triangle ``k`` intersects the interior of box ``k``.
    """
    T = np.asarray(tri, float) - np.asarray(centre, float)[:, None, :]
    h = np.asarray(half, float)
    a = np.asarray(yaw, float)
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    v = np.stack(
        [c * T[..., 0] + s * T[..., 1], -s * T[..., 0] + c * T[..., 1], T[..., 2]], axis=-1
    )  # box frame (n, 3, 3)
    sep = ((v.min(axis=1) >= h - eps) | (v.max(axis=1) <= -h + eps)).any(axis=1)
    f = np.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 1], v[:, 0] - v[:, 2]], axis=1)  # (n,3,3)
    normal = np.cross(f[:, 0], f[:, 1])
    axes = [normal]
    eye = np.eye(3)
    for kk in range(3):
        for j in range(3):
            axes.append(np.cross(np.broadcast_to(eye[kk], f[:, j].shape), f[:, j]))
    for ax in axes:
        norm = np.linalg.norm(ax, axis=1)
        p = np.einsum("nij,nj->ni", v, ax)
        r = np.einsum("nj,nj->n", h, np.abs(ax))
        tol = eps * norm
        good = norm > 1e-12 * (1.0 + np.abs(v).max(axis=(1, 2)))
        sep |= good & ((p.min(axis=1) >= r - tol) | (p.max(axis=1) <= -r + tol))
    return ~sep
