"""are_stats: the ARE paper (Augmented Reality Environment for mobile robots) as software.

The public surface is re-exported here; implementation lives in private ``_module.py``
files inside one subpackage per concept of the paper (traffic, fitting, logs, scenarios,
environment, builder, behaviour, perception, experiments, export).

Names are loaded on first use (PEP 562), so ``import are_stats`` and ``are-stats --help``
stay fast: JAX, Warp, ArviZ and the rest are imported only by the part that needs them.

Importing ``are_stats`` enables 64-bit floats in JAX (``jax_enable_x64``): the exact
likelihoods of the life-cycle models need double precision. Kernels that are faster in
single precision (behaviours, perception) ask for ``float32`` explicitly.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import TYPE_CHECKING, Any


def configure_jax(cache: bool | None = None) -> None:
    """Settings JAX needs for are_stats: 64-bit floats and the persistent compile cache.

    The compiled XLA programs are kept in ``$XDG_CACHE_HOME/are_stats/jax`` (default
    ``~/.cache/are_stats/jax``), small programs included, so a second process skips most
    compiling. ``ARE_STATS_NO_CACHE=1`` (or ``are-stats --no-cache``, or ``cache=False``)
    turns the cache off; a ``JAX_COMPILATION_CACHE_DIR`` set by the user is kept.
    The traced programs that :mod:`are_stats._program_cache` keeps (so that a second
    process does not trace them again) go to ``$XDG_CACHE_HOME/are_stats/programs``
    (``ARE_STATS_PROGRAM_CACHE``), on and off with the rest. Each ``are-stats`` run then
    keeps both folders under their cap (:func:`are_stats._program_cache.prune_cache`,
    ``ARE_STATS_CACHE_MAX_MB``, default 1024).

    Called on import; JAX reads the settings when it is first imported (by whichever part
    of are_stats needs it), or they are applied at once when JAX is already loaded.
    """
    if cache is None:
        cache = os.environ.get("ARE_STATS_NO_CACHE", "") in ("", "0")
    settings: dict[str, bool | float | str | None] = {"jax_enable_x64": True}
    # the cache directory is ours to manage unless the user chose one
    ours = os.environ.get("ARE_STATS_JAX_CACHE", "") == os.environ.get(
        "JAX_COMPILATION_CACHE_DIR", ""
    )
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    os.environ["ARE_STATS_PROGRAM_CACHE"] = (
        os.path.join(base, "are_stats", "programs") if cache else ""
    )
    folder = ""
    if ours:
        if cache:
            folder = os.path.join(base, "are_stats", "jax")
        settings["jax_compilation_cache_dir"] = folder or None
        settings["jax_persistent_cache_min_compile_time_secs"] = 0.0 if cache else 1.0
        settings["jax_persistent_cache_min_entry_size_bytes"] = -1 if cache else 0
        os.environ["ARE_STATS_JAX_CACHE"] = folder
    jax = sys.modules.get("jax")
    for name, value in settings.items():
        if jax is not None:
            jax.config.update(name, value)
        elif value is None:
            os.environ.pop(name.upper(), None)
        else:
            os.environ[name.upper()] = "1" if value is True else str(value)


configure_jax()

__version__ = "0.1.0"

# name -> subpackage that defines it
_LAZY: dict[str, str] = {}
# --- traffic: birth-death N(t), marked Poisson arrivals, Poisson mixture (eq. 1) ---
_LAZY.update(
    dict.fromkeys(
        [
            "BirthDeath",
            "BirthDeathEvents",
            "BirthDeathFit",
            "birth_death_loglik",
            "fit_birth_death",
            "PoissonMixture",
            "GammaPosterior",
            "LifecycleData",
            "LifecyclePriors",
            "MixturePosterior",
            "conjugate_arrival_rate",
            "conjugate_leave_rate",
            "conjugate_mixture",
            "lifecycle_model",
            "prior_predictive",
            "simulate_lifecycle",
            "TrafficLaws",
            "sample_population",
            "simulate_traffic_log",
        ],
        "are_stats.traffic",
    )
)
# --- fitting: EM, NUTS, model choice, criticism ---
_LAZY.update(
    dict.fromkeys(
        [
            "MixtureEMResult",
            "fit_mixture_em",
            "fit_mixture_nuts",
            "select_n_components",
            "fit_lifecycle_nuts",
            "Fit",
            "FitSettings",
            "fit_log",
            "fit_summary",
            "posterior_draws",
            "traffic_draws",
            "kaplan_meier",
            "read_fit",
            "write_fit",
            "write_report",
            "fit_loo",
            "pointwise_log_likelihood",
            "TrafficFit",
            "fit_traffic",
            "run_nuts",
        ],
        "are_stats.fitting",
    )
)
# --- logs: field-log formats ---
_LAZY.update(
    dict.fromkeys(
        [
            "LifecycleLog",
            "lifecycle_log_from_frame",
            "read_count_panel",
            "read_field_log",
            "read_lifecycle_log",
            "read_tracks",
            "read_tracks_bag",
            "tracks_to_lifecycle",
            "vision_msgs_typestore",
        ],
        "are_stats.logs",
    )
)
# --- scenarios: posterior-predictive scenario generation ---
_LAZY.update(
    dict.fromkeys(
        [
            "generate_scenarios",
            "read_scenes",
            "scenario_counts",
            "scenes_from_fit",
            "write_scenes",
            "Boxes",
            "Scene",
        ],
        "are_stats.scenarios",
    )
)
# --- environment: occupancy grid, voxel map, meshes, frames, catalogue ---
_LAZY.update(
    dict.fromkeys(
        [
            "ArtefactCatalogue",
            "ArtefactClass",
            "OccupancyGrid",
            "TransformTree",
            "VoxelMap",
            "extrude_grid",
            "load_catalogue",
            "load_mesh",
            "resolve_shipped",
            "shipped_names",
            "shipped_path",
        ],
        "are_stats.environment",
    )
)
# --- builder: registration, collisions ---
_LAZY.update(
    dict.fromkeys(["ARBuilder", "OrientedBox", "Placement", "Resolution"], "are_stats.builder")
)
# --- behaviour: finite-horizon MDP ---
_LAZY.update(
    dict.fromkeys(
        ["GridMDP", "MDPSolution", "plot_tracks", "plot_values", "rollout", "scenario_tracks"],
        "are_stats.behaviour",
    )
)
# --- perception: camera, Warp kernels, perceived set A_f ---
_LAZY.update(
    dict.fromkeys(
        [
            "PerceptionResult",
            "PinholeCamera",
            "perceive_frames",
            "perceive_scenario",
            "perceive_scene",
            "perceived_counts",
            "perceived_counts_batch",
            "perceived_grid",
            "sample_perceived",
        ],
        "are_stats.perception",
    )
)
# --- experiments: robot, planners, metrics ---
_LAZY.update(
    dict.fromkeys(
        [
            "AStarPlanner",
            "MissionResult",
            "OMPLPlanner",
            "Robot",
            "load_results",
            "plot_results",
            "replanning_ratio",
            "run_mission",
            "run_sweep",
            "space_complexity",
        ],
        "are_stats.experiments",
    )
)
# --- export: MCAP, augmented bags, the live view ---
_LAZY.update(dict.fromkeys(["augment_bag", "export_mcap", "serve_scenario"], "are_stats.export"))

__all__ = ["__version__", "configure_jax", *_LAZY]

# Real types for type checkers and IDEs: the names of _LAZY, imported only when type
# checking (tests/test_import.py checks that the two lists agree)
if TYPE_CHECKING:
    from are_stats.behaviour import (  # noqa: F401
        GridMDP,
        MDPSolution,
        plot_tracks,
        plot_values,
        rollout,
        scenario_tracks,
    )
    from are_stats.builder import (  # noqa: F401
        ARBuilder,
        OrientedBox,
        Placement,
        Resolution,
    )
    from are_stats.environment import (  # noqa: F401
        ArtefactCatalogue,
        ArtefactClass,
        OccupancyGrid,
        TransformTree,
        VoxelMap,
        extrude_grid,
        load_catalogue,
        load_mesh,
        resolve_shipped,
        shipped_names,
        shipped_path,
    )
    from are_stats.experiments import (  # noqa: F401
        AStarPlanner,
        MissionResult,
        OMPLPlanner,
        Robot,
        load_results,
        plot_results,
        replanning_ratio,
        run_mission,
        run_sweep,
        space_complexity,
    )
    from are_stats.export import (  # noqa: F401
        augment_bag,
        export_mcap,
        serve_scenario,
    )
    from are_stats.fitting import (  # noqa: F401
        Fit,
        FitSettings,
        MixtureEMResult,
        TrafficFit,
        fit_lifecycle_nuts,
        fit_log,
        fit_loo,
        fit_mixture_em,
        fit_mixture_nuts,
        fit_summary,
        fit_traffic,
        kaplan_meier,
        pointwise_log_likelihood,
        posterior_draws,
        read_fit,
        run_nuts,
        select_n_components,
        traffic_draws,
        write_fit,
        write_report,
    )
    from are_stats.logs import (  # noqa: F401
        LifecycleLog,
        lifecycle_log_from_frame,
        read_count_panel,
        read_field_log,
        read_lifecycle_log,
        read_tracks,
        read_tracks_bag,
        tracks_to_lifecycle,
        vision_msgs_typestore,
    )
    from are_stats.perception import (  # noqa: F401
        PerceptionResult,
        PinholeCamera,
        perceive_frames,
        perceive_scenario,
        perceive_scene,
        perceived_counts,
        perceived_counts_batch,
        perceived_grid,
        sample_perceived,
    )
    from are_stats.scenarios import (  # noqa: F401
        Boxes,
        Scene,
        generate_scenarios,
        read_scenes,
        scenario_counts,
        scenes_from_fit,
        write_scenes,
    )
    from are_stats.traffic import (  # noqa: F401
        BirthDeath,
        BirthDeathEvents,
        BirthDeathFit,
        GammaPosterior,
        LifecycleData,
        LifecyclePriors,
        MixturePosterior,
        PoissonMixture,
        TrafficLaws,
        birth_death_loglik,
        conjugate_arrival_rate,
        conjugate_leave_rate,
        conjugate_mixture,
        fit_birth_death,
        lifecycle_model,
        prior_predictive,
        sample_population,
        simulate_lifecycle,
        simulate_traffic_log,
    )


def __getattr__(name: str) -> Any:  # any of the names in _LAZY: functions, classes, data
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'are_stats' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
