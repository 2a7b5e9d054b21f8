"""Write the example field log shipped for the demo (seeded; re-running gives the same bytes).

Truth (stated here and in the manifest's description): a 4-hour window [0, 14400] s on the
courtyard map (free area from models/courtyard.yaml), arrival rate lambda such that
lambda * area = 1/30 artefacts per second (480 expected arrivals), mean stay 1/mu = 600 s
(stationary mean 20 artefacts present), marks from the Poisson mixture of the paper's Fig. 2,
rates (15, 7, 3, 21, 5) for the classes (person, child, car, pallet, cart) with weights
(0.35, 0.2, 0.1, 0.2, 0.15). The window opens on the stationary population (left-truncated
rows) and closes with right-censored rows.

Run: ``python models/make_example_log.py``.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pandas as pd
import yaml

import are_stats as ar
from are_stats.traffic import simulate_lifecycle

HERE = Path(__file__).resolve().parent
CLASSES = ["person", "child", "car", "pallet", "cart"]
WEIGHTS = [0.35, 0.2, 0.1, 0.2, 0.15]
RATES = [15.0, 7.0, 3.0, 21.0, 5.0]
WINDOW = (0.0, 14400.0)
LEAVE_RATE = 1.0 / 600.0


def main() -> None:
    grid = ar.OccupancyGrid.from_ros_yaml(HERE / "courtyard.yaml")
    area = grid.free_area
    arrival_rate = 1.0 / 30.0 / area
    data = simulate_lifecycle(
        jax.random.key(20261122),
        arrival_rate,
        LEAVE_RATE,
        WEIGHTS,
        RATES,
        WINDOW,
        area=area,
        free_mask=grid.free,
        resolution=grid.resolution,
        origin=tuple(grid.origin[:2]),
    )
    df = pd.DataFrame(
        {
            "id": [f"a{i:04d}" for i in range(data.n)],
            "t_arrive": np.round(data.t_arrive, 3),
            "t_leave": np.round(data.t_leave, 3),
            "label": np.asarray(CLASSES)[data.labels],
            "mark": data.marks,
            "x": np.round(data.x, 3),
            "y": np.round(data.y, 3),
            "yaw": np.round(data.yaw, 4),
        }
    )
    out = HERE / "logs"
    out.mkdir(exist_ok=True)
    df.to_csv(out / "courtyard_traffic.csv", index=False, na_rep="")
    manifest = {
        "description": (
            "Simulated example log (models/make_example_log.py). Truth: "
            f"lambda = {arrival_rate:.6g} per m^2 per s, mu = {LEAVE_RATE:.6g} per s, "
            f"mixture weights {WEIGHTS}, rates {RATES} for classes {CLASSES}."
        ),
        "window": list(WINDOW),
        "map": "../courtyard.yaml",
        "time_unit": "s",
    }
    (out / "courtyard_traffic.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    print(f"{data.n} artefacts, {int(data.truncated.sum())} truncated, "
          f"{int(data.censored.sum())} censored; area {area:.2f} m^2")


if __name__ == "__main__":
    main()
