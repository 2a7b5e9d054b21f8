"""The motion tables a fit stores for ``report`` (issue 26): written and read back."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.fitting import MOTION_TABLES, motion_attrs, motion_tables


def test_motion_tables_round_trip_through_the_attributes():
    real = pd.DataFrame(
        {"kind": ["kinematic", "all"], "weight": [0.25, 1.0], "constant velocity": [0.1, 0.2],
         "fitted": [0.3, np.nan]}, index=["speed (m/s)", "realism (weighted)"],
    )  # fmt: skip
    methods = pd.Index(["constant velocity", "model mean of K"], name="method")
    errors = pd.DataFrame({"ADE": [0.7, 0.6], "FDE": [1.3, 1.1]}, index=methods)
    attrs = motion_attrs(realism=real, displacement=errors)
    assert set(attrs) == {MOTION_TABLES["realism"], MOTION_TABLES["displacement"]}
    back = motion_tables(attrs)
    assert set(back) == {"realism", "displacement"}
    pd.testing.assert_frame_equal(back["realism"], real, check_dtype=False, check_names=False)
    pd.testing.assert_frame_equal(back["displacement"], errors, check_dtype=False)
    assert motion_tables({}) == {}
    with pytest.raises(ValueError, match="expected names among"):
        motion_attrs(other=real)
