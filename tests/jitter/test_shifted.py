"""Jitter with a non-zero mean (jitterid.jitter.laws.Shifted): density, support and
characteristic function of the shifted law against the centred one, and bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji


# ---------------------------------------------------------------------------- Shifted law
def test_shifted_law_moves_density_support_and_characteristic_function() -> None:
    base = ji.Uniform(0.5)
    law = ji.Shifted(base, 0.2)
    assert law.support == pytest.approx((-0.3, 0.7))
    assert law.mean == pytest.approx(0.2)
    assert law.var == pytest.approx(base.var)
    np.testing.assert_allclose(law.pdf([0.65, 0.75, -0.25]), [1.0, 0.0, 1.0])
    # cf against a quadrature of the density itself (an independent route)
    f = np.array([0.0, 0.3, 1.1])
    tau = np.linspace(-0.3, 0.7, 200_001)
    direct = np.trapezoid(
        law.pdf(tau)[None, :] * np.exp(-2j * np.pi * f[:, None] * tau), tau, axis=1
    )
    np.testing.assert_allclose(law.cf(f), direct, atol=1e-8)
    draws = law.sample(200_000, np.random.default_rng(0))
    assert abs(draws.mean() - 0.2) < 4 * base.std / np.sqrt(draws.size)
    assert draws.min() >= -0.3
    assert draws.max() <= 0.7
    # nested shifts flatten; the parameters name the offset
    nested = ji.Shifted(law, -0.05)
    assert nested.law == base
    assert nested.mean_s == pytest.approx(0.15)
    assert law.params == {"a": 0.5, "mean_s": 0.2}


@pytest.mark.parametrize(
    ("args", "error", "match"),
    [
        ((0.5, 0.1), TypeError, "law must be a jitter law"),
        ((ji.Uniform(0.5), float("nan")), ValueError, "mean_s must be finite"),
        ((ji.Uniform(0.5), "x"), TypeError, "mean_s must be a real number"),
    ],
)
def test_shifted_law_refuses_bad_arguments(args: tuple, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        ji.Shifted(*args)
