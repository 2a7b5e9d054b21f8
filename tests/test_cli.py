"""The are-stats console script."""

from __future__ import annotations

from typer.testing import CliRunner

import are_stats
from are_stats.cli import app

runner = CliRunner()


def test_version():
    res = runner.invoke(app, ["version"])
    assert res.exit_code == 0
    assert res.stdout.strip() == are_stats.__version__


def test_help_lists_commands():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    assert "version" in res.stdout
