"""Every docstring example in the package runs and prints what it says.

The examples are part of the documentation (the API pages render them), so they are run
here as the other tests are: one test per module that has examples, with the doctest
options the package's examples are written for. ``# doctest: +SKIP`` marks the few that
need a display, a network port or minutes of sampling.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import are_stats

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _modules() -> list[str]:
    names = ["are_stats"]
    for info in pkgutil.walk_packages(are_stats.__path__, "are_stats."):
        if info.name.endswith("__main__"):
            continue
        names.append(info.name)
    return names


def _with_examples(name: str) -> bool:
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    return any(t.examples for t in finder.find(module, name, module=module))


MODULES = [n for n in _modules() if _with_examples(n)]


def test_the_package_has_examples():
    # a guard against the finder silently finding nothing (a broken walk or import)
    assert len(MODULES) >= 30


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in finder.find(module, name, module=module):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
