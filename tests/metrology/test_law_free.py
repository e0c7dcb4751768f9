"""The moment route without an assumed jitter law (issue 26 item 0): uniform, dual-Dirac and
Gaussian-mixture jitter (a location mixture, in the dual-Dirac family, and a scale mixture,
heavier-tailed than a Gaussian) get an honest interval.

Referees: brute force over jitter draws for the fourth-moment identity (F4); records made
here with numpy whose jitter law and std are known.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import moments

T, F = 1e-3, 123.0


def _draw(law, rng, s, n):
    """Phase jitter (rad) of std s."""
    if law == "uniform":
        return rng.uniform(-s * math.sqrt(3), s * math.sqrt(3), n)
    if law == "dual-dirac":  # +-delta plus Gaussian s / 3 (the benchmark's)
        rj = s / 3
        return math.sqrt(s * s - rj * rj) * rng.choice([-1.0, 1.0], n) + rj * rng.standard_normal(n)
    if law == "mixture":  # two Gaussians at +-0.6 s, each of std 0.8 s
        return 0.6 * s * rng.choice([-1.0, 1.0], n) + 0.8 * s * rng.standard_normal(n)
    if law == "scale-mixture":  # stds 0.6 : 1.28, probability 1/2 each (kurtosis 4.2)
        sc = np.where(rng.random(n) < 0.5, 0.6, 1.28) / math.sqrt((0.36 + 1.28**2) / 2)
        return s * sc * rng.standard_normal(n)
    return s * rng.standard_normal(n)


@pytest.mark.parametrize("law", ["uniform", "dual-dirac", "gaussian"])
@pytest.mark.parametrize("s", [0.3, 0.8])
def test_the_fourth_moment_identity_against_brute_force(law, s):
    """(F4): the cos(4 phi) coefficient of E[(sin(phi + e) - chi_1 sin phi)^4] is
    (chi_4 - 4 chi_1 chi_3 + 6 chi_1^2 chi_2 - 3 chi_1^4) / 8. Both sides are taken over
    the same draws, and the identity holds for their own empirical law to rounding (1e-11
    of the tolerance with 2e5 draws or 2e4): 2e4 draws test it as well. A wrong
    coefficient (6 -> 5) misses by 4-6000 tolerances, with either."""
    rng = np.random.default_rng(2)
    e = _draw(law, rng, s, 20_000)
    chi = [float(np.mean(np.cos(m * e))) for m in range(5)]
    c1 = chi[1]
    formula = (chi[4] - 4 * c1 * chi[3] + 6 * c1 * c1 * chi[2] - 3 * c1**4) / 8
    phis = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    vals = np.array([np.mean((np.sin(p + e) - c1 * np.sin(p)) ** 4) for p in phis])
    brute = 2 * float(np.mean(vals * np.cos(4 * phis)))
    assert formula == pytest.approx(brute, abs=2e-3 * max(abs(formula), s**4))


def test_the_shape_family_spans_the_kurtosis():
    """The family's kurtosis: 1 at theta = -1 (dual Dirac), 3 at 0, 6 at 1; h / g^2 tends
    to K / 8 as the spread vanishes."""
    g = 1e-5
    for theta, K in ((-1.0, 1.0), (0.0, 3.0), (1.0, 6.0)):
        s2 = moments._s2_for(g, theta)
        h = moments._gh(s2, theta)[1]
        assert h / g**2 == pytest.approx(K / 8, rel=1e-3)


def _run(law, s, seed, N=2000):
    rng = np.random.default_rng(seed)
    sig = s / (2 * np.pi * F)
    tau = _draw(law, rng, s, N) / (2 * np.pi * F)
    t = np.arange(N) * T + tau
    y = np.sin(2 * np.pi * F * t + rng.uniform(0, 2 * np.pi)) + 0.1
    y = y + 1e-2 * rng.standard_normal(N)
    m = ji.measure_jitter(y, T, method="gaussian")  # the default laws: law-free
    lo, hi = m.interval()
    return m, sig, lo <= sig <= hi


@pytest.mark.parametrize("law", ["uniform", "dual-dirac", "mixture"])
def test_non_gaussian_jitter_gets_an_honest_interval_small(law):
    """Before: the Gaussian route fitted the first law only (issue 26: uniform at 0.3 rad
    coverage 0.79-0.83, dual-Dirac 0.12-0.21). 48 records at 0.15 rad, where the fourth
    moment tells the shape (beyond ~0.2 rad the likelihood measures: the slow test below
    and tests/metrology/test_meter_large_spread.py): >= 41 covered (a coverage of 0.93 fails
    this 3 % of the time, one of 0.8 82 %; 128 records covered 0.93 / 0.96 / 0.98 for the
    three laws in session 26, the stated errors 0.98-1.0 of the spreads). Until session 26
    12 records, >= 10: a coverage of 0.93 failed that 5 % of the time, and the moment
    route's Gaussian weights met it on the uniform's first 12 (9 of 12; 44 of 48)."""
    covered = 0
    for r in range(48):
        m, _, hit = _run(law, 0.15, 100 + r)
        assert m.family == "law-free"
        covered += hit
    assert covered >= 41, covered


def test_the_kurtosis_is_measured_at_small_spread():
    m, _, _ = _run("uniform", 0.1, 7, N=20000)
    assert "kurtosis 1.8" in m.message or "kurtosis 1.7" in m.message or "kurtosis 1.9" in m.message


#: Cells known to fail, as strict xfails. The uniform at 1 rad was one (the estimate right,
#: the Wald interval covering 0.72 over 32 records of benchmarks/jitter_meter.py, the law's
#: edges: the estimates spread 1.55 x the observed-information error); in session 17's
#: run of this test (the first since session 16's scale probes in fit_sine_ml, numpy 2.4.6,
#: scipy 1.17.1) it passed both thresholds here (bias within 3 %, 58-63 of 64 covered), so
#: the strict xfail failed, and it was taken out. The count itself was not recorded.
_LEFT: dict[tuple[str, float], str] = {}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("law", "s"),
    [
        pytest.param(
            law,
            s,
            marks=[pytest.mark.xfail(strict=True, reason=_LEFT[law, s])]
            if (law, s) in _LEFT
            else [],
        )
        for law in ("uniform", "dual-dirac", "mixture", "scale-mixture", "gaussian")
        for s in (0.05, 0.3, 1.0)
    ],
)
def test_non_gaussian_jitter_bias_and_coverage(law, s):
    """Issue 26: bias within 3 % and coverage 90-98 % over 64 records per cell, the fast
    route (method="gaussian", the default laws): the moments at 0.05 rad, the likelihood
    beyond ~0.2 rad, where the moments cannot tell the law's shape (the 1 rad cells take
    30-40 CPU-minutes each). Measured in session 13 (the scale mixture among the default
    laws): the location mixture at 1 rad +0.2 %, 60 of 64 (it had been marked a strict
    xfail without being run, for the scale mixture's failure); the scale mixture -0.2 /
    -0.2 / +0.2 %, 59 / 61 / 58 of 64 at 0.05 / 0.3 / 1 rad."""
    est, covered = [], 0
    for r in range(64):
        m, sig, hit = _run(law, s, 3000 + r)
        est.append(m.jitter_std / sig)
        covered += hit
    assert abs(np.mean(est) - 1) < 0.03
    assert 58 <= covered <= 63, covered
