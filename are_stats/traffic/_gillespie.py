"""Exact event-by-event (Gillespie) simulation of the birth-death process N(t).

All paths advance in lock-step: one loop iteration draws the next event of every path that
is still inside the horizon, so the work is vectorised over paths and the loop runs as many
times as the busiest path has events. The random numbers of event ``s`` of every path come
from ``jax.random.fold_in(k, s)`` where ``k`` is an ``"rbg"`` key (XLA's RngBitGenerator, about
twice as fast on CPU as threefry for these bulk draws) seeded by 128 bits drawn from the
caller's key, so :func:`simulate_counts` and :func:`simulate_events` return the same paths for
the same key.

Nothing is truncated: :func:`simulate_counts` loops until every path has passed ``t_end``;
:func:`simulate_events` scans in fixed-length chunks (the first sized by a Poisson tail bound
on the number of events) and appends chunks until every path has passed ``t_end``.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from are_stats._lazy import scipy_stats as stats

__all__ = ["BirthDeathEvents", "simulate_counts", "simulate_events", "event_bound"]


class BirthDeathEvents(NamedTuple):
    """Padded event record of simulated paths.

    Attributes
    ----------
    times : (n_paths, n_max) float64
        Event times in increasing order; ``+inf`` after a path's last event.
    kinds : (n_paths, n_max) int8
        ``+1`` for a birth (arrival), ``-1`` for a death (departure), ``0`` for padding.
    counts : (n_paths, n_max) int64
        N(t) just after each event (the last value repeats over the padding).
    n_events : (n_paths,) int64
        Number of events of each path in ``[0, t_end]``.
    observed : (n_paths, n_times) int64
        N(t) at the requested observation times.
    """

    times: np.ndarray
    kinds: np.ndarray
    counts: np.ndarray
    n_events: np.ndarray
    observed: np.ndarray


def event_bound(birth_rate: float, n0_max: int, t_end: float, tail: float = 1e-6) -> int:
    """Number of event steps that suffices for a path with probability ``1 - tail``.

    A path starting from ``n0`` has ``B ~ Poisson(birth_rate * t_end)`` births in
    ``[0, t_end]`` (births have rate ``birth_rate`` in every state, for both death laws) and
    at most ``n0 + B`` deaths, hence at most ``n0 + 2 B`` events.
    """
    x = birth_rate * t_end
    q = 0 if x == 0 else int(stats.poisson.isf(tail, x))
    return int(n0_max + 2 * q + 1)


def _event(key, step, lam, mu, t, n, done, t_end, linear, second=None):
    """Next event of every path (vectorised); paths already past ``t_end`` stay frozen.

    With ``second`` (:func:`_counts_loop`) the paths are padded: the draws of the ``n_real``
    real paths are those of ``uniform(k, (2, n_real))``, taken from one flat draw of
    ``2 * n_paths`` (the ``"rbg"`` stream of a longer draw starts with that of a shorter
    one; on this host's CPU backend, tested) as ``flat[:n_paths]`` and ``flat[second]``,
    ``second = n_real + arange(n_paths)`` (a gather: a traced ``dynamic_slice`` made the
    loop 20-50 % slower); ``linear`` may be a traced bool.
    """
    k = jax.random.fold_in(key, step)
    if second is None:
        u = jax.random.uniform(k, (2,) + t.shape, dtype=t.dtype)
        u0, u1 = u[0], u[1]
    else:
        flat = jax.random.uniform(k, (2 * t.shape[0],), dtype=t.dtype)
        u0, u1 = flat[: t.shape[0]], flat[second]
    nf = n.astype(t.dtype)
    if isinstance(linear, bool):
        death = mu * nf if linear else mu * (n > 0).astype(t.dtype)
    else:
        death = jnp.where(linear, mu * nf, mu * (n > 0).astype(t.dtype))
    rate = lam + death
    wait = jnp.where(rate > 0, -jnp.log1p(-u0) / jnp.where(rate > 0, rate, 1.0), jnp.inf)
    t_new = t + wait
    active = (~done) & (t_new <= t_end)
    birth = u1 * rate < lam
    delta = jnp.where(active, jnp.where(birth, 1, -1), 0).astype(n.dtype)
    return jnp.where(active, t_new, t), n + delta, delta, active, done | ~active


def _record(hist, times, t_evt, delta):
    """Add each event's +-1 to the first observation time at or after it."""
    j = jnp.searchsorted(times, t_evt, side="left")
    rows = jnp.arange(hist.shape[0])
    return hist.at[rows, j].add(delta)


@partial(jax.jit, static_argnames=("padded",))
def _counts_loop(key, lam, mu, n0, n_real, t_end, times, linear, padded):
    """Counts at ``times`` of the first ``n_real`` of the paths ``n0`` (all when not
    ``padded``).

    Padded paths start done; padded ``times`` are ``+inf`` (no event reaches them), so the
    counts of the real paths at the real times are those of an unpadded run, bit for bit,
    and calls of nearby sizes (and both death laws: ``linear`` is traced) share one program.
    """
    n_paths = n0.shape[0]
    t0 = jnp.zeros(n_paths, dtype=times.dtype)
    hist = jnp.zeros((n_paths, times.shape[0] + 1), dtype=n0.dtype)
    done = jnp.arange(n_paths) >= n_real
    second = n_real + jnp.arange(n_paths) if padded else None  # < 2 n_paths

    def cond(c):
        return ~jnp.all(c[3])

    def body(c):
        step, t, n, done, hist = c
        t, n, delta, active, done = _event(key, step, lam, mu, t, n, done, t_end, linear, second)
        hist = _record(hist, times, t, delta)
        return step + 1, t, n, done, hist

    steps, _, _, _, hist = jax.lax.while_loop(cond, body, (jnp.int64(0), t0, n0, done, hist))
    observed = n0[:, None] + jnp.cumsum(hist, axis=1)[:, :-1]
    return observed, steps


@partial(jax.jit, static_argnames=("linear", "length"))
def _events_chunk(key, lam, mu, t_end, times, carry, linear, length):
    def body(c, _):
        step, t, n, done, hist = c
        t, n, delta, active, done = _event(key, step, lam, mu, t, n, done, t_end, linear)
        hist = _record(hist, times, t, delta)
        return (step + 1, t, n, done, hist), (jnp.where(active, t, jnp.inf), delta.astype(jnp.int8))

    return jax.lax.scan(body, carry, None, length=length)


def _stream_key(key):
    """The ``"rbg"`` key of the simulation stream, derived deterministically from ``key``."""
    return jax.random.wrap_key_data(jax.random.bits(key, (4,), jnp.uint32), impl="rbg")


def _round_up(x: int, m: int = 64) -> int:
    return int(-(-x // m) * m)


#: Fewer paths than this, :func:`simulate_counts` pads to this many (one program); more are
#: not padded (the padded draw's gather made the loop of 4000-20000 paths 20-50 % slower).
_SMALL_PATHS = 16


def _pow2(n: int, least: int) -> int:
    """The next power of two, at least ``least``."""
    return max(least, 1 << (max(int(n), 1) - 1).bit_length())


def simulate_counts(key, lam, mu, n0, t_end, times, linear):
    """Counts at ``times`` of independent paths; see :meth:`BirthDeath.simulate`.

    Fewer than :data:`_SMALL_PATHS` paths are padded to that many and their times to a
    power of two (at least 64: a longer search costs so few paths little); more paths
    and their times are not padded (a longer search cost the 20000-path loop 7 %). The
    counts are those of the unpadded run (see :func:`_counts_loop`), so small calls of
    nearby sizes, and both death laws at any size, share one compiled program.
    """
    n0 = np.asarray(n0, dtype=np.int64)
    times = np.asarray(times, dtype=np.float64)
    n_paths, n_times = n0.shape[0], times.shape[0]
    padded = n_paths < _SMALL_PATHS
    n0_pad = np.zeros(_SMALL_PATHS if padded else n_paths, np.int64)
    n0_pad[:n_paths] = n0
    times_pad = np.full(_pow2(n_times, 64) if padded else n_times, np.inf)
    times_pad[:n_times] = times
    key = _stream_key(key)
    observed, _ = _counts_loop(
        key,
        float(lam),
        float(mu),
        n0_pad,
        np.int64(n_paths),
        float(t_end),
        times_pad,
        np.bool_(linear),
        padded=padded,
    )
    return np.asarray(observed)[:n_paths, :n_times]


def simulate_events(key, lam, mu, n0, t_end, times, linear, chunk: int | None = None):
    """Padded event record; see :meth:`BirthDeath.simulate_events`.

    ``chunk`` overrides the first chunk length (the Poisson bound of :func:`event_bound`);
    later chunks are a quarter of it (at least 64 steps).
    """
    n0 = jnp.asarray(n0, dtype=jnp.int64)
    times = jnp.asarray(times, dtype=jnp.float64)
    n_paths = n0.shape[0]
    if chunk is None:
        chunk = event_bound(float(lam), int(n0.max()), float(t_end), tail=1e-3 / max(n_paths, 1))
    length = _round_up(max(int(chunk), 1))
    carry = (
        jnp.int64(0),
        jnp.zeros(n_paths, dtype=jnp.float64),
        n0,
        jnp.zeros(n_paths, dtype=bool),
        jnp.zeros((n_paths, times.shape[0] + 1), dtype=jnp.int64),
    )
    t_parts, k_parts = [], []
    args = (_stream_key(key), float(lam), float(mu), float(t_end), times)
    while True:
        carry, (tt, kk) = _events_chunk(*args, carry, linear=bool(linear), length=length)
        t_parts.append(np.asarray(tt).T)
        k_parts.append(np.asarray(kk).T)
        if bool(jnp.all(carry[3])):
            break
        length = _round_up(max(length // 4, 64))
    ev_t = np.concatenate(t_parts, axis=1)
    ev_k = np.concatenate(k_parts, axis=1)
    n_events = (ev_k != 0).sum(axis=1).astype(np.int64)
    width = int(n_events.max()) if n_paths else 0
    ev_t, ev_k = ev_t[:, :width], ev_k[:, :width]
    counts = np.asarray(n0)[:, None] + np.cumsum(ev_k, axis=1, dtype=np.int64)
    observed = np.asarray(n0)[:, None] + np.cumsum(np.asarray(carry[4]), axis=1)[:, :-1]
    return BirthDeathEvents(ev_t, ev_k, counts, n_events, observed)
