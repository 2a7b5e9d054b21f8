"""GridMDP against an independent dense NumPy backward induction, properties, bad input."""

from __future__ import annotations

import functools
import weakref

import jax
import numpy as np
import pytest
import scipy.sparse as sp

from are_stats.behaviour import GridMDP, backward_induction, follow_rewards
from are_stats.behaviour._mdp import _BufferPool
from tests.helpers import assert_allclose


def dense_backward_induction(p, r, v_terminal, d):
    """Plain finite-horizon backward induction on dense arrays: V[t] for t = 0 .. d."""
    v = np.asarray(v_terminal, dtype=float)
    out = [v]
    for _ in range(d):
        q = r + np.einsum("asn,n->sa", p, v)
        v = q.max(axis=1)
        out.append(v)
    return np.array(out[::-1])


def random_grid(rng, h, w, density=0.25):
    occ = rng.random((h, w)) < density
    occ[0, 0] = False
    return occ


@pytest.mark.parametrize("seed", range(6))
def test_values_equal_dense_reference(seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(3, 8, size=2)
    occ = random_grid(rng, h, w)
    free = np.argwhere(~occ)
    slip = float(rng.uniform(0, 0.6))
    mdp = GridMDP(
        occ, slip=slip, step_cost=float(rng.uniform(0, 0.1)), goal_reward=1.5, dtype="float64"
    )
    goals = free[rng.choice(len(free), 3)]
    behaviours = ["walk", "run", "stop"]
    horizons = rng.integers(0, 16, size=3)
    sol = mdp.solve(goals, behaviours, horizons)
    d_max = int(horizons.max())
    assert sol.values.shape == (3, d_max + 1, h, w, 4)
    assert sol.policy.shape == (3, d_max, h, w, 4)
    for b in range(3):
        p, r, vt = mdp.to_dense(goals[b], behaviours[b])
        ref = dense_backward_induction(p, r, vt, int(horizons[b]))
        ours = sol.values[b].reshape(d_max + 1, -1)
        assert_allclose(ours[: horizons[b] + 1], ref, rtol=0, atol=1e-9)
        assert_allclose(ours[horizons[b] + 1 :], 0.0, atol=0)
        assert_allclose(sol.v0[b].ravel(), ref[0], rtol=0, atol=1e-9)
        # policy is greedy wherever the best action is decisive
        for t in range(int(horizons[b])):
            q = r + np.einsum("asn,n->sa", p, ref[t + 1])
            top2 = np.sort(q, axis=1)[:, -2:]
            decisive = top2[:, 1] - top2[:, 0] > 1e-9
            pol = sol.policy[b, t].reshape(-1)
            assert np.array_equal(pol[decisive], q.argmax(axis=1)[decisive])


def test_dense_export_hand_computed():
    # 3 x 3 grid, obstacle at (1, 1); state index s = (row * W + col) * 4 + heading
    occ = np.zeros((3, 3), bool)
    occ[1, 1] = True
    mdp = GridMDP(occ, slip=0.2, step_cost=0.0, goal_reward=2.0, dtype="float64")
    p, r, vt = mdp.to_dense((0, 2), "run")

    def s(row, col, h):
        return (row * 3 + col) * 4 + h

    # at (0, 0) heading east: forward -> (0, 1) w.p. 0.8; slip north -> (1, 0) 0.1; south blocked
    row = p[1, s(0, 0, 0)]
    assert row[s(0, 1, 0)] == pytest.approx(0.8)
    assert row[s(1, 0, 0)] == pytest.approx(0.1)
    assert row[s(0, 0, 0)] == pytest.approx(0.1)
    # run east from (0, 0): two cells -> (0, 2) (the goal) w.p. 0.8, north two -> (2, 0)
    row = p[2, s(0, 0, 0)]
    assert row[s(0, 2, 0)] == pytest.approx(0.8)
    assert row[s(2, 0, 0)] == pytest.approx(0.1)
    assert row[s(0, 0, 0)] == pytest.approx(0.1)
    assert r[s(0, 0, 0), 2] == pytest.approx(0.8 * 2.0)
    # run north from (0, 1) is blocked by the obstacle, both sideways runs leave the map
    assert p[2, s(0, 1, 1), s(0, 1, 1)] == pytest.approx(1.0)
    # forward north from (2, 1) is blocked by the obstacle; slips go to (2, 0) and (2, 2)
    assert p[1, s(2, 1, 3), s(2, 1, 3)] == pytest.approx(0.8)
    assert p[1, s(2, 1, 3), s(2, 0, 3)] == pytest.approx(0.1)
    # turns are deterministic, obstacle and goal states absorbing with zero reward
    assert p[3, s(2, 2, 3), s(2, 2, 0)] == 1.0
    assert p[4, s(2, 2, 0), s(2, 2, 3)] == 1.0
    for a in range(5):
        assert p[a, s(1, 1, 2), s(1, 1, 2)] == 1.0
        assert p[a, s(0, 2, 1), s(0, 2, 1)] == 1.0
        assert r[s(0, 2, 1), a] == 0.0
    assert_allclose(p.sum(axis=2), 1.0, rtol=1e-12)
    assert np.all(vt == 0)
    # walk forbids running; stop forbids every move
    assert np.all(mdp.to_dense((0, 2), "walk")[1][:, 2] == -np.inf)
    assert np.all(mdp.to_dense(None, "stop")[1][:, 1:] == -np.inf)


def test_sparse_export_matches_dense():
    rng = np.random.default_rng(3)
    mdp = GridMDP(random_grid(rng, 5, 6), slip=0.3, dtype="float64")
    p, r, _ = mdp.to_dense((0, 0), "run")
    ps, rs, _ = mdp.to_dense((0, 0), "run", sparse=True)
    assert all(isinstance(m, sp.csr_array) for m in ps)
    assert_allclose(np.stack([m.toarray() for m in ps]), p, atol=0)
    assert_allclose(rs, r, atol=0)


def test_float32_close_to_float64():
    rng = np.random.default_rng(4)
    occ = random_grid(rng, 12, 15, 0.2)
    goal = np.argwhere(~occ)[7]
    v64 = GridMDP(occ, dtype="float64").solve(goal, "run", 40).values
    v32 = GridMDP(occ).solve(goal, "run", 40).values
    assert v32.dtype == np.float32
    assert_allclose(v32, v64, rtol=0, atol=1e-5)


def test_values_monotone_in_horizon():
    rng = np.random.default_rng(5)
    occ = random_grid(rng, 10, 12, 0.2)
    goal = np.argwhere(~occ)[-1]
    mdp = GridMDP(occ, slip=0.2, step_cost=0.01, dtype="float64")
    sol = mdp.solve(goal, ["walk"] * 5, [0, 3, 8, 20, 40])
    v0 = sol.v0
    assert np.all(np.diff(v0, axis=0) >= -1e-12)
    # and within one solve, V_t decreases as fewer epochs remain
    assert np.all(np.diff(sol.values[4], axis=0) <= 1e-12)


def test_unreachable_goal_keeps_stop_value():
    occ = np.zeros((6, 9), bool)
    occ[:, 4] = True  # a wall splits the map
    mdp = GridMDP(occ, slip=0.1, step_cost=0.01, dtype="float64")
    sol = mdp.solve([[2, 7], [2, 7]], ["walk", "stop"], 30)
    left = sol.values[0][:, :, :4]
    assert_allclose(left, sol.values[1][:, :, :4], atol=0)
    assert np.all(left == 0)
    assert np.all(sol.policy[0][:, :, :4] == 0)  # stay
    # the reachable side has positive value
    reachable = ~occ
    reachable[:, :5] = False
    reachable[2, 7] = False  # the goal itself is absorbing with value 0
    assert np.all(sol.v0[0][reachable] > 0)


def test_stop_is_zero_and_stays():
    mdp = GridMDP(np.zeros((4, 4), bool))
    sol = mdp.solve(None, "stop", 5)
    assert np.all(sol.values == 0) and np.all(sol.policy == 0)


def test_lazy_values_match_stored():
    rng = np.random.default_rng(6)
    occ = random_grid(rng, 8, 9, 0.2)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, dtype="float64")
    a = mdp.solve(free[:3], ["walk", "run", "walk"], [5, 9, 7], store_values=True)
    b = mdp.solve(free[:3], ["walk", "run", "walk"], [5, 9, 7], store_values=False)
    assert b._values is None
    assert_allclose(b.values, a.values, atol=0)
    assert_allclose(b.v0, a.values[:, 0], atol=0)
    assert np.array_equal(a.policy, b.policy)


def test_follow_rewards_drive_values():
    occ = np.zeros((3, 12), bool)
    cells = np.stack([np.ones(11, int), np.arange(11)], axis=1)
    r = follow_rewards(cells, (3, 12))
    assert r.shape == (10, 3, 12)
    assert r[0, 1, 0] == 1 and r[0, 1, 2] == 1 and r[0, 1, 1] == 0 and r[0, 0, 1] == 1
    mdp = GridMDP(occ, slip=0.0, dtype="float64")
    sol = mdp.solve(None, "follow", 10, follow=[r])
    # starting next to the target, following earns ~1 per epoch minus step costs
    assert sol.v0[0, 1, 0, 0] > 9 * (1 - 2 * mdp.step_cost)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(slip=1.0), "slip"),
        (dict(slip=-0.1), "slip"),
        (dict(step_cost=-1), "step_cost"),
        (dict(dtype="int8"), "dtype"),
    ],
)
def test_bad_model_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        GridMDP(np.zeros((3, 3), bool), **kwargs)


def test_bad_grid():
    with pytest.raises(ValueError, match="occupied"):
        GridMDP(np.zeros(5, bool))
    with pytest.raises(ValueError, match="occupied"):
        GridMDP(np.full((3, 3), 0.5))


def test_bad_solve_inputs():
    occ = np.zeros((4, 5), bool)
    occ[2, 3] = True
    mdp = GridMDP(occ)
    with pytest.raises(ValueError, match=r"goals\[0\].*obstacle"):
        mdp.solve([2, 3], "walk", 5)
    with pytest.raises(ValueError, match=r"goals\[0\].*inside"):
        mdp.solve([9, 0], "walk", 5)
    with pytest.raises(ValueError, match="horizons"):
        mdp.solve([0, 0], "walk", -1)
    with pytest.raises(ValueError, match="horizons"):
        mdp.solve([0, 0], "walk", 2.5)
    with pytest.raises(ValueError, match="behaviour"):
        mdp.solve([0, 0], "fly", 5)
    with pytest.raises(ValueError, match=r"follow\[0\]"):
        mdp.solve(None, "follow", 5)
    with pytest.raises(ValueError, match=r"follow\[0\]"):
        mdp.solve(None, "follow", 5, follow=[np.zeros((2, 4, 5))])
    with pytest.raises(ValueError, match="goals"):
        mdp.solve([[0, 0], [1, 1]], ["walk"] * 3, 5)
    with pytest.raises(ValueError, match="goal.*obstacle"):
        mdp.to_dense((2, 3))
    with pytest.raises(ValueError, match="follow"):
        mdp.to_dense(None, "follow")
    with pytest.raises(ValueError, match="sparse=True"):
        GridMDP(np.zeros((80, 80), bool)).to_dense((0, 0))


def test_occupancy_grid_like_object():
    class Grid:
        occupied = np.eye(4, dtype=bool)

    mdp = GridMDP(Grid())
    assert mdp.grid is not None and mdp.occupied.sum() == 4


def _bfs_actions(occ, goal, moves):
    """Fewest actions from every (row, col, heading) to the goal cell (independent BFS)."""
    h, w = occ.shape
    dist = np.full((h, w, 4), -1)
    dr, dc = [0, 1, 0, -1], [1, 0, -1, 0]
    frontier = [(goal[0], goal[1], k) for k in range(4)]
    for state in frontier:
        dist[state] = 0
    # reverse search: a predecessor p reaches s with one action
    preds = {}
    for r in range(h):
        for c in range(w):
            if occ[r, c] or (r, c) == tuple(goal):
                continue
            for k in range(4):
                nxt = [(r, c, (k + 1) % 4), (r, c, (k - 1) % 4)]
                for step in moves:
                    cells = [(r + m * dr[k], c + m * dc[k]) for m in range(1, step + 1)]
                    if all(0 <= a < h and 0 <= b < w and not occ[a, b] for a, b in cells):
                        nxt.append((*cells[-1], k))
                for s in nxt:
                    preds.setdefault(s, []).append((r, c, k))
    while frontier:
        new = []
        for s in frontier:
            for p in preds.get(s, []):
                if dist[p] < 0:
                    dist[p] = dist[s] + 1
                    new.append(p)
        frontier = new
    return dist


@pytest.mark.parametrize(("behaviour", "moves"), [("walk", (1,)), ("run", (1, 2))])
def test_values_without_slip_equal_shortest_paths(behaviour, moves):
    rng = np.random.default_rng(8)
    occ = random_grid(rng, 6, 7, 0.25)
    goal = tuple(np.argwhere(~occ)[-1])
    c = 0.01
    mdp = GridMDP(occ, slip=0.0, step_cost=c, goal_reward=1.0, dtype="float64")
    sol = mdp.solve([goal], behaviour, 15)
    dist = _bfs_actions(occ, goal, moves)
    reach = (dist > 0) & (dist <= 15)
    assert_allclose(sol.v0[0][reach], 1.0 - c * dist[reach], rtol=0, atol=1e-12)
    assert np.all(sol.v0[0][dist < 0] == 0)


def test_action_looks_up_the_policy_in_every_part():
    """``MDPSolution.action`` (what a rollout asks once per epoch) is ``policy[b, t, row,
    col, h]`` for items of every part the devices wrote (a batch split across the local
    devices, padded to a multiple of them), every heading, and a single item."""
    rng = np.random.default_rng(21)
    occ = random_grid(rng, 7, 8, 0.2)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ)
    for n in (1, 5):
        sol = mdp.solve(free[:n], ["walk", "run", "walk", "walk", "run"][:n], 6, n_epochs=6)
        m = 300
        items, t = rng.integers(0, n, m), rng.integers(0, 6, m)
        cells = free[rng.integers(0, len(free), m)]
        states = np.column_stack([cells, rng.integers(0, 4, m)])
        want = sol.policy[items, t, states[:, 0], states[:, 1], states[:, 2]]
        got = sol.action(items, t, states)
        assert got.dtype == np.int8
        np.testing.assert_array_equal(got, want)
        assert sol.action(items[:0], t[:0], states[:0]).shape == (0,)


def test_lazy_policy_matches_eager():
    rng = np.random.default_rng(9)
    occ = random_grid(rng, 8, 9, 0.2)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, dtype="float64")
    a = mdp.solve(free[:3], ["walk", "run", "walk"], [5, 9, 7])
    b = mdp.solve(free[:3], ["walk", "run", "walk"], [5, 9, 7], with_policy=False)
    assert b._policy is None
    assert np.array_equal(a.policy, b.policy)
    assert_allclose(a.v0, b.v0, atol=0)


def test_backward_induction_pure_function_under_jit():
    rng = np.random.default_rng(10)
    occ = random_grid(rng, 5, 6, 0.2)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, dtype="float64")
    sol = mdp.solve(free[:2], ["walk", "run"], [4, 6])
    fn = jax.jit(functools.partial(backward_induction, **{**sol._inputs, "store_values": True}))
    v0, policy, values = fn()
    assert policy.shape == (2, 6, 4, 5, 6) and values.shape == (2, 7, 4, 5, 6)
    assert_allclose(np.moveaxis(np.asarray(values), 2, -1), sol.values, atol=0)
    assert np.array_equal(np.moveaxis(np.asarray(policy), 2, -1), sol.policy)
    assert_allclose(np.moveaxis(np.asarray(v0), 1, -1), sol.v0, atol=0)


def same_bits(a, b):
    """``a`` and ``b`` hold the same values bit for bit (signed zeros included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_padded_solve_equals_unpadded_program_bit_for_bit(dtype):
    # solve() pads the grid (with occupied cells), each device's items and the epochs of its
    # buffers to shared sizes; the pure function run at the true shapes is the reference
    rng = np.random.default_rng(12)
    h, w = (17, 9) if dtype == "float32" else (6, 13)
    occ = random_grid(rng, h, w, 0.2)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, slip=0.15, step_cost=0.01, dtype=dtype)
    reward = rng.normal(size=(14, h, w)) * 0.1  # negative rewards: signed zeros on obstacles
    sol = mdp.solve(
        free[:3],
        ["run", "follow", "walk"],
        [13, 11, 5],
        follow=[None, reward, None],
        store_values=True,
    )
    ref = jax.jit(functools.partial(backward_induction, **{**sol._inputs, "store_values": True}))
    v0, policy, values = (np.asarray(x) for x in ref())
    assert sol.values.shape == (3, 14, h, w, 4)
    assert same_bits(sol.values, np.moveaxis(values, 2, -1))
    assert same_bits(sol.policy, np.moveaxis(policy, 2, -1))
    assert same_bits(sol.v0, np.moveaxis(v0, 1, -1))


def test_a_horizon_of_zero_is_the_terminal_value_and_an_empty_policy():
    """No epoch to go: ``V_0`` is the terminal value (``V_1`` of a one-epoch solve) and the
    policy has no epoch (the solver's buffers hold at least 16 epochs; before they were
    padded, a policy of 0 epochs failed to trace)."""
    rng = np.random.default_rng(5)
    occ = random_grid(rng, 5, 7, 0.2)
    mdp = GridMDP(occ, slip=0.1, step_cost=0.01)
    goal = np.argwhere(~occ)[:1]
    none = mdp.solve(goal, "walk", 0)
    one = mdp.solve(goal, "walk", 1, store_values=True)
    assert none.policy.shape == (1, 0, 5, 7, 4)
    assert same_bits(none.v0, one.values[:, 1])


def test_padded_sizes_cover_and_bound_the_waste():
    from are_stats.behaviour._mdp import _CALL_BYTES, _epoch_size, _grid_size, _padded_shapes

    for n in range(1, 700):
        g, e = _grid_size(n), _epoch_size(n)
        assert n <= g <= max(16, n + 3 * n / 17) and (n < 64 or g <= n + n / 16)
        assert n <= e <= max(16, 1.5 * n)
    for b in (1, 2, 3, 8, 9, 100, 129, 4096):
        for item_bytes in (10**3, 10**6, 10**8):
            n_dev, slots = _padded_shapes(b, 2, item_bytes)
            per = -(-b // n_dev)  # items a device solves, in calls of ``slots``
            assert n_dev == (1 if b == 1 else 2)
            # the share fits in one call unless the next level would pass the call's bytes
            assert slots >= min(per, 64) or n_dev * 4 * slots * item_bytes > _CALL_BYTES
            assert slots <= max(4, 4 * per)
            assert slots == 1 or n_dev * slots * item_bytes <= _CALL_BYTES


@pytest.mark.parametrize(
    "dtype",
    [
        # 8 s of CPU cold, six programs of its own; make test: the float64 case (the same
        # batch against the same per-goal solves) and test_float32_close_to_float64
        pytest.param("float32", marks=pytest.mark.slow),
        "float64",
    ],
)
def test_batched_solve_equals_per_goal_solves(dtype):
    # a batch (odd size: padded when split across devices) gives each item's own solve
    rng = np.random.default_rng(11)
    occ = random_grid(rng, 9, 11, 0.15)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, slip=0.2, dtype=dtype)
    goals = free[rng.choice(len(free), 5, replace=False)]
    behaviours = ["run", "walk", "run", "stop", "run"]
    horizons = [12, 7, 12, 5, 9]
    batch = mdp.solve(goals, behaviours, horizons, store_values=True)
    # a lone walk compiles without the run action: its sums may round differently (1 ulp)
    atol = 1e-6 if dtype == "float32" else 1e-14
    for b in range(len(goals)):
        one = mdp.solve(goals[b], behaviours[b], horizons[b], n_epochs=12, store_values=True)
        assert_allclose(batch.v0[b], one.v0[0], rtol=0, atol=atol)
        assert_allclose(batch.values[b], one.values[0], rtol=0, atol=atol)
        assert np.array_equal(batch.policy[b], one.policy[0])
    lazy = mdp.solve(goals, behaviours, horizons, store_values=False, with_policy=False)
    assert np.array_equal(lazy.policy, batch.policy)
    assert np.array_equal(lazy.values, batch.values)


def test_reused_output_buffers_give_the_same_solutions():
    # a solution's buffers are reused by later solves only once it is gone; a live one keeps
    # its values, and what was handed out (v0, policy, values) never changes afterwards.
    # A solution is gone with its last reference (no cycle holds it: checked after each
    # del), so no full collection is needed (in a long test process each walked every
    # object left from earlier tests: the test took 19 s of a cold run, 6 s alone)

    rng = np.random.default_rng(12)
    occ = random_grid(rng, 10, 12, 0.15)
    free = np.argwhere(~occ)
    mdp = GridMDP(occ, slip=0.1)
    goals = free[rng.choice(len(free), 4, replace=False)]
    fresh = []
    for g in goals:
        s = mdp.solve(g, "run", 15)
        fresh.append((s.v0.copy(), s.policy.copy(), s.values.copy()))
        gone = weakref.ref(s)
        del s  # gone with its last reference: its buffers are back without a collection
        assert gone() is None
    kept = mdp.solve(goals[0], "run", 15, store_values=False)  # alive through the loop below
    v0_out = mdp.solve(goals[1], "run", 15).v0  # its solution is gone, the array stays
    for _ in range(2):
        for g, (v0, pol, val) in zip(goals, fresh, strict=True):
            s = mdp.solve(g, "run", 15)
            assert np.array_equal(s.v0, v0) and np.array_equal(s.policy, pol)
            assert np.array_equal(s.values, val)
            gone = weakref.ref(s)
            del s
            assert gone() is None
    assert np.array_equal(kept.policy, fresh[0][1]) and np.array_equal(kept.v0, fresh[0][0])
    assert np.array_equal(kept.values, fresh[0][2])
    assert np.array_equal(v0_out, fresh[1][0])


def test_buffer_pool_takes_back_only_what_fits():
    class Buf:
        def __init__(self, n):
            self.nbytes = n

        def is_deleted(self):
            return False

    pool = _BufferPool(max_bytes=100)
    a, b = Buf(60), Buf(60)
    pool.give("k", a)
    pool.give("k", b)  # over the limit: dropped
    assert pool.take("k", lambda: "new") is a
    assert pool.take("k", lambda: "new") == "new"
