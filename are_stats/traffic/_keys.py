"""JAX's threefry key operations (seed, split, fold-in, bits, uniforms) computed in NumPy.

Each ``jax.random`` operation on a key outside a compiled program is an XLA program of
its own, compiled in every fresh process that has no persistent cache: a fit on a new
machine compiled about a dozen of them (0.7 s of CPU) before any model. These functions
give the same keys and bits, bit for bit, as ``jax.random.key``, ``split``, ``fold_in``,
``bits`` and float64 ``uniform`` with JAX's default threefry2x32 keys (the partitionable
derivation, JAX's default), computed in NumPy and wrapped as JAX keys
(:func:`jax.random.wrap_key_data` compiles nothing). Another key implementation, or the
original (non-partitionable) derivation, goes to ``jax.random`` itself.
"""

from __future__ import annotations

import jax
import numpy as np

__all__ = ["fold_in_key", "key_bits", "key_from_seed", "key_uniform", "split_key"]

#: Rotations of the threefry2x32 rounds (Salmon et al. 2011), four per group, alternating.
_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))
_PARITY = np.uint32(0x1BD11BDA)


def _threefry2x32(k1: np.uint32, k2: np.uint32, x1: np.ndarray, x2: np.ndarray) -> tuple:
    """The threefry2x32 hash of the counters ``(x1, x2)`` (uint32 arrays) under the key
    ``(k1, k2)``: 20 rounds, as JAX's ``threefry2x32_p``."""
    ks = (np.uint32(k1), np.uint32(k2), np.uint32(k1) ^ np.uint32(k2) ^ _PARITY)
    with np.errstate(over="ignore"):  # uint32 arithmetic wraps, as XLA's
        x = [np.asarray(x1, np.uint32) + ks[0], np.asarray(x2, np.uint32) + ks[1]]
        for group in range(5):
            for r in _ROTATIONS[group % 2]:
                x[0] = x[0] + x[1]
                x[1] = (x[1] << np.uint32(r)) | (x[1] >> np.uint32(32 - r))
                x[1] = x[0] ^ x[1]
            x[0] = x[0] + ks[(group + 1) % 3]
            x[1] = x[1] + ks[(group + 2) % 3] + np.uint32(group + 1)
    return x[0], x[1]


def _numpy_ok(key: jax.Array) -> bool:
    """Whether ``key`` is a threefry2x32 key derived the partitionable way (JAX's default)."""
    if not bool(jax.config.jax_threefry_partitionable):
        return False
    try:
        return str(jax.random.key_impl(key)) == "threefry2x32" and np.shape(key) == ()
    except (TypeError, ValueError):
        return False


def _data(key: jax.Array) -> tuple[np.uint32, np.uint32]:
    k = np.asarray(jax.random.key_data(key), np.uint32).ravel()
    return k[0], k[1]


def _wrap(k1: int | np.uint32, k2: int | np.uint32) -> jax.Array:
    return jax.random.wrap_key_data(np.array([k1, k2], np.uint32), impl="threefry2x32")


def key_from_seed(seed: int) -> jax.Array:
    """``jax.random.key(seed)`` without an XLA program (a threefry2x32 key).

    Parameters
    ----------
    seed : int
        An integer (the CLI's seeds are in ``[0, 2**32)``); outside ``[0, 2**63)``
        ``jax.random.key`` itself makes the key.

    Returns
    -------
    jax.Array
        A scalar key, equal to ``jax.random.key(seed)``.
    """
    seed = int(seed)
    if not 0 <= seed < 2**63 or str(jax.config.jax_default_prng_impl) != "threefry2x32":
        return jax.random.key(seed)
    return _wrap(seed >> 32, seed & 0xFFFFFFFF)


def split_key(key: jax.Array, num: int = 2) -> tuple[jax.Array, ...]:
    """``tuple(jax.random.split(key, num))`` without an XLA program.

    Parameters
    ----------
    key : jax.Array
        A scalar key.
    num : int

    Returns
    -------
    tuple of jax.Array
        ``num`` scalar keys (a tuple: unpacking a key array is a program too).
    """
    if not _numpy_ok(key):
        return tuple(jax.random.split(key, num))
    k1, k2 = _data(key)
    b1, b2 = _threefry2x32(k1, k2, np.zeros(num, np.uint32), np.arange(num, dtype=np.uint32))
    return tuple(_wrap(a, b) for a, b in zip(b1, b2, strict=True))


def fold_in_key(key: jax.Array, data: int) -> jax.Array:
    """``jax.random.fold_in(key, data)`` without an XLA program.

    Parameters
    ----------
    key : jax.Array
        A scalar key.
    data : int
        In ``[0, 2**32)``.

    Returns
    -------
    jax.Array
    """
    data = int(data)
    if not _numpy_ok(key) or not 0 <= data < 2**32:
        return jax.random.fold_in(key, data)
    k1, k2 = _data(key)
    b1, b2 = _threefry2x32(k1, k2, np.zeros(1, np.uint32), np.array([data], np.uint32))
    return _wrap(b1[0], b2[0])


def key_bits(key: jax.Array, num: int) -> np.ndarray:
    """``jax.random.bits(key, (num,), jnp.uint32)`` without an XLA program.

    Parameters
    ----------
    key : jax.Array
    num : int

    Returns
    -------
    (num,) uint32
    """
    if not _numpy_ok(key):
        return np.asarray(jax.random.bits(key, (num,), np.uint32))
    k1, k2 = _data(key)
    b1, b2 = _threefry2x32(k1, k2, np.zeros(num, np.uint32), np.arange(num, dtype=np.uint32))
    return b1 ^ b2


def key_uniform(key: jax.Array, shape: tuple[int, ...]) -> np.ndarray:
    """``jax.random.uniform(key, shape, dtype=float64)`` without an XLA program.

    Element ``j`` of the flattened shape takes the 64 bits ``threefry(key, (j >> 32, j &
    0xffffffff))``, high word first, keeps their top 52 as the mantissa of a number in
    ``[1, 2)`` and subtracts 1, as ``jax.random.uniform`` does (its ``* (1 - 0) + 0`` and
    ``max(0, .)`` change no bit).

    Parameters
    ----------
    key : jax.Array
        A scalar key.
    shape : tuple of int

    Returns
    -------
    float64 array of ``shape``, in ``[0, 1)``
    """
    shape = tuple(int(s) for s in shape)
    if not _numpy_ok(key) or not jax.config.jax_enable_x64:
        return np.asarray(jax.random.uniform(key, shape, dtype=np.float64))
    k1, k2 = _data(key)
    j = np.arange(int(np.prod(shape, dtype=np.int64)), dtype=np.uint64)
    hi, lo = _threefry2x32(k1, k2, (j >> np.uint64(32)).astype(np.uint32), j.astype(np.uint32))
    bits = (hi.astype(np.uint64) << np.uint64(32)) | lo.astype(np.uint64)
    one = np.uint64(0x3FF0000000000000)  # the bits of 1.0
    return (((bits >> np.uint64(12)) | one).view(np.float64) - 1.0).reshape(shape)
