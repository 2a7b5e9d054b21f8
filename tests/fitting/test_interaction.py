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
