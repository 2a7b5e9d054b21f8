"""Continuous motion between the MDP's decisions (issue 26).

Straight any-angle paths, per-person preferred speeds, tracks that stay on free cells, and
catalogue walkers that keep walking while alive. Statistical checks are k-sigma checks
with k = 4 (false-failure rate about 6e-5 for a random seed; the seeds are fixed).
"""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import (
    BehaviourFit,
    GridMDP,
    behaviour_tracks,
    continuous_paths,
    line_of_sight,
    preferred_speeds,
    rollout,
    simulate_behaviour_tracks,
    string_pull,
    string_pull_many,
    walk_times,
    walk_times_many,
    walk_tracks,
)
from are_stats.behaviour._motion import (
    _blocked_table,
    _box_clear,
    _crossed,
    _crossed_block,
    _sight,
)
from are_stats.environment import OccupancyGrid, load_catalogue, shipped_path

K_SIGMA = 4.0


def _straightness(xy: np.ndarray) -> float:
    length = np.hypot(*np.diff(xy, axis=0).T).sum()
    return float(np.hypot(*(xy[-1] - xy[0])) / length)


def _room(h: int = 20, w: int = 30) -> np.ndarray:
    """Occupied cells of an open room: walls all round."""
    occ = np.zeros((h, w), bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    return occ


def _on_free_cells(xy: np.ndarray, free: np.ndarray, origin=(0.0, 0.0), cell=1.0) -> bool:
    """Every segment between consecutive track points crosses free cells only."""
    rc = np.column_stack([(xy[:, 1] - origin[1]) / cell, (xy[:, 0] - origin[0]) / cell])
    return all(line_of_sight(free, a, b, 0.0) for a, b in zip(rc[:-1], rc[1:], strict=True))


def test_line_of_sight_against_dense_sampling() -> None:
    rng = np.random.default_rng(0)
    for _ in range(400):
        free = rng.random((7, 7)) > 0.25
        a, b = rng.uniform(0, 7, 2), rng.uniform(0, 7, 2)
        t = np.linspace(0.0, 1.0, 20001)
        cells = np.floor(a + t[:, None] * (b - a)).astype(int)
        expected = bool(free[cells[:, 0], cells[:, 1]].all())
        assert line_of_sight(free, a, b, 0.0) == expected
    free = np.ones((5, 5), bool)
    free[2, 2] = False
    # a segment through the corner of an occupied cell keeps its clearance off it
    assert line_of_sight(free, [1.5, 0.5], [2.0, 4.5], 0.0)
    assert not line_of_sight(free, [1.5, 0.5], [2.0, 4.5], 0.2)


def test_mdp_routes_across_an_open_room_become_straight() -> None:
    """Routes of the paper's MDP (slip 0.1) across an open room zig-zag along grid cells;
    string-pulled, each crossing is one straight segment (straightness > 0.95)."""
    occ = _room()
    mdp = GridMDP(occ, slip=0.1)
    rng = np.random.default_rng(3)
    n = 16
    starts = np.column_stack([rng.integers(2, 18, n), np.full(n, 2), np.zeros(n, int)])
    goals = np.column_stack([rng.integers(2, 18, n), np.full(n, 27)])
    sol = mdp.solve(goals, "walk", 80)
    states = rollout(jax.random.key(1), sol, starts, resolve=None)
    raw, pulled = [], []
    for i in range(n):
        st = states[i]
        end = int(np.flatnonzero((st[:, :2] == goals[i]).all(axis=1))[0])
        xy = st[: end + 1, ::-1][:, 1:] + 0.5  # (x, y) = (col, row) + 0.5
        raw.append(_straightness(xy))
        path = string_pull(xy, ~occ)
        pulled.append(_straightness(path))
        assert _on_free_cells(path, ~occ)
        assert np.allclose(path[0], xy[0]) and np.allclose(path[-1], xy[-1])
    assert np.median(raw) < 0.95  # the grid routes themselves are not straight
    assert min(pulled) > 0.95, pulled


def test_pulled_paths_round_walls_stay_on_free_cells() -> None:
    occ = _room(20, 20)
    occ[10, 1:15] = True  # a wall with a gap at its east end
    mdp = GridMDP(occ, slip=0.1)
    sol = mdp.solve([[17, 3]] * 8, "walk", 120)
    starts = np.tile([3, 3, 0], (8, 1))
    states = rollout(jax.random.key(4), sol, starts, resolve=None)
    for st in states:
        end = int(np.flatnonzero((st[:, :2] == [17, 3]).all(axis=1))[0])
        xy = st[: end + 1, ::-1][:, 1:] + 0.5
        path = string_pull(xy, ~occ)
        assert _on_free_cells(path, ~occ)
        assert 3 <= len(path) <= 6  # round the wall's end: a few corners, no zig-zag


def _pull_by_definition(points, free, origin, cell, clearance) -> np.ndarray:
    """The string pull as defined, one sight test at a time: from each kept vertex, extend
    to the next route point while it is in sight (:func:`line_of_sight`)."""
    p = np.asarray(points, float)
    p = p[np.concatenate([[True], (np.diff(p, axis=0) != 0).any(axis=1)])]
    rc = np.column_stack([(p[:, 1] - origin[1]) / cell, (p[:, 0] - origin[0]) / cell])
    keep, a = [0], 0
    while a < len(p) - 1:
        j = a + 1
        while j + 1 < len(p) and line_of_sight(free, rc[a], rc[j + 1], clearance):
            j += 1
        keep.append(j)
        a = j
    return p[keep]


def _random_routes(rng, free, n_routes, origin, cell) -> list[np.ndarray]:
    """4-connected random walks over free cells (with repeats, some longer than a sight
    window) from a point inside the first cell, ending off-centre in the last one."""
    cells = np.argwhere(free)
    routes = []
    for _ in range(n_routes):
        r, c = cells[rng.integers(len(cells))]
        path = [(r, c)]
        for _ in range(int(rng.integers(1, 160))):
            dr, dc = [(0, 1), (1, 0), (0, -1), (-1, 0), (0, 0)][rng.integers(5)]
            if 0 <= r + dr < free.shape[0] and 0 <= c + dc < free.shape[1] and free[r + dr, c + dc]:
                r, c = r + dr, c + dc
            path.append((r, c))
        rc = np.asarray(path, float) + 0.5
        rc[0] += rng.uniform(-0.45, 0.45, 2)
        rc[-1] += rng.uniform(-0.45, 0.45, 2)
        routes.append(np.column_stack([origin[0] + rc[:, 1] * cell, origin[1] + rc[:, 0] * cell]))
    return routes


def test_many_routes_pulled_at_once_are_each_pulled_by_definition() -> None:
    """The lockstep string pull keeps exactly the vertices of the definition, route by
    route, on cluttered maps, with a shared grid and with one grid per route.
    50 routes a map (100 before 2026-11-29: the definition's sight tests one at a time were
    most of the test's 16 s): a pull with the clearance off by 0.05 cells differs from the
    definition on 9 to 25 of each map's 50 routes, one missing its last point on all."""
    rng = np.random.default_rng(7)
    origin, cell = (-3.0, 2.0), 0.5
    for _ in range(2):
        free = rng.random((18, 26)) > 0.2
        free[8:10, :] = True  # a corridor, so that some routes see far
        routes = _random_routes(rng, free, 50, origin, cell)
        for clearance in (0.0, 0.2):
            got = string_pull_many(routes, free, origin, cell, clearance)
            for route, path in zip(routes, got, strict=True):
                want = _pull_by_definition(route, free, origin, cell, clearance)
                np.testing.assert_array_equal(path, want)
        # one grid per route: each route's own cells and their neighbours
        grids = np.zeros((len(routes), *free.shape), bool)
        for g, route in zip(grids, routes, strict=True):
            col = np.floor((route[:, 0] - origin[0]) / cell).astype(int)
            row = np.floor((route[:, 1] - origin[1]) / cell).astype(int)
            g[row, col] = True
            g[:] = g | np.roll(g, 1, 0) | np.roll(g, -1, 1)
            g &= free
        got = string_pull_many(routes, grids, origin, cell, 0.2)
        for route, g, path in zip(routes, grids, got, strict=True):
            np.testing.assert_array_equal(path, _pull_by_definition(route, g, origin, cell, 0.2))


def test_preferred_speeds_between_person_sd_is_the_configured_one() -> None:
    """``log v ~ N(log median, sd^2)``: the sample sd of n draws has standard error
    ``sd / sqrt(2 (n - 1))``, the sample mean ``sd / sqrt(n)``."""
    n, sd = 4000, 0.12
    v = preferred_speeds(jax.random.key(0), np.full(n, 1.2), sd)
    lv = np.log(v)
    assert abs(lv.std(ddof=1) - sd) < K_SIGMA * sd / np.sqrt(2 * (n - 1))
    assert abs(lv.mean() - np.log(1.2)) < K_SIGMA * sd / np.sqrt(n)
    with pytest.raises(ValueError, match="median"):
        preferred_speeds(jax.random.key(0), [1.0, 0.0], sd)


def test_preferred_speeds_are_the_draw_of_their_own_shape() -> None:
    """The normals come from a bucket's longer draw (one program for many sizes): its
    prefix is exactly the draw of the asked shape, for typed and raw keys, at sizes below,
    at and past the bucket (a longer draw would otherwise shift every speed)."""
    med = 1.3
    for key in (jax.random.key(5), jax.random.fold_in(jax.random.key(1), 3), jax.random.PRNGKey(2)):
        for n in (0, 1, 302, 16384, 16385):
            z = np.asarray(jax.random.normal(key, (n,), dtype=np.float32), float)
            np.testing.assert_array_equal(
                preferred_speeds(key, np.full(n, med), 0.2), med * np.exp(0.2 * z)
            )


def _walkers(n: int, occ: np.ndarray, stay: float, behaviour="walk", speed=1.2, seed=0):
    rng = np.random.default_rng(seed)
    free = np.argwhere(~occ)
    cells = free[rng.choice(len(free), n, replace=False)]
    return pd.DataFrame({
        "scenario": 0, "id": np.arange(n), "t_arrive": rng.uniform(0, 20, n),
        "t_leave": 0.0, "x": cells[:, 1] + 0.5, "y": cells[:, 0] + 0.5, "yaw": 0.0,
        "behaviour": behaviour, "speed": speed,
    }).assign(t_leave=lambda d: d["t_arrive"] + stay)  # fmt: skip


def test_walkers_walk_at_their_own_preferred_speed() -> None:
    """Measured on the tracks (path length over moving time, within-person variation off),
    the between-person sd of the log speed is the configured 0.12 (4-sigma, closed form)."""
    occ = _room(30, 30)
    n, sd = 160, 0.12
    arts = _walkers(n, occ, 40.0)
    tracks = walk_tracks(jax.random.key(2), arts, occ, dt=0.5, speed_sd=sd, within_sd=0.0)
    speeds = []
    for _, g in tracks.groupby("id"):
        xy, t = g[["x", "y"]].to_numpy(), g["t"].to_numpy()
        step = np.hypot(*np.diff(xy, axis=0).T)
        moving = step > 1e-9
        speeds.append(step[moving].sum() / np.diff(t)[moving].sum())
    lv = np.log(speeds)
    assert abs(lv.std(ddof=1) - sd) < K_SIGMA * sd / np.sqrt(2 * (n - 1)), lv.std(ddof=1)
    assert abs(lv.mean() - np.log(1.2)) < K_SIGMA * sd / np.sqrt(n)


def test_walkers_plan_alone_and_never_hold_for_each_other() -> None:
    """Thirty walkers crossing a 10 x 10 m room (issue 26): nobody stands on the way to
    keep its distance (people give way while walking, under the social force of the one
    assembly, not by holding on their plans): every walker's track moves at every sample
    until it stands for good, if ever (no reachable goal left in its stay)."""
    occ = _room(10, 10)
    arts = _walkers(30, occ, 60.0, seed=3)
    tracks = walk_tracks(jax.random.key(7), arts, occ, dt=0.5)
    assert "holds" not in tracks.attrs
    for i, g in tracks.groupby("id"):
        step = np.hypot(*np.diff(g[["x", "y"]].to_numpy(), axis=0).T)
        still = step < 1e-9
        assert not still.any() or still[int(np.argmax(still)) :].all(), i


def test_walkers_keep_walking_while_alive_and_stay_on_free_cells() -> None:
    """Goals within reach of the rest of the stay and a new one on arrival: every walker
    moves in every minute of a five-minute stay, on free cells only; a stop stands."""
    occ = _room(20, 30)
    occ[10, 1:22] = True  # an inner wall
    arts = _walkers(8, occ, 300.0, seed=1)
    arts.loc[7, "behaviour"] = "stop"
    tracks = walk_tracks(jax.random.key(5), arts, occ, dt=2.0)
    assert list(tracks.columns) == ["scenario", "id", "t", "x", "y", "yaw"]
    for i, g in tracks.groupby("id"):
        xy, t = g[["x", "y"]].to_numpy(), g["t"].to_numpy()
        assert t[0] == pytest.approx(arts["t_arrive"][i]) and t[-1] == pytest.approx(
            arts["t_leave"][i]
        )
        if i == 7:
            assert (xy == xy[0]).all()
            continue
        assert _on_free_cells(xy, ~occ)
        for a in np.arange(t[0], t[-1] - 60.0, 60.0):
            p0 = [np.interp(a, t, xy[:, 0]), np.interp(a, t, xy[:, 1])]
            p1 = [np.interp(a + 60, t, xy[:, 0]), np.interp(a + 60, t, xy[:, 1])]
            assert np.hypot(p1[0] - p0[0], p1[1] - p0[1]) > 0.5, (i, a)


def test_catalogue_people_walk_in_the_courtyard_and_pallets_stand() -> None:
    """The issue's target, with the shipped catalogue and map: most person and child
    artefacts alive over a minute move more than 0.5 m in the middle minute of their stay
    (all whose mark gives walk, run or follow); pallets never move."""
    cat = load_catalogue()
    grid = OccupancyGrid.from_ros_yaml(shipped_path("courtyard", "map"))
    labels = [c.label for c in cat.classes]
    rng = np.random.default_rng(7)
    n = 24
    cls = np.array([labels.index(c) for c in ["person", "child", "pallet"] * (n // 3)])
    free = np.argwhere(grid.free)
    cells = free[rng.choice(len(free), n, replace=False)]
    xy = np.asarray(grid.cell_to_world(cells), float)
    t_arr = rng.uniform(0, 60, n)
    arts = pd.DataFrame({
        "scenario": 0, "artefact": np.arange(n), "mark": rng.integers(0, 40, n),
        "t_arrive": t_arr, "t_leave": t_arr + rng.uniform(90, 300, n), "x": xy[:, 0],
        "y": xy[:, 1], "yaw": 0.0,
    })  # fmt: skip
    tracks = behaviour_tracks(jax.random.key(3), arts, cls, grid, cat, cell=1.0, dt=2.0)
    from are_stats.behaviour import choose_behaviours

    beh = choose_behaviours(cls, arts["mark"], cat)
    moved = {}
    for i, g in tracks.groupby("id"):
        t, x, y = g["t"].to_numpy(), g["x"].to_numpy(), g["y"].to_numpy()
        mid = 0.5 * (t[0] + t[-1])
        d = np.hypot(*(np.interp([mid + 30], t, x) - np.interp([mid - 30], t, x)),
                     *(np.interp([mid + 30], t, y) - np.interp([mid - 30], t, y)))  # fmt: skip
        moved[i] = bool(d > 0.5)
        if labels[cls[i]] == "pallet":
            assert (x == x[0]).all() and (y == y[0]).all()
    people = [i for i in range(n) if labels[cls[i]] in ("person", "child")]
    goers = [i for i in people if beh[i] != "stop"]
    assert np.mean([moved[i] for i in people]) > 0.5
    assert all(moved[i] for i in goers), [(i, beh[i]) for i in goers if not moved[i]]


def _open_fit(speed_sigma: float = 0.12) -> BehaviourFit:
    """A hand-made behaviour on a 12 x 24 room (cell 1 m): people cross from the west wall
    to the east wall at a median 1.2 m/s."""
    occ = _room(12, 24)
    rows = np.arange(2, 10)
    entry = np.column_stack([np.full(rows.size, 1.5), rows + 0.5])
    exit_ = np.column_stack([np.full(rows.size, 22.5), (11 - rows) + 0.5])
    one = np.ones(1)
    return BehaviourFit(
        classes=("person",), cell=1.0, origin=np.zeros(2), free=~occ, dt=one / 1.2,
        speed_mu=np.log(1.2) * one, speed_sigma=speed_sigma * one, run_fraction=0 * one,
        run_mu=np.nan * one, run_sigma=np.nan * one, beta=4.0 * one, beta_se=0 * one,
        slip=0.1 * one, slip_se=0 * one, loglik=0 * one, n_moves=one.astype(int),
        n_tracks=one.astype(int) * rows.size, n_fit_tracks=one.astype(int),
        n_epochs=200 * one.astype(int), bandwidth_entry=0.3 * one, bandwidth_exit=0.1 * one,
        fit_seconds=0 * one, track_class=np.zeros(rows.size, int), entry_xy=entry,
        exit_xy=exit_,
    )  # fmt: skip


def test_fitted_walkers_cross_an_open_room_straight_at_their_own_speed() -> None:
    """Entries on the west wall, each with its own exit on the east wall (kernels narrow),
    stays of people walking at lognormal speeds (median 1.2, sd of the log 0.12): the
    crossings are straight, and each person's one speed recovers that law."""
    fit = _open_fit()
    n = 40
    rng = np.random.default_rng(1)
    row = rng.integers(2, 10, n)
    y0, y1 = row + 0.5, (11 - row) + 0.5  # the exit of the entry track on that row
    v = 1.2 * np.exp(0.12 * rng.standard_normal(n))
    arts = pd.DataFrame({
        "scenario": np.arange(n), "id": 0, "t_arrive": 0.0,
        "t_leave": np.hypot(21.0, y1 - y0) / v, "x": 1.5, "y": y0,
    })  # fmt: skip
    out = simulate_behaviour_tracks(jax.random.key(0), fit, arts, dt_out=0.4)
    straight, speeds = [], []
    for _, g in out.groupby("scenario"):
        xy, t = g[["x", "y"]].to_numpy(), g["t"].to_numpy()
        step = np.hypot(*np.diff(xy, axis=0).T)
        moving = np.flatnonzero(step > 1e-9)
        straight.append(_straightness(xy[moving[0] : moving[-1] + 2]))
        speeds.append(step[moving].sum() / np.diff(t)[moving].sum())
        assert _on_free_cells(xy, fit.free)
    assert np.median(straight) > 0.95, np.median(straight)
    # one speed per person (clipped at 2 sd of the law: sd 0.96 of the law's)
    lv = np.log(speeds)
    assert abs(np.median(speeds) / 1.2 - 1) < 0.1
    sd = 0.96 * 0.12
    assert abs(lv.std(ddof=1) - sd) < K_SIGMA * sd / np.sqrt(2 * (n - 1)), lv.std(ddof=1)


def test_starts_snap_to_coarse_cells_whose_centre_is_free() -> None:
    """A coarse behaviour cell that is mostly free can have a wall at its centre; an artefact
    placed there starts at the nearest coarse cell whose centre is a free map cell (the
    social force never walks out of a wall, so such a start stood its whole stay)."""
    data = np.zeros((60, 60))  # 6 x 6 m at 0.1 m: coarse cells of 1 m hold 10 x 10 map cells
    data[13:18, 13:18] = 100.0  # a pillar at the centre of coarse cell (1, 1): 25 of 100
    grid = OccupancyGrid(data, 0.1)
    cat = load_catalogue()
    person = [c.label for c in cat.classes].index("person")
    arts = pd.DataFrame({
        "scenario": 0, "artefact": [0], "mark": [0], "t_arrive": [0.0], "t_leave": [60.0],
        "x": [1.5], "y": [1.5], "yaw": [0.0],
    })  # fmt: skip
    tracks = behaviour_tracks(jax.random.key(0), arts, np.array([person]), grid, cat, cell=1.0)
    x0, y0 = tracks[["x", "y"]].to_numpy()[0]
    assert grid.free[int(y0 // 0.1), int(x0 // 0.1)]
    assert np.hypot(x0 - 1.5, y0 - 1.5) == pytest.approx(1.0)  # a neighbouring cell's centre


def test_continuous_paths_of_many_are_those_one_at_a_time_by_definition() -> None:
    """Many artefacts' paths at once: each the route pulled by definition (on the free
    cells, or within one cell of its route with fitted cell rewards), timed in order from
    one generator (so the within-person speeds are drawn as one path after another)."""
    import dataclasses

    from scipy import ndimage

    base = _open_fit()
    free = base.free.copy()
    free[4:8, 8:10] = False  # a pillar to walk round
    rng = np.random.default_rng(11)
    routes = _random_routes(rng, free, 120, (0.0, 0.0), 1.0)
    paths, starts, ends = [], [], []
    for r in routes:
        cells = np.floor(r[:, ::-1]).astype(int)
        states = np.column_stack([cells, np.zeros(len(cells), int)])
        pad = int(rng.integers(0, 4))  # ended early: -1 actions, the last state repeated
        states = np.concatenate([states, np.repeat(states[-1:], pad, 0)])
        actions = np.concatenate([np.zeros(len(cells) - 1, int), np.full(pad, -1)])
        paths.append((states, actions))
        starts.append(r[0])
        ends.append(r[-1] if rng.random() < 0.5 else None)
    speeds = rng.uniform(0.6, 1.8, len(paths))
    walls = np.asarray(~free, float)[None]
    weighted = dataclasses.replace(
        base, free=free, feature_names=("walls",), features=walls, weights=np.ones((1, 1)),
        weights_se=np.zeros((1, 1)),
    )  # fmt: skip
    for fit in (dataclasses.replace(base, free=free), weighted):
        got = continuous_paths(
            paths, fit, speeds, np.asarray(starts), ends, rng=np.random.default_rng(2),
            within_sd=0.1,
        )  # fmt: skip
        ref_rng = np.random.default_rng(2)
        for (states, actions), v, p0, end, (t, xy) in zip(
            paths, speeds, starts, ends, got, strict=True
        ):
            n_act = int((actions >= 0).sum())
            pts = np.concatenate([p0[None], fit.cell_to_world(states[1 : n_act + 1, :2])])
            if end is not None and len(pts) > 1:
                pts[-1] = end
            allowed = free
            if fit is weighted:
                near = np.zeros(free.shape, bool)
                near[states[: n_act + 1, 0], states[: n_act + 1, 1]] = True
                allowed = free & ndimage.binary_dilation(near, np.ones((3, 3), bool))
            want = _pull_by_definition(pts, allowed, (0.0, 0.0), 1.0, 0.2)
            np.testing.assert_array_equal(xy, want)
            np.testing.assert_array_equal(t, walk_times(want, float(v), ref_rng, 0.1))


def test_many_paths_are_timed_as_one_after_another() -> None:
    """walk_times_many: each path's times those of walk_times, path after path from one
    generator, to the bit, and the generator left in the same state; 3,000 paths of 0 to
    40 vertices (repeated vertices among them: zero-length segments), short and long
    segments (correlations from 1 to about 0), with and without within-person variation,
    and the checks of walk_times on a bad speed."""
    r = np.random.default_rng(29)
    paths = []
    for _ in range(3000):
        m = int(r.integers(0, 41))
        p = np.cumsum(r.exponential(r.choice([0.05, 1.0, 20.0]), (m, 2)), axis=0)
        if m > 1:  # a vertex repeated: a zero-length segment
            dup = r.random(m - 1) < 0.1
            p[1:][dup] = p[:-1][dup]
        paths.append(p)
    speeds = r.uniform(0.3, 2.0, len(paths))
    for sd in (0.0, 0.05, 0.3):
        got_rng, want_rng = np.random.default_rng(4), np.random.default_rng(4)
        got = walk_times_many(paths, speeds, got_rng, sd)
        assert len(got) == len(paths)
        for p, v, t in zip(paths, speeds, got, strict=True):
            np.testing.assert_array_equal(t, walk_times(p, float(v), want_rng, sd))
        assert got_rng.bit_generator.state == want_rng.bit_generator.state
    with pytest.raises(ValueError, match="speed"):
        walk_times_many(paths[:3], [1.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="rng"):
        walk_times_many([np.zeros((1, 2)), np.eye(2)], [1.0, 1.0], None, 0.1)
    assert walk_times_many([], []) == []


def test_fitted_planning_reports_each_batch_of_exits(monkeypatch) -> None:
    """``progress(done, total)`` after each chunk of exits solved (a soft solve each), then
    once for the paths: ``done`` counts up to ``total`` = solves + 1, and the tracks are the
    same as without it."""
    from are_stats.behaviour import _model

    fit = _open_fit()
    n = 30
    rng = np.random.default_rng(4)
    row = rng.integers(2, 10, n)
    arts = pd.DataFrame({
        "scenario": np.arange(n) % 3, "id": np.arange(n), "t_arrive": 0.0,
        "t_leave": 40.0, "x": 1.5, "y": row + 0.5,
    })  # fmt: skip
    events = []
    solve = _model.soft_policy  # what BehaviourFit.soft_policy calls

    def counted(*args, **kwargs):
        events.append("solve")
        return solve(*args, **kwargs)

    monkeypatch.setattr(_model, "soft_policy", counted)
    key = jax.random.key(2)
    out = simulate_behaviour_tracks(key, fit, arts, chunk=2, progress=lambda *c: events.append(c))
    solves = events.count("solve")
    assert solves >= 3  # a few chunks of two exits (the exits: up to 8 rows of the east wall)
    total = solves + 1
    assert events == [e for k in range(1, solves + 1) for e in ("solve", (k, total))] + [
        (total, total)
    ]
    pd.testing.assert_frame_equal(out, simulate_behaviour_tracks(key, fit, arts, chunk=2))


def test_arrival_velocities_are_each_tracks_first_planned_move() -> None:
    """The velocity of each track's first move, on every row of the track: tracks keyed by
    (scenario, id) in any order, a track of one row and one whose first move takes no time
    arrive standing."""
    from are_stats.behaviour import arrival_velocities

    tracks = pd.DataFrame({
        "scenario": [0, 0, 1, 0, 0, 1, 2, 2],
        "id": [5, 5, 5, 7, 7, 5, 3, 3],
        "t": [0.0, 0.5, 2.0, 1.0, 3.0, 2.4, 1.0, 1.0],
        "x": [0.0, 0.6, 1.0, 2.0, 2.0, 1.4, 0.0, 9.0],
        "y": [0.0, 0.0, 1.0, 0.0, -1.0, 1.3, 0.0, 0.0],
    })  # fmt: skip
    got = arrival_velocities(tracks)
    want = np.array([[1.2, 0], [1.2, 0], [1.0, 0.75], [0, -0.5], [0, -0.5], [1.0, 0.75],
                     [0, 0], [0, 0]])  # fmt: skip
    np.testing.assert_allclose(got[["vx", "vy"]].to_numpy(), want, atol=1e-12)
    pd.testing.assert_frame_equal(got.drop(columns=["vx", "vy"]), tracks)
    alone = arrival_velocities(pd.DataFrame({"id": [1], "t": [0.0], "x": [1.0], "y": [2.0]}))
    assert alone[["vx", "vy"]].to_numpy().tolist() == [[0.0, 0.0]]


def test_clear_boxes_answer_as_the_traced_cells() -> None:
    """The summed-table shortcut of the segment test (a box of free cells) answers every
    segment as tracing its cells does: on open maps with walls and scattered blocks, with
    segments from and to cell corners and edges (coordinates on the grid lines), along
    rows and columns, off the map, with one grid and with one grid per segment."""
    rng = np.random.default_rng(3)
    shortcut = 0
    for _ in range(6):
        free = ~_room(24, 40)
        free[rng.integers(1, 23, 6), rng.integers(1, 39, 6)] = False
        m = 3000
        p0 = rng.uniform(-1.0, 41.0, (m, 2)) * [24 / 40, 1.0]
        p1 = rng.uniform(-1.0, 41.0, (m, 2)) * [24 / 40, 1.0]
        lines = rng.random((m, 2)) < 0.3  # on grid lines, corners included
        p0 = np.where(lines, np.round(p0), p0)
        p1 = np.where(rng.random((m, 2)) < 0.3, np.round(p1), p1)
        p1[::7, 0] = p0[::7, 0]  # along a row
        p1[1::7, 1] = p0[1::7, 1]  # along a column
        for grids, g in ((free, None), (np.stack([free, free & ~np.eye(24, 40, 3, bool)]),
                                        rng.integers(0, 2, m))):  # fmt: skip
            table = _blocked_table(grids)
            shortcut += int(_box_clear(table, p0, p1, g).sum())
            want = _crossed_block(grids, p0, p1, g)
            np.testing.assert_array_equal(_crossed(grids, p0, p1, g, table), want)
            np.testing.assert_array_equal(_crossed(grids, p0, p1, g), want)
    assert shortcut > 1000  # the shortcut answered many of them


def _sight_three_calls(free, p0, p1, clearance, grid=None):
    """Line of sight as it was tested before the segment and its shifted copies went
    through one :func:`_crossed` call: three calls, and'ed."""
    p0 = np.broadcast_to(np.asarray(p0, float), np.shape(p1))
    ok = _crossed(free, p0, p1, grid)
    if clearance <= 0.0:
        return ok
    d = p1 - p0
    length = np.hypot(d[:, 0], d[:, 1])
    n = np.column_stack([-d[:, 1], d[:, 0]]) / np.where(length > 0, length, 1.0)[:, None]
    n = n * float(clearance)
    n[length == 0] = 0.0
    return ok & _crossed(free, p0 + n, p1 + n, grid) & _crossed(free, p0 - n, p1 - n, grid)


def test_line_of_sight_is_the_three_segment_tests_as_the_mask_changes() -> None:
    """One segment test for a segment and its two shifted copies answers as three did, with
    one grid and one grid per segment; ``line_of_sight`` keeps a grid's summed table
    between calls, and a mask edited in place (the same array) is a new grid."""
    rng = np.random.default_rng(11)
    free = ~_room(16, 22)
    for _ in range(5):
        free[rng.integers(1, 15, 4), rng.integers(1, 21, 4)] ^= True  # in place
        m = 400
        p0 = rng.uniform(-0.5, 22.5, (m, 2)) * [16 / 22, 1.0]
        p1 = rng.uniform(-0.5, 22.5, (m, 2)) * [16 / 22, 1.0]
        p1[::9] = p0[::9]  # zero length
        grids = np.stack([free, free & ~np.eye(16, 22, 2, bool)])
        g = rng.integers(0, 2, m)
        for c in (0.0, 0.2, 0.45):
            want = _sight_three_calls(free, p0, p1, c)
            np.testing.assert_array_equal(_sight(free, p0, p1, c), want)
            got = [line_of_sight(free, a, b, c) for a, b in zip(p0[:60], p1[:60], strict=True)]
            np.testing.assert_array_equal(got, want[:60])
            np.testing.assert_array_equal(
                _sight(grids, p0, p1, c, g), _sight_three_calls(grids, p0, p1, c, g)
            )


def test_walkers_legs_pulled_together_are_the_legs_pulled_alone(monkeypatch) -> None:
    """The legs of a round are string-pulled together (``_pulled_legs``: each route
    foreseen from the rolled-out states, the next leg starting at the previous route's
    end) and walked exactly as when each leg is pulled on its own (issue 29): the same
    tracks, bit for bit; and every walked leg was foreseen (no leg pulled alone)."""
    from are_stats.behaviour import _walk

    occ = _room(20, 30)
    occ[10, 1:22] = True  # an inner wall: corners to keep
    arts = _walkers(12, occ, 240.0, seed=3)
    alone = []

    def counted(*args, **kwargs):
        alone.append(1)
        return string_pull(*args, **kwargs)

    monkeypatch.setattr(_walk, "string_pull", counted)
    together = walk_tracks(jax.random.key(9), arts, occ, dt=2.0)
    assert not alone
    monkeypatch.setattr(_walk, "_pulled_legs", lambda *args: {})  # every leg alone
    one_by_one = walk_tracks(jax.random.key(9), arts, occ, dt=2.0)
    assert alone  # the fallback did the pulling
    pd.testing.assert_frame_equal(together, one_by_one, check_exact=True)
