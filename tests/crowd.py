"""An independent synthetic crowd for realism tests and benchmarks (issue 26).

Not the package's own motion model (no social force, no MDP, no formation code of
``are_stats``): a room of 20 x 10 m at 0.1 m with a 3 m door in the left and right walls
and a round pillar (radius 0.6 m) in its middle. People arrive at one door in groups of
1-3 (probabilities 0.6, 0.3, 0.1; Poisson arrivals) and walk to the other door:

* each group has a preferred speed drawn once, ``N(1.3, 0.2)`` m/s clipped to 0.8-1.8
  (the slowest member's, as groups walk at the pace of their slowest);
* the path bends smoothly round the pillar: while the straight line to the exit passes
  within ``PILLAR_CLEAR`` of the pillar's centre, the walker heads along the tangent to
  that circle on the side it is on;
* people avoid each other by sampling velocities (a velocity-obstacle rule): every 0.1 s
  each picks, among 15 headings within +-70 degrees of its desired one and 3 speeds, the
  velocity minimising ``|v - v_desired| + 2 / max(ttc, 0.1)`` (the time to collision of
  two 0.3 m discs within 4 m, capped at 3 s; group mates ignore each other), then turns
  towards it with an acceleration of at most 2 m/s^2;
* members of a group walk abreast of their leader at the group's spacing (``N(0.7,
  0.05)`` m per neighbour, left then right), heading for their slot beside the leader;
* people come in through the door already walking (at their speed, towards the exit) and
  leave within 0.4 m of their exit point;
* tracks are seen at 2.5 Hz with 5 cm Gaussian position noise;
* with ``wander = (sd, time)`` (default none) each person's desired heading is turned by
  its own stationary Ornstein-Uhlenbeck deviation of sd ``sd`` (rad) and correlation time
  ``time`` (s), the within-person wander of the package's model (group members keep
  heading for their slot); its draws come from a stream of their own, so the crowd
  without it is the same draw for draw.

:func:`crowd_tracks` returns the table and each track's group; :func:`write_crowd`
writes the map, the tracks table and its manifest as ``are-stats fit`` reads them;
:func:`crowd_realism` fits the crowd and scores the fit against the baselines.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

#: Room size (m), map resolution (m), door span in y (m) and the pillar (centre, radius).
ROOM = (20.0, 10.0)
RESOLUTION = 0.1
DOOR = (3.5, 6.5)
PILLAR = (10.0, 5.0, 0.6)
#: Distance from the pillar's centre (m) the walkers keep (its radius plus a body and a gap).
PILLAR_CLEAR = 1.3
#: Simulation step and the sampling period of the tracks (s).
SIM_DT = 0.1
SAMPLE_DT = 0.4
RADIUS = 0.3


def crowd_grid() -> np.ndarray:
    """Occupancy image rows (H, W) uint8, row 0 at the top as in a PGM (254 free, 0 wall)."""
    w, h = round(ROOM[0] / RESOLUTION), round(ROOM[1] / RESOLUTION)
    img = np.full((h, w), 254, np.uint8)
    img[:3, :] = img[-3:, :] = 0
    img[:, :3] = img[:, -3:] = 0
    lo, hi = round(DOOR[0] / RESOLUTION), round(DOOR[1] / RESOLUTION)
    img[h - hi : h - lo, :3] = img[h - hi : h - lo, -3:] = 254
    yy, xx = np.mgrid[0:h, 0:w]
    cx, cy = (xx + 0.5) * RESOLUTION, (h - yy - 0.5) * RESOLUTION
    img[np.hypot(cx - PILLAR[0], cy - PILLAR[1]) <= PILLAR[2]] = 0
    return img


def write_map(folder: Path) -> Path:
    """The room's ROS map (``crowd.pgm`` + ``crowd.yaml``) in ``folder``."""
    img = crowd_grid()
    h, w = img.shape
    with open(folder / "crowd.pgm", "wb") as f:
        f.write(f"P5\n{w} {h}\n255\n".encode())
        f.write(img.tobytes())
    meta = {"image": "crowd.pgm", "resolution": RESOLUTION, "origin": [0.0, 0.0, 0.0],
            "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196,
            "mode": "trinary"}  # fmt: skip
    (folder / "crowd.yaml").write_text(yaml.safe_dump(meta))
    return folder / "crowd.yaml"


def _desired_heading(x: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(n, 2) unit vectors to the goals, bent along the pillar's tangent where the straight
    line would pass it closer than :data:`PILLAR_CLEAR`."""
    c = np.array(PILLAR[:2])
    to = goal - x
    dist = np.maximum(np.hypot(*to.T), 1e-9)
    e = to / dist[:, None]
    rel = c - x
    along = (rel * e).sum(1)
    miss = np.abs(rel[:, 0] * e[:, 1] - rel[:, 1] * e[:, 0])  # distance of the line to c
    d_c = np.maximum(np.hypot(*rel.T), 1e-9)
    blocked = (along > 0) & (along < dist) & (miss < PILLAR_CLEAR) & (d_c > PILLAR_CLEAR)
    # tangent from x to the circle of radius PILLAR_CLEAR, on the side of the goal line
    ang = np.arcsin(np.clip(PILLAR_CLEAR / d_c, -1, 1))
    side = np.sign(rel[:, 0] * e[:, 1] - rel[:, 1] * e[:, 0])  # pillar right (+) or left
    side = np.where(side == 0, 1.0, side)
    base = np.arctan2(rel[:, 1], rel[:, 0]) + side * ang
    tangent = np.column_stack([np.cos(base), np.sin(base)])
    inside = d_c <= PILLAR_CLEAR  # pushed in: straight away from the pillar's centre
    out = np.where(blocked[:, None], tangent, e)
    return np.where(inside[:, None], -rel / d_c[:, None], out)


#: The candidate headings (rad, off the desired one) and speeds (of the desired one).
_ANGLES = np.deg2rad(np.linspace(-70, 70, 15))
_FRACS = np.array([1.0, 0.6, 0.25])


def _choose(x, v, desired, group, alive):
    """The velocity-obstacle choice of every alive walker (n, 2); walkers not alive: 0
    (not moved)."""
    idx = np.flatnonzero(alive)
    angles, fracs = _ANGLES, _FRACS
    want = desired[idx]
    h = np.arctan2(want[:, 1], want[:, 0])
    ang = h[:, None, None] + angles[None, :, None]  # (alive, 15, 1)
    mag = np.hypot(*want.T)[:, None, None] * fracs[None, None, :]
    cand = np.stack([np.cos(ang) * mag, np.sin(ang) * mag], axis=-1).reshape(idx.size, 45, 2)
    cand = np.concatenate([cand, np.zeros((idx.size, 1, 2))], axis=1)  # standing still too
    cost = np.hypot(*(cand - want[:, None, :]).transpose(2, 0, 1))
    p = x[idx][:, None, :] - x[idx][None, :, :]  # i minus j
    near = (np.hypot(*p.transpose(2, 0, 1)) < 4.0) & ~np.eye(idx.size, dtype=bool)
    near &= group[idx][:, None] != group[idx][None, :]
    # every near pair (a, b) at once, elementwise as walker by walker; a pair not near is
    # no collision (3 s), so the min over b is the min over a's neighbours
    a, b = np.nonzero(near)
    rel_p = -p[a, b]  # j minus i: (P, 2)
    w = cand[a] - v[idx[b]][:, None, :]  # relative velocity i to j (P, k, 2)
    qa = (w * w).sum(-1)
    qb = -2 * (w * rel_p[:, None]).sum(-1)
    qc = (rel_p * rel_p).sum(-1)[:, None] - (2 * RADIUS) ** 2
    disc = qb * qb - 4 * qa * qc
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hit = (-qb - np.sqrt(np.maximum(disc, 0))) / (2 * qa)
    t_hit = np.where((disc >= 0) & (qa > 1e-12) & (t_hit >= 0), t_hit, 3.0)
    t_pair = np.full((idx.size, idx.size, cand.shape[1]), 3.0)
    t_pair[a, b] = np.where(qc <= 0, 0.0, np.minimum(t_hit, 3.0))
    t_min = t_pair.min(axis=1, initial=3.0)  # (alive, k); none alive: none
    cost = cost + np.where(t_min < 3.0, 2.0 / np.maximum(t_min, 0.1), 0.0)
    best = cost.argmin(axis=1)  # ties: the first candidate
    chosen = np.zeros_like(desired)
    chosen[idx] = cand[np.arange(idx.size), best]
    return chosen


def crowd_tracks(
    seed: int = 0,
    horizon: float = 300.0,
    mean_gap: float = 5.0,
    wander: tuple[float, float] = (0.0, 2.0),
) -> tuple[pd.DataFrame, dict[str, str]]:
    """Seeded tracks of the crowd (see the module docstring).

    Parameters
    ----------
    seed : int
        Seeds every draw.
    horizon : float
        Seconds of the log (arrivals stop 30 s before it; tracks are cut at it).
    mean_gap : float
        Mean time (s) between group arrivals.
    wander : (float, float)
        Sd (rad) and correlation time (s) of each person's heading wander; sd 0: none.

    Returns
    -------
    tracks : pandas.DataFrame
        ``id, t, x, y`` at 2.5 Hz with 5 cm noise.
    groups : dict of str to str
        Group of each track id that walked in a group of two or more.
    """
    sd, corr = float(wander[0]), float(wander[1])
    if sd < 0.0 or not corr > 0.0:
        raise ValueError(f"wander: expected (sd >= 0 rad, time > 0 s), got {wander}")
    rng = np.random.default_rng(seed)
    people = []  # (t0, x0, goal, speed, group, leader, offset)
    t, g = 0.0, 0
    while True:
        t += rng.exponential(mean_gap)
        if t > horizon - 30.0:
            break
        size = int(rng.choice([1, 2, 3], p=[0.6, 0.3, 0.1]))
        speed = float(np.clip(rng.normal(1.3, 0.2), 0.8, 1.8))
        left = rng.random() < 0.5
        y0, y1 = rng.uniform(DOOR[0] + 0.9, DOOR[1] - 0.9, 2)
        x0, x1 = (0.4, 19.9) if left else (19.6, 0.1)
        spacing = float(rng.normal(0.7, 0.05))
        lead = len(people)
        for m in range(size):
            off = 0.0 if m == 0 else (spacing if m == 1 else -spacing)
            start = np.array([x0, y0 + (off if left else -off)])
            people.append((t, start, np.array([x1, y1]), speed, g, lead, off))
        g += 1
    n = len(people)
    t_on = np.array([p[0] for p in people])
    x = np.array([p[1] for p in people])
    goal = np.array([p[2] for p in people])
    speed = np.array([p[3] for p in people])
    group = np.array([p[4] for p in people])
    leader = np.array([p[5] for p in people])
    offset = np.array([p[6] for p in people])
    # people walk in through the door (a tracker sees them walking): at their speed
    v = _desired_heading(x, goal) * speed[:, None]
    gone = np.zeros(n, bool)
    turn_rng = np.random.default_rng([seed, 1])  # its own stream: none leaves the crowd as is
    phi = np.exp(-SIM_DT / corr)
    theta = sd * turn_rng.standard_normal(n) if sd > 0.0 else None
    every = round(SAMPLE_DT / SIM_DT)
    rows = []
    steps = int(horizon / SIM_DT)
    for s in range(steps + 1):
        now = s * SIM_DT
        alive = (t_on <= now + 1e-9) & ~gone
        if s % every == 0:
            for i in np.flatnonzero(alive):
                rows.append((i, round(now, 3), x[i, 0], x[i, 1]))
        if not alive.any():
            continue
        desired = _desired_heading(x, goal) * speed[:, None]
        if theta is not None:
            c, s_ = np.cos(theta), np.sin(theta)
            desired = np.column_stack(
                [c * desired[:, 0] - s_ * desired[:, 1], s_ * desired[:, 0] + c * desired[:, 1]]
            )
            theta = phi * theta + sd * np.sqrt(1.0 - phi**2) * turn_rng.standard_normal(n)
        is_member = leader != np.arange(n)
        with_lead = is_member & alive & alive[leader]
        if with_lead.any():
            lv = v[leader[with_lead]]
            ls = np.hypot(*lv.T)
            hd = np.where(
                (ls > 0.1)[:, None], lv / np.maximum(ls, 1e-9)[:, None], desired[leader[with_lead]]
            )
            hd = hd / np.maximum(np.hypot(*hd.T), 1e-9)[:, None]
            normal = np.column_stack([-hd[:, 1], hd[:, 0]])
            slot = x[leader[with_lead]] + offset[with_lead, None] * normal
            want = lv + (slot - x[with_lead]) / 1.0
            cap = 1.3 * speed[with_lead]
            norm = np.maximum(np.hypot(*want.T), 1e-9)
            desired[with_lead] = want * np.minimum(1.0, cap / norm)[:, None]
        chosen = _choose(x, v, desired, group, alive)
        dv = chosen - v
        mag = np.maximum(np.hypot(*dv.T), 1e-12)
        dv = dv * np.minimum(1.0, 2.0 * SIM_DT / mag)[:, None]
        v = np.where(alive[:, None], v + dv, v)
        x_new = x + v * SIM_DT
        x_new[:, 1] = np.clip(x_new[:, 1], 0.6, ROOM[1] - 0.6)
        x = np.where(alive[:, None], x_new, x)
        done = alive & (np.hypot(*(goal - x).T) < 0.4)
        gone |= done
    tab = pd.DataFrame(rows, columns=["i", "t", "x", "y"])
    tab["x"] += rng.normal(0.0, 0.05, len(tab))
    tab["y"] += rng.normal(0.0, 0.05, len(tab))
    tab["id"] = "c" + tab["i"].astype(str)
    size = np.bincount(group)
    groups = {f"c{i}": f"g{group[i]}" for i in range(n) if size[group[i]] > 1}
    counts = tab.groupby("id").size()
    keep = counts.index[counts >= 3]
    tab = tab[tab["id"].isin(keep)]
    return tab[["id", "t", "x", "y"]].reset_index(drop=True), groups


def write_crowd(folder: Path, seed: int = 0, horizon: float = 300.0) -> Path:
    """The map (``crowd.yaml``), the tracks table ``walkers.csv`` and its manifest
    ``walkers.yaml`` (window and map) in ``folder``; the table's path."""
    write_map(folder)
    tab, _ = crowd_tracks(seed, horizon)
    path = folder / "walkers.csv"
    tab.round({"t": 3, "x": 3, "y": 3}).to_csv(path, index=False)
    meta = {"window": [0.0, horizon], "map": "crowd.yaml", "time_unit": "s"}
    (folder / "walkers.yaml").write_text(yaml.safe_dump(meta))
    return path


def crowd_realism(
    seed: int = 0, horizon: float = 300.0, n_replicates: int = 3, errors: bool = True
) -> dict[str, Any]:
    """The crowd's behaviour and interaction fitted from its tracks on its map as
    ``are-stats fit`` fits them (:func:`~are_stats.fitting.fit_behaviour`,
    :func:`~are_stats.fitting.learn_interaction`: the fitted force, or none or the
    published one where it cannot be fitted), scored by the realism table (constant
    velocity, the catalogue behaviour, the fitted one, ``n_replicates`` each) and, with
    ``errors``, the displacement errors (8 observed / 12 predicted, K = 20).

    Returns
    -------
    dict
        ``table`` (the realism table), ``errors`` (the displacement errors, or None),
        ``interaction`` (the fitted :class:`~are_stats.behaviour.SocialForce`), ``info``,
        ``cpu`` (seconds per stage) and ``tracks``.
    """
    import jax

    from are_stats.environment import OccupancyGrid, load_catalogue
    from are_stats.fitting import displacement_errors, fit_behaviour, learn_interaction
    from are_stats.scenarios import realism_table

    cpu: dict[str, float] = {}
    tic = time.process_time()
    tracks, _ = crowd_tracks(seed, horizon)
    cpu["crowd"] = time.process_time() - tic
    with tempfile.TemporaryDirectory() as tmp:
        grid = OccupancyGrid.from_ros_yaml(write_map(Path(tmp)))
    cat = load_catalogue()
    tic = time.process_time()
    bfit = fit_behaviour(
        tracks, grid.free, grid.resolution, grid.origin[:2], seed=seed,
        run_speed=cat.run_thresholds(),
    )  # fmt: skip
    cpu["behaviour fit"] = time.process_time() - tic
    tic = time.process_time()
    learned, info, _ = learn_interaction(tracks)
    cpu["interaction fit"] = time.process_time() - tic
    key = jax.random.key(seed)
    tic = time.process_time()
    table = realism_table(
        jax.random.fold_in(key, 4), tracks, grid, behaviour=bfit, catalogue=cat,
        n_replicates=n_replicates, interaction=learned,
    )  # fmt: skip
    cpu["realism table"] = time.process_time() - tic
    err = None
    if errors:
        tic = time.process_time()
        err = displacement_errors(
            jax.random.fold_in(key, 3), bfit, tracks, n_samples=20, interaction=learned,
            grid=grid, max_windows=200,
        )  # fmt: skip
        cpu["displacement errors"] = time.process_time() - tic
    return {"table": table, "errors": err, "interaction": learned, "info": info, "cpu": cpu,
            "tracks": tracks}  # fmt: skip
