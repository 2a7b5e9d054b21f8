"""Laplace approximation of a numpyro model, and PSIS-LOO from its draws (no NUTS).

``are-stats fit --method em`` chooses the traffic models without compiling a NUTS program:
each candidate's posterior is approximated by a Gaussian on the unconstrained scale at its
mode (the Laplace approximation), and the candidates are compared by the same rule as the
NUTS fits (:func:`~are_stats.fitting.choose_simplest` on pointwise ``elpd``), with the
leave-one-out densities estimated by importance sampling from that Gaussian:
``log r_si = log p(theta_s, y) - log q(theta_s) - log p(y_i | theta_s)`` for draws
``theta_s`` of ``q = Normal(z_hat, H^-1)`` (``z_hat`` the mode, ``H`` the Hessian of minus
the log density there), Pareto-smoothed (PSIS) per unit ``i``, and
``elpd_i = log sum_s w_si p(y_i | theta_s)``. The first two terms correct the draws of
``q`` toward the posterior, the third leaves unit ``i`` out (Vehtari, Gelman and Gabry
2017, Sect. 2, with a proposal other than the posterior). The draws kept for the chosen
model are the Gaussian's (a Laplace posterior; a fit records the comparison in its
``traffic_model_choice`` attribute).

One small program is compiled per candidate (cheap XLA optimisation unless the caller
asks for XLA's default, for a likelihood with a long recursion; kept in the process and on
disk like the NUTS programs): the log density, constrained sites and pointwise
log-likelihood of a batch of points, without derivatives. The mode is found by SciPy's
L-BFGS-B with central-difference gradients (each gradient one batch), the Hessian by
central second differences, and the draws are scored batch by batch through the same
program. Array arguments of the model are arguments of the program, so logs of one size
share it.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, NamedTuple  # Any: programs' pytrees, _blas_users' mixed pair

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from numpyro import handlers
from numpyro.distributions.distribution import Unit
from numpyro.distributions.transforms import (
    ExpTransform,
    IdentityTransform,
    IndependentTransform,
    SigmoidTransform,
    StickBreakingTransform,
    Transform,
    biject_to,
)
from numpyro.infer.util import potential_energy
from scipy.optimize import minimize
from scipy.special import gammaln, logsumexp
from threadpoolctl import threadpool_limits

from are_stats._program_cache import TRACE_LOCK, compile_program, load_record, store_record
from are_stats.fitting._nuts import (
    _cached,
    _fn_key,
    _hashable,
    _join_kwargs,
    _shapes,
    _split_kwargs,
)
from are_stats.fitting._psis import psislw

if TYPE_CHECKING:
    from jax.tree_util import PyTreeDef
    from numpyro.distributions.constraints import Constraint

    #: What a batch program gives for each point: its potential energy, its sites
    #: (constrained, deterministic ones included) and the pointwise log-likelihood.
    _Batch = tuple[jax.Array, dict[str, jax.Array], jax.Array | dict[str, jax.Array]]

__all__ = [
    "RESAMPLE_MAX_K",
    "LaplaceRun",
    "Resampled",
    "importance_resample",
    "laplace_dimension",
    "laplace_loo",
    "laplace_program",
    "run_laplace",
]


#: The mode is searched within ``[-Z_BOUND, Z_BOUND]`` on the unconstrained scale (the
#: traffic models centre every rate on its empirical value, so ``e^12`` away is no data's).
Z_BOUND = 12.0
#: Iterations of the mode search at most (a well-posed candidate needs a few dozen).
MAX_ITER = 200
#: Largest Pareto ``k`` of the importance weights whose resampled draws stand for the
#: posterior (Vehtari et al. 2024, "Pareto smoothed importance sampling": above 0.7 the
#: estimates' error no longer shrinks at the Monte Carlo rate).
RESAMPLE_MAX_K = 0.7


class LaplaceRun(NamedTuple):
    """Draws of a Laplace approximation and what the comparison needs.

    Attributes
    ----------
    samples : dict of str to (S, ...) ndarray
        Constrained and deterministic sites of ``S`` draws from the Gaussian.
    loglik : (S, n) ndarray
        Pointwise log-likelihood of each draw.
    log_ratio : (S,) ndarray
        ``log p(theta_s, y) - log q(theta_s)``: importance log weights toward the posterior.
    mode : dict of str to ndarray
        The mode on the unconstrained scale.
    converged : bool
        Whether the mode search converged at a finite log density inside the bounds
        (``|z| < Z_BOUND``), within :data:`MAX_ITER` iterations.
    name : str
    redraw : callable or None
        ``redraw(key, num_draws, df)``: a :class:`LaplaceRun` of ``num_draws`` draws from
        the Student-t with ``df`` degrees of freedom at the same mode and scale (the
        Gaussian's heavier-tailed relative, through the same compiled program), for
        :func:`importance_resample` where the Gaussian's tails are too light.
    """

    samples: dict
    loglik: np.ndarray
    log_ratio: np.ndarray
    mode: dict
    converged: bool
    name: str
    redraw: Callable[[jax.Array, int, float], LaplaceRun] | None = None


_BLAS_LOCK = threading.Lock()
#: Mode searches running, and the BLAS thread limit they hold (the first one sets it).
_blas_users: list[Any] = [0, None]


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[None]:
    """BLAS (OpenBLAS, MKL) on one thread inside the block, its limit restored after the
    last of the blocks running in any thread (the limit is the process's).

    SciPy's L-BFGS-B calls BLAS and LAPACK on ``d``-sized vectors and matrices a few times
    an iteration; a multithreaded OpenBLAS wakes and syncs its threads for each, which
    cost 37 ms of the caller's CPU per mode search of a 7-dimensional quadratic against
    1.7 ms on one thread (``OPENBLAS_NUM_THREADS=1``; 30 searches, 14 iterations each,
    SciPy 1.17 with its OpenBLAS 0.3.30, 2026-11-27 on the loaded 2-core machine), plus
    what its spinning threads burn. The values are the same: these sizes are far below
    OpenBLAS's threading thresholds, so one thread computes what one of several did.
    """
    with _BLAS_LOCK:
        if _blas_users[0] == 0:
            _blas_users[1] = threadpool_limits(limits=1, user_api="blas")
        _blas_users[0] += 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _blas_users[0] -= 1
            if _blas_users[0] == 0:
                _blas_users[1].restore_original_limits()
                _blas_users[1] = None


def _batch_fn(
    model: Callable,
    treedef: PyTreeDef,
    static: tuple,
    pointwise: Callable,
    likelihood: str | None = None,
) -> Callable[[list, dict], _Batch]:
    """``(arrays, zs) -> (potential, sites, pointwise)`` of each point of a batch, jitted.

    With ``likelihood`` (the name of the model's factor site whose value is the sum of
    ``pointwise``), the likelihood is computed once a point: the potential is that of the
    model without the factor (:func:`numpyro.handlers.block`) minus the sum of the
    pointwise terms, and the model's own computation of the factor is dead code that the
    compiler drops. Where the factor is the model's last sample site this is the same
    arithmetic, in the same order, as the whole model's potential: the same bits.

    The model runs once a point: the constrained and deterministic sites are read off
    the potential's own run (a trace inside its substitution), not off a second run of
    the model (:func:`numpyro.infer.util.constrain_fn`), which computed the same values
    again and doubled what is traced, lowered and handed to XLA.
    """

    def batch(arrays: list, zs: dict) -> _Batch:
        kwargs = _join_kwargs(arrays, treedef, static)

        def one(u: dict) -> _Batch:
            # one run of the model gives both the potential and the sites: the trace
            # inside the block (and the substitution) sees the constrained values, the
            # deterministic sites and the factor the potential leaves out
            seen = handlers.trace(model)
            pe = potential_energy(
                seen if likelihood is None else handlers.block(seen, hide=[likelihood]),
                (),
                kwargs,
                u,
            )
            tr = seen.trace
            if likelihood is not None:
                _check_factor(tr, likelihood)
            s = {n: v["value"] for n, v in tr.items() if n in u or v["type"] == "deterministic"}
            ll = pointwise(s, **kwargs)
            if likelihood is not None:
                # -(log prior + log Jacobian + sum ll): negation is exact, so the same
                # rounding as numpyro's sum over the sites with the factor last
                pe = pe - jnp.sum(ll)
            return pe, s, ll

        return jax.vmap(one)(zs)

    return jax.jit(batch)


def _check_factor(tr: dict, name: str) -> None:
    """Raise unless ``name`` is a factor site (``numpyro.factor``) of the traced model."""
    site = tr.get(name)
    if site is None or site["type"] != "sample" or not isinstance(site["fn"], Unit):
        factors = [n for n, v in tr.items() if v["type"] == "sample" and isinstance(v["fn"], Unit)]
        raise ValueError(
            f"likelihood: expected the name of one of the model's factor sites {factors}, "
            f"got {name!r}"
        )


#: XLA options of a candidate's program: cheap, and with ``optimise`` (XLA's default
#: optimisation). The CPU fusion emitters are off in both: the shipped log's nine programs
#: compiled in 7.3-8.7 s of CPU instead of 12.4-14.2 s with them, and ran as fast (the
#: cheap ones compile in a third to a half of the time). NUTS programs keep them: a NUTS
#: fit of the shipped log's group arrivals sampled in 2.6 s of CPU with them, 3.7 s without.
_CHEAP_OPTIONS = {
    "xla_backend_optimization_level": 0,
    "xla_llvm_disable_expensive_passes": True,
    "xla_cpu_use_fusion_emitters": False,
}
_DEFAULT_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
#: ``optimise="light"``: XLA's first backend optimisation level instead of its default
#: (LLVM's -O1 instead of -O2). The gamma stays' program compiled in 0.94-1.07 s of CPU
#: instead of 1.33-1.49 s and gave the same bits; its batches ran in 2.9-3.3 ms instead
#: of 2.9-3.2 ms (138 a fit: under 0.1 s more; 2026-11-29, the shipped log, the loaded
#: 2-core machine). The MMPP and Hawkes programs round differently there and ran up to
#: twice as long: they keep the default.
_LIGHT_OPTIONS = {"xla_cpu_use_fusion_emitters": False, "xla_backend_optimization_level": 1}


def _options(optimise: bool | str) -> dict:
    """XLA options of a candidate's program: cheap (False), XLA's default (True) or
    ``"light"`` (see :data:`_LIGHT_OPTIONS`)."""
    if optimise == "light":
        return _LIGHT_OPTIONS
    if isinstance(optimise, bool):
        return _DEFAULT_OPTIONS if optimise else _CHEAP_OPTIONS
    raise ValueError(f"optimise: expected True, False or 'light', got {optimise!r}")


def _program(
    name: str,
    fn: Callable[..., Any],
    args: tuple,
    key_parts: tuple,
    optimise: bool | str = False,
) -> Callable[..., Any]:
    """``fn`` compiled for ``args`` with cheap XLA optimisation (small programs run a few
    times; ``optimise``: XLA's default optimisation, or ``"light"``: its first level),
    kept in the process and, traced, on disk (as the NUTS programs)."""
    options = _options(optimise)
    key = _hashable((name, *key_parts, _shapes(args), optimise))
    return _cached(key, lambda: compile_program(fn, args, key, options), {})


def _init_z(model: Callable, kwargs: dict, init: dict | None) -> dict:
    """The start on the unconstrained scale: ``init`` where given, else 0.

    The latent sites, their transforms and shapes are those of :func:`_site_layout` (an
    abstract trace of the model, or its record on disk).
    """
    z0 = {}
    for name, (kind, zshape) in _site_layout(model, kwargs).items():
        if init and name in init:
            if kind is None:  # a transform not inverted in NumPy: the traced support's
                support = _latent_sites(model, kwargs)[name][0]
                z0[name] = _unconstrain(biject_to(support), init[name])
            else:
                z0[name] = _inverse(kind, init[name])
        else:
            z0[name] = np.zeros(zshape)
    return z0


#: The transforms :func:`_unconstrain` inverts in NumPy, by the name a site layout records
#: (checked in this order, as the classes could share a base).
_KINDS: dict[str, type] = {
    "identity": IdentityTransform,
    "exp": ExpTransform,
    "sigmoid": SigmoidTransform,
    "stick_breaking": StickBreakingTransform,
}


def _kind(transform: Transform) -> str | None:
    """The name in :data:`_KINDS` of ``transform`` (inside ``IndependentTransform``s), or
    None for a transform numpyro must invert."""
    t = transform
    while isinstance(t, IndependentTransform):
        t = t.base_transform
    for name, cls in _KINDS.items():
        if isinstance(t, cls):
            return name
    return None


def _unconstrain(transform: Transform, value: npt.ArrayLike) -> np.ndarray:
    """``transform.inv(value)``, in NumPy for the transforms of the traffic models' sites.

    The identity, ``exp`` (positive), sigmoid (unit interval) and stick-breaking
    (simplex) transforms, also inside an ``IndependentTransform``, are inverted in NumPy
    (:func:`_inverse`): numpyro's own inverse runs JAX operations one by one, each a small
    XLA compilation in a fresh process (14 of them for the shipped log's starts). Other
    transforms are inverted by numpyro.

    Parameters
    ----------
    transform : numpyro.distributions.transforms.Transform
        ``biject_to(support)`` of a site.
    value : (...) float
        A point of the support.

    Returns
    -------
    (...) float64
        The point on the unconstrained scale (stick-breaking: one entry fewer).
    """
    kind = _kind(transform)
    if kind is not None:
        return _inverse(kind, value)
    return np.asarray(transform.inv(jnp.asarray(np.asarray(value, np.float64))), np.float64)


def _inverse(kind: str, value: npt.ArrayLike) -> np.ndarray:
    """The inverse of the transform named ``kind`` (:data:`_KINDS`) at ``value``, in NumPy.

    Parameters
    ----------
    kind : str
    value : (...) float

    Returns
    -------
    (...) float64
    """
    y = np.asarray(value, np.float64)
    if kind == "identity":
        return y.copy()
    if kind == "exp":
        return np.log(y)
    if kind == "sigmoid":
        return np.log(y) - np.log1p(-y)
    if kind == "stick_breaking":  # as numpyro's StickBreakingTransform._inverse
        crop = y[..., :-1]
        rest = np.clip(1.0 - np.cumsum(crop, axis=-1), np.finfo(np.float64).tiny, None)
        x = np.log(crop / rest)
        return x + np.log(x.shape[-1] - np.arange(x.shape[-1]))
    raise ValueError(f"kind: expected one of {sorted(_KINDS)}, got {kind!r}")


#: The latent sites of a model by (model, static arguments, array shapes): tracing the
#: model abstractly takes a few tenths of a second (:func:`_site_layout` asks once a
#: process, and not at all when its record is on disk).
_SITES: dict[tuple, dict[str, tuple[Constraint, tuple]]] = {}


def _latent_sites(model: Callable, kwargs: dict) -> dict[str, tuple[Constraint, tuple]]:
    """``name -> (support, shape)`` of the latent sample sites of ``model(**kwargs)``, read
    off an abstract trace (``jax.eval_shape``: shapes only), kept per model and shapes."""

    arrays, treedef, static = _split_kwargs(kwargs)
    key = _hashable((_fn_key(model), treedef, static, _shapes(arrays)))
    if key is not None and key in _SITES:
        return _SITES[key]
    found: dict[str, tuple[Constraint, tuple]] = {}

    def trace() -> int:
        with handlers.trace() as tr, handlers.seed(rng_seed=0):
            model(**kwargs)
        for name, site in tr.items():
            if site["type"] == "sample" and not site.get("is_observed", False):
                found[name] = (site["fn"].support, tuple(site["value"].shape))
        return 0

    with TRACE_LOCK:  # numpyro's handlers are one global stack: one trace at a time
        if key is not None and key in _SITES:  # traced by another thread while this waited
            return _SITES[key]
        jax.eval_shape(trace)
        if key is not None:
            _SITES[key] = found
    return found


#: Each model's site layout by (model, static arguments, array shapes), in this process.
_LAYOUTS: dict[tuple, dict[str, tuple[str | None, tuple]]] = {}


def _site_layout(model: Callable, kwargs: dict) -> dict[str, tuple[str | None, tuple]]:
    """``name -> (kind, shape)`` of the latent sites of ``model(**kwargs)``: the name of
    the transform to the unconstrained scale (:data:`_KINDS`; None for another) and the
    site's shape there.

    Read off an abstract trace (:func:`_latent_sites`) once a process, and kept on disk
    beside the compiled programs (:func:`are_stats._program_cache.store_record`, keyed by
    the model, its static arguments, the arrays' shapes and the package's source), so a
    later process does not trace the model again: the trace of each of the shipped log's
    nine candidates cost 0.05-0.25 s of CPU in every repeated fit. A layout with a
    transform outside :data:`_KINDS` stays off the disk (its support is needed).
    """
    arrays, treedef, static = _split_kwargs(kwargs)
    key = _hashable((_fn_key(model), treedef, static, _shapes(arrays)))
    if key is not None and key in _LAYOUTS:
        return _LAYOUTS[key]
    disk_key = ("laplace_sites", _fn_key(model), treedef, static)
    layout = _parse_layout(load_record(disk_key, (arrays,)))
    if layout is None:
        layout = {}
        for name, (support, shape) in _latent_sites(model, kwargs).items():
            t = biject_to(support)
            layout[name] = (_kind(t), tuple(int(n) for n in t.inverse_shape(shape)))
        if all(kind is not None for kind, _ in layout.values()):
            record = [[name, kind, list(shape)] for name, (kind, shape) in layout.items()]
            store_record(disk_key, (arrays,), record)
    if key is not None:
        _LAYOUTS[key] = layout
    return layout


def _parse_layout(record: object) -> dict[str, tuple[str | None, tuple]] | None:
    """A layout from its record (``[[name, kind, shape], ...]``), or None when the record
    is missing or not of that form (then the model is traced again)."""
    if not isinstance(record, list):
        return None
    layout: dict[str, tuple[str | None, tuple]] = {}
    for entry in record:
        if not (isinstance(entry, list) and len(entry) == 3):
            return None
        name, kind, shape = entry
        if not (isinstance(name, str) and kind in _KINDS and isinstance(shape, list)):
            return None
        if name in layout or not all(type(n) is int and n >= 0 for n in shape):
            return None
        layout[name] = (kind, tuple(shape))
    return layout


def laplace_dimension(model: Callable[..., None], model_kwargs: dict, init: dict | None) -> int:
    """Number of latent parameters of ``model`` on the unconstrained scale (nothing compiled)."""
    return int(sum(np.size(v) for v in _init_z(model, model_kwargs, init).values()))


#: Fewest points per program call. The draws (1000 a candidate) are most of a run's
#: points, and a call of few points costs its dispatch and the cheap program's per-call
#: work: the shipped log's nine candidates (2 to 7 parameters: stencils of 8 or 16 points)
#: ran in 2.6 s of CPU in calls of 8-16 points, 2.0 s in calls of 32 and 3.9 s in calls of
#: 128 (larger calls outgrow the caches; 2026-11-28, a warm process, loaded 2-core
#: machine). Each point's values are computed alone (``vmap``), whatever the call's size.
MIN_BATCH = 32


def _batch_size(d: int) -> int:
    """Points per program call: a central-difference gradient stencil (``2d + 1``), and at
    least :data:`MIN_BATCH`."""
    return max(MIN_BATCH, int(2 ** np.ceil(np.log2(2 * d + 1))))


def laplace_program(
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    pointwise: Callable,
    optimise: bool | str = False,
    likelihood: str | None = None,
) -> tuple[Callable[..., Any], list, np.ndarray, list[str], list[tuple]]:
    """The compiled batch program of :func:`run_laplace` (cached: calling this ahead, in
    another thread, compiles it while other work goes on).

    ``optimise`` compiles it with XLA's default optimisation instead of the cheap one: for
    a likelihood with a long recursion (the MMPP's forward pass over every tick), whose
    run time at the cheap level (5-6 times longer) outweighs the longer compile;
    ``"light"``, with XLA's first optimisation level (:data:`_LIGHT_OPTIONS`).
    ``likelihood`` names the model's factor site that ``pointwise`` sums to (see
    :func:`run_laplace`).

    Returns
    -------
    program, arrays, x0, names, shapes
        The program, the model's array arguments, the flat start and the latent sites'
        names and shapes on the unconstrained scale.
    """
    arrays, treedef, static = _split_kwargs(model_kwargs)
    z0 = _init_z(model, model_kwargs, init)
    names = sorted(z0)
    shapes = [np.shape(z0[n]) for n in names]
    x0 = np.concatenate([np.asarray(z0[n], np.float64).ravel() for n in names])
    size = _batch_size(x0.size)
    program = _program(
        "laplace_batch",
        _batch_fn(model, treedef, static, pointwise, likelihood),
        (arrays, _unflat_batch(np.zeros((size, x0.size)), names, shapes)),
        (_fn_key(model), treedef, static, _fn_key(pointwise), likelihood),
        optimise,
    )
    return program, arrays, x0, names, shapes


def run_laplace(
    key: jax.Array,
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    *,
    num_draws: int,
    pointwise: Callable[..., jax.Array],
    name: str = "",
    optimise: bool | str = False,
    likelihood: str | None = None,
) -> LaplaceRun:
    """Laplace approximation of ``model(**model_kwargs)`` and ``num_draws`` draws from it.

    Parameters
    ----------
    key : jax PRNG key
        The draws' randomness.
    model : callable
        A numpyro model (module level, as for :func:`~are_stats.fitting.run_nuts`).
    model_kwargs : dict
        Its arguments (array leaves are program arguments, the rest constants).
    init : dict or None
        Start of the mode search, constrained scale (as ``run_nuts``'s ``init``).
    num_draws : int
        Draws ``S``.
    pointwise : callable
        ``pointwise(sample_dict, **model_kwargs) -> (n,)`` for one draw.
    name : str
    optimise : bool or {"light"}
        Compile the model's program with XLA's default optimisation, or its first level
        (see :func:`laplace_program`).
    likelihood : str, optional
        The name of the model's factor site (``numpyro.factor``) whose value is the sum
        of ``pointwise``: the program then computes the likelihood once a point (from
        ``pointwise``) instead of in both the model and ``pointwise``, a smaller program
        (the gamma stay law's incomplete gammas, the MMPP's forward pass: half the
        likelihood's compile). The same values where the factor is the model's last
        sample site; None keeps the model's own factor.

    Returns
    -------
    LaplaceRun
    """
    program, arrays, x0, names, shapes = laplace_program(
        model, model_kwargs, init, pointwise, optimise, likelihood
    )
    d = x0.size
    size = _batch_size(d)

    def evaluate(points: np.ndarray) -> tuple[np.ndarray, dict, np.ndarray]:
        """Potential, sites and pointwise log-likelihood of ``(m, d)`` points."""
        pes, sites, lls = [], [], []
        for k in range(0, len(points), size):
            chunk = points[k : k + size]
            pad = np.concatenate([chunk, np.repeat(chunk[-1:], size - len(chunk), 0)])
            pe, si, ll = program(arrays, _unflat_batch(pad, names, shapes))
            pes.append(np.asarray(pe, np.float64)[: len(chunk)])
            sites.append({n: np.asarray(v)[: len(chunk)] for n, v in si.items()})
            lls.append(np.asarray(ll, np.float64)[: len(chunk)])
        pe = np.concatenate(pes)
        return (
            np.where(np.isfinite(pe), pe, np.inf),
            {n: np.concatenate([c[n] for c in sites]) for n in sites[0]},
            np.concatenate(lls),
        )

    def steps(x: np.ndarray, rel: float) -> np.ndarray:
        return rel * np.maximum(1.0, np.abs(x))

    last_ok: list = [None]  # the last point with a finite density and gradient

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        h = steps(x, 1e-6)
        stencil = np.vstack([x, x + np.diag(h), x - np.diag(h)])
        pe = evaluate(stencil)[0]
        if np.isfinite(pe).all():
            grad = (pe[1 : d + 1] - pe[d + 1 :]) / (2 * h)
            last_ok[0] = (x.copy(), float(pe[0]))
            return float(pe[0]), grad
        # outside the density's finite region: a steep bowl around the last finite point,
        # so that the line search steps back instead of stopping
        if last_ok[0] is None:
            return 1e300, np.zeros(d)
        x_ok, f_ok = last_ok[0]
        dx = x - x_ok
        scale = 1e6 * (1.0 + abs(f_ok))
        return f_ok + scale * (1.0 + float(dx @ dx)), 2.0 * scale * dx

    # within Z_BOUND of 0 on the unconstrained scale (4 prior sds of a rate's z, 8 of a
    # shape's eta): beyond it a likelihood's numerics (and its cost: an incomplete gamma
    # of shape e^30 takes seconds a point), not the data, rule
    bounds = [(-Z_BOUND, Z_BOUND)] * d
    with _one_blas_thread():
        res = minimize(
            fun,
            np.clip(x0, -Z_BOUND, Z_BOUND),
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": MAX_ITER},
        )
        mode = res.x
        hess = _hessian(lambda pts: evaluate(pts)[0], mode, steps(mode, 1e-4))
        lam, vec = np.linalg.eigh(hess)
    # a flat or non-convex direction (a mode on a boundary of the data's support): a wide
    # unit variance there, so that the importance weights can still reach the posterior
    lam = np.where(np.isfinite(lam) & (lam > 1e-8), lam, 1.0)
    eps = _numpy_rng(key).standard_normal((int(num_draws), d))
    zs = mode + (eps / np.sqrt(lam)) @ vec.T
    log_q = -0.5 * np.sum(eps**2, axis=1) - 0.5 * d * np.log(2 * np.pi) + 0.5 * np.sum(np.log(lam))
    pe, samples, ll = evaluate(zs)
    log_ratio = np.where(np.isfinite(pe), -pe - log_q, -np.inf)
    on_bound = bool(np.any(np.abs(mode) >= Z_BOUND * (1 - 1e-9)))
    converged = bool(res.success) and bool(np.isfinite(res.fun)) and not on_bound
    mode_d = {n: v[0] for n, v in _unflat_batch(mode[None], names, shapes).items()}

    def redraw(key_t: jax.Array, n_t: int, df: float) -> LaplaceRun:
        """Draws of the multivariate Student-t at the mode with the Gaussian's scale."""
        rng = _numpy_rng(key_t)
        eps_t = rng.standard_normal((int(n_t), d))
        eps_t *= np.sqrt(df / rng.chisquare(df, int(n_t)))[:, None]
        zs_t = mode + (eps_t / np.sqrt(lam)) @ vec.T
        log_q_t = (
            gammaln(0.5 * (df + d))
            - gammaln(0.5 * df)
            - 0.5 * d * np.log(df * np.pi)
            + 0.5 * np.sum(np.log(lam))
            - 0.5 * (df + d) * np.log1p(np.sum(eps_t**2, axis=1) / df)
        )
        pe_t, samples_t, ll_t = evaluate(zs_t)
        ratio_t = np.where(np.isfinite(pe_t), -pe_t - log_q_t, -np.inf)
        return LaplaceRun(samples_t, ll_t, ratio_t, mode_d, converged, name)

    return LaplaceRun(samples, ll, log_ratio, mode_d, converged, name, redraw)


def _numpy_rng(key: jax.Array) -> np.random.Generator:
    """A NumPy generator seeded by a JAX key's bits: the draws' randomness without a
    compiled JAX sampler per shape (each a small XLA compilation in a fresh process)."""
    return np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel().tolist())


def _hessian(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Hessian of ``f`` at ``x`` by central second differences (``f`` maps ``(m, d)`` points
    to ``(m,)`` values, all points of a call at once)."""
    d = x.size
    e = np.diag(h)
    pts = [x]
    for i in range(d):
        pts += [x + e[i], x - e[i]]
        for j in range(i):
            pts += [x + e[i] + e[j], x + e[i] - e[j], x - e[i] + e[j], x - e[i] - e[j]]
    v = f(np.asarray(pts))
    f0, k = v[0], 1
    out = np.empty((d, d))
    for i in range(d):
        out[i, i] = (v[k] - 2 * f0 + v[k + 1]) / (h[i] * h[i])
        k += 2
        for j in range(i):
            out[i, j] = out[j, i] = (v[k] - v[k + 1] - v[k + 2] + v[k + 3]) / (4 * h[i] * h[j])
            k += 4
    return out


def _unflat_batch(zs: np.ndarray, names: list[str], shapes: list[tuple]) -> dict:
    """``(S, d)`` flat draws to a dict of ``(S, *shape)`` arrays (the order of ``names``)."""
    out, k = {}, 0
    for n, s in zip(names, shapes, strict=True):
        m = int(np.prod(s))
        out[n] = zs[:, k : k + m].reshape((zs.shape[0], *s))
        k += m
    return out


def laplace_loo(run: LaplaceRun) -> tuple[np.ndarray, np.ndarray]:
    """Pointwise ``elpd_i`` and Pareto ``k_i`` by importance-sampled PSIS-LOO.

    The raw log weights of unit ``i`` are ``log_ratio - loglik[:, i]`` (see the module
    docstring); ``k_i`` above 0.7 flags a unit whose estimate is unreliable.

    Returns
    -------
    elpd : (n,) float64
    k : (n,) float64
    """
    ll = np.asarray(run.loglik, np.float64)
    n = ll.shape[1]
    if n == 0:
        return np.zeros(0), np.zeros(0)
    ok = np.isfinite(run.log_ratio) & np.isfinite(ll).all(axis=1)
    ll, base = ll[ok], run.log_ratio[ok]
    if ll.shape[0] < 5:
        return np.full(n, -np.inf), np.full(n, np.inf)
    log_w, k = psislw(base[None, :] - ll.T, 1.0)
    elpd = logsumexp(log_w + ll.T, axis=1)
    return np.asarray(elpd, float), np.atleast_1d(np.asarray(k, float))


class Resampled(NamedTuple):
    """Posterior draws by importance resampling of a Laplace approximation's draws.

    Attributes
    ----------
    samples : dict of str to (S, ...) ndarray, or None
        The resampled draws (every site of :attr:`LaplaceRun.samples`); None when the
        weights are not reliable (Pareto ``k`` at least ``max_k``, or the mode search did
        not converge): the caller samples the posterior otherwise (NUTS).
    k_hat : float
        Pareto ``k`` of the weights' tail (inf when it could not be estimated).
    ess : float
        Effective sample size of the smoothed weights, ``1 / sum_s w_s^2``.
    """

    samples: dict | None
    k_hat: float
    ess: float


def importance_resample(
    key: jax.Array, run: LaplaceRun, num_draws: int, max_k: float = RESAMPLE_MAX_K
) -> Resampled:
    """Draws of the posterior from a Laplace approximation's draws, by PSIS resampling.

    The draws ``theta_s`` of ``q`` (the Gaussian at the mode) carry the log weights
    ``log p(theta_s, y) - log q(theta_s)`` (:attr:`LaplaceRun.log_ratio`); Pareto
    smoothing (:func:`~are_stats.fitting.psislw`) stabilises them and estimates ``k``,
    whose value says whether ``q`` covers the posterior's tails. With ``k < max_k``
    ``num_draws`` indices are drawn by systematic resampling with probabilities ``w_s``
    (then shuffled), so that the draws' averages estimate posterior expectations (a
    draw may repeat: the information is that of ``ess`` independent draws).

    Parameters
    ----------
    key : jax PRNG key
        The resampling's randomness.
    run : LaplaceRun
        A converged Laplace approximation and its draws (:func:`run_laplace`).
    num_draws : int
        Draws returned.
    max_k : float
        Largest Pareto ``k`` accepted.

    Returns
    -------
    Resampled
    """
    num_draws = int(num_draws)
    ok = np.isfinite(run.log_ratio)
    if not run.converged or ok.sum() < 5 or num_draws < 1:
        return Resampled(None, float("inf"), 0.0)
    lr = run.log_ratio[ok]
    if np.ptp(lr) <= 1e-12 * max(1.0, float(np.max(np.abs(lr)))):
        log_w, k_hat = np.zeros(lr.size), 0.0  # q is the posterior: equal weights, no tail
    else:
        log_w, k = psislw(lr, 1.0)
        k_hat = float(np.asarray(k))
    w = np.exp(log_w - logsumexp(log_w))
    ess = float(1.0 / np.sum(w**2))
    if not k_hat < max_k:
        return Resampled(None, k_hat, ess)
    rng = _numpy_rng(key)
    u = (rng.random() + np.arange(num_draws)) / num_draws
    cdf = np.cumsum(w)
    idx = np.minimum(np.searchsorted(cdf / cdf[-1], u, side="right"), w.size - 1)
    idx = np.flatnonzero(ok)[idx[rng.permutation(num_draws)]]
    return Resampled({n: np.asarray(v)[idx] for n, v in run.samples.items()}, k_hat, ess)
