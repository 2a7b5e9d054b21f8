"""The CPU time a process spends importing, per module and per thread (for
:mod:`tests.benchmarks.bench_imports`).

``python -X importtime`` measures wall time (inflated by every other thread and process on
a loaded machine) and charges a library to whichever module imports it first; a profiler
run with ``time.process_time`` charges the CPU of every thread to the main thread's calls.
This clock times each module's creation and execution with ``time.thread_time`` in the
thread that imports it, so that a module imported in a worker thread (the fit's ArviZ)
counts once and other threads' work does not count at all.

Run a command under it in a fresh process::

    python tests/benchmarks/_import_clock.py RECORD.json fit courtyard_traffic --out X

It imports only the standard library before it installs itself (it is run as a script, not
as ``tests.benchmarks._import_clock``), then runs ``are_stats.cli`` as
``python -m are_stats.cli`` would and writes ``RECORD.json`` at exit: one row per module,
``[depth, name, thread CPU in s (children included), thread name]``, in the order the
imports finished.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import json
import sys
import threading
import time
from collections import defaultdict
from collections.abc import Sequence
from types import ModuleType
from typing import Any

#: One row per imported module: (depth, name, thread CPU s, thread name).
Row = tuple[int, str, float, str]


class _TimedLoader:
    """Stands for one module's loader; times ``create_module`` and ``exec_module``."""

    def __init__(self, loader: Any, clock: ImportClock) -> None:
        self._loader = loader
        self._clock = clock

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._loader, attr)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self._clock.timed(spec.name, self._loader.create_module, spec)

    def exec_module(self, module: ModuleType) -> None:
        self._clock.timed(module.__name__, self._loader.exec_module, module)


class ImportClock(importlib.abc.MetaPathFinder):
    """A finder placed first on ``sys.meta_path`` that wraps every module's loader in a
    thread-CPU clock (:attr:`rows`)."""

    def __init__(self) -> None:
        self.rows: list[Row] = []
        self._depth = threading.local()

    def find_spec(
        self, name: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is None:
                continue
            if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                spec.loader = _TimedLoader(spec.loader, self)  # type: ignore[assignment]
            return spec
        return None

    def timed(self, name: str, step: Any, arg: Any) -> Any:
        depth = getattr(self._depth, "n", 0)
        self._depth.n = depth + 1
        t0 = time.thread_time()
        try:
            return step(arg)
        finally:
            self._depth.n = depth
            dt = time.thread_time() - t0
            if dt > 2e-5:  # the creation of a pure-Python module (nothing): left out
                self.rows.append((depth, name, dt, threading.current_thread().name))


def self_times(rows: Sequence[Row]) -> dict[str, float]:
    """Each module's own thread CPU (s): its time less its children's.

    The rows of a thread come in the order the imports finished (children before their
    parent), so a module's children are the rows one level deeper since its last sibling.
    """
    per_thread: dict[str, list[Row]] = defaultdict(list)
    for row in rows:
        per_thread[row[3]].append(row)
    own: dict[str, float] = defaultdict(float)
    for thread_rows in per_thread.values():
        pending: dict[int, list[float]] = defaultdict(list)
        for depth, name, dt, _ in thread_rows:
            own[name] += dt - sum(pending.pop(depth + 1, []))
            pending[depth].append(dt)
    return dict(own)


def by_package(rows: Sequence[Row], level: int = 1) -> list[tuple[str, float]]:
    """Own thread CPU (s) summed per package (the first ``level`` parts of the module
    names), largest first."""
    total: dict[str, float] = defaultdict(float)
    for name, dt in self_times(rows).items():
        total[".".join(name.split(".")[:level])] += dt
    return sorted(total.items(), key=lambda kv: -kv[1])


def import_cpu(rows: Sequence[Row]) -> dict[str, float]:
    """The outermost imports' thread CPU (s): in all, in the main thread, in the others."""
    main = sum(dt for depth, _, dt, th in rows if depth == 0 and th == "MainThread")
    others = sum(dt for depth, _, dt, th in rows if depth == 0 and th != "MainThread")
    return {"all": main + others, "main thread": main, "other threads": others}


def _run(record: str, argv: list[str]) -> None:
    import atexit
    import runpy

    clock = ImportClock()
    sys.meta_path.insert(0, clock)

    def write() -> None:
        with open(record, "w") as fh:
            json.dump({"rows": clock.rows, "process_cpu": time.process_time()}, fh)

    atexit.register(write)
    sys.argv = ["are-stats", *argv]
    runpy.run_module("are_stats.cli", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    sys.path.pop(0)  # this folder: nothing here may stand for a library (e.g. 'tree')
    _run(sys.argv[1], sys.argv[2:])
