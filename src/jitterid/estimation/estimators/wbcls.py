"""Weighted BCLS (20): (Y - mu)^H R^{-1} (Y - mu) with R = R_Y (17)-(19).

Written literally, (20) takes R = R_Y(theta) at the searched theta; with no ln det R term
that criterion is minimised partly by inflating R, and the estimate is biased (Table 2, 32
realizations: k0 7.12, pr -1.29, pi 2.26 against 6.25, -1.5, 2; 6-14 standard errors). The
problem therefore freezes R at ``weights_at`` (feasible generalised least squares);
:func:`jitterid.fit` sets it to the BCLS estimate and re-freezes ``refreeze`` times at the
new estimate. ``Problem(weights_at=None)`` keeps the literal form, for comparison.

With coloured noise (Box-Jenkins) R = E Sigma_y E^H with Sigma_y of (C2), frozen the same
way (:class:`jitterid.estimation.boxjenkins.BoxJenkinsRoute`); the noise parameters are
plug-in values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve, solve_triangular

from .base import ColouredContext, CriterionContext, Estimator, FloatArray, register
from .leastsquares import BCLS

__all__ = ["WBCLS"]


@register
@dataclass(frozen=True)
class WBCLS(Estimator):
    """Weighted BCLS (20), with R_Y frozen at the BCLS estimate and re-frozen ``refreeze``
    times at the new estimate (iterated feasible GLS; module docstring).

    Parameters
    ----------
    refreeze : int, optional
        Number of times the weighting is re-frozen at the new estimate (>= 0).

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.WBCLS()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "wbcls"
    first_stage_class = BCLS
    rank = 2
    equation = "(20)"
    least_squares = True
    estimates_noise = False
    full_covariance = True
    coloured_noise = True
    refreeze: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.refreeze, int) or self.refreeze < 0:
            raise ValueError(f"refreeze must be a whole number >= 0; got {self.refreeze!r}")

    @property
    def freeze_rounds(self) -> int:
        return 1 + self.refreeze

    def residuals(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        z = solve_triangular(chol[0], r, lower=True)
        return np.concatenate([z.real, z.imag])

    def jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        _, _, dm, dw = problem.derivatives(x)
        dmu = problem.dmu(dm)  # (P, F)
        r, chol = problem.weighted(x)
        assert chol is not None
        L = chol[0]
        z = solve_triangular(L, r, lower=True)
        dz = -solve_triangular(L, dmu.T, lower=True)  # (F, P)
        if problem.frozen_weights:  # R does not depend on x
            return np.vstack([dz.real, dz.imag])
        for i, dRi in enumerate(problem.dR(dw)):
            B = solve_triangular(L, dRi, lower=True)
            A = solve_triangular(L, B.conj().T, lower=True)  # L^{-1} dR L^{-H}
            phi = np.tril(A, -1) + 0.5 * np.diag(np.diag(A))
            dz[:, i] -= phi @ z
        return np.vstack([dz.real, dz.imag])

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        return 2 * problem.adjoint(cho_solve(chol, r))

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        if not problem.frozen_weights:  # R(theta) moves too: differences
            return None
        _, chol = problem.weighted(x)
        assert chol is not None
        dmu = problem.dmu(problem.derivatives(x)[2])
        return np.array([-2 * problem.adjoint(cho_solve(chol, row)) for row in dmu])

    # ------------------------------------------------------------------ coloured noise
    def bj_residuals(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        z = solve_triangular(chol[0], r, lower=True)
        return np.concatenate([z.real, z.imag])

    def bj_has_jacobian(self, problem: ColouredContext) -> bool:
        return problem.frozen_weights

    def bj_jacobian(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """-[Re; Im] L^{-1} dmu with R = L L^H frozen (``weights_at``); the literal (20), R at
        the searched point, has none here (its residuals are differenced)."""
        if not problem.frozen_weights:
            raise ValueError("jacobian: the literal wbcls (R at the searched point) has none here")
        _, dm, _, _ = problem.derivatives(x)
        dmu = problem.dmu(dm).T  # (F, P)
        _, chol = problem.weighted(x)
        assert chol is not None
        dmu = solve_triangular(chol[0], dmu, lower=True)
        return -np.vstack([dmu.real, dmu.imag])

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, chol = problem.weighted(x)
        assert chol is not None
        return 2 * problem.adjoint(cho_solve(chol, r))
