"""positions_at: many timed paths evaluated at once, bit for bit as np.interp per path."""

import numpy as np
import pytest

from are_stats.behaviour import positions_at


def _paths(rng: np.random.Generator, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Timed paths of 1-8 vertices: repeated times (a pause of no duration), values from
    tiny to huge and infinite, as the timing of string-pulled routes may give."""
    out = []
    for _ in range(n):
        m = int(rng.integers(1, 9))
        tv = np.sort(np.round(rng.uniform(0.0, 5.0, m), int(rng.integers(0, 3))))
        scale = rng.choice([1.0, 1e-300, 1e300, np.inf], (m, 2), p=[0.7, 0.1, 0.1, 0.1])
        out.append((tv, rng.normal(size=(m, 2)) * scale))
    return out


@pytest.mark.parametrize("seed", range(5))
def test_positions_are_np_interp_of_each_path_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    paths = _paths(rng, 60)
    # times before, between, on and after the vertices (rounded: exact hits), and a NaN
    t = np.r_[np.round(rng.uniform(-1.0, 6.0, 40), 1), np.nan]
    got = positions_at(paths, t)
    want = np.stack(
        [np.stack([np.interp(t, tv, pv[:, k]) for k in range(2)], axis=1) for tv, pv in paths]
    )
    assert got.shape == (60, t.size, 2)
    assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_no_paths_give_an_empty_table() -> None:
    assert positions_at([], [0.0, 1.0]).shape == (0, 2, 2)
