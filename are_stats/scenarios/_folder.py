"""The scenarios folder: one writer (:func:`write_scenes`) and one validating reader
(:func:`read_scenes`), the only code that touches such a folder.

A scenarios folder holds

* ``manifest.yaml``: a mapping with ``format_version`` (an integer, :data:`FORMAT_VERSION`
  for folders written now; a folder without one is version 1, written before the key
  existed, and reads the same way), the columns, the generation settings and the keys the
  writer adds (``fit``, ``map``, ``seed``, ``class_labels``, ``tracks``, ...);
* ``artefacts.parquet``: one row per artefact (:data:`SCENARIO_COLUMNS`); zero rows is a
  valid folder (no artefact arrived);
* optionally the behaviour tracks the manifest names (``tracks: {file: tracks.parquet}``):
  columns ``scenario, id, t, x, y, yaw``, one pose per artefact and time.

Every value is checked on reading; an error names the file, the row (1-based data rows) or
the manifest key, the column and what was expected.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NotRequired, TypedDict, Unpack

import numpy as np
import pandas as pd
import pyarrow as pa
import yaml

from are_stats import __version__
from are_stats._atomic import atomic_folder
from are_stats.environment import ArtefactCatalogue, OccupancyGrid, coarse_cell
from are_stats.inputs import Described, InputError, get_float, get_int, get_list, get_str, load_yaml
from are_stats.logs import RawTable, read_raw_table
from are_stats.scenarios._behaviour_rule import behaviour_source
from are_stats.scenarios._options import AssemblyOptions, AssemblySettings

if TYPE_CHECKING:
    from are_stats.behaviour import BehaviourFit
    from are_stats.fitting import Fit

__all__ = [
    "FORMAT_VERSION",
    "MAX_POSITION",
    "SCENARIO_COLUMNS",
    "ScenesFolder",
    "check_positions",
    "generate_manifest",
    "read_scenes",
    "tracks_record",
    "write_scenes",
]

#: Version of the folder layout written by :func:`write_scenes` (``format_version`` in the
#: manifest). Version 1: folders written before the key (read the same way).
FORMAT_VERSION = 2
#: Largest ``|x|``, ``|y|`` of an artefact or a track pose accepted (metres).
MAX_POSITION = 1e7

#: Columns of a scenarios table and their meaning (also written into the manifest).
SCENARIO_COLUMNS: dict[str, str] = {
    "scenario": "int32, scenario index 0..n_scenarios-1",
    "artefact": "int32, artefact index within its scenario, in order of arrival",
    "class": "int32, mixture component that drew the mark, or the class of a log that names "
    "its classes (an index into the manifest's class_labels; -1 without either)",
    "mark": "int64, mark X of eq. (1) (-1 without a mixture)",
    "t_arrive": "float64, arrival time in [0, horizon] (0 for the initial population)",
    "t_leave": "float64, leaving time (may exceed the horizon: see censored)",
    "x": "float64, arrival position x in the map frame (m)",
    "y": "float64, arrival position y in the map frame (m)",
    "yaw": "float64, arrival heading in [0, 2 pi) (rad)",
    "truncated": "bool, present at time 0 (initial population)",
    "censored": "bool, t_leave > horizon (still present at the end)",
    "group": "int32, group within the scenario (members arrived together; a lone artefact "
    "has a group of its own)",
}
#: Columns every scenarios table must have; the others have defaults (``artefact``: the
#: position within the scenario, ``mark``: -1, ``group``: the artefact, ``truncated``:
#: ``t_arrive <= 0``, ``censored``: false).
REQUIRED_COLUMNS = ("scenario", "class", "t_arrive", "t_leave", "x", "y", "yaw")
TRACK_COLUMNS = ("scenario", "id", "t", "x", "y", "yaw")
_FLOATS = ("t_arrive", "t_leave", "x", "y", "yaw")
_INT32 = np.iinfo(np.int32).max
_ARTEFACTS, _MANIFEST, _TRACKS = "artefacts.parquet", "manifest.yaml", "tracks.parquet"


class TracksRecord(TypedDict):
    """A manifest's ``tracks`` section (:func:`tracks_record`): which behaviour made the
    tracks, on what, and their file."""

    #: ``fitted behaviour`` or ``catalogue behaviour``.
    source: str
    #: Poses in the tracks file.
    rows: int
    #: A catalogue behaviour's MDP cell side (m) and seconds per decision epoch.
    cell_m: NotRequired[float]
    dt_s: NotRequired[float]
    #: The tracks file's name in the folder (:func:`write_scenes` adds it).
    file: NotRequired[str]


class ScenesManifest(TypedDict, total=False):
    """A scenarios folder's ``manifest.yaml`` (module docstring): the keys
    :func:`write_scenes` and :func:`generate_manifest` write. :func:`read_scenes` checks
    ``format_version``, ``generation`` (and its ``horizon``), ``n_scenarios``, ``map``,
    ``class_labels`` and ``tracks`` (a mapping naming a file of the folder); the other
    values are as the file has them, and a folder made by hand may have more keys."""

    #: ``are_stats scenarios <FORMAT_VERSION>``, :data:`FORMAT_VERSION`, the are_stats
    #: version that wrote the folder.
    format: str
    format_version: int
    version: str
    n_scenarios: int
    n_artefacts: int
    #: ``{"artefacts": "artefacts.parquet"}``; the columns and their meaning
    #: (:data:`SCENARIO_COLUMNS`).
    files: dict[str, str]
    columns: dict[str, str]
    #: The scenes table's ``attrs["generation"]`` (seed, horizon, parameters, ...).
    generation: dict[str, object]
    #: The fit file, its traffic model, the map file (or None), the scenes' seed, the
    #: classes' labels (or None).
    fit: str
    model: str
    map: str | None
    seed: int
    class_labels: list[str] | None
    tracks: TracksRecord


@dataclass(frozen=True, eq=False)
class ScenesFolder:
    """What :func:`read_scenes` returns: the folder's tables and manifest, and what the
    manifest says about the scenes (their map, horizon, classes) for every reader.

    It unpacks as ``artefacts, manifest, tracks`` (``df, manifest, tracks =
    read_scenes(d)``).

    Examples
    --------
    >>> folder = read_scenes("scen/")  # doctest: +SKIP
    >>> grid, horizon = folder.grid(), folder.horizon  # doctest: +SKIP
    """

    #: One row per artefact: the columns of :data:`SCENARIO_COLUMNS` (their dtypes) in
    #: that order, then any other column of the file as it was.
    artefacts: pd.DataFrame
    #: The manifest (a mapping, checked).
    manifest: ScenesManifest
    #: Behaviour tracks: ``scenario, id`` (int64), ``t, x, y, yaw`` (float64); None when
    #: the manifest names none.
    tracks: pd.DataFrame | None
    #: The folder it was read from (named in errors); None for one made in memory.
    folder: Path | None = None

    def __iter__(self) -> Iterator[pd.DataFrame | ScenesManifest | None]:
        """``artefacts, manifest, tracks``: the folder unpacks as the tuple it once was."""
        return iter((self.artefacts, self.manifest, self.tracks))

    @property
    def manifest_path(self) -> Path:
        """``<folder>/manifest.yaml``: what errors about the manifest's keys name."""
        return Path(_MANIFEST) if self.folder is None else self.folder / _MANIFEST

    @property
    def map_file(self) -> str | None:
        """The ROS map YAML the manifest names (``map``; relative to the current folder),
        or None."""
        name = self.manifest.get("map")
        return str(name) if name else None

    @property
    def horizon(self) -> float | None:
        """The scenarios' length ``generation.horizon`` (s, checked >= 0 on reading), or None
        for a folder that does not record it (made by hand)."""
        generation = self.manifest.get("generation")
        horizon = generation.get("horizon") if isinstance(generation, Mapping) else None
        return None if horizon is None else float(horizon)

    @property
    def class_labels(self) -> list[str] | None:
        """The label of each mixture component (``class`` indexes it): the manifest's
        ``class_labels`` (strings, checked on reading), or None."""
        labels = self.manifest.get("class_labels")
        return None if labels is None else [str(x) for x in labels]

    @property
    def scenario_numbers(self) -> list[int]:
        """The folder's scenarios: ``0 .. n_scenarios - 1`` as the manifest says (some may
        hold no artefact), else those of the artefacts table, in order."""
        n_sc = self.manifest.get("n_scenarios")
        if n_sc is not None:
            return list(range(int(n_sc)))
        return sorted(set(self.artefacts["scenario"].astype(np.int64).tolist()))

    @property
    def n_moving(self) -> int:
        """Artefacts with behaviour tracks (distinct ``scenario, id`` of the tracks)."""
        if self.tracks is None:
            return 0
        return len(self.tracks[["scenario", "id"]].drop_duplicates())

    def grid(self, *, missing_ok: bool = False, or_else: str = "") -> OccupancyGrid | None:
        """The map the manifest names, read (:meth:`OccupancyGrid.from_ros_yaml`); None when
        it names none.

        Parameters
        ----------
        missing_ok : bool
            Return None, instead of refusing, when the named map is not there (a reader
            with another source of the environment: ``perceive --mesh``).
        or_else : str
            The way out a refusal suggests (``"pass --mesh MESH"``).

        Raises
        ------
        are_stats.inputs.InputError
            Naming ``manifest.yaml`` and its key ``map`` when the file is not there (and not
            ``missing_ok``), or what is wrong with the map itself.
        """
        name = self.map_file
        if name is None:
            return None
        if not Path(name).exists():
            if missing_ok:
                return None
            expected = "an existing ROS map YAML (a relative path is read from the current folder)"
            raise InputError(
                self.manifest_path,
                "map",
                f"{expected}, or {or_else}" if or_else else expected,
                Described(f"{name}: no such file"),
            )
        return OccupancyGrid.from_ros_yaml(name)

    def unknown_classes(self, catalogue: ArtefactCatalogue) -> list[str]:
        """The class labels of the artefacts (``class`` indexing the manifest's
        ``class_labels``) that ``catalogue`` lacks, sorted; a :class:`Scene` sizes such an
        artefact as the catalogue's class in its position (a reader warns).

        Parameters
        ----------
        catalogue : ArtefactCatalogue
            The property table ``Q``.

        Returns
        -------
        list of str
            Empty without ``class_labels`` or when every class present is known.
        """
        labels = self.class_labels
        if not labels:
            return []
        present = np.unique(self.artefacts["class"]).tolist()
        used = {labels[c] for c in present if 0 <= c < len(labels)}
        return sorted(used - set(catalogue.labels))


# ---- writing ---------------------------------------------------------------------------


def _plain(x: object) -> object:
    """YAML-safe plain Python values."""
    if isinstance(x, Mapping):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, Path):
        return str(x)
    return x


def _write_parquet(df: pd.DataFrame, path: Path) -> None:
    """Pinned Parquet options (zstd 3, no dictionary, no schema metadata): same table, same
    bytes."""
    import pyarrow.parquet as pq  # lazy: +0.02 s CPU on `import are_stats.scenarios`

    table = pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None)
    pq.write_table(
        table,
        path,
        compression="zstd",
        compression_level=3,
        use_dictionary=False,
        write_statistics=True,
        version="2.6",
        data_page_version="1.0",
        row_group_size=1 << 20,
        store_schema=False,
    )


def _check_table(df: pd.DataFrame, columns: Sequence[str], what: str) -> None:
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(
            f"{what}: expected a table with columns {list(columns)}, "
            f"got {list(df.columns)} (missing {missing})"
        )


def tracks_record(
    behaviours: bool | str,
    fitted: BehaviourFit | None,
    tracks: pd.DataFrame,
    grid: OccupancyGrid | None = None,
    *,
    behaviour_cell: float = 1.0,
    behaviour_dt: float = 2.0,
    cell_source: str = "behaviour_cell",
) -> TracksRecord | None:
    """The manifest's ``tracks`` section for scenes moved by the assembly's behaviour rule
    (:func:`~are_stats.scenarios.scenes_from_fit`'s ``behaviours=``): which behaviour made
    the tracks and on what; None when nothing moves (no tracks file is written then).

    Parameters
    ----------
    behaviours : bool or str
        As given to the assembly (``True``: the fit's behaviour when it has one, else the
        catalogue's).
    fitted : BehaviourFit or None
        The fit's behaviour (:attr:`~are_stats.fitting.Fit.behaviour`).
    tracks : pandas.DataFrame
        The tracks written, ``(n_poses,)`` rows.
    grid : OccupancyGrid, optional
        The map (the catalogue's behaviours move on its coarsened cells).
    behaviour_cell, behaviour_dt : float
        The catalogue behaviours' target cell (m) and seconds per decision epoch.
    cell_source : str
        The option ``behaviour_cell`` came from, named in errors.

    Returns
    -------
    dict or None
        ``{"source": "fitted behaviour", "rows": n}``, or ``{"source": "catalogue
        behaviour", "cell_m": side of the MDP's cells (m), "dt_s": behaviour_dt, "rows":
        n}``; :func:`write_scenes` adds ``file``.

    Raises
    ------
    ValueError
        For catalogue behaviours without a map, or a ``behaviours`` the rule does not know.

    Examples
    --------
    >>> tracks_record(True, None, pd.DataFrame({"t": [0.0, 2.0]}),
    ...               OccupancyGrid(np.zeros((40, 40)), 0.1), behaviour_cell=0.5)
    {'source': 'catalogue behaviour', 'cell_m': 0.5, 'dt_s': 2.0, 'rows': 2}
    """
    kind = behaviour_source(behaviours, fitted, grid)
    if kind == "none":
        return None
    if kind == "fitted":
        return {"source": "fitted behaviour", "rows": len(tracks)}
    cell = coarse_cell(grid.shape, grid.resolution, behaviour_cell, source=cell_source)
    return {
        "source": "catalogue behaviour",
        "cell_m": cell,
        "dt_s": behaviour_dt,
        "rows": len(tracks),
    }


def generate_manifest(
    df: pd.DataFrame,
    tracks: pd.DataFrame,
    fit: Fit,
    grid: OccupancyGrid | None = None,
    options: AssemblyOptions | None = None,
    *,
    fit_file: str | os.PathLike,
    map_file: str | os.PathLike | None,
    seed: int,
    **settings: Unpack[AssemblySettings],
) -> tuple[ScenesManifest, pd.DataFrame | None]:
    """What a folder of scenes drawn from a fit records (``are-stats generate``): the
    ``manifest`` and ``tracks`` to give :func:`write_scenes`.

    Parameters
    ----------
    df, tracks : pandas.DataFrame
        The scenes' tables (:func:`~are_stats.scenarios.scenes_tables`), ``(n_artefacts,)``
        and ``(n_poses,)`` rows.
    fit : Fit
        The fit they were drawn from (its class labels and behaviour).
    grid : OccupancyGrid, optional
        The map they were placed on.
    fit_file, map_file : path
        The fit's and the map's files, as the manifest names them (``map_file`` None
        without a map).
    options : AssemblyOptions, optional
        The options the scenes were drawn with
        (:func:`~are_stats.scenarios.scenes_from_fit`): the manifest records its
        ``model`` and ``positions``, and its behaviour settings (:func:`tracks_record`).
    seed : int
        The seed of the scenes.
    **settings
        Fields of :class:`~are_stats.scenarios.AssemblyOptions` that replace those of
        ``options``.

    Returns
    -------
    manifest : dict
        ``fit``, ``model``, ``map``, ``seed``, ``class_labels``, ``generation`` (the
        table's ``attrs["generation"]`` with ``positions``) and, when something moves,
        ``tracks`` (:func:`tracks_record`).
    tracks : pandas.DataFrame or None
        The tracks to write; None when nothing moves (no tracks file).
    """
    opts = (options or AssemblyOptions()).with_settings(settings)
    manifest: ScenesManifest = {
        "fit": str(fit_file),
        "model": opts.model,
        "map": None if map_file is None else str(map_file),
        "seed": int(seed),
        "class_labels": None if fit.class_labels is None else list(fit.class_labels),
        "generation": {**df.attrs.get("generation", {}), "positions": opts.positions},
    }
    section = tracks_record(
        opts.behaviours,
        fit.behaviour,
        tracks,
        grid,
        behaviour_cell=opts.behaviour_cell,
        behaviour_dt=opts.behaviour_dt,
        cell_source=opts.cell_source,
    )
    if section is None:
        return manifest, None
    manifest["tracks"] = section
    return manifest, tracks


def write_scenes(
    df: pd.DataFrame,
    out_dir: str | os.PathLike,
    manifest: Mapping[str, object] | None = None,
    *,
    tracks: pd.DataFrame | None = None,
    force: bool = False,
) -> Path:
    """Write a scenarios folder: ``artefacts.parquet``, ``manifest.yaml`` and, with
    ``tracks``, ``tracks.parquet``, as a whole new folder ``out_dir``.

    The Parquet files are written with pinned options, so the same tables give the same
    bytes. The manifest holds ``format_version`` (:data:`FORMAT_VERSION`), the are_stats
    version, the columns, the generation settings (``df.attrs["generation"]``: seed,
    parameters summary, ...), the tracks file with ``tracks`` and every key of
    ``manifest`` (e.g. ``fit``: the fit file used; ``tracks``: more about the tracks). The
    folder is written beside ``out_dir`` and put in its place as a whole
    (:func:`are_stats.scenarios.atomic_folder`): with ``force`` an existing folder is
    replaced entirely (no file of an earlier run stays).

    Parameters
    ----------
    df : pandas.DataFrame
        A scenarios table, ``(n_artefacts,)`` rows with the columns of
        :data:`SCENARIO_COLUMNS`.
    out_dir : str or PathLike
        Output folder.
    manifest : dict, optional
        Extra manifest entries (they win over the generated ones).
    tracks : pandas.DataFrame, optional
        Behaviour tracks, ``(n_poses,)`` rows with columns ``scenario, id, t, x, y, yaw``.
    force : bool
        Replace an existing folder.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    OutputExistsError
        If the folder exists (and is not empty) and ``force`` is false (nothing is written
        then).
    ValueError
        If ``df`` or ``tracks`` lacks a column.

    Examples
    --------
    >>> write_scenes(df, "scen/", {"fit": "fit.nc"})  # doctest: +SKIP
    >>> read_scenes("scen/").artefacts.equals(df)  # doctest: +SKIP
    True
    """
    _check_table(df, SCENARIO_COLUMNS, "df")
    if tracks is not None:
        _check_table(tracks, TRACK_COLUMNS, "tracks")
    plain = pd.DataFrame({c: df[c].to_numpy() for c in SCENARIO_COLUMNS})
    generation = df.attrs.get("generation", {})
    n_sc = int(generation.get("n_scenarios", int(df["scenario"].max()) + 1 if len(df) else 0))
    meta: ScenesManifest = {
        "format": f"are_stats scenarios {FORMAT_VERSION}",
        "format_version": FORMAT_VERSION,
        "version": __version__,
        "n_scenarios": n_sc,
        "n_artefacts": len(df),
        "files": {"artefacts": _ARTEFACTS},
        "columns": dict(SCENARIO_COLUMNS),
        "generation": generation,
    }
    extra = dict(manifest or {})
    if tracks is not None:
        given = extra.get("tracks")
        spec = dict(given) if isinstance(given, Mapping) else {}
        spec = {"file": _TRACKS, **{k: v for k, v in spec.items() if k != "file"}}
        spec.setdefault("rows", len(tracks))
        extra["tracks"] = spec
    meta.update(extra)
    text = yaml.safe_dump(_plain(meta), sort_keys=False, default_flow_style=None)
    out = Path(out_dir)
    with atomic_folder(out, force=force) as tmp:
        _write_parquet(plain, tmp / _ARTEFACTS)
        if tracks is not None:
            kinds = {c: np.int64 if c in ("scenario", "id") else np.float64 for c in TRACK_COLUMNS}
            cols = {c: tracks[c].to_numpy(kinds[c]) for c in TRACK_COLUMNS}
            _write_parquet(pd.DataFrame(cols), tmp / _TRACKS)
        (tmp / _MANIFEST).write_text(text)
    return out


# ---- reading ---------------------------------------------------------------------------


def _error(path: Path, where: str, expected: str, got: object) -> InputError:
    return InputError(path, where, expected, got)


def _raw(path: Path, what: str, required: tuple[str, ...]) -> tuple[RawTable | None, list[str]]:
    """``(RawTable or None, columns)``: None for a Parquet file with no rows (its schema
    still checked for the ``required`` columns)."""
    if path.suffix.lower() in (".parquet", ".pq") and path.is_file() and path.stat().st_size:
        import pyarrow.parquet as pq  # lazy: +0.02 s CPU on `import are_stats.scenarios`

        try:
            meta = pq.ParquetFile(path).metadata
        except (pa.ArrowException, OSError) as err:
            raise InputError(
                path, "", f"a {what} in Parquet format", Described(f"an unreadable file: {err}")
            ) from None
        if meta.num_rows == 0:
            names = [str(n) for n in meta.schema.to_arrow_schema().names]
            missing = [c for c in required if c not in names]
            if missing:
                raise InputError(
                    path,
                    f"missing column(s) {', '.join(repr(c) for c in missing)}",
                    f"a {what} with columns {', '.join(required)}",
                    Described(f"columns {', '.join(repr(c) for c in names) or '(none)'}"),
                )
            return None, names
    table = read_raw_table(path, what)
    table.require(list(required), what)
    return table, table.columns


def check_positions(table: RawTable, num: Mapping[str, np.ndarray]) -> None:
    """Refuse a position farther than :data:`MAX_POSITION` metres from the origin.

    Parameters
    ----------
    table : RawTable
        The table read (named in the error with the row and column).
    num : mapping of str to (rows,) float
        Its parsed columns; ``x`` and ``y`` are checked.

    Raises
    ------
    ValueError
        ``<file>: row <r>, column 'x': expected a position within 1e+07 m of the origin,
        got ...`` at the first such cell.
    """
    for c in ("x", "y"):
        big = np.abs(num[c]) > MAX_POSITION
        if big.any():
            i = int(np.argmax(big))
            raise table.error(
                i, c, f"a position within {MAX_POSITION:g} m of the origin", repr(float(num[c][i]))
            )


def _ints(table: RawTable, column: str, lo: int, hi: int) -> np.ndarray:
    """Integers in ``[lo, hi]`` (``lo`` is 0 or -1), first bad row named."""
    if lo >= 0:
        return table.nonneg_ints(column, allow_empty=False, hi=hi)[0]
    v = table.floats(column, allow_empty=False)[0]
    bad = (v < lo) | (v != np.round(v)) | (v > hi)
    if bad.any():
        i = int(np.argmax(bad))
        raise table.error(i, column, f"an integer >= {lo}", repr(float(v[i])))
    return v.astype(np.int64)


def _bools(table: RawTable, column: str) -> np.ndarray:
    if column not in table.bools:
        raise table.error(0, column, "booleans (true/false)", "a column of other values")
    s = table.strings[column]
    bad = ~np.isin(s, ["True", "False"])
    if bad.any():
        i = int(np.argmax(bad))
        raise table.error(i, column, "true or false", "an empty cell")
    return s == "True"


def _manifest(d: Path) -> ScenesManifest:
    mpath = d / _MANIFEST
    meta = load_yaml(mpath, "scenarios manifest")
    if not isinstance(meta, Mapping):
        raise _error(mpath, "", "a mapping (a scenarios manifest)", meta)
    meta = dict(meta)
    bad_key = next((k for k in meta if not isinstance(k, str)), None)
    if bad_key is not None:
        raise _error(mpath, "", "text keys", Described(f"the key {bad_key!r}"))
    if "format_version" in meta:
        get_int(meta["format_version"], mpath, "format_version", lo=1, hi=FORMAT_VERSION)
    generation = meta.get("generation")
    if generation is None:
        meta.pop("generation", None)
    elif not isinstance(generation, Mapping):
        raise _error(mpath, "generation", "a mapping", generation)
    elif generation.get("horizon") is not None:
        get_float(generation["horizon"], mpath, "generation.horizon", lo=0)
    if meta.get("n_scenarios") is not None:
        get_int(meta["n_scenarios"], mpath, "n_scenarios", lo=0, hi=_INT32)
    if meta.get("map") is not None:
        get_str(meta["map"], mpath, "map")
    if meta.get("class_labels") is not None:
        labels = get_list(meta["class_labels"], mpath, "class_labels")
        for i, lab in enumerate(labels):
            get_str(lab, mpath, f"class_labels[{i}]")
    return meta


def _artefacts(d: Path, n_sc: int | None) -> pd.DataFrame:
    path = d / _ARTEFACTS
    table, names = _raw(path, "scenarios table", REQUIRED_COLUMNS)
    if table is None:  # no artefact: a valid folder
        empty = {c: np.zeros(0, SCENARIO_COLUMNS[c].split(",")[0]) for c in SCENARIO_COLUMNS}
        return pd.DataFrame(empty)
    num = {c: table.floats(c, allow_empty=False)[0] for c in _FLOATS}
    check_positions(table, num)
    early = num["t_leave"] < num["t_arrive"]
    if early.any():
        i = int(np.argmax(early))
        expected = f"t_leave >= t_arrive ({float(num['t_arrive'][i])!r})"
        raise table.error(i, "t_leave", expected, repr(float(num["t_leave"][i])))
    hi_sc = _INT32 if n_sc is None else n_sc - 1
    scen = table.nonneg_ints("scenario", allow_empty=False, hi=max(hi_sc, 0))[0]
    if n_sc is not None and n_sc == 0:
        raise table.error(
            0, "scenario", f"no row ({d / _MANIFEST} says n_scenarios: 0)", int(scen[0])
        )
    if "artefact" in names:
        art = _ints(table, "artefact", 0, _INT32)
        dup = pd.DataFrame({"s": scen, "a": art}).duplicated().to_numpy()
        if dup.any():
            i = int(np.argmax(dup))
            raise table.error(i, "artefact", "artefact ids unique within a scenario", int(art[i]))
    else:
        art = pd.Series(scen).groupby(scen).cumcount().to_numpy(np.int64)
    cols: dict[str, np.ndarray] = {
        "scenario": scen,
        "artefact": art,
        "class": _ints(table, "class", -1, _INT32),
        "mark": _ints(table, "mark", -1, 2**53) if "mark" in names else np.full(len(scen), -1),
        **num,
        "truncated": _bools(table, "truncated") if "truncated" in names else num["t_arrive"] <= 0,
        "censored": _bools(table, "censored") if "censored" in names else np.zeros(len(scen), bool),
        "group": _ints(table, "group", 0, _INT32) if "group" in names else art,
    }
    df = pd.DataFrame(
        {c: np.asarray(v).astype(SCENARIO_COLUMNS[c].split(",")[0]) for c, v in cols.items()}
    )
    extras = [c for c in names if c not in SCENARIO_COLUMNS]
    if extras:  # kept as they are
        import pyarrow.parquet as pq  # lazy: +0.02 s CPU on `import are_stats.scenarios`

        more = pq.read_table(path, columns=extras).to_pandas()
        for c in extras:
            df[c] = more[c].to_numpy()
    return df


def _tracks(d: Path, meta: ScenesManifest, artefacts: pd.DataFrame) -> pd.DataFrame | None:
    spec = meta.get("tracks")
    if spec is None:
        return None
    mpath = d / _MANIFEST
    if not isinstance(spec, Mapping):
        raise _error(mpath, "tracks", "a mapping naming the tracks file (file: NAME)", spec)
    name = get_str(spec.get("file"), mpath, "tracks.file")
    if Path(name).name != name or name in ("", ".", ".."):
        raise _error(mpath, "tracks.file", "a file name inside the scenarios folder", name)
    if not (d / name).is_file():
        raise _error(
            mpath,
            "tracks.file",
            "a tracks file in the scenarios folder",
            Described(f"no file {name}"),
        )
    table, _ = _raw(d / name, "behaviour tracks", TRACK_COLUMNS)
    if table is None:
        dtypes = {c: np.int64 if c in ("scenario", "id") else float for c in TRACK_COLUMNS}
        return pd.DataFrame({c: np.zeros(0, t) for c, t in dtypes.items()})
    num = {c: table.floats(c, allow_empty=False)[0] for c in ("t", "x", "y", "yaw")}
    check_positions(table, num)
    scen = table.nonneg_ints("scenario", allow_empty=False)[0]
    ids = table.nonneg_ints("id", allow_empty=False)[0]
    known = pd.MultiIndex.from_arrays(
        [artefacts["scenario"].to_numpy(np.int64), artefacts["artefact"].to_numpy(np.int64)]
    )
    bad = ~pd.MultiIndex.from_arrays([scen, ids]).isin(known)
    if bad.any():
        i = int(np.argmax(bad))
        raise table.error(
            i, "id", f"an artefact of scenario {int(scen[i])} in {_ARTEFACTS}", repr(int(ids[i]))
        )
    dup = pd.DataFrame({"s": scen, "a": ids, "t": num["t"]}).duplicated().to_numpy()
    if dup.any():
        i = int(np.argmax(dup))
        expected = f"one pose per artefact and time (artefact {int(ids[i])} has two)"
        raise table.error(i, "t", expected, repr(float(num["t"][i])))
    return pd.DataFrame({"scenario": scen, "id": ids, **num})


def read_scenes(folder: str | os.PathLike) -> ScenesFolder:
    """Read and check a scenarios folder (written by :func:`write_scenes`, by an older
    are_stats without ``format_version``, or by hand).

    Checked: the manifest is a mapping with text keys; ``format_version`` an integer from 1
    to :data:`FORMAT_VERSION`; ``generation`` a mapping (``horizon`` a finite number >= 0);
    ``n_scenarios`` an integer >= 0; ``map`` a string or null; ``class_labels`` a list of
    strings or null; ``tracks`` a mapping naming a file of the folder. The artefacts table
    has the columns of :data:`REQUIRED_COLUMNS` (the others of :data:`SCENARIO_COLUMNS`
    are optional and filled in), zero rows or more; integer columns hold integers
    (``scenario`` below ``n_scenarios``, ``class`` and ``mark`` >= -1, ``artefact`` ids
    unique within a scenario), the float columns finite numbers with ``|x|, |y|`` at most
    :data:`MAX_POSITION` and ``t_arrive <= t_leave``, ``truncated`` and ``censored``
    booleans. The tracks hold finite poses within :data:`MAX_POSITION`, each naming an
    artefact of the table, one pose per artefact and time.

    Parameters
    ----------
    folder : str or PathLike
        The scenarios folder.

    Returns
    -------
    ScenesFolder
        ``artefacts`` (``df.attrs["generation"]`` holds the manifest's generation),
        ``manifest``, ``tracks`` (None without) and ``folder``; its map, horizon and
        classes for every reader (:meth:`ScenesFolder.grid`, :attr:`ScenesFolder.horizon`,
        :meth:`ScenesFolder.unknown_classes`).

    Raises
    ------
    FileNotFoundError
        If the folder does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) naming the file and the key, or the row and the column, and what
        was expected (``LimitError`` when a table is too large for the memory limit).
    """
    d = Path(folder)
    if not d.exists():
        raise FileNotFoundError(f"{d}: no such scenarios folder")
    if not d.is_dir():
        got = Described("a file" if d.is_file() else "neither a folder nor a file")
        raise _error(d, "", "a scenarios folder written by are-stats generate", got)
    for name in (_MANIFEST, _ARTEFACTS):
        if not (d / name).is_file():
            raise _error(
                d,
                name,
                f"a scenarios folder with {_MANIFEST} and {_ARTEFACTS}",
                Described(f"no file {name}"),
            )
    meta = _manifest(d)
    n_sc = meta.get("n_scenarios")
    df = _artefacts(d, None if n_sc is None else int(n_sc))
    df.attrs["generation"] = dict(meta.get("generation") or {})
    return ScenesFolder(df, meta, _tracks(d, meta, df), d)
