"""Exact posterior draws of the paper's life-cycle model, without MCMC (issue 29).

:func:`~are_stats.traffic.lifecycle_model` has Gamma priors on ``arrival_rate`` (lambda)
and ``leave_rate`` (mu), Poisson counts and exponential stays, so its posterior needs no
sampler where the mixture of eq. (1) is conjugate too:

* ``stationary_start=False``: lambda ~ Gamma(a1 + n, b1 + A T) and
  mu ~ Gamma(a2 + d, b2 + E) independently (:func:`~are_stats.traffic.conjugate_arrival_rate`,
  :func:`~are_stats.traffic.conjugate_leave_rate`; ``n`` arrivals in the window, ``d``
  departures, ``E`` the exposure, censoring and truncation included);
* ``stationary_start=True`` (the default of ``are-stats fit``): the count present at
  ``t0``, ``n0`` ~ Poisson(lambda A / mu), couples the rates. The joint density is

  .. math::

     p(\\lambda, \\mu) \\propto \\lambda^{\\alpha - 1}
         e^{-\\lambda (b_1 + A T + A / \\mu)}\\, \\mu^{a_2 + d - n_0 - 1} e^{-\\mu (b_2 + E)},
     \\qquad \\alpha = a_1 + n + n_0,

  so lambda given mu is Gamma(alpha, b1 + A T + A / mu) and mu's marginal is, on
  ``u = log mu``, ``h(u) = (a2 + d - n0) u - (b2 + E) e^u - alpha log(b1 + A T + A e^-u)``:
  strictly concave (``h'' = -(b2 + E) e^u - alpha s (1 - s) < 0`` with ``s`` a logistic
  function of ``u``). mu is drawn exactly by rejection from a three-piece exponential
  envelope (the tangents of ``h`` one standard deviation either side of its mode and the
  flat line through the mode: an upper bound of a concave function, about 80 % accepted),
  then lambda from its Gamma conditional. The draws are independent and exact, not
  approximate;
* the mixture: with class labels the complete-data posterior Dirichlet x Gamma
  (:func:`~are_stats.traffic.conjugate_mixture`); one component without labels is a Poisson
  with a Gamma prior, Gamma(a + sum of marks, b + n). Several components without labels
  (the ordered prior of a latent class) have no closed form: :func:`has_exact_posterior`
  says so and ``fit_log`` samples such a log by NUTS as before.
"""

from __future__ import annotations

import jax
import numpy as np
from scipy.optimize import brentq

from are_stats._checks import check_in, check_nonneg_int
from are_stats.traffic import (
    LifecycleData,
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    numpy_rng,
)

__all__ = ["exact_lifecycle_draws", "has_exact_posterior", "sample_coupled_rates"]

#: Rejection rounds before giving up (each draws 1.5x the draws still missing; the
#: envelope accepts about 80 %, so three or four rounds are the rule).
_MAX_ROUNDS = 200


def has_exact_posterior(data: LifecycleData, n_components: int | None) -> bool:
    """Whether :func:`exact_lifecycle_draws` covers this log: no marks, class labels, or a
    one-component mixture (the ordered mixture of several latent classes needs NUTS).

    Parameters
    ----------
    data : LifecycleData
    n_components : int or None
        Mixture components of the fit (None: no mixture).
    """
    if data.marks is None or n_components is None:
        return True
    return data.labels is not None or int(n_components) == 1


class _LogMarginal:
    """``h(u)`` of the module docstring (mu's log posterior on ``u = log mu``) and its
    first two derivatives."""

    def __init__(self, power: float, b: float, alpha: float, log_c: float, log_a: float):
        self.power, self.b, self.alpha, self.log_c, self.log_a = power, b, alpha, log_c, log_a

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float)
        return (
            self.power * u
            - self.b * np.exp(u)
            - self.alpha * np.logaddexp(self.log_c, self.log_a - u)
        )

    def _s(self, u: float | np.ndarray) -> float | np.ndarray:  # A e^-u / (c + A e^-u)
        return 1.0 / (1.0 + np.exp(u + self.log_c - self.log_a))

    def d1(self, u: float) -> float:
        return float(self.power - self.b * np.exp(u) + self.alpha * self._s(u))

    def d2(self, u: float) -> float:
        s = self._s(u)
        return float(-self.b * np.exp(u) - self.alpha * s * (1.0 - s))


def _mode(h: _LogMarginal, start: float) -> float:
    """The root of the decreasing ``h'``, bracketed from ``start`` then by Brent's method."""
    lo, hi, step = start - 1.0, start + 1.0, 1.0
    while h.d1(lo) <= 0:
        lo, step = lo - step, step * 2
    step = 1.0
    while h.d1(hi) >= 0:
        hi, step = hi + step, step * 2
    return float(brentq(h.d1, lo, hi, xtol=1e-13, rtol=4 * np.finfo(float).eps))


def _tangent_point(h: _LogMarginal, m: float, sd: float, side: float) -> tuple[float, float]:
    """A point ``sd`` (or more) from the mode on ``side`` whose tangent slopes away from it."""
    u = m + side * sd
    for _ in range(60):
        slope = h.d1(u)
        if side * slope < 0:
            return u, slope
        u += side * sd
    raise ArithmeticError("no tangent of the posterior of leave_rate slopes away from its mode")


def _sample_concave(rng: np.random.Generator, h: _LogMarginal, m: float, n: int) -> np.ndarray:
    """``n`` exact draws from the density ``exp(h)`` (``h`` concave, mode ``m``) by
    rejection from the tangents at ``m -+ sd`` and the flat line through the mode."""
    sd = 1.0 / np.sqrt(-h.d2(m))
    hm = float(h(m))
    u_l, s_l = _tangent_point(h, m, sd, -1.0)
    u_r, s_r = _tangent_point(h, m, sd, 1.0)
    z1 = u_l + (hm - float(h(u_l))) / s_l  # where each tangent meets the flat line
    z2 = u_r + (hm - float(h(u_r))) / s_r
    mass = np.array([1.0 / s_l, z2 - z1, -1.0 / s_r])
    prob = mass / mass.sum()
    out: list[np.ndarray] = []
    got = 0
    for _ in range(_MAX_ROUNDS):
        if got >= n:
            break
        size = int(1.5 * (n - got)) + 16
        piece = rng.choice(3, size=size, p=prob)
        v = 1.0 - rng.random(size)  # (0, 1]
        u = np.where(
            piece == 0,
            z1 + np.log(v) / s_l,
            np.where(piece == 1, z1 + v * (z2 - z1), z2 + np.log(v) / s_r),
        )
        log_env = hm + np.where(
            piece == 0, s_l * (u - z1), np.where(piece == 1, 0.0, s_r * (u - z2))
        )
        accept = np.log(1.0 - rng.random(size)) <= h(u) - log_env
        out.append(u[accept])
        got += int(accept.sum())
    else:
        if got < n:
            raise ArithmeticError("rejection sampling of leave_rate accepted too few draws")
    return np.concatenate(out)[:n]


def sample_coupled_rates(
    rng: np.random.Generator, data: LifecycleData, priors: LifecyclePriors, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Exact joint posterior draws of (lambda, mu) with the stationary count present at ``t0``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Randomness.
    data : LifecycleData
        The observed window (censoring and truncation included).
    priors : LifecyclePriors
        Gamma priors of ``arrival_rate`` and ``leave_rate``.
    n : int
        Number of draws.

    Returns
    -------
    arrival_rate, leave_rate : (n,) float
        Independent draws of the joint posterior of
        :func:`~are_stats.traffic.lifecycle_model` with ``stationary_start=True``
        (marginal of the mixture, which is independent of the rates a posteriori).
    """
    n = int(check_nonneg_int("n", n, ndim=0))
    s = data.summary
    area, duration = float(s.area), float(s.duration)
    n0 = float(s.n_present)
    departures = float(np.sum(s.departed))
    alpha = priors.arrival_shape + float(s.n_arrivals) + n0
    c = priors.arrival_rate + area * duration
    h = _LogMarginal(
        power=priors.leave_shape + departures - n0,
        b=priors.leave_rate + float(np.sum(s.dwell)),
        alpha=alpha,
        log_c=float(np.log(c)),
        log_a=float(np.log(area)),
    )
    start = conjugate_leave_rate(data, priors)
    m = _mode(h, float(np.log(start.mean)))
    mu = np.exp(_sample_concave(rng, h, m, n))
    lam = rng.gamma(alpha, 1.0 / (c + area / mu))
    return lam, mu


def exact_lifecycle_draws(
    key: jax.Array,
    data: LifecycleData,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    *,
    n_components: int | None = None,
    num_samples: int = 1000,
    num_chains: int = 4,
    stationary_start: bool = True,
) -> dict[str, np.ndarray]:
    """Independent exact draws of the life-cycle posterior, laid out as NUTS chains.

    Parameters
    ----------
    key : jax PRNG key
        Randomness (a NumPy generator is seeded from it).
    data : LifecycleData
        The observed window.
    priors : LifecyclePriors
        The priors of :func:`~are_stats.traffic.lifecycle_model`.
    n_components : int, optional
        Mixture components (None, or a log without marks: no mixture).
    num_samples, num_chains : int
        The draws' layout: ``num_chains`` "chains" of ``num_samples`` independent draws
        (the shape of a NUTS posterior, so that every consumer reads them alike).
    stationary_start : bool
        Include the Poisson(lambda * area / mu) count present at ``t0``.

    Returns
    -------
    dict
        ``arrival_rate``, ``leave_rate`` (chains, draws); with a mixture ``mix_weights``
        and ``mix_rates`` (chains, draws, k).

    Raises
    ------
    ValueError
        If the log's mixture has no closed form (several components without labels: see
        :func:`has_exact_posterior`), or an argument is invalid.
    """
    if not isinstance(data, LifecycleData):
        raise ValueError(f"data: expected a LifecycleData, got {type(data).__name__}")
    if not isinstance(priors, LifecyclePriors):
        raise ValueError(f"priors: expected a LifecyclePriors, got {type(priors).__name__}")
    check_in("stationary_start", stationary_start, (True, False))
    chains = int(check_nonneg_int("num_chains", num_chains, ndim=0))
    samples = int(check_nonneg_int("num_samples", num_samples, ndim=0))
    if chains < 1 or samples < 1:
        raise ValueError(
            f"num_chains, num_samples: expected integers >= 1, got {num_chains!r}, {num_samples!r}"
        )
    k = None if data.marks is None else n_components
    if not has_exact_posterior(data, k):
        raise ValueError(
            f"n_components: the mixture of {k} components without class labels has no "
            "closed-form posterior (sample it by NUTS: fit_lifecycle_nuts)"
        )
    n = chains * samples
    rng = numpy_rng(key)
    if stationary_start:
        lam, mu = sample_coupled_rates(rng, data, priors, n)
    else:
        arr, lea = conjugate_arrival_rate(data, priors), conjugate_leave_rate(data, priors)
        lam = rng.gamma(arr.shape, 1.0 / arr.rate, n)
        mu = rng.gamma(lea.shape, 1.0 / lea.rate, n)
    post = {"arrival_rate": lam, "leave_rate": mu}
    if k is not None:
        k = int(k)
        if data.labels is not None:
            mix = conjugate_mixture(data, priors, n_components=k)
            shape, rate = np.asarray(mix.shape), np.asarray(mix.rate)
            conc = np.asarray(mix.concentration)
        else:  # one component: a Poisson with a Gamma prior
            shape = np.array([priors.mix_rate_shape + float(np.sum(data.marks))])
            rate = np.array([priors.mix_rate_rate + float(data.n)])
            conc = None
        post["mix_weights"] = np.ones((n, 1)) if k == 1 else rng.dirichlet(conc, n)
        post["mix_rates"] = rng.gamma(shape, 1.0 / rate, (n, k))
    return {name: v.reshape((chains, samples) + v.shape[1:]) for name, v in post.items()}
