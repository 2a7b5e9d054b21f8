"""The one assembly fit -> scenes (scenes_from_fit) against the pieces it stands for."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats._lazy import arviz as az
from are_stats.behaviour import behaviour_tracks
from are_stats.environment import OccupancyGrid, load_catalogue, shipped_path
from are_stats.fitting import posterior_draws
from are_stats.scenarios import (
    Scene,
    generate_scenarios,
    scene_tracks,
    scenes_from_draws,
    scenes_from_fit,
)

HORIZON = 120.0


@pytest.fixture(scope="module")
def grid() -> OccupancyGrid:
    return OccupancyGrid.from_ros_yaml(shipped_path("courtyard", "map"))


@pytest.fixture(scope="module")
def catalogue():
    return load_catalogue()


def _idata(n_draws: int = 6) -> object:
    """A small paper-model fit: 2 chains of posterior draws, five classes (eq. 1)."""
    rng = np.random.default_rng(3)
    shape = (2, n_draws // 2)
    w = rng.dirichlet(np.ones(5), size=shape)
    idata = az.from_dict(
        posterior={
            "arrival_rate": rng.uniform(2e-4, 4e-4, shape),
            "leave_rate": rng.uniform(1 / 200, 1 / 100, shape),
            "mix_weights": w,
            "mix_rates": np.broadcast_to([15.0, 7, 3, 21, 5], (*shape, 5)).copy(),
        },
        dims={"mix_weights": ["component"], "mix_rates": ["component"]},
    )
    idata.posterior.attrs.update({"area": 800.0, "window": [0.0, 3600.0]})
    return idata


def _table(scenes: list[Scene]) -> pd.DataFrame:
    return pd.concat([s.artefacts for s in scenes], ignore_index=True)


def test_scenes_are_the_generated_scenarios_split_by_scenario(grid, catalogue):
    idata = _idata()
    scenes = scenes_from_fit(7, idata, grid, catalogue, 4, HORIZON)
    assert len(scenes) == 4
    want = generate_scenarios(7, posterior_draws(idata), 4, HORIZON, free_mask=grid)
    pd.testing.assert_frame_equal(_table(scenes), want.reset_index(drop=True))
    for k, s in enumerate(scenes):
        assert (s.artefacts["scenario"] == k).all()
        assert not s.has_tracks.any()  # behaviours off: everyone stands


def test_catalogue_behaviour_is_behaviour_tracks_cut_at_the_horizon(grid, catalogue):
    idata = _idata()
    scenes = scenes_from_fit(
        11, idata, grid, catalogue, 2, HORIZON, behaviours=True, interaction=False
    )
    art = generate_scenarios(11, posterior_draws(idata), 2, HORIZON, free_mask=grid)
    classes = np.concatenate(
        [Scene.from_scenarios(art[art["scenario"] == k], catalogue).classes for k in range(2)]
    )
    want = behaviour_tracks(jax.random.key(11), art, classes, grid, catalogue, horizon=HORIZON)
    got = pd.concat(
        [s.tracks_table().assign(scenario=k) for k, s in enumerate(scenes)], ignore_index=True
    )
    want = want.sort_values(["scenario", "id", "t"]).reset_index(drop=True)
    got = got.sort_values(["scenario", "id", "t"]).reset_index(drop=True)
    np.testing.assert_allclose(got[["t", "x", "y"]], want[["t", "x", "y"]])
    assert got["t"].max() <= HORIZON + 2.0  # the last epoch of dt = 2 s
    assert any(s.has_tracks.any() for s in scenes)


def test_one_posterior_draw_for_every_scene(grid, catalogue):
    idata = _idata()
    draws = posterior_draws(idata)
    scenes = scenes_from_fit(5, idata, grid, catalogue, 3, HORIZON, posterior_draw=4)
    one = {k: v[4:5] for k, v in draws.items()}
    want = generate_scenarios(5, one, 3, HORIZON, free_mask=grid)
    pd.testing.assert_frame_equal(_table(scenes), want.reset_index(drop=True))


def test_the_behaviour_rule_refuses_what_it_cannot_do(grid, catalogue):
    idata = _idata()
    with pytest.raises(ValueError, match="no behaviour group"):
        scenes_from_fit(0, idata, grid, catalogue, 1, HORIZON, behaviours="fitted")
    with pytest.raises(ValueError, match="expected one of"):
        scenes_from_fit(0, idata, grid, catalogue, 1, HORIZON, behaviours="dance")
    with pytest.raises(ValueError, match="need a map"):
        scenes_from_draws(0, posterior_draws(idata), None, catalogue, 1, HORIZON,
                          area=800.0, behaviours="catalogue")  # fmt: skip


def test_empty_scenarios_are_scenes_without_artefacts(grid, catalogue):
    idata = _idata()
    idata.posterior["arrival_rate"] = idata.posterior["arrival_rate"] * 1e-9
    scenes = scenes_from_fit(1, idata, grid, catalogue, 3, 10.0, behaviours=True, start="empty")
    assert [len(s) for s in scenes] == [0, 0, 0]


def test_with_tracks_and_tracks_table_round_trip(grid, catalogue):
    scenes = scenes_from_fit(3, _idata(), grid, catalogue, 1, HORIZON, behaviours=True)
    (scene,) = scenes
    table = scene.tracks_table()
    again = scene.with_tracks(None).with_tracks(table)
    pd.testing.assert_frame_equal(again.tracks_table(), table)
    for t in (0.0, 30.0, 90.0):
        np.testing.assert_allclose(again.poses(t), scene.poses(t))
    assert not scene.with_tracks(None).has_tracks.any()
    pd.testing.assert_frame_equal(again.artefacts, scene.artefacts)


def test_the_interaction_walks_pedestrians_again_and_keeps_vehicles_on_their_plan(grid, catalogue):
    idata = _idata()
    planned = scenes_from_fit(
        11, idata, grid, catalogue, 2, HORIZON, behaviours=True, interaction=False
    )
    walked = scenes_from_fit(11, idata, grid, catalogue, 2, HORIZON, behaviours=True)
    moved_people = 0
    for plan, scene in zip(planned, walked, strict=True):
        a, b = plan.tracks_table(), scene.tracks_table()
        pd.testing.assert_frame_equal(a[["id", "t"]], b[["id", "t"]])  # same life-cycles
        np.testing.assert_array_equal(plan.classes, scene.classes)
        kinds = [catalogue.row(int(c)).features.get("kind") for c in scene.classes]
        walker = dict(zip(scene.ids.tolist(), [k == "pedestrian" for k in kinds], strict=True))
        is_walker = a["id"].map(walker).to_numpy(bool)
        gap = np.hypot(a["x"] - b["x"], a["y"] - b["y"]).to_numpy()
        assert gap[~is_walker].max(initial=0.0) < 1e-9  # cars, carts, pallets: as planned
        moved_people += int((gap[is_walker] > 0.05).any())
        # no walker steps onto a wall cell of the map (vehicles keep their coarse-grid plans,
        # which the AR-builder's embedding tests resolve)
        row, col = np.asarray(grid.world_to_cell(b[["x", "y"]].to_numpy())).T
        assert grid.free[row[is_walker], col[is_walker]].all()
    assert moved_people >= 1


def test_arrival_groups_walk_together_in_every_assembly(grid, catalogue):
    """Groups of three (the groups arrival model) share their leader's route and walk at
    the group spacing, against independent walkers without the group column."""
    from are_stats.behaviour import SocialForce
    from are_stats.traffic import TrafficLaws

    draws = {
        "arrival_rate": np.array([3e-4]), "leave_rate": np.array([1 / 60]),
        "event_rate": np.array([1e-4]), "stay_mean": np.array([60.0]),
        "group_size_probs": np.array([[0.0, 0.0, 1.0]]),
        "mix_weights": np.array([[1.0, 0, 0, 0, 0]]),
        "mix_rates": np.array([[15.0, 7, 3, 21, 5]]),
    }  # fmt: skip
    laws = TrafficLaws(arrivals="groups")
    scene = scenes_from_draws(3, draws, grid, catalogue, 1, HORIZON, laws=laws, behaviours=True)[0]
    art, tracks = scene.artefacts, scene.tracks_table()

    def nearest(art: pd.DataFrame, tracks: pd.DataFrame) -> np.ndarray:
        out = []
        for _, part in art.groupby("group"):
            tabs = [tracks[tracks["id"] == i].set_index("t")[["x", "y"]] for i in part["artefact"]]
            times = tabs[0].index
            for tab in tabs[1:]:
                times = times.intersection(tab.index)
            xy = np.stack([tab.loc[times].to_numpy() for tab in tabs])
            d = np.hypot(*(xy[:, None] - xy[None, :]).transpose(3, 0, 1, 2))
            d[np.arange(len(tabs)), np.arange(len(tabs))] = np.inf
            out.append(d.min(axis=0).ravel())
        return np.concatenate(out)

    assert art.groupby("group").size().eq(3).all() and art["group"].nunique() >= 8
    near = nearest(art, tracks)
    assert abs(np.median(near) - SocialForce().group_spacing) < 0.1
    assert np.quantile(near, 0.9) < 2 * SocialForce().group_spacing
    # the same artefacts without their groups: everybody on its own route
    alone = scene_tracks(jax.random.key(3), art.drop(columns="group"), grid, catalogue, HORIZON)
    apart = nearest(art, alone)
    assert np.median(apart) > 2 * np.median(near)
    assert np.quantile(apart, 0.9) > 4 * np.quantile(near, 0.9)


def test_progress_counts_the_assembly_steps_to_the_end(grid, catalogue):
    idata = _idata()
    calls = []
    scenes = scenes_from_fit(
        11, idata, grid, catalogue, 2, HORIZON, behaviours=True,
        progress=lambda done, total, what: calls.append((done, total, what)),
    )  # fmt: skip
    assert [c[:2] for c in calls] == [(1, 3), (2, 3), (3, 3)]
    assert [c[2] for c in calls] == [
        "scenarios drawn", "tracks planned", "walked with the social force"
    ]  # fmt: skip
    # the same scenes as without a progress
    again = scenes_from_fit(11, idata, grid, catalogue, 2, HORIZON, behaviours=True)
    for a, b in zip(scenes, again, strict=True):
        pd.testing.assert_frame_equal(a.tracks_table(), b.tracks_table())
    calls.clear()
    scenes_from_fit(11, idata, grid, catalogue, 2, HORIZON, progress=lambda *c: calls.append(c))
    assert calls == [(1, 1, "scenarios drawn")]  # no behaviours: one step
    calls.clear()
    scenes_from_fit(11, idata, grid, catalogue, 2, HORIZON, behaviours=True, interaction=False,
                    progress=lambda *c: calls.append(c))  # fmt: skip
    assert [c[:2] for c in calls] == [(1, 2), (2, 2)]
