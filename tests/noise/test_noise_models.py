"""Coloured noise models (jitterid.noise.models): the autocovariance and spectrum against the
impulse response, and the exact simulation against the process covariance."""

import numpy as np
import pytest
from helpers import OU_NOISE, RESONANT_NOISE
from scipy import integrate

Z_MAX = 4.5  # |z| bound for Monte Carlo comparisons (two-sided p = 7e-6 per comparison)


# --------------------------------------------------------------------------- noise model


def test_autocovariance_and_spectrum_follow_from_the_impulse_response():
    """(N1): r_v(t) = lambda int_0^inf h(s) h(s + t) ds, and (N2): int S_v df = r_v(0)."""
    _, r, p = RESONANT_NOISE.tf.modal

    def h(s):
        return float(np.real(np.sum(r * np.exp(p * s))))

    for lag in (0.0, 0.7, 2.5):
        direct = (
            RESONANT_NOISE.intensity
            * integrate.quad(lambda s, lag=lag: h(s) * h(s + lag), 0, np.inf, limit=200)[0]
        )
        assert RESONANT_NOISE.autocovariance(lag) == pytest.approx(direct, rel=1e-8, abs=1e-12)
    total = integrate.quad(lambda f: float(RESONANT_NOISE.spectrum(f)), -np.inf, np.inf, limit=400)[
        0
    ]
    assert total == pytest.approx(RESONANT_NOISE.variance, rel=1e-7)
    assert OU_NOISE.variance == pytest.approx(0.5)


@pytest.mark.parametrize("model", [RESONANT_NOISE, OU_NOISE], ids=["resonant", "first-order"])
def test_exact_simulation_matches_the_process_covariance(model):
    """Sample covariance of many draws at fixed, unsorted instants (a repeated one, gaps from 0
    to 50 s) against r_v(t_i - t_j); the Gaussian standard error of each entry is
    sqrt((r_ij^2 + r_ii r_jj) / R)."""
    t = np.array([3.0, 0.0, 0.3, 0.3, 1.7, 53.0, 0.31])
    R = 40_000
    v = model.sample(np.broadcast_to(t, (R, t.size)), np.random.default_rng(11))
    S = v.T @ v / R
    E = model.autocovariance(t[:, None] - t[None, :])
    se = np.sqrt((E**2 + np.outer(np.diag(E), np.diag(E))) / R)
    assert np.max(np.abs(S - E) / se) < Z_MAX
    np.testing.assert_array_equal(v[:, 2], v[:, 3])  # one instant, one value
    assert np.abs(v.mean(axis=0)).max() < Z_MAX * np.sqrt(model.variance / R)
