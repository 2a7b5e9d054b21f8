"""Scenario tracks (the `generate --behaviours` hook) and the pictures."""

from __future__ import annotations

import jax
import matplotlib
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import GridMDP, plot_tracks, plot_values, scenario_tracks

matplotlib.use("Agg")


def _grid():
    occ = np.zeros((12, 16), bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    occ[3:9, 7] = True
    return occ


def _artefacts():
    return pd.DataFrame(
        {
            "scenario": [0, 0, 0, 1],
            "id": [1, 2, 3, 1],
            "class": ["car", "person", "pallet", "person"],
            "mark": [3, 7, 1, 7],
            "t_arrive": [0.0, 1.0, 0.5, 2.0],
            "t_leave": [10.0, 9.0, 6.5, 4.0],
            "x": [0.35, 0.45, 1.25, 0.35],
            "y": [0.25, 0.95, 0.45, 0.55],
            "yaw": [0.0, np.pi / 2, np.pi, 3 * np.pi / 2],
        }
    )


def test_scenario_tracks_table():
    occ = _grid()
    beh = {"car": "run", "person": "follow", "pallet": "stop"}
    tracks = scenario_tracks(
        jax.random.key(0), _artefacts(), occ, dt=0.5, resolution=0.1, behaviour_of=beh
    )
    assert list(tracks.columns) == ["scenario", "id", "t", "x", "y", "yaw"]
    sizes = tracks.groupby(["scenario", "id"]).size()
    assert sizes[(0, 1)] == 21 and sizes[(0, 2)] == 17 and sizes[(0, 3)] == 13
    assert sizes[(1, 1)] == 5  # alone in its scenario: nobody to follow, it walks
    first = tracks.groupby(["scenario", "id"]).first()
    assert first.loc[(0, 2), "t"] == pytest.approx(1.0)
    assert first.loc[(0, 2), "x"] == pytest.approx(0.45) and first.loc[
        (0, 2), "y"
    ] == pytest.approx(0.95)
    pallet = tracks[(tracks.scenario == 0) & (tracks.id == 3)]
    assert np.all(pallet.x == pallet.x.iloc[0]) and np.all(pallet.yaw == np.pi)
    # positions stay on free cells and artefacts of a scenario never share a cell
    rows = np.floor(tracks.y / 0.1).astype(int)
    cols = np.floor(tracks.x / 0.1).astype(int)
    assert not occ[rows, cols].any()
    for _, at_t in tracks.assign(r=rows, c=cols).groupby(["scenario", "t"]):
        assert not at_t.duplicated(["r", "c"]).any()


def test_scenario_tracks_bad_input():
    occ = _grid()
    key = jax.random.key(0)
    with pytest.raises(ValueError, match="missing"):
        scenario_tracks(key, _artefacts().drop(columns="yaw"), occ)
    bad = _artefacts()
    bad.loc[0, "x"] = 0.75  # (row 2, col 7) is free; (row 3..8, col 7) is a wall
    bad.loc[0, "y"] = 0.45
    with pytest.raises(ValueError, match="free cells"):
        scenario_tracks(key, bad, occ, resolution=0.1)
    bad = _artefacts()
    bad.loc[1, "t_leave"] = 0.0
    with pytest.raises(ValueError, match="t_arrive <= t_leave"):
        scenario_tracks(key, bad, occ, resolution=0.1)
    with pytest.raises(ValueError, match="behaviour"):
        scenario_tracks(key, _artefacts(), occ, resolution=0.1, behaviour_of={"car": "fly"})


def test_plots_draw(tmp_path):
    occ = _grid()
    sol = GridMDP(occ).solve([[6, 12]], "walk", 20)
    ax = plot_values(sol, 0, 0)
    assert ax.get_xlabel() == "column (+x)"
    ax.figure.savefig(tmp_path / "values.png")
    tracks = scenario_tracks(jax.random.key(1), _artefacts(), occ, dt=0.5, resolution=0.1)
    fig = plot_tracks(tracks, occ, times=[0, 2, 4], resolution=0.1)
    assert len(fig.axes) == 3
    with pytest.raises(ValueError, match="t"):
        plot_values(sol, 0, 21)
    with pytest.raises(ValueError, match="tracks"):
        plot_tracks(pd.DataFrame({"a": [1]}), occ, times=[0])
