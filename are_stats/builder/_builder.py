"""The AR-builder server (paper Sect. 3.3, Fig. 4): registration, collisions, resolution.

Artefacts are upright boxes ``b`` (from the catalogue Q) at planar poses ``(x, y, yaw)`` of
their frame F_A in F_E. Registration projects the box footprint on M_2D (exact coverage:
every cell that shares positive area with the footprint) and concatenates the vertices of
the artefact mesh S_A to the voxels of M_3D; the augmented grid and voxel map are views over
the base maps that :meth:`ARBuilder.reset` restores.

Collisions (DECISIONS 9): pairwise oriented-box hit tests between artefacts (spatial-hash
broad phase, separating-axis narrow phase) and embedding tests of each box against the
environment: occupied cells of M_2D (and unknown cells when ``unknown_blocks``), the map
border, and the triangles of S_E when a mesh is given. A colliding move is resolved by
``rule="revert"`` (back to the artefact's last safe pose, the default) or
``rule="advance"`` (along the move only up to the largest collision-free fraction, less
``safe_distance`` metres); every resolution is recorded in :attr:`ARBuilder.log`.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite, check_in, check_nonnegative, check_positive
from are_stats.builder._broadphase import SpatialHash, aabb_pairs
from are_stats.builder._geometry import (
    box_centres,
    box_corners,
    box_runs,
    obb_overlap,
    runs_to_cells,
    triangle_box_overlap,
)
from are_stats.environment import (
    ArtefactCatalogue,
    OccupancyGrid,
    TransformTree,
    VoxelMap,
    planar_pose_matrix,
    surface_points,
)

if TYPE_CHECKING:
    import trimesh

    from are_stats.scenarios import Scene

__all__ = ["ARBuilder", "Resolution", "Placement"]

_HEADINGS = np.array([0.0, np.pi / 2, np.pi, 3 * np.pi / 2])
#: Open ground: a box whose footprint corners keep this many cells inside the map's
#: border is inside the map (its rasterised runs are off by far less than a cell).
_BORDER_CELLS = 2.0


class Resolution(NamedTuple):
    """One resolved collision.

    Attributes
    ----------
    time : float
        Time (or epoch) of the step.
    artefact : int
        Id of the artefact whose move was changed.
    rule : str
        ``"revert"`` or ``"advance"``.
    cause : str
        ``"environment"`` (occupied / blocked cells), ``"bounds"`` (left the map),
        ``"mesh"`` (hit S_E) or ``"artefact"``.
    other : int
        Id of the other artefact for ``cause == "artefact"``, else ``-1``.
    fraction : float
        Fraction of the proposed move that was kept (0 for a revert).
    """

    time: float
    artefact: int
    rule: str
    cause: str
    other: int
    fraction: float


class Placement(NamedTuple):
    """Outcome of :meth:`ARBuilder.place`.

    Attributes
    ----------
    ok : bool
        ``False`` when no collision-free pose was found in ``max_tries`` ("area full").
    artefact : int
        Id of the registered artefact (``-1`` when not ok).
    pose : (3,) float
        Its pose ``(x, y, yaw)`` (NaN when not ok).
    tries : int
        Candidate poses drawn.
    """

    ok: bool
    artefact: int
    pose: np.ndarray
    tries: int


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


class ARBuilder:
    """Registers artefacts on M_2D / M_3D, detects and resolves their collisions.

    Parameters
    ----------
    grid : OccupancyGrid
        The base map M_2D.
    catalogue : ArtefactCatalogue, optional
        The table Q (needed to register artefacts by label).
    voxels : VoxelMap, optional
        The base map M_3D; default an empty map at ``voxel_resolution``.
    env_mesh : trimesh.Trimesh, optional
        The environment mesh S_E for embedding tests.
    rule : {"revert", "advance"}
        Collision resolution rule (DECISIONS 9).
    safe_distance : float
        For ``"advance"``: metres kept back from the first contact.
    unknown_blocks : bool
        Whether unknown cells block artefacts like occupied ones.
    voxel_resolution : float
        Resolution of the default M_3D.
    eps : float
        Contacts shallower than ``eps`` metres do not count as collisions.

    Examples
    --------
    >>> from are_stats import OccupancyGrid
    >>> g = OccupancyGrid(np.zeros((100, 100)), 0.1)
    >>> b = ARBuilder(g)
    >>> a = b.register(None, [2.0, 2.0, 0.0], size=[1.0, 0.5, 1.0])
    >>> c = b.register(None, [5.0, 5.0, 0.0], size=[1.0, 0.5, 1.0])
    >>> b.step([[2.0, 2.0, 0.0], [2.5, 2.0, 0.0]], time=1.0).tolist()  # c would hit a
    [[2.0, 2.0, 0.0], [5.0, 5.0, 0.0]]
    >>> b.log[0].cause, b.log[0].other
    ('artefact', 0)
    """

    #: :meth:`resolve_scene` with ``rule="revert"`` holds a colliding move itself, as
    #: :meth:`step` of that one move would (False: through :meth:`step`, the reference
    #: tests/builder compares it with)
    _direct_revert: bool = True

    def __init__(
        self,
        grid: OccupancyGrid,
        catalogue: ArtefactCatalogue | None = None,
        *,
        voxels: VoxelMap | None = None,
        env_mesh: trimesh.Trimesh | None = None,
        rule: str = "revert",
        safe_distance: float = 0.0,
        unknown_blocks: bool = False,
        voxel_resolution: float = 0.1,
        eps: float = 1e-9,
        advance_iters: int = 12,
    ) -> None:
        if not isinstance(grid, OccupancyGrid):
            raise ValueError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
        self.grid = grid
        self.catalogue = catalogue
        self.rule = check_in("rule", rule, ("revert", "advance"))
        self.safe_distance = float(check_nonnegative("safe_distance", safe_distance))
        self.eps = float(check_nonnegative("eps", eps))
        self.advance_iters = int(advance_iters)
        self.unknown_blocks = bool(unknown_blocks)
        self.base_voxels = (
            voxels
            if voxels is not None
            else VoxelMap(check_positive("voxel_resolution", voxel_resolution))
        )
        self._mesh_tris: np.ndarray | None = None
        self._mesh_hash: SpatialHash | None = None
        if env_mesh is not None:
            tris = np.asarray(env_mesh.triangles, dtype=float)
            if tris.size:
                lo, hi = tris[..., :2].min(axis=1), tris[..., :2].max(axis=1)
                cell = max(1.0, 4 * grid.resolution)
                self._mesh_tris = tris
                self._mesh_hash = SpatialHash(lo, hi, cell)
        self._surface_cache: dict[str, np.ndarray] = {}
        self.reset()

    # ------------------------------------------------------------ the base map's tables
    # (made on the first collision test or placement: a builder that only rasterises, such
    # as the planner's map of perceived_grid, never pays for them; copies share them)
    @functools.cached_property
    def _blocked(self) -> np.ndarray:
        """``(H, W)`` bool: cells that block artefacts."""
        g = self.grid
        return g.occupied | (g.unknown if self.unknown_blocks else False)

    @functools.cached_property
    def _prefix(self) -> np.ndarray:
        """``(H, W + 1)`` int32 row prefix sums of :attr:`_blocked` (blocked cells of a run
        in O(1))."""
        prefix = np.zeros((self.grid.height, self.grid.width + 1), dtype=np.int32)
        np.cumsum(self._blocked, axis=1, out=prefix[:, 1:])
        return prefix

    @functools.cached_property
    def _free_flat(self) -> np.ndarray:
        """Flat indices of the free cells that do not block: where :meth:`place` draws."""
        return np.flatnonzero(self.grid.free.ravel() & ~self._blocked.ravel())

    # ------------------------------------------------------------ state
    def reset(self) -> None:
        """Remove every artefact and clear the resolution log (the base maps are kept)."""
        self.ids = np.zeros(0, np.int64)
        self.labels: list[str] = []
        self.poses = np.zeros((0, 3))
        self._half = np.zeros((0, 3))
        self._offset = np.zeros((0, 3))
        self._next_id = 0
        self._runs: tuple[np.ndarray, ...] | None = None
        self.log: list[Resolution] = []
        self._epoch = 0

    def __len__(self) -> int:
        return int(self.ids.size)

    def index_of(self, artefact_id: int) -> int:
        """Row of ``artefact_id`` in :attr:`ids` / :attr:`poses`."""
        hit = np.flatnonzero(self.ids == int(artefact_id))
        if hit.size == 0:
            raise ValueError(f"artefact_id: no live artefact with id {artefact_id!r}")
        return int(hit[0])

    def _dims(self, label: str | None, size: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        if size is not None:
            s = check_positive("size", size, ndim=1)
            if s.shape != (3,):
                raise ValueError(f"size: expected [length, width, height], got {s.tolist()}")
            return s / 2.0, np.array([0.0, 0.0, s[2] / 2.0])
        if self.catalogue is None:
            raise ValueError("label: registering by label needs a catalogue (or pass size=)")
        cls = self.catalogue[label]  # raises a clear error for unknown labels
        return cls.half_extents.copy(), cls.box_centre.copy()

    def boxes(
        self, poses: npt.ArrayLike | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Box centres ``(n, 3)``, half sizes ``(n, 3)`` and yaws ``(n,)`` at ``poses``
        (default the current poses)."""
        P = self.poses if poses is None else np.asarray(poses, float)
        return self._boxes_for(P, self._half, self._offset)

    @staticmethod
    def _boxes_for(P: np.ndarray, half: np.ndarray, offset: np.ndarray):
        return box_centres(P, offset), half, P[:, 2]

    # ------------------------------------------------------------ collision tests
    def _footprints(self, centre, half, yaw):
        g = self.grid
        uv = g.world_to_local(centre[:, :2])
        return box_runs(uv, half[:, :2] / g.resolution, yaw - g.origin[2], g.shape)

    def _env_hits(
        self, centre: np.ndarray, half: np.ndarray, yaw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """Per box: blocked cells hit, outside the map, mesh hit; and the runs."""
        runs = self._footprints(centre, half, yaw)
        owner, rows, jlo, jhi, outside = runs
        cnt = self._prefix[rows, jhi + 1] - self._prefix[rows, jlo]
        env = np.bincount(owner[cnt > 0], minlength=centre.shape[0]) > 0
        mesh = np.zeros(centre.shape[0], bool)
        if self._mesh_hash is not None and centre.shape[0]:
            corners = box_corners(centre[:, :2], half[:, :2], yaw)
            qa, tb = self._mesh_hash.query(corners.min(axis=1), corners.max(axis=1))
            if qa.size:
                hit = triangle_box_overlap(
                    self._mesh_tris[tb], centre[qa], half[qa], yaw[qa], self.eps
                )
                mesh[qa[hit]] = True
        return env, outside, mesh, runs

    def _pair_hits(self, centre, half, yaw) -> np.ndarray:
        """``(m, 2)`` index pairs of colliding boxes."""
        if centre.shape[0] < 2:
            return np.zeros((0, 2), np.int64)
        pairs = aabb_pairs(*_aabbs(centre, half, yaw))
        if pairs.size == 0:
            return pairs
        a, b = pairs[:, 0], pairs[:, 1]
        hit = obb_overlap(centre[a], half[a], yaw[a], centre[b], half[b], yaw[b], self.eps)
        return pairs[hit]

    def _hits_against(self, idx, centre, half, yaw, o_centre, o_half, o_yaw) -> np.ndarray:
        """Boxes ``idx`` (at ``centre``...) vs all others (``o_*``), skipping themselves."""
        out = np.zeros(idx.size, bool)
        if idx.size == 0 or o_centre.shape[0] == 0:
            return out
        o_lo, o_hi = _aabbs(o_centre, o_half, o_yaw)
        h = SpatialHash(o_lo, o_hi, float((o_hi - o_lo).max()))
        qa, sb = h.query(*_aabbs(centre, half, yaw))
        keep = sb != idx[qa]
        qa, sb = qa[keep], sb[keep]
        hit = obb_overlap(
            centre[qa], half[qa], yaw[qa], o_centre[sb], o_half[sb], o_yaw[sb], self.eps
        )
        out[qa[hit]] = True
        return out

    def collisions(self, poses: npt.ArrayLike | None = None) -> dict[str, np.ndarray]:
        """Collision report for ``(n, 3)`` poses (default: the current ones).

        Returns
        -------
        dict
            ``environment``, ``bounds``, ``mesh``: ``(n,)`` bool; ``pairs``: ``(m, 2)``
            artefact ids of colliding pairs.
        """
        P = self._check_poses(poses) if poses is not None else self.poses
        centre, half, yaw = self.boxes(P)
        env, outside, mesh, _ = self._env_hits(centre, half, yaw)
        pairs = self._pair_hits(centre, half, yaw)
        return {
            "environment": env,
            "bounds": outside,
            "mesh": mesh,
            "pairs": self.ids[pairs] if pairs.size else np.zeros((0, 2), np.int64),
        }

    # ------------------------------------------------------------ registration
    def register(
        self,
        label: str | None,
        pose: npt.ArrayLike,
        *,
        size: npt.ArrayLike | None = None,
        artefact_id: int | None = None,
        check: bool = True,
    ) -> int:
        """Register one artefact at ``pose = (x, y, yaw)`` of F_A in F_E and return its id
        (:meth:`register_many` registers a batch in one vectorised pass).

        Parameters
        ----------
        label : str or None
            Catalogue class (its mesh bounding box is ``b``); ``None`` with ``size``.
        pose : (3,) float
        size : (3,) float, optional
            Box length, width, height (F_A at the centre of the box base) instead of a
            catalogue class.
        artefact_id : int, optional
            Id to use (default: the next free one).
        check : bool
            Refuse a pose that collides with the environment or another artefact.

        Returns
        -------
        int
            The artefact id.
        """
        p = check_finite("pose", pose, ndim=1)
        if p.shape != (3,):
            raise ValueError(f"pose: expected (x, y, yaw), got {p.tolist()}")
        half, offset = self._dims(label, size)
        ids = None if artefact_id is None else [int(artefact_id)]
        return int(self._add([label], p[None], half[None], offset[None], ids, check)[0])

    def register_many(
        self,
        labels: Sequence[str | None],
        poses: npt.ArrayLike,
        *,
        sizes: npt.ArrayLike | None = None,
        artefact_ids: npt.ArrayLike | None = None,
        check: bool = True,
    ) -> np.ndarray:
        """Register ``n`` artefacts at once: what ``n`` calls of :meth:`register` do, in
        one vectorised pass (the same ids, boxes and footprints, in the same order).

        Parameters
        ----------
        labels : sequence of n str or None
            Catalogue classes; ``None`` entries (or every entry) with ``sizes``.
        poses : (n, 3) float
            ``(x, y, yaw)`` of each F_A in F_E.
        sizes : (n, 3) float, optional
            Box length, width, height of each artefact (F_A at the centre of the box base)
            instead of its catalogue class.
        artefact_ids : (n,) int, optional
            Ids to use (default: the next free ones, in order).
        check : bool
            Refuse the whole batch (``ValueError``, nothing registered) when a box collides
            with the environment, an artefact already registered or another box of the
            batch.

        Returns
        -------
        (n,) int64
            The artefact ids, in input order.

        Examples
        --------
        >>> from are_stats import OccupancyGrid
        >>> b = ARBuilder(OccupancyGrid(np.zeros((100, 100)), 0.1))
        >>> b.register_many([None, None], [[2.0, 2.0, 0.0], [5.0, 5.0, 0.0]],
        ...                 sizes=[[1.0, 0.5, 1.0]] * 2).tolist()
        [0, 1]
        """
        P = check_finite("poses", poses, ndim=2)
        n = P.shape[0]
        if P.shape[1] != 3:
            raise ValueError(f"poses: expected (n, 3) rows (x, y, yaw), got shape {P.shape}")
        labels = list(labels)
        if len(labels) != n:
            raise ValueError(f"labels: expected {n} labels (one per pose), got {len(labels)}")
        half, offset = self._dims_many(labels, sizes, n)
        return self._add(labels, P, half, offset, artefact_ids, check)

    def _add(
        self,
        labels: list[str | None],
        P: np.ndarray,
        half: np.ndarray,
        offset: np.ndarray,
        artefact_ids: npt.ArrayLike | None,
        check: bool,
    ) -> np.ndarray:
        """Append ``n`` checked boxes (poses, half sizes and centres in F_A, ``(n, 3)``)."""
        n = P.shape[0]
        if artefact_ids is None:
            ids = self._next_id + np.arange(n, dtype=np.int64)
        else:
            ids = np.asarray(artefact_ids).astype(np.int64).reshape(-1)
            if ids.shape != (n,):
                raise ValueError(f"artefact_ids: expected {n} ids, got {ids.size}")
            # (default ids are past every id in use: no check needed)
            taken = np.isin(ids, self.ids) if self.ids.size else np.zeros(n, bool)
            if not taken.any() and np.unique(ids).size < n:  # twice in the batch
                taken = ~np.isin(np.arange(n), np.unique(ids, return_index=True)[1])
            if taken.any():
                aid = int(ids[np.argmax(taken)])
                raise ValueError(f"artefact_id: id {aid} is already registered")
        hit = self._collision(P, half, offset, live=True) if check and n else None
        if hit is not None:
            raise ValueError(f"pose: artefact box at {P[hit[0]].tolist()} collides with {hit[1]}")
        self.ids = np.r_[self.ids, ids]
        self.labels.extend(lab if lab is not None else "box" for lab in labels)
        self.poses = np.vstack([self.poses, P])
        self._half = np.vstack([self._half, half])
        self._offset = np.vstack([self._offset, offset])
        if n:
            self._next_id = max(self._next_id, int(ids.max()) + 1)
        self._runs = None
        return ids.copy()

    def _dims_many(
        self, labels: list[str | None], sizes: npt.ArrayLike | None, n: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Half sizes and box centres in F_A, ``(n, 3)`` each, from ``sizes`` or Q."""
        if sizes is not None:
            s = check_positive("sizes", sizes, ndim=2)
            if s.shape != (n, 3):
                raise ValueError(
                    f"sizes: expected ({n}, 3) rows [length, width, height], got {s.shape}"
                )
            return s / 2.0, np.column_stack([np.zeros((n, 2)), s[:, 2] / 2.0])
        dims = [self._dims(lab, None) for lab in labels]
        if not dims:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return np.stack([d[0] for d in dims]), np.stack([d[1] for d in dims])

    def _collision(
        self, P: np.ndarray, half: np.ndarray, offset: np.ndarray, *, live: bool
    ) -> tuple[int, str, int] | None:
        """The first box at poses ``P`` (n, 3) that collides, as ``(row, what, other)``:
        with the environment (``other = -1``), with a live box when ``live`` (``-1``), or
        with box ``other`` of ``P``; None when none does."""
        c, h, y = self._boxes_for(P, half, offset)
        env, outside, mesh, _ = self._env_hits(c, h, y)
        bad = env | outside | mesh
        if bad.any():
            k = int(np.argmax(bad))
            return k, "the map border" if outside[k] else "the environment", -1
        if live:
            hit = self._hits_against(np.full(P.shape[0], -1), c, h, y, *self.boxes())
            if hit.any():
                return int(np.argmax(hit)), "an artefact", -1
        pairs = self._pair_hits(c, h, y)
        if pairs.size:
            return int(pairs[0, 1]), "an artefact", int(pairs[0, 0])
        return None

    def register_scene(self, scene: Scene, t: float, *, check: bool = False) -> np.ndarray:
        """Hold exactly the artefacts of ``scene`` alive at time ``t``, where they are then.

        The builder's boxes become those of ``scene.at(t)``: artefacts that are not alive
        at ``t`` are removed, the live ones are registered (or moved, when already
        registered) under their scene ids and labels at their scene pose, each with the
        box of its row of Q (:class:`~are_stats.Scene`, DECISIONS 5). The poses are taken
        as they are: to resolve collisions of a move, pass the scene's poses to
        :meth:`step` instead. The resolution log is kept.

        Parameters
        ----------
        scene : Scene
            One scenario's artefacts (:meth:`Scene.from_scenarios`).
        t : float
            Time on the scenario's clock.
        check : bool
            Refuse (``ValueError``, nothing changed) a scene whose live boxes collide with
            the environment or with each other.

        Returns
        -------
        (n,) int64
            The registered ids, in scene order (aligned with :attr:`ids`).

        Examples
        --------
        >>> import pandas as pd
        >>> from are_stats import OccupancyGrid, Scene, load_catalogue
        >>> table = pd.DataFrame({"t_arrive": [0.0, 5.0], "t_leave": [9.0, 9.0],
        ...                       "x": [2.0, 6.0], "y": [2.0, 6.0], "yaw": [0.0, 0.0]})
        >>> scene = Scene.from_scenarios(table, load_catalogue())
        >>> b = ARBuilder(OccupancyGrid(np.zeros((100, 100)), 0.1), load_catalogue())
        >>> b.register_scene(scene, 1.0).tolist()
        [0]
        >>> later = b.with_scene(scene, 6.0)  # a new builder; b is unchanged
        >>> later.ids.tolist(), b.ids.tolist()
        ([0, 1], [0])
        >>> b.register_scene(scene, 6.0).tolist()
        [0, 1]
        """
        # lazy: a cycle (scenarios imports the builder); +1.95 s CPU on `import are_stats.builder`
        from are_stats.scenarios import Scene

        if not isinstance(scene, Scene):
            raise ValueError(f"scene: expected a Scene, got {type(scene).__name__}")
        t = float(check_finite("t", t, ndim=0))
        idx = np.flatnonzero(scene.alive(t))
        poses = scene.poses(t, idx)
        half, offset = scene.half_extents[idx], scene.offsets[idx]
        hit = self._collision(poses, half, offset, live=False) if check and idx.size else None
        if hit is not None:
            k, what, other = hit
            if other >= 0:
                a, b = scene.ids[idx[[other, k]]].tolist()
                raise ValueError(f"scene: artefacts {a} and {b} collide at t={t!r}")
            raise ValueError(
                f"scene: artefact {int(scene.ids[idx[k]])} at t={t!r} collides with {what}"
            )
        self.ids = scene.ids[idx].astype(np.int64)
        self.labels = [str(lab) for lab in scene.labels[idx]]
        self.poses = poses.astype(float)
        self._half, self._offset = half.astype(float), offset.astype(float)
        if idx.size:
            self._next_id = max(self._next_id, int(self.ids.max()) + 1)
        self._runs = None
        return self.ids.copy()

    def with_scene(self, scene: Scene, t: float, *, check: bool = False) -> ARBuilder:
        """A new builder that holds the artefacts of ``scene`` alive at ``t``, as
        :meth:`register_scene` would make this one hold them; this builder is unchanged.

        The base maps, the mesh index and the catalogue are shared (they are never
        changed); the artefacts, their footprints and the resolution log are the new
        builder's own. The experiment loop keeps its builder as state this way
        (:func:`~are_stats.experiments.run_mission`).

        Returns
        -------
        ARBuilder

        Examples
        --------
        See :meth:`register_scene`.
        """
        new = copy.copy(self)
        new.log = list(self.log)
        new.register_scene(scene, t, check=check)
        return new

    def remove(self, artefact_id: int) -> None:
        """Remove an artefact (it leaves the scene; its cells and voxels are released)."""
        k = self.index_of(artefact_id)
        keep = np.arange(self.ids.size) != k
        self.ids = self.ids[keep]
        del self.labels[k]
        self.poses = self.poses[keep]
        self._half = self._half[keep]
        self._offset = self._offset[keep]
        self._runs = None

    def place(
        self,
        label: str | None,
        seed: int | np.random.Generator,
        *,
        size: npt.ArrayLike | None = None,
        yaw: float | None = None,
        max_tries: int = 1000,
        batch: int = 64,
    ) -> Placement:
        """Register a new arrival uniformly over the free cells where its footprint fits.

        A free cell is drawn uniformly, the position uniformly inside it and the yaw
        uniformly among the 4 headings (DECISIONS 4, 6) unless ``yaw`` is given; poses that
        collide are rejected. After ``max_tries`` candidates the outcome is "area full"
        (``Placement.ok`` false): never an endless loop.
        """
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        if int(max_tries) < 1:
            raise ValueError(f"max_tries: expected an integer >= 1, got {max_tries!r}")
        half, offset = self._dims(label, size)
        tries = 0
        nan = np.full(3, np.nan)
        if self._free_flat.size == 0:
            return Placement(False, -1, nan, 0)
        oc, oh, oy = self.boxes()
        while tries < max_tries:
            m = min(int(batch), int(max_tries) - tries)
            cells = rng.choice(self._free_flat, size=m)
            i, j = np.divmod(cells, self.grid.width)
            uv = np.stack([j + rng.random(m), i + rng.random(m)], axis=1)
            xy = self.grid.local_to_world(uv)
            th = rng.choice(_HEADINGS, size=m) if yaw is None else np.full(m, float(yaw))
            P = np.column_stack([xy, th])
            c, h, y = self._boxes_for(P, np.tile(half, (m, 1)), np.tile(offset, (m, 1)))
            env, outside, mesh, _ = self._env_hits(c, h, y)
            bad = env | outside | mesh
            bad |= self._hits_against(np.full(m, -1), c, h, y, oc, oh, oy)
            good = np.flatnonzero(~bad)
            if good.size:
                k = int(good[0])
                tries += k + 1
                aid = self.register(label, P[k], size=size, check=False)
                return Placement(True, aid, P[k].copy(), tries)
            tries += m
        return Placement(False, -1, nan, tries)

    # ------------------------------------------------------------ the epoch hook
    def _check_poses(self, poses: npt.ArrayLike) -> np.ndarray:
        if isinstance(poses, Mapping):
            P = self.poses.copy()
            for aid, pose in poses.items():
                P[self.index_of(aid)] = check_finite(f"poses[{aid}]", pose, ndim=1)
            return P
        P = check_finite("poses", poses)
        if P.shape != (self.ids.size, 3):
            raise ValueError(
                f"poses: expected an ({self.ids.size}, 3) array aligned with ids, got {P.shape}"
            )
        return P

    def step(self, poses: npt.ArrayLike, time: float | None = None) -> np.ndarray:
        """Move every artefact to its proposed pose, resolving collisions by the rule.

        A move whose box would be embedded in the environment, or hit another artefact's
        box, is resolved by the builder's rule (DECISIONS 9): back to the artefact's last
        safe pose (``"revert"``) or along its move up to a safe distance (``"advance"``).
        Two artefacts that would exchange places (each one's new box on the other's box
        before the move: they would pass through each other) both stay where they were,
        whatever the rule. Resolutions are appended to :attr:`log`.

        Parameters
        ----------
        poses : (n, 3) float or mapping of id to (3,) pose
            Proposed poses ``(x, y, yaw)`` aligned with :attr:`ids` (or a dict; missing
            artefacts stay where they are).
        time : float, optional
            Time stamp recorded in the log (default: an epoch counter).

        Returns
        -------
        (n, 3) float
            Resolved poses, aligned with :attr:`ids`; they become the new safe poses and
            are collision-free if the previous poses were.
        """
        P = self._check_poses(poses).copy()
        t = float(self._epoch if time is None else check_finite("time", time))
        self._epoch += 1
        S = self.poses
        n = S.shape[0]
        if n == 0:
            return P
        at_safe = ~(P != S).any(axis=1)
        # 1. embedding in the environment
        idx = np.flatnonzero(~at_safe)
        bad, causes = self._env_bad(idx, P)
        if bad.any():
            bi = idx[bad]
            frac = self._advance(bi, S, P) if self.rule == "advance" else np.zeros(bi.size)
            P[bi] = self._interp(S[bi], P[bi], frac)
            for k, f, cause in zip(bi, frac, causes[bad], strict=True):
                self._record(t, k, -1, str(cause), float(f))
            at_safe[bi[frac == 0]] = True
        # 2. exchanges: two movers, each of whose new box hits the other's safe box, would
        # pass through each other (a swap of places, which no test of the new poses sees):
        # both stay where they were
        for a, b in self._exchanges(np.flatnonzero(~at_safe), S, P):
            for k, o in ((a, b), (b, a)):
                P[k] = S[k]
                at_safe[k] = True
                self._record(t, k, o, "artefact", 0.0, rule="revert")
        # 3. artefact pairs: with "advance", movers in a colliding pair first advance as
        # far as they safely can against everything else
        if self.rule == "advance":
            pairs = self._live_pairs(P, at_safe)
            if pairs.size:
                a, b = pairs[:, 0], pairs[:, 1]
                movers = np.unique(np.r_[a[~at_safe[a]], b[~at_safe[b]]])
                frac = self._advance(movers, S, P)
                P[movers] = self._interp(S[movers], P[movers], frac)
                other = self._partner(movers, a, b)
                for k, f, o in zip(movers, frac, other, strict=True):
                    self._record(t, k, o, "artefact", float(f))
                at_safe[movers[frac == 0]] = True
                adv = movers[frac > 0]
                env_bad, _ = self._env_bad(adv, P)
                P[adv[env_bad]] = S[adv[env_bad]]
                at_safe[adv[env_bad]] = True
        # 4. revert until no colliding pair involves a box away from its safe pose; each
        # round reverts at least one artefact, so this ends within n rounds
        for _ in range(n + 1):
            pairs = self._live_pairs(P, at_safe)
            if pairs.size == 0:
                break
            for aa, bb in pairs:
                for k, o in ((aa, bb), (bb, aa)):
                    if not at_safe[k]:
                        P[k] = S[k]
                        at_safe[k] = True
                        self._record(t, k, o, "artefact", 0.0, rule="revert")
        self.poses = P
        self._runs = None
        return P.copy()

    def _record(
        self, t: float, k: int, other: int, cause: str, frac: float, rule: str | None = None
    ) -> None:
        oid = int(self.ids[other]) if other >= 0 else -1
        rule = rule or ("advance" if frac > 0 else "revert")
        self.log.append(Resolution(t, int(self.ids[k]), rule, cause, oid, frac))

    def _env_bad(self, idx: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, h, y = self._boxes_for(P[idx], self._half[idx], self._offset[idx])
        env, outside, mesh, _ = self._env_hits(c, h, y)
        return env | outside | mesh, np.where(env | outside | mesh, _causes(env, outside, mesh), "")

    def _exchanges(self, movers: np.ndarray, S: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``(m, 2)`` pairs ``a < b`` of ``movers`` that would exchange places: the box of
        each at its new pose ``P`` hits the other's box at its safe pose ``S``."""
        n = movers.size
        if n < 2:
            return np.zeros((0, 2), np.int64)
        c, h, y = self._boxes_for(
            np.concatenate([P[movers], S[movers]]),
            np.concatenate([self._half[movers]] * 2),
            np.concatenate([self._offset[movers]] * 2),
        )
        pairs = self._pair_hits(c, h, y)
        lo, hi = pairs.min(axis=1), pairs.max(axis=1)
        cross = (lo < n) & (hi >= n) & (lo != hi - n)  # a new box against another's safe one
        hits = set(zip(movers[lo[cross]].tolist(), movers[hi[cross] - n].tolist(), strict=True))
        both = sorted((a, b) for a, b in hits if a < b and (b, a) in hits)
        return np.array(both, np.int64).reshape(-1, 2)

    def _live_pairs(self, P: np.ndarray, at_safe: np.ndarray) -> np.ndarray:
        centre, half, yaw = self.boxes(P)
        pairs = self._pair_hits(centre, half, yaw)
        if pairs.size == 0:
            return pairs
        return pairs[~(at_safe[pairs[:, 0]] & at_safe[pairs[:, 1]])]

    @staticmethod
    def _partner(movers: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        out = np.empty(movers.size, np.int64)
        for i, k in enumerate(movers):
            hit = np.flatnonzero(a == k)
            out[i] = b[hit[0]] if hit.size else a[np.flatnonzero(b == k)[0]]
        return out

    @staticmethod
    def _interp(S: np.ndarray, P: np.ndarray, f: np.ndarray) -> np.ndarray:
        out = S + f[:, None] * (P - S)
        out[:, 2] = S[:, 2] + f * _wrap(P[:, 2] - S[:, 2])
        return out

    def _advance(self, bi: np.ndarray, S: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Largest collision-free fraction of the move of artefacts ``bi`` (bisection),
        less ``safe_distance``; others are held at their current candidate poses, the
        artefacts in ``bi`` at their safe poses."""
        lo = np.zeros(bi.size)
        hi = np.ones(bi.size)
        others = P.copy()
        others[bi] = S[bi]
        oc, oh, oy = self.boxes(others)
        for _ in range(self.advance_iters):
            mid = 0.5 * (lo + hi)
            Q = self._interp(S[bi], P[bi], mid)
            c, h, y = self._boxes_for(Q, self._half[bi], self._offset[bi])
            env, outside, mesh, _ = self._env_hits(c, h, y)
            bad = env | outside | mesh
            bad |= self._hits_against(bi, c, h, y, oc, oh, oy)
            lo = np.where(bad, lo, mid)
            hi = np.where(bad, mid, hi)
        dist = np.hypot(*(P[bi, :2] - S[bi, :2]).T)
        with np.errstate(divide="ignore", invalid="ignore"):
            back = np.where(dist > 0, self.safe_distance / dist, 1.0)
        return np.clip(lo - back, 0.0, 1.0)

    def _env_cause(self, pose: np.ndarray, half: np.ndarray, offset: np.ndarray) -> str:
        """What :meth:`step` logs for one box (half sizes, centre in F_A ``(3,)``) moved
        to ``pose`` (3,) against the environment: its cause, ``""`` for nothing."""
        c, h, y = self._boxes_for(pose[None], half[None], offset[None])
        env, outside, mesh, _ = self._env_hits(c, h, y)
        return str(_causes(env, outside, mesh)[0]) if (env | outside | mesh)[0] else ""

    # ------------------------------------------------------------ moving scenes
    def resolve_scene(
        self,
        scene: Scene,
        movers: npt.ArrayLike | None = None,
        *,
        others: npt.ArrayLike | None = None,
        dt: float = 0.5,
    ) -> Scene:
        """The scene with the moves of ``movers`` resolved by the builder's rule along
        their tracks (DECISIONS 9): :meth:`step` every ``dt`` seconds of the scene's clock.

        At every step each live mover proposes the pose of its track at its own time
        ``t - delay`` (the planned track, less the time it has lost); the builder holds the
        movers at their last safe poses and the ``others`` where the scene puts them, and
        :meth:`step` resolves the proposals. A mover whose move is reverted holds its last
        safe pose for the step and walks on from there (its delay grows by ``dt``); with
        ``rule="advance"`` it keeps the collision-free fraction ``f`` of its move (its
        delay grows by ``(1 - f) dt``). Movers step one at a time, earlier arrivals first
        (of two crossing, the first passes and the other waits), and a box that a mover
        already touches where it stands (artefacts placed on each other) does not hold
        it. A mover keeps its route and its life-cycle and never jumps: it only waits; a
        mover that never has to wait keeps its track exactly. :meth:`step` runs only for a
        move whose box hits the environment or another box (it would take any other move
        as it is); every resolution is in :attr:`log` (cleared first). The builder holds
        no artefact afterwards.

        Parameters
        ----------
        scene : Scene
            The artefacts and their planned tracks.
        movers : (N,) bool, optional
            Artefacts (scene order) whose moves are resolved; default every artefact with
            a track.
        others : (N,) bool, optional
            Artefacts that take part as they are (obstacles at their scene poses, never
            moved by the builder); default every artefact that is not a mover. Artefacts
            in neither do not take part.
        dt : float
            Seconds between steps.

        Returns
        -------
        Scene
            ``scene`` with the tracks of the movers that had to wait re-timed: a row at
            every step of their life and at every vertex of their planned track.

        Examples
        --------
        Two carts cross; the one that would run into the other waits for it to pass:

        >>> import pandas as pd
        >>> from are_stats import OccupancyGrid, Scene, load_catalogue
        >>> table = pd.DataFrame({"t_arrive": [0.0, 0.0], "t_leave": [10.0, 10.0],
        ...                       "x": [0.0, 5.0], "y": [5.0, 0.0], "yaw": [0.0, 0.0]})
        >>> tracks = pd.DataFrame({"id": [0, 0, 1, 1], "t": [0.0, 10.0, 0.0, 10.0],
        ...                        "x": [0.0, 10.0, 5.0, 5.0], "y": [5.0, 5.0, 0.0, 10.0],
        ...                        "yaw": [0.0, 0.0, 0.0, 0.0]})
        >>> scene = Scene.from_scenarios(table, load_catalogue(), tracks)
        >>> b = ARBuilder(OccupancyGrid(np.zeros((160, 160)), 0.1, origin=(-3.0, -3.0, 0.0)))
        >>> moved = b.resolve_scene(scene)
        >>> len(b.log) > 0, bool(moved.poses(10.0)[1, 1] < 10.0)
        (True, True)
        """
        # lazy: a cycle (scenarios imports the builder); +1.95 s CPU on `import are_stats.builder`
        from are_stats.scenarios import Scene

        if not isinstance(scene, Scene):
            raise ValueError(f"scene: expected a Scene, got {type(scene).__name__}")
        n = len(scene)
        dt = float(check_positive("dt", dt))
        mv = scene.has_tracks.copy() if movers is None else np.asarray(movers, bool)
        if mv.shape != (n,):
            raise ValueError(f"movers: expected ({n},) bool in scene order, got {mv.shape}")
        ot = ~mv if others is None else np.asarray(others, bool)
        if ot.shape != (n,):
            raise ValueError(f"others: expected ({n},) bool in scene order, got {ot.shape}")
        mv = mv & scene.has_tracks
        ot = ot & ~mv
        self.reset()
        if not mv.any():
            return scene
        take = mv | ot
        half, offset = scene.half_extents.astype(float), scene.offsets.astype(float)
        reach = np.hypot(half[:, 0], half[:, 1]) + np.hypot(offset[:, 0], offset[:, 1])
        t_on, t_off = scene.t_arrive, scene.t_leave
        plan = {int(i): scene.track(int(i)) for i in np.flatnonzero(mv)}
        delay = np.zeros(n)
        safe = np.zeros((n, 3))
        started = np.zeros(n, bool)
        rec: dict[int, tuple[list[float], list[float], list[np.ndarray]]] = {}
        open_ground = not self._blocked.any() and self._mesh_hash is None
        t_last = max(min(float(t_off[i]), float(tr[0][-1])) for i, tr in plan.items())
        for t in np.arange(float(t_on[mv].min()), t_last, dt):
            live = take & (t_on <= t) & (t < t_off)
            if not (live & mv).any():
                continue
            idx = np.flatnonzero(live)
            j_mv = np.flatnonzero(mv[idx])
            j_mv = j_mv[np.argsort(t_on[idx[j_mv]], kind="stable")]  # earlier arrivals first
            m_idx = idx[j_mv]
            for i in m_idx[~started[m_idx]]:  # arrivals: safe where their tracks start
                safe[i] = plan[int(i)][1][0]
                started[i] = True
            now = np.empty((idx.size, 3))
            rest = np.flatnonzero(~mv[idx])
            now[rest] = scene.poses(float(t), idx[rest])
            now[j_mv] = safe[m_idx]
            prop = now.copy()
            for j, i in zip(j_mv, m_idx, strict=True):
                prop[j] = _track_pose(*plan[int(i)], t - delay[i])
            # a mover steps alone where its box could touch no other box, before or after
            xy = np.concatenate([now[:, :2], prop[:, :2]])
            r2 = np.concatenate([reach[idx], reach[idx]])
            gap = np.minimum(
                np.hypot(*(now[j_mv, None, :2] - xy[None]).transpose(2, 0, 1)),
                np.hypot(*(prop[j_mv, None, :2] - xy[None]).transpose(2, 0, 1)),
            )
            step_len = np.hypot(*(prop[j_mv, :2] - now[j_mv, :2]).T)
            near = gap <= reach[m_idx, None] + r2[None, :] + step_len[:, None]
            mine = np.arange(j_mv.size)
            near[mine, j_mv] = near[mine, j_mv + idx.size] = False
            # the environment (map, border, mesh) for every mover's proposal at once; on
            # open ground (nothing blocked, no mesh) only the border
            env_bad = np.zeros(j_mv.size, bool)
            # what step() finds against the environment (a cause, or "" for nothing), for
            # the one-mover step of rule "revert" below; None: not known yet (open ground,
            # near the border: the exact rasterised test decides)
            env_cause: list[str | None] = [""] * j_mv.size
            go = (prop[j_mv] != now[j_mv]).any(axis=1)
            if go.any():
                c, h, y = self._boxes_for(prop[j_mv[go]], half[m_idx[go]], offset[m_idx[go]])
                if open_ground:
                    uv = self.grid.world_to_local(box_corners(c[:, :2], h[:, :2], y).reshape(-1, 2))
                    uv = uv.reshape(-1, 4, 2)
                    env_bad[go] = ((uv < 0.0) | (uv > [self.grid.width, self.grid.height])).any(
                        axis=(1, 2)
                    )
                    # two cells inside the border, a box's rasterised runs (box_runs) are
                    # inside the map too (their rounding is far below a cell)
                    wh = np.array([self.grid.width, self.grid.height]) - _BORDER_CELLS
                    inner = ((uv >= _BORDER_CELLS) & (uv <= wh)).all(axis=(1, 2))
                    for g, ok in zip(np.flatnonzero(go), inner, strict=True):
                        env_cause[g] = "" if ok else None
                else:
                    env, outside, mesh, _ = self._env_hits(c, h, y)
                    env_bad[go] = env | outside | mesh
                    causes = np.where(env | outside | mesh, _causes(env, outside, mesh), "")
                    for g, cause in zip(np.flatnonzero(go), causes, strict=True):
                        env_cause[g] = str(cause)
            # the boxes where everyone stands and where the movers would go (kept up to
            # date as movers move; a box's geometry does not depend on the boxes computed
            # with it, bit for bit)
            h_idx = half[idx]
            c_now = box_centres(now, offset[idx])
            lo_now, hi_now = _aabbs(c_now, h_idx, now[:, 2])
            c_mv = box_centres(prop[j_mv], offset[m_idx])
            lo_mv, hi_mv = _aabbs(c_mv, half[m_idx], prop[j_mv, 2])
            direct = self.rule == "revert" and self._direct_revert
            for q, (j, i, row, bad, cause) in enumerate(
                zip(j_mv, m_idx, near, env_bad, env_cause, strict=True)
            ):
                moves = bool(go[q])
                stood = now[j].copy()
                o, hit = np.zeros(0, np.int64), np.zeros(0, bool)
                if moves and row.any():
                    # the boxes it could touch; those it already touches where it stands
                    # (placed on each other) do not hold it: it may walk out of them
                    close = np.zeros(idx.size, bool)
                    close[np.flatnonzero(row) % idx.size] = True
                    close[j] = False
                    o = np.flatnonzero(close)
                    m = o.size
                    # one separating-axis test (symmetric in its two boxes, bit for bit):
                    # the mover where it stands, then where it would go, against each of o
                    ov = obb_overlap(
                        np.repeat(np.stack([c_now[j], c_mv[q]]), m, axis=0),
                        np.repeat(half[i][None], 2 * m, 0),
                        np.concatenate([np.full(m, now[j, 2]), np.full(m, prop[j, 2])]),
                        np.concatenate([c_now[o], c_now[o]]),
                        np.concatenate([h_idx[o], h_idx[o]]),
                        np.concatenate([now[o, 2], now[o, 2]]),
                        self.eps,
                    )
                    touching = ov[:m] & _aabb_touch(lo_now[j], hi_now[j], lo_now[o], hi_now[o])
                    o, hit = o[~touching], ov[m:][~touching]
                    if o.size and not bad:
                        bad = bool(hit.any())
                if moves and bad and direct:  # what step() does to this move alone
                    if cause is None:
                        cause = self._env_cause(prop[j], half[i], offset[i])
                    if not cause:  # its pairs: footprint AABBs that touch and overlap boxes
                        hit &= _aabb_touch(lo_mv[q], hi_mv[q], lo_now[o], hi_now[o])
                        cause = "artefact" if hit.any() else ""
                    if cause:  # held; the log names the first pair's partner: the lowest
                        oid = int(scene.ids[idx[o[np.argmax(hit)]]]) if cause == "artefact" else -1
                        self.log.append(
                            Resolution(float(t), int(scene.ids[i]), "revert", cause, oid, 0.0)
                        )
                        delay[i] += dt  # a revert keeps none of the move
                    else:
                        now[j] = prop[j]
                elif moves and bad:  # the builder's step: this mover's move alone
                    sub = np.zeros(idx.size, bool)
                    sub[o] = True
                    sub[j] = True
                    self.ids = scene.ids[idx[sub]].astype(np.int64)
                    self.labels = [str(lab) for lab in scene.labels[idx[sub]]]
                    self.poses = now[sub]
                    self._half, self._offset = half[idx[sub]], offset[idx[sub]]
                    self._runs = None
                    first = len(self.log)
                    k = int(np.count_nonzero(sub[:j]))
                    moved = now[sub]
                    moved[k] = prop[j]
                    now[j] = self.step(moved, time=float(t))[k]
                    kept = [r.fraction for r in self.log[first:] if r.artefact == scene.ids[i]]
                    if kept:
                        delay[i] += (1.0 - min(kept)) * dt
                else:  # nothing in the way: the step would take it as it is
                    now[j] = prop[j]
                if (now[j] != stood).any() and (now[j] == prop[j]).all():
                    c_now[j], lo_now[j], hi_now[j] = c_mv[q], lo_mv[q], hi_mv[q]
                elif (now[j] != stood).any():  # advanced part of the way
                    c_now[j] = box_centres(now[j][None], offset[i][None])[0]
                    lo, hi = _aabbs(c_now[j][None], half[i][None], now[j, 2][None])
                    lo_now[j], hi_now[j] = lo[0], hi[0]
                safe[i] = now[j]
                ts, us, ps = rec.setdefault(int(i), ([], [], []))
                ts.append(float(t))
                us.append(float(t - delay[i]))
                ps.append(now[j].copy())
        log = self.log
        self.reset()
        self.log = log
        for i in np.flatnonzero(mv & (delay > 0.0)):
            ts, us, ps = rec[int(i)]
            t_new, p_new = _retimed(*plan[int(i)], np.array(ts), np.array(us), np.array(ps))

            scene = scene.with_track(int(i), t_new, p_new)
        return scene

    # ------------------------------------------------------------ augmented views
    def _current_runs(self):
        if self._runs is None:
            c, h, y = self.boxes()
            owner, rows, jlo, jhi, _ = self._footprints(c, h, y)
            self._runs = (owner, rows, jlo, jhi)
        return self._runs

    def artefact_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """``(owner_row, flat_cell)`` of every grid cell covered by a live artefact."""
        owner, rows, jlo, jhi = self._current_runs()
        return runs_to_cells(rows, jlo, jhi, self.grid.width, owner)

    @property
    def n_artefact_cells(self) -> int:
        """n_A: number of distinct cells of M_2D covered by live artefacts."""
        return int(np.unique(self.artefact_cells()[1]).size)

    def augmented_grid(self, perceived: npt.ArrayLike | None = None) -> OccupancyGrid:
        """The augmented M_2D (Fig. 4b): the base grid with artefact cells set to 100.

        Parameters
        ----------
        perceived : (n,) bool, optional
            Aligned with :attr:`ids`: only these artefacts' cells are set (the planner's
            map: the perceived set A_f on M_2D, Sect. 3.3). Default: every live artefact.

        Returns
        -------
        OccupancyGrid
            A copy of :attr:`grid`.
        """
        if perceived is None:
            flat = self.artefact_cells()[1]
        else:
            p = np.asarray(perceived)
            if p.dtype != bool or p.shape != (self.ids.size,):
                raise ValueError(
                    f"perceived: expected a ({self.ids.size},) bool array aligned with the "
                    f"builder's ids, got {p.dtype} of shape {p.shape}"
                )
            if self._runs is not None:  # the footprints of this update, rasterised already
                owner, flat = self.artefact_cells()
                flat = flat[p[owner]]
            else:  # rasterise only the perceived boxes (a footprint depends on its box only)
                c, h, y = self.boxes()
                _, rows, jlo, jhi, _ = self._footprints(c[p], h[p], y[p])
                flat = runs_to_cells(rows, jlo, jhi, self.grid.width, rows)[1]
        g = self.grid.copy()
        g.data.ravel()[flat] = 100
        return g

    def _surface(self, k: int) -> np.ndarray:
        # lazy: trimesh adds 2.4 s CPU to `import are_stats.builder`
        import trimesh

        label = self.labels[k]
        key = label if label != "box" else f"box{self._half[k].tolist()}"
        if key not in self._surface_cache:
            if label != "box" and self.catalogue is not None and label in self.catalogue:
                mesh = self.catalogue[label].mesh()
            else:
                mesh = trimesh.creation.box(extents=2 * self._half[k])
                mesh.apply_translation(self._offset[k])
            self._surface_cache[key] = surface_points(mesh, self.base_voxels.resolution)
        return self._surface_cache[key]

    def augmented_voxels(self) -> VoxelMap:
        """The augmented M_3D (Fig. 4b): base voxels plus the mesh vertices of every
        artefact (surface points at the voxel resolution) at its current pose."""
        out = self.base_voxels.copy()
        pts = []
        for k in range(self.ids.size):
            v = self._surface(k)
            x, y, th = self.poses[k]
            c, s = np.cos(th), np.sin(th)
            pts.append(
                np.column_stack(
                    [x + c * v[:, 0] - s * v[:, 1], y + s * v[:, 0] + c * v[:, 1], v[:, 2]]
                )
            )
        if pts:
            out.insert_points(np.concatenate(pts))
        return out

    def sync_frames(
        self, tree: TransformTree, env_frame: str = "F_E", prefix: str = "F_A/"
    ) -> None:
        """Publish every live artefact's frame F_A (``prefix + id``) in a
        :class:`~are_stats.environment.TransformTree` under ``env_frame`` at its current
        pose, and drop the frames of artefacts that left."""
        live = {f"{prefix}{int(a)}" for a in self.ids}
        for f in tree.frames:
            if f.startswith(prefix) and f not in live and tree.parent(f) == env_frame:
                tree.remove(f)
        for aid, (x, y, th) in zip(self.ids, self.poses, strict=True):
            tree.set_static(f"{prefix}{int(aid)}", env_frame, planar_pose_matrix(x, y, th))

    def log_table(self) -> dict[str, np.ndarray]:
        """The resolution log as columns (``time, artefact, rule, cause, other, fraction``)."""
        cols = Resolution._fields
        if not self.log:
            return {c: np.zeros(0) for c in cols}
        return {c: np.array([getattr(r, c) for r in self.log]) for c in cols}


def _causes(env: np.ndarray, outside: np.ndarray, mesh: np.ndarray) -> np.ndarray:
    """The cause logged for boxes that hit the environment (``(n,)`` each): ``"bounds"``
    before ``"environment"`` before ``"mesh"``."""
    return np.where(outside, "bounds", np.where(env, "environment", "mesh"))


def _aabbs(centre: np.ndarray, half: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners ``(n, 2)`` of the footprints' axis-aligned
    bounding boxes (centres, half sizes ``(n, 3)``, yaws ``(n,)``): those of
    :meth:`ARBuilder._pair_hits`'s broad phase."""
    corners = box_corners(centre[:, :2], half[:, :2], yaw)
    return corners.min(axis=1), corners.max(axis=1)


def _aabb_touch(lo: np.ndarray, hi: np.ndarray, los: np.ndarray, his: np.ndarray) -> np.ndarray:
    """``(m,)`` bool: whether the AABB ``lo, hi`` (2,) overlaps or touches each of
    ``los, his`` (m, 2), as :func:`~are_stats.builder.aabb_pairs` tests a pair."""
    return (los <= hi).all(axis=1) & (lo <= his).all(axis=1)


def _track_pose(tv: np.ndarray, pv: np.ndarray, u: float) -> np.ndarray:
    """Pose ``(3,)`` of a track (times ``tv`` (m,), poses ``pv`` (m, 3)) at time ``u``
    (clamped to its ends; yaw the short way round)."""
    # (Python min / max: np.clip on scalars costs more than the rest of the function)
    k = min(max(int(np.searchsorted(tv, u, side="right")) - 1, 0), len(tv) - 1)
    k1 = min(k + 1, len(tv) - 1)
    f = min(max(float((u - tv[k]) / (tv[k1] - tv[k])), 0.0), 1.0) if tv[k1] > tv[k] else 0.0
    out = pv[k] + f * (pv[k1] - pv[k])
    out[2] = pv[k, 2] + f * _wrap(np.array(pv[k1, 2] - pv[k, 2]))
    return out


def _retimed(
    tv: np.ndarray, pv: np.ndarray, ts: np.ndarray, us: np.ndarray, ps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A planned track (``tv`` (m,), ``pv`` (m, 3)) walked with the waits of
    :meth:`ARBuilder.resolve_scene`: its poses ``ps`` (k, 3) at the steps ``ts`` (k,),
    where it had reached its own time ``us`` (k,) (non-decreasing); the planned vertices
    at the times it reached them; the planned rows before the first step; after the last
    step, on along the plan (where it was held at that step: there). It ends where the
    plan ends (``tv[-1]``: its leaving time, or the scenario's horizon), late by its
    delay."""
    t_end = float(tv[-1])
    before = tv < ts[0]
    inside = (tv > us[0]) & (tv <= us[-1])
    j = np.searchsorted(us, tv[inside], side="left")  # first step that reached the vertex
    t_in = ts[j - 1] + (tv[inside] - us[j - 1]) / (us[j] - us[j - 1]) * (ts[j] - ts[j - 1])
    lag = ts[-1] - us[-1]
    after = (tv > us[-1]) & (tv + lag < t_end)
    end = _track_pose(tv, pv, t_end - lag)
    if len(us) > 1 and us[-1] <= us[-2]:  # held at its last step: it stays there
        after[:] = False
        end = ps[-1]
    t_all = np.concatenate([tv[before], ts, t_in, tv[after] + lag, [t_end]])
    p_all = np.concatenate([pv[before], ps, pv[inside], pv[after], end[None]])
    keep = t_all <= t_end
    t_all, p_all = t_all[keep], p_all[keep]
    order = np.argsort(t_all, kind="stable")
    t_all, p_all = t_all[order], p_all[order]
    keep = np.r_[True, np.diff(t_all) > 1e-9]
    return t_all[keep], p_all[keep]
