"""A search that meets a maximum already found (jitterid.metrology.sinelik_fit.fit_sine_ml's
``found``): the search on the whole record is skipped only where the subsample optimum from
the start lies in one quadratic bowl with that maximum; the referee is the same search run
without ``found``."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import sinelik_fit
from jitterid.metrology.sinelik import RankStart, fit_sine_ml, rank_sine_law, rank_start
from jitterid.metrology.sinelik_loglik import SineLikelihood
from jitterid.systems.tones import SineWave

T = 1 / 7e9
JITTER = 2e-12  # 2 pi f sigma = 1.3e-2 rad at 1 GHz
NOISE = 1e-3
N = 1 << 15  # the shortest record fit_sine_ml starts on a subsample (every 4th sample)


def _record(seed: int) -> tuple[np.ndarray, float]:
    """A coherent ~1 GHz tone at 7 GS/s, amplitude 0.49, uniform jitter of std JITTER."""
    cyc = round(1e9 * N * T)
    cyc += 1 - cyc % 2
    f = cyc / (N * T)
    rng = np.random.default_rng(seed)
    tau = JITTER * math.sqrt(3.0) * rng.uniform(-1.0, 1.0, N)
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + 0.4)
    return y + NOISE * rng.standard_normal(N), f


def _setting(seed: int):
    y, f = _record(seed)
    model = SineWave(band_hz=(0.99 * f, 1.01 * f))
    fam = ji.UniformFamily(a_max=20 * T, a_min=1e-9 * T)
    here = np.r_[fam.start_for_std(JITTER), 0.49, 0.4, f, 0.0, NOISE]
    there = np.r_[fam.start_for_std(1.3 * JITTER), 0.4905, 0.4003, f, 1e-4, 1.4 * NOISE]
    return y, model, fam, here, there


@pytest.fixture(scope="module")
def record_fit():
    """The record of seed 1, its setting, and its maximum from ``here`` (the fit the first
    four tests start from or compare with: one fit of 2^15 samples, made once)."""
    y, model, fam, here, there = _setting(1)
    return y, model, fam, here, there, fit_sine_ml(y, T, model, fam, here)


class _Passes:
    """Counts the whole record's passes (score passes of N samples)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.n = 0
        inner = SineLikelihood.scores_information

        def counted(lik, x, stride=1):
            if lik.N == N:
                self.n += 1
            return inner(lik, x, stride)

        monkeypatch.setattr(SineLikelihood, "scores_information", counted)


def test_a_search_that_meets_a_maximum_is_not_run_again(monkeypatch, record_fit):
    """From a second start, with the first start's maximum as ``found``: that maximum,
    the message saying the search met it, no score pass of the whole record; the search
    without ``found`` ends within 0.01 standard errors of it, after score passes of the
    whole record."""
    y, model, fam, _, there, first = record_fit
    assert first.status is ji.FitStatus.CONVERGED
    passes = _Passes(monkeypatch)
    alone = fit_sine_ml(y, T, model, fam, there)
    searched = passes.n
    passes.n = 0
    met = fit_sine_ml(y, T, model, fam, there, found=first)
    assert searched >= 2
    assert passes.n == 0
    assert "met this maximum" in met.message
    assert np.array_equal(met.x, first.x)
    assert met.cost == first.cost
    se = np.sqrt(np.diag(first.cov))
    assert np.all(np.abs(alone.x - first.x) <= 0.01 * se)


def test_a_maximum_elsewhere_is_not_met(monkeypatch, record_fit):
    """``found`` moved by 40 of its standard errors in the phase (a maximum that is not
    the one the start climbs to): not met; the search runs on the whole record and ends at
    the maximum, not at ``found``."""
    y, model, fam, _, there, first = record_fit
    k = first.names.index("phase_rad")
    x = first.x.copy()
    x[k] += 40.0 * math.sqrt(first.cov[k, k])
    elsewhere = replace(first, x=x)
    passes = _Passes(monkeypatch)
    got = fit_sine_ml(y, T, model, fam, there, found=elsewhere)
    assert passes.n >= 2
    assert "met this maximum" not in got.message
    assert abs(got.x[k] - first.x[k]) <= 0.01 * math.sqrt(first.cov[k, k])


def test_the_bowl_test_reads_the_quadratic_model(monkeypatch, record_fit):
    """The test itself: the maximum meets its own subsample optimum; a point on the segment
    beyond the chi^2 radius does not; and with MEET_QUADRATIC and MEET_SLACK at 0 a point
    inside the radius is refused unless ln L falls exactly as the quadratic model says (it
    never does to the last digit)."""
    y, model, fam, here, _, first = record_fit
    size = sinelik_fit._fit_subsample_size(N)
    fitted = sinelik_fit._subsample_fit(y, T, model, fam, here, 0.0, 100, size, None)
    assert fitted is not None
    sub = fitted[0].x
    assert sinelik_fit._meets(y, T, fam, sub, first, size, None) is not None
    far = np.asarray(sub) + 30.0 * (first.x - np.asarray(sub))
    assert sinelik_fit._meets(y, T, fam, sub, replace(first, x=far), size, None) is None
    not_converged = replace(first, status=ji.FitStatus.MAX_EVALUATIONS)
    assert sinelik_fit._meets(y, T, fam, sub, not_converged, size, None) is None
    monkeypatch.setattr(sinelik_fit, "MEET_QUADRATIC", 0.0)
    monkeypatch.setattr(sinelik_fit, "MEET_SLACK", 0.0)
    assert sinelik_fit._meets(y, T, fam, sub, first, size, None) is None


def test_a_ranking_past_its_give_up_line_takes_the_fit_s_information(monkeypatch, record_fit):
    """A ranking whose ln L is above its give-up line (the family leads its rival by 50)
    cannot be ranked out: after its first step its passes take their information as
    fit_sine_ml's do (every chunk at 2^15 samples, not every RANK_INFO_SAMPLES-th), and it
    ends at fit_sine_ml's maximum (within 0.01 standard errors)."""
    y, model, fam, here, _, full = record_fit
    strides: list[int] = []
    inner = SineLikelihood.scores_information

    def recorded(lik, x, stride=1):
        if lik.N == N:
            strides.append(stride)
        return inner(lik, x, stride)

    monkeypatch.setattr(SineLikelihood, "scores_information", recorded)
    rank = rank_sine_law(
        y, T, model, fam, here, rival_loglik=-0.5 * full.cost - 50.0, rival_n_params=full.x.size
    )
    assert not rank.ranked_out
    assert strides[0] == N // sinelik_fit.RANK_INFO_SAMPLES
    assert len(strides) >= 2
    assert set(strides[1:]) == {1}
    se = np.sqrt(np.diag(full.cov))
    assert np.all(np.abs(rank.fit.x - full.x) <= 0.01 * se)


@pytest.mark.slow
def test_the_meter_fits_the_chosen_law_once(monkeypatch):
    """The meter's ML on a uniform record of 2^15 samples (about 30 CPU-s): the uniform,
    not ranked out, is fitted to its maximum by its ranking, and its fit from its own start
    meets that maximum (the message says so); with the meeting test disabled (a chi^2
    level of 0) the second search runs, and the estimate is the same within 0.01 stated
    errors."""
    y, _, _, _, _ = _setting(6)
    m = ji.measure_jitter(y, T)
    assert m.family == "uniform"
    assert "met this maximum" in m.fit.message
    monkeypatch.setattr(sinelik_fit, "MEET_LEVEL", 0.0)
    again = ji.measure_jitter(y, T)
    assert again.family == "uniform"
    assert "met this maximum" not in again.fit.message
    assert abs(again.jitter_std - m.jitter_std) <= 0.01 * m.jitter_std_stderr


def test_a_ranking_from_its_presearched_start_is_the_same_ranking():
    """rank_sine_law from rank_start's point (the meter's, after ordering the laws by
    their subsample BIC) is the ranking from the start itself, bit for bit; on a uniform
    record the uniform's subsample BIC is below the Gaussian's (it is ranked first)."""
    y, model, fam, here, _ = _setting(7)
    gauss = ji.GaussianFamily(sigma_max=10 * T, sigma_min=1e-9 * T)
    # (a rival far ahead: each ranking stops after its first step on the record)
    rival = {"rival_loglik": 1e9, "rival_n_params": here.size}
    pre = rank_start(y, T, model, fam, here)
    assert isinstance(pre, RankStart)
    assert pre.fitted
    assert pre.samples == N // 4
    direct = rank_sine_law(y, T, model, fam, here, **rival)
    via = rank_sine_law(y, T, model, fam, pre, **rival)
    assert np.array_equal(direct.fit.x, via.fit.x)
    assert direct.fit.cost == via.fit.cost
    assert direct.ranked_out
    assert via.ranked_out
    assert direct.fit.nfev == via.fit.nfev
    g_pre = rank_start(y, T, model, gauss, np.r_[JITTER, here[1:]])
    assert pre.bic() < g_pre.bic()


def test_a_start_in_the_maximum_s_bowl_is_not_searched_at_all(monkeypatch, record_fit):
    """A start one standard error (of the whole record) from ``found`` in the phase and the
    jitter: met at once, with no search on the subsample either (one score pass of the
    subsample, at ``found``; before, the subsample's search from the start ran first); a
    start 40 standard errors off in the phase: not met at once (its subsample search
    runs, then the test at its optimum)."""
    y, model, fam, _, _, first = record_fit
    se = np.sqrt(np.diag(first.cov))
    k = [first.names.index("phase_rad"), 0]
    sub_passes = {"n": 0}
    inner = SineLikelihood.scores_information

    def counted(lik, x, stride=1):
        if lik.N < N:
            sub_passes["n"] += 1
        return inner(lik, x, stride)

    monkeypatch.setattr(SineLikelihood, "scores_information", counted)
    near = first.x.copy()
    near[k] += se[k]
    met = fit_sine_ml(y, T, model, fam, near, found=first)
    assert "met this maximum" in met.message
    assert sub_passes["n"] == 1
    far = first.x.copy()
    far[k[0]] += 40.0 * se[k[0]]
    sub_passes["n"] = 0
    fit_sine_ml(y, T, model, fam, far, found=first)
    assert sub_passes["n"] >= 3


def test_a_search_that_cannot_reach_the_maximum_found_is_given_up(record_fit):
    """``found`` 1e4 above in ln L (its cost lowered; x moved 40 standard errors in the
    phase, so that neither the start nor its subsample optimum meets it): the search from
    the start, whose upper estimate (ln L + RANK_SAFETY x its predicted further gain) stays
    below that, is given up after RANK_MIN_STEPS steps, and ``found`` is the fit, its
    message saying so; with ``found`` at its own ln L the search runs to its maximum."""
    y, model, fam, _, there, first = record_fit
    k = first.names.index("phase_rad")
    x = first.x.copy()
    x[k] += 40.0 * math.sqrt(first.cov[k, k])
    high = replace(first, x=x, cost=first.cost - 2e4)
    got = fit_sine_ml(y, T, model, fam, there, found=high)
    assert got.cost == high.cost
    assert "was given up after" in got.message
    assert got.nfev - high.nfev <= sinelik_fit.RANK_MIN_STEPS + 2
    level = replace(first, x=x)
    searched = fit_sine_ml(y, T, model, fam, there, found=level)
    assert "given up" not in searched.message
    assert searched.status is ji.FitStatus.CONVERGED
    assert abs(searched.cost - first.cost) < 1e-6 * abs(first.cost)
