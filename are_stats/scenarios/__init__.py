"""Posterior-predictive scenario generation: artefact populations from fitted priors."""

from are_stats.scenarios._generate import (
    PARAMETER_NAMES,
    SCENARIO_COLUMNS,
    atomic_folder,
    check_folder,
    expected_artefacts,
    generate_scenarios,
    posterior_draws,
    read_scenarios,
    scenario_counts,
    write_scenarios,
)

__all__ = [
    "PARAMETER_NAMES",
    "SCENARIO_COLUMNS",
    "atomic_folder",
    "check_folder",
    "expected_artefacts",
    "generate_scenarios",
    "posterior_draws",
    "read_scenarios",
    "scenario_counts",
    "write_scenarios",
]
