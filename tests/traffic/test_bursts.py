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
    group_count_dispersion,
    hawkes_count_dispersion,
    hawkes_step_loglik,
    mmpp_count_dispersion,
    mmpp_factors,
    mmpp_transfer,
    period_of,
    sample_hawkes_times,
    sample_mmpp_times,
    sample_population,
)

#: arrival_unit_loglik as one compiled program per spec and padded shape (the units are a
#: pytree, the spec static). Called op by op, the scans, matrix exponentials and
#: convolutions compiled a program per primitive and shape: 13.9 s of CPU against 3.6 s
#: for test_flat_group_bursts_are_the_groups_likelihood alone (2026-11-29).
_loglik = jax.jit(arrival_unit_loglik, static_argnums=2)

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
    got = np.asarray(_loglik(params, units, ArrivalSpec.from_name("mmpp")))
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
    want = _loglik(base, units, ArrivalSpec.from_name("poisson"))
    got = _loglik(params, units, spec)
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
    got = np.asarray(_loglik(params, units, ArrivalSpec.from_name("mmpp")))
    assert np.all(np.isfinite(got)) and np.all(got <= 1e-12), got.max()


# --- groups+hawkes, the time-of-day variants ------------------------------------------------

PROBS = np.array([0.6, 0.25, 0.15])  # group sizes 1, 2, 3


def _conv(probs, c_max):
    """``p^{*j}(c)`` for ``j = 1..c_max``, ``c = 0..c_max`` (numpy, by repeated convolution)."""
    p = np.concatenate([[0.0], probs, np.zeros(c_max)])[: c_max + 1]
    rows, cur = [], np.zeros(c_max + 1)
    cur[0] = 1.0
    for _ in range(c_max):
        cur = np.convolve(cur, p)[: c_max + 1]
        rows.append(cur)
    return np.array(rows)


def _brute_hawkes(t, window, delta, mu_of, alpha, beta, a0, probs=None, cuts=()):
    """Hawkes log-likelihood of quantised arrivals by brute force: each tick's count at the
    intensity reached at its end (compound Poisson over group counts ``j`` with weights
    ``(lambda delta)^j / j! p^{*j}(c)``), the excitation jumping by ``alpha beta E[j | c]``
    at the tick's end, and the compensator by ``quad`` over the window (baseline
    ``mu_of(s)``, piecewise constant with jumps at ``cuts``)."""
    t0, t1 = window
    ticks, counts = np.unique(np.floor((np.asarray(t) - t0) / delta + 1e-9).astype(int),
                              return_counts=True)  # fmt: skip
    ev = (ticks + 1) * delta
    jumps = np.zeros(ticks.size)
    tick_ll = 0.0
    for i, (e, c) in enumerate(zip(ev, counts, strict=True)):
        past = slice(0, i)
        lam = (
            mu_of(e - 1e-9)
            + a0 * np.exp(-beta * e)
            + np.sum(jumps[past] * np.exp(-beta * (e - ev[past])))
        )
        ld = lam * delta
        if probs is None:
            tick_ll += c * np.log(ld) - gammaln(c + 1.0)
            n_ev = c
        else:
            conv = _conv(probs, int(c))
            j = np.arange(1, int(c) + 1)
            w = ld**j / np.exp(gammaln(j + 1.0)) * conv[:, int(c)]
            tick_ll += np.log(w.sum())
            n_ev = float(np.sum(j * w) / w.sum())
        jumps[i] = alpha * beta * n_ev

    def intensity(s):
        past = ev < s
        return (
            mu_of(s) + a0 * np.exp(-beta * s) + np.sum(jumps[past] * np.exp(-beta * (s - ev[past])))
        )

    pts = np.concatenate([ev, np.asarray(cuts, float)])
    comp, err = quad(intensity, 0.0, t1 - t0, points=pts, limit=4 * pts.size + 50)
    assert err < 1e-7
    return tick_ll - comp


def test_groups_hawkes_loglik_matches_brute_force():
    mu, alpha, beta, a0, delta = 0.1, 0.5, 0.05, 0.1, 0.5
    rng = np.random.default_rng(21)
    ev = np.round(sample_hawkes_times(rng, mu, alpha, beta, (0.0, 400.0), burn=100.0), 1)
    sizes = rng.choice([1, 2, 3], size=ev.size, p=PROBS)
    t = np.repeat(ev, sizes)
    units = arrival_units(t, (0.0, 400.0), 1.0, delta, 40.0)
    c_max = int(np.max(units.tick_count))
    assert c_max >= 3 and t.size > 30
    log_p = jnp.log(jnp.concatenate([jnp.array([1e-300]), jnp.asarray(PROBS),
                                     jnp.full(c_max - 3, 1e-300)]))  # fmt: skip
    from are_stats.traffic._models import _log_convolution_powers

    conv = _log_convolution_powers(log_p.at[0].set(-jnp.inf), c_max)
    got = float(jnp.sum(hawkes_step_loglik(mu, alpha, beta, units.log_delta, units.steps,
                                           units.bin_weight.size, excitation0=a0,
                                           conv=conv)))  # fmt: skip
    want = _brute_hawkes(t, (0.0, 400.0), delta, lambda s: mu, alpha, beta, a0, PROBS)
    assert got == pytest.approx(want, rel=1e-9, abs=1e-7)


def test_flat_group_bursts_are_the_groups_likelihood():
    """No excitation (Hawkes) or equal rates (MMPP) with groups: bin by bin ``groups``."""
    rng = np.random.default_rng(1)
    ev = np.round(np.sort(rng.uniform(0, 300, 50)), 1)
    t = np.repeat(ev, rng.choice([1, 2, 3], size=ev.size, p=PROBS))
    units = arrival_units(t, (0.0, 300.0), 2.0, 0.5, 25.0)
    base = {"event_rate": 0.08, "log_area": np.log(2.0), "group_size_probs": jnp.asarray(PROBS)}
    want = _loglik(base, units, ArrivalSpec.from_name("groups"))
    for name in ("groups+hawkes", "groups+mmpp"):
        params = {**base, "hawkes_branching": 0.0, "hawkes_decay": 0.5, "mmpp_contrast": 0.0,
                  "mmpp_switch": jnp.array([0.1, 0.3])}  # fmt: skip
        got = _loglik(params, units, ArrivalSpec.from_name(name))
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-9, atol=1e-9)


DAY_S, TOD = 600.0, np.array([0.4, 1.6, 0.7, 1.3, 0.5, 1.5])  # a 'day' of six 100 s periods
OFFSET = 30.0  # time of day of t = 0: boundaries at t = 70, 170, ...


def _tod_of(s):
    return TOD[period_of(np.asarray(s, float), OFFSET, TOD.size, DAY_S)]


def _brute_mmpp_tod(t, window, delta, lam, switch):
    """Whole-window MMPP log-likelihood with rates ``lam * tod(t)`` by scipy's expm, walked
    through the ticks and the boundaries of the periods."""
    t0, t1 = window
    ticks, counts = np.unique(np.floor((np.asarray(t) - t0) / delta + 1e-9).astype(int),
                              return_counts=True)  # fmt: skip
    cuts = np.arange(70.0, t1 - t0, 100.0)
    pi = np.array([switch[1], switch[0]]) / switch.sum()
    alpha, pos = pi.copy(), 0.0

    def walk(alpha, pos, to):  # empty stretch, cut at the boundaries
        for b in [*cuts[(cuts > pos) & (cuts < to)], to]:
            f = float(_tod_of(0.5 * (pos + b)))
            alpha = alpha @ expm((_q(switch) - np.diag(lam * f)) * (b - pos))
            pos = b
        return alpha

    for j, c in zip(ticks, counts, strict=True):
        s = j * delta
        alpha = walk(alpha, pos, s)
        la = lam * float(_tod_of(s + delta / 2)) * delta
        alpha = alpha * la**c * np.exp(-la - gammaln(c + 1)) @ expm(_q(switch) * delta)
        pos = s + delta
    alpha = walk(alpha, pos, t1 - t0)
    return float(np.log(alpha.sum()))


def test_mmpp_time_of_day_loglik_matches_brute_force():
    rng = np.random.default_rng(13)
    t = np.round(sample_mmpp_times(rng, LAM, SWITCH, (0.0, 600.0), tod=TOD, offset=OFFSET,
                                   period=DAY_S), 1)  # fmt: skip
    units = arrival_units(t, (0.0, 600.0), 1.0, 0.5, 50.0, clock_offset=OFFSET,
                          n_periods=TOD.size, period=DAY_S)  # fmt: skip
    assert np.sum(units.steps.tick < 0) > units.bin_weight.sum()  # the boundaries are steps
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    params = {
        "event_rate": mean,
        "log_area": 0.0,
        "mmpp_switch": jnp.asarray(SWITCH),
        "mmpp_contrast": float(np.log(LAM[1] / LAM[0])),
        "arrival_tod": jnp.asarray(TOD),
    }
    got = float(jnp.sum(_loglik(params, units, ArrivalSpec.from_name("mmpp+time-of-day"))))
    want = _brute_mmpp_tod(t, (0.0, 600.0), 0.5, LAM, SWITCH)
    assert t.size > 20
    assert got == pytest.approx(want, rel=1e-9, abs=1e-8)


@pytest.mark.parametrize("groups", [False, True])
def test_hawkes_time_of_day_compensator_matches_numerical_integration(groups):
    mu, alpha, beta, a0, delta = 0.15, 0.5, 0.05, 0.1, 0.5
    rng = np.random.default_rng(17)
    ev = np.round(sample_hawkes_times(rng, mu, alpha, beta, (0.0, 600.0), burn=100.0, tod=TOD,
                                      offset=OFFSET, period=DAY_S), 1)  # fmt: skip
    probs = PROBS if groups else None
    t = np.repeat(ev, rng.choice([1, 2, 3], size=ev.size, p=PROBS)) if groups else ev
    units = arrival_units(t, (0.0, 600.0), 1.0, delta, 60.0, clock_offset=OFFSET,
                          n_periods=TOD.size, period=DAY_S)  # fmt: skip
    params = {"event_rate": mu / (1 - alpha), "log_area": 0.0, "hawkes_branching": alpha,
              "hawkes_decay": beta, "arrival_tod": jnp.asarray(TOD),
              "group_size_probs": jnp.asarray(np.concatenate(
                  [PROBS, np.full(int(units.tick_count.max()) - 3, 1e-300)]))}  # fmt: skip
    name = "groups+hawkes+time-of-day" if groups else "hawkes+time-of-day"
    # the model starts from the stationary excitation mu alpha / (1 - alpha)
    got = float(jnp.sum(_loglik(params, units, ArrivalSpec.from_name(name))))
    a0 = mu * alpha / (1 - alpha)
    want = _brute_hawkes(t, (0.0, 600.0), delta, lambda s: mu * float(_tod_of(s)), alpha, beta,
                         a0, probs, cuts=np.arange(70.0, 600.0, 100.0))  # fmt: skip
    assert t.size > 30
    assert got == pytest.approx(want, rel=1e-8, abs=1e-6)


def _mle_grad(nll, x0):
    """Maximum likelihood by L-BFGS with JAX gradients."""
    vg = jax.jit(jax.value_and_grad(nll))

    def fun(v):
        f, g = vg(jnp.asarray(v))
        return float(f), np.asarray(g, float)

    res = minimize(fun, x0, jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    assert np.isfinite(res.fun)
    return res.x


HOURS20 = (0.0, 72000.0)


def test_groups_hawkes_parameters_are_recovered():
    """Maximum likelihood on 20 h drawn by the one sampler (a burst of groups): rate within
    15%, alpha 0.1 absolute, decay 30%, group-size probabilities 0.05 absolute."""
    mu, alpha, beta = 0.05, 0.6, 1 / 30.0
    draw = {"event_rate": mu / (1 - alpha), "stay_mean": 30.0, "hawkes_branching": alpha,
            "hawkes_decay": beta, "group_size_probs": PROBS}  # fmt: skip
    pop = sample_population(np.random.default_rng(31), draw, TrafficLaws(arrivals="groups+hawkes"),
                            HOURS20[1], 1.0, start="empty")  # fmt: skip
    units = arrival_units(pop["t_arrive"], HOURS20, 1.0, 0.1, 120.0, group=pop["group"])
    k = int(units.tick_count.max())
    spec = ArrivalSpec.from_name("groups+hawkes")

    def nll(x):
        p = {
            "event_rate": jnp.exp(x[0]),
            "log_area": 0.0,
            "hawkes_branching": jax.nn.sigmoid(x[1]),
            "hawkes_decay": jnp.exp(x[2]),
            "group_size_probs": jax.nn.softmax(jnp.concatenate([jnp.zeros(1), x[3:]])),
        }
        return -jnp.sum(arrival_unit_loglik(p, units, spec))

    x = _mle_grad(nll, np.concatenate([[np.log(0.1), 0.0, np.log(0.1)], np.zeros(k - 1)]))
    probs = np.asarray(jax.nn.softmax(jnp.concatenate([jnp.zeros(1), jnp.asarray(x[3:])])))
    assert float(jax.nn.sigmoid(x[1])) == pytest.approx(alpha, abs=0.1)
    assert np.exp(x[0]) == pytest.approx(mu / (1 - alpha), rel=0.15)
    assert np.exp(x[2]) == pytest.approx(beta, rel=0.3)
    np.testing.assert_allclose(probs[:3], PROBS, atol=0.05)


TOD4, HOUR = np.array([0.5, 1.5, 0.8, 1.2]), 3600.0  # a 'day' of one hour, four periods


def _tod_units(t, group=None):
    return arrival_units(t, HOURS20, 1.0, 0.1, 120.0, group=group, clock_offset=0.0,
                         n_periods=4, period=HOUR)  # fmt: skip


def test_mmpp_time_of_day_is_recovered():
    """20 h ('days' of one hour, four periods): switching rates and intensities within 25%,
    the time-of-day factors within 10%."""
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    draw = {"event_rate": mean, "stay_mean": 30.0, "mmpp_factor": LAM / mean,
            "mmpp_switch": SWITCH, "arrival_tod": TOD4}  # fmt: skip
    laws = TrafficLaws(arrivals="mmpp+time-of-day", clock_offset=0.0, period=HOUR)
    pop = sample_population(np.random.default_rng(32), draw, laws, HOURS20[1], 1.0, start="empty")
    units = _tod_units(pop["t_arrive"])
    spec = ArrivalSpec.from_name("mmpp+time-of-day")

    def nll(x):
        p = {"event_rate": jnp.exp(x[0]), "log_area": 0.0, "mmpp_contrast": jnp.exp(x[1]),
             "mmpp_switch": jnp.exp(x[2:4]),
             "arrival_tod": 4 * jax.nn.softmax(jnp.concatenate([jnp.zeros(1), x[4:]]))}  # fmt: skip
        return -jnp.sum(arrival_unit_loglik(p, units, spec))

    x = _mle_grad(nll, np.concatenate([np.log([mean, 1.0, 1e-2, 1e-2]), np.zeros(3)]))
    lam_hat = np.exp(x[0]) * np.asarray(mmpp_factors(np.exp(x[1]), np.exp(x[2:4])))
    tod_hat = 4 * np.asarray(jax.nn.softmax(jnp.concatenate([jnp.zeros(1), jnp.asarray(x[4:])])))
    np.testing.assert_allclose(np.exp(x[2:4]), SWITCH, rtol=0.25)
    np.testing.assert_allclose(lam_hat, LAM, rtol=0.25)
    np.testing.assert_allclose(tod_hat, TOD4, rtol=0.1)


def test_hawkes_time_of_day_is_recovered():
    """20 h ('days' of one hour): rate within 15%, alpha 0.1 absolute, decay 30%, the
    time-of-day factors within 10%."""
    mu, alpha, beta = 0.05, 0.6, 1 / 30.0
    draw = {"event_rate": mu / (1 - alpha), "stay_mean": 30.0, "hawkes_branching": alpha,
            "hawkes_decay": beta, "arrival_tod": TOD4}  # fmt: skip
    laws = TrafficLaws(arrivals="hawkes+time-of-day", clock_offset=0.0, period=HOUR)
    pop = sample_population(np.random.default_rng(33), draw, laws, HOURS20[1], 1.0, start="empty")
    units = _tod_units(pop["t_arrive"])
    spec = ArrivalSpec.from_name("hawkes+time-of-day")

    def nll(x):
        p = {
            "event_rate": jnp.exp(x[0]),
            "log_area": 0.0,
            "hawkes_branching": jax.nn.sigmoid(x[1]),
            "hawkes_decay": jnp.exp(x[2]),
            "arrival_tod": 4 * jax.nn.softmax(jnp.concatenate([jnp.zeros(1), x[3:]])),
        }
        return -jnp.sum(arrival_unit_loglik(p, units, spec))

    x = _mle_grad(nll, np.array([np.log(0.1), 0.0, np.log(0.1), 0.0, 0.0, 0.0]))
    tod_hat = 4 * np.asarray(jax.nn.softmax(jnp.concatenate([jnp.zeros(1), jnp.asarray(x[3:])])))
    assert float(jax.nn.sigmoid(x[1])) == pytest.approx(alpha, abs=0.1)
    assert np.exp(x[0]) == pytest.approx(mu / (1 - alpha), rel=0.15)
    assert np.exp(x[2]) == pytest.approx(beta, rel=0.3)
    np.testing.assert_allclose(tod_hat, TOD4, rtol=0.1)


@pytest.mark.parametrize("name, w", [("groups+hawkes", 10.0), ("groups+hawkes", 600.0),
                                     ("groups+mmpp", 60.0)])  # fmt: skip
def test_generated_group_burst_dispersion_matches_the_closed_form(name, w):
    """Artefacts from the one sampler (each event a group): index of dispersion within 12%
    of ``E[S^2] / E[S] + E[S] (I_events(w) - 1)``."""
    alpha, beta = 0.5, 0.1
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    draw = {"event_rate": 0.2 if "hawkes" in name else mean, "stay_mean": 30.0,
            "hawkes_branching": alpha, "hawkes_decay": beta, "mmpp_factor": LAM / mean,
            "mmpp_switch": SWITCH, "group_size_probs": PROBS}  # fmt: skip
    laws = TrafficLaws(arrivals=name)
    rng = np.random.default_rng(14)
    got = [_dispersion(sample_population(rng, draw, laws, 1e5, 1.0)["t_arrive"], w, 1e5)
           for _ in range(20)]  # fmt: skip
    events = (hawkes_count_dispersion(alpha, beta, w) if "hawkes" in name
              else mmpp_count_dispersion(LAM, SWITCH, w))  # fmt: skip
    want = float(group_count_dispersion(events, PROBS))
    assert want > float(events) + 0.5  # groups add to the events' dispersion
    assert np.mean(got) == pytest.approx(want, rel=0.12)


@pytest.mark.parametrize("name", ["mmpp+time-of-day", "hawkes+time-of-day"])
def test_generated_time_of_day_bursts_follow_the_profile(name):
    """Arrivals from the one sampler, 100 'days' of one hour: the mean count in each period
    is ``rate * tod * 900 s`` within 5% (the Hawkes decay, 10 s, is short next to a
    period)."""
    mean = float(np.array([SWITCH[1], SWITCH[0]]) / SWITCH.sum() @ LAM)
    draw = {"event_rate": mean, "stay_mean": 30.0, "mmpp_factor": LAM / mean,
            "mmpp_switch": SWITCH, "hawkes_branching": 0.5, "hawkes_decay": 0.1,
            "arrival_tod": TOD4}  # fmt: skip
    laws = TrafficLaws(arrivals=name, clock_offset=0.0, period=HOUR)
    t = sample_population(np.random.default_rng(15), draw, laws, 100 * HOUR, 1.0)["t_arrive"]
    t = t[t > 0]
    per = np.bincount(period_of(t, 0.0, 4, HOUR), minlength=4) / 100.0
    np.testing.assert_allclose(per, mean * TOD4 * 900.0, rtol=0.05)
