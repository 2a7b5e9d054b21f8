"""Soft (maximum-entropy) backward induction on the grid MDP and the likelihood of moves.

The MDP is :class:`~are_stats.behaviour.GridMDP`'s (DECISIONS.md item 7): states ``(row,
col, h)``, actions ``stay, forward, run, left, right``, slip ``slip / 2`` to each side,
blocked outcomes stay, goal cells and occupied cells absorbing with value 0, ``goal_reward``
for entering the goal, ``step_cost`` for every move. Two optional reward terms are added for
behaviour fits: a ``time_cost`` for every epoch spent off the goal (stay included; it sets
the reward scale that ``beta`` is measured in), and cell rewards ``sum_k w_k phi_k(cell)``
earned at every epoch spent on a non-absorbing cell. With both zero the rewards are exactly
``GridMDP``'s.

A noisily rational (Boltzmann) artefact (Ziebart et al. 2008) solves, with ``V_0 = 0`` and
time-to-go ``k = 1, ..., K``,

.. math::

    Q_k(s, a) = r(s, a) + \\sum_{s'} p(s' | s, a) V_{k-1}(s'), \\quad
    V_k(s) = \\frac{1}{\\beta} \\log \\frac{1}{A} \\sum_a e^{\\beta Q_k(s, a)}, \\quad
    \\pi_k(a | s) = \\frac{1}{A} e^{\\beta (Q_k(s, a) - V_k(s))}

(entropy relative to the uniform prior over the ``A`` allowed actions, the default; the
plain ``log sum`` is ``relative=False``, see :func:`soft_backward_induction`).

As ``beta -> infinity``, ``V_k -> max_a Q_k`` (``GridMDP``'s values; the gap is at most
``k log(n_actions) / beta``). Everything is pure JAX and differentiable in ``beta``, ``slip``
and the weights; transitions are stencils (shifted copies of ``V``), never ``S x S`` matrices.

Log-likelihood of observed moves
--------------------------------
A track is a sequence of cells at successive epochs, consecutive cells equal or 4-adjacent
(one move per epoch). The heading is hidden: turns happen in place (the cell repeats) and a
slip moves sideways with the heading kept. The likelihood sums over the hidden headings by
the forward algorithm of a hidden Markov model (initial heading uniform), with the policy at
a fixed time-to-go ``K`` (long enough to reach the goal: the stationary policy). A small
outlier probability ``eps`` per step keeps moves the model forbids (a reversal without a
turn, a move into an obstacle) from giving ``-inf``.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt

from are_stats._checks import describe
from are_stats.behaviour._mdp import _occupancy, path_free
from are_stats.behaviour._rewards import HEADINGS
from are_stats.environment import OccupancyGrid

__all__ = [
    "GOAL_BUCKET",
    "SoftSolution",
    "MoveObservations",
    "soft_backward_induction",
    "soft_policy",
    "moves_log_likelihood",
    "move_observations",
    "track_log_likelihoods",
    "wall_distance_feature",
]

_DROW = np.array([d[0] for d in HEADINGS])
_DCOL = np.array([d[1] for d in HEADINGS])
#: Outlier probability of one observed step (a move the model forbids).
OUTLIER = 1e-3


class SoftSolution(NamedTuple):
    """Soft backward induction for a batch of goals.

    Attributes
    ----------
    values : (G, 4, H, W) or (G, K + 1, 4, H, W)
        ``V_K`` (or every ``V_k``, ``k = 0 .. K``, with ``store_values``), heading-major.
    policy : (G, 4, A, H, W)
        ``pi_K(a | s)`` with ``A = 5`` actions (``stay, forward, run, left, right``); run has
        probability 0 when not allowed.
    epochs : () int or None
        With ``tol`` and ``with_epochs`` (:func:`soft_backward_induction`), the epochs the
        values were iterated before the solve stopped (the same solve with ``n_epochs =
        epochs + 1`` and no early stop, ``tol < 0``, repeats it epoch for epoch); else
        ``None``.
    """

    values: jax.Array
    policy: jax.Array
    epochs: jax.Array | None = None


def _shift(x: jax.Array, dr: int, dc: int) -> jax.Array:
    """``y[..., r, c] = x[..., r + dr, c + dc]``, zero outside the grid."""
    h, w = x.shape[-2:]
    pad = [(0, 0)] * (x.ndim - 2) + [(2, 2), (2, 2)]
    xp = jnp.pad(x, pad)
    return xp[..., 2 + dr : 2 + dr + h, 2 + dc : 2 + dc + w]


def _slip_matrix(slip: jax.Array) -> jax.Array:
    """``P[h, j]``: a move along heading ``h`` goes along direction ``j``."""
    eye = jnp.eye(4, dtype=slip.dtype)
    side = jnp.roll(eye, 1, axis=1) + jnp.roll(eye, -1, axis=1)
    return (1 - slip) * eye + (slip / 2) * side


def _q_values(
    w: jax.Array,
    ok: jax.Array,
    slip: jax.Array,
    cost: jax.Array,
    cell_reward: jax.Array,
    use_run: bool,
) -> list[jax.Array]:
    """The action values ``(4, G, H, W)`` (all headings at once) from ``w = V_{k-1} + bonus``
    ``(4, G, H, W)``, heading-major.

    The list holds one array per action: ``stay, forward, [run,] left, right``. The grid is
    padded once per epoch; a shift is a static slice, and a blocked outcome keeps ``w`` of
    the current state (``w + ok (shifted - w)``). Each element is computed by the same
    operations, in the same order, as one heading at a time; a quarter of the operations
    to trace (the behaviour fit's gradient program: StableHLO 281 -> 133 kB, tracing and
    lowering 2.1 -> 1.1 s of CPU; XLA's compile, nearly all LLVM, unchanged). XLA fuses
    the arrays otherwise, so a value may move by an ulp (tests/behaviour/test_soft.py pins
    the formulas).
    """
    h_, w_ = w.shape[-2:]
    p_main, p_side = 1 - slip, slip / 2
    wp = jnp.pad(w, ((0, 0), (0, 0), (2, 2), (2, 2)))
    okf = ok.astype(w.dtype)

    def moved(k: int) -> jax.Array:
        out = w
        # outcome m of heading h goes along direction (h + d) % 4: main, then the sides
        for d, p in ((0, p_main), (1, p_side), (-1, p_side)):
            sh = []
            for h in range(4):
                j = (h + d) % 4
                dr, dc = k * int(_DROW[j]), k * int(_DCOL[j])
                sh.append(wp[h, :, 2 + dr : 2 + dr + h_, 2 + dc : 2 + dc + w_])
            ok_d = jnp.roll(okf[:, k - 1], -d, axis=0)[:, None]  # (4, 1, H, W): okf[(h + d) % 4]
            out = out + p * ok_d * (jnp.stack(sh) - w)
        return out

    q = [w - cost[0] + cell_reward, moved(1) - cost[1] + cell_reward]
    if use_run:
        q.append(moved(2) - cost[2] + cell_reward)
    q.append(jnp.roll(w, -1, axis=0) - cost[3] + cell_reward)  # left: heading h -> h + 1
    q.append(jnp.roll(w, 1, axis=0) - cost[4] + cell_reward)  # right: h -> h - 1
    return q


def _soft_max(beta: jax.Array, q: list[jax.Array], relative: bool) -> tuple[jax.Array, jax.Array]:
    """``(1 / beta) log sum_a exp(beta q_a)`` (``mean_a`` when ``relative``) and the
    log-normaliser offset, over a list of planes."""
    m = q[0]
    for x in q[1:]:
        m = jnp.maximum(m, x)
    m = jax.lax.stop_gradient(m)
    tot = sum(jnp.exp(beta * (x - m)) for x in q)
    v = m + jnp.log(tot) / beta
    off = jnp.log(jnp.asarray(len(q), v.dtype)) / beta
    return (v - off if relative else v), off


def soft_backward_induction(
    ok: jax.Array,
    keep: jax.Array,
    bonus: jax.Array,
    beta: jax.Array,
    slip: jax.Array,
    *,
    n_epochs: int,
    step_cost: float | jax.Array = 1e-3,
    time_cost: float | jax.Array = 0.0,
    cell_reward: float | jax.Array = 0.0,
    use_run: bool = False,
    store_values: bool = False,
    relative: bool = True,
    tol: float | None = None,
    tol_mask: jax.Array | None = None,
    axis_name: str | None = None,
    with_epochs: bool = False,
) -> SoftSolution:
    """Soft backward induction over ``K = n_epochs`` epochs (pure; the caller jits).

    Parameters
    ----------
    ok : (4, 2, H, W) bool
        ``ok[j, k - 1]``: a move of ``k`` cells along heading ``j`` stays on free cells.
    keep : (G, H, W) bool
        Non-absorbing cells of each goal (free and not the goal).
    bonus : (G, H, W) float
        Reward for entering a cell (``goal_reward`` on the goal, else 0).
    beta : scalar float
        Rationality (``> 0``); its dtype is the computation's.
    slip : scalar float
        Slip probability in ``[0, 1)``.
    n_epochs : int or traced int scalar
        ``K >= 1`` (static without ``tol``; with it only the loop's bound, so it may be
        traced: one compiled program for every cap).
    step_cost, time_cost : scalar float
        Cost of every move; cost of every epoch off the goal.
    cell_reward : scalar or (G or 1, H, W) float
        Reward of every epoch spent on a cell (e.g. ``sum_k w_k phi_k``).
    use_run : bool
        Allow the run action (static).
    store_values : bool
        Return every ``V_k`` (static).
    relative : bool
        Entropy relative to the uniform action prior (static, default):
        ``V = (1 / beta) log mean_a exp(beta Q)``, the plain form minus ``log(A) / beta`` per
        epoch off the goal. With the plain form (``False``) wandering earns ``log(A) / beta``
        per epoch, so for ``beta < log(A) / time_cost`` never reaching the goal is optimal and
        ``V`` does not converge with the horizon; the relative form has the same Boltzmann
        policy given ``Q`` and the same ``beta -> infinity`` limit.
    tol : float, traced float scalar, or None
        Stop once the values change by at most ``tol`` in an epoch (``n_epochs`` is then a
        cap; a negative ``tol`` never stops early, so the cap is the epoch count as data);
        ``None`` (static) runs all ``n_epochs``.
    tol_mask : (G, H, W) bool or None
        Cells on which that change is measured (default: all).
    axis_name : str or None
        Name of a mapped axis that splits the goals (``jax.shard_map`` over devices): the
        change is then the largest over every shard, so that all stop at the same epoch,
        the epoch of the unsplit batch (identical results).
    with_epochs : bool
        With ``tol``: return the epochs iterated before the stop (static; the behaviour
        fit holds the solve there to difference its gradient, :mod:`are_stats.fitting`).

    Returns
    -------
    SoftSolution
        ``values``, the policy ``pi_K`` and, with ``tol`` and ``with_epochs``, the epochs
        iterated.
    """
    dtype = jnp.result_type(beta)
    beta = jnp.asarray(beta, dtype)
    slip = jnp.asarray(slip, dtype)
    keep_f = jnp.asarray(keep, dtype)[:, None]  # (G, 1, H, W)
    bonus = jnp.asarray(bonus, dtype)[:, None]
    cr = jnp.asarray(cell_reward, dtype)
    cr = cr[:, None] if cr.ndim == 3 else cr
    sc, tc = jnp.asarray(step_cost, dtype), jnp.asarray(time_cost, dtype)
    cost = jnp.stack([tc, sc + tc, sc + tc, sc + tc, sc + tc])
    g, h, w = keep.shape
    keep_f = keep_f[:, 0]
    bonus = bonus[:, 0]
    cr = cr[:, 0] if cr.ndim == 4 else cr

    def q_of(v: jax.Array) -> list[jax.Array]:
        return _q_values(v + bonus, ok, slip, cost, cr, use_run)

    def step(v: jax.Array, _: None) -> tuple[jax.Array, jax.Array | None]:
        v_new = _soft_max(beta, q_of(v), relative)[0] * keep_f
        return v_new, (v_new if store_values else None)

    v0 = jnp.zeros((4, g, h, w), dtype)  # heading-major inside the scan
    epochs = None
    if tol is None:
        v_prev, vs = jax.lax.scan(step, v0, None, length=n_epochs - 1)
    else:

        def cond(c: tuple[jax.Array, jax.Array, jax.Array]) -> jax.Array:
            return (c[0] < n_epochs - 1) & (c[2] > tol_v)

        def body(
            c: tuple[jax.Array, jax.Array, jax.Array],
        ) -> tuple[jax.Array, jax.Array, jax.Array]:
            v_new, _ = step(c[1], None)
            change = jnp.abs(v_new - c[1])
            if tol_mask is not None:
                change = jnp.where(tol_mask[None], change, 0.0)
            # only the loop's predicate: no derivative (pmax has no differentiation rule)
            largest = jax.lax.stop_gradient(jnp.max(change))
            if axis_name is not None:
                largest = jax.lax.pmax(largest, axis_name)
            return c[0] + 1, v_new, largest

        # in the computation's dtype, as a number would be: a traced tol stops alike
        tol_v = jnp.asarray(tol, dtype)
        start = (jnp.asarray(0), v0, jnp.asarray(jnp.inf, dtype))
        count, v_prev, _ = jax.lax.while_loop(cond, body, start)
        epochs = count if with_epochs else None
        vs = None
    q = q_of(v_prev)
    v_h, off = _soft_max(beta, q, relative)  # (4, G, H, W)
    # pi = exp(beta (Q - V)) (over A with a uniform prior), unmasked V on absorbing cells
    lse = v_h + off if relative else v_h
    p = [jnp.exp(beta * (x - lse)) for x in q]
    if not use_run:  # run has probability 0
        p.insert(2, jnp.zeros_like(p[0]))
    policy = jnp.moveaxis(jnp.stack(p, axis=2), 0, 1)  # (G, 4, 5, H, W)
    v_k = jnp.moveaxis(v_h * keep_f, 0, 1)
    if store_values and vs is not None:
        values = jnp.concatenate(
            [jnp.zeros((g, 1, 4, h, w), dtype), jnp.moveaxis(vs, (0, 1), (1, 2)), v_k[:, None]],
            axis=1,
        )
    else:
        values = v_k
    return SoftSolution(values, policy, epochs)


def _goal_arrays(
    occupied: np.ndarray, goals: np.ndarray, goal_reward: float
) -> tuple[np.ndarray, np.ndarray]:
    g = len(goals)
    mask = np.zeros((g,) + occupied.shape, bool)
    mask[np.arange(g), goals[:, 0], goals[:, 1]] = True
    keep = ~occupied[None] & ~mask
    return keep, np.where(mask, goal_reward, 0.0)


def soft_policy(
    occupied: npt.ArrayLike | OccupancyGrid,
    goals: npt.ArrayLike,
    beta: float,
    slip: float,
    *,
    n_epochs: int,
    goal_reward: float = 1.0,
    step_cost: float = 1e-3,
    time_cost: float = 0.0,
    cell_reward: npt.ArrayLike = 0.0,
    use_run: bool = False,
    store_values: bool = False,
    relative: bool = True,
    tol: float | None = None,
    bucket: int | None = None,
) -> SoftSolution:
    """Soft solution for goals on a grid (the convenience front of the soft solver).

    Parameters
    ----------
    occupied : (H, W) bool or OccupancyGrid
        Occupied cells.
    goals : (G, 2) int
        Goal cells ``(row, col)`` (free).
    beta, slip : float
        Rationality ``> 0`` and slip probability in ``[0, 1)``.
    n_epochs : int
        Time-to-go ``K >= 1``.
    goal_reward, step_cost, time_cost : float
        Rewards (see the module docstring; ``time_cost = 0`` gives ``GridMDP``'s).
    cell_reward : float or (H, W) float
        Reward of every epoch on a non-absorbing cell.
    use_run, store_values, relative : bool
        See :func:`soft_backward_induction`.
    tol : float or None
        Stop once the values change by at most ``tol`` (``n_epochs`` is then a cap).
    bucket : int or None
        With ``tol`` (and the defaults of ``use_run``, ``store_values``, ``relative``): pad
        the goals to a multiple of ``bucket`` by repeating the last one, and pass the epoch
        cap and ``tol`` as data, so that one compiled program serves every cap, tolerance
        and number of goals up to ``bucket`` (:data:`GOAL_BUCKET`: generation's chunks, the
        fit's criticism). The solution is the same, bit for bit: a copy of the last goal
        changes by exactly as much per epoch, so the solve stops at the same epoch. Its
        arrays are then NumPy arrays.

    Returns
    -------
    SoftSolution
        ``values (G, 4, H, W)`` (or ``(G, K + 1, 4, H, W)``), ``policy (G, 4, 5, H, W)``.

    Raises
    ------
    ValueError
        On goals outside the grid or on obstacles, or ``beta <= 0``, ``n_epochs < 1``.

    Examples
    --------
    >>> import numpy as np
    >>> sol = soft_policy(np.zeros((4, 5), bool), [[1, 4]], 5.0, 0.1, n_epochs=10)
    >>> sol.policy.shape
    (1, 4, 5, 4, 5)
    """
    occ = _occupancy(occupied)
    gl = np.asarray(goals, dtype=np.int64).reshape(-1, 2)
    h, w = occ.shape
    bad = (gl[:, 0] < 0) | (gl[:, 0] >= h) | (gl[:, 1] < 0) | (gl[:, 1] >= w)
    if bad.any() or occ[gl[~bad, 0], gl[~bad, 1]].any():
        raise ValueError(f"goals: expected free cells of the {h} x {w} grid, got {describe(gl)}")
    if not beta > 0:
        raise ValueError(f"beta: expected a positive float, got {beta!r}")
    if int(n_epochs) < 1:
        raise ValueError(f"n_epochs: expected an integer >= 1, got {n_epochs!r}")
    if bucket is not None:
        if tol is None or use_run or store_values or not relative:
            raise ValueError(
                "bucket: expected with tol and without use_run, store_values or relative=False"
            )
        if int(bucket) < 1:
            raise ValueError(f"bucket: expected an integer >= 1, got {bucket!r}")
        g = len(gl)
        padded = gl[np.minimum(np.arange(-(-g // int(bucket)) * int(bucket)), g - 1)]
        keep, bonus = _goal_arrays(occ, padded, goal_reward)
        # the arrays placed as they are (jax.device_put) and the numbers as Python's:
        # jnp.asarray of each compiled a program of its own (issue 29; the same values)
        sol = _capped_jit(
            jax.device_put(np.asarray(path_free(occ))),
            jax.device_put(keep),
            jax.device_put(bonus),
            float(beta),
            float(slip),
            jax.device_put(np.asarray(int(n_epochs), np.int32)),
            step_cost,
            time_cost,
            jax.device_put(np.asarray(cell_reward, float)),
            float(tol),
        )
        # cut on the host: slicing (or copying back) a device array compiles a program per
        # goal count
        return SoftSolution(np.asarray(sol.values)[:g], np.asarray(sol.policy)[:g])
    keep, bonus = _goal_arrays(occ, gl, goal_reward)
    return _soft_jit(
        jnp.asarray(path_free(occ)),
        jnp.asarray(keep),
        jnp.asarray(bonus),
        jnp.asarray(float(beta)),
        jnp.asarray(float(slip)),
        n_epochs=int(n_epochs),
        step_cost=step_cost,
        time_cost=time_cost,
        cell_reward=jnp.asarray(cell_reward, float),
        use_run=use_run,
        store_values=store_values,
        relative=relative,
        tol=tol,
    )


_soft_jit = jax.jit(
    soft_backward_induction,
    static_argnames=("n_epochs", "use_run", "store_values", "relative", "tol"),
)

#: Goals per soft solve of :func:`soft_policy` with ``bucket``: generation solves its
#: goals in chunks of this many, and the fit's criticism pads its solves to it.
GOAL_BUCKET = 16


@jax.jit
def _capped_jit(ok, keep, bonus, beta, slip, n_epochs, step_cost, time_cost, cell_reward, tol):
    """:func:`soft_backward_induction` with the epoch cap ``n_epochs`` and ``tol`` traced
    (with ``tol`` the cap only bounds the loop, so neither need be compiled in)."""
    return soft_backward_induction(
        ok,
        keep,
        bonus,
        beta,
        slip,
        n_epochs=n_epochs,
        step_cost=step_cost,
        time_cost=time_cost,
        cell_reward=cell_reward,
        tol=tol,
    )


def wall_distance_feature(occupied: npt.ArrayLike, scale: float = 1.0) -> np.ndarray:
    """A reward feature: ``exp(-d / scale)`` with ``d`` the distance (cells) to an obstacle.

    Parameters
    ----------
    occupied : (H, W) bool
        Occupied cells; the map's border counts as a wall.
    scale : float
        Decay length in cells.

    Returns
    -------
    phi : (H, W) float64
        1 next to a wall, decaying away from it (0 on occupied cells).
    """
    from scipy import ndimage  # lazy: +0.2 s CPU on `import are_stats.behaviour`

    occ = _occupancy(occupied)
    padded = np.pad(~occ, 1, constant_values=False)
    d = ndimage.distance_transform_edt(padded)[1:-1, 1:-1]
    return np.where(occ, 0.0, np.exp(-(d - 1.0) / float(scale)))


class MoveObservations(NamedTuple):
    """Observed steps of tracks, arranged for :func:`moves_log_likelihood`.

    Attributes
    ----------
    goal_index : (N,) int
        Index of each track's goal in the goal batch.
    rows, cols : (N, T) int
        Cell of each step's start (padding: 0).
    move : (N, T) int
        ``0`` the cell repeats, ``1 + j`` a one-cell move along direction ``j``, ``-1``
        padding; ``5`` a forbidden step (counted as an outlier).
    goals : (G, 2) int
        The distinct goal cells.
    n_moves : int
        Number of observed steps.
    """

    goal_index: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    move: np.ndarray
    goals: np.ndarray
    n_moves: int


def move_observations(paths: list[np.ndarray]) -> MoveObservations:
    """Arrange per-track cell paths (goal = last cell) as :class:`MoveObservations`.

    Parameters
    ----------
    paths : list of (T_n + 1, 2) int
        Cells at successive epochs; consecutive cells equal or 4-adjacent. The goal is the
        last cell, and each path must reach it only at its end (see
        :func:`~are_stats.fitting.discretise_tracks`).

    Returns
    -------
    MoveObservations
    """
    paths = [np.asarray(p, np.int64).reshape(-1, 2) for p in paths]
    paths = [p for p in paths if len(p) >= 2]
    n = len(paths)
    t = max((len(p) - 1 for p in paths), default=1)
    rows = np.zeros((n, t), np.int64)
    cols = np.zeros((n, t), np.int64)
    move = np.full((n, t), -1, np.int64)
    ends = np.array([p[-1] for p in paths], np.int64).reshape(-1, 2)
    goals, gidx = np.unique(ends, axis=0, return_inverse=True)
    for i, p in enumerate(paths):
        d = np.diff(p, axis=0)
        code = np.full(len(d), 5, np.int64)
        code[(d == 0).all(axis=1)] = 0
        for j in range(4):
            code[(d[:, 0] == _DROW[j]) & (d[:, 1] == _DCOL[j])] = 1 + j
        rows[i, : len(d)] = p[:-1, 0]
        cols[i, : len(d)] = p[:-1, 1]
        move[i, : len(d)] = code
    return MoveObservations(gidx.reshape(-1), rows, cols, move, goals, int((move >= 0).sum()))


def moves_log_likelihood(
    policy: jax.Array,
    ok: jax.Array,
    slip: jax.Array,
    obs: MoveObservations | tuple[jax.Array, ...],
    *,
    eps: float = OUTLIER,
    per_track: bool = False,
) -> jax.Array:
    """Log-likelihood of observed cell paths under a soft policy (headings marginalised).

    Parameters
    ----------
    policy : (G, 4, 5, H, W)
        ``pi(a | row, col, h)`` per goal (:attr:`SoftSolution.policy`).
    ok : (4, 2, H, W) bool
        Free paths (as for :func:`soft_backward_induction`).
    slip : scalar float
        Slip probability.
    obs : MoveObservations
        Observed steps (:func:`move_observations`).
    eps : float
        Outlier probability of a step (mixed with a uniform law over 4 headings x 6 steps).
    per_track : bool
        Return ``(N,)`` per-track log-likelihoods instead of their sum.

    Returns
    -------
    scalar or (N,)
        ``sum_n log p(path_n)``.
    """
    gi, rows, cols, move = (jnp.asarray(x) for x in obs[:4])
    dtype = policy.dtype
    pmat = _slip_matrix(jnp.asarray(slip, dtype))
    blocked = 1.0 - jnp.asarray(ok[:, 0], dtype)  # (4 directions, H, W)
    # pi at each step start: (N, T, 4 headings, 5 actions)
    pi = policy[gi[:, None], :, :, rows, cols]
    blk = blocked[:, rows, cols]  # (4 j, N, T)
    p_blk = jnp.einsum("hj,jnt->nth", pmat, blk)  # forward blocked, per heading
    eye = jnp.eye(4, dtype=dtype)
    left = jnp.roll(eye, 1, axis=1)  # h -> h + 1
    right = jnp.roll(eye, -1, axis=1)
    same = (
        (pi[..., 0] + pi[..., 1] * p_blk)[..., None] * eye
        + pi[..., 3, None] * left
        + pi[..., 4, None] * right
    )
    # one-cell move along j keeps the heading: pi_fwd(h) P[h, j]
    pj = pmat[:, jnp.clip(move - 1, 0, 3)]  # (4 h, N, T)
    moved = (pi[..., 1] * jnp.moveaxis(pj, 0, -1))[..., None] * eye
    mv = move[..., None, None]
    tm = jnp.where(mv == 0, same, jnp.where((mv >= 1) & (mv <= 4), moved, 0.0))
    tm = (1 - eps) * tm + eps / 24.0
    tm = jnp.where((move < 0)[..., None, None], eye, tm)

    def fwd(
        carry: tuple[jax.Array, jax.Array], step: tuple[jax.Array, jax.Array]
    ) -> tuple[tuple[jax.Array, jax.Array], None]:
        alpha, ll = carry
        m, pad = step
        a = jnp.einsum("nh,nhk->nk", alpha, m)
        c = a.sum(axis=1)
        # a padding step is a factor of exactly 1: the carry passes unchanged (renormalising
        # alpha would add round-off, so a track's value would depend on the batch's longest)
        alpha = jnp.where(pad[:, None], alpha, a / c[:, None])
        return (alpha, jnp.where(pad, ll, ll + jnp.log(c))), None

    n = gi.shape[0]
    alpha0 = jnp.full((n, 4), 0.25, dtype)
    steps = (jnp.moveaxis(tm, 1, 0), jnp.moveaxis(move < 0, 1, 0))
    (_, ll), _ = jax.lax.scan(fwd, (alpha0, jnp.zeros(n, dtype)), steps)
    return ll if per_track else ll.sum()


@partial(jax.jit, static_argnames=("eps",))
def _per_track_jit(policy, ok, slip, gi, rows, cols, move, eps):
    return moves_log_likelihood(policy, ok, slip, (gi, rows, cols, move), eps=eps, per_track=True)


def _pow2(n: int, lo: int) -> int:
    return max(lo, 1 << (max(int(n), 1) - 1).bit_length())


def track_log_likelihoods(
    policy: npt.ArrayLike,
    ok: npt.ArrayLike,
    slip: float,
    obs: MoveObservations | tuple[np.ndarray, ...],
    *,
    eps: float = OUTLIER,
) -> np.ndarray:
    """Per-track log-likelihoods of :func:`moves_log_likelihood` (``per_track=True``) for
    host arrays, by one compiled program per shape bucket (issue 29: called op by op, a
    criticism's batches of changing sizes compiled some 40 one-operation programs each).

    The tracks are padded to a power of two (at least 16) with tracks of no step, the
    steps to a power of two (at least 8) with padding steps (a factor of exactly 1: a
    track's value does not depend on the batch's longest) and the goals to a multiple of
    :data:`GOAL_BUCKET` with zero policies that no track uses; the values are those of
    :func:`moves_log_likelihood`.

    Parameters
    ----------
    policy : (G, 4, 5, H, W) float
        The soft policy per goal (:attr:`SoftSolution.policy`).
    ok : (4, 2, H, W) bool
        Free paths (:func:`~are_stats.behaviour.path_free`).
    slip : float
        Slip probability.
    obs : MoveObservations or (goal_index (N,), rows (N, T), cols (N, T), move (N, T))
        Observed steps (:func:`move_observations`).
    eps : float
        Outlier probability of a step.

    Returns
    -------
    (N,) float64
        ``log p(path_n)`` of each track.
    """
    pol = np.asarray(policy)
    gi, rows, cols, move = (np.asarray(x) for x in obs[:4])
    n, t = move.shape
    g = pol.shape[0]
    n_b, t_b, g_b = _pow2(n, 16), _pow2(t, 8), -(-g // GOAL_BUCKET) * GOAL_BUCKET

    def padded(x: np.ndarray, fill: int) -> np.ndarray:
        out = np.full((n_b, t_b), fill, np.int64)
        out[:n, :t] = x
        return out

    gi_b = np.zeros(n_b, np.int64)
    gi_b[:n] = gi
    if g_b > g:
        pol = np.concatenate([pol, np.zeros((g_b - g, *pol.shape[1:]), pol.dtype)])
    ll = _per_track_jit(
        pol,
        np.asarray(ok),
        np.asarray(slip, pol.dtype),
        gi_b,
        padded(rows, 0),
        padded(cols, 0),
        padded(move, -1),
        float(eps),
    )
    return np.asarray(ll, np.float64)[:n]
