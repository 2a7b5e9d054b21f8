"""Bursty arrival models (MMPP, Hawkes): likelihoods against brute force, recovery, sampler.

Synthetic data only, seeded. Tolerances of the statistical checks are stated at each
assert (several standard errors of the estimator at these sizes).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm
from scipy.optimize import minimize
from scipy.special import gammaln

from are_stats.traffic import (
    ArrivalSpec,
    TrafficLaws,
    arrival_unit_loglik,
    arrival_units,
    hawkes_count_dispersion,
    hawkes_step_loglik,
    mmpp_count_dispersion,
    mmpp_factors,
    mmpp_transfer,
    sample_hawkes_times,
    sample_mmpp_times,
    sample_population,
)

LAM = np.array([0.05, 0.6])  # events per s in the quiet and the busy state
SWITCH = np.array([1 / 180.0, 1 / 120.0])  # quiet three minutes, busy two


def _q(switch):
    return np.array([[-switch[0], switch[0]], [switch[1], -switch[1]]])


@pytest.mark.parametrize("u", [0.0, 1e-6, 0.3, 7.0, 250.0, 5000.0])
def test_mmpp_transfer_is_the_matrix_exponential(u):
    log_scale, mat = mmpp_transfer(jnp.asarray(LAM), jnp.asarray(SWITCH), u)
    want = expm((_q(SWITCH) - np.diag(LAM)) * u)
    got = np.exp(float(log_scale)) * np.asarray(mat)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-300)


def _brute_mmpp_bins(t, window, delta, width, lam, switch, area=1.0):
    """Per-bin one-step-ahead log-likelihood by scipy's expm, walked in time order."""
    t0, t1 = window
    ticks, counts = np.unique(np.floor((np.asarray(t) - t0) / delta + 1e-9).astype(int),
                              return_counts=True)  # fmt: skip
    n_bins = int(np.ceil((t1 - t0) / width - 1e-9))
    pi = np.array([switch[1], switch[0]]) / switch.sum()
    gen = _q(switch) - np.diag(lam)
    alpha, pos, prev_total, out = pi.copy(), 0.0, 0.0, np.zeros(n_bins)
    total = 0.0
    for b in range(n_bins):
        end = min((b + 1) * width, t1 - t0)
        for j, c in zip(ticks, counts, strict=True):
            s = j * delta
            if b * width <= s + delta / 2 < (b + 1) * width:
                alpha = alpha @ expm(gen * (s - pos))  # nothing until the tick
                alpha = alpha * (lam * delta) ** c * np.exp(-lam * delta - gammaln(c + 1))
                alpha = alpha @ expm(_q(switch) * delta)  # switches over the tick
                pos = s + delta
                total += np.log(alpha.sum())
                alpha /= alpha.sum()
        alpha = alpha @ expm(gen * (end - pos))
        pos = end
        total += np.log(alpha.sum())
        alpha /= alpha.sum()
        out[b] = total - prev_total
        prev_total = total
    return out


def test_mmpp_loglik_matches_brute_force_matrix_exponentials():
    rng = np.random.default_rng(3)
    t = sample_mmpp_times(rng, LAM, SWITCH, (0.0, 600.0))
    t = np.round(t, 1)  # on the tick grid; delta divides the bin width
    units = arrival_units(t, (0.0, 600.0), 1.0, 0.5, 50.0)
    params = {"event_rate": 1.0, "log_area": 0.0, "mmpp_switch": jnp.asarray(SWITCH)}
    f = LAM / (np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    params["event_rate"] = float(LAM[0] / f[0])
    params["mmpp_contrast"] = float(np.log(LAM[1] / LAM[0]))
    np.testing.assert_allclose(np.asarray(mmpp_factors(params["mmpp_contrast"], SWITCH)), f)
    got = np.asarray(arrival_unit_loglik(params, units, ArrivalSpec.from_name("mmpp")))
    want = _brute_mmpp_bins(t, (0.0, 600.0), 0.5, 50.0, LAM, SWITCH)
    assert t.size > 20
    np.testing.assert_allclose(got[: want.size], want, rtol=1e-9, atol=1e-9)
    assert np.all(got[want.size :] == 0.0)


@pytest.mark.parametrize("name", ["mmpp", "hawkes", "groups+mmpp"])
def test_flat_bursts_are_the_poisson_tick_likelihood(name):
    """Equal rates (MMPP) or no excitation (Hawkes): bin by bin the Poisson model."""
    rng = np.random.default_rng(0)
    t = np.round(np.sort(rng.uniform(0, 300, 60)), 1)
    units = arrival_units(t, (0.0, 300.0), 2.0, 0.5, 25.0)
    base = {"event_rate": 0.1, "log_area": np.log(2.0)}
    spec = ArrivalSpec.from_name(name)
    params = {**base, "mmpp_contrast": 0.0, "mmpp_switch": jnp.array([0.1, 0.3]),
              "hawkes_branching": 0.0, "hawkes_decay": 0.5,
              "group_size_probs": jnp.array([1.0, 1e-300])}  # fmt: skip
    want = arrival_unit_loglik(base, units, ArrivalSpec.from_name("poisson"))
    got = arrival_unit_loglik(params, units, spec)
    np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-9, atol=1e-9)


def test_hawkes_compensator_matches_numerical_integration():
    mu, alpha, beta, a0, delta = 0.2, 0.6, 0.05, 0.1, 0.5
    rng = np.random.default_rng(5)
    t = np.round(sample_hawkes_times(rng, mu, alpha, beta, (0.0, 400.0), burn=100.0), 1)
    units = arrival_units(t, (0.0, 400.0), 1.0, delta, 40.0)
    got = float(jnp.sum(hawkes_step_loglik(mu, alpha, beta, units.log_delta, units.steps,
                                           units.bin_weight.size, excitation0=a0)))  # fmt: skip
    ticks, counts = np.unique(np.floor(t / delta + 1e-9).astype(int), return_counts=True)
    ev = (ticks + 1) * delta  # the tick's events act from its end

    def intensity(s):
        past = ev < s
        return mu + a0 * np.exp(-beta * s) + np.sum(alpha * beta * counts[past]
                                                    * np.exp(-beta * (s - ev[past])))  # fmt: skip

    comp, err = quad(intensity, 0.0, 400.0, points=ev, limit=4 * ev.size + 50)
    left = [intensity(e - 1e-12) for e in ev]
    want = float(np.sum(counts * np.log(np.array(left) * delta) - gammaln(counts + 1.0))) - comp
    assert err < 1e-8 and t.size > 30
    assert got == pytest.approx(want, rel=1e-9, abs=1e-7)


def _mle(fun, x0):
    res = minimize(fun, x0, method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 4000})  # fmt: skip
    return res.x


def test_mmpp_switching_rates_are_recovered():
    """Maximum likelihood on 20 h of simulated arrivals: rates within 25%."""
    rng = np.random.default_rng(7)
    window = (0.0, 72000.0)
    t = sample_mmpp_times(rng, LAM, SWITCH, window)
    units = arrival_units(t, window, 1.0, 0.1, 120.0)
    spec = ArrivalSpec.from_name("mmpp")

    @jax.jit
    def nll(x):
        p = {"event_rate": jnp.exp(x[0]), "log_area": 0.0, "mmpp_contrast": jnp.exp(x[1]),
             "mmpp_switch": jnp.exp(x[2:4])}  # fmt: skip
        return -jnp.sum(arrival_unit_loglik(p, units, spec))

    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    x = _mle(lambda v: float(nll(jnp.asarray(v))), np.log([mean, 1.0, 1e-2, 1e-2]))
    lam_hat = np.exp(x[0]) * np.asarray(mmpp_factors(np.exp(x[1]), np.exp(x[2:4])))
    np.testing.assert_allclose(np.exp(x[2:4]), SWITCH, rtol=0.25)
    np.testing.assert_allclose(lam_hat, LAM, rtol=0.25)


def test_hawkes_parameters_are_recovered():
    """Maximum likelihood on 20 h of simulated arrivals: within 15% (alpha 0.1 absolute)."""
    mu, alpha, beta = 0.05, 0.6, 1 / 30.0
    rng = np.random.default_rng(8)
    window = (0.0, 72000.0)
    t = sample_hawkes_times(rng, mu, alpha, beta, window, burn=3000.0)
    units = arrival_units(t, window, 1.0, 0.1, 120.0)
    spec = ArrivalSpec.from_name("hawkes")

    @jax.jit
    def nll(x):
        a = jax.nn.sigmoid(x[1])
        p = {"event_rate": jnp.exp(x[0]), "log_area": 0.0, "hawkes_branching": a,
             "hawkes_decay": jnp.exp(x[2])}  # fmt: skip
        return -jnp.sum(arrival_unit_loglik(p, units, spec))

    x = _mle(lambda v: float(nll(jnp.asarray(v))), np.array([np.log(0.1), 0.0, np.log(0.1)]))
    a_hat = float(jax.nn.sigmoid(x[1]))
    assert a_hat == pytest.approx(alpha, abs=0.1)
    assert np.exp(x[0]) == pytest.approx(mu / (1 - alpha), rel=0.15)
    assert np.exp(x[2]) == pytest.approx(beta, rel=0.3)


def _dispersion(t, w, horizon):
    c = np.bincount((t // w).astype(int), minlength=int(horizon // w))[: int(horizon // w)]
    return c.var(ddof=1) / c.mean()


@pytest.mark.parametrize("w", [10.0, 60.0, 600.0])
def test_generated_mmpp_dispersion_matches_the_closed_form(w):
    """Arrivals from the one sampler: index of dispersion within 12% of the closed form."""
    laws = TrafficLaws(arrivals="mmpp")
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    draw = {"event_rate": mean, "stay_mean": 30.0, "mmpp_factor": LAM / mean,
            "mmpp_switch": SWITCH}  # fmt: skip
    rng = np.random.default_rng(11)
    got = []
    for _ in range(20):
        pop = sample_population(rng, draw, laws, 1e5, 1.0, start="empty")
        got.append(_dispersion(pop["t_arrive"], w, 1e5))
    want = float(mmpp_count_dispersion(LAM, SWITCH, w))
    assert want > 1.5
    assert np.mean(got) == pytest.approx(want, rel=0.12)


@pytest.mark.parametrize("w", [10.0, 600.0])
def test_generated_hawkes_dispersion_matches_the_closed_form(w):
    """Arrivals from the one sampler: within 12% of I(w); 1 / (1 - alpha)^2 for long w."""
    alpha, beta = 0.5, 0.1
    laws = TrafficLaws(arrivals="hawkes")
    draw = {"event_rate": 0.2, "stay_mean": 30.0, "hawkes_branching": alpha,
            "hawkes_decay": beta}  # fmt: skip
    rng = np.random.default_rng(12)
    got = [_dispersion(sample_population(rng, draw, laws, 1e5, 1.0)["t_arrive"], w, 1e5)
           for _ in range(20)]  # fmt: skip
    want = float(hawkes_count_dispersion(alpha, beta, w))
    assert np.mean(got) == pytest.approx(want, rel=0.12)
    if w >= 600.0:
        assert want == pytest.approx(1.0 / (1.0 - alpha) ** 2, rel=0.05)


def test_bursty_start_is_stationary():
    """The population at t = 0 (burn-in) has the stationary mean rate * area * stay."""
    laws = TrafficLaws(arrivals="mmpp")
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    draw = {"event_rate": mean, "stay_mean": 100.0, "mmpp_factor": LAM / mean,
            "mmpp_switch": SWITCH}  # fmt: skip
    rng = np.random.default_rng(2)
    n0 = [int(sample_population(rng, draw, laws, 1.0, 1.0)["truncated"].sum())
          for _ in range(400)]  # fmt: skip
    # E N(0) = mean * 100 = 22.5; sd of the mean of 400 draws < 0.6
    assert np.mean(n0) == pytest.approx(mean * 100.0, abs=2.0)
    assert np.var(n0) / np.mean(n0) > 2.0  # bursty: over-dispersed, unlike Poisson


def test_hawkes_sampler_refuses_an_explosive_branching_ratio():
    with pytest.raises(ValueError, match="branching ratio"):
        sample_hawkes_times(np.random.default_rng(0), 1.0, 1.0, 1.0, (0.0, 1.0))


@pytest.mark.parametrize(
    "contrast, switch", [(14.0, (1.0, 1000.0)), (8.0, (50.0, 1000.0)), (0.5, (1e-3, 2e-2))]
)
def test_mmpp_bins_are_probabilities_at_extreme_parameters(contrast, switch):
    """Clumped ticks (2-3 arrivals) and a rare, short, very busy state: every one-step-ahead
    term is the log of a probability of discrete counts, so at most 0 (a state read only
    at the tick's end, switched into just before it, gave terms above 0)."""
    rng = np.random.default_rng(9)
    t = np.repeat(np.round(np.sort(rng.uniform(0, 600, 80)), 1), rng.integers(1, 4, 80))
    units = arrival_units(t, (0.0, 600.0), 1.0, 0.4, 30.0)
    params = {"event_rate": 0.3, "log_area": 0.0, "mmpp_contrast": contrast,
              "mmpp_switch": jnp.array(switch)}  # fmt: skip
    got = np.asarray(arrival_unit_loglik(params, units, ArrivalSpec.from_name("mmpp")))
    assert np.all(np.isfinite(got)) and np.all(got <= 1e-12), got.max()
