"""are_stats: the ARE paper (Augmented Reality Environment for mobile robots) as software.

The public surface is re-exported here; implementation lives in private ``_module.py``
files inside one subpackage per concept of the paper (traffic, fitting, logs, scenarios,
environment, builder, behaviour, perception, experiments).

Importing ``are_stats`` enables 64-bit floats in JAX (``jax_enable_x64``): the exact
likelihoods of the life-cycle models need double precision. Kernels that are faster in
single precision (behaviours, perception) ask for ``float32`` explicitly.
"""

from __future__ import annotations

import jax as _jax

_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"

__all__ = ["__version__"]

# --- traffic: birth-death N(t), marked Poisson arrivals, Poisson mixture (eq. 1) ---
from are_stats.traffic import (  # noqa: E402
    BirthDeath,
    BirthDeathEvents,
    BirthDeathFit,
    birth_death_loglik,
    fit_birth_death,
)

__all__ += ["BirthDeath", "BirthDeathEvents", "BirthDeathFit", "birth_death_loglik"]
__all__ += ["fit_birth_death"]
from are_stats.traffic import PoissonMixture  # noqa: E402

__all__ += ["PoissonMixture"]
from are_stats.traffic import (  # noqa: E402
    GammaPosterior,
    LifecycleData,
    LifecyclePriors,
    MixturePosterior,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
    lifecycle_model,
    prior_predictive,
    simulate_lifecycle,
)

__all__ += ["GammaPosterior", "LifecycleData", "LifecyclePriors", "MixturePosterior"]
__all__ += ["conjugate_arrival_rate", "conjugate_leave_rate", "conjugate_mixture"]
__all__ += ["lifecycle_model", "prior_predictive", "simulate_lifecycle"]

# --- fitting: EM, NUTS, model criticism ---
from are_stats.fitting import (  # noqa: E402
    MixtureEMResult,
    fit_mixture_em,
    fit_mixture_nuts,
    select_n_components,
)

__all__ += ["MixtureEMResult", "fit_mixture_em", "fit_mixture_nuts", "select_n_components"]
from are_stats.fitting import fit_lifecycle_nuts  # noqa: E402

__all__ += ["fit_lifecycle_nuts"]

from are_stats.fitting import (  # noqa: E402
    FitSettings,
    compare_models,
    fit_arrival_models,
    fit_lifetime_models,
    fit_log,
    fit_summary,
    kaplan_meier,
    read_fit,
    write_fit,
    write_report,
)

__all__ += ["FitSettings", "compare_models", "fit_arrival_models", "fit_lifetime_models"]
__all__ += ["fit_log", "fit_summary", "kaplan_meier", "read_fit", "write_fit", "write_report"]

# --- logs: field-log formats ---
from are_stats.logs import (  # noqa: E402
    LifecycleLog,
    lifecycle_log_from_frame,
    read_count_panel,
    read_lifecycle_log,
    read_tracks,
    read_tracks_bag,
    tracks_to_lifecycle,
    vision_msgs_typestore,
)

__all__ += [
    "LifecycleLog",
    "lifecycle_log_from_frame",
    "read_count_panel",
    "read_lifecycle_log",
    "read_tracks",
    "read_tracks_bag",
    "tracks_to_lifecycle",
    "vision_msgs_typestore",
]

# --- scenarios: posterior-predictive scenario generation ---
from are_stats.scenarios import (  # noqa: E402
    generate_scenarios,
    posterior_draws,
    read_scenarios,
    scenario_counts,
    write_scenarios,
)

__all__ += [
    "generate_scenarios",
    "posterior_draws",
    "read_scenarios",
    "scenario_counts",
    "write_scenarios",
]

# --- environment: occupancy grid, voxel map, meshes, frames, catalogue ---
from are_stats.environment import (  # noqa: E402
    ArtefactCatalogue,
    ArtefactClass,
    OccupancyGrid,
    TransformTree,
    VoxelMap,
    extrude_grid,
    load_catalogue,
    load_mesh,
)

__all__ += [
    "ArtefactCatalogue",
    "ArtefactClass",
    "OccupancyGrid",
    "TransformTree",
    "VoxelMap",
    "extrude_grid",
    "load_catalogue",
    "load_mesh",
]

# --- builder: registration, collisions ---
from are_stats.builder import ARBuilder, OrientedBox, Placement, Resolution  # noqa: E402

__all__ += ["ARBuilder", "OrientedBox", "Placement", "Resolution"]

# --- behaviour: finite-horizon MDP ---
from are_stats.behaviour import (  # noqa: E402
    GridMDP,
    MDPSolution,
    plot_tracks,
    plot_values,
    rollout,
    scenario_tracks,
)

__all__ += ["GridMDP", "MDPSolution", "plot_tracks", "plot_values", "rollout", "scenario_tracks"]

# --- perception: camera, Warp kernels, perceived set A_f ---
from are_stats.perception import (  # noqa: E402
    PerceptionResult,
    PinholeCamera,
    perceive_frames,
    perceive_scenario,
    perceived_counts,
    perceived_counts_batch,
    perceived_grid,
    sample_perceived,
)

__all__ += [
    "PerceptionResult",
    "PinholeCamera",
    "perceive_frames",
    "perceive_scenario",
    "perceived_counts",
    "perceived_counts_batch",
    "perceived_grid",
    "sample_perceived",
]

# --- experiments: robot, planners, metrics ---
from are_stats.experiments import (  # noqa: E402
    AStarPlanner,
    MissionResult,
    OMPLPlanner,
    Robot,
    export_mcap,
    load_results,
    plot_results,
    replanning_ratio,
    run_mission,
    run_sweep,
    space_complexity,
)

__all__ += [
    "AStarPlanner",
    "MissionResult",
    "OMPLPlanner",
    "Robot",
    "export_mcap",
    "load_results",
    "plot_results",
    "replanning_ratio",
    "run_mission",
    "run_sweep",
    "space_complexity",
]
