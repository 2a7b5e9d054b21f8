"""Scene: boxes from the table and Q, poses interpolated between epochs, events."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from are_stats.scenarios._scene import Scene


def table(n: int = 4) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    return pd.DataFrame(
        {
            "scenario": 0,
            "artefact": np.arange(10, 10 + n),
            "class": rng.integers(0, 3, n),
            "mark": rng.integers(0, 6, n),
            "t_arrive": np.arange(n, dtype=float),
            "t_leave": np.arange(n, dtype=float) + 10.0,
            "x": rng.uniform(-5, 5, n),
            "y": rng.uniform(-5, 5, n),
            "yaw": rng.uniform(0, 2 * np.pi, n),
        }
    )


def test_boxes_equal_the_table_and_the_rows_of_q(catalogue):
    t = table(6)
    boxes = Scene.from_scenarios(t, catalogue).at(5.5)
    assert boxes.ids.tolist() == t["artefact"].tolist()  # all alive at 5.5
    for k, r in t.reset_index(drop=True).iterrows():
        row = catalogue.select(int(r["class"]), int(r["mark"]))  # DECISIONS 5
        assert boxes.labels[k] == row.label
        np.testing.assert_allclose(boxes.half_extents[k], row.half_extents)
        off = (row.bounds[0] + row.bounds[1]) / 2
        c, s = np.cos(r["yaw"]), np.sin(r["yaw"])
        want = [r["x"] + c * off[0] - s * off[1], r["y"] + s * off[0] + c * off[1], off[2]]
        np.testing.assert_allclose(boxes.centres[k], want, atol=1e-12)
        assert boxes.yaws[k] == pytest.approx(r["yaw"])


def test_class_labels_pick_catalogue_classes_by_label(catalogue):
    t = table(2).assign(**{"class": [0, 1], "mark": [0, 0]})
    # the fit's component 0 is "cart" and component 1 an unknown label: by position
    scene = Scene.from_scenarios(t, catalogue, class_labels=["cart", "unicorn"])
    assert scene.labels.tolist() == ["cart", catalogue.row(1).label]


def test_alive_is_half_open(catalogue):
    scene = Scene.from_scenarios(table(3), catalogue)
    assert scene.at(0.0).ids.tolist() == [10]
    assert scene.at(10.0).ids.tolist() == [11, 12]  # artefact 10 left at 10.0
    assert len(scene.at(100.0)) == 0


def tracks_for(t: pd.DataFrame) -> pd.DataFrame:
    # artefact 10 walks east 1 m/s with epochs every 2 s from t=1; turns from 350 to 10 deg
    ep = np.arange(1.0, 9.0, 2.0)
    yaw = np.deg2rad([350.0, 10.0, 10.0, 10.0])
    return pd.DataFrame({"scenario": 0, "id": 10, "t": ep, "x": ep, "y": 0.0, "yaw": yaw}).iloc[
        ::-1
    ]  # unsorted on purpose


def test_poses_exact_at_epochs_and_interpolated_between(catalogue):
    t = table(2)
    scene = Scene.from_scenarios(t, catalogue, tracks_for(t))
    assert scene.has_tracks.tolist() == [True, False]
    for e, yaw in zip([1.0, 3.0, 5.0, 7.0], [350.0, 10.0, 10.0, 10.0], strict=True):
        p = scene.poses(e)[0]
        np.testing.assert_allclose(p, [e, 0.0, np.deg2rad(yaw)], atol=1e-12)
    # halfway between the first epochs: heading through 0 (short way), not through 180
    p = scene.poses(2.0)[0]
    np.testing.assert_allclose(p[:2], [2.0, 0.0])
    assert p[2] == pytest.approx(0.0, abs=1e-12) or p[2] == pytest.approx(2 * np.pi)
    # before the first epoch: the arrival pose; after the last: the last pose
    np.testing.assert_allclose(scene.poses(0.5)[0], t.iloc[0][["x", "y", "yaw"]].to_numpy(float))
    np.testing.assert_allclose(scene.poses(9.5)[0], [7.0, 0.0, np.deg2rad(10.0)])
    # the artefact without a track stands at its arrival pose
    np.testing.assert_allclose(scene.poses(5.0)[1], t.iloc[1][["x", "y", "yaw"]].to_numpy(float))


def test_vectorised_poses_equal_one_by_one(catalogue):
    rng = np.random.default_rng(3)
    n = 30
    t = table(n)
    rows = []
    for i in range(n):
        ep = np.sort(rng.choice(np.arange(0, 40, 0.5), size=rng.integers(0, 6), replace=False))
        for e in ep:
            rows.append((10 + i, e, *rng.uniform(-5, 5, 2), rng.uniform(0, 2 * np.pi)))
    tracks = pd.DataFrame(rows, columns=["id", "t", "x", "y", "yaw"])
    scene = Scene.from_scenarios(t, catalogue, tracks)
    for q in rng.uniform(-1, 41, 25):
        got = scene.poses(q)
        for i in range(n):
            want = Scene.from_scenarios(
                t.iloc[[i]], catalogue, tracks[tracks["id"] == 10 + i]
            ).poses(q)[0]
            np.testing.assert_allclose(got[i], want, atol=1e-12)


def test_events_between_two_times(catalogue):
    t = table(3)
    scene = Scene.from_scenarios(t, catalogue, tracks_for(t))
    ev = scene.events(0.5, 11.0)
    kinds = ["arrive", "move", "arrive", "move", "move", "move", "leave", "leave"]
    assert ev["kind"].tolist() == kinds
    assert ev["t"].tolist() == [1.0, 1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 11.0]
    assert ev["id"].tolist() == [11, 10, 12, 10, 10, 10, 10, 11]


@pytest.mark.parametrize(
    "bad, match",
    [
        (lambda t: t.drop(columns="yaw"), "missing \\['yaw'\\]"),
        (lambda t: t.assign(scenario=[0, 1, 0]), "one scenario"),
        (lambda t: t.assign(x=[0.0, np.nan, 1.0]), "row 1"),
        (lambda t: t.assign(artefact=[1, 1, 2]), "unique"),
    ],
)
def test_bad_tables_are_clear_errors(catalogue, bad, match):
    with pytest.raises(ValueError, match=match):
        Scene.from_scenarios(bad(table(3)), catalogue)


def test_bad_tracks_are_clear_errors(catalogue):
    t = table(2)
    tr = tracks_for(t)
    with pytest.raises(ValueError, match="id 99 is not an artefact"):
        Scene.from_scenarios(t, catalogue, tr.assign(id=99))
    with pytest.raises(ValueError, match="two poses at t=1.0"):
        Scene.from_scenarios(t, catalogue, pd.concat([tr, tr.iloc[[-1]]]))


@pytest.mark.parametrize(
    "bad, message",
    [
        (
            lambda tr: tr.drop(columns="t"),
            "tracks: expected columns ['id', 't', 'x', 'y', 'yaw'], missing ['t']",
        ),
        (
            lambda tr: tr.assign(scenario=np.arange(len(tr)) % 2),
            "tracks: expected one scenario, got several (filter by 'scenario')",
        ),
        (
            lambda tr: tr.assign(yaw=np.r_[0.0, np.inf, np.zeros(len(tr) - 2)]),
            "tracks: row 1: expected finite t, x, y, yaw",
        ),
        (lambda tr: tr.to_numpy().tolist(), "tracks: expected a DataFrame, got list"),
    ],
)
def test_bad_track_tables_are_named_as_tracks(catalogue, bad, message):
    t = table(2)
    with pytest.raises(ValueError) as err:
        Scene.from_scenarios(t, catalogue, bad(tracks_for(t)))
    assert str(err.value) == message


def test_bad_artefact_tables_are_named_as_artefacts(catalogue):
    with pytest.raises(ValueError) as err:
        Scene.from_scenarios(table(3).assign(t_leave=[1.0, 2.0, np.nan]), catalogue)
    assert str(err.value) == "artefacts: row 2: expected finite times and poses"
    with pytest.raises(ValueError) as err:
        Scene.from_scenarios(table(3).to_dict(), catalogue)
    assert str(err.value) == "artefacts: expected a DataFrame, got dict"


def test_with_track_replaces_one_track_and_leaves_the_scene_alone(catalogue):
    t = table(3)
    scene = Scene.from_scenarios(t, catalogue, tracks_for(t))
    ep, pose = scene.track(0)
    np.testing.assert_allclose(ep, [1.0, 3.0, 5.0, 7.0])
    np.testing.assert_allclose(pose[:, 0], ep)
    assert scene.track(1)[0].size == 0
    # artefact 1 (no track) gets one; artefact 0 waits 2 s at x = 3 (its track delayed)
    moved = scene.with_track(1, [2.0, 4.0], [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    late = moved.with_track(
        0,
        [1.0, 3.0, 5.0, 7.0, 9.0],
        np.c_[[1.0, 3.0, 3.0, 5.0, 7.0], np.zeros(5), pose[[0, 1, 1, 2, 3], 2]],
    )
    assert late.has_tracks.tolist() == [True, True, False]
    np.testing.assert_allclose(late.poses(3.0, [1])[0, :2], [1.0, 0.0])  # halfway
    np.testing.assert_allclose(late.poses(4.0, [0])[0, :2], [3.0, 0.0])  # waiting
    np.testing.assert_allclose(late.poses(8.0, [0])[0, :2], [6.0, 0.0])
    np.testing.assert_allclose(late.poses(8.0, [2]), scene.poses(8.0, [2]))
    # the original scene is unchanged, and so are life-cycles and boxes
    np.testing.assert_allclose(scene.poses(4.0, [0])[0, :2], [4.0, 0.0])
    assert scene.track(1)[0].size == 0
    np.testing.assert_array_equal(late.t_leave, scene.t_leave)
    ev = late.events(0.0, 20.0)
    assert sorted(ev.loc[ev["kind"] == "move", "t"].tolist()) == [1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 9.0]
    # next epochs: by hand from the two tracks, inf without one or after the last
    np.testing.assert_array_equal(late.next_epoch(0.0), [1.0, 2.0, np.inf])
    np.testing.assert_array_equal(late.next_epoch(3.0, [1, 0]), [4.0, 5.0])
    np.testing.assert_array_equal(late.next_epoch(9.0, [0, 1]), [np.inf, np.inf])
    np.testing.assert_array_equal(late.next_epoch(-50.0, [1]), [2.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        scene.with_track(0, [1.0, 1.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"pose \(m, 3\)"):
        scene.with_track(0, [1.0, 2.0], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="artefact index"):
        scene.track(3)
