"""Posterior-predictive scenarios: whole artefact populations drawn from fitted parameters.

Each scenario takes one posterior draw ``(lambda, mu, pi, lambda_mix)`` and simulates, on
``[0, horizon]``, the marked Poisson process of Sect. 3.2:

* the population present at time 0: ``Poisson(lambda * nu / mu)`` artefacts (the
  stationary law of N(t) under linear death, DECISIONS 1), or none with ``start="empty"``;
  by memorylessness their residual lifetimes are again ``Exp(mu)``;
* arrivals: ``Poisson(lambda * nu * horizon)`` times uniform on ``[0, horizon]``;
* lifetimes ``Exp(mu)``; a leaving time beyond the horizon is kept (not clipped) and
  flagged ``censored``;
* marks X from the Poisson mixture of eq. (1); the component is the artefact's ``class``
  (DECISIONS 5); a fit of a log that names its classes without marks draws the class from
  its shares instead, and the stay from the class's law;
* positions uniform over the free cells of the map (a uniformly chosen free cell, then
  uniform inside it, DECISIONS 4); headings uniform over ``{0, pi/2, pi, 3pi/2}``
  (DECISIONS 6) or over ``[0, 2pi)``.

Everything is drawn for all scenarios at once with one NumPy ``Generator`` (no Python loop
per scenario or artefact), so the same seed gives the same table on every machine with the
same NumPy version, and :func:`~are_stats.scenarios.write_scenes` writes it byte for byte
identically.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd

from are_stats._atomic import atomic_folder, check_folder
from are_stats._checks import check_in, check_nonnegative, check_positive, describe
from are_stats.inputs import check_memory, check_work, get_float, get_int
from are_stats.scenarios._folder import SCENARIO_COLUMNS

if TYPE_CHECKING:
    from are_stats.environment import OccupancyGrid
    from are_stats.traffic import PositionDensity, TrafficLaws

__all__ = [
    "ORIGIN_YAW_TOLERANCE",
    "SCENARIO_COLUMNS",
    "ScenarioSize",
    "atomic_folder",
    "check_folder",
    "check_origin_yaw",
    "check_scenario_size",
    "expected_artefacts",
    "generate_scenarios",
    "scenario_counts",
]


#: Largest ``|yaw|`` (rad) of a map's origin that counts as no rotation. Positions learned
#: on an axis-aligned grid (entry densities) are placed unrotated on such a map: ignoring a
#: yaw ``e`` moves a point ``r`` metres from the origin by ``e * r``, at most 1e-5 m at
#: :data:`~are_stats.scenarios.MAX_POSITION` (1e7 m) with 1e-12, far below any cell.
#: (The CLI once pre-checked with 1e-9, up to 1 cm there; yaws between the two passed it
#: and were refused here anyway: this one check decides.)
ORIGIN_YAW_TOLERANCE = 1e-12


def check_origin_yaw(yaw: float, what: str, source: str | None = None) -> None:
    """Refuse a rotated map for positions learned on an axis-aligned grid.

    Parameters
    ----------
    yaw : float
        The map's origin yaw (rad; ``OccupancyGrid.origin[2]``).
    what : str
        What needs the unrotated map, named in the error (``"learned positions"``).
    source : str, optional
        The map's file (``OccupancyGrid.source``), named in the error; ``map`` without
        one.

    Raises
    ------
    ValueError
        ``<source>: expected an origin yaw of 0 for <what>, got <yaw> (or use --positions
        uniform, or --model paper)`` when ``|yaw|`` exceeds :data:`ORIGIN_YAW_TOLERANCE`.

    Examples
    --------
    >>> check_origin_yaw(1e-13, "learned positions")  # below the tolerance: no rotation
    >>> check_origin_yaw(1e-9, "learned positions")
    Traceback (most recent call last):
    ValueError: map: expected an origin yaw of 0 for learned positions, got 1e-09 (or use ...)
    """
    if abs(float(yaw)) > ORIGIN_YAW_TOLERANCE:
        raise ValueError(
            f"{source or 'map'}: expected an origin yaw of 0 for {what}, got {yaw} (or use "
            "--positions uniform, or --model paper)"
        )


def _seed_sequence(key: int | jax.Array) -> tuple[np.random.SeedSequence, int | list[int]]:
    """A NumPy SeedSequence from an int seed or a JAX PRNG key (and a YAML-able record)."""
    if isinstance(key, bool):
        raise ValueError(f"key: expected an int seed >= 0 or a JAX PRNG key, got {key!r}")
    if isinstance(key, int | np.integer):
        if int(key) < 0:
            raise ValueError(f"key: expected an int seed >= 0 or a JAX PRNG key, got {key!r}")
        return np.random.SeedSequence(int(key)), int(key)
    try:
        if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
            key = jax.random.key_data(key)
        words = np.asarray(key)
    except (AttributeError, TypeError):
        raise ValueError(
            f"key: expected an int seed >= 0 or a JAX PRNG key, got {describe(key)}"
        ) from None
    if words.dtype != np.uint32 or words.ndim != 1 or words.size == 0:
        raise ValueError(f"key: expected an int seed >= 0 or a JAX PRNG key, got {describe(key)}")
    vals = [int(w) for w in words]
    return np.random.SeedSequence(vals), vals


def _sorted_uniforms(rng: np.random.Generator, sizes: np.ndarray) -> np.ndarray:
    """Concatenated blocks of ``sizes[i]`` sorted Uniform(0, 1) draws, without sorting.

    The order statistics of m uniforms are ``S_k / S_{m+1}`` with ``S_k`` the partial sums of
    m + 1 standard exponentials (Devroye 1986, V.2), so each block comes out sorted.
    """
    seg = sizes + 1
    e = rng.standard_exponential(int(seg.sum()))
    cs = np.cumsum(e)
    ends = np.cumsum(seg) - 1
    before = np.concatenate([[0.0], cs[ends[:-1]]])
    local = cs - np.repeat(before, seg)
    u = local / np.repeat(local[ends], seg)
    keep = np.ones(u.size, dtype=bool)
    keep[ends] = False
    return u[keep]


def _draws(params: Mapping[str, npt.ArrayLike]) -> dict[str, np.ndarray]:
    if not isinstance(params, Mapping):
        raise ValueError(f"params: expected a dict of posterior draws, got {type(params).__name__}")
    for name in ("arrival_rate", "leave_rate"):
        if name not in params:
            raise ValueError(
                f"params: expected a key {name!r} (posterior draws), got keys {sorted(params)}"
            )
    lam = np.atleast_1d(check_positive("params['arrival_rate']", params["arrival_rate"]))
    mu = np.atleast_1d(check_positive("params['leave_rate']", params["leave_rate"]))
    if lam.ndim != 1 or mu.ndim != 1:
        raise ValueError(
            f"params['arrival_rate'], params['leave_rate']: expected (S,) draws, "
            f"got shapes {lam.shape} and {mu.shape}"
        )
    s = lam.shape[0]
    if mu.shape[0] != s:
        raise ValueError(
            f"params['leave_rate']: expected {s} draws (as arrival_rate), got {mu.shape[0]}"
        )
    out = {"arrival_rate": lam, "leave_rate": mu}
    has_w, has_r = "mix_weights" in params, "mix_rates" in params
    if has_w != has_r:
        raise ValueError(
            "params: expected both 'mix_weights' and 'mix_rates' or neither, got "
            f"keys {sorted(params)}"
        )
    if has_w:
        w = check_nonnegative("params['mix_weights']", np.asarray(params["mix_weights"]) + 0.0)
        r = check_positive("params['mix_rates']", params["mix_rates"])
        if np.any(r > 1e18):  # NumPy's Poisson sampler refuses larger rates; marks are int64
            raise ValueError(
                f"params['mix_rates']: expected rates <= 1e18, got {float(np.max(r))!r}"
            )
        w = w[None, :] if w.ndim == 1 else w
        r = r[None, :] if r.ndim == 1 else r
        if w.ndim != 2 or w.shape != r.shape or w.shape[0] != s:
            raise ValueError(
                f"params['mix_weights'], params['mix_rates']: expected shapes "
                f"({s}, K), got {w.shape} and {r.shape}"
            )
        sums = w.sum(axis=1)
        bad = np.abs(sums - 1.0) > 1e-6
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"params['mix_weights']: expected rows summing to 1, got sum "
                f"{float(sums[i])!r} in draw {i}"
            )
        out["mix_weights"] = w / sums[:, None]
        out["mix_rates"] = r
    if "class_weights" in params:
        out.update(_class_draws(params, s))
    return out


def _class_draws(params: Mapping[str, npt.ArrayLike], s: int) -> dict[str, np.ndarray]:
    """``class_weights`` (S, K) and optional ``class_stay_mean`` (S, K), checked."""
    w = check_nonnegative("params['class_weights']", np.asarray(params["class_weights"]) + 0.0)
    w = w[None, :] if w.ndim == 1 else w
    if w.ndim != 2 or w.shape[0] != s:
        raise ValueError(f"params['class_weights']: expected shape ({s}, K), got {w.shape}")
    sums = w.sum(axis=1)
    if np.any(np.abs(sums - 1.0) > 1e-6):
        raise ValueError(
            f"params['class_weights']: expected rows summing to 1, got sums from "
            f"{float(sums.min())!r} to {float(sums.max())!r}"
        )
    out = {"class_weights": w / sums[:, None]}
    if "class_stay_mean" in params:
        m = check_positive("params['class_stay_mean']", params["class_stay_mean"])
        m = m[None, :] if m.ndim == 1 else m
        if m.shape != w.shape:
            raise ValueError(
                f"params['class_stay_mean']: expected shape {w.shape} (as class_weights), "
                f"got {m.shape}"
            )
        out["class_stay_mean"] = m
        k = np.atleast_1d(
            check_positive("params['class_stay_shape']", params.get("class_stay_shape", 1.0))
        )
        if k.shape not in ((1,), (s,)):
            raise ValueError(f"params['class_stay_shape']: expected ({s},) draws, got {k.shape}")
        out["class_stay_shape"] = np.broadcast_to(k, (s,)).astype(float)
    if "class_tod_weights" in params:
        t = check_nonnegative(
            "params['class_tod_weights']", np.asarray(params["class_tod_weights"]) + 0.0
        )
        if t.ndim != 3 or t.shape[0] != s or t.shape[2] != w.shape[1]:
            raise ValueError(
                f"params['class_tod_weights']: expected shape ({s}, P, {w.shape[1]}), got {t.shape}"
            )
        sums = t.sum(axis=2)
        if not np.allclose(sums, 1.0, atol=1e-6):
            raise ValueError("params['class_tod_weights']: expected shares summing to 1 per period")
        out["class_tod_weights"] = t / sums[..., None]
    return out


def _draw_classes(
    rng: np.random.Generator,
    p: Mapping[str, np.ndarray],
    law: str,
    d: np.ndarray,
    scen: np.ndarray,
    group: np.ndarray,
    initial: np.ndarray,
    t_arr: np.ndarray,
    t_leave: np.ndarray,
    clock: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The class of each artefact of a labelled fit, and its stay under its class.

    One class per group (members of a group share it): an arriving group's class is drawn
    from the shares ``class_weights``; a group present at the start from the stationary
    composition, shares times mean stays. With ``class_tod_weights`` (S, P, K) and the
    ``clock`` (time of day of ``t = 0``, length of a day) the shares are those of the
    period of the day the group arrives in (``t = 0``'s for those present at the start).
    With ``class_stay_mean`` each group's stay is drawn again from ``law`` with its class's
    mean and the shared ``class_stay_shape`` (a residual stay for the initial population),
    and each member's stay is scaled by the ratio of the new group stay to the old one (the
    members' jitter kept).
    """
    w = p["class_weights"][d]  # (n_sc, K)
    keys = np.stack([scen.astype(np.int64), np.asarray(group, np.int64)], axis=1)
    if keys.shape[0] == 0:
        return np.zeros(0, np.int32), t_leave
    _, first, inv = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    g_scen = scen[first]
    probs = w[g_scen]
    if "class_tod_weights" in p and clock is not None:
        # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
        from are_stats.traffic import period_of

        tw = p["class_tod_weights"][d]  # (n_sc, P, K)
        when = np.where(initial[first], 0.0, t_arr[first])
        probs = tw[g_scen, period_of(when, clock[0], tw.shape[1], clock[1])]
    per_class = "class_stay_mean" in p
    if per_class:
        m = p["class_stay_mean"][d][g_scen]
        biased = probs * m
        biased = biased / biased.sum(axis=1, keepdims=True)
        probs = np.where(initial[first][:, None], biased, probs)
    cum = np.cumsum(probs, axis=1)
    u = rng.random(first.size)
    cls_g = np.sum(u[:, None] >= cum[:, :-1], axis=1).astype(np.int32)
    cls = cls_g[inv]
    if per_class:
        # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
        from are_stats.traffic import stay_draws

        m_g = p["class_stay_mean"][d][g_scen, cls_g]
        k_g = p["class_stay_shape"][d][g_scen]
        g_init = initial[first]
        new = np.empty(first.size)
        for residual in (False, True):
            sel = g_init == residual
            new[sel] = stay_draws(rng, law, m_g[sel], k_g[sel], int(sel.sum()), residual)
        old = np.maximum(t_leave[first] - t_arr[first], 1e-300)
        t_leave = t_arr + (t_leave - t_arr) * (new / old)[inv]
    return cls, t_leave


def _place_by_class(
    rng: np.random.Generator,
    densities: Sequence[PositionDensity],
    cls: np.ndarray,
    scen: np.ndarray,
    group: np.ndarray,
    initial: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Arriving groups enter from their class's entry density (issue 31).

    Each arriving group's first member is placed at a point of ``densities[class]``; the
    other members keep their offsets from it (the group's spread), falling back to the
    point where the offset leaves the density's free cells. Those present at the start keep
    their places (drawn over the free cells, as the pooled laws place them).
    """
    x, y = np.array(x, float), np.array(y, float)
    keys = np.stack([scen.astype(np.int64), np.asarray(group, np.int64)], axis=1)
    arriving = ~np.asarray(initial, bool)
    if not arriving.any():
        return x, y
    k = int(np.max(cls)) + 1 if cls.size else 0
    if k > len(densities):
        raise ValueError(
            f"class_entry: expected an entry density per class ({k}), got {len(densities)}"
        )
    idx = np.flatnonzero(arriving)
    _, first, inv = np.unique(keys[idx], axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    g_cls = cls[idx[first]]
    anchor = np.empty((first.size, 2))
    for c in range(len(densities)):
        sel = g_cls == c
        if sel.any():
            anchor[sel] = densities[c].sample(rng, int(sel.sum()))
    off = np.column_stack([x[idx] - x[idx[first]][inv], y[idx] - y[idx[first]][inv]])
    new = anchor[inv] + off
    for c in range(len(densities)):
        sel = cls[idx] == c
        if sel.any():
            row, col = densities[c].cell_of(new[sel])
            ok = row >= 0
            on = np.zeros(row.size, bool)
            on[ok] = densities[c].prob[row[ok], col[ok]] > 0
            new[sel] = np.where(on[:, None], new[sel], anchor[inv][sel])
    x[idx], y[idx] = new[:, 0], new[:, 1]
    return x, y


def _grid(
    free_mask: npt.ArrayLike | OccupancyGrid, resolution: float, origin: Sequence[float]
) -> tuple[np.ndarray, float, tuple]:
    """Free mask, resolution and origin (x, y, yaw) from an array or an OccupancyGrid."""
    if hasattr(free_mask, "free") and hasattr(free_mask, "resolution"):
        ox, oy, oyaw = (float(v) for v in free_mask.origin)
        return np.asarray(free_mask.free, dtype=bool), float(free_mask.resolution), (ox, oy, oyaw)
    m = np.asarray(free_mask)
    if m.ndim != 2 or m.dtype != bool:
        raise ValueError(
            f"free_mask: expected a 2-d bool array (ny, nx) or an OccupancyGrid, "
            f"got {describe(free_mask)} of dtype {m.dtype}"
        )
    res = float(check_positive("resolution", resolution))
    o = np.asarray(origin, dtype=float).ravel()
    if o.size not in (2, 3) or not np.isfinite(o).all():
        raise ValueError(f"origin: expected (x, y) or (x, y, yaw), got {describe(origin)}")
    return m, res, (float(o[0]), float(o[1]), float(o[2]) if o.size == 3 else 0.0)


def generate_scenarios(
    key: int | jax.Array,
    params: Mapping[str, npt.ArrayLike],
    n_scenarios: int,
    horizon: float,
    free_mask: npt.ArrayLike | OccupancyGrid | None = None,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    area: float | None = None,
    start: str = "stationary",
    draw: str = "cycle",
    headings: int = 4,
    laws: TrafficLaws | None = None,
) -> pd.DataFrame:
    """Draw ``n_scenarios`` artefact populations on ``[0, horizon]`` from posterior draws.

    Parameters
    ----------
    key : int or jax.Array
        An int seed >= 0 or a JAX PRNG key; it seeds one NumPy ``Generator`` (PCG64).
    params : dict of str to array
        Posterior draws: ``arrival_rate`` (S,) (lambda, per m^2 per time unit),
        ``leave_rate`` (S,) (mu), optional ``mix_weights`` (S, K) and ``mix_rates`` (S, K)
        (eq. 1). Scalars / (K,) vectors are one draw. See
        :func:`~are_stats.fitting.posterior_draws`. A fit
        of a log that names its classes (labels, no marks) gives ``class_weights`` (S, K)
        instead of the mixture, and with per-class stays ``class_stay_mean`` (S, K) and
        ``class_stay_shape`` (S,): each group's class is drawn from the shares and its stay
        from its class (:func:`are_stats.fitting.fit_classes`); ``mark`` is then -1.
    n_scenarios : int
        Number of scenarios.
    horizon : float
        Length of each scenario, in the time unit of the rates.
    free_mask : (ny, nx) bool or OccupancyGrid, optional
        Free cells, ``free_mask[iy, ix]`` with ``iy = 0`` at the origin (ROS
        OccupancyGrid order); an ``OccupancyGrid`` brings its own
        resolution and origin (yaw included). Without a map, positions are uniform over the
        square ``[ox, ox + sqrt(area)] x [oy, oy + sqrt(area)]``.
    resolution : float
        Cell side (m) of ``free_mask`` given as an array.
    origin : (2,) or (3,) float
        World pose of the lower-left corner of cell (0, 0) for an array ``free_mask``.
    area : float, optional
        ``nu(M2D)`` in m^2 for the intensity ``lambda * nu``; default: free cells x
        resolution^2 (required without ``free_mask``).
    start : {"stationary", "empty"}
        Initial population ``Poisson(lambda * nu / mu)`` or none.
    draw : {"cycle", "random"}
        Scenario ``i`` uses draw ``i mod S``, or a draw chosen uniformly at random.
    headings : int
        4: yaw uniform over ``{0, pi/2, pi, 3pi/2}`` (plus the map's yaw); 0: uniform on
        ``[0, 2 pi)``.
    laws : are_stats.traffic.TrafficLaws, optional
        The arrival, stay and position laws (:func:`~are_stats.fitting.traffic_draws`
        reads them from a fit).
        None or the paper's laws: the vectorised paper sampler; otherwise each scenario is
        drawn by :func:`are_stats.traffic.sample_population` and ``params`` must also hold
        the laws' draws (``event_rate``, ``stay_mean``, ...).

    Returns
    -------
    pandas.DataFrame
        One row per artefact, columns :data:`SCENARIO_COLUMNS`, sorted by scenario then
        arrival time. ``attrs["generation"]`` records seed, settings and a summary of the
        parameters (written into the manifest by :func:`~are_stats.scenarios.write_scenes`);
        ``attrs["draws"]`` is the (n_scenarios,) draw index used by each scenario.

    Raises
    ------
    ValueError
        On malformed parameters, arguments or an empty map.

    Examples
    --------
    >>> df = generate_scenarios(0, {"arrival_rate": 0.001, "leave_rate": 1 / 600},
    ...                         n_scenarios=3, horizon=3600.0, area=100.0)
    >>> sorted(df["scenario"].unique().tolist())
    [0, 1, 2]
    """
    seq, seed_record = _seed_sequence(key)
    p = _draws(params)
    n_sc = get_int(n_scenarios, "n_scenarios", "", lo=1)
    h = get_float(horizon, "horizon", "", lo=0.0, lo_open=True)
    check_in("start", start, ("stationary", "empty"))
    check_in("draw", draw, ("cycle", "random"))
    check_in("headings", headings, (0, 4))
    map_source = getattr(free_mask, "source", None)  # an OccupancyGrid read from a file
    if free_mask is not None:
        mask, res, (ox, oy, oyaw) = _grid(free_mask, resolution, origin)
        iy_free, ix_free = np.nonzero(mask)
        if iy_free.size == 0:
            raise ValueError("free_mask: expected at least one free cell, got none")
        nu = float(iy_free.size) * res * res
    else:
        if area is None:
            raise ValueError(
                "area: expected the free area (m^2) when no free_mask is given, got None"
            )
        _, _, (ox, oy, oyaw) = _grid(np.ones((1, 1), bool), 1.0, origin)
        nu = float(check_positive("area", area))
    if area is not None:
        nu = float(check_positive("area", area))
    _check_size(p, ScenarioSize(n_sc, h, nu, start))
    rng = np.random.Generator(np.random.PCG64(seq))
    s = p["arrival_rate"].shape[0]
    d = np.arange(n_sc) % s if draw == "cycle" else rng.integers(0, s, size=n_sc)
    rich = laws is not None and not laws.is_paper
    if rich:
        scen, j, t_arr, t_leave, initial, group, xy_map = _rich_populations(
            rng,
            params,
            laws,
            d,
            h,
            nu,
            start,
            (mask, res, (ox, oy, oyaw)) if free_mask is not None else None,
            (ox, oy, oyaw),
            map_source,
        )
        total = scen.size
    else:
        scen, j, t_arr, t_leave, initial, total = _paper_populations(rng, p, d, h, nu, start)
        group = j.copy()
        xy_map = None
    if "class_weights" in p and "mix_weights" not in p:  # a labelled log: class = label
        law = laws.lifetimes if rich else "exponential"  # the class fit's (the chosen) law
        clock = None
        if laws is not None and laws.clock_offset is not None:
            clock = (float(laws.clock_offset), float(laws.period))
        cls, t_leave = _draw_classes(rng, p, law, d, scen, group, initial, t_arr, t_leave, clock)
        mark = np.full(total, -1, dtype=np.int64)
    elif "mix_weights" in p:
        w = p["mix_weights"][d]
        cw = np.cumsum(w, axis=1)
        u = rng.random(total)
        cls = np.zeros(total, dtype=np.int32)
        for k in range(w.shape[1] - 1):
            cls += u >= cw[scen, k]
        rates = p["mix_rates"][d]
        mark = rng.poisson(rates[scen, cls])
    else:
        cls = np.full(total, -1, dtype=np.int32)
        mark = np.full(total, -1, dtype=np.int64)
    if xy_map is not None:
        x, y = xy_map
    else:
        if free_mask is not None:
            cell = rng.integers(0, iy_free.size, size=total)
            u_loc = ix_free[cell] + rng.random(total)
            v_loc = iy_free[cell] + rng.random(total)
            q_u, q_v = u_loc * res, v_loc * res
        else:
            side = math.sqrt(nu)
            q_u, q_v = rng.random(total) * side, rng.random(total) * side
        c, sn = math.cos(oyaw), math.sin(oyaw)
        x = ox + c * q_u - sn * q_v
        y = oy + sn * q_u + c * q_v
    if laws is not None and laws.class_entry is not None and "class_weights" in p:
        check_origin_yaw(oyaw, "per-class entry densities", map_source)
        if free_mask is not None:  # the map the fit learned its classes' entries on
            # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
            from are_stats.traffic import uniform_position_density

            on_map = uniform_position_density(mask, res, (ox, oy))
            for density in laws.class_entry:
                _check_entries_on_map(density, on_map, map_source)
        x, y = _place_by_class(rng, laws.class_entry, cls, scen, group, initial, x, y)
    if headings == 4:
        yaw = np.mod(rng.integers(0, 4, size=total) * (np.pi / 2) + oyaw, 2 * np.pi)
    else:
        yaw = rng.random(total) * (2 * np.pi)
    df = pd.DataFrame(
        {
            "scenario": scen,
            "artefact": j.astype(np.int32),
            "class": cls.astype(np.int32),
            "mark": mark.astype(np.int64),
            "t_arrive": t_arr,
            "t_leave": t_leave,
            "x": x,
            "y": y,
            "yaw": yaw,
            "truncated": initial,
            "censored": t_leave > h,
            "group": group.astype(np.int32),
        }
    )
    df.attrs["draws"] = d.tolist()
    df.attrs["generation"] = {
        "seed": seed_record,
        "n_scenarios": n_sc,
        "horizon": h,
        "start": start,
        "draw": draw,
        "headings": headings,
        "area": nu,
        "map": None
        if free_mask is None
        else {
            "shape": list(mask.shape),
            "resolution": res,
            "origin": [ox, oy, oyaw],
            "free_cells": int(iy_free.size),
        },
        "n_draws": s,
        "parameters": _summary(p),
        "laws": None if laws is None else _laws_record(laws),
    }
    return df


def _laws_record(laws: TrafficLaws) -> dict[str, str | float | None]:
    """The laws of a generation, for the manifest."""
    return {
        "arrivals": laws.arrivals,
        "lifetimes": laws.lifetimes,
        "positions": laws.positions,
        "bin_width": laws.bin_width,
        "clock_offset": laws.clock_offset,
        "group_stay_sd": laws.group_stay_sd,
        "group_spread": laws.group_spread,
    }


def _paper_populations(
    rng: np.random.Generator,
    p: Mapping[str, np.ndarray],
    d: np.ndarray,
    h: float,
    nu: float,
    start: str,
) -> tuple:
    """The paper's model for all scenarios at once (vectorised: no loop per scenario)."""
    n_sc = d.size
    lam_nu = p["arrival_rate"][d] * nu
    mu = p["leave_rate"][d]
    n0 = rng.poisson(lam_nu / mu) if start == "stationary" else np.zeros(n_sc, np.int64)
    n_arr = rng.poisson(lam_nu * h)
    per = n0 + n_arr
    total = int(per.sum())
    scen = np.repeat(np.arange(n_sc, dtype=np.int32), per)
    first = np.cumsum(per) - per
    j = np.arange(total, dtype=np.int64) - np.repeat(first, per)
    initial = j < np.repeat(n0, per)
    t_arr = np.zeros(total)
    t_arr[~initial] = _sorted_uniforms(rng, n_arr) * h
    t_leave = t_arr + rng.standard_exponential(total) / mu[scen]
    return scen, j, t_arr, t_leave, initial, total


def _check_entries_on_map(
    entry: PositionDensity, free: PositionDensity, source: str | None = None
) -> None:
    """Refuse a learned entry density that mostly lies off the given map's free cells
    (``source``: the map's file, named in the error; ``map`` without one)."""
    h, w = entry.prob.shape
    yy, xx = np.mgrid[0:h, 0:w]
    centres = np.column_stack(
        [
            entry.origin[0] + (xx.ravel() + 0.5) * entry.resolution,
            entry.origin[1] + (yy.ravel() + 0.5) * entry.resolution,
        ]
    )
    row, col = free.cell_of(centres)
    on = row >= 0
    ok = np.zeros(row.size, bool)
    ok[on] = free.prob[row[on], col[on]] > 0
    mass = float(entry.prob.ravel()[ok].sum())
    if mass < 0.5:
        raise ValueError(
            f"{source or 'map'}: expected the map the fit learned its entry points on, got one "
            f"whose free cells hold {mass:.0%} of the entry density (use the fit's map, or uniform "
            "positions on this map with the fit's arrivals and stays: --positions uniform; or "
            "the paper's whole model: --model paper)"
        )


def _rich_populations(
    rng: np.random.Generator,
    params: Mapping[str, npt.ArrayLike],
    laws: TrafficLaws,
    d: np.ndarray,
    h: float,
    nu: float,
    start: str,
    grid: tuple | None,
    origin: tuple[float, float, float],
    map_source: str | None = None,
) -> tuple:
    """Each scenario by :func:`are_stats.traffic.sample_population` (positions in the map;
    ``map_source``: its file, named in errors)."""
    # lazy: are_stats.traffic brings NumPyro (+0.75 s CPU on `import are_stats.scenarios`)
    from are_stats.traffic import sample_population, uniform_position_density

    ox, oy, oyaw = origin
    rotated = abs(oyaw) > ORIGIN_YAW_TOLERANCE
    if laws.positions == "learned":
        check_origin_yaw(oyaw, "learned positions", map_source)
    if grid is not None:
        mask, res, _ = grid
        free = uniform_position_density(mask, res, (0.0, 0.0) if rotated else (ox, oy))
        if laws.positions == "learned":
            _check_entries_on_map(laws.entry, free, map_source)
    else:
        side = math.sqrt(nu)
        free = uniform_position_density(np.ones((1, 1), bool), side, (ox, oy))
    flat = {k: np.asarray(v) for k, v in params.items()}
    if "event_rate" not in flat:
        flat["event_rate"] = np.atleast_1d(flat["arrival_rate"])
    if "stay_mean" not in flat:
        flat["stay_mean"] = 1.0 / np.atleast_1d(flat["leave_rate"])
    cols: dict[str, list] = {k: [] for k in ("scen", "j", "ta", "tl", "tr", "g", "x", "y")}
    for i, di in enumerate(d.tolist()):
        one = {k: v[di] if v.ndim >= 1 and v.shape[0] > di else v for k, v in flat.items()}
        pop = sample_population(rng, one, laws, h, nu, start=start, free=free)
        n = pop["t_arrive"].size
        cols["scen"].append(np.full(n, i, np.int32))
        cols["j"].append(np.arange(n, dtype=np.int64))
        cols["ta"].append(pop["t_arrive"])
        cols["tl"].append(pop["t_leave"])
        cols["tr"].append(pop["truncated"])
        cols["g"].append(pop["group"])
        cols["x"].append(pop["x"])
        cols["y"].append(pop["y"])
    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}
    x, y = cat["x"], cat["y"]
    if rotated:
        c, sn = math.cos(oyaw), math.sin(oyaw)
        x, y = ox + c * cat["x"] - sn * cat["y"], oy + sn * cat["x"] + c * cat["y"]
    return (
        cat["scen"].astype(np.int32),
        cat["j"].astype(np.int64),
        cat["ta"].astype(float),
        cat["tl"].astype(float),
        cat["tr"].astype(bool),
        cat["g"].astype(np.int64),
        (x, y),
    )


#: Bytes per generated artefact while drawing a table (its 11 columns and the temporaries).
BYTES_PER_ARTEFACT = 256
#: Bytes per scenario (draw index, counts, offsets).
BYTES_PER_SCENARIO = 64


@dataclass(frozen=True)
class ScenarioSize:
    """How many scenarios of what length over what area: what the size of a scenario table
    follows from, with the draws' rates (:func:`expected_artefacts`,
    :func:`check_scenario_size`).

    Attributes
    ----------
    n_scenarios : int
        Number of scenarios.
    horizon : float
        Length of each scenario, in the time unit of the rates (s for a fit).
    area : float
        Free area ``nu`` in m^2.
    start : {"stationary", "empty"}
        Initial population (as :func:`generate_scenarios` takes it).
    """

    n_scenarios: int
    horizon: float
    area: float
    start: str = "stationary"


def expected_artefacts(params: Mapping[str, npt.ArrayLike], size: ScenarioSize) -> float:
    """Expected number of artefacts of :func:`generate_scenarios` (before drawing anything).

    Each scenario holds ``Poisson(lambda nu / mu)`` initial artefacts (stationary start) and
    ``Poisson(lambda nu horizon)`` arrivals; the expectation averages over the draws.

    Parameters
    ----------
    params : dict
        Posterior draws (``arrival_rate``, ``leave_rate``; see :func:`generate_scenarios`).
    size : ScenarioSize
        The scenarios' number, horizon, free area ``nu`` (m^2) and initial population.

    Returns
    -------
    float
        Expected total artefacts (may be ``inf`` for absurd inputs).
    """
    p = _draws(params)
    lam_nu = p["arrival_rate"] * float(size.area)
    per = lam_nu * float(size.horizon)
    if size.start == "stationary":
        per = per + lam_nu / p["leave_rate"]
    with np.errstate(over="ignore", invalid="ignore"):
        mean = float(np.mean(per)) if np.all(np.isfinite(per)) else math.inf
        return mean * float(size.n_scenarios)


def check_scenario_size(
    params: Mapping[str, npt.ArrayLike], size: ScenarioSize, source: str = "n_scenarios, horizon"
) -> None:
    """Refuse, before drawing, scenario tables past the memory or work limit.

    The expected number of artefacts follows from the draws' rates (as in
    :func:`expected_artefacts`); the check allows six Poisson standard deviations above it.

    Parameters
    ----------
    params : dict
        Posterior draws (validated here; see :func:`generate_scenarios`).
    size : ScenarioSize
        The scenarios asked for (``horizon`` in seconds).
    source : str
        What the sizes came from (files, options), named in the error.

    Raises
    ------
    ValueError
        On malformed draws.
    are_stats.inputs.LimitError
        When the table would pass the memory or work limit.
    """
    _check_size(_draws(params), size, source)


def _check_size(
    p: Mapping[str, np.ndarray], size: ScenarioSize, source: str = "n_scenarios, horizon"
) -> None:
    """:func:`check_scenario_size` on validated draws."""
    n_sc, h, nu = size.n_scenarios, size.horizon, size.area
    check_memory(float(n_sc) * BYTES_PER_SCENARIO, f"{n_sc} scenarios", source)
    expected = expected_artefacts(p, size)
    # the count is Poisson around its mean: allow 6 standard deviations
    high = expected + 6.0 * math.sqrt(expected) + 64.0 if math.isfinite(expected) else math.inf
    what = (
        f"about {expected:.3g} artefacts ({n_sc} scenarios of horizon {h:g} over {nu:g} m^2 at "
        "the fitted rates)"
    )
    check_memory(high * BYTES_PER_ARTEFACT, what, source)
    check_work(high * 20.0, what, source)


def _summary(p: Mapping[str, np.ndarray]) -> dict[str, dict[str, list[float]]]:
    out: dict[str, dict[str, list[float]]] = {}
    for name, a in p.items():
        a = np.asarray(a, dtype=float)
        out[name] = {
            "mean": [float(f"{v:.12g}") for v in np.ravel(a.mean(axis=0))],
            "sd": [float(f"{v:.12g}") for v in np.ravel(a.std(axis=0))],
        }
    return out


def scenario_counts(
    df: pd.DataFrame, times: npt.ArrayLike, n_scenarios: int | None = None
) -> np.ndarray:
    """N(t) of every scenario: artefacts with ``t_arrive <= t < t_leave``.

    Parameters
    ----------
    df : pandas.DataFrame
        A scenarios table (:func:`generate_scenarios`).
    times : (m,) float
        Query times.
    n_scenarios : int, optional
        Number of scenarios (default ``attrs["generation"]["n_scenarios"]`` or the largest
        scenario index + 1); scenarios without artefacts count 0.

    Returns
    -------
    (n_scenarios, m) int64
    """
    t = np.atleast_1d(np.asarray(times, dtype=float))
    if t.ndim != 1 or not np.isfinite(t).all():
        raise ValueError(f"times: expected a 1-d array of finite times, got {describe(times)}")
    for c in ("scenario", "t_arrive", "t_leave"):
        if c not in df.columns:
            raise ValueError(
                f"df: expected a scenarios table with column {c!r}, got columns {list(df.columns)}"
            )
    sc = df["scenario"].to_numpy(dtype=np.int64)
    if n_scenarios is None:
        gen = df.attrs.get("generation", {})
        n_scenarios = int(gen.get("n_scenarios", sc.max() + 1 if sc.size else 0))
    ta = df["t_arrive"].to_numpy(dtype=float)
    tl = df["t_leave"].to_numpy(dtype=float)
    out = np.empty((int(n_scenarios), t.size), dtype=np.int64)
    for k, tk in enumerate(t):
        alive = (ta <= tk) & (tl > tk)
        out[:, k] = np.bincount(sc[alive], minlength=int(n_scenarios))
    return out
