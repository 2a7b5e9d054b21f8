"""Birth-death process N(t) (paper Sect. 3.2): against scipy, expm of the generator, simulation.

False-failure rates: every seeded statistical check below uses ``ALPHA = 1e-3`` (two-sided
z-tests at |z| < 3.29, chi-square tests via ``tests.helpers.chisquare_gof``, binomial
acceptance regions with 5e-4 in each tail); with the fixed seeds the outcome is deterministic.
The module runs 16 such checks, so a correct implementation would fail one of them for a
random seed with probability below 1.6e-2.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
import scipy.linalg
from scipy import special, stats
from scipy.optimize import minimize

from are_stats.fitting import count_path
from are_stats.traffic import (
    BirthDeath,
    BirthDeathFit,
    TrafficLaws,
    _gillespie,
    birth_death_loglik,
    fit_birth_death,
    hac_bandwidth,
    sample_population,
)
from tests.helpers import ALPHA, assert_allclose, chisquare_gof

Z = stats.norm.isf(ALPHA / 2)  # 3.29

LAWS = [("linear", 2.0, 0.5), ("constant", 1.0, 1.6)]


def generator(lam: float, mu: float, n_top: int, linear: bool) -> np.ndarray:
    """Generator Q of the chain truncated to {0..n_top} (births blocked at the top)."""
    q = np.zeros((n_top + 1, n_top + 1))
    for i in range(n_top + 1):
        if i < n_top:
            q[i, i + 1] = lam
        if i > 0:
            q[i, i - 1] = mu * i if linear else mu
        q[i, i] = -q[i].sum()
    return q


# ---------------------------------------------------------------------------------------
# stationary law
# ---------------------------------------------------------------------------------------


def test_stationary_linear_is_poisson():
    bd = BirthDeath(2.0, 0.1)
    k = np.arange(200)
    assert_allclose(bd.stationary_pmf(k), stats.poisson.pmf(k, 20.0), rtol=1e-12)
    assert_allclose(bd.stationary_logpmf(k), stats.poisson.logpmf(k, 20.0), rtol=1e-12)
    assert abs(bd.stationary_pmf(k).sum() - 1) < 1e-12
    assert bd.stationary_mean() == pytest.approx(20.0) and bd.stationary_var() == 20.0


def test_stationary_constant_is_geometric():
    bd = BirthDeath(1.0, 1.6, death="constant")
    r = 1.0 / 1.6
    k = np.arange(200)
    # scipy's geom lives on {1, 2, ...}: N = G - 1
    assert_allclose(bd.stationary_pmf(k), stats.geom.pmf(k + 1, 1 - r), rtol=1e-12)
    assert abs(bd.stationary_pmf(k).sum() - 1) < 1e-12
    assert bd.stationary_mean() == pytest.approx(stats.geom.mean(1 - r) - 1, rel=1e-12)
    assert bd.stationary_var() == pytest.approx(stats.geom.var(1 - r), rel=1e-12)


@pytest.mark.parametrize("death, lam, mu, t_end", [("linear", 2.0, 0.5, 40.0), LAWS[1] + (160.0,)])
def test_long_run_occupancy_matches_stationary_law(death, lam, mu, t_end):
    # from n0 = 0 the law at t_end is within e^{-20} of stationarity (linear: e^{-mu t};
    # constant: relaxation rate (sqrt(mu) - sqrt(lam))^2); 4000 independent paths.
    bd = BirthDeath(lam, mu, death=death)
    x = bd.simulate(jax.random.key(11), 0, t_end, 4000)[:, 0]
    chisquare_gof(x, bd.stationary_pmf)


# ---------------------------------------------------------------------------------------
# transient law
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("death, lam, mu", LAWS)
def test_transition_pmf_equals_expm_of_generator(death, lam, mu):
    bd = BirthDeath(lam, mu, death=death)
    n_top = 220
    for dt in (0.3, 2.5, 9.0):
        exact = scipy.linalg.expm(generator(lam, mu, n_top, death == "linear") * dt)
        ours = bd.transition_pmf(np.arange(40)[:, None], np.arange(80)[None, :], dt)
        assert np.abs(ours - exact[:40, :80]).max() < 1e-10


@pytest.mark.parametrize("death, lam, mu", LAWS)
def test_transition_pmf_sums_to_one(death, lam, mu):
    bd = BirthDeath(lam, mu, death=death)
    for n0 in (0, 3, 25):
        for dt in (0.0, 0.1, 1.0, 30.0):
            p = bd.transition_pmf(n0, np.arange(400), dt)
            assert abs(p.sum() - 1) < 1e-11
    assert bd.transition_pmf(4, 4, 0.0) == 1.0 and bd.transition_pmf(4, 5, 0.0) == 0.0


def test_linear_logpmf_large_counts_against_scipy_convolution():
    # exact log of Binomial(n0, p) * Poisson(m) by scipy terms; counts in the thousands and
    # probabilities far below the float64 range.
    lam, mu, dt = 300.0, 0.1, 2.0
    bd = BirthDeath(lam, mu)
    p = np.exp(-mu * dt)
    m = lam / mu * (1 - p)
    for n0, n in [(3000, 3000), (2500, 2900), (3000, 1000), (0, 600), (1200, 0), (5, 4000)]:
        k = np.arange(min(n0, n) + 1)
        ref = special.logsumexp(stats.binom.logpmf(k, n0, p) + stats.poisson.logpmf(n - k, m))
        assert_allclose(bd.transition_logpmf(n0, n, dt), ref, rtol=1e-11)
    # vectorised call with mixed k-ranges equals the scalar calls
    n0s, ns = np.array([[0], [40], [3000]]), np.array([0, 50, 2990])
    grid = bd.transition_logpmf(n0s, ns, dt)
    one = np.array([[bd.transition_logpmf(a, b, dt) for b in ns] for a in n0s[:, 0]])
    assert_allclose(grid, one, rtol=1e-13)


@pytest.mark.parametrize("death, lam, mu", LAWS)
def test_mean_var_equal_moments_of_expm(death, lam, mu):
    bd = BirthDeath(lam, mu, death=death)
    k = np.arange(301)
    for t, n0 in [(0.7, 0), (2.5, 12), (15.0, 40)]:
        row = scipy.linalg.expm(generator(lam, mu, 300, death == "linear") * t)[n0]
        m1 = row @ k
        assert_allclose(bd.mean(t, n0), m1, rtol=1e-10)
        assert_allclose(bd.var(t, n0), row @ k**2 - m1**2, rtol=1e-9)
    assert bd.mean(np.array([1.0, 2.0]), 3).shape == (2,)


@pytest.mark.parametrize("death, lam, mu", LAWS)
def test_simulated_transient_law(death, lam, mu):
    # 20000 independent paths from n0 = 10, observed at t = 1.5 (and at 0, 0.4):
    # mean z-test, variance z-test (se from the exact 4th central moment), chi-square.
    bd = BirthDeath(lam, mu, death=death)
    n0, t = 10, 1.5
    x = bd.simulate(jax.random.key(5), n0, t, 20000, times=[0.0, 0.4, t])
    assert np.all(x[:, 0] == n0)
    x = x[:, 2]
    k = np.arange(400)
    pk = bd.transition_pmf(n0, k, t)
    mean, var = float(bd.mean(t, n0)), float(bd.var(t, n0))
    mu4 = pk @ (k - mean) ** 4
    n = x.size
    assert abs(x.mean() - mean) < Z * np.sqrt(var / n)
    assert abs(x.var(ddof=1) - var) < Z * np.sqrt((mu4 - var**2) / n)
    chisquare_gof(x, lambda kk: bd.transition_pmf(n0, kk, t))


def test_simulate_events_consistent_and_never_truncated():
    bd = BirthDeath(2.0, 0.5)
    key = jax.random.key(7)
    times = np.array([0.0, 1.0, 2.5, 6.0])
    counts = bd.simulate(key, 3, 6.0, 50, times=times)
    ev = bd.simulate_events(key, 3, 6.0, 50, times=times)
    assert np.array_equal(ev.observed, counts)
    # a first chunk far too short is extended, never truncated: identical record
    short = _gillespie.simulate_events(key, 2.0, 0.5, np.full(50, 3), 6.0, times, True, chunk=3)
    for a, b in zip(ev, short, strict=True):
        assert np.array_equal(a, b)
    for i in range(50):
        ne = ev.n_events[i]
        tt, kk = ev.times[i, :ne], ev.kinds[i, :ne]
        assert np.all(np.diff(tt) > 0) and np.all(tt <= 6.0) and np.all(kk != 0)
        assert np.all(np.isinf(ev.times[i, ne:])) and np.all(ev.kinds[i, ne:] == 0)
        path = 3 + np.cumsum(kk)
        assert np.all(path >= 0) and np.array_equal(ev.counts[i, :ne], path)
        at = 3 + np.array([kk[tt <= s].sum() for s in times])
        assert np.array_equal(at, counts[i])


@pytest.mark.parametrize("linear", [True, False])
def test_padded_counts_are_the_unpadded_run(linear):
    """simulate_counts pads paths and times to shared program sizes: the counts are those of
    the same loop run at the exact sizes, bit for bit (the draws of the real paths are the
    unpadded ones, ``uniform(k, (2, n_paths))`` as in simulate_events; the padded paths and
    times touch nothing)."""
    key = jax.random.key(11)
    n0 = np.array([0, 1, 4, 2, 7])
    times = np.array([0.5, 1.0, 2.0, 2.0, 4.5, 5.0])  # padded to 64, as a 3-path panel test
    padded = _gillespie.simulate_counts(key, 1.5, 0.4, n0, 5.0, times, linear)
    exact, _ = _gillespie._counts_loop(
        _gillespie._stream_key(key), 1.5, 0.4, n0, np.int64(5), 5.0, times, np.bool_(linear), False
    )
    assert padded.shape == (5, 6) and padded.dtype == np.int64
    assert np.array_equal(padded, np.asarray(exact))


# ---------------------------------------------------------------------------------------
# panel likelihood and MLE
# ---------------------------------------------------------------------------------------


def _brute_loglik(lam, mu, times, counts, linear=True):
    """Sum of log transition probabilities, one scipy convolution per consecutive pair."""
    tot = 0.0
    for dt, a, b in zip(np.diff(times), counts[:-1], counts[1:], strict=True):
        p = np.exp(-mu * dt)
        k = np.arange(min(a, b) + 1)
        tot += special.logsumexp(
            stats.binom.logpmf(k, a, p) + stats.poisson.logpmf(b - k, lam / mu * (1 - p))
        )
    return tot


@pytest.fixture(scope="module")
def minutely():
    bd = BirthDeath(2.0, 0.1)
    t = np.arange(1001.0)
    n0 = int(np.random.default_rng(3).poisson(20.0))
    return t, bd.simulate(jax.random.key(2026), n0, 1000.0, 1, times=t)[0]


def test_loglik_equals_bruteforce(minutely):
    t, n = minutely
    rng = np.random.default_rng(0)
    tu = np.sort(rng.choice(np.arange(1001.0), 300, replace=False))  # unequal spacing
    nu = n[tu.astype(int)]
    for lam, mu in [(2.0, 0.1), (1.3, 0.3)]:
        assert_allclose(birth_death_loglik(lam, mu, t, n), _brute_loglik(lam, mu, t, n), 1e-11)
        assert_allclose(
            birth_death_loglik(lam, mu, tu, nu), _brute_loglik(lam, mu, tu, nu), rtol=1e-11
        )


def test_mle_recovers_rates_and_matches_direct_optimum(minutely):
    t, n = minutely
    fit = fit_birth_death(t, n)
    assert isinstance(fit, BirthDeathFit) and fit.converged
    assert fit.n_obs == 1001 and fit.n_transitions == 1000 and fit.n_distinct < 1000
    assert abs(fit.birth_rate - 2.0) < Z * fit.stderr[0]
    assert abs(fit.death_rate - 0.1) < Z * fit.stderr[1]
    # independent optimiser on the same likelihood
    res = minimize(
        lambda x: -birth_death_loglik(*np.exp(x), t, n),
        np.log([1.5, 0.2]),
        method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-10, "maxiter": 4000},
    )
    assert_allclose([fit.birth_rate, fit.death_rate], np.exp(res.x), rtol=1e-6)
    assert fit.loglik == pytest.approx(-res.fun, abs=1e-8)
    # observed information: central differences of the likelihood in log-rates
    h = 1e-4
    x0 = np.log([fit.birth_rate, fit.death_rate])

    def f(x):
        return birth_death_loglik(*np.exp(x), t, n)

    e = np.eye(2) * h
    H = np.array(
        [
            [
                (
                    f(x0 + e[i] + e[j])
                    - f(x0 + e[i] - e[j])
                    - f(x0 - e[i] + e[j])
                    + f(x0 - e[i] - e[j])
                )
                / (4 * h * h)
                for j in range(2)
            ]
            for i in range(2)
        ]
    )
    assert_allclose(fit.log_cov, np.linalg.inv(-H), rtol=1e-4)
    jac = np.diag([fit.birth_rate, fit.death_rate])
    assert_allclose(fit.cov, jac @ fit.log_cov @ jac, rtol=1e-12)
    assert_allclose(fit.stderr, np.sqrt(np.diag(fit.cov)), rtol=1e-12)
    ci = fit.confint(0.95)
    assert ci.shape == (2, 2) and np.all(ci[:, 0] < [fit.birth_rate, fit.death_rate])
    assert np.all(ci[:, 1] > [fit.birth_rate, fit.death_rate])


def test_confidence_intervals_cover_at_nominal_rate():
    # 200 independent datasets of 1001 minutely counts from the stationary law; coverage of
    # the 95% intervals must lie in the binomial(200, 0.95) acceptance region (5e-4 per tail).
    bd = BirthDeath(2.0, 0.1)
    n_sets = 200
    t = np.arange(1001.0)
    n0 = np.random.default_rng(99).poisson(20.0, n_sets)
    data = bd.simulate(jax.random.key(99), n0, 1000.0, n_sets, times=t)
    truth = np.array([2.0, 0.1])
    hits_log = np.zeros(2, dtype=int)
    hits_wald = np.zeros(2, dtype=int)
    hits_robust = np.zeros(2, dtype=int)
    ratios = []
    for row in data:
        fit = fit_birth_death(t, row)
        assert fit.converged
        ci = fit.confint(0.95)
        hits_log += (ci[:, 0] < truth) & (truth < ci[:, 1])
        est = np.array([fit.birth_rate, fit.death_rate])
        hits_wald += np.abs(est - truth) < 1.959964 * fit.stderr
        ci = fit.confint(0.95, kind="robust")
        hits_robust += (ci[:, 0] < truth) & (truth < ci[:, 1])
        ratios.append(fit.stderr_robust / fit.stderr)
    lo = stats.binom.ppf(ALPHA / 2, n_sets, 0.95)
    hi = stats.binom.isf(ALPHA / 2, n_sets, 0.95)
    assert np.all((hits_log >= lo) & (hits_log <= hi)), (hits_log, lo, hi)
    assert np.all((hits_wald >= lo) & (hits_wald <= hi)), (hits_wald, lo, hi)
    # on the model's own data the robust (HAC) errors agree with the model-based ones and
    # cover at the nominal rate too (measured: median ratio 0.99, 1.00; coverage 0.945, 0.945)
    assert np.all((hits_robust >= lo) & (hits_robust <= hi)), (hits_robust, lo, hi)
    med = np.median(ratios, axis=0)
    assert np.all((med > 0.9) & (med < 1.1)), med


def test_panel_of_series_equals_sum_of_series():
    bd = BirthDeath(2.0, 0.5)
    t = np.array([0.0, 0.5, 2.0, 2.1, 5.0, 9.0])
    panel = bd.simulate(jax.random.key(1), 4, 9.0, 3, times=t)
    total = sum(birth_death_loglik(2.0, 0.5, t, row) for row in panel)
    assert_allclose(birth_death_loglik(2.0, 0.5, t, panel), total, rtol=1e-12)


def test_constant_law_fit():
    bd = BirthDeath(2.0, 2.5, death="constant")
    t = np.arange(1001.0)
    n = bd.simulate(jax.random.key(3), 4, 1000.0, 1, times=t)[0]
    fit = fit_birth_death(t, n, death="constant")
    assert fit.converged and fit.death == "constant"
    assert abs(fit.birth_rate - 2.0) < Z * fit.stderr[0]
    assert abs(fit.death_rate - 2.5) < Z * fit.stderr[1]
    res = minimize(
        lambda x: -birth_death_loglik(*np.exp(x), t, n, death="constant"),
        np.log([1.5, 2.0]),
        method="Nelder-Mead",
        options={"xatol": 1e-9, "fatol": 1e-9},
    )
    assert_allclose([fit.birth_rate, fit.death_rate], np.exp(res.x), rtol=1e-5)
    # the likelihood of the constant law equals one built from expm of the generator
    q = generator(2.0, 2.5, 150, linear=False)
    p1 = scipy.linalg.expm(q)
    ref = np.log(p1[n[:-1], n[1:]]).sum()
    assert_allclose(birth_death_loglik(2.0, 2.5, t, n, death="constant"), ref, rtol=1e-10)


# ---------------------------------------------------------------------------------------
# robust standard errors (issue 14, count panels)
# ---------------------------------------------------------------------------------------


def _fd_scores(fit, t, n, h=1e-5):
    """(T, 2) central differences of each transition's log-probability in the log-rates."""
    x0 = np.log([fit.birth_rate, fit.death_rate])
    out = np.empty((n.size - 1, 2))
    for i in range(2):
        e = np.zeros(2)
        e[i] = h
        up = BirthDeath(*np.exp(x0 + e)).transition_logpmf(n[:-1], n[1:], np.diff(t))
        down = BirthDeath(*np.exp(x0 - e)).transition_logpmf(n[:-1], n[1:], np.diff(t))
        out[:, i] = (up - down) / (2 * h)
    return out


def test_hac_sandwich_equals_direct_computation(minutely):
    # the sandwich from finite differences of scipy-checked transition probabilities,
    # Bartlett weights written out: the closed-form scores and the bookkeeping agree
    t, n = minutely
    s = _fd_scores(fit_birth_death(t, n), t, n)
    for lags in (0, 3, 40):
        fit = fit_birth_death(t, n, bandwidth=lags)
        meat = s.T @ s
        for lag in range(1, lags + 1):
            g = s[lag:].T @ s[:-lag]
            meat += (1 - lag / (lags + 1)) * (g + g.T)
        b = (lags + 1) / s.shape[0]
        meat /= 1 - b + b * b / 3
        ref = fit.log_cov @ meat @ fit.log_cov
        assert fit.stderr_method == "hac" and fit.bandwidth == lags and fit.n_boot == 0
        assert_allclose(fit.log_cov_robust, ref, rtol=1e-5)
        jac = np.diag([fit.birth_rate, fit.death_rate])
        assert_allclose(fit.cov_robust, jac @ ref @ jac, rtol=1e-5)
        assert_allclose(fit.stderr_robust, np.sqrt(np.diag(fit.cov_robust)), rtol=1e-12)


def test_hac_within_series_only():
    # two series: lags never pair the end of one series with the start of the next
    bd = BirthDeath(2.0, 0.5)
    t = np.arange(41.0)
    panel = bd.simulate(jax.random.key(5), 4, 40.0, 2, times=t)
    fit = fit_birth_death(t, panel, bandwidth=2)
    x0 = np.log([fit.birth_rate, fit.death_rate])
    s = np.stack([_fd_scores(fit, t, row) for row in panel])
    meat = np.einsum("sta,stb->ab", s, s)
    for lag in (1, 2):
        g = np.einsum("sta,stb->ab", s[:, lag:], s[:, :-lag])
        meat += (1 - lag / 3) * (g + g.T)
    b = 3 / 80  # all transitions of both series: only their pooled score sum is zero
    meat /= 1 - b + b * b / 3
    assert np.allclose(x0, np.log([fit.birth_rate, fit.death_rate]))
    assert_allclose(fit.log_cov_robust, fit.log_cov @ meat @ fit.log_cov, rtol=1e-5)


def test_hac_bandwidth_rule():
    # Andrews' AR(1) plug-in with the counts' lag-1 autocorrelation rho (pooled over series)
    def rule(rho, n_t):
        alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
        return min(int(np.ceil(1.1447 * (alpha * n_t) ** (1 / 3))) - 1, n_t - 1)

    assert rule(np.exp(-0.1), 1000) == 53  # the docstring's example
    bd = BirthDeath(2.0, 0.1)
    counts = bd.simulate(jax.random.key(8), [20, 25], 500.0, 2, times=np.arange(501.0))
    x = counts - counts.mean(axis=1, keepdims=True)
    rho = (x[:, 1:] * x[:, :-1]).sum() / (x * x).sum()
    assert hac_bandwidth(counts) == rule(rho, 500)
    assert hac_bandwidth(np.tile([3, 3, 4, 4], 50)) == 0  # no persistence, no lags
    assert hac_bandwidth([1, 2]) == 0  # never more lags than transitions - 1


def _group_panels(rng, n_sets, t, birth, death, probs):
    """Counts of the toolkit's group process (members share arrival time and stay)."""
    probs = np.asarray(probs)
    mean_size = float(np.arange(1, probs.size + 1) @ probs)
    draw = {"event_rate": birth / mean_size, "stay_mean": 1 / death, "group_size_probs": probs}
    laws = TrafficLaws(arrivals="groups")
    out = np.empty((n_sets, t.size), dtype=np.int64)
    for i in range(n_sets):
        pop = sample_population(rng, draw, laws, float(t[-1]), 1.0)
        out[i] = count_path(pop["t_arrive"], pop["t_leave"], t)
    return out


def test_robust_errors_cover_under_group_arrivals():
    """Groups of 1-4 (equally likely) arrive together and leave together.

    ``sample_population(TrafficLaws(arrivals="groups"))`` with member arrival rate 2 and
    mean stay 10, counted once a time unit (1001 counts, var/mean about 3). The panel model
    (single Poisson arrivals, independent stays) is then wrong, and its MLE is biased: it
    explains jumps of whole groups by faster turnover, so **both** rates come out about
    2.5x too large (measured 2.47, 2.46; their ratio, the stationary mean, stays unbiased).
    Standard errors can only be honest about the estimator's spread, so intervals are
    checked

    * for the two rates, around the panel model's best approximation (the pooled MLE of 400
      further independent series, whose own error is 1/20 of one series'), and
    * for the stationary mean ``birth/death``, around the **truth** (20).

    Measured on these seeds over 200 series: model-based 95% coverage 0.795 and 0.765 for
    the rates and 0.58 for the stationary mean; robust (HAC, 38-67 lags) 0.90, 0.895 and
    0.925; median robust/model ratio 1.5 and 1.4 (another seed: model 0.82, 0.795, 0.53;
    robust 0.935, 0.91, 0.905). So the robust coverage is about 0.91, a little below
    nominal, and the model-based one about 0.80 for the rates and 0.55 for the mean.
    Bands: each robust rate coverage >= 0.85 and each model-based one <= 0.89 (the
    binomial(200, 0.95) lower acceptance bound is 0.905); for the stationary mean model
    <= 0.70, robust >= 0.82. Each bound is at least 3 binomial standard deviations from
    those true coverages: false-failure rate below 1.5e-3 per check, 1e-2 for the test.
    """
    birth, death = 2.0, 0.1
    probs = [0.25, 0.25, 0.25, 0.25]
    t = np.arange(1001.0)
    rng = np.random.default_rng(14)
    pooled = fit_birth_death(t, _group_panels(rng, 400, t, birth, death, probs))
    target = np.log([pooled.birth_rate, pooled.death_rate])
    bias = np.exp(target) / [birth, death]
    assert np.all(bias > 1.8), bias  # measured 2.45 and 2.45
    assert abs(np.log(bias[0] / bias[1])) < 0.03  # the stationary mean is unbiased
    data = _group_panels(rng, 200, t, birth, death, probs)
    assert np.mean(data.var(axis=1) / data.mean(axis=1)) > 2.0  # overdispersed
    d = np.array([1.0, -1.0])  # log(birth / death)
    z = stats.norm.isf(0.025)
    hits = {"model": np.zeros(3), "robust": np.zeros(3)}
    ratios = []
    for row in data:
        fit = fit_birth_death(t, row)
        est = np.log([fit.birth_rate, fit.death_rate])
        for kind, cov in (("model", fit.log_cov), ("robust", fit.log_cov_robust)):
            se = np.sqrt(np.diag(cov))
            hits[kind][:2] += np.abs(est - target) < z * se
            hits[kind][2] += abs(d @ est - np.log(birth / death)) < z * np.sqrt(d @ cov @ d)
        ratios.append(fit.stderr_robust / fit.stderr)
    cover = {k: v / len(data) for k, v in hits.items()}
    assert np.all(cover["robust"][:2] >= 0.85), cover
    assert np.all(cover["model"][:2] <= 0.89), cover
    assert cover["robust"][2] >= 0.82 and cover["model"][2] <= 0.70, cover
    assert np.all(np.median(ratios, axis=0) > 1.2), np.median(ratios, axis=0)


def test_block_bootstrap_agrees_with_hac_and_is_seeded():
    rng = np.random.default_rng(15)
    t = np.arange(1001.0)
    data = _group_panels(rng, 12, t, 2.0, 0.1, [0.25, 0.25, 0.25, 0.25])
    ratio, boots = [], []
    for i, row in enumerate(data):
        hac = fit_birth_death(t, row)
        boot = fit_birth_death(t, row, robust="block-bootstrap", key=jax.random.key(i), n_boot=100)
        assert boot.stderr_method == "block-bootstrap" and boot.n_boot == 100
        assert boot.bandwidth == hac.bandwidth + 1  # blocks of L + 1 transitions
        assert boot.birth_rate == hac.birth_rate  # same point estimate
        ratio.append(boot.stderr_robust / hac.stderr_robust)
        boots.append(boot)
    # two estimators of the same long-run variance (Kunsch 1989): measured median 0.97, 1.01
    med = np.median(ratio, axis=0)
    assert np.all((med > 0.8) & (med < 1.25)), med
    # seeded: the first panel's refits again from its key (one run of 100 Newton refits,
    # not two of the default 200: a quarter of this test's refits)
    again = fit_birth_death(t, data[0], robust="block-bootstrap", key=jax.random.key(0), n_boot=100)
    assert_allclose(again.cov_robust, boots[0].cov_robust, rtol=1e-12)
    other = fit_birth_death(t, data[0], robust="block-bootstrap", key=jax.random.key(1), n_boot=100)
    assert not np.allclose(other.cov_robust, boots[0].cov_robust, rtol=1e-12)  # the key counts
    short = fit_birth_death(
        t, data[0], robust="block-bootstrap", key=jax.random.key(0), n_boot=20, block_length=5
    )
    assert short.bandwidth == 5 and short.n_boot == 20


def test_constant_law_robust_errors():
    bd = BirthDeath(2.0, 2.5, death="constant")
    t = np.arange(1001.0)
    n = bd.simulate(jax.random.key(3), 4, 1000.0, 1, times=t)[0]
    fit = fit_birth_death(t, n, death="constant", bandwidth=0)
    # Huber-White from finite differences of the expm-checked constant-law likelihood
    x0 = np.log([fit.birth_rate, fit.death_rate])
    h = 1e-5
    s = np.empty((1000, 2))
    for i in range(2):
        e = np.zeros(2)
        e[i] = h
        up = BirthDeath(*np.exp(x0 + e), death="constant").transition_logpmf(n[:-1], n[1:], 1.0)
        down = BirthDeath(*np.exp(x0 - e), death="constant").transition_logpmf(n[:-1], n[1:], 1.0)
        s[:, i] = (up - down) / (2 * h)
    b = 1 / 1000
    ref = fit.log_cov @ (s.T @ s / (1 - b + b * b / 3)) @ fit.log_cov
    assert_allclose(fit.log_cov_robust, ref, rtol=1e-3)
    auto = fit_birth_death(t, n, death="constant")
    assert np.all(np.abs(auto.stderr_robust / auto.stderr - 1) < 0.3)
    boot = fit_birth_death(
        t, n, death="constant", robust="block-bootstrap", key=jax.random.key(1), n_boot=20
    )
    assert boot.n_boot == 20 and boot.bandwidth == auto.bandwidth + 1
    # 20 resamples: a loose check that the refits of the constant law are sane
    assert np.all(np.abs(np.log(boot.stderr_robust / auto.stderr_robust)) < np.log(2.0))


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------

T = np.arange(5.0)
C = np.array([3, 4, 4, 2, 5])
KEY = jax.random.key(0)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: BirthDeath(-1.0, 0.1), "birth_rate"),
        (lambda: BirthDeath(np.nan, 0.1), "birth_rate"),
        (lambda: BirthDeath(2.0, 0.0), "death_rate"),
        (lambda: BirthDeath(2.0, np.inf), "death_rate"),
        (lambda: BirthDeath(2.0, 1.0, death="constant"), "birth_rate / death_rate < 1"),
        (lambda: BirthDeath(2.0, 1.0, death="quadratic"), "death"),
        (lambda: BirthDeath(2.0, 0.1).stationary_pmf(-1), "n"),
        (lambda: BirthDeath(2.0, 0.1).stationary_pmf(1.5), "n"),
        (lambda: BirthDeath(2.0, 0.1).transition_pmf(-1, 2, 1.0), "n0"),
        (lambda: BirthDeath(2.0, 0.1).transition_pmf(1, 2, -1.0), "dt"),
        (lambda: BirthDeath(2.0, 0.1).transition_pmf([1, 2], [1, 2, 3], 1.0), "n0, n, dt"),
        (lambda: BirthDeath(2.0, 0.1).mean(-1.0, 2), "t"),
        (lambda: BirthDeath(2.0, 0.1).simulate(jax.random.key(0), -1, 1.0, 3), "n0"),
        (lambda: BirthDeath(2.0, 0.1).simulate(0, 1, 1.0, 3), "key"),
        (lambda: BirthDeath(2.0, 0.1).simulate(jax.random.key(0), [1, 2], 1.0, 3), "n0"),
        (lambda: BirthDeath(2.0, 0.1).simulate(jax.random.key(0), 1, 0.0, 3), "t_end"),
        (lambda: BirthDeath(2.0, 0.1).simulate(jax.random.key(0), 1, 1.0, 0), "n_paths"),
        (lambda: BirthDeath(2.0, 0.1).simulate(jax.random.key(0), 1, 1.0, 2, [2.0]), "times"),
        (lambda: birth_death_loglik(-2.0, 0.1, T, C), "birth_rate"),
        (lambda: birth_death_loglik(3.0, 2.0, T, C, death="constant"), "death_rate"),
        (lambda: fit_birth_death(T[::-1], C), "times"),
        (lambda: fit_birth_death([0.0, 1.0, 1.0, 2.0, 3.0], C), "times"),
        (lambda: fit_birth_death(T, C - 4), "counts"),
        (lambda: fit_birth_death(T, C + 0.5), "counts"),
        (lambda: fit_birth_death(T, C[:4]), "counts"),
        (lambda: fit_birth_death([], []), "times"),
        (lambda: fit_birth_death([1.0], [3]), "times"),
        (lambda: fit_birth_death(T, np.zeros(5)), "counts"),
        (lambda: fit_birth_death(T, C, death="cubic"), "death"),
        (lambda: fit_birth_death(T, C).confint(1.5), "level"),
        (lambda: fit_birth_death(T, C).confint(0.9, kind="sandwich"), "kind"),
        (lambda: fit_birth_death(T, C, robust="jackknife"), "robust"),
        (lambda: fit_birth_death(T, C, bandwidth=-1), "bandwidth"),
        (lambda: fit_birth_death(T, C, bandwidth=4), "bandwidth"),
        (lambda: fit_birth_death(T, C, robust="block-bootstrap"), "key"),
        (lambda: fit_birth_death(T, C, robust="block-bootstrap", key=0), "key"),
        (
            lambda: fit_birth_death(T, C, robust="block-bootstrap", key=KEY, n_boot=1),
            "n_boot",
        ),
        (lambda: fit_birth_death(T, C, block_length=0), "block_length"),
        (lambda: fit_birth_death(T, C, block_length=5), "block_length"),
        (lambda: hac_bandwidth([[1], [2]]), "counts"),
    ],
)
def test_bad_input_names_argument(call, name):
    with pytest.raises(ValueError, match=name.replace("(", r"\(")) as info:
        call()
    assert "expected" in str(info.value)
