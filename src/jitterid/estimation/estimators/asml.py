"""Asymptotic maximum likelihood: (22) with the full frequency covariance R_Y, and the reduced
(23) with its diagonal. By Lemma 2 in the time domain (notes 2), R_Y(f, f) = sum_k w_k is the
same at every frequency, so (23) weights all frequencies equally.

With coloured noise (Box-Jenkins) both keep their form with R = E Sigma_y E^H (Sigma_y of
(C2)) and dR = E dSigma_y E^H (linear in d and gamma); R(f, f) of (23) then varies with f.
Their ln det term identifies the noise model's parameters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_solve, solve_triangular

from .base import ColouredContext, ComplexArray, CriterionContext, Estimator, FloatArray, register
from .leastsquares import BCLS

__all__ = ["AsML", "AsMLDiag"]


def _value_gradient_information(
    dmu: ComplexArray, r: ComplexArray, chol: tuple[FloatArray, bool], dR: ComplexArray
) -> tuple[float, FloatArray, FloatArray]:
    """(V, dV/dx, expected Hessian) of (22), V = r^H R^{-1} r + ln det R, from the DTFT
    residual r, R's Cholesky factor, dmu (P, F) and dR (P, F, F), white or coloured noise."""
    L = chol[0]
    z = solve_triangular(L, r, lower=True)
    value = float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(L).real)))
    a = cho_solve(chol, r)
    Rinv = cho_solve(chol, np.eye(r.size))
    grad = -2 * (dmu @ a.conj()).real
    RdR = Rinv[None] @ dR  # R^{-1} dR_i as BLAS products (einsum loops in C, ~10x slower)
    grad += np.trace(RdR, axis1=1, axis2=2).real - ((dR @ a) @ a.conj()).real
    # tr(R^{-1} dR_i R^{-1} dR_j) = sum_kl (R^{-1} dR_i)_kl (R^{-1} dR_j)_lk
    flat = RdR.reshape(RdR.shape[0], -1)
    info = (
        2 * (dmu.conj() @ Rinv @ dmu.T).real
        + (flat @ RdR.transpose(0, 2, 1).reshape(flat.shape).T).real
    )
    return value, grad, info


@register
@dataclass(frozen=True)
class AsML(Estimator):
    """Asymptotic ML (22): (Y - mu)^H R^{-1} (Y - mu) + ln det R.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.AsML()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "asml"
    first_stage_class = BCLS
    rank = 3
    equation = "(22)"
    full_covariance = True
    coloured_noise = True
    identifies_noise_model = True

    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        r, chol = problem.weighted(x)
        assert chol is not None
        z = solve_triangular(chol[0], r, lower=True)
        return float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(chol[0]).real)))

    def objective_gradient(
        self, problem: CriterionContext, x: FloatArray
    ) -> tuple[float, FloatArray, FloatArray]:
        _, _, dm, dw = problem.derivatives(x)
        r, chol = problem.weighted(x)
        assert chol is not None
        return _value_gradient_information(problem.dmu(dm), r, chol, problem.dR(dw))

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        return 2 * problem.adjoint(cho_solve(chol, r))

    def frequency_kernel(self, problem: CriterionContext, x: FloatArray) -> ComplexArray | None:
        # the quadratic part of dV/dx_p: -a^H dR_p a = r^H (-R^{-1} dR_p R^{-1}) r
        _, _, _, dw = problem.derivatives(x)
        r, chol = problem.weighted(x)
        assert chol is not None
        Rinv = cho_solve(chol, np.eye(r.size))
        return np.asarray(-(Rinv[None] @ problem.dR(dw) @ Rinv[None]), dtype=complex)

    # ------------------------------------------------------------------ coloured noise
    def bj_objective(self, problem: ColouredContext, x: FloatArray) -> float:
        return self.objective(problem, x)  # type: ignore[arg-type]  # the same (22) of weighted()

    def bj_objective_gradient(
        self, problem: ColouredContext, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """The formulas of :meth:`objective_gradient` with dR = E dSigma_y E^H
        (:meth:`BJProblem.dR`); O(F^3) as the criterion itself, all parameters."""
        x = np.asarray(x, float)
        _, dm, dd, dg = problem.derivatives(x)
        r, chol = problem.weighted(x)
        assert chol is not None
        return _value_gradient_information(problem.dmu(dm), r, chol, problem.dR(dd, dg))

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        return 2 * problem.adjoint(cho_solve(chol, r))


@register
@dataclass(frozen=True)
class AsMLDiag(Estimator):
    """Reduced asymptotic ML (23): sum_f |Y - mu|^2 / R(f, f) + ln R(f, f).

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.AsMLDiag()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "asml-diag"
    first_stage_class = BCLS
    rank = 4
    equation = "(23)"
    coloured_noise = True
    identifies_noise_model = True

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

    def frequency_kernel(self, problem: CriterionContext, x: FloatArray) -> ComplexArray | None:
        # the quadratic part of dV/dx_p: -|r|^2 drho_p / rho^2, a diagonal kernel
        _, w, _, dw = problem.derivatives(x)
        rho = float(np.sum(w))
        F = problem.freqs.size
        return np.repeat((-dw.sum(axis=1) / rho**2)[:, None], F, axis=1).astype(complex)

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        _, w, dm, dw = problem.derivatives(x)  # d(2 F^H r / rho), rho = sum w
        r, _ = problem.weighted(x)
        rho, drho = float(np.sum(w)), dw.sum(axis=1)
        base = 2 * problem.adjoint(r)
        dmu = problem.dmu(dm)
        return np.array(
            [
                -2 * problem.adjoint(row) / rho - base * dr / rho**2
                for row, dr in zip(dmu, drho, strict=True)
            ]
        )

    # ------------------------------------------------------------------ coloured noise
    # R(f, f) of (23) is no longer the same at every frequency: rho(f) and its derivatives
    # (:meth:`BJProblem.R_diagonal`, :meth:`BJProblem.dR_diagonal`), O(N log N) each.
    def bj_objective(self, problem: ColouredContext, x: FloatArray) -> float:
        r, _ = problem.weighted(x)
        rho = problem.R_diagonal(x)
        return float(np.sum(np.abs(r) ** 2 / rho + np.log(rho)))

    def bj_objective_gradient(
        self, problem: ColouredContext, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        x = np.asarray(x, float)
        _, dm, dd, dg = problem.derivatives(x)
        dmu = problem.dmu(dm)  # (P, F)
        r, _ = problem.weighted(x)
        rho = problem.R_diagonal(x)
        drho = problem.dR_diagonal(dd, dg)
        rr = np.abs(r) ** 2
        value = float(np.sum(rr / rho + np.log(rho)))
        grad = -2 * (dmu @ (r.conj() / rho)).real + drho @ ((1 - rr / rho) / rho)
        info = 2 * ((dmu / rho).conj() @ dmu.T).real + (drho / rho**2) @ drho.T
        return value, grad, info

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return 2 * problem.adjoint(r / problem.R_diagonal(x))
