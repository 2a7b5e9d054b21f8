"""Artefacts that avoid the robot: at a move epoch, an artefact whose next motion would bring
its box within ``clearance`` of the robot's centre (robot radius plus a safety margin), where
the robot is at each instant along its current plan, detours around the robot or waits for
it (issue 15, "Moving artefacts in the loop").

The decision is a pure function of a :class:`~are_stats.Scene`, the artefact, the time, the
robot's position and the map; it returns the artefact's new behaviour track, which the
experiment loop puts into its scene with :meth:`~are_stats.Scene.with_track`:

* **conflict**: the box, sampled along the artefact's motion from ``t`` to its next check
  ``t_check`` (at most ``ds`` apart relative to the robot), comes closer to the robot's
  centre at that instant than ``clearance`` *and* closer than it would be had it stood
  still (an artefact near the robot may move away from it, or stand; a robot driving at a
  standing artefact is the robot's doing);
* **detour**: a shortest 8-connected path on the map's free cells from the artefact's
  position to one of its own next ``lookahead`` track epochs past the conflict, with the
  cells blocked where its inscribed disc would meet a wall, where its circumscribed disc
  would come within ``clearance`` of the robot or meet another live artefact's box; the
  path is string-pulled, cut into pieces of one epoch's travel and walked at the
  artefact's speed on the track it leaves (never arriving before the epoch it rejoins);
  the rest of its track is delayed by the extra time. The detour's box, sampled at most
  ``ds`` apart with its heading as the scene interpolates it, is then tested exactly
  against the map's non-free cells (grown by ``ds``, for the motion between samples) and
  against the other artefacts' boxes at the same times (they move too); a detour that
  meets either, or takes more than ``lookahead`` epochs longer than the track, is refused;
* **yield** (no detour): the artefact advances along its own track up to the last sample
  before the conflict and holds there until ``t_check``, where the loop checks it again;
  the rest of its track is delayed by the wait;
* **give way** (no detour, and ``give_way`` given: the loop's patience rule, the robot
  standing and the artefact waiting for it for ``patience`` seconds already): instead of
  waiting again, the artefact steps back, as people do, out of the robot's safety margin:
  straight away from the robot (or up to 120 degrees off that direction) until its box is
  ``give_way`` metres from the robot's centre, to the nearest such spot whose walk (and
  stay until ``t_check``) keeps its box clear of the map's non-free cells and of the other
  artefacts' boxes, sampled as a detour is (past ``t_check`` the others' motions are
  decided again); it walks there at its track's speed, stands there until
  ``give_way_stay`` seconds past ``t_check`` (so that the robot's next plan, which also
  avoids where the artefacts will be at the next scene event, finds the way open), walks
  back and goes on along its track, late by the time that took. Without it a robot ringed
  by people waiting for it, its plans failing, waited for them as they waited for it
  (the one-hour RRT-Connect benchmark mission stalled).

Either way the artefact's life-cycle is unchanged: a delayed artefact still leaves at its
leaving time, possibly before the end of its track. ``t`` need not be one of the artefact's
epochs: the decision starts from its pose at ``t`` (its track gains an epoch there), so the
loop can ask again between its epochs. The decision trusts the robot's plan at ``t``; the
loop asks every moving artefact again whenever the robot replans (its plan, or its
standing when a plan fails), so the decisions hold for the motion the robot drives, up to
the sampling (``ds``). A waiting artefact is not an obstacle to the other artefacts'
(precomputed) tracks.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from are_stats.builder import box_centres, obb_overlap_2d, point_box_distance
from are_stats.environment import OccupancyGrid
from are_stats.experiments._planners import astar_cells
from are_stats.scenarios import Scene

__all__ = ["Avoidance", "plan_avoidance"]


class Avoidance(NamedTuple):
    """An artefact's answer to the robot in its way.

    Attributes
    ----------
    kind : {"detour", "yield", "give_way"}
    t : (m,) float
        The artefact's new track epochs (its whole track).
    pose : (m, 3) float
        ``x, y, yaw`` at the epochs.
    delay : float
        Seconds by which the rest of its track now runs late.
    """

    kind: str
    t: np.ndarray
    pose: np.ndarray
    delay: float


def _centres(scene: Scene, i: int | npt.NDArray[np.integer], pose: np.ndarray) -> np.ndarray:
    """Box centres (k, 2) of artefact ``i`` (an index, or (k,) indices) at poses (k, 3)."""
    return box_centres(pose, scene.offsets[i])[:, :2]


def _sample(
    scene: Scene,
    i: int,
    t0: float,
    t1: float,
    ds: float,
    v_robot: float = 0.0,
    track: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, ...]:
    """Times (k,), poses (k, 3) and box centres (k, 2) of artefact ``i`` over ``[t0, t1]``,
    at most ``ds`` metres apart, relative to a robot driving at up to ``v_robot`` (m/s);
    along ``track`` (epochs (m,), poses (m, 3)) instead of its track in ``scene`` when
    given."""
    tt, pp = scene.track(i) if track is None else track
    v = np.linalg.norm(np.diff(pp[:, :2], axis=0), axis=1) / np.maximum(np.diff(tt), 1e-12)
    v_max = (float(v.max()) if v.size else 0.0) + float(v_robot)
    k = int(np.ceil((t1 - t0) * v_max / ds)) + 2
    times = np.linspace(t0, t1, k)
    # as Scene.poses (t0 is at or after its first epoch): linear between epochs, the
    # heading the short way round, the last pose after the last epoch
    turn = np.mod(np.diff(pp[:, 2]) + np.pi, 2 * np.pi) - np.pi
    yaw = np.interp(times, tt, pp[0, 2] + np.r_[0.0, np.cumsum(turn)])
    pose = np.column_stack(
        [np.interp(times, tt, pp[:, 0]), np.interp(times, tt, pp[:, 1]), np.mod(yaw, 2 * np.pi)]
    )
    return times, pose, _centres(scene, i, pose)


def _clear_of_others(
    scene: Scene, i: int, times: np.ndarray, pose: np.ndarray, centres: np.ndarray
) -> bool:
    """Whether artefact ``i``'s box at ``pose`` (k, 3) meets no other live box at ``times``."""
    alive = scene.alive(np.asarray(times, float)[:, None])  # (k, N)
    alive[:, i] = False
    cols = np.flatnonzero(alive.any(axis=0))
    if not cols.size:
        return True
    # every (sample, other) pair alive then, tested in one pass
    ks, js = np.nonzero(alive[:, cols])
    pj = scene.poses_at(times, cols)[ks, js]
    cj = _centres(scene, cols[js], pj)
    n = ks.size
    hit = obb_overlap_2d(
        centres[ks],
        np.tile(scene.half_extents[i, :2], (n, 1)),
        pose[ks, 2],
        cj,
        scene.half_extents[cols[js], :2],
        pj[:, 2],
    )
    return not hit.any()


def plan_avoidance(
    scene: Scene,
    i: int,
    t: float,
    t_check: float,
    robot_xy: npt.ArrayLike,
    clearance: float,
    grid: OccupancyGrid,
    wall_distance: np.ndarray,
    *,
    robot_track: tuple[np.ndarray, np.ndarray] | None = None,
    lookahead: int = 4,
    ds: float | None = None,
    give_way: float | None = None,
    give_way_stay: float = 4.0,
) -> Avoidance | None:
    """Detour, wait or give way when artefact ``i``'s motion over ``[t, t_check]`` meets
    the robot.

    Parameters
    ----------
    scene : Scene
        The artefacts now (their tracks as already changed by earlier avoidances).
    i : int
        The artefact (index in the scene), alive at ``t`` and on a track.
    t, t_check : float
        Now and when the loop checks ``i`` next (its next move epoch), ``t_check > t``.
        ``t`` is one of its move epochs or, when the robot has just replanned, any instant
        between two: the artefact goes on from its pose at ``t`` (a new epoch of its
        track) and its epochs before ``t`` are kept.
    robot_xy : (2,) float
        The robot's centre now.
    robot_track : ((r,) float, (r, 2) float), optional
        Where the robot will be: times (increasing, from ``t``) and centres along its
        current plan (it stands at the last one after); default: it stands at
        ``robot_xy``. The footprint the artefact avoids is the robot's at each instant.
    clearance : float
        Robot radius plus the safety margin (m).
    grid : OccupancyGrid
        The real map M_2D.
    wall_distance : (H, W) float
        ``grid.distance_to_occupied()`` (computed once per mission).
    lookahead : int
        How many of its track epochs past the conflict the artefact may rejoin at, and how
        many epochs longer than its track a detour may take.
    ds : float, optional
        Spacing of the motion samples (m); default the smaller of the grid's resolution and
        a quarter of ``clearance``.
    give_way : float, optional
        The artefact has waited for a standing robot long enough (the loop's patience):
        with no detour it steps back until its box is this far from the robot's centre (m,
        more than ``clearance``) instead of waiting (kind ``"give_way"``); it waits when
        no such spot is clear. Default: it waits.
    give_way_stay : float
        Seconds past ``t_check`` the artefact that gave way stands at its spot (s).

    Returns
    -------
    Avoidance or None
        ``None`` when the motion keeps clear of the robot (nothing to do).
    """
    res = float(grid.resolution)
    ds = min(res, clearance / 4.0) if ds is None else float(ds)
    q = np.asarray(robot_xy, float)
    rt, rxy = (np.array([t]), q[None]) if robot_track is None else robot_track
    rt, rxy = np.asarray(rt, float), np.asarray(rxy, float).reshape(-1, 2)
    half = scene.half_extents[i, :2]
    # far away: its box cannot reach the robot's discs by t_check, whatever its path
    tt, pp = scene.track(i)
    v = np.linalg.norm(np.diff(pp[:, :2], axis=0), axis=1) / np.maximum(np.diff(tt), 1e-12)
    reach = (float(v.max()) if v.size else 0.0) * (t_check - t)
    r_art = float(np.hypot(*scene.offsets[i, :2]) + np.hypot(*half))
    reach += _speed(rt, rxy) * (t_check - t)  # the robot comes at most this close
    if np.linalg.norm(scene.poses(t, [i])[0, :2] - q) - r_art - reach > clearance:
        return None
    times, pose, centres = _sample(scene, i, t, t_check, ds, _speed(rt, rxy))
    bad = _closing(times, centres, pose[:, 2], half, rt, rxy, clearance)
    if not bad.any():
        return None
    j0 = int(np.argmax(bad))
    past = tt < t
    head_t, head_p = np.r_[tt[past], t], np.vstack([pp[past], pose[0]])
    got = _detour(
        scene,
        i,
        t,
        times[j0],
        q,
        clearance,
        grid,
        wall_distance,
        lookahead,
        ds,
        head_t,
        head_p,
        (rt, rxy),
    )
    if got is not None:
        return got
    if give_way is not None:
        got = _step_back(
            scene, i, t, t_check, q, float(give_way), float(give_way_stay), grid, ds, head_t, head_p
        )
        if got is not None:
            return got
    # wait on the track just short of the conflict, until the next check
    t_stop, p_stop = times[j0 - 1], pose[j0 - 1]
    mid, later = (tt > t) & (tt < t_stop), tt > t_stop
    delay = float(t_check - t_stop)
    stop_t = [t_stop] if t_stop > t else []
    stop_p = p_stop[None] if t_stop > t else np.zeros((0, 3))
    new_t = [head_t, tt[mid], stop_t, [t_check], tt[later] + delay]
    new_p = [head_p, pp[mid], stop_p, p_stop[None], pp[later]]
    return Avoidance("yield", np.concatenate(new_t), np.vstack(new_p), delay)


def _robot_at(rt: np.ndarray, rxy: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The robot's centres (k, 2) at ``times``, along its track (standing after its end)."""
    return np.column_stack([np.interp(times, rt, rxy[:, 0]), np.interp(times, rt, rxy[:, 1])])


def _closing(
    times: np.ndarray,
    centres: np.ndarray,
    yaws: np.ndarray,
    half: np.ndarray,
    rt: np.ndarray,
    rxy: np.ndarray,
    clearance: float,
) -> np.ndarray:
    """(k,) bool: samples where the box is within ``clearance`` of the robot's centre then,
    and closer than it would be had it stood at its first sample (its own motion closed the
    gap: a robot driving at a standing artefact is the robot's doing)."""
    r = _robot_at(rt, rxy, times)
    d = point_box_distance(r, centres, half, yaws)
    stay = point_box_distance(
        r, np.broadcast_to(centres[0], r.shape), half, np.full(len(r), yaws[0])
    )
    bad = (d < clearance) & (d < stay - 1e-9)
    bad[0] = False
    return bad


def _detour(
    scene: Scene,
    i: int,
    t: float,
    t_bad: float,
    q: np.ndarray,
    clearance: float,
    grid: OccupancyGrid,
    wall_distance: np.ndarray,
    lookahead: int,
    ds: float,
    head_t: np.ndarray,
    head_p: np.ndarray,
    robot: tuple[np.ndarray, np.ndarray],
) -> Avoidance | None:
    """A detour rejoining the track at one of its next ``lookahead`` epochs past ``t_bad``."""
    tt, pp = scene.track(i)
    res = float(grid.resolution)
    half = scene.half_extents[i]
    r_art = float(np.hypot(*scene.offsets[i, :2]) + np.hypot(*half[:2]))
    k_first = int(np.searchsorted(tt, t_bad, side="left"))
    cand = np.arange(k_first, min(k_first + lookahead, tt.size))
    cand_c = _centres(scene, i, pp[cand]) if cand.size else np.zeros((0, 2))
    far = point_box_distance(q, cand_c, np.tile(half[:2], (cand.size, 1)), pp[cand, 2])
    cand = cand[far >= clearance]
    if not cand.size:
        return None
    p_t = head_p[-1, :2]
    dt = float(np.median(np.diff(tt))) if tt.size > 1 else 1.0
    # a window of the map around the artefact and the epochs it may rejoin at
    reach = float(np.linalg.norm(pp[cand, :2] - p_t, axis=1).max()) + 2 * (clearance + r_art)
    corners = p_t + reach * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    cells = grid.world_to_cell(corners)
    lo = np.clip(cells.min(axis=0), 0, [grid.height - 1, grid.width - 1])
    hi = np.clip(cells.max(axis=0) + 1, 1, [grid.height, grid.width])
    win = (slice(int(lo[0]), int(hi[0])), slice(int(lo[1]), int(hi[1])))
    # the search runs on cells where the box's inscribed disc clears the walls; the exact
    # box-vs-wall-cells test of every sample below makes the decision
    r_in = float(np.hypot(*scene.offsets[i, :2]) + half[:2].min())
    ok = grid.free[win] & (wall_distance[win] > r_in + res * np.sqrt(0.5))
    # the robot's disc now and along its plan until the latest rejoin time
    rt, rxy = robot
    horizon = float(tt[cand].max() - t) + lookahead * dt
    n_r = int(np.ceil(horizon * _speed(rt, rxy) / res)) + 2
    sweep = _robot_at(rt, rxy, t + horizon * np.linspace(0.0, 1.0, n_r))
    gone = np.linalg.norm(sweep - p_t, axis=1)
    keep_out = np.minimum(clearance + r_art, gone - res)
    # lazy: SciPy's ndimage adds 0.15 s CPU to `import are_stats.experiments`
    from scipy import ndimage

    # cells within keep_out of a sweep point (their centres; a ball of radius 0 holds a
    # centre it is on)
    flat = ok.reshape(-1)
    cells, ball, xy = _cells_near(grid, lo, ok.shape, sweep, np.maximum(keep_out, 0.0))
    d2 = _sq_distance(xy, sweep[ball])
    flat[cells[d2 <= np.maximum(keep_out, 0.0)[ball] ** 2]] = False
    alive = scene.alive(t)
    alive[i] = False
    others = np.flatnonzero(alive)
    p_o = scene.poses(t, others)
    c_o = _centres(scene, others, p_o)
    r_o = np.hypot(*scene.half_extents[others, :2].T)
    near = np.linalg.norm(c_o - p_t, axis=1) <= reach * np.sqrt(2.0) + r_o + r_art + res
    # cells within r_art (plus half a cell diagonal) of a near box are blocked: only those
    # within that of the box's circumscribed disc can be (the cells near it, tested exactly)
    thr = r_art + res * np.sqrt(0.5)
    js = others[near]
    if js.size:
        hj = scene.half_extents[js, :2]
        reach_j = np.hypot(hj[:, 0], hj[:, 1]) + thr + 1e-9
        cells, box, xy = _cells_near(grid, lo, ok.shape, c_o[near], reach_j)
        yj = p_o[near, 2]
        gap = point_box_distance(xy, c_o[near][box], hj[box], yj[box])
        flat[cells[gap <= thr]] = False
    start = tuple(int(v) for v in grid.world_to_cell(p_t) - lo)
    if not (0 <= start[0] < ok.shape[0] and 0 <= start[1] < ok.shape[1]):
        return None
    ok[start] = True  # where the artefact stands now
    # the search moves diagonally only between two free orthogonal neighbours, so it
    # reaches exactly the 4-connected part of ok around the start: a goal outside it is
    # refused before a search that would visit all of that part in vain
    part, _ = ndimage.label(ok)
    for k in cand:
        goal = tuple(int(v) for v in grid.world_to_cell(pp[k, :2]) - lo)
        if not (0 <= goal[0] < ok.shape[0] and 0 <= goal[1] < ok.shape[1]) or not ok[goal]:
            continue
        if part[goal] != part[start]:
            continue
        # the track's speed to the epoch, and the refusals that need no search: no speed,
        # or a straight line to the epoch already longer than the time the detour may take
        # (the string-pulled path is no shorter than it; 1e-9 for rounding)
        orig = np.vstack([p_t, pp[int(np.searchsorted(tt, t, "right")) : k + 1, :2]])
        v = float(np.linalg.norm(np.diff(orig, axis=0), axis=1).sum()) / max(tt[k] - t, 1e-9)
        if v <= 0.0:
            continue
        straight = float(np.linalg.norm(pp[k, :2] - p_t)) * (1.0 - 1e-9)
        if max(straight / v, float(tt[k] - t)) > float(tt[k] - t) + lookahead * dt:
            continue
        path = astar_cells(ok, start, goal)
        if path is None:
            continue
        # from where it is to the epoch's pose through the path's inner cells (between
        # epochs, it may stand in the cell of the epoch it rejoins at: a one-cell path)
        pts = np.vstack([p_t, grid.cell_to_world(path[1:-1] + lo), pp[k, :2]])
        pts = _string_pull(pts, ok, grid, lo)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        length = float(seg.sum())
        dur = max(length / v, float(tt[k] - t))
        if dur > float(tt[k] - t) + lookahead * dt:
            continue
        # pieces of at most one epoch's travel, walked at the track's speed
        way = [pts[0]]
        for a, b, ln in zip(pts[:-1], pts[1:], seg, strict=True):
            n = max(int(np.ceil(ln / max(v * dt, 1e-9))), 1)
            way.extend(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
        way = np.array(way)
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(way, axis=0), axis=1))]
        heading = np.arctan2(*(np.diff(way, axis=0)[:, ::-1].T))
        frac = arc[1:] / length if length > 1e-12 else np.arange(1, arc.size) / (arc.size - 1)
        w_t = t + dur * frac
        w_p = np.column_stack([way[1:], heading])
        w_p[-1, 2] = pp[k, 2]
        delay = float(t + dur - tt[k])
        new_t = np.concatenate([head_t, w_t, tt[k + 1 :] + delay])
        new_p = np.vstack([head_p, w_p, pp[k + 1 :]])
        # against the robot: samples at most ds apart relative to it (vectorised); against
        # the walls and the others: at most ds apart along the detour (the new track is
        # sampled as the scene with it would, and the others' tracks are this scene's:
        # no new scene, which rebuilds every artefact's track, per trial)
        trial = (new_t, new_p)
        near = _sample(scene, i, t, t + dur, ds, _speed(rt, rxy), track=trial)
        if _closing(near[0], near[2], near[1][:, 2], half[:2], rt, rxy, clearance).any():
            continue
        times, pose, centres = _sample(scene, i, t, t + dur, ds, track=trial)
        if not _clear_of_walls(grid, centres, half[:2] + ds, pose[:, 2]):
            continue
        if not _clear_of_others(scene, i, times, pose, centres):
            continue
        return Avoidance("detour", new_t, new_p, delay)
    return None


#: Directions the artefact may step back along (rad) off the one straight away from the
#: robot, tried in this order for each distance.
_STEP_BACK_TURNS = np.deg2rad([0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0])


def _step_back(
    scene: Scene,
    i: int,
    t: float,
    t_check: float,
    q: np.ndarray,
    gap: float,
    stay: float,
    grid: OccupancyGrid,
    ds: float,
    head_t: np.ndarray,
    head_p: np.ndarray,
) -> Avoidance | None:
    """The artefact steps back from a standing robot at ``q`` until its box is ``gap`` from
    it, stays there until ``stay`` seconds past ``t_check``, walks back and goes on
    (``plan_avoidance``'s give way); ``None`` when no spot within ``gap`` plus a metre past
    the box is clear.

    Its walk to the spot and its stay there up to ``t_check`` are tested, as a detour's
    motion is, against the walls and the other artefacts' boxes; past ``t_check`` the
    others' tracks are those of their own next checks, which the loop decides again (a
    person ringing the robot with it walks on through the robot's position there), so
    the stay is tested against the walls only (it stands where its walk ended)."""
    tt, pp = scene.track(i)
    v = np.linalg.norm(np.diff(pp[:, :2], axis=0), axis=1) / np.maximum(np.diff(tt), 1e-12)
    v = v[v > 1e-9]
    if not v.size:
        return None
    v = float(np.median(v))
    half = scene.half_extents[i, :2]
    p0 = head_p[-1]
    r_art = float(np.hypot(*scene.offsets[i, :2]) + np.hypot(*half))
    away = _centres(scene, i, p0[None])[0] - q
    phi = float(np.arctan2(away[1], away[0])) if np.hypot(*away) > 1e-9 else p0[2]
    # the distance each direction needs: the first of steps ds apart that is far enough
    steps = ds * np.arange(1, int(np.ceil((gap + r_art + 1.0) / ds)) + 1)
    found = []
    for turn in _STEP_BACK_TURNS:
        u = np.array([np.cos(phi + turn), np.sin(phi + turn)])
        spots = np.column_stack([p0[:2] + steps[:, None] * u, np.full(steps.size, p0[2])])
        d = point_box_distance(q, _centres(scene, i, spots), half, spots[:, 2])
        far = np.flatnonzero(d >= gap)
        if far.size:
            found.append((float(steps[far[0]]), spots[far[0]]))
    for r, spot in sorted(found, key=lambda f: f[0]):  # nearest first (stable: turns' order)
        t_spot = t + r / v
        t_hold = max(float(t_check), t_spot) + stay
        later = tt > t
        delay = t_hold + r / v - t
        new_t = np.concatenate([head_t, [t_spot, t_hold, t_hold + r / v], tt[later] + delay])
        new_p = np.vstack([head_p, spot[None], spot[None], p0[None], pp[later]])
        t_end = max(float(t_check), t_spot)
        times, pose, centres = _sample(scene, i, t, t_end, ds, track=(new_t, new_p))
        if not _clear_of_walls(grid, centres, half + ds, pose[:, 2]):
            continue
        if not _clear_of_others(scene, i, times, pose, centres):
            continue
        return Avoidance("give_way", new_t, new_p, float(delay))
    return None


def _speed(rt: np.ndarray, rxy: np.ndarray) -> float:
    """The robot's fastest speed along its track (0 standing)."""
    if rt.size < 2:
        return 0.0
    return float(
        (np.linalg.norm(np.diff(rxy, axis=0), axis=1) / np.maximum(np.diff(rt), 1e-12)).max()
    )


def _clear_of_walls(
    grid: OccupancyGrid, centres: np.ndarray, half: np.ndarray, yaws: np.ndarray
) -> bool:
    """Whether boxes (k of them, half sizes ``half`` (2,)) share no area with a cell of
    ``grid`` that is not free (an exact separating-axis test against the cells' squares).

    Each box is tested against the non-free cells of the square window of cells around it
    (its circumscribed radius plus a cell); the windows of all k boxes are gathered and
    tested in one pass.
    """
    centres = np.asarray(centres, float).reshape(-1, 2)
    yaws = np.asarray(yaws, float).reshape(-1)
    k = len(centres)
    if not k:
        return True
    res = float(grid.resolution)
    r = float(np.hypot(*half)) + res
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * r
    cells = grid.world_to_cell((centres[:, None, :] + square[None]).reshape(-1, 2))
    cells = cells.reshape(k, 4, 2)
    shape = np.array([grid.height, grid.width])
    lo = np.clip(cells.min(axis=1), 0, shape)  # (k, 2) each box's window [lo, hi)
    size = np.clip(cells.max(axis=1) + 1, 0, shape) - lo
    s0, s1 = (int(v) for v in size.max(axis=0))
    if s0 <= 0 or s1 <= 0:
        return True
    off = np.indices((s0, s1)).reshape(2, -1).T  # (S, 2)
    box, o = np.nonzero((off[None] < size[:, None, :]).all(axis=2))  # (box, offset) pairs
    ij = lo[box] + off[o]
    wall = ~grid.free[ij[:, 0], ij[:, 1]]
    box, ij = box[wall], ij[wall]
    n = box.size
    if not n:
        return True
    hit = obb_overlap_2d(
        centres[box],
        np.tile(half, (n, 1)),
        yaws[box],
        grid.cell_to_world(ij),
        np.full((n, 2), res / 2.0),
        np.full(n, float(grid.origin[2])),
    )
    return not hit.any()


def _cells_near(
    grid: OccupancyGrid,
    lo: np.ndarray,
    shape: tuple[int, int],
    centres: np.ndarray,
    radii: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells of the window ``shape`` at ``lo`` (rows, cols) whose centres may lie within
    ``radii`` (m,) of ``centres`` (m, 2): a superset (each disc's square of cells, a cell
    wider); flat window indices (n,), which disc (n,), and the cells' centres (n, 2) as
    :meth:`~are_stats.environment.OccupancyGrid.cell_to_world` gives them."""
    if not len(centres):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2))
    uv = grid.world_to_local(centres)  # (m, 2) u along columns, v along rows (cell units)
    r = np.asarray(radii, float) / grid.resolution
    first = np.floor(uv[:, ::-1] - r[:, None]).astype(np.int64) - 1  # (m, 2) rows, cols
    size = int(np.ceil(2.0 * r.max())) + 4
    off = np.indices((size, size)).reshape(2, -1).T
    ij = first[:, None, :] + off[None] - lo  # (m, S, 2) window cells
    ok = (ij >= 0).all(axis=2) & (ij < shape).all(axis=2)
    disc, k = np.nonzero(ok)
    ij = ij[disc, k]
    return ij[:, 0] * shape[1] + ij[:, 1], disc, grid.cell_to_world(ij + lo)


def _sq_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) squared distances between points ``a`` and ``b`` (n, 2), summed as a k-d tree
    sums them (x first)."""
    d = a - b
    s = np.zeros(len(d))
    s += d[:, 0] * d[:, 0]
    s += d[:, 1] * d[:, 1]
    return s


#: Chords tested in the first batch from a vertex (:func:`_string_pull`); a batch that finds
#: none clear is followed by one twice as large.
_PULL_BATCH = 8


def _string_pull(
    pts: np.ndarray, ok: np.ndarray, grid: OccupancyGrid, lo: np.ndarray
) -> np.ndarray:
    """Drop the path's vertices that a straight chord on ``ok`` cells can skip: from each
    kept vertex, on to the farthest vertex it sees (chords sampled every quarter cell).

    Each chord is sampled as ``np.linspace(0, 1, k)`` along it, ``k`` from its length
    (:func:`_chord_counts`), and the chords from a vertex are tested from the farthest
    vertex back, in batches of ``_PULL_BATCH``, twice that... (one grid transform of a
    batch's samples), until one is clear: the same vertices as testing every chord one at a time.
    """
    step = grid.resolution / 4.0
    out, a = [pts[0]], 0
    while a < len(pts) - 1:
        b, hi, batch = a + 1, len(pts), _PULL_BATCH
        while hi > a + 2:
            js = np.arange(max(a + 2, hi - batch), hi)
            seen = _chords_clear(pts[a], pts[js] - pts[a], ok, grid, lo, step)
            if seen.any():
                b = int(js[np.flatnonzero(seen)[-1]])
                break
            hi, batch = js[0], 2 * batch
        out.append(pts[b])
        a = b
    return np.array(out)


def _chords_clear(
    p: np.ndarray, d: np.ndarray, ok: np.ndarray, grid: OccupancyGrid, lo: np.ndarray, step: float
) -> np.ndarray:
    """(m,) bool: whether the chords from ``p`` (2,) along ``d`` (m, 2), sampled every
    ``step`` at most, stay on ``ok`` cells (the window at ``lo``)."""
    n = _chord_counts(d, step)
    first = np.r_[0, np.cumsum(n)[:-1]]
    which = np.repeat(np.arange(n.size), n)
    i = np.arange(which.size) - first[which]  # sample index along its chord
    div = (n - 1)[which]
    # np.linspace(0, 1, k): i * (1 / (k - 1)), the last sample exactly 1
    frac = i * (1.0 / np.maximum(div, 1))
    frac[i == div] = 1.0
    frac[div == 0] = 0.0
    x, y = p[0] + d[which, 0] * frac, p[1] + d[which, 1] * frac
    x0, y0, yaw = (float(v) for v in grid.origin)
    if yaw == 0.0:  # world_to_cell unrotated: u = (x - x0) / res exactly (1 dx + 0 dy)
        res = float(grid.resolution)
        r = np.floor((y - y0) / res).astype(np.int64) - lo[0]
        c = np.floor((x - x0) / res).astype(np.int64) - lo[1]
    else:
        ij = grid.world_to_cell(np.column_stack([x, y])) - lo
        r, c = ij[:, 0], ij[:, 1]
    inside = (r >= 0) & (r < ok.shape[0]) & (c >= 0) & (c < ok.shape[1])
    clear = np.zeros(r.size, bool)
    clear[inside] = ok[r[inside], c[inside]]
    return np.logical_and.reduceat(clear, first)


def _chord_counts(d: np.ndarray, step: float) -> np.ndarray:
    """(m,) samples ``ceil(|d| / step) + 1`` of chords ``d`` (m, 2), with ``|d|`` as
    ``np.linalg.norm`` of each chord computes it (a dot product): one vectorised pass, and
    that norm again only where the two could round to different counts (a chord a whole
    number of steps long, which cell-centred paths often have)."""
    q = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) / step
    near = np.abs(q - np.round(q)) <= 1e-9 * np.maximum(q, 1.0)
    for j in np.flatnonzero(near):
        q[j] = np.linalg.norm(d[j]) / step
    return np.ceil(q).astype(np.int64) + 1
