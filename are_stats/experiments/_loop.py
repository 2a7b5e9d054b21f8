"""The navigation experiment loop (paper Sect. 4): a robot drives to a sequence of goals on
the augmented map of one scenario, replanning at every scene update.

The loop is event-driven on simulated time:

* **scene updates** are artefact arrivals and leaves of the scenario table (artefacts stand
  at their arrival pose until they leave) and, with ``perception="camera"``, changes of the
  perceived set A_f checked every ``perception_period`` seconds of driving;
* at each update (and when a new goal becomes current) the planner replans from the robot's
  position to the current goal on the augmented grid that holds **only the perceived
  artefacts**, inflated by the robot radius plus half a cell diagonal (cells around the
  robot's own position that are inflated but not occupied are released, so a robot
  brushing an obstacle can still leave);
* between updates the robot moves along its path at its speed; its footprint is tested
  against every live artefact (perceived or not) and each new contact made while driving
  counts as a collision (an artefact that *arrives* on the robot's footprint is counted
  apart, as an arrival contact); when the plan fails the robot waits for the next update.

The replanning time ``rho_t`` is measured on the wall clock (DECISIONS 10) and recorded, but
it does not advance simulated time, so everything except ``rho_t`` and ``rho`` is
deterministic given the seed (for OMPL planners: given the seed and an iteration budget).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from are_stats._checks import check_finite, check_in, check_nonnegative, check_positive
from are_stats.experiments._metrics import replanning_ratio, time_average
from are_stats.experiments._planners import make_planner, timed_plan
from are_stats.experiments._robot import Robot, circle_box_overlap
from are_stats.inputs import check_memory, check_work

__all__ = ["MissionResult", "MissionTrace", "random_goals", "run_mission"]


class MissionTrace(NamedTuple):
    """What happened, for replay and export (see :func:`are_stats.experiments.export_mcap`).

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
    """

    poses: np.ndarray
    plans: list
    scenes: list
    goals: np.ndarray


class MissionResult(NamedTuple):
    """Outcome of :func:`run_mission`.

    Attributes
    ----------
    summary : dict
        ``goals_total``, ``goals_reached``, ``mission_time`` (s: when the last goal was
        reached, else the time limit), ``time_per_goal`` (s, mean over reached goals),
        ``collisions`` (contacts the robot drove into), ``arrival_contacts`` (artefacts
        that appeared on the robot's footprint), ``n_replans``, ``n_failed_plans``,
        ``n_updates``,
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


def random_goals(grid: Any, n: int, radius: float, seed: int, min_separation: float = 2.0):
    """``(n, 2)`` goal positions drawn uniformly over the free cells of ``grid`` inflated by
    ``radius``, each at least ``min_separation`` metres from the previous goal (cell centres).
    """
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


@dataclass
class _Scene:
    """Artefact boxes of one scenario (static at their arrival pose)."""

    ids: np.ndarray
    labels: list
    t_arrive: np.ndarray
    t_leave: np.ndarray
    centres: np.ndarray  # (n, 3)
    half: np.ndarray  # (n, 3)
    yaws: np.ndarray
    live: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    seen: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def _scene(artefacts: pd.DataFrame, catalogue: Any) -> _Scene:
    need = ["t_arrive", "t_leave", "x", "y", "yaw"]
    if not isinstance(artefacts, pd.DataFrame):
        raise ValueError(f"artefacts: expected a DataFrame, got {type(artefacts).__name__}")
    missing = [c for c in need if c not in artefacts.columns]
    if missing:
        raise ValueError(f"artefacts: expected columns {need}, missing {missing}")
    if "scenario" in artefacts.columns and artefacts["scenario"].nunique() > 1:
        raise ValueError("artefacts: expected one scenario, got several (filter by 'scenario')")
    num = check_finite("artefacts", artefacts[need].to_numpy(float), ndim=2)
    n = len(artefacts)
    marks = artefacts["mark"].to_numpy() if "mark" in artefacts.columns else np.zeros(n, int)
    classes = artefacts["class"].to_numpy() if "class" in artefacts.columns else np.zeros(n, int)
    labels, half, off = [], np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(n):
        # DECISIONS 5: the component is the class, the mark selects the class's row of Q
        c = int(np.clip(int(classes[k]), 0, len(catalogue) - 1))
        row = catalogue.select(c, max(int(marks[k]), 0))
        labels.append(row.label)
        half[k] = row.half_extents
        off[k] = (row.bounds[0] + row.bounds[1]) / 2.0
    ta, tl, x, y, yaw = num.T
    c, s = np.cos(yaw), np.sin(yaw)
    centres = np.column_stack(
        [x + c * off[:, 0] - s * off[:, 1], y + s * off[:, 0] + c * off[:, 1], off[:, 2]]
    )
    ids = (
        artefacts["artefact"].to_numpy(np.int64)
        if "artefact" in artefacts.columns
        else np.arange(n, dtype=np.int64)
    )
    return _Scene(ids, labels, ta, tl, centres, half, yaw, np.zeros(n, bool), np.zeros(n, bool))


def _arc(path: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]


def _point_at(path: np.ndarray, cum: np.ndarray, s: Any) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(m, 2)`` and headings ``(m,)`` at arc lengths ``s``."""
    s = np.clip(np.atleast_1d(np.asarray(s, float)), 0.0, cum[-1])
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2)
    seg = path[k + 1] - path[k]
    ln = np.maximum(cum[k + 1] - cum[k], 1e-12)
    f = ((s - cum[k]) / ln)[:, None]
    return path[k] + f * seg, np.arctan2(seg[:, 1], seg[:, 0])


def run_mission(
    grid: Any,
    artefacts: pd.DataFrame,
    goals: Any,
    planner: Mapping[str, Any] | Callable[..., Any] = "astar",  # type: ignore[assignment]
    *,
    robot: Robot | None = None,
    start: Any = None,
    catalogue: Any = None,
    time_limit: float = 300.0,
    perception: str = "all",
    env_mesh: Any = None,
    perception_period: float = 1.0,
    d_max: float = 10.0,
    tau: float = 10.0,
    perception_memory: bool = True,
    seed: int = 0,
    record: bool = False,
) -> MissionResult:
    """Drive a robot through ``goals`` on the augmented map of one scenario (Sect. 4).

    Parameters
    ----------
    grid : OccupancyGrid
        The real map M_2D.
    artefacts : pandas.DataFrame
        One scenario of :func:`are_stats.scenarios.generate_scenarios` (columns
        ``t_arrive, t_leave, x, y, yaw`` and ``mark`` or ``class``).
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
    catalogue : ArtefactCatalogue, optional
        Box sizes by mark (default :func:`~are_stats.environment.load_catalogue`).
    time_limit : float
        Mission time limit (s).
    perception : {"all", "camera"}
        ``"all"``: every live artefact is perceived; ``"camera"``: A_f of the robot's camera
        (Sect. 3.3, :func:`~are_stats.perception.perceived_counts`) against ``env_mesh``.
    env_mesh : trimesh.Trimesh, optional
        Environment mesh S_3D (required for ``"camera"``).
    perception_period : float
        Seconds of driving between perception checks (``"camera"``).
    d_max, tau : float
        Range and occlusion threshold of A_f.
    perception_memory : bool
        Keep an artefact on the planner's map once perceived, until it leaves.
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
    from are_stats.environment import OccupancyGrid, load_catalogue
    from are_stats.perception import perceived_grid

    if not isinstance(grid, OccupancyGrid):
        raise ValueError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    robot = Robot() if robot is None else robot
    if not isinstance(robot, Robot):
        raise ValueError(f"robot: expected a Robot, got {type(robot).__name__}")
    catalogue = load_catalogue() if catalogue is None else catalogue
    plan_fn = make_planner({"algorithm": "astar"} if planner == "astar" else planner)
    perception = check_in("perception", perception, ("all", "camera"))
    if perception == "camera" and env_mesh is None:
        raise ValueError("env_mesh: perception='camera' needs the environment mesh S_3D")
    T = float(check_positive("time_limit", time_limit))
    period = float(check_positive("perception_period", perception_period))
    d_max = float(check_positive("d_max", d_max))
    tau = float(check_nonnegative("tau", tau))
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
    scene = _scene(artefacts, catalogue)
    res = grid.resolution
    n_free = grid.n_free
    if n_free == 0:
        raise ValueError("grid: expected free cells, got none")
    from are_stats.builder import ARBuilder

    builder = ARBuilder(grid, catalogue)

    # ----------------------------------------------------------------- scene helpers
    def set_live(t: float) -> None:
        scene.live = (scene.t_arrive <= t) & (scene.t_leave > t)
        scene.seen &= scene.live
        builder.reset()
        for k in np.flatnonzero(scene.live):
            c = scene.centres[k]
            builder.register(None, [c[0], c[1], scene.yaws[k]], size=2 * scene.half[k], check=False)

    def perceive(p: np.ndarray) -> np.ndarray:
        live = np.flatnonzero(scene.live)
        now = np.zeros(scene.live.size, bool)
        if perception == "all":
            now[live] = True
        elif live.size:
            from are_stats.perception import perceived_counts, yaw_rotations

            cam = robot.camera(p)
            _, seen = perceived_counts(
                env_mesh, scene.centres[live], scene.half[live],
                yaw_rotations(scene.yaws[live]), cam, d_max, tau,
            )  # fmt: skip
            now[live] = seen
        return (now | scene.seen) if perception_memory else now

    def planning_grid(p: np.ndarray) -> tuple[Any, np.ndarray]:
        idx = np.flatnonzero(scene.seen)
        aug = perceived_grid(
            grid, scene.centres[idx], scene.half[idx], scene.yaws[idx], np.ones(idx.size, bool)
        )
        from scipy import ndimage

        occ = ~aug.free
        dist = (
            ndimage.distance_transform_edt(~occ) * res if occ.any() else np.full(occ.shape, np.inf)
        )
        # cell-centre distances: add half a cell diagonal so the disc clears box edges
        free = (dist > robot.radius + res * np.sqrt(0.5)) & ~occ
        ij = np.indices(occ.shape).reshape(2, -1).T
        near = np.linalg.norm(grid.cell_to_world(ij) - p[:2], axis=1).reshape(occ.shape)
        free |= (near <= robot.radius + res) & ~occ
        return aug, free

    # ----------------------------------------------------------------- state
    t = 0.0
    set_live(t)
    scene.seen = perceive(pose)
    in_contact = np.zeros(scene.live.size, bool)
    collisions = 0
    arrival_contacts = 0
    distance = 0.0
    events = np.unique(np.r_[scene.t_arrive, scene.t_leave])
    events = events[(events > 0) & (events < T)]
    ev_i = 0
    next_percept = period if perception == "camera" else np.inf
    goal_i = 0
    reached = np.full(G.shape[0], np.nan)
    path: np.ndarray | None = None
    cum = np.zeros(1)
    s_along = 0.0
    need_plan, reason = True, "goal"
    replans: list[dict] = []
    timeline: list[dict] = []
    poses_log: list[list[float]] = [[0.0, *pose]]
    plans_log: list = []
    scenes_log: list = []
    n_updates = 0
    step = min(res, robot.radius / 2.0)
    # refuse before looping: footprint tests along the path, and grid passes per replan
    n_motion = robot.speed * T / step + 1.0
    n_plans = events.size + G.shape[0] + (T / period if perception == "camera" else 0.0) + 1.0
    check_memory(n_motion * 64.0, f"the robot's {n_motion:.3g} motion steps", "run_mission")
    check_work(
        n_motion * 200.0 + n_plans * (grid.data.size * 100.0 + scene.live.size * 3000.0),
        f"{n_plans:.3g} replans on {grid.data.size} cells and {n_motion:.3g} motion steps",
        "run_mission",
    )

    def log_scene(kind: str, aug: Any = None) -> None:
        n_a = builder.n_artefact_cells
        timeline.append(
            {"t": t, "kind": kind, "n_live": int(scene.live.sum()),
             "n_perceived": int(scene.seen.sum()), "n_A": n_a, "nu": n_a / n_free}
        )  # fmt: skip
        if record:
            idx = np.flatnonzero(scene.live)
            scenes_log.append(
                {"t": t, "ids": scene.ids[idx], "centres": scene.centres[idx],
                 "half": scene.half[idx], "yaws": scene.yaws[idx],
                 "labels": [scene.labels[k] for k in idx], "perceived": scene.seen[idx],
                 "grid": aug if aug is not None else planning_grid(pose)[0]}
            )  # fmt: skip

    def check_contacts(pts: np.ndarray, moving: bool = True) -> None:
        nonlocal collisions, arrival_contacts, in_contact
        idx = np.flatnonzero(scene.live)
        for q in pts:
            now = np.zeros(scene.live.size, bool)
            if idx.size:
                now[idx] = circle_box_overlap(
                    q, robot.radius, scene.centres[idx, :2], scene.half[idx, :2], scene.yaws[idx]
                )
            new = int((now & ~in_contact).sum())
            if moving:
                collisions += new
            else:
                arrival_contacts += new
            in_contact = now

    def move_to(s_new: float, t_new: float) -> None:
        nonlocal s_along, distance, pose
        assert path is not None
        ds = s_new - s_along
        m = max(int(np.ceil(ds / step)), 1)
        ss = s_along + ds * np.arange(1, m + 1) / m
        pts, hd = _point_at(path, cum, ss)
        check_contacts(pts)
        distance += ds
        s_along = s_new
        pose = np.array([pts[-1, 0], pts[-1, 1], hd[-1]])
        if record:
            tt = t + (t_new - t) * np.arange(1, m + 1) / m
            poses_log.extend(np.column_stack([tt, pts, hd]).tolist())

    log_scene("start")
    check_contacts(pose[None, :2], moving=False)
    while goal_i < G.shape[0] and t < T:
        if need_plan:
            aug, free = planning_grid(pose)
            start_l = grid.world_to_local(pose[:2]) * res
            goal_l = grid.world_to_local(G[goal_i]) * res
            params = {"resolution": res, "seed": int(seed) * 100003 + len(replans)}
            p_local, rho_t = timed_plan(plan_fn, free, start_l, goal_l, params)
            if p_local is not None:
                path = grid.local_to_world(p_local / res)
                path[0], path[-1] = pose[:2], G[goal_i]
                cum = _arc(path)
                s_along = 0.0
                g_t = cum[-1] / robot.speed
                if record:
                    plans_log.append((t, path.copy()))
            else:
                path, g_t = None, np.inf
            n_a = builder.n_artefact_cells
            replans.append(
                {"t": t, "goal": goal_i, "reason": reason, "rho_t": rho_t, "g_t": g_t,
                 "rho": float(replanning_ratio([rho_t], [g_t])[0]) if p_local is not None
                 else np.nan, "success": p_local is not None,
                 "path_length": float(cum[-1]) if p_local is not None else np.nan,
                 "n_live": int(scene.live.sum()), "n_perceived": int(scene.seen.sum()),
                 "n_A": n_a, "nu": n_a / n_free}
            )  # fmt: skip
            need_plan = False
        t_event = events[ev_i] if ev_i < events.size else np.inf
        t_next = min(t_event, next_percept, T)
        if path is not None:
            t_goal = t + (cum[-1] - s_along) / robot.speed
            if t_goal <= t_next:
                move_to(cum[-1], t_goal)
                t = t_goal
                reached[goal_i] = t
                goal_i += 1
                path, need_plan, reason = None, True, "goal"
                continue
            move_to(s_along + (t_next - t) * robot.speed, t_next)
        t = t_next
        if t >= T:
            break
        kinds = []
        if t == t_event:
            before = scene.live.copy()
            set_live(t)
            arrived, left = scene.live & ~before, before & ~scene.live
            while ev_i < events.size and events[ev_i] <= t:
                ev_i += 1
            old_seen = scene.seen.copy()
            scene.seen = perceive(pose)
            if arrived.any():
                kinds.append("arrival")
            if left.any():
                kinds.append("leave")
            if not kinds and not np.array_equal(old_seen, scene.seen):
                kinds.append("perceived")
            check_contacts(pose[None, :2], moving=False)
        if t == next_percept:
            next_percept = t + period
            old_seen = scene.seen.copy()
            scene.seen = perceive(pose)
            if not np.array_equal(old_seen, scene.seen) and not kinds:
                kinds.append("perceived")
        if kinds:
            n_updates += 1
            need_plan, reason = True, "+".join(kinds)
            log_scene(reason)

    end = float(t if goal_i == G.shape[0] else T)
    rp = pd.DataFrame(
        replans,
        columns=["t", "goal", "reason", "rho_t", "g_t", "rho", "success", "path_length",
                 "n_live", "n_perceived", "n_A", "nu"],
    )  # fmt: skip
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
        "collisions": int(collisions),
        "arrival_contacts": int(arrival_contacts),
        "n_replans": len(rp),
        "n_failed_plans": int((~rp["success"]).sum()) if len(rp) else 0,
        "n_updates": n_updates,
        "update_rate": n_updates / end if end > 0 else np.nan,
        "rho_mean": float(rp["rho"].mean()) if rp["rho"].notna().any() else np.nan,
        "rho_t_mean": float(rp["rho_t"].mean()) if len(rp) else np.nan,
        "nu_mean": time_average(
            tl["t"].to_numpy(), tl["nu"].to_numpy(), max(end, tl["t"].iloc[-1])
        ),
        "nu_max": float(tl["nu"].max()),
        "distance": float(distance),
    }
    trace = MissionTrace(np.array(poses_log), plans_log, scenes_log, G.copy()) if record else None
    return MissionResult(summary, rp, gl, tl, trace)
