"""The jobs behind ``are-stats fit / report / generate / demo`` (the CLI only parses options).

Each job validates its inputs, refuses to overwrite outputs without ``force`` *before* doing
any work, writes every file atomically and prints a short rich summary.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping
from contextlib import ExitStack
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np
import pandas as pd
import yaml
from rich.console import Console
from rich.table import Table

from are_stats import __version__
from are_stats._atomic import atomic_path, check_writable
from are_stats._stage_clock import StageClock, StepsLeft
from are_stats.environment import (
    load_catalogue,
    resolve_shipped,
    shipped_path,
)
from are_stats.export import (
    AugmentOptions,
    AugmentResult,
    ServeInfo,
    ServeOptions,
    augment_bag,
    serve_robot,
    serve_scenario,
)
from are_stats.inputs import (
    Described,
    InputError,
    get_float,
    get_int,
    get_list,
    get_seed,
    get_str,
)
from are_stats.logs import TrajectoryOptions, find_manifest, read_count_panel, read_field_log
from are_stats.scenarios import GenerateFolderOptions, generate_folder

if TYPE_CHECKING:
    from are_stats.behaviour import BehaviourFit
    from are_stats.fitting import Fit, FitSettings, MotionReport
    from are_stats.perception import PerceiveFolderOptions

# fitting and perception are imported in the jobs that use them (each import says the CPU it
# would add on top of the rooms above, which every job loads anyway; measured 2026-11-28).

console = Console(highlight=False, width=None if Console().is_terminal else 100)

# The demo's inputs, shipped inside the package (are_stats.environment.shipped_path); its
# outputs, the fit included, go under --out: nothing is written into the install.
EXAMPLE_LOG_NAME = "courtyard_traffic"
EXAMPLE_LOG = shipped_path(EXAMPLE_LOG_NAME, "log")
EXAMPLE_MAP = shipped_path("courtyard", "map")


#: The options of ``are-stats fit`` that set :class:`~are_stats.fitting.FitSettings`' sampler
#: fields (named in a size error).
SETTING_OPTIONS = {"num_samples": "--samples", "num_warmup": "--warmup", "num_chains": "--chains"}


def _summary_table(summary: pd.DataFrame, title: str) -> Table:
    table = Table(title=title, title_justify="left")
    for col in ("parameter", "mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "r_hat"):
        table.add_column(col, justify="left" if col == "parameter" else "right", no_wrap=True)
    for name, row in summary.iterrows():
        r_hat = row.get("r_hat", np.nan)
        table.add_row(
            str(name),
            f"{row['mean']:.4g}",
            f"{row['sd']:.3g}",
            f"{row['hdi_3%']:.4g}",
            f"{row['hdi_97%']:.4g}",
            f"{row['ess_bulk']:.0f}",
            "-" if not np.isfinite(r_hat) else f"{r_hat:.3f}",
        )
    return table


@dataclass(frozen=True)
class FitOptions:
    """The options of ``are-stats fit``, one frozen record: the command builds it from its
    command line and passes it whole to :func:`run_fit` (as ``generate`` passes
    :class:`~are_stats.scenarios.AssemblyOptions`); ``demo`` builds its own.

    Attributes
    ----------
    method : {"nuts", "em"}
        ``--method``: the joint posterior by NUTS, or conjugate rates + EM.
    seed : int
        ``--seed``, in ``[0, 2**32 - 1]``.
    window : (t0, t1) or None
        ``--window``: the observation window (the log's time unit), ``t0 < t1``.
    area : float or None
        ``--area``: the free area (m^2), overriding the manifest's.
    manifest, counts : Path or None
        ``--manifest`` (default: beside the log), ``--counts`` (a count panel).
    components : int or None
        ``--components``: mixture components (default: the labels, else BIC).
    warmup, samples, chains : int
        ``--warmup``, ``--samples``, ``--chains``: NUTS draws per chain and chains.
    figures : Path or None
        Folder for the criticism figures; None draws none.
    n_replicates : int
        Replicated windows of the posterior-predictive checks (``--replicates``).
    stationary_start, exact : bool
        ``--stationary-start``, ``--exact``.
    arrivals, lifetimes, positions, compare : str
        ``--arrivals``, ``--lifetimes``, ``--positions``, ``--compare``.
    clock_start : str or None
        ``--clock-start``: ISO 8601 time of t = 0.
    behaviour : bool
        ``--behaviour``: also fit the behaviour of a tracks table.
    behaviour_features : str
        ``--behaviour-features``: comma-separated reward features (:meth:`features`).

    Examples
    --------
    >>> FitOptions(method="em", samples=20, behaviour_features="walls").checked().samples
    20
    """

    method: str = "nuts"
    seed: int = 0
    window: tuple[float, float] | None = None
    area: float | None = None
    manifest: Path | None = None
    counts: Path | None = None
    components: int | None = None
    warmup: int = 1000
    samples: int = 1000
    chains: int = 4
    figures: Path | None = None
    n_replicates: int = 200
    stationary_start: bool = True
    arrivals: str = "auto"
    lifetimes: str = "auto"
    positions: str = "auto"
    compare: str = "laplace"
    exact: bool = True
    clock_start: str | None = None
    behaviour: bool = True
    behaviour_features: str = ""

    def checked(self) -> FitOptions:
        """These options checked and named as on the command line (``--method``,
        ``--arrivals``, ``--lifetimes``, ``--positions``, ``--behaviour-features``,
        ``--clock-start``, ``--seed``, ``--warmup``, ``--samples``, ``--chains``,
        ``--replicates``, ``--components``, ``--window``, ``--area``, in that order).

        Raises
        ------
        ValueError
            Naming the first option that is out of range (an
            :class:`~are_stats.inputs.InputError`, or ``--clock-start`` that is not ISO 8601).
        """
        # lazy: fitting +1.05 s, traffic alone +0.91 s CPU on every job's start (NumPyro)
        from are_stats.fitting import ARRIVAL_CHOICES, LIFETIME_CHOICES, POSITION_CHOICES
        from are_stats.traffic import clock_offset

        checked: FitFields = {
            "method": get_str(self.method, "--method", "", choices=("nuts", "em")),
            "arrivals": get_str(self.arrivals, "--arrivals", "", choices=ARRIVAL_CHOICES),
            "lifetimes": get_str(self.lifetimes, "--lifetimes", "", choices=LIFETIME_CHOICES),
            "positions": get_str(self.positions, "--positions", "", choices=POSITION_CHOICES),
        }
        if self.features() and not self.behaviour:
            raise InputError(
                "--behaviour-features",
                "",
                "the behaviour to be fitted (drop one of the two)",
                Described("--no-behaviour"),
            )
        if self.clock_start is not None:
            clock = checked["clock_start"] = get_str(self.clock_start, "--clock-start", "")
            try:
                clock_offset(clock)
            except ValueError:
                raise ValueError(
                    f"--clock-start: expected an ISO 8601 time such as 2024-05-02T07:30:00, "
                    f"got {clock!r}"
                ) from None
        checked["seed"] = get_seed(self.seed)
        checked["warmup"] = get_int(self.warmup, "--warmup", "", lo=0)
        checked["samples"] = get_int(self.samples, "--samples", "", lo=1)
        checked["chains"] = get_int(self.chains, "--chains", "", lo=1)
        checked["n_replicates"] = get_int(self.n_replicates, "--replicates", "", lo=1)
        if self.components is not None:
            checked["components"] = get_int(self.components, "--components", "", lo=1, hi=1000)
        if self.window is not None:
            window = get_list(list(self.window), "--window", "", min_len=2, max_len=2)
            w0 = get_float(window[0], "--window", "t0")
            checked["window"] = (w0, get_float(window[1], "--window", "t1", lo=w0, lo_open=True))
        if self.area is not None:
            checked["area"] = get_float(self.area, "--area", "", lo=0.0, lo_open=True)
        return replace(self, **checked)

    def features(self) -> tuple[str, ...]:
        """The reward features of ``behaviour_features``, each one of
        :data:`~are_stats.fitting.BEHAVIOUR_FEATURES` (named as ``--behaviour-features``).

        Raises
        ------
        are_stats.inputs.InputError
            For a name that is not a feature.
        """
        # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
        from are_stats.fitting import BEHAVIOUR_FEATURES

        return tuple(
            get_str(f.strip(), "--behaviour-features", "", choices=sorted(BEHAVIOUR_FEATURES))
            for f in get_str(self.behaviour_features, "--behaviour-features", "").split(",")
            if f.strip()
        )

    def settings(self) -> FitSettings:
        """The :class:`~are_stats.fitting.FitSettings` of :func:`~are_stats.fitting.fit_log`
        (the sampler's and the traffic models' fields)."""
        # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
        from are_stats.fitting import FitSettings

        return FitSettings(
            method=self.method,
            n_components=self.components,
            num_warmup=self.warmup,
            num_samples=self.samples,
            num_chains=self.chains,
            stationary_start=self.stationary_start,
            arrivals=self.arrivals,
            lifetimes=self.lifetimes,
            positions=self.positions,
            compare=self.compare,
            exact=self.exact,
        )


class FitFields(TypedDict, total=False):
    """The fields of :class:`FitOptions` as keywords of :func:`run_fit` (see the record for
    their meaning)."""

    method: str
    seed: int
    window: tuple[float, float] | None
    area: float | None
    manifest: Path | None
    counts: Path | None
    components: int | None
    warmup: int
    samples: int
    chains: int
    figures: Path | None
    n_replicates: int
    stationary_start: bool
    arrivals: str
    lifetimes: str
    positions: str
    compare: str
    exact: bool
    clock_start: str | None
    behaviour: bool
    behaviour_features: str


def run_fit(
    log: Path,
    out: Path,
    options: FitOptions | None = None,
    *,
    force: bool = False,
    **fields: Unpack[FitFields],
) -> Fit:
    """Read a log, fit it, write the NetCDF fit and (optionally) its criticism figures.

    ``options`` (:class:`FitOptions`, the command's options; default: its defaults) with the
    fields named as keywords replaced (``fields``, :class:`FitFields`). A tracks table with a
    map also gets its behaviour fitted (speeds, exits, rationality:
    :func:`are_stats.fitting.fit_behaviour`, stored as the ``behaviour`` group) unless
    ``behaviour`` is false; ``behaviour_features`` (``--behaviour-features``, comma-separated
    names of :data:`are_stats.fitting.BEHAVIOUR_FEATURES`) adds fitted reward weights.

    The options are checked first, named as on the command line
    (:meth:`FitOptions.checked`), then ``out`` (a ``.nc`` name, written only with
    ``force`` where it exists); :func:`~are_stats.fitting.fit_log` checks the draws and the
    sampler's work against the limits of :mod:`are_stats.inputs` (naming these options)
    before it samples.

    The fit's posterior attributes name the log by its file name (``log``) and the
    SHA-256 of its bytes (``log_sha256``), never by its folder; ``log_report`` holds the
    reading counts (its ``source`` is the file name too).
    """
    # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
    from are_stats.fitting import (
        can_check_motion,
        compare_panel,
        fit_log,
        fit_summary,
        panel_estimates,
        sampler_warnings,
        write_fit,
        write_motion_report,
        write_report,
    )

    opts = replace(options or FitOptions(), **fields).checked()
    out = Path(out)
    if out.suffix != ".nc":
        raise ValueError(f"--out: expected a .nc file name, got {str(out)!r}")
    check_writable(out, force)
    settings = opts.settings()
    log = resolve_shipped(log, "log", source="LOG")  # a file, or a shipped log's name
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        lifecycle = read_field_log(
            log,
            manifest=opts.manifest,
            window=opts.window,
            area=opts.area,
            clock_start=opts.clock_start,
        )
    for w in caught:
        console.print(f"[yellow]warning:[/] {w.message}")
    data = lifecycle.to_lifecycle_data()
    rep = lifecycle.report()
    console.print(
        f"[bold]{log}[/]: {rep['rows_used']} artefacts ({rep['left_truncated']} present at "
        f"start, {rep['right_censored']} still present at end, excluded: "
        f"{sum(rep['excluded'].values())}); window {rep['window']} s, area {rep['area']:.1f} m^2"
    )
    if rep.get("groups"):
        console.print(f"{rep['artefacts_in_groups']} artefacts arrived in {rep['groups']} groups")
    panel = read_count_panel(opts.counts) if opts.counts is not None else None

    catalogue = load_catalogue()  # read once: the labels' rows and the classes' run speeds
    t_start = time.perf_counter()
    with (
        console.status("fitting ...") as status,
        StageClock(
            status, "fitting: ", size=f"{opts.method}, {data.n} rows", live=console.is_terminal
        ) as clock,
    ):
        fit = fit_log(
            opts.seed,
            lifecycle,
            settings,
            counts_panel=panel,
            progress=clock,
            behaviour=opts.behaviour,
            features=opts.features(),
            catalogue=catalogue,
            setting_names=SETTING_OPTIONS,
        )
    idata = fit.idata
    for note in fit.notes:
        console.print(f"note: {note}")
    if fit.behaviour is not None:
        for line in _behaviour_lines(fit.behaviour):
            console.print(line)
        _print_variation(fit.behaviour)
        _print_interaction(fit)
    write_fit(idata, out, force=force)
    summary = fit_summary(idata)
    console.print(_summary_table(summary, f"fit in {time.perf_counter() - t_start:.1f} s"))
    # how each posterior was drawn (the paper's exact draws, resampled Laplace or NUTS): the
    # method alone ("nuts") no longer says it
    how = [f"{who}: {how}" for who, how in fit.posterior_sources.items()]
    if how:
        console.print("posteriors: " + "; ".join(how))
    for w in sampler_warnings(idata, summary):
        console.print(f"[yellow]warning:[/] {w}")
    _print_traffic(fit)
    _print_classes(fit)
    if panel is not None:
        console.print(f"birth-death MLE of {opts.counts}: {panel_estimates(fit)}")
        cmp = compare_panel(idata)
        if cmp.warning:
            console.print(f"[yellow]warning:[/] {cmp.warning}")
    console.print(f"wrote {out}")
    if opts.figures is not None:
        # stages over 2 s: the time left from the last run (StageClock)
        figures, replicates, seed = opts.figures, opts.n_replicates, opts.seed
        size = f"{replicates} replicates, {data.n} rows"
        with (
            console.status("posterior-predictive checks ...") as status,
            StageClock(status, size=size, live=console.is_terminal) as clock,
        ):
            clock("posterior-predictive checks")
            written = write_report(
                idata, figures, key=seed, n_replicates=replicates, force=force, summary=summary
            )
        _print_checks(written)
        if can_check_motion(fit, lifecycle.tracks):
            stage = "motion checks (speeds, straightness, held-out moves)"
            with (
                console.status(f"{stage} ...") as status,
                StageClock(
                    status, size=f"{len(lifecycle.tracks)} track rows", live=console.is_terminal
                ) as clock,
            ):
                clock(stage)
                motion = write_motion_report(
                    seed, fit, lifecycle.tracks, figures, force, catalogue, progress=clock.steps
                )
                written.update(motion.written)
            _print_motion_report(motion, fit.motion)
        console.print(f"wrote {len(written)} criticism files to {figures}/")
    return fit


def _print_classes(fit: Fit) -> None:
    """One line on a labelled log's classes: shares and mean stays (issue 31)."""
    classes = fit.class_shares()
    if classes is None:
        return
    parts = [
        f"{name} {wi:.0%} ({hi:.3g}/h, mean stay {mi:.3g} s)"
        for name, wi, hi, mi in zip(*classes, strict=True)
    ]
    console.print(f"classes (stays {fit.class_stay_model} by PSIS-LOO): " + ", ".join(parts))
    extra = []
    if fit.class_position_model is not None:
        extra.append(f"entry/exit densities {fit.class_position_model}")
    if fit.class_share_model is not None:
        extra.append(f"shares {fit.class_share_model}")
    if extra:
        console.print("classes by PSIS-LOO: " + ", ".join(extra))


def _print_interaction(fit: Fit) -> None:
    """The social force a fit learned from the log's tracks (issue 26)."""
    params = fit.interaction
    if params is None:
        return
    info = fit.interaction_info
    how = {
        "estimated": f"R^2 {info.get('r2', np.nan):.2f} over {info.get('n', 0):.0f} accelerations",
        "none": "no repulsion: the published one fits the tracks worse than none",
        "published": "published: the tracks do not fit a repulsion",
    }[fit.interaction_source]
    console.print(
        f"interaction (social force): strength A {params.strength:.3g} m/s^2, range B "
        f"{params.range:.3g} m, relaxation tau {params.relaxation:.3g} s ({how})"
    )
    if info.get("group_samples", 0) > 0:
        console.print(
            f"groups walk {params.group_spacing:.2f} m apart (median over "
            f"{int(info['group_samples'])} member samples)"
        )


def _behaviour_lines(fit: BehaviourFit) -> list[str]:
    """One line per class: the fitted rationality, slip and reward weights with their
    standard errors; then the fit's warnings (a standard error NaN and why, an optimiser
    that did not converge), which the fit file keeps too."""
    out = []
    for c, name in enumerate(fit.classes):
        parts = [
            f"beta {fit.beta[c]:.3g} +- {fit.beta_se[c]:.2g}",
            f"slip {fit.slip[c]:.3g} +- {fit.slip_se[c]:.2g}",
        ]
        parts += [
            f"{f} weight {fit.weights[c, k]:+.3g} +- {fit.weights_se[c, k]:.2g}"
            for k, f in enumerate(fit.feature_names)
        ]
        out.append(f"behaviour {name!r}: " + ", ".join(parts))
    out += [f"warning: behaviour {w}" for w in fit.warnings]
    return out


def _print_variation(fit: BehaviourFit) -> None:
    """The within-person pace and wander per class, +- their standard errors (issue 26)."""
    # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
    from are_stats.fitting import variation_table

    table = variation_table(fit)
    rich = Table(title="within-person variation (+- standard error)", title_justify="left")
    rich.add_column("class", justify="left")
    for col in table.columns:
        rich.add_column(str(col), justify="right")
    for name, row in table.iterrows():
        rich.add_row(str(name), *(str(v) for v in row))
    console.print(rich)


def _print_motion_tables(tables: Mapping[str, pd.DataFrame]) -> None:
    """The ADE/FDE lines and the realism table (stored in the fit)."""
    if "displacement" in tables:
        for method, row in tables["displacement"].iterrows():
            console.print(
                f"ADE/FDE ({int(row['n_windows'])} windows, 8 observed / 12 predicted), "
                f"{method}: {row['ADE']:.2f} / {row['FDE']:.2f} m"
            )
    if "realism" not in tables:
        return
    real = tables["realism"]
    models = [c for c in real.columns if c not in ("kind", "weight")]
    rich = Table(title="realism against the log (higher is closer)", title_justify="left")
    rich.add_column("feature", justify="left")
    for m in models:
        rich.add_column(m, justify="right")
    for feat, row in real.iterrows():
        cells = [f"{float(row[m]):.3f}" if np.isfinite(float(row[m])) else "-" for m in models]
        rich.add_row(str(feat), *cells)
    console.print(rich)


def _print_motion_report(rep: MotionReport, stored: Mapping[str, pd.DataFrame]) -> None:
    """The motion checks table, per-class rows, held-out moves and stored motion tables."""
    rich = Table(title="motion checks (90% bands; ! = observed outside)", title_justify="left")
    for col in ("statistic", "observed", "model 5% - 95%"):
        rich.add_column(col, justify="left" if col == "statistic" else "right")
    for stat, row in rep.checks.iterrows():
        flag = bool(row["model_flag"])
        band = f"{row['model_5%']:.3g} - {row['model_95%']:.3g}"
        rich.add_row(
            str(stat), f"{row['observed']:.3g}", ("[red]! " + band + "[/]") if flag else band
        )
    console.print(rich)
    if rep.per_class is not None:
        _print_class_checks(rep.per_class)
    held = rep.heldout
    console.print(
        f"held-out moves: fitted policy {held['policy_per_move']:.3f} vs random walk "
        f"{held['random_walk_per_move']:.3f} nats per move"
    )
    _print_motion_tables(stored)


def _print_traffic(fit: Fit) -> None:
    """The model comparison tables and the chosen models of a fit, with sampler warnings."""
    for factor, table in fit.comparisons.items():
        rich = Table(
            title=f"{factor}: candidates by PSIS-LOO (chosen: simplest within 2 SE of the best)",
            title_justify="left",
        )
        cols = [
            c
            for c in ("elpd", "se", "elpd_diff", "dse", "k>0.7", "divergent", "r_hat")
            if c in table.columns
        ]
        rich.add_column("model")
        for c in cols:
            rich.add_column(c, justify="right")
        rich.add_column("chosen")
        for model, row in table.iterrows():
            cells = []
            for c in cols:
                v = row[c]
                cells.append(
                    "-"
                    if not np.isfinite(v)
                    else (
                        f"{v:.3f}"
                        if c == "r_hat"
                        else f"{v:.1f}"
                        if isinstance(v, float)
                        else str(v)
                    )
                )
            rich.add_row(str(model), *cells, "yes" if bool(row["chosen"]) else "")
        console.print(rich)
    laws = fit.laws
    console.print(
        f"chosen models: arrivals [bold]{laws.arrivals}[/], stays [bold]{laws.lifetimes}[/], "
        f"positions [bold]{laws.positions}[/]"
    )
    for kind, text in fit.traffic_notes:
        console.print(f"note: {text}" if kind == "note" else f"[yellow]warning:[/] {text}")


def _print_checks(written: Mapping[str, Path]) -> None:
    """The posterior-predictive statistics table (observed vs 90% bands, misfits flagged)."""
    path = written.get("traffic_checks_table")
    if path is None:
        return
    table = pd.read_csv(path, index_col=0)
    models = [m for m in ("paper", "chosen") if f"{m}_5%" in table.columns]
    rich = Table(
        title="posterior-predictive checks (90% bands; ! = observed outside)", title_justify="left"
    )
    rich.add_column("statistic")
    rich.add_column("observed", justify="right")
    for m in models:
        rich.add_column(m, justify="right")
    for stat, row in table.iterrows():
        cells = [_band(row[f"{m}_5%"], row[f"{m}_95%"], row[f"{m}_flag"]) for m in models]
        rich.add_row(str(stat), _fmt(row["observed"]), *cells)
    console.print(rich)
    for name in ("class_checks", "class_motion_checks"):
        if written.get(name) is not None:
            _print_class_checks(pd.read_csv(written[name], index_col=[0, 1]))


def _fmt(v: float) -> str:
    """A checks table's number: three significant digits, ``-`` where undefined."""
    return "-" if not np.isfinite(v) else f"{v:.3g}"


def _band(lo: float, hi: float, flag: bool) -> str:
    """A 90% band cell of the checks tables, red with a ``!`` when the observed value
    falls outside it."""
    band = f"{_fmt(lo)} - {_fmt(hi)}"
    return f"[red]! {band}[/]" if bool(flag) else f"  {band}"


def _print_class_checks(table: pd.DataFrame) -> None:
    """Per-class rows of a labelled log's checks (issue 31): observed vs the model's band."""
    rich = Table(title="per class (90% bands; ! = observed outside)", title_justify="left")
    for col in ("class", "statistic", "observed", "model"):
        rich.add_column(col, justify="left" if col in ("class", "statistic") else "right")
    for (cls, stat), row in table.iterrows():
        band = _band(row["model_5%"], row["model_95%"], row["model_flag"])
        rich.add_row(str(cls), str(stat), _fmt(row["observed"]), band)
    console.print(rich)


def run_report(
    fit_path: Path, out: Path, seed: int = 0, replicates: int = 200, force: bool = False
) -> dict[str, Path]:
    """Summary table and posterior-predictive figures of a saved fit.

    ``--replicates`` (an integer >= 1) and ``--seed`` are checked, then the fit file
    (:func:`are_stats.fitting.read_fit`) and the size of the replicates against the limits
    of :mod:`are_stats.inputs`, before anything is drawn.
    """
    # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
    from are_stats.fitting import (
        check_report_outputs,
        check_report_size,
        fit_summary,
        read_fit,
        sampler_warnings,
        write_motion_tables,
        write_report,
    )

    seed = get_seed(seed)
    replicates = get_int(replicates, "--replicates", "", lo=1)
    fit = read_fit(fit_path)
    idata = fit.idata
    check_report_size(idata, replicates, f"{fit_path} with --replicates {replicates}")
    check_report_outputs(out, force)  # before the summary's work, not after it
    summary = fit_summary(idata)
    console.print(_summary_table(summary, f"{fit_path} ({fit.method})"))
    for w in sampler_warnings(idata, summary):
        console.print(f"[yellow]warning:[/] {w}")
    with console.status("posterior-predictive checks ..."):
        written = write_report(
            idata, out, key=seed, n_replicates=replicates, force=force, summary=summary
        )
    _print_traffic(fit)
    _print_checks(written)
    if fit.behaviour is not None:
        _print_variation(fit.behaviour)
    if fit.motion:  # the motion criticism the fit stored (issue 26)
        written.update(write_motion_tables(fit.motion, out, force))
        _print_motion_tables(fit.motion)
    console.print(f"wrote {len(written)} files to {out}/")
    return written


def run_generate(
    fit_path: Path,
    n_scenarios: int,
    horizon: float,
    seed: int,
    out: Path,
    map_path: Path | None = None,
    **options: Unpack[GenerateFolderOptions],
) -> pd.DataFrame:
    """``are-stats generate``: posterior-predictive scenarios from a saved fit, written as
    a folder (:func:`are_stats.scenarios.generate_folder`, which ``map_path`` and
    ``options`` go to; it checks every option before anything is drawn); the stage's
    progress shown, then the laws drawn from and what it wrote."""
    stage = "scenarios with their walks (rollouts)" if options.get("behaviours") else "scenarios"
    started: list[float] = []  # when drawing began

    with ExitStack() as progress:

        def start() -> StepsLeft:
            started.append(time.perf_counter())
            status = progress.enter_context(console.status(f"{stage} ..."))
            clock = progress.enter_context(
                StageClock(
                    status,
                    size=f"{n_scenarios} x {horizon:g} s, {Path(fit_path).name}",
                    live=console.is_terminal,
                )
            )
            clock(stage)
            return StepsLeft(clock, stage)

        df = generate_folder(
            fit_path, n_scenarios, horizon, seed, out, map_path, on_start=start, **options
        )
    laws = df.attrs["generation"]["laws"]  # what the scenes were drawn from
    console.print(
        f"model: arrivals {laws['arrivals']}, stays {laws['lifetimes']}, "
        f"positions {laws['positions']}"
    )
    out = Path(out)
    # the files generate_folder wrote: the tracks too with --behaviours (when any artefact)
    names = ["artefacts.parquet", "tracks.parquet", "manifest.yaml"]
    names = [name for name in names if (out / name).is_file()]
    wrote = ", ".join(str(out / name) for name in names[:-1])
    console.print(
        f"{n_scenarios} scenarios, "
        f"{len(df)} artefacts in {time.perf_counter() - started[0]:.2f} s; "
        f"wrote {wrote} and {out / names[-1]}"
    )
    return df


def run_demo(out: Path, force: bool = False, quick: bool = False) -> dict[str, object]:
    """log -> fit -> criticism figures -> 100 scenarios -> summary, on the shipped defaults."""
    # lazy: +1.05 s CPU on every job's start (NumPyro), which perceive and serve do not use
    from are_stats.fitting import crowding_statistics, read_traffic_checks

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "", "a folder for the demo's outputs (--out)", Described("a file"))
    fit_file = out / f"{EXAMPLE_LOG_NAME}.nc"
    summary_file = out / "summary.yaml"
    check_writable(summary_file, force)
    check_writable(fit_file, force)
    t0 = time.perf_counter()
    console.rule("[bold]are_stats demo: from a field log to scenarios")
    draws = 200 if quick else 500
    options = FitOptions(
        warmup=draws,
        samples=draws,
        chains=2 if quick else 4,
        figures=out / "criticism",
        n_replicates=50 if quick else 200,
    )
    fit = run_fit(EXAMPLE_LOG, fit_file, options, force=force)
    # the same scenarios from the chosen models and from the paper's, side by side
    df = run_generate(fit_file, 100, 3600.0, 1, out / "scenarios", EXAMPLE_MAP, force=force)
    df_paper = run_generate(
        fit_file, 100, 3600.0, 1, out / "scenarios_paper", EXAMPLE_MAP, force=force, model="paper"
    )

    means = fit.posterior_means()
    desc = find_manifest(EXAMPLE_LOG)[0].get("description")
    res = fit.time_resolution

    def crowding(table: pd.DataFrame) -> dict[str, float]:
        return {k: round(v, 3) for k, v in crowding_statistics(table, (0.0, 3600.0), res).items()}

    checks = read_traffic_checks(out / "criticism")
    summary: dict[str, object] = {
        "are_stats_version": __version__,
        "log": f"{EXAMPLE_LOG_NAME} (shipped)",
        "truth": desc,
        "fit": str(fit_file),
        "chosen_models": {
            "arrivals": fit.laws.arrivals,
            "lifetimes": fit.laws.lifetimes,
            "positions": fit.laws.positions,
        },
        "posterior_mean": {
            "arrival_rate": means.arrival_rate,
            "leave_rate": means.leave_rate,
            "arrivals_per_s (lambda * area)": means.arrivals_per_s,
            "mean_stay_s (1 / mu)": means.mean_stay_s,
            "classes": {
                label: {"weight": round(float(w), 4), "mark_rate": round(float(r), 3)}
                for label, w, r in zip(
                    means.class_labels, means.class_weights, means.mark_rates, strict=True
                )
            },
        },
        "checks (observed; outside the 90% band of)": None
        if checks is None
        else {
            str(stat): {
                "observed": round(float(row["observed"]), 3),
                "paper misfit": bool(row.get("paper_flag", False)),
                "chosen misfit": bool(row.get("chosen_flag", False)),
            }
            for stat, row in checks.iterrows()
        },
        "scenarios (100 of 1 h; medians)": {
            "chosen": {"artefacts": len(df), **crowding(df)},
            "paper": {"artefacts": len(df_paper), **crowding(df_paper)},
        },
        "seconds": round(time.perf_counter() - t0, 1),
    }
    with atomic_path(summary_file, force=force) as tmp:
        tmp.write_text(yaml.safe_dump(summary, sort_keys=False))
    console.rule("[bold]summary")
    console.print(yaml.safe_dump(summary, sort_keys=False))
    console.print(f"outputs in {out}/ (figures in {out / 'criticism'}/), fit in {fit_file}")
    return summary


def run_perceive(
    scenario: Path, camera_path: Path, robot_path: Path, **options: Unpack[PerceiveFolderOptions]
) -> pd.DataFrame:
    """``are-stats perceive``: perceived flags (A_f, eq. 2) added to a scenario folder for a
    robot path (:func:`are_stats.perception.perceive_folder`, which ``options`` go to; it
    checks every input before any tracing); its warnings and progress shown, then what it
    wrote."""
    # lazy: +0.93 s CPU on every job's start (Warp), which only perceive uses
    from are_stats.perception import FolderPlan, perceive_folder

    started: list[tuple[FolderPlan, float]] = []  # the plan, and when perceiving began

    with ExitStack() as progress:

        def start(plan: FolderPlan) -> None:
            for note in plan.warnings:
                console.print(f"[yellow]warning:[/] {note}")
            moving = f" ({plan.moving} moving)" if plan.moving else ""
            started.append((plan, time.perf_counter()))
            progress.enter_context(
                console.status(
                    f"perceiving {plan.artefacts} artefacts{moving} over {plan.poses} robot "
                    "poses ..."
                )
            )

        target, res = perceive_folder(scenario, camera_path, robot_path, on_start=start, **options)
    (plan, t), n_p = started[0], int(res["perceived"].sum())
    moving = f" ({plan.moving} moving)" if plan.moving else ""
    console.print(
        f"{n_p} of {len(res)} artefacts{moving} perceived (tau={plan.tau}, "
        f"d_max={plan.d_max} m) in {time.perf_counter() - t:.1f} s; wrote {target}"
    )
    return res


def run_augment(
    bag: Path,
    fit_path: Path,
    map_path: str,
    out: Path,
    seed: int,
    trajectory: TrajectoryOptions,
    *,
    topics: str | None = None,
    **options: Unpack[AugmentOptions],
) -> AugmentResult:
    """``are-stats augment``: a robot's bag plus generated artefacts -> an augmented MCAP
    (:func:`are_stats.export.augment_bag`, which ``options`` go to); ``trajectory`` how the
    bag's robot is read, ``topics`` the comma-separated input topics passed through
    (default all)."""
    t = time.perf_counter()
    with console.status(f"augmenting {bag} ..."), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        res = augment_bag(
            bag,
            fit_path,
            map_path,
            out,
            seed,
            **trajectory.checked().keywords(),
            topics=None if topics is None else [t.strip() for t in topics.split(",") if t.strip()],
            **options,
        )
    for w in caught:
        if issubclass(w.category, UserWarning):  # a trajectory partly outside the map
            console.print(f"[yellow]warning:[/] {w.message}")
        else:  # shown as they would have been (a fit's older format: a note)
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    n_seen = int(res.perceived.any(axis=0).sum())
    console.print(
        f"{len(res.scene)} artefacts over {res.times[-1] - res.times[0]:.1f} s of the bag, "
        f"{n_seen} perceived in {len(res.times)} camera frames, "
        f"{int(res.contacts.any(axis=0).sum())} touched by the robot "
        f"({time.perf_counter() - t:.1f} s); wrote {res.path} "
        f"({', '.join(f'{k} {v}' for k, v in res.topics.items())}; passed through: "
        f"{', '.join(f'{k} {v}' for k, v in res.passed.items()) or 'nothing'}); "
        f"clock: {res.clock_note}"
    )
    for note in (res.frame_note, res.camera_note):
        if note:
            console.print(f"note: {note}")
    return res


def run_serve(
    folder: Path,
    *,
    robot_path: Path | None = None,
    bag: Path | None = None,
    trajectory: TrajectoryOptions | None = None,
    **options: Unpack[ServeOptions],
) -> ServeInfo | None:
    """``are-stats serve``: stream a scenario replay over Foxglove's WebSocket protocol
    (:func:`are_stats.export.serve_scenario`, which ``options`` go to), with the robot of a
    path or of a bag (:func:`are_stats.export.serve_robot`, read with ``trajectory``: the options of
    ``augment``); what was served, None when stopped by Ctrl-C."""
    robot = serve_robot(bag, trajectory, robot_path=robot_path)

    def ready(info: ServeInfo) -> None:
        moving = f" ({info['moving']} moving)" if info["moving"] else ""
        duration, loop = info["duration"], info["loop"]
        until = f", for {duration:g} s" if duration is not None else ""
        console.print(
            f"serving scenario {info['scenario']} of {folder}: {info['artefacts']} artefacts"
            f"{moving} over {info['horizon']:g} s at x{info['speed']:g}"
            f"{' (looping)' if loop else ''}"
            f"{until} on {info['url']} (Foxglove: Open connection -> {info['url']}; "
            "Ctrl-C stops)"
        )
        if robot is not None:
            console.print(
                f"robot from {bag}: {robot['source']}, {robot['t'].size} poses over "
                f"{robot['duration']:.1f} s, camera frame {robot['camera_frame']}, fixed frame "
                f"{info['frame']}; clock: {robot['clock_note']}"
            )
            if robot["frame_note"]:
                console.print(f"note: {robot['frame_note']}")

    try:
        info = serve_scenario(folder, on_ready=ready, robot_path=robot_path, robot=robot, **options)
    except KeyboardInterrupt:
        console.print("stopped")
        return None
    console.print(
        f"sent {info['messages']} messages in {info['frames']} frames ({info['wall']:.1f} s)"
    )
    return info
