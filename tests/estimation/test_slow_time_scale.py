"""Issue 25, item 9: PolePairGain's floors on pr and pi are rates in rad/s (1e-6, 1e-3), so
data on a slow time scale (T = 1e6 s) ended on a floor with advice about structures. The
check now says that the floors lie above every rate the record resolves and names the fix
(times in a larger unit); the same record in that unit converges to the scaled truth."""

import numpy as np

import jitterid as ji

S = 1e6  # seconds per unit


def record(scale):
    rng = np.random.default_rng(1)
    truth = ji.PolePairGain(pr_min=1e-300, pi_min=1e-300).system(
        [6.25 / scale**2, -1.5 / scale, 2.0 / scale]
    )
    u = ji.zoh_input(np.sign(rng.standard_normal(210)) * 0.5, T=scale)
    return ji.simulate(truth, u, ji.Uniform(0.5 * scale), T=scale, N=200, noise_std=0.01, rng=rng)


def test_a_slow_record_says_the_floors_are_above_its_rates():
    res = ji.fit(record(S), ji.PolePairGain(), ji.Uniform(0.5 * S), method="bcls")
    assert res.status is ji.FitStatus.AT_BOUND
    assert "slowest rate the record resolves" in res.message
    assert "Give the times in a larger unit" in res.message


def test_the_same_record_in_units_of_1e6_s_converges():
    res = ji.fit(record(1.0), ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert abs(res.params["pi"] - 2.0) < 0.3
