"""Behaviours of the ARE paper (Sec. 3.2) as reward structures of the MDP H_A(t).

The paper lists four behaviours an artefact can show: walking, running, following
another artefact and stopping (DECISIONS.md item 7). Here each behaviour is a set of
allowed actions plus a reward:

=========  ===============================  ============================================
behaviour  allowed actions                  reward r_t(s, a)
=========  ===============================  ============================================
walk       stay, forward, left, right       ``goal_reward`` on entering the goal cell
                                            (absorbing), ``-step_cost`` per non-stay action
run        all five (two-cell moves too)    as walk; running covers two cells per epoch
follow     all five                         ``follow[t][cell]`` on being at ``cell`` after
                                            the action of epoch ``t`` (another artefact's
                                            predicted cells), ``-step_cost`` per non-stay
                                            action
stop       stay only                        0
=========  ===============================  ============================================

A disallowed action has reward ``-inf`` (it is never chosen).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from are_stats._checks import check_array, check_nonnegative, describe

__all__ = [
    "ACTIONS",
    "BEHAVIOURS",
    "HEADINGS",
    "STAY",
    "FORWARD",
    "RUN",
    "LEFT",
    "RIGHT",
    "allowed_actions",
    "follow_rewards",
]

#: Action names in index order (the order also breaks ties: the lowest index wins).
ACTIONS: tuple[str, ...] = ("stay", "forward", "run", "left", "right")
STAY, FORWARD, RUN, LEFT, RIGHT = range(5)

#: Behaviour names (DECISIONS.md item 7).
BEHAVIOURS: tuple[str, ...] = ("walk", "run", "follow", "stop")

#: Heading index -> (d_row, d_col): 0 east (+col, +x), 1 north (+row, +y), 2 west, 3 south.
HEADINGS: tuple[tuple[int, int], ...] = ((0, 1), (1, 0), (0, -1), (-1, 0))

_ALLOWED = {
    "walk": (True, True, False, True, True),
    "run": (True, True, True, True, True),
    "follow": (True, True, True, True, True),
    "stop": (True, False, False, False, False),
}


def allowed_actions(behaviour: str) -> np.ndarray:
    """Boolean mask of the actions a behaviour may use.

    Parameters
    ----------
    behaviour : str
        One of ``"walk"``, ``"run"``, ``"follow"``, ``"stop"``.

    Returns
    -------
    mask : (5,) bool
        ``mask[a]`` is true when action ``a`` (see ``ACTIONS``) is allowed.

    Raises
    ------
    ValueError
        If ``behaviour`` is not a known behaviour.
    """
    if behaviour not in _ALLOWED:
        opts = ", ".join(repr(b) for b in BEHAVIOURS)
        raise ValueError(f"behaviour: expected one of {opts}, got {behaviour!r}")
    return np.array(_ALLOWED[behaviour], dtype=bool)


def follow_rewards(
    target_cells: npt.ArrayLike,
    shape: tuple[int, int],
    reward: float = 1.0,
    radius: int = 1,
) -> np.ndarray:
    """Time-varying reward r_t of the follow behaviour from a target's predicted cells.

    Being at Manhattan distance ``1 .. radius`` from the target's cell at epoch ``t + 1``,
    after the action taken at epoch ``t``, earns ``reward``; the target's own cell earns
    nothing (it is occupied by the target).

    Parameters
    ----------
    target_cells : (d + 1, 2) int
        The target's predicted ``(row, col)`` at epochs ``0 .. d``.
    shape : tuple of int
        Grid shape ``(H, W)``.
    reward : float
        Reward per epoch spent near the target (>= 0).
    radius : int
        Largest Manhattan distance that counts as following (>= 1).

    Returns
    -------
    r : (d, H, W) float64
        ``r[t, row, col]``, the reward for arriving at ``(row, col)`` at epoch ``t + 1``.

    Raises
    ------
    ValueError
        If ``target_cells`` is not a ``(d + 1, 2)`` integer array with ``d >= 1``, or
        ``reward`` / ``radius`` are out of range.

    Examples
    --------
    >>> r = follow_rewards([[0, 0], [0, 1], [0, 2]], (3, 4))
    >>> r.shape
    (2, 3, 4)
    """
    cells = check_array("target_cells", target_cells, dtype=float, ndim=2)
    if cells.shape[1] != 2 or cells.shape[0] < 2 or not np.all(cells == np.round(cells)):
        raise ValueError(
            f"target_cells: expected a (d + 1, 2) integer array with d >= 1, got {describe(cells)}"
        )
    reward = float(check_nonnegative("reward", reward))
    if int(radius) != radius or radius < 1:
        raise ValueError(f"radius: expected an integer >= 1, got {radius!r}")
    h, w = shape
    rows = np.arange(h)[None, :, None]
    cols = np.arange(w)[None, None, :]
    tr = cells[1:, 0].astype(np.int64)[:, None, None]
    tc = cells[1:, 1].astype(np.int64)[:, None, None]
    dist = np.abs(rows - tr) + np.abs(cols - tc)
    return np.where((dist >= 1) & (dist <= radius), reward, 0.0)
