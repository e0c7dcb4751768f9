"""Issue 25, item 10: a single fit with one order too many said CONVERGED where
select_order flags the row as over-order; the one predicate (estimation.checks.
over_order_symptom) is now a check of every fit (FitStatus.OVER_ORDER)."""

import numpy as np
import pytest

import jitterid as ji
from jitterid.analysis.selection import over_order
from jitterid.estimation.checks import over_order_symptom

T, N = 0.5, 600


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(1)
    truth = ji.RationalModel(1, 3).system([2.0, 6.0, 3.0, 4.0, 2.0])  # poles -1, -1 +- i
    u = ji.zoh_input(np.sign(rng.standard_normal(N + 10)), T=T)
    return ji.simulate(truth, u, ji.Gaussian(0.04), T=T, N=N, noise_std=0.02, rng=rng)


def test_one_pole_too_many_is_flagged_on_a_single_fit(data):
    res = ji.fit(data, ji.RationalModel(1, 4), ji.Gaussian(0.04), method="bcls")
    assert res.status is ji.FitStatus.OVER_ORDER, res.message
    assert "over-order model: pole" in res.message
    assert "select_order" in res.message
    # the same words as select_order's row for this fit (one predicate)
    sl = res.layout.slice("system")
    symptom = over_order_symptom(res.structure, res.x[sl], res.cov[sl, sl], T)
    assert symptom
    assert symptom in res.message
    assert over_order(res, T) == symptom


def test_the_true_order_still_converges(data):
    res = ji.fit(data, ji.RationalModel(1, 3), ji.Gaussian(0.04), method="bcls")
    assert res.status is ji.FitStatus.CONVERGED, res.message


def test_the_predicate_on_a_pole_that_cancels_a_zero():
    # (s + 2) / ((s + 2.01)(s + 1)): |p - z| = 0.01 = 0.5 % of |p|
    structure = ji.RationalModel(1, 2)
    theta = np.array([1.0, 2.0, 3.01, 2.01])
    text = over_order_symptom(structure, theta, np.full((4, 4), np.nan), 0.1)
    assert "cancel" in text
    assert (
        over_order_symptom(structure, np.array([1.0, 2.0, 3.0, 8.0]), np.eye(4) * 1e-8, 0.1) == ""
    )
