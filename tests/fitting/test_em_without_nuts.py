"""``are-stats fit --method em`` compiles no NUTS program, also when it chooses models."""

from __future__ import annotations

import arviz as az
import numpy as np
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
    res = runner.invoke(
        app,
        [
            "fit",
            str(log),
            "--out",
            str(fit),
            "--method",
            "em",
            "--no-figures",
            "--samples",
            "200",
            "--chains",
            "2",
            *models,
        ],
    )
    assert res.exit_code == 0, res.output

    a = az.from_netcdf(fit).posterior.attrs
    assert "Laplace" in a["traffic_model_choice"] and "no NUTS" in a["traffic_model_choice"]
    if not auto:
        assert (a["arrival_model"], a["lifetime_model"]) == ("negbin", "weibull")
    # the NUTS method does reach the driver (the patch is what the em fit avoided); the
    # paper's model alone has exact draws, so --no-exact asks for its NUTS run
    res = runner.invoke(
        app,
        [
            "fit",
            str(log),
            "--out",
            str(tmp_path / "g.nc"),
            "--no-figures",
            "--samples",
            "20",
            "--warmup",
            "20",
            "--no-exact",
        ],
    )
    assert res.exit_code != 0


def test_em_leaves_out_a_candidate_too_large_for_the_laplace_approximation(tmp_path):
    """100 artefacts arriving in one tick make a group-size law of 99 free parameters:
    em does not offer it (a note says why) unless it is named, which is a clean error."""
    rng = np.random.default_rng(0)
    stays = rng.exponential(20.0, 100).round(1) + 0.1
    rows = [f"a{k},10,{10 + s:.1f}" for k, s in enumerate(stays)]
    rows += [f"b{k},{50 + 7 * k},{60 + 7 * k}" for k in range(20)]
    log = tmp_path / "crowd.csv"
    log.write_text("id,t_arrive,t_leave\n" + "\n".join(rows) + "\n")
    (tmp_path / "crowd.yaml").write_text("window: [0, 300]\narea: 100\n")
    fit = tmp_path / "f.nc"
    base = [
        "fit",
        str(log),
        "--out",
        str(fit),
        "--method",
        "em",
        "--no-figures",
        "--samples",
        "200",
        "--chains",
        "1",
    ]
    res = runner.invoke(app, base + ["--lifetimes", "exponential"])
    assert res.exit_code == 0, res.output

    a = az.from_netcdf(fit).posterior.attrs
    assert "groups not offered: 100 parameters" in a["traffic_arrival_notes"]
    assert a["arrival_model"] != "groups"
    res = runner.invoke(app, base + ["--arrivals", "groups", "--force"])
    assert res.exit_code == 2
    assert "--arrivals groups" in res.output and "--method nuts" in res.output
