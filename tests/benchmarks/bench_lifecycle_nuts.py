"""Benchmark: NUTS on the life-cycle model, ours vs stock numpyro vs PyMC, in ESS per second.

Model (the same in every implementation): arrival rate lambda ~ Gamma(1, 1) with a Poisson
arrival count in the window, leave rate mu ~ Gamma(1, 1) with exponential stays,
right-censored at t1 (log-survival); about 2000 arrivals. The conjugate posterior is the
truth. Each run: 4 chains, 1000 warm-up + 1000 draws.

* ours: :func:`are_stats.fitting.fit_lifecycle_nuts` (numpyro's NUTS kernel in one
  ahead-of-time compiled program), chain methods parallel (pmap over the host devices,
  chains vectorised within a device), vectorized and sequential; "cold" runs clear the
  cache of compiled programs first, "cached" runs reuse it;
* stock numpyro: ``numpyro.infer.MCMC`` on the same model, chain_method="vectorized";
* PyMC (if installed): ``pm.sample(chains=4, cores=2)``.

ESS/s = min bulk ESS over (lambda, mu) / wall time, with and without compilation (for
PyMC: ``sample_stats.attrs["sampling_time"]``; for ours: the ``sampling_time`` attribute).
Medians of ``n_runs`` runs after one warm-up run. Run with
``python -m tests.benchmarks.bench_lifecycle_nuts``.
"""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import time  # noqa: E402
import warnings  # noqa: E402

import jax  # noqa: E402
import numpy as np  # noqa: E402

from are_stats.fitting import _nuts, fit_lifecycle_nuts  # noqa: E402
from are_stats.traffic import (  # noqa: E402
    LifecycleData,
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    lifecycle_model,
    simulate_lifecycle,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

PRIORS = LifecyclePriors()
NAMES = ("arrival_rate", "leave_rate")


def _data() -> LifecycleData:
    d = simulate_lifecycle(
        jax.random.key(2000), 2.0, 0.05, [1.0], [1.0], (0.0, 1000.0), area=1.0,
        stationary_start=False,
    )  # fmt: skip
    return LifecycleData(d.t_arrive, d.t_leave, d.window, d.area)


def _summary(posterior: dict[str, np.ndarray], truth: dict) -> tuple[float, float]:
    """min bulk ESS and max |mean - truth| in posterior sd units."""
    ess = min(float(az.ess(np.asarray(posterior[n]), method="bulk")) for n in NAMES)
    err = max(abs(float(np.mean(posterior[n])) - truth[n][0]) / truth[n][1] for n in NAMES)
    return ess, err


def _ours(data, method, seed, warmup, samples, cold):
    if cold:  # forget compiled programs: every run pays tracing and compilation
        _nuts._CACHE.clear()
    tic = time.perf_counter()
    idata = fit_lifecycle_nuts(
        jax.random.key(seed), data, PRIORS, num_warmup=warmup, num_samples=samples,
        num_chains=4, chain_method=method, stationary_start=False, num_prior_draws=0,
    )  # fmt: skip
    wall = time.perf_counter() - tic
    post = {n: idata.posterior[n].values for n in NAMES}
    return post, wall, float(idata.sample_stats.attrs["sampling_time"])


def _stock_numpyro(data, seed, warmup, samples):
    from numpyro.infer import MCMC, NUTS

    tic = time.perf_counter()
    mcmc = MCMC(
        NUTS(lifecycle_model), num_warmup=warmup, num_samples=samples, num_chains=4,
        chain_method="vectorized", progress_bar=False,
    )  # fmt: skip
    mcmc.run(jax.random.key(seed), data=data, priors=PRIORS, stationary_start=False)
    post = {n: np.asarray(v) for n, v in mcmc.get_samples(group_by_chain=True).items()}
    return post, time.perf_counter() - tic, float("nan")


def _pymc(data, seed, warmup, samples):
    import pymc as pm
    import pytensor.tensor as pt

    n_arr = int((~data.truncated).sum())
    departed = (~data.censored).astype(float)
    tic = time.perf_counter()
    with pm.Model():
        lam = pm.Gamma("arrival_rate", alpha=PRIORS.arrival_shape, beta=PRIORS.arrival_rate)
        mu = pm.Gamma("leave_rate", alpha=PRIORS.leave_shape, beta=PRIORS.leave_rate)
        pm.Poisson("n_arrivals", mu=lam * data.area * data.duration, observed=n_arr)
        pm.Potential("stays", pt.sum(departed * pt.log(mu) - mu * data.dwell))
        idata = pm.sample(
            draws=samples, tune=warmup, chains=4, cores=2, random_seed=seed,
            progressbar=False, compute_convergence_checks=False,
        )  # fmt: skip
    wall = time.perf_counter() - tic
    post = {n: idata.posterior[n].values for n in NAMES}
    return post, wall, float(idata.sample_stats.attrs["sampling_time"])


def _pymc_available() -> bool:
    try:
        import pymc  # noqa: F401
    except ImportError:
        return False
    return True


def main(quick: bool = False) -> None:
    """Run every implementation side by side and print ESS/s, ratios and accuracy."""
    import logging

    logging.getLogger("pymc").setLevel(logging.ERROR)
    n_runs = 2 if quick else 5
    warmup = samples = 1000
    data = _data()
    lam, mu = conjugate_arrival_rate(data, PRIORS), conjugate_leave_rate(data, PRIORS)
    truth = {"arrival_rate": (lam.mean, lam.sd), "leave_rate": (mu.mean, mu.sd)}
    print(
        f"life-cycle NUTS: {int((~data.truncated).sum())} arrivals, "
        f"{int(data.censored.sum())} censored; 4 chains x ({warmup} warm-up + {samples} draws); "
        f"{jax.local_device_count()} JAX host devices, {os.cpu_count()} CPUs; "
        f"median of {n_runs} runs after a warm-up run"
    )
    impls = {}
    for method in ("parallel", "vectorized", "sequential"):
        for cold in (True, False):
            label = f"ours {method} {'cold' if cold else 'cached'}"
            impls[label] = lambda s, m=method, c=cold: _ours(data, m, s, warmup, samples, c)
    impls["numpyro MCMC vectorized"] = lambda s: _stock_numpyro(data, s, warmup, samples)
    if _pymc_available():
        impls["PyMC 2 cores"] = lambda s: _pymc(data, s, warmup, samples)
    else:
        print("PyMC not installed: peer rows skipped (pip install 'are-stats[bench]')")
    rows = {}
    for name, fn in impls.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fn(0)  # warm-up (imports, caches)
            results = [fn(seed) for seed in range(1, n_runs + 1)]
        walls = np.array([r[1] for r in results])
        samp = np.array([r[2] for r in results])
        stats = [_summary(r[0], truth) for r in results]
        ess = np.array([s[0] for s in stats])
        err = max(s[1] for s in stats)
        rows[name] = (
            float(np.median(walls)),
            float(np.median(ess / walls)),
            float(np.median(samp)),
            float(np.median(ess / samp)),
            float(np.median(ess)),
            err,
        )
    ref = rows.get("PyMC 2 cores")
    print(
        f"{'implementation':<26}{'wall s':>8}{'ESS/s':>9}{'sampling s':>12}{'ESS/s excl.':>13}"
        f"{'min ESS':>9}{'max |err|/sd':>14}{'x PyMC':>8}"
    )
    for name, (wall, eps, samp, eps_x, ess, err) in rows.items():
        ratio = f"{eps / ref[1]:8.2f}" if ref else f"{'-':>8}"
        samp_s = f"{samp:12.3f}" if np.isfinite(samp) else f"{'-':>12}"
        eps_x_s = f"{eps_x:13.0f}" if np.isfinite(eps_x) else f"{'-':>13}"
        print(f"{name:<26}{wall:8.2f}{eps:9.0f}{samp_s}{eps_x_s}{ess:9.0f}{err:14.3f}{ratio}")
    print(
        "x PyMC: ratio of ESS/s including compilation. cold: every run traces and compiles; "
        "cached: the compiled program is reused (same settings, data padded to the same "
        "bucket). |err|/sd: largest distance of a posterior mean from the conjugate "
        "posterior mean, in posterior sd (MC error ~ 1/sqrt(ESS))."
    )


if __name__ == "__main__":
    main()
