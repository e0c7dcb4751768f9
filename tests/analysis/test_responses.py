"""Step and impulse responses of a fit with bands, and their plot.

Referees: a fine-step ODE solution (scipy.integrate.solve_ivp on a companion form written out
here), the closed-form step response of the pole pair (27) over parameter draws (Monte Carlo
of the delta band), and the sampling band.
"""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import jitterid as ji
from jitterid import plots
from jitterid.analysis.responses import lti_response

TRUTH = np.array([6.25, -1.5, 2.0])  # the paper's (27)
C_SMALL = np.array([[4e-3, -8e-4, 2e-4], [-8e-4, 2.5e-4, -1e-5], [2e-4, -1e-5, 6e-5]])


def fit_of(structure, theta, cov=None, cov_type="sandwich") -> ji.FitResult:
    """A FitResult at ``theta`` with covariance ``cov``, built directly (no data needed)."""
    theta = np.asarray(theta, float)
    cov = np.zeros((theta.size, theta.size)) if cov is None else np.asarray(cov, float)
    return ji.FitResult(
        "bcls",
        tuple(structure.param_names),
        theta,
        0.0,
        ji.FitStatus.CONVERGED,
        "",
        0,
        structure.system(theta),
        ji.NoJitter(),
        0.01,
        np.zeros(0),
        cov,
        cov_type,
        structure,
        ji.NoJitter(),
    )


def sine_fit() -> ji.FitResult:
    """A fit of a signal model (no transfer function)."""
    sine = ji.SignalModel(
        lambda t, th: th[0] * np.sin(2 * np.pi * 0.1 * t),
        param_names=("A",),
        starts=[(1.0,)],
        rate=2 * np.pi * 0.1,
    )
    t = np.arange(60.0)
    y = 1.5 * np.sin(2 * np.pi * 0.1 * t) + 0.05 * np.random.default_rng(0).standard_normal(60)
    return ji.fit(ji.SampledData(y, T=1.0), sine, ji.NoJitter(), method="ls")


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def ode_response(num, den, t, kind):
    """y(t) by integrating x' = A x + B u in controllable canonical form (written out here,
    not scipy's tf2ss) with tight tolerances; the impulse starts from x(0) = B, u = 0."""
    den = np.asarray(den, float) / den[0]
    num = np.asarray(num, float) / 1.0
    n = den.size - 1
    num = np.r_[np.zeros(n + 1 - num.size), num] / 1.0
    d = num[0] / 1.0
    c = (num - d * den)[1:]  # strictly proper part, s^(n-1) .. s^0
    A = np.zeros((n, n))
    A[0, :] = -den[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros(n)
    B[0] = 1.0
    u = 1.0 if kind == "step" else 0.0
    x0 = np.zeros(n) if kind == "step" else B
    sol = solve_ivp(
        lambda _t, x: A @ x + B * u,
        (0.0, float(t[-1])),
        x0,
        t_eval=t,
        method="DOP853",
        rtol=1e-11,
        atol=1e-13,
        max_step=0.01,
    )
    return c @ sol.y + (d if kind == "step" else 0.0)


SYSTEMS = {
    "pole pair (27)": ([6.25], [1.0, 3.0, 6.25]),
    "biproper, zero": ([0.5, 2.0, 3.0], [1.0, 3.0, 2.0]),
    "third order": ([2.0, 6.0], list(np.polymul([1.0, 1.0], [1.0, 2.0, 5.0]))),
    "repeated pole": ([1.0, 3.0], [1.0, 2.0, 1.0]),  # (s + 1)^2: the matrix-exponential path
    "integrator": ([1.0], [1.0, 1.0, 0.0]),
    "unstable": ([1.0], [1.0, -0.3]),
}


@pytest.mark.parametrize("kind", ["step", "impulse"])
@pytest.mark.parametrize("name", list(SYSTEMS))
def test_response_against_a_fine_step_ode_solution(name, kind):
    num, den = SYSTEMS[name]
    t = np.linspace(0.0, 6.0, 121)
    mine = lti_response(ji.TransferFunction(num, den), t, kind)
    ref = ode_response(num, den, t, kind)
    np.testing.assert_allclose(mine, ref, rtol=1e-8, atol=1e-9)


def test_near_repeated_poles_agree_on_both_routes():
    """Poles 1e-5 apart (below the modal threshold) against 1e-3 apart (modal): continuous."""
    t = np.linspace(0, 5, 51)
    a = lti_response(ji.TransferFunction([1.0], np.poly([-1.0, -1.0 - 1e-5]).real), t)
    b = lti_response(ji.TransferFunction([1.0], np.poly([-1.0, -1.0 - 1e-3]).real), t)
    np.testing.assert_allclose(a, b, atol=1e-3)
    np.testing.assert_allclose(
        a, ode_response([1.0], np.poly([-1.0, -1.0 - 1e-5]), t, "step"), atol=1e-9
    )


# ------------------------------------------------------------------------------ bands


def pair_step(k0, pr, pi, t):
    """The step response of k0 / ((s - pr)^2 + pi^2) in closed form, broadcast over draws."""
    e = np.exp(pr * t)
    return k0 / (pr**2 + pi**2) * (1 - e * (np.cos(pi * t) - pr / pi * np.sin(pi * t)))


def test_delta_band_against_a_monte_carlo_of_the_response():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    t = np.linspace(0.0, 5.0, 41)
    band = ji.step_response(res, t, 0.9)
    np.testing.assert_allclose(band.response, pair_step(*TRUTH, t), atol=1e-12)
    k0, pr, pi = np.random.default_rng(2).multivariate_normal(TRUTH, C_SMALL, 100_000).T[:, :, None]
    mc = pair_step(k0, pr, pi, t)
    z = 1.6448536269514722
    half = (band.hi - band.lo) / 2
    np.testing.assert_allclose(half[1:], z * mc.std(axis=0)[1:], rtol=0.03)
    assert band.lo[0] == band.hi[0] == 0.0  # from rest: no uncertainty at t = 0
    lo, hi = np.quantile(mc, [0.05, 0.95], axis=0)
    np.testing.assert_allclose(band.lo[1:], lo[1:], atol=0.05 * half.max())
    np.testing.assert_allclose(band.hi[1:], hi[1:], atol=0.05 * half.max())


@pytest.mark.parametrize("kind", ["step", "impulse"])
def test_delta_and_sampling_bands_agree_where_the_linearisation_is_good(kind):
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    t = np.linspace(0.0, 5.0, 51)
    delta = getattr(ji, f"{kind}_response")(res, t)
    draws = getattr(ji, f"{kind}_response")(res, t, method="sampling", draws=4000, rng=1)
    assert (delta.method, draws.method, delta.kind, draws.kind) == ("delta", "sampling", kind, kind)
    np.testing.assert_array_equal(delta.response, draws.response)
    width = np.max(delta.hi - delta.lo)
    np.testing.assert_allclose(draws.lo, delta.lo, atol=0.05 * width)
    np.testing.assert_allclose(draws.hi, delta.hi, atol=0.05 * width)


def test_band_is_immutable_and_the_result_methods_delegate():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    t = np.linspace(0, 3, 7)
    band = res.step_response(t, 0.8)
    ref = ji.step_response(res, t, 0.8)
    np.testing.assert_array_equal(band.hi, ref.hi)
    assert band.level == 0.8
    with pytest.raises(ValueError, match="read-only"):
        band.response[0] = 1.0
    with pytest.raises(AttributeError):
        band.kind = "impulse"  # type: ignore[misc]
    imp = res.impulse_response(t, method="sampling", draws=200, rng=0)
    assert imp.kind == "impulse"
    assert imp.method == "sampling"


def test_bands_without_covariance_known_systems_and_biproper_impulses():
    cov = C_SMALL.copy()
    cov[2, :] = cov[:, 2] = np.nan
    band = ji.step_response(fit_of(ji.PolePairGain(), TRUTH, cov), [0.5, 1.0])
    assert np.all(np.isnan(band.lo))
    assert np.all(np.isfinite(band.response))
    assert "no standard error for pi" in band.note
    known = ji.step_response(
        fit_of(ji.KnownSystem(ji.TransferFunction([2.0], [1.0, 2.0])), []), [0, 1]
    )
    np.testing.assert_array_equal(known.lo, known.hi)
    assert known.method == "known"
    np.testing.assert_allclose(known.response, [0.0, 1 - math.exp(-2.0)])
    bip = fit_of(ji.RationalModel(1, 1), [3.0, 1.0, 2.0], np.eye(3) * 1e-4)
    imp = ji.impulse_response(bip, [0.0, 1.0])
    assert "3 delta(t)" in imp.note
    np.testing.assert_allclose(
        imp.response, [-5.0, -5.0 * math.exp(-2.0)]
    )  # (3s + 1)/(s + 2) = 3 - 5/(s + 2)


def test_response_bad_inputs():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    with pytest.raises(ValueError, match=r"t_s must be >= 0 \(s\)"):
        ji.step_response(res, [-1.0, 0.0])
    with pytest.raises(ValueError, match="t_s contains 1 NaN"):
        ji.step_response(res, [0.0, np.nan])
    with pytest.raises(ValueError, match="method must be 'delta' or 'sampling'"):
        ji.impulse_response(res, [0.0], method="exact")
    with pytest.raises(ValueError, match="level must be"):
        ji.step_response(res, [0.0], level=0.0)
    with pytest.raises(TypeError, match="rng must be"):
        ji.step_response(res, [0.0], method="sampling")
    with pytest.raises(ValueError, match="kind must be 'step' or 'impulse'"):
        lti_response(res.system, [0.0], "ramp")
    with pytest.raises(ValueError, match=r"step_response needs an LTI fit.*use its params"):
        ji.step_response(sine_fit(), [0.0])
    with pytest.raises(ValueError, match=r"impulse_response needs an LTI fit"):
        sine_fit().impulse_response([0.0])
    with pytest.raises(ValueError, match="kind must be one of"):
        ji.TimeResponseBand(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), 0.95, "ramp")


# ------------------------------------------------------------------------------ plot


@pytest.mark.parametrize("kind", ["step", "impulse"])
def test_plot_step_response_draws_the_band_and_references(kind, tmp_path):
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    t = np.linspace(0.0, 5.0, 101)
    band = getattr(ji, f"{kind}_response")(res, t)
    other = ji.TransferFunction([5.0], [1.0, 3.0, 5.0])
    art = ji.plot_step_response(band, {"other": other})
    assert isinstance(art, plots.Plot)
    np.testing.assert_array_equal(art["response"].get_ydata(), band.response)
    np.testing.assert_allclose(art["other"].get_ydata(), lti_response(other, t, kind))
    verts = art["band"].get_paths()[0].vertices
    assert verts[:, 1].min() == pytest.approx(band.lo.min())
    assert verts[:, 1].max() == pytest.approx(band.hi.max())
    assert kind in art.axes[0].get_ylabel()
    assert "(s)" in art.axes[0].get_xlabel()
    assert art.legend is not None
    art.savefig(tmp_path / "r.png")
    assert (tmp_path / "r.png").stat().st_size > 1000
    _, ax = plt.subplots()
    on = ji.plot_step_response(band, ax=ax)
    assert on.axes == (ax,)
    nan = ji.step_response(fit_of(ji.PolePairGain(), TRUTH, np.full((3, 3), np.nan), "none"), t)
    assert "band" not in ji.plot_step_response(nan)  # nothing to shade
    with pytest.raises(TypeError, match="band must be a TimeResponseBand"):
        ji.plot_step_response(band.response)  # type: ignore[arg-type]
