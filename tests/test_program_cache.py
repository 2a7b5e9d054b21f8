"""Traced programs kept on disk (``are_stats._program_cache``): keys, reuse, corrupt files."""

from __future__ import annotations

import dataclasses
import functools
import os
import subprocess
import sys
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from are_stats import _program_cache as pc
from are_stats.traffic import lifecycle_model


class _Spec(NamedTuple):
    a: int
    b: float


@dataclasses.dataclass(frozen=True)
class _Priors:
    shape: float
    names: tuple


def test_stable_repr_names_functions_and_values_exactly():
    assert pc.stable_repr(lifecycle_model) == "are_stats.traffic._lifecycle.lifecycle_model"
    part = functools.partial(lifecycle_model, n_components=2)
    assert pc.stable_repr(part) == (
        "partial(are_stats.traffic._lifecycle.lifecycle_model, (,), [('n_components', 2,)])"
    )
    # floats round-trip exactly: 0.1 + 0.2 is not 0.3 in the key either
    assert pc.stable_repr(0.1 + 0.2) != pc.stable_repr(0.3)
    assert pc.stable_repr({"x": (1, "a", None, True)}) == "{'x': (1, 'a', None, True,)}"
    assert pc.stable_repr(np.dtype("float64")) == "dtype('float64')"
    tree = jax.tree.structure({"a": 1, "b": (2, 3)})
    assert pc.stable_repr(tree) == str(tree)


def test_stable_repr_refuses_what_has_no_stable_text():
    def local(x):
        return x

    assert pc.stable_repr(lambda x: x) is None
    assert pc.stable_repr(local) is None
    assert pc.stable_repr((1, object())) is None
    assert pc.stable_repr(np.sum) is None  # not a module whose version or source is keyed
    # classes defined outside are_stats (here: the test module) have no stable name either
    assert pc.stable_repr(_Spec(1, 2.0)) is None
    assert pc.stable_repr(_Priors(1.0, ("a",))) is None


def test_source_hash_is_a_sha256_of_the_package():
    h = pc.source_hash()
    assert len(h) == 64 and int(h, 16) >= 0
    assert pc.source_hash() == h  # once a process


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", str(tmp_path / "programs"))
    return tmp_path / "programs"


class _Counter:
    """A jitted function that counts its traces (a Python side effect at trace time)."""

    def __init__(self) -> None:
        self.traces = 0

        def f(x, pair):
            self.traces += 1
            return {"y": jnp.sin(x) * pair[0] + pair[1], "n": jnp.sum(x > 0)}

        self.fn = jax.jit(f)


def _args(n: int = 5) -> tuple:
    x = np.linspace(-1.0, 2.0, n)
    return x, (np.asarray(2.0), np.arange(n, dtype=float))


def _traces(args: tuple, key, options: dict | None = None) -> int:
    """Traces of a new function object (as in a new process) compiled for ``args``."""
    c = _Counter()
    _check(pc.compile_program(c.fn, args, key, options)(*args), args)
    return c.traces


def _check(out: dict, args: tuple) -> None:
    x, (a, b) = args
    np.testing.assert_array_equal(np.asarray(out["y"]), np.asarray(jnp.sin(x) * a + b))
    assert int(out["n"]) == int(np.sum(x > 0))


def test_a_kept_program_is_read_not_traced(folder):
    args = _args()
    first = _Counter()
    out1 = pc.compile_program(first.fn, args, ("test", 1))(*args)
    _check(out1, args)
    assert first.traces == 1
    files = list(folder.glob("*" + pc.SUFFIX))
    assert len(files) == 1 and not list(folder.glob("*.tmp"))
    second = _Counter()  # a new function object, as in a new process
    out2 = pc.compile_program(second.fn, args, ("test", 1))(*args)
    assert second.traces == 0  # read from disk
    for k in out1:
        np.testing.assert_array_equal(np.asarray(out1[k]), np.asarray(out2[k]))
    # other shapes, another key, or other compiler options: traced again, another file
    assert _traces(_args(6), ("test", 1)) == 1
    assert _traces(args, ("test", 2)) == 1
    assert _traces(args, ("test", 1), {"xla_backend_optimization_level": 0}) == 1
    assert _traces(args, ("test", 1)) == 0
    assert len(list(folder.glob("*" + pc.SUFFIX))) == 4


def test_the_source_hash_is_part_of_the_key(folder, monkeypatch):
    args = _args()
    pc.compile_program(_Counter().fn, args, ("test", 1))
    monkeypatch.setattr(pc, "source_hash", lambda: "0" * 64)  # an edited package
    assert _traces(args, ("test", 1)) == 1
    assert len(list(folder.glob("*" + pc.SUFFIX))) == 2


@pytest.mark.parametrize("content", [b"", b"not a program", b"\x00" * 64])
def test_a_corrupt_file_is_traced_again_and_replaced(folder, content):
    args = _args()
    pc.compile_program(_Counter().fn, args, ("test", 1))
    (path,) = folder.glob("*" + pc.SUFFIX)
    good = path.read_bytes()
    path.write_bytes(content if content else good[: len(good) // 2])  # truncated too
    assert _traces(args, ("test", 1)) == 1
    assert path.read_bytes() != content  # rewritten whole: read by the next call
    assert _traces(args, ("test", 1)) == 0


def test_a_file_for_other_shapes_is_not_used(folder):
    """A stale file under the name (another program's arguments) is traced over."""
    args5, args6 = _args(5), _args(6)
    pc.compile_program(_Counter().fn, args6, ("test", 1))
    (other,) = folder.glob("*" + pc.SUFFIX)
    name = pc._file_name(pc.stable_repr(("test", 1)), args5, None)
    (folder / name).write_bytes(other.read_bytes())
    assert _traces(args5, ("test", 1)) == 1
    assert _traces(args5, ("test", 1)) == 0


def test_an_unwritable_folder_does_not_fail(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the folder should be")
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", str(blocker / "programs"))
    args = _args()
    _check(pc.compile_program(_Counter().fn, args, ("test", 1))(*args), args)


def test_cache_off_or_unstable_key_keeps_nothing(folder, monkeypatch):
    args = _args()
    for key in [("test", lambda: 0), None, ("test", lambda: 0), None]:
        assert _traces(args, key) == 1
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")
    assert pc.program_folder() is None
    assert _traces(args, ("test", 1)) == 1
    assert _traces(args, ("test", 1)) == 1
    assert not folder.exists()


def test_configure_jax_sets_the_folder_and_turns_it_off(tmp_path):
    code = (
        "import are_stats, os, sys\n"
        "if sys.argv[1:]: are_stats.configure_jax(cache=False)  # as are-stats --no-cache\n"
        "print(os.environ['ARE_STATS_PROGRAM_CACHE'])"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "ARE_STATS_"))}
    env["XDG_CACHE_HOME"] = str(tmp_path)

    def run(extra: dict, *argv: str) -> str:
        out = subprocess.run([sys.executable, "-c", code, *argv], env={**env, **extra},
                             capture_output=True, text=True, check=True)  # fmt: skip
        return out.stdout.strip()

    assert run({}) == str(tmp_path / "are_stats" / "programs")
    assert run({"ARE_STATS_NO_CACHE": "1"}) == ""
    assert run({}, "off") == ""


def test_prune_deletes_the_least_recently_used_files_past_the_cap(tmp_path, monkeypatch):
    """A folder over its cap loses its least recently used files until it holds 80% of
    the cap; a folder under the cap, young temporary files and a cap turned off keep all."""
    big, small = tmp_path / "jax", tmp_path / "programs"
    big.mkdir()
    small.mkdir()
    now = 1_700_000_000.0
    for i in range(10):  # 10 files of 100 bytes, used at times now - 10 + i
        f = big / f"entry{i}-cache"
        f.write_bytes(b"x" * 100)
        os.utime(f, (now - 10 + i, now - 10 + i))
    writing = big / ".entry.tmp"  # being written: neither counted nor deleted
    writing.write_bytes(b"y" * 500)
    (small / "p.jaxexport").write_bytes(b"z" * 100)
    assert pc.prune_cache(900, [big, small, tmp_path / "missing"]) == 300
    left = sorted(p.name for p in big.iterdir())
    assert left == [".entry.tmp"] + [f"entry{i}-cache" for i in range(3, 10)]  # 700 <= 720
    assert (small / "p.jaxexport").exists()
    monkeypatch.setenv("ARE_STATS_CACHE_MAX_MB", "0")
    assert pc.cache_limit() is None and pc.prune_cache(None, [big]) == 0
    monkeypatch.setenv("ARE_STATS_CACHE_MAX_MB", "2.5")
    assert pc.cache_limit() == int(2.5 * 2**20)
    monkeypatch.delenv("ARE_STATS_CACHE_MAX_MB")
    assert pc.cache_limit() == pc.CACHE_MAX_MB * 2**20


def test_reading_a_kept_program_marks_it_used(folder):
    """The traced programs are touched when read, so pruning keeps the ones in use."""
    f = jax.jit(lambda x: x * 2.0)
    args = (np.ones(3),)
    pc.compile_program(f, args, ("double",))
    (path,) = folder.glob("*.jaxexport")
    os.utime(path, (1.0, 1.0))
    pc.compile_program(f, args, ("double",))
    assert path.stat().st_mtime > 1.0


@pytest.mark.parametrize("kept", [True, False])
def test_an_xla_option_this_jaxlib_lacks_is_left_out(folder, monkeypatch, kept):
    """An XLA option this jaxlib does not know (a later XLA may drop one that the
    programs ask for, such as ``xla_cpu_use_fusion_emitters``) is left out, not an error,
    and the program's results are the function's; an error that names no option is still
    raised."""
    monkeypatch.setattr(pc, "_UNKNOWN_OPTIONS", set())
    if not kept:
        monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")
    bogus = "xla_no_such_option_for_this_test"
    args = _args()
    options = {"xla_cpu_use_fusion_emitters": False, bogus: True}
    assert _traces(args, ("test", "options"), options) == 1  # _check: the right results
    assert pc._UNKNOWN_OPTIONS == {bogus}
    assert _traces(args, ("test", "options", 2), options) == 1  # no failed try now
    with pytest.raises(Exception, match="INVALID_ARGUMENT"):  # a wrong value: XLA's error
        _traces(args, ("test", "options", 3), {"xla_backend_optimization_level": "high"})


def test_a_record_is_kept_per_key_and_shapes_and_not_when_off(folder, monkeypatch):
    args = _args()
    assert pc.load_record(("test", 1), args) is None
    pc.store_record(("test", 1), args, [["a", "exp", [2]]])
    assert pc.load_record(("test", 1), args) == [["a", "exp", [2]]]
    assert pc.load_record(("test", 2), args) is None  # another key
    assert pc.load_record(("test", 1), _args(6)) is None  # other shapes
    pc.store_record(("test", lambda: 0), args, 1)  # no stable text: not kept
    assert len(list(folder.glob("*" + pc.RECORD_SUFFIX))) == 1
    monkeypatch.setenv("ARE_STATS_PROGRAM_CACHE", "")
    assert pc.load_record(("test", 1), args) is None
    pc.store_record(("test", 3), args, 1)
    assert len(list(folder.glob("*" + pc.RECORD_SUFFIX))) == 1
