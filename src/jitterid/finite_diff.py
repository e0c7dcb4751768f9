"""The one finite-difference rule of the package.

Derivatives that have no closed form are taken here: a model structure's coefficient map
when it declares no closed form (:mod:`jitterid.moments.modal`), the moments of a model
that declares no gradient (:mod:`jitterid.estimation.jacobians`), a jitter family's std
(:mod:`jitterid.experiments.runner`), the jittered noise autocovariance
(C1)-(C3) with respect to the noise and jitter-family parameters (whose near lags are
quadratures over the law), the delta-method covariance's d^2 V / d theta dy and
d(gradient)/d theta (:mod:`jitterid.estimation.covariance`,
:func:`jitterid.estimation.bjcriteria.bj_covariance`), and the exact likelihood's
observed information, its jitter-shape scores (:func:`forward`) and its Fisher information
(:func:`central_pair`). :func:`derivative` is a central difference of step
``rel * max(|x_i|, floor)``, or the second-order one-sided rule
(-3 f(x) + 4 f(x + h) - f(x + 2 h)) / (2 h) (and its mirror) where a central step would
leave the bounds; :func:`hessian` the second differences of a scalar function. All are
O(h^2).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["central_pair", "derivative", "forward", "hessian", "step"]

FloatArray = NDArray[np.float64]

REL_STEP = 1e-5  # (eps)^(1/3) ~ 6e-6: balances the O(h^2) error against rounding


def step(x: FloatArray, i: int | np.integer, rel: float = REL_STEP, floor: float = 1e-2) -> float:
    """The step for parameter ``i``: rel * max(|x_i|, floor)."""
    return rel * max(abs(float(x[i])), floor)


def forward(
    x: FloatArray,
    i: int | np.integer,
    bounds: tuple[float, float],
    rel: float,
    floor: float = 1e-2,
) -> tuple[FloatArray, float]:
    """x with x_i moved by a forward step :func:`step` (backward where the upper bound
    forbids), and the signed step: a one-sided (O(h)) difference, for callers that difference
    a costly quantity already evaluated at x (the likelihood's jitter-shape scores, the
    moments' derivatives in a jitter shape)."""
    h = step(x, i, rel, floor)
    if x[i] + h > bounds[1]:
        h = -h
    out = np.array(x, dtype=float)
    out[i] += h
    return out, h


def central_pair(
    x: FloatArray,
    i: int | np.integer,
    bounds: tuple[float, float],
    rel: float,
    h: float | None = None,
) -> tuple[FloatArray, FloatArray, float]:
    """(x + h e_i, x - h e_i, 2 h) with the pair's centre moved inside ``bounds`` where x_i is
    within h of one: for callers that difference many quantities at the same two points
    (the Fisher information (L3)); ``h`` overrides the step."""
    h = step(x, i, rel) if h is None else float(h)
    centre = float(np.clip(x[i], bounds[0] + h, bounds[1] - h))
    xp, xm = np.array(x, dtype=float), np.array(x, dtype=float)
    xp[i], xm[i] = centre + h, centre - h
    return xp, xm, 2 * h


def derivative(
    fun: Callable[[FloatArray], FloatArray],
    x: FloatArray,
    i: int | np.integer,
    bounds: tuple[float, float],
    f0: FloatArray | None = None,
    rel: float = REL_STEP,
    floor: float = 1e-2,
    h: float | None = None,
) -> FloatArray:
    """d fun / d x_i at ``x`` (``fun`` returns an array), O(h^2), never outside ``bounds``.

    ``f0`` = fun(x), if known, saves an evaluation in the one-sided case; ``h`` overrides
    the step (e.g. a fraction of the parameter's standard error, where ``rel * |x_i|`` is
    far beyond the function's scale: a frequency over a long record).
    """
    x = np.asarray(x, dtype=float)
    h = step(x, i, rel, floor) if h is None else float(h)
    lo, hi = bounds

    def at(dx: float) -> FloatArray:
        xs = x.copy()
        xs[i] += dx
        return np.asarray(fun(xs), dtype=float)

    if x[i] - h >= lo and x[i] + h <= hi:
        return (at(h) - at(-h)) / (2 * h)
    side = 1.0 if x[i] + 2 * h <= hi else -1.0
    base = np.asarray(fun(x), dtype=float) if f0 is None else f0
    return side * (-3 * base + 4 * at(side * h) - at(2 * side * h)) / (2 * h)


def hessian(fun: Callable[[FloatArray], float], x: FloatArray, h: FloatArray) -> FloatArray:
    """Second differences of a scalar ``fun`` at ``x`` with steps ``h`` (x +- 2h inside the
    domain): (f(x + 2h e_i) - 2 f(x) + f(x - 2h e_i)) / 4h_i^2 on the diagonal and the
    four-point cross rule off it."""
    p = x.size
    H = np.empty((p, p))
    f0 = fun(x)
    e = np.eye(p) * h
    for i in range(p):
        H[i, i] = (fun(x + 2 * e[i]) - 2 * f0 + fun(x - 2 * e[i])) / (4 * h[i] ** 2)
        for j in range(i):
            H[i, j] = H[j, i] = (
                fun(x + e[i] + e[j])
                - fun(x + e[i] - e[j])
                - fun(x - e[i] + e[j])
                + fun(x - e[i] - e[j])
            ) / (4 * h[i] * h[j])
    return H
