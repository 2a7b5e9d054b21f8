"""The one NUTS driver (``run_nuts``) against a conjugate normal posterior.

Model: ``mu ~ Normal(0, s0)``, ``y_i ~ Normal(mu, s)``; the posterior of ``mu`` is
normal with precision ``1/s0^2 + n/s^2`` and mean ``sum(y)/s^2`` over it. Checks as in
``test_lifecycle_mcmc``: bulk ESS > 400 first, then the mean within 4 Monte Carlo standard
errors and the sd within 10 %.
"""

from __future__ import annotations

import inspect
import warnings
from typing import Unpack, get_type_hints

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from numpyro.diagnostics import split_gelman_rubin
from scipy import stats

from are_stats.fitting import (
    NutsPrefetch,
    NutsRun,
    NutsSettings,
    chains_per_device,
    nuts_warnings,
    resolve_chain_method,
    run_nuts,
)
from are_stats.fitting import _nuts as nuts_module
from are_stats.fitting._nuts import chunk_length, time_left
from are_stats.fitting._traffic import _stay_draw_loglik
from are_stats.traffic._models import stay_model, stay_units

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

S, S0 = 2.0, 10.0


def normal_model(y, prior_sd=S0):
    """``mu ~ Normal(0, prior_sd)``, ``y ~ Normal(mu, S)``; ``mu2 = mu^2`` deterministic."""
    mu = numpyro.sample("mu", dist.Normal(0.0, prior_sd))
    numpyro.deterministic("mu2", mu**2)
    numpyro.sample("y", dist.Normal(mu, S), obs=y)


def normal_pointwise(draw, y, prior_sd=S0):
    """Pointwise log-likelihood of one draw, given the model's arguments."""
    return dist.Normal(draw["mu"], S).log_prob(y)


def _posterior(y: np.ndarray, prior_sd: float = S0) -> tuple[float, float]:
    prec = 1.0 / prior_sd**2 + y.size / S**2
    return float(y.sum() / S**2 / prec), float(np.sqrt(1.0 / prec))


def _check(draws: np.ndarray, mean: float, sd: float) -> None:
    ess = float(az.ess(draws, method="bulk"))
    assert ess > 400, f"bulk ESS {ess:.0f} too small for the check"
    mcse = draws.std() / np.sqrt(float(az.ess(draws, method="mean")))
    assert abs(draws.mean() - mean) < 4 * mcse, (draws.mean(), mean, mcse)
    assert abs(draws.std() / sd - 1) < 0.10, (draws.std(), sd)


def _data(seed: int, n: int = 40, shift: float = 0.0) -> np.ndarray:
    return np.random.default_rng(seed).normal(3.0 + shift, S, n)


#: Two vectorised chains with their tree sizes and step sizes kept: the program of the
#: conjugate test and of the vectorised chunk test, compiled once
TWO = {
    "num_warmup": 300,
    "num_samples": 600,
    "num_chains": 2,
    "chain_method": "vectorized",
    "extra_fields": ("num_steps", "step_size"),
}


def test_matches_conjugate_posterior_and_reuses_its_program():
    """Closed-form posterior; a second call on other data of the same shape compiles
    nothing and still samples the NEW data's posterior (data are program arguments)."""
    nuts_module._CACHE.clear()
    y1, y2 = _data(0), _data(1, shift=-6.0)
    kw = {k: v for k, v in TWO.items() if k != "extra_fields"}
    runs = []
    for i, y in enumerate((y1, y2)):
        run = run_nuts(
            jax.random.key(i),
            normal_model,
            {"y": y},
            {"mu": 0.0},
            pointwise=normal_pointwise,
            pointwise_kwargs=True,
            name="normal",
            **TWO,
        )
        runs.append(run)
        mean, sd = _posterior(y)
        _check(run.samples["mu"].ravel(), mean, sd)
        assert run.samples["mu"].shape == (2, 600)
        np.testing.assert_allclose(run.samples["mu2"], run.samples["mu"] ** 2, rtol=1e-12)
        expect = stats.norm.logpdf(y[None, None, :], run.samples["mu"][..., None], S)
        np.testing.assert_allclose(run.loglik, expect, rtol=1e-10)
        assert run.diverging.shape == (2, 600) and run.n_divergent == 0
        r = float(np.max(split_gelman_rubin(run.samples["mu"])))
        assert run.r_hat["mu"] == pytest.approx(r) and run.max_r_hat < 1.05
        assert set(run.extra) == {"num_steps", "step_size"}
        assert run.chain_method == "vectorized"
        assert nuts_warnings(run) == []
    assert runs[0].timing["compile"] > 0.0
    assert runs[1].timing["compile"] == 0.0  # both programs found in the in-process cache
    # a static argument (a Python number) is part of the program: a new one compiles
    run = run_nuts(jax.random.key(5), normal_model, {"y": y1, "prior_sd": 0.5}, {"mu": 0.0}, **kw)
    assert run.timing["compile"] > 0.0 and run.loglik is None
    _check(run.samples["mu"].ravel(), *_posterior(y1, 0.5))


#: Four chains from numpyro's uniform start, 300 warm-up iterations (chunks of 40): the
#: one program of the parallel-start, default-method and prefetch tests below, compiled
#: once (traced without the program cache, so that the prefetch test, which traces, finds
#: it in the persistent XLA cache; the other tests here read their programs from disk).
#: Cheap XLA optimisation: this model's programs compile in 5.4-5.9 s of CPU instead of
#: 8.7-8.8 s (2026-11-29, loaded host) and sample in under a second either way; TWO's
#: programs are compiled at XLA's default level, the product's for most models
FOUR = {"num_warmup": 300, "num_chains": 4, "cheap_compile": True}


def test_parallel_chains_and_random_start(monkeypatch):
    """No ``init``: numpyro's uniform start; ``parallel`` with more chains than devices
    vectorises chains on each device (sequential: the one-chain test)."""
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")  # the program FOUR's tests share
    assert jax.local_device_count() * 2 == FOUR["num_chains"]
    y = _data(2)
    run = run_nuts(
        jax.random.key(3), normal_model, {"y": y}, None, num_samples=500, chain_method="parallel",
        **FOUR,
    )  # fmt: skip
    assert run.chain_method == "parallel"
    assert run.samples["mu"].shape == (jax.local_device_count() * 2, 500)
    _check(run.samples["mu"].ravel(), *_posterior(y))


#: One chain from a stated unconstrained start, its step sizes kept: the program of the
#: one-chain test and of the sequential chunk test, compiled once (cheap, as FOUR's)
ONE = {
    "num_warmup": 200,
    "num_samples": 200,
    "num_chains": 1,
    "init_params": {"mu": np.asarray(1.0)},
    "extra_fields": ("step_size",),
    "cheap_compile": True,
}


def test_unconstrained_start_per_chain_and_one_chain():
    """``init_params`` on the unconstrained scale (a chain axis; none with one chain)."""
    y = _data(3)
    run = run_nuts(jax.random.key(4), normal_model, {"y": y}, None, **ONE)
    assert run.chain_method == "sequential" and run.samples["mu"].shape == (1, 200)
    assert np.isnan(run.max_r_hat)
    mean, sd = _posterior(y)
    assert abs(run.samples["mu"].mean() - mean) < 6 * sd / np.sqrt(20)  # >= 20 eff. draws


def test_bad_sizes_name_the_arguments():
    with pytest.raises(ValueError, match="num_warmup, num_samples, num_chains: expected"):
        run_nuts(jax.random.key(0), normal_model, {"y": _data(0)}, None, num_samples=0)
    with pytest.raises(ValueError, match="chain_method: expected one of"):
        run_nuts(jax.random.key(0), normal_model, {"y": _data(0)}, None, chain_method="x")


def test_nuts_settings_are_its_keywords():
    """NutsSettings (what NutsPrefetch.add and the traffic fit pass on) names run_nuts's
    keywords after ``init``, with their types: a keyword added to one is added to the other."""
    hints = get_type_hints(run_nuts)
    names = list(inspect.signature(run_nuts).parameters)
    keywords = names[names.index("init") + 1 :]
    assert list(NutsSettings.__annotations__) == keywords
    assert get_type_hints(NutsSettings) == {k: hints[k] for k in keywords}
    assert get_type_hints(NutsPrefetch.add)["settings"] == Unpack[NutsSettings]


def test_warnings_word_divergences_and_r_hat():
    run = NutsRun(
        samples={},
        diverging=np.array([[True, False], [False, True]]),
        r_hat={"a": 1.2, "b": 1.0, "c": float("nan")},
        loglik=None,
        name="m",
    )
    words = nuts_warnings(run)
    assert len(words) == 2
    assert words[0].startswith("m: 2 of 4 draws divergent")
    assert words[1].startswith("m: r_hat 1.200 > 1.01 for a:")
    stuck = run._replace(diverging=np.zeros((2, 2), bool), r_hat={"a": float("inf")})
    assert stuck.max_r_hat == np.inf
    assert nuts_warnings(stuck) == [nuts_warnings(stuck)[0]]
    assert nuts_warnings(stuck)[0].startswith("m: r_hat inf > 1.01 for a:")
    clean = run._replace(diverging=np.zeros((2, 2), bool), r_hat={"a": 1.001})
    assert nuts_warnings(clean) == []


#: Four chains of the exponential stay model, cheap XLA optimisation: the program cache
#: test's and (its cache-off program, parallel) the prefetch test's
STAY = {"num_warmup": 60, "num_samples": 40, "num_chains": 4, "cheap_compile": True}


def _stays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """40 gamma stays (s), those over 900 s censored, the first five truncated."""
    stay = np.random.default_rng(7).gamma(4.0, 150.0, 40)
    return stay, stay > 900.0, np.arange(40) < 5


@pytest.mark.parametrize(
    "method",
    [
        "parallel",
        # make test: [parallel] keeps run_nuts's claim (its sampler and post-processing
        # programs kept, read without tracing, the same bits as traced and as cache off),
        # and tests/test_program_cache.py::test_a_kept_program_is_read_not_traced the
        # reading of a program without shardings, as the vectorised chains' are
        pytest.param("vectorized", marks=pytest.mark.slow),
    ],
)
def test_a_program_read_from_disk_gives_the_same_draws(tmp_path, monkeypatch, method):
    """The traced programs are kept on disk (``are_stats._program_cache``): a fresh process
    (here: the in-process cache cleared, tracing forbidden) reads them and samples the same
    bits, which are also those of the cache turned off."""
    stay, censored, truncated = _stays()
    kwargs = {
        "units": stay_units(stay, censored, truncated),
        "law": "exponential",
        "mean_centre": np.asarray(stay.mean()),
        "resolution": 0.4,
    }
    init = {"stay_mean_z": 0.0}

    def run():
        nuts_module._CACHE.clear()
        return run_nuts(
            jax.random.key(1),
            stay_model,
            kwargs,
            init,
            chain_method=method,
            pointwise=_stay_draw_loglik,
            pointwise_kwargs=True,
            **STAY,
        )

    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", str(tmp_path))
    traced = run()
    assert traced.chain_method == method
    assert len(list(tmp_path.glob("*.jaxexport"))) == 2  # the sampler and the post-processing

    def no_tracing(*args, **kwargs):
        raise AssertionError("traced again: the kept program was not read")

    with monkeypatch.context() as m:
        m.setattr(jax.export, "export", no_tracing)
        read = run()
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")
    off = run()
    for other in (read, off):
        for site in traced.samples:
            np.testing.assert_array_equal(other.samples[site], traced.samples[site])
        np.testing.assert_array_equal(other.loglik, traced.loglik)
        np.testing.assert_array_equal(other.diverging, traced.diverging)


def test_default_spreads_chains_over_devices(monkeypatch):
    """Without a stated method, chains that split evenly over two or more devices run
    "parallel" (each device vectorising its share), otherwise vectorised on one."""
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")  # FOUR's program as traced above
    n_dev = jax.local_device_count()
    assert n_dev == 2  # tests/conftest.py asks for 2 host devices
    assert chains_per_device(4) == (2, 2) and chains_per_device(2) == (2, 1)
    assert chains_per_device(3) == (1, 3) and chains_per_device(1) == (1, 1)
    assert resolve_chain_method(None, 4) == "parallel"
    assert resolve_chain_method(None, 3) == "vectorized"
    assert resolve_chain_method(None, 1) == "sequential"
    assert resolve_chain_method("vectorized", 4) == "vectorized"
    # the same draws up to rounding either way, and the loglik of each of them (odd
    # draw count: the post-processing on one device; even: split over both); 499 draws
    # a chain: chunks of 40 iterations, as in FOUR's other tests
    y = _data(5)
    kw = {**FOUR, "num_samples": 499, "pointwise": normal_pointwise, "pointwise_kwargs": True}
    assert chunk_length(300, 499) == chunk_length(300, 500) == 40
    runs = {
        m: run_nuts(jax.random.key(8), normal_model, {"y": y}, None, chain_method=m, **kw)
        for m in ("parallel", "vectorized", None)
    }
    assert runs[None].chain_method == "parallel"
    np.testing.assert_array_equal(runs[None].samples["mu"], runs["parallel"].samples["mu"])
    np.testing.assert_allclose(
        runs["vectorized"].samples["mu"], runs["parallel"].samples["mu"], rtol=1e-9
    )
    odd = run_nuts(jax.random.key(8), normal_model, {"y": y}, None, **{**kw, "num_chains": 3})
    assert odd.chain_method == "vectorized" and odd.samples["mu"].size % 2 == 1
    for run in (*runs.values(), odd):
        expect = stats.norm.logpdf(y[None, None, :], run.samples["mu"][..., None], S)
        np.testing.assert_allclose(run.loglik, expect, rtol=1e-10)


def _failing_model(y):
    numpyro.sample("mu", dist.Normal(0.0, 1.0))
    raise RuntimeError("model error on purpose")


def test_prefetch_compiles_ahead_and_changes_no_draw(monkeypatch):
    """Programs compiled by :class:`NutsPrefetch` worker threads (two models traced at
    once, so the trace lock matters) are the ones ``run_nuts`` then uses, and give the same
    bits as programs compiled by ``run_nuts`` itself. A model that fails to compile fails
    in ``run_nuts``, not in the prefetch."""
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")  # trace in the workers, not read
    # the programs of test_default_spreads_chains_over_devices (FOUR) and of the program
    # cache test (its cache-off run): traced here again, compiled by XLA once in the file
    stay, censored, truncated = _stays()
    calls = [
        (
            jax.random.key(2),
            normal_model,
            {"y": _data(6)},
            None,
            {**FOUR, "num_samples": 499, "pointwise": normal_pointwise},
        ),
        (
            jax.random.key(3),
            stay_model,
            {
                "units": stay_units(stay, censored, truncated),
                "law": "exponential",  # gamma's incomplete-gamma program adds ~40 s cold
                "mean_centre": np.asarray(stay.mean()),
                "resolution": 0.4,
            },
            {"stay_mean_z": 0.0},
            {**STAY, "pointwise": _stay_draw_loglik},
        ),
    ]

    def runs():
        return [run_nuts(k, m, a, i, pointwise_kwargs=True, **kw) for k, m, a, i, kw in calls]

    nuts_module._CACHE.clear()
    alone = runs()
    nuts_module._CACHE.clear()
    compiled = []
    original = nuts_module._compile
    monkeypatch.setattr(
        nuts_module, "_compile", lambda *a, **k: compiled.append(a[2]) or original(*a, **k)
    )
    with NutsPrefetch() as ahead:
        for k, m, a, i, kw in calls:
            ahead.add(k, m, a, i, name="ignored", pointwise_kwargs=True, **kw)
    assert len(nuts_module._CACHE) == 2 and len(compiled) == 2  # both sampling programs
    ahead_runs = runs()
    assert len(compiled) == 4  # run_nuts compiled only the two post-processing programs
    for a, b in zip(alone, ahead_runs, strict=True):
        for site in a.samples:
            np.testing.assert_array_equal(a.samples[site], b.samples[site])
        np.testing.assert_array_equal(a.loglik, b.loglik)
    with NutsPrefetch() as ahead:
        ahead.add(jax.random.key(0), _failing_model, {"y": _data(0)}, None, num_chains=2)
    with pytest.raises(RuntimeError, match="model error on purpose"):
        run_nuts(jax.random.key(0), _failing_model, {"y": _data(0)}, None, num_chains=2)


def test_time_left_from_the_measured_rates():
    assert time_left((0, 500, 0.0, float("nan")), (0, 500, 0.0)) is None
    # warm-up 100 of 500 in 20 s (0.2 s each), the last chunk 0.1 s each: 400 x 0.2 + 500 x 0.1
    assert time_left((100, 500, 20.0, 0.1), (0, 500, 0.0)) == pytest.approx(130.0)
    # sampling 200 of 500 in 10 s: 300 x 0.05
    assert time_left((500, 500, 60.0, 0.1), (200, 500, 10.0)) == pytest.approx(15.0)
    assert time_left((500, 500, 60.0, 0.1), (500, 500, 10.0)) == 0.0


@pytest.mark.parametrize("method", ["vectorized", "sequential"])
def test_chunks_report_progress_and_change_no_draw(monkeypatch, method):
    """Warm-up and sampling run as chunks of one compiled program; every chunk tells the
    phase, the iterations done and an estimate of the time left; the draws are those of
    the whole run in one chunk (the sampler's state goes on exactly from chunk to chunk).
    The chunked programs are those of the tests above (TWO: vectorised, ONE: sequential)."""
    y = _data(9)
    kw = TWO if method == "vectorized" else {**ONE, "chain_method": "sequential"}
    warmup, samples, chains = kw["num_warmup"], kw["num_samples"], kw["num_chains"]
    init = None if "init_params" in kw else {"mu": 0.0}
    assert chunk_length(45, 30) == 4  # 75 iterations in about 20 chunks
    chunk = chunk_length(warmup, samples)
    assert chunk == {"vectorized": 45, "sequential": 20}[method]  # 900 and 400 iterations
    told = []
    run = run_nuts(jax.random.key(6), normal_model, {"y": y}, init, progress=told.append, **kw)
    one = [(p.phase, p.done, p.total) for p in told if p.phase in ("warm-up", "sampling")]
    per_chain = [("warm-up", d, warmup) for d in [*range(chunk, warmup, chunk), warmup]] + [
        ("sampling", d, samples) for d in [*range(chunk, samples, chunk), samples]
    ]
    assert one == per_chain * (1 if method == "vectorized" else chains)
    assert told[0] == ("compile", 0, 0, None) and told[-1] == ("postprocess", 0, 0, None)
    lefts = [p.seconds_left for p in told[1:-1]]
    assert all(x is not None and x >= 0 for x in lefts) and lefts[-1] == 0.0
    assert run.timing["sampling"] >= run.timing["warmup"] > 0.0
    monkeypatch.setattr(nuts_module, "TARGET_CHUNKS", 1)  # the whole run in one chunk
    whole = run_nuts(jax.random.key(6), normal_model, {"y": y}, init, **kw)
    np.testing.assert_allclose(run.samples["mu"], whole.samples["mu"], rtol=1e-9)
    np.testing.assert_allclose(run.extra["step_size"], whole.extra["step_size"], rtol=1e-9)
    assert run.samples["mu"].shape == (chains, samples)
