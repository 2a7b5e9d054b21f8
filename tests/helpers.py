"""Shared test helpers: one tolerance helper and seeded goodness-of-fit checks.

Statistical tests state their false-failure rate: with a fixed seed the outcome is
deterministic, and ``ALPHA`` is the probability that a correct implementation would fail
the test for a random seed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

ALPHA = 1e-3  # false-failure rate of every seeded goodness-of-fit test


def assert_allclose(actual, desired, rtol: float = 1e-7, atol: float = 0.0, err_msg: str = ""):
    """The one tolerance helper for array comparisons."""
    np.testing.assert_allclose(
        np.asarray(actual), np.asarray(desired), rtol=rtol, atol=atol, err_msg=err_msg
    )


def chisquare_gof(samples, pmf, min_expected: float = 5.0, alpha: float = ALPHA) -> float:
    """Chi-square test of integer ``samples`` against ``pmf(k)``.

    Bins with expected count below ``min_expected`` are pooled into the tails so the
    chi-square approximation holds. Returns the p-value and asserts ``p > alpha``.
    """
    samples = np.asarray(samples).ravel().astype(np.int64)
    n = samples.size
    kmax = int(max(samples.max(), 1))
    # extend support until the remaining tail mass is negligible
    while pmf(np.arange(kmax + 1)).sum() < 1 - 1e-12 and kmax < 10**6:
        kmax *= 2
    ks = np.arange(kmax + 1)
    expected = n * pmf(ks)
    observed = np.bincount(samples, minlength=kmax + 1)[: kmax + 1].astype(float)
    # pool low bins from the left and right
    edges = []
    acc = 0.0
    for k in ks:
        acc += expected[k]
        if acc >= min_expected:
            edges.append(k)
            acc = 0.0
    if not edges:
        raise AssertionError("too few samples for a chi-square test")
    edges[-1] = kmax
    obs_b, exp_b, lo = [], [], 0
    for e in edges:
        obs_b.append(observed[lo : e + 1].sum())
        exp_b.append(expected[lo : e + 1].sum())
        lo = e + 1
    exp_b = np.asarray(exp_b)
    exp_b[-1] += n - exp_b.sum()  # tail mass beyond kmax
    obs_b = np.asarray(obs_b)
    stat = float(((obs_b - exp_b) ** 2 / exp_b).sum())
    p = float(stats.chi2.sf(stat, df=len(exp_b) - 1))
    assert p > alpha, f"chi-square goodness of fit failed: stat={stat:.2f}, p={p:.2e}"
    return p


#: A sweep small enough to run in seconds: two tasks of one short mission.
TINY_SWEEP = {
    "name": "tiny",
    "map": "courtyard",
    "seed": 0,
    "replicates": 1,
    "scenario": {
        "arrival_rate": 0.0005,
        "leave_rate": 0.02,
        "mix_weights": [0.6, 0.4],
        "mix_rates": [0.5, 3.0],
        "start": "stationary",
    },
    "robot": {"radius": 0.3, "speed": 0.5},
    "mission": {"n_goals": 1, "time_limit": 10.0, "perception": "all"},
    "planner": {"algorithm": "RRTConnect", "range": 2.0},
    "factors": {"scenario.arrival_rate": [0.0002, 0.0008]},
}


#: ``are-stats fit`` options that fit the paper's model alone (no candidate NUTS runs): for
#: tests whose subject is not the choice of traffic models.
PAPER_MODELS = ["--arrivals", "poisson", "--lifetimes", "exponential", "--positions", "uniform"]


def crossing_world(seed: int, n: int = 60, *, speed_sd: float = 0.05, noise: float = 0.03):
    """A 20 m x 12 m room (0.5 m map cells) with a door in the west and the east wall;
    people walk straight from door to door at 1.2 m/s times a log-normal of sd ``speed_sd``,
    one every 100 s, with ``noise`` (m) of tracker noise, sampled at 2.5 Hz (the
    synthetic pedestrians of the behaviour tests and of the docs' motion-checks figure).

    Returns
    -------
    tracks : pandas.DataFrame
        ``id, t, x, y``.
    free : (24, 40) bool
        The map's free cells (row = y).
    """
    import pandas as pd

    rng = np.random.default_rng(seed)
    free = np.zeros((24, 40), bool)
    free[1:-1, 1:-1] = True
    free[9:15, 0] = True  # west door, y in [4.5, 7.5]
    free[9:15, -1] = True  # east door
    rows = []
    for i in range(n):
        y0, y1 = rng.uniform(4.7, 7.3, 2)
        a, b = np.array([0.3, y0]), np.array([19.7, y1])
        if i % 2:
            a, b = b, a
        v = 1.2 * np.exp(speed_sd * rng.standard_normal())
        dist = np.hypot(*(b - a))
        t = np.arange(0.0, dist / v, 0.4)
        t = np.append(t, dist / v)
        xy = a + np.outer(t / t[-1], b - a)
        if noise > 0:
            xy = xy + rng.normal(0, noise, (t.size, 2))
        rows.append(pd.DataFrame({"id": i, "t": 100.0 * i + t, "x": xy[:, 0], "y": xy[:, 1]}))
    return pd.concat(rows, ignore_index=True), free


def crossing_artefacts(walkers: pd.DataFrame, every: float = 6.0) -> tuple[pd.DataFrame, float]:
    """The people of a tracks table (``id, t, x, y``, e.g. :func:`crossing_world`'s) as one
    scenario's ``person`` artefacts: each enters where its track starts and stays as long
    as its track lasts, one arriving every ``every`` s (so that they meet on the way).

    Returns
    -------
    artefacts : pandas.DataFrame
        A scenarios folder's ``artefacts.parquet`` rows, scenario 0.
    horizon : float
        One second past the last leave (s).
    """
    g = walkers.groupby("id", sort=True)
    first, last = g.first(), g.last()
    t_arr = every * np.arange(len(first))
    art = pd.DataFrame({
        "scenario": 0, "artefact": np.arange(len(first)), "class": 0, "mark": 0,
        "t_arrive": t_arr, "t_leave": t_arr + (last["t"] - first["t"]).to_numpy(),
        "x": first["x"].to_numpy(), "y": first["y"].to_numpy(), "yaw": 0.0, "label": "person",
    })  # fmt: skip
    return art, float(art["t_leave"].max()) + 1.0


def courtyard_artefacts(**over) -> pd.DataFrame:
    """Three artefacts of two scenarios in the courtyard map's free space (a scenarios
    folder's ``artefacts.parquet``), with any column replaced by ``over``."""
    cols = {
        "scenario": np.array([0, 0, 1], np.int32),
        "artefact": np.array([0, 1, 0], np.int32),
        "class": np.array([0, 1, 0], np.int32),
        "mark": np.array([0, 3, 1], np.int64),
        "t_arrive": [0.0, 50.0, 10.0],
        "t_leave": [150.0, 250.0, 120.0],
        "x": [-12.0, -8.0, -11.0],
        "y": [-8.0, -4.0, -6.0],
        "yaw": [0.0, 1.0, 2.0],
    }
    cols.update(over)
    return pd.DataFrame(cols)


def variation_inputs(tracks: pd.DataFrame) -> tuple[list, np.ndarray, float, list]:
    """What ``fit_behaviour`` hands its within-person variation estimators
    (``_speed_variation``, ``_heading_variation``): each track's ``(t, xy)`` in id order,
    its speed, the log's tracker noise and each sample's crowded flag."""
    # lazy: are_stats.fitting costs about 3 s to import, and most tests here do not need it
    from are_stats.fitting import tracker_noise
    from are_stats.fitting._behaviour import _crowded, _track_speed

    noise = tracker_noise(tracks)
    tracks = tracks.sort_values(["id", "t"]).reset_index(drop=True)
    near = _crowded(tracks)
    seen, crowded = [], []
    for _, g in tracks.groupby("id"):
        seen.append((g["t"].to_numpy(float), g[["x", "y"]].to_numpy(float)))
        crowded.append(near[g.index.to_numpy()])
    speeds = np.array([_track_speed(t, xy, noise) for t, xy in seen])
    return seen, speeds, noise, crowded
