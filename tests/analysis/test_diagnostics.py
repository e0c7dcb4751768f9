"""Diagnostics against independent referees: finite differences, scipy, closed forms, Monte
Carlo."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
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
from jitterid.analysis.uncertainty import bode_band, jitter_pdf_band
from jitterid.estimation.covariance import noise_variance_ml

TRUTH = [6.25, -1.5, 2.0]
T, N, NOISE = 1.0, 200, 0.01
# The paper's jitter levels (Table 1): sigma = T/(2 sqrt 3), T/6, T/(6 sqrt 3).
PAPER_LAWS = [
    ji.Uniform(0.5),
    ji.SumOfUniforms(2, 0.5),
    ji.SumOfUniforms(2, 0.5 / np.sqrt(3)),
    ji.Gaussian(1 / (6 * np.sqrt(3))),
]


def paper_data(seed: int, law: ji.JitterLaw, n: int = N) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 2.0, rng)
    return ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, n, NOISE, rng)


@pytest.fixture(scope="module")
def ls_fit() -> tuple[ji.SampledData, ji.FitResult]:
    data = paper_data(1, ji.Uniform(0.5))
    return data, ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "ls")


# ------------------------------------------------------------------------------ model output


@pytest.mark.parametrize(
    ("num", "den"),
    [([6.25], [1.0, 3.0, 6.25]), ([2.0, 1.0, 3.0], [1.0, 3.0, 2.0]), ([1.0, 2.0], [1.0, 1.1, 4.0])],
)
def test_model_slope_matches_finite_differences(num, den):
    data = paper_data(4, ji.NoJitter(), n=60)
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
        data = paper_data(seed, law)
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
        data = paper_data(seed, law)
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


# ------------------------------------------------------------------------------ bands


def _with_cov(res: ji.FitResult, names, x, cov, system, jitter) -> ji.FitResult:
    cov = np.asarray(cov, float)
    return dataclasses.replace(
        res,
        names=tuple(names),
        x=np.asarray(x, float),
        system=system,
        jitter_law=jitter,
        jitter_model=ji.UniformFamily() if "a" in names else jitter,
        cov=cov,
    )


def test_bode_band_against_monte_carlo(ls_fit):
    _, ls = ls_fit
    x = np.array([0.3, *TRUTH])  # a jitter parameter first, as in a family fit
    cov = np.diag([1e-3, 0.04, 0.004, 0.003])
    cov[1, 2] = cov[2, 1] = 0.005
    struct = ji.PolePairGain()
    res = _with_cov(ls, ("a", "k0", "pr", "pi"), x, cov, struct.system(TRUTH), ji.Uniform(0.3))
    f = np.array([0.01, 0.1, 0.3, 0.5])
    band = bode_band(res, f, level=0.9, structure=struct)
    np.testing.assert_allclose(band.magnitude, np.abs(struct.system(TRUTH).frequency_response(f)))
    rng = np.random.default_rng(3)
    k0, pr, pi = rng.multivariate_normal(x[1:], cov[1:, 1:], size=200_000).T[:, :, None]
    s = 2j * np.pi * f
    g = k0 / ((s - pr) ** 2 + pi**2)  # the paper's (27), written out independently
    logmag, ph = np.log(np.abs(g)), np.degrees(np.angle(g))
    half = (np.log(band.magnitude_hi) - np.log(band.magnitude_lo)) / 2
    mc_half = (np.quantile(logmag, 0.95, axis=0) - np.quantile(logmag, 0.05, axis=0)) / 2
    np.testing.assert_allclose(half, mc_half, rtol=0.05)
    ph_half = (band.phase_hi - band.phase_lo) / 2
    mc_ph = (np.quantile(ph, 0.95, axis=0) - np.quantile(ph, 0.05, axis=0)) / 2
    np.testing.assert_allclose(ph_half, mc_ph, rtol=0.05)


def test_bode_band_argument_checks(ls_fit):
    _, ls = ls_fit
    with pytest.raises(ValueError, match=r"parameters \['b0', 'a1', 'a0'\] are not among"):
        bode_band(ls, [0.1], structure=ji.RationalModel(0, 2))
    with pytest.raises(TypeError, match="structure must be the ModelStructure"):
        bode_band(ls, [0.1], structure="polepair")  # type: ignore[arg-type]
    nan_cov = np.full((3, 3), np.nan)
    res = _with_cov(ls, ls.names, ls.x, nan_cov, ls.system, ji.NoJitter())
    band = bode_band(res, [0.1, 0.2], structure=ji.PolePairGain())
    assert np.all(np.isnan(band.magnitude_lo))
    assert np.all(np.isfinite(band.magnitude))


def test_pdf_band_against_the_transformed_quantiles(ls_fit):
    """For U(-a, a) with a ~ N(m, s^2), p(0) = 1/(2a) is monotone in a: its quantiles are known."""
    _, ls = ls_fit
    m, sd = 0.4, 0.03
    x = np.array([m, *TRUTH])
    cov = np.diag([sd**2, 0.04, 0.004, 0.003])
    res = _with_cov(ls, ("a", "k0", "pr", "pi"), x, cov, ls.system, ji.Uniform(m))
    band = jitter_pdf_band(res, [0.0, 0.3], 7, level=0.9, n_draws=8000)
    q = stats.norm.ppf(0.95)
    assert band.pdf[0] == pytest.approx(1 / (2 * m))
    assert band.lo[0] == pytest.approx(1 / (2 * (m + q * sd)), rel=0.01)
    assert band.hi[0] == pytest.approx(1 / (2 * (m - q * sd)), rel=0.01)
    assert band.fixed == ()
    again = jitter_pdf_band(res, [0.0, 0.3], 7, level=0.9, n_draws=8000)
    np.testing.assert_array_equal(band.lo, again.lo)  # explicit seed: reproducible
    known = jitter_pdf_band(res, [0.0, 0.3], 7, family=None)
    np.testing.assert_array_equal(known.lo, known.hi)
    cov_nan = cov.copy()
    cov_nan[0, :] = cov_nan[:, 0] = np.nan
    fixed = jitter_pdf_band(
        _with_cov(ls, ("a", "k0", "pr", "pi"), x, cov_nan, ls.system, ji.Uniform(m)), [0.0], 1
    )
    assert fixed.fixed == ("a",)
    wild = cov.copy()
    wild[0, 0] = 10.0**2  # a ~ N(0.4, 10^2) but bounded to (0, 0.5]: almost no draw fits
    res_wild = _with_cov(ls, ("a", "k0", "pr", "pi"), x, wild, ls.system, ji.Uniform(m))
    with pytest.raises(ValueError, match="too uncertain for a density band"):
        jitter_pdf_band(res_wild, [0.0], 1, family=ji.UniformFamily(a_max=0.5))
    with pytest.raises(ValueError, match="no jitter"):
        jitter_pdf_band(ls, [0.0], 1)
    with pytest.raises(TypeError, match="rng must be"):
        jitter_pdf_band(res, [0.0], None)  # type: ignore[arg-type]
    with pytest.warns(DeprecationWarning, match="the result knows its family"):
        old = jitter_pdf_band(res, ji.UniformFamily(), [0.0, 0.3], 7, level=0.9, n_draws=8000)
    np.testing.assert_array_equal(old.lo, band.lo)


def test_bode_band_agrees_with_a_linearisation_of_the_magnitude_itself(ls_fit):
    """Second route: linearise |G| (not log G) by hand; to first order in the band's relative
    width the half-widths agree."""
    from scipy import stats

    _, ls = ls_fit
    f = np.geomspace(0.01, 0.5, 25)
    mine = bode_band(ls, f, level=0.9)
    theta, cov = ls.x, ls.cov
    jac = np.empty((f.size, theta.size))
    for i in range(theta.size):
        h = 1e-6 * abs(theta[i])
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        g_up = np.abs(ji.PolePairGain().system(up).frequency_response(f))
        g_down = np.abs(ji.PolePairGain().system(down).frequency_response(f))
        jac[:, i] = (g_up - g_down) / (2 * h)
    se_lin = np.sqrt(np.einsum("fi,ij,fj->f", jac, cov, jac))
    half_lin = stats.norm.ppf(0.95) * se_lin / np.abs(ls.system.frequency_response(f))
    half_log = (np.log(mine.magnitude_hi) - np.log(mine.magnitude_lo)) / 2
    assert np.max(half_log) < 0.2  # narrow enough for first-order agreement
    np.testing.assert_allclose(half_log, half_lin, rtol=0.02)
