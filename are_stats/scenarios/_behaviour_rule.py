"""The behaviour rule (issue 25): which behaviour moves a scene's artefacts, one rule for
every command.

* ``False`` / ``"none"``: artefacts stand at their arrival pose for their whole stay;
* ``True`` / ``"auto"``: the fit's behaviour when the fit has one, otherwise the
  catalogue's (the finite-horizon MDP of the paper on the map's coarsened cells). A fit's
  behaviour moves every class: the classes that walked in the log's tracks by their fitted
  behaviour, those that only stood there (``BehaviourFit.standing``) standing; a fit from
  tracks has none only when nobody in them walked;
* ``"fitted"`` or ``"catalogue"``: that one (``"fitted"`` without a fitted behaviour is an
  error, and the catalogue's needs a map).

The assembly (:func:`~are_stats.scenarios.scenes_from_fit`, :mod:`._assembly`) moves the
scenes by it and the scenarios folder (:func:`~are_stats.scenarios.tracks_record`) records
what it chose; a module of its own, as both import it (the folder sits below the assembly).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from are_stats.environment import OccupancyGrid

if TYPE_CHECKING:
    from are_stats.behaviour import BehaviourFit

__all__ = ["BEHAVIOUR_SOURCES", "behaviour_source"]

#: Values of ``behaviours=`` (besides ``True`` = ``"auto"`` and ``False`` = ``"none"``).
BEHAVIOUR_SOURCES = ("none", "auto", "fitted", "catalogue")


def behaviour_source(
    behaviours: bool | str,
    fitted: BehaviourFit | None,
    grid: OccupancyGrid | None,
    source: str = "behaviours",
    *,
    map_source: str | None = None,
) -> str:
    """The behaviour that moves the artefacts, by the module's one rule.

    Parameters
    ----------
    behaviours : bool or str
        ``False``/``"none"``, ``True``/``"auto"``, ``"fitted"`` or ``"catalogue"`` (the
        module docstring).
    fitted : BehaviourFit or None
        The fit's behaviour (``"auto"`` uses it when there is one).
    grid : OccupancyGrid or None
        The map: the catalogue's behaviours move on its cells, so they need one.
    source : str
        What the errors name (the behaviours' option or the fit).
    map_source : str, optional
        The option that gives ``grid`` (e.g. ``"--map"``): a missing map is then
        ``"{source}: expected {map_source} (trajectories need the grid)"``.

    Returns
    -------
    str
        ``"none"``, ``"fitted"`` or ``"catalogue"``.

    Raises
    ------
    ValueError
        For a ``behaviours`` the rule does not know, ``"fitted"`` without a fitted
        behaviour, or catalogue behaviours without a map.

    Examples
    --------
    >>> behaviour_source(True, None, OccupancyGrid(np.zeros((4, 4)), 1.0))
    'catalogue'
    >>> behaviour_source(True, None, None, "--behaviours", map_source="--map")
    Traceback (most recent call last):
    ...
    ValueError: --behaviours: expected --map (trajectories need the grid)
    """
    if isinstance(behaviours, bool | np.bool_):
        behaviours = "auto" if behaviours else "none"
    if behaviours not in BEHAVIOUR_SOURCES:
        raise ValueError(
            f"{source}: behaviours: expected one of {list(BEHAVIOUR_SOURCES)} or a bool, "
            f"got {behaviours!r}"
        )
    if behaviours == "auto":
        behaviours = "fitted" if fitted is not None else "catalogue"
    if behaviours == "fitted" and fitted is None:
        raise ValueError(
            f"{source}: behaviours 'fitted': the fit has no behaviour group (fit a tracks "
            "table to learn one), use 'catalogue'"
        )
    if behaviours == "catalogue" and grid is None:
        if map_source is not None:
            raise ValueError(f"{source}: expected {map_source} (trajectories need the grid)")
        raise ValueError(f"{source}: catalogue behaviours need a map (the MDP moves on its cells)")
    return behaviours
