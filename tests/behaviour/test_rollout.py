"""Rollouts: slip frequencies, goal reaching, following, collisions, tracks table."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from are_stats.behaviour import (
    GridMDP,
    cells_to_tracks,
    follow_rewards,
    rollout,
)
from tests.helpers import assert_allclose, chisquare_gof


def test_walk_reaches_reachable_goal_without_slip():
    rng = np.random.default_rng(0)
    occ = rng.random((9, 11)) < 0.2
    occ[4, :] = False
    occ[:, 5] = False
    mdp = GridMDP(occ, slip=0.0)
    goal = np.array([4, 5])
    free = np.argwhere(~occ)
    from scipy import ndimage

    labels, _ = ndimage.label(~occ)
    starts = free[labels[free[:, 0], free[:, 1]] == labels[4, 5]]
    starts = starts[(starts != goal).any(axis=1)]
    starts = np.column_stack([starts, rng.integers(0, 4, len(starts))])
    n = len(starts)
    sol = mdp.solve(np.tile(goal, (n, 1)), "walk", 60)
    states = rollout(jax.random.key(0), sol, starts, resolve=None)
    assert np.all(states[:, -1, :2] == goal)
    # and it goes there at once: the number of actions spent is the value's step count
    arrived = (states[:, :, :2] == goal).all(axis=2).argmax(axis=1)
    v = sol.v0[0][starts[:, 0], starts[:, 1], starts[:, 2]]
    assert_allclose(v, 1.0 - mdp.step_cost * arrived, rtol=0, atol=1e-5)
    # the value says the same: positive everywhere it can reach
    assert np.all(sol.v0[0][starts[:, 0], starts[:, 1], starts[:, 2]] > 0)


def test_slip_outcome_frequencies():
    # forward from the centre of an open 5 x 5 grid, heading east: outcomes east / north / south
    slip = 0.3
    mdp = GridMDP(np.zeros((5, 5), bool), slip=slip)
    n = 4000
    sol = mdp.solve(np.tile([2, 3], (n, 1)), "walk", 1)
    assert np.all(sol.policy[:, 0, 2, 2, 0] == 1)  # forward
    states = rollout(jax.random.key(1), sol, np.tile([2, 2, 0], (n, 1)), resolve=None)
    end = states[:, 1, :2]
    outcome = np.select(
        [(end == [2, 3]).all(1), (end == [3, 2]).all(1), (end == [1, 2]).all(1)], [0, 1, 2], -1
    )
    assert np.all(outcome >= 0)
    pmf = np.array([1 - slip, slip / 2, slip / 2])
    chisquare_gof(outcome, lambda k: np.where(k < 3, pmf[np.minimum(k, 2)], 0.0))


def test_follow_tracks_moving_target():
    occ = np.zeros((3, 30), bool)
    d = 25
    target = np.stack([np.ones(d + 1, int), np.arange(3, 3 + d + 1)], axis=1)
    mdp = GridMDP(occ, slip=0.0)
    r = follow_rewards(target, occ.shape)
    sol = mdp.solve(None, "follow", d, follow=[r])
    states = rollout(jax.random.key(2), sol, [[1, 0, 0]], resolve=None)
    dist = np.abs(states[0, :, :2] - target).sum(axis=1)
    assert dist[0] == 3
    assert np.all(dist[5:] <= 1) and np.all(dist[5:] >= 1)


def test_builder_resolution_on_cells_by_hand():
    """The default resolution (the AR-builder's, on cells): movers onto a shared cell go
    back, a chain reverts in rounds, a swap is reverted, a follower is not."""
    from are_stats import ARBuilder, OccupancyGrid
    from are_stats.behaviour import builder_resolver

    def resolve(prop, prev):
        b = ARBuilder(OccupancyGrid(np.zeros((8, 8)), 1.0))
        return builder_resolver(b)(0, np.array(prop), np.array(prev))

    prev = [[0, 0], [0, 2], [5, 5]]
    assert resolve([[0, 1], [0, 1], [5, 6]], prev).tolist() == [[0, 0], [0, 2], [5, 6]]
    # a chain: reverting one artefact can block another that moved into its old cell
    prev = [[0, 0], [0, 1], [0, 3]]
    assert resolve([[0, 1], [0, 2], [0, 2]], prev).tolist() == prev
    # a swap (passing through each other) is reverted too; following is not
    prev = [[0, 4], [0, 5]]
    assert resolve(prev[::-1], prev).tolist() == prev
    assert resolve([[0, 5], [0, 6]], prev).tolist() == [[0, 5], [0, 6]]


def test_rollout_resolves_collisions_in_a_corridor():
    occ = np.zeros((1, 12), bool)
    mdp = GridMDP(occ, slip=0.0)
    # two artefacts walk towards each other's side along a one-cell corridor
    sol = mdp.solve([[0, 11], [0, 0]], "walk", 20)
    states = rollout(jax.random.key(3), sol, [[0, 0, 0], [0, 11, 2]])
    cells = states[:, :, 1]
    assert np.all(cells[0] < cells[1])  # they neither meet nor pass through each other
    with pytest.raises(ValueError, match="resolve: expected a callable, 'builder' or None"):
        rollout(jax.random.key(3), sol, [[0, 0, 0], [0, 11, 2]], resolve="revert")
    free_run = rollout(jax.random.key(3), sol, [[0, 0, 0], [0, 11, 2]], resolve=None)
    assert free_run[0, -1, 1] == 11 and free_run[1, -1, 1] == 0  # without it they swap


def test_arrivals_and_tracks_table():
    mdp = GridMDP(np.zeros((4, 6), bool), slip=0.1)
    sol = mdp.solve([[3, 5], [0, 0]], ["run", "stop"], [6, 3])
    states = rollout(jax.random.key(4), sol, [[0, 0, 0], [2, 2, 1]], arrive=[0, 2])
    assert states.shape == (2, 7, 3)
    assert np.all(states[1, :2] == -1) and np.all(states[1, 2:6, :2] == [2, 2])
    assert np.all(states[1, 6] == -1)
    tracks = cells_to_tracks(
        states, scenario=7, ids=[10, 11], dt=0.5, resolution=0.1, origin=(1.0, -2.0)
    )
    assert list(tracks.columns) == ["scenario", "id", "t", "x", "y", "yaw"]
    assert len(tracks) == 7 + 4
    row = tracks[(tracks.id == 11)].iloc[0]
    assert row.t == pytest.approx(1.0)
    assert row.x == pytest.approx(1.0 + 2.5 * 0.1) and row.y == pytest.approx(-2.0 + 0.25)
    assert row.yaw == pytest.approx(np.pi / 2)


def test_rollout_bad_input():
    occ = np.zeros((3, 3), bool)
    occ[1, 1] = True
    mdp = GridMDP(occ)
    sol = mdp.solve([0, 0], "walk", 3)
    key = jax.random.key(0)
    with pytest.raises(ValueError, match="starts"):
        rollout(key, sol, [[0, 0]])
    with pytest.raises(ValueError, match=r"starts\[0\].*obstacle"):
        rollout(key, sol, [[1, 1, 0]])
    with pytest.raises(ValueError, match="heading"):
        rollout(key, sol, [[0, 1, 4]])
    with pytest.raises(ValueError, match="arrive"):
        rollout(key, sol, [[0, 1, 0]], arrive=[-1])
    with pytest.raises(ValueError, match="solution"):
        rollout(key, [], [[0, 1, 0]])


def test_builder_resolver_and_occupancy_grid():
    from are_stats import ARBuilder, OccupancyGrid
    from are_stats.behaviour import builder_resolver

    data = np.zeros((1, 11))
    grid = OccupancyGrid(data, 0.5, origin=(1.0, 2.0, 0.0))
    mdp = GridMDP(grid, slip=0.0)
    sol = mdp.solve([[0, 10], [0, 0]], "walk", 12)
    starts = [[0, 0, 0], [0, 10, 2]]
    free_run = rollout(jax.random.key(5), sol, starts, resolve=None)
    assert np.any((free_run[0, :, :2] == free_run[1, :, :2]).all(axis=1))  # they meet
    builder = ARBuilder(grid)
    states = rollout(jax.random.key(5), sol, starts, resolve=builder_resolver(builder))
    assert not np.any((states[0, :, :2] == states[1, :, :2]).all(axis=1))
    assert len(builder.log) > 0 and builder.log[0].cause == "artefact"
    tracks = cells_to_tracks(states, grid=grid)
    assert tracks.x.iloc[0] == pytest.approx(1.25) and tracks.y.iloc[0] == pytest.approx(2.25)
    with pytest.raises(ValueError, match="builder"):
        builder_resolver(object())


def test_epochs_after_everyone_left_are_absent_and_change_no_draw():
    """A rollout longer than the artefacts' stays (the walkers' legs pad it to a multiple
    of 64 epochs) is the rollout up to the last leaving epoch, then absent rows: the
    slip draws of the earlier epochs do not depend on how many epochs are asked for."""
    rng = np.random.default_rng(5)
    occ = np.zeros((6, 9), bool)
    occ[2, 2:6] = True
    mdp = GridMDP(occ, slip=0.4)
    sol = mdp.solve([[5, 8], [0, 8], [5, 0]], ["walk", "run", "walk"], [7, 12, 4], n_epochs=64)
    starts = np.array([[0, 0, 0], [5, 0, 1], [0, 8, 2]])
    arrive = np.array([0, 3, 9])
    key = jax.random.key(int(rng.integers(1 << 30)))
    short = rollout(key, sol, starts, 15, arrive=arrive, resolve=None)
    for n in (15, 40, 64):
        long = rollout(key, sol, starts, n, arrive=arrive, resolve=None)
        assert long.shape == (3, n + 1, 3)
        np.testing.assert_array_equal(long[:, :16], short)
        assert (long[:, 16:] == -1).all()
