"""What a scenarios folder says about its scenes, read once for every reader (issue 25):
ScenesFolder.grid, .horizon, .class_labels, .scenario_numbers, .n_moving and
.unknown_classes, checked against tables written here by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.environment import OccupancyGrid, load_catalogue, shipped_path
from are_stats.inputs import InputError
from are_stats.scenarios import SCENARIO_COLUMNS, ScenesFolder, read_scenes, write_scenes


def _table(scenarios, classes):
    """One artefact per entry, present [10, 50] s, at (1, 2)."""
    n = len(scenarios)
    cols = {
        "scenario": scenarios, "artefact": np.arange(n), "class": classes,
        "mark": np.full(n, -1), "t_arrive": np.full(n, 10.0), "t_leave": np.full(n, 50.0),
        "x": np.ones(n), "y": np.full(n, 2.0), "yaw": np.zeros(n), "truncated": np.zeros(n, bool),
        "censored": np.zeros(n, bool), "group": np.arange(n),
    }  # fmt: skip
    return pd.DataFrame({c: np.asarray(v).astype(SCENARIO_COLUMNS[c].split(",")[0])
                         for c, v in cols.items()})  # fmt: skip


def test_a_generated_folder_tells_its_map_horizon_scenarios_and_movers(tmp_path):
    df = _table([0, 2, 2], [0, 1, 0])
    df.attrs["generation"] = {"n_scenarios": 4, "horizon": 600.0}
    courtyard = shipped_path("courtyard", "map")
    tracks = pd.DataFrame(
        {"scenario": [0, 0, 2], "id": [0, 0, 1], "t": [10.0, 12.0, 10.0], "x": [1.0, 2.0, 1.0],
         "y": [2.0, 2.0, 2.0], "yaw": [0.0] * 3}
    )  # fmt: skip
    write_scenes(df, tmp_path / "s", {"map": str(courtyard)}, tracks=tracks)
    folder = read_scenes(tmp_path / "s")
    assert folder.folder == tmp_path / "s"
    assert folder.manifest_path == tmp_path / "s" / "manifest.yaml"
    assert folder.horizon == 600.0 and folder.map_file == str(courtyard)
    assert folder.scenario_numbers == [0, 1, 2, 3]  # the manifest's, empty ones included
    assert folder.n_moving == 2  # (0, 0) and (2, 1)
    grid, truth = folder.grid(), OccupancyGrid.from_ros_yaml(courtyard)
    np.testing.assert_array_equal(grid.free, truth.free)
    assert grid.origin == truth.origin and grid.resolution == truth.resolution
    art, manifest, tr = folder  # unpacks as the tuple it was
    assert art is folder.artefacts and manifest is folder.manifest and tr is folder.tracks


def test_a_hand_made_folder_has_no_horizon_map_or_movers():
    folder = ScenesFolder(_table([3, 1, 3], [0, 0, 0]), {}, None)
    assert folder.horizon is None and folder.map_file is None and folder.grid() is None
    assert folder.scenario_numbers == [1, 3]  # those of the table
    assert folder.n_moving == 0 and folder.unknown_classes(load_catalogue()) == []


def test_a_missing_map_is_refused_naming_the_manifest_unless_missing_ok(tmp_path):
    write_scenes(_table([0], [0]), tmp_path / "s", {"map": "nowhere/map.yaml"})
    folder = read_scenes(tmp_path / "s")
    with pytest.raises(InputError) as err:
        folder.grid()
    text = str(err.value)
    assert str(tmp_path / "s" / "manifest.yaml") in text and "map" in text
    assert "nowhere/map.yaml: no such file" in text and "--mesh" not in text
    with pytest.raises(InputError, match="current folder\\), or pass --mesh MESH"):
        folder.grid(or_else="pass --mesh MESH")
    assert folder.grid(missing_ok=True) is None


def test_unknown_classes_are_the_present_labels_the_catalogue_lacks():
    cat = load_catalogue()
    known = cat.labels[0]
    labels = ["forklift", known, "zeppelin", "robot dog"]
    # classes present: 0 (forklift), 1 (known), 3 (robot dog), -1 and 7 (no label):
    # zeppelin (2) is absent from the table
    folder = ScenesFolder(_table([0] * 5, [0, 1, 3, -1, 7]), {"class_labels": labels}, None)
    assert folder.unknown_classes(cat) == ["forklift", "robot dog"]
    only_known = ScenesFolder(_table([0], [1]), {"class_labels": labels}, None)
    assert only_known.unknown_classes(cat) == []


def test_class_labels_are_the_manifests_as_written_and_read_back(tmp_path):
    labels = ["person", "car", "pallet"]
    write_scenes(_table([0, 0], [2, 0]), tmp_path / "s", {"class_labels": labels})
    assert read_scenes(tmp_path / "s").class_labels == labels
    write_scenes(_table([0], [0]), tmp_path / "bare")
    assert read_scenes(tmp_path / "bare").class_labels is None


def test_the_tracks_record_follows_the_assemblys_behaviour_rule():
    from are_stats.scenarios import tracks_record

    tracks = pd.DataFrame({"t": [0.0, 2.0, 4.0]})
    grid = OccupancyGrid(np.zeros((60, 80)), 0.1)
    fitted = object()  # the rule asks only whether the fit has a behaviour
    assert tracks_record(False, fitted, tracks, grid) is None  # nothing moves: no file
    assert tracks_record(True, fitted, tracks, grid) == {"source": "fitted behaviour", "rows": 3}
    # no fitted behaviour: the catalogue's MDP on the map coarsened to whole cells,
    # 0.33 m -> 3 cells of 0.1 m
    got = tracks_record(True, None, tracks, grid, behaviour_cell=0.33, behaviour_dt=1.5)
    assert got == {"source": "catalogue behaviour", "cell_m": pytest.approx(0.3), "dt_s": 1.5,
                   "rows": 3}  # fmt: skip
    assert tracks_record("catalogue", fitted, tracks, grid)["cell_m"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="catalogue behaviours need a map"):
        tracks_record(True, None, tracks, None, cell_source="--behaviour-cell")


def test_a_generated_manifest_records_the_fit_choices_and_the_movers(tmp_path):
    from types import SimpleNamespace

    from are_stats.scenarios import generate_manifest

    df = _table([0, 1], [1, 0])
    df.attrs["generation"] = {"n_scenarios": 2, "horizon": 60.0}
    tracks = pd.DataFrame(
        {"scenario": [0, 0], "id": [0, 0], "t": [10.0, 12.0], "x": [1.0, 2.0], "y": [2.0, 2.0],
         "yaw": [0.0, 0.0]}
    )  # fmt: skip
    grid = OccupancyGrid(np.zeros((60, 80)), 0.1)
    fit = SimpleNamespace(class_labels=("person", "car"), behaviour=object())
    kw = {"fit_file": "f.nc", "map_file": "m.yaml", "seed": 3, "model": "paper"}
    manifest, kept = generate_manifest(df, tracks, fit, grid, **kw, positions="uniform",
                                       behaviours=True)  # fmt: skip
    assert kept is tracks
    assert manifest == {
        "fit": "f.nc", "model": "paper", "map": "m.yaml", "seed": 3,
        "class_labels": ["person", "car"],
        "generation": {"n_scenarios": 2, "horizon": 60.0, "positions": "uniform"},
        "tracks": {"source": "fitted behaviour", "rows": 2},
    }  # fmt: skip
    assert "positions" not in df.attrs["generation"]  # the table is left as it was
    # written and read back: the generation holds the choice, the fit's labels are the folder's
    write_scenes(df, tmp_path / "s", manifest, tracks=kept)
    folder = read_scenes(tmp_path / "s")
    assert folder.manifest["generation"]["positions"] == "uniform" and folder.horizon == 60.0
    assert folder.class_labels == ["person", "car"] and folder.n_moving == 1
    # nothing moves: no tracks section and no tracks file
    bare = SimpleNamespace(class_labels=None, behaviour=None)
    manifest, kept = generate_manifest(df, tracks[:0], bare, None, **kw, positions="chosen")
    assert kept is None and "tracks" not in manifest and manifest["class_labels"] is None
    assert manifest["map"] == "m.yaml" and manifest["generation"]["positions"] == "chosen"
