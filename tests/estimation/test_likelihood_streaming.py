"""The exact likelihood streamed chunk by chunk (jitterid.estimation.likelihood._Rule).

A rule with more nodes than ``node_budget`` is made again at every evaluation instead of
kept: the values, scores, information and Fisher information must be those of the kept
rule (the same nodes, the same arithmetic), and an evaluation must not hold the whole
rule in memory.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.likelihood import ExactLikelihood

T = 1.0


def _data(law, N, noise=0.01, seed=5):
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(N * T + 2, rng)
    data = ji.simulate(ji.PolePairGain().system([6.25, -1.5, 2.0]), u, law, T, N, noise, rng)
    return u, data.y


CASES = [
    # known law, the windowed rule (Table 2's setting), noise std estimated
    (ji.PolePairGain(), ji.Uniform(0.5), [6.25, -1.5, 2.0, 0.01], 0.01, None),
    # the full rule (noise large against the signal's slope)
    (ji.PolePairGain(), ji.Uniform(0.5), [6.25, -1.5, 2.0, 0.3], 0.3, False),
    # a family with a shape (n differenced at the same nodes) and a scale
    (ji.PolePairGain(), ji.SumOfUniformsFamily(), [1.5, 0.4, 6.25, -1.5, 2.0, 0.01], 0.01, None),
    # a family with a closed-form pdf gradient, and a delay
    (
        ji.Delayed(ji.PolePairGain()),
        ji.GaussianFamily(),
        [0.1, 6.25, -1.5, 2.0, 0.3, 0.01],
        0.01,
        None,
    ),
]


@pytest.mark.parametrize(("model", "jitter", "x", "noise", "window"), CASES, ids=str)
def test_streamed_rule_gives_the_kept_rules_values_scores_and_information(
    model, jitter, x, noise, window
):
    law = jitter if isinstance(jitter, ji.JitterLaw) else jitter.law(x[: len(jitter.param_names)])
    u, y = _data(law, 120, noise)
    kept = ExactLikelihood(model, jitter, u, T, y.size, None, window=window)
    streamed = ExactLikelihood(model, jitter, u, T, y.size, None, window=window, node_budget=0)
    for lik in (kept, streamed):
        lik.logpdf(x, y)  # designs the rule, makes (and keeps, or not) the nodes
    assert streamed._cache
    assert all(r.streamed for r in streamed._cache.values())
    assert all(not r.streamed for r in kept._cache.values())
    np.testing.assert_allclose(streamed.logpdf(x, y), kept.logpdf(x, y), rtol=0, atol=1e-10)
    (la, ga), (lb, gb) = streamed.scores(x, y), kept.scores(x, y)
    np.testing.assert_allclose(la, lb, rtol=0, atol=1e-10)
    np.testing.assert_allclose(ga, gb, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(
        streamed.information(x, y), kept.information(x, y), rtol=1e-10, atol=1e-8
    )


def test_streamed_fisher_information_equals_the_kept_rules():
    u, y = _data(ji.Uniform(0.5), 40, noise=0.05)
    x = [6.25, -1.5, 2.0]
    a = ExactLikelihood(ji.PolePairGain(), ji.Uniform(0.5), u, T, y.size, 0.05)
    b = ExactLikelihood(ji.PolePairGain(), ji.Uniform(0.5), u, T, y.size, 0.05, node_budget=0)
    np.testing.assert_allclose(b.fisher(x), a.fisher(x), rtol=1e-10)


def _peak_of_scores(N):
    u, y = _data(ji.Uniform(0.5), N)
    x = np.array([6.25, -1.5, 2.0, 0.01])
    lik = ExactLikelihood(ji.PolePairGain(), ji.Uniform(0.5), u, T, y.size, None, node_budget=0)
    lik.logpdf(x, y)  # the design and its pieces (kept: ~30 bytes per piece)
    nodes = sum(nd.t.size for nd in lik._nodes(x, *lik.split(x)[:2], y, 0.01))
    tracemalloc.start()
    lik.scores(x, y)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return nodes, peak


def test_a_streamed_evaluation_does_not_hold_the_whole_rule():
    """The peak traced memory of a streamed evaluation grows with N only through its
    outputs (ln p and the scores, ~40 bytes per sample), not through the rule's nodes
    (~90 per sample, ~50 bytes each when kept): one chunk's nodes at a time."""
    n1, p1 = _peak_of_scores(4000)
    n2, p2 = _peak_of_scores(16000)
    assert n2 - n1 > 1e6
    assert p2 - p1 < 0.05 * 50 * (n2 - n1), (p1, p2, n1, n2)
