"""Path planners on the augmented, inflated occupancy grid (paper Sect. 4, Fig. 6).

A planner is any callable ``planner(free, start, goal, params) -> path | None``:

* ``free : (H, W) bool``: cells the robot centre may occupy (the augmented grid with only
  the perceived artefacts, inflated by the robot radius); ``free[i, j]`` is row ``i``
  (grid y) and column ``j`` (grid x), row 0 at the map origin as in ROS;
* ``start, goal : (2,) float``: positions in metres in the grid's local frame (the lower-left
  corner of cell ``(0, 0)`` is the origin, x along columns, y along rows);
* ``params : dict``: planner settings; the experiment loop always adds ``resolution`` (m per
  cell) and ``seed`` (int);
* returns a ``(k, 2)`` float path from ``start`` to ``goal`` in the same frame, or ``None``
  when no path was found.

Users plug their own planner by passing such a callable. :func:`timed_plan` measures the
wall-clock time ``rho_t`` of a call (eq. 3). Two planners ship:

* :class:`OMPLPlanner`: OMPL's sampling-based planners (RRT, RRT-Connect, RRT*, PRM) over an
  R^2 state space with a grid validity checker; ``range`` and ``goal_bias`` are the paper's
  parameters (Fig. 6);
* :class:`AStarPlanner`: a deterministic 8-connected grid A* baseline.
"""

from __future__ import annotations

import abc
import functools
import heapq
import math
import time
from collections import deque
from collections.abc import Mapping
from typing import Any, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_finite, check_in, check_positive, describe
from are_stats.inputs import get_bool, get_float, get_int, get_str

__all__ = [
    "OMPL_ALGORITHMS",
    "AStarPlanner",
    "OMPLPlanner",
    "Planner",
    "check_free_mask",
    "make_planner",
    "timed_plan",
]

#: OMPL geometric planners offered by :class:`OMPLPlanner`.
OMPL_ALGORITHMS = ("RRT", "RRTConnect", "RRTstar", "PRM")

# OMPL's bindings load when an OMPLPlanner plans, not with A*; their states stay `Any` (the
# bindings ship no type stubs).


class Planner(Protocol):
    """A path planner: ``(free, start, goal, params) -> (k, 2) path | None`` (see module)."""

    def __call__(
        self, free: np.ndarray, start: np.ndarray, goal: np.ndarray, params: Mapping[str, float]
    ) -> np.ndarray | None: ...


def check_free_mask(free: npt.ArrayLike) -> np.ndarray:
    """Validate a ``(H, W)`` bool free mask."""
    m = np.asarray(free)
    if m.dtype != bool or m.ndim != 2 or 0 in m.shape:
        raise ValueError(f"free: expected a non-empty (H, W) bool array, got {describe(free)}")
    return m


def _point(name: str, p: npt.ArrayLike) -> np.ndarray:
    a = check_finite(name, p, ndim=1)
    if a.shape != (2,):
        raise ValueError(f"{name}: expected (x, y), got {a.tolist()}")
    return a


def _resolution(params: Mapping[str, float]) -> float:
    if "resolution" not in params:
        raise ValueError(f"params: expected a 'resolution' key (m per cell), got {sorted(params)}")
    return float(check_positive("params['resolution']", params["resolution"]))


def _cell(free: np.ndarray, p: np.ndarray, res: float) -> tuple[int, int] | None:
    i, j = int(math.floor(p[1] / res)), int(math.floor(p[0] / res))
    if 0 <= i < free.shape[0] and 0 <= j < free.shape[1]:
        return i, j
    return None


class _Query(NamedTuple):
    """What both planners check before planning: the mask, the end points and their cells."""

    free: np.ndarray  # (H, W) bool
    start: np.ndarray  # (2,) float, m
    goal: np.ndarray  # (2,) float, m
    res: float  # m per cell
    start_cell: tuple[int, int]  # (row, col)
    goal_cell: tuple[int, int]


def _query(
    free: np.ndarray, start: np.ndarray, goal: np.ndarray, params: Mapping[str, float]
) -> _Query | None:
    """A planner's validated arguments; ``None`` (no path) when ``start`` or ``goal`` lies
    off the grid or on a blocked cell."""
    free = check_free_mask(free)
    res = _resolution(params)
    start, goal = _point("start", start), _point("goal", goal)
    s, g = _cell(free, start, res), _cell(free, goal, res)
    if s is None or g is None or not free[s] or not free[g]:
        return None
    return _Query(free, start, goal, res, s, g)


def timed_plan(
    planner: Planner,
    free: npt.ArrayLike,
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    params: Mapping[str, float],
) -> tuple[np.ndarray | None, float]:
    """Call ``planner`` and measure its wall-clock time ``rho_t`` (eq. 3).

    Returns
    -------
    path : (k, 2) float or None
        The planner's path, validated (``None`` when it found none).
    seconds : float
        Wall-clock planning time (``time.perf_counter``).

    Raises
    ------
    ValueError
        If the planner returns something other than ``None`` or a finite ``(k, 2)`` array.
    """
    f = check_free_mask(free)
    s, g = _point("start", start), _point("goal", goal)
    t0 = time.perf_counter()
    path = planner(f, s, g, params)
    dt = time.perf_counter() - t0
    if path is None:
        return None, dt
    p = np.asarray(path, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 1 or not np.isfinite(p).all():
        raise ValueError(
            f"planner: expected a finite (k, 2) path or None, got {describe(path)} "
            f"from {getattr(planner, '__name__', type(planner).__name__)}"
        )
    return p, dt


class _GridPlanner(abc.ABC):
    """What the two planners share: the checks of :func:`_query` before ``_plan``."""

    def __call__(
        self, free: np.ndarray, start: np.ndarray, goal: np.ndarray, params: Mapping[str, float]
    ) -> np.ndarray | None:
        q = _query(free, start, goal, params)
        return None if q is None else self._plan(q, params)

    @abc.abstractmethod
    def _plan(self, q: _Query, params: Mapping[str, float]) -> np.ndarray | None:
        """The path of a checked query, or None."""


class AStarPlanner(_GridPlanner):
    """Grid A* on the 8-connected free cells (a deterministic, fast baseline).

    Moves between cell centres cost their Euclidean length; diagonal moves may not cut a
    blocked corner. The heuristic is the octile distance (admissible and consistent), so
    the path is a shortest 8-connected path. The returned path starts at ``start``, runs
    through the centres of the cells on the way (collinear runs merged) and ends at ``goal``.

    Examples
    --------
    >>> free = np.ones((5, 5), bool); free[1:4, 2] = False
    >>> path = AStarPlanner()(free, np.array([0.5, 2.5]), np.array([4.5, 2.5]),
    ...                       {"resolution": 1.0})
    >>> path[0].tolist(), path[-1].tolist()
    ([0.5, 2.5], [4.5, 2.5])
    """

    name = "astar"

    def _plan(self, q: _Query, params: Mapping[str, float]) -> np.ndarray | None:
        cells = astar_cells(q.free, q.start_cell, q.goal_cell)
        if cells is None:
            return None
        pts = _merge_collinear((cells[:, ::-1] + 0.5) * q.res)
        if len(pts) > 2:
            return np.vstack([q.start, pts[1:-1], q.goal])
        return np.vstack([q.start, q.goal])


def _merge_collinear(pts: np.ndarray) -> np.ndarray:
    if len(pts) <= 2:
        return pts
    d = np.diff(pts, axis=0)
    turn = np.abs(d[1:, 0] * d[:-1, 1] - d[1:, 1] * d[:-1, 0]) > 1e-12
    keep = np.r_[True, turn, True]
    return pts[keep]


_MOVES = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def astar_cells(
    free: np.ndarray, start: tuple[int, int], goal: tuple[int, int]
) -> np.ndarray | None:
    """Shortest 8-connected cell path ``(k, 2)`` (rows, cols) from ``start`` to ``goal``.

    Diagonal moves need both adjacent orthogonal cells free (no corner cutting). ``None``
    when the goal cannot be reached.
    """
    h, w = free.shape
    sq2 = math.sqrt(2.0)
    c2 = sq2 - 2.0
    # the grid padded by a blocked ring (no bounds tests), as bytes; costs and parents in
    # dicts of the cells reached: NumPy scalar indexing costs more than the search itself,
    # and whole-grid lists more than a short search. The same pops and pushes in the same
    # order as on the (H, W) grid (padded indices keep the cells' order), so the same path,
    # ties included
    fp = np.zeros((h + 2, w + 2), bool)
    fp[1:-1, 1:-1] = free
    fr = fp.tobytes()
    wp = w + 2
    sp, gp = (start[0] + 1) * wp + start[1] + 1, (goal[0] + 1) * wp + goal[1] + 1
    gr, gc = goal[0] + 1, goal[1] + 1
    # octile distance to the goal, dr + dc + (sqrt 2 - 2) min(dr, dc)
    ar, ac = abs(start[0] + 1 - gr), abs(start[1] + 1 - gc)
    heap = [(ar + ac + c2 * min(ar, ac), 0.0, sp)]
    inf = math.inf
    cost = {sp: 0.0}
    parent: dict[int, int] = {}
    closed = bytearray(len(fr))
    # (offset, step, the two orthogonal neighbours a diagonal needs free, dr, dc) in the
    # order of _MOVES (the order ties are pushed in)
    moves = [
        (
            dr * wp + dc,
            sq2 if dr and dc else 1.0,
            dr * wp if dr and dc else 0,
            dc if dr and dc else 0,
            dr,
            dc,
        )
        for dr, dc in _MOVES
    ]
    pop, push, get = heapq.heappop, heapq.heappush, cost.get
    while heap:
        _, g_cost, u = pop(heap)
        if closed[u]:
            continue
        if u == gp:
            break
        closed[u] = 1
        r, c = divmod(u, wp)
        for off, step, a, b, dr, dc in moves:
            v = u + off
            if not fr[v] or closed[v]:
                continue
            if a and not (fr[u + b] and fr[u + a]):
                continue
            nc = g_cost + step
            if nc < get(v, inf):
                cost[v] = nc
                parent[v] = u
                ar, ac = abs(r + dr - gr), abs(c + dc - gc)
                push(heap, (nc + (ar + ac + c2 * (ar if ar < ac else ac)), nc, v))
    if gp not in cost:
        return None
    out = [gp]
    while out[-1] != sp:
        out.append(parent[out[-1]])
    idx = np.array(out[::-1])
    return np.stack(np.divmod(idx, wp), axis=1) - 1


class OMPLPlanner(_GridPlanner):
    """OMPL's sampling-based planners on the grid (RRT, RRT-Connect, RRT*, PRM).

    The state space is R^2 bounded by the grid; a state is valid when its cell is free.
    Motions are checked every ``motion_resolution`` cells, so a segment may clip an
    obstacle corner by less than that step (the experiment loop's inflation margin of half
    a cell diagonal absorbs it). ``range`` (m) and ``goal_bias``
    (probability) are the paper's parameters (Fig. 6); they apply to the algorithms that
    have them (``range``: RRT, RRT-Connect, RRT*; ``goal_bias``: RRT, RRT*), and giving them
    to an algorithm without them is an error.

    Termination: RRT and RRT-Connect stop at the first exact solution; the anytime planners
    (RRT*, PRM) use the whole budget. The budget is ``time_limit`` seconds and, when given,
    ``max_iterations`` termination-condition checks (deterministic, machine-independent;
    not for PRM, which grows its roadmap in a second thread and runs on time only).
    OMPL's random generator is seeded with ``params["seed"]`` before each plan, so
    planners that end on the iteration budget or at their first solution give the same
    path for the same seed.

    Parameters
    ----------
    algorithm : {"RRT", "RRTConnect", "RRTstar", "PRM"}
    range : float, optional
        Maximum motion length added to the tree (m).
    goal_bias : float, optional
        Probability of sampling the goal, in [0, 1].
    time_limit : float
        Planning time budget (s), in ``(0, 3600]``.
    max_iterations : int, optional
        Budget of termination-condition checks.
    simplify : bool
        Shortcut and smooth the solution with OMPL's path simplifier (its time counts in
        ``rho_t``).
    motion_resolution : float
        Motion-check step, in cells, in ``[0.01, 1000]``.

    Examples
    --------
    >>> free = np.ones((50, 50), bool)
    >>> plan = OMPLPlanner("RRTConnect", range=1.0)
    >>> path = plan(free, np.array([0.5, 0.5]), np.array([4.0, 4.0]),
    ...             {"resolution": 0.1, "seed": 1})
    >>> path[0].tolist(), path[-1].tolist()
    ([0.5, 0.5], [4.0, 4.0])
    """

    def __init__(
        self,
        algorithm: str = "RRTConnect",
        *,
        range: float | None = None,  # noqa: A002 (OMPL's name)
        goal_bias: float | None = None,
        time_limit: float = 1.0,
        max_iterations: int | None = None,
        simplify: bool = True,
        motion_resolution: float = 0.25,
    ) -> None:
        src = "planner"
        self.algorithm = get_str(algorithm, src, "algorithm", choices=OMPL_ALGORITHMS)
        if range is not None:
            range = get_float(range, src, "range", lo=0.0, lo_open=True)
            if self.algorithm == "PRM":
                raise ValueError("range: OMPL's PRM has no range parameter (use RRT*, RRT...)")
        if goal_bias is not None:
            goal_bias = get_float(goal_bias, src, "goal_bias", lo=0.0, hi=1.0)
            if self.algorithm in ("RRTConnect", "PRM"):
                raise ValueError(f"goal_bias: OMPL's {self.algorithm} has no goal bias")
        self.range = range
        self.goal_bias = goal_bias
        self.time_limit = get_float(time_limit, src, "time_limit", lo=0.0, lo_open=True, hi=3600.0)
        self.max_iterations = (
            None
            if max_iterations is None
            else get_int(max_iterations, src, "max_iterations", lo=1, hi=2**62)
        )
        if self.max_iterations is not None and self.algorithm == "PRM":
            raise ValueError("max_iterations: OMPL's PRM runs on a time budget only")
        self.simplify = get_bool(simplify, src, "simplify")
        # finer than 1/100 cell, a motion check could take longer than any time budget
        self.motion_resolution = get_float(
            motion_resolution, src, "motion_resolution", lo=0.01, hi=1000.0
        )

    @property
    def name(self) -> str:
        """Short label, e.g. ``RRTConnect(range=2.0)``."""
        opts = [f"range={self.range:g}"] if self.range is not None else []
        if self.goal_bias is not None:
            opts.append(f"goal_bias={self.goal_bias:g}")
        return f"{self.algorithm}({', '.join(opts)})"

    def __repr__(self) -> str:
        return f"OMPLPlanner({self.name}, time_limit={self.time_limit:g})"

    def _plan(self, q: _Query, params: Mapping[str, float]) -> np.ndarray | None:
        # lazy: OMPL's bindings add 0.04 s CPU to `import are_stats.experiments`
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        free, start, goal, res = q.free, q.start, q.goal, q.res
        if self.motion_resolution < 1.0 and not _connected(free, q.start_cell, q.goal_cell):
            # checks less than a cell apart on a motion fall in 8-neighbouring cells, so
            # every path OMPL can validate stays in the start's 8-connected free cells: the
            # goal outside them, every seed fails (after its whole budget)
            return None
        h, w = free.shape
        ou.setLogLevel(ou.LOG_NONE)
        ou.RNG.setSeed(int(params.get("seed", 0)) % (2**31 - 1) + 1)
        space = ob.RealVectorStateSpace(2)
        bounds = ob.RealVectorBounds(2)
        bounds.setLow(0, 0.0)
        bounds.setHigh(0, w * res)
        bounds.setLow(1, 0.0)
        bounds.setHigh(1, h * res)
        space.setBounds(bounds)
        setup = og.SimpleSetup(space)
        inv = 1.0 / res

        # a lookup in bytes, not NumPy's scalar indexing (the same cells, so the same plans)
        cells = free.tobytes()

        def valid(state: Any) -> bool:
            j, i = int(state[0] * inv), int(state[1] * inv)
            return 0 <= i < h and 0 <= j < w and cells[i * w + j] == 1

        setup.setStateValidityChecker(valid)
        si = setup.getSpaceInformation()
        # fraction of the space's maximum extent (its diagonal)
        si.setStateValidityCheckingResolution(min(1.0, self.motion_resolution / math.hypot(h, w)))
        # the motions' states checked in one NumPy pass each instead of one Python call
        # each from OMPL's discrete motion validator (5.6 million in 600 s of mission)
        si.setMotionValidator(_grid_motion_validator()(si, space, free, inv))
        a, b = space.allocState(), space.allocState()
        a[0], a[1] = float(start[0]), float(start[1])
        b[0], b[1] = float(goal[0]), float(goal[1])
        setup.setStartAndGoalStates(a, b)
        planner = getattr(og, self.algorithm)(si)
        if self.range is not None:
            planner.setRange(self.range)
        if self.goal_bias is not None:
            planner.setGoalBias(self.goal_bias)
        setup.setPlanner(planner)
        deadline = time.perf_counter() + self.time_limit
        budget = self.max_iterations
        count = [0]

        def stop() -> bool:
            count[0] += 1
            return (budget is not None and count[0] > budget) or time.perf_counter() > deadline

        if self.algorithm == "PRM":
            # PRM grows its roadmap in a second thread: a Python termination callback would
            # deadlock with it on the GIL, so PRM runs on OMPL's own timed condition.
            setup.solve(self.time_limit)
        else:
            setup.solve(ob.PlannerTerminationCondition(stop))
        if not setup.haveExactSolutionPath():
            return None
        if self.simplify:
            setup.simplifySolution()
        path = setup.getSolutionPath()
        out = np.array([[st[0], st[1]] for st in path.getStates()], dtype=float)
        out[0], out[-1] = start, goal
        return out


def _connected(free: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether cells ``a`` and ``b`` (row, col) of ``free`` (H, W) bool are in the same
    8-connected set of free cells (both free)."""
    # lazy: SciPy's ndimage adds 0.15 s CPU to `import are_stats.experiments`
    from scipy import ndimage

    lab, _ = ndimage.label(free, structure=np.ones((3, 3), bool))
    return bool(lab[a] != 0 and lab[a] == lab[b])


def _bisection(n: int) -> list[float]:
    """The interpolation fractions ``k / n`` (k = 1 .. n - 1) in the order OMPL's
    ``DiscreteMotionValidator`` checks them: the middle of each remaining interval first."""
    out, queue = [], deque([(1, n - 1)])
    while queue:
        lo, hi = queue.popleft()
        mid = (lo + hi) // 2
        out.append(mid / n)
        if lo < mid:
            queue.append((lo, mid - 1))
        if hi > mid:
            queue.append((mid + 1, hi))
    return out


#: The states of a motion checked one at a time in Python, in OMPL's order, before the rest
#: in one NumPy pass: a motion into a wall mostly fails among them, and NumPy's few calls
#: cost as much as about 45 states checked in Python.
_FIRST_CHECKS = 16


@functools.lru_cache(maxsize=4096)
def _motion_fractions(n: int) -> tuple[tuple[float, ...], np.ndarray | None]:
    """:func:`_bisection` of ``n`` as the motion validator reads it: the first
    ``_FIRST_CHECKS`` fractions, and the rest (read-only) when there are more (``None``
    otherwise). Cached for the process: a motion's segment count recurs across plans (a
    validator's own cache, one per plan, recomputed them about 270,000 times in the RRT
    hour of the benchmark, 38 million fractions)."""
    order = _bisection(n)
    rest = None
    if n - 1 > _FIRST_CHECKS:
        rest = np.array(order)
        rest.flags.writeable = False
    return tuple(order[:_FIRST_CHECKS]), rest


@functools.cache
def _grid_motion_validator() -> type:
    """The class of :class:`OMPLPlanner`'s motion validator (OMPL is imported on first use).

    The same answer as OMPL's ``DiscreteMotionValidator`` over the planner's state validity
    checker (a state is valid when its cell is free), in one Python call per motion instead
    of one per state (OMPL's call into Python costs more than the check): the end state,
    then the ``validSegmentCount - 1`` states between, ``s1 + (s2 - s1) * (k / n)`` as
    OMPL's ``RealVectorStateSpace::interpolate`` computes them, the first
    ``_FIRST_CHECKS`` in OMPL's order (the middle first), the rest of a long motion in one
    NumPy pass; their cells by truncation as the state check takes them (the start state
    is assumed valid, as OMPL does).
    """
    # lazy: OMPL's bindings add 0.04 s CPU to `import are_stats.experiments`
    from ompl import base as ob

    class GridMotionValidator(ob.MotionValidator):
        def __init__(
            self,
            si: ob.SpaceInformation,
            space: ob.RealVectorStateSpace,
            free: np.ndarray,
            inv: float,
        ) -> None:
            super().__init__(si)
            self._space = space  # OMPL's validSegmentCount: its exact rounding
            self._cells = free.tobytes()
            self._free = free.ravel()
            self._h, self._w = free.shape
            self._inv = inv

        def checkMotion(self, s1: Any, s2: Any) -> bool:  # noqa: N802 (OMPL's name)
            h, w, inv, cells = self._h, self._w, self._inv, self._cells
            x2, y2 = s2[0], s2[1]
            j, i = int(x2 * inv), int(y2 * inv)
            if not (0 <= i < h and 0 <= j < w and cells[i * w + j]):
                return False
            n = self._space.validSegmentCount(s1, s2)
            if n < 2:
                return True
            first, rest = _motion_fractions(n)
            x1, y1 = s1[0], s1[1]
            dx, dy = x2 - x1, y2 - y1
            for t in first:  # where a motion into a wall mostly fails, one at a time
                j, i = int((x1 + dx * t) * inv), int((y1 + dy * t) * inv)
                if not (0 <= i < h and 0 <= j < w and cells[i * w + j]):
                    return False
            if rest is None:
                return True
            # a long motion: all its states in one NumPy pass
            jj = ((x1 + dx * rest) * inv).astype(np.int64)
            ii = ((y1 + dy * rest) * inv).astype(np.int64)
            if ((ii < 0) | (ii >= h) | (jj < 0) | (jj >= w)).any():
                return False
            return bool(self._free[ii * w + jj].all())

    return GridMotionValidator


def make_planner(spec: Mapping[str, object] | Planner) -> Planner:
    """A planner from a spec dict (as in a sweep YAML) or a callable (returned unchanged).

    ``{"algorithm": "astar"}`` gives :class:`AStarPlanner`; any of :data:`OMPL_ALGORITHMS`
    gives :class:`OMPLPlanner` with the remaining keys (``range``, ``goal_bias``,
    ``time_limit``, ``max_iterations``, ``simplify``, ``motion_resolution``). A ``name``
    key (a label for tables and plots) is ignored here.
    """
    if callable(spec):
        return spec
    if not isinstance(spec, Mapping):
        raise ValueError(f"planner: expected a dict or a callable, got {describe(spec)}")
    opts = {k: v for k, v in spec.items() if k != "name"}
    algorithm = opts.pop("algorithm", "RRTConnect")
    if algorithm == "astar":
        if opts:
            raise ValueError(f"planner: astar takes no options, got {sorted(opts)}")
        return AStarPlanner()
    check_in("planner['algorithm']", algorithm, (*OMPL_ALGORITHMS, "astar"))
    known = {"range", "goal_bias", "time_limit", "max_iterations", "simplify", "motion_resolution"}
    extra = sorted(set(opts) - known)
    if extra:
        raise ValueError(f"planner: unknown option(s) {extra} (known: {sorted(known)})")
    return OMPLPlanner(algorithm, **opts)
