"""The validation layer: strict scalars, known keys, bounded YAML, memory/work limits."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from are_stats import inputs
from are_stats.inputs import (
    InputError,
    LimitError,
    check_file,
    check_keys,
    check_memory,
    check_work,
    get_bool,
    get_float,
    get_int,
    get_list,
    get_seed,
    get_str,
    limits,
    load_yaml,
    parse_size,
    parse_yaml,
)


def _bomb(levels: int, width: int = 10) -> str:
    lines = ["- &l0 [" + ", ".join(["x"] * width) + "]"]
    for i in range(1, levels):
        lines.append(f"- &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def test_yaml_numbers_follow_yaml_1_2():
    doc = parse_yaml("a: 1e-9\nb: 1E5\nc: .5\nd: 3\ne: -2.5e+3\nf: .inf\ng: '1e3'\n", "x.yaml")
    assert doc == {"a": 1e-9, "b": 1e5, "c": 0.5, "d": 3, "e": -2500.0, "f": math.inf, "g": "1e3"}
    assert isinstance(doc["d"], int)
    # PyYAML's own SafeLoader is left as it was (YAML 1.1: 1e-9 is a string)
    assert yaml.safe_load("a: 1e-9") == {"a": "1e-9"}


def test_yaml_duplicate_keys_are_errors_naming_the_line():
    with pytest.raises(InputError, match=r"m\.yaml: line 3: expected each key once.*'area'"):
        parse_yaml("area: 1\nwindow: [0, 1]\narea: 2\n", "m.yaml")
    # merge keys are not duplicates
    assert parse_yaml("base: &b {x: 1}\nd:\n  <<: *b\n  x: 2\n", "m.yaml")["d"] == {"x": 2}


def test_yaml_alias_bomb_is_refused_before_expansion():
    assert len(parse_yaml(_bomb(3), "ok.yaml")[2]) == 10  # 10^3 leaves: fine
    with pytest.raises(InputError, match="alias bomb"):
        parse_yaml(_bomb(9), "bomb.yaml")  # 10^9 leaves once expanded
    with pytest.raises(InputError, match="recursive alias"):
        parse_yaml("a: &a [1, *a]\n", "rec.yaml")


@pytest.mark.parametrize("depth", [65, 5000, 200_000])
def test_yaml_deep_nesting_is_an_error(depth):
    with pytest.raises(InputError, match="nested at most 64 levels"):
        parse_yaml("[" * depth + "]" * depth, "deep.yaml")


@pytest.mark.parametrize("text", ["key: " + "[" * 5000 + "]" * 5000, "[{a: " * 2000 + "}]" * 2000])
def test_yaml_deep_nesting_is_refused_at_the_first_level_past_the_limit(text, monkeypatch):
    """The scanner stops at level 65, not at Python's recursion limit (some 500 levels, read
    with a cost quadratic in the levels: 1.8 s a document) or 1,024 characters ahead."""
    opened = []
    scan = yaml.scanner.Scanner.fetch_flow_collection_start

    def counted(self, token_class):
        opened.append(self.flow_level)
        return scan(self, token_class)

    monkeypatch.setattr(yaml.scanner.Scanner, "fetch_flow_collection_start", counted)
    with pytest.raises(InputError, match="nested at most 64 levels deep, got deeper nesting"):
        parse_yaml(text, "deep.yaml")
    assert len(opened) == inputs.MAX_YAML_DEPTH


def test_load_yaml_file_problems(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.yaml"):
        load_yaml(tmp_path / "missing.yaml", "manifest")
    with pytest.raises(InputError, match="expected a manifest, got a directory"):
        load_yaml(tmp_path, "manifest")
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(InputError, match=r"latin1.yaml: byte 9: expected a manifest in UTF-8"):
        load_yaml(bad, "manifest")
    bom = tmp_path / "bom.yaml"
    bom.write_bytes(b"\xef\xbb\xbfarea: 2.5\n")
    assert load_yaml(bom) == {"area": 2.5}
    broken = tmp_path / "broken.yaml"
    broken.write_text("a: [1, 2\n")
    with pytest.raises(InputError, match=r"broken.yaml: expected a map in valid YAML, got .*line"):
        load_yaml(broken, "map")
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (inputs.MAX_YAML_BYTES + 1))
    with pytest.raises(InputError, match="at most 16.0 MiB"):
        load_yaml(big)


def test_check_file_sizes_a_regular_file_and_names_what_is_not(tmp_path):
    f = tmp_path / "x.bt"
    f.write_bytes(b"12345")
    assert check_file(f, "an OctoMap .bt file") == 5
    with pytest.raises(FileNotFoundError, match=r"none.bt: no such file: expected an OctoMap"):
        check_file(tmp_path / "none.bt", "an OctoMap .bt file")
    with pytest.raises(InputError, match="expected an OctoMap .bt file, got a directory"):
        check_file(tmp_path, "an OctoMap .bt file")
    fifo = tmp_path / "fifo.bt"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="fifo.bt: expected an OctoMap .bt file in a regular file"):
        check_file(fifo, "an OctoMap .bt file")


def test_check_keys_lists_the_known_keys():
    assert check_keys({"a": 1}, "c.yaml", "robot", ["a", "b"]) == {"a": 1}
    with pytest.raises(InputError, match=r"c.yaml: robot.zz: expected one of the known keys a, b"):
        check_keys({"a": 1, "zz": 2}, "c.yaml", "robot", ["a", "b"])
    with pytest.raises(InputError, match=r"c.yaml: robot.b: expected this key to be present"):
        check_keys({"a": 1}, "c.yaml", "robot", ["a", "b"], required=["b"])
    with pytest.raises(InputError, match=r"c.yaml: robot: expected a mapping of a, b, got a list"):
        check_keys([1, 2], "c.yaml", "robot", ["a", "b"])


@pytest.mark.parametrize(
    "value, got",
    [
        (True, "True (a bool)"),
        (np.bool_(False), "False (a bool)"),
        ("1.5", "'1.5' (a string)"),
        (None, "nothing (null)"),
        ([1], "a list [1]"),
        ({"a": 1}, "a mapping with keys 'a'"),
        (math.nan, "nan"),
        (math.inf, "inf"),
        (10**400, "1000"),
    ],
)
def test_get_float_rejects_non_numbers(value, got):
    with pytest.raises(InputError, match=r"f: k: expected a finite number, got " + got[:4]):
        get_float(value, "f", "k")


def test_get_float_bounds():
    assert get_float(np.float32(2.0), "f", "k", lo=0, lo_open=True) == 2.0
    assert get_float(math.inf, "f", "k", finite=False) == math.inf
    with pytest.raises(InputError, match="expected a finite number > 0 and <= 1, got 0"):
        get_float(0, "f", "k", lo=0, lo_open=True, hi=1)
    with pytest.raises(InputError, match="< 1"):
        get_float(1.0, "f", "k", hi=1, hi_open=True)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.one_of(st.integers(), st.floats(allow_nan=True, allow_infinity=True), st.booleans()))
def test_get_int_accepts_exactly_int64_integers(value):
    ok = (
        not isinstance(value, bool)
        and (isinstance(value, int) or (math.isfinite(value) and value == math.floor(value)))
        and -(2**63) <= value < 2**63
    )
    if ok:
        assert get_int(value, "f", "k") == int(value)
    else:
        with pytest.raises(InputError, match="f: k: expected an integer"):
            get_int(value, "f", "k")


def test_small_getters():
    assert get_bool(True, "f", "k") is True
    with pytest.raises(InputError, match="expected true or false, got 1"):
        get_bool(1, "f", "k")
    assert get_str("a", "f", "k", choices=["a", "b"]) == "a"
    with pytest.raises(InputError, match="expected one of 'a', 'b', got 'c'"):
        get_str("c", "f", "k", choices=["a", "b"])
    assert get_list((1, 2), "f", "k", min_len=2, max_len=2) == [1, 2]
    with pytest.raises(InputError, match="expected a list of 2 values, got 3 values"):
        get_list([1, 2, 3], "f", "k", min_len=2, max_len=2)
    assert get_seed(2**32 - 1) == 2**32 - 1
    with pytest.raises(InputError, match=r"--seed: expected an integer >= 0 and <= 4294967295"):
        get_seed(2**70)


def test_sizes_and_limits(monkeypatch):
    assert parse_size("16G") == 16 * 2**30
    assert parse_size("512MiB") == 512 * 2**20
    assert parse_size("1e9") == 10**9
    for bad in ["", "-1G", "G", "1X", True, "nan"]:
        with pytest.raises(InputError):
            parse_size(bad, "--max-memory")
    monkeypatch.delenv("ARE_STATS_MAX_MEMORY", raising=False)
    assert inputs.memory_limit() == inputs.DEFAULT_MEMORY
    check_memory(inputs.DEFAULT_MEMORY, "an array")
    with pytest.raises(LimitError, match=r"a.nc: expected the marks .*4.0 GiB.*got about 7.0 PiB"):
        check_memory(7 * 2**50, "the marks", "a.nc")
    with pytest.raises(LimitError):
        check_memory(math.nan, "the marks")
    monkeypatch.setenv("ARE_STATS_MAX_MEMORY", "8P")
    check_memory(7 * 2**50, "the marks", "a.nc")
    with limits(memory="1K", work=10):
        with pytest.raises(LimitError, match="1.0 KiB"):
            check_memory(2048, "x")
        with pytest.raises(LimitError, match="work limit of 10 steps"):
            check_work(11, "x")
    assert inputs.memory_limit() == 8 * 2**50


def test_cli_turns_errors_into_one_line(monkeypatch, tmp_path):
    from are_stats import cli

    runner = CliRunner()
    res = runner.invoke(cli.app, ["report", str(tmp_path / "none.nc")])
    assert res.exit_code == 2 and "Traceback" not in res.output
    res = runner.invoke(cli.app, ["--max-memory", "lots", "version"])
    assert res.exit_code == 2 and "--max-memory: expected a size" in res.output

    def boom(*args, **kwargs):
        raise KeyError("a bug")

    monkeypatch.setattr("are_stats._cli_jobs.run_report", boom)
    monkeypatch.delenv("ARE_STATS_DEBUG", raising=False)
    res = runner.invoke(cli.app, ["report", str(tmp_path / "none.nc")])
    assert res.exit_code == 1
    assert "internal error in are-stats (KeyError" in res.output and "Traceback" not in res.output


def test_yaml_control_characters_and_fifos_are_errors(tmp_path):
    import os

    with pytest.raises(InputError, match=r"x.yaml: expected a map in valid YAML, got .*#x0000"):
        parse_yaml("a: \x00b\n", "x.yaml", "map")
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="pipe.yaml: expected a map in a regular file"):
        load_yaml(fifo, "map")  # would block forever if opened


def test_a_text_parsed_again_is_not_parsed_and_its_copy_is_the_callers(monkeypatch):
    """parse_yaml keeps the documents of texts it parsed: the same text again gives an equal
    document without running the loader, as a deep copy (a caller changing it changes no
    later caller's, anchors still shared within it); a bad text is refused every time."""
    text = "a: &x [1, 2.5e-3, {b: yes}]\nc: *x\nd: 2026-11-29\n"
    first = inputs.parse_yaml(text, "one.yaml")
    want = yaml.safe_load(text) | {"a": [1, 0.0025, {"b": True}], "c": [1, 0.0025, {"b": True}]}
    assert first == want
    first["a"].append("changed")  # the caller's own object

    def no_loader(*args, **kwargs):
        raise AssertionError("parsed again")

    monkeypatch.setattr(inputs, "_Loader", no_loader)
    second = inputs.parse_yaml(text, "two.yaml", "catalogue YAML")
    assert second == want and second is not first
    assert second["a"] is second["c"]  # the alias, as the loader gives it
    monkeypatch.undo()
    for _ in range(2):
        with pytest.raises(inputs.InputError, match="bad.yaml.*each key once per mapping"):
            inputs.parse_yaml("k: 1\nk: 2\n", "bad.yaml")
