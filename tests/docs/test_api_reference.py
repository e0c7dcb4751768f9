"""Every public name of ``jitterid`` has a page in the API reference (docs/api.rst)."""

from __future__ import annotations

import re

from helpers import DOCS

import jitterid

API = DOCS / "api.rst"


def _listed() -> set[str]:
    """Names in the autosummary blocks under ``.. currentmodule:: jitterid``."""
    names: set[str] = set()
    module = None
    in_block = False
    for line in API.read_text().splitlines():
        m = re.match(r"\.\. currentmodule:: (\S+)", line)
        if m:
            module = m.group(1)
            continue
        if line.startswith(".. autosummary::"):
            in_block = True
            continue
        if in_block:
            if not line.strip() or line.strip().startswith(":"):
                continue
            if not line.startswith("   "):
                in_block = False
                continue
            if module == "jitterid" and "." not in line.strip():  # dotted: a submodule's
                names.add(line.strip())
    return names


def test_every_public_name_has_a_reference_page():
    missing = sorted(set(jitterid.__all__) - _listed())
    assert not missing, f"add these to docs/api.rst: {missing}"


def test_the_reference_names_only_public_names():
    stale = sorted(n for n in _listed() if n not in jitterid.__all__)
    assert not stale, f"docs/api.rst lists names that jitterid does not export: {stale}"
