"""A family ranked out on its ranking's subsample (jitterid.metrology.sinelik_subrank):
the referees are the family's exact ln L on the whole record at the subsample optimum
(the estimate's error within its stated standard deviations) and its maximum there (below
the stated upper bound), and the meter's choice without the subsample's ranking."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import sinelik_subrank
from jitterid.metrology.sinelik import (
    RankStart,
    SineLikelihood,
    fit_sine_ml,
    rank_on_subsample,
    rank_start,
)
from jitterid.metrology.sinelik_subrank import SUB_RANK_Z, subsample_estimate
from jitterid.systems.tones import SineWave

T = 1e-9
N = 1 << 15  # every 4th sample: the ranking's subsample of 2^13
JITTER = 3e-12  # 2 pi f sigma = 1.8e-3 rad at 97 MHz
NOISE = 30e-6


def _record(seed: int) -> tuple[np.ndarray, float]:
    """A 97 MHz tone at 1 GS/s (not coherent), amplitude 0.49, uniform jitter."""
    rng = np.random.default_rng(seed)
    f = 97.123e6 + rng.uniform(-1e5, 1e5)
    tau = JITTER * math.sqrt(3.0) * rng.uniform(-1.0, 1.0, N)
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + 0.3)
    return y + NOISE * rng.standard_normal(N), f


@pytest.fixture(scope="module")
def uniform_lead():
    """The record of seed 1, its model, and its uniform maximum (the leading law)."""
    y, f = _record(1)
    model = SineWave(band_hz=(0.99 * f, 1.01 * f))
    fam = ji.UniformFamily(a_max=20 * T, a_min=1e-9 * T)
    x0 = np.r_[fam.start_for_std(JITTER), 0.49, 0.3, f, 0.0, NOISE]
    lead = fit_sine_ml(y, T, model, fam, x0)
    assert lead.status is ji.FitStatus.CONVERGED
    return y, model, lead


@pytest.mark.parametrize(
    "family",
    [
        ji.DualDiracFamily(rj_max=10 * T, rj_min=1e-9 * T, dj_max=20 * T),
        ji.GaussianFamily(sigma_max=10 * T, sigma_min=1e-9 * T),
    ],
    ids=["dual-dirac", "gaussian"],
)
def test_the_estimate_and_the_bound_against_the_whole_record(uniform_lead, family):
    """On a uniform record the dual Dirac (about 2300 below in ln L) and the Gaussian
    (about 4600 below): the estimate of ln L_F at the subsample optimum within SUB_RANK_Z
    of its standard deviations of the exact value, the family's maximum on the whole
    record (searched from there) below the upper bound, and the family ranked out."""
    y, model, lead = uniform_lead
    start = rank_start(
        y, T, model, family, np.r_[family.start_for_std(lead.jitter_std), lead.x[1:]]
    )
    assert start.fitted
    got = subsample_estimate(y, T, family, start, lead)
    assert got is not None
    estimate, sd, climb = got
    exact = SineLikelihood(y, T, family).loglik(start.x)
    assert abs(exact - estimate) <= SUB_RANK_Z * sd
    peak = -0.5 * fit_sine_ml(y, T, model, family, start.x).cost
    assert exact <= peak <= estimate + SUB_RANK_Z * sd + climb
    rank = rank_on_subsample(y, T, model, family, start, lead)
    assert rank is not None
    assert rank.ranked_out
    assert rank.loglik_upper == pytest.approx(estimate + SUB_RANK_Z * sd + climb)
    assert rank.loglik_upper < -0.5 * lead.cost - 1000.0
    assert "ranked out on every 4th sample" in rank.fit.message
    assert rank.fit.status is ji.FitStatus.MAX_EVALUATIONS
    np.testing.assert_array_equal(rank.fit.x, start.x)


def test_a_family_near_the_lead_is_not_ranked_out_on_the_subsample(uniform_lead):
    """The uniform itself as the candidate (its subsample optimum against its own maximum:
    no deficit at all): not ranked out."""
    y, model, lead = uniform_lead
    fam = lead.jitter_model
    start = rank_start(y, T, model, fam, lead.x)
    assert rank_on_subsample(y, T, model, fam, start, lead) is None


def test_a_subsample_that_misses_the_record_s_phases_tells_nothing(uniform_lead):
    """A tone at fs/4 exactly: every 4th sample sits at one phase, where the record has
    four; the subsample's phase bins miss three of them, and nothing is estimated; a
    tone 0.37 bin off fs/4 the same (its every 4th sample drifts over 0.37 of a cycle, the
    record's four phases over the whole); at 97 MHz the subsample holds every phase."""
    _, _, lead = uniform_lead
    rng = np.random.default_rng(3)
    for f, told in ((0.25 / T, False), ((0.25 + 0.37 / N) / T, False), (0.097123 / T, True)):
        y = 0.49 * np.sin(2 * np.pi * f * np.arange(N) * T + 0.3)
        y = y + NOISE * rng.standard_normal(N)
        x = lead.x.copy()
        x[lead.names.index("frequency_hz")] = f
        start = RankStart(lead.x.copy(), 0.0, N // 4)
        got = subsample_estimate(y, T, lead.jitter_model, start, replace(lead, x=x))
        assert (got is not None) is told


@pytest.mark.slow
def test_the_meter_chooses_as_without_the_subsample_s_ranking(monkeypatch):
    """The meter's ML on a uniform record of 2^15 samples: the dual Dirac and the Gaussian
    are ranked out on the subsample (their reports say so) and the measurement is the one
    made with the subsample's ranking disabled (SUB_RANK_Z = inf): the same law, the same
    jitter std to 1e-9, fewer passes of the whole record."""
    y, _ = _record(2)
    passes = {"n": 0}
    inner = SineLikelihood.scores_information

    def counted(lik, x, stride=1):
        if lik.N == N:
            passes["n"] += 1
        return inner(lik, x, stride)

    monkeypatch.setattr(SineLikelihood, "scores_information", counted)
    m = ji.measure_jitter(y, T)
    with_sub = passes["n"]
    assert m.family == "uniform"
    out = [c.name for c in m.laws if c.ranked_out]
    assert "dual-dirac" in out
    monkeypatch.setattr(sinelik_subrank, "SUB_RANK_Z", math.inf)
    passes["n"] = 0
    again = ji.measure_jitter(y, T)
    assert again.family == "uniform"
    assert again.jitter_std == pytest.approx(m.jitter_std, rel=1e-9)
    assert with_sub < passes["n"]


def _other_record(kind: str, law: str, seed: int) -> tuple[np.ndarray, float, float, float | None]:
    """(y, T, f, q) of a 2^15-sample record: ``kind`` "coh" a coherent ~1 GHz tone at 7 GS/s
    (200 fs), "q12" a 97 MHz tone at 1 GS/s quantised to 12 bits (3 ps), else that tone
    as floats; ``law`` the jitter's ("t5": Student-t with 5 degrees of freedom)."""
    rng = np.random.default_rng(seed)
    if kind == "coh":
        Ts = 1 / 7e9
        cyc = round(1e9 * N * Ts)
        cyc += 1 - cyc % 2
        f, sj = cyc / (N * Ts), 200e-15
    else:
        Ts, f, sj = T, 97.123e6 + rng.uniform(-1e5, 1e5), JITTER
    tau = {
        "gaussian": lambda: sj * rng.standard_normal(N),
        "dd": lambda: 0.6 * sj * rng.standard_normal(N) + 0.8 * sj * rng.choice([-1.0, 1.0], N),
        "t5": lambda: sj * math.sqrt(3 / 5) * rng.standard_t(5, N),
    }[law]()
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * Ts + tau) + 0.3)
    y = y + NOISE * rng.standard_normal(N)
    q = None
    if kind == "q12":
        q = 2.0**-11
        y = q * np.round(y / q)
    return y, Ts, f, q


@pytest.mark.slow  # about 3 CPU-minutes: every law's maximum on the whole record
@pytest.mark.parametrize(
    ("kind", "law", "seed"),
    [("coh", "gaussian", 4), ("q12", "gaussian", 6), ("float", "dd", 3), ("float", "t5", 7)],
)
def test_the_bound_holds_on_other_records(kind, law, seed):
    """Against a Gaussian leader, each other default law on coherent, quantised,
    dual-Dirac and Student-t records: the estimate within SUB_RANK_Z standard deviations of
    the exact ln L at the subsample optimum, and the law's maximum on the whole record below
    the upper bound (whether or not it is ranked out)."""
    y, Ts, f, q = _other_record(kind, law, seed)
    model = SineWave(band_hz=(0.99 * f, 1.01 * f))
    sj = 200e-15 if kind == "coh" else JITTER
    gauss = ji.GaussianFamily(sigma_max=10 * Ts, sigma_min=1e-9 * Ts)
    lead = fit_sine_ml(
        y, Ts, model, gauss, np.r_[sj, 0.49, 0.3, f, 0.0, NOISE], quantisation_step=q
    )
    assert lead.status is ji.FitStatus.CONVERGED
    for family in (
        ji.UniformFamily(a_max=20 * Ts, a_min=1e-9 * Ts),
        ji.DualDiracFamily(rj_max=10 * Ts, rj_min=1e-9 * Ts, dj_max=20 * Ts),
        ji.GaussianScaleMixtureFamily(sigma_max=10 * Ts, sigma_min=1e-9 * Ts),
    ):
        x0 = np.r_[family.start_for_std(lead.jitter_std), lead.x[1:]]
        start = rank_start(y, Ts, model, family, x0, quantisation_step=q)
        got = subsample_estimate(y, Ts, family, start, lead, q)
        assert got is not None
        estimate, sd, climb = got
        exact = SineLikelihood(y, Ts, family, quantisation_step=q).loglik(start.x)
        assert abs(exact - estimate) <= SUB_RANK_Z * sd
        peak = -0.5 * fit_sine_ml(y, Ts, model, family, start.x, quantisation_step=q).cost
        assert peak <= estimate + SUB_RANK_Z * sd + climb
