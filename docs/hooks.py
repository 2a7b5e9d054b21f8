"""mkdocs hooks: figures and executed notebooks made at build time, math as MathML.

Registered in ``docs/mkdocs.yml`` (``hooks:``). Three jobs, none of which needs a network:

* **Figures.** ``docs/make_figures.py`` draws every figure a page shows (``FIGURES``) in a
  subprocess; the PNGs are cached in ``docs/.cache/figures/<hash>`` keyed by the content of
  that script and of the package, and enter the site as ``figures/NAME.png``.
* **Notebooks.** Every ``notebooks/*.ipynb`` (committed with a full run's outputs) is run
  again with nbclient (``ARE_STATS_NOTEBOOK_QUICK=1``; cached by the same kind of hash) and
  becomes the page ``notebooks/NAME.md``: markdown cells as they are, code cells as Python
  blocks, their outputs as text blocks, HTML tables and PNGs. A cell that raises fails the build.
* **Math.** arithmatex (``generic: true``) leaves ``\\(...\\)`` / ``\\[...\\]`` in spans and
  divs; they are converted to MathML with ``latex2mathml``, which browsers render natively,
  so the site loads no MathJax.

``ARE_STATS_DOCS_FAST=1`` (the default test's strict build) skips the first two costly steps:
figures are not drawn (every ``figures/NAME.png`` a page names must still be one that
``make_figures.FIGURES`` draws for that page; the image is left out) and notebooks are
rendered unexecuted. ``make docs`` builds without it.
"""

from __future__ import annotations

import base64
import hashlib
import html
import os
import re
import shutil
import subprocess
import sys
import unicodedata
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
CACHE = DOCS / ".cache"
NOTEBOOKS = ROOT / "notebooks"
FIGURE_LINK = re.compile(r"!\[[^\]]*\]\((?:\.\./)*figures/([^)\s]+)\)")

sys.path.insert(0, str(DOCS))
from make_figures import FIGURES  # noqa: E402

_state: dict[str, Any] = {}


def _fast() -> bool:
    return os.environ.get("ARE_STATS_DOCS_FAST", "") not in ("", "0")


def _source_hash(*extra: Path) -> str:
    """Hash of the package's sources and data (and ``extra`` files): the cache key."""
    h = hashlib.sha256()
    files = sorted(
        p for p in (ROOT / "are_stats").rglob("*") if p.is_file() and "__pycache__" not in p.parts
    )
    for p in [*files, *extra]:
        h.update(str(p.relative_to(ROOT)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


# --------------------------------------------------------------------------- figures


def _figures() -> Path:
    """The folder of drawn figures for this source hash, drawing it if not cached."""
    folder = CACHE / "figures" / _source_hash(DOCS / "make_figures.py")
    if all((folder / n).is_file() for n in FIGURES):
        return folder
    tmp = folder.with_name(folder.name + ".tmp")
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    res = subprocess.run(
        [sys.executable, str(DOCS / "make_figures.py"), str(tmp)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    if res.returncode != 0:
        raise RuntimeError(f"docs/make_figures.py failed:\n{res.stdout}\n{res.stderr}")
    for old in folder.parent.iterdir():  # earlier sources' figures, a half-written folder
        if old != tmp:
            shutil.rmtree(old)
    tmp.rename(folder)
    return folder


# --------------------------------------------------------------------------- notebooks


def _execute(path: Path) -> Any:
    """The notebook executed top to bottom (cached by its content and the package's)."""
    import nbformat

    cached = CACHE / "notebooks" / f"{path.stem}-{_source_hash(path)}.ipynb"
    if cached.is_file():
        return nbformat.read(cached, as_version=4)
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    saved = dict(os.environ)
    # the inline backend draws the figures; the quick settings keep the build short
    os.environ.pop("MPLBACKEND", None)
    os.environ["ARE_STATS_NOTEBOOK_QUICK"] = "1"
    os.environ["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT), *filter(None, [saved.get("PYTHONPATH")])]
    )
    try:
        NotebookClient(
            nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}
        ).execute()
    except Exception as err:  # CellExecutionError names the cell and the traceback
        raise RuntimeError(
            f"{path.relative_to(ROOT)}: a cell failed while building the docs\n{err}"
        ) from None
    finally:
        os.environ.clear()
        os.environ.update(saved)
    cached.parent.mkdir(parents=True, exist_ok=True)
    for old in cached.parent.glob(f"{path.stem}-*.ipynb"):
        old.unlink()
    nbformat.write(nb, cached)
    return nb


def _fence(text: str, lang: str = "text") -> str:
    ticks = "```"
    while ticks in text:
        ticks += "`"
    return f"{ticks}{lang}\n{text.rstrip()}\n{ticks}\n"


def _notebook_page(path: Path, nb: Any, executed: bool) -> tuple[str, dict[str, bytes]]:
    """Markdown for one notebook and its output images ``{name: png bytes}``."""
    parts: list[str] = []
    images: dict[str, bytes] = {}
    if executed:
        note = "executed when these pages were built (`ARE_STATS_NOTEBOOK_QUICK=1`: small runs)"
    else:
        note = "shown without outputs (fast build, `ARE_STATS_DOCS_FAST=1`)"
    parts.append(f'!!! note "`notebooks/{path.name}`"\n    This notebook was {note}.\n')
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown":
            parts.append(cell.source + "\n")
            continue
        if cell.cell_type != "code" or not cell.source.strip():
            continue
        parts.append(_fence(cell.source, "python"))
        shown: set[bytes] = set()
        for j, out in enumerate(cell.get("outputs", [])):
            kind = out.get("output_type")
            if kind == "stream":
                parts.append(_fence(out.get("text", "")))
            elif kind == "error":
                raise RuntimeError(f"{path.name}: cell {i} raised {out.get('ename')}")
            elif kind in ("display_data", "execute_result"):
                data = out.get("data", {})
                if "image/png" in data:
                    png = base64.b64decode(data["image/png"])
                    if png in shown:  # a returned figure is also flushed by the inline backend
                        continue
                    shown.add(png)
                    name = f"{path.stem}_{i}_{j}.png"
                    images[name] = png
                    parts.append(f"![output of cell {i}]({name})\n")
                elif "text/html" in data:
                    body = "\n".join(ln for ln in data["text/html"].splitlines() if ln.strip())
                    parts.append(f'<div class="nb-output">\n{body}\n</div>\n')
                elif "text/plain" in data:
                    parts.append(_fence(data["text/plain"]))
    return "\n".join(parts), images


# --------------------------------------------------------------------------- math

_ARITH = re.compile(r'<(span|div) class="arithmatex">(.*?)</\1>', re.S)
_VARIANT = re.compile(r'<mi mathvariant="(bold|script|double-struck|fraktur)">([A-Za-z])</mi>')
_UNICODE_NAME = {
    "bold": "BOLD",
    "script": "SCRIPT",
    "double-struck": "DOUBLE-STRUCK",
    "fraktur": "FRAKTUR",
}
# letters whose styled forms live in the Letterlike Symbols block
_LETTERLIKE = {
    ("script", "B"): "\u212c",
    ("script", "E"): "\u2130",
    ("script", "F"): "\u2131",
    ("script", "H"): "\u210b",
    ("script", "I"): "\u2110",
    ("script", "L"): "\u2112",
    ("script", "M"): "\u2133",
    ("script", "R"): "\u211b",
    ("script", "e"): "\u212f",
    ("script", "g"): "\u210a",
    ("script", "o"): "\u2134",
    ("double-struck", "C"): "\u2102",
    ("double-struck", "H"): "\u210d",
    ("double-struck", "N"): "\u2115",
    ("double-struck", "P"): "\u2119",
    ("double-struck", "Q"): "\u211a",
    ("double-struck", "R"): "\u211d",
    ("double-struck", "Z"): "\u2124",
    ("fraktur", "C"): "\u212d",
    ("fraktur", "H"): "\u210c",
    ("fraktur", "I"): "\u2111",
    ("fraktur", "R"): "\u211c",
    ("fraktur", "Z"): "\u2128",
}


def _styled_letter(m: re.Match) -> str:
    """``<mi mathvariant="script">M</mi>`` as the Unicode letter (MathML Core browsers
    ignore mathvariant other than normal)."""
    variant, ch = m.group(1), m.group(2)
    char = _LETTERLIKE.get((variant, ch))
    if char is None:
        case = "CAPITAL" if ch.isupper() else "SMALL"
        char = unicodedata.lookup(f"MATHEMATICAL {_UNICODE_NAME[variant]} {case} {ch.upper()}")
    return f'<mi mathvariant="normal">{char}</mi>'


def latex_to_mathml(tex: str, display: bool, where: str) -> str:
    """One formula to MathML; an error names the page and the formula."""
    from latex2mathml.converter import convert

    try:
        out = convert(tex, display="block" if display else "inline")
    except Exception as err:
        raise ValueError(f"{where}: cannot convert the formula {tex!r} to MathML: {err}") from None
    return _VARIANT.sub(_styled_letter, out)


def math_to_mathml(content: str, where: str) -> str:
    """Replace arithmatex's generic spans/divs in a page's HTML by MathML."""

    def one(m: re.Match) -> str:
        tex = html.unescape(m.group(2)).strip()
        display = m.group(1) == "div"
        opener, closer = ("\\[", "\\]") if display else ("\\(", "\\)")
        if not (tex.startswith(opener) and tex.endswith(closer)):
            raise ValueError(f"{where}: unexpected arithmatex output {m.group(0)[:80]!r}")
        mathml = latex_to_mathml(tex[2:-2].strip(), display, where)
        return f'<div class="math">{mathml}</div>' if display else mathml

    return _ARITH.sub(one, content)


# --------------------------------------------------------------------------- mkdocs events


def on_config(config: Any) -> Any:
    _state["figures"] = None if _fast() else _figures()
    _state["notebooks"] = sorted(NOTEBOOKS.glob("*.ipynb"))
    return config


def on_files(files: Files, config: Any) -> Files:
    folder = _state["figures"]
    if folder is not None:
        for name in FIGURES:
            files.append(File.generated(config, f"figures/{name}", abs_src_path=str(folder / name)))
    for path in _state["notebooks"]:
        executed = not _fast()
        nb = _execute(path) if executed else _read(path)
        page, images = _notebook_page(path, nb, executed)
        files.append(File.generated(config, f"notebooks/{path.stem}.md", content=page))
        for name, data in images.items():
            files.append(File.generated(config, f"notebooks/{name}", content=data))
    return files


def _read(path: Path) -> Any:
    import nbformat

    return nbformat.read(path, as_version=4)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    src = page.file.src_uri

    def check(m: re.Match) -> str:
        name = m.group(1)
        if name not in FIGURES:
            raise ValueError(
                f"docs/src/{src}: figures/{name} is not a figure that docs/make_figures.py "
                f"draws (FIGURES: {sorted(FIGURES)})"
            )
        if FIGURES[name][0] != src:
            raise ValueError(
                f"docs/src/{src}: figures/{name} belongs to {FIGURES[name][0]} "
                "in docs/make_figures.py FIGURES"
            )
        return m.group(0) if _state["figures"] is not None else ""

    return FIGURE_LINK.sub(check, markdown)


def on_page_content(content: str, page: Any, config: Any, files: Files) -> str:
    return math_to_mathml(content, f"docs/src/{page.file.src_uri}")


_VERBATIM = re.compile(r"(<(pre|code|script|style|textarea)\b.*?</\2>)", re.S)
_TEXT_MATH = re.compile(r"\\\((.+?)\\\)", re.S)


def on_post_page(output: str, page: Any, config: Any) -> str:
    """Math left as text outside the page body (the table of contents and the navigation
    show headings as text, ``\\(...\\)`` included) becomes MathML too."""
    where = f"docs/src/{page.file.src_uri}"
    parts = _VERBATIM.split(output)
    # split keeps two groups per match: the verbatim block and its tag name
    out = []
    for i, part in enumerate(parts):
        if i % 3 == 0:
            part = _TEXT_MATH.sub(
                lambda m: latex_to_mathml(html.unescape(m.group(1)).strip(), False, where), part
            )
        elif i % 3 == 2:
            continue
        out.append(part)
    return "".join(out)


def on_post_build(config: Any) -> None:
    """Every figure of ``FIGURES`` is shown on its page (in a full build)."""
    if _state["figures"] is None:
        return
    site = Path(config["site_dir"])
    for name, (page, _) in FIGURES.items():
        index = site / page.removesuffix(".md") / "index.html"
        if index.is_file() and f"figures/{name}" not in index.read_text():
            raise ValueError(
                f"docs/src/{page} does not show figures/{name}, which "
                "docs/make_figures.py draws for it"
            )
