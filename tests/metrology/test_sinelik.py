"""The structured likelihood of a jittered tone (jitterid.metrology.sinelik) against its
referees: the generic exact likelihood, brute force over jitter draws, the closed-form
noise-free density, a refined rule of its own, differences of itself; and its ML fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
import jitterid.metrology.sinelik_rule as rule
from jitterid.estimation.likelihood import ExactLikelihood
from jitterid.jitter import registry
from jitterid.jitter.regular import DualDiracFamily
from jitterid.metrology.sinelik import TOLERANCE, SineLikelihood, fit_sine_ml, sine_ml_applies
from jitterid.systems.tones import SineWave

T, F, A, PHI, C = 1.0, 0.1234, 0.7, 0.3, 0.1

CASES = {
    "gaussian": (ji.GaussianFamily(), ji.Gaussian(0.3), [0.3]),
    "uniform": (ji.UniformFamily(), ji.Uniform(0.5), [0.5]),
    "dual-dirac": (DualDiracFamily(), ji.DualDirac(0.1, 0.6), [0.1, 0.6]),
    "scale-mixture": (
        ji.GaussianScaleMixtureFamily(),
        ji.GaussianScaleMixture(0.3, 0.6),
        [0.3, 0.6],
    ),
}


def _record(law, N, noise, rng, f=F, amp=A):
    tau = law.sample(N, rng)
    t = np.arange(N) * T + tau
    return amp * np.sin(2 * np.pi * f * t + PHI) + C + noise * rng.standard_normal(N)


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("noise", [0.3, 1e-2, 1e-4, 1e-7])
def test_matches_generic_exact_likelihood(name, noise):
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(11)
    N = 200
    y = _record(law, N, noise, rng)
    x = np.r_[jp, A, PHI, F, C, noise]
    mine = SineLikelihood(y, T, fam).logpdf(x)
    ref = ExactLikelihood(SineWave(), fam, None, T, N).logpdf(x, y)
    assert np.max(np.abs(mine - ref)) < TOLERANCE


@pytest.mark.parametrize("name", list(CASES))
def test_matches_generic_off_the_truth(name):
    """Away from the parameters that made the record (a search's path): samples far in
    the tails of their density."""
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(12)
    y = _record(law, 150, 1e-2, rng)
    x = np.r_[np.asarray(jp) * 0.6, A * 1.05, PHI + 0.05, F * 1.001, C - 0.02, 2e-2]
    mine = SineLikelihood(y, T, fam).logpdf(x)
    ref = ExactLikelihood(SineWave(), fam, None, T, y.size).logpdf(x, y)
    body = ref > -20  # the generic rule drops pieces below e^-24 of a sample's largest
    assert np.max(np.abs(mine - ref)[body]) < TOLERANCE
    # the deep tail (a sample 10 to 30 noise std's from the tone) against a dense grid
    law_x = fam.law(x[: len(jp)])
    for k in np.flatnonzero(~body)[:4]:
        assert abs(mine[k] - _dense_logp(y[k], k, law_x, x[len(jp) :])) < TOLERANCE


def _dense_logp(yk, k, law, sine):
    """ln p(y_k) by the trapezoidal rule on 400 001 points of the jitter's support (the
    integrand is smooth there; its ends are the support's, where it is 0 or flat)."""
    amp, phi, f, c, sigma = sine
    lo, hi = law.support
    tau = np.linspace(lo, hi, 400_001)
    s = amp * np.sin(2 * np.pi * f * (k * T + tau) + phi) + c
    ln = -0.5 * ((yk - s) / sigma) ** 2 + np.log(np.maximum(law.pdf(tau), 1e-300))
    top = ln.max()
    val = np.trapezoid(np.exp(ln - top), tau)
    return top + math.log(val) - math.log(sigma * math.sqrt(2 * math.pi))


@pytest.mark.parametrize("name", list(CASES))
def test_brute_force_over_jitter_draws(name):
    """p(y_k) = E_tau N(y_k - s(kT + tau); sigma^2), by 400 000 draws of the law."""
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(13)
    noise = 0.2
    y = _record(law, 6, noise, rng)
    x = np.r_[jp, A, PHI, F, C, noise]
    mine = np.exp(SineLikelihood(y, T, fam).logpdf(x))
    tau = law.sample(400_000, np.random.default_rng(14))
    for k in range(y.size):
        s = A * np.sin(2 * np.pi * F * (k * T + tau) + PHI) + C
        dens = np.exp(-0.5 * ((y[k] - s) / noise) ** 2) / (noise * math.sqrt(2 * math.pi))
        mc, se = dens.mean(), dens.std() / math.sqrt(dens.size)
        assert abs(mine[k] - mc) < 5 * se


def _noise_free_density(y, k, jp, fam_name):
    """The sigma = 0 limit: sum over the roots psi of A sin psi = y - c of
    p_u(psi - theta_k) / |A cos psi| (p_u: the phase jitter's density)."""
    w = 2 * np.pi * F
    theta = np.mod(w * k * T + PHI, 2 * np.pi)
    z = (y - C) / A
    out = np.zeros_like(y)
    for base in (np.arcsin(z), np.pi - np.arcsin(z)):
        for m in range(-3, 4):
            tau = (base + 2 * np.pi * m - theta) / w  # every wrap of the root
            if fam_name == "gaussian":
                pu = ji.Gaussian(jp[0]).pdf(tau) / w
            else:
                pu = ji.Uniform(jp[0]).pdf(tau) / w
            out += pu / np.abs(A * np.cos(base))
    return out


@pytest.mark.parametrize("name", ["gaussian", "uniform"])
def test_tends_to_the_noise_free_density(name):
    """sigma -> 0 (1e-8 of the amplitude): the closed-form density of the noise-free
    tone, away from the turning points (where it is unbounded). (Below ~1e-9 of the
    amplitude double precision limits ln p: the samples and the phase carry ~1e-16
    relative rounding, 1e-16 A / sigma of the noise std; the meter's floor is >= 1e-9 A.)"""
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(15)
    y = _record(law, 300, 0.0, rng)
    k = np.arange(y.size)
    z = (y - C) / A
    inner = (np.abs(z) < 0.95) & (np.abs(np.abs(z) - 1) > 0.05)  # away from the turning points
    ref = _noise_free_density(y, k, jp, name)
    inner &= ref > 0
    x = np.r_[jp, A, PHI, F, C, 1e-8 * A]
    mine = SineLikelihood(y, T, fam).logpdf(x)
    np.testing.assert_allclose(mine[inner], np.log(ref[inner]), atol=1e-6, rtol=0)


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("noise", [0.3, 3e-3, 3e-6, 1e-9])
@pytest.mark.parametrize("spread", [1e-6, 1e-2, 1.0])
def test_rule_error_bound(name, noise, spread, monkeypatch):
    """The stated error (TOLERANCE in each ln p) against the same rule refined: twice the
    nodes per panel, a window 1.4 times as wide, every piece's third rule twice as fine."""
    fam, law, jp = CASES[name]
    w = 2 * np.pi * F
    scale = spread / (w * law.std)  # the time-valued parameters scaled (not a split)
    named = zip(fam.param_names, jp, strict=True)
    jp = [v if n in registry.UNITLESS else v * scale for n, v in named]
    law = fam.law(jp)
    rng = np.random.default_rng(16)
    y = _record(law, 120, noise, rng)
    x = np.r_[jp, A, PHI, F, C, noise]
    coarse = SineLikelihood(y, T, fam).logpdf(x)
    monkeypatch.setattr(rule, "_ORDER", 20)
    gx, gw = np.polynomial.legendre.leggauss(20)
    monkeypatch.setattr(rule, "_GL_X", gx)
    monkeypatch.setattr(rule, "_GL_LOGW", np.log(gw))
    monkeypatch.setattr(rule, "_WINDOW", 14.0)
    monkeypatch.setattr(rule, "_FINE", 32)
    fine = SineLikelihood(y, T, fam).logpdf(x)
    assert np.max(np.abs(coarse - fine)) < TOLERANCE


@pytest.mark.parametrize("name", list(CASES))
def test_score_is_the_gradient(name):
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(17)
    y = _record(law, 300, 1e-2, rng)
    x = np.r_[np.asarray(jp) * 0.9, A * 0.99, PHI + 0.01, F * 1.0001, C, 1.2e-2]
    lik = SineLikelihood(y, T, fam)
    _, g, _ = lik.scores(x)
    per = lik.per_sample_scores(x)
    np.testing.assert_allclose(per.sum(axis=0), g, rtol=1e-12, atol=0)
    for i in range(x.size):
        h = 1e-6 * abs(x[i])
        up, dn = x.copy(), x.copy()
        up[i] += h
        dn[i] -= h
        num = (lik.loglik(up) - lik.loglik(dn)) / (2 * h)
        assert abs(num - g[i]) <= 1e-4 * max(abs(g[i]), 1.0) + 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("name", list(CASES))
def test_observed_information_is_the_score_s_jacobian(name):
    """Louis' identity at the nodes against central differences of the analytic score."""
    fam, law, jp = CASES[name]
    rng = np.random.default_rng(24)
    y = _record(law, 400, 1e-2, rng)
    x = np.r_[np.asarray(jp) * 0.9, A * 0.99, PHI + 0.01, F * 1.0001, C, 1.1e-2]
    lik = SineLikelihood(y, T, fam)
    H = lik.observed_information(x)
    num = np.zeros_like(H)
    for i in range(x.size):
        h = 1e-5 * abs(x[i])
        up, dn = x.copy(), x.copy()
        up[i] += h
        dn[i] -= h
        num[i] = -(lik.scores(up)[1] - lik.scores(dn)[1]) / (2 * h)
    num = 0.5 * (num + num.T)
    d = np.sqrt(np.abs(np.diag(num)))
    assert np.max(np.abs(H - num) / np.outer(d, d)) < 2e-3


def test_negative_amplitude_is_the_shifted_phase():
    fam, law, jp = CASES["gaussian"]
    y = _record(law, 100, 1e-2, np.random.default_rng(18))
    lik = SineLikelihood(y, T, fam)
    a = lik.loglik(np.r_[jp, A, PHI, F, C, 1e-2])
    b = lik.loglik(np.r_[jp, -A, PHI + math.pi, F, C, 1e-2])
    assert a == pytest.approx(b, abs=1e-8)


def test_bad_input_is_named():
    y = np.sin(np.arange(50.0))
    with pytest.raises(TypeError, match="family"):
        SineLikelihood(y, 1.0, ji.SumOfUniformsFamily())
    lik = SineLikelihood(y, 1.0, ji.GaussianFamily())
    with pytest.raises(ValueError, match="noise_std"):
        lik.loglik([0.1, 1.0, 0.0, 0.15, 0.0, 0.0])
    with pytest.raises(ValueError, match="x must hold 6"):
        lik.loglik([0.1, 1.0, 0.0, 0.15, 0.0])
    with pytest.raises(ValueError, match="NaN or infinite"):
        SineLikelihood(np.r_[y, np.nan], 1.0, ji.GaussianFamily())
    assert sine_ml_applies(SineWave(), ji.UniformFamily())
    assert not sine_ml_applies(SineWave(harmonics=2), ji.UniformFamily())
    with pytest.raises(TypeError, match="pure-tone"):
        fit_sine_ml(y, 1.0, SineWave(harmonics=2), ji.GaussianFamily(), np.zeros(8))


def _fit(name, N, noise, rng, spread=0.3):
    fam, law, jp = CASES[name]
    w = 2 * np.pi * F
    scale = spread / (w * law.std)  # the time-valued parameters scaled (not a split)
    named = zip(fam.param_names, jp, strict=True)
    jp = [v if n in registry.UNITLESS else v * scale for n, v in named]
    law = fam.law(jp)
    y = _record(law, N, noise, rng)
    start = np.r_[np.asarray(jp) * 1.2, A * 1.01, PHI + 0.01, F, C, noise * 1.3]
    model = SineWave(band_hz=(0.9 * F, 1.1 * F))
    return fit_sine_ml(y, T, model, fam, start), law.std


@pytest.mark.parametrize("name", list(CASES))
def test_ml_fit_recovers_the_jitter(name):
    r, std = _fit(name, 2000, 1e-2, np.random.default_rng(19))
    assert r.status is ji.FitStatus.CONVERGED, r.message
    assert abs(r.jitter_std - std) < 4 * r.jitter_std_stderr
    assert abs(r.params["noise_std"] - 1e-2) < 4 * r.stderr["noise_std"]
    assert r.cov_type == "oim"
    assert np.all(np.isfinite(r.cov))


def _meter_noise_free(seed, N=1024):
    rng = np.random.default_rng(seed)
    Ts, f, sj = 1 / 7e9, 1e9, 1e-13
    f = (round(f * N * Ts) + 0.5) / (N * Ts)
    tau = sj * rng.standard_normal(N)
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * Ts + tau) + 0.4)  # no noise at all
    return ji.measure_jitter(y, Ts, laws=["gaussian"], method="ml"), sj


def test_meter_ml_on_a_noise_free_float_record():
    """A simulator's record (no additive noise): the structured likelihood with the noise
    on its floor, CONVERGED, the truth in the interval."""
    m, sj = _meter_noise_free(20)
    assert "structured sine likelihood" in m.fit.message
    assert m.status is ji.FitStatus.CONVERGED, m.message
    lo, hi = m.interval()
    assert lo <= sj <= hi


@pytest.mark.slow  # 7 CPU-s; test_meter_ml_on_a_noise_free_float_record is the fast version
def test_meter_ml_on_noise_free_records_is_not_biased_by_its_floor():
    """A noise-free record shows each sample's jitter, so the ML std is the realised std of
    the draws (well inside its standard error, which is that of the law's std); the noise
    floor must not pull it low (at 3 % of the jitter's spread it did, by 1 standard error
    on every record at N = 2^14)."""
    N, Ts = 1 << 13, 1 / 7e9
    cycles = round(1e9 * N * Ts)
    f = (cycles + 1 - cycles % 2) / (N * Ts)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        tau = 1e-13 * rng.standard_normal(N)
        y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * Ts + tau) + 0.4)
        m = ji.measure_jitter(y, Ts, laws=["gaussian"], method="ml")
        assert m.status is ji.FitStatus.CONVERGED, m.message
        assert abs(m.jitter_std - tau.std()) < 0.2 * m.jitter_std_stderr


def test_meter_keeps_the_generic_route_for_strong_harmonics():
    """HD2 at -20 dBc (its slope 0.2 of the fundamental's): not held at its least-squares
    fit (jitterid.metrology.held, tests/metrology/test_held.py), the generic quadrature."""
    rng = np.random.default_rng(21)
    N = 200
    t = np.arange(N) + 0.05 * rng.standard_normal(N)
    y = np.sin(2 * np.pi * 0.1234 * t) + 0.1 * np.sin(4 * np.pi * 0.1234 * t)
    y += 1e-3 * rng.standard_normal(N)
    m = ji.measure_jitter(y, 1.0, laws=["gaussian"], harmonics=2, method="ml")
    assert m.harmonics_fitted == 2
    assert "structured sine likelihood" not in m.fit.message
    assert "held" not in m.message


_UNIFORM_WIDE = pytest.mark.xfail(
    strict=True,
    reason="measured 55/64 = 0.86 (again in session 18): the estimates spread 1.46 x the "
    "observed-information error (0.0101 against 0.0069), with the bias within 0.2 %. Not the "
    "information: at the truth the scores' variance over 200 records equals the mean observed "
    "information to 4 %. Not the interval's shape: the profile-likelihood interval covered "
    "57/64 on the same records (4 % wider on average). The misses lie 2.6-4.6 errors off, with "
    "the phase 0.01-0.11 rad off as well and -2 ln L at the truth 8-11 above the fit "
    "(inside chi2(6)): at 1 rad the support's edges make ln L rough in (phase, half-width), "
    "and N = 1000 is short of the asymptotic regime there",
)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "spread"),
    [
        pytest.param(
            name, spread, marks=[_UNIFORM_WIDE] if (name, spread) == ("uniform", 1.0) else []
        )
        for name in CASES
        for spread in (0.05, 0.3, 1.0)
    ],
)
def test_ml_bias_and_coverage(name, spread):
    """64 records per cell (N = 1000): bias of the jitter std within 3 % and 95 % coverage
    within 88-99 % (measured: 11 of the 12 cells; see _UNIFORM_WIDE. The scale mixture's,
    session 13: -0.3 / -0.1 / +0.4 %, 59 / 62 / 61 of 64 at 0.05 / 0.3 / 1 rad)."""
    rng = np.random.default_rng(22)
    est, cover = [], 0
    std = None
    for _ in range(64):
        r, std = _fit(name, 1000, 1e-2, rng, spread)
        est.append(r.jitter_std)
        cover += abs(r.jitter_std - std) < 1.96 * r.jitter_std_stderr
    assert abs(np.mean(est) / std - 1) < 0.03
    assert 0.88 <= cover / 64 <= 0.99


def test_ml_bias_and_coverage_fast():
    """The slow test's small version: 12 Gaussian records, no interval far off."""
    rng = np.random.default_rng(23)
    z = []
    for _ in range(12):
        r, std = _fit("gaussian", 500, 1e-2, rng)
        z.append((r.jitter_std - std) / r.jitter_std_stderr)
    assert np.max(np.abs(z)) < 4
    assert abs(np.mean(z)) < 1.5


@pytest.mark.slow
def test_meter_noise_free_coverage():
    """Noise-free float records: the truth inside the 95 % interval in >= 90 % of 32."""
    hits = 0
    for seed in range(100, 132):
        m, sj = _meter_noise_free(seed)
        lo, hi = m.interval()
        hits += lo <= sj <= hi
    assert hits >= 29


def test_a_start_on_a_scale_bound_is_searched_not_refused():
    """A start at (or clipped onto) a scale's upper bound: searched in ln of the scale,
    exp(ln b) rounds one ulp past b, which the family refused (ValueError from the law)
    before the search clipped its points to the bounds."""
    rng = np.random.default_rng(4)
    y = _record(ji.Uniform(0.5), 300, 1e-2, rng)
    b = 0.218  # exp(ln b) > b in floating point
    assert np.exp(np.log(b)) > b
    fam = ji.UniformFamily(a_max=b, a_min=1e-9)
    model = SineWave(band_hz=(0.99 * F, 1.01 * F))
    fit = fit_sine_ml(y, T, model, fam, [0.5, A, PHI, F, C, 1e-2])
    assert fit.x[0] <= b
    assert "a" in fit.message  # on its bound, and said so
