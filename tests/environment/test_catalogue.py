"""The artefact catalogue Q."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import yaml

from are_stats import load_catalogue
from are_stats.environment import DEFAULT_MODELS, load_mesh


def test_shipped_catalogue():
    q = load_catalogue()
    assert {"person", "child", "car", "pallet", "cart"} <= set(q.labels)
    for row, c in enumerate(q.classes):
        assert c.row == row
        m = load_mesh(c.mesh_path)
        assert np.allclose(c.bounds, m.bounds)
        assert (c.half_extents > 0).all() and c.speeds["walk"] > 0
        assert set(c.behaviours) <= {"walk", "run", "follow", "stop"}
    car = q["car"]
    assert 4.0 < 2 * car.half_extents[0] < 5.0
    assert q.row(-3).label == q.labels[0] and q.row(10**6).label == q.labels[-1]
    assert q.table()[0]["label"] == "person"


def _copy(tmp_path):
    src = DEFAULT_MODELS / "artefacts"
    dst = tmp_path / "artefacts"
    shutil.copytree(src, dst)
    return dst / "catalogue.yaml"


def _edit(path, fn):
    doc = yaml.safe_load(path.read_text())
    fn(doc)
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["classes"][0].pop("mesh"), "class 'person': missing field 'mesh'"),
        (lambda d: d["classes"][1]["speeds"].update(walk=-1), "'speeds.walk'"),
        (lambda d: d["classes"][2].update(behaviours=["fly"]), "'behaviours'"),
        (lambda d: d["classes"][3].update(label="person"), "duplicate label"),
        (lambda d: d["classes"][0]["speeds"].update(run=0.5), "run >= walk"),
        (lambda d: d.pop("classes"), "'classes' list"),
    ],
)
def test_catalogue_errors(tmp_path, edit, match):
    p = _edit(_copy(tmp_path), edit)
    with pytest.raises(ValueError, match=match):
        load_catalogue(p)


def test_missing_and_unreadable_meshes(tmp_path):
    p = _copy(tmp_path)
    (p.parent / "cart.obj").unlink()
    with pytest.raises(FileNotFoundError, match="cart.obj"):
        load_catalogue(p)
    (p.parent / "cart.obj").write_text("this is not a mesh\n")
    with pytest.raises(ValueError, match="cart.obj"):
        load_catalogue(p)
    with pytest.raises(FileNotFoundError):
        load_catalogue(tmp_path / "none.yaml")
    q = load_catalogue(_copy(tmp_path / "x"))
    with pytest.raises(ValueError, match="unknown artefact class 'dragon'"):
        q["dragon"]


def test_marks_select_rows_within_the_class():
    """DECISIONS 5: the component is the class, the mark selects the class's row (clipped)."""
    q = load_catalogue()
    person = q["person"]
    assert person.n_rows == 31
    first, last = q.select(0, 0), q.select(0, 10**6)
    assert first.label == last.label == "person" and last.row == 30
    # the compact form scales the box linearly from 0.85 to 1.15, about the base centre
    np.testing.assert_allclose(first.half_extents, 0.85 * person.half_extents, rtol=1e-12)
    np.testing.assert_allclose(q.select(0, 15).half_extents, person.half_extents, rtol=1e-12)
    assert first.bounds[0, 2] == person.bounds[0, 2]  # stays on the ground
    van = q.select(q.labels.index("car"), 3)
    assert van.features["body"] == "van" and van.features["kind"] == "vehicle"
    assert q.select(q.labels.index("pallet"), -4).row == 0
    with pytest.raises(ValueError, match="component: expected a class position"):
        q.select(len(q), 0)


@pytest.mark.parametrize(
    "variants, match",
    [
        ("{rows: 0, scale: [1, 2]}", "variants.rows"),
        ("{rows: 3, scale: [1]}", "variants.scale"),
        ("[{scale: -1}]", r"variants\[0\].scale"),
        ("[]", "field 'variants'"),
    ],
)
def test_bad_variants(tmp_path, variants, match):
    shutil.copy(DEFAULT_MODELS / "artefacts" / "pallet.obj", tmp_path / "pallet.obj")
    (tmp_path / "q.yaml").write_text(
        "classes:\n  - label: pallet\n    mesh: pallet.obj\n    speeds: {walk: 0.1}\n"
        f"    behaviours: [stop]\n    variants: {variants}\n"
    )
    with pytest.raises(ValueError, match=match):
        load_catalogue(tmp_path / "q.yaml")
