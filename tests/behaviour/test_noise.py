"""The tracker's position noise read from tracks (issue 26), against known noise levels."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import tracker_noise


def _walks(seed: int, speed: float, rate: float, noise: float, n: int = 30) -> pd.DataFrame:
    """``n`` people walking 60 s at ``speed`` along smoothly winding paths (heading
    ``h0 + 0.6 sin(0.5 t + phase)``: turning rates up to 0.3 rad/s), seen at ``rate`` Hz
    with white Gaussian noise of sd ``noise`` per coordinate."""
    rng = np.random.default_rng(seed)
    fine = np.arange(0.0, 60.0, 0.01)
    rows = []
    for i in range(n):
        heading = rng.uniform(0, 2 * np.pi) + 0.6 * np.sin(0.5 * fine + rng.uniform(0, 2 * np.pi))
        x = np.cumsum(speed * np.cos(heading)) * 0.01
        y = np.cumsum(speed * np.sin(heading)) * 0.01
        every = round(1.0 / (rate * 0.01))
        t, x, y = fine[::every], x[::every], y[::every]
        x = x + rng.normal(0, noise, t.size)
        y = y + rng.normal(0, noise, t.size)
        rows.append(pd.DataFrame({"id": i, "t": t, "x": x, "y": y}))
    return pd.concat(rows, ignore_index=True)


def _second_differences(tracks: pd.DataFrame) -> float:
    """The estimate tracker_noise replaced: robust scale of second differences / sqrt(6)."""
    d = np.concatenate(
        [np.diff(g[["x", "y"]].to_numpy(), n=2, axis=0).ravel() for _, g in tracks.groupby("id")]
    )
    return 1.4826 * float(np.median(np.abs(d))) / math.sqrt(6.0)


def _autocovariances(tracks: pd.DataFrame) -> float:
    """The realism table's former estimate: ``s^2 = (c_2 - c_1) / 5`` from the
    autocovariances of second differences at lags 1 and 2."""
    c1 = c2 = 0.0
    n1 = n2 = 0
    for _, g in tracks.groupby("id"):
        d2 = np.diff(g[["x", "y"]].to_numpy(), n=2, axis=0)
        c1, n1 = c1 + float((d2[1:] * d2[:-1]).sum()), n1 + d2[1:].size
        c2, n2 = c2 + float((d2[2:] * d2[:-2]).sum()), n2 + d2[2:].size
    return math.sqrt(max((c2 / n2 - c1 / n1) / 5.0, 0.0))


@pytest.mark.parametrize("rate", [2.5, 10.0])
@pytest.mark.parametrize("speed", [0.5, 1.3, 2.0])
@pytest.mark.parametrize("noise", [0.01, 0.05])
def test_the_noise_is_recovered_at_every_rate_and_speed(rate, speed, noise):
    """Within 10% of the truth (1 cm and 5 cm, 2.5 and 10 Hz, slow to fast walkers).
    False failure: the estimate's sd is about 1.5% of the noise here (900 to 3,600
    fourth differences per coordinate, MAD efficiency 37%), so 10% is over 6 sd."""
    tracks = _walks(7, speed, rate, noise)
    assert tracker_noise(tracks) == pytest.approx(noise, rel=0.1)
    assert tracker_noise(tracks.sample(frac=1.0, random_state=1)) == tracker_noise(tracks)


def test_second_differences_and_their_autocovariances_miss_it_on_slow_sampling():
    """Why fourth differences: at 2.5 Hz a fast walker's turns (up to 0.6 m/s^2 of lateral
    acceleration, 10 cm per second difference) dwarf 1 cm of noise in second
    differences, and break the autocovariances' assumption that the path's accelerations
    are as correlated at lag 1 as at lag 2 (2.4 cm and 0.79 cm, against 0.99 cm from
    fourth differences); at 10 Hz all three agree."""
    slow = _walks(7, 2.0, 2.5, 0.01)
    assert tracker_noise(slow) == pytest.approx(0.01, rel=0.1)
    assert _second_differences(slow) > 0.015
    assert _autocovariances(slow) < 0.0085
    fast = _walks(7, 2.0, 10.0, 0.01)
    for estimate in (tracker_noise, _second_differences, _autocovariances):
        assert estimate(fast) == pytest.approx(0.01, rel=0.1)


def test_no_noise_and_too_short_tracks():
    exact = _walks(3, 1.3, 10.0, 0.0)
    assert tracker_noise(exact) < 1e-4
    assert tracker_noise(exact.groupby("id").head(4)) == 0.0  # nothing with 5 samples in a row
    # a scenario column keeps equal ids of different scenarios apart
    two = pd.concat([exact.assign(scenario=0), exact.assign(scenario=1, x=exact["x"] + 50)])
    assert tracker_noise(two) < 1e-4
