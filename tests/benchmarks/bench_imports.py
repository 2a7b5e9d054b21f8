"""Benchmark: what a repeated ``are-stats fit courtyard_traffic`` (figures on) spends on
imports (issue 29's repeated fit in at most 5 s).

Each run is a fresh process on one cache (a new ``$XDG_CACHE_HOME``, filled by one cold run
first), under :mod:`tests.benchmarks._import_clock`: every module's creation and execution
timed with ``time.thread_time`` in the thread that imports it. Printed per repeated run:
the process's CPU, the import CPU of the outermost imports (all threads, the main thread,
the others: the fit imports ArviZ in its InferenceData thread); for the last run the own
import CPU per package (a module's time less its children's, summed per top-level
package and per ``package.subpackage``). ``-X importtime`` and a profiler with
``time.process_time`` mislead here: the first is wall time (inflated by every busy thread
and process) and charges a library to whichever module imported it first (JAX to
``are_stats.export`` when the CLI's job module imports it before ``are_stats.fitting``
does), the second charges every thread's CPU to the main thread's calls.

Run with ``python -m tests.benchmarks imports`` (``--quick``: one repeated run, not three).
Benchmarks never assert on time.

Measured 2026-11-28 (main 2f397d6, a user's virtual environment without numba, bytecode
written, load 17-18 where recorded, on the shared 2-core machine; three repeated runs):
process CPU 13.0-15.1 s, import CPU 4.35, 5.12, 5.48 s (main thread 2.7-3.3 s, the InferenceData
thread's ArviZ 1.6-2.2 s). Own import CPU per package over the three: scipy 1.24-1.67
(stats 0.44-0.63, signal 0.23-0.25: ArviZ imports both, the traffic positions' smoothing
scipy.signal too; scipy 1.17 rewrites the docstrings of its array-API functions at import),
jax 0.70-0.82 + jaxlib 0.15-0.22, matplotlib 0.50-0.60 (+ mpl_toolkits' 3-D axes 0.05-0.17
and pyparsing 0.12-0.14, all through ``matplotlib.pyplot``, which ArviZ imports), pandas
0.28-0.36 + pyarrow 0.11-0.14, numpy 0.18-0.24, xarray 0.15-0.19, numpyro 0.08-0.10,
typer's pydantic 0.06-0.08 (its option coercion), are_stats' own modules 0.14-0.17. The fit
calls into every one of these: the CLI's import of ``are_stats.export`` (which brings
``are_stats.scenarios`` and JAX first) adds 6 modules and 8 ms of CPU to what
``are_stats.fitting``, ArviZ and the report import anyway.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

from tests.benchmarks._import_clock import by_package, import_cpu
from tests.benchmarks.bench_traffic_nuts import _env, _spawn

CLOCK = Path(__file__).with_name("_import_clock.py")
COMMAND = ["fit", "courtyard_traffic", "--force"]


def _run(home: Path, record: Path) -> dict[str, Any]:
    """One ``are-stats fit`` under the import clock on the cache ``home``."""
    env = _env(home)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # a user's process writes its bytecode
    args = [sys.executable, str(CLOCK), str(record), *COMMAND, "--out", str(home / "fit.nc")]
    proc, wall = _spawn(args, env)
    if proc.returncode != 0:
        raise RuntimeError(f"are-stats {' '.join(COMMAND)} failed:\n{proc.stderr[-3000:]}")
    data = json.loads(record.read_text())
    return {"wall": wall, "cpu": data["process_cpu"], "rows": data["rows"]}


def main(quick: bool = False) -> None:
    """Import CPU of repeated fits of the shipped log, per run and per package."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_imports_"))
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the start")
    try:
        cold = _run(tmp, tmp / "cold.json")
        print(f"cold (fills the cache): CPU {cold['cpu']:.1f} s, wall {cold['wall']:.1f} s")
        for i in range(1 if quick else 3):
            r = _run(tmp, tmp / f"repeated{i}.json")
            cpu = import_cpu(r["rows"])
            print(
                f"repeated {i + 1}: CPU {r['cpu']:.2f} s (wall {r['wall']:.1f} s, load "
                f"{os.getloadavg()[0]:.1f}); imports {cpu['all']:.2f} s "
                f"(main thread {cpu['main thread']:.2f}, others {cpu['other threads']:.2f})"
            )
        for level in (1, 2):
            top = by_package(r["rows"], level)[:15]
            print(f"own import CPU per package, level {level} (s): ", end="")
            print(", ".join(f"{name} {dt:.3f}" for name, dt in top))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
