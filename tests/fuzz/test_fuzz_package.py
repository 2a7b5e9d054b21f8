"""Fuzz every input kind through the package entry point the CLI uses.

Each case either succeeds (and then what it returns is sane: finite where finiteness
matters) or raises ``ValueError`` / ``FileNotFoundError`` / ``FileExistsError`` naming the
input file; any other exception, a case past its time or a runaway allocation fails
(see :func:`tests.fuzz.strategies.bounded`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import strategies as st

from tests.fuzz.strategies import (
    CASE_CPU_SECONDS,
    CASE_WALL_SECONDS,
    LOG_HEADER,
    LOG_ROWS,
    MANIFEST,
    MODELS,
    PANEL_HEADER,
    PANEL_ROWS,
    ROBOT_HEADER,
    ROBOT_ROWS,
    TRACK_HEADER,
    TRACK_ROWS,
    _byte_edit,
    _csv_text,
    _dump,
    alias_bomb,
    bounded,
    csv_case,
    deep_nesting,
    expect_clean,
    file_cases,
    fit_case,
    fuzz_tiers,
    load_base_yaml,
    obj_case,
    pgm_case,
    write_case,
    write_fit_case,
    yaml_case,
)

pytestmark = pytest.mark.fuzz

MAP_YAML = load_base_yaml(MODELS / "courtyard.yaml")
CAMERA_YAML = load_base_yaml(MODELS / "cameras" / "front_camera.yaml")
CATALOGUE_YAML = load_base_yaml(MODELS / "artefacts" / "catalogue.yaml")
SWEEP_YAML = load_base_yaml(MODELS / "experiments" / "fig7.yaml")


def _names(path: Path) -> list[str]:
    return [path.name]


# ----------------------------------------------------------------------------- logs


def _check_lifecycle(log) -> None:
    data = log.to_lifecycle_data()
    log.report()
    t0, t1 = (float(v) for v in data.window)
    assert np.isfinite([t0, t1]).all() and t0 < t1, data.window
    assert np.isfinite(data.area) and data.area > 0, data.area
    ta, tl = np.asarray(data.t_arrive), np.asarray(data.t_leave)
    known = ~np.isnan(ta)
    assert (np.isfinite(ta[known]) & (ta[known] >= t0) & (ta[known] <= t1)).all()
    left = ~np.isnan(tl)
    assert (np.isfinite(tl[left]) & (tl[left] >= t0) & (tl[left] <= t1)).all()
    both = known & left
    assert (tl[both] >= ta[both]).all()
    if data.marks is not None:
        assert (np.asarray(data.marks) >= 0).all()


@fuzz_tiers(400, case=file_cases(csv_case(LOG_HEADER, LOG_ROWS)))
def test_lifecycle_log_csv(case, case_dir) -> None:
    from are_stats import read_lifecycle_log

    d = case_dir()
    (d / "log.yaml").write_text(_dump(MANIFEST))
    path = write_case(d / "log.csv", case)
    log = expect_clean(lambda: read_lifecycle_log(path), _names(path))
    if log is not None:
        expect_clean(lambda: _check_lifecycle(log), _names(path))


_PARQUET_COLUMN_VALUES = [
    [True, False],
    [2**63 - 1, -(2**62)],
    [1e30, -1e30],
    [float("nan"), float("inf")],
    ["x", "12"],
    [None, None],
    [b"\x00\xff", b""],
]


@st.composite
def _parquet_log(draw) -> bytes:
    df = pd.DataFrame(LOG_ROWS, columns=LOG_HEADER)
    for c in ("t_arrive", "t_leave", "x", "y", "yaw"):
        df[c] = pd.to_numeric(df[c])
    df["mark"] = df["mark"].astype(np.int64)
    for _ in range(draw(st.integers(1, 2))):
        col = draw(st.sampled_from(LOG_HEADER))
        values = draw(st.sampled_from(_PARQUET_COLUMN_VALUES))
        kind = draw(st.sampled_from(["column", "cell", "drop"]))
        if col not in df:
            continue
        if kind == "drop":
            df = df.drop(columns=[col], errors="ignore")
        elif kind == "column":
            df[col] = [values[i % 2] for i in range(len(df))]
        else:
            s = df[col].astype(object)
            s.iloc[draw(st.integers(0, len(df) - 1))] = values[0]
            df[col] = s
    import io

    buf = io.BytesIO()
    try:
        df.to_parquet(buf, index=False)
    except (TypeError, ValueError, OverflowError, ArithmeticError):  # pyarrow refused the mix
        buf = io.BytesIO()
        df.apply(lambda col: [str(v) for v in col]).to_parquet(buf, index=False)
    return draw(st.one_of(st.just(buf.getvalue()), _byte_edit(buf.getvalue())))


@fuzz_tiers(150, case=_parquet_log())
def test_lifecycle_log_parquet(case, case_dir) -> None:
    from are_stats import read_lifecycle_log

    d = case_dir()
    (d / "log.yaml").write_text(_dump(MANIFEST))
    path = write_case(d / "log.parquet", case)
    log = expect_clean(lambda: read_lifecycle_log(path), _names(path))
    if log is not None:
        expect_clean(lambda: _check_lifecycle(log), _names(path))


@fuzz_tiers(300, case=file_cases(yaml_case(MANIFEST)))
def test_lifecycle_manifest(case, case_dir, tiny_log) -> None:
    from are_stats import read_lifecycle_log

    d = case_dir()
    log_path = d / "log.csv"
    shutil.copy(tiny_log, log_path)
    path = write_case(d / "manifest.yaml", case)
    # a manifest without the area may be refused naming the log (area can come from the call)
    names = [path.name, log_path.name]
    log = expect_clean(lambda: read_lifecycle_log(log_path, manifest=path), names)
    if log is not None:
        expect_clean(lambda: _check_lifecycle(log), names)


@fuzz_tiers(250, case=file_cases(csv_case(PANEL_HEADER, PANEL_ROWS)))
def test_count_panel(case, case_dir) -> None:
    from are_stats import read_count_panel

    path = write_case(case_dir() / "panel.csv", case)
    out = expect_clean(lambda: read_count_panel(path), _names(path))
    if out is not None:
        t, n = out
        assert np.isfinite(t).all() and (np.diff(t) > 0).all()
        assert n.dtype == np.int64 and (n >= 0).all()


@fuzz_tiers(250, case=file_cases(csv_case(TRACK_HEADER, TRACK_ROWS)))
def test_tracks(case, case_dir) -> None:
    from are_stats import read_tracks, tracks_to_lifecycle

    path = write_case(case_dir() / "tracks.csv", case)
    df = expect_clean(lambda: read_tracks(path), _names(path))
    if df is not None:
        assert np.isfinite(df[["t", "x", "y"]].to_numpy(float)).all()
        expect_clean(lambda: tracks_to_lifecycle(df), ["tracks"])


# ----------------------------------------------------------------------------- environment


def _map_dir(d: Path) -> None:
    shutil.copy(MODELS / "courtyard.pgm", d / "courtyard.pgm")


def _check_grid(grid) -> None:
    assert np.isfinite(grid.resolution) and grid.resolution > 0
    assert np.isfinite(np.asarray(grid.origin, float)).all()
    assert np.isfinite(grid.free_area) and grid.free_area >= 0


@fuzz_tiers(200, case=file_cases(yaml_case(MAP_YAML)))
def test_map_yaml(case, case_dir) -> None:
    from are_stats import OccupancyGrid

    d = case_dir()
    _map_dir(d)
    path = write_case(d / "map.yaml", case)
    grid = expect_clean(lambda: OccupancyGrid.from_ros_yaml(path), _names(path))
    if grid is not None:
        _check_grid(grid)


@fuzz_tiers(100, case=file_cases(pgm_case((MODELS / "courtyard.pgm").read_bytes())))
def test_map_image(case, case_dir) -> None:
    from are_stats import OccupancyGrid

    d = case_dir()
    (d / "map.yaml").write_text(_dump(MAP_YAML))
    image = write_case(d / "courtyard.pgm", case)
    grid = expect_clean(
        lambda: OccupancyGrid.from_ros_yaml(d / "map.yaml"), [image.name, "map.yaml"]
    )
    if grid is not None:
        _check_grid(grid)


@fuzz_tiers(150, case=file_cases(yaml_case(CATALOGUE_YAML)))
def test_catalogue(case, case_dir) -> None:
    from are_stats import load_catalogue

    d = case_dir()
    for obj in (MODELS / "artefacts").glob("*.obj"):
        shutil.copy(obj, d / obj.name)
    path = write_case(d / "catalogue.yaml", case)
    cat = expect_clean(lambda: load_catalogue(path), _names(path))
    if cat is not None:
        for cls in cat.classes:
            ext = np.asarray(cls.property_row(0).half_extents, float)
            assert np.isfinite(ext).all() and (ext > 0).all(), (cls, ext)


@fuzz_tiers(100, case=file_cases(obj_case((MODELS / "artefacts" / "cart.obj").read_text())))
def test_mesh(case, case_dir) -> None:
    from are_stats import load_mesh

    path = write_case(case_dir() / "cart.obj", case)
    mesh = expect_clean(lambda: load_mesh(path), _names(path))
    if mesh is not None:
        assert np.isfinite(np.asarray(mesh.vertices)).all()
        faces = np.asarray(mesh.faces)
        assert faces.size == 0 or (faces.min() >= 0 and faces.max() < len(mesh.vertices))


@fuzz_tiers(250, case=file_cases(yaml_case(CAMERA_YAML)))
def test_camera(case, case_dir) -> None:
    from are_stats import PinholeCamera

    path = write_case(case_dir() / "camera.yaml", case)
    cam = expect_clean(lambda: PinholeCamera.from_yaml(path), _names(path))
    if cam is not None:
        assert cam.width > 0 and cam.height > 0
        assert cam.width * cam.height <= 2**26, "camera image sized past any real camera"
        assert np.isfinite(np.asarray(cam.pose, float)).all()


# ----------------------------------------------------------------------------- experiments


@fuzz_tiers(300, case=file_cases(yaml_case(SWEEP_YAML)))
def test_sweep_config(case, case_dir) -> None:
    from are_stats.experiments import load_sweep_config

    path = write_case(case_dir() / "sweep.yaml", case)
    expect_clean(lambda: load_sweep_config(path), _names(path))


def test_yaml_bombs_are_refused(case_dir) -> None:
    """Billion laughs and deep nesting in every YAML input: refused, named, bounded."""
    from are_stats import OccupancyGrid, PinholeCamera, load_catalogue, read_lifecycle_log
    from are_stats.experiments import load_sweep_config

    loaders = {
        "map.yaml": OccupancyGrid.from_ros_yaml,
        "camera.yaml": PinholeCamera.from_yaml,
        "catalogue.yaml": load_catalogue,
        "sweep.yaml": load_sweep_config,
        "log.yaml": lambda p: read_lifecycle_log(p.with_suffix(".csv")),
    }
    for text in (alias_bomb(), alias_bomb(12, 12), deep_nesting(100000)):
        for name, load in loaders.items():
            d = case_dir()
            (d / "log.csv").write_text(_csv_text(LOG_HEADER, LOG_ROWS))
            path = d / name
            path.write_text(text)
            limits = {"seconds": CASE_WALL_SECONDS, "cpu_seconds": CASE_CPU_SECONDS}
            with bounded(**limits), pytest.raises(ValueError) as info:
                load(path)
            assert name in str(info.value), f"{name}: the refusal does not name it: {info.value}"


# ----------------------------------------------------------------------------- fits, scenarios


@fuzz_tiers(40, case=fit_case())
def test_fit_file_to_scenarios(case, case_dir, tiny_fit) -> None:
    """``are-stats generate``'s path: read the fit, draw scenarios from it."""
    from are_stats._cli_jobs import run_generate

    d = case_dir()
    path = d / "fit.nc"
    write_fit_case(tiny_fit, path, case)
    df = expect_clean(lambda: run_generate(path, 2, 60.0, 0, d / "out"), _names(path))
    if df is not None:
        cols = ["t_arrive", "t_leave", "x", "y", "yaw"]
        assert np.isfinite(df[cols].to_numpy(float)).all(), "non-finite scenario values"


@fuzz_tiers(120, data=st.data())
def test_scenario_folder(data, case_dir, tiny_scenarios) -> None:
    from are_stats import read_scenes

    d = case_dir() / "scen"
    shutil.copytree(tiny_scenarios, d)
    which = data.draw(st.sampled_from(["manifest.yaml", "artefacts.parquet"]))
    if which == "manifest.yaml":
        base = load_base_yaml(d / which)
        case = data.draw(file_cases(yaml_case(base)))
    else:
        df = pd.read_parquet(d / which)
        col = data.draw(st.sampled_from(list(df.columns)))
        edit = data.draw(st.sampled_from(["drop", "nan", "bool", "huge", "str", "bytes"]))
        import io

        if edit == "drop":
            df = df.drop(columns=[col])
        elif edit == "nan":
            df[col] = np.nan
        elif edit == "bool":
            df[col] = True
        elif edit == "huge":
            df[col] = 2**62
        elif edit == "str":
            df[col] = "x"
        buf = io.BytesIO()
        df.to_parquet(buf, index=False)
        raw = buf.getvalue()
        case = data.draw(_byte_edit(raw)) if edit == "bytes" else raw
    (d / which).unlink()
    path = write_case(d / which, case)
    out = expect_clean(lambda: read_scenes(d), [path.name, d.name])
    if out is not None:
        df, manifest, _ = out
        assert isinstance(manifest, dict)
        for c in ("t_arrive", "t_leave", "x", "y", "yaw"):
            assert c in df, f"read_scenes returned no {c!r} column"
            assert df[c].dtype.kind == "f", f"read_scenes returned {c!r} as {df[c].dtype}"
        for c in ("t_arrive", "x", "y", "yaw"):
            assert np.isfinite(df[c].to_numpy()).all(), f"read_scenes: non-finite {c!r}"


@fuzz_tiers(12, case=file_cases(csv_case(ROBOT_HEADER, ROBOT_ROWS, max_edits=2)))
def test_robot_path(case, case_dir, tiny_scenarios) -> None:
    """``are-stats perceive``'s path with a damaged robot path (few cases: it ray-traces)."""
    from are_stats._cli_jobs import run_perceive

    d = case_dir()
    path = write_case(d / "robot.csv", case)
    expect_clean(
        lambda: run_perceive(
            tiny_scenarios,
            MODELS / "cameras" / "front_camera.yaml",
            path,
            out=d / "perceived.parquet",
        ),
        _names(path),
        seconds=120.0,
    )
