"""Tracks -> life-cycle log on hand-made tracks, and the tracks / panel readers' errors."""

from __future__ import annotations

import math
import warnings

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


# ---- groups, exits, splits, single sightings ----------------------------------------------

STEP = 0.4  # a 2.5 Hz tracker


def walk(track_id, t_start, start, velocity, duration, rng, noise=0.03):
    """Sightings of one walker every STEP seconds (times on the tracker's frame grid)."""
    k0 = round(t_start / STEP)
    k = np.arange(k0, k0 + round(duration / STEP) + 1)
    t = k * STEP
    pos = np.asarray(start) + np.outer(t - t[0], velocity)
    pos = pos + rng.normal(0.0, noise, pos.shape)
    return pd.DataFrame({"id": track_id, "t": t, "x": pos[:, 0], "y": pos[:, 1]})


def synthetic_groups(rng):
    """3 pairs walking together, 4 people alone, 2 people passing each other."""
    parts = []
    for p, (t_start, start, v, lag) in enumerate(
        [
            (4.0, (0.0, 5.0), (1.3, 0.0), 0),
            (20.0, (10.0, 0.0), (0.0, 1.1), 1),  # the partner is first seen a frame later
            (36.0, (20.0, 15.0), (-0.9, -0.9), 0),
        ]
    ):
        parts.append(walk(f"p{p}a", t_start, start, v, 12.0, rng))
        off = np.array([-v[1], v[0]]) / np.hypot(*v) * 0.7  # side by side, 0.7 m apart
        s2 = np.asarray(start) + off + np.asarray(v) * lag * STEP
        parts.append(walk(f"p{p}b", t_start + lag * STEP, s2, v, 12.0 - lag * STEP, rng))
    # alone: far in time or space from everyone
    parts.append(walk("s0", 12.0, (0.0, 0.0), (1.0, 0.5), 10.0, rng))
    parts.append(walk("s1", 4.0, (18.0, 18.0), (-1.2, 0.0), 10.0, rng))  # same time, far
    parts.append(walk("s2", 9.0, (0.0, 5.0), (1.3, 0.0), 8.0, rng))  # p0's door, later
    parts.append(walk("s3", 28.0, (5.0, 10.0), (0.0, -1.0), 9.0, rng))
    # two people first seen 0.8 m apart in the same frame, walking in opposite directions
    parts.append(walk("x0", 44.0, (10.0, 10.0), (1.3, 0.0), 8.0, rng))
    parts.append(walk("x1", 44.0, (10.8, 10.0), (-1.3, 0.0), 8.0, rng))
    return pd.concat(parts, ignore_index=True).sample(frac=1.0, random_state=1)


def groups_of(out):
    g = {}
    for i, grp in zip(out["id"], out["group"], strict=True):
        if grp:
            g.setdefault(grp, set()).add(i)
    return sorted(sorted(v) for v in g.values())


def test_groups_inferred_exactly(rng):
    tr = synthetic_groups(rng)
    out = tracks_to_lifecycle(tr, window=(0.0, 60.0), gap_tolerance=2.0)
    assert groups_of(out) == [["p0a", "p0b"], ["p1a", "p1b"], ["p2a", "p2b"]]
    r = out.set_index("id")
    assert r.loc["p0b", "group"] == r.loc["p0a", "group"] == "p0a"  # first member's id
    assert r.loc["x0", "group"] == r.loc["x1", "group"] == ""
    info = out.attrs["tracks"]
    assert info["sampling_step"] == pytest.approx(STEP)
    assert info["group_time"] == pytest.approx(1.5 * STEP)
    assert info["group_distance"] == 1.5
    assert info["groups"] == 3 and info["artefacts_in_groups"] == 6
    assert info["track_ids"] == info["artefacts"] == 12 and info["split_track_ids"] == 0
    # the log keeps them: group codes in order of first appearance
    log = lifecycle_log_from_frame(out, window=(0.0, 60.0), area=400.0)
    assert log.report()["groups"] == 3 and log.report()["artefacts_in_groups"] == 6
    data = log.to_lifecycle_data()
    codes = dict(zip(out["id"], data.group.tolist(), strict=True))
    assert codes["p0a"] == codes["p0b"] != codes["s1"]
    assert len(set(data.group.tolist())) == 9
    # tolerances: a group_time under one frame loses the lagging pair; 0 m turns it off
    late = tracks_to_lifecycle(tr, window=(0.0, 60.0), group_time=0.1)
    assert groups_of(late) == [["p0a", "p0b"], ["p2a", "p2b"]]
    off = tracks_to_lifecycle(tr, window=(0.0, 60.0), group_distance=0.0)
    assert (off["group"] == "").all()
    # first-sighting proximity suffices when they share fewer than two common times
    brief = pd.DataFrame(
        {"id": ["u", "v", "v", "w"], "t": [2.0, 2.0, 4.0, 2.0], "x": [0, 1, 9, 9], "y": 0.0}
    )
    out = tracks_to_lifecycle(brief, window=(0.0, 10.0), time_step=0.5)
    assert groups_of(out) == [["u", "v"]]


def test_entry_and_exit_points(rng):
    tr = synthetic_groups(rng)
    out = tracks_to_lifecycle(tr, window=(0.0, 50.0), gap_tolerance=2.0).set_index("id")
    s0 = tr[tr["id"] == "s0"].sort_values("t")
    assert (out.loc["s0", "x"], out.loc["s0", "y"]) == (s0["x"].iloc[0], s0["y"].iloc[0])
    assert (out.loc["s0", "x_exit"], out.loc["s0", "y_exit"]) == (
        s0["x"].iloc[-1],
        s0["y"].iloc[-1],
    )
    # x0, x1 are still walking at t1 = 50: censored, exit unknown
    assert np.isnan(out.loc["x0", "t_leave"]) and np.isnan(out.loc["x0", "x_exit"])
    assert np.isnan(out.loc["x1", "y_exit"])


def test_split_warning_names_the_numbers():
    rows = []
    for i in range(4):  # 4 tracks seen in bursts separated by 5 s gaps
        for burst in range(5):
            for k in range(3):
                rows.append((f"v{i}", 20.0 * i + 6.0 * burst + k * 0.5, float(i), 0.0))
    tr = pd.DataFrame(rows, columns=["id", "t", "x", "y"])
    with pytest.warns(
        UserWarning,
        match=r"4 track ids became 20 artefacts: gaps longer than gap_tolerance=2 s split 4 "
        r"of the tracks .*raise gap_tolerance",
    ):
        out = tracks_to_lifecycle(tr, window=(0.0, 100.0), gap_tolerance=2.0)
    assert out.attrs["tracks"]["track_ids"] == 4
    assert out.attrs["tracks"]["artefacts"] == 20 and out.attrs["tracks"]["split_track_ids"] == 4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = tracks_to_lifecycle(tr, window=(0.0, 100.0), gap_tolerance=6.0)
    assert len(out) == 4


def test_single_sightings_never_give_zero_stays(rng):
    t = np.round(rng.uniform(0.0, 100.0, 40) / STEP) * STEP
    singles = pd.DataFrame({"id": [f"s{i}" for i in range(40)], "t": t, "x": 0.0, "y": 0.0})
    tr = pd.concat([singles, walk("w", 0.0, (50.0, 50.0), (1.0, 0.0), 100.0, rng)])
    out = tracks_to_lifecycle(tr, window=(0.0, 100.0), gap_tolerance=1.0, edge_tolerance=0.0)
    data = lifecycle_log_from_frame(out, window=(0.0, 100.0), area=5.0).to_lifecycle_data()
    assert data.n == 41
    stays = data.dwell[~data.censored]
    assert (stays > 0).all()
    one = ~data.censored & ~data.truncated & (out["n_sightings"].to_numpy() == 1)
    assert_allclose = np.testing.assert_allclose
    assert_allclose(data.t_leave[one] - data.t_arrive[one], STEP, rtol=1e-9)
    # a single sighting within one step of t1 is censored (its step would pass t1)
    last = out[np.isclose(out["x"], 0.0) & (out["t_arrive"] > 100.0 - STEP)]
    assert last["t_leave"].isna().all()


def test_window_tolerance_is_one_sampling_step():
    t = np.arange(0, 540) * STEP  # ends at 215.60000000000002
    assert t[-1] == 215.60000000000002
    tr = pd.DataFrame({"id": "a", "t": np.r_[t, 216.4], "x": 0.0, "y": 0.0})
    out = tracks_to_lifecycle(tr, window=(0.0, 215.6), gap_tolerance=1.0)
    assert out.attrs["excluded"]["outside_window"] == 1  # 216.4 is two steps out
    assert len(out) == 1 and out.attrs["tracks"]["sightings"] == 540
    log = lifecycle_log_from_frame(out, window=(0.0, 215.6), area=1.0)
    assert log.to_lifecycle_data().window == (0.0, 215.6)


def test_group_argument_errors():
    tr = tracks([("a", 0.0, 0.0, 0.0, "")])
    with pytest.raises(ValueError, match=r"^group_time: expected a finite number >= 0"):
        tracks_to_lifecycle(tr, group_time=-1)
    with pytest.raises(ValueError, match=r"^group_distance: expected a finite number >= 0"):
        tracks_to_lifecycle(tr, group_distance=float("nan"))
    with pytest.raises(ValueError, match=r"^time_step: expected a finite number > 0"):
        tracks_to_lifecycle(tr, time_step=0)
