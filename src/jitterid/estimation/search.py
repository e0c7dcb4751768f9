"""The search: one damped Newton (Fisher-scoring) trust-region loop for every criterion that
provides a value, a gradient and an expected Hessian.

Least-squares criteria (``ls``, ``bcls``, ``wbcls``) go to ``scipy.optimize.least_squares``
(see :mod:`jitterid.estimation.fit`); every other criterion goes through
:func:`newton_search`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["damped_step", "evaluator", "newton_search"]

FloatArray = NDArray[np.float64]


def evaluator(
    fun: Callable[[FloatArray], tuple[float, FloatArray, FloatArray]],
) -> Callable[[FloatArray], tuple[float, FloatArray, FloatArray] | None]:
    """Wrap ``fun`` -> (V, g, M) so that a model that cannot be evaluated (ValueError) or a
    non-finite value gives None, which :func:`newton_search` treats as a rejected step."""

    def evaluate(x: FloatArray) -> tuple[float, FloatArray, FloatArray] | None:
        try:
            v, g, M = fun(x)
        except ValueError:  # e.g. an unstable system
            return None
        ok = np.isfinite(v) and np.all(np.isfinite(g)) and np.all(np.isfinite(M))
        return (v, g, M) if ok else None

    return evaluate


def newton_search(
    evaluate: Callable[[FloatArray], tuple[float, FloatArray, FloatArray] | None],
    x0: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    max_nfev: int,
    tol: float = 1e-8,
    smooth: NDArray[np.bool_] | None = None,
) -> tuple[FloatArray, bool, str, int]:
    """Minimise a criterion V by damped Newton (Fisher scoring) inside box bounds.

    ``evaluate(x)`` returns (V, dV/dx, M) with M the expected Hessian of V (or None where V
    cannot be evaluated, e.g. an unstable system): the
    step solves (M + lam diag M) d = -g on the parameters not held at a bound (a parameter on
    its bound whose gradient points outwards is held). lam follows the trust-region rule on
    rho = (actual decrease) / (predicted decrease g.d + d.M.d / 2): divided by 4 when
    rho >= 3/4, multiplied by 4 (at least to 1e-3) when rho < 1/4; a step with rho < 1e-4 is
    rejected. Converged when the Newton decrement g^T M^{-1} g (twice the predicted remaining
    decrease) is below ``tol``. Near the optimum M is within O(1/sqrt(N)) of the Hessian, so
    the search needs a handful of evaluations where L-BFGS-B needed tens.

    ``smooth`` (optional; default None: V is differentiable everywhere) marks the parameters
    in which V is differentiable; V may have kinks in the others (e.g. the exact likelihood
    in the shape n of SumOfUniformsFamily, at integer n), where no damping makes the full
    step acceptable. After a rejected step, an undamped Newton step on the free smooth
    parameters alone is tried (if their decrement exceeds ``tol``). Where those are
    stationary, a rejected full step that was predicted to decrease V by at most
    ``1e-6 max(1, |V|)`` but increased it is taken as a kink: converged, with a message
    saying so (as is exhausted damping with the smooth parameters stationary). With the
    smooth parameters stationary, a decrement of at most ``1e-6 max(1, |V|)`` in all of them
    is convergence too: a search that approaches a kink creeps, halving its distance at each
    step, and this is the precision to which the exact likelihood's quadrature is checked.

    Returns
    -------
    x, converged, message, evaluations
    """

    x = np.clip(np.asarray(x0, float), lo, hi)
    first = evaluate(x)
    if first is None:
        return x, False, "the criterion cannot be evaluated at the start", 1
    v, g, M = first
    n, lam = 1, 0.0
    while n < max_nfev:
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        dec = float(-g @ damped_step(M, g, free, 0.0))
        if dec <= tol:
            return x, True, f"converged: Newton decrement {dec:.2g} <= {tol:g}", n
        if smooth is not None and dec <= 1e-6 * max(1.0, abs(v)):
            dec_s = float(-g @ damped_step(M, g, free & smooth, 0.0))
            if dec_s <= tol:
                msg = (
                    f"converged: Newton decrement {dec_s:.2g} <= {tol:g} in the smooth "
                    f"parameters and {dec:.2g} <= 1e-6 |V| in all (the others may sit at a kink)"
                )
                return x, True, msg, n
        d = np.clip(x + damped_step(M, g, free, lam), lo, hi) - x
        pred = float(-(g @ d) - 0.5 * d @ M @ d)
        trial = evaluate(x + d) if pred > 0 else None
        n += 1
        gain = v - trial[0] if trial is not None else -np.inf
        lam = lam / 4 if gain >= 0.75 * pred else lam
        lam = lam if gain >= 0.25 * pred else max(4 * lam, 1e-3)
        if trial is not None and gain >= 1e-4 * pred:
            x = x + d
            v, g, M = trial
            continue
        if smooth is not None:
            inner = free & smooth
            dec_s = float(-g @ damped_step(M, g, inner, 0.0))
            if dec_s > tol and n < max_nfev:  # a Newton step in the smooth parameters alone
                d = np.clip(x + damped_step(M, g, inner, 0.0), lo, hi) - x
                pred_s = float(-(g @ d) - 0.5 * d @ M @ d)
                trial = evaluate(x + d) if pred_s > 0 else None
                n += 1
                if trial is not None and v - trial[0] >= 1e-4 * pred_s:
                    x = x + d
                    v, g, M = trial
                    continue
            elif (gain < 0 and pred <= 1e-6 * max(1.0, abs(v))) or lam > 1e8:
                msg = (
                    f"converged: stationary in the smooth parameters (decrement {dec_s:.2g}) "
                    "and no descent in the others, where the criterion is not differentiable "
                    "(e.g. SumOfUniformsFamily at integer n)"
                )
                return x, True, msg, n
        if lam > 1e8:
            return x, False, "no step decreases the criterion (damping exhausted)", n
    return x, False, f"evaluation budget ({max_nfev}) used up", n


def damped_step(M: FloatArray, g: FloatArray, free: NDArray[np.bool_], lam: float) -> FloatArray:
    """-(M + lam diag M)^{-1} g on the free parameters, zero elsewhere (scaled Cholesky)."""
    step = np.zeros_like(g)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return step
    Mf = M[np.ix_(idx, idx)]
    scale = np.sqrt(np.abs(np.diag(Mf)))
    scale[scale == 0] = 1.0
    A = Mf / np.outer(scale, scale) + (lam + 1e-12) * np.eye(idx.size)
    try:
        L = np.linalg.cholesky(A)
        step[idx] = -np.linalg.solve(L.T, np.linalg.solve(L, g[idx] / scale)) / scale
    except np.linalg.LinAlgError:  # not positive definite: a scaled gradient step
        step[idx] = -g[idx] / scale**2 / (1.0 + lam)
    return step
