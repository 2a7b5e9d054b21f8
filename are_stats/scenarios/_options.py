"""The settings of the one assembly: :class:`AssemblyOptions`, one frozen record.

A command reads its options once (``generate``'s command line, an experiment's
``mission``, ``augment``'s command line), builds one :class:`AssemblyOptions` and passes it
whole to :func:`~are_stats.scenarios.scenes_from_fit` (or
:func:`~are_stats.scenarios.move_scenes`) and to the folder's manifest
(:func:`~are_stats.scenarios.generate_manifest`), so the scenes drawn and the manifest that
describes them cannot disagree. The assembly's
functions also take the record's fields as keywords (:class:`AssemblySettings`): they
replace the fields of ``options`` (:meth:`AssemblyOptions.with_settings`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, TypedDict

from are_stats.inputs import get_float, get_str

if TYPE_CHECKING:
    from are_stats.behaviour import SocialForce

__all__ = ["MODEL_CHOICES", "POSITION_CHOICES", "AssemblyOptions", "AssemblySettings"]

#: Values of ``model=`` (``generate --model``, ``augment --model``): the fit's chosen
#: traffic models, or the paper's.
MODEL_CHOICES = ("chosen", "paper")
#: Values of ``positions=`` (``generate --positions``, ``augment --positions``).
POSITION_CHOICES = ("chosen", "uniform")


@dataclass(frozen=True)
class AssemblyOptions:
    """How the assembly draws and moves scenes: the behaviour rule and its settings.

    Each function of the assembly reads the fields it needs: the draws' ``model`` and
    ``positions`` only apply where the scenes come from a fit
    (:func:`~are_stats.scenarios.scenes_from_fit`), ``start`` where scenarios are drawn.

    Attributes
    ----------
    behaviours : bool or str
        The behaviour rule (:func:`~are_stats.scenarios.behaviour_source`): ``False`` /
        ``"none"`` (standing), ``True`` / ``"auto"`` (the fit's behaviour when it has one,
        else the catalogue's), ``"fitted"``, ``"catalogue"``.
    model : {"chosen", "paper"}
        Draw from the models the fit chose, or the paper's
        (:meth:`~are_stats.fitting.Fit.traffic`).
    positions : {"chosen", "uniform"}
        Where artefacts enter: as ``model`` says, or uniformly over the map's free cells.
    start : {"stationary", "empty"}
        Initial population.
    behaviour_cell : float
        The catalogue behaviours' coarse grid cell (m).
    behaviour_dt : float
        Seconds per decision epoch of the catalogue behaviours.
    cell_source : str
        The option or key ``behaviour_cell`` came from, named in errors (e.g.
        ``"--behaviour-cell"``, ``"mission.behaviour_cell"``).
    interaction : bool or SocialForce
        Walk the tracks again with the social force: ``True`` with the fit's parameters
        when it has them, else the published ones; a
        :class:`~are_stats.behaviour.SocialForce` with those; ``False`` keeps the planned
        tracks.

    Examples
    --------
    >>> options = AssemblyOptions(behaviours=True, behaviour_cell=0.5)
    >>> options.with_settings({"behaviour_dt": 1.0}).behaviour_dt
    1.0
    """

    behaviours: bool | str = False
    model: str = "chosen"
    positions: str = "chosen"
    start: str = "stationary"
    behaviour_cell: float = 1.0
    behaviour_dt: float = 2.0
    cell_source: str = "behaviour_cell"
    interaction: bool | SocialForce = True

    @classmethod
    def from_command(
        cls,
        behaviours: bool | str,
        model: str,
        positions: str,
        behaviour_cell: float,
        behaviour_dt: float,
    ) -> AssemblyOptions:
        """The options of the ``generate`` and ``augment`` commands, checked and named as
        on their command lines.

        ``model`` must be one of :data:`MODEL_CHOICES` (``--model``), ``positions`` one of
        :data:`~are_stats.scenarios.POSITION_CHOICES` (``--positions``); with
        ``behaviours``, ``behaviour_cell`` (``--behaviour-cell``, m) and ``behaviour_dt``
        (``--behaviour-dt``, s) finite and > 0. Errors of the behaviours name
        ``--behaviour-cell`` (``cell_source``).

        Raises
        ------
        are_stats.inputs.InputError
            Naming the first option that is out of range.

        Examples
        --------
        >>> AssemblyOptions.from_command(True, "paper", "chosen", 0.5, 1).behaviour_dt
        1.0
        """
        model = get_str(model, "--model", "", choices=MODEL_CHOICES)
        positions = get_str(positions, "--positions", "", choices=POSITION_CHOICES)
        cell_source = "--behaviour-cell"  # the option its check and the behaviours' errors name
        if behaviours:
            behaviour_cell = get_float(behaviour_cell, cell_source, "", lo=0.0, lo_open=True)
            behaviour_dt = get_float(behaviour_dt, "--behaviour-dt", "", lo=0.0, lo_open=True)
        return cls(
            behaviours=behaviours,
            model=model,
            positions=positions,
            behaviour_cell=behaviour_cell,
            behaviour_dt=behaviour_dt,
            cell_source=cell_source,
        )

    def with_settings(self, settings: Mapping[str, object]) -> AssemblyOptions:
        """These options with the fields named in ``settings`` replaced (the keywords of
        the assembly's functions, :class:`AssemblySettings`); ``self`` when there are none.

        Raises
        ------
        TypeError
            For a key that is not a field of :class:`AssemblyOptions`.
        """
        if not settings:
            return self
        unknown = sorted(set(settings) - {f.name for f in fields(self)})
        if unknown:
            raise TypeError(f"unexpected keyword argument {unknown[0]!r} of the assembly")
        return replace(self, **settings)


class AssemblySettings(TypedDict, total=False):
    """The fields of :class:`AssemblyOptions` as keywords (the ``**settings`` of the
    assembly's functions; see the record for their meaning)."""

    behaviours: bool | str
    model: str
    positions: str
    start: str
    behaviour_cell: float
    behaviour_dt: float
    cell_source: str
    interaction: bool | SocialForce
