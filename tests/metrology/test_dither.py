"""The meter says when a quantised record's noise does not dither its quantiser
(:func:`jitterid.metrology.adequacy.dither_finding`): the fits model the quantiser's error
as Gaussian noise, which biases the jitter when the noise before the quantiser is below
about half a step."""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology.adequacy import DITHER_STEPS, dither_finding

FS = 1e9
SJ = 2e-12
STEP = 2.0 / 2**12


def _record(seed: int, N: int, thermal_steps: float) -> tuple[np.ndarray, float]:
    """A 12-bit record (full scale +-1) of a 97.1 MHz tone at 0.95, 2 ps Gaussian jitter and
    ``thermal_steps`` of Gaussian noise before the quantiser; and the realised jitter std."""
    rng = np.random.default_rng(seed)
    f = 97.123e6 + rng.uniform(-1e5, 1e5)
    tau = SJ * rng.standard_normal(N)
    x = 0.95 * np.sin(2 * np.pi * f * (np.arange(N) / FS + tau) + 0.3)
    x += thermal_steps * STEP * rng.standard_normal(N)
    return STEP * np.round(x / STEP), float(tau.std())


def test_the_finding_reads_the_noise_before_the_quantiser():
    """None for a float record and at DITHER_STEPS or more; below, the message names the
    noise before the quantiser in steps (the fitted noise less the step's own variance)."""
    assert dither_finding(None, 0.1) is None
    assert dither_finding(1.0, math.sqrt(1 / 12 + DITHER_STEPS**2)) is None
    assert dither_finding(1.0, math.nan) is None
    got = dither_finding(1.0, math.sqrt(1 / 12 + 0.2**2))
    assert got is not None
    assert got.kind == "undithered"
    assert "about 0.2 steps of noise before its quantiser" in got.message
    floor = dither_finding(0.5, 0.5 / math.sqrt(12))  # the noise on its floor: no dither
    assert floor is not None
    assert "about 0 steps" in floor.message


@pytest.mark.parametrize(("thermal", "flagged"), [(0.2, True), (1.0, False)])
def test_the_meter_says_a_record_is_not_dithered(thermal, flagged):
    """12-bit records of 4096 samples: 0.2 steps of noise before the quantiser is flagged
    (the fit's noise is then about 0.35 steps, the quantiser's included), 1 step is not; the
    status stays CONVERGED and the message carries the finding."""
    y, _ = _record(7, 4096, thermal)
    m = ji.measure_jitter(y, 1 / FS, method="gaussian")
    assert m.status is ji.FitStatus.CONVERGED, m.message
    assert ("undithered" in {f.kind for f in m.findings}) is flagged
    assert ("before its quantiser" in m.message) is flagged
    assert m.quantisation_step == pytest.approx(STEP)


@pytest.mark.parametrize(("thermal", "bins"), [(0.2, True), (3.0, False)])
def test_the_likelihood_measures_an_undithered_record_by_its_bins(thermal, bins):
    """The default route (the structured likelihood of a pure tone) on a 12-bit record of
    4096 samples: with 0.2 steps of noise before the quantiser each sample is the
    probability of its bin, the fit's noise std is the noise before the quantiser and the
    reported one the record's, sqrt(sigma^2 + q^2 / 12); no "undithered" finding. With 3
    steps (dithered) the Gaussian noise of the record's std, as before."""
    y, _ = _record(11, 4096, thermal)
    m = ji.measure_jitter(y, 1 / FS, laws=["gaussian"])
    assert m.status is ji.FitStatus.CONVERGED, m.message
    assert "undithered" not in {f.kind for f in m.findings}
    fitted = float(m.fit.params["noise_std"])
    if bins:
        assert fitted / STEP == pytest.approx(thermal, rel=0.3)
        assert m.noise_std == pytest.approx(math.sqrt(fitted**2 + STEP**2 / 12), rel=1e-12)
    else:
        assert m.noise_std == fitted


@pytest.mark.slow
def test_the_bins_remove_the_bias():
    """16 records of 2^16 samples with 0.2 steps of noise before the quantiser, the meter's
    defaults (about 8 CPU-min): the jitter's error against each record's realised std, in
    stated errors, averages within +-0.5 (measured +0.05, sd 0.6, with the bins modelled;
    -1.28, 8 of 16 intervals covering the truth, with Gaussian noise before session 22) and
    spreads less than 1.2 (the stated error holds the realised std's own spread too)."""
    z = []
    for s in range(100, 116):
        y, real = _record(s, 1 << 16, 0.2)
        m = ji.measure_jitter(y, 1 / FS)
        assert "undithered" not in {f.kind for f in m.findings}
        z.append((m.jitter_std - real) / m.jitter_std_stderr)
    assert abs(np.mean(z)) < 0.5, z
    assert np.std(z) < 1.2, z


@pytest.mark.slow
def test_a_noise_free_record_ranks_its_laws_in_a_few_passes(monkeypatch):
    """The noise-free record of seed 100 (N = 2^16, no noise before the quantiser): with the
    noise std on its floor (0.01 step) ln L is rough in the tone's amplitude and offset on
    that scale, and the dual Dirac's ranking crawled: 63 passes, each step gaining 1.1e-3
    against a predicted 5, 183 of the measurement's 444 CPU-s. Its ranking now ends after
    sinelik_fit.ROUGH_STEPS rough steps, ranked out, within 25 passes; the Gaussian is
    chosen and its interval covers the truth (about 1 CPU-min)."""
    from jitterid.metrology import sinelik_fit

    seen = []
    search = sinelik_fit._search

    def recording(y, T, model, family, *args, **kw):  # type: ignore[no-untyped-def]
        out = search(y, T, model, family, *args, **kw)
        seen.append((type(family).__name__, np.size(y), out))
        return out

    monkeypatch.setattr(sinelik_fit, "_search", recording)
    y, _ = _record(100, 1 << 16, 0.0)
    m = ji.measure_jitter(y, 1 / FS)
    dd = [out for name, n, out in seen if name == "DualDiracFamily" and n == y.size]
    assert len(dd) == 1, [(name, n) for name, n, _ in seen]
    fit, ranked_out, _ = dd[0]
    assert ranked_out, fit.message
    assert "rough" in fit.message
    assert fit.nfev <= 25, fit.nfev
    assert type(m.law).__name__ == "Gaussian"
    lo, hi = m.interval()
    assert lo <= SJ <= hi
