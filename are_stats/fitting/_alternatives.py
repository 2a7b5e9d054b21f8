"""Richer alternatives beside the paper's model, compared by PSIS-LOO.

Real traffic is rarely a homogeneous Poisson process with exponential stays. This module
fits, side by side with the paper's assumptions,

* **arrivals** (counts of arrivals per time bin):
  ``"poisson"`` (the paper: one rate ``lambda``), ``"time_of_day"`` (a piecewise-constant
  rate over the periods of the day) and ``"gamma_poisson"`` (over-dispersed counts, a
  negative binomial with mean ``lambda * area * width`` and concentration ``phi``);
* **lifetimes** (dwell times with right-censoring at the window end):
  ``"exponential"`` (the paper), ``"weibull"`` and ``"gamma"``.

A stay recorded as zero long (left at the very time it arrived: a single sighting) is not a
stay of length zero, which has density 0 or infinity under the Weibull and Gamma laws, but a
stay shorter than the log's time resolution: it is interval-censored on ``(0, resolution]``
and contributes ``log F(resolution)`` (see :func:`time_resolution`). A right-censored stay
of length zero (arrived at the window end) carries no information (``log S(0) = 0``).

Each model is a numpyro model whose observed site gives one pointwise log-likelihood per
unit (a time bin, or an artefact), so that :func:`compare_models` can rank them with
ArviZ's PSIS-LOO. Left-truncated artefacts (arrival unknown) carry no information about the
shape of a non-exponential lifetime law and are left out of the lifetime comparison; the
caller reports how many were left out.

Priors (documented, weakly informative, on the scale of the data):

* rates: ``Gamma(2, 2 / r_hat)`` where ``r_hat`` is the empirical rate (prior mean ``r_hat``,
  coefficient of variation 0.71);
* negative-binomial concentration ``phi``: ``Gamma(2, 0.1)`` (mean 20, allows strong and
  negligible over-dispersion);
* Weibull / Gamma shape ``k``: ``LogNormal(0, 1)`` (median 1, the exponential); their scale /
  rate parameter has the rate prior above.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import arviz as az
import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
from jax.scipy.special import gammaincc
from numpyro.distributions import constraints
from numpyro.infer import MCMC, NUTS

from are_stats._checks import (
    check_finite,
    check_in,
    check_nonempty,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "ARRIVAL_MODELS",
    "LIFETIME_MODELS",
    "arrival_counts",
    "arrival_model",
    "lifetime_model",
    "fit_arrival_models",
    "fit_lifetime_models",
    "compare_models",
    "time_resolution",
]

ARRIVAL_MODELS = ("poisson", "time_of_day", "gamma_poisson")
LIFETIME_MODELS = ("exponential", "weibull", "gamma")


def arrival_counts(
    t_arrive: Any, window: tuple[float, float], bin_width: float
) -> tuple[np.ndarray, np.ndarray]:
    """Counts of arrivals in consecutive bins of ``bin_width`` covering the window.

    Parameters
    ----------
    t_arrive : (n,) float
        Observed arrival times (left-truncated artefacts, whose arrival is unknown, must be
        left out by the caller).
    window : (t0, t1)
        Observation window. The last, partial bin is dropped so every bin has the same
        exposure.
    bin_width : float
        Bin width in the log's time unit.

    Returns
    -------
    starts : (m,) float
        Start time of each bin.
    counts : (m,) int
        Number of arrivals in ``[start, start + bin_width)``.
    """
    t0, t1 = (float(v) for v in check_finite("window", window, ndim=1))
    width = float(check_positive("bin_width", bin_width))
    n_bins = int(np.floor((t1 - t0) / width + 1e-9))
    if n_bins < 2:
        raise ValueError(
            f"bin_width: expected at most half the window length {t1 - t0!r}, got {width!r}"
        )
    t = check_finite("t_arrive", t_arrive, ndim=1)
    starts = t0 + width * np.arange(n_bins)
    idx = np.floor((t - t0) / width).astype(np.int64)
    idx = idx[(idx >= 0) & (idx < n_bins)]
    return starts, np.bincount(idx, minlength=n_bins)


def _rate_prior(r_hat: float) -> dist.Distribution:
    return dist.Gamma(2.0, 2.0 / r_hat)


def arrival_model(
    counts: jnp.ndarray | None,
    exposure: float,
    period_index: jnp.ndarray,
    n_periods: int,
    r_hat: float,
    kind: str = "poisson",
    n_bins: int | None = None,
) -> None:
    """Numpyro model of arrival counts per bin.

    Parameters
    ----------
    counts : (m,) int or None
        Observed counts (``None`` for prior-predictive draws).
    exposure : float
        ``area * bin_width``: the expected count in a bin is ``arrival_rate * exposure``.
    period_index : (m,) int
        Period of the day of each bin (used by ``"time_of_day"``).
    n_periods : int
        Number of periods of the day.
    r_hat : float
        Empirical arrival rate (per area per time), the centre of the rate prior.
    kind : {"poisson", "time_of_day", "gamma_poisson"}
        Which arrival law.
    n_bins : int, optional
        Number of bins when ``counts`` is ``None``.
    """
    m = counts.shape[0] if counts is not None else n_bins
    if kind == "time_of_day":
        with numpyro.plate("periods", n_periods):
            rates = numpyro.sample("arrival_rate_period", _rate_prior(r_hat))
        mean = rates[period_index] * exposure
    else:
        rate = numpyro.sample("arrival_rate", _rate_prior(r_hat))
        mean = jnp.full((m,), rate * exposure)
    if kind == "gamma_poisson":
        phi = numpyro.sample("concentration", dist.Gamma(2.0, 0.1))
        obs_dist = dist.NegativeBinomial2(mean, phi)
    else:
        obs_dist = dist.Poisson(mean)
    with numpyro.plate("bins", m):
        numpyro.sample("counts", obs_dist, obs=counts)


class _RightCensored(dist.Distribution):
    """A lifetime law observed with censoring.

    Density where observed, survival where right-censored, and the probability of a stay
    at most ``resolution`` long where the recorded stay is zero (interval-censored).
    """

    support = constraints.nonnegative

    def __init__(self, kind: str, params: tuple, censored: jnp.ndarray, resolution: float = 1.0):
        self.kind, self.params, self.censored = kind, params, censored
        self.resolution = resolution
        super().__init__(batch_shape=jnp.shape(censored))

    def _log_pdf_surv(self, t):
        if self.kind == "exponential":
            (rate,) = self.params
            return jnp.log(rate) - rate * t, -rate * t
        if self.kind == "weibull":
            shape, rate = self.params  # scale = 1 / rate
            z = t * rate
            logpdf = jnp.log(shape) + jnp.log(rate) + (shape - 1) * jnp.log(z) - z**shape
            return logpdf, -(z**shape)
        shape, rate = self.params
        logpdf = dist.Gamma(shape, rate).log_prob(t)
        return logpdf, jnp.log(gammaincc(shape, rate * t))

    def log_prob(self, value):
        zero = value <= 0
        # zero stays are evaluated at the resolution (a safe point: no log(0), no NaN
        # gradients); their exact-time terms are never used
        t = jnp.where(zero, self.resolution, value)
        logpdf, logsurv = self._log_pdf_surv(t)
        # log F(resolution) = log(1 - S(resolution)), stable for small and large S
        log_cdf = jnp.log(-jnp.expm1(jnp.minimum(logsurv, -1e-300)))
        observed = jnp.where(zero, log_cdf, logpdf)
        censored = jnp.where(zero, 0.0, logsurv)
        return jnp.where(self.censored, censored, observed)

    def sample(self, key, sample_shape=()):
        shape = sample_shape + self.batch_shape
        if self.kind == "exponential":
            (rate,) = self.params
            return jax.random.exponential(key, shape) / rate
        if self.kind == "weibull":
            k, rate = self.params
            return jax.random.weibull_min(key, 1.0, k, shape) / rate
        k, rate = self.params
        return jax.random.gamma(key, k, shape) / rate


def lifetime_model(
    durations: jnp.ndarray | None,
    censored: jnp.ndarray,
    r_hat: float,
    kind: str = "exponential",
    resolution: float = 1.0,
) -> None:
    """Numpyro model of dwell times with right-censoring.

    Parameters
    ----------
    durations : (n,) float or None
        Observed stays (time from arrival to leave, or to the window end when censored).
    censored : (n,) bool
        True where the artefact was still present at the window end.
    r_hat : float
        Empirical leave rate (events / exposure), the centre of the rate prior.
    kind : {"exponential", "weibull", "gamma"}
        Which lifetime law. For Weibull the rate is the inverse scale; for Gamma the rate is
        the usual rate, so the mean stay is ``shape / rate``.
    resolution : float
        Time resolution of the log: an observed stay of length zero is a stay in
        ``(0, resolution]`` (interval-censored).
    """
    if kind == "exponential":
        rate = numpyro.sample("leave_rate", _rate_prior(r_hat))
        params: tuple = (rate,)
    else:
        shape = numpyro.sample("shape", dist.LogNormal(0.0, 1.0))
        rate = numpyro.sample("leave_rate", _rate_prior(r_hat))
        params = (shape, rate)
    with numpyro.plate("artefacts", censored.shape[0]):
        numpyro.sample(
            "durations", _RightCensored(kind, params, censored, resolution), obs=durations
        )


def _fit_each(key, model, data, kinds, num_warmup, num_samples, num_chains):
    """One NUTS fit of ``model(**data, kind=kind)`` per kind, keyed by kind."""
    return {
        kind: _run_nuts(
            jax.random.fold_in(key, i),
            model,
            {**data, "kind": kind},
            num_warmup,
            num_samples,
            num_chains,
        )
        for i, kind in enumerate(kinds)
    }


def _run_nuts(key, model, kwargs, num_warmup, num_samples, num_chains):
    chain_method = "parallel" if jax.local_device_count() >= num_chains else "vectorized"
    mcmc = MCMC(
        NUTS(model),
        num_warmup=num_warmup,
        num_samples=num_samples,
        num_chains=num_chains,
        chain_method=chain_method,
        progress_bar=False,
    )
    mcmc.run(key, **kwargs)
    return az.from_numpyro(mcmc)  # observed site -> observed_data and log_likelihood


def fit_arrival_models(
    key: jax.Array,
    t_arrive: Any,
    window: tuple[float, float],
    area: float,
    bin_width: float,
    period: float = 24.0,
    n_periods: int = 24,
    clock_offset: float = 0.0,
    models: Sequence[str] = ARRIVAL_MODELS,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 2,
) -> dict[str, az.InferenceData]:
    """Fit the arrival-count models by NUTS; one InferenceData per model.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    t_arrive : (n,) float
        Observed arrival times inside the window.
    window : (t0, t1)
        Observation window.
    area : float
        Free area ``nu(M2D)`` in m^2.
    bin_width : float
        Width of a count bin, in the log's time unit.
    period : float
        Length of a day in the log's time unit (24 for hours, 1440 for minutes).
    n_periods : int
        Number of equal periods of the day for ``"time_of_day"``.
    clock_offset : float
        Time of day at ``t = 0`` in the log's time unit.
    models : sequence of str
        Subset of :data:`ARRIVAL_MODELS`.
    num_warmup, num_samples, num_chains : int
        NUTS settings.

    Returns
    -------
    dict
        ``{name: arviz.InferenceData}`` with pointwise ``log_likelihood`` of ``counts``.
    """
    for m in models:
        check_in("models", m, ARRIVAL_MODELS)
    area = float(check_positive("area", area))
    starts, counts = arrival_counts(t_arrive, window, bin_width)
    phase = np.mod(starts + 0.5 * bin_width + clock_offset, period)
    period_index = np.minimum((phase / (period / n_periods)).astype(np.int64), n_periods - 1)
    exposure = area * bin_width
    r_hat = max(counts.mean(), 0.5) / exposure
    data = dict(
        counts=jnp.asarray(counts),
        exposure=exposure,
        period_index=jnp.asarray(period_index),
        n_periods=n_periods,
        r_hat=r_hat,
    )
    return _fit_each(key, arrival_model, data, models, num_warmup, num_samples, num_chains)


def time_resolution(*times: Any) -> float:
    """The time resolution of a log: the smallest gap between distinct recorded times.

    Parameters
    ----------
    *times : array_like of float
        Recorded times (NaN entries, for unknown times, are ignored).

    Returns
    -------
    float
        The smallest positive difference between two distinct finite times.

    Raises
    ------
    ValueError
        If fewer than two distinct finite times are given.
    """
    parts = [np.asarray(t, dtype=np.float64).ravel() for t in times]
    allt = np.concatenate(parts) if parts else np.zeros(0)
    u = np.unique(allt[np.isfinite(allt)])
    if u.size < 2:
        raise ValueError(
            f"times: expected at least two distinct recorded times to tell the log's time "
            f"resolution, got {u.size}"
        )
    return float(np.diff(u).min())


def fit_lifetime_models(
    key: jax.Array,
    durations: Any,
    censored: Any,
    models: Sequence[str] = LIFETIME_MODELS,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 2,
    resolution: float | None = None,
) -> dict[str, az.InferenceData]:
    """Fit the lifetime models (right-censored) by NUTS; one InferenceData per model.

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    durations : (n,) float
        Stays of the artefacts whose arrival was observed (>= 0; a zero stay is a stay
        shorter than ``resolution``, interval-censored).
    censored : (n,) bool
        True where the stay was cut by the window end.
    models : sequence of str
        Subset of :data:`LIFETIME_MODELS`.
    num_warmup, num_samples, num_chains : int
        NUTS settings.
    resolution : float, optional
        Time resolution of the log (see :func:`time_resolution`); needed only when some
        observed stay is zero. Default: the smallest positive stay.

    Returns
    -------
    dict
        ``{name: arviz.InferenceData}`` with pointwise ``log_likelihood`` of ``durations``.
    """
    for m in models:
        check_in("models", m, LIFETIME_MODELS)
    d = check_nonnegative("durations", check_nonempty("durations", durations), ndim=1)
    c = np.asarray(censored)
    if c.dtype != bool:
        raise ValueError(f"censored: expected booleans, got dtype {c.dtype}")
    if c.shape != d.shape:
        raise ValueError(f"censored: expected shape {d.shape} like durations, got {c.shape}")
    events = int((~c).sum())
    if events == 0:
        raise ValueError("censored: expected at least one observed (uncensored) stay, got none")
    zero = (d == 0) & ~c
    if resolution is None:
        positive = d[d > 0]
        if zero.any() and positive.size == 0:
            raise ValueError(
                "resolution: expected the log's time resolution (every observed stay is "
                "zero long), got None"
            )
        res = float(positive.min()) if positive.size else 1.0
    else:
        res = float(check_positive("resolution", resolution))
    # a zero stay counts as half the resolution in the empirical rate
    r_hat = events / float(np.where(d > 0, d, 0.5 * res).sum())
    data = dict(durations=jnp.asarray(d), censored=jnp.asarray(c), r_hat=r_hat, resolution=res)
    return _fit_each(key, lifetime_model, data, models, num_warmup, num_samples, num_chains)


def compare_models(idatas: dict[str, az.InferenceData]):
    """Rank fitted models by PSIS-LOO (ArviZ ``compare``, expected log predictive density).

    Parameters
    ----------
    idatas : dict
        ``{name: InferenceData}`` fitted to the same data (same pointwise units).

    Returns
    -------
    pandas.DataFrame
        ArviZ's comparison table (``elpd_loo``, ``p_loo``, ``elpd_diff``, ``weight``, ...),
        best model first.
    """
    if len(idatas) < 2:
        raise ValueError(f"idatas: expected at least two models to compare, got {len(idatas)}")
    return az.compare(idatas, ic="loo")
