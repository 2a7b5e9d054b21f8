"""Where artefacts enter (and leave) the map: uniform, as in the paper, or learned.

The paper places arrivals uniformly over the free cells of ``M2D`` (Fig. 3b, DECISIONS 4).
In field logs most arrivals are first seen near the scene's edges and doors. A
:class:`PositionDensity` is a density over the free cells of the occupancy grid:

* ``uniform``: equal mass on every free cell (the paper);
* ``learned``: the posterior mean of a Dirichlet over free cells, prior ``alpha`` spread
  uniformly, updated by the observed points spread with a Gaussian kernel of bandwidth
  ``h`` metres renormalised over the free cells (so no mass lands on walls or off the map):

  ``p(c) = (alpha / n_free + sum_i K_h(c, x_i) / Z_h(x_i)) / (alpha + n)``

  ``alpha`` and ``h`` are chosen by leave-one-out log-likelihood of the points' cells
  (:func:`fit_position_density`).

Draws pick a cell by its mass and a point uniformly inside it. :func:`boundary_distance`
(the distance from a point to the nearest non-free cell or the map's edge) is the statistic
the posterior-predictive checks compare.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from are_stats._checks import check_finite, check_positive
from are_stats._lazy import scipy_signal as signal

__all__ = [
    "POSITION_MODELS",
    "PositionDensity",
    "boundary_distance",
    "fit_position_density",
    "uniform_position_density",
]

#: Position models, simplest first (the paper's uniform placement is the first).
POSITION_MODELS = ("uniform", "learned")


class PositionDensity(NamedTuple):
    """A density over the cells of an occupancy grid.

    Attributes
    ----------
    prob : (H, W) float64
        Mass of each cell (zero on cells that are not free); sums to one. Row 0 is the
        grid's first row (``y = origin_y``), as in :class:`~are_stats.OccupancyGrid` arrays.
    resolution : float
        Cell size (m).
    origin : (2,) float
        Map-frame position of cell (0, 0)'s corner.
    bandwidth : float
        Kernel bandwidth (m); 0 for the uniform density.
    alpha : float
        Dirichlet prior mass (inf for the uniform density).
    loo_logpdf : (n,) float or None
        Leave-one-out log density (per m^2) of each point the density was learned from
        (None for the uniform density): the pointwise units of the PSIS-LOO comparison
        with the uniform density.
    """

    prob: np.ndarray
    resolution: float
    origin: tuple[float, float]
    bandwidth: float
    alpha: float
    loo_logpdf: np.ndarray | None = None

    def cell_of(self, xy: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of points ``xy (n, 2)``; ``-1`` off the map."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        col = np.floor((xy[:, 0] - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((xy[:, 1] - self.origin[1]) / self.resolution).astype(np.int64)
        h, w = self.prob.shape
        off = (row < 0) | (row >= h) | (col < 0) | (col >= w)
        return np.where(off, -1, row), np.where(off, -1, col)

    def logpdf(self, xy: npt.ArrayLike) -> np.ndarray:
        """Log density (per m^2) at points ``xy (n, 2)``; ``-inf`` off the free cells."""
        row, col = self.cell_of(xy)
        ok = row >= 0
        p = np.zeros(row.size)
        p[ok] = self.prob[row[ok], col[ok]]
        with np.errstate(divide="ignore"):
            return np.log(p) - 2.0 * np.log(self.resolution)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points ``(n, 2)``: a cell by its mass, then uniform inside it."""
        flat = self.prob.ravel()
        idx = rng.choice(flat.size, size=int(n), p=flat / flat.sum())
        row, col = np.divmod(idx, self.prob.shape[1])
        u = rng.random((int(n), 2))
        x = self.origin[0] + (col + u[:, 0]) * self.resolution
        y = self.origin[1] + (row + u[:, 1]) * self.resolution
        return np.column_stack([x, y])


def _free(free_mask: npt.ArrayLike) -> np.ndarray:
    free = np.asarray(free_mask, bool)
    if free.ndim != 2 or not free.any():
        raise ValueError(
            f"free_mask: expected a 2-d boolean grid with at least one free cell, "
            f"got shape {free.shape} with {int(free.sum())} free cells"
        )
    return free


def uniform_position_density(
    free_mask: npt.ArrayLike, resolution: float, origin: Sequence[float] = (0.0, 0.0)
) -> PositionDensity:
    """The paper's placement: equal mass on every free cell."""
    free = _free(free_mask)
    res = float(check_positive("resolution", resolution))
    o = check_finite("origin", origin, ndim=1)
    return PositionDensity(free / free.sum(), res, (float(o[0]), float(o[1])), 0.0, np.inf)


def _kernel(h_cells: float) -> np.ndarray:
    r = int(np.ceil(4 * h_cells))
    g = np.exp(-0.5 * (np.arange(-r, r + 1) / h_cells) ** 2)
    return np.outer(g, g)


def _smooth(counts: np.ndarray, free: np.ndarray, h_cells: float) -> tuple[np.ndarray, float]:
    """``sum_i K(c, x_i) / Z(x_i)`` over free cells, and ``K(0)`` (per-source normalised)."""
    k = _kernel(h_cells)
    z = signal.fftconvolve(free.astype(float), k, mode="same")
    src = np.where(counts > 0, counts / np.maximum(z, 1e-300), 0.0)
    out = signal.fftconvolve(src, k, mode="same")
    return np.where(free, np.maximum(out, 0.0), 0.0), z


def fit_position_density(
    xy: npt.ArrayLike,
    free_mask: npt.ArrayLike,
    resolution: float,
    origin: Sequence[float] = (0.0, 0.0),
    *,
    bandwidths: npt.ArrayLike | None = None,
    alphas: npt.ArrayLike = (0.1, 1.0, 10.0),
    base: npt.ArrayLike | None = None,
) -> PositionDensity:
    """Learn a position density from observed points (first or last sightings).

    Parameters
    ----------
    xy : (n, 2) float
        Observed points in the map frame (points off the free cells are moved to the
        nearest free cell: trackers see people on thresholds the map marks occupied).
    free_mask : (H, W) bool
        Free cells of the occupancy grid.
    resolution : float
        Cell size (m).
    origin : (2,) float
        Map-frame corner of cell (0, 0).
    bandwidths : sequence of float, optional
        Candidate kernel bandwidths (m); default ``resolution * [0.5, 1, 2, 4, 8, 16]`` capped
        at a quarter of the map's smaller side.
    alphas : sequence of float
        Candidate Dirichlet prior masses.
    base : (H, W) float, optional
        The Dirichlet prior's base measure (mass of each cell, zero off the free cells,
        summing to one): default uniform over the free cells (``1 / n_free``, the formula
        of the module docstring). A class's density pooled toward the other classes' passes
        theirs (:func:`are_stats.fitting.fit_class_positions`): a large ``alpha`` then
        returns the base.

    Returns
    -------
    PositionDensity
        With the (bandwidth, alpha) pair of highest leave-one-out log-likelihood.
    """
    free = _free(free_mask)
    res = float(check_positive("resolution", resolution))
    o = check_finite("origin", origin, ndim=1)
    pts = check_finite("xy", xy, ndim=2)
    if pts.shape[1] != 2 or pts.shape[0] == 0:
        raise ValueError(f"xy: expected an (n, 2) array of points with n >= 1, got {pts.shape}")
    uni = uniform_position_density(free, res, o)
    # snap points off the free cells (or off the map) to the nearest free cell
    h, w = free.shape
    col = np.clip(np.floor((pts[:, 0] - uni.origin[0]) / res), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor((pts[:, 1] - uni.origin[1]) / res), 0, h - 1).astype(np.int64)
    _, (near_r, near_c) = ndimage.distance_transform_edt(~free, return_indices=True)
    row, col = near_r[row, col], near_c[row, col]
    counts = np.zeros(free.shape)
    np.add.at(counts, (row, col), 1.0)
    n, n_free = pts.shape[0], int(free.sum())
    prior = None  # uniform: a / n_free on every free cell (kept bit for bit)
    if base is not None:
        prior = np.asarray(base, float)
        if prior.shape != free.shape or not np.isfinite(prior).all() or (prior < 0).any():
            raise ValueError(
                f"base: expected a finite non-negative ({h}, {w}) density, got {prior.shape}"
            )
        prior = np.where(free, prior, 0.0)
        if prior.sum() <= 0:
            raise ValueError("base: expected mass on the free cells, got none")
        prior = prior / prior.sum()
    if bandwidths is None:
        top = max(min(h, w) * res / 4.0, res)
        bandwidths = [b for b in res * np.array([0.5, 1.0, 2, 4, 8, 16]) if b <= top] or [res]
    best: tuple[float, float, float, np.ndarray] | None = None
    for bw in check_positive("bandwidths", bandwidths, ndim=1):
        smooth, z = _smooth(counts, free, bw / res)
        k0 = 1.0  # the kernel's centre weight
        own = k0 / z[row, col]
        for a in check_positive("alphas", alphas, ndim=1):
            at = a / n_free if prior is None else a * prior[row, col]
            loo = (at + smooth[row, col] - own) / (a + n - 1)
            score = float(np.sum(np.log(np.maximum(loo, 1e-300))))
            if best is None or score > best[0]:
                best = (score, float(bw), float(a), smooth, loo)
    assert best is not None
    _, bw, a, smooth, loo = best
    at_cells = a / n_free if prior is None else a * prior
    prob = np.where(free, (at_cells + smooth) / (a + n), 0.0)
    with np.errstate(divide="ignore"):
        loo_logpdf = np.log(np.maximum(loo, 1e-300)) - 2.0 * np.log(res)
    return PositionDensity(prob / prob.sum(), res, uni.origin, bw, a, loo_logpdf)


def boundary_distance(
    xy: npt.ArrayLike, free_mask: npt.ArrayLike, resolution: float, origin: Sequence[float]
) -> np.ndarray:
    """Distance (m) from each point to the nearest cell that is not free, or the map edge.

    Parameters
    ----------
    xy : (n, 2) float
    free_mask : (H, W) bool
    resolution : float
    origin : (2,) float

    Returns
    -------
    (n,) float
        Cell-centre distances (``0`` for points on non-free cells or off the map).
    """
    free = np.pad(_free(free_mask), 1, constant_values=False)
    dist = ndimage.distance_transform_edt(free) * float(resolution)
    uni = uniform_position_density(free_mask, resolution, origin)
    row, col = uni.cell_of(xy)
    out = np.zeros(row.size)
    ok = row >= 0
    out[ok] = dist[row[ok] + 1, col[ok] + 1]
    return out
