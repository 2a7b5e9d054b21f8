"""Posterior-predictive scenario generation: artefact populations from fitted priors, the
Scene that turns one scenario into boxes over time, and the scenarios folder (one writer,
:func:`write_scenes`, and one validating reader, :func:`read_scenes`)."""

from are_stats.scenarios._assembly import (
    check_tracks_size,
    move_scenes,
    scene_tracks,
    scenes_from_fit,
    scenes_from_tables,
    scenes_tables,
)
from are_stats.scenarios._behaviour_rule import BEHAVIOUR_SOURCES, behaviour_source
from are_stats.scenarios._folder import (
    FORMAT_VERSION,
    MAX_POSITION,
    ScenesFolder,
    check_positions,
    generate_manifest,
    read_scenes,
    tracks_record,
    write_scenes,
)
from are_stats.scenarios._generate import (
    ORIGIN_YAW_TOLERANCE,
    SCENARIO_COLUMNS,
    ScenarioSize,
    atomic_folder,
    check_folder,
    check_origin_yaw,
    check_scenario_size,
    expected_artefacts,
    generate_scenarios,
    scenario_counts,
)
from are_stats.scenarios._generate_folder import GenerateFolderOptions, generate_folder
from are_stats.scenarios._options import (
    MODEL_CHOICES,
    POSITION_CHOICES,
    AssemblyOptions,
    AssemblySettings,
)
from are_stats.scenarios._realism import (
    REALISM_FEATURES,
    plot_realism,
    realism_features,
    realism_score,
    realism_summary,
    realism_table,
)
from are_stats.scenarios._scene import Boxes, Scene

__all__ = [
    "AssemblyOptions",
    "AssemblySettings",
    "BEHAVIOUR_SOURCES",
    "Boxes",
    "FORMAT_VERSION",
    "MAX_POSITION",
    "MODEL_CHOICES",
    "ORIGIN_YAW_TOLERANCE",
    "POSITION_CHOICES",
    "Scene",
    "ScenesFolder",
    "REALISM_FEATURES",
    "SCENARIO_COLUMNS",
    "ScenarioSize",
    "atomic_folder",
    "behaviour_source",
    "check_folder",
    "check_origin_yaw",
    "check_positions",
    "check_scenario_size",
    "check_tracks_size",
    "expected_artefacts",
    "GenerateFolderOptions",
    "generate_folder",
    "generate_manifest",
    "generate_scenarios",
    "move_scenes",
    "plot_realism",
    "realism_features",
    "realism_score",
    "realism_summary",
    "realism_table",
    "read_scenes",
    "scenario_counts",
    "scene_tracks",
    "scenes_from_fit",
    "scenes_from_tables",
    "scenes_tables",
    "tracks_record",
    "write_scenes",
]
