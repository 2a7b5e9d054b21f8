"""The artefact life-cycle as a marked Poisson process (Sec. 3.2 of the paper, eq. 1).

Artefacts arrive in the free area ``nu(M2D)`` of the occupancy grid as a homogeneous Poisson
process of intensity ``arrival_rate * area`` (``arrival_rate`` is the paper's lambda, per m^2
per time unit). Each arrival draws

* a position uniform over the free cells and a heading uniform in ``[0, 2 pi)``
  (the spatial marking of Fig. 3b, DECISIONS 4);
* an integer mark ``X`` from the Poisson mixture of eq. (1); the component that produced it is
  the artefact's class (DECISIONS 5);
* an exponential lifetime of rate ``leave_rate`` (the paper's mu).

A field log covers a window ``[t0, t1]`` (DECISIONS 3): artefacts still present at ``t1`` are
right-censored, artefacts already present at ``t0`` are left-truncated (arrival unknown; by
memorylessness their residual lifetime is again exponential of rate mu).

One numpyro model, :func:`lifecycle_model`, gives prior-predictive draws (``data=None``) and,
conditioned on a :class:`LifecycleData` log, the posterior by NUTS with a vectorised
likelihood whose cost scales with the number of artefacts for the stays and with the number of
*distinct* marks for the mixture.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from functools import cached_property
from typing import Any, NamedTuple  # Any: aot_compile's pytrees, in and out

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import numpyro
import numpyro.distributions as dist
from jax.scipy.special import gammaln
from numpyro.distributions import constraints

from are_stats._checks import (
    check_array,
    check_finite,
    check_in,
    check_nonneg_int,
    check_positive,
    check_simplex,
    describe,
)
from are_stats._program_cache import compile_program
from are_stats.traffic._keys import key_bits
from are_stats.traffic._mixture import PoissonMixture
from are_stats.traffic._positions import PositionDensity, uniform_position_density
from are_stats.traffic._sampler import TrafficLaws, sample_population

__all__ = [
    "aot_compile",
    "check_components",
    "LifecycleSummary",
    "numpy_rng",
    "LifecyclePriors",
    "LifecycleData",
    "simulate_lifecycle",
    "simulate_traffic_log",
    "lifecycle_model",
    "prior_predictive",
]


# --------------------------------------------------------------------------------------
# priors
# --------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class LifecyclePriors:
    """Explicit priors of the life-cycle model (all Gamma laws in shape-rate form).

    Units: ``arrival_rate`` (lambda) is in artefacts per m^2 per time unit, ``leave_rate``
    (mu) in departures per artefact per time unit, where the time unit is the one of the log
    (seconds for ROS logs). The defaults are weakly informative: a Gamma(1, 1) prior adds the
    information of one event over one unit of exposure (1 m^2 x 1 s for lambda, 1 artefact x
    1 s for mu), negligible against any field log, while keeping the prior proper.

    Parameters
    ----------
    arrival_shape, arrival_rate : float
        Gamma(shape, rate) prior on ``arrival_rate`` (lambda). Prior mean
        ``arrival_shape / arrival_rate``.
    leave_shape, leave_rate : float
        Gamma(shape, rate) prior on ``leave_rate`` (mu).
    weights_concentration : float
        Symmetric Dirichlet concentration of the prior on ``mix_weights`` (pi_i of eq. 1).
    mix_rate_shape, mix_rate_rate : float
        Each component rate (lambda_i of eq. 1) is a priori Gamma(shape, rate). Without class
        labels the rates are the order statistics of ``n_components`` such draws (an ordered,
        exchangeable prior that removes label switching); with labels they are independent.
        The default Gamma(2, 0.1) has mean 20 and covers marks from about 1 to 60.

    Raises
    ------
    ValueError
        If any value is not a finite number > 0 (the message names the field).
    """

    arrival_shape: float = 1.0
    arrival_rate: float = 1.0
    leave_shape: float = 1.0
    leave_rate: float = 1.0
    weights_concentration: float = 1.0
    mix_rate_shape: float = 2.0
    mix_rate_rate: float = 0.1

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            checked = check_positive(f"LifecyclePriors.{field.name}", value, ndim=0)
            object.__setattr__(self, field.name, float(checked))


class _OrderedGamma(dist.Distribution):
    """Order statistics of ``size`` i.i.d. Gamma(concentration, rate) draws.

    Density ``size! * prod_k Gamma(r_k)`` on the increasing positive vectors.
    """

    arg_constraints = {"concentration": constraints.positive, "rate": constraints.positive}
    support = constraints.positive_ordered_vector
    reparametrized_params = ["concentration", "rate"]

    def __init__(self, concentration: float, rate: float, size: int, *, validate_args=None):
        self.concentration = concentration
        self.rate = rate
        self.size = int(size)
        super().__init__(batch_shape=(), event_shape=(self.size,), validate_args=validate_args)

    def sample(self, key, sample_shape=()):
        base = dist.Gamma(self.concentration, self.rate)
        return jnp.sort(base.sample(key, tuple(sample_shape) + (self.size,)), axis=-1)

    def log_prob(self, value):
        base = dist.Gamma(self.concentration, self.rate)
        return base.log_prob(value).sum(-1) + gammaln(self.size + 1.0)


# Compilation dominates the cost of these small models (a NUTS step takes microseconds):
# compile once, ahead of time, with cheap XLA optimisation.
_COMPILER_OPTIONS = {
    "xla_backend_optimization_level": 0,
    "xla_llvm_disable_expensive_passes": True,
}


def aot_compile(
    fn: Callable[..., Any], *args: Any, key: tuple | None = None, in_shardings: tuple | None = None
) -> Callable[..., Any]:
    """Compile a jitted/pmapped ``fn`` ahead of time for ``args`` with cheap XLA optimisation
    (small programs whose compile time outweighs their run time).

    Parameters
    ----------
    fn : jax.stages.Wrapped
        A ``jax.jit`` or ``jax.pmap`` function.
    *args : pytrees of arrays
        Example arguments (their shapes and dtypes fix the program).
    key : tuple, optional
        What shapes ``fn``'s trace besides ``args`` (its function by name, static
        arguments): with one, the traced program is kept on disk for later processes
        (:func:`are_stats._program_cache.compile_program`).
    in_shardings : tuple, optional
        One sharding per argument, for a program over several devices.

    Returns
    -------
    callable
        The compiled program.
    """
    return compile_program(fn, args, key, _COMPILER_OPTIONS, in_shardings)


def _mark_distribution(weights, rates) -> dist.Distribution:
    """The mark law of eq. (1): a Poisson mixture with ``weights`` (pi_i) and ``rates``."""
    return PoissonMixture(weights, rates)


# --------------------------------------------------------------------------------------
# data container
# --------------------------------------------------------------------------------------


class LifecycleSummary(NamedTuple):
    """Sufficient statistics of a log (computed once, used by the likelihood).

    A pytree: :func:`fit_lifecycle_nuts` passes it (padded to bucketed sizes with zero-weight
    rows) as an argument of its compiled programs, so logs of similar size share one
    compilation.
    """

    duration: float  # t1 - t0
    area: float  # free area in m^2
    n_arrivals: int  # arrivals observed inside the window (not left-truncated)
    n_present: int  # artefacts present at t0 (left-truncated)
    dwell: np.ndarray  # (n,) time each artefact is observed inside the window
    departed: np.ndarray  # (n,) bool, departure observed (not right-censored)
    mark_values: np.ndarray  # (m,) distinct marks
    mark_counts: np.ndarray  # (m,) their multiplicities
    pair_labels: np.ndarray  # (p,) distinct (label, mark) pairs: label
    pair_marks: np.ndarray  # (p,) ... and mark
    pair_counts: np.ndarray  # (p,) multiplicities


def _optional_column(name: str, value: npt.ArrayLike, n: int, kind: str) -> np.ndarray | None:
    if value is None:
        return None
    if kind == "int":
        a = check_nonneg_int(name, value, ndim=1)
    else:
        a = check_finite(name, value, ndim=1)
    if a.shape[0] != n:
        raise ValueError(f"{name}: expected {n} rows (one per artefact), got {a.shape[0]}")
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class LifecycleData:
    """One observed window of the artefact life-cycle (DECISIONS 3).

    One row per artefact seen in the window ``[t0, t1]``. Artefacts already present at ``t0``
    are left-truncated: their arrival time is unknown (NaN). Artefacts still present at
    ``t1`` are right-censored: their departure time is unknown (NaN). The masks
    :attr:`truncated` and :attr:`censored` are derived from the NaNs, so they cannot disagree
    with the times.

    Parameters
    ----------
    t_arrive : (n,) float
        Arrival times in ``[t0, t1]``; NaN for artefacts present at ``t0``.
    t_leave : (n,) float
        Departure times in ``[t0, t1]`` and not before the arrival; NaN when censored at
        ``t1``.
    window : (2,) float
        The observation window ``(t0, t1)`` with ``t1 > t0``.
    area : float
        The free area ``nu(M2D)`` in m^2 (free cells times resolution squared, DECISIONS 4).
    marks : (n,) int, optional
        Integer marks X >= 0 (eq. 1), one per artefact.
    labels : (n,) int, optional
        Class of each artefact (the mixture component, DECISIONS 5). Needs ``marks``.
    x, y : (n,) float, optional
        Arrival positions in metres (map frame).
    yaw : (n,) float, optional
        Arrival headings in radians.
    group : (n,) int, optional
        Group of each artefact (integers >= 0): artefacts with the same value arrived
        together (they share the group's arrival time and entry point). Artefacts alone have
        a group of their own. None: every artefact is alone.
    x_exit, y_exit : (n,) float, optional
        Leaving positions in metres (map frame; last sighting); NaN where unknown (still
        present at ``t1``).

    Raises
    ------
    ValueError
        Naming the field and the row when a value is invalid: a departure before its
        arrival, a time outside the window, a negative or non-integer mark, columns of
        different lengths, an empty window or a non-positive area.

    Examples
    --------
    >>> import numpy as np
    >>> d = LifecycleData(
    ...     t_arrive=np.array([np.nan, 2.0, 5.0]),
    ...     t_leave=np.array([1.5, np.nan, 7.0]),
    ...     window=(0.0, 10.0),
    ...     area=50.0,
    ... )
    >>> d.truncated.tolist(), d.censored.tolist()
    ([True, False, False], [False, True, False])
    """

    t_arrive: np.ndarray
    t_leave: np.ndarray
    window: tuple[float, float]
    area: float
    marks: np.ndarray | None = None
    labels: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    yaw: np.ndarray | None = None
    group: np.ndarray | None = None
    x_exit: np.ndarray | None = None
    y_exit: np.ndarray | None = None

    def __post_init__(self) -> None:
        w = check_finite("window", self.window, ndim=1)
        if w.shape != (2,):
            raise ValueError(f"window: expected (t0, t1), got {describe(self.window)}")
        t0, t1 = float(w[0]), float(w[1])
        if not t1 > t0:
            raise ValueError(f"window: expected t1 > t0 (a non-empty window), got ({t0}, {t1})")
        area = float(check_positive("area", self.area, ndim=0))
        ta = check_array("t_arrive", self.t_arrive, float, ndim=1)
        tl = check_array("t_leave", self.t_leave, float, ndim=1)
        n = ta.shape[0]
        if tl.shape[0] != n:
            raise ValueError(f"t_leave: expected {n} rows (as many as t_arrive), got {tl.shape[0]}")
        for name, a in (("t_arrive", ta), ("t_leave", tl)):
            bad = np.isinf(a) | (~np.isnan(a) & ((a < t0) | (a > t1)))
            if bad.any():
                i = int(np.argmax(bad))
                raise ValueError(
                    f"{name}: expected a time inside the window [{t0}, {t1}] or NaN, "
                    f"got {a[i]!r} at row {i}"
                )
        bad = ~np.isnan(ta) & ~np.isnan(tl) & (tl < ta)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"t_leave: expected a departure not before the arrival, got t_leave "
                f"{tl[i]!r} < t_arrive {ta[i]!r} at row {i}"
            )
        marks = _optional_column("marks", self.marks, n, "int")
        labels = _optional_column("labels", self.labels, n, "int")
        if labels is not None and marks is None:
            raise ValueError("labels: expected marks as well (labels are the marks' classes)")
        x = _optional_column("x", self.x, n, "float")
        y = _optional_column("y", self.y, n, "float")
        yaw = _optional_column("yaw", self.yaw, n, "float")
        group = _optional_column("group", self.group, n, "int")
        exits = {}
        for name in ("x_exit", "y_exit"):
            v = self.__dict__[name]
            if v is None:
                exits[name] = None
                continue
            a = check_array(name, v, float, ndim=1)
            if a.shape[0] != n:
                raise ValueError(f"{name}: expected {n} rows (one per artefact), got {a.shape[0]}")
            if np.isinf(a).any():
                i = int(np.argmax(np.isinf(a)))
                raise ValueError(
                    f"{name}: expected a finite position or NaN, got {a[i]!r} at row {i}"
                )
            exits[name] = a
        for name, value in (
            ("group", group),
            ("x_exit", exits["x_exit"]),
            ("y_exit", exits["y_exit"]),
            ("window", (t0, t1)),
            ("area", area),
            ("t_arrive", ta),
            ("t_leave", tl),
            ("marks", marks),
            ("labels", labels),
            ("x", x),
            ("y", y),
            ("yaw", yaw),
        ):
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        """Number of artefacts (rows)."""
        return int(self.t_arrive.shape[0])

    @property
    def truncated(self) -> np.ndarray:
        """(n,) bool: present at ``t0``, arrival unknown (left-truncated)."""
        return np.isnan(self.t_arrive)

    @property
    def censored(self) -> np.ndarray:
        """(n,) bool: still present at ``t1``, departure unknown (right-censored)."""
        return np.isnan(self.t_leave)

    @property
    def duration(self) -> float:
        """Window length ``t1 - t0``."""
        return float(self.window[1] - self.window[0])

    @property
    def dwell(self) -> np.ndarray:
        """(n,) float: time each artefact is observed inside the window.

        From its arrival (or ``t0`` when truncated) to its departure (or ``t1`` when
        censored). The sum is the exposure of the conjugate posterior of ``leave_rate``.
        """
        t0, t1 = self.window
        start = np.where(self.truncated, t0, self.t_arrive)
        end = np.where(self.censored, t1, self.t_leave)
        return end - start

    @cached_property
    def summary(self) -> LifecycleSummary:
        """The log's sufficient statistics for the likelihood (computed once)."""
        empty = np.zeros(0, dtype=np.int64)
        mark_values = mark_counts = empty
        pair_labels = pair_marks = pair_counts = empty
        if self.marks is not None:
            mark_values, mark_counts = np.unique(self.marks, return_counts=True)
            if self.labels is not None:
                pairs, pair_counts = np.unique(
                    np.stack([self.labels, self.marks], axis=1), axis=0, return_counts=True
                )
                pair_labels, pair_marks = pairs[:, 0], pairs[:, 1]
        return LifecycleSummary(
            duration=self.duration,
            area=self.area,
            n_arrivals=int((~self.truncated).sum()),
            n_present=int(self.truncated.sum()),
            dwell=self.dwell,
            departed=~self.censored,
            mark_values=mark_values,
            mark_counts=mark_counts,
            pair_labels=pair_labels,
            pair_marks=pair_marks,
            pair_counts=pair_counts,
        )


# --------------------------------------------------------------------------------------
# simulation
# --------------------------------------------------------------------------------------


def _check_window(window: npt.ArrayLike) -> tuple[float, float]:
    w = check_finite("window", window, ndim=1)
    if w.shape != (2,) or not w[1] > w[0]:
        raise ValueError(f"window: expected (t0, t1) with t1 > t0, got {describe(window)}")
    return float(w[0]), float(w[1])


def _check_mixture(weights: npt.ArrayLike, rates: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    w = check_simplex("mix_weights", weights)
    r = check_positive("mix_rates", rates, ndim=1)
    if r.shape != w.shape:
        raise ValueError(
            f"mix_rates: expected {w.shape[0]} rates (one per weight), got {r.shape[0]}"
        )
    return w / w.sum(), r


def numpy_rng(key: jax.Array) -> np.random.Generator:
    """A NumPy generator seeded from a JAX key (variable-size draws without recompiling).

    Parameters
    ----------
    key : jax.Array
        A JAX PRNG key.

    Returns
    -------
    numpy.random.Generator

    Raises
    ------
    ValueError
        If ``key`` is not a JAX PRNG key.
    """
    try:
        bits = key_bits(key, 4)  # jax.random.bits's, without its XLA programs
    except (TypeError, ValueError) as err:
        raise ValueError(f"key: expected a JAX PRNG key, got {describe(key)}") from err
    return np.random.default_rng(np.asarray(bits).tolist())


def simulate_lifecycle(
    key: jax.Array,
    arrival_rate: float,
    leave_rate: float,
    mix_weights: npt.ArrayLike,
    mix_rates: npt.ArrayLike,
    window: tuple[float, float],
    area: float | None = None,
    free_mask: npt.ArrayLike | None = None,
    resolution: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    stationary_start: bool = True,
) -> LifecycleData:
    """Simulate one observed window of the marked Poisson life-cycle exactly.

    The population is drawn by the one sampler of the life-cycle process
    (:func:`are_stats.traffic.sample_population` with the paper's laws) and seen through
    the window as a field log records it. Arrivals in ``[t0, t1]``: a
    Poisson(``arrival_rate * area * (t1 - t0)``) number of uniform times (sorted);
    exponential(``leave_rate``) lifetimes; departures at or after ``t1`` are censored
    (NaN). With ``stationary_start`` the window opens on the stationary
    population of the immigration-death process: a Poisson(``arrival_rate * area /
    leave_rate``) number of artefacts already present (arrival NaN) with exponential residual
    lifetimes. Every artefact draws a mark from the Poisson mixture of eq. (1) and its class
    (the component). Fully vectorised: no Python loop per artefact.

    Parameters
    ----------
    key : jax PRNG key
        Randomness; the draws are made by a NumPy generator seeded from the key.
    arrival_rate : float
        lambda > 0, artefacts per m^2 per time unit.
    leave_rate : float
        mu > 0, departures per artefact per time unit.
    mix_weights : (k,) float
        Mixture weights pi_i of eq. (1), summing to one.
    mix_rates : (k,) float
        Component rates lambda_i of eq. (1), > 0.
    window : (2,) float
        Observation window ``(t0, t1)``.
    area : float, optional
        Free area in m^2. Defaults to the free area of ``free_mask``; when both are given
        they must agree.
    free_mask : (H, W) bool, optional
        Free cells of the occupancy grid. Cell ``[i, j]`` covers
        ``x in [x0 + j r, x0 + (j + 1) r)``, ``y in [y0 + i r, y0 + (i + 1) r)``
        (ROS ``OccupancyGrid`` row-major order). Without it, no positions are drawn.
    resolution : float
        Cell size ``r`` in metres.
    origin : (2,) float
        Map-frame position ``(x0, y0)`` of the corner of cell ``[0, 0]``.
    stationary_start : bool
        Open the window on the stationary population (left-truncated artefacts).

    Returns
    -------
    LifecycleData
        Rows: the artefacts present at ``t0`` first, then the arrivals in time order. With
        ``free_mask``, ``x``, ``y`` (uniform inside a uniformly chosen free cell) and ``yaw``
        (uniform in ``[0, 2 pi)``) are filled.

    Raises
    ------
    ValueError
        Naming the argument when a rate, the mixture, the window, the mask or the area is
        invalid.

    Examples
    --------
    >>> import jax
    >>> d = simulate_lifecycle(jax.random.key(0), 0.01, 0.1, [0.5, 0.5], [3.0, 15.0],
    ...                        window=(0.0, 100.0), area=100.0)
    >>> bool(d.n > 0)
    True
    """
    lam = float(check_positive("arrival_rate", arrival_rate, ndim=0))
    mu = float(check_positive("leave_rate", leave_rate, ndim=0))
    weights, rates = _check_mixture(mix_weights, mix_rates)
    t0, t1 = _check_window(window)
    check_in("stationary_start", stationary_start, (True, False))
    cells = None
    res = float(check_positive("resolution", resolution, ndim=0))
    orig = check_finite("origin", origin, ndim=1)
    if orig.shape != (2,):
        raise ValueError(f"origin: expected (x0, y0), got {describe(origin)}")
    if free_mask is not None:
        mask = np.asarray(free_mask)
        if mask.ndim != 2 or mask.dtype != np.bool_:
            raise ValueError(
                f"free_mask: expected a 2-d bool array, got {mask.dtype} of shape {mask.shape}"
            )
        cells = np.argwhere(mask)
        if cells.shape[0] == 0:
            raise ValueError("free_mask: expected at least one free cell, got none")
        mask_area = cells.shape[0] * res**2
        if area is None:
            area = mask_area
        elif not math.isclose(float(area), mask_area, rel_tol=1e-9):
            raise ValueError(
                f"area: expected the free area of free_mask ({mask_area} m^2), got {area!r}"
            )
    if area is None:
        raise ValueError("area: expected the free area in m^2 (or a free_mask), got None")
    area = float(check_positive("area", area, ndim=0))

    rng = numpy_rng(key)
    free = None
    if cells is not None:
        free = uniform_position_density(free_mask, res, (float(orig[0]), float(orig[1])))
    # the one sampler of the life-cycle process (the paper's laws), seen through the window
    pop = sample_population(
        rng,
        {"event_rate": lam, "stay_mean": 1.0 / mu},
        TrafficLaws(),
        t1 - t0,
        area,
        start="stationary" if stationary_start else "empty",
        free=free,
    )
    n = pop["t_arrive"].size
    initial = pop["truncated"]
    t_arrive = np.where(initial, np.nan, pop["t_arrive"] + t0)
    leave = pop["t_leave"] + t0
    t_leave = np.where(leave < t1, leave, np.nan)
    labels = rng.choice(weights.shape[0], size=n, p=weights)
    marks = rng.poisson(rates[labels])
    x = y = yaw = None
    if cells is not None:
        x, y = pop["x"], pop["y"]
        yaw = rng.uniform(0.0, 2.0 * np.pi, size=n)
    return LifecycleData(
        t_arrive=t_arrive,
        t_leave=t_leave,
        window=(t0, t1),
        area=area,
        marks=marks,
        labels=labels,
        x=x,
        y=y,
        yaw=yaw,
    )


def simulate_traffic_log(
    rng: np.random.Generator,
    draw: Mapping[str, npt.ArrayLike],
    laws: TrafficLaws,
    window: tuple[float, float],
    area: float,
    *,
    free: PositionDensity | None = None,
    resolution: float = 0.0,
) -> LifecycleData:
    """A synthetic field log of one window, drawn by :func:`~are_stats.traffic.sample_population`.

    Parameters
    ----------
    rng, draw, laws, area, free
        As :func:`~are_stats.traffic.sample_population`.
    window : (t0, t1)
        The log's window; the population starts stationary at ``t0``.
    resolution : float
        Times are rounded up to multiples of it (a tracker's frame period); 0: exact.

    Returns
    -------
    LifecycleData
        Left-truncated rows (present at ``t0``) first; ``group`` always; ``x``, ``y`` with
        positions.
    """
    t0, t1 = float(window[0]), float(window[1])
    pop = sample_population(rng, draw, laws, t1 - t0, area, free=free)
    ta = pop["t_arrive"] + t0
    tl = pop["t_leave"] + t0
    if resolution > 0:
        ta = t0 + np.ceil((ta - t0) / resolution - 1e-9) * resolution
        tl = t0 + np.ceil((tl - t0) / resolution - 1e-9) * resolution
        tl = np.maximum(tl, ta)
    ta = np.where(pop["truncated"], np.nan, np.minimum(ta, t1))
    tl = np.where(tl >= t1, np.nan, tl)
    kept = ~(np.isfinite(ta) & (ta >= t1))
    return LifecycleData(
        t_arrive=ta[kept],
        t_leave=tl[kept],
        window=(t0, t1),
        area=float(area),
        group=pop["group"][kept],
        x=pop["x"][kept] if "x" in pop else None,
        y=pop["y"][kept] if "y" in pop else None,
    )


# --------------------------------------------------------------------------------------
# the numpyro model
# --------------------------------------------------------------------------------------


def check_components(n_components: int | None, data: LifecycleData | None) -> int | None:
    """The number of mixture components (classes) of the model for ``data``.

    ``None`` with a log that has labels gives their number; ``None`` without marks gives
    ``None`` (no mark model). Raises ``ValueError`` for a log with marks and no number, or
    for a number that is not an integer >= 1.
    """
    if n_components is None:
        if data is not None and data.labels is not None:
            return int(data.labels.max()) + 1 if data.n else 1
        if data is not None and data.marks is not None:
            raise ValueError(
                "n_components: expected the number of mixture components (classes) for a "
                "log with marks, got None"
            )
        return None
    k = int(check_nonneg_int("n_components", n_components, ndim=0))
    if k < 1:
        raise ValueError(f"n_components: expected an integer >= 1, got {n_components!r}")
    if data is not None and data.labels is not None and data.n and data.labels.max() >= k:
        i = int(np.argmax(data.labels >= k))
        raise ValueError(
            f"labels: expected classes below n_components={k}, got {data.labels[i]} at row {i}"
        )
    return k


def lifecycle_model(
    data: LifecycleData | None = None,
    *,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    n_components: int | None = None,
    window: tuple[float, float] | None = None,
    area: float | None = None,
    stationary_start: bool = True,
    labelled: bool | None = None,
) -> None:
    """numpyro model of one observed window of the life-cycle (eq. 1 and Sec. 3.2).

    Latent sites (the names are part of the API: fits are stored under them):
    ``arrival_rate`` ~ Gamma, ``leave_rate`` ~ Gamma and, with marks, ``mix_weights`` ~
    Dirichlet and ``mix_rates`` (ordered Gamma without labels, i.i.d. Gamma with labels),
    see :class:`LifecyclePriors`.

    Likelihood of a log (vectorised, no per-event sites):

    * ``n_arrivals`` ~ Poisson(lambda * area * (t1 - t0)), the count of arrivals inside the
      window. Given the count, exact arrival times are uniform, a factor free of lambda.
    * ``n_present`` ~ Poisson(lambda * area / mu), the count present at ``t0`` (stationary
      law of the immigration-death process, DECISIONS 1), only with ``stationary_start``.
      It carries information on the ratio lambda/mu and couples the two rates.
    * ``stays``: per artefact, ``log mu - mu * dwell`` for an observed departure and the
      log-survival ``- mu * dwell`` for a censored one; left-truncated artefacts count from
      ``t0`` (memorylessness).
    * ``mark_histogram``: the mixture log-likelihood of each *distinct* mark times its count; with
      labels, the complete-data likelihood ``log pi_c + log Poisson(x | lambda_c)`` of each
      distinct (class, mark) pair times its count (DECISIONS 5).

    With ``data=None`` the model draws the parameters and the counts ``n_arrivals`` (and
    ``n_present``) for ``window`` and ``area``: prior- or posterior-predictive draws with
    :class:`numpyro.infer.Predictive`. Full synthetic logs come from
    :func:`simulate_lifecycle`.

    Parameters
    ----------
    data : LifecycleData, optional
        The observed log; ``None`` for predictive draws.
    priors : LifecyclePriors
        The priors.
    n_components : int, optional
        Number of mixture components (classes). Required when ``data`` has marks without
        labels; inferred from the labels otherwise. ``None`` with ``data=None`` leaves the
        mixture out.
    window : (2,) float, optional
        ``(t0, t1)`` for ``data=None``; taken from ``data`` otherwise.
    area : float, optional
        Free area in m^2 for ``data=None``; taken from ``data`` otherwise.
    stationary_start : bool
        Include the ``n_present`` term.
    labelled : bool, optional
        Use the prior of a labelled log (independent ``mix_rates``) rather than the ordered
        one. Defaults to whether ``data`` has labels (``False`` for ``data=None``).

    Raises
    ------
    ValueError
        If ``data=None`` without ``window`` and ``area``, or ``n_components`` is missing or
        inconsistent with the labels.
    """
    if isinstance(data, LifecycleSummary):  # internal: pre-summarised (possibly traced) log
        k, s = n_components, data
        duration, area = s.duration, s.area
    elif data is not None:
        k, s = check_components(n_components, data), data.summary
        duration, area = s.duration, s.area
        if labelled is None:
            labelled = data.labels is not None
    else:
        k, s = check_components(n_components, None), None
        if window is None or area is None:
            raise ValueError("window, area: expected both when data is None, got None")
        t0, t1 = _check_window(window)
        area = float(check_positive("area", area, ndim=0))
        duration = t1 - t0

    lam = numpyro.sample("arrival_rate", dist.Gamma(priors.arrival_shape, priors.arrival_rate))
    mu = numpyro.sample("leave_rate", dist.Gamma(priors.leave_shape, priors.leave_rate))
    numpyro.sample(
        "n_arrivals",
        dist.Poisson(lam * (area * duration)),
        obs=None if s is None else jnp.asarray(s.n_arrivals, dtype=jnp.float64),
    )
    if stationary_start:
        numpyro.sample(
            "n_present",
            dist.Poisson(lam * area / mu),
            obs=None if s is None else jnp.asarray(s.n_present, dtype=jnp.float64),
        )
    if s is not None and s.dwell.size:
        dwell = jnp.asarray(s.dwell)
        departed = jnp.asarray(s.departed)
        numpyro.factor("stays", jnp.where(departed, jnp.log(mu), 0.0) - mu * dwell)

    if k is None:
        return
    labelled = bool(labelled)
    if k == 1:
        weights = numpyro.deterministic("mix_weights", jnp.ones(1))
    else:
        weights = numpyro.sample(
            "mix_weights", dist.Dirichlet(jnp.full(k, priors.weights_concentration))
        )
    if labelled:
        rates = numpyro.sample(
            "mix_rates",
            dist.Gamma(priors.mix_rate_shape, priors.mix_rate_rate).expand([k]).to_event(1),
        )
    else:
        rates = numpyro.sample(
            "mix_rates", _OrderedGamma(priors.mix_rate_shape, priors.mix_rate_rate, k)
        )
    if s is None or not s.mark_values.size:
        return
    if labelled:
        lab = jnp.asarray(s.pair_labels)
        x = jnp.asarray(s.pair_marks, dtype=jnp.float64)
        logp = jnp.log(weights[lab]) + dist.Poisson(rates[lab]).log_prob(x)
        numpyro.factor("mark_histogram", jnp.asarray(s.pair_counts) * logp)
    else:
        x = jnp.asarray(s.mark_values, dtype=jnp.float64)
        logp = _mark_distribution(weights, rates).log_prob(x)
        numpyro.factor("mark_histogram", jnp.asarray(s.mark_counts) * logp)


def prior_predictive(
    key: jax.Array,
    priors: LifecyclePriors = LifecyclePriors(),  # noqa: B008 (frozen, immutable)
    window: tuple[float, float] = (0.0, 1.0),
    area: float = 1.0,
    n_draws: int = 1000,
    *,
    n_components: int | None = None,
    stationary_start: bool = True,
    labelled: bool = False,
) -> dict[str, np.ndarray]:
    """Prior-predictive draws of :func:`lifecycle_model` for one window.

    Parameters
    ----------
    key : jax PRNG key
        Randomness.
    priors : LifecyclePriors
        The priors.
    window : (2,) float
        Observation window ``(t0, t1)``.
    area : float
        Free area in m^2.
    n_draws : int
        Number of draws, >= 1.
    n_components : int, optional
        Also draw ``mix_weights`` and ``mix_rates`` with this many components.
    stationary_start : bool
        Also draw ``n_present``, the count present at ``t0``.
    labelled : bool
        Draw ``mix_rates`` from the prior used for labelled logs (independent, not ordered).

    Returns
    -------
    dict of str to ndarray
        ``arrival_rate``, ``leave_rate`` : (n_draws,); ``n_arrivals`` (and ``n_present``) :
        (n_draws,) int; with ``n_components``: ``mix_weights``, ``mix_rates`` :
        (n_draws, n_components). Marginally ``n_arrivals`` is negative binomial.

    Raises
    ------
    ValueError
        Naming the argument when it is invalid.
    """
    n = int(check_nonneg_int("n_draws", n_draws, ndim=0))
    if n < 1:
        raise ValueError(f"n_draws: expected an integer >= 1, got {n_draws!r}")
    if not isinstance(priors, LifecyclePriors):
        raise ValueError(f"priors: expected a LifecyclePriors, got {type(priors).__name__}")
    t0, t1 = _check_window(window)
    area = float(check_positive("area", area, ndim=0))
    k = check_components(n_components, None)
    check_in("stationary_start", stationary_start, (True, False))
    check_in("labelled", labelled, (True, False))
    # the priors are Gamma, Dirichlet and Poisson laws: NumPy draws them in microseconds,
    # where a compiled numpyro Predictive cost seconds of compilation in every new process
    # (its program depends on the window and the area, so no cache is shared across logs)
    rng = numpy_rng(key)
    lam = rng.gamma(priors.arrival_shape, 1.0 / priors.arrival_rate, n)
    mu = rng.gamma(priors.leave_shape, 1.0 / priors.leave_rate, n)
    out = {"arrival_rate": lam, "leave_rate": mu}
    out["n_arrivals"] = rng.poisson(lam * (area * (t1 - t0))).astype(np.int64)
    if stationary_start:
        out["n_present"] = rng.poisson(lam * area / mu).astype(np.int64)
    if k is not None:
        if k == 1:
            out["mix_weights"] = np.ones((n, 1))
        else:
            out["mix_weights"] = rng.dirichlet(np.full(k, priors.weights_concentration), n)
        rates = rng.gamma(priors.mix_rate_shape, 1.0 / priors.mix_rate_rate, (n, k))
        out["mix_rates"] = rates if labelled else np.sort(rates, axis=1)  # order statistics
    return out
