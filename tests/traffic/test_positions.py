"""Entry/exit position densities: uniform truth, door-concentrated recovery, held-out fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from are_stats.traffic._positions import (
    boundary_distance,
    fit_position_density,
    uniform_position_density,
)

RES, ORIGIN = 0.5, (-10.0, -5.0)


def courtyard() -> np.ndarray:
    """A 40 x 60 cell (20 m x 30 m) free area, a pillar block in the middle."""
    free = np.ones((40, 60), bool)
    free[15:25, 25:35] = False
    return free


def door_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """Truth: 85 % enter through two 2 m doors on the west and north edges, 15 % anywhere."""
    door = rng.random(n) < 0.85
    west = rng.random(n) < 0.5
    # west door: x in [0, 0.5) m from the edge, y in [9, 11) m; north door: y near top
    x = np.where(west, rng.uniform(0, 0.5, n), rng.uniform(14, 16, n))
    y = np.where(west, rng.uniform(9, 11, n), rng.uniform(19.5, 20, n))
    uni = uniform_position_density(courtyard(), RES, ORIGIN).sample(rng, n)
    pts = np.column_stack([x + ORIGIN[0], y + ORIGIN[1]])
    return np.where(door[:, None], pts, uni)


def test_uniform_density_is_the_papers_placement():
    free = courtyard()
    d = uniform_position_density(free, RES, ORIGIN)
    area = free.sum() * RES**2
    pts = d.sample(np.random.default_rng(0), 2000)
    np.testing.assert_allclose(d.logpdf(pts), -np.log(area))
    row, col = d.cell_of(pts)
    assert np.all(free[row, col])
    assert np.isneginf(d.logpdf([[5.0, 5.0]]))[0]  # inside the pillar


def test_samples_follow_the_cell_masses():
    free = courtyard()
    rng = np.random.default_rng(1)
    d = fit_position_density(door_points(rng, 300), free, RES, ORIGIN)
    assert d.prob.sum() == pytest.approx(1.0) and np.all(d.prob[~free] == 0)
    pts = d.sample(rng, 20000)
    row, col = d.cell_of(pts)
    # chi-square on 4 x 6 blocks of cells (alpha = 1e-4)
    blocks = (row // 10) * 6 + col // 10
    obs = np.bincount(blocks, minlength=24)
    exp = d.prob.reshape(4, 10, 6, 10).sum(axis=(1, 3)).ravel() * pts.shape[0]
    keep = exp > 5
    chi = np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep])
    assert stats.chi2(keep.sum() - 1).sf(chi) > 1e-4


def test_learned_density_recovers_door_entries():
    free = courtyard()
    rng = np.random.default_rng(2)
    d = fit_position_density(door_points(rng, 400), free, RES, ORIGIN)
    fresh = door_points(rng, 2000)
    uni = uniform_position_density(free, RES, ORIGIN)
    gain = np.mean(d.logpdf(fresh) - uni.logpdf(fresh))
    assert gain > 1.0  # nats per point on held-out entries
    # entries within 1 m of the boundary: truth about 0.87, uniform about 0.2
    near = lambda p: np.mean(boundary_distance(p, free, RES, ORIGIN) <= 1.0)  # noqa: E731
    truth, model, paper = near(fresh), near(d.sample(rng, 4000)), near(uni.sample(rng, 4000))
    assert abs(model - truth) < 0.1 and paper < 0.35  # kernel smoothing bias < 0.1


def test_learned_density_does_not_overfit_uniform_entries():
    free = courtyard()
    rng = np.random.default_rng(3)
    uni = uniform_position_density(free, RES, ORIGIN)
    d = fit_position_density(uni.sample(rng, 300), free, RES, ORIGIN)
    fresh = uni.sample(rng, 4000)
    loss = np.mean(uni.logpdf(fresh) - d.logpdf(fresh))
    assert loss < 0.1  # nats per point lost against the truth
    assert d.bandwidth >= 4 * RES  # LOO chose a wide kernel


def test_points_on_walls_are_snapped_to_free_cells():
    free = courtyard()
    pts = np.array([[5.0, 5.0]] * 20 + [[100.0, 100.0]] * 20)  # pillar centre, off the map
    d = fit_position_density(pts, free, RES, ORIGIN)
    assert d.prob.sum() == pytest.approx(1.0) and np.all(d.prob[~free] == 0)
    # mass moved to the free cells nearest the pillar's centre and nearest (100, 100)
    corner = d.prob[35:, 55:].sum()
    pillar_edge = d.prob[13:27, 23:37].sum()
    assert corner > 0.2 and pillar_edge > 0.2


def test_boundary_distance_matches_brute_force():
    free = courtyard()
    rng = np.random.default_rng(4)
    pts = uniform_position_density(free, RES, ORIGIN).sample(rng, 200)
    got = boundary_distance(pts, free, RES, ORIGIN)
    padded = np.pad(free, 1, constant_values=False)
    wall = np.argwhere(~padded)
    row, col = uniform_position_density(free, RES, ORIGIN).cell_of(pts)
    ref = [
        np.min(np.hypot(*(wall - [r + 1, c + 1]).T)) * RES for r, c in zip(row, col, strict=True)
    ]
    np.testing.assert_allclose(got, ref)
