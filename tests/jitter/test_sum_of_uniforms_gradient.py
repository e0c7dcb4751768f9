"""The closed-form density derivative d p / d (n, a) of the family (26) (issue 24).

Referee: the density as a truncated-power sum, independent of the B-spline evaluation the
law uses,

    p(t) = sum_{j, e} C(K, j) (-1)^(K - j) e (t + (2j - K) b + e c)_+^K / (K! (2b)^K 2c),

(e = +-1: the K uniforms U(-b, b) and one U(-c, c)), with b, c from n exactly as the class
defines them, in 90-digit decimal arithmetic; its derivative is the central difference at a
step of 1e-32 (truncation ~1e-64 times p''', rounding ~1e-90 / 1e-32: both far below double
precision, even 1e-12 below an integer, where the derivatives in n grow like powers of the
distance's inverse square root). The points tau avoid the knots themselves (there dp/dn
jumps), by 1e-7 a and more: a knot moves by at most ~1e-32 / sqrt(distance) over the step.
"""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest

import jitterid as ji

A = 0.37  # the support's half-width (s)
_DIGITS = 90
_STEP = Decimal("1e-32")


def _pdf(t: Decimal, n: Decimal, a: Decimal) -> Decimal:
    """The density of (26) at a non-integer n by its truncated-power form (exact arithmetic
    up to the context's digits)."""
    nu = n + 1
    k = math.ceil(nu) - 1
    s = (k * (k + 1 - nu) / nu).sqrt()
    b = a * (k + s) / (k * (k + 1))
    c = a - k * b
    total = Decimal(0)
    for j in range(k + 1):
        shift = (2 * j - k) * b
        coef = math.comb(k, j) * (-1) ** (k - j)
        for end, sign in ((c, 1), (-c, -1)):
            z = t + shift + end
            if z > 0:
                total += coef * sign * z**k
    return total / (math.factorial(k) * (2 * b) ** k * 2 * c)


def _referee(tau: np.ndarray, n: float, a: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, dp/dn, dp/da) at every tau, in 90-digit arithmetic."""
    out = []
    with localcontext() as ctx:
        ctx.prec = _DIGITS
        nd, ad, h = Decimal(n), Decimal(a), _STEP
        for t in tau:
            td = Decimal(float(t))
            p = _pdf(td, nd, ad)
            dn = (_pdf(td, nd + h, ad) - _pdf(td, nd - h, ad)) / (2 * h)
            ha = h * ad
            da = (_pdf(td, nd, ad + ha) - _pdf(td, nd, ad - ha)) / (2 * ha)
            out.append((float(p), float(dn), float(da)))
    arr = np.array(out)
    return arr[:, 0], arr[:, 1], arr[:, 2]


def _points(law: ji.SumOfUniforms) -> np.ndarray:
    """A grid over the support plus points 1e-7 a and 1e-4 a on either side of every knot
    (their pieces' ends, where a wrong piece shows), none on a knot itself."""
    a = law.a
    knots = np.unique(np.abs(law.breakpoints()))
    grid = np.linspace(-0.999 * a, 0.999 * a, 23)
    near = np.concatenate([knots + d for d in (-1e-4 * a, -1e-7 * a, 1e-7 * a, 1e-4 * a)])
    near = near[(near > 0) & (near < a)]
    pts = np.concatenate([grid, near, -near[::2]])
    gap = np.min(np.abs(np.abs(pts)[:, None] - knots[None, :]), axis=1)
    return pts[gap > 5e-8 * a]


# (n, tolerance on dp/dn relative to its largest value over tau): every regime of each piece
# K = ceil(n + 1) - 1, i.e. n in (0, 1), (1, 2), (2, 3), (7, 8): just above an integer (a
# narrow extra uniform: the window form), mid-piece (the boundary form, at its switch
# c = 0.01 K b, where its 1/c^2 terms cost most, and far from it), and 2e-9 below an integer
# (twice the None threshold, where the cancellation costs ~K 1e-16 / sqrt(distance)).
CASES = [
    (1e-9, 1e-12),
    (0.01, 1e-12),
    (0.3, 1e-12),
    (0.5, 1e-12),
    (0.97, 1e-12),
    (1 - 2e-9, 1e-12),  # K = 1: the trapezoid, exact (dp/dn ~ 1/sqrt(distance) at the centre)
    (1 + 1e-10, 1e-12),
    (1.01, 1e-12),
    (1.0397, 1e-12),  # the window form at its switch (n = 1.03979)
    (1.0399, 3e-12),  # the boundary form at its switch: its worst case
    (1.5, 1e-12),
    (1.99, 1e-12),
    (2 - 2e-9, 1e-10),
    (2 + 1e-7, 1e-12),
    (2.0593, 1e-12),
    (2.0595, 3e-12),
    (2.5, 1e-12),
    (2.999, 1e-12),
    (3 - 2e-9, 1e-10),
    (7 + 1e-6, 1e-12),
    (7.154, 1e-12),
    (7.155, 3e-12),
    (7.3, 1e-11),
    (7.5, 1e-11),
    (8 - 1e-5, 1e-10),
    (8 - 2e-9, 1e-9),
]


@pytest.mark.parametrize(("n", "tol"), CASES, ids=[repr(c[0]) for c in CASES])
def test_pdf_gradient_matches_high_precision_differences(n, tol):
    law = ji.SumOfUniforms(n, A)
    tau = _points(law)
    p, dn, da = _referee(tau, n, A)
    # the referee is the law (its own density, to the law's accuracy)
    np.testing.assert_allclose(law.pdf(tau), p, rtol=0, atol=1e-13 * np.max(p))
    # a few points: the closed form at each; many (the quadratures' nodes): the window form
    # from its Chebyshev pieces (SumOfUniforms._gradient_pieces)
    many = np.r_[tau, np.linspace(-A, A, 4 * 51**2 + 1)]
    for g in (law.pdf_gradient(tau), law.pdf_gradient(many)[:, : tau.size]):
        assert g is not None
        assert g.shape == (2, *tau.shape)
        assert np.max(np.abs(g[0] - dn)) <= tol * np.max(np.abs(dn))
        assert np.max(np.abs(g[1] - da)) <= 1e-12 * np.max(np.abs(da))


@pytest.mark.parametrize(
    ("n", "window"),
    [
        (1.0397, True),
        (1.0399, False),
        (2.0593, True),
        (2.0595, False),
        (7.154, True),
        (7.155, False),
    ],
)
def test_the_cases_above_take_the_route_they_name(n, window):
    """The switch between the window and the boundary form is where the cases say
    (c = 0.01 K b: n ~ 0.02 K above an integer: 1.03979, 2.05938, 7.15428)."""
    m, b, c = ji.SumOfUniforms(n, A).components
    assert (c < 0.01 * m * b) == window


def test_the_family_gives_the_laws_gradient_in_any_shape_and_zero_outside():
    fam = ji.SumOfUniformsFamily()
    law = ji.SumOfUniforms(2.4, A)
    half = np.linspace(0.0, 1.2 * A, 12)
    tau = np.r_[-half[::-1], half].reshape(4, 6)
    g = fam.pdf_gradient([2.4, A], tau)
    assert g is not None
    assert g.shape == (2, 4, 6)
    np.testing.assert_array_equal(g, law.pdf_gradient(tau))
    np.testing.assert_array_equal(g[:, np.abs(tau) > A], 0.0)
    flat = g.reshape(2, -1)
    np.testing.assert_array_equal(flat[:, ::-1], flat)  # even in tau (tau symmetric), as p
    assert fam.pdf_gradient([2.4, A], np.zeros(0)).shape == (2, 0)  # the callers' probe


@pytest.mark.parametrize(
    "n", [0.0, 1.0, 2.0, 7.0, 50.0, 2 + 5e-13, 2 - 5e-13, 1 - 5e-10, 3 - 9.9e-10, 50 - 1e-10]
)
def test_no_closed_form_at_an_integer_and_within_1e_9_below_one(n):
    """At an integer n (within 1e-12, where the law is the integer's) the derivative is
    one-sided; less than 1e-9 below one its cancellation costs too much: None, and the
    callers difference instead."""
    assert ji.SumOfUniforms(n, A).pdf_gradient([0.0, 0.1]) is None
    assert ji.SumOfUniformsFamily(n_max=50).pdf_gradient([n, A], np.zeros(0)) is None


@pytest.mark.parametrize("n", [2 + 2e-12, 1e-11, 2 - 1.1e-9, 3 - 2e-9, 49.5])
def test_a_closed_form_just_outside_those_bands(n):
    assert ji.SumOfUniforms(n, A).pdf_gradient([0.0, 0.1]) is not None


def test_widths_are_accurate_near_a_pieces_ends():
    """b and c from the distances to the piece's ends (exact in floating point): the
    variance a^2 / (3 nu) holds to rounding however near an integer n is, and c grows like
    the distance above it."""
    for n in (2 - 1e-11, 2 - 1e-9, 1 + 1e-11, 1 + 1e-9, 7.5):
        m, b, c = ji.SumOfUniforms(n, A).components
        nu = n + 1
        var = (m * b**2 + c**2) / 3
        assert var == pytest.approx(A**2 / (3 * nu), rel=4e-16)
        with localcontext() as ctx:
            ctx.prec = 50
            nd = Decimal(n)
            k = math.ceil(nd + 1) - 1
            s = (k * (k - nd) / (nd + 1)).sqrt()
            bd = Decimal(A) * (k + s) / (k * (k + 1))
        assert b == pytest.approx(float(bd), rel=4e-16)


@pytest.mark.parametrize("n", [0, 1, 2, 5])
def test_scale_equivalent_gives_the_derivative_from_above_at_an_integer(n):
    """On an integer n (a kink, or the bound 0) the family gives the derivative from above
    as a multiple of the scale's: dp/dn (+) = -a / (2 (n + 1)) dp/da. Referee: the
    truncated-power form at n + d and n + 2 d (d = 1e-30: a forward difference from above,
    truncation ~1e-30, the form's 1/2c cancellation costing 30 of its 90 digits), against
    the central difference in a at n + d, at points off the knots. Can fail: a factor off
    by its sign, its 1/2 or its nu is off by 100 % or more."""
    fam = ji.SumOfUniformsFamily()
    r = fam.scale_equivalent((float(n), A), 0)
    assert r is not None
    law = ji.SumOfUniforms(n + 1e-3, A)  # its knots: those of n, split by +-c
    tau = _points(law)
    got, ref = [], []
    with localcontext() as ctx:
        ctx.prec = _DIGITS
        d = Decimal("1e-30")
        nd, ad = Decimal(n) + d, Decimal(A)
        for t in tau:
            td = Decimal(float(t))
            dn = (_pdf(td, nd + d, ad) - _pdf(td, nd, ad)) / d
            ha = _STEP * ad
            da = (_pdf(td, nd, ad + ha) - _pdf(td, nd, ad - ha)) / (2 * ha)
            got.append(float(da) * r)
            ref.append(float(dn))
    got_a, ref_a = np.array(got), np.array(ref)
    assert np.max(np.abs(ref_a)) > 0
    np.testing.assert_allclose(got_a, ref_a, rtol=0, atol=1e-12 * np.max(np.abs(ref_a)))


@pytest.mark.parametrize("n", [1, 2, 3, 8, 20, 49])
def test_below_kink_gives_the_derivative_from_below_at_an_integer(n):
    """On an integer n >= 1 the family gives the derivative from below as a combination of
    laws: dphi/dn (-) = -(phi_n - phi_L) / 2, L the sum of n - 1 of the n + 1 uniforms.
    Referee: backward differences of the characteristic function (26)'s extension at steps
    h, h/4, h/16 (h = 1e-4), whose error runs in powers of sqrt(h) (the widths move like the
    square root of the distance), Richardson-extrapolated in sqrt(h) twice (measured 1e-8 -
    3e-6 of the largest value; the plain difference at h is off by 2e-4 - 7e-3). Can fail: a
    coefficient off by its sign or its 1/2, or L one uniform off, is off by 30 % or more."""
    fam = ji.SumOfUniformsFamily(n_max=50)
    got = fam.below_kink((float(n), A), 0)
    assert got is not None
    c0, terms = got
    assert c0 + sum(c for c, _ in terms) == 0  # a measure of mass 0
    f = np.linspace(0.1, 6.0 / A, 41)
    base = ji.SumOfUniforms(n, A).cf(f).real
    pred = c0 * base + sum(c * law.cf(f).real for c, law in terms)
    h = 1e-4
    d = [(base - ji.SumOfUniforms(n - h / 4**k, A).cf(f).real) / (h / 4**k) for k in range(3)]
    r1 = [2 * d[k + 1] - d[k] for k in range(2)]
    rich = (4 * r1[1] - r1[0]) / 3
    np.testing.assert_allclose(pred, rich, rtol=0, atol=1e-5 * np.max(np.abs(pred)))


def test_below_kink_only_on_an_integer_n_from_one():
    """No combination off the integers, at the bound 0 (nothing below), for the scale, or
    from the families without kinks; at n = 1 the other law is the point mass (no
    uniform left)."""
    fam = ji.SumOfUniformsFamily()
    assert fam.below_kink((2.0 + 1e-9, A), 0) is None
    assert fam.below_kink((2.5, A), 0) is None
    assert fam.below_kink((0.0, A), 0) is None
    assert fam.below_kink((2.0, A), 1) is None
    assert ji.GaussianFamily().below_kink((0.1,), 0) is None
    got = fam.below_kink((1.0, A), 0)
    assert got is not None
    assert isinstance(got[1][0][1], ji.NoJitter)
    got = fam.below_kink((4.0, A), 0)
    assert got is not None
    assert got[1][0][1] == ji.SumOfUniforms(2, 3 * A / 5)


def test_scale_equivalent_only_on_an_integer_n():
    """No factor off the integers (there pdf_gradient gives the closed form), none for the
    scale a itself, and none from the families without kinks."""
    fam = ji.SumOfUniformsFamily()
    assert fam.scale_equivalent((2.0 + 1e-9, A), 0) is None
    assert fam.scale_equivalent((2.5, A), 0) is None
    assert fam.scale_equivalent((2.0, A), 1) is None
    assert ji.GaussianFamily().scale_equivalent((0.1,), 0) is None
