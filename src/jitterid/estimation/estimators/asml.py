"""Asymptotic maximum likelihood: (22) with the full frequency covariance R_Y, and the reduced
(23) with its diagonal. By Lemma 2 in the time domain (notes 2), R_Y(f, f) = sum_k w_k is the
same at every frequency, so (23) weights all frequencies equally."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve, solve_triangular

from .base import CriterionContext, Estimator, FloatArray, register

__all__ = ["AsML", "AsMLDiag"]


@register
@dataclass(frozen=True)
class AsML(Estimator):
    """Asymptotic ML (22): (Y - mu)^H R^{-1} (Y - mu) + ln det R."""

    name = "asml"
    rank = 3
    equation = "(22)"
    full_covariance = True

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        r, chol = problem.weighted(x)
        assert chol is not None
        z = solve_triangular(chol[0], r, lower=True)
        return float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(chol[0]).real)))

    def objective_gradient(
        self, problem: CriterionContext, x: FloatArray
    ) -> tuple[float, FloatArray, FloatArray]:
        _, _, dm, dw = problem.derivatives(x)
        dmu = problem.dmu(dm)
        r, chol = problem.weighted(x)
        assert chol is not None
        L = chol[0]
        z = solve_triangular(L, r, lower=True)
        value = float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(L).real)))
        a = cho_solve(chol, r)
        Rinv = cho_solve(chol, np.eye(r.size))
        dR = problem.dR(dw)
        grad = -2 * (dmu @ a.conj()).real
        RdR = Rinv[None] @ dR  # R^{-1} dR_i as BLAS products (einsum loops in C, ~10x slower)
        grad += np.trace(RdR, axis1=1, axis2=2).real - ((dR @ a) @ a.conj()).real
        # tr(R^{-1} dR_i R^{-1} dR_j) = sum_kl (R^{-1} dR_i)_kl (R^{-1} dR_j)_lk
        flat = RdR.reshape(RdR.shape[0], -1)
        info = 2 * (dmu.conj() @ Rinv @ dmu.T).real + (
            flat @ RdR.transpose(0, 2, 1).reshape(flat.shape).T
        ).real
        return value, grad, info

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        return 2 * problem.adjoint(cho_solve(chol, r))


@register
@dataclass(frozen=True)
class AsMLDiag(Estimator):
    """Reduced asymptotic ML (23): sum_f |Y - mu|^2 / R(f, f) + ln R(f, f)."""

    name = "asml-diag"
    rank = 4
    equation = "(23)"

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        r, _ = problem.weighted(x)
        rho = float(np.sum(problem.variances(x)))
        return float(np.sum(np.abs(r) ** 2) / rho + r.size * np.log(rho))

    def objective_gradient(
        self, problem: CriterionContext, x: FloatArray
    ) -> tuple[float, FloatArray, FloatArray]:
        _, w, dm, dw = problem.derivatives(x)
        dmu = problem.dmu(dm)
        r, _ = problem.weighted(x)
        rho = float(np.sum(w))
        drho = dw.sum(axis=1)
        F, rr = r.size, float(np.sum(np.abs(r) ** 2))
        value = rr / rho + F * np.log(rho)
        grad = -2 * (dmu @ r.conj()).real / rho + (F - rr / rho) * drho / rho
        info = 2 * (dmu.conj() @ dmu.T).real / rho + F * np.outer(drho, drho) / rho**2
        return float(value), grad, info

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return 2 * problem.adjoint(r / float(np.sum(problem.variances(x))))

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        _, w, dm, dw = problem.derivatives(x)  # d(2 F^H r / rho), rho = sum w
        r, _ = problem.weighted(x)
        rho, drho = float(np.sum(w)), dw.sum(axis=1)
        base = 2 * problem.adjoint(r)
        dmu = problem.dmu(dm)
        return np.array([-2 * problem.adjoint(row) / rho - base * dr / rho**2 for row, dr in zip(dmu, drho, strict=True)])
