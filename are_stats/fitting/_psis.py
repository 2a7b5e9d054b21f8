"""Pareto-smoothed importance sampling (PSIS) for many observations at once.

The same estimator as :func:`arviz.psislw` (Vehtari et al. 2024, JMLR 25(72)), with the
same constants: a right tail of ``M = ceil(min(S / 5, 3 sqrt(S / r_eff)))`` draws, the
generalized Pareto fit of Zhang and Stephens (2009) with its ``30 + sqrt(M)`` grid and
the weak prior on ``k`` (``prior_k = 10``), the tail replaced by the fitted quantiles at
``(i - 1/2) / M`` and truncated at the largest raw weight, and the weights normalised.

ArviZ runs the estimator observation by observation, sorting every row of ``S`` draws.
Here the rows are processed together: the tail is found by a partial sort
(:func:`numpy.argpartition`, linear in ``S``), and the Pareto fits of all rows are one
array computation. Rows where the tail is not ``M`` distinct values above the cutoff
(ties at the cutoff, a cutoff below the smallest normal float, fewer than 5 tail draws)
are done one at a time, exactly as ArviZ does. Tested against :func:`arviz.psislw`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["psislw"]

_PRIOR_BS = 3.0
_PRIOR_K = 10.0
_CUTOFF_MIN = float(np.log(np.finfo(float).tiny))
_EPS = float(np.finfo(float).eps)
_ROWS = 256  # rows per block: bounds the (rows, grid, M) work array to ~20 MB


def psislw(log_weights: np.ndarray, reff: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Pareto-smoothed, normalised log importance weights and Pareto ``k`` of each row.

    Parameters
    ----------
    log_weights : (n, S) or (S,) float array
        Raw log weights of ``S`` draws for each of ``n`` observations (for PSIS-LOO: minus
        the pointwise log-likelihood).
    reff : float
        Relative MCMC efficiency ``ess / S`` (sets the tail length).

    Returns
    -------
    log_w : (n, S) or (S,) float64
        Smoothed, truncated, normalised log weights (``logsumexp`` of each row is 0).
    k : (n,) float64 or float
        The fitted Pareto shape of each row's tail (inf where the tail has 4 draws or
        fewer).

    Raises
    ------
    ValueError
        If ``log_weights`` is not 1-D or 2-D, or ``reff`` is not positive.
    """
    x = np.array(log_weights, dtype=np.float64)  # a copy: filled in place
    one = x.ndim == 1
    if one:
        x = x[None]
    if x.ndim != 2:
        raise ValueError(f"log_weights: expected a 1-D or 2-D array, got shape {x.shape}")
    if not reff > 0:
        raise ValueError(f"reff: expected a positive number, got {reff}")
    n, s = x.shape
    m = int(np.ceil(min(s / 5.0, 3.0 * (s / reff) ** 0.5)))
    k = np.full(n, np.inf)
    # overflow in the grid's weights is an underflow to 0 of that candidate, as in ArviZ
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        for lo in range(0, n if s else 0, _ROWS):
            rows = slice(lo, min(lo + _ROWS, n))
            k[rows] = _smooth_block(x[rows], m)
    if one:
        return x[0], float(k[0])
    return x, k


def _smooth_block(x: np.ndarray, m: int) -> np.ndarray:
    """Smooth the rows of ``x`` (r, S) in place; return their ``k``."""
    r, s = x.shape
    x -= np.max(x, axis=1, keepdims=True)
    k = np.full(r, np.inf)
    if m + 1 > s:  # one draw: nothing to smooth (ArviZ raises an IndexError)
        x -= _logsumexp_rows(x)[:, None]
        return k
    idx = np.argpartition(x, s - m - 1, axis=1)
    cutoff = np.take_along_axis(x, idx[:, s - m - 1 : s - m], axis=1)[:, 0]
    # in draw order, as ArviZ finds them (ties in the tail then sort alike)
    tail_idx = np.sort(idx[:, s - m :], axis=1)
    tail = np.take_along_axis(x, tail_idx, axis=1)
    # the fast path needs exactly the M partitioned draws strictly above the cutoff
    regular = (cutoff >= _CUTOFF_MIN) & np.all(tail > cutoff[:, None], axis=1) & (m > 4)
    for i in np.flatnonzero(~regular):
        x[i], k[i] = _psis_row(x[i], m)
    if regular.any():
        rows = np.flatnonzero(regular)
        order = np.argsort(tail[rows], axis=1)
        sub = x[rows]
        k[rows] = _replace_tails(
            sub,
            np.take_along_axis(tail_idx[rows], order, axis=1),
            np.take_along_axis(tail[rows], order, axis=1),
            np.exp(cutoff[rows]),
        )
        x[rows] = sub
    x -= _logsumexp_rows(x)[:, None]
    return k


def _replace_tails(
    x: np.ndarray, idx_sorted: np.ndarray, t_sorted: np.ndarray, exp_cut: np.ndarray
) -> np.ndarray:
    """Fit the Pareto law to each row's tail and put its quantiles in place; return ``k``.

    ``x`` (r, S) rows, changed in place; ``idx_sorted``, ``t_sorted`` (r, M): each row's
    tail draws and their values, ascending; ``exp_cut`` (r,): ``exp`` of the cutoffs. Rows
    whose fit fails (``k`` not finite) are left as they are.
    """
    m = t_sorted.shape[1]
    k, sigma = _gpdfit(np.exp(t_sorted) - exp_cut[:, None])
    fit = np.isfinite(k)
    if fit.any():
        probs = np.arange(0.5, m) / m
        smooth = np.log(_gpinv(probs, k[fit], sigma[fit]) + exp_cut[fit, None])
        sub = x[fit]
        np.put_along_axis(sub, idx_sorted[fit], smooth, axis=1)
        sub[sub > 0] = 0.0  # truncated at the largest raw weight
        x[fit] = sub
    return k


def _gpdfit(ary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zhang-Stephens empirical-Bayes fit of the generalized Pareto law to sorted rows.

    ``ary`` (r, M): exceedances over the cutoff, each row sorted ascending. Returns the
    shape ``k`` (with the weak prior toward 0.5) and the scale ``sigma`` of each row.
    """
    r, n = ary.shape
    m_est = 30 + int(n**0.5)
    b = 1.0 - np.sqrt(m_est / (np.arange(1, m_est + 1, dtype=float) - 0.5))
    b = b[None, :] / (_PRIOR_BS * ary[:, int(n / 4 + 0.5) - 1])[:, None]
    b += (1.0 / ary[:, -1])[:, None]
    k_ary = np.log1p(-b[:, :, None] * ary[:, None, :]).mean(axis=2)  # (r, m_est)
    len_scale = n * (np.log(-(b / k_ary)) - k_ary - 1.0)
    weights = 1.0 / np.exp(len_scale[:, None, :] - len_scale[:, :, None]).sum(axis=2)
    weights = np.where(weights >= 10.0 * _EPS, weights, 0.0)  # negligible weights out
    weights /= weights.sum(axis=1, keepdims=True)
    b_post = np.sum(b * weights, axis=1)
    k_post = np.log1p(-b_post[:, None] * ary).mean(axis=1)
    sigma = -k_post / b_post
    k_post = (n * k_post + _PRIOR_K * 0.5) / (n + _PRIOR_K)
    return k_post, sigma


def _gpinv(probs: np.ndarray, kappa: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Generalized Pareto quantiles at ``probs`` (M,) in (0, 1) for each row's law."""
    kap = kappa[:, None]
    near0 = np.abs(kap) < _EPS
    with np.errstate(divide="ignore", invalid="ignore"):
        tail = np.log1p(-probs)[None, :]
        q = np.where(near0, -tail, np.expm1(-kap * tail) / np.where(near0, 1.0, kap))
    q = q * sigma[:, None]
    return np.where(sigma[:, None] > 0, q, np.nan)


def _logsumexp_rows(x: np.ndarray) -> np.ndarray:
    top = np.max(x, axis=1)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.sum(np.exp(x - top[:, None]), axis=1)) + top


def _psis_row(x: np.ndarray, m: int) -> tuple[np.ndarray, float]:
    """One row, step for step as ArviZ's ``_psislw`` (``x`` already shifted to max 0)."""
    x = x.copy()
    xcutoff = max(np.sort(x)[-m - 1], _CUTOFF_MIN)
    exp_cut = np.exp(xcutoff)
    (tail_idx,) = np.where(x > xcutoff)
    tail = x[tail_idx]
    k = np.inf
    rows = x[None]
    if tail.size > 4:
        order = np.argsort(tail)
        k = float(
            _replace_tails(rows, tail_idx[order][None], tail[order][None], np.array([exp_cut]))[0]
        )
    rows -= _logsumexp_rows(rows)[:, None]
    return rows[0], k
