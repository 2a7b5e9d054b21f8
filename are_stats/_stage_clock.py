"""Stage progress with the time left, for the CLI's long jobs (``fit``, ``generate``).

A command's slow parts (a NUTS fit per model, the candidates' comparison, the behaviour
fit, the rollouts) each run as one compiled program, so their progress cannot be counted
from inside. What can be said is how long each stage took the last time: :class:`StageClock`
records every stage's duration (keyed by the stage's words and a size the caller gives,
e.g. the log's rows) in ``$XDG_CACHE_HOME/are_stats/stage_times.json`` beside the compile
cache, and while a stage runs it shows ``<stage> ... 12 s, about 20 s left`` from that
record (``12 s`` alone for a stage never timed here; a stage past its last time says
``longer than last time``). A stage that can measure its own rate says so
(:meth:`StageClock.left`: NUTS between its compiled chunks of iterations), and then the
line shows that estimate, ``NUTS for groups ... 12 s, sampling 300/500, about 8 s left``,
on a machine's first run too. A stage of counted steps says where it stands
(:meth:`StageClock.steps`, :class:`StepsLeft`: the scene assembly's planning and social
force, the fit's behaviour classes and realism replicates), and on a first run its time
left is the rate of its steps after the first (which compiles) times the steps left. The
record follows the compile cache: off with ``ARE_STATS_NO_CACHE``.

What is recorded is a stage's time **less the XLA compiling it paid**
(:func:`xla_compiling`: the time during the stage when some thread compiled), and a
running stage's time left is the record less its own time so far, again less its
compiling. A first run compiles every program; the persistent compile cache (which the
record follows, small programs included) spares the next run all of it, so the first
run's whole duration made the second run's estimate too long by the compile (the third
run, timing a warm second, was right). The alternatives were weaker: the rate after the
first step of a stage misses the programs compiled later (the social force compiles one
per padded size of its windows) and says nothing of one-step stages; keeping only runs
with a warm cache gives the second run no estimate at all; the minimum of the runs still
shows the second run the first's. Compiling is measured rather than guessed, from JAX's
own events, so a run that must compile again (an evicted program, a new size) shows its
time left holding still while it compiles rather than running out. Measured
(2026-11-27, ``are-stats fit courtyard_traffic``, 10 stages, fresh cache then warm, a
loaded 2-core machine): the first run fitted in 75 s and recorded 25 s for its stages,
which took 20 s on the warm run (the whole duration would have said 75 s). Per stage the
record is rougher (0.6 s against 1.8 s, 6.8 s against 1.3 s) where the fit compiles the
next candidates in two background threads while a stage works. What the record still
holds of a first run that a warm run skips: tracing the programs that
:mod:`are_stats._program_cache` keeps (NUTS) and Warp's kernel builds.

Nothing is drawn unless the console is a terminal (rich's status is silent elsewhere), so
piped output and tests see only the command's own lines.
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import jax.monitoring

if TYPE_CHECKING:

    class _Status(Protocol):
        """Where a :class:`StageClock`'s words go: a ``rich.status.Status``, or anything
        with its ``update``."""

        def update(self, status: str) -> object: ...


__all__ = [
    "StageClock",
    "StepsLeft",
    "format_left",
    "stage_times_path",
    "watch_xla_compiles",
    "xla_compiling",
]

#: Stages shorter than this are not worth a clock (seconds).
MIN_SHOWN = 2.0
#: Most stages kept in the record (oldest dropped first).
MAX_RECORDS = 512


def stage_times_path() -> Path | None:
    """The record of stage durations, or None when the cache is off."""
    if os.environ.get("ARE_STATS_NO_CACHE", "") not in ("", "0"):
        return None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "are_stats" / "stage_times.json"


#: JAX's events: a program's compile (or its load from the persistent cache), and the load.
_COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
_LOAD_EVENT = "/jax/compilation_cache/cache_retrieval_time_sec"
_spans: list[list[float]] = []  # disjoint, sorted (time.perf_counter): when XLA compiled
_spans_lock = threading.Lock()
_loaded = threading.local()  # the load just before a compile event, on its thread
_watch: list[float] = []  # time.time() - time.perf_counter(), once watching


def _on_load(event: str, duration_secs: float, **kwargs: object) -> None:
    if event == _LOAD_EVENT:
        _loaded.seconds = float(duration_secs)


def _on_span(event: str, start_time: float, end_time: float, **kwargs: object) -> None:
    if event != _COMPILE_EVENT:
        return
    # a hit: its load is paid on every run, so only the rest of the span counts
    start = min(start_time + getattr(_loaded, "seconds", 0.0), end_time) - _watch[0]
    end = end_time - _watch[0]
    _loaded.seconds = 0.0
    with _spans_lock:  # merge into the disjoint spans
        inside = [s for s in _spans if s[1] >= start and s[0] <= end]
        merged = [min([start, *(s[0] for s in inside)]), max([end, *(s[1] for s in inside)])]
        _spans[:] = sorted([s for s in _spans if s not in inside] + [merged])


def watch_xla_compiles() -> bool:
    """Start recording when XLA compiles (JAX's events); True once recording."""
    if not _watch:
        _watch.append(time.time() - time.perf_counter())
        jax.monitoring.register_event_duration_secs_listener(_on_load)
        jax.monitoring.register_event_time_span_listener(_on_span)
    return True


def xla_compiling(t0: float, t1: float) -> float:
    """Seconds of ``[t0, t1]`` (:func:`time.perf_counter`) during which XLA compiled a
    program, in any thread (loads from the persistent cache not counted): time that a run
    with a warm cache does not spend.

    The union of the compiles' spans, not the sum of their durations: the fit compiles its
    candidates in two threads while a stage runs, and the stage waits on them at most the
    once. A compile still running is counted when it ends. Records from the first call of
    :func:`watch_xla_compiles` on (this calls it); 0.0 before it is on.
    """
    watch_xla_compiles()
    with _spans_lock:
        return float(sum(max(0.0, min(b, t1) - max(a, t0)) for a, b in _spans))


def format_left(elapsed: float, last: float | None, compiled: float = 0.0) -> str:
    """``12 s`` / ``12 s, about 20 s left`` / ``40 s, longer than last time (31 s)``.

    Parameters
    ----------
    elapsed : float
        Seconds spent in the stage so far.
    last : float or None
        The stage's duration the last time it ran here, less its compiling (None: never).
    compiled : float
        Seconds of ``elapsed`` spent compiling: not counted against ``last``.
    """
    spent = f"{elapsed:.0f} s"
    if last is None:
        return spent
    left = last - (elapsed - compiled)
    if left < 0:
        return f"{spent}, longer than last time ({last:.0f} s)"
    return f"{spent}, about {max(left, 1.0):.0f} s left"


class StageClock:
    """Time a job's stages, show the time left in a rich status, record the durations.

    Parameters
    ----------
    status : rich.status.Status or None
        Where the words go (``status.update(text)``); None: only record.
    prefix : str
        Put before every stage (``"fitting: "``).
    size : str
        Part of every stage's key (e.g. ``"500 rows"``): the same stage on other data
        takes another time.
    live : bool
        Refresh the words every half second (a terminal); otherwise once per stage.
    path : Path or None
        The record (default :func:`stage_times_path`).
    timer : callable
        Seconds now (default :func:`time.perf_counter`).
    compiled : callable or None
        ``compiled(t0, t1)``: seconds of ``[t0, t1]`` (``timer``'s) spent compiling,
        which the next run will not spend (default :func:`xla_compiling` when there is a
        record to keep and ``timer`` is the default, else None: nothing subtracted). A
        stage's recorded time and its time spent against the record are the timer's less
        these (see the module docstring).

    Examples
    --------
    >>> clock = StageClock(None, size="500 rows", path=None)
    >>> clock("NUTS for groups")  # a stage starts; the previous one ends
    >>> clock.left(20.0, "warm-up 50/500")  # the stage's own estimate of its time left
    >>> clock.close()  # the last stage ends; the record is written
    """

    def __init__(
        self,
        status: _Status | None,
        prefix: str = "",
        size: str = "",
        live: bool = False,
        path: Path | None | str = "default",
        timer: Callable[[], float] = time.perf_counter,
        compiled: Callable[[float, float], float] | None | str = "default",
    ) -> None:
        self._status, self._prefix, self._size = status, prefix, size
        self._timer = timer
        self._path = stage_times_path() if path == "default" else path
        if compiled == "default":
            default = self._path is not None and timer is time.perf_counter
            compiled = xla_compiling if default and watch_xla_compiles() else None
        self._compiled: Callable[[float, float], float] = compiled or (lambda t0, t1: 0.0)  # type: ignore[assignment]
        self._record = self._read()
        self._stage: str | None = None
        self._t0 = 0.0
        self._estimate: tuple[float | None, str, float] | None = None  # (left, words, at)
        self._steps: StepsLeft | None = None  # the running stage's steps (steps())
        self._lock = threading.Lock()
        self._done = threading.Event()
        self.durations: dict[str, float] = {}
        self._ticker = None
        if live and status is not None:
            self._ticker = threading.Thread(target=self._tick, name="are-stats-clock", daemon=True)
            self._ticker.start()

    def _read(self) -> dict[str, float]:
        if self._path is None:
            return {}
        try:
            data = json.loads(Path(self._path).read_text())
        except (OSError, ValueError):
            return {}
        return {str(k): float(v) for k, v in data.items()} if isinstance(data, dict) else {}

    def _key(self, stage: str) -> str:
        return f"{stage} [{self._size}]" if self._size else stage

    def last(self, stage: str) -> float | None:
        """The stage's duration the last time, less its compiling (None: never recorded
        here)."""
        return self._record.get(self._key(stage))

    def spent(self) -> float:
        """Seconds of the running stage so far less its compiling: what :meth:`last` is
        to be compared with (0.0 between stages)."""
        with self._lock:
            if self._stage is None:
                return 0.0
            now = self._timer()
            return now - self._t0 - self._compiled(self._t0, now)

    def _words(self) -> str:
        stage = self._stage or ""
        now = self._timer()
        elapsed = now - self._t0
        if self._estimate is not None:
            left, words, at = self._estimate
            parts = [f"{elapsed:.0f} s", words]
            if left is not None:
                parts.append(f"about {max(left - (now - at), 1.0):.0f} s left")
            return f"{self._prefix}{stage} ... " + ", ".join(p for p in parts if p)
        last = self.last(stage)
        if elapsed < MIN_SHOWN and last is None:
            return f"{self._prefix}{stage} ..."
        compiled = self._compiled(self._t0, now)
        return f"{self._prefix}{stage} ... {format_left(elapsed, last, compiled)}"

    def _tick(self) -> None:
        while not self._done.wait(0.5):
            with self._lock:
                if self._stage is not None:
                    self._status.update(self._words())

    def _end(self) -> None:
        if self._stage is not None:
            now = self._timer()
            spent = now - self._t0 - self._compiled(self._t0, now)
            self.durations[self._key(self._stage)] = max(spent, 0.0)

    def __call__(self, stage: str) -> None:
        """Start ``stage`` (ending the one before)."""
        with self._lock:
            self._end()
            self._stage, self._t0, self._estimate = stage, self._timer(), None
            self._steps = None
            if self._status is not None:
                self._status.update(self._words())

    def left(self, seconds: float | None, words: str = "") -> None:
        """The current stage's own estimate of its time left, from its measured rate.

        It replaces the record's until the stage ends; the line counts it down between
        two estimates.

        Parameters
        ----------
        seconds : float or None
            Seconds left (None: not known yet, e.g. while compiling).
        words : str
            Where the stage stands (``"warm-up 100/500"``), shown before the time left.
        """
        with self._lock:
            if self._stage is None:
                return
            self._estimate = (None if seconds is None else float(seconds), words, self._timer())
            if self._status is not None:
                self._status.update(self._words())

    def steps(self, done: int, total: int, what: str = "") -> None:
        """The current stage's steps: ``done`` of ``total`` (``what``: the last one done).

        The time left is :class:`StepsLeft`'s: the record's on a later run, on a first
        run the rate of the steps after the first of a phase (which compiles) times the
        steps left. A stage that reports no steps keeps the record's time left alone.

        Parameters
        ----------
        done, total : int
            Steps done so far, and in all (a new ``total`` starts a new phase).
        what : str
            Where the stage stands (``"displacement errors"``), shown before ``done/total``.
        """
        with self._lock:
            if self._stage is None:
                return
            if self._steps is None:
                self._steps = StepsLeft(self, self._stage, timer=self._timer)
            steps = self._steps
        steps(done, total, what)

    def close(self, failed: bool = False) -> None:
        """End the last stage, stop the refresh and write the record (best effort).

        ``failed``: the last stage stopped on an error, so its time so far is not its
        duration and stays out of the record (the stages before it are kept).
        """
        with self._lock:
            if not failed:
                self._end()
            self._stage = None
        self._done.set()
        if self._ticker is not None:
            self._ticker.join()
        if self._path is None or not self.durations:
            return
        # the stages just timed go last: the oldest are dropped first
        record = {k: v for k, v in self._record.items() if k not in self.durations}
        record.update(self.durations)
        record = dict(list(record.items())[-MAX_RECORDS:])
        try:
            path = Path(self._path)
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps(record, indent=0))
            os.replace(tmp, path)
        except OSError:  # a read-only cache: the clock is a nicety
            pass

    def __enter__(self) -> StageClock:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self.close(failed=exc_type is not None)


class StepsLeft:
    """A ``progress(done, total, what)`` that tells a stage clock where a stage of counted
    steps stands and the time left (:meth:`StageClock.left`): the scene assembly's
    (:func:`~are_stats.scenarios.scenes_from_fit`, ``are-stats generate``) and, through
    :meth:`StageClock.steps`, the fit's (behaviour classes, realism replicates).

    The time left is the stage's recorded duration less the time spent when the clock
    has one (a later run; both without compiling, :meth:`StageClock.spent`); on a
    machine's first run it is the mean time of the steps of the current phase done after
    its first (which compiles) times the steps left, unknown until one of those is timed.
    A phase is a run of steps with the same ``total``: the assembly's planning and its
    social force have steps of different lengths, and each announces its own total when
    it starts (the scenarios' draw, quick, is a phase of its own). ``what`` may be empty:
    the line then shows ``done/total`` alone.

    Parameters
    ----------
    clock : StageClock
        The clock of the running stage.
    stage : str
        The stage's words (its key in the clock's record).
    timer : callable
        Seconds now (default :func:`time.perf_counter`).
    """

    def __init__(
        self, clock: StageClock, stage: str, timer: Callable[[], float] = time.perf_counter
    ) -> None:
        self._clock, self._stage, self._timer = clock, stage, timer
        self._phase: tuple[int, int, float] | None = None  # (total, done, time) at its start

    def __call__(self, done: int, total: int, what: str) -> None:
        now = self._timer()
        if self._phase is None or self._phase[0] != total:
            self._phase = (total, done, now)
        _, done0, t0 = self._phase
        last = self._clock.last(self._stage)
        if last is not None:
            left: float | None = max(last - self._clock.spent(), 0.0)
        elif done >= total:
            left = 0.0
        elif done > done0:
            left = (now - t0) / (done - done0) * (total - done)
        else:
            left = None
        self._clock.left(left, f"{what} ({done}/{total})" if what else f"{done}/{total}")
