"""Where the wall time of one ``are-stats fit`` goes: a timeline of its threads.

``python -m tests.benchmarks.fit_timeline [--min-s 0.1] -- fit courtyard_traffic --out
/tmp/x.nc --force`` runs the command in this process (as ``are-stats`` would: dask and
numba hidden, the same ``main``) with every function of the fit's modules wrapped by a
timer, then prints each call of at least ``--min-s`` seconds: start and end (wall, from
the start of this script), its thread, the thread's CPU in the call and the process's CPU
in it (XLA's threads included); then the five phases of the command (imports, the fit,
the fit file, the summary, the report) with their wall and process CPU. Not a benchmark
of ours against a peer (no ``bench_`` prefix: ``python -m tests.benchmarks`` skips it);
the tool behind the issue-29 timings of ``docs/src/models.md``.

The wrappers cost about a microsecond a call; a repeated fit of the shipped log makes
some 10^5 such calls. Run it on a warm cache (a repeated fit) to see the repeated run.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import threading
import time
import types
from collections.abc import Callable
from typing import Any

#: Modules whose functions are timed (the traffic models are left alone: they are traced).
PREFIXES = (
    "are_stats.fitting",
    "are_stats._cli_jobs",
    "are_stats._program_cache",
    "are_stats.environment",
    "are_stats.logs",
    "are_stats._lazy",
)

#: The command's phases, by the function that is each one (all in the command's thread).
PHASES = {
    "fit_log": "the fit (fit_log)",
    "write_fit": "the fit file (write_fit)",
    "fit_summary": "the summary table (fit_summary)",
    "write_report": "the report (write_report)",
}

Event = tuple[str, str, float, float, float, float]


def _timed(name: str, fn: Callable, t0: float, events: list[Event], min_s: float) -> Callable:
    @functools.wraps(fn)
    def timed(*args: Any, **kwargs: Any) -> Any:
        start, cpu, proc = time.perf_counter(), time.thread_time(), time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            wall = time.perf_counter() - start
            if wall >= min_s:
                label = name
                if name.endswith(("_run_candidate", "_ahead_program")) and len(args) > 1:
                    label += f" {args[1]}"  # the candidate
                events.append(
                    (
                        threading.current_thread().name,
                        label,
                        start - t0,
                        wall,
                        time.thread_time() - cpu,
                        time.process_time() - proc,
                    )
                )

    return timed


def _wrap_modules(t0: float, events: list[Event], min_s: float) -> None:
    wrapped: dict[int, Callable] = {}
    for mod_name, mod in list(sys.modules.items()):
        if not mod_name.startswith("are_stats") or mod is None:
            continue
        for attr, value in list(vars(mod).items()):
            if (
                isinstance(value, types.FunctionType)
                and (value.__module__ or "").startswith(PREFIXES)
                and not attr.startswith("__")
            ):
                if id(value) not in wrapped:
                    name = f"{value.__module__.rsplit('.', 1)[-1]}.{value.__qualname__}"
                    wrapped[id(value)] = _timed(name, value, t0, events, min_s)
                setattr(mod, attr, wrapped[id(value)])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.benchmarks.fit_timeline")
    parser.add_argument("--min-s", type=float, default=0.1, help="shortest call shown (s)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- fit LOG --out X.nc ...")
    args = parser.parse_args(argv)
    command = [a for a in args.command if a != "--"] or ["fit", "courtyard_traffic"]
    t0, c0 = time.perf_counter(), time.process_time()
    events: list[Event] = []

    import are_stats.cli as cli

    if command[0] in ("fit", "report", "demo"):  # as cli.main hides them, before any import
        cli.hide_dask()
        cli.hide_numba()
    import are_stats._cli_jobs
    import are_stats.fitting  # noqa: F401 (imported here to be wrapped)

    imports = (time.perf_counter() - t0, time.process_time() - c0)
    _wrap_modules(t0, events, args.min_s)
    sys.argv = ["are-stats", *command]
    try:
        cli.main()
    except SystemExit:
        pass
    total = (time.perf_counter() - t0, time.process_time() - c0)
    out = sys.__stderr__
    print(
        f"\n{'start':>7} {'end':>7} {'wall':>6} {'thread':>6} {'proc':>6}  thread: call", file=out
    )
    for thread, name, start, wall, cpu, proc in sorted(events, key=lambda e: e[2]):
        print(
            f"{start:7.2f} {start + wall:7.2f} {wall:6.2f} {cpu:6.2f} {proc:6.2f}  "
            f"{thread}: {name}",
            file=out,
        )
    print(
        f"\nimports (cli, jobs, fitting): {imports[0]:.2f} s wall, {imports[1]:.2f} s CPU", file=out
    )
    for short, words in PHASES.items():
        for thread, name, _start, wall, _cpu, proc in events:
            if thread == "MainThread" and name.endswith(f".{short}"):
                print(f"{words}: {wall:.2f} s wall, {proc:.2f} s CPU (process)", file=out)
                break
    load = os.getloadavg()[0]
    print(f"all: {total[0]:.2f} s wall, {total[1]:.2f} s CPU; load average {load:.1f}", file=out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
