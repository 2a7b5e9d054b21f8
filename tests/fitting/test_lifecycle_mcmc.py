"""NUTS on the life-cycle model against exact posteriors (censoring and truncation present).

Recovery checks follow blackjax's fixtures: require enough effective samples first
(bulk ESS > 400), then the posterior mean within 4 Monte Carlo standard errors of the truth
(false-failure rate about 6e-5 per check, below 1e-3 for the checks of this file together)
and the posterior sd within 10 % (about 6 standard errors of an sd estimated from > 1000
effective draws).
"""

from __future__ import annotations

import warnings

import jax
import numpy as np
import pytest
from numpyro.diagnostics import split_gelman_rubin
from scipy import stats

from are_stats.fitting import fit_lifecycle_nuts, pointwise_log_likelihood, resolve_chain_method
from are_stats.traffic import (
    LifecycleData,
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    simulate_lifecycle,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

PRIORS = LifecyclePriors()


@pytest.fixture(scope="module")
def data() -> LifecycleData:
    # about 2000 arrivals, 40 present at t0 (truncated), 40 still present at t1 (censored)
    d = simulate_lifecycle(
        jax.random.key(2026), 2.0, 0.05, [0.3, 0.7], [3.0, 15.0], window=(0.0, 1000.0), area=1.0
    )
    assert d.truncated.sum() > 20 and d.censored.sum() > 20 and d.n > 1800
    return d


def _check(draws: np.ndarray, mean: float, sd: float, name: str) -> None:
    ess = float(az.ess(draws, method="bulk"))
    assert ess > 400, f"{name}: bulk ESS {ess:.0f} too small for the check"
    mcse = draws.std() / np.sqrt(float(az.ess(draws, method="mean")))
    got = float(draws.mean())
    assert abs(got - mean) < 4 * mcse, f"{name}: mean {got} vs {mean} (mcse {mcse})"
    assert abs(draws.std() / sd - 1) < 0.10, f"{name}: sd {draws.std()} vs {sd}"


def test_nuts_matches_conjugate_posteriors(data):
    """stationary_start=False: lambda, mu, weights and class rates are exactly conjugate."""
    idata = fit_lifecycle_nuts(
        jax.random.key(1),
        data,
        PRIORS,
        num_warmup=500,
        num_samples=500,
        num_chains=4,
        chain_method="vectorized",
        stationary_start=False,
        num_prior_draws=200,
    )
    post = idata.posterior
    assert post.attrs["chain_method"] == "vectorized"
    for name, conj in (
        ("arrival_rate", conjugate_arrival_rate(data, PRIORS)),
        ("leave_rate", conjugate_leave_rate(data, PRIORS)),
    ):
        _check(post[name].values, conj.mean, conj.sd, name)
    mix = conjugate_mixture(data, PRIORS)
    alpha = mix.concentration
    for c in range(2):
        w = stats.beta(alpha[c], alpha.sum() - alpha[c])
        _check(post["mix_weights"].values[..., c], w.mean(), w.std(), f"mix_weights[{c}]")
        g = stats.gamma(mix.shape[c], scale=1 / mix.rate[c])
        _check(post["mix_rates"].values[..., c], g.mean(), g.std(), f"mix_rates[{c}]")
    # groups and shapes other issues rely on
    assert set(idata.groups()) >= {
        "posterior",
        "sample_stats",
        "log_likelihood",
        "prior",
        "prior_predictive",
        "posterior_predictive",
        "observed_data",
    }
    # the per-artefact stays are not stored (draws x rows): recomputed on demand, equal to
    # the model's own pointwise terms
    assert "stays" not in idata.log_likelihood
    stays = pointwise_log_likelihood(idata).values
    assert stays.shape == (4, 500, data.n)
    mu = post["leave_rate"].values[..., None]
    np.testing.assert_allclose(stays, np.where(data.censored, 0.0, np.log(mu)) - mu * data.dwell)
    assert "n_present" not in idata.log_likelihood
    assert idata.prior["arrival_rate"].shape == (1, 200)
    assert int(idata.observed_data["n_arrivals"]) == int((~data.truncated).sum())
    assert not bool(idata.sample_stats["diverging"].any())
    # the posterior predictive arrival count is negative binomial around the observed count
    pp = idata.posterior_predictive["n_arrivals"].values
    assert abs(pp.mean() - int((~data.truncated).sum())) < 5 * pp.std() / np.sqrt(pp.size) + 3


def _grid_posterior_moments(data: LifecycleData):
    """Exact joint posterior of (lambda, mu) with the stationary count, on a fine grid."""
    lam_c = conjugate_arrival_rate(data, PRIORS)
    mu_c = conjugate_leave_rate(data, PRIORS)
    lam = np.linspace(lam_c.mean - 9 * lam_c.sd, lam_c.mean + 9 * lam_c.sd, 1201)
    mu = np.linspace(mu_c.mean - 9 * mu_c.sd, mu_c.mean + 9 * mu_c.sd, 1201)
    L, M = np.meshgrid(lam, mu, indexing="ij")
    n0 = int(data.truncated.sum())
    logp = lam_c.frozen().logpdf(L) + mu_c.frozen().logpdf(M)
    logp += stats.poisson.logpmf(n0, L * data.area / M)
    p = np.exp(logp - logp.max())
    z = p.sum()
    moments = {}
    for name, x in (("arrival_rate", L), ("leave_rate", M)):
        m = (p * x).sum() / z
        moments[name] = (m, np.sqrt((p * (x - m) ** 2).sum() / z))
    return moments


# make test: tests/fitting/test_lifecycle_exact.py checks this posterior on the same log:
# test_fit_log_draws_the_paper_model_exactly_and_agrees_with_nuts (NUTS of the stationary-start
# model, 4 x 500, against the exact draws) and test_coupled_rates_match_quadrature_of_the_
# joint_density (the exact draws against a 2-d quadrature of the joint density)
@pytest.mark.slow
def test_nuts_with_stationary_start_matches_grid_posterior(data):
    """stationary_start=True couples lambda and mu: compare with 2-d integration."""
    unlabelled = LifecycleData(
        data.t_arrive, data.t_leave, data.window, data.area, marks=data.marks
    )
    idata = fit_lifecycle_nuts(
        jax.random.key(2),
        unlabelled,
        PRIORS,
        n_components=2,
        num_warmup=500,
        num_samples=500,
        num_chains=4,
        chain_method="parallel",
        num_prior_draws=0,
    )
    post = idata.posterior
    assert post.attrs["chain_method"] == "parallel"
    for name, (mean, sd) in _grid_posterior_moments(data).items():
        _check(post[name].values, mean, sd, name)
    # ordered mixture rates, well mixed, near the truth (3, 15)
    rates = post["mix_rates"].values
    assert np.all(np.diff(rates, axis=-1) > 0)
    assert float(az.rhat(post)["mix_rates"].max()) < 1.01
    assert np.allclose(rates.mean(axis=(0, 1)), [3.0, 15.0], rtol=0.1)
    assert "prior" not in idata.groups()
    assert idata.log_likelihood["n_present"].shape == (4, 500)
    values = idata.log_likelihood["mark_histogram"].coords["mark_value"].values
    assert np.array_equal(values, np.unique(data.marks))


def test_chain_method_resolution():
    assert resolve_chain_method(None, 1) == "sequential"
    n_dev = jax.local_device_count()
    assert resolve_chain_method(None, n_dev) == "parallel"
    assert resolve_chain_method(None, n_dev + 1) == "vectorized"
    assert resolve_chain_method("sequential", 4) == "sequential"


def test_sequential_chains_run(caplog):
    import logging

    d = simulate_lifecycle(jax.random.key(4), 2.0, 0.05, [1.0], [5.0], (0.0, 100.0), area=1.0)
    small = LifecycleData(d.t_arrive, d.t_leave, d.window, d.area)
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        idata = fit_lifecycle_nuts(
            jax.random.key(3),
            small,
            num_warmup=100,
            num_samples=100,
            num_chains=2,
            chain_method="sequential",
            num_prior_draws=0,
        )
    # issue 29: the sites' supports come from an abstract trace and the start values'
    # inverse transforms are one program (run eagerly, every operation of the model and of
    # the transforms compiled a program of its own, about 45 of them)
    messages = [r.getMessage() for r in caplog.records]
    compiled = {m.split()[1] for m in messages if m.startswith("Compiling")}
    allowed = {"jit(<lambda>)", "jit(call)", "jit(_threefry_split)", "jit(unstack)"}
    allowed |= {"jit(dynamic_slice)", "jit(squeeze)"}  # one chain's key, sequential chains
    assert compiled <= allowed, compiled - allowed
    assert idata.posterior["arrival_rate"].shape == (2, 100)
    assert set(idata.posterior.data_vars) == {"arrival_rate", "leave_rate"}
    # the one NUTS driver's diagnostics: divergences and split-r_hat of every site
    a = idata.sample_stats.attrs
    assert a["n_divergent"] == int(idata.sample_stats["diverging"].sum())
    for site in ("arrival_rate", "leave_rate"):
        r = float(np.max(split_gelman_rubin(idata.posterior[site].values)))
        assert a[f"r_hat_{site}"] == pytest.approx(r)
    assert a["max_r_hat"] == max(a["r_hat_arrival_rate"], a["r_hat_leave_rate"])
    assert ("r_hat" in a["nuts_warnings"]) == (a["max_r_hat"] > 1.01)
    assert ("divergent" in a["nuts_warnings"]) == (a["n_divergent"] > 0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"data": "log"}, "data: expected a LifecycleData"),
        ({"priors": {}}, "priors: expected a LifecyclePriors"),
        ({"num_samples": 0}, "num_samples: expected an integer >= 1"),
        ({"num_warmup": -1}, "num_warmup: expected non-negative integers"),
        ({"num_chains": 0}, "num_chains: expected an integer >= 1"),
        ({"chain_method": "threads"}, "chain_method: expected one of"),
        ({"target_accept_prob": 1.0}, r"target_accept_prob: expected a value in \(0, 1\)"),
        ({"stationary_start": "yes"}, "stationary_start: expected one of"),
        ({"n_components": None}, "n_components: expected the number of mixture"),
        ({"n_components": 0}, "n_components: expected an integer >= 1"),
        ({"key": "seed"}, "key: expected a JAX PRNG key"),
    ],
)
def test_bad_arguments_name_the_argument(data, kwargs, match):
    unlabelled = LifecycleData(
        data.t_arrive, data.t_leave, data.window, data.area, marks=data.marks
    )
    args = {"key": jax.random.key(0), "data": unlabelled, "n_components": 2}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fit_lifecycle_nuts(**args)
