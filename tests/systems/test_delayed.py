"""Input-output delay (Delayed, TransferFunction.delay_s) and its fits, with jitter of a non-zero
mean (Shifted) beside it: each against an independent referee (a shifted input, Monte Carlo
over jitter draws, the generic node evaluation, central differences, simulated records)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import jitterid as ji
from jitterid import finite_diff
from jitterid.estimation import jacobians
from jitterid.estimation.problem import Problem
from jitterid.moments.sample import moment_pass, sample_moments
from jitterid.systems.model import DelayedSignal

TRUTH = ji.TransferFunction([6.25], [1.0, 3.0, 6.25])
MODEL = ji.Delayed(ji.PolePairGain(), max_delay_s=10.0)


def _data(law: ji.JitterLaw, delay: float, seed: int, N: int = 200) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(N + 30.0, rng)
    tf = ji.TransferFunction(TRUTH.num, TRUTH.den, delay_s=delay)
    return ji.simulate(tf, u, law, T=1.0, N=N, noise_std=0.01, rng=rng)


# ---------------------------------------------------------------------------- the delayed system
def test_delayed_transfer_function_response_and_frequency_response() -> None:
    rng = np.random.default_rng(1)
    u = ji.telegraph_input(60.0, rng)
    d = 0.7
    tf = ji.TransferFunction(TRUTH.num, TRUTH.den, delay_s=d)
    # referee: the undelayed system driven by the input moved by d
    moved = ji.PiecewiseConstant(u.times + d, u.levels)
    t = np.linspace(0.0, 55.0, 2001)
    np.testing.assert_allclose(tf.response(u)(t), TRUTH.response(moved)(t), atol=1e-12)
    f = np.array([0.0, 0.1, 0.4])
    np.testing.assert_allclose(
        tf.frequency_response(f), TRUTH.frequency_response(f) * np.exp(-2j * np.pi * f * d)
    )
    assert tf.dcgain == pytest.approx(TRUTH.dcgain)
    assert "delay_s=0.7" in repr(tf)
    from jitterid import _serial

    again = _serial.decode(json.loads(json.dumps(_serial.encode(tf))))
    assert again.delay_s == d
    assert np.array_equal(again.den, tf.den)
    with pytest.raises(ValueError, match="delay_s must be finite"):
        ji.TransferFunction([1.0], [1.0, 1.0], delay_s=float("inf"))


@pytest.mark.parametrize(
    "law", [ji.NoJitter(), ji.Uniform(0.5), ji.Gaussian(0.2), ji.Shifted(ji.Uniform(0.3), 0.2)]
)
def test_moments_of_a_delayed_response_three_routes(law: ji.JitterLaw) -> None:
    """The modal path (the delay moved into the jitter) against the generic node evaluation
    of the delayed signal itself and a Monte Carlo over jitter draws."""
    rng = np.random.default_rng(2)
    u = ji.telegraph_input(230.0, rng)
    sig = ji.TransferFunction(TRUTH.num, TRUTH.den, delay_s=0.7).response(u)
    assert isinstance(sig, DelayedSignal)
    fast = sample_moments(sig, law, 1.0, 200)
    nodes = moment_pass(sig, law, 1.0, 200)  # evaluates s(t - d) at the nodes: no shift
    assert nodes.var is not None
    np.testing.assert_allclose(fast.mean, nodes.mean, atol=1e-9)
    np.testing.assert_allclose(fast.var, nodes.var, atol=1e-9)
    R = 4000
    vals = sig(np.arange(200.0) + law.sample((R, 200), rng))
    se = vals.std(0) / np.sqrt(R)
    assert np.max(np.abs(fast.mean - vals.mean(0)) / (se + 1e-3)) < 4.5


@pytest.mark.parametrize("jitter", [ji.Uniform(0.5), ji.UniformFamily()])
@pytest.mark.parametrize("method", ["bcls", "gaussian"])
def test_moment_derivatives_in_the_delay_against_central_differences(
    jitter: ji.JitterLaw | ji.JitterFamily, method: str
) -> None:
    data = _data(ji.Uniform(0.5), 0.7, seed=3)
    noise = None if method == "gaussian" else 0.01
    pr = Problem(data, MODEL, jitter, method, ji.default_frequencies(200, 1.0), noise)
    x = np.array([6.25, -1.5, 2.0, 0.7])
    if isinstance(jitter, ji.JitterFamily):
        x = np.r_[0.5, x]
    if noise is None:
        x = np.r_[x, 0.01]
    _, w, dm, dw = jacobians.moment_derivatives(pr, x)

    def both(v: np.ndarray) -> np.ndarray:
        m = jacobians.moments(pr, v)
        return np.r_[m.mean, m.var]

    for i, name in enumerate(pr.names):
        if name == "noise_std":
            continue
        ref = finite_diff.derivative(both, x, i, pr.bounds[i], rel=1e-5)
        scale = np.max(np.abs(ref[:200]))
        assert np.max(np.abs(ref[:200] - dm[i])) < 1e-6 * scale, name
        if w.size:
            assert np.max(np.abs(ref[200:] - dw[i])) < 1e-5 * np.max(np.abs(ref[200:])), name


@pytest.mark.parametrize("jitter", [ji.Uniform(0.5), ji.UniformFamily()])
def test_likelihood_score_of_the_delay_against_differences(
    jitter: ji.JitterLaw | ji.JitterFamily,
) -> None:
    data = _data(ji.Uniform(0.5), 0.7, seed=3)
    pr = Problem(data, MODEL, jitter, "ml", ji.default_frequencies(200, 1.0), 0.01)
    lik = pr.likelihood
    assert lik is not None
    x = np.array([6.25, -1.5, 2.0, 0.7])
    if isinstance(jitter, ji.JitterFamily):
        x = np.r_[0.5, x]
    g = lik.scores(x, data.y)[1].sum(0)
    for i in range(x.size):
        ref = finite_diff.derivative(
            lambda v: np.atleast_1d(lik.logpdf(v, data.y).sum()), x, i, lik.bounds[i], rel=1e-6
        )[0]
        assert g[i] == pytest.approx(ref, rel=2e-4, abs=1e-3), lik.names[i]


# ---------------------------------------------------------------------------- fits
@pytest.mark.parametrize(
    ("true_law", "assumed", "expected"),
    [
        # ~3 s of CPU for each jittered case: the default run keeps the case without jitter
        # (1 s) and the one where the delay absorbs the jitter's mean
        (ji.NoJitter(), ji.NoJitter(), 0.7),
        pytest.param(ji.Uniform(0.5), ji.Uniform(0.5), 0.7, marks=pytest.mark.slow),
        # a converter sampling 0.2 s late on average: known, the delay is the true one ...
        pytest.param(
            ji.Shifted(ji.Uniform(0.3), 0.2),
            ji.Shifted(ji.Uniform(0.3), 0.2),
            0.7,
            marks=pytest.mark.slow,
        ),
        # ... assumed zero-mean, the delay absorbs the mean: delay - mean = 0.5
        (ji.Shifted(ji.Uniform(0.3), 0.2), ji.Uniform(0.3), 0.5),
    ],
)
def test_delay_estimate_is_unbiased_over_records(
    true_law: ji.JitterLaw, assumed: ji.JitterLaw, expected: float
) -> None:
    est = []
    for seed in range(8):
        data = _data(true_law, 0.7, seed=100 + seed)
        method = "gaussian" if not isinstance(assumed, ji.NoJitter) else "ls"
        res = ji.fit(
            data, ji.Delayed(ji.PolePairGain(), min_delay_s=-2.0, max_delay_s=10.0), assumed, method
        )
        assert res.status is ji.FitStatus.CONVERGED, res.message
        assert res.system is not None
        assert res.system.delay_s == res.params["delay_s"]
        assert res.jitter_law == assumed  # the law as stated, not the shifted equivalent
        est.append(res.params["delay_s"])
    d = np.array(est)
    assert abs(d.mean() - expected) < 3.5 * d.std(ddof=1) / np.sqrt(d.size)


def test_result_of_a_delayed_fit_reports_the_identifiability() -> None:
    data = _data(ji.Uniform(0.5), 0.7, seed=4)
    res = ji.fit(data, MODEL, ji.Uniform(0.5), "bcls")
    assert res.success
    assert "the samples identify only delay_s - mean jitter" in res.summary()
    band = res.bode_band([0.05, 0.2])
    np.testing.assert_allclose(
        np.radians(band.phase),
        np.unwrap(np.angle(res.system.frequency_response([0.05, 0.2]))),
        atol=1e-9,
    )
    again = ji.FitResult.from_json(res.to_json())
    assert again.system is not None
    assert again.system.delay_s == res.system.delay_s
    pred = res.predict(data)
    assert np.sqrt(np.mean((data.y - pred) ** 2)) < 0.2


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"structure": ji.TransferFunction([1.0], [1.0, 1.0])}, TypeError, "LTI model structure"),
        ({"structure": MODEL}, ValueError, "delay it once"),
        (
            {"structure": ji.PolePairGain(), "min_delay_s": 1.0, "max_delay_s": 0.5},
            ValueError,
            "min_delay_s",
        ),
    ],
)
def test_delayed_refuses_bad_arguments(kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        ji.Delayed(**kwargs)


def test_integrator_is_refused_before_the_fit_with_the_fix() -> None:
    data = _data(ji.Uniform(0.5), 0.0, seed=5)
    integrator = ji.TransferFunction([1.0], [1.0, 0.0])
    with pytest.raises(ValueError, match=r"an integrator \(a pole at 0\).*stable pole"):
        ji.fit(data, integrator, ji.Uniform(0.5), "bcls")
    with pytest.raises(ValueError, match="an integrator"):
        ji.simulate(integrator, data.u, ji.Uniform(0.5), T=1.0, N=50, noise_std=0.01, rng=0)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["bcls", "gaussian", "ml"])
def test_delay_intervals_cover_over_records(method: str) -> None:
    """64 records of jitter with a non-zero mean (known): the delay's 95 % intervals cover
    0.90-0.98 and its mean is within 3.5 standard errors of the truth. Measured with 100
    records (seeds 1000-1099, the same setting): coverage 0.92 / 0.96 / 0.96, std 0.058 /
    0.022 / 0.0093 s against mean standard errors 0.051 / 0.025 / 0.0097 s (bcls, gaussian, ml)."""
    law = ji.Shifted(ji.Uniform(0.4), 0.1)
    est, covered = [], []
    for r in range(64):
        data = _data(law, 0.7, seed=1000 + r)
        res = ji.fit(data, MODEL, law, method)
        assert res.success, res.message
        est.append(res.params["delay_s"])
        lo, hi = res.conf_int()["delay_s"]
        covered.append(lo <= 0.7 <= hi)
    d = np.array(est)
    assert 0.90 <= np.mean(covered) <= 0.98
    assert abs(d.mean() - 0.7) < 3.5 * d.std(ddof=1) / np.sqrt(d.size)


def _delayed_fit() -> ji.FitResult:
    data = _data(ji.Uniform(0.5), 0.7, seed=4)
    return ji.fit(data, MODEL, ji.Uniform(0.5), "bcls")


def test_step_response_of_a_delayed_fit_is_the_rational_one_moved() -> None:
    res = _delayed_fit()
    d = res.system.delay_s
    t = np.linspace(0.0, 12.0, 241)
    band = res.step_response(t)
    rational = ji.analysis.responses.lti_response(res.system.undelayed, np.maximum(t - d, 0.0))
    np.testing.assert_allclose(band.response, np.where(t >= d, rational, 0.0), atol=1e-12)
    assert np.all(band.response[t < d] == 0.0)


def test_exports_of_a_delay_say_how_or_approximate_it() -> None:
    from scipy import signal

    res = _delayed_fit()
    with pytest.raises(ValueError, match="pade_order"):
        res.to_scipy()
    # the Pade approximant against e^{-i w d} G at low frequencies (|w d| < 1)
    lti = res.to_scipy(pade_order=4)
    f = np.array([0.01, 0.05, 0.1])
    _, g = signal.freqresp(lti, 2 * np.pi * f)
    np.testing.assert_allclose(g, res.system.frequency_response(f), rtol=1e-6)
    with pytest.raises(ValueError, match="not a whole number of periods"):
        res.to_discrete(0.3)
    with pytest.raises(ValueError, match="pade_order must be"):
        res.to_scipy(pade_order=0)


def test_to_discrete_of_a_whole_period_delay_is_z_to_the_minus_m() -> None:
    from scipy import signal

    tf = ji.TransferFunction([2.0], [1.0, 1.0], delay_s=0.75)
    data = _data(ji.NoJitter(), 0.0, seed=6, N=60)
    res = ji.fit(data, ji.KnownSystem(tf), ji.NoJitter(), "bcls")
    sys_d = res.to_discrete(0.25)
    plain = ji.fit(data, ji.KnownSystem(tf.undelayed), ji.NoJitter(), "bcls").to_discrete(0.25)
    _, y_delayed = signal.dstep(sys_d, n=30)
    _, y_plain = signal.dstep(plain, n=30)
    np.testing.assert_allclose(y_delayed[0][3:, 0], y_plain[0][:-3, 0], atol=1e-12)
    np.testing.assert_allclose(y_delayed[0][:3, 0], 0.0, atol=1e-15)


def test_constrained_delayed_model_keeps_the_delay_derivative() -> None:
    """Constrained maps the inner delay to its free position: fixing k0 leaves the delay's
    moment derivative right (central differences as the referee)."""
    model = ji.Constrained(MODEL, fixed={"k0": 6.25})
    assert model.delay_index == 2
    assert ji.Constrained(MODEL, fixed={"delay_s": 0.7}).delay_index is None
    data = _data(ji.Uniform(0.5), 0.7, seed=3)
    pr = Problem(data, model, ji.Uniform(0.5), "bcls", ji.default_frequencies(200, 1.0), 0.01)
    x = np.array([-1.5, 2.0, 0.7])
    dm = jacobians.moment_derivatives(pr, x)[2]
    ref = finite_diff.derivative(
        lambda v: jacobians.moments(pr, v).mean, x, 2, pr.bounds[2], rel=1e-5
    )
    assert np.max(np.abs(ref - dm[2])) < 1e-6 * np.max(np.abs(ref))
    res = ji.fit(data, ji.Constrained(MODEL, fixed={"delay_s": 0.7}), ji.Uniform(0.5), "bcls")
    assert res.success
    assert res.system.delay_s == 0.7
