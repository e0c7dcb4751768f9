"""Model structures' derivative protocol (jitterid.systems.structures): closed-form coefficient
derivatives against differences, and a reparameterised structure without them taking the
difference route with the analytic fit's answer."""

import numpy as np
import pytest
from helpers import table2_data

import jitterid as ji


# ------------------------------------------------------------------ derivative protocol
def _coefficient_differences(structure, theta, n):
    P = theta.size
    dnum, dden = np.zeros((P, n)), np.zeros((P, n))
    for i in range(P):
        h = 1e-6 * max(abs(theta[i]), 1.0)
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        a, b = structure.system(up), structure.system(down)
        pad = lambda c: np.r_[np.zeros(n - c.size), c]
        dnum[i] = (pad(a.num) - pad(b.num)) / (2 * h)
        dden[i] = (pad(a.den) - pad(b.den)) / (2 * h)
    return dnum, dden


@pytest.mark.parametrize(
    ("structure", "theta"),
    [
        (ji.PolePairGain(), np.array([6.25, -1.5, 2.0])),
        (ji.RationalModel(1, 3), np.array([0.5, 2.0, 3.0, 4.0, 2.0])),
    ],
)
def test_structures_coefficient_derivatives_against_differences(structure, theta):
    n = structure.system(theta).den.size
    closed = structure.coefficient_jacobian(theta, n)
    assert closed is not None
    ref = _coefficient_differences(structure, theta, n)
    for got, want in zip(closed, ref, strict=True):
        np.testing.assert_allclose(got, want, atol=1e-7)


def test_a_structure_without_derivatives_takes_the_declared_difference_route():
    """A reparameterised structure that does not override coefficient_jacobian: its parent's
    closed form belongs to another map, so the moments' sensitivities use differences of
    the new map (never the parent's formula), and the fit equals the analytic one's."""

    class LogGain(ji.PolePairGain):
        @property
        def param_names(self):
            return ("log_k0", "pr", "pi")

        @property
        def bounds(self):
            return ((-10.0, 10.0), *super().bounds[1:])

        def system(self, params):
            p = np.asarray(params, float)
            return super().system([np.exp(p[0]), p[1], p[2]])

        def starts(self, T):
            return [np.r_[np.log(s[0]), s[1:]] for s in super().starts(T)]

    data = table2_data(14)
    ref = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    res = ji.fit(data, LogGain(), ji.Uniform(0.5), "bcls")
    assert res.success
    np.testing.assert_allclose(np.exp(res.x[0]), ref.x[0], rtol=1e-5)
    np.testing.assert_allclose(res.x[1:], ref.x[1:], rtol=1e-5)
