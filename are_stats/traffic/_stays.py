"""How long artefacts stay: the lifetime laws beside the paper's exponential.

The paper draws each artefact's stay from an exponential law of rate ``mu`` (Sect. 3.2).
Field stays are crossing times, far more regular than that (coefficient of variation
0.3-0.8, few very short stays), so the toolkit offers four laws, all parameterised by the
**mean stay** ``m`` and one **shape** ``k`` (unused by the exponential), which keeps a
posterior on the scale of the data whether a log is in seconds or in days:

============  ==========================================  ===========================
law           density                                     shape ``k``
============  ==========================================  ===========================
exponential   ``e^{-t/m} / m``                            (none; cv = 1)
gamma         ``Gamma(k, rate = k/m)``                    cv = ``1/sqrt(k)``
weibull       ``Weibull(k, scale = m / Gamma(1 + 1/k))``  k = 1 is the exponential
lognormal     ``LogNormal(log m - s^2/2, s)``, ``s = k``  cv = ``sqrt(e^{s^2} - 1)``
============  ==========================================  ===========================

Observation window (DECISIONS 3). A field log sees a window ``[t0, t1]``; each artefact
contributes one of four terms to the likelihood:

* arrived and left inside the window, stay ``d``: ``log f(d)``; a stay recorded as zero
  (shorter than the log's time resolution ``delta``, a single sighting) is
  interval-censored: ``log F(delta)``;
* arrived inside, still there at ``t1`` (right-censored at ``d``): ``log S(d)``;
* already there at ``t0`` (left-truncated, arrival unknown) and left ``r`` after ``t0``:
  in a stationary M/G/inf process the residual stay of an artefact present at a fixed time
  has the *equilibrium* density ``S(r) / m`` (renewal theory), so ``log S(r) - log m``;
* there for the whole window (truncated and censored, ``r = t1 - t0``): the equilibrium
  survival ``E[(T - r)^+] / m``, in closed form for every law (:func:`stay_log_excess`).

For the exponential law the last two reduce to the memoryless terms the paper's model uses
(``log mu - mu r`` and ``-mu r``). The stationary count of an M/G/inf process is
``Poisson(lambda * area * m)`` whatever the law (insensitivity), which the tests use as truth.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax.scipy.special import gammaln, log_ndtr, ndtr, xlogy
from scipy.special import gammaln as sgammaln

from are_stats._checks import check_in

__all__ = [
    "STAY_LAWS",
    "stay_cv",
    "stay_draws",
    "stay_log_excess",
    "stay_logcdf",
    "stay_loglik",
    "stay_logpdf",
    "stay_logsf",
    "stay_sample",
    "stay_sample_residual",
    "stay_shape_from_cv",
]

#: Lifetime laws, simplest first (the paper's exponential is the first).
STAY_LAWS = ("exponential", "gamma", "weibull", "lognormal")

_TINY = float(np.finfo(np.float64).tiny)


def _law(law: str) -> str:
    return check_in("law", law, STAY_LAWS)


def _log(x: npt.ArrayLike) -> jnp.ndarray:
    return jnp.log(jnp.maximum(x, _TINY))


#: Relative step of the central difference that gives the incomplete gammas' derivative in
#: their first argument (float64: truncation and rounding errors both near 1e-10).
_SHAPE_STEP = 1e-5
#: Most continued-fraction steps of an incomplete gamma (as JAX's).
_MAX_FRACTION_STEPS = 2000


# jitted: called outside a trace (stay_logsf on host arrays, scipy's quad in tests), the
# while loop's closures are new on every call, so an unjitted call traced and compiled
# its loop each time (0.16 s a call instead of JAX's primitive's 8 ms); inside a trace
# it is inlined (inline=True), so a program holds one loop per call, as before.
@functools.partial(jax.jit, inline=True)
def _incomplete_gamma(a: npt.ArrayLike, x: npt.ArrayLike, lower: npt.ArrayLike) -> jnp.ndarray:
    """``P(a, x)`` where ``lower``, else ``Q(a, x)``: JAX's algorithms in ONE loop.

    :func:`jax.scipy.special.gammainc` and ``gammaincc`` each compile two loops (a power
    series for ``P`` and a continued fraction for ``Q``, the one not needed masked off),
    and each loop carries the derivative's terms too; XLA's default optimisation of the
    gamma stay law's Laplace program spent most of its 4-5 s of CPU on six such loops.
    Here each element runs the series or the continued fraction in one shared loop, by
    the same recurrences, tests and limits as JAX (the series where ``x < 1`` or
    ``x < a`` for ``Q``, where not ``x >= 1`` and ``x > a`` for ``P``; the other tail
    as ``1 -`` the computed one; at most :data:`_MAX_FRACTION_STEPS` fraction steps), so
    the values are JAX's to the last bit or one rounding (tested against JAX and SciPy).

    Parameters
    ----------
    a, x : (...) float
        Shape (>= 0) and argument (>= 0), broadcast together.
    lower : (...) bool
        Where to return ``P`` (else ``Q``).

    Returns
    -------
    (...) float
        NaN outside the domain (``a < 0``, ``x < 0``, ``a = x = 0``, NaN).
    """
    a, x, lower = jnp.broadcast_arrays(
        jnp.asarray(a, float), jnp.asarray(x, float), jnp.asarray(lower, bool)
    )
    eps = float(jnp.finfo(a.dtype).eps)
    a_zero, x_zero, x_inf = a == 0, x == 0, x == jnp.inf
    domain = (x < 0) | (a < 0) | (a_zero & x_zero) | jnp.isnan(a) | jnp.isnan(x)
    series = jnp.where(lower, ~((x >= 1) & (x > a)), (x < 1) | (x < a))
    ax = a * jnp.log(x) - x - gammaln(a)
    underflow = ax < -float(np.log(jnp.finfo(a.dtype).max))
    ax = jnp.exp(ax)
    enabled = ~(domain | underflow | x_inf | jnp.where(lower, x_zero, a_zero))
    y = 1.0 - a  # the continued fraction's start (Cephes' igamc, as JAX)
    z = x + y + 1.0
    one = jnp.ones_like(a)
    state = (
        jnp.zeros((), a.dtype),  # continued-fraction steps taken
        enabled & series,  # series running
        a,  # its r
        one,  # its term c
        one,  # its sum
        enabled & ~series,  # fraction running
        (x + 1.0) / (z * x),  # its value
        y,
        z,
        x + 1.0,  # p_{k-1}
        z * x,  # q_{k-1}
        one,  # p_{k-2}
        x,  # q_{k-2}
    )

    def more(v: tuple) -> jnp.ndarray:
        return jnp.any(v[1]) | (jnp.any(v[5]) & (v[0] < _MAX_FRACTION_STEPS))

    def step(v: tuple) -> tuple:
        c, s_on, r, term, total, f_on, ans, y, z, pkm1, qkm1, pkm2, qkm2 = v
        r1 = r + 1.0
        term1 = term * (x / r1)
        total1 = total + term1
        s_next = s_on & (term1 / total1 > eps)
        f_on = f_on & (c < _MAX_FRACTION_STEPS)
        c = c + 1.0
        y1, z1 = y + 1.0, z + 2.0
        yc = y1 * c
        pk = pkm1 * z1 - pkm2 * yc
        qk = qkm1 * z1 - qkm2 * yc
        nonzero = qk != 0
        ratio = pk / qk
        t = jnp.where(nonzero, jnp.abs((ans - ratio) / ratio), 1.0)
        rescale = jnp.abs(pk) > 1.0 / eps
        f_next = f_on & (t > eps)

        def keep(on: jnp.ndarray, new: jnp.ndarray, old: jnp.ndarray) -> jnp.ndarray:
            return jnp.where(on, new, old)

        return (
            c,
            s_next,
            keep(s_on, r1, r),
            keep(s_on, term1, term),
            keep(s_on, total1, total),
            f_next,
            keep(f_on & nonzero, ratio, ans),
            keep(f_on, y1, y),
            keep(f_on, z1, z),
            keep(f_on, jnp.where(rescale, pk * eps, pk), pkm1),
            keep(f_on, jnp.where(rescale, qk * eps, qk), qkm1),
            keep(f_on, jnp.where(rescale, pkm1 * eps, pkm1), pkm2),
            keep(f_on, jnp.where(rescale, qkm1 * eps, qkm1), qkm2),
        )

    v = jax.lax.while_loop(more, step, state)
    p = (v[4] * ax) / a
    q = v[6] * ax
    out = jnp.where(series, jnp.where(lower, p, 1.0 - p), jnp.where(lower, 1.0 - q, q))
    out = jnp.where(
        lower,
        jnp.where(x_zero, 0.0, jnp.where(x_inf, 1.0, out)),
        jnp.where(x_inf | a_zero, 0.0, out),
    )
    return jnp.where(domain, jnp.nan, out)


def _dq_dx(a: npt.ArrayLike, x: npt.ArrayLike) -> jnp.ndarray:
    """``d Q(a, x) / d x = -x^(a-1) e^-x / Gamma(a)`` (closed form)."""
    return -jnp.exp(xlogy(a - 1.0, x) - x - gammaln(a))


@jax.custom_jvp
def incomplete_gamma(a: npt.ArrayLike, x: npt.ArrayLike, lower: npt.ArrayLike) -> jnp.ndarray:
    """Regularised incomplete gamma: ``P(a, x)`` where ``lower``, else ``Q(a, x)``.

    The values of :func:`jax.scipy.special.gammainc` / ``gammaincc`` in one loop (see
    :func:`_incomplete_gamma`); several tails of one likelihood in one call are one loop
    for XLA to compile. Its derivative in ``a`` is a central difference (one evaluation
    at ``a - h, a, a + h``) instead of JAX's own, whose series XLA compiles for a minute
    or more (it was most of a NUTS fit's compile time, and XLA's "very slow compile" alarm
    pointed at it). NUTS stays exact with it: the leapfrog is reversible and keeps volume
    whatever the force, and the accept step uses the values. In ``x`` it is closed form.

    Parameters
    ----------
    a, x : (...) float
    lower : (...) bool

    Returns
    -------
    (...) float
    """
    return _incomplete_gamma_padded(a, x, lower)


def _incomplete_gamma_padded(
    a: npt.ArrayLike, x: npt.ArrayLike, lower: npt.ArrayLike
) -> jnp.ndarray:
    """:func:`_incomplete_gamma`; on concrete inputs of one shape (scalars aside), the
    arrays flattened and padded to a power of two (at least 8) so that calls of nearby
    sizes share one compiled program (issue 25).

    Scalars stay scalars (broadcast in the program, as before: broadcasting them first
    moved some values by one rounding). The padding is ``NaN`` (``a``, ``x``: outside the
    domain, their loop is off) or ``False``; each entry's loop stops on its own tests and
    then keeps its values, so the real entries' values are those of an unpadded call, bit
    for bit. Inside a trace, with partly broadcast shapes or one entry (XLA compiles a
    one-entry call as scalar code: one rounding apart from the vector loop), the call is as
    before.
    """
    if any(isinstance(v, jax.core.Tracer) for v in (a, x, lower)):
        return _incomplete_gamma(a, x, lower)
    args = (np.asarray(a, float), np.asarray(x, float), np.asarray(lower, bool))
    shape = np.broadcast_shapes(*(v.shape for v in args))
    n = int(np.prod(shape))
    if n < 2 or any(v.ndim and v.shape != shape for v in args):
        return _incomplete_gamma(a, x, lower)
    size = max(8, 1 << (n - 1).bit_length())

    def pad(v: np.ndarray, fill: float | bool) -> np.ndarray:
        if not v.ndim:
            return v
        out = np.full(size, fill, v.dtype)
        out[:n] = v.ravel()
        return out

    a_pad, x_pad = pad(args[0], np.nan), pad(args[1], np.nan)
    out = np.asarray(_incomplete_gamma(a_pad, x_pad, pad(args[2], False)))[:n]
    return jax.device_put(out.reshape(shape))  # jnp.asarray compiled a "stage" per shape


@incomplete_gamma.defjvp
def _incomplete_gamma_jvp(primals: tuple, tangents: tuple) -> tuple:
    a, x, lower = primals
    da, dx, _ = tangents
    a, x, lower = jnp.broadcast_arrays(
        jnp.asarray(a, float), jnp.asarray(x, float), jnp.asarray(lower, bool)
    )
    h = _SHAPE_STEP * jnp.maximum(a, 1.0)
    v = _incomplete_gamma(
        jnp.stack([a - h, a, a + h]), jnp.stack([x, x, x]), jnp.stack([lower, lower, lower])
    )
    dv_da = (v[2] - v[0]) / (2.0 * h)
    dq_dx = _dq_dx(a, x)
    return v[1], dv_da * da + jnp.where(lower, -dq_dx, dq_dx) * dx


def gammaincc(a: npt.ArrayLike, x: npt.ArrayLike) -> jnp.ndarray:
    """Regularised upper incomplete gamma ``Q(a, x)``, as :func:`jax.scipy.special.gammaincc`
    (:func:`incomplete_gamma`: one loop, a central difference in ``a``)."""
    return incomplete_gamma(a, x, False)


def gammainc(a: npt.ArrayLike, x: npt.ArrayLike) -> jnp.ndarray:
    """Regularised lower incomplete gamma ``P(a, x) = 1 - Q(a, x)``, computed as ``P`` where
    it is tiny (see :func:`incomplete_gamma`)."""
    return incomplete_gamma(a, x, True)


def _weibull_scale(mean: npt.ArrayLike, k: npt.ArrayLike) -> jnp.ndarray:
    return mean / jnp.exp(gammaln(1.0 + 1.0 / k))


def _lognormal_mu(mean: npt.ArrayLike, s: npt.ArrayLike) -> jnp.ndarray:
    return jnp.log(mean) - 0.5 * s * s


def _gamma_tails(
    r: npt.ArrayLike, mean: npt.ArrayLike, shape: npt.ArrayLike
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Gamma law: ``log S(r)`` and ``log E[(T - r)^+]`` from ONE incomplete-gamma call
    (``Q(k, x)`` and ``Q(k + 1, x)``, ``x = k r / m``, stacked): each call is a loop that
    XLA compiles for seconds, and NUTS programs compile the likelihood's derivative too."""
    r, mean, shape = jnp.broadcast_arrays(
        jnp.asarray(r, float), jnp.asarray(mean, float), jnp.asarray(shape, float)
    )
    x = shape / mean * r
    q = gammaincc(jnp.stack([shape, shape + 1.0]), jnp.stack([x, x]))
    return _log(q[0]), _log_excess(mean * q[1], r * q[0])


def gamma_window_terms(
    surv: npt.ArrayLike,
    excess: npt.ArrayLike,
    resolution: float,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike,
) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray | None]:
    """The gamma law's censored terms from ONE incomplete-gamma loop: ``log S`` of the
    stays ``surv``, ``log E[(T - r)^+]`` of the stays ``excess`` and ``log F(resolution)``
    (as :func:`stay_logsf`, :func:`stay_log_excess` and :func:`stay_logcdf`, the same
    arithmetic; one loop for XLA to compile instead of three).

    Parameters
    ----------
    surv : (ns,) float
    excess : (ne,) float
    resolution : float or () array
        None is returned for it when not positive (:func:`has_resolution`).
    mean, shape : float
        Scalars (one draw).

    Returns
    -------
    log_sf : (ns,) float
    log_excess : (ne,) float
    log_cdf : float or None
    """
    t = jnp.maximum(jnp.asarray(surv, float), 0.0)
    r = jnp.maximum(jnp.asarray(excess, float), 0.0)
    ns, ne = t.shape[0], r.shape[0]
    rate = shape / mean
    a = [jnp.full(ns + ne, shape), jnp.full(ne, shape + 1.0)]
    x = [rate * t, rate * r, rate * r]
    interval = has_resolution(resolution)
    lower = np.zeros(ns + 2 * ne + interval, bool)
    if interval:
        a.append(jnp.reshape(shape, (1,)))
        x.append(jnp.reshape(rate * jnp.maximum(jnp.asarray(resolution, float), 0.0), (1,)))
        lower[-1] = True
    q = incomplete_gamma(jnp.concatenate(a), jnp.concatenate(x), lower)
    log_sf = _log(q[:ns])
    log_excess = _log_excess(mean * q[ns + ne : ns + 2 * ne], r * q[ns : ns + ne])
    return log_sf, log_excess, (_log(q[-1]) if interval else None)


def has_resolution(resolution: npt.ArrayLike) -> bool:
    """Whether the stays' terms include the interval below ``resolution``: a positive
    number, or any array (a program argument, whose value is not known when the program
    is traced; at 0 its interval term is computed and never selected, as no stay is
    shorter than 0).

    Parameters
    ----------
    resolution : float or () array

    Returns
    -------
    bool
    """
    if isinstance(resolution, (int, float, np.number)):  # a number: known when traced
        return bool(resolution > 0)
    return True


def _log_excess(a: npt.ArrayLike, b: npt.ArrayLike) -> jnp.ndarray:
    """``log(a - b)`` for ``a > b >= 0``: their ratio keeps precision when both are small."""
    return _log(a) + jnp.log1p(-jnp.clip(b / jnp.maximum(a, _TINY), 0.0, 1.0 - 1e-16))


def stay_logpdf(
    law: str, t: npt.ArrayLike, mean: npt.ArrayLike, shape: npt.ArrayLike = 1.0
) -> jnp.ndarray:
    """Log density of a stay ``t > 0`` under ``law`` with mean ``mean`` and shape ``shape``.

    Parameters
    ----------
    law : {"exponential", "gamma", "weibull", "lognormal"}
    t : (...) float
        Stays (> 0), broadcast against the parameters.
    mean : (...) float
        Mean stay ``m`` (> 0).
    shape : (...) float
        Shape ``k`` (> 0); ignored by the exponential law.

    Returns
    -------
    (...) float
    """
    law = _law(law)
    t = jnp.asarray(t, float)
    lt = _log(t)
    if law == "exponential":
        return -jnp.log(mean) - t / mean
    if law == "gamma":
        rate = shape / mean
        return shape * jnp.log(rate) + (shape - 1.0) * lt - rate * t - gammaln(shape)
    if law == "weibull":
        scale = _weibull_scale(mean, shape)
        z = t / scale
        return jnp.log(shape) - jnp.log(scale) + (shape - 1.0) * _log(z) - z**shape
    mu = _lognormal_mu(mean, shape)
    zz = (lt - mu) / shape
    return -lt - jnp.log(shape) - 0.5 * jnp.log(2.0 * jnp.pi) - 0.5 * zz * zz


def stay_logsf(
    law: str, t: npt.ArrayLike, mean: npt.ArrayLike, shape: npt.ArrayLike = 1.0
) -> jnp.ndarray:
    """Log survival ``log P(T > t)``, ``t >= 0`` (see :func:`stay_logpdf` for the arguments)."""
    law = _law(law)
    t = jnp.maximum(jnp.asarray(t, float), 0.0)
    if law == "exponential":
        return -t / mean
    if law == "gamma":
        return _gamma_tails(t, mean, shape)[0]
    if law == "weibull":
        return -((t / _weibull_scale(mean, shape)) ** shape)
    mu = _lognormal_mu(mean, shape)
    return log_ndtr(-(_log(t) - mu) / shape)


def stay_logcdf(
    law: str, t: npt.ArrayLike, mean: npt.ArrayLike, shape: npt.ArrayLike = 1.0
) -> jnp.ndarray:
    """Log distribution function ``log P(T <= t)`` (see :func:`stay_logpdf`)."""
    law = _law(law)
    t = jnp.maximum(jnp.asarray(t, float), 0.0)
    if law == "exponential":
        return _log(-jnp.expm1(-t / mean))
    if law == "gamma":
        return _log(gammainc(shape, shape / mean * t))
    if law == "weibull":
        return _log(-jnp.expm1(-((t / _weibull_scale(mean, shape)) ** shape)))
    mu = _lognormal_mu(mean, shape)
    return log_ndtr((_log(t) - mu) / shape)


def stay_log_excess(
    law: str, r: npt.ArrayLike, mean: npt.ArrayLike, shape: npt.ArrayLike = 1.0
) -> jnp.ndarray:
    """``log E[(T - r)^+] = log int_r^inf S(u) du``, the mean excess over ``r >= 0``.

    Divided by the mean it is the survival of the equilibrium (stationary residual) law,
    the likelihood of an artefact present for the whole window. Closed forms:

    * exponential: ``m e^{-r/m}``;
    * gamma: ``m Q(k + 1, k r / m) - r Q(k, k r / m)`` (``Q`` the regularised upper
      incomplete gamma);
    * weibull: ``m Q(1 + 1/k, (r/b)^k) - r S(r)``;
    * lognormal: ``m Phi((mu + s^2 - log r)/s) - r Phi((mu - log r)/s)``.
    """
    law = _law(law)
    r = jnp.maximum(jnp.asarray(r, float), 0.0)
    if law == "exponential":
        return jnp.log(mean) - r / mean
    if law == "gamma":
        return _gamma_tails(r, mean, shape)[1]
    if law == "weibull":
        z = (r / _weibull_scale(mean, shape)) ** shape
        a = mean * gammaincc(1.0 + 1.0 / shape, z)
        b = r * jnp.exp(-z)
    else:
        mu = _lognormal_mu(mean, shape)
        lr = _log(r)
        a = mean * ndtr((mu + shape * shape - lr) / shape)
        b = r * ndtr((mu - lr) / shape)
    return _log_excess(a, b)  # a > b always


def stay_loglik(
    law: str,
    stay: npt.ArrayLike,
    censored: npt.ArrayLike,
    truncated: npt.ArrayLike,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike = 1.0,
    resolution: float = 0.0,
) -> jnp.ndarray:
    """Pointwise log-likelihood of the stays seen through a window (DECISIONS 3).

    Parameters
    ----------
    law : {"exponential", "gamma", "weibull", "lognormal"}
    stay : (n,) float
        Time seen inside the window: ``t_leave - t_arrive`` for artefacts that arrived
        inside it, ``t_leave - t0`` (the residual) for those already there at ``t0``; up to
        ``t1`` for those still there.
    censored : (n,) bool
        Still present at the window end (right-censored).
    truncated : (n,) bool
        Already present at the window start (left-truncated, arrival unknown).
    mean, shape : float
        Parameters of ``law`` (broadcast against ``stay``).
    resolution : float
        The log's time step ``delta``: an uncensored, untruncated stay shorter than it is
        interval-censored on ``(0, delta]``.

    Returns
    -------
    (n,) float
    """
    stay = jnp.asarray(stay, float)
    censored = jnp.asarray(censored, bool)
    truncated = jnp.asarray(truncated, bool)
    log_m = jnp.log(mean)
    d = jnp.maximum(stay, _TINY)
    full = stay_logpdf(law, d, mean, shape)
    if resolution > 0:
        short = stay < resolution
        full = jnp.where(short & ~censored, stay_logcdf(law, resolution, mean, shape), full)
    # survival terms at a stay of exactly 0 (an artefact that arrived at t1) have NaN
    # gradients in the shape (the incomplete gamma at 0): 1e-12 mean is the same survival
    s_pos = jnp.maximum(stay, 1e-12 * mean)
    if _law(law) == "gamma":  # both tails from one incomplete-gamma call
        surv, excess = _gamma_tails(s_pos, mean, shape)
    else:
        surv = stay_logsf(law, s_pos, mean, shape)
        excess = stay_log_excess(law, s_pos, mean, shape)
    return jnp.where(
        truncated,
        jnp.where(censored, excess, surv) - log_m,
        jnp.where(censored, surv, full),
    )


def _gamma_draws(key: jax.Array, a: npt.ArrayLike, size: tuple[int, ...]) -> jnp.ndarray:
    """``jax.random.gamma`` of shape ``size``: a scalar ``a`` goes in as a scalar (JAX
    broadcasts it in the program, to the same draws), so the laws' draws of one size share
    one program whatever their ``a`` (issue 25: ``gamma(key, 2.0, size)`` and
    ``gamma(key, broadcast_to(a, size))`` were two programs, 5-6 s of compile each)."""
    if np.ndim(a) == 0:
        return jax.random.gamma(key, a, size)
    return jax.random.gamma(key, jnp.broadcast_to(a, size))


def stay_sample(
    key: jax.Array,
    law: str,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike = 1.0,
    size: int | tuple[int, ...] = (),
) -> jnp.ndarray:
    """Draw stays of ``law`` with the given mean and shape.

    Parameters
    ----------
    key : jax.random.key
    law : {"exponential", "gamma", "weibull", "lognormal"}
    mean, shape : float or array
        Broadcast against ``size``.
    size : tuple of int
        Output shape.

    Returns
    -------
    size float
    """
    law = _law(law)
    size = tuple(np.broadcast_shapes(tuple(size), np.shape(mean), np.shape(shape)))
    if law == "exponential":
        return jax.random.exponential(key, size) * mean
    if law == "gamma":
        return _gamma_draws(key, shape, size) * (mean / shape)
    if law == "weibull":
        e = jax.random.exponential(key, size)
        return _weibull_scale(mean, shape) * e ** (1.0 / shape)
    z = jax.random.normal(key, size)
    return jnp.exp(_lognormal_mu(mean, shape) + shape * z)


def stay_sample_residual(
    key: jax.Array,
    law: str,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike = 1.0,
    size: int | tuple[int, ...] = (),
) -> jnp.ndarray:
    """Draw residual stays of artefacts present at a fixed time of a stationary process.

    The residual has the equilibrium density ``S(r) / m`` (see :func:`stay_log_excess`); it
    is ``U * T*`` with ``U`` uniform and ``T*`` the length-biased stay (density
    ``t f(t) / m``), which is again in the family: ``Gamma(k + 1, k/m)`` for the gamma law,
    ``(T*/b)^k ~ Gamma(1 + 1/k)`` for the Weibull, ``LogNormal(mu + s^2, s)`` for the
    lognormal and ``Gamma(2, 1/m)`` for the exponential (so the residual is exponential,
    the memoryless case). Use it for the initial population of a scenario.

    Parameters
    ----------
    key : jax.random.key
    law : {"exponential", "gamma", "weibull", "lognormal"}
    mean, shape : float or array
    size : tuple of int

    Returns
    -------
    size float
    """
    law = _law(law)
    size = tuple(np.broadcast_shapes(tuple(size), np.shape(mean), np.shape(shape)))
    k_len, k_u = jax.random.split(key)
    if law == "exponential":
        biased = _gamma_draws(k_len, 2.0, size) * mean
    elif law == "gamma":
        biased = _gamma_draws(k_len, shape + 1.0, size) * (mean / shape)
    elif law == "weibull":
        y = _gamma_draws(k_len, 1.0 + 1.0 / shape, size)
        biased = _weibull_scale(mean, shape) * y ** (1.0 / shape)
    else:
        z = jax.random.normal(k_len, size)
        biased = jnp.exp(_lognormal_mu(mean, shape) + shape * shape + shape * z)
    return jax.random.uniform(k_u, size) * biased


def stay_cv(law: str, shape: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Coefficient of variation (sd / mean) of ``law`` with shape ``shape``."""
    law = _law(law)
    k = np.asarray(shape, float)
    if law == "exponential":
        return np.ones_like(k)
    if law == "gamma":
        return 1.0 / np.sqrt(k)
    if law == "weibull":
        g1, g2 = sgammaln(1 + 1 / k), sgammaln(1 + 2 / k)
        return np.sqrt(np.expm1(g2 - 2 * g1))
    return np.sqrt(np.expm1(k * k))


def stay_shape_from_cv(law: str, cv: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The shape giving coefficient of variation ``cv`` (inverse of :func:`stay_cv`)."""
    law = _law(law)
    c = np.asarray(cv, float)
    if law == "exponential":
        return np.ones_like(c)
    if law == "gamma":
        return 1.0 / (c * c)
    if law == "lognormal":
        return np.sqrt(np.log1p(c * c))
    from scipy.optimize import brentq  # lazy: +0.16 s CPU on `import are_stats.traffic`

    flat = [brentq(lambda k, v=v: float(stay_cv("weibull", k)) - v, 0.05, 200.0) for v in c.ravel()]
    return np.reshape(flat, c.shape)


def stay_draws(
    rng: np.random.Generator,
    law: str,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike = 1.0,
    size: int | tuple[int, ...] = (),
    residual: bool = False,
) -> np.ndarray:
    """NumPy twin of :func:`stay_sample` / :func:`stay_sample_residual` (same laws).

    The scenario sampler draws populations of every size one after another; NumPy draws
    them without compiling a program per size.

    Parameters
    ----------
    rng : numpy.random.Generator
    law : {"exponential", "gamma", "weibull", "lognormal"}
    mean, shape : float or array
        Broadcast against ``size``.
    size : tuple of int
    residual : bool
        Draw the equilibrium residual stay (of artefacts present at a fixed time of a
        stationary process) instead of a whole stay.

    Returns
    -------
    size float64
    """
    law = _law(law)
    size = (int(size),) if isinstance(size, int | np.integer) else tuple(size)
    size = tuple(np.broadcast_shapes(size, np.shape(mean), np.shape(shape)))
    m = np.broadcast_to(np.asarray(mean, float), size)
    k = np.broadcast_to(np.asarray(shape, float), size)
    if law == "exponential":
        t = rng.gamma(2.0, 1.0, size) * m if residual else rng.exponential(1.0, size) * m
    elif law == "gamma":
        t = rng.gamma(k + 1.0 if residual else k, 1.0, size) * (m / k)
    elif law == "weibull":
        scale = m / np.exp(_gammaln_np(1.0 + 1.0 / k))
        y = rng.gamma(1.0 + 1.0 / k, 1.0, size) if residual else rng.exponential(1.0, size)
        t = scale * y ** (1.0 / k)
    else:
        mu = np.log(m) - 0.5 * k * k
        t = np.exp(mu + (k * k if residual else 0.0) + k * rng.standard_normal(size))
    if residual:
        t = t * rng.random(size)
    return np.asarray(t, float)


def _gammaln_np(x: npt.ArrayLike) -> np.ndarray:
    """``log Gamma(x)`` in NumPy (scipy)."""
    return sgammaln(x)
