"""A jitter law declares what it offers; the fast paths ask for the capability, not the type.

Each new law here is written from scratch (not a subclass of a built-in law), so that a fast
path chosen by concrete type would miss it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

import jitterid as ji
from jitterid.jitter.laws import BandRule
from jitterid.moments.quadrature import relative_cuts
from jitterid.systems.tf import Response

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RaisedCosine(ji.JitterLaw):
    """p(tau) = (1 + cos(pi tau / a)) / (2a) on [-a, a]: declared by pdf, cf and support only."""

    a: float

    def pdf(self, tau: ArrayLike) -> FloatArray:
        t = np.asarray(tau, dtype=float)
        return np.where(np.abs(t) <= self.a, (1 + np.cos(np.pi * t / self.a)) / (2 * self.a), 0.0)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        x = 2 * np.asarray(f, dtype=float) * self.a
        return np.asarray(np.sinc(x) + 0.5 * (np.sinc(x - 1) + np.sinc(x + 1)), dtype=complex)

    @property
    def support(self) -> tuple[float, float]:
        return (-self.a, self.a)


A = 0.3
T, N = 0.5, 60
G = ji.TransferFunction([2.0, 1.0], [1.0, 1.0, 2.5])
U = ji.telegraph_input(40.0, rng=3)


def test_a_law_needs_only_its_pdf_cf_and_support():
    law = RaisedCosine(A)  # TypeError (abstract sample, var, breakpoints, params) before
    assert law.breakpoints().tolist() == [-A, A]
    assert law.params == {}
    assert law.var == pytest.approx(A**2 * (1 / 3 - 2 / math.pi**2), rel=1e-13)
    f = np.array([0.0, 0.7, 2.3, 5.1])  # the declared cf is the Fourier transform of the pdf
    by_pdf = law.expect(lambda t: np.exp(-2j * np.pi * np.outer(f, t)))
    np.testing.assert_allclose(law.cf(f), by_pdf, atol=1e-14)
    draws = law.sample(200_000, rng=1)  # the default sampler: the tabulated inverse CDF
    se = law.std / math.sqrt(draws.size)
    assert abs(draws.mean()) < 5 * se
    assert draws.var() == pytest.approx(law.var, rel=0.01)
    assert np.all(np.abs(draws) <= A)


class _Counting:
    """Counts the node-by-node evaluations of a Response (the quadrature route)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.calls = 0
        call = Response.__call__

        def counted(sig: Response, t: ArrayLike) -> FloatArray:
            self.calls += 1
            return call(sig, t)

        monkeypatch.setattr(Response, "__call__", counted)


def test_the_new_law_takes_the_segment_route_and_gives_the_node_route_moments(monkeypatch):
    law, resp = RaisedCosine(A), G.response(U)
    count = _Counting(monkeypatch)
    fast = ji.sample_moments(resp, law, T, N)
    assert count.calls == 0  # summed per input segment from the modal form
    slow = ji.moments.sample.moment_pass(resp, law, T, N)  # s(t) at every node
    assert count.calls > 0
    np.testing.assert_allclose(fast.mean, slow.mean, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.var, slow.var, rtol=0, atol=1e-13)
    # and brute force over jitter draws
    R = 5000
    tau = law.sample((R, N), rng=7)
    s = resp(T * np.arange(N) + tau)
    se = s.std(axis=0) / math.sqrt(R)
    assert np.all(np.abs(s.mean(axis=0) - fast.mean) < 5 * se + 1e-12)
    dev = s - s.mean(axis=0)
    var_se = np.sqrt(np.mean(dev**4, axis=0) - np.mean(dev**2, axis=0) ** 2) / math.sqrt(R)
    assert np.all(np.abs(s.var(axis=0) - fast.var) < 5 * var_se + 1e-12)


def _gauss_pdf(tau: ArrayLike, sigma: float) -> FloatArray:
    z = np.asarray(tau, dtype=float) / sigma
    dens = np.exp(-0.5 * z**2) / (sigma * math.sqrt(2.0 * math.pi))
    return np.where(np.abs(z) <= 8.5, dens, 0.0)


@dataclass(frozen=True)
class Normal(ji.JitterLaw):
    """A Gaussian written from scratch, declaring the Gaussian-kernel band rule."""

    sigma: float

    def pdf(self, tau: ArrayLike) -> FloatArray:
        return _gauss_pdf(tau, self.sigma)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        f = np.asarray(f, dtype=float)
        return np.exp(-2.0 * np.pi**2 * self.sigma**2 * f**2).astype(complex)

    @property
    def support(self) -> tuple[float, float]:
        return (-8.5 * self.sigma, 8.5 * self.sigma)

    @property
    def var(self) -> float:
        return self.sigma**2

    @property
    def band_rule(self) -> BandRule:
        return BandRule(self.sigma, 8.5, (3.0, 6.0), (1.7, 0.9, 0.6, 0.9, 1.7))


@dataclass(frozen=True)
class NormalFamily(ji.GaussianFamily):
    def _make(self, values: tuple[float, ...]) -> ji.JitterLaw:
        return Normal(values[0])


def test_a_law_that_declares_the_band_rule_gets_the_gaussian_rule():
    for sigma in (0.01, 0.07, 0.071, 0.3):
        for rate in (0.0, 3.0, 40.0):
            np.testing.assert_array_equal(
                relative_cuts(Normal(sigma), rate), relative_cuts(ji.Gaussian(sigma), rate)
            )
    resp = G.response(U)
    a = ji.sample_moments(resp, Normal(0.07), T, N)
    b = ji.sample_moments(resp, ji.Gaussian(0.07), T, N)
    np.testing.assert_array_equal(a.mean, b.mean)
    np.testing.assert_array_equal(a.var, b.var)


def test_a_family_of_band_laws_shares_its_nodes_across_the_band_like_the_gaussian(monkeypatch):
    """A search over sigma builds the node geometry once per band: counted, the same number
    of builds and bit-identical estimates for the new family and GaussianFamily."""
    from jitterid.moments import modal

    builds = []
    panels = modal.jitter_panels

    def counted(*args, **kwargs):
        builds.append(args[0])
        return panels(*args, **kwargs)

    monkeypatch.setattr(modal, "jitter_panels", counted)
    data = ji.simulate(G, U, ji.Gaussian(0.07), T, N, 0.02, rng=5)
    out = {}
    for fam in (ji.GaussianFamily(), NormalFamily()):
        modal.clear_plans()
        builds.clear()
        res = ji.fit(data, ji.RationalModel(1, 2), fam, method="bcls")
        out[type(fam).__name__] = (res.params, len(builds))
    (p_gauss, n_gauss), (p_new, n_new) = out["GaussianFamily"], out["NormalFamily"]
    assert n_new == n_gauss  # before: one build per new sigma (no band for a new type)
    np.testing.assert_array_equal(p_new, p_gauss)


@dataclass(frozen=True)
class Triangle(ji.JitterLaw):
    """The triangle on [-a, a]: a polynomial of degree 1 between its knots, declared."""

    a: float

    def pdf(self, tau: ArrayLike) -> FloatArray:
        self.calls.append(np.size(tau))
        t = np.abs(np.asarray(tau, dtype=float))
        return np.where(t <= self.a, (self.a - t) / self.a**2, 0.0)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        return (np.sinc(np.asarray(f, dtype=float) * self.a) ** 2).astype(complex)

    @property
    def support(self) -> tuple[float, float]:
        return (-self.a, self.a)

    def breakpoints(self) -> FloatArray:
        return np.array([-self.a, 0.0, self.a])

    @property
    def calls(self) -> list[int]:
        return self.__dict__.setdefault("_calls", [])


@dataclass(frozen=True)
class PolynomialTriangle(Triangle):
    @property
    def pdf_degree(self) -> int:
        return 1


def test_a_piecewise_polynomial_law_takes_the_likelihoods_exact_density_route():
    data = ji.simulate(G, U, ji.Uniform(A), T, N, 0.02, rng=5)
    plain, poly = Triangle(A), PolynomialTriangle(A)
    lp_plain = ji.log_density(G, U, plain, T, data.y, noise_std=0.02)
    lp_poly = ji.log_density(G, U, poly, T, data.y, noise_std=0.02)
    np.testing.assert_allclose(lp_poly, lp_plain, rtol=0, atol=1e-12)
    # the nodes' densities come from 2 values per piece, not from a call at every node
    assert max(poly.calls) < max(plain.calls) / 10


@dataclass(frozen=True)
class Trapezoid(ji.JitterLaw):
    """A flat top on [-b, b] with linear flanks to [-a, a] (b < a): its density vanishes at
    its ends, continuously; with b = a it is the uniform (a jump at each end)."""

    a: float
    b: float

    def pdf(self, tau: ArrayLike) -> FloatArray:
        t = np.abs(np.asarray(tau, dtype=float))
        h = 1.0 / (self.a + self.b)
        flank = h * (self.a - t) / max(self.a - self.b, 1e-300)
        return np.where(t <= self.b, h, np.where(t <= self.a, flank, 0.0))

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        x = np.asarray(f, dtype=float)
        return np.asarray(np.sinc(x * (self.a + self.b)) * np.sinc(x * (self.a - self.b)), complex)

    @property
    def support(self) -> tuple[float, float]:
        return (-self.a, self.a)


@pytest.mark.parametrize(
    ("law", "hard"),
    [
        (ji.Uniform(0.3), True),
        (ji.SumOfUniforms(0, 0.3), True),
        (Trapezoid(1.0, 1.0), True),  # the uniform, written from scratch
        (Trapezoid(1.0, 0.5), False),  # a density falling to 0 at its ends
        (ji.SumOfUniforms(1, 0.3), False),  # the triangle
        (ji.Gaussian(0.3), False),  # a finite support where its mass ends (8.5 sigma)
        (RaisedCosine(0.3), False),
        (ji.NoJitter(), False),
    ],
)
def test_hard_edges_is_read_off_the_density(law: ji.JitterLaw, hard: bool) -> None:
    """JitterLaw.hard_edges, from pdf and support alone: whether the density jumps at the
    support's ends (the likelihood's scale probes and the meter's sharp-edge finding ask
    for it)."""
    assert law.hard_edges is hard
