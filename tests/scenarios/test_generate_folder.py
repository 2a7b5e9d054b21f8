"""generate_folder: a scenarios folder drawn from a fit, its options checked before any work."""

from __future__ import annotations

import inspect
from typing import get_type_hints

import jax
import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import load_catalogue, read_map
from are_stats.fitting import read_fit
from are_stats.inputs import InputError
from are_stats.scenarios import (
    GenerateFolderOptions,
    generate_folder,
    read_scenes,
    scenes_from_fit,
    scenes_tables,
)
from are_stats.traffic import simulate_lifecycle
from tests.helpers import PAPER_MODELS


@pytest.fixture(scope="module")
def fit_file(tmp_path_factory):
    """A small conjugate + EM fit of a simulated one-hour log (lambda*A = 1/20 per s)."""
    folder = tmp_path_factory.mktemp("genfit")
    data = simulate_lifecycle(
        jax.random.key(3), 1 / 20 / 400.0, 1 / 300, [1.0], [3.0], (0.0, 3600.0), area=400.0
    )
    ids = [f"x{i}" for i in range(data.n)]
    log = folder / "log.csv"
    pd.DataFrame({"id": ids, "t_arrive": data.t_arrive, "t_leave": data.t_leave}).to_csv(
        log, index=False, na_rep=""
    )
    (folder / "log.yaml").write_text(yaml.safe_dump({"window": [0.0, 3600.0], "area": 400.0}))
    fit = folder / "small.nc"
    args = ["fit", log, "--out", fit, "--method", "em", "--no-figures", "--samples", "20",
            "--chains", "2", *PAPER_MODELS]  # fmt: skip
    res = CliRunner().invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return fit


def test_generate_folder_writes_the_one_assemblys_scenes(fit_file, tmp_path):
    out = tmp_path / "scen"
    calls = []

    def start():
        calls.append(out.exists())  # before anything is written
        return lambda done, total, what: calls.append((done, total))

    df = generate_folder(fit_file, 3, 300.0, 5, out, "courtyard", on_start=start)
    assert calls[0] is False and calls[-1][0] == calls[-1][1]  # every step reported
    # the folder holds the table returned, and records the fit, the map and the seed
    folder = read_scenes(out)
    pd.testing.assert_frame_equal(
        folder.artefacts.reset_index(drop=True), df.reset_index(drop=True), check_like=True
    )
    assert folder.manifest["fit"] == str(fit_file) and folder.manifest["seed"] == 5
    assert folder.map_file.endswith("courtyard.yaml")
    # the same scenes as the one assembly called by hand with the same seed
    _, grid = read_map("courtyard")
    scenes = scenes_from_fit(5, read_fit(fit_file), grid, load_catalogue(), 3, 300.0)
    want, _ = scenes_tables(scenes)
    np.testing.assert_array_equal(df[["x", "y", "t_arrive"]], want[["x", "y", "t_arrive"]])


def test_generate_folder_checks_options_before_reading_or_writing(tmp_path):
    with pytest.raises(InputError, match="--scenarios: expected an integer >= 1"):
        generate_folder(tmp_path / "missing.nc", 0, 300.0, 5, tmp_path / "out")
    with pytest.raises(InputError, match="--behaviour-cell: expected a finite number > 0"):
        generate_folder(
            tmp_path / "missing.nc", 1, 300.0, 5, tmp_path / "out", behaviours=True,
            behaviour_cell=0.0,
        )  # fmt: skip
    assert not (tmp_path / "out").exists()


def test_generate_folder_options_are_its_keywords():
    """GenerateFolderOptions (the job's ``**options``) names generate_folder's keywords after
    map_path, but on_start, with their types: a keyword added to one is added to the other."""
    hints = get_type_hints(generate_folder)
    names = list(inspect.signature(generate_folder).parameters)
    keywords = names[names.index("map_path") + 1 : names.index("on_start")]
    assert list(GenerateFolderOptions.__annotations__) == keywords
    assert get_type_hints(GenerateFolderOptions) == {k: hints[k] for k in keywords}
