"""Write the example field log shipped for the demo (seeded; re-running gives the same bytes).

Truth (stated here and in the manifest's description), chosen so that the paper's model
fits the averages but not the world, and the toolkit's choice matters:

* a 4-hour window [0, 14400] s on the shipped courtyard map (free area from its
  ``courtyard.yaml``), opening on the stationary population and closing with right-censored
  rows;
* **groups**: groups arrive at a rate such that ``1/30`` artefacts per second arrive on
  average (480 expected arrivals); sizes 1, 2, 3, 4 with probabilities (0.6, 0.25, 0.1,
  0.05); members share the arrival time, the entry point (within 0.5 m) and the class,
  and their stays differ from the group's by a factor exp(0.15 e);
* **gamma stays**: mean 600 s, shape 4 (coefficient of variation 0.5, few short stays);
* **door entries**: 90% of groups enter within about a metre of one of three doors
  (the south gate, the west side, the north-east corner), 10% anywhere; exits likewise;
* times rounded to 0.1 s (a tracker's frame period);
* marks from the Poisson mixture of the paper's Fig. 2, rates (15, 7, 3, 21, 5) for the
  classes (person, child, car, pallet, cart) with weights (0.35, 0.2, 0.1, 0.2, 0.15),
  one class per group.

Run: ``python models/make_example_log.py``; it writes ``logs/courtyard_traffic.csv`` and its
manifest into the package data folder ``are_stats/data/`` (the shipped log
``courtyard_traffic``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

import are_stats as ar
from are_stats.environment import coarse_free
from are_stats.traffic import (
    PositionDensity,
    TrafficLaws,
    simulate_traffic_log,
    uniform_position_density,
)

#: The package data folder (the shipped map is read from it, the log written into it).
HERE = Path(__file__).resolve().parents[1] / "are_stats" / "data"
CLASSES = ["person", "child", "car", "pallet", "cart"]
WEIGHTS = [0.35, 0.2, 0.1, 0.2, 0.15]
RATES = [15.0, 7.0, 3.0, 21.0, 5.0]
WINDOW = (0.0, 14400.0)
SIZE_PROBS = [0.6, 0.25, 0.1, 0.05]
MEAN_STAY, STAY_SHAPE = 600.0, 4.0
DOORS = [(0.0, -14.0), (-18.0, 0.0), (17.5, 12.5)]
DOOR_SD, DOOR_SHARE = 0.8, 0.9
SEED = 20261124


def door_density(grid: ar.OccupancyGrid) -> PositionDensity:
    """Gaussian bumps at the doors (90%) over a uniform floor (10%), on free 0.5 m cells."""
    free, res = coarse_free(grid.free, grid.resolution, 0.5)
    origin = (float(grid.origin[0]), float(grid.origin[1]))
    h, w = free.shape
    xc = origin[0] + (np.arange(w) + 0.5) * res
    yc = origin[1] + (np.arange(h) + 0.5) * res
    xx, yy = np.meshgrid(xc, yc)
    bumps = sum(np.exp(-0.5 * ((xx - x) ** 2 + (yy - y) ** 2) / DOOR_SD**2) for x, y in DOORS)
    bumps = np.where(free, bumps, 0.0)
    prob = DOOR_SHARE * bumps / bumps.sum() + (1 - DOOR_SHARE) * free / free.sum()
    return PositionDensity(prob, res, origin, DOOR_SD, np.inf)


def main() -> None:
    grid = ar.OccupancyGrid.from_ros_yaml(HERE / "courtyard.yaml")
    area = grid.free_area
    mean_size = float(np.dot(np.arange(1, 5), SIZE_PROBS))
    event_rate = 1.0 / 30.0 / area / mean_size
    doors = door_density(grid)
    free, res = coarse_free(grid.free, grid.resolution, 0.5)
    origin = (float(grid.origin[0]), float(grid.origin[1]))
    uniform = uniform_position_density(free, res, origin)
    laws = TrafficLaws(
        arrivals="groups",
        lifetimes="gamma",
        positions="learned",
        group_stay_sd=0.15,
        group_spread=0.5,
        entry=doors,
    )
    draw = {
        "event_rate": event_rate,
        "stay_mean": MEAN_STAY,
        "stay_shape": STAY_SHAPE,
        "group_size_probs": np.asarray(SIZE_PROBS),
    }
    rng = np.random.default_rng(SEED)
    data = simulate_traffic_log(rng, draw, laws, WINDOW, area, free=uniform, resolution=0.1)
    n = data.n
    # one class per group, marks from the mixture of eq. (1)
    _, g_code = np.unique(data.group, return_inverse=True)
    g_class = rng.choice(len(CLASSES), size=g_code.max() + 1, p=WEIGHTS)
    labels = g_class[g_code]
    marks = rng.poisson(np.asarray(RATES)[labels])
    exits = doors.sample(rng, n)
    gone = ~data.censored
    df = pd.DataFrame(
        {
            "id": [f"a{i:04d}" for i in range(n)],
            "t_arrive": np.round(data.t_arrive, 1),
            "t_leave": np.round(data.t_leave, 1),
            "label": np.asarray(CLASSES)[labels],
            "mark": marks,
            "x": np.round(data.x, 3),
            "y": np.round(data.y, 3),
            "yaw": np.round(rng.uniform(0, 2 * np.pi, n), 4),
            "group": [f"g{c:04d}" for c in g_code],
            "x_exit": np.where(gone, np.round(exits[:, 0], 3), np.nan),
            "y_exit": np.where(gone, np.round(exits[:, 1], 3), np.nan),
        }
    )
    out = HERE / "logs"
    out.mkdir(exist_ok=True)
    df.to_csv(out / "courtyard_traffic.csv", index=False, na_rep="")
    manifest = {
        "description": (
            "Simulated example log (models/make_example_log.py). Truth: groups arrive at "
            f"{event_rate:.6g} per m^2 per s with sizes 1-4 of probabilities {SIZE_PROBS}; "
            f"gamma stays of mean {MEAN_STAY:g} s and shape {STAY_SHAPE:g}; {DOOR_SHARE:.0%} "
            f"of entries and exits near the doors {DOORS}; mixture weights {WEIGHTS}, rates "
            f"{RATES} for classes {CLASSES} (one class per group); times in 0.1 s steps."
        ),
        "window": list(WINDOW),
        "map": "../courtyard.yaml",
        "time_unit": "s",
        "clock_start": "2026-05-04T08:00:00",
    }
    (out / "courtyard_traffic.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    print(
        f"{n} artefacts in {g_code.max() + 1} groups, {int(data.truncated.sum())} truncated, "
        f"{int(data.censored.sum())} censored; area {area:.2f} m^2"
    )


if __name__ == "__main__":
    main()
