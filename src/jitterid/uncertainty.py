"""Confidence bands on the fitted frequency response |G(i 2 pi f)|.

Two routes from the estimate x and its covariance C (``FitResult.cov``, the system
parameters' block):

- ``"delta"`` (default): linearise the magnitude, se(f)^2 = J C J^T with
  J = d|G(i 2 pi f; theta)| / d theta by central differences (relative step 1e-6); the band
  is |G| -+ z se, z the normal quantile of ``level``, the lower edge clipped at 0.
- ``"sampling"``: draw theta^(r) ~ N(x, C) (draws outside the structure's bounds are
  discarded), and take the (1 - level)/2 and (1 + level)/2 quantiles of |G(theta^(r))|.
  It needs no linearisation, so where the two differ the delta band is not to be trusted.

Both are as honest as C: for ``ml`` the inverse observed information, for the moment
estimators the sandwich covariance (:mod:`jitterid.sandwich`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from ._checks import count, generator, real_array
from .result import FitResult
from .structures import ModelStructure

__all__ = ["MagnitudeBand", "magnitude_band"]

FloatArray = NDArray[np.float64]


class MagnitudeBand(NamedTuple):
    """|G(i 2 pi f)| at the estimate and a confidence band, one value per frequency."""

    magnitude: FloatArray
    lower: FloatArray
    upper: FloatArray


def _system_block(result: FitResult) -> tuple[ModelStructure, slice]:
    structure = result.structure
    if not isinstance(structure, ModelStructure):
        raise TypeError(
            "result.structure must be the fitted ModelStructure; this result has none; use a FitResult from jitterid.fit "
            "(which records it), or build one with structure=..."
        )
    ns = len(structure.param_names)
    start = len(result.names) - ns - (1 if result.names[-1:] == ("noise_std",) else 0)
    block = slice(start, start + ns)
    if result.names[block] != structure.param_names:
        raise ValueError(
            f"result.names {result.names} do not hold the structure's parameters "
            f"{structure.param_names}; the result and its structure do not match"
        )
    return structure, block


def magnitude_band(
    result: FitResult,
    f: ArrayLike,
    level: float = 0.95,
    *,
    method: str = "delta",
    draws: int = 4000,
    rng: np.random.Generator | int | None = None,
) -> MagnitudeBand:
    """Confidence band on |G(i 2 pi f)| of a fitted model (module docstring).

    Parameters
    ----------
    result : FitResult
        A fit from :func:`jitterid.fit` (it records the structure and the covariance).
    f : array_like
        Frequencies in Hz.
    level : float
        Confidence level in (0, 1).
    method : {"delta", "sampling"}
        Linearisation, or quantiles over parameter draws from N(x, cov).
    draws : int
        Number of parameter draws for ``"sampling"``.
    rng : numpy.random.Generator or int
        Source of randomness, required for ``"sampling"``.

    Returns
    -------
    MagnitudeBand
        ``(magnitude, lower, upper)``, arrays shaped like ``f``; NaN where the covariance is
        not available (a parameter on a bound); zero width for a known system.
    """
    if not isinstance(result, FitResult):
        raise TypeError(
            f"result must be a FitResult from jitterid.fit; got {type(result).__name__}"
        )
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), e.g. 0.95; got {level!r}")
    if method not in ("delta", "sampling"):
        raise ValueError(f"method must be 'delta' or 'sampling'; got {method!r}")
    freqs = np.atleast_1d(real_array(f, "f")).astype(float)
    structure, block = _system_block(result)
    theta = result.x[block]
    mag = np.abs(result.system.freqresp(freqs))
    if theta.size == 0:
        return MagnitudeBand(mag, mag.copy(), mag.copy())
    C = result.cov[block, block]
    if not np.all(np.isfinite(C)):
        nan = np.full_like(mag, np.nan)
        return MagnitudeBand(mag, nan, nan.copy())
    if method == "delta":
        J = np.empty((freqs.size, theta.size))
        lo, hi = np.array(structure.bounds, dtype=float).reshape(-1, 2).T
        for i in range(theta.size):
            h = 1e-6 * max(abs(float(theta[i])), 1e-3)
            c = float(np.clip(theta[i], lo[i] + h, hi[i] - h))
            up, down = theta.copy(), theta.copy()
            up[i], down[i] = c + h, c - h
            g_up = np.abs(structure.system(up).freqresp(freqs))
            g_down = np.abs(structure.system(down).freqresp(freqs))
            J[:, i] = (g_up - g_down) / (2 * h)
        se = np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", J, C, J), 0.0))
        z = float(stats.norm.ppf(0.5 + level / 2))
        return MagnitudeBand(mag, np.maximum(mag - z * se, 0.0), mag + z * se)
    gen = generator(rng, "rng")
    draws = count(draws, "draws", minimum=100)
    samples = gen.multivariate_normal(theta, C, size=draws, method="eigh")
    values = []
    for th in samples:
        try:
            values.append(np.abs(structure.system(th).freqresp(freqs)))
        except ValueError:  # outside the structure's bounds
            continue
    if len(values) < 0.9 * draws:
        raise ValueError(
            f"only {len(values)} of {draws} parameter draws lie inside the structure's bounds: "
            "the normal approximation is poor here; use method='delta' with care"
        )
    q = np.quantile(np.array(values), [0.5 - level / 2, 0.5 + level / 2], axis=0)
    return MagnitudeBand(mag, q[0], q[1])
