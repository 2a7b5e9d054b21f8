"""The fuzz harness itself: its guard stops runaway cases and its contract can fail."""

from __future__ import annotations

import numpy as np
import pytest

from tests.fuzz.strategies import CaseTimeout, bounded, expect_clean


def test_bounded_stops_a_runaway_allocation() -> None:
    with pytest.raises(MemoryError), bounded(seconds=30.0, memory=2**30):
        np.ones(2**31, dtype=np.uint8)  # 2 GiB against 1 GiB of headroom


def test_bounded_stops_a_hang() -> None:
    with pytest.raises(CaseTimeout), bounded(seconds=0.2):
        while True:
            pass


def test_bounded_stops_a_runaway_by_cpu_time() -> None:
    """The CPU-time bound trips on its own: the wall-clock bound is far away."""
    with pytest.raises(CaseTimeout, match="CPU time"), bounded(seconds=60.0, cpu_seconds=0.2):
        while True:
            pass
    import signal

    assert signal.getitimer(signal.ITIMER_PROF) == (0.0, 0.0)


def test_bounded_restores_the_limits() -> None:
    import resource
    import signal

    before = resource.getrlimit(resource.RLIMIT_AS), signal.getsignal(signal.SIGALRM)
    with bounded(seconds=5.0):
        pass
    assert (resource.getrlimit(resource.RLIMIT_AS), signal.getsignal(signal.SIGALRM)) == before
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def _raise(err: Exception) -> None:
    raise err


def test_expect_clean_contract() -> None:
    assert expect_clean(lambda: 3, ["x.csv"]) == 3
    assert expect_clean(lambda: _raise(ValueError("x.csv: row 2")), ["x.csv"]) is None
    with pytest.raises(AssertionError, match="does not name the input"):
        expect_clean(lambda: _raise(ValueError("row 2: bad")), ["x.csv"])
    with pytest.raises(KeyError):
        expect_clean(lambda: {}["k"], ["x.csv"])


def test_expect_clean_bounds_a_case_by_cpu_time(monkeypatch) -> None:
    """By default a case's work is bounded by CPU time (load-proof), wall time only far off."""
    import tests.fuzz.strategies as strategies

    monkeypatch.setattr(strategies, "CASE_CPU_SECONDS", 0.2)
    assert strategies.CASE_WALL_SECONDS > 100 * strategies.CASE_CPU_SECONDS  # cannot trip first

    def spin() -> None:
        while True:
            pass

    with pytest.raises(CaseTimeout, match="CPU time"):
        expect_clean(spin, ["x.csv"])
