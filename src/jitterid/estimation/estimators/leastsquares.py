"""Least squares on the DFT: LS (8), which ignores the jitter, and BCLS (14), which compares
with the jittered mean mu_Y(f) = DTFT of m_k (Lemma 1 in the time domain, notes 1).

With coloured noise (Box-Jenkins) BCLS is (14) unchanged: the noise model does not enter the
criterion, only its error bars (the noise parameters are plug-in values). LS has no
coloured-noise form."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import ColouredContext, CriterionContext, Estimator, FloatArray, register

__all__ = ["BCLS", "LS"]


@dataclass(frozen=True)
class _DFTResidual(Estimator):
    """sum_f |Y(f) - mu(f)|^2 as least squares on the stacked real and imaginary parts."""

    least_squares = True
    needs_noise = False
    estimates_noise = False
    uses_variances = False

    def residuals(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return np.concatenate([r.real, r.imag])

    def jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        dmu = problem.dmu(problem.derivatives(x)[2])  # (P, F)
        return -np.vstack([dmu.real.T, dmu.imag.T])

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return 2 * problem.adjoint(r)

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        dmu = problem.dmu(problem.derivatives(x)[2])  # d(2 Re F^H (Y - mu)) = -2 Re F^H dmu
        return np.array([-2 * problem.adjoint(row) for row in dmu])


@register
@dataclass(frozen=True)
class LS(_DFTResidual):
    """Ordinary least squares (8): ignores the jitter (biased at high frequencies).

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.LS()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.NoJitter(), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "ls"
    rank = 0
    equation = "(8)"
    ignores_jitter = True
    cov_types = ("robust", "sandwich", "none")


@register
@dataclass(frozen=True)
class BCLS(_DFTResidual):
    """Bias-compensated least squares (14): the residual to the jittered mean mu_Y.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> est = ji.BCLS()
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method=est)
    >>> res.success, res.x.round(1).tolist()
    (True, [2.0, 2.0])
    """

    name = "bcls"
    rank = 1
    equation = "(14)"
    coloured_noise = True
    weighs_by_noise = False  # (14) has no weights: the BJ system estimate is the OE one

    # ------------------------------------------------------------------ coloured noise
    def bj_residuals(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return np.concatenate([r.real, r.imag])

    def bj_jacobian(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """-[Re; Im] dmu, dmu = F dm from the OE pass (the pinned noise parameters do not
        enter)."""
        _, dm, _, _ = problem.derivatives(x)
        dmu = problem.dmu(dm).T  # (F, P)
        return -np.vstack([dmu.real, dmu.imag])

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        r, _ = problem.weighted(x)
        return 2 * problem.adjoint(r)
