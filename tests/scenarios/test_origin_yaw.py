"""The one origin-yaw check of the scenarios room (issue 25): a map counts as unturned up to
ORIGIN_YAW_TOLERANCE (1e-12 rad), and learned positions need an unturned map."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.environment import OccupancyGrid
from are_stats.scenarios import ORIGIN_YAW_TOLERANCE, check_origin_yaw, generate_scenarios
from are_stats.traffic import PositionDensity, TrafficLaws


def test_the_tolerance_is_inclusive_and_names_what_needs_it():
    assert ORIGIN_YAW_TOLERANCE == 1e-12
    check_origin_yaw(1e-12, "learned positions")
    check_origin_yaw(-1e-12, "learned positions")
    for yaw in (1.5e-12, -1e-10, 1e-9, np.pi / 2):
        with pytest.raises(ValueError, match=r"^map: expected an origin yaw of 0 for things, got"):
            check_origin_yaw(yaw, "things")


@pytest.mark.parametrize(("yaw", "refused"), [(0.0, False), (1e-13, False), (1e-10, True)])
def test_learned_positions_on_a_turned_map(yaw, refused):
    """A learned entry density on the 10 x 10 m free map: refused once the yaw passes the
    tolerance (1e-10 rad passed the CLI's old 1e-9 pre-check and was refused here anyway)."""
    grid = OccupancyGrid(np.zeros((10, 10)), 1.0, origin=(0.0, 0.0, yaw))
    entry = PositionDensity(np.full((10, 10), 0.01), 1.0, (0.0, 0.0), 1.0, float("nan"))
    laws = TrafficLaws(positions="learned", entry=entry)
    params = {"arrival_rate": np.array([0.001]), "leave_rate": np.array([0.01])}
    if refused:
        with pytest.raises(ValueError, match="origin yaw of 0 for learned positions"):
            generate_scenarios(0, params, 2, 600.0, free_mask=grid, laws=laws)
    else:
        df = generate_scenarios(0, params, 2, 600.0, free_mask=grid, laws=laws)
        assert len(df) and df["x"].between(0, 10).all() and df["y"].between(0, 10).all()
