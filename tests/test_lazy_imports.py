"""Imports inside functions say why they are lazy (issue 25: imports at the top of modules
unless a measured start-up cost needs them lazy).

An import in a function body passes when a comment on it, on the comment lines right above
its block of imports (adjacent, or apart by blank lines only), or on the line that opens that
block (``try:  # ...``) says
``lazy`` (with the cost measured), ``cycle`` or ``optional``. Checked: every module of the
package (the top-level modules and every room in :data:`ROOMS`).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import are_stats

#: The rooms whose modules are checked, besides the top-level modules.
ROOMS = (
    "traffic",
    "fitting",
    "behaviour",
    "scenarios",
    "environment",
    "logs",
    "builder",
    "perception",
    "experiments",
    "export",
)

_REASON = re.compile(r"\b(lazy|cycle|optional)\b", re.IGNORECASE)


def unjustified(source: str) -> list[int]:
    """The line numbers of the imports in ``source``'s function bodies that no comment
    justifies (see the module docstring)."""
    lines = source.splitlines()
    tree = ast.parse(source)
    bad = []
    for func in ast.walk(tree):
        if not isinstance(func, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        for node in ast.walk(func):
            for field in ("body", "orelse", "finalbody", "handlers"):
                block = getattr(node, field, None)
                if not isinstance(block, list):
                    continue
                group: list[ast.stmt] = []
                for stmt in [*block, None]:
                    is_import = isinstance(stmt, ast.Import | ast.ImportFrom)
                    # adjacent, or apart by the blank line between import sections
                    if is_import and (
                        not group
                        or not "".join(lines[group[-1].end_lineno : stmt.lineno - 1]).strip()
                    ):
                        group.append(stmt)
                        continue
                    if group:
                        first, last = group[0].lineno, group[-1].end_lineno
                        text = lines[first - 1 : last]
                        i = first - 2
                        while i >= 0 and lines[i].strip().startswith("#"):
                            text.append(lines[i])
                            i -= 1
                        if i >= 0 and "#" in lines[i]:  # the block's opening line
                            text.append(lines[i])
                        if not _REASON.search("\n".join(t for t in text if "#" in t)):
                            bad += [s.lineno for s in group]
                    group = [stmt] if is_import else []
    return sorted(set(bad))


def test_the_check_finds_an_import_without_a_reason():
    source = (
        "def f():\n"
        "    # lazy: scipy.ndimage adds 0.3 s CPU to `import x`\n"
        "    from scipy import ndimage\n"
        "\n"
        "    import json\n"
        "    x = 1\n"
        "    import os  # the environment\n"
        "    try:  # optional: the extra 'live'\n"
        "        import foxglove\n"
        "    except ImportError:\n"
        "        import csv\n"
        "    return ndimage, json, os, foxglove, csv, x\n"
    )
    assert unjustified(source) == [7, 11]  # os (a comment, no reason) and csv


def test_imports_in_functions_say_why_they_are_lazy():
    root = Path(are_stats.__file__).parent
    rooms = {p.parent.name for p in root.glob("*/__init__.py")}
    assert rooms == set(ROOMS), f"rooms not checked: {sorted(rooms - set(ROOMS))}"
    files = [*root.glob("*.py"), *(f for room in ROOMS for f in (root / room).rglob("*.py"))]
    bad = [
        f"{f.relative_to(root.parent)}:{n}"
        for f in sorted(files)
        for n in unjustified(f.read_text())
    ]
    assert not bad, f"imports in functions without a reason to be lazy: {bad}"
