"""Prediction for motion criticism (issue 16): ADE / FDE of the fitted behaviour against
constant velocity.

**Displacement errors** (:func:`displacement_errors`). Tracks resampled at ``rate`` (2.5 Hz)
are cut into windows of ``n_obs + n_pred`` (8 + 12) samples. From the ``n_obs`` observed
positions, a **constant-velocity** prediction (the mean velocity of the observed window)
and the fitted model's prediction are scored by the same code: ADE (mean distance over the
predicted steps) and FDE (distance at the last one). The model draws ``n_samples``
continuations: a goal and a route to it from the posterior given the window (the
goals' prior, the class's observed exit frequencies, times the soft policy's likelihood
of the window's observed moves, discretised as in the fit; the route the soft policy
walked from the last observed cell with the observed heading over the whole way to the
goal; times the likelihood of the window's continuous heading given the direction in
which that route's path leaves, by importance resampling of whole continuations), at a
preferred speed drawn from the person's posterior given the window (the class's fitted
between-person law as the prior, the window's least-squares speed as a conjugate
lognormal likelihood: :func:`_speed_posterior`), timed as in the generator: the
continuous (any-angle) path, then, with ``interaction``, walked again with the social
force among the people around (the person's own group aside; everybody gives way) and
turned by the class's fitted heading wander, as generation walks people. It is scored as
the mean of the samples and as the best of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from are_stats._checks import check_positive
from are_stats.behaviour import (
    BehaviourFit,
    continuous_paths,
    move_observations,
    path_free,
    positions_at,
    sample_soft_paths,
    track_log_likelihoods,
)
from are_stats.fitting._behaviour import discretise_tracks
from are_stats.fitting._motion_checks import _policies, _rng, _social, _walk, tracker_noise
from are_stats.logs import GROUP_DISTANCE
from are_stats.traffic import key_from_seed

if TYPE_CHECKING:
    import jax

    from are_stats.behaviour import SocialForce
    from are_stats.environment import OccupancyGrid

__all__ = ["constant_velocity", "displacement_errors"]


def _windows(
    tracks: pd.DataFrame, n_obs: int, n_pred: int, rate: float, stride: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows ``(B, n_obs + n_pred, 2)`` of tracks resampled at ``rate``, their track ids,
    labels and start times ``(B,)``."""
    n = n_obs + n_pred
    stride = n if stride is None else int(stride)
    out, tid, lab, t0 = [], [], [], []
    has_label = "label" in tracks.columns
    for i, g in tracks.sort_values(["id", "t"], kind="stable").groupby("id", sort=True):
        t = g["t"].to_numpy(float)
        ts = np.arange(t[0], t[-1] + 1e-9, 1.0 / rate)
        if ts.size < n:
            continue
        xy = np.column_stack([np.interp(ts, t, g["x"]), np.interp(ts, t, g["y"])])
        for s in range(0, ts.size - n + 1, stride):
            out.append(xy[s : s + n])
            tid.append(i)
            lab.append(str(g["label"].iloc[0]) if has_label else "")
            t0.append(ts[s])
    win = np.asarray(out, float).reshape(-1, n, 2)
    return win, np.asarray(tid), np.asarray(lab), np.asarray(t0, float)


def _errors(pred: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ADE and FDE of predictions ``(B, n_pred, 2)`` against ``(B, n_pred, 2)``."""
    d = np.hypot(*np.moveaxis(pred - truth, -1, 0))
    return d.mean(axis=1), d[:, -1]


def constant_velocity(observed: np.ndarray, n_pred: int) -> np.ndarray:
    """Constant-velocity continuation of observed windows.

    Parameters
    ----------
    observed : (B, n_obs, 2) float
        Positions at a fixed rate.
    n_pred : int

    Returns
    -------
    (B, n_pred, 2) float
        ``p_last + k v`` with ``v`` the mean step of the observed window, ``k = 1..n_pred``.
    """
    obs = np.asarray(observed, float)
    v = (obs[:, -1] - obs[:, 0]) / max(obs.shape[1] - 1, 1)
    k = np.arange(1, n_pred + 1)[None, :, None]
    return obs[:, -1:, :] + k * v[:, None, :]


def _solved(
    policies: dict | None, fit: BehaviourFit, c: int, goals: np.ndarray, tol: float = 1e-3
) -> np.ndarray:
    """:func:`~are_stats.fitting._motion_checks._policies` of class ``c`` to ``goals (G,
    2)``, the last solve of each class and tolerance kept in ``policies`` (a dict; None:
    solved afresh) and handed out again while the same goals come (issue 29: the
    displacement errors' chunks of windows solved the same exits' policies once each, 16
    solves where 2 give the same arrays: one program, the same inputs)."""
    goals = np.asarray(goals, np.int64).reshape(-1, 2)
    if policies is None:
        return _policies(fit, c, goals, tol)
    last = policies.get((c, tol))
    if last is not None and np.array_equal(last[0], goals):
        return last[1]
    pol = _policies(fit, c, goals, tol)
    policies[(c, tol)] = (goals.copy(), pol)
    return pol


def _goal_posterior(
    fit: BehaviourFit,
    c: int,
    observed: np.ndarray,
    rate: float,
    chunk: int,
    policies: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate exits ``(G, 2)`` of class ``c`` (the observed exit cells) and the log
    posterior ``(B, G)`` of each window's goal: the empirical exit frequencies times the soft
    policy's likelihood of the window's observed moves (discretised as in the fit); the
    policies kept in ``policies`` (:func:`_solved`)."""
    ends = fit.world_to_cell(fit.exit_xy[fit.track_class == c])
    if not len(ends):
        ends = fit.world_to_cell(fit.exit_xy)
    goals, counts = np.unique(ends, axis=0, return_counts=True)
    b, n_obs, _ = observed.shape
    logp = np.tile(np.log(counts / counts.sum()), (b, 1))
    df = pd.DataFrame(
        {
            "id": np.repeat(np.arange(b), n_obs),
            "t": np.tile(np.arange(n_obs) / rate, b),
            "x": observed[..., 0].ravel(),
            "y": observed[..., 1].ravel(),
        }
    )
    paths, ids = discretise_tracks(df, fit.free, fit.cell, fit.origin, float(fit.dt[c]))
    moved = np.array([len(p) >= 2 for p in paths])
    if not moved.any():
        return goals, logp
    rows_of = ids[moved].astype(np.int64)
    obs = move_observations([p for p, m in zip(paths, moved, strict=True) if m])
    n = len(rows_of)
    ok = path_free(~fit.free)
    slip = float(fit.slip[c])
    for g0 in range(0, len(goals), chunk):
        gsel = np.arange(g0, min(g0 + chunk, len(goals)))
        pol = _solved(policies, fit, c, goals[gsel])
        gi = np.repeat(np.arange(len(gsel)), n)
        tiled = (gi, *(np.tile(x, (len(gsel), 1)) for x in (obs.rows, obs.cols, obs.move)))
        # one compiled program per shape bucket (issue 29: op by op, each chunk's sizes
        # compiled some 40 programs)
        ll = track_log_likelihoods(pol, ok, slip, tiled)
        logp[rows_of[:, None], gsel[None, :]] += ll.reshape(len(gsel), n).T
    return goals, logp


#: Floor (rad) of the standard deviation of an observed heading about the direction of
#: the path the person walks (:func:`_observed_heading`): people do not walk exactly
#: straight at their path's next corner or exit (about a degree of sway and aim).
HEADING_SD_FLOOR = 0.02


def _observed_heading(observed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heading of each observed window and its standard deviation.

    A straight line at constant velocity is fitted to the window by least squares
    (``x(t), y(t)`` linear in the sample index); the heading is that of its velocity and
    its standard error the slopes' (from the residual scatter about the line) over the
    speed, combined with :data:`HEADING_SD_FLOOR`. A person who stands, wanders or turns
    within the window gets a wide one, a person who walks straight a narrow one.

    Parameters
    ----------
    observed : (B, n_obs, 2) float

    Returns
    -------
    heading : (B,) float
        Radians.
    sd : (B,) float
        Radians (``inf`` for a window that does not move).
    """
    obs = np.asarray(observed, float)
    n = obs.shape[1]
    k = np.arange(n) - 0.5 * (n - 1)
    sxx = float((k * k).sum())
    if n < 3 or sxx <= 0:
        d = obs[:, -1] - obs[:, 0]
        return np.arctan2(d[:, 1], d[:, 0]), np.full(len(obs), np.inf)
    slope = (k[None, :, None] * (obs - obs.mean(axis=1, keepdims=True))).sum(axis=1) / sxx
    resid = obs - obs.mean(axis=1, keepdims=True) - k[None, :, None] * slope[:, None, :]
    s2 = (resid**2).sum(axis=(1, 2)) / (2.0 * (n - 2))  # pooled over x and y
    speed = np.hypot(slope[:, 0], slope[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.where(speed > 0, np.sqrt(s2 / sxx) / speed, np.inf)
    return np.arctan2(slope[:, 1], slope[:, 0]), np.hypot(se, HEADING_SD_FLOOR)


#: Speed (m/s) below which a window counts as standing: its continuations keep this speed
#: (no preferred speed is inferred from a person who does not walk).
STILL_SPEED = 0.05


def _speed_posterior(
    observed: np.ndarray,
    rate: float,
    noise: float,
    mu: np.ndarray,
    sigma: np.ndarray,
    run_fraction: np.ndarray,
    run_mu: np.ndarray,
    run_sigma: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Posterior of each window's preferred speed given its observed steps.

    The prior is the class's fitted between-person law: ``log v ~ N(mu, sigma^2)`` for
    walkers, ``N(run_mu, run_sigma^2)`` for the ``run_fraction`` of runners. The window's
    speed is measured by the straight line fitted to it by least squares (as
    :func:`_observed_heading`): ``v_hat = rate |slope|``, unbiased under tracker noise
    (the summed step lengths are not: each step adds the noise of two samples), with the
    slope's standard error ``se = rate sqrt(s2 / sxx)`` from the residual scatter ``s2``
    (tracker noise and the person's own variation about a steady walk), at least the
    noise's alone (``s2 >= noise^2``); on the log scale ``se / v_hat``. The likelihood
    ``log v_hat ~ N(log v, se_log^2)`` is conjugate to each component: its posterior is
    normal with precision ``1/sigma^2 + 1/se_log^2`` and mean
    ``(mu/sigma^2 + log v_hat/se_log^2) / precision``, and the components are weighted by
    their prior weight times the marginal likelihood ``N(log v_hat; mu, sigma^2 +
    se_log^2)``. A component with ``sigma = 0`` is its own posterior (``mu``); a window
    slower than :data:`STILL_SPEED` stands (all weight on the first component, a point
    mass at :data:`STILL_SPEED`).

    Parameters
    ----------
    observed : (B, n_obs, 2) float
        Positions at ``rate``.
    rate : float
        Samples per second.
    noise : float
        Tracker noise sd (m) per coordinate (:func:`~are_stats.fitting.tracker_noise`).
    mu, sigma, run_fraction, run_mu, run_sigma : (B,) float
        The prior of each window (its class's fitted laws; ``run_fraction`` 0 or NaN: no
        runners).

    Returns
    -------
    weight, mean, sd : (B, 2) float
        Posterior weight, mean and sd of ``log v`` of the walking and running components.
    v_hat : (B,) float
        The window's measured speed (m/s).

    Examples
    --------
    A window at 1.0 m/s seen without noise does not move a prior centred at 1.5 m/s:

    >>> obs = np.stack([np.arange(8) * 0.4, np.zeros(8)], axis=1)[None]
    >>> w, m, sd, v = _speed_posterior(obs, 2.5, 0.0, np.array([np.log(1.5)]),
    ...                                np.array([0.2]), np.zeros(1), np.ones(1), np.ones(1))
    >>> round(float(np.exp(m[0, 0])), 6), round(float(v[0]), 6)
    (1.0, 1.0)
    """
    obs = np.asarray(observed, float)
    n = obs.shape[1]
    k = np.arange(n) - 0.5 * (n - 1)
    sxx = max(float((k * k).sum()), 1e-12)
    centred = obs - obs.mean(axis=1, keepdims=True)
    slope = (k[None, :, None] * centred).sum(axis=1) / sxx  # (B, 2) m per sample
    resid = centred - k[None, :, None] * slope[:, None, :]
    s2 = (resid**2).sum(axis=(1, 2)) / (2.0 * max(n - 2, 1))  # pooled over x and y
    v_hat = rate * np.hypot(slope[:, 0], slope[:, 1])
    se = rate * np.sqrt(np.maximum(s2, noise**2) / sxx)
    walking = v_hat >= STILL_SPEED
    y = np.log(np.maximum(v_hat, STILL_SPEED))
    se_log = np.maximum(se, 1e-12) / np.maximum(v_hat, STILL_SPEED)
    pi_run = np.nan_to_num(np.asarray(run_fraction, float))
    prior_w = np.column_stack([1.0 - pi_run, pi_run])
    prior_mu = np.column_stack([mu, np.where(pi_run > 0, run_mu, mu)]).astype(float)
    prior_sd = np.column_stack([sigma, np.where(pi_run > 0, run_sigma, sigma)]).astype(float)
    prior_sd = np.nan_to_num(prior_sd)
    lik2 = se_log[:, None] ** 2
    known = np.isfinite(prior_mu)
    prior_mu = np.where(known, prior_mu, y[:, None])  # no law fitted: the window alone
    v2 = prior_sd**2
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(v2 > 0, (prior_mu * lik2 + y[:, None] * v2) / (lik2 + v2), prior_mu)
        sd = np.where(v2 > 0, np.sqrt(v2 * lik2 / (v2 + lik2)), 0.0)
    mean = np.where(known, mean, y[:, None])
    sd = np.where(known, sd, se_log[:, None])
    tot = v2 + lik2
    logw = np.log(np.maximum(prior_w, 1e-300)) - 0.5 * (
        np.log(2 * np.pi * tot) + (y[:, None] - prior_mu) ** 2 / tot
    )
    logw = np.where(prior_w > 0, logw, -np.inf)
    weight = np.exp(logw - logw.max(axis=1, keepdims=True))
    weight /= weight.sum(axis=1, keepdims=True)
    still = ~walking
    weight[still] = [1.0, 0.0]
    mean[still] = math.log(STILL_SPEED)
    sd[still] = 0.0
    return weight, mean, sd, v_hat


def _draw_window_speeds(
    rng: np.random.Generator,
    fit: BehaviourFit,
    observed: np.ndarray,
    cls: np.ndarray,
    rate: float,
    noise: float,
    n_samples: int,
) -> np.ndarray:
    """``(B, K)`` preferred speeds (m/s) drawn from each window's posterior
    (:func:`_speed_posterior`, with its class's fitted laws as the prior)."""
    weight, mean, sd, _ = _speed_posterior(
        observed,
        rate,
        noise,
        fit.speed_mu[cls],
        fit.speed_sigma[cls],
        fit.run_fraction[cls],
        fit.run_mu[cls],
        fit.run_sigma[cls],
    )
    b = len(observed)
    comp = (rng.random((b, n_samples)) < weight[:, 1:2]).astype(np.int64)
    rows = np.arange(b)[:, None]
    z = rng.standard_normal((b, n_samples))
    return np.clip(np.exp(mean[rows, comp] + sd[rows, comp] * z), STILL_SPEED, 10.0)


def _model_predictions(
    rng: np.random.Generator,
    fit: BehaviourFit,
    observed: np.ndarray,
    labels: np.ndarray,
    n_pred: int,
    rate: float,
    n_samples: int,
    smooth: int,
    chunk: int = 16,
    oversample: int = 8,
    noise: float = 0.0,
    policies: dict | None = None,
) -> np.ndarray:
    """``(B, K, n_pred, 2)`` continuations sampled from the soft policy given the window
    (the soft policies kept in ``policies`` for the next call, :func:`_solved`).

    Each continuation, its goal and its route, is drawn from the posterior given the whole
    window by importance resampling: ``oversample * K`` candidates are drawn given the
    window's moves on the grid (a goal, an exit cell from :func:`_goal_posterior` with the
    person's point uniform within it; a route to it, the soft policy walked from the last
    observed cell, :func:`_rollouts`; a speed from the person's posterior given the
    window's steps, :func:`_speed_posterior`, tracker noise ``noise`` m), each is weighted
    by the likelihood of the window's continuous heading (normal with the sd of
    :func:`_observed_heading`) given the direction in which its own path leaves (uniform
    for a candidate that stands), and ``K`` are resampled by those weights. The weight is
    that of the route itself, not of the goal alone: where the policy goes either way
    round an obstacle, a person seen heading for one side goes on round that side (a
    route drawn afresh to the chosen goal would not know the heading). The continuations
    are thus conditioned on where the person was seen walking, not only on the cells it
    crossed."""
    b = observed.shape[0]
    names = {c: i for i, c in enumerate(fit.classes)}
    cls = np.array([names.get(str(v), 0) for v in labels], np.int64)
    k = int(n_samples)
    k_all = k * max(int(oversample), 1)
    speeds = _draw_window_speeds(rng, fit, observed, cls, rate, noise, k_all)
    cand = _draw_goals(rng, fit, observed, cls, rate, k_all, chunk, policies)  # (B, K', 2)
    ends = fit.cell_to_world(cand.reshape(-1, 2)).reshape(b, k_all, 2)
    ends += (rng.random((b, k_all, 2)) - 0.5) * fit.cell
    out, first, timed = _rollouts(
        rng, fit, observed, cls, cand, speeds, n_pred, rate, smooth, chunk, ends, policies
    )
    if k_all == k:
        return _paced(rng, fit, cls, out, timed, speeds, speeds, n_pred, rate)
    heading, sd = _observed_heading(observed)
    pick = np.empty((b, k), np.int64)
    for i in range(b):
        moving = np.isfinite(first[i])
        diff = np.angle(np.exp(1j * (np.where(moving, first[i], 0.0) - heading[i])))
        if np.isfinite(sd[i]):
            lw = np.where(
                moving,
                -0.5 * (diff / sd[i]) ** 2 - np.log(np.sqrt(2 * np.pi) * sd[i]),
                -np.log(2 * np.pi),
            )
        else:  # a still window: its heading tells nothing
            lw = np.zeros(k_all)
        w = np.exp(lw - lw.max())
        pick[i] = rng.choice(k_all, k, p=w / w.sum())
    out = out[np.arange(b)[:, None], pick]
    # the speed is independent of the goal and the route given the window, and the weights
    # do not depend on it: each resampled route is walked at a fresh draw of the speed's
    # posterior (a route drawn twice is not walked twice at one speed)
    fresh = _draw_window_speeds(rng, fit, observed, cls, rate, noise, k)
    ts = np.arange(1, n_pred + 1) / rate
    for i in range(b):
        for j, c in enumerate(pick[i]):
            if timed[i, c] is not None:
                tv, pv = timed[i, c]
                tv = tv * (speeds[i, c] / fresh[i, j])  # walked at constant speed
                out[i, j, :, 0] = np.interp(ts, tv, pv[:, 0])
                out[i, j, :, 1] = np.interp(ts, tv, pv[:, 1])
    timed_k = timed[np.arange(b)[:, None], pick]
    return _paced(
        rng, fit, cls, out, timed_k, speeds[np.arange(b)[:, None], pick], fresh, n_pred, rate
    )


def _paced(
    rng: np.random.Generator,
    fit: BehaviourFit,
    cls: np.ndarray,
    out: np.ndarray,
    timed: np.ndarray,
    timed_speed: np.ndarray,
    speed: np.ndarray,
    n_pred: int,
    rate: float,
) -> np.ndarray:
    """The continuations ``out (B, K, n_pred, 2)`` walked along their timed paths
    (``timed (B, K)``, vertex times at ``timed_speed (B, K)`` m/s) at a pace that varies
    as the fit's within-person variation says, from the window's drawn speed ``speed (B,
    K)``; ``out`` itself where the window's class has none (an older fit: not a draw
    more).

    The drawn speed ``c`` is the person's speed now, ``log c = log v + u0``: its preferred
    speed (between-person law ``N(mu, s^2)``) times its pace now (``u0``, the OU of sd
    ``sigma``, ``speed_within_sd``). Given ``log c``, ``u0`` is normal with mean
    ``sigma^2 / (s^2 + sigma^2) (log c - mu)`` and variance ``sigma^2 s^2 / (s^2 +
    sigma^2)``: a person seen faster than its class is partly a fast walker and partly
    in a fast spell, which passes (``u`` reverts to 0 with the correlation time ``T``,
    its exact AR(1) at the samples). The speed at each sample is ``c exp(u(t) - u0)``;
    the distance walked along the path by each sample, the trapezoid sum of those
    speeds, places the continuation on its path."""
    sd = np.nan_to_num(fit.speed_within_sd[cls])  # (B,)
    varies = sd > 0
    if not varies.any():
        return out
    b, k = speed.shape
    s2 = np.nan_to_num(fit.speed_sigma[cls]) ** 2
    mu = fit.speed_mu[cls]
    var = np.where(varies, sd**2, 0.0)
    gain = np.where(varies, var / np.maximum(s2 + var, 1e-300), 0.0)
    log_c = np.log(speed)
    u0 = gain[:, None] * (log_c - mu[:, None]) + np.sqrt(gain * s2)[:, None] * rng.standard_normal(
        (b, k)
    )
    tau = np.where(varies, fit.speed_within_time[cls], 1.0)
    phi = np.exp(-1.0 / (rate * tau))[:, None]
    eps = rng.standard_normal((n_pred, b, k))
    u = u0.copy()
    pace = np.empty((n_pred + 1, b, k))
    pace[0] = 1.0
    for j in range(n_pred):
        u = phi * u + (np.sqrt(var)[:, None] * np.sqrt(1.0 - phi**2)) * eps[j]
        pace[j + 1] = np.exp(u - u0)
    v = speed[None] * pace
    walked = np.cumsum(0.5 * (v[1:] + v[:-1]) / rate, axis=0)  # (n_pred, B, K)
    out = out.copy()
    for i in np.flatnonzero(varies):
        for j in range(k):
            if timed[i, j] is None:
                continue
            tv, pv = timed[i, j]
            along = tv * timed_speed[i, j]  # the path's length to each vertex
            out[i, j, :, 0] = np.interp(walked[:, i, j], along, pv[:, 0])
            out[i, j, :, 1] = np.interp(walked[:, i, j], along, pv[:, 1])
    return out


def _draw_goals(
    rng: np.random.Generator,
    fit: BehaviourFit,
    observed: np.ndarray,
    cls: np.ndarray,
    rate: float,
    n_samples: int,
    chunk: int,
    policies: dict | None = None,
) -> np.ndarray:
    """``(B, K, 2)`` goal cells per window from the posterior over the class's observed
    exits given the window's moves (:func:`_goal_posterior`, its policies kept in
    ``policies``)."""
    b = observed.shape[0]
    exits = np.zeros((b, n_samples, 2), np.int64)
    for c in np.unique(cls):
        w = np.flatnonzero(cls == c)
        goals, logp = _goal_posterior(fit, int(c), observed[w], rate, chunk, policies)
        u = rng.gumbel(size=(len(w), n_samples, len(goals)))
        exits[w] = goals[np.argmax(logp[:, None, :] + u, axis=2)]
    return exits


def _rollouts(
    rng: np.random.Generator,
    fit: BehaviourFit,
    observed: np.ndarray,
    cls: np.ndarray,
    goals_of: np.ndarray,
    speeds: np.ndarray,
    n_pred: int,
    rate: float,
    smooth: int,
    chunk: int = 16,
    ends: np.ndarray | None = None,
    policies: dict | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuations ``(B, K, n_pred, 2)`` to the goal cells ``goals_of (B, K, 2)``: the
    soft policy walked from the last observed cell with the observed heading, the
    continuous path at the speeds ``speeds (B, K)`` (m/s), ending at ``ends (B, K, 2)``
    (world; default the goal cell's centre) where the route reaches its goal; the
    direction ``(B, K)`` (rad) of each one's first segment (NaN for one that stands); and
    each one's timed path ``(B, K)`` object (vertex times and positions, None for one
    that stands). The soft policies are kept in ``policies`` (:func:`_solved`)."""
    b, n_obs, _ = observed.shape
    n_samples = goals_of.shape[1]
    last = observed[:, -1]
    cur = fit.world_to_cell(last)
    d = observed[:, -1] - observed[:, 0]
    head = np.mod(np.round(np.arctan2(d[:, 1], d[:, 0]) / (np.pi / 2)), 4).astype(np.int64)
    rep = np.repeat(np.arange(b), n_samples)
    exits = goals_of.reshape(-1, 2)
    out = np.repeat(last[:, None, None, :], n_samples, axis=1).repeat(n_pred, axis=2)
    first = np.full((b, n_samples), np.nan)
    timed = np.full((b, n_samples), None, dtype=object)
    ts = np.arange(1, n_pred + 1) / rate
    occ = ~fit.free
    moving = (exits[:, 0] >= 0) & ~(exits == cur[rep]).all(axis=1)
    for c in np.unique(cls):
        idx = np.flatnonzero(moving & (cls[rep] == c))
        if not idx.size:
            continue
        goals, ginv = np.unique(exits[idx], axis=0, return_inverse=True)
        ginv = ginv.ravel()
        for g0 in range(0, len(goals), chunk):
            gsel = np.arange(g0, min(g0 + chunk, len(goals)))
            sel = np.isin(ginv, gsel)
            members, local = idx[sel], ginv[sel] - g0
            pol = _solved(policies, fit, int(c), goals[gsel], tol=1e-2)
            w = rep[members]
            starts = np.column_stack([cur[w], head[w]])
            # the whole route to the goal, as generation walks it: the any-angle path of
            # a route cut at the horizon would aim at wherever the cut falls
            dist = fit.geodesic(goals[gsel])[local, cur[w, 0], cur[w, 1]]
            n_ep = np.where(np.isfinite(dist), np.ceil(1.25 * dist) + 10, 0).astype(np.int64)
            st, ac = sample_soft_paths(
                rng, pol, occ, float(fit.slip[c]), starts, local, goals[gsel], n_ep
            )
            # where each route ended: at its goal, or cut at its horizon
            done = ac < 0
            stop = np.where(done.any(axis=1), np.argmax(done, axis=1), ac.shape[1])
            arrived = (st[np.arange(len(members)), stop, :2] == exits[members]).all(axis=1)
            i_of, k_of = rep[members], members - rep[members] * n_samples
            end_of = [
                ends[i, k] if ends is not None and ok else None
                for i, k, ok in zip(i_of, k_of, arrived, strict=True)
            ]
            walked = continuous_paths(
                list(zip(st, ac, strict=True)), fit, speeds[i_of, k_of], last[i_of], end_of, smooth
            )
            for j, path in enumerate(walked):
                timed[i_of[j], k_of[j]] = path
            out[i_of, k_of] = positions_at(walked, ts)
            # each one's first segment: to its first vertex more than 1 nm from its start
            count = np.array([len(pv) for _, pv in walked], np.int64)
            owner = np.repeat(np.arange(len(walked)), count)
            pv = np.concatenate([pv for _, pv in walked])
            d = pv - pv[np.cumsum(count)[owner] - count[owner]]
            far = np.flatnonzero(np.hypot(*d.T) > 1e-9)
            j, at = np.unique(owner[far], return_index=True)
            first[i_of[j], k_of[j]] = np.arctan2(d[far[at], 1], d[far[at], 0])
    return out, first, timed


#: Relative speed (m/s) below which a neighbour seen close by throughout the observed
#: window walks *with* the person (one group, :func:`_walks_with`).
GROUP_RELATIVE_SPEED = 0.5


def _walks_with(
    observed: np.ndarray,
    v_obs: np.ndarray,
    p_then: np.ndarray,
    p_now: np.ndarray,
    vel: np.ndarray,
    seen_then: bool,
) -> bool:
    """Whether a neighbour belongs to the observed person's group, as the life-cycle
    conversion groups people (:func:`~are_stats.logs.tracks_to_lifecycle`): within
    ``GROUP_DISTANCE`` now, within twice that at the window's start (they moved
    together), and walking at the person's velocity (within
    :data:`GROUP_RELATIVE_SPEED`). Members of a group repel each other only on contact
    (:func:`~are_stats.behaviour.social_force_tracks`), which their formation avoids."""
    near_now = np.hypot(*(p_now - observed[-1])) <= GROUP_DISTANCE
    near_then = seen_then and np.hypot(*(p_then - observed[0])) <= 2.0 * GROUP_DISTANCE
    return bool(near_now and near_then and np.hypot(*(vel - v_obs)) <= GROUP_RELATIVE_SPEED)


def _interacting(
    samples: np.ndarray,
    observed: np.ndarray,
    ids: np.ndarray,
    t_last: np.ndarray,
    tracks: pd.DataFrame,
    rate: float,
    params: SocialForce,
    grid: OccupancyGrid | None,
    turn: tuple | None = None,
) -> np.ndarray:
    """Continuations ``(B, K, n_pred, 2)`` walked again with the social force, as generation
    walks people: each from its last observed position at its observed velocity along its
    sampled path (with ``turn``, ``(key, sd (B,), time (B,))``, turned by the fitted
    heading wander of its window's class as generation turns it), among the people present
    at that time who can come within the interaction's reach over the horizon (planned at
    constant velocity from what was observed of them: no future leaks), the members of its
    own group aside (:func:`_walks_with`). The neighbours walk under the social force too, as in
    generation, where everybody gives way: held to their plans (kinematic), they left
    the person to make the whole of each avoidance, twice the model's sidestep."""
    b, k, n_pred, _ = samples.shape
    n_obs = observed.shape[1]
    span = (n_obs - 1) / rate
    v_obs = (observed[:, -1] - observed[:, 0]) / max(span, 1e-9)
    steps = np.arange(n_pred + 1) / rate
    # everyone's track, by id (as groupby orders them): slices of one sorted table, not a
    # DataFrame per person (a chunk's call rebuilt 300 of them, most of its own time)
    tab = tracks.sort_values(["id", "t"], kind="stable")
    tab = tab[tab["id"].notna()]
    key = tab["id"].to_numpy()
    t_all = tab["t"].to_numpy(float)
    xy_all = tab[["x", "y"]].to_numpy(float)
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, int)
    last = np.r_[first[1:], len(key)]
    per = {key[a]: (t_all[a:z], xy_all[a:z]) for a, z in zip(first, last, strict=True)}
    frames = []
    for w in range(b):
        # the person: its K continuations, one scenario each
        path = np.concatenate([np.repeat(observed[w, -1][None, None], k, 0), samples[w]], 1)
        scen = w * k + np.arange(k)
        nb = []
        for j, (tj, xj) in per.items():
            if j == ids[w] or not (tj[0] <= t_last[w] <= tj[-1]):
                continue
            p_now = np.array(
                [np.interp(t_last[w], tj, xj[:, 0]), np.interp(t_last[w], tj, xj[:, 1])]
            )
            t_from = max(t_last[w] - span, tj[0])
            p_then = np.array([np.interp(t_from, tj, xj[:, 0]), np.interp(t_from, tj, xj[:, 1])])
            vel = (p_now - p_then) / (t_last[w] - t_from) if t_last[w] > t_from else np.zeros(2)
            if _walks_with(
                observed[w], v_obs[w], p_then, p_now, vel, t_last[w] - span >= tj[0] - 1e-6
            ):
                continue  # a member of the person's group: their formation keeps them apart
            # near enough to meet within the horizon
            closing = steps[-1] * (np.hypot(*v_obs[w]) + np.hypot(*vel))
            if np.hypot(*(p_now - observed[w, -1])) <= params.reach + closing:
                nb.append((p_now, vel))
        m = 1 + len(nb)
        xy = np.empty((k, m, n_pred + 1, 2))
        xy[:, 0] = path
        vel0 = np.empty((m, 2))
        vel0[0] = v_obs[w]
        for q, (p_now, vel) in enumerate(nb, start=1):
            xy[:, q] = p_now + steps[:, None] * vel
            vel0[q] = vel
        frames.append(
            pd.DataFrame(
                {
                    "scenario": np.repeat(scen, m * (n_pred + 1)),
                    "id": np.tile(np.repeat(np.arange(m), n_pred + 1), k),
                    "t": np.tile(steps, k * m),  # from the window's last observed time
                    "x": xy[..., 0].ravel(),
                    "y": xy[..., 1].ravel(),
                    "yaw": 0.0,
                    "vx": np.tile(np.repeat(vel0[:, 0], n_pred + 1), k),
                    "vy": np.tile(np.repeat(vel0[:, 1], n_pred + 1), k),
                }
            )
        )
    plan = pd.concat(frames, ignore_index=True)
    variation = None
    if turn is not None:
        key, h_sd, h_time = turn
        window = plan["scenario"].to_numpy() // k
        me = plan["id"].to_numpy() == 0
        none = np.zeros(len(plan))
        variation = (
            key,
            none,
            np.full(len(plan), np.nan),
            np.where(me, np.asarray(h_sd, float)[window], 0.0),
            np.where(me, np.asarray(h_time, float)[window], np.nan),
        )
    walked = _walk(plan, params, grid, variation=variation)
    me = walked[walked["id"] == 0].sort_values(["scenario", "t"], kind="stable")
    return me[["x", "y"]].to_numpy(float).reshape(b, k, n_pred + 1, 2)[:, :, 1:]


def _heading_wander(
    rng: np.random.Generator, fit: BehaviourFit, labels: np.ndarray
) -> tuple | None:
    """``(key, sd (B,), time (B,))`` of the fitted heading wander of each window's class
    (labels as :func:`_model_predictions` takes them), for :func:`_interacting`, its key
    drawn from ``rng``; None where no class has one (an older fit: not a draw more)."""
    names = {c: i for i, c in enumerate(fit.classes)}
    cls = np.array([names.get(str(v), 0) for v in labels], np.int64)
    sd = np.nan_to_num(np.asarray(fit.heading_within_sd, float)[cls])
    if not (sd > 0).any():
        return None
    key = key_from_seed(int(rng.integers(2**31)))
    return key, sd, np.asarray(fit.heading_within_time, float)[cls]


#: Windows predicted per progress step of :func:`displacement_errors` (a fit's 200 windows
#: in 8 steps).
PROGRESS_WINDOWS = 25


def _progress_of(progress: object) -> Callable[[int, int, str], object]:
    """``progress.steps`` where it has one (a stage clock), else ``progress`` itself, else a
    no-op: a callable ``(done, total, what)``."""
    steps = getattr(progress, "steps", None)
    if callable(steps):
        return steps
    return progress if callable(progress) else (lambda done, total, what: None)


def displacement_errors(
    key: int | jax.Array,
    behaviour_fit: BehaviourFit | None,
    tracks: pd.DataFrame,
    *,
    n_obs: int = 8,
    n_pred: int = 12,
    rate: float = 2.5,
    n_samples: int = 20,
    stride: int | None = None,
    smooth: int = 0,
    max_windows: int | None = 500,
    interaction: bool | SocialForce | None = None,
    grid: OccupancyGrid | None = None,
    progress: object = None,  # duck-typed: a stage clock (.steps) or a callable
) -> pd.DataFrame:
    """Average and final displacement errors of the fitted model and of constant velocity.

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the model's samples (and of the subset of windows).
    behaviour_fit : BehaviourFit or None
        The fitted behaviour (``None``: constant velocity only).
    tracks : pandas.DataFrame
        ``id, t, x, y`` [, ``label``], resampled at ``rate`` by linear interpolation.
    n_obs, n_pred : int
        Observed and predicted samples of each window.
    rate : float
        Samples per second.
    n_samples : int
        Continuations ``K`` sampled from the model per window.
    stride : int or None
        Samples between window starts (default: ``n_obs + n_pred``, disjoint windows).
    smooth : int
        ``0``: the continuous motion of generation (any-angle paths:
        :func:`~are_stats.behaviour.continuous_path`); ``> 1``: the old grid motion, the
        cells' path smoothed over this many vertices.
    max_windows : int or None
        At most this many windows (a random subset).
    interaction : bool or SocialForce, optional
        Walk the model's continuations again with the social force, as generation does
        (``True``: the published parameters; a :class:`~are_stats.behaviour.SocialForce`:
        those, e.g. the fit's), among the people present at the window's last observed
        time within its reach, who go on at their observed velocity; each continuation
        turned by the fitted heading wander of its window's class
        (``BehaviourFit.heading_within_sd``, ``heading_within_time``), as generation turns
        people. None: the sampled paths as they are.
    grid : OccupancyGrid, optional
        The map the interaction keeps off (None: open ground).
    progress : object, optional
        Told after each chunk of ``PROGRESS_WINDOWS`` (25) windows predicted:
        ``progress.steps(done, total, what)`` (a
        :class:`~are_stats._stage_clock.StageClock`), or ``progress(done, total, what)``
        for a plain callable; ``total`` chunks, the last call has ``done == total``.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``method``: ``constant velocity``, ``model mean of K`` (the mean of the
        ``K`` continuations), ``model best of K`` (the sample of least ADE; its FDE is that
        sample's); columns ``ADE``, ``FDE`` (m), ``ADE_se``, ``FDE_se`` (over windows),
        ``n_windows`` and ``K``.
    """
    rate = float(check_positive("rate", rate))
    win, tid, lab, t0 = _windows(tracks, int(n_obs), int(n_pred), rate, stride)
    rng = _rng(key)
    if max_windows is not None and len(win) > max_windows:
        pick = np.sort(rng.choice(len(win), int(max_windows), replace=False))
        win, tid, lab, t0 = win[pick], tid[pick], lab[pick], t0[pick]
    obs, truth = win[:, :n_obs], win[:, n_obs:]
    rows = {}

    def add(name: str, ade: np.ndarray, fde: np.ndarray, k: int) -> None:
        n = len(ade)
        sq = math.sqrt(n) if n > 1 else math.nan
        rows[name] = {
            "ADE": float(ade.mean()) if n else math.nan,
            "FDE": float(fde.mean()) if n else math.nan,
            "ADE_se": float(ade.std(ddof=1) / sq) if n > 1 else math.nan,
            "FDE_se": float(fde.std(ddof=1) / sq) if n > 1 else math.nan,
            "n_windows": n,
            "K": k,
        }

    add("constant velocity", *_errors(constant_velocity(obs, n_pred), truth), 1)
    if behaviour_fit is not None and len(win):
        params = _social(interaction)
        walked = params is not None
        # with the interaction, the paths go on past the horizon (as far again): a walker
        # whose plan ended there would slow down to stop at its end
        n_plan = 2 * int(n_pred) if walked else int(n_pred)
        noise = tracker_noise(tracks)
        t_last = t0 + (int(n_obs) - 1) / rate
        say = _progress_of(progress)
        parts = []
        policies: dict = {}  # the chunks' soft policies, solved once per goal set
        starts = range(0, len(obs), PROGRESS_WINDOWS)
        for j, a in enumerate(starts):
            sl = slice(a, a + PROGRESS_WINDOWS)
            part = _model_predictions(
                rng,
                behaviour_fit,
                obs[sl],
                lab[sl],
                n_plan,
                rate,
                int(n_samples),
                smooth,
                noise=noise,
                policies=policies,
            )
            if walked:
                part = _interacting(
                    part,
                    obs[sl],
                    tid[sl],
                    t_last[sl],
                    tracks,
                    rate,
                    params,
                    grid,
                    _heading_wander(rng, behaviour_fit, lab[sl]),
                )
            parts.append(part[:, :, : int(n_pred)])
            say(j + 1, len(starts), "displacement errors, windows")
        samples = np.concatenate(parts, axis=0)
        add("model mean of K", *_errors(samples.mean(axis=1), truth), int(n_samples))
        d = np.hypot(*np.moveaxis(samples - truth[:, None], -1, 0))  # (B, K, n_pred)
        best = np.argmin(d.mean(axis=2), axis=1)
        db = d[np.arange(len(d)), best]
        add("model best of K", db.mean(axis=1), db[:, -1], int(n_samples))
    out = pd.DataFrame.from_dict(rows, orient="index")
    out.index.name = "method"
    return out
