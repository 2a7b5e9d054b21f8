"""Test configuration: CPU only, two host devices for parallel chains, every test reseeded."""

from __future__ import annotations

import gc
import os
import platform
import sys

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
os.environ.setdefault("MPLBACKEND", "Agg")

#: The tests that pin results to the bit (the goldens' digests) or read a chaotic
#: simulation (``tests/crowd.py``: one ulp in a sine moves people by metres) hold on one
#: x86-64 instruction set: AVX2. On a host with AVX-512, NumPy's float64 trigonometry
#: (``sin``, ``cos``, ``arctan2``, ``arcsin``), OpenBLAS's kernels and XLA's code are other
#: kernels, correct to the last bit or two but not the same bits (seen 2026-11-28: every
#: digest taken on an AVX-512 host differed on an AVX2 AMD EPYC, with the same packages).
#: The tests therefore ask all three for their AVX2 kernels; on an AVX2 host these settings
#: change nothing. They are read when NumPy, OpenBLAS and XLA load, so they are set here,
#: before anything imports them (the workers of ``-n 2`` inherit them). The product itself
#: keeps each host's fastest kernels: a run is reproducible from its seed on one host.
PINNED_ISA = {
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OPENBLAS_CORETYPE": "Haswell",
}
if platform.machine().lower() in ("x86_64", "amd64"):
    for name, value in PINNED_ISA.items():
        os.environ.setdefault(name, value)
    if "xla_cpu_max_isa" not in os.environ["XLA_FLAGS"]:
        os.environ["XLA_FLAGS"] += " --xla_cpu_max_isa=AVX2"
    if "numpy" in sys.modules:  # a plugin imported NumPy first: its kernels are chosen
        import warnings

        warnings.warn(
            "NumPy was imported before tests/conftest.py: NPY_DISABLE_CPU_FEATURES has no "
            "effect, and bit-pinned tests may differ on an AVX-512 host",
            stacklevel=1,
        )

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import are_stats  # noqa: E402,F401  (enables x64 before any test touches JAX)

# Property tests explore new examples on every local run (failures are kept in
# .hypothesis/); CI (.ci/run sets HYPOTHESIS_PROFILE=ci) runs the same derandomised examples
# every time, so a landing is not decided by which examples a run happened to draw.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

#: The collector's thresholds of the test processes: those the ``are-stats`` command sets
#: (``are_stats.cli.main``, measured there: a warm fit spent 1.1-1.3 s of its 9 s in
#: collections at Python's defaults, 0.3-0.4 s at these). The tests trace and compile
#: programs in one long process whose imported libraries, fixtures and traced programs
#: every full collection walks again. Cycles are still collected; no value a test computes
#: depends on when.
GC_THRESHOLDS = (10_000, 20, 20)
gc.set_threshold(*GC_THRESHOLDS)

#: The test files that take longest, roughly longest first, for both tiers (``make test``:
#: ``-m "not slow"``; ``make test-slow``: ``-m slow``; a file with nothing selected drops
#: out). From the per-test durations of the cold full run of 2026-11-27 (an empty JAX
#: cache) and per-test CPU times of 2026-11-28 (cold, file by file). ``make test`` hands whole
#: files to two workers (``--dist loadfile``); a long file handed out last runs alone at the
#: end, so these go first and the many short files fill in behind them (longest processing
#: time first). xdist's own order (most tests first) would put them last: it is switched
#: off in :func:`pytest_configure`. A file missing here only runs later; nothing is skipped.
#: Change the order only with repeated measured full runs: on 2026-11-29 this order ran
#: the same code in 16:03 and in 12:19 on idle cores (every file 0.6-0.9x in the second
#: run: the host's speed changed), and a reorder by per-file seconds ran 20:52 once, which
#: that variance alone could explain.
HEAVY_FILES: tuple[str, ...] = (
    "tests/fitting/test_behaviour_fit.py",  # default: about 230 s of CPU cold in 19 tests
    # default: the rich log's true stay law against the paper's by NUTS, Laplace and
    # ranked fits (about 50 s of CPU, 2026-11-29); slow: the groups arrivals by NUTS, every
    # candidate by NUTS (140 s), a log per candidate, the paper's truth, stays in days,
    # diurnal (about 700 s)
    "tests/fitting/test_traffic.py",
    "tests/test_integrity.py",  # slow: same-seed runs and kills, about 20 are-stats processes
    # slow: builds the wheel; in CI (ARE_STATS_FRESH_VENV=1) a fresh venv, about 3.5 min
    "tests/test_wheel.py",
    # default: the first stream of each fuzz test (fuzz_tiers, a quarter of its cases), 11
    # edited fit files drawn from and some 670 file cases (51 s of CPU cold alone, against
    # 78 s for the half, 1,300 cases, before 2026-11-29); slow: the second stream
    "tests/fuzz/test_fuzz_package.py",
    "tests/fuzz/test_fuzz_tracks_scale.py",  # slow: three 300-person tracks fits
    "tests/test_cli_tracks.py",  # slow: the tracks fit, report and generation by the CLI
    "tests/fitting/test_fit.py",  # default: two tracks fits (about 100 s of CPU cold)
    # walks and motion checks by generation and criticism (about 100 s of CPU cold without
    # the slow one), with 15 tests: by test count it started among the last files
    "tests/fitting/test_heading_variation.py",
    "tests/scenarios/test_assembly_golden.py",  # about 120 s of CPU cold
    "tests/scenarios/test_assembly.py",  # about 90 s of CPU cold
    "tests/fitting/test_nuts.py",
    "tests/test_cli_jobs.py",  # default: about 90 s of CPU cold
    "tests/fitting/test_lifecycle_mcmc.py",
    "tests/fitting/test_mixture_mcmc.py",
    "tests/fitting/test_speed_variation.py",  # about 70 s of CPU in 12 tests
    "tests/test_notebooks.py",  # a kernel per notebook, about 70 s of CPU
    "tests/fitting/test_importance_resample.py",  # slow: NUTS and ranked fits of the shipped log
    "tests/behaviour/test_fit_without_map.py",  # slow: a no-map tracks fit by the CLI (66 s)
    "tests/fuzz/test_fuzz_cli.py",
    "tests/fitting/test_prediction.py",
    "tests/fuzz/test_fuzz_bags.py",
    "tests/fitting/test_bursts_fit.py",
    "tests/test_docs.py",
    "tests/fitting/test_em.py",
    "tests/fitting/test_class_traffic.py",
)


def pytest_configure(config: pytest.Config) -> None:
    # keep the order of pytest_collection_modifyitems below for --dist loadfile
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Files in :data:`HEAVY_FILES` first, in that order; then the rest, most tests first.

    The order within a file is kept, so module fixtures are still built once per file.
    """
    files: dict[str, list[pytest.Item]] = {}
    for item in items:
        files.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    rank = {name: i for i, name in enumerate(HEAVY_FILES)}
    order = sorted(files, key=lambda f: (rank.get(f, len(rank)), -len(files[f])))
    items[:] = [item for f in order for item in files[f]]


def pytest_collection_finish(session: pytest.Session) -> None:
    """What collection built (the imported libraries, the test functions) lives to the end
    of the session: freeze it (:func:`gc.freeze`) so that full collections stop walking
    it; what the tests build afterwards is collected as before."""
    gc.collect()
    gc.freeze()


@pytest.fixture(autouse=True)
def _reseed() -> None:
    """Tests that use NumPy's global RNG get the same stream every run."""
    np.random.seed(20261122)  # noqa: NPY002 (reseed the legacy global stream)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
