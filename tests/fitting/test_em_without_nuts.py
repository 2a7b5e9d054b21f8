"""``are-stats fit --method em`` compiles no NUTS program, also when it chooses models."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

import are_stats.fitting._nuts as nuts_module
from are_stats.cli import app

runner = CliRunner()


def _no_nuts(*_args, **_kwargs):
    raise AssertionError("a NUTS program was planned")


@pytest.mark.parametrize("auto", [True, False])
def test_em_fit_never_calls_the_nuts_driver(tmp_path, monkeypatch, auto):
    """Every NUTS run and prefetch goes through ``_plan``: with it raising, an em fit of a
    three-row log with the automatic model choice (or named richer models) still works."""
    monkeypatch.setattr(nuts_module, "_plan", _no_nuts)
    monkeypatch.setattr(nuts_module, "run_nuts", _no_nuts)
    log = tmp_path / "three.csv"
    log.write_text("id,t_arrive,t_leave\na,10,40\nb,50,55\nc,70,130\n")
    (tmp_path / "three.yaml").write_text("window: [0, 200]\narea: 100\n")
    fit = tmp_path / "f.nc"
    models = [] if auto else ["--arrivals", "negbin", "--lifetimes", "weibull"]
    res = runner.invoke(app, ["fit", str(log), "--out", str(fit), "--method", "em",
                              "--no-figures", "--samples", "200", "--chains", "2",
                              *models])  # fmt: skip
    assert res.exit_code == 0, res.output
    import arviz as az

    a = az.from_netcdf(fit).posterior.attrs
    assert "Laplace" in a["traffic_model_choice"] and "no NUTS" in a["traffic_model_choice"]
    if not auto:
        assert (a["arrival_model"], a["lifetime_model"]) == ("negbin", "weibull")
    # the NUTS method does reach the driver (the patch is what the em fit avoided)
    res = runner.invoke(app, ["fit", str(log), "--out", str(tmp_path / "g.nc"),
                              "--no-figures", "--samples", "20", "--warmup", "20"])  # fmt: skip
    assert res.exit_code != 0
