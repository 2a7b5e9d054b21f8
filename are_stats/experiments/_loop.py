"""The navigation experiment loop (paper Sect. 4): a robot drives to a sequence of goals on
the augmented map of one scenario, replanning at every scene update.

The loop is event-driven on simulated time, an explicit state machine: ``_init`` builds the
state at t = 0 and ``_step`` makes one transition (plan if needed, drive to the next event,
apply it), both functions of the mission's fixed settings (``_Mission``) and the state
(``_State``, a NamedTuple), as the EM code does with ``em_init`` / ``em_step``; everything
that changes is in the state, the AR-builder that gives n_A and the batch of camera percepts
ahead included (``_Mission`` is frozen and holds no cache, and no step changes a state, or
an object it holds, in place):

* the artefacts are an :class:`~are_stats.Scene` (the one place where an artefact becomes a
  box); **scene updates** are its events: arrivals, leaves and, with behaviour tracks,
  **moves** at the artefacts' epochs (timeline ``kind == "move"``); with
  ``perception="camera"``, changes of the perceived set A_f checked every
  ``perception_period`` seconds on the boxes at their current pose;
* at an arrival or leave (and when a new goal becomes current) the planner replans from the
  robot's position to the current goal on the augmented grid that holds **only the
  perceived artefacts**, inflated by the robot radius plus half a cell diagonal (cells
  around the robot's own position that are inflated but not occupied are released, so a
  robot brushing an obstacle can still leave); a moving perceived artefact is on that grid
  at its pose now and at the next event's, and a move replans when it blocks the rest of
  the path (or the robot is waiting);
* between updates the robot moves along its path at its speed; its footprint is tested
  against every live artefact (perceived or not) at its pose at that instant and each new
  contact the robot drives into counts as a collision (an artefact that *arrives* on the
  robot's footprint is counted apart, as an arrival contact, and one that walks into the
  robot, closing the gap faster than the robot did, as an artefact contact); when the plan
  fails the robot waits for the next update;
* with ``avoid_robot`` (the default) the robot's footprint is an obstacle to the moving
  artefacts: at a move, an artefact whose motion to its next epoch would enter it (where
  the robot is then, along its current plan) detours or waits
  (:mod:`are_stats.experiments._avoid`, timeline ``"move+detour"`` / ``"move+yield"``);
  its new track goes into the state's scene (``_State.scene``, built by
  :meth:`~are_stats.Scene.with_track`) and the coming events are rebuilt from it. The robot
  replans after some of those decisions: after every plan (or failed plan: it then
  stands) every live moving artefact whose motion until its next check meets the new one
  decides again from where it is (timeline ``"replan+detour"`` / ``"replan+yield"``, a
  scene update of its own at the replan's time).

The replanning time ``rho_t`` is measured on the wall clock (DECISIONS 10) and recorded, but
it does not advance simulated time, so everything except ``rho_t`` and ``rho`` is
deterministic given the seed (for OMPL planners: given the seed and an iteration budget).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_finite, check_in, check_nonnegative, check_positive
from are_stats.builder import (
    ARBuilder,
    box_centres,
    box_corners,
    point_box_distance,
    rasterise_convex,
)
from are_stats.environment import OccupancyGrid
from are_stats.experiments._avoid import plan_avoidance
from are_stats.experiments._metrics import replanning_ratio, time_average
from are_stats.experiments._planners import Planner, make_planner, timed_plan
from are_stats.experiments._robot import Robot
from are_stats.inputs import check_memory, check_work
from are_stats.scenarios import Boxes, Scene

if TYPE_CHECKING:
    import trimesh

__all__ = ["MissionResult", "MissionTrace", "random_goals", "run_mission"]


class MissionTrace(NamedTuple):
    """What happened, for replay and export (see :func:`are_stats.export.export_mcap`).

    Attributes
    ----------
    poses : (m, 4) float
        ``t, x, y, yaw`` of the robot base, sampled along the motion.
    plans : list of (float, (k, 2) float)
        Time and world path of every successful plan.
    scenes : list of dict
        One per scene update: ``t``, ``ids`` (n,), ``centres`` (n, 3), ``half`` (n, 3),
        ``yaws`` (n,), ``labels`` (list), ``perceived`` (n,) bool and ``grid`` (the planner's
        augmented :class:`~are_stats.environment.OccupancyGrid`).
    goals : (g, 2) float
    scene : Scene or None
        The mission's artefacts over the whole mission: the scene it ran on with every
        avoidance's track in it (:meth:`~are_stats.Scene.with_track` keeps the epochs
        before the decision, so ``scene.at(t)`` is where the artefacts were at every ``t``
        of the mission); the MCAP export samples the artefacts' poses from it between
        scene updates. None in a trace built without it.
    """

    poses: np.ndarray
    plans: list
    scenes: list
    goals: np.ndarray
    scene: Scene | None = None


class MissionResult(NamedTuple):
    """Outcome of :func:`run_mission`.

    Attributes
    ----------
    summary : dict
        ``goals_total``, ``goals_reached``, ``mission_time`` (s: when the last goal was
        reached, else the time limit), ``time_per_goal`` (s, mean over reached goals),
        ``collisions`` (contacts the robot drove into), ``arrival_contacts`` (artefacts
        that appeared on the robot's footprint), ``artefact_contacts`` (moving artefacts
        that walked into the robot: they closed the gap faster than the robot),
        ``n_detours``, ``n_yields`` (artefacts that detoured around the robot or waited for
        it, ``avoid_robot``), ``avoid_delay`` (s, the delays those added to their tracks),
        ``n_give_ways`` (artefacts that stepped back from a robot standing too long,
        ``avoid_patience``), ``n_replans``, ``n_failed_plans``, ``n_updates``,
        ``n_move_updates`` (updates with moves),
        ``update_rate`` (scene updates per s), ``rho_mean``, ``rho_t_mean``, ``nu_mean``
        (time average), ``nu_max``, ``distance`` (m driven).
    replans : pandas.DataFrame
        One row per plan: ``t, goal, reason, rho_t, g_t, rho, success, path_length,
        n_live, n_perceived, n_A, nu``.
    goals : pandas.DataFrame
        One row per goal: ``goal, x, y, t_reached`` (NaN if not reached).
    timeline : pandas.DataFrame
        One row per scene update: ``t, kind, n_live, n_perceived, n_A, nu``.
    trace : MissionTrace or None
        With ``record=True``.
    """

    summary: dict
    replans: pd.DataFrame
    goals: pd.DataFrame
    timeline: pd.DataFrame
    trace: MissionTrace | None


def random_goals(
    grid: OccupancyGrid, n: int, radius: float, seed: int, min_separation: float = 2.0
):
    """``(n, 2)`` goal positions drawn uniformly over the free cells of ``grid`` inflated by
    ``radius``, each at least ``min_separation`` metres from the previous goal (cell centres).
    """
    # lazy: SciPy's ndimage adds 0.15 s CPU to `import are_stats.experiments`
    from scipy import ndimage

    n = int(n)
    if n < 1:
        raise ValueError(f"n: expected an integer >= 1, got {n!r}")
    ok = grid.free & ~grid.inflate(float(radius))
    lab, _ = ndimage.label(ok)
    if not ok.any():
        raise ValueError(f"grid: no free cell is farther than {radius} m from obstacles")
    # stay in the largest connected free region so every goal is reachable in the base map
    big = np.bincount(lab.ravel())[1:].argmax() + 1
    cells = np.flatnonzero(lab.ravel() == big)
    rng = np.random.default_rng(seed)
    out: list[np.ndarray] = []
    tries = 0
    while len(out) < n:
        c = int(rng.choice(cells))
        xy = grid.cell_to_world(np.array(divmod(c, grid.width), float))
        tries += 1
        if out and np.linalg.norm(xy - out[-1]) < min_separation and tries < 1000:
            continue
        out.append(xy)
    return np.array(out)


def _arc(path: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]


def _point_at(path: np.ndarray, cum: np.ndarray, s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(m, 2)`` and headings ``(m,)`` at arc lengths ``s``."""
    s = np.clip(np.atleast_1d(np.asarray(s, float)), 0.0, cum[-1])
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2)
    seg = path[k + 1] - path[k]
    ln = np.maximum(cum[k + 1] - cum[k], 1e-12)
    f = ((s - cum[k]) / ln)[:, None]
    return path[k] + f * seg, np.arctan2(seg[:, 1], seg[:, 0])


# ---- the mission as a state machine ---------------------------------------------------------


@dataclass(frozen=True)
class _Mission:
    """What does not change during a mission (the step functions' first argument).

    ``events`` are the scene's events in ``(0, T)`` (:class:`_Events`).
    """

    grid: OccupancyGrid
    scene: Scene
    robot: Robot
    plan_fn: Planner
    goals: np.ndarray  # (g, 2)
    T: float
    perception: str
    env_mesh: trimesh.Trimesh | None
    period: float
    d_max: float
    tau: float
    memory: bool
    seed: int
    record: bool
    step: float  # footprint test spacing along the path (m)
    n_free: int
    events: _Events  # the events of the scene as given (the state holds the coming ones)
    avoid: bool  # artefacts avoid the robot's footprint
    clearance: float  # robot radius + avoidance margin (m)
    patience: float  # s an artefact waits for a standing robot before it gives way
    move_period: float | None
    wall_distance: np.ndarray | None  # grid.distance_to_occupied() when avoid
    art_radius: np.ndarray  # (N,) box reach from an artefact's pose (m)
    art_speed: np.ndarray  # (N,) fastest speed along its track (avoidances only slow it)
    # the map's own non-free cells (H, W), unknown included as the planner treats them, the
    # cells farther than the clearance (robot radius + half a cell diagonal) from them, and
    # the cell offsets (k, 2) within the clearance (their Euclidean distance transform
    # distance); the planner adds the artefacts' cells (_free_cells)
    static_occ: np.ndarray
    static_clear: np.ndarray
    clear_offsets: np.ndarray


class _State(NamedTuple):
    """The mission between two steps: the robot, its plan, what it perceives, the counters.

    Arrays over artefacts are (N,) in the scene's order.
    """

    t: float
    pose: np.ndarray  # (3,) x, y, yaw
    goal: int  # index of the current goal
    reached: np.ndarray  # (g,) time each goal was reached, NaN if not (yet)
    path: np.ndarray | None  # (k, 2) current plan, None while waiting
    cum: np.ndarray  # (k,) arc length along the plan
    s_along: float  # arc length driven on the plan
    need_plan: bool
    reason: str
    live: np.ndarray  # (N,) bool
    seen: np.ndarray  # (N,) bool, on the planner's map
    in_contact: np.ndarray  # (N,) bool
    n_A: int  # artefact cells of the augmented map
    event: int  # index of the next event time in events.t
    next_percept: float
    n_replans: int
    n_updates: int
    n_moves: int
    collisions: int
    arrival_contacts: int
    artefact_contacts: int
    distance: float
    scene: Scene  # the artefacts, with the tracks changed by their avoidances of the robot
    events: _Events  # the scene's coming events
    n_detours: int
    n_yields: int
    avoid_delay: float  # s, summed over the avoidances
    n_give_ways: int
    # the patience rule of _avoid: (N,) since when each artefact has been waiting for the
    # robot (NaN: it is not), since when the robot has stood with its plans failing (NaN:
    # it has a plan), and (N,) the standing spell (its start) in which each artefact last
    # gave way (NaN: never): once a spell
    waiting: np.ndarray
    standing: float
    gave_way: np.ndarray
    # (t, n): the robot planned again n times at time t because the artefacts' answers
    # to its plan blocked it (_check_after_avoidance)
    replans_at: tuple
    # the AR-builder (M_2D augmented with the live boxes) holding the scene at builder_at =
    # (scene, t); never changed in place: _register puts a new one in the state at each
    # update (it gives n_A) and _planning_grid one at the plan's time (the planner's map
    # is its grid), with ARBuilder.with_scene
    builder: ARBuilder
    builder_at: tuple  # (scene, t) the builder holds
    # the last planner's map and free cells (_planning_grid) and what they were made of:
    # (scene, t, events, event, seen, pose, augmented grid, free (H, W) bool), both
    # read-only; the same instant asks for them again (a move's check of the plan, then
    # its replan; an avoidance's check, then its replan)
    planning_at: tuple
    # A_f of the camera ticks ahead, predicted along the current plan and perceived in one
    # batch: {tick time: (robot pose (3,), perceived (N,), scene)}, replaced (never
    # changed) by each batch. An entry is used only when the robot is where it was
    # predicted to be at that tick, in the same scene.
    percepts: Mapping[float, tuple]
    # (scene, live (N,), t): no footprint test in that scene with those live artefacts
    # finds a contact up to t (_contacts); () when unknown
    contact_clear: tuple


class _Info(NamedTuple):
    """What one step reports (rows of the result tables and trace entries)."""

    replan: dict | None = None
    update: dict | None = None
    poses: list | None = None
    plan: tuple | None = None
    scene: dict | None = None


def _boxes(scene: Scene, t: float) -> tuple[np.ndarray, Boxes]:
    """Indices (n,) of the live artefacts and their boxes at ``t``."""
    return np.flatnonzero(scene.alive(t)), scene.at(t)


def _footprints(scene: Scene, t: float, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (k, 2) and headings (k,) of artefacts ``idx`` at ``t``, alive or not (the
    robot's footprint tests run up to an event time, where some of them leave)."""
    pose = scene.poses(t, idx)
    return box_centres(pose, scene.offsets[idx])[:, :2], pose[:, 2]


def _register(s: _State) -> _State:
    """Register the scene's live boxes at ``s.t`` on the state's AR-builder (M_2D); n_A."""
    builder = s.builder.with_scene(s.scene, s.t)
    return s._replace(builder=builder, n_A=builder.n_artefact_cells, builder_at=(s.scene, s.t))


def _perceive(m: _Mission, s: _State, idx: np.ndarray, tick: bool = False) -> _State:
    """The state with ``seen``, the artefacts on the planner's map after a perception at
    ``s.pose``; ``idx`` (n,) the live artefacts at ``s.t`` (``tick``: at a camera tick,
    which perceives the ticks ahead in the same batch and keeps them in ``percepts``)."""
    now = np.zeros(s.live.size, bool)
    if m.perception == "all":
        now[idx] = True
    elif idx.size:
        now, s = _camera_percept(m, s, tick)
    return s._replace(seen=(now | (s.seen & s.live)) if m.memory else now)


#: Camera ticks perceived together in one batch (the robot's poses at them predicted along
#: its plan): one Warp launch sequence instead of one per 0.1 s tick.
_PERCEPT_BATCH = 32


def _camera_percept(m: _Mission, s: _State, tick: bool) -> tuple[np.ndarray, _State]:
    """(N,) bool: the artefacts in A_f at ``s.t`` seen from ``s.pose`` (no memory), and the
    state with the batch's ``percepts``.

    The same A_f as perceiving ``s.scene.at(s.t)`` on its own (:func:`perceive_scene`'s
    frames are independent): the ticks ahead are perceived in the same batch, at the poses
    the robot will have if it keeps driving its plan (or keeps waiting), and reused when
    it is there (to 1e-9 m and rad) and the scene is the same one (an artefact avoiding
    the robot makes a new scene), up to the next scene event; a replan, a goal or a wait
    that changes the robot's motion makes the prediction miss and the tick is perceived
    anew.
    """
    # lazy: perception (Warp) adds 0.75 s CPU to `import are_stats.experiments`
    from are_stats.perception import perceive_scene

    hit = s.percepts.get(s.t)
    # (np.allclose(hit[0], s.pose, rtol=0, atol=1e-9) for finite poses, without its cost)
    if hit is not None and hit[2] is s.scene and float(np.abs(hit[0] - s.pose).max()) <= 1e-9:
        return hit[1].copy(), s
    times, t = [s.t], s.t
    if tick and not s.need_plan:  # (an arrival, a leave or a replan changes the motion)
        # up to the next scene event: most events change the scene (an avoidance) or the
        # plan, and the ticks past them are perceived in vain (in the courtyard missions,
        # 60% of the frames of batches that ran to _PERCEPT_BATCH ticks)
        t_event = s.events.t[s.event] if s.event < s.events.t.size else m.T
        while len(times) < _PERCEPT_BATCH:
            t = t + m.period  # as _step accumulates next_percept
            if t >= min(m.T, t_event):
                break
            times.append(t)
    tt = np.asarray(times)
    poses = np.repeat(s.pose[None, :], tt.size, axis=0)
    if s.path is not None and not s.need_plan and tt.size > 1:
        along = s.s_along + (tt - s.t) * m.robot.speed
        ahead = along <= s.cum[-1]  # past the goal the robot replans: no prediction
        tt, along = tt[ahead], along[ahead]
        pts, hd = _point_at(s.path, s.cum, along)
        poses = np.column_stack([pts, hd])
        poses[0] = s.pose
    _, seen = perceive_scene(
        s.scene,
        tt,
        m.robot.camera_poses(poses),
        m.env_mesh,
        m.robot.camera(s.pose),
        m.d_max,
        m.tau,
    )
    batch = {float(t): (p, row, s.scene) for t, p, row in zip(tt, poses, seen, strict=True)}
    return seen[0], s._replace(percepts=MappingProxyType(batch))


def _planning_grid(
    m: _Mission, s: _State, idx: np.ndarray
) -> tuple[_State, OccupancyGrid, np.ndarray]:
    """The planner's map and the robot's free cells on it, and the state with the builder
    at ``s.t``; ``idx`` (n,) the live artefacts at ``s.t``.

    The map is the AR-builder's augmented grid with the perceived artefacts
    (:meth:`ARBuilder.augmented_grid` with ``perceived``): the boxes rasterised at the
    update are reused when the plan follows it; a plan at a later time (a camera tick
    between events, tracks having moved the boxes) brings the builder to ``s.t`` first. A
    moving perceived artefact also covers its footprint at the next event, or at the
    mission's time limit after the last one (the AR-builder knows where its artefacts go
    next).
    """
    c = s.planning_at
    if (
        c
        and c[0] is s.scene
        and c[1] == s.t
        and c[2] is s.events
        and c[3] == s.event
        and np.array_equal(c[4], s.seen)
        and np.array_equal(c[5], s.pose)
        and s.builder_at[0] is s.scene
        and s.builder_at[1] == s.t
    ):
        return s, c[6], c[7]
    at_scene, at_t = s.builder_at
    if at_scene is not s.scene or at_t != s.t:
        s = s._replace(builder=s.builder.with_scene(s.scene, s.t), builder_at=(s.scene, s.t))
    on = s.seen[idx]
    aug = s.builder.augmented_grid(perceived=on)
    ahead = idx[on & s.scene.has_tracks[idx]]
    # the perceived boxes now, and the moving ones ahead: the cells released around the
    # robot keep their distance to each (_free_cells)
    xy, yaw = _footprints(s.scene, s.t, idx[on])
    boxes = (xy, s.scene.half_extents[idx[on], :2], yaw)
    if ahead.size:
        # where they are at the next event, or at the mission's end after the last one (an
        # artefact that yields onto the plan after the last move tick waits there: the sixth
        # robot collision of the one-hour A* benchmark mission)
        t_ahead = float(s.events.t[s.event]) if s.event < s.events.t.size else m.T
        xy, yaw = _footprints(s.scene, t_ahead, ahead)
        half = s.scene.half_extents[ahead, :2]
        poly = box_corners(xy, half, yaw)
        _, flat, _ = rasterise_convex(m.grid.world_to_local(poly), m.grid.shape)
        aug.data.ravel()[flat] = 100
        boxes = tuple(np.concatenate(p) for p in zip(boxes, (xy, half, yaw), strict=True))
    free = _free_cells(m, ~aug.free, s.pose, boxes)
    aug.data.flags.writeable = False
    free.flags.writeable = False
    at = (s.scene, s.t, s.events, s.event, s.seen.copy(), s.pose.copy(), aug, free)
    return s._replace(planning_at=at), aug, free


def _free_cells(
    m: _Mission, occ: np.ndarray, pose: np.ndarray, boxes: tuple | None = None
) -> np.ndarray:
    """(H, W) bool: the cells where the robot's centre may go on the augmented grid whose
    occupied cells are ``occ``: farther than the robot radius plus half a cell diagonal
    from every occupied cell, or free, within reach of the robot's own ``pose`` and no
    nearer to any of the artefact ``boxes`` (centres (k, 2), half sizes (k, 2), headings
    (k,): those on the grid) than the robot is, up to that clearance (the robot's own
    cell, where its plans start, whatever its distance).

    The released cells let a robot brushing an obstacle leave; without the boxes' test
    they let a plan run along an artefact standing next to the robot, and into it (5 of the
    6 robot collisions of the one-hour A* benchmark mission: the robot planned 0.33-0.38 m
    from a waiting person's box, inside the inflation of its cells, and closed to
    0.27-0.29 m). The map's own cells are not tested: the robot may brush a wall."""
    res, radius = m.grid.resolution, m.robot.radius
    # the cells farther than the clearance from the map's own occupied cells (once per
    # mission, m.static_clear), less those within it of an artefact's cell: the offsets
    # (m.clear_offsets) whose distance transform distance, sqrt(dr^2 + dc^2) * res, is at
    # most the clearance, around the artefact cells on their set's edge (a cell within
    # reach of one inside it is within reach of one on its edge: a staircase path between
    # them, inside the grid, gets no farther from it). The same cells as thresholding one Euclidean
    # distance transform of the whole augmented grid, at a fraction of its cost.
    free = m.static_clear & ~occ
    art = occ & ~m.static_occ
    if art.any():
        inner = art.copy()
        inner[1:, :] &= art[:-1, :]
        inner[:-1, :] &= art[1:, :]
        inner[:, 1:] &= art[:, :-1]
        inner[:, :-1] &= art[:, 1:]
        edge = np.argwhere(art & ~inner)
        ij = (edge[:, None, :] + m.clear_offsets[None, :, :]).reshape(-1, 2)
        h, w = occ.shape
        ok = (ij[:, 0] >= 0) & (ij[:, 0] < h) & (ij[:, 1] >= 0) & (ij[:, 1] < w)
        free.ravel()[ij[ok, 0] * w + ij[ok, 1]] = False
    # cells around the robot that are inflated but not occupied are released
    reach = radius + res
    r_c = np.asarray(m.grid.world_to_cell(pose[None, :2]), np.int64).reshape(2)
    pad = int(np.ceil(reach / res)) + 2
    lo = np.clip(r_c - pad, 0, occ.shape)
    hi = np.clip(r_c + pad + 1, 0, occ.shape)
    ij = np.indices(tuple(hi - lo)).reshape(2, -1).T + lo
    if ij.size:
        xy = m.grid.cell_to_world(ij)
        near = np.linalg.norm(xy - pose[:2], axis=1) <= reach
        ij, xy = ij[near], xy[near]
        ok = ~occ[ij[:, 0], ij[:, 1]]
        if boxes is not None and len(boxes[0]) and ok.any():
            c, half, yaw = (np.asarray(a, float) for a in boxes)
            clear = radius + res * np.sqrt(0.5)
            # only the boxes within the clearance of a cell within reach count
            r_box = np.hypot(half[:, 0], half[:, 1])
            j = np.flatnonzero(np.linalg.norm(c - pose[:2], axis=1) - r_box <= reach + clear)
            if j.size:
                d_robot = point_box_distance(pose[:2], c[j], half[j], yaw[j])  # (b,)
                k = np.flatnonzero(ok)
                d = point_box_distance(
                    np.repeat(xy[k], j.size, axis=0),
                    np.tile(c[j], (k.size, 1)),
                    np.tile(half[j], (k.size, 1)),
                    np.tile(yaw[j], k.size),
                ).reshape(k.size, j.size)
                ok[k] = (d >= np.minimum(d_robot, clear) - 1e-9).all(axis=1)
            # the robot's own cell stays released: a plan starts there (its centre may be
            # nearer to a box than the robot, but the path leaves from the robot's pose)
            ok |= (ij == r_c).all(axis=1) & ~occ[ij[:, 0], ij[:, 1]]
        free[ij[ok, 0], ij[ok, 1]] = True
    return free


def _static_clearance(
    grid: OccupancyGrid, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The map's part of :func:`_free_cells`, once per mission: its non-free cells (H, W)
    bool (unknown included, as the planner treats them), the cells (H, W) bool farther
    than the clearance (``radius`` plus half a cell diagonal) from them, and the cell
    offsets (k, 2) int within the clearance, their distance computed as scipy's
    ``distance_transform_edt`` computes it (``sqrt(dr^2 + dc^2)``, then scaled)."""
    # lazy: SciPy's ndimage adds 0.15 s CPU to `import are_stats.experiments`
    from scipy import ndimage

    res = grid.resolution
    static_occ = ~grid.free
    # cell-centre distances: half a cell diagonal added so the disc clears box edges
    clear = radius + res * np.sqrt(0.5)
    static_dist = (
        ndimage.distance_transform_edt(~static_occ) * res
        if static_occ.any()
        else np.full(static_occ.shape, np.inf)
    )
    reach = int(np.ceil(clear / res)) + 1
    offsets = np.indices((2 * reach + 1, 2 * reach + 1)).reshape(2, -1).T - reach
    d_off = np.sqrt((offsets.astype(np.float64) ** 2).sum(1)) * res
    return static_occ, static_dist > clear, offsets[d_off <= clear]


def _path_blocked(m: _Mission, s: _State, free: np.ndarray) -> bool:
    """Whether the rest of the plan crosses a cell the planner may not use."""
    assert s.path is not None
    ss = np.arange(s.s_along, s.cum[-1] + m.step, m.step)
    pts, _ = _point_at(s.path, s.cum, ss)
    pts = pts[np.linalg.norm(pts - s.pose[:2], axis=1) > m.robot.radius + m.grid.resolution]
    ij = m.grid.world_to_cell(pts)
    inside = m.grid.in_bounds(ij)
    return bool((~inside).any() or (~free[ij[inside, 0], ij[inside, 1]]).any())


def _contacts(
    m: _Mission, pts: np.ndarray, times: np.ndarray, s: _State
) -> tuple[np.ndarray, int, int, tuple]:
    """Footprint tests at robot positions ``pts`` (k, 2) at ``times`` (k,) against the live
    boxes there, starting from ``s.pose`` at ``s.t``.

    Returns the contact flags (N,) after the last test and the new contacts, split by who
    closed the gap over the last step: the robot (it drove into the box: a collision) or
    the artefact (it walked into the robot faster than the robot came), and the state's
    new ``contact_clear``.

    With no contact after a test, ``contact_clear`` keeps until when none can begin: the
    smallest gap between the robot's disc and a live box's reach from its pose
    (``m.art_radius``), over the speeds at which both can close it (``m.art_speed``, the
    robot's speed). Tests up to then, in the same scene with the same live artefacts,
    find no contact and are skipped (in the camera missions most of the footprint tests,
    one a 0.1 s tick, are far from every box).
    """
    c = s.contact_clear
    if (
        c
        and c[0] is s.scene
        and float(times[-1]) <= c[2]
        and np.array_equal(c[1], s.live)
        and not s.in_contact.any()
    ):
        return s.in_contact, 0, 0, c
    idx = np.flatnonzero(s.live)
    k, n = len(pts), idx.size
    if not n:
        return np.zeros(s.live.size, bool), 0, 0, ()
    half = s.scene.half_extents[idx, :2]
    # the boxes at s.t and at every test time: (k + 1, n) centres and headings
    if s.scene.has_tracks[idx].any():
        pose = s.scene.poses_at(np.r_[s.t, times], idx).reshape(-1, 3)
        xy = box_centres(pose, np.tile(s.scene.offsets[idx], (k + 1, 1)))[:, :2]
        xy, yaw = xy.reshape(k + 1, n, 2), pose[:, 2].reshape(k + 1, n)
        last = pose[-n:, :2]
    else:
        pose = s.scene.poses(s.t, idx)  # as _footprints
        xy0, yaw0 = box_centres(pose, s.scene.offsets[idx])[:, :2], pose[:, 2]
        xy, yaw = np.broadcast_to(xy0, (k + 1, n, 2)), np.broadcast_to(yaw0, (k + 1, n))
        last = pose[:, :2]
    q = np.repeat(pts, n, axis=0)
    hit = (
        point_box_distance(
            q, xy[1:].reshape(-1, 2), np.tile(half, (k, 1)), yaw[1:].reshape(-1)
        ).reshape(k, n)
        <= m.robot.radius
    )
    before = np.vstack([s.in_contact[idx][None], hit[:-1]])
    step, box = np.nonzero(hit & ~before)  # new contacts: (step, box) pairs
    by_robot = by_artefact = 0
    if step.size:
        q_prev = np.vstack([s.pose[None, :2], pts[:-1]])
        d = pts[step] - xy[step + 1, box]
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        robot_gain = -np.einsum("ij,ij->i", d, pts[step] - q_prev[step])
        artefact_gain = np.einsum("ij,ij->i", d, xy[step + 1, box] - xy[step, box])
        # a box that did not come closer (one standing) never walked in
        by_artefact = int(((artefact_gain > robot_gain) & (artefact_gain > 0)).sum())
        by_robot = int(step.size) - by_artefact
    in_contact = np.zeros(s.live.size, bool)
    in_contact[idx] = hit[-1]
    clear: tuple = ()
    if not hit[-1].any():
        # the reach from the pose bounds the box (offset plus half diagonal, any heading);
        # 1e-6 m for rounding
        gap = np.linalg.norm(last - pts[-1], axis=1) - m.art_radius[idx] - m.robot.radius
        v = np.maximum(m.art_speed[idx] + m.robot.speed, 1e-12)
        clear = (s.scene, s.live, float(times[-1]) + float(((gap - 1e-6) / v).min()))
    return in_contact, by_robot, by_artefact, clear


def _plan(m: _Mission, s: _State) -> tuple[_State, dict, tuple | None]:
    """Plan from the robot's pose to the current goal on the perceived grid."""
    idx = np.flatnonzero(s.scene.alive(s.t))
    s, _, free = _planning_grid(m, s, idx)
    res = m.grid.resolution
    start_l = m.grid.world_to_local(s.pose[:2]) * res
    goal_l = m.grid.world_to_local(m.goals[s.goal]) * res
    params = {"resolution": res, "seed": int(m.seed) * 100003 + s.n_replans}
    p_local, rho_t = timed_plan(m.plan_fn, free, start_l, goal_l, params)
    path, cum, g_t, plan = None, np.zeros(1), np.inf, None
    if p_local is not None:
        path = m.grid.local_to_world(p_local / res)
        path[0], path[-1] = s.pose[:2], m.goals[s.goal]
        cum = _arc(path)
        g_t = cum[-1] / m.robot.speed
        plan = (s.t, path.copy()) if m.record else None
    ok = p_local is not None
    row = {
        "t": s.t,
        "goal": s.goal,
        "reason": s.reason,
        "rho_t": rho_t,
        "g_t": g_t,
        "rho": float(replanning_ratio([rho_t], [g_t])[0]) if ok else np.nan,
        "success": ok,
        "path_length": float(cum[-1]) if ok else np.nan,
        "n_live": int(s.live.sum()),
        "n_perceived": int(s.seen.sum()),
        "n_A": s.n_A,
        "nu": s.n_A / m.n_free,
    }
    standing = np.nan if ok else (s.standing if np.isfinite(s.standing) else s.t)
    s = s._replace(
        path=path,
        cum=cum,
        s_along=0.0,
        need_plan=False,
        n_replans=s.n_replans + 1,
        standing=standing,
    )
    return s, row, plan


def _drive(m: _Mission, s: _State, s_new: float, t_new: float) -> tuple[_State, list]:
    """Drive along the plan to arc length ``s_new``, reached at ``t_new``."""
    assert s.path is not None
    ds = s_new - s.s_along
    k = max(int(np.ceil(ds / m.step)), 1)
    frac = np.arange(1, k + 1) / k
    pts, hd = _point_at(s.path, s.cum, s.s_along + ds * frac)
    tt = s.t + (t_new - s.t) * frac
    in_contact, by_robot, by_artefact, clear = _contacts(m, pts, tt, s)
    poses = np.column_stack([tt, pts, hd]).tolist() if m.record else []
    s = s._replace(
        t=t_new,
        pose=np.array([pts[-1, 0], pts[-1, 1], hd[-1]]),
        s_along=s_new,
        distance=s.distance + ds,
        in_contact=in_contact,
        collisions=s.collisions + by_robot,
        artefact_contacts=s.artefact_contacts + by_artefact,
        contact_clear=clear,
    )
    return s, poses


def _scene_update(m: _Mission, s: _State) -> tuple[_State, list[str]]:
    """Apply the scene's events at ``s.t`` (arrivals, leaves, moves); returns the update's
    kinds."""
    e = s.event
    live = s.scene.alive(s.t)
    idx = np.flatnonzero(live)
    arrived, left = live & ~s.live, s.live & ~live
    s = _register(s._replace(live=live, seen=s.seen & live, event=e + 1))
    kinds = []
    if s.events.lifecycle[e]:
        old = s.seen
        s = _perceive(m, s, idx)
        if arrived.any():
            kinds.append("arrival")
        if left.any():
            kinds.append("leave")
        if not kinds and not np.array_equal(old, s.seen):
            kinds.append("perceived")
        if kinds:
            s = s._replace(need_plan=True)
    moved = np.zeros(live.size, bool)
    moved[s.events.moved_at(e)] = True
    moved &= live
    if moved.any():
        kinds.append("move")
        s = s._replace(n_moves=s.n_moves + 1)
        if m.avoid:
            s, avoided, _ = _avoid(m, s, np.flatnonzero(moved))
            kinds.extend(avoided)
        if not s.need_plan and (moved & s.seen).any():
            # a perceived artefact moved: replan when it now blocks the plan (or the robot
            # was waiting for a way through)
            if s.path is None:
                s = s._replace(need_plan=True)
            else:
                s, _, free = _planning_grid(m, s, idx)
                if _path_blocked(m, s, free):
                    s = s._replace(need_plan=True)
    in_contact, _, _, clear = _contacts(m, s.pose[None, :2], np.array([s.t]), s)
    fresh = in_contact & ~s.in_contact
    s = s._replace(
        in_contact=in_contact,
        contact_clear=clear,
        arrival_contacts=s.arrival_contacts + int((fresh & arrived).sum()),
        artefact_contacts=s.artefact_contacts + int((fresh & ~arrived).sum()),
    )
    return s, kinds


def _avoid(
    m: _Mission, s: _State, moved: np.ndarray, replan: bool = False
) -> tuple[_State, list[str], np.ndarray]:
    """Artefacts ``moved`` (indices: those moving at this update, or every moving one after
    a replan, ``replan``) whose motion until their next check meets the robot's footprint,
    along its current plan, detour around it or wait
    (:func:`~are_stats.experiments._avoid.plan_avoidance`, the distance filter first);
    their new tracks go into the state's scene and the rest of the event table is rebuilt
    from it; also returns the indices (k,) of the artefacts whose tracks changed.

    The patience rule: an artefact that has waited for the robot (``s.waiting``, from its
    first wait; reset when it moves on at one of its own checks, detours or gives way)
    while the robot has stood with its plans failing (``s.standing``), both for at least
    ``m.patience`` seconds, gives way instead of waiting again, tried once in each of the
    robot's standing spells (``s.gave_way``; a try finding no clear spot waits): it steps
    back until its box is ``m.clearance + _GIVE_WAY_GAP`` from the robot's centre
    (``plan_avoidance(give_way=...)``). Without it a robot ringed by people waiting for it
    waited for them as they waited for it; once a spell, so that people who walk back to a
    robot still standing wait again instead of stepping back and forth, and a crowd with
    no room to step back tries once instead of at each of its checks."""
    scene, kinds, delay = s.scene, [], 0.0
    counts = {"detour": 0, "yield": 0, "give_way": 0}
    changed: list[int] = []
    if not moved.size:
        return s, kinds, np.zeros(0, np.int64)
    waiting, gave_way = s.waiting, s.gave_way
    if not replan and np.isfinite(waiting[moved]).any():
        # at its own check an artefact that does not wait again moves on
        waiting = waiting.copy()
        waiting[moved] = np.nan
    t_check = scene.next_epoch(s.t, moved)
    if m.move_period is not None:
        # its next move is registered on the clock's tick; a wait ends just before it, so
        # that the tick _event_table puts the wait's end on is that tick (k * p / p may
        # round above k)
        t_check = np.ceil(t_check / m.move_period) * m.move_period
        fin = np.isfinite(t_check)
        t_check[fin] -= 1e-9 * np.abs(t_check[fin])
    t_check = np.minimum(t_check, scene.t_leave[moved])
    # only those whose box can reach the robot's disc by then (both at their fastest)
    gap = np.linalg.norm(scene.poses(s.t, moved)[:, :2] - s.pose[:2], axis=1)
    v = m.art_speed[moved] + (m.robot.speed if s.path is not None else 0.0)
    near = gap - m.art_radius[moved] - v * (t_check - s.t) <= m.clearance
    track = None
    if s.path is not None:  # where the robot will be: along its plan, then at its end
        ahead = s.cum > s.s_along
        track = (
            s.t + np.r_[0.0, s.cum[ahead] - s.s_along] / m.robot.speed,
            np.vstack([s.pose[:2], s.path[ahead]]),
        )
    cand, t_cand = moved[near], t_check[near]
    ok = (s.t < t_cand) & (t_cand < np.inf)
    cand, t_cand = cand[ok], t_cand[ok]
    if cand.size:  # only those that come within reach of the robot's disc by then
        cand, t_cand = _within_reach(m, s, cand, t_cand, track)
    stood = s.t - s.standing if s.path is None and np.isfinite(s.standing) else -np.inf
    for i, tc in zip(cand.tolist(), t_cand.tolist(), strict=True):
        since = s.waiting[i]
        patient = (
            np.isfinite(since)
            and min(stood, s.t - since) >= m.patience - 1e-9
            and gave_way[i] != s.standing
        )
        got = plan_avoidance(
            scene,
            i,
            s.t,
            tc,
            s.pose[:2],
            m.clearance,
            m.grid,
            m.wall_distance,
            robot_track=track,
            give_way=m.clearance + _GIVE_WAY_GAP if patient else None,
            give_way_stay=_GIVE_WAY_STAY,
        )
        if patient:  # its one try in this spell, whether a spot was clear or not
            gave_way = gave_way.copy() if gave_way is s.gave_way else gave_way
            gave_way[i] = s.standing
        if got is None:
            continue
        now = (since if np.isfinite(since) else s.t) if got.kind == "yield" else np.nan
        if not (now == waiting[i] or (np.isnan(now) and np.isnan(waiting[i]))):
            waiting = waiting.copy() if waiting is s.waiting else waiting
            waiting[i] = now
        scene = scene.with_track(i, got.t, got.pose)
        changed.append(i)
        counts[got.kind] += 1
        delay += got.delay
        if got.kind not in kinds:
            kinds.append(got.kind)
    if not kinds:
        return s._replace(waiting=waiting, gave_way=gave_way), kinds, np.zeros(0, np.int64)
    # the tracks changed after s.t only: the coming events are rebuilt from there (the
    # changed artefacts' events; the others' are the coming ones of s.events)
    events = _events_after(s.events, scene, np.array(changed), m.T, m.move_period, s.t)
    s = s._replace(
        scene=scene,
        events=events,
        event=0,
        n_detours=s.n_detours + counts["detour"],
        n_yields=s.n_yields + counts["yield"],
        avoid_delay=s.avoid_delay + delay,
        n_give_ways=s.n_give_ways + counts["give_way"],
        waiting=waiting,
        gave_way=gave_way,
    )
    return s, sorted(kinds), np.array(changed, np.int64)


#: How far past the clearance (m) an artefact that gives way to a standing robot steps
#: back (its box from the robot's centre): room for the robot's plans between the people
#: who ringed it.
_GIVE_WAY_GAP = 0.5
#: How long (s) past its next check it stands there: the robot's next plan avoids the
#: artefacts where they are then and at the next scene event (two ticks of the benchmark's
#: 2 s move clock).
_GIVE_WAY_STAY = 4.0


#: Common times at which :func:`_within_reach` compares the moving artefacts with the robot.
_REACH_SAMPLES = 64


def _within_reach(
    m: _Mission, s: _State, cand: np.ndarray, t_check: np.ndarray, track: tuple | None
) -> tuple[np.ndarray, np.ndarray]:
    """The artefacts ``cand`` (k,) (with their next checks ``t_check`` (k,)) whose box may
    come within the clearance of the robot's centre by then: the others' motions keep clear
    of the robot, and :func:`plan_avoidance` would return ``None`` for them.

    A lower bound on the distance, in one vectorised pass instead of one sampled motion
    per artefact: the track positions and the robot's (along ``track``, its plan) at
    ``_REACH_SAMPLES + 1`` common times over ``[s.t, max(t_check)]``, the smallest gap
    less the distance both can close between two samples (at their fastest: half the
    spacing times the speeds) and the box's reach from its pose (``m.art_radius``); a
    box farther than the clearance (plus 1e-6 m for rounding) is dropped. The order of the
    rest is kept.
    """
    t1 = float(t_check.max())
    tau = s.t + (t1 - s.t) * np.arange(_REACH_SAMPLES + 1) / _REACH_SAMPLES
    pos = s.scene.poses_at(tau, cand)[..., :2]  # (S + 1, k, 2)
    if track is None:
        robot, v_robot = np.broadcast_to(s.pose[:2], (tau.size, 2)), 0.0
    else:
        rt, rxy = track
        robot = np.column_stack([np.interp(tau, rt, rxy[:, 0]), np.interp(tau, rt, rxy[:, 1])])
        speeds = np.linalg.norm(np.diff(rxy, axis=0), axis=1) / np.maximum(np.diff(rt), 1e-12)
        v_robot = float(speeds.max()) if rt.size > 1 else 0.0
    gap = np.linalg.norm(pos - robot[:, None, :], axis=2).min(axis=0)
    slack = (m.art_speed[cand] + v_robot) * (t1 - s.t) / _REACH_SAMPLES / 2.0
    keep = gap - slack - m.art_radius[cand] <= m.clearance + 1e-6
    return cand[keep], t_check[keep]


def _init(m: _Mission, pose: np.ndarray) -> _State:
    """The state at t = 0: the live artefacts registered and perceived from ``pose``."""
    n = len(m.scene)
    live = m.scene.alive(0.0)
    idx = np.flatnonzero(live)
    s = _State(
        t=0.0,
        pose=pose,
        goal=0,
        reached=np.full(m.goals.shape[0], np.nan),
        path=None,
        cum=np.zeros(1),
        s_along=0.0,
        need_plan=True,
        reason="goal",
        live=live,
        seen=np.zeros(n, bool),
        in_contact=np.zeros(n, bool),
        n_A=0,
        event=0,
        next_percept=m.period if m.perception == "camera" else np.inf,
        n_replans=0,
        n_updates=0,
        n_moves=0,
        collisions=0,
        arrival_contacts=0,
        artefact_contacts=0,
        distance=0.0,
        scene=m.scene,
        events=m.events,
        n_detours=0,
        n_yields=0,
        avoid_delay=0.0,
        n_give_ways=0,
        waiting=np.full(n, np.nan),
        standing=np.nan,
        gave_way=np.full(n, np.nan),
        replans_at=(np.nan, 0),
        builder=ARBuilder(m.grid),
        builder_at=(None, np.nan),
        planning_at=(),
        percepts=MappingProxyType({}),
        contact_clear=(),
    )
    s = _perceive(m, _register(s), idx)
    in_contact, _, _, clear = _contacts(m, pose[None, :2], np.array([0.0]), s)
    return s._replace(
        in_contact=in_contact, arrival_contacts=int(in_contact.sum()), contact_clear=clear
    )


def _done(m: _Mission, s: _State) -> bool:
    return s.goal >= m.goals.shape[0] or s.t >= m.T


def _step(m: _Mission, s: _State) -> tuple[_State, _Info]:
    """One transition: plan if needed, then drive to the next event (goal reached, scene
    event, perception tick or time limit) and apply it. With ``avoid_robot``, a plan is
    followed by the moving artefacts' decisions against it; when one detours or yields,
    the transition ends there (a scene update at the plan's time)."""
    replan = plan = None
    if s.need_plan:
        s, replan, plan = _plan(m, s)
        if m.avoid:
            # the moving artefacts decided against the robot's old plan (or its standing):
            # those whose motion until their next check meets the new one decide again
            moving = np.flatnonzero(s.live & s.scene.has_tracks)
            s, avoided, changed = _avoid(m, s, moving, replan=True)
            if avoided:  # a scene update of its own, at the replan's time
                s = _check_after_avoidance(m, s, changed)
                s, update, scene = _update(m, s, ["replan", *avoided])
                return s, _Info(replan=replan, update=update, plan=plan, scene=scene)
    t_event = s.events.t[s.event] if s.event < s.events.t.size else np.inf
    t_next = min(t_event, s.next_percept, m.T)
    poses: list = []
    if s.path is not None:
        t_goal = s.t + (s.cum[-1] - s.s_along) / m.robot.speed
        if t_goal <= t_next:
            s, poses = _drive(m, s, float(s.cum[-1]), t_goal)
            reached = s.reached.copy()
            reached[s.goal] = s.t
            s = s._replace(
                goal=s.goal + 1, reached=reached, path=None, need_plan=True, reason="goal"
            )
            return s, _Info(replan=replan, poses=poses, plan=plan)
        s, poses = _drive(m, s, s.s_along + (t_next - s.t) * m.robot.speed, t_next)
    s = s._replace(t=t_next)
    if t_next >= m.T:
        return s, _Info(replan=replan, poses=poses, plan=plan)
    kinds: list[str] = []
    if t_next == t_event:
        s, kinds = _scene_update(m, s)
    if t_next == s.next_percept:
        old = s.seen
        # (the live artefacts only: a tick perceived in its batch needs no boxes)
        idx = np.flatnonzero(s.scene.alive(s.t))
        s = _perceive(m, s, idx, tick=True)._replace(next_percept=t_next + m.period)
        if not np.array_equal(old, s.seen):
            s = s._replace(need_plan=True)
            if not kinds:
                kinds.append("perceived")
    update = scene = None
    if kinds:
        s, update, scene = _update(m, s, kinds)
    return s, _Info(replan=replan, update=update, poses=poses, plan=plan, scene=scene)


#: Plans one instant may make again because the artefacts' answers to the previous one
#: (a wait, a detour) stand in its way (:func:`_check_after_avoidance`).
_REPLANS_AT_ONCE = 3


def _check_after_avoidance(m: _Mission, s: _State, changed: np.ndarray) -> _State:
    """The state after the moving artefacts answered a new plan: when a perceived one of
    those that changed their tracks (``changed`` (k,)) now blocks the plan (it waits on it,
    or detours across it), the robot plans again at the same instant, as after a move that
    blocks its plan; at most ``_REPLANS_AT_ONCE`` times in one instant (each plan is
    answered again).

    Without it the robot drove on along a plan made against the artefacts' old tracks,
    into an artefact waiting on it for the robot to pass (most of the robot's collisions
    in the one-hour benchmark mission)."""
    if s.path is None or not s.seen[changed].any():
        return s
    at, n = s.replans_at
    if at == s.t and n >= _REPLANS_AT_ONCE:
        return s
    s, _, free = _planning_grid(m, s, np.flatnonzero(s.scene.alive(s.t)))
    if not _path_blocked(m, s, free):
        return s
    return s._replace(need_plan=True, replans_at=(s.t, n + 1 if at == s.t else 1))


def _update(m: _Mission, s: _State, kinds: list[str]) -> tuple[_State, dict, dict | None]:
    """A scene update of ``kinds`` at ``s.t``: counted, with its timeline row and recorded
    scene; it is the reason of the next plan when it asks for one."""
    reason = "+".join(kinds)
    s = s._replace(n_updates=s.n_updates + 1, reason=reason if s.need_plan else s.reason)
    record = None
    if m.record:
        s, record = _scene_record(m, s)
    return s, _timeline_row(m, s, reason), record


def _timeline_row(m: _Mission, s: _State, kind: str) -> dict:
    return {
        "t": s.t,
        "kind": kind,
        "n_live": int(s.live.sum()),
        "n_perceived": int(s.seen.sum()),
        "n_A": s.n_A,
        "nu": s.n_A / m.n_free,
    }


def _scene_record(m: _Mission, s: _State) -> tuple[_State, dict]:
    idx, boxes = _boxes(s.scene, s.t)
    s, grid, _ = _planning_grid(m, s, idx)
    return s, {
        "t": s.t,
        "ids": boxes.ids,
        "centres": boxes.centres,
        "half": boxes.half_extents,
        "yaws": boxes.yaws,
        "labels": list(boxes.labels),
        "perceived": s.seen[idx],
        "grid": grid,
    }


def _track_speeds(scene: Scene) -> np.ndarray:
    """(N,) the fastest speed of each artefact between its track epochs (0 without)."""
    out = np.zeros(len(scene))
    for i in np.flatnonzero(scene.has_tracks):
        tt, pp = scene.track(int(i))
        if tt.size > 1:
            v = np.linalg.norm(np.diff(pp[:, :2], axis=0), axis=1) / np.diff(tt)
            out[i] = float(v.max())
    return out


class _Events(NamedTuple):
    """A scene's events as the loop reads them: distinct times (e,), whether an artefact
    arrives or leaves at each (e,) bool, and the indices of the artefacts that move at
    each, ``moved[start[k]:start[k + 1]]`` for time ``k`` (start (e + 1,))."""

    t: np.ndarray
    lifecycle: np.ndarray
    start: np.ndarray
    moved: np.ndarray

    def moved_at(self, k: int) -> np.ndarray:
        """(j,) indices of the artefacts that move at time ``t[k]``."""
        return self.moved[self.start[k] : self.start[k + 1]]


def _event_table(scene: Scene, T: float, move_period: float | None, after: float = 0.0) -> _Events:
    """The scene's events at times in ``(after, T)``: arrivals and leaves at their times,
    moves at their epochs, or on the next tick of ``move_period`` when given (an epoch up
    to a period before ``after`` may tick after it)."""
    lower = after if move_period is None else max(0.0, after - 2.0 * move_period)
    t, kind, idx = scene.event_arrays(lower, T)
    is_move = kind == 2
    if move_period is not None:
        t = np.where(is_move, np.ceil(t / move_period) * move_period, t)
    keep = (t > after) & (t < T)
    t, is_move, idx = t[keep], is_move[keep], idx[keep]
    times, inv = np.unique(t, return_inverse=True)
    lifecycle = np.zeros(times.size, bool)
    lifecycle[inv[~is_move]] = True
    at, who = inv[is_move], idx[is_move]
    order = np.lexsort((who, at))
    start = np.r_[0, np.cumsum(np.bincount(at, minlength=times.size))].astype(np.int64)
    return _Events(times, lifecycle, start, who[order])


def _events_after(
    events: _Events,
    scene: Scene,
    changed: np.ndarray,
    T: float,
    move_period: float | None,
    after: float,
) -> _Events:
    """:func:`_event_table` of ``scene`` after ``after``, from ``events``, the table of a
    scene that differs from it only in the tracks of the artefacts ``changed`` (k,) and was
    built at or before ``after``: its events after ``after`` less the moves of ``changed``,
    and their moves on their new tracks. The same table as a rebuild of every artefact's
    events, at the cost of the changed artefacts' tracks and a merge."""
    lower = after if move_period is None else max(0.0, after - 2.0 * move_period)
    # the moves of the changed artefacts on their new tracks, as _event_table finds them
    ticks, who = [], []
    for i in np.unique(changed).tolist():
        tt, _ = scene.track(i)
        tt = tt[(tt > lower) & (tt <= T) & (tt >= scene.t_arrive[i]) & (tt < scene.t_leave[i])]
        if move_period is not None:
            tt = np.ceil(tt / move_period) * move_period
        tt = tt[(tt > after) & (tt < T)]
        ticks.append(tt)
        who.append(np.full(tt.size, i, np.int64))
    new_t = np.concatenate([np.zeros(0), *ticks])
    new_who = np.concatenate([np.zeros(0, np.int64), *who])
    # the old table after ``after``, less the changed artefacts' moves
    at = np.repeat(np.arange(events.t.size), np.diff(events.start))
    keep = (events.t[at] > after) & ~np.isin(events.moved, changed)
    old_at, old_who = at[keep], events.moved[keep]
    life = events.lifecycle & (events.t > after)
    times = np.unique(np.concatenate([events.t[old_at], events.t[life], new_t]))
    lifecycle = np.zeros(times.size, bool)
    lifecycle[np.searchsorted(times, events.t[life])] = True
    # old moves stay sorted by (time, artefact): the new ones are merged in by that key
    n = len(scene)
    key_old = np.searchsorted(times, events.t[old_at]) * n + old_who
    key_new = np.sort(np.searchsorted(times, new_t) * n + new_who)
    key = np.insert(key_old, np.searchsorted(key_old, key_new, side="right"), key_new)
    at_all, moved = np.divmod(key, n)
    start = np.r_[0, np.cumsum(np.bincount(at_all, minlength=times.size))].astype(np.int64)
    return _Events(times, lifecycle, start, moved.astype(np.int64))


def run_mission(
    grid: OccupancyGrid,
    scene: Scene,
    goals: npt.ArrayLike,
    planner: Mapping[str, object] | Planner | str = "astar",
    *,
    robot: Robot | None = None,
    start: npt.ArrayLike | None = None,
    time_limit: float = 300.0,
    perception: str = "all",
    env_mesh: trimesh.Trimesh | None = None,
    perception_period: float = 1.0,
    d_max: float = 10.0,
    tau: float = 10.0,
    perception_memory: bool = True,
    move_period: float | None = None,
    avoid_robot: bool = True,
    avoid_margin: float = 0.2,
    avoid_patience: float = 2.0,
    seed: int = 0,
    record: bool = False,
) -> MissionResult:
    """Drive a robot through ``goals`` on the augmented map of one scenario (Sect. 4),
    replanning as the artefacts arrive, move and leave.

    Parameters
    ----------
    grid : OccupancyGrid
        The real map M_2D.
    scene : Scene
        The artefacts of one scenario as boxes over time, moving along their behaviour
        tracks when they have some (:func:`~are_stats.scenarios.scenes_from_fit`, or
        :meth:`are_stats.Scene.from_scenarios` for a scenario table, the catalogue Q and
        the tracks).
    goals : (g, 2) float
        Goal positions (m, map frame), visited in order.
    planner : callable, dict or "astar"
        A planner callable (see :mod:`are_stats.experiments`), a spec for
        :func:`~are_stats.experiments.make_planner`, or ``"astar"``.
    robot : Robot, optional
        Footprint, speed, camera (default :class:`Robot`).
    start : (3,) float, optional
        Initial pose ``(x, y, yaw)``; default the first goal's position (which then counts
        as reached at time 0 and is dropped from the goals).
    time_limit : float
        Mission time limit (s).
    perception : {"all", "camera"}
        ``"all"``: every live artefact is perceived; ``"camera"``: A_f of the robot's camera
        (Sect. 3.3, :func:`~are_stats.perception.perceived_counts`) against ``env_mesh``.
    env_mesh : trimesh.Trimesh, optional
        Environment mesh S_3D (required for ``"camera"``).
    perception_period : float
        Seconds between perception checks (``"camera"``).
    d_max, tau : float
        Range and occlusion threshold of A_f.
    perception_memory : bool
        Keep an artefact on the planner's map once perceived (at its current pose), until
        it leaves.
    move_period : float, optional
        Apply the artefacts' moves on a clock of this period (s): the builder registers the
        new poses at its ticks (the boxes still slide continuously between them). Default:
        at every track epoch of every artefact (their epochs start at their own arrival
        times, so with many artefacts this makes many updates).
    avoid_robot : bool
        The robot's current footprint (a disc of radius ``robot.radius + avoid_margin``) is
        an obstacle the moving artefacts plan around: at each of its move epochs an
        artefact whose motion to its next epoch would bring its box into that disc (and
        closer than it is) detours on the map's free cells, clear of walls and of the
        other artefacts, rejoining its track a few epochs on, or, with no such detour,
        stops short on its track and waits an epoch; the rest of its track runs late by
        the extra time (:mod:`are_stats.experiments._avoid`). When the robot replans, every
        moving artefact whose motion until its next epoch meets the new plan decides again
        the same way, from where it is. Each avoidance is a timeline ``kind``
        (``"move+detour"``, ``"move+yield"``; ``"replan+detour"``, ``"replan+yield"`` after
        a replan) and counted in the summary. With ``False`` the artefacts ignore the
        robot.
    avoid_margin : float
        Safety margin (m) added to the robot's radius for ``avoid_robot``.
    avoid_patience : float
        Seconds an artefact waits for a robot that stands, its plans failing, before it
        gives way (``avoid_robot``), once in each spell the robot stands: it steps back
        until its box is 0.5 m past the safety margin from the robot's centre
        (``"move+give_way"``, ``"replan+give_way"``, counted in ``n_give_ways``), to a spot
        clear of walls and of the other artefacts, then goes on along its track. With the
        moves on a 2 s clock, the default gives way at the artefact's next check after a
        wait.
    seed : int
        Passed to the planner as ``params["seed"]`` (plus the replan index).
    record : bool
        Keep a :class:`MissionTrace` for export.

    Returns
    -------
    MissionResult

    Raises
    ------
    ValueError
        On malformed input (named argument and what was expected).
    """
    if not isinstance(grid, OccupancyGrid):
        raise ValueError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    robot = Robot() if robot is None else robot
    if not isinstance(robot, Robot):
        raise ValueError(f"robot: expected a Robot, got {type(robot).__name__}")
    if not isinstance(scene, Scene):
        raise ValueError(
            f"scene: expected a Scene (scenes_from_fit, or Scene.from_scenarios for a "
            f"scenario table), got {type(scene).__name__}"
        )
    plan_fn = make_planner({"algorithm": "astar"} if planner == "astar" else planner)
    perception = check_in("perception", perception, ("all", "camera"))
    if perception == "camera" and env_mesh is None:
        raise ValueError("env_mesh: perception='camera' needs the environment mesh S_3D")
    T = float(check_positive("time_limit", time_limit))
    period = float(check_positive("perception_period", perception_period))
    d_max = float(check_positive("d_max", d_max))
    tau = float(check_nonnegative("tau", tau))
    if move_period is not None:
        move_period = float(check_positive("move_period", move_period))
    if not isinstance(avoid_robot, bool | np.bool_):
        raise ValueError(f"avoid_robot: expected true or false, got {avoid_robot!r}")
    avoid = bool(avoid_robot)
    margin = float(check_nonnegative("avoid_margin", avoid_margin))
    patience = float(check_nonnegative("avoid_patience", avoid_patience))
    G = check_finite("goals", goals, ndim=2)
    if G.shape[1] != 2 or G.shape[0] < 1:
        raise ValueError(f"goals: expected shape (g, 2) with g >= 1, got {G.shape}")
    if start is None:
        if G.shape[0] < 2:
            raise ValueError(
                "goals: without start, expected at least 2 goals (the first is the start)"
            )
        pose = np.array([G[0, 0], G[0, 1], 0.0])
        G = G[1:]
    else:
        pose = check_finite("start", start, ndim=1).copy()
        if pose.shape != (3,):
            raise ValueError(f"start: expected (x, y, yaw), got {pose.tolist()}")
    if grid.n_free == 0:
        raise ValueError("grid: expected free cells, got none")
    events = _event_table(scene, T, move_period)
    static_occ, static_clear, clear_offsets = _static_clearance(grid, robot.radius)
    m = _Mission(
        grid=grid,
        scene=scene,
        robot=robot,
        plan_fn=plan_fn,
        goals=G,
        T=T,
        perception=perception,
        env_mesh=env_mesh,
        period=period,
        d_max=d_max,
        tau=tau,
        memory=bool(perception_memory),
        seed=int(seed),
        record=bool(record),
        step=min(grid.resolution, robot.radius / 2.0),
        n_free=grid.n_free,
        events=events,
        static_occ=static_occ,
        static_clear=static_clear,
        clear_offsets=clear_offsets,
        avoid=avoid,
        clearance=robot.radius + margin,
        patience=patience,
        move_period=move_period,
        wall_distance=grid.distance_to_occupied() if avoid and scene.has_tracks.any() else None,
        art_radius=np.hypot(*scene.offsets[:, :2].T) + np.hypot(*scene.half_extents[:, :2].T),
        art_speed=_track_speeds(scene),
    )
    # refuse before looping: footprint tests along the path, and grid passes per replan
    n_motion = robot.speed * T / m.step + 1.0
    # a camera tick casts the image's rays; it replans only when A_f changes, which each
    # artefact does about twice (into view, out of it)
    n_ticks = T / period if perception == "camera" else 0.0
    rays = float(np.prod(robot.image_size)) if perception == "camera" else 0.0
    n_plans = events.t.size + G.shape[0] + min(n_ticks, 2.0 * len(scene)) + 1.0
    check_memory(n_motion * 64.0, f"the robot's {n_motion:.3g} motion steps", "run_mission")
    check_work(
        n_motion * 200.0
        + n_plans * (grid.data.size * 100.0 + len(scene) * 3000.0)
        + n_ticks * rays * 2000.0,
        f"{n_plans:.3g} replans on {grid.data.size} cells, {n_motion:.3g} motion steps and "
        f"{n_ticks * rays:.3g} camera rays",
        "run_mission",
    )

    s = _init(m, pose)
    replans: list[dict] = []
    timeline: list[dict] = [_timeline_row(m, s, "start")]
    poses_log: list[list[float]] = [[0.0, *pose]]
    plans_log: list = []
    scenes_log: list = []
    if record:
        s, first = _scene_record(m, s)
        scenes_log.append(first)
    while not _done(m, s):
        s, info = _step(m, s)
        if info.replan is not None:
            replans.append(info.replan)
        if info.update is not None:
            timeline.append(info.update)
        if record:
            poses_log.extend(info.poses or [])
            if info.plan is not None:
                plans_log.append(info.plan)
            if info.scene is not None:
                scenes_log.append(info.scene)

    reached = s.reached
    end = float(s.t if s.goal == G.shape[0] else T)
    rp = pd.DataFrame(
        replans,
        columns=[
            "t",
            "goal",
            "reason",
            "rho_t",
            "g_t",
            "rho",
            "success",
            "path_length",
            "n_live",
            "n_perceived",
            "n_A",
            "nu",
        ],
    )
    tl = pd.DataFrame(timeline, columns=["t", "kind", "n_live", "n_perceived", "n_A", "nu"])
    gl = pd.DataFrame(
        {"goal": np.arange(G.shape[0]), "x": G[:, 0], "y": G[:, 1], "t_reached": reached}
    )
    n_reached = int(np.isfinite(reached).sum())
    t_goals = np.diff(np.r_[0.0, reached[np.isfinite(reached)]])
    summary = {
        "goals_total": int(G.shape[0]),
        "goals_reached": n_reached,
        "mission_time": end,
        "time_per_goal": float(t_goals.mean()) if n_reached else np.nan,
        "collisions": int(s.collisions),
        "arrival_contacts": int(s.arrival_contacts),
        "artefact_contacts": int(s.artefact_contacts),
        "n_detours": int(s.n_detours),
        "n_yields": int(s.n_yields),
        "avoid_delay": float(s.avoid_delay),
        "n_give_ways": int(s.n_give_ways),
        "n_replans": len(rp),
        "n_failed_plans": int((~rp["success"]).sum()) if len(rp) else 0,
        "n_updates": s.n_updates,
        "n_move_updates": s.n_moves,
        "update_rate": s.n_updates / end if end > 0 else np.nan,
        "rho_mean": float(rp["rho"].mean()) if rp["rho"].notna().any() else np.nan,
        "rho_t_mean": float(rp["rho_t"].mean()) if len(rp) else np.nan,
        "nu_mean": time_average(
            tl["t"].to_numpy(), tl["nu"].to_numpy(), max(end, tl["t"].iloc[-1])
        ),
        "nu_max": float(tl["nu"].max()),
        "distance": float(s.distance),
    }
    trace = (
        MissionTrace(np.array(poses_log), plans_log, scenes_log, G.copy(), s.scene)
        if record
        else None
    )
    return MissionResult(summary, rp, gl, tl, trace)
