"""The steady-state response to a multisine: closed-form jittered moments (Response.
jitter_moments, the tones' (S1)-(S2)) against the node route (the same signal with the hook
switched off) and a Monte Carlo over jitter draws."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji
from jitterid.moments.sample import sample_moments
from jitterid.systems.model import Signal
from jitterid.systems.tf import Response

U = ji.Multisine(
    [0.05, 0.13, 0.31], [1.0, 0.5, 0.3], end=1e9, phases=[0.1, 1.0, 2.0], steady_state=True
)
TF = ji.TransferFunction([1.0, 6.25], [1.0, 3.0, 6.25])  # a zero: D = 0 but not strictly trivial


def _node_route(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(Response, "jitter_moments", Signal.jitter_moments)


@pytest.mark.parametrize(
    "law", [ji.Uniform(0.5), ji.Gaussian(0.2), ji.Shifted(ji.Uniform(0.3), 0.1), ji.NoJitter()]
)
def test_closed_form_agrees_with_the_node_route(law, monkeypatch):
    sig = TF.response(U)
    fast = sample_moments(sig, law, 1.0, 300)
    with monkeypatch.context() as m:
        _node_route(m)
        ref = sample_moments(sig, law, 1.0, 300)
    np.testing.assert_allclose(fast.mean, ref.mean, atol=1e-10)
    np.testing.assert_allclose(fast.var, ref.var, atol=1e-10)


def test_closed_form_against_monte_carlo():
    sig = TF.response(U)
    law = ji.Uniform(0.5)
    fast = sample_moments(sig, law, 1.0, 60)
    rng = np.random.default_rng(0)
    R = 20000
    vals = sig(np.arange(60.0) + law.sample((R, 60), rng))
    se = vals.std(0) / np.sqrt(R)
    assert np.max(np.abs(fast.mean - vals.mean(0)) / se) < 4.5
    np.testing.assert_allclose(fast.var, vals.var(0), rtol=0.05, atol=1e-4)


def test_switched_on_multisine_keeps_the_node_route():
    u = ji.Multisine([0.1], [1.0], end=100.0)
    assert TF.response(u).jitter_moments(ji.Uniform(0.2), 1.0, 5) is None
    steady = ji.Multisine([0.1], [1.0], end=100.0, steady_state=True)
    assert TF.response(steady).jitter_moments(ji.Uniform(0.2), 1.0, 5, higher=True) is None


def test_fit_is_the_same_by_either_route(monkeypatch):
    """One tone, N = 400, a Gaussian family: the closed form changes the cost (5x less CPU
    here), not the estimate."""
    rng = np.random.default_rng(1)
    u = ji.Multisine([0.17], [1.0], end=1e9, steady_state=True)
    data = ji.simulate(
        ji.TransferFunction([2.0], [1.0, 1.0]),
        u,
        ji.Uniform(0.3),
        T=1.0,
        N=400,
        noise_std=0.01,
        rng=rng,
    )
    fast = ji.fit(data, ji.RationalModel(0, 1), ji.GaussianFamily(), "gaussian")
    with monkeypatch.context() as m:
        _node_route(m)
        slow = ji.fit(data, ji.RationalModel(0, 1), ji.GaussianFamily(), "gaussian")
    assert fast.success
    np.testing.assert_allclose(fast.x, slow.x, rtol=1e-5)
