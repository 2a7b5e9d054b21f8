"""Fixtures shared by the scenarios tests: the shipped courtyard map and catalogue."""

from __future__ import annotations

import pytest

from are_stats.environment import ArtefactCatalogue, OccupancyGrid, load_catalogue, shipped_path


@pytest.fixture(scope="module")
def grid() -> OccupancyGrid:
    """The shipped courtyard's occupancy grid."""
    return OccupancyGrid.from_ros_yaml(shipped_path("courtyard", "map"))


@pytest.fixture(scope="module")
def catalogue() -> ArtefactCatalogue:
    """The shipped artefact catalogue."""
    return load_catalogue()
