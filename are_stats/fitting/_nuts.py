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
driven by one ahead-of-time compiled XLA program for all chains: a chunk of
:func:`chunk_length` iterations (the start too, in the first), called about
:data:`TARGET_CHUNKS` times with the sampler's state carried from call to call (the same
iterations, hence the same draws, as one long loop). Between the calls the time left is
estimated from the measured rates of warm-up and sampling (:class:`NutsProgress`,
:func:`time_left`), so that a first run on a machine shows it too. A second small program
computes the constrained draws (deterministic sites included) and the pointwise
log-likelihood. The model's array arguments (NumPy or
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
import inspect
import operator
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, NamedTuple, TypedDict, TypeVar, Unpack, cast

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
from jax.sharding import NamedSharding, PartitionSpec
from jax.tree_util import PyTreeDef
from numpyro.diagnostics import split_gelman_rubin
from numpyro.distributions import biject_to
from numpyro.infer import init_to_uniform, init_to_value
from numpyro.infer.hmc import hmc
from numpyro.infer.util import constrain_fn, potential_energy

from are_stats._checks import check_in
from are_stats._program_cache import TRACE_LOCK, compile_program
from are_stats.traffic import aot_compile

if TYPE_CHECKING:
    from numpyro.infer.hmc import HMCState

__all__ = [
    "NutsPrefetch",
    "NutsProgress",
    "NutsRun",
    "NutsSettings",
    "chains_per_device",
    "chunk_length",
    "clock_progress",
    "nuts_warnings",
    "resolve_chain_method",
    "run_nuts",
    "time_left",
]


def resolve_chain_method(chain_method: str | None, num_chains: int) -> str:
    """The numpyro chain method actually used.

    ``None`` picks ``"parallel"`` when the chains split evenly over two or more of the
    JAX devices (``jax.local_device_count()``; :func:`chains_per_device`), each device
    vectorising its share (4 chains on this machine's 2 host devices: 2 per core, the
    sampling 1.7-2x faster than all 4 in lock-step on one), and ``"vectorized"``
    otherwise. Parallel and vectorised chains draw the same values up to rounding (the
    vectorisation width differs).

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
    return "parallel" if chains_per_device(num_chains)[0] > 1 else "vectorized"


def chains_per_device(num_chains: int) -> tuple[int, int]:
    """How "parallel" spreads ``num_chains`` over the local JAX devices.

    Parameters
    ----------
    num_chains : int

    Returns
    -------
    (n_devices, chains_per_device) : tuple of int
        The most devices, at most ``jax.local_device_count()``, that share the chains
        evenly; each vectorises its ``chains_per_device`` chains.
    """
    n_dev = _even_devices(int(num_chains))
    return n_dev, int(num_chains) // n_dev


def _even_devices(n: int) -> int:
    """The most local devices (at least 1) that share ``n`` items evenly."""
    n_dev = max(1, min(jax.local_device_count(), n))
    while n % n_dev:
        n_dev -= 1
    return n_dev


def _split_over_devices(
    fn: Callable[..., Any], n_dev: int, axis: str, split: tuple[bool, ...]
) -> tuple[jax.stages.Wrapped, tuple]:
    """``fn`` jitted over ``n_dev`` devices (``shard_map`` on mesh axis ``axis``): the
    arguments flagged in ``split`` and the outputs are split along their leading axis,
    the others whole on every device. Returns the program and the arguments' shardings.
    """
    mesh = jax.sharding.Mesh(np.asarray(jax.local_devices()[:n_dev]), (axis,))
    specs = tuple(PartitionSpec(axis) if s else PartitionSpec() for s in split)
    mapped = jax.shard_map(
        fn,
        mesh=mesh,
        in_specs=specs,
        out_specs=PartitionSpec(axis),
        check_vma=False,  # as pmap: the models' scans need no varying-axis types
    )
    return jax.jit(mapped), tuple(NamedSharding(mesh, p) for p in specs)


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
        process), in warm-up (``warmup``), in warm-up and sampling together
        (``sampling``) and post-processing (``postprocess``).
    """

    samples: dict
    diverging: np.ndarray
    r_hat: dict
    loglik: np.ndarray | dict[str, np.ndarray] | None
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

# compiled programs (with their blank states), keyed by model, settings and shapes: each
# entry has its own key's type, what that key's build returned
_CACHE: dict[tuple, Any] = {}
_CACHE_SIZE = 32
_LOCKS: dict[tuple, threading.Lock] = {}  # one per key: a program is compiled once
_LOCKS_GUARD = threading.Lock()


#: What a build returns, and its cache entry holds (a program, or one with its blank state).
_Built = TypeVar("_Built")


def _cached(key: tuple | None, build: Callable[[], _Built], timing: dict[str, float]) -> _Built:
    """The compiled program for ``key``, compiling it with ``build()`` on a miss.

    Thread-safe: a caller that finds the program being compiled by another thread (a
    :class:`NutsPrefetch`) waits for it instead of compiling it again. ``key=None``
    (static arguments that cannot be hashed): compile, keep nothing.
    """
    if key is None:
        return _timed_build(build, timing)
    program = _CACHE.get(key)
    if program is not None:
        return program
    with _LOCKS_GUARD:
        lock = _LOCKS.setdefault(key, threading.Lock())
    tic = time.perf_counter()
    with lock:
        program = _CACHE.get(key)
        if program is not None:  # compiled by another thread meanwhile: waiting was compiling
            timing["compile"] = timing.get("compile", 0.0) + time.perf_counter() - tic
        else:
            program = _timed_build(build, timing)
            with _LOCKS_GUARD:
                if len(_CACHE) >= _CACHE_SIZE:
                    old = next(iter(_CACHE))
                    _CACHE.pop(old)
                    if old in _LOCKS and not _LOCKS[old].locked():
                        del _LOCKS[old]
                _CACHE[key] = program
    return program


def _timed_build(build: Callable[[], _Built], timing: dict[str, float]) -> _Built:
    tic = time.perf_counter()
    program = build()
    timing["compile"] = timing.get("compile", 0.0) + time.perf_counter() - tic
    return program


def _compile(
    fn: Callable[..., Any],
    args: tuple,
    cheap: bool,
    key: tuple | None,
    in_shardings: tuple | None = None,
) -> Callable[..., Any]:
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


def _is_array(x: object) -> bool:
    return isinstance(x, (np.ndarray, np.generic, jax.Array))


def _split_kwargs(model_kwargs: dict) -> tuple[list, PyTreeDef, tuple]:
    """Array leaves of ``model_kwargs`` (program arguments) and the static rest.

    Returns ``(arrays, treedef, static)``: ``static`` holds the non-array leaves in order,
    with ``None`` where an array goes.
    """
    leaves, treedef = jax.tree.flatten(model_kwargs)
    arrays = [np.asarray(x) if isinstance(x, np.generic) else x for x in leaves if _is_array(x)]
    static = tuple(None if _is_array(x) else x for x in leaves)
    return arrays, treedef, static


def _join_kwargs(arrays: list, treedef: PyTreeDef, static: tuple) -> dict:
    it = iter(arrays)
    return jax.tree.unflatten(treedef, [next(it) if s is None else s for s in static])


def _fn_key(fn: Callable[..., object]) -> Callable[..., object] | tuple:
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
    model: Callable[..., None], kwargs: dict, chain_key: jax.Array, init: dict | None
) -> dict[str, jax.Array]:
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
            n: s
            for n, s in tr.items()
            if s["type"] == "sample" and not s["is_observed"] and not s["fn"].support.is_discrete
        }
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

#: Warm-up and sampling run as about this many compiled chunks in all (at least one
#: iteration each): the time left is measured from the first ones.
TARGET_CHUNKS = 20


def chunk_length(num_warmup: int, num_samples: int) -> int:
    """Iterations per compiled chunk: about :data:`TARGET_CHUNKS` chunks in all.

    Parameters
    ----------
    num_warmup, num_samples : int

    Returns
    -------
    int
        At least 1.
    """
    return max(1, -(-(int(num_warmup) + int(num_samples)) // TARGET_CHUNKS))


def _chain_fn(
    model: Callable[..., None],
    treedef: PyTreeDef,
    static: tuple,
    num_warmup: int,
    chunk: int,
    accept: float,
    fields: tuple[str, ...],
    given_start: bool,
) -> tuple[Callable[..., Any], Callable[..., Any]]:
    """One chain's start and chunk.

    Returns ``(start, step)``: ``start(chain_key, start, init, arrays) -> state`` (the
    sampler's state, numpyro's ``HMCState``, before the first iteration) and
    ``step(chain_key, start, init, arrays, leaves, first, limit) -> (leaves, (z, stats))``:
    ``limit`` (at most ``chunk``) NUTS iterations from the state whose leaves are given
    (from :func:`start` itself when ``first``: the state's leaves are then ignored),
    with the draws in the first ``limit`` of ``chunk`` slots.
    The state goes in and out as its flat leaves (a program kept by :mod:`jax.export`
    takes and gives only pytrees it knows).
    """
    getters = {f: operator.attrgetter(_STAT_ALIASES.get(f, f)) for f in fields}

    def kernels(chain_key, start, init, kwargs):
        k_init, k_run = jax.random.split(chain_key)
        u0 = start if given_start else _start(model, kwargs, k_init, init)

        def potential_fn(u):
            return potential_energy(model, (), kwargs, u)

        init_kernel, sample_kernel = hmc(potential_fn, algo="NUTS")
        # traced here, so that the sample kernel knows the warm-up schedule
        state = init_kernel(u0, num_warmup, target_accept_prob=accept, rng_key=k_run)
        return state, sample_kernel

    def first_state(chain_key, start, init, arrays):
        kwargs = _join_kwargs(arrays, treedef, static)
        return kernels(chain_key, start, init, kwargs)[0]

    def step(chain_key, start, init, arrays, leaves, first, limit):
        kwargs = _join_kwargs(arrays, treedef, static)
        made: _Made = {}

        def fresh():  # the start, computed only in the first chunk
            state, made["sample"] = kernels(chain_key, start, init, kwargs)
            made["tree"] = jax.tree.structure(state)
            return tuple(jax.tree.leaves(state))

        flat = jax.lax.cond(first, fresh, lambda: tuple(leaves))
        state, sample_kernel = jax.tree.unflatten(made["tree"], flat), made["sample"]

        def record(s):
            return s.z, {f: get(s) for f, get in getters.items()}

        def body(j, carry):  # a loop of ``limit`` iterations: no branch in it
            s, out = carry
            s = sample_kernel(s)
            out = jax.tree.map(lambda b, x: b.at[j].set(x), out, record(s))
            return s, out

        # slots past ``limit`` keep the state's values (never read)
        out = jax.tree.map(lambda x: jnp.broadcast_to(x, (chunk, *jnp.shape(x))), record(state))
        state, out = jax.lax.fori_loop(0, limit, body, (state, out))
        return tuple(jax.tree.leaves(state)), out

    return first_state, step


class _Made(TypedDict, total=False):
    """What the first chunk's start (traced inside :func:`_chain_fn`'s ``step``) hands
    back to the chunk: the sample kernel and the tree of the sampler's state."""

    sample: Callable[[HMCState], HMCState]
    tree: PyTreeDef


class _Plan(NamedTuple):
    """Everything :func:`run_nuts` needs to find (or compile) and run its programs."""

    first_state: Callable[..., Any]
    step: Callable[..., Any]
    key_base: tuple | None
    keys: jax.Array
    start: dict[str, jax.Array] | None
    init: dict | None
    arrays: list
    treedef: PyTreeDef
    static: tuple
    method: str
    num_chains: int
    cheap: bool
    num_warmup: int
    num_samples: int
    chunk: int


def _plan(
    key: jax.Array,
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    settings: NutsSettings,
) -> _Plan:
    """Check the settings and set up the chains' functions, arguments and cache key.

    ``settings``: :func:`run_nuts`'s keywords, those left out at its defaults (those that
    do not shape the sampling program are not read).
    """
    opts: NutsSettings = {**_RUN_NUTS_DEFAULTS, **settings}
    num_warmup, num_samples, num_chains = (
        int(opts["num_warmup"]),
        int(opts["num_samples"]),
        int(opts["num_chains"]),
    )
    init_params, chain_method = opts["init_params"], opts["chain_method"]
    extra_fields, cheap_compile = opts["extra_fields"], opts["cheap_compile"]
    target_accept_prob = opts["target_accept_prob"]
    if num_warmup < 0 or num_samples < 1 or num_chains < 1:
        raise ValueError(
            "num_warmup, num_samples, num_chains: expected >= 0, >= 1, >= 1, got "
            f"{num_warmup}, {num_samples}, {num_chains}"
        )
    method = resolve_chain_method(chain_method, num_chains)
    accept = float(target_accept_prob)
    fields = tuple(dict.fromkeys(("diverging", *extra_fields)))
    arrays, treedef, static = _split_kwargs(model_kwargs)
    start = None
    if init_params is not None:
        start = {n: jnp.asarray(v, float) for n, v in init_params.items()}
        if num_chains == 1:  # numpyro's convention: no chain axis for one chain
            start = {n: v[None] for n, v in start.items()}
        init = None
    init_arg = None if init is None else {n: jnp.asarray(v, float) for n, v in init.items()}
    keys = jax.random.split(key, num_chains)
    chunk = chunk_length(num_warmup, num_samples)
    key_base = _hashable(
        (
            _fn_key(model),
            treedef,
            static,
            num_warmup,
            "chunk",
            chunk,
            num_chains,
            accept,
            fields,
            jax.local_device_count(),
            bool(cheap_compile),
            _shapes((arrays, start, init_arg)),
            None if init_arg is None else tuple(sorted(init_arg)),
            None if start is None else tuple(sorted(start)),
        )
    )
    first_state, step = _chain_fn(
        model, treedef, static, num_warmup, chunk, accept, fields, start is not None
    )
    return _Plan(
        first_state,
        step,
        key_base,
        keys,
        start,
        init_arg,
        arrays,
        treedef,
        static,
        method,
        num_chains,
        bool(cheap_compile),
        num_warmup,
        num_samples,
        chunk,
    )


def _blank_state(plan: _Plan, chains: int | None) -> tuple:
    """Leaves of a sampler state of the right shapes (zeros, the chains' keys), for the
    first chunk, which ignores them; ``chains`` None: one chain, no chain axis."""

    # one chain's start and key as shapes: slicing the arrays compiled a program a leaf
    def one(x: jax.Array) -> jax.ShapeDtypeStruct:
        return jax.ShapeDtypeStruct(x.shape[1:], x.dtype)

    first = None if plan.start is None else jax.tree.map(one, plan.start)
    with TRACE_LOCK:  # numpyro's handler stack is global: one model traced at a time
        shape = jax.eval_shape(plan.first_state, one(plan.keys), first, plan.init, plan.arrays)
    lead = () if chains is None else (chains,)

    def blank(s):
        if jax.dtypes.issubdtype(s.dtype, jax.dtypes.prng_key):
            if lead + s.shape == plan.keys.shape:  # any keys do: the chains' own
                return plan.keys
            return jnp.broadcast_to(plan.keys[0], lead + s.shape)
        return np.zeros(lead + s.shape, s.dtype)

    return tuple(blank(s) for s in jax.tree.leaves(shape))


def _sampling_program(plan: _Plan, timing: dict[str, float]) -> tuple[Callable[..., Any], tuple]:
    """The compiled chunk program of ``plan`` (cached) and its arguments (the first
    chunk's: a blank state, ``first`` true, ``limit`` a whole chunk)."""
    step, start, init, arrays = plan.step, plan.start, plan.init, plan.arrays
    cheap, keys = plan.cheap, plan.keys
    first, limit = np.asarray(True), np.asarray(plan.chunk, np.int32)
    start_axis = None if start is None else 0
    axes = (0, start_axis, None, None, 0, None, None)
    head = (keys, start, init, arrays)
    if plan.method == "vectorized":
        key = None if plan.key_base is None else ("vectorized", *plan.key_base)

        def build():
            blank = _blank_state(plan, plan.num_chains)
            fn = jax.jit(jax.vmap(step, in_axes=axes))
            return _compile(fn, (*head, blank, first, limit), cheap, key), blank

        program, blank = _cached(key, build, timing)
        return program, (*head, blank, first, limit)
    if plan.method == "parallel":
        # the chains split over the devices by shard_map (several on one device are
        # vectorised): a jitted program, which jax.export can keep on disk
        n_dev = chains_per_device(plan.num_chains)[0]
        key = None if plan.key_base is None else ("parallel", n_dev, *plan.key_base)

        def build():
            fn, shardings = _split_over_devices(
                jax.vmap(step, in_axes=axes),
                n_dev,
                "chains",
                (True, True, False, False, True, False, False),
            )
            blank = _blank_state(plan, plan.num_chains)
            return _compile(fn, (*head, blank, first, limit), cheap, key, shardings), blank

        program, blank = _cached(key, build, timing)
        return program, (*head, blank, first, limit)
    # sequential: compile one chain, run it chain after chain
    key = None if plan.key_base is None else ("sequential", *plan.key_base)

    one = None if start is None else jax.tree.map(lambda x: x[0], start)
    head = (keys[0], one, init, arrays)

    def build():
        blank = _blank_state(plan, None)
        return _compile(jax.jit(step), (*head, blank, first, limit), cheap, key), blank

    program, blank = _cached(key, build, timing)
    return program, (*head, blank, first, limit)


class NutsProgress(NamedTuple):
    """Where a :func:`run_nuts` call stands, given to its ``progress`` callback.

    Attributes
    ----------
    phase : {"compile", "warm-up", "sampling", "postprocess"}
        What runs now (``compile``: before the first iteration, also when the program
        is read from the caches; ``postprocess``: after the last draw, the constrained
        draws and pointwise log-likelihood, their program compiled on a first run).
    done : int
        Iterations of the phase done (per chain).
    total : int
        Iterations of the phase (0 while compiling).
    seconds_left : float or None
        Estimated seconds until the last draw (warm-up and sampling, from the rates
        measured so far; the first chunk, which also finds the start and the first
        step size, counts only until a second warm-up chunk is timed); None while
        compiling and post-processing.
    """

    phase: str
    done: int
    total: int
    seconds_left: float | None


def time_left(
    warmup: tuple[int, int, float, float], sampling: tuple[int, int, float]
) -> float | None:
    """Seconds left of warm-up and sampling, from the rates measured so far.

    The rest of the warm-up goes at its mean rate so far; sampling, before it starts, at
    the rate of the warm-up's last chunk (the adapted step size and mass matrix), then at
    its own mean rate.

    Parameters
    ----------
    warmup : (done, total, seconds, last_rate)
        Warm-up iterations done and in all, the seconds they took, and the seconds per
        iteration of the last warm-up chunk (NaN before any).
    sampling : (done, total, seconds)
        The same for sampling.

    Returns
    -------
    float or None
        None before any iteration was timed.
    """
    w_done, w_total, w_sec, w_last = warmup
    s_done, s_total, s_sec = sampling
    if s_done > 0:
        return s_sec / s_done * (s_total - s_done)
    if w_done == 0:
        return None
    return w_sec / w_done * (w_total - w_done) + w_last * s_total


def clock_progress(clock: object) -> Callable[[NutsProgress], None] | None:
    """A :func:`run_nuts` ``progress`` that tells a stage clock the time left.

    Parameters
    ----------
    clock : object
        Anything with ``left(seconds, words)`` (a
        :class:`~are_stats._stage_clock.StageClock`); other objects (a plain
        ``progress(message)`` callable, None) give None: no estimate to tell.

    Returns
    -------
    callable or None
    """
    left = getattr(clock, "left", None)
    if left is None:
        return None

    def tell(p: NutsProgress) -> None:
        if p.phase == "compile":
            left(None, "compiling")
        elif p.phase == "postprocess":
            left(None, "constrained draws and log-likelihood")
        else:
            left(p.seconds_left, f"{p.phase} {p.done}/{p.total}")

    return tell


def _sample(
    plan: _Plan, timing: dict[str, float], progress: Callable[[NutsProgress], object] | None
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Run the chains by the plan's method, chunk after chunk; arrays by chain first."""
    say = progress or (lambda _p: None)
    say(NutsProgress("compile", 0, 0, None))
    program, args = _sampling_program(plan, timing)
    if plan.method != "sequential":
        out = _run_chunks(program, args, plan, timing, say, (0, 1))
    else:
        runs = []
        for c in range(plan.num_chains):
            start = None if plan.start is None else jax.tree.map(lambda x, c=c: x[c], plan.start)
            chain_args = (plan.keys[c], start, *args[2:])
            runs.append(_run_chunks(program, chain_args, plan, timing, say, (c, plan.num_chains)))
        out = jax.tree.map(lambda *xs: np.stack(xs), *runs)
    return out


def _run_chunks(
    program: Callable[..., Any],
    args: tuple,
    plan: _Plan,
    timing: dict[str, float],
    say: Callable[[NutsProgress], object],
    chain: tuple[int, int],
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Warm-up then sampling, a chunk of ``plan.chunk`` iterations a call, the state
    carried from call to call; returns the draws, (draws, ...) per chain or with a chain
    axis first, as the program gives them. ``chain``: (this run's chains before it, runs
    in all), for the estimate when the chains run one after another."""
    before, runs = chain
    leaves, first = args[4], True
    keep = []
    spent = {"warm-up": 0.0, "sampling": 0.0}
    last_rate = float("nan")
    opening = (0, 0.0)  # the first warm-up chunk (start, first step size): iterations, s
    axis = 0 if plan.method == "sequential" else 1  # the draws' axis in a chunk's output
    for phase, total in (("warm-up", plan.num_warmup), ("sampling", plan.num_samples)):
        done = 0
        while done < total:
            limit = min(plan.chunk, total - done)
            tic = time.perf_counter()
            leaves, draws = program(
                *args[:4], leaves, np.asarray(first), np.asarray(limit, np.int32)
            )
            jax.block_until_ready(leaves)
            # empty leaves (a model without some kind of site) come back replicated: the
            # program, split over devices, takes them split; host zeros fit either way
            leaves = tuple(np.zeros(x.shape, x.dtype) if x.size == 0 else x for x in leaves)
            took = time.perf_counter() - tic
            first = False
            spent[phase] += took
            done += limit
            if phase == "sampling":
                keep.append(
                    jax.tree.map(
                        lambda x, n=limit: np.take(np.asarray(x), np.arange(n), axis=axis), draws
                    )
                )
            else:
                last_rate = took / limit
                opening = opening if opening[0] else (limit, took)
            w_done = plan.num_warmup if phase == "sampling" else done
            s_done = done if phase == "sampling" else 0
            o_it, o_sec = opening if w_done > opening[0] else (0, 0.0)
            left = time_left(
                (w_done - o_it, plan.num_warmup - o_it, spent["warm-up"] - o_sec, last_rate),
                (s_done, plan.num_samples, spent["sampling"]),
            )
            if left is not None and runs > 1:  # the chains to come, as this one
                per_run = spent["warm-up"] + spent["sampling"] + left
                left += per_run * (runs - before - 1)
            say(NutsProgress(phase, done, total, left))
    # "sampling" as before: every iteration, warm-up included (as PyMC's sampling_time)
    timing["warmup"] = timing.get("warmup", 0.0) + spent["warm-up"]
    timing["sampling"] = timing.get("sampling", 0.0) + spent["warm-up"] + spent["sampling"]
    return jax.tree.map(lambda *xs: np.concatenate(xs, axis=axis), *keep)


class NutsSettings(TypedDict, total=False):
    """The keywords of :func:`run_nuts` (after ``init``), as a caller passes them on
    (:meth:`NutsPrefetch.add`, the traffic fit's candidates). See :func:`run_nuts` for
    their meaning and defaults."""

    num_warmup: int
    num_samples: int
    num_chains: int
    pointwise: Callable[..., jax.Array | dict[str, jax.Array]] | None
    name: str
    target_accept_prob: float
    init_params: dict | None
    chain_method: str | None
    extra_fields: tuple[str, ...]
    pointwise_kwargs: bool
    cheap_compile: bool
    progress: Callable[[NutsProgress], object] | None


class NutsPrefetch:
    """Compile the sampling programs of coming :func:`run_nuts` calls in the background.

    A fit that samples several candidate models one after another (:func:`fit_traffic`)
    announces them all first; worker threads compile (or, in a later process, read and
    load: :mod:`are_stats._program_cache` and JAX's persistent cache) their programs while
    the first models sample. :func:`run_nuts` then finds each program compiled, or waits
    for the worker compiling it. Tracing stays one thread at a time
    (:data:`are_stats._program_cache.TRACE_LOCK`); the draws are the same bits either way.
    A program that fails to compile here is compiled again by :func:`run_nuts`, which
    raises the error.

    Parameters
    ----------
    workers : int
        Threads that compile (default 2).

    Examples
    --------
    >>> calls = [(key_a, model_a, kw_a, init_a), (key_b, model_b, kw_b, init_b)]  # doctest: +SKIP
    >>> with NutsPrefetch() as ahead:  # doctest: +SKIP
    ...     for call in calls:
    ...         ahead.add(*call, num_chains=4)
    ...     runs = [run_nuts(*call, num_chains=4) for call in calls]
    """

    def __init__(self, workers: int = 2) -> None:
        self._pool = ThreadPoolExecutor(max(1, int(workers)), "are-stats-compile")
        self._futures: list[Future[object]] = []

    def add(
        self,
        key: jax.Array,
        model: Callable[..., None],
        model_kwargs: dict,
        init: dict | None,
        **settings: Unpack[NutsSettings],
    ) -> None:
        """Start compiling the program of ``run_nuts(key, model, model_kwargs, init, **settings)``.

        ``settings`` are :func:`run_nuts`'s keywords; those that do not shape the sampling
        program (``pointwise``, ``name``, ...) are ignored here.
        """
        plan = _plan(key, model, model_kwargs, init, settings)
        if plan.key_base is not None:  # a program nobody could find again is not kept
            self._futures.append(self._pool.submit(_sampling_program, plan, {}))

    def close(self, cancel: bool = False) -> None:
        """Wait for the workers; their errors are left to :func:`run_nuts` to raise.

        ``cancel=True`` drops the programs not started yet (the ones compiling finish).
        """
        self._pool.shutdown(wait=True, cancel_futures=cancel)
        for f in self._futures:
            if not f.cancelled():
                f.exception()
        self._futures.clear()

    def __enter__(self) -> NutsPrefetch:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self.close(cancel=exc_type is not None)  # an error or Ctrl-C: do not compile on


def run_nuts(
    key: jax.Array,
    model: Callable[..., None],
    model_kwargs: dict,
    init: dict | None,
    *,
    num_warmup: int = 1000,
    num_samples: int = 1000,
    num_chains: int = 4,
    pointwise: Callable[..., jax.Array | dict[str, jax.Array]] | None = None,
    name: str = "",
    target_accept_prob: float = 0.85,
    init_params: dict | None = None,
    chain_method: str | None = None,
    extra_fields: tuple[str, ...] = (),
    pointwise_kwargs: bool = False,
    cheap_compile: bool = False,
    progress: Callable[[NutsProgress], object] | None = None,
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
        Default: parallel when the chains split evenly over two or more devices
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
    progress : callable, optional
        ``progress(NutsProgress)`` before compiling and after every chunk of iterations
        (:data:`TARGET_CHUNKS` chunks in all): the phase, its iterations done and the
        estimated seconds left (:func:`time_left`). :func:`clock_progress` turns a
        :class:`~are_stats._stage_clock.StageClock` into one.

    Returns
    -------
    NutsRun

    Raises
    ------
    ValueError
        On an unknown ``chain_method`` or non-positive sizes.
    """
    shaping: NutsSettings = {  # the keywords that shape the sampling program
        "num_warmup": num_warmup,
        "num_samples": num_samples,
        "num_chains": num_chains,
        "target_accept_prob": target_accept_prob,
        "init_params": init_params,
        "chain_method": chain_method,
        "extra_fields": extra_fields,
        "cheap_compile": cheap_compile,
    }
    plan = _plan(key, model, model_kwargs, init, shaping)
    timing: dict[str, float] = {"compile": 0.0}
    zs, stats = _sample(plan, timing, progress)
    if progress is not None:
        progress(NutsProgress("postprocess", 0, 0, None))
    samples, loglik = _post_process(model, plan, zs, pointwise, pointwise_kwargs, timing)
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
    return NutsRun(samples, diverging, r_hat, loglik, name, extra, plan.method, timing)


def _post_process(
    model: Callable[..., None],
    plan: _Plan,
    zs: dict[str, np.ndarray],
    pointwise: Callable[..., jax.Array | dict[str, jax.Array]] | None,
    pointwise_kwargs: bool,
    timing: dict[str, float],
) -> tuple[dict, np.ndarray | dict[str, np.ndarray] | None]:
    """Constrained and deterministic sites and pointwise log-likelihood of every draw.

    The draws are split over the local devices (``shard_map``) when they divide evenly:
    each draw's sites and log-likelihood are computed alone, so the result is the same.
    """
    treedef, static = plan.treedef, plan.static

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
    n_draws = shape[0] * shape[1]
    flat = {n: v.reshape((n_draws,) + v.shape[2:]) for n, v in zs.items()}
    n_dev = _even_devices(n_draws)
    fn, shardings = jax.jit(post), None
    if n_dev > 1:
        fn, shardings = _split_over_devices(post, n_dev, "draws", (True, False))
    key = None
    if plan.key_base is not None and (pointwise is None or pointwise_kwargs):
        key = _hashable(("post", n_dev, _fn_key(pointwise), *plan.key_base))
    args = (flat, plan.arrays)
    program = _cached(key, lambda: _compile(fn, args, plan.cheap, key, shardings), timing)
    tic = time.perf_counter()
    samples, loglik = jax.tree.map(np.asarray, program(*args))
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


#: run_nuts's keywords that shape the sampling program, at their defaults (for _plan).
_RUN_NUTS_DEFAULTS = cast(
    NutsSettings,
    {
        name: p.default
        for name, p in inspect.signature(run_nuts).parameters.items()
        if name
        in (
            "num_warmup",
            "num_samples",
            "num_chains",
            "target_accept_prob",
            "init_params",
            "chain_method",
            "extra_fields",
            "cheap_compile",
        )
    },
)
