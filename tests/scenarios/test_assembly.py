"""The one assembly fit -> scenes (scenes_from_fit) against the pieces it stands for."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import behaviour_tracks
from are_stats.builder import ARBuilder
from are_stats.environment import OccupancyGrid
from are_stats.fitting import Fit, posterior_draws
from are_stats.scenarios import (
    Scene,
    generate_scenarios,
    scene_tracks,
    scenes_from_fit,
)
from tests.scenarios.test_assembly_golden import WANT, _idata, _scenes_digest

HORIZON = 120.0


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


@pytest.fixture(scope="module")
def catalogue_plan(grid, catalogue) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Two scenarios of :func:`_idata` (seed 11) and the catalogue behaviour's plans of
    their artefacts (key 11): what the assembly's scenes are compared against below."""
    art = generate_scenarios(11, posterior_draws(_idata()), 2, HORIZON, free_mask=grid)
    classes = np.concatenate(
        [Scene.from_scenarios(art[art["scenario"] == k], catalogue).classes for k in range(2)]
    )
    plan = behaviour_tracks(jax.random.key(11), art, classes, grid, catalogue, horizon=HORIZON)
    return art, plan


@pytest.fixture(scope="module")
def walked_progress(grid, catalogue) -> tuple[list[Scene], list[tuple]]:
    """The same two scenes assembled with the catalogue behaviour and the interaction, and
    the progress calls of that assembly (test_assembly_golden pins these scenes as
    assembled without a progress)."""
    calls: list[tuple] = []
    scenes = scenes_from_fit(
        11, _idata(), grid, catalogue, 2, HORIZON, behaviours=True,
        progress=lambda done, total, what: calls.append((done, total, what)),
    )  # fmt: skip
    return scenes, calls


@pytest.fixture(scope="module")
def walked(walked_progress) -> list[Scene]:
    """The scenes of :func:`walked_progress`."""
    return walked_progress[0]


@pytest.fixture(scope="module")
def unwalked(grid, catalogue) -> tuple[list[Scene], list[tuple]]:
    """The same two scenes assembled with the catalogue behaviour without the interaction,
    and the progress calls of that assembly (one assembly for both tests that need it;
    test_assembly_golden pins these scenes as assembled without a progress)."""
    calls: list[tuple] = []
    scenes = scenes_from_fit(
        11, _idata(), grid, catalogue, 2, HORIZON, behaviours=True, interaction=False,
        progress=lambda *c: calls.append(c),
    )  # fmt: skip
    return scenes, calls


def test_catalogue_behaviour_is_behaviour_tracks_cut_at_the_horizon(
    grid, catalogue, catalogue_plan, unwalked
):
    """Without the interaction, the scenes' tracks are the catalogue behaviour's, cut at
    the horizon, with every mover's collisions resolved by the AR-builder's rule
    (DECISIONS 9) on open ground (the routes keep to free cells)."""
    scenes, _ = unwalked
    art, plan = catalogue_plan
    ground = OccupancyGrid(np.zeros((160, 160), np.int8), 0.5, (-40.0, -40.0, 0.0))
    builder = ARBuilder(ground)
    want, waited = [], 0
    for k in range(2):
        planned = Scene.from_scenarios(
            art[art["scenario"] == k], catalogue, plan[plan["scenario"] == k]
        )
        moving = np.array(
            [np.ptp(planned.track(i)[1][:, :2], axis=0).max(initial=0.0) > 1e-9
             for i in range(len(planned))]
        )  # fmt: skip
        resolved = builder.resolve_scene(planned, moving, others=~moving)
        waited += len({r.artefact for r in builder.log})
        want.append(resolved.tracks_table().assign(scenario=k))
    want = pd.concat(want, ignore_index=True)
    got = pd.concat(
        [s.tracks_table().assign(scenario=k) for k, s in enumerate(scenes)], ignore_index=True
    )
    want = want.sort_values(["scenario", "id", "t"]).reset_index(drop=True)
    got = got.sort_values(["scenario", "id", "t"]).reset_index(drop=True)
    np.testing.assert_allclose(got[["t", "x", "y"]], want[["t", "x", "y"]])
    assert got["t"].max() <= HORIZON + 2.0  # the last epoch of dt = 2 s
    assert any(s.has_tracks.any() for s in scenes)
    assert waited > 0  # some movers did meet


def test_one_posterior_draw_for_every_scene(grid, catalogue):
    idata = _idata()
    draws = posterior_draws(idata)
    scenes = scenes_from_fit(5, idata, grid, catalogue, 3, HORIZON, posterior_draw=4)
    one = {k: v[4:5] for k, v in draws.items()}
    want = generate_scenarios(5, one, 3, HORIZON, free_mask=grid)
    pd.testing.assert_frame_equal(_table(scenes), want.reset_index(drop=True))


def test_an_unknown_positions_choice_names_the_option(grid, catalogue):
    from are_stats.inputs import InputError

    with pytest.raises(InputError, match=r"--positions: expected one of 'chosen', 'uniform'"):
        scenes_from_fit(7, _idata(), grid, catalogue, 1, HORIZON, positions="learned")


def test_the_behaviour_rule_refuses_what_it_cannot_do(grid, catalogue):
    idata = _idata()
    with pytest.raises(ValueError, match="no behaviour group"):
        scenes_from_fit(0, idata, grid, catalogue, 1, HORIZON, behaviours="fitted")
    with pytest.raises(ValueError, match="expected one of"):
        scenes_from_fit(0, idata, grid, catalogue, 1, HORIZON, behaviours="dance")
    with pytest.raises(ValueError, match="need a map"):
        scenes_from_fit(0, Fit.from_draws(posterior_draws(idata)), None, catalogue, 1, HORIZON,
                        area=800.0, behaviours="catalogue")  # fmt: skip


def test_errors_name_where_the_fit_came_from(catalogue):
    """A Fit passed without ``source`` is named by its own (the file read_fit read, the
    ``source`` given to Fit.from_draws), not "fit"; a ``source`` given wins."""
    from are_stats.inputs import InputError

    draws = posterior_draws(_idata())
    read = Fit.from_draws(draws, source="courtyard_fit.nc")  # read_fit's: source=str(path)
    with pytest.raises(InputError, match=r"^courtyard_fit\.nc: posterior\.attrs\.area: "):
        scenes_from_fit(0, read, None, catalogue, 1, HORIZON)
    with pytest.raises(ValueError, match=r"^courtyard_fit\.nc: catalogue behaviours need a map"):
        scenes_from_fit(0, read, None, catalogue, 1, HORIZON, area=800.0, behaviours="catalogue")
    with pytest.raises(InputError, match=r"^draws: posterior\.attrs\.area: "):
        scenes_from_fit(0, Fit.from_draws(draws), None, catalogue, 1, HORIZON)
    with pytest.raises(InputError, match=r"^--fit: posterior\.attrs\.area: "):
        scenes_from_fit(0, read, None, catalogue, 1, HORIZON, source="--fit")


def test_empty_scenarios_are_scenes_without_artefacts(grid, catalogue):
    idata = _idata()
    idata.posterior["arrival_rate"] = idata.posterior["arrival_rate"] * 1e-9
    scenes = scenes_from_fit(1, idata, grid, catalogue, 3, 10.0, behaviours=True, start="empty")
    assert [len(s) for s in scenes] == [0, 0, 0]


def test_the_catalogue_scenes_are_the_pinned_ones(walked, unwalked):
    """The catalogue behaviour's two scenes with and without the interaction are those
    test_assembly_golden pins (its own tests of these digests assemble the same scenes
    again, in the slow tier); both were assembled with a progress and are pinned as
    assembled without one: the progress changes nothing."""
    assert any(s.has_tracks.any() for s in walked)
    assert _scenes_digest(walked) == WANT["catalogue"]
    assert any(s.has_tracks.any() for s in unwalked[0])
    assert _scenes_digest(unwalked[0]) == WANT["catalogue, no interaction"]


def test_with_tracks_and_tracks_table_round_trip(walked):
    scene = walked[0]
    assert scene.has_tracks.any()
    table = scene.tracks_table()
    again = scene.with_tracks(None).with_tracks(table)
    pd.testing.assert_frame_equal(again.tracks_table(), table)
    for t in (0.0, 30.0, 90.0):
        np.testing.assert_allclose(again.poses(t), scene.poses(t))
    assert not scene.with_tracks(None).has_tracks.any()
    pd.testing.assert_frame_equal(again.artefacts, scene.artefacts)


def _off_route(xy: np.ndarray, route: np.ndarray) -> float:
    """Largest distance (m) from the points ``xy`` (n, 2) to the polyline ``route`` (m, 2)."""
    if len(route) < 2:
        return float(np.hypot(*(xy - route[0]).T).max(initial=0.0))
    a, b = route[:-1], route[1:]
    ab = b - a
    f = ((xy[:, None, :] - a[None]) * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-18)
    near = a[None] + np.clip(f, 0.0, 1.0)[..., None] * ab[None]
    return float(np.hypot(*(xy[:, None, :] - near).transpose(2, 0, 1)).min(axis=1).max())


def test_the_interaction_walks_pedestrians_again_and_keeps_vehicles_on_their_plan(
    grid, catalogue, catalogue_plan, walked
):
    """Against the catalogue behaviour's plans: people keep their life-cycles (the same
    rows) and are walked again (off their plans, on free cells); cars, carts and pallets
    keep to their planned routes (the AR-builder may only make them wait on them)."""
    _, plan = catalogue_plan
    moved_people = 0
    for k, scene in enumerate(walked):
        a = plan[plan["scenario"] == k].sort_values(["id", "t"]).reset_index(drop=True)
        b = scene.tracks_table().sort_values(["id", "t"]).reset_index(drop=True)
        kinds = [catalogue.row(int(c)).features.get("kind") for c in scene.classes]
        walker = dict(zip(scene.ids.tolist(), [kd == "pedestrian" for kd in kinds], strict=True))
        wa, wb = a[a["id"].map(walker).astype(bool)], b[b["id"].map(walker).astype(bool)]
        pd.testing.assert_frame_equal(
            wa[["id", "t"]].reset_index(drop=True),
            wb[["id", "t"]].reset_index(drop=True),
            check_dtype=False,
        )  # same life-cycles
        gap = np.hypot(wa["x"].to_numpy() - wb["x"].to_numpy(), wa["y"].to_numpy() - wb["y"])
        moved_people += int((gap > 0.05).any())
        for i, g in b[~b["id"].map(walker).astype(bool)].groupby("id"):
            route = a.loc[a["id"] == i, ["x", "y"]].to_numpy()
            assert _off_route(g[["x", "y"]].to_numpy(), route) < 1e-6, i  # on its route
            assert g["t"].iloc[-1] == a.loc[a["id"] == i, "t"].iloc[-1]  # its life-cycle
        # no walker steps onto a wall cell of the map
        row, col = np.asarray(grid.world_to_cell(wb[["x", "y"]].to_numpy())).T
        assert grid.free[row, col].all()
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
    fit = Fit.from_draws(draws, laws=laws)
    scene = scenes_from_fit(3, fit, grid, catalogue, 1, HORIZON, behaviours=True)[0]
    # the scene test_assembly_golden pins (its own test of the digest is in the slow tier)
    assert scene.has_tracks.any()
    assert _scenes_digest([scene]) == WANT["groups"]
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


def test_progress_counts_the_assembly_steps_to_the_end(grid, catalogue, walked_progress, unwalked):
    idata = _idata()
    scenes, calls = walked_progress
    calls = list(calls)
    # the catalogue's planning reports each scenario (the time left on a first run comes
    # from the scenarios timed so far), the social force each window of its simulation
    # (25.6 s of the scenarios each): the total grows when it starts
    windows = calls[-1][1] - 3
    assert HORIZON / 25.6 <= windows <= HORIZON / 25.6 + 2
    assert [c[:2] for c in calls] == [(1, 3), (2, 4), (3, 4)] + [
        (3 + k, 3 + windows) for k in range(1, windows + 1)
    ]
    assert [c[2] for c in calls[:4]] == [
        "scenarios drawn", "tracks planned (1 of 2 scenarios)", "tracks planned (2 of 2 scenarios)",
        f"walked with the social force (1 of {windows} windows)",
    ]  # fmt: skip
    # the same scenes as without a progress (pinned so by test_assembly_golden)
    assert _scenes_digest(scenes) == WANT["catalogue"]
    calls.clear()
    scenes_from_fit(11, idata, grid, catalogue, 2, HORIZON, progress=lambda *c: calls.append(c))
    assert calls == [(1, 1, "scenarios drawn")]  # no behaviours: one step
    # without the interaction: the scenarios drawn, then each scenario's tracks planned
    assert [c[:2] for c in unwalked[1]] == [(1, 2), (2, 3), (3, 3)]


def test_one_collision_story_recount():
    """Issue 25: one collision story. The after-the-fact path separation is gone
    (``separate_paths``, ``min_separation`` of the generators); the AR-builder's rule
    (DECISIONS 9, ``ARBuilder.step``) resolves moving scenes through
    ``ARBuilder.resolve_scene``, which the one assembly calls, and the MDP rollouts on their
    cells (``builder_resolver``)."""
    import re
    from pathlib import Path

    import are_stats
    import are_stats.behaviour as behaviour

    root = Path(are_stats.__file__).parent
    src = {p.relative_to(root).as_posix(): p.read_text() for p in root.rglob("*.py")}

    def users(pattern):
        return sorted(k for k, t in src.items() if re.search(pattern, re.sub(r">>>.*", "", t)))

    assert users(r"separate_paths") == []
    assert not hasattr(behaviour, "separate_paths")
    assert [k for k in users(r"min_separation") if k.startswith("behaviour/")] == []
    assert users(r"\.resolve_scene\(") == ["scenarios/_assembly.py"]
    assert users(r"builder\.step\(|self\.step\(") == [
        "behaviour/_rollout.py",
        "builder/_builder.py",
    ]
