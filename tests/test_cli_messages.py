"""The command line's small messages (a new user's tour): the fit's class line gives its
stays' unit, an existing output is refused in the command line's words (``--force``; the
API's error says ``force=True``), and ``report`` refuses an existing report before it
computes anything."""

from __future__ import annotations

import re

import pandas as pd
import pytest

import are_stats.fitting as fitting
from are_stats._atomic import OutputExistsError, check_writable
from are_stats.fitting import check_report_outputs
from tests.test_cli_jobs import PAPER_MODELS, _invoke, _write_log


def test_an_existing_output_is_refused_in_the_callers_words(tmp_path):
    (tmp_path / "f.nc").write_bytes(b"")
    with pytest.raises(OutputExistsError) as err:
        check_writable(tmp_path / "f.nc", force=False)
    assert str(err.value).endswith("f.nc: already exists; pass force=True to overwrite it")
    assert err.value.cli_message.endswith("f.nc: already exists; pass --force to overwrite it")
    assert check_writable(tmp_path / "f.nc", force=True) == tmp_path / "f.nc"


def test_check_report_outputs_names_the_first_existing_report_file(tmp_path):
    check_report_outputs(tmp_path / "none", force=False)  # no folder: nothing in the way
    (tmp_path / "class_entries.png").write_bytes(b"old")
    (tmp_path / "notes.txt").write_text("not the report's")
    with pytest.raises(OutputExistsError, match=r"class_entries.png: already exists"):
        check_report_outputs(tmp_path, force=False)
    check_report_outputs(tmp_path, force=True)
    (tmp_path / "class_entries.png").unlink()
    check_report_outputs(tmp_path, force=False)  # a file of another kind stays allowed


def test_fit_says_the_unit_of_the_stays_and_report_refuses_before_its_summary(
    tmp_path, monkeypatch
):
    log, _ = _write_log(tmp_path, labels=True)
    rows = pd.read_csv(log).drop(columns="mark")  # labels, no marks: the labels are classes
    rows["label"] = rows["label"].map({"small": "person", "large": "bicycle"})
    rows.to_csv(log, index=False, na_rep="")
    fit = tmp_path / "f.nc"
    res = _invoke(["fit", log, "--out", fit, "--method", "em", "--no-figures",
                   "--samples", "20", "--chains", "2", *PAPER_MODELS])  # fmt: skip
    assert res.exit_code == 0, res.output
    said = " ".join(res.output.split())
    assert re.search(r"/h, mean stay [\d.e+]+ s\)", said), said
    out = tmp_path / "rep"
    out.mkdir()
    (out / "ppc_counts.png").write_bytes(b"old")

    def summary(*args, **kwargs):
        raise AssertionError("report computed the summary before refusing the folder")

    monkeypatch.setattr(fitting, "fit_summary", summary)
    res = _invoke(["report", fit, "--out", out, "--replicates", "5"])
    said = " ".join(res.output.split())
    assert res.exit_code == 2, said
    assert "ppc_counts.png: already exists; pass --force to overwrite it" in said
    assert "force=True" not in said
    assert [p.name for p in out.iterdir()] == ["ppc_counts.png"]  # nothing written
    assert (out / "ppc_counts.png").read_bytes() == b"old"
