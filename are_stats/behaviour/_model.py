"""The fitted behaviour model: speeds, rationality, slip and exits per class (issue 16).

:class:`BehaviourFit` holds what :func:`~are_stats.fitting.fit_behaviour` estimates and what
:func:`~are_stats.behaviour.simulate_behaviour_tracks` needs: the MDP grid (a coarse free
mask of cells of ``cell`` metres), per class a lognormal law of walking speeds (and of run
speeds), the decision epoch ``dt = cell / median speed``, the soft-policy rationality
``beta`` and the slip probability with standard errors, optionally the weights ``w`` of
reward features ``phi`` (cell rewards ``sum_k w_k phi_k`` per epoch, e.g. closeness to walls)
with standard errors, and the observed (entry, exit) pairs that define the exit density
given an entry: a Gaussian kernel over the entries picks a track, a Gaussian kernel around
its exit gives the exit cell.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.sparse import csr_array

from are_stats.behaviour._soft import SoftSolution, soft_policy

if TYPE_CHECKING:
    import xarray as xr

    from are_stats.environment import OccupancyGrid

__all__ = ["BehaviourFit", "grid_geodesic"]


_PER_CLASS = (
    "dt",
    "speed_mu",
    "speed_sigma",
    "run_fraction",
    "run_mu",
    "run_sigma",
    "beta",
    "beta_se",
    "slip",
    "slip_se",
    "loglik",
    "n_moves",
    "n_tracks",
    "n_fit_tracks",
    "n_epochs",
    "bandwidth_entry",
    "bandwidth_exit",
    "fit_seconds",
)
#: Per-class values that fit files written before them lack, and their defaults there: no
#: within-person variation of the walking speed or heading.
_WITHIN = {
    "speed_within_sd": 0.0,
    "speed_within_time": np.nan,
    "heading_within_sd": 0.0,
    "heading_within_time": np.nan,
    "speed_within_sd_se": np.nan,
    "speed_within_time_se": np.nan,
    "heading_within_sd_se": np.nan,
    "heading_within_time_se": np.nan,
}


#: The 4-connected graphs of the last free masks :func:`grid_geodesic` saw, by
#: ``(shape, packed mask)``: a caller asks for one source cell at a time (the walkers'
#: legs, 597 calls on three moves of a courtyard scenario), and building the graph cost
#: about two thirds of a call.
_GRAPHS: dict[tuple[tuple[int, int], bytes], csr_array] = {}
_GRAPHS_MAX = 8
_GRAPHS_LOCK = threading.Lock()  # the eviction iterates the dict: one thread at a time


def _grid_graph(free: np.ndarray) -> csr_array:
    """The ``(H W, H W)`` graph of 4-connected moves between the free cells of ``free``
    (H, W) bool, both directions of every move stored (``dijkstra(..., directed=True)``
    finds the path lengths of ``directed=False`` on one direction, without transposing
    the graph on every call: 0.63 against 0.93 ms a source on a 60 x 80 grid)."""
    key = (free.shape, np.packbits(free).tobytes())
    graph = _GRAPHS.get(key)
    if graph is None:
        h, w = free.shape
        idx = np.arange(h * w).reshape(h, w)
        src, dst = [], []
        for a, b in ((idx[:, :-1], idx[:, 1:]), (idx[:-1], idx[1:])):
            both = free.ravel()[a.ravel()] & free.ravel()[b.ravel()]
            src.append(a.ravel()[both])
            dst.append(b.ravel()[both])
        s, d = np.concatenate(src), np.concatenate(dst)
        graph = csr_array(
            (np.ones(2 * s.size), (np.concatenate([s, d]), np.concatenate([d, s]))),
            shape=(h * w, h * w),
        )
        with _GRAPHS_LOCK:
            if len(_GRAPHS) >= _GRAPHS_MAX:
                del _GRAPHS[next(iter(_GRAPHS))]
            _GRAPHS[key] = graph
    return graph


def grid_geodesic(free: npt.ArrayLike, cells: npt.ArrayLike) -> np.ndarray:
    """4-connected path lengths (in cells) over free cells from each of ``cells``.

    Parameters
    ----------
    free : (H, W) bool
    cells : (n, 2) int
        Sources ``(row, col)``.

    Returns
    -------
    dist : (n, H, W) float64
        ``inf`` where unreachable.
    """
    from scipy.sparse.csgraph import dijkstra  # lazy: +0.14 s CPU on `import are_stats.behaviour`

    free = np.asarray(free, bool)
    h, w = free.shape
    graph = _grid_graph(free)
    c = np.asarray(cells, np.int64).reshape(-1, 2)
    out = dijkstra(graph, directed=True, indices=c[:, 0] * w + c[:, 1], unweighted=True)
    return np.asarray(out).reshape(len(c), h, w)


@dataclass
class BehaviourFit:
    """Behaviour of each class of artefacts, fitted from tracks.

    Attributes
    ----------
    classes : tuple of str
        Class labels (``C`` of them).
    cell : float
        MDP cell side (m).
    origin : (2,) float
        World ``(x, y)`` of the corner of cell ``(0, 0)``.
    free : (H, W) bool
        Free cells of the MDP grid (row along +y, column along +x).
    dt : (C,) float
        Decision epoch (s): ``cell`` over the class's median walking speed.
    speed_mu, speed_sigma : (C,) float
        Lognormal law of walking speeds (m/s): ``log v ~ N(mu, sigma^2)``.
    run_fraction, run_mu, run_sigma : (C,) float
        Fraction of runners and the lognormal law of their speeds (NaN without runners).
    beta, beta_se, slip, slip_se : (C,) float
        Maximum-likelihood rationality and slip with standard errors (inverse Hessian; NaN
        where the tracks do not identify the parameter at the fit's precision, with a
        ``warnings`` entry saying so).
    loglik, n_moves : (C,) float, (C,) int
        Log-likelihood at the optimum and the number of observed steps it covers.
    n_tracks, n_fit_tracks : (C,) int
        Tracks of the class, and those used for ``beta`` and ``slip``.
    n_epochs : (C,) int
        Cap on the epochs of the stationary soft policy used in the fit.
    bandwidth_entry, bandwidth_exit : (C,) float
        Kernel widths (m) of the exit density given an entry.
    fit_seconds : (C,) float
        Wall time of the class's maximum-likelihood fit.
    track_class : (M,) int
        Class of each observed track.
    entry_xy, exit_xy : (M, 2) float
        First and last position of each observed track (m).
    time_cost, goal_reward, step_cost : float
        Rewards of the soft MDP (``time_cost`` sets the scale of ``beta`` and the weights).
    feature_names : tuple of str
        Names of the ``F`` reward features (``()``: none, the default).
    features : (F, H, W) float
        The features ``phi_k`` on the MDP grid.
    weights, weights_se : (C, F) float
        Maximum-likelihood weights ``w_k`` per class (reward per epoch spent on a cell with
        ``phi_k = 1``, in the units of ``time_cost``) and their standard errors (NaN as
        ``beta_se``'s).
    speed_within_sd, speed_within_time : (C,) float
        Within-person variation of the walking speed: a walker's log speed is a stationary
        Ornstein-Uhlenbeck process around its preferred speed's, of this sd (log units)
        and correlation time (s) (:func:`~are_stats.fitting.fit_behaviour`). Default (and
        fit files written before it was fitted): sd 0 and time NaN, no within-person
        variation, each walker at its one preferred speed. NaN sd: not identified (below);
        generation then walks without it.
    heading_within_sd, heading_within_time : (C,) float
        Within-person variation of the walking heading: a walker's heading deviates from
        its route's direction by a stationary Ornstein-Uhlenbeck process of this sd (rad)
        and correlation time (s). Defaults (older fit files) as for the speed: sd 0 and
        time NaN, each walker straight at the next corner of its route. For both, an sd
        of 0 is no variation and NaN a variation the tracks do not identify (its
        correlation time past half the longest lag, or no track long enough): generation
        walks neither (issue 26; files before 2026-11-28 stored 0 for both).
    speed_within_sd_se, speed_within_time_se : (C,) float
        Bootstrap standard errors over the tracks of the speed's sd and time (NaN: not
        identified, or a file written before they were stored).
    heading_within_sd_se, heading_within_time_se : (C,) float
        The same for the heading's.
    standing : tuple of str
        Classes of the log none of whose tracks walked (pallets parked): not among
        ``classes`` (nothing to fit), and standing at their entry for their whole stay in
        generated scenes (:func:`~are_stats.behaviour.simulate_behaviour_tracks`). Default
        (and fit files written before it was recorded): ``()``.
    """

    classes: tuple
    cell: float
    origin: np.ndarray
    free: np.ndarray
    dt: np.ndarray
    speed_mu: np.ndarray
    speed_sigma: np.ndarray
    run_fraction: np.ndarray
    run_mu: np.ndarray
    run_sigma: np.ndarray
    beta: np.ndarray
    beta_se: np.ndarray
    slip: np.ndarray
    slip_se: np.ndarray
    loglik: np.ndarray
    n_moves: np.ndarray
    n_tracks: np.ndarray
    n_fit_tracks: np.ndarray
    n_epochs: np.ndarray
    bandwidth_entry: np.ndarray
    bandwidth_exit: np.ndarray
    fit_seconds: np.ndarray
    track_class: np.ndarray
    entry_xy: np.ndarray
    exit_xy: np.ndarray
    time_cost: float = 1.0
    goal_reward: float = 1.0
    step_cost: float = 1e-3
    warnings: list = field(default_factory=list)
    feature_names: tuple = ()
    features: npt.ArrayLike | None = None
    weights: npt.ArrayLike | None = None
    weights_se: npt.ArrayLike | None = None
    speed_within_sd: npt.ArrayLike | None = None
    speed_within_time: npt.ArrayLike | None = None
    heading_within_sd: npt.ArrayLike | None = None
    heading_within_time: npt.ArrayLike | None = None
    speed_within_sd_se: npt.ArrayLike | None = None
    speed_within_time_se: npt.ArrayLike | None = None
    heading_within_sd_se: npt.ArrayLike | None = None
    heading_within_time_se: npt.ArrayLike | None = None
    standing: tuple = ()

    def __post_init__(self) -> None:
        self.feature_names = tuple(str(n) for n in self.feature_names)
        self.standing = tuple(str(n) for n in self.standing)
        both = sorted(set(self.standing) & {str(c) for c in self.classes})
        if both:
            raise ValueError(
                f"BehaviourFit.standing: expected classes not among the fitted ones, got {both}"
            )
        n_f, n_c = len(self.feature_names), len(self.classes)
        for name, default in _WITHIN.items():
            v = getattr(self, name)
            v = np.full(n_c, default) if v is None else np.asarray(v, float)
            if v.shape != (n_c,):
                raise ValueError(
                    f"BehaviourFit.{name}: expected shape ({n_c},) (one per class), got {v.shape}"
                )
            setattr(self, name, v)
        shape = np.shape(self.free)
        self.features = (
            np.zeros((0, *shape)) if self.features is None else np.asarray(self.features, float)
        )
        for name in ("weights", "weights_se"):
            v = getattr(self, name)
            setattr(self, name, np.zeros((n_c, 0)) if v is None else np.asarray(v, float))
        expect = {"features": (n_f, *shape), "weights": (n_c, n_f), "weights_se": (n_c, n_f)}
        for name, want in expect.items():
            got = getattr(self, name).shape
            if got != want:
                raise ValueError(
                    f"BehaviourFit.{name}: expected shape {want} ({n_f} features, {n_c} "
                    f"classes, grid {shape}), got {got}"
                )

    def cell_reward(self, class_index: int) -> float | np.ndarray:
        """The fitted cell reward ``sum_k w_k phi_k`` of a class.

        Parameters
        ----------
        class_index : int

        Returns
        -------
        float or (H, W) float64
            ``0.0`` without features (the soft solve is then exactly the one without them),
            else the reward per epoch on each cell (``cell_reward`` of
            :func:`~are_stats.behaviour.soft_policy`).
        """
        if not self.feature_names:
            return 0.0
        return np.tensordot(self.weights[int(class_index)], self.features, axes=1)

    def soft_policy(
        self,
        class_index: int,
        occupied: npt.ArrayLike | OccupancyGrid,
        goals: npt.ArrayLike,
        *,
        n_epochs: int,
        tol: float | None,
        bucket: int | None,
    ) -> SoftSolution:
        """A class's soft policy toward ``goals``: :func:`~are_stats.behaviour.soft_policy`
        with the fitted ``beta``, ``slip``, goal reward, step and time costs and cell reward
        of class ``class_index`` (the one place generation and the motion checks take them
        from the fit). ``occupied``, ``goals``, ``n_epochs``, ``tol`` and ``bucket`` as
        :func:`~are_stats.behaviour.soft_policy`'s."""
        c = int(class_index)
        return soft_policy(
            occupied,
            goals,
            float(self.beta[c]),
            float(self.slip[c]),
            n_epochs=n_epochs,
            goal_reward=self.goal_reward,
            step_cost=self.step_cost,
            time_cost=self.time_cost,
            cell_reward=self.cell_reward(c),
            tol=tol,
            bucket=bucket,
        )

    # ------------------------------------------------------------------ grid helpers
    def world_to_cell(self, xy: npt.ArrayLike) -> np.ndarray:
        """``(n, 2)`` world points -> ``(n, 2)`` cells ``(row, col)`` snapped to free cells."""
        from scipy import ndimage  # lazy: +0.2 s CPU on `import are_stats.behaviour`

        xy = np.asarray(xy, float).reshape(-1, 2)
        h, w = self.free.shape
        col = np.clip(np.floor((xy[:, 0] - self.origin[0]) / self.cell), 0, w - 1).astype(int)
        row = np.clip(np.floor((xy[:, 1] - self.origin[1]) / self.cell), 0, h - 1).astype(int)
        _, (ri, ci) = ndimage.distance_transform_edt(~self.free, return_indices=True)
        return np.column_stack([ri[row, col], ci[row, col]])

    def cell_to_world(self, cells: npt.ArrayLike) -> np.ndarray:
        """``(n, 2)`` cells -> ``(n, 2)`` world centres."""
        c = np.asarray(cells, float).reshape(-1, 2)
        return np.column_stack(
            [
                self.origin[0] + (c[:, 1] + 0.5) * self.cell,
                self.origin[1] + (c[:, 0] + 0.5) * self.cell,
            ]
        )

    def geodesic(self, cells: npt.ArrayLike) -> np.ndarray:
        """``(n, H, W)`` path lengths from ``cells`` (see :func:`grid_geodesic`)."""
        return grid_geodesic(self.free, cells)

    # ------------------------------------------------------------------ exits
    def draw_exits(
        self,
        rng: np.random.Generator,
        class_index: npt.ArrayLike,
        entries: npt.ArrayLike,
        reach: npt.ArrayLike,
        *,
        tries: int = 20,
        stays: npt.ArrayLike | None = None,
        speed_mu: npt.ArrayLike | None = None,
        speed_sigma: npt.ArrayLike | None = None,
    ) -> np.ndarray:
        """Exit cells given entry cells (and stays), reachable within ``reach`` cells.

        A track of the class is drawn with weight ``N(entry_m - entry; 0, h_entry^2)``, its
        exit jittered by ``N(0, h_exit^2)``; a jitter past the map's edge takes the cell
        nearest to it among those connected to the entry (the kernel's mass past the edge
        goes to the edge, where the log's exits are, instead of being redrawn inside: the
        redraw moved exits at a door in the map's edge inward and shortened walks); a draw
        that is not free or not reachable within ``reach`` moves (4-connected) is retried;
        after ``tries`` the reachable cell nearest to the last drawn exit is taken.

        With ``stays``, the exit is drawn given the entry **and** the stay: people leave when
        they reach their exit, so a stay ``s`` and a path of length ``L`` mean a walking
        speed ``L / s``. ``tries`` exits are drawn as above and one of them is kept with
        weight ``p_v(L / s)``, the class's lognormal speed density (sampling importance
        resampling of ``p(exit | entry, s) ~ p(exit | entry) p_v(L(exit) / s)``). ``L`` is the
        straight-line distance stretched by the grid's detour (4-connected geodesic over
        Manhattan distance). Where none of the ``tries`` is within reach (a stay too short
        for any exit of the density: an exit at the edge of the reach), each is replaced
        by the reachable cell nearest to it and one of those is kept with the same weight:
        the person walks towards the exit the stay makes likeliest as far as its stay
        allows, instead of towards the last draw's nearest cell (often beside its entry,
        where it then stood).

        Parameters
        ----------
        rng : numpy.random.Generator
        class_index : (n,) int
        entries : (n, 2) int
            Entry cells ``(row, col)`` (free).
        reach : (n,) float
            Largest path length in cells.
        stays : (n,) float, optional
            Stay of each artefact (s).
        speed_mu, speed_sigma : (n,) float, optional
            Lognormal speed law of each artefact (log m/s), with ``stays``.

        Returns
        -------
        exits : (n, 2) int
            ``(-1, -1)`` where no other cell is reachable (the artefact stays).
        """
        ent = np.asarray(entries, np.int64).reshape(-1, 2)
        if stays is not None:
            stays = np.broadcast_to(np.asarray(stays, float), (len(ent),))
            speed_mu = np.broadcast_to(np.asarray(speed_mu, float), stays.shape)
            speed_sigma = np.broadcast_to(np.asarray(speed_sigma, float), stays.shape)
        cls = np.broadcast_to(np.asarray(class_index, np.int64), (len(ent),))
        reach = np.broadcast_to(np.asarray(reach, float), (len(ent),))
        out = np.full((len(ent), 2), -1, np.int64)
        if not len(ent):
            return out
        uniq, inv = np.unique(ent, axis=0, return_inverse=True)
        inv = inv.ravel()
        dist = self.geodesic(uniq)
        # the nearest cell one move or more from each entry: a smaller reach has no exit
        # (checked without building an (H, W) mask per artefact)
        near = np.array([d[d >= 1].min(initial=np.inf) for d in dist])
        ent_xy = self.cell_to_world(ent)
        h, w = self.free.shape
        of_class = {c: np.flatnonzero(self.track_class == c) for c in np.unique(cls)}
        if stays is not None:
            self._draw_exits_given_stays(
                rng,
                out,
                cls,
                ent,
                inv,
                dist,
                near,
                ent_xy,
                reach,
                of_class,
                tries,
                stays,
                speed_mu,
                speed_sigma,
            )
            return out
        for i in range(len(ent)):
            d_i = dist[inv[i]]
            if not near[inv[i]] <= reach[i]:
                continue
            m_of = of_class[cls[i]]
            if not m_of.size:
                cand = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
                out[i] = cand[rng.integers(len(cand))]
                continue
            hx = self.bandwidth_exit[cls[i]]
            cdf = self._track_cdf(int(cls[i]), m_of, ent_xy[i])
            xy, c = None, None  # the first exit that is free and reachable
            for _ in range(tries):
                m = m_of[int(cdf.searchsorted(rng.random(), side="right"))]
                xy = self.exit_xy[m] + rng.normal(0.0, hx, 2)
                c = np.floor((xy - self.origin) / self.cell).astype(int)[::-1]
                if not (0 <= c[0] < h and 0 <= c[1] < w):
                    c = self._nearest_open(d_i, xy[None, :])[0]
                if 1 <= d_i[c[0], c[1]] <= reach[i]:
                    break
                c = None
            if c is not None:
                out[i] = c
            else:
                cand = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
                cxy = self.cell_to_world(cand)
                out[i] = cand[np.argmin(((cxy - xy) ** 2).sum(axis=1))]
        return out

    def _draw_exits_given_stays(
        self,
        rng: np.random.Generator,
        out: np.ndarray,
        cls: np.ndarray,
        ent: np.ndarray,
        inv: np.ndarray,
        dist: np.ndarray,
        near: np.ndarray,
        ent_xy: np.ndarray,
        reach: np.ndarray,
        of_class: dict,
        tries: int,
        stays: np.ndarray,
        speed_mu: np.ndarray,
        speed_sigma: np.ndarray,
    ) -> None:
        """:meth:`draw_exits` with ``stays``, into ``out`` (n, 2).

        Each artefact draws from ``rng`` in a fixed order, whatever the draws are: ``tries``
        times a uniform (the track) and two standard normals (its exit's jitter), then one
        uniform (the kept try: ``rng.choice`` with weights draws one uniform against their
        normalised cumulative sum). So the draws are made first, artefact after artefact
        (the same draws from the same generator as checking each in turn), and everything
        else at once: the tracks' kernel weights once per entry cell, the checks of every
        try together, the speed weights of artefacts with as many exits within reach
        together (row sums over the same number of terms: the same sums as one by one).
        """
        n = len(ent)
        active = near[inv] <= reach
        has = np.array([of_class[c].size > 0 for c in cls]) if n else np.zeros(0, bool)
        u, z, u_keep = np.empty((n, tries)), np.empty((n, tries, 2)), np.empty(n)
        random, normal = rng.random, rng.standard_normal
        for i in np.flatnonzero(active):
            if not has[i]:  # a class without tracks: any cell within reach
                d_i = dist[inv[i]]
                cand = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
                out[i] = cand[rng.integers(len(cand))]
                continue
            u_i, z_i = u[i], z[i]
            for t in range(tries):
                u_i[t] = random()
                normal(out=z_i[t])  # rng.normal(0, hx, 2) is 0 + hx * these, bit for bit
            u_keep[i] = random()
        sel = np.flatnonzero(active & has)
        if not sel.size:
            return
        # the track of each try: inverse cdf of the kernel weights of the entry's cell
        track = np.empty((sel.size, tries), np.int64)
        keys = inv[sel] * (int(cls.max()) + 1) + cls[sel]
        for key in np.unique(keys):
            rows = np.flatnonzero(keys == key)
            i0 = sel[rows[0]]
            m_of = of_class[cls[i0]]
            cdf = self._track_cdf(int(cls[i0]), m_of, ent_xy[i0])
            track[rows] = m_of[cdf.searchsorted(u[sel[rows]], side="right")]
        hx = self.bandwidth_exit[cls[sel]]
        all_xy = self.exit_xy[track] + (0.0 + hx[:, None, None] * z[sel])
        cc = np.floor((all_xy - self.origin) / self.cell).astype(int)[..., ::-1]
        h, w = self.free.shape
        inside = (cc[..., 0] >= 0) & (cc[..., 0] < h) & (cc[..., 1] >= 0) & (cc[..., 1] < w)
        if not inside.all():  # jittered past the map's edge: its nearest open cell
            row_of = np.broadcast_to(inv[sel][:, None], inside.shape)
            for j in np.unique(row_of[~inside]):
                past = ~inside & (row_of == j)
                cc[past] = self._nearest_open(dist[j], all_xy[past])
        d_c = dist[inv[sel][:, None], cc[..., 0], cc[..., 1]]
        ok = (d_c >= 1) & (d_c <= reach[sel][:, None])
        for r in np.flatnonzero(~ok.any(axis=1)):
            # no exit within reach: each draw as far towards it as it can
            i = sel[r]
            d_i = dist[inv[i]]
            within = np.argwhere((d_i <= reach[i]) & (d_i >= 1))
            cxy = self.cell_to_world(within)
            d2 = ((all_xy[r][:, None, :] - cxy[None, :, :]) ** 2).sum(axis=2)
            cc[r] = within[np.argmin(d2, axis=1)]
            ok[r] = True
        # the exits within reach first, in the order drawn; one kept with weight p_v(L / s)
        k = ok.sum(axis=1)
        first = np.argsort(~ok, axis=1, kind="stable")
        cc = np.take_along_axis(cc, first[..., None], axis=1)
        sd = np.where(np.isfinite(speed_sigma[sel]), speed_sigma[sel], 0.1)
        sd = np.maximum(sd, 0.02)
        per_s = np.maximum(stays[sel], 1e-9)
        for k_g in np.unique(k):
            rows = np.flatnonzero(k == k_g)
            i_g = sel[rows]
            c_g = cc[rows, :k_g]  # (g, k, 2)
            geo = dist[inv[i_g][:, None], c_g[..., 0], c_g[..., 1]]
            manhattan = np.maximum(np.abs(c_g - ent[i_g][:, None, :]).sum(axis=2), 1)
            xy = self.cell_to_world(c_g).reshape(*c_g.shape) - ent_xy[i_g][:, None, :]
            length = np.hypot(xy[..., 0], xy[..., 1]) * geo / manhattan
            v = np.maximum(length / per_s[rows][:, None], 1e-9)
            logw = (
                -np.log(v) - 0.5 * ((np.log(v) - speed_mu[i_g][:, None]) / sd[rows][:, None]) ** 2
            )
            q = np.exp(logw - logw.max(axis=1, keepdims=True))
            p = q / q.sum(axis=1, keepdims=True)
            if not np.isfinite(p).all():
                raise ValueError("draw_exits: the speed weights of some exits are not finite")
            cdf = p.cumsum(axis=1)
            cdf /= cdf[:, -1:]
            # numpy's rng.choice(k, p=p): cdf.searchsorted(u, side="right"), the number of
            # cumulative weights at most u (nondecreasing)
            pick = (cdf <= u_keep[i_g][:, None]).sum(axis=1)
            out[i_g] = c_g[np.arange(len(rows)), pick]

    def _track_cdf(self, c: int, m_of: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """(len(m_of),) float: the normalised cumulative kernel weights of class ``c``'s
        tracks ``m_of`` for an entry at ``xy`` (2,) (m), Gaussian in the distance to each
        track's entry (bandwidth :attr:`bandwidth_entry`).

        ``cdf.searchsorted(u, side="right")`` of a uniform ``u`` is ``rng.choice(len(m_of),
        p=p)`` as numpy draws it (one uniform against the normalised cumulative weights),
        without re-checking ``p`` on each try: the same draws from the same generator.
        """
        d2 = ((self.entry_xy[m_of] - xy) ** 2).sum(axis=1)
        logw = -0.5 * d2 / self.bandwidth_entry[c] ** 2
        p = np.exp(logw - logw.max())
        p /= p.sum()
        cdf = p.cumsum()
        cdf /= cdf[-1]
        return cdf

    def _nearest_open(self, dist: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """The cells ``(row, col)`` (m, 2) nearest to the points ``xy`` (m, 2) (m) among
        those reachable from the entry whose geodesic is ``dist`` (H, W) (the entry itself
        if no cell is)."""
        h, w = dist.shape
        # the map's cell nearest to a point past its edge is the one it clips to; where
        # that one is open it is the answer (a door in the edge), else the nearest open one
        c = np.floor((xy - self.origin) / self.cell).astype(np.int64)[:, ::-1]
        c = np.clip(c, 0, [h - 1, w - 1])
        shut = ~np.isfinite(dist[c[:, 0], c[:, 1]])
        if shut.any():
            open_ = np.argwhere(np.isfinite(dist))
            if not len(open_):
                return c
            centre = self.cell_to_world(open_)
            d2 = ((xy[shut, None, :] - centre[None, :, :]) ** 2).sum(axis=2)
            c[shut] = open_[np.argmin(d2, axis=1)]
        return c

    # ------------------------------------------------------------------ xarray
    def to_dataset(self) -> xr.Dataset:
        """The fit as an ``xarray.Dataset`` (the fit file's ``behaviour`` group).

        Returns
        -------
        xarray.Dataset
            Per-class variables on dimension ``class``, tracks on ``track``, the grid on
            ``row, col``; scalars and settings in ``attrs``.
        """
        import xarray as xr  # lazy: +0.22 s CPU on `import are_stats.behaviour`

        data = {k: (("class",), np.asarray(getattr(self, k))) for k in (*_PER_CLASS, *_WITHIN)}
        data["free"] = (("row", "col"), np.asarray(self.free, np.int8))
        data["track_class"] = (("track",), np.asarray(self.track_class, np.int64))
        data["entry_xy"] = (("track", "xy"), np.asarray(self.entry_xy, float))
        data["exit_xy"] = (("track", "xy"), np.asarray(self.exit_xy, float))
        attrs = {
            "cell": float(self.cell),
            "origin_x": float(self.origin[0]),
            "origin_y": float(self.origin[1]),
            "time_cost": float(self.time_cost),
            "goal_reward": float(self.goal_reward),
            "step_cost": float(self.step_cost),
            "warnings": "\n".join(self.warnings),
        }
        if self.standing:  # absent without standing classes: such files are as before
            attrs["standing"] = "\n".join(self.standing)
        coords = {"class": list(self.classes), "xy": ["x", "y"]}
        if self.feature_names:  # absent without features: such files are as before
            data["feature_weight"] = (("class", "feature"), np.asarray(self.weights, float))
            data["feature_weight_se"] = (("class", "feature"), np.asarray(self.weights_se, float))
            data["feature_map"] = (("feature", "row", "col"), np.asarray(self.features, float))
            coords["feature"] = list(self.feature_names)
        return xr.Dataset(data, coords=coords, attrs=attrs)

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> BehaviourFit:
        """Inverse of :meth:`to_dataset` (files without features give ``F = 0``)."""
        a = ds.attrs
        n_class = int(ds.sizes["class"])
        kw = {
            k: np.asarray(ds[k].values) if k in ds else np.full(n_class, np.nan) for k in _PER_CLASS
        }  # fit files leave out the wall-clock fit_seconds (same seed, same bytes)
        # files from before the within-person variation was fitted: none (_WITHIN)
        kw |= {k: np.asarray(ds[k].values, float) for k in _WITHIN if k in ds}
        w = str(a.get("warnings", ""))
        standing = str(a.get("standing", ""))  # files before it: none
        feats: dict[str, tuple[str, ...] | np.ndarray] = {}
        if "feature_weight" in ds:
            feats = {
                "feature_names": tuple(str(n) for n in ds["feature"].values),
                "features": np.asarray(ds["feature_map"].values, float),
                "weights": np.asarray(ds["feature_weight"].values, float),
                "weights_se": np.asarray(ds["feature_weight_se"].values, float),
            }
        return cls(
            classes=tuple(str(c) for c in ds["class"].values),
            cell=float(a["cell"]),
            origin=np.array([float(a["origin_x"]), float(a["origin_y"])]),
            free=np.asarray(ds["free"].values).astype(bool),
            track_class=np.asarray(ds["track_class"].values, np.int64),
            entry_xy=np.asarray(ds["entry_xy"].values, float),
            exit_xy=np.asarray(ds["exit_xy"].values, float),
            time_cost=float(a["time_cost"]),
            goal_reward=float(a["goal_reward"]),
            step_cost=float(a["step_cost"]),
            warnings=w.split("\n") if w else [],
            standing=tuple(standing.split("\n")) if standing else (),
            **feats,
            **kw,
        )
