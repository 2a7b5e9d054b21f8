"""Test configuration: CPU only, two host devices for parallel chains, every test reseeded."""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import are_stats  # noqa: E402,F401  (enables x64 before any test touches JAX)


@pytest.fixture(autouse=True)
def _reseed() -> None:
    """Tests that use NumPy's global RNG get the same stream every run."""
    np.random.seed(20261122)  # noqa: NPY002 (reseed the legacy global stream)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
