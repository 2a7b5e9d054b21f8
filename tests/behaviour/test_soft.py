"""Soft backward induction: the hard limit, the likelihood's gradients, observations."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.sharding import Mesh
from jax.sharding import PartitionSpec as P

from are_stats.behaviour import (
    GridMDP,
    move_observations,
    moves_log_likelihood,
    sample_soft_paths,
    smooth_path,
    soft_policy,
    track_log_likelihoods,
)
from are_stats.behaviour._mdp import path_free
from are_stats.behaviour._soft import soft_backward_induction
from are_stats.fitting import behaviour_log_likelihood
from tests.helpers import assert_allclose


def _grid() -> np.ndarray:
    occ = np.zeros((8, 9), bool)
    occ[3, 2:6] = True
    occ[5:7, 6] = True
    return occ


@pytest.mark.parametrize("relative", [True, False])
def test_soft_values_tend_to_hard_values(relative: bool) -> None:
    occ, goal, k = _grid(), (6, 7), 15
    hard = GridMDP(occ, slip=0.1, dtype="float64").solve([goal], "walk", k)
    v_hard = np.moveaxis(hard.values[0, 0], -1, 0)  # time-to-go k, (4, H, W)
    errs = []
    for beta in (10.0, 100.0, 1e3, 1e4):
        sol = soft_policy(occ, [goal], beta, 0.1, n_epochs=k, relative=relative)
        err = np.abs(np.asarray(sol.values[0]) - v_hard).max()
        assert err <= k * np.log(4) / beta + 1e-9  # the log-sum-exp gap, k epochs
        errs.append(err)
    assert errs[-1] < 1e-2 * errs[0]


def test_soft_argmax_is_the_hard_policy_where_unique() -> None:
    occ, goal, k = _grid(), (6, 7), 15
    mdp = GridMDP(occ, slip=0.1, dtype="float64")
    hard = mdp.solve([goal], "walk", k)
    p, r, _ = mdp.to_dense(goal, "walk")
    v_next = hard.values[0, 1].reshape(-1)  # time-to-go k - 1, s = (row W + col) 4 + h
    q = r + np.einsum("ast,t->sa", p, v_next)
    top = np.sort(q, axis=1)
    unique = top[:, -1] - top[:, -2] > 1e-6
    free = ~mdp.occupied.ravel().repeat(4)
    not_goal = np.ones(mdp.n_states, bool)
    not_goal[
        (goal[0] * occ.shape[1] + goal[1]) * 4 : (goal[0] * occ.shape[1] + goal[1]) * 4 + 4
    ] = 0
    sel = unique & free & not_goal
    sol = soft_policy(occ, [goal], 1e4, 0.1, n_epochs=k)
    pol = np.asarray(sol.policy[0])  # (4, 5, H, W)
    soft_arg = np.moveaxis(pol.argmax(axis=1), 0, -1).reshape(-1)
    assert sel.sum() > 100
    np.testing.assert_array_equal(soft_arg[sel], np.argmax(q, axis=1)[sel])


def test_policy_is_a_distribution_and_run_is_optional() -> None:
    occ = _grid()
    walk = np.asarray(soft_policy(occ, [[0, 0], [7, 8]], 2.0, 0.2, n_epochs=30).policy)
    assert_allclose(walk.sum(axis=2), 1.0, rtol=1e-12)
    assert (walk[:, :, 2] == 0).all()
    run = np.asarray(soft_policy(occ, [[0, 0]], 2.0, 0.2, n_epochs=30, use_run=True).policy)
    assert_allclose(run.sum(axis=2), 1.0, rtol=1e-12)
    assert (run[:, :, 2] > 0).any()


def _paths(seed: int, occ: np.ndarray, beta: float, slip: float, n: int = 12) -> list:
    rng = np.random.default_rng(seed)
    free = np.argwhere(~occ)
    goals = free[rng.choice(len(free), 3, replace=False)]
    gi = rng.integers(0, 3, n)
    starts = np.column_stack([free[rng.choice(len(free), n)], rng.integers(0, 4, n)])
    sol = soft_policy(occ, goals, beta, slip, n_epochs=200, time_cost=1.0, tol=1e-8)
    st, _ = sample_soft_paths(
        rng, np.asarray(sol.policy), occ, slip, starts, gi, goals, np.full(n, 80)
    )
    out = []
    for i in range(n):
        at = np.flatnonzero((st[i, :, :2] == goals[gi[i]]).all(axis=1))
        if at.size and at[0] > 0:
            out.append(st[i, : at[0] + 1, :2])
    return out


@pytest.mark.slow  # 14 s of CPU, nearly all XLA's compile of the reverse-mode program
def test_log_likelihood_gradient_matches_finite_differences() -> None:
    """Reverse mode (``jax.grad``) through the fixed-epoch solve. make test: the
    likelihood's derivatives against differences in forward mode, through the solve the
    fit differentiates (test_forward_mode_gradient_of_the_stationary_policy)."""
    occ = _grid()
    paths = _paths(1, occ, 2.0, 0.15)

    def ll(theta: jax.Array) -> jax.Array:
        return behaviour_log_likelihood(paths, ~occ, theta[0], theta[1], n_epochs=40)[0]

    # the gradient and the differences' values from one compiled program (a jitted ``ll``
    # and ``jax.grad`` of it were two, each compiling the 40-epoch solve)
    value_and_grad = jax.jit(jax.value_and_grad(ll))
    th = jnp.array([1.7, 0.12])
    grad = np.asarray(value_and_grad(th)[1])
    h = 1e-5

    def value(q: jax.Array) -> float:
        return float(value_and_grad(q)[0])

    fd = [(value(th + h * e) - value(th - h * e)) / (2 * h) for e in np.eye(2, dtype=float)]
    assert_allclose(grad, fd, rtol=1e-6, atol=1e-6)
    assert np.abs(grad).min() > 1e-3  # not a trivially flat point


def test_forward_mode_gradient_of_the_stationary_policy() -> None:
    """The early-stopped (while_loop) solve used by the fit: jacfwd against differences."""
    occ = _grid()
    paths = _paths(2, occ, 2.0, 0.15)

    def ll(theta: jax.Array) -> tuple[jax.Array, jax.Array]:
        obs = move_observations(paths)
        g = len(obs.goals)
        mask = np.zeros((g,) + occ.shape, bool)
        mask[np.arange(g), obs.goals[:, 0], obs.goals[:, 1]] = True
        ok = jnp.asarray(path_free(occ))
        sol = soft_backward_induction(
            ok,
            ~occ[None] & ~mask,
            jnp.asarray(mask, float),
            theta[0],
            theta[1],
            n_epochs=500,
            time_cost=1.0,
            tol=1e-12,
        )
        value = moves_log_likelihood(sol.policy, ok, theta[1], obs)
        return value, value  # the value again as aux: jacfwd's program gives both

    # the Jacobian and the differences' values from one compiled program (a jitted ``ll``
    # and jacfwd of it were two, each compiling the 500-epoch solve)
    jac_and_value = jax.jit(jax.jacfwd(ll, has_aux=True))
    th = jnp.array([2.1, 0.1])
    grad = np.asarray(jac_and_value(th)[0])
    h = 1e-5

    def value(q: jax.Array) -> float:
        return float(jac_and_value(q)[1])

    fd = [(value(th + h * e) - value(th - h * e)) / (2 * h) for e in np.eye(2, dtype=float)]
    assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)


def test_move_observations_codes_steps() -> None:
    obs = move_observations([np.array([[0, 0], [0, 0], [0, 1], [1, 1], [3, 1]])])
    np.testing.assert_array_equal(obs.move[0], [0, 1, 2, 5])  # stay, east, north, forbidden
    np.testing.assert_array_equal(obs.goals, [[3, 1]])
    assert obs.n_moves == 4


def test_smooth_path_keeps_ends_and_straightens_a_staircase() -> None:
    stairs = np.array([[i // 2 + (i % 2), i // 2] for i in range(21)], float)
    s = smooth_path(stairs, 5)
    assert_allclose(s[[0, -1]], stairs[[0, -1]])
    length = np.hypot(*np.diff(s, axis=0).T).sum()
    net = np.hypot(*(s[-1] - s[0]))
    assert net / length > 0.95


def test_goals_split_across_devices_stop_at_the_epoch_of_the_whole_batch() -> None:
    """shard_map over goals with ``axis_name``: the same values as one unsplit solve, although
    the near goal's shard alone would stop epochs earlier than the far goals' shard."""
    if jax.local_device_count() < 2:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    occ = _grid()
    goals = np.array([[0, 0], [1, 1], [7, 8], [6, 7]])  # a near pair, a far pair
    mask = np.zeros((4,) + occ.shape, bool)
    mask[np.arange(4), goals[:, 0], goals[:, 1]] = True
    keep, bonus = ~occ[None] & ~mask, jnp.asarray(mask, float)
    ok = jnp.asarray(path_free(occ))
    opts = dict(n_epochs=400, time_cost=1.0, tol=1e-4)

    def solve(keep_, bonus_, axis_name=None):
        return soft_backward_induction(
            ok, keep_, bonus_, jnp.asarray(1.5), jnp.asarray(0.1), axis_name=axis_name, **opts
        )

    whole = jax.jit(solve)(keep, bonus)
    mesh = Mesh(np.array(jax.local_devices()[:2]), ("g",))
    results = {}
    for name in ("g", None):
        split = jax.shard_map(
            lambda k, b, name=name: solve(k, b, name),
            mesh=mesh,
            in_specs=(P("g"), P("g")),
            out_specs=P("g"),
            check_vma=False,
        )
        results[name] = jax.jit(split)(keep, bonus)
    assert_allclose(results["g"].values, whole.values, rtol=1e-12, atol=1e-12)
    assert_allclose(results["g"].policy, whole.policy, rtol=1e-12, atol=1e-12)
    # without the shared stopping rule the near goals' shard stops early
    assert np.abs(np.asarray(results[None].values - whole.values)).max() > 1e-6


def test_bucketed_soft_policy_compiles_nothing_but_its_program(caplog) -> None:
    """soft_policy's ``bucket`` hands its arrays and numbers to the solve as they are (issue
    29: jnp.asarray of each compiled a one-operation program, four per grid and goal
    bucket): on a grid of its own (7 x 11) the solve's program is the only one."""
    import logging

    occ = np.zeros((7, 11), bool)
    occ[3, 2:8] = True
    cells = np.argwhere(~occ)
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        sol = soft_policy(occ, cells[:3], 2.0, 0.1, n_epochs=30, tol=1e-3, bucket=4)
    compiled = [r.getMessage() for r in caplog.records if r.getMessage().startswith("Compiling")]
    assert [m.split()[1] for m in compiled] == ["jit(_capped_jit)"]
    assert np.isfinite(np.asarray(sol.policy)).all()


def test_bucketed_soft_policy_is_the_same_bit_for_bit_from_one_program() -> None:
    """soft_policy's ``bucket`` (issue 29: generation's soft solves compiled one program per
    epoch cap and goal count): the goals padded with copies of the last one, the cap and
    the tolerance passed as data. Values and policies equal the unpadded solve's bit for
    bit, and new caps, tolerances and goal counts up to the bucket compile nothing."""
    from are_stats.behaviour._soft import _capped_jit

    occ = _grid()
    cells = np.argwhere(~occ)
    rng = np.random.default_rng(1)
    cr = -0.3 * np.asarray(rng.uniform(0, 1, occ.shape))
    opts = dict(goal_reward=1.0, step_cost=1e-3, time_cost=1.0, cell_reward=cr)
    soft_policy(occ, cells[:2], 2.0, 0.1, n_epochs=30, tol=1e-3, bucket=4, **opts)
    size = _capped_jit._cache_size()
    for g, k, tol in ((1, 40, 1e-3), (3, 25, 1e-2), (4, 200, 1e-6)):
        goals = cells[rng.choice(len(cells), g, replace=False)]
        got = soft_policy(occ, goals, 2.0, 0.1, n_epochs=k, tol=tol, bucket=4, **opts)
        want = soft_policy(occ, goals, 2.0, 0.1, n_epochs=k, tol=tol, **opts)
        assert got.policy.shape == want.policy.shape == (g, 4, 5) + occ.shape
        np.testing.assert_array_equal(np.asarray(got.policy), np.asarray(want.policy))
        np.testing.assert_array_equal(np.asarray(got.values), np.asarray(want.values))
    assert _capped_jit._cache_size() == size
    with pytest.raises(ValueError, match="bucket: expected with tol"):
        soft_policy(occ, cells[:2], 2.0, 0.1, n_epochs=30, bucket=4)


def test_track_log_likelihoods_are_the_per_track_values_from_one_program() -> None:
    """track_log_likelihoods (issue 29: the criticism called moves_log_likelihood op by
    op, some 40 one-operation programs per batch size): the tracks, steps and goals
    padded to buckets give every track's value of the unpadded per-track likelihood (to
    float64 round-off: two programs of their own)."""
    occ = _grid()
    paths = _paths(3, occ, 2.0, 0.15)
    ok = path_free(occ)
    # one solve and one op-by-op reference for all tracks: a track's value depends only on
    # its own steps and its goal's policy, so the first n tracks' values are the first n
    # of the whole batch's (a solve and a reference per batch size compiled each again)
    every = move_observations(paths)
    sol = soft_policy(occ, every.goals, 2.0, 0.15, n_epochs=200, time_cost=1.0, tol=1e-8)
    policy = np.asarray(sol.policy)
    # the reference jitted whole (op by op it compiled some 60 one-operation programs:
    # 3.6 s of CPU against 0.6 s; the values agree to 7e-15)
    want = jax.jit(lambda p: moves_log_likelihood(p, jnp.asarray(ok), 0.15, every, per_track=True))(
        jnp.asarray(policy)
    )
    for n in (len(paths), 5, 1):
        obs = move_observations(paths[:n])
        rows = [np.flatnonzero((every.goals == g).all(axis=1))[0] for g in obs.goals]
        got = track_log_likelihoods(policy[rows], ok, 0.15, obs)
        assert got.shape == (n,) and got.dtype == np.float64
        assert_allclose(got, np.asarray(want)[:n], rtol=1e-13, atol=1e-13)


def _reference_soft_solve(occ, goals, beta, slip, k, sc, tc, cr, use_run, relative):
    """One heading and one action at a time, in NumPy: ``(values (G, 4, H, W), policy
    (G, 4, 5, H, W))`` of :func:`soft_backward_induction` after ``k`` epochs (the
    module's formulas written out, independent of its heading-major arrays)."""
    from are_stats.behaviour._rewards import HEADINGS

    h_, w_ = occ.shape
    ok = np.asarray(path_free(occ), float)  # (4, 2, H, W)
    g = len(goals)
    at_goal = np.zeros((g, h_, w_), bool)
    at_goal[np.arange(g), goals[:, 0], goals[:, 1]] = True
    keep, bonus = (~occ[None] & ~at_goal).astype(float), np.where(at_goal, 1.0, 0.0)
    acts = (0, 1, 2, 3, 4) if use_run else (0, 1, 3, 4)

    def shifted(x, j, n):
        xp = np.pad(x, ((0, 0), (2, 2), (2, 2)))
        dr, dc = n * HEADINGS[j][0], n * HEADINGS[j][1]
        return xp[:, 2 + dr : 2 + dr + h_, 2 + dc : 2 + dc + w_]

    def q_values(v):
        q = np.zeros((g, 4, 5, h_, w_))
        for h in range(4):
            wh = v[:, h] + bonus
            q[:, h, 0] = wh - tc
            for n in (1, 2):
                out = wh
                for j, p in ((h, 1 - slip), ((h + 1) % 4, slip / 2), ((h - 1) % 4, slip / 2)):
                    out = out + p * ok[j, n - 1] * (shifted(wh, j, n) - wh)
                q[:, h, n] = out - sc - tc
            q[:, h, 3] = v[:, (h + 1) % 4] + bonus - sc - tc
            q[:, h, 4] = v[:, (h - 1) % 4] + bonus - sc - tc
        return q[:, :, acts] + cr

    v = np.zeros((g, 4, h_, w_))
    for _ in range(k):
        q = q_values(v)
        lse = np.log(np.exp(beta * q).sum(axis=2)) / beta
        v = (lse - (np.log(len(acts)) / beta if relative else 0.0)) * keep[:, None]
    pol = np.zeros((g, 4, 5, h_, w_))
    pol[:, :, acts] = np.exp(beta * (q - lse[:, :, None]))
    return v, pol


@pytest.mark.parametrize("use_run, relative", [(False, True), (True, False)])
def test_soft_solve_is_the_per_heading_formula(use_run: bool, relative: bool) -> None:
    """The solver's heading-major arrays (all four headings in one array: a program half
    the size) hold the per-heading, per-action values of the formulas, slips, runs and
    a cell reward included (float64, to round-off)."""
    occ = _grid()
    goals = np.array([[0, 0], [7, 8], [2, 4]])
    cr = np.linspace(-0.2, 0.3, occ.size).reshape(occ.shape) * ~occ
    sol = soft_policy(
        occ, goals, 1.7, 0.2, n_epochs=12, step_cost=0.01, time_cost=0.5, cell_reward=cr,
        use_run=use_run, relative=relative,
    )  # fmt: skip
    v, pol = _reference_soft_solve(occ, goals, 1.7, 0.2, 12, 0.01, 0.5, cr, use_run, relative)
    assert_allclose(np.asarray(sol.values), v, rtol=1e-12, atol=1e-12)
    assert_allclose(np.asarray(sol.policy), pol, rtol=1e-11, atol=1e-14)
