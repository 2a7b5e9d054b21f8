"""read_field_log: a life-cycle log or a tracks table, detected from the columns."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from are_stats.inputs import InputError
from are_stats.logs import read_field_log, read_lifecycle_log
from tests.helpers import assert_allclose

MANIFEST = "window: [0, 30]\narea: 400\nclock_start: '2024-05-02T07:30:00'\n"


def write(tmp_path, text, name="log.csv", manifest=MANIFEST):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    if manifest is not None:
        p.with_suffix(".yaml").write_text(manifest, encoding="utf-8")
    return p


def pair_tracks():
    """Two people walking side by side from t = 4 to 12 s and one alone, at 2 Hz."""
    t = np.arange(8, 25) * 0.5
    rows = []
    for i, ti in enumerate(t):
        rows.append(("a", ti, 1.0 * (ti - 4), 0.0, "person"))
        rows.append(("b", ti, 1.0 * (ti - 4), 0.6, "person"))
        if i < 10:
            rows.append(("c", ti + 12.0, 20.0, 0.5 * i, "person"))
    return pd.DataFrame(rows, columns=["id", "t", "x", "y", "label"])


def test_life_cycle_log_is_read_as_today(tmp_path):
    text = "id,t_arrive,t_leave,label,group\na,1,5,car,g\nb,,6,car,g\nc,2,,car,\n"
    p = write(tmp_path, text)
    log = read_field_log(p)
    ref = read_lifecycle_log(p)
    pd.testing.assert_frame_equal(log.table, ref.table)
    assert log.window == (0.0, 30.0) and log.area == 400.0
    assert log.clock_start == "2024-05-02T07:30:00"
    assert log.conversion == {} and "tracks" not in log.report()
    assert log.report()["groups"] == 1
    log = read_field_log(p, window=(0, 10), area=3.0, clock_start="2024-05-03T00:00:00")
    assert log.window == (0.0, 10.0) and log.area == 3.0
    assert log.clock_start == "2024-05-03T00:00:00"


def test_tracks_table_is_converted(tmp_path):
    p = tmp_path / "tracks.csv"
    pair_tracks().to_csv(p, index=False)
    p.with_suffix(".yaml").write_text(MANIFEST)
    log = read_field_log(p)
    t = log.table.set_index("id")
    assert sorted(t.index) == ["a", "b", "c"]
    assert t.loc["a", "t_arrive"] == 4.0 and t.loc["a", "t_leave"] == 12.0
    assert (t.loc["a", "x"], t.loc["a", "x_exit"]) == (0.0, 8.0)
    assert t.loc["a", "group"] == t.loc["b", "group"] != "" and t.loc["c", "group"] == ""
    assert log.window == (0.0, 30.0) and log.clock_start == "2024-05-02T07:30:00"
    rep = log.report()
    assert rep["groups"] == 1 and rep["artefacts_in_groups"] == 2
    assert rep["tracks"]["track_ids"] == 3 and rep["tracks"]["sightings"] == 44
    assert rep["tracks"]["sampling_step"] == 0.5
    assert rep["tracks"]["excluded"] == {"outside_window": 0, "too_few_sightings": 0}
    assert log.manifest["input"] == "tracks table"
    data = log.to_lifecycle_data()
    assert data.group is not None and data.group[0] == data.group[1]
    assert_allclose(data.x_exit, [8.0, 8.0, 20.0])
    assert (data.dwell > 0).all()
    # track options reach tracks_to_lifecycle
    alone = read_field_log(p, group_distance=0.0)
    assert alone.report()["groups"] == 0


def test_tracks_parquet_units_and_default_window(tmp_path):
    df = pair_tracks()
    df["t"] = df["t"] * 1000.0  # milliseconds
    p = tmp_path / "tracks.parquet"
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False), p)
    p.with_suffix(".yaml").write_text("area: 50\ntime_unit: ms\n")
    log = read_field_log(p)
    assert log.window == (4.0, 20.5)
    t = log.table.set_index("id")
    assert np.isnan(t.loc["a", "t_arrive"])  # seen from the window's start: present at t0
    assert t.loc["a", "t_leave"] == 12.0
    assert log.report()["tracks"]["sampling_step"] == 0.5


def test_tracks_manifest_time_step_and_window_tolerance(tmp_path):
    t = np.arange(0, 540) * 0.4  # the last sighting is 215.60000000000002
    df = pd.DataFrame({"id": "a", "t": t, "x": 0.0, "y": 0.0})
    p = tmp_path / "tracks.csv"
    df.to_csv(p, index=False)
    p.with_suffix(".yaml").write_text("window: [0, 215.6]\narea: 5\n")
    log = read_field_log(p)
    assert log.report()["tracks"]["excluded"]["outside_window"] == 0
    assert log.to_lifecycle_data().window == (0.0, 215.6)


def test_unknown_columns_name_the_file_and_both_kinds(tmp_path):
    p = write(tmp_path, "id,time,x,y\na,1,2,3\n")
    with pytest.raises(InputError) as err:
        read_field_log(p)
    msg = str(err.value)
    assert "log.csv" in msg and "id, t_arrive, t_leave" in msg and "id, t, x, y" in msg
    assert "'time'" in msg
    both = write(tmp_path, "id,t,x,y,t_arrive,t_leave\na,1,2,3,1,2\n", name="both.csv")
    with pytest.raises(InputError, match=r"both\.csv: columns: expected a life-cycle log"):
        read_field_log(both)


def test_option_errors(tmp_path):
    p = write(tmp_path, "id,t_arrive,t_leave\na,1,2\n")
    with pytest.raises(InputError, match=r"^gap_tolerance: expected a tracks table"):
        read_field_log(p, gap_tolerance=3.0)
    assert read_field_log(p, gap_tolerance=None).n_artefacts == 1  # None: the default
    with pytest.raises(InputError, match=r"track options: gap: expected one of gap_tolerance"):
        read_field_log(p, gap=3.0)
    q = tmp_path / "tracks.csv"
    q.write_text("id,t,x,y\na,1,0,abc\n")
    with pytest.raises(ValueError, match=r"tracks\.csv: row 1 \(line 2\), column 'y': expected"):
        read_field_log(q, window=(0, 5), area=1.0)
    one_time = tmp_path / "flash.csv"
    one_time.write_text("id,t,x,y\na,1,0,0\nb,1,5,5\n")
    with pytest.raises(InputError, match=r"flash\.yaml \(not found\): window: expected"):
        read_field_log(one_time, area=1.0)


def test_split_tracks_warn_naming_the_file(tmp_path):
    rows = [("v", 6.0 * b + 0.5 * k, 0.0, 0.0) for b in range(5) for k in range(3)]
    p = tmp_path / "vessels.csv"
    pd.DataFrame(rows, columns=["id", "t", "x", "y"]).to_csv(p, index=False)
    with pytest.warns(UserWarning, match=r"vessels\.csv: 1 track ids became 5 artefacts"):
        log = read_field_log(p, area=1.0)
    assert log.report()["tracks"]["artefacts"] == 5
    assert log.report()["tracks"]["split_track_ids"] == 1


def test_both_readers_take_the_same_manifest_overrides(tmp_path):
    """ManifestOverrides is one definition of the readers' keywords: the same overrides
    give the same log through either reader; an unknown one is refused by each."""
    import typing

    from are_stats.logs import TRACK_OPTIONS, FieldLogOptions, ManifestOverrides

    assert ManifestOverrides.__optional_keys__ == {"manifest", "window", "area", "clock_start"}
    assert ManifestOverrides.__optional_keys__ < FieldLogOptions.__optional_keys__
    assert set(typing.get_type_hints(FieldLogOptions)) == {
        *ManifestOverrides.__optional_keys__,
        *TRACK_OPTIONS,
    }
    p = write(tmp_path, "id,t_arrive,t_leave\na,1,2\nb,3,9\n", manifest="window: [0, 10]\n")
    other = tmp_path / "other.yaml"
    other.write_text("window: [0, 20]\narea: 5\n", encoding="utf-8")
    given = {"manifest": other, "window": (0.5, 12.0), "area": 7.5,
             "clock_start": "2024-05-02T07:30:00"}  # fmt: skip
    by_field, by_lifecycle = read_field_log(p, **given), read_lifecycle_log(p, **given)
    pd.testing.assert_frame_equal(by_field.table, by_lifecycle.table)
    assert by_field.window == by_lifecycle.window == (0.5, 12.0)
    assert by_field.area == by_lifecycle.area == 7.5
    assert by_field.report() == by_lifecycle.report()
    assert read_lifecycle_log(p, manifest=other).window == (0.0, 20.0)  # the manifest given
    with pytest.raises(TypeError, match=r"read_lifecycle_log\(\) got an unexpected keyword "):
        read_lifecycle_log(p, windw=(0, 1))
