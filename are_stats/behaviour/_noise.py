"""The position noise of a tracker, read from its tracks (issue 26).

One estimate for every consumer: the fitted speeds and the motion checks
(:mod:`are_stats.fitting`), the interaction's fit (:func:`~are_stats.behaviour.fit_social_force`)
and the realism table (:mod:`are_stats.scenarios`), which sees the models as the log's
tracker saw the log.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["NOISE_ORDER", "tracker_noise"]

#: Order of the differences the noise is read from (see :func:`tracker_noise`).
NOISE_ORDER = 4


def tracker_noise(tracks: pd.DataFrame) -> float:
    """Standard deviation (m) of a tracker's white position noise, per coordinate.

    Of ``K + 1`` consecutive samples of a track equally spaced in time (``K`` =
    :data:`NOISE_ORDER`), the ``K``-th difference of white noise of sd ``s`` is Gaussian
    with sd ``s sqrt(C(2K, K))`` (``sqrt(70)`` for ``K = 4``), while a walk's own
    contribution is its ``K``-th derivative times ``dt^K``: nothing on straight stretches,
    little elsewhere. The estimate is the robust scale of all of them (1.4826 times their
    median absolute value, over x and y) over ``sqrt(C(2K, K))``, so turns, stops and
    pushes, which are few, do not count.

    Why fourth differences: second differences (``K = 2``) read a walk's turns as noise
    where the step is long, and the autocovariances of second differences (the noise's
    ``-4 s^2`` at lag 1 and ``s^2`` at lag 2, the path's taken as equal at both) read them
    as too little noise: 1 cm of noise on a 2 m/s walker winding at up to 0.3 rad/s, seen at
    2.5 Hz, comes out as 2.4 cm and 0.79 cm, and as 0.99 cm from fourth differences; at
    10 Hz all three give 1.0 cm (``tests/behaviour/test_noise.py``).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (and ``scenario``: ids are per scenario), rows in any order.

    Returns
    -------
    float
        0 where no track has ``K + 1`` equally spaced samples in a row.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> t = np.arange(400) * 0.1
    >>> rng = np.random.default_rng(0)
    >>> walk = pd.DataFrame({"id": 0, "t": t, "x": 1.3 * t + rng.normal(0, 0.02, t.size),
    ...                      "y": rng.normal(0, 0.02, t.size)})
    >>> round(tracker_noise(walk), 2)
    0.02
    """
    order = NOISE_ORDER
    by = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    tab = tracks.sort_values([*by, "t"], kind="stable")
    if len(tab) <= order:
        return 0.0
    keys = tab[by].to_numpy()
    same = np.r_[False, (keys[1:] == keys[:-1]).all(axis=1)]  # row continues its track
    t = tab["t"].to_numpy(float)
    xy = tab[["x", "y"]].to_numpy(float)
    step = np.r_[0.0, np.diff(t)]
    n = len(tab) - order
    # rows k .. k + K all in one track, every step equal to the first
    ok = np.ones(n, bool)
    for j in range(1, order + 1):
        ok &= same[j : j + n] & (step[j : j + n] > 0)
        ok &= np.abs(step[j : j + n] - step[1 : 1 + n]) <= 1e-6 * np.maximum(step[1 : 1 + n], 1.0)
    diff = np.diff(xy, n=order, axis=0)[ok]
    if not diff.size:
        return 0.0
    return float(1.4826 * np.median(np.abs(diff)) / math.sqrt(math.comb(2 * order, order)))
