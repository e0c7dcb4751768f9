"""Peer jitter estimators for the jitter-meter study (``benchmarks/jitter_meter.py``).

Each takes a sine record ``y`` sampled at nominal interval ``T`` (seconds) and returns the
jitter standard deviation in seconds.

``adctoolbox_jitter`` -- adctoolbox 0.9.1 (PyPI, MIT; a benchmark-only extra: ``pip install
jitterid[bench]``), function ``adctoolbox.analyze_error_by_phase`` (file
``adctoolbox/aout/analyze_error_by_phase.py``, which calls
``adctoolbox/aout/rearrange_error_by_phase.py``). What it computes, read from that source:

1. ``fit_sine_4param(signal, frequency_estimate=norm_freq, max_iterations=1, tolerance=1e-9)``
   (``adctoolbox/fundamentals/fit_sine_4param.py``): a three-parameter LS fit ``A cos(w n) +
   B sin(w n) + C`` at the given normalised frequency (or, when None, an FFT peak with
   parabolic interpolation, rectangular window), then **one** IEEE 1057 four-parameter
   Gauss-Newton update of the frequency (clamped to (1e-10, 0.5 - 1e-10)); it warns
   (RuntimeWarning) when that single update exceeds 1e-9 -- almost always -- and goes on.
   The time axis is ``n = 0..N-1`` (not centred).
2. The residual ``e = y - fit`` and the fit's phase ``phi_n = 2 pi f n + atan2(-B, A)``
   (cosine convention: ``fit = amplitude cos(phi)``).
3. Ordinary least squares over the individual samples of ``e_n**2`` on ``[cos(2 phi_n),
   1]`` giving ``e**2 ~ A2 cos(2 phi) + B2``. If ``A2 < 0`` (errors larger at the zero
   crossings) it reports phase-modulation variance ``pm**2 = -2 A2`` and amplitude-noise
   variance 0; if ``A2 > 0`` it reports ``pm = 0``. So ``pm_noise_rms_v**2`` is the
   coefficient of ``sin(phi)**2`` in ``e**2 ~ base + pm**2 sin(phi)**2``, truncated at 0.
4. ``pm_noise_rms_rad = pm_noise_rms_v / amplitude``.

Since the slope of ``amplitude cos(phi)`` is ``-2 pi f amplitude sin(phi)``, step 3 is the
IEEE 1057 / 1241 slope regression of ``e**2`` on the squared slope, with the same
intercept, and ``pm_noise_rms_rad / (2 pi f0)`` is its jitter std in seconds, clipped at 0
(the ``include_base_noise=True`` default). The binned statistics it also returns (100
phase bins) are only for its plot and its ``r_squared_binned``; they do not enter the
numbers. The differences from :func:`ieee1057_jitter` are thus the single frequency
update, the FFT start without a window, and the clipping (a small jitter below the
regression's resolution reads 0 rather than a negative variance).

``ieee1057_jitter`` -- :mod:`jitterid.metrology.sinefit`: Hann-windowed periodogram peak,
four-parameter fit iterated to convergence, slope regression.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from jitterid.metrology import periodogram_peak, sine_fit_4, slope_regression_jitter

__all__ = ["adctoolbox_jitter", "adctoolbox_version", "ieee1057_jitter"]


def adctoolbox_version() -> str | None:
    """The installed adctoolbox version, or None when it is not installed."""
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return None
    try:
        return version("adctoolbox")
    except PackageNotFoundError:
        return None


def _baseband(frequency: float, T: float) -> float:
    """The alias of ``frequency`` in [0, 1/2] cycles per sample."""
    x = (frequency * T) % 1.0
    return 1.0 - x if x > 0.5 else x


def adctoolbox_jitter(y: np.ndarray, T: float, frequency: float | None = None) -> float:
    """Jitter std (s) from adctoolbox's ``analyze_error_by_phase``:
    ``pm_noise_rms_rad / (2 pi f0)``.

    Parameters
    ----------
    y : ndarray
        The record.
    T : float
        Nominal sampling interval (s).
    frequency : float, optional
        The sine's frequency in Hz, any positive value (its baseband alias is passed to
        adctoolbox, which only accepts (0, 0.5) cycles per sample; the conversion to
        seconds uses this frequency, since the phase noise is ``2 pi f0 tau``). None lets
        adctoolbox find the frequency (its FFT peak and one four-parameter update) and
        converts with that baseband frequency.

    Returns
    -------
    float
        Seconds, >= 0 (adctoolbox clips a negative phase-noise variance to 0).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(20_000)
    >>> y = np.sin(2 * np.pi * 0.1234 * (t + rng.normal(0, 0.05, t.size)))
    >>> round(adctoolbox_jitter(y, 1.0, 0.1234), 2)  # doctest: +SKIP
    0.05
    """
    from adctoolbox import analyze_error_by_phase

    norm = None if frequency is None else _baseband(float(frequency), float(T))
    with warnings.catch_warnings():
        # fit_sine_4param warns whenever its single frequency update exceeds 1e-9
        warnings.simplefilter("ignore", RuntimeWarning)
        res = analyze_error_by_phase(np.asarray(y, dtype=float), norm_freq=norm, create_plot=False)
    f0 = float(frequency) if frequency is not None else float(res["norm_freq"]) / float(T)
    return float(res["pm_noise_rms_rad"]) / (2 * math.pi * f0)


def ieee1057_jitter(y: np.ndarray, T: float, frequency: float | None = None) -> float:
    """Jitter std (s) by IEEE 1057 / 1241: four-parameter fit, then slope regression.

    ``frequency`` (Hz, any positive value, also above Nyquist) starts the four-parameter
    fit; None starts it from :func:`jitterid.metrology.periodogram_peak` (baseband). The
    fit is iterated to convergence; a fit that does not converge raises ValueError.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(20_000)
    >>> y = np.sin(2 * np.pi * 0.1234 * (t + rng.normal(0, 0.05, t.size)))
    >>> round(ieee1057_jitter(y, 1.0), 2)
    0.05
    """
    y = np.asarray(y, dtype=float)
    t = float(T) * np.arange(y.size)
    f0 = periodogram_peak(y, T) if frequency is None else float(frequency)
    fit = sine_fit_4(y, t, f0)
    return slope_regression_jitter(y, t, fit).jitter_std
