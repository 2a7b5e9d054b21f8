"""Conjugate closed forms of the life-cycle posterior (the tests' truth and a fast path).

With Gamma priors the Poisson arrival count and the censored / truncated exponential stays
give Gamma posteriors:

* ``arrival_rate`` (lambda): prior Gamma(a, b), ``n`` arrivals inside a window of length
  ``T`` over an area ``A``: posterior Gamma(a + n, b + A T).
* ``leave_rate`` (mu): prior Gamma(a, b), ``d`` observed departures and total exposure ``E``
  (each artefact's time inside the window: from its arrival, or ``t0`` when left-truncated, to
  its departure, or ``t1`` when right-censored): posterior Gamma(a + d, b + E).

These are the exact marginal posteriors of :func:`~are_stats.traffic.lifecycle_model` with
``stationary_start=False`` only. The stationary count of artefacts present at ``t0``,
Poisson(lambda A / mu), couples lambda and mu, and the joint posterior is then no longer a
product of Gammas.

With class labels the complete-data mixture posterior is conjugate too (DECISIONS 5):
``mix_weights`` ~ Dirichlet(alpha + n_c) and each ``mix_rates[c]`` ~ Gamma(a + S_c, b + n_c),
with ``n_c`` the artefacts of class ``c`` and ``S_c`` the sum of their marks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from are_stats._checks import check_nonneg_int
from are_stats._lazy import scipy_stats as stats
from are_stats.traffic._lifecycle import LifecycleData, LifecyclePriors

if TYPE_CHECKING:  # scipy.stats stays lazy (test_import): its frozen law's class, for the type
    from scipy.stats._distn_infrastructure import rv_continuous_frozen

__all__ = [
    "GammaPosterior",
    "MixturePosterior",
    "conjugate_arrival_rate",
    "conjugate_leave_rate",
    "conjugate_mixture",
]


class GammaPosterior(NamedTuple):
    """A Gamma law in shape-rate form (mean ``shape / rate``).

    Attributes
    ----------
    shape : float
        Shape ``a``.
    rate : float
        Rate ``b`` (inverse scale).
    """

    shape: float
    rate: float

    @property
    def mean(self) -> float:
        """Posterior mean ``shape / rate``."""
        return self.shape / self.rate

    @property
    def sd(self) -> float:
        """Posterior standard deviation ``sqrt(shape) / rate``."""
        return float(np.sqrt(self.shape)) / self.rate

    def frozen(self) -> rv_continuous_frozen:
        """The law as a frozen ``scipy.stats.gamma`` (``scale = 1 / rate``)."""
        return stats.gamma(self.shape, scale=1.0 / self.rate)


class MixturePosterior(NamedTuple):
    """Complete-data (labelled) conjugate posterior of the Poisson mixture of eq. (1).

    Attributes
    ----------
    concentration : (k,) float
        Dirichlet concentration of the posterior of ``mix_weights``.
    shape, rate : (k,) float
        Gamma(shape, rate) posterior of each component rate ``mix_rates[c]``.
    """

    concentration: np.ndarray
    shape: np.ndarray
    rate: np.ndarray


def _check_inputs(data: object, priors: object) -> None:
    if not isinstance(data, LifecycleData):
        raise ValueError(f"data: expected a LifecycleData, got {type(data).__name__}")
    if not isinstance(priors, LifecyclePriors):
        raise ValueError(f"priors: expected a LifecyclePriors, got {type(priors).__name__}")


def conjugate_arrival_rate(
    data: LifecycleData,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
) -> GammaPosterior:
    """Posterior of ``arrival_rate`` (lambda): Gamma(a + n_arrivals, b + area * T).

    ``n_arrivals`` counts the artefacts that arrive inside the window (not the left-truncated
    ones); ``T = t1 - t0``. Exact for :func:`~are_stats.traffic.lifecycle_model` with
    ``stationary_start=False``.

    Parameters
    ----------
    data : LifecycleData
        The observed window.
    priors : LifecyclePriors
        Uses ``arrival_shape`` and ``arrival_rate``.

    Returns
    -------
    GammaPosterior
        ``(shape, rate)``; ``.frozen()`` gives the scipy law.

    Raises
    ------
    ValueError
        If ``data`` or ``priors`` has the wrong type.
    """
    _check_inputs(data, priors)
    n_arrivals = int((~data.truncated).sum())
    return GammaPosterior(
        priors.arrival_shape + n_arrivals, priors.arrival_rate + data.area * data.duration
    )


def conjugate_leave_rate(
    data: LifecycleData,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
) -> GammaPosterior:
    """Posterior of ``leave_rate`` (mu): Gamma(a + d, b + E).

    ``d`` is the number of observed departures and ``E`` the exposure, the sum of
    :attr:`LifecycleData.dwell` (censored artefacts count up to ``t1``, truncated ones from
    ``t0``). Exact for :func:`~are_stats.traffic.lifecycle_model` with
    ``stationary_start=False``.

    Parameters
    ----------
    data, priors
        As :func:`conjugate_arrival_rate`; ``priors`` supplies ``leave_shape`` and
        ``leave_rate``.

    Returns
    -------
    GammaPosterior
        As :func:`conjugate_arrival_rate` (and the same ``ValueError`` on wrong types).
    """
    _check_inputs(data, priors)
    departures = int((~data.censored).sum())
    exposure = float(data.dwell.sum())
    return GammaPosterior(priors.leave_shape + departures, priors.leave_rate + exposure)


def conjugate_mixture(
    data: LifecycleData,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    n_components: int | None = None,
) -> MixturePosterior:
    """Complete-data posterior of the mixture of eq. (1) for a log with class labels.

    ``mix_weights`` ~ Dirichlet(alpha + n_c) and ``mix_rates[c]`` ~ Gamma(a + S_c, b + n_c)
    independently, with the i.i.d. Gamma prior that :func:`~are_stats.traffic.lifecycle_model`
    uses when labels are present.

    Parameters
    ----------
    data : LifecycleData
        A log with ``marks`` and ``labels``.
    priors : LifecyclePriors
        Uses ``weights_concentration``, ``mix_rate_shape`` and ``mix_rate_rate``.
    n_components : int, optional
        Number of classes; defaults to ``max(labels) + 1``.

    Returns
    -------
    MixturePosterior
        Dirichlet concentration and per-component Gamma(shape, rate), each (k,).

    Raises
    ------
    ValueError
        If the log has no labels, or a label is not below ``n_components``.
    """
    _check_inputs(data, priors)
    if data.labels is None:
        raise ValueError("data.labels: expected class labels for the conjugate mixture, got None")
    labels = data.labels
    k = int(labels.max()) + 1 if labels.size else 1
    if n_components is not None:
        k_given = int(check_nonneg_int("n_components", n_components, ndim=0))
        if k_given < max(k, 1):
            raise ValueError(
                f"n_components: expected at least max(labels) + 1 = {k}, got {n_components!r}"
            )
        k = k_given
    counts = np.bincount(labels, minlength=k).astype(float)
    sums = np.bincount(labels, weights=data.marks, minlength=k).astype(float)
    return MixturePosterior(
        concentration=priors.weights_concentration + counts,
        shape=priors.mix_rate_shape + sums,
        rate=priors.mix_rate_rate + counts,
    )
