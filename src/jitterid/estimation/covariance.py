"""Delta-method (sandwich) covariance of any criterion's minimiser.

An estimate theta(y) solves dV/dtheta (theta, y) = 0. Differentiating in y gives
d theta / dy = -H^{-1} G with H = d^2 V / d theta^2 and G = d^2 V / d theta dy^T, and since
the samples are independent with variances w_k,

    Cov(theta) ~ H^{-1} G diag(w) G^T H^{-1}.

This holds for every criterion of the library, whether or not it is a likelihood, so every
estimator gets honest error bars by one route. For least-squares criteria H is the
Gauss-Newton matrix 2 J^T J with the analytic Jacobian; otherwise central differences of
the analytic gradient (:mod:`jitterid.estimation.jacobians`).

The exact likelihood (``ml``, V = -2 ln L) gets the inverse observed information instead,
Cov = (-d^2 ln L)^{-1} = 2 H^{-1}, since the score is not linear in y; ``robust=True`` gives
the Huber-White form H^{-1} (4 sum_k g_k g_k^T) H^{-1} with g_k the per-sample scores.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from threadpoolctl import threadpool_limits

if TYPE_CHECKING:
    from .problem import Problem

__all__: list[str] = []

FloatArray = NDArray[np.float64]
_REL_STEP = 1e-4


def _steps(x: FloatArray, bounds: tuple[tuple[float, float], ...]) -> tuple[FloatArray, NDArray[np.bool_]]:
    h = _REL_STEP * np.maximum(np.abs(x), 1e-2)
    lo, hi = np.array(bounds, dtype=float).reshape(-1, 2).T
    free = (x - 2 * h >= lo) & (x + 2 * h <= hi)
    return h, free


def _hessian(fun: Callable[[FloatArray], float], x: FloatArray, h: FloatArray) -> FloatArray:
    p = x.size
    H = np.empty((p, p))
    f0 = fun(x)
    e = np.eye(p) * h
    for i in range(p):
        H[i, i] = (fun(x + 2 * e[i]) - 2 * f0 + fun(x - 2 * e[i])) / (4 * h[i] ** 2)
        for j in range(i):
            H[i, j] = H[j, i] = (
                fun(x + e[i] + e[j]) - fun(x + e[i] - e[j]) - fun(x - e[i] + e[j]) + fun(x - e[i] - e[j])
            ) / (4 * h[i] * h[j])
    return H


def sandwich_covariance(problem: Problem, x: FloatArray, robust: bool | None = None) -> FloatArray:
    """Covariance of the estimate ``x`` of ``problem``; NaN for parameters on a bound.

    ``robust`` uses squared residuals (y_k - m_k)^2 for the variances (White's HC0) instead
    of the model's w_k; the default is robust only for ``ls``, whose model has no jitter.
    For ``ml``: the inverse observed information, or with ``robust`` the Huber-White
    sandwich of the per-sample scores (module docstring).
    """
    # Called lazily, outside fit's BLAS limit; its small complex Cholesky factorisations run
    # ~100x slower multi-threaded on small machines.
    with threadpool_limits(limits=1, user_api="blas"):
        return _covariance(problem, x, robust)


def _covariance(problem: Problem, x: FloatArray, robust: bool | None) -> FloatArray:
    p = x.size
    cov = np.full((p, p), np.nan)
    if p == 0:
        return cov
    h, free = _steps(x, problem.bounds)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov
    xf = x.copy()

    def embed(z: FloatArray) -> FloatArray:
        out = xf.copy()
        out[idx] = z
        return out

    z0, hz = x[idx], h[idx]
    if problem.method == "ml":
        return _ml_covariance(problem, x, idx, embed, z0, hz, bool(robust), cov)
    G = np.empty((idx.size, problem.data.N))
    for i in range(idx.size):
        dz = np.zeros(idx.size)
        dz[i] = hz[i]
        G[i] = (problem.grad_y(embed(z0 + dz)) - problem.grad_y(embed(z0 - dz))) / (2 * hz[i])
    if problem.method in ("ls", "bcls", "wbcls"):
        J = problem.jacobian(x)[:, idx]  # analytic (jitterid.estimation.jacobians)
        H = 2 * J.T @ J
    else:
        # Central differences of the analytic gradient: 2 p evaluations, against ~2 p^2 for
        # second differences of the criterion, and one order of differencing fewer.
        H = np.empty((idx.size, idx.size))
        for i in range(idx.size):
            dz = np.zeros(idx.size)
            dz[i] = hz[i]
            up = problem.objective_gradient(embed(z0 + dz))[1][idx]
            down = problem.objective_gradient(embed(z0 - dz))[1][idx]
            H[:, i] = (up - down) / (2 * hz[i])
        H = 0.5 * (H + H.T)
    if robust is None:
        robust = problem.method == "ls"
    w = (problem.data.y - problem.moments(x).mean) ** 2 if robust else problem.variances(x)
    B = (G * w) @ G.T
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    cov[np.ix_(idx, idx)] = Hinv @ B @ Hinv.T
    return cov


def _ml_covariance(
    problem: Problem,
    x: FloatArray,
    idx: NDArray[np.intp],
    embed: Callable[[FloatArray], FloatArray],
    z0: FloatArray,
    hz: FloatArray,
    robust: bool,
    cov: FloatArray,
) -> FloatArray:
    """Inverse observed information of the exact likelihood (or its Huber-White sandwich)."""
    H = _hessian(lambda z: problem.objective(embed(z)), z0, hz)  # of V = -2 ln L
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    if robust:
        assert problem.likelihood is not None
        g = problem.likelihood.scores(x, problem.data.y)[1][:, idx]
        cov[np.ix_(idx, idx)] = Hinv @ (4 * g.T @ g) @ Hinv.T
    else:
        cov[np.ix_(idx, idx)] = 2 * Hinv
    return cov
