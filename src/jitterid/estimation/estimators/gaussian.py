"""The exact real-valued Gaussian criterion of the sample means and variances (notes 3):
V = sum_k (y_k - m_k)^2 / w_k + ln w_k, w_k = Var s(kT + tau) + sigma_v^2. Over all N
DFT bins it equals (22) with the full covariance and pseudo-covariance, in O(N).

With coloured noise (Box-Jenkins) the diagonal w becomes Sigma_y = diag(d) + Toeplitz(gamma)
of (C2): V = (y - m)^T Sigma_y^{-1} (y - m) + ln det Sigma_y, still O(N) through the banded
form (C4) of :class:`jitterid.moments.noise_covariance.SampleCovariance`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...moments.noise_covariance import toeplitz_products
from .base import ColouredContext, CriterionContext, Estimator, FloatArray, register
from .leastsquares import BCLS

__all__ = ["GaussianCriterion"]


@register
@dataclass(frozen=True)
class GaussianCriterion(Estimator):
    """The exact real Gaussian criterion (notes 3); ``oim`` is its inverse observed
    information as a (pseudo) likelihood.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.GaussianCriterion()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "gaussian"
    first_stage_class = BCLS
    rank = 5
    equation = "notes 3"
    cov_types = ("sandwich", "robust", "oim", "none")
    coloured_noise = True
    identifies_noise_model = True

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

    # ------------------------------------------------------------------ coloured noise
    def bj_objective(self, problem: ColouredContext, x: FloatArray) -> float:
        e = problem.data.y - problem.moments(x).mean
        cov = problem.covariance(x)
        return float(e @ cov.solve(e) + cov.logdet)

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        return 2 * problem.covariance(x).solve(problem.data.y - problem.moments(x).mean)

    def bj_grad_y_jacobian(self, problem: ColouredContext, x: FloatArray) -> FloatArray | None:
        """d(2 S^{-1} e)/dx_p = -2 S^{-1} (dm_p + dS_p z), z = S^{-1} e, dS_p = diag(dd_p) +
        Toeplitz(dgamma_p): one derivative pass and P solves (instead of 2P criteria)."""
        mom, dm, dd, dg = problem.derivatives(x)
        cov = problem.covariance(x)
        z = cov.solve(problem.data.y - mom.mean)
        R = dm + dd * z  # (P, N): dm_p + diag(dd_p) z
        if dg:
            keys = list(dg)
            R[keys] += toeplitz_products(np.array([dg[p][0] for p in keys]), z[:, None])[:, :, 0].T
        return -2 * cov.solve(R.T).T

    def bj_gradient(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        return self._bj_parts(problem, np.asarray(x, float), None, information=False)[1]

    def bj_objective_gradient(
        self, problem: ColouredContext, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """V = e^T S^{-1} e + ln det S, S = Sigma_y, e = y - m, through the banded B = L S L^T
        of (C4): with u = L e, z = B^{-1} u,

            V = u^T z + ln det B,
            dV = 2 (dL e - L dm)^T z - z^T dB z + tr(B^{-1} dB),

        dB banded (:meth:`SampleCovariance.derivative_band`) and tr(B^{-1} dB) from B^{-1}
        on the band only (:attr:`SampleCovariance.band_inverse`): O(N w^2) in all.

        Expected Hessian (2 x Fisher information) M = 2 dm^T S^{-1} dm + tr(S^{-1} dS_i
        S^{-1} dS_j). The first term is exact (whitened columns C^{-1} L dm). The trace term
        has no banded form (it needs all of S^{-1}); it is estimated with the problem's fixed
        probe vectors zeta = L^T C^{-T} xi, xi ~ N(0, I) (:meth:`BJProblem.probes`; so
        E zeta zeta^T = S^{-1}): tr(S^{-1} dS_i S^{-1} dS_j) = E[(dS_i zeta)^T S^{-1}
        (dS_j zeta)], a Gram matrix of whitened vectors, hence positive semi-definite, and
        smooth in x (the same xi at every point). M only steers the Newton steps; the
        gradient and value are exact. ``free``: only those rows and columns are formed (zeros
        elsewhere), e.g. the noise stage with the system fixed.
        """
        value, grad, info = self._bj_parts(problem, np.asarray(x, float), free, information=True)
        assert info is not None
        return value, grad, info

    def _bj_parts(
        self,
        problem: ColouredContext,
        x: FloatArray,
        free: NDArray[np.intp] | None,
        information: bool,
    ) -> tuple[float, FloatArray, FloatArray | None]:
        """(V, dV/dx, M or None): :meth:`bj_objective_gradient`, M only if ``information``."""
        mom, dm, dd, dg = problem.derivatives(x)
        cov = problem.covariance(x)
        N, P_all = problem.data.N, x.size
        sel = np.arange(P_all) if free is None else np.asarray(free, dtype=np.intp)
        dm, dd = dm[sel], dd[sel]
        dg = {j: dg[p] for j, p in enumerate(sel) if p in dg}
        P = sel.size
        e = problem.data.y - mom.mean
        u = cov.filter(e)
        z = cov.band_solve(u)
        value = float(u @ z + cov.logdet)
        Lm = cov.filter(dm.T)  # (N, P)
        grad = -2 * (Lm.T @ z)
        w = cov.width
        n = cov.gamma.ar.size - 1 if cov.gamma is not None else 0
        dgam, dar = np.zeros((P, N)), np.zeros((P, n + 1))
        for p, (dgp, darp) in dg.items():
            dgam[p], dar[p] = dgp, darp
            grad[p] += 2 * (cov.dfilter(darp, e) @ z)
        dB = cov.derivative_band(dd, dgam if dg else None, dar if dg else None)  # (P, w + 1, N)
        twice = np.where(np.arange(w + 1) > 0, 2.0, 1.0)[:, None]
        zz = np.zeros((w + 1, N))
        for b in range(w + 1):
            zz[b, : N - b] = z[b:] * z[: N - b]
        grad += dB.reshape(P, -1) @ (twice * (cov.band_inverse - zz)).ravel()
        if not information:
            if P_all == P:
                return value, grad, None
            g_all = np.zeros(P_all)
            g_all[sel] = grad
            return value, g_all, None
        Wm = cov._triangular(Lm, "N")
        info = 2 * (Wm.T @ Wm)
        zeta = cov.colour(problem.probes())  # (N, K)
        K = zeta.shape[1]
        V = dd.T[:, :, None] * zeta[:, None, :]  # (N, P, K): diag(dd_p) zeta
        if dg:
            keys = list(dg)
            V[:, keys] += toeplitz_products(np.array([dg[p][0] for p in keys]), zeta)
        X = cov.whiten(V.reshape(N, P * K)).reshape(N, P, K).transpose(1, 0, 2).reshape(P, N * K)
        info += (X @ X.T) / K
        if P_all == P:
            return value, grad, info
        g_all, M_all = np.zeros(P_all), np.zeros((P_all, P_all))
        g_all[sel], M_all[np.ix_(sel, sel)] = grad, info
        return value, g_all, M_all
