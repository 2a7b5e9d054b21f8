"""The one validation layer for what users hand to the toolkit.

Every input kind (field logs, manifests, maps, catalogues, cameras, robot paths, scenario
folders, fit files, experiment configs, command-line options) is checked where it enters,
with the helpers below, so that the numerics never see a value of the wrong type, and users
never see a traceback from deep inside NumPy, PyYAML or JAX.

- :class:`InputError` names the input (a file or an option), the place inside it (row,
  column, key path) and what was expected; it subclasses :class:`ValueError`.
- :func:`load_yaml` reads YAML safely: duplicate keys rejected, alias expansion, nesting
  depth and file size bounded, YAML 1.2 numbers (``1e-9`` is a float, not a string).
- :func:`check_keys` and the ``get_*`` functions validate mappings and scalars strictly:
  no bool as a number, integers that fit int64, finite where finiteness matters, unknown
  keys rejected with the list of known ones.
- :func:`check_memory` and :func:`check_work` refuse, before anything is allocated, inputs
  that would need more memory or work than the documented limits (:data:`DEFAULT_MEMORY`,
  :data:`DEFAULT_WORK`), which ``ARE_STATS_MAX_MEMORY`` / ``ARE_STATS_MAX_WORK`` (or
  ``are-stats --max-memory/--max-work``) raise.

Examples
--------
>>> from are_stats.inputs import get_float
>>> get_float(0.5, "run.yaml", "robot.speed", lo=0, lo_open=True)
0.5
>>> get_float(True, "run.yaml", "robot.speed")
Traceback (most recent call last):
...
are_stats.inputs.InputError: run.yaml: robot.speed: expected a finite number, got True (a bool)
"""

from __future__ import annotations

import contextlib
import copy
import math
import os
import re
import threading
from collections import OrderedDict
from collections.abc import Hashable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any  # a parsed YAML document (parse_yaml, load_yaml): any value

import numpy as np
import yaml

from are_stats._checks import describe

#: Where an input came from, as an error names it: a file path or an option (``--seed``).
Source = str | os.PathLike[str]

__all__ = [
    "DEFAULT_MEMORY",
    "DEFAULT_WORK",
    "Described",
    "MAX_YAML_BYTES",
    "MAX_YAML_DEPTH",
    "MAX_SEED",
    "MAX_YAML_NODES",
    "Source",
    "InputError",
    "LimitError",
    "check_file",
    "check_keys",
    "check_memory",
    "check_work",
    "format_bytes",
    "get_bool",
    "get_float",
    "get_int",
    "get_list",
    "get_seed",
    "get_str",
    "limits",
    "load_yaml",
    "memory_limit",
    "parse_size",
    "parse_yaml",
    "work_limit",
]

#: Default memory limit (bytes) for one allocation sized by the input: 4 GiB.
DEFAULT_MEMORY = 4 * 2**30
#: Default work limit: elementary steps (array elements touched, events simulated,
#: ray-box tests, MDP state updates) one call may do, about a few minutes on one core.
DEFAULT_WORK = 5 * 10**10
#: Largest YAML file read (bytes).
MAX_YAML_BYTES = 16 * 2**20
#: Deepest nesting of YAML collections.
MAX_YAML_DEPTH = 64
#: Most nodes a YAML document may expand to once its aliases are followed.
MAX_YAML_NODES = 1_000_000

_MISSING = object()
_INT64 = (-(2**63), 2**63 - 1)


def _show(got: object, limit: int = 80) -> str:
    """A short description of a bad value, with its type where the repr hides it."""
    if isinstance(got, bool | np.bool_):
        return f"{bool(got)!r} (a bool)"
    if isinstance(got, str):
        text = repr(got) if len(got) <= limit else repr(got[:limit]) + f"... ({len(got)} chars)"
        return f"{text} (a string)"
    if got is None:
        return "nothing (null)"
    if isinstance(got, Mapping):
        keys = ", ".join(repr(k) for k in list(got)[:5])
        return f"a mapping with keys {keys}{', ...' if len(got) > 5 else ''}"
    if isinstance(got, list | tuple):
        text = repr(got)
        return f"a list {text if len(text) <= limit else text[:limit] + '...'}"
    if isinstance(got, np.ndarray):
        return describe(got, limit)
    text = repr(got.item() if isinstance(got, np.generic) else got)
    return text if len(text) <= limit else text[:limit] + "..."


class InputError(ValueError):
    """Bad user input, with where it is and what was expected.

    The message reads ``"<source>: <where>: expected <expected>, got <got>"``; ``where``
    (a row, a column, a key path) may be empty for whole-file problems, and ``got`` may be
    left out when there is nothing to show.

    Parameters
    ----------
    source : str or os.PathLike
        The input: a file path, or a command-line option such as ``--seed``.
    where : str
        The place inside it: ``"row 12 (line 13), column 'mark'"``, ``"robot.speed"``.
    expected : str
        What was expected, in words.
    got : object, optional
        What was found; described briefly (type shown for bools and strings).
    """

    def __init__(self, source: Source, where: str, expected: str, got: object = _MISSING) -> None:
        self.source = str(source)
        self.where = where
        self.expected = expected
        self.got = None if got is _MISSING else got
        text = f"{self.source}: " + (f"{where}: " if where else "") + f"expected {expected}"
        if got is not _MISSING:
            text += f", got {got if isinstance(got, Described) else _show(got)}"
        super().__init__(text)


class Described(str):
    """A ``got`` that is already worded (printed as is, not quoted as a string).

    Examples
    --------
    >>> str(InputError("m.obj", "", "a mesh with triangles", Described("an empty file")))
    'm.obj: expected a mesh with triangles, got an empty file'
    """


class LimitError(InputError):
    """The input asks for more memory or work than the current limit."""


# ---- limits ------------------------------------------------------------------------------

_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtTpP]?)(i?[bB])?\s*$")
_OVERRIDE: dict[str, int | None] = {"memory": None, "work": None}


def parse_size(text: str | int | float, source: str = "size") -> int:
    """Parse ``"16G"``, ``"512MiB"``, ``"1e9"`` or a number into an integer count.

    Suffixes K, M, G, T, P are powers of 1024 (with or without ``iB``/``B``).
    """
    if isinstance(text, bool):
        raise InputError(source, "", "a size such as 4G, 512M or 1e9", text)
    if isinstance(text, int | float):
        value, unit = float(text), ""
    else:
        m = _SIZE.match(str(text))
        if m is None:
            raise InputError(source, "", "a size such as 4G, 512M or 1e9", str(text))
        value, unit = float(m.group(1)), m.group(2).upper()
    scale = 1024 ** "_KMGTP".index(unit) if unit else 1
    out = value * scale
    if not math.isfinite(out) or out <= 0 or out > 2**62:
        raise InputError(source, "", "a positive size below 2**62", text)
    return int(out)


def _limit(kind: str, env: str, default: int) -> int:
    if _OVERRIDE[kind] is not None:
        return int(_OVERRIDE[kind])  # type: ignore[arg-type]
    raw = os.environ.get(env)
    return default if raw in (None, "") else parse_size(raw, env)


def memory_limit() -> int:
    """Bytes one input-sized allocation may take (``ARE_STATS_MAX_MEMORY``, default 4 GiB)."""
    return _limit("memory", "ARE_STATS_MAX_MEMORY", DEFAULT_MEMORY)


def work_limit() -> int:
    """Elementary steps one call may do (``ARE_STATS_MAX_WORK``, default 5e10)."""
    return _limit("work", "ARE_STATS_MAX_WORK", DEFAULT_WORK)


@contextlib.contextmanager
def limits(memory: int | str | None = None, work: int | str | None = None) -> Iterator[None]:
    """Temporarily set the memory and/or work limits (``None`` keeps the current one).

    Examples
    --------
    >>> from are_stats.inputs import limits, memory_limit
    >>> with limits(memory="1G"):
    ...     memory_limit()
    1073741824
    """
    old = dict(_OVERRIDE)
    try:
        if memory is not None:
            _OVERRIDE["memory"] = parse_size(memory, "memory limit")
        if work is not None:
            _OVERRIDE["work"] = parse_size(work, "work limit")
        yield
    finally:
        _OVERRIDE.update(old)


def format_bytes(n: float) -> str:
    """``1536 -> '1.5 KiB'``; past 1024 PiB in scientific notation (``'1e+300 B'``)."""
    if not abs(n) < 2**60:
        return f"{n:.3g} B"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} EiB"  # pragma: no cover


def check_memory(n_bytes: float, what: str, source: Source = "") -> None:
    """Refuse an allocation of about ``n_bytes`` past :func:`memory_limit`.

    Parameters
    ----------
    n_bytes : float
        Estimated size (may be huge or infinite: it is never allocated here).
    what : str
        What would be allocated, e.g. ``"the 100000 x 100000 map image"``.
    source : str, optional
        The input that asks for it (file or option), named in the message.
    """
    limit = memory_limit()
    if not n_bytes <= limit:  # also catches NaN
        raise LimitError(
            source or "input",
            "",
            f"{what} to fit in the memory limit of {format_bytes(limit)} "
            "(raise it with are-stats --max-memory SIZE or ARE_STATS_MAX_MEMORY)",
            Described(f"about {format_bytes(float(n_bytes))}"),
        )


def check_work(n_ops: float, what: str, source: Source = "") -> None:
    """Refuse a computation of about ``n_ops`` elementary steps past :func:`work_limit`."""
    limit = work_limit()
    if not n_ops <= limit:
        raise LimitError(
            source or "input",
            "",
            f"{what} to fit in the work limit of {limit:.3g} steps "
            "(raise it with are-stats --max-work N or ARE_STATS_MAX_WORK)",
            Described(f"about {float(n_ops):.3g} steps"),
        )


# ---- YAML -------------------------------------------------------------------------------


class _TooDeep(Exception):
    """Collections nested past :data:`MAX_YAML_DEPTH` while composing."""


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 floats, duplicate keys rejected and nesting bounded.

    Nesting is counted as the collections are composed, and flow collections (``[``, ``{``)
    as they are scanned, and refused at the first level past :data:`MAX_YAML_DEPTH`: PyYAML's
    scanner costs time quadratic in the open flow levels (each token walks the possible
    simple keys of all of them) and reads up to 1,024 characters ahead of the composer, so a
    deep document read to Python's recursion limit took about 1.8 s; stopped at the limit it
    takes milliseconds.
    """

    _depth = 0

    def fetch_flow_collection_start(self, token_class: type) -> None:
        if self.flow_level >= MAX_YAML_DEPTH:
            raise _TooDeep
        yaml.SafeLoader.fetch_flow_collection_start(self, token_class)

    def _nested(self, compose: Any, anchor: str | None) -> yaml.Node:
        if self._depth >= MAX_YAML_DEPTH:
            raise _TooDeep
        self._depth += 1
        try:
            return compose(self, anchor)
        finally:
            self._depth -= 1

    def compose_sequence_node(self, anchor: str | None) -> yaml.SequenceNode:
        return self._nested(yaml.SafeLoader.compose_sequence_node, anchor)

    def compose_mapping_node(self, anchor: str | None) -> yaml.MappingNode:
        return self._nested(yaml.SafeLoader.compose_mapping_node, anchor)


_Loader.yaml_implicit_resolvers = {
    k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
# YAML 1.1 reads 1e-9 and 1E5 as strings; users mean numbers (YAML 1.2 core schema).
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


class _DuplicateKey(Exception):
    def __init__(self, key: Hashable, line: int) -> None:
        self.key, self.line = key, line


def _construct_mapping(loader: _Loader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen: set[Hashable] = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=True)
        try:
            dup = key in seen
        except TypeError:  # unhashable key: the base constructor reports it
            break
        if dup:
            raise _DuplicateKey(key, key_node.start_mark.line + 1)
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_Loader.construct_mapping = _construct_mapping  # type: ignore[method-assign]


def _expanded_size(root: yaml.Node, source: str) -> None:
    """Nodes and depth of the tree once aliases are followed, without expanding it."""
    memo: dict[int, tuple[int, int]] = {}
    on_stack: set[int] = set()

    def visit(node: yaml.Node) -> tuple[int, int]:
        key = id(node)
        if key in memo:
            return memo[key]
        if key in on_stack:
            raise InputError(
                source, "", "YAML without recursive aliases", Described("a recursive alias")
            )
        if isinstance(node, yaml.ScalarNode):
            return (1, 0)
        on_stack.add(key)
        children: list[yaml.Node] = (
            [n for kv in node.value for n in kv]
            if isinstance(node, yaml.MappingNode)
            else list(node.value)
        )
        size, depth = 1, 0
        for child in children:
            s, d = visit(child)
            size, depth = size + s, max(depth, d)
            if size > MAX_YAML_NODES:
                break
        on_stack.discard(key)
        memo[key] = (size, depth + 1)
        if size > MAX_YAML_NODES:
            raise InputError(
                source,
                "",
                f"YAML that expands to at most {MAX_YAML_NODES} values once its aliases are "
                "followed",
                Described(f"more than {MAX_YAML_NODES} (an alias bomb?)"),
            )
        if depth + 1 > MAX_YAML_DEPTH:
            raise InputError(
                source,
                "",
                f"YAML nested at most {MAX_YAML_DEPTH} levels deep",
                Described(f"{depth + 1} levels"),
            )
        return memo[key]

    visit(root)


#: Documents parsed from texts of at most :data:`PARSED_MAX_CHARS` characters, by their
#: text (the last :data:`PARSED_KEPT`): PyYAML's pure-Python loader takes some 12 ms for the
#: shipped catalogue, which every command and many functions read again. Only successful
#: parses are kept (a document depends on its text alone; ``source`` and ``what`` only name
#: it in errors), and each caller gets its own deep copy, free to change.
PARSED_KEPT = 32
PARSED_MAX_CHARS = 1 << 20
_PARSED: OrderedDict[str, Any] = OrderedDict()
_PARSED_LOCK = threading.Lock()  # the live view reads inputs from threads


def parse_yaml(text: str, source: Source, what: str = "YAML document") -> Any:
    """Parse YAML text safely (see :func:`load_yaml`); ``source`` names it in errors.

    A text parsed before (one of the last :data:`PARSED_KEPT`) is not parsed again: its
    document is handed out as a deep copy.
    """
    kept = len(text) <= PARSED_MAX_CHARS
    if kept:
        with _PARSED_LOCK:
            if text in _PARSED:
                _PARSED.move_to_end(text)
                return copy.deepcopy(_PARSED[text])
    doc = _parse_yaml(text, source, what)
    if kept:
        with _PARSED_LOCK:
            _PARSED[text] = copy.deepcopy(doc)
            while len(_PARSED) > PARSED_KEPT:
                _PARSED.popitem(last=False)
    return doc


def _parse_yaml(text: str, source: Source, what: str) -> Any:
    """:func:`parse_yaml` without its memo."""
    src = str(source)

    def invalid(err: yaml.YAMLError) -> InputError:
        return InputError(src, "", f"a {what} in valid YAML", Described(_yaml_problem(err)))

    def too_deep() -> InputError:
        deeper = Described("deeper nesting")
        return InputError(src, "", f"a {what} nested at most {MAX_YAML_DEPTH} levels deep", deeper)

    try:
        loader = _Loader(text)
    except yaml.YAMLError as err:  # e.g. NUL or control characters
        raise invalid(err) from None
    try:
        try:
            node = loader.get_single_node()
        except (_TooDeep, RecursionError):
            raise too_deep() from None
        except yaml.YAMLError as err:
            raise invalid(err) from None
        if node is None:
            return None
        _expanded_size(node, src)
        try:
            return loader.construct_document(node)
        except _DuplicateKey as dup:
            raise InputError(
                src,
                f"line {dup.line}",
                "each key once per mapping",
                Described(f"{dup.key!r} again"),
            ) from None
        except yaml.YAMLError as err:
            raise invalid(err) from None
        except RecursionError:
            raise too_deep() from None
    finally:
        loader.dispose()


def _yaml_problem(err: yaml.YAMLError) -> str:
    mark = getattr(err, "problem_mark", None)
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    return f"{problem} at line {mark.line + 1}, column {mark.column + 1}" if mark else problem


def check_file(path: str | os.PathLike, expected: str) -> int:
    """The size in bytes of ``path``, refused unless it is a regular file.

    The readers of YAML (:func:`load_yaml`), mesh and OctoMap files ask this first, so that a
    missing path, a directory and a FIFO or device (whose read would block or never end) get
    the same messages.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    expected : str
        What it should be, with its article, for messages (``"an OctoMap .bt file"``).

    Returns
    -------
    int
        The file's size in bytes.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    InputError
        If it is a directory or not a regular file.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file: expected {expected}")
    if p.is_dir():
        raise InputError(p, "", expected, Described("a directory"))
    if not p.is_file():
        raise InputError(p, "", f"{expected} in a regular file", Described("not a regular file"))
    return p.stat().st_size


def load_yaml(path: str | os.PathLike, what: str = "YAML file") -> Any:
    """Read a YAML file safely.

    Duplicate keys are errors (PyYAML keeps the last silently); aliases may not expand to
    more than :data:`MAX_YAML_NODES` values (no "billion laughs"), nesting is limited to
    :data:`MAX_YAML_DEPTH`, files to :data:`MAX_YAML_BYTES`; numbers follow YAML 1.2 (``1e-9``
    is a float).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file should be, for messages (``"ROS map YAML"``).

    Returns
    -------
    object
        The document (``None`` for an empty file).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    InputError
        If it is a directory, too large, not UTF-8 or not valid YAML.
    """
    p = Path(path)
    size = check_file(p, f"a {what}")
    if size > MAX_YAML_BYTES:
        raise InputError(
            p,
            "",
            f"a {what} of at most {format_bytes(MAX_YAML_BYTES)}",
            Described(format_bytes(size)),
        )
    try:
        text = p.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(
            p, f"byte {err.start}", f"a {what} in UTF-8 text", Described("undecodable bytes")
        ) from None
    except OSError as err:
        raise InputError(p, "", f"a readable {what}", Described(err.strerror or str(err))) from None
    return parse_yaml(text, p, what)


# ---- mappings and scalars ---------------------------------------------------------------


def _join(where: str, key: object) -> str:
    return f"{where}.{key}" if where else str(key)


def check_keys(
    mapping: object,
    source: Source,
    where: str,
    known: Iterable[str],
    required: Iterable[str] = (),
) -> dict[str, object]:
    """A mapping whose keys are all known and include the required ones.

    Parameters
    ----------
    mapping : object
        The value to check.
    source, where : str
        The input and the key path of ``mapping`` inside it (``""`` for the top level).
    known : iterable of str
        Every key allowed.
    required : iterable of str
        Keys that must be present.

    Returns
    -------
    dict
        ``mapping`` as a plain dict.
    """
    known = list(known)
    if not isinstance(mapping, Mapping):
        raise InputError(source, where, "a mapping of " + ", ".join(known), mapping)
    unknown = [k for k in mapping if k not in known]
    if unknown:
        raise InputError(
            source,
            _join(where, unknown[0]),
            "one of the known keys " + ", ".join(known),
            Described(f"an unknown key {unknown[0]!r}"),
        )
    missing = [k for k in required if k not in mapping]
    if missing:
        raise InputError(
            source, _join(where, missing[0]), "this key to be present", Described("no such key")
        )
    return dict(mapping)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def get_float(
    value: object,
    source: Source,
    where: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    finite: bool = True,
) -> float:
    """A real number (not a bool, string or list), optionally finite and in a range.

    Parameters
    ----------
    value : object
        The value to check.
    source, where : str
        The input and the key path (or option) named in the message.
    lo, hi : float, optional
        Bounds; ``lo_open``/``hi_open`` make them strict.
    finite : bool
        Reject NaN and infinities (default).
    """
    lo_s = "" if lo is None else f"{'>' if lo_open else '>='} {lo:g}"
    hi_s = "" if hi is None else f"{'<' if hi_open else '<='} {hi:g}"
    bounds = " and ".join(s for s in (lo_s, hi_s) if s)
    expected = ("a finite number" if finite else "a number") + (f" {bounds}" if bounds else "")
    x = _as_float(value)
    if x is None or not _within(x, lo, hi, lo_open, hi_open, finite):
        raise InputError(source, where, expected, value)
    return x


def _as_float(value: object) -> float | None:
    """``value`` as a float; None for a non-number (a bool, string, list) or an int too
    large for a float."""
    if not _is_number(value):
        return None
    try:
        return float(value)
    except OverflowError:
        return None


def _within(
    x: float, lo: float | None, hi: float | None, lo_open: bool, hi_open: bool, finite: bool
) -> bool:
    """Whether ``x`` passes :func:`get_float`'s checks (NaN only when neither finite nor
    bounded)."""
    if math.isnan(x):
        return not (finite or lo is not None or hi is not None)
    if finite and not math.isfinite(x):
        return False
    below = lo is not None and (x < lo or (lo_open and x == lo))
    return not (below or (hi is not None and (x > hi or (hi_open and x == hi))))


def get_int(
    value: object, source: Source, where: str, *, lo: int | None = None, hi: int | None = None
) -> int:
    """An integer that fits int64 (integral floats such as ``1.0e3`` accepted; no bools)."""
    lo_ = _INT64[0] if lo is None else lo
    hi_ = _INT64[1] if hi is None else hi
    bounds = []
    if lo is not None:
        bounds.append(f">= {lo}")
    if hi is not None:
        bounds.append(f"<= {hi}")
    expected = "an integer" + (f" {' and '.join(bounds)}" if bounds else " that fits int64")
    n = _as_int(value)
    if n is None or n < lo_ or n > hi_:
        raise InputError(source, where, expected, value)
    return n


def _as_int(value: object) -> int | None:
    """``value`` as an int; None for a non-number or a float that is not a whole number in
    int64's range."""
    if not _is_number(value):
        return None
    if isinstance(value, float | np.floating) and not (
        math.isfinite(value) and value == math.floor(value) and -(2.0**63) <= value < 2.0**63
    ):
        return None
    return int(value)


def get_bool(value: object, source: Source, where: str) -> bool:
    """``true`` or ``false`` (not 0/1, not strings)."""
    if not isinstance(value, bool | np.bool_):
        raise InputError(source, where, "true or false", value)
    return bool(value)


def get_str(
    value: object, source: Source, where: str, *, choices: Iterable[str] | None = None
) -> str:
    """A string, optionally one of ``choices``."""
    opts = None if choices is None else list(choices)
    expected = "a string" if opts is None else "one of " + ", ".join(repr(c) for c in opts)
    if not isinstance(value, str) or (opts is not None and value not in opts):
        raise InputError(source, where, expected, value)
    return value


def get_list(
    value: object,
    source: Source,
    where: str,
    *,
    min_len: int = 0,
    max_len: int | None = None,
) -> list[object]:
    """A list (or tuple) with a length in ``[min_len, max_len]``."""
    size = (
        f"at least {min_len}"
        if max_len is None
        else f"{min_len}"
        if min_len == max_len
        else f"{min_len} to {max_len}"
    )
    expected = f"a list of {size} values"
    if not isinstance(value, list | tuple):
        raise InputError(source, where, expected, value)
    if len(value) < min_len or (max_len is not None and len(value) > max_len):
        raise InputError(source, where, expected, Described(f"{len(value)} values"))
    return list(value)


#: Largest seed accepted (seeds are 32-bit, so that ``seed + k`` sub-seeds never overflow).
MAX_SEED = 2**32 - 1


def get_seed(value: object, source: str = "--seed") -> int:
    """A seed for :func:`jax.random.key` and NumPy: an integer in ``[0, 2**32 - 1]``."""
    return get_int(value, source, "", lo=0, hi=MAX_SEED)
