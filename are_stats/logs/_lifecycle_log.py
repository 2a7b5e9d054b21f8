"""Life-cycle logs: one row per observed artefact, with its observation window and area.

A life-cycle log is the field record the arrival/leaving model of Sect. 3.2 is fitted to:
each artefact's arrival time ``t_arrive`` and leaving time ``t_leave`` inside the
observation window ``[t0, t1]`` (DECISIONS 3), its mark X (eq. 1), optional class label and
its pose at arrival. An empty ``t_arrive`` means the artefact was already present at ``t0``
(left-truncated: its arrival is unknown); an empty ``t_leave`` means it was still present at
``t1`` (right-censored). The area ``nu(M2D)`` (DECISIONS 4) comes from the manifest.
"""

from __future__ import annotations

import datetime
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, NotRequired, TypedDict, Unpack

import numpy as np
import pandas as pd

from are_stats.environment import OccupancyGrid
from are_stats.inputs import (
    Described,
    InputError,
    Source,
    check_keys,
    get_float,
    get_list,
    get_str,
    load_yaml,
)
from are_stats.logs._table import RawTable, frame_table, read_raw_table

if TYPE_CHECKING:
    from are_stats.traffic import LifecycleData

__all__ = [
    "LIFECYCLE_COLUMNS",
    "LifecycleLog",
    "ManifestOverrides",
    "find_manifest",
    "lifecycle_log_from_frame",
    "read_lifecycle_log",
    "read_manifest",
]

#: Columns of a life-cycle log, in canonical order (``id, t_arrive, t_leave`` required).
LIFECYCLE_COLUMNS = (
    "id",
    "t_arrive",
    "t_leave",
    "label",
    "mark",
    "x",
    "y",
    "yaw",
    "group",
    "x_exit",
    "y_exit",
)
_REQUIRED = ["id", "t_arrive", "t_leave"]

#: Multipliers to seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0}
#: Multipliers to square metres.
AREA_UNITS = {"m^2": 1.0, "m2": 1.0, "cm^2": 1e-4, "km^2": 1e6, "ha": 1e4}
_MANIFEST_KEYS = (
    "window",
    "area",
    "map",
    "time_unit",
    "area_unit",
    "min_lifetime",
    "time_step",
    "clock_start",
    "description",
)


class LifecycleManifest(TypedDict, total=False):
    """A life-cycle log's manifest as :func:`read_manifest` checks it: the keys the file
    has, in its own units (see :func:`read_manifest` for their meaning)."""

    #: ``[t0, t1]`` in ``time_unit``.
    window: list[float]
    #: In ``area_unit``; or ``map``, a ROS map YAML's path (resolved against the manifest's
    #: folder) whose free area is taken.
    area: float
    map: str
    #: A key of :data:`TIME_UNITS` and of :data:`AREA_UNITS`.
    time_unit: str
    area_unit: str
    #: In ``time_unit``.
    min_lifetime: float
    time_step: float
    #: ISO 8601 text.
    clock_start: str
    description: str


class ResolvedManifest(TypedDict, total=False):
    """A log's settings once the caller's overrides are applied and the units converted
    (:attr:`LifecycleLog.manifest`): the manifest's keys in seconds and m^2, and where they
    came from. A log read by :func:`read_lifecycle_log`, :func:`~are_stats.logs.read_field_log`
    or :func:`lifecycle_log_from_frame` has ``window``, ``area``, ``time_unit``,
    ``area_unit`` and ``min_lifetime``."""

    #: ``[t0, t1]`` in s.
    window: list[float]
    #: m^2, None when neither the manifest nor the caller gave one.
    area: float | None
    map: str
    #: ``s`` and ``m^2``; the manifest's own units were ``source_time_unit`` and
    #: ``source_area_unit``.
    time_unit: str
    area_unit: str
    source_time_unit: str
    source_area_unit: str
    #: s.
    min_lifetime: float
    time_step: float
    #: ISO 8601 text.
    clock_start: str
    description: str
    #: The manifest's path, where an area would have come from (set when there is none).
    area_missing_in: str
    #: ``tracks table`` for a log converted from tracks.
    input: str


class TrackConversion(TypedDict, total=False):
    """How a log was made from a tracks table (:attr:`LifecycleLog.conversion`, empty for a
    life-cycle log read as such): the counts and settings of
    :func:`~are_stats.logs.tracks_to_lifecycle` (times in s)."""

    sightings: int
    track_ids: int
    artefacts: int
    split_track_ids: int
    groups: int
    artefacts_in_groups: int
    sampling_step: float
    gap_tolerance: float
    group_time: float
    group_distance: float
    #: Left out, by reason (``outside_window`` sightings, ``too_few_sightings`` segments).
    excluded: dict[str, int]


class LifecycleReport(TypedDict):
    """A log's counts for a fit report (:meth:`LifecycleLog.report`)."""

    source: str
    #: ``[t0, t1]`` in s; the area in m^2 (or None); the wall-clock time of ``t = 0``.
    window: list[float]
    area: float | None
    clock_start: str | None
    rows_read: int
    rows_used: int
    #: Rows left out, by reason.
    excluded: dict[str, int]
    left_truncated: int
    right_censored: int
    with_mark: int
    with_label: int
    groups: int
    artefacts_in_groups: int
    #: The conversion, for a log made from tracks.
    tracks: NotRequired[TrackConversion]


class LifecycleArrays(TypedDict):
    """A log's columns as arrays for the life-cycle likelihoods (:meth:`LifecycleLog.to_arrays`;
    its docstring gives their meaning)."""

    #: (n,) object str.
    ids: np.ndarray
    #: (n,) float64 s, NaN when truncated / censored.
    t_arrive: np.ndarray
    t_leave: np.ndarray
    #: (n,) bool.
    truncated: np.ndarray
    censored: np.ndarray
    #: (n,) int64, -1 when missing.
    marks: np.ndarray
    #: (n,) object str; (n,) int64 indices into ``label_names`` (sorted), -1 when missing.
    labels: np.ndarray
    label_codes: np.ndarray
    label_names: list[str]
    #: (n,) float64.
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    #: (n,) int64 group codes.
    group: np.ndarray
    #: (n,) float64, NaN when unknown.
    x_exit: np.ndarray
    y_exit: np.ndarray
    window: tuple[float, float]
    area: float | None
    clock_start: str | None


@dataclass(frozen=True, eq=False)
class LifecycleLog:
    """A validated life-cycle log.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per artefact, columns ``id`` (str), ``t_arrive``, ``t_leave`` (float64
        seconds, NaN when left-truncated / right-censored), ``label`` (str, ``""`` when
        absent), ``mark`` (int64, -1 when absent), ``x``, ``y``, ``yaw`` (float64, NaN when
        absent), ``group`` (str, the group id as written, ``""`` when alone), ``x_exit``,
        ``y_exit`` (float64, NaN when unknown), ``truncated`` and ``censored`` (bool).
    window : (float, float)
        Observation window ``(t0, t1)`` in seconds.
    area : float or None
        Free area ``nu(M2D)`` in m^2 (None when neither manifest nor caller gave one).
    source : str
        The file the log was read from (or ``"<frame>"``).
    excluded : dict of str to int
        Rows left out on purpose, by reason (``blank_row``, ``shorter_than_min_lifetime``).
    manifest : dict
        The manifest as read (after overrides), with units.
    columns : tuple of str
        The optional columns of :data:`LIFECYCLE_COLUMNS` the source table had (``group``,
        ``x_exit``, ... ): a column absent from the source is all-empty in ``table``.
    conversion : dict
        How the log was made from a tracks table (:func:`read_field_log`): sightings,
        track ids, artefacts, split track ids, the sampling step and the group tolerances;
        empty for a life-cycle log read as such.
    tracks : pandas.DataFrame or None
        The tracks table itself (``id, t, x, y, label, yaw``, ``t`` in seconds) of a log
        made from one, read with it (the behaviour fit reads its motion); None otherwise.
    """

    table: pd.DataFrame
    window: tuple[float, float]
    area: float | None
    source: str
    excluded: dict[str, int] = field(default_factory=dict)
    manifest: ResolvedManifest = field(default_factory=dict)
    columns: tuple[str, ...] = ()
    conversion: TrackConversion = field(default_factory=dict)
    tracks: pd.DataFrame | None = None

    @property
    def n_artefacts(self) -> int:
        """Number of artefacts (rows kept)."""
        return len(self.table)

    @property
    def clock_start(self) -> str | None:
        """Wall-clock time of ``t = 0`` (ISO 8601, manifest key ``clock_start``), or None."""
        value = self.manifest.get("clock_start")
        return None if value is None else str(value)

    def report(self) -> LifecycleReport:
        """Counts for a fit report.

        Rows kept, excluded by reason, truncated, censored, with mark / label, ``groups``
        (groups of two or more artefacts) and ``artefacts_in_groups``, ``clock_start``, and
        for a log made from tracks the conversion counts under ``tracks``.
        """
        t = self.table
        sizes = self._group_sizes()
        out: LifecycleReport = {
            "source": self.source,
            "window": list(self.window),
            "area": self.area,
            "clock_start": self.clock_start,
            "rows_read": int(len(t) + sum(self.excluded.values())),
            "rows_used": int(len(t)),
            "excluded": dict(self.excluded),
            "left_truncated": int(t["truncated"].sum()),
            "right_censored": int(t["censored"].sum()),
            "with_mark": int((t["mark"] >= 0).sum()),
            "with_label": int((t["label"] != "").sum()),
            "groups": int((sizes > 1).sum()),
            "artefacts_in_groups": int(sizes[sizes > 1].sum()),
        }
        if self.conversion:
            out["tracks"] = dict(self.conversion)
        return out

    def _group_sizes(self) -> np.ndarray:
        """(G,) int64: artefacts per group (lone artefacts are groups of one)."""
        codes = self._group_codes()
        return np.bincount(codes) if codes.size else np.zeros(0, dtype=np.int64)

    def _group_codes(self) -> np.ndarray:
        """(n,) int64 group codes 0..G-1 in order of first appearance; alone = own code."""
        ids = self.table["group"].to_numpy(dtype=object)
        # a lone artefact's key cannot collide with a group id (ids are non-empty text)
        keys = [("", i) if g == "" else (g, -1) for i, g in enumerate(ids)]
        codes, _ = pd.factorize(pd.Series(keys, dtype=object), sort=False)
        return np.asarray(codes, dtype=np.int64)

    def to_arrays(self) -> LifecycleArrays:
        """Arrays for the life-cycle likelihoods.

        Returns
        -------
        dict
            ``t_arrive`` (n,) float64 (NaN when truncated), ``t_leave`` (n,) float64 (NaN
            when censored), ``truncated`` (n,) bool, ``censored`` (n,) bool, ``marks`` (n,)
            int64 (-1 when missing), ``labels`` (n,) object str (``""`` when missing),
            ``label_codes`` (n,) int64 (index into ``label_names``, -1 when missing),
            ``label_names`` list of str (sorted), ``x``, ``y``, ``yaw`` (n,) float64,
            ``group`` (n,) int64 (group codes 0..G-1 in order of first appearance, each
            lone artefact its own code), ``x_exit``, ``y_exit`` (n,) float64 (NaN when
            unknown), ``ids`` (n,) object str, ``window`` (t0, t1), ``area`` float or None,
            ``clock_start`` str or None.
        """
        t = self.table
        labels = t["label"].to_numpy(dtype=object)
        names = sorted({s for s in labels if s != ""})
        lookup = {s: i for i, s in enumerate(names)}
        codes = np.array([lookup.get(s, -1) for s in labels], dtype=np.int64)
        return {
            "ids": t["id"].to_numpy(dtype=object),
            "t_arrive": t["t_arrive"].to_numpy(dtype=np.float64),
            "t_leave": t["t_leave"].to_numpy(dtype=np.float64),
            "truncated": t["truncated"].to_numpy(dtype=bool),
            "censored": t["censored"].to_numpy(dtype=bool),
            "marks": t["mark"].to_numpy(dtype=np.int64),
            "labels": labels,
            "label_codes": codes,
            "label_names": names,
            "x": t["x"].to_numpy(dtype=np.float64),
            "y": t["y"].to_numpy(dtype=np.float64),
            "yaw": t["yaw"].to_numpy(dtype=np.float64),
            "group": self._group_codes(),
            "x_exit": t["x_exit"].to_numpy(dtype=np.float64),
            "y_exit": t["y_exit"].to_numpy(dtype=np.float64),
            "window": self.window,
            "area": self.area,
            "clock_start": self.clock_start,
        }

    def to_lifecycle_data(self, label_names: Sequence[str] | None = None) -> LifecycleData:
        """Build the life-cycle model's container :class:`are_stats.traffic.LifecycleData`.

        Parameters
        ----------
        label_names : sequence of str, optional
            Class order: label ``label_names[c]`` becomes class ``c`` (mixture component c,
            DECISIONS 5). Default: the sorted distinct labels.

        Returns
        -------
        LifecycleData
            ``marks`` when every row has one (None when no row has), ``labels`` (class
            indices) when every row has a label and marks are present, ``x``, ``y``, ``yaw``
            when every row has them, ``group`` (int codes 0..G-1 in order of first
            appearance, each lone artefact its own code) when the log has a ``group``
            column, ``x_exit``, ``y_exit`` (NaN where unknown) when it has those columns.

        Raises
        ------
        ValueError
            If the log has no area, marks or labels are given on some rows only, or a label
            is not in ``label_names``.
        """
        # lazy: traffic (JAX, NumPyro) adds 2.0 s CPU to `import are_stats.logs`
        from are_stats.traffic import LifecycleData

        a = self.to_arrays()
        if self.area is None:
            raise InputError(
                self.manifest.get("area_missing_in", self.source),
                "area",
                f"the free area of {self.source}'s scene (manifest key 'area' or 'map', "
                "or area=... / --area)",
                Described("none"),
            )
        ids = a["ids"]
        marks = a["marks"]
        has = marks >= 0
        if has.any() and not has.all():
            i = int(np.argmax(~has))
            raise ValueError(
                f"{self.source}: artefact {ids[i]!r}, column 'mark': expected a "
                "mark on every row or on none (the mixture needs all), got an "
                "empty cell"
            )
        labels = a["labels"]
        lab = labels != ""
        codes = None
        if has.all() and lab.any():
            if not lab.all():
                i = int(np.argmax(~lab))
                raise ValueError(
                    f"{self.source}: artefact {ids[i]!r}, column 'label': "
                    "expected a label on every row or on none, got an empty cell"
                )
            names = a["label_names"] if label_names is None else _label_names(label_names)
            lookup = {n: c for c, n in enumerate(names)}
            unknown = [v for v in labels if v not in lookup]
            if unknown:
                raise ValueError(
                    f"{self.source}: column 'label': expected one of {names}, got {unknown[0]!r}"
                )
            codes = np.array([lookup[v] for v in labels], dtype=np.int64)
        pose = {k: a[k] if np.isfinite(a[k]).all() else None for k in ("x", "y", "yaw")}
        cols = set(self.columns)
        return LifecycleData(
            t_arrive=a["t_arrive"],
            t_leave=a["t_leave"],
            window=self.window,
            area=self.area,
            marks=marks if has.all() else None,
            labels=codes,
            group=a["group"] if "group" in cols else None,
            x_exit=a["x_exit"] if "x_exit" in cols else None,
            y_exit=a["y_exit"] if "y_exit" in cols else None,
            **pose,
        )

    def label_classes(self) -> tuple[np.ndarray, list[str]] | None:
        """The classes a log without marks names in its ``label`` column (issue 31).

        With labels and no marks the class of each artefact is its label (DECISIONS 5):
        :func:`are_stats.fitting.fit_log` fits the class shares and per-class stays from
        these codes (``classes=``). A log with marks keeps the mixture (the labels are its
        components, :meth:`to_lifecycle_data`); a log without labels has no classes.

        Returns
        -------
        (codes, names) or None
            ``codes`` (n,) int64 indexes ``names`` (the sorted distinct labels), in the
            order of :meth:`to_lifecycle_data`'s rows; None when the log has marks or no
            label.

        Raises
        ------
        ValueError
            If some rows have a label and others none.
        """
        a = self.to_arrays()
        labels = a["labels"]
        lab = labels != ""
        if (a["marks"] >= 0).any() or not lab.any():
            return None
        if not lab.all():
            i = int(np.argmax(~lab))
            raise ValueError(
                f"{self.source}: artefact {a['ids'][i]!r}, column 'label': expected a label "
                "on every row or on none (the class of each artefact), got an empty cell"
            )
        return np.asarray(a["label_codes"], np.int64), list(a["label_names"])


def _label_names(value: object) -> list[str]:
    """``label_names``: a list of distinct strings."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    names = [
        get_str(v, "label_names", f"[{k}]")
        for k, v in enumerate(get_list(value, "label_names", ""))
    ]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError("label_names", "", "distinct class labels", Described(f"{dup} repeated"))
    return names


def read_manifest(path: str | os.PathLike) -> LifecycleManifest:
    """Read and check a life-cycle-log manifest (YAML).

    Keys: ``window: [t0, t1]`` (in ``time_unit``), ``area`` (in ``area_unit``) or ``map``
    (path to a ROS map YAML, relative to the manifest), ``time_unit`` (``s``, ``ms``,
    ``min``, ``h``; default ``s``), ``area_unit`` (``m^2``, ``cm^2``, ``km^2``, ``ha``;
    default ``m^2``), ``min_lifetime`` (default 0), ``time_step`` (the sampling step of the
    times, e.g. the tracker's period, in ``time_unit``: times up to one step outside the
    window are clipped onto its edge; default: only rounding errors are), ``clock_start``
    (the wall-clock time of ``t = 0``, ISO 8601 text such as ``2024-05-02T07:30:00``, read
    with :meth:`datetime.datetime.fromisoformat`), ``description`` (free text).

    The file is read with :func:`are_stats.inputs.load_yaml` (duplicate keys, alias bombs
    and over-deep nesting rejected) and every value is type-checked strictly: numbers are
    YAML numbers (not booleans, strings or lists), finite, in range.

    Returns
    -------
    dict
        The keys present, with values as written (numbers as floats) and ``map`` resolved
        against the manifest's folder.

    Raises
    ------
    FileNotFoundError
        If the manifest does not exist.
    InputError
        On invalid YAML, unknown keys or malformed values, naming the file and the key.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such manifest file")
    if not (p.is_file() or p.is_dir()):  # a FIFO or device would block or never end
        raise InputError(p, "", "a life-cycle log manifest file", Described("a special file"))
    meta = load_yaml(p, "life-cycle log manifest")
    if meta is None:
        meta = {}
    if not isinstance(meta, Mapping):
        raise InputError(p, "", "a YAML mapping of manifest keys", meta)
    meta = check_keys(meta, p, "", _MANIFEST_KEYS)
    if "area" in meta and "map" in meta:
        raise InputError(p, "keys 'area' and 'map'", "one of them", Described("both"))
    out: LifecycleManifest = {}
    if "window" in meta:
        out["window"] = list(_window(p, "window", meta["window"], 1.0))
    if "area" in meta:
        out["area"] = get_float(meta["area"], p, "area", lo=0.0, lo_open=True)
    if "map" in meta:
        mp = Path(get_str(meta["map"], p, "map"))
        out["map"] = str(mp if mp.is_absolute() else p.parent / mp)
    if "time_unit" in meta:
        out["time_unit"] = get_str(meta["time_unit"], p, "time_unit", choices=TIME_UNITS)
    if "area_unit" in meta:
        out["area_unit"] = get_str(meta["area_unit"], p, "area_unit", choices=AREA_UNITS)
    if "min_lifetime" in meta:
        out["min_lifetime"] = get_float(meta["min_lifetime"], p, "min_lifetime", lo=0.0)
    if "time_step" in meta:
        out["time_step"] = get_float(meta["time_step"], p, "time_step", lo=0.0, lo_open=True)
    if "clock_start" in meta:
        out["clock_start"] = _clock_start(p, "clock_start", meta["clock_start"])
    if "description" in meta:
        out["description"] = get_str(meta["description"], p, "description")
    return out


def _clock_start(source: Source, where: str, value: object) -> str:
    """``clock_start``: ISO 8601 date-time text (:meth:`datetime.datetime.fromisoformat`).

    YAML reads an unquoted ``2024-05-02T07:30:00`` as a timestamp: it is accepted and
    written back in ISO form.
    """
    if isinstance(value, datetime.datetime):
        return value.isoformat()
    expected = "an ISO 8601 date and time such as '2024-05-02T07:30:00'"
    if isinstance(value, datetime.date):
        raise InputError(source, where, expected, Described(f"the date {value.isoformat()!r}"))
    text = get_str(value, source, where)
    try:
        datetime.datetime.fromisoformat(text)
    except ValueError:
        raise InputError(source, where, expected, text) from None
    return text


def _window(source: Source, where: str, value: object, scale: float) -> tuple[float, float]:
    """A window ``[t0, t1]`` of two finite numbers with ``t0 < t1``, times ``scale``."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    pair = get_list(value, source, where, min_len=2, max_len=2)
    t0 = get_float(pair[0], source, f"{where}[0]" if where else "t0")
    t1 = get_float(pair[1], source, f"{where}[1]" if where else "t1")
    if not t1 > t0:
        raise InputError(
            source,
            where,
            "a window [t0, t1] of finite numbers with t0 < t1",
            Described(f"[{t0!r}, {t1!r}]"),
        )
    lo, hi = t0 * scale, t1 * scale
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise InputError(
            source, where, "a window that stays finite in seconds", Described(f"[{t0!r}, {t1!r}]")
        )
    return lo, hi


def _resolve_settings(
    manifest: LifecycleManifest, mpath: str, overrides: ManifestOverrides
) -> tuple[tuple[float, float], float | None, float, ResolvedManifest]:
    window, area = overrides.get("window"), overrides.get("area")
    clock_start = overrides.get("clock_start")
    tu = str(manifest.get("time_unit", "s"))
    au = str(manifest.get("area_unit", "m^2"))
    scale = TIME_UNITS[tu]
    if window is not None:
        win = _window("window", "", window, scale)
    elif "window" in manifest:
        win = _window(mpath, "window", manifest["window"], scale)
    else:
        raise InputError(
            mpath,
            "window",
            "the observation window [t0, t1] in the manifest or as window=(t0, t1)",
            Described("nothing"),
        )
    if area is not None:
        a: float | None = get_float(area, "area", "", lo=0.0, lo_open=True)
    elif "area" in manifest:
        a = manifest["area"] * AREA_UNITS[au]
        if not math.isfinite(a):
            raise InputError(mpath, "area", "an area that stays finite in m^2", manifest["area"])
    elif "map" in manifest:
        a = OccupancyGrid.from_ros_yaml(manifest["map"]).free_area
        if a <= 0:
            raise InputError(manifest["map"], "", "a map with free cells", Described("none"))
    else:
        a = None
    min_life = float(manifest.get("min_lifetime", 0.0)) * scale
    if not math.isfinite(min_life):
        raise InputError(
            mpath,
            "min_lifetime",
            "a lifetime that stays finite in seconds",
            manifest["min_lifetime"],
        )
    resolved = dict(manifest)
    if clock_start is not None:
        resolved["clock_start"] = _clock_start("clock_start", "", clock_start)
    if "time_step" in manifest:
        step = float(manifest["time_step"]) * scale
        if not (math.isfinite(step) and step > 0):
            raise InputError(
                mpath, "time_step", "a step that stays finite in seconds", manifest["time_step"]
            )
        resolved["time_step"] = step
    resolved.update(
        {
            "window": list(win),
            "area": a,
            "time_unit": "s",
            "area_unit": "m^2",
            "min_lifetime": min_life,
            "source_time_unit": tu,
            "source_area_unit": au,
        }
    )
    if a is None:  # where an area would have come from, for the error when one is needed
        resolved["area_missing_in"] = mpath
    return win, a, min_life, resolved


class ManifestOverrides(TypedDict, total=False):
    """What a caller gives of a log's settings instead of its manifest's: the keywords of
    :func:`read_lifecycle_log` and :func:`~are_stats.logs.read_field_log` (None: as the
    manifest says).

    Attributes
    ----------
    manifest : str or PathLike or None
        The YAML manifest (default ``<stem>.yaml`` or ``.yml`` beside the table, if any).
    window : (float, float) or None
        Observation window ``(t0, t1)`` in the table's time unit.
    area : float or None
        Free area in m^2 (instead of the manifest's ``area`` / ``map``).
    clock_start : str or None
        Wall-clock time of ``t = 0`` (ISO 8601).
    """

    manifest: str | os.PathLike | None
    window: tuple[float, float] | None
    area: float | None
    clock_start: str | None


def read_lifecycle_log(
    path: str | os.PathLike, **overrides: Unpack[ManifestOverrides]
) -> LifecycleLog:
    """Read and validate a life-cycle log (CSV or Parquet) and its manifest.

    Parameters
    ----------
    path : str or PathLike
        The table: ``.csv`` / ``.tsv`` / ``.txt`` or ``.parquet`` / ``.pq``, one row per
        artefact with columns ``id``, ``t_arrive``, ``t_leave`` and optional ``label``,
        ``mark``, ``x``, ``y``, ``yaw``, ``group`` (an id shared by artefacts that arrived
        together; empty = alone), ``x_exit``, ``y_exit`` (leaving position; empty =
        unknown; both or neither).
    **overrides
        ``manifest``, ``window``, ``area``, ``clock_start`` (:class:`ManifestOverrides`), as
        :func:`~are_stats.logs.read_field_log` takes them (the manifest by default
        ``<stem>.yaml`` or ``.yml`` beside the table; the other three override it).

    Returns
    -------
    LifecycleLog
        Times converted to seconds, area to m^2. Times outside the window by at most the
        tolerance (one ``time_step`` when the manifest gives one, else a rounding error,
        see :data:`WINDOW_RTOL`) are clipped onto the window's edge.

    Raises
    ------
    FileNotFoundError
        If the table, an explicit manifest or the manifest's map is missing.
    ValueError
        ``"<file>: row <r> (line <l>), column '<col>': expected ..., got ..."`` for every
        malformed cell (rows are 1-based data rows, lines 1-based physical CSV lines), and
        for missing columns, empty files, duplicate ids, ``t_leave < t_arrive`` and times
        outside the window.

    Examples
    --------
    >>> log = read_lifecycle_log("field/courtyard.csv", window=(0, 3600), area=450.0)
    ... # doctest: +SKIP
    >>> arrays = log.to_arrays()  # doctest: +SKIP
    """
    unknown = sorted(set(overrides) - ManifestOverrides.__optional_keys__)
    if unknown:
        raise TypeError(f"read_lifecycle_log() got an unexpected keyword argument {unknown[0]!r}")
    p = Path(path)
    meta, mpath = find_manifest(p, overrides.get("manifest"))
    raw = read_raw_table(p, "life-cycle log")
    return _lifecycle_from_raw(raw, p, meta, mpath, overrides)


def _lifecycle_from_raw(
    raw: RawTable,
    path: Path,
    meta: LifecycleManifest,
    mpath: str,
    overrides: ManifestOverrides,
) -> LifecycleLog:
    """A life-cycle log table already read (``raw``, from ``path``) with its manifest
    (``meta`` at ``mpath``), its settings overridden by ``overrides``, validated:
    :func:`read_lifecycle_log` and the life-cycle branch of
    :func:`~are_stats.logs.read_field_log`."""
    win, a, min_life, resolved = _resolve_settings(meta, mpath, overrides)
    scale = TIME_UNITS[resolved["source_time_unit"]]
    tol = max(window_tolerance(win), float(resolved.get("time_step", 0.0)))
    return _validate(raw, win, a, min_life, scale, str(path), resolved, tol)


def find_manifest(
    path: str | os.PathLike, manifest: str | os.PathLike | None = None
) -> tuple[LifecycleManifest, str]:
    """The manifest of a log table: ``manifest`` if given, else the table's neighbour
    ``<stem>.yaml`` (or ``<stem>.yml``), read and checked by :func:`read_manifest`.

    Parameters
    ----------
    path : str or PathLike
        The log table (CSV or Parquet).
    manifest : str or PathLike, optional
        A manifest given explicitly (``are-stats fit --manifest``).

    Returns
    -------
    meta : dict
        The checked manifest; empty when the table has none.
    where : str
        Its path, for messages (``"<stem>.yaml (not found)"`` when there is none).

    Examples
    --------
    >>> from are_stats.environment import shipped_path
    >>> meta, where = find_manifest(shipped_path("courtyard_traffic", "log"))
    >>> where.endswith("courtyard_traffic.yaml"), "window" in meta
    (True, True)
    """
    path = Path(path)
    if manifest is None:
        cands = [path.with_suffix(".yaml"), path.with_suffix(".yml")]
        found = next((c for c in cands if c.exists()), None)
        meta = read_manifest(found) if found is not None else {}
        mpath = str(found) if found is not None else f"{path.with_suffix('.yaml')} (not found)"
        return meta, mpath
    return read_manifest(manifest), str(manifest)


def lifecycle_log_from_frame(
    frame: pd.DataFrame,
    window: tuple[float, float],
    area: float | None = None,
    source: str = "<frame>",
    min_lifetime: float = 0.0,
    *,
    time_step: float | None = None,
    clock_start: str | None = None,
) -> LifecycleLog:
    """Validate an in-memory life-cycle table (e.g. from :func:`tracks_to_lifecycle`).

    Parameters
    ----------
    frame : pandas.DataFrame
        Columns as in :func:`read_lifecycle_log`; NaN / None cells are empty cells.
    window : (float, float)
        Observation window in seconds.
    area : float, optional
        Free area in m^2.
    source : str
        Name used in error messages.
    min_lifetime : float
        Complete lifetimes shorter than this are excluded (and counted).
    time_step : float, optional
        Sampling step of the times in seconds: times up to one step outside the window are
        clipped onto its edge (default: only rounding errors, :data:`WINDOW_RTOL`).
    clock_start : str, optional
        Wall-clock time of ``t = 0`` (ISO 8601).

    Returns
    -------
    LifecycleLog
    """
    raw = frame_table(frame, source, "life-cycle log")
    if raw.n_rows == 0:
        raise InputError(source, "empty life-cycle log", "at least one row", Described("none"))
    win = _window("window", "", window, 1.0)
    a = None if area is None else get_float(area, "area", "", lo=0.0, lo_open=True)
    min_life = get_float(min_lifetime, "min_lifetime", "", lo=0.0)
    resolved: ResolvedManifest = {
        "window": list(win),
        "area": a,
        "time_unit": "s",
        "area_unit": "m^2",
        "min_lifetime": min_life,
    }
    tol = window_tolerance(win)
    if time_step is not None:
        resolved["time_step"] = get_float(time_step, "time_step", "", lo=0.0, lo_open=True)
        tol = max(tol, resolved["time_step"])
    if clock_start is not None:
        resolved["clock_start"] = _clock_start("clock_start", "", clock_start)
    return _validate(raw, win, a, min_life, 1.0, source, resolved, tol)


#: Relative tolerance of the window check: times within ``WINDOW_RTOL * max(|t0|, |t1|,
#: t1 - t0)`` outside the window are rounding errors (``215.60000000000002`` for a window
#: ending at ``215.6``) and are clipped onto its edge; times further out are errors. When the
#: sampling step of the times is known (manifest ``time_step``, or the tracker's step for a
#: log made from tracks) the tolerance is one step.
WINDOW_RTOL = 1e-9


def window_tolerance(win: tuple[float, float]) -> float:
    """Absolute tolerance of the window check for window ``win`` (see :data:`WINDOW_RTOL`)."""
    t0, t1 = win
    return WINDOW_RTOL * max(abs(t0), abs(t1), t1 - t0)


def _blank_rows(raw: RawTable) -> np.ndarray:
    blank = np.ones(raw.n_rows, dtype=bool)
    for s in raw.strings.values():
        blank &= s == ""
    for _, null in raw.numbers.values():
        blank &= null
    return blank


def _validate(
    raw: RawTable,
    win: tuple[float, float],
    area: float | None,
    min_life: float,
    scale: float,
    source: str,
    manifest: ResolvedManifest,
    tol: float,
) -> LifecycleLog:
    raw.require(_REQUIRED, "life-cycle log")
    if ("x_exit" in raw.columns) != ("y_exit" in raw.columns):
        raw.require(["x_exit", "y_exit"], "life-cycle log with exit positions")
    n = raw.n_rows
    blank = _blank_rows(raw)
    keep = ~blank
    if not keep.any():
        raise ValueError(
            f"{raw.path}: empty life-cycle log: expected at least one data row, "
            f"got {n} blank row(s)"
        )
    sub = raw.subset(keep)
    err = sub.error

    ids = sub.ids("id")
    ta, trunc = sub.floats("t_arrive", allow_empty=True)
    tl, cens = sub.floats("t_leave", allow_empty=True)
    ta = ta * scale
    tl = tl * scale
    m = len(ids)
    label = sub.class_labels("label") if "label" in sub.columns else np.full(m, "", dtype=object)
    if "mark" in sub.columns:
        mark, _ = sub.nonneg_ints("mark", allow_empty=True)
    else:
        mark = np.full(m, -1, dtype=np.int64)
    pose = {}
    for c in ("x", "y", "yaw", "x_exit", "y_exit"):
        pose[c] = sub.floats(c, allow_empty=True)[0] if c in sub.columns else np.full(m, np.nan)
    if "group" in sub.columns:
        group = sub.ids("group", allow_empty=True)
    else:
        group = np.full(m, "", dtype=object)
    t0, t1 = win
    wtxt = f"the window [{t0 / scale:g}, {t1 / scale:g}]"
    for name, vals, empty in (("t_arrive", ta, trunc), ("t_leave", tl, cens)):
        bad = ~empty & ((vals < t0 - tol) | (vals > t1 + tol))
        if bad.any():
            i = int(np.argmax(bad))
            raise err(
                i, name, f"a time inside {wtxt}", f"{float(vals[i] / scale)!r} (outside the window)"
            )
        # times a rounding error outside the window are on its edge
        np.clip(vals, t0, t1, out=vals, where=~empty)
    order = ~trunc & ~cens & (tl < ta)
    if order.any():
        i = int(np.argmax(order))
        raise err(
            i,
            "t_leave",
            f"t_leave >= t_arrive ({float(ta[i] / scale)!r})",
            f"{float(tl[i] / scale)!r} (t_leave < t_arrive)",
        )
    seen: dict[str, int] = {}
    for i, v in enumerate(ids):
        if v in seen:
            raise err(
                i,
                "id",
                f"a unique id (already used in {sub.where(seen[v])})",
                f"duplicate id {v!r}",
            )
        seen[v] = i
    short = ~trunc & ~cens & ((tl - ta) < min_life)
    excluded = {"blank_row": int(blank.sum()), "shorter_than_min_lifetime": int(short.sum())}
    k = ~short
    table = pd.DataFrame(
        {
            "id": pd.array(ids[k].astype(str), dtype="str"),
            "t_arrive": ta[k],
            "t_leave": tl[k],
            "label": pd.array(label[k].astype(str), dtype="str"),
            "mark": mark[k],
            "x": pose["x"][k],
            "y": pose["y"][k],
            "yaw": pose["yaw"][k],
            "group": pd.array(group[k].astype(str), dtype="str"),
            "x_exit": pose["x_exit"][k],
            "y_exit": pose["y_exit"][k],
            "truncated": trunc[k],
            "censored": cens[k],
        }
    )
    if table.empty:
        raise ValueError(
            f"{raw.path}: expected at least one artefact after exclusions, got none ({excluded})"
        )
    columns = tuple(c for c in LIFECYCLE_COLUMNS if c in sub.columns)
    return LifecycleLog(
        table, (float(t0), float(t1)), area, source, excluded, manifest, columns=columns
    )
