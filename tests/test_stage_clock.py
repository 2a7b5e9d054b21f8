"""The CLI's stage clock: time spent, time left from the last run, the record on disk."""

from __future__ import annotations

import json

from are_stats._stage_clock import StageClock, format_left, stage_times_path


class _Status:
    def __init__(self):
        self.words: list[str] = []

    def update(self, text):
        self.words.append(text)


class _Timer:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_format_left():
    assert format_left(12.2, None) == "12 s"
    assert format_left(12.2, 32.0) == "12 s, about 20 s left"
    assert format_left(31.8, 32.0) == "32 s, about 1 s left"
    assert format_left(40.0, 31.0) == "40 s, longer than last time (31 s)"


def test_second_run_shows_the_time_left(tmp_path):
    path = tmp_path / "stage_times.json"
    timer = _Timer()
    first = _Status()
    with StageClock(first, "fitting: ", size="500 rows", path=path, timer=timer) as clock:
        clock("NUTS for groups")
        timer.now += 30.0
        clock("Laplace approximation of gamma")
        timer.now += 5.0
    assert first.words == [
        "fitting: NUTS for groups ...",
        "fitting: Laplace approximation of gamma ...",
    ]
    record = json.loads(path.read_text())
    assert record == {
        "NUTS for groups [500 rows]": 30.0,
        "Laplace approximation of gamma [500 rows]": 5.0,
    }

    second = _Status()
    clock = StageClock(second, "fitting: ", size="500 rows", path=path, timer=timer)
    clock("NUTS for groups")
    timer.now += 10.0
    clock._status.update(clock._words())  # what the live refresh shows 10 s in
    assert second.words[0] == "fitting: NUTS for groups ... 0 s, about 30 s left"
    assert second.words[-1] == "fitting: NUTS for groups ... 10 s, about 20 s left"
    # another size is another stage: nothing known about it
    other = StageClock(None, size="9000 rows", path=path, timer=timer)
    assert other.last("NUTS for groups") is None
    timer.now += 2.0
    clock.close()
    assert json.loads(path.read_text())["NUTS for groups [500 rows]"] == 12.0


def test_no_record_without_the_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("ARE_STATS_NO_CACHE", "1")
    assert stage_times_path() is None
    with StageClock(None) as clock:
        clock("a stage")
    assert not any(tmp_path.iterdir())
    monkeypatch.setenv("ARE_STATS_NO_CACHE", "0")
    assert stage_times_path() == tmp_path / "are_stats" / "stage_times.json"


def test_an_unreadable_record_is_no_record(tmp_path):
    path = tmp_path / "stage_times.json"
    path.write_text("not json")
    clock = StageClock(None, path=path)
    assert clock.last("anything") is None
    clock("anything")
    clock.close()
    assert "anything" in json.loads(path.read_text())


def test_a_stage_estimate_counts_down_and_ends_with_the_stage(tmp_path):
    """A stage's own estimate (NUTS between its chunks) replaces the record's, counts
    down between two estimates, and is gone at the next stage."""
    from are_stats.fitting import NutsProgress, clock_progress

    timer, status = _Timer(), _Status()
    clock = StageClock(status, "fitting: ", path=tmp_path / "t.json", timer=timer)
    clock("NUTS for groups")
    tell = clock_progress(clock)
    tell(NutsProgress("compile", 0, 0, None))
    assert status.words[-1] == "fitting: NUTS for groups ... 0 s, compiling"
    timer.now += 4.0
    tell(NutsProgress("warm-up", 50, 500, 30.0))
    assert status.words[-1] == "fitting: NUTS for groups ... 4 s, warm-up 50/500, about 30 s left"
    timer.now += 10.0
    clock._status.update(clock._words())  # the live refresh, 10 s later
    assert status.words[-1] == "fitting: NUTS for groups ... 14 s, warm-up 50/500, about 20 s left"
    timer.now += 40.0  # past the estimate: never below a second
    assert clock._words().endswith("about 1 s left")
    tell(NutsProgress("postprocess", 0, 0, None))
    assert status.words[-1] == (
        "fitting: NUTS for groups ... 54 s, constrained draws and log-likelihood"
    )
    clock("Laplace approximation of gamma")
    assert status.words[-1] == "fitting: Laplace approximation of gamma ..."
    clock.close()
    # a plain callable has no estimate to be told
    assert clock_progress(print) is None and clock_progress(None) is None
