"""Issue 25, item 11: crb(SineWave(), ...) in its integral mode took 135 CPU-s on one record of
1000 samples: (L3)'s y-grid summed every quadrature node at every grid point, a cost growing
like (the signal's range / noise std)^2 per sample. The sum now takes the nodes within 10
noise std's of each grid point; referee: the full sum."""

import numpy as np

import jitterid as ji
from jitterid.estimation.likelihood import _LOG_SQRT_2PI, _log_mixture


def full_sum(grid, s, logw, sigma):
    z = logw - 0.5 * ((grid[:, None] - s) / sigma) ** 2
    top = np.max(z, axis=1)
    return top + np.log(np.sum(np.exp(z - top[:, None]), axis=1)) - np.log(sigma) - _LOG_SQRT_2PI


def test_the_banded_sum_equals_the_full_one():
    rng = np.random.default_rng(0)
    sigma = 0.01
    t = np.sort(rng.uniform(-1.0, 1.0, 800))
    s = np.sin(3.0 * t)  # a steep stretch and a turning point: dense and sparse windows
    logw = np.log(rng.uniform(0.1, 1.0, t.size) / t.size)
    logw[::50] = -np.inf  # nodes with no weight
    grid = np.linspace(s.min() - 9 * sigma, s.max() + 9 * sigma, 4000)
    np.testing.assert_allclose(
        _log_mixture(grid, s, logw, sigma), full_sum(grid, s, logw, sigma), rtol=1e-12, atol=1e-12
    )
    far = np.array([s.max() + 30 * sigma, s.min() - 50 * sigma])  # beyond the grid too
    np.testing.assert_allclose(
        _log_mixture(far, s, logw, sigma), full_sum(far, s, logw, sigma), rtol=1e-12
    )


def test_the_sine_bound_agrees_with_the_draws_route():
    args = (ji.SineWave(), ji.Gaussian(50e-6), None, 1e-3, 20, 0.002, [1.0, 0.3, 123.0, 0.05])
    C = ji.crb(*args)
    D = ji.crb(*args, draws=400, rng=3)
    np.testing.assert_allclose(np.sqrt(np.diag(C)), np.sqrt(np.diag(D)), rtol=0.08)
