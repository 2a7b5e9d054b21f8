"""are-stats fit refuses a fit past the limits through fit_log's own check (issue 25: the
CLI holds no estimate of its own), naming its options; nothing is written."""

from __future__ import annotations

from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.inputs import limits

runner = CliRunner()


def test_fit_past_the_memory_limit_names_samples_and_chains(tmp_path):
    out = tmp_path / "f.nc"
    args = ["fit", "courtyard_traffic", "--out", str(out), "--samples", "1000", "--chains", "500"]
    # 5e5 draws of 512 bytes, one byte past the limit (reading the log needs far less)
    with limits(memory=500_000 * 8 * 64 - 1):
        res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    assert "--samples, --chains" in res.output and "5e+05 posterior draws" in res.output
    assert "Traceback" not in res.output and not out.exists()


def test_nuts_past_the_work_limit_names_samples_warmup_and_chains(tmp_path):
    out = tmp_path / "f.nc"
    args = ["fit", "courtyard_traffic", "--out", str(out), "--samples", "20", "--warmup", "20"]
    with limits(work=1000):
        res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    assert "--samples, --warmup, --chains" in res.output and "NUTS on" in res.output
    assert not out.exists()
