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
