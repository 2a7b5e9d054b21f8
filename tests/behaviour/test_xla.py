"""jit_with_options: XLA options a jaxlib does not know are left out, the others kept."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from are_stats.behaviour import _xla, jit_with_options

UNKNOWN = "xla_no_such_option_for_are_stats_tests"


@pytest.fixture(autouse=True)
def _fresh_registry(monkeypatch):
    monkeypatch.setattr(_xla, "UNKNOWN_OPTIONS", set())


def _f(x, k):
    return jnp.cumsum(x * k)


def test_known_options_give_the_plain_jit_program_and_result():
    opts = {"xla_cpu_use_fusion_emitters": False}
    x = np.linspace(0.0, 1.0, 33, dtype=np.float32)
    ours = jit_with_options(_f, compiler_options=opts, static_argnames=("k",))
    plain = jax.jit(_f, compiler_options=opts, static_argnames=("k",))
    assert np.array_equal(np.asarray(ours(x, k=3)), np.asarray(plain(x, k=3)))
    assert ours._cache_size() == 1  # the jitted function's attributes
    assert ours.lower(x, k=3).as_text() == plain.lower(x, k=3).as_text()
    assert _xla.UNKNOWN_OPTIONS == set()


def test_an_unknown_option_is_left_out_and_remembered():
    x = np.arange(5.0, dtype=np.float32)
    with pytest.raises(Exception, match="No such compile option"):
        jax.jit(_f, compiler_options={UNKNOWN: True}, static_argnames=("k",))(x, k=2)
    opts = {UNKNOWN: True, "xla_cpu_use_fusion_emitters": False}
    g = jit_with_options(compiler_options=opts, static_argnames=("k",))(_f)
    assert np.array_equal(np.asarray(g(x, k=2)), np.cumsum(x * 2))
    assert _xla.UNKNOWN_OPTIONS == {UNKNOWN}
    # a program made later leaves it out from its first compile
    h = jit_with_options(lambda y: y - 1.0, compiler_options={UNKNOWN: False})
    assert np.array_equal(np.asarray(h(x)), x - 1.0)


def test_other_errors_are_raised():
    g = jit_with_options(lambda y: y.reshape(3), compiler_options={})
    with pytest.raises(TypeError):
        g(np.zeros(4))
