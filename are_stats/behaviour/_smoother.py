"""A fixed-interval smoother of tracks: positions, velocities and accelerations (issue 26).

Each coordinate of a track is a constant-acceleration path driven by white jerk of
spectral density ``q`` (m^2/s^5), seen with white position noise of sd ``s``: the state
``(p, v, a)`` follows ``x_{k+1} = F x_k + w_k`` with

.. math::

    F = \\begin{pmatrix} 1 & h & h^2/2 \\\\ 0 & 1 & h \\\\ 0 & 0 & 1 \\end{pmatrix},\\quad
    \\mathrm{Cov}(w) = q \\begin{pmatrix} h^5/20 & h^4/8 & h^3/6 \\\\ h^4/8 & h^3/3 & h^2/2
    \\\\ h^3/6 & h^2/2 & h \\end{pmatrix}

and the Kalman filter and Rauch-Tung-Striebel smoother give each sample's posterior mean
(Bar-Shalom, Li and Kirubarajan 2001, Sect. 6.3). The filter's covariances and gains do
not depend on the observations, only on the step index, so every track of a table (one
step ``h`` for everybody) shares them: the tracks, aligned at their first sample, are
smoothed together, one NumPy step per sample index. The smoother is linear in the
observations, so any number of sequences (``channels``) go through it at once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["smooth_samples", "smooth_tracks"]

#: Prior sd of the first sample's position (m), velocity (m/s) and acceleration (m/s^2):
#: diffuse against a walk's.
PRIOR_SD = (1e3, 1e3, 1e3)


def smooth_tracks(
    values: np.ndarray, length: np.ndarray, step: float, noise: float, jerk: float
) -> np.ndarray:
    """Posterior means of position, velocity and acceleration of padded sequences.

    Parameters
    ----------
    values : (T, n, c) float
        Observed positions: ``n`` tracks of ``c`` channels each, aligned at their first
        sample (index 0); entries at and past a track's ``length`` are ignored.
    length : (n,) int
        Samples in each track (at least 1).
    step : float
        Sampling step ``h`` (s).
    noise : float
        Sd ``s`` (m) of the white observation noise (a floor of 1e-4 m keeps the filter
        regular on exact tracks).
    jerk : float
        Spectral density ``q`` (m^2/s^5) of the white jerk.

    Returns
    -------
    (3, T, n, c) float
        Smoothed position, velocity and acceleration (0 past each track's end).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(50) * 0.1
    >>> x = (1.0 + 1.2 * t + 0.3 * t**2)[:, None, None]
    >>> out = smooth_tracks(x, np.array([50]), 0.1, 0.0, 1.0)
    >>> np.round(out[1:, 25, 0, 0], 3)  # velocity and acceleration at t = 2.5 s
    array([2.7, 0.6])
    """
    values = np.asarray(values, float)
    big_t, n, c = values.shape
    length = np.asarray(length, int)
    h = float(step)
    f = np.array([[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
    q = float(jerk) * np.array(
        [
            [h**5 / 20, h**4 / 8, h**3 / 6],
            [h**4 / 8, h**3 / 3, h**2 / 2],
            [h**3 / 6, h**2 / 2, h],
        ]
    )
    r = max(float(noise), 1e-4) ** 2
    # covariances and gains: the same for every track and channel
    p_pred = np.zeros((big_t, 3, 3))
    p_filt = np.zeros((big_t, 3, 3))
    gain = np.zeros((big_t, 3))
    p = np.diag(np.square(PRIOR_SD))
    for k in range(big_t):
        if k:
            p = f @ p_filt[k - 1] @ f.T + q
        p_pred[k] = p
        gain[k] = p[:, 0] / (p[0, 0] + r)
        p_filt[k] = p - np.outer(gain[k], p[0, :])
    # filter: state means (T, 3, n, c)
    x_filt = np.zeros((big_t, 3, n, c))
    for k in range(big_t):
        x_pred = np.einsum("ij,jnc->inc", f, x_filt[k - 1]) if k else np.zeros((3, n, c))
        innov = values[k] - x_pred[0]
        x_filt[k] = x_pred + gain[k][:, None, None] * innov
    # smoother, backwards from each track's last sample
    out = np.zeros((big_t, 3, n, c))
    alive = np.arange(big_t)[:, None] < length[None, :]  # (T, n)
    last = np.arange(big_t)[:, None] == (length - 1)[None, :]
    out[big_t - 1] = x_filt[big_t - 1]
    for k in range(big_t - 2, -1, -1):
        g = p_filt[k] @ f.T @ np.linalg.inv(p_pred[k + 1])
        ahead = np.einsum("ij,jnc->inc", f, x_filt[k])
        smoothed = x_filt[k] + np.einsum("ij,jnc->inc", g, out[k + 1] - ahead)
        out[k] = np.where(last[k][None, :, None], x_filt[k], smoothed)
    out = np.where(alive[:, None, :, None], out, 0.0)
    return np.moveaxis(out, 1, 0)


def smooth_samples(
    values: np.ndarray,
    track: np.ndarray,
    index: np.ndarray,
    step: float,
    noise: float,
    jerk: float,
) -> np.ndarray:
    """:func:`smooth_tracks` of samples given row by row.

    Tracks are padded to a common length in batches of similar lengths (longest first,
    a batch closed when padding would double its samples), so a few long tracks among
    many short ones cost what their samples cost.

    Parameters
    ----------
    values : (n, c) float
        Observed positions, one row per sample.
    track : (n,) int
        Each row's track, ``0 .. n_tracks - 1``.
    index : (n,) int
        Each row's sample index within its track, ``0 .. length - 1`` (every index once).
    step, noise, jerk
        As in :func:`smooth_tracks`.

    Returns
    -------
    (3, n, c) float
        Smoothed position, velocity and acceleration of each row.
    """
    values = np.asarray(values, float)
    track = np.asarray(track, int)
    index = np.asarray(index, int)
    length = np.bincount(track)
    order = np.argsort(-length, kind="stable")
    out = np.zeros((3, *values.shape))
    rows_of = np.argsort(track, kind="stable")
    first_row = np.r_[0, np.cumsum(length)]
    k = 0
    while k < order.size:
        top, samples, stop = length[order[k]], 0, k
        while stop < order.size and (stop - k + 1) * top <= 2 * (samples + length[order[stop]]):
            samples += length[order[stop]]
            stop += 1
        batch = order[k:stop]
        rows = np.concatenate([rows_of[first_row[b] : first_row[b + 1]] for b in batch])
        slot = np.repeat(np.arange(batch.size), length[batch])
        pad = np.zeros((top, batch.size, values.shape[1]))
        pad[index[rows], slot] = values[rows]
        out[:, rows] = smooth_tracks(pad, length[batch], step, noise, jerk)[:, index[rows], slot]
        k = stop
    return out
