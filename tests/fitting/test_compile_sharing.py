"""Logs that differ in their measured time resolution's last digits share the candidates'
compiled Laplace programs (issue 29: the resolution is an argument, not a constant)."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

import are_stats.fitting._laplace as laplace
from are_stats.fitting._traffic import (
    TrafficFit,
    _likelihood,
    _optimise,
    _setup,
    compile_laplace_ahead,
)
from are_stats.traffic import (
    TrafficLaws,
    simulate_traffic_log,
    stay_unit_loglik,
    stay_units,
    uniform_position_density,
)

FREE = np.ones((20, 20), bool)
RES = 0.5
AREA = float(FREE.sum()) * RES * RES
KW = {"arrivals": "negbin", "lifetimes": "weibull"}


def _log():
    """Poisson arrivals, Weibull stays over 1,300 s, times on a 0.1 s grid (the smallest
    gap between times, the measured resolution, is longer)."""
    laws = TrafficLaws(arrivals="poisson", lifetimes="weibull", positions="uniform")
    draw = {"event_rate": 2e-4, "stay_mean": 80.0, "stay_shape": 2.0}
    uni = uniform_position_density(FREE, RES, (0.0, 0.0))
    return simulate_traffic_log(np.random.default_rng(11), draw, laws, (0.0, 1300.0), AREA,
                                free=uni, resolution=0.1)  # fmt: skip


def _calls(data):
    out = TrafficFit("poisson", "exponential", "uniform")
    setup = _setup(jax.random.key(3), data, KW["arrivals"], KW["lifetimes"], None, out)
    return setup.calls, out.attrs["time_resolution"]


def _rescaled(data, factor):
    """The same log with its clock scaled by ``factor`` (window included)."""
    t0, t1 = data.window
    return dataclasses.replace(
        data,
        t_arrive=data.t_arrive * factor,
        t_leave=data.t_leave * factor,
        window=(t0 * factor, t1 * factor),
    )


def test_a_resolution_off_in_its_last_digits_compiles_nothing_again(monkeypatch):
    """The second log's resolution is the first's off in its 13th digit (the same nominal
    0.1 s, rounded otherwise): its negbin and weibull programs are the first log's."""
    data = _log()
    other = _rescaled(data, 1.0 + 1e-13)
    calls, res = _calls(data)
    calls2, res2 = _calls(other)
    assert res != res2 and res == pytest.approx(res2, rel=1e-12)
    with compile_laplace_ahead(jax.random.key(3), data, **KW) as ahead:
        ahead.wait()

    def no_compile(*args, **kwargs):
        raise AssertionError("a log differing in its resolution's last digits compiled again")

    monkeypatch.setattr(laplace, "compile_program", no_compile)
    for which, (_, model, kwargs, init) in calls2.items():
        pointwise, site = _likelihood(which[0])
        laplace.laplace_program(model, kwargs, init, pointwise, _optimise(which), site)


@pytest.mark.parametrize("law", ["gamma", "weibull", "lognormal"])
def test_an_array_resolution_gives_the_constant_ones_values(law):
    """Passed as an argument of a compiled program, the resolution gives the values of
    the same resolution as a constant (to rounding), the interval term included; an
    array of 0 gives those of no resolution (its interval term is never selected)."""
    rng = np.random.default_rng(2)
    stay = np.concatenate([rng.gamma(2.0, 40.0, 30), [0.05, 0.2, 0.0]])
    censored = np.zeros(stay.size, bool)
    censored[:5] = True
    truncated = np.zeros(stay.size, bool)
    truncated[3:8] = True
    units = stay_units(stay, censored, truncated)
    params = {"stay_mean": 70.0, "stay_shape": 1.7}

    # one program per law: the constants' values beside the argument's (each eager
    # operation of the constants' values compiled on its own: twice the CPU, 2026-11-29)
    @jax.jit
    def constant_and_argument(r):
        const = tuple(stay_unit_loglik(params, units, law, c) for c in (0.5, 0.0))
        return const, stay_unit_loglik(params, units, law, r)

    for k, r in enumerate((0.5, 0.0)):
        const, got = constant_and_argument(np.asarray(r))
        np.testing.assert_allclose(np.asarray(got), np.asarray(const[k]), rtol=1e-12, atol=0.0)
