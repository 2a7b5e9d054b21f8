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


def test_a_stage_stopped_by_an_error_stays_out_of_the_record(tmp_path):
    """A refusal inside a stage (``generate --behaviours`` without ``--map`` is checked in
    the assembly's first stage) would record its moment as the stage's duration, and the
    next run would show that as the time left; the stages finished before it are kept."""
    path, timer = tmp_path / "stage_times.json", _Timer()
    try:
        with StageClock(None, path=path, timer=timer) as clock:
            clock("read the log")
            timer.now += 3.0
            clock("scenes")
            timer.now += 0.01
            raise ValueError("--behaviours: expected --map")
    except ValueError:
        pass
    assert json.loads(path.read_text()) == {"read the log": 3.0}


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


def _compiling(spans):
    """``compiled(t0, t1)`` of a clock whose compiles ran in ``spans`` (disjoint)."""
    return lambda t0, t1: sum(max(0.0, min(b, t1) - max(a, t0)) for a, b in spans)


def test_the_record_leaves_out_the_compiling_a_warm_cache_spares(tmp_path):
    """A first run compiles (20 s of its 30 s); the persistent cache spares the second run
    that, so the second run's estimate is the first's 10 s of work, not its 30 s. A run
    that compiles again holds its time left while it compiles."""
    path = tmp_path / "stage_times.json"
    timer, spans = _Timer(), [(101.0, 121.0)]  # the timer starts at 100 s
    first = StageClock(None, size="4 x 600 s", path=path, timer=timer, compiled=_compiling(spans))
    first("rollouts")
    timer.now += 30.0
    first.close()
    assert json.loads(path.read_text()) == {"rollouts [4 x 600 s]": 10.0}

    status = _Status()
    spans.append((134.0, 137.0))  # a program the cache did not have
    second = StageClock(status, size="4 x 600 s", path=path, timer=timer,
                        compiled=_compiling(spans))  # fmt: skip
    second("rollouts")
    timer.now += 4.0
    assert second._words() == "rollouts ... 4 s, about 6 s left"
    assert second.spent() == 4.0
    timer.now += 3.0  # compiling: the time left holds
    assert second._words() == "rollouts ... 7 s, about 6 s left"
    assert second.spent() == 4.0
    timer.now += 7.0
    assert second._words() == "rollouts ... 14 s, longer than last time (10 s)"
    second.close()
    assert json.loads(path.read_text()) == {"rollouts [4 x 600 s]": 11.0}
    assert second.spent() == 0.0  # between stages


def test_xla_compiling_is_the_time_xla_compiled_not_loaded(tmp_path):
    """JAX's own compile events: a new program's compile is inside the time measured; the
    same program loaded from the persistent cache by a fresh jit adds (almost) nothing;
    two threads compiling at once count once (at most the time that passed)."""
    import threading
    import time

    import jax
    import numpy as np
    from jax.experimental.compilation_cache import compilation_cache

    from are_stats._stage_clock import xla_compiling

    names = (
        "jax_compilation_cache_dir",
        "jax_persistent_cache_min_compile_time_secs",
        "jax_persistent_cache_min_entry_size_bytes",
    )
    saved = {name: getattr(jax.config, name) for name in names}
    base = float(np.random.default_rng().integers(1, 10**9))  # programs no cache holds

    def program(constant):
        def f(x):
            for _ in range(20):
                x = jax.numpy.sin(x) * constant + jax.numpy.cos(x)
            return x

        return jax.jit(f)

    x = np.linspace(0.0, 1.0, 37)
    try:
        for name, value in zip(names, (str(tmp_path), 0.0, -1), strict=True):
            jax.config.update(name, value)
        compilation_cache.reset_cache()
        xla_compiling(0.0, 0.0)  # watching from here
        t0 = time.perf_counter()
        program(base)(x).block_until_ready()
        t1 = time.perf_counter()
        compiled = xla_compiling(t0, t1)
        assert 0.0 < compiled <= t1 - t0
        assert any(tmp_path.iterdir())  # the program went to the persistent cache
        # a fresh jit of a new closure traces again and finds the executable only in the
        # persistent cache (no jax.clear_caches(): it would empty this worker's compiled
        # programs for every test after this one)
        t2 = time.perf_counter()
        program(base)(x).block_until_ready()
        assert xla_compiling(t2, time.perf_counter()) < 0.5 * compiled
        threads = [
            threading.Thread(target=lambda c=c: program(c)(x).block_until_ready())
            for c in (base + 1, base + 2, base + 3)
        ]
        t3 = time.perf_counter()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        t4 = time.perf_counter()
        assert 0.0 < xla_compiling(t3, t4) <= t4 - t3
    finally:
        for name, value in saved.items():
            jax.config.update(name, value)
        compilation_cache.reset_cache()


def test_a_stage_of_steps_shows_the_time_left_from_their_rate_on_a_first_run(tmp_path):
    """``clock.steps``: nothing recorded, the first step (which compiles) starts the count,
    the next ones' mean time times the steps left is the time left; a new stage counts
    afresh; a later run uses the record instead."""
    path = tmp_path / "stage_times.json"
    timer = _Timer()
    status = _Status()
    with StageClock(status, "fitting: ", path=path, timer=timer, compiled=None) as clock:
        clock("realism")
        for dt, done in ((30.0, 1), (10.0, 2), (12.0, 3)):
            timer.now += dt
            clock.steps(done, 5, "replicates")
        assert status.words[-3:] == [
            "fitting: realism ... 30 s, replicates (1/5)",
            "fitting: realism ... 40 s, replicates (2/5), about 30 s left",
            "fitting: realism ... 52 s, replicates (3/5), about 22 s left",
        ]
        clock("behaviour")  # the steps of the stage before count for nothing here
        timer.now += 8.0
        clock.steps(1, 2)
        assert status.words[-1] == "fitting: behaviour ... 8 s, 1/2"
        timer.now += 4.0
    second = _Status()
    with StageClock(second, "fitting: ", path=path, timer=timer, compiled=None) as clock:
        clock("realism")
        timer.now += 20.0
        clock.steps(1, 5, "replicates")  # 52 s recorded, 20 s spent
    assert second.words[-1] == "fitting: realism ... 20 s, replicates (1/5), about 32 s left"
