"""NUTS for the Poisson mixture over the histogram of marks; WAIC/LOO; choosing n."""

from __future__ import annotations

import arviz as az
import jax
import numpy as np
import pytest
from scipy import stats

from are_stats import fit_mixture_nuts, select_n_components
from are_stats.fitting import mixture_loo, mixture_waic
from tests.helpers import assert_allclose


@pytest.fixture(scope="module")
def one_component():
    marks = np.random.default_rng(21).poisson(4.0, 2000)
    idata = fit_mixture_nuts(jax.random.key(0), marks, 1, num_warmup=400, num_samples=1000)
    return marks, idata


def test_one_component_matches_conjugate_gamma_posterior(one_component):
    """Posterior of the rate is Gamma(a + sum k, b + N) with the default a=1, b=1/mean.

    Mean within 4 MCSE (false-failure rate about 6e-5), sd within 10%.
    """
    marks, idata = one_component
    a = 1.0 + marks.sum()
    b = 1.0 / marks.mean() + marks.size
    exact = stats.gamma(a, scale=1.0 / b)
    rate = idata.posterior["mix_rates"].sel(component=0).values  # (chain, draw)
    assert float(az.ess(rate, method="bulk")) > 400
    assert float(az.rhat(rate)) < 1.01
    mcse = float(rate.std() / np.sqrt(az.ess(rate, method="mean")))
    assert abs(float(rate.mean()) - exact.mean()) < 4 * mcse
    assert abs(float(rate.std()) / exact.std() - 1) < 0.10
    assert idata.posterior.attrs["rate_prior_rate"] == pytest.approx(1.0 / marks.mean())
    expected_method = "parallel" if jax.local_device_count() >= 2 else "vectorized"
    assert idata.posterior.attrs["chain_method"] == expected_method
    assert int(idata.sample_stats["diverging"].sum()) == 0


def test_weighted_waic_and_loo_equal_arviz_on_expanded_marks(one_component):
    """The count-weighted sums equal arviz's waic/loo over one column per mark."""
    marks, idata = one_component
    ll = idata.log_likelihood["marks"]
    values = idata.log_likelihood["mark_value"].values
    cols = np.searchsorted(values, marks)
    expanded = az.from_dict(
        posterior={"r": idata.posterior["mix_rates"].values[..., 0]},
        log_likelihood={"marks": ll.values[:, :, cols]},
    )
    ref_waic = az.waic(expanded)
    # relative efficiency as mixture_loo computes it: mean over marks of ess(p(k | theta)) / S
    ll_marks = ll.values[:, :, cols]
    uniq, first = np.unique(cols, return_index=True)
    ess_u = np.array([az.ess(np.exp(ll_marks[:, :, j]), method="mean") for j in first])
    reff = float(np.mean(ess_u[np.searchsorted(uniq, cols)])) / ll_marks[..., 0].size
    ref_loo = az.loo(expanded, reff=reff)
    waic, loo = mixture_waic(idata), mixture_loo(idata)
    assert_allclose(waic.elpd, ref_waic.elpd_waic, rtol=1e-10)
    assert_allclose(waic.se, ref_waic.se, rtol=1e-8)
    assert_allclose(waic.p_eff, ref_waic.p_waic, rtol=1e-8)
    assert_allclose(loo.elpd, ref_loo.elpd_loo, rtol=1e-8)
    assert_allclose(loo.p_eff, ref_loo.p_loo, rtol=1e-6)
    assert_allclose(loo.se, ref_loo.se, rtol=1e-8)
    assert_allclose(waic.deviance, -2 * waic.elpd)


@pytest.mark.slow  # three NUTS fits; make test keeps the k = 1 checks
def test_bic_waic_loo_select_the_true_number_of_components_and_nuts_recovers_truth():
    """Rates (3, 30), weights (.6, .4), 1000 marks: every criterion picks k = 2, and the
    k = 2 posterior covers the truth (posterior means within 4 sd)."""
    rng = np.random.default_rng(8)
    w, r = np.array([0.6, 0.4]), np.array([3.0, 30.0])
    marks = rng.poisson(r[rng.choice(2, 1000, p=w)])
    table, fits = select_n_components(
        jax.random.key(2), marks, 3, num_warmup=200, num_samples=300, return_fits=True
    )
    assert list(table.index) == [1, 2, 3]
    for col in ("bic", "waic", "loo", "chosen_bic", "chosen_waic", "chosen_loo"):
        assert col in table.columns
    for crit in ("bic", "waic", "loo"):
        assert table.index[table[f"chosen_{crit}"]].tolist() == [2], table
    assert np.all(table["pareto_k_max"] < 0.7)

    em, idata = fits[2]
    assert_allclose(table.loc[2, "bic"], em.bic)
    post = idata.posterior
    assert float(az.rhat(post)["mix_rates"].max()) < 1.05
    assert float(az.ess(post, method="bulk")["mix_rates"].min()) > 100
    rates = post["mix_rates"].stack(s=("chain", "draw")).values  # (2, S)
    weights = post["mix_weights"].stack(s=("chain", "draw")).values
    assert np.all(np.diff(rates, axis=0) > 0)  # ordered in every draw
    assert np.all(np.abs(rates.mean(1) - r) < 4 * rates.std(1)), rates.mean(1)
    assert np.all(np.abs(weights.mean(1) - w) < 4 * weights.std(1)), weights.mean(1)
    assert idata.log_likelihood["marks"].shape[-1] == np.unique(marks).size


def test_select_bic_only_skips_nuts():
    marks = np.random.default_rng(9).poisson(5.0, 500)
    table = select_n_components(jax.random.key(0), marks, 2, method="bic")
    assert table["waic"].isna().all() and table["loo"].isna().all()
    assert table["chosen_bic"].sum() == 1 and not table["chosen_waic"].any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_components": 0}, "n_components: expected an integer >= 1"),
        ({"n_components": 9}, "n_components: expected at most the number of distinct"),
        ({"chain_method": "threads"}, "chain_method: expected one of"),
        ({"num_samples": 0}, "num_samples: expected an integer >= 1"),
        ({"init": "random"}, "init: expected one of"),
        ({"rate_prior": (1.0, -1.0)}, "rate_prior: expected finite numbers > 0"),
        ({"marks": [1, -1, 2]}, "marks: expected non-negative integers"),
        ({"marks": []}, "marks: expected at least one mark"),
    ],
)
def test_nuts_bad_input_raises(kwargs, match):
    args = {"marks": [0, 1, 2, 3, 3], "n_components": 1, **kwargs}
    with pytest.raises(ValueError, match=match):
        fit_mixture_nuts(jax.random.key(0), **args)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"k_max": 0}, "k_max: expected an integer >= 1"),
        ({"k_max": 5}, "k_max: expected at most the number of distinct"),
        ({"method": ("aic",)}, "method: expected one of"),
        ({"method": ()}, "method: expected at least one"),
    ],
)
def test_select_bad_input_raises(kwargs, match):
    args = {"marks": [0, 1, 2, 3, 3], "k_max": 2, **kwargs}
    with pytest.raises(ValueError, match=match):
        select_n_components(jax.random.key(0), **args)
