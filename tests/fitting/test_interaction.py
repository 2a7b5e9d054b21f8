"""The interaction fitted from a log's tracks and stored in a fit."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import SocialForce, social_force_tracks
from are_stats.fitting import fit_interaction, interaction_attrs, interaction_from_attrs


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


def test_the_group_spacing_of_a_log_is_fitted_and_stored_with_the_interaction():
    rng = np.random.default_rng(5)
    truth = 1.1
    crowd = _crowd(2, 40)  # people walking alone, whom the pairs meet
    rows, groups, i = [crowd], [-1] * 40, 40
    for g in range(10):  # pairs walking across the square, one pair after the other
        ang = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(ang), np.sin(ang)])
        t0 = 4.0 * g
        for m in range(2):
            a = 10 - 9 * u + m * truth * np.array([-u[1], u[0]])
            t = t0 + np.arange(0, 14.0, 0.1)
            xy = a + np.clip(t - t0, 0, 18 / 1.3)[:, None] * 1.3 * u
            rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
            groups.append(g)
            i += 1
    plan = pd.concat(rows, ignore_index=True)
    log = social_force_tracks(
        plan,
        SocialForce(group_spacing=truth),
        dt=0.1,
        groups=np.asarray(groups)[plan["id"].to_numpy()],
    )
    est, info = fit_interaction(log[["id", "t", "x", "y"]])
    assert est.group_spacing == pytest.approx(truth, abs=0.05)
    assert info["group_samples"] > 1000
    attrs = interaction_attrs(est, info)
    assert attrs["interaction_group_spacing"] == est.group_spacing
    assert interaction_from_attrs(attrs).group_spacing == est.group_spacing
    # a fit stored before group spacings were fitted reads back with the default
    old = {k: v for k, v in attrs.items() if k != "interaction_group_spacing"}
    assert interaction_from_attrs(old).group_spacing == SocialForce().group_spacing
