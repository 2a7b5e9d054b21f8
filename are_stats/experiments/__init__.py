"""Navigation experiments (paper Sect. 4, Fig. 6-7): robot, planners, the metrics rho
(eq. 3) and nu (eq. 4), the event-driven experiment loop, Dask sweeps and plots.

What leaves the package (MCAP files, augmented bags, the live Foxglove view) is in
:mod:`are_stats.export`, downstream of this room."""

from are_stats.experiments._loop import MissionResult, MissionTrace, random_goals, run_mission
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
from are_stats.experiments._robot import Robot, circle_box_overlap
from are_stats.experiments._sweep import (
    expand_tasks,
    load_results,
    load_sweep_config,
    run_sweep,
    run_task,
)

__all__ = [
    "OMPL_ALGORITHMS",
    "AStarPlanner",
    "MissionResult",
    "MissionTrace",
    "OMPLPlanner",
    "Planner",
    "Robot",
    "astar_cells",
    "circle_box_overlap",
    "expand_tasks",
    "load_results",
    "load_sweep_config",
    "make_planner",
    "path_length",
    "plot_goals",
    "plot_results",
    "plot_rho",
    "random_goals",
    "replanning_ratio",
    "run_mission",
    "run_sweep",
    "run_task",
    "space_complexity",
    "time_average",
    "timed_plan",
]
