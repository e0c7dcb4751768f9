"""A fit's result reaches its analysis through the registry that jitterid.analysis fills
(estimation imports nothing above it: tests/test_layers.py)."""

from __future__ import annotations

import pytest

import jitterid as ji
from jitterid.estimation.hooks import analysis, register_analysis


@pytest.mark.parametrize(
    "name",
    [
        "bode_band",
        "detect_jitter",
        "impulse_response",
        "jitter_pdf_band",
        "physical_quantities",
        "step_response",
    ],
)
def test_the_analysis_package_registers_what_a_result_reaches(name: str) -> None:
    assert analysis(name) is getattr(ji, name)


def test_an_unregistered_name_is_refused_with_the_registered_ones() -> None:
    with pytest.raises(LookupError, match=r"no analysis function 'nonesuch'.*step_response"):
        analysis("nonesuch")


def test_only_callables_are_registered() -> None:
    with pytest.raises(TypeError, match="functions must be callables"):
        register_analysis(42)  # type: ignore[arg-type]
