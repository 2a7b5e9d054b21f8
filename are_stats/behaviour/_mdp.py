"""The finite-horizon MDP H_A(t) = {D, S, A_s, p_t, r_t} of the ARE paper (Sec. 3.2).

Dynamics (DECISIONS.md items 6 and 7)
-------------------------------------
* **Grid axes.** ``occupied[row, col]`` with ``row`` along +y (north) and ``col`` along +x
  (east), as in a ROS ``nav_msgs/OccupancyGrid`` (cell ``(0, 0)`` at the map origin).
* **States** ``s = (row, col, h)`` with heading ``h`` in ``{0: east (+x, yaw 0),
  1: north (+y, pi/2), 2: west (pi), 3: south (3 pi/2)}``. Dense exports order them as
  ``s = (row * W + col) * 4 + h`` over *all* cells; occupied cells are absorbing with zero
  reward (they are never entered).
* **Actions** (in this order, which also breaks ties): ``0 stay``, ``1 forward`` (one cell
  along the heading), ``2 run`` (two cells), ``3 left`` (``h -> h + 1``), ``4 right``
  (``h -> h - 1``). Turns and stay are deterministic.
* **Slip.** A move of ``k`` cells (forward ``k = 1``, run ``k = 2``) goes ``k`` cells along
  the heading with probability ``1 - slip`` and ``k`` cells along the adjacent heading
  ``h + 1`` or ``h - 1`` (sideways, heading kept) with probability ``slip / 2`` each.
* **Blocking.** An outcome whose path leaves the map or crosses an occupied cell (for a run,
  either of the two cells) is replaced by staying where the artefact is.
* **Goal.** For walk and run, the goal cell (all four headings) is absorbing: entering it
  earns ``goal_reward``, and nothing is earned after. Every action except ``stay`` costs
  ``step_cost``. The terminal value is ``V_d = 0``.

Because staying is always allowed and free, every value is ``>= 0``; an artefact that cannot
reach its goal keeps the value of stopping (0), and values grow with the horizon.

Backward induction
------------------
``V_d = 0`` and, for ``t = d - 1, ..., 0``,

.. math::

    Q_t(s, a) = r_t(s, a) + \\sum_{s'} p(s' | s, a) V_{t+1}(s'), \\quad
    V_t(s) = \\max_a Q_t(s, a), \\quad \\pi_t(s) = \\arg\\max_a Q_t(s, a).

The sum is a stencil: shifted copies of ``V_{t+1}`` (``jnp.pad`` + static slices) selected
by precomputed "path is free" masks, never a dense ``S x S`` matrix. The epochs run in one
``fori_loop`` writing each epoch's policy (and values) in place into donated output buffers,
reused from finished solutions (no page faults); a batch of artefacts with different goals,
behaviours and horizons runs one item at a time, split across the local devices (XLA host
devices: one per core) when there are several (horizons are padded to the largest; epochs
beyond an item's horizon keep the terminal value and the policy ``stay``).
"""

from __future__ import annotations

import functools
import math
import threading
import weakref
from collections.abc import Callable, Sequence
from typing import NamedTuple, TypedDict, TypeVar

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from are_stats._checks import check_array, check_nonnegative, check_probability, describe
from are_stats.behaviour._rewards import (
    ACTIONS,
    FORWARD,
    HEADINGS,
    LEFT,
    RIGHT,
    RUN,
    STAY,
    allowed_actions,
)
from are_stats.behaviour._xla import jit_with_options, padded_size
from are_stats.environment import OccupancyGrid

__all__ = ["GridMDP", "MDPSolution", "backward_induction", "path_free"]

_DROW = np.array([d[0] for d in HEADINGS])
_DCOL = np.array([d[1] for d in HEADINGS])
#: Store every V_t in solve() when it takes at most this many bytes; else recompute on demand.
_VALUES_BYTES = 64 * 2**20
_DENSE_MAX_STATES = 20_000
#: Tie-breaking order of the moves; ``stay`` wins only when strictly better (by ``tie_tol``).
_MOVE_ORDER = (RUN, FORWARD, LEFT, RIGHT)
#: Relative tolerance of that comparison per dtype (a few ulps of the largest value).
_TIE_RTOL = {"float32": 1e-5, "float64": 1e-12}


def _occupancy(occupied: npt.ArrayLike | OccupancyGrid) -> np.ndarray:
    """The boolean occupancy array of ``occupied`` (an array or an OccupancyGrid-like object)."""
    if hasattr(occupied, "free"):  # OccupancyGrid: unknown cells are not free (DECISIONS 4)
        occupied = ~np.asarray(occupied.free, dtype=bool)
    elif hasattr(occupied, "occupied"):
        occupied = occupied.occupied
    a = np.asarray(occupied)
    if a.ndim != 2 or a.size == 0:
        raise ValueError(f"occupied: expected a non-empty 2-d (H, W) array, got {describe(a)}")
    if a.dtype != bool:
        if not np.isin(a, (0, 1)).all():
            raise ValueError(f"occupied: expected a boolean (H, W) array, got {describe(a)}")
        a = a.astype(bool)
    return a


def path_free(occupied: np.ndarray) -> np.ndarray:
    """Which forward moves stay on free cells (the MDP's blocking rule, shared by the
    samplers and the behaviour fit).

    Parameters
    ----------
    occupied : (H, W) bool

    Returns
    -------
    ok : (4, 2, H, W) bool
        ``ok[j, k - 1, r, c]``: moving ``k`` in {1, 2} cells from ``(r, c)`` along heading
        ``j`` crosses only free cells inside the grid.
    """
    h, w = occupied.shape
    free = np.zeros((h + 4, w + 4), dtype=bool)
    free[2:-2, 2:-2] = ~occupied
    ok = np.ones((4, 2, h, w), dtype=bool)
    for j in range(4):
        for k in (1, 2):
            for m in range(1, k + 1):
                r0, c0 = 2 + m * _DROW[j], 2 + m * _DCOL[j]
                ok[j, k - 1] &= free[r0 : r0 + h, c0 : c0 + w]
    return ok


def _solve_one(
    ok: jax.Array,
    occupied: jax.Array,
    goal: jax.Array,
    allow: jax.Array,
    horizon: jax.Array,
    follow: jax.Array | None,
    slip: jax.Array,
    step_cost: jax.Array,
    goal_reward: jax.Array,
    tie_tol: jax.Array,
    item: jax.Array,
    out: _Outputs,
    n_epochs: int | jax.Array,
    use_run: bool,
) -> _Outputs:
    """Backward induction for batch item ``item``, written into its rows of ``out``.

    ``out`` holds the batch's output buffers (see :class:`_Outputs`); the epochs run in a
    ``fori_loop`` that writes each epoch's policy (and values) in place, so a solve
    allocates nothing the size of its outputs (reused, donated buffers are never touched by
    the kernel's page faults again). ``follow`` is the item's ``(D, H, W)`` rewards or None.

    Inside the loop each heading is one flat plane of the grid padded by two cells on every
    side (``N = (H + 4)(W + 4)`` values, zero border). A shift by ``(dr, dc)`` cells is then a
    contiguous slice at offset ``dr (W + 4) + dc``, and every epoch is a few vectorised loops
    over the index range ``[m, N - m)``, ``m = 2 (W + 4)``: the grid's rows at full padded
    width (the carry holds only that range). Masks enter as arithmetic where possible
    (``+ penalty``, ``* keep``), which XLA's CPU backend vectorises better than selects.
    Policy and values are stored "wide", ``(..., H, W + 4)`` with the grid in columns
    ``2 .. W + 1``, so that the caller can crop them without a copy.

    ``n_epochs`` (``D``) may be a traced scalar: the loop then runs ``D`` epochs into buffers
    of any ``D' >= D`` epochs (their epochs past ``D`` are left as they were), so that one
    program serves every ``D`` up to ``D'`` with the same bits (each epoch's arithmetic does
    not depend on ``D``; the padding epochs are never run).
    """
    with_policy, store_values = out.policy is not None, out.values is not None
    dtype = slip.dtype
    h_, w_ = goal.shape
    wp_ = w_ + 4
    n = (h_ + 4) * wp_
    m = 2 * wp_

    def flat(x: jax.Array, fill: bool | float) -> jax.Array:
        """``(..., H, W)`` -> ``(..., N)`` padded with ``fill``."""
        pad = [(0, 0)] * (x.ndim - 2) + [(2, 2), (2, 2)]
        x = jnp.pad(x, pad, constant_values=fill)
        return x.reshape(*x.shape[:-2], n)

    def unflat(x: jax.Array) -> jax.Array:
        """``(..., N - 2m)`` interior -> wide ``(..., H, W + 4)``."""
        return x.reshape(*x.shape[:-1], h_, wp_)

    ok_f = flat(ok, False)[..., m : n - m]  # (4, 2, L)
    keep = flat(~(occupied | goal), False)[m : n - m]
    bonus = flat(jnp.where(goal, goal_reward, jnp.zeros((), dtype)), 0.0)
    # rewards can only be collected on free cells; with W = 0 on every blocked cell (and on
    # the zero border), a one-cell move needs no mask: sum_j p_j W(s + d_j) plus the
    # blocked probability mass times W(s)
    free = ~occupied
    follow_f = None if follow is None else flat(jnp.where(free, follow, 0.0), 0.0)
    # per-action additive term: -cost when allowed, -inf when not (stay is always allowed)
    cost = jnp.stack([jnp.zeros((), dtype)] + [step_cost] * 4)
    penalty = jnp.where(allow, -cost, jnp.asarray(-jnp.inf, dtype))
    p_main, p_side = 1 - slip, slip / 2
    offsets = [(int(_DROW[j]) * wp_ + int(_DCOL[j])) for j in range(4)]
    blocked = 1 - ok_f.astype(dtype)  # (4, 2, L)
    p_blocked = [
        [
            p_main * blocked[h, k] + p_side * (blocked[(h + 1) % 4, k] + blocked[(h - 1) % 4, k])
            for k in range(2)
        ]
        for h in range(4)
    ]

    def step(v: tuple[jax.Array, ...], xs: tuple[jax.Array, jax.Array | None]):
        t, reward_t = xs
        extra = bonus if reward_t is None else bonus + reward_t
        wn = [jnp.pad(x, (m, m)) + extra for x in v]
        inner = [x[m : n - m] for x in wn]
        keep_t = keep & (t < horizon)
        keep_v = keep_t.astype(dtype)
        keep_p = keep_t.astype(jnp.int8)

        def move(h: int, k: int) -> jax.Array:
            if k == 1:

                def shifted(j: int) -> jax.Array:
                    return wn[h][m + offsets[j] : n - m + offsets[j]]

                stay_part = p_blocked[h][0] * inner[h]
            else:

                def shifted(j: int) -> jax.Array:
                    o = 2 * offsets[j]
                    return jnp.where(ok_f[j, 1], wn[h][m + o : n - m + o], jnp.zeros((), dtype))

                # sliced from wn here, not taken from ``inner``: a conditional's operands
                # are materialised, and four interior copies per epoch cost ~10 % of a solve
                stay_part = p_blocked[h][1] * wn[h][m : n - m]
            return (
                p_main * shifted(h)
                + p_side * (shifted((h + 1) % 4) + shifted((h - 1) % 4))
                + stay_part
            )

        def runs(_: None) -> list[jax.Array | None]:
            return [move(h, 2) + penalty[2] if use_run else None for h in range(4)]

        q_fwd = [move(h, 1) + penalty[1] for h in range(4)]
        if use_run:
            # The run values (three masked two-cell shifts, the dearest action) are computed
            # in their own loops and written to memory: fusion does not cross a conditional
            # (whose predicate is always true). XLA's CPU backend writes the values and the
            # policy in two loops that would otherwise both recompute them, and even the
            # values alone run faster as two simpler loops than as one that does everything.
            # Materialising the forward values too costs more in memory traffic than it saves.
            q_run = jax.lax.cond(t >= 0, runs, runs, None)
        else:
            q_run = runs(None)
        v_new, pols = [], []
        for h in range(4):
            qs = [
                inner[h],
                q_fwd[h],
                q_run[h],
                inner[(h + 1) % 4] + penalty[3],  # left: h -> h + 1
                inner[(h - 1) % 4] + penalty[4],  # right: h -> h - 1
            ]
            # best move, ties to the first of run, forward, left, right
            order = [a for a in _MOVE_ORDER if qs[a] is not None]
            best = qs[order[0]]
            arg = jnp.full(best.shape, order[0], jnp.int8)
            for a in order[1:]:
                better = qs[a] > best
                best = jnp.where(better, qs[a], best)
                arg = jnp.where(better, jnp.int8(a), arg)
            # stay only when strictly better than every move by more than tie_tol
            stay = qs[STAY] > best + tie_tol
            arg = jnp.where(stay, jnp.int8(STAY), arg)
            best = jnp.maximum(best, qs[STAY])
            v_new.append(best * keep_v)
            pols.append(arg * keep_p)
        # two headings per byte (actions < 16): half the memory a fresh output has to touch
        packed = (pols[0] | (pols[1] << 4), pols[2] | (pols[3] << 4)) if with_policy else None
        return tuple(v_new), (packed, tuple(v_new) if store_values else None)

    def put(buf: jax.Array, x: jax.Array, t: jax.Array) -> jax.Array:
        """``buf[item, t] = x`` in place (x flat over the interior rows)."""
        zero = jnp.zeros((), t.dtype)
        return jax.lax.dynamic_update_slice(buf, x.reshape(1, 1, h_, wp_), (item, t, zero, zero))

    def epoch(i: jax.Array, carry: tuple) -> tuple:
        v, pol, val = carry
        t = n_epochs - 1 - i
        reward_t = None if follow_f is None else jax.lax.dynamic_index_in_dim(follow_f, t, 0, False)
        v, (packed, v_t) = step(v, (t, reward_t))
        if with_policy:
            pol = tuple(put(b, x, t) for b, x in zip(pol, packed, strict=True))
        if store_values:
            val = tuple(put(b, x, t) for b, x in zip(val, v_t, strict=True))
        return v, pol, val

    v_terminal = tuple(jnp.zeros(n - 2 * m, dtype) for _ in range(4))
    val = out.values
    if store_values:  # V_D = 0
        last = jnp.zeros(n - 2 * m, dtype)
        val = tuple(put(b, last, jnp.asarray(n_epochs)) for b in val)
    v0, pol, val = jax.lax.fori_loop(0, n_epochs, epoch, (v_terminal, out.policy, val))
    zero = jnp.zeros((), item.dtype)
    v0_all = jax.lax.dynamic_update_slice(
        out.v0, unflat(jnp.stack(v0))[None], (item, zero, zero, zero)
    )
    return _Outputs(v0_all, pol, val)


def backward_induction(
    ok: jax.Array,
    occupied: jax.Array,
    goals: jax.Array,
    allow: jax.Array,
    horizons: jax.Array,
    follow: jax.Array | None,
    slip: jax.Array,
    step_cost: jax.Array,
    goal_reward: jax.Array,
    tie_tol: jax.Array,
    *,
    n_epochs: int,
    store_values: bool = False,
    use_run: bool = True,
    with_policy: bool = True,
) -> tuple[jax.Array, jax.Array | None, jax.Array | None]:
    """Batched backward induction on the grid MDP (pure; the caller jits).

    Parameters
    ----------
    ok : (4, 2, H, W) bool
        ``ok[j, k - 1]``: a move of ``k`` cells along heading ``j`` stays on free cells.
    occupied : (H, W) bool
        Occupied cells (absorbing, value 0).
    goals : (B, H, W) bool
        Goal cells of each artefact (absorbing; entering them earns ``goal_reward``).
    allow : (B, 5) bool
        Allowed actions of each artefact's behaviour.
    horizons : (B,) int
        Horizons ``d_b <= n_epochs``.
    follow : (B, n_epochs, H, W) float or None
        Time-varying rewards ``r_t`` for arriving at a cell at epoch ``t + 1``.
    slip, step_cost, goal_reward : scalar float
        Slip probability, cost of every non-stay action, goal reward; their dtype
        (float32 or float64) is the dtype of the computation.
    tie_tol : scalar float
        The policy stays only where ``stay`` beats every move by more than ``tie_tol``
        (values are exact maxima either way). Without discounting, waiting is free once
        the horizon is long enough, so exact ties between ``stay`` and the best move are
        common; they are broken towards moving (then run, forward, left, right).
    n_epochs : int
        Number of epochs ``D = max_b d_b`` (static).
    store_values : bool
        Also return every ``V_t`` (static).
    use_run : bool
        Compute the run action (static; false when no behaviour allows it).
    with_policy : bool
        Also return the policy (static). The values alone take about two thirds of the time.

    Returns
    -------
    v0 : (B, 4, H, W)
        ``V_0``, the value with the whole horizon to go.
    policy : (B, n_epochs, 4, H, W) int8 or None
        ``pi_t`` (action indices) when ``with_policy``.
    values : (B, n_epochs + 1, 4, H, W) or None
        ``V_t`` for ``t = 0 .. n_epochs`` when ``store_values``.
    """
    shapes = _output_shapes(
        goals.shape[0], n_epochs, goals.shape[1:], slip.dtype, store_values, with_policy
    )
    v0, policy, values = _backward_induction_wide(
        ok,
        occupied,
        goals,
        allow,
        horizons,
        follow,
        slip,
        step_cost,
        goal_reward,
        tie_tol,
        _zeros(shapes),
        n_epochs=n_epochs,
        use_run=use_run,
    )
    v0 = v0[..., 2:-2]

    def crop(x: tuple[jax.Array, ...] | None) -> jax.Array | None:
        if x is None:
            return None
        return jnp.stack(x, axis=2)[..., 2:-2]

    if policy is not None:
        policy = _unpack_policy(policy)
    return v0, crop(policy), crop(values)


#: A policy plane: a NumPy array, or a JAX one inside the compiled solver.
_Plane = TypeVar("_Plane", np.ndarray, jax.Array)


def _unpack_policy(packed: Sequence[_Plane]) -> tuple[_Plane, ...]:
    """Per heading action planes from the two packed ones (low nibble: heading 0 or 2)."""
    return tuple((packed[h // 2] >> (4 * (h % 2))) & 15 for h in range(4))


class _Outputs(NamedTuple):
    """The solver's output buffers for a batch of ``B`` items, wide (``W + 4`` columns).

    ``v0`` is ``(B, 4, H, W + 4)``; ``policy`` two ``(B, D, H, W + 4)`` int8 planes, the
    actions of headings ``2k`` (low four bits) and ``2k + 1`` (high four bits) in plane ``k``,
    or None; ``values`` four ``(B, D + 1, H, W + 4)`` planes (one per heading) or None.
    """

    v0: jax.Array | np.ndarray
    policy: tuple[jax.Array, ...] | tuple[_Batch, ...] | None
    values: tuple[jax.Array, ...] | tuple[_Batch, ...] | None


def _output_shapes(
    b: int,
    n_epochs: int,
    shape: tuple[int, int],
    dtype: npt.DTypeLike,
    store_values: bool,
    with_policy: bool,
) -> _Outputs:
    """The :class:`_Outputs` of a batch of ``b`` items, as ``jax.ShapeDtypeStruct`` leaves."""
    h, w = shape
    wide = (h, w + 4)
    sds = jax.ShapeDtypeStruct
    return _Outputs(
        v0=sds((b, 4, *wide), dtype),
        policy=(sds((b, n_epochs, *wide), np.int8),) * 2 if with_policy else None,
        values=(sds((b, n_epochs + 1, *wide), dtype),) * 4 if store_values else None,
    )


def _zeros(shapes: _Outputs) -> _Outputs:
    """Fresh zero buffers of ``shapes`` (inside a trace: the pure :func:`backward_induction`)."""
    return jax.tree.map(lambda sd: jnp.zeros(sd.shape, sd.dtype), shapes)


def _backward_induction_wide(
    ok: jax.Array,
    occupied: jax.Array,
    goals: jax.Array,
    allow: jax.Array,
    horizons: jax.Array,
    follow: jax.Array | None,
    slip: jax.Array,
    step_cost: jax.Array,
    goal_reward: jax.Array,
    tie_tol: jax.Array,
    out: _Outputs,
    *,
    n_epochs: int | jax.Array,
    use_run: bool = True,
    n_items: jax.Array | None = None,
) -> _Outputs:
    """:func:`backward_induction` into the output buffers ``out`` (:class:`_Outputs`, batch-major
    and wide), one item after the other, every epoch written in place.

    ``n_epochs`` may be traced (see :func:`_solve_one`); ``n_items`` (traced, default all)
    solves only the first ``n_items`` items, leaving the other rows of ``out`` as they were.
    """
    fn = functools.partial(_solve_one, n_epochs=n_epochs, use_run=use_run)

    def one(b: jax.Array, acc: _Outputs) -> _Outputs:
        pick = functools.partial(jax.lax.dynamic_index_in_dim, index=b, keepdims=False)
        f = None if follow is None else pick(follow)
        return fn(
            ok,
            occupied,
            pick(goals),
            pick(allow),
            pick(horizons),
            f,
            slip,
            step_cost,
            goal_reward,
            tie_tol,
            b,
            acc,
        )

    stop = goals.shape[0] if n_items is None else n_items
    return jax.lax.fori_loop(0, stop, one, out)


#: XLA's CPU backend vectorises for 256-bit registers by default; where the CPU has 512-bit
#: ones (AVX-512) the stencil loops run about 1.5x faster with them (results are identical:
#: no fast-math). Elsewhere LLVM keeps the widest width the CPU has.
_COMPILER_OPTIONS = {"xla_cpu_prefer_vector_width": 512}


class _SolverInputs(TypedDict):
    """What ``GridMDP.solve`` hands the compiled solver (NumPy: the call transfers them)."""

    ok: np.ndarray
    occupied: np.ndarray
    goals: np.ndarray
    allow: np.ndarray
    horizons: np.ndarray
    follow: np.ndarray | None
    slip: np.ndarray
    step_cost: np.ndarray
    goal_reward: np.ndarray
    tie_tol: np.ndarray
    n_epochs: int
    use_run: bool


_SHARED = ("ok", "occupied", "slip", "step_cost", "goal_reward", "tie_tol")


@functools.lru_cache(maxsize=32)
def _mesh(n_dev: int) -> Mesh:
    return Mesh(np.array(jax.local_devices()[:n_dev]), ("b",))


@functools.lru_cache(maxsize=32)
def _sharded_jit(n_dev: int, use_run: bool, follow: bool) -> jax.stages.Wrapped:
    """:func:`_backward_induction_wide` with the batch split across ``n_dev`` local devices.

    The epochs ``n_epochs`` (a shared ``()`` int32) and each device's number of items
    ``counts`` (``(n_dev,)`` int32, split with the batch) are traced: one program serves
    every call whose padded shapes (:func:`_padded_shapes`) agree.
    """

    def body(
        goals,
        allow,
        horizons,
        follow_,
        counts,
        out,
        ok,
        occupied,
        slip,
        step_cost,
        goal_reward,
        tie_tol,
        n_epochs,
    ):
        return _backward_induction_wide(
            ok,
            occupied,
            goals,
            allow,
            horizons,
            follow_ if follow else None,
            slip,
            step_cost,
            goal_reward,
            tie_tol,
            out,
            n_epochs=n_epochs,
            use_run=use_run,
            n_items=counts[0],
        )

    batch, shared = PartitionSpec("b"), PartitionSpec()
    specs = (batch, batch, batch, batch if follow else shared, batch, batch)
    specs += (shared,) * (len(_SHARED) + 1)
    fn = jax.shard_map(body, mesh=_mesh(n_dev), in_specs=specs, out_specs=batch, check_vma=False)
    return jit_with_options(fn, donate_argnums=(5,), compiler_options=_COMPILER_OPTIONS)


def _round_up(n: int, step: int) -> int:
    return -(-n // step) * step


def _grid_size(n: int) -> int:
    """The padded size of a grid side of ``n`` cells: 8 or 16 cells up to 16, then a multiple
    of 4 up to 127 cells, of 8 up to 255, of 16 up to 511... (``2^(bits(n) - 5)``): at most
    3/17 more cells per side beyond 16 cells, 1/16 from 64 on (each padded cell costs a cell's
    work every epoch; on small grids the call's overhead dominates)."""
    if n <= 16:
        return 8 if n <= 8 else 16
    return _round_up(n, max(4, 2 ** (n.bit_length() - 5)))


def _epoch_size(n: int) -> int:
    """The padded number of epochs of the buffers: 16, 24, 32, 48, 64, 96... (:func:`padded_size`);
    padded epochs cost buffer memory only (they are never run)."""
    return padded_size(n, 16)


#: Items a device solves per call: the smallest of these that holds its share (a device
#: with fewer items runs fewer loop iterations; the slots past them cost buffer memory only).
#: A larger batch is solved in several calls of the largest.
_SLOTS = (1, 4, 16, 64)
#: A solve of several items whose padded outputs take at most this many bytes on
#: ``_SLOTS[1]`` items a device runs on every local device with at least that many slots
#: (one program for 2 to ``_SLOTS[1] * n_devices`` items; a device with no items runs an
#: empty loop).
_SMALL_BYTES = 8 * 2**20
#: At most this many bytes of output buffers per call (fewer slots, more calls, beyond).
_CALL_BYTES = 128 * 2**20


def _padded_shapes(b: int, n_all: int, item_bytes: int) -> tuple[int, int]:
    """``(n_dev, slots)``: the devices and items per device of each call solving ``b`` items
    whose padded outputs take ``item_bytes`` each, on ``n_all`` local devices."""
    small = n_all * _SLOTS[1] * item_bytes <= _SMALL_BYTES
    # a lone item runs on one device: a call on several costs ~1 ms more to dispatch
    n_dev = n_all if small and b > 1 else max(1, min(n_all, b))
    per = -(-b // n_dev)
    slots = next((k for k in _SLOTS if k >= per), _SLOTS[-1])
    if small:
        slots = max(slots, _SLOTS[1])
    while slots > 1 and n_dev * slots * item_bytes > _CALL_BYTES:
        slots = _SLOTS[_SLOTS.index(slots) - 1]
    return n_dev, slots


class _BufferPool:
    """Output buffers of finished solutions, kept for the next solve of the same shapes.

    The solver writes its outputs in place into buffers it is given (donated). A fresh
    buffer costs a page fault per 4 KiB page on its first write (about 1.3 ms of a 5 ms
    solve for the 2 MB policy of a 100 x 100 grid and 100 epochs), every call, since the
    allocator hands large blocks back to the system; a reused one costs nothing. A
    :class:`MDPSolution` gives its buffers back when it is garbage collected (its NumPy
    views of them die with it); at most ``max_bytes`` are kept.
    """

    def __init__(self, max_bytes: int = 256 * 2**20) -> None:
        self.max_bytes = max_bytes
        self._free: dict[tuple, list[jax.Array]] = {}
        self._bytes = 0
        # reentrant: a collection inside take() or give() may run a finalizer that gives
        self._lock = threading.RLock()

    def take(self, key: tuple, make: Callable[[], jax.Array]) -> jax.Array:
        with self._lock:
            stack = self._free.get(key)
            if stack:
                buf = stack.pop()
                self._bytes -= buf.nbytes
                return buf
        return make()

    def give(self, key: tuple, buf: jax.Array) -> None:
        if buf.is_deleted():
            return
        with self._lock:
            if self._bytes + buf.nbytes <= self.max_bytes:
                self._free.setdefault(key, []).append(buf)
                self._bytes += buf.nbytes


_POOL = _BufferPool()


def _outputs(shapes: _Outputs, sharding: jax.sharding.Sharding) -> tuple[_Outputs, list[tuple]]:
    """Output buffers for ``shapes`` (from the pool, else fresh zeros) and their pool keys."""
    keys: list[tuple] = []

    def get(sd: jax.ShapeDtypeStruct) -> jax.Array:
        key = (sd.shape, np.dtype(sd.dtype).str, sharding)
        keys.append(key)
        return _POOL.take(key, lambda: jax.device_put(np.zeros(sd.shape, sd.dtype), sharding))

    out = jax.tree.map(get, shapes)
    return out, keys


class _Batch:
    """A batch-major array kept as the pieces the devices wrote (views, no gathering copy).

    ``parts[k]`` holds items ``starts[k] .. starts[k + 1] - 1`` (the last may hold padding
    items past ``n``).
    """

    def __init__(self, parts: list[np.ndarray], n: int) -> None:
        self.parts = parts
        self.n = n
        self.starts = np.cumsum([0] + [len(x) for x in parts])

    def take(self, items: np.ndarray, *index: np.ndarray) -> np.ndarray:
        """``a[items, *index]`` for 1-d integer arrays of equal length."""
        part = np.searchsorted(self.starts, items, side="right") - 1
        out = np.empty(len(items), self.parts[0].dtype)
        for k in np.unique(part).tolist():
            sel = part == k
            out[sel] = self.parts[k][(items[sel] - self.starts[k], *(i[sel] for i in index))]
        return out


def _joined(batches: tuple[_Batch, ...], fn: Callable[..., np.ndarray]) -> np.ndarray:
    """``fn`` applied part by part to ``batches`` (aligned), joined along the batch axis."""
    n = batches[0].n
    pieces = [fn(*xs) for xs in zip(*(b.parts for b in batches), strict=True)]
    return pieces[0][:n] if len(pieces) == 1 else np.concatenate(pieces)[:n]


def _run_solver(
    inputs: _SolverInputs, *, store_values: bool, with_policy: bool
) -> tuple[_Outputs, Callable[[], None]]:
    """Run the compiled solver on ``inputs`` (NumPy arrays, as built by ``GridMDP.solve``).

    With several local devices (``XLA_FLAGS=--xla_force_host_platform_device_count=N``, which
    the CLI sets; one per core) a batch is split across them: each device solves its share
    one item at a time, in parallel. Results are identical to a single-device solve.

    One compiled program serves many sizes: the grid is padded with occupied cells (rows
    below, columns to the right; :func:`_grid_size`), the buffers' epochs to a few sizes
    (:func:`_epoch_size`) and each device's items to a few slot counts (:data:`_SLOTS`,
    :func:`_padded_shapes`; a larger batch runs as several calls). The number of epochs and
    each device's number of items are traced, so padded items and epochs are never
    computed. A padded cell is blocked exactly as the outside of the map is (the stencil
    reads +0 there either way, and every cell's arithmetic is elementwise), so the real
    cells' values and policy are bit for bit those of an unpadded solve.

    Returns the outputs (``v0`` a NumPy copy, the policy and value planes :class:`_Batch`
    views of the device buffers, cropped to the items, epochs and grid) and ``release()``,
    which hands the buffers back to the pool once nothing refers to those views any more.
    """
    b = inputs["goals"].shape[0]
    dtype = np.dtype(inputs["slip"].dtype)
    h, w = inputs["occupied"].shape
    n_epochs, use_run = int(inputs["n_epochs"]), bool(inputs["use_run"])
    d_pad, hp, wp = _epoch_size(n_epochs), _grid_size(h), _grid_size(w)
    one = _output_shapes(1, d_pad, (hp, wp), dtype, store_values, with_policy)
    item_bytes = sum(math.prod(x.shape) * x.dtype.itemsize for x in jax.tree.leaves(one))
    n_dev, slots = _padded_shapes(b, jax.local_device_count(), item_bytes)

    def grid(x: np.ndarray, fill: bool | float, epochs: int | None = None) -> np.ndarray:
        """``x`` with its trailing ``(H, W)`` axes padded to ``(H', W')`` with ``fill`` (and
        its axis 1 to ``epochs``); zeros and a copy (``np.pad`` costs ~0.1 ms a call)."""
        shape = (*x.shape[:-2], hp, wp) if epochs is None else (x.shape[0], epochs, hp, wp)
        if shape == x.shape:
            return x
        y = np.full(shape, fill, x.dtype)
        y[tuple(slice(k) for k in x.shape)] = x
        return y

    follow = inputs["follow"] is not None
    shared = [
        grid(inputs["ok"], False),
        grid(inputs["occupied"], True),
        *(inputs[name] for name in _SHARED[2:]),
        np.asarray(n_epochs, np.int32),
    ]
    sharding = NamedSharding(_mesh(n_dev), PartitionSpec("b"))
    shapes = _output_shapes(n_dev * slots, d_pad, (hp, wp), dtype, store_values, with_policy)
    fn = _sharded_jit(n_dev, use_run, follow)
    outs, counts, keys = [], [], []
    for first in range(0, b, n_dev * slots):
        n = min(b - first, n_dev * slots)
        per = -(-n // n_dev)
        count = np.clip(n - per * np.arange(n_dev), 0, per).astype(np.int32)
        # padded position -> item (slots past a device's count repeat a valid item, unused)
        k, j = np.divmod(np.arange(n_dev * slots), slots)
        src = first + np.minimum(k * per + j, n - 1)
        if follow:
            f = grid(inputs["follow"][src], 0.0, d_pad)
        else:
            f = np.zeros(n_dev * slots, np.int8)  # placeholder, unused
        batched = [
            grid(inputs["goals"][src], False),
            inputs["allow"][src],
            inputs["horizons"][src],
            f,
            count,
        ]
        bufs, call_keys = _outputs(shapes, sharding)
        outs.append(fn(*batched, bufs, *shared))
        counts += count.tolist()
        keys += call_keys

    def parts(xs: list[jax.Array], epochs: int | None = None) -> list[np.ndarray]:
        """The devices' items of the calls' ``xs`` (views), cropped to ``epochs`` and the grid."""
        crop = (slice(None),) if epochs is None else (slice(None), slice(epochs))
        shards = [
            sh
            for x in xs
            for sh in sorted(x.addressable_shards, key=lambda sh: sh.index[0].start or 0)
        ]
        return [
            np.asarray(sh.data)[:c][(*crop, Ellipsis, slice(h), slice(2, w + 2))]
            for sh, c in zip(shards, counts, strict=True)
            if c
        ]

    leaves = [leaf for out in outs for leaf in jax.tree.leaves(out)]

    def release() -> None:
        for key, buf in zip(keys, leaves, strict=True):
            _POOL.give(key, buf)

    def planes(name: str, epochs: int) -> tuple[_Batch, ...] | None:
        if getattr(outs[0], name) is None:
            return None
        n_planes = len(getattr(outs[0], name))
        return tuple(
            _Batch(parts([getattr(out, name)[p] for out in outs], epochs), b)
            for p in range(n_planes)
        )

    v0 = np.concatenate(parts([out.v0 for out in outs]))  # a copy: the buffers go back
    return _Outputs(v0, planes("policy", n_epochs), planes("values", n_epochs + 1)), release


class MDPSolution:
    """The result of :meth:`GridMDP.solve` for a batch of ``B`` artefacts.

    The policy is stored compactly, four bits per epoch and state (or, with
    ``solve(..., with_policy=False)``, computed on first access). ``V_0`` is always stored;
    the full ``V_t`` array is stored when it takes at most 64 MiB and otherwise recomputed
    (and cached) on the first access to :attr:`values`.

    Attributes
    ----------
    mdp : GridMDP
        The model that was solved.
    goals : (B, 2) int
        Goal cells ``(row, col)`` (``-1`` for behaviours without a goal).
    behaviours : tuple of str
        Behaviour of each artefact.
    horizons : (B,) int
        Horizon ``d_b`` of each artefact (epochs ``0 .. d_b``).
    v0 : (B, H, W, 4)
        ``V_0``, the value with the whole horizon to go.
    """

    def __init__(
        self,
        mdp: GridMDP,
        goals: np.ndarray,
        behaviours: tuple[str, ...],
        horizons: np.ndarray,
        v0: np.ndarray,
        policy: tuple[_Batch, ...] | None,
        values: tuple[_Batch, ...] | None,
        inputs: _SolverInputs,
        release: Callable[[], None] | None = None,
    ) -> None:
        self.mdp = mdp
        self.goals = goals
        self.behaviours = behaviours
        self.horizons = horizons
        self.v0 = np.moveaxis(v0, 1, -1)
        self._policy = policy
        self._values = values
        self._policy_full: np.ndarray | None = None
        self._values_full: np.ndarray | None = None
        self._inputs = inputs
        if release is not None:
            weakref.finalize(self, release)

    def _solve(self, *, store_values: bool, with_policy: bool) -> _Outputs:
        """Solve again (for what was not stored); the buffers go back to the pool with self."""
        out, release = _run_solver(self._inputs, store_values=store_values, with_policy=with_policy)
        weakref.finalize(self, release)
        return out

    @property
    def n_epochs(self) -> int:
        """Padded horizon ``D`` (``max_b d_b`` unless ``solve(..., n_epochs=...)``)."""
        return int(self._inputs["n_epochs"])

    def _policy_planes(self) -> tuple[_Batch, ...]:
        """The two packed ``(B, D, H, W)`` int8 policy planes (computed on first use).

        Plane ``k`` holds the actions of heading ``2k`` in its low four bits and of heading
        ``2k + 1`` in its high four bits.
        """
        if self._policy is None:
            self._policy = self._solve(store_values=False, with_policy=True).policy
        return self._policy

    def action(self, items: npt.ArrayLike, t: npt.ArrayLike, states: npt.ArrayLike) -> np.ndarray:
        """Actions ``pi_t(s)`` of batch items at their epochs and states ``(row, col, h)``.

        Parameters
        ----------
        items : (n,) int
            Batch items.
        t : (n,) int
            Epochs (``0 <= t < D``).
        states : (n, 3) int
            States ``(row, col, heading)``.

        Returns
        -------
        (n,) int8
            Action indices (see ``ACTIONS``).
        """
        planes = self._policy_planes()
        items, t = np.asarray(items), np.asarray(t)
        states = np.asarray(states)
        out = np.zeros(len(items), np.int8)
        # (the two planes are split into the same parts: look each item's part up once,
        # then each plane's bytes; a rollout asks once per epoch)
        starts = planes[0].starts
        part = np.searchsorted(starts, items, side="right") - 1
        high = states[:, 2] >= 2  # headings 2, 3: plane 1
        for k in np.unique(part).tolist():
            sel = part == k
            local, tk, hk = items[sel] - starts[k], t[sel], high[sel]
            rk, ck = states[sel, 0], states[sel, 1]
            packed = np.empty(len(local), planes[0].parts[k].dtype)
            for plane, on in ((0, ~hk), (1, hk)):
                packed[on] = planes[plane].parts[k][local[on], tk[on], rk[on], ck[on]]
            out[sel] = (packed >> (4 * (states[sel, 2] % 2))) & 15
        return out

    @property
    def policy(self) -> np.ndarray:
        """``(B, D, H, W, 4) int8``: ``policy[b, t, row, col, h]`` is the action at epoch t.

        Epochs ``t >= d_b`` (beyond an artefact's horizon) hold ``stay``. Unpacked on first
        access from the solver's two ``(B, D, H, W)`` planes (two headings per byte).
        """
        if self._policy_full is None:
            self._policy_full = _joined(
                self._policy_planes(), lambda *p: np.stack(_unpack_policy(p), axis=-1)
            )
        return self._policy_full

    @property
    def values(self) -> np.ndarray:
        """``(B, D + 1, H, W, 4)``: ``values[b, t]`` is ``V_t`` (index 0: whole horizon to go).

        Epochs ``t >= d_b`` hold the terminal value 0. For large problems the array is
        recomputed on first access (it takes ``B (D + 1) H W 4`` floats).
        """
        if self._values is None:
            self._values = self._solve(store_values=True, with_policy=False).values
        if self._values_full is None:
            self._values_full = _joined(self._values, lambda *v: np.stack(v, axis=-1))
        return self._values_full

    def __repr__(self) -> str:
        b = len(self.behaviours)
        h, w = self.mdp.shape
        return f"MDPSolution(batch={b}, n_epochs={self.n_epochs}, grid=({h}, {w}))"


class GridMDP:
    """The finite-horizon MDP H_A(t) of the ARE paper (Sec. 3.2) on an occupancy grid.

    See the module documentation (and ``docs/src/behaviour.md``) for the exact dynamics:
    headings, actions, slip and blocking rules.

    Parameters
    ----------
    occupied : (H, W) bool array or OccupancyGrid-like
        Occupied cells, ``occupied[row, col]`` with ``row`` along +y and ``col`` along +x.
        An object with a ``free`` (or ``occupied``) attribute, such as
        ``are_stats.OccupancyGrid``, is accepted: every cell that is not free (occupied or
        unknown) blocks. It is kept as :attr:`grid`.
    slip : float
        Probability in ``[0, 1)`` that a move goes sideways (``slip / 2`` to each side).
    step_cost : float
        Cost (>= 0) of every action except ``stay``.
    goal_reward : float
        Reward (>= 0) for entering the goal cell (walk and run).
    dtype : str
        ``"float32"`` (default, faster) or ``"float64"``.

    Raises
    ------
    ValueError
        On a malformed grid or parameters out of range.

    Examples
    --------
    >>> import numpy as np
    >>> mdp = GridMDP(np.zeros((5, 6), bool), slip=0.0)
    >>> sol = mdp.solve(goals=[[2, 5]], behaviours="walk", horizons=20)
    >>> sol.values.shape
    (1, 21, 5, 6, 4)
    """

    def __init__(
        self,
        occupied: npt.ArrayLike | OccupancyGrid,
        slip: float = 0.1,
        *,
        step_cost: float = 1e-3,
        goal_reward: float = 1.0,
        dtype: str = "float32",
    ) -> None:
        self.grid = occupied if not isinstance(occupied, np.ndarray | list) else None
        self.occupied = _occupancy(occupied)
        self.slip = float(check_probability("slip", slip, closed_right=False))
        self.step_cost = float(check_nonnegative("step_cost", step_cost))
        self.goal_reward = float(check_nonnegative("goal_reward", goal_reward))
        if dtype not in ("float32", "float64"):
            raise ValueError(f"dtype: expected 'float32' or 'float64', got {dtype!r}")
        self.dtype = dtype
        self._ok = path_free(self.occupied)

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape ``(H, W)``."""
        return self.occupied.shape  # type: ignore[return-value]

    @property
    def n_states(self) -> int:
        """Number of states ``H * W * 4`` (all cells, occupied ones included)."""
        h, w = self.shape
        return h * w * 4

    # ------------------------------------------------------------------ validation
    def _check_goal(self, name: str, goal: npt.ArrayLike) -> tuple[int, int]:
        g = check_array(name, goal, dtype=float)
        h, w = self.shape
        if g.shape != (2,) or not np.all(g == np.round(g)):
            raise ValueError(f"{name}: expected an integer cell (row, col), got {describe(g)}")
        r, c = int(g[0]), int(g[1])
        if not (0 <= r < h and 0 <= c < w):
            raise ValueError(f"{name}: expected a cell inside the {h} x {w} grid, got ({r}, {c})")
        if self.occupied[r, c]:
            raise ValueError(f"{name}: expected a free cell, got ({r}, {c}) which is an obstacle")
        return r, c

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        goals: npt.ArrayLike | Sequence[npt.ArrayLike | None] | None,
        behaviours: str | Sequence[str] = "walk",
        horizons: npt.ArrayLike = 100,
        *,
        follow: Sequence[npt.ArrayLike | None] | None = None,
        store_values: bool | None = None,
        n_epochs: int | None = None,
        with_policy: bool = True,
    ) -> MDPSolution:
        """Backward induction for a batch of artefacts.

        The compiled program is shared by nearby sizes: grids, horizons and batch sizes are
        padded to a few sizes inside (padded cells, epochs and items are blocked or never
        computed; the results are those of an unpadded solve, bit for bit).

        Parameters
        ----------
        goals : (B, 2) int or (2,) int
            Goal cell ``(row, col)`` of each artefact; ignored (may be ``None`` or ``-1``)
            for the ``follow`` and ``stop`` behaviours.
        behaviours : str or sequence of B str
            ``"walk"``, ``"run"``, ``"follow"`` or ``"stop"``.
        horizons : int or (B,) int
            Horizon ``d_b >= 0`` of each artefact in decision epochs.
        follow : sequence of B arrays or None
            For ``follow`` artefacts, the rewards ``r_t``, an ``(n, H, W)`` array with
            ``n >= d_b`` (see :func:`follow_rewards`); ``None`` for the others.
        store_values : bool or None
            Store every ``V_t`` now (``True``), never (``False``: recomputed on access), or
            when they take at most 64 MiB (``None``).
        n_epochs : int or None
            Pad the epochs to ``D = n_epochs >= max(horizons)`` (default ``max(horizons)``);
            the result then has ``D`` epochs.
        with_policy : bool
            Compute the policy now (default) or on first access to ``.policy`` (the values
            alone take about two thirds of the time).

        Returns
        -------
        MDPSolution
            ``.values (B, D + 1, H, W, 4)``, ``.policy (B, D, H, W, 4) int8``, ``.v0``.

        Raises
        ------
        ValueError
            On a goal outside the grid or in an obstacle, a negative horizon, an unknown
            behaviour, or missing / malformed follow rewards.
        """
        h, w = self.shape
        if isinstance(behaviours, str):
            behaviours = [behaviours]
        behaviours = list(behaviours)
        hz = check_array("horizons", horizons, dtype=float)
        if hz.ndim > 1:
            raise ValueError(f"horizons: expected an int or a 1-d array, got {describe(hz)}")
        if (hz < 0).any() or (hz != np.round(hz)).any():
            raise ValueError(f"horizons: expected integers >= 0, got {describe(hz)}")
        goal_list = _goal_rows(goals)
        n = max(len(behaviours), len(goal_list), hz.size if hz.ndim else 1)
        behaviours = _broadcast("behaviours", behaviours, n)
        goal_list = _broadcast("goals", goal_list, n)
        hz = np.broadcast_to(hz, (n,)) if hz.ndim == 0 or hz.size == 1 else hz
        if hz.size != n:
            raise ValueError(f"horizons: expected {n} values, got {hz.size}")
        hz = hz.reshape(n).astype(np.int64)
        if follow is not None and len(follow) != n:
            raise ValueError(
                f"follow: expected {n} entries (None for non-followers), got {len(follow)}"
            )
        d = int(hz.max()) if n else 0
        if n_epochs is not None:
            if int(n_epochs) != n_epochs or n_epochs < d:
                raise ValueError(
                    f"n_epochs: expected an integer >= the largest horizon {d}, got {n_epochs!r}"
                )
            d = int(n_epochs)

        goal_cells = np.full((n, 2), -1, dtype=np.int64)
        goal_masks = np.zeros((n, h, w), dtype=bool)
        allow = np.zeros((n, len(ACTIONS)), dtype=bool)
        rewards = None
        for b, beh in enumerate(behaviours):
            allow[b] = allowed_actions(beh)
            if beh in ("walk", "run"):
                r, c = self._check_goal(f"goals[{b}]", goal_list[b])
                goal_cells[b] = r, c
                goal_masks[b, r, c] = True
            if beh == "follow":
                if follow is None or follow[b] is None:
                    raise ValueError(
                        f"follow[{b}]: expected rewards (n >= {hz[b]}, {h}, {w}) for a follow "
                        "behaviour, got None"
                    )
                if rewards is None:
                    rewards = np.zeros((n, max(d, 1), h, w))
                fr = check_array(f"follow[{b}]", follow[b], dtype=float, ndim=3)
                if fr.shape[1:] != (h, w) or fr.shape[0] < hz[b] or not np.isfinite(fr).all():
                    raise ValueError(
                        f"follow[{b}]: expected finite rewards of shape (n >= {hz[b]}, {h}, {w}), "
                        f"got {describe(fr)}"
                    )
                rewards[b, : hz[b]] = fr[: hz[b]]
        dt = np.dtype(self.dtype)
        scale = self.goal_reward + self.step_cost
        if rewards is not None:
            scale += float(np.abs(rewards).sum(axis=(2, 3)).max(initial=0.0)) if d else 0.0
        if store_values is None:
            store_values = n * (d + 1) * h * w * 4 * dt.itemsize <= _VALUES_BYTES
        # NumPy inputs: the jitted call transfers them (jnp.asarray would cost ~0.1 ms each)
        inputs = _SolverInputs(
            ok=self._ok,
            occupied=self.occupied,
            goals=goal_masks,
            allow=allow,
            horizons=hz,
            follow=None if rewards is None else np.asarray(rewards[:, :d], dtype=dt),
            slip=np.asarray(self.slip, dt),
            step_cost=np.asarray(self.step_cost, dt),
            goal_reward=np.asarray(self.goal_reward, dt),
            tie_tol=np.asarray(_TIE_RTOL[self.dtype] * scale, dt),
            n_epochs=d,
            use_run=bool(allow[:, RUN].any()),
        )
        (v0, policy, values), release = _run_solver(
            inputs, store_values=bool(store_values), with_policy=bool(with_policy)
        )
        return MDPSolution(
            self,
            goal_cells,
            tuple(behaviours),
            hz,
            v0,
            policy,
            values,
            inputs,
            release,
        )

    # ------------------------------------------------------------------ dense export
    def to_dense(
        self,
        goal: npt.ArrayLike | None = None,
        behaviour: str = "walk",
        *,
        sparse: bool = False,
    ) -> tuple[np.ndarray | list[sp.csr_array], np.ndarray, np.ndarray]:
        """Export the (time-homogeneous) MDP as arrays for an independent solver.

        States are ordered ``s = (row * W + col) * 4 + heading`` over all cells; occupied
        cells and the goal cell are absorbing with zero reward. Disallowed actions of the
        behaviour have reward ``-inf``. Any finite-horizon backward induction
        ``V = v_terminal; V = max_a (R[:, a] + P[a] @ V)`` reproduces :attr:`MDPSolution.values`.

        Parameters
        ----------
        goal : (2,) int or None
            Goal cell for ``walk`` and ``run``; ignored for ``stop``.
        behaviour : str
            ``"walk"``, ``"run"`` or ``"stop"`` (follow rewards vary with time).
        sparse : bool
            Return ``P`` as a list of 5 ``scipy.sparse.csr_array`` (for large grids).

        Returns
        -------
        P : (5, S, S) float64 or list of 5 csr_array
            ``P[a, s, s']``.
        R : (S, 5) float64
            Expected reward ``R[s, a]``.
        v_terminal : (S,) float64
            Terminal values (zeros).

        Raises
        ------
        ValueError
            On a bad goal or behaviour, or a dense export of more than 20,000 states.
        """
        if behaviour == "follow":
            raise ValueError(
                "behaviour: expected 'walk', 'run' or 'stop' (follow rewards vary with time), "
                "got 'follow'"
            )
        allow = allowed_actions(behaviour)
        h, w = self.shape
        n = self.n_states
        if not sparse and n > _DENSE_MAX_STATES:
            raise ValueError(
                f"to_dense: expected at most {_DENSE_MAX_STATES} states for a dense export, "
                f"got {n}; pass sparse=True"
            )
        goal_mask = np.zeros((h, w), dtype=bool)
        if behaviour in ("walk", "run"):
            r, c = self._check_goal("goal", goal)
            goal_mask[r, c] = True
        rows, cols, heads = np.meshgrid(np.arange(h), np.arange(w), np.arange(4), indexing="ij")
        rows, cols, heads = rows.ravel(), cols.ravel(), heads.ravel()
        s = np.arange(n)
        absorbing = (self.occupied | goal_mask)[rows, cols]
        bonus = np.where(goal_mask[rows, cols], self.goal_reward, 0.0)

        def move(direction: np.ndarray, k: int) -> np.ndarray:
            """Next state of moving k cells along ``direction`` (blocked -> same state)."""
            blocked = np.zeros(n, dtype=bool)
            for m in range(1, k + 1):
                rr = rows + m * _DROW[direction]
                cc = cols + m * _DCOL[direction]
                inside = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
                blocked |= ~inside
                blocked[inside] |= self.occupied[rr[inside], cc[inside]]
            rr = rows + k * _DROW[direction]
            cc = cols + k * _DCOL[direction]
            return np.where(blocked, s, (rr * w + cc) * 4 + heads)

        outcomes: list[list[tuple[np.ndarray, float]]] = [
            [(s, 1.0)],
            [],
            [],
            [((rows * w + cols) * 4 + (heads + 1) % 4, 1.0)],
            [((rows * w + cols) * 4 + (heads - 1) % 4, 1.0)],
        ]
        for a, k in ((1, 1), (2, 2)):
            outcomes[a] = [
                (move(heads, k), 1.0 - self.slip),
                (move((heads + 1) % 4, k), self.slip / 2),
                (move((heads - 1) % 4, k), self.slip / 2),
            ]
        cost = np.array([0.0] + [self.step_cost] * 4)
        mats = []
        reward = np.zeros((n, len(ACTIONS)))
        for a, outs in enumerate(outcomes):
            src = np.concatenate([s for _ in outs])
            dst = np.concatenate([np.where(absorbing, s, nxt) for nxt, _ in outs])
            prob = np.concatenate([np.full(n, p) for _, p in outs])
            m = sp.csr_array((prob, (src, dst)), shape=(n, n))
            m.sum_duplicates()
            mats.append(m)
            reward[:, a] = np.where(absorbing, 0.0, m @ bonus - cost[a])
            if not allow[a]:
                reward[:, a] = -np.inf
        p_out: np.ndarray | list[sp.csr_array] = (
            mats if sparse else np.stack([m.toarray() for m in mats])
        )
        return p_out, reward, np.zeros(n)


def _goal_rows(
    goals: npt.ArrayLike | Sequence[npt.ArrayLike | None] | None,
) -> list[npt.ArrayLike | None]:
    """Split ``goals`` into per-artefact rows (a single (2,) goal gives one row)."""
    if goals is None:
        return [None]
    if isinstance(goals, np.ndarray | jax.Array):
        g = np.asarray(goals)
        return [g] if g.ndim == 1 else list(g)
    goals = list(goals)
    if len(goals) == 2 and all(np.ndim(x) == 0 and x is not None for x in goals):
        return [np.asarray(goals)]
    return goals


_Item = TypeVar("_Item")


def _broadcast(name: str, items: list[_Item], n: int) -> list[_Item]:
    if len(items) == n:
        return items
    if len(items) == 1:
        return items * n
    raise ValueError(f"{name}: expected 1 or {n} entries, got {len(items)}")
