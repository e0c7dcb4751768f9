"""Inputs (jitterid.inputs): a zero-order hold is piecewise constant, the Fourier transform of
a piecewise-constant input against quadrature, and bad inputs refused naming the argument."""

import numpy as np
import pytest

from jitterid.inputs import PiecewiseConstant, telegraph_input, zoh_input


def test_zoh_input_is_piecewise_constant():
    u = zoh_input([1.0, -2.0, 3.0], T=0.5, start=1.0)
    np.testing.assert_array_equal(u(np.array([0.9, 1.0, 1.6, 2.2])), [0.0, 1.0, -2.0, 3.0])
    assert u.end == pytest.approx(2.5)


def test_fourier_transform_of_piecewise_constant_by_quadrature():
    u = PiecewiseConstant([0.0, 0.7, 2.0, 2.5], [1.0, -0.5, 2.0])
    t = np.linspace(0, 2.5, 250001)
    for psi in (0.0, 0.3, 1.7, -2.2):
        direct = np.trapezoid(u(t) * np.exp(-2j * np.pi * psi * t), t)
        assert u.fourier(np.array([psi]))[0] == pytest.approx(direct, abs=2e-5)


def test_bad_inputs():
    with pytest.raises(ValueError, match="strictly increasing"):
        PiecewiseConstant([0, 1, 1, 2], [1, 2, 3])
    with pytest.raises(ValueError, match="levels"):
        PiecewiseConstant([0, 1, 2], [1])
    with pytest.raises(TypeError, match="rng"):
        telegraph_input(5.0, None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="duration"):
        telegraph_input(-1.0, 0)
