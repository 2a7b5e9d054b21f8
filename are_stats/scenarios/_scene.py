"""The Scene: where a scenario's artefacts become boxes that live and move.

A scenario table (one row per artefact: class, mark, arrival and leaving times, arrival pose)
and, when behaviours were generated, a tracks table (poses at the MDP's epochs) describe
what happens; the builder, perception, the robot's planner and the exports all need the
same thing from them: **which boxes are where at time t**. :class:`Scene` is the one place
that answers it.

* **Boxes from Q (DECISIONS 5).** The mixture component is the artefact's class, the mark
  selects the class's row of the property table ``Q``; the row gives the label ``l`` and
  the bounding box ``b``. With class labels (the fit's), a class is found in the catalogue
  by its label, else by its position (the catalogue's last class beyond the table).
* **Poses at time t.** Before its first track epoch (or without a track) an artefact stands
  at its arrival pose; between epochs its position is interpolated linearly and its heading
  the short way round; after its last epoch it keeps its last pose. The box centre is the
  row's box centre in F_A carried by the pose (the artefact stands on the ground).
* **Alive** means ``t_arrive <= t < t_leave``.

Examples
--------
>>> import pandas as pd
>>> from are_stats import Scene, load_catalogue
>>> table = pd.DataFrame({"class": [0], "mark": [0], "t_arrive": [0.0], "t_leave": [9.0],
...                       "x": [1.0], "y": [2.0], "yaw": [0.0]})
>>> boxes = Scene.from_scenarios(table, load_catalogue()).at(3.0)
>>> boxes.labels.tolist(), boxes.centres[0, :2].tolist()
(['person'], [1.0, 2.0])
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats.builder import box_centres
from are_stats.environment import ArtefactCatalogue

__all__ = ["Boxes", "Scene"]

# the kinds of Scene.events, indexed by the codes of Scene.event_arrays
_KINDS = np.array(["leave", "arrive", "move"], dtype=object)

_NEED = ("t_arrive", "t_leave", "x", "y", "yaw")
_TRACK_NEED = ("id", "t", "x", "y", "yaw")


@dataclass(frozen=True)
class Boxes:
    """The artefact boxes alive at one time.

    Attributes
    ----------
    ids : (n,) int64
        Artefact ids (the scenario table's ``artefact`` column, else the row order).
    centres : (n, 3) float64
        Box centres in the environment frame F_E (m).
    half_extents : (n, 3) float64
        Half sizes of the boxes along the artefact's axes (m).
    yaws : (n,) float64
        Headings (rad, in ``[0, 2 pi)``).
    labels : (n,) object
        Class labels ``l``.
    """

    ids: np.ndarray
    centres: np.ndarray
    half_extents: np.ndarray
    yaws: np.ndarray
    labels: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.size)


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.mod(a, 2.0 * np.pi)


class Scene:
    """The artefacts of one scenario as boxes over time (see the module docstring).

    Build it with :meth:`from_scenarios`. Arrays are per artefact, in table order.

    Attributes
    ----------
    ids : (N,) int64
    labels : (N,) object
    classes, rows : (N,) int64
        Catalogue class position and row of ``Q`` of each artefact.
    half_extents : (N, 3) float64
    offsets : (N, 3) float64
        Box centre in the artefact frame F_A (x forward, z up; the base on the ground).
    t_arrive, t_leave : (N,) float64
    """

    def __init__(
        self,
        ids: np.ndarray,
        labels: np.ndarray,
        classes: np.ndarray,
        rows: np.ndarray,
        half_extents: np.ndarray,
        offsets: np.ndarray,
        t_arrive: np.ndarray,
        t_leave: np.ndarray,
        pose0: np.ndarray,
        track_start: np.ndarray,
        track_t: np.ndarray,
        track_pose: np.ndarray,
        artefacts: pd.DataFrame | None = None,
        class_labels: Sequence[str] | None = None,
    ) -> None:
        self.ids, self.labels, self.classes, self.rows = ids, labels, classes, rows
        # the scenario's table as given (life-cycle, marks, classes), written back by the
        # scenes writer; tracks change only through with_track(s), so it never goes stale
        self.artefacts = artefacts
        self.class_labels = None if class_labels is None else list(class_labels)
        self.half_extents, self.offsets = half_extents, offsets
        self.t_arrive, self.t_leave = t_arrive, t_leave
        self._pose0 = pose0  # (N, 3) arrival x, y, yaw
        self._start = track_start  # (N + 1,) CSR offsets into the track arrays
        self._t = track_t  # (M,) epoch times, sorted within each artefact
        self._pose = track_pose  # (M, 3) x, y, yaw at the epochs
        # one sorted key for every epoch: artefact index * span + (t - t_min)
        owner = np.repeat(np.arange(ids.size), np.diff(track_start))
        self._t_min = float(track_t.min()) if track_t.size else 0.0
        self._span = (float(np.ptp(track_t)) if track_t.size else 0.0) * 2.0 + 1.0
        self._key = owner * self._span + (track_t - self._t_min)

    def __len__(self) -> int:
        return int(self.ids.size)

    def __repr__(self) -> str:
        moving = int(np.count_nonzero(np.diff(self._start)))
        return f"Scene({len(self)} artefacts, {moving} with tracks)"

    @property
    def has_tracks(self) -> np.ndarray:
        """(N,) bool: the artefact moves along a behaviour track."""
        return np.diff(self._start) > 0

    @classmethod
    def from_scenarios(
        cls,
        artefacts: pd.DataFrame,
        catalogue: ArtefactCatalogue,
        tracks: pd.DataFrame | None = None,
        *,
        class_labels: Sequence[str] | None = None,
    ) -> Scene:
        """Build the scene of one scenario.

        Parameters
        ----------
        artefacts : pandas.DataFrame
            One scenario of a scenarios table (:func:`~are_stats.generate_scenarios`):
            columns ``t_arrive, t_leave, x, y, yaw`` and optionally ``class`` (mixture
            component, default 0), ``mark`` (default 0; -1 means none), ``artefact`` (id,
            default the row order), ``scenario`` (a single value).
        catalogue : ArtefactCatalogue
            The property table ``Q`` (:func:`~are_stats.load_catalogue`).
        tracks : pandas.DataFrame, optional
            Behaviour tracks ``id, t, x, y, yaw`` (and ``scenario``): poses at epochs;
            ``id`` matches the artefact ids.
        class_labels : sequence of str, optional
            Label of each mixture component (the fit's ``class_labels``); a class whose
            label the catalogue knows is looked up by label, otherwise by position.

        Returns
        -------
        Scene
        """
        num = _one_scenario("artefacts", artefacts, _NEED, _NEED, "times and poses")
        n = len(artefacts)
        ids = (
            artefacts["artefact"].to_numpy(np.int64)
            if "artefact" in artefacts.columns
            else np.arange(n, dtype=np.int64)
        )
        if np.unique(ids).size != n:
            raise ValueError("artefacts: expected unique 'artefact' ids in one scenario")
        comp = (
            artefacts["class"].to_numpy(np.int64)
            if "class" in artefacts.columns
            else np.zeros(n, np.int64)
        )
        marks = (
            artefacts["mark"].to_numpy(np.int64)
            if "mark" in artefacts.columns
            else np.zeros(n, np.int64)
        )
        labels, classes, rows, half, off = _boxes(catalogue, comp, marks, class_labels)
        start, t, pose = _tracks(tracks, ids)
        return cls(
            ids,
            labels,
            classes,
            rows,
            half,
            off,
            num[:, 0],
            num[:, 1],
            num[:, 2:5],
            start,
            t,
            pose,
            artefacts,
            class_labels,
        )

    def with_tracks(self, tracks: pd.DataFrame | None) -> Scene:
        """A new scene, equal to this one except that its artefacts follow ``tracks``.

        Behaviours are Scene -> Scene: the life-cycle, classes and boxes stay; only the
        poses over time change.

        Parameters
        ----------
        tracks : pandas.DataFrame or None
            ``id, t, x, y, yaw`` (and ``scenario``, one value) as in :meth:`from_scenarios`;
            None: every artefact stands at its arrival pose.

        Returns
        -------
        Scene
        """
        return self._moved(*_tracks(tracks, self.ids))

    def _moved(self, start: np.ndarray, t: np.ndarray, pose: np.ndarray) -> Scene:
        """This scene with the track arrays ``start (N + 1,)``, ``t (M,)``, ``pose (M, 3)``:
        the life-cycle, classes and boxes stay."""
        return Scene(
            self.ids,
            self.labels,
            self.classes,
            self.rows,
            self.half_extents,
            self.offsets,
            self.t_arrive,
            self.t_leave,
            self._pose0,
            start,
            t,
            pose,
            self.artefacts,
            self.class_labels,
        )

    def tracks_table(self) -> pd.DataFrame:
        """The scene's tracks as a table ``id, t, x, y, yaw`` (one row per epoch).

        Returns
        -------
        pandas.DataFrame
            Sorted by artefact (table order) and time; empty without tracks.
        """
        owner = np.repeat(np.arange(self.ids.size), np.diff(self._start))
        return pd.DataFrame(
            {
                "id": self.ids[owner],
                "t": self._t,
                "x": self._pose[:, 0],
                "y": self._pose[:, 1],
                "yaw": self._pose[:, 2],
            }
        )

    # ---- poses ------------------------------------------------------------------------------

    def poses(self, t: float, which: npt.ArrayLike | None = None) -> np.ndarray:
        """``(k, 3)`` poses ``x, y, yaw`` of artefacts ``which`` (indices; default all) at ``t``."""
        return self.poses_at(np.array([float(t)]), which)[0]

    def poses_at(self, times: npt.ArrayLike, which: npt.ArrayLike | None = None) -> np.ndarray:
        """``(m, k, 3)`` poses ``x, y, yaw`` of artefacts ``which`` (indices; default all) at
        each of ``times`` (m,): :meth:`poses` at every time, in one vectorised pass."""
        tt = np.asarray(times, float).reshape(-1)
        idx = np.arange(len(self)) if which is None else np.asarray(which, np.int64).reshape(-1)
        out = np.repeat(self._pose0[idx][None], tt.size, axis=0)
        n_ep = self._start[idx + 1] - self._start[idx]
        moving = n_ep > 0
        if not moving.any() or not tt.size:
            return out
        i = idx[moving]
        lo, hi = self._start[i], self._start[i + 1] - 1
        q = i * self._span + (tt[:, None] - self._t_min)  # (m, j)
        k = np.searchsorted(self._key, q, side="right") - 1  # last epoch <= t
        before = k < lo
        k = np.clip(k, lo, hi)
        k1 = np.minimum(k + 1, hi)
        t0, t1 = self._t[k], self._t[k1]
        gap = t1 > t0
        f = np.where(gap, np.clip((tt[:, None] - t0) / np.where(gap, t1 - t0, 1.0), 0, 1), 0)
        p0, p1 = self._pose[k], self._pose[k1]
        xy = p0[..., :2] + f[..., None] * (p1[..., :2] - p0[..., :2])
        dyaw = np.mod(p1[..., 2] - p0[..., 2] + np.pi, 2 * np.pi) - np.pi  # the short way round
        yaw = _wrap(p0[..., 2] + f * dyaw)
        track = np.concatenate([xy, yaw[..., None]], axis=-1)
        out[:, moving] = np.where(before[..., None], self._pose0[i][None], track)
        return out

    def track(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """The behaviour track of artefact ``i`` (an index in table order).

        Returns
        -------
        t : (m,) float64
            Epoch times, increasing (empty without a track).
        pose : (m, 3) float64
            ``x, y, yaw`` at the epochs.
        """
        i = self._index(i)
        lo, hi = self._start[i], self._start[i + 1]
        return self._t[lo:hi].copy(), self._pose[lo:hi].copy()

    def next_epoch(self, t: float, which: npt.ArrayLike | None = None) -> np.ndarray:
        """``(k,)`` the first track epoch after ``t`` of artefacts ``which`` (indices;
        default all), ``inf`` where there is none."""
        idx = np.arange(len(self)) if which is None else np.asarray(which, np.int64)
        q = idx * self._span + (float(t) - self._t_min)
        k = np.maximum(np.searchsorted(self._key, q, side="right"), self._start[idx])
        ok = k < self._start[idx + 1]
        out = np.full(idx.size, np.inf)
        out[ok] = self._t[k[ok]]
        return out

    def with_track(self, i: int, t: npt.ArrayLike, pose: npt.ArrayLike) -> Scene:
        """A new scene, equal to this one except that artefact ``i`` follows the track
        ``t`` (m,) increasing, ``pose`` (m, 3) ``x, y, yaw`` (this scene is unchanged).

        The experiment loop uses it to make an artefact detour around the robot or wait for
        it (the rest of its track delayed); its life-cycle (arrival, leaving) is unchanged.

        Raises
        ------
        ValueError
            If ``i`` is not an artefact index, or ``t``/``pose`` are not finite, of
            matching shapes, with ``t`` strictly increasing.
        """
        i = self._index(i)
        tt = np.asarray(t, float).reshape(-1)
        pp = np.asarray(pose, float)
        if pp.shape != (tt.size, 3) or not (np.isfinite(tt).all() and np.isfinite(pp).all()):
            raise ValueError(
                f"with_track: expected finite t (m,) and pose (m, 3), got shapes "
                f"{tt.shape} and {pp.shape}"
            )
        if (np.diff(tt) <= 0).any():
            raise ValueError("with_track: expected strictly increasing epoch times t")
        lo, hi = self._start[i], self._start[i + 1]
        start = self._start.copy()
        start[i + 1 :] += tt.size - (hi - lo)
        return self._moved(
            start,
            np.concatenate([self._t[:lo], tt, self._t[hi:]]),
            np.concatenate([self._pose[:lo], pp, self._pose[hi:]]),
        )

    def _index(self, i: object) -> int:
        if isinstance(i, bool) or not isinstance(i, int | np.integer) or not 0 <= i < len(self):
            raise ValueError(f"i: expected an artefact index in [0, {len(self)}), got {i!r}")
        return int(i)

    def alive(self, t: float) -> np.ndarray:
        """(N,) bool: ``t_arrive <= t < t_leave``."""
        return (self.t_arrive <= t) & (t < self.t_leave)

    def at(self, t: float) -> Boxes:
        """The boxes alive at time ``t`` (vectorised over artefacts).

        Returns
        -------
        Boxes
        """
        idx = np.flatnonzero(self.alive(float(t)))
        pose = self.poses(float(t), idx)
        centres = box_centres(pose, self.offsets[idx])
        return Boxes(
            self.ids[idx],
            centres,
            self.half_extents[idx].copy(),
            _wrap(pose[:, 2]),
            self.labels[idx],
        )

    def events(self, t0: float, t1: float) -> pd.DataFrame:
        """Arrivals, leavings and moves (track epochs of live artefacts) in ``(t0, t1]``.

        Returns
        -------
        pandas.DataFrame
            Columns ``t, kind ("arrive" | "leave" | "move"), id``, sorted by time (leaves
            before arrivals before moves at equal times).
        """
        t, kind, idx = self.event_arrays(t0, t1)
        return pd.DataFrame({"t": t, "kind": _KINDS[kind], "id": self.ids[idx]})

    def event_arrays(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`events` as arrays, in the same order (for loops that read them often).

        Returns
        -------
        t : (k,) float64
            Event times in ``(t0, t1]``.
        kind : (k,) int8
            0 leave, 1 arrive, 2 move.
        index : (k,) int64
            The artefact's index in the scene (table order).
        """
        a = np.flatnonzero((self.t_arrive > t0) & (self.t_arrive <= t1))
        lv = np.flatnonzero((self.t_leave > t0) & (self.t_leave <= t1))
        owner = np.repeat(np.arange(len(self)), np.diff(self._start))
        mv = np.flatnonzero(
            (self._t > t0)
            & (self._t <= t1)
            & (self._t >= self.t_arrive[owner])
            & (self._t < self.t_leave[owner])
        )
        t = np.concatenate([self.t_leave[lv], self.t_arrive[a], self._t[mv]])
        kind = np.repeat(np.array([0, 1, 2], np.int8), [lv.size, a.size, mv.size])
        idx = np.concatenate([lv, a, owner[mv]]).astype(np.int64)
        keys = np.lexsort((self.ids[idx], kind, t))
        return t[keys], kind[keys], idx[keys]


def _boxes(
    catalogue: ArtefactCatalogue,
    comp: np.ndarray,
    marks: np.ndarray,
    class_labels: Sequence[str] | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Label, class position, row of Q, half extents and F_A box centre per artefact."""
    n_cls = len(catalogue)
    names = list(class_labels) if class_labels is not None else None
    pairs, inv = np.unique(
        np.stack([comp, np.maximum(marks, 0)], axis=1), axis=0, return_inverse=True
    )
    inv = inv.ravel()
    table = []
    for c, x in pairs.tolist():
        if names is not None and 0 <= c < len(names) and names[c] in catalogue:
            cls = catalogue[names[c]]
        else:
            cls = catalogue.row(int(np.clip(c, 0, n_cls - 1)))
        row = cls.property_row(int(x))
        table.append(
            (
                row.label,
                row.class_row,
                row.row,
                row.half_extents,
                (row.bounds[0] + row.bounds[1]) / 2.0,
            )
        )
    labels = np.array([table[k][0] for k in inv], dtype=object)
    classes = np.array([table[k][1] for k in inv], dtype=np.int64).reshape(-1)
    rows = np.array([table[k][2] for k in inv], dtype=np.int64).reshape(-1)
    half = np.array([table[k][3] for k in inv], dtype=float).reshape(-1, 3)
    off = np.array([table[k][4] for k in inv], dtype=float).reshape(-1, 3)
    return labels, classes, rows, half, off


def _one_scenario(
    name: str, table: object, need: Sequence[str], numeric: Sequence[str], what: str
) -> np.ndarray:
    """The ``numeric`` columns of one scenario's table ``name``, as (rows, k) floats.

    Raises ``ValueError`` naming ``name`` for anything but a DataFrame, missing ``need``
    columns, several values of ``scenario``, or a non-finite number (``what`` says which).
    """
    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"{name}: expected a DataFrame, got {type(table).__name__}")
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise ValueError(f"{name}: expected columns {list(need)}, missing {missing}")
    if "scenario" in table.columns and table["scenario"].nunique() > 1:
        raise ValueError(f"{name}: expected one scenario, got several (filter by 'scenario')")
    num = table[list(numeric)].to_numpy(float)
    if not np.isfinite(num).all():
        r = int(np.argwhere(~np.isfinite(num))[0, 0])
        raise ValueError(f"{name}: row {r}: expected finite {what}")
    return num


def _tracks(
    tracks: pd.DataFrame | None, ids: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR arrays (start (N+1,), t (M,), pose (M, 3)) of the tracks, in artefact order."""
    n = ids.size
    if tracks is None or len(tracks) == 0:
        return np.zeros(n + 1, np.int64), np.zeros(0), np.zeros((0, 3))
    poses = ("t", "x", "y", "yaw")
    num = _one_scenario("tracks", tracks, _TRACK_NEED, poses, ", ".join(poses))
    tid = tracks["id"].to_numpy(np.int64)
    order_ids = np.argsort(ids, kind="stable")
    pos = np.searchsorted(ids[order_ids], tid)
    pos = np.clip(pos, 0, n - 1)
    known = ids[order_ids][pos] == tid
    if not known.all():
        bad = int(tid[~known][0])
        raise ValueError(f"tracks: id {bad} is not an artefact of the scenario")
    owner = order_ids[pos]
    keys = np.lexsort((num[:, 0], owner))
    owner, num = owner[keys], num[keys]
    dup = (np.diff(owner) == 0) & (np.diff(num[:, 0]) == 0)
    if dup.any():
        r = int(np.flatnonzero(dup)[0])
        raise ValueError(
            f"tracks: artefact {int(ids[owner[r]])} has two poses at t={float(num[r, 0])!r}"
        )
    start = np.zeros(n + 1, np.int64)
    np.add.at(start, owner + 1, 1)
    return np.cumsum(start), num[:, 0].copy(), num[:, 1:4].copy()
