"""The ML stage's starts: a jitter family is never searched only from a jitter scale of zero.

The exact likelihood is even in a jitter family's scale, so its gradient vanishes at zero
jitter: a search started there (BCLS stops at its boundary minimum sigma ~ 1e-11 in about one
realization in 64 on Table 2's system with Gaussian jitter) used to report CONVERGED at
-2 ln L ~ +6500 where the maximum is ~ -835. Referee: the likelihood's own search started at
the truth (ExactLikelihood.maximise; a fit from there ends at the same point, 6 x dearer for
its checks).
"""

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation import ml
from jitterid.estimation.problem import Problem

T, N, NOISE = 1.0, 200, 0.01
TRUTH = np.array([6.25, -1.5, 2.0])
TOL = 1e-3  # in -2 ln L; the searches stop at a Newton decrement of 1e-8


def _data(seed, law):
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(N * T + 2, rng)
    return ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, N, NOISE, rng)


def _maximum(data, family, start):
    """The referee: the maximum of ln L that the likelihood's search from ``start`` (at the
    truth) reaches, as (x, -2 ln L): the estimate and cost of an ``ml`` fit."""
    lik = ji.ExactLikelihood(ji.PolePairGain(), family, data.u, T, N, NOISE)
    x, loglik, converged, message, _ = lik.maximise(data.y, start)
    assert converged, message
    return x, -2 * loglik


@pytest.fixture(scope="module")
def at_zero():
    """Seed 61: BCLS with the Gaussian family stops at sigma ~ 4e-11 (a boundary minimum)."""
    data = _data(61, ji.Gaussian(0.1))
    bcls = ji.fit(data, ji.PolePairGain(), ji.GaussianFamily(), method="bcls")
    # the search ended at the boundary minimum, which the checks flag (jitter is detected)
    assert bcls.status in (ji.FitStatus.CONVERGED, ji.FitStatus.AT_BOUND), bcls.message
    assert bcls.x[0] < 1e-9, bcls.x  # the premise of the test
    return data, bcls, _maximum(data, ji.GaussianFamily(), np.r_[0.1, TRUTH])


@pytest.mark.parametrize("sigma0", [None, 3e-11, 1e-12])
def test_ml_from_a_zero_jitter_start_vector_reaches_the_maximum(at_zero, sigma0):
    data, bcls, (best_x, best_cost) = at_zero
    start = np.r_[bcls.x[0] if sigma0 is None else sigma0, bcls.x[1:]]
    res = ji.fit(data, ji.PolePairGain(), ji.GaussianFamily(), method="ml", start=start)
    assert res.cost == pytest.approx(best_cost, abs=TOL) or not res.success
    assert res.success, res.message
    assert res.params["sigma"] == pytest.approx(best_x[0], rel=1e-3)


def test_ml_from_a_zero_jitter_bcls_result_reaches_the_maximum(at_zero):
    data, bcls, (best_x, best_cost) = at_zero
    res = ji.fit(data, ji.PolePairGain(), ji.GaussianFamily(), method="ml", start=bcls)
    assert res.cost == pytest.approx(best_cost, abs=TOL) or not res.success
    assert res.success, res.message
    np.testing.assert_allclose(res.x, best_x, rtol=1e-3)


def test_ml_uniform_family_from_zero_width():
    data = _data(5, ji.Uniform(0.2))
    fam = ji.UniformFamily()
    _, best_cost = _maximum(data, fam, np.r_[0.2, TRUTH])
    res = ji.fit(data, ji.PolePairGain(), fam, method="ml", start=np.r_[3e-11, TRUTH])
    assert res.success, res.message
    assert res.cost == pytest.approx(best_cost, abs=TOL)


def test_a_stop_at_zero_jitter_is_restarted_from_a_wider_scored_start(at_zero, monkeypatch):
    """The safety net behind the scoring: even if the search stopped at zero jitter (here
    forced: the first search returns its start, at zero jitter, as converged), the stop is
    not reported while a scored start with a jitter std that is not zero remains; the
    restart's better end is kept."""
    data, bcls, (_, best_cost) = at_zero
    real_start, real_search = ml._ml_start, ml._search
    calls = []

    def zero_first(problem, x0):
        starts, n = real_start(problem, x0)
        zero = [s for s in starts if s[1][0] < 1e-9]
        assert zero
        return [(-np.inf, zero[0][1])] + [s for s in starts if s[1][0] >= 1e-9], n

    def stuck_first(problem, x0, max_nfev, tol=None):
        calls.append(x0)
        if len(calls) == 1:
            return x0, -2 * problem.likelihood.loglik(x0, problem.data.y), True, "converged", 1
        return real_search(problem, x0, max_nfev, tol)

    monkeypatch.setattr(ml, "_ml_start", zero_first)
    monkeypatch.setattr(ml, "_search", stuck_first)
    res = ji.fit(
        data, ji.PolePairGain(), ji.GaussianFamily(), method="ml", start=np.r_[3e-11, bcls.x[1:]]
    )
    assert len(calls) == 2
    assert calls[0][0] < 1e-9 < calls[1][0]
    assert res.success, res.message
    assert "restart" in res.message
    assert res.cost == pytest.approx(best_cost, abs=TOL)


def test_every_family_gets_several_scored_starts(at_zero):
    data, bcls, _ = at_zero
    for fam, x0 in (
        (ji.GaussianFamily(), np.r_[3e-11, bcls.x[1:]]),
        (ji.UniformFamily(), np.r_[3e-11, bcls.x[1:]]),
        (ji.SumOfUniformsFamily(), np.r_[2.0, 3e-11, bcls.x[1:]]),
    ):
        problem = Problem(data, ji.PolePairGain(), fam, "ml", ji.default_frequencies(N, T), NOISE)
        starts, n = ml._ml_start(problem, x0)
        assert n == len(starts) >= 3
        scores = [v for v, _ in starts]
        assert scores == sorted(scores)
        stds = [problem.likelihood.split(c)[0].std for _, c in starts]
        assert max(stds) > 0.01  # some start is far from zero jitter


class _MyUniformFamily(ji.UniformFamily):
    """A subclass: no analytic scale score (it might change the law), so differences."""


@pytest.mark.parametrize("family", [ji.UniformFamily(), _MyUniformFamily()])
def test_scale_scores_match_differences_whether_analytic_or_not(family):
    """The analytic scale score (tau / a) s'(t) includes the moving support edges of the
    uniform law; a family the likelihood does not know is differenced with new nodes."""
    data = _data(2, ji.Uniform(0.3))
    n = 60
    lik = ji.ExactLikelihood(ji.PolePairGain(), family, data.u, T, n, NOISE)
    x = np.r_[0.3, TRUTH]
    y = data.y[:n]
    _, G = lik.scores(x, y)
    h = 1e-5 * x[0]
    up, down = x.copy(), x.copy()
    up[0] += h
    down[0] -= h
    fd = (lik.logpdf(up, y) - lik.logpdf(down, y)) / (2 * h)
    np.testing.assert_allclose(G[:, 0], fd, rtol=1e-4, atol=1e-4 * np.max(np.abs(fd)))
