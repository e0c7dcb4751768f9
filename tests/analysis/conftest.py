"""Fixtures shared by the tests of jitterid.analysis."""

from __future__ import annotations

import pytest
from helpers import table2_data

import jitterid as ji


@pytest.fixture(scope="module")
def ls_fit() -> tuple[ji.SampledData, ji.FitResult]:
    """Table 2's data (seed 1) and its LS fit: a result to build bands and diagnostics on."""
    data = table2_data(1, ji.Uniform(0.5))
    return data, ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "ls")
