"""TransferFunction (jitterid.systems.tf): the exact response at arbitrary instants against an
independent fine-step ODE solution, the frequency response, and bad transfer functions."""

import numpy as np
import pytest
from scipy import signal as sps
from scipy.integrate import solve_ivp

from jitterid.inputs import Multisine, PiecewiseConstant, telegraph_input
from jitterid.systems.tf import TransferFunction

SYSTEMS = {
    "first order": TransferFunction([1.0], [1.0, 2.0]),
    "pole pair": TransferFunction([6.25], [1.0, 3.0, 6.25]),
    "third order, zero, feedthrough": TransferFunction([0.5, 1.0, 2.0, 3.0], [1.0, 4.0, 6.0, 4.5]),
}


def ode_reference(tf: TransferFunction, u, t_eval: np.ndarray) -> np.ndarray:
    """Integrate x' = A x + B u(t) with solve_ivp at tight tolerance, interval by interval."""
    A, B, C, D = sps.tf2ss(tf.num, tf.den)
    order = A.shape[0]
    out = np.empty_like(t_eval)
    edges = u.times if isinstance(u, PiecewiseConstant) else np.array([u.start, u.end])
    x = np.zeros(order)
    for j in range(edges.size - 1):
        a, b = edges[j], edges[j + 1]
        mask = (t_eval >= a) & (t_eval < b)
        ev = np.sort(t_eval[mask])
        sol = solve_ivp(
            lambda t, x: A @ x + B[:, 0] * float(u(np.array(t))),
            (a, b),
            x,
            method="DOP853",
            rtol=1e-12,
            atol=1e-14,
            t_eval=np.r_[ev, b] if ev.size else [b],
            max_step=0.05,
        )
        vals = sol.y[:, :-1]
        if ev.size:
            order_idx = np.argsort(t_eval[mask])
            res = np.empty(ev.size)
            res[order_idx] = C[0] @ vals + D[0, 0] * u(ev)
            out[mask] = res
        x = sol.y[:, -1]
    out[t_eval < edges[0]] = 0.0
    return out


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_piecewise_constant_response_matches_ode(name):
    # 15 s of input (16 switches; was 30 s): the referee's fine steps cost in proportion
    rng = np.random.default_rng(1)
    tf = SYSTEMS[name]
    u = telegraph_input(15.0, rng)
    t = np.sort(rng.uniform(-1.0, 14.9, size=200))
    exact = tf.response(u)(t)
    ref = ode_reference(tf, u, t)
    np.testing.assert_allclose(exact, ref, rtol=0, atol=1e-8)
    assert np.all(exact[t < 0] == 0.0)


@pytest.mark.parametrize("name", ["first order", "pole pair"])
def test_multisine_switched_on_matches_ode(name):
    tf = SYSTEMS[name]
    u = Multisine([0.1, 0.37], [1.0, 0.5], end=20.0, phases=[0.3, -1.0], start=0.5)
    t = np.random.default_rng(2).uniform(0.0, 19.9, size=120)
    np.testing.assert_allclose(tf.response(u)(t), ode_reference(tf, u, t), atol=1e-8)


def test_multisine_steady_state_is_the_frequency_response():
    tf = SYSTEMS["pole pair"]
    f0 = 0.3
    u = Multisine([f0], [2.0], end=100.0, steady_state=True)
    t = np.linspace(-50, 90, 77)
    g = tf.frequency_response(f0)
    expected = 2.0 * np.abs(g) * np.sin(2 * np.pi * f0 * t + np.angle(g))
    np.testing.assert_allclose(tf.response(u)(t), expected, atol=1e-12)


def test_long_record_stays_accurate_across_blocks():
    # 20000 s of a fast pole: the switch-state recursion is chained over many blocks.
    tf = TransferFunction([50.0], [1.0, 50.0])
    rng = np.random.default_rng(3)
    u = telegraph_input(20000.0, rng)
    resp = tf.response(u)
    # A first-order system's exact state at the last switch, by the scalar recursion.
    x = 0.0
    for j in range(u.levels.size - 1):
        dt = u.times[j + 1] - u.times[j]
        x = np.exp(-50 * dt) * x + u.levels[j] * (1 - np.exp(-50 * dt))
    assert resp(u.times[-2:-1])[0] == pytest.approx(x, abs=1e-10)


def test_freqresp_in_hz():
    tf = SYSTEMS["first order"]
    assert tf.frequency_response(1.0) == pytest.approx(1 / (2j * np.pi + 2))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num": [1, 0, 0], "den": [1, 1]}, "improper"),
        ({"num": [1], "den": [0, 0]}, "den"),
        ({"num": [np.nan], "den": [1, 1]}, "num"),
    ],
)
def test_bad_transfer_functions(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TransferFunction(**kwargs)


def test_unstable_and_repeated_poles_refused():
    u = telegraph_input(5.0, 0)
    with pytest.raises(ValueError, match="not stable"):
        TransferFunction([1], [1, -1]).response(u)
    with pytest.raises(ValueError, match="repeated poles"):
        TransferFunction([1], [1, 2, 1]).response(u)


def test_sampling_past_the_input_end_is_refused():
    u = telegraph_input(5.0, 0)
    resp = TransferFunction([1], [1, 1]).response(u)
    with pytest.raises(ValueError, match="input ends"):
        resp(np.array([1.0, 5.0]))
