"""``--positions chosen|uniform`` of ``generate`` and ``augment`` (issue 27): a fit that
learned its entry points on one map (the courtyard) generates on another map with the
fit's arrivals and stays and the paper's uniform positions, instead of being refused or
thrown back to ``--model paper``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats.cli import app
from are_stats.environment import OccupancyGrid
from are_stats.scenarios import read_scenes
from tests.helpers import chisquare_gof

runner = CliRunner()

#: Map B: a 20 x 10 m room at 0.25 m with walls and a 3 x 2 m pillar, 100 m away from the
#: courtyard the fit learned its doors on.
ROOM_ORIGIN = (100.0, 100.0)
RES = 0.25


def _room(folder: Path, origin=ROOM_ORIGIN, shape=(40, 80), name="room") -> Path:
    h, w = shape
    img = np.full((h, w), 254, np.uint8)
    img[:2, :] = img[-2:, :] = 0
    img[:, :2] = img[:, -2:] = 0
    img[16:24, 30:42] = 0  # the pillar
    with open(folder / f"{name}.pgm", "wb") as f:
        f.write(f"P5\n{w} {h}\n255\n".encode())
        f.write(img.tobytes())
    meta = {"image": f"{name}.pgm", "resolution": RES, "origin": [*origin, 0.0],
            "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}  # fmt: skip
    (folder / f"{name}.yaml").write_text(yaml.safe_dump(meta))
    return folder / f"{name}.yaml"


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    """A fit of the shipped courtyard log with learned entries (its doors) and gamma stays
    (so that both position choices use the same sampler), and map B."""
    d = tmp_path_factory.mktemp("positions")
    fit = d / "courtyard.nc"
    res = runner.invoke(app, ["fit", "courtyard_traffic", "--out", str(fit), "--method", "em",
                              "--arrivals", "poisson", "--lifetimes", "gamma",
                              "--positions", "learned", "--samples", "50", "--warmup", "50",
                              "--chains", "2", "--no-figures", "--seed", "0"])  # fmt: skip
    assert res.exit_code == 0, res.output
    import arviz as az

    a = az.from_netcdf(fit).posterior.attrs
    assert (a["lifetime_model"], a["position_model"]) == ("gamma", "learned")
    return {"fit": fit, "room": _room(d), "dir": d}


def _generate(learned, out: Path, map_path, *extra: str, n: int = 40):
    args = ["generate", learned["fit"], "--scenarios", str(n), "--horizon", "3600", "--seed",
            "5", "--out", out, "--map", map_path, *extra]  # fmt: skip
    return runner.invoke(app, [str(a) for a in args])


def test_learned_entries_on_another_map_are_refused_naming_positions(learned):
    out = learned["dir"] / "refused"
    res = _generate(learned, out, learned["room"])
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--positions uniform" in errors[0], res.output
    assert "--model paper" in errors[0] and "Traceback" not in res.output
    # the map's file, not "map:" (the check only had the grid)
    want = f"error: {learned['room']}: expected the map the fit learned its entry points on"
    assert " ".join(res.output.split()).startswith(want), res.output
    assert not out.exists()


def test_uniform_positions_spread_over_the_other_maps_free_cells(learned):
    out = learned["dir"] / "uniform"
    res = _generate(learned, out, learned["room"], "--positions", "uniform")
    assert res.exit_code == 0, res.output
    assert "positions uniform" in res.output
    folder = read_scenes(out)
    gen = folder.manifest["generation"]
    assert gen["positions"] == "uniform" and gen["laws"]["positions"] == "uniform"
    assert gen["laws"]["lifetimes"] == "gamma"  # the fit's stays are kept
    df = folder.artefacts
    grid = OccupancyGrid.from_ros_yaml(learned["room"])
    cells = grid.world_to_cell(df[["x", "y"]].to_numpy())
    assert grid.in_bounds(cells).all()
    row, col = cells[:, 0], cells[:, 1]
    assert grid.free[row, col].all()
    # uniform over the free cells: counts in 2.5 m blocks (10 x 10 cells) against the
    # blocks' free areas, chi-square at the false-failure rate tests.helpers.ALPHA. The
    # artefacts are independent (Poisson arrivals: no groups).
    assert (df["group"].groupby([df["scenario"], df["group"]]).size() == 1).all()
    blocks_x = grid.free.shape[1] // 10
    block = (row // 10) * blocks_x + col // 10
    fr, fc = np.nonzero(grid.free)
    free_per_block = np.bincount((fr // 10) * blocks_x + fc // 10, minlength=grid.free.size // 100)
    frac = free_per_block / free_per_block.sum()
    assert len(df) > 20 * frac.size  # enough artefacts for the test

    def pmf(k):
        k = np.asarray(k)
        return np.where(k < frac.size, frac[np.minimum(k, frac.size - 1)], 0.0)

    chisquare_gof(block, pmf)


def test_uniform_positions_keep_the_chosen_arrivals_and_stays(learned):
    """Same seed, same area: ``--positions uniform`` on map B draws the arrivals, stays,
    groups and classes of ``--positions chosen`` on the fit's own map, only elsewhere."""
    a, b = learned["dir"] / "chosen_a", learned["dir"] / "uniform_b"
    res = _generate(learned, a, "courtyard", "--area", "400", n=5)
    assert res.exit_code == 0, res.output
    res = _generate(learned, b, learned["room"], "--area", "400", "--positions", "uniform", n=5)
    assert res.exit_code == 0, res.output
    da, db = read_scenes(a).artefacts, read_scenes(b).artefacts
    assert len(da) == len(db) > 0
    same = ["scenario", "artefact", "class", "mark", "t_arrive", "t_leave", "truncated", "group"]
    pd.testing.assert_frame_equal(da[same], db[same])
    assert (db["x"] > ROOM_ORIGIN[0]).all() and (da["x"] < ROOM_ORIGIN[0]).all()


def test_augment_forwards_positions_to_the_one_assembly(learned, tmp_path):
    """A 14 x 8 m room around the test bag's robot path, inside the courtyard but away from
    its doors: the learned entries are refused, ``--positions uniform`` places the bag's
    artefacts on the room's free cells."""
    from are_stats.export import augment_bag
    from tests.export.rosbag_fixtures import write_bag

    room = _room(tmp_path, origin=(-20.0, -13.0), shape=(32, 56), name="corner")
    bag = write_bag(tmp_path / "robot", "mcap")
    base = ["augment", bag, "--fit", learned["fit"], "--map", room, "--seed", "3",
            "--camera-info-topic", "/camera/camera_info"]  # fmt: skip
    res = runner.invoke(app, [str(a) for a in [*base, "--out", tmp_path / "no.mcap"]])
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--positions uniform" in errors[0], res.output
    out = tmp_path / "yes.mcap"
    res = runner.invoke(app, [str(a) for a in [*base, "--out", out, "--positions", "uniform"]])
    assert res.exit_code == 0, res.output
    got = augment_bag(bag, learned["fit"], room, tmp_path / "py.mcap", 3, positions="uniform",
                      camera_info_topic="/camera/camera_info")  # fmt: skip
    assert got.path.read_bytes() == out.read_bytes()  # the CLI is the package's
    art = got.scene.artefacts
    grid = OccupancyGrid.from_ros_yaml(room)
    cells = grid.world_to_cell(art[["x", "y"]].to_numpy())
    assert len(art) and grid.in_bounds(cells).all()
    assert grid.free[cells[:, 0], cells[:, 1]].all()


def test_an_unknown_positions_choice_is_refused_before_any_work(learned, tmp_path):
    out = tmp_path / "bad"
    res = _generate(learned, out, learned["room"], "--positions", "learned")
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--positions" in errors[0], res.output
    assert "'chosen', 'uniform'" in errors[0] and not out.exists()


def _courtyard_turned(folder: Path, yaw: float) -> Path:
    """The shipped courtyard map with its origin turned by ``yaw`` (rad)."""
    from are_stats.environment import shipped_path

    src = shipped_path("courtyard", "map")
    meta = yaml.safe_load(src.read_text())
    meta["image"] = str(src.parent / meta["image"])
    meta["origin"] = [*meta["origin"][:2], yaw]
    path = folder / f"courtyard_{yaw:g}.yaml"
    path.write_text(yaml.safe_dump(meta))
    return path


@pytest.mark.parametrize("yaw", [0.1, 1e-10])
def test_a_turned_map_is_refused_for_learned_entries_by_the_one_yaw_check(learned, yaw):
    """One check (scenarios.check_origin_yaw, 1e-12 rad) decides, whatever the yaw: the
    CLI no longer pre-checks with its own tolerance and message."""
    out = learned["dir"] / f"turned_{yaw:g}"
    turned = _courtyard_turned(learned["dir"], yaw)
    res = _generate(learned, out, turned, n=2)
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, res.output
    want = f"{turned}: expected an origin yaw of 0 for learned positions, got {yaw}"
    assert want in " ".join(res.output.split()), res.output
    assert "--positions uniform" in errors[0] and not out.exists()


def test_a_yaw_within_the_tolerance_is_no_turn(learned):
    """A yaw of 1e-13 rad (below ORIGIN_YAW_TOLERANCE) places the learned entries as on the
    unturned map: same positions, headings within 1e-12 rad."""
    a, b = learned["dir"] / "yaw_0", learned["dir"] / "yaw_1e-13"
    res = _generate(learned, a, _courtyard_turned(learned["dir"], 0.0), n=2)
    assert res.exit_code == 0, res.output
    res = _generate(learned, b, _courtyard_turned(learned["dir"], 1e-13), n=2)
    assert res.exit_code == 0, res.output
    da, db = read_scenes(a).artefacts, read_scenes(b).artefacts
    assert len(da) == len(db) > 0
    pd.testing.assert_frame_equal(da.drop(columns="yaw"), db.drop(columns="yaw"))
    turn = np.angle(np.exp(1j * (db["yaw"].to_numpy() - da["yaw"].to_numpy())))
    assert np.abs(turn).max() <= 1e-12
