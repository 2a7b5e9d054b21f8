"""BehaviourFit's exit draws (:meth:`~are_stats.behaviour.BehaviourFit.draw_exits`)."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from are_stats.behaviour import BehaviourFit


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
