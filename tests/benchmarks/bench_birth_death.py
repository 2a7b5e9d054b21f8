"""Benchmark: panel MLE of the immigration-death process N(t), ours vs birdepy (2.0 where
the environment allows it; the bench extra takes 1.0 while torch's sympy refuses mpmath 1.4).

Data: 1001 counts observed every minute from the stationary immigration-death process with
lambda = 2.0 per minute and mu = 0.1 per minute (``death="linear"``, birdepy's ``'M/M/inf'``).

* ours: :func:`are_stats.fit_birth_death` (exact binomial x Poisson likelihood over the
  distinct (n_prev, n_next) pairs, Newton's method with closed-form gradient and Hessian);
* birdepy ``framework='dnm'`` with ``likelihood='Erlang'`` (first call reported apart: numba
  compiles) and ``likelihood='expm'``;
* reference: the exact MLE by scipy Nelder-Mead on the exact likelihood (tight tolerances),
  used to report each estimate's relative error.

Also times :meth:`are_stats.BirthDeath.simulate` for 10,000 paths (about 2,000 events each).
Run with ``python -m tests.benchmarks.bench_birth_death`` (``--quick`` for fewer repeats).
"""

from __future__ import annotations

import statistics
import sys
import time
import warnings

import jax
import numpy as np
from scipy.optimize import minimize

import are_stats
from are_stats import BirthDeath, birth_death_loglik, fit_birth_death

LAM, MU = 2.0, 0.1


def _median_time(fn, reps: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def _data() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(1001.0)
    n0 = int(np.random.default_rng(1).poisson(LAM / MU))
    n = BirthDeath(LAM, MU).simulate(jax.random.key(1), n0, 1000.0, 1, times=t)[0]
    return t, n


def _exact_mle(t, n) -> np.ndarray:
    res = minimize(
        lambda x: -birth_death_loglik(*np.exp(x), t, n),
        np.log([1.0, 0.2]),
        method="Nelder-Mead",
        options={"xatol": 1e-11, "fatol": 1e-11, "maxiter": 5000},
    )
    return np.exp(res.x)


def _nelder_mead(t, n) -> np.ndarray:
    """The peer measurement's method: scipy Nelder-Mead (default tolerances), exact likelihood."""
    res = minimize(lambda x: -birth_death_loglik(*np.exp(x), t, n), np.log([1.0, 0.2]),
                   method="Nelder-Mead")  # fmt: skip
    return np.exp(res.x)


def main(quick: bool = False) -> None:
    reps = 5 if quick else 21
    t, n = _data()
    exact = _exact_mle(t, n)
    pairs = len({(a, b) for a, b in zip(n[:-1], n[1:], strict=True)})
    print(f"birth-death panel MLE: 1001 minutely counts, lambda={LAM}, mu={MU}, "
          f"{pairs} distinct pairs")  # fmt: skip
    print(f"exact MLE (scipy Nelder-Mead, tight tol): lambda={exact[0]:.6f}, mu={exact[1]:.7f}")

    rows = []
    fit_birth_death(t, n)  # warm-up
    t_ours, fit = _median_time(lambda: fit_birth_death(t, n), reps * 5)
    ours = np.array([fit.birth_rate, fit.death_rate])
    rows.append(("are_stats fit_birth_death", t_ours, ours))

    t_nm, est_nm = _median_time(lambda: _nelder_mead(t, n), max(3, reps // 4))
    rows.append(("scipy Nelder-Mead, exact likelihood", t_nm, est_nm))

    peers = {}
    try:
        from importlib.metadata import version

        import birdepy as bd

        bd_version = version("birdepy")

        def run(method):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                est = bd.estimate(list(t), list(n), [1.0, 0.2], [[1e-3, 20.0], [1e-4, 2.0]],
                                  framework="dnm", model="M/M/inf", likelihood=method)  # fmt: skip
            return np.asarray(est.p, dtype=float)

        t0 = time.perf_counter()
        run("Erlang")
        first = time.perf_counter() - t0
        print(f"birdepy 'Erlang' first call (numba compilation): {first:.2f} s")
        for method, r in (("Erlang", reps // 2 + 1), ("expm", max(3, reps // 4))):
            run(method)
            t_m, est = _median_time(lambda m=method: run(m), r)
            peers[method] = t_m
            rows.append((f"birdepy {bd_version} dnm '{method}'", t_m, est))
    except ImportError:
        print("birdepy is not installed (pip install '.[bench]'): comparing with Nelder-Mead only")

    print(f"{'method':40s} {'time/fit':>10s} {'lambda':>10s} {'mu':>10s} {'rel.err':>9s}")
    for name, sec, est in rows:
        err = float(np.max(np.abs(est / exact - 1)))
        print(f"{name:40s} {sec * 1e3:8.2f}ms {est[0]:10.5f} {est[1]:10.6f} {err:9.1e}")
    best_name, best = min(peers.items(), key=lambda kv: kv[1]) if peers else ("NM", t_nm)
    print(f"speed-up vs birdepy best ('{best_name}'): {best / t_ours:.1f}x; "
          f"vs Nelder-Mead: {t_nm / t_ours:.1f}x; our estimate within "
          f"{np.max(np.abs(ours / exact - 1)):.1e} of the exact MLE")  # fmt: skip

    # simulation: 10,000 paths of ~2,000 events each (stationary start, t_end = 500)
    proc = BirthDeath(LAM, MU)
    n_paths, t_end = 10_000 if not quick else 2_000, 500.0
    n0 = np.random.default_rng(2).poisson(LAM / MU, n_paths)
    obs = np.linspace(0.0, t_end, 11)
    proc.simulate(jax.random.key(0), n0, t_end, n_paths, times=obs)  # compile
    t_sim, _ = _median_time(
        lambda: proc.simulate(jax.random.key(3), n0, t_end, n_paths, times=obs), 5
    )
    events = proc.simulate_events(jax.random.key(3), n0[:200], t_end, 200).n_events.mean()
    print(f"simulate: {n_paths} paths x ~{events:.0f} events (t_end={t_end}): {t_sim:.2f} s "
          f"(jax {jax.__version__}, are_stats {are_stats.__version__})")  # fmt: skip


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
