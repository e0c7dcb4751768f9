"""Sinusoidal signal models (jitterid.systems.tones): SineWave and MultiTone.

Referees: the generic quadrature path of the model protocol (the same signal wrapped as a
SignalModel, whose moments are quadratures over the jitter at nodes), central differences
of the closed-form moments, and brute force over jitter draws.
"""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji
from jitterid.moments.sample import moment_pass

T = 1.0


def _as_generic(model, theta):
    """The same s(t; theta) as a SignalModel: the moments then take the quadrature path."""
    sig = model.signal(theta)

    def fun(t, th):
        return model.signal(th)(t)

    def grad(t, th):
        return model.signal(th).gradient(t)

    def slope(t, th):
        return model.signal(th).slope(t)

    return ji.SignalModel(
        fun, model.param_names, starts=[theta], rate=sig.rate, gradient=grad, slope=slope
    ).signal(theta)


CASES = [
    (ji.SineWave(), [1.5, 0.4, 0.23, 0.3]),
    (ji.SineWave(form="iq"), [0.7, -1.1, 0.61, -0.2]),  # above Nyquist
    (ji.SineWave(harmonics=3), [1.0, 0.2, 0.1, -0.5, 0.05, 2.0, 0.17, 0.0]),
    (ji.SineWave(frequency_hz=0.14), [2.0, 1.0, 0.1]),
    (ji.MultiTone([0.05, 0.21, 0.33]), [1.0, 0.1, 0.5, 2.0, 0.3, -1.0, 0.2]),
]
LAWS = [ji.Uniform(0.4), ji.Gaussian(0.3), ji.SumOfUniforms(2, 0.5), ji.NoJitter()]


@pytest.mark.parametrize("law", LAWS, ids=str)
@pytest.mark.parametrize(
    ("model", "theta"), CASES, ids=lambda c: getattr(c, "param_names", [""])[0]
)
def test_closed_form_moments_match_the_quadrature_path(model, theta, law):
    N = 40
    closed = moment_pass(model.signal(theta), law, T, N, gradient=True, scale=0.5)
    generic = moment_pass(_as_generic(model, theta), law, T, N, gradient=True, scale=0.5)
    assert closed.dmean is not None
    assert generic.dmean is not None
    for a, b in [
        (closed.mean, generic.mean),
        (closed.var, generic.var),
        (closed.dmean, generic.dmean),
        (closed.dvar, generic.dvar),
        (closed.scale_mean, generic.scale_mean),
        (closed.scale_var, generic.scale_var),
    ]:
        np.testing.assert_allclose(a, b, atol=1e-9 * (1 + np.max(np.abs(b))))


@pytest.mark.parametrize(("model", "theta"), CASES[:3], ids=["polar", "iq", "harmonics"])
def test_closed_form_derivatives_match_central_differences(model, theta):
    law, N = ji.Gaussian(0.25), 30
    theta = np.asarray(theta, float)
    mp = moment_pass(model.signal(theta), law, T, N, gradient=True)
    for i in range(theta.size):
        h = 1e-6 * max(1.0, abs(theta[i]))
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        a, b = (moment_pass(model.signal(v), law, T, N) for v in (up, dn))
        dm, dv = (a.mean - b.mean) / (2 * h), (a.var - b.var) / (2 * h)
        np.testing.assert_allclose(mp.dmean[i], dm, atol=1e-7 * (1 + np.max(np.abs(dm))))
        np.testing.assert_allclose(mp.dvar[i], dv, atol=1e-7 * (1 + np.max(np.abs(dv))))
    # the jitter scale: the law of a xi, a = sigma
    a = 0.25
    mp = moment_pass(model.signal(theta), law, T, N, scale=a)
    up, dn = (moment_pass(model.signal(theta), ji.Gaussian(v), T, N) for v in (a + 1e-6, a - 1e-6))
    np.testing.assert_allclose(mp.scale_mean, (up.mean - dn.mean) / 2e-6, atol=1e-6)
    np.testing.assert_allclose(mp.scale_var, (up.var - dn.var) / 2e-6, atol=1e-6)


def test_moments_match_brute_force_over_jitter_draws():
    model, theta = ji.SineWave(harmonics=2), [1.0, 0.3, 0.4, 1.0, 0.31, 0.2]
    law, N, R = ji.Uniform(0.6), 12, 200_000
    rng = np.random.default_rng(5)
    tau = law.sample((R, N), rng)
    s = model.signal(theta)(T * np.arange(N) + tau)
    mom = ji.sample_moments(model.signal(theta), law, T, N)
    se_m = s.std(axis=0) / np.sqrt(R)
    assert np.all(np.abs(s.mean(axis=0) - mom.mean) < 4.5 * se_m)
    se_v = np.sqrt(np.var((s - s.mean(axis=0)) ** 2, axis=0) / R)
    assert np.all(np.abs(s.var(axis=0) - mom.var) < 4.5 * se_v)


def test_gradient_and_slope_match_differences_of_the_signal():
    model, theta = ji.SineWave(harmonics=2, form="iq"), np.array([0.5, 1.0, 0.3, -0.2, 0.27, 0.1])
    t = np.linspace(0, 20, 17)
    sig = model.signal(theta)
    G = sig.gradient(t)
    for i in range(theta.size):
        up, dn = theta.copy(), theta.copy()
        up[i] += 1e-6
        dn[i] -= 1e-6
        np.testing.assert_allclose(
            G[i], (model.signal(up)(t) - model.signal(dn)(t)) / 2e-6, atol=1e-6
        )
    np.testing.assert_allclose(sig.slope(t), (sig(t + 1e-6) - sig(t - 1e-6)) / 2e-6, atol=1e-6)


def test_bad_arguments_name_the_fix():
    with pytest.raises(ValueError, match="form"):
        ji.SineWave(form="cartesian")
    with pytest.raises(ValueError, match="harmonics"):
        ji.SineWave(harmonics=0)
    with pytest.raises(ValueError, match="band_hz"):
        ji.SineWave(band_hz=(0.5, 0.1))
    with pytest.raises(ValueError, match="either"):
        ji.SineWave(frequency_hz=1.0, band_hz=(0.1, 2.0))
    with pytest.raises(ValueError, match="distinct"):
        ji.MultiTone([0.1, 0.1])
    with pytest.raises(ValueError, match="frequency_hz"):
        ji.SineWave().signal([1.0, 0.0, -0.2, 0.0])


def test_simulate_samples_a_signal_model_at_jittered_instants():
    theta, law, N = [1.2, 0.3, 0.61, 0.1], ji.Uniform(0.3), 50
    d = ji.simulate(ji.SineWave().signal(theta), None, law, T, N, 0.01, 4)
    gen = np.random.default_rng(4)
    tau = law.sample(N, gen)
    t = np.arange(N) * T + tau
    y = 1.2 * np.sin(2 * np.pi * 0.61 * t + 0.3) + 0.1 + 0.01 * gen.standard_normal(N)
    np.testing.assert_allclose(d.y, y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.instants, t)
    assert d.u is None
    with pytest.raises(ValueError, match="u must be None"):
        ji.simulate(ji.SineWave().signal(theta), ji.telegraph_input(100.0, 1), law, T, N, 0.01, 4)
    with pytest.raises(TypeError, match="Signal"):
        ji.simulate(ji.SineWave(), None, law, T, N, 0.01, 4)


@pytest.mark.parametrize(
    ("model", "theta"),
    [
        (ji.SineWave(harmonics=2), [1.0, 0.3, 0.4, 1.0, 0.31, 0.2]),
        (ji.SineWave(form="iq"), [0.7, -1.1, 0.61, -0.2]),
        (ji.MultiTone([0.05, 0.21]), [1.0, 0.1, 0.5, 2.0, 0.3]),
    ],
    ids=["polar-harmonics", "iq", "multitone"],
)
def test_second_derivatives_match_differences_of_the_gradient_and_slope(model, theta):
    theta = np.asarray(theta, float)
    t = np.linspace(0, 15, 23)
    hess, dslope, curv = model.signal(theta).second_derivatives(t)
    for i in range(theta.size):
        up, dn = theta.copy(), theta.copy()
        up[i] += 1e-6
        dn[i] -= 1e-6
        su, sd = model.signal(up), model.signal(dn)
        np.testing.assert_allclose(hess[i], (su.gradient(t) - sd.gradient(t)) / 2e-6, atol=1e-5)
        np.testing.assert_allclose(dslope[i], (su.slope(t) - sd.slope(t)) / 2e-6, atol=1e-5)
    sig = model.signal(theta)
    np.testing.assert_allclose(curv, (sig.slope(t + 1e-6) - sig.slope(t - 1e-6)) / 2e-6, atol=1e-5)
