"""Seeded hypothesis strategies of malformed-but-fair inputs, and the per-case guard.

Every strategy starts from a *valid* input (a file shipped in ``are_stats/data`` or a small
table written here) and applies one to three edits of the kinds a hostile-but-fair user
could produce: dropped or extra fields, swapped types, bools, huge / negative / NaN / inf
numbers, empty cells, a BOM, unicode, very long fields, truncated files, garbage bytes,
YAML lists or mappings where scalars belong, unknown and duplicate keys, deep nesting and
alias bombs. A case is ``bytes`` (the file's new content) or :data:`DIRECTORY` (a folder
where the file belongs).

:func:`bounded` is the per-case time and memory guard; :func:`expect_clean` states the
contract: a case succeeds, or raises ``ValueError`` / ``FileNotFoundError`` /
``FileExistsError`` (``are_stats.inputs.InputError`` is a ``ValueError``) whose message
names the input; any other exception is a finding.
"""

from __future__ import annotations

import contextlib
import copy
import csv
import functools
import inspect
import io
import os
import resource
import signal
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

from are_stats.environment import SHIPPED_DATA

#: The package data folder (:data:`are_stats.environment.SHIPPED_DATA`).
MODELS = SHIPPED_DATA

#: A case that puts a directory where the file belongs.
DIRECTORY = "<directory>"

#: Exceptions that are a clean refusal (with the input named in the message).
ACCEPTED = (ValueError, FileNotFoundError, FileExistsError)

# ----------------------------------------------------------------------------- run size


def n_examples(default: int) -> int:
    """Examples per test: ``default`` times ``ARE_STATS_FUZZ_EXAMPLES`` (a multiplier, 1)."""
    scale = float(os.environ.get("ARE_STATS_FUZZ_EXAMPLES", "1"))
    return max(1, int(default * scale))


def fuzz_settings(default: int) -> settings:
    """Reproducible hypothesis settings: derandomized, no database, no deadline.

    Shrinking is skipped in the default run (a failing case is still reported, unshrunk) so a
    known bug does not cost minutes; the larger run (``ARE_STATS_FUZZ_EXAMPLES`` > 1)
    shrinks to a minimal reproduction.
    """
    big = float(os.environ.get("ARE_STATS_FUZZ_EXAMPLES", "1")) > 1
    phases = tuple(Phase) if big else (Phase.explicit, Phase.generate)
    return settings(
        max_examples=n_examples(default),
        derandomize=True,
        database=None,
        deadline=None,
        phases=phases,
        suppress_health_check=list(HealthCheck),
        print_blob=False,
    )


#: The tiers a fuzz test's examples are split between: ``make test`` runs the first stream
#: (``-m "not slow"``), ``make test-slow`` the second (``-m slow``); CI runs both.
TIERS = ("default", "slow")


def fuzz_tiers(
    default: int, **strategies: st.SearchStrategy[Any]
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """``@given(**strategies)`` with ``default`` examples split between the two test tiers.

    In place of ``@fuzz_settings(default)`` and ``@given(**strategies)``. The test becomes
    one pytest test per tier, each a hypothesis test with :func:`fuzz_settings` and its own
    reproducible stream (:func:`hypothesis.seed` of the test's name and tier; with
    ``derandomize`` alone both would draw the same cases, for hypothesis derives that seed
    from the test function): ``test_x[default]`` in ``make test`` runs ``default // 4 + 1``
    examples, ``test_x[slow]`` (marked slow) in ``make test-slow`` runs ``default + 2``,
    both times ``ARE_STATS_FUZZ_EXAMPLES``.

    The slow stream is the longer one so that CI (both tiers) runs at least as many
    distinct cases as one stream of ``default`` examples did: a stream repeats cases
    (small spaces such as the directory case, and hypothesis draws simple cases more often
    early in a run), and the two streams share a few, the simplest first. Counted per test
    on 2026-11-28 (``repr`` of the drawn case, or of the files a ``data()`` test wrote).
    The split was half and three quarters until 2026-11-29; the default tier's quarter
    (every test still runs, each on a stream of its own) keeps ``make test`` within its
    15 minutes (issue 25), and CI runs the same number of cases in all.
    """
    counts = {TIERS[0]: default // 4 + 1, TIERS[1]: default + 2}

    def decorate(body: Callable[..., None]) -> Callable[..., None]:
        tests = {
            tier: seed(f"{body.__name__}/{tier}")(fuzz_settings(n)(given(**strategies)(body)))
            for tier, n in counts.items()
        }
        # the fixtures: hypothesis leaves out the arguments it draws
        signature = inspect.signature(tests[TIERS[0]])

        def run(tier: str, **fixtures: Any) -> None:
            tests[tier](**fixtures)

        for name in ("__name__", "__qualname__", "__doc__", "__module__"):
            setattr(run, name, getattr(body, name))
        tier_parameter = inspect.Parameter("tier", inspect.Parameter.POSITIONAL_OR_KEYWORD)
        run.__signature__ = signature.replace(  # type: ignore[attr-defined]
            parameters=[tier_parameter, *signature.parameters.values()]
        )
        tiers = [pytest.param(TIERS[0]), pytest.param(TIERS[1], marks=pytest.mark.slow)]
        return pytest.mark.parametrize("tier", tiers)(run)

    return decorate


# ----------------------------------------------------------------------------- the guard


class CaseTimeout(BaseException):  # noqa: N818 (a BaseException so `except Exception` cannot eat it)
    """Raised by :func:`bounded` when a case runs past its time."""


def _vm_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


@contextlib.contextmanager
def bounded(
    seconds: float = 20.0, memory: int = 3 * 2**30, cpu_seconds: float | None = None
) -> Iterator[None]:
    """Run a case with a time limit and a memory limit.

    Time: ``setitimer`` raises :class:`CaseTimeout` (a ``BaseException``, so no
    ``except Exception`` in the package can swallow it) in the main thread; it cannot stop
    a single C call, but every loop sized by an input returns to Python or allocates
    first, and the allocation is what the memory limit catches. ``seconds`` is wall-clock
    time; ``cpu_seconds``, where given, also bounds the CPU time of the process (all its
    threads, ``ITIMER_PROF``), which does not grow when other processes share the cores:
    a long case bounded by CPU time can keep a generous wall-clock bound for hangs only.

    Memory: ``RLIMIT_AS`` set to the process's current address space plus ``memory`` for
    the case, restored afterwards. Unlike ``tracemalloc`` it sees every allocation (NumPy,
    pandas, Arrow, HDF5, XLA), costs nothing per allocation (tracemalloc slows pandas
    parsing several-fold), and it *prevents* a runaway allocation instead of measuring it
    after the machine ran out of memory: the allocation fails with ``MemoryError``, which is
    not an accepted refusal, so the case fails naming the input. The limit is relative, so
    the large virtual reservations JAX makes at import do not matter.
    """

    def on_alarm(signum: int, frame: Any) -> None:
        raise CaseTimeout(f"case ran past {seconds} s")

    def on_cpu(signum: int, frame: Any) -> None:
        raise CaseTimeout(f"case ran past {cpu_seconds} s of CPU time")

    old_handler = signal.signal(signal.SIGALRM, on_alarm)
    old_prof = signal.signal(signal.SIGPROF, on_cpu) if cpu_seconds is not None else None
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = _vm_bytes() + memory
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    signal.setitimer(signal.ITIMER_REAL, seconds)
    if cpu_seconds is not None:
        signal.setitimer(signal.ITIMER_PROF, cpu_seconds)
    try:
        yield
    except CaseTimeout as err:
        # raised by the signal handler inside whatever ran: that traceback can hold a frame
        # without a line number (CPython 3.11, a C call interrupted), on which pytest's
        # report fails with an INTERNALERROR that ends the whole run (2026-11-28): the
        # timeout goes on from here, without the interrupted frames
        raise CaseTimeout(str(err)) from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        if cpu_seconds is not None:
            signal.setitimer(signal.ITIMER_PROF, 0)
            signal.signal(signal.SIGPROF, old_prof)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


#: The work one fuzz case may do (s of CPU time of the process, all threads), and the
#: wall-clock bound for a case that hangs without using CPU (:func:`expect_clean`).
CASE_CPU_SECONDS = 20.0
CASE_WALL_SECONDS = 120.0


def expect_clean(fn: Callable[[], Any], names: Sequence[str], **limits: Any) -> Any:
    """Run ``fn`` under :func:`bounded`; a refusal must name one of ``names``.

    Returns ``fn()``'s result, or ``None`` when it refused cleanly. Any exception other than
    :data:`ACCEPTED` propagates (the case fails); an accepted one whose message names none of
    ``names`` fails with an ``AssertionError``.

    Unless ``limits`` say otherwise a case may take :data:`CASE_CPU_SECONDS` of CPU time and
    :data:`CASE_WALL_SECONDS` of wall-clock time: the work bound is CPU time, which does not
    grow when other processes share the cores (a 20 s wall bound failed cases of a second's
    work on a machine at load 11-20); the wall bound is for hangs that use no CPU.
    """
    limits.setdefault("cpu_seconds", CASE_CPU_SECONDS)
    limits.setdefault("seconds", CASE_WALL_SECONDS)
    try:
        with bounded(**limits):
            return fn()
    except ACCEPTED as err:
        msg = str(err)
        assert any(n and n in msg for n in names), (
            f"{type(err).__name__} does not name the input (one of {list(names)}): {msg!r}"
        )
        assert "Traceback" not in msg, msg
        return None


# ----------------------------------------------------------------------------- values

#: Scalars a YAML field may get instead of the right one.
NASTY_SCALARS: list[Any] = [
    True,
    False,
    None,
    0,
    -1,
    1.5,
    -0.0,
    1e30,
    -1e30,
    9.3e18,
    2**63,
    2**70,
    -(2**70),
    1e-320,
    float("nan"),
    float("inf"),
    float("-inf"),
    "",
    "abc",
    "1e999",
    "12",
    "\u0663",
    "caf\u00e9 \U0001f600",
    "x" * 5000,
]

#: Values a YAML field may get instead of a scalar (or instead of a list / mapping).
NASTY_VALUES: list[Any] = [*NASTY_SCALARS, [], [1, 2], [[1]], {}, {"a": 1}, [None], [True]]

#: Cells a table may get.
NASTY_CELLS: list[str] = [
    "",
    " ",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "1e30",
    "-1e30",
    "9.3e18",
    str(2**63),
    str(2**70),
    "-1",
    "0",
    "-0",
    "1e-320",
    "1.5",
    "true",
    "True",
    "1,5",
    " 1 ",
    "0x10",
    "1_000",
    "\u0661\u0662",
    "caf\u00e9",
    "\U0001f600",
    "x" * 20000,
    '"',
    "None",
    "NULL",
    "#",
]


# ----------------------------------------------------------------------------- tables


def read_csv_rows(path: Path, n_rows: int | None = None) -> tuple[list[str], list[list[str]]]:
    """Header and the first ``n_rows`` rows of a CSV file."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1 : None if n_rows is None else n_rows + 1]


def _csv_text(header: list[str], rows: list[list[str]], sep: str = ",") -> str:
    buf = io.StringIO()
    w = csv.writer(buf, delimiter=sep, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


@st.composite
def _byte_edit(draw: st.DrawFn, data: bytes) -> bytes:
    kind = draw(
        st.sampled_from(
            ["none"] * 6 + ["bom", "truncate", "garbage", "nul", "latin1", "crlf", "empty"]
        )
    )
    if kind == "bom":
        return b"\xef\xbb\xbf" + data
    if kind == "truncate":
        return data[: draw(st.integers(0, max(0, len(data) - 1)))]
    if kind == "garbage":
        at = draw(st.integers(0, len(data)))
        junk = draw(st.binary(min_size=1, max_size=64))
        return data[:at] + junk + data[at:]
    if kind == "nul":
        at = draw(st.integers(0, len(data)))
        return data[:at] + b"\x00" + data[at:]
    if kind == "latin1":
        return data + "\ncaf\u00e9".encode("latin-1")
    if kind == "crlf":
        return data.replace(b"\n", b"\r\n")
    if kind == "empty":
        return b""
    return data


@st.composite
def csv_case(
    draw: st.DrawFn, header: Sequence[str], rows: Sequence[Sequence[str]], max_edits: int = 3
) -> bytes:
    """A CSV table after one to ``max_edits`` edits, then maybe a byte-level edit."""
    header = list(header)
    rows = [list(r) for r in rows]
    for _ in range(draw(st.integers(1, max_edits))):
        kind = draw(
            st.sampled_from(
                [
                    "cell",
                    "cell",
                    "cell",
                    "column_cells",
                    "drop_column",
                    "extra_column",
                    "rename_column",
                    "duplicate_column",
                    "drop_rows",
                    "short_row",
                    "long_row",
                    "duplicate_row",
                    "blank_line",
                    "reverse_rows",
                ]
            )
        )
        ncol = len(header)
        if kind in ("cell", "column_cells") and rows and ncol:
            j = draw(st.integers(0, ncol - 1))
            value = draw(st.sampled_from(NASTY_CELLS))
            targets = (
                range(len(rows))
                if kind == "column_cells"
                else [draw(st.integers(0, len(rows) - 1))]
            )
            for i in targets:
                if j < len(rows[i]):
                    rows[i][j] = value
        elif kind == "drop_column" and ncol:
            j = draw(st.integers(0, ncol - 1))
            header.pop(j)
            for r in rows:
                if j < len(r):
                    r.pop(j)
        elif kind == "extra_column":
            header.append(draw(st.sampled_from(["extra", "", "id", "t", "\u00e9"])))
            for r in rows:
                r.append(draw(st.sampled_from(NASTY_CELLS[:12])))
        elif kind == "rename_column" and ncol:
            j = draw(st.integers(0, ncol - 1))
            header[j] = draw(st.sampled_from([header[j].upper(), " " + header[j], "", "?"]))
        elif kind == "duplicate_column" and ncol:
            j = draw(st.integers(0, ncol - 1))
            header.append(header[j])
            for r in rows:
                r.append(r[j] if j < len(r) else "")
        elif kind == "drop_rows":
            rows = rows[: draw(st.integers(0, 1))]
        elif kind == "short_row" and rows:
            r = rows[draw(st.integers(0, len(rows) - 1))]
            if r:
                r.pop()
        elif kind == "long_row" and rows:
            rows[draw(st.integers(0, len(rows) - 1))].append("1")
        elif kind == "duplicate_row" and rows:
            rows.append(list(rows[draw(st.integers(0, len(rows) - 1))]))
        elif kind == "blank_line" and rows:
            rows.insert(draw(st.integers(0, len(rows))), [])
        elif kind == "reverse_rows":
            rows.reverse()
    sep = draw(st.sampled_from([","] * 8 + [";", "\t"]))
    return draw(_byte_edit(_csv_text(header, rows, sep).encode()))


# ----------------------------------------------------------------------------- YAML


def _paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, (*prefix, i))
    return out


def _parent(doc: Any, path: tuple) -> Any:
    for k in path[:-1]:
        doc = doc[k]
    return doc


def _dump(doc: Any) -> str:
    return yaml.safe_dump(doc, sort_keys=False, allow_unicode=True, width=10**6)


def alias_bomb(levels: int = 9, fan: int = 9) -> str:
    """A billion-laughs document: ``fan ** levels`` leaves from a few hundred bytes."""
    lines = ['a0: &a0 ["lol"]']
    for i in range(1, levels + 1):
        refs = ", ".join(f"*a{i - 1}" for _ in range(fan))
        lines.append(f"a{i}: &a{i} [{refs}]")
    return "\n".join(lines) + "\n"


def deep_nesting(depth: int = 5000) -> str:
    """A flow sequence nested ``depth`` deep."""
    return "key: " + "[" * depth + "]" * depth + "\n"


@st.composite
def yaml_case(draw: st.DrawFn, base: Any, max_edits: int = 3) -> bytes:
    """A YAML document after structural edits, then maybe a text- or byte-level edit."""
    doc = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, max_edits))):
        paths = _paths(doc)
        kind = draw(st.sampled_from(["replace", "replace", "replace", "delete", "unknown", "wrap"]))
        if not paths or kind == "unknown":
            target = doc
            if paths and draw(st.booleans()):
                p = draw(st.sampled_from(paths))
                if isinstance(_parent(doc, p)[p[-1]], dict):
                    target = _parent(doc, p)[p[-1]]
            if isinstance(target, dict):
                target[draw(st.sampled_from(["unknown_key", "Window", "", "x" * 300]))] = 1
            continue
        p = draw(st.sampled_from(paths))
        parent = _parent(doc, p)
        if kind == "replace":
            parent[p[-1]] = copy.deepcopy(draw(st.sampled_from(NASTY_VALUES)))
        elif kind == "delete":
            del parent[p[-1]]
        else:
            parent[p[-1]] = draw(st.sampled_from([[parent[p[-1]]], {"value": parent[p[-1]]}]))
    text = _dump(doc)
    kind = draw(
        st.sampled_from(
            ["none"] * 8
            + ["duplicate_key", "alias_bomb", "deep", "list", "scalar", "tab", "anchor_reuse"]
        )
    )
    if kind == "duplicate_key" and isinstance(doc, dict) and doc:
        k = draw(st.sampled_from(list(doc)))
        text += _dump({k: copy.deepcopy(draw(st.sampled_from(NASTY_VALUES)))})
    elif kind == "alias_bomb":
        text = alias_bomb() + text if draw(st.booleans()) else alias_bomb()
    elif kind == "deep":
        # 100: refused by the depth check; 1000: by the parser's recursion. Deeper texts take
        # the second path at quadratic cost in PyYAML's scanner (2.5 s of CPU at 20000 under
        # hypothesis); test_yaml_bombs_are_refused sends each loader 100000 levels, and
        # tests/test_inputs.py parses 200000.
        text = deep_nesting(draw(st.sampled_from([100, 1000])))
    elif kind == "list":
        text = "- " + text.replace("\n", "\n  ")
    elif kind == "scalar":
        text = draw(st.sampled_from(["42\n", "~\n", "'text'\n", "!!binary aGVsbG8=\n", "[]\n"]))
    elif kind == "tab":
        text = text.replace("  ", "\t", 1)
    elif kind == "anchor_reuse" and isinstance(doc, dict):
        text = "base: &b {x: 1}\n" + text + "other: *b\n"
    return draw(_byte_edit(text.encode("utf-8")))


def load_base_yaml(path: Path) -> Any:
    """A shipped YAML file as data (the base of :func:`yaml_case`)."""
    return yaml.safe_load(path.read_text())


# ----------------------------------------------------------------------------- images, meshes


@st.composite
def pgm_case(draw: st.DrawFn, data: bytes) -> bytes:
    """A binary PGM with a forged header (huge, zero, negative sizes) or damaged pixels."""
    kind = draw(st.sampled_from(["header", "header", "bytes", "ascii"]))
    if kind == "header":
        w, h = draw(
            st.sampled_from(
                [(0, 0), (1, 1), (100000, 100000), (2**31, 2), (-5, 10), (10, 10), (300, 400)]
            )
        )
        maxval = draw(st.sampled_from([255, 0, 1, 65535, 70000]))
        body = data[data.index(b"255\n") + 4 :] if b"255\n" in data[:64] else data
        return f"P5\n{w} {h}\n{maxval}\n".encode() + body[: draw(st.integers(0, len(body)))]
    if kind == "ascii":
        return b"P2\n3 2\n255\n0 255 x\n1 2 3\n"
    return draw(_byte_edit(data))


@st.composite
def obj_case(draw: st.DrawFn, text: str) -> bytes:
    """A Wavefront OBJ with damaged vertices / faces."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["vertex", "face", "drop", "garbage"]))
        if kind == "vertex":
            v = draw(st.sampled_from(["nan", "inf", "1e30", "x", "", "2e308"]))
            lines.append(f"v {v} 0 0")
        elif kind == "face":
            f = draw(st.sampled_from(["1 2 999999", "0 0 0", "-999 1 2", "1", "a b c"]))
            lines.append(f"f {f}")
        elif kind == "drop" and lines:
            lines = [ln for ln in lines if not ln.startswith(draw(st.sampled_from(["v ", "f "])))]
        else:
            lines.append(draw(st.text(max_size=40)))
    return draw(_byte_edit("\n".join(lines).encode("utf-8", "surrogatepass")))


# ----------------------------------------------------------------------------- fit files

_FIT_EDITS = [
    ("attr", "area", float("nan")),
    ("attr", "area", -1.0),
    ("attr", "area", 1e300),
    ("attr", "area", "big"),
    ("attr", "class_labels", ""),
    ("attr", "class_labels", "a,b"),
    ("attr", "class_labels", "," * 40),
    ("attr", "method", "??"),
    ("var", "arrival_rate", float("nan")),
    ("var", "arrival_rate", -1.0),
    ("var", "arrival_rate", float("inf")),
    ("var", "arrival_rate", 1e30),
    ("var", "leave_rate", 0.0),
    ("var", "leave_rate", -1.0),
    ("var", "mix_weights", float("nan")),
    ("var", "mix_weights", -0.5),
    ("var", "mix_rates", 1e30),
    ("var", "mix_rates", -1.0),
    ("drop", "leave_rate", None),
    ("drop", "mix_weights", None),
    ("drop", "mix_rates", None),
    ("drop", "arrival_rate", None),
]


@st.composite
def fit_case(draw: st.DrawFn) -> tuple[str, tuple]:
    """A fit file edit: attributes / posterior values / dropped variables, or bytes."""
    kind = draw(st.sampled_from(["semantic", "semantic", "bytes"]))
    if kind == "bytes":
        return "bytes", (draw(st.integers(0, 10**7)), draw(st.binary(min_size=0, max_size=32)))
    return "semantic", tuple(draw(st.lists(st.sampled_from(_FIT_EDITS), min_size=1, max_size=2)))


@functools.lru_cache(maxsize=4)
def _loaded_fit(src: str, mtime_ns: int) -> Any:
    """The fit file ``src`` read whole into memory once (``mtime_ns``: a rewritten file is
    read again): each case edits a deep copy, sparing a read of every group (about 0.4 s
    of CPU a case)."""
    import arviz as az

    idata = az.from_netcdf(src)
    for group in idata.groups():
        getattr(idata, group).load()
    return idata


def write_fit_case(src: Path, dst: Path, case: tuple[str, tuple]) -> None:
    """Write ``src`` with the edit ``case`` (from :func:`fit_case`) applied to ``dst``."""
    kind, spec = case
    if kind == "bytes":
        data = src.read_bytes()
        at, junk = spec
        at = at % len(data)
        dst.write_bytes(data[:at] + junk if junk else data[:at])
        return
    from are_stats.fitting import write_fit  # lazy like arviz in _loaded_fit: JAX comes too

    idata = copy.deepcopy(_loaded_fit(str(src), src.stat().st_mtime_ns))
    post = idata.posterior
    for what, name, value in spec:
        if what == "attr":
            post.attrs[name] = value
        elif what == "var" and name in post:
            post[name] = post[name] * 0 + value
        elif what == "drop" and name in post:
            post = post.drop_vars(name)
    idata.posterior = post
    # the writer of ``are-stats fit`` (one open file; the file InferenceData.to_netcdf
    # writes, which reopens it for every group: 0.51 -> 0.43 s of CPU a case)
    write_fit(idata, dst)


# ----------------------------------------------------------------------------- writing cases


def write_case(path: Path, case: bytes | str) -> Path:
    """Put a case at ``path``: its bytes, or a directory when ``case`` is :data:`DIRECTORY`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if case == DIRECTORY:
        path.mkdir()
    else:
        path.write_bytes(case)
    return path


def file_cases(strategy: st.SearchStrategy[bytes]) -> st.SearchStrategy[bytes | str]:
    """``strategy``'s cases, and now and then a directory where the file belongs."""
    return st.one_of(strategy, strategy, strategy, strategy, st.just(DIRECTORY))


# ----------------------------------------------------------------------------- small valid tables

#: A tiny valid life-cycle log (the first 40 rows of the shipped example log).
LOG_HEADER, LOG_ROWS = read_csv_rows(MODELS / "logs" / "courtyard_traffic.csv", 40)

#: A tiny valid manifest for it (area instead of the shipped map, so it stands alone).
MANIFEST = {"window": [0.0, 14400.0], "area": 900.0, "time_unit": "s", "description": "tiny"}

#: A small valid tracks table: three tracks of five sightings.
TRACK_HEADER = ["id", "t", "x", "y", "label", "yaw"]
TRACK_ROWS = [
    [
        f"trk{k}",
        f"{10.0 * k + 2.0 * i:.1f}",
        f"{k + 0.1 * i:.2f}",
        f"{-k + 0.2 * i:.2f}",
        "person",
        "0.5",
    ]
    for k in range(3)
    for i in range(5)
]

#: A small valid count panel.
PANEL_HEADER = ["t", "count"]
PANEL_ROWS = [[f"{60.0 * i:.1f}", str(c)] for i, c in enumerate([3, 4, 4, 5, 3, 2, 2, 3, 4, 4])]

#: A small valid robot path (t, x, y, yaw) inside the courtyard.
ROBOT_HEADER = ["t", "x", "y", "yaw"]
ROBOT_ROWS = [[f"{2.0 * i:.1f}", f"{-5.0 + 0.5 * i:.2f}", "0.0", "0.0"] for i in range(6)]
