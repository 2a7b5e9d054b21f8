"""Planners: A* against scipy's Dijkstra on the same graph, OMPL paths valid and seeded."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse import csgraph

from are_stats.experiments import (
    AStarPlanner,
    OMPLPlanner,
    astar_cells,
    make_planner,
    path_length,
    timed_plan,
)
from tests.helpers import assert_allclose


def _dijkstra_length(free: np.ndarray, s: tuple[int, int], g: tuple[int, int]) -> float:
    """Independent reference: 8-connected grid graph without corner cutting, scipy Dijkstra."""
    h, w = free.shape
    rows, cols, vals = [], [], []
    for r in range(h):
        for c in range(w):
            if not free[r, c]:
                continue
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if (dr, dc) == (0, 0) or not (0 <= rr < h and 0 <= cc < w):
                        continue
                    if not free[rr, cc]:
                        continue
                    if dr and dc and not (free[r, cc] and free[rr, c]):
                        continue
                    rows.append(r * w + c)
                    cols.append(rr * w + cc)
                    vals.append(math.hypot(dr, dc))
    m = sparse.csr_matrix((vals, (rows, cols)), shape=(h * w, h * w))
    d = csgraph.dijkstra(m, indices=s[0] * w + s[1])
    return float(d[g[0] * w + g[1]])


@pytest.mark.parametrize("seed", range(6))
def test_astar_is_shortest(seed):
    rng = np.random.default_rng(seed)
    free = rng.random((25, 30)) > 0.3
    cells = np.argwhere(free)
    s, g = (tuple(int(v) for v in cells[k]) for k in rng.choice(len(cells), 2, replace=False))
    ref = _dijkstra_length(free, s, g)
    path = astar_cells(free, s, g)
    if not np.isfinite(ref):
        assert path is None
        return
    assert tuple(path[0]) == s and tuple(path[-1]) == g
    assert free[path[:, 0], path[:, 1]].all()
    assert np.abs(np.diff(path, axis=0)).max() <= 1
    assert_allclose(np.linalg.norm(np.diff(path, axis=0), axis=1).sum(), ref, rtol=1e-12)


def _segments_free(free, path, res):
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = int(np.ceil(np.linalg.norm(b - a) / (0.25 * res))) + 1
        pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
        ij = np.floor(pts[:, ::-1] / res).astype(int)
        if not free[ij[:, 0], ij[:, 1]].all():
            return False
    return True


WALL = np.ones((60, 60), bool)
WALL[25:35, :45] = False  # a wall with a gap on the right


@pytest.mark.parametrize(
    "planner",
    [
        AStarPlanner(),
        OMPLPlanner("RRT", range=1.0, goal_bias=0.1, max_iterations=20000),
        OMPLPlanner("RRTConnect", range=1.0),
        OMPLPlanner("RRTstar", range=1.0, goal_bias=0.05, max_iterations=3000),
        OMPLPlanner("PRM", time_limit=0.3),
    ],
    ids=["astar", "rrt", "rrtconnect", "rrtstar", "prm"],
)
def test_paths_are_valid(planner):
    start, goal = np.array([0.5, 0.5]), np.array([0.5, 5.5])
    path, dt = timed_plan(planner, WALL, start, goal, {"resolution": 0.1, "seed": 7})
    assert path is not None and dt >= 0
    assert_allclose(path[0], start)
    assert_allclose(path[-1], goal)
    if isinstance(planner, AStarPlanner):
        assert _segments_free(WALL, path, 0.1)
    else:  # sampled motion checks may clip a corner by less than one check step
        from scipy import ndimage

        core = ndimage.binary_erosion(~WALL, border_value=1)
        assert _segments_free(~core, path, 0.1)
    # must go round the wall: longer than the straight line through it
    assert path_length(path) > 2 * 4.0


def test_ompl_seeded_is_reproducible():
    pl = OMPLPlanner("RRTstar", range=1.0, goal_bias=0.05, max_iterations=500)
    args = (WALL, np.array([0.5, 0.5]), np.array([0.5, 5.5]))
    a = pl(*args, {"resolution": 0.1, "seed": 3})
    b = pl(*args, {"resolution": 0.1, "seed": 3})
    c = pl(*args, {"resolution": 0.1, "seed": 4})
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_unreachable_goal_gives_none():
    free = np.ones((30, 30), bool)
    free[14:16, :] = False
    args = (free, np.array([0.5, 0.5]), np.array([0.5, 2.5]), {"resolution": 0.1, "seed": 1})
    assert AStarPlanner()(*args) is None
    assert OMPLPlanner("RRTConnect", time_limit=0.1)(*args) is None
    blocked = (free, np.array([0.5, 0.5]), np.array([0.5, 1.45]), {"resolution": 0.1})
    assert AStarPlanner()(*blocked) is None


def test_plugin_planner_and_bad_output():
    free = np.ones((10, 10), bool)

    def straight(free, start, goal, params):
        return np.vstack([start, goal])

    path, _ = timed_plan(straight, free, [0.5, 0.5], [5.0, 5.0], {"resolution": 1.0})
    assert path.shape == (2, 2)
    assert make_planner(straight) is straight
    with pytest.raises(ValueError, match="planner"):
        timed_plan(lambda *a: np.zeros((3, 3)), free, [0.5, 0.5], [5.0, 5.0], {})


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"algorithm": "Dijkstra"}, "algorithm"),
        ({"algorithm": "RRT", "goal_bias": 1.5}, "goal_bias"),
        ({"algorithm": "PRM", "range": 1.0}, "range"),
        ({"algorithm": "RRTConnect", "goal_bias": 0.1}, "goal_bias"),
        ({"algorithm": "RRT", "range": -1.0}, "range"),
        ({"algorithm": "RRT", "max_iterations": 0}, "max_iterations"),
        ({"algorithm": "RRT", "speed": 1}, "unknown option"),
        ({"algorithm": "astar", "range": 1.0}, "astar"),
    ],
)
def test_bad_planner_specs(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_planner(kwargs)


def test_bad_free_mask_and_resolution():
    with pytest.raises(ValueError, match="free"):
        AStarPlanner()(np.ones((3, 3)), np.zeros(2), np.ones(2), {"resolution": 1.0})
    with pytest.raises(ValueError, match="resolution"):
        AStarPlanner()(np.ones((3, 3), bool), np.zeros(2), np.ones(2), {})


def _ompl_space(free: np.ndarray, res: float, motion_resolution: float = 0.25):
    """OMPL's space information over ``free`` as :class:`OMPLPlanner` sets it up, with its
    default (discrete) motion validator over a per-state validity checker."""
    from ompl import base as ob
    from ompl import geometric as og

    h, w = free.shape
    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    bounds.setLow(0, 0.0)
    bounds.setHigh(0, w * res)
    bounds.setLow(1, 0.0)
    bounds.setHigh(1, h * res)
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)

    inv = 1.0 / res  # the planner's per-state check

    def valid(state):
        i, j = int(state[1] * inv), int(state[0] * inv)
        return 0 <= i < h and 0 <= j < w and bool(free[i, j])

    setup.setStateValidityChecker(valid)
    si = setup.getSpaceInformation()
    si.setStateValidityCheckingResolution(min(1.0, motion_resolution / math.hypot(h, w)))
    si.setup()
    return setup, space, si


@pytest.mark.parametrize("seed", range(3))
def test_grid_motion_validator_agrees_with_ompls_discrete_one(seed):
    """OMPLPlanner's NumPy motion check answers as OMPL's DiscreteMotionValidator over the
    per-state check, on random motions (cell-aligned end points, zero length and motions
    leaving the grid included)."""
    from are_stats.experiments._planners import _grid_motion_validator

    rng = np.random.default_rng(seed)
    res = 0.1
    free = rng.random((40, 50)) > 0.15
    setup, space, si = _ompl_space(free, res)
    mv = _grid_motion_validator()(si, space, free, 1.0 / res)
    a, b = space.allocState(), space.allocState()
    top = np.array([50 * res, 40 * res])
    n, agree, n_valid = 4000, 0, 0
    for k in range(n):
        p = rng.uniform(0.0, top)
        q = p + 10.0 ** rng.uniform(-3.0, 0.5) * rng.normal(size=2)
        if k % 4 == 1:  # on cell edges and corners
            p, q = np.round(p / res) * res, np.round(q / res) * res
        elif k % 4 == 2:
            q = p.copy()
        q = np.clip(q, 0.0, top)
        a[0], a[1] = float(p[0]), float(p[1])
        b[0], b[1] = float(q[0]), float(q[1])
        ref = si.checkMotion(a, b)
        n_valid += ref
        agree += mv.checkMotion(a, b) == ref
    assert agree == n
    assert 0.2 * n < n_valid < 0.8 * n  # both answers are exercised


def _blocks(rng: np.random.Generator) -> np.ndarray:
    free = np.ones((80, 100), bool)
    for _ in range(25):
        r, c = rng.integers(0, 80), rng.integers(0, 100)
        free[r : r + rng.integers(2, 15), c : c + rng.integers(2, 15)] = False
    return free


@pytest.mark.parametrize("algorithm", ["RRTConnect", "RRT"])
def test_ompl_plans_as_with_ompls_motion_validator(algorithm, monkeypatch):
    """The same seeded plans as with OMPL's own motion validator over the per-state check
    (RRT* is left out: OMPL's RRT* does not repeat its own plans exactly)."""
    import are_stats.experiments._planners as planners

    rng = np.random.default_rng(5)
    kw = {"range": 1.0, "max_iterations": 2000}
    if algorithm == "RRT":
        kw["goal_bias"] = 0.05
    plan = OMPLPlanner(algorithm, **kw)
    ours = planners._grid_motion_validator
    theirs = lambda: lambda si, space, free, inv: si.getMotionValidator()  # noqa: E731
    found = 0
    for k in range(12):
        free = _blocks(rng)
        cells = np.argwhere(free)
        s, g = cells[rng.choice(len(cells), 2, replace=False)]
        args = (free, (s[::-1] + 0.5) * 0.1, (g[::-1] + 0.5) * 0.1, {"resolution": 0.1, "seed": k})
        monkeypatch.setattr(planners, "_grid_motion_validator", ours)
        a = plan(*args)
        monkeypatch.setattr(planners, "_grid_motion_validator", theirs)
        b = plan(*args)
        assert (a is None) == (b is None)
        if a is not None:
            found += 1
            assert np.array_equal(a, b)
    assert found >= 8


def test_ompl_goal_outside_the_starts_part_is_refused_unsearched(monkeypatch):
    """A goal outside the start's 8-connected free cells is answered without a search (no
    OMPL path can reach it); one joined to it only through a diagonal step is searched."""
    import ompl.geometric as og

    free = np.ones((30, 30), bool)
    free[14:16, :] = False
    args = (free, np.array([0.5, 0.5]), np.array([0.5, 2.5]), {"resolution": 0.1, "seed": 1})
    plan = OMPLPlanner("RRTConnect", max_iterations=10**9, time_limit=3600.0)

    class NoSearch:
        def __init__(self, *a):
            raise AssertionError("searched")

    monkeypatch.setattr(og, "SimpleSetup", NoSearch)
    assert plan(*args) is None
    monkeypatch.undo()
    free[14:16, 10] = True  # a door: a plan
    assert plan(*args) is not None
    # a wall of cells that touch at their corners only: 8-connected, so searched (and a
    # motion check's steps may slip through a corner)
    diag = np.ones((30, 30), bool)
    diag[np.arange(30), np.arange(30)] = False
    monkeypatch.setattr(og, "SimpleSetup", NoSearch)
    with pytest.raises(AssertionError, match="searched"):
        plan(diag, np.array([0.25, 2.5]), np.array([2.5, 0.25]), {"resolution": 0.1})
