"""Pictures of a frame: the camera view with boxes coloured perceived/occluded over the
depth image, and the top view with the view cone W (paper section 3.3, Fig. 4)."""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from are_stats._atomic import save_figure
from are_stats.environment import OccupancyGrid
from are_stats.perception._camera import CameraModel, fov_cone
from are_stats.perception._perceive import _EDGES, _SIGNS, PerceptionResult

if TYPE_CHECKING:
    import matplotlib.axes
    import matplotlib.figure

__all__ = ["PerceivedFrame", "plot_camera_view", "plot_top_view", "save_figure"]

_COLOURS = {"perceived": "#1a9850", "occluded": "#d73027", "outside": "#969696"}


class PerceivedFrame(NamedTuple):
    """One perceived frame, whole: the camera, its depth image, the boxes and what the
    camera made of them; what :func:`plot_camera_view` and :func:`plot_top_view` draw.

    Build it from a :func:`~are_stats.perception.perceive_frames` result with
    :meth:`from_result`.

    Attributes
    ----------
    camera : CameraModel
        The camera at the frame's pose (its ``K``, ``width``, ``height`` and ``pose`` are
        drawn; e.g. a :class:`~are_stats.perception.PinholeCamera`).
    depth : (height, width) float
        The augmented depth image (m; +inf where nothing is hit within ``d_max``).
    centers : (n, 3) float
        Box centres (m, world frame).
    half_extents : (n, 3) float
        Half sizes (m).
    rotations : (n, 3, 3) float
        Box-to-world rotations (:func:`~are_stats.perception.yaw_rotations` for upright
        boxes; the top view turns each footprint by the upper-left 2 x 2 block).
    counts : (n,) int
        Pixel counts of the frame.
    perceived : (n,) bool
        Membership in A_f.
    d_max : float
        The range the frame was traced to (m): the depth colour scale's upper end and the
        view cone's length.
    """

    camera: CameraModel
    depth: np.ndarray
    centers: np.ndarray
    half_extents: np.ndarray
    rotations: np.ndarray
    counts: np.ndarray
    perceived: np.ndarray
    d_max: float

    @classmethod
    def from_result(
        cls,
        result: PerceptionResult,
        t: int,
        camera: CameraModel,
        centers: npt.ArrayLike,
        half_extents: npt.ArrayLike,
        rotations: npt.ArrayLike,
        d_max: float,
    ) -> PerceivedFrame:
        """Frame ``t`` of a :func:`~are_stats.perception.perceive_frames` result, with the
        arguments that call was given.

        Parameters
        ----------
        result : PerceptionResult
            Traced with ``return_depth=True``.
        t : int
            The frame.
        camera : CameraModel
            The camera at frame ``t``'s pose (for a trajectory of ``poses``,
            ``camera.with_pose(poses[t])``).
        centers : (n, 3) or (T, n, 3) float
            Box centres (per frame for boxes that move: frame ``t``'s are taken).
        half_extents : (n, 3) float
        rotations : (n, 3, 3) or (T, n, 3, 3) float
        d_max : float
            The range the frame was traced to (m).

        Returns
        -------
        PerceivedFrame

        Raises
        ------
        ValueError
            For a result without depth images or a frame out of range.
        """
        if result.depth is None:
            raise ValueError("result: expected depth images (perceive_frames(return_depth=True))")
        n_frames = result.depth.shape[0]
        if not 0 <= t < n_frames:
            raise ValueError(f"t: expected a frame in [0, {n_frames}), got {t}")
        c = np.asarray(centers, float)
        r = np.asarray(rotations, float)
        return cls(
            camera=camera,
            depth=np.asarray(result.depth[t], float),
            centers=c[t] if c.ndim == 3 else c,
            half_extents=np.asarray(half_extents, float),
            rotations=r[t] if r.ndim == 4 else r,
            counts=np.asarray(result.counts[t]),
            perceived=np.asarray(result.perceived[t], bool),
            d_max=float(d_max),
        )


def _status(counts: np.ndarray, perceived: np.ndarray) -> list[str]:
    return [
        "perceived" if p else ("occluded" if c > 0 else "outside")
        for c, p in zip(counts, perceived, strict=True)
    ]


def _legend(ax, used: set[str]) -> None:
    # lazy: matplotlib adds 0.94 s CPU to `import are_stats.perception`
    from matplotlib.lines import Line2D

    labels = {
        "perceived": "perceived (count > tau)",
        "occluded": "occluded (0 < count <= tau)",
        "outside": "hidden or out of view (count 0)",
    }
    handles = [
        Line2D([], [], color=_COLOURS[k], lw=2, label=labels[k])
        for k in ("perceived", "occluded", "outside")
        if k in used
    ]
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.85)


def plot_camera_view(
    frame: PerceivedFrame, *, ax: matplotlib.axes.Axes | None = None
) -> matplotlib.figure.Figure:
    """Camera view: the depth image (colour scale ``[0, d_max]``) with every box's
    wireframe, projected by the frame's camera, coloured by its A_f status.

    Parameters
    ----------
    frame : PerceivedFrame
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        When the depth image's shape is not the camera's.
    """
    # lazy: matplotlib adds 0.94 s CPU to `import are_stats.perception`
    import matplotlib.pyplot as plt

    camera, z = frame.camera, np.asarray(frame.depth, float)
    if z.shape != (camera.height, camera.width):
        raise ValueError(f"depth: expected shape ({camera.height}, {camera.width}), got {z.shape}")
    if ax is None:
        _, ax = plt.subplots(figsize=(7.5, 7.5 * camera.height / camera.width + 0.6))
    fin = np.isfinite(z)
    im = ax.imshow(
        np.where(fin, z, np.nan),
        cmap="viridis",
        vmin=0.0,
        vmax=float(frame.d_max),
        extent=(0, camera.width, camera.height, 0),
        interpolation="nearest",
    )
    ax.set_facecolor("#f0f0f0")
    ax.figure.colorbar(
        im, ax=ax, fraction=0.035, pad=0.02, label="depth (m); blank: nothing within d_max"
    )
    c, h, r = frame.centers, frame.half_extents, frame.rotations
    status = _status(frame.counts, frame.perceived)
    used = set()
    r_cam, c_cam = camera.pose[:3, :3], camera.pose[:3, 3]
    k = camera.K
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    z_near = 1e-3
    for a in range(len(c)):
        corners = c[a] + (_SIGNS * h[a]) @ r[a].T
        pc = (corners - c_cam) @ r_cam
        colour = _COLOURS[status[a]]
        drawn = False
        for i, j in _EDGES:
            p, q = pc[i], pc[j]
            if p[2] < z_near and q[2] < z_near:
                continue
            if p[2] < z_near or q[2] < z_near:  # clip the edge at the near plane
                s = (z_near - p[2]) / (q[2] - p[2])
                m = p + s * (q - p)
                p, q = (m, q) if p[2] < z_near else (p, m)
            e = np.stack([p, q])
            uv = np.column_stack(
                [
                    fx * e[:, 0] / e[:, 2] + cx,
                    fy * e[:, 1] / e[:, 2] + cy,
                ]
            )
            ax.plot(uv[:, 0], uv[:, 1], color=colour, lw=1.4)
            drawn = True
        if drawn:
            used.add(status[a])
    ax.set_xlim(0, camera.width)
    ax.set_ylim(camera.height, 0)
    ax.set_xlabel("u (pixels)")
    ax.set_ylabel("v (pixels)")
    n_p = int(np.sum(frame.perceived))
    ax.set_title(f"Camera view: {n_p} of {len(c)} artefacts perceived")
    _legend(ax, used)
    return ax.figure


def plot_top_view(
    frame: PerceivedFrame,
    *,
    grid: OccupancyGrid | None = None,
    ax: matplotlib.axes.Axes | None = None,
) -> matplotlib.figure.Figure:
    """Top view: the occupancy grid, the camera's centre and view cone W cut at ``d_max``,
    and the boxes' footprints (turned by their rotations' upper-left 2 x 2 block) coloured
    by their A_f status.

    Parameters
    ----------
    frame : PerceivedFrame
    grid : OccupancyGrid, optional
        Drawn underneath (free white, occupied black, unknown grey).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    # lazy: matplotlib adds 0.94 s CPU to `import are_stats.perception`
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    if ax is None:
        _, ax = plt.subplots(figsize=(7.5, 6.5))
    if grid is not None:
        img = np.full(grid.shape, 0.75)
        img[grid.data == 0] = 1.0
        img[grid.data >= 65] = 0.1
        ox, oy, _ = grid.origin
        ax.imshow(
            img,
            cmap="gray",
            vmin=0,
            vmax=1,
            origin="lower",
            interpolation="nearest",
            extent=(ox, ox + grid.width * grid.resolution, oy, oy + grid.height * grid.resolution),
        )
    camera, d_max = frame.camera, frame.d_max
    cone = fov_cone(camera, d_max)
    # horizontal footprint of the cone: hull of the apex and the far corners
    # lazy: SciPy's spatial adds 0.35 s CPU to `import are_stats.perception`
    from scipy.spatial import ConvexHull

    pts = cone[:, :2]
    try:
        hull = pts[ConvexHull(pts).vertices]
    except Exception:  # degenerate (camera looking straight up/down)
        hull = pts
    ax.add_patch(
        Polygon(
            hull,
            closed=True,
            fc="#fee08b",
            ec="#f46d43",
            alpha=0.45,
            lw=1.5,
            label=f"view cone W (d_max = {d_max:g} m)",
        )
    )
    ax.plot(*camera.pose[:2, 3], marker="o", color="#f46d43", ms=6)
    c, h, r = frame.centers, frame.half_extents, frame.rotations
    status = _status(frame.counts, frame.perceived)
    used = set()
    for a in range(len(c)):
        loc = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * h[a, :2]
        xy = c[a, :2] + loc @ r[a, :2, :2].T
        ax.add_patch(Polygon(xy, closed=True, fc=_COLOURS[status[a]], ec="k", lw=0.5, alpha=0.9))
        used.add(status[a])
    lim = np.vstack([hull, c[:, :2]]) if len(c) else hull
    if grid is None:
        pad = 1.0
        ax.set_xlim(lim[:, 0].min() - pad, lim[:, 0].max() + pad)
        ax.set_ylim(lim[:, 1].min() - pad, lim[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Top view: view cone and artefacts")
    _legend(ax, used)
    handles, labels = ax.get_legend_handles_labels()
    leg = ax.get_legend()
    if leg is not None:
        handles = leg.legend_handles + handles
        labels = [t.get_text() for t in leg.get_texts()] + labels
    ax.legend(handles, labels, loc="upper right", fontsize=8, framealpha=0.85)
    return ax.figure
