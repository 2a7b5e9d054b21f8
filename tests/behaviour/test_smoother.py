"""The tracks' smoother (constant-acceleration Kalman filter and RTS smoother) against
truth: exact on quadratic paths, each track as if smoothed alone, and the smoothed
acceleration of a noisy path within its posterior's spread of the truth."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.behaviour._smoother import smooth_samples, smooth_tracks


def test_quadratic_paths_come_back_exactly_whatever_the_noise_assumed():
    """A path of constant acceleration is the smoother's own model without jerk: its
    position, velocity and acceleration come back at every sample, ends included."""
    t = np.arange(30) * 0.4
    path = 2.0 - 0.7 * t + 0.15 * t**2
    for noise in (0.0, 0.05):
        out = smooth_tracks(path[:, None, None], np.array([30]), 0.4, noise, 10.0)[:, :, 0, 0]
        assert out[0] == pytest.approx(path, abs=1e-6)
        assert out[1] == pytest.approx(-0.7 + 0.3 * t, abs=1e-5)
        assert out[2] == pytest.approx(np.full(30, 0.3), abs=1e-5)


def test_tracks_of_different_lengths_are_smoothed_as_if_alone():
    """Padded together (aligned at their first sample), each track gets what it gets on
    its own; entries past a track's end are 0 and what the padding holds is ignored."""
    rng = np.random.default_rng(0)
    lengths = np.array([40, 7, 23])
    pad = rng.normal(0.0, 1.0, (40, 3, 2)) * 50.0  # junk past each end
    alone = []
    for i, n in enumerate(lengths):
        walk = np.cumsum(rng.normal(0.0, 0.1, (n, 2)), axis=0)
        pad[:n, i] = walk
        alone.append(smooth_tracks(walk[:, None, :], np.array([n]), 0.1, 0.03, 5.0)[:, :, 0])
    out = smooth_tracks(pad, lengths, 0.1, 0.03, 5.0)
    for i, n in enumerate(lengths):
        assert out[:, :n, i] == pytest.approx(alone[i], abs=1e-9)
        assert np.all(out[:, n:, i] == 0.0)


def test_the_smoothed_acceleration_of_a_noisy_walk_is_near_the_truth():
    """A sinusoidal walk (amplitude 0.5 m/s^2 of acceleration, period 6 s) seen every
    0.1 s with 5 cm of noise: the smoothed acceleration's error has an rms of about a
    third of the signal's (0.29-0.37 over 20 noise seeds; bound 0.45), where the second
    difference's noise alone is 12 m/s^2, 35 times the signal (seeded)."""
    rng = np.random.default_rng(3)
    t = np.arange(800) * 0.1
    w = 2 * np.pi / 6.0
    path = 1.2 * t + (0.5 / w**2) * (1 - np.cos(w * t))
    acc = 0.5 * np.cos(w * t)
    seen = path + rng.normal(0.0, 0.05, t.size)
    out = smooth_tracks(seen[:, None, None], np.array([800]), 0.1, 0.05, 1.0)[:, :, 0, 0]
    inner = slice(20, -20)
    err = out[2][inner] - acc[inner]
    assert np.sqrt(np.mean(err**2)) < 0.45 * np.sqrt(np.mean(acc[inner] ** 2))
    second = np.diff(seen, 2) / 0.01
    assert np.std(second - acc[1:-1]) > 10.0


def test_samples_row_by_row_are_smoothed_as_their_tracks_alone():
    """Rows of tracks of very different lengths (batched by length inside), in shuffled
    order: each row gets what its track smoothed alone gives at its index."""
    rng = np.random.default_rng(1)
    lengths = [300, 5, 9, 120, 4, 4, 60]
    walks = [np.cumsum(rng.normal(0.0, 0.1, (n, 2)), axis=0) for n in lengths]
    track = np.concatenate([np.full(n, i) for i, n in enumerate(lengths)])
    index = np.concatenate([np.arange(n) for n in lengths])
    values = np.concatenate(walks)
    mix = rng.permutation(track.size)
    out = smooth_samples(values[mix], track[mix], index[mix], 0.4, 0.05, 3.0)
    for i, n in enumerate(lengths):
        alone = smooth_tracks(walks[i][:, None, :], np.array([n]), 0.4, 0.05, 3.0)[:, :, 0]
        rows = np.flatnonzero(track[mix] == i)
        assert out[:, rows] == pytest.approx(alone[:, index[mix][rows]], abs=1e-9)
