"""Tracks -> life-cycle log on hand-made tracks, and the tracks / panel readers' errors."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from are_stats.logs import (
    lifecycle_log_from_frame,
    read_count_panel,
    read_tracks,
    tracks_to_lifecycle,
)


def tracks(rows):
    return pd.DataFrame(rows, columns=["id", "t", "x", "y", "label"])


def by_id(df):
    return {r.id: r for r in df.itertuples()}


def test_gap_merge_split_and_censoring():
    tr = tracks(
        [
            # a: seen from the window start, gap of 1.5 (merged), leaves at 6
            ("a", 0.0, 0.0, 0.0, "person"),
            ("a", 1.0, 1.0, 0.0, "person"),
            ("a", 2.5, 2.0, 0.0, "person"),
            ("a", 6.0, 2.0, 1.0, "person"),
            # b: arrives at 3, gap of 5 -> split into b#1 (3..4) and b#2 (9..10, censored)
            ("b", 3.0, 5.0, 5.0, "car"),
            ("b", 4.0, 5.0, 6.0, "car"),
            ("b", 9.0, 1.0, 1.0, "car"),
            ("b", 10.0, 1.0, 2.0, "car"),
            # c: single sighting in the middle
            ("c", 5.0, 3.0, 3.0, ""),
        ]
    )
    # gaps of a: 1.0, 1.5, 3.5 -> tolerance 4 keeps a whole; b's gap of 5 splits it
    with pytest.warns(UserWarning, match=r"3 track ids became 4 artefacts"):
        out = tracks_to_lifecycle(tr, window=(0.0, 10.0), gap_tolerance=4.0, edge_tolerance=0.5)
    r = by_id(out)
    assert set(r) == {"a", "b#1", "b#2", "c"}
    assert math.isnan(r["a"].t_arrive) and r["a"].t_leave == 6.0
    assert r["b#1"].t_arrive == 3.0 and r["b#1"].t_leave == 4.0
    assert r["b#2"].t_arrive == 9.0 and math.isnan(r["b#2"].t_leave)
    # a single sighting stays one sampling step (the median step within tracks: 1 s)
    assert r["c"].t_arrive == 5.0 and r["c"].t_leave == 6.0
    assert out.attrs["tracks"]["sampling_step"] == 1.0
    assert r["a"].n_sightings == 4 and r["b#1"].n_sightings == 2
    assert r["b#1"].label == "car" and r["c"].label == ""
    # headings from the first displacement; a single sighting has none
    assert r["a"].yaw == pytest.approx(0.0)
    assert r["b#1"].yaw == pytest.approx(math.pi / 2)
    assert math.isnan(r["c"].yaw)
    assert (r["b#2"].x, r["b#2"].y) == (1.0, 1.0)
    # sorted by first sighting
    assert out["id"].tolist() == ["a", "b#1", "c", "b#2"]
    # a smaller tolerance splits a at its 3.5 gap too
    with pytest.warns(UserWarning, match=r"3 track ids became 6 artefacts"):
        out2 = tracks_to_lifecycle(tr, window=(0.0, 10.0), gap_tolerance=1.2, edge_tolerance=0.5)
    assert {"a#1", "a#2", "a#3"} <= set(out2["id"])
    # the output is a valid life-cycle log
    log = lifecycle_log_from_frame(out, window=(0.0, 10.0), area=10.0)
    assert log.table["truncated"].sum() == 1 and log.table["censored"].sum() == 1


def test_window_clipping_min_sightings_and_majority_label():
    tr = tracks(
        [
            ("a", -5.0, 0.0, 0.0, "x"),  # outside the window: counted
            ("a", 1.0, 0.0, 0.0, "car"),
            ("a", 2.0, 0.0, 0.0, "person"),
            ("a", 3.0, 0.0, 0.0, "person"),
            ("z", 5.0, 0.0, 0.0, "ghost"),  # one sighting: flicker
        ]
    )
    out = tracks_to_lifecycle(
        tr, window=(0, 20), gap_tolerance=2, edge_tolerance=0.1, min_sightings=2
    )
    assert out["id"].tolist() == ["a"]
    assert out["label"].tolist() == ["person"]
    assert out.attrs["excluded"] == {"outside_window": 1, "too_few_sightings": 1}
    assert out["t_arrive"].tolist() == [1.0]


def test_default_window_and_yaw_column():
    tr = pd.DataFrame(
        {
            "id": [7, 7, 8],
            "t": [0.0, 1.0, 0.5],
            "x": [0.0, 1.0, 2.0],
            "y": [0.0, 0.0, 2.0],
            "yaw": [1.0, 1.0, np.nan],
        }
    )
    out = tracks_to_lifecycle(tr, gap_tolerance=2.0, edge_tolerance=0.0)
    assert out.attrs["window"] == (0.0, 1.0)
    r = by_id(out)
    assert math.isnan(r["7"].t_arrive) and math.isnan(r["7"].t_leave)  # spans the window
    assert r["7"].yaw == 1.0  # the yaw column wins over the heading of motion
    # one sighting: a stay of one step (1 s) would reach past t1 = 1, so it is censored
    assert r["8"].t_arrive == 0.5 and math.isnan(r["8"].t_leave)


def test_tracks_argument_errors():
    tr = tracks([("a", 0.0, 0.0, 0.0, "")])
    with pytest.raises(ValueError, match=r"^gap_tolerance: expected a finite number >= 0"):
        tracks_to_lifecycle(tr, gap_tolerance=-1)
    with pytest.raises(ValueError, match=r"^min_sightings: expected an integer >= 1"):
        tracks_to_lifecycle(tr, min_sightings=0)
    with pytest.raises(ValueError, match=r"^window: expected \(t0, t1\) with t0 < t1"):
        tracks_to_lifecycle(tr, window=(3, 1))
    with pytest.raises(
        ValueError,
        match=r"tracks: row 1, column 't': expected a number, got an "
        "empty cell",
    ):
        tracks_to_lifecycle(tr.assign(t=[np.nan]))
    with pytest.raises(ValueError, match=r"tracks: missing column\(s\) 'x'"):
        tracks_to_lifecycle(tr.drop(columns="x"))
    with pytest.raises(ValueError, match=r"tracks: empty tracks table"):
        tracks_to_lifecycle(tr.iloc[:0])


TRACK_FILE_CASES = [
    (
        "id,t,x\na,0,1\n",
        r"tr\.csv: missing column\(s\) 'y': expected a tracks table with "
        r"columns id, t, x, y",
    ),
    (
        "id,t,x,y\na,0,1,2\na,zz,1,2\n",
        r"tr\.csv: row 2 \(line 3\), column 't': expected a "
        "number, got 'zz'",
    ),
    (
        "id,t,x,y\na,0,nan,2\n",
        r"tr\.csv: row 1 \(line 2\), column 'x': expected a finite "
        "number",
    ),
    (
        "id,t,x,y\n,0,1,2\n",
        r"tr\.csv: row 1 \(line 2\), column 'id': expected a non-empty "
        "identifier",
    ),
    ("id,t,x,y\n", r"tr\.csv: empty tracks table"),
    ("", r"tr\.csv: empty file"),
]


@pytest.mark.parametrize(("text", "message"), TRACK_FILE_CASES)
def test_read_tracks_errors(tmp_path, text, message):
    p = tmp_path / "tr.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_tracks(p)


def test_read_tracks_parquet(tmp_path):
    p = tmp_path / "tr.parquet"
    pd.DataFrame(
        {
            "id": ["a", "a"],
            "t": [0.0, 1.0],
            "x": [1.0, 2.0],
            "y": [0.0, 0.0],
            "label": ["car", "car"],
        }
    ).to_parquet(p)
    df = read_tracks(p)
    assert df["id"].tolist() == ["a", "a"] and df["label"].tolist() == ["car", "car"]
    assert np.isnan(df["yaw"]).all()


def test_count_panel(tmp_path):
    p = tmp_path / "panel.csv"
    p.write_text("t,count\n0,3\n60,4\n120,0\n")
    t, n = read_count_panel(p)
    assert t.tolist() == [0.0, 60.0, 120.0] and n.tolist() == [3, 4, 0]
    assert n.dtype == np.int64


PANEL_CASES = [
    ("t\n0\n", r"panel\.csv: missing column\(s\) 'count': expected a count panel"),
    (
        "t,count\n0,1\n60,-1\n",
        r"panel\.csv: row 2 \(line 3\), column 'count': expected a "
        "non-negative integer, got -1",
    ),
    (
        "t,count\n0,1.5\n",
        r"row 1 \(line 2\), column 'count': expected a non-negative integer, "
        r"got 1\.5",
    ),
    (
        "t,count\n0,1\n0,2\n",
        r"row 2 \(line 3\), column 't': expected a time greater than the "
        r"previous row's 0\.0 \(strictly increasing times\), got 0\.0",
    ),
    ("t,count\n0,1\n,2\n", r"row 2 \(line 3\), column 't': expected a number, got an empty cell"),
    ("t,count\n0,NaN\n", r"row 1 \(line 2\), column 'count': expected a finite number"),
    ("t,count\n", r"panel\.csv: empty count panel"),
]


@pytest.mark.parametrize(("text", "message"), PANEL_CASES)
def test_count_panel_errors(tmp_path, text, message):
    p = tmp_path / "panel.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_count_panel(p)
