"""Shipped data: the small files the defaults need, inside the package (``are_stats/data``).

Everything ``are-stats demo``, ``are-stats show courtyard`` and the shipped experiment
configs read is installed with the package and found with :mod:`importlib.resources`, so
they work from any folder after ``pip install``. The files are made by seeded scripts kept
in the repository (``models/make_models.py``, ``models/make_example_log.py``), which write
into this folder; nothing else writes there, and the toolkit never writes into the install.

A shipped file is named by its kind and its name (the file's stem):

- ``map``: ``courtyard`` (``courtyard.yaml``, with its ``.pgm`` image and ``.ply`` mesh);
- ``catalogue``: ``catalogue`` (``artefacts/catalogue.yaml``, with the class meshes; the
  default of :func:`~are_stats.load_catalogue`);
- ``camera``: ``front_camera`` (``cameras/front_camera.yaml``);
- ``log``: ``courtyard_traffic`` (``logs/courtyard_traffic.csv``, with its manifest
  ``.yaml``: the example field log of ``are-stats demo``);
- ``experiment``: ``fig7``, ``fig7_fit`` (``experiments/<name>.yaml``).

:func:`resolve_shipped` is the rule every command follows: an existing file given by the
user wins; otherwise a bare name (no folder, no suffix) is looked up among the shipped
names of its kind; anything else is an error that lists those names.

Examples
--------
>>> from are_stats.environment import resolve_shipped, shipped_names, shipped_path
>>> shipped_names("map")
['courtyard']
>>> shipped_path("courtyard", "map").name
'courtyard.yaml'
>>> resolve_shipped("front_camera", "camera").parent.name
'cameras'
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

from are_stats.inputs import Described, InputError

__all__ = ["SHIPPED_DATA", "SHIPPED_KINDS", "resolve_shipped", "shipped_names", "shipped_path"]

#: Kind -> (folder inside the data folder, file suffix, what the file is, in words).
SHIPPED_KINDS: dict[str, tuple[str, str, str]] = {
    "map": ("", ".yaml", "ROS map YAML"),
    "catalogue": ("artefacts", ".yaml", "artefact catalogue YAML"),
    "camera": ("cameras", ".yaml", "camera YAML"),
    "log": ("logs", ".csv", "life-cycle log (CSV or Parquet)"),
    "experiment": ("experiments", ".yaml", "sweep config YAML"),
}


def _data_folder() -> Path:
    root = importlib.resources.files("are_stats") / "data"
    if not isinstance(root, Path):  # a zipped install: files have no path of their own
        raise RuntimeError(
            f"are_stats's shipped data is not on the file system ({root!r}); install "
            "are_stats as a folder (pip installs wheels that way)"
        )
    return root


#: The folder of the shipped data inside the installed package (read-only: never written).
SHIPPED_DATA: Path = _data_folder()


def _check_kind(kind: str) -> tuple[str, str, str]:
    if kind not in SHIPPED_KINDS:
        raise InputError("kind", "", "one of " + ", ".join(SHIPPED_KINDS), kind)
    return SHIPPED_KINDS[kind]


def shipped_names(kind: str) -> list[str]:
    """Names of the shipped files of one kind, sorted.

    Parameters
    ----------
    kind : str
        One of :data:`SHIPPED_KINDS`: ``map``, ``catalogue``, ``camera``, ``log``,
        ``experiment``.

    Returns
    -------
    list of str
        File stems, e.g. ``['courtyard']`` for maps (a map needs its image beside it).
    """
    folder, suffix, _ = _check_kind(kind)
    files = (SHIPPED_DATA / folder).glob(f"*{suffix}")
    if kind == "map":  # a map YAML names its image; other YAMLs here are not maps
        files = (p for p in files if p.with_suffix(".pgm").is_file())
    return sorted(p.stem for p in files if p.is_file())


def shipped_path(name: str, kind: str) -> Path:
    """The path of a shipped file, by name.

    Parameters
    ----------
    name : str
        A shipped name of ``kind`` (:func:`shipped_names`), e.g. ``"courtyard"``.
    kind : str
        ``map``, ``catalogue``, ``camera``, ``log`` or ``experiment``.

    Returns
    -------
    pathlib.Path
        The file inside the installed package (read it; never write it).

    Raises
    ------
    are_stats.inputs.InputError
        (a ``ValueError``) if ``name`` is not a shipped name of ``kind``; the message lists
        the shipped names.
    """
    folder, suffix, what = _check_kind(kind)
    names = shipped_names(kind)
    if name not in names:
        raise InputError(
            f"shipped {kind}", "", f"one of the shipped {kind} names ({', '.join(names)})", name
        )
    return SHIPPED_DATA / folder / f"{name}{suffix}"


def resolve_shipped(
    name_or_path: str | os.PathLike,
    kind: str,
    *,
    base: str | os.PathLike | None = None,
    source: str | os.PathLike | None = None,
    where: str = "",
) -> Path:
    """A user's file path, or else the shipped file of that name.

    The rule of every command and config: a path to an existing file wins (a relative path
    is taken from ``base``, default the working directory); otherwise a bare name (no
    folder, no suffix) must be a shipped name of ``kind`` and gives the shipped file. A
    path with a folder or a suffix that does not exist is returned as it is (absolute when
    ``base`` is given), so that the reader of the file reports it in its own words.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A file path (``maps/site.yaml``) or a shipped name (``courtyard``).
    kind : str
        ``map``, ``catalogue``, ``camera``, ``log`` or ``experiment``.
    base : str or os.PathLike, optional
        Folder relative paths are taken from (a config file's folder).
    source, where : optional
        Named in the error (the option ``--map`` or a config file, and its key).

    Returns
    -------
    pathlib.Path
        The user's file (absolute when ``base`` is given) or the shipped one.

    Raises
    ------
    are_stats.inputs.InputError
        (a ``ValueError``) naming ``source``/``where`` and the value, listing the shipped
        names of ``kind``, for a bare name that is neither a file nor a shipped name.

    Examples
    --------
    >>> resolve_shipped("courtyard", "map").name
    'courtyard.yaml'
    """
    _, _, what = _check_kind(kind)
    text = os.fspath(name_or_path)
    path = Path(text).expanduser()
    if base is not None and not path.is_absolute():
        path = (Path(base) / path).resolve()
    if path.is_file():
        return path
    bare = bool(text) and Path(text).name == text and not Path(text).suffix
    if not bare:
        return path
    names = shipped_names(kind)
    if text in names:
        return shipped_path(text, kind)

    raise InputError(
        source if source is not None else text,
        where,
        f"an existing {what} or the name of a shipped {kind} ({', '.join(names) or 'none'})",
        Described(f"{text!r}: no such file {path}, and no shipped {kind} of that name"),
    )
