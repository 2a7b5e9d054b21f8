"""The interaction fitted from a log's tracks and stored in a fit."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import SocialForce, social_force_tracks
from are_stats.fitting import (
    fit_interaction,
    interaction_attrs,
    interaction_from_attrs,
    learn_interaction,
)


def _crowd(seed: int, n: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        a, b = rng.uniform(0, 20, 2), rng.uniform(0, 20, 2)
        while np.hypot(*(b - a)) < 8:
            b = rng.uniform(0, 20, 2)
        t0, v = np.round(rng.uniform(0, 40), 1), rng.lognormal(np.log(1.3), 0.1)
        dur = np.hypot(*(b - a)) / v
        t = t0 + np.arange(0, np.ceil((dur + 5) / 0.1) + 1) * 0.1
        xy = a + (b - a) * np.clip((t - t0) / dur, 0, 1)[:, None]
        rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
    return pd.concat(rows, ignore_index=True)


@pytest.mark.slow
def test_the_interaction_of_a_log_is_recovered_and_survives_the_fit_file():
    truth = SocialForce(strength=2.5, range=0.35, relaxation=0.7)
    log = social_force_tracks(_crowd(2, 60), truth, dt=0.1)
    shuffled = log.sample(frac=1.0, random_state=0)  # a log's rows come in any order
    est, info = fit_interaction(shuffled[["id", "t", "x", "y"]])
    assert est.strength == pytest.approx(2.5, rel=0.1)
    assert est.range == pytest.approx(0.35, abs=0.051)
    assert est.relaxation == pytest.approx(0.7, rel=0.1)
    attrs = interaction_attrs(est, info)
    assert interaction_from_attrs(attrs) == est
    assert interaction_from_attrs({}) is None
    with pytest.raises(ValueError, match="interaction_range: expected a finite number > 0"):
        interaction_from_attrs({**attrs, "interaction_range": -1.0})


def _crowd_with_pairs(spacing: float, params: SocialForce) -> pd.DataFrame:
    """40 people walking alone across a 20 m square and 10 pairs abreast at ``spacing``,
    one pair after the other, walked by the social force ``params`` with their groups."""
    rng = np.random.default_rng(5)
    crowd = _crowd(2, 40)  # people walking alone, whom the pairs meet
    rows, groups, i = [crowd], [-1] * 40, 40
    for g in range(10):  # pairs walking across the square, one pair after the other
        ang = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(ang), np.sin(ang)])
        t0 = 4.0 * g
        for m in range(2):
            a = 10 - 9 * u + m * spacing * np.array([-u[1], u[0]])
            t = t0 + np.arange(0, 14.0, 0.1)
            xy = a + np.clip(t - t0, 0, 18 / 1.3)[:, None] * 1.3 * u
            rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
            groups.append(g)
            i += 1
    plan = pd.concat(rows, ignore_index=True)
    params = params._replace(group_spacing=spacing)
    return social_force_tracks(
        plan, params, dt=0.1, groups=np.asarray(groups)[plan["id"].to_numpy()]
    )


@pytest.mark.slow
def test_the_repulsion_is_recovered_from_a_log_with_pairs_walking_abreast():
    """Pairs 0.7 m apart (closer than the repulsion lets strangers pass) walk in formation:
    the fit leaves them out, else every calm pair at 0.7 m reads as a weak push (strength
    0.18 instead of 2.5 before the groups were left out)."""
    truth = SocialForce(strength=2.5, range=0.35, relaxation=0.7)
    log = _crowd_with_pairs(0.7, truth)
    est, info = fit_interaction(log[["id", "t", "x", "y"]])
    assert est.strength == pytest.approx(truth.strength, rel=0.1)
    assert est.range == pytest.approx(truth.range, abs=0.051)
    assert est.relaxation == pytest.approx(truth.relaxation, rel=0.1)
    assert info["r2"] > 0.9


def test_the_group_spacing_of_a_log_is_fitted_and_stored_with_the_interaction():
    truth = 1.1
    log = _crowd_with_pairs(truth, SocialForce())
    est, info = fit_interaction(log[["id", "t", "x", "y"]])
    assert est.group_spacing == pytest.approx(truth, abs=0.05)
    assert info["group_samples"] > 1000
    attrs = interaction_attrs(est, info)
    assert attrs["interaction_group_spacing"] == est.group_spacing
    assert interaction_from_attrs(attrs).group_spacing == est.group_spacing
    # a fit stored before group spacings were fitted reads back with the default
    old = {k: v for k, v in attrs.items() if k != "interaction_group_spacing"}
    assert interaction_from_attrs(old).group_spacing == SocialForce().group_spacing


def _straight_pairs(spacing: float, n_pairs: int = 12) -> pd.DataFrame:
    """Pairs walking abreast in straight lines at constant speed, one pair at a time: no
    pushing to learn a repulsion from, but a spacing to measure."""
    rows = []
    for k in range(n_pairs):
        t0 = 30.0 * k
        t = t0 + np.arange(0, 201) * 0.1
        y0 = 5.0 + (k % 3)
        for m in range(2):
            x = 1.0 + 1.2 * (t - t0)
            y = np.full_like(t, y0 + m * spacing)
            rows.append(pd.DataFrame({"id": 2 * k + m, "t": t, "x": x, "y": y}))
    return pd.concat(rows, ignore_index=True)


def test_a_log_without_repulsion_keeps_its_group_spacing():
    log = _straight_pairs(0.5)
    with pytest.raises(ValueError, match="tracks: expected"):
        fit_interaction(log)
    params, info, note = learn_interaction(log)
    assert params is not None and params.group_spacing == pytest.approx(0.5, abs=0.02)
    # the rest is the published force, and the note says so
    assert params._replace(group_spacing=SocialForce().group_spacing) == SocialForce()
    assert info["group_samples"] > 100 and "group spacing, 0.50 m" in note
    # read back from a fit file as the fitted one would be
    assert interaction_from_attrs(interaction_attrs(params, info)) == params
    # walkers alone: nothing to learn, the published force (None) and a note
    alone = log[log["id"] % 2 == 0]
    params, info, note = learn_interaction(alone)
    assert params is None and "published one" in note
