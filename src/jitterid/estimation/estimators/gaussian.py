"""The exact real-valued Gaussian criterion of the sample means and variances (notes 3):
V = sum_k (y_k - m_k)^2 / w_k + ln w_k, w_k = Var s(kT + tau) + sigma_v^2. Over all N
DFT bins it equals (22) with the full covariance and pseudo-covariance, in O(N)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import CriterionContext, Estimator, FloatArray, register

__all__ = ["GaussianCriterion"]


@register
@dataclass(frozen=True)
class GaussianCriterion(Estimator):
    """The exact real Gaussian criterion (notes 3); ``oim`` is its inverse observed
    information as a (pseudo) likelihood."""

    name = "gaussian"
    rank = 5
    equation = "notes 3"
    cov_types = ("sandwich", "robust", "oim", "none")

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        w = problem.variances(x)
        e = problem.data.y - problem.moments(x).mean
        return float(np.sum(e * e / w + np.log(w)))

    def objective_gradient(
        self, problem: CriterionContext, x: FloatArray
    ) -> tuple[float, FloatArray, FloatArray]:
        mom, w, dm, dw = problem.derivatives(x)
        e = problem.data.y - mom.mean
        value = float(np.sum(e * e / w + np.log(w)))
        grad = dm @ (-2 * e / w) + dw @ ((1 - e * e / w) / w)
        info = 2 * (dm / w) @ dm.T + (dw / w**2) @ dw.T
        return value, grad, info

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        return 2 * (problem.data.y - problem.moments(x).mean) / problem.variances(x)

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        mom, w, dm, dw = problem.derivatives(x)  # d(2 e / w) = -2 dm / w - 2 e dw / w^2
        e = problem.data.y - mom.mean
        return -2 * dm / w - 2 * e * dw / w**2

    def y_hessian_diagonal(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        _, w, _, dw = problem.derivatives(x)  # d(-2 e dw / w^2) / dy = -2 dw / w^2
        return -dw / w**2
