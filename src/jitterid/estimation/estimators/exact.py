"""The exact likelihood as an estimator (notes 4): V = -2 sum_k ln p(y_k | theta). The
likelihood itself is :mod:`jitterid.estimation.likelihood`; its search (starts, quadrature
re-design) is :mod:`jitterid.estimation.ml`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .base import CriterionContext, Estimator, FloatArray, register
from .leastsquares import BCLS

__all__ = ["ML"]


@register
@dataclass(frozen=True)
class ML(Estimator):
    """The exact likelihood (notes 4), at the Cramer-Rao bound.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.ML()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "ml"
    first_stage_class = BCLS
    exact_likelihood = True
    scores_own_starts = True

    @property
    def search(self) -> str:
        return "likelihood"

    def noise_start(self, rms: float | None, plug_in: Callable[[], float]) -> float:
        # the likelihood's cost grows like 1 / noise: start close to the plug-in value
        return max(plug_in(), 0.05 * (rms or 0.0), 1e-12)

    rank = 6
    equation = "notes 4"
    cov_types = ("oim", "robust", "none")

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        return -2 * float(problem.likelihood.loglik(x, problem.data.y))

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        return -2 * problem.likelihood.dlogpdf_dy(x, problem.data.y)
