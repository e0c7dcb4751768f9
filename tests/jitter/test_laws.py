"""Tests of jitterid.jitter.laws against independent referees.

Referees: Monte Carlo averages over the law's own sampler (within a few standard errors),
scipy.integrate.quad of the density, the closed-form Irwin-Hall density, scipy.stats, and the
definitions written out again here. No expected value is copied from the code under test.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy import integrate, stats
from scipy.interpolate import BSpline

from jitterid.jitter.laws import (
    CustomJitter,
    Gaussian,
    GaussianFamily,
    JitterFamily,
    JitterLaw,
    NoJitter,
    SumOfUniforms,
    SumOfUniformsFamily,
    Uniform,
    UniformFamily,
)

N_MC = 100_000
SEED = 20240611
F_GRID = np.array([0.0, 0.3, 0.9, 1.7, 3.1])  # Hz, for laws of width ~1 time unit


def _beta_pdf(t: np.ndarray) -> np.ndarray:
    """Unnormalised Beta(2, 4) density on [-0.2, 0.8] (skewed, non-zero mean)."""
    u = t + 0.2
    return 7.0 * u * (1.0 - u) ** 3


def _triangle(t: np.ndarray) -> np.ndarray:
    """Unnormalised triangle on [-1, 1] (mass 3, not 1, on purpose)."""
    return 3.0 * (1.0 - np.abs(t))


LAWS: dict[str, Callable[[], JitterLaw]] = {
    "uniform": lambda: Uniform(0.5),
    "gaussian": lambda: Gaussian(0.2),
    "sou_n0": lambda: SumOfUniforms(0, 0.5),
    "sou_n1": lambda: SumOfUniforms(1, 0.5),
    "sou_n2": lambda: SumOfUniforms(2, 0.5),
    "sou_n0.5": lambda: SumOfUniforms(0.5, 0.5),
    "sou_n1.3": lambda: SumOfUniforms(1.3, 0.5),
    "sou_n2.7": lambda: SumOfUniforms(2.7, 0.5),
    "sou_n7": lambda: SumOfUniforms(7, 0.5),
    "custom_triangle": lambda: CustomJitter(_triangle, (-1.0, 1.0), breakpoints=[0.0]),
    "custom_beta": lambda: CustomJitter(_beta_pdf, (-0.2, 0.8)),
}
law_param = pytest.mark.parametrize("make", list(LAWS.values()), ids=list(LAWS))


def _panels(law: JitterLaw) -> list[tuple[float, float]]:
    bp = law.breakpoints()
    return list(itertools.pairwise(bp))


def _quad(law: JitterLaw, g: Callable[[float], float]) -> float:
    """Integral of g(t) p(t) over the support, by adaptive quadrature panel by panel."""
    total = 0.0
    for lo, hi in _panels(law):
        val, _ = integrate.quad(
            lambda t: g(t) * float(law.pdf(t)), lo, hi, epsabs=1e-13, epsrel=1e-12, limit=200
        )
        total += val
    return total


def _irwin_hall_pdf(x: np.ndarray, m: int) -> np.ndarray:
    """Closed-form density of the sum of m i.i.d. U(0, 1)."""
    x = np.asarray(x, dtype=float)
    out = np.zeros_like(x)
    for k in range(m + 1):
        out += (-1) ** k * math.comb(m, k) * np.where(x >= k, (x - k) ** (m - 1), 0.0)
    out /= math.factorial(m - 1)
    return np.where((x >= 0) & (x <= m), out, 0.0)


def _irwin_hall_cdf(x: np.ndarray, m: int) -> np.ndarray:
    x = np.clip(np.asarray(x, dtype=float), 0.0, m)
    out = np.zeros_like(x)
    for k in range(m + 1):
        out += (-1) ** k * math.comb(m, k) * np.where(x > k, x - k, 0.0) ** m
    return out / math.factorial(m)


def _naive_widths(n: float, a: float) -> tuple[int, float, float]:
    """The non-integer-n definition, transcribed directly from the specification."""
    nu = n + 1.0
    k = math.ceil(nu) - 1
    b = a * (k + math.sqrt(k * ((k + 1) / nu - 1))) / (k * (k + 1))
    return k, b, a - k * b


# ------------------------------------------------------------------------------------------
# properties common to every law
# ------------------------------------------------------------------------------------------


@law_param
def test_cf_at_zero_is_one_and_bounded(make: Callable[[], JitterLaw]) -> None:
    law = make()
    assert law.cf(0.0) == pytest.approx(1.0, abs=1e-13)
    f = np.linspace(-40.0, 40.0, 4001)
    phi = law.cf(f)
    assert phi.shape == f.shape
    assert np.iscomplexobj(phi)
    assert np.all(np.abs(phi) <= 1.0 + 1e-12)
    # phi(-f) = conj(phi(f)) for any real random variable
    np.testing.assert_allclose(law.cf(-f), np.conj(phi), atol=1e-14)


@law_param
def test_cf_matches_monte_carlo(make: Callable[[], JitterLaw]) -> None:
    law = make()
    tau = law.sample(N_MC, np.random.default_rng(SEED))
    assert tau.shape == (N_MC,)
    for f in F_GRID[1:]:
        z = np.exp(-2j * np.pi * f * tau)
        se_re = z.real.std() / math.sqrt(N_MC) + 1e-12
        se_im = z.imag.std() / math.sqrt(N_MC) + 1e-12
        phi = complex(law.cf(f))
        assert abs(z.real.mean() - phi.real) < 5 * se_re, f
        assert abs(z.imag.mean() - phi.imag) < 5 * se_im, f


@law_param
def test_sample_moments_match(make: Callable[[], JitterLaw]) -> None:
    law = make()
    tau = law.sample(N_MC, SEED)  # an int seed is accepted
    lo, hi = law.support
    assert np.all((tau >= lo) & (tau <= hi))
    se_mean = tau.std() / math.sqrt(N_MC)
    assert abs(tau.mean() - law.mean) < 5 * se_mean
    d = tau - tau.mean()
    se_var = math.sqrt(np.mean(d**4) - np.mean(d**2) ** 2) / math.sqrt(N_MC)
    assert abs(d.var() - law.var) < 5 * se_var
    assert law.std == pytest.approx(math.sqrt(law.var), rel=1e-14)


@law_param
def test_pdf_integrates_to_one_with_matching_moments(make: Callable[[], JitterLaw]) -> None:
    law = make()
    assert _quad(law, lambda t: 1.0) == pytest.approx(1.0, abs=1e-10)
    mean = _quad(law, lambda t: t)
    assert mean == pytest.approx(law.mean, abs=1e-10)
    assert _quad(law, lambda t: (t - mean) ** 2) == pytest.approx(law.var, rel=1e-9, abs=1e-13)


@law_param
def test_pdf_nonnegative_zero_outside_and_shaped(make: Callable[[], JitterLaw]) -> None:
    law = make()
    lo, hi = law.support
    t = np.linspace(lo - 0.5, hi + 0.5, 3000).reshape(3, 1000, 1)
    p = law.pdf(t)
    assert p.shape == t.shape
    assert np.all(p >= 0.0)
    assert np.all(p[(t < lo) | (t > hi)] == 0.0)
    assert np.ndim(law.pdf(0.1)) == 0


@law_param
def test_pdf_and_cf_are_a_fourier_pair(make: Callable[[], JitterLaw]) -> None:
    law = make()
    for f in (0.37, 1.1, 2.9):
        w = 2 * np.pi * f
        re = _quad(law, lambda t, w=w: math.cos(w * t))
        im = -_quad(law, lambda t, w=w: math.sin(w * t))
        assert abs(complex(law.cf(f)) - complex(re, im)) < 1e-8, f


@law_param
def test_breakpoints_cut_the_pdf_into_polynomial_or_smooth_pieces(
    make: Callable[[], JitterLaw],
) -> None:
    law = make()
    bp = law.breakpoints()
    lo, hi = law.support
    assert bp[0] == lo
    assert bp[-1] == hi
    assert np.all(np.diff(bp) > 0)
    if not isinstance(law, SumOfUniforms):
        return
    m = law.components[0]
    # On each panel the density is a polynomial of degree <= m: a degree-m least-squares fit
    # must leave no residual. A kink inside a panel (a missing breakpoint) would.
    for a, b in _panels(law):
        t = np.linspace(a, b, 60)[1:-1]
        p = law.pdf(t)
        fit = np.polynomial.Polynomial.fit(t, p, deg=m)
        assert np.max(np.abs(fit(t) - p)) < 1e-8 * np.max(law.pdf(np.linspace(lo, hi, 101)))


@law_param
def test_quadrature_and_expect(make: Callable[[], JitterLaw]) -> None:
    law = make()
    _, w = law.quadrature()
    assert np.all(w >= 0)
    assert w.sum() == pytest.approx(1.0, abs=1e-12)
    assert law.expect(lambda t: t) == pytest.approx(law.mean, abs=1e-12)
    assert law.expect(lambda t: (t - law.mean) ** 2) == pytest.approx(law.var, rel=1e-11)
    # a vector-valued g: leading axes are kept
    f = np.array([0.4, 1.3])
    got = law.expect(lambda t: np.exp(-2j * np.pi * f[:, None] * t[None, :]))
    np.testing.assert_allclose(got, law.cf(f), atol=1e-12)


@law_param
def test_laws_are_immutable_and_printable(make: Callable[[], JitterLaw]) -> None:
    law = make()
    for name in law.params:
        with pytest.raises(AttributeError):
            setattr(law, name, 1.0)
    text = str(law)
    assert type(law).__name__ in text
    assert "std" in text
    assert type(law).__name__ in repr(law)
    hash(law)


# ------------------------------------------------------------------------------------------
# individual laws
# ------------------------------------------------------------------------------------------


def test_no_jitter() -> None:
    law = NoJitter()
    f = np.linspace(-5, 5, 11)
    np.testing.assert_array_equal(law.cf(f), np.ones_like(f))
    assert law.var == 0.0
    assert law.std == 0.0
    assert law.mean == 0.0
    assert law.support == (0.0, 0.0)
    np.testing.assert_array_equal(law.breakpoints(), [0.0])
    np.testing.assert_array_equal(law.sample((2, 3), 1), np.zeros((2, 3)))
    assert law.expect(lambda t: np.cos(t) + 2.0) == pytest.approx(3.0)
    with pytest.raises(NotImplementedError, match="point mass"):
        law.pdf(0.0)
    assert law == NoJitter()


def test_uniform_and_gaussian_closed_forms() -> None:
    f = np.linspace(-3, 3, 61)
    # (15a): U(-1, 1) has phi(f) = sin(2 pi f)/(2 pi f)
    expected = np.where(f == 0, 1.0, np.sin(2 * np.pi * f) / np.where(f == 0, 1, 2 * np.pi * f))
    np.testing.assert_allclose(Uniform(1.0).cf(f).real, expected, atol=1e-15)
    # (15b): N(0, 1/3) has phi(f) = exp(-2 pi^2 f^2 / 3)
    np.testing.assert_allclose(
        Gaussian(math.sqrt(1 / 3)).cf(f).real, np.exp(-2 * np.pi**2 * f**2 / 3), rtol=1e-14
    )
    g = Gaussian(0.1)
    lo, hi = g.support
    t = np.linspace(-1, 1, 41)
    ref = np.where((t >= lo) & (t <= hi), stats.norm(0, 0.1).pdf(t), 0.0)  # documented cut
    np.testing.assert_allclose(g.pdf(t), ref, rtol=1e-14, atol=0)
    assert hi == pytest.approx(-lo)
    assert 2 * stats.norm.sf(hi / 0.1) < 1e-16  # documented effective support


@pytest.mark.parametrize("n", [0, 1, 2, 3, 5, 7, 20, 50])
def test_sum_of_uniforms_integer_n_is_eq26(n: int) -> None:
    a = 0.5
    law = SumOfUniforms(n, a)
    f = np.linspace(-30, 30, 1201)
    np.testing.assert_allclose(law.cf(f).real, np.sinc(2 * f * a / (n + 1)) ** (n + 1), atol=1e-14)
    np.testing.assert_array_equal(law.cf(f).imag, 0.0)
    m = n + 1
    if m <= 8:  # closed-form Irwin-Hall referee (alternating sum is accurate for small m)
        b = a / m
        t = np.linspace(-0.6, 0.6, 241)
        # symmetric law: evaluate the alternating sum in the left tail, where it is accurate
        ref = _irwin_hall_pdf((-np.abs(t) + m * b) / (2 * b), m) / (2 * b)
        np.testing.assert_allclose(law.pdf(t), ref, rtol=1e-10, atol=1e-13)


def test_sum_of_uniforms_n1_is_the_triangle() -> None:
    a = 0.7
    t = np.linspace(-1, 1, 401)
    np.testing.assert_allclose(
        SumOfUniforms(1, a).pdf(t), np.maximum(0, 1 - np.abs(t) / a) / a, atol=1e-14
    )
    np.testing.assert_allclose(SumOfUniforms(0, a).pdf(t), Uniform(a).pdf(t), atol=1e-15)


@pytest.mark.parametrize("n", [0.5, 1.3, 2.7, 3.999, 4.001, 12.25, 1e-5, 3 + 1e-5])
def test_sum_of_uniforms_noninteger_definition(n: float) -> None:
    a = 0.5
    law = SumOfUniforms(n, a)
    k, b, c = _naive_widths(n, a)
    m, b_law, c_law = law.components
    assert m == k
    assert b_law == pytest.approx(b, rel=1e-9)
    assert c_law == pytest.approx(c, rel=1e-6, abs=1e-15)
    # support and variance exactly those of (26)
    assert k * b + c == pytest.approx(a, rel=1e-14)
    assert (k * b**2 + c**2) / 3 == pytest.approx(a**2 / (3 * (n + 1)), rel=1e-12)
    assert 0 < c <= b
    assert law.std == a / math.sqrt(3 * (n + 1))
    # cf: product of the sincs of the components
    f = np.linspace(-20, 20, 801)
    np.testing.assert_allclose(
        law.cf(f).real, np.sinc(2 * f * b) ** k * np.sinc(2 * f * c), atol=1e-12
    )
    # pdf: Irwin-Hall CDF difference, written independently
    if k <= 8:
        t = np.linspace(-0.55, 0.55, 221)

        def cdf_k(x: np.ndarray) -> np.ndarray:
            return _irwin_hall_cdf((x + k * b) / (2 * b), k)

        x = -np.abs(t)  # the law is symmetric; the left tail is where the referee is accurate
        ref = (cdf_k(x + c) - cdf_k(x - c)) / (2 * c)
        np.testing.assert_allclose(law.pdf(t), ref, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("n", [0.5, 1.3, 2.7, 6.6])
def test_sum_of_uniforms_noninteger_std_by_samples(n: float) -> None:
    a = 0.5
    tau = SumOfUniforms(n, a).sample(N_MC, np.random.default_rng(SEED + 1))
    d = tau - tau.mean()
    se_var = math.sqrt(np.mean(d**4) - np.mean(d**2) ** 2) / math.sqrt(N_MC)
    assert abs(d.var() - a**2 / (3 * (n + 1))) < 5 * se_var
    assert np.all(np.abs(tau) <= a)


def test_sum_of_uniforms_continuous_in_n() -> None:
    a = 0.5
    t = np.linspace(-0.55, 0.55, 551)
    f = np.linspace(-15, 15, 301)
    ref = SumOfUniforms(2, a)
    for n in (2 - 1e-9, 2 + 1e-9, 2 + 1e-13):
        law = SumOfUniforms(n, a)
        assert np.max(np.abs(law.pdf(t) - ref.pdf(t))) < 1e-6, n
        assert np.max(np.abs(law.cf(f) - ref.cf(f))) < 1e-6, n
    # integer n given as a float (and within 1e-12 of it) is three equal uniforms
    m, b, c = SumOfUniforms(2.0, a).components
    assert (m, c) == (3, 0.0)
    assert b == pytest.approx(a / 3, rel=1e-15)
    # at the kinked triangle n = 1 the law is still continuous: cf linearly, peak like sqrt
    tri = SumOfUniforms(1, a)
    for n in (1 - 1e-9, 1 + 1e-9):
        law = SumOfUniforms(n, a)
        assert np.max(np.abs(law.cf(f) - tri.cf(f))) < 1e-7, n
        assert np.max(np.abs(law.pdf(t) - tri.pdf(t))) < 1e-4, n


def test_sum_of_uniforms_large_n_is_close_to_gaussian() -> None:
    a = 0.5
    law = SumOfUniforms(50, a)
    t = np.linspace(-0.2, 0.2, 81)
    ref = stats.norm(0, a / math.sqrt(3 * 51)).pdf(t)
    np.testing.assert_allclose(law.pdf(t), ref, rtol=0.01, atol=1e-3 * ref.max())


@settings(max_examples=40, deadline=None)
@example(n=1e-7, a=1.0)  # a very narrow extra uniform (found by hypothesis)
@given(
    n=st.floats(min_value=0.0, max_value=12.0, allow_nan=False),
    a=st.floats(min_value=1e-3, max_value=1e3, allow_nan=False),
)
def test_sum_of_uniforms_property(n: float, a: float) -> None:
    law = SumOfUniforms(n, a)
    f = np.linspace(-10 / a, 10 / a, 201)
    assert np.all(np.abs(law.cf(f)) <= 1 + 1e-12)
    bp = law.breakpoints()
    assert bp[0] == -a
    assert bp[-1] == a
    assert np.all(np.diff(bp) > 0)
    nodes, w = law.quadrature()
    assert w.sum() == pytest.approx(1.0, abs=1e-11)
    assert w @ nodes**2 == pytest.approx(a**2 / (3 * (n + 1)), rel=1e-10)
    assert np.all(law.pdf(np.linspace(-1.1 * a, 1.1 * a, 201)) >= 0)


# ------------------------------------------------------------------------------------------
# CustomJitter
# ------------------------------------------------------------------------------------------


def test_custom_triangle_is_normalised_and_matches_closed_form() -> None:
    law = CustomJitter(_triangle, (-1.0, 1.0), breakpoints=[0.0])
    t = np.linspace(-1.2, 1.2, 121)
    np.testing.assert_allclose(law.pdf(t), np.maximum(0, 1 - np.abs(t)), atol=1e-13)
    f = np.linspace(-8, 8, 161)
    # triangle on [-1, 1] = sum of two U(-1/2, 1/2): phi = sinc(f)^2
    np.testing.assert_allclose(law.cf(f), np.sinc(f) ** 2, atol=1e-12)
    assert law.var == pytest.approx(1 / 6, rel=1e-12)
    assert law.mean == pytest.approx(0.0, abs=1e-14)
    assert law == law  # noqa: PLR0124  (identity equality)
    assert law != CustomJitter(_triangle, (-1.0, 1.0), breakpoints=[0.0])  # identity


def test_custom_skewed_matches_scipy_beta() -> None:
    law = CustomJitter(_beta_pdf, (-0.2, 0.8))
    ref = stats.beta(2, 4, loc=-0.2, scale=1.0)
    assert law.mean == pytest.approx(ref.mean(), rel=1e-12)
    assert law.var == pytest.approx(ref.var(), rel=1e-12)
    t = np.linspace(-0.3, 0.9, 121)
    np.testing.assert_allclose(law.pdf(t), ref.pdf(t), atol=1e-12)
    tau = law.sample(N_MC, np.random.default_rng(SEED + 2))
    assert stats.kstest(tau, ref.cdf).pvalue > 1e-3


def test_custom_with_a_gap_never_samples_in_the_gap() -> None:
    def two_blocks(t: np.ndarray) -> np.ndarray:
        return (np.abs(t) >= 0.5).astype(float)

    law = CustomJitter(two_blocks, (-1.0, 1.0), breakpoints=[-0.5, 0.5])
    tau = law.sample(20_000, 3)
    assert not np.any(np.abs(tau) < 0.5 - 1e-12)
    assert law.var == pytest.approx(7 / 12, rel=1e-12)  # E[t^2] = (1 - 1/8) * 2 / 3 / 1
    assert np.mean(tau < 0) == pytest.approx(0.5, abs=5 * 0.5 / math.sqrt(20_000))


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: Uniform(0.0), "a"),
        (lambda: Uniform(-1.0), "a"),
        (lambda: Uniform(float("nan")), "a"),
        (lambda: Uniform(float("inf")), "a"),
        (lambda: Gaussian(0.0), "sigma"),
        (lambda: Gaussian(-0.1), "sigma"),
        (lambda: Gaussian(float("nan")), "sigma"),
        (lambda: SumOfUniforms(-0.1, 0.5), "n"),
        (lambda: SumOfUniforms(50.5, 0.5), "n"),
        (lambda: SumOfUniforms(float("nan"), 0.5), "n"),
        (lambda: SumOfUniforms(1.0, 0.0), "a"),
        (lambda: SumOfUniforms(1.0, -2.0), "a"),
        (lambda: CustomJitter(lambda t: t, (-1.0, 1.0)), "pdf"),  # negative on [-1, 0)
        (lambda: CustomJitter(lambda t: 0.0 * t, (-1.0, 1.0)), "pdf"),  # zero mass
        (lambda: CustomJitter(lambda t: np.where(t > 0.5, np.nan, 1.0), (0.0, 1.0)), "pdf"),
        (lambda: CustomJitter(lambda t: np.log(t + 1), (-1.0, 1.0)), "pdf"),  # negative
        (lambda: CustomJitter(lambda t: np.full_like(t, np.inf), (-1.0, 1.0)), "pdf"),
        (lambda: CustomJitter(lambda t: math.exp(t), (-1.0, 1.0)), "pdf"),  # not vectorised
        (lambda: CustomJitter(lambda t: np.ones(3), (-1.0, 1.0)), "pdf"),  # wrong shape
        (lambda: CustomJitter(_triangle, (1.0, 1.0)), "support"),
        (lambda: CustomJitter(_triangle, (1.0, -1.0)), "support"),
        (lambda: CustomJitter(_triangle, (-np.inf, 1.0)), "support"),
        (lambda: CustomJitter(_triangle, (-1.0, 0.0, 1.0)), "support"),
        (lambda: CustomJitter(_triangle, (-1.0, 1.0), breakpoints=[2.0]), "breakpoints"),
    ],
)
def test_bad_arguments_are_named(make: Callable[[], object], name: str) -> None:
    with pytest.raises((ValueError, TypeError), match=rf"\b{name}\b"):
        make()


def test_custom_pdf_must_be_callable() -> None:
    with pytest.raises(TypeError, match="pdf"):
        CustomJitter(3.0, (-1.0, 1.0))  # type: ignore[arg-type]


@pytest.mark.parametrize("make", [NoJitter, *LAWS.values()], ids=["none", *LAWS])
def test_rng_must_be_explicit(make: Callable[[], JitterLaw]) -> None:
    law = make()
    with pytest.raises(TypeError, match="rng"):
        law.sample(10, None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="rng"):
        law.sample(10, np.random.RandomState(0))  # type: ignore[arg-type]
    with pytest.raises((TypeError, ValueError), match="size"):
        law.sample(-1, 0)
    with pytest.raises((TypeError, ValueError), match=r"\bf\b"):
        law.cf([0.0, np.nan])


def test_bad_evaluation_points() -> None:
    with pytest.raises(ValueError, match="tau"):
        Uniform(1.0).pdf([0.0, np.inf])
    with pytest.raises(TypeError, match=r"\bg\b"):
        Uniform(1.0).expect(3.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="nodes_per_panel"):
        Uniform(1.0).quadrature(0)


# ------------------------------------------------------------------------------------------
# families
# ------------------------------------------------------------------------------------------

FAMILIES: dict[str, Callable[[], JitterFamily]] = {
    "uniform": UniformFamily,
    "uniform_capped": lambda: UniformFamily(a_max=0.05),
    "gaussian": GaussianFamily,
    "gaussian_capped": lambda: GaussianFamily(sigma_max=0.3),
    "sou": SumOfUniformsFamily,
    "sou_capped": lambda: SumOfUniformsFamily(n_max=3.0, a_max=0.5),
}
fam_param = pytest.mark.parametrize("make", list(FAMILIES.values()), ids=list(FAMILIES))


@fam_param
@pytest.mark.parametrize("T", [1.0, 2e-3])
def test_family_default_starts(make: Callable[[], JitterFamily], T: float) -> None:
    fam = make()
    starts = fam.default_starts(T)
    assert 3 <= len(starts) <= 6
    assert len(set(starts)) == len(starts)
    assert len(fam.bounds) == len(fam.param_names)
    for start in starts:
        assert len(start) == len(fam.param_names)
        for v, (lo, hi) in zip(start, fam.bounds, strict=True):
            assert lo <= v <= hi
        law = fam.law(start)
        assert isinstance(law, JitterLaw)
        assert tuple(law.params[k] for k in fam.param_names) == pytest.approx(start)
        # starts are scaled to T: the jitter is at most of the order of the sampling interval
        assert 0 < law.std <= T


@fam_param
def test_family_bounds_and_errors(make: Callable[[], JitterFamily]) -> None:
    fam = make()
    k = len(fam.param_names)
    for name, (lo, hi) in zip(fam.param_names, fam.bounds, strict=True):
        assert lo < hi
        if name in ("a", "sigma"):
            assert lo > 0  # 0 itself is excluded
    with pytest.raises(ValueError, match="params"):
        fam.law([0.1] * (k + 1))
    with pytest.raises(ValueError, match="params"):
        fam.law([])
    for i, name in enumerate(fam.param_names):
        lo, hi = fam.bounds[i]
        good = [max(lo, min(0.1, hi))] * k
        for bad in (lo - 1.0, hi * 2 if np.isfinite(hi) else np.nan, np.nan):
            vals = list(good)
            vals[i] = bad
            with pytest.raises(ValueError, match=rf"\b{name}\b"):
                fam.law(vals)
    with pytest.raises(ValueError, match=r"\bT\b"):
        fam.default_starts(0.0)


def test_family_laws_are_the_right_laws() -> None:
    assert UniformFamily().law([0.3]) == Uniform(0.3)
    assert GaussianFamily().law((0.2,)) == Gaussian(0.2)
    assert SumOfUniformsFamily().law(np.array([2.0, 0.5])) == SumOfUniforms(2.0, 0.5)
    assert SumOfUniformsFamily().bounds[0] == (0.0, 20.0)
    assert UniformFamily(a_max=0.5).bounds[0][1] == 0.5
    assert GaussianFamily().bounds[0][1] == math.inf


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: UniformFamily(a_max=-1.0), "a_max"),
        (lambda: GaussianFamily(sigma_max=0.0), "sigma_max"),
        (lambda: SumOfUniformsFamily(n_max=60.0), "n_max"),
        (lambda: SumOfUniformsFamily(n_max=-1.0), "n_max"),
        (lambda: SumOfUniformsFamily(a_max=float("nan")), "a_max"),
    ],
)
def test_family_bad_construction(make: Callable[[], object], name: str) -> None:
    with pytest.raises((ValueError, TypeError), match=name):
        make()


@pytest.mark.parametrize("n", [0.0, 0.37, 1.0, 2.0, 2.6, 7.3, 19.999, 50.0])
def test_sum_of_uniforms_shared_splines_and_knots(n: float) -> None:
    """The piecewise polynomials shared per m are the B-spline and its antiderivative
    built for the law alone (to 3e-15, the referee being scipy's B-spline evaluation), and
    the knots kept per law are a fresh array at every call."""
    law = SumOfUniforms(n, 0.4)
    m = law.components[0]
    u = np.linspace(0.0, m, 4001)
    if m == 1:
        own_pdf, own_cdf = np.ones_like(u), u
    else:
        own = BSpline.basis_element(np.arange(m + 1.0), extrapolate=False)
        own_pdf, own_cdf = own(u), own.antiderivative()(u)
    assert np.max(np.abs(law._spline(u) - own_pdf)) <= 3e-15 * np.max(own_pdf)
    assert np.max(np.abs(law._spline_cdf(u) - own_cdf)) <= 3e-15
    k1 = law.breakpoints()
    k1[0] = 99.0  # a caller's change does not reach the law
    assert np.array_equal(law.breakpoints(), SumOfUniforms(n, 0.4)._breakpoints())
    tau = np.linspace(-0.45, 0.45, 301)
    assert np.array_equal(law.pdf(tau), SumOfUniforms(n, 0.4).pdf(tau))


def test_wide_window_density_in_one_evaluation() -> None:
    """The moving-average density of a non-integer n takes both CDF ends from one spline
    call: the values of two calls."""
    law = SumOfUniforms(2.6, 0.3)
    x = -np.abs(np.linspace(-0.31, 0.31, 257))
    c = law.components[2]
    two = (law._irwin_hall_cdf(x + c) - law._irwin_hall_cdf(x - c)) / (2.0 * c)
    assert np.array_equal(law._window_mean(x), two)
