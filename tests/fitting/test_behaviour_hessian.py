"""The behaviour fit's Hessian (issue 29): differences of the gradient program, no program of
its own. The soft solve stops early at ``tol``; forward mode through it (the previous
``jvp(jvp)`` program, compiled for the Hessian alone) differentiates the solve at the epochs
it ran, so the differences hold the solve at those epochs (a cap as data, ``tol < 0``)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
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
    # what is returned is the claim, not its values: traced, not compiled and run (eagerly,
    # each call compiled its own solve: about 3 s of CPU for the two)
    assert jax.eval_shape(lambda: solve(10, None)).epochs is None  # without tol: no count
    without = jax.eval_shape(
        lambda: soft_backward_induction(
            ok,
            keep,
            bonus,
            jnp.asarray(1.5),
            jnp.asarray(0.1),
            n_epochs=400,
            time_cost=1.0,
            tol=1e-4,
        )
    )
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
    # the goals split over the devices there are, as _mle splits them: the fit's float32
    # program of the test below, compiled once for both (results are identical for any
    # split: test_behaviour_fit's split tests)
    data32, n_dev = _data(np.float32, None)
    tol = jnp.asarray(1e-3, np.float32)
    epochs = fb._gradient_value_epochs(jnp.asarray(TH, np.float32), data32, tol, n_dev)[2]
    got = np.asarray(fb._hessian(jnp.asarray(TH, np.float32), data32, int(epochs), n_dev))
    assert np.isfinite(got).all()
    rel = np.linalg.norm(got.astype(np.float64) - want, 2) / np.linalg.norm(want, 2)
    assert rel < 2e-4, rel


def test_the_fit_compiles_one_program_and_its_standard_errors_are_float64s_or_nan(
    caplog,
) -> None:
    """_mle's optimisation and its Hessian run the one program per shape bucket, and
    nothing else is compiled: its data stay NumPy arrays on the host (issue 29), so no
    program is compiled to make them (``jnp.asarray``'s ``stage``,
    ``convert_element_type``), to cast ``theta``, or to split the goals across the devices
    (``_multi_slice``). Every in-memory cache is cleared first (:func:`jax.clear_caches`),
    so that what any earlier test compiled is lowered, and logged, again (until
    2026-11-29 a second fit on a grid of its own, 11 x 13, made that sure: a program of
    its own, about 8 s of CPU cold).

    Its float32 standard errors are float64's where float32 resolves them and NaN, with
    the reason, where not. This world does not identify beta or the wall weight: slip is
    near 0.5 and the likelihood rises towards beta -> inf (float32 stops at beta 39,
    float64 at 73). At float32's optimum the information's two small eigenvalues are
    8.2e-4 and 7.0e-3 in float64, below float32's Hessian round-off (1.8e-3 per entry,
    measured by the stencil's fourth differences): float32's Hessian there had eigenvalues
    -9.8e-4 and 5.8e-3 on this AVX2 host, ``inv(-H)`` two negative variances and beta's
    and the weight's standard errors NaN, silently (on an AVX-512 host other round-off,
    other numbers; on the 11 x 13 grid float32's Hessian happened to be positive definite
    and gave beta 823 and the weight 11.1 where float64's gives 1,600 and 13.0). Slip's
    direction (eigenvalue 7.0) is resolved: its standard error, from the resolved
    directions, is float64's at the same point to 2e-3 (measured 1e-3)."""
    import logging

    free, paths, phi = _world()
    jax.clear_caches()
    with caplog.at_level(logging.WARNING), jax.log_compiles():
        out = fb._mle(
            paths, free, goal_reward=1.0, step_cost=1e-3, time_cost=1.0, beta0=2.0,
            slip0=0.1, dtype=jnp.dtype("float32"), tol=1e-3, features=phi,
        )  # fmt: skip
    compiled = [r.getMessage() for r in caplog.records if r.getMessage().startswith("Compiling")]
    assert [m.split()[1] for m in compiled] == ["jit(_gradient_value_epochs)"]
    assert fb._gradient_value_epochs._cache_size() == 1
    assert np.isfinite([out["beta"], out["slip"], out["slip_se"]]).all()
    assert np.isnan([out["beta_se"], *out["weights_se"]]).all()
    assert "below 10 times the float32 Hessian's error" in out["se_unresolved"]
    # float64 at float32's optimum: every direction resolved, the small ones below
    # float32's round-off
    th = np.r_[np.log(out["beta"]), np.log(out["slip"] / (1 - out["slip"])), out["weights"]]
    data64, n_dev = _data(np.float64)
    epochs = fb._gradient_value_epochs(th, data64, np.asarray(1e-3), n_dev)[2]
    h64 = fb._hessian(jnp.asarray(th), data64, int(epochs), n_dev, with_error=True)
    ref = fb._standard_errors(h64.hessian, h64.error)
    assert ref.resolved.all() and np.isfinite(ref.se).all()
    assert ref.eigenvalues[1] < fb.RESOLVED_EIGENVALUE * 1e-3  # float32's error: 1.8e-3
    slip = out["slip"]
    assert_allclose(out["slip_se"], slip * (1 - slip) * ref.se[1], rtol=2e-3)


def test_standard_errors_leave_out_only_what_the_round_off_decides() -> None:
    """:func:`_standard_errors` against closed forms, with a round-off of 1e-3 per entry (an
    eigenvalue of ``-H`` is resolved above 1e-2): all resolved, ``inv(-H)``'s; one
    direction unresolved (information 5e-3), NaN along it and the other parameter's
    ``1 / sqrt(4)`` when the two are uncoupled or nearly (rotated by 1e-3: the weak
    direction would add at least ``sin^2 / 1e-2 = 1e-4`` to a variance of 0.25, 0.04%),
    NaN for both when coupled (rotated by 0.1: 1.0 against 0.25); a maximum it is not
    (eigenvalue -1) is unresolved too; a non-finite Hessian, all NaN."""
    err = 1e-3
    got = fb._standard_errors(-np.diag([4.0, 0.25]), err)
    assert_allclose(got.se, [0.5, 2.0], rtol=1e-15)
    assert got.resolved.all()

    def rotated(angle, weak):
        c, s = np.cos(angle), np.sin(angle)
        r = np.array([[c, -s], [s, c]])
        return -(r @ np.diag([4.0, weak]) @ r.T)

    got = fb._standard_errors(rotated(0.0, 5e-3), err)
    assert got.se[0] == 0.5 and np.isnan(got.se[1])
    assert list(got.resolved) == [False, True]  # eigenvalues ascending
    got = fb._standard_errors(rotated(1e-3, 5e-3), err)
    assert_allclose(got.se[0], np.cos(1e-3) / 2, rtol=1e-12)
    assert np.isnan(got.se[1])
    assert np.isnan(fb._standard_errors(rotated(0.1, 5e-3), err).se).all()
    got = fb._standard_errors(rotated(0.0, -1.0), err)
    assert got.se[0] == 0.5 and np.isnan(got.se[1])
    assert np.isnan(fb._standard_errors(np.full((2, 2), np.nan), err).se).all()
    assert "not finite" in fb._unresolved_note(
        fb._standard_errors(np.full((2, 2), np.nan), err), "float32"
    )


def test_nan_standard_errors_are_named_with_their_reason_in_the_fit_and_the_cli(
    monkeypatch,
) -> None:
    """fit_behaviour turns _mle's reason into a warning that names the NaN standard errors
    (the fit file keeps the warnings), and ``are-stats fit`` prints it under the class's
    line: before, a float32 fit's NaN standard errors came with no word of why. (_mle is
    replaced by its result on this file's world: no program to compile here.)"""
    from are_stats._cli_jobs import _behaviour_lines

    def mle(paths, free, **kwargs):
        return {
            "beta": 39.3, "beta_se": np.nan, "slip": 0.4996, "slip_se": 0.0945,
            "weights": np.array([-0.09]), "weights_se": np.array([np.nan]), "loglik": -34.7,
            "n_moves": 28, "n_epochs": 100, "converged": True, "se_unresolved": "WHY",
        }  # fmt: skip

    monkeypatch.setattr(fb, "_mle", mle)
    free = np.ones((10, 12), bool)
    t = np.arange(10.0)
    tracks = pd.concat(
        [pd.DataFrame({"id": i, "t": t, "x": 0.5 + t, "y": 1.5 + i}) for i in range(6)]
    )
    fit = fb.fit_behaviour(tracks, free, 1.0, (0.0, 0.0), cell=1.0, features=("walls",))
    want = "class 'all': standard errors of beta, walls weight are NaN: WHY"
    assert fit.warnings == [want]
    assert _behaviour_lines(fit) == [
        "behaviour 'all': beta 39.3 +- nan, slip 0.5 +- 0.095, walls weight -0.09 +- nan",
        f"warning: behaviour {want}",
    ]
