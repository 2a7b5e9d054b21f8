"""Traced JAX programs kept on disk (:mod:`jax.export`), so a new process skips tracing.

JAX's persistent compilation cache (:func:`are_stats.configure_jax`) spares a second
process XLA's compile, but it is keyed on the *lowered* program: every process still
traces the Python function and lowers it to StableHLO first, seconds for a NUTS program.
:func:`compile_program` keeps the lowered program itself, serialised by
:func:`jax.export.export`, in ``$XDG_CACHE_HOME/are_stats/programs`` (beside the JAX
cache, off with it: ``ARE_STATS_NO_CACHE=1``, ``are-stats --no-cache``,
``configure_jax(cache=False)``); a later process deserialises it and compiles it, which
hits JAX's persistent cache.

**The key.** A program file is named by a SHA-256 over everything that shapes the trace:
the caller's key (the function by module and qualified name, its static arguments and
settings, written by :func:`stable_repr`), a hash of the are_stats source files
(:func:`source_hash`, so an edited model is traced again), the arguments' tree, shapes
and dtypes, the device count, the JAX, jaxlib and numpyro versions, the 64-bit flag and
the compiler options. A key that cannot be written stably (a lambda, a local function,
an object without a stable ``repr``) keeps that program off the disk.

**Never in the way.** A missing, unreadable, corrupt or stale file is traced again (and
rewritten); a file is written to a temporary name in its folder and renamed into place
(:func:`os.replace`), so readers never see half a file; a failed write is ignored. The
program compiled is always the exported one (``jax.jit(exported.call)``), in the first
process as in later ones, so a fit gives the same bits whether its program was traced or
read.

**Records.** :func:`load_record` / :func:`store_record` keep small JSON values under the
same key rules (``.json`` files in the same folder): what a process would otherwise learn
by tracing a model again, such as the latent sites of a Laplace candidate
(:mod:`are_stats.fitting._laplace`).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import json
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any  # Any: a program's pytree of results

# JAX is imported by the functions that trace or compile, not with the module (the CLI
# imports it for prune_cache; each import says the cost, measured 2026-11-28).
if TYPE_CHECKING:
    import jax

__all__ = [
    "TRACE_LOCK",
    "cache_limit",
    "compile_program",
    "load_record",
    "program_folder",
    "prune_cache",
    "source_hash",
    "stable_repr",
    "store_record",
]

#: Held while a program is traced: numpyro's effect handlers live on one global stack, so
#: two threads must not trace models at once. Reading, lowering and compiling a kept
#: program need no lock: programs can be loaded in several threads while one is traced.
TRACE_LOCK = threading.RLock()

#: Options this jaxlib does not know (a later XLA may drop one): left out from then on.
_UNKNOWN_OPTIONS: set[str] = set()

#: Suffix of the program files.
SUFFIX = ".jaxexport"
#: Suffix of the record files (:func:`store_record`).
RECORD_SUFFIX = ".json"
#: Modules whose functions may be named in a key: are_stats (its source is hashed) and
#: the libraries whose versions are part of the key.
_KNOWN_MODULES = ("are_stats", "numpyro", "jax")


def program_folder() -> Path | None:
    """The folder of the exported programs, or None when the cache is off.

    Set by :func:`are_stats.configure_jax` (``ARE_STATS_PROGRAM_CACHE``):
    ``$XDG_CACHE_HOME/are_stats/programs``, empty when the cache is off.

    Returns
    -------
    Path or None
    """
    folder = os.environ.get("ARE_STATS_PROGRAM_CACHE", "")
    return Path(folder) if folder else None


@functools.cache
def source_hash() -> str:
    """SHA-256 of the are_stats package's Python sources (names and contents), once a process.

    Returns
    -------
    str
        Hex digest.
    """
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


class _Unstable(TypeError):
    """A key part without a stable text form."""


def _function_name(fn: object) -> str:
    module = getattr(fn, "__module__", None) or ""
    qual = getattr(fn, "__qualname__", None) or ""
    if not qual or "<" in qual or not module.startswith(_KNOWN_MODULES):
        raise _Unstable(f"no stable name for {fn!r}")
    # the name must find the same object (not a decorated or shadowed one)
    obj: object = sys.modules.get(module)
    for part in qual.split("."):
        obj = getattr(obj, part, None)
    if obj is not fn and getattr(obj, "__wrapped__", None) is not fn:
        raise _Unstable(f"{module}.{qual} does not name {fn!r}")
    return f"{module}.{qual}"


def _repr(x: object) -> str:
    if x is None or isinstance(x, (bool, int, float, complex, str, bytes)):
        return repr(x)
    if isinstance(x, enum.Enum):
        return f"{type(x).__module__}.{type(x).__qualname__}.{x.name}"
    if isinstance(x, functools.partial):
        kw = sorted(x.keywords.items())
        return f"partial({_repr(x.func)}, {_repr(x.args)}, {_repr(kw)})"
    if isinstance(x, tuple) and hasattr(type(x), "_fields"):  # NamedTuple
        return f"{_function_name(type(x))}{_repr(tuple(x))}"
    if isinstance(x, (tuple, list)):
        inner = ", ".join(_repr(v) for v in x)
        return f"({inner},)" if isinstance(x, tuple) else f"[{inner}]"
    if isinstance(x, dict):
        return "{" + ", ".join(f"{_repr(k)}: {_repr(v)}" for k, v in x.items()) + "}"
    if isinstance(x, (set, frozenset)):
        return "{" + ", ".join(sorted(_repr(v) for v in x)) + "}"
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        fields = {f.name: getattr(x, f.name) for f in dataclasses.fields(x)}
        return f"{_function_name(type(x))}{_repr(fields)}"
    if callable(x) and hasattr(x, "__qualname__"):
        return _function_name(x)
    np = sys.modules.get("numpy")
    if np is not None and isinstance(x, (np.dtype, np.generic)):
        return repr(x)
    jtu = sys.modules.get("jax.tree_util")
    if jtu is not None and isinstance(x, jtu.PyTreeDef):
        return str(x)  # node types by class name; the source hash covers their code
    raise _Unstable(f"no stable text for {type(x).__name__}")


def stable_repr(key: object) -> str | None:
    """A text of ``key`` that is the same in every process, or None when there is none.

    Python scalars, strings, enums, tuples, lists, dicts, sets, named tuples and
    dataclasses (by class and fields), NumPy dtypes and scalars, pytree structures, and
    functions (and ``functools.partial`` of them) of are_stats, numpyro or JAX by module
    and qualified name. Lambdas, local functions and other objects have no stable text.

    Parameters
    ----------
    key : object

    Returns
    -------
    str or None
    """
    try:
        return _repr(key)
    except _Unstable:
        return None


def _environment() -> str:
    # lazy: JAX adds 1.06 s CPU to `are-stats --help` (which imports prune_cache)
    import jax
    import jaxlib

    try:
        # lazy: NumPyro adds 0.64 s CPU after JAX
        import numpyro

        numpyro_version = numpyro.__version__
    except ImportError:  # pragma: no cover - numpyro is a dependency
        numpyro_version = "-"
    devices = jax.local_devices()
    return repr(
        (
            jax.__version__,
            jaxlib.__version__,
            numpyro_version,
            bool(jax.config.jax_enable_x64),
            devices[0].platform,
            len(devices),
            source_hash(),
        )
    )


def _file_name(key_text: str, args: tuple, options: dict | None, suffix: str = SUFFIX) -> str:
    # lazy: JAX adds 1.06 s CPU to `are-stats --help` (which imports prune_cache)
    import jax

    leaves, tree = jax.tree.flatten(args)
    avals = [(a.shape, str(a.dtype), a.weak_type) for a in map(jax.typeof, leaves)]
    text = repr((key_text, str(tree), avals, sorted((options or {}).items()), _environment()))
    return hashlib.sha256(text.encode()).hexdigest()[:40] + suffix


def _read(path: Path, leaves: list) -> jax.export.Exported | None:
    """The exported program in ``path`` when it is there, whole and fits ``leaves``."""
    # lazy: JAX adds 1.06 s CPU to `are-stats --help` (which imports prune_cache)
    import jax

    try:
        exported = jax.export.deserialize(bytearray(path.read_bytes()))
        want = [(jax.typeof(x).shape, jax.typeof(x).dtype) for x in leaves]
        if [(a.shape, a.dtype) for a in exported.in_avals] != want:
            return None
    except Exception:  # noqa: BLE001 - anything wrong with the file: trace again
        return None
    try:
        os.utime(path)  # its last use, for prune_cache
    except OSError:
        pass
    return exported


def _write(path: Path, blob: bytes) -> None:
    """Write ``blob`` to ``path`` through a temporary file in its folder; ignore failures."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            f.write(blob)
        os.replace(tmp, path)
        tmp = None
    except OSError:
        pass
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def _record_path(key: object, args: tuple) -> Path | None:
    folder = program_folder()
    key_text = None if key is None else stable_repr(key)
    if folder is None or key_text is None:
        return None
    return folder / _file_name(key_text, args, None, RECORD_SUFFIX)


def load_record(key: object, args: tuple) -> object:
    """The JSON value kept by :func:`store_record` for ``key`` and ``args``, or None.

    None when the cache is off, the key has no :func:`stable_repr`, or the file is
    missing, unreadable or not JSON; the caller then computes the value (and stores it).
    The caller checks the value's form: a record is a cache, never trusted input.

    Parameters
    ----------
    key : object
        What the value depends on besides the arguments' shapes (as for
        :func:`compile_program`).
    args : tuple
        Example arguments: their tree, shapes and dtypes are part of the file's name, as
        are the versions and the source hash.

    Returns
    -------
    object or None
        The decoded JSON value (lists where tuples were stored).
    """
    path = _record_path(key, args)
    if path is None:
        return None
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    try:
        os.utime(path)  # its last use, for prune_cache
    except OSError:
        pass
    return value


def store_record(key: object, args: tuple, value: object) -> None:
    """Keep the JSON value ``value`` for ``key`` and ``args`` (see :func:`load_record`).

    Written through a temporary file and renamed into place; nothing is kept when the
    cache is off or the key has no stable text, and a failed write is ignored.

    Parameters
    ----------
    key : object
    args : tuple
    value : JSON-serialisable
    """
    path = _record_path(key, args)
    if path is not None:
        _write(path, json.dumps(value).encode("utf-8"))


def compile_program(
    fn: Callable[..., Any],
    args: tuple,
    key: object,
    compiler_options: dict | None = None,
    in_shardings: tuple | None = None,
) -> Callable[..., Any]:
    """Compile the jitted ``fn`` for ``args``, its traced program read from disk if kept.

    Parameters
    ----------
    fn : jax.stages.Wrapped
        A ``jax.jit`` function (``jax.pmap`` ones are compiled as before, not exported).
    args : tuple
        Example arguments (a pytree: their tree, shapes and dtypes fix the program).
    key : object
        What else shapes ``fn``'s trace: the traced function (by name), its static
        arguments and settings. None, or a key without a :func:`stable_repr`, keeps the
        program off the disk.
    compiler_options : dict, optional
        XLA compiler options (e.g. cheap optimisation), part of the file's key.
    in_shardings : tuple of jax.sharding.Sharding, optional
        One sharding per argument (for all its leaves), when ``fn`` spreads over several
        devices (``shard_map``): the program is exported and called with them.

    Returns
    -------
    callable
        The compiled program, called with arguments of the same tree, shapes and dtypes
        as ``args``.
    """
    # lazy: JAX adds 1.06 s CPU to `are-stats --help` (which imports prune_cache)
    import jax

    folder = program_folder()
    key_text = None if key is None else stable_repr(key)
    if folder is None or key_text is None or not hasattr(fn, "trace"):
        with TRACE_LOCK:
            lowered = fn.lower(*args)
        return _compile_lowered(lowered, compiler_options)
    # exported with flat arguments: jax.export serialises only the pytree nodes it knows
    leaves, tree = jax.tree.flatten(args)
    shardings = None
    if in_shardings is not None:
        shardings = tuple(
            s for a, s in zip(args, in_shardings, strict=True) for _ in jax.tree.leaves(a)
        )
    path = folder / _file_name(key_text, args, compiler_options)
    exported = _read(path, leaves)
    if exported is not None:
        try:
            return _compile_exported(exported, leaves, shardings, compiler_options)
        except Exception:  # noqa: BLE001 - a file that reads but does not fit: trace again
            pass
    flat = jax.jit(lambda *xs: fn(*jax.tree.unflatten(tree, xs)), in_shardings=shardings)
    with TRACE_LOCK:
        exported = jax.export.export(flat)(*leaves)
    try:
        blob = exported.serialize()
    except Exception:  # noqa: BLE001 - e.g. an unregistered output node: not kept
        blob = None
    if blob is not None:
        _write(path, bytes(blob))
    return _compile_exported(exported, leaves, shardings, compiler_options)


def _compile_exported(
    exported: jax.export.Exported, leaves: list, shardings: tuple | None, options: dict | None
) -> Callable[..., Any]:
    """Compile ``exported`` (the same program whether just traced or read from disk)."""
    # lazy: JAX adds 1.06 s CPU to `are-stats --help` (which imports prune_cache)
    import jax

    compiled = _compile_lowered(
        jax.jit(exported.call, in_shardings=shardings).lower(*leaves), options
    )

    def call(*args: object) -> Any:
        return compiled(*jax.tree.leaves(args))

    return call


def _compile_lowered(lowered: jax.stages.Lowered, options: dict | None) -> jax.stages.Compiled:
    """``lowered.compile(options)``, leaving out the options this jaxlib does not know."""

    def known() -> dict | None:
        return (
            None
            if options is None
            else {k: v for k, v in options.items() if k not in _UNKNOWN_OPTIONS}
        )

    try:
        return lowered.compile(known())
    except Exception as err:  # noqa: BLE001 - XLA's own error type: one that names options
        unknown = {k for k in options or {} if f"No such compile option: '{k}'" in str(err)}
        if not unknown:
            raise
        _UNKNOWN_OPTIONS.update(unknown)
        return lowered.compile(known())


#: Default cap on each cache folder, MiB (``ARE_STATS_CACHE_MAX_MB``; 0: no cap).
CACHE_MAX_MB = 1024


def cache_limit() -> int | None:
    """Bytes each cache folder may hold (``ARE_STATS_CACHE_MAX_MB``, default 1024 MiB).

    Returns
    -------
    int or None
        None when the cap is off (``ARE_STATS_CACHE_MAX_MB=0``) or the value is not a
        number.
    """
    text = os.environ.get("ARE_STATS_CACHE_MAX_MB", "").strip()
    try:
        mb = float(text) if text else float(CACHE_MAX_MB)
    except ValueError:
        return None
    return int(mb * 2**20) if mb > 0 else None


def prune_cache(max_bytes: int | None = None, folders: list[Path] | None = None) -> int:
    """Delete the least recently used cache files of a folder past ``max_bytes``.

    Every compiled program stays in ``$XDG_CACHE_HOME/are_stats`` until removed: an
    edited or upgraded are_stats, other shapes or settings each add files. When a folder
    holds more than ``max_bytes``, its files are deleted, least recently used first (the
    later of access and modification time: the traced programs are touched when read,
    JAX's compiled ones carry the access time the file system keeps), until it holds at
    most 80% of it. A deleted program is compiled again when next needed. Files being
    written (temporary names younger than an hour) are kept; errors are ignored.

    Parameters
    ----------
    max_bytes : int, optional
        Cap per folder; default :func:`cache_limit`. None (and a cap that is off): nothing
        is deleted.
    folders : list of Path, optional
        Default: the traced programs' folder and JAX's compile cache, when are_stats
        manages it (:func:`are_stats.configure_jax`).

    Returns
    -------
    int
        Bytes deleted.
    """
    limit = cache_limit() if max_bytes is None else int(max_bytes)
    if limit is None:
        return 0
    if folders is None:
        folders = [
            Path(f)
            for f in (
                os.environ.get("ARE_STATS_PROGRAM_CACHE"),
                os.environ.get("ARE_STATS_JAX_CACHE"),
            )
            if f
        ]
    freed = 0
    now = time.time()
    for folder in folders:
        entries = []
        try:
            with os.scandir(folder) as it:
                for e in it:
                    try:
                        st = e.stat(follow_symlinks=False)
                    except OSError:
                        continue
                    if not e.is_file(follow_symlinks=False):
                        continue
                    if e.name.endswith(".tmp") and now - st.st_mtime < 3600:
                        continue
                    entries.append((max(st.st_atime, st.st_mtime), st.st_size, e.path))
        except OSError:
            continue
        total = sum(size for _, size, _ in entries)
        if total <= limit:
            continue
        for _, size, path in sorted(entries):
            if total <= 0.8 * limit:
                break
            try:
                os.unlink(path)
            except OSError:
                continue
            total -= size
            freed += size
    return freed
