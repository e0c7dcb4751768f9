"""The exact likelihood at a known noise std far below the samples' jitter spread has many
maxima; its search starts by a continuation in the noise std (ml._continuation, session 19).

Table 2's system, Gaussian jitter std 0.2, noise std 1e-4, N = 200 (the record below): from
the BCLS estimate the search ended CONVERGED at k0 = 7.24 (true 6.25), 2 ln L 132 below
the maximum that a search from the true parameters reaches, with a barrier of 39 between.
The referee: that search from the truth, on the same data (the likelihood's own search,
ExactLikelihood.maximise: no continuation, and none of fit()'s checks, whose criterion at
the structure's default starts was 5 of the 6 CPU-s of a referee fit(..., start=truth))."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji

THETA = np.array([6.25, -1.5, 2.0])


def _record(seed: int, noise: float, law: ji.JitterLaw) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(202.0, rng)
    truth = ji.PolePairGain().system(THETA)
    return ji.simulate(truth, u, law, T=1.0, N=200, noise_std=noise, rng=rng)


def test_a_low_noise_record_reaches_the_maximum_a_search_from_the_truth_reaches():
    law = ji.Gaussian(0.2)
    d = _record(7001, 1e-4, law)
    res = ji.fit(d, ji.PolePairGain(), law, method="ml")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert "continuation in the noise std from 100 times the known one" in res.message
    lik = ji.ExactLikelihood(ji.PolePairGain(), law, d.u, d.T, d.N, d.noise_std)
    x_ref, loglik_ref, converged, message, _ = lik.maximise(d.y, THETA)
    assert converged, message
    referee_cost = -2 * loglik_ref  # fit's cost for method 'ml'
    assert res.cost == pytest.approx(referee_cost, abs=1e-6 * abs(referee_cost))
    assert np.allclose(res.x, x_ref, rtol=1e-5)
    assert np.all(np.abs(res.x - THETA) < [0.1, 0.02, 0.02])  # (was 0.99, 0.12, 0.15 off)


def test_a_noise_near_the_jitter_spread_needs_no_continuation():
    law = ji.Gaussian(0.2)
    # the paper's noise std, 0.04 of the spread: 10 times it is above ROUGH_NOISE of it
    d = _record(7001, 1e-2, law)
    res = ji.fit(d, ji.PolePairGain(), law, method="ml")
    assert res.success, res.message
    assert "continuation" not in res.message
