"""The exact likelihood as an estimator (notes 4): V = -2 sum_k ln p(y_k | theta). The
likelihood itself is :mod:`jitterid.estimation.likelihood`; its search (starts, quadrature
re-design) is :mod:`jitterid.estimation.ml`."""

from __future__ import annotations

from dataclasses import dataclass

from .base import CriterionContext, Estimator, FloatArray, register

__all__ = ["ML"]


@register
@dataclass(frozen=True)
class ML(Estimator):
    """The exact likelihood (notes 4), at the Cramer-Rao bound."""

    name = "ml"
    rank = 6
    equation = "notes 4"
    cov_types = ("oim", "robust", "none")

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        return -2 * float(problem.likelihood.loglik(x, problem.data.y))

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        return -2 * problem.likelihood.dlogpdf_dy(x, problem.data.y)
