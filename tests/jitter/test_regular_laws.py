"""Jitter laws regular in their shape (jitterid.jitter.regular): GeneralizedNormal, DualDirac,
GaussianScaleMixture, their families.

Referees: direct numerical integration of the density (scipy.integrate.quad), the empirical
characteristic function and moments of simulated draws, the closed-form neighbours
(Gaussian, Uniform), central differences of the moments and of the log-likelihood, and
repeated simulation (round trip; ML against the Cramer-Rao bound, slow).
"""

import itertools
import math
import warnings

import numpy as np
import pytest
from scipy import integrate

import jitterid as ji
from jitterid.estimation.problem import Problem
from jitterid.jitter import registry

T, NOISE = 1.0, 0.01
TRUTH = np.array([6.25, -1.5, 2.0])
SIGMA3 = 1 / (6 * np.sqrt(3))  # Table 3's jitter std

LAWS = {
    "gn-laplace": ji.GeneralizedNormal(0.1, 1.0),
    "gn-1.37": ji.GeneralizedNormal(0.1, 1.37),
    "gn-2.6": ji.GeneralizedNormal(0.12, 2.6),
    "gn-40": ji.GeneralizedNormal(0.1, 40.0),
    "dd": ji.DualDirac(0.05, 0.3),
    "dd-overlap": ji.DualDirac(0.08, 0.05),
    "mix-0.6": ji.GaussianScaleMixture(0.1, 0.6),
    "mix-0.95": ji.GaussianScaleMixture(0.1, 0.95),
}
law_param = pytest.mark.parametrize("law", list(LAWS.values()), ids=list(LAWS))


def _quad(fun, law, lo=-np.inf, hi=np.inf):
    """int_lo^hi fun(tau) p(tau) dtau by adaptive quadrature (scipy's QUADPACK) between the
    law's breakpoints (the referee of the laws' own Gauss-Legendre panels)."""
    bp = law.breakpoints()
    edges = np.unique(np.clip(bp, max(lo, bp[0]), min(hi, bp[-1])))
    total = 0.0
    with warnings.catch_warnings():  # roundoff notices at 1e-13: the result is still used
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        for a, b in itertools.pairwise(edges):
            total += integrate.quad(
                lambda t: fun(t) * float(law.pdf(t)), a, b, epsabs=1e-15, epsrel=1e-13, limit=200
            )[0]
    return total


# ------------------------------------------------------------------ the laws
@law_param
def test_pdf_integrates_to_one_and_has_the_stated_variance(law):
    assert _quad(lambda t: 1.0, law) == pytest.approx(1.0, abs=1e-12)
    assert _quad(lambda t: t * t, law) == pytest.approx(law.var, rel=1e-10)
    lo, hi = law.support
    assert law.pdf(np.array([lo - 1e-9, hi + 1e-9])).tolist() == [0.0, 0.0]
    bp = law.breakpoints()
    assert bp[0] == lo
    assert bp[-1] == hi
    assert np.all(np.diff(bp) > 0)
    np.testing.assert_allclose(bp, -bp[::-1], atol=1e-15)  # symmetric rule


@law_param
def test_cf_matches_integration_of_the_pdf(law):
    f = np.array([0.0, 0.7, 2.3, 5.0, 11.0]) / law.std
    ref = [_quad(lambda t, fi=fi: math.cos(2 * math.pi * fi * t), law) for fi in f]
    np.testing.assert_allclose(law.cf(f).real, ref, rtol=0, atol=1e-11)
    assert np.all(law.cf(f).imag == 0)


@law_param
def test_samples_match_cf_std_and_support(law):
    rng = np.random.default_rng(20240612)
    tau = law.sample(400_000, rng)
    assert tau.std() == pytest.approx(
        law.std, rel=5 * np.sqrt(0.5 * (law_kurtosis(law) - 1) / tau.size)
    )
    f = np.array([0.3, 1.0, 2.0]) / law.std
    emp = np.exp(-2j * np.pi * np.outer(f, tau)).mean(axis=1)
    # the empirical cf's std is at most 1 / sqrt(n) per component
    np.testing.assert_allclose(emp, law.cf(f), rtol=0, atol=5 / np.sqrt(tau.size))
    lo, hi = law.support
    assert np.mean((tau < lo) | (tau > hi)) == 0.0
    # the histogram against the density (the sampler's shape, not only its moments)
    edges = np.linspace(-2 * law.std, 2 * law.std, 9)
    mass = np.array([_quad(lambda t: 1.0, law, a, b) for a, b in itertools.pairwise(edges)])
    counts = np.histogram(tau, edges)[0] / tau.size
    assert np.all(np.abs(counts - mass) <= 5 * np.sqrt(mass / tau.size))


def law_kurtosis(law):
    return _quad(lambda t: t**4, law) / law.var**2


def test_beta_two_is_the_gaussian_and_large_beta_the_uniform():
    gn, g = ji.GeneralizedNormal(0.1, 2.0), ji.Gaussian(0.1)
    t = np.linspace(-0.9, 0.9, 181)
    np.testing.assert_allclose(gn.pdf(t), g.pdf(t), rtol=1e-13, atol=1e-300)
    np.testing.assert_allclose(gn.support, g.support, rtol=1e-15)
    f = np.linspace(0, 12, 25)
    np.testing.assert_allclose(gn.cf(f), g.cf(f), rtol=0, atol=1e-15)
    # beta -> inf: U(-sqrt 3 std, sqrt 3 std), the cf converging like 1 / beta
    u = ji.Uniform(np.sqrt(3) * 0.1)
    f = np.linspace(0, 8, 17)
    gaps = [
        np.max(np.abs(ji.GeneralizedNormal(0.1, b).cf(f) - u.cf(f))) for b in (50.0, 200.0, 800.0)
    ]
    assert gaps[2] < 5e-3
    assert gaps[0] > 3 * gaps[1] > 9 * gaps[2]


def test_dual_dirac_with_no_deterministic_jitter_is_gaussian():
    dd, g = ji.DualDirac(0.07, 0.0), ji.Gaussian(0.07)
    t = np.linspace(-0.7, 0.7, 141)
    np.testing.assert_allclose(dd.pdf(t), g.pdf(t), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(dd.cf(t * 30), g.cf(t * 30), rtol=1e-15)
    assert dd.std == g.std
    assert dd.support == pytest.approx(g.support, rel=1e-15)
    assert ji.DualDirac(0.03, 0.4).std == pytest.approx(math.sqrt(0.03**2 + 0.2**2), rel=1e-15)


def test_scale_mixture_with_no_split_is_gaussian_and_has_its_kurtosis():
    mx, g = ji.GaussianScaleMixture(0.07, 0.0), ji.Gaussian(0.07)
    t = np.linspace(-0.7, 0.7, 141)
    np.testing.assert_allclose(mx.pdf(t), g.pdf(t), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(mx.cf(t * 30), g.cf(t * 30), rtol=1e-13)
    assert mx.support == pytest.approx(g.support, rel=1e-15)
    for rho in (0.3, 0.8):
        law = ji.GaussianScaleMixture(0.07, rho)
        assert _quad(lambda t: t**4, law) / law.var**2 == pytest.approx(law.kurtosis, rel=1e-10)
        assert law.kurtosis == pytest.approx(3 * (1 + rho**2), rel=1e-15)


@law_param
def test_expect_of_smooth_functions_matches_a_fine_reference(law):
    def g(t):
        return np.vstack([np.cos(7 * t / law.std + 0.4), np.exp(t / law.std), t**4 / law.var**2])

    ref = [
        _quad(lambda t: math.cos(7 * t / law.std + 0.4), law),
        _quad(lambda t: math.exp(t / law.std), law),
        _quad(lambda t: t**4 / law.var**2, law),
    ]
    np.testing.assert_allclose(law.expect(g), ref, rtol=0, atol=1e-10)


def test_bad_arguments_name_the_argument_and_the_fix():
    with pytest.raises(ValueError, match=r"beta must lie in \[0.5, 1000\].*Uniform"):
        ji.GeneralizedNormal(0.1, 0.0)
    with pytest.raises(ValueError, match="beta must lie"):
        ji.GeneralizedNormal(0.1, -2.0)
    with pytest.raises(ValueError, match="std must be finite and > 0"):
        ji.GeneralizedNormal(0.0, 2.0)
    with pytest.raises(TypeError, match="beta must be a real number"):
        ji.GeneralizedNormal(0.1, "two")
    with pytest.raises(ValueError, match=r"dj must be finite and >= 0.*peak-to-peak"):
        ji.DualDirac(0.05, -0.1)
    with pytest.raises(ValueError, match="rj must be finite and > 0"):
        ji.DualDirac(0.0, 0.1)
    with pytest.raises(ValueError, match="beta_min < beta_max"):
        ji.GeneralizedNormalFamily(beta_min=3.0, beta_max=2.0)
    with pytest.raises(ValueError, match=r"beta must be finite and lie in \[1, 50\]"):
        ji.GeneralizedNormalFamily().law([0.1, 60.0])
    with pytest.raises(ValueError, match=r"dj must be finite and lie in \[0, 1\]"):
        ji.DualDiracFamily(dj_max=1.0).law([0.1, -0.1])
    with pytest.raises(ValueError, match=r"rho must lie in \[0, 1\).*variance split"):
        ji.GaussianScaleMixture(0.1, 1.0)
    with pytest.raises(ValueError, match="sigma must be finite and > 0"):
        ji.GaussianScaleMixture(-0.1, 0.5)
    with pytest.raises(ValueError, match=r"rho_max must lie in \(0, 0.99\]"):
        ji.GaussianScaleMixtureFamily(rho_max=1.0)


# ------------------------------------------------------------------ families: derivatives
FAMILIES = {
    "gn": (ji.GeneralizedNormalFamily(std_max=0.5), [0.1, 2.7]),
    "gn-near-integer": (ji.GeneralizedNormalFamily(std_max=0.5), [0.09, 3.0]),
    "dd": (ji.DualDiracFamily(rj_max=0.5, dj_max=1.0), [0.05, 0.2]),
    "mix": (ji.GaussianScaleMixtureFamily(sigma_max=0.5), [0.1, 0.6]),
}
fam_param = pytest.mark.parametrize(("family", "jp"), list(FAMILIES.values()), ids=list(FAMILIES))


def _data(law, seed=5, n=60):
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 2, rng)
    return ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, n, NOISE, rng)


@fam_param
def test_pdf_gradient_matches_differences_of_the_pdf(family, jp):
    law = family.law(jp)
    t = np.linspace(*law.support, 301)[1:-1]
    grad = family.pdf_gradient(jp, t)
    for i in range(2):
        h = 1e-5 * jp[i]
        up, down = list(jp), list(jp)
        up[i] += h
        down[i] -= h
        fd = (family.law(up).pdf(t) - family.law(down).pdf(t)) / (2 * h)
        np.testing.assert_allclose(grad[i], fd, rtol=0, atol=1e-7 * np.max(np.abs(fd)))
    # d/dtheta of the mass is zero
    np.testing.assert_allclose(
        law.expect(lambda tau: family.pdf_gradient(jp, tau) / law.pdf(tau)), 0, atol=1e-10
    )


@fam_param
@pytest.mark.parametrize("method", ["gaussian", "bcls"])
def test_moment_derivatives_in_the_family_parameters(family, jp, method):
    """The moments' derivative pass (analytic: dp/dtheta at the nodes) against central
    differences of the moments, in every jitter parameter."""
    data = _data(family.law(jp))
    pr = Problem(data, ji.PolePairGain(), family, method, ji.default_frequencies(data.N, T), NOISE)
    x = np.r_[jp, TRUTH]
    _, _, dm, dw = pr.derivatives(x)
    for i in range(2):
        h = 1e-4 * x[i]
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        mu, md = pr.moments(up), pr.moments(down)
        fd = (mu.mean - md.mean) / (2 * h)
        np.testing.assert_allclose(dm[i], fd, rtol=0, atol=2e-6 * np.max(np.abs(fd)))
        if method == "gaussian":
            fdv = (mu.var - md.var) / (2 * h)
            np.testing.assert_allclose(dw[i], fdv, rtol=0, atol=2e-6 * np.max(np.abs(fdv)))


@fam_param
def test_likelihood_scores_in_the_family_parameters(family, jp):
    data = _data(family.law(jp), seed=6)
    lik = ji.ExactLikelihood(ji.PolePairGain(), family, data.u, T, data.N, NOISE)
    x = np.r_[jp, TRUTH]
    _, G = lik.scores(x, data.y)
    for i in range(x.size):
        h = 1e-4 * abs(x[i])
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        fd = (lik.logpdf(up, data.y) - lik.logpdf(down, data.y)) / (2 * h)
        np.testing.assert_allclose(G[:, i], fd, rtol=0, atol=1e-5 * np.max(np.abs(fd)))


def test_crb_is_smooth_in_beta_across_integers():
    """(26) has a kink at every integer n, and its "CRB" jumps in slope there (measured on this
    record: the one-sided slopes of sqrt(CRB) at n = 2 differ by ~70x sqrt(CRB) per unit n,
    growing as the step shrinks). The generalized normal has none: at beta = 2 and 3 the
    one-sided slopes of sqrt(CRB) with steps of 0.05 agree to a few percent of sqrt(CRB)
    per unit beta (s'' h for a smooth curve). 15 samples (was 30; the record's length
    hardly moves these numbers): with these steps the generalized normal's slopes differ
    by 0.3 and 0.1 of the tolerance at beta = 2 and 3 (0.3 and 0.1 at 30), and those of
    the kinked SumOfUniformsFamily (a = 0.3) by 7000 and 9000 of it at n = 2 and 3 (6600
    and 8700 at 30)."""
    n, h = 15, 0.05
    u = ji.telegraph_input(n * T + 2, np.random.default_rng(3))
    fam = ji.GeneralizedNormalFamily(std_max=0.5)
    for k in (2.0, 3.0):
        sd = np.array(
            [
                np.sqrt(
                    np.diag(ji.crb(ji.PolePairGain(), fam, u, T, n, NOISE, np.r_[0.1, b, TRUTH]))
                )
                for b in (k - h, k, k + h)
            ]
        )
        assert np.all(np.isfinite(sd))
        assert np.all(sd > 0)
        left, right = (sd[1] - sd[0]) / h, (sd[2] - sd[1]) / h
        assert np.all(np.abs(sd[2] - sd[0]) <= 0.1 * sd[1])  # continuous
        assert np.all(np.abs(right - left) <= 0.05 * sd[1]), (k, (right - left) / sd[1])  # no kink


# ------------------------------------------------------------------ fits
@pytest.mark.parametrize(
    ("law", "family", "jp"),
    [
        (ji.GeneralizedNormal(SIGMA3, 2.0), ji.GeneralizedNormalFamily(std_max=0.5), [SIGMA3, 2.0]),
        (ji.DualDirac(0.05, 0.2), ji.DualDiracFamily(rj_max=0.5, dj_max=1.0), [0.05, 0.2]),
    ],
    ids=["generalized-normal", "dual-dirac"],
)
def test_ml_round_trip_on_table_2s_system(law, family, jp):
    rng = np.random.default_rng(1202)
    u = ji.telegraph_input(200 * T + 2, rng)
    data = ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, 200, NOISE, rng)
    res = ji.fit(data, ji.PolePairGain(), family, method="ml", noise_std=NOISE)
    assert res.status.success, res.message
    truth = np.r_[jp, TRUTH]
    se = np.sqrt(np.diag(res.cov))
    assert np.all(np.abs(res.x - truth) <= 3.5 * se), (res.x, truth, se)


@pytest.mark.parametrize("method", ["bcls", "gaussian"])
def test_moment_fits_run_with_the_regular_families(method):
    law, fam = ji.DualDirac(0.05, 0.2), ji.DualDiracFamily(rj_max=0.5, dj_max=1.0)
    data = _data(law, seed=8, n=120)
    res = ji.fit(data, ji.PolePairGain(), fam, method=method, noise_std=NOISE)
    assert res.names[:2] == ("rj", "dj")
    assert np.all(np.isfinite(res.x))
    # the moment criteria see the jitter's std (through the variances or the bias), hardly
    # its shape: the fitted law's std within a factor 2 (BCLS's std error is ~35 % here)
    assert abs(np.log(fam.law(res.x[:2]).std / law.std)) < np.log(2)
    gn = ji.GeneralizedNormalFamily(std_max=0.5)
    res = ji.fit(data, ji.PolePairGain(), gn, method=method, noise_std=NOISE)
    assert res.names[:2] == ("std", "beta")
    assert abs(np.log(res.x[0] / law.std)) < np.log(2)


# ------------------------------------------------------------------ registry
def test_registry_is_the_one_table_for_cli_and_toml():
    from jitterid.cli import _specs
    from jitterid.experiments import config

    assert registry.law_kind("generalized_normal") is registry.law_kind("generalized-normal")
    assert registry.law_kind("generalized-normal").cls is ji.GeneralizedNormal
    assert registry.family_kind("dual_dirac").cls is ji.DualDiracFamily
    assert config.LAWS["dual_dirac"][0] is ji.DualDirac
    assert config.FAMILIES["generalized_normal"][0] is ji.GeneralizedNormalFamily
    law = _specs.parse_jitter("known:generalized-normal:std=80ms,beta=3")
    assert law == ji.GeneralizedNormal(0.08, 3.0)
    assert _specs.parse_jitter("dual_dirac:rj=5ms,dj=0.2", law_only=True) == ji.DualDirac(
        0.005, 0.2
    )
    fam = _specs.parse_jitter("generalized-normal:std_max=0.5,beta_max=20")
    assert fam == ji.GeneralizedNormalFamily(std_max=0.5, beta_max=20.0)
    assert _specs.parse_jitter("dual-dirac:dj_max=1") == ji.DualDiracFamily(dj_max=1.0)
    assert _specs.parse_jitter("known:scale-mixture:sigma=5ms,rho=0.6") == (
        ji.GaussianScaleMixture(0.005, 0.6)
    )
    assert _specs.parse_jitter("scale-mixture:rho_max=0.9") == ji.GaussianScaleMixtureFamily(
        rho_max=0.9
    )
    with pytest.raises(ValueError, match="unknown law"):
        _specs.parse_jitter("known:generalised-normal:std=1,beta=2")


# ------------------------------------------------------------------ Table 3, regular family
def _table3_study(law, family, jp, runs, seed):
    """Table 3's setup (N = 200, telegraph input, noise 0.01, model (27)) with ``law`` and
    ``family``: ML per realization, the CRB at the truth for that input."""
    truth = np.r_[jp, TRUTH]
    est, crbs = [], []
    for child in np.random.SeedSequence(seed).spawn(runs):
        rng = np.random.default_rng(child)
        u = ji.telegraph_input(200 * T + 2, rng)
        data = ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, 200, NOISE, rng)
        est.append(ji.fit(data, ji.PolePairGain(), family, method="ml", noise_std=NOISE).x)
        crbs.append(ji.crb(ji.PolePairGain(), family, u, T, 200, NOISE, truth))
    est = np.array(est)
    bound = np.sqrt(np.diag(np.mean(crbs, axis=0)))
    return truth, est, bound


@pytest.mark.slow
@pytest.mark.parametrize(
    ("law", "family", "jp"),
    [
        pytest.param(
            ji.GeneralizedNormal(SIGMA3, 2.0),
            ji.GeneralizedNormalFamily(std_max=0.5),
            [SIGMA3, 2.0],
            # measured (docs/ml_and_crb.md): std, k0, pr, pi at 0.95-1.03, but beta at 1.233
            # (these 64 runs) and 1.21 +- 0.08 over 128: at N = 200 beta-hat is still
            # right-skewed (mean 2.17 for 2, robust std 1.13 sqrt(CRB)), not a kink
            marks=pytest.mark.xfail(
                reason="beta: ML std / sqrt(CRB) = 1.23 at N = 200 (finite-sample skew)",
                strict=False,
            ),
        ),
        (ji.DualDirac(0.05, 0.2), ji.DualDiracFamily(rj_max=0.5, dj_max=1.0), [0.05, 0.2]),
    ],
    ids=["generalized-normal", "dual-dirac"],
)
def test_table3_with_a_regular_family_ml_attains_the_crb(law, family, jp):
    truth, est, bound = _table3_study(law, family, jp, runs=64, seed=20070203)
    ratio = est.std(axis=0, ddof=1) / bound
    names = [*family.param_names, "k0", "pr", "pi"]
    print(
        "\n"
        + "\n".join(
            f"{n}: true {t:.4g} mean {m:.4g} std {s:.4g} sqrt(CRB) {b:.4g} ratio {r:.3f}"
            for n, t, m, s, b, r in zip(
                names, truth, est.mean(axis=0), est.std(axis=0, ddof=1), bound, ratio, strict=True
            )
        )
    )
    assert np.all(ratio <= 1.2), dict(zip(names, ratio.round(3), strict=True))
