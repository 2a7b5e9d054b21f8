"""Fitted walkers walk at the log's speeds (issue 26): people crossing a room at speeds of
a known between-person law, walked again by the one assembly
(:func:`~are_stats.scenarios.scene_tracks`, the fitted behaviour: exit drawn given the
entry and the stay, route, social force), as the realism table and the motion checks walk
them.

The generated median speed and between-person spread are those of the log. Over seeds
10-21 (40 walkers each) the generated median speed was 0.35% above the log's (sd 0.16%)
and the spread (log-sd of the walkers' speeds) 0.95 of the log's (sd 0.045); the checks
allow 1% (4 sd from the mean: a false-failure rate of about 3e-5 for a random seed) and a
ratio of 0.8-1.2 (3.3 sd: about 5e-4). Before the exits' reach counted 4-connected moves
as a length and before people arrived walking, seeds 0-3 read 0.8-3.6% slow and a spread
of 0.53-0.77 of the log's (the law's fast walkers had no exit within reach).
"""

from __future__ import annotations

import math

import jax
import numpy as np
import pandas as pd

from are_stats.behaviour import BehaviourFit
from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.fitting import track_statistics
from are_stats.scenarios import scene_tracks
from tests.helpers import crossing_world

MU, SIGMA = math.log(1.2), 0.08  # the between-person law (log m/s)


def _crossings(seed: int, n: int = 40) -> tuple[pd.DataFrame, np.ndarray]:
    """``n`` people crossing a 20 x 12 m room from door to door (0.5 m cells), one every
    100 s, straight at a speed of the law, sampled at 2.5 Hz, leaving at their exit."""
    return crossing_world(seed, n, speed_sd=SIGMA, noise=0.0)


def _known_fit(log: pd.DataFrame, free: np.ndarray) -> BehaviourFit:
    """The behaviour that made ``log``: the law, its entries and exits. The exit kernel is
    narrow (5 cm) so that the check sees the timing, not the kernel (a jitter past the
    map's edge takes the edge cell, :meth:`BehaviourFit.draw_exits`; it used to be
    redrawn, and the walkers read about 1% slow with 0.5 m)."""
    g = log.groupby("id", sort=True)
    first, last = g.first(), g.last()
    n, one = len(first), np.ones(1)
    return BehaviourFit(
        classes=("person",), cell=0.5, origin=np.zeros(2), free=free, dt=0.4 * one,
        speed_mu=MU * one, speed_sigma=SIGMA * one, run_fraction=0 * one,
        run_mu=np.nan * one, run_sigma=np.nan * one, beta=4.0 * one, beta_se=0 * one,
        slip=0.1 * one, slip_se=0 * one, loglik=0 * one, n_moves=one.astype(int),
        n_tracks=one.astype(int) * n, n_fit_tracks=one.astype(int),
        n_epochs=200 * one.astype(int), bandwidth_entry=one, bandwidth_exit=0.05 * one,
        fit_seconds=0 * one, track_class=np.zeros(n, int),
        entry_xy=first[["x", "y"]].to_numpy(), exit_xy=last[["x", "y"]].to_numpy(),
    )  # fmt: skip


def test_fitted_walkers_walk_at_the_logs_speeds() -> None:
    seed = 12
    log, free = _crossings(seed)
    g = log.groupby("id", sort=True)
    first, last = g.first(), g.last()
    art = pd.DataFrame({
        "scenario": 0, "artefact": np.arange(len(first)), "t_arrive": first["t"].to_numpy(),
        "t_leave": last["t"].to_numpy(), "x": first["x"].to_numpy(),
        "y": first["y"].to_numpy(), "yaw": 0.0, "label": "person",
    })  # fmt: skip
    walked = scene_tracks(
        jax.random.key(seed), art, OccupancyGrid(np.where(free, 0, 100), 0.5),
        load_catalogue(), float(art["t_leave"].max()) + 1.0, behaviours="fitted",
        fitted=_known_fit(log, free),
    )  # fmt: skip
    seen = track_statistics(log)["speed"].to_numpy()
    made = track_statistics(walked.drop(columns="scenario"))["speed"].to_numpy()
    assert made.size == seen.size == 40
    assert abs(math.log(np.median(made) / np.median(seen))) < 0.01
    assert 0.8 < np.log(made).std() / np.log(seen).std() < 1.2
