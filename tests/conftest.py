"""Test configuration: CPU only, two host devices for parallel chains, every test reseeded."""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import are_stats  # noqa: E402,F401  (enables x64 before any test touches JAX)

# Property tests explore new examples on every local run (failures are kept in
# .hypothesis/); CI (.ci/run sets HYPOTHESIS_PROFILE=ci) runs the same derandomised examples
# every time, so a landing is not decided by which examples a run happened to draw.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

#: The test files that take longest (from per-test CPU and wall times of 2026-11-27 and the
#: full runs before), roughly longest first. ``make test`` hands whole files to
#: two workers (``--dist loadfile``); a long file handed out last runs alone at the end, so
#: these go first and the many short files fill in behind them (longest processing time
#: first). xdist's own order (most tests first) would put them last: it is switched off in
#: :func:`pytest_configure`. A file missing here only runs later; nothing is skipped.
HEAVY_FILES: tuple[str, ...] = (
    "tests/test_integrity.py",  # same-seed runs and kills: about 20 are-stats processes
    "tests/fuzz/test_fuzz_tracks_scale.py",  # 300-person tracks fits
    "tests/fitting/test_fit.py",  # three tracks fits (behaviour, realism)
    # about 230 s of CPU (walks and motion checks by generation and criticism), with 15
    # tests: by test count it started among the last files
    "tests/fitting/test_heading_variation.py",
    "tests/test_wheel.py",  # builds the wheel; with ARE_STATS_FRESH_VENV=1 a fresh venv
    "tests/test_notebooks.py",  # a kernel per notebook
    "tests/test_cli_tracks.py",
    "tests/fuzz/test_fuzz_cli.py",
    "tests/test_cli_jobs.py",
    "tests/test_docs.py",
    "tests/fitting/test_behaviour_fit.py",
    "tests/fitting/test_speed_variation.py",  # about 70 s of CPU in 12 tests
    "tests/fitting/test_bursts_fit.py",
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


@pytest.fixture(autouse=True)
def _reseed() -> None:
    """Tests that use NumPy's global RNG get the same stream every run."""
    np.random.seed(20261122)  # noqa: NPY002 (reseed the legacy global stream)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
