"""One entry point for field logs: a life-cycle log or a tracks table, told apart by columns.

Users hand ``are-stats fit`` whatever their pipeline produced: a life-cycle log (one row per
artefact, ``id, t_arrive, t_leave, ...``) or a tracker's output (one row per sighting,
``id, t, x, y [, label]``). :func:`read_field_log` reads either, turns a tracks table into
life-cycles with :func:`are_stats.logs.tracks_to_lifecycle` (groups inferred, entry and exit
points kept) and applies the same manifest to both.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Unpack, cast

import pandas as pd

from are_stats.inputs import Described, InputError
from are_stats.logs._lifecycle_log import (
    TIME_UNITS,
    LifecycleLog,
    ManifestOverrides,
    _lifecycle_from_raw,
    _resolve_settings,
    _validate,
    find_manifest,
    window_tolerance,
)
from are_stats.logs._table import RawTable, frame_table, read_raw_table
from are_stats.logs._tracks import _from_raw, tracks_to_lifecycle

if TYPE_CHECKING:
    from are_stats.logs._lifecycle_log import LifecycleManifest

__all__ = [
    "FieldLogOptions",
    "LIFECYCLE_KIND_COLUMNS",
    "TRACK_OPTIONS",
    "TRACKS_KIND_COLUMNS",
    "read_field_log",
    "read_field_tracks",
]

#: Columns that make a table a life-cycle log.
LIFECYCLE_KIND_COLUMNS = ("id", "t_arrive", "t_leave")
#: Columns that make a table a tracks table.
TRACKS_KIND_COLUMNS = ("id", "t", "x", "y")
#: Keyword options of :func:`read_field_log` passed on to :func:`tracks_to_lifecycle`.
TRACK_OPTIONS = (
    "gap_tolerance",
    "edge_tolerance",
    "min_sightings",
    "group_time",
    "group_distance",
    "time_step",
)


def _open(
    p: Path, manifest: str | os.PathLike | None
) -> tuple[LifecycleManifest, str, RawTable, bool, bool]:
    """Manifest (and its path), raw table, and which kind of field log the columns say."""
    meta, mpath = find_manifest(p, manifest)
    raw = read_raw_table(p, "field log (life-cycle log or tracks table)")
    cols = set(raw.columns)
    return (meta, mpath, raw, set(LIFECYCLE_KIND_COLUMNS) <= cols, set(TRACKS_KIND_COLUMNS) <= cols)


class FieldLogOptions(ManifestOverrides, total=False):
    """The keywords of :func:`read_field_log`: the manifest's overrides
    (:class:`~are_stats.logs.ManifestOverrides`) and, for a tracks table, the options of
    :func:`~are_stats.logs.tracks_to_lifecycle` (:data:`TRACK_OPTIONS`; None: the
    default)."""

    gap_tolerance: float | None
    edge_tolerance: float | None
    min_sightings: float | None
    group_time: float | None
    group_distance: float | None
    time_step: float | None


def read_field_log(path: str | os.PathLike, **options: Unpack[FieldLogOptions]) -> LifecycleLog:
    """Read a field log, a life-cycle log or a tracks table, detected from its columns.

    Parameters
    ----------
    path : str or PathLike
        A CSV (``.csv``, ``.tsv``, ``.txt``) or Parquet (``.parquet``, ``.pq``) table.
        With columns ``id, t_arrive, t_leave`` it is a life-cycle log, read as
        :func:`are_stats.logs.read_lifecycle_log` reads it; with columns ``id, t, x, y``
        (optional ``label``, ``yaw``) it is a tracks table, converted by
        :func:`are_stats.logs.tracks_to_lifecycle`: first and last sightings become
        arrival / entry point and leaving / exit point, groups are inferred, a single
        sighting stays one sampling step.
    manifest : str or PathLike, optional
        The YAML manifest (see :func:`are_stats.logs.read_manifest`); by default
        ``<stem>.yaml`` (or ``.yml``) beside the table, if any. It applies to both kinds:
        ``window``, ``area`` / ``map``, ``time_unit`` (the unit of ``t`` of a tracks
        table too), ``time_step``, ``min_lifetime``, ``clock_start``. A tracks table
        without a window in the manifest or ``window=`` is observed from its first to its
        last sighting.
    window : (float, float), optional
        Observation window ``(t0, t1)`` in the table's time unit; overrides the manifest.
    area : float, optional
        Free area in m^2; overrides the manifest's ``area`` / ``map``.
    clock_start : str, optional
        Wall-clock time of ``t = 0`` (ISO 8601); overrides the manifest's ``clock_start``.
    gap_tolerance, edge_tolerance, min_sightings, group_time, group_distance, time_step
        Floats, optional. For a tracks table only (:class:`FieldLogOptions`): the options of
        :func:`are_stats.logs.tracks_to_lifecycle` (times in seconds). ``None`` means the
        default. ``time_step`` defaults to the manifest's ``time_step``, else the
        tracker's median step.

    Returns
    -------
    LifecycleLog
        For a tracks table, ``conversion`` holds the conversion counts and settings (also
        under ``"tracks"`` in :meth:`LifecycleLog.report`, with the sightings left out) and
        the table has the ``group``, ``x_exit``, ``y_exit`` columns.

    Raises
    ------
    FileNotFoundError
        If the table, an explicit manifest or the manifest's map is missing.
    InputError
        If the columns are neither kind's (naming the file and both column sets), a track
        option is unknown or given for a life-cycle log, and for every malformed cell,
        naming file, row and column.

    Warns
    -----
    UserWarning
        When gaps split a tracks table's tracks into many more artefacts than track ids
        (the message names the file and the numbers).

    Examples
    --------
    >>> log = read_field_log("field/courtyard_tracks.csv", area=450.0)  # doctest: +SKIP
    >>> log.report()["groups"]  # doctest: +SKIP
    """
    p = Path(path)
    keys = ManifestOverrides.__optional_keys__
    overrides = cast(ManifestOverrides, {k: v for k, v in options.items() if k in keys})
    track_options = {k: v for k, v in options.items() if k not in overrides}
    unknown = sorted(k for k in track_options if k not in TRACK_OPTIONS)
    if unknown:
        raise InputError(
            "track options",
            unknown[0],
            f"one of {', '.join(TRACK_OPTIONS)}",
            Described("an unknown option"),
        )
    given = {k: v for k, v in track_options.items() if v is not None}
    meta, mpath, raw, is_life, is_tracks = _open(p, overrides.get("manifest"))
    kinds = (
        f"a life-cycle log (columns {', '.join(LIFECYCLE_KIND_COLUMNS)}, ...) or a tracks "
        f"table (columns {', '.join(TRACKS_KIND_COLUMNS)} [, label])"
    )
    got = ", ".join(repr(c) for c in raw.columns) or "(none)"
    if is_life == is_tracks:
        what = "both" if is_life else "neither"
        raise InputError(p, "columns", kinds, Described(f"columns {got} ({what})"))
    if is_life:
        if given:
            name = next(iter(given))
            raise InputError(
                name, "", "a tracks table to apply to", Described(f"the life-cycle log {p}")
            )
        return _lifecycle_from_raw(raw, p, meta, mpath, overrides)

    tracks = _from_raw(raw)
    scale = TIME_UNITS[str(meta.get("time_unit", "s"))]
    window = overrides.get("window")
    if window is None and "window" not in meta:
        t = tracks["t"].to_numpy()
        window = (float(t.min()), float(t.max()))
        if not window[1] > window[0]:
            raise InputError(
                mpath,
                "window",
                "the observation window [t0, t1] in the manifest or as window=(t0, t1) "
                "(a tracks table seen at one time only has no window of its own)",
                Described("nothing"),
            )
    win, a, min_life, resolved = _resolve_settings(meta, mpath, {**overrides, "window": window})
    tracks["t"] = tracks["t"] * scale
    if "time_step" in resolved:
        given.setdefault("time_step", resolved["time_step"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = tracks_to_lifecycle(tracks, window=win, **given)
    for w in caught:  # said again naming the file, at the caller
        warnings.warn(f"{p}: {w.message}", w.category, stacklevel=2)
    info = dict(out.attrs["tracks"])
    info["excluded"] = dict(out.attrs["excluded"])
    resolved["input"] = "tracks table"
    if out.empty:
        raise InputError(
            p,
            "",
            "at least one artefact after converting the tracks",
            Described(f"none ({info['excluded']})"),
        )
    step = info["sampling_step"]
    tol = max(window_tolerance(win), step)
    log = _validate(
        frame_table(out, str(p), "life-cycle log"), win, a, min_life, 1.0, str(p), resolved, tol
    )
    return dataclasses.replace(log, conversion=info, tracks=tracks)


def read_field_tracks(
    path: str | os.PathLike, *, manifest: str | os.PathLike | None = None
) -> pd.DataFrame | None:
    """The tracks of a field log that is a tracks table (None for a life-cycle log).

    The behaviour fit reads the motion of the tracks that :func:`read_field_log` turned
    into life-cycles: the same table, validated the same way, with ``t`` in seconds (the
    manifest's ``time_unit``).

    Parameters
    ----------
    path : str or PathLike
        The field log.
    manifest : str or PathLike, optional
        As :func:`read_field_log`.

    Returns
    -------
    pandas.DataFrame or None
        ``id, t, x, y, label, yaw`` (see :func:`are_stats.logs.read_tracks`).
    """
    meta, _, raw, is_life, is_tracks = _open(Path(path), manifest)
    if is_life or not is_tracks:
        return None
    tracks = _from_raw(raw)
    tracks["t"] = tracks["t"] * TIME_UNITS[str(meta.get("time_unit", "s"))]
    return tracks
