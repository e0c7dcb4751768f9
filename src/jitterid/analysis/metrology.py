"""What the jitter meter's figures show, computed: the residual variance against the phase.

:func:`jitter_phase_profile` bins the squared residuals of a :class:`~jitterid.
JitterMeasurement`'s fitted sine by the sine's phase, the plot test engineers read jitter
from: the noise alone gives a flat variance sigma_v^2, jitter adds (2 pi f A sigma)^2
cos^2(phase) (largest at the zero crossings, where the slope is steepest). The model's
curve is binned the same way, so measurement and model are compared bin by bin.
:func:`jitterid.plots.plot_jitter_phase` draws it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import real_array
from ..metrology.meter import JitterMeasurement
from ..moments.sample import sample_moments

__all__ = ["JitterPhaseProfile", "jitter_phase_profile"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class JitterPhaseProfile:
    """The residual variance of a sine record, binned by the fitted sine's phase.

    Attributes
    ----------
    edges : ndarray, shape (bins + 1,)
        Phase bin edges, radians, from 0 to 2 pi; the phase of sample k is
        (2 pi f kT + phase_rad) mod 2 pi, so the sine is A sin(phase) + offset.
    centers : ndarray, shape (bins,)
        Bin centres, radians.
    count : ndarray of int, shape (bins,)
        Samples per bin.
    resid_var, resid_var_stderr : ndarray, shape (bins,)
        Mean of the squared residuals (y_k - E y_k)^2 in each bin and its standard error
        (sample std / sqrt(count)); NaN for a bin with too few samples (none, or one for
        the standard error).
    model_var : ndarray, shape (bins,)
        The fitted model's Var y_k = Var s(kT + tau) + sigma_v^2, binned the same way.
    noise_var : float
        sigma_v^2, the noise-only level.
    """

    edges: FloatArray
    centers: FloatArray
    count: NDArray[np.int64]
    resid_var: FloatArray
    resid_var_stderr: FloatArray
    model_var: FloatArray
    noise_var: float


def jitter_phase_profile(
    measurement: JitterMeasurement, y: ArrayLike, bins: int = 32
) -> JitterPhaseProfile:
    """Bin the squared residuals of ``measurement``'s fit to ``y`` by the sine's phase.

    Parameters
    ----------
    measurement : JitterMeasurement
        From :func:`jitterid.measure_jitter` on ``y``.
    y : array_like, shape (N,)
        The record that was measured.
    bins : int
        Phase bins over one period (at least 1).

    Returns
    -------
    JitterPhaseProfile

    Notes
    -----
    The residuals are taken from the model's mean E y_k = E s(kT + tau) (the sine damped
    by the jitter's characteristic function), so that their expected square is the model's
    Var y_k exactly; both come from one call of :func:`jitterid.sample_moments`.
    """
    if not isinstance(measurement, JitterMeasurement):
        raise TypeError(
            f"measurement must be a JitterMeasurement; got {type(measurement).__name__}"
        )
    if isinstance(bins, bool) or not isinstance(bins, int | np.integer) or bins < 1:
        raise ValueError(f"bins must be an integer >= 1; got {bins!r}")
    yv = real_array(y, "y", ndim=1)
    N, T = yv.size, measurement.T
    mom = sample_moments(measurement.fit.signal(), measurement.law, T, N)
    resid2 = (yv - np.asarray(mom.mean, dtype=float)) ** 2
    noise_var = float(measurement.noise_std) ** 2
    model = np.asarray(mom.var, dtype=float) + noise_var
    two_pi = 2 * math.pi
    phase = np.mod(
        two_pi * measurement.frequency * T * np.arange(N) + measurement.phase_rad, two_pi
    )
    idx = np.minimum((phase / two_pi * bins).astype(np.int64), bins - 1)
    count = np.bincount(idx, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.bincount(idx, resid2, minlength=bins) / count
        model_mean = np.bincount(idx, model, minlength=bins) / count
        dev2 = np.bincount(idx, (resid2 - mean[idx]) ** 2, minlength=bins)
        stderr = np.where(count > 1, np.sqrt(dev2 / np.maximum(count - 1, 1) / count), np.nan)
    edges = np.linspace(0.0, two_pi, bins + 1)
    return JitterPhaseProfile(
        edges=edges,
        centers=0.5 * (edges[:-1] + edges[1:]),
        count=count,
        resid_var=np.where(count > 0, mean, np.nan),
        resid_var_stderr=stderr,
        model_var=np.where(count > 0, model_mean, np.nan),
        noise_var=noise_var,
    )
