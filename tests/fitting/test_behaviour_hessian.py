"""The behaviour fit's Hessian (issue 29): differences of the gradient program, no program of
its own. The soft solve stops early at ``tol``; forward mode through it (the previous
``jvp(jvp)`` program, compiled for the Hessian alone) differentiates the solve at the epochs
it ran, so the differences hold the solve at those epochs (a cap as data, ``tol < 0``)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import are_stats.fitting._behaviour as fb
from are_stats.behaviour import path_free, wall_distance_feature
from are_stats.behaviour._soft import soft_backward_induction
from tests.helpers import assert_allclose


def _world():
    """A 10 x 12 grid with a wall, four cell paths to three goals, the walls feature."""
    free = np.ones((10, 12), bool)
    free[4, 3:9] = False
    paths = [
        np.array([[0, 0], [0, 1], [0, 1], [0, 2], [1, 2], [1, 3], [1, 4], [0, 4], [0, 5]]),
        np.array([[9, 11], [8, 11], [7, 11], [7, 10], [6, 10], [5, 10], [5, 9], [5, 8]]),
        np.array([[9, 0], [8, 0], [8, 1], [7, 1], [6, 1], [5, 1], [5, 2], [5, 3], [5, 4]]),
        np.array([[2, 8], [2, 7], [1, 7], [1, 6], [1, 5], [0, 5]]),
    ]
    return free, paths, wall_distance_feature(~free, 1.0)[None]


def _data(dtype, n_devices=1):
    free, paths, phi = _world()
    data, _, _, n_dev = fb._likelihood_data(
        paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, dtype=dtype,
        n_devices=n_devices, features=phi,
    )  # fmt: skip
    return data, n_dev


TH = np.array([np.log(1.7), -2.0, -0.4])


@functools.cache
def _forward_hessian(n_devices: int) -> np.ndarray:
    """``jacfwd(jacfwd)`` at ``TH`` of the float64 log-likelihood whose solve stops at
    ``tol = 1e-3`` (the previous Hessian's definition): the reference of the float64 and
    the float32 tests below, traced and run once per device count instead of once per test.

    Returns
    -------
    (3, 3) float64
    """
    data, n_dev = _data(np.float64, n_devices)
    return np.asarray(
        jax.jit(jax.jacfwd(jax.jacfwd(lambda t: fb._loglik(t, data, 1e-3, n_dev))))(TH)
    )


def test_a_solve_held_at_its_epochs_repeats_the_stopped_solve() -> None:
    """soft_backward_induction's ``with_epochs``: the same solve capped at ``epochs + 1``
    with ``tol < 0`` is the stopped one, bit for bit; a cap one lower is not."""
    free, _, _ = _world()
    occ = ~free
    keep = jnp.asarray(free[None] & (np.arange(free.size).reshape(free.shape) != 5)[None])
    bonus = jnp.asarray((np.arange(free.size).reshape(free.shape) == 5)[None], float)
    ok = jnp.asarray(path_free(occ))

    def solve(k, tol):
        return soft_backward_induction(
            ok, keep, bonus, jnp.asarray(1.5), jnp.asarray(0.1), n_epochs=k, time_cost=1.0,
            tol=tol, with_epochs=True,
        )  # fmt: skip

    run = jax.jit(solve)
    stopped = run(jnp.asarray(400), jnp.asarray(1e-4))
    epochs = int(stopped.epochs)
    assert 5 < epochs < 399  # stopped by the tolerance, not the cap
    held = run(jnp.asarray(epochs + 1), jnp.asarray(-1.0))
    np.testing.assert_array_equal(np.asarray(held.values), np.asarray(stopped.values))
    np.testing.assert_array_equal(np.asarray(held.policy), np.asarray(stopped.policy))
    assert int(held.epochs) == epochs
    short = run(jnp.asarray(epochs), jnp.asarray(-1.0))
    assert np.abs(np.asarray(short.values - stopped.values)).max() > 0
    assert solve(10, None).epochs is None  # without tol: no count
    without = soft_backward_induction(
        ok, keep, bonus, jnp.asarray(1.5), jnp.asarray(0.1), n_epochs=400, time_cost=1.0,
        tol=1e-4,
    )  # fmt: skip
    assert without.epochs is None  # only when asked (shard_map callers keep their outputs)


# two devices: the slow tier (a second forward-over-forward reference compile, ~26 s cold);
# make test splits the same program across devices in test_behaviour_fit's split tests
@pytest.mark.parametrize("n_devices", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_hessian_by_differences_is_forward_mode_through_the_stopped_solve(n_devices) -> None:
    """Float64: the five-point differences of the gradient program equal ``jacfwd(jacfwd)``
    of the log-likelihood whose solve stops at ``tol`` (the previous Hessian's definition),
    to 1e-7 relative (the stencil's ``O(h^4)`` error at ``h = 1e-3`` here: about 1e-9)."""
    if jax.local_device_count() < n_devices:
        pytest.skip("needs two XLA host devices (tests/conftest.py asks for them)")
    data, n_dev = _data(np.float64, n_devices)
    tol = jnp.asarray(1e-3, np.float64)
    g, v, epochs = fb._gradient_value_epochs(jnp.asarray(TH), data, tol, n_dev)
    assert 5 < int(epochs) < int(data.n_epochs) - 1
    want = _forward_hessian(n_devices)
    got = fb._hessian(jnp.asarray(TH), data, int(epochs), n_dev)
    assert_allclose(got, want, rtol=1e-7, atol=1e-7 * np.abs(want).max())
    # the gradient held at those epochs is the stopped one, bit for bit
    fixed = data._replace(n_epochs=jnp.asarray(int(epochs) + 1, jnp.int32))
    g2, v2, e2 = fb._gradient_value_epochs(
        jnp.asarray(TH), fixed, jnp.asarray(-1.0, np.float64), n_dev
    )
    np.testing.assert_array_equal(np.asarray(g2), np.asarray(g))
    assert float(v2) == float(v) and int(e2) == int(epochs)


def test_float32_differenced_hessian_matches_float64_forward_mode() -> None:
    """Float32 (the fit's default): the differenced Hessian is within 2e-4 of float64's
    forward-mode one in the spectral norm, relative (measured 1.2e-4: float32 round-off
    over the step against the stencil's error; the Hessian's own forward mode in float32
    was 5e-6 off), so the covariance ``inv(-H)`` is within ``cond(H) * 2e-4`` of its
    float64 value, to first order.

    Before, the test compared standard errors ``sqrt(diag(inv(-H)))`` at ``TH``. ``TH`` is
    not the likelihood's maximum: ``-H`` is indefinite there, two of the three "variances"
    were negative, and their NaN square roots on both sides passed ``assert_allclose``
    unchecked (one of them, a small variance after cancellation, differs by 4.7e-3
    relative, within the bound above: ``cond(H)`` is 11.5 here)."""
    want = _forward_hessian(1)
    data32, n_dev = _data(np.float32)
    tol = jnp.asarray(1e-3, np.float32)
    epochs = fb._gradient_value_epochs(jnp.asarray(TH, np.float32), data32, tol, n_dev)[2]
    got = np.asarray(fb._hessian(jnp.asarray(TH, np.float32), data32, int(epochs), n_dev))
    assert np.isfinite(got).all()
    rel = np.linalg.norm(got.astype(np.float64) - want, 2) / np.linalg.norm(want, 2)
    assert rel < 2e-4, rel


def test_the_fit_compiles_one_program_for_value_gradient_and_hessian() -> None:
    """_mle's optimisation and its Hessian run the one program per shape bucket. (The
    standard errors' finiteness is checked by the next test, on its own grid: on this
    5-goal world in float32, an AVX2 host's Hessian leaves beta's and the weights' NaN, not
    positive definite there, where an AVX-512 host's did not; seen 2026-11-28 on main too.)"""
    free, paths, phi = _world()
    fb._gradient_value_epochs.clear_cache()
    out = fb._mle(
        paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, beta0=2.0, slip0=0.1,
        dtype=jnp.dtype("float32"), tol=1e-3, features=phi,
    )  # fmt: skip
    assert fb._gradient_value_epochs._cache_size() == 1
    assert np.isfinite([out["beta"], out["slip"]]).all()


def test_the_fit_compiles_nothing_but_its_program(caplog) -> None:
    """_mle's data stay NumPy arrays on the host (issue 29): no program compiled to make
    them (``jnp.asarray``'s ``stage``, ``convert_element_type``), to cast ``theta``, or to
    split the goals across the devices (``_multi_slice``); the gradient program is the
    only one. A grid of its own (11 x 13) so that no other test compiled its shapes."""
    import logging

    free, paths, _ = _world()
    free = np.pad(free, ((0, 1), (0, 1)), constant_values=True)
    phi = wall_distance_feature(~free, 1.0)[None]
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        out = fb._mle(
            paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, beta0=2.0,
            slip0=0.1, dtype=jnp.dtype("float32"), tol=1e-3, features=phi,
        )  # fmt: skip
    compiled = [r.getMessage() for r in caplog.records if r.getMessage().startswith("Compiling")]
    assert [m.split()[1] for m in compiled] == ["jit(_gradient_value_epochs)"]
    assert np.isfinite([out["beta_se"], out["slip_se"], *out["weights_se"]]).all()
