"""The Laplace approximation's start: the inits taken to the unconstrained scale in NumPy
give numpyro's own inverse transforms (the truth), and map back to the inits; the latent
sites' layout, kept on disk, is read by a later process instead of tracing the model."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from numpyro import handlers
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to

from are_stats.fitting import _laplace as lap
from are_stats.fitting._laplace import _unconstrain
from are_stats.traffic import stay_model, stay_units

CASES = [
    (constraints.real, np.array(0.7)),
    (constraints.independent(constraints.real, 1), np.array([-1.5, 0.0, 2.0])),
    (constraints.positive, np.array(5.0)),
    (constraints.positive, np.array([1e-3, 2.0, 40.0])),
    (constraints.unit_interval, np.array(0.3)),
    (constraints.unit_interval, np.array([0.01, 0.5, 0.99])),
    (constraints.simplex, np.full(4, 0.25)),
    (constraints.simplex, np.array([0.1, 0.6, 0.05, 0.25])),
    (constraints.interval(2.0, 5.0), np.array(3.0)),  # not in NumPy: numpyro's inverse
]


@pytest.mark.parametrize(("support", "value"), CASES)
def test_unconstrain_is_numpyros_inverse(support, value):
    t = biject_to(support)
    got = _unconstrain(t, value)
    want = np.asarray(t.inv(jnp.asarray(value, jnp.float64)))
    assert got.dtype == np.float64 and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(t(jnp.asarray(got))), value, rtol=1e-12, atol=1e-14)


def _stay_kwargs(law: str = "gamma") -> dict:
    rng = np.random.default_rng(3)
    stay = rng.gamma(2.0, 30.0, 40)
    units = stay_units(stay, rng.random(40) < 0.2, rng.random(40) < 0.1)
    return {"units": units, "law": law, "mean_centre": np.asarray(60.0), "resolution": 0.0}


def _numpyro_layout(model, kwargs) -> dict:
    """The truth: each latent site's unconstrained shape, from numpyro's own concrete trace."""
    tr = handlers.trace(handlers.seed(model, 0)).get_trace(**kwargs)
    return {
        name: tuple(biject_to(s["fn"].support).inverse_shape(jnp.shape(s["value"])))
        for name, s in tr.items()
        if s["type"] == "sample" and not s["is_observed"]
    }


@pytest.fixture
def new_process(tmp_path, monkeypatch):
    """A program folder of its own; ``forget()`` drops what the process learned (as a new
    process would start)."""
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", str(tmp_path / "programs"))

    def forget() -> None:
        monkeypatch.setattr(lap, "_LAYOUTS", {})
        monkeypatch.setattr(lap, "_SITES", {})

    forget()
    return tmp_path / "programs", forget


def test_a_kept_site_layout_is_read_not_traced(new_process, monkeypatch):
    folder, forget = new_process
    kwargs = _stay_kwargs()
    init = {"stay_mean_z": 0.4, "stay_shape_eta": -0.3}
    want = _numpyro_layout(stay_model, kwargs)
    first = lap._init_z(stay_model, kwargs, init)
    assert {n: np.shape(v) for n, v in first.items()} == want
    assert len(list(folder.glob("*.json"))) == 1
    forget()

    def no_trace(*args, **kw):
        raise AssertionError("the model was traced again")

    monkeypatch.setattr(lap.jax, "eval_shape", no_trace)
    second = lap._init_z(stay_model, kwargs, init)
    assert second.keys() == first.keys()
    for name in first:
        np.testing.assert_array_equal(second[name], first[name])
    assert lap.laplace_dimension(stay_model, kwargs, None) == sum(
        int(np.prod(s)) for s in want.values()
    )


@pytest.mark.parametrize("content", ["", "not json", '{"a": 1}', '[["x", "tanh", []]]'])
def test_a_damaged_site_record_is_traced_again(new_process, content):
    folder, forget = new_process
    kwargs = _stay_kwargs("weibull")
    lap._init_z(stay_model, kwargs, None)
    (path,) = folder.glob("*.json")
    good = path.read_text()
    path.write_text(content)
    forget()
    z0 = lap._init_z(stay_model, kwargs, None)
    assert {n: np.shape(v) for n, v in z0.items()} == _numpyro_layout(stay_model, kwargs)
    assert path.read_text() == good  # rewritten whole


def _interval_model() -> None:
    numpyro.sample("a", dist.Uniform(2.0, 5.0))
    numpyro.sample("b", dist.Exponential(1.0))


def test_a_site_numpyro_must_invert_starts_at_its_init(new_process):
    """A support outside the NumPy inverses (an interval) is inverted by numpyro."""
    folder, _ = new_process
    z0 = lap._init_z(_interval_model, {}, {"a": 3.0, "b": 2.0})
    want = np.asarray(biject_to(constraints.interval(2.0, 5.0)).inv(jnp.asarray(3.0)))
    np.testing.assert_allclose(z0["a"], want, rtol=1e-12)
    np.testing.assert_allclose(z0["b"], np.log(2.0), rtol=1e-12)
    assert not list(folder.glob("*.json"))  # a test's local model has no stable name


def test_mode_searches_hold_blas_to_one_thread_until_the_last_ends():
    """The BLAS limit of the mode search is the process's: the first search sets it, the
    last one to end (in any thread) restores the original."""
    import threadpoolctl

    def blas_threads():
        return [
            i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"
        ]

    before = blas_threads()
    if not before:
        pytest.skip("no BLAS library that threadpoolctl can see")
    with lap._one_blas_thread():
        assert set(blas_threads()) == {1}
        with lap._one_blas_thread():  # a second search (another thread) starts ...
            assert set(blas_threads()) == {1}
        assert set(blas_threads()) == {1}  # ... and ends first: the limit holds
    assert blas_threads() == before


@pytest.mark.parametrize("law", ["weibull", "lognormal"])
def test_a_run_is_the_same_whatever_points_a_call_holds(new_process, monkeypatch, law):
    """Each point's values are computed alone (``vmap``): a run with calls of 8 points (the
    2-parameter stencil's size) and one with calls of :data:`MIN_BATCH` give the same
    mode, draws, log-likelihoods and weights, to the bit."""
    import jax

    from are_stats.fitting._traffic import _stay_draw_loglik

    kwargs = _stay_kwargs(law)
    init = {"stay_mean_z": 0.0, "stay_shape_eta": 0.0}
    runs = []
    for size in (8, lap.MIN_BATCH):
        monkeypatch.setattr(lap, "MIN_BATCH", size)
        assert lap._batch_size(2) == size
        run = lap.run_laplace(
            jax.random.key(5), stay_model, kwargs, init, num_draws=203, pointwise=_stay_draw_loglik
        )
        runs.append(run)
    small, large = runs
    assert lap.MIN_BATCH > 8 and small.converged and large.converged
    _assert_same_run(small, large)


def _assert_same_run(a: lap.LaplaceRun, b: lap.LaplaceRun) -> None:
    """Two Laplace runs with the same mode, draws, log-likelihoods and weights, to the bit."""
    for name in a.mode:
        np.testing.assert_array_equal(a.mode[name], b.mode[name])
    for name in a.samples:
        np.testing.assert_array_equal(a.samples[name], b.samples[name])
    np.testing.assert_array_equal(a.loglik, b.loglik)
    np.testing.assert_array_equal(a.log_ratio, b.log_ratio)


@pytest.mark.parametrize("law", ["gamma", "weibull"])
def test_the_likelihood_computed_once_is_the_same_run(new_process, law):
    """With ``likelihood`` naming the model's last factor, the program takes the potential's
    likelihood from the pointwise terms (computed once a point, the model's own factor
    dropped): the same mode, draws, log-likelihoods and weights, to the bit, and a program
    with one copy of the incomplete-gamma loop instead of two."""
    import jax

    from are_stats.fitting._nuts import _split_kwargs
    from are_stats.fitting._traffic import _stay_draw_loglik

    kwargs = {**_stay_kwargs(law), "resolution": 1.0}
    init = {"stay_mean_z": 0.0, "stay_shape_eta": 0.0}
    runs = [
        lap.run_laplace(
            jax.random.key(5),
            stay_model,
            kwargs,
            init,
            num_draws=203,
            pointwise=_stay_draw_loglik,
            likelihood=site,
        )
        for site in (None, "stays")
    ]
    whole, once = runs
    assert whole.converged and once.converged
    _assert_same_run(whole, once)
    arrays, treedef, static = _split_kwargs(kwargs)
    zs = {"stay_mean_z": np.zeros(4), "stay_shape_eta": np.zeros(4)}
    loops = [
        lap._batch_fn(stay_model, treedef, static, _stay_draw_loglik, site)
        .lower(arrays, zs)
        .as_text()
        .count("stablehlo.while")
        for site in (None, "stays")
    ]
    assert loops == [2, 1]  # gamma: its censored terms; weibull: its mean excess


def test_a_likelihood_that_is_no_factor_is_an_error(new_process):
    import jax

    from are_stats.fitting._traffic import _stay_draw_loglik

    init = {"stay_mean_z": 0.0, "stay_shape_eta": 0.0}
    for site in ("stay_mean", "stays_typo"):
        with pytest.raises(ValueError, match=r"likelihood: expected .*\['stays'\].*" + site):
            lap.run_laplace(
                jax.random.key(5),
                stay_model,
                _stay_kwargs("weibull"),
                init,
                num_draws=10,
                pointwise=_stay_draw_loglik,
                likelihood=site,
            )
