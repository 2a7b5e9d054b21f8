"""Field-log inputs under hostile-but-fair input: clean errors naming file, row and column.

Reproductions from the fuzz run of issue 13 (each with its CSV / Parquet / tracks / panel
siblings), and a hypothesis fuzz of every table reader: a mutated log either reads into
valid values or raises a ``ValueError`` naming the file, never another exception.
"""

from __future__ import annotations

import math
import string
import warnings

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from are_stats.inputs import InputError, LimitError, limits
from are_stats.logs import (
    lifecycle_log_from_frame,
    read_count_panel,
    read_lifecycle_log,
    read_manifest,
    read_tracks,
    tracks_to_lifecycle,
)

H = "id,t_arrive,t_leave,mark\n"
MANIFEST = "window: [0, 215.6]\narea: 5\n"


def write(tmp_path, text, name="log.csv", manifest=MANIFEST):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    if manifest is not None:
        p.with_suffix(".yaml").write_text(manifest, encoding="utf-8")
    return p


# ---- integers checked before the int64 cast ---------------------------------------------

TOO_LARGE = [
    ("mark", H + "a,1,2,1e30\n", r"row 1 \(line 2\), column 'mark': expected a non-negative "),
    ("mark", H + "a,1,2,9.3e18\n", r"column 'mark': .*got 9\.3e\+18 \(too large\)"),
    ("mark", H + "a,1,2,9007199254740993\n", r"column 'mark': .*\(too large\)"),
]


@pytest.mark.parametrize(("column", "text", "message"), TOO_LARGE)
def test_huge_integers_are_errors_not_wrapped(tmp_path, column, text, message):
    with pytest.raises(InputError, match=message):
        read_lifecycle_log(write(tmp_path, text))


@pytest.mark.parametrize("value", [1e30, 9.3e18, float(2**62)])
def test_huge_integers_parquet_and_panel(tmp_path, value):
    p = tmp_path / "log.parquet"
    (tmp_path / "log.yaml").write_text(MANIFEST)
    pq.write_table(pa.table({"id": ["a"], "t_arrive": [1.0], "t_leave": [2.0], "mark": [value]}), p)
    with pytest.raises(InputError, match=r"log\.parquet: row 1, column 'mark': .*too large"):
        read_lifecycle_log(p)
    c = tmp_path / "panel.csv"
    c.write_text(f"t,count\n0,1\n1,{value!r}\n")
    with pytest.raises(InputError, match=r"panel\.csv: row 2 \(line 3\), column 'count'"):
        read_count_panel(c)
    q = tmp_path / "panel.parquet"
    count = pa.array([1, min(int(value), 2**63 - 1)], pa.int64())
    pq.write_table(pa.table({"t": [0.0, 1.0], "count": count}), q)
    with pytest.raises(InputError, match=r"panel\.parquet: row 2, column 'count'.*too large"):
        read_count_panel(q)


def test_parquet_integers_are_exact(tmp_path):
    p = tmp_path / "log.parquet"
    big = 2**53 - 1
    pq.write_table(
        pa.table(
            {
                "id": pa.array([2**62 + 1, 7], pa.int64()),
                "t_arrive": [1.0, 2.0],
                "t_leave": [2.0, 3.0],
                "mark": pa.array([big, 0], pa.int64()),
            }
        ),
        p,
    )
    log = read_lifecycle_log(p, window=(0, 10))
    assert log.table["id"].tolist() == [str(2**62 + 1), "7"]
    assert log.table["mark"].tolist() == [big, 0]


# ---- field counts, BOM, encodings, long fields -------------------------------------------

CSV_SHAPE_CASES = [
    (
        H + "a,1,2,3,\nb,1,2,3,\n",
        r"log\.csv: row 1 \(line 2\): expected 4 fields \(id, t_arrive, t_leave, mark\), got 5",
    ),
    (H + "a,1,2,3\nb,1,2\n", r"row 2 \(line 3\): expected 4 fields .*got 3"),
    (
        "id,t_arrive,t_leave,mark,\na,1,2,3,\n",
        r"log\.csv: header: expected a non-empty name for every column.*field 5",
    ),
    ("a" * 200_000 + "\n", r"log\.csv: line 1: expected fields of at most 131072 characters"),
    (H + "a" * 200_000 + ",1,2,3\n", r"log\.csv: line 2: expected fields of at most"),
    (H + "a,1,2,\x00\n", r"log\.csv: line 2: expected a life-cycle log in CSV text, got a NUL"),
    ("\ufeff", r"log\.csv: empty file"),
    ("\n\n", r"log\.csv: empty file"),
]


@pytest.mark.parametrize(("text", "message"), CSV_SHAPE_CASES)
def test_csv_shape_errors(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        read_lifecycle_log(write(tmp_path, text))


def test_csv_shape_errors_in_tracks_and_panels(tmp_path):
    p = tmp_path / "tr.csv"
    p.write_text("id,t,x,y\na,0,1,2,9\n")
    with pytest.raises(ValueError, match=r"tr\.csv: row 1 \(line 2\): expected 4 fields"):
        read_tracks(p)
    q = tmp_path / "panel.csv"
    q.write_text("t,count\n0,1,\n")
    with pytest.raises(ValueError, match=r"panel\.csv: row 1 \(line 2\): expected 2 fields"):
        read_count_panel(q)


def test_not_utf8(tmp_path):
    p = tmp_path / "log.csv"
    p.write_bytes(H.encode() + b"a,1,2,\xff\n")
    (tmp_path / "log.yaml").write_text(MANIFEST)
    with pytest.raises(
        ValueError, match=r"log\.csv: line 2: expected .* UTF-8 text, got byte 0xff"
    ):
        read_lifecycle_log(p)


def test_bom_is_accepted(tmp_path):
    log = read_lifecycle_log(write(tmp_path, "\ufeff" + H + "a,1,2,3\n"))
    assert log.table["id"].tolist() == ["a"] and log.table["mark"].tolist() == [3]
    p = tmp_path / "tr.csv"
    p.write_text("\ufeffid,t,x,y\na,0,1,2\n", encoding="utf-8")
    assert read_tracks(p)["id"].tolist() == ["a"]


def test_quoted_newline_row_names_its_first_line(tmp_path):
    p = write(tmp_path, H + 'a,1,2,3\n"b\nc",1,2,x\n')
    with pytest.raises(InputError, match=r"row 2 \(line 3\), column 'mark'"):
        read_lifecycle_log(p)


# ---- booleans are never numbers ----------------------------------------------------------


def _bool_tables(tmp_path):
    pq.write_table(pa.table({"id": ["a"], "t_arrive": [True], "t_leave": [2.0]}), tmp_path / "t.pq")
    pq.write_table(
        pa.table({"id": ["a"], "t_arrive": [1.0], "t_leave": [2.0], "mark": [True]}),
        tmp_path / "m.pq",
    )
    pq.write_table(pa.table({"id": [True], "t_arrive": [1.0], "t_leave": [2.0]}), tmp_path / "i.pq")
    pq.write_table(pa.table({"t": [0.0, 1.0], "count": [True, False]}), tmp_path / "c.pq")
    pq.write_table(
        pa.table({"id": ["a"], "t": [False], "x": [0.0], "y": [0.0]}), tmp_path / "tr.pq"
    )


BOOL_CASES = [
    (lambda d: read_lifecycle_log(d / "t.pq", window=(0, 5)), r"t\.pq: row 1, column 't_arrive'"),
    (lambda d: read_lifecycle_log(d / "m.pq", window=(0, 5)), r"m\.pq: row 1, column 'mark'"),
    (lambda d: read_lifecycle_log(d / "i.pq", window=(0, 5)), r"i\.pq: row 1, column 'id'"),
    (lambda d: read_count_panel(d / "c.pq"), r"c\.pq: row 1, column 'count'"),
    (lambda d: read_tracks(d / "tr.pq"), r"tr\.pq: row 1, column 't'"),
    (
        lambda d: lifecycle_log_from_frame(
            pd.DataFrame({"id": ["a"], "t_arrive": [True], "t_leave": [2.0]}), window=(0, 5)
        ),
        r"<frame>: row 1, column 't_arrive'",
    ),
    (
        lambda d: lifecycle_log_from_frame(
            pd.DataFrame({"id": ["a", "b"], "t_arrive": [1.0, True], "t_leave": [2.0, 3.0]}).astype(
                object
            ),
            window=(0, 5),
        ),
        r"<frame>: row 2, column 't_arrive'",
    ),
    (
        lambda d: tracks_to_lifecycle(
            pd.DataFrame({"id": ["a"], "t": [1.0], "x": [True], "y": [0.0]})
        ),
        r"tracks: row 1, column 'x'",
    ),
]


@pytest.mark.parametrize(("call", "message"), BOOL_CASES)
def test_booleans_are_not_numbers(tmp_path, call, message):
    _bool_tables(tmp_path)
    with pytest.raises(InputError, match=message + r": expected .*got a boolean \((True|False)"):
        call(tmp_path)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: lifecycle_log_from_frame(
                pd.DataFrame({"id": ["a"], "t_arrive": [1.0], "t_leave": [2.0]}), (False, 5)
            ),
            r"^window: t0: expected a finite number, got False \(a bool\)",
        ),
        (
            lambda: tracks_to_lifecycle(
                pd.DataFrame({"id": ["a"], "t": [1.0], "x": [0.0], "y": [0.0]}),
                gap_tolerance=True,
            ),
            r"^gap_tolerance: expected a finite number >= 0, got True \(a bool\)",
        ),
        (
            lambda: tracks_to_lifecycle(
                pd.DataFrame({"id": ["a"], "t": [1.0], "x": [0.0], "y": [0.0]}),
                min_sightings=2.5,
            ),
            r"^min_sightings: expected an integer >= 1, got 2\.5",
        ),
    ],
)
def test_boolean_and_fractional_arguments(call, message):
    with pytest.raises(InputError, match=message):
        call()


# ---- manifests ---------------------------------------------------------------------------

BOMB = "".join(
    f"{n}: &{n} [{', '.join([f'*{p}'] * 9) if p else ', '.join(['1'] * 9)}]\n"
    for p, n in zip(
        ["", "a", "b", "c", "d", "e", "f"], ["a", "b", "c", "d", "e", "f", "g"], strict=True
    )
)

MANIFEST_CASES = [
    ("window: {t0: 0, t1: 10}\n", r"log\.yaml: window: expected a list of 2 values, got a mapping"),
    ("window: [0, 10]\narea: yes\n", r"log\.yaml: area: expected a finite number > 0, got True"),
    ("window: [0, 10]\narea: .inf\n", r"log\.yaml: area: expected a finite number > 0, got inf"),
    ("window: [0, 10]\narea: 1e400\n", r"log\.yaml: area: expected a finite number > 0"),
    ("window: [0, 10]\nwindow: [0, 5]\n", r"log\.yaml: line 2: expected each key once"),
    ("window: [0, 10]\nfoo: 1\n", r"log\.yaml: foo: expected one of the known keys window, area"),
    ("window: [true, 10]\n", r"log\.yaml: window\[0\]: expected a finite number, got True"),
    ("window: ['0', 10]\n", r"log\.yaml: window\[0\]: expected a finite number, got '0'"),
    ("window: [0, .nan]\n", r"log\.yaml: window\[1\]: expected a finite number"),
    ("window: [0, 10]\nmin_lifetime: -1\n", r"log\.yaml: min_lifetime: expected a finite number"),
    ("window: [0, 1e308]\ntime_unit: h\n", r"log\.yaml: window: expected a window that stays"),
    ("window: [0, 10]\ndescription: [a]\n", r"log\.yaml: description: expected a string"),
    ("window: [0, 10]\nmap: 5\n", r"log\.yaml: map: expected a string, got 5"),
    ("window: [0, 10]\narea_unit: acre\n", r"log\.yaml: area_unit: expected one of 'm\^2'"),
    (BOMB, r"log\.yaml: expected YAML that expands to at most"),
]


@pytest.mark.parametrize(("manifest", "message"), MANIFEST_CASES)
def test_manifest_values_strict(tmp_path, manifest, message):
    p = write(tmp_path, H + "a,1,2,3\n", manifest=manifest)
    with pytest.raises(ValueError, match=message):
        read_lifecycle_log(p)


def test_manifest_that_is_a_directory(tmp_path):
    p = write(tmp_path, H + "a,1,2,3\n", manifest=None)
    with pytest.raises(InputError, match=r"expected a life-cycle log manifest, got a directory"):
        read_lifecycle_log(p, manifest=tmp_path)
    (tmp_path / "log.yaml").mkdir()  # the default manifest beside the log
    with pytest.raises(InputError, match=r"log\.yaml: expected a life-cycle log manifest"):
        read_lifecycle_log(p)


def test_manifest_numbers_read_as_floats(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("window: [0, 1e3]\narea: 2.5e2\n")
    assert read_manifest(p) == {"window": [0.0, 1000.0], "area": 250.0}


# ---- window edges: rounding tolerance, clipped -------------------------------------------


def test_times_a_rounding_error_outside_the_window_are_clipped(tmp_path):
    log = read_lifecycle_log(write(tmp_path, H + "a,-1e-13,215.60000000000002,3\n"))
    assert log.table["t_leave"].tolist() == [215.6]
    assert log.table["t_arrive"].tolist() == [0.0]
    with pytest.raises(InputError, match=r"column 't_leave': expected a time inside the window"):
        read_lifecycle_log(write(tmp_path, H + "a,1,215.61,3\n"))
    # units: milliseconds scaled to seconds keep the tolerance
    ms = "window: [0, 215600]\ntime_unit: ms\narea: 5\n"
    log = read_lifecycle_log(write(tmp_path, H + "a,0,215600.00000000003,3\n", manifest=ms))
    assert log.table["t_leave"].tolist() == [215.6]


# ---- zero-length stays -------------------------------------------------------------------


def test_single_sightings_stay_one_sampling_step():
    tr = pd.DataFrame({"id": ["a", "b", "b"], "t": [5.0, 4.0, 6.0], "x": [9.0, 0.0, 0.0], "y": 0.0})
    out = tracks_to_lifecycle(tr, window=(0, 10), gap_tolerance=3.0)
    a = out.set_index("id").loc["a"]
    # the sampling step is b's 2 s: a single sighting stays one step, never zero
    assert a.t_arrive == 5.0 and a.t_leave == 7.0 and a.n_sightings == 1
    log = lifecycle_log_from_frame(out, window=(0, 10), area=1.0)
    assert log.n_artefacts == 2
    assert (log.to_lifecycle_data().dwell > 0).all()
    short = tracks_to_lifecycle(tr, window=(0, 10), gap_tolerance=3.0, min_sightings=2)
    assert short["id"].tolist() == ["b"] and short.attrs["excluded"]["too_few_sightings"] == 1


# ---- memory limit ------------------------------------------------------------------------


def test_memory_limit_checked_before_reading(tmp_path):
    p = write(tmp_path, H + "".join(f"a{i},1,2,3\n" for i in range(50)))
    q = tmp_path / "log.parquet"
    pq.write_table(
        pa.table({"id": ["a"] * 100, "t_arrive": [1.0] * 100, "t_leave": [2.0] * 100}), q
    )
    with limits(memory="1K"):
        with pytest.raises(
            LimitError, match=r"log\.csv: expected parsing the life-cycle log to fit"
        ):
            read_lifecycle_log(p)
        with pytest.raises(LimitError, match=r"log\.parquet: expected reading the life-cycle log"):
            read_lifecycle_log(q)
    assert read_lifecycle_log(p, window=(0, 5)).n_artefacts == 50


# ---- fuzz --------------------------------------------------------------------------------

EXAMPLE = (
    "id,t_arrive,t_leave,label,mark,x,y,yaw\n"
    "a0,,198.9,pallet,20,-7.6,6.1,4.8\n"
    "a1,3.5,19.5,cart,6,4.0,-8.4,4.3\n"
    "a2,10,,child,5,4.5,-2.5,3.4\n"
)
TRACKS = "id,t,x,y,label,yaw\na,0,1,2,car,0.1\na,0.5,1,2,car,\nb,1,0,0,,0.2\n"
PANEL = "t,count\n0,1\n1,2\n2.5,0\n"
CELLS = st.sampled_from(
    ["", "nan", "inf", "-inf", "1e30", "9.3e18", "True", "-0", "1e-400", "0x10", "'", '"',
     '"a,b"', " ", "1_000", "\u0663", "+5", ".5", "1e308", "NA", "\ufeff", "\u00e9", "2**3"]
)  # fmt: skip


@st.composite
def mutated(draw, text):
    lines = text.split("\n")
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.integers(0, 6))
        i = draw(st.integers(0, len(lines) - 1))
        fields = lines[i].split(",")
        if op == 0:
            fields[draw(st.integers(0, len(fields) - 1))] = draw(CELLS)
        elif op == 1:
            fields.append(draw(CELLS))
        elif op == 2 and len(fields) > 1:
            fields.pop(draw(st.integers(0, len(fields) - 1)))
        elif op == 3:
            lines.insert(i, draw(st.text(string.printable + "\u00e9\ufeff\x00", max_size=20)))
        elif op == 4:
            return "\n".join(lines)[: draw(st.integers(0, len("\n".join(lines))))]
        elif op == 5:
            fields[draw(st.integers(0, len(fields) - 1))] = draw(
                st.floats(allow_nan=True, allow_infinity=True).map(repr)
            )
        lines[i] = ",".join(fields)
    return "\n".join(lines)


FUZZ = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@FUZZ
@given(text=mutated(EXAMPLE), manifest=st.sampled_from([MANIFEST, "window: [0, 300]\n"]))
def test_fuzz_lifecycle_log(tmp_path, text, manifest):
    p = write(tmp_path, text, manifest=manifest)
    try:
        log = read_lifecycle_log(p)
    except ValueError as err:
        assert str(err).startswith(str(p))
        return
    t = log.table
    t0, t1 = log.window
    for c in ("t_arrive", "t_leave"):
        v = t[c].to_numpy()
        assert np.all(np.isnan(v) | ((v >= t0) & (v <= t1)))
    assert (t["mark"] >= -1).all() and (t["mark"] <= 2**53).all()
    assert all(math.isfinite(v) or math.isnan(v) for v in t[["x", "y", "yaw"]].to_numpy().ravel())


@FUZZ
@given(text=mutated(TRACKS))
def test_fuzz_tracks(tmp_path, text):
    p = tmp_path / "tr.csv"
    p.write_text(text, encoding="utf-8")
    try:
        tr = read_tracks(p)
    except ValueError as err:
        assert str(err).startswith(str(p))
        return
    assert np.isfinite(tr[["t", "x", "y"]].to_numpy()).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # mutated tracks may split
        out = tracks_to_lifecycle(tr)
    assert (out["n_sightings"] >= 1).all()
    both = out["t_arrive"].notna() & out["t_leave"].notna()
    assert (out["t_leave"][both] > out["t_arrive"][both]).all()  # never a zero stay


@FUZZ
@given(text=mutated(PANEL))
def test_fuzz_count_panel(tmp_path, text):
    p = tmp_path / "panel.csv"
    p.write_text(text, encoding="utf-8")
    try:
        t, n = read_count_panel(p)
    except ValueError as err:
        assert str(err).startswith(str(p))
        return
    assert np.isfinite(t).all() and (np.diff(t) > 0).all()
    assert n.dtype == np.int64 and (n >= 0).all()


def test_special_files_are_refused_not_read(tmp_path):
    import os

    fifo = tmp_path / "log.yaml"
    os.mkfifo(fifo)  # reading it would block forever
    p = write(tmp_path, H + "a,1,2,3\n", manifest=None)
    with pytest.raises(InputError, match=r"log\.yaml: expected a life-cycle log manifest file"):
        read_lifecycle_log(p)
    table = tmp_path / "fifo.csv"
    os.mkfifo(table)
    with pytest.raises(ValueError, match=r"fifo\.csv: expected a life-cycle log file .*special"):
        read_lifecycle_log(table, window=(0, 5))


def test_label_names_checked(tmp_path):
    text = "id,t_arrive,t_leave,label,mark\na,1,2,car,3\nb,1,2,person,4\n"
    log = read_lifecycle_log(write(tmp_path, text))
    assert log.to_lifecycle_data(np.array(["person", "car"])).labels.tolist() == [1, 0]
    with pytest.raises(InputError, match=r"^label_names: \[1\]: expected a string, got 3"):
        log.to_lifecycle_data(["car", 3])
    with pytest.raises(InputError, match=r"^label_names: expected distinct class labels"):
        log.to_lifecycle_data(["car", "car", "person"])
    with pytest.raises(InputError, match=r"^label_names: expected a list"):
        log.to_lifecycle_data("car")


@pytest.mark.parametrize(
    "column",
    [
        pa.array([1, 2], pa.timestamp("s")),
        pa.array([[1.0], [2.0]], pa.list_(pa.float64())),
        pa.array([{"a": 1.0}, {"a": 2.0}]),
        pa.array([b"\x00\xff", b"1"], pa.binary()),
        pa.nulls(2),
        pa.array(["1", "2"]).dictionary_encode(),
        pa.array(np.array([1, 2], np.float16)),
        pa.array([1, 2**64 - 1], pa.uint64()),
    ],
    ids=["timestamp", "list", "struct", "binary", "null", "dictionary", "float16", "uint64"],
)
def test_parquet_column_types(tmp_path, column):
    p = tmp_path / "log.parquet"
    pq.write_table(pa.table({"id": ["a", "b"], "t_arrive": column, "t_leave": [3.0, 4.0]}), p)
    try:
        log = read_lifecycle_log(p, window=(0, 5))
    except ValueError as err:
        assert str(err).startswith(f"{p}: ")
    else:
        v = log.table["t_arrive"].to_numpy()
        assert np.all(np.isnan(v) | ((v >= 0) & (v <= 5)))


def test_labels_with_commas_are_refused_at_the_row(tmp_path):
    """Fit files list class labels comma-separated: a comma in a label is refused where
    the log enters (it used to fail late, inside the fit)."""

    from are_stats.environment import shipped_path

    src = shipped_path("courtyard_traffic", "log").read_text().splitlines()
    label = src[0].split(",").index("label")
    cells = src[3].split(",")
    cells[label] = '"a,b"'
    src[3] = ",".join(cells)
    (tmp_path / "log.csv").write_text("\n".join(src) + "\n")
    (tmp_path / "log.yaml").write_text("window: [0, 3600]\narea: 400\n")
    with pytest.raises(ValueError, match=r"log.csv: row 3 \(line 4\).*'label'.*without commas"):
        read_lifecycle_log(tmp_path / "log.csv")
