"""Periodic and coloured jitter from the per-sample phase error (issue 26 item 0).

Referees: records made here with numpy whose jitter is white, periodic (a sine of known
amplitude and frequency holding half the variance) or AR(1) (coefficient 0.9, half the
variance); the portmanteau test's chi-square null on independent heteroscedastic series.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology.phase import newey_west_lags, whiteness

T, F, N = 1e-3, 123.0, 1000
STD = 0.3 / (2 * np.pi * F)
#: The small tests' laws: one law keeps the fast route on the moments at 0.3 rad (with
#: several it hands a spread beyond ~0.2 rad to the likelihood: seconds a record, which the
#: slow tests below take).
SMALL_LAWS = ["gaussian"]


def _record(kind, seed, N=N):
    rng = np.random.default_rng(seed)
    k = np.arange(N)
    fp = math.nan
    if kind == "white":
        tau = STD * rng.standard_normal(N)
    elif kind == "periodic":  # a PJ of rms STD / sqrt(2): half the variance
        fp = rng.uniform(5, 60)
        tau = STD * math.sqrt(0.5) * rng.standard_normal(N) + STD * np.sin(
            2 * np.pi * fp * k * T + rng.uniform(0, 2 * np.pi)
        )
    else:  # AR(1) 0.9 holding half the variance
        e = rng.standard_normal(N)
        x = np.empty(N)
        x[0] = e[0]
        for i in range(1, N):
            x[i] = 0.9 * x[i - 1] + math.sqrt(1 - 0.81) * e[i]
        tau = STD * math.sqrt(0.5) * (rng.standard_normal(N) + x)
    y = 1.3 * np.sin(2 * np.pi * F * (k * T + tau) + rng.uniform(0, 2 * np.pi)) + 0.2
    return y + 1e-2 * rng.standard_normal(N), fp


def test_the_whiteness_test_holds_its_level_on_independent_heteroscedastic_series():
    rng = np.random.default_rng(1)
    scale = 0.2 + np.abs(np.cos(np.linspace(0, 40, 1000)))
    rejected = sum(whiteness(scale * rng.standard_normal(1000))[0] < 0.01 for _ in range(400))
    assert rejected <= 10, rejected  # expected 4; P(X > 10 | 400, 0.01) < 0.3 %


def test_newey_west_bandwidth_grows_with_the_correlation():
    assert newey_west_lags(1000, 0.0) == 1
    assert newey_west_lags(1000, 0.5) < newey_west_lags(1000, 0.9) <= 250


def test_periodic_jitter_is_found_and_split_from_the_random_part():
    found = 0
    for s in range(8):
        y, fp = _record("periodic", 40 + s)
        m = ji.measure_jitter(y, T, method="gaussian", laws=SMALL_LAWS)
        dec = m.decomposition
        assert m.status is ji.FitStatus.CONVERGED, m.message
        if not dec.periodic:
            continue
        found += 1
        assert "periodic-jitter" in {f.kind for f in m.findings}
        assert dec.pj_frequency_hz == pytest.approx(fp, abs=1.5 / (N * T))
        assert dec.pj_amplitude == pytest.approx(STD, rel=0.15)
        assert dec.rj_std == pytest.approx(STD * math.sqrt(0.5), rel=0.2)
        assert dec.rj_std**2 + dec.pj_rms**2 == pytest.approx(m.jitter_std**2, rel=1e-9)
        assert "PJ" in m.summary()
    assert found >= 7


def test_coloured_jitter_is_found_and_its_interval_widened():
    found = 0
    for s in range(8):
        y, _ = _record("ar", 60 + s)
        m = ji.measure_jitter(y, T, method="gaussian", laws=SMALL_LAWS)
        assert m.status is ji.FitStatus.CONVERGED, m.message
        if m.decomposition.coloured:
            found += 1
            assert m.decomposition.hac_lags > 1
            assert "correlated" in m.message
    assert found >= 7


def test_white_jitter_is_not_called_periodic_or_coloured_small():
    flagged = 0
    for s in range(16):
        y, _ = _record("white", 80 + s)
        m = ji.measure_jitter(y, T, method="gaussian", laws=SMALL_LAWS)
        flagged += m.decomposition.periodic or m.decomposition.coloured
    assert flagged <= 2, flagged


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["periodic", "ar"])
def test_detection_rate_where_it_holds_half_the_variance(kind):
    """Issue 26: detected in >= 95 % of records (64), the rms within its interval in
    >= 85 % (the Newey-West interval is about 10 % short at N = 1000 on AR(1) 0.9)."""
    hits = cover = 0
    for s in range(64):
        y, _ = _record(kind, 1000 + s)
        m = ji.measure_jitter(y, T, method="gaussian")
        d = m.decomposition
        hits += d.periodic if kind == "periodic" else d.coloured
        lo, hi = m.interval()
        cover += lo <= STD <= hi
    assert hits >= 61, hits
    assert cover >= 54, cover


@pytest.mark.slow
def test_false_alarm_rate_on_white_jitter():
    """Issue 26: <= 5 % of 64 white-jitter records called periodic or coloured."""
    flagged = 0
    for s in range(64):
        y, _ = _record("white", 2000 + s)
        m = ji.measure_jitter(y, T, method="gaussian")
        flagged += m.decomposition.periodic or m.decomposition.coloured
    assert flagged <= 3, flagged
