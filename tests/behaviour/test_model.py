"""BehaviourFit's exit draws (:meth:`~are_stats.behaviour.BehaviourFit.draw_exits`)."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from are_stats.behaviour import BehaviourFit, grid_geodesic


def _door_fit(exits: list[tuple[float, float]], bandwidth: float) -> BehaviourFit:
    """The crossing room (20 x 12 m, 0.5 m cells, doors in the west and east walls at
    y 4.5-7.5 m) with one track per exit, each entering by the west door at (0.25, 6.25)
    and leaving at its exit."""
    free = np.zeros((24, 40), bool)
    free[1:-1, 1:-1] = True
    free[9:15, 0] = free[9:15, -1] = True
    one, k = np.ones(1), len(exits)
    return BehaviourFit(
        classes=("person",), cell=0.5, origin=np.zeros(2), free=free, dt=0.4 * one,
        speed_mu=math.log(1.2) * one, speed_sigma=0.1 * one, run_fraction=0 * one,
        run_mu=np.nan * one, run_sigma=np.nan * one, beta=4.0 * one, beta_se=0 * one,
        slip=0.1 * one, slip_se=0 * one, loglik=0 * one, n_moves=one.astype(int),
        n_tracks=k * one.astype(int), n_fit_tracks=one.astype(int),
        n_epochs=200 * one.astype(int), bandwidth_entry=one, bandwidth_exit=bandwidth * one,
        fit_seconds=0 * one, track_class=np.zeros(k, int),
        entry_xy=np.tile([0.25, 6.25], (k, 1)), exit_xy=np.array(exits, float),
    )  # fmt: skip


def test_an_exit_jittered_past_the_maps_edge_takes_the_edge_cell() -> None:
    """An exit in a door at the map's east edge (x = 20 m), jittered by ``N(0, 0.5^2)``:
    the kernel's mass past the edge goes to the edge, so the door's edge cell (x 19.5-20 m)
    holds ``P(z > -1) = Phi(1) = 0.841`` of the exits (the y jitter leaves the 3 m door with
    probability 0.003, neglected). Redrawing the jitters past the edge, as before, gave
    ``P(-1 < z < 0) / P(z < 0) = 0.683``: exits 0.16 m further in on average, shorter
    walks. 4,000 draws: binomial sd 0.006, the check allows 4 (false-failure rate 6e-5)."""
    n = 4000
    fit = _door_fit([(20.0, 6.0)], 0.5)
    entries = np.tile([12, 1], (n, 1))
    exits = fit.draw_exits(np.random.default_rng(26), np.zeros(n, int), entries, np.full(n, 1e9))
    assert (exits >= 0).all()
    assert fit.free[exits[:, 0], exits[:, 1]].all()
    p = stats.norm.cdf(1.0)
    share = np.mean(exits[:, 1] == 39)
    assert abs(share - p) < 4 * math.sqrt(p * (1 - p) / n)


def test_a_stay_too_short_for_every_exit_walks_towards_the_likeliest() -> None:
    """Two tracks from the west door: one crossing to the east door (19.5 m), one leaving
    where it entered (in its entry cell: no move, never an exit). Given a stay of 5 s (6 m
    at 1.2 m/s, a reach of 12 moves) no draw is an exit within reach; each draw is taken
    as far towards it as the reach allows and one kept by the speed law at ``L / s``, so
    the person walks towards the east door (a cell one move from its entry means 0.1 m/s).
    Before, the reachable cell nearest to the last draw was taken: beside the entry for
    the half of the people whose last draw was the second track's exit, who then stood."""
    n = 50
    fit = _door_fit([(19.7, 6.0), (0.25, 6.25)], 0.05)
    entries = np.tile([12, 0], (n, 1))
    reach = np.full(n, 12.0)  # moves
    exits = fit.draw_exits(
        np.random.default_rng(3), np.zeros(n, int), entries, reach, stays=np.full(n, 5.0),
        speed_mu=math.log(1.2), speed_sigma=0.1,
    )  # fmt: skip
    moves = fit.geodesic(entries[:1])[0][exits[:, 0], exits[:, 1]]
    assert (moves <= reach).all()
    assert (moves >= 10).all()  # at the reach's far end, towards the east door


def _one_by_one(fit, rng, cls, ent, reach, stays, mu, sigma, tries=20):
    """draw_exits with stays as it was written before issue 29: artefact after artefact,
    each try's draws and checks, then ``rng.choice`` of the speed weights."""
    out = np.full((len(ent), 2), -1, np.int64)
    h, w = fit.free.shape
    dist = fit.geodesic(ent)
    for i in range(len(ent)):
        d_i = dist[i]
        if not d_i[d_i >= 1].min(initial=np.inf) <= reach[i]:
            continue
        m_of = np.flatnonzero(fit.track_class == cls[i])
        if not m_of.size:
            cand = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
            out[i] = cand[rng.integers(len(cand))]
            continue
        e_xy = fit.cell_to_world(ent[i])[0]
        logw = (
            -0.5 * ((fit.entry_xy[m_of] - e_xy) ** 2).sum(axis=1) / fit.bandwidth_entry[cls[i]] ** 2
        )
        p = np.exp(logw - logw.max())
        p /= p.sum()
        all_xy = np.empty((tries, 2))
        for t in range(tries):
            all_xy[t] = fit.exit_xy[m_of[rng.choice(len(m_of), p=p)]]
            all_xy[t] += rng.normal(0.0, fit.bandwidth_exit[cls[i]], 2)
        cc = np.floor((all_xy - fit.origin) / fit.cell).astype(int)[:, ::-1]
        inside = (cc[:, 0] >= 0) & (cc[:, 0] < h) & (cc[:, 1] >= 0) & (cc[:, 1] < w)
        for t in np.flatnonzero(~inside):  # past the edge: the clipped cell, else the nearest open
            cc[t] = np.clip(cc[t], 0, [h - 1, w - 1])
            if not np.isfinite(d_i[cc[t, 0], cc[t, 1]]):
                open_ = np.argwhere(np.isfinite(d_i))
                d2 = ((fit.cell_to_world(open_) - all_xy[t]) ** 2).sum(axis=1)
                cc[t] = open_[np.argmin(d2)]
        d_c = d_i[cc[:, 0], cc[:, 1]]
        cands = list(cc[(d_c >= 1) & (d_c <= reach[i])])
        if not cands:
            within = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
            d2 = ((all_xy[:, None, :] - fit.cell_to_world(within)[None]) ** 2).sum(axis=2)
            cands = list(within[np.argmin(d2, axis=1)])
        cc = np.asarray(cands)
        geo = d_i[cc[:, 0], cc[:, 1]]
        manhattan = np.maximum(np.abs(cc - ent[i]).sum(axis=1), 1)
        length = np.hypot(*(fit.cell_to_world(cc) - e_xy).T) * geo / manhattan
        v = np.maximum(length / max(float(stays[i]), 1e-9), 1e-9)
        sd = max(float(sigma[i]) if np.isfinite(sigma[i]) else 0.1, 0.02)
        logw = -np.log(v) - 0.5 * ((np.log(v) - float(mu[i])) / sd) ** 2
        q = np.exp(logw - logw.max())
        out[i] = cc[rng.choice(len(cc), p=q / q.sum())]
    return out


def test_exits_given_stays_are_drawn_as_one_by_one() -> None:
    """draw_exits with stays makes every artefact's draws first, then checks and weighs
    them all at once (issue 29): the exits and the generator's state after are those of
    drawing artefact after artefact. 1,000 artefacts at both doors and in the room, two
    classes (the second without tracks: any cell within reach), stays from 0.1 s (no
    exit within reach, or no move at all) to a minute, a NaN speed sd; tracks leaving by
    both doors and jittered past the map's edge."""
    r = np.random.default_rng(5)
    k = 40
    xy = np.column_stack([r.choice([0.1, 19.9, 10.0], k), r.uniform(4, 8, k)])
    fit = _door_fit([tuple(p) for p in xy], 0.5)
    fit.entry_xy = np.column_stack([r.choice([0.25, 19.75], k), r.uniform(4.5, 7.5, k)])
    for name in ("bandwidth_entry", "bandwidth_exit", "speed_mu", "speed_sigma"):
        setattr(fit, name, np.r_[getattr(fit, name), getattr(fit, name)])
    n = 1000
    cls = (r.random(n) < 0.1).astype(int)
    free = np.argwhere(fit.free)
    ent = np.where(r.random((n, 1)) < 0.7, [[12, 0]], free[r.integers(len(free), size=n)])
    ent[r.random(n) < 0.3] = [10, 39]
    stays = np.exp(r.uniform(np.log(0.1), np.log(60.0), n))
    reach = np.floor(0.9 * np.floor(stays * 1.5 / fit.cell) * math.sqrt(2))
    mu = np.full(n, math.log(1.2))
    sigma = np.where(r.random(n) < 0.05, np.nan, 0.1)
    got_rng, want_rng = np.random.default_rng(11), np.random.default_rng(11)
    got = fit.draw_exits(got_rng, cls, ent, reach, stays=stays, speed_mu=mu, speed_sigma=sigma)
    want = _one_by_one(fit, want_rng, cls, ent, reach, stays, mu, sigma)
    assert (got >= 0).any(axis=1).sum() > 2 * n // 3 and (got < 0).all(axis=1).any()
    np.testing.assert_array_equal(got, want)
    assert got_rng.bit_generator.state == want_rng.bit_generator.state


def _bfs_lengths(free, cell):
    """4-connected path lengths from ``cell`` by breadth-first search (reference)."""
    h, w = free.shape
    out = np.full((h, w), np.inf)
    out[cell] = 0.0
    todo = [cell]
    for r, c in todo:
        for rr, cc in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if 0 <= rr < h and 0 <= cc < w and free[rr, cc] and out[rr, cc] == np.inf:
                out[rr, cc] = out[r, c] + 1.0
                todo.append((rr, cc))
    return out


def test_grid_geodesic_equals_breadth_first_search_as_the_mask_changes():
    """The graph of a free mask is kept between calls (one source at a time is the walkers'
    use): path lengths equal a breadth-first search's, also when the same array is edited
    in place between calls or another mask of the same shape comes."""
    rng = np.random.default_rng(7)
    free = rng.random((9, 13)) > 0.3
    for _ in range(4):
        cells = np.argwhere(free)[rng.integers(0, free.sum(), 3)]
        got = grid_geodesic(free, cells)
        assert got.dtype == np.float64 and got.shape == (3, *free.shape)
        for k, cell in enumerate(cells):
            np.testing.assert_array_equal(got[k], _bfs_lengths(free, tuple(cell)))
        free[rng.integers(9), rng.integers(13)] ^= True  # the same array, another mask
