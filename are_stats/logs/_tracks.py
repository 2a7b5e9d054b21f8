"""Tracker output (``id, t, x, y``) to a life-cycle log: first/last sighting per artefact.

A tracker reports sightings of tracked objects. An artefact's life cycle (Sect. 3.2) is
read off its track: it arrives at its first sighting (its entry point) and leaves at its
last one (its exit point). Gaps in a track shorter than ``gap_tolerance`` are occlusions
and are merged; longer gaps split the track into separate artefacts (ids suffixed ``#1``,
``#2``, ...; a warning says so when many tracks split). Tracks that touch the window edges
are censored (DECISIONS 3): first seen within ``edge_tolerance`` of ``t0`` means already
present (left-truncated, empty ``t_arrive``), last seen within ``edge_tolerance`` of ``t1``
means still present (right-censored, empty ``t_leave``).

Artefacts that arrive together (people walking in a group) are found as connected
components of the relation "first seen within ``group_time`` and ``group_distance`` of each
other and moving together" (see :func:`tracks_to_lifecycle`).
"""

from __future__ import annotations

import itertools
import os
import warnings

import numpy as np
import pandas as pd

from are_stats.inputs import Described, InputError, check_work, get_float, get_int, get_list
from are_stats.logs._table import RawTable, frame_table, read_raw_table

__all__ = [
    "GROUP_DISTANCE",
    "GROUP_HORIZON_STEPS",
    "GROUP_TIME_STEPS",
    "MAX_COORDINATE",
    "MAX_TIME",
    "TRACK_COLUMNS",
    "read_tracks",
    "sampling_step",
    "track_groups",
    "tracks_to_lifecycle",
    "validate_tracks",
]

#: Columns of a tracks table (``id, t, x, y`` required; ``label``, ``yaw`` optional).
TRACK_COLUMNS = ("id", "t", "x", "y", "label", "yaw")

#: Largest map coordinate (metres) a tracks table may hold: beyond any real map (UTM
#: northings are below 1e7 m), it catches corrupted cells such as ``1e300``.
MAX_COORDINATE = 1e9
#: Largest time (s) a tracks table may hold: 1e12 s is about 31,700 years (epoch seconds
#: are 1.8e9; a clock in ns or us must be converted first).
MAX_TIME = 1e12
#: Default ``group_time`` of :func:`tracks_to_lifecycle`, in sampling steps.
GROUP_TIME_STEPS = 1.5
#: Default ``group_distance`` of :func:`tracks_to_lifecycle`, in metres.
GROUP_DISTANCE = 1.5
#: Candidate group members must move together over this many sampling steps after the
#: later of their first sightings (at most 2 x ``group_distance`` apart at common times).
GROUP_HORIZON_STEPS = 10
#: A warning is given when gaps split the tracks into more than this many artefacts per
#: track id, or split more than :data:`_SPLIT_FRACTION` of the track ids.
_SPLIT_RATIO = 1.5
_SPLIT_FRACTION = 0.1
# members of each nearby component checked first against a new segment (group inference)
_FIRST_LOOK = 4


def _from_raw(raw: RawTable) -> pd.DataFrame:
    raw.require(["id", "t", "x", "y"], "tracks table")
    out: dict[str, np.ndarray] = {"id": raw.ids("id")}
    for c in ("t", "x", "y"):
        out[c] = raw.floats(c, allow_empty=False)[0]
    for c in ("x", "y"):
        far = np.abs(out[c]) > MAX_COORDINATE
        if far.any():
            i = int(np.argmax(far))
            raise raw.error(
                i,
                c,
                f"a map coordinate within +-{MAX_COORDINATE:g} m",
                f"{float(out[c][i])!r}",
            )
    late = np.abs(out["t"]) > MAX_TIME  # (sums of such times overflow)
    if late.any():
        i = int(np.argmax(late))
        raise raw.error(
            i,
            "t",
            f"a time within +-{MAX_TIME:g} s (seconds: convert ns or us clocks)",
            f"{float(out['t'][i])!r}",
        )
    _check_unique_sightings(raw, out["id"], out["t"], out["x"], out["y"])
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


def _check_unique_sightings(
    raw: RawTable, ids: np.ndarray, t: np.ndarray, x: np.ndarray, y: np.ndarray
) -> None:
    """One sighting per ``(id, t)``: a second row for the same id and time is an error.

    A tracker reports each object at most once per frame; two rows for one id at one time
    (the same position or not) mean a damaged or concatenated table, and collapsing them
    would hide it (a one-point track seen "twice" would even look like a real stay). The
    error names the later row, the id, the time and the earlier row. Sort and sweep:
    ``O(n log n)``.
    """
    codes, _ = pd.factorize(ids)
    order = np.lexsort((np.arange(len(t)), t, codes))
    c, tt = codes[order], t[order]
    same = (c[1:] == c[:-1]) & (tt[1:] == tt[:-1])
    if not same.any():
        return
    # the first offending row in file order, and the earlier row it repeats
    later = order[1:][same]
    earlier = order[:-1][same]
    k = int(np.argmin(later))
    i, j = int(later[k]), int(earlier[k])
    what = (
        "the same position"
        if x[i] == x[j] and y[i] == y[j]
        else f"another position ({float(x[j])!r}, {float(y[j])!r})"
    )
    raise raw.error(
        i,
        "t",
        "one sighting per (id, t)",
        f"id {str(ids[i])!r} seen twice at t={float(t[i])!r}: {raw.where(j)} has {what}",
    )


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
        ids, empty files, coordinates beyond :data:`MAX_COORDINATE` and a second sighting
        of one id at one time (duplicate ``(id, t)`` rows are never collapsed: the error
        names the row, the id, the time and the earlier row, and whether the positions
        agree).
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


def sampling_step(tracks: pd.DataFrame, gap_tolerance: float | None = None) -> float | None:
    """The tracker's sampling step: the median positive time difference within tracks.

    Parameters
    ----------
    tracks : pandas.DataFrame
        Sightings with columns ``id``, ``t``, ``x``, ``y`` (see :func:`read_tracks`).
    gap_tolerance : float, optional
        Differences longer than this are gaps, not steps, and are left out (unless every
        difference is one).

    Returns
    -------
    float or None
        The step in seconds; None when no track has two sightings at different times.

    Examples
    --------
    >>> tr = pd.DataFrame({"id": ["a", "a", "a", "b", "b"], "t": [0.0, 0.4, 0.8, 5.0, 5.4],
    ...                    "x": 0.0, "y": 0.0})
    >>> round(sampling_step(tr), 9)
    0.4
    """
    df = validate_tracks(tracks)
    if gap_tolerance is not None:
        gap_tolerance = get_float(gap_tolerance, "gap_tolerance", "", lo=0.0)
    return _sampling_step(df, gap_tolerance)


def _sampling_step(tracks: pd.DataFrame, gap_tolerance: float | None) -> float | None:
    codes, _ = pd.factorize(tracks["id"].to_numpy(dtype=object))
    t = tracks["t"].to_numpy(dtype=np.float64)
    order = np.lexsort((t, codes))
    codes, t = codes[order], t[order]
    d = np.diff(t)
    d = d[(codes[1:] == codes[:-1]) & (d > 0) & np.isfinite(d)]
    if gap_tolerance is not None and (d <= gap_tolerance).any():
        d = d[d <= gap_tolerance]
    return float(np.median(d)) if d.size else None


def tracks_to_lifecycle(
    tracks: pd.DataFrame,
    window: tuple[float, float] | None = None,
    gap_tolerance: float = 2.0,
    edge_tolerance: float | None = None,
    min_sightings: int = 1,
    *,
    group_time: float | None = None,
    group_distance: float | None = None,
    time_step: float | None = None,
) -> pd.DataFrame:
    """Convert sightings to a life-cycle log (first/last sighting per artefact, groups):
    the tracker's ids split at long gaps, sightings outside the window left out.

    Parameters
    ----------
    tracks : pandas.DataFrame
        Sightings with columns ``id``, ``t``, ``x``, ``y`` and optional ``label``, ``yaw``
        (as returned by :func:`read_tracks` or :func:`read_tracks_bag`).
    window : (float, float), optional
        Observation window ``(t0, t1)``; default: first to last sighting of the table.
        Sightings up to one sampling step outside the window are clipped onto its edge
        (``215.60000000000002`` is on a window ending at ``215.6``); sightings further out
        are left out and counted.
    gap_tolerance : float
        Gaps between consecutive sightings of one track up to this long are merged; longer
        gaps split the track into artefacts ``<id>#1``, ``<id>#2``, ... When that makes
        more than 1.5 artefacts per track id, or splits more than 10% of the ids, a
        ``UserWarning`` names the numbers (raise ``gap_tolerance`` if the gaps are
        occlusions).
    edge_tolerance : float, optional
        A segment first seen at or before ``t0 + edge_tolerance`` is left-truncated (empty
        ``t_arrive``); last seen at or after ``t1 - edge_tolerance`` right-censored (empty
        ``t_leave``). Default: ``gap_tolerance``.
    min_sightings : int
        Segments with fewer sightings are left out (tracker flicker) and counted.
    group_time : float, optional
        Artefacts first seen at most this long apart (seconds) may be one group. Default:
        1.5 sampling steps (:data:`GROUP_TIME_STEPS`), so members first seen in the same or
        the next frame qualify.
    group_distance : float, optional
        ... and at most this far apart (metres) at their first sightings. Default 1.5 m
        (:data:`GROUP_DISTANCE`). They are one group when they also move together: at the
        times both are seen during the :data:`GROUP_HORIZON_STEPS` sampling steps after
        the later first sighting (times matched within half a step), they stay within
        ``2 * group_distance`` of each other; with fewer than two such common times the
        first-sighting proximity suffices. Groups are the connected components of this
        relation. ``group_distance=0`` turns group inference off.
    time_step : float, optional
        The tracker's sampling step in seconds. Default: :func:`sampling_step`, the median
        positive time difference within tracks (gaps left out).

    Returns
    -------
    pandas.DataFrame
        Life-cycle log columns ``id``, ``t_arrive``, ``t_leave`` (NaN when truncated /
        censored), ``label`` (most frequent label of the segment, ties to the first),
        ``x``, ``y`` (first sighting: the entry point), ``yaw`` (the ``yaw`` column at the
        first sighting if given, else the heading from the first to the second sighting,
        NaN when it did not move), ``x_exit``, ``y_exit`` (last sighting: the exit point;
        NaN when censored), ``group`` (the id of the group's first member, ``""`` when
        alone), ``n_sightings``; sorted by first sighting.

        A segment observed for less than one sampling step (a single sighting, or
        sightings at one time) gets a stay of one step, ``t_leave = t_first + step``: the
        tracker saw it in one frame, so it was there for about one frame; when that would
        reach past ``t1`` it is right-censored instead. No stay is ever zero.

        ``attrs["excluded"]`` counts ``outside_window`` sightings and ``too_few_sightings``
        segments; ``attrs["window"]`` holds the window used; ``attrs["tracks"]`` the
        conversion counts (``sightings``, ``track_ids``, ``artefacts``, ``split_track_ids``,
        ``groups``, ``artefacts_in_groups``) and settings (``sampling_step``,
        ``gap_tolerance``, ``group_time``, ``group_distance``).

    Raises
    ------
    ValueError
        On malformed tracks or arguments.

    Examples
    --------
    >>> tr = pd.DataFrame({"id": ["a", "a", "a", "a"], "t": [0.0, 1.0, 2.0, 9.0],
    ...                    "x": [0.0, 1.0, 2.0, 2.0], "y": [0.0, 0.0, 0.0, 0.0]})
    >>> import warnings
    >>> with warnings.catch_warnings():  # 1 track id became 2 artefacts
    ...     warnings.simplefilter("ignore")
    ...     out = tracks_to_lifecycle(tr, window=(0, 20), gap_tolerance=2.0)
    >>> out["id"].tolist(), out["t_arrive"].tolist(), out["t_leave"].tolist()
    (['a#1', 'a#2'], [nan, 9.0], [2.0, 10.0])
    """
    df = validate_tracks(tracks)
    gap = get_float(gap_tolerance, "gap_tolerance", "", lo=0.0)
    edge = (
        gap if edge_tolerance is None else get_float(edge_tolerance, "edge_tolerance", "", lo=0.0)
    )
    min_sightings = get_int(min_sightings, "min_sightings", "", lo=1)
    if time_step is None:
        step = _sampling_step(df, gap)
        if step is None:  # no track seen twice: the table's own time resolution, else 1 s
            u = np.diff(np.unique(df["t"].to_numpy()))
            u = u[np.isfinite(u)]
            step = float(np.median(u)) if u.size else 1.0
    else:
        step = get_float(time_step, "time_step", "", lo=0.0, lo_open=True)
    g_time = (
        GROUP_TIME_STEPS * step
        if group_time is None
        else get_float(group_time, "group_time", "", lo=0.0)
    )
    g_dist = (
        GROUP_DISTANCE
        if group_distance is None
        else get_float(group_distance, "group_distance", "", lo=0.0)
    )
    t_all = df["t"].to_numpy().copy()
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
    # one sampling step of tolerance at the edges (and never less than a rounding error)
    tol = max(step, 1e-9 * max(abs(t0), abs(t1), t1 - t0))
    inside = (t_all >= t0 - tol) & (t_all <= t1 + tol)
    df = df.assign(t=np.clip(t_all, t0, t1))
    excluded = {"outside_window": int((~inside).sum()), "too_few_sightings": 0}
    df = df[inside]
    info: dict[str, int | float] = {
        "sightings": int(len(df)),
        "track_ids": 0,
        "artefacts": 0,
        "split_track_ids": 0,
        "groups": 0,
        "artefacts_in_groups": 0,
        "sampling_step": float(step),
        "gap_tolerance": float(gap),
        "group_time": float(g_time),
        "group_distance": float(g_dist),
    }
    cols = [
        "id",
        "t_arrive",
        "t_leave",
        "label",
        "x",
        "y",
        "yaw",
        "x_exit",
        "y_exit",
        "group",
        "n_sightings",
    ]
    if df.empty:
        out = pd.DataFrame({c: [] for c in cols})
        out.attrs.update(excluded=excluded, window=(t0, t1), tracks=info)
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
    n_ids, n_art, n_split = len(uniq), len(first), int((n_segs > 1).sum())
    info.update(track_ids=int(n_ids), artefacts=int(n_art), split_track_ids=n_split)
    if n_art > _SPLIT_RATIO * n_ids or n_split > _SPLIT_FRACTION * n_ids:
        warnings.warn(
            f"{n_ids} track ids became {n_art} artefacts: gaps longer than "
            f"gap_tolerance={gap:g} s split {n_split} of the tracks (the sampling step is "
            f"{step:.3g} s); if the gaps are occlusions, raise gap_tolerance",
            UserWarning,
            stacklevel=2,
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
    # a segment seen for less than a step stayed about one step (never a zero stay)
    brief = t_last - t_first < step
    t_end = np.where(brief, t_first + step, t_last)
    t_arr = np.where(t_first <= t0 + edge, np.nan, t_first)
    censored = (t_last >= t1 - edge) | (t_end > t1)
    t_lea = np.where(censored, np.nan, t_end)
    x_exit = np.where(censored, np.nan, x[last])
    y_exit = np.where(censored, np.nan, y[last])
    keep = n_sight >= int(min_sightings)
    excluded["too_few_sightings"] = int((~keep).sum())
    group = _infer_groups(np.flatnonzero(keep), first, last, t, x, y, seg_ids, g_time, g_dist, step)
    sizes = pd.Series(group[group != ""]).value_counts()
    info.update(groups=int(len(sizes)), artefacts_in_groups=int(sizes.sum()))
    out = pd.DataFrame(
        {
            "id": pd.array(seg_ids.astype(str), dtype="str"),
            "t_arrive": t_arr,
            "t_leave": t_lea,
            "label": pd.array(seg_label.astype(str), dtype="str"),
            "x": x[first],
            "y": y[first],
            "yaw": yaw,
            "x_exit": x_exit,
            "y_exit": y_exit,
            "group": pd.array(group.astype(str), dtype="str"),
            "n_sightings": n_sight.astype(np.int64),
        }
    )
    out = out[keep]
    out = out.iloc[
        np.lexsort((out["id"].to_numpy(dtype=object).astype(str), t_first[keep]))
    ].reset_index(drop=True)
    out.attrs.update(excluded=excluded, window=(t0, t1), tracks=info)
    return out


def track_groups(tracks: pd.DataFrame) -> dict[str, str]:
    """The arrival group of each grouped track, as :func:`tracks_to_lifecycle` infers groups
    (people first seen together who move together).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (other columns are ignored).

    Returns
    -------
    dict of str to str
        Group label by track id as text; tracks alone and the parts of a track split at a
        gap (``<id>#k``, reported by the conversion's warning, silenced here) are left out.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> t = np.arange(0.0, 10.0, 0.5)
    >>> pair = [pd.DataFrame({"id": i, "t": t, "x": t, "y": 0.5 * i}) for i in (1, 2)]
    >>> alone = pd.DataFrame({"id": 3, "t": t + 20, "x": 0.0, "y": t})
    >>> g = track_groups(pd.concat([*pair, alone]))
    >>> sorted(g), g["1"] == g["2"]
    (['1', '2'], True)
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # split tracks: the fit reports them
        life = tracks_to_lifecycle(tracks[["id", "t", "x", "y"]])
    return {
        str(i): str(g)
        for i, g in zip(life["id"], life["group"], strict=True)
        if str(g) not in ("", "nan", "None")
    }


def _infer_groups(
    segs: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    seg_ids: np.ndarray,
    g_time: float,
    g_dist: float,
    step: float,
    stats: dict | None = None,
) -> np.ndarray:
    """Group id of every segment (the first member's id, ``""`` when alone).

    ``segs`` are the segments taking part (indices into ``first`` / ``last``, whose
    sightings ``first[k]..last[k]`` of ``t``, ``x``, ``y`` are sorted by time).

    The groups are the connected components of the relation of
    :func:`tracks_to_lifecycle` (first seen within ``g_time`` and ``g_dist``, and moving
    together: :func:`_move_together_many`), found with bounded work rather than over all
    pairs:

    * a sweep in first-sighting order keeps only the segments first seen within
      ``g_time`` before the current one, binned on a grid of cells about ``g_dist`` wide
      (so only the 3 x 3 cells around it hold candidates);
    * each cell holds its segments by component (union-find with union by size), and a
      pair whose ends are already in one component is never checked: the current segment
      is checked against at most :data:`_FIRST_LOOK` members of each other component
      first, and against the others only if none of those links.

    Tracks that start together at one spot and move together (or are seen once) cost
    O(1) checks each; the work left is the checks that can change the answer (a crowd at
    one spot whose members all part ways needs a check per pair, within ``g_time``). The
    checks are counted and held to :func:`are_stats.inputs.check_work`; ``stats``, when
    given, receives ``pair_checks`` and ``work``.
    """
    out = np.full(len(first), "", dtype=object)
    if stats is not None:
        stats.update(pair_checks=0, work=0)
    if len(segs) < 2 or g_dist <= 0:
        return out
    tf = t[first[segs]]
    order = np.argsort(tf, kind="stable")
    segs, tf = segs[order], tf[order]
    m = len(segs)
    fx, fy = x[first[segs]], y[first[segs]]
    s_lo, s_hi = first[segs], last[segs] + 1
    horizon = GROUP_HORIZON_STEPS * step
    # each segment's sightings that a check may look at: up to g_time + horizon (+ a step
    # of margin for rounding) after its first sighting; counted per segment, vectorised
    seg_of = np.repeat(np.arange(m), s_hi - s_lo)
    idx_all = _ranges(s_lo, s_hi)
    lim = tf + (g_time + horizon + step)
    n_look = np.bincount(seg_of, weights=t[idx_all] <= lim[seg_of], minlength=m).astype(np.int64)
    s_end = s_lo + n_look
    # cells at least g_dist wide (and wide enough that their indices stay exact integers)
    xmin, ymin = float(fx.min()), float(fy.min())
    span = max(float(fx.max()) - xmin, float(fy.max()) - ymin)
    width = max(g_dist * 1.01, span / 2.0**40)
    cx = np.floor((fx - xmin) / width).astype(np.int64).tolist()
    cy = np.floor((fy - ymin) / width).astype(np.int64).tolist()
    label = np.arange(m)
    members: dict[int, list[int]] = {}  # component -> its segments (those of size > 1)
    cells: dict[tuple[int, int], dict[int, set[int]]] = {}
    tf_list = tf.tolist()
    lo = 0
    work = checks = 0
    next_check = 1 << 16

    def check(cands: np.ndarray, j: int) -> np.ndarray:
        nonlocal work, checks
        d = np.hypot(fx[j] - fx[cands], fy[j] - fy[cands])
        cands = cands[d <= g_dist]
        if cands.size == 0:
            return cands
        linked, w = _move_together_many(
            cands, j, s_lo, s_end, s_hi, t, x, y, horizon, step, 2 * g_dist
        )
        checks += int(cands.size)
        work += w
        return cands[linked]

    for j in range(m):
        while not tf_list[j] <= tf_list[lo] + g_time:  # no longer within g_time
            _bucket_remove(cells, (cx[lo], cy[lo]), int(label[lo]), lo)
            lo += 1
        near = [
            cells[k]
            for k in {(cx[j] + a, cy[j] + b) for a in (-1, 0, 1) for b in (-1, 0, 1)}
            if k in cells
        ]
        comps: dict[int, list[set[int]]] = {}
        for cell in near:
            for lab, mem in cell.items():
                comps.setdefault(lab, []).append(mem)
        linked: set[int] = set()
        if comps:
            # first look: a few members of each component
            first_look = np.fromiter(
                (
                    k
                    for sets in comps.values()
                    for mem in sets
                    for k in itertools.islice(mem, _FIRST_LOOK)
                ),
                dtype=np.int64,
            )
            hit = check(first_look, j)
            linked.update(int(label[k]) for k in hit)
            rest = [lab for lab in comps if lab not in linked]
            more = [
                np.fromiter(mem, dtype=np.int64)
                for lab in rest
                for mem in comps[lab]
                if len(mem) > _FIRST_LOOK
            ]
            if more:
                cands = np.concatenate(more)
                cands = cands[~np.isin(cands, first_look)]
                work += int(cands.size)
                linked.update(int(label[k]) for k in check(cands, j))
            if work >= next_check:
                check_work(float(work), "group inference (sightings compared)", "group_time")
                next_check = 2 * work
        lab_j = j
        for lab in linked:
            lab_j = _union(lab_j, lab, label, members, cells, cx, cy, lo)
        cells.setdefault((cx[j], cy[j]), {}).setdefault(int(label[j]), set()).add(j)
    check_work(float(work), "group inference (sightings compared)", "group_time")
    if stats is not None:
        stats.update(pair_checks=checks, work=work)
    comp = np.unique(label, return_inverse=True)[1]
    sizes = np.bincount(comp)
    # the group's id: its first member's (segments are in first-sighting order)
    first_member = np.full(sizes.size, -1)
    for k in range(m - 1, -1, -1):
        first_member[comp[k]] = k
    in_group = sizes[comp] > 1
    out[segs[in_group]] = seg_ids[segs[first_member[comp[in_group]]]]
    return out


def _ranges(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``concatenate([arange(a, b) for a, b in zip(lo, hi)])``, vectorised."""
    n = hi - lo
    total = int(n.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.repeat(lo - np.r_[0, np.cumsum(n)[:-1]], n)
    return starts + np.arange(total)


def _bucket_remove(cells: dict, key: tuple[int, int], lab: int, k: int) -> None:
    cell = cells[key]
    mem = cell[lab]
    mem.discard(k)
    if not mem:
        del cell[lab]
        if not cell:
            del cells[key]


def _union(
    a: int,
    b: int,
    label: np.ndarray,
    members: dict[int, list[int]],
    cells: dict,
    cx: list[int],
    cy: list[int],
    lo: int,
) -> int:
    """Merge components ``a`` and ``b`` (the smaller into the larger); the merged label."""
    if a == b:
        return a
    ma, mb = members.get(a, [a]), members.get(b, [b])
    if len(ma) < len(mb):
        a, b, ma, mb = b, a, mb, ma
    for k in mb:
        label[k] = a
        if k >= lo:  # still in a cell: move it to its new component there
            key = (cx[k], cy[k])
            if key in cells and b in cells[key] and k in cells[key][b]:
                _bucket_remove(cells, key, b, k)
                cells.setdefault(key, {}).setdefault(a, set()).add(k)
    ma.extend(mb)
    members[a] = ma
    members.pop(b, None)
    return a


def _move_together_many(
    cands: np.ndarray,
    b: int,
    s_lo: np.ndarray,
    s_end: np.ndarray,
    s_hi: np.ndarray,
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    horizon: float,
    step: float,
    max_dist: float,
) -> tuple[np.ndarray, int]:
    """Whether each earlier segment ``a`` in ``cands`` moves together with segment ``b``.

    Common times: sightings of ``a`` during ``horizon`` after the later first sighting
    (from half a step before it) matched to the nearest sighting of ``b`` within half a
    step. ``a`` and ``b`` move together when they stay within ``max_dist`` at every
    common time; with fewer than two common times they do (first-sighting proximity,
    checked by the caller, suffices). Segments are given by position in first-sighting
    order (sightings ``s_lo[k]:s_hi[k]``, of which ``s_lo[k]:s_end[k]`` can fall in a
    check's window). One vectorised pass over all candidates.

    Returns
    -------
    linked : (len(cands),) bool
    work : int
        Sightings looked at.
    """
    a_lo, a_end = s_lo[cands], s_end[cands]
    n = a_end - a_lo
    idx = _ranges(a_lo, a_end)
    owner = np.repeat(np.arange(cands.size), n)
    tb = t[s_lo[b] : s_hi[b]]
    start = np.maximum(t[a_lo], tb[0])[owner]
    ta = t[idx]
    win = (ta >= start - 0.5 * step) & (ta <= start + horizon)
    idx, owner, ta = idx[win], owner[win], ta[win]
    pos = np.clip(np.searchsorted(tb, ta), 1, max(tb.size - 1, 1))
    lo = np.clip(pos - 1, 0, tb.size - 1)
    hi = np.clip(pos, 0, tb.size - 1)
    near = np.where(np.abs(tb[lo] - ta) <= np.abs(tb[hi] - ta), lo, hi)
    match = np.abs(tb[near] - ta) < 0.5 * step
    n_match = np.bincount(owner[match], minlength=cands.size)
    ia = idx[match]
    ib = near[match] + s_lo[b]
    far = np.hypot(x[ia] - x[ib], y[ia] - y[ib]) > max_dist
    n_far = np.bincount(owner[match][far], minlength=cands.size)
    return (n_match < 2) | (n_far == 0), int(idx.size + n.sum())
