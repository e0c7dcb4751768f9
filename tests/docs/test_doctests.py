"""The Examples sections of jitterid's docstrings run and print what they show (issue 14)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import matplotlib
import pytest

import jitterid

matplotlib.use("Agg")

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _modules() -> list[str]:
    names = [jitterid.__name__]
    for info in pkgutil.walk_packages(jitterid.__path__, prefix=jitterid.__name__ + "."):
        if ".cli" in info.name or info.name.endswith("__main__"):
            continue  # the command line entry points: exercised by tests/cli/
        names.append(info.name)
    return sorted(names)


MODULES = _modules()


@pytest.mark.parametrize("name", MODULES)
def test_module_doctests(name: str) -> None:
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in finder.find(module, name, globs=None):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} doctest failure(s) in {name}"


def test_there_are_examples() -> None:
    finder = doctest.DocTestFinder(exclude_empty=True)
    count = sum(
        len(t.examples)
        for name in MODULES
        for t in finder.find(importlib.import_module(name), name, globs=None)
    )
    assert count >= 20
