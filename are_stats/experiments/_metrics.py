"""The paper's navigation metrics: the replanning ratio rho (eq. 3) and the space
complexity nu (eq. 4), with the definitions of DECISIONS 10.

* ``rho = rho_t / (rho_t + g_t)``: ``rho_t`` is the wall-clock time the planner spent on a
  replan (measured), ``g_t`` the estimated time to reach the goal at that replan: the length
  of the new path over the robot speed. ``rho`` near 0: planning is cheap compared with
  driving; near 1: the robot spends its time planning.
* ``nu = n_A / n_free``: ``n_A`` the cells of M_2D covered by live artefacts, ``n_free`` the
  free cells of the real map M_2D.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite, check_nonnegative, check_positive, describe

__all__ = ["path_length", "replanning_ratio", "space_complexity", "time_average"]


def replanning_ratio(rho_t: npt.ArrayLike, g_t: npt.ArrayLike) -> np.ndarray:
    """The replanning ratio of eq. (3), ``rho = rho_t / (rho_t + g_t)``.

    Parameters
    ----------
    rho_t : (n,) float
        Replanning times (s, >= 0).
    g_t : (n,) float
        Estimated times to the goal at each replan (s, >= 0): remaining path length over
        speed (DECISIONS 10); ``inf`` (no path) gives ``rho = 0``.

    Returns
    -------
    (n,) float
        ``rho`` in ``[0, 1]``; NaN where ``rho_t + g_t == 0``.

    Raises
    ------
    ValueError
        If a time is negative or NaN, or the shapes differ.

    Examples
    --------
    >>> replanning_ratio([0.5, 0.1], [1.5, 9.9]).tolist()
    [0.25, 0.01]
    """
    r = np.atleast_1d(check_nonnegative("rho_t", rho_t))
    g = np.atleast_1d(np.asarray(g_t, dtype=float))
    if np.isnan(g).any() or (g < 0).any():
        raise ValueError(f"g_t: expected times >= 0 (inf allowed), got {describe(g)}")
    if np.isinf(r).any():
        raise ValueError(f"rho_t: expected finite times, got {describe(r)}")
    if r.shape != g.shape:
        raise ValueError(f"rho_t, g_t: expected equal shapes, got {r.shape} and {g.shape}")
    den = r + g
    out = np.full(r.shape, np.nan)
    ok = den > 0
    out[ok] = r[ok] / den[ok]  # finite / inf is 0
    return out


def space_complexity(n_artefact_cells: npt.ArrayLike, n_free: npt.ArrayLike) -> np.ndarray:
    """The space complexity of eq. (4), ``nu = n_A / n_free``.

    Parameters
    ----------
    n_artefact_cells : (n,) int
        ``n_A``: cells of M_2D covered by live artefacts (e.g.
        :attr:`are_stats.builder.ARBuilder.n_artefact_cells`).
    n_free : int or (n,) int
        Free cells of the real map M_2D (> 0).

    Returns
    -------
    (n,) float

    Examples
    --------
    >>> space_complexity([0, 25, 100], 1000).tolist()
    [0.0, 0.025, 0.1]
    """
    a = np.atleast_1d(check_nonnegative("n_artefact_cells", n_artefact_cells))
    f = check_positive("n_free", n_free)
    return a / f


def path_length(path: npt.ArrayLike) -> float:
    """Length (m) of a polyline ``path : (k, 2)`` (0 for fewer than two points)."""
    p = check_finite("path", path, ndim=2)
    if p.shape[1] != 2:
        raise ValueError(f"path: expected shape (k, 2), got {p.shape}")
    if p.shape[0] < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def time_average(times: npt.ArrayLike, values: npt.ArrayLike, t_end: float) -> float:
    """Time average over ``[times[0], t_end]`` of a piecewise-constant signal.

    ``values[k]`` holds on ``[times[k], times[k + 1])`` (the last one up to ``t_end``).

    Examples
    --------
    >>> time_average([0.0, 1.0], [0.0, 1.0], 4.0)
    0.75
    """
    t = check_finite("times", times, ndim=1)
    v = check_finite("values", values, ndim=1)
    if t.shape != v.shape or t.size == 0:
        raise ValueError(
            f"times, values: expected equal non-empty shapes, got {t.shape} and {v.shape}"
        )
    if (np.diff(t) < 0).any() or float(t_end) < t[-1]:
        raise ValueError("times: expected non-decreasing times ending at or before t_end")
    dt = np.diff(np.r_[t, float(t_end)])
    span = float(t_end) - t[0]
    if span <= 0:
        return float(v[-1])
    return float((v * dt).sum() / span)
