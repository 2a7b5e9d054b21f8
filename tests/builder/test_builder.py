"""ARBuilder: registration, collisions, resolution and placement against brute force."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh
from scipy import stats

from are_stats import ARBuilder, OccupancyGrid, VoxelMap, load_catalogue
from are_stats.builder import box_corners
from tests.helpers import ALPHA


def _walled_grid(h=60, w=80, res=0.1, origin=(0.0, 0.0, 0.0), pillars=True):
    d = np.zeros((h, w))
    d[0, :] = d[-1, :] = d[:, 0] = d[:, -1] = 100
    if pillars:
        d[20:26, 30:34] = 100
        d[40:44, 55:70] = 100
    return OccupancyGrid(d, res, origin)


def _shapely_boxes(b: ARBuilder, poses):
    c, h, y = b.boxes(poses)
    return [shapely.Polygon(p) for p in box_corners(c[:, :2], h[:, :2], y)]


def _brute_force_ok(b: ARBuilder, poses) -> bool:
    """No pair of footprints shares area, and no footprint covers an occupied cell."""
    polys = _shapely_boxes(b, poses)
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            if polys[i].intersection(polys[j]).area > 1e-9:
                return False
    g = b.grid
    occ = np.argwhere(g.occupied)
    cells = shapely.MultiPolygon(
        [
            shapely.Polygon(
                g.local_to_world(np.array([[j, i], [j + 1, i], [j + 1, i + 1], [j, i + 1]], float))
            )
            for i, j in occ
        ]
    )
    border = shapely.Polygon(g.corners_world)
    for p in polys:
        if p.intersection(cells).area > 1e-9 or p.difference(border).area > 1e-9:
            return False
    return True


def test_registration_projects_the_exact_footprint():
    g = _walled_grid(origin=(1.0, -2.0, 0.4), pillars=False)
    b = ARBuilder(g, voxel_resolution=0.05)
    pose = g.cell_to_world([30, 40]).tolist() + [0.7]
    aid = b.register(None, pose, size=[1.1, 0.45, 0.8])
    aug = b.augmented_grid()
    poly = _shapely_boxes(b, None)[0]
    ij = np.argwhere(np.ones(g.shape, bool))
    sq = [
        shapely.Polygon(
            g.local_to_world(np.array([[j, i], [j + 1, i], [j + 1, i + 1], [j, i + 1]], float))
        )
        for i, j in ij
    ]
    area = shapely.area(shapely.intersection(sq, poly)).reshape(g.shape)
    expect = (area > 1e-9) | g.occupied
    assert ((aug.data == 100) == expect).all()
    assert b.n_artefact_cells == int((area > 1e-9).sum())
    assert g.data[area > 1e-9].max() == 0  # the base grid is untouched
    vox = b.augmented_voxels()
    assert len(vox) > 0 and len(b.base_voxels) == 0
    b.remove(aid)
    assert (b.augmented_grid().data == g.data).all()
    assert len(b.augmented_voxels()) == 0


def test_augmented_grid_with_the_perceived_artefacts_only():
    """The planner's map (augmented_grid(perceived=...)) holds exactly the perceived boxes'
    cells: those whose area the boxes' footprint polygons share (rasterise_convex), and
    the perception module's grid of the same boxes is this map (one producer)."""
    from are_stats.builder import box_corners, rasterise_convex
    from are_stats.perception import perceived_grid

    g = _walled_grid(origin=(0.5, 0.3, 0.2), pillars=False)
    b = ARBuilder(g)
    rng = np.random.default_rng(3)
    for k in range(6):
        pose = g.cell_to_world([12 + 18 * (k % 3), 20 + 40 * (k // 3)]).tolist()
        b.register(None, [*pose, float(rng.uniform(-3, 3))], size=[0.9, 0.4, 1.0])
    seen = np.array([True, False, True, True, False, False])
    c, h, y = b.boxes()
    want = g.copy()
    poly = box_corners(c[seen, :2], h[seen, :2], y[seen])
    want.data.ravel()[rasterise_convex(g.world_to_local(poly), g.shape)[1]] = 100
    got = b.augmented_grid(perceived=seen)
    np.testing.assert_array_equal(got.data, want.data)
    np.testing.assert_array_equal(perceived_grid(g, c, h, y, seen).data, got.data)
    assert (got.data == 100).sum() < (b.augmented_grid().data == 100).sum()
    np.testing.assert_array_equal(
        b.augmented_grid(perceived=np.ones(6, bool)).data, b.augmented_grid().data
    )
    np.testing.assert_array_equal(b.augmented_grid(perceived=np.zeros(6, bool)).data, g.data)
    with pytest.raises(ValueError, match="aligned with the builder's ids"):
        b.augmented_grid(perceived=np.ones(5, bool))


def _same_builders(a: ARBuilder, b: ARBuilder) -> None:
    np.testing.assert_array_equal(a.ids, b.ids)
    assert a.labels == b.labels
    for x, y in zip(a.boxes(), b.boxes(), strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.augmented_grid().data, b.augmented_grid().data)
    assert a.n_artefact_cells == b.n_artefact_cells
    ca, cb = a.collisions(), b.collisions()
    for k in ca:
        np.testing.assert_array_equal(ca[k], cb[k])


def test_register_many_is_register_one_at_a_time():
    """register_many holds the same ids, labels, boxes, cells and collisions as one
    register call per artefact, by label (rows of Q) and by size, with given ids."""
    q = load_catalogue()
    g = _walled_grid()
    rng = np.random.default_rng(11)
    n = 40
    poses = np.column_stack(
        [rng.uniform(0.5, 7.5, n), rng.uniform(0.5, 5.5, n), rng.uniform(-4, 4, n)]
    )
    labels = list(rng.choice(["person", "child", "pallet"], n))
    one, many = ARBuilder(g, q), ARBuilder(g, q)
    one.register(None, [3.0, 3.0, 0.0], size=[0.3, 0.3, 1.0])  # one artefact there first
    many.register(None, [3.0, 3.0, 0.0], size=[0.3, 0.3, 1.0])
    for lab, p in zip(labels, poses, strict=True):
        one.register(lab, p, check=False)
    got = many.register_many(labels, poses, check=False)
    np.testing.assert_array_equal(got, np.arange(1, n + 1))
    _same_builders(one, many)
    assert one.collisions()["pairs"].size  # the check below has collisions to refuse
    sizes = rng.uniform(0.2, 1.5, (n, 3))
    ids = rng.permutation(1000)[:n]
    one, many = ARBuilder(g), ARBuilder(g)
    for p, sz, aid in zip(poses, sizes, ids, strict=True):
        one.register(None, p, size=sz, artefact_id=aid, check=False)
    many.register_many([None] * n, poses, sizes=sizes, artefact_ids=ids, check=False)
    _same_builders(one, many)
    assert (
        one.register(None, [1.0, 1.0, 0.0], size=[0.2, 0.2, 1.0], check=False)
        == (many.register_many([None], [[1.0, 1.0, 0.0]], sizes=[[0.2, 0.2, 1.0]], check=False)[0])
    )


def test_register_many_refuses_a_colliding_batch_whole():
    """With check, a batch is refused (nothing registered) when a box hits the
    environment, a live artefact or another box of the batch; ids must be new and
    distinct; register_many([]) registers nothing."""
    q = load_catalogue()
    b = ARBuilder(_walled_grid(), q)
    b.register("person", [1.0, 1.0, 0.0])
    free = [[2.0, 4.0, 0.0], [5.0, 2.0, 0.0]]
    cases = {
        "the environment": [*free, [3.2, 2.3, 0.0]],  # into a pillar
        "an artefact": [*free, [1.1, 1.0, 0.0]],  # onto the person
        "an artefact ": [*free, [5.1, 2.0, 0.0]],  # onto the batch's second box
    }
    for what, poses in cases.items():
        with pytest.raises(ValueError, match=f"collides with {what.strip()}"):
            b.register_many(["person"] * 3, poses)
        assert b.ids.tolist() == [0]
    with pytest.raises(ValueError, match="id 0 is already registered"):
        b.register_many(["person"] * 2, free, artefact_ids=[5, 0])
    with pytest.raises(ValueError, match="id 5 is already registered"):
        b.register_many(["person"] * 2, free, artefact_ids=[5, 5])
    with pytest.raises(ValueError, match="labels: expected 2 labels"):
        b.register_many(["person"], free)
    with pytest.raises(ValueError, match=r"sizes: expected \(2, 3\)"):
        b.register_many([None] * 2, free, sizes=[[1.0, 1.0, 1.0]])
    assert b.register_many([], np.zeros((0, 3))).size == 0
    assert b.register_many(["person"] * 2, free).tolist() == [1, 2]


def test_perceived_map_with_and_without_the_footprints_cached():
    """augmented_grid(perceived=...) rasterises only the perceived boxes when the
    footprints of the update are not there yet, and filters them when they are: the
    same map."""
    g = _walled_grid(origin=(0.3, -0.2, 0.1))
    rng = np.random.default_rng(5)
    n = 30
    poses = np.column_stack([rng.uniform(-1, 9, n), rng.uniform(-1, 7, n), rng.uniform(-4, 4, n)])
    b = ARBuilder(g)
    b.register_many([None] * n, poses, sizes=rng.uniform(0.1, 2.0, (n, 3)), check=False)
    seen = rng.random(n) < 0.5
    fresh = b.augmented_grid(perceived=seen)
    assert b._runs is None  # only the perceived boxes were rasterised
    b.augmented_grid()
    np.testing.assert_array_equal(b.augmented_grid(perceived=seen).data, fresh.data)


def test_catalogue_registration_and_voxels():
    q = load_catalogue()
    g = _walled_grid()
    base = VoxelMap(0.1)
    base.insert_points([[0.05, 0.05, 0.05]])
    b = ARBuilder(g, q, voxels=base)
    b.register("person", [2.0, 2.0, 0.0])
    b.register("cart", [5.0, 2.0, np.pi / 2])
    vox = b.augmented_voxels()
    assert vox.query([[0.05, 0.05, 0.05]])[0]
    # the voxels of the person's head are present at about 1.6 m
    assert vox.query([[2.0, 2.0, 1.6]])[0] or vox.query([[2.0, 2.0, 1.69]])[0]
    assert len(vox) > 50
    b.reset()
    assert len(b) == 0 and len(b.augmented_voxels()) == 1


def test_revert_rule_and_log():
    b = ARBuilder(_walled_grid(pillars=False))
    b.register(None, [2.0, 2.0, 0.0], size=[1.0, 0.5, 1.0])
    b.register(None, [5.0, 4.0, 0.0], size=[1.0, 0.5, 1.0])
    b.register(None, [6.5, 2.0, 0.0], size=[0.5, 0.5, 1.0])
    out = b.step([[2.0, 2.0, 0.0], [2.6, 2.1, 0.3], [7.0, 2.0, 0.0]], time=4.0)
    assert out.tolist() == [[2.0, 2.0, 0.0], [5.0, 4.0, 0.0], [7.0, 2.0, 0.0]]
    assert b.log == [(4.0, 1, "revert", "artefact", 0, 0.0)]
    out = b.step({2: [7.7, 2.0, 0.0]}, time=5.0)  # into the border wall (x 7.9..8)
    assert out[2].tolist() == [7.0, 2.0, 0.0]
    assert b.log[-1].cause == "environment"
    out = b.step({2: [8.5, 2.0, 0.0]}, time=6.0)  # off the map
    assert b.log[-1].cause == "bounds"
    # two movers swapping into each other both revert; a chain reverts in rounds
    out = b.step({0: [4.0, 3.0, 0.0], 1: [4.2, 3.1, 0.0]}, time=7.0)
    assert out[:2].tolist() == [[2.0, 2.0, 0.0], [5.0, 4.0, 0.0]]
    assert {r.artefact for r in b.log if r.time == 7.0} == {0, 1}
    table = b.log_table()
    assert table["cause"].tolist()[0] == "artefact"


@pytest.mark.parametrize("rule", ["revert", "advance"])
def test_exchange_of_places_is_reverted_under_either_rule(rule):
    b = ARBuilder(_walled_grid(pillars=False), rule=rule)
    for x in (2.0, 3.0, 5.0):
        b.register(None, [x, 2.0, 0.0], size=[0.9, 0.9, 1.0])
    # 0 and 1 would swap places (pass through each other): no new pose collides, yet both
    # stay; 2 moves freely
    out = b.step([[3.0, 2.0, 0.0], [2.0, 2.0, 0.0], [5.0, 3.0, 0.0]], time=1.0)
    assert out.tolist() == [[2.0, 2.0, 0.0], [3.0, 2.0, 0.0], [5.0, 3.0, 0.0]]
    assert [(r.artefact, r.rule, r.cause, r.other, r.fraction) for r in b.log] == [
        (0, "revert", "artefact", 1, 0.0),
        (1, "revert", "artefact", 0, 0.0),
    ]
    # following is no exchange: 0 moves into the place that 1 leaves
    out = b.step([[3.0, 2.0, 0.0], [4.0, 2.0, 0.0], [5.0, 3.0, 0.0]], time=2.0)
    assert out.tolist() == [[3.0, 2.0, 0.0], [4.0, 2.0, 0.0], [5.0, 3.0, 0.0]]
    assert len(b.log) == 2


def test_advance_rule_moves_up_to_a_safe_distance():
    b = ARBuilder(_walled_grid(pillars=False), rule="advance", safe_distance=0.05)
    b.register(None, [2.0, 2.0, 0.0], size=[1.0, 1.0, 1.0])
    b.register(None, [5.0, 2.0, 0.0], size=[1.0, 1.0, 1.0])
    out = b.step({1: [2.5, 2.0, 0.0]}, time=1.0)
    # contact at x = 3.0; stop 0.05 before it (bisection accuracy 2.5 / 2^12)
    assert 3.05 - 1e-12 <= out[1, 0] <= 3.05 + 2.5 / 2**12 + 1e-12
    r = b.log[-1]
    assert r.rule == "advance" and r.cause == "artefact" and 0 < r.fraction < 1
    out = b.step({1: [7.45, 2.0, 0.0]}, time=2.0)  # into the wall at x = 7.9..8.0
    # the wall starts at x = 7.9: contact at centre 7.4, minus the safe distance
    assert abs(out[1, 0] - 7.35) <= 4.4 / 2**12 and b.log[-1].cause == "environment"
    assert _brute_force_ok(b, None)


@pytest.mark.parametrize("rule", ["revert", "advance"])
def test_random_walks_stay_collision_free(rule):
    rng = np.random.default_rng(3)
    g = _walled_grid(origin=(0.0, 0.0, 0.2))
    q = load_catalogue()
    b = ARBuilder(g, q, rule=rule)
    labels = ["person", "child", "cart", "pallet"]
    for k in range(25):
        assert b.place(labels[k % 4], rng).ok
    for _ in range(6):
        P = b.poses + np.column_stack([rng.normal(0, 0.4, (len(b), 2)), rng.normal(0, 0.3, len(b))])
        out = b.step(P)
        assert _brute_force_ok(b, out)
        c = b.collisions()
        assert not c["environment"].any() and c["pairs"].size == 0
    assert len(b.log) > 0


def test_mesh_embedding():
    g = OccupancyGrid(np.zeros((50, 50)), 0.1)
    mesh = trimesh.creation.box(extents=[0.4, 0.4, 2.0])
    mesh.apply_translation([2.5, 2.5, 1.0])
    high = trimesh.creation.box(extents=[1.0, 1.0, 0.2])
    high.apply_translation([1.0, 4.0, 3.0])  # above the artefacts: no collision
    b = ARBuilder(g, env_mesh=trimesh.util.concatenate([mesh, high]))
    b.register(None, [1.0, 1.0, 0.0], size=[0.5, 0.5, 1.0])
    with pytest.raises(ValueError, match="collides"):
        b.register(None, [2.5, 2.8, 0.0], size=[0.5, 0.5, 1.0])
    b.step([[2.3, 2.3, 0.0]], time=1.0)
    assert b.log[-1].cause == "mesh"
    out = b.step([[1.0, 4.0, 0.0]], time=2.0)
    assert out[0].tolist() == [1.0, 4.0, 0.0]


def test_placement_uniform_over_free_cells():
    # 6 x 6 free interior; a tiny artefact fits in every free cell
    g = _walled_grid(8, 8, 1.0, pillars=False)
    b = ARBuilder(g)
    rng = np.random.default_rng(11)
    n = 1800
    counts = np.zeros(g.shape, int)
    for _ in range(n):
        pl = b.place(None, rng, size=[1e-6, 1e-6, 1.0], yaw=0.0)
        i, j = g.world_to_cell(pl.pose[:2])
        counts[i, j] += 1
        b.reset()
    assert counts[g.occupied].sum() == 0
    p = stats.chisquare(counts[g.free]).pvalue
    assert p > ALPHA


def test_area_full_is_reported_not_looped():
    g = _walled_grid(8, 8, 0.5, pillars=False)  # 3 m x 3 m free interior
    b = ARBuilder(g)
    rng = np.random.default_rng(0)
    out = [b.place(None, rng, size=[1.2, 1.2, 1.0], max_tries=300) for _ in range(12)]
    assert any(o.ok for o in out)
    full = [o for o in out if not o.ok]
    assert full and all(o.tries == 300 and o.artefact == -1 for o in full)
    big = b.place(None, rng, size=[10.0, 10.0, 1.0], max_tries=50)
    assert not big.ok and big.tries == 50


def test_bad_inputs():
    q = load_catalogue()
    b = ARBuilder(_walled_grid(), q)
    with pytest.raises(ValueError, match="unknown artefact class"):
        b.register("dragon", [1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="collides"):
        b.register("person", [0.05, 1.0, 0.0])
    a = b.register("person", [1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="already registered"):
        b.register("child", [3.0, 1.0, 0.0], artefact_id=a)
    with pytest.raises(ValueError, match=r"\(1, 3\)"):
        b.step(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="no live artefact"):
        b.step({7: [1.0, 1.0, 0.0]})
    with pytest.raises(ValueError, match="rule"):
        ARBuilder(_walled_grid(), rule="teleport")
    with pytest.raises(ValueError, match="catalogue"):
        ARBuilder(_walled_grid()).register("person", [1.0, 1.0, 0.0])


def test_sync_frames_publishes_artefact_frames():
    from are_stats import TransformTree

    b = ARBuilder(_walled_grid(pillars=False))
    a = b.register(None, [2.0, 3.0, 0.5], size=[0.5, 0.5, 1.0])
    c = b.register(None, [5.0, 3.0, 0.0], size=[0.5, 0.5, 1.0])
    tree = TransformTree()
    tree.set_static("F_R", "F_E", [1.0, 1.0, 0.0])
    b.sync_frames(tree)
    p = tree.transform_points("F_R", f"F_A/{a}", [[0.0, 0.0, 0.0]])
    assert np.allclose(p, [[1.0, 2.0, 0.0]])
    b.remove(c)
    b.step([[2.5, 3.0, 0.5]])
    b.sync_frames(tree)
    assert f"F_A/{c}" not in tree.frames
    assert np.allclose(tree.lookup("F_E", f"F_A/{a}")[:2, 3], [2.5, 3.0])


def _scene():
    import pandas as pd

    from are_stats import Scene

    rng = np.random.default_rng(5)
    n = 6
    table = pd.DataFrame(
        {
            "artefact": np.arange(20, 20 + n),
            "class": rng.integers(0, 5, n),
            "mark": rng.integers(0, 8, n),
            "t_arrive": [0.0, 0.0, 1.0, 2.0, 3.0, 9.0],
            "t_leave": [5.0, 10.0, 10.0, 4.0, 10.0, 10.0],
            "x": [1.5, 3.0, 5.0, 6.5, 2.0, 6.0],
            "y": [1.5, 4.5, 1.5, 4.5, 3.0, 2.0],
            "yaw": rng.uniform(0, 2 * np.pi, n),
        }
    )
    tracks = pd.DataFrame({"id": [21, 21], "t": [0.0, 8.0], "x": [3.0, 4.0],
                           "y": [4.5, 4.0], "yaw": [0.3, 2.0]})  # fmt: skip
    return Scene.from_scenarios(table, load_catalogue(), tracks)


def test_register_scene_equals_registering_its_boxes():
    grid = _walled_grid(pillars=False)
    scene = _scene()
    b = ARBuilder(grid, load_catalogue())
    for t in (0.5, 3.5, 4.5, 9.5):
        ids = b.register_scene(scene, t)
        boxes = scene.at(t)
        # the same boxes registered one by one, by size, at their box centres
        d = ARBuilder(grid)
        for k in range(len(boxes)):
            pose = [boxes.centres[k, 0], boxes.centres[k, 1], boxes.yaws[k]]
            d.register(None, pose, size=2 * boxes.half_extents[k], artefact_id=boxes.ids[k],
                       check=False)  # fmt: skip
        assert ids.tolist() == boxes.ids.tolist() == b.ids.tolist() == d.ids.tolist()
        assert b.labels == boxes.labels.tolist()
        (cb, hb, yb), (cd, hd, yd) = b.boxes(), d.boxes()
        np.testing.assert_allclose(cb, boxes.centres, atol=1e-12)
        # (register(size=) stands a box on the ground; a row's box may float a little)
        np.testing.assert_allclose(cb[:, :2], cd[:, :2], atol=1e-12)
        np.testing.assert_allclose(hb, hd)
        np.testing.assert_allclose(np.mod(yb, 2 * np.pi), np.mod(yd, 2 * np.pi), atol=1e-12)
        np.testing.assert_array_equal(b.augmented_grid().data, d.augmented_grid().data)
        assert b.n_artefact_cells == d.n_artefact_cells > 0
        cb_, cd_ = b.collisions(), d.collisions()
        for key in ("environment", "bounds", "mesh", "pairs"):
            np.testing.assert_array_equal(cb_[key], cd_[key])
    assert len(b.register_scene(scene, 50.0)) == 0 and len(b) == 0  # all left


def test_register_scene_check_refuses_collisions():
    import pandas as pd

    from are_stats import Scene

    grid = _walled_grid(pillars=False)
    table = pd.DataFrame({"t_arrive": [0.0, 0.0], "t_leave": [9.0, 9.0], "x": [3.0, 3.1],
                          "y": [3.0, 3.0], "yaw": [0.0, 0.0]})  # fmt: skip
    b = ARBuilder(grid, load_catalogue())
    scene = Scene.from_scenarios(table, load_catalogue())
    with pytest.raises(ValueError, match="scene: artefacts 0 and 1 collide at t=1.0"):
        b.register_scene(scene, 1.0, check=True)
    assert len(b) == 0  # nothing changed
    assert b.register_scene(scene, 1.0).tolist() == [0, 1]
    with pytest.raises(ValueError, match="scene: expected a Scene"):
        b.register_scene(table, 1.0)


def _moving_scene(rows, tracks):
    """A Scene of person boxes (catalogue row 0) from (t_arrive, t_leave, x, y) rows and
    tracks ``{index: [(t, x, y), ...]}`` (yaw 0)."""
    import pandas as pd

    from are_stats import Scene

    table = pd.DataFrame(rows, columns=["t_arrive", "t_leave", "x", "y"]).assign(yaw=0.0)
    tr = pd.DataFrame(
        [(i, t, x, y, 0.0) for i, pts in tracks.items() for t, x, y in pts],
        columns=["id", "t", "x", "y", "yaw"],
    )
    return Scene.from_scenarios(table, load_catalogue(), tr)


def _open_ground():
    return OccupancyGrid(np.zeros((140, 200)), 0.1, (-3.0, -2.0, 0.0))


def test_resolve_scene_a_mover_waits_for_a_standing_box_then_walks_on_its_route():
    """A mover walking at 1 m/s into a box that stands until t = 6 s holds its last safe
    pose from the step its box would touch the other (the contact distance, known from the
    two boxes) until the box leaves, then walks on: it reaches the end of its route that
    much later (to within one step), never overlaps the box, never moves faster than
    planned, and the standing box is not moved. (The builder tests poses at its steps;
    between them the scene interpolates.)"""
    scene = _moving_scene(
        [(0.0, 15.0, 0.0, 5.0), (0.0, 6.0, 5.0, 5.0)],
        {0: [(0.0, 0.0, 5.0), (10.0, 10.0, 5.0), (15.0, 10.0, 5.0)]},
    )
    dt = 0.5
    b = ARBuilder(_open_ground())
    out = b.resolve_scene(scene, np.array([True, False]), dt=dt)
    contact = 5.0 - (scene.half_extents[0, 0] + scene.half_extents[1, 0])  # centre x at touch
    # the first step whose proposal passes the contact is reverted; it waits until t = 6
    t_touch = np.ceil(contact / dt + 1e-9) * dt
    delay = np.ceil((6.0 - t_touch) / dt - 1e-9) * dt
    t, pose = out.track(0)
    t_end = t[np.argmax(pose[:, 0] >= 10.0 - 1e-9)]
    assert abs(t_end - (10.0 + delay)) <= dt + 1e-9
    assert abs(pose[-1, 0] - 10.0) < 1e-9 and t[-1] == 15.0
    speed = np.hypot(*np.diff(pose[:, :2], axis=0).T) / np.diff(t)
    assert speed.max() <= 1.0 + 1e-9  # no jump: it only waited
    assert np.allclose(pose[:, 1], 5.0)  # on its route
    assert out.track(1)[0].size == 0 and np.allclose(out.poses(3.0)[1], scene.poses(3.0)[1])
    assert {(r.rule, r.cause, r.other) for r in b.log} == {("revert", "artefact", 1)}
    assert len(b) == 0
    check = ARBuilder(_open_ground())
    for tt in np.arange(0.0, 6.0, dt):
        check.register_scene(out, tt)
        assert check.collisions()["pairs"].size == 0, tt
    # the planned track walks through the box
    check.register_scene(scene, 5.0)
    assert check.collisions()["pairs"].size == 2


def test_resolve_scene_crossing_movers_the_later_arrival_waits():
    """Two movers at the crossing of their routes at the same time (t = 5 s): the
    earlier arrival keeps its track exactly, the later one waits and is in contact at no
    step; movers that meet nobody keep their tracks (the same rows)."""
    scene = _moving_scene(
        [(0.0, 14.0, 0.0, 5.0), (0.5, 14.0, 5.0, 0.5), (0.0, 14.0, 15.0, 10.0)],
        {
            0: [(0.0, 0.0, 5.0), (10.0, 10.0, 5.0), (14.0, 10.0, 5.0)],
            1: [(0.5, 5.0, 0.5), (10.0, 5.0, 10.0), (14.0, 5.0, 10.0)],
            2: [(0.0, 15.0, 10.0), (14.0, 15.0, 1.0)],
        },
    )
    b = ARBuilder(_open_ground())
    out = b.resolve_scene(scene, dt=0.25)
    for i in (0, 2):
        assert all(np.array_equal(a, c) for a, c in zip(out.track(i), scene.track(i), strict=True))
    t, pose = out.track(1)
    assert t[np.argmax(pose[:, 1] >= 10.0 - 1e-9)] > 10.0 + 0.25  # it waited
    assert {r.artefact for r in b.log} == {1}
    check = ARBuilder(_open_ground())
    for tt in np.arange(0.5, 14.0, 0.25):
        check.register_scene(out, tt)
        assert check.collisions()["pairs"].size == 0, tt
    with pytest.raises(ValueError, match="movers"):
        b.resolve_scene(scene, np.ones(2, bool))


def test_resolve_scene_a_mover_stops_at_a_wall_on_its_route():
    """On a map (not open ground) the environment is tested too: a mover whose planned
    route runs into a wall (x from 7 m) holds its last safe pose before it, a box length
    short of the wall, for the rest of its life."""
    d = np.zeros((140, 200))
    d[:, 100:110] = 100  # x in [7, 8)
    grid = OccupancyGrid(d, 0.1, (-3.0, -2.0, 0.0))
    scene = _moving_scene([(0.0, 12.0, 0.0, 5.0)], {0: [(0.0, 0.0, 5.0), (12.0, 12.0, 5.0)]})
    b = ARBuilder(grid)
    out = b.resolve_scene(scene, dt=0.25)
    front = 7.0 - scene.half_extents[0, 0] - scene.offsets[0, 0]  # centre x at contact
    x_end = out.poses(11.9)[0, 0]
    assert front - 0.25 - 1e-9 <= x_end <= front + 1e-9
    assert {(r.cause, r.rule) for r in b.log} == {("environment", "revert")}


class _StepBuilder(ARBuilder):
    """The reference: every held move of :meth:`ARBuilder.resolve_scene` through
    :meth:`ARBuilder.step` (the builder's general resolution of one move)."""

    _direct_revert = False


def _busy_scene(seed: int, n: int = 14):
    """``n`` artefacts of mixed classes (people, cars, pallets, carts) in a 10 m x 8 m
    yard: random arrivals and departures, random routes of 2-5 vertices with turning
    headings (some running off the map), some standing, some placed on each other."""
    import pandas as pd

    from are_stats import Scene

    rng = np.random.default_rng(seed)
    t_on = rng.uniform(0.0, 4.0, n)
    rows = np.column_stack([t_on, t_on + rng.uniform(4.0, 12.0, n), rng.uniform(0.0, 10.0, (n, 2))])
    rows[1, 2:] = rows[0, 2:] + 0.3  # on each other where they arrive
    table = pd.DataFrame(rows, columns=["t_arrive", "t_leave", "x", "y"]).assign(
        yaw=rng.uniform(-np.pi, np.pi, n), **{"class": rng.choice([0, 2, 3, 4], n)}
    )
    tracks = []
    for i in range(n):
        if i % 5 == 4:
            continue  # standing
        m = int(rng.integers(2, 6))
        t = np.sort(rng.uniform(rows[i, 0], rows[i, 1], m))
        t[0] = rows[i, 0]
        xy = np.r_[rows[i, 2:][None], rng.uniform(-1.5, 11.5, (m - 1, 2))]
        yaw = table["yaw"][i] + np.cumsum(rng.normal(0.0, 1.0, m))
        tracks += [(i, *v) for v in zip(t, xy[:, 0], xy[:, 1], yaw, strict=True)]
    tr = pd.DataFrame(tracks, columns=["id", "t", "x", "y", "yaw"])
    return Scene.from_scenarios(table, load_catalogue(), tr)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("ground", ["open", "walled"])
def test_resolve_scene_holds_moves_as_step_does(seed, ground):
    """resolve_scene under rule "revert" holds a colliding move itself (the environment
    test of the moved box, then its pairs with the others); the same scenes resolved
    through step() for every held move give the same tracks and the same log, bit for
    bit: on open ground (the border only: movers leave the 10 m x 8 m map) and on a map
    with walls and pillars."""
    grid = (
        OccupancyGrid(np.zeros((80, 100)), 0.1, (0.0, 0.0, 0.0))
        if ground == "open"
        else _walled_grid(80, 100)
    )
    scene = _busy_scene(seed)
    got, want = ARBuilder(grid), _StepBuilder(grid)
    out, ref = got.resolve_scene(scene, dt=0.25), want.resolve_scene(scene, dt=0.25)
    causes = {"artefact", "bounds"} if ground == "open" else {"artefact", "environment"}
    assert len(want.log) > 100 and {r.cause for r in want.log} >= causes
    assert got.log == want.log
    a, b = out.tracks_table(), ref.tracks_table()
    assert list(a.columns) == list(b.columns) and len(a) == len(b)
    for col in a.columns:
        assert np.array_equal(a[col].to_numpy(), b[col].to_numpy()), col
