"""The meter's exact likelihood with harmonics on a converter's record: a 12-bit tone with
HD2 and HD3, picosecond jitter, little thermal noise. (The generic quadrature's route when
written; since session 25 such small harmonics are held at their least-squares fit and the
fundamental measured by the structured likelihood: tests/metrology/test_held.py. The
generic route with harmonics: tests/metrology/test_sinelik.py.)"""

from __future__ import annotations

import numpy as np

import jitterid as ji

TS = 1e-9  # 1 GS/s


def _record(seed: int, N: int = 1024) -> tuple[np.ndarray, float]:
    rng = np.random.default_rng(seed)
    f = 97.123e6 + rng.uniform(-1e5, 1e5)  # not coherent
    sj = 2e-12
    ph = 2 * np.pi * f * (np.arange(N) * TS + sj * rng.standard_normal(N)) + 0.7
    x = 0.45 * np.sin(ph) + 0.01
    x += 0.45 * 10 ** (-60 / 20) * np.sin(3 * ph + 0.3)  # HD3 at -60 dBc
    x += 0.45 * 10 ** (-66 / 20) * np.sin(2 * ph + 1)  # HD2 at -66 dBc
    x += 30e-6 * rng.standard_normal(N)
    lsb = 2.0**-12
    return lsb * np.round(x / lsb), sj


def test_harmonics_on_a_12_bit_record_get_error_bars():
    """Before: UNIDENTIFIABLE with no error bars on every such record. The search from the
    IEEE start ended at noise std 3e-4 (in the search's units), the comparison with the
    default starts (noise std 1.6e-3) re-designed the likelihood's windowed rule, and the
    covariance back at the estimate was refused as a search step towards zero noise."""
    y, sj = _record(500)
    m = ji.measure_jitter(y, TS, harmonics=3, laws=["gaussian"])
    assert m.status is ji.FitStatus.CONVERGED, m.message
    assert m.harmonics_fitted == 3
    assert np.isfinite(m.jitter_std_stderr)
    assert m.jitter_std_stderr > 0
    lo, hi = m.interval()
    assert lo <= sj <= hi
