"""Benchmark: NUTS on the traffic models (groups arrivals, gamma stays), ours vs PyMC, ESS/s.

Data: one synthetic log from a stated truth (:data:`TRUTH`, drawn by
:func:`are_stats.traffic.simulate_traffic_log`): groups arrive at ``1/30`` artefacts per
second on average on 400 m^2, sizes 1-4 with probabilities (0.6, 0.25, 0.1, 0.05); gamma
stays of mean 600 s and shape 4 (members' stays jittered by ``exp(0.15 e)``); a 3-hour
window (1 hour with ``--quick``) that opens on the stationary population; times on 0.4 s
ticks. About 360 artefacts (130 quick).

Models (the same in both implementations, on the same data, with the same priors):

* **arrivals, groups**: :func:`are_stats.traffic.arrival_model` with
  ``ArrivalSpec(groups=True)``: compound-Poisson counts on the log's ticks,
  ``event_rate = centre * exp(z)``, ``z ~ Normal(0, 3)``,
  ``group_size_probs ~ Dirichlet(1, ..., 1)`` on sizes ``1..K``;
* **stays, gamma**: :func:`are_stats.traffic.stay_model` with ``law="gamma"``: gamma stays
  through the window (right-censoring ``log S``, left-truncation by the equilibrium residual
  law ``log S(r) - log m``, ``log E[(T - r)^+] - log m`` for artefacts present the whole
  window, stays shorter than the resolution interval-censored), ``stay_mean = centre *
  exp(z)``, ``z ~ Normal(0, 3)``, ``stay_shape = exp(eta)``, ``eta ~ Normal(0, 1.5)``.

Our side calls :func:`are_stats.fitting.run_nuts` with the model arguments and starting
point that :func:`are_stats.fitting.fit_traffic` builds (:func:`traffic_kwargs`, from the
same helpers), without the pointwise log-likelihood (PyMC computes none either). The PyMC
side (:func:`pymc_arrival_model`, :func:`pymc_stay_model`) writes the likelihoods again in
PyTensor, independently (the convolution powers of the size law as a Toeplitz product, the
window terms as explicit sums over masks). Before anything is timed,
:func:`check_log_densities` asserts that both give the same log joint density (priors
included, on the constrained scale) at several parameter points, on the benchmark's log
and on a short-window log that has every window case (zero stays, present the whole
window).

Both sample 2 chains in parallel (ours: ``pmap`` over 2 XLA host devices; PyMC:
``cores=2``), the same warm-up and draws (1000 + 1000, quick 300 + 300), target acceptance
0.85, started from the empirical centre (``z = 0``, ``eta = 0``, uniform size law; PyMC
with ``init="adapt_diag"``, no jitter). ESS/s = min bulk ESS over the parameters (ArviZ,
the same function for both) / wall time of the call (model building and compilation
included; the process start-up, interpreter and imports, is printed apart). Each
implementation and model runs in fresh processes (``subprocess``), so compilation counts:

* **cold**: first call in a fresh process with an empty compile cache (JAX persistent
  cache dir / PyTensor ``base_compiledir``, both in a temporary folder): the first run
  after installing;
* **cold model**: first call in a fresh process whose cache holds only an unrelated
  one-parameter model's programs (for PyTensor: its own C modules, compiled once per
  installation): a model met for the first time;
* **warm, same process**: a second call in the cold run's process;
* **warm, new process**: first call in a fresh process that finds the cold run's cache
  (for ours, the JAX persistent cache as the CLI configures it:
  :func:`are_stats.configure_jax`, ``$XDG_CACHE_HOME/are_stats/jax``).

Last, ``are-stats fit courtyard_traffic --method em --no-figures`` (the
shipped log) end to end in a subprocess, three times on one fresh cache: first run, then
second and third runs with the caches warm (JAX's compiled programs and the traced ones
that :mod:`are_stats._program_cache` keeps), and the ratio first / second against issue
17's target of 4x.

Run with ``python -m tests.benchmarks traffic_nuts`` (or ``python -m
tests.benchmarks.bench_traffic_nuts``; ``--fit-only``: only the CLI fits). The timing
workers are this module run with ``--worker``. Benchmarks never assert on time. On 2
shared cores (load 6-8) the whole benchmark took about 21 minutes (10 of them the two CLI
fits, before the traced programs were kept), ``--quick`` about 6. The CLI fits alone
(``--fit-only``, 2 shared cores, load 1.2-2, 2026-11-25): first 68.3 s, second 18.6 s,
third 17.8 s (3.7x; other runs 3.6-4.2x); before the traced programs were kept, in the
same conditions, 57.9 s then 27.0 s (2.1x). On idle cores (2026-11-25, later): 65.4 s,
19.5 s, 18.2 s (3.4x / 3.6x) in the bench environment. Then three changes (2026-11-25,
third session): the 4 chains run 2 per core instead of all 4 in lock-step on one core
(the default chain method was "vectorized" with fewer devices than chains); every
candidate's program is compiled or loaded in background threads while the first ones
sample (:class:`are_stats.fitting.NutsPrefetch`); PSIS-LOO for all observations at once
(:func:`are_stats.fitting.psislw`, 1.2 s -> 0.5 s). Idle cores, bench environment, four
runs: first 57.7 / 48.3 / 45.6 / 55.4 s, second 13.8 / 11.9 / 12.2 / 12.6 s, third 15.8 /
13.5 / 11.9 / 14.3 s (first / second 3.7-4.4x; the first run also compiles its candidates
two at a time now). Without numba (a plain install; ArviZ compiles numba functions at import
in the bench environment): first 55.9 / 45.8 / 65.2 s, second 12.2 / 10.9 / 12.4 s, third
11.3 / 10.7 / 11.5 s (4.2-5.3x). A warm run is then about
3.3 s of imports (ArviZ 2.1 s), 4.3 s of sampling on both cores, 0.5 s of PSIS-LOO and
1.7 s of building and writing the InferenceData and its summary. On 2026-11-26 (an AMD EPYC
with AVX-512, idle cores, bench environment, six runs): first 43.1 / 44.2 / 36.3 / 37.8 /
34.0 / 41.1 s, second 9.6 / 8.9 / 9.0 / 8.2 / 8.6 / 8.5 s (4.5 / 4.9 / 4.0 / 4.6 / 3.9 / 4.9x;
third within 0.3 s of the second). Of a warm run's 8.5 s, the five NUTS candidates sample for
about 4.4 s, the gamma stays alone 1.3-1.9 s: their survival terms need the incomplete gamma
and its derivative in the shape, whose data-dependent loops cost about 200 us per gradient
on a few dozen censored stays (a fused one-loop version was tried: no faster on XLA's CPU
backend, which runs every carried array of a loop body as its own kernel). Later that day the
console script became :func:`are_stats.cli.main`, which sets Python's garbage-collector
thresholds to 10000/20/20 (a warm run had spent 1.1-1.3 s in about 1,000 collections, now
0.3-0.4 s in 70) and freezes every object after the command (the interpreter's final
collection at exit had taken 1.1 s): three runs, first 38.1 / 39.3 / 37.1 s, second 8.0 /
7.6 / 7.5 s (4.7 / 5.1 / 4.9x), third within 0.1 s of the second.
"""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import argparse  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

#: The synthetic log's truth (events per m^2 per s follows from the artefact rate).
TRUTH = {
    "artefact_rate": 1.0 / 30.0,  # artefacts per second
    "area": 400.0,
    "group_size_probs": (0.6, 0.25, 0.1, 0.05),
    "stay_mean": 600.0,
    "stay_shape": 4.0,
    "group_stay_sd": 0.15,
    "resolution": 0.4,
}
SEED = 20261124
MODELS = ("arrivals", "stays")
#: Parameters whose min bulk ESS is reported, per model.
PARAMS = {"arrivals": ("event_rate", "group_size_probs"), "stays": ("stay_mean", "stay_shape")}


def _event_rate() -> float:
    """Group (event) rate per m^2 per s of :data:`TRUTH`."""
    p = np.asarray(TRUTH["group_size_probs"])
    mean_size = float(np.dot(np.arange(1, p.size + 1), p))
    return TRUTH["artefact_rate"] / TRUTH["area"] / mean_size


def make_log(duration: float = 10800.0, seed: int = SEED) -> Any:
    """The benchmark's synthetic log (seeded: every process draws the same one).

    Parameters
    ----------
    duration : float
        Window length (s); the window is ``[0, duration]``.
    seed : int

    Returns
    -------
    LifecycleData
    """
    from are_stats.traffic import TrafficLaws, simulate_traffic_log

    laws = TrafficLaws(arrivals="groups", lifetimes="gamma", group_stay_sd=TRUTH["group_stay_sd"])
    draw = {
        "event_rate": _event_rate(),
        "stay_mean": TRUTH["stay_mean"],
        "stay_shape": TRUTH["stay_shape"],
        "group_size_probs": np.asarray(TRUTH["group_size_probs"]),
    }
    return simulate_traffic_log(
        np.random.default_rng(seed), draw, laws, (0.0, float(duration)), TRUTH["area"],
        resolution=TRUTH["resolution"],
    )  # fmt: skip


def edge_log() -> Any:
    """A short-window log with every case of the stay likelihood (for the check only).

    A 600 s window (artefacts present the whole window, left-truncated and right-censored
    ones) plus one artefact whose recorded stay is zero (interval-censored at the
    resolution).
    """
    from are_stats.traffic import LifecycleData

    d = make_log(600.0, seed=3)
    grp = np.asarray(d.group)
    return LifecycleData(
        t_arrive=np.append(d.t_arrive, 100.0),
        t_leave=np.append(d.t_leave, 100.0),
        window=d.window,
        area=d.area,
        group=np.append(grp, grp.max() + 1),
    )


def traffic_kwargs(data: Any) -> dict[str, tuple[dict, dict]]:
    """Model arguments and starting points, built as :func:`fit_traffic` builds them.

    Parameters
    ----------
    data : LifecycleData

    Returns
    -------
    dict
        ``{"arrivals": (kwargs, init), "stays": (kwargs, init)}`` for
        :func:`arrival_model` (groups) and :func:`stay_model` (gamma).
    """
    from are_stats.fitting._traffic import _bin_width, _empirical_rate, time_resolution
    from are_stats.traffic._models import ArrivalSpec, arrival_units, stay_units

    t0, t1 = data.window
    res = time_resolution(data.t_arrive, data.t_leave, [t0, t1])
    if res <= 0:
        res = (t1 - t0) * 1e-6
    units = arrival_units(
        data.t_arrive, data.window, data.area, res, _bin_width(data), group=data.group
    )
    max_tick = int(np.max(units.tick_count))
    n_ticks = int(np.sum(units.tick_weight))
    spec = ArrivalSpec(groups=True)
    arrivals = (
        {
            "units": units,
            "spec": spec,
            "rate_centre": _empirical_rate(np.sum(units.tick_count), data, True, n_ticks),
            "log_area": float(np.log(data.area)),
            "max_group": max(max_tick, 1),
        },
        {"event_rate_z": 0.0, "group_size_probs": np.full(max_tick, 1.0 / max_tick)},
    )
    departed = int(np.sum(~data.censored))
    mean_centre = float(np.sum(data.dwell)) / max(departed, 1)
    stays = (
        {
            "units": stay_units(data.dwell, data.censored, data.truncated),
            "law": "gamma",
            "mean_centre": mean_centre if mean_centre > 0 else res,
            "resolution": res,
        },
        {"stay_mean_z": 0.0, "stay_shape_eta": 0.0},
    )
    return {"arrivals": arrivals, "stays": stays}


# ----------------------------------------------------------------------------- PyMC peer


def pymc_arrival_model(kwargs: dict) -> Any:
    """The groups arrival model of ``kwargs`` (see :func:`traffic_kwargs`) in PyMC.

    Compound-Poisson ticks: for a tick with ``c`` arrivals,
    ``log sum_{k=1..K} (rho delta)^k / k! p^{*k}(c)``; empty ticks and the rest of the
    window give ``-rho T`` (``rho = event_rate * area``). ``p^{*k}`` are the convolution
    powers of the size law, here products with the lower-triangular Toeplitz matrix of
    ``p`` (ours: a ``scan`` of ``jnp.convolve``).

    Parameters
    ----------
    kwargs : dict
        Arguments of :func:`are_stats.traffic.arrival_model`.

    Returns
    -------
    pymc.Model
    """
    import pymc as pm
    import pytensor.tensor as pt
    from scipy.special import gammaln

    u = kwargs["units"]
    k_max = int(kwargs["max_group"])
    real = np.asarray(u.tick_weight) > 0
    counts = np.asarray(u.tick_count)[real].astype(np.int64)
    exposure = float(np.sum(np.asarray(u.bin_exposure)[np.asarray(u.bin_weight) > 0]))
    log_delta_area = float(u.log_delta) + float(kwargs["log_area"])
    lag = np.subtract.outer(np.arange(k_max + 1), np.arange(k_max + 1))  # c - c'
    sizes = np.arange(1, k_max + 1)
    with pm.Model() as model:
        z = pm.Normal("event_rate_z", 0.0, 3.0)
        rate = pm.Deterministic("event_rate", kwargs["rate_centre"] * pt.exp(z))
        p = pm.Dirichlet("group_size_probs", a=np.ones(k_max))
        p0 = pt.concatenate([pt.zeros(1), p])  # P(size = 0..K)
        toeplitz = pt.where(lag >= 0, p0[np.clip(lag, 0, k_max)], 0.0)
        rows = [p0]
        for _ in range(k_max - 1):
            rows.append(pt.dot(toeplitz, rows[-1]))
        log_conv = pt.log(pt.maximum(pt.stack(rows), 1e-300))  # (K, K + 1)
        lam = pt.log(rate) + log_delta_area
        terms = sizes[None, :] * lam - gammaln(sizes + 1.0)[None, :] + log_conv[:, counts].T
        pm.Potential("arrival_units", pt.sum(pt.logsumexp(terms, axis=1)) - rate * exposure)
    return model


def pymc_stay_model(kwargs: dict) -> Any:
    """The gamma stay model of ``kwargs`` (see :func:`traffic_kwargs`) in PyMC.

    One explicit sum per window case (``Q`` the regularised upper incomplete gamma,
    ``x = k r / m``):

    * seen arriving and leaving, stay ``d >= delta``: the gamma log density;
      ``d < delta``: ``log P(k, k delta / m)``;
    * seen arriving, still there at the end: ``log Q(k, k d / m)``;
    * there at the start, left ``r`` later: ``log Q(k, x) - log m``;
    * there the whole window (``r = t1 - t0``): ``log(m Q(k + 1, x) - r Q(k, x)) - log m``.

    Parameters
    ----------
    kwargs : dict
        Arguments of :func:`are_stats.traffic.stay_model` (``law="gamma"``).

    Returns
    -------
    pymc.Model
    """
    import pymc as pm
    import pytensor.tensor as pt

    u = kwargs["units"]
    res = float(kwargs["resolution"])
    real = np.asarray(u.weight) > 0
    stay = np.asarray(u.stay, float)[real]
    cen = np.asarray(u.censored, bool)[real]
    tru = np.asarray(u.truncated, bool)[real]
    seen = ~cen & ~tru
    short = seen & (stay < res) if res > 0 else np.zeros_like(seen)
    full = stay[seen & ~short]
    n_short = int(short.sum())
    cens = stay[cen & ~tru]
    trunc = stay[tru & ~cen]
    whole = stay[tru & cen]
    with pm.Model() as model:
        z = pm.Normal("stay_mean_z", 0.0, 3.0)
        m = pm.Deterministic("stay_mean", kwargs["mean_centre"] * pt.exp(z))
        eta = pm.Normal("stay_shape_eta", 0.0, 1.5)
        k = pm.Deterministic("stay_shape", pt.exp(eta))
        beta = k / m
        ll = pt.sum(k * pt.log(beta) + (k - 1.0) * np.log(full) - beta * full - pt.gammaln(k))
        if n_short:
            ll += n_short * pt.log(pt.gammainc(k, beta * res))
        if cens.size:
            ll += pt.sum(pt.log(pt.gammaincc(k, beta * cens)))
        if trunc.size:
            ll += pt.sum(pt.log(pt.gammaincc(k, beta * trunc))) - trunc.size * pt.log(m)
        if whole.size:
            x = beta * whole
            excess = m * pt.gammaincc(k + 1.0, x) - whole * pt.gammaincc(k, x)
            ll += pt.sum(pt.log(excess)) - whole.size * pt.log(m)
        pm.Potential("stays", ll)
    return model


def _pymc_model(name: str, kwargs: dict) -> Any:
    return pymc_arrival_model(kwargs) if name == "arrivals" else pymc_stay_model(kwargs)


def _test_points(name: str, kwargs: dict, rng: np.random.Generator) -> list[dict]:
    """Parameter points (constrained values) around and away from the posterior."""
    if name == "arrivals":
        k = int(kwargs["max_group"])
        pts = [{"event_rate_z": 0.0, "group_size_probs": np.full(k, 1.0 / k)}]
        for z in (-1.3, 0.2, 0.9):
            pts.append({"event_rate_z": z, "group_size_probs": rng.dirichlet(np.ones(k))})
        return pts
    pts = [{"stay_mean_z": 0.0, "stay_shape_eta": 0.0}]
    for z, eta in ((0.3, 1.4), (-0.7, -0.8), (0.05, 2.2)):
        pts.append({"stay_mean_z": z, "stay_shape_eta": eta})
    return pts


def check_log_densities(data_list: list | None = None, mode: str | None = None) -> int:
    """Assert that ours and the PyMC peer give the same log joint density.

    The log density of the latent values (priors and likelihood, constrained scale, no
    Jacobian) of each model, at several points, on each log; the stay model's cases
    (seen, short, censored, truncated, present the whole window) must all occur.

    Parameters
    ----------
    data_list : list of LifecycleData, optional
        Default: the benchmark's quick log and :func:`edge_log`.
    mode : str, optional
        PyTensor compilation mode (``"FAST_COMPILE"`` skips the C compiler).

    Returns
    -------
    int
        Number of points checked.

    Raises
    ------
    AssertionError
        When a log density differs (relative 1e-8, absolute 1e-6).
    """
    import pytensor
    from numpyro.infer.util import log_density

    from are_stats.traffic._models import arrival_model, stay_model

    if data_list is None:
        data_list = [make_log(3600.0), edge_log()]
    rng = np.random.default_rng(0)
    cases = np.zeros(5, int)
    n = 0
    for data in data_list:
        kw = traffic_kwargs(data)
        su = kw["stays"][0]["units"]
        real = su.weight > 0
        cen, tru, stay = su.censored[real], su.truncated[real], su.stay[real]
        short = ~cen & ~tru & (stay < kw["stays"][0]["resolution"])
        cases += [
            int(np.sum(~cen & ~tru & ~short)), int(short.sum()), int(np.sum(cen & ~tru)),
            int(np.sum(tru & ~cen)), int(np.sum(tru & cen)),
        ]  # fmt: skip
        for name, ours_model in (("arrivals", arrival_model), ("stays", stay_model)):
            kwargs = kw[name][0]
            model = _pymc_model(name, kwargs)
            with model:
                logp = model.compile_logp(jacobian=False, mode=mode)
            for point in _test_points(name, kwargs, rng):
                ours = float(log_density(ours_model, (), kwargs, point)[0])
                value = {}
                for rv in model.free_RVs:
                    v = np.asarray(point[rv.name], float)
                    tr = model.rvs_to_transforms.get(rv)
                    vv = model.rvs_to_values[rv]
                    value[vv.name] = v if tr is None else tr.forward(pytensor.shared(v)).eval()
                peer = float(logp(value))
                assert np.isfinite(ours) and np.isclose(ours, peer, rtol=1e-8, atol=1e-6), (
                    f"{name}: log density at {point}: ours {ours!r}, PyMC {peer!r}"
                )
                n += 1
    assert cases.min() > 0, f"stay cases (seen, short, censored, truncated, whole) {cases}"
    return n


# ----------------------------------------------------------------------------- workers


def _param_draws(samples: dict, name: str) -> dict[str, np.ndarray]:
    """(chains, draws) arrays of every scalar parameter of the model."""
    out = {}
    for key in PARAMS[name]:
        v = np.asarray(samples[key], float)
        if v.ndim == 3:
            for j in range(v.shape[2]):
                out[f"{key}[{j + 1}]"] = v[..., j]
        else:
            out[key] = v
    return out


def _summarise(draws: dict[str, np.ndarray]) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az
    ess = {k: float(az.ess(v, method="bulk")) for k, v in draws.items()}
    return {
        "ess": ess,
        "min_ess": min(ess.values()),
        "mean": {k: float(v.mean()) for k, v in draws.items()},
        "sd": {k: float(v.std()) for k, v in draws.items()},
    }


def _ours_call(name: str, data: Any, seed: int, warmup: int, samples: int) -> dict:
    import jax

    from are_stats.fitting import run_nuts
    from are_stats.traffic._models import arrival_model, stay_model

    tic = time.perf_counter()
    kwargs, init = traffic_kwargs(data)[name]
    run = run_nuts(
        jax.random.key(seed), arrival_model if name == "arrivals" else stay_model, kwargs,
        init, num_warmup=warmup, num_samples=samples, num_chains=2, name=name,
    )  # fmt: skip
    wall = time.perf_counter() - tic
    out = _summarise(_param_draws(run.samples, name))
    out.update(wall=wall, divergent=run.n_divergent)
    return out


def _pymc_call(name: str, data: Any, seed: int, warmup: int, samples: int) -> dict:
    import pymc as pm

    tic = time.perf_counter()
    kwargs, init = traffic_kwargs(data)[name]
    model = _pymc_model(name, kwargs)
    with model:
        idata = pm.sample(
            draws=samples, tune=warmup, chains=2, cores=2, random_seed=seed,
            target_accept=0.85, init="adapt_diag", initvals=init, progressbar=False,
            compute_convergence_checks=False,
        )  # fmt: skip
    wall = time.perf_counter() - tic
    post = {k: idata.posterior[k].values for k in idata.posterior.data_vars}
    out = _summarise(_param_draws(post, name))
    out.update(
        wall=wall,
        divergent=int(idata.sample_stats["diverging"].values.sum()),
        sampling_time=float(idata.sample_stats.attrs.get("sampling_time", np.nan)),
    )
    return out


def _trivial(impl: str) -> None:
    """Sample ``x ~ Normal(0, 1)`` briefly: fills a compile cache with the generic parts."""
    if impl == "ours":
        import jax
        import numpyro
        import numpyro.distributions as dist

        from are_stats.fitting import run_nuts

        def model() -> None:
            numpyro.sample("x", dist.Normal(0.0, 1.0))

        run_nuts(jax.random.key(0), model, {}, {"x": 0.0}, num_warmup=20, num_samples=20,
                 num_chains=2)  # fmt: skip
    else:
        import pymc as pm

        with pm.Model():
            pm.Normal("x", 0.0, 1.0)
            pm.sample(draws=20, tune=20, chains=2, cores=2, random_seed=0, progressbar=False,
                      compute_convergence_checks=False)  # fmt: skip


def _worker(argv: list[str]) -> None:
    """``--worker ours|pymc --model arrivals|stays|trivial --calls N ...``: one RESULT line."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker", choices=("ours", "pymc"), required=True)
    ap.add_argument("--model", choices=(*MODELS, "trivial"), required=True)
    ap.add_argument("--calls", type=int, default=2)
    ap.add_argument("--warmup", type=int, default=1000)
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=10800.0)
    a = ap.parse_args(argv)
    import logging

    logging.getLogger("pymc").setLevel(logging.ERROR)
    warnings.simplefilter("ignore")
    if a.model == "trivial":
        _trivial(a.worker)
        print("RESULT " + json.dumps({"n": 0, "calls": []}), flush=True)
        return
    data = make_log(a.duration)
    call = _ours_call if a.worker == "ours" else _pymc_call
    calls = [call(a.model, data, seed, a.warmup, a.samples) for seed in range(1, a.calls + 1)]
    print("RESULT " + json.dumps({"n": int(data.n), "calls": calls}), flush=True)


# ----------------------------------------------------------------------------- driver

_CACHE_ENV = (
    "JAX_COMPILATION_CACHE_DIR",
    "ARE_STATS_JAX_CACHE",
    "ARE_STATS_NO_CACHE",
    "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS",
    "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES",
)


def _env(cache_home: Path) -> dict[str, str]:
    """A child environment whose JAX and PyTensor caches live under ``cache_home``."""
    env = {k: v for k, v in os.environ.items() if k not in _CACHE_ENV}
    env["XDG_CACHE_HOME"] = str(cache_home)
    flags = [f for f in env.get("PYTENSOR_FLAGS", "").split(",") if f]
    env["PYTENSOR_FLAGS"] = ",".join(flags + [f"base_compiledir={cache_home / 'pytensor'}"])
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    )
    env.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
    env.setdefault("JAX_PLATFORMS", "cpu")
    return env


def _spawn(args: list[str], env: dict[str, str]) -> tuple[subprocess.CompletedProcess, float]:
    tic = time.perf_counter()
    proc = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True)
    return proc, time.perf_counter() - tic


def _run_worker(impl: str, name: str, calls: int, env: dict, opts: list[str]) -> tuple:
    args = [sys.executable, "-m", "tests.benchmarks.bench_traffic_nuts", "--worker", impl,
            "--model", name, "--calls", str(calls), *opts]  # fmt: skip
    proc, wall = _spawn(args, env)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"worker {impl} {name} failed:\n{proc.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :]), wall


def _pymc_available() -> bool:
    try:
        import pymc  # noqa: F401
    except ImportError:
        return False
    return True


def _cache_entries(cache_home: Path) -> int:
    folder = cache_home / "are_stats" / "jax"
    return sum(1 for _ in folder.rglob("*") if _.is_file()) if folder.is_dir() else 0


#: The conditions of a call, in the table's order.
RUNS = ("cold", "cold model", "warm, same process", "warm, new process")


def _bench_model(name: str, impls: list[str], opts: list[str], tmp: Path) -> dict:
    """The four conditions (:data:`RUNS`) of one model for each implementation.

    Four fresh processes per implementation: (1) an empty compile cache, two calls (cold,
    then warm in the same process); (2) a new process on (1)'s cache (warm, new process);
    (3) an unrelated one-parameter model sampled into a second empty cache, then (4) a new
    process on that cache (cold model: the library's generic compiled parts are cached,
    this model's are not). Returns ``{(impl, run): call result}`` and
    ``{(impl, "start-up"): seconds}`` (process (2)'s wall time less its call: interpreter,
    imports, the log).
    """
    rows: dict[Any, Any] = {}
    for impl in impls:
        print(f"  {name}: {impl} (four fresh processes)", flush=True)
        home = tmp / f"{impl}-{name}"
        home.mkdir()
        env = _env(home)
        first, _ = _run_worker(impl, name, 2, env, opts)
        entries = _cache_entries(home) if impl == "ours" else None
        second, wall2 = _run_worker(impl, name, 1, env, opts)
        home2 = tmp / f"{impl}-{name}-generic"
        home2.mkdir()
        env2 = _env(home2)
        _run_worker(impl, "trivial", 0, env2, [])
        third, _ = _run_worker(impl, name, 1, env2, opts)
        rows[(impl, "cold")] = first["calls"][0]
        rows[(impl, "warm, same process")] = first["calls"][1]
        rows[(impl, "warm, new process")] = second["calls"][0]
        rows[(impl, "cold model")] = third["calls"][0]
        rows[(impl, "start-up")] = wall2 - second["calls"][0]["wall"]
        rows["n"] = first["n"]
        if entries is not None:
            print(f"  {name}: JAX persistent cache after the first process: {entries} files")
    return rows


def _print_table(name: str, rows: dict, impls: list[str]) -> None:
    """One line per condition: wall, min ESS and ESS/s of each implementation, and the ratio."""
    labels = {"ours": "ours", "pymc": "PyMC"}
    head = f"{name:<20}"
    for impl in impls:
        lab = labels[impl]
        head += f"{lab + ' wall s':>14}{'min ESS':>9}{'ESS/s':>8}{'div':>5}"
    if len(impls) > 1:
        head += f"{'ours/PyMC':>11}"
    print("\n" + head)
    for run in RUNS:
        line = f"  {run:<18}"
        eps = {}
        for impl in impls:
            r = rows[(impl, run)]
            eps[impl] = r["min_ess"] / r["wall"]
            line += f"{r['wall']:14.1f}{r['min_ess']:9.0f}{eps[impl]:8.1f}{r['divergent']:5d}"
        if len(impls) > 1:
            line += f"{eps['ours'] / eps['pymc']:11.2f}"
        print(line)
    print(
        "  start-up s (fresh process: interpreter, imports, the log): "
        + ", ".join(f"{labels[i]} {rows[(i, 'start-up')]:.1f}" for i in impls)
    )
    print("  posterior mean (sd), warm same-process runs:")
    for impl in impls:
        res = rows[(impl, "warm, same process")]
        cells = "  ".join(f"{k} {res['mean'][k]:.4g} ({res['sd'][k]:.2g})" for k in res["mean"])
        print(f"    {labels[impl]:<6}{cells}")


def _bench_fit(tmp: Path, extra: list[str]) -> None:
    """``are-stats fit`` of the shipped log, first, second and third run on one fresh cache.

    ``extra``: more options (the quick run shortens the NUTS runs of the traffic models).
    """
    home = tmp / "fit"
    home.mkdir()
    env = _env(home)
    log = "courtyard_traffic"  # the shipped example log (resolved from anywhere)
    walls = []
    cmd = " ".join(["are-stats fit", log, "--method em --no-figures", *extra])
    print(f"\n{cmd}: first, second and third run", flush=True)
    for i in (1, 2, 3):
        args = [sys.executable, "-m", "are_stats", "fit", log, "--out", str(home / f"fit{i}.nc"),
                "--method", "em", "--no-figures", *extra]  # fmt: skip
        proc, wall = _spawn(args, env)
        if proc.returncode != 0:
            raise RuntimeError(f"are-stats fit failed:\n{proc.stderr[-3000:]}")
        walls.append(wall)
    print(
        f"{cmd} (process wall time, fresh cache): first run {walls[0]:.1f} s, second run "
        f"(caches warm) {walls[1]:.1f} s, third {walls[2]:.1f} s: first / second "
        f"{walls[0] / walls[1]:.1f}x, first / third {walls[0] / walls[2]:.1f}x (issue 17 "
        f"target: 4x); load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"
    )


def main(quick: bool = False) -> None:
    """Check the log densities agree, then time both implementations and the CLI fit."""
    warmup = samples = 300 if quick else 1000
    duration = 3600.0 if quick else 10800.0
    impls = ["ours"]
    if _pymc_available():
        impls.append("pymc")
        n = check_log_densities([make_log(duration), edge_log()])
        print(f"log densities: ours == PyMC at {n} points (two logs, both models)")
    else:
        print("PyMC not installed: peer rows skipped (pip install 'are-stats[bench]')")
    opts = ["--warmup", str(warmup), "--samples", str(samples), "--duration", str(duration)]
    tmp = Path(tempfile.mkdtemp(prefix="bench_traffic_"))
    try:
        results = {}
        for name in MODELS:
            results[name] = _bench_model(name, impls, opts, tmp)
        n = results["arrivals"]["n"]
        print(
            f"\ntraffic NUTS on a synthetic log of {n} artefacts ({duration:g} s window; truth "
            f"event_rate {_event_rate():.4g} /m^2/s, group sizes {TRUTH['group_size_probs']}, "
            f"gamma stays mean {TRUTH['stay_mean']:g} s shape {TRUTH['stay_shape']:g}); "
            f"2 chains x ({warmup} warm-up + {samples} draws); {os.cpu_count()} CPUs"
        )
        for name in MODELS:
            _print_table(name, results[name], impls)
        print(
            "\nwall: the call (model building, compilation, sampling). ESS/s = min bulk ESS "
            "over the parameters / wall. cold: fresh process, empty compile cache (JAX "
            "persistent cache / PyTensor compiledir); cold model: fresh process, the cache "
            "holds an unrelated model's programs (for PyTensor: its own C modules); warm, "
            "same process: a second call; warm, new process: a fresh process on the cold "
            "run's cache. ours/PyMC: ratio of ESS/s in the same condition."
        )
        _bench_fit(tmp, ["--warmup", "200", "--samples", "200", "--chains", "2"] if quick else [])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    if "--worker" in sys.argv[1:]:
        _worker(sys.argv[1:])
    elif "--fit-only" in sys.argv[1:]:  # only the three CLI fits (about 2-3 minutes)
        fit_tmp = Path(tempfile.mkdtemp(prefix="bench_traffic_fit_"))
        try:
            _bench_fit(fit_tmp, [])
        finally:
            shutil.rmtree(fit_tmp, ignore_errors=True)
    else:
        main(quick="--quick" in sys.argv[1:])
