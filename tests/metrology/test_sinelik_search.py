"""The search of the structured sine likelihood (jitterid.metrology.sinelik_fit) on
noise-free records, where ln L is rough in the amplitude and offset on the scale of the
noise std's floor: rejected trial steps cost a ln L pass only, and a long record's search
starts from its own optimum on a subsample, to the same maximum."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import jitterid as ji
import jitterid.metrology.sinelik_fit as sf
from jitterid.metrology.sinelik import NUMERIC_FLOOR, SineLikelihood, fit_sine_ml
from jitterid.systems.tones import SineWave

T = 1 / 7e9
JITTER = 100e-15
AMP = 0.49


def _ended(r) -> bool:
    """At a maximum: CONVERGED, or AT_BOUND with only the noise std on its floor."""
    if r.status is ji.FitStatus.CONVERGED:
        return True
    return r.status is ji.FitStatus.AT_BOUND and r.message.endswith("on its bound: noise_std")


def _noise_free(log2n: int, seed: int):
    """The issue-26 record without additive noise; returns (y, f, model, family, start,
    floor) with the start off the truth and the meter's numeric noise floor."""
    N = 1 << log2n
    cyc = round(1e9 * N * T)
    cyc += 1 - cyc % 2
    f = cyc / (N * T)
    rng = np.random.default_rng(seed)
    tau = JITTER * rng.standard_normal(N)
    y = AMP * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + 0.4)
    spread = AMP * 2 * np.pi * f * JITTER / math.sqrt(2.0)
    floor = NUMERIC_FLOOR * spread
    fam = ji.GaussianFamily(sigma_max=10 * T, sigma_min=1e-9 * T)
    model = SineWave(band_hz=(0.99 * f, 1.01 * f))
    start = np.r_[1.3 * JITTER, AMP * (1 + 1e-5), 0.4 + 1e-4, f, 1e-6, 30 * floor]
    return y, f, model, fam, start, floor


def test_rejected_trials_cost_a_loglik_pass_only(monkeypatch):
    """A step's first trial is a full pass (ln L, score, information: usually accepted);
    after a rejection the trials are judged on ln L alone, and the full pass is made only
    at the accepted point. (Before: every trial was a full pass; on noise-free records
    most of them were rejected.) The fit is the same either way."""
    y, _, model, fam, start, floor = _noise_free(12, 3)
    seen: list[float] = []
    orig_si = SineLikelihood.scores_information
    orig_ll = SineLikelihood.loglik
    trials = []

    def si(self, x, stride=1):
        out = orig_si(self, x, stride)
        seen.append(out[0])
        return out

    def ll(self, x):
        out = orig_ll(self, x)
        trials.append(out)
        return out

    monkeypatch.setattr(SineLikelihood, "scores_information", si)
    monkeypatch.setattr(SineLikelihood, "loglik", ll)
    r = fit_sine_ml(y, T, model, fam, start, noise_floor=floor)
    assert _ended(r), r.message
    assert trials, "no step was rejected: the test's record does not exercise the trials"
    # a full pass below the last accepted point (the step's first trial, rejected) is
    # followed by an accepted one: the further trials were ln L passes
    best = seen[0]
    for a, b in itertools.pairwise(seen):
        tol = 1e-12 * abs(best)
        if a < best - tol:
            assert b >= best - tol, "two rejected trials in a row had full passes"
        best = max(best, a, b)
    assert abs(seen[-1] - (-0.5 * r.cost)) <= 1e-9 * abs(r.cost)


def test_a_long_record_starts_from_its_subsample_optimum(monkeypatch):
    """With the subsample start (every 4th sample here, FIT_SUBSAMPLE lowered so that a
    small record takes the long records' path) the search ends at the maximum the direct
    search reaches: ln L within 0.01, the jitter std within 0.05 of its standard error."""
    y, _, model, fam, start, floor = _noise_free(13, 4)
    direct = fit_sine_ml(y, T, model, fam, start, noise_floor=floor)
    monkeypatch.setattr(sf, "FIT_SUBSAMPLE", 1 << 11)
    calls = []
    orig = sf._search

    def spy(yy, *args, **kw):
        calls.append(np.size(yy))
        return orig(yy, *args, **kw)

    monkeypatch.setattr(sf, "_search", spy)
    sub = fit_sine_ml(y, T, model, fam, start, noise_floor=floor)
    assert calls == [y.size // 4, y.size]
    assert _ended(direct), direct.message
    assert _ended(sub), sub.message
    assert abs(sub.cost - direct.cost) < 0.02
    assert abs(sub.jitter_std - direct.jitter_std) < 0.05 * direct.jitter_std_stderr
    assert abs(sub.jitter_std - JITTER) < 4 * sub.jitter_std_stderr


@pytest.mark.slow  # about 40 CPU-s
def test_a_noise_free_2_18_record_is_fitted_with_an_honest_interval():
    """The long records' path as it runs (2^18 samples: from the optimum on every 4th
    sample), against the realised std of the draws and the direct search's answer."""
    y, _, model, fam, start, floor = _noise_free(18, 5)
    r = fit_sine_ml(y, T, model, fam, start, noise_floor=floor)
    assert _ended(r), r.message
    assert abs(r.jitter_std - JITTER) < 4 * r.jitter_std_stderr
    rng = np.random.default_rng(5)
    realised = float(np.std(JITTER * rng.standard_normal(y.size)))
    assert abs(r.jitter_std - realised) < 2 * r.jitter_std_stderr


def test_records_from_2_15_samples_start_from_a_subsample():
    # 2^15-2^17 samples: from every s-th sample, s = N // RANK_SUBSAMPLE (s >= 4); from 2^18
    # on, s = N // FIT_SUBSAMPLE as before; below 2^15 no subsample (_subsample_start)
    assert sf._fit_subsample_size(1 << 16) == sf.RANK_SUBSAMPLE
    assert (1 << 15) // sf._fit_subsample_size(1 << 15) == 4
    assert (1 << 14) // sf._fit_subsample_size(1 << 14) < 4
    assert sf._fit_subsample_size(1 << 20) == sf.FIT_SUBSAMPLE == 1 << 16
    assert sf._fit_subsample_size(1 << 18) == sf.FIT_SUBSAMPLE


def test_a_uniform_fit_stopped_at_a_local_maximum_in_its_scale_goes_on():
    """A uniform record at 1 rad of phase spread with noise 1e-3 (N = 1000), searched from
    1.2 x the true half-width: the search stops, CONVERGED, at a local maximum at 1.18 x the
    truth, -2 ln L 164 above the maxima near the truth (a scan of ln L over the half-width,
    the rest as fitted, rises all the way down to it). fit_sine_ml probes ln L at 0.85 and
    1.15 x the fitted scale (SCALE_PROBES), searches again from the higher probe and says
    so. The referee: the truth, within 3 % (the stated error is about 0.1 %, but in this
    regime of sharp edges ln L is rough: the meter says so, jitterid.metrology.edges), and
    -2 ln L at least 150 below the local maximum's."""
    Ts, F, A, phi, c, noise, N = 1.0, 0.1234, 0.7, 0.3, 0.1, 1e-3, 1000
    a = math.sqrt(3) / (2 * np.pi * F)  # 2 pi F std = 1 rad
    law = ji.Uniform(a)
    rng = np.random.default_rng(22)
    for _ in range(18):  # the 18th record of this stream (the case found)
        tau = law.sample(N, rng)
        y = A * np.sin(2 * np.pi * F * (np.arange(N) * Ts + tau) + phi) + c
        y = y + noise * rng.standard_normal(N)
    model = SineWave(band_hz=(0.9 * F, 1.1 * F))
    start = np.r_[1.2 * a, 1.01 * A, phi + 0.01, F, c, 1.3 * noise]
    stuck = sf._search(y, Ts, model, ji.UniformFamily(), start, 0.0, 100, None)[0]
    assert stuck.status is ji.FitStatus.CONVERGED  # the premise: a silent local maximum
    assert stuck.x[0] > 1.15 * a
    fit = fit_sine_ml(y, Ts, model, ji.UniformFamily(), start)
    assert fit.status is ji.FitStatus.CONVERGED
    assert "local maximum" in fit.message
    assert abs(fit.x[0] / a - 1) < 0.03
    assert fit.cost < stuck.cost - 150


def test_a_gaussian_fit_is_not_probed(monkeypatch):
    """The scale probes are for laws with hard edges only: a Gaussian fit costs nothing
    more (one search, the record too short for a subsample start)."""
    y, _, model, fam, start, floor = _noise_free(12, 0)
    assert isinstance(fam, ji.GaussianFamily)
    calls = []
    orig = sf._search

    def counted(*args, **kw):
        calls.append(1)
        return orig(*args, **kw)

    monkeypatch.setattr(sf, "_search", counted)
    fit = fit_sine_ml(y, T, model, fam, start, noise_floor=floor)
    assert len(calls) == 1
    assert "local maximum" not in fit.message
