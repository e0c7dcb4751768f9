"""Referees for the per-evaluation savings of the Monte Carlo (issue 13, item 3): every cache
or vectorised rewrite gives the numbers of the code it replaced."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import sparse
from scipy.interpolate import BSpline

import jitterid as ji
from jitterid.jitter.laws import SumOfUniforms
from jitterid.moments.modal import SegmentPlan, _PoleTable, _table_sums, modal_moments, tables
from jitterid.moments.quadrature import _relative_cuts


def _loop_cuts(knots, max_panel, limits=None):
    """The former per-gap loop of ``_relative_cuts`` (np.linspace per gap)."""
    knots = np.asarray(knots, float)
    if limits is None:
        knots = np.unique(knots)
    pieces = [knots[:1]]
    for i, (a, b) in enumerate(itertools.pairwise(knots)):
        lim = max_panel if limits is None else min(max_panel, float(limits[i]))
        n = max(1, int(np.ceil((b - a) / lim)))
        pieces.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(pieces)


def test_relative_cuts_match_the_linspace_loop_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    for t in range(2000):
        k = np.sort(rng.uniform(-1, 1, rng.integers(1, 12)) * 10 ** rng.uniform(-8, 2))
        panel = 10 ** rng.uniform(-3, 1) * (np.ptp(k) + 1e-12)
        limits = None
        if t % 2:
            k = np.unique(k)
            limits = rng.uniform(0.01, 2, k.size) * panel
        assert np.array_equal(_relative_cuts(None, panel, k, limits), _loop_cuts(k, panel, limits))


@pytest.mark.parametrize("n", [0.0, 0.37, 1.0, 2.0, 2.6, 7.3, 19.999])
def test_sum_of_uniforms_shared_splines_and_knots(n: float) -> None:
    """The B-splines shared per m and the knots kept per law give the density of splines
    built for the law alone, and the knots are a fresh array at every call."""
    law = SumOfUniforms(n, 0.4)
    m = law.components[0]
    own = BSpline.basis_element(np.arange(m + 1.0), extrapolate=False)
    assert np.array_equal(law._spline.t, own.t)
    assert np.array_equal(law._spline_cdf.c, own.antiderivative().c)
    k1 = law.breakpoints()
    k1[0] = 99.0  # a caller's change does not reach the law
    assert np.array_equal(law.breakpoints(), SumOfUniforms(n, 0.4)._breakpoints())
    tau = np.linspace(-0.45, 0.45, 301)
    assert np.array_equal(law.pdf(tau), SumOfUniforms(n, 0.4).pdf(tau))


def test_table_sums_equal_the_counts_product() -> None:
    """The per-piece table sums equal the sparse counts-times-tables product they replace."""
    u = ji.telegraph_input(220.0, rng=3)
    G = ji.TransferFunction([1.0, 3.0], [1.0, 0.8, 4.0])
    plan = SegmentPlan(SumOfUniforms(6.4, 0.45), 1.0, 200, u, 2.0, poles=G.modal.poles)
    tab = tables(G, u)
    for pc in plan.chunks():
        tabs = [_PoleTable.make(complex(p), pc.std, True) for p in tab.p]
        got = _table_sums(pc, tabs, pc.std)
        npc, R = pc.row.size, pc.std.mid.size
        counts = sparse.csr_matrix(
            (
                np.ones(pc.sp_m.size),
                pc.sp_m,
                np.r_[0, np.cumsum(np.bincount(pc.sp_piece, minlength=npc))],
            ),
            shape=(npc, R),
        )
        for pt, g in zip(tabs, got, strict=True):
            assert g is not None
            np.testing.assert_allclose(g[0], counts @ pt.G, rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(g[1], counts @ pt.H, rtol=1e-13, atol=1e-15)
    mean, var, _, _ = modal_moments(plan, tab, scale=0.45)
    assert np.all(np.isfinite(mean))
    assert var is not None
    assert np.all(var >= 0)


def test_panel_layout_memo_gives_the_computed_layout() -> None:
    """The memoised layout of a law equals the one computed afresh for an equal law."""
    from jitterid.moments.quadrature import _panel_layout, panel_layout

    poles = np.array([-2.0, -300.0 + 40j, -300.0 - 40j])
    for law in (SumOfUniforms(2.3, 0.4), ji.Gaussian(0.1), ji.Uniform(0.2)):
        first = panel_layout(law, poles)
        again = panel_layout(type(law)(**law.params), poles)
        fresh = _panel_layout(law, np.asarray(poles, complex), 5)
        for lay in (first, again):
            assert lay.key == fresh.key
            assert lay.rate == fresh.rate
            assert np.array_equal(lay.grade, fresh.grade)


def test_wide_window_density_in_one_evaluation() -> None:
    """The moving-average density of a non-integer n takes both CDF ends from one spline
    call: the values of two calls."""
    law = SumOfUniforms(2.6, 0.3)
    x = -np.abs(np.linspace(-0.31, 0.31, 257))
    c = law.components[2]
    two = (law._irwin_hall_cdf(x + c) - law._irwin_hall_cdf(x - c)) / (2.0 * c)
    assert np.array_equal(law._window_mean(x), two)


def test_unique_skips_the_sort_only_when_already_unique() -> None:
    """The switch times and knots skip np.unique's sort when they increase strictly; any
    other array gets np.unique itself."""
    from jitterid.moments.quadrature import _unique

    rng = np.random.default_rng(11)
    for a in (
        np.sort(rng.uniform(0, 100, 50)),
        rng.uniform(0, 100, 50),
        np.repeat(np.arange(5.0), 2),
        np.array([1.0]),
        np.zeros(0),
        np.array([0.0, np.nan, 1.0]),
    ):
        assert np.array_equal(_unique(a), np.unique(a), equal_nan=True)
