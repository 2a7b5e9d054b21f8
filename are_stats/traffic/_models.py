"""The traffic models beside the paper's, as numpyro models on data-scaled parameters.

Two factors of the life-cycle likelihood are modelled separately (they share no
parameter once the stationary count at ``t0`` is left out):

**Arrivals** (:func:`arrival_model`). The log's arrival times are quantised by its time
resolution ``delta`` (a tracker's frame period; the smallest gap between recorded times).
The observation is the number of artefacts ``c_j`` arriving in each tick ``j`` of width
``delta``; members of a recorded group are put at the group's first arrival. Events
arrive at intensity ``rho(t) = r * area * tod[period(t)] (* f_b)`` and each event brings a
group of ``S`` artefacts (``S = 1`` without groups):

* ``poisson``: ``c_j ~ Poisson(rho_j delta)`` (the paper's homogeneous process);
* ``negbin``: a ``Gamma(phi, phi)`` frailty ``f_b`` per bin of width ``w``: the bin total
  is negative binomial, its allocation to ticks multinomial;
* ``time-of-day``: ``tod`` piecewise constant over ``P`` periods of the day (mean 1);
* ``groups``: ``c_j`` compound Poisson, ``P(c) = e^{-rho delta} sum_k (rho delta)^k / k!
  p^{*k}(c)`` with ``p`` the group-size law on ``1..K`` (a Dirichlet prior);
* ``groups+time-of-day``, ``negbin+time-of-day``: the combinations;
* ``mmpp``: a two-state Markov-modulated Poisson process (rates ``rho f_0 < rho f_1``,
  ``pi . f = 1``, switching rates ``q01``, ``q10``), and ``groups+mmpp`` (each event
  brings a group): bursts of a few minutes within the window;
* ``hawkes``: a self-exciting process with an exponential kernel (baseline
  ``rho (1 - alpha)``, branching ratio ``alpha``, decay ``beta``), and ``groups+hawkes``
  (the events are groups: a burst of groups);
* ``mmpp+time-of-day``, ``hawkes+time-of-day`` and their ``groups+`` variants: the
  time-of-day profile multiplies the MMPP's intensities (``rho tod f_k``) or the Hawkes
  baseline (``rho (1 - alpha) tod``); the boundaries of the periods are steps of the
  forward recursion, so the likelihood is exact for piecewise-constant rates.

The MMPP and Hawkes likelihoods are forward recursions over the ticks in time order
(:mod:`are_stats.traffic._bursts`); their pointwise terms are the one-step-ahead
``log p(bin_b | bins < b)``, since their bins are not exchangeable.

All of them are probabilities of the same quantised data, so their pointwise
log-likelihoods (one per time bin, :func:`arrival_unit_loglik`) can be compared by
PSIS-LOO. Without groups and time of day the Poisson tick likelihood is the paper's
``n log(lambda area) - lambda area T`` up to a constant that every model shares.

**Stays** (:func:`stay_model`): the four laws of :mod:`are_stats.traffic._stays` through the
observation window (censoring, truncation by the equilibrium residual law, zero stays
interval-censored at the resolution), one pointwise term per artefact.

**Scale.** Every positive parameter is ``empirical value * exp(z)`` with ``z ~ Normal(0,
3)`` (a factor of 20 either way at one standard deviation): the posterior is found from
``z = 0`` whether the log is in seconds or in days, and the prior is nearly flat on the
log scale. Shapes are ``exp(eta)``, ``eta ~ Normal(0, 1.5)`` (``eta = 0``: the exponential
for the gamma and Weibull laws); the negative-binomial concentration is
``LogNormal(log 5, 2)``; time-of-day factors are ``P * softmax(eta)`` with
``eta ~ Normal(0, 1)``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import numpyro
import numpyro.distributions as dist
from jax.scipy.special import gammaln, logsumexp
from jax.typing import ArrayLike
from scipy.special import gammaln as _np_gammaln

from are_stats._checks import check_in
from are_stats.traffic._arrivals import DAY, period_exposure, period_of
from are_stats.traffic._bursts import (
    BurstSteps,
    burst_steps,
    hawkes_step_loglik,
    mmpp_factors,
    mmpp_step_loglik,
)
from are_stats.traffic._stays import (
    STAY_LAWS,
    gamma_window_terms,
    has_resolution,
    stay_log_excess,
    stay_logcdf,
    stay_logpdf,
    stay_logsf,
)

_TINY = float(np.finfo(np.float64).tiny)

__all__ = [
    "ARRIVAL_SPECS",
    "ArrivalSpec",
    "ArrivalUnits",
    "StayUnits",
    "arrival_model",
    "arrival_unit_loglik",
    "arrival_units",
    "exponential_unit_loglik",
    "poisson_unit_loglik",
    "stay_model",
    "stay_unit_loglik",
    "stay_units",
]


class ArrivalSpec(NamedTuple):
    """Which factors an arrival model has (see the module docstring)."""

    negbin: bool = False
    tod: bool = False
    groups: bool = False
    mmpp: bool = False
    hawkes: bool = False

    @property
    def name(self) -> str:
        """``poisson``, ``negbin``, ``time-of-day``, ``groups``, ``mmpp``, ``hawkes`` or a
        ``+`` combination."""
        parts = [
            n
            for n, on in (
                ("groups", self.groups),
                ("negbin", self.negbin),
                ("mmpp", self.mmpp),
                ("hawkes", self.hawkes),
            )
            if on
        ]
        if self.tod:
            parts.append("time-of-day")
        return "+".join(parts) or "poisson"

    @property
    def bursts(self) -> bool:
        """An MMPP or Hawkes process (a forward recursion over the ticks in time order)."""
        return self.mmpp or self.hawkes

    @property
    def n_params(self) -> int:
        """A complexity order (fewer first) used to break ties towards simpler models.

        The bursty models come after the time of day: a latent rate that wanders can mimic
        a daily profile over days (a Hawkes process with a decay of hours), and where a
        fixed profile does as well it is the simpler account.
        """
        return (
            1
            + int(self.negbin)
            + 23 * int(self.tod)
            + 4 * int(self.groups)
            + 31 * int(self.mmpp)
            + 30 * int(self.hawkes)
        )

    @classmethod
    def from_name(cls, name: str) -> ArrivalSpec:
        """The spec of a model name (inverse of :attr:`name`)."""
        check_in("arrivals", name, ARRIVAL_SPECS)
        parts = set(name.split("+"))
        return cls(
            "negbin" in parts,
            "time-of-day" in parts,
            "groups" in parts,
            "mmpp" in parts,
            "hawkes" in parts,
        )


#: Arrival models the fit can choose from, simplest first.
ARRIVAL_SPECS = (
    "poisson",
    "negbin",
    "groups",
    "time-of-day",
    "negbin+time-of-day",
    "groups+time-of-day",
    "mmpp",
    "hawkes",
    "groups+mmpp",
    "groups+hawkes",
    "mmpp+time-of-day",
    "hawkes+time-of-day",
    "groups+mmpp+time-of-day",
    "groups+hawkes+time-of-day",
)


class ArrivalUnits(NamedTuple):
    """Quantised arrivals of a window, as the arrival models score them (a pytree).

    Attributes
    ----------
    tick_count : (m,) float
        Artefacts arriving in each non-empty tick (zero on padding).
    tick_bin : (m,) int
        Bin of each tick.
    tick_period : (m,) int
        Period of the day of each tick (0 without a clock).
    tick_weight : (m,) float
        1 for real ticks, 0 for padding.
    bin_exposure : (B, P) float
        ``area x time`` each bin spends in each period of the day.
    bin_count : (B,) float
        Artefacts arriving in each bin.
    bin_weight : (B,) float
        1 for real bins, 0 for padding.
    log_delta : () float array
        ``log`` of the tick width (the log's time resolution): an array, so an argument
        of the compiled programs, not a constant of them (logs whose measured
        resolutions differ in the last digits share their programs).
    steps : BurstSteps, optional
        The ticks and the ends of the bins in time order (the MMPP and Hawkes models).
    """

    tick_count: npt.ArrayLike
    tick_bin: npt.ArrayLike
    tick_period: npt.ArrayLike
    tick_weight: npt.ArrayLike
    bin_exposure: npt.ArrayLike
    bin_count: npt.ArrayLike
    bin_weight: npt.ArrayLike
    log_delta: npt.ArrayLike
    steps: BurstSteps | None = None


def _bucket(n: int, least: int = 16) -> int:
    """Padded size: the next power of two (so logs of similar size share compiled programs)."""
    return max(least, 1 << int(np.ceil(np.log2(max(n, 1)))))


def arrival_units(
    t_arrive: npt.ArrayLike,
    window: tuple[float, float],
    area: float,
    resolution: float,
    bin_width: float,
    *,
    group: npt.ArrayLike | None = None,
    clock_offset: float | None = None,
    n_periods: int = 24,
    period: float = DAY,
) -> ArrivalUnits:
    """Quantise the arrivals of a window into ticks and bins (see :class:`ArrivalUnits`).

    Parameters
    ----------
    t_arrive : (n,) float
        Arrival times inside the window (NaN entries, left-truncated artefacts, are left out).
    window : (t0, t1)
    area : float
        Free area (m^2).
    resolution : float
        Tick width ``delta`` (the log's time resolution).
    bin_width : float
        Width of the pointwise units (and of the negative-binomial frailty bins).
    group : (n,) int, optional
        Recorded groups: members are put at their group's first arrival.
    clock_offset : float, optional
        Time of day of ``t = 0``; None: no time-of-day periods (``P = 1``).
    n_periods, period : int, float
        Periods per day and the day's length in the log's time unit.

    Returns
    -------
    ArrivalUnits
        Padded to power-of-two sizes.
    """
    t0, t1 = float(window[0]), float(window[1])
    t = np.asarray(t_arrive, float)
    keep = np.isfinite(t)
    if group is not None:
        g = np.asarray(group)[keep]
        tk = t[keep]
        first = {}
        for gi, ti in zip(g.tolist(), tk.tolist(), strict=True):
            first[gi] = min(first.get(gi, ti), ti)
        tk = np.array([first[gi] for gi in g.tolist()], float)
    else:
        tk = t[keep]
    delta = float(resolution)
    tick = np.floor((tk - t0) / delta + 1e-9).astype(np.int64)
    ticks, counts = np.unique(tick, return_counts=True)
    mid = t0 + (ticks + 0.5) * delta
    n_bins = max(1, int(np.ceil((t1 - t0) / bin_width - 1e-9)))
    tbin = np.minimum(np.floor((mid - t0) / bin_width).astype(np.int64), n_bins - 1)
    if clock_offset is None:
        periods = np.zeros(ticks.size, np.int64)
        p = 1
    else:
        periods = period_of(mid, clock_offset, n_periods, period)
        p = n_periods
    edges = np.minimum(t0 + bin_width * np.arange(n_bins + 1), t1)
    expo = np.zeros((n_bins, p))
    for b in range(n_bins):
        if clock_offset is None:
            expo[b, 0] = edges[b + 1] - edges[b]
        else:
            expo[b] = period_exposure((edges[b], edges[b + 1]), clock_offset, n_periods, period)
    expo *= float(area)
    bin_count = np.bincount(tbin, weights=counts, minlength=n_bins)
    m, bb = _bucket(ticks.size), _bucket(n_bins)
    clock = None if clock_offset is None else (float(clock_offset), int(n_periods), float(period))
    steps = burst_steps(ticks, counts, tbin, (t0, t1), delta, bin_width, m + bb, clock)

    def pad(a: np.ndarray, size: int, dtype: npt.DTypeLike) -> np.ndarray:
        out = np.zeros((size,) + a.shape[1:], dtype)
        out[: a.shape[0]] = a
        return out

    return ArrivalUnits(
        tick_count=pad(counts.astype(float), m, float),
        tick_bin=pad(tbin, m, np.int64),
        tick_period=pad(periods, m, np.int64),
        tick_weight=pad(np.ones(ticks.size), m, float),
        bin_exposure=pad(expo, bb, float),
        bin_count=pad(bin_count, bb, float),
        bin_weight=pad(np.ones(n_bins), bb, float),
        log_delta=np.asarray(np.log(delta), float),
        steps=steps,
    )


def _log_convolution_powers(log_p: jnp.ndarray, c_max: int) -> jnp.ndarray:
    """``log p^{*k}(c)`` for ``k = 1..c_max`` (rows) and ``c = 0..c_max`` (columns).

    Each power is the previous one times the lower-triangular Toeplitz matrix of ``p``
    (``T[c, j] = p[c - j]``, the convolution truncated at ``c_max``): a matrix product,
    not ``jnp.convolve``, whose batched form (``vmap`` over draws or chains) XLA's CPU
    backend runs as a grouped convolution 15-100 times slower.
    """
    p = jnp.exp(log_p)
    lag = jnp.arange(c_max + 1)[:, None] - jnp.arange(c_max + 1)[None, :]
    toeplitz = jnp.where(lag >= 0, p[jnp.clip(lag, 0, c_max)], 0.0)

    def body(prev, _):
        nxt = toeplitz @ prev
        return nxt, nxt

    _, rows = jax.lax.scan(body, jnp.zeros(c_max + 1).at[0].set(1.0), None, length=c_max)
    return jnp.log(jnp.maximum(rows, 1e-300))


def arrival_unit_loglik(params: dict, units: ArrivalUnits, spec: ArrivalSpec) -> jnp.ndarray:
    """Log-likelihood of each bin of quantised arrivals (the pointwise units of LOO).

    Parameters
    ----------
    params : dict
        ``event_rate`` (events per m^2 per time), ``log_area`` (log of the free area), and
        as the spec needs ``arrival_phi``, ``arrival_tod`` (P,), ``group_size_probs`` (K,)
        (sizes ``1..K``; ``K`` must be at least the largest count of a tick, the
        ``max_group`` of :func:`arrival_model`).
    units : ArrivalUnits
    spec : ArrivalSpec

    Returns
    -------
    (B,) float
        Zero on padded bins.
    """
    rate = params["event_rate"]
    n_bins = units.bin_weight.shape[0]
    if spec.bursts:
        return _burst_unit_loglik(params, units, spec)
    tod = params["arrival_tod"] if spec.tod else jnp.ones(units.bin_exposure.shape[1])
    log_tod_tick = jnp.log(tod)[units.tick_period]
    log_rho_delta = jnp.log(rate) + log_tod_tick + units.log_delta  # log(rho delta / area)
    mu_bin = rate * (units.bin_exposure @ tod)  # expected events per bin
    c = units.tick_count
    if spec.groups:
        probs = params["group_size_probs"]
        c_max = probs.shape[0]
        log_p = jnp.concatenate([jnp.array([-jnp.inf]), jnp.log(probs)])
        conv = _log_convolution_powers(log_p, c_max)  # (c_max, c_max + 1)
        k = jnp.arange(1, c_max + 1)
        ci = jnp.clip(c.astype(jnp.int32), 0, c_max)
        lam = log_rho_delta + params["log_area"]
        terms = k[None, :] * lam[:, None] - gammaln(k + 1.0)[None, :] + conv[:, ci].T
        tick_ll = logsumexp(terms, axis=1)
    else:
        lam = log_rho_delta + params["log_area"]
        tick_ll = c * lam - gammaln(c + 1.0)
    tick_ll = jnp.where(units.tick_weight > 0, tick_ll, 0.0)
    per_bin = jax.ops.segment_sum(tick_ll, units.tick_bin, num_segments=n_bins)
    if spec.negbin:
        phi = params["arrival_phi"]
        n = units.bin_count
        mu = jnp.maximum(mu_bin, 1e-300)
        nb = (
            gammaln(n + phi)
            - gammaln(phi)
            - gammaln(n + 1.0)
            + phi * jnp.log(phi / (phi + mu))
            + n * jnp.log(mu / (phi + mu))
        )
        # Poisson ticks given the total are multinomial: replace Poisson(total) by NB(total)
        pois = n * jnp.log(mu) - mu - gammaln(n + 1.0)
        out = per_bin + nb - pois - mu_bin
    else:
        out = per_bin - mu_bin
    return jnp.where(units.bin_weight > 0, out, 0.0)


def poisson_unit_loglik(rate: npt.ArrayLike, units: ArrivalUnits, log_area: float) -> np.ndarray:
    """:func:`arrival_unit_loglik` of the ``poisson`` spec for many draws, in NumPy.

    The paper's arrival model has a closed form per bin (ticks' Poisson terms minus the
    bin's expected count), so the draws of its exact posterior are scored without a
    compiled program (a fresh process would compile one for this alone).

    Parameters
    ----------
    rate : (S,) float
        ``event_rate`` of each draw (events per m^2 per time).
    units : ArrivalUnits
        Without a clock (one period of the day).
    log_area : float
        ``log`` of the free area.

    Returns
    -------
    (S, B) float
        Zero on padded bins.
    """
    rate = np.asarray(rate, float).reshape(-1)
    c = np.asarray(units.tick_count, float)
    real_tick = np.asarray(units.tick_weight) > 0
    n_bins = np.asarray(units.bin_weight).shape[0]
    bins = np.asarray(units.tick_bin)[real_tick]
    # sum over a bin's ticks of c (log rate + log delta + log area) - log c!
    per_bin_c = np.bincount(bins, c[real_tick], n_bins)
    per_bin_g = np.bincount(bins, _np_gammaln(c[real_tick] + 1.0), n_bins)
    lam0 = float(np.asarray(units.log_delta)) + float(log_area)
    exposure = np.asarray(units.bin_exposure, float).sum(axis=1)  # tod = 1 in every period
    with np.errstate(divide="ignore"):
        log_rate = np.log(rate)
    out = (
        per_bin_c[None, :] * (log_rate[:, None] + lam0)
        - per_bin_g[None, :]
        - rate[:, None] * exposure[None, :]
    )
    return np.where(np.asarray(units.bin_weight)[None, :] > 0, out, 0.0)


def _burst_unit_loglik(params: dict, units: ArrivalUnits, spec: ArrivalSpec) -> jnp.ndarray:
    """``(B,)`` one-step-ahead log-likelihood of each bin under an MMPP or Hawkes spec."""
    if units.steps is None:
        raise ValueError(f"units: expected the burst steps for {spec.name}, got None")
    n_bins = units.bin_weight.shape[0]
    total = params["event_rate"] * jnp.exp(params["log_area"])  # events per time, whole area
    conv = None
    if spec.groups:
        probs = params["group_size_probs"]
        log_p = jnp.concatenate([jnp.array([-jnp.inf]), jnp.log(probs)])
        conv = _log_convolution_powers(log_p, probs.shape[0])
    tod = params["arrival_tod"] if spec.tod else None
    if spec.mmpp:
        switch = params["mmpp_switch"]
        lam = total * mmpp_factors(params["mmpp_contrast"], switch)
        out = mmpp_step_loglik(lam, switch, units.log_delta, units.steps, n_bins, conv, tod)
    else:
        alpha = params["hawkes_branching"]
        mu = total * (1.0 - alpha)
        out = hawkes_step_loglik(
            mu,
            alpha,
            params["hawkes_decay"],
            units.log_delta,
            units.steps,
            n_bins,
            conv=conv,
            tod=tod,
        )
    return jnp.where(units.bin_weight > 0, out, 0.0)


def _positive(name: str, centre: float, sd: float = 3.0) -> jnp.ndarray:
    z = numpyro.sample(f"{name}_z", dist.Normal(0.0, sd))
    return numpyro.deterministic(name, centre * jnp.exp(z))


def arrival_model(
    units: ArrivalUnits,
    spec: ArrivalSpec,
    rate_centre: float,
    log_area: float,
    max_group: int = 1,
    time_centre: float = 1.0,
) -> None:
    """numpyro model of quantised arrivals under ``spec`` (see the module docstring).

    Latent sites: ``event_rate_z`` (deterministic ``event_rate``), and as the spec needs
    ``arrival_phi``, ``tod_eta`` (deterministic ``arrival_tod``), ``group_size_probs``,
    ``mmpp_contrast`` (``HalfNormal(2)``: ``log(f_1 / f_0)``) and ``mmpp_switch_z``
    (deterministic ``mmpp_switch``, ``(q01, q10)``, and ``mmpp_factor``, ``f``),
    ``hawkes_branching`` (``Beta(1, 2)``) and ``hawkes_decay_z`` (deterministic
    ``hawkes_decay``).
    The likelihood is one factor, ``arrival_units``, the sum of
    :func:`arrival_unit_loglik`.

    Parameters
    ----------
    units : ArrivalUnits
    spec : ArrivalSpec
    rate_centre : float
        Empirical event rate per m^2 per time (the centre of the rate's prior).
    log_area : float
        ``log`` of the free area.
    max_group : int
        Largest group size ``K`` (``groups`` only).
    time_centre : float
        A time scale of the bursts (the LOO bin width): the centre of the priors of the
        switching rates and the Hawkes decay, ``exp(Normal(0, 1.5)) / time_centre``.
    """
    params: dict[str, ArrayLike] = {"log_area": log_area}
    params["event_rate"] = _positive("event_rate", rate_centre)
    if spec.negbin:
        params["arrival_phi"] = numpyro.sample("arrival_phi", dist.LogNormal(np.log(5.0), 2.0))
    if spec.tod:
        p = units.bin_exposure.shape[1]
        eta = numpyro.sample("tod_eta", dist.Normal(0.0, 1.0).expand([p]).to_event(1))
        params["arrival_tod"] = numpyro.deterministic("arrival_tod", p * jax.nn.softmax(eta))
    if spec.groups:
        params["group_size_probs"] = numpyro.sample(
            "group_size_probs", dist.Dirichlet(jnp.ones(int(max_group)))
        )
    if spec.mmpp:
        params["mmpp_contrast"] = numpyro.sample("mmpp_contrast", dist.HalfNormal(2.0))
        z = numpyro.sample("mmpp_switch_z", dist.Normal(0.0, 1.5).expand([2]).to_event(1))
        params["mmpp_switch"] = numpyro.deterministic("mmpp_switch", jnp.exp(z) / time_centre)
        numpyro.deterministic(
            "mmpp_factor", mmpp_factors(params["mmpp_contrast"], params["mmpp_switch"])
        )
    if spec.hawkes:
        params["hawkes_branching"] = numpyro.sample("hawkes_branching", dist.Beta(1.0, 2.0))
        params["hawkes_decay"] = _positive("hawkes_decay", 1.0 / time_centre, 1.5)
    numpyro.factor("arrival_units", jnp.sum(arrival_unit_loglik(params, units, spec)))


class StayUnits(NamedTuple):
    """Stays seen through a window (a pytree; see :func:`~are_stats.traffic.stay_loglik`).

    The artefacts are split by the term they contribute, so that each law's costly
    functions (the incomplete gamma and its gradient in the shape) run only where they are
    needed: the density for stays seen from arrival to departure (most of a log), the
    survival for censored or truncated ones, the mean excess for those present the whole
    window.

    Attributes
    ----------
    stay : (n,) float
        Time seen inside the window (residual from ``t0`` when truncated).
    censored, truncated : (n,) bool
    weight : (n,) float
        1 for real artefacts, 0 for padding.
    idx_full, idx_surv, idx_excess : (k,) int
        Rows whose term is the density (or, below the resolution, the interval
        probability), the survival, or the mean excess; padded with ``n`` (a dummy row).
    """

    stay: npt.ArrayLike
    censored: npt.ArrayLike
    truncated: npt.ArrayLike
    weight: npt.ArrayLike
    idx_full: npt.ArrayLike
    idx_surv: npt.ArrayLike
    idx_excess: npt.ArrayLike


def _padded_index(idx: np.ndarray, dummy: int) -> np.ndarray:
    out = np.full(_bucket(idx.size, least=8), dummy, np.int64)
    out[: idx.size] = idx
    return out


def stay_units(stay: npt.ArrayLike, censored: npt.ArrayLike, truncated: npt.ArrayLike) -> StayUnits:
    """Pad the stays of a log to a power-of-two size (see :class:`StayUnits`)."""
    s = np.asarray(stay, float)
    n = s.size
    m = _bucket(n)
    out = np.ones(m)
    out[:n] = s
    cen = np.zeros(m, bool)
    cen[:n] = np.asarray(censored, bool)
    tru = np.zeros(m, bool)
    tru[:n] = np.asarray(truncated, bool)
    w = np.zeros(m)
    w[:n] = 1.0
    real = np.arange(m) < n
    full = np.flatnonzero(real & ~cen & ~tru)
    surv = np.flatnonzero(real & (cen ^ tru))
    excess = np.flatnonzero(real & cen & tru)
    return StayUnits(out, cen, tru, w, *(_padded_index(i, m) for i in (full, surv, excess)))


def stay_unit_loglik(
    params: dict, units: StayUnits, law: str, resolution: npt.ArrayLike = 0.0
) -> jnp.ndarray:
    """Pointwise log-likelihood of each artefact's stay under ``law`` (zero on padding).

    Equal to :func:`~are_stats.traffic.stay_loglik`, each term computed on its own rows.
    ``resolution`` (float or () array): stays shorter are interval-censored; an array is
    an argument of a compiled program, not a constant (see
    :func:`~are_stats.traffic._stays.has_resolution`).
    """
    mean = params["stay_mean"]
    shape = params.get("stay_shape", 1.0)
    m = units.stay.shape[0]
    stay = jnp.concatenate([jnp.asarray(units.stay, float), jnp.ones(1)])  # row m: dummy
    trunc = jnp.concatenate([jnp.asarray(units.truncated, bool), jnp.zeros(1, bool)])
    log_m = jnp.log(mean)
    floor = 1e-12 * mean  # survival terms at a zero stay: NaN gradients at exactly 0
    sa = stay[units.idx_full]
    ss = jnp.maximum(stay[units.idx_surv], floor)
    se = jnp.maximum(stay[units.idx_excess], floor)
    la = stay_logpdf(law, jnp.maximum(sa, _TINY), mean, shape)
    interval = has_resolution(resolution)
    if law == "gamma":  # its incomplete gammas in one loop (one for XLA to compile)
        ls, le, cdf = gamma_window_terms(ss, se, resolution, mean, shape)
    else:
        ls = stay_logsf(law, ss, mean, shape)
        le = stay_log_excess(law, se, mean, shape)
        cdf = stay_logcdf(law, resolution, mean, shape) if interval else None
    if interval:
        la = jnp.where(sa < resolution, cdf, la)
    ls = ls - jnp.where(trunc[units.idx_surv], log_m, 0.0)
    le = le - log_m
    out = (
        jnp.zeros(m + 1)
        .at[units.idx_full]
        .set(la)
        .at[units.idx_surv]
        .set(ls)
        .at[units.idx_excess]
        .set(le)
    )[:m]
    return jnp.where(jnp.asarray(units.weight) > 0, out, 0.0)


def exponential_unit_loglik(
    mean: npt.ArrayLike, units: StayUnits, resolution: float = 0.0
) -> np.ndarray:
    """:func:`stay_unit_loglik` of the ``exponential`` law for many draws, in NumPy.

    The paper's stay law in closed form (density ``e^{-s/m} / m``, below the resolution
    ``1 - e^{-r/m}``; survival ``e^{-s/m}``, over ``m`` when left-truncated; mean excess
    over ``m``: ``e^{-s/m}``), so the draws of its exact posterior are scored without a
    compiled program.

    Parameters
    ----------
    mean : (S,) float
        ``stay_mean`` of each draw.
    units : StayUnits
    resolution : float
        The log's time resolution (stays shorter are interval-censored).

    Returns
    -------
    (S, n) float
        Zero on padding.
    """
    m = np.asarray(mean, float).reshape(-1)[:, None]
    n = np.asarray(units.stay).shape[0]
    stay = np.concatenate([np.asarray(units.stay, float), np.ones(1)])  # row n: dummy
    trunc = np.concatenate([np.asarray(units.truncated, bool), np.zeros(1, bool)])
    log_m = np.log(m)
    floor = 1e-12 * m
    out = np.zeros((m.shape[0], n + 1))
    idx = np.asarray(units.idx_full)
    sa = stay[idx][None, :]
    la = -log_m - np.maximum(sa, _TINY) / m
    if resolution > 0:
        cdf = np.log(np.maximum(-np.expm1(-resolution / m), _TINY))
        la = np.where(sa < resolution, cdf, la)
    out[:, idx] = la
    idx = np.asarray(units.idx_surv)
    ls = -np.maximum(stay[idx][None, :], floor) / m
    out[:, idx] = ls - np.where(trunc[idx][None, :], log_m, 0.0)
    idx = np.asarray(units.idx_excess)
    out[:, idx] = -np.maximum(stay[idx][None, :], floor) / m
    return np.where(np.asarray(units.weight)[None, :] > 0, out[:, :n], 0.0)


def stay_model(
    units: StayUnits, law: str, mean_centre: float, resolution: npt.ArrayLike = 0.0
) -> None:
    """numpyro model of the stays under ``law`` (mean and shape parameterisation).

    Latent sites: ``stay_mean_z`` (deterministic ``stay_mean``) and, except for the
    exponential law, ``stay_shape_eta`` (deterministic ``stay_shape``).
    """
    check_in("law", law, STAY_LAWS)
    params = {"stay_mean": _positive("stay_mean", mean_centre)}
    if law != "exponential":
        eta = numpyro.sample("stay_shape_eta", dist.Normal(0.0, 1.5))
        params["stay_shape"] = numpyro.deterministic("stay_shape", jnp.exp(eta))
    numpyro.factor("stays", jnp.sum(stay_unit_loglik(params, units, law, resolution)))
