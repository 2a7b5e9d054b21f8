"""The documentation builds in strict mode (every page, every mkdocstrings reference), with
no network: no script from a URL, every formula rendered to MathML at build time.

The default run builds with ``ARE_STATS_DOCS_FAST=1`` (no figures drawn, notebooks not
executed; see ``docs/hooks.py``). ``ARE_STATS_DOCS_FULL=1`` also runs the full build that
``make docs`` does: figures drawn by ``docs/make_figures.py``, notebooks executed (minutes).
"""

from __future__ import annotations

import base64
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
VERBATIM = re.compile(r"<(pre|code|script|style|textarea)\b.*?</\1>", re.S)


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _build(site: Path, fast: bool) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "-q"]
    cmd += ["-f", str(ROOT / "docs" / "mkdocs.yml"), "-d", str(site)]
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)}
    env["ARE_STATS_DOCS_FAST"] = "1" if fast else "0"
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)


def offline_problems(site: Path) -> list[str]:
    """Scripts from a URL, and LaTeX left as text (``$``, ``\\(``, ``\\[`` outside code)."""
    problems = []
    for page in sorted(site.rglob("*.html")):
        text = page.read_text()
        name = page.relative_to(site)
        for src in re.findall(r"<script[^>]*\bsrc=\"(https?://[^\"]*)\"", text):
            problems.append(f"{name}: script from {src}")
        if 'class="arithmatex"' in text:
            problems.append(f"{name}: arithmatex output not converted to MathML")
        prose = VERBATIM.sub("", text)
        for m in re.finditer(r"\$|\\\(|\\\[", prose):
            problems.append(f"{name}: raw LaTeX {prose[max(m.start() - 40, 0) : m.end() + 40]!r}")
    return problems


def test_docs_build_strict(tmp_path):
    site = tmp_path / "site"
    res = _build(site, fast=True)
    assert res.returncode == 0, res.stdout + res.stderr
    assert (site / "index.html").exists()
    assert offline_problems(site) == []
    eq3 = (site / "experiments" / "index.html").read_text()
    assert eq3.count('<math xmlns="http://www.w3.org/1998/Math/MathML" display="block">') >= 2
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert (site / "notebooks" / nb.stem / "index.html").is_file(), nb.name


def test_offline_problems_finds_leftovers(tmp_path):
    page = tmp_path / "a.html"
    page.write_text(
        '<script src="https://cdn.example/x.js"></script><p>$x$ and \\(y\\)</p>'
        "<pre>echo $HOME</pre>"
    )
    found = offline_problems(tmp_path)
    assert len(found) == 4 and "script from https://cdn.example/x.js" in found[0]
    page.write_text("<p>no math</p><code>$PATH</code>")
    assert offline_problems(tmp_path) == []


def test_math_to_mathml_against_hand_written_mathml():
    hooks = _hooks()
    out = hooks.latex_to_mathml(r"\mathcal M_{2D}", False, "page.md")
    assert '<mi mathvariant="normal">\u2133</mi>' in out and 'display="inline"' in out
    assert "\U0001d400" in hooks.latex_to_mathml(r"n_{\mathbf A}", False, "page.md")  # bold A
    html = '<p><span class="arithmatex">\\(a &lt; b\\)</span></p>'
    html += '<div class="arithmatex">\\[\\frac{1}{2}\\]</div>'
    out = hooks.math_to_mathml(html, "page.md")
    assert "arithmatex" not in out and "<mo>&#x0003C;</mo>" in out
    assert (
        '<div class="math"><math' in out
        and "<mfrac><mrow><mn>1</mn></mrow><mrow><mn>2</mn></mrow></mfrac>" in out
    )
    with pytest.raises(ValueError, match=r"page\.md: cannot convert the formula"):
        hooks.latex_to_mathml(r"\frac{1}{", False, "page.md")


def test_notebook_page_keeps_outputs_and_refuses_errors():
    hooks = _hooks()
    png = base64.b64encode(b"\x89PNG fake").decode()
    nb = nbformat.v4.new_notebook()
    code = nbformat.v4.new_code_cell("print('hi')\nx")
    code.outputs = [
        nbformat.v4.new_output("stream", name="stdout", text="hi\n"),
        nbformat.v4.new_output("display_data", data={"image/png": png, "text/plain": "<Fig>"}),
        nbformat.v4.new_output("display_data", data={"image/png": png, "text/plain": "<Fig>"}),
        nbformat.v4.new_output(
            "execute_result", data={"text/html": "<table>\n\n</table>"}, execution_count=1
        ),
    ]
    nb.cells = [nbformat.v4.new_markdown_cell("# Title"), code]
    page, images = hooks._notebook_page(Path("nb.ipynb"), nb, True)
    assert "# Title" in page and "```python\nprint('hi')\nx\n```" in page
    assert "```text\nhi\n```" in page and "![output of cell 1](nb_1_1.png)" in page
    assert images == {"nb_1_1.png": b"\x89PNG fake"}
    assert '<div class="nb-output">\n<table>\n</table>\n</div>' in page
    code.outputs = [
        nbformat.v4.new_output("error", ename="ZeroDivisionError", evalue="", traceback=[])
    ]
    with pytest.raises(RuntimeError, match="nb.ipynb: cell 1 raised ZeroDivisionError"):
        hooks._notebook_page(Path("nb.ipynb"), nb, True)


def test_every_figure_is_named_on_its_page():
    hooks = _hooks()
    for name, (page, _) in hooks.FIGURES.items():
        text = (ROOT / "docs" / "src" / page).read_text()
        assert f"(figures/{name})" in text, f"docs/src/{page} does not show {name}"
    sys.path.insert(0, str(ROOT / "docs"))
    try:
        from make_figures import make_figures
    finally:
        sys.path.remove(str(ROOT / "docs"))
    with pytest.raises(ValueError, match="unknown figures"):
        make_figures("/nonexistent", ["nope.png"])


@pytest.mark.skipif(
    os.environ.get("ARE_STATS_DOCS_FULL", "") in ("", "0"),
    reason="the full docs build (figures, executed notebooks) runs with ARE_STATS_DOCS_FULL=1",
)
def test_docs_full_build(tmp_path):
    site = tmp_path / "site"
    res = _build(site, fast=False)
    assert res.returncode == 0, res.stdout + res.stderr
    assert offline_problems(site) == []
    hooks = _hooks()
    for name, (page, _) in hooks.FIGURES.items():
        png = site / "figures" / name
        assert png.stat().st_size > 10_000, name
        assert f"figures/{name}" in (site / page.removesuffix(".md") / "index.html").read_text()
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert list((site / "notebooks").glob(f"{nb.stem}_*.png")), f"{nb.name}: no figure"
