"""JAX's key operations in NumPy against ``jax.random`` itself (the truth): the same keys
and bits, bit for bit, and no XLA program compiled for them."""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from are_stats.traffic import fold_in_key, key_bits, key_from_seed, key_uniform, split_key

SEEDS = [0, 1, 7, 123456789, 2**32 - 1, 2**32, 2**40 + 5, 2**63 - 1]


def _data(key) -> np.ndarray:
    return np.asarray(jax.random.key_data(key))


@pytest.mark.parametrize("seed", SEEDS)
def test_numpy_key_operations_are_jax_random_bit_for_bit(seed):
    want, got = jax.random.key(seed), key_from_seed(seed)
    np.testing.assert_array_equal(_data(got), _data(want))
    for num in (1, 2, 3, 5, 16):
        keys = split_key(got, num)
        assert isinstance(keys, tuple) and len(keys) == num
        np.testing.assert_array_equal(
            np.stack([_data(k) for k in keys]), _data(jax.random.split(want, num))
        )
    for data in (0, 1, 14, 101, 2**31, 2**32 - 1):
        np.testing.assert_array_equal(
            _data(fold_in_key(got, data)), _data(jax.random.fold_in(want, data))
        )
    for num in (1, 4, 7):
        bits = key_bits(got, num)
        assert bits.dtype == np.uint32
        np.testing.assert_array_equal(bits, np.asarray(jax.random.bits(want, (num,), np.uint32)))
    # derived keys derive on: a chain of operations stays on jax.random's stream
    a, b = split_key(fold_in_key(got, 14))
    wa, wb = jax.random.split(jax.random.fold_in(want, 14))
    np.testing.assert_array_equal(_data(fold_in_key(b, 3)), _data(jax.random.fold_in(wb, 3)))
    np.testing.assert_array_equal(key_bits(a, 4), np.asarray(jax.random.bits(wa, (4,), np.uint32)))


def test_other_key_implementations_go_to_jax_random():
    key = jax.random.key(3, impl="rbg")
    np.testing.assert_array_equal(_data(fold_in_key(key, 5)), _data(jax.random.fold_in(key, 5)))
    got = split_key(key, 3)
    np.testing.assert_array_equal(
        np.stack([_data(k) for k in got]), _data(jax.random.split(key, 3))
    )
    np.testing.assert_array_equal(
        key_bits(key, 4), np.asarray(jax.random.bits(key, (4,), np.uint32))
    )
    with pytest.raises((TypeError, ValueError)):
        key_bits(np.arange(3), 4)  # not a key: jax.random's own error


def test_no_xla_program_is_compiled_for_them():
    """In a fresh process without a persistent cache, JAX logs no compilation."""
    code = (
        "import are_stats, numpy as np\n"
        "from are_stats.traffic import fold_in_key, key_bits, key_from_seed, key_uniform\n"
        "from are_stats.traffic import split_key\n"
        "k = key_from_seed(5)\n"
        "a, b, c = split_key(k, 3)\n"
        "print(*key_bits(fold_in_key(b, 14), 4))\n"
        "print(*key_uniform(c, (2, 2)).ravel().tolist())\n"
    )
    env = {"JAX_LOG_COMPILES": "1", "ARE_STATS_NO_CACHE": "1", "JAX_PLATFORMS": "cpu"}
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ, **env},
        check=True, timeout=300,
    )  # fmt: skip
    assert "Finished XLA compilation" not in proc.stderr, proc.stderr[-2000:]
    want = jax.random.bits(jax.random.fold_in(jax.random.split(jax.random.key(5), 3)[1], 14),
                           (4,), np.uint32)  # fmt: skip
    bits, unif = proc.stdout.splitlines()
    assert bits.split() == [str(x) for x in np.asarray(want)]
    u = jax.random.uniform(jax.random.split(jax.random.key(5), 3)[2], (4,), dtype=np.float64)
    assert unif.split() == [str(x) for x in np.asarray(u).tolist()]


@pytest.mark.parametrize("seed", [0, 7, 2**32 + 3])
def test_numpy_uniforms_are_jax_random_bit_for_bit(seed):
    """float64 uniforms of empty, flat and two-dimensional shapes, a derived key's too."""
    want, got = jax.random.key(seed), key_from_seed(seed)
    for shape in [(0,), (1,), (5,), (3, 7), (64, 33), (1, 0)]:
        u = key_uniform(got, shape)
        assert u.dtype == np.float64 and u.shape == shape
        np.testing.assert_array_equal(
            u, np.asarray(jax.random.uniform(want, shape, dtype=np.float64))
        )
    np.testing.assert_array_equal(
        key_uniform(fold_in_key(got, 26), (9,)),
        np.asarray(jax.random.uniform(jax.random.fold_in(want, 26), (9,), dtype=np.float64)),
    )
    key = jax.random.key(seed, impl="rbg")  # another implementation: jax.random's own
    np.testing.assert_array_equal(
        key_uniform(key, (4,)), np.asarray(jax.random.uniform(key, (4,), dtype=np.float64))
    )
