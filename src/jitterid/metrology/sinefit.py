"""Classical sine-wave test methods of IEEE Std 1057 / 1241: sine fits and slope-regression jitter.

A sine-wave test records ``y_k = A sin(2 pi f (k T + tau_k) + phi) + c + v_k`` with an
unknown sampling-time jitter ``tau_k`` and additive noise ``v_k``. The functions here are
the textbook tools, evaluated at the *nominal* instants ``t_k = k T`` (the jitter is
unknown):

- :func:`periodogram_peak` -- a starting frequency from a Hann-windowed, zero-padded
  periodogram with three-point Gaussian interpolation (the baseband alias, in
  ``(0, 1/(2T))``);
- :func:`sine_fit_3` -- the three-parameter least-squares fit at a known frequency
  (IEEE 1057 section 4.1.3.1, IEEE 1241 section 4.1.4.1);
- :func:`sine_fit_4` -- the four-parameter fit, the frequency updated by linearisation
  (IEEE 1057 section 4.1.3.3, IEEE 1241 section 4.1.4.3);
- :func:`slope_regression_jitter` -- the jitter estimate from regressing the squared fit
  residuals on the squared slope of the fitted sine (IEEE 1057 section 4.9, IEEE 1241
  section 4.8 "random jitter").

Phase convention, used everywhere in this module::

    s(t) = amplitude * sin(2 pi f t + phase) + offset
         = a * cos(2 pi f t) + b * sin(2 pi f t) + offset,

so ``a = amplitude * sin(phase)`` (the cosine, "in-phase" coefficient), ``b = amplitude *
cos(phase)`` (the sine, "quadrature" coefficient), ``phase = atan2(a, b)`` in ``(-pi, pi]``,
all referred to ``t = 0``.

The fits accept any positive frequency, also above the Nyquist frequency ``1/(2T)``
(equivalent-time sampling): they only evaluate the sine at the given instants. A frequency
that aliases to DC or to the Nyquist frequency at uniform instants (``2 f T`` an integer)
leaves the cosine and sine columns dependent and is refused.

This module uses numpy only (plus :mod:`jitterid._checks` for argument checks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

# The four-parameter fit and its periodogram start live in the systems layer, where the sine
# models start from them; their public home stays here.
from ..systems._sinefit import (
    SineFit,
    _frequency,
    _instants,
    _record,
    _result,
    periodogram_peak,
    sine_fit_4,
)

__all__ = [
    "SineFit",
    "SlopeRegression",
    "periodogram_peak",
    "sine_fit_3",
    "sine_fit_4",
    "slope_regression_jitter",
]

_MIN_SAMPLES_3 = 4  # three parameters and at least one residual degree of freedom

# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class SlopeRegression:
    """The IEEE 1057 / 1241 slope-regression jitter estimate (see :func:`slope_regression_jitter`).

    Attributes
    ----------
    jitter_std : float
        Seconds: ``sqrt(max(jitter_var, 0))``.
    noise_std : float
        Units of y: ``sqrt(max(noise_var, 0))``.
    jitter_var, noise_var : float
        The regression's slope (s^2) and intercept (y units^2), unclipped (may be negative
        when the jitter is below the regression's resolution).
    jitter_var_stderr, noise_var_stderr : float
        Their heteroscedasticity-consistent (HC0 sandwich) standard errors.
    jitter_std_stderr : float
        Delta-method standard error of ``jitter_std``: ``jitter_var_stderr / (2 jitter_std)``
        (NaN when ``jitter_std`` is 0).
    n : int
        Samples used.
    """

    jitter_std: float
    noise_std: float
    jitter_var: float
    noise_var: float
    jitter_var_stderr: float
    noise_var_stderr: float
    jitter_std_stderr: float
    n: int


# --------------------------------------------------------------------------- fits


def sine_fit_3(y: ArrayLike, t: ArrayLike, frequency: float) -> SineFit:
    """IEEE Std 1057 / 1241 three-parameter least-squares sine fit at a known frequency.

    Solves ``min sum_k (y_k - a cos(2 pi f t_k) - b sin(2 pi f t_k) - c)**2`` (linear least
    squares) and reports it as ``amplitude * sin(2 pi f t + phase) + offset`` (module
    docstring). Any positive ``frequency`` is accepted, also above the Nyquist frequency
    of uniform instants; one that aliases to DC or to Nyquist (``2 f T`` an integer) is
    refused because the sine is not identifiable there.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record, N >= 4, finite, not constant.
    t : array_like, shape (N,)
        The nominal sample instants in seconds (e.g. ``T * np.arange(N)``).
    frequency : float
        The sine's frequency in Hz (> 0).

    Returns
    -------
    SineFit
        ``iterations = 0``, ``converged = True``.

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology import sine_fit_3
    >>> t = np.arange(200) * 1e-3
    >>> y = 2.0 * np.sin(2 * np.pi * 1234.5 * t + 0.5) + 0.1  # above Nyquist (500 Hz)
    >>> fit = sine_fit_3(y, t, 1234.5)
    >>> print(f"{fit.amplitude:.6f} {fit.phase:.6f} {fit.offset:.6f}")
    2.000000 0.500000 0.100000
    """
    arr = _record(y, _MIN_SAMPLES_3)
    tt = _instants(t, arr.size)
    f = _frequency(frequency, "frequency")
    tm = 0.5 * (float(tt.min()) + float(tt.max()))
    return _result(
        arr, tt, tm, 2 * np.pi * f, 0, True, "three-parameter fit at the given frequency"
    )


# --------------------------------------------------------------------------- jitter


def slope_regression_jitter(y: ArrayLike, t: ArrayLike, fit: SineFit) -> SlopeRegression:
    """IEEE Std 1057 / 1241 jitter estimate: squared residuals regressed on the squared slope.

    With jitter ``tau_k`` and noise ``v_k`` the residual of a good sine fit is, to first order
    in the jitter, ``e_k ~ s'(t_k) tau_k + v_k``, so ``E e_k**2 ~ sigma_v**2 + sigma_tau**2
    s'(t_k)**2``. This function fits that line by **ordinary least squares over the
    individual samples** (not binned by phase): ``e_k**2`` on ``[1, s'(t_k)**2]`` with
    ``s'`` the slope of the fitted sine, ``e_k = y_k - s(t_k)``. The intercept estimates the
    noise variance, the slope the jitter variance; standard errors are the HC0 sandwich
    (the ``e_k**2`` are heteroscedastic by construction). Binning by phase, as IEEE 1241
    describes, gives the same line up to the bins' weights.

    Limits, by construction:

    - it linearises in the jitter, valid for ``2 pi f sigma_tau << 1``. For a symmetric
      jitter law, with ``phi_m = E cos(m 2 pi f tau)``, the fitted amplitude shrinks by
      ``phi_1`` and the estimated phase variance ``(2 pi f sigma)**2`` tends to
      ``(phi_1**2 - phi_2) / phi_1**2`` as N grows. For Gaussian jitter that is ``1 -
      exp(-(2 pi f sigma)**2)``: about 6 % low in the standard deviation at 0.5 rad, 20 %
      low at 1 rad (measured: 0.940 and 0.792); for a dual-Dirac law (+-delta) it is
      ``tan(2 pi f delta)**2``, biased *high*; the rest of the residual appears as apparent
      noise;
    - the sine fit removes 3 (or 4) degrees of freedom from the residuals, so both
      variances are biased low by a relative ``O(p / N)`` (no correction is applied);
    - it is a moment method: it ignores the shape of the jitter law and the noise's
      distribution, which an exact likelihood uses.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record the fit was made on.
    t : array_like, shape (N,)
        The nominal instants of the fit.
    fit : SineFit
        A converged fit of ``y`` (:func:`sine_fit_4` when the frequency is estimated).

    Returns
    -------
    SlopeRegression

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology import periodogram_peak, sine_fit_4, slope_regression_jitter
    >>> rng = np.random.default_rng(1)
    >>> T, f, n = 1e-3, 97.13, 100_000
    >>> t = np.arange(n) * T
    >>> tau = rng.normal(0.0, 5e-5, n)  # 2 pi f sigma = 0.03 rad
    >>> y = np.sin(2 * np.pi * f * (t + tau)) + rng.normal(0.0, 1e-3, n)
    >>> fit = sine_fit_4(y, t, periodogram_peak(y, T))
    >>> est = slope_regression_jitter(y, t, fit)
    >>> print(f"{est.jitter_std * 1e6:.1f} +- {est.jitter_std_stderr * 1e6:.1f} us")
    49.9 +- 0.2 us
    """
    arr = _record(y, _MIN_SAMPLES_3)
    tt = _instants(t, arr.size)
    if not isinstance(fit, SineFit):
        raise TypeError(
            f"fit must be a SineFit (from sine_fit_3 / sine_fit_4); got {type(fit).__name__}"
        )
    if not fit.converged:
        raise ValueError(
            f"fit did not converge ({fit.message}); the residuals of an unconverged fit still "
            "contain the sine: fix the fit first (a better frequency0, more iterations)"
        )
    e2 = (arr - fit.evaluate(tt)) ** 2
    g = fit.slope(tt) ** 2
    scale = float(np.max(g))
    if scale == 0 or np.ptp(g) <= 1e-6 * scale:
        raise ValueError(
            "the fitted sine's slope is (nearly) the same at every sample, so the jitter cannot "
            "be told from the noise: sample the sine at spread phases (a non-coherent "
            "frequency, several periods)"
        )
    x = np.column_stack((np.ones_like(g), g / scale))  # scaled for conditioning
    coef = np.linalg.lstsq(x, e2, rcond=None)[0]
    u = e2 - x @ coef
    bread = np.linalg.inv(x.T @ x)
    meat = (x * (u**2)[:, None]).T @ x
    cov = bread @ meat @ bread
    noise_var = float(coef[0])
    jitter_var = float(coef[1]) / scale
    noise_se = float(np.sqrt(max(cov[0, 0], 0.0)))
    jitter_se = float(np.sqrt(max(cov[1, 1], 0.0))) / scale
    jitter_std = math.sqrt(max(jitter_var, 0.0))
    return SlopeRegression(
        jitter_std=jitter_std,
        noise_std=math.sqrt(max(noise_var, 0.0)),
        jitter_var=jitter_var,
        noise_var=noise_var,
        jitter_var_stderr=jitter_se,
        noise_var_stderr=noise_se,
        jitter_std_stderr=jitter_se / (2 * jitter_std) if jitter_std > 0 else math.nan,
        n=int(arr.size),
    )
