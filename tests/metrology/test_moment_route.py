"""The meter's moment route and the physical noise floor (issue 26 items 1 and 2).

Referees: brute force over jitter draws for the closed-form moments (F1)-(F3); records made
here with numpy (float with no additive noise, and quantised to 12-16 bits) whose true
jitter std is known; the issue's own femtosecond records.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import moments
from jitterid.metrology.adequacy import quantisation_step
from jitterid.metrology.meter import DEFAULT_LAWS

FS = 7e9
T = 1 / FS


def _draw(rng, law, s, n):
    """Phase jitter w tau of std s (rad)."""
    if law == "gaussian":
        return s * rng.standard_normal(n)
    return rng.uniform(-s * math.sqrt(3), s * math.sqrt(3), n)


@pytest.mark.parametrize("law", ["gaussian", "uniform"])
@pytest.mark.parametrize("s", [0.05, 0.5, 1.2])
def test_the_closed_form_moments_agree_with_brute_force(law, s):
    """(F1)-(F2) at eight phases against 4e5 jitter draws each."""
    rng = np.random.default_rng(1)
    eps = _draw(rng, law, s, 400_000)
    chi1 = moments._chi1(law, s)
    chi2 = chi1**2 * moments._ratio(law, s)
    assert chi1 == pytest.approx(np.mean(np.cos(eps)), abs=4e-3)
    assert chi2 == pytest.approx(np.mean(np.cos(2 * eps)), abs=4e-3)
    A = 0.7
    for phi in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        x = A * np.sin(phi + eps)
        mean = A * chi1 * np.sin(phi)
        var = 0.5 * A**2 * ((1 - chi1**2) + (chi1**2 - chi2) * np.cos(2 * phi))
        assert np.mean(x) == pytest.approx(mean, abs=5e-3 * A)
        assert np.var(x) == pytest.approx(var, rel=2e-2, abs=1e-4 * A**2)


@pytest.mark.parametrize("law", ["gaussian", "uniform"])
def test_the_inversion_of_f3_is_exact(law):
    for s in (1e-6, 1e-3, 0.1, 0.5, 1.0, 1.5):
        g = 1 - moments._ratio(law, s)
        s2, ds2 = moments._invert(law, g)
        assert s2 == pytest.approx(s * s, rel=1e-6)
        h = 1e-7 * max(g, 1e-12)
        num = (moments._invert(law, g + h)[0] - moments._invert(law, g - h)[0]) / (2 * h)
        assert ds2 == pytest.approx(num, rel=1e-3)


def _coherent_record(N, sigma_s, rng, bits=0, noise=0.0, amplitude=0.49):
    """A 1 GHz-ish coherent tone (J prime to N) at 7 GS/s, as in issue 26."""
    J = round(1e9 * N * T) | 1
    while math.gcd(J, N) != 1:
        J += 2
    f = J / (N * T)
    t = np.arange(N) * T + sigma_s * rng.standard_normal(N)
    y = amplitude * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    y = y + noise * rng.standard_normal(N)
    if bits:
        q = 1.0 / 2**bits
        y = np.round(y / q) * q
    return y, f


@pytest.mark.parametrize("sigma", [1e-15, 10e-15, 100e-15])
def test_femtosecond_jitter_on_a_noise_free_float_record(sigma):
    """Issue 26: N = 2^16, 1 GHz at 7 GS/s, amplitude 0.49, no additive noise. Before:
    0.00 fs AT_BOUND for 1 and 10 fs, 96.95 +- 0.29 fs for 100 fs (the 1e-4 rms floor)."""
    rng = np.random.default_rng(int(sigma * 1e18))
    y, _ = _coherent_record(2**16, sigma, rng)
    m = ji.measure_jitter(y, T, method="gaussian")
    assert m.status is ji.FitStatus.CONVERGED, m.message
    assert m.noise_floor is None
    lo, hi = m.interval()
    assert lo < sigma < hi
    assert abs(m.jitter_std / sigma - 1) < 0.02
    assert m.jitter_std_stderr / sigma < 0.01


def test_a_quantised_record_has_its_step_found_and_used_as_the_floor():
    rng = np.random.default_rng(2)
    y, _ = _coherent_record(4096, 2e-12, rng, bits=12, noise=0.2 / 2**12)
    assert quantisation_step(y) == pytest.approx(1 / 2**12)
    m = ji.measure_jitter(y, T, method="gaussian")
    assert m.quantisation_step == pytest.approx(1 / 2**12)
    assert m.noise_floor == pytest.approx(1 / 2**12 / math.sqrt(12))
    assert m.status is ji.FitStatus.CONVERGED, m.message
    lo, hi = m.interval()
    assert lo < 2e-12 < hi


def test_an_unresolved_jitter_has_a_one_sided_interval():
    """2 pi f sigma = 1e-6 rad on a 12-bit record: far below the LSB; the interval is [0,
    upper] and holds the truth; the std has a finite standard error (no NaN)."""
    rng = np.random.default_rng(3)
    sigma = 1e-6 / (2 * np.pi * 1e9)
    y, _ = _coherent_record(4096, sigma, rng, bits=12)
    m = ji.measure_jitter(y, T, method="gaussian")
    lo, hi = m.interval()
    assert lo == 0.0
    assert hi > sigma
    assert math.isfinite(m.jitter_std_stderr)
    assert "one-sided" in m.message


def _coverage(setting, records, N, seed0):
    s, bits, thermal = setting
    sigma = s / (2 * np.pi * 1e9)
    hits = flagged = 0
    for r in range(records):
        rng = np.random.default_rng([seed0, r, bits, round(s * 1e9)])
        y, _ = _coherent_record(N, sigma, rng, bits=bits, noise=thermal / 2**bits if bits else 0)
        # beyond ~0.2 rad the law-free route hands the record to the likelihood: the law
        # (the truth's) is given there, to test the moment route itself
        laws = ["gaussian"] if s >= 0.2 else list(DEFAULT_LAWS)
        m = ji.measure_jitter(y, T, method="gaussian", laws=laws)
        lo, hi = m.interval()
        hits += lo <= sigma <= hi
        flagged += m.status is not ji.FitStatus.CONVERGED  # a failing finding
    return hits, flagged


@pytest.mark.parametrize(
    "setting",
    [(1e-6, 0, 0.0), (1e-2, 0, 0.0), (0.5, 0, 0.0), (0.05, 12, 0.2), (1e-3, 14, 0.0)],
    ids=["float-1e-6", "float-1e-2", "float-0.5", "12bit-0.05", "14bit-1e-3"],
)
def test_coverage_on_noise_free_and_quantised_records_small(setting):
    """16 records each (the slow test runs 64): at least 13 intervals hold the truth
    (P(<= 12 | 16, 0.95) = 0.7 %), and the adequacy checks fail at most 2."""
    hits, flagged = _coverage(setting, 16, 2048, 11)
    assert hits >= 13
    assert flagged <= 2


@pytest.mark.slow
@pytest.mark.parametrize(
    "setting",
    [(s, 0, 0.0) for s in (1e-6, 1e-4, 1e-2, 0.1, 0.3, 1.0)]
    + [(s, b, th) for b in (12, 14, 16) for s in (1e-3, 0.05, 0.3) for th in (0.0, 0.2)],
)
def test_coverage_on_noise_free_and_quantised_records(setting):
    """Issue 26's test: the truth inside the 95 % interval in >= 90 % of 64 records; the
    adequacy checks fail at most 5 % of them (periodic and coloured jitter, which only
    inform, have their own false-alarm test in test_phase_error.py)."""
    hits, flagged = _coverage(setting, 64, 8192, 12)
    assert hits >= 58
    assert flagged <= 3


@pytest.mark.parametrize("T", [1e-9, 1e-3])
@pytest.mark.parametrize("laws", [["gaussian"], ["uniform"], list(DEFAULT_LAWS)])
def test_the_fit_and_law_carry_the_measured_jitter(T, laws):
    """The moment route's answer as a fit: its jitter parameter is the family's scale at
    the measured std (the law's std is the measurement's, the scale's error the std's
    times the scale per unit std). Before: the scale per unit std was read at a std of 1 s,
    which the families' bounds (10 T) clip, so the fit, its law and the report's pdf had a
    std of 1e-18 s at 1 GS/s (5e-7 of the truth at 1 kS/s) and an error of zero."""
    rng = np.random.default_rng(3)
    N, f, sj = 4096, 0.0971 / T, 2e-3 * T
    t = np.arange(N) * T
    y = 0.45 * np.sin(2 * np.pi * f * (t + sj * rng.standard_normal(N)))
    y += 30e-6 * rng.standard_normal(N)
    m = ji.measure_jitter(y, T, method="gaussian", laws=laws)
    assert m.status is ji.FitStatus.CONVERGED, m.message
    assert m.fit.jitter_std == pytest.approx(m.jitter_std, rel=1e-9)
    assert m.law.std == pytest.approx(m.jitter_std, rel=1e-9)
    assert m.fit.jitter_std_stderr == pytest.approx(m.jitter_std_stderr, rel=1e-6)
    assert abs(m.jitter_std - sj) < 4 * m.jitter_std_stderr


def test_a_noise_free_float_record_is_measured_at_the_bound():
    """Noise-free float records (2 ps at 97 MHz, 1 GS/s, N = 4096, 12 records): the jitter's
    own variance is all the samples' variance, so the Gaussian likelihood's bound for the
    std is sigma / sqrt(2 N) (the samples' phase errors tau_k are observed through the
    slopes), and an efficient estimate follows each record's realised std far more closely
    than the population's. Referees: that bound, and the realised std of each record's
    draws. Before session 26 (the variance profile's weights floored at a quarter of the
    mean variance, two reweightings): the stated error 1.23 times the bound, the error
    against the realised std 0.53 of the stated error; now 1.01 and 0.18 (48 records)."""
    N, sj, T = 4096, 2e-12, 1e-9
    stated, off = [], []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        f = 97.123e6 + rng.uniform(-1e5, 1e5)
        tau = sj * rng.standard_normal(N)
        y = 0.95 * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + rng.uniform(0, 2 * np.pi))
        m = ji.measure_jitter(y, T, method="gaussian", laws=["gaussian"])
        assert m.status is ji.FitStatus.CONVERGED, m.message
        stated.append(m.jitter_std_stderr)
        off.append(m.jitter_std - tau.std())
    bound = sj / math.sqrt(2 * N)
    assert np.mean(stated) / bound == pytest.approx(1.0, abs=0.06)
    assert np.std(off) < 0.3 * np.mean(stated)
