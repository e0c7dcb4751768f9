"""Diagnostics (jitterid.analysis.diagnostics) against independent referees: finite
differences, scipy, closed forms, Monte Carlo."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import table2_data
from scipy import stats

import jitterid as ji
from jitterid.analysis.diagnostics import (
    bias_frequency,
    detect_jitter,
    input_correlation_test,
    ljung_box,
    ls_gain_factor,
    model_output,
    standardized_residuals,
)
from jitterid.estimation.covariance import noise_variance_ml

TRUTH = [6.25, -1.5, 2.0]
NOISE = 0.01
# The paper's jitter levels (Table 1): sigma = T/(2 sqrt 3), T/6, T/(6 sqrt 3).
PAPER_LAWS = [
    ji.Uniform(0.5),
    ji.SumOfUniforms(2, 0.5),
    ji.SumOfUniforms(2, 0.5 / np.sqrt(3)),
    ji.Gaussian(1 / (6 * np.sqrt(3))),
]


# ------------------------------------------------------------------------------ model output


@pytest.mark.parametrize(
    ("num", "den"),
    [([6.25], [1.0, 3.0, 6.25]), ([2.0, 1.0, 3.0], [1.0, 3.0, 2.0]), ([1.0, 2.0], [1.0, 1.1, 4.0])],
)
def test_model_slope_matches_finite_differences(num, den):
    data = table2_data(4, ji.NoJitter(), n=60)
    tf = ji.TransferFunction(num, den)
    s, slope = model_output(data, tf)
    resp = tf.response(data.u)
    t = data.t_nominal
    np.testing.assert_allclose(s, resp(t))
    h = 1e-5
    # Away from the input's switches (where a biproper model's output jumps).
    sw = data.u.times
    keep = np.min(np.abs(t[:, None] - sw[None, :]), axis=1) > 10 * h
    fd = (resp(t[keep] + h) - resp(t[keep] - h)) / (2 * h)
    np.testing.assert_allclose(slope[keep], fd, rtol=1e-5, atol=1e-7)


# ------------------------------------------------------------------------------ detection


def test_detection_statistic_matches_scipy_linregress(ls_fit):
    data, ls = ls_fit
    det = detect_jitter(data, ls)
    s, slope = model_output(data, ls)
    ref = stats.linregress(slope**2, (data.y - s) ** 2)
    assert det.coef[1] == pytest.approx(ref.slope, rel=1e-10)
    assert det.coef[0] == pytest.approx(ref.intercept, rel=1e-10)
    assert det.statistic == pytest.approx(ref.slope / ref.stderr, rel=1e-10)
    # linregress is two-sided; the test is one-sided in the direction of growth.
    assert det.pvalue == pytest.approx(ref.pvalue / 2, rel=1e-8)
    assert det.jitter_std == pytest.approx(np.sqrt(ref.slope))


def test_detection_interval_matches_jackknife(ls_fit):
    """HC3 is asymptotically the jackknife variance of the slope: an independent referee."""
    data, ls = ls_fit
    det = detect_jitter(data, ls, level=0.9)
    s, slope = model_output(data, ls)
    x, z = slope**2, (data.y - s) ** 2
    loo = np.array(
        [stats.linregress(np.delete(x, i), np.delete(z, i)).slope for i in range(x.size)]
    )
    se_jack = np.sqrt((x.size - 1) / x.size * np.sum((loo - loo.mean()) ** 2))
    q = stats.norm.ppf(0.95)
    lo2, hi2 = det.jitter_std_ci[0] ** 2, det.jitter_std_ci[1] ** 2
    assert (hi2 - lo2) / (2 * q) == pytest.approx(se_jack, rel=0.05)
    assert lo2 < det.coef[1] < hi2


def test_detection_accepts_a_transfer_function_and_checks_arguments(ls_fit):
    data, ls = ls_fit
    assert detect_jitter(data, ls.system).pvalue == pytest.approx(detect_jitter(data, ls).pvalue)
    with pytest.raises(TypeError, match="model must be a FitResult or a TransferFunction"):
        detect_jitter(data, [1.0])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="level must be a number in"):
        detect_jitter(data, ls, level=95)
    flat = ji.SampledData(np.zeros(10), 1.0, ji.PiecewiseConstant([0.0, 20.0], [1.0]))
    with pytest.raises(ValueError, match=r"slope is .* constant"):
        detect_jitter(flat, ji.TransferFunction([1.0], [1.0]))


def _mc_pvalues(law: ji.JitterLaw, seeds: range) -> np.ndarray:
    out = []
    for seed in seeds:
        data = table2_data(seed, law)
        ls = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "ls")
        out.append(detect_jitter(data, ls).pvalue)
    return np.array(out)


def _binomial_region(n: int, p: float = 0.05, mass: float = 0.999) -> tuple[float, float]:
    """Two-sided acceptance region of Binomial(n, p) / n."""
    lo, hi = stats.binom.ppf([(1 - mass) / 2, (1 + mass) / 2], n, p)
    return lo / n, hi / n


def test_detection_false_alarm_and_power_small_monte_carlo():
    """150 data sets without jitter and 30 at the paper's smallest level, N = 200."""
    p0 = _mc_pvalues(ji.NoJitter(), range(1000, 1150))
    lo, hi = _binomial_region(p0.size)
    assert lo <= np.mean(p0 < 0.05) <= hi
    assert stats.kstest(p0, "uniform").pvalue > 0.001
    p1 = _mc_pvalues(PAPER_LAWS[-1], range(2000, 2030))
    assert np.mean(p1 < 0.05) > 0.9


@pytest.mark.slow
def test_detection_false_alarm_rate_full_monte_carlo():
    p0 = _mc_pvalues(ji.NoJitter(), range(10_000, 12_000))
    lo, hi = _binomial_region(p0.size)
    assert lo <= np.mean(p0 < 0.05) <= hi, np.mean(p0 < 0.05)
    assert stats.kstest(p0, "uniform").pvalue > 0.001


@pytest.mark.slow
@pytest.mark.parametrize("law", PAPER_LAWS, ids=str)
def test_detection_power_at_paper_levels_full_monte_carlo(law):
    p1 = _mc_pvalues(law, range(20_000, 20_200))
    assert np.mean(p1 < 0.05) > 0.9


@pytest.mark.slow
def test_implied_std_interval_covers_small_jitter():
    """For small jitter the interval's coverage is within 10 points of nominal (it under-covers
    a little, see detect_jitter's notes)."""
    law = ji.Uniform(0.05)
    hits = []
    for seed in range(30_000, 30_200):
        data = table2_data(seed, law)
        ls = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "ls")
        lo, hi = detect_jitter(data, ls).jitter_std_ci
        hits.append(lo <= law.std <= hi)
    assert 0.85 <= np.mean(hits) <= 0.99


# ------------------------------------------------------------------------------ residual tests


def test_ljung_box_false_alarm_and_power():
    rng = np.random.default_rng(5)
    white = rng.standard_normal((400, 200))
    p = np.array([ljung_box(w).pvalue for w in white])
    assert 0.025 <= np.mean(p < 0.05) <= 0.08
    e = rng.standard_normal((100, 201))
    ar = e[:, 1:] + 0.5 * e[:, :-1]  # MA(1): rho_1 = 0.4
    assert np.mean([ljung_box(a).pvalue < 0.05 for a in ar]) > 0.9


def test_ljung_box_statistic_by_definition():
    r = np.random.default_rng(1).standard_normal(50)
    res = ljung_box(r, lags=3)
    c = r - r.mean()
    rho = [
        np.corrcoef(c[k:], c[:-k])[0, 1] * np.std(c[k:]) * np.std(c[:-k]) / np.var(c)
        for k in (1, 2, 3)
    ]
    q = 50 * 52 * sum(rk**2 / (50 - k) for k, rk in zip((1, 2, 3), rho, strict=True))
    # corrcoef centres each slice separately; the definition centres once: equal to O(1/N).
    assert res.statistic == pytest.approx(q, rel=0.15)
    assert res.dof == 3
    assert res.pvalue == pytest.approx(stats.chi2.sf(res.statistic, 3))
    with pytest.raises(ValueError, match="lags must be below"):
        ljung_box(r, lags=25)
    with pytest.raises(ValueError, match="at least 8"):
        ljung_box(r[:5])


def test_input_correlation_false_alarm_and_power():
    rng = np.random.default_rng(8)
    rates, power = [], []
    for _ in range(300):
        u = ji.telegraph_input(201.0, rng)(np.arange(200.0))  # coloured input
        rates.append(input_correlation_test(rng.standard_normal(200), u).pvalue < 0.05)
    for _ in range(50):
        u = ji.telegraph_input(201.0, rng)(np.arange(200.0))
        r = rng.standard_normal(200) + np.r_[0.0, 0.0, u[:-2]]  # R^2 = 0.2
        power.append(input_correlation_test(r, u).pvalue < 0.05)
    assert 0.02 <= np.mean(rates) <= 0.09
    assert np.mean(power) > 0.9
    with pytest.raises(ValueError, match="one value per residual"):
        input_correlation_test(np.ones(20), np.ones(19))


def test_standardized_residuals_against_monte_carlo_moments(ls_fit):
    data, ls = ls_fit
    law = ji.Uniform(0.5)
    truth = ji.PolePairGain().system(TRUTH)
    res = dataclasses.replace(ls, system=truth, jitter_law=law, noise_std=NOISE)
    z = standardized_residuals(data, res)
    rng = np.random.default_rng(0)
    s = truth.response(data.u)(data.t_nominal[None, :] + law.sample((8_000, 1), rng))
    z_mc = (data.y - s.mean(0)) / np.sqrt(s.var(0) + NOISE**2)
    np.testing.assert_allclose(z, z_mc, rtol=0.05, atol=0.05)
    assert abs(np.mean(z)) < 0.2
    assert np.std(z) == pytest.approx(1.0, abs=0.15)
    # Without a noise std the noise variance is a plug-in estimate: still unit variance.
    z0 = standardized_residuals(data, dataclasses.replace(res, noise_std=0.0))
    assert np.std(z0) == pytest.approx(1.0, abs=0.15)
    r_mc = data.y - s.mean(0)
    assert np.sqrt(noise_variance_ml(r_mc, s.var(0))) == pytest.approx(NOISE, rel=0.25)
    # An over-estimated jitter law must not blow up samples where the output is flat.
    over = dataclasses.replace(res, jitter_law=ji.Uniform(0.6), noise_std=0.0)
    assert np.max(np.abs(standardized_residuals(data, over))) < 6


# ------------------------------------------------------------------------------ LS gain bias


def test_gain_factor_closed_forms():
    f = np.linspace(0, 2, 41)
    np.testing.assert_allclose(
        ls_gain_factor(ji.Uniform(0.5), f), np.abs(np.sinc(2 * f * 0.5)), atol=1e-12
    )
    np.testing.assert_allclose(
        ls_gain_factor(ji.Gaussian(0.1), f), np.exp(-2 * np.pi**2 * 0.01 * f**2), atol=1e-12
    )
    np.testing.assert_allclose(ls_gain_factor(ji.NoJitter(), f), 1.0)
    with pytest.raises(TypeError, match="jitter must be a jitter law"):
        ls_gain_factor(ji.UniformFamily(), f)  # type: ignore[arg-type]


@pytest.mark.parametrize("law", [ji.Uniform(0.4), ji.SumOfUniforms(2, 0.5)], ids=str)
def test_gain_factor_is_the_damping_of_a_jittered_sinusoid(law):
    """Monte Carlo referee: E sin(2 pi f0 (t + tau)) = |phi(f0)| sin(2 pi f0 t), symmetric tau."""
    rng = np.random.default_rng(2)
    f0, t = 0.37, np.linspace(0, 3, 7)
    tau = law.sample((200_000, 1), rng)
    mean = np.mean(np.sin(2 * np.pi * f0 * (t + tau)), axis=0)
    np.testing.assert_allclose(
        mean, ls_gain_factor(law, f0) * np.sin(2 * np.pi * f0 * t), atol=5e-3
    )


def test_bias_frequency():
    sigma, tol = 0.1, 0.01
    closed = np.sqrt(-np.log(1 - tol) / (2 * np.pi**2 * sigma**2))
    assert bias_frequency(ji.Gaussian(sigma), tol) == pytest.approx(closed, rel=1e-8)
    fb = bias_frequency(ji.Uniform(0.5), 0.05)
    assert ls_gain_factor(ji.Uniform(0.5), fb) == pytest.approx(0.95, abs=1e-9)
    assert np.all(ls_gain_factor(ji.Uniform(0.5), np.linspace(0, fb, 100)[:-1]) > 0.95)
    assert bias_frequency(ji.NoJitter()) == np.inf
    with pytest.raises(ValueError, match="level must be"):
        bias_frequency(ji.Uniform(0.5), 1.5)
