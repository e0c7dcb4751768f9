"""The one fit driver (jitterid.estimation.fit): estimator objects travel with their options
into the criterion and the result, with white and with coloured noise; capabilities, not
names, decide what the driver does."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.estimators import BCLS
from jitterid.estimation.search import SEARCHES


@dataclass(frozen=True)
class WeightedBCLS(BCLS):
    """BCLS with its residuals multiplied by ``factor`` and those above ``f_max_hz`` dropped:
    an option that changes the criterion (and, through ``f_max_hz``, its minimiser)."""

    name = "weighted-bcls-test"
    factor: float = 1.0
    f_max_hz: float = np.inf

    def _w(self, problem) -> np.ndarray:
        keep = (problem.freqs <= self.f_max_hz).astype(float)
        return self.factor * np.r_[keep, keep]

    def residuals(self, problem, x):
        return self._w(problem) * super().residuals(problem, x)

    def jacobian(self, problem, x):
        return self._w(problem)[:, None] * super().jacobian(problem, x)

    def bj_residuals(self, problem, x):
        return self._w(problem) * super().bj_residuals(problem, x)

    def bj_jacobian(self, problem, x):
        return self._w(problem)[:, None] * super().bj_jacobian(problem, x)

    def bj_grad_y(self, problem, x):
        return self.factor**2 * super().bj_grad_y(problem, x)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(5)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    u = ji.telegraph_input(160.0, rng)
    return ji.simulate(truth, u, ji.Uniform(0.3), T=1.0, N=150, noise_std=0.02, rng=rng)


@pytest.mark.parametrize("noise", [None, ji.RationalNoise(0, 1)], ids=["white", "coloured"])
def test_an_estimator_option_reaches_the_criterion_and_the_result(data, noise):
    kw = {"noise": noise} if noise is not None else {}
    plain = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), WeightedBCLS(), cov_type="none", **kw)
    tenfold = ji.fit(
        data, ji.PolePairGain(), ji.Uniform(0.3), WeightedBCLS(factor=10.0), cov_type="none", **kw
    )
    # the same minimiser, a criterion 100 times larger: the option was applied, not dropped
    np.testing.assert_allclose(tenfold.x[:3], plain.x[:3], rtol=1e-6)
    assert tenfold.cost == pytest.approx(100 * plain.cost, rel=1e-9)
    assert tenfold.estimator == WeightedBCLS(factor=10.0)
    assert tenfold.estimator.factor == 10.0
    assert tenfold.method == "weighted-bcls-test"
    # an option that moves the minimiser moves the estimate
    low = ji.fit(
        data, ji.PolePairGain(), ji.Uniform(0.3), WeightedBCLS(f_max_hz=0.2), cov_type="none", **kw
    )
    assert not np.allclose(low.x[:3], plain.x[:3], rtol=1e-4)


def test_the_result_keeps_the_search_layout_and_the_estimator(data):
    res = ji.fit(data, ji.PolePairGain(), ji.GaussianFamily(), "gaussian")
    assert res.layout.names == res.names
    assert res.layout.jitter == ("sigma",)
    assert isinstance(res.estimator, ji.GaussianCriterion)
    back = ji.FitResult.from_json(res.to_json())
    assert back.estimator == res.estimator
    assert back.layout == res.layout


def test_wbcls_refreeze_option_changes_the_number_of_searches(data):
    once = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), ji.WBCLS(refreeze=0))
    thrice = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), ji.WBCLS(refreeze=2))
    assert thrice.nfev > once.nfev
    assert thrice.estimator.refreeze == 2
    assert ji.FitResult.from_json(thrice.to_json()).estimator == ji.WBCLS(refreeze=2)


def test_ml_with_coloured_noise_is_refused_by_its_capability(data):
    with pytest.raises(ValueError, match="no coloured-noise"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), "ml", noise=ji.RationalNoise(0, 1))


def test_an_estimator_naming_an_unknown_search_is_refused(data):
    @dataclass(frozen=True)
    class Odd(BCLS):
        name = "odd-search-test"

        @property
        def search(self) -> str:
            return "simplex"

    assert "simplex" not in SEARCHES
    with pytest.raises(ValueError, match="register_search"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), Odd())


def test_every_registered_estimator_names_a_registered_search():
    from jitterid.estimation.estimators import as_estimator, method_names

    for name in method_names():
        assert as_estimator(name).search in SEARCHES
