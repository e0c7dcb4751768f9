"""mu_Y and R_Y from the fast time-domain path against three referees: the paper's own
frequency-domain formulas (14b) and Lemma 2, and brute-force Monte Carlo over jitter draws."""

import numpy as np
import pytest

import jitterid as ji
from jitterid.moments import reference as spectral
from jitterid.moments.quadrature import jitter_nodes
from jitterid.moments.sample import sample_moments

T = 1.0


def mc_dft(system, u, law, T, N, f, noise_std, draws, rng):
    """Brute force: draw jitter and noise, sample, transform."""
    resp = system.response(u)
    tau = law.sample((draws, N), rng)
    y = resp(np.arange(N) * T + tau) + noise_std * rng.standard_normal((draws, N))
    return ji.dtft(y, T, f)


@pytest.mark.parametrize(
    "law",
    [ji.Uniform(0.5), ji.Gaussian(0.2), ji.SumOfUniforms(2, 0.45), ji.SumOfUniforms(1.4, 0.5)],
)
def test_expected_dft_matches_brute_force_monte_carlo(law):
    rng = np.random.default_rng(11)
    N = 24
    system = ji.TransferFunction([6.25], [1, 3, 6.25])
    u = ji.telegraph_input(N * T + 3, rng)
    f = np.array([0.0, 0.13, 0.37, 0.5, 0.8, 1.3, 2.45])  # below and above Nyquist (0.5 Hz)
    mu = ji.expected_dft(system, u, law, T, N, f)
    Y = mc_dft(system, u, law, T, N, f, 0.01, 4000, rng)
    se = Y.std(axis=0) / np.sqrt(Y.shape[0])
    z = np.abs(Y.mean(axis=0) - mu) / se
    assert np.all(z < 5), z
    # and jitter matters here: the jitter-free DTFT is many standard errors away
    mu0 = ji.expected_dft(system, u, ji.NoJitter(), T, N, f)
    assert np.max(np.abs(Y.mean(axis=0) - mu0) / se) > 10


@pytest.mark.parametrize("law", [ji.Uniform(0.4), ji.Gaussian(0.25)])
def test_covariance_and_pseudo_covariance_match_monte_carlo(law):
    rng = np.random.default_rng(12)
    N, noise = 16, 0.05
    system = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(N * T + 3, rng)
    f = np.array([0.05, 0.31, 0.62, 1.4])
    R = ji.dft_covariance(system, u, law, T, N, f, noise)
    C = ji.dft_pseudo_covariance(system, u, law, T, N, f, noise)
    Y = mc_dft(system, u, law, T, N, f, noise, 20000, rng)
    D = Y - Y.mean(axis=0)
    for model, prods in (
        (R, D[:, :, None] * D[:, None, :].conj()),
        (C, D[:, :, None] * D[:, None, :]),
    ):
        est = prods.mean(axis=0)
        se_re = prods.real.std(axis=0) / np.sqrt(len(D))
        se_im = prods.imag.std(axis=0) / np.sqrt(len(D))
        assert np.all(np.abs(est.real - model.real) < 5 * se_re + 1e-12)
        assert np.all(np.abs(est.imag - model.imag) < 5 * se_im + 1e-12)


def test_time_domain_mean_equals_the_papers_integral_14b():
    """(14b): mu_Y(f) = int S_c(psi) phi(-psi) d_N(f - psi) dpsi, with S_c = G U exactly."""
    rng = np.random.default_rng(13)
    N = 16
    system = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(N * T + 2, rng)
    law = ji.Uniform(0.5)
    f = np.linspace(0, 1.2, 9)
    fast = ji.expected_dft(system, u, law, T, N, f)

    def spectrum(psi):
        return system.frequency_response(psi) * u.fourier(psi)

    psi_max = 200.0
    n_psi = spectral.integral_grid_size(psi_max, T, N, (0.0, u.end + 25.0))
    ref = spectral.expected_dft_integral(spectrum, law, T, N, f, psi_max=psi_max, n_psi=n_psi)
    # The reference's truncation error at psi_max = 200 is ~1e-8 (it decays like psi_max^-3).
    np.testing.assert_allclose(fast, ref, atol=1e-6)


def test_time_domain_covariance_equals_literal_lemma_2_for_a_line_spectrum():
    """R_Y from Lemma 2 applied literally (deltas in S_c) equals the time-domain form."""
    N = 12
    f0, f1, amp0, amp1, ph0, ph1 = 0.14, 0.31, 1.0, 0.6, 0.4, -1.1
    u = ji.Multisine([f0, f1], [amp0, amp1], end=100.0, phases=[ph0, ph1], steady_state=True)
    identity = ji.TransferFunction([1.0], [1.0])
    law = ji.Uniform(0.5)
    f = np.array([0.0, 0.1, 0.26, 0.7])
    freqs = np.array([f0, -f0, f1, -f1])
    coeffs = (
        np.array(
            [
                amp0 * np.exp(1j * ph0),
                -amp0 * np.exp(-1j * ph0),
                amp1 * np.exp(1j * ph1),
                -amp1 * np.exp(-1j * ph1),
            ]
        )
        / 2j
    )
    ref_mu = spectral.expected_dft_lines(freqs, coeffs, law, T, N, f)
    ref_R = spectral.dft_covariance_lines(freqs, coeffs, law, T, N, f, f, noise_std=0.02)
    np.testing.assert_allclose(ji.expected_dft(identity, u, law, T, N, f), ref_mu, atol=1e-10)
    np.testing.assert_allclose(
        ji.dft_covariance(identity, u, law, T, N, f, 0.02), ref_R, atol=1e-10
    )


def test_alias_example_of_figure_2_through_the_time_domain_path():
    """T = 2, f0 = 0.14 and 0.64 are aliases; under U(-1, 1) jitter their mean DFTs differ by
    exactly phi(0.64) / phi(0.14) (phi is even, so both lines of each sinusoid scale alike)."""
    T2, N = 2.0, 32
    identity = ji.TransferFunction([1.0], [1.0])
    f = np.linspace(0.0, 0.25, 40)
    law = ji.Uniform(1.0)

    def mean(f0, jitter):
        u = ji.Multisine([f0], [1.0], end=200.0, steady_state=True)
        return ji.expected_dft(identity, u, jitter, T2, N, f)

    np.testing.assert_allclose(
        np.abs(mean(0.14, ji.NoJitter())), np.abs(mean(0.64, ji.NoJitter())), atol=1e-9
    )
    ratio = (law.cf(0.64) / law.cf(0.14)).real
    np.testing.assert_allclose(mean(0.64, law), ratio * mean(0.14, law), atol=1e-9)
    assert abs(ratio) < 0.25  # the damping is strong: the two are separable under jitter


@pytest.mark.parametrize("law", [ji.Uniform(0.5), ji.Gaussian(0.15), ji.SumOfUniforms(1.5, 0.5)])
def test_default_quadrature_matches_a_high_resolution_reference(law):
    rng = np.random.default_rng(14)
    N = 60
    # feedthrough: the output jumps at every switch, the hardest case for quadrature
    system = ji.TransferFunction([0.5, 1.0, 2.0, 3.0], [1.0, 4.0, 6.0, 4.5])
    resp = system.response(ji.telegraph_input(N * T + 2, rng))
    fast = sample_moments(resp, law, T, N)
    m_ref = np.zeros(N)
    v_ref = np.zeros(N)
    for ch in jitter_nodes(law, T, N, resp.breaks, resp.rate, order=16, max_panel=0.01):
        s = resp(ch.t)
        m_ref[ch.k0 : ch.k1] = ch.expect(s)
        v_ref[ch.k0 : ch.k1] = ch.expect((s - m_ref[ch.k0 : ch.k1][ch.owner]) ** 2)
    np.testing.assert_allclose(fast.mean, m_ref, atol=1e-11)
    np.testing.assert_allclose(fast.var, v_ref, atol=1e-11)


def test_chunked_and_unchunked_quadrature_agree():
    rng = np.random.default_rng(15)
    N = 300
    resp = ji.TransferFunction([6.25], [1, 3, 6.25]).response(ji.telegraph_input(N + 2.0, rng))
    law = ji.Uniform(0.5)
    whole = list(jitter_nodes(law, T, N, resp.breaks, resp.rate, chunk=N))
    parts = list(jitter_nodes(law, T, N, resp.breaks, resp.rate, chunk=37))
    m_whole = whole[0].expect(resp(whole[0].t))
    m_parts = np.concatenate([c.expect(resp(c.t)) for c in parts])
    np.testing.assert_allclose(m_parts, m_whole, rtol=0, atol=1e-13)


def test_no_jitter_moments_are_the_plain_samples():
    rng = np.random.default_rng(16)
    resp = ji.TransferFunction([1.0], [1.0, 2.0]).response(ji.telegraph_input(20.0, rng))
    mom = sample_moments(resp, ji.NoJitter(), T, 18)
    np.testing.assert_array_equal(mom.mean, resp(np.arange(18.0)))
    np.testing.assert_array_equal(mom.var, 0.0)


def test_input_too_short_for_the_jittered_record_is_refused():
    u = ji.telegraph_input(9.4, 0)  # the last instant may reach 9 + 0.5
    with pytest.raises(ValueError, match="input ends"):
        ji.expected_dft(ji.TransferFunction([1], [1, 2]), u, ji.Uniform(0.5), 1.0, 10, [0.1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"T": 0.0}, "T"),
        ({"N": 0}, "N"),
        ({"f": [np.nan]}, "f"),
        ({"noise_std": -1.0}, "noise_std"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, match):
    args = {
        "system": ji.TransferFunction([1], [1, 2]),
        "u": ji.telegraph_input(30.0, 0),
        "jitter": ji.Uniform(0.5),
        "T": 1.0,
        "N": 10,
        "f": [0.1],
        "noise_std": 0.1,
    }
    args.update(kwargs)
    with pytest.raises((ValueError, TypeError), match=match):
        ji.dft_covariance(**args)
