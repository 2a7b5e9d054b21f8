"""Model criticism for the life-cycle model: is the traffic really Poisson?

Summaries that a posterior-predictive check compares with replicated data:

* :func:`kaplan_meier` — the Kaplan-Meier survival curve of dwell times with right
  censoring (Greenwood variance, log-log confidence band);
* :func:`dispersion_index` — variance over mean of counts per bin, with the two-sided
  chi-square test of the Poisson hypothesis (index 1);
* :func:`count_path` — ``N(t)`` of a log (artefacts present at each time);
* :func:`hour_of_day_counts` — arrivals per period of the day.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from are_stats._checks import (
    check_finite,
    check_nonempty,
    check_nonneg_int,
    check_nonnegative,
    check_positive,
    check_probability,
)
from are_stats._lazy import scipy_stats as stats

__all__ = [
    "KaplanMeier",
    "kaplan_meier",
    "DispersionTest",
    "dispersion_index",
    "count_path",
    "hour_of_day_counts",
]


@dataclass(frozen=True)
class KaplanMeier:
    """Kaplan-Meier estimate at the distinct event times.

    Attributes
    ----------
    time : (m,) float
        Distinct times with at least one observed event.
    survival : (m,) float
        ``S(t)`` just after each time.
    lower, upper : (m,) float
        Pointwise confidence band (log-log transform, Greenwood variance).
    at_risk : (m,) int
        Number at risk just before each time.
    events : (m,) int
        Observed events at each time.
    """

    time: np.ndarray
    survival: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    at_risk: np.ndarray
    events: np.ndarray

    def __call__(self, t: npt.ArrayLike) -> np.ndarray:
        """Evaluate the right-continuous step function ``S(t)`` at ``t``."""
        idx = np.searchsorted(self.time, np.asarray(t, dtype=float), side="right")
        return np.concatenate([[1.0], self.survival])[idx]


def kaplan_meier(
    durations: npt.ArrayLike, censored: npt.ArrayLike, level: float = 0.95
) -> KaplanMeier:
    """Kaplan-Meier survival curve of right-censored durations.

    Parameters
    ----------
    durations : (n,) float
        Observed stays (to the leave, or to the censoring time).
    censored : (n,) bool
        True where the stay was right-censored.
    level : float
        Confidence level of the pointwise band.

    Returns
    -------
    KaplanMeier
        The estimate; the band uses the log-log transform with Greenwood's variance.
    """
    d = check_nonnegative("durations", check_nonempty("durations", durations), ndim=1)
    c = np.asarray(censored, dtype=bool)
    if c.shape != d.shape:
        raise ValueError(f"censored: expected shape {d.shape} like durations, got {c.shape}")
    level = float(check_probability("level", level, closed_right=False))
    times = np.unique(d[~c])
    # at risk just before t: stays >= t; events at t: uncensored stays == t
    sorted_d = np.sort(d)
    at_risk = d.size - np.searchsorted(sorted_d, times, side="left")
    ev_sorted = np.sort(d[~c])
    events = np.searchsorted(ev_sorted, times, side="right") - np.searchsorted(
        ev_sorted, times, side="left"
    )
    surv = np.cumprod(1.0 - events / at_risk)
    with np.errstate(divide="ignore", invalid="ignore"):
        green = np.cumsum(events / (at_risk * (at_risk - events)))
        z = stats.norm.ppf(0.5 + level / 2)
        log_s = np.log(surv)
        se = np.sqrt(green) / np.abs(log_s)
        ll = np.log(-log_s)
        lower = np.exp(-np.exp(ll + z * se))
        upper = np.exp(-np.exp(ll - z * se))
    lower = np.where(surv > 0, np.nan_to_num(lower, nan=0.0), 0.0)
    upper = np.where(surv > 0, np.nan_to_num(upper, nan=1.0), 0.0)
    return KaplanMeier(times, surv, lower, upper, at_risk.astype(np.int64), events)


@dataclass(frozen=True)
class DispersionTest:
    """Index of dispersion of counts and its chi-square test.

    Attributes
    ----------
    index : float
        Sample variance over sample mean (1 for Poisson counts).
    statistic : float
        ``(n - 1) * index``, chi-square with ``n - 1`` degrees of freedom under Poisson.
    pvalue : float
        Two-sided p-value.
    n : int
        Number of counts.
    """

    index: float
    statistic: float
    pvalue: float
    n: int


def dispersion_index(counts: npt.ArrayLike) -> DispersionTest:
    """Dispersion index of counts per bin (variance / mean) with a Poisson test.

    Parameters
    ----------
    counts : (n,) int
        Counts per bin (n >= 2, not all zero).

    Returns
    -------
    DispersionTest
    """
    x = check_nonneg_int("counts", check_nonempty("counts", counts), ndim=1).astype(float)
    if x.size < 2:
        raise ValueError(f"counts: expected at least 2 bins, got {x.size}")
    mean = x.mean()
    if mean == 0:
        raise ValueError("counts: expected at least one non-zero count, got all zeros")
    index = x.var(ddof=1) / mean
    stat = (x.size - 1) * index
    df = x.size - 1
    p = 2 * min(stats.chi2.cdf(stat, df), stats.chi2.sf(stat, df))
    return DispersionTest(float(index), float(stat), float(min(p, 1.0)), int(x.size))


def count_path(t_arrive: npt.ArrayLike, t_leave: npt.ArrayLike, times: npt.ArrayLike) -> np.ndarray:
    """``N(t)``: artefacts present at each of ``times``.

    Parameters
    ----------
    t_arrive : (n,) float
        Arrival times; ``-inf`` or NaN for artefacts present since before the window.
    t_leave : (n,) float
        Leave times; ``+inf`` or NaN for artefacts still present.
    times : (m,) float
        Query times.

    Returns
    -------
    (m,) int
        Number of artefacts with ``t_arrive <= t < t_leave``.
    """
    a = np.asarray(t_arrive, dtype=float)
    b = np.asarray(t_leave, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(
            f"t_leave: expected a 1-d array shaped like t_arrive {a.shape}, got {b.shape}"
        )
    a = np.where(np.isnan(a), -np.inf, a)
    b = np.where(np.isnan(b), np.inf, b)
    t = check_finite("times", times)
    arrived = np.searchsorted(np.sort(a), t, side="right")
    left = np.searchsorted(np.sort(b), t, side="right")
    return (arrived - left).astype(np.int64)


def hour_of_day_counts(
    t_arrive: npt.ArrayLike, period: float = 24.0, n_periods: int = 24, clock_offset: float = 0.0
) -> np.ndarray:
    """Arrivals per period of the day.

    Parameters
    ----------
    t_arrive : (n,) float
        Observed arrival times.
    period : float
        Length of a day in the log's time unit.
    n_periods : int
        Number of equal periods (24 for hours of the day).
    clock_offset : float
        Time of day at ``t = 0``.

    Returns
    -------
    (n_periods,) int
    """
    t = check_finite("t_arrive", t_arrive, ndim=1)
    period = float(check_positive("period", period))
    phase = np.mod(t + clock_offset, period)
    idx = np.minimum((phase / (period / n_periods)).astype(np.int64), n_periods - 1)
    return np.bincount(idx, minlength=n_periods)
