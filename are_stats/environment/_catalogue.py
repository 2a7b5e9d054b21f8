"""The artefact catalogue: the property table Q of the paper (Sect. 3.2).

Each row is a tuple ``Q = {l, b, p, q, Phi}``: a label ``l``, the bounding box ``b`` derived
from the class mesh S_A, speeds (for the position/orientation operators driven by the
behaviours) and features ``Phi``. Marks select rows (DECISIONS 5): row ``X`` with ``X``
clipped to the last row.

The catalogue is a YAML file::

    version: 1
    classes:
      - label: person
        mesh: person.obj            # relative to the YAML file
        speeds: {walk: 1.2, run: 3.0}   # m/s; walk required, run >= walk
        behaviours: [walk, run, follow, stop]
        features: {colour: [200, 60, 60], ...}   # free-form Phi
        variants: {rows: 31, scale: [0.85, 1.15]}   # optional: the class's rows of Q

A class's rows of Q (DECISIONS 5) are its ``variants``: either ``{rows: N, scale: [a, b]}``
(row ``r`` scales the box by ``a + (b - a) r / (N - 1)``) or an explicit list of
``{scale: s or [sx, sy, sz], features: {...}}`` mappings (features override the class's).
Without ``variants`` a class has one row, the mesh's own box. The mixture component of an
arrival is its class, and its mark X selects the class's row ``min(X, N - 1)``
(:meth:`ArtefactCatalogue.select`).

The artefact frame F_A is attached at the centre of the box base (the mesh is expected
around the origin with ``z >= 0``); the box is the mesh's axis-aligned bounds in F_A.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from are_stats import inputs
from are_stats.environment._mesh import MAX_COORDINATE, _mesh_file_size, load_mesh
from are_stats.environment._shipped import SHIPPED_DATA
from are_stats.inputs import Described, InputError, Source

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "ArtefactClass",
    "ArtefactCatalogue",
    "PropertyRow",
    "load_catalogue",
    "BEHAVIOURS",
    "DEFAULT_MODELS",
]

#: Behaviours an artefact may be allowed (DECISIONS 7).
BEHAVIOURS = ("walk", "run", "follow", "stop")

#: Largest speed accepted in a catalogue (m/s).
MAX_SPEED = 1000.0
#: Largest box scale factor accepted in a catalogue's variants.
MAX_SCALE = 1000.0
#: Memory estimate of one row of Q (bytes), for the memory limit on ``variants.rows``.
ROW_BYTES = 512
_CLASS_KEYS = ("label", "mesh", "speeds", "behaviours", "features", "variants")

#: The shipped data folder inside the package (default courtyard map, mesh and catalogue);
#: the same folder as :data:`~are_stats.environment.SHIPPED_DATA` (read-only: never written).
DEFAULT_MODELS = SHIPPED_DATA


@dataclass(frozen=True)
class _Box:
    """What a class of Q and a row of Q have alike: a label, a box, speeds, behaviours.

    Attributes
    ----------
    label : str
        Class label ``l``.
    row : int
        Index of the class in Q (:class:`ArtefactClass`), or of the row within its class
        (:class:`PropertyRow`, the clipped mark).
    bounds : (2, 3) float
        Axis-aligned bounding box ``b`` in F_A: ``[[xmin, ymin, zmin], [xmax, ...]]``.
    speeds : dict of str to float
        m/s per speed name (``walk`` and optionally ``run``; the operators p, q are driven
        by the behaviours).
    behaviours : tuple of str
        Allowed behaviours, a subset of :data:`BEHAVIOURS`.
    """

    label: str
    row: int
    bounds: np.ndarray
    speeds: dict[str, float]
    behaviours: tuple[str, ...]

    @property
    def half_extents(self) -> np.ndarray:
        """``(3,)`` half sizes of the bounding box."""
        return (self.bounds[1] - self.bounds[0]) / 2.0

    @property
    def box_centre(self) -> np.ndarray:
        """``(3,)`` centre of the bounding box in F_A."""
        return (self.bounds[1] + self.bounds[0]) / 2.0


@dataclass(frozen=True)
class ArtefactClass(_Box):
    """One class of Q: its rows are the class box scaled by its variants.

    Attributes
    ----------
    label, row, bounds, speeds, behaviours
        As for every row of Q (``row``: the index of the class in Q; ``bounds``: the
        mesh's bounding box).
    mesh_path : Path
    features : dict
        Class features Phi.
    variants : tuple of ((3,) float, dict)
        Per row of the class: the box scale about the base centre and the features it
        updates.
    """

    mesh_path: Path
    features: dict[str, object] = field(default_factory=dict)
    variants: tuple[tuple[np.ndarray, dict[str, object]], ...] = ((np.ones(3), {}),)

    @property
    def n_rows(self) -> int:
        """Number of rows of Q for this class (its variants)."""
        return len(self.variants)

    def property_row(self, mark: int) -> PropertyRow:
        """The row of Q selected by ``mark`` (clipped to ``[0, n_rows - 1]``, DECISIONS 5).

        The row's box is the class box scaled about the base centre of F_A (the artefact
        stays on the ground); its features are the class features updated by the variant's.
        """
        r = int(np.clip(int(mark), 0, self.n_rows - 1))
        scale, feats = self.variants[r]
        lo, hi = self.bounds
        centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
        bounds = np.stack([centre + (lo - centre) * scale, centre + (hi - centre) * scale])
        return PropertyRow(
            label=self.label,
            class_row=self.row,
            row=r,
            bounds=bounds,
            speeds=dict(self.speeds),
            behaviours=self.behaviours,
            features={**self.features, **feats},
        )

    def mesh(self) -> trimesh.Trimesh:
        """The class mesh S_A (loaded on demand)."""
        return load_mesh(self.mesh_path)


@dataclass(frozen=True)
class PropertyRow(_Box):
    """One tuple ``Q = {l, b, p, q, Phi}`` of the table, as selected by a mark.

    Attributes
    ----------
    label, row, bounds, speeds, behaviours
        As for every row of Q (``row``: the row within the class, the clipped mark).
    class_row : int
        Position of the class in the catalogue (the mixture component).
    features : dict
        Features Phi.
    """

    class_row: int
    features: dict[str, object]


class ArtefactCatalogue:
    """The table Q: artefact classes in row order.

    Examples
    --------
    >>> q = load_catalogue()  # the shipped catalogue (are_stats/data/artefacts)
    >>> q.labels[:2]
    ('person', 'child')
    >>> q.row(99).label == q.labels[-1]  # class positions clip to the last class
    True
    >>> r = q.select(0, 1000)  # class 0 (person), mark 1000: the person's last row
    >>> r.label, r.row == q["person"].n_rows - 1
    ('person', True)
    """

    def __init__(self, classes: list[ArtefactClass]) -> None:
        if not classes:
            raise ValueError("classes: expected at least one artefact class, got none")
        self.classes = tuple(classes)
        self._by_label = {c.label: c for c in classes}

    @property
    def labels(self) -> tuple[str, ...]:
        """Class labels in row order."""
        return tuple(c.label for c in self.classes)

    def __len__(self) -> int:
        return len(self.classes)

    def __getitem__(self, label: str) -> ArtefactClass:
        try:
            return self._by_label[label]
        except KeyError:
            raise ValueError(
                f"label: unknown artefact class {label!r} (known: {', '.join(self.labels)})"
            ) from None

    def __contains__(self, label: object) -> bool:
        return label in self._by_label

    def rows_of_labels(
        self, labels: Sequence[str], source: Source = "log", where: str = "label"
    ) -> np.ndarray:
        """The catalogue row (class position) of each class label of a log.

        A log that names its classes (the ``label`` column) is generated with the
        catalogue's rows of those names (issue 31); a label the catalogue lacks is an
        error that lists the catalogue's labels and shows how to add a row.

        Parameters
        ----------
        labels : sequence of str
            Distinct class labels (e.g. the fit's ``class_labels``).
        source, where : str
            What the error names (the log or fit file, and the column or attribute).

        Returns
        -------
        (len(labels),) int64
            Row of each label in :attr:`labels` order of the catalogue.

        Raises
        ------
        are_stats.inputs.InputError
            If a label is not one of the catalogue's.
        """
        names = [str(v) for v in labels]
        unknown = [v for v in names if v not in self._by_label]
        if unknown:
            raise InputError(
                source,
                where,
                f"class labels of the artefact catalogue ({', '.join(self.labels)}); to add "
                f"one, copy the shipped catalogue (are_stats/data/artefacts/catalogue.yaml) "
                f"and append a row such as '- {{label: {unknown[0]}, mesh: {unknown[0]}.obj, "
                f"speeds: {{walk: 1.0}}, behaviours: [walk, stop]}}' with its mesh beside it",
                Described(f"the unknown label(s) {', '.join(repr(v) for v in unknown)}"),
            )
        return np.array([self.classes.index(self._by_label[v]) for v in names], np.int64)

    def run_thresholds(self, floor: float = 2.5) -> dict[str, float]:
        """Per class label, the speed (m/s) above which a track of the class runs.

        Half-way between the class's walking and running speeds, and at least ``floor``
        (the threshold of :func:`are_stats.fitting.fit_behaviour` for people); a class
        without a running speed gets ``floor``. Cyclists (4 and 7 m/s) then ride, rather
        than all run.
        """
        out = {}
        for c in self.classes:
            walk, run = c.speeds.get("walk"), c.speeds.get("run")
            mid = 0.5 * (float(walk) + float(run)) if walk is not None and run is not None else 0.0
            out[c.label] = max(float(floor), mid)
        return out

    def row(self, i: int) -> ArtefactClass:
        """The class at position ``i`` (clipped to ``[0, len - 1]``)."""
        i = int(np.clip(int(i), 0, len(self.classes) - 1))
        return self.classes[i]

    def select(self, component: int, mark: int) -> PropertyRow:
        """The tuple of Q for an arrival of mixture component ``component`` with mark ``mark``.

        The component is the class (DECISIONS 5); the mark selects the class's row,
        clipped to its last row.

        Raises
        ------
        ValueError
            If ``component`` is not a class position ``0..len - 1``.
        """
        c = int(component)
        if not 0 <= c < len(self.classes):
            raise ValueError(
                f"component: expected a class position in [0, {len(self.classes) - 1}], got {c}"
            )
        return self.classes[c].property_row(mark)

    def table(self) -> list[dict[str, object]]:
        """Q as a list of plain dicts (label, row, box size, speeds, behaviours, features)."""
        return [
            {
                "label": c.label,
                "row": c.row,
                "size": (2 * c.half_extents).tolist(),
                "speeds": dict(c.speeds),
                "behaviours": list(c.behaviours),
                "features": dict(c.features),
            }
            for c in self.classes
        ]

    def __repr__(self) -> str:
        return f"ArtefactCatalogue({', '.join(self.labels)})"


def load_catalogue(path: str | os.PathLike | None = None) -> ArtefactCatalogue:
    """Load and validate an artefact catalogue YAML.

    Parameters
    ----------
    path : str or PathLike, optional
        The catalogue YAML; default the shipped ``artefacts/catalogue.yaml``. Top-level keys
        ``version`` (optional, 1) and ``classes``; class keys ``label``, ``mesh``,
        ``speeds`` (``walk``, optional ``run``; m/s in ``(0, MAX_SPEED]``), ``behaviours``,
        ``features`` (free-form mapping) and ``variants``; any other key is an error.
        Numbers must be numbers (no booleans or strings).

    Raises
    ------
    FileNotFoundError
        If the YAML does not exist.
    are_stats.inputs.InputError
        (a ``ValueError``) if a field is missing, unknown or invalid (the message names the
        file and the key path, e.g. ``classes[2].speeds.walk``), a mesh is missing or
        cannot be read, or the ``variants`` ask for more rows than the memory limit allows
        (:class:`are_stats.inputs.LimitError`, :data:`ROW_BYTES` bytes per row).
    """
    p = Path(path) if path is not None else DEFAULT_MODELS / "artefacts" / "catalogue.yaml"
    doc = inputs.check_keys(
        inputs.load_yaml(p, "catalogue YAML"), p, "", ("version", "classes"), ("classes",)
    )
    if "version" in doc and inputs.get_int(doc["version"], p, "version") != 1:
        raise InputError(p, "version", "1", doc["version"])
    entries = inputs.get_list(doc["classes"], p, "classes", min_len=1)
    out: list[ArtefactClass] = []
    seen: dict[str, int] = {}
    for k, raw in enumerate(entries):
        where = f"classes[{k}]"
        entry = inputs.check_keys(
            raw, p, where, _CLASS_KEYS, ("label", "mesh", "speeds", "behaviours")
        )
        label = inputs.get_str(entry["label"], p, f"{where}.label")
        if not label.strip():
            raise InputError(p, f"{where}.label", "a non-empty label", label)
        if label in seen:
            raise InputError(
                p,
                f"{where}.label",
                "a label used once",
                Described(f"{label!r}, a duplicate label of classes[{seen[label]}]"),
            )
        seen[label] = k
        speeds = inputs.check_keys(
            entry["speeds"], p, f"{where}.speeds", ("walk", "run"), ("walk",)
        )
        sp = {
            name: inputs.get_float(v, p, f"{where}.speeds.{name}", lo=0, lo_open=True, hi=MAX_SPEED)
            for name, v in speeds.items()
        }
        if "run" in sp and sp["run"] < sp["walk"]:
            raise InputError(
                p, f"{where}.speeds.run", f"run >= walk ({sp['walk']:g} m/s)", speeds["run"]
            )
        beh = tuple(inputs.get_list(entry["behaviours"], p, f"{where}.behaviours", min_len=1))
        for j, b in enumerate(beh):
            inputs.get_str(b, p, f"{where}.behaviours[{j}]", choices=BEHAVIOURS)
            if b in beh[:j]:
                raise InputError(p, f"{where}.behaviours[{j}]", "each behaviour once", b)
        if "run" in beh and "run" not in sp:
            raise InputError(
                p,
                f"{where}.speeds.run",
                "a 'run' speed (behaviour 'run' needs it)",
                Described("none"),
            )
        feats = entry.get("features") or {}
        if not isinstance(feats, dict):
            raise InputError(p, f"{where}.features", "a mapping of features", feats)
        feats = dict(feats)  # the class's own copy
        variants = _variants(p, where, entry.get("variants"))
        mesh_name = inputs.get_str(entry["mesh"], p, f"{where}.mesh")
        mesh_path = Path(mesh_name)
        if not mesh_path.is_absolute():
            mesh_path = p.parent / mesh_path
        if not mesh_path.is_file():
            raise InputError(
                p,
                f"{where}.mesh",
                "an existing mesh file",
                Described(f"{mesh_path}: {'not a file' if mesh_path.exists() else 'no such file'}"),
            )
        try:
            bounds = _mesh_bounds(mesh_path)
        except InputError as err:
            raise InputError(p, f"{where}.mesh", "a readable mesh", Described(str(err))) from None
        if not (bounds[1] > bounds[0]).all():
            raise InputError(
                p,
                f"{where}.mesh",
                "a mesh with a non-degenerate bounding box",
                Described(f"{mesh_path.name} with bounds {bounds.tolist()}"),
            )
        out.append(
            ArtefactClass(
                label=label,
                row=k,
                mesh_path=mesh_path,
                bounds=bounds,
                speeds=sp,
                behaviours=beh,
                features=feats,
                variants=variants,
            )
        )
    return ArtefactCatalogue(out)


def _mesh_bounds(path: Path) -> np.ndarray:
    """The axis-aligned bounds of the mesh at ``path``, as ``load_mesh(path).bounds``.

    A plain OBJ file (:func:`_obj_bounds`) is read here, without trimesh (0.4 s of imports
    in a process that only needs the catalogue's boxes, such as ``are-stats fit``); any
    other file, or an OBJ with more than vertices and triangles, is read by
    :func:`~are_stats.environment.load_mesh`, which also says what is wrong with a bad one.

    Parameters
    ----------
    path : Path
        A mesh file.

    Returns
    -------
    (2, 3) float64
        Lowest and highest corner of the vertices the faces use.

    Raises
    ------
    are_stats.inputs.InputError
        As :func:`~are_stats.environment.load_mesh`.
    """
    bounds = _obj_bounds(path) if path.suffix.lower() == ".obj" else None
    if bounds is None:
        bounds = np.asarray(load_mesh(path).bounds, dtype=float)
    return bounds


def _obj_bounds(path: Path) -> np.ndarray | None:
    """Bounds of a plain OBJ file, or None for anything else.

    Plain: comments, ``o``/``g``/``s`` lines, vertices ``v x y z`` and triangles ``f a b c``
    (indices from 1, or negative from the last vertex; ``a/t/n`` forms use ``a``), at least
    one triangle, every index within the vertices and every coordinate finite and within
    ``MAX_COORDINATE``: the file :func:`~are_stats.environment.load_mesh` accepts with the
    same vertices and triangles, whose bounds (trimesh's ``Trimesh.bounds``) are those of
    the vertices the triangles use. Anything else (normals, texture coordinates, polygons,
    a line that does not parse) returns None, for trimesh to read.

    Returns
    -------
    (2, 3) float64 or None
    """
    _mesh_file_size(path)
    vertices: list[tuple[float, float, float]] = []
    faces: list[int] = []
    try:
        with open(path, encoding="utf-8") as f:
            for line in f:
                parts = line.split()
                if "_" in line and parts and parts[0] in ("v", "f"):
                    return None  # Python's float and int read 1_000; trimesh does not
                if not parts or parts[0].startswith("#") or parts[0] in ("o", "g", "s"):
                    continue
                if len(parts) != 4:
                    return None
                if parts[0] == "v":
                    vertices.append((float(parts[1]), float(parts[2]), float(parts[3])))
                elif parts[0] == "f":
                    for token in parts[1:]:
                        i = int(token.split("/", 1)[0])
                        if i == 0:
                            return None
                        faces.append(i - 1 if i > 0 else len(vertices) + i)
                else:
                    return None
    except (ValueError, UnicodeDecodeError):
        return None
    if not faces:
        return None
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    idx = np.asarray(faces)
    if idx.min() < 0 or idx.max() >= len(v):
        return None
    if not (np.isfinite(v).all() and (np.abs(v) <= MAX_COORDINATE).all()):
        return None
    used = v[np.unique(idx)]
    return np.stack([used.min(axis=0), used.max(axis=0)])


def _variants(
    source: Path, where: str, spec: object
) -> tuple[tuple[np.ndarray, dict[str, object]], ...]:
    """Parse a class's ``variants`` field (see the module docstring)."""
    if spec is None:
        return ((np.ones(3), {}),)
    key = f"{where}.variants"

    def scale_of(value: object, at: str) -> np.ndarray:
        if isinstance(value, list | tuple):
            vals = inputs.get_list(value, source, at, min_len=3, max_len=3)
            return np.array(
                [
                    inputs.get_float(v, source, f"{at}[{i}]", lo=0, lo_open=True, hi=MAX_SCALE)
                    for i, v in enumerate(vals)
                ]
            )
        return np.full(3, inputs.get_float(value, source, at, lo=0, lo_open=True, hi=MAX_SCALE))

    if isinstance(spec, dict):
        spec = inputs.check_keys(spec, source, key, ("rows", "scale"), ("rows", "scale"))
        rows = inputs.get_int(spec["rows"], source, f"{key}.rows", lo=1)
        inputs.check_memory(rows * ROW_BYTES, f"the {rows} rows of {key}", source)
        ends = inputs.get_list(spec["scale"], source, f"{key}.scale", min_len=2, max_len=2)
        a, b = (scale_of(v, f"{key}.scale[{i}]") for i, v in enumerate(ends))
        steps = np.linspace(0.0, 1.0, rows) if rows > 1 else np.zeros(1)
        return tuple((a + (b - a) * t, {}) for t in steps)
    if isinstance(spec, list):
        items = inputs.get_list(spec, source, key, min_len=1)
        inputs.check_memory(len(items) * ROW_BYTES, f"the {len(items)} rows of {key}", source)
        out = []
        for r, raw in enumerate(items):
            at = f"{key}[{r}]"
            item = inputs.check_keys(raw, source, at, ("scale", "features"))
            feats = item.get("features") or {}
            if not isinstance(feats, dict):
                raise InputError(source, f"{at}.features", "a mapping of features", feats)
            out.append((scale_of(item.get("scale", 1.0), f"{at}.scale"), dict(feats)))
        return tuple(out)
    raise InputError(source, key, "{rows: N, scale: [a, b]} or a non-empty list", spec)
