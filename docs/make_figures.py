"""Draw every figure the documentation pages describe, with the package's own plotting code.

Run by the mkdocs hook (``docs/hooks.py``) at build time, or by hand::

    python docs/make_figures.py OUT_DIR [NAME ...]

Every figure comes from shipped data (the courtyard map, camera, example log, experiment
config) or seeded synthetic data, at small settings so the whole set takes about a minute
on two cores. Nothing here is committed: the PNGs go to ``OUT_DIR`` (the hook caches them by
the content hash of this script and the package).

``FIGURES`` maps each PNG to the page that shows it; ``make_figures`` draws them by job
(one job can draw several figures, e.g. one fit gives every criticism figure).
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MPLBACKEND", "Agg")
DPI = 100


#: The rooms of the package (subpackages) and what each holds: (name, text, x, y).
_ROOMS = (
    ("logs", "field logs,\ntracks, bags", 0, 1.0),
    ("fitting", "EM, NUTS, LOO;\nread_fit", 1, 1.0),
    ("scenarios", "scenes_from_fit;\nScene; folders", 2, 1.0),
    ("builder", "registration,\ncollisions, nu", 3, 1.0),
    ("perception", "Warp z-buffer,\nA_f (tau)", 4, 1.0),
    ("experiments", "mission init/step,\nplanners, rho", 5, 1.0),
    ("export", "MCAP, Foxglove,\nbag augmentation", 6, 1.0),
    ("traffic", "N(t), arrivals,\nstays, eq. (1)", 1.5, -0.1),
    ("behaviour", "MDP decisions,\nmotion", 2.5, -0.1),
    ("environment", "grids, meshes,\nframes, catalogue Q", 3.5, -0.1),
    ("cli", "are-stats: parses the options, calls the rooms", 3, 2.1),
)
_STEP = 1.45  # distance between neighbouring rooms


def _house(out: Path) -> None:
    """The package as a house: its rooms and the one-way flow fit -> scenes -> mission ->
    export (issue 25), drawn from :data:`_ROOMS`."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    fig, ax = plt.subplots(figsize=(13.0, 4.6))
    w, h = 1.12, 0.62
    centre = {}
    for name, text, x, y in _ROOMS:
        x = x * _STEP
        width = 6 * _STEP + w if name == "cli" else w
        main = y == 1.0
        colour = "#dbe8f6" if main else ("#f2f2f2" if name == "cli" else "#e8f3e1")
        ax.add_patch(
            FancyBboxPatch(
                (x - width / 2, y - h / 2), width, h, boxstyle="round,pad=0.02",
                facecolor=colour, edgecolor="#444", linewidth=1.2,
            )
        )  # fmt: skip
        ax.text(x, y + 0.14, name + "/" if name != "cli" else "cli.py", ha="center",
                va="center", fontsize=10.5, weight="bold")  # fmt: skip
        ax.text(x, y - 0.1, text, ha="center", va="center", fontsize=8.2, color="#333")
        centre[name] = (x, y)

    def arrow(a: str, b: str, label: str = "", colour: str = "#1f4e8c") -> None:
        (xa, ya), (xb, yb) = centre[a], centre[b]
        if ya == yb:
            start, end = (xa + w / 2, ya), (xb - w / 2, yb)
        else:  # from a lower room up into a main one
            start, end = (xa, ya + h / 2), (xb, yb - h / 2)
        ax.add_patch(
            FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=14, color=colour,
                            linewidth=1.6)
        )  # fmt: skip
        if label:
            mid = ((start[0] + end[0]) / 2, (start[1] + end[1]) / 2 + 0.06)
            ax.text(*mid, label, ha="center", va="bottom", fontsize=8.5, color=colour,
                    style="italic")  # fmt: skip

    flow = ["logs", "fitting", "scenarios", "builder", "perception", "experiments", "export"]
    labels = ["log", "Fit", "Scenes", "boxes", "A_f", "trace"]
    for a, b, label in zip(flow[:-1], flow[1:], labels, strict=True):
        arrow(a, b, label)
    arrow("traffic", "scenarios", colour="#3c7a2a")
    arrow("traffic", "fitting", colour="#3c7a2a")
    arrow("behaviour", "scenarios", colour="#3c7a2a")
    arrow("environment", "builder", colour="#3c7a2a")
    arrow("environment", "perception", colour="#3c7a2a")
    ax.text(3 * _STEP, 1.56, "every command (fit, generate, experiment, augment, serve) calls the "
            "same rooms, left to right", ha="center", fontsize=8.2, color="#555")  # fmt: skip
    ax.text(3 * _STEP, -0.6, "models and worlds (green) feed the flow; nothing downstream is "
            "imported upstream", ha="center", fontsize=8.2, color="#3c7a2a")  # fmt: skip
    ax.set_xlim(-0.65, 6 * _STEP + 0.65)
    ax.set_ylim(-0.72, 2.5)
    ax.set_aspect("equal")
    ax.axis("off")
    fig.savefig(out / "house.png", dpi=1.3 * DPI, bbox_inches="tight")
    plt.close(fig)


def _courtyard(out: Path) -> None:
    """``are-stats show courtyard``: the shipped map, its inflation and a few artefacts."""
    from are_stats.builder import show_map

    show_map("courtyard", out / "courtyard.png", inflate=0.4, artefacts=12, seed=0, force=True)


def _fit(out: Path) -> None:
    """A quick NUTS fit of the shipped log, then its criticism figures (``write_report``)."""
    import jax

    import are_stats as ar
    from are_stats.fitting import write_report

    log = ar.read_lifecycle_log(ar.shipped_path("courtyard_traffic", "log"))
    grid = ar.OccupancyGrid.from_ros_yaml(ar.shipped_path("courtyard", "map"))
    settings = ar.FitSettings(method="nuts", num_warmup=150, num_samples=150, num_chains=2)
    idata = ar.fit_log(
        jax.random.key(0),
        log.to_lifecycle_data(),
        settings,
        class_labels=log.to_arrays()["label_names"],
        grid=grid,
        clock_start=log.clock_start,
    ).idata
    with tempfile.TemporaryDirectory() as tmp:
        written = write_report(idata, tmp, key=1, n_replicates=50)
        for name in ("criticism", "traffic_checks"):
            if name not in written:
                raise RuntimeError(f"write_report drew no {name} (it wrote {sorted(written)})")
            shutil.copy(written[name], out / f"{name}.png")


def _behaviour(out: Path) -> None:
    """Values and policy of a walk towards a goal, and a rollout of a small scenario."""
    import jax
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from are_stats.behaviour import GridMDP, plot_tracks, plot_values, scenario_tracks

    occ = np.zeros((14, 20), bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    occ[3:11, 9] = True  # a wall to walk around
    sol = GridMDP(occ).solve([[7, 15]], "walk", 30)
    fig, ax = plt.subplots(figsize=(7, 5))
    plot_values(sol, 0, 0, ax=ax)
    ax.set_title("V_0 (best heading) and the policy of 'walk' to cell (7, 15), d = 30")
    fig.savefig(out / "mdp_values.png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)

    arts = pd.DataFrame(
        {
            "scenario": 0,
            "id": [1, 2, 3, 4],
            "class": ["person", "person", "cart", "pallet"],
            "mark": [7, 7, 3, 1],
            "t_arrive": [0.0, 0.5, 1.0, 0.0],
            "t_leave": [12.0, 12.0, 12.0, 12.0],
            "x": [0.25, 0.35, 1.65, 1.45],
            "y": [0.25, 1.15, 0.35, 1.15],
            "yaw": [0.0, 0.0, np.pi / 2, np.pi],
        }
    )
    beh = {"person": "walk", "cart": "follow", "pallet": "stop"}
    tracks = scenario_tracks(jax.random.key(1), arts, occ, dt=0.5, resolution=0.1, behaviour_of=beh)
    fig = plot_tracks(tracks, occ, times=[0.0, 4.0, 8.0, 12.0], resolution=0.1)
    fig.savefig(out / "behaviour_tracks.png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)


def _crossing_tracks(seed: int, n: int) -> tuple[Any, Any]:
    """Door-to-door crossings of a 20 m x 12 m room (0.5 m cells) at about 1.2 m/s, 2.5 Hz:
    the synthetic tracks of the behaviour tests (``tests.helpers.crossing_world``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.helpers import crossing_world

    return crossing_world(seed, n)


def _motion(out: Path) -> None:
    """Motion checks of a behaviour fitted on 28 of 40 synthetic crossings."""
    import jax
    import matplotlib.pyplot as plt

    from are_stats.fitting import (
        displacement_errors,
        heldout_log_likelihood,
        motion_checks,
        plot_motion_checks,
    )

    tracks, free = _crossing_tracks(3, 40)
    held, fit = heldout_log_likelihood(0, tracks, free, 0.5, (0.0, 0.0), max_fit_tracks=10)
    table, reps = motion_checks(jax.random.key(1), fit, tracks, 50)
    errors = displacement_errors(3, fit, tracks, n_samples=20)
    fig = plot_motion_checks(table, reps, heldout=held, displacement=errors)
    fig.savefig(out / "motion_checks.png", dpi=DPI)
    plt.close(fig)


def _perception(out: Path) -> None:
    """One camera frame in the courtyard: depth with the boxes' A_f status, and a top view."""
    import matplotlib.pyplot as plt
    import numpy as np

    import are_stats as ar
    from are_stats.perception import (
        PerceivedFrame,
        optical_from_base,
        perceive_frames,
        plot_camera_view,
        plot_top_view,
        yaw_rotations,
    )

    grid = ar.OccupancyGrid.from_ros_yaml(ar.shipped_path("courtyard", "map"))
    env = ar.extrude_grid(grid, 2.5)
    cam = ar.PinholeCamera.from_yaml(ar.shipped_path("front_camera", "camera"))
    x, y, yaw = -12.0, -8.0, 0.6
    base = np.eye(4)
    base[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    base[:2, 3] = x, y
    cam = cam.with_pose(base @ optical_from_base([0.0, 0.0, 1.0]))
    # artefacts on free cells, most of them ahead of the robot (seeded)
    rng = np.random.default_rng(3)
    free = np.argwhere(grid.free)
    xy = grid.cell_to_world(free[rng.choice(len(free), 4000, replace=False)])[:, :2]
    rel = xy - [x, y]
    ahead = (rel @ [np.cos(yaw), np.sin(yaw)] > 4.0) & (np.hypot(*rel.T) < 25.0)
    xy = xy[ahead][:18]
    n = len(xy)
    half = np.tile([[0.3, 0.3, 0.9], [0.6, 0.4, 0.5]], (n // 2 + 1, 1))[:n]
    centers = np.column_stack([xy, half[:, 2]])
    yaws = rng.uniform(0, np.pi, n)
    rots = yaw_rotations(yaws)
    res = perceive_frames(env, centers, half, rots, cam, None, 30.0, 50.0, return_depth=True)
    frame = PerceivedFrame.from_result(res, 0, cam, centers, half, rots, 30.0)
    fig = plot_camera_view(frame)
    fig.savefig(out / "camera_view.png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    fig = plot_top_view(frame, grid=grid)
    fig.savefig(out / "top_view.png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)


def _experiments(out: Path) -> None:
    """The shipped ``fig7`` sweep with two replicates instead of three, then Fig. 7."""
    from are_stats.experiments import load_sweep_config, plot_results, run_sweep

    cfg = load_sweep_config("fig7")
    cfg["replicates"] = 2
    with tempfile.TemporaryDirectory() as tmp:
        res = run_sweep(cfg, Path(tmp) / "fig7", workers=1, processes=False, progress=False)
        for path in plot_results(res, Path(tmp) / "plots"):
            shutil.copy(path, out / path.name)


def _augment(out: Path) -> None:
    """The tests' synthetic robot bag (a 12 s drive, ROS 2 MCAP, /tf and a camera) augmented
    with a quick em fit of the shipped log, then its top-down view (``are-stats show``)."""
    import subprocess

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from are_stats.export import augment_bag, plot_mcap
    from tests.export.rosbag_fixtures import write_bag

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        fit = d / "fit.nc"
        subprocess.run(
            [sys.executable, "-m", "are_stats", "fit", "courtyard_traffic", "--method", "em",
             "--out", str(fit), "--seed", "1"],
            check=True, capture_output=True,
        )  # fmt: skip
        bag = write_bag(d / "robot", "mcap")
        res = augment_bag(
            bag, fit, "courtyard", d / "augmented.mcap", seed=1,
            camera_info_topic="/camera/camera_info", period=0.5,
        )  # fmt: skip
        plot_mcap(res.path, out / "augmented_bag.png", force=True)


# figure -> (page that shows it, job that draws it)
JOBS: dict[str, Callable[[Path], None]] = {
    "house": _house,
    "courtyard": _courtyard,
    "fit": _fit,
    "behaviour": _behaviour,
    "motion": _motion,
    "perception": _perception,
    "experiments": _experiments,
    "augment": _augment,
}
FIGURES: dict[str, tuple[str, str]] = {
    "house.png": ("index.md", "house"),
    "courtyard.png": ("environment.md", "courtyard"),
    "criticism.png": ("pipeline.md", "fit"),
    "traffic_checks.png": ("models.md", "fit"),
    "mdp_values.png": ("behaviour.md", "behaviour"),
    "behaviour_tracks.png": ("behaviour.md", "behaviour"),
    "motion_checks.png": ("behaviour.md", "motion"),
    "camera_view.png": ("perception.md", "perception"),
    "top_view.png": ("perception.md", "perception"),
    "fig7a_rho.png": ("experiments.md", "experiments"),
    "fig7b_goals.png": ("experiments.md", "experiments"),
    "augmented_bag.png": ("ros.md", "augment"),
}


def make_figures(out: str | os.PathLike, names: list[str] | None = None) -> list[Path]:
    """Draw the named figures (default: all of ``FIGURES``) into ``out``.

    Parameters
    ----------
    out : path
        Folder for the PNGs (created).
    names : list of str, optional
        PNG names, keys of ``FIGURES``.

    Returns
    -------
    list of Path
        The PNGs drawn, in ``names`` order.

    Raises
    ------
    ValueError
        Naming an unknown figure.
    RuntimeError
        If a job did not draw a figure it owns.
    """
    names = list(FIGURES) if names is None else list(names)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ValueError(f"unknown figures {unknown}: expected some of {sorted(FIGURES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for job in dict.fromkeys(FIGURES[n][1] for n in names):
        JOBS[job](out)
    missing = [n for n in names if not (out / n).is_file()]
    if missing:
        raise RuntimeError(f"the figure jobs drew no {missing} in {out}")
    return [out / n for n in names]


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: python docs/make_figures.py OUT_DIR [NAME ...]")
    for path in make_figures(sys.argv[1], sys.argv[2:] or None):
        print(path)
