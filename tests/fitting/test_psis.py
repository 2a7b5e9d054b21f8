"""The vectorised PSIS (``psislw``) against ArviZ's row-by-row ``arviz.psislw``.

The same estimator, so the same numbers to rounding: smoothed weights within 1e-12 and
Pareto ``k`` within 1e-12, on light and heavy tails, ties (the rows done one at a time),
constant rows (no tail: ``k = inf``), short rows and both tail lengths (``reff``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.special import logsumexp

from are_stats.fitting import psislw

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az


def _cases() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    s = 2000
    mixed = rng.normal(size=(40, s))
    mixed[5] = 0.0  # constant: no tail
    mixed[6] = np.round(mixed[6], 1)  # ties at the cutoff: done row by row
    mixed[7, :3] = 50.0  # three huge weights: a tail of 3 above a flat body
    return {
        "light": rng.normal(size=(300, s)),
        "heavy": 3.0 * rng.standard_t(1.5, size=(300, s)),  # many k > 0.7
        "ties": np.round(rng.normal(size=(50, s)), 1),
        "mixed": mixed,
        "short": rng.normal(size=(7, 23)),
        "far": 800.0 * rng.normal(size=(3, s)),  # cutoff below the smallest normal float
    }


@pytest.mark.parametrize("reff", [1.0, 0.3])
@pytest.mark.parametrize("name", list(_cases()))
def test_matches_arviz(name, reff):
    lw = _cases()[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want_w, want_k = az.psislw(lw, reff)
    got_w, got_k = psislw(lw, reff)
    np.testing.assert_allclose(got_w, np.asarray(want_w), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got_k, np.asarray(want_k), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(logsumexp(got_w, axis=1), 0.0, atol=1e-12)
    assert got_w is not lw and np.shares_memory(got_w, lw) is False


def test_heavy_tails_give_large_k_and_one_row_works():
    rng = np.random.default_rng(1)
    _, k = psislw(3.0 * rng.standard_t(1.0, size=(20, 4000)))
    assert np.median(k) > 0.7  # Cauchy-like weights: the diagnostic fires
    row = rng.normal(size=500)
    w, k1 = psislw(row, 0.5)
    want_w, want_k = az.psislw(row, 0.5)
    assert isinstance(k1, float) and k1 == pytest.approx(float(want_k), abs=1e-12)
    np.testing.assert_allclose(w, np.asarray(want_w), atol=1e-12)
    w1, k_one = psislw(np.zeros((2, 1)))
    assert np.all(w1 == 0.0) and np.all(np.isinf(k_one))


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="log_weights: expected a 1-D or 2-D array"):
        psislw(np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="reff: expected a positive number"):
        psislw(np.zeros((2, 10)), 0.0)
