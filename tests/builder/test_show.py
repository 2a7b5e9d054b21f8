"""The ``are-stats show`` command."""

from __future__ import annotations

import re

import pytest
from PIL import Image
from typer.testing import CliRunner

from are_stats.builder import show_map
from are_stats.cli import app
from are_stats.inputs import InputError

runner = CliRunner()


def test_show_renders_png(tmp_path):
    out = tmp_path / "c.png"
    res = runner.invoke(
        app, ["show", "courtyard", "--out", str(out), "--inflate", "0.4", "--artefacts", "10"]
    )
    assert res.exit_code == 0, res.output
    with Image.open(out) as im:
        assert im.size[0] > 300 and im.size[1] > 200
    res = runner.invoke(app, ["show", "courtyard", "--out", str(out)])
    assert res.exit_code == 2 and "already exists" in res.output
    res = runner.invoke(app, ["show", "courtyard", "--out", str(out), "--force"])
    assert res.exit_code == 0


def test_show_bad_map(tmp_path):
    res = runner.invoke(app, ["show", str(tmp_path / "none.yaml")])
    assert res.exit_code == 2 and "no such file" in res.output
    bad = tmp_path / "b.yaml"
    bad.write_text("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n")
    res = runner.invoke(app, ["show", str(bad)])
    assert res.exit_code == 2 and "free_thresh" in res.output


@pytest.mark.parametrize(
    ("args", "match"),
    [
        # --artefacts 1e5 never returned (placement loop): refused up front
        (["--artefacts", "100000"], r"--artefacts: expected an integer >= 0 and <= 1000"),
        (["--artefacts", "-1"], r"--artefacts: expected an integer >= 0"),
        (["--inflate", "-0.5"], r"--inflate: expected a finite number >= 0 and <= 1000"),
        (["--inflate", "1e300"], r"--inflate: expected a finite number >= 0 and <= 1000"),
        (["--inflate", "nan"], r"--inflate: expected a finite number"),
        (["--seed", "-3"], r"--seed: expected an integer >= 0"),
    ],
)
def test_show_bad_options(tmp_path, args, match):
    res = runner.invoke(app, ["show", "courtyard", "--out", str(tmp_path / "c.png"), *args])
    assert res.exit_code == 2, res.output
    assert re.search(match, res.output), res.output
    assert not (tmp_path / "c.png").exists()


def test_show_refuses_more_artefacts_than_fit(tmp_path):
    (tmp_path / "m.pgm").write_bytes(b"P5\n4 4\n255\n" + bytes([254]) * 16)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError, match=r"--artefacts: expected at most \d+ artefacts"):
        show_map(tmp_path / "m.yaml", tmp_path / "m.png", artefacts=500)
    # a crowded map: the first placement that finds no room stops with a clear error
    with pytest.raises(InputError, match=r"--artefacts: expected artefacts that fit on m.yaml"):
        show_map(tmp_path / "m.yaml", tmp_path / "m.png", artefacts=3, seed=1)
    assert not (tmp_path / "m.png").exists()


def test_show_long_thin_map(tmp_path):
    (tmp_path / "m.pgm").write_bytes(b"P5\n2 3000\n255\n" + bytes([254]) * 6000)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    out = show_map(tmp_path / "m.yaml", tmp_path / "m.png")
    with Image.open(out) as im:
        assert im.size[1] < 6000
