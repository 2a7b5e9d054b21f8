"""``are-stats fit``'s options as one record (:class:`are_stats._cli_jobs.FitOptions`):
checked and named as on the command line, in a fixed order, before any file is read."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from are_stats._cli_jobs import FitOptions, run_fit
from are_stats.cli import app
from are_stats.fitting import FitSettings


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("method", "mcmc", r"--method: expected one of"),
        ("arrivals", "cauchy", r"--arrivals: expected one of"),
        ("lifetimes", "pareto", r"--lifetimes: expected one of"),
        ("positions", "anywhere", r"--positions: expected one of"),
        ("behaviour_features", "walls,doors", r"--behaviour-features: expected one of"),
        ("clock_start", "yesterday", r"--clock-start: expected an ISO 8601 time"),
        ("seed", -1, r"--seed: expected an integer >= 0"),
        ("warmup", -1, r"--warmup: expected an integer >= 0"),
        ("samples", 0, r"--samples: expected an integer >= 1"),
        ("chains", 0, r"--chains: expected an integer >= 1"),
        ("n_replicates", 0, r"--replicates: expected an integer >= 1"),
        ("components", 0, r"--components: expected an integer"),
        ("window", (5.0, 1.0), r"--window: t1: expected a finite number > 5"),
        ("window", (1.0,), r"--window: expected"),
        ("area", -1.0, r"--area: expected a finite number > 0, got -1\.0"),
    ],
)
def test_each_option_is_named_in_its_error(field, value, match):
    with pytest.raises(ValueError, match=match):
        FitOptions(**{field: value}).checked()


def test_features_without_the_behaviour_name_both_options():
    with pytest.raises(ValueError, match=r"--behaviour-features.*--no-behaviour"):
        FitOptions(behaviour=False, behaviour_features="walls").checked()


def test_the_first_bad_option_in_the_command_line_order_is_named():
    # the order of FitOptions.checked: the choices, the features, the clock, the numbers
    bad = {"method": "mcmc", "behaviour_features": "doors", "clock_start": "x", "area": -1.0}
    names = ["--method", "--behaviour-features", "--clock-start", "--area"]
    for k, name in enumerate(names):
        with pytest.raises(ValueError, match=f"^{name}"):
            FitOptions(**dict(list(bad.items())[k:])).checked()


def test_checked_normalises_and_is_idempotent():
    opts = FitOptions(window=[0, 10], area=5, behaviour_features=" walls, ", components=3)
    checked = opts.checked()
    assert checked.window == (0.0, 10.0) and checked.area == 5.0
    assert checked.features() == ("walls",) and FitOptions().features() == ()
    assert checked.checked() == checked
    # the fields no check touches pass through as given
    same = ("manifest", "counts", "figures", "compare", "exact", "behaviour", "behaviour_features")
    assert all(getattr(checked, f) == getattr(opts, f) for f in same)


#: FitOptions' fields that FitSettings names otherwise.
RENAMED = {"components": "n_components", "warmup": "num_warmup", "samples": "num_samples",
           "chains": "num_chains"}  # fmt: skip


def test_settings_carry_the_sampler_and_model_fields():
    given = {"method": "em", "components": 2, "warmup": 3, "samples": 4, "chains": 5,
             "stationary_start": False, "arrivals": "poisson", "lifetimes": "gamma",
             "positions": "uniform", "compare": "nuts", "exact": False}  # fmt: skip
    want = FitSettings(**{RENAMED.get(k, k): v for k, v in given.items()})
    assert FitOptions(**given).settings() == want != FitOptions().settings()


def test_run_fit_checks_options_and_out_before_reading_the_log(tmp_path):
    missing = tmp_path / "missing.csv"
    with pytest.raises(ValueError, match="^--method"):
        run_fit(missing, tmp_path / "f.nc", FitOptions(), method="mcmc")
    with pytest.raises(ValueError, match=r"^--out: expected a \.nc file name"):
        run_fit(missing, tmp_path / "f.txt", FitOptions())
    # a keyword replaces the record's field: the bad method is never checked
    with pytest.raises(FileNotFoundError, match="missing.csv"):
        run_fit(missing, tmp_path / "f.nc", FitOptions(method="mcmc"), method="em")
    assert not (tmp_path / "f.nc").exists()


def test_cli_names_the_option_and_exits_2(tmp_path):
    out = tmp_path / "f.nc"
    res = CliRunner().invoke(
        app, ["fit", "courtyard_traffic", "--out", str(out), "--window", "5", "1"]
    )
    assert res.exit_code == 2 and "error: --window: t1: expected" in res.output
    assert not out.exists()
