"""One NUTS driver for every model: robust start, diagnostics, pointwise log-likelihood.

:func:`run_nuts` samples a numpyro model from a stated starting point (the traffic models
are parameterised so that ``z = 0`` is the empirical estimate, whatever the data's time
scale; the life-cycle and mixture fits give jittered unconstrained starts per chain), and
returns the draws by chain, the divergences, split-``r_hat`` of every latent scalar and,
through a caller's pure function, the pointwise log-likelihood of every draw (for
PSIS-LOO). Nothing is hidden: divergences and ``r_hat`` are part of the result and
:func:`nuts_warnings` words them for the CLI and the summary table.

**One compiled program per model and shapes.** The sampler is numpyro's NUTS kernel
(``numpyro.infer.hmc.hmc``: step size and diagonal mass matrix adapted during warm-up)
driven by one ahead-of-time compiled XLA program for all chains, start, warm-up and
sampling together; a second small program computes the constrained draws (deterministic
sites included) and the pointwise log-likelihood. The model's array arguments (NumPy or
JAX arrays, 0-d included, anywhere in ``model_kwargs``) are *arguments* of these
programs, everything else (Python numbers, strings, specs, priors) is part of the
program. Both are kept in an in-process cache keyed by the model, those static
arguments, the settings and the array shapes: a second fit of the same model on data of
the same (bucketed) shapes compiles nothing and traces nothing. A fresh process neither
traces them (the traced programs are kept on disk by :mod:`jax.export`, under the same
key: :func:`are_stats._program_cache.compile_program`) nor compiles them (JAX's
persistent cache, :func:`are_stats.configure_jax`).
"""

from __future__ import annotations

import functools
import operator
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
from jax.sharding import NamedSharding, PartitionSpec
from numpyro.diagnostics import split_gelman_rubin
from numpyro.distributions import biject_to
from numpyro.infer import init_to_uniform, init_to_value
from numpyro.infer.hmc import hmc
from numpyro.infer.util import constrain_fn, potential_energy

from are_stats._checks import check_in
from are_stats._program_cache import compile_program
from are_stats.traffic import aot_compile

__all__ = ["NutsRun", "nuts_warnings", "resolve_chain_method", "run_nuts"]


def resolve_chain_method(chain_method: str | None, num_chains: int) -> str:
    """The numpyro chain method actually used.

    ``None`` picks ``"parallel"`` when there are at least ``num_chains`` JAX devices
    (``jax.local_device_count()``) and ``"vectorized"`` otherwise: numpyro silently runs
    "parallel" chains one after another when devices are missing.

    Parameters
    ----------
    chain_method : {"parallel", "vectorized", "sequential"} or None
        Requested method.
    num_chains : int
        Number of chains.

    Returns
    -------
    str
        ``"parallel"``, ``"vectorized"`` or ``"sequential"``.

    Raises
    ------
    ValueError
        If ``chain_method`` is not one of the options.
    """
    check_in("chain_method", chain_method, (None, "parallel", "vectorized", "sequential"))
    if chain_method is not None:
        return chain_method
    if num_chains == 1:
        return "sequential"
    return "parallel" if jax.local_device_count() >= num_chains else "vectorized"


class NutsRun(NamedTuple):
    """Draws and diagnostics of :func:`run_nuts`.

    Attributes
    ----------
    samples : dict of str to (chains, draws, ...) ndarray
        Latent and deterministic sites.
    diverging : (chains, draws) bool
    r_hat : dict of str to float
        Largest split-``r_hat`` over each site's scalars (NaN with one chain, inf when
        the chains do not move).
    loglik : (chains, draws, units) ndarray, dict of them, or None
        Pointwise log-likelihood (a dict when ``pointwise`` returns one).
    name : str
        The model's name (in warnings).
    extra : dict of str to (chains, draws) ndarray
        The sampler's extra fields asked for (``num_steps``, ``energy``, ...).
    chain_method : str
        How the chains ran (``parallel``, ``vectorized`` or ``sequential``).
    timing : dict of str to float
        Seconds spent compiling (``compile``: 0 when the programs were cached in this
        process), sampling (``sampling``) and post-processing (``postprocess``).
    """

    samples: dict
    diverging: np.ndarray
    r_hat: dict
    loglik: Any
    name: str
    extra: dict = {}  # noqa: RUF012 (NamedTuple default, never mutated)
    chain_method: str = "sequential"
    timing: dict = {}  # noqa: RUF012 (NamedTuple default, never mutated)

    @property
    def n_divergent(self) -> int:
        """Divergent transitions after warm-up."""
        return int(self.diverging.sum())

    @property
    def max_r_hat(self) -> float:
        """Largest ``r_hat`` over the sites (NaN with one chain; inf for stuck chains)."""
        vals = [v for v in self.r_hat.values() if not np.isnan(v)]
        return float(max(vals)) if vals else float("nan")


# ------------------------------------------------------------------- compiled programs

_CACHE: dict[tuple, Any] = {}  # compiled programs, keyed by model, settings and shapes
_CACHE_SIZE = 32


def _cached(key: tuple | None, build: Callable[[], Any], timing: dict[str, float]) -> Any:
    """The compiled program for ``key``, compiling it with ``build()`` on a miss.

    ``key=None`` (static arguments that cannot be hashed): compile, keep nothing.
    """
    if key is not None and key in _CACHE:
        return _CACHE[key]
    tic = time.perf_counter()
    program = build()
    timing["compile"] = timing.get("compile", 0.0) + time.perf_counter() - tic
    if key is not None:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = program
    return program


def _compile(
    fn: Any, args: tuple, cheap: bool, key: tuple | None, in_shardings: tuple | None = None
) -> Any:
    """Compile ``fn`` for ``args``: cheap XLA optimisation (fast to compile, slower to run:
    for small models) or XLA's default (4-5x faster sampling of the traffic models for
    about twice the compile time, which the persistent cache pays once).

    With a ``key`` (the in-process cache key: model, static arguments, settings, shapes)
    the traced program is kept on disk and a later process reads it instead of tracing
    the model again (:func:`are_stats._program_cache.compile_program`).
    """
    if cheap:
        return aot_compile(fn, *args, key=key, in_shardings=in_shardings)
    return compile_program(fn, args, key, None, in_shardings)


def _shapes(tree: Any) -> tuple:
    """Shapes and dtypes of the leaves of ``tree`` (part of a cache key)."""
    return tuple((np.shape(x), np.asarray(x).dtype.str) for x in jax.tree.leaves(tree))


def _is_array(x: Any) -> bool:
    return isinstance(x, (np.ndarray, np.generic, jax.Array))


def _split_kwargs(model_kwargs: dict) -> tuple[list, Any, tuple]:
    """Array leaves of ``model_kwargs`` (program arguments) and the static rest.

    Returns ``(arrays, treedef, static)``: ``static`` holds the non-array leaves in order,
    with ``None`` where an array goes.
    """
    leaves, treedef = jax.tree.flatten(model_kwargs)
    arrays = [np.asarray(x) if isinstance(x, np.generic) else x for x in leaves if _is_array(x)]
    static = tuple(None if _is_array(x) else x for x in leaves)
    return arrays, treedef, static


def _join_kwargs(arrays: list, treedef: Any, static: tuple) -> dict:
    it = iter(arrays)
    return jax.tree.unflatten(treedef, [next(it) if s is None else s for s in static])


def _fn_key(fn: Any) -> Any:
    """A cache key of a callable: ``functools.partial`` by its function and arguments."""
    if isinstance(fn, functools.partial):
        return (_fn_key(fn.func), fn.args, tuple(sorted(fn.keywords.items())))
    return fn


def _hashable(key: tuple) -> tuple | None:
    try:
        hash(key)
    except TypeError:
        return None
    return key


def _start(
    model: Callable[..., None], kwargs: dict, chain_key: Any, init: dict | None
) -> dict[str, Any]:
    """Unconstrained start of one chain, inside the compiled program.

    Sites in ``init`` start there (``init_to_value``), the others uniformly in (-2, 2) on
    the unconstrained scale (``init_to_uniform``, numpyro's default), redrawn (at most
    100 times) while the potential or its gradient is not finite.
    """
    strategy = init_to_uniform if init is None else init_to_value(values=init)

    def draw(k):
        seeded = numpyro.handlers.substitute(
            numpyro.handlers.seed(model, k), substitute_fn=strategy
        )
        tr = numpyro.handlers.trace(seeded).get_trace(**kwargs)
        latent = {
            n: s for n, s in tr.items()
            if s["type"] == "sample" and not s["is_observed"]
            and not s["fn"].support.is_discrete
        }  # fmt: skip
        u = {n: biject_to(s["fn"].support).inv(s["value"]) for n, s in latent.items()}
        return u, set(latent) <= set(init or {})

    u, fixed = draw(chain_key)
    if fixed:  # every site has a stated start: nothing random to redraw
        return u

    def valid(z):
        pe, g = jax.value_and_grad(lambda v: potential_energy(model, (), kwargs, v))(z)
        flat = jnp.concatenate([jnp.ravel(x) for x in jax.tree.leaves(g)] + [jnp.ravel(pe)])
        return jnp.all(jnp.isfinite(flat))

    def cond(state):
        i, _, z = state
        return (i < 100) & ~valid(z)

    def body(state):
        i, k, _ = state
        k, sub = jax.random.split(k)
        return i + 1, k, draw(sub)[0]

    return jax.lax.while_loop(cond, body, (0, jax.random.fold_in(chain_key, 1), u))[2]


_STAT_ALIASES = {"step_size": "adapt_state.step_size"}


def _chain_fn(
    model: Callable[..., None],
    treedef: Any,
    static: tuple,
    num_warmup: int,
    num_samples: int,
    accept: float,
    fields: tuple[str, ...],
    given_start: bool,
) -> Callable[..., Any]:
    """``(chain_key, start, init, arrays) -> (z draws, stats)`` for one chain."""
    getters = {f: operator.attrgetter(_STAT_ALIASES.get(f, f)) for f in fields}

    def one_chain(chain_key, start, init, arrays):
        kwargs = _join_kwargs(arrays, treedef, static)
        k_init, k_run = jax.random.split(chain_key)
        u0 = start if given_start else _start(model, kwargs, k_init, init)

        def potential_fn(u):
            return potential_energy(model, (), kwargs, u)

        init_kernel, sample_kernel = hmc(potential_fn, algo="NUTS")
        state = init_kernel(u0, num_warmup, target_accept_prob=accept, rng_key=k_run)

        def body(s, _):
            s = sample_kernel(s)
            return s, (s.z, {f: get(s) for f, get in getters.items()})

        _, out = jax.lax.scan(body, state, None, length=num_warmup + num_samples)
        return jax.tree.map(lambda x: x[num_warmup:], out)

    return one_chain


def _sample(
    one_chain: Callable[..., Any],
    key_base: tuple | None,
    keys: Any,
    start: Any,
    init: Any,
    arrays: list,
    method: str,
    num_chains: int,
    cheap: bool,
    timing: dict[str, float],
) -> Any:
    """Run the chains by ``method`` with the cached program; arrays by chain first."""
    start_axis = None if start is None else 0
    if method == "vectorized":
        key = None if key_base is None else ("vectorized", *key_base)
        program = _cached(
            key,
            lambda: _compile(
                jax.jit(jax.vmap(one_chain, in_axes=(0, start_axis, None, None))),
                (keys, start, init, arrays),
                cheap,
                key,
            ),  # fmt: skip
            timing,
        )
        tic = time.perf_counter()
        out = jax.tree.map(np.asarray, program(keys, start, init, arrays))
    elif method == "parallel":
        # the chains split over the devices by shard_map (several on one device are
        # vectorised): a jitted program, which jax.export can keep on disk
        n_dev = min(jax.local_device_count(), num_chains)
        while num_chains % n_dev:
            n_dev -= 1
        mesh = jax.sharding.Mesh(np.asarray(jax.local_devices()[:n_dev]), ("chains",))
        by_chain, whole = PartitionSpec("chains"), PartitionSpec()
        fn = jax.jit(
            jax.shard_map(
                jax.vmap(one_chain, in_axes=(0, start_axis, None, None)),
                mesh=mesh,
                in_specs=(by_chain, by_chain, whole, whole),
                out_specs=by_chain,
                check_vma=False,  # as pmap: the models' scans need no varying-axis types
            )
        )
        shardings = tuple(NamedSharding(mesh, p) for p in (by_chain, by_chain, whole, whole))
        key = None if key_base is None else ("parallel", n_dev, *key_base)
        program = _cached(
            key,
            lambda: _compile(fn, (keys, start, init, arrays), cheap, key, shardings),
            timing,
        )
        tic = time.perf_counter()
        out = jax.tree.map(np.asarray, program(keys, start, init, arrays))
    else:  # sequential: compile one chain, run it chain after chain
        first = None if start is None else jax.tree.map(lambda x: x[0], start)
        key = None if key_base is None else ("sequential", *key_base)
        program = _cached(
            key,
            lambda: _compile(jax.jit(one_chain), (keys[0], first, init, arrays), cheap, key),
            timing,
        )
        tic = time.perf_counter()
        runs = [
            program(
                keys[c],
                None if start is None else jax.tree.map(lambda x, c=c: x[c], start),
                init,
                arrays,
            )  # fmt: skip
            for c in range(num_chains)
        ]
        out = jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *runs)
    timing["sampling"] = time.perf_counter() - tic
    return out


def run_nuts(
    key: Any,
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    *,
    num_warmup: int = 1000,
    num_samples: int = 1000,
    num_chains: int = 4,
    pointwise: Callable[..., Any] | None = None,
    name: str = "",
    target_accept_prob: float = 0.85,
    init_params: dict | None = None,
    chain_method: str | None = None,
    extra_fields: tuple[str, ...] = (),
    pointwise_kwargs: bool = False,
    cheap_compile: bool = False,
) -> NutsRun:
    """Sample ``model(**model_kwargs)`` by NUTS from ``init``.

    Parameters
    ----------
    key : jax PRNG key
    model : callable
        A numpyro model (a module-level function or a ``functools.partial`` of one, so
        that its compiled programs are found again by later calls).
    model_kwargs : dict
        Its arguments. Array leaves (NumPy/JAX arrays and NumPy scalars, also inside
        named tuples) are arguments of the compiled programs; the other leaves (Python
        numbers, strings, ...) are constants of them and must be hashable to be cached.
    init : dict or None
        Starting values of the latent sites, on their constrained scale, the same for
        every chain (the traffic models start at ``z = 0``, the empirical estimate);
        sites left out (or all, with None) start uniformly in (-2, 2) on the
        unconstrained scale, redrawn while the density is not finite.
    num_warmup, num_samples, num_chains : int
    pointwise : callable, optional
        ``pointwise(sample_dict) -> (units,)`` (or a dict of such arrays) for ONE draw of
        the constrained and deterministic sites (vmapped over draws).
    name : str
        Model name for the warnings.
    target_accept_prob : float
        NUTS step-size adaptation target.
    init_params : dict, optional
        Starting values on the unconstrained scale, with a leading chain axis (none with
        one chain; e.g. an EM fit jittered per chain); they win over ``init``.
    chain_method : {"parallel", "vectorized", "sequential"}, optional
        Default: parallel when there is a device per chain
        (:func:`resolve_chain_method`). "parallel" spreads the chains over the JAX
        devices (``jax.shard_map`` in one jitted program; several chains on one device
        are vectorised; the same draws as ``jax.pmap``),
        "vectorized" runs them in lock-step on one device, "sequential" one after
        another with one compilation.
    extra_fields : tuple of str
        Sampler statistics to keep, named as numpyro's ``HMCState`` fields
        (``num_steps``, ``accept_prob``, ``energy``, ``potential_energy``, ...;
        ``step_size`` for the adapted step size); ``diverging`` is always kept.
    pointwise_kwargs : bool
        Call ``pointwise(sample_dict, **model_kwargs)`` instead: the data are then
        arguments of the compiled program rather than constants captured by a closure,
        and a module-level ``pointwise`` lets later calls reuse the program.
    cheap_compile : bool
        Compile with cheap XLA optimisation: for small models whose compilation costs
        more than their sampling (the life-cycle model). Default: XLA's optimisation
        (the traffic models sample 4-5x faster with it).

    Returns
    -------
    NutsRun

    Raises
    ------
    ValueError
        On an unknown ``chain_method`` or non-positive sizes.
    """
    num_warmup, num_samples, num_chains = int(num_warmup), int(num_samples), int(num_chains)
    if num_warmup < 0 or num_samples < 1 or num_chains < 1:
        raise ValueError(
            "num_warmup, num_samples, num_chains: expected >= 0, >= 1, >= 1, got "
            f"{num_warmup}, {num_samples}, {num_chains}"
        )
    method = resolve_chain_method(chain_method, num_chains)
    accept = float(target_accept_prob)
    fields = tuple(dict.fromkeys(("diverging", *extra_fields)))
    timing: dict[str, float] = {"compile": 0.0}

    arrays, treedef, static = _split_kwargs(model_kwargs)
    start = None
    if init_params is not None:
        start = {n: jnp.asarray(v, float) for n, v in init_params.items()}
        if num_chains == 1:  # numpyro's convention: no chain axis for one chain
            start = {n: v[None] for n, v in start.items()}
        init = None
    init_arg = None if init is None else {n: jnp.asarray(v, float) for n, v in init.items()}
    keys = jax.random.split(key, num_chains)
    key_base = _hashable(
        (
            _fn_key(model), treedef, static, num_warmup, num_samples, num_chains, accept,
            fields, jax.local_device_count(), bool(cheap_compile),
            _shapes((arrays, start, init_arg)),
            None if init_arg is None else tuple(sorted(init_arg)),
            None if start is None else tuple(sorted(start)),
        )
    )  # fmt: skip
    one_chain = _chain_fn(
        model, treedef, static, num_warmup, num_samples, accept, fields, start is not None
    )
    zs, stats = _sample(
        one_chain, key_base, keys, start, init_arg, arrays, method, num_chains, cheap_compile,
        timing,
    )  # fmt: skip
    samples, loglik = _post_process(
        model, treedef, static, zs, arrays, pointwise, pointwise_kwargs, key_base,
        cheap_compile, timing,
    )  # fmt: skip
    diverging = np.asarray(stats.pop("diverging")).astype(bool)
    extra = {f: np.asarray(v) for f, v in stats.items()}
    r_hat = {}
    for site, v in samples.items():
        if v.shape[0] < 2 or v.shape[1] < 4:
            r_hat[site] = float("nan")
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.asarray(split_gelman_rubin(v))
        # stuck chains (no variance within them) give inf: kept, it is the worst case
        r_hat[site] = float(np.nanmax(r)) if (~np.isnan(r)).any() else float("nan")
    return NutsRun(samples, diverging, r_hat, loglik, name, extra, method, timing)


def _post_process(
    model: Callable[..., None],
    treedef: Any,
    static: tuple,
    zs: dict[str, np.ndarray],
    arrays: list,
    pointwise: Callable[..., Any] | None,
    pointwise_kwargs: bool,
    key_base: tuple | None,
    cheap: bool,
    timing: dict[str, float],
) -> tuple[dict, Any]:
    """Constrained and deterministic sites and pointwise log-likelihood of every draw."""

    def post(flat, arrays):
        kwargs = _join_kwargs(arrays, treedef, static)
        samples = jax.vmap(lambda u: constrain_fn(model, (), kwargs, u, return_deterministic=True))(
            flat
        )
        if pointwise is None:
            return samples, None
        if pointwise_kwargs:
            return samples, jax.vmap(lambda s: pointwise(s, **kwargs))(samples)
        return samples, jax.vmap(pointwise)(samples)

    shape = next(iter(zs.values())).shape[:2]
    flat = {n: v.reshape((shape[0] * shape[1],) + v.shape[2:]) for n, v in zs.items()}
    key = None
    if key_base is not None and (pointwise is None or pointwise_kwargs):
        key = _hashable(("post", _fn_key(pointwise), *key_base))
    program = _cached(key, lambda: _compile(jax.jit(post), (flat, arrays), cheap, key), timing)
    tic = time.perf_counter()
    samples, loglik = jax.tree.map(np.asarray, program(flat, arrays))
    timing["postprocess"] = time.perf_counter() - tic

    def unflat(v):
        return v.reshape(shape + v.shape[1:])

    samples = {n: unflat(v) for n, v in samples.items()}
    return samples, None if loglik is None else jax.tree.map(unflat, loglik)


def nuts_warnings(run: NutsRun, r_hat_limit: float = 1.01) -> list[str]:
    """Words for the divergences and large ``r_hat`` of a run (empty when clean)."""
    out = []
    total = run.diverging.size
    if run.n_divergent:
        out.append(
            f"{run.name}: {run.n_divergent} of {total} draws divergent: the posterior may be "
            "biased (more --warmup, or the model does not suit the data)"
        )
    if not np.isnan(run.max_r_hat) and run.max_r_hat > r_hat_limit:
        bad = sorted(k for k, v in run.r_hat.items() if not np.isnan(v) and v > r_hat_limit)
        out.append(
            f"{run.name}: r_hat {run.max_r_hat:.3f} > {r_hat_limit} for {', '.join(bad)}: the "
            "chains disagree (run longer chains: --samples, --warmup)"
        )
    return out
