"""One field log in, the whole fit out: traffic, classes, behaviour, interaction, motion.

:func:`fit_log` is what ``are-stats fit`` runs: it takes a field log read once
(:func:`are_stats.logs.read_field_log`: the life-cycle rows, and the tracks of a tracks
table), reads the manifest's map once, fits the paper's models and the chosen traffic
models (:func:`fit_lifecycle_data`), then, for a tracks table, the behaviour
(:func:`~are_stats.fitting.fit_behaviour`), the social force
(:func:`~are_stats.fitting.fit_interaction`) and the motion criticism stored with them
(realism, displacement errors), and stamps the provenance. It returns a
:class:`~are_stats.fitting.Fit`; the CLI only prints and writes it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd
import yaml

from are_stats.behaviour import BehaviourFit, SocialForce
from are_stats.environment import ArtefactCatalogue, OccupancyGrid, load_catalogue
from are_stats.fitting._behaviour import NoWalkersError, fit_behaviour, open_area_grid
from are_stats.fitting._classes import class_motion_checks
from are_stats.fitting._fit import Fit, fit_from_idata
from are_stats.fitting._fit_log import (
    FitSettings,
    attach_behaviour,
    fit_lifecycle_data,
)
from are_stats.fitting._interaction import interaction_attrs, learn_interaction
from are_stats.fitting._motion_checks import motion_checks
from are_stats.fitting._motion_store import motion_attrs
from are_stats.fitting._prediction import displacement_errors
from are_stats.logs import LifecycleLog
from are_stats.scenarios import realism_features, realism_summary, realism_table
from are_stats.traffic import LifecycleData, LifecyclePriors, fold_in_key, key_from_seed

if TYPE_CHECKING:  # the type only: ArviZ (+3.0 s CPU on import are_stats.fitting) loads later
    import arviz as az

__all__ = ["FIT_WINDOWS", "fit_log", "log_sha256"]

#: Held-out windows (8 observed, 12 predicted) the fit scores ADE/FDE on, at most.
FIT_WINDOWS = 200


def log_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes (read in 1 MiB blocks): the fit's ``log_sha256``."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _seed_of(key: int | jax.Array) -> tuple[jax.Array, int | None]:
    """A PRNG key and the int seed it came from (None for a key given as such)."""
    if isinstance(key, int | np.integer) and not isinstance(key, bool):
        return key_from_seed(int(key)), int(key)
    return key, None


class _Walkers(NamedTuple):
    """What a tracks table's behaviour needs of the tracks alone (:func:`_fit_walkers`)."""

    grid: OccupancyGrid  # the map, or the open area the tracks cover
    bfit: BehaviourFit | None  # None: nobody walks (a note says why)
    learned: SocialForce | None  # learn_interaction's (None also when nobody walks)
    info: dict[str, float]
    notes: list[str]  # in the order the fit tells them
    classes_done: list[tuple[int, int]]  # fit_behaviour's progress (done, total), in order


def _fit_walkers(
    seed: int,
    log: LifecycleLog,
    grid: OccupancyGrid | None,
    features: tuple[str, ...],
    catalogue: ArtefactCatalogue | None,
) -> _Walkers:
    """The behaviour (:func:`~are_stats.fitting.fit_behaviour`) and the interaction
    (:func:`~are_stats.fitting.learn_interaction`) of a tracks table, with the map they use.

    Neither depends on the traffic fit, so :func:`fit_log` runs this in a thread beside it
    (issue 29: on a first fit the traffic stage mostly waits on XLA compiling its
    candidates' programs, and the behaviour fit's own compile and solves fill that wait).
    Nothing here draws from the traffic fit's key; only the behaviour's soft solves run a
    program across the devices with a collective (``pmax``), and nothing else in the fit
    does, so no two such programs are ever in flight at once.
    """
    notes: list[str] = []
    done: list[tuple[int, int]] = []  # told to the stage clock after the thread (_behaviour)
    tracks = log.tracks
    if grid is not None:
        free, res, origin = grid.free, grid.resolution, grid.origin[:2]
    else:  # no map: the open area the tracks cover (issue 26)
        free, res, origin = open_area_grid(tracks, source=log.source)
        # the criticism (motion checks, realism) then scores on that open area too
        grid = OccupancyGrid(np.where(free, 0, 100), res, (origin[0], origin[1], 0.0))
        notes.append(
            "no map in the manifest: behaviour fitted on the open area the tracks cover "
            f"({free.shape[1] * res:.1f} x {free.shape[0] * res:.1f} m, their bounding box "
            "plus 1 m, all free)"
        )
    run_speed = None if catalogue is None else catalogue.run_thresholds()
    try:
        bfit = fit_behaviour(
            tracks,
            free,
            res,
            origin,
            seed=seed,
            features=features or None,
            run_speed=run_speed,
            progress=lambda d, total: done.append((d, total)),
        )
    except NoWalkersError as err:  # nobody walks: no walking to learn
        notes.append(f"behaviour not fitted ({err}); scenes use the catalogue's")
        return _Walkers(grid, None, None, {}, notes, done)
    if bfit.standing:  # classes that only stand: the others' behaviour is fitted
        one = len(bfit.standing) == 1
        notes.append(
            f"behaviour fitted for {', '.join(map(repr, bfit.classes))}; "
            f"{'class' if one else 'classes'} {', '.join(map(repr, bfit.standing))} "
            f"{'has' if one else 'have'} no moving walkers in the tracks and "
            f"{'stands' if one else 'stand'} in the scenes (the realism and displacement "
            "errors score the walking classes' tracks)"
        )
    # the walking classes' accelerations (the standing ones still push them)
    learned, info, note = learn_interaction(tracks, bfit.standing)
    if note:
        notes.append(note)
    return _Walkers(grid, bfit, learned, info, notes, done)


def _behaviour(
    seed: int,
    idata: az.InferenceData,
    log: LifecycleLog,
    walkers: Future[_Walkers],
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[
    az.InferenceData,
    OccupancyGrid,
    tuple[pd.DataFrame, dict[str, np.ndarray | pd.DataFrame]] | None,
]:
    """The behaviour, interaction and motion tables of a tracks table, attached to ``idata``;
    the map used and the motion checks of a labelled table (None without labels). The
    behaviour and interaction come from ``walkers`` (:func:`_fit_walkers`, running in a
    thread); the long stages report their steps to ``say.steps(done, total, what)`` when it
    has one."""
    steps = _steps_of(say)
    say("behaviour from the tracks (speeds, exits, rationality)")
    w = walkers.result()
    for done, total in w.classes_done:  # the classes fitted in the thread, told now
        steps(done, total, "classes")
    notes.extend(w.notes)
    if w.bfit is None:
        return idata, w.grid, None
    bfit, learned, grid = w.bfit, w.learned, w.grid
    idata = attach_behaviour(idata, bfit)
    say("interaction (social force) from the tracks")
    if learned is not None:
        idata.behaviour.attrs.update(interaction_attrs(learned, w.info))
    say("realism and displacement errors against the tracks")
    tracks = log.tracks
    walking = tracks
    if bfit.standing:  # the criticism scores the behaviour fitted: the walking classes
        walking = tracks[~tracks["label"].astype(str).isin(bfit.standing).to_numpy()]
    checks = _attach_motion_tables(seed, idata, bfit, learned, walking, grid, steps)
    return idata, grid, checks


def _steps_of(progress: object) -> Callable[[int, int, str], None]:
    """``progress.steps`` (a stage clock's: :meth:`~are_stats._stage_clock.StageClock.steps`),
    or a no-op for a plain ``progress(message)`` or None."""
    steps = getattr(progress, "steps", None)
    return steps if callable(steps) else (lambda done, total, what: None)


def _attach_motion_tables(
    seed: int,
    idata: az.InferenceData,
    bfit: BehaviourFit,
    learned: SocialForce | None,
    tracks: pd.DataFrame,
    grid: OccupancyGrid,
    steps: Callable[[int, int, str], None] | None = None,
) -> tuple[pd.DataFrame, dict[str, np.ndarray | pd.DataFrame]] | None:
    """Realism and displacement errors against the log's tracks, stored in the fit so that
    ``report`` shows them (the tracks are not stored): issue 26. Tracks with labels also
    store the per-class motion rows (median speed, fraction still: issue 31); their motion
    checks (table, replicates) are returned for the report to reuse (None without labels).

    ``steps(done, total, what)`` is told each step: the realism table's replicates, then
    the displacement errors, then the motion checks' steps (labels only: their routes'
    chunks and social force windows, :func:`motion_checks`). The realism runs first
    so that the count is known at the first step (its own total); each part draws with its
    own key, so the order changes no number."""
    say = steps or (lambda done, total, what: None)
    after = 1 + int("label" in tracks.columns)  # displacement errors, motion checks
    key = key_from_seed(seed)
    # every walk below (realism, displacement errors, motion checks) with the log's own
    # social force, else the published one
    interaction = learned if learned is not None else True
    # realism, the sim-agents way: constant velocity, the catalogue and the fitted behaviour
    # (each through the one assembly, social force included) against the log
    xy = tracks[["id", "t", "x", "y"]]
    walked = [0]  # the realism table's replicates

    def realism_step(done: int, total: int) -> None:
        walked[0] = total
        say(done, total + after, f"realism, replicate {done} of {total}")

    # the three parts draw with their own keys and share nothing they change, so the
    # displacement errors and the motion checks run in threads beside the realism (issue
    # 29: on idle cores one part's compiles and Python fill another's waits; none runs a
    # program with a collective across the devices); their steps are held back and told
    # in the order of one part after the other (_Relay), so the clock sees the same steps
    def check_step(done: int, total: int, what: str) -> None:
        say(walked[0] + 1 + done, walked[0] + 1 + total, f"motion checks, {what}")

    labelled = "label" in tracks.columns
    errors_say, checks_say = _Relay(say), _Relay(check_step)
    with ThreadPoolExecutor(1 + int(labelled), "are-stats-criticism") as pool:
        # predicted as generation walks people: continuous paths, then the fit's social
        # force at most FIT_WINDOWS windows: each rolls out a path per candidate goal (the
        # table keeps n_windows and the standard errors)
        pending_errors = pool.submit(
            displacement_errors,
            fold_in_key(key, 3),
            bfit,
            tracks.copy(),  # a table of its own: pandas' caches are not for two threads
            n_samples=20,
            interaction=interaction,
            grid=grid,
            max_windows=FIT_WINDOWS,
            progress=errors_say,
        )
        # the report's motion checks (write_motion_report) draw with the same key: computed
        # once here and handed on with the fit
        pending_checks = None
        if labelled:
            pending_checks = pool.submit(
                motion_checks,
                fold_in_key(key, 1),
                bfit,
                tracks.copy(),
                n_replicates=50,
                interaction=interaction,
                grid=grid,
                progress=checks_say,
            )
        real = realism_table(
            fold_in_key(key, 4),
            xy,
            grid,
            behaviour=bfit,
            n_replicates=1,
            interaction=interaction,
            progress=realism_step,
        )
        errors_say.go_live()
        errors = pending_errors.result()
        say(walked[0] + 1, walked[0] + after, "displacement errors")
        checks_say.go_live()
        same = xy["id"].to_numpy()[1:] == xy["id"].to_numpy()[:-1]
        dt = float(np.median(np.diff(xy.sort_values(["id", "t"])["t"].to_numpy(float))[same]))
        observed = realism_summary(realism_features(xy, dt, grid))
        idata.behaviour.attrs.update(
            motion_attrs(realism=real, observed=observed, displacement=errors)
        )
        if pending_checks is None:
            return None
        table, reps = pending_checks.result()
    per_class = class_motion_checks(tracks, reps)
    if per_class is not None:
        idata.behaviour.attrs.update(motion_attrs(class_motion=per_class.reset_index()))
    return table, reps


class _Relay:
    """``progress(done, total, what)`` called from a thread, held back until
    :meth:`go_live` (then told in order), and passed straight on after it: a part run
    beside another tells its steps when it would have run alone."""

    def __init__(self, say: Callable[[int, int, str], None]) -> None:
        self._say, self._live = say, False
        self._held: list[tuple[int, int, str]] = []
        # re-entrant: a step told while go_live tells the held ones (from another thread,
        # or from ``say`` itself) comes after them
        self._lock = threading.RLock()

    def __call__(self, done: int, total: int, what: str) -> None:
        with self._lock:
            if self._live:
                self._say(done, total, what)
            else:
                self._held.append((done, total, what))

    def go_live(self) -> None:
        """Tell the steps held so far, then pass the next ones straight on."""
        with self._lock:
            for step in self._held:
                self._say(*step)
            self._held, self._live = [], True


def fit_log(
    key: int | jax.Array,
    log: LifecycleLog | LifecycleData,
    settings: FitSettings = FitSettings(),  # noqa: B008 (frozen, immutable)
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    counts_panel: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Callable[[str], None] | None = None,
    class_labels: Sequence[str] | None = None,
    grid: OccupancyGrid | None = None,
    clock_start: str | None = None,
    classes: npt.ArrayLike | None = None,
    *,
    behaviour: bool = True,
    features: tuple[str, ...] = (),
    catalogue: ArtefactCatalogue | None = None,
    setting_names: Mapping[str, str] | None = None,
) -> Fit:
    """Fit one field log: the whole fit ``are-stats fit`` writes.

    Parameters
    ----------
    key : int or jax PRNG key
        All randomness of the fit (reproducible from it). With a tracks table, an int seed
        (as the CLI's ``--seed``) also seeds the behaviour fit and its motion criticism; a
        key then seeds them with its first word.
    log : LifecycleLog or LifecycleData
        A field log read once by :func:`are_stats.logs.read_field_log` (life-cycle rows,
        the tracks of a tracks table, the manifest with its map), or an already validated
        :class:`~are_stats.logs.LifecycleData` (the traffic models only; ``class_labels``,
        ``classes``, ``grid`` and ``clock_start`` as :func:`fit_lifecycle_data` takes them).
    settings, priors, counts_panel
        See :func:`fit_lifecycle_data`.
    progress : callable, optional
        ``progress(stage)`` at each stage, as :func:`fit_lifecycle_data` takes it (one with
        ``left(seconds, words)`` is told the NUTS fits' time left). One that also has a
        ``steps(done, total, what)`` method (:class:`~are_stats._stage_clock.StageClock`)
        is told the steps of a tracks table's long stages, after each: the behaviour's
        classes (:func:`~are_stats.fitting.fit_behaviour`), then the realism table's
        replicates (:func:`~are_stats.scenarios.realism_table`), the displacement errors
        and, with labels, the motion checks; the clock shows a time left from their rate
        on a machine's first run. A plain callable is only told the stages.
    class_labels, grid, clock_start, classes
        Only with a :class:`~are_stats.logs.LifecycleData`: a field log supplies them (its
        labels, the manifest's map, its ``clock_start``, its label classes).
    behaviour : bool
        Fit the behaviour, interaction and motion tables of a tracks table.
    features : tuple of str
        Extra reward features of the behaviour (:data:`BEHAVIOUR_FEATURES`).
    catalogue : ArtefactCatalogue, optional
        The property table Q: the labels' rows (an unknown label is an error) and the
        classes' run speeds (default :func:`~are_stats.environment.load_catalogue`).
    setting_names : mapping of str to str, optional
        What a size error calls the sampler settings: the draws and the NUTS work are
        checked against the limits of :mod:`are_stats.inputs` before anything is sampled
        (:func:`~are_stats.fitting.check_fit_size`; the CLI names its options).

    Returns
    -------
    Fit
        The decoded fit (:attr:`Fit.idata` is what :func:`write_fit` writes), with the
        notes on what was not fitted and why (:attr:`Fit.notes`).

    Raises
    ------
    are_stats.inputs.InputError
        For a label the catalogue does not have (naming the file and column ``label``).
    are_stats.inputs.LimitError
        For draws or NUTS work past the limits (:func:`~are_stats.fitting.check_fit_size`).
    """
    key, seed = _seed_of(key)
    if isinstance(log, LifecycleData):
        idata = fit_lifecycle_data(
            key,
            log,
            settings,
            priors,
            counts_panel,
            progress,
            class_labels,
            grid,
            clock_start,
            classes,
            setting_names=setting_names,
        )
        return fit_from_idata(idata)
    if not isinstance(log, LifecycleLog):
        raise ValueError(
            f"log: expected a LifecycleLog (read_field_log) or LifecycleData, got "
            f"{type(log).__name__}"
        )
    say = progress or (lambda _msg: None)
    data = log.to_lifecycle_data()
    # labels without marks: the class is the label, found in the catalogue by name (issue 31)
    labelled = log.label_classes()
    catalogue = load_catalogue() if catalogue is None else catalogue
    if labelled is not None:
        catalogue.rows_of_labels(labelled[1], source=log.source, where="column 'label'")
    tracks = log.tracks if behaviour else None
    if (settings.positions != "uniform" or tracks is not None) and log.manifest.get("map"):
        grid = OccupancyGrid.from_ros_yaml(log.manifest["map"])
    # the behaviour and interaction need the tracks alone: fitted in a thread beside the
    # traffic models (_fit_walkers), whose first fit mostly waits on XLA compiling
    pool = ThreadPoolExecutor(1, "are-stats-walkers")
    walkers = None
    if tracks is not None:
        if seed is None:
            seed = int(np.asarray(jax.random.key_data(key)).ravel()[-1])
        walkers = pool.submit(_fit_walkers, seed, log, grid, features, catalogue)
    with pool:  # an error in the traffic fit waits for the thread, then is raised
        idata = fit_lifecycle_data(
            key,
            data,
            settings,
            priors,
            counts_panel,
            progress,
            class_labels=(
                log.to_arrays()["label_names"]
                if data.labels is not None or labelled is not None
                else None
            ),
            grid=None if settings.positions == "uniform" else grid,
            clock_start=log.clock_start,
            classes=None if labelled is None else labelled[0],
            setting_names=setting_names,
        )
        notes: list[str] = []
        checks = None
        if walkers is not None:
            idata, grid, checks = _behaviour(seed, idata, log, walkers, say, notes)
    # the log's file name and content hash, never its folder (a shared fit must not carry
    # the user's folder layout): the hash identifies the bytes that were fitted
    rep = log.report()
    rep["source"] = Path(str(rep.get("source") or log.source)).name
    stamp: dict[str, int | str] = {} if seed is None else {"seed": int(seed)}
    stamp["log"] = Path(log.source).name
    if Path(log.source).is_file():
        stamp["log_sha256"] = log_sha256(log.source)
    stamp["log_report"] = yaml.safe_dump(rep, sort_keys=False)
    if notes:
        stamp["fit_notes"] = "\n".join(notes)
    idata.posterior.attrs.update(stamp)
    return dataclasses.replace(fit_from_idata(idata, log.source), grid=grid, motion_checks=checks)
