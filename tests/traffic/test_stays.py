"""Stay laws against scipy, closed-form excesses against quadrature, window likelihood truth."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate, optimize, stats

from are_stats.traffic._stays import (
    STAY_LAWS,
    stay_cv,
    stay_log_excess,
    stay_logcdf,
    stay_loglik,
    stay_logpdf,
    stay_logsf,
    stay_sample,
    stay_sample_residual,
    stay_shape_from_cv,
)

SHAPES = {"lognormal": (0.3, 0.8, 1.5)}  # lognormal shape is sigma: cv 0.3 to 2.9
CASES = [
    (law, m, k)
    for law in STAY_LAWS
    for m, k in zip((12.0, 3.5, 8000.0), SHAPES.get(law, (0.7, 2.5, 6.0)), strict=True)
]


def scipy_law(law: str, m: float, k: float):
    if law == "exponential":
        return stats.expon(scale=m)
    if law == "gamma":
        return stats.gamma(a=k, scale=m / k)
    if law == "weibull":
        from scipy.special import gamma as G

        return stats.weibull_min(c=k, scale=m / G(1 + 1 / k))
    return stats.lognorm(s=k, scale=np.exp(np.log(m) - k * k / 2))


@functools.partial(jax.jit, static_argnames="law")
def _density_survival_cdf(law, t, m, k):
    """The three functions in one compiled program per law, shared by the law's cases (op
    by op, every primitive of the incomplete gammas was compiled on its own)."""
    return stay_logpdf(law, t, m, k), stay_logsf(law, t, m, k), stay_logcdf(law, t, m, k)


@pytest.mark.parametrize("law, m, k", CASES)
def test_density_survival_cdf_match_scipy(law, m, k):
    ref = scipy_law(law, m, k)
    t = ref.ppf(np.linspace(0.001, 0.999, 41))
    logpdf, logsf, logcdf = _density_survival_cdf(law, t, m, k)
    np.testing.assert_allclose(logpdf, ref.logpdf(t), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(logsf, ref.logsf(t), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(logcdf, ref.logcdf(t), rtol=1e-8, atol=1e-10)
    assert ref.mean() == pytest.approx(m, rel=1e-12)


def _excess_reference(ref, r):
    """int_r^inf S(u) du by quadrature in log u (heavy tails and long scales alike)."""
    lo = max(r, float(ref.ppf(1e-13)))
    head = lo - r  # S = 1 up to 1e-13 below ppf(1e-13)
    hi = float(ref.isf(1e-17))
    f = lambda v: ref.sf(np.exp(v)) * np.exp(v)  # noqa: E731
    body, _ = integrate.quad(f, np.log(lo), np.log(hi), limit=400, epsabs=0, epsrel=1e-12)
    return head + body


@pytest.mark.parametrize("law, m, k", CASES)
def test_mean_excess_matches_quadrature(law, m, k):
    ref = scipy_law(law, m, k)
    for q in [0.0, 0.1, 0.5, 0.9, 0.99]:
        r = float(ref.ppf(q)) if q > 0 else 0.0
        want = _excess_reference(ref, r)
        got = float(np.exp(stay_log_excess(law, r, m, k)))
        assert got == pytest.approx(want, rel=1e-7), (q, r)
    # at r = 0 the excess is the mean: the equilibrium density S(r)/m integrates to one
    assert float(np.exp(stay_log_excess(law, 0.0, m, k))) == pytest.approx(m, rel=1e-10)


def test_exponential_window_terms_are_the_memoryless_ones():
    mu = 0.25
    stay = np.array([2.0, 3.0, 4.0, 5.0])
    cens = np.array([False, True, False, True])
    trunc = np.array([False, False, True, True])
    ll = stay_loglik("exponential", stay, cens, trunc, 1 / mu)
    want = np.where(cens, -mu * stay, np.log(mu) - mu * stay)
    np.testing.assert_allclose(ll, want, rtol=1e-12)


def test_short_stays_are_interval_censored_at_the_resolution():
    ll = stay_loglik("gamma", [0.0, 0.3, 2.0], [False] * 3, [False] * 3, 10.0, 2.0, 0.5)
    ref = stats.gamma(a=2.0, scale=5.0)
    np.testing.assert_allclose(ll, [ref.logcdf(0.5), ref.logcdf(0.5), ref.logpdf(2.0)])
    assert np.all(np.isfinite(ll))


@pytest.mark.parametrize("law", STAY_LAWS)
def test_gradients_are_finite_and_match_finite_differences(law):
    stay = np.array([0.0, 0.5, 3.0, 9.0, 40.0])
    cens = np.array([False, False, True, False, True])
    trunc = np.array([False, True, False, True, True])

    def total(p):
        return stay_loglik(law, stay, cens, trunc, p[0], p[1], 0.25).sum()

    # one program gives the values and the gradient (a jitted ``total`` and ``jax.grad``
    # of it were two, each compiling the incomplete gammas' loops)
    value_and_grad = jax.jit(jax.value_and_grad(total))
    p = np.array([6.0, 1.7])
    g = np.asarray(value_and_grad(p)[1])
    eps = 1e-6

    def value(q):
        return float(value_and_grad(q)[0])

    fd = [(value(p + eps * e) - value(p - eps * e)) / (2 * eps) for e in np.eye(2)]
    assert np.all(np.isfinite(g))
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7)


def test_incomplete_gamma_derivatives_match_jax_own():
    """Our Q(a, x) and P(a, x) (central difference in ``a``) against JAX's series derivative."""
    from jax.scipy import special

    from are_stats.traffic._stays import gammainc, gammaincc

    a = np.array([0.3, 0.9, 2.5, 7.0, 40.0])[:, None]
    x = np.array([1e-3, 0.2, 1.0, 3.0, 12.0, 60.0])[None, :]
    pairs = ((gammaincc, special.gammaincc), (gammainc, special.gammainc))

    @jax.jit
    def everything(a, x):
        """Both functions' derivatives and values, ours and JAX's, from one compiled
        program (op by op, one argument at a time: 15.0 s of CPU cold against 12.5 s for
        one program per function and kind, 2026-11-28; eight programs then)."""
        out = []
        for ours, theirs in pairs:
            for f in (ours, theirs):
                out.append((jax.vmap(jax.vmap(jax.grad(f, (0, 1))))(a, x), f(a, x)))
        return out

    results = everything(*np.broadcast_arrays(a, x))
    for i in range(len(pairs)):
        (g, value), (want, want_value) = results[2 * i], results[2 * i + 1]
        for arg in (0, 1):
            np.testing.assert_allclose(g[arg], want[arg], rtol=1e-5, atol=1e-10)
        # one loop of JAX's recurrences, not JAX's primitive: one program's rounding
        np.testing.assert_allclose(value, want_value, rtol=1e-14)


def test_gamma_likelihood_gradient_has_one_incomplete_gamma_loop_per_function():
    """The gamma window likelihood and its gradient (what NUTS compiles) evaluate the
    incomplete gammas in two vectorised calls (Q for the tails, P at the resolution), not
    one per term and derivative: each call is a loop XLA compiles for seconds."""
    stay = np.array([0.0, 0.5, 3.0, 9.0, 40.0])
    cens = np.array([False, False, True, False, True])
    trunc = np.array([False, True, False, True, True])

    def total(p):
        return stay_loglik("gamma", stay, cens, trunc, p[0], p[1], 0.25).sum()

    text = jax.jit(jax.value_and_grad(total)).lower(np.array([6.0, 1.7])).as_text()
    # each incomplete gamma holds two loops (its series and its continued fraction)
    assert text.count("stablehlo.while") <= 4


@pytest.mark.parametrize("law, m, k", CASES)
def test_sampler_matches_law(law, m, k):
    # Kolmogorov-Smirnov at alpha = 1e-4 per case (12 cases: false-failure rate about 1e-3)
    x = np.asarray(stay_sample(jax.random.key(7), law, m, k, (4000,)))
    assert stats.kstest(x, scipy_law(law, m, k).cdf).pvalue > 1e-4


@pytest.mark.parametrize("law", STAY_LAWS[1:])
def test_cv_and_its_inverse(law):
    for k in [0.4, 1.0, 3.0]:
        ref = scipy_law(law, 5.0, k)
        assert stay_cv(law, k) == pytest.approx(ref.std() / ref.mean(), rel=1e-9)
        assert stay_shape_from_cv(law, stay_cv(law, k)) == pytest.approx(k, rel=1e-6)


def _stationary_window(rng, law, m, k, rate, t0, t1):
    """Arrivals of a stationary M/G/inf process seen through [t0, t1]."""
    burn = t0 - 60 * m
    n = rng.poisson(rate * (t1 - burn))
    arrive = np.sort(rng.uniform(burn, t1, n))
    life = scipy_law(law, m, k).rvs(size=n, random_state=rng)
    leave = arrive + life
    seen = leave >= t0
    arrive, leave = arrive[seen], leave[seen]
    trunc = arrive < t0
    cens = leave > t1
    start = np.where(trunc, t0, arrive)
    stay = np.minimum(leave, t1) - start
    return stay, cens, trunc


@pytest.mark.slow
@pytest.mark.parametrize("law", STAY_LAWS)
def test_window_likelihood_recovers_the_truth(law):
    """Left-truncated artefacts use the equilibrium law: the MLE of (mean, shape) from one
    stationary window lands within 4 standard errors (observed information) of the truth."""
    m, k = (20.0, 1.0) if law == "exponential" else (20.0, 2.0 if law != "lognormal" else 0.5)
    rng = np.random.default_rng(11)
    stay, cens, trunc = _stationary_window(rng, law, m, k, 2.0, 0.0, 600.0)
    assert trunc.sum() > 20 and cens.sum() > 20

    @jax.jit
    def nll(p):
        return -stay_loglik(law, stay, cens, trunc, jnp.exp(p[0]), jnp.exp(p[1])).sum()

    grad = jax.jit(jax.grad(nll))

    def hessian(p, eps=1e-5):  # JAX has no second derivative of igamma in its shape
        cols = [(grad(p + eps * e) - grad(p - eps * e)) / (2 * eps) for e in np.eye(len(p))]
        return np.asarray(cols)

    x0 = np.log([np.mean(stay) * 1.5, 1.0])
    res = optimize.minimize(
        lambda p: float(nll(p)), x0, jac=lambda p: np.asarray(grad(p)), method="BFGS"
    )
    # BFGS's "precision loss" (status 2) is its line search finding no lower value in the
    # last bits: at the optimum of a likelihood with incomplete gammas it depends on the
    # host's kernels (seen on an AVX2 host for the gamma law, gradient 7e-6). The optimum
    # is what the gradient says it is; the test's claim is the 4 standard errors below.
    assert res.success or (res.status == 2 and np.abs(res.jac).max() < 1e-3), res
    free = slice(0, 1) if law == "exponential" else slice(0, 2)
    se = np.sqrt(np.diag(np.linalg.inv(hessian(res.x)[free, free])))
    truth = np.log([m, k])[free]
    assert np.all(np.abs(res.x[free] - truth) < 4 * se), (np.exp(res.x), se)


@pytest.mark.parametrize("law, m, k", CASES)
def test_residual_sampler_follows_the_equilibrium_law(law, m, k):
    """Residual stays against the equilibrium cdf 1 - E[(T - r)^+] / m (KS, alpha 1e-4).

    4000 draws, as test_sampler_matches_law's: JAX's samplers (the gamma's rejection loop)
    are compiled once for both tests' shape (KS's false-failure rate is alpha whatever
    the size; 3000 draws until 2026-11-29)."""
    x = np.asarray(stay_sample_residual(jax.random.key(9), law, m, k, (4000,)))

    def cdf(r):
        return 1.0 - np.exp(np.asarray(stay_log_excess(law, r, m, k))) / m

    assert stats.kstest(x, cdf).pvalue > 1e-4


def _fit_range(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shapes and arguments of the gamma law's window terms over what a fit explores: the
    shape ``k = e^eta`` for ``|eta| <= 7`` (the mode search is bounded at 12, the shipped
    log's mode is near 4), ``x = k r / m`` from ``e^-12`` to ``e^5`` times the shape."""
    rng = np.random.default_rng(seed)
    a = np.exp(rng.uniform(-7.0, 7.0, n))
    x = a * np.exp(rng.uniform(-12.0, 5.0, n))
    return a, x, rng.random(n) < 0.5


def test_incomplete_gamma_in_one_loop_is_scipys_and_jaxs():
    """``P`` (``lower``) and ``Q`` in one loop: SciPy's values to 1e-10 relative over the
    fit's range (where a tail is above 1e-300), and JAX's own to one rounding (the same
    recurrences; most of them the same bits), with JAX's values at the domain's edges."""
    from jax.scipy import special
    from scipy import special as sc

    from are_stats.traffic._stays import incomplete_gamma

    a, x, lower = _fit_range(20000, 4)
    edge_a = np.array([0.0, 1.0, 2.0, 0.0, -1.0, 3.0, np.nan, 2.0, 1e-300])
    edge_x = np.array([0.0, 0.0, np.inf, 1.0, 1.0, -1.0, 1.0, 2.0, 5.0])

    @jax.jit
    def ours_and_jaxs(a, x, lower, edge_a, edge_x):
        """Ours and JAX's, on the range and at the edges, from one compiled program (JAX's
        op by op and ours at the edges eagerly were 6.0 s of CPU cold, this 3.7 s, with
        the same bits, 2026-11-29)."""
        jaxs = jnp.where(lower, special.gammainc(a, x), special.gammaincc(a, x))
        edges = [
            (incomplete_gamma(edge_a, edge_x, jnp.full(edge_a.size, lo)), theirs(edge_a, edge_x))
            for lo, theirs in ((False, special.gammaincc), (True, special.gammainc))
        ]
        return incomplete_gamma(a, x, lower), jaxs, edges

    got, jaxs, edges = ours_and_jaxs(a, x, lower, edge_a, edge_x)
    got, jaxs = np.asarray(got), np.asarray(jaxs)
    want = np.where(lower, sc.gammainc(a, x), sc.gammaincc(a, x))
    ok = want > 1e-300
    assert ok.mean() > 0.9
    np.testing.assert_allclose(got[ok], want[ok], rtol=1e-10)
    np.testing.assert_allclose(got, jaxs, rtol=4e-16, atol=2e-16)
    assert np.mean(got == jaxs) > 0.99
    for ours, theirs in edges:
        np.testing.assert_array_equal(ours, theirs)


def test_gamma_unit_likelihood_is_one_incomplete_gamma_loop():
    """The gamma law's censored terms (survival, mean excess, the resolution's
    distribution function) in ONE loop, value and gradient (what a Laplace and a NUTS
    program compile; each loop XLA compiles for about a second at its default level),
    with the values of the per-term functions."""
    from are_stats.traffic import stay_unit_loglik, stay_units

    rng = np.random.default_rng(2)
    stay = rng.gamma(3.0, 4.0, 37)
    units = stay_units(stay, rng.random(37) < 0.3, rng.random(37) < 0.3)

    def terms(p):
        return stay_unit_loglik({"stay_mean": p[0], "stay_shape": p[1]}, units, "gamma", 0.25)

    def total(p):
        return terms(p).sum()

    for fn in (total, jax.value_and_grad(total)):
        text = jax.jit(fn).lower(np.array([9.0, 2.0])).as_text()
        assert text.count("stablehlo.while") == 1

    # the values, the gradient and the differences from one compiled program, the per-term
    # functions from another (op by op, the same checks compiled some hundred one-operation
    # programs: 26 s of CPU cold on 2026-11-28)
    def total_and_terms(p):
        t = terms(p)
        return t.sum(), t

    value_and_grad = jax.jit(jax.value_and_grad(total_and_terms, has_aux=True))
    p = np.array([9.0, 2.0])
    (_, got), g = value_and_grad(p)

    @jax.jit
    def per_term(p):
        return stay_loglik("gamma", stay, units.censored[:37], units.truncated[:37], *p, 0.25)

    np.testing.assert_allclose(np.asarray(got)[:37], per_term(p), rtol=1e-13)
    eps = 1e-6

    def value(q):
        return float(value_and_grad(q)[0][0])

    fd = [(value(p + eps * e) - value(p - eps * e)) / (2 * eps) for e in np.eye(2)]
    np.testing.assert_allclose(np.asarray(g), fd, rtol=1e-5, atol=1e-7)


def test_padded_incomplete_gamma_is_the_unpadded_call():
    """On concrete inputs the arrays are flattened and padded to a shared program size (here
    the 8 entries of other tests' calls): the values are those of the loop called at the
    exact shape, bit for bit, series and continued fraction, at the domain's edges too."""
    from are_stats.traffic._stays import _incomplete_gamma, incomplete_gamma

    a = np.array([[0.0, 0.5, 3.0], [12.0, np.nan, 2.0]])
    x = np.array([[1.0, 0.2, 40.0], [11.0, 1.0, np.inf]])
    got = incomplete_gamma(a, x, False)
    assert got.shape == (2, 3) and got.dtype == np.float64
    np.testing.assert_array_equal(np.asarray(got), np.asarray(_incomplete_gamma(a, x, False)))
