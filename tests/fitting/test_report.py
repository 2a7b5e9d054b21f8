"""fit_summary: ArviZ's summary of a fit, quiet for single-chain (em) fits."""

from __future__ import annotations

import logging

import arviz as az
import numpy as np

from are_stats.fitting import fit_summary


class _Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def test_single_chain_summary_is_quiet_and_has_no_r_hat():
    rng = np.random.default_rng(0)
    lam = rng.gamma(50.0, 1e-6, size=(1, 400))
    mu = rng.gamma(80.0, 2e-5, size=(1, 400))
    idata = az.from_dict(posterior={"arrival_rate": lam, "leave_rate": mu})
    log = getattr(az, "_log", logging.getLogger("arviz"))
    seen = _Records()
    log.addHandler(seen)
    try:
        table = fit_summary(idata)
    finally:
        log.removeHandler(seen)
    assert [r.getMessage() for r in seen.records if r.levelno >= logging.WARNING] == []
    assert list(table.index) == ["arrival_rate", "leave_rate"]
    assert np.isnan(table["r_hat"]).all()
    np.testing.assert_allclose(table.loc["leave_rate", "mean"], mu.mean(), rtol=1e-12)
    # the level ArviZ's logger had is restored
    assert log.level == logging.NOTSET or log.level < logging.ERROR


def test_summary_matches_arviz_and_leaves_its_numba_flag_alone():
    # fit_summary takes ArviZ's NumPy paths (no numba compile per process); the numbers
    # are ArviZ's own, and ArviZ's flag is what it was afterwards
    rng = np.random.default_rng(1)
    post = {
        "arrival_rate": rng.gamma(50.0, 1e-6, size=(4, 300)),
        "mix_rates": rng.gamma(9.0, 1.0, size=(4, 300, 2)).cumsum(axis=-1),
    }
    idata = az.from_dict(posterior=post)
    flag = az.Numba.numba_flag
    table = fit_summary(idata)
    assert az.Numba.numba_flag == flag
    ref = az.summary(idata, round_to="none")
    assert list(table.index) == list(ref.index)
    np.testing.assert_allclose(table.to_numpy(float), ref.to_numpy(float), rtol=1e-8)
