"""Navigation experiments (paper Sect. 4, Fig. 6-7): robot, planners, the metrics rho
(eq. 3) and nu (eq. 4), the event-driven experiment loop, Dask sweeps, plots, MCAP
export with ROS conventions, the augmentation of a robot's recorded bag and the live view
(a scenario replay streamed to Foxglove)."""

from are_stats.experiments._augment import (
    AUGMENT_TOPICS,
    CLOCK_TOLERANCE,
    CLOCKS,
    POSE_TYPES,
    AugmentResult,
    BagTrajectory,
    augment_bag,
    read_trajectory,
)
from are_stats.experiments._live import (
    LIVE_TOPICS,
    LiveMessage,
    load_replay,
    replay_messages,
    serve_scenario,
)
from are_stats.experiments._loop import MissionResult, MissionTrace, random_goals, run_mission
from are_stats.experiments._mcap import MCAP_TOPICS, export_mcap
from are_stats.experiments._metrics import (
    path_length,
    replanning_ratio,
    space_complexity,
    time_average,
)
from are_stats.experiments._planners import (
    OMPL_ALGORITHMS,
    AStarPlanner,
    OMPLPlanner,
    Planner,
    astar_cells,
    make_planner,
    timed_plan,
)
from are_stats.experiments._plots import plot_goals, plot_results, plot_rho
from are_stats.experiments._robot import Robot, circle_box_overlap, point_box_distance
from are_stats.experiments._ros import ROS_FRAMES, artefact_frame, parse_start_time
from are_stats.experiments._sweep import (
    expand_tasks,
    load_results,
    load_sweep_config,
    run_sweep,
    run_task,
)

__all__ = [
    "AUGMENT_TOPICS",
    "CLOCKS",
    "CLOCK_TOLERANCE",
    "LIVE_TOPICS",
    "MCAP_TOPICS",
    "POSE_TYPES",
    "ROS_FRAMES",
    "AugmentResult",
    "BagTrajectory",
    "LiveMessage",
    "OMPL_ALGORITHMS",
    "AStarPlanner",
    "MissionResult",
    "MissionTrace",
    "OMPLPlanner",
    "Planner",
    "Robot",
    "artefact_frame",
    "astar_cells",
    "augment_bag",
    "circle_box_overlap",
    "expand_tasks",
    "export_mcap",
    "load_replay",
    "load_results",
    "load_sweep_config",
    "make_planner",
    "parse_start_time",
    "path_length",
    "plot_goals",
    "point_box_distance",
    "plot_results",
    "plot_rho",
    "random_goals",
    "read_trajectory",
    "replanning_ratio",
    "replay_messages",
    "run_mission",
    "run_sweep",
    "run_task",
    "serve_scenario",
    "space_complexity",
    "time_average",
    "timed_plan",
]
