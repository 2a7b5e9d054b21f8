"""Richer arrival and lifetime models: recovery and LOO model choice on simulated truth."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from are_stats.fitting._alternatives import (
    arrival_counts,
    compare_models,
    fit_arrival_models,
    fit_lifetime_models,
)


def test_arrival_counts_bins():
    starts, counts = arrival_counts([0.1, 0.2, 1.5, 2.99, 3.5], (0.0, 3.5), 1.0)
    assert starts.tolist() == [0.0, 1.0, 2.0]
    assert counts.tolist() == [2, 1, 1]  # 3.5 is in the dropped partial bin


def test_loo_prefers_time_of_day_for_diurnal_arrivals(rng):
    # 5 days of hourly bins with a strong diurnal cycle; area 10 m^2
    t_end = 120.0
    lam = lambda t: 1.0 + 0.9 * np.sin(2 * np.pi * t / 24)  # noqa: E731
    cand = np.sort(rng.uniform(0, t_end, rng.poisson(1.9 * 10 * t_end)))
    keep = rng.uniform(size=cand.size) < lam(cand) / 1.9
    fits = fit_arrival_models(
        jax.random.key(0),
        cand[keep],
        (0.0, t_end),
        10.0,
        bin_width=1.0,
        num_warmup=300,
        num_samples=300,
    )
    table = compare_models(fits)
    assert table.index[0] == "time_of_day"
    # the homogeneous fit recovers the average rate (1.0 per m^2 per hour) within 5%
    mean_rate = float(fits["poisson"].posterior["arrival_rate"].mean())
    assert abs(mean_rate - 1.0) < 0.05


def test_weibull_lifetimes_recovered_and_preferred(rng):
    d = 10.0 * rng.weibull(2.0, 400)
    c = d > 15.0
    d = np.minimum(d, 15.0)
    fits = fit_lifetime_models(jax.random.key(1), d, c, num_warmup=300, num_samples=300)
    table = compare_models(fits)
    assert table.index[0] in ("weibull", "gamma") and table.index[-1] == "exponential"
    post = fits["weibull"].posterior
    shape, sd = float(post["shape"].mean()), float(post["shape"].std())
    assert abs(shape - 2.0) < 4 * sd
    assert abs(float(post["leave_rate"].mean()) - 0.1) < 4 * float(post["leave_rate"].std())


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: arrival_counts([1.0], (0.0, 1.0), 1.0), "bin_width: expected at most half"),
        (lambda: fit_lifetime_models(None, [1.0, 2.0], [True, True]), "at least one observed"),
        (lambda: fit_lifetime_models(None, [1.0], [True], models=["lognormal"]), "models:"),
        (lambda: compare_models({}), "at least two models"),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.slow
def test_zero_length_stays_are_interval_censored(rng):
    # stays recorded to the second: some artefacts leave within the second they arrived
    d = np.floor(rng.exponential(3.0, 200))
    c = np.zeros(d.size, dtype=bool)
    assert (d == 0).sum() > 20
    fits = fit_lifetime_models(
        jax.random.key(2),
        d,
        c,
        models=["exponential", "weibull"],
        num_warmup=100,
        num_samples=100,
        num_chains=1,
        resolution=1.0,
    )
    for fit in fits.values():
        ll = fit.log_likelihood["durations"].to_numpy()
        assert np.isfinite(ll).all()
        assert (ll[..., d == 0] < 0).all()  # log P(stay <= 1 s) of a probability < 1
    table = compare_models(fits)
    assert np.isfinite(table["elpd_loo"].to_numpy()).all()
    # the exponential rate is of the order of the truth (1/3 per s), not driven to infinity
    rate = float(fits["exponential"].posterior["leave_rate"].mean())
    assert 0.2 < rate < 0.6


@pytest.mark.parametrize("kind", ["exponential", "weibull", "gamma"])
def test_zero_stay_log_prob_and_gradient_finite(kind):
    from are_stats.fitting._alternatives import _RightCensored

    value = jnp.array([0.0, 0.0, 2.0, 2.0])
    censored = jnp.array([False, True, False, True])

    def total(params):
        law = _RightCensored(
            kind, tuple(params[: 1 if kind == "exponential" else 2]), censored, 0.5
        )
        return law.log_prob(value)

    params = jnp.array([0.7, 0.4]) if kind != "exponential" else jnp.array([0.4])
    lp = total(params)
    grad = jax.grad(lambda p: total(p).sum())(params)
    assert np.isfinite(np.asarray(lp)).all() and np.isfinite(np.asarray(grad)).all()
    assert float(lp[1]) == 0.0  # censored at zero: log S(0)
    law = _RightCensored(kind, tuple(params), censored, 0.5)
    _, log_s = law._log_pdf_surv(jnp.array(0.5))
    assert np.isclose(float(lp[0]), np.log1p(-np.exp(float(log_s))))  # log F(resolution)


def test_time_resolution():
    from are_stats.fitting._alternatives import time_resolution

    assert time_resolution([0.0, 2.0, np.nan], [2.0, 2.5]) == 0.5
    with pytest.raises(ValueError, match="at least two distinct"):
        time_resolution([1.0, 1.0, np.nan])


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: fit_lifetime_models(None, [0.0, 0.0], [False, True]), "resolution: expected"),
        (lambda: fit_lifetime_models(None, [-1.0, 2.0], [False, True]), "durations: expected"),
        (lambda: fit_lifetime_models(None, [1.0, 2.0], [0, 1]), "censored: expected booleans"),
    ],
)
def test_bad_durations(call, match):
    with pytest.raises(ValueError, match=match):
        call()
