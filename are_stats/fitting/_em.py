"""Expectation-maximisation for the Poisson mixture of eq. (1), over the histogram of marks.

The marks of a field log take few distinct values (a few dozen for the paper's Fig. 2
mixture), so every E- and M-step runs over the histogram ``(values, counts)`` of distinct
marks: one million marks cost O(distinct values) per iteration, not O(marks).

The algorithm is written as a pure pair (blackjax / optax style)::

    state = em_init(hist, weights, rates)
    state, info = em_step(state, hist)

``fit_mixture_em`` runs it under ``jax.lax.while_loop`` for several restarts at once
(``vmap``) and keeps the restart with the highest log-likelihood.
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import lax, random
from jax.scipy.special import xlogy
from scipy.special import gammaln

from are_stats._checks import check_array, check_nonneg_int, check_nonnegative, describe
from are_stats.traffic import PoissonMixture

__all__ = [
    "MarksHistogram",
    "marks_histogram",
    "EMState",
    "EMInfo",
    "em_init",
    "em_step",
    "squarem_step",
    "MixtureEMResult",
    "fit_mixture_em",
]

# Rates never fall below this floor in the M-step (a component fitted to the mark 0 alone
# would otherwise get rate 0, outside the parameter space).
_RATE_FLOOR = 1e-10


class MarksHistogram(NamedTuple):
    """Histogram of distinct marks: the sufficient statistic of eq. (1).

    Attributes
    ----------
    values : (m,) float64
        Distinct marks in increasing order.
    counts : (m,) float64
        How many marks take each value (non-negative; real weights are allowed).
    log_factorial : (m,) float64
        ``log(values!)``, precomputed once.
    """

    values: np.ndarray | jax.Array
    counts: np.ndarray | jax.Array
    log_factorial: np.ndarray | jax.Array

    @property
    def n_marks(self) -> float:
        """Total number of marks (sum of the counts)."""
        return float(np.sum(self.counts))

    @property
    def n_distinct(self) -> int:
        """Number of distinct marks ``m``."""
        return int(np.shape(self.values)[0])


def _check_marks(marks: npt.ArrayLike) -> np.ndarray:
    """Marks as a 1-d int64 array of non-negative integers (fast path for integer input)."""
    a = np.asarray(marks) if not isinstance(marks, np.ndarray) else marks
    if a.dtype.kind in "iu":
        a = a.ravel()
        if a.size and a.min() < 0:
            check_nonneg_int("marks", a)  # raises with the offending value and index
        return a.astype(np.int64, copy=False)
    if a.dtype.kind == "b" or a.dtype.kind not in "f":
        a = check_array("marks", marks, float)
    return check_nonneg_int("marks", a.ravel())


def marks_histogram(marks: npt.ArrayLike, counts: npt.ArrayLike | None = None) -> MarksHistogram:
    """Histogram of distinct marks.

    Parameters
    ----------
    marks : (n,) int
        Non-negative integer marks. With ``counts``, the values of a precomputed histogram
        (repeats are merged).
    counts : (n,) float, optional
        Multiplicity (or non-negative weight) of each entry of ``marks``. Entries with
        zero count are dropped.

    Returns
    -------
    MarksHistogram
        Distinct values in increasing order with their total counts.

    Raises
    ------
    ValueError
        If ``marks`` is empty or holds negative or non-integer values, or ``counts`` is
        negative, non-finite, of another length, or sums to zero.

    Examples
    --------
    >>> from are_stats.fitting import marks_histogram
    >>> h = marks_histogram([3, 1, 3, 3])
    >>> h.values.tolist(), h.counts.tolist()
    ([1.0, 3.0], [1.0, 3.0])
    """
    k = _check_marks(marks)
    if k.size == 0:
        raise ValueError("marks: expected at least one mark, got an empty input")
    if counts is None:
        kmax = int(k.max())
        if kmax <= 4 * k.size + 1024:
            c = np.bincount(k, minlength=kmax + 1)
            values = np.flatnonzero(c)
            cnt = c[values].astype(np.float64)
        else:
            values, c = np.unique(k, return_counts=True)
            cnt = c.astype(np.float64)
    else:
        w = check_nonnegative("counts", counts)
        w = w.ravel()
        if w.shape != k.shape:
            raise ValueError(f"counts: expected {k.size} counts (one per mark), got {w.size}")
        values, inv = np.unique(k, return_inverse=True)
        cnt = np.bincount(inv, weights=w, minlength=values.size)
        keep = cnt > 0
        values, cnt = values[keep], cnt[keep]
        if values.size == 0:
            raise ValueError(f"counts: expected a positive total count, got {describe(w)}")
    v = values.astype(np.float64)
    return MarksHistogram(values=v, counts=cnt, log_factorial=gammaln(v + 1.0))


class EMState(NamedTuple):
    """State of the EM iteration.

    Attributes
    ----------
    weights : (n,) float
        Current mixture weights.
    rates : (n,) float
        Current Poisson rates.
    mean_loglik : () float
        Mean log-likelihood per mark of ``(weights, rates)``.
    resp_counts : (n,) float
        Expected number of marks per component (E-step at the current parameters).
    resp_sums : (n,) float
        Expected sum of marks per component (E-step at the current parameters).
    """

    weights: jax.Array
    rates: jax.Array
    mean_loglik: jax.Array
    resp_counts: jax.Array
    resp_sums: jax.Array


class EMInfo(NamedTuple):
    """What one EM step did.

    Attributes
    ----------
    mean_loglik : () float
        Mean log-likelihood per mark after the step.
    delta : () float
        Change of the mean log-likelihood (never negative up to rounding: EM is monotone).
    """

    mean_loglik: jax.Array
    delta: jax.Array


def _e_step(
    weights: jax.Array, rates: jax.Array, hist: MarksHistogram
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Mean log-likelihood and expected sufficient statistics at ``(weights, rates)``."""
    v = hist.values[:, None]
    joint = jnp.log(weights) + xlogy(v, rates) - rates - hist.log_factorial[:, None]  # (m, n)
    lse = jax.nn.logsumexp(joint, axis=-1)  # (m,)
    resp = jnp.exp(joint - lse[:, None])  # (m, n)
    n = jnp.sum(hist.counts)
    mean_ll = jnp.sum(hist.counts * lse) / n
    resp_counts = hist.counts @ resp
    resp_sums = (hist.counts * hist.values) @ resp
    return mean_ll, resp_counts, resp_sums


def em_init(hist: MarksHistogram, weights: npt.ArrayLike, rates: npt.ArrayLike) -> EMState:
    """Start EM at ``(weights, rates)``: runs the first E-step.

    Parameters
    ----------
    hist : MarksHistogram
        Histogram of the marks (arrays may be NumPy or JAX).
    weights : (n,) float
        Initial weights (simplex).
    rates : (n,) float
        Initial rates (> 0).

    Returns
    -------
    EMState
        The state, with the mean log-likelihood of the initial parameters.
    """
    weights = jnp.asarray(weights, dtype=jnp.float64)
    rates = jnp.asarray(rates, dtype=jnp.float64)
    mean_ll, rc, rs = _e_step(weights, rates, hist)
    return EMState(weights, rates, mean_ll, rc, rs)


def em_step(state: EMState, hist: MarksHistogram) -> tuple[EMState, EMInfo]:
    """One EM iteration: M-step from the stored expectations, then the next E-step.

    Parameters
    ----------
    state : EMState
        Current state.
    hist : MarksHistogram
        Histogram of the marks.

    Returns
    -------
    state : EMState
        Updated parameters and their mean log-likelihood.
    info : EMInfo
        Mean log-likelihood after the step and its change.

    Notes
    -----
    M-step: ``pi_i = N_i / N`` and ``lambda_i = S_i / N_i`` with ``N_i`` (``S_i``) the
    expected count (sum) of marks of component ``i``. A component with no expected marks
    keeps its rate; rates are floored at 1e-10.
    """
    n = jnp.sum(state.resp_counts)
    weights = state.resp_counts / n
    safe = state.resp_counts > 0
    rates = jnp.where(safe, state.resp_sums / jnp.where(safe, state.resp_counts, 1.0), state.rates)
    rates = jnp.maximum(rates, _RATE_FLOOR)
    mean_ll, rc, rs = _e_step(weights, rates, hist)
    new = EMState(weights, rates, mean_ll, rc, rs)
    return new, EMInfo(mean_ll, mean_ll - state.mean_loglik)


def _weighted_quantiles(hist: MarksHistogram, q: jax.Array) -> jax.Array:
    """Quantiles of the marks (histogram with sorted values)."""
    cdf = jnp.cumsum(hist.counts) / jnp.sum(hist.counts)
    idx = jnp.searchsorted(cdf, q, side="left")
    return hist.values[jnp.clip(idx, 0, hist.values.shape[0] - 1)]


def _kmeanspp(key: jax.Array, hist: MarksHistogram, n_slots: int, n_real: jax.Array) -> jax.Array:
    """k-means++ seeding on the distinct marks weighted by counts (first ``n_real`` slots)."""
    keys = random.split(key, n_slots)
    idx = jnp.arange(n_slots)

    def body(i: jax.Array, centers: jax.Array) -> jax.Array:
        d2 = (hist.values[:, None] - centers[None, :]) ** 2
        d2 = jnp.min(jnp.where(idx[None, :] < i, d2, jnp.inf), axis=1)
        d2 = jnp.where(i == 0, 1.0, d2)
        logits = jnp.log(hist.counts * d2)
        j = random.categorical(keys[i], logits)
        return centers.at[i].set(hist.values[j])

    return lax.fori_loop(0, n_real, body, jnp.zeros(n_slots))


def _initial_rates(
    key: jax.Array, hist: MarksHistogram, n_slots: int, n_real: jax.Array, restart: jax.Array
) -> jax.Array:
    """Initial rates of the ``n_real`` components; padding slots get rate 1.

    Restart 0: evenly spaced quantiles of the marks; odd restarts: k-means++ seeding; even
    restarts: quantiles at sorted uniform draws. All but restart 0 get a 5% multiplicative
    jitter; restart 0 gets a deterministic 1% spread so that tied quantiles separate.
    """
    k_q, k_pp, k_jit = random.split(key, 3)
    real = jnp.arange(n_slots) < n_real
    even_q = (jnp.arange(n_slots) + 0.5) / n_real
    rand_q = jnp.sort(jnp.where(real, random.uniform(k_q, (n_slots,)), 2.0))
    quant = _weighted_quantiles(hist, jnp.where(restart == 0, even_q, rand_q))
    pp = _kmeanspp(k_pp, hist, n_slots, n_real)
    centers = jnp.where((restart % 2) == 1, pp, quant)
    mean = jnp.sum(hist.counts * hist.values) / jnp.sum(hist.counts)
    floor = jnp.maximum(0.1 * mean, 1e-3)
    jitter = jnp.exp(0.05 * random.normal(k_jit, (n_slots,)))
    jitter = jnp.where(restart == 0, 1.0 + 0.01 * jnp.arange(n_slots), jitter)
    rates = jnp.sort(jnp.where(real, jnp.maximum(centers, floor) * jitter, jnp.inf))
    return jnp.where(real, rates, 1.0)


def squarem_step(state: EMState, hist: MarksHistogram) -> tuple[EMState, EMInfo, jax.Array]:
    """One SQUAREM-accelerated EM iteration (Varadhan and Roland 2008, scheme S3).

    Two EM steps ``theta0 -> theta1 -> theta2`` define ``r = theta1 - theta0`` and
    ``v = theta2 - 2 theta1 + theta0``; the extrapolation
    ``theta0 - 2 a r + a^2 v`` with ``a = min(-|r| / |v|, -1)`` is followed by one
    stabilising EM step. It is accepted only if it is a valid parameter and its
    log-likelihood is at least that of ``theta2``; otherwise ``theta2`` is kept, so the
    iteration is monotone like plain EM.

    Parameters
    ----------
    state : EMState
        Current state.
    hist : MarksHistogram
        Histogram of the marks.

    Returns
    -------
    state : EMState
        Updated state.
    info : EMInfo
        Mean log-likelihood after the iteration and its change.
    n_updates : () int
        EM updates (M-steps) spent: 2, or 3 when the extrapolation was tried.
    """
    s1, _ = em_step(state, hist)
    s2, _ = em_step(s1, hist)
    theta0 = jnp.concatenate([state.weights, state.rates])
    theta1 = jnp.concatenate([s1.weights, s1.rates])
    theta2 = jnp.concatenate([s2.weights, s2.rates])
    r = theta1 - theta0
    v = theta2 - 2.0 * theta1 + theta0
    nr = jnp.sqrt(jnp.sum(r * r))
    nv = jnp.sqrt(jnp.sum(v * v))
    alpha = jnp.minimum(-nr / jnp.where(nv > 0, nv, 1.0), -1.0)
    theta = theta0 - 2.0 * alpha * r + alpha**2 * v
    n = state.weights.shape[0]
    w, lam = theta[:n], theta[n:]
    valid = jnp.all(w >= 0) & jnp.all(lam > _RATE_FLOOR) & (nv > 0) & jnp.all(jnp.isfinite(theta))
    w = jnp.where(valid, w, state.weights)
    lam = jnp.where(valid, lam, state.rates)
    w = w / jnp.sum(w)
    s3, _ = em_step(em_init(hist, w, lam), hist)
    accept = valid & jnp.isfinite(s3.mean_loglik) & (s3.mean_loglik >= s2.mean_loglik)
    new = jax.tree.map(lambda a, b: jnp.where(accept, a, b), s3, s2)
    return new, EMInfo(new.mean_loglik, new.mean_loglik - state.mean_loglik), 2 + valid


@partial(jax.jit, static_argnames=("n_slots", "n_restarts", "max_iter", "accelerate"))
def _fit_restarts(
    key: jax.Array,
    hist: MarksHistogram,
    tol: float | jax.Array,
    n_components: int | jax.Array,
    *,
    n_slots: int,
    n_restarts: int,
    max_iter: int,
    accelerate: bool,
) -> tuple[EMState, jax.Array, jax.Array]:
    """EM from ``n_restarts`` initialisations at once: final states, EM updates, deltas.

    The parameter vectors have ``n_slots >= n_components`` entries; the extra slots have
    weight 0 and stay at weight 0 under EM (their responsibilities are 0), so one
    compiled function serves every ``n_components <= n_slots``.
    """
    keys = random.split(key, n_restarts)
    rates0 = jax.vmap(lambda k, r: _initial_rates(k, hist, n_slots, n_components, r))(
        keys, jnp.arange(n_restarts)
    )
    real = jnp.arange(n_slots) < n_components
    w0 = jnp.where(real, 1.0 / n_components, 0.0)
    weights0 = jnp.broadcast_to(w0, (n_restarts, n_slots))

    def run(w0: jax.Array, r0: jax.Array) -> tuple[EMState, jax.Array, jax.Array]:
        state0 = em_init(hist, w0, r0)

        def cond(carry: tuple[EMState, jax.Array, jax.Array]) -> jax.Array:
            _, it, delta = carry
            return (it < max_iter) & (jnp.abs(delta) >= tol)

        def body(
            carry: tuple[EMState, jax.Array, jax.Array],
        ) -> tuple[EMState, jax.Array, jax.Array]:
            state, it, _ = carry
            if accelerate:
                state, info, used = squarem_step(state, hist)
            else:
                state, info = em_step(state, hist)
                used = 1
            delta = jnp.where(jnp.isfinite(info.delta), info.delta, 0.0)
            return state, it + used, delta

        return lax.while_loop(cond, body, (state0, jnp.array(0), jnp.array(jnp.inf)))

    return jax.vmap(run)(weights0, rates0)


@dataclasses.dataclass(frozen=True)
class MixtureEMResult:
    """Maximum-likelihood fit of the Poisson mixture of eq. (1) by EM.

    Attributes
    ----------
    weights : (n,) float64
        Mixture weights, permuted to match the sorted rates.
    rates : (n,) float64
        Poisson rates in increasing order.
    loglik : float
        Total log-likelihood over all marks (including ``-log k!``).
    n_iter : int
        EM updates (M-steps, counting the SQUAREM stabilising step) of the winning restart.
    converged : bool
        Whether the winning restart met the tolerance before ``max_iter``.
    bic : float
        ``-2 loglik + (2n - 1) log N`` with ``N`` the number of marks.
    restarts_logliks : (n_restarts,) float64
        Final total log-likelihood of every restart.
    n_marks : float
        Number of marks ``N`` (sum of the counts).
    n_distinct : int
        Number of distinct marks the iteration ran over.
    """

    weights: np.ndarray
    rates: np.ndarray
    loglik: float
    n_iter: int
    converged: bool
    bic: float
    restarts_logliks: np.ndarray
    n_marks: float
    n_distinct: int

    @property
    def n_components(self) -> int:
        """Number of components ``n``."""
        return int(self.rates.shape[0])

    @property
    def n_params(self) -> int:
        """Free parameters ``2n - 1``."""
        return 2 * self.n_components - 1

    @property
    def aic(self) -> float:
        """``-2 loglik + 2 (2n - 1)``."""
        return -2.0 * self.loglik + 2.0 * self.n_params

    def distribution(self) -> PoissonMixture:
        """The fitted law as a :class:`are_stats.traffic.PoissonMixture`."""
        w = self.weights / self.weights.sum()
        return PoissonMixture(w, self.rates)


def _bucket(m: int, minimum: int) -> int:
    """Padded length (power of two, at least ``minimum``) so that jit caches are reused."""
    return max(minimum, 1 << (m - 1).bit_length())


def _check_positive_int(name: str, x: object) -> int:
    if isinstance(x, bool) or not isinstance(x, int | np.integer) or x < 1:
        raise ValueError(f"{name}: expected an integer >= 1, got {x!r}")
    return int(x)


def _pad(hist: MarksHistogram) -> MarksHistogram:
    """Pad to the bucket length with zero-count entries (they do not change anything)."""
    m = hist.n_distinct
    pad = _bucket(m, 64) - m
    last = hist.values[-1]
    return MarksHistogram(
        values=jnp.asarray(np.concatenate([hist.values, np.full(pad, last)])),
        counts=jnp.asarray(np.concatenate([hist.counts, np.zeros(pad)])),
        log_factorial=jnp.asarray(
            np.concatenate([hist.log_factorial, np.full(pad, hist.log_factorial[-1])])
        ),
    )


def fit_mixture_em(
    marks: npt.ArrayLike,
    n_components: int,
    key: jax.Array | None = None,
    n_restarts: int = 16,
    tol: float = 1e-8,
    max_iter: int = 10_000,
    *,
    counts: npt.ArrayLike | None = None,
    accelerate: bool = True,
) -> MixtureEMResult:
    """Fit the Poisson mixture of eq. (1) by EM over the histogram of distinct marks.

    Parameters
    ----------
    marks : (N,) int
        Non-negative integer marks. With ``counts``: the values of a histogram.
    n_components : int
        Number of components ``n`` (at most the number of distinct marks).
    key : jax.Array, optional
        PRNG key for the random restarts (default ``jax.random.key(0)``).
    n_restarts : int
        Initialisations run side by side (restart 0: evenly spaced quantiles of the
        marks; odd restarts: k-means++ seeding; even: random quantiles; all with small
        multiplicative jitter and equal weights). The highest log-likelihood wins.
    tol : float
        Stop when the mean log-likelihood per mark changes by less than ``tol``.
    max_iter : int
        Cap on EM updates (M-steps) per restart.
    counts : (N,) float, optional
        Multiplicity of each entry of ``marks`` (a precomputed histogram or weights).
    accelerate : bool
        Iterate with :func:`squarem_step` (default) instead of plain :func:`em_step`. Both
        are monotone; SQUAREM reaches the maximum of poorly identified mixtures in far
        fewer updates and stops closer to it at the same ``tol``.

    Returns
    -------
    MixtureEMResult
        Weights, sorted rates, total log-likelihood, iterations, convergence flag, BIC.

    Raises
    ------
    ValueError
        On empty, negative or non-integer marks, bad counts, ``n_components < 1``, more
        components than distinct marks, or non-positive ``n_restarts``/``tol``/``max_iter``.

    Examples
    --------
    >>> import numpy as np
    >>> from are_stats import fit_mixture_em
    >>> rng = np.random.default_rng(0)
    >>> marks = np.concatenate([rng.poisson(2, 3000), rng.poisson(30, 1000)])
    >>> fit = fit_mixture_em(marks, 2)
    >>> np.round(fit.rates, 0).tolist()
    [2.0, 30.0]
    """
    n_components = _check_positive_int("n_components", n_components)
    n_restarts = _check_positive_int("n_restarts", n_restarts)
    max_iter = _check_positive_int("max_iter", max_iter)
    if not (isinstance(tol, int | float | np.floating) and np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol: expected a finite number > 0, got {tol!r}")
    hist = marks_histogram(marks, counts)
    if n_components > hist.n_distinct:
        raise ValueError(
            f"n_components: expected at most the number of distinct marks "
            f"({hist.n_distinct}), got {n_components}"
        )
    if key is None:
        key = random.key(0)
    states, iters, deltas = _fit_restarts(
        key,
        _pad(hist),
        jnp.asarray(float(tol)),
        jnp.asarray(n_components),
        n_slots=_bucket(n_components, 8),
        n_restarts=n_restarts,
        max_iter=max_iter,
        accelerate=bool(accelerate),
    )
    n = hist.n_marks
    mean_ll = np.asarray(states.mean_loglik)
    totals = np.where(np.isfinite(mean_ll), mean_ll * n, -np.inf)
    best = int(np.argmax(totals))
    rates = np.asarray(states.rates[best])[:n_components]
    weights = np.asarray(states.weights[best])[:n_components]
    order = np.argsort(rates, kind="stable")
    loglik = float(totals[best])
    p = 2 * n_components - 1
    return MixtureEMResult(
        weights=weights[order],
        rates=rates[order],
        loglik=loglik,
        n_iter=int(iters[best]),
        converged=bool(np.abs(np.asarray(deltas[best])) < tol),
        bic=-2.0 * loglik + p * float(np.log(n)),
        restarts_logliks=totals,
        n_marks=n,
        n_distinct=hist.n_distinct,
    )
