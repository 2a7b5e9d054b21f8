"""The one sampler of the life-cycle process, for every arrival, stay and position law.

:func:`sample_population` draws the artefacts of one window ``[0, horizon]`` from one
posterior draw: the population present at ``t = 0`` (stationary start) and the arrivals,
each with its group, stay and entry point. Scenario generation
(:func:`are_stats.scenarios.generate_scenarios`), the posterior-predictive checks and the
synthetic logs of the tests (:func:`are_stats.traffic.simulate_traffic_log`) all draw through it.

* **Arrivals**: :func:`~are_stats.traffic.sample_arrivals` (events at ``event_rate * area``,
  times of day, negative-binomial frailty, group sizes); the bursty models (``mmpp``,
  ``hawkes``, their ``groups+`` and ``+time-of-day`` variants) by
  :func:`~are_stats.traffic.sample_mmpp_times` and
  :func:`~are_stats.traffic.sample_hawkes_times` (the time of day by thinning), run from a
  burn-in before ``t = 0`` so that the window starts in the process's stationary regime.
* **Initial population** (``start="stationary"``): ``Poisson(event_rate * area * m)``
  groups (times the time-of-day factor at ``t = 0`` and, for the negative binomial, one
  frailty draw), each with the equilibrium residual stay of its law
  (:func:`~are_stats.traffic.stay_draws` with ``residual=True``). For the bursty models
  the number present at ``t = 0`` depends on the recent rate, so the initial population is
  the groups of the burn-in (``BURN_STAYS`` mean stays and ``BURN_SCALES`` of the process's
  time scale) still present at ``t = 0``, with their remaining stays.
* **Stays**: one stay per group from the stay law; members keep the group's stay times
  ``exp(s * e - s^2 / 2)`` with ``e`` standard normal and ``s = group_stay_sd`` (0: they
  leave together).
* **Positions**: a group's entry point from the entry density (uniform over free cells, or
  learned); members within ``group_spread`` metres of it (Gaussian, kept on free cells).
  The initial population stands anywhere (uniform over the free cells).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_in
from are_stats.traffic._arrivals import DAY, ArrivalDraw, period_of, sample_arrivals
from are_stats.traffic._bursts import sample_hawkes_times, sample_mmpp_times
from are_stats.traffic._models import ARRIVAL_SPECS, ArrivalSpec
from are_stats.traffic._positions import POSITION_MODELS, PositionDensity
from are_stats.traffic._stays import STAY_LAWS, stay_draws

__all__ = ["TrafficLaws", "sample_population"]

#: Burn-in of the bursty arrival models before ``t = 0``: mean stays ...
BURN_STAYS = 20.0
#: ... plus time scales of the process (``1 / (q01 + q10)``, ``1 / (beta (1 - alpha))``).
BURN_SCALES = 10.0


@dataclass(frozen=True)
class TrafficLaws:
    """Which laws a population is drawn from, and their fixed settings.

    Parameters
    ----------
    arrivals : str
        One of :data:`~are_stats.traffic.ARRIVAL_SPECS` (``"poisson"`` is the paper's).
    lifetimes : str
        One of :data:`~are_stats.traffic.STAY_LAWS`.
    positions : {"uniform", "learned"}
    bin_width : float, optional
        Frailty bins of the negative binomial.
    clock_offset : float, optional
        Time of day of ``t = 0`` (time-of-day models).
    period : float
        Length of a day in the time unit.
    group_stay_sd, group_spread : float
        Members' log-stay deviation and entry spread (m) around their group's.
    entry : PositionDensity, optional
        Entry density (``learned``; also the free cells for ``uniform``).
    class_entry : tuple of PositionDensity, optional
        Entry density of each class of a labelled log (issue 31): an arriving group of
        class ``c`` enters from ``class_entry[c]`` whatever ``positions`` says
        (:func:`are_stats.scenarios.generate_scenarios` places them once the classes are
        drawn).
    """

    arrivals: str = "poisson"
    lifetimes: str = "exponential"
    positions: str = "uniform"
    bin_width: float | None = None
    clock_offset: float | None = None
    period: float = DAY
    group_stay_sd: float = 0.0
    group_spread: float = 0.0
    entry: PositionDensity | None = None
    class_entry: tuple[PositionDensity, ...] | None = None

    def __post_init__(self) -> None:
        check_in("arrivals", self.arrivals, ARRIVAL_SPECS)
        check_in("lifetimes", self.lifetimes, STAY_LAWS)
        check_in("positions", self.positions, POSITION_MODELS)
        spec = self.spec
        if spec.negbin and not (self.bin_width and self.bin_width > 0):
            raise ValueError(f"bin_width: expected a width > 0 for {self.arrivals}, got None")
        if spec.tod and self.clock_offset is None:
            raise ValueError(f"clock_offset: expected the clock of {self.arrivals}, got None")
        if self.positions == "learned" and self.entry is None:
            raise ValueError("entry: expected a learned entry density, got None")

    @property
    def spec(self) -> ArrivalSpec:
        """The arrival factors."""
        return ArrivalSpec.from_name(self.arrivals)

    @property
    def is_paper(self) -> bool:
        """Poisson arrivals, exponential stays, uniform positions: the paper's model."""
        return (self.arrivals, self.lifetimes, self.positions) == (
            "poisson",
            "exponential",
            "uniform",
        )


def _one(
    draw: Mapping[str, npt.ArrayLike], name: str, default: float | None = None
) -> npt.NDArray[np.float64] | float:
    if name in draw:
        return np.asarray(draw[name], float)
    if default is None:
        raise ValueError(f"draw: expected {name!r}, got keys {sorted(draw)}")
    return default


def sample_population(
    rng: np.random.Generator,
    draw: Mapping[str, npt.ArrayLike],
    laws: TrafficLaws,
    horizon: float,
    area: float,
    *,
    start: str = "stationary",
    free: PositionDensity | None = None,
) -> dict[str, np.ndarray]:
    """Draw the artefacts of one window ``[0, horizon]`` (see the module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
    draw : mapping
        One posterior draw: ``event_rate`` (events per m^2 per time; the paper's
        ``arrival_rate``), ``stay_mean`` (the paper's ``1 / leave_rate``), and as the laws
        need ``arrival_phi``, ``arrival_tod`` (P,), ``group_size_probs`` (K,),
        ``stay_shape``, ``mmpp_factor`` (2,) and ``mmpp_switch`` (2,), ``hawkes_branching``
        and ``hawkes_decay``.
    laws : TrafficLaws
    horizon : float
    area : float
        Free area ``nu(M2D)`` (m^2).
    start : {"stationary", "empty"}
    free : PositionDensity, optional
        Uniform density over the free cells (positions are drawn only when given, or when
        the laws carry a learned entry density).

    Returns
    -------
    dict of str to ndarray
        ``t_arrive``, ``t_leave`` (n,) float (0 for the initial population, whose leaving
        time is its residual stay), ``truncated`` (n,) bool, ``group`` (n,) int64
        (``0..G-1``, initial groups first), and with positions ``x``, ``y`` (n,) float.
        Initial population first, then arrivals in time order.
    """
    check_in("start", start, ("stationary", "empty"))
    spec = laws.spec
    rate = float(_one(draw, "event_rate"))
    mean = float(_one(draw, "stay_mean"))
    shape = float(_one(draw, "stay_shape", 1.0)) if laws.lifetimes != "exponential" else 1.0
    phi = float(_one(draw, "arrival_phi")) if spec.negbin else None
    tod = _one(draw, "arrival_tod") if spec.tod else None
    probs = _one(draw, "group_size_probs") if spec.groups else None
    offset = 0.0 if laws.clock_offset is None else float(laws.clock_offset)
    if spec.bursts:
        size0, stay0, arr, stay_arr = _burst_groups(
            rng, draw, laws, float(horizon), area, rate, mean, shape, probs, start
        )
        n0_groups = size0.size
        return _finish(rng, laws, size0, stay0, arr, stay_arr, n0_groups, free)
    arr = sample_arrivals(
        rng,
        rate,
        area,
        (0.0, float(horizon)),
        phi=phi,
        bin_width=laws.bin_width if spec.negbin else None,
        tod=tod,
        offset=offset,
        period=laws.period,
        size_probs=None if probs is None else probs / probs.sum(),
    )
    # initial population: groups present at t = 0
    n0_groups = 0
    if start == "stationary":
        c = rate * area * mean
        if tod is not None:
            c *= float(tod[period_of(np.array([0.0]), offset, tod.size, laws.period)[0]])
        if phi is not None:
            c *= rng.gamma(phi, 1.0 / phi)
        n0_groups = int(rng.poisson(c))
    if probs is not None and n0_groups:
        p = probs / probs.sum()
        size0 = rng.choice(np.arange(1, p.size + 1), size=n0_groups, p=p).astype(np.int64)
    else:
        size0 = np.ones(n0_groups, np.int64)
    n_arr_groups = int(arr.group.max()) + 1 if arr.group.size else 0
    stay0 = stay_draws(rng, laws.lifetimes, mean, shape, (n0_groups,), residual=True)
    stay_arr = stay_draws(rng, laws.lifetimes, mean, shape, (n_arr_groups,))
    return _finish(rng, laws, size0, stay0, arr, stay_arr, n0_groups, free)


def _burst_groups(
    rng: np.random.Generator,
    draw: Mapping[str, npt.ArrayLike],
    laws: TrafficLaws,
    horizon: float,
    area: float,
    rate: float,
    mean: float,
    shape: float,
    probs: np.ndarray | None,
    start: str,
) -> tuple[np.ndarray, np.ndarray, ArrivalDraw, np.ndarray]:
    """Groups of a bursty model: sizes and remaining stays of those present at ``t = 0``,
    the arrivals of the window and their groups' stays (see the module docstring)."""
    spec = laws.spec
    total = rate * area
    if spec.mmpp:
        f = _one(draw, "mmpp_factor")
        q = _one(draw, "mmpp_switch")
        scale = 1.0 / float(q.sum())
    else:
        alpha = float(_one(draw, "hawkes_branching"))
        beta = float(_one(draw, "hawkes_decay"))
        scale = 1.0 / (beta * (1.0 - alpha))
    burn = BURN_SCALES * scale + (BURN_STAYS * mean if start == "stationary" else 0.0)
    window = (-burn, horizon)
    clock = {}
    if spec.tod:
        offset = 0.0 if laws.clock_offset is None else float(laws.clock_offset)
        clock = {"tod": _one(draw, "arrival_tod"), "offset": offset, "period": laws.period}
    if spec.mmpp:
        t = sample_mmpp_times(rng, total * f, q, window, **clock)
    else:
        t = sample_hawkes_times(rng, total * (1.0 - alpha), alpha, beta, window, **clock)
    if probs is not None and t.size:
        p = probs / probs.sum()
        sizes = rng.choice(np.arange(1, p.size + 1), size=t.size, p=p).astype(np.int64)
    else:
        sizes = np.ones(t.size, np.int64)
    before = t < 0.0
    n_before = int(np.sum(before))
    if start == "stationary" and n_before:
        stays = stay_draws(rng, laws.lifetimes, mean, shape, (n_before,))
        left = t[before] + stays
        here = left > 0.0
        size0, stay0 = sizes[before][here], left[here]
    else:
        size0, stay0 = np.zeros(0, np.int64), np.zeros(0)
    ta, sa = t[~before], sizes[~before]
    n = ta.size
    group = np.repeat(np.arange(n, dtype=np.int64), sa)
    arr = ArrivalDraw(np.repeat(ta, sa), group, np.repeat(sa, sa))
    return size0, stay0, arr, stay_draws(rng, laws.lifetimes, mean, shape, (n,))


def _finish(
    rng: np.random.Generator,
    laws: TrafficLaws,
    size0: np.ndarray,
    stay0: np.ndarray,
    arr: ArrivalDraw,
    stay_arr: np.ndarray,
    n0_groups: int,
    free: PositionDensity | None,
) -> dict[str, np.ndarray]:
    """Artefacts of the groups present at ``t = 0`` and of the arrivals: stays, positions."""
    g_stay = np.concatenate([stay0, stay_arr])
    group = np.concatenate([np.repeat(np.arange(n0_groups), size0), n0_groups + arr.group])
    t_arr = np.concatenate([np.zeros(int(size0.sum())), arr.t])
    truncated = np.zeros(group.size, bool)
    truncated[: int(size0.sum())] = True
    stay = g_stay[group]
    sizes = np.bincount(group, minlength=g_stay.size)[group] if group.size else group
    if laws.group_stay_sd > 0 and group.size:
        s = float(laws.group_stay_sd)
        jitter = np.exp(s * rng.standard_normal(group.size) - 0.5 * s * s)
        stay = np.where(sizes > 1, stay * jitter, stay)
    out = {
        "t_arrive": t_arr,
        "t_leave": t_arr + stay,
        "truncated": truncated,
        "group": group.astype(np.int64),
    }
    entry = laws.entry if laws.positions == "learned" else free
    if entry is not None:
        base = free if free is not None else entry
        n_groups = g_stay.size
        g_xy = np.empty((n_groups, 2))
        g_xy[:n0_groups] = base.sample(rng, n0_groups)
        g_xy[n0_groups:] = entry.sample(rng, n_groups - n0_groups)
        xy = g_xy[group]
        if laws.group_spread > 0 and group.size:
            moved = xy + rng.normal(0.0, laws.group_spread, xy.shape)
            row, _ = base.cell_of(moved)
            ok = row >= 0
            r, c = base.cell_of(moved[ok])
            good = np.zeros(xy.shape[0], bool)
            good[np.flatnonzero(ok)] = base.prob[r, c] > 0
            xy = np.where(((sizes > 1) & good)[:, None], moved, xy)
        out["x"], out["y"] = xy[:, 0], xy[:, 1]
    return out
