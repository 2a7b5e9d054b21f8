"""Smoke test of the traffic NUTS benchmark: its PyMC peer is the same model as ours.

Runs the benchmark's correctness check (log joint densities of the groups arrival model and
the gamma stay model equal in numpyro and PyMC at several points) on a short-window log
that has every window case, without timing anything. Skipped without PyMC (the bench
extra).
"""

from __future__ import annotations

import pytest


@pytest.mark.slow  # PyMC peer
def test_pymc_peer_has_our_log_density():
    pytest.importorskip("pymc")
    from tests.benchmarks import bench_traffic_nuts as bench

    # FAST_COMPILE: PyTensor's Python implementations, no C compiler run
    n = bench.check_log_densities([bench.edge_log()], mode="FAST_COMPILE")
    assert n == 8
