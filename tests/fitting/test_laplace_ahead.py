"""The candidates' Laplace programs compiled ahead of ``fit_traffic``
(:func:`~are_stats.fitting._traffic.compile_laplace_ahead`), the longest first."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import are_stats.fitting._laplace as laplace
from are_stats.fitting import fit_traffic
from are_stats.fitting._traffic import _laplace_order, compile_laplace_ahead
from are_stats.traffic import TrafficLaws, simulate_traffic_log, uniform_position_density

FREE = np.ones((20, 20), bool)
RES = 0.5
AREA = float(FREE.sum()) * RES * RES


def _log():
    """Poisson arrivals, Weibull stays over 1,500 s (a size no other test fits)."""
    laws = TrafficLaws(arrivals="poisson", lifetimes="weibull", positions="uniform")
    draw = {"event_rate": 2e-4, "stay_mean": 90.0, "stay_shape": 2.0}
    uni = uniform_position_density(FREE, RES, (0.0, 0.0))
    return simulate_traffic_log(np.random.default_rng(7), draw, laws, (0.0, 1500.0), AREA,
                                free=uni, resolution=0.5)  # fmt: skip


def _paper(shape=(1, 50)):
    rng = np.random.default_rng(0)
    return {
        "arrival_rate": rng.gamma(50.0, 4e-6, shape),
        "leave_rate": rng.gamma(50.0, 2e-4, shape),
    }


def test_the_longest_compiles_come_first():
    """XLA's default optimisation first (the gamma law's incomplete gammas, the MMPP and
    groups+hawkes recursions), the stay laws before the arrival models, else as given."""
    given = [("arrivals", "negbin"), ("arrivals", "mmpp"), ("arrivals", "groups"),
             ("arrivals", "groups+hawkes"), ("stays", "gamma"), ("stays", "weibull"),
             ("arrivals", "hawkes"), ("stays", "lognormal")]  # fmt: skip
    assert _laplace_order(given) == [
        ("stays", "gamma"),
        ("arrivals", "mmpp"),
        ("arrivals", "groups+hawkes"),
        ("stays", "weibull"),
        ("stays", "lognormal"),
        ("arrivals", "negbin"),
        ("arrivals", "groups"),
        ("arrivals", "hawkes"),
    ]


def test_the_fit_finds_every_program_compiled_ahead(monkeypatch):
    """After the ahead threads finish, fit_traffic compiles nothing: the programs are the
    ones it asks for (same model, settings, shapes and XLA options)."""
    data = _log()
    key = jax.random.key(5)
    kw = {"arrivals": "negbin", "lifetimes": "weibull"}
    ahead = compile_laplace_ahead(key, data, **kw)
    ahead.wait()

    def no_compile(*args, **kwargs):
        raise AssertionError("fit_traffic compiled a program the ahead threads had compiled")

    monkeypatch.setattr(laplace, "compile_program", no_compile)
    fit = fit_traffic(key, data, paper=_paper(), positions="uniform", approximation="laplace",
                      **kw)  # fmt: skip
    assert list(fit.tables["arrivals"].index) == ["poisson", "negbin"]
    assert list(fit.tables["lifetimes"].index) == ["exponential", "weibull"]


def test_a_log_the_fit_refuses_starts_nothing():
    """The error is fit_traffic's to raise (with its words); ahead of it nothing runs."""
    data = _log()
    key = jax.random.key(5)
    with compile_laplace_ahead(key, data, arrivals="time-of-day") as ahead:
        ahead.wait()
    with pytest.raises(ValueError, match="expected the log's clock"):
        fit_traffic(key, data, paper=_paper(), arrivals="time-of-day", approximation="laplace")
