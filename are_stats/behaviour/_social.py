"""Local interaction: walking artefacts avoid each other and the walls (issue 26).

The MDP decides the route (paper Sect. 3.2); between its decisions a person walks the route
in continuous space and gives way to the people around it. The interaction is the social
force model of Helbing and Molnar (1995), in the circular specification whose parameters
Moussaid et al. (2009) and Johansson et al. (2007) fitted to pedestrian tracks:

.. math::

    \\frac{d v_i}{dt} = \\frac{v^0_i e_i - v_i}{\\tau}
        + \\sum_{j \\ne i} A \\, e^{(2 r - d_{ij}) / B} \\, n_{ij}
        + A_w \\, e^{(r - d_{iW}) / B_w} \\, n_{iW}

with ``e_i`` the unit vector to the next corner of artefact ``i``'s route, ``v0_i`` its
preferred speed, ``d_ij`` the distance between two people and ``n_ij`` the unit vector from
``j`` to ``i``, ``d_iW`` the distance to the nearest wall (occupied map cell) and ``n_iW``
pointing away from it. Speeds are capped at ``max_speed`` times the preferred speed.

**Groups** (``groups=``): the members of an arrival group share their leader's route and
head for a formation slot beside it (or, where that is not free, behind the member ahead)
at ``group_spacing``, at the group's one pace, its leader's preferred speed; the repulsion
acts between members only when they are closer than that spacing
(:mod:`~are_stats.behaviour._groups`).

Why the leader's speed and not the slowest member's: the between-person law of preferred
speeds is fitted on the log's tracks (:func:`~are_stats.fitting.fit_behaviour`), one
speed per track, and in the log a group's members walk at the group's pace: each of the
log's tracks walks at a pace drawn from that law, a group's tracks all at one. A generated
group therefore draws one pace from the law for all its members: its leader's speed,
itself one draw of the law independent of the group (as the fit's motion checks walk
their replicates, one draw per group). At the slowest of its ``g`` members' own draws it
would walk at the minimum of ``g`` draws, slower than the law: for a lognormal law of
log-sd ``sigma``, a median ``0.55 sigma`` (pairs) or ``0.82 sigma`` (threes) below the
law's in log speed (the assemblies' :func:`~are_stats.behaviour.group_tracks` already
re-times members' plans to their leader's; the pace here does not rely on it).

Why a social force and not reciprocal velocity obstacles: the force is a few smooth terms
whose three parameters (``A``, ``B``, ``tau``) enter the acceleration linearly (``A``,
``1/tau``) or through one decay length (``B``), so they are estimated from tracks by least
squares on the observed accelerations (:func:`fit_social_force`), the way they were
calibrated in the literature; a velocity-obstacle model has a time horizon and a
non-smooth choice of velocity whose likelihood is not available in closed form.

:func:`social_force_tracks` re-walks planned tracks (the behaviour's, one row per artefact
and epoch) with the interaction: each artefact keeps its life-cycle and its route, walks at
its preferred speed (the planned one), and people pass each other instead of walking
through one another. The simulation runs in windows of 256 steps over the artefacts alive
in them; with more than :data:`ALL_PAIRS_MAX` people in a window, neighbours are found on a
grid of cells as wide as the interaction's ``reach`` (a sort and a binary search per step:
linear in the number of people, not all pairs), or, when the window holds many scenarios of
at most :data:`BLOCK_MAX` people each (the displacement errors' continuations), by all pairs
within each scenario's block of slots. A window runs only the steps somebody is alive in,
and one compiled program serves every window of a size and search on a map
(:func:`_layout`). 1,000 artefacts arriving over an hour, walked at 10 Hz: about 1 s CPU
warm, 6 s with compiling, on 2 loaded cores (``bench_social``).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import TYPE_CHECKING, NamedTuple, NotRequired, TypedDict

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_positive
from are_stats.behaviour._groups import formation, slot_offsets
from are_stats.behaviour._noise import tracker_noise
from are_stats.behaviour._smoother import smooth_samples
from are_stats.behaviour._xla import jit_with_options, padded_size
from are_stats.inputs import check_memory, check_work

if TYPE_CHECKING:
    from collections.abc import Callable

    from are_stats.environment import OccupancyGrid

__all__ = ["SocialForce", "fit_social_force", "social_force_tracks"]


class SocialForce(NamedTuple):
    """Parameters of the social force model (see the module docstring).

    Defaults are the published values for walking pedestrians (Moussaid et al. 2009;
    Helbing and Molnar 1995): contact repulsion 2.1 m/s^2 decaying over 0.3 m, relaxation
    0.5 s, body radius 0.25 m.
    """

    strength: float = 2.1  # A (m/s^2)
    range: float = 0.3  # B (m)
    relaxation: float = 0.5  # tau (s)
    radius: float = 0.25  # r (m)
    wall_strength: float = 3.0  # A_w (m/s^2)
    wall_range: float = 0.15  # B_w (m)
    max_speed: float = 1.3  # speed cap, times the preferred speed
    horizon: float = 2.0  # anticipation (s): pairs repel at their predicted closest approach
    reach: float = 4.0  # neighbourhood (m): people farther apart than this do not interact
    group_spacing: float = 0.75  # distance (m) between neighbouring members of a group


#: Neighbours looked at per grid cell of ``reach`` metres (16 people on 16 m^2 is a dense
#: crowd; past that, the first 16 in sort order).
CELL_CAPACITY = 16
#: Simulation steps per window of time.
WINDOW_STEPS = 256


def _route(t: np.ndarray, xy: np.ndarray, tol: float = 0.05) -> tuple[np.ndarray, float]:
    """Corners of a planned track (distinct positions, collinear runs merged) and the
    preferred speed (median speed over the planned moves, 0 for a standing artefact)."""
    (pts,), v0 = _routes(t, xy, np.array([0]), np.array([len(t)]), tol)
    return pts, float(v0[0])


def _routes(
    t: np.ndarray, xy: np.ndarray, start: np.ndarray, stop: np.ndarray, tol: float = 0.05
) -> tuple[list[np.ndarray], np.ndarray]:
    """:func:`_route` of every artefact at once: rows ``start[i]:stop[i]`` of ``t`` (N,)
    and ``xy`` (N, 2) are artefact ``i``'s planned track (consecutive, non-empty). Returns
    its corners (a list of (m_i, 2) arrays) and preferred speeds (n,), the same numbers
    as one :func:`_route` per artefact, in a few array passes instead of a Python loop."""
    n = start.size
    seg = np.repeat(np.arange(n), stop - start)
    head = np.zeros(t.size, bool)
    head[start] = True
    step = np.r_[0.0, np.hypot(*np.diff(xy, axis=0).T)]  # from the row before (any artefact)
    keep = head | (step > 1e-9)
    pts, owner = xy[keep], seg[keep]
    # drop corners that lie on the segment between their neighbours (on one artefact's
    # track: a corner with a neighbour before and after it)
    drop = np.zeros(pts.shape[0], bool)
    if pts.shape[0] > 2:
        a, b, c = pts[:-2], pts[1:-1], pts[2:]
        ab, ac = b - a, c - a
        cross = np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])
        lac = np.hypot(*ac.T)
        dot = (ab * ac).sum(1)
        on = (cross <= tol * np.maximum(lac, 1e-12)) & (dot >= 0) & (dot <= lac**2)
        drop[1:-1] = on & (owner[:-2] == owner[1:-1]) & (owner[1:-1] == owner[2:])
    pts, owner = pts[~drop], owner[~drop]
    corners = np.split(pts, np.searchsorted(owner, np.arange(1, n)))
    # the median speed over the moves of each artefact's track
    dt = np.r_[0.0, np.diff(t)]
    moving = ~head & (step > 1e-6)
    speed = step[moving] / np.maximum(dt[moving], 1e-9)
    who = seg[moving]
    order = np.lexsort((speed, who))
    speed, who = speed[order], who[order]
    count = np.bincount(who, minlength=n)
    first = np.r_[0, np.cumsum(count)[:-1]]
    mid = first + count // 2
    v0 = np.zeros(n)
    odd = (count % 2 == 1) & (count > 0)
    v0[odd] = speed[mid[odd]]
    even = (count % 2 == 0) & (count > 0)
    v0[even] = (speed[mid[even] - 1] + speed[mid[even]]) / 2.0
    return corners, v0


def _anticipated(diff, dv, horizon):
    """Separation at the predicted closest approach within ``horizon`` (Zanlungo et al.
    2011): ``r + v t*`` with ``t* = clip(-r.v / |v|^2, 0, horizon)``; arrays (..., 2)."""
    xp = jnp if isinstance(diff, jax.Array) else np
    t_star = -(diff * dv).sum(-1) / ((dv * dv).sum(-1) + 1e-9)
    t_star = xp.clip(t_star, 0.0, horizon)
    return diff + dv * t_star[..., None]


def _pair_term(now, dv, ok, p, mates=None):
    """Repulsions (..., 2) of the pairs ``now`` (from j to i), relative velocities ``dv``;
    ``mates`` marks pairs of one group, which repel only when closer than the group's
    spacing (their formation keeps them at it)."""
    d2 = jnp.sum(now**2, axis=-1)
    ok = ok & (d2 <= p.reach**2)
    if mates is not None:
        ok = ok & ~(mates & (d2 > p.group_spacing**2))
    diff = _anticipated(now, dv, p.horizon)
    dist = jnp.sqrt(jnp.sum(diff**2, axis=-1) + 1e-12)
    mag = p.strength * jnp.exp((2.0 * p.radius - dist) / p.range)
    return jnp.where(ok[..., None], (mag / dist)[..., None] * diff, 0.0)


#: Seconds in which a group member makes up the distance to its formation slot (its
#: desired velocity is its leader's plus the distance over this time).
SLOT_TIME = 1.0
#: A member farther than this (m) from its slot (plus its abreast offset), or with a wall
#: between them, walks the group's route to catch up instead.
SLOT_REACH = 1.5

#: Up to this many people in a window every pair is looked at (cheaper than the grid's
#: sort and gathers at this size); beyond it, the grid of cells.
ALL_PAIRS_MAX = 128
#: Beyond :data:`ALL_PAIRS_MAX` people, when no scenario has more than this many people in
#: a window (many small scenes: the displacement errors' continuations, one scene each),
#: every scenario gets a block of slots and all pairs are looked at within blocks only
#: (cheaper than the cell list's 9 x :data:`CELL_CAPACITY` candidates per person).
BLOCK_MAX = 16


def _pair_forces(x, v, alive, p, cell, n_y, origin, all_pairs, gid, block=0):
    """(n, 2) sum of the pair repulsions on each alive person (all pairs for a few people;
    all pairs within consecutive blocks of ``block`` slots, one scenario each; else
    neighbours by a cell list; the three agree while no cell holds more than
    :data:`CELL_CAPACITY`); ``gid`` (n,) the groups (None: nobody in one)."""
    n = x.shape[0]
    if block:
        xb, vb, ab = x.reshape(-1, block, 2), v.reshape(-1, block, 2), alive.reshape(-1, block)
        ok = ab[:, :, None] & ab[:, None, :] & ~jnp.eye(block, dtype=bool)
        mates = None
        if gid is not None:
            gb = gid.reshape(-1, block)
            mates = (gb[:, :, None] == gb[:, None, :]) & (gb[:, :, None] >= 0)
        now = xb[:, :, None, :] - xb[:, None, :, :]
        dv = vb[:, :, None, :] - vb[:, None, :, :]
        return _pair_term(now, dv, ok, p, mates).sum(axis=2).reshape(n, 2)
    if all_pairs:
        ok = alive[:, None] & alive[None, :] & ~jnp.eye(n, dtype=bool)
        now = x[:, None, :] - x[None, :, :]
        mates = None if gid is None else (gid[:, None] == gid[None, :]) & (gid[:, None] >= 0)
        return _pair_term(now, v[:, None, :] - v[None, :, :], ok, p, mates).sum(axis=1)
    c = jnp.floor((x - origin) / cell).astype(jnp.int32)
    key = jnp.where(alive, c[:, 0] * n_y + c[:, 1], jnp.iinfo(jnp.int32).max)
    order = jnp.argsort(key)
    sk = key[order]
    d = jnp.array([-1, 0, 1], jnp.int32)
    off = (d[:, None] * n_y + d[None, :]).reshape(-1)  # the 9 neighbouring cells
    target = key[:, None] + off[None, :]  # (n, 9)
    # (an unrolled bisection: XLA's CPU loop of the default method costs ~30x more)
    start = jnp.searchsorted(sk, target.reshape(-1), method="scan_unrolled").reshape(n, 9)
    slot = start[..., None] + jnp.arange(CELL_CAPACITY)  # (n, 9, K)
    slot = jnp.minimum(slot, n - 1)
    cand = order[slot]
    ok = (sk[slot] == target[..., None]) & (cand != jnp.arange(n)[:, None, None])
    now = x[:, None, None, :] - x[cand]  # from j to i
    ok = ok & alive[:, None, None]
    mates = None if gid is None else (gid[:, None, None] == gid[cand]) & (gid[:, None, None] >= 0)
    return _pair_term(now, v[:, None, None, :] - v[cand], ok, p, mates).sum(axis=(1, 2))


#: XLA options of :func:`_window`: XLA's CPU fusion emitters off (as the Laplace programs'
#: and the behaviour gradient's). The walks keep their bits (tests/behaviour/
#: test_social_golden.py; a window of 4,096 slots alike) and compile in about two thirds
#: of the CPU (issue 29: the golden walks in fresh processes 19.8, 6.6, 14.1 and 3.5 s ->
#: 14.2, 4.6, 9.6 and 2.2 s of CPU, their repeated runs alike).
_WINDOW_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


@jit_with_options(static_argnames=("all_pairs", "block", "repel"), compiler_options=_WINDOW_OPTIONS)
def _window(
    state,
    route,
    n_vert,
    v0,
    t_on,
    t_off,
    kin,
    plan,
    pace,
    shift,
    form,
    t0,
    dt,
    p,
    walls,
    n_steps,
    n_y,
    all_pairs,
    block,
    repel=True,
    turn=None,
):
    """Integrate ``n_steps`` steps of ``dt`` from ``t0`` (semi-implicit Euler); returns the
    final state and the positions after every step (W, n, 2), ``W = plan.shape[0]`` (rows
    past ``n_steps`` are zero). ``n_steps <= W`` is traced: one compiled program runs any
    number of steps of a window, and a window that ends early (the last one, or one whose
    people have all left) costs only its steps.

    Positions are in a frame where each scenario is shifted by ``shift`` (n, 2) so that
    artefacts of different scenarios never meet; the walls are looked up unshifted.
    Kinematic artefacts (``kin``) are where their ``plan`` (n_steps, n, 2) puts them.
    ``pace`` (n_steps, n) is each artefact's desired speed over its preferred ``v0`` at
    each step (ones: the preferred speed throughout).
    ``form`` is the formation: each artefact's leader and the member one slot ahead of it
    (indices here; itself when it has none), its abreast offset and its group (``-1``:
    alone). One program serves windows with and without groups (nobody in a group: the
    formation's terms change nothing), so a walk compiles once per size. The state is
    positions, velocities, route indices and headings (unit vectors).
    ``all_pairs`` and ``block`` choose the neighbour search (:func:`_pair_forces`);
    ``repel`` False (a force of strength 0: every pair term is exactly zero) skips it.
    ``turn`` (W, n), optional: each artefact's desired heading's deviation (rad) from
    the line to its route's next corner at each step (None: none, and no term of it in
    the program).
    """
    dist_w, grad_w, free, w_origin, w_res, origin, cell, hw = walls
    lead, prev, side, gid = form
    has_lead = lead != jnp.arange(lead.shape[0])
    h, w = hw[0], hw[1]  # the map's size; the grids are padded past it (:func:`_walls`)

    def lookup(grid, xy):
        """``grid`` at the points ``xy`` (..., 2), and whether they lie on the map."""
        ij = jnp.floor((xy - w_origin) / w_res).astype(jnp.int32)
        col = jnp.clip(ij[..., 0], 0, w - 1)
        row = jnp.clip(ij[..., 1], 0, h - 1)
        inside = (ij[..., 0] >= 0) & (ij[..., 0] < w) & (ij[..., 1] >= 0) & (ij[..., 1] < h)
        return grid[row, col], inside

    def clear(a, b):
        """Whether the straight walks ``a -> b`` (n, 2) keep on free cells (sampled)."""
        f = jnp.array([0.2, 0.4, 0.6, 0.8, 1.0])[:, None, None]
        d, _ = lookup(dist_w, a + f * (b - a) - shift)
        return jnp.all(d > 0.0, axis=0)

    def formation_slots(x, v, k, hd, alive, target, to, dist, speed, last):
        """Members' desired velocities towards their slots; the rest keep ``speed``."""
        grouped = has_lead & alive[lead]
        xl, el = x[lead], hd[lead]
        abreast = xl + side[:, None] * jnp.stack([-el[:, 1], el[:, 0]], axis=1)
        behind = x[prev] - p.group_spacing * hd[prev]  # single file: behind the one ahead
        d, _ = lookup(dist_w, jnp.stack([abreast, 0.5 * (xl + abreast), behind]) - shift)
        slot = jnp.where(
            ((d[0] > p.radius) & (d[1] > 0.0))[:, None],
            abreast,
            jnp.where((d[2] > p.radius)[:, None], behind, xl),
        )
        gap = slot - x
        near = jnp.sqrt(jnp.sum(gap**2, axis=1)) <= SLOT_REACH + jnp.abs(side)
        in_slot = grouped & near & clear(x, slot)
        # a member cut off from its slot (a corner, a crowd) walks the shared route at its
        # top speed to catch up
        speed = jnp.where(grouped & ~in_slot & ~last, p.max_speed * v0, speed)
        desired = speed[:, None] * to / dist[:, None]
        desired = jnp.where(in_slot[:, None], v[lead] + gap / SLOT_TIME, desired)
        return desired, speed, in_slot

    def step(carry, inputs):
        s, planned, pace_s, turn_s = inputs
        x, v, k, hd = carry
        t = t0 + s * dt
        alive = (t >= t_on) & (t < t_off)
        target = jnp.take_along_axis(route, k[:, None, None].repeat(2, axis=2), axis=1)[:, 0]
        to = target - x
        dist = jnp.sqrt(jnp.sum(to**2, axis=1) + 1e-12)
        last = k >= n_vert - 1
        if turn_s is not None:  # the heading's wander: aimed turn_s off the corner
            c, sn = jnp.cos(turn_s), jnp.sin(turn_s)
            to = jnp.stack([c * to[:, 0] - sn * to[:, 1], sn * to[:, 0] + c * to[:, 1]], axis=1)
        vd = v0 * pace_s  # the desired speed: the preferred one times the pace's drift
        speed = jnp.where(last, vd * jnp.minimum(1.0, dist / 0.5), vd)
        # members head for their slot beside (or behind) their leader
        desired, speed, in_slot = formation_slots(x, v, k, hd, alive, target, to, dist, speed, last)
        dw, _ = lookup(dist_w, x - shift)
        gw, _ = lookup(grad_w, x - shift)
        # whoever walks into a wall or pillar (a member off the route after walking beside
        # its leader, anybody pushed off it by the others) goes round it: the desired
        # velocity along the wall, not into it (the social force alone stalls where the
        # wall's push balances the drive)
        into = jnp.sum(desired * gw, axis=1)
        along = desired - into[:, None] * gw
        n_along = jnp.sqrt(jnp.sum(along**2, axis=1))
        turn = jnp.stack([-gw[:, 1], gw[:, 0]], axis=1)  # head-on: turn left
        along = jnp.where(
            (n_along > 1e-3 * speed)[:, None], along / jnp.maximum(n_along, 1e-9)[:, None], turn
        )
        round_it = ~in_slot & (into < 0.0) & (dw < p.radius + 2.0 * p.wall_range)
        desired = jnp.where(round_it[:, None], speed[:, None] * along, desired)
        a = (desired - v) / p.relaxation
        if repel:
            a = a + _pair_forces(x, v, alive, p, cell, n_y, origin, all_pairs, gid, block)
        a = a + (p.wall_strength * jnp.exp((p.radius - dw) / p.wall_range))[:, None] * gw
        # the time each artefact has been alive in this step, from t - dt to t: all of it,
        # but the step it arrives in only from its arrival (t - t_on; 0 at t == t_on, where
        # it stands on its arrival point). A full step there put every walker up to v0 dt
        # ahead of its plan from its first sample on: a speed of up to (1 + dt / gap) v0
        # over a first row gap after the arrival (1.7 v0 over 0.2 s, past the cap).
        h = jnp.clip(t - t_on, 0.0, dt)[:, None]
        v_new = v + a * h
        cap = p.max_speed * jnp.maximum(v0, 1e-9)
        sp = jnp.sqrt(jnp.sum(v_new**2, axis=1) + 1e-18)
        v_new = v_new * jnp.minimum(1.0, cap / sp)[:, None]
        x_new = x + v_new * h
        on_free, inside = lookup(free, x_new - shift)
        ok = on_free & inside
        # a member blocked by a wall slides along it (one component of its step) instead
        # of standing: following its leader off the route, it meets corners
        v_try = jnp.stack([v_new * jnp.array([1.0, 0.0]), v_new * jnp.array([0.0, 1.0])])
        f_try, i_try = lookup(free, x + v_try * h - shift)
        can = has_lead & ~ok & f_try & i_try  # (2, n)
        pick = jnp.where(can[0][:, None], v_try[0], v_try[1])
        slide = can[0] | can[1]
        v_new = jnp.where(slide[:, None], pick, v_new)
        x_new = jnp.where(slide[:, None], x + pick * h, x_new)
        ok = ok | slide
        move = alive & ~kin
        x_out = jnp.where((move & ok)[:, None], x_new, x)
        v_out = jnp.where((move & ok)[:, None], v_new, jnp.where(move[:, None], 0.0, v))
        follow = (alive & kin)[:, None]
        x_out = jnp.where(follow, planned, x_out)
        v_out = jnp.where(follow, (planned - x) / dt, v_out)
        # the next corner once this one is reached (a member abreast passes a corner its
        # offset away)
        tol = jnp.maximum(0.4, 2.0 * v0 * dt) + jnp.where(has_lead, jnp.abs(side), 0.0)
        reached = jnp.sqrt(jnp.sum((target - x_out) ** 2, axis=1)) < tol
        k_out = jnp.where(move & reached & ~last, k + 1, k)
        # a member in its slot is at most one corner behind its leader on the route (one
        # it sees)
        k_c = jnp.maximum(k_out, k_out[lead] - 1)
        corner = jnp.take_along_axis(route, k_c[:, None, None].repeat(2, axis=2), axis=1)
        k_out = jnp.where(in_slot & move & clear(x_out, corner[:, 0]), k_c, k_out)
        sp_out = jnp.sqrt(jnp.sum(v_out**2, axis=1))
        hd_out = jnp.where((sp_out > 0.1)[:, None], v_out / jnp.maximum(sp_out, 1e-9)[:, None], hd)
        return (x_out, v_out, k_out, hd_out), x_out

    def body(s, carry):
        state, out = carry
        turn_s = None if turn is None else turn[s]
        state, x_out = step(state, ((s + 1).astype(jnp.float64), plan[s], pace[s], turn_s))
        return state, out.at[s].set(x_out)

    out = jnp.zeros(plan.shape, state[0].dtype)
    return jax.lax.fori_loop(0, n_steps, body, (state, out))


def _interp_runs(
    x: np.ndarray, run: np.ndarray, xp: np.ndarray, fp: np.ndarray, bounds: np.ndarray
) -> np.ndarray:
    """``np.interp(x[i], xp[a:b], fp[a:b, k])`` for every ``i`` and column ``k``, with
    ``a, b = bounds[run[i]], bounds[run[i] + 1]``: many piecewise-linear functions (the
    runs of ``xp`` (N,), each sorted and non-empty, their values ``fp`` (N, K)) evaluated
    at once, bit for bit as NumPy's ``interp`` evaluates each (the same interval, slope
    and arithmetic, the same ends and exact hits; issue 29: a call per run and column was
    most of a walk's tail). ``x`` (M,) float, ``run`` (M,) int; returns (M, K) float."""
    # each x's place in its run: the last xp <= x (NumPy's interval; bounds[run] - 1: none),
    # by a bisection of all runs at once
    lo, top = bounds[run].astype(np.int64), bounds[run + 1].astype(np.int64)
    while True:
        left = lo < top
        if not left.any():
            break
        mid = (lo + top) // 2
        after = left & (xp[np.minimum(mid, xp.size - 1)] <= x)
        lo = np.where(after, mid + 1, lo)
        top = np.where(left & ~after, mid, top)
    j = lo - 1
    lo, hi = bounds[run], bounds[run + 1] - 1
    a = np.clip(j, lo, np.maximum(hi - 1, lo))
    b = np.minimum(a + 1, hi)
    xc = x[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (fp[b] - fp[a]) / (xp[b] - xp[a])[:, None]
        out = slope * (xc - xp[a][:, None]) + fp[a]
        # NumPy's other cases, where they arise: NaN (from the right end, else the flat
        # value), an x on a vertex or before or after the run (its value), a NaN x
        nan = np.isnan(out)
        if nan.any():
            out = np.where(nan, slope * (xc - xp[b][:, None]) + fp[b], out)
            out = np.where(nan & np.isnan(out) & (fp[a] == fp[b]), fp[a], out)
    at = np.maximum(j, 0)
    end = np.where(j < lo, lo, np.where((j >= hi) | (x == xp[at]), at, -1))
    hit = np.flatnonzero(end >= 0)
    out[hit] = fp[end[hit]]
    # a NaN x gives NaN, except on a run of one point (its value)
    odd = np.flatnonzero(np.isnan(x) & (hi > lo))
    out[odd] = x[odd, None]
    return out


def _bucket(n: int, lo: int = 8) -> int:
    return max(lo, 1 << (max(n, 1) - 1).bit_length())


def _layout(active: list[np.ndarray], scen: np.ndarray, repel: bool) -> list[tuple | None]:
    """Each window's neighbour search and slots, ``(all_pairs, block, nb, width)`` (None
    for an empty window): many small scenarios (past :data:`ALL_PAIRS_MAX` people, at
    most :data:`BLOCK_MAX` in any) in blocks of ``width`` slots, one scenario each, else
    one slot each, in order; ``nb`` slots in all (a power of two: a few compiled
    programs). The search (:func:`_pair_forces`) is all pairs, blocks of ``block`` slots
    or the grid of cells; without repulsion (``repel`` False) there is none, and the
    windows of a size share one program whatever search they would have had (issue 29);
    nor blocks: a slot each, in order (every term of a step is then the artefact's own, so
    where it sits changes no bit: the displacement errors' eight chunks of the 302-person
    tracks table, 500 small scenarios each, took 4,096 or 8,192 slots in blocks of 8 or
    16, and take 2,048 or 4,096 so).
    The windows of blocks of one width and those without repulsion have ``nb`` of the
    walk's largest of them: one program each per walk (issue 29: the motion checks'
    50 replicates, walked without repulsion where the fit found none, compiled five
    sizes, 64 to 1,024). A block's sums keep their width and a window without repulsion
    has none, so the padding leaves the walks as they were, bit for bit
    (tests/behaviour/test_social_golden.py). All pairs (up to :data:`ALL_PAIRS_MAX`) sum
    over the slots, and keep their own sizes; so do the windows of the grid of cells:
    padded, their sums keep their length but not their bits (a fitted scene of
    tests/scenarios/test_assembly_golden.py, 1,024 people padded to 2,048, walked
    otherwise by round-off).
    ``active[w]`` (m,) the artefacts alive in window ``w`` (sorted by scenario), ``scen``
    (n,) their scenarios (integer codes)."""
    out: list[tuple | None] = []
    for act in active:
        if act.size == 0:
            out.append(None)
            continue
        scenes = np.bincount(scen[act])
        per_scene = int(scenes.max())
        if act.size > ALL_PAIRS_MAX and per_scene <= BLOCK_MAX:
            width = _bucket(per_scene, 4)
            nb = _bucket(int(np.count_nonzero(scenes)), 16) * width
        else:
            width, nb = 0, _bucket(act.size, 16)
        if not repel:  # no search, so no blocks: one slot each, in order (fewer slots)
            out.append((False, 0, _bucket(act.size, 16), 0))
        else:
            out.append((not width and nb <= ALL_PAIRS_MAX, width, nb, width))

    # the windows of a block width (or without repulsion) share one program: each is
    # padded to the walk's largest of them (more blocks: the same sums)
    def shared(lay: tuple | None) -> bool:
        return lay is not None and not lay[0] and (lay[1] > 0 or not repel)

    most: dict[tuple, int] = {}
    for lay in filter(shared, out):
        most[lay[:2]] = max(most.get(lay[:2], 0), lay[2])
    return [(lay[0], lay[1], most[lay[:2]], lay[3]) if shared(lay) else lay for lay in out]


def _walls(grid: OccupancyGrid, xy: np.ndarray, reach: float, x_shift: float = 0.0) -> tuple:
    """Distance to walls, its unit gradient, the free mask and the frames (JAX arrays)."""
    from scipy import ndimage  # lazy: +0.2 s CPU on `import are_stats.behaviour`

    if grid is not None:
        free = np.asarray(grid.free, bool)
        res = float(grid.resolution)
        org = np.asarray(grid.origin[:2], float)
    else:  # open ground around the tracks
        lo, hi = xy.min(0) - 5.0, xy.max(0) + 5.0
        res = 0.25
        shape = np.ceil((hi - lo) / res).astype(int) + 1
        free = np.ones((shape[1], shape[0]), bool)
        org = lo
    dist = ndimage.distance_transform_edt(free) * res if (~free).any() else np.full(free.shape, 1e6)
    gy, gx = np.gradient(dist, res)
    norm = np.maximum(np.hypot(gx, gy), 1e-9)
    grad = np.stack([gx / norm, gy / norm], axis=-1)
    lo = xy.min(0) - reach
    hi = xy.max(0) + reach + np.array([x_shift, 0.0])
    cell = reach
    n_y = int(np.ceil((hi[1] - lo[1]) / cell)) + 3
    # the three grids padded to a size of few values, the map's own size passed beside them:
    # maps a few cells apart (a room's extent read from each log's tracks) share one
    # compiled walk; the lookups clip to the map's size, so no padded cell is ever read
    h, w = free.shape
    size = (_grid_bucket(h), _grid_bucket(w))
    # placed as they are (jax.device_put): jnp.asarray compiled a program per array (issue 29)
    return (
        jax.device_put(_padded(np.asarray(dist, float), size)),
        jax.device_put(_padded(grad, size)),
        jax.device_put(_padded(free, size)),
        jax.device_put(org),
        float(res),
        jax.device_put(np.asarray(lo - cell)),
        float(cell),
        jax.device_put(np.array([h, w], np.int32)),
    ), n_y


def _grid_bucket(n: int) -> int:
    """The padded length of a wall grid's side of ``n`` cells: 32, 48, 64, 96, 128, 192, ...
    (:func:`padded_size`), at most 1.5x ``n``."""
    return padded_size(n, 32)


def _padded(a: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``a`` (h, w, ...) in the corner of zeros (size[0], size[1], ...)."""
    out = np.zeros(size + a.shape[2:], a.dtype)
    out[: a.shape[0], : a.shape[1]] = a
    return out


class _Pace(NamedTuple):
    """The walkers' within-person variation of the desired speed (see
    :func:`social_force_tracks`' ``speed_variation``): the log pace ``u`` of each artefact
    (n,), its AR(1) coefficient per step ``phi`` and innovation sd ``innovation`` (n,),
    and the generator that draws the innovations."""

    rng: np.random.Generator
    u: np.ndarray
    phi: np.ndarray
    innovation: np.ndarray


def _pace(
    speed_variation: tuple,
    n_rows: int,
    rows: np.ndarray,
    relaxation: float,
    dt: float,
    name: str = "speed_variation",
    units: str = "log units",
) -> _Pace:
    """The stationary start of each artefact's log pace (``rows``: its first row in the
    caller's table), from ``speed_variation = (key, sd, time)``; with ``name``
    ``"heading_variation"`` (``units`` ``"rad"``), its heading's deviation from its
    route's direction, an OU of the same kind (errors name ``name``)."""
    try:
        key, sd, time = speed_variation
    except (TypeError, ValueError):
        raise ValueError(
            f"{name}: expected (key, sd, time), got "
            f"{type(speed_variation).__name__} {speed_variation!r:.60}"
        ) from None
    values = {}
    for what, v in (("sd", sd), ("time", time)):
        a = np.asarray(v, float)
        if a.ndim == 0:
            a = np.full(n_rows, float(a))
        if a.shape != (n_rows,):
            raise ValueError(
                f"{name}: expected {what} a number or one per track row ({n_rows}), "
                f"got shape {a.shape}"
            )
        values[what] = a[rows]
    sd, time = np.nan_to_num(values["sd"], nan=0.0), values["time"]
    varies = sd > 0
    bad = ~np.isfinite(sd) | (sd < 0) | (varies & ~(np.isfinite(time) & (time > 0)))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{name}: expected sd >= 0 ({units}) and, where sd > 0, a time > 0 (s), "
            f"got sd {sd[i]!r} and time {time[i]!r}"
        )
    time = np.where(varies, time, 1.0)
    # the walked process (speed's log, or heading) is the desired OU (sd_d, T_d) through
    # the social force's first-order lag tau: its autocovariance sd_d^2 T_d (T_d e^{-L/T_d}
    # - tau e^{-L/tau}) / (T_d^2 - tau^2) is, past a few tau, its whole variance
    # C0 = sd_d^2 T_d / (T_d + tau) less the slow part's sd_d^2 T_d^2 / (T_d^2 - tau^2)
    # e^{-L/T_d}: an OU's variogram delayed by about tau, which no one OU matches. The
    # fit's OU (least squares over lags from its window W to 8-19 s) reads about T_d + tau
    # as the time and C0 / (1 - tau / (2 T)) as the variance (the exact window variogram
    # through the fit: docs/src/behaviour.md), so T_d = T - tau (at least T / 2) and
    # sd_d = sd sqrt(1 + tau / (2 T_d)) read sd within -3..+1% at T = 2-4 s and
    # W = 0.4-2 s. The heading's rule since 2026-11-28; the pace's too since then (its
    # walk, with _on_schedule's rescaling linearised, reads sd 0.98-1.02 and T 0.87-0.98
    # of the truth at T = 2-4 s, W 1.2 s and walks of 77 s, where the rule until then,
    # the slow part's variance sd^2, sd_d = sd sqrt(1 - (tau / T)^2) with T_d = T, read
    # 0.83-0.99 and 1.10-1.30; docs/src/behaviour.md, *The generated pace read back*).
    # The whole variance sd^2 (sd_d = sd sqrt(1 + tau / T_d), the heading's until
    # 2026-11-28) reads 2-8% high at T = 2-4 s.
    time = np.maximum(time - relaxation, 0.5 * time)
    sd_desired = sd * np.sqrt(1.0 + 0.5 * relaxation / time)
    phi = np.where(varies, np.exp(-dt / time), 1.0)
    if isinstance(key, jax.Array):
        seed = np.asarray(jax.random.key_data(key)).ravel().tolist()
    else:
        seed = int(key)
    rng = np.random.default_rng(seed)
    u = sd_desired * rng.standard_normal(sd.size)
    return _Pace(rng, u, phi, sd_desired * np.sqrt(1.0 - phi**2))


def _pace_window(pace: _Pace, act: np.ndarray, n_steps: int, log: bool = False) -> np.ndarray:
    """(n_steps, len(act)) desired speed over preferred speed of the artefacts ``act`` at
    the steps of a window (the exact AR(1) of their OU log pace); advances ``pace.u``.
    ``log``: the process itself (a heading's deviation, rad), not its exponential."""
    eps = pace.rng.standard_normal((n_steps, act.size))
    u, phi, innovation = pace.u[act], pace.phi[act], pace.innovation[act]
    out = np.empty((n_steps, act.size))
    for s in range(n_steps):
        u = phi * u + innovation * eps[s]
        out[s] = u
    pace.u[act] = u
    return out if log else np.exp(out)


def _on_schedule(
    drift: np.ndarray,
    tt: np.ndarray,
    t_on: np.ndarray,
    due: np.ndarray,
    done: np.ndarray,
    varies: np.ndarray,
    relaxation: float,
    max_speed: float,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The pace ``drift`` (W, n) of a window made neutral over each walk: the walker keeps
    its plan's schedule. ``done`` (n,) is the plan's time (s) each walker has walked at its
    pace so far (the pace's integral since its arrival ``t_on``); at the step at ``tt[s]``
    its pace is multiplied by ``(due - t_on - done) / (due - tt[s])``, the speed that walks
    the rest of the plan by ``due`` (the plan's arrival at its last corner) at the rest of
    the pace (the time left at least ``relaxation``, the factor at least
    ``1 / max_speed``). So a fast spell is given back over the rest of the walk, and a slow
    one made up, instead of ending the walk early (and standing at the exit until the stay
    ends) or late; within the walk the log pace moves as before (the factor changes
    slowly, except in the last correlation time or so). Only ``varies`` (n,) walkers (a
    pace of sd > 0) are scaled: the others keep the pace 1, bit for bit. Returns the
    scaled drift and ``done`` at the window's end."""
    walking = varies & (tt[:, None] >= t_on) & (tt[:, None] < due)  # (W, n)
    cols = np.flatnonzero(walking.any(axis=0))
    out, done = drift.copy(), done.copy()
    if cols.size == 0:
        return out, done
    # only the columns walking in this window, each step's arithmetic as one (n,) pass
    walk = walking[:, cols]
    left = np.maximum(due[cols] - tt[:, None], relaxation)
    plan, d, sub = due[cols] - t_on[cols], done[cols], drift[:, cols]
    for s in range(drift.shape[0]):
        factor = (plan - d) / left[s]
        sub[s] = np.where(walk[s], sub[s] * np.maximum(factor, 1.0 / max_speed), sub[s])
        d = d + np.where(walk[s], sub[s] * dt, 0.0)
    out[:, cols], done[cols] = sub, d
    return out, done


def social_force_tracks(
    tracks: pd.DataFrame,
    params: SocialForce | None = None,
    grid: OccupancyGrid | None = None,
    *,
    dt: float = 0.1,
    kinematic: npt.ArrayLike | None = None,
    groups: npt.ArrayLike | None = None,
    progress: Callable[[int, int], None] | None = None,
    speed_variation: tuple | None = None,
    heading_variation: tuple | None = None,
) -> pd.DataFrame:
    """Planned tracks walked again with the social force (people give way to each other).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y, yaw`` (and optionally ``scenario``, and ``vx, vy``: the velocity at
        an artefact's first row, default 0): one row per artefact and epoch of its life, as
        the behaviours write them. Each artefact keeps its first and last
        time (its life-cycle) and its route (the corners of its planned path); it walks the
        route at its preferred speed (the median of its planned speeds; an artefact that
        never moves stands, and the others walk around it). Artefacts of different
        scenarios never meet.
    params : SocialForce, optional
        The model's parameters (default: the published values).
    grid : OccupancyGrid, optional
        The map: its occupied cells repel, and no step enters them.
    dt : float
        Integration step (s).
    kinematic : (n_tracks,) bool, optional
        Artefacts that keep their planned track exactly (vehicles, carts: no social force
        of their own) and are still avoided by the others, per row of ``tracks`` (True for
        any row of an artefact makes it kinematic). Standing artefacts always are.
    groups : (n_tracks,) array, optional
        Group label of each row's artefact (its first row counts; groups are per scenario;
        ``None``, NaN, ``""`` or a negative number: alone). The members of a group walk
        together (:mod:`~are_stats.behaviour._groups`): the first to arrive leads on its
        route, the others take the same route at the group's pace (the leader's preferred
        speed, one draw of the speed law per group: module docstring) and keep to their
        formation slot, abreast of the leader at
        ``params.group_spacing`` or, where the slot is not free (a door), that far behind
        it; members repel each other only on contact, everybody else as usual. When the
        leader has left, the others walk on along the shared route. Kinematic artefacts
        walk alone.
    progress : callable, optional
        ``progress(done, total)`` after each window of the simulation (``WINDOW_STEPS``
        steps of every scenario at once, one compiled program), ``total`` windows; the
        last call has ``done == total``.
    speed_variation : (key, sd, time), optional
        Within-person variation of the walking speed
        (``BehaviourFit.speed_within_sd``): each walker's desired
        speed is its preferred speed times ``exp(u(t))``, ``u`` a stationary
        Ornstein-Uhlenbeck process, drawn with ``key`` (a JAX PRNG key or an int seed),
        whose walked speed :func:`~are_stats.fitting.fit_behaviour` reads back as log-sd
        ``sd`` and correlation time ``time`` (s): the walked speed follows the desired
        one with the relaxation time ``tau``, so the desired process has correlation
        time ``time - tau`` (at least ``time / 2``) and sd ``sd sqrt(1 + tau / (2 (time -
        tau)))``, as the heading's (docs/src/behaviour.md). ``sd`` and ``time`` are
        numbers or one
        per track row (an artefact's first row counts; ``sd`` 0 or NaN: none). The members
        of a group keep their leader's pace. Default: each walker at its preferred speed
        throughout; ``sd = 0`` everywhere gives exactly the same tracks.
    heading_variation : (key, sd, time), optional
        Within-person variation of the walking heading
        (``BehaviourFit.heading_within_sd``): each walker's desired velocity points
        ``theta(t)`` (rad) off the straight line to its route's next corner, ``theta`` a
        stationary OU process drawn with ``key`` (its own, independent of the pace's),
        of sd ``sd`` (rad) and correlation time ``time`` (s) in the walked heading: the
        walked heading follows the desired one with the relaxation time ``tau``, so the
        desired one's correlation time is ``time - tau`` (at least ``time / 2``) and its
        sd ``sd sqrt(1 + tau / (2 (time - tau)))``: the walked heading is then read by
        :func:`~are_stats.fitting.fit_behaviour` as ``sd`` and ``time`` (its variance is
        ``sd^2 (1 - tau / (2 time))``, its integral correlation time ``time``; the fit's
        one OU reads the lagged process's variance over ``1 - tau / (2 time)``:
        docs/src/behaviour.md). It aims at the
        corner all the while, so the deviation stays bounded and the walker on its route
        (a heading-rate noise would drift off it). Arguments as ``speed_variation``'s.
        The members of a group turn with their leader (its ``theta``): in their slots
        they follow its velocity anyway, and a wander of their own would only pull them
        out of formation. Default (or ``sd = 0`` everywhere): straight at the corner,
        exactly as without it.

    Returns
    -------
    pandas.DataFrame
        The same rows (same ``id`` and ``t``, sorted by ``scenario``, ``id`` and ``t``) with
        ``x, y`` from the simulation and ``yaw`` along the direction of motion (the planned
        one while standing).
    """
    p = SocialForce() if params is None else SocialForce(*params)
    dt = float(check_positive("dt", dt))
    if len(tracks) == 0:
        return tracks.copy()
    by = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    base = tracks.reset_index(drop=True)
    perm = base.sort_values([*by, "t"], kind="stable").index.to_numpy()
    tab = base.iloc[perm].reset_index(drop=True)
    keys = tab[by].to_numpy()
    first = np.r_[True, (keys[1:] != keys[:-1]).any(axis=1)]
    start = np.flatnonzero(first)
    stop = np.r_[start[1:], len(tab)]
    t_all = tab["t"].to_numpy(float)
    xy_all = tab[["x", "y"]].to_numpy(float)
    n = start.size
    span = float(t_all.max() - t_all.min())
    steps_alive = float(np.sum(t_all[stop - 1] - t_all[start])) / dt + n
    check_memory(steps_alive * 24.0, f"social-force motion of {n} artefacts, dt {dt:g} s", "dt")
    check_work(steps_alive * 9.0 * CELL_CAPACITY * 30.0, f"social force of {n} artefacts", "dt")
    routes, v0 = _routes(t_all, xy_all, start, stop)
    t_on, t_off = t_all[start], t_all[stop - 1] + 1e-9
    # when each plan reaches its last corner (its last move; its arrival if it never
    # moves): a walker's pace keeps to that schedule (_on_schedule)
    moved = ~first & (np.r_[0.0, np.hypot(*np.diff(xy_all, axis=0).T)] > 1e-9)
    due = t_on.copy()
    np.maximum.at(due, np.repeat(np.arange(n), stop - start)[moved], t_all[moved])
    done = np.zeros(n)
    kin = v0 <= 0.0
    if kinematic is not None:
        rows = np.asarray(kinematic, bool)
        if rows.shape != (len(tracks),):
            raise ValueError(
                f"kinematic: expected one bool per track row ({len(tracks)}), got {rows.shape}"
            )
        rows = rows[perm]
        kin |= np.logical_or.reduceat(rows, start)
    gid = np.full(n, -1, np.int64)
    side = np.zeros(n)
    leader, ahead = np.arange(n), np.arange(n)
    if groups is not None:
        labels = np.asarray(groups, dtype=object)
        if labels.shape != (len(tracks),):
            raise ValueError(
                f"groups: expected one label per track row ({len(tracks)}), got {labels.shape}"
            )
        labels = labels[perm][start].copy()
        labels[kin] = None  # vehicles, carts and standing artefacts walk alone
        scen_of = tab["scenario"].to_numpy()[start] if "scenario" in tab.columns else None
        leader, slot = formation(scen_of if scen_of is not None else np.zeros(n), labels, t_on)
        side, _ = slot_offsets(slot, float(p.group_spacing))
        member = leader != np.arange(n)
        ahead = leader.copy()  # in single file each follows the member one slot ahead
        by_slot = {(int(leader[i]), int(slot[i])): i for i in range(n)}
        for i in np.flatnonzero(slot > 1):
            ahead[i] = by_slot[(int(leader[i]), int(slot[i]) - 1)]
        if member.any():
            gid[member] = leader[member]
            gid[leader[member]] = leader[member]
            # one pace per group, its leader's preferred speed (see the docstring)
            v0 = np.where(gid >= 0, v0[np.maximum(gid, 0)], v0)
            for i in np.flatnonzero(member):
                routes[i] = routes[leader[i]]  # one route: the leader's
    # each scenario on its own stretch of the plane, far from the others
    scen = (
        pd.factorize(tab["scenario"].to_numpy()[start])[0]
        if "scenario" in tab.columns
        else np.zeros(n, np.int64)
    )
    stride = float(np.ptp(xy_all[:, 0])) + 2.0 * p.reach + 10.0
    shift = np.column_stack([scen * stride, np.zeros(n)])
    m_max = _bucket(max(len(r) for r in routes), 16)  # a few route widths: few programs
    route = np.zeros((n, m_max, 2))
    n_vert = np.zeros(n, np.int32)
    for i, r in enumerate(routes):
        route[i, : len(r)] = r
        route[i, len(r) :] = r[-1]
        n_vert[i] = len(r)
    route = route + shift[:, None, :]
    walls, n_y = _walls(grid, xy_all, p.reach, float(shift[:, 0].max()))
    x = xy_all[start] + shift  # where each artefact arrives (a member: beside its leader)
    v = np.zeros((n, 2))
    if "vx" in tab.columns and "vy" in tab.columns:  # walking already when it appears
        v = np.nan_to_num(tab[["vx", "vy"]].to_numpy(float)[start])
    # each heads for its route's second vertex: the first is where it stands (aiming
    # at it would stop a walker that arrives walking for a step, a lag of tau's worth)
    k = np.minimum(n_vert - 1, 1).astype(np.int32)
    first_leg = route[:, min(1, m_max - 1)] - route[:, 0]
    norm = np.hypot(*first_leg.T)
    hd = np.where((norm > 1e-9)[:, None], first_leg / np.maximum(norm, 1e-9)[:, None], [1.0, 0.0])
    p_j = SocialForce(*(float(f) for f in p))
    pace = None
    if speed_variation is not None:
        pace = _pace(speed_variation, len(tracks), perm[start], p.relaxation, dt)
    wander = None
    if heading_variation is not None:
        wander = _pace(
            heading_variation,
            len(tracks),
            perm[start],
            p.relaxation,
            dt,
            "heading_variation",
            "rad",
        )
        if not (wander.innovation > 0).any() and not (wander.u != 0).any():
            wander = None  # nobody wanders: the program without the turn, bit for bit
    t0 = float(t_on.min())
    n_win = int(np.ceil(span / dt / WINDOW_STEPS)) + 1
    w_start = t0 + np.arange(n_win) * WINDOW_STEPS * dt
    active = [np.flatnonzero((t_on < w0 + WINDOW_STEPS * dt) & (t_off > w0)) for w0 in w_start]
    repel = bool(p.strength != 0.0)
    layout = _layout(active, scen, repel)
    sim_t, sim_x, sim_i = [], [], []
    for w, (w0, act) in enumerate(zip(w_start, active, strict=True)):
        if progress is not None and w:
            progress(w, n_win)
        if act.size == 0:
            continue
        all_pairs, block, nb, width = layout[w]
        if width:  # many small scenarios: a block of slots per scenario
            first_in, rank = np.unique(scen[act], return_index=True, return_inverse=True)[1:]
            rank = rank.ravel()  # act is sorted by scenario: each scenario a run
            slot = rank * width + (np.arange(act.size) - first_in[rank])
        else:
            slot = np.arange(act.size)
        pad = np.full(nb, act[0])
        pad[slot] = act
        live_pad = np.zeros(nb, bool)
        live_pad[slot] = True

        def take(a, pad=pad):
            return a[pad]

        state = (take(x), take(v), take(k), take(hd))
        slot_of = np.full(n, -1)
        slot_of[act] = slot

        def local(j, act=act, slot=slot, slot_of=slot_of, nb=nb):
            """Slot of each slot's leader (or member ahead): itself when not in the window."""
            loc = np.arange(nb)
            there = slot_of[j[act]]
            loc[slot] = np.where(there >= 0, there, slot)
            return loc.astype(np.int32)

        form = (
            local(leader),
            local(ahead),
            take(side),
            np.where(live_pad, gid[pad], -1),
        )
        t_on_w = np.where(live_pad, t_on[pad], np.inf)
        tt = w0 + dt * np.arange(1, WINDOW_STEPS + 1)
        # the steps anybody is alive in (all of them unless everybody leaves in this window)
        n_run = int(np.searchsorted(tt, t_off[act].max(), side="left"))
        plan = np.zeros((WINDOW_STEPS, nb, 2))
        pace_w = np.ones((WINDOW_STEPS, nb))
        # a member walks at its leader's pace and turns with it (when the leader is in the
        # window): the column of each slot's leader
        col = slot_of[leader[act]]
        col = np.where(col >= 0, col, slot)
        lead_col = np.argsort(slot)[np.searchsorted(np.sort(slot), col)]
        if pace is not None:
            drift = _pace_window(pace, act, WINDOW_STEPS)
            drift, done[act] = _on_schedule(
                drift,
                tt,
                t_on[act],
                due[act],
                done[act],
                pace.phi[act] < 1.0,
                p.relaxation,
                p.max_speed,
                dt,
            )
            pace_w[:, slot] = drift[:, lead_col]
        turn_w = None
        if wander is not None:
            turn_w = np.zeros((WINDOW_STEPS, nb))
            turn_w[:, slot] = _pace_window(wander, act, WINDOW_STEPS, log=True)[:, lead_col]
            turn_w = jax.device_put(turn_w)
        moves_plan = kin[act]  # only the kinematic artefacts follow a plan
        for c, i in zip(slot[moves_plan], act[moves_plan], strict=True):
            a, b = start[i], stop[i]
            plan[:, c, 0] = np.interp(tt, t_all[a:b], xy_all[a:b, 0]) + shift[i, 0]
            plan[:, c, 1] = np.interp(tt, t_all[a:b], xy_all[a:b, 1]) + shift[i, 1]
        (xf, vf, kf, hf), xs = _window(
            state,
            take(route),
            take(n_vert),
            take(v0),
            t_on_w,
            take(t_off),
            take(kin),
            plan,
            pace_w,
            take(shift),
            form,
            w0,
            dt,
            p_j,
            walls,
            np.int32(n_run),
            np.int32(n_y),
            all_pairs,
            block,
            repel,
            turn=turn_w,
        )
        xf, vf, kf, xs = np.asarray(xf), np.asarray(vf), np.asarray(kf), np.asarray(xs)
        x[act], v[act], k[act] = xf[slot], vf[slot], kf[slot]
        hd[act] = np.asarray(hf)[slot]
        alive = (tt[:, None] >= t_on[act][None, :]) & (tt[:, None] < t_off[act][None, :])
        si, ai = np.nonzero(alive)
        sim_t.append(tt[si])
        sim_x.append(xs[si, slot[ai]] - shift[act[ai]])
        sim_i.append(act[ai])
    if progress is not None:
        progress(n_win, n_win)
    st = np.concatenate(sim_t) if sim_t else np.zeros(0)
    sx = np.concatenate(sim_x) if sim_x else np.zeros((0, 2))
    si = np.concatenate(sim_i) if sim_i else np.zeros(0, np.int64)
    order = np.lexsort((st, si))
    st, sx, si = st[order], sx[order], si[order]
    # each walker's samples after its arrival point, interpolated at its rows (all walkers
    # at once: _interp_runs); a kinematic artefact keeps its plan, row for row
    bounds = np.searchsorted(si, np.arange(n + 1)) + np.arange(n + 1)
    t_walk = np.empty(st.size + n)
    x_walk = np.empty((st.size + n, 2))
    t_walk[bounds[:-1]], x_walk[bounds[:-1]] = t_on, xy_all[start]
    later = np.ones(t_walk.size, bool)
    later[bounds[:-1]] = False
    t_walk[later], x_walk[later] = st, sx
    owner = np.repeat(np.arange(n), stop - start)
    rows = np.flatnonzero(~kin[owner])
    out_xy = xy_all.copy()
    out_xy[rows] = _interp_runs(t_all[rows], owner[rows], t_walk, x_walk, bounds)
    yaw = tab["yaw"].to_numpy(float).copy() if "yaw" in tab.columns else np.zeros(len(tab))
    # the yaw along each walker's moves of over 1 mm (the row before's otherwise)
    d = out_xy[1:] - out_xy[:-1]
    moving = (np.hypot(*d.T) > 1e-3) & ~first[1:] & ~kin[owner[1:]]
    yaw[1:][moving] = np.arctan2(d[moving, 1], d[moving, 0])
    out = tab.copy()
    out["x"], out["y"], out["yaw"] = out_xy[:, 0], out_xy[:, 1], yaw
    return out


def _group_codes(ids: np.ndarray, groups: Mapping[Hashable, Hashable]) -> np.ndarray:
    """(n,) int code of each row's group (``-1``: alone; a missing label, ``None``, NaN,
    ``""`` or a negative number)."""
    lab = pd.Series([groups.get(i) for i in ids], dtype=object)
    num = pd.to_numeric(lab, errors="coerce")
    alone = lab.isna() | lab.astype(str).isin(["", "nan", "None"]) | (num < 0).to_numpy()
    code = pd.factorize(lab.astype(str))[0]
    return np.where(alone.to_numpy(), -1, code)


#: Accelerations are second differences over ``d`` steps, ``d`` the fewest whose noise
#: (``sqrt(6) s / (d dt)^2`` for position noise of sd ``s``) is at most this (m/s^2: the
#: push of a passer-by), up to :data:`ACCELERATION_SPAN` seconds; the state is estimated
#: from ``d + 1`` samples on either side.
ACCELERATION_NOISE = 1.0
ACCELERATION_SPAN = 0.4
#: Step (s) of the simulation the fitted parameters are for (:func:`social_force_tracks`'s
#: default ``dt``): its semi-implicit Euler step is the continuous model with ``tau - h/2``
#: and ``A tau / (tau - h/2)`` to first order in ``h``.
SIMULATION_STEP = 0.1
#: Polynomial order of the paths the state's weights are exact for.
STATE_ORDER = 2
#: SIMEX's raised noise variances (in units of the tracker's) and replicates of each.
SIMEX_LAMBDAS = (0.5, 1.0, 1.5, 2.0)
SIMEX_REPLICATES = 2
#: Position noise (m) from which the accelerations and the state are read from a smoother
#: (:func:`_smoothed_design`) instead of differences of the samples.
SMOOTH_NOISE = 0.02
#: Corrections of the fit by simulation (:func:`_simulation_correction`), noise draws of
#: each simulated crowd, and the largest factor one correction applies.
CORRECTIONS = 2
SIMULATION_NOISE_DRAWS = 2
MAX_CORRECTION = 4.0
#: Relaxation time (s) past which a fit is no estimate (published values are 0.3-1 s).
MAX_RELAXATION = 5.0
#: Nodes (in units of the second difference's span) and weights of the quadrature of the
#: triangle-weighted mean over ``-1 .. 1`` (composite Simpson's rule on each half).
NODES = np.array([-0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75])
NODE_WEIGHTS = np.array([1.0, 1.0, 3.0, 2.0, 3.0, 1.0, 1.0]) / 12.0


def _state_weights(
    half: int, lag: int, at: float, derivative: int, order: int = STATE_ORDER
) -> np.ndarray:
    """(2 half + 1,) weights over samples ``-half .. half`` giving the position
    (``derivative`` 0) or the velocity times the step (1) at ``at`` steps, exact for
    paths polynomial up to ``order``, orthogonal to the second difference over
    ``-lag, 0, lag`` (so independent of its white noise), of least variance under white
    noise."""
    j = np.arange(-half, half + 1, dtype=float)
    rows = [j**p for p in range(order + 1)]
    rhs = [at**p if derivative == 0 else p * at ** max(p - 1, 0) for p in range(order + 1)]
    if derivative == 1:
        rhs[0] = 0.0
    contrast = np.zeros_like(j)
    contrast[[half - lag, half + lag]] = 1.0
    contrast[half] = -2.0
    a = np.vstack([*rows, contrast])
    b = np.array([*rhs, 0.0])
    return a.T @ np.linalg.solve(a @ a.T, b)


def _node_states(
    xy: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    dt: float,
    half: int,
    lag: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each sample's position and velocity (Q, n, 2) at the nodes ``-lag/2, 0, lag/2``
    steps from it (Q = 3), and whether (n,) bool it has ``half`` samples on either side in
    its track. With them, the weights of :func:`_state_weights`; without (samples near a
    track's ends, which only serve as neighbours), the sample moved along its central (or
    one-sided) difference."""
    start = np.flatnonzero(first)
    stop = np.flatnonzero(last)
    who = np.cumsum(first) - 1
    k = np.arange(len(xy))
    left, right = k - start[who], stop[who] - k
    full = np.minimum(left, right) >= half
    v_fb = np.zeros_like(xy)
    both = (left >= 1) & (right >= 1)
    kb = np.flatnonzero(both)
    v_fb[kb] = (xy[kb + 1] - xy[kb - 1]) / (2.0 * dt)
    kf = np.flatnonzero(~both & (right >= 1))
    v_fb[kf] = (xy[kf + 1] - xy[kf]) / dt
    kl = np.flatnonzero(~both & (left >= 1))
    v_fb[kl] = (xy[kl] - xy[kl - 1]) / dt
    nodes = NODES * lag
    pos = np.stack([xy + s * dt * v_fb for s in nodes])
    vel = np.stack([v_fb] * len(nodes))
    kk = np.flatnonzero(full)
    for q, s in enumerate(nodes):
        w_p = _state_weights(half, lag, s, 0)
        w_v = _state_weights(half, lag, s, 1) / dt
        pos[q, kk] = 0.0
        vel[q, kk] = 0.0
        for o, (a, b) in enumerate(zip(w_p, w_v, strict=True)):
            pos[q, kk] += a * xy[kk + o - half]
            vel[q, kk] += b * xy[kk + o - half]
    return pos, vel, full


def _equal_step(t: np.ndarray, first: np.ndarray) -> float:
    """The one time step (s) of tracks sorted by id and time (``first`` (n,) bool marks
    each track's first row).

    Raises
    ------
    ValueError
        Without two samples in a track, or with unequal steps.
    """
    steps = np.diff(t)[~first[1:]]
    if steps.size == 0:
        raise ValueError("tracks: expected tracks of at least three samples")
    dt = float(np.median(steps))
    if not np.allclose(steps, dt, rtol=1e-6, atol=1e-9):
        raise ValueError(
            f"tracks: expected equally spaced times, got steps from {steps.min()} to {steps.max()}"
        )
    return dt


def _sorted_rows(
    tracks: pd.DataFrame,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The rows of ``tracks`` in id and time order: ids, times, positions (n, 2), each
    track's first and last rows as (n,) bool, and the one time step (:func:`_equal_step`)."""
    tab = tracks.sort_values(["id", "t"], kind="stable")
    ids = tab["id"].to_numpy()
    t = tab["t"].to_numpy(float)
    raw = tab[["x", "y"]].to_numpy(float)
    first = np.r_[True, ids[1:] != ids[:-1]]
    last = np.r_[first[1:], True]
    return ids, t, raw, first, last, _equal_step(t, first)


def _neighbour_pairs(
    t: np.ndarray, pos: np.ndarray, dt: float, reach: float, label: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """The ordered pairs (i, j) (P,) int of samples at one time within ``reach`` of each
    other (positions ``pos`` (n, 2)), pairs of one group (``label`` (n,), ``-1`` alone) left
    out."""
    from scipy.spatial import cKDTree  # lazy: +0.25 s CPU on `import are_stats.behaviour`

    order = np.argsort(t, kind="stable")
    ts = t[order]
    cut = np.r_[0, np.flatnonzero(np.diff(ts) > 1e-6 * dt) + 1, ts.size]
    pi, pj = [], []
    for a, b in zip(cut[:-1], cut[1:], strict=True):
        idx = order[a:b]
        if idx.size < 2:
            continue
        pr = cKDTree(pos[idx]).query_pairs(reach, output_type="ndarray")
        if pr.size:
            pi.append(np.r_[idx[pr[:, 0]], idx[pr[:, 1]]])
            pj.append(np.r_[idx[pr[:, 1]], idx[pr[:, 0]]])
    pi = np.concatenate(pi) if pi else np.zeros(0, np.int64)
    pj = np.concatenate(pj) if pj else np.zeros(0, np.int64)
    if label is not None and pi.size:
        # group mates: the formation, not the repulsion, keeps them apart (the pair term
        # leaves them out while they walk at their spacing, _pair_term's ``mates``), so
        # their pairs are no evidence about A and B
        pair_ok = ~((label[pi] >= 0) & (label[pi] == label[pj]))
        pi, pj = pi[pair_ok], pj[pair_ok]
    return pi, pj


class _Smoothing(TypedDict):
    """What :func:`_smoothed_acceleration` needs of the smoother: each row's track number
    ``who`` and index in its track ``at`` (n,), and the smoother's position noise sd (m)
    and white jerk (m^2/s^5)."""

    at: np.ndarray
    who: np.ndarray
    noise: float
    jerk: float


class _Design(TypedDict):
    """The least squares of :func:`fit_social_force` before ``B`` is chosen
    (:func:`_acceleration_design`, :func:`_smoothed_design`; the keys are said there): the
    arrays are NumPy's, ``n``, ``n_people`` and ``m`` counts, ``dt`` (s) and ``v_var``
    floats; ``smooth`` only from the smoothed state."""

    n: int
    inner: np.ndarray
    pi: np.ndarray
    pj: np.ndarray
    dist: np.ndarray
    n_hat: np.ndarray
    y: np.ndarray
    person: np.ndarray
    e_col: np.ndarray
    minus_v: np.ndarray
    n_people: int
    m: int
    dt: float
    v_var: float
    smooth: NotRequired[_Smoothing]


def _acceleration_design(
    tracks: pd.DataFrame,
    base: SocialForce,
    min_speed: float,
    groups: Mapping[Hashable, Hashable] | None,
    noise: float,
) -> _Design:
    """The least squares of :func:`fit_social_force` before ``B`` is chosen: the observed
    accelerations ``y`` (2m,) (x, y interleaved), the columns of ``1/tau`` (``minus_v``) and
    of the ``v0_i / tau`` (``e_col`` in row ``person``), the samples used (``inner``), the
    neighbour pairs within reach (``pi``, ``pj``) with their anticipated separations at
    the Q nodes (``dist`` (Q, P), ``n_hat`` (Q, P, 2)), ``n`` (samples), ``n_people``,
    ``m``, ``dt``, and ``v_var`` (the variance of ``minus_v``'s noise per unit variance of
    the position noise).

    The acceleration at sample ``k`` is the second difference over ``k - d, k, k + d``
    (``d`` steps: :data:`ACCELERATION_NOISE`, ``noise`` the position noise's sd), the
    triangle-weighted mean of the
    acceleration over that span; the model's is the mean of its values at ``-d/2, 0, d/2``
    (Simpson's rule for the triangle), each at the state (position, velocity, the
    anticipated separations from the neighbours) estimated from ``k - d - 1 .. k + d + 1``
    by weights orthogonal to the second difference
    (:func:`_state_weights`). So white position noise enters the acceleration and the
    regressors independently: no errors-in-variables correlation, which with the state
    from ``k - 1, k`` (a backward difference) read 1 cm of noise at 10 Hz as a strength of
    3.4 for 2.1. Only samples with ``d + 1`` neighbours on either side are used."""
    ids, t, raw, first, last, dt = _sorted_rows(tracks)
    lag = 1  # the second difference's span, in steps
    acc_noise = np.sqrt(6) * noise / dt**2
    while lag < ACCELERATION_SPAN / dt and acc_noise > ACCELERATION_NOISE * lag**2:
        lag += 1
    half = lag + 1
    pos, vel, full = _node_states(raw, first, last, dt, half, lag)
    who = np.cumsum(first) - 1
    dest = raw[np.flatnonzero(last)][who]
    inner = np.flatnonzero(full)
    acc = (raw[inner + lag] - 2 * raw[inner] + raw[inner - lag]) / (lag * dt) ** 2
    v_mean = np.einsum("q,qnc->nc", NODE_WEIGHTS, vel[:, inner])
    mid = int(np.argmin(np.abs(NODES)))
    to = dest[inner] - pos[mid, inner]
    e = to / np.maximum(np.hypot(*to.T), 1e-9)[:, None]
    use = (np.hypot(*v_mean.T) >= min_speed) & (np.hypot(*to.T) > 0.5)
    label = None if groups is None else _group_codes(ids, groups)
    if label is not None:  # members head for their slot, not their destination
        use &= label[inner] < 0
    inner, acc, e, v_mean = inner[use], acc[use], e[use], v_mean[use]
    # the triangle-weighted mean of the velocity over the span is the central difference
    # (integrating by parts, up to the trapezoid rule's error): antisymmetric, so it too
    # is independent of the second difference's noise
    v_mean = (raw[inner + lag] - raw[inner - lag]) / (2 * lag * dt)
    m = inner.size
    if m < 10:
        raise ValueError(f"tracks: expected at least 10 walking samples, got {m}")
    pi, pj = _neighbour_pairs(t, pos[mid], dt, base.reach, label)
    diff = _anticipated(pos[:, pi] - pos[:, pj], vel[:, pi] - vel[:, pj], base.horizon)
    dist = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), 1e-9)
    return {
        "n": len(raw),
        "inner": inner,
        "pi": pi,
        "pj": pj,
        "dist": dist,
        "n_hat": diff / dist[..., None],
        "y": acc.reshape(-1),  # x, y interleaved per sample
        "person": np.repeat(who[inner], 2),  # the one per-person column each row touches
        "e_col": e.reshape(-1),  # its value there (v0_i / tau times the destination direction)
        "minus_v": -v_mean.reshape(-1),  # the column of 1 / tau
        "n_people": int(who.max()) + 1,
        "m": m,
        "dt": dt,
        "v_var": 0.5 / (lag * dt) ** 2,
    }


def _repulsion_column(d: _Design, radius: float, b_range: float) -> np.ndarray:
    """(2m,) the column of ``A`` in :func:`_acceleration_design`'s least squares for the
    range ``b_range``: each used sample's summed unit repulsions, averaged over the nodes
    (or, for :func:`_smoothed_design`, through the smoother)."""
    g = np.zeros((d["dist"].shape[0], d["n"], 2))
    push = np.exp((2 * radius - d["dist"]) / b_range)[..., None] * d["n_hat"]
    for q in range(g.shape[0]):
        np.add.at(g[q], d["pi"], push[q])
    if "smooth" in d:
        return _smoothed_acceleration(d, g[0]).reshape(-1)
    return np.einsum("q,qnc->nc", NODE_WEIGHTS, g)[d["inner"]].reshape(-1)


#: Spectral density (m^2/s^5) of the white jerk of the smoother's walk
#: (:func:`~are_stats.behaviour._smoother.smooth_tracks`): a push of 2 m/s^2 that builds
#: up and fades in about 0.3 s.
JERK_DENSITY = 10.0
#: Samples within this many seconds (and at least 2 samples) of a track's end are not
#: fitted (the smoother sees them from one side only); they serve as neighbours.
SMOOTH_EDGE = 0.4
#: White jerk (m^2/s^5) of the smoother that gives the state the repulsion is evaluated at
#: (positions and velocities of the anticipated separations): smoother than the
#: accelerations', since the velocity's noise times the 2 s horizon is the separations'
#: (with the accelerations' 10: 5 cm at 10 Hz read the published 2.1 as 1.06 for 1.36).
STATE_JERK = 1.0
#: Share of the worst-fitted samples the least squares' second pass leaves out.
FIT_TRIM = 0.02
#: Close passes (:func:`_close_passes`): pairs of people ever within this many metres of
#: each other at one sample count, each by ``exp(-(d - 2 r) / PASS_SCALE)`` of its
#: closest smoothed distance ``d`` (m); :func:`repulsion_evidence` reads them from
#: :data:`PASS_MIN_PAIRS` such pairs on, and decides where the tracks' lie within the
#: first or last :data:`PASS_BAND` of the way (in logs) from the crowd re-walked under
#: the published force to the crowd re-walked under none.
PASS_REACH = 2.0
PASS_SCALE = 0.3
PASS_MIN_PAIRS = 20
PASS_BAND = 1.0 / 3.0


def _smoothed_acceleration(d: _Design, seq: np.ndarray) -> np.ndarray:
    """(m, c) the smoother's acceleration at the used samples of the path whose
    acceleration is ``seq`` (n, c), one value per sample (constant over the step after it),
    integrated twice along each track from rest at its first sample: the smoother's own
    kernel applied to ``seq``, as the observed accelerations have it applied to the walk's
    (so a pulse of repulsion the smoother flattens is flattened in the model too)."""
    sm = d["smooth"]
    dt, at, who = d["dt"], sm["at"], sm["who"]
    start = np.flatnonzero(at == 0)

    def along(x: np.ndarray) -> np.ndarray:
        """Cumulative sums of ``x`` (n, c) along each track (rows sorted by track)."""
        cs = np.cumsum(x, axis=0)
        return cs - (cs[start] - x[start])[who]

    vel = along(seq) * dt - seq * dt  # the velocity at each sample, before its step
    moved = vel * dt + seq * (0.5 * dt * dt)
    pos = along(moved) - moved  # the position at each sample
    acc = smooth_samples(pos, who, at, dt, sm["noise"], sm["jerk"])[2]
    return acc[d["inner"]]


def _smoothing_rows(
    tracks: pd.DataFrame,
) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float
]:
    """The rows of ``tracks`` in id and time order, as the smoother reads them: ids,
    times, positions (n, 2), each row's track number and index in its track (n,), each
    track's first and last row (T,), and the one time step (:func:`_equal_step`). Checks
    the smoother's memory (six (n, 2) float arrays, twice) before it is spent."""
    ids, t, raw, first, last, dt = _sorted_rows(tracks)
    who = np.cumsum(first) - 1
    start, stop = np.flatnonzero(first), np.flatnonzero(last)
    at = np.arange(len(raw)) - start[who]
    check_memory(8 * len(raw) * 2 * 2 * 6, "the smoothed tracks")
    return ids, t, raw, who, at, start, stop, dt


def _smoothed_design(
    tracks: pd.DataFrame,
    base: SocialForce,
    min_speed: float,
    groups: Mapping[Hashable, Hashable] | None,
    noise: float,
    jerk: float | None = None,
) -> _Design:
    """:func:`_acceleration_design`'s least squares from a smoothed state (same keys, one
    node, and ``smooth``, what :func:`_smoothed_acceleration` needs).

    Each track is smoothed by a constant-acceleration Kalman filter and RTS smoother
    (:func:`~are_stats.behaviour._smoother.smooth_tracks`, observation noise ``noise``,
    white jerk ``jerk``). The observed acceleration is the smoother's, at each sample
    ``SMOOTH_EDGE`` s or more from its track's ends: a linear, nearly time-symmetric
    filter ``K`` of the positions, so the walk's acceleration ``K * a`` (plus noise). The
    model's is ``K`` applied to the model's acceleration: the velocity column is the
    smoothed velocity (``K * v``, the derivative of the same smoother, and its noise odd
    in time where the acceleration's is even, so independent of it at one sample), the
    destination and repulsion columns their instantaneous values at the smoothed states,
    integrated twice along the track and passed through the smoother
    (:func:`_smoothed_acceleration`); the state those are evaluated at comes from a
    smoother of less jerk (:data:`STATE_JERK`). ``v_var`` is the smoothed velocity's noise
    variance per unit position noise (white noise through the smoother)."""

    ids, t, raw, who, at, start, stop, dt = _smoothing_rows(tracks)
    k = np.arange(len(raw))
    n_tracks = start.size
    jerk = JERK_DENSITY if jerk is None else jerk
    sm = {"at": at, "who": who, "noise": float(noise), "jerk": float(jerk)}
    state = smooth_samples(raw, who, at, dt, noise, jerk)  # (3, n, 2)
    pos, vel, acc = state
    edge = max(2, int(np.ceil(SMOOTH_EDGE / dt - 1e-9)))
    full = np.minimum(at, stop[who] - k) >= edge
    dest = raw[stop][who]
    to = dest - pos
    e_all = to / np.maximum(np.hypot(*to.T), 1e-9)[:, None]
    use = full & (np.hypot(*vel.T) >= min_speed) & (np.hypot(*to.T) > 0.5)
    label = None if groups is None else _group_codes(ids, groups)
    if label is not None:  # members head for their slot, not their destination
        use &= label < 0
    inner = np.flatnonzero(use)
    m = inner.size
    if m < 10:
        raise ValueError(f"tracks: expected at least 10 walking samples, got {m}")
    pos_g, vel_g, _ = smooth_samples(raw, who, at, dt, noise, STATE_JERK)
    pi, pj = _neighbour_pairs(t, pos_g, dt, base.reach, label)
    diff = _anticipated(pos_g[pi] - pos_g[pj], vel_g[pi] - vel_g[pj], base.horizon)[None]
    dist = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), 1e-9)
    d = {
        "n": len(raw),
        "inner": inner,
        "pi": pi,
        "pj": pj,
        "dist": dist,
        "n_hat": diff / dist[..., None],
        "y": acc[inner].reshape(-1),
        "person": np.repeat(who[inner], 2),
        "minus_v": -vel[inner].reshape(-1),
        "n_people": n_tracks,
        "m": m,
        "dt": dt,
        "smooth": sm,
    }
    d["e_col"] = _smoothed_acceleration(d, e_all).reshape(-1)
    # the smoothed velocity's noise per unit position noise: white noise through it
    rng = np.random.default_rng(0)
    v_noise = smooth_samples(rng.normal(0.0, 1.0, raw.shape), who, at, dt, noise, jerk)[1]
    v_noise = v_noise[inner]
    d["v_var"] = float(np.mean(v_noise**2))
    return d


def _profiled_least_squares(
    w: np.ndarray,
    person: np.ndarray,
    n_people: int,
    e_col: np.ndarray,
    y: np.ndarray,
    cols: tuple[np.ndarray, np.ndarray],
    *,
    inverse: bool = False,
    noise_var: float = 0.0,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, int]:
    """Weighted least squares (weights ``w`` (2m,)) of ``y`` on a per-person column
    (``e_col``, person ``person`` of each row) and two shared columns ``cols``, the first
    measured with white noise of variance ``noise_var`` independent of ``y``'s (its
    square sum in the normal equations less the noise's expectation, for weights of 0 or
    1: the method-of-moments correction for errors in variables, which otherwise shrink
    its coefficient).

    The per-person columns touch disjoint rows, so the normal equations are a diagonal
    block and a 2 x 2 one: the per-person coefficients are eliminated (Schur complement)
    in O(rows) instead of a dense (2m x n_people) solve.

    Returns
    -------
    beta : (2,) float
        The shared coefficients (``lstsq`` of the Schur complement, or with ``inverse``
        its pseudo-inverse times the right-hand side).
    inv : (2, 2) float or None
        With ``inverse``, the Schur complement's pseudo-inverse (the shared coefficients'
        covariance up to the residual variance); else None.
    res : (2m,) float
        Residuals (fit - ``y``).
    n_per : int
        Per-person coefficients fitted (people with weight).
    """

    def per_person(v: np.ndarray) -> np.ndarray:
        return np.bincount(person, weights=w * v, minlength=n_people)

    d = per_person(e_col * e_col)
    has = d > 0
    d_inv = np.where(has, 1.0 / np.where(has, d, 1.0), 0.0)
    b_p = per_person(e_col * y)
    c = np.stack([per_person(e_col * col) for col in cols], axis=1)  # (P, 2)
    f = np.array([[np.sum(w * u * v) for v in cols] for u in cols])
    rhs = np.array([np.sum(w * col * y) for col in cols])
    schur = f - c.T @ (d_inv[:, None] * c)
    # the noise's expected share of the first column's square sum, less the share its
    # per-person projections took (one noise variance per person, for 0/1 weights)
    schur[0, 0] -= noise_var * (np.sum(w) - np.sum(has))
    inv = None
    if inverse:
        inv = np.linalg.pinv(schur)
        beta = inv @ (rhs - c.T @ (d_inv * b_p))
    else:
        beta = np.linalg.lstsq(schur, rhs - c.T @ (d_inv * b_p), rcond=None)[0]
    alpha = d_inv * (b_p - c @ beta)
    res = e_col * alpha[person] + cols[0] * beta[0] + cols[1] * beta[1] - y
    return beta, inv, res, int(has.sum())


def fit_social_force(
    tracks: pd.DataFrame,
    *,
    base: SocialForce | None = None,
    ranges: npt.ArrayLike | None = None,
    min_speed: float = 0.2,
    groups: Mapping[Hashable, Hashable] | None = None,
    noise: float | None = None,
    step: float = SIMULATION_STEP,
    simex: bool = True,
    smooth: bool | None = None,
    corrections: int = CORRECTIONS,
) -> tuple[SocialForce, dict[str, float]]:
    """Estimate ``A``, ``B`` and ``tau`` from observed tracks by least squares on the
    accelerations (as Johansson, Helbing and Shukla 2007 calibrated the model).

    Every person is taken to head for the last point of its track at its own preferred
    speed ``v0_i`` (unknown, estimated with the rest): its acceleration at each inner
    sample is ``(v0_i e_i - v_i) / tau + sum_j A exp((2 r - d*_ij) / B) n*_ij`` with ``e_i``
    the unit vector to its destination and ``d*``, ``n*`` the anticipated separation of
    the pair (:class:`SocialForce`'s ``horizon``, over the neighbours within ``reach``), so
    for a fixed ``B`` the model is linear in ``1/tau``, ``A`` and the ``v0_i / tau``; ``B``
    is chosen on a grid by the residual sum of squares. The samples must be equally spaced
    in time (one step for everybody).

    Tracker noise: below :data:`SMOOTH_NOISE` (``noise``, read from the tracks by
    :func:`~are_stats.behaviour.tracker_noise`), the accelerations are second differences
    and the state they are regressed on (positions, velocities, anticipated separations)
    is estimated from the neighbouring samples by weights orthogonal to them
    (:func:`_acceleration_design`), so the noise in the two is independent (with the
    state from finite differences of the same samples, 1 cm of noise at 10 Hz read the
    published 2.1 m/s^2 as 3.4 and ``tau`` 0.5 s as 0.1 s); the velocities' noise is
    subtracted from the normal equations (method of moments). From :data:`SMOOTH_NOISE`
    on, second differences drown in the noise (5 cm at 10 Hz: 12 m/s^2 per sample), and
    the accelerations and the state are read from a constant-acceleration Kalman
    smoother of each track instead (:func:`_smoothed_design`: the model's acceleration
    passed through the same smoother, so a push it flattens is flattened in both).

    What noise remains in the regressors still shrinks their coefficients, and at 2.5 Hz
    the force changes within a step. So the estimate is corrected by simulation
    (``corrections`` times; indirect inference, Gourieroux, Monfort and Renault 1993:
    :func:`_simulation_correction`): the tracks' people walked again by the model at the
    estimate (straight to their last point at their own speed, :func:`social_force_tracks`
    with the simulation's step ``step``), seen with the tracker's noise, fitted the same
    way at the tracks' ``B``; ``A`` and ``tau`` are scaled by the ratio of the tracks'
    estimate to the simulated tracks', until the simulated tracks give the tracks'
    estimate (``B`` is kept: the smoothed state's is nearly unbiased, and correcting it
    too walks along the ridge ``A exp(-d / B)`` of the distances seen). The
    estimator it corrects need not be unbiased, only the same on both; the parameters it
    returns are those of the simulation's semi-implicit Euler step (the least squares'
    continuous ``tau_c``, ``A_c`` as ``tau = tau_c + h/2``, ``A = A_c tau_c / tau``, to
    first order in ``h``). With ``corrections=0``, the least squares alone (with SIMEX on
    the repulsion, ``simex``: the fit repeated with the noise variance raised by 0.5-2
    times its own, ``1/tau`` and ``A`` extrapolated back to no noise by a quadratic).

    Recovery (crowds of 60 walked with the published 2.1 m/s^2, 0.3 m, 0.5 s; six seeds,
    bias (sd)): at 10 Hz without noise A +0.03 (0.06), tau -0.01 (0.01) s; with 1 cm
    -0.12 (0.12), -0.00 (0.02); with 5 cm -0.47 (0.33), +0.08 (0.09) (second differences
    and SIMEX: -1.40 (0.16), +0.39); at 2.5 Hz without noise -0.25 (0.30), +0.05 (0.05)
    (-0.71, +0.20); with 5 cm still -1.10 (0.20), +0.36 (0.10) (-1.28, +0.51). The
    correction costs ``corrections`` simulations of the tracks' people and twice as many
    fits.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene, equally spaced times.
    base : SocialForce, optional
        The parameters not estimated (``radius``, ``horizon``, ``reach``, the walls').
    ranges : array of float, optional
        Candidate ``B`` (m); default 0.1 to 1.0 m in steps of 0.025 m.
    min_speed : float
        Samples where the person moves slower (m/s) are left out (standing is not walking).
    groups : Mapping, optional
        Group label of each track id (ids missing or labelled ``None``, NaN, ``""`` or a
        negative number walk alone). A group's members walk in formation
        (:func:`social_force_tracks`): they head for a slot beside their leader, not for
        their destination, and repel each other only inside the group's spacing. So their
        own accelerations are left out of the least squares and the pairs of one group out
        of the repulsion sums; members still repel the people outside their group. Without
        it, a log with groups walking abreast gives a repulsion far too weak (every
        untroubled pair at 0.7 m reads as no push at that distance).

    noise : float, optional
        Sd (m) of the tracker's position noise per coordinate; default: read from the
        tracks (:func:`~are_stats.behaviour.tracker_noise`).
    step : float
        Step (s) of the simulation the parameters are for (:data:`SIMULATION_STEP`).
    simex : bool
        Without ``corrections``, correct the repulsion for the noise by SIMEX (with noise
        only).
    smooth : bool, optional
        Read the accelerations and the state from the smoothed tracks
        (:func:`_smoothed_design`); default: from :data:`SMOOTH_NOISE` of noise on.
    corrections : int
        Corrections by simulation (:func:`_simulation_correction`; 0: none).

    Returns
    -------
    SocialForce
        ``base`` with the estimated ``strength``, ``range`` and ``relaxation``.
    dict
        ``rss`` (residual sum of squares), ``n`` (accelerations used), ``r2`` (share of the
        acceleration variance explained), ``dt`` (the sampling step), ``noise`` (the
        position noise's sd corrected for), all of the fit to the tracks as they are;
        ``strength_direct`` and ``relaxation_direct`` (the least squares' estimate, before
        the correction) and ``corrections`` (made).

    Raises
    ------
    ValueError
        With fewer than 10 walking samples, or unequal time steps; or when no parameters
        of the model reproduce the tracks' estimate (the correction would scale one by
        :data:`MAX_CORRECTION` or more, the range is at an end of ``ranges``, or the
        relaxation time past :data:`MAX_RELAXATION`).
    """
    base = SocialForce() if base is None else base
    ranges = np.linspace(0.1, 1.0, 37) if ranges is None else np.asarray(ranges, float)
    sd = tracker_noise(tracks) if noise is None else float(noise)
    smooth = sd >= SMOOTH_NOISE if smooth is None else bool(smooth)
    # corrected by simulation, the estimator needs no SIMEX of its own (the simulated
    # tracks' estimates carry the same attenuation as the tracks')
    simex = simex and corrections <= 0
    params, info = _direct_fit(tracks, base, ranges, min_speed, groups, sd, step, simex, smooth)
    info = {
        **info,
        "noise": sd,
        "strength_direct": params.strength,
        "relaxation_direct": params.relaxation,
        "corrections": 0.0,
    }
    if corrections > 0 and _in_range(params):
        if params.relaxation > MAX_RELAXATION:
            # nobody steers to a goal over this long: the model does not describe them
            raise ValueError(
                f"tracks: the social force's relaxation time reads {params.relaxation:.3g} s "
                f"(strength {params.strength:.3g} m/s^2), past {MAX_RELAXATION:g} s: they do "
                f"not walk as the model walks, or too little near each other to tell"
            )
        if ranges.size > 2 and params.range in (ranges.min(), ranges.max()):
            # a range at the end of its grid is no estimate of it: nothing to correct at
            raise ValueError(
                f"tracks: the social force's range is at the end of its grid "
                f"({params.range:.3g} m of {ranges.min():.3g}-{ranges.max():.3g}): too little "
                f"walking near each other to estimate it, or no repulsion in them"
            )
        params, done = _simulation_correction(
            tracks, params, (ranges, min_speed, groups, sd, step, simex, smooth), corrections
        )
        info["corrections"] = float(done)
    return params, info


def _in_range(params: SocialForce) -> bool:
    """Whether a fitted force can be simulated (positive finite strength and relaxation)."""
    return bool(
        np.isfinite(params.strength)
        and params.strength > 0
        and np.isfinite(params.relaxation)
        and params.relaxation > 0
    )


def _direct_fit(
    tracks: pd.DataFrame,
    base: SocialForce,
    ranges: np.ndarray,
    min_speed: float,
    groups: Mapping[Hashable, Hashable] | None,
    sd: float,
    step: float,
    simex: bool,
    smooth: bool,
) -> tuple[SocialForce, dict[str, float]]:
    """:func:`fit_social_force` before its correction by simulation: the least squares (and
    SIMEX, on the finite differences' design), as the simulation step's parameters."""
    theta, info = _least_squares_fit(tracks, base, ranges, min_speed, groups, sd, sd, smooth)
    if sd > 0 and simex and not smooth:
        # SIMEX (Cook and Stefanski 1994): the estimates with the noise's variance raised
        # by lambda s^2 (the tracks plus more noise of known sd), extrapolated back to no
        # noise at lambda = -1 by a quadratic in lambda; deterministic (seeded)
        rng = np.random.default_rng(0)
        lams, thetas = [0.0], [theta]
        tab = tracks.reset_index(drop=True)
        for lam in SIMEX_LAMBDAS:
            reps = []
            for _ in range(SIMEX_REPLICATES):
                more = rng.normal(0.0, sd * np.sqrt(lam), (len(tab), 2))
                noisier = tab.assign(x=tab["x"] + more[:, 0], y=tab["y"] + more[:, 1])
                fixed = theta[2:]  # at the range chosen from the tracks as they are
                # the same estimator (same spans), its velocities corrected as at lambda = 0
                sd_lam = sd * np.sqrt(1.0 + lam)
                fit = _least_squares_fit(noisier, base, fixed, min_speed, groups, sd_lam, sd)
                reps.append(fit[0])
            lams.append(lam)
            thetas.append(np.mean(reps, axis=0))
        coef = np.polyfit(np.asarray(lams), np.asarray(thetas), 2)
        theta = coef.T @ np.array([1.0, -1.0, 1.0])
    inv_tau, strength, b_best = (float(v) for v in theta)
    # the continuous model's tau_c and A_c as the parameters of the simulation's step
    tau_c = 1.0 / inv_tau if inv_tau > 0 else float("inf")
    tau = tau_c + 0.5 * step
    params = base._replace(
        strength=strength * (tau_c / tau if np.isfinite(tau) else 1.0),
        range=b_best,
        relaxation=tau,
    )
    return params, info


def _walk_plans(
    tracks: pd.DataFrame, sd: float, min_speed: float
) -> tuple[pd.DataFrame, np.ndarray]:
    """Plans that walk the people of ``tracks`` again (:func:`social_force_tracks`'s
    ``tracks``): each track's rows (same ``id`` and ``t``) on the straight line from its
    first smoothed position to its last one, at its median smoothed walking speed (samples
    at ``min_speed`` or more), standing at the end; ``vx, vy`` its smoothed velocity at the
    first row. And (n,) the rows' ids."""
    ids, t, raw, who, at, start, stop, dt = _smoothing_rows(tracks)
    pos, vel, _ = smooth_samples(raw, who, at, dt, sd, JERK_DENSITY)
    speed = np.hypot(*vel.T)
    moving = speed >= min_speed
    v0 = pd.Series(np.where(moving, speed, np.nan)).groupby(who).median().to_numpy()
    a, b = pos[start], pos[stop]
    dur = np.hypot(*(b - a).T) / np.where(np.isfinite(v0) & (v0 > 0), v0, np.inf)
    frac = np.clip((t - t[start][who]) / np.maximum(dur[who], 1e-9), 0.0, 1.0)
    frac = np.where(np.isfinite(dur[who]) & (dur[who] > 0), frac, 0.0)
    xy = a[who] + (b - a)[who] * frac[:, None]
    plan = pd.DataFrame(
        {
            "id": ids,
            "t": t,
            "x": xy[:, 0],
            "y": xy[:, 1],
            "yaw": 0.0,
            "vx": vel[start][who][:, 0],
            "vy": vel[start][who][:, 1],
        }
    )
    return plan, ids


def _simulation_correction(
    tracks: pd.DataFrame,
    params: SocialForce,
    fit_args: tuple,
    corrections: int,
) -> tuple[SocialForce, int]:
    """Indirect inference (Gourieroux, Monfort and Renault 1993) of the strength and the
    relaxation time: the people of ``tracks`` walked again by the model at the current
    parameters (:func:`_walk_plans`, :func:`social_force_tracks`, the simulation's own
    step), seen with the tracker's noise (:data:`SIMULATION_NOISE_DRAWS` seeded draws),
    fitted as the tracks were (:func:`_direct_fit`, ``fit_args``) at the tracks' range
    ``B``; the strength and the relaxation time are then scaled by the ratio of the
    tracks' estimate to the simulated tracks' mean estimate, ``corrections`` times (a
    fixed point of the estimator's binding function, exact in one step where it is
    proportional), and the iterates after the first averaged (geometrically: the
    simulations' own noise). Returns the parameters and the corrections made.

    Raises
    ------
    ValueError
        When a correction would scale a parameter by :data:`MAX_CORRECTION` or more: no
        parameters of the model reproduce the tracks' estimates (too few people near
        each other, or no repulsion in them)."""
    _, min_speed, groups, sd, step, simex, smooth = fit_args
    plan, ids = _walk_plans(tracks, sd, min_speed)
    labels = None
    if groups is not None:
        labels = np.array([groups.get(i) for i in ids], dtype=object)
    target = np.array([params.strength, params.relaxation])
    # B at the tracks' estimate (the smoothed state's is nearly unbiased), A and tau
    # corrected at it: A and B trade off along a ridge (A exp(-d / B) at the distances
    # seen), which correcting both at once walks along
    fixed = np.array([params.range])
    current = params
    rng = np.random.default_rng(0)
    iterates = []
    for _ in range(corrections):
        walked = social_force_tracks(plan, current, dt=step, groups=labels)
        walked = walked[["id", "t", "x", "y"]]
        got = []
        for _ in range(SIMULATION_NOISE_DRAWS):
            more = rng.normal(0.0, sd, (len(walked), 2))
            seen = walked.assign(x=walked["x"] + more[:, 0], y=walked["y"] + more[:, 1])
            fit, _ = _direct_fit(seen, current, fixed, min_speed, groups, sd, step, simex, smooth)
            got.append((fit.strength, fit.relaxation))
        mean = np.mean(got, axis=0)
        ratio = target / mean
        if not (
            np.all(np.isfinite(ratio))
            and np.all((ratio > 1.0 / MAX_CORRECTION) & (ratio < MAX_CORRECTION))
        ):
            raise ValueError(
                f"tracks: the social force walked at strength {current.strength:.3g} m/s^2, "
                f"range {current.range:.3g} m, relaxation {current.relaxation:.3g} s does not "
                f"reproduce their estimates (strength {target[0]:.3g}, relaxation "
                f"{target[1]:.3g} against {mean[0]:.3g}, {mean[1]:.3g}): no repulsion in "
                f"them, or too little walking near each other to correct the fit"
            )
        current = current._replace(
            strength=float(current.strength * ratio[0]),
            relaxation=float(current.relaxation * ratio[1]),
        )
        iterates.append((current.strength, current.relaxation))
    if len(iterates) > 1:  # the iterates past the first, averaged (simulation noise)
        mean = np.exp(np.mean(np.log(iterates[1:]), axis=0))
        current = current._replace(strength=float(mean[0]), relaxation=float(mean[1]))
    done = len(iterates)
    return current, done


def _least_squares_fit(
    tracks: pd.DataFrame,
    base: SocialForce,
    ranges: np.ndarray,
    min_speed: float,
    groups: Mapping[Hashable, Hashable] | None,
    sd: float,
    design_sd: float,
    smooth: bool = False,
) -> tuple[np.ndarray, dict[str, float]]:
    """:func:`fit_social_force`'s least squares of the continuous model (position noise of
    sd ``sd``; the second differences' span chosen for ``design_sd``): ``(1/tau_c, A_c,
    B)`` and ``rss``, ``n``, ``r2``, ``dt``."""
    design = _smoothed_design if smooth else _acceleration_design
    d = design(tracks, base, min_speed, groups, design_sd)
    y, person, e_col, minus_v = d["y"], d["person"], d["e_col"], d["minus_v"]
    n_people, m, dt = d["n_people"], d["m"], d["dt"]
    g_of = {float(b): _repulsion_column(d, base.radius, float(b)) for b in ranges}
    v_var = sd**2 * d["v_var"]

    def solve(w: np.ndarray) -> tuple:
        """Weighted least squares (weights ``w`` (2m,)) for every ``B``; the best."""
        best = None
        for b_range, g in g_of.items():
            cols = (minus_v, g)
            beta, _, res, n_per = _profiled_least_squares(
                w, person, n_people, e_col, y, cols, noise_var=v_var
            )
            rss = float(np.sum(w * res**2))
            # the objective the noise-corrected coefficients minimise: the residuals' square
            # sum less what the velocities' noise adds to it
            objective = rss - v_var * (float(np.sum(w)) - n_per) * beta[0] ** 2
            if best is None or objective < best[5]:
                best = (rss, b_range, beta[0], beta[1], res, objective)
        return best

    # a second pass without the 2% worst-fitted samples: a few accelerations dominated by
    # what the model leaves out (a speed at its cap, a track cut off) must not steer it
    rss, b_best, inv_tau, strength, res, _ = solve(np.ones(2 * m))
    norm = np.hypot(res[0::2], res[1::2])
    keep = np.repeat(norm <= np.quantile(norm, 1.0 - FIT_TRIM), 2)
    rss, b_best, inv_tau, strength, _, _ = solve(keep.astype(float))
    y = y[keep]
    r2 = 1.0 - rss / max(float(np.sum((y - y.mean()) ** 2)), 1e-300)
    info = {"rss": rss, "n": float(keep.sum() // 2), "r2": float(r2), "dt": dt}
    return np.array([inv_tau, strength, b_best]), info


def _close_passes(
    tracks: pd.DataFrame,
    sd: float,
    groups: Mapping[Hashable, Hashable] | None,
    radius: float,
) -> tuple[float, int]:
    """How close the people of ``tracks`` come to each other: over the pairs ever within
    :data:`PASS_REACH` of each other at one sample (pairs of one group left out), the mean
    of ``exp(-(d - 2 radius) / PASS_SCALE)``, ``d`` (m) the pair's closest distance between
    the smoothed positions (:data:`STATE_JERK`, tracker noise ``sd``) at their common
    samples (NaN without such pairs); and the number of pairs.

    The repulsion's effect on positions, not on accelerations: 5 cm of noise is small
    against distances of 0.5-2 m, where the accelerations over a 0.4 s step drown in it.
    The coarser the sampling, the longer the closest distance seen, alike on tracks
    re-walked and sampled as the tracks are."""
    ids, t, raw, who, at, start, stop, dt = _smoothing_rows(tracks)
    pos = smooth_samples(raw, who, at, dt, sd, STATE_JERK)[0]
    label = None if groups is None else _group_codes(ids, groups)
    pi, pj = _neighbour_pairs(t, pos, dt, PASS_REACH, label)
    one = who[pi] < who[pj]  # each unordered pair once per sample
    pi, pj = pi[one], pj[one]
    if pi.size == 0:
        return float("nan"), 0
    dist = np.hypot(*(pos[pi] - pos[pj]).T)
    pair = who[pi].astype(np.int64) * start.size + who[pj]
    closest = pd.Series(dist).groupby(pair).min().to_numpy()
    return float(np.mean(np.exp((2.0 * radius - closest) / PASS_SCALE))), int(closest.size)


def repulsion_evidence(
    tracks: pd.DataFrame,
    *,
    base: SocialForce | None = None,
    min_speed: float = 0.2,
    groups: Mapping[Hashable, Hashable] | None = None,
    level: float = 0.01,
    min_close: int = 50,
    trim: float = 0.02,
    smooth: bool | None = None,
    calibrate: bool | None = None,
) -> dict[str, float | str]:
    """Whether observed accelerations show ``base``'s repulsion or none at all.

    On the samples :func:`fit_social_force` uses where another person is within ``reach``
    (elsewhere both models predict the same), the accelerations are fitted by least
    squares with the repulsion's range fixed at ``base.range`` and ``1/tau``, the
    ``v0_i / tau`` and the strength ``A`` free (the ``trim`` share of worst-fitted samples
    left out, 2% as in the fit). The residual sums of squares with ``A`` held at ``base.strength``
    (``rss_published``) and at 0 (``rss_none``), the others refitted, follow from it:
    ``RSS(A) = RSS(A_hat) + (A - A_hat)^2 / k`` with ``k`` the ``A, A`` entry of the
    inverse normal matrix. Their difference is linear in ``A_hat``, so with Gaussian
    residuals of variance ``s^2`` it is tested exactly:
    ``z = (A_pub / 2 - A_hat) / (s sqrt(k))``; the published repulsion fits worse than
    none at ``level`` when ``z`` exceeds the normal's upper ``level`` quantile, and none
    fits worse than it when ``-z`` does. (The residuals of one track are correlated,
    second differences over overlapping samples, so the level is nominal.)

    The accelerations and the state are :func:`fit_social_force`'s: from differences
    below :data:`SMOOTH_NOISE` of tracker noise, from the smoothed tracks from it on. The
    noise left in the regressors shrinks ``A_hat`` towards 0 (with 5 cm of noise at 10 Hz
    the published 2.1 reads as about 0.9, at 2.5 Hz as 0.4), and would read the published
    force as none. So, with ``calibrate``, ``A_pub`` is the published force as this least
    squares sees it (``strength_seen``): the tracks' people walked again under it
    (:func:`_walk_plans`, :func:`social_force_tracks`), with the tracker's noise (seeded),
    fitted the same way. Under no repulsion ``A_hat`` is near 0 either way (the noise
    shrinks it towards 0, not away), so the test's level against "published" holds.

    Where that test cannot tell (neither is rejected) and the published force was walked
    again (``calibrate``), how close people come decides: at 2.5 Hz with 5 cm the
    published force reads as 0.25-0.52 and one crowd of six walked by it reads "too
    little" (z -1.4), where its positions still show it (5 cm against distances of
    0.5-2 m).
    The tracks' :func:`_close_passes` (from :data:`PASS_MIN_PAIRS` pairs within
    :data:`PASS_REACH` on) are placed on the way, in logs, from those of the crowd walked
    again under the published force to those of the same crowd walked under none (one
    more simulation, the same noise): within its first :data:`PASS_BAND` the verdict is
    "published", within its last "none". Six crowds of 60 walked by the published force
    and twelve walked straight through each other, at 2.5 Hz with 5 cm, lay 0.01-0.12
    and 0.90-1.09 of the way. This verdict has no level of its own (``z`` and ``p`` stay
    the least squares').

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene, equally spaced times.
    base : SocialForce, optional
        The published force tested (default :class:`SocialForce`'s).
    min_speed, groups
        As in :func:`fit_social_force`.
    level : float
        Significance level of the one-sided test.
    min_close : int
        Fewest close samples (accelerations with a neighbour within reach) to decide.
    trim : float
        Share of the close samples left out as worst fitted (by the free fit's residual).
    smooth : bool, optional
        Accelerations and state from the smoothed tracks (default: from
        :data:`SMOOTH_NOISE` of noise on).
    calibrate : bool, optional
        Test against the published force as seen through the noise (default: with
        ``smooth``); else against ``base.strength``.

    Returns
    -------
    dict
        ``verdict``: ``"none"`` (the published repulsion fits significantly worse than
        none), ``"published"`` (none fits significantly worse than it) or ``"too little"``
        (neither is rejected, or fewer than ``min_close`` close samples); ``close`` (close
        samples used), ``strength_hat`` and its standard error ``se``, ``rss_published``,
        ``rss_none``, ``z`` and ``p`` (one-sided, for "published fits worse than none"),
        ``strength_seen`` (the ``A_pub`` tested against, where a decision was made);
        ``passes``, ``passes_published`` and ``passes_none`` (the close passes of the
        tracks and of the two re-walked crowds, where they decided; else NaN).

    Raises
    ------
    ValueError
        As :func:`fit_social_force`.
    """
    from scipy.stats import norm  # lazy: +1.0 s CPU on `import are_stats.behaviour`

    base = SocialForce() if base is None else base
    sd = tracker_noise(tracks)
    smooth = sd >= SMOOTH_NOISE if smooth is None else bool(smooth)
    calibrate = smooth if calibrate is None else bool(calibrate)
    out: dict[str, float | str] = {"verdict": "too little"}
    for k in (
        "close",
        "strength_hat",
        "se",
        "rss_published",
        "rss_none",
        "z",
        "p",
        "passes",
        "passes_published",
        "passes_none",
    ):
        out[k] = float("nan")
    args = (base, min_speed, groups, sd, smooth, trim, min_close)
    got = _evidence_fit(tracks, *args)
    out["close"] = got[0]
    if got[1] is None:
        return out
    close, a_hat, se, rss, k = got
    a_seen = float(base.strength)
    rewalk = None
    if calibrate and a_seen > 0:
        # the published force as this least squares sees it: the tracks' people walked
        # again under it, with the tracker's noise (seeded), fitted the same way
        plan, ids = _walk_plans(tracks, sd, min_speed)
        labels = None if groups is None else np.array([groups.get(i) for i in ids], object)
        more = None

        def rewalk(force: SocialForce) -> pd.DataFrame:
            """The tracks' people walked again under ``force``, seen with the noise."""
            nonlocal more
            walked = social_force_tracks(plan, force, dt=SIMULATION_STEP, groups=labels)
            walked = walked[["id", "t", "x", "y"]]
            if more is None:
                more = np.random.default_rng(0).normal(0.0, sd, (len(walked), 2))
            return walked.assign(x=walked["x"] + more[:, 0], y=walked["y"] + more[:, 1])

        seen = rewalk(base)
        sim = _evidence_fit(seen, *args)
        if sim[1] is not None and sim[1] > 0:
            a_seen = float(sim[1])
    z = (a_seen / 2 - a_hat) / se
    p = float(norm.sf(z))
    if p < level:  # the published repulsion fits worse than none
        verdict = "none"
    elif 1.0 - p < level:  # none fits worse than the published repulsion
        verdict = "published"
    else:  # neither is rejected: too few close samples (or too noisy) to tell
        verdict = "too little"
    if verdict == "too little" and rewalk is not None:
        # the accelerations cannot tell (at 2.5 Hz with 5 cm the published force reads
        # as 0.2-0.5): how close the people come, against the same people re-walked
        # under the published force and under none
        passes, pairs = _close_passes(tracks, sd, groups, base.radius)
        if pairs >= PASS_MIN_PAIRS:
            published = _close_passes(seen, sd, groups, base.radius)[0]
            none = _close_passes(rewalk(base._replace(strength=0.0)), sd, groups, base.radius)[0]
            out.update(passes=passes, passes_published=published, passes_none=none)
            span = np.log(none) - np.log(published)
            way = (np.log(passes) - np.log(published)) / span if span > 0 else np.nan
            if way <= PASS_BAND:
                verdict = "published"
            elif way >= 1.0 - PASS_BAND:
                verdict = "none"
    out.update(
        verdict=verdict,
        close=close,
        strength_hat=a_hat,
        se=se,
        rss_published=rss + (a_seen - a_hat) ** 2 / k,
        rss_none=rss + a_hat**2 / k,
        z=float(z),
        p=p,
        strength_seen=a_seen,
    )
    return out


def _evidence_fit(
    tracks: pd.DataFrame,
    base: SocialForce,
    min_speed: float,
    groups: Mapping[Hashable, Hashable] | None,
    sd: float,
    smooth: bool,
    trim: float,
    min_close: int,
) -> tuple[float, float | None, float, float, float]:
    """:func:`repulsion_evidence`'s least squares on the close samples: their number and,
    with at least ``min_close`` of them (else None and NaNs), the strength ``A_hat``, its
    standard error, the residual sum of squares and ``k`` (the ``A, A`` entry of the
    inverse normal matrix)."""
    design = _smoothed_design if smooth else _acceleration_design
    d = design(tracks, base, min_speed, groups, sd)
    y, person, e_col, minus_v = d["y"], d["person"], d["e_col"], d["minus_v"]
    near = np.zeros(d["n"], bool)
    near[d["pi"]] = True
    close = near[d["inner"]]
    nan = float("nan")
    if close.sum() < min_close:
        return float(close.sum()), None, nan, nan, nan
    cols = (minus_v, _repulsion_column(d, base.radius, base.range))
    n_people = d["n_people"]

    def fit(w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Coefficients ``(1/tau, A)``, the inverse 2 x 2 normal matrix, the residuals and
        the number of per-person coefficients fitted (weights ``w`` (2m,))."""
        return _profiled_least_squares(w, person, n_people, e_col, y, cols, inverse=True)

    _, _, res, _ = fit(np.repeat(close, 2).astype(float))
    norm_res = np.hypot(res[0::2], res[1::2])
    kept = close & (norm_res <= np.quantile(norm_res[close], 1.0 - trim))
    w = np.repeat(kept, 2).astype(float)
    beta, inv, res, n_per = fit(w)
    rss = float(np.sum(w * res**2))
    k = float(inv[1, 1])
    dof = float(w.sum()) - n_per - 2
    if not (k > 0 and dof > 0):
        return float(close.sum()), None, nan, nan, nan
    se = float(np.sqrt(rss / dof * k))
    return float(kept.sum()), float(beta[1]), se, rss, k
