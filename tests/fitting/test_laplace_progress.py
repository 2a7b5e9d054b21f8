"""The Laplace stages' time left on a first fit (issue 29: every stage over 2 s shows
progress with the time left): the candidates' throughput so far, told to the stage clock."""

from __future__ import annotations

import time
from concurrent.futures import Future

import pytest

from are_stats.fitting import _traffic
from are_stats.fitting._traffic import _queue_left, _wait_laplace


def test_queue_left_is_the_runs_ahead_at_the_measured_rate():
    # started at 0, two runs finished at 2 and 4 s: 2 s a run; two more from 4 s is 8 s
    assert _queue_left(5.0, 0.0, [2.0, 4.0], 2) == pytest.approx(3.0)
    assert _queue_left(5.0, 0.0, [4.0, 2.0], 1) == pytest.approx(1.0)  # order does not matter
    assert _queue_left(9.0, 0.0, [2.0, 4.0], 1) is None  # overdue: the rate says nothing
    assert _queue_left(1.0, 0.0, [], 3) is None  # no run finished: no rate yet


class _Clock:
    """A stage clock's ``left`` and ``last`` (no record unless ``record``), which finishes
    the awaited run at its ``finish_after``-th estimate."""

    def __init__(self, pending: Future, finish_after: int, record: float | None = None):
        self.calls: list = []
        self.pending, self.finish_after, self.record = pending, finish_after, record

    def __call__(self, _words: str) -> None:  # the stage's start
        pass

    def last(self, _stage: str) -> float | None:
        return self.record

    def left(self, seconds: float | None, words: str) -> None:
        self.calls.append((seconds, words))
        if len(self.calls) >= self.finish_after:
            self.pending.set_result("run")


def _runs() -> tuple[dict, Future]:
    done, pending, queued = Future(), Future(), Future()
    done.set_result("first")
    return {("arrivals", "a"): done, ("arrivals", "b"): pending, ("stays", "c"): queued}, pending


def test_a_waiting_laplace_stage_tells_the_clock_its_time_left(monkeypatch):
    monkeypatch.setattr(_traffic, "LAPLACE_POLL", 0.001)
    runs, pending = _runs()
    clock = _Clock(pending, finish_after=2)
    start, finished = -1e9, [-1e9 + 2.0]  # one run in 2 s, long ago: overdue
    got = _wait_laplace(("arrivals", "b"), runs, clock, (start, finished))
    assert got == "run"
    assert clock.calls == [(None, "1/3 Laplace candidates done")] * 2
    # a rate that still says something: one run in 1e6 s, just now; one run ahead
    runs, pending = _runs()
    clock = _Clock(pending, finish_after=1)
    now = time.perf_counter()
    assert _wait_laplace(("arrivals", "b"), runs, clock, (now - 1e6, [now])) == "run"
    [(seconds, words)] = clock.calls
    assert 1e6 - 60.0 < seconds <= 1e6 and words == "1/3 Laplace candidates done"
    # before any run finished: the time left is not known yet
    runs, pending = _runs()
    runs[("arrivals", "a")] = Future()
    clock = _Clock(pending, finish_after=1)
    assert _wait_laplace(("arrivals", "b"), runs, clock, (0.0, [])) == "run"
    assert clock.calls == [(None, "0/3 Laplace candidates done")]


def test_a_recorded_stage_keeps_the_records_time_left(monkeypatch):
    """A later fit: the stage clock's record of the stage is the better estimate; the
    wait tells the clock nothing (and a progress without ``left`` is just waited on)."""
    monkeypatch.setattr(_traffic, "LAPLACE_POLL", 0.001)
    runs, pending = _runs()
    pending.set_result("run")
    clock = _Clock(pending, finish_after=1, record=3.0)
    assert _wait_laplace(("arrivals", "b"), runs, clock, (0.0, [1.0])) == "run"
    assert clock.calls == []
    assert _wait_laplace(("arrivals", "b"), runs, print, (0.0, [1.0])) == "run"
