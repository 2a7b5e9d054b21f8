"""The candidates' Laplace programs compiled ahead of ``fit_traffic``
(:func:`~are_stats.fitting._traffic.compile_laplace_ahead`), the longest first."""

from __future__ import annotations

import threading

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


_TRACES: list[int] = []


def _counted_model(y):
    import numpyro
    import numpyro.distributions as dist

    _TRACES.append(1)
    mu = numpyro.sample("mu", dist.Normal(0.0, 1.0))
    numpyro.sample("y", dist.Normal(mu, 1.0), obs=y)


class _CountingLock:
    """The trace lock, counting the threads that came to it."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.came = 0

    def __enter__(self) -> None:
        self.came += 1
        self.lock.acquire()

    def __exit__(self, *exc: object) -> None:
        self.lock.release()


def test_a_model_waited_for_is_traced_once(monkeypatch):
    """Two threads that ask for the same model's sites (the fit's thread and an ahead
    thread) while the trace lock is held: the second to get it finds the first's sites
    instead of tracing the model again."""
    lock = _CountingLock()
    monkeypatch.setattr(laplace, "TRACE_LOCK", lock)
    kwargs = {"y": np.zeros(13)}  # a shape of this test alone
    _TRACES.clear()
    threads = [
        threading.Thread(target=laplace._latent_sites, args=(_counted_model, kwargs))
        for _ in range(2)
    ]
    with lock.lock:
        for t in threads:
            t.start()
        while lock.came < 2:  # both past the cache's first look, at the lock
            pass
    for t in threads:
        t.join()
    assert len(_TRACES) == 1
    assert list(laplace._latent_sites(_counted_model, kwargs)) == ["mu"]
    assert len(_TRACES) == 1
