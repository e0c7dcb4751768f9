"""The exact likelihood's rule serves a point away from the last evaluations, and the
check of the information equality after an ML fit (FitStatus.IRREGULAR, session 19)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import table2_post_context

import jitterid as ji
from jitterid.estimation.checks import post_checks
from jitterid.estimation.status import FitStatus

THETA = np.array([6.25, -1.5, 2.0])  # the paper's Table 2 system
FAR = [0.099, -0.094, 0.3]  # one of the structure's default starts: a flat, slow response


def _record(seed: int, n: int, noise: float) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n + 2.0, rng)
    truth = ji.PolePairGain().system(THETA)
    return ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=n, noise_std=noise, rng=rng)


def _likelihood(d: ji.SampledData) -> ji.ExactLikelihood:
    return ji.ExactLikelihood(ji.PolePairGain(), ji.Uniform(0.5), d.u, 1.0, d.N, d.noise_std)


@pytest.mark.parametrize("noise", [1e-2, 1e-3])
def test_a_rule_made_far_off_is_designed_again_where_it_must_serve(noise):
    d = _record(1000, 60, noise)
    referee = _likelihood(d).loglik(THETA, d.y)  # a rule designed at the point itself
    lik = _likelihood(d)
    lik.loglik(FAR, d.y)  # a check's start far off: the full rule, frozen there
    stale = lik.loglik(THETA, d.y)
    assert abs(stale - referee) > 0.1  # its panels were cut for the flat response
    lik.serve(THETA)
    assert lik.loglik(THETA, d.y) == pytest.approx(referee, rel=1e-12, abs=1e-9)


def test_serve_keeps_a_rule_designed_at_the_point(monkeypatch):
    d = _record(1000, 60, 1e-2)
    lik = _likelihood(d)
    lik.design(FAR)
    assert not lik.windowed  # the full rule, made there
    calls = []
    original = ji.ExactLikelihood.design
    monkeypatch.setattr(
        ji.ExactLikelihood, "design", lambda self, x: (calls.append(x), original(self, x))[1]
    )
    lik.serve(FAR)
    assert calls == []
    lik.serve(THETA)
    assert len(calls) == 1


@pytest.mark.parametrize(
    ("ratios", "flagged"),
    [
        ((0.1, 0.1, 0.1), True),
        ((0.02, 0.05, 0.15), True),
        ((0.1, 0.1, 1.0), False),  # one direction regular: not every direction fails
        ((0.3, 0.3, 0.3), False),
        ((1.0, 1.0, 1.0), False),
    ],
)
def test_scores_far_smaller_than_the_curvature_in_every_direction_are_irregular(ratios, flagged):
    lab = _record(1, 200, 1e-2)
    rng = np.random.default_rng(5)
    A = rng.standard_normal((3, 3))
    info = A @ A.T + 3 * np.eye(3)  # the observed information; cov its inverse
    cov = np.linalg.inv(info)
    # per-sample scores whose outer product is info^(1/2) diag(ratios) info^(1/2)
    w, V = np.linalg.eigh(info)
    root = V @ np.diag(np.sqrt(w)) @ V.T
    Q, _ = np.linalg.qr(rng.standard_normal((200, 3)))
    G = Q @ np.diag(np.sqrt(ratios)) @ root
    ctx = table2_post_context(lab, cov, scores=lambda v: G)
    status, message = post_checks(ctx, FitStatus.CONVERGED, "ok")
    assert (status is FitStatus.IRREGULAR) is flagged, message
    if flagged:
        assert f"{1 / max(ratios):.3g} times" in message
        assert "hard edges" in message
        assert "bcls" in message


def test_the_message_names_hard_edges_only_where_the_law_has_them():
    lab = _record(1, 200, 1e-2)
    cov = np.eye(3)
    G = np.sqrt(0.01 / 200) * np.ones((200, 3)) * np.eye(3)[np.arange(200) % 3]
    for law, hard in ((ji.Gaussian(0.2), False), (ji.SumOfUniformsFamily(), True)):
        ctx = table2_post_context(lab, cov, jitter=law, scores=lambda v: G)
        if isinstance(law, ji.JitterFamily):  # n = 0: the uniform law, hard edges
            ctx = dataclasses.replace(
                ctx,
                x=np.r_[0.0, 0.5, THETA],
                cov=np.eye(5),
                bounds=(*law.bounds, *ctx.bounds),
                names=(*law.param_names, *ctx.names),
                scores=lambda v: np.c_[G, G[:, :2]],
            )
        status, message = post_checks(ctx, FitStatus.CONVERGED, "ok")
        assert status is FitStatus.IRREGULAR, message
        assert ("hard edges" in message) is hard, message
        assert "a few samples" in message


@pytest.mark.slow  # the default run has this check on 20 other such records (2 CPU-s here):
# tests/estimation/test_likelihood.py::test_ml_error_bars_cover_the_truth_small_monte_carlo
# asserts that every ml fit of Table 2's setting (the same known law and noise) is
# successful, i.e. CONVERGED, not IRREGULAR
def test_regular_ml_fits_are_not_irregular():
    # Table 2's system, U(-0.5, 0.5) known, noise 1e-2: the largest generalized eigenvalue
    # of the scores' outer product to the information was 0.85-2.2 (session 19)
    for seed in range(3000, 3006):
        res = ji.fit(_record(seed, 200, 1e-2), ji.PolePairGain(), ji.Uniform(0.5), method="ml")
        assert res.status is FitStatus.CONVERGED, res.message


@pytest.mark.slow
def test_ml_on_a_record_with_almost_no_noise_and_a_hard_edged_law_is_irregular():
    # was CONVERGED with errors 20-1000 x the stated ones; now (after the noise std's
    # continuation, ml._continuation) IRREGULAR on 5 of 6 such records, this one included
    # (|z| up to 58, the truth 3.7 below the fit in 2 ln L); a moment criterion's errors hold
    # there (bcls: 35 of 36 intervals covering on 12 records)
    d = _record(7000, 200, 1e-6)
    res = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), method="ml")
    assert res.status is FitStatus.IRREGULAR, res.message
    bcls = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
    assert bcls.success, bcls.message
    z = (bcls.x - THETA) / np.sqrt(np.diag(bcls.cov))
    assert np.all(np.abs(z) < 3)
