"""The one sampler against closed forms: stay laws, group sizes, stationary N(t) moments.

Goodness-of-fit tests use ALPHA (tests.helpers) as their false-failure rate; moment checks
are 5-standard-error bounds (false-failure rate below 1e-6 each).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from are_stats.traffic import (
    TrafficLaws,
    fit_position_density,
    sample_population,
    stationary_count_moments,
    stay_draws,
    stay_logsf,
    uniform_position_density,
)
from tests.helpers import ALPHA

MEAN, SHAPE = 30.0, 2.5


def _scipy_law(law: str):
    if law == "exponential":
        return stats.expon(scale=MEAN)
    if law == "gamma":
        return stats.gamma(SHAPE, scale=MEAN / SHAPE)
    if law == "weibull":
        from scipy.special import gamma as g

        return stats.weibull_min(SHAPE, scale=MEAN / g(1 + 1 / SHAPE))
    s = 0.7
    return stats.lognorm(s, scale=np.exp(np.log(MEAN) - s * s / 2))


@pytest.mark.parametrize("law", ["exponential", "gamma", "weibull", "lognormal"])
def test_stay_draws_follow_scipy(law):
    shape = 0.7 if law == "lognormal" else SHAPE
    t = stay_draws(np.random.default_rng(1), law, MEAN, shape, 4000)
    assert stats.kstest(t, _scipy_law(law).cdf).pvalue > ALPHA


@pytest.mark.parametrize("law", ["gamma", "weibull", "lognormal"])
def test_residual_draws_follow_the_equilibrium_law(law):
    """The residual stay has survival int_r^inf S(u) du / m (renewal theory)."""
    shape = 0.7 if law == "lognormal" else SHAPE
    r = stay_draws(np.random.default_rng(2), law, MEAN, shape, 3000, residual=True)

    def cdf(x):
        x = np.atleast_1d(x)
        out = [
            integrate.quad(lambda u: np.exp(float(stay_logsf(law, u, MEAN, shape))), 0, v)[0] / MEAN
            for v in x
        ]
        return np.asarray(out)

    grid = np.quantile(r, np.linspace(0.05, 0.95, 10))
    want = cdf(grid)
    got = np.searchsorted(np.sort(r), grid) / r.size
    # Kolmogorov bound at ALPHA for n = 3000
    assert np.max(np.abs(got - want)) < 1.63 / np.sqrt(r.size)


def test_group_sizes_and_stationary_moments():
    """N(t) of groups with shared stays: E = c E[S], Var = c E[S^2] (M^X/G/inf)."""
    probs = np.array([0.5, 0.3, 0.2])
    laws = TrafficLaws(arrivals="groups", lifetimes="gamma")
    draw = {"event_rate": 0.01, "stay_mean": 20.0, "stay_shape": 3.0, "group_size_probs": probs}
    rng = np.random.default_rng(3)
    n0 = []
    sizes = []
    for _ in range(3000):
        pop = sample_population(rng, draw, laws, 50.0, 10.0)
        n0.append(int(pop["truncated"].sum()))
        arrived = ~pop["truncated"]
        sizes.append(np.bincount(pop["group"][arrived])[np.unique(pop["group"][arrived])])
        # the population at t = 50 is stationary too (checked through t = 0 here)
    mean, var = stationary_count_moments(0.01, 10.0, 20.0, probs)
    n0 = np.asarray(n0, float)
    assert abs(n0.mean() - mean) < 5 * np.sqrt(var / n0.size)
    # the variance of a sample variance: about 2 var^2 / n for these light tails, x 3 margin
    assert abs(n0.var() - var) < 5 * np.sqrt(3 * 2 * var**2 / n0.size)
    s = np.concatenate(sizes)
    counts = np.bincount(s, minlength=4)[1:]
    assert stats.chisquare(counts, probs * counts.sum()).pvalue > ALPHA


def test_members_share_time_entry_and_stay():
    free = np.ones((20, 20), bool)
    uni = uniform_position_density(free, 0.5, (0.0, 0.0))
    laws = TrafficLaws(arrivals="groups", group_spread=0.0)
    draw = {"event_rate": 0.02, "stay_mean": 10.0, "group_size_probs": np.array([0.0, 1.0])}
    pop = sample_population(np.random.default_rng(4), draw, laws, 100.0, 100.0, free=uni)
    for g in np.unique(pop["group"]):
        idx = pop["group"] == g
        assert idx.sum() == 2
        for k in ("t_arrive", "t_leave", "x", "y"):
            assert np.ptp(pop[k][idx]) == 0.0


def test_learned_entries_follow_the_density():
    free = np.ones((10, 10), bool)
    rng = np.random.default_rng(5)
    door = np.column_stack([rng.normal(0.5, 0.3, 400), rng.normal(2.5, 0.3, 400)])
    dens = fit_position_density(np.clip(door, 0.01, 4.99), free, 0.5, (0.0, 0.0))
    laws = TrafficLaws(positions="learned", entry=dens)
    draw = {"event_rate": 0.05, "stay_mean": 10.0}
    pop = sample_population(rng, draw, laws, 400.0, 25.0, start="empty",
                            free=uniform_position_density(free, 0.5, (0.0, 0.0)))  # fmt: skip
    row, col = dens.cell_of(np.column_stack([pop["x"], pop["y"]]))
    counts = np.bincount(row * 10 + col, minlength=100)
    expected = dens.prob.ravel() * counts.sum()
    keep = expected > 5  # chi-square cells with enough expectation, the rest pooled
    obs = np.append(counts[keep], counts[~keep].sum())
    exp = np.append(expected[keep], expected[~keep].sum())
    assert stats.chisquare(obs, exp).pvalue > ALPHA
