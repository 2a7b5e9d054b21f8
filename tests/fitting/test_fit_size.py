"""fit_log checks its own size (issue 25): the posterior draws against the memory limit and
the NUTS work against the work limit, before anything is sampled, by the estimates of
check_fit_size (computed here by hand)."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.fitting import FitSettings, check_fit_size, fit_log
from are_stats.inputs import LimitError, limits
from are_stats.traffic import LifecycleData

# 10 draws x 2 chains = 20 draws of 8 * 64 bytes: 10240 bytes
SETTINGS = FitSettings(num_samples=10, num_chains=2, num_warmup=5, arrivals="poisson",
                       lifetimes="exponential", positions="uniform")  # fmt: skip
MEMORY = 20 * 8 * 64
# 2 chains x (5 + 10) iterations x 16 leapfrog steps x (36 rows + 64)
WORK = 2 * 15 * 16 * (36 + 64)


def test_the_draws_are_checked_against_the_memory_limit():
    with limits(memory=MEMORY, work=WORK):
        check_fit_size(SETTINGS, 36)  # exactly at both limits: accepted
    with limits(memory=MEMORY - 1), pytest.raises(LimitError) as err:
        check_fit_size(SETTINGS, 36)
    assert "num_samples, num_chains" in str(err.value)
    assert "20 posterior draws" in str(err.value) and "10.0 KiB" in str(err.value)


def test_nuts_work_is_checked_and_em_has_none():
    with limits(work=WORK - 1), pytest.raises(LimitError) as err:
        check_fit_size(SETTINGS, 36)
    assert "NUTS on 36 artefacts" in str(err.value)
    assert "num_samples, num_warmup, num_chains" in str(err.value)
    assert "4.8e+04 steps" in str(err.value)
    em = FitSettings(method="em", num_samples=10, num_chains=2, num_warmup=5)
    with limits(work=1):
        check_fit_size(em, 36)  # no NUTS: no work to refuse


def test_fit_log_refuses_before_sampling_naming_the_given_options():
    rng = np.random.default_rng(0)
    ta = np.sort(rng.uniform(0.0, 900.0, 36))
    tl = ta + rng.exponential(60.0, 36)
    data = LifecycleData(ta, np.where(tl < 1000.0, tl, np.nan), (0.0, 1000.0), 100.0)
    names = {"num_samples": "--samples", "num_warmup": "--warmup", "num_chains": "--chains"}
    with limits(work=WORK - 1), pytest.raises(LimitError, match="--samples, --warmup, --chains"):
        fit_log(0, data, SETTINGS, setting_names=names)
    with limits(memory=MEMORY - 1), pytest.raises(LimitError, match="num_samples, num_chains"):
        fit_log(0, data, SETTINGS)
