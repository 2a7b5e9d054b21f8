"""The are-stats console script."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from importlib.metadata import entry_points
from pathlib import Path

import pytest
from typer.testing import CliRunner

import are_stats
from are_stats.cli import app

runner = CliRunner()


def test_version():
    res = runner.invoke(app, ["version"])
    assert res.exit_code == 0
    assert res.stdout.strip() == are_stats.__version__


def test_version_option():
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.stdout.strip() == are_stats.__version__


@pytest.mark.parametrize(
    "command, names",
    [
        ("fit", ("--behaviour-features", "--stationary-start", "--no-stationary-start")),
        ("generate", ("--positions", "--model", "--behaviour-cell")),
        ("augment", ("--positions", "--model", "--camera-info-topic")),
    ],
)
def test_help_at_80_columns_keeps_every_option_name_whole(command, names):
    # rich's boxed help cut long names at 80 columns (--behaviour-fea…)
    res = runner.invoke(app, [command, "--help"], terminal_width=80, env={"COLUMNS": "80"})
    assert res.exit_code == 0
    assert "…" not in res.stdout
    for name in names:
        assert name in res.stdout
    assert max(len(line) for line in res.stdout.splitlines()) <= 80


def test_fit_compare_option_is_checked_before_any_work(tmp_path):
    res = runner.invoke(
        app, ["fit", "courtyard_traffic", "--out", str(tmp_path / "f.nc"), "--compare", "bogus"]
    )
    assert res.exit_code == 2
    assert "compare" in res.output and "laplace" in res.output
    assert not (tmp_path / "f.nc").exists()


def test_help_lists_commands():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    assert "version" in res.stdout


def _console_script() -> str:
    """The installed ``are-stats`` script of this environment."""
    script = shutil.which("are-stats", path=str(Path(sys.executable).parent))
    assert script is not None, "are-stats is not installed next to this Python"
    return script


def test_console_script_is_main_not_the_bare_app():
    (ep,) = entry_points(group="console_scripts", name="are-stats")
    assert ep.value == "are_stats.cli:main"


def test_console_script_prunes_the_cache_and_keeps_the_exit_status(tmp_path):
    cache = tmp_path / "cache"
    programs = cache / "are_stats" / "programs"
    programs.mkdir(parents=True)
    old = programs / "old.bin"
    old.write_bytes(b"x" * 20_000)
    os.utime(old, (1e9, 1e9))  # long unused
    env = dict(os.environ, XDG_CACHE_HOME=str(cache), ARE_STATS_CACHE_MAX_MB="0.01")
    env.pop("ARE_STATS_NO_CACHE", None)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    env.pop("ARE_STATS_JAX_CACHE", None)
    ok = subprocess.run([_console_script(), "version"], env=env, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == are_stats.__version__
    assert not old.exists()  # 20 kB past a 10 kB cap: pruned after the command
    bad = subprocess.run(
        [_console_script(), "report", str(tmp_path / "none.nc")], env=env, capture_output=True,
        text=True,
    )  # fmt: skip
    assert bad.returncode == 2 and "none.nc" in bad.stderr
