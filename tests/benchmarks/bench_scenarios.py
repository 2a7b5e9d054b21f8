"""Scenario generation: 1e4 scenarios of one hour at ~50 live artefacts.

Ours: :func:`are_stats.scenarios.generate_scenarios` (every scenario at once, NumPy).
Peer: the straightforward per-scenario loop a user would write with NumPy and pandas
(one draw, arrivals, lifetimes, marks, positions and a DataFrame per scenario, then
``pd.concat``). Both draw the same law; accuracy is checked on N(t) at half the horizon
(stationary mean lambda*nu/mu = 50). Median of >= 5 runs after a warm-up.

Run: ``python -m tests.benchmarks.bench_scenarios [--quick]``.
"""

from __future__ import annotations

import sys
import tempfile
import time

import numpy as np
import pandas as pd

from are_stats.scenarios import generate_scenarios, scenario_counts, write_scenes

HORIZON = 3600.0
MU = 1 / 600.0  # 10 min mean stay
AREA = 400.0
LIVE = 50.0
LAM = LIVE * MU / AREA


def _params(s: int = 200) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {
        "arrival_rate": LAM * rng.gamma(400, 1 / 400, s),
        "leave_rate": MU * rng.gamma(400, 1 / 400, s),
        "mix_weights": rng.dirichlet([200, 200, 200, 200, 200], s),
        "mix_rates": np.array([15.0, 7, 3, 21, 5]) * rng.gamma(400, 1 / 400, (s, 5)),
    }


def peer_loop(seed: int, p: dict, n: int, horizon: float, mask: np.ndarray, res: float):
    """Per-scenario Python loop, the way a user would write it."""
    rng = np.random.default_rng(seed)
    iy, ix = np.nonzero(mask)
    nu = iy.size * res * res
    s = len(p["arrival_rate"])
    frames = []
    for i in range(n):
        d = i % s
        lam, mu = p["arrival_rate"][d] * nu, p["leave_rate"][d]
        n0 = rng.poisson(lam / mu)
        m = rng.poisson(lam * horizon)
        t_arr = np.concatenate([np.zeros(n0), np.sort(rng.uniform(0, horizon, m))])
        t_leave = t_arr + rng.exponential(1 / mu, n0 + m)
        cls = rng.choice(len(p["mix_weights"][d]), size=n0 + m, p=p["mix_weights"][d])
        mark = rng.poisson(p["mix_rates"][d][cls])
        cell = rng.integers(0, iy.size, n0 + m)
        x = (ix[cell] + rng.random(n0 + m)) * res
        y = (iy[cell] + rng.random(n0 + m)) * res
        yaw = rng.integers(0, 4, n0 + m) * (np.pi / 2)
        frames.append(
            pd.DataFrame(
                {
                    "scenario": i,
                    "artefact": np.arange(n0 + m),
                    "class": cls,
                    "mark": mark,
                    "t_arrive": t_arr,
                    "t_leave": t_leave,
                    "x": x,
                    "y": y,
                    "yaw": yaw,
                    "truncated": np.arange(n0 + m) < n0,
                    "censored": t_leave > horizon,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _median_time(fn, repeats: int) -> tuple[float, object]:
    fn()  # warm-up
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main(quick: bool = False) -> None:
    n = 1000 if quick else 10_000
    repeats = 3 if quick else 5
    p = _params()
    mask = np.ones((20, 20), dtype=bool)  # 400 m^2 at 1 m cells
    t_ours, ours = _median_time(
        lambda: generate_scenarios(0, p, n, HORIZON, free_mask=mask, resolution=1.0), repeats
    )
    t_peer, peer = _median_time(lambda: peer_loop(0, p, n, HORIZON, mask, 1.0), repeats)
    n_ours = scenario_counts(ours, [HORIZON / 2])[:, 0]
    n_peer = scenario_counts(peer, [HORIZON / 2], n_scenarios=n)[:, 0]
    print(
        f"{n} scenarios x {HORIZON:.0f} s, ~{LIVE:.0f} live artefacts, "
        f"{len(ours) / n:.0f} artefacts per scenario (median of {repeats} runs)"
    )
    print(
        f"  ours  generate_scenarios  {t_ours:8.2f} s  {n / t_ours:10.0f} scenarios/s  "
        f"N(T/2) mean {n_ours.mean():.2f} var {n_ours.var():.2f}"
    )
    print(
        f"  peer  per-scenario loop   {t_peer:8.2f} s  {n / t_peer:10.0f} scenarios/s  "
        f"N(T/2) mean {n_peer.mean():.2f} var {n_peer.var():.2f}"
    )
    print(
        f"  speed-up ours/peer: {t_peer / t_ours:.1f}x  (stationary law: mean = var = "
        f"{LIVE:.0f} up to the posterior spread)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        write_scenes(ours, tmp, {"fit": "benchmark"})
        print(
            f"  write artefacts.parquet + manifest.yaml: {time.perf_counter() - t0:.2f} s "
            f"({len(ours)} rows)"
        )


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
