"""fit() checks its arguments and data before the search: a ValueError naming the argument
(noise_std, max_nfev, data.u, data.y, too few samples) instead of a fit that an earlier version
reported as a success or never returned."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji

T = 1.0
N = 200
G = ji.TransferFunction([6.25], [1.0, 3.0, 6.25])  # the paper's (27) at the truth


def _paper(
    seed: int = 7, law: ji.JitterLaw | None = None, n: int = N, noise: float = 0.01
) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 5.0, rng)
    return ji.simulate(G, u, law or ji.Uniform(0.5), T, n, noise, rng)


@pytest.fixture(scope="module")
def data() -> ji.SampledData:
    return _paper()


# ------------------------------------------------------------------------ arguments
@pytest.mark.parametrize("method", ["bcls", "asml", "asml-diag", "gaussian", "wbcls"])
@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), "0.01"])
def test_noise_std_must_be_a_nonnegative_number(data, method, bad):
    # was: -1 silently used as +1 (asml, asml-diag, gaussian, wbcls) and reported as -1.0
    with pytest.raises(ValueError, match="noise_std"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method, noise_std=bad)


@pytest.mark.parametrize("bad", [1.5, 0, -3, float("nan"), True, "10", None])
def test_max_nfev_must_be_a_positive_whole_number(data, bad):
    # was: max_nfev=1.5 never returned
    with pytest.raises(ValueError, match="max_nfev"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls", max_nfev=bad)


def test_a_whole_float_max_nfev_is_accepted(data):
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls", max_nfev=2000.0)
    assert res.success


# ------------------------------------------------------------------------ data
@pytest.mark.parametrize("method", ["ls", "bcls", "wbcls", "asml", "asml-diag", "gaussian", "ml"])
def test_zero_input_is_refused(data, method):
    # was: CONVERGED at the first start with all 7 methods
    u = ji.PiecewiseConstant(data.u.times, np.zeros_like(data.u.levels))
    zero = ji.SampledData(data.y, T, u, 0.01)
    law = ji.NoJitter() if method == "ls" else ji.Uniform(0.5)
    with pytest.raises(ValueError, match=r"data\.u: the input is zero"):
        ji.fit(zero, ji.PolePairGain(), law, method)


def test_zero_input_is_refused_with_coloured_noise_too(data):
    u = ji.PiecewiseConstant(data.u.times, np.zeros_like(data.u.levels))
    zero = ji.SampledData(data.y, T, u, 0.01)
    with pytest.raises(ValueError, match=r"data\.u: the input is zero"):
        ji.fit(zero, ji.PolePairGain(), ji.Uniform(0.5), "bcls", noise=ji.RationalNoise(0, 1))


@pytest.mark.parametrize("level", [0.0, 3.5])
def test_constant_output_is_refused(data, level):
    # was: y = 0 CONVERGED
    flat = ji.SampledData(np.full(N, level), T, data.u, 0.01)
    with pytest.raises(ValueError, match=r"data\.y: the output is constant"):
        ji.fit(flat, ji.PolePairGain(), ji.Uniform(0.5), "bcls")


def test_an_input_that_ends_before_the_data_is_refused(data):
    # was: CONVERGED (the input is zero after its end)
    short = ji.PiecewiseConstant(data.u.times[:101], data.u.levels[:100])
    assert short.end < (N - 1) * T
    with pytest.raises(ValueError, match=r"data\.u: the input ends at"):
        ji.fit(ji.SampledData(data.y, T, short, 0.01), ji.PolePairGain(), ji.Uniform(0.5), "bcls")


@pytest.mark.parametrize("n", [6, 8])
def test_too_few_samples_for_the_parameters_are_refused(n):
    # was: N = 6-8 CONVERGED with wrong estimates (k0 = 1.7 and 4.1 for 6.25)
    d = _paper(law=ji.Uniform(0.5), n=n)
    with pytest.raises(ValueError, match=rf"N = {n} samples are too few for 3 parameters"):
        ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    with pytest.raises(ValueError, match="too few for 5 parameters"):
        ji.fit(_paper(n=12), ji.PolePairGain(), ji.SumOfUniformsFamily(), "bcls")
