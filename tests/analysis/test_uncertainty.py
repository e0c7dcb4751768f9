"""Uncertainty bands (jitterid.analysis.uncertainty): the Bode band and the jitter pdf band
against Monte Carlo over parameter draws, transformed quantiles and a linearisation of the
magnitude itself."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

import jitterid as ji
from jitterid.analysis.uncertainty import bode_band, jitter_pdf_band

TRUTH = [6.25, -1.5, 2.0]


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
