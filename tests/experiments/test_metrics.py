"""rho (eq. 3) and nu (eq. 4) against hand computations."""

from __future__ import annotations

import numpy as np
import pytest

from are_stats.experiments import path_length, replanning_ratio, space_complexity, time_average
from tests.helpers import assert_allclose


def test_rho_by_hand():
    assert_allclose(replanning_ratio([0.5, 0.1, 2.0], [1.5, 9.9, 2.0]), [0.25, 0.01, 0.5])


def test_rho_edge_cases():
    out = replanning_ratio([0.0, 0.3, 0.0], [0.0, np.inf, 4.0])
    assert np.isnan(out[0]) and out[1] == 0.0 and out[2] == 0.0


@pytest.mark.parametrize(
    ("rho_t", "g_t", "match"),
    [
        ([-1.0], [1.0], "rho_t"),
        ([1.0], [-1.0], "g_t"),
        ([1.0], [np.nan], "g_t"),
        ([1.0, 2.0], [1.0], "shapes"),
        ([np.inf], [1.0], "rho_t"),
    ],
)
def test_rho_bad_input(rho_t, g_t, match):
    with pytest.raises(ValueError, match=match):
        replanning_ratio(rho_t, g_t)


def test_nu_by_hand():
    assert_allclose(space_complexity([0, 4, 40], 400), [0.0, 0.01, 0.1])
    with pytest.raises(ValueError, match="n_free"):
        space_complexity([1], 0)
    with pytest.raises(ValueError, match="n_artefact_cells"):
        space_complexity([-1], 10)


def test_path_length_and_time_average():
    assert path_length([[0.0, 0.0], [3.0, 4.0], [3.0, 5.0]]) == 6.0
    assert path_length([[1.0, 1.0]]) == 0.0
    # nu = 0 on [0, 2), 0.01 on [2, 4), 0 on [4, 16]
    assert_allclose(time_average([0.0, 2.0, 4.0], [0.0, 0.01, 0.0], 16.0), 0.02 / 16)
    with pytest.raises(ValueError, match="path"):
        path_length([[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="times"):
        time_average([1.0, 0.0], [0.0, 0.0], 2.0)
