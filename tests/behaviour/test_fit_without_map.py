"""A tracks table without a map is fitted on the open area its tracks cover (issue 26)."""

from __future__ import annotations

import arviz as az
import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.behaviour import BehaviourFit
from are_stats.cli import app
from are_stats.fitting import open_area_grid
from tests.test_cli_tracks import _tracks

runner = CliRunner()


def test_open_area_grid_covers_the_tracks_with_its_margin() -> None:
    tracks = pd.DataFrame({"x": [0.4, 19.6, 5.0], "y": [4.3, 5.9, np.nan]})
    free, res, origin = open_area_grid(tracks, 0.1, 1.0)
    assert res == 0.1 and free.all()
    assert np.allclose(origin, [-0.6, 3.3])
    assert free.shape == (36, 212)  # (5.9 - 4.3 + 2) / 0.1 rows, (19.2 + 2) / 0.1 columns
    with pytest.raises(ValueError, match="finite x, y"):
        open_area_grid(tracks.iloc[2:], 0.1)


@pytest.mark.slow
def test_tracks_without_a_map_get_a_behaviour(tmp_path):
    log = _tracks(tmp_path, horizon=200.0)
    meta = yaml.safe_load((tmp_path / "tracks.yaml").read_text())
    del meta["map"]
    meta["area"] = 200.0  # the traffic fit needs the area; the map is what is missing
    (tmp_path / "tracks.yaml").write_text(yaml.safe_dump(meta))
    fit = tmp_path / "f.nc"
    res = runner.invoke(
        app,
        [
            "fit",
            str(log),
            "--out",
            str(fit),
            "--method",
            "em",
            "--positions",
            "uniform",
            "--no-figures",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "behaviour fitted on the open area the tracks cover" in " ".join(res.output.split())

    idata = az.from_netcdf(fit)
    assert "behaviour" in idata.groups()

    bfit = BehaviourFit.from_dataset(idata.behaviour)
    assert abs(float(np.exp(bfit.speed_mu[0])) / 1.2 - 1) < 0.15  # the log's 1.2 m/s
