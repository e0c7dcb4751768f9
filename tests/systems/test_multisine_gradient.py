"""The steady-state response to a multisine: closed-form parameter gradient, slope and second
derivatives (Response.gradient, slope, second_derivatives; dG/dtheta from the structure's
coefficient derivatives) against central differences of s (the independent referee: only
s(t) at other parameters and instants), and the ML fit with the closed forms against the fit
with them switched off, and against the truth over a Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji
from jitterid.systems.model import Signal
from jitterid.systems.tf import CoefficientDerivatives, Response

U = ji.Multisine(
    [0.05, 0.13, 0.31], [1.0, 0.5, 0.3], end=1e9, phases=[0.1, 1.0, 2.0], steady_state=True
)
T_EVAL = np.linspace(0.0, 40.0, 173)

CASES = [
    pytest.param(ji.RationalModel(0, 1), [2.0, 1.0], id="rational01"),
    pytest.param(ji.RationalModel(1, 2), [0.5, 2.0, 3.0, 2.0], id="rational12"),
    pytest.param(ji.PolePairGain(), [5.0, -1.0, 2.0], id="polepair"),
    pytest.param(
        ji.Delayed(ji.RationalModel(1, 2), max_delay_s=5.0), [0.5, 2.0, 3.0, 2.0, 0.7], id="delayed"
    ),
    pytest.param(
        ji.Constrained(ji.PolePairGain(), fixed={"k0": 6.25}), [-1.5, 2.0], id="constrained"
    ),
    pytest.param(
        ji.Constrained(ji.Delayed(ji.PolePairGain(), max_delay_s=5.0), fixed={"pr": -1.2}),
        [4.0, 2.0, 0.3],
        id="constrained-delayed",
    ),
]

H = 1e-5  # central-difference step: truncation ~H^2 |s'''| ~ 1e-10, rounding ~1e-16 / H


def _s(model, x, t):
    return model.signal(np.asarray(x, float), U)(t)


def _d_theta(fun, x, i):
    """Central difference of fun(x) in x_i (step H)."""
    e = np.zeros(len(x))
    e[i] = H
    x = np.asarray(x, float)
    return (fun(x + e) - fun(x - e)) / (2 * H)


def _five_point(fun, z, h):
    """d fun / dz at z by the five-point central difference, step h."""
    return (fun(z - 2 * h) - 8 * fun(z - h) + 8 * fun(z + h) - fun(z + 2 * h)) / (12 * h)


@pytest.mark.parametrize(("model", "x"), CASES)
def test_gradient_against_differences(model, x):
    sig = model.signal(x, U)
    assert sig.has_gradient
    assert sig.has_slope
    G = sig.gradient(T_EVAL)
    assert G.shape == (len(x), T_EVAL.size)
    for i in range(len(x)):
        ref = _d_theta(lambda v: _s(model, v, T_EVAL), x, i)
        np.testing.assert_allclose(G[i], ref, rtol=0, atol=1e-8, err_msg=model.param_names[i])


@pytest.mark.parametrize(("model", "x"), CASES)
def test_slope_against_differences(model, x):
    sig = model.signal(x, U)
    ref = (sig(T_EVAL + H) - sig(T_EVAL - H)) / (2 * H)
    np.testing.assert_allclose(sig.slope(T_EVAL), ref, rtol=0, atol=1e-8)


@pytest.mark.parametrize(("model", "x"), CASES)
def test_second_derivatives_against_differences(model, x):
    sig = model.signal(x, U)
    hss, dslope, curv = sig.second_derivatives(T_EVAL)
    P = len(x)
    assert hss.shape == (P, P, T_EVAL.size)
    assert dslope.shape == (P, T_EVAL.size)
    # nested five-point central differences of s (truncation ~h^4, rounding ~1e-16 / h^2)
    h = 1e-2
    t = T_EVAL
    ref_curv = (
        -sig(t + 2 * h) + 16 * sig(t + h) - 30 * sig(t) + 16 * sig(t - h) - sig(t - 2 * h)
    ) / (12 * h**2)
    np.testing.assert_allclose(curv, ref_curv, rtol=0, atol=1e-6)
    for i in range(P):

        def s_slope(v):  # s' by a five-point difference of s in t
            return _five_point(lambda dt: _s(model, v, t + dt), 0.0, 1e-3)

        ref = _five_point(
            lambda d, i=i: s_slope(np.asarray(x, float) + d * np.eye(P)[i]), 0.0, 1e-3
        )
        np.testing.assert_allclose(dslope[i], ref, rtol=0, atol=1e-6)
        for j in range(P):

            def dj(v, j=j):  # d s / dtheta_j by a five-point difference of s
                return _five_point(lambda d: _s(model, v + d * np.eye(P)[j], t), 0.0, 1e-3)

            ref = _five_point(
                lambda d, i=i, dj=dj: dj(np.asarray(x, float) + d * np.eye(P)[i]), 0.0, 1e-3
            )
            np.testing.assert_allclose(hss[i, j], ref, rtol=0, atol=1e-6, err_msg=f"{i}, {j}")
    np.testing.assert_allclose(hss, hss.transpose(1, 0, 2), atol=1e-12)


def test_delayed_rows_are_the_time_shift():
    """The delay's row is -s'(t) of the delayed signal, its curvature s''."""
    model = ji.Delayed(ji.RationalModel(0, 1), max_delay_s=5.0)
    sig = model.signal([2.0, 1.0, 0.4], U)
    np.testing.assert_allclose(sig.gradient(T_EVAL)[2], -sig.slope(T_EVAL), atol=1e-14)
    hss, _, curv = sig.second_derivatives(T_EVAL)
    np.testing.assert_allclose(hss[2, 2], curv, atol=1e-14)


def test_other_inputs_give_no_closed_form():
    model = ji.RationalModel(0, 1)
    switched = ji.Multisine([0.1], [1.0], end=100.0)
    sig = model.signal([2.0, 1.0], switched)
    assert not sig.has_gradient
    assert not sig.has_slope
    assert sig.gradient(T_EVAL) is None
    assert sig.second_derivatives(T_EVAL) is None
    steps = model.signal([2.0, 1.0], ji.zoh_input([1.0, -1.0] * 30, T=1.0))
    assert not steps.has_gradient
    assert steps.slope(T_EVAL) is None
    plain = ji.TransferFunction([2.0], [1.0, 1.0]).response(U)  # no structure: no gradient
    assert plain.has_slope
    assert not plain.has_gradient
    assert plain.gradient(T_EVAL) is None


def test_steady_state_values_agree_with_the_modal_formula():
    """s(t) as a sum of tones equals the modal (partial-fraction) formula."""
    tf = ji.TransferFunction([1.0, 6.25], [1.0, 3.0, 6.25])
    sig = tf.response(U)
    d, r, p = tf.modal
    ref = sig._multisine(T_EVAL, d, r, p)
    np.testing.assert_allclose(sig(T_EVAL), ref, atol=1e-13)


def test_a_structure_without_second_derivatives_gives_none():
    class Scaled(ji.RationalModel):  # its own map, no closed form of its own
        def system(self, params):
            x = np.asarray(params, float)
            return ji.TransferFunction([x[0]], [1.0, 2.0 * x[1]])

    model = Scaled(0, 1)
    sig = model.signal([2.0, 0.5], U)
    assert sig.has_gradient
    assert sig.second_derivatives(T_EVAL) is None
    ref = _d_theta(lambda v: _s(model, v, T_EVAL), [2.0, 0.5], 1)
    np.testing.assert_allclose(sig.gradient(T_EVAL)[1], ref, rtol=0, atol=1e-8)


def test_coefficient_derivatives_refuse_bad_shapes():
    with pytest.raises(ValueError, match="dnum and dden"):
        CoefficientDerivatives(np.zeros((2, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="d2num and d2den"):
        CoefficientDerivatives(
            np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 2, 2)), np.zeros((2, 2, 2))
        )
    with pytest.raises(ValueError, match="both"):
        CoefficientDerivatives(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match="delay"):
        CoefficientDerivatives(np.zeros((2, 3)), np.zeros((2, 3)), delay=2)
    with pytest.raises(TypeError, match="derivatives"):
        Response(ji.TransferFunction([1.0], [1.0, 1.0]), U, derivatives=(1, 2))
    bad = CoefficientDerivatives(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="derivatives has 3"):
        Response(ji.TransferFunction([1.0], [1.0, 1.0]), U, derivatives=bad)(T_EVAL)


# ------------------------------------------------------------------------------ the ML fit
def _switch_off(m: pytest.MonkeyPatch) -> None:
    """The generic route: forward differences of s in theta, no slope, Gauss-Newton."""
    m.setattr(Response, "has_gradient", property(lambda self: False))
    m.setattr(Response, "has_slope", property(lambda self: False))
    m.setattr(Response, "slope", Signal.slope)
    m.setattr(Response, "second_derivatives", Signal.second_derivatives)


def _one_tone(
    n: int, rng: np.random.Generator, noise_std: float = 0.02, freqs: tuple[float, ...] = (0.17,)
) -> ji.SampledData:
    u = ji.Multisine(freqs, np.ones(len(freqs)), end=1e12, steady_state=True)
    G = ji.TransferFunction([2.0], [1.0, 1.0], delay_s=0.4 if len(freqs) > 1 else 0.0)
    return ji.simulate(G, u, ji.Uniform(0.3), T=1.0, N=n, noise_std=noise_std, rng=rng)


@pytest.mark.parametrize(
    ("model", "jitter", "freqs"),
    [
        (ji.RationalModel(0, 1), ji.Uniform(0.3), (0.17,)),
        (ji.RationalModel(0, 1), ji.UniformFamily(), (0.17,)),
        # one tone fixes a gain and a phase: the delay needs a second
        (ji.Delayed(ji.RationalModel(0, 1), max_delay_s=2.0), ji.Uniform(0.3), (0.11, 0.23)),
    ],
    ids=["known-law", "family", "delayed"],
)
def test_ml_fit_is_the_same_by_either_route(model, jitter, freqs, monkeypatch):
    data = _one_tone(300, np.random.default_rng(7), freqs=freqs)
    fast = ji.fit(data, model, jitter, "ml")
    with monkeypatch.context() as m:
        _switch_off(m)
        slow = ji.fit(data, model, jitter, "ml")
    assert fast.status.name == slow.status.name == "CONVERGED", (fast.message, slow.message)
    # the switched-off route's scores are forward differences of s (relative step 1e-7,
    # the likelihood's _SCORE_STEP), whose O(step) error moves its optimum by ~1e-7
    # relative: the closed form's is the referee's up to that
    gap = np.abs(fast.x - slow.x) / (1 + np.abs(slow.x))
    assert np.all(gap < 1e-6), (fast.x, slow.x, gap)
    se = np.sqrt(np.diag(slow.cov))
    assert np.all(np.abs(fast.x - slow.x) < 1e-4 * se), (fast.x - slow.x, se)
    np.testing.assert_allclose(fast.cost, slow.cost, rtol=1e-10)
    # the covariance: the exact observed information against a differenced Hessian
    np.testing.assert_allclose(fast.cov, slow.cov, rtol=2e-3)


def _monte_carlo(records: int, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    model, law = ji.RationalModel(0, 1), ji.Uniform(0.3)
    # the estimates only: no covariance (the same x; a seventh of a fit's cost)
    est = np.array(
        [
            ji.fit(_one_tone(n, rng, 0.05), model, law, "ml", cov_type="none").x
            for _ in range(records)
        ]
    )
    truth = np.array([2.0, 1.0])
    se = est.std(axis=0, ddof=1) / np.sqrt(records)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 3 * se), (est.mean(axis=0), se)


def test_ml_monte_carlo_one_tone():
    _monte_carlo(40, 300, 11)


@pytest.mark.slow
def test_ml_monte_carlo_one_tone_long():
    _monte_carlo(200, 1000, 12)


# ------------------------------------------------------------------------ the shared bases
def test_responses_to_one_input_share_their_bases():
    u = ji.Multisine([0.05, 0.31], [1.0, 0.3], end=1e9, steady_state=True)
    model = ji.RationalModel(0, 1)
    t = np.linspace(0.0, 50.0, 500)
    a, b = model.signal([2.0, 1.0], u), model.signal([3.0, 0.5], u)
    sa = a(t)
    kept = u.__dict__["_tone_bases"]
    assert len(kept._held) == 1
    np.testing.assert_allclose(
        b(t),
        ji.TransferFunction([3.0], [1.0, 0.5])
        .response(u)
        ._multisine(t, *ji.TransferFunction([3.0], [1.0, 0.5]).modal),
        atol=1e-13,
    )
    w = 2 * np.pi * np.array([0.05, 0.31])
    ref = np.vstack([np.cos(w[:, None] * t), np.sin(w[:, None] * t)])
    np.testing.assert_array_equal(kept.basis(t), ref)
    t += 1.0  # changed in place: not the kept basis
    np.testing.assert_allclose(model.signal([2.0, 1.0], u)(t), a(t.copy()), atol=1e-13)
    assert not np.allclose(a(t), sa)
    del t, a, b  # the instants and the signals that keep their last ones
    assert len(kept._held) == 0  # dropped with its instants


def test_shared_bases_pickle_empty_and_refuse_other_frequencies():
    import pickle

    from jitterid.systems.tones import ToneBases, ToneSignal

    u = ji.Multisine([0.13], [1.0], end=1e9, steady_state=True)
    t = np.linspace(0.0, 9.0, 100)
    s = ji.RationalModel(0, 1).signal([2.0, 1.0], u)
    s(t)
    back = pickle.loads(pickle.dumps(u))
    assert back.__dict__["_tone_bases"]._held == {}
    np.testing.assert_allclose(ji.RationalModel(0, 1).signal([2.0, 1.0], back)(t), s(t), atol=0)
    with pytest.raises(ValueError, match="bases"):
        ToneSignal(s._tones.tones, ToneBases(np.array([1.0])))


def test_a_signals_own_basis_follows_instants_changed_in_place():
    s = ji.MultiTone([0.1]).signal([1.0, 0.3, 0.0])
    t = np.linspace(0.0, 9.0, 100)
    before = s(t)
    t += 1.0
    assert not np.allclose(s(t), before)
    np.testing.assert_allclose(s(t), s(t.copy()), atol=0)


@pytest.mark.parametrize(("model", "x"), [CASES[1], CASES[3], CASES[5]])
def test_closed_form_moment_derivatives_against_differences(model, x):
    """dm_k and dVar_k of the tones' (S1)-(S2) with the structure's da (the delay's row
    through the jitter-equivalent frame) against central differences of m_k and Var_k."""
    law0 = ji.Uniform(0.3)

    def moments(v, gradient=False):
        law, sig = model.signal(np.asarray(v, float), U).jitter_equivalent(law0)
        return sig.jitter_moments(law, 1.0, 80, gradient=gradient)

    mp = moments(x, gradient=True)
    for i in range(len(x)):
        dm = _five_point(
            lambda d, i=i: moments(np.asarray(x) + d * np.eye(len(x))[i]).mean, 0, 1e-3
        )
        dv = _five_point(lambda d, i=i: moments(np.asarray(x) + d * np.eye(len(x))[i]).var, 0, 1e-3)
        np.testing.assert_allclose(mp.dmean[i], dm, rtol=0, atol=1e-9)
        np.testing.assert_allclose(mp.dvar[i], dv, rtol=0, atol=1e-9)
