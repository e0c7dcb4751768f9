"""The structured sine likelihood's noise kernel (jitterid.metrology.sinelik_kernel): the
bin kernel of a quantised record, K(e) = [Phi((e + q/2)/sigma) - Phi((e - q/2)/sigma)] / q,
and the per-sample likelihood built on it, against independent referees."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

import jitterid as ji
from jitterid.metrology.sinelik import TOLERANCE, SineLikelihood
from jitterid.metrology.sinelik_kernel import Kernel


def _quad_ln_k(e: float, sigma: float, half: float) -> float:
    """ln K(e) by adaptive quadrature of the Gaussian density over the bin."""
    val, _ = integrate.quad(
        lambda t: stats.norm.pdf(t, scale=sigma), e - half, e + half, epsabs=0, epsrel=1e-13
    )
    return math.log(val / (2 * half))


def _rich(f, x: float, d: float) -> float:
    """Central differences at steps d and d/2, Richardson-extrapolated (O(d^4))."""

    def c(h: float) -> float:
        return (f(x + h) - f(x - h)) / (2 * h)

    return (4 * c(d / 2) - c(d)) / 3


@pytest.mark.parametrize(("sigma", "half"), [(1.0, 0.5), (0.2, 0.5), (5.0, 0.5), (1.0, 1e-3)])
def test_the_bin_kernel_against_quadrature_and_differences(sigma, half):
    """ln K against quadrature of the Gaussian over the bin (within 1e-12), and its five
    derivatives in e and sigma against Richardson-extrapolated central differences of the
    kernel's own lower derivatives (measured 1e-12-1e-9 relative; within 1e-6). Can fail:
    a sign or a factor of a derivative off is off by 10 % or more."""
    k = Kernel(sigma, half)
    scale = max(sigma, half)
    e = np.array([-3.0, -0.6, -0.5, -0.2, 0.0, 0.3, 0.49, 0.7, 2.0, 4.0]) * scale
    ln = k.log_rel(e) + k.const
    k1, ks = k.first(e)
    k2, kss, k1s, k1b, ksb = k.second(e)
    np.testing.assert_allclose(k1b, k1, rtol=1e-13)
    np.testing.assert_allclose(ksb, ks, rtol=1e-13, atol=1e-13 / scale)
    for i, ei in enumerate(e):
        assert ln[i] == pytest.approx(_quad_ln_k(ei, sigma, half), abs=1e-12)
        de, ds = 1e-3 * scale, 1e-3 * sigma

        def lnk(ee, ss):
            kk = Kernel(ss, half)
            return float(kk.log_rel(np.array([ee]))[0] + kk.const)

        refs = {
            "k1": (k1[i], _rich(lambda v: lnk(v, sigma), ei, de)),
            "ks": (ks[i], _rich(lambda v, ei=ei: lnk(ei, v), sigma, ds)),
            "k2": (k2[i], _rich(lambda v: Kernel(sigma, half).first(np.array([v]))[0][0], ei, de)),
            "kss": (
                kss[i],
                _rich(lambda v, ei=ei: Kernel(v, half).first(np.array([ei]))[1][0], sigma, ds),
            ),
            "k1s": (
                k1s[i],
                _rich(lambda v, ei=ei: Kernel(v, half).first(np.array([ei]))[0][0], sigma, ds),
            ),
        }
        for name, (got, ref) in refs.items():
            assert abs(got - ref) <= 1e-6 * max(abs(ref), 1.0 / scale**2), (name, ei, got, ref)


def test_the_bin_kernel_deep_inside_its_bin_is_the_full_formula(monkeypatch):
    """More than INSIDE sigma inside the bin's edges the kernel skips the CDFs (ln K = -ln q,
    the derivatives 0): on a 2-d grid of errors through that threshold and both edges, the
    same values as the full formulas (INSIDE set beyond the bin), within 1e-13 of each
    term's scale (1/sigma, 1/sigma^2). Can fail: a value scattered to the wrong place, an
    odd term's sign lost, a threshold too shallow (Phi(-3) = 1e-3 there)."""
    from jitterid.metrology import sinelik_kernel

    sigma, half = 0.01, 0.5
    e = np.linspace(-0.75, 0.75, 3003).reshape(3, -1)
    k = Kernel(sigma, half)
    fast = (k.log_rel(e), *k.first(e), *k.second(e))
    assert k._near(np.abs(e)) is not None  # (the threshold is in use)
    for ei in (0.0, 0.2, -0.35, 0.45, 0.5, -0.53):  # ln K against quadrature
        got = float(k.log_rel(np.array([ei]))[0] + k.const)
        assert got == pytest.approx(_quad_ln_k(ei, sigma, half), abs=1e-12)
    monkeypatch.setattr(sinelik_kernel, "INSIDE", 1e9)
    assert k._near(np.abs(e)) is None
    full = (k.log_rel(e), *k.first(e), *k.second(e))
    scales = (1.0, 1 / sigma, 1 / sigma, *[1 / sigma**2] * 3, 1 / sigma, 1 / sigma)
    for got, ref, sc in zip(fast, full, scales, strict=True):
        assert got.shape == e.shape
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-13 * sc)


def test_the_bin_kernel_far_past_its_bin_and_the_gaussian_limit():
    """Far past the bin (60 sigma: Phi underflows, the log form takes over) ln K is finite
    and continuous with the near form, its derivatives finite; with no bin (half = 0) the
    Gaussian's closed forms; a bin 1e-6 of sigma is the Gaussian to 1e-12 in ln K."""
    k = Kernel(0.01, 0.5)
    e = np.array([0.5 + 0.01 * 37.0, 0.5 + 0.01 * 38.5, 0.5 + 0.01 * 60.0, -(0.5 + 0.6)])
    ln = k.log_rel(e)
    assert np.all(np.isfinite(ln))
    assert ln[0] > ln[1] > ln[2]
    assert all(np.all(np.isfinite(t)) for t in k.second(e))
    # either side of the switch to the log form (d > 1e-290): the slope is the kernel's own
    lo, hi = 0.5 + 0.01 * 37.5, 0.5 + 0.01 * 37.7
    slope = (k.log_rel(np.array([hi]))[0] - k.log_rel(np.array([lo]))[0]) / (hi - lo)
    mid = k.first(np.array([0.5 * (lo + hi)]))[0][0]
    assert slope == pytest.approx(mid, rel=1e-4)
    g = Kernel(0.3)
    x = np.linspace(-1, 1, 7)
    np.testing.assert_allclose(g.log_rel(x), -0.5 * (x / 0.3) ** 2)
    np.testing.assert_allclose(g.first(x)[0], -x / 0.09)
    narrow = Kernel(0.3, 0.3e-6)
    np.testing.assert_allclose(narrow.log_rel(x) + narrow.const, g.log_rel(x) + g.const, atol=1e-12)


def test_the_bin_kernel_is_the_probability_of_the_bin():
    """The model itself: s + N(0, sigma^2) rounded to the grid of step q lands in the bin of
    centre y with probability q K(y - s) (200 000 draws a setting; within 5 binomial
    standard errors). Can fail: a kernel of the wrong width or centre is off by 10 % or
    more."""
    rng = np.random.default_rng(5)
    q = 0.1
    for sigma, s in ((0.02, 0.013), (0.05, 0.031), (0.2, -0.04)):
        k = Kernel(sigma, q / 2)
        draws = q * np.round((s + sigma * rng.standard_normal(200_000)) / q)
        for y in np.unique(draws):
            p_hat = float(np.mean(draws == y))
            p = q * math.exp(float(k.log_rel(np.array([y - s]))[0]) + k.const)
            assert abs(p_hat - p) <= 5 * math.sqrt(p * (1 - p) / draws.size) + 1e-12, (y, p, p_hat)


def _quantised(N, family_law, sigma, q, rng, T=1.0, f=0.1234, A=1.0, c=0.05, phi=0.4):
    tau = family_law.sample(N, rng)
    x = A * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + phi) + c
    return q * np.round((x + sigma * rng.standard_normal(N)) / q)


@pytest.mark.parametrize(
    ("law", "sigma"),
    [
        (ji.Gaussian(0.02), 0.01),
        (ji.Gaussian(0.02), 0.002),
        (ji.Gaussian(0.2), 0.02),
        (ji.Gaussian(0.005), 0.05),
        (ji.Gaussian(0.02), 1e-4),
        (ji.Uniform(0.03), 0.01),
    ],
)
def test_the_bin_likelihood_per_sample_against_quadrature(law, sigma):
    """ln p(y_k) of a quantised record (q = 0.05, sigma from 0.002 to 1 step before the
    quantiser, phase spreads 0.015-1.5 rad) against adaptive quadrature over the jitter of
    its density times the bin kernel, within the rule's stated TOLERANCE (measured 5e-12 -
    2.4e-8)."""
    rng = np.random.default_rng(1)
    q, f, A, c, phi = 0.05, 0.1234, 1.0, 0.05, 0.4
    y = _quantised(48, law, sigma, q, rng)
    fam = ji.GaussianFamily() if isinstance(law, ji.Gaussian) else ji.UniformFamily()
    jp = law.std if isinstance(law, ji.Gaussian) else law.a
    lik = SineLikelihood(y, 1.0, fam, quantisation_step=q)
    lp = lik.logpdf([jp, A, phi, f, c, sigma])
    lo, hi = law.support if isinstance(law, ji.Uniform) else (-9 * law.std, 9 * law.std)
    k = Kernel(sigma, q / 2)
    for j in range(0, 48, 6):

        def g(t, j=j):
            e = y[j] - c - A * np.sin(2 * np.pi * f * (j + t) + phi)
            return float(law.pdf(np.array([t]))[0]) * math.exp(
                float(k.log_rel(np.array([e]))[0]) + k.const
            )

        v, _ = integrate.quad(
            g, lo, hi, limit=2000, epsabs=0, epsrel=1e-11, points=np.linspace(lo, hi, 41)[1:-1]
        )
        assert abs(lp[j] - math.log(v)) <= TOLERANCE, (j, lp[j], math.log(v))


@pytest.mark.parametrize(
    ("family", "jp", "sigma"),
    [
        (ji.GaussianFamily(), [0.02], 0.01),
        (ji.GaussianFamily(), [0.02], 0.003),
        (ji.UniformFamily(), [0.03], 0.01),
        (ji.DualDiracFamily(), [0.01, 0.03], 0.01),
        (ji.GaussianScaleMixtureFamily(), [0.02, 0.5], 0.01),
    ],
)
def test_the_bin_likelihood_score_and_information(family, jp, sigma):
    """The score of the bin likelihood against central differences of ln L, and its
    observed information against central differences of the score (500 samples, q =
    0.05; measured: the score 1e-7-2e-4 of sqrt(diag H) apart, the tolerance 1e-3; the
    information 5e-10-7e-7 of its largest entry, the tolerance 1e-5. At 1500 samples, as
    before: 2e-7-3e-4 and 2e-9-6e-7). Can fail: a kernel derivative off in the score or
    the information is off by 1 % or more of the largest entry."""
    rng = np.random.default_rng(2)
    q = 0.05
    y = _quantised(500, family.law(jp), sigma, q, rng)
    lik = SineLikelihood(y, 1.0, family, quantisation_step=q)
    th = np.array([*jp, 1.0, 0.4, 0.1234, 0.05, sigma])
    _, g, _, H = lik.scores_information(th)
    gn, Hn = np.zeros_like(th), np.zeros((th.size, th.size))
    for i in range(th.size):
        h = 1e-9 if i == len(jp) + 2 else 1e-5 * max(abs(th[i]), 1e-3)
        up, dn = th.copy(), th.copy()
        up[i] += h
        dn[i] -= h
        gn[i] = (lik.loglik(up) - lik.loglik(dn)) / (2 * h)
        Hn[i] = -(lik.scores(up)[1] - lik.scores(dn)[1]) / (2 * h)
    scale = np.sqrt(np.abs(np.diag(H)))
    assert np.max(np.abs(g - gn) / scale) <= 1e-3
    Hn = 0.5 * (Hn + Hn.T)
    assert np.max(np.abs(H - Hn)) <= 1e-5 * np.max(np.abs(Hn))
