"""Fuzz every ``are-stats`` command with malformed files and malformed options.

Contract: each case exits 0, or exits 2 with a message on stderr naming the input (the
file or the option); never a traceback (an uncaught exception is exit 1 under
``CliRunner``), never past its time or memory bound. Most cases run in-process through
``typer.testing.CliRunner`` (fast); a handful run ``are-stats`` in a fresh process.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import strategies as st
from typer.testing import CliRunner

from tests.fuzz.conftest import FUZZ_MEMORY_LIMIT
from tests.fuzz.strategies import (
    CASE_WALL_SECONDS,
    LOG_HEADER,
    LOG_ROWS,
    MANIFEST,
    MODELS,
    ROBOT_HEADER,
    ROBOT_ROWS,
    _byte_edit,
    _csv_text,
    _dump,
    alias_bomb,
    bounded,
    csv_case,
    file_cases,
    fit_case,
    fuzz_tiers,
    load_base_yaml,
    write_case,
    write_fit_case,
    yaml_case,
)
from tests.helpers import PAPER_MODELS, TINY_SWEEP

pytestmark = pytest.mark.fuzz

CAMERA = str(MODELS / "cameras" / "front_camera.yaml")
MAP = str(MODELS / "courtyard.yaml")


def invoke(args: list[str], names: list[str], seconds: float = 60.0) -> int:
    """Run ``are-stats ARGS`` in-process and check the contract; returns the exit code.

    ``seconds`` bounds the CPU time of the run (all threads); the wall clock, which grows
    when other processes share the cores, only bounds hangs, at six times as long (at least
    :data:`CASE_WALL_SECONDS`), as :func:`expect_clean` does.
    """
    from are_stats.cli import app

    runner = CliRunner()
    with bounded(seconds=max(CASE_WALL_SECONDS, 6 * seconds), cpu_seconds=seconds):
        res = runner.invoke(app, args, catch_exceptions=True)
    shown = (
        f"are-stats {' '.join(args)}\nstdout: {res.stdout[-2000:]}\nstderr: {res.stderr[-2000:]}"
    )
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise AssertionError(f"uncaught {type(res.exception).__name__}: {res.exception}\n{shown}")
    assert res.exit_code in (0, 2), f"exit {res.exit_code}\n{shown}"
    assert "Traceback" not in res.output, shown
    if res.exit_code == 2:
        assert any(n in res.stderr for n in names), f"stderr names none of {names}\n{shown}"
    return res.exit_code


@pytest.fixture(scope="session")
def files(tiny_log: Path, tiny_fit: Path, tiny_scenarios: Path, fuzz_root: Path) -> dict:
    d = fuzz_root / "cli"
    d.mkdir()
    robot = d / "robot.csv"
    robot.write_text(_csv_text(ROBOT_HEADER, ROBOT_ROWS))
    garbage = d / "garbage.nc"
    garbage.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 40)
    (d / "folder").mkdir()
    return {
        "log": str(tiny_log),
        "fit": str(tiny_fit),
        "scen": str(tiny_scenarios),
        "robot": str(robot),
        "garbage": str(garbage),
        "dir": str(d / "folder"),
        "camera": CAMERA,
        "map": MAP,
    }


def _fill(args: list[str], files: dict, out: Path) -> list[str]:
    return [a.format(out=out, **files) for a in args]


# (args, names that the error must mention); {out} is a fresh folder per case
# fmt: off
BAD_OPTIONS = [
    # fit
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--seed", str(2**70)], ["--seed"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--seed", "-1"], ["--seed"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "bogus"], ["--method"]),
    (["fit", "{log}", "--out", "{out}/f.txt", "--method", "em"], ["--out"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--window", "10", "5"], ["window"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--window", "nan", "1"], ["window"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--window", "0", "inf"], ["window"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--area", "-1"], ["area"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--area", "nan"], ["area"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--area", "inf"], ["area"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--components", "0"],
     ["--components"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--components", "-3"],
     ["--components"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--components", "100000"],
     ["--components"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--samples", "0"], ["--samples"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--samples", str(10**12)], ["--samples"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--warmup", "-1"], ["--warmup"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--chains", "0"], ["--chains"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--chains", "100000"], ["--chains"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--manifest", "{dir}"],
     ["folder"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--counts", "{dir}"], ["folder"]),
    (["fit", "{log}", "--out", "{out}/f.nc", "--method", "em", "--counts", "{out}/none.csv"],
     ["none.csv"]),
    (["fit", "{dir}", "--out", "{out}/f.nc", "--method", "em"], ["folder"]),
    (["fit", "{garbage}", "--out", "{out}/f.nc", "--method", "em"], ["garbage.nc"]),
    (["fit", "{log}", "--out", "{dir}", "--method", "em"], ["--out", "folder"]),
    # report
    (["report", "{garbage}", "--out", "{out}/r"], ["garbage.nc"]),
    (["report", "{dir}", "--out", "{out}/r"], ["folder"]),
    (["report", "{fit}", "--out", "{out}/r", "--replicates", "0"], ["--replicates"]),
    (["report", "{fit}", "--out", "{out}/r", "--replicates", "-1"], ["--replicates"]),
    (["report", "{fit}", "--out", "{out}/r", "--replicates", str(10**9)], ["--replicates"]),
    (["report", "{fit}", "--out", "{out}/r", "--seed", str(2**70)], ["--seed"]),
    # generate
    (["generate", "{fit}", "--scenarios", "0", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g"], ["--scenarios"]),
    (["generate", "{fit}", "--scenarios", "-1", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g"], ["--scenarios"]),
    (["generate", "{fit}", "--scenarios", str(10**9), "--horizon", "60", "--seed", "1",
      "--out", "{out}/g"], ["--scenarios"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "1e12", "--seed", "1", "--out",
      "{out}/g"], ["--horizon"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "nan", "--seed", "1", "--out",
      "{out}/g"], ["--horizon"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "-5", "--seed", "1", "--out",
      "{out}/g"], ["--horizon"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "inf", "--seed", "1", "--out",
      "{out}/g"], ["--horizon"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", str(2**70),
      "--out", "{out}/g"], ["--seed"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "-1", "--out",
      "{out}/g"], ["--seed"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--area", "nan"], ["--area"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--area", "1e300"], ["--area", "--scenarios", "--horizon"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--map", "{map}", "--behaviours", "--behaviour-cell", "0"],
     ["--behaviour-cell"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--map", "{map}", "--behaviours", "--behaviour-cell", "nan"],
     ["--behaviour-cell"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--map", "{map}", "--behaviours", "--behaviour-dt", "0"], ["--behaviour-dt"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--map", "{map}", "--behaviours", "--behaviour-dt", "-2"], ["--behaviour-dt"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--behaviours"], ["--behaviours", "--map"]),
    (["generate", "{fit}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g", "--map", "{garbage}"], ["garbage.nc"]),
    (["generate", "{garbage}", "--scenarios", "2", "--horizon", "60", "--seed", "1", "--out",
      "{out}/g"], ["garbage.nc"]),
    # demo
    (["demo", "--out", "{garbage}", "--quick"], ["garbage.nc"]),
    # perceive
    (["perceive", "{dir}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet"], ["folder"]),
    (["perceive", "{scen}", "--camera", "{garbage}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet"], ["garbage.nc"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{garbage}", "--out",
      "{out}/p.parquet"], ["garbage.nc"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{dir}", "--out",
      "{out}/p.parquet"], ["folder"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet", "--d-max", "nan"], ["--d-max"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet", "--d-max", "-1"], ["--d-max"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet", "--tau", "nan"], ["--tau"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet", "--camera-height", "inf"], ["--camera-height"]),
    (["perceive", "{scen}", "--camera", "{camera}", "--robot-path", "{robot}", "--out",
      "{out}/p.parquet", "--mesh", "{garbage}"], ["garbage.nc"]),
    # show
    (["show", "{map}", "--out", "{out}/m.png", "--artefacts", "100000"], ["--artefacts"]),
    (["show", "{map}", "--out", "{out}/m.png", "--artefacts", "-1"], ["--artefacts"]),
    (["show", "{map}", "--out", "{out}/m.png", "--inflate", "nan"], ["--inflate"]),
    (["show", "{map}", "--out", "{out}/m.png", "--inflate", "-1"], ["--inflate"]),
    (["show", "{map}", "--out", "{out}/m.png", "--inflate", "1e9"], ["--inflate"]),
    (["show", "{map}", "--out", "{out}/m.png", "--artefacts", "3", "--seed", str(2**70)],
     ["--seed"]),
    (["show", "{map}", "--out", "{out}/m.png", "--artefacts", "3", "--seed", "-1"], ["--seed"]),
    (["show", "{garbage}", "--out", "{out}/m.png"], ["garbage.nc"]),
    (["show", "{dir}", "--out", "{out}/m.png"], ["folder"]),
    (["show", "nosuchmap", "--out", "{out}/m.png"], ["nosuchmap"]),
    (["show", "{map}", "--out", "{dir}"], ["--out", "folder"]),
    # experiment
    (["experiment", "{garbage}", "--out", "{out}/e"], ["garbage.nc"]),
    (["experiment", "{dir}", "--out", "{out}/e"], ["folder"]),
    (["experiment", "{out}/none.yaml", "--out", "{out}/e"], ["none.yaml"]),
    (["experiment", "{tiny_sweep}", "--out", "{out}/e", "--workers", "0"], ["--workers"]),
    (["experiment", "{tiny_sweep}", "--out", "{out}/e", "--workers", "-1"], ["--workers"]),
    (["experiment", "{tiny_sweep}", "--out", "{out}/e", "--workers", "100000"], ["--workers"]),
    (["experiment", "{tiny_sweep}", "--out", "{out}/e", "--scheduler", "not-an-address"],
     ["--scheduler"]),
    # plot
    (["plot", "{dir}", "--out", "{out}/pl"], ["folder"]),
    (["plot", "{out}/missing", "--out", "{out}/pl"], ["missing"]),
    (["plot", "{garbage}", "--out", "{out}/pl"], ["garbage.nc"]),
    # version, root options
    (["version", "extra"], ["extra"]),
    (["--max-memory", "abc", "version"], ["--max-memory"]),
    (["--max-memory", "0", "version"], ["--max-memory"]),
    (["--max-memory", "-5G", "version"], ["--max-memory"]),
    (["--max-work", "nan", "version"], ["--max-work"]),
]
# fmt: on


@pytest.fixture(scope="session")
def tiny_sweep(fuzz_root: Path) -> str:
    path = fuzz_root / "tiny_sweep.yaml"
    path.write_text(_dump(TINY_SWEEP))
    return str(path)


@pytest.mark.parametrize(
    ("args", "names"), BAD_OPTIONS, ids=[" ".join(a[:1] + a[-2:]) for a, _ in BAD_OPTIONS]
)
def test_bad_option(args, names, files, tiny_sweep, case_dir) -> None:
    """Each malformed option or file: exit 2 naming it, before any long work (20 s)."""
    out = case_dir()
    full = _fill(args, {**files, "tiny_sweep": tiny_sweep}, out)
    invoke(full, names, seconds=20.0)


def test_version() -> None:
    assert invoke(["version"], []) == 0


# ----------------------------------------------------------------------------- files


def _em_fit(log, out, *extra: str) -> list[str]:
    """The arguments of a quick ``fit`` (em, the paper's models, no figures) of ``log``."""
    return ["fit", str(log), *extra, "--out", str(out), "--method", "em", "--no-figures",
            *PAPER_MODELS]  # fmt: skip


@fuzz_tiers(10, case=file_cases(csv_case(LOG_HEADER, LOG_ROWS)))
def test_fit_damaged_log(case, case_dir) -> None:
    d = case_dir()
    (d / "log.yaml").write_text(_dump(MANIFEST))
    path = write_case(d / "log.csv", case)
    invoke(_em_fit(path, d / "f.nc"), [path.name], seconds=60.0)


@fuzz_tiers(25, case=file_cases(yaml_case(MANIFEST)))
def test_fit_damaged_manifest(case, case_dir, tiny_log) -> None:
    d = case_dir()
    path = write_case(d / "manifest.yaml", case)
    invoke(_em_fit(tiny_log, d / "f.nc", "--manifest", str(path)), [path.name], seconds=60.0)


@fuzz_tiers(8, case=fit_case())
def test_report_damaged_fit(case, case_dir, tiny_fit) -> None:
    d = case_dir()
    path = d / "fit.nc"
    write_fit_case(tiny_fit, path, case)
    invoke(["report", str(path), "--out", str(d / "r"), "--replicates", "5"], [path.name])


@fuzz_tiers(25, case=file_cases(yaml_case(load_base_yaml(MODELS / "courtyard.yaml"))))
def test_show_damaged_map(case, case_dir) -> None:
    d = case_dir()
    shutil.copy(MODELS / "courtyard.pgm", d / "courtyard.pgm")
    path = write_case(d / "map.yaml", case)
    invoke(["show", str(path), "--out", str(d / "m.png"), "--artefacts", "2"], [path.name])


@fuzz_tiers(25, case=file_cases(yaml_case(load_base_yaml(MODELS / "courtyard.yaml"))))
def test_generate_damaged_map(case, case_dir, tiny_fit) -> None:
    d = case_dir()
    shutil.copy(MODELS / "courtyard.pgm", d / "courtyard.pgm")
    path = write_case(d / "map.yaml", case)
    args = [
        "generate",
        str(tiny_fit),
        "--scenarios",
        "2",
        "--horizon",
        "60",
        "--seed",
        "3",
        "--out",
        str(d / "g"),
        "--map",
        str(path),
    ]
    invoke(args, [path.name])


@fuzz_tiers(
    15, case=file_cases(yaml_case(load_base_yaml(MODELS / "cameras" / "front_camera.yaml")))
)
def test_perceive_damaged_camera(case, case_dir, tiny_scenarios, files) -> None:
    d = case_dir()
    path = write_case(d / "camera.yaml", case)
    args = [
        "perceive",
        str(tiny_scenarios),
        "--camera",
        str(path),
        "--robot-path",
        files["robot"],
        "--out",
        str(d / "p.parquet"),
    ]
    invoke(args, [path.name], seconds=120.0)


@fuzz_tiers(10, case=file_cases(yaml_case(TINY_SWEEP)))
def test_experiment_damaged_config(case, case_dir) -> None:
    d = case_dir()
    path = write_case(d / "sweep.yaml", case)
    invoke(["experiment", str(path), "--out", str(d / "e")], [path.name], seconds=120.0)


@pytest.fixture(scope="session")
def tiny_results(fuzz_root: Path, tiny_sweep: str) -> Path:
    """The results folder of the tiny sweep (``are-stats experiment``), run on a Dask cluster
    of this process (``--scheduler``, as tests/export/test_augment.py's experiment does): the
    default's worker process imports the package and loads every program again, some 10 s
    of the default tier for a folder these tests only damage and plot.
    tests/experiments/test_sweep.py::test_cli_experiment_and_plot runs the command with its
    own worker process."""
    from distributed import LocalCluster

    out = fuzz_root / "results"
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        args = [
            "experiment",
            tiny_sweep,
            "--out",
            str(out),
            "--scheduler",
            cluster.scheduler_address,
        ]
        assert invoke(args, [], seconds=300.0) == 0
    return out


@st.composite
def _results_case(draw: st.DrawFn, folder: Path) -> tuple[str, bytes | str]:
    """One file of a results folder, damaged: its table's columns or its bytes."""
    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    name = draw(st.sampled_from(files))
    data = (folder / name).read_bytes()
    if name.endswith(".yaml"):
        return name, draw(file_cases(yaml_case(yaml.safe_load(data))))
    df = pd.read_parquet(folder / name)
    col = draw(st.sampled_from(list(df.columns)))
    edit = draw(st.sampled_from(["drop", "nan", "bool", "huge", "str", "bytes", "empty"]))
    if edit == "bytes":
        return name, draw(file_cases(_byte_edit(data)))
    if edit == "drop":
        df = df.drop(columns=[col])
    elif edit == "empty":
        df = df.iloc[:0]
    else:
        df[col] = {"nan": np.nan, "bool": True, "huge": 2**62, "str": "x"}[edit]
    buf = io.BytesIO()
    df.to_parquet(buf, index=False)
    return name, buf.getvalue()


@fuzz_tiers(15, data=st.data())
def test_plot_damaged_results(data, case_dir, tiny_results) -> None:
    d = case_dir() / "results"
    shutil.copytree(tiny_results, d)
    name, case = data.draw(_results_case(tiny_results))
    (d / name).unlink()
    path = write_case(d / name, case)
    invoke(["plot", str(d), "--out", str(d.parent / "png")], [path.name, d.name])


# ----------------------------------------------------------------------------- fresh processes


def _are_stats() -> list[str]:
    exe = Path(sys.executable).with_name("are-stats")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "are_stats.cli"]


@pytest.mark.parametrize(
    ("args", "name"),
    [
        (
            [
                "generate",
                "{fit}",
                "--scenarios",
                "2",
                "--horizon",
                "60",
                "--seed",
                str(2**70),
                "--out",
                "{out}/g",
            ],
            "--seed",
        ),
        (["fit", "{bomb}", "--out", "{out}/f.nc", "--method", "em"], "log.yaml"),
        (["experiment", "{bomb_yaml}", "--out", "{out}/e"], "bomb.yaml"),
        (["show", "courtyard", "--out", "{out}/m.png", "--artefacts", "100000"], "--artefacts"),
    ],
    ids=["generate-seed", "fit-bomb-manifest", "experiment-bomb", "show-artefacts"],
)
def test_fresh_process(args, name, files, case_dir) -> None:
    """A real ``are-stats`` process: exit 2, the input named, no traceback."""
    d = case_dir()
    (d / "log.csv").write_text(_csv_text(LOG_HEADER, LOG_ROWS))
    (d / "log.yaml").write_text(alias_bomb())
    (d / "bomb.yaml").write_text(alias_bomb() + yaml.safe_dump(TINY_SWEEP))
    full = [a.format(out=d, bomb=d / "log.csv", bomb_yaml=d / "bomb.yaml", **files) for a in args]
    env = {**os.environ, "COLUMNS": "200", "ARE_STATS_MAX_MEMORY": FUZZ_MEMORY_LIMIT}
    try:
        res = subprocess.run(
            [*_are_stats(), *full], capture_output=True, text=True, timeout=60, env=env, cwd=d
        )
    except subprocess.TimeoutExpired:
        raise AssertionError(f"are-stats {' '.join(full)}: still running after 60 s") from None
    shown = f"{full}\nstdout: {res.stdout[-2000:]}\nstderr: {res.stderr[-3000:]}"
    assert res.returncode == 2, shown
    assert "Traceback" not in res.stderr + res.stdout, shown
    assert name in res.stderr, shown
