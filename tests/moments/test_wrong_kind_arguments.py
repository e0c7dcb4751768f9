"""Issue 25, items 7 and 9: arguments of the wrong kind or size get a ValueError/TypeError
naming the argument and the fix, not a traceback from deep inside (OverflowError,
AttributeError, LinAlgError, MemoryError)."""

import numpy as np
import pytest

import jitterid as ji
from jitterid._checks import TooLargeError

G = ji.TransferFunction([2.0], [1.0, 2.0])


def test_a_law_whose_variance_overflows_is_refused():
    for make, name in [(ji.Gaussian, "sigma"), (ji.Uniform, "a")]:
        with pytest.raises(ValueError, match=f"{name} must be at most 1e\\+150 s"):
            make(1e200)
    with pytest.raises(ValueError, match="a must be at most"):
        ji.SumOfUniforms(1.0, 1e200)
    assert ji.Gaussian(1e100).var == pytest.approx(1e200)


def test_an_array_is_not_an_input():
    with pytest.raises(TypeError, match=r"u must be a jitterid input .*zoh_input\(values, T\)"):
        ji.simulate(G, np.ones(10), ji.Uniform(0.5), T=1.0, N=10, noise_std=0.01, rng=1)
    with pytest.raises(TypeError, match="u must be a jitterid input"):
        ji.expected_dft(G, np.ones(10), ji.Uniform(0.05), 0.1, 10, [0.5])


def test_a_family_is_not_a_known_law():
    u = ji.zoh_input(np.ones(20), T=0.1)
    for call in (
        lambda j: ji.expected_dft(G, u, j, 0.1, 10, [0.5]),
        lambda j: ji.dft_covariance(G, u, j, 0.1, 10, [0.5], noise_std=0.01),
        lambda j: ji.sample_moments(G.response(u), j, 0.1, 10),
        lambda j: ji.simulate(G, u, j, T=0.1, N=10, noise_std=0.01, rng=1),
    ):
        with pytest.raises(TypeError, match=r"family UniformFamily.*family\.law\(params\)"):
            call(ji.UniformFamily())
        with pytest.raises(TypeError, match="jitter must be a jitter law"):
            call(0.5)


@pytest.mark.parametrize("T", [1e-300, 1e-30, 1e30])
def test_a_sampling_interval_outside_the_handled_range_is_refused(T):
    with pytest.raises(ValueError, match="outside the range of sampling intervals"):
        ji.SampledData(np.ones(10), T)
    with pytest.raises(ValueError, match="outside the range of sampling intervals"):
        ji.zoh_input(np.ones(10), T=T)


def test_dft_covariance_estimates_its_memory_before_it_starts(monkeypatch):
    """20000 frequencies raised MemoryError; now the estimate refuses it up front."""
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1e8")
    u = ji.zoh_input(np.ones(50), T=0.1)
    f = np.linspace(0.0, 5.0, 2000)  # 4e6 pairs: ~0.2 GB at peak, over the 0.1 GB budget
    with pytest.raises(TooLargeError, match=r"2000 x 2000 DFT covariance needs about 0\.2"):
        ji.dft_covariance(G, u, ji.Uniform(0.02), 0.1, 40, f, noise_std=0.01)
    R = ji.dft_covariance(G, u, ji.Uniform(0.02), 0.1, 40, f[:100], noise_std=0.01)
    assert R.shape == (100, 100)


def test_complex_samples_are_refused_not_cast():
    """Complex y was accepted with a ComplexWarning that dropped the imaginary part."""
    y = np.exp(1j * np.arange(20.0))
    with pytest.raises(TypeError, match=r"y must be real; got complex values.*y\.real"):
        ji.SampledData(y, 1.0)
    with pytest.raises(TypeError, match="y must be real"):
        ji.measure_jitter(y, 1e-3, laws=["gaussian"])
    with pytest.raises(TypeError, match="samples must be real"):
        ji.zoh_input(y, T=1.0)
    ok = ji.SampledData(y.real, 1.0)  # the real part, said explicitly, is fine
    assert ok.y.dtype == np.float64
