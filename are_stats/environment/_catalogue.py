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
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

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

#: The repository's ``models/`` folder (default courtyard map, mesh and catalogue).
DEFAULT_MODELS = Path(__file__).resolve().parents[2] / "models"


@dataclass(frozen=True)
class ArtefactClass:
    """One row of Q.

    Attributes
    ----------
    label : str
    row : int
        Index of the row in Q.
    mesh_path : Path
    bounds : (2, 3) float
        Axis-aligned bounding box of the mesh in F_A: ``[[xmin, ymin, zmin], [xmax, ...]]``.
    speeds : dict of str to float
        m/s per speed name (``walk`` and optionally ``run``).
    behaviours : tuple of str
        Allowed behaviours, a subset of :data:`BEHAVIOURS`.
    features : dict
        Class features Phi.
    """

    label: str
    row: int
    mesh_path: Path
    bounds: np.ndarray
    speeds: dict[str, float]
    behaviours: tuple[str, ...]
    features: dict[str, Any] = field(default_factory=dict)
    variants: tuple[tuple[np.ndarray, dict[str, Any]], ...] = ((np.ones(3), {}),)

    @property
    def half_extents(self) -> np.ndarray:
        """``(3,)`` half sizes of the bounding box."""
        return (self.bounds[1] - self.bounds[0]) / 2.0

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

    @property
    def box_centre(self) -> np.ndarray:
        """``(3,)`` centre of the bounding box in F_A."""
        return (self.bounds[1] + self.bounds[0]) / 2.0

    def mesh(self) -> trimesh.Trimesh:
        """The class mesh S_A (loaded on demand)."""
        from are_stats.environment._mesh import load_mesh

        return load_mesh(self.mesh_path)


@dataclass(frozen=True)
class PropertyRow:
    """One tuple ``Q = {l, b, p, q, Phi}`` of the table, as selected by a mark.

    Attributes
    ----------
    label : str
        Class label ``l``.
    class_row : int
        Position of the class in the catalogue (the mixture component).
    row : int
        Row within the class (the clipped mark).
    bounds : (2, 3) float
        Bounding box ``b`` in F_A.
    speeds : dict of str to float
        m/s per speed name (the operators p, q are driven by the behaviours).
    behaviours : tuple of str
        Allowed behaviours.
    features : dict
        Features Phi.
    """

    label: str
    class_row: int
    row: int
    bounds: np.ndarray
    speeds: dict[str, float]
    behaviours: tuple[str, ...]
    features: dict[str, Any]

    @property
    def half_extents(self) -> np.ndarray:
        """``(3,)`` half sizes of the bounding box."""
        return (self.bounds[1] - self.bounds[0]) / 2.0


class ArtefactCatalogue:
    """The table Q: artefact classes in row order.

    Examples
    --------
    >>> q = load_catalogue()  # the catalogue shipped in models/artefacts
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

    def table(self) -> list[dict[str, Any]]:
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
        The catalogue YAML; default ``models/artefacts/catalogue.yaml``.

    Raises
    ------
    FileNotFoundError
        If the YAML or a mesh file is missing.
    ValueError
        If a field is missing or invalid (the message names the class and field), or a
        mesh cannot be read.
    """
    import yaml

    from are_stats.environment._mesh import load_mesh

    p = Path(path) if path is not None else DEFAULT_MODELS / "artefacts" / "catalogue.yaml"
    if not p.is_file():
        raise FileNotFoundError(f"{p}: artefact catalogue not found")
    try:
        doc = yaml.safe_load(p.read_text())
    except yaml.YAMLError as err:
        raise ValueError(f"{p}: not valid YAML ({err})") from err
    if not isinstance(doc, dict) or not isinstance(doc.get("classes"), list):
        raise ValueError(f"{p}: expected a mapping with a 'classes' list")
    out: list[ArtefactClass] = []
    seen: set[str] = set()
    for k, entry in enumerate(doc["classes"]):
        where = f"{p}: classes[{k}]"
        if not isinstance(entry, dict):
            raise ValueError(f"{where}: expected a mapping, got {entry!r}")
        label = entry.get("label")
        if not isinstance(label, str) or not label:
            raise ValueError(f"{where}: field 'label': expected a non-empty string, got {label!r}")
        where = f"{p}: class {label!r}"
        if label in seen:
            raise ValueError(f"{where}: duplicate label")
        seen.add(label)
        for key in ("mesh", "speeds", "behaviours"):
            if key not in entry:
                raise ValueError(f"{where}: missing field {key!r}")
        speeds = entry["speeds"]
        if not isinstance(speeds, dict) or "walk" not in speeds:
            raise ValueError(f"{where}: field 'speeds': expected a mapping with 'walk' (m/s)")
        sp: dict[str, float] = {}
        for name, v in speeds.items():
            try:
                fv = float(v)
            except (TypeError, ValueError):
                fv = float("nan")
            if not np.isfinite(fv) or fv <= 0:
                raise ValueError(
                    f"{where}: field 'speeds.{name}': expected a number > 0, got {v!r}"
                )
            sp[str(name)] = fv
        if "run" in sp and sp["run"] < sp["walk"]:
            raise ValueError(f"{where}: field 'speeds': expected run >= walk, got {sp}")
        beh = entry["behaviours"]
        if not isinstance(beh, list) or not beh or any(b not in BEHAVIOURS for b in beh):
            raise ValueError(
                f"{where}: field 'behaviours': expected a non-empty subset of {BEHAVIOURS}, "
                f"got {beh!r}"
            )
        if "run" in beh and "run" not in sp:
            raise ValueError(f"{where}: behaviour 'run' needs a 'run' speed")
        feats = entry.get("features", {}) or {}
        if not isinstance(feats, dict):
            raise ValueError(f"{where}: field 'features': expected a mapping, got {feats!r}")
        variants = _variants(where, entry.get("variants"))
        mesh_path = Path(str(entry["mesh"]))
        if not mesh_path.is_absolute():
            mesh_path = p.parent / mesh_path
        mesh = load_mesh(mesh_path)
        bounds = np.asarray(mesh.bounds, dtype=float)
        if not (bounds[1] > bounds[0]).all():
            raise ValueError(f"{where}: mesh {mesh_path.name} has a degenerate bounding box")
        out.append(
            ArtefactClass(
                label=label,
                row=k,
                mesh_path=mesh_path,
                bounds=bounds,
                speeds=sp,
                behaviours=tuple(beh),
                features=dict(feats),
                variants=variants,
            )
        )
    return ArtefactCatalogue(out)


def _variants(where: str, spec: Any) -> tuple[tuple[np.ndarray, dict[str, Any]], ...]:
    """Parse a class's ``variants`` field (see the module docstring)."""
    if spec is None:
        return ((np.ones(3), {}),)

    def scale_of(value: Any, field_name: str) -> np.ndarray:
        try:
            a = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
        except (TypeError, ValueError):
            a = np.full(3, np.nan)
        if not np.isfinite(a).all() or (a <= 0).any():
            raise ValueError(
                f"{where}: field '{field_name}': expected a scale > 0 or 3 scales > 0, "
                f"got {value!r}"
            )
        return a

    if isinstance(spec, dict):
        rows, scale = spec.get("rows"), spec.get("scale")
        if not isinstance(rows, int) or rows < 1:
            raise ValueError(
                f"{where}: field 'variants.rows': expected an integer >= 1, got {rows!r}"
            )
        if not isinstance(scale, list) or len(scale) != 2:
            raise ValueError(
                f"{where}: field 'variants.scale': expected [first, last], got {scale!r}"
            )
        a, b = (scale_of(v, "variants.scale") for v in scale)
        steps = np.linspace(0.0, 1.0, rows) if rows > 1 else np.zeros(1)
        return tuple((a + (b - a) * t, {}) for t in steps)
    if isinstance(spec, list) and spec:
        out = []
        for r, item in enumerate(spec):
            if not isinstance(item, dict):
                raise ValueError(
                    f"{where}: field 'variants[{r}]': expected a mapping, got {item!r}"
                )
            feats = item.get("features", {}) or {}
            if not isinstance(feats, dict):
                raise ValueError(
                    f"{where}: field 'variants[{r}].features': expected a mapping, got {feats!r}"
                )
            out.append((scale_of(item.get("scale", 1.0), f"variants[{r}].scale"), dict(feats)))
        return tuple(out)
    raise ValueError(
        f"{where}: field 'variants': expected {{rows: N, scale: [a, b]}} or a non-empty list, "
        f"got {spec!r}"
    )
