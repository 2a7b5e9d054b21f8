"""A candidate's Laplace program at XLA's default optimisation (``optimise=True``, what
``fit_traffic`` compiles for the MMPP, gamma and groups+hawkes candidates) gives the
approximation of the cheap program: the same mode, draws, weights and PSIS-LOO, to
rounding. XLA's optimisation may reorder sums (last bits), never the model."""

from __future__ import annotations

import jax
import numpy as np

from are_stats import shipped_path
from are_stats.fitting import _traffic
from are_stats.fitting._laplace import laplace_loo, run_laplace
from are_stats.logs import read_field_log


def test_an_optimised_program_gives_the_cheap_programs_approximation():
    data = read_field_log(shipped_path("courtyard_traffic", "log")).to_lifecycle_data()
    out = _traffic.TrafficFit("poisson", "exponential", "uniform")
    setup = _traffic._setup(jax.random.key(3), data, "groups+hawkes", "exponential", None, out)
    key, model, kwargs, init = setup.calls["arrivals", "groups+hawkes"]
    pointwise = _traffic._arrival_draw_loglik
    cheap, opt = (
        run_laplace(key, model, kwargs, init, num_draws=200, pointwise=pointwise, optimise=o)
        for o in (False, True)
    )
    assert cheap.converged and opt.converged
    # the same key: the runs differ only by the programs' rounding (about 1e-13 of the log
    # density), which the Hessian's second differences (steps of 1e-4) enlarge; measured
    # 2026-11-28: modes 1e-7 apart, draws 0.2% of a posterior sd, elpd 7e-4 nats, k 1e-3
    for name in cheap.mode:
        np.testing.assert_allclose(opt.mode[name], cheap.mode[name], rtol=0, atol=1e-6)
    for name in cheap.samples:
        sd = np.std(cheap.samples[name], axis=0)
        assert np.all(np.abs(opt.samples[name] - cheap.samples[name]) <= 0.01 * sd), name
    np.testing.assert_allclose(opt.loglik, cheap.loglik, rtol=0, atol=0.01)
    top_opt, top_cheap = opt.log_ratio.max(), cheap.log_ratio.max()
    np.testing.assert_allclose(opt.log_ratio - top_opt, cheap.log_ratio - top_cheap, atol=0.01)
    n = int(np.sum(setup.plain.bin_weight))
    (e_cheap, k_cheap), (e_opt, k_opt) = (
        laplace_loo(r._replace(loglik=r.loglik[:, :n])) for r in (cheap, opt)
    )
    assert abs(e_opt.sum() - e_cheap.sum()) < 0.01
    np.testing.assert_allclose(k_opt, k_cheap, rtol=0, atol=0.01)
