"""The layout of tests/ (tests/README.md): folders mirror src/jitterid/'s subpackages, and
test-file basenames are unique across the tree."""

from __future__ import annotations

from collections import Counter

from helpers import REPO

TESTS = REPO / "tests"
PACKAGE = REPO / "src" / "jitterid"
EXTRA = {"docs", "benchmarks"}  # tests of the documents and of benchmarks/*.py


def test_every_test_folder_is_a_subpackage_or_docs_or_benchmarks():
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    parts = [p.relative_to(TESTS).parts for p in TESTS.rglob("test_*.py")]
    folders = {q[0] for q in parts if len(q) > 1}
    assert folders - EXTRA <= subpackages, sorted(folders - EXTRA - subpackages)
    assert not list(TESTS.rglob("__init__.py"))  # importlib mode: no packages


def test_test_file_basenames_are_unique():
    names = Counter(p.name for p in TESTS.rglob("test_*.py"))
    assert not [n for n, c in names.items() if c > 1]
