"""Groups walk together (issue 26): one route per arrival group, members in formation at
the fitted spacing, through doors in single file; the spacing recovered from tracks
simulated with a known one."""

from __future__ import annotations

import numpy as np
import pandas as pd

from are_stats.behaviour import (
    SocialForce,
    formation,
    group_spacing,
    group_tracks,
    social_force_tracks,
)
from are_stats.environment import OccupancyGrid
from are_stats.fitting import fit_group_spacing


def _plan(walkers, dt: float, rest: float = 0.0) -> pd.DataFrame:
    """Straight planned tracks: (id, t0, start (2,), end (2,), speed), then ``rest`` s
    standing at the end."""
    rows = []
    for i, t0, a, b, v in walkers:
        a, b = np.asarray(a, float), np.asarray(b, float)
        dur = np.hypot(*(b - a)) / v
        t = t0 + np.arange(0, np.ceil((dur + rest) / dt) + 1) * dt
        xy = a + (b - a) * np.clip((t - t0) / dur, 0, 1)[:, None]
        rows += [(i, tt, x, y, 0.0) for tt, (x, y) in zip(t, xy, strict=True)]
    return pd.DataFrame(rows, columns=["id", "t", "x", "y", "yaw"])


def _door() -> OccupancyGrid:
    """A 20 m x 10 m room of 0.1 m cells split at x = 10 m by a wall with a 1.2 m door."""
    data = np.zeros((100, 200))
    data[:, 99:102] = 100
    data[44:56, 99:102] = 0  # the door: y from 4.4 to 5.6 m
    return OccupancyGrid(data, 0.1)


def _nearest_mate(out: pd.DataFrame, ids, t_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and (members, times) distance of each member to its nearest co-member."""
    tabs = [out[out["id"] == i].set_index("t")[["x", "y"]] for i in ids]
    times = tabs[0].index
    for tab in tabs[1:]:
        times = times.intersection(tab.index)
    times = times[times <= t_max]
    xy = np.stack([tab.loc[times].to_numpy() for tab in tabs])  # (m, T, 2)
    d = np.hypot(*(xy[:, None] - xy[None, :]).transpose(3, 0, 1, 2))
    d[np.arange(len(ids)), np.arange(len(ids))] = np.inf
    return times.to_numpy(), d.min(axis=1)


def test_formation_leader_is_the_first_to_arrive_and_slots_follow_arrival():
    leader, slot = formation(
        [0, 0, 0, 1, 1, 0], [5, 5, 5, 5, -1, 7], [3.0, 1.0, 2.0, 1.0, 1.0, 0.0]
    )
    assert leader.tolist() == [1, 1, 1, 3, 4, 5]
    assert slot.tolist() == [2, 0, 1, 0, 0, 0]


def test_a_group_keeps_its_spacing_through_a_door():
    grid = _door()
    spacing = 0.75
    params = SocialForce(group_spacing=spacing)
    # three friends planned side by side straight across the room (the door is on the
    # leader's line only), one of them faster than the others
    plan = _plan(
        [
            (0, 0.0, (2, 5), (18, 5), 1.2),
            (1, 0.0, (2, 5.75), (18, 5.75), 1.2),
            (2, 0.0, (2, 4.25), (18, 4.25), 1.5),
        ],
        0.1,
        3.0,
    )
    out = social_force_tracks(plan, params, grid=grid, dt=0.1, groups=np.full(len(plan), 4))
    t, near = _nearest_mate(out, [0, 1, 2], t_max=13.0)
    assert near.min() > 2 * params.radius  # never on top of each other
    assert near.max() < 2 * spacing  # nor left behind at the door
    before, after = (t >= 3) & (t <= 7), (t >= 11.5) & (t <= 13)
    assert np.abs(near[:, before] - spacing).max() < 0.05  # abreast at their spacing
    assert np.abs(near[:, after] - spacing).max() < 0.1  # and again after the door
    leader = out[out["id"] == 0]
    assert leader[leader["t"] == 13.0]["x"].iloc[0] > 16.0  # through the door, at pace
    # the whole group went through the door (x = 10 m): all three on the far side
    for i in (1, 2):
        assert out[(out["id"] == i) & (out["t"] == 13.0)]["x"].iloc[0] > 16.0
    row, col = np.asarray(grid.world_to_cell(out[["x", "y"]].to_numpy())).T
    assert grid.free[row, col].all()
    # without the group each walks its own plan at its own pace: they come apart
    alone = social_force_tracks(plan, params, grid=grid, dt=0.1)
    assert _nearest_mate(alone, [0, 1, 2], t_max=13.0)[1].max() > 2 * spacing


def test_a_group_walks_at_its_leaders_pace():
    plan = _plan([(0, 0.0, (0, 0), (30, 0), 1.5), (1, 0.0, (0, 0.8), (30, 0.8), 1.0)], 0.1, 0)
    out = social_force_tracks(plan, dt=0.1, groups=np.full(len(plan), 1))
    t, near = _nearest_mate(out, [0, 1], t_max=19.0)
    assert np.abs(near[0, t > 2] - SocialForce().group_spacing).max() < 0.05
    for i in (0, 1):  # both at the leader's 1.5 m/s, the slower member too
        walker = out[out["id"] == i]
        speed = np.hypot(np.diff(walker["x"]), np.diff(walker["y"])) / 0.1
        assert abs(np.median(speed[(walker["t"].to_numpy()[1:] < 19.0)]) - 1.5) < 0.02


def test_generated_groups_walk_at_the_speed_laws_pace():
    """Groups whose members each draw a preferred speed from the law (as generation plans
    them) walk at one draw of the law per group: the groups' median pace is the law's
    median ``exp(mu)`` (scipy). At the slowest member's pace it would be the median of the
    minimum of 2 or 3 draws, ``0.55 sigma`` to ``0.82 sigma`` lower in log speed (0.14 to
    0.20 here). The median of ``n`` log paces has sd ``1.2533 sigma / sqrt(n)`` (0.022): 4 of
    them, a false-failure rate of about 6e-5 (the seed is fixed)."""
    import jax
    from scipy import stats

    from are_stats.behaviour import preferred_speeds

    mu, sigma, n_groups = np.log(1.3), 0.25, 200
    rng = np.random.default_rng(26)
    size = rng.choice([2, 3], n_groups)
    speed = preferred_speeds(jax.random.key(26), np.full(size.sum(), np.exp(mu)), sigma)
    walkers, scen, k = [], [], 0
    for g in range(n_groups):
        for y in (0.0, 0.75, -0.75)[: size[g]]:  # in their slots, each planned at its own speed
            walkers.append((k, 0.0, (0.0, y), (40.0, y), float(speed[k])))
            scen.append(g)
            k += 1
    plans = [_plan([w], 0.5) for w in walkers]
    plan = pd.concat(
        [p.assign(scenario=s) for p, s in zip(plans, scen, strict=True)], ignore_index=True
    )
    out = social_force_tracks(plan, dt=0.1, groups=plan["scenario"].to_numpy())
    out = out[out["t"].isin([4.0, 9.0])]
    xy = out.pivot_table(index="id", columns="t", values="x")
    pace = (xy[9.0] - xy[4.0]).to_numpy() / 5.0  # (people,) m/s, in the order of their ids
    first = np.r_[0, np.cumsum(size)[:-1]]
    leaders = pace[first]
    for g in range(n_groups):  # the members walk with their leader
        assert np.abs(pace[first[g] : first[g] + size[g]] - leaders[g]).max() < 0.05
    law = stats.lognorm(s=sigma, scale=np.exp(mu))
    tol = 4.0 * 1.2533 * sigma / np.sqrt(n_groups)
    assert abs(np.log(np.median(leaders)) - np.log(law.median())) < tol


def test_group_tracks_put_members_on_the_leaders_path():
    grid = _door()
    plan = _plan([(0, 0.0, (2, 5), (18, 5), 1.0), (1, 0.0, (3, 8), (19, 8), 1.0)], 1.0, 0)
    art = pd.DataFrame({"scenario": 0, "artefact": [0, 1], "t_arrive": [0.0, 0.0], "group": [2, 2]})
    moved = group_tracks(plan.assign(scenario=0), art, 0.8, grid)
    assert moved.attrs["group_members"] == 1
    lead = moved[moved["id"] == 0].set_index("t")
    mate = moved[moved["id"] == 1].set_index("t")
    both = lead.index.intersection(mate.index)
    gap = np.hypot(*(lead.loc[both, ["x", "y"]] - mate.loc[both, ["x", "y"]]).to_numpy().T)
    assert np.allclose(gap, 0.8)
    # abreast (to the leader's left) in the open, in single file behind it in the door
    assert np.allclose(mate.loc[5.0, ["x", "y"]], [7.0, 5.8])
    assert np.allclose(mate.loc[8.0, ["x", "y"]], [9.2, 5.0])
    assert np.allclose(moved[moved["id"] == 0][["x", "y"]], plan[plan["id"] == 0][["x", "y"]])


def test_group_spacing_is_recovered_from_tracks_simulated_with_known_spacing():
    rng = np.random.default_rng(3)
    truth = 0.9
    walkers, groups, i = [], [], 0
    for g in range(8):  # pairs and triples, one after the other across an open square
        t0 = 12.0 * g
        ang = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(ang), np.sin(ang)])
        a, b = -10 * u, 10 * u
        for m in range(2 + g % 2):
            side = np.array([-u[1], u[0]]) * (0.0 if m == 0 else (-1) ** (m + 1) * truth)
            walkers.append((i, t0 + 0.2 * m, a + side, b + side, 1.3))
            groups.append(g)
            i += 1
    plan = _plan(walkers, 0.2, 0)
    out = social_force_tracks(
        plan,
        SocialForce(group_spacing=truth),
        dt=0.1,
        groups=np.asarray(groups)[plan["id"].to_numpy()],
    )
    spacing, samples = fit_group_spacing(out)
    assert samples > 500
    assert abs(spacing - truth) < 0.05
    # the same measure with the true groups, and nothing without groups
    known = dict(enumerate(groups))
    assert abs(group_spacing(out, known)[0] - truth) < 0.05
    assert np.isnan(group_spacing(out, {})[0])
