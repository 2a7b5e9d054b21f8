"""The ``are-stats`` command line: thin wrappers over the package's functions."""

from __future__ import annotations

import functools
import gc
import os
import sys
import warnings
from collections.abc import Callable
from typing import Annotated, ParamSpec, TextIO, TypeVar

# Two XLA host devices so that NUTS chains run in parallel on the two cores; must be set
# before JAX is imported (by are_stats).
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
# XLA's C++ log lines (e.g. the 'Very slow compile? If you want to file a bug' alarm of a long
# CPU compile) are for XLA's developers, not for this command's users; errors that matter
# reach Python as exceptions. A level the user set wins.
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from pathlib import Path  # noqa: E402

import typer  # noqa: E402

from are_stats import __version__, configure_jax  # noqa: E402
from are_stats._atomic import OutputExistsError  # noqa: E402 (stdlib only)
from are_stats._lazy import hide_dask, hide_numba  # noqa: E402 (stdlib only)
from are_stats._program_cache import prune_cache  # noqa: E402 (stdlib only; main runs it)

# The commands import their rooms when they run: `are-stats --help` and each command load
# only what they use (each import says what it would add to `--help`, measured 2026-11-28).

app = typer.Typer(
    name="are-stats",
    help=(
        "ARE toolkit: fit artefact life-cycle priors from field logs, generate "
        "posterior-predictive scenarios, build augmented maps, compute what the robot "
        "perceives and run navigation experiments."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # click's plain help: it wraps every option's text under its full name at the terminal's
    # width (rich's boxed tables cut long option names, e.g. --behaviour-features, at 80
    # columns and squeezed their help into a narrow column)
    rich_markup_mode=None,
)

# The commands' positional arguments (FIT and SCENARIOS_DIR serve two commands each): a
# command's signature lists them without a default, before its options.
_FIT_HELP = "A fit written by are-stats fit."
_Fit = Annotated[Path, typer.Argument(metavar="FIT", help=_FIT_HELP)]
_ScenariosDir = Annotated[
    Path,
    typer.Argument(metavar="SCENARIOS_DIR", help="Scenarios folder written by are-stats generate."),
]
_MapOrBag = Annotated[
    str,
    typer.Argument(
        metavar="MAP",
        help="ROS map YAML, the name of a shipped map (courtyard), or an MCAP/bag written "
        "by augment or experiment --mcap.",
    ),
]
_Log = Annotated[
    Path,
    typer.Argument(
        metavar="LOG",
        help="Field log (CSV or Parquet): a life-cycle log (id, t_arrive, t_leave, ...) or a "
        "tracks table (id, t, x, y [, label]), told apart by its columns; or a shipped log "
        "(courtyard_traffic).",
    ),
]
_SweepConfig = Annotated[
    str,
    typer.Argument(
        metavar="CONFIG.yaml", help="Sweep config (YAML), or a shipped one (fig7, fig7_fit)."
    ),
]
_Results = Annotated[str, typer.Argument(metavar="RESULTS", help="Sweep results folder.")]
_Bag = Annotated[
    Path, typer.Argument(metavar="BAG", help="Robot bag: ROS 1 .bag, ROS 2 bag folder or .mcap.")
]

# Options that several commands share: the same flag, help text and meaning (each command
# gives its own default).
_DMax = Annotated[float, typer.Option("--d-max", help="Maximum viewing distance d_max (m).")]
_Tau = Annotated[float, typer.Option("--tau", help="Pixels needed to perceive (count > tau).")]
_ForceOutputs = Annotated[bool, typer.Option("--force", help="Overwrite existing outputs.")]
_Camera = Annotated[
    Path,
    typer.Option(
        "--camera", help="Camera YAML (ROS camera_info fields) or a shipped camera (front_camera)."
    ),
]
_Model = Annotated[
    str,
    typer.Option(
        "--model",
        help="chosen: the traffic models the fit chose (groups, stays, entries); paper: "
        "Poisson arrivals, exponential stays, uniform positions (for a fit whose learned "
        "entries belong to another map).",
    ),
]
_Positions = Annotated[
    str,
    typer.Option(
        "--positions",
        help="chosen: where --model places artefacts (the fit's learned entries, if it "
        "chose them); uniform: uniformly on the map's free cells, keeping the model's "
        "arrivals and stays (for a fit whose learned entries belong to another map).",
    ),
]

# How a robot bag is read (augment, serve --bag): the fields of logs.TrajectoryOptions.
_PoseTopic = Annotated[
    str,
    typer.Option(
        "--pose-topic",
        help="Robot poses from this topic of the bag (PoseStamped, PoseWithCovarianceStamped, "
        "Odometry).",
    ),
]
_BaseFrame = Annotated[
    str,
    typer.Option(
        "--base-frame", help="Robot poses from the bag's /tf: map -> ... -> this frame (base_link)."
    ),
]
_MapFrame = Annotated[
    str,
    typer.Option(
        "--map-frame",
        help="Fixed frame of the artefacts (odom is used when the bag's tree has no map).",
    ),
]
_CameraFrame = Annotated[
    str,
    typer.Option(
        "--camera-frame",
        help="The camera's frame in the bag's tree (default: the CameraInfo's frame).",
    ),
]
_CameraInfoTopic = Annotated[
    str,
    typer.Option(
        "--camera-info-topic",
        help="The bag's sensor_msgs/CameraInfo topic: the camera's intrinsics and frames.",
    ),
]
_Clock = Annotated[
    str,
    typer.Option(
        "--clock",
        help="The bag's clock of poses, camera frames and start: header stamps, log "
        "(recording) times, or auto (header stamps when set).",
    ),
]

# Errors that mean "bad input or environment": one line on stderr, exit status 2.
# (ValueError covers are_stats.inputs.InputError/LimitError; OSError covers missing files,
# directories where files belong, permissions and full disks.)
_USER_ERRORS = (ValueError, OSError)


#: The parameters and result of a command function (the decorators keep its signature, which
#: typer reads for the options).
_P = ParamSpec("_P")
_R = TypeVar("_R")


def _fail(err: BaseException) -> typer.Exit:
    # an existing output: the remedy in the command line's words (--force, not force=True)
    text = err.cli_message if isinstance(err, OutputExistsError) else str(err)
    typer.echo(f"error: {text}", err=True)
    return typer.Exit(2)


def _cli_errors(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run a command so that users see one clear line, never a traceback.

    Bad input exits with status 2 and ``error: <file>: <where>: expected ..., got ...``.
    Anything else is a bug in are_stats: it exits with status 1 and says so (the traceback
    is printed only with ``ARE_STATS_DEBUG=1``).
    """

    @functools.wraps(func)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        try:
            return func(*args, **kwargs)
        except (typer.Exit, typer.Abort, KeyboardInterrupt):
            raise
        except _USER_ERRORS as err:
            raise _fail(err) from None
        except MemoryError:
            typer.echo(
                "error: out of memory; lower the input's sizes or the limits "
                "(are-stats --max-memory SIZE)",
                err=True,
            )
            raise typer.Exit(2) from None
        except Exception as err:  # a bug: say so plainly instead of a traceback
            if os.environ.get("ARE_STATS_DEBUG"):
                raise
            typer.echo(
                f"internal error in are-stats ({type(err).__name__}: {err}); please report it "
                "with the command line (ARE_STATS_DEBUG=1 shows the traceback)",
                err=True,
            )
            raise typer.Exit(1) from None

    return wrapper


def _command(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """A command of :data:`app` whose errors users see as one line (:func:`_cli_errors`)."""
    return app.command()(_cli_errors(func))


def _seed(seed: int) -> int:
    # lazy: +0.21 s CPU on `are-stats --help` (NumPy, YAML)
    from are_stats.inputs import get_seed

    return get_seed(seed, "--seed")


def _print_version(value: bool) -> None:
    if value:
        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _limits(
    show_version: bool = typer.Option(
        False,
        "--version",
        help="Print the are_stats version and exit.",
        is_eager=True,
        callback=_print_version,
    ),
    max_memory: str = typer.Option(
        None,
        "--max-memory",
        help="Largest input-sized allocation, e.g. 16G (default 4G; ARE_STATS_MAX_MEMORY).",
    ),
    max_work: str = typer.Option(
        None,
        "--max-work",
        help="Most elementary steps one computation may take (default 5e10; ARE_STATS_MAX_WORK).",
    ),
    no_cache: bool = typer.Option(
        False,
        "--no-cache",
        help="Keep no compiled or traced JAX programs in $XDG_CACHE_HOME/are_stats "
        "(ARE_STATS_NO_CACHE=1).",
    ),
) -> None:
    """Limits that refuse runaway inputs before anything is allocated; the compile cache."""
    # lazy: +0.21 s CPU on `are-stats --help` (NumPy, YAML)
    from are_stats.inputs import parse_size

    if no_cache:
        os.environ["ARE_STATS_NO_CACHE"] = "1"
        configure_jax(cache=False)

    try:
        # Environment variables, so that Dask workers and subprocesses inherit them.
        if max_memory is not None:
            os.environ["ARE_STATS_MAX_MEMORY"] = str(parse_size(max_memory, "--max-memory"))
        if max_work is not None:
            os.environ["ARE_STATS_MAX_WORK"] = str(parse_size(max_work, "--max-work"))
    except ValueError as err:
        raise _fail(err) from None


@app.command()
def version() -> None:
    """Print the are_stats version."""
    typer.echo(__version__)


@_command
def show(
    map_path: _MapOrBag,
    out: str = typer.Option(None, "--out", help="PNG to write (default: <map name>.png)."),
    inflate: float = typer.Option(None, "--inflate", help="Inflation radius to draw (m)."),
    artefacts: int = typer.Option(0, "--artefacts", help="Random catalogue artefacts to place."),
    seed: int = typer.Option(0, "--seed", help="Seed for the artefact placement."),
    at: float = typer.Option(
        None, "--at", help="An MCAP/bag: seconds after its start (default: most perceived)."
    ),
    force: bool = typer.Option(False, "--force", help="Overwrite the PNG."),
) -> None:
    """Render an occupancy grid, its inflation and artefacts to a PNG; or an MCAP/bag from
    above at one time (map, augmented cells, artefacts, robot and camera)."""
    # lazy: builder +0.23 s, logs +0.93 s (pandas) CPU on `are-stats --help`
    from are_stats.builder import show_map
    from are_stats.logs import is_bag_path

    if is_bag_path(map_path):
        # lazy: +2.2 s CPU on `are-stats --help` (JAX, the scenarios room)
        from are_stats.export import plot_mcap

        typer.echo(str(plot_mcap(map_path, out, at=at, force=force)))
        return
    path = show_map(
        map_path, out, inflate=inflate, artefacts=artefacts, seed=_seed(seed), force=force
    )
    typer.echo(str(path))


@_command
def fit(
    log: _Log,
    out: Path = typer.Option(..., "--out", help="Fit to write, e.g. fits/NAME.nc (NetCDF)."),
    method: str = typer.Option(
        "nuts", "--method", help="nuts: joint posterior by NUTS; em: conjugate rates + EM."
    ),
    seed: int = typer.Option(0, "--seed", help="Seed of the fit (same seed, same fit)."),
    force: _ForceOutputs = False,
    window: tuple[float, float] | None = typer.Option(
        None, "--window", help="Observation window T0 T1 (log's time unit)."
    ),
    area: float = typer.Option(None, "--area", help="Free area in m^2 (overrides the manifest)."),
    manifest: Path = typer.Option(None, "--manifest", help="Manifest YAML (default: beside LOG)."),
    counts: Path = typer.Option(
        None, "--counts", help="Count panel CSV/Parquet (t, count) for the birth-death MLE."
    ),
    components: int = typer.Option(
        None, "--components", help="Mixture components (default: labels, else BIC)."
    ),
    warmup: int = typer.Option(1000, "--warmup", help="NUTS warm-up draws per chain."),
    samples: int = typer.Option(1000, "--samples", help="NUTS draws per chain."),
    chains: int = typer.Option(4, "--chains", help="NUTS chains."),
    figures: Path = typer.Option(
        None, "--figures", help="Folder for criticism figures (default: OUT without .nc)."
    ),
    no_figures: bool = typer.Option(False, "--no-figures", help="Skip the criticism figures."),
    arrivals: str = typer.Option(
        "auto",
        "--arrivals",
        help="auto (compare by PSIS-LOO) | poisson | negbin | groups | time-of-day | "
        "negbin+time-of-day | groups+time-of-day | mmpp | hawkes | groups+mmpp | "
        "groups+hawkes | mmpp+time-of-day | hawkes+time-of-day | groups+mmpp+time-of-day | "
        "groups+hawkes+time-of-day.",
    ),
    lifetimes: str = typer.Option(
        "auto", "--lifetimes", help="auto | exponential | gamma | weibull | lognormal."
    ),
    positions: str = typer.Option(
        "auto", "--positions", help="auto | uniform | learned (entry density; needs a map)."
    ),
    clock_start: str = typer.Option(
        None,
        "--clock-start",
        help="ISO 8601 wall-clock time of t = 0 (overrides the manifest's clock_start).",
    ),
    behaviour: bool = typer.Option(
        True, help="Tracks tables: also fit the behaviour (speeds, exits, rationality)."
    ),
    behaviour_features: str = typer.Option(
        "",
        "--behaviour-features",
        help="Reward features whose weights the behaviour fit estimates with beta and slip, "
        "comma-separated: walls (closeness to walls). Default: none.",
    ),
    compare: str = typer.Option(
        "laplace",
        "--compare",
        help="How --method nuts compares the traffic candidates: laplace (PSIS-LOO from "
        "each one's Laplace approximation; the chosen one's draws importance-resampled, NUTS "
        "where their Pareto k is 0.7 or more) | nuts (all sampled).",
    ),
    stationary_start: bool = typer.Option(
        True, help="NUTS: use the Poisson(lambda*area/mu) count present at T0 (couples the rates)."
    ),
    exact: bool = typer.Option(
        True,
        help="--method nuts: the paper's model by exact posterior draws where it has them "
        "(no NUTS; a mixture of several classes without labels is sampled by NUTS); "
        "--no-exact: always NUTS.",
    ),
) -> None:
    """Fit a field log: the paper's rates and mixture, and the traffic models the data choose.

    Writes the NetCDF fit (posteriors, chosen models, comparison tables) and its figures.
    """
    # lazy: the jobs add 2.5 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import FitOptions, run_fit

    options = FitOptions(
        method=method,
        seed=_seed(seed),
        window=window,
        area=area,
        manifest=manifest,
        counts=counts,
        components=components,
        warmup=warmup,
        samples=samples,
        chains=chains,
        figures=None if no_figures else (figures or out.with_suffix("")),
        stationary_start=stationary_start,
        arrivals=arrivals,
        lifetimes=lifetimes,
        positions=positions,
        compare=compare,
        exact=exact,
        clock_start=clock_start,
        behaviour=behaviour,
        behaviour_features=behaviour_features,
    )
    run_fit(log, out, options, force=force)


@_command
def report(
    fit_path: _Fit,
    out: Path = typer.Option(None, "--out", help="Folder for figures (default: FIT without .nc)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the replicated windows."),
    replicates: int = typer.Option(200, "--replicates", help="Replicated windows for the PPC."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing figures."),
) -> None:
    """Re-draw the summary table and the posterior-predictive figures of a saved fit."""
    # lazy: the jobs add 2.5 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_report

    run_report(fit_path, out or fit_path.with_suffix(""), _seed(seed), replicates, force)


@_command
def generate(
    fit_path: _Fit,
    scenarios: int = typer.Option(..., "--scenarios", help="Number of scenarios."),
    horizon: float = typer.Option(..., "--horizon", help="Scenario length (fit's time unit, s)."),
    seed: int = typer.Option(..., "--seed", help="Seed (same seed, same bytes)."),
    out: Path = typer.Option(
        ...,
        "--out",
        help="Output folder (artefacts.parquet, manifest.yaml; tracks.parquet with --behaviours).",
    ),
    map_path: Path = typer.Option(
        None, "--map", help="ROS map YAML or a shipped map (courtyard): positions on free cells."
    ),
    area: float = typer.Option(None, "--area", help="Area in m^2 (default: the fit's or map's)."),
    behaviours: bool = typer.Option(
        False,
        "--behaviours",
        help="Move the artefacts (tracks.parquet): the fit's behaviour when it learned one "
        "from a tracks table, else the catalogue's MDP behaviours, then the social force; "
        "needs --map.",
    ),
    behaviour_cell: float = typer.Option(
        1.0, "--behaviour-cell", help="MDP grid cell (m): the map is coarsened to it."
    ),
    behaviour_dt: float = typer.Option(2.0, "--behaviour-dt", help="Seconds per MDP epoch."),
    force: _ForceOutputs = False,
    model: _Model = "chosen",
    positions: _Positions = "chosen",
) -> None:
    """Generate posterior-predictive scenarios (one posterior draw per scenario)."""
    # lazy: the jobs add 2.5 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_generate

    run_generate(
        fit_path,
        scenarios,
        horizon,
        _seed(seed),
        out,
        map_path,
        area=area,
        behaviours=behaviours,
        force=force,
        behaviour_cell=behaviour_cell,
        behaviour_dt=behaviour_dt,
        model=model,
        positions=positions,
    )


@_command
def demo(
    out: Path = typer.Option(
        Path("demo-output"), "--out", help="Folder for the demo outputs, the fit included."
    ),
    force: bool = typer.Option(False, "--force", help="Overwrite earlier demo outputs."),
    quick: bool = typer.Option(False, "--quick", help="Fewer draws (for tests)."),
) -> None:
    """The main job on the shipped defaults: log -> fit -> criticism -> scenarios -> summary."""
    # lazy: the jobs add 2.5 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_demo

    run_demo(out, force=force, quick=quick)


@_command
def perceive(
    scenario: _ScenariosDir,
    camera: _Camera = ...,
    robot_path: Path = typer.Option(
        ..., "--robot-path", help="Robot base poses over time: CSV/Parquet with t, x, y, yaw."
    ),
    mesh: Path = typer.Option(
        None, "--mesh", help="Environment mesh (default: walls extruded from the map)."
    ),
    d_max: _DMax = 30.0,
    tau: _Tau = 50.0,
    camera_height: float = typer.Option(
        1.0, "--camera-height", help="Camera height (m) when the camera file has no pose."
    ),
    mutual: bool = typer.Option(False, "--mutual", help="Artefacts also occlude each other."),
    out: Path = typer.Option(None, "--out", help="Output (default SCENARIO/perceived.parquet)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing output."),
) -> None:
    """Add perceived flags (A_f: count of unoccluded box pixels > tau) to scenarios."""
    # lazy: the jobs add 2.5 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_perceive

    run_perceive(
        scenario,
        camera,
        robot_path,
        mesh=mesh,
        d_max=d_max,
        tau=tau,
        camera_height=camera_height,
        occlusion_between_artefacts=mutual,
        out=out,
        force=force,
    )


@_command
def experiment(
    config: _SweepConfig,
    out: str = typer.Option(None, "--out", help="Results folder (default: results/<name>)."),
    workers: int = typer.Option(1, "--workers", min=1, max=64, help="Local Dask workers."),
    scheduler: str = typer.Option(
        None, "--scheduler", help="Existing Dask scheduler address (tcp://host:port)."
    ),
    force: bool = typer.Option(False, "--force", help="Redo every task and overwrite results."),
    host: str = typer.Option(
        "127.0.0.1", "--host", help="Address the local Dask cluster and dashboard listen on."
    ),
    mcap: str = typer.Option(
        None, "--mcap", help="Folder for one ROS 2 MCAP per mission (/tf, markers, maps)."
    ),
    start_time: str = typer.Option(
        None, "--start-time", help="Wall-clock time of t = 0 in the MCAPs: ISO 8601 or seconds."
    ),
) -> None:
    """Run a navigation-experiment sweep (Fig. 7) on Dask; resumes unfinished sweeps."""
    # lazy: experiments +2.1 s, export +2.2 s CPU on `are-stats --help` (JAX; mostly the same)
    from are_stats.experiments import load_sweep_config, run_sweep
    from are_stats.export import parse_start_time

    cfg = load_sweep_config(config)
    target = out if out is not None else f"results/{cfg['name']}"
    start = 0.0 if start_time is None else parse_start_time(start_time)
    path = run_sweep(
        cfg,
        target,
        workers=workers,
        scheduler=scheduler,
        force=force,
        host=host,
        mcap=mcap,
        start_time=start,
    )
    typer.echo(str(path))


@_command
def plot(
    results: _Results,
    out: str = typer.Option(None, "--out", help="Folder for the PNGs (default: RESULTS)."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing PNGs."),
) -> None:
    """Draw the Fig. 7a (rho) and Fig. 7b (goals reached) plots of a sweep."""
    # lazy: +2.1 s CPU on `are-stats --help` (JAX, the scenarios room)
    from are_stats.experiments import plot_results

    paths = plot_results(results, out, force=force)
    for p in paths:
        typer.echo(str(p))


@_command
def augment(
    bag: _Bag,
    fit_path: Path = typer.Option(..., "--fit", help=_FIT_HELP),
    map_path: str = typer.Option(
        ..., "--map", help="ROS map YAML of the run (or a shipped map name: courtyard)."
    ),
    out: Path = typer.Option(..., "--out", help="The augmented MCAP to write (OUT.mcap)."),
    seed: int = typer.Option(..., "--seed", help="Seed of the scenario (same seed, same file)."),
    pose_topic: _PoseTopic = None,
    base_frame: _BaseFrame = None,
    camera: _Camera = None,
    camera_info_topic: _CameraInfoTopic = None,
    period: float = typer.Option(
        0.5, "--period", help="Seconds between camera frames with --camera."
    ),
    d_max: _DMax = 10.0,
    tau: _Tau = 10.0,
    clock: _Clock = "auto",
    model: _Model = "chosen",
    positions: _Positions = "chosen",
    topics: str = typer.Option(
        None,
        "--topics",
        help="Comma-separated input topics copied into OUT (default: all of them).",
    ),
    map_frame: _MapFrame = "map",
    camera_frame: _CameraFrame = None,
    force: bool = typer.Option(False, "--force", help="Overwrite OUT."),
) -> None:
    """Augment a robot's recorded bag with artefacts generated from a fit (ROS 2 MCAP out)."""
    # lazy: the jobs +2.5 s, logs +0.93 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_augment
    from are_stats.logs import TrajectoryOptions

    run_augment(
        bag,
        fit_path,
        map_path,
        out,
        _seed(seed),
        TrajectoryOptions(
            pose_topic, base_frame, map_frame, camera_info_topic, clock, camera_frame
        ),
        camera=camera,
        period=period,
        d_max=d_max,
        tau=tau,
        force=force,
        model=model,
        positions=positions,
        topics=topics,
    )


@_command
def serve(
    scenarios: _ScenariosDir,
    scenario: int = typer.Option(
        None, "--scenario", help="Which scenario of the folder (default: the first)."
    ),
    speed: float = typer.Option(1.0, "--speed", help="Replay speed-up (1 = real time)."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on."),
    port: int = typer.Option(8765, "--port", help="Port to listen on (0: any free port)."),
    loop: bool = typer.Option(False, "--loop", help="Start again after the horizon, forever."),
    duration: float = typer.Option(
        None, "--duration", help="Stop after this many wall-clock seconds."
    ),
    robot_path: Path = typer.Option(
        None,
        "--robot-path",
        help="Robot path (CSV/Parquet t,x,y,yaw) to stream too: base_link and the camera "
        "frustum (the shipped front_camera).",
    ),
    bag: Path = typer.Option(
        None,
        "--bag",
        help="Robot bag (ROS 1 .bag, ROS 2 folder or .mcap) to stream the robot from, as "
        "augment reads it (the options below): its path and camera frustum, scene time 0 "
        "at the bag's start, stamps on its header clock.",
    ),
    pose_topic: _PoseTopic = None,
    base_frame: _BaseFrame = None,
    map_frame: _MapFrame = "map",
    camera_frame: _CameraFrame = None,
    camera_info_topic: _CameraInfoTopic = None,
    clock: _Clock = "auto",
) -> None:
    """Stream a scenario replay live to Foxglove (WebSocket, foxglove.sdk.v1): boxes, map, /tf,
    and the robot with --robot-path or --bag."""
    # lazy: the jobs +2.5 s, logs +0.93 s CPU on `are-stats --help` (JAX, pandas)
    from are_stats._cli_jobs import run_serve
    from are_stats.logs import TrajectoryOptions

    run_serve(
        scenarios,
        scenario=scenario,
        speed=speed,
        host=host,
        port=port,
        loop=loop,
        duration=duration,
        robot_path=robot_path,
        bag=bag,
        trajectory=TrajectoryOptions(
            pose_topic, base_frame, map_frame, camera_info_topic, clock, camera_frame
        ),
    )


#: Garbage-collector thresholds of a command's process (Python's default: 700, 10, 10).
_GC_THRESHOLDS = (10_000, 20, 20)


def _note_fit_formats(show: Callable[..., None]) -> Callable[..., None]:
    """``warnings.showwarning`` that shows a fit read under an older format
    (:class:`~are_stats.fitting.FitFormatWarning`) as one ``note:`` line, as the commands'
    other notes, and any other warning by ``show``."""

    def showwarning(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        fitting = sys.modules.get("are_stats.fitting")  # loaded when the fit was read
        if fitting is not None and issubclass(category, fitting.FitFormatWarning):
            typer.echo(f"note: {message}", err=True)
        else:
            show(message, category, filename, lineno, file, line)

    return showwarning


#: Commands whose process hides dask from xarray (:func:`are_stats._lazy.hide_dask`: 0.6 s
#: of imports a fit does not use) and numba from ArviZ (:func:`are_stats._lazy.hide_numba`:
#: 1.5 s of CPU at load 16 where numba is installed); ``experiment`` runs its sweeps on Dask.
_WITHOUT_DASK = frozenset({"fit", "report", "demo"})

#: The options before a command that take a value (``--max-memory 16G fit ...``).
_VALUE_OPTIONS = frozenset({"--max-memory", "--max-work"})


def _command_of(argv: list[str]) -> str | None:
    """The command named in ``argv`` (the arguments after the program's name), or None.

    >>> _command_of(["--max-memory", "16G", "fit", "log.csv"])
    'fit'
    """
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg in _VALUE_OPTIONS:
            skip = True
        elif not arg.startswith("-"):
            return arg
    return None


def main() -> None:
    """The ``are-stats`` console script: :data:`app`, then the process's own housekeeping.

    * A fit of an older format is read with a ``note:`` line, not a
      Python warning with a line of our source (:func:`_note_fit_formats`).
    * A command builds up many long-lived objects (the imported libraries, traced and
      compiled programs), which every full collection walks again: at Python's default
      thresholds a warm ``are-stats fit`` of the shipped log spent 1.1-1.3 s of its 9 s in
      about 1,000 collections, 0.3-0.4 s in 70 at :data:`_GC_THRESHOLDS`. Cycles are still
      collected; a library user's process keeps its own settings.
    * After the command, the compiled programs it added are pruned so that the cache
      folders stay under their cap (:func:`are_stats._program_cache.prune_cache`).
    * The commands of :data:`_WITHOUT_DASK` hide dask from xarray (its imports cost 0.6 s
      of a repeated fit of the shipped log; :func:`are_stats._lazy.hide_dask`) and numba
      from ArviZ (its import and one eager kernel compile, :func:`are_stats._lazy.hide_numba`).
    * Last, every object is frozen (:func:`gc.freeze`): the interpreter's final collection
      at exit would walk them all once more only to free memory the exit frees anyway
      (1.1 s after a fit). Outputs are written and closed by then.
    """
    if _command_of(sys.argv[1:]) in _WITHOUT_DASK:
        hide_dask()
        hide_numba()
    gc.set_threshold(*_GC_THRESHOLDS)
    warnings.showwarning = _note_fit_formats(warnings.showwarning)
    try:
        app()
    finally:
        # the compiled programs this run added: the cache folders stay under their cap
        prune_cache()
        gc.freeze()


if __name__ == "__main__":  # python -m are_stats.cli
    main()
