"""The scenarios folder: one writer (write_scenes), one validating reader (read_scenes)."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
import yaml

from are_stats.inputs import InputError
from are_stats.scenarios import (
    FORMAT_VERSION,
    SCENARIO_COLUMNS,
    generate_scenarios,
    read_scenes,
    write_scenes,
)

AREA = 400.0


def _params():
    return {
        "arrival_rate": np.array([0.01]),
        "leave_rate": np.array([0.05]),
        "mix_weights": np.array([[0.6, 0.4]]),
        "mix_rates": np.array([[1.0, 4.0]]),
    }


def _scenarios(seed=1, n=3):
    return generate_scenarios(seed, _params(), n, 100.0, area=AREA)


def _tracks(df):
    """Two poses per artefact, 1 s and 2 s after it arrives."""
    rows = [
        {"scenario": r.scenario, "id": r.artefact, "t": r.t_arrive + k, "x": r.x + 0.5 * k,
         "y": r.y, "yaw": r.yaw}
        for r in df.itertuples() for k in (1.0, 2.0)
    ]  # fmt: skip
    return pd.DataFrame(rows)


def _empty():
    return pd.DataFrame(
        {c: np.zeros(0, SCENARIO_COLUMNS[c].split(",")[0]) for c in SCENARIO_COLUMNS}
    )


def test_round_trip_with_tracks(tmp_path):
    df, out = _scenarios(), tmp_path / "sc"
    tracks = _tracks(df)
    assert write_scenes(df, out, {"fit": "f.nc", "class_labels": ["a", "b"]}, tracks=tracks) == out
    assert sorted(p.name for p in out.iterdir()) == [
        "artefacts.parquet", "manifest.yaml", "tracks.parquet",
    ]  # fmt: skip
    back = read_scenes(out)
    pd.testing.assert_frame_equal(back.artefacts, df)
    pd.testing.assert_frame_equal(
        back.tracks, tracks.astype({"scenario": np.int64, "id": np.int64})
    )
    m = back.manifest
    assert m["format_version"] == FORMAT_VERSION and m["class_labels"] == ["a", "b"]
    assert m["tracks"] == {"file": "tracks.parquet", "rows": len(tracks)}
    assert m["n_scenarios"] == 3 and m["n_artefacts"] == len(df) and m["fit"] == "f.nc"


def test_same_tables_same_bytes(tmp_path):
    df = _scenarios()
    for name in ("a", "b"):
        write_scenes(df, tmp_path / name, {"seed": 1}, tracks=_tracks(df))
    for f in ("artefacts.parquet", "manifest.yaml", "tracks.parquet"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f


def test_old_unversioned_folder_reads(tmp_path):
    """A folder of an earlier are_stats: no format_version, no group column."""
    df = _scenarios()
    out = tmp_path / "old"
    out.mkdir()
    df.drop(columns="group").to_parquet(out / "artefacts.parquet", index=False)
    manifest = {"format": "are_stats scenarios 1", "version": "0.9", "n_scenarios": 3}
    (out / "manifest.yaml").write_text(yaml.safe_dump(manifest))
    back = read_scenes(out)
    assert "format_version" not in back.manifest and back.tracks is None
    np.testing.assert_array_equal(back.artefacts["group"], df["artefact"])
    pd.testing.assert_frame_equal(back.artefacts.drop(columns="group"), df.drop(columns="group"))


def test_hand_made_folder_gets_the_optional_columns(tmp_path):
    out = tmp_path / "hand"
    out.mkdir()
    pd.DataFrame({
        "scenario": [0, 0, 1], "class": [0, 1, 0], "t_arrive": [0.0, 5.0, 1.0],
        "t_leave": [10.0, 20.0, 3.0], "x": [1.0, 2.0, 3.0], "y": [0.0, 0.0, 1.0],
        "yaw": [0.0, 1.0, 2.0], "note": ["a", "b", "c"],
    }).to_parquet(out / "artefacts.parquet", index=False)  # fmt: skip
    (out / "manifest.yaml").write_text("map: null\n")
    df = read_scenes(out).artefacts
    assert list(df.columns) == [*SCENARIO_COLUMNS, "note"]
    assert df["artefact"].tolist() == [0, 1, 0] and df["mark"].tolist() == [-1, -1, -1]
    assert df["truncated"].tolist() == [True, False, False] and not df["censored"].any()
    assert df["note"].tolist() == ["a", "b", "c"]
    assert df["scenario"].dtype == np.int32 and df["mark"].dtype == np.int64


def test_empty_artefacts_table_is_a_valid_folder(tmp_path):
    # zero artefacts (no arrival in any scenario): the folder reads, with typed columns
    out = tmp_path / "empty"
    # (behaviour_tracks of no artefact: a table of empty object columns)
    no_tracks = pd.DataFrame({c: [] for c in ("scenario", "id", "t", "x", "y", "yaw")})
    write_scenes(_empty(), out, {"n_scenarios": 2}, tracks=no_tracks)
    back = read_scenes(out)
    assert len(back.artefacts) == 0 and list(back.artefacts.columns) == list(SCENARIO_COLUMNS)
    assert back.artefacts["scenario"].dtype == np.int32
    assert len(back.tracks) == 0 and back.manifest["n_scenarios"] == 2
    assert back.tracks["id"].dtype == np.int64 and back.tracks["t"].dtype == np.float64
    # a hand-made empty table without a required column is still named
    pd.DataFrame({"scenario": np.zeros(0, int)}).to_parquet(out / "artefacts.parquet")
    with pytest.raises(InputError, match=r"artefacts\.parquet: missing column\(s\) 'class'"):
        read_scenes(out)


def _folder(tmp_path, manifest=None, df=None, tracks=None):
    out = tmp_path / "sc"
    df = _scenarios() if df is None else df
    write_scenes(df, out, manifest, tracks=tracks, force=True)
    return out


@pytest.mark.parametrize(
    ("manifest", "match"),
    [
        # integer class labels gave "TypeError: 'int' object is not iterable" in a sweep
        ({"class_labels": 3}, r"manifest\.yaml: class_labels: expected a list"),
        ({"class_labels": [0, 1]}, r"manifest\.yaml: class_labels\[0\]: expected a string, got 0"),
        ({"format_version": 99}, r"manifest\.yaml: format_version: expected an integer"),
        ({"format_version": "2"}, r"manifest\.yaml: format_version: expected an integer"),
        ({"generation": [1]}, r"manifest\.yaml: generation: expected a mapping"),
        ({"generation": {"horizon": -1.0}}, r"generation\.horizon: expected a finite number >= 0"),
        ({"n_scenarios": 2}, r"row \d+, column 'scenario': expected a non-negative integer <= 1"),
        ({"map": 3}, r"manifest\.yaml: map: expected a string, got 3"),
        ({"tracks": "tracks.parquet"}, r"manifest\.yaml: tracks: expected a mapping"),
        ({"tracks": {"file": "../x.parquet"}}, r"tracks\.file: expected a file name inside"),
        ({"tracks": {"file": "none.parquet"}}, r"tracks\.file: .*got no file none\.parquet"),
    ],
)
def test_bad_manifests_are_named(tmp_path, manifest, match):
    out = _folder(tmp_path, manifest)
    with pytest.raises(InputError, match=match):
        read_scenes(out)


def _edit(df, column, row, value):
    df = df.copy()
    df[column] = df[column].astype(type(value)) if isinstance(value, float) else df[column]
    df.loc[row, column] = value
    return df


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        # coordinates of 1e300 were accepted by the sweep's reader
        ("x", 1e300, r"row 3, column 'x': expected a position within 1e\+07 m of the origin"),
        ("y", -1e300, r"row 3, column 'y': expected a position within 1e\+07 m"),
        ("t_leave", -1.0, r"row 3, column 't_leave': expected t_leave >= t_arrive"),
        ("yaw", np.inf, r"row 3, column 'yaw': expected a finite number"),
        ("class", -2, r"row 3, column 'class': expected an integer >= -1, got -2"),
        ("artefact", 0, r"row \d+, column 'artefact': expected artefact ids unique"),
    ],
)
def test_bad_artefacts_name_row_and_column(tmp_path, column, value, match):
    out = _folder(tmp_path)
    df = pd.read_parquet(out / "artefacts.parquet")
    _edit(df, column, 2, value).to_parquet(out / "artefacts.parquet", index=False)
    with pytest.raises(InputError, match=r"artefacts\.parquet: " + match):
        read_scenes(out)


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        ("id", 999, r"row 2, column 'id': expected an artefact of scenario 0 in artefacts"),
        ("x", 1e300, r"row 2, column 'x': expected a position within 1e\+07 m"),
        ("t", np.nan, r"row 2, column 't': expected a number, got an empty cell"),
    ],
)
def test_bad_tracks_name_row_and_column(tmp_path, column, value, match):
    df = _scenarios()
    out = _folder(tmp_path, tracks=_tracks(df))
    tracks = pd.read_parquet(out / "tracks.parquet")
    _edit(tracks, column, 1, value).to_parquet(out / "tracks.parquet", index=False)
    with pytest.raises(InputError, match=r"tracks\.parquet: " + match):
        read_scenes(out)


def test_missing_files_and_folders(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such scenarios folder"):
        read_scenes(tmp_path / "nope")
    out = _folder(tmp_path)
    (out / "manifest.yaml").unlink()
    with pytest.raises(InputError, match=re.escape("got no file manifest.yaml")):
        read_scenes(out)


def test_writer_refuses_tables_without_columns(tmp_path):
    with pytest.raises(ValueError, match=r"df: expected a table with columns"):
        write_scenes(_scenarios().drop(columns="x"), tmp_path / "a")
    with pytest.raises(ValueError, match=r"tracks: expected a table with columns"):
        write_scenes(_scenarios(), tmp_path / "b", tracks=pd.DataFrame({"id": [0]}))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
