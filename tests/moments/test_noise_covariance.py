"""The covariance of jittered coloured-noise samples (jitterid.moments.noise_covariance): the lag
autocovariance against brute-force Monte Carlo, the sampled spectrum against the aliased
sum, the O(N) banded Sigma_y and its DFT forms against dense linear algebra, and the closed-form
derivatives against central differences."""

import numpy as np
import pytest
from helpers import OU_NOISE, RESONANT_NOISE, central_differences, table2_data
from scipy import integrate

import jitterid as ji
from jitterid.moments.noise_covariance import autocovariance_derivatives

T = 1.0
TRUTH = np.array([6.25, -1.5, 2.0])
Z_MAX = 4.5  # |z| bound for Monte Carlo comparisons (two-sided p = 7e-6 per comparison)


@pytest.mark.parametrize(
    ("model", "law"),
    [(RESONANT_NOISE, ji.Uniform(0.5)), (OU_NOISE, ji.Gaussian(0.5))],
    ids=["uniform-jitter", "gaussian-jitter"],
)
def test_jittered_noise_autocovariance_matches_brute_force_monte_carlo(model, law):
    """(C1)-(C3): lag covariances of v(kT + tau_k), simulated exactly for R realizations, against
    gamma(m); the standard error comes from the spread of the per-realization averages. For
    Gaussian jitter (support wider than T) the factorised form c M(p) M(-p) e^{p m T} is wrong
    at lag 1, where samples can swap order, and the exact quadrature is needed."""
    R, n = 40_000, 12
    rng = np.random.default_rng(5)
    instants = T * np.arange(n) + law.sample((R, n), rng)
    v = model.sample(instants, rng)
    gamma = ji.jittered_autocovariance(model, law, T)
    for m in range(5):
        per_run = np.mean(v[:, : n - m] * v[:, m:], axis=1)
        est, se = per_run.mean(), per_run.std(ddof=1) / np.sqrt(R)
        assert abs(est - gamma(np.array(m))) < Z_MAX * se, (m, est, gamma(np.array(m)), se)
        if m == 1 and gamma.start > 1:
            c, p = model.modes
            mgf = [law.expect(lambda tau, z=z: np.exp(z * tau)) for z in (p, -p)]
            naive = float(np.real(np.sum(c * mgf[0] * mgf[1] * np.exp(p * T))))
            assert abs(est - naive) > Z_MAX * se, (est, naive, se)
    assert gamma(np.array(0)) == pytest.approx(model.variance)


@pytest.mark.parametrize("law", [ji.NoJitter(), ji.Uniform(0.5), ji.Gaussian(0.4)], ids=str)
def test_jittered_noise_spectrum_is_the_phi_squared_aliased_spectrum_plus_a_white_floor(law):
    """gamma(m) = int S_v |phi|^2 e^{i 2 pi f m T} df for m != 0 and r_v(0) at m = 0, so by
    Poisson's formula the sampled spectrum is sum_k S_v |phi|^2 (f + k/T) plus the flat
    T (r_v(0) - int S_v |phi|^2 df) >= 0: jitter turns that part of the coloured noise white."""
    wide = ji.NoiseModel(ji.TransferFunction([3.0], [1.0, 3.0]))

    def smoothed(f):
        return wide.spectrum(f) * np.abs(law.cf(f)) ** 2

    kept = 2 * integrate.quad(smoothed, 0, np.inf, limit=500, epsabs=1e-13)[0]
    floor = T * (wide.variance - kept)
    f = np.array([0.0, 0.1, 0.25, 0.5])
    K = 2000
    k = np.arange(-K, K + 1) / T

    def tail(fi):
        # Without jitter |phi| = 1 and the alias sum converges like S_v ~ f^-2: add the terms
        # |k| > K as an integral (midpoint rule, error ~ K^-4). With jitter |phi|^2 decays
        # too (f^-2 or faster) and the truncation error is below 1e-10.
        if not isinstance(law, ji.NoJitter):
            return 0.0
        right = integrate.quad(lambda x: smoothed(fi + x), (K + 0.5) / T, np.inf, epsabs=1e-14)[0]
        left = integrate.quad(lambda x: smoothed(fi - x), (K + 0.5) / T, np.inf, epsabs=1e-14)[0]
        return T * (right + left)

    aliased = np.array([np.sum(smoothed(fi + k)) + tail(fi) for fi in f])
    got = ji.jittered_autocovariance(wide, law, T).spectrum(f)
    np.testing.assert_allclose(got, aliased + floor, rtol=1e-7)
    assert floor == pytest.approx(0.0, abs=1e-9) if isinstance(law, ji.NoJitter) else floor > 0.01


# --------------------------------------------------------------------------- Sigma_y


@pytest.mark.parametrize("law", [ji.Uniform(0.5), ji.Gaussian(0.4), ji.NoJitter()], ids=str)
def test_banded_criterion_and_dft_covariance_match_dense_linear_algebra(law):
    """(C4) ln det and solve, the Toeplitz product, R_Y and C_Y and R_Y(f, f) against the dense
    N x N Sigma_y = diag(d) + Toeplitz(gamma)."""
    n = 41
    rng = np.random.default_rng(2)
    gamma = ji.jittered_autocovariance(RESONANT_NOISE, law, T)
    d = rng.uniform(0.0, 0.05, n)
    cov = ji.SampleCovariance(d, gamma)
    lags = np.abs(np.arange(n)[:, None] - np.arange(n)[None, :])
    dense = np.diag(d) + gamma(lags)
    np.testing.assert_allclose(cov.dense(), dense, atol=1e-15)
    assert cov.logdet == pytest.approx(np.linalg.slogdet(dense)[1], rel=1e-12)
    r = rng.standard_normal((n, 3))
    np.testing.assert_allclose(cov.solve(r), np.linalg.solve(dense, r), rtol=1e-9, atol=1e-9)
    f, psi = np.arange(n // 2) / (n * T), np.array([0.013, 0.21, 0.37])
    E, Epsi = (np.exp(-2j * np.pi * np.outer(x, np.arange(n) * T)) for x in (f, psi))
    np.testing.assert_allclose(cov.dft(T, f), E @ dense @ E.conj().T, atol=1e-12)
    np.testing.assert_allclose(cov.dft(T, f, psi), E @ dense @ Epsi.conj().T, atol=1e-12)
    np.testing.assert_allclose(cov.dft(T, f, sign=-1.0), E @ dense @ E.T, atol=1e-12)
    np.testing.assert_allclose(
        cov.dft_diagonal(T, psi), np.diag(Epsi @ dense @ Epsi.conj().T).real, atol=1e-12
    )


def test_without_coloured_noise_the_dft_covariance_is_lemma_2s():
    d = table2_data(1, n=40)
    g = ji.PolePairGain().system(TRUTH)
    f = ji.default_frequencies(40, T)
    ours = ji.coloured_dft_covariance(g, d.u, ji.Uniform(0.5), T, 40, f, 0.01)
    np.testing.assert_allclose(
        ours, ji.dft_covariance(g, d.u, ji.Uniform(0.5), T, 40, f, 0.01), atol=1e-12
    )


def test_banded_derivative_gives_the_log_det_derivative_and_band_inverse_is_exact():
    """(C4) for parameter derivatives: dB = d(L_a Sigma L_a^T) is banded although dL_a Sigma
    L_a^T is not, tr(B^{-1} dB) = d ln det Sigma, and B^{-1} on the band (Takahashi) equals
    the dense inverse there."""
    n, law = 30, ji.Uniform(0.5)
    d = np.random.default_rng(4).uniform(0.0, 0.05, n)
    st, eta = ji.RationalNoise(1, 2), np.array([0.3, 1.0, 0.8, 2.0])

    def cov_at(e):
        return ji.SampleCovariance(d, ji.jittered_autocovariance(st.model(e), law, T))

    cov = cov_at(eta)
    dc, dp = st.mode_derivatives(eta)
    dgam, dar = autocovariance_derivatives(st.model(eta), law, T, dc, dp, n)
    dB = cov.derivative_band(np.zeros((eta.size, n)), dgam, dar)
    L = cov.filter(np.eye(n))

    def band_matrix(e):
        c = cov_at(e)
        return c.filter(c.filter(c.dense()).T).T  # L_a Sigma L_a^T

    dense_db = central_differences(band_matrix, eta)
    dlogdets = central_differences(lambda e: np.array([cov_at(e).logdet]), eta)[:, 0]
    for i in range(eta.size):
        fd = dense_db[i]
        assert np.max(np.abs(np.tril(fd, -cov.width - 1))) < 1e-7  # banded
        for b in range(cov.width + 1):
            np.testing.assert_allclose(dB[i, b, : n - b], np.diag(fd, -b), atol=1e-7)
        zb = cov.band_inverse
        trace = np.sum(zb[0] * dB[i, 0]) + 2 * np.sum(zb[1:] * dB[i, 1:])
        assert trace == pytest.approx(dlogdets[i], rel=1e-6)
    Z = np.linalg.inv(L @ cov.dense() @ L.T)
    for b in range(cov.width + 1):
        np.testing.assert_allclose(cov.band_inverse[b, : n - b], np.diag(Z, -b), rtol=1e-10)


@pytest.mark.parametrize(
    ("model", "law"),
    [
        (ji.RationalNoise(0, 1), ji.Uniform(0.5)),
        (ji.RationalNoise(1, 2), ji.SumOfUniforms(2, 0.5)),
        (ji.RationalNoise(0, 2), ji.NoJitter()),
    ],
    ids=str,
)
def test_closed_form_autocovariance_derivatives_match_differences(model, law):
    eta = {
        2: np.array([0.07, 0.08]),
        4: np.array([0.3, 1.0, 0.8, 2.0]),
        3: np.array([0.5, 3.0, 1.5]),
    }[len(model.param_names)]
    dc, dp = model.mode_derivatives(eta)
    dgam, dar = autocovariance_derivatives(model.model(eta), law, T, dc, dp, 25)

    def flat(e):
        g = ji.jittered_autocovariance(model.model(e), law, T)
        return np.r_[g.sequence(25), g.ar]

    np.testing.assert_allclose(
        np.c_[dgam, dar], central_differences(flat, eta), rtol=1e-7, atol=1e-9
    )
    assert autocovariance_derivatives(model.model(eta), ji.Gaussian(0.4), T, dc, dp, 25) is None
