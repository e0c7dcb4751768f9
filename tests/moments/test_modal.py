"""The modal route of the jittered moments (jitterid.moments.modal): the per-piece table sums
against the sparse counts-times-tables product they replace, and a kept Gaussian plan serving
every sigma of its band with the numbers of a plan of its own."""

from __future__ import annotations

import numpy as np
from scipy import sparse

import jitterid as ji
from jitterid.jitter.laws import SumOfUniforms
from jitterid.moments import modal as _modal
from jitterid.moments.modal import SegmentPlan, _PoleTable, _table_sums, modal_moments, tables


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


T = 0.5  # the lab setting (tests/moments/test_quadrature.py)


def _lab_input(n, seed=3):
    rng = np.random.default_rng(seed)
    return ji.zoh_input(rng.choice([-1.0, 1.0], size=n + 20), T)


def test_a_gaussian_plan_serves_every_sigma_of_its_band():
    n = 60
    u = _lab_input(n)
    structure, theta = ji.RationalModel(1, 3), np.array([1.0, 2.0, 3.0, 4.0, 2.0])
    tf = structure.system(theta)
    tab = _modal.tables(tf, u)
    dtab = _modal.derivative_tables(tf, u, _modal.modal_sensitivity(structure, theta, tf))
    p = tf.modal.poles
    _modal.clear_plans()
    first = _modal.cached_plan(ji.Gaussian(0.0801), T, n, u, 1.5, p)
    _modal.modal_moments(first, tab)  # builds and keeps the nodes
    law = ji.Gaussian(0.0806)  # the same band
    shared = _modal.cached_plan(law, T, n, u, 1.5, p)
    assert shared._store is first._store
    assert len(_modal._plans) == 1
    own = _modal.SegmentPlan(law, T, n, u, 1.5, poles=p)
    for a, b in zip(
        _modal.modal_moments(shared, tab, dtab, scale=0.0806),
        _modal.modal_moments(own, tab, dtab, scale=0.0806),
        strict=True,
    ):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
    _modal.clear_plans()
