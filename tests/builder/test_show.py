"""The ``are-stats show`` command."""

from __future__ import annotations

from PIL import Image
from typer.testing import CliRunner

from are_stats.cli import app

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
    assert res.exit_code == 2 and "map YAML not found" in res.output
    bad = tmp_path / "b.yaml"
    bad.write_text("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n")
    res = runner.invoke(app, ["show", str(bad)])
    assert res.exit_code == 2 and "free_thresh" in res.output
