"""The chosen traffic models' posteriors by importance resampling of Laplace draws.

Against truth: a known Gaussian posterior from a wrong Gaussian proposal; against NUTS on
the shipped log (the groups arrivals and gamma stays it chooses: means within 4 Monte
Carlo standard errors, sds within 30%); a proposal that misses the posterior's tails is
refused, and then ``fit_traffic`` samples the chosen model by NUTS.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy import stats

import are_stats.fitting._traffic as traffic_module
from are_stats import shipped_path
from are_stats.fitting import LaplaceRun, fit_traffic, importance_resample
from are_stats.logs import read_field_log
from are_stats.traffic import LifecyclePriors, conjugate_arrival_rate, conjugate_leave_rate

NUTS = {"num_warmup": 300, "num_samples": 500, "num_chains": 2}


def _run(z: np.ndarray, log_post: np.ndarray, log_q: np.ndarray) -> LaplaceRun:
    return LaplaceRun({"theta": z}, np.zeros((z.size, 1)), log_post - log_q, {}, True, "t")


def test_resampling_recovers_a_known_posterior():
    """Proposal N(0, 1), posterior N(0.4, 0.8^2): the resampled draws' mean and sd are the
    posterior's within 4 Monte Carlo standard errors (false-failure rate about 1e-4)."""
    rng = np.random.default_rng(0)
    z = rng.normal(0.0, 1.0, 8000)
    post = stats.norm(0.4, 0.8)
    got = importance_resample(jax.random.key(1), _run(z, post.logpdf(z), stats.norm.logpdf(z)),
                              4000)  # fmt: skip
    assert got.samples is not None and got.k_hat < 0.7
    assert 0.5 * z.size < got.ess < z.size
    s = got.samples["theta"]
    assert s.shape == (4000,)
    assert abs(s.mean() - 0.4) < 4 * 0.8 / np.sqrt(got.ess)
    assert abs(s.std() - 0.8) < 4 * 0.8 / np.sqrt(2 * got.ess)
    assert np.all(np.isin(s, z))  # draws of the proposal, nothing invented


def test_a_proposal_that_misses_the_tails_is_refused():
    """Proposal N(0, 0.2^2), posterior N(0, 1): weights ``exp(z^2 (1/0.04 - 1) / 2)``
    whose tail has Pareto ``k = 1 - 0.04 = 0.96`` in theory (estimated 0.71-0.94 from
    4000 draws over seeds 0-2; 0.86 with this one); refused."""
    rng = np.random.default_rng(0)
    z = rng.normal(0.0, 0.2, 4000)
    run = _run(z, stats.norm.logpdf(z), stats.norm(0.0, 0.2).logpdf(z))
    got = importance_resample(jax.random.key(0), run, 4000)
    assert got.samples is None and got.k_hat >= 0.7
    # an unconverged mode search is refused whatever the weights
    ok = _run(z, stats.norm(0.0, 0.21).logpdf(z), stats.norm(0.0, 0.2).logpdf(z))
    assert importance_resample(jax.random.key(0), ok, 100).samples is not None
    exact = _run(z, stats.norm(0.0, 0.2).logpdf(z), stats.norm(0.0, 0.2).logpdf(z))
    got = importance_resample(jax.random.key(0), exact, 100)  # equal weights: no tail
    assert got.samples is not None and got.k_hat == 0.0 and got.ess == pytest.approx(z.size)
    assert importance_resample(jax.random.key(0), ok._replace(converged=False), 100).samples is None


def _student_t_prior() -> None:
    import numpyro
    import numpyro.distributions as dist

    numpyro.sample("x", dist.StudentT(2.0, 0.5, 1.0))


def test_student_t_redraw_covers_tails_the_gaussian_misses():
    """Posterior Student-t with 2 degrees of freedom (no data): the Laplace Gaussian at its
    mode (sd ``sqrt(2/3)``) misses its tails (weights refused: ``k`` 0.72-0.75 over seeds
    0-2, 0.75 with this one); the Student-t redraw at the same mode and scale (3 degrees of
    freedom: weights growing as ``|x|``, a tail of ``k`` about 1/3; 0.35-0.49 over seeds)
    is accepted, and the resampled draws' quartiles are the posterior's within 4 Monte
    Carlo standard errors (false-failure rate about 1e-4 each)."""
    import jax.numpy as jnp

    from are_stats.fitting import run_laplace

    run = run_laplace(jax.random.key(1), _student_t_prior, {}, None, num_draws=4000,
                      pointwise=lambda s: jnp.zeros(1))  # fmt: skip
    assert run.converged and abs(float(run.mode["x"]) - 0.5) < 1e-3
    assert importance_resample(jax.random.key(1), run, 4000).samples is None
    got = importance_resample(jax.random.key(1), run.redraw(jax.random.key(11), 4000, 3.0), 4000)
    assert got.samples is not None and got.k_hat < 0.7, got.k_hat
    truth = stats.t(2.0, 0.5, 1.0)
    for p in (0.1, 0.25, 0.5, 0.75, 0.9):
        q = np.quantile(got.samples["x"], p)
        se = np.sqrt(p * (1 - p) / got.ess) / truth.pdf(truth.ppf(p))
        assert abs(q - truth.ppf(p)) < 4 * se, (p, q, truth.ppf(p), se)
    # the tails are there: the Gaussian's 90% quantile is 0.5 + 1.05, the posterior's 0.5 + 1.89
    assert abs(np.quantile(got.samples["x"], 0.9) - 0.5) > 1.5


@pytest.fixture(scope="module")
def shipped():
    log = read_field_log(shipped_path("courtyard_traffic", "log"))
    data = log.to_lifecycle_data()
    rng = np.random.default_rng(0)
    a = conjugate_arrival_rate(data, LifecyclePriors())
    m = conjugate_leave_rate(data, LifecyclePriors())
    paper = {
        "arrival_rate": rng.gamma(a.shape, 1 / a.rate, (1, 1000)),
        "leave_rate": rng.gamma(m.shape, 1 / m.rate, (1, 1000)),
    }
    return data, paper


@pytest.fixture(scope="module")
def shipped_nuts(shipped):
    data, paper = shipped
    return fit_traffic(
        jax.random.key(4),
        data,
        paper=paper,
        arrivals="groups",
        lifetimes="gamma",
        positions="uniform",
        approximation="nuts",
        **NUTS,
    )


NAMES = ("event_rate", "group_size_probs", "stay_mean", "stay_shape")


@pytest.mark.slow  # NUTS + ranked fits of the shipped log; make test: test_traffic's ranked fit
def test_shipped_log_resampled_posterior_is_nuts_posterior(shipped, shipped_nuts):
    data, paper = shipped
    got = fit_traffic(
        jax.random.key(5), data, paper=paper, positions="uniform", approximation="ranked", **NUTS
    )
    assert (got.arrival_model, got.lifetime_model) == ("groups", "gamma")
    for attr in ("arrival_posterior", "lifetime_posterior"):
        assert got.attrs[attr].startswith("importance-resampled Laplace (Pareto k 0."), got.attrs
    for name in NAMES:
        a, b = np.asarray(got.posterior[name]), np.asarray(shipped_nuts.posterior[name])
        assert a.shape == b.shape, name
        sd = b.std(axis=(0, 1))
        mc = 4.0 * sd * np.sqrt(10.0 / b[..., 0].size + 1.0 / a[..., 0].size)
        assert np.all(np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))) <= mc), name
        assert np.all(np.abs(a.std(axis=(0, 1)) / sd - 1.0) < 0.3), name


@pytest.mark.slow  # the shipped log's NUTS fit (above)
def test_a_refused_resampling_falls_back_to_nuts(shipped, shipped_nuts, monkeypatch):
    """Every k refused: the chosen models are sampled by NUTS (the same program and key as
    the all-NUTS fit of the same candidates: the same draws), and the fit says so."""
    data, paper = shipped
    monkeypatch.setattr(traffic_module, "RESAMPLE_MAX_K", -np.inf)  # the Student-t's too
    got = fit_traffic(
        jax.random.key(4),
        data,
        paper=paper,
        arrivals="groups",
        lifetimes="gamma",
        positions="uniform",
        approximation="ranked",
        **NUTS,
    )
    for attr in ("arrival_posterior", "lifetime_posterior"):
        assert got.attrs[attr].startswith("nuts (the Laplace draws' importance weights"), got.attrs
    for name in NAMES:
        np.testing.assert_allclose(got.posterior[name], shipped_nuts.posterior[name], rtol=1e-9)
    for factor, chosen in (("arrivals", "groups"), ("lifetimes", "gamma")):
        assert np.isfinite(got.tables[factor].loc[chosen, "r_hat"])
