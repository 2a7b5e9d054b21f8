"""Groups walk together (issue 26): one route per arrival group, members in formation.

Members of an arrival group (artefacts of one scenario with the same ``group``, as the
traffic sampler draws them) share their **leader's** route: the leader is the member that
arrives first (ties: the first in table order), and every other member walks the leader's
path in a formation slot at the group's ``spacing`` (the fitted distance between a member
and its nearest co-member, :func:`group_spacing`):

- slot ``k = 1, 2, 3, ...`` is abreast of the leader, on its left for odd ``k`` and on its
  right for even ``k``, ``ceil(k / 2) * spacing`` from it, perpendicular to the leader's
  heading (pairs and small groups walk side by side, as observed groups do: Moussaid et
  al. 2010);
- where the abreast slot is not free (a door, a narrow passage: the slot lies on an
  occupied cell or a wall stands between it and the leader), the member walks in single
  file instead, ``k * spacing`` behind the leader along the leader's own path.

:func:`formation` finds each artefact's leader and slot; :func:`group_tracks` moves the
members of planned tracks onto their slots (the plan all assemblies walk: with the social
force on, :func:`~are_stats.behaviour.social_force_tracks` keeps the formation while the
members walk, see there). :func:`group_spacing` measures the spacing of observed groups
(what the fit stores, :func:`~are_stats.fitting.fit_interaction`).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._checks import check_positive
from are_stats.environment import OccupancyGrid

__all__ = ["formation", "group_spacing", "group_tracks", "slot_offsets"]


def formation(
    scenario: npt.ArrayLike, group: npt.ArrayLike, t_arrive: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Each artefact's group leader and formation slot.

    Parameters
    ----------
    scenario, group : (n,) array
        Scenario and group label of each artefact (groups are per scenario; a missing label,
        ``None``, NaN, ``""`` or a negative number, means alone).
    t_arrive : (n,) float
        Arrival times: the first to arrive leads (ties: the first in order).

    Returns
    -------
    leader : (n,) int64
        Index of each artefact's leader (itself for a leader or a lone artefact).
    slot : (n,) int64
        ``0`` for leaders and lone artefacts, ``1 .. size - 1`` for the other members in
        order of arrival.
    """
    t = np.asarray(t_arrive, float).reshape(-1)
    n = t.size
    sc = np.asarray(scenario).reshape(-1)
    gr = pd.Series(np.asarray(group, dtype=object).reshape(-1))
    if sc.size != n or gr.size != n:
        raise ValueError(
            f"scenario, group, t_arrive: expected one value per artefact ({n}), got "
            f"{sc.size} and {gr.size}"
        )
    lone = gr.isna().to_numpy() | gr.astype(str).isin(["", "nan", "None"]).to_numpy()
    num = pd.to_numeric(gr, errors="coerce").to_numpy(float)
    lone |= np.isfinite(num) & (num < 0)
    leader = np.arange(n, dtype=np.int64)
    slot = np.zeros(n, np.int64)
    if n == 0 or lone.all():
        return leader, slot
    frame = pd.DataFrame({"s": sc, "g": gr.astype(str), "t": t, "i": np.arange(n)})[~lone]
    frame = frame.sort_values(["t", "i"], kind="stable")
    # every group at once (issue 29: a loop over the groups was most of this function's
    # CPU, thousands of groups in a criticism's walks): each group's rows in arrival
    # order, the first its leader, the rank its slot; a group key left out (NaN) none
    code = frame.groupby(["s", "g"], sort=False).ngroup().to_numpy()
    code = np.nan_to_num(code, nan=-1.0).astype(np.int64)
    idx = frame["i"].to_numpy()[code >= 0]
    code = code[code >= 0]
    order = np.argsort(code, kind="stable")  # by group, arrival order within each
    idx, code = idx[order], code[order]
    first = np.flatnonzero(np.diff(code, prepend=-1))
    size = np.diff(np.r_[first, code.size])
    leader[idx] = np.repeat(idx[first], size)
    slot[idx] = np.arange(code.size) - np.repeat(first, size)
    return leader, slot


def slot_offsets(slot: npt.ArrayLike, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Lateral (abreast) and backward (single file) offsets of formation slots.

    Parameters
    ----------
    slot : (n,) int
        Slots (:func:`formation`).
    spacing : float
        The group's spacing (m).

    Returns
    -------
    side : (n,) float
        Offset to the leader's left (m; negative: right): ``+-ceil(k / 2) * spacing``.
    back : (n,) float
        Distance behind the leader along its path in single file (m): ``k * spacing``.
    """
    k = np.asarray(slot, np.int64)
    sign = np.where(k % 2 == 1, 1.0, -1.0)
    side = np.where(k > 0, sign * np.ceil(k / 2.0) * spacing, 0.0)
    return side, k * float(spacing)


def _free_at(grid: OccupancyGrid | None, xy: np.ndarray) -> np.ndarray:
    if grid is None:
        return np.ones(len(xy), bool)
    rc = np.asarray(grid.world_to_cell(xy))
    h, w = grid.free.shape
    inside = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
    out = np.zeros(len(xy), bool)
    out[inside] = grid.free[rc[inside, 0], rc[inside, 1]]
    return out


def _clear(grid: OccupancyGrid | None, a: np.ndarray, b: np.ndarray, steps: int = 8) -> np.ndarray:
    """Whether the segments ``a -> b`` (m, 2) stay on free cells (sampled)."""
    ok = np.ones(len(a), bool)
    for f in np.linspace(0.0, 1.0, steps + 1)[1:]:
        ok &= _free_at(grid, a + f * (b - a))
    return ok


def group_tracks(
    tracks: pd.DataFrame,
    artefacts: pd.DataFrame,
    spacing: float,
    grid: OccupancyGrid | None = None,
) -> pd.DataFrame:
    """Planned tracks with every group member on its leader's path, in formation.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``scenario, id, t, x, y, yaw``: one planned track per artefact.
    artefacts : pandas.DataFrame
        The scenarios table: ``scenario``, the artefact id (``artefact``, else ``id``),
        ``t_arrive`` and ``group``; without a ``group`` column nothing changes.
    spacing : float
        Distance (m) between neighbouring members (> 0).
    grid : OccupancyGrid, optional
        The map: a slot on an occupied cell, or behind a wall from the leader, turns the
        member into single file (module docstring).

    Returns
    -------
    pandas.DataFrame
        The same rows; a member's ``x, y`` follow the leader's track (clamped to its first
        and last position outside the leader's time) at the member's slot, ``yaw`` the
        leader's heading. ``attrs["group_members"]`` counts the members moved.
    """
    spacing = float(check_positive("spacing", spacing))
    out = tracks.copy()
    out.attrs["group_members"] = 0
    if "group" not in artefacts.columns or len(tracks) == 0:
        return out
    id_col = "artefact" if "artefact" in artefacts.columns else "id"
    sc = (
        artefacts["scenario"].to_numpy()
        if "scenario" in artefacts.columns
        else np.zeros(len(artefacts), np.int64)
    )
    leader, slot = formation(sc, artefacts["group"].to_numpy(), artefacts["t_arrive"])
    if not (slot > 0).any():
        return out
    side, back = slot_offsets(slot, spacing)
    ids = artefacts[id_col].to_numpy()
    t_sc = out["scenario"].to_numpy() if "scenario" in out.columns else np.zeros(len(out), int)
    rows = pd.DataFrame({"s": t_sc, "a": out["id"].to_numpy(), "r": np.arange(len(out))})
    by = {k: g["r"].to_numpy() for k, g in rows.groupby(["s", "a"], sort=False)}
    t_all = out["t"].to_numpy(float)
    xy_all = out[["x", "y"]].to_numpy(float)
    new_xy = xy_all.copy()
    yaw = out["yaw"].to_numpy(float).copy() if "yaw" in out.columns else np.zeros(len(out))
    moved = 0
    for m in np.flatnonzero(slot > 0):
        mine = by.get((sc[m], ids[m]))
        lead = by.get((sc[leader[m]], ids[leader[m]]))
        if mine is None or lead is None:
            continue
        lt, lxy = t_all[lead], xy_all[lead]
        tt = t_all[mine]
        pos = np.column_stack([np.interp(tt, lt, lxy[:, 0]), np.interp(tt, lt, lxy[:, 1])])
        # the leader's heading: its displacement over the next and previous second
        ahead = np.column_stack(
            [np.interp(tt + 1.0, lt, lxy[:, 0]), np.interp(tt + 1.0, lt, lxy[:, 1])]
        )
        behind = np.column_stack(
            [np.interp(tt - 1.0, lt, lxy[:, 0]), np.interp(tt - 1.0, lt, lxy[:, 1])]
        )
        d = ahead - behind
        norm = np.hypot(*d.T)
        head = np.arctan2(d[:, 1], d[:, 0])
        still = norm < 1e-6
        if still.all():
            head[:] = yaw[lead[0]]
        else:  # standing: the last heading walked (the first one before it walked)
            idx = np.where(~still, np.arange(tt.size), -1)
            idx = np.maximum.accumulate(idx)
            idx[idx < 0] = np.flatnonzero(~still)[0]
            head = head[idx]
        left = np.column_stack([-np.sin(head), np.cos(head)])
        abreast = pos + side[m] * left
        # single file: back along the leader's path (its arc length, clamped to its start)
        seg = np.r_[0.0, np.cumsum(np.hypot(*np.diff(lxy, axis=0).T))]
        s_now = np.interp(tt, lt, seg) - back[m]
        keep = np.r_[True, np.diff(seg) > 0]
        file_xy = np.column_stack(
            [np.interp(s_now, seg[keep], lxy[keep, 0]), np.interp(s_now, seg[keep], lxy[keep, 1])]
        )
        # before the leader has walked that far: behind its start, against its heading
        early = s_now < 0.0
        if early.any():
            back_xy = lxy[0] + s_now[early, None] * np.column_stack(
                [np.cos(head[early]), np.sin(head[early])]
            )
            fine = _free_at(grid, back_xy) & _clear(
                grid, np.broadcast_to(lxy[0], back_xy.shape), back_xy
            )
            file_xy[np.flatnonzero(early)[fine]] = back_xy[fine]
        ok = _free_at(grid, abreast) & _clear(grid, pos, abreast)
        new_xy[mine] = np.where(ok[:, None], abreast, file_xy)
        yaw[mine] = head
        moved += 1
    out["x"], out["y"] = new_xy[:, 0], new_xy[:, 1]
    if "yaw" in out.columns:
        out["yaw"] = yaw
    out.attrs["group_members"] = moved
    return out


def group_spacing(
    tracks: pd.DataFrame, groups: Mapping[Hashable, Hashable] | pd.Series, *, min_speed: float = 0.2
) -> tuple[float, int]:
    """The spacing of observed groups: the median distance from a walking member to its
    nearest co-member at the same time.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` (and ``scenario``: groups are per scenario).
    groups : Mapping or pandas.Series
        Group label of each track id (``(scenario, id)`` with a ``scenario`` column); ids
        missing or with an empty label walk alone.
    min_speed : float
        Only samples where the member moves at least this fast (m/s) count: standing
        groups gather closer or spread out, the formation is a walking one.

    Returns
    -------
    spacing : float
        Metres (NaN without two members of a group seen walking at one time).
    samples : int
        Member samples the median is taken over.
    """
    from scipy.spatial import cKDTree  # lazy: +0.25 s CPU on `import are_stats.behaviour`

    groups = dict(groups)
    keys = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    tab = tracks.sort_values([*keys, "t"], kind="stable").reset_index(drop=True)
    kk = list(tab[keys].itertuples(index=False, name=None))
    lab = [groups.get(k if len(k) > 1 else k[0]) for k in kk]
    label = pd.Series(lab, dtype=object)
    grouped = ~(label.isna() | label.astype(str).isin(["", "nan", "None"])).to_numpy()
    if not grouped.any():
        return float("nan"), 0
    xy = tab[["x", "y"]].to_numpy(float)
    t = tab["t"].to_numpy(float)
    same = np.r_[False, (tab[keys].to_numpy()[1:] == tab[keys].to_numpy()[:-1]).all(axis=1)]
    dt = np.diff(t, prepend=np.nan)
    step = np.hypot(*np.diff(xy, axis=0, prepend=xy[:1]).T)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(same & (dt > 0), step / dt, np.nan)
    walking = grouped & (speed >= min_speed)
    sc = tab["scenario"].to_numpy() if "scenario" in tab.columns else np.zeros(len(tab), int)
    frame = pd.DataFrame(
        {"s": sc, "g": label.astype(str).to_numpy(), "t": np.round(t, 6), "r": np.arange(len(tab))}
    )[walking]
    # every (scenario, group, time) of two members or more at once: one k-d tree, each on
    # its own stretch of a third axis, farther from the next than any two of its members
    # are apart (the third coordinate's difference is exactly 0 within one, so each
    # distance is the plane's, bit for bit; issue 29: a tree per (scenario, group, time)
    # was most of learn_interaction's CPU). The median takes the values in any order.
    part = frame.groupby(["s", "g", "t"], sort=False).ngroup().to_numpy()
    part = np.nan_to_num(part, nan=-1.0).astype(np.int64)  # a key left out (NaN): no frame
    size = np.bincount(part[part >= 0], minlength=1)
    shared = (part >= 0) & (size[np.maximum(part, 0)] >= 2)
    if not shared.any():
        return float("nan"), 0
    pts = xy[frame["r"].to_numpy()[shared]]
    gap = 2.0 * (float(np.ptp(pts[:, 0]) + np.ptp(pts[:, 1])) + 1.0)
    pts = np.column_stack([pts, part[shared] * gap])
    vals = cKDTree(pts).query(pts, k=2)[0][:, 1]
    return float(np.median(vals)), int(vals.size)
