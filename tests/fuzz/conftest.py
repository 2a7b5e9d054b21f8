"""Fuzz fixtures: a tiny valid fit and scenario folder (made once), fresh case folders.

Each fuzz test runs as two tests (:func:`tests.fuzz.strategies.fuzz_tiers`): ``test_x[default]``
in ``make test`` (``-m "not slow"``) draws about a quarter of its examples, ``test_x[slow]`` in
``make test-slow`` (``-m slow``) all of them, other cases from a second seed; CI runs
both tiers, at least as many distinct cases per test as one stream of all its examples did.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.fuzz.strategies import LOG_HEADER, LOG_ROWS, MANIFEST, _csv_text, _dump


def pytest_configure(config: pytest.Config) -> None:
    # also to be registered in pyproject.toml; registering here keeps --strict-markers happy
    config.addinivalue_line(
        "markers", "fuzz: fuzz harness (ARE_STATS_FUZZ_EXAMPLES=10 multiplies the examples)"
    )


#: Limits the fuzz run sets for the package: a case may ask for at most this much before the
#: package must refuse it; :func:`tests.fuzz.strategies.bounded` allows a few GiB more, so a
#: missing check shows up as ``MemoryError`` / a timeout, not as a machine out of memory.
FUZZ_MEMORY_LIMIT = "512M"
FUZZ_WORK_LIMIT = "2e9"


@pytest.fixture(autouse=True)
def _fuzz_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ARE_STATS_MAX_MEMORY", FUZZ_MEMORY_LIMIT)
    monkeypatch.setenv("ARE_STATS_MAX_WORK", FUZZ_WORK_LIMIT)


@pytest.fixture(scope="session", autouse=True)
def _warm() -> None:
    """Load the heavy libraries before any bounded case.

    JAX, XLA and Warp reserve gigabytes of address space when they start; loaded inside a
    case that reservation would count against the case's ``RLIMIT_AS`` headroom (and XLA
    aborts the process when a reservation fails).
    """
    import arviz  # noqa: F401
    import jax.numpy as jnp
    import matplotlib.pyplot  # noqa: F401
    import pyarrow.parquet  # noqa: F401
    import warp

    import are_stats.cli  # noqa: F401
    import are_stats.perception._perceive  # noqa: F401

    jnp.zeros(3).block_until_ready()
    warp.init()


@pytest.fixture(scope="session")
def fuzz_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="session")
def case_dir(fuzz_root: Path) -> Callable[[], Path]:
    """A new empty folder per call (hypothesis examples cannot use function fixtures)."""
    counter = itertools.count()

    def make() -> Path:
        d = fuzz_root / "cases" / f"c{next(counter):06d}"
        d.mkdir(parents=True)
        return d

    return make


@pytest.fixture(scope="session")
def tiny_log(fuzz_root: Path) -> Path:
    """A valid 40-artefact life-cycle log with its manifest beside it."""
    d = fuzz_root / "log"
    d.mkdir()
    (d / "tiny.yaml").write_text(_dump(MANIFEST))
    path = d / "tiny.csv"
    path.write_text(_csv_text(LOG_HEADER, LOG_ROWS))
    return path


@pytest.fixture(scope="session")
def tiny_fit(tiny_log: Path, fuzz_root: Path) -> Path:
    """An EM fit of the tiny log (``are-stats fit --method em --no-figures``)."""
    from are_stats._cli_jobs import run_fit

    out = fuzz_root / "fit" / "tiny.nc"
    out.parent.mkdir()
    run_fit(tiny_log, out, method="em", seed=3, figures=None, arrivals="poisson",
            lifetimes="exponential", positions="uniform")  # fmt: skip
    return out


@pytest.fixture(scope="session")
def tiny_scenarios(tiny_fit: Path, fuzz_root: Path) -> Path:
    """Three scenarios of 300 s on the shipped courtyard map."""
    from are_stats._cli_jobs import EXAMPLE_MAP, run_generate

    out = fuzz_root / "scenarios"
    run_generate(tiny_fit, 3, 300.0, 5, out, EXAMPLE_MAP)
    return out
