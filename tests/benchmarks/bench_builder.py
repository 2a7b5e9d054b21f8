"""AR-builder scene update: 1,000 moving artefacts on a 2000 x 2000 grid.

One scene update = ``ARBuilder.step``: footprints of every moved box on M_2D (exact row runs),
embedding test against occupied cells, spatial-hash broad phase, separating-axis narrow
phase and revert resolution. Peers, on the same proposed poses:

* brute force: shapely polygons of all boxes and ``shapely.intersects`` on all n(n-1)/2
  pairs (vectorised shapely 2), pairs only;
* shapely ``STRtree`` query with the ``intersects`` predicate, pairs only.

The collision pairs of ours are checked against the shapely oracle (positive intersection
area). Run: ``python -m tests.benchmarks.bench_builder [--quick]``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from are_stats import ARBuilder, OccupancyGrid, load_catalogue
from are_stats.builder import box_corners


def _median_ms(fn, repeats: int) -> float:
    fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts))


def _scene(n_cells: int, n_art: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    data = np.zeros((n_cells, n_cells), np.int8)
    data[:3, :] = data[-3:, :] = data[:, :3] = data[:, -3:] = 100
    for _ in range(n_cells // 20):  # rectangular obstacles, ~5 % of the area
        i, j = rng.integers(0, n_cells - 60, 2)
        h, w = rng.integers(5, 60, 2)
        data[i : i + h, j : j + w] = 100
    grid = OccupancyGrid(data, 0.05)
    cat = load_catalogue()
    builder = ARBuilder(grid, cat)
    labels = rng.choice(
        ["person", "child", "cart", "pallet", "car"], size=n_art, p=[0.4, 0.2, 0.15, 0.15, 0.1]
    )
    for lab in labels:
        builder.place(str(lab), rng, max_tries=500)
    return builder, rng


def _proposals(builder: ARBuilder, rng: np.random.Generator, dt: float = 0.2):
    P = builder.poses.copy()
    speed = np.array([1.2 if lab != "pallet" else 0.0 for lab in builder.labels])
    P[:, 2] += rng.normal(0, 0.2, len(P))
    P[:, 0] += speed * dt * np.cos(P[:, 2])
    P[:, 1] += speed * dt * np.sin(P[:, 2])
    return P


def main(quick: bool = False) -> None:
    import shapely

    n_cells, n_art, repeats = (500, 200, 5) if quick else (2000, 1000, 7)
    builder, rng = _scene(n_cells, n_art)
    n = len(builder)
    print(f"grid {n_cells}x{n_cells} @ 0.05 m, {n} artefacts placed, catalogue mixture")
    state = builder.poses.copy()
    proposals = [_proposals(builder, rng) for _ in range(repeats + 1)]

    # ours: full scene update (from the same start each time)
    it = iter(proposals * 2)

    def ours_step():
        builder.poses = state.copy()
        builder.step(next(it))

    t_step = _median_ms(ours_step, repeats)
    builder.poses = state.copy()
    builder.step(proposals[0])
    t_grid = _median_ms(lambda: builder.augmented_grid(), repeats)

    P = proposals[0]
    centre, half, yaw = builder.boxes(P)

    def ours_pairs():
        return builder._pair_hits(centre, half, yaw)

    t_pairs = _median_ms(ours_pairs, repeats)
    polys_xy = box_corners(centre[:, :2], half[:, :2], yaw)

    a, b = np.triu_indices(n, k=1)

    def brute():
        polys = shapely.polygons(polys_xy)
        return shapely.intersects(polys[a], polys[b])

    t_brute = _median_ms(brute, max(3, repeats // 2))

    def strtree():
        polys = shapely.polygons(polys_xy)
        return shapely.STRtree(polys).query(polys, predicate="intersects")

    t_tree = _median_ms(strtree, repeats)

    # accuracy: our colliding pairs vs positive shapely intersection area
    polys = shapely.polygons(polys_xy)
    hit = brute()
    area = shapely.area(shapely.intersection(polys[a[hit]], polys[b[hit]]))
    ref = {(int(i), int(j)) for i, j, ar in zip(a[hit], b[hit], area, strict=True) if ar > 1e-9}
    amb = {(int(i), int(j)) for i, j, ar in zip(a[hit], b[hit], area, strict=True) if ar <= 1e-9}
    got = {tuple(map(int, p)) for p in ours_pairs()}
    agree = (got - amb) == ref
    print(f"{'implementation':58s} {'ms':>9s}")
    print(f"{'ours: ARBuilder.step (footprints+embedding+pairs+revert)':58s} {t_step:9.2f}")
    print(f"{'ours: augmented_grid() view (paint footprints, copy grid)':58s} {t_grid:9.2f}")
    print(f"{'ours: pairs only (spatial hash + SAT)':58s} {t_pairs:9.2f}")
    print(f"{'shapely brute force, all pairs intersects':58s} {t_brute:9.2f}")
    print(f"{'shapely STRtree query intersects':58s} {t_tree:9.2f}")
    print(f"ratio brute-force shapely pairs / ours step : {t_brute / t_step:8.1f}x")
    print(f"ratio brute-force shapely pairs / ours pairs: {t_brute / t_pairs:8.1f}x")
    print(f"ratio STRtree / ours pairs                  : {t_tree / t_pairs:8.1f}x")
    print(
        f"colliding pairs: ours {len(got)}, shapely {len(ref)} (touching {len(amb)}); "
        f"agree: {agree}"
    )


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
