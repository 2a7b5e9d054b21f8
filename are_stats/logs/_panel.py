"""Count panels: the number of artefacts present, N(t), at observation times.

A panel ``(t_k, n_k)`` is the data of the birth-death fit of N(t) (Sect. 3.2, DECISIONS
1-2): with linear death the exact transition law between consecutive counts is
Binomial x Poisson, so counts at irregular times are fine.
"""

from __future__ import annotations

import os

import numpy as np

from are_stats.logs._table import read_raw_table

__all__ = ["read_count_panel"]


def read_count_panel(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a count panel (CSV or Parquet) with columns ``t`` and ``count``.

    Parameters
    ----------
    path : str or PathLike
        One row per observation time; other columns are ignored.

    Returns
    -------
    times : (n,) float64
        Observation times (seconds), strictly increasing.
    counts : (n,) int64
        Artefacts present at each time.

    Raises
    ------
    FileNotFoundError
        If the file is missing.
    ValueError
        Naming file, row and column: missing columns, empty file, non-numeric / NaN /
        empty cells, negative or non-integer counts, times not strictly increasing.
    """
    raw = read_raw_table(path, "count panel")
    raw.require(["t", "count"], "count panel")
    t, _ = raw.floats("t", allow_empty=False)
    n, _ = raw.nonneg_ints("count", allow_empty=False)
    d = np.diff(t)
    bad = d <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise raw.error(
            i,
            "t",
            f"a time greater than the previous row's {float(t[i - 1])!r} "
            "(strictly increasing times)",
            repr(float(t[i])),
        )
    return t, n
