"""Rollouts of MDP policies: sampled trajectories with slip noise and collision resolution.

Artefacts move on a global clock of decision epochs. Artefact ``b`` arrives at epoch
``arrive[b]`` and follows its policy ``pi_t`` (``t = e - arrive[b]``) until its horizon
``d_b``; at each epoch the proposed cells of the artefacts present are passed to a
``resolve(t, proposed, previous)`` callable. The default is the AR-builder's collision step
(Sec. 3.3, DECISIONS.md item 9; :func:`builder_resolver` on the MDP's cells): an artefact
whose move would put it on another's cell goes back to its previous cell, its last safe
pose, and so do two artefacts that would swap cells (pass through each other).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping, Sequence

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_array, check_positive, describe
from are_stats.behaviour._mdp import GridMDP, MDPSolution
from are_stats.behaviour._rewards import FORWARD, LEFT, RIGHT, RUN, follow_rewards
from are_stats.builder import ARBuilder
from are_stats.environment import OccupancyGrid

__all__ = [
    "builder_resolver",
    "cells_to_tracks",
    "rollout",
    "scenario_tracks",
]

Resolver = Callable[[int, np.ndarray, np.ndarray], np.ndarray]
#: A behaviour per class (``{class: behaviour}``) or per artefact row (``f(row)``).
BehaviourOf = Mapping[Hashable, str] | Callable[[pd.Series], str]

#: ``resolve=BUILDER`` (the default of :func:`rollout` and :func:`scenario_tracks`): the
#: AR-builder's resolution (:func:`builder_resolver`) on the MDP's own cells.
BUILDER = "builder"


def builder_resolver(
    builder: ARBuilder, size: npt.ArrayLike | None = None, label: str | None = None
) -> Resolver:
    """Collision resolution by the AR-builder (Sec. 3.3) as a :func:`rollout` resolver.

    At each epoch the artefacts present are (re-)registered on ``builder`` at their previous
    cells, as boxes of ``size`` (default ``0.9 x 0.9`` cells, 1 m high) or of the catalogue
    class ``label``, and ``builder.step`` moves them to their proposed cells, resolving
    collisions with its rule (revert to the last safe pose, or advance up to a safe
    distance; DECISIONS.md item 9). The resolved poses are mapped back to cells. The
    builder's own log records every resolution.

    Parameters
    ----------
    builder : are_stats.ARBuilder
        A builder on the same grid as the MDP (``builder.grid`` an ``OccupancyGrid``).
    size : (3,) float or None
        Box length, width, height in metres.
    label : str or None
        Catalogue class instead of ``size``.

    Returns
    -------
    callable
        ``resolve(t, proposed (n, 2), previous (n, 2)) -> (n, 2)``.

    Raises
    ------
    ValueError
        If ``builder`` has no ``grid``, ``register``, ``remove`` and ``step``.
    """
    if not all(hasattr(builder, a) for a in ("grid", "register", "remove", "step", "ids")):
        raise ValueError(f"builder: expected an ARBuilder, got {type(builder).__name__}")
    grid = builder.grid
    if label is None and size is None:
        size = (0.9 * grid.resolution, 0.9 * grid.resolution, 1.0)

    def resolve(t: int, proposed: np.ndarray, previous: np.ndarray) -> np.ndarray:
        for aid in list(np.asarray(builder.ids).tolist()):
            builder.remove(aid)
        prev_xy = np.asarray(grid.cell_to_world(np.asarray(previous)), dtype=float)
        for xy in prev_xy:
            builder.register(label, [xy[0], xy[1], 0.0], size=size, check=False)
        prop_xy = np.asarray(grid.cell_to_world(np.asarray(proposed)), dtype=float)
        poses = np.column_stack([prop_xy, np.zeros(len(prop_xy))])
        out = np.asarray(builder.step(poses, time=float(t)))
        return np.asarray(grid.world_to_cell(out[:, :2]), dtype=np.int64)

    return resolve


def _cell_resolver(mdp: GridMDP) -> Resolver:
    """:func:`builder_resolver` on a builder of the MDP's cells (1 m cells at the origin:
    the boxes, 0.9 of a cell, meet exactly when two artefacts share a cell)."""
    grid = OccupancyGrid(np.where(mdp.occupied, 100, 0).astype(np.int8), 1.0)
    return builder_resolver(ARBuilder(grid))


def _groups(solutions: MDPSolution | Sequence[MDPSolution]) -> list[MDPSolution]:
    sols = [solutions] if isinstance(solutions, MDPSolution) else list(solutions)
    if not sols or not all(isinstance(s, MDPSolution) for s in sols):
        raise ValueError(f"solution: expected an MDPSolution or a list of them, got {solutions!r}")
    if any(s.mdp is not sols[0].mdp for s in sols):
        raise ValueError("solution: expected solutions of one GridMDP, got several models")
    return sols


def rollout(
    key: jax.Array,
    solution: MDPSolution | Sequence[MDPSolution],
    starts: npt.ArrayLike,
    n_steps: int | None = None,
    *,
    arrive: npt.ArrayLike | None = None,
    resolve: Resolver | str | None = BUILDER,
) -> np.ndarray:
    """Sample trajectories of a batch of artefacts from their policies (Sec. 3.2).

    Each artefact follows ``pi_t`` of its batch item; move actions slip sideways with
    probability ``slip`` (``slip / 2`` to each side) exactly as in the MDP, and blocked
    outcomes stay. Artefacts present at the same epoch are passed through ``resolve``.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    solution : MDPSolution or list of MDPSolution
        Solved batch(es) of one :class:`GridMDP`; the artefacts are their items in order.
    starts : (B, 3) int
        Start states ``(row, col, heading)`` on free cells.
    n_steps : int or None
        Number of global epochs to simulate (default: enough for every artefact to reach
        its horizon).
    arrive : (B,) int or None
        Arrival epoch of each artefact on the global clock (default 0).
    resolve : callable, "builder" or None
        ``resolve(t, proposed (n, 2), previous (n, 2)) -> (n, 2)`` applied to the cells of
        the artefacts present after each epoch; ``"builder"`` (default): the AR-builder's
        resolution on the MDP's cells (see the module docstring); ``None`` disables
        collision handling.

    Returns
    -------
    states : (B, n_steps + 1, 3) int64
        ``(row, col, heading)`` per artefact and global epoch; ``-1`` where the artefact is
        not present (before arrival or after ``arrive + d_b``).

    Raises
    ------
    ValueError
        On malformed starts (shape, off-grid, obstacle, heading) or arrivals.
    """
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.behaviour`)
    from are_stats.traffic import key_uniform

    sols = _groups(solution)
    mdp = sols[0].mdp
    if isinstance(resolve, str):
        if resolve != BUILDER:
            raise ValueError(f"resolve: expected a callable, {BUILDER!r} or None, got {resolve!r}")
        resolve = _cell_resolver(mdp)
    h_, w_ = mdp.shape
    item_sol = np.concatenate([np.full(len(s.behaviours), g) for g, s in enumerate(sols)])
    item_idx = np.concatenate([np.arange(len(s.behaviours)) for s in sols])
    horizons = np.concatenate([s.horizons for s in sols])
    b = len(item_sol)
    st = check_array("starts", starts, dtype=float)
    if st.shape != (b, 3) or not np.all(st == np.round(st)):
        raise ValueError(f"starts: expected a ({b}, 3) integer array, got {describe(st)}")
    st = st.astype(np.int64)
    inside = (st[:, 0] >= 0) & (st[:, 0] < h_) & (st[:, 1] >= 0) & (st[:, 1] < w_)
    if not inside.all():
        i = int(np.argmin(inside))
        raise ValueError(f"starts[{i}]: expected a cell inside the {h_} x {w_} grid, got {st[i]}")
    blocked = mdp.occupied[st[:, 0], st[:, 1]]
    if blocked.any():
        i = int(np.argmax(blocked))
        raise ValueError(f"starts[{i}]: expected a free cell, got {tuple(st[i, :2])} (obstacle)")
    if ((st[:, 2] < 0) | (st[:, 2] > 3)).any():
        raise ValueError(f"starts: expected headings in 0..3, got {describe(st[:, 2])}")
    arr = np.zeros(b, np.int64) if arrive is None else check_array("arrive", arrive, float)
    if arr.shape != (b,) or (arr < 0).any() or not np.all(arr == np.round(arr)):
        raise ValueError(f"arrive: expected {b} integers >= 0, got {describe(arr)}")
    arr = arr.astype(np.int64)
    leave = arr + horizons
    if n_steps is None:
        n_steps = int(leave.max()) if b else 0
    if int(n_steps) != n_steps or n_steps < 0:
        raise ValueError(f"n_steps: expected an integer >= 0, got {n_steps!r}")
    n_steps = int(n_steps)

    u = key_uniform(key, (max(n_steps, 1), b))
    slip = mdp.slip
    ok = mdp._ok
    drow = np.array([0, 1, 0, -1])
    dcol = np.array([1, 0, -1, 0])

    out = np.full((b, n_steps + 1, 3), -1, dtype=np.int64)
    cur = st.copy()
    present0 = arr == 0
    out[present0, 0] = cur[present0]
    # past the last leaving epoch nobody is present: the rest of ``out`` stays -1 (the
    # uniforms are drawn for every epoch all the same: the draws do not depend on it)
    for e in range(min(n_steps, int(leave.max()) if b else 0)):
        t_local = e - arr
        moving = (t_local >= 0) & (t_local < horizons)
        action = np.zeros(b, np.int64)
        for g, sol in enumerate(sols):
            sel = moving & (item_sol == g)
            if sel.any():
                action[sel] = sol.action(item_idx[sel], t_local[sel], cur[sel])
        nxt = cur.copy()
        is_move = (action == FORWARD) | (action == RUN)
        k = np.where(action == RUN, 2, 1)
        side = np.where(u[e] < 1 - slip, 0, np.where(u[e] < 1 - slip / 2, 1, -1))
        direction = (cur[:, 2] + side) % 4
        free = ok[direction, k - 1, cur[:, 0], cur[:, 1]]
        go = is_move & free
        nxt[go, 0] += k[go] * drow[direction[go]]
        nxt[go, 1] += k[go] * dcol[direction[go]]
        nxt[action == LEFT, 2] = (cur[action == LEFT, 2] + 1) % 4
        nxt[action == RIGHT, 2] = (cur[action == RIGHT, 2] - 1) % 4
        present = (e + 1 >= arr) & (e + 1 <= leave)
        if resolve is not None and present.sum() > 1:
            prev = np.where(moving[present, None], cur[present, :2], nxt[present, :2])
            cells = np.asarray(resolve(e, nxt[present, :2], prev), dtype=np.int64)
            if cells.shape != (int(present.sum()), 2):
                raise ValueError(
                    f"resolve: expected ({int(present.sum())}, 2) cells, got {describe(cells)}"
                )
            nxt[present, :2] = cells
        cur = nxt
        out[present, e + 1] = cur[present]
    return out


def cells_to_tracks(
    states: np.ndarray,
    *,
    scenario: Hashable | npt.ArrayLike = 0,
    ids: npt.ArrayLike | None = None,
    dt: float = 1.0,
    t0: npt.ArrayLike = 0.0,
    resolution: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    grid: OccupancyGrid | None = None,
) -> pd.DataFrame:
    """Tracks table ``(scenario, id, t, x, y, yaw)`` from rollout states.

    Cell ``(row, col)`` maps to its centre ``x = origin_x + (col + 0.5) resolution``,
    ``y = origin_y + (row + 0.5) resolution`` (ROS occupancy-grid convention), heading ``h``
    to ``yaw = h pi / 2``; epoch ``e`` to ``t = t0 + e dt``. Absent epochs (``-1``) are left out.
    With ``grid`` (an ``OccupancyGrid``) its ``cell_to_world`` and origin yaw are used instead
    of ``resolution`` and ``origin``.

    Parameters
    ----------
    states : (B, T + 1, 3) int
        Output of :func:`rollout`.
    scenario : int or (B,) array
        Scenario label(s).
    ids : (B,) array or None
        Artefact ids (default ``0 .. B - 1``).
    dt : float
        Duration of an epoch in seconds.
    t0 : float or (B,) float
        Time of global epoch 0 (per artefact if an array).
    resolution : float
        Cell size in metres.
    origin : tuple of float
        World coordinates of the grid's corner ``(x, y)``.
    grid : OccupancyGrid or None
        Grid whose ``cell_to_world`` (and ``origin[2]``, its yaw) map cells to F_E.

    Returns
    -------
    pandas.DataFrame
        Columns ``scenario, id, t, x, y, yaw``, sorted by scenario, id and t.
    """
    s = np.asarray(states)
    if s.ndim != 3 or s.shape[2] != 3:
        raise ValueError(f"states: expected a (B, T + 1, 3) array, got {describe(s)}")
    dt = float(check_positive("dt", dt))
    resolution = float(check_positive("resolution", resolution))
    b, n, _ = s.shape
    ids = np.arange(b) if ids is None else np.asarray(ids)
    scen = np.broadcast_to(np.asarray(scenario), (b,))
    t0 = np.broadcast_to(np.asarray(t0, dtype=float), (b,))
    bi, ei = np.nonzero(s[:, :, 0] >= 0)
    row, col, head = s[bi, ei, 0], s[bi, ei, 1], s[bi, ei, 2]
    if grid is not None:
        xy = np.asarray(grid.cell_to_world(np.stack([row, col], axis=-1)), dtype=float)
        x, y = xy[:, 0], xy[:, 1]
        yaw = np.mod(head * (np.pi / 2) + float(grid.origin[2]), 2 * np.pi)
    else:
        x = origin[0] + (col + 0.5) * resolution
        y = origin[1] + (row + 0.5) * resolution
        yaw = head * (np.pi / 2)
    table = pd.DataFrame(
        {"scenario": scen[bi], "id": ids[bi], "t": t0[bi] + ei * dt, "x": x, "y": y, "yaw": yaw}
    )
    return table.sort_values(["scenario", "id", "t"], kind="stable").reset_index(drop=True)


_SCENARIO_COLUMNS = ("scenario", "id", "t_arrive", "t_leave", "x", "y", "yaw")


def _behaviour_column(table: pd.DataFrame, behaviour_of: BehaviourOf | None) -> list[str]:
    if "behaviour" in table.columns:
        return [str(b) for b in table["behaviour"]]
    if behaviour_of is None:
        return ["walk"] * len(table)
    if callable(behaviour_of):
        return [str(behaviour_of(row)) for _, row in table.iterrows()]
    if "class" not in table.columns:
        raise ValueError("artefacts: expected a 'class' column to look behaviours up by class")
    out = []
    for c in table["class"]:
        if c not in behaviour_of:
            raise ValueError(f"behaviour_of: expected an entry for class {c!r}, got none")
        out.append(str(behaviour_of[c]))
    return out


def check_on_free_cells(
    rows: np.ndarray, cols: np.ndarray, occ: np.ndarray, xy: np.ndarray, scenario: Hashable
) -> None:
    """Refuse artefacts whose cells ``(rows, cols)`` (n,) lie outside ``occ`` (H, W) or on an
    occupied cell, naming the first one's row of the scenario and its position ``xy``."""
    h_, w_ = occ.shape
    bad = (rows < 0) | (rows >= h_) | (cols < 0) | (cols >= w_)
    bad[~bad] = occ[rows[~bad], cols[~bad]]
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"artefacts: expected positions on free cells, got row {i} of scenario "
            f"{scenario!r} at x={xy[i, 0]!r}, y={xy[i, 1]!r}"
        )


def scenario_tracks(
    key: jax.Array,
    artefacts: pd.DataFrame,
    occupied: npt.ArrayLike | OccupancyGrid,
    *,
    dt: float = 1.0,
    resolution: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    behaviour_of: BehaviourOf | None = None,
    slip: float = 0.1,
    step_cost: float = 1e-3,
    resolve: Resolver | str | None = BUILDER,
) -> pd.DataFrame:
    """Trajectories for the artefacts of generated scenarios (the ``--behaviours`` hook).

    For every scenario, each artefact gets a behaviour (a ``behaviour`` column, else
    ``behaviour_of``, else ``"walk"``), a horizon ``d = round((t_leave - t_arrive) / dt)``
    and, for walk and run, a goal drawn uniformly among the free cells connected to its
    start (an artefact alone in its component stops). Followers follow the nearest
    non-follower present at their arrival, with rewards at that artefact's predicted cells
    (a rollout without collisions); without one they walk. All artefacts of a scenario are
    then rolled out together, their collisions resolved by ``resolve`` at each epoch.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    artefacts : pandas.DataFrame
        One row per artefact: ``scenario, id, t_arrive, t_leave, x, y, yaw`` (and
        optionally ``class``, ``mark``, ``behaviour``); positions in world coordinates.
    occupied : (H, W) bool array or OccupancyGrid
        The (augmented) grid the artefacts move on. With an ``OccupancyGrid`` its own
        ``world_to_cell`` / ``cell_to_world`` and origin are used (``resolution`` and
        ``origin`` are then ignored).
    dt : float
        Seconds per decision epoch.
    resolution : float
        Cell size in metres (for a plain array).
    origin : tuple of float
        World coordinates ``(x, y)`` of the grid's corner (cell ``(0, 0)``).
    behaviour_of : mapping or callable or None
        ``{class: behaviour}`` or ``f(row) -> behaviour`` (the class row of the catalogue Q).
    slip, step_cost : float
        MDP parameters (see :class:`GridMDP`).
    resolve : callable, "builder" or None
        Collision resolution (see :func:`rollout`; default the AR-builder's).

    Returns
    -------
    pandas.DataFrame
        Tracks ``scenario, id, t, x, y, yaw``, one row per artefact and epoch of its life.

    Raises
    ------
    ValueError
        On missing columns, artefacts outside the grid or on an obstacle, ``t_leave <
        t_arrive``, or unknown behaviours.
    """
    from scipy import ndimage  # lazy: +0.2 s CPU on `import are_stats.behaviour`

    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.behaviour`)
    from are_stats.traffic import key_uniform, split_key

    if not isinstance(artefacts, pd.DataFrame):
        raise ValueError(f"artefacts: expected a pandas DataFrame, got {type(artefacts).__name__}")
    missing = [c for c in _SCENARIO_COLUMNS if c not in artefacts.columns]
    if missing:
        raise ValueError(
            f"artefacts: expected columns {list(_SCENARIO_COLUMNS)}, missing {missing}"
        )
    dt = float(check_positive("dt", dt))
    resolution = float(check_positive("resolution", resolution))
    mdp = GridMDP(occupied, slip=slip, step_cost=step_cost)
    occ = mdp.occupied
    grid = (
        occupied
        if hasattr(occupied, "world_to_cell") and hasattr(occupied, "cell_to_world")
        else None
    )
    h_, w_ = occ.shape
    labels, _ = ndimage.label(~occ)
    sizes = np.bincount(labels.ravel())
    tables = []
    for s_label, table in artefacts.groupby("scenario", sort=True):
        table = table.reset_index(drop=True)
        n = len(table)
        key, k_goal, k_pre, k_roll = split_key(key, 4)
        t_arr = table["t_arrive"].to_numpy(float)
        t_leave = table["t_leave"].to_numpy(float)
        if (t_leave < t_arr).any() or not np.isfinite(t_arr).all():
            i = int(np.argmax((t_leave < t_arr) | ~np.isfinite(t_arr)))
            raise ValueError(
                f"artefacts: expected finite t_arrive <= t_leave, got row {i} of scenario "
                f"{s_label!r} with {t_arr[i]!r} and {t_leave[i]!r}"
            )
        xy = table[["x", "y"]].to_numpy(float)
        if grid is not None:
            rows, cols = np.asarray(grid.world_to_cell(xy), dtype=np.int64).T
        else:
            cols = np.floor((xy[:, 0] - origin[0]) / resolution).astype(np.int64)
            rows = np.floor((xy[:, 1] - origin[1]) / resolution).astype(np.int64)
        check_on_free_cells(rows, cols, occ, xy, s_label)
        yaw0 = float(grid.origin[2]) if grid is not None else 0.0
        heads = np.round((table["yaw"].to_numpy(float) - yaw0) / (np.pi / 2)).astype(np.int64) % 4
        starts = np.column_stack([rows, cols, heads])
        t0 = t_arr.min()
        arrive = np.round((t_arr - t0) / dt).astype(np.int64)
        horizons = np.maximum(np.round((t_leave - t_arr) / dt).astype(np.int64), 0)
        behaviours = _behaviour_column(table, behaviour_of)
        comp = labels[rows, cols]
        u = key_uniform(k_goal, (n,))
        goals = np.full((n, 2), -1, np.int64)
        for i in range(n):
            if behaviours[i] in ("walk", "run", "follow"):
                cells = np.argwhere(labels == comp[i])
                cells = cells[(cells != starts[i, :2]).any(axis=1)]
                if sizes[comp[i]] <= 1 or len(cells) == 0:
                    behaviours[i] = "stop"
                    continue
                goals[i] = cells[min(int(u[i] * len(cells)), len(cells) - 1)]
        leader = np.array([b != "follow" for b in behaviours])
        bucket = 64 * (-(-max(int(horizons.max()), 1) // 64))
        sols, order = [], []
        lead_idx = np.flatnonzero(leader)
        if len(lead_idx):
            sol_lead = mdp.solve(
                goals[lead_idx],
                [behaviours[i] for i in lead_idx],
                horizons[lead_idx],
                n_epochs=bucket,
                store_values=False,
            )
            sols.append(sol_lead)
            order.extend(lead_idx)
        fol_idx = np.flatnonzero(~leader)
        if len(fol_idx):
            rewards, fol_beh = [], []
            pred = None
            if len(lead_idx):
                pred = rollout(
                    k_pre,
                    sol_lead,
                    starts[lead_idx],
                    int((arrive + horizons).max()),
                    arrive=arrive[lead_idx],
                    resolve=None,
                )
            for i in fol_idx:
                target = None
                if pred is not None:
                    here = pred[:, min(arrive[i], pred.shape[1] - 1), :2]
                    present = here[:, 0] >= 0
                    if present.any():
                        dist = np.abs(here - starts[i, :2]).sum(axis=1).astype(float)
                        dist[~present] = np.inf
                        target = int(np.argmin(dist))
                if target is None:
                    fol_beh.append("walk")
                    rewards.append(None)
                    continue
                path = pred[target, arrive[i] : arrive[i] + horizons[i] + 1, :2].copy()
                path = np.concatenate([path, np.repeat(path[-1:], horizons[i] + 1 - len(path), 0)])
                for k in range(1, len(path)):  # after the target leaves, keep its last cell
                    if path[k, 0] < 0:
                        path[k] = path[k - 1]
                fol_beh.append("follow")
                rewards.append(
                    follow_rewards(path, occ.shape) if horizons[i] > 0 else np.zeros((1, h_, w_))
                )
            sols.append(
                mdp.solve(
                    goals[fol_idx],
                    fol_beh,
                    horizons[fol_idx],
                    follow=rewards,
                    n_epochs=bucket,
                    store_values=False,
                )
            )
            order.extend(fol_idx)
        order = np.asarray(order)
        states = rollout(k_roll, sols, starts[order], arrive=arrive[order], resolve=resolve)
        tables.append(
            cells_to_tracks(
                states,
                scenario=s_label,
                ids=table["id"].to_numpy()[order],
                dt=dt,
                t0=t_arr[order] - arrive[order] * dt,
                resolution=resolution,
                origin=origin,
                grid=grid,
            )
        )
    if not tables:
        return pd.DataFrame({c: [] for c in ("scenario", "id", "t", "x", "y", "yaw")})
    out = pd.concat(tables, ignore_index=True)
    return out.sort_values(["scenario", "id", "t"], kind="stable").reset_index(drop=True)
