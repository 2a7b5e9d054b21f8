"""behaviour: the finite-horizon MDP H_A(t) of the ARE paper (Sec. 3.2) and its rollouts."""

from __future__ import annotations

__all__: list[str] = []

from are_stats.behaviour._rewards import (  # noqa: E402
    ACTIONS,
    BEHAVIOURS,
    HEADINGS,
    allowed_actions,
    follow_rewards,
)

__all__ += ["ACTIONS", "BEHAVIOURS", "HEADINGS", "allowed_actions", "follow_rewards"]

from are_stats.behaviour._mdp import (  # noqa: E402
    GridMDP,
    MDPSolution,
    backward_induction,
    path_free,
)

__all__ += ["GridMDP", "MDPSolution", "backward_induction", "path_free"]

from are_stats.behaviour._xla import jit_with_options  # noqa: E402

__all__ += ["jit_with_options"]

from are_stats.behaviour._rollout import (  # noqa: E402
    builder_resolver,
    cells_to_tracks,
    rollout,
    scenario_tracks,
)

__all__ += [
    "builder_resolver",
    "cells_to_tracks",
    "rollout",
    "scenario_tracks",
]

from are_stats.behaviour._plots import plot_tracks, plot_values  # noqa: E402

__all__ += ["plot_tracks", "plot_values"]

from are_stats.behaviour._choice import (  # noqa: E402
    TRACK_COLUMNS,
    behaviour_tracks,
    choose_behaviours,
)

__all__ += ["TRACK_COLUMNS", "behaviour_tracks", "choose_behaviours"]
from are_stats.behaviour._soft import (  # noqa: E402
    GOAL_BUCKET,
    MoveObservations,
    SoftSolution,
    move_observations,
    moves_log_likelihood,
    soft_backward_induction,
    soft_policy,
    track_log_likelihoods,
    wall_distance_feature,
)

__all__ += [
    "GOAL_BUCKET",
    "MoveObservations",
    "SoftSolution",
    "move_observations",
    "moves_log_likelihood",
    "soft_backward_induction",
    "soft_policy",
    "track_log_likelihoods",
    "wall_distance_feature",
]

from are_stats.behaviour._model import BehaviourFit, grid_geodesic  # noqa: E402

__all__ += ["BehaviourFit", "grid_geodesic"]

from are_stats.behaviour._generate import (  # noqa: E402
    continuous_path,
    continuous_paths,
    path_points,
    positions_at,
    sample_soft_paths,
    simulate_behaviour_tracks,
    smooth_path,
)

__all__ += [
    "continuous_path",
    "continuous_paths",
    "path_points",
    "positions_at",
    "sample_soft_paths",
    "simulate_behaviour_tracks",
    "smooth_path",
]

from are_stats.behaviour._motion import (  # noqa: E402
    arrival_velocities,
    line_of_sight,
    preferred_speeds,
    string_pull,
    string_pull_many,
    walk_times,
    walk_times_many,
)

__all__ += [
    "arrival_velocities",
    "line_of_sight",
    "preferred_speeds",
    "string_pull",
    "string_pull_many",
    "walk_times",
    "walk_times_many",
]

from are_stats.behaviour._walk import walk_tracks  # noqa: E402

__all__ += ["walk_tracks"]

from are_stats.behaviour._noise import NOISE_ORDER, tracker_noise  # noqa: E402

__all__ += ["NOISE_ORDER", "tracker_noise"]

from are_stats.behaviour._social import (  # noqa: E402
    SocialForce,
    fit_social_force,
    repulsion_evidence,
    social_force_tracks,
)

__all__ += ["SocialForce", "fit_social_force", "repulsion_evidence", "social_force_tracks"]

from are_stats.behaviour._groups import (  # noqa: E402
    formation,
    group_spacing,
    group_tracks,
    slot_offsets,
)

__all__ += ["formation", "group_spacing", "group_tracks", "slot_offsets"]
