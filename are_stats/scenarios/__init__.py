"""Posterior-predictive scenario generation: artefact populations from fitted priors, and
the Scene that turns one scenario into boxes over time."""

from are_stats.scenarios._assembly import (
    BEHAVIOUR_SOURCES,
    check_tracks_size,
    scenes_from_draws,
    scenes_from_fit,
)
from are_stats.scenarios._generate import (
    PARAMETER_NAMES,
    SCENARIO_COLUMNS,
    TRAFFIC_NAMES,
    atomic_folder,
    check_folder,
    check_scenario_size,
    expected_artefacts,
    generate_scenarios,
    posterior_draws,
    read_scenarios,
    scenario_counts,
    traffic_draws,
    write_scenario_files,
    write_scenarios,
)
from are_stats.scenarios._scene import Boxes, Scene

__all__ = [
    "BEHAVIOUR_SOURCES",
    "Boxes",
    "Scene",
    "PARAMETER_NAMES",
    "SCENARIO_COLUMNS",
    "TRAFFIC_NAMES",
    "atomic_folder",
    "check_folder",
    "check_scenario_size",
    "check_tracks_size",
    "expected_artefacts",
    "generate_scenarios",
    "posterior_draws",
    "read_scenarios",
    "scenario_counts",
    "scenes_from_draws",
    "scenes_from_fit",
    "traffic_draws",
    "write_scenario_files",
    "write_scenarios",
]
