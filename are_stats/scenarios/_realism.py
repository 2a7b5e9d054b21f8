"""Realism of generated motion, measured as the Waymo Open Sim Agents Challenge scores sim
agents (issue 26): distribution matching, feature by feature.

For each feature the observed values (from the log's tracks) are scored under a histogram
of the values the model generated for the same artefacts (same entries, same stays): the
score is ``exp(mean log p)``, ``p`` the smoothed probability of the observed value's bin
(20 bins over the log's own 1-99% range, a model's values past it counted in the end
bins, one pseudo-count per bin; two bins for the indicators): higher is closer to the log,
and a model that generates the log's own distribution scores what that distribution scores
against itself (about 1/12 for a bell-shaped feature, 1 for an indicator that is always
the same), so compare models on one feature, not features with each other. The bins are
the log's, as the challenge's are fixed per feature by its configuration, not by the agents
it scores: every model is scored on the same bins, and a model's score does not change with
the other models in the table. (On bins over the pooled values of all models, the
catalogue's straightness of 0.1-0.99 made them 0.04 wide on a crossing log whose observed
straightness is 0.96-0.99: one bin held nearly every observed value, and constant velocity,
exactly straight, scored 0.81 against the fitted model's 0.73, whose median is the nearer.)
The realism score is the weighted mean over features, with the challenge's weights per
kind: kinematic 0.25, interactive 0.5, map 0.25 (split evenly between the features of a kind).

Features (:data:`REALISM_FEATURES`), on tracks resampled to one step ``dt``:

* kinematic: speed, acceleration (change of velocity per second), turning rate (change
  of heading per second while moving), straightness (net / path length, per track), time
  to exit over the stay (first time within 0.5 m of the track's last position, per track);
* interactive: distance to the nearest other person, collision (two discs of radius
  ``radius`` overlap), time to collision (constant velocities, capped at 10 s), group
  spacing (distance from a walking member of a group to its nearest walking co-member: the
  statistic whose median is the fit's spacing, :func:`~are_stats.behaviour.group_spacing`);
* map (with a map): distance to the nearest wall, on a free cell.

:func:`realism_table` compares three motion models for the observed artefacts side by
side: **constant velocity** (each person keeps its velocity of the first second), the
**catalogue** behaviour (the paper's MDP on the coarse map, then the social force) and the
**fitted** behaviour (then the social force), the last two through the one assembly's
:func:`~are_stats.scenarios.scene_tracks`. The log's groups are those the life-cycle
conversion infers (:func:`~are_stats.logs.tracks_to_lifecycle`: people first seen together
who move together); the models walk the same artefacts in the same groups (the assembly
walks an arrival group in formation), so group spacing compares like with like. The
models are seen as the log was: their tracks at the log's step with the log's position
noise (estimated from the log's tracks, :func:`realism_table`'s ``noise``), so that a
model is not scored on the tracker's noise in the log's accelerations, turning rates and
near passes, which no model of motion makes.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping
from typing import TYPE_CHECKING

import jax
import numpy as np
import pandas as pd

from are_stats.behaviour import tracker_noise
from are_stats.environment import load_catalogue
from are_stats.logs import track_groups
from are_stats.scenarios._assembly import scene_tracks

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from are_stats.behaviour import BehaviourFit, SocialForce
    from are_stats.environment import ArtefactCatalogue, OccupancyGrid

#: The groups argument: a track's group label by track id, or by ``(scenario, id)``.
Groups = Mapping[Hashable, Hashable]

__all__ = [
    "REALISM_FEATURES",
    "plot_realism",
    "realism_features",
    "realism_score",
    "realism_summary",
    "realism_table",
]

#: Feature -> kind (kinematic, interactive, map).
REALISM_FEATURES: dict[str, str] = {
    "speed (m/s)": "kinematic",
    "acceleration (m/s^2)": "kinematic",
    "turning rate (rad/s)": "kinematic",
    "straightness": "kinematic",
    "time to exit / stay": "kinematic",
    "nearest person (m)": "interactive",
    "collision": "interactive",
    "time to collision (s)": "interactive",
    "group spacing (m)": "interactive",
    "wall distance (m)": "map",
    "on free cells": "map",
}
#: The challenge's weight of each kind of feature.
KIND_WEIGHTS = {"kinematic": 0.25, "interactive": 0.5, "map": 0.25}
_TTC_MAX = 10.0
_NEAR_MAX = 10.0
#: Group members count for the group spacing while they walk at least this fast (m/s), as
#: in :func:`~are_stats.behaviour.group_spacing` (standing groups gather closer).
_GROUP_MIN_SPEED = 0.2


def _resample(tracks: pd.DataFrame, dt: float) -> pd.DataFrame:
    """Each track at the times ``k dt`` within its span (linear interpolation).

    The tracks are runs of one sorted table, interpolated from its arrays and gathered
    into one table at the end (issue 29: a table per track, then their concatenation, cost
    the realism stage several seconds; the values and dtypes are those of that way, rows
    with a missing key left out as ``groupby`` leaves them)."""
    cols = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    tab = tracks.sort_values([*cols, "t"], kind="stable")
    tab = tab[tab[cols].notna().all(axis=1).to_numpy()]
    keys = [tab[c].to_numpy() for c in cols]
    first, stop = _run_bounds(keys)
    t_all = tab["t"].to_numpy(float)
    x_all, y_all = tab["x"].to_numpy(float), tab["y"].to_numpy(float)
    ts, xs, ys, sizes = [], [], [], np.zeros(first.size, np.int64)
    for g, (a, b) in enumerate(zip(first, stop, strict=True)):
        t = t_all[a:b]
        grid_t = np.arange(np.ceil(t[0] / dt - 1e-9), np.floor(t[-1] / dt + 1e-9) + 1) * dt
        sizes[g] = grid_t.size
        ts.append(grid_t)
        xs.append(np.interp(grid_t, t, x_all[a:b]))
        ys.append(np.interp(grid_t, t, y_all[a:b]))
    if not sizes.sum():
        return pd.DataFrame(columns=[*cols, "t", "x", "y"])
    # each key as groupby hands it out (Python scalars), repeated: the old np.full's dtypes
    part = {
        c: np.repeat(np.array(k[first].tolist()), sizes) for c, k in zip(cols, keys, strict=True)
    }
    part["t"], part["x"], part["y"] = np.concatenate(ts), np.concatenate(xs), np.concatenate(ys)
    res = pd.DataFrame(part)
    if "scenario" not in res.columns:
        res["scenario"] = 0
    return res


def _run_bounds(keys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """First and stop rows ``(R,)`` of each run of equal ``keys`` (arrays of one length,
    rows sorted by them)."""
    n = len(keys[0])
    new = np.ones(n, bool)
    if n:
        new[1:] = np.logical_or.reduce([k[1:] != k[:-1] for k in keys])
    first = np.flatnonzero(new)
    return first, np.r_[first[1:], n][: first.size].astype(np.int64)


def _runs(tab: pd.DataFrame) -> list[tuple[int, int]]:
    """``(start, stop)`` rows of each track of a :func:`_resample` table (runs of one
    ``scenario, id``, in table order)."""
    first, stop = _run_bounds([tab[c].to_numpy() for c in ("scenario", "id")])
    return list(zip(first.tolist(), stop.tolist(), strict=True))


def _observation_noise(tracks: pd.DataFrame, dt: float) -> float:
    """Standard deviation (m) of white position noise in tracks sampled every ``dt``: the
    tracker's (:func:`~are_stats.behaviour.tracker_noise`) on the tracks resampled to ``dt``."""
    return tracker_noise(_resample(tracks, dt))


def _seen_as_logged(
    seed: int | list[int], tracks: pd.DataFrame, dt: float, noise: float
) -> pd.DataFrame:
    """Tracks resampled to the log's step ``dt`` and seen through its tracker: white
    Gaussian noise of ``noise`` metres on every position (seeded by ``seed``)."""
    tab = _resample(tracks, dt)
    if noise > 0 and len(tab):
        rng = np.random.default_rng(seed)
        tab = tab.assign(
            x=tab["x"] + rng.normal(0.0, noise, len(tab)),
            y=tab["y"] + rng.normal(0.0, noise, len(tab)),
        )
    return tab


def realism_features(
    tracks: pd.DataFrame,
    dt: float,
    grid: OccupancyGrid | None = None,
    radius: float = 0.3,
    groups: Groups | None = None,
) -> dict[str, np.ndarray]:
    """The values of every feature of :data:`REALISM_FEATURES` in ``tracks``.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (and ``scenario``: scenarios never meet).
    dt : float
        Resampling step (s): the log's sampling period.
    grid : OccupancyGrid, optional
        The map (map features need it).
    radius : float
        Disc radius of a person (m) for collisions and times to collision.
    groups : Mapping, optional
        Group label of each track id (``(scenario, id)`` keys are looked up first, then
        ``id``); ids missing or labelled ``None``, NaN, ``""`` or a negative number walk
        alone. Without it there are no group spacing values.

    Returns
    -------
    dict of str to (k,) float
        Per-sample values for speed, acceleration, turning rate, nearest person, collision,
        time to collision, group spacing (one per walking member of a group with another
        member walking at that time, capped at 10 m) and the map features; per-track
        values for straightness and time to exit.
    """

    tab = _resample(tracks, dt)
    feats: dict[str, list[np.ndarray]] = {k: [] for k in REALISM_FEATURES}
    vel_all = np.full((len(tab), 2), np.nan)
    # each track is a run of rows of the resampled table (sorted by scenario and id, index
    # 0 .. n - 1): array slices, not a groupby's tables (issue 29)
    xy_tab = tab[["x", "y"]].to_numpy(float)
    for a, b in _runs(tab):
        idx = np.arange(a, b)
        xy = xy_tab[a:b]
        if len(xy) < 2:
            continue
        v = np.diff(xy, axis=0) / dt
        vel_all[idx[1:]] = v
        sp = np.hypot(*v.T)
        feats["speed (m/s)"].append(sp)
        if len(v) > 1:
            feats["acceleration (m/s^2)"].append(np.hypot(*np.diff(v, axis=0).T) / dt)
            moving = (sp[1:] > 0.2) & (sp[:-1] > 0.2)
            head = np.arctan2(v[:, 1], v[:, 0])
            turn = np.abs(np.angle(np.exp(1j * np.diff(head)))) / dt
            feats["turning rate (rad/s)"].append(turn[moving])
        path = float(sp.sum() * dt)
        if path > 0.5:
            feats["straightness"].append(np.array([np.hypot(*(xy[-1] - xy[0])) / path]))
        stay = float(len(xy) - 1) * dt
        near_end = np.flatnonzero(np.hypot(*(xy - xy[-1]).T) <= 0.5)
        if stay > 0:
            feats["time to exit / stay"].append(np.array([near_end[0] * dt / stay]))
    ok = np.isfinite(vel_all).all(axis=1)
    near, hit, ttc = _interactive(tab[ok], vel_all[ok], radius)
    feats["nearest person (m)"].append(near)
    feats["collision"].append(hit)
    feats["time to collision (s)"].append(ttc)
    if groups is not None and len(tab):
        feats["group spacing (m)"].append(_group_spacing(tab, vel_all, groups))
    if grid is not None and len(tab):
        dist = grid.distance_to_occupied()
        xy = tab[["x", "y"]].to_numpy(float)
        ij = np.asarray(grid.world_to_cell(xy))
        inside = (
            (ij[:, 0] >= 0)
            & (ij[:, 0] < grid.free.shape[0])
            & (ij[:, 1] >= 0)
            & (ij[:, 1] < grid.free.shape[1])
        )
        r = np.clip(ij[:, 0], 0, grid.free.shape[0] - 1)
        c = np.clip(ij[:, 1], 0, grid.free.shape[1] - 1)
        feats["wall distance (m)"].append(np.where(inside, np.minimum(dist[r, c], 10.0), 0.0))
        feats["on free cells"].append((inside & grid.free[r, c]).astype(float))
    return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in feats.items()}


def _interactive(
    tab: pd.DataFrame, vel: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest other person (capped at 10 m), collision and time to collision of every
    row of ``tab`` (``scenario, t, x, y``; velocities ``vel (n, 2)``) that shares its
    scenario and time with somebody else: ``(k,)`` each.

    All times at once: each (scenario, time) gets its own stretch of a third axis, farther
    from the next than any two people of one frame are apart, so one k-d tree answers
    every frame's queries (a tree per frame cost about a millisecond each).
    """
    from scipy.spatial import cKDTree  # lazy: +0.3 s CPU on `import are_stats.scenarios`

    if len(tab) < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    xy = tab[["x", "y"]].to_numpy(float)
    frame = pd.factorize(
        pd.MultiIndex.from_arrays([tab["scenario"].to_numpy(), tab["t"].to_numpy()])
    )[0]
    size = np.bincount(frame)[frame]
    shared = size >= 2
    xy, frame, vel = xy[shared], frame[shared], vel[shared]
    if not len(xy):
        return np.zeros(0), np.zeros(0), np.zeros(0)
    gap = 2.0 * (float(np.ptp(xy[:, 0]) + np.ptp(xy[:, 1])) + _NEAR_MAX + 1.0)
    pts = np.column_stack([xy, frame * gap])
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=2)
    near = np.minimum(d[:, 1], _NEAR_MAX)
    hit = (d[:, 1] < 2 * radius).astype(float)
    ttc = np.full(len(xy), _TTC_MAX)
    pairs = tree.query_pairs(_NEAR_MAX, output_type="ndarray")
    if pairs.size:
        a, b = pairs[:, 0], pairs[:, 1]
        p = xy[b] - xy[a]
        w = vel[b] - vel[a]
        # |p + w t| = 2 r: the first root t > 0
        qa = (w * w).sum(1)
        qb = 2 * (p * w).sum(1)
        qc = (p * p).sum(1) - (2 * radius) ** 2
        disc = qb * qb - 4 * qa * qc
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hit = (-qb - np.sqrt(np.maximum(disc, 0))) / (2 * qa)
        t_hit = np.where((disc >= 0) & (qa > 1e-12) & (t_hit >= 0), t_hit, _TTC_MAX)
        t_hit = np.where(qc <= 0, 0.0, np.minimum(t_hit, _TTC_MAX))
        np.minimum.at(ttc, a, t_hit)
        np.minimum.at(ttc, b, t_hit)
    return near, hit, ttc


def _label_text(lab: Hashable) -> str | None:
    """A group label as text (None: alone: None, a negative or non-finite number, or text
    ``""``, ``"nan"`` or ``"None"``)."""
    if lab is None:
        return None
    num = pd.to_numeric(pd.Series([lab]), errors="coerce").iloc[0]
    if pd.notna(num) and (not np.isfinite(num) or num < 0):
        return None
    text = str(lab)
    return None if text in ("", "nan", "None") else text


def _group_spacing(tab: pd.DataFrame, vel: np.ndarray, groups: Groups) -> np.ndarray:
    """Distance ``(k,)`` from each walking group member to its nearest walking co-member
    at the same time (resampled rows ``tab``, velocities ``vel (n, 2)``)."""
    from scipy.spatial import cKDTree  # lazy: +0.3 s CPU on `import are_stats.scenarios`

    keys = tab[["scenario", "id"]].drop_duplicates()
    # each distinct text or integer label read once (issue 29: a pandas parse per track was
    # most of this function's CPU); other labels (floats: -0.0 == 0.0 but not as text) each
    # time
    texts: dict[tuple[type, Hashable], str | None] = {}

    def text(s: Hashable, i: Hashable) -> str | None:
        lab = groups.get((s, i), groups.get(i))
        if not isinstance(lab, str | int | np.integer):
            return _label_text(lab)
        key = (type(lab), lab)
        if key not in texts:
            texts[key] = _label_text(lab)
        return texts[key]

    label = {
        (s, i): text(s, i)
        for s, i in zip(keys["scenario"].to_numpy(), keys["id"].to_numpy(), strict=True)
    }
    lab = pd.Series(
        [label[k] for k in zip(tab["scenario"].to_numpy(), tab["id"].to_numpy(), strict=True)],
        dtype=object,
    )
    speed = np.hypot(*np.nan_to_num(vel).T)
    walking = (speed >= _GROUP_MIN_SPEED) & np.isfinite(vel).all(axis=1) & lab.notna().to_numpy()
    if walking.sum() < 2:
        return np.zeros(0)
    frame = pd.DataFrame(
        {
            "s": tab["scenario"].to_numpy(),
            "g": lab.to_numpy(),
            "t": np.round(tab["t"].to_numpy(float), 6),
        }
    )[walking]
    xy = tab[["x", "y"]].to_numpy(float)[walking]
    # every (scenario, group, time) at once, as _interactive's frames: one k-d tree, each
    # frame on its own stretch of a third axis, farther from the next than any two of its
    # members are apart (a tree per frame cost about a millisecond, thousands per call).
    # Values in the order of the frames' first rows, members in row order within each
    part = frame.groupby(["s", "g", "t"], sort=False).ngroup().to_numpy()
    part = np.where(part >= 0, part, -1)  # a key groupby leaves out (NaN) is no frame
    size = np.bincount(part[part >= 0], minlength=1)
    shared = (part >= 0) & (size[np.maximum(part, 0)] >= 2)
    if not shared.any():
        return np.zeros(0)
    order = np.argsort(part[shared], kind="stable")
    pts = xy[shared][order]
    gap = 2.0 * (float(np.ptp(pts[:, 0]) + np.ptp(pts[:, 1])) + _NEAR_MAX + 1.0)
    pts = np.column_stack([pts, part[shared][order] * gap])
    d, _ = cKDTree(pts).query(pts, k=2)
    return np.minimum(d[:, 1], _NEAR_MAX)


def realism_summary(features: dict[str, np.ndarray]) -> pd.DataFrame:
    """Summaries of feature values (:func:`realism_features`): the log's side of the table.

    Returns
    -------
    pandas.DataFrame
        Indexed by feature: ``kind``, ``n`` (values), ``mean``, ``5%``, ``50%``, ``95%``
        (NaN without values).
    """
    rows = {}
    for f, kind in REALISM_FEATURES.items():
        v = np.asarray(features.get(f, np.zeros(0)), float)
        v = v[np.isfinite(v)]
        q = np.quantile(v, [0.05, 0.5, 0.95]) if v.size else np.full(3, np.nan)
        rows[f] = {
            "kind": kind,
            "n": int(v.size),
            "mean": float(v.mean()) if v.size else np.nan,
            "5%": q[0],
            "50%": q[1],
            "95%": q[2],
        }
    out = pd.DataFrame(rows).T
    out.index.name = "feature"
    return out


def realism_score(
    observed: dict[str, np.ndarray], generated: dict[str, np.ndarray], edges: dict | None = None
) -> dict[str, float]:
    """Per feature, ``exp(mean log p)`` of the observed values under the smoothed histogram
    of the generated ones (NaN where either side has no value).

    Parameters
    ----------
    observed, generated : dict of str to (k,) float
        :func:`realism_features` of the log and of a model.
    edges : dict of str to (21,) float, optional
        Bin edges per feature (default: the observed values', :func:`realism_table`'s
        bins, the same whatever the generated values).

    Returns
    -------
    dict of str to float
    """
    out = {}
    for name in REALISM_FEATURES:
        obs, gen = observed.get(name, np.zeros(0)), generated.get(name, np.zeros(0))
        if obs.size == 0 or gen.size == 0:
            out[name] = float("nan")
            continue
        e = edges[name] if edges is not None else _edges(name, obs)
        counts = np.histogram(np.clip(gen, e[0], e[-1]), bins=e)[0] + 1.0
        p = counts / counts.sum()
        k = np.clip(np.searchsorted(e, np.clip(obs, e[0], e[-1]), side="right") - 1, 0, len(p) - 1)
        out[name] = float(np.exp(np.mean(np.log(p[k]))))
    return out


def _edges(name: str, observed: np.ndarray) -> np.ndarray:
    """Bin edges of a feature from the log's values alone: two bins for the indicators,
    else 21 edges over the observed 1-99% range. A range narrower than ``2e-3`` of its
    scale (of at least 1 unit: a log whose feature never varies, as two walkers exactly 0.7 m
    apart, or varies by rounding only, as the accelerations of exact lines) is widened to
    that round its middle, with the middle inside a bin: the observed value has that bin
    and other values the end ones, whatever rounding the log's values carry."""
    if name in ("collision", "on free cells"):
        return np.array([-0.5, 0.5, 1.5])
    lo, hi = np.quantile(observed, [0.01, 0.99])
    mid = 0.5 * (lo + hi)
    width = 1e-4 * max(1.0, abs(float(mid)))  # a bin of the narrowest range
    if hi - lo < 20.0 * width:
        lo, hi = mid - 9.5 * width, mid + 10.5 * width
    return np.linspace(lo, hi, 21)


def _weighted(scores: dict[str, float]) -> float:
    """The realism score: the kinds' weights split evenly over their scored features."""
    total, weight = 0.0, 0.0
    for kind, w in KIND_WEIGHTS.items():
        vals = [scores[f] for f, k in REALISM_FEATURES.items() if k == kind]
        vals = [v for v in vals if np.isfinite(v)]
        if vals:
            total += w * float(np.mean(vals))
            weight += w
    return total / weight if weight else float("nan")


def _constant_velocity(tracks: pd.DataFrame, dt: float) -> pd.DataFrame:
    """Each observed person keeping the mean velocity of its first second, for its stay."""
    tab = _resample(tracks, dt)
    runs = _runs(tab)
    if not runs:
        return tab
    xy_all, t_all = tab[["x", "y"]].to_numpy(float), tab["t"].to_numpy(float)
    out = np.empty_like(xy_all)
    for a, b in runs:
        xy, t = xy_all[a:b], t_all[a:b]
        k = max(1, min(len(xy) - 1, int(round(1.0 / dt))))
        v = (xy[k] - xy[0]) / max(t[k] - t[0], 1e-9) if len(xy) > 1 else np.zeros(2)
        out[a:b] = xy[0] + (t - t[0])[:, None] * v
    return tab.assign(x=out[:, 0], y=out[:, 1])


def realism_table(
    key: jax.Array,
    tracks: pd.DataFrame,
    grid: OccupancyGrid | None = None,
    *,
    behaviour: BehaviourFit | None = None,
    catalogue: ArtefactCatalogue | None = None,
    n_replicates: int = 3,
    radius: float = 0.3,
    interaction: bool | SocialForce = True,
    noise: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """Realism of constant velocity, the catalogue behaviour and the fitted behaviour on the
    observed artefacts, side by side (see the module docstring).

    Parameters
    ----------
    key : jax.Array
        PRNG key (the models' replicates).
    tracks : pandas.DataFrame
        The log's tracks ``id, t, x, y`` (one scene), sampled at one rate.
    grid : OccupancyGrid, optional
        The map: map features, and the catalogue behaviour (which needs it).
    behaviour : BehaviourFit, optional
        The fitted behaviour (its column is left out without it).
    catalogue : ArtefactCatalogue, optional
        For the catalogue behaviour (default the shipped one); artefacts are its first
        class (``person``).
    n_replicates : int
        Replicates of each stochastic model, pooled in its histograms.
    radius : float
        Disc radius of a person (m).
    interaction : bool or SocialForce
        The interaction the two behaviours walk with (:func:`scene_tracks`; pass the fit's,
        :func:`~are_stats.fitting.interaction_from_attrs`, to score what generation makes:
        its group spacing included).
    noise : float, optional
        Standard deviation (m) of the log's position noise, with which every model's
        tracks are seen before their features are taken (default: estimated from the log's
        tracks, 0 for noise-free ones; 0 switches it off). The log's accelerations, turning
        rates, near passes and times to collision are those of noisy positions (5 cm at
        2.5 Hz is an acceleration noise of 0.8 m/s^2); a model's exact positions, scored
        against them, would lose on the sensor, not on the motion.
    progress : callable, optional
        ``progress(done, total)`` after each replicate of each behaviour (``total``: the
        behaviours walked, catalogue and fitted, times ``n_replicates``; each replicate
        assembles a scene, the long part of the table). The table does not depend on it.

    Returns
    -------
    pandas.DataFrame
        Rows: the features and ``realism (weighted)``; columns: ``kind``, ``weight`` and one
        score per model (``constant velocity``, ``catalogue``, ``fitted``);
        ``attrs["observation_noise"]`` the noise (m) the models were seen with.
    """
    from are_stats.traffic import fold_in_key  # lazy: NumPyro (+0.75 s on the import)

    tab = tracks.sort_values(["id", "t"], kind="stable")
    steps = np.diff(tab["t"].to_numpy(float))[tab["id"].to_numpy()[1:] == tab["id"].to_numpy()[:-1]]
    if steps.size == 0:
        raise ValueError("tracks: expected tracks of at least two samples")
    dt = float(np.median(steps))
    first = tab.groupby("id", sort=False).first()
    last = tab.groupby("id", sort=False).last()
    art = pd.DataFrame(
        {
            "scenario": 0,
            "artefact": np.arange(len(first)),
            "class": 0,
            "mark": 0,
            "t_arrive": first["t"].to_numpy(float),
            "t_leave": last["t"].to_numpy(float),
            "x": first["x"].to_numpy(float),
            "y": first["y"].to_numpy(float),
            "yaw": 0.0,
            "label": "person",
        }
    )
    # the log's groups (as the life-cycle conversion infers them); the models walk the
    # same artefacts in the same groups (a lone artefact is a group of its own)
    label = track_groups(tab)
    code = pd.factorize(pd.Series([label.get(str(i)) for i in first.index], dtype=object))[0]
    lone = code < 0
    art["group"] = np.where(lone, code.max(initial=-1) + 1 + np.arange(len(art)), code)
    by_id = {i: int(c) for i, c, o in zip(first.index, code, lone, strict=True) if not o}
    by_artefact = {k: int(c) for k, (c, o) in enumerate(zip(code, lone, strict=True)) if not o}
    horizon = float(art["t_leave"].max()) + dt
    sigma = _observation_noise(tab, dt) if noise is None else float(noise)
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"noise: expected a finite number >= 0 (m), got {noise}")

    def seen(k: jax.Array, moved: pd.DataFrame) -> pd.DataFrame:
        seed = np.asarray(jax.random.key_data(k)).ravel().tolist()
        return _seen_as_logged(seed, moved, dt, sigma)

    observed = realism_features(tab, dt, grid, radius, groups=by_id)
    cv = seen(fold_in_key(key, 7), _constant_velocity(tab, dt))
    models: dict[str, list[dict[str, np.ndarray]]] = {
        "constant velocity": [realism_features(cv, dt, grid, radius, groups=by_id)]
    }
    cat = load_catalogue() if catalogue is None else catalogue
    sources = []
    if grid is not None and abs(float(grid.origin[2])) < 1e-9:
        sources.append(("catalogue", "catalogue"))
    if behaviour is not None:
        sources.append(("fitted", "fitted"))
    say = progress or (lambda done, total: None)
    total = len(sources) * n_replicates
    for m, (name, rule) in enumerate(sources):
        runs = []
        for r in range(n_replicates):
            k_run = fold_in_key(fold_in_key(key, m), r)
            moved = scene_tracks(
                k_run,
                art,
                grid,
                cat,
                horizon,
                behaviours=rule,
                fitted=behaviour,
                source="realism",
                interaction=interaction,
            )
            if moved is not None and len(moved):
                moved = seen(fold_in_key(k_run, 7), moved)
                runs.append(realism_features(moved, dt, grid, radius, groups=by_artefact))
            say(m * n_replicates + r + 1, total)
        if runs:
            models[name] = runs
    pooled = {
        name: {f: np.concatenate([run[f] for run in runs]) for f in REALISM_FEATURES}
        for name, runs in models.items()
    }
    # the log's bins, the same for every model (module docstring)
    edges = {f: _edges(f, observed[f]) for f in REALISM_FEATURES if observed[f].size}
    rows = {f: {"kind": k, "weight": np.nan} for f, k in REALISM_FEATURES.items()}
    for kind, w in KIND_WEIGHTS.items():
        names = [f for f, k in REALISM_FEATURES.items() if k == kind and f in edges]
        for f in names:
            rows[f]["weight"] = w / len(names)
    table = pd.DataFrame(rows).T
    for name, feats in pooled.items():
        scores = realism_score(observed, feats, edges)
        table[name] = pd.Series(scores)
        table.loc["realism (weighted)", name] = _weighted(scores)
    table.loc["realism (weighted)", "kind"] = "all"
    table.loc["realism (weighted)", "weight"] = 1.0
    table.attrs["observation_noise"] = sigma
    return table


def plot_realism(table: pd.DataFrame) -> Figure:
    """Bars of every feature's score per model, the weighted realism score first.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`realism_table`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt  # lazy: +0.55 s CPU on `import are_stats.scenarios`

    models = [c for c in table.columns if c not in ("kind", "weight")]
    rows = ["realism (weighted)", *[r for r in table.index if r != "realism (weighted)"]]
    fig, ax = plt.subplots(figsize=(9.0, 0.42 * len(rows) + 1.2))
    height = 0.8 / max(len(models), 1)
    colours = {"constant velocity": "0.65", "catalogue": "#d08c3c", "fitted": "#2f6db3"}
    y = np.arange(len(rows))
    for m, name in enumerate(models):
        vals = pd.to_numeric(table.loc[rows, name], errors="coerce").to_numpy(float)
        ax.barh(
            y + (m - (len(models) - 1) / 2) * height,
            np.nan_to_num(vals),
            height,
            color=colours.get(name, f"C{m}"),
            label=name,
        )
    labels = [f"{r}  [{table.loc[r, 'kind']}]" if r != rows[0] else r for r in rows]
    ax.set_yticks(y, labels)
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("likelihood of the log's values under the generated histogram")
    ax.axhline(0.5, color="k", linewidth=0.6)
    ax.set_title("Realism of generated motion against the log (higher is better)")
    fig.legend(loc="lower center", ncol=len(models), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return fig
