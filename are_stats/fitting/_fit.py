"""The typed fit: what a fit file holds, decoded once where it enters.

A fit is written as ArviZ NetCDF (:func:`~are_stats.fitting.write_fit`): a posterior, the
observed log, and attributes (the chosen traffic laws, the class labels, the area, the
provenance) plus an optional ``behaviour`` group. :func:`~are_stats.fitting.read_fit`
checks it and returns a :class:`Fit`: every consumer outside this room (the scenes
assembly, the sweeps, ``augment``, the CLI) reads these typed fields, never the NetCDF
attributes. The raw :attr:`Fit.idata` stays available to the fitting room itself (report,
PSIS-LOO, criticism), which works on the InferenceData.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt
import pandas as pd
import yaml

from are_stats import _lazy
from are_stats._checks import check_in
from are_stats.behaviour import BehaviourFit, SocialForce
from are_stats.fitting._class_traffic import class_position_densities
from are_stats.fitting._interaction import interaction_from_attrs, interaction_info
from are_stats.fitting._motion_store import motion_tables
from are_stats.inputs import Described, InputError
from are_stats.traffic import PositionDensity, TrafficLaws, clock_offset

# Lazy imports: _fit_log (it imports this module) in as_fit and Fit.from_draws; ArviZ
# (_lazy.arviz) when a fit is made from draws.

if TYPE_CHECKING:
    import arviz as az
    import xarray as xr

    from are_stats.environment import OccupancyGrid

__all__ = [
    "PARAMETER_NAMES",
    "TRAFFIC_NAMES",
    "ClassShares",
    "Fit",
    "PosteriorMeans",
    "as_fit",
    "fit_class_labels",
    "fit_from_idata",
    "posterior_draws",
    "traffic_draws",
]

#: Posterior variables of the paper's models (names of the fit's NetCDF variables).
PARAMETER_NAMES = ("arrival_rate", "leave_rate", "mix_weights", "mix_rates", "class_weights")

#: Variables of the chosen traffic models (beside :data:`PARAMETER_NAMES`).
TRAFFIC_NAMES = (
    "event_rate",
    "arrival_phi",
    "arrival_tod",
    "group_size_probs",
    "stay_mean",
    "stay_shape",
    "class_stay_mean",
    "class_stay_shape",
    "class_tod_weights",
    "mmpp_factor",
    "mmpp_switch",
    "hawkes_branching",
    "hawkes_decay",
)


def _flat(post: xr.Dataset, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """``(chain * draw, ...)`` arrays of the variables of ``names`` present in ``post``."""
    out = {}
    for name in names:
        if name in post:
            a = np.asarray(post[name].values)
            out[name] = a.reshape(-1, *a.shape[2:])
    return out


#: How each posterior was drawn: (what the CLI calls it, the posterior attribute).
_POSTERIOR_SOURCES = (
    ("the paper's model", "paper_posterior"),
    ("arrivals", "traffic_arrival_posterior"),
    ("stays", "traffic_lifetime_posterior"),
)


def _text(attrs: Mapping[str, object], name: str) -> str | None:
    return None if attrs.get(name) is None else str(attrs[name])


def _num(attrs: Mapping[str, object], name: str, default: float) -> float:
    return float(np.asarray(attrs.get(name, default)).ravel()[0])


def _chosen_laws(idata: az.InferenceData) -> TrafficLaws:
    """The arrival, stay and position laws ``are-stats fit`` chose (posterior attributes)."""
    a = idata.posterior.attrs
    positions = str(a.get("position_model", "uniform"))
    entry = None
    if positions == "learned":
        cd = idata.constant_data
        o = np.asarray(cd.attrs["position_origin"], float).ravel()
        entry = PositionDensity(
            np.asarray(cd["entry_density"].values, float),
            _num(cd.attrs, "position_resolution", 0.0),
            (float(o[0]), float(o[1])),
            _num(cd.attrs, "position_bandwidth", 0.0),
            float("nan"),
        )
    clock = a.get("traffic_clock_start")
    return TrafficLaws(
        arrivals=str(a.get("arrival_model", "poisson")),
        lifetimes=str(a.get("lifetime_model", "exponential")),
        positions=positions,
        bin_width=_num(a, "traffic_arrival_bin_width", 0.0) or None,
        clock_offset=None if clock is None else clock_offset(str(clock)),
        group_stay_sd=_num(a, "traffic_group_stay_sd", 0.0),
        group_spread=_num(a, "traffic_group_spread", 0.0),
        entry=entry,
        class_entry=class_position_densities(idata),
    )


def fit_class_labels(idata: az.InferenceData | Fit) -> list[str] | None:
    """The class name of each mixture component of a fit, or None.

    A log with labels (life-cycle rows or tracks) stores them, comma-separated, as the
    posterior attribute ``class_labels``; the only reader of that attribute (consumers
    read :attr:`Fit.class_labels`).

    Parameters
    ----------
    idata : arviz.InferenceData or Fit

    Returns
    -------
    list of str or None
    """
    if isinstance(idata, Fit):
        return None if idata.class_labels is None else list(idata.class_labels)
    names = idata.posterior.attrs.get("class_labels")
    return str(names).split(",") if names else None


class PosteriorMeans(NamedTuple):
    """Posterior means of the paper's model of a fit (:meth:`Fit.posterior_means`)."""

    #: ``E[lambda]``, arrivals per m^2 per second.
    arrival_rate: float
    #: ``E[mu]``, leaving rate per second.
    leave_rate: float
    #: ``E[lambda * area]``, arrivals per second over the log's area (None without one).
    arrivals_per_s: float | None
    #: ``E[1 / mu]``, the mean stay (s).
    mean_stay_s: float
    #: Each mixture component's name: the fit's class labels, else ``"0"``, ``"1"``, ...
    #: (empty without marks).
    class_labels: tuple[str, ...]
    #: ``(K,)`` ``E[w_k]``, the mixture weights of eq. (1) (empty without marks).
    class_weights: np.ndarray
    #: ``(K,)`` ``E[r_k]``, the components' Poisson mark rates (empty without marks).
    mark_rates: np.ndarray


class ClassShares(NamedTuple):
    """The classes of a labelled log (issue 31) as the fit sees them
    (:meth:`Fit.class_shares`)."""

    #: The class names, in component order.
    labels: tuple[str, ...]
    #: ``(K,)`` posterior mean share of the arrivals of each class.
    shares: np.ndarray
    #: ``(K,)`` arrivals per hour of each class: its share of ``E[lambda] * area * 3600``.
    per_hour: np.ndarray
    #: ``(K,)`` posterior median of each class's mean stay (s).
    stay_mean: np.ndarray


@dataclass(frozen=True)
class Fit:
    """A fit of a field log, decoded (:func:`~are_stats.fitting.read_fit`).

    Attributes
    ----------
    idata : arviz.InferenceData
        The file's content, for the fitting room's report, PSIS-LOO and criticism.
    source : str
        What errors name (the file, or ``"fit"`` for one in memory).
    method : str
        ``em`` or ``nuts`` (how the paper's models were fitted).
    format_version : int
        The file format (:data:`~are_stats.fitting.FIT_FORMAT_VERSION`; 1 for fits written
        before formats had numbers).
    area : float or None
        ``area(M_2D)`` of the log (m^2), the area lambda is per.
    window : (float, float) or None
        The log's observation window ``(t0, t1)`` (s).
    n_components : int
        Mixture components (eq. 1); 0 without marks or labels.
    class_labels : tuple of str or None
        The class of each component (a labelled log), else None.
    laws : are_stats.traffic.TrafficLaws
        The arrival, stay and position laws the fit chose.
    behaviour : BehaviourFit or None
        The behaviour fitted from the log's tracks (None without tracks).
    interaction : SocialForce or None
        The social force estimated from the tracks (None: the published one applies).
    interaction_info : mapping of str to float
        How well it was estimated: ``r2``, ``n`` (accelerations), ``group_samples``.
    motion : mapping of str to pandas.DataFrame
        The realism and displacement-error tables stored at fit time (issue 26).
    provenance : mapping of str to str
        ``seed``, ``log`` (file name), ``log_sha256``, when recorded.
    log_report : mapping
        How the log was read (rows used, truncated, censored, excluded, groups, the
        conversion of a tracks table), when recorded.
    notes : tuple of str
        What the fit did not do and why, or did differently (no map: the behaviour on the
        open area the tracks cover; people who only stand: no behaviour; ...).
    comparisons : mapping of str to pandas.DataFrame
        The candidates of each factor (``arrivals``, ``lifetimes``, ``positions``) by
        PSIS-LOO, with the chosen one flagged, when the fit compared them.
    traffic_notes : tuple of str
        Notes and warnings of the traffic model choice (``traffic_arrival_notes``,
        ``traffic_warnings``), as ``("note", text)`` / ``("warning", text)`` pairs.
    class_stay_model : str or None
        ``pooled`` or ``per-class`` (which LOO kept for a labelled log's stays).
    class_position_model, class_share_model : str or None
        Which LOO kept for a labelled log's entry/exit densities (pooled or per class)
        and class shares (constant or by time of day), when compared.
    time_resolution : float
        Time resolution (s) of the crowding statistics of the checks.
    posterior_sources : mapping of str to str
        How each posterior was drawn (the paper's exact draws, resampled Laplace or NUTS),
        keyed ``the paper's model``, ``arrivals`` and ``stays``, where recorded.
    grid : OccupancyGrid or None
        The map the behaviour and its criticism used (in memory after
        :func:`~are_stats.fitting.fit_log`; None for a fit read from a file).
    motion_checks : (pandas.DataFrame, pandas.DataFrame) or None
        The posterior-predictive motion checks of a labelled tracks table
        (:func:`~are_stats.fitting.motion_checks`: the table and the replicates' statistics)
        that :func:`~are_stats.fitting.fit_log` computed for the per-class rows, in memory
        only, so that :func:`~are_stats.fitting.write_motion_report` does not draw them again
        (None for a fit read from a file, or without labels).
    """

    idata: az.InferenceData
    source: str
    method: str
    format_version: int
    area: float | None
    window: tuple[float, float] | None
    n_components: int
    class_labels: tuple[str, ...] | None
    laws: TrafficLaws
    behaviour: BehaviourFit | None = None
    interaction: SocialForce | None = None
    interaction_info: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    motion: Mapping[str, pd.DataFrame] = field(default_factory=lambda: MappingProxyType({}))
    provenance: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    log_report: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))
    notes: tuple[str, ...] = ()
    comparisons: Mapping[str, pd.DataFrame] = field(default_factory=lambda: MappingProxyType({}))
    traffic_notes: tuple[tuple[str, str], ...] = ()
    class_stay_model: str | None = None
    class_position_model: str | None = None
    class_share_model: str | None = None
    time_resolution: float = 0.1
    posterior_sources: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    grid: OccupancyGrid | None = None
    motion_checks: tuple[pd.DataFrame, dict[str, np.ndarray | pd.DataFrame]] | None = None

    @classmethod
    def from_draws(
        cls,
        draws: Mapping[str, npt.ArrayLike],
        *,
        laws: TrafficLaws | None = None,
        behaviour: BehaviourFit | None = None,
        interaction: SocialForce | None = None,
        class_labels: Sequence[str] | None = None,
        area: float | None = None,
        source: str = "draws",
    ) -> Fit:
        """A fit of hand-set traffic parameters (or draws from elsewhere), so that every
        assembly starts from a :class:`Fit` (:func:`~are_stats.scenarios.scenes_from_fit`).

        Its posterior holds ``draws`` as one chain, its :meth:`traffic` gives them back
        (``model="chosen"``: all of them with ``laws``; ``"paper"``: those of
        :data:`PARAMETER_NAMES` with the paper's laws). A ``class_stay_mean`` makes the
        stays per class (:attr:`class_stay_model` ``"per-class"``), a ``class_tod_weights``
        the class shares by time of day, as a fit that chose them.

        Parameters
        ----------
        draws : dict of str to array
            ``arrival_rate`` (S,) (lambda, per m^2 per second), ``leave_rate`` (S,) (mu, per
            second), optional ``mix_weights`` (S, K), ``mix_rates`` (S, K) (eq. 1) and the
            variables of the laws' models (:data:`TRAFFIC_NAMES`), ``S`` draws each; when
            ``arrival_rate`` is a scalar, every value is one draw (no draw axis).
        laws : TrafficLaws, optional
            The arrival, stay and position laws (default: the paper's).
        behaviour : BehaviourFit, optional
            A behaviour (``behaviours="auto"`` uses it).
        interaction : SocialForce, optional
            A social force (``interaction=True`` uses it; default: the published one).
        class_labels : sequence of str, optional
            The class of each mixture component (catalogue rows by name).
        area : float, optional
            ``area(M_2D)`` (m^2) the rates are per, used where there is no map.
        source : str
            What errors name.

        Returns
        -------
        Fit
            ``method`` ``"draws"``; no log, window, provenance or checks.

        Raises
        ------
        ValueError
            Without ``arrival_rate`` or ``leave_rate``, or for a variable that is neither in
            :data:`PARAMETER_NAMES` nor in :data:`TRAFFIC_NAMES`.

        Examples
        --------
        >>> fit = Fit.from_draws({"arrival_rate": [2e-3], "leave_rate": [0.05]}, area=100.0)
        >>> draws, laws = fit.traffic()
        >>> draws["arrival_rate"].tolist(), laws.is_paper, fit.posterior_means().mean_stay_s
        ([0.002], True, 20.0)
        """
        # lazy: a cycle, _fit_log imports this module
        from are_stats.fitting._fit_log import FIT_FORMAT_VERSION

        known = PARAMETER_NAMES + TRAFFIC_NAMES
        for name in ("arrival_rate", "leave_rate"):
            if name not in draws:
                raise ValueError(
                    f"{source}: expected a variable {name!r} in the draws, got {sorted(draws)}"
                )
        unknown = sorted(set(draws) - set(known))
        if unknown:
            raise ValueError(
                f"{source}: expected draws of {', '.join(known)}, got unknown {unknown}"
            )
        one = np.ndim(draws["arrival_rate"]) == 0
        arrays = {k: np.asarray(v)[None] if one else np.asarray(v) for k, v in draws.items()}
        idata = _lazy.arviz.from_dict(posterior={k: a[None] for k, a in arrays.items()})
        weights = arrays.get("mix_weights", arrays.get("class_weights"))
        return cls(
            idata=idata,
            source=source,
            method="draws",
            format_version=FIT_FORMAT_VERSION,
            area=None if area is None else float(area),
            window=None,
            n_components=0 if weights is None else int(np.shape(weights)[-1]),
            class_labels=None if class_labels is None else tuple(str(c) for c in class_labels),
            laws=TrafficLaws() if laws is None else laws,
            behaviour=behaviour,
            interaction=interaction,
            class_stay_model="per-class" if "class_stay_mean" in arrays else None,
            class_share_model="time-of-day" if "class_tod_weights" in arrays else None,
        )

    def draws(self, names: tuple[str, ...] = PARAMETER_NAMES) -> dict[str, np.ndarray]:
        """``(chain * draw, ...)`` posterior draws of ``names`` (those present)."""
        return posterior_draws(self.idata, names)

    def posterior_means(self) -> PosteriorMeans:
        """Posterior means of the paper's model: ``lambda``, ``mu``, the arrivals per
        second ``lambda * area``, the mean stay ``1 / mu`` (means of the transformed draws,
        not transforms of the means) and the mixture's weights and mark rates (eq. 1).

        Returns
        -------
        PosteriorMeans

        Examples
        --------
        >>> import arviz as az
        >>> idata = az.from_dict(posterior={"arrival_rate": [[1.0, 3.0]],
        ...                                 "leave_rate": [[0.5, 0.25]]})
        >>> idata.posterior.attrs["area"] = 10.0
        >>> m = fit_from_idata(idata).posterior_means()
        >>> m.arrival_rate, m.arrivals_per_s, m.mean_stay_s
        (2.0, 20.0, 3.0)
        """
        post = self.idata.posterior
        k = int(post["mix_weights"].shape[-1]) if "mix_weights" in post else 0
        if k:
            weights = np.asarray(post["mix_weights"].mean(("chain", "draw")))
            rates = np.asarray(post["mix_rates"].mean(("chain", "draw")))
        else:
            weights = rates = np.zeros(0)
        labels = (self.class_labels or tuple(str(c) for c in range(k))) if k else ()
        return PosteriorMeans(
            arrival_rate=float(post["arrival_rate"].mean()),
            leave_rate=float(post["leave_rate"].mean()),
            arrivals_per_s=(
                None if self.area is None else float((post["arrival_rate"] * self.area).mean())
            ),
            mean_stay_s=float((1.0 / post["leave_rate"]).mean()),
            class_labels=tuple(str(v) for v in labels),
            class_weights=weights,
            mark_rates=rates,
        )

    @property
    def interaction_source(self) -> str | None:
        """Where the fit's social force (:attr:`interaction`) comes from: ``"estimated"``
        from the tracks' accelerations (:attr:`interaction_info` holds ``r2`` and ``n``),
        ``"none"`` when the tracks show no repulsion (strength 0: the published force fits
        them worse than none), ``"published"`` when they do not fit one (the published
        parameters kept); None without an interaction (the published force applies).
        """
        if self.interaction is None:
            return None
        if np.isfinite(self.interaction_info.get("n", np.nan)):
            return "estimated"
        return "none" if self.interaction.strength == 0 else "published"

    def class_shares(self) -> ClassShares | None:
        """Each class's share of the arrivals, its arrivals per hour and its mean stay, for a
        log that names its classes (posterior ``class_weights`` and ``class_stay_mean``);
        None for other fits.

        The arrivals per hour of class ``k`` are ``E[w_k] * E[lambda] * area * 3600``.

        Returns
        -------
        ClassShares or None

        Examples
        --------
        >>> import arviz as az
        >>> idata = az.from_dict(posterior={
        ...     "arrival_rate": [[1e-4, 3e-4]], "leave_rate": [[0.01, 0.01]],
        ...     "class_weights": [[[0.25, 0.75], [0.75, 0.25]]],
        ...     "class_stay_mean": [[[10.0, 100.0], [30.0, 300.0]]]})
        >>> idata.posterior.attrs.update(area=10.0, class_labels="person,cart")
        >>> c = fit_from_idata(idata).class_shares()
        >>> c.labels, c.shares.tolist(), c.per_hour.round(6).tolist(), c.stay_mean.tolist()
        (('person', 'cart'), [0.5, 0.5], [3.6, 3.6], [20.0, 200.0])
        """
        post = self.idata.posterior
        if "class_weights" not in post:
            return None
        shares = np.asarray(post["class_weights"].mean(("chain", "draw")))
        stays = np.asarray(post["class_stay_mean"].median(("chain", "draw")))
        total = float(post["arrival_rate"].mean()) * float(self.area) * 3600.0
        return ClassShares(tuple(self.class_labels or ()), shares, shares * total, stays)

    def traffic(self, model: str = "chosen") -> tuple[dict[str, np.ndarray], TrafficLaws]:
        """Draws and laws to generate from: the fit's chosen models or the paper's
        (:func:`traffic_draws`)."""
        return traffic_draws(self, model)


def fit_from_idata(idata: az.InferenceData, source: str = "fit") -> Fit:
    """Decode an InferenceData of :func:`~are_stats.fitting.fit_log` into a :class:`Fit`.

    :func:`~are_stats.fitting.read_fit` checks a file first and then calls this; a fit
    in memory (just fitted) is decoded as it is.

    Raises
    ------
    are_stats.inputs.InputError
        Naming ``source`` and the group, if the behaviour group or its stored tables are
        damaged.
    """
    a = idata.posterior.attrs
    window = None
    if "window" in a:
        w = np.asarray(a["window"], float).ravel()
        window = (float(w[0]), float(w[1]))
    version = a.get("format_version")
    labels = fit_class_labels(idata)
    behaviour = interaction = None
    motion: dict[str, pd.DataFrame] = {}
    info: dict[str, float] = {}
    if "behaviour" in idata.groups():
        ds = idata.behaviour
        try:
            behaviour = BehaviourFit.from_dataset(ds)
            interaction = interaction_from_attrs(ds.attrs)
            if interaction is not None:
                info = interaction_info(ds.attrs)
            motion = motion_tables(ds.attrs)
        except (KeyError, ValueError, TypeError, IndexError) as err:
            raise InputError(
                source,
                "behaviour",
                "the behaviour group written by are-stats fit",
                Described(f"a damaged group ({type(err).__name__}: {err})"),
            ) from None
    provenance = {k: str(a[k]) for k in ("seed", "log", "log_sha256") if k in a}
    report = yaml.safe_load(str(a["log_report"])) if a.get("log_report") else {}
    notes = tuple(n for n in str(a.get("fit_notes", "") or "").splitlines() if n.strip())
    comparisons = {}
    for factor in ("arrivals", "lifetimes", "positions"):
        text = a.get(f"loo_{factor}")
        if text:
            comparisons[factor] = pd.read_csv(io.StringIO(str(text)), index_col=0)
    traffic_notes = (
        [("note", str(a["traffic_arrival_notes"]))] if a.get("traffic_arrival_notes") else []
    )
    traffic_notes += [
        ("warning", w) for w in str(a.get("traffic_warnings", "") or "").splitlines() if w.strip()
    ]
    stay_model = a.get("class_stay_model")
    return Fit(
        idata=idata,
        source=source,
        method=str(a.get("method", "")),
        format_version=1 if version is None else int(np.asarray(version).ravel()[0]),
        area=float(np.asarray(a["area"]).ravel()[0]) if "area" in a else None,
        window=window,
        n_components=int(np.asarray(a.get("n_components", 0)).ravel()[0]),
        class_labels=None if labels is None else tuple(labels),
        laws=_chosen_laws(idata),
        behaviour=behaviour,
        interaction=interaction,
        interaction_info=MappingProxyType(info),
        motion=MappingProxyType(motion),
        provenance=MappingProxyType(provenance),
        log_report=MappingProxyType(report if isinstance(report, dict) else {}),
        notes=notes,
        comparisons=MappingProxyType(comparisons),
        traffic_notes=tuple(traffic_notes),
        class_stay_model=None if stay_model is None else str(stay_model),
        class_position_model=_text(a, "class_position_model"),
        class_share_model=_text(a, "class_share_model"),
        time_resolution=_num(a, "traffic_time_resolution", 0.1),
        posterior_sources=MappingProxyType(
            {who: str(a[key]) for who, key in _POSTERIOR_SOURCES if a.get(key)}
        ),
    )


def as_fit(fit: Fit | az.InferenceData | str | os.PathLike, source: str | None = None) -> Fit:
    """A :class:`Fit` from a fit, an InferenceData of ``fit_log``, or a fit file's path
    (read and checked by :func:`~are_stats.fitting.read_fit`)."""
    if isinstance(fit, Fit):
        return fit
    if isinstance(fit, str | os.PathLike):
        # lazy: a cycle, _fit_log imports this module
        from are_stats.fitting._fit_log import read_fit

        return read_fit(fit)
    return fit_from_idata(fit, "fit" if source is None else source)


def posterior_draws(
    fit: Fit | az.InferenceData | str | os.PathLike, names: tuple[str, ...] = PARAMETER_NAMES
) -> dict[str, np.ndarray]:
    """Flatten the posterior of a fit (or a fit file, read by ``read_fit``) to draws.

    Parameters
    ----------
    fit : Fit or arviz.InferenceData or str or PathLike
        A fit (as written by ``are-stats fit``).
    names : tuple of str
        Variables to take when present (:data:`PARAMETER_NAMES`).

    Returns
    -------
    dict of str to array
        ``(chain * draw, ...)`` arrays for each variable found.

    Raises
    ------
    ValueError
        If the posterior lacks ``arrival_rate`` or ``leave_rate``.
    """
    if isinstance(fit, str | os.PathLike):
        fit = as_fit(Path(fit))
    idata = fit.idata if isinstance(fit, Fit) else fit
    post = idata.posterior
    out = _flat(post, names)
    for name in ("arrival_rate", "leave_rate"):
        if name not in out:
            raise ValueError(
                f"posterior: expected a variable {name!r}, got {sorted(post.data_vars)}"
            )
    return out


def traffic_draws(
    fit: Fit | az.InferenceData | str | os.PathLike, model: str = "chosen"
) -> tuple[dict[str, np.ndarray], TrafficLaws]:
    """Posterior draws and laws to generate from: the fit's chosen models or the paper's.

    Parameters
    ----------
    fit : Fit or arviz.InferenceData or str or PathLike
        A fit (:func:`are_stats.fitting.read_fit`).
    model : {"chosen", "paper"}
        ``chosen``: the arrival, stay and position models recorded by ``are-stats fit``
        (:attr:`Fit.laws`); ``paper``: Poisson arrivals, exponential stays, uniform
        positions.

    Returns
    -------
    draws : dict of str to (S, ...) ndarray
        :data:`PARAMETER_NAMES` and, for chosen models, :data:`TRAFFIC_NAMES` present.
    laws : are_stats.traffic.TrafficLaws
    """
    check_in("model", model, ("chosen", "paper"))
    fit = as_fit(fit)
    draws = posterior_draws(fit)
    if model == "paper":
        return draws, TrafficLaws()
    per_class = fit.class_stay_model == "per-class"
    by_hour = fit.class_share_model == "time-of-day"
    # LOO kept the pooled stays unless per-class (then one law for every class), one set of
    # class shares for the whole day unless time-of-day
    names = tuple(
        n
        for n in TRAFFIC_NAMES
        if (per_class or not n.startswith("class_stay")) and (by_hour or n != "class_tod_weights")
    )
    draws.update(_flat(fit.idata.posterior, names))
    return draws, fit.laws
