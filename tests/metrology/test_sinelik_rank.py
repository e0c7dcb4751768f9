"""The law ranking of the structured sine likelihood (jitterid.metrology.sinelik_fit,
rank_sine_law, and the meter's ML with several laws): a family is given up only where
even the upper estimate of its maximum cannot come within the margin of the leading
family; the referee is the full route (every family fitted to its maximum)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.jitter.regular import DualDiracFamily
from jitterid.metrology import meter
from jitterid.metrology.reading import law_evidence
from jitterid.metrology.sinelik import RANK_MARGIN_BIC, fit_sine_ml, rank_sine_law
from jitterid.systems.tones import SineWave

T = 1 / 7e9
JITTER = 100e-15  # std of every truth, s (2 pi f sigma = 6.3e-4 rad at 1 GHz)
NOISE = 50e-6


def _record(law: str, log2n: int, seed: int) -> tuple[np.ndarray, float]:
    """The issue-26 record (a coherent ~1 GHz tone at 7 GS/s, amplitude 0.49, 50 uV noise)
    with jitter of std JITTER drawn from ``law``; returns (y, f)."""
    N = 1 << log2n
    cyc = round(1e9 * N * T)
    cyc += 1 - cyc % 2
    f = cyc / (N * T)
    rng = np.random.default_rng(seed)
    if law == "gaussian":
        tau = JITTER * rng.standard_normal(N)
    elif law == "uniform":
        tau = JITTER * math.sqrt(3.0) * rng.uniform(-1.0, 1.0, N)
    else:  # dual Dirac: rj = std / 2, dj from the rest of the variance
        rj = 0.5 * JITTER
        dj = 2.0 * math.sqrt(JITTER**2 - rj**2)
        tau = rj * rng.standard_normal(N) + 0.5 * dj * rng.choice([-1.0, 1.0], N)
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + 0.4)
    return y + NOISE * rng.standard_normal(N), f


def _families():
    return {
        "gaussian": ji.GaussianFamily(sigma_max=10 * T, sigma_min=1e-9 * T),
        "uniform": ji.UniformFamily(a_max=20 * T, a_min=1e-9 * T),
        "dual-dirac": DualDiracFamily(rj_max=10 * T, rj_min=1e-9 * T, dj_max=20 * T),
    }


def _gaussian_fit(y, f):
    fam = _families()["gaussian"]
    model = SineWave(band_hz=(0.99 * f, 1.01 * f))
    start = np.r_[JITTER * 1.2, 0.49, 0.4, f, 0.0, NOISE * 1.1]
    return model, fit_sine_ml(y, T, model, fam, start)


@functools.cache
def _gaussian_record_fit(log2n: int, seed: int):
    """A Gaussian record, its model and its Gaussian maximum: (y, f, model, g). Several
    tests rank or fit other families from the same record's Gaussian optimum: fitted once
    per record (the results are only read)."""
    y, f = _record("gaussian", log2n, seed)
    model, g = _gaussian_fit(y, f)
    return y, f, model, g


@functools.cache
def _full_fit(name: str, log2n: int, seed: int):
    """The family ``name`` fitted to its maximum by fit_sine_ml on that record, from the
    start the ranking takes (the Gaussian optimum's std and signal): (start, fit)."""
    y, _, model, g = _gaussian_record_fit(log2n, seed)
    fam = _families()[name]
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    return start, fit_sine_ml(y, T, model, fam, start)


def test_a_family_that_can_win_is_fitted_as_fit_sine_ml_fits_it():
    """Against its own rival (its maximum): not ranked out, and the same fit, bit for bit,
    as fit_sine_ml from the same start."""
    y, _, model, _ = _gaussian_record_fit(12, 1)
    fam = _families()["uniform"]
    start, full = _full_fit("uniform", 12, 1)
    rank = rank_sine_law(
        y, T, model, fam, start, rival_loglik=-0.5 * full.cost, rival_n_params=full.x.size
    )
    assert not rank.ranked_out
    assert rank.fit.cost == full.cost
    assert np.array_equal(rank.fit.x, full.x)
    assert rank.loglik_upper == -0.5 * full.cost
    assert rank.fit.status is full.status


@pytest.mark.parametrize(
    ("name", "log2n"),
    [
        ("uniform", 12),
        ("dual-dirac", 12),
        # on every 4th sample first, then on the whole record (about 20 CPU-s each)
        pytest.param(
            "uniform",
            15,
            marks=[
                pytest.mark.slow,
                pytest.mark.xfail(
                    strict=True,
                    reason="since the full fit at 2^15 starts from its own subsample optimum "
                    "(sinelik_fit._fit_subsample_size), it reaches the maximum in 3 "
                    "evaluations and the ranking takes 6: at this size the ranking saves "
                    "nothing (its upper estimate still bounds the maximum)",
                ),
            ],
        ),
        pytest.param("dual-dirac", 15, marks=pytest.mark.slow),
    ],
)
def test_a_ranked_out_family_s_upper_estimate_bounds_its_maximum(name, log2n):
    """On a Gaussian record, from the Gaussian optimum: the uniform and the dual Dirac are
    given up (after a few steps, fewer than their full fits take), each with an upper
    estimate at least the maximum its full fit reaches, and a status that does not claim
    convergence (no standard errors). At 2^15 samples the ranking starts from the family's
    optimum on a subsample."""
    y, _, model, g = _gaussian_record_fit(log2n, 1)
    fam = _families()[name]
    start, full = _full_fit(name, log2n, 1)
    rank = rank_sine_law(
        y, T, model, fam, start, rival_loglik=-0.5 * g.cost, rival_n_params=g.x.size
    )
    assert rank.ranked_out, rank.fit.message
    assert "ranked out" in rank.fit.message
    assert rank.fit.status is ji.FitStatus.MAX_EVALUATIONS
    assert np.all(np.isnan(rank.fit.cov))
    assert rank.fit.nfev < full.nfev
    assert rank.loglik_upper >= -0.5 * full.cost
    # and it is behind by the margin: its BIC bound stands RANK_MARGIN_BIC above
    bic_rank = full.x.size * math.log(y.size) - 2 * rank.loglik_upper
    assert bic_rank - (g.cost + g.x.size * math.log(y.size)) >= RANK_MARGIN_BIC


def test_meter_reports_ranked_out_laws_honestly():
    """The meter's ML with the default three laws on a Gaussian record: the uniform and
    the dual Dirac ranked out, said in the candidates and the summary; the law chosen by a
    BIC margin counted against their upper estimates (a lower bound on the margin)."""
    y, _ = _record("gaussian", 12, 0)
    m = ji.measure_jitter(y, T, method="ml")
    assert m.family == "gaussian"
    by = {c.name: c for c in m.laws}
    assert by["uniform"].ranked_out
    assert by["dual-dirac"].ranked_out
    assert not by["gaussian"].ranked_out
    assert by["uniform"].status is ji.FitStatus.MAX_EVALUATIONS
    ev = law_evidence(m)
    assert ev.verdict == "chosen"
    assert ev.delta_bic >= RANK_MARGIN_BIC
    assert "ranked out" in m.summary()
    assert abs(m.jitter_std - JITTER) < 4 * m.jitter_std_stderr


def _never_rank(monkeypatch):
    """The full route: rank_sine_law with no rival never gives up, and no family is ranked
    out on its subsample (every family fitted to its maximum from the same starts as before
    the ranking)."""
    monkeypatch.setattr(meter, "rank_on_subsample", lambda *args, **kw: None)
    orig = meter.rank_sine_law

    def full(*args, **kw):
        kw["rival_loglik"] = -math.inf
        return orig(*args, **kw)

    monkeypatch.setattr(meter, "rank_sine_law", full)


def _same_choice(law, seed, log2n, monkeypatch):
    y, _ = _record(law, log2n, seed)
    ranked = ji.measure_jitter(y, T, method="ml")
    with monkeypatch.context() as mp:
        _never_rank(mp)
        full = ji.measure_jitter(y, T, method="ml")
    assert not any(c.ranked_out for c in full.laws)
    assert ranked.family == full.family == law
    e_r, e_f = law_evidence(ranked), law_evidence(full)
    assert e_r.verdict == e_f.verdict
    assert e_r.delta_bic <= e_f.delta_bic + 1e-6  # the ranked margin is a lower bound
    assert ranked.jitter_std == full.jitter_std  # the chosen fit is the same fit


@pytest.mark.slow  # about 4 CPU-minutes: the full route fits every law to its maximum
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("law", ["gaussian", "uniform", "dual-dirac"])
def test_ranking_chooses_the_law_the_full_route_chooses(law, seed, monkeypatch):
    _same_choice(law, seed, 12, monkeypatch)


@pytest.mark.slow  # about 2 CPU-minutes
def test_ranking_from_a_subsample_chooses_the_law_the_full_route_chooses(monkeypatch):
    """At 2^15 samples (the ranking starts from each law's optimum on every 4th sample)."""
    _same_choice("gaussian", 2, 15, monkeypatch)


# (seed 2, the same claim on another record, in the slow run: seed 1's record and Gaussian
# fit are shared with the tests above)
@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_dual_dirac_ranking_starts_near_the_nested_gaussian(seed):
    """On a Gaussian record the dual Dirac's ranking starts from the Gaussian optimum with
    RANK_DJ_SHARE of the variance in dj (near dj = 0, where ln L is close to quadratic in
    dj^2), so it is ranked out in at most 3 evaluations with an upper estimate within 0.05
    of the nested Gaussian's maximum (from the even split: 4 evaluations, 0.3-0.45 above;
    that it bounds the full fit's maximum: the test above)."""
    y, _, model, g = _gaussian_record_fit(12, seed)
    fam = _families()["dual-dirac"]
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    rank = rank_sine_law(
        y, T, model, fam, start, rival_loglik=-0.5 * g.cost, rival_n_params=g.x.size
    )
    assert rank.ranked_out, rank.fit.message
    assert rank.fit.nfev <= 3
    assert 0.0 <= rank.loglik_upper + 0.5 * g.cost < 0.05


def test_a_family_climbing_faster_than_its_newton_model_is_not_ranked_out():
    """At a large phase spread (0.6 rad, N = 1000) a record whose jitter is mostly
    deterministic (dual Dirac, rj = std / 3): ranked from the Gaussian optimum (as the
    meter ranks it) against the uniform's maximum, the dual Dirac's ln L rises about 3 x
    faster than the Newton model predicts for its first steps, so the predicted further
    gain bounds nothing. It is
    fitted to its maximum (the referee: fit_sine_ml from the truth), far above the
    uniform's; before the upper estimate was scaled by the steps' realised / predicted
    gain it was ranked out after two steps with an "upper
    estimate" 270 below that maximum and the uniform law was reported."""
    Ts, F, s = 1e-3, 123.0, 0.6
    sig = s / (2 * np.pi * F)
    rng = np.random.default_rng([27, 2, 60, 2])
    rj = sig / 3
    tau = math.sqrt(sig**2 - rj**2) * rng.choice([-1.0, 1.0], 1000) + rj * rng.normal(0, 1, 1000)
    t = np.arange(1000) * Ts + tau
    y = np.sin(2 * np.pi * F * t + 1.0) + 0.1 + 1e-2 * rng.normal(0, 1, 1000)
    fams = {
        "gaussian": ji.GaussianFamily(sigma_max=2 * Ts, sigma_min=1e-9 * Ts),
        "uniform": ji.UniformFamily(a_max=4 * Ts, a_min=1e-9 * Ts),
        "dual-dirac": DualDiracFamily(rj_max=2 * Ts, rj_min=1e-9 * Ts, dj_max=4 * Ts),
    }
    model = SineWave(band_hz=(0.99 * F, 1.01 * F))
    rest = np.r_[1.0, 1.0, F, 0.1, 1e-2]
    g = fit_sine_ml(y, Ts, model, fams["gaussian"], np.r_[sig, rest])
    u = fit_sine_ml(y, Ts, model, fams["uniform"], np.r_[sig * math.sqrt(3), rest])
    fam = fams["dual-dirac"]
    truth = fit_sine_ml(y, Ts, model, fam, np.r_[rj, 2 * math.sqrt(sig**2 - rj**2), rest])
    assert -0.5 * truth.cost > -0.5 * u.cost + 100  # the dual Dirac wins by far
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    rank = rank_sine_law(
        y, Ts, model, fam, start, rival_loglik=-0.5 * u.cost, rival_n_params=u.x.size
    )
    assert not rank.ranked_out, rank.fit.message
    assert rank.fit.status is ji.FitStatus.CONVERGED
    assert abs(rank.fit.cost - truth.cost) < 1e-3
    assert abs(rank.fit.jitter_std - truth.jitter_std) < 0.1 * rank.fit.jitter_std_stderr


def _mixture_family():
    return ji.GaussianScaleMixtureFamily(sigma_max=10 * T, sigma_min=1e-9 * T)


def _mixture_maximum(y, T_, model, fam, g):
    """The scale mixture's maximum of ln L: the best of full fits from rho = 0.05, 0.3, 0.6
    at the Gaussian's std (the referee of the ranking's upper estimate)."""
    fits = [
        fit_sine_ml(y, T_, model, fam, np.r_[g.jitter_std, r, g.x[1:]]) for r in (0.05, 0.3, 0.6)
    ]
    return max(-0.5 * f.cost for f in fits)


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow), 4])
def test_scale_mixture_ranked_from_the_nested_gaussian_is_bounded(seed):
    """On a Gaussian record, ranked from the Gaussian's maximum (rho = 0: nested=True, as
    the meter ranks it): given up after at most two passes of the record, its upper
    estimate at least the mixture's maximum from three other starts (seeds 1 and 4: the
    record's kurtosis above 3, the maximum 0.18 and 0.37 above the Gaussian's, the upper
    estimates 0.50 and 0.94; seed 0: the maximum at rho = 0, ranked out at the start)."""
    y, _, model, g = _gaussian_record_fit(12, seed)
    fam = _mixture_family()
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    rank = rank_sine_law(
        y, T, model, fam, start, rival_loglik=-0.5 * g.cost, rival_n_params=g.x.size, nested=True
    )
    assert rank.ranked_out, rank.fit.message
    assert rank.fit.nfev <= 2
    assert rank.loglik_upper >= _mixture_maximum(y, T, model, fam, g) - 1e-6


def test_scale_mixture_ranked_from_the_nested_gaussian_is_fitted_where_it_wins():
    """A record whose jitter is a scale mixture (stds 0.6 : 1.28 of the rms, 0.3 rad,
    N = 1000; ln L 9.2 above the Gaussian's): ranked from the Gaussian's maximum it is not
    given up, and its search
    from there ends at the mixture's maximum (the referee: the best of three full fits)."""
    Ts, F, s = 1e-3, 123.0, 0.3
    sig = s / (2 * np.pi * F)
    rng = np.random.default_rng([31, 5, 30, 0])
    sc = np.where(rng.random(1000) < 0.5, 0.6, 1.28) / math.sqrt((0.36 + 1.28**2) / 2)
    tau = sig * sc * rng.normal(0, 1, 1000)
    y = np.sin(2 * np.pi * F * (np.arange(1000) * Ts + tau) + 1.0) + 0.1
    y = y + 1e-2 * rng.normal(0, 1, 1000)
    model = SineWave(band_hz=(0.99 * F, 1.01 * F))
    gfam = ji.GaussianFamily(sigma_max=2 * Ts, sigma_min=1e-9 * Ts)
    g = fit_sine_ml(y, Ts, model, gfam, np.r_[sig, 1.0, 1.0, F, 0.1, 1e-2])
    fam = ji.GaussianScaleMixtureFamily(sigma_max=2 * Ts, sigma_min=1e-9 * Ts)
    best = _mixture_maximum(y, Ts, model, fam, g)
    assert best > -0.5 * g.cost + 0.5 * math.log(1000)  # its BIC beats the Gaussian's
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    rank = rank_sine_law(
        y, Ts, model, fam, start, rival_loglik=-0.5 * g.cost, rival_n_params=g.x.size, nested=True
    )
    assert not rank.ranked_out, rank.fit.message
    assert rank.fit.status is ji.FitStatus.CONVERGED
    assert abs(-0.5 * rank.fit.cost - best) < 1e-3


def test_a_dual_dirac_is_not_ranked_from_the_nested_gaussian():
    """nested=True leaves a dual Dirac's ranking as it was (its score at dj = 0 is blind to
    the shape at a fixed std: sinelik_fit._nested_start): the same fit, bit for bit."""
    y, _, model, g = _gaussian_record_fit(12, 0)
    fam = _families()["dual-dirac"]
    start = np.r_[fam.start_for_std(g.jitter_std), g.x[1:]]
    kw = {"rival_loglik": -0.5 * g.cost, "rival_n_params": g.x.size}
    a = rank_sine_law(y, T, model, fam, start, nested=True, **kw)
    b = rank_sine_law(y, T, model, fam, start, **kw)
    assert a.ranked_out == b.ranked_out
    assert np.array_equal(a.fit.x, b.fit.x)
    assert a.loglik_upper == b.loglik_upper
