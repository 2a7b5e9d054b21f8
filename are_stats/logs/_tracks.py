"""Tracker output (``id, t, x, y``) to a life-cycle log: first/last sighting per artefact.

A tracker reports sightings of tracked objects. An artefact's life cycle (Sect. 3.2) is
read off its track: it arrives at its first sighting and leaves at its last one. Gaps in a
track shorter than ``gap_tolerance`` are occlusions and are merged; longer gaps split the
track into separate artefacts (ids suffixed ``#1``, ``#2``, ...). Tracks that touch the
window edges are censored (DECISIONS 3): first seen within ``edge_tolerance`` of ``t0``
means already present (left-truncated, empty ``t_arrive``), last seen within
``edge_tolerance`` of ``t1`` means still present (right-censored, empty ``t_leave``).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pandas as pd

from are_stats.inputs import Described, InputError, get_float, get_int, get_list
from are_stats.logs._table import RawTable, frame_table, read_raw_table

__all__ = ["TRACK_COLUMNS", "read_tracks", "tracks_to_lifecycle", "validate_tracks"]

#: Columns of a tracks table (``id, t, x, y`` required; ``label``, ``yaw`` optional).
TRACK_COLUMNS = ("id", "t", "x", "y", "label", "yaw")


def _from_raw(raw: RawTable) -> pd.DataFrame:
    raw.require(["id", "t", "x", "y"], "tracks table")
    out: dict[str, Any] = {"id": raw.ids("id")}
    for c in ("t", "x", "y"):
        out[c] = raw.floats(c, allow_empty=False)[0]
    out["label"] = (
        raw.class_labels("label")
        if "label" in raw.columns
        else np.full(raw.n_rows, "", dtype=object)
    )
    out["yaw"] = (
        raw.floats("yaw", allow_empty=True)[0]
        if "yaw" in raw.columns
        else np.full(raw.n_rows, np.nan)
    )
    df = pd.DataFrame(out)
    df["id"] = df["id"].astype("str")
    df["label"] = df["label"].astype("str")
    return df


def read_tracks(path: str | os.PathLike) -> pd.DataFrame:
    """Read a tracks table (CSV or Parquet): one row per sighting.

    Parameters
    ----------
    path : str or PathLike
        Columns ``id`` (track id), ``t`` (seconds), ``x``, ``y`` (metres, map frame) and
        optional ``label`` and ``yaw`` (radians).

    Returns
    -------
    pandas.DataFrame
        Columns ``id`` (str), ``t``, ``x``, ``y`` (float64), ``label`` (str, ``""`` when
        absent), ``yaw`` (float64, NaN when absent), in file order.

    Raises
    ------
    FileNotFoundError
        If the file is missing.
    ValueError
        Naming file, row and column for missing columns, non-numeric or NaN cells, empty
        ids and empty files.
    """
    return _from_raw(read_raw_table(path, "tracks table"))


def validate_tracks(tracks: pd.DataFrame, name: str = "tracks") -> pd.DataFrame:
    """Check an in-memory tracks table and return it in canonical form (see :func:`read_tracks`).

    Raises
    ------
    ValueError
        As :func:`read_tracks`, with ``name`` in place of the file.
    """
    raw = frame_table(tracks, name, "tracks table")
    if raw.n_rows == 0:
        raise InputError(name, "empty tracks table", "at least one sighting", Described("none"))
    df = _from_raw(raw)
    extra = [c for c in tracks.columns if c not in df.columns]
    for c in extra:
        df[c] = tracks[c].to_numpy()
    return df


def tracks_to_lifecycle(
    tracks: pd.DataFrame,
    window: tuple[float, float] | None = None,
    gap_tolerance: float = 2.0,
    edge_tolerance: float | None = None,
    min_sightings: int = 1,
) -> pd.DataFrame:
    """Convert sightings to a life-cycle log (first/last sighting per artefact).

    Parameters
    ----------
    tracks : pandas.DataFrame
        Sightings with columns ``id``, ``t``, ``x``, ``y`` and optional ``label``, ``yaw``
        (as returned by :func:`read_tracks` or :func:`read_tracks_bag`).
    window : (float, float), optional
        Observation window ``(t0, t1)``; default: first to last sighting of the table.
        Sightings outside the window are left out and counted.
    gap_tolerance : float
        Gaps between consecutive sightings of one track up to this long are merged; longer
        gaps split the track into artefacts ``<id>#1``, ``<id>#2``, ...
    edge_tolerance : float, optional
        A segment first seen at or before ``t0 + edge_tolerance`` is left-truncated (empty
        ``t_arrive``); last seen at or after ``t1 - edge_tolerance`` right-censored (empty
        ``t_leave``). Default: ``gap_tolerance``.
    min_sightings : int
        Segments with fewer sightings are left out (tracker flicker) and counted.

    Returns
    -------
    pandas.DataFrame
        Life-cycle log columns ``id``, ``t_arrive``, ``t_leave`` (NaN when truncated /
        censored), ``label`` (most frequent label of the segment, ties to the first),
        ``x``, ``y`` (first sighting), ``yaw`` (the ``yaw`` column at the first sighting if
        given, else the heading from the first to the second sighting, NaN when it did not
        move), ``n_sightings``; sorted by first sighting. ``attrs["excluded"]`` counts
        ``outside_window`` sightings and ``too_few_sightings`` segments; ``attrs["window"]``
        holds the window used.

    Raises
    ------
    ValueError
        On malformed tracks or arguments.

    Examples
    --------
    >>> tr = pd.DataFrame({"id": ["a", "a", "a"], "t": [0.0, 1.0, 9.0],
    ...                    "x": [0.0, 1.0, 1.0], "y": [0.0, 0.0, 0.0]})
    >>> out = tracks_to_lifecycle(tr, window=(0, 20), gap_tolerance=2.0)
    >>> out["id"].tolist(), out["t_arrive"].tolist(), out["t_leave"].tolist()
    (['a#1', 'a#2'], [nan, 9.0], [1.0, 9.0])
    """
    df = validate_tracks(tracks)
    gap = get_float(gap_tolerance, "gap_tolerance", "", lo=0.0)
    edge = (
        gap if edge_tolerance is None else get_float(edge_tolerance, "edge_tolerance", "", lo=0.0)
    )
    min_sightings = get_int(min_sightings, "min_sightings", "", lo=1)
    t_all = df["t"].to_numpy()
    if window is None:
        t0, t1 = float(t_all.min()), float(t_all.max())
    else:
        if isinstance(window, np.ndarray):
            window = window.tolist()
        pair = get_list(window, "window", "", min_len=2, max_len=2)
        t0 = get_float(pair[0], "window", "[0]")
        t1 = get_float(pair[1], "window", "[1]")
        if not t1 > t0:
            raise InputError("window", "", "(t0, t1) with t0 < t1", Described(f"({t0!r}, {t1!r})"))
    inside = (t_all >= t0) & (t_all <= t1)
    excluded = {"outside_window": int((~inside).sum()), "too_few_sightings": 0}
    df = df[inside]
    cols = ["id", "t_arrive", "t_leave", "label", "x", "y", "yaw", "n_sightings"]
    if df.empty:
        out = pd.DataFrame({c: [] for c in cols})
        out.attrs.update(excluded=excluded, window=(t0, t1))
        return out

    ids = df["id"].to_numpy(dtype=object)
    codes, uniq = pd.factorize(ids, sort=True)
    t = df["t"].to_numpy()
    order = np.lexsort((t, codes))
    codes, t = codes[order], t[order]
    x = df["x"].to_numpy()[order]
    y = df["y"].to_numpy()[order]
    yaw_col = df["yaw"].to_numpy()[order]
    labels = df["label"].to_numpy(dtype=object)[order]
    n = len(t)
    new = np.ones(n, dtype=bool)
    new[1:] = (codes[1:] != codes[:-1]) | (np.diff(t) > gap)
    first = np.flatnonzero(new)
    last = np.r_[first[1:] - 1, n - 1]
    seg = np.cumsum(new) - 1
    n_sight = last - first + 1
    # suffixes for tracks split by long gaps
    seg_code = codes[first]
    n_segs = np.bincount(seg_code)
    k_in_track = np.arange(len(first)) - np.searchsorted(seg_code, seg_code)
    base = np.asarray(uniq, dtype=object)[seg_code]
    seg_ids = np.array(
        [
            b if n_segs[c] == 1 else f"{b}#{k + 1}"
            for b, c, k in zip(base, seg_code, k_in_track, strict=True)
        ],
        dtype=object,
    )
    # majority label per segment (ties: the label seen first)
    lab_codes, lab_uniq = pd.factorize(labels)
    counts = pd.DataFrame({"seg": seg, "lab": lab_codes, "pos": np.arange(n)})
    agg = counts.groupby(["seg", "lab"], sort=False).agg(n=("pos", "size"), p=("pos", "min"))
    agg = agg.reset_index().sort_values(["seg", "n", "p"], ascending=[True, False, True])
    best = agg.drop_duplicates("seg").set_index("seg")["lab"].reindex(np.arange(len(first)))
    seg_label = np.asarray(lab_uniq, dtype=object)[best.to_numpy()]
    # heading at arrival
    yaw = yaw_col[first].copy()
    has_next = n_sight > 1
    dx = np.where(has_next, x[np.minimum(first + 1, n - 1)] - x[first], 0.0)
    dy = np.where(has_next, y[np.minimum(first + 1, n - 1)] - y[first], 0.0)
    moved = np.hypot(dx, dy) > 0
    fill = np.isnan(yaw) & moved
    yaw[fill] = np.arctan2(dy[fill], dx[fill])
    t_first, t_last = t[first], t[last]
    t_arr = np.where(t_first <= t0 + edge, np.nan, t_first)
    t_lea = np.where(t_last >= t1 - edge, np.nan, t_last)
    out = pd.DataFrame(
        {
            "id": pd.array(seg_ids.astype(str), dtype="str"),
            "t_arrive": t_arr,
            "t_leave": t_lea,
            "label": pd.array(seg_label.astype(str), dtype="str"),
            "x": x[first],
            "y": y[first],
            "yaw": yaw,
            "n_sightings": n_sight.astype(np.int64),
        }
    )
    keep = n_sight >= int(min_sightings)
    excluded["too_few_sightings"] = int((~keep).sum())
    out = out[keep]
    out = out.iloc[
        np.lexsort((out["id"].to_numpy(dtype=object).astype(str), t_first[keep]))
    ].reset_index(drop=True)
    out.attrs.update(excluded=excluded, window=(t0, t1))
    return out
