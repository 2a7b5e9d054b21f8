"""Fit.posterior_means (issue 25: the demo's summary no longer computes them) against means
worked out by hand from a 2-chain x 2-draw posterior."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from are_stats.fitting import fit_from_idata

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az


def _idata(labels: str | None = "small,large", area: float | None = 10.0, marks: bool = True):
    post = {
        "arrival_rate": np.array([[1.0, 2.0], [3.0, 4.0]]),
        "leave_rate": np.array([[0.5, 1.0], [0.25, 0.5]]),
    }
    if marks:
        post["mix_weights"] = np.array([[[0.2, 0.8], [0.4, 0.6]], [[0.6, 0.4], [0.8, 0.2]]])
        post["mix_rates"] = np.array([[[1.0, 10.0], [3.0, 10.0]], [[1.0, 20.0], [3.0, 20.0]]])
    idata = az.from_dict(posterior=post)
    if area is not None:
        idata.posterior.attrs["area"] = area
    if labels is not None:
        idata.posterior.attrs["class_labels"] = labels
    return idata


def test_means_of_the_draws_and_of_their_transforms():
    m = fit_from_idata(_idata()).posterior_means()
    assert m.arrival_rate == pytest.approx(2.5)  # (1 + 2 + 3 + 4) / 4
    assert m.leave_rate == pytest.approx(0.5625)  # (0.5 + 1 + 0.25 + 0.5) / 4
    assert m.arrivals_per_s == pytest.approx(25.0)  # E[lambda] * 10 m^2
    # E[1 / mu] = (2 + 1 + 4 + 2) / 4, not 1 / E[mu] = 1.78
    assert m.mean_stay_s == pytest.approx(2.25)
    assert m.class_labels == ("small", "large")
    np.testing.assert_allclose(m.class_weights, [0.5, 0.5])
    np.testing.assert_allclose(m.mark_rates, [2.0, 15.0])


def test_components_without_labels_are_numbered_and_no_area_gives_none():
    m = fit_from_idata(_idata(labels=None, area=None)).posterior_means()
    assert m.class_labels == ("0", "1") and m.arrivals_per_s is None
    bare = fit_from_idata(_idata(labels=None, marks=False)).posterior_means()
    assert bare.class_labels == () and bare.class_weights.shape == (0,)
    assert bare.mark_rates.shape == (0,) and bare.mean_stay_s == pytest.approx(2.25)


def test_class_shares_of_a_labelled_fit():
    """Shares (0.25 + 0.75) / 2, arrivals per hour share x E[lambda] x area x 3600 =
    0.5 x 2.5 x 10 x 3600, stays the median of two draws (their mean)."""
    idata = _idata(marks=False, labels="person,cart")
    idata.posterior["class_weights"] = (
        ("chain", "draw", "class"),
        np.array([[[0.25, 0.75], [0.75, 0.25]], [[0.25, 0.75], [0.75, 0.25]]]),
    )
    idata.posterior["class_stay_mean"] = (
        ("chain", "draw", "class"),
        np.array([[[10.0, 100.0], [30.0, 300.0]], [[10.0, 100.0], [30.0, 300.0]]]),
    )
    c = fit_from_idata(idata).class_shares()
    assert c.labels == ("person", "cart")
    np.testing.assert_allclose(c.shares, [0.5, 0.5])
    np.testing.assert_allclose(c.per_hour, [45000.0, 45000.0])
    np.testing.assert_allclose(c.stay_mean, [20.0, 200.0])
    assert fit_from_idata(_idata()).class_shares() is None  # marks, no named classes


def test_interaction_source_says_where_the_social_force_came_from():
    import dataclasses

    from are_stats.behaviour import SocialForce

    fit = fit_from_idata(_idata())
    assert fit.interaction_source is None  # no interaction stored: the published applies
    fitted = dataclasses.replace(
        fit, interaction=SocialForce(strength=1.2), interaction_info={"r2": 0.4, "n": 812.0}
    )
    assert fitted.interaction_source == "estimated"
    unfit = {"r2": np.nan, "n": np.nan}
    none = dataclasses.replace(fit, interaction=SocialForce(strength=0.0), interaction_info=unfit)
    assert none.interaction_source == "none"
    kept = dataclasses.replace(fit, interaction=SocialForce(), interaction_info=unfit)
    assert kept.interaction_source == "published"
