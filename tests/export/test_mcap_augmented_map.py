"""The mission MCAP's ``/augmented_map`` is the AR-builder's augmented grid (issue 25:
one producer of the map), and the file's bytes are those written before the change."""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

from are_stats.builder import box_corners, rasterise_convex
from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.experiments import run_mission
from are_stats.export import export_mcap
from are_stats.scenarios import Scene

#: sha256 of the MCAP file written before ``/augmented_map`` came from the builder
#: (commit 07438ab), with the artefacts' ``/tf`` and ``/artefacts`` at 10 Hz between scene
#: updates added since (issue mcap: 893 ``/artefacts`` and 892 ``/tf`` messages added; the
#: 519 messages of 1cc67d3c... are in it byte for byte, in the same order).
WANT = "2dc03e9034cf4192f5622a32770007905179aad9bfa08db669b4ba76cd310d30"


def _mission():
    occ = np.zeros((40, 60), np.int8)
    occ[[0, -1], :] = occ[:, [0, -1]] = 100
    occ[10:30, 30] = 100
    grid = OccupancyGrid(occ, 0.5, (-1.0, -2.0, 0.0))
    art = pd.DataFrame(
        [[0.0, 60.0, 6.0, 5.0, 0.3, 0, 0], [5.0, 40.0, 9.0, 12.0, 1.1, 3, 1],
         [0.0, 90.0, 22.0, 4.0, 2.5, 1, 2], [12.0, 80.0, 4.0, 14.0, 5.9, 2, 3]],
        columns=["t_arrive", "t_leave", "x", "y", "yaw", "mark", "class"],
    )  # fmt: skip
    tracks = pd.DataFrame({
        "id": 1, "t": [5.0, 15.0, 25.0, 40.0], "x": [9.0, 11.0, 13.5, 14.0],
        "y": [12.0, 10.0, 8.5, 6.0], "yaw": [1.1, 5.5, 5.2, 4.9],
    })  # fmt: skip
    scene = Scene.from_scenarios(art, load_catalogue(), tracks)
    goals = [[2.0, 2.0], [25.0, 15.0], [3.0, 14.0]]
    res = run_mission(grid, scene, goals, "astar", record=True, time_limit=90)
    return grid, res.trace


def test_augmented_map_holds_every_live_box_and_the_bytes_are_unchanged(tmp_path):
    grid, trace = _mission()
    path = export_mcap(tmp_path / "run.mcap", grid, trace, start_time=1.7e9)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    maps = []
    with open(path, "rb") as fh:
        for _, _channel, msg in make_reader(fh).iter_messages(topics=["/augmented_map"]):
            maps.append(ts.deserialize_cdr(msg.data, "nav_msgs/msg/OccupancyGrid"))
    assert len(maps) == len(trace.scenes) >= 3
    covered = 0
    for sc, got in zip(trace.scenes, maps, strict=True):
        # every live box of the frame, rasterised: the cells its footprint covers
        want = grid.data.copy()
        poly = box_corners(sc["centres"][:, :2], sc["half"][:, :2], sc["yaws"])
        want.ravel()[rasterise_convex(grid.world_to_local(poly), grid.shape)[1]] = 100
        data = np.asarray(got.data).reshape(grid.shape)
        np.testing.assert_array_equal(data, want)
        covered += int((data == 100).sum() - (grid.data == 100).sum())
    assert covered > 0
    assert hashlib.sha256(path.read_bytes()).hexdigest() == WANT
