"""Bursts within the window: arrival rates that wander (MMPP) or excite themselves (Hawkes).

Two doubly stochastic event processes beside the Poisson, negative-binomial and
time-of-day ones (:mod:`are_stats.traffic._arrivals`); each event may bring a group.

* **MMPP** (Markov-modulated Poisson process, two rate states): a hidden state
  ``k(t) in {0, 1}`` switches ``0 -> 1`` at rate ``q01`` and ``1 -> 0`` at rate ``q10``
  (stationary law ``pi = (q10, q01) / (q01 + q10)``); events arrive at intensity
  ``lambda_k = rate * area * f_k`` with ``f_0 < f_1`` and ``pi . f = 1`` (``rate`` is the
  stationary mean rate, as for the other models). The index of dispersion of the counts
  in a window of length ``w`` is

  ``I(w) = 1 + 2 pi_0 pi_1 (lambda_1 - lambda_0)^2 / (Lambda q) [1 - (1 - e^{-q w}) / (q w)]``

  with ``q = q01 + q10`` and ``Lambda = pi . lambda`` (:func:`mmpp_count_dispersion`).
* **Hawkes** with an exponential kernel: intensity
  ``lambda(t) = mu + sum_{t_i < t} alpha beta e^{-beta (t - t_i)}``, branching ratio
  ``0 <= alpha < 1`` (mean offspring per event), decay ``beta``; the stationary rate is
  ``Lambda = mu / (1 - alpha)``. The compensator over an empty stretch of length ``u``
  after excitation ``A`` is ``mu u + A (1 - e^{-beta u}) / beta`` (exact), and ``A`` is
  carried from event to event by ``A <- A e^{-beta u} + alpha beta c`` (O(n)). The index
  of dispersion is ``I(w) = 1 + (1 / (1 - alpha)^2 - 1) [1 - (1 - e^{-g w}) / (g w)]``
  with ``g = beta (1 - alpha)``: ``1 / (1 - alpha)^2`` for long windows
  (:func:`hawkes_count_dispersion`).

**Likelihood of quantised arrivals.** A log's arrivals are counts ``c_j`` per tick of
width ``delta`` (its time resolution; :class:`~are_stats.traffic.ArrivalUnits`). The
forward recursion walks the non-empty ticks in time order, with the ends of the LOO bins
as extra steps (:class:`BurstSteps`): each step covers the empty time since the previous
one, then its tick. The MMPP holds its state over a non-empty tick (the count is
``Poisson(lambda_k delta)``, or the compound-Poisson sum over group counts, then the state
may switch: ``expm(Q delta)``), so that every factor is a probability of the quantised
data; the Hawkes process scores the count at the intensity reached at the tick's end
(``c log(lambda delta) - log c!``) and the exact compensator over the tick. With equal
rates (MMPP) or ``alpha = 0`` (Hawkes) it is the Poisson
tick likelihood exactly. The MMPP transfer over a stretch ``u`` is ``expm((Q - Lambda) u)``
in closed form (a 2 x 2 matrix with real eigenvalues), in scaled (normalised) form so that
long windows neither underflow nor overflow. The recursion starts from the stationary
law (MMPP: ``pi``; Hawkes: the stationary mean excitation ``A = mu alpha / (1 - alpha)``,
an approximation: the history before the window is not seen).

**Pointwise terms.** The bins are not exchangeable (a busy bin predicts a busy next bin),
so the pointwise term of bin ``b`` is the one-step-ahead predictive
``log p(bin_b | bins < b)``; they sum to the log-likelihood. PSIS-LOO over them is
leave-future-out-style and approximate (see ``docs/src/models.md``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax.scipy.special import gammaln, logsumexp

from are_stats._checks import check_finite, check_positive
from are_stats.traffic._arrivals import DAY, period_of

__all__ = [
    "BurstSteps",
    "burst_steps",
    "group_count_dispersion",
    "hawkes_count_dispersion",
    "hawkes_step_loglik",
    "mmpp_count_dispersion",
    "mmpp_factors",
    "mmpp_step_loglik",
    "mmpp_transfer",
    "sample_hawkes_times",
    "sample_mmpp_times",
]


class BurstSteps(NamedTuple):
    """The steps of the forward recursion over a window's quantised arrivals (a pytree).

    Attributes
    ----------
    gap : (S,) float
        Time the step covers: the empty time since the previous step plus, for a tick, its
        width.
    count : (S,) float
        Artefacts arriving in the step's tick (0 for a bin's end).
    tick : (S,) int
        Row of the tick in :class:`~are_stats.traffic.ArrivalUnits` (``-1``: a bin's end).
    bin : (S,) int
        Bin the step belongs to.
    weight : (S,) float
        1 for real steps, 0 for padding.
    period : (S,) int
        Period of the day the step lies in (0 without a clock). With a clock the
        boundaries of the periods are steps of their own (``tick = -1``, ``count = 0``),
        so that a step never crosses one (but a tick that straddles a boundary is held at
        the period of its midpoint, as in the time-of-day model).
    """

    gap: npt.ArrayLike
    count: npt.ArrayLike
    tick: npt.ArrayLike
    bin: npt.ArrayLike
    weight: npt.ArrayLike
    period: npt.ArrayLike | None = None


def burst_steps(
    tick: np.ndarray,
    tick_count: np.ndarray,
    tick_bin: np.ndarray,
    window: tuple[float, float],
    delta: float,
    bin_width: float,
    size: int,
    clock: tuple[float, int, float] | None = None,
) -> BurstSteps:
    """Order the non-empty ticks and the ends of the bins in time (see :class:`BurstSteps`).

    Parameters
    ----------
    tick : (m,) int
        Index of each non-empty tick (``floor((t - t0) / delta)``), increasing.
    tick_count : (m,) float
    tick_bin : (m,) int
    window : (t0, t1)
    delta : float
        Tick width.
    bin_width : float
    size : int
        Padded length (at least ``m + B``, plus the boundaries of the periods with a clock).
    clock : (offset, n_periods, period), optional
        Time of day of ``t = 0`` (log time), periods per day and the day's length: the
        boundaries of the periods inside the window become steps, and each step gets its
        period.

    Returns
    -------
    BurstSteps
    """
    t0, t1 = float(window[0]), float(window[1])
    n_bins = max(1, int(np.ceil((t1 - t0) / bin_width - 1e-9)))
    m = tick.size
    t_start = tick * delta  # window time
    t_end = t_start + delta
    b_end = np.minimum(bin_width * np.arange(1, n_bins + 1), t1 - t0)
    cuts = np.zeros(0)
    if clock is not None:
        offset, n_periods, day = float(clock[0]), int(clock[1]), float(clock[2])
        width = day / n_periods
        k0 = np.floor((t0 + offset) / width) + 1
        k1 = np.ceil((t1 + offset) / width) - 1
        cuts = np.arange(k0, k1 + 1) * width - offset - t0  # window time, inside (0, T)
        cuts = cuts[(cuts > 0.0) & (cuts < t1 - t0)]
    n_cut = cuts.size
    cut_bin = np.minimum(np.floor(cuts / bin_width + 1e-12).astype(np.int64), n_bins - 1)
    # time order: the ticks and boundaries of bin b (a boundary before a tick at the same
    # time), then the end of bin b
    kind = np.concatenate(
        [np.zeros(m, np.int64), np.ones(n_bins, np.int64), np.zeros(n_cut, np.int64)]
    )
    tie = np.concatenate([np.ones(m), np.ones(n_bins), np.zeros(n_cut)])
    bins = np.concatenate([np.asarray(tick_bin, np.int64), np.arange(n_bins), cut_bin])
    start = np.concatenate([t_start, b_end, cuts])
    end = np.concatenate([t_end, b_end, cuts])
    order = np.lexsort((tie, start, kind, bins))
    start, end, kind, bins = start[order], end[order], kind[order], bins[order]
    is_tick = np.concatenate([np.ones(m, bool), np.zeros(n_bins + n_cut, bool)])[order]
    prev_end = np.maximum.accumulate(np.concatenate([[0.0], end[:-1]]))
    gap = np.where(
        is_tick, np.maximum(start - prev_end, 0.0) + delta, np.maximum(end - prev_end, 0.0)
    )
    count = np.concatenate([np.asarray(tick_count, float), np.zeros(n_bins + n_cut)])[order]
    rows = np.concatenate([np.arange(m), np.full(n_bins + n_cut, -1)])[order]
    if clock is None:
        per = np.zeros(gap.size, np.int64)
    else:
        # a step spans [end - gap, end]: no boundary inside it (they are steps), but for a
        # tick straddling one; its midpoint names its period
        per = period_of(t0 + end - 0.5 * gap, offset, n_periods, day)
    s = gap.size
    size = int(size) if s <= int(size) else 1 << int(np.ceil(np.log2(s)))

    def pad(a: np.ndarray, fill: npt.ArrayLike, dtype: npt.DTypeLike) -> np.ndarray:
        out = np.full(size, fill, dtype)
        out[:s] = a
        return out

    return BurstSteps(
        gap=pad(gap, 0.0, float),
        count=pad(count, 0.0, float),
        tick=pad(rows, -1, np.int64),
        bin=pad(bins, 0, np.int64),
        weight=pad(np.ones(s), 0.0, float),
        period=pad(per, 0, np.int64),
    )


def mmpp_factors(contrast: npt.ArrayLike, switch: npt.ArrayLike) -> jnp.ndarray:
    """Rate factors ``f = (f_0, f_1)`` with ``f_1 / f_0 = e^contrast`` and ``pi . f = 1``.

    Parameters
    ----------
    contrast : float
        ``log(f_1 / f_0) >= 0``.
    switch : (2,) float
        Switching rates ``(q01, q10)``.

    Returns
    -------
    (2,) float
    """
    q01, q10 = switch[0], switch[1]
    pi1 = q01 / (q01 + q10)
    f0 = 1.0 / (1.0 - pi1 + pi1 * jnp.exp(contrast))
    return jnp.stack([f0, f0 * jnp.exp(contrast)])


def mmpp_transfer(
    lam: npt.ArrayLike, switch: npt.ArrayLike, u: npt.ArrayLike
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """``expm((Q - diag(lam)) u)`` of a two-state MMPP, in closed form and scaled.

    Parameters
    ----------
    lam : (2,) float
        Event intensities of the two states.
    switch : (2,) float
        Switching rates ``(q01, q10)``.
    u : float
        Length of the stretch (no events in it).

    Returns
    -------
    log_scale : float
    mat : (2, 2) float
        ``expm((Q - diag(lam)) u) = exp(log_scale) * mat`` (entries of ``mat`` in [0, 1]).
    """
    q01, q10 = switch[0], switch[1]
    a = -q01 - lam[0]
    d = -q10 - lam[1]
    s = 0.5 * (a + d)
    h = 0.5 * (a - d)
    r = jnp.sqrt(h * h + q01 * q10)
    x = jnp.exp(-2.0 * r * u)
    y = jnp.where(r * u > 1e-12, -jnp.expm1(-2.0 * r * u) / (2.0 * r), u)
    diag = 0.5 * (1.0 + x)
    mat = jnp.array([[diag + y * h, y * q01], [y * q10, diag - y * h]])
    return (s + r) * u, mat


def _log_tick_terms(
    log_lam_delta: jnp.ndarray, count: jnp.ndarray, conv: npt.ArrayLike
) -> jnp.ndarray:
    """``log P(count | state)`` without ``e^{-lambda delta}``: ``(S, K)`` for ``(K,)`` or
    ``(S, K)`` rates (per state, or per step and state).

    Plain: ``c log(lambda delta) - log c!``; with ``conv`` (``log p^{*j}(c)``, rows
    ``j = 1..J``): ``log sum_j (lambda delta)^j / j! p^{*j}(c)``; zero where ``c = 0``.
    """
    c = count[:, None]
    lld = log_lam_delta if log_lam_delta.ndim == 2 else log_lam_delta[None, :]
    if conv is None:
        out = c * lld - gammaln(c + 1.0)
    else:
        j_max = conv.shape[0]
        j = jnp.arange(1, j_max + 1, dtype=lld.dtype)
        ci = jnp.clip(count.astype(jnp.int32), 0, conv.shape[1] - 1)
        pc = conv[:, ci].T  # (S, J)
        terms = (
            j[None, None, :] * lld[:, :, None] - gammaln(j + 1.0)[None, None, :] + pc[:, None, :]
        )
        out = logsumexp(terms, axis=-1)
    return jnp.where(c > 0, out, 0.0)


def mmpp_step_loglik(
    lam: npt.ArrayLike,
    switch: npt.ArrayLike,
    log_delta: npt.ArrayLike,
    steps: BurstSteps,
    n_bins: int,
    conv: npt.ArrayLike | None = None,
    tod: npt.ArrayLike | None = None,
) -> jnp.ndarray:
    """Log-likelihood of each bin given the earlier bins, under a two-state MMPP.

    Parameters
    ----------
    lam : (2,) float
        Event intensities of the states (events per time over the whole area).
    switch : (2,) float
        Switching rates ``(q01, q10)``.
    log_delta : float
        ``log`` of the tick width.
    steps : BurstSteps
    n_bins : int
    conv : (J, C + 1) float, optional
        ``log p^{*j}(c)`` of the group-size law (compound counts); None: one per event.
    tod : (P,) float, optional
        Time-of-day factors: in period ``p`` both intensities are ``lam * tod[p]`` (the
        steps' ``period``; the boundaries of the periods are steps, so each transfer is
        exact).

    Returns
    -------
    (n_bins,) float
        ``log p(bin_b | bins < b)``; they sum to the log-likelihood of the window.
    """
    lam = jnp.asarray(lam)
    n_steps = steps.gap.shape[0]
    if tod is None:
        lam_s = jnp.broadcast_to(lam, (n_steps, 2))
    else:
        lam_s = lam[None, :] * jnp.asarray(tod)[steps.period][:, None]  # (S, 2)
    q01, q10 = switch[0], switch[1]
    pi = jnp.stack([q10, q01]) / (q01 + q10)
    is_tick = (steps.tick >= 0).astype(lam.dtype)
    delta = jnp.exp(log_delta)
    # every step's factors at once; the recursion only multiplies. A step is the empty
    # stretch before it, expm((Q - Lambda) u), then its tick with the state held over the
    # tick: P(c | k) = Poisson(c; lambda_k delta), then the switches over the tick,
    # expm(Q delta) = 1 pi + e^{-q delta} (I - 1 pi). Each factor is a probability.
    log_d = _log_tick_terms(jnp.log(lam_s) + log_delta, steps.count, conv)  # (S, 2)
    log_d = log_d - is_tick[:, None] * lam_s * delta
    empty = jnp.maximum(steps.gap - is_tick * delta, 0.0)
    log_scale, mat = jax.vmap(lambda la, u: mmpp_transfer(la, switch, u))(lam_s, empty)
    d_max = jnp.max(log_d, axis=1)
    mat = mat * jnp.exp(log_d - d_max[:, None])[:, None, :]  # T(u) diag(P(c | k)) / max
    keep = jnp.exp(-(q01 + q10) * delta * is_tick)[:, None, None]
    switched = keep * jnp.eye(2)[None] + (1.0 - keep) * jnp.ones((2, 1)) * pi[None, None, :]
    mat = mat @ switched
    log_scale = log_scale + d_max

    def body(alpha, xs):
        m, w = xs
        v = alpha @ m
        z = jnp.sum(v)
        return jnp.where(w > 0, v / z, alpha), jnp.where(w > 0, jnp.log(z), 0.0)

    _, log_z = jax.lax.scan(body, pi, (mat, steps.weight))
    inc = jnp.where(steps.weight > 0, log_scale + log_z, 0.0)
    return jax.ops.segment_sum(inc, steps.bin, num_segments=n_bins)


def hawkes_step_loglik(
    mu: npt.ArrayLike,
    alpha: npt.ArrayLike,
    beta: npt.ArrayLike,
    log_delta: npt.ArrayLike,
    steps: BurstSteps,
    n_bins: int,
    excitation0: npt.ArrayLike | None = None,
    conv: npt.ArrayLike | None = None,
    tod: npt.ArrayLike | None = None,
) -> jnp.ndarray:
    """Log-likelihood of each bin given the earlier bins, under an exponential Hawkes process.

    Parameters
    ----------
    mu : float
        Baseline intensity (events per time over the whole area).
    alpha, beta : float
        Branching ratio and decay.
    log_delta : float
    steps : BurstSteps
    n_bins : int
    excitation0 : float, optional
        Excitation ``A`` at the window's start (default the stationary mean
        ``mu alpha / (1 - alpha)``).
    conv : (J, C + 1) float, optional
        ``log p^{*j}(c)`` of the group-size law: the events are groups, a tick's count is
        compound Poisson at the intensity reached at the tick's end, and the excitation
        jumps by ``alpha beta E[j | c]``, the expected number of groups that brought the
        count (exactly ``1`` for ``c = 1``; the events within one tick are not told
        apart). None: one artefact per event.
    tod : (P,) float, optional
        Time-of-day factors of the baseline: ``mu tod[p]`` in period ``p`` (the steps'
        ``period``; the boundaries of the periods are steps, so the compensator is exact).

    Returns
    -------
    (n_bins,) float
        ``log p(bin_b | bins < b)``: the tick terms minus the exact compensator over the bin.
    """
    a0 = mu * alpha / (1.0 - alpha) if excitation0 is None else excitation0
    u, c, w = steps.gap, steps.count, steps.weight
    base = mu if tod is None else mu * jnp.asarray(tod)[steps.period]  # scalar or (S,)
    base = jnp.broadcast_to(base, u.shape)
    decay = jnp.exp(-beta * u)
    spent = -jnp.expm1(-beta * u) / beta  # integral of e^{-beta s} over the stretch
    if conv is None:
        pcs = jnp.zeros((u.shape[0], 1))
        j = None
    else:
        ci = jnp.clip(c.astype(jnp.int32), 0, conv.shape[1] - 1)
        pcs = conv[:, ci].T  # (S, J): log p^{*j}(c) of each step's count
        j = jnp.arange(1, conv.shape[0] + 1, dtype=pcs.dtype)

    def body(a, xs):  # excitation at the step's start -> its end, after the tick's events
        d, sp, ci_, wt, b, pc = xs
        a_end = a * d
        log_lam = jnp.log(b + a_end) + log_delta
        if conv is None:
            tick, n_ev = ci_ * log_lam - gammaln(ci_ + 1.0), ci_
        else:  # log sum_j (lambda delta)^j / j! p^{*j}(c), and E[j | c]
            terms = j * log_lam - gammaln(j + 1.0) + pc
            tick = logsumexp(terms)
            n_ev = jnp.sum(j * jnp.exp(terms - tick))
        tick = jnp.where(ci_ > 0, tick, 0.0)
        n_ev = jnp.where(ci_ > 0, n_ev, 0.0)
        return jnp.where(wt > 0, a_end + alpha * beta * n_ev, a), (a * sp, tick)

    xs = (decay, spent, c, w, base, pcs)
    _, (excited, tick_ll) = jax.lax.scan(body, jnp.asarray(a0, float), xs)
    ll = tick_ll - base * u - excited
    return jax.ops.segment_sum(jnp.where(w > 0, ll, 0.0), steps.bin, num_segments=n_bins)


def mmpp_count_dispersion(
    lam: npt.ArrayLike, switch: npt.ArrayLike, w: npt.ArrayLike
) -> np.ndarray:
    """Stationary variance over mean of the number of events in a window of length ``w``.

    Parameters
    ----------
    lam : (2,) float
        Event intensities of the two states.
    switch : (2,) float
        ``(q01, q10)``.
    w : float or array
        Window lengths.

    Returns
    -------
    ndarray shaped like ``w``
    """
    lam = check_positive("lam", lam, ndim=1)
    q01, q10 = (float(v) for v in check_positive("switch", switch, ndim=1))
    w = np.asarray(check_positive("w", w), float)
    q = q01 + q10
    pi = np.array([q10, q01]) / q
    mean = float(pi @ lam)
    var_rate = pi[0] * pi[1] * float(lam[1] - lam[0]) ** 2
    return 1.0 + 2.0 * var_rate / (mean * q) * (1.0 - (-np.expm1(-q * w)) / (q * w))


def hawkes_count_dispersion(alpha: float, beta: float, w: npt.ArrayLike) -> np.ndarray:
    """Stationary variance over mean of the number of events in a window of length ``w``
    (exponential Hawkes; ``1 / (1 - alpha)^2`` as ``w`` grows)."""
    alpha = float(alpha)
    if not 0.0 <= alpha < 1.0:
        raise ValueError(f"alpha: expected a branching ratio in [0, 1), got {alpha}")
    beta = float(check_positive("beta", beta))
    w = np.asarray(check_positive("w", w), float)
    g = beta * (1.0 - alpha)
    return 1.0 + (1.0 / (1.0 - alpha) ** 2 - 1.0) * (1.0 - (-np.expm1(-g * w)) / (g * w))


def _thin(
    rng: np.random.Generator, t: np.ndarray, tod: npt.ArrayLike, offset: float, period: float
) -> np.ndarray:
    """Keep each time with probability ``tod[p(t)] / max(tod)`` (exact thinning)."""
    f = np.asarray(tod, float)
    keep = rng.random(t.size) * f.max() < f[period_of(t, offset, f.size, period)]
    return t[keep]


def group_count_dispersion(
    event_dispersion: npt.ArrayLike, size_probs: npt.ArrayLike
) -> np.ndarray:
    """Variance over mean of the artefacts' counts when each event brings a group.

    For i.i.d. group sizes ``S`` independent of the events' counts ``J`` (any process),
    ``Var N = E[J] Var S + Var J E[S]^2`` and ``E N = E[J] E[S]``, so

    ``I_N = E[S^2] / E[S] + E[S] (I_J - 1)``.

    Parameters
    ----------
    event_dispersion : float or array
        ``I_J``, e.g. :func:`hawkes_count_dispersion` or :func:`mmpp_count_dispersion`.
    size_probs : (K,) float
        Probabilities of group sizes ``1 .. K``.

    Returns
    -------
    ndarray shaped like ``event_dispersion``
    """
    p = np.asarray(check_finite("size_probs", size_probs, ndim=1), float)
    p = p / p.sum()
    k = np.arange(1, p.size + 1)
    m1, m2 = float(p @ k), float(p @ k**2)
    return m2 / m1 + m1 * (np.asarray(event_dispersion, float) - 1.0)


def sample_mmpp_times(
    rng: np.random.Generator,
    lam: npt.ArrayLike,
    switch: npt.ArrayLike,
    window: npt.ArrayLike,
    state0: int | None = None,
    *,
    tod: npt.ArrayLike | None = None,
    offset: float = 0.0,
    period: float = DAY,
) -> np.ndarray:
    """Event times of a two-state MMPP over ``window`` (exact: Poisson within each sojourn;
    with ``tod``, intensities ``lam * tod[p(t)]`` by thinning).

    Parameters
    ----------
    rng : numpy.random.Generator
    lam : (2,) float
        Intensities of the states.
    switch : (2,) float
        ``(q01, q10)``.
    window : (t0, t1)
    state0 : int, optional
        State at ``t0`` (default drawn from the stationary law).
    tod : (P,) float, optional
        Time-of-day factors (mean 1 over the day).
    offset, period : float
        Time of day of ``t = 0`` and the length of a day.

    Returns
    -------
    (n,) float
        Sorted.
    """
    lam = np.asarray(check_finite("lam", lam, ndim=1), float)
    if tod is not None:
        f = check_positive("tod", tod, ndim=1)
        t = sample_mmpp_times(rng, lam * float(f.max()), switch, window, state0)
        return _thin(rng, t, f, float(offset), float(period))
    q = check_positive("switch", switch, ndim=1)
    t0, t1 = (float(v) for v in check_finite("window", window, ndim=1))
    if state0 is None:
        state0 = int(rng.random() < q[0] / (q[0] + q[1]))
    # sojourns alternate; draw them in blocks until the window is covered
    mean_cycle = 1.0 / q[0] + 1.0 / q[1]
    k = int(np.ceil((t1 - t0) / mean_cycle)) * 2 + 8
    ends = np.zeros(0)
    while True:
        states = (state0 + np.arange(k)) % 2
        soj = rng.exponential(1.0 / q[states])
        ends = t0 + np.cumsum(soj)
        if ends[-1] >= t1:
            break
        k *= 2
    n_seg = int(np.searchsorted(ends, t1)) + 1
    states = (state0 + np.arange(n_seg)) % 2
    starts = np.concatenate([[t0], ends[: n_seg - 1]])
    stops = np.minimum(ends[:n_seg], t1)
    counts = rng.poisson(lam[states] * (stops - starts))
    t = np.repeat(starts, counts) + rng.random(int(counts.sum())) * np.repeat(
        stops - starts, counts
    )
    return np.sort(t)


def sample_hawkes_times(
    rng: np.random.Generator,
    mu: float,
    alpha: float,
    beta: float,
    window: npt.ArrayLike,
    burn: float = 0.0,
    *,
    tod: npt.ArrayLike | None = None,
    offset: float = 0.0,
    period: float = DAY,
) -> np.ndarray:
    """Event times of an exponential Hawkes process over ``window`` (the cluster process).

    Immigrants arrive as a Poisson process of rate ``mu`` (``mu tod[p(t)]`` with ``tod``,
    by thinning) from ``t0 - burn``; each event has ``Poisson(alpha)`` children at
    ``Exp(beta)`` delays, generation by generation. With ``burn`` a few times
    ``1 / (beta (1 - alpha))`` the window starts near stationarity.

    Returns
    -------
    (n,) float
        Sorted times inside ``[t0, t1)``.
    """
    t0, t1 = (float(v) for v in check_finite("window", window, ndim=1))
    if not 0.0 <= float(alpha) < 1.0:
        raise ValueError(f"alpha: expected a branching ratio in [0, 1), got {alpha}")
    start = t0 - float(burn)
    f_max = 1.0 if tod is None else float(check_positive("tod", tod, ndim=1).max())
    n = rng.poisson(float(mu) * f_max * (t1 - start))
    gen = start + rng.random(n) * (t1 - start)
    if tod is not None:
        gen = _thin(rng, gen, tod, float(offset), float(period))
    out = [gen]
    while gen.size:
        kids = rng.poisson(float(alpha), gen.size)
        gen = np.repeat(gen, kids) + rng.exponential(1.0 / float(beta), int(kids.sum()))
        gen = gen[gen < t1]
        out.append(gen)
    t = np.concatenate(out)
    return np.sort(t[t >= t0])
