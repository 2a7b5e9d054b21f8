"""Benchmark: Poisson-mixture EM (eq. 1) on the paper's Fig. 2 mixture, ours vs peers.

1e6 marks from rates (15, 7, 3, 21, 5) with equal weights, tol 1e-8 on the change of the
mean log-likelihood per mark. Compared side by side in one run (median of 5 runs after a
warm-up):

* ``are_stats.fit_mixture_em`` (histogram of distinct marks, JAX, 16 restarts, SQUAREM);
* the same with plain EM steps (``accelerate=False``);
* pomegranate 1.1 ``GeneralMixtureModel`` of ``Poisson`` (torch, float64; its ``tol`` is on
  the total log-likelihood, so it gets ``1e-8 * n``);
* a plain NumPy EM over every sample (written here; one start at the quantiles).

Every log-likelihood is recomputed from the fitted parameters with scipy. Also reports
NUTS (``fit_mixture_nuts``) time and bulk ESS per second on 1e4 marks.

Run: ``python -m tests.benchmarks.bench_mixture_em`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
from scipy.special import gammaln, logsumexp  # noqa: E402

RATES = np.array([15.0, 7.0, 3.0, 21.0, 5.0])
TOL = 1e-8


def simulate(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.poisson(RATES[rng.integers(0, RATES.size, n)])


def loglik(marks: np.ndarray, weights: np.ndarray, rates: np.ndarray) -> float:
    """Total log-likelihood from scipy (one formula for every implementation)."""
    values, counts = np.unique(marks, return_counts=True)
    with np.errstate(divide="ignore"):
        lp = logsumexp(np.log(weights) + stats.poisson.logpmf(values[:, None], rates), axis=1)
    return float(np.sum(counts * lp))


def numpy_em_per_sample(
    marks: np.ndarray, k: int, tol: float = TOL, max_iter: int = 10_000
) -> tuple[np.ndarray, np.ndarray, int]:
    """Textbook EM over every sample (n x k responsibilities each iteration)."""
    x = marks.astype(np.float64)[:, None]
    log_fact = -gammaln(x + 1.0)
    rates = np.quantile(marks, (np.arange(k) + 0.5) / k) * (1 + 0.01 * np.arange(k))
    weights = np.full(k, 1.0 / k)
    last, it = -np.inf, 0
    while it < max_iter:
        it += 1
        joint = np.log(weights) + x * np.log(rates) - rates + log_fact
        lse = logsumexp(joint, axis=1, keepdims=True)
        resp = np.exp(joint - lse)
        mean_ll = float(lse.mean())
        nk = resp.sum(axis=0)
        weights = nk / marks.size
        rates = (resp * x).sum(axis=0) / nk
        if abs(mean_ll - last) < tol:
            break
        last = mean_ll
    order = np.argsort(rates)
    return weights[order], rates[order], it


def pomegranate_em(marks: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, int]:
    import torch
    from pomegranate.distributions import Poisson
    from pomegranate.gmm import GeneralMixtureModel

    x = torch.as_tensor(marks.reshape(-1, 1), dtype=torch.float64)
    model = GeneralMixtureModel(
        [Poisson() for _ in range(k)],
        max_iter=10_000,
        tol=TOL * marks.size,
        random_state=0,
    ).double()  # nn.Module.double(): every buffer, hence every parameter, in float64
    iters = {"n": 0}
    summarize = model.summarize

    def counting(*args, **kwargs):
        iters["n"] += 1
        return summarize(*args, **kwargs)

    model.summarize = counting
    model.fit(x)
    assert model.priors.dtype == torch.float64  # float64 throughout (follows the data)
    weights = model.priors.detach().numpy().astype(np.float64)
    weights = weights / weights.sum()
    rates = np.array([float(d.lambdas.reshape(-1)[0]) for d in model.distributions])
    assert model.distributions[0].lambdas.dtype == torch.float64
    order = np.argsort(rates)
    return weights[order], rates[order], iters["n"] - 1


def timed(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main(quick: bool = False, peer_repeats: int | None = None) -> None:
    import jax

    from are_stats import fit_mixture_em, fit_mixture_nuts

    n = 100_000 if quick else 1_000_000
    repeats = 1 if quick else 5
    peer_repeats = repeats if peer_repeats is None else peer_repeats
    marks = simulate(n)
    print(f"Poisson-mixture EM, {n} marks, rates {RATES.tolist()}, equal weights, tol {TOL}")
    print(
        f"distinct marks: {np.unique(marks).size}; median of {repeats} run(s) after warm-up "
        f"(peers: {peer_repeats})\n"
    )

    rows = []
    fit_mixture_em(marks, 5)  # warm-up (jit compile)
    t, fit = timed(lambda: fit_mixture_em(marks, 5), repeats)
    rows.append(("are_stats EM, histogram, 16 restarts, SQUAREM", t, fit.n_iter, fit))
    fit_mixture_em(marks, 5, accelerate=False)
    t, fit = timed(lambda: fit_mixture_em(marks, 5, accelerate=False), repeats)
    rows.append(("are_stats EM, histogram, 16 restarts, plain", t, fit.n_iter, fit))
    results = []
    for name, t, it, f in rows:
        results.append((name, t, it, loglik(marks, f.weights, f.rates)))

    try:
        import pomegranate  # noqa: F401

        pomegranate_em(marks[:1000], 5)  # warm-up (torch)
        t, (w, r, it) = timed(lambda: pomegranate_em(marks, 5), peer_repeats)
        results.append(("pomegranate 1.1 GeneralMixtureModel, float64", t, it, loglik(marks, w, r)))
    except ImportError as err:
        print(f"pomegranate not available ({err}); comparing to the NumPy EM only")
    t, (w, r, it) = timed(lambda: numpy_em_per_sample(marks, 5), peer_repeats)
    results.append(("NumPy EM over every sample, 1 start", t, it, loglik(marks, w, r)))

    ours = results[0][1]
    print(f"{'implementation':52s} {'time [s]':>10s} {'iter':>6s} {'log-lik':>16s} {'x ours':>9s}")
    for name, t, it, ll in results:
        print(f"{name:52s} {t:10.4f} {it:6d} {ll:16.2f} {t / ours:9.0f}")
    best_peer = max(ll for _, _, _, ll in results[2:])
    print(f"\nours - best peer log-lik: {results[0][3] - best_peer:+.3f}")

    # NUTS over the histogram, 1e4 marks
    import arviz as az

    m = simulate(10_000, seed=1)
    kw = dict(num_warmup=500, num_samples=1000, num_chains=2)
    fit_mixture_nuts(jax.random.key(0), m, 5, **kw)  # warm-up (compile)
    nuts_times, ess = [], []
    for i in range(1 if quick else 3):
        t0 = time.perf_counter()
        idata = fit_mixture_nuts(jax.random.key(i), m, 5, **kw)
        nuts_times.append(time.perf_counter() - t0)
        e = az.ess(idata, method="bulk")
        ess.append(min(float(e["mix_rates"].min()), float(e["mix_weights"].min())))
    tn = statistics.median(nuts_times)
    rhat = az.rhat(idata)
    print(
        f"\nNUTS, 5 components, 1e4 marks ({np.unique(m).size} distinct), 2 chains x 1000 draws "
        f"(+500 warm-up), chain_method={idata.posterior.attrs['chain_method']}: "
        f"{tn:.2f} s (incl. compile), min bulk ESS {statistics.median(ess):.0f}, "
        f"{statistics.median(ess) / tn:.0f} ESS/s, max r_hat "
        f"{float(max(rhat['mix_rates'].max(), rhat['mix_weights'].max())):.3f}, "
        f"mean leapfrog steps {float(idata.sample_stats['n_steps'].mean()):.0f}"
    )


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
