"""The closed-form moments of a sum of tones (jitterid.systems.tones, (S1)-(S2)) in a jitter
family's shape parameters: the derivative pass integrates the signed measure dp/dtheta
(mass 0) in place of the law, so the closed form must not take its mass for 1.

Before this was fixed the pass returned the tone's offset c as dm (c times a mass of one)
and a clipped "variance" as dVar: on a 12-bit converter record (three harmonics, a Gaussian
scale mixture) the Gaussian criterion's gradient in rho was 6.6e6 where central differences
of the criterion give 4e-4, its search stopped "damping exhausted" at its start, and the
meter's restart from there ran for more than 7 CPU-minutes.

Referees: central differences of the moments (the law itself, not its derivative, at two
nearby parameters), and the node route of jitterid.moments.sample (the same sums at
quadrature nodes, no closed form).
"""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.jacobians import _PdfDerivative
from jitterid.estimation.problem import Problem
from jitterid.moments.sample import moment_pass

T = 1.0
N = 48

FAMILIES = {
    "mix": (ji.GaussianScaleMixtureFamily(sigma_max=1.0), [0.12, 0.6]),
    "dd": (ji.DualDiracFamily(rj_max=1.0, dj_max=1.0), [0.06, 0.2]),
    "gn": (ji.GeneralizedNormalFamily(std_max=1.0), [0.12, 2.7]),
    "sum-of-uniforms": (ji.SumOfUniformsFamily(), [1.6, 0.25]),
}
fam_param = pytest.mark.parametrize(("family", "jp"), list(FAMILIES.values()), ids=list(FAMILIES))


def _tone(harmonics: int) -> tuple[ji.SineWave, np.ndarray]:
    """A tone at 0.23 Hz (phase spread 2 pi f std ~ 0.17 rad), offset 0.3, and its
    parameters after the jitter's."""
    theta = [1.5, 0.4]
    for h in range(2, harmonics + 1):
        theta += [0.2 / h, 0.3 * h]
    return ji.SineWave(harmonics=harmonics), np.array([*theta, 0.23, 0.3])


def _check_jitter_derivatives(prob: Problem, x: np.ndarray, nj: int) -> None:
    """dm, dVar in the first ``nj`` (jitter) parameters against central differences of the
    moments. The shape's effect is second order in the phase spread: the scale of the check
    is the derivative itself, not the moments (the defect put the offset 0.3 into dm)."""
    _, _, dm, dw = prob.derivatives(x)
    for i in range(nj):
        h = 1e-5 * abs(x[i])
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        mu, md = prob.moments(up), prob.moments(down)
        fd_m = (mu.mean - md.mean) / (2 * h)
        fd_w = (mu.var - md.var) / (2 * h)
        np.testing.assert_allclose(dm[i], fd_m, rtol=0, atol=1e-4 * np.abs(fd_m).max() + 1e-9)
        np.testing.assert_allclose(dw[i], fd_w, rtol=0, atol=1e-4 * np.abs(fd_w).max() + 1e-9)


@fam_param
@pytest.mark.parametrize("harmonics", [1, 3])
def test_moment_derivatives_in_the_shape_against_differences(family, jp, harmonics):
    model, theta = _tone(harmonics)
    data = ji.SampledData(np.linspace(-1.0, 1.0, N), T, None)
    prob = Problem(data, model, family, "gaussian", ji.default_frequencies(N, T), 0.05)
    x = np.r_[jp, theta]
    _check_jitter_derivatives(prob, x, len(jp))


@fam_param
def test_a_signed_measure_has_the_node_routes_sums(family, jp):
    """sum w s and sum w (s - m)^2 over dp/dtheta: the closed form against the quadrature
    nodes of the same measure (the node route, asked for by requesting higher moments)."""
    model, theta = _tone(3)
    sig = model.signal(theta, None)
    law = family.law(jp)
    for i in range(len(jp)):
        dlaw = _PdfDerivative(family, list(jp), law, i)
        assert dlaw.mass == 0.0
        assert law.mass == 1.0
        closed = sig.jitter_moments(dlaw, T, N)
        assert closed is not None
        nodes = moment_pass(sig, dlaw, T, N, higher=True)  # (higher: no closed form)
        assert closed.var is not None
        assert nodes.var is not None
        # (the node route's panels hold ~1e-9 of these sums, of size 0.5; the defect was the
        # offset 0.3 in every mean)
        np.testing.assert_allclose(closed.mean, nodes.mean, rtol=0, atol=1e-7)
        np.testing.assert_allclose(closed.var, nodes.var, rtol=0, atol=1e-7)


def test_the_meters_gaussian_start_moves_in_the_shape():
    """The record of the defect, shortened: the Gaussian criterion with the scale mixture and
    three harmonics from the meter's start converges (it stopped at the start)."""
    rng = np.random.default_rng(8000)
    TS, SJ = 1e-9, 2e-12
    f = 97.123e6 + rng.uniform(-1e5, 1e5)
    n = 1024
    scale = np.where(rng.random(n) < 0.5, np.sqrt(0.1), np.sqrt(1.9))
    ph = 2 * np.pi * f * (np.arange(n) * TS + SJ * scale * rng.standard_normal(n)) + 0.7
    y = 0.45 * np.sin(ph) + 0.01 + 0.45e-3 * np.sin(3 * ph + 0.3) + 0.45 * 10 ** (-3.3)
    y = y + 0.45 * 10 ** (-66 / 20) * np.sin(2 * ph + 1) + 30e-6 * rng.standard_normal(n)
    lsb = 2.0**-12
    y = lsb * np.round(y / lsb)
    data = ji.SampledData(y, TS, None)
    model = ji.SineWave(harmonics=3)
    fit = ji.fit(data, model, ji.GaussianScaleMixtureFamily(), method="gaussian")
    assert fit.status is ji.FitStatus.CONVERGED, fit.message
    assert 0.7 < fit.jitter_law.std / SJ < 1.3


@fam_param
def test_a_steady_state_multisine_response_too(family, jp):
    """The LTI response to a steady-state multisine takes the same closed form
    (jitterid.systems.tf.Response.jitter_moments): its shape derivatives against central
    differences of the moments."""
    u = ji.Multisine(
        [0.05, 0.13, 0.31], [1.0, 0.5, 0.3], end=1e9, phases=[0.1, 1.0, 2.0], steady_state=True
    )
    data = ji.SampledData(np.linspace(-1.0, 1.0, N), T, u)
    prob = Problem(data, ji.PolePairGain(), family, "gaussian", ji.default_frequencies(N, T), 0.05)
    x = np.r_[jp, 5.0, -1.0, 2.0]
    _check_jitter_derivatives(prob, x, len(jp))
