"""Benchmark: people walking with local interaction, ours vs pysocialforce (issue 26).

Two measurements:

1. **The issue's target**: 1,000 artefacts arriving over one hour (each crossing a 30 m
   square at its own preferred speed), walked at 10 Hz with the social force
   (:func:`are_stats.behaviour.social_force_tracks`): at most 10 s on 2 cores. Printed for
   the first call in the process (compiling included) and the second, wall and CPU
   seconds (user + system of all threads: on a loaded machine the CPU time is the one to
   compare).
2. **Side by side on the same crowd**: ``n`` pedestrians alive together, crossing a 30 m
   square for 60 s at 10 Hz (600 steps), ours against pysocialforce 1.1 (the Extended
   Social Force model in NumPy + numba, all pairs), with the same relaxation time and step;
   no groups and no obstacles in either. Printed: seconds per run and the ratio. The two
   models differ in their pair term (pysocialforce: Moussaid's velocity-dependent
   ellipses; ours: anticipated circles), so this compares the cost of a step, not paths.

Run ``python -m tests.benchmarks.bench_social`` (``--quick``: smaller crowds).
"""

from __future__ import annotations

import os
import sys
import time

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import numpy as np
import pandas as pd

import are_stats  # noqa: F401
from are_stats.behaviour import social_force_tracks

#: Issue 26: 1,000 artefacts over an hour at 10 Hz, seconds on 2 cores.
_TARGET = 10.0


def _plans(rng: np.random.Generator, n: int, t_max: float, dt: float = 0.5) -> pd.DataFrame:
    """``n`` straight crossings of a 30 m square, arrivals uniform on [0, t_max]."""
    rows = []
    for i in range(n):
        t0 = rng.uniform(0.0, t_max)
        a, b = rng.uniform(0, 30, 2), rng.uniform(0, 30, 2)
        v = rng.lognormal(np.log(1.3), 0.12)
        dur = max(np.hypot(*(b - a)), 1.0) / v
        t = t0 + np.arange(0.0, np.ceil(dur / dt) + 1) * dt
        f = np.clip((t - t0) / dur, 0, 1)[:, None]
        xy = a + (b - a) * f
        rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
    return pd.concat(rows, ignore_index=True)


def _hour(quick: bool) -> None:
    n = 200 if quick else 1000
    plans = _plans(np.random.default_rng(0), n, 3600.0)
    for label in ("first call (compiling)", "second call"):
        t0, c0 = time.perf_counter(), time.process_time()
        social_force_tracks(plans, dt=0.1)
        sec, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(
            f"  {n} artefacts over 1 h at 10 Hz, {label}: {sec:.2f} s wall, {cpu:.2f} s CPU"
            f" (target {_TARGET:g} s)"
        )


def _crowd(n: int) -> tuple[pd.DataFrame, np.ndarray]:
    """``n`` people on the square at once for 60 s: our plans and pysocialforce's state."""
    rng = np.random.default_rng(n)
    a, b = rng.uniform(0, 30, (n, 2)), rng.uniform(0, 30, (n, 2))
    v = rng.lognormal(np.log(1.3), 0.12, n)
    t = np.arange(0.0, 60.0 + 1e-9, 0.1)
    rows = []
    for i in range(n):
        dur = max(np.hypot(*(b[i] - a[i])), 1.0) / v[i]
        xy = a[i] + (b[i] - a[i]) * np.clip(t / dur, 0, 1)[:, None]
        rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
    direction = (b - a) / np.hypot(*(b - a).T)[:, None]
    state = np.column_stack([a, direction * v[:, None], b])
    return pd.concat(rows, ignore_index=True), state


def _peer(state: np.ndarray, steps: int) -> float:
    import pysocialforce as psf

    config = os.path.join(os.path.dirname(__file__), "_psf_bench.toml")
    with open(config, "w") as fh:  # step 0.1 s, no groups, relaxation 0.5 s as ours
        fh.write("[scene]\nenable_group = false\nstep_width = 0.1\ntau = 0.5\n")
    try:
        sim = psf.Simulator(state.copy(), groups=None, obstacles=None, config_file=config)
        sim.step(1)  # numba's first compile outside the timing
        sim = psf.Simulator(state.copy(), groups=None, obstacles=None, config_file=config)
        t0, c0 = time.perf_counter(), time.process_time()
        sim.step(steps)
        return time.perf_counter() - t0, time.process_time() - c0
    finally:
        os.remove(config)


def main(quick: bool = False) -> None:
    print("1. the issue's crowd:")
    _hour(quick)
    print("2. the same crowd side by side (60 s at 10 Hz, everybody present):")
    try:
        import logging

        import pysocialforce  # noqa: F401

        logging.getLogger().setLevel(logging.WARNING)  # it sets the root logger to DEBUG
        have_peer = True
    except ImportError:
        have_peer = False
        print("  pysocialforce is not installed (pip install -e '.[bench]'): ours only")
    for n in (20, 100) if quick else (20, 100, 400):
        plans, state = _crowd(n)
        social_force_tracks(plans, dt=0.1)  # compile this crowd's size
        t0, c0 = time.perf_counter(), time.process_time()
        social_force_tracks(plans, dt=0.1)
        ours, cpu = time.perf_counter() - t0, time.process_time() - c0
        line = f"  n={n:4d}: ours {ours:.3f} s ({cpu:.3f} s CPU)"
        if have_peer:
            peer, peer_cpu = _peer(state, 600)
            line += (
                f", pysocialforce {peer:.3f} s ({peer_cpu:.3f} s CPU), ratio {peer / ours:.1f}x"
                f" wall, {peer_cpu / cpu:.1f}x CPU"
            )
        print(line, flush=True)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
