"""Shipped data (are_stats/data) and the name-or-path rule of resolve_shipped."""

from __future__ import annotations

from pathlib import Path

import pytest

import are_stats
from are_stats.environment import (
    DEFAULT_MODELS,
    SHIPPED_DATA,
    SHIPPED_KINDS,
    load_catalogue,
    resolve_shipped,
    shipped_names,
    shipped_path,
)
from are_stats.inputs import InputError

#: The names the defaults, the docs and the README use.
NAMES = {
    "map": ["courtyard"],
    "catalogue": ["catalogue"],
    "camera": ["front_camera"],
    "log": ["courtyard_traffic"],
    "experiment": ["fig7", "fig7_fit"],
}


def test_shipped_data_is_inside_the_package_and_small():
    package = Path(are_stats.__file__).resolve().parent
    assert SHIPPED_DATA.resolve() == package / "data" and DEFAULT_MODELS == SHIPPED_DATA
    files = [p for p in SHIPPED_DATA.rglob("*") if p.is_file()]
    assert sum(p.stat().st_size for p in files) < 512 * 1024
    for kind, names in NAMES.items():
        assert shipped_names(kind) == names
        for name in names:
            assert shipped_path(name, kind).is_file()
    assert set(SHIPPED_KINDS) == set(NAMES)
    # what the shipped files name beside them is shipped too
    assert shipped_path("courtyard", "map").with_suffix(".pgm").is_file()
    assert shipped_path("courtyard", "map").with_suffix(".ply").is_file()
    assert shipped_path("courtyard_traffic", "log").with_suffix(".yaml").is_file()
    assert load_catalogue(shipped_path("catalogue", "catalogue")).labels == load_catalogue().labels


def test_a_user_file_wins_over_a_shipped_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "courtyard").write_text("mine")
    assert resolve_shipped("courtyard", "map") == Path("courtyard")
    # a folder of that name is not a file: the shipped map
    (tmp_path / "front_camera").mkdir()
    assert resolve_shipped("front_camera", "camera") == shipped_path("front_camera", "camera")


def test_relative_paths_resolve_against_base(tmp_path):
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "site.yaml").write_text("x")
    got = resolve_shipped("maps/site.yaml", "map", base=tmp_path)
    assert got == (tmp_path / "maps" / "site.yaml").resolve()
    # a missing path with a folder or a suffix is left to its reader to report
    assert resolve_shipped("maps/none.yaml", "map", base=tmp_path) == tmp_path / "maps/none.yaml"
    assert resolve_shipped("none.yaml", "map") == Path("none.yaml")


def test_an_unknown_name_lists_the_shipped_ones(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=r"--map: expected .* shipped map \(courtyard\).*'yard'"):
        resolve_shipped("yard", "map", source="--map")
    with pytest.raises(InputError, match=r"sweep\.yaml: catalogue: .*\(catalogue\)"):
        resolve_shipped("default", "catalogue", source="sweep.yaml", where="catalogue")
    with pytest.raises(InputError, match=r"shipped experiment names \(fig7, fig7_fit\)"):
        shipped_path("fig8", "experiment")
    with pytest.raises(InputError, match="one of map, catalogue, camera, log, experiment"):
        shipped_names("mesh")


def test_read_map_takes_a_file_or_a_shipped_name_and_names_its_option(tmp_path):
    import numpy as np

    from are_stats.environment import OccupancyGrid, read_map

    path, grid = read_map("courtyard")
    assert path == shipped_path("courtyard", "map")
    truth = OccupancyGrid.from_ros_yaml(path)
    np.testing.assert_array_equal(grid.data, truth.data)
    assert (grid.resolution, grid.origin) == (truth.resolution, truth.origin)
    copy = tmp_path / "courtyard.yaml"  # a file of that name wins over the shipped map
    truth.to_ros_yaml(copy)
    assert read_map(copy)[0] == copy
    with pytest.raises(InputError, match=r"^MAP: .*courtyard") as err:
        read_map("no_such_map", source="MAP")
    assert "no_such_map" in str(err.value)
