"""When artefacts arrive: the paper's Poisson process and the laws field logs need.

The paper's arrivals are a homogeneous Poisson process of intensity ``lambda * area``
(Sect. 3.2). Field logs are burstier: people walk in groups that appear in the same frame,
traffic follows the time of day, and counts per minute are over-dispersed. One generative
process covers the four arrival models of the toolkit:

* **events** arrive as a Poisson process of intensity
  ``rate * area * tod[period(t)] * frailty[bin(t)]``;
* ``tod`` (time of day, ``P`` periods of a day, mean 1 over the day) is all ones unless the
  model is ``"time-of-day"``; it needs the wall-clock time of ``t = 0`` (``clock_start``);
* ``frailty`` (one ``Gamma(phi, phi)`` factor per bin of width ``bin_width``) is all ones
  unless the model is ``"negbin"``: counts per bin are then negative binomial with mean
  ``mu`` and variance ``mu + mu^2 / phi``;
* each event brings a **group** of ``S`` artefacts, ``P(S = s) = size_probs[s - 1]``, who
  share its arrival time (and, downstream, its entry point); ``S = 1`` unless the model is
  ``"groups"`` (a compound Poisson process). ``rate`` is then the rate of groups.

:func:`arrival_loglik` is the matching log-likelihood (for NUTS) and
:func:`stationary_count_moments` the closed-form mean and variance of ``N(t)`` that the
tests and the posterior-predictive checks use.
"""

from __future__ import annotations

import datetime as _dt
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax.scipy.special import gammaln

from are_stats._checks import check_finite, check_in, check_positive, check_simplex

__all__ = [
    "ARRIVAL_MODELS",
    "DAY",
    "ArrivalDraw",
    "arrival_loglik",
    "clock_offset",
    "period_exposure",
    "period_of",
    "sample_arrivals",
    "stationary_count_moments",
]

#: Arrival models, simplest first (the paper's Poisson process is the first).
ARRIVAL_MODELS = ("poisson", "negbin", "time-of-day", "groups")
#: Seconds in a day: the period of the time-of-day model when times are in seconds.
DAY = 86400.0


class ArrivalDraw(NamedTuple):
    """Arrivals drawn over a window.

    Attributes
    ----------
    t : (n,) float
        Arrival time of each artefact, sorted.
    group : (n,) int64
        Group of each artefact (``0 .. n_groups - 1`` in order of arrival); members of a
        group share its arrival time.
    size : (n,) int64
        Size of each artefact's group.
    """

    t: np.ndarray
    group: np.ndarray
    size: np.ndarray


def clock_offset(clock_start: str | _dt.datetime, time_unit: float = 1.0) -> float:
    """Time of day of ``t = 0``, in the log's time unit, from an ISO 8601 timestamp.

    Parameters
    ----------
    clock_start : str or datetime
        Wall-clock time of ``t = 0``, e.g. ``"2024-05-02T07:30:00+02:00"`` (local time is
        what the time of day means, so the offset, if any, is not applied).
    time_unit : float
        Seconds per time unit of the log (1 for seconds, 60 for minutes).

    Returns
    -------
    float
        Seconds since local midnight divided by ``time_unit``.
    """
    if isinstance(clock_start, str):
        try:
            clock_start = _dt.datetime.fromisoformat(clock_start.strip())
        except ValueError:
            raise ValueError(
                f"clock_start: expected an ISO 8601 time such as 2024-05-02T07:30:00, "
                f"got {clock_start!r}"
            ) from None
    if not isinstance(clock_start, _dt.datetime):
        raise ValueError(f"clock_start: expected an ISO 8601 time, got {clock_start!r}")
    c = clock_start
    seconds = c.hour * 3600.0 + c.minute * 60.0 + c.second + c.microsecond * 1e-6
    return seconds / float(check_positive("time_unit", time_unit))


def period_of(t: npt.ArrayLike, offset: float, n_periods: int, period: float = DAY) -> np.ndarray:
    """Period of the day (``0 .. n_periods - 1``) of each time ``t``.

    ``offset`` is the time of day of ``t = 0`` (:func:`clock_offset`), ``period`` the length
    of a day in the log's time unit.
    """
    t = np.asarray(t, float)
    frac = np.mod(t + offset, period) / period
    return np.minimum((frac * n_periods).astype(np.int64), n_periods - 1)


def period_exposure(
    window: npt.ArrayLike, offset: float, n_periods: int, period: float = DAY
) -> np.ndarray:
    """Exact time the window spends in each period of the day.

    Parameters
    ----------
    window : (t0, t1)
    offset : float
        Time of day of ``t = 0``.
    n_periods : int
        Periods of equal length per day.
    period : float
        Length of a day in the log's time unit.

    Returns
    -------
    (n_periods,) float
        Sums to ``t1 - t0``.
    """
    t0, t1 = (float(v) for v in check_finite("window", window, ndim=1))
    width = period / n_periods
    # boundaries of periods crossing the window, in window time
    a = t0 + offset
    first = np.floor(a / width)
    edges = (first + np.arange(int(np.ceil((t1 + offset) / width) - first) + 1)) * width
    lo = np.clip(edges[:-1], a, t1 + offset)
    hi = np.clip(edges[1:], a, t1 + offset)
    idx = (first + np.arange(lo.size)).astype(np.int64) % n_periods
    return np.bincount(idx, weights=hi - lo, minlength=n_periods)


def _pieces(
    window: tuple[float, float],
    tod: np.ndarray | None,
    offset: float,
    period: float,
    bin_width: float | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cut the window where the intensity may change: (starts, ends, tod factor, bin)."""
    t0, t1 = window
    cuts = [np.array([t0, t1])]
    if tod is not None:
        width = period / tod.size
        k0 = np.ceil((t0 + offset) / width)
        k1 = np.floor((t1 + offset) / width)
        cuts.append(np.arange(k0, k1 + 1) * width - offset)
    if bin_width is not None:
        cuts.append(t0 + bin_width * np.arange(1, int(np.ceil((t1 - t0) / bin_width))))
    edges = np.unique(np.clip(np.concatenate(cuts), t0, t1))
    starts, ends = edges[:-1], edges[1:]
    mid = 0.5 * (starts + ends)
    factor = np.ones_like(mid) if tod is None else tod[period_of(mid, offset, tod.size, period)]
    bins = (
        np.zeros(mid.size, np.int64)
        if bin_width is None
        else np.floor((mid - t0) / bin_width).astype(np.int64)
    )
    return starts, ends, factor, bins


def sample_arrivals(
    rng: np.random.Generator,
    rate: float,
    area: float,
    window: npt.ArrayLike,
    *,
    model: str = "poisson",
    phi: float | None = None,
    bin_width: float | None = None,
    tod: npt.ArrayLike | None = None,
    offset: float = 0.0,
    period: float = DAY,
    size_probs: npt.ArrayLike | None = None,
) -> ArrivalDraw:
    """Draw the arrivals of one window (exactly, piece by piece).

    Parameters
    ----------
    rng : numpy.random.Generator
    rate : float
        Events per unit area per unit time (``lambda``; groups per area per time for
        ``"groups"``).
    area : float
        Free area ``nu(M2D)``.
    window : (t0, t1)
    model : {"poisson", "negbin", "time-of-day", "groups"}
        Which factors apply (see the module docstring). ``tod``, ``phi`` and
        ``size_probs`` may also be combined explicitly: any given factor is used.
    phi, bin_width : float
        Negative-binomial concentration and bin width (``"negbin"``).
    tod : (P,) float
        Time-of-day multipliers (``"time-of-day"``), mean 1 over the day.
    offset, period : float
        Time of day of ``t = 0`` and the length of a day, in the log's time unit.
    size_probs : (K,) float
        Probabilities of group sizes ``1 .. K`` (``"groups"``).

    Returns
    -------
    ArrivalDraw
    """
    check_in("model", model, ARRIVAL_MODELS)
    t0, t1 = (float(v) for v in check_finite("window", window, ndim=1))
    base = float(check_positive("rate", rate)) * float(check_positive("area", area))
    tod_a = None if tod is None else check_positive("tod", tod, ndim=1)
    if model == "time-of-day" and tod_a is None:
        raise ValueError("tod: expected time-of-day multipliers for model 'time-of-day'")
    use_bins = phi is not None or model == "negbin"
    if use_bins and (phi is None or bin_width is None):
        raise ValueError("phi, bin_width: expected both for model 'negbin'")
    starts, ends, factor, bins = _pieces(
        (t0, t1), tod_a, float(offset), float(period), float(bin_width) if use_bins else None
    )
    mean = base * factor * (ends - starts)
    if use_bins:
        phi_ = float(check_positive("phi", phi))
        frailty = rng.gamma(phi_, 1.0 / phi_, size=int(bins.max()) + 1)
        mean = mean * frailty[bins]
    counts = rng.poisson(mean)
    t = np.sort(
        np.repeat(starts, counts) + rng.random(int(counts.sum())) * np.repeat(ends - starts, counts)
    )
    probs = None if size_probs is None else check_simplex("size_probs", size_probs)
    if model == "groups" and probs is None:
        raise ValueError("size_probs: expected group-size probabilities for model 'groups'")
    if probs is None:
        n = t.size
        return ArrivalDraw(t, np.arange(n, dtype=np.int64), np.ones(n, np.int64))
    sizes = rng.choice(np.arange(1, probs.size + 1), size=t.size, p=probs).astype(np.int64)
    group = np.repeat(np.arange(t.size, dtype=np.int64), sizes)
    return ArrivalDraw(np.repeat(t, sizes), group, np.repeat(sizes, sizes))


def arrival_loglik(
    t_events: npt.ArrayLike,
    sizes: npt.ArrayLike,
    window: npt.ArrayLike,
    area: float,
    rate: npt.ArrayLike,
    *,
    tod: npt.ArrayLike | None = None,
    offset: float = 0.0,
    period: float = DAY,
    size_probs: npt.ArrayLike | None = None,
    bin_counts: npt.ArrayLike | None = None,
    bin_exposure: npt.ArrayLike | None = None,
    phi: npt.ArrayLike | None = None,
) -> jnp.ndarray:
    """Log-likelihood of the arrival events seen in a window (differentiable in the rates).

    Parameters
    ----------
    t_events : (g,) float
        Event (group) arrival times inside the window.
    sizes : (g,) int
        Group sizes (all ones without groups).
    window : (t0, t1)
    area : float
    rate : float
        Event rate per area per time.
    tod : (P,) float, optional
        Time-of-day multipliers.
    offset, period : float
        Clock of the time-of-day model.
    size_probs : (K,) float, optional
        Group-size law on ``1 .. K``; without it the sizes are not scored.
    bin_counts, bin_exposure, phi : optional
        Negative binomial: events per bin, ``area * integral of tod over the bin`` per bin,
        and the concentration. Given these, the counts are scored by the negative binomial
        and the times within bins by the time-of-day shape.

    Returns
    -------
    float
        ``sum_g [log intensity(t_g) + log P(S_g)] - integral of the intensity`` (Poisson),
        or the negative-binomial counts plus within-bin time densities.
    """
    t0, t1 = (float(v) for v in np.asarray(window, float))
    t = jnp.asarray(t_events, float)
    if tod is None:
        log_shape = jnp.zeros_like(t)
        total_shape = t1 - t0
    else:
        tod = jnp.asarray(tod)
        idx = period_of(np.asarray(t_events, float), offset, int(tod.shape[0]), period)
        log_shape = jnp.log(tod[idx])
        expo = period_exposure((t0, t1), offset, int(tod.shape[0]), period)
        total_shape = jnp.sum(tod * expo)
    if phi is None:
        ll = t.shape[0] * jnp.log(rate * area) + jnp.sum(log_shape) - rate * area * total_shape
    else:
        c = jnp.asarray(bin_counts, float)
        mu = rate * jnp.asarray(bin_exposure, float)
        nb = (
            gammaln(c + phi)
            - gammaln(phi)
            - gammaln(c + 1.0)
            + phi * jnp.log(phi / (phi + mu))
            + c * jnp.log(mu / (phi + mu))
        )
        # times within their bin: density tod(t) / integral of tod over the bin
        ll = (
            jnp.sum(nb)
            + jnp.sum(log_shape)
            - jnp.sum(c * jnp.log(jnp.asarray(bin_exposure) / area))
        )
    if size_probs is not None:
        s = np.asarray(sizes, np.int64)
        ll = ll + jnp.sum(jnp.log(jnp.asarray(size_probs)[s - 1]))
    return ll


def stationary_count_moments(
    rate: float, area: float, mean_stay: float, size_probs: npt.ArrayLike | None = None
) -> tuple[float, float]:
    """Mean and variance of the stationary count ``N(t)`` (M^X/G/inf, shared group stays).

    Groups arrive at ``rate * area``, stay a time of mean ``mean_stay`` (any law:
    insensitivity) and leave together: the number of groups present is
    ``Poisson(rate * area * mean_stay)`` and ``N`` is its compound sum, so
    ``E[N] = c E[S]`` and ``Var[N] = c E[S^2]`` with ``c = rate * area * mean_stay``. Without
    groups (``S = 1``) both equal ``c``: the paper's Poisson(lambda nu / mu).
    """
    c = float(rate) * float(area) * float(mean_stay)
    if size_probs is None:
        return c, c
    p = check_simplex("size_probs", size_probs)
    s = np.arange(1, p.size + 1)
    return c * float(p @ s), c * float(p @ (s * s))
