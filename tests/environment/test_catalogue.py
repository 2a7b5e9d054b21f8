"""The artefact catalogue Q."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import yaml

from are_stats import load_catalogue
from are_stats.environment import DEFAULT_MODELS, load_mesh
from are_stats.inputs import InputError, limits


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
        (lambda d: d["classes"][0].pop("mesh"), r"classes\[0\]\.mesh: expected this key"),
        (lambda d: d["classes"][1]["speeds"].update(walk=-1), r"classes\[1\]\.speeds\.walk"),
        (lambda d: d["classes"][2].update(behaviours=["fly"]), r"\[2\]\.behaviours\[0\]"),
        (lambda d: d["classes"][3].update(label="person"), "duplicate label of classes.0."),
        (lambda d: d["classes"][0]["speeds"].update(run=0.5), "run >= walk"),
        (lambda d: d.pop("classes"), "classes: expected this key to be present"),
        # strict types: no bool or string as a number, unknown keys listed
        (lambda d: d["classes"][0]["speeds"].update(walk=True), r"walk: .*True \(a bool\)"),
        (lambda d: d["classes"][0]["speeds"].update(walk="1"), r"walk: .*'1' \(a string\)"),
        (lambda d: d["classes"][0]["speeds"].update(walk=1e300), r"speeds\.walk: .*<= 1000"),
        (lambda d: d["classes"][0]["speeds"].update(jog=2.0), r"speeds\.jog: .*known keys walk"),
        (lambda d: d["classes"][0].update(colour=3), r"\[0\]\.colour: expected one of the known"),
        (lambda d: d.update(extra=1), r"extra: expected one of the known keys version, classes"),
        (lambda d: d.update(version=2), r"version: expected 1, got 2"),
        (lambda d: d.update(version=True), r"version: expected an integer"),
        (lambda d: d["classes"][0].update(label=3), r"classes\[0\]\.label: expected a string"),
        (lambda d: d["classes"][0].update(mesh=[1]), r"classes\[0\]\.mesh: expected a string"),
        (lambda d: d["classes"][0].update(behaviours=["walk", "walk"]), "each behaviour once"),
        (lambda d: d["classes"][0].update(features=[1]), r"features: expected a mapping"),
        (lambda d: d.update(classes=[]), r"classes: expected a list of at least 1"),
        (lambda d: d.update(classes={"a": 1}), r"classes: expected a list"),
    ],
)
def test_catalogue_errors(tmp_path, edit, match):
    p = _edit(_copy(tmp_path), edit)
    with pytest.raises(ValueError, match=match):
        load_catalogue(p)


def test_missing_and_unreadable_meshes(tmp_path):
    p = _copy(tmp_path)
    (p.parent / "cart.obj").unlink()
    with pytest.raises(InputError, match=r"classes\[4\]\.mesh: expected an existing .*cart.obj"):
        load_catalogue(p)
    (p.parent / "cart.obj").write_text("this is not a mesh\n")
    with pytest.raises(InputError, match=r"classes\[4\]\.mesh: expected a readable .*cart.obj"):
        load_catalogue(p)
    with pytest.raises(FileNotFoundError):
        load_catalogue(tmp_path / "none.yaml")
    with pytest.raises(InputError, match="expected a catalogue YAML, got a directory"):
        load_catalogue(tmp_path)
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
        ("[]", r"variants: expected a list of at least 1"),
        ("{rows: true, scale: [1, 2]}", r"variants\.rows: expected an integer >= 1, got True"),
        ("{rows: 2.5, scale: [1, 2]}", r"variants\.rows: expected an integer"),
        ("{rows: 3, scale: [1, 0]}", r"variants\.scale\[1\]: expected a finite number > 0"),
        ("{rows: 3, scale: [1, 2], step: 1}", r"variants\.step: expected one of the known"),
        ("[{scale: true}]", r"variants\[0\]\.scale: .*True \(a bool\)"),
        ("[{scale: [1, 2, 3, 4]}]", r"variants\[0\]\.scale: expected a list of 3 values"),
        ("[{scal: 2}]", r"variants\[0\]\.scal: expected one of the known keys scale"),
        ("[{scale: .nan}]", r"variants\[0\]\.scale: expected a finite number"),
        ("3", r"variants: expected \{rows: N"),
        # a catalogue asking for 1e8 rows of Q is refused before anything is allocated
        ("{rows: 100000000, scale: [1, 2]}", r"expected the 100000000 rows of classes\[0\]"),
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


def test_catalogue_row_limit_follows_the_memory_limit(tmp_path):
    shutil.copy(DEFAULT_MODELS / "artefacts" / "pallet.obj", tmp_path / "pallet.obj")
    (tmp_path / "q.yaml").write_text(
        "classes:\n  - label: pallet\n    mesh: pallet.obj\n    speeds: {walk: 0.1}\n"
        "    behaviours: [stop]\n    variants: {rows: 1000, scale: [1, 2]}\n"
    )
    with limits(memory="100K"), pytest.raises(ValueError, match="memory limit of 100.0 KiB"):
        load_catalogue(tmp_path / "q.yaml")
    assert load_catalogue(tmp_path / "q.yaml")["pallet"].n_rows == 1000


def test_catalogue_alias_bomb_is_refused(tmp_path):
    shutil.copy(DEFAULT_MODELS / "artefacts" / "pallet.obj", tmp_path / "pallet.obj")
    bomb = "".join(
        f"      x{k}: &{chr(98 + k)} [{', '.join([f'*{chr(97 + k)}'] * 10)}]\n" for k in range(6)
    )
    (tmp_path / "q.yaml").write_text(
        "classes:\n  - label: pallet\n    mesh: pallet.obj\n    speeds: {walk: 0.1}\n"
        "    behaviours: [stop]\n    features:\n      x: &a [a, a, a, a, a, a, a, a, a, a]\n" + bomb
    )
    with pytest.raises(InputError, match="expands to at most"):
        load_catalogue(tmp_path / "q.yaml")


def test_mesh_bounds_equal_trimesh_on_every_shipped_mesh():
    """The catalogue reads a plain OBJ's bounds without trimesh: the same numbers as
    trimesh's Trimesh.bounds (exactly) on each shipped mesh."""
    from are_stats.environment._catalogue import _mesh_bounds, _obj_bounds

    meshes = sorted((DEFAULT_MODELS / "artefacts").glob("*.obj"))
    assert len(meshes) >= 7
    for path in meshes:
        fast = _obj_bounds(path)
        assert fast is not None, path.name
        np.testing.assert_array_equal(fast, np.asarray(load_mesh(path).bounds))
        np.testing.assert_array_equal(_mesh_bounds(path), fast)


def test_obj_bounds_use_the_faces_vertices_and_leave_other_files_to_trimesh(tmp_path):
    from are_stats.environment._catalogue import _mesh_bounds, _obj_bounds

    # an unused far vertex, negative and v/t/n-style indices, groups and comments
    plain = tmp_path / "plain.obj"
    plain.write_text(
        "# a tetrahedron\no tet\nv 0 0 0\nv 1 0 0\nv 0 2 0\nv 0 0 3\nv 50 -50 9\n"
        "g sides\ns off\nf 1 2 3\nf 1//1 2//1 4//1\nf -5 -3 -2\n"
    )
    np.testing.assert_array_equal(_obj_bounds(plain), [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_array_equal(_obj_bounds(plain), np.asarray(load_mesh(plain).bounds))
    # a quad, normals, a bad index: trimesh reads it (and says what is wrong)
    quad = tmp_path / "quad.obj"
    quad.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nf 1 2 3 4\n")
    assert _obj_bounds(quad) is None
    np.testing.assert_array_equal(_mesh_bounds(quad), np.asarray(load_mesh(quad).bounds))
    normals = tmp_path / "normals.obj"
    normals.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n")
    assert _obj_bounds(normals) is None
    np.testing.assert_array_equal(_mesh_bounds(normals), np.asarray(load_mesh(normals).bounds))
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n")
    assert _obj_bounds(bad) is None
    with pytest.raises(InputError, match="bad.obj"):
        _mesh_bounds(bad)
    for text in (
        "v 0 0 nan\nv 1 0 0\nv 1 1 1\nf 1 2 3\n",
        "v 0 0 1_0\nv 1 0 0\nv 1 1 1\nf 1 2 3\n",
    ):
        odd = tmp_path / "odd.obj"
        odd.write_text(text)
        assert _obj_bounds(odd) is None


def test_loading_the_catalogue_imports_no_trimesh():
    import subprocess
    import sys

    code = (
        "import sys\nfrom are_stats import load_catalogue\nq = load_catalogue()\n"
        "assert len(q) >= 7\nprint('trimesh' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
