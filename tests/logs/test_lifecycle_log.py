"""Life-cycle logs: parsing, manifest, censoring semantics and every malformed-input error."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from PIL import Image

from are_stats.logs import lifecycle_log_from_frame, read_lifecycle_log, read_manifest
from tests.helpers import assert_allclose

HEADER = "id,t_arrive,t_leave,label,mark,x,y,yaw\n"
GOOD = HEADER + "a,,10,car,3,1,2,0\nb,5,,person,,1.5,1,\nc,2,4,car,1,0,0,0.5\n"


def write(tmp_path, text, name="log.csv", manifest="window: [0, 100]\narea: 50\n"):
    p = tmp_path / name
    p.write_text(text)
    if manifest is not None:
        p.with_suffix(".yaml").write_text(manifest)
    return p


def test_reads_good_log_with_censoring_semantics(tmp_path):
    log = read_lifecycle_log(write(tmp_path, GOOD))
    t = log.table
    assert list(t["id"]) == ["a", "b", "c"]
    assert t["truncated"].tolist() == [True, False, False]
    assert t["censored"].tolist() == [False, True, False]
    assert t["mark"].tolist() == [3, -1, 1]
    assert t["label"].tolist() == ["car", "person", "car"]
    assert log.window == (0.0, 100.0)
    assert log.area == 50.0
    assert t["mark"].dtype == np.int64 and t["t_arrive"].dtype == np.float64
    a = log.to_arrays()
    assert np.isnan(a["t_arrive"][0]) and np.isnan(a["t_leave"][1])
    assert a["label_names"] == ["car", "person"]
    assert a["label_codes"].tolist() == [0, 1, 0]
    assert np.isnan(a["yaw"][1])
    rep = log.report()
    assert rep["rows_used"] == 3 and rep["left_truncated"] == 1 and rep["right_censored"] == 1


def test_required_columns_only(tmp_path):
    log = read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\n1,0.5,0.7\n"))
    assert log.table["mark"].tolist() == [-1]
    assert log.table["id"].tolist() == ["1"]
    assert np.isnan(log.table["x"][0])


def test_parquet_matches_csv(tmp_path):
    csv_log = read_lifecycle_log(write(tmp_path, GOOD))
    table = pa.table(
        {
            "id": ["a", "b", "c"],
            "t_arrive": [None, 5.0, 2.0],
            "t_leave": [10.0, None, 4.0],
            "label": ["car", "person", "car"],
            "mark": pa.array([3, None, 1], type=pa.int64()),
            "x": [1.0, 1.5, 0.0],
            "y": [2.0, 1.0, 0.0],
            "yaw": [0.0, None, 0.5],
        }
    )
    p = tmp_path / "log.parquet"
    pq.write_table(table, p)
    pq_log = read_lifecycle_log(p, manifest=tmp_path / "log.yaml")
    pd.testing.assert_frame_equal(csv_log.table, pq_log.table)


def test_blank_rows_excluded_and_counted(tmp_path):
    log = read_lifecycle_log(write(tmp_path, HEADER + "a,1,2,,,,,\n,,,,,,,\n\nb,3,4,,,,,\n"))
    assert log.n_artefacts == 2
    assert log.excluded["blank_row"] == 2
    assert log.report()["rows_read"] == 4


def test_min_lifetime_excluded_and_counted(tmp_path):
    text = "id,t_arrive,t_leave\na,1,1.2\nb,1,5\nc,,0.1\n"
    log = read_lifecycle_log(
        write(tmp_path, text, manifest="window: [0, 10]\narea: 5\nmin_lifetime: 0.5\n")
    )
    assert log.table["id"].tolist() == ["b", "c"]  # truncated rows are never excluded
    assert log.excluded["shorter_than_min_lifetime"] == 1


def test_units_converted_to_seconds_and_square_metres(tmp_path):
    m = "window: [0, 2]\narea: 0.5\ntime_unit: h\narea_unit: ha\n"
    log = read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,0.5,1.5\n", manifest=m))
    assert log.window == (0.0, 7200.0)
    assert log.area == 5000.0
    assert_allclose(log.table["t_arrive"], [1800.0])
    assert_allclose(log.table["t_leave"], [5400.0])


def test_overrides_win_over_manifest(tmp_path):
    p = write(tmp_path, "id,t_arrive,t_leave\na,150,160\n")
    log = read_lifecycle_log(p, window=(100, 200), area=7.5)
    assert log.window == (100.0, 200.0) and log.area == 7.5


def test_area_from_ros_map(tmp_path):
    pix = np.full((4, 6), 254, dtype=np.uint8)  # free
    pix[0, :] = 0  # occupied
    pix[1, :2] = 205  # unknown: not free
    Image.fromarray(pix).save(tmp_path / "m.pgm")
    (tmp_path / "m.yaml").write_text(
        "image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    p = write(tmp_path, "id,t_arrive,t_leave\na,1,2\n", manifest="window: [0, 10]\nmap: m.yaml\n")
    log = read_lifecycle_log(p)
    assert log.area == pytest.approx(16 * 0.25)


def test_no_manifest_needs_window(tmp_path):
    p = write(tmp_path, "id,t_arrive,t_leave\na,1,2\n", manifest=None)
    with pytest.raises(
        ValueError, match=r"log\.yaml \(not found\): window: expected the observation"
    ):
        read_lifecycle_log(p)
    log = read_lifecycle_log(p, window=(0, 5))
    assert log.area is None


def test_from_frame_roundtrip():
    df = pd.DataFrame({"id": ["x", "y"], "t_arrive": [np.nan, 1.0], "t_leave": [2.0, np.nan]})
    log = lifecycle_log_from_frame(df, window=(0, 3), area=2.0)
    assert log.table["truncated"].tolist() == [True, False]
    with pytest.raises(ValueError, match=r"<frame>: row 2, column 't_arrive'.*outside the window"):
        lifecycle_log_from_frame(df.assign(t_arrive=[np.nan, 9.0]), window=(0, 3))


# ---- every malformed input names file, row and column -------------------------------------

BAD_CASES = [
    # (csv text, message regex)
    ("id,t_arrive\na,1\n", r"log\.csv: missing column\(s\) 't_leave': expected a life-cycle log"),
    (
        "id,t_arrive,t_leave\na,abc,3\n",
        r"log\.csv: row 1 \(line 2\), column 't_arrive': "
        r"expected a number, got 'abc'",
    ),
    (
        "id,t_arrive,t_leave\na,1,3\nb,NaN,3\n",
        r"log\.csv: row 2 \(line 3\), column 't_arrive': "
        r"expected a finite number .*got NaN",
    ),
    (
        "id,t_arrive,t_leave\na,1,inf\n",
        r"row 1 \(line 2\), column 't_leave': expected a finite "
        r"number, got inf",
    ),
    (
        "id,t_arrive,t_leave\na,5,3\n",
        r"row 1 \(line 2\), column 't_leave': expected t_leave >= "
        r"t_arrive \(5\.0\), got 3\.0 \(t_leave < t_arrive\)",
    ),
    (
        "id,t_arrive,t_leave\na,-1,3\n",
        r"row 1 \(line 2\), column 't_arrive': expected a time "
        r"inside the window \[0, 100\], got -1\.0 \(outside the window\)",
    ),
    (
        "id,t_arrive,t_leave\na,1,101\n",
        r"row 1 \(line 2\), column 't_leave': expected a time "
        r"inside the window \[0, 100\], got 101\.0 \(outside the window\)",
    ),
    (
        "id,t_arrive,t_leave\na,1,3\nb,1,3\na,2,4\n",
        r"row 3 \(line 4\), column 'id': expected a "
        r"unique id \(already used in row 1 \(line 2\)\), got duplicate id 'a'",
    ),
    (
        "id,t_arrive,t_leave,mark\na,1,3,-2\n",
        r"row 1 \(line 2\), column 'mark': expected a "
        r"non-negative integer, got -2",
    ),
    (
        "id,t_arrive,t_leave,mark\na,1,3,2.5\n",
        r"row 1 \(line 2\), column 'mark': expected a "
        r"non-negative integer, got 2\.5",
    ),
    (
        "id,t_arrive,t_leave,mark\na,1,3,many\n",
        r"row 1 \(line 2\), column 'mark': expected a "
        r"number, got 'many'",
    ),
    (
        "id,t_arrive,t_leave\n,1,3\n",
        r"row 1 \(line 2\), column 'id': expected a non-empty "
        r"identifier, got an empty cell",
    ),
    (
        "id,t_arrive,t_leave,x\na,1,3,north\n",
        r"row 1 \(line 2\), column 'x': expected a number, "
        r"got 'north'",
    ),
    ("", r"log\.csv: empty file: expected a life-cycle log with a header row"),
    (
        "id,t_arrive,t_leave\n",
        r"log\.csv: empty life-cycle log: expected a header and at least "
        r"one data row, got no data rows",
    ),
    (
        "id,t_arrive,t_leave\n,,\n",
        r"log\.csv: empty life-cycle log: expected at least one data "
        r"row, got 1 blank row",
    ),
    ("id,id,t_arrive,t_leave\na,b,1,2\n", r"log\.csv: header: expected unique column names"),
    (
        "id,t_arrive,t_leave\na,1,2\nb,1\n",
        r"log\.csv: row 2 \(line 3\): expected 3 fields "
        r"\(id, t_arrive, t_leave\), got 2",
    ),
    (
        "id,t_arrive,t_leave\na,1,2\nb,1,2,3,4\n",
        r"log\.csv: row 2 \(line 3\): expected 3 fields "
        r"\(id, t_arrive, t_leave\), got 5 \(more fields than the header",
    ),
]


@pytest.mark.parametrize(("text", "message"), BAD_CASES)
def test_malformed_csv(tmp_path, text, message):
    p = write(tmp_path, text)
    with pytest.raises(ValueError, match=message):
        read_lifecycle_log(p)


def test_malformed_parquet_nan_and_negative_mark(tmp_path):
    p = tmp_path / "log.parquet"
    (tmp_path / "log.yaml").write_text("window: [0, 100]\n")
    pq.write_table(
        pa.table({"id": ["a", "b"], "t_arrive": [1.0, float("nan")], "t_leave": [2.0, 3.0]}), p
    )
    with pytest.raises(
        ValueError,
        match=r"log\.parquet: row 2, column 't_arrive': expected a "
        r"finite number .*got NaN",
    ):
        read_lifecycle_log(p)
    pq.write_table(
        pa.table({"id": [1, 2], "t_arrive": [1.0, 2.0], "t_leave": [2.0, 3.0], "mark": [0, -4]}), p
    )
    with pytest.raises(
        ValueError,
        match=r"log\.parquet: row 2, column 'mark': expected a "
        r"non-negative integer, got -4",
    ):
        read_lifecycle_log(p)
    pq.write_table(
        pa.table(
            {
                "id": pa.array([], pa.string()),
                "t_arrive": pa.array([], pa.float64()),
                "t_leave": pa.array([], pa.float64()),
            }
        ),
        p,
    )
    with pytest.raises(ValueError, match=r"log\.parquet: empty life-cycle log"):
        read_lifecycle_log(p)


def test_missing_and_wrong_files(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nope\.csv: no such life-cycle log file"):
        read_lifecycle_log(tmp_path / "nope.csv")
    p = tmp_path / "log.json"
    p.write_text("{}")
    with pytest.raises(ValueError, match=r"log\.json: expected a life-cycle log file ending in"):
        read_lifecycle_log(p, window=(0, 1))
    q = tmp_path / "log.parquet"
    q.write_text("not parquet")
    with pytest.raises(
        ValueError,
        match=r"log\.parquet: expected a life-cycle log in Parquet "
        "format, got an unreadable file",
    ):
        read_lifecycle_log(q, window=(0, 1))


MANIFEST_CASES = [
    ("window: [0]\n", r"log\.yaml: window: expected a list of 2 values, got 1 values"),
    ("window: [5, 1]\n", r"log\.yaml: window: expected a window .* with t0 < t1"),
    ("window: [0, 1]\narea: -3\n", r"log\.yaml: area: expected a finite number > 0, got -3"),
    ("window: [0, 1]\nwindoww: 3\n", r"log\.yaml: windoww: expected one of the known keys window"),
    ("window: [0, 1]\ntime_unit: days\n", r"log\.yaml: time_unit: expected one of 's', 'ms'"),
    ("window: [0, 1]\narea: 3\nmap: m.yaml\n", r"keys 'area' and 'map': expected one of them"),
    ("window: [0, 1]\nmap: missing.yaml\n", r"missing\.yaml: (map YAML not found|no such file)"),
    ("- 1\n- 2\n", r"log\.yaml: expected a YAML mapping of manifest keys, got a list"),
    ("window: [0, 1\n", r"log\.yaml: expected a life-cycle log manifest in valid YAML"),
]


@pytest.mark.parametrize(("manifest", "message"), MANIFEST_CASES)
def test_malformed_manifest(tmp_path, manifest, message):
    p = write(tmp_path, "id,t_arrive,t_leave\na,0.1,0.2\n", manifest=manifest)
    with pytest.raises((ValueError, FileNotFoundError), match=message):
        read_lifecycle_log(p)


def test_override_errors(tmp_path):
    p = write(tmp_path, "id,t_arrive,t_leave\na,0.1,0.2\n")
    with pytest.raises(ValueError, match=r"^window: expected a window \[t0, t1\] of finite"):
        read_lifecycle_log(p, window=(1, 1))
    with pytest.raises(ValueError, match=r"^area: expected a finite number > 0, got 0"):
        read_lifecycle_log(p, area=0)
    with pytest.raises(FileNotFoundError, match=r"other\.yaml: no such manifest file"):
        read_lifecycle_log(p, manifest=tmp_path / "other.yaml")
    m = read_manifest(tmp_path / "log.yaml")
    assert m == {"window": [0, 100], "area": 50}


def test_error_row_numbers_are_unambiguous(tmp_path):
    # a blank line before the bad row: the row/line still point at the physical position
    p = write(tmp_path, HEADER + "a,1,2,,,,,\n\nb,x,2,,,,,\n")
    with pytest.raises(ValueError, match=re.escape("row 3 (line 4), column 't_arrive'")):
        read_lifecycle_log(p)


def test_to_lifecycle_data(tmp_path):
    text = "id,t_arrive,t_leave,label,mark,x,y,yaw\na,,10,car,3,1,2,0\nb,5,,person,4,1,1,0\n"
    data = read_lifecycle_log(write(tmp_path, text)).to_lifecycle_data()
    assert data.area == 50.0 and data.window == (0.0, 100.0)
    assert data.truncated.tolist() == [True, False] and data.censored.tolist() == [False, True]
    assert data.marks.tolist() == [3, 4] and data.labels.tolist() == [0, 1]
    data = read_lifecycle_log(write(tmp_path, text)).to_lifecycle_data(["person", "car"])
    assert data.labels.tolist() == [1, 0]
    with pytest.raises(ValueError, match=r"column 'label': expected one of \['car'\]"):
        read_lifecycle_log(write(tmp_path, text)).to_lifecycle_data(["car"])
    partial = "id,t_arrive,t_leave,mark\na,1,2,3\nb,1,2,\n"
    with pytest.raises(ValueError, match=r"artefact 'b', column 'mark': expected a mark on every"):
        read_lifecycle_log(write(tmp_path, partial)).to_lifecycle_data()
    bare = read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,1,2\n")).to_lifecycle_data()
    assert bare.marks is None and bare.x is None
    no_area = write(tmp_path, "id,t_arrive,t_leave\na,1,2\n", manifest="window: [0, 5]\n")
    with pytest.raises(ValueError, match=r"area: expected the free area"):
        read_lifecycle_log(no_area).to_lifecycle_data()


# ---- group and exit columns ------------------------------------------------------------

GROUPS = (
    "id,t_arrive,t_leave,group,x_exit,y_exit\n"
    "a,1,5,g7,1.5,2\n"  # group g7: a, c
    "b,1,6,,,\n"  # alone
    "c,1.1,,g7,,\n"  # still present: no exit
    "d,2,3,3,0,0\n"  # group 3: d, e (integer ids are ids)
    "e,2,4,3,0.5,0\n"
    "f,4,8,,4,4\n"  # alone
)


def test_group_and_exit_columns(tmp_path):
    log = read_lifecycle_log(write(tmp_path, GROUPS))
    t = log.table
    assert t["group"].tolist() == ["g7", "", "g7", "3", "3", ""]
    assert_allclose(t["x_exit"].to_numpy()[[0, 3, 4, 5]], [1.5, 0.0, 0.5, 4.0])
    assert np.isnan(t["x_exit"][1]) and np.isnan(t["y_exit"][2])
    assert set(log.columns) == {"id", "t_arrive", "t_leave", "group", "x_exit", "y_exit"}
    a = log.to_arrays()
    # codes in order of first appearance; every lone artefact its own code
    assert a["group"].tolist() == [0, 1, 0, 2, 2, 3]
    assert a["group"].dtype == np.int64
    rep = log.report()
    assert rep["groups"] == 2 and rep["artefacts_in_groups"] == 4
    data = log.to_lifecycle_data()
    assert data.group.tolist() == [0, 1, 0, 2, 2, 3]
    assert_allclose(data.x_exit[[0, 3]], [1.5, 0.0])
    assert np.isnan(data.y_exit[1])


def test_without_group_column_lifecycle_data_has_none(tmp_path):
    log = read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,1,2\nb,2,3\n"))
    assert log.table["group"].tolist() == ["", ""]
    assert log.to_arrays()["group"].tolist() == [0, 1]
    data = log.to_lifecycle_data()
    assert data.group is None and data.x_exit is None and data.y_exit is None
    assert log.report()["groups"] == 0 and log.report()["artefacts_in_groups"] == 0


def test_group_column_in_parquet_and_frames(tmp_path):
    p = tmp_path / "log.parquet"
    table = pa.table(
        {
            "id": ["a", "b", "c"],
            "t_arrive": [1.0, 1.0, 2.0],
            "t_leave": [2.0, 3.0, None],
            "group": pa.array([4, None, 4], pa.int64()),
            "x_exit": [1.0, None, None],
            "y_exit": [2.0, None, None],
        }
    )
    pq.write_table(table, p)
    log = read_lifecycle_log(p, window=(0, 10), area=3.0)
    assert log.table["group"].tolist() == ["4", "", "4"]
    assert log.to_lifecycle_data().group.tolist() == [0, 1, 0]
    df = pd.DataFrame(
        {"id": ["a", "b"], "t_arrive": [1.0, 2.0], "t_leave": [2.0, 3.0], "group": [None, "x"]}
    )
    assert lifecycle_log_from_frame(df, (0, 5), 1.0).table["group"].tolist() == ["", "x"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "id,t_arrive,t_leave,x_exit,y_exit\na,1,2,1,2\nb,1,2,abc,2\n",
            r"log\.csv: row 2 \(line 3\), column 'x_exit': expected a number, got 'abc'",
        ),
        (
            "id,t_arrive,t_leave,x_exit,y_exit\na,1,2,1,NaN\n",
            r"log\.csv: row 1 \(line 2\), column 'y_exit': expected a finite number",
        ),
        (
            "id,t_arrive,t_leave,x_exit,y_exit\na,1,2,1,inf\n",
            r"log\.csv: row 1 \(line 2\), column 'y_exit': expected a finite number, got inf",
        ),
        (
            "id,t_arrive,t_leave,x_exit\na,1,2,1\n",
            r"log\.csv: missing column\(s\) 'y_exit': expected a life-cycle log with exit",
        ),
    ],
)
def test_exit_column_errors(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        read_lifecycle_log(write(tmp_path, text))


def test_group_column_errors(tmp_path):
    p = tmp_path / "log.parquet"
    pq.write_table(pa.table({"id": ["a"], "t_arrive": [1.0], "t_leave": [2.0], "group": [True]}), p)
    with pytest.raises(
        ValueError, match=r"log\.parquet: row 1, column 'group': expected a non-empty identifier"
    ):
        read_lifecycle_log(p, window=(0, 5))
    q = tmp_path / "inf.parquet"
    pq.write_table(
        pa.table({"id": ["a"], "t_arrive": [1.0], "t_leave": [2.0], "group": [np.inf]}), q
    )
    with pytest.raises(ValueError, match=r"inf\.parquet: row 1, column 'group': .*got inf"):
        read_lifecycle_log(q, window=(0, 5))


# ---- clock_start -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("'2024-05-02T07:30:00'", "2024-05-02T07:30:00"),
        ("2024-05-02T07:30:00", "2024-05-02T07:30:00"),  # a YAML timestamp
        ("'2024-05-02T07:30:00+02:00'", "2024-05-02T07:30:00+02:00"),
    ],
)
def test_clock_start_in_manifest(tmp_path, value, expected):
    m = f"window: [0, 100]\narea: 50\nclock_start: {value}\n"
    log = read_lifecycle_log(write(tmp_path, GOOD, manifest=m))
    assert log.clock_start == expected
    assert log.manifest["clock_start"] == expected
    assert log.report()["clock_start"] == expected
    assert log.to_arrays()["clock_start"] == expected


def test_clock_start_override_and_absent(tmp_path):
    p = write(tmp_path, GOOD)
    assert read_lifecycle_log(p).clock_start is None
    log = read_lifecycle_log(p, clock_start="2024-05-02T00:00:00")
    assert log.clock_start == "2024-05-02T00:00:00"
    assert log.manifest["clock_start"] == "2024-05-02T00:00:00"
    with pytest.raises(ValueError, match=r"^clock_start: expected an ISO 8601 date and time"):
        read_lifecycle_log(p, clock_start="half past seven")


@pytest.mark.parametrize("value", ["'07:30 on Monday'", "'2024-13-02T07:30:00'", "3", "[1]"])
def test_clock_start_invalid_names_manifest_and_key(tmp_path, value):
    m = f"window: [0, 100]\narea: 50\nclock_start: {value}\n"
    with pytest.raises(ValueError, match=r"log\.yaml: clock_start: expected"):
        read_lifecycle_log(write(tmp_path, GOOD, manifest=m))


# ---- window tolerance: one sampling step ---------------------------------------------------


def test_window_tolerance_215_6(tmp_path):
    m = "window: [0, 215.6]\narea: 5\n"
    log = read_lifecycle_log(
        write(tmp_path, "id,t_arrive,t_leave\na,1,215.60000000000002\n", manifest=m)
    )
    assert log.table["t_leave"].tolist() == [215.6]
    data = log.to_lifecycle_data()
    assert data.t_leave.tolist() == [215.6]
    # one time_step of tolerance: 0.3 past the end is clipped, 0.5 past it is refused
    m_step = m + "time_step: 0.4\n"
    log = read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,1,215.9\n", manifest=m_step))
    assert log.table["t_leave"].tolist() == [215.6]
    with pytest.raises(ValueError, match=r"row 1 \(line 2\), column 't_leave': expected a time"):
        read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,1,216.1\n", manifest=m_step))
    # without a step, only rounding errors are tolerated
    with pytest.raises(ValueError, match=r"column 't_leave': expected a time inside"):
        read_lifecycle_log(write(tmp_path, "id,t_arrive,t_leave\na,1,215.9\n", manifest=m))
    with pytest.raises(ValueError, match=r"log\.yaml: time_step: expected a finite number > 0"):
        read_lifecycle_log(write(tmp_path, GOOD, manifest=m + "time_step: 0\n"))
    df = pd.DataFrame({"id": ["a"], "t_arrive": [-0.1], "t_leave": [215.60000000000002]})
    log = lifecycle_log_from_frame(df, (0, 215.6), 1.0, time_step=0.4)
    assert log.table["t_arrive"].tolist() == [0.0] and log.table["t_leave"].tolist() == [215.6]
