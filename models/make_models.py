"""Generate the shipped models (seeded, deterministic): run ``python models/make_models.py``.

They are written into the package's data folder ``are_stats/data/`` (shipped in the wheel and
read with :func:`are_stats.environment.shipped_path`); this script is the only source of:

* ``courtyard.yaml`` + ``courtyard.pgm``: a 40 m x 30 m outdoor courtyard at 0.1 m (ROS
  ``map_server`` trinary map): perimeter walls, three building blocks, a few pillars and
  planters, unknown space outside the walls.
* ``courtyard.ply``: the environment mesh S_E, extruded from the map (walls and pillars
  2.5 m, buildings 8 m).
* ``artefacts/``: low-poly meshes (OBJ) of the artefact classes and ``catalogue.yaml`` (Q).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
#: The package data folder the files are written into (one copy, inside the package).
HERE = REPO / "are_stats" / "data"

RES = 0.1
WIDTH_M, HEIGHT_M = 40.0, 30.0


def courtyard(seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Cell values (row 0 at the bottom) and a mask of the building cells."""
    rng = np.random.default_rng(seed)
    w, h = int(WIDTH_M / RES), int(HEIGHT_M / RES)
    data = np.full((h, w), -1, dtype=np.int8)
    m = 10  # 1 m of unknown outside the walls
    t = 3  # 0.3 m thick walls
    data[m : h - m, m : w - m] = 100
    data[m + t : h - m - t, m + t : w - m - t] = 0
    # a gate in the south wall
    data[m : m + t, 180:220] = 0
    data[:m, 180:220] = 0
    buildings = np.zeros((h, w), bool)
    for i0, i1, j0, j1 in [(200, 287, 13, 120), (13, 90, 290, 387), (130, 180, 230, 300)]:
        buildings[i0:i1, j0:j1] = True
    data[buildings] = 100
    # pillars and planters, away from buildings
    yy, xx = np.mgrid[0:h, 0:w]
    placed = 0
    while placed < 8:
        ci, cj = rng.integers(40, h - 40), rng.integers(40, w - 40)
        r = rng.uniform(2.5, 6.0)
        disk = (yy - ci) ** 2 + (xx - cj) ** 2 <= r * r
        ring = (yy - ci) ** 2 + (xx - cj) ** 2 <= (r + 15) ** 2
        if (data[ring] != 0).any():
            continue
        data[disk] = 100
        placed += 1
    return data, buildings


def artefact_meshes() -> dict[str, object]:
    """Low-poly meshes per class, F_A at the centre of the base, z up, x forward."""
    import trimesh

    def person(scale: float) -> trimesh.Trimesh:
        body = trimesh.creation.cylinder(radius=0.22 * scale, height=1.45 * scale, sections=10)
        body.apply_translation([0, 0, 0.725 * scale])
        head = trimesh.creation.icosphere(subdivisions=1, radius=0.12 * scale)
        head.apply_translation([0, 0, 1.45 * scale + 0.12 * scale])
        return trimesh.util.concatenate([body, head])

    def box(ext, at) -> trimesh.Trimesh:
        b = trimesh.creation.box(extents=ext)
        b.apply_translation(at)
        return b

    car = trimesh.util.concatenate(
        [box([4.4, 1.8, 0.8], [0, 0, 0.55]), box([2.4, 1.6, 0.55], [-0.2, 0, 1.225])]
        + [
            trimesh.creation.cylinder(radius=0.33, height=0.25, sections=10)
            .apply_transform(
                trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0], [0, 0, 0])
            )
            .apply_translation([x, y, 0.33])
            for x in (-1.4, 1.4)
            for y in (-0.78, 0.78)
        ]
    )
    pallet = trimesh.util.concatenate(
        [box([1.2, 0.8, 0.03], [0, 0, 0.135])]
        + [box([1.2, 0.1, 0.12], [0, y, 0.06]) for y in (-0.35, 0.0, 0.35)]
    )
    cart = trimesh.util.concatenate(
        [
            box([1.0, 0.6, 0.35], [0, 0, 0.45]),
            box([0.04, 0.6, 0.5], [-0.48, 0, 0.85]),
        ]
        + [box([0.08, 0.08, 0.27], [x, y, 0.135]) for x in (-0.4, 0.4) for y in (-0.24, 0.24)]
    )
    # a city bicycle with its rider: 1.75 m long, 0.6 m across the bars, 1.7 m high
    wheel = trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0], [0, 0, 0])
    bicycle = trimesh.util.concatenate(
        [
            trimesh.creation.cylinder(radius=0.34, height=0.05, sections=12)
            .apply_transform(wheel)
            .apply_translation([x, 0, 0.34])
            for x in (-0.53, 0.53)
        ]
        + [
            box([1.06, 0.05, 0.05], [0, 0, 0.55]),  # frame
            box([0.05, 0.6, 0.05], [0.45, 0, 1.0]),  # handlebar
            box([0.34, 0.36, 0.72], [-0.1, 0, 1.05]),  # rider's body
        ]
    )
    rider_head = trimesh.creation.icosphere(subdivisions=1, radius=0.12)
    rider_head.apply_translation([-0.05, 0, 1.58])
    bicycle = trimesh.util.concatenate([bicycle, rider_head])
    # a skater on a board: 0.8 m board, 1.75 m high, 0.45 m across the shoulders
    skater = trimesh.util.concatenate(
        [box([0.8, 0.22, 0.1], [0, 0, 0.05]), person(1.0).apply_translation([0, 0, 0.1])]
    )
    skater = trimesh.util.concatenate(
        [skater, box([0.3, 0.45, 0.4], [0, 0, 1.2])]  # shoulders, arms out for balance
    )
    return {
        "person": person(1.0),
        "child": person(0.65),
        "car": car,
        "pallet": pallet,
        "cart": cart,
        "bicycle": bicycle,
        "skater": skater,
    }


CATALOGUE = """\
# The artefact catalogue Q (paper Sect. 3.2; DECISIONS 5): classes in mixture-component order;
# each class's variants are its rows of Q, selected by the mark (clipped to the last row).
# Bounding boxes are derived from the meshes. Speeds in m/s. Generated by make_models.py.
version: 1
classes:
  - label: person
    mesh: person.obj
    speeds: {walk: 1.2, run: 3.0}
    behaviours: [walk, run, follow, stop]
    features: {colour: [200, 80, 60], mass_kg: 75, kind: pedestrian}
    variants: {rows: 31, scale: [0.85, 1.15]}
  - label: child
    mesh: child.obj
    speeds: {walk: 0.9, run: 2.5}
    behaviours: [walk, run, follow, stop]
    features: {colour: [240, 170, 40], mass_kg: 25, kind: pedestrian}
    variants: {rows: 15, scale: [0.8, 1.2]}
  - label: car
    mesh: car.obj
    speeds: {walk: 2.0, run: 5.0}
    behaviours: [walk, run, stop]
    features: {colour: [60, 90, 200], mass_kg: 1300, kind: vehicle}
    variants:
      - {scale: [0.85, 0.95, 0.95], features: {body: compact, mass_kg: 1000}}
      - {scale: 1.0, features: {body: sedan}}
      - {scale: [1.05, 1.05, 1.2], features: {body: suv, mass_kg: 1900}}
      - {scale: [1.2, 1.1, 1.35], features: {body: van, mass_kg: 2300}}
  - label: pallet
    mesh: pallet.obj
    speeds: {walk: 0.01}
    behaviours: [stop]
    features: {colour: [160, 120, 70], mass_kg: 20, kind: static}
    variants:
      - {scale: 1.0, features: {load: empty}}
      - {scale: [1.0, 1.0, 4.0], features: {load: boxes, mass_kg: 250}}
      - {scale: [1.0, 1.0, 8.0], features: {load: stacked, mass_kg: 600}}
  - label: cart
    mesh: cart.obj
    speeds: {walk: 0.8}
    behaviours: [walk, follow, stop]
    features: {colour: [90, 160, 90], mass_kg: 40, kind: pushed}
    variants: {rows: 10, scale: [0.9, 1.1]}
  - label: bicycle
    mesh: bicycle.obj
    speeds: {walk: 4.0, run: 7.0}
    behaviours: [walk, run, stop]
    features: {colour: [40, 160, 200], mass_kg: 90, kind: cycle}
    variants: {rows: 10, scale: [0.9, 1.1]}
  - label: skater
    mesh: skater.obj
    speeds: {walk: 2.5, run: 5.0}
    behaviours: [walk, run, follow, stop]
    features: {colour: [180, 60, 180], mass_kg: 70, kind: skater}
    variants: {rows: 10, scale: [0.9, 1.1]}
"""


def main() -> None:
    import yaml

    from are_stats.environment import OccupancyGrid, extrude_grid, occupied_polygons

    data, buildings = courtyard()
    grid = OccupancyGrid(data, RES, (-20.0, -15.0, 0.0))
    (HERE / "courtyard.yaml").unlink(missing_ok=True)
    (HERE / "courtyard.pgm").unlink(missing_ok=True)
    grid.to_ros_yaml(HERE / "courtyard.yaml")
    meta = yaml.safe_load((HERE / "courtyard.yaml").read_text())
    assert meta["image"] == "courtyard.pgm"

    import trimesh

    walls = grid.copy()
    walls.data[buildings] = 0
    low = extrude_grid(walls, 2.5)
    high = [
        trimesh.creation.extrude_polygon(p, 8.0, engine="earcut")
        for p in occupied_polygons(grid, buildings)
    ]
    mesh = trimesh.util.concatenate([low, *high])
    mesh.export(HERE / "courtyard.ply", file_type="ply", encoding="binary")

    out = HERE / "artefacts"
    out.mkdir(exist_ok=True)
    for name, m in artefact_meshes().items():
        m.export(
            out / f"{name}.obj",
            file_type="obj",
            include_normals=False,
            include_texture=False,
            digits=4,
        )
    (out / "catalogue.yaml").write_text(CATALOGUE)
    print(f"courtyard: {grid}; mesh {len(mesh.faces)} faces")


if __name__ == "__main__":
    main()
