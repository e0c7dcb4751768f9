"""The IEEE Std 1057 / 1241 four-parameter sine fit and its periodogram start.

The public home of these functions is :mod:`jitterid.metrology.sinefit` (with the phase
convention and the limits of the classical methods): they live here, in the systems layer,
because the sine models' starting frequency (:meth:`jitterid.SineWave.start_frequencies`)
is the four-parameter fit at the periodogram's peak, and the systems layer does not import
the metrology layer (``docs/develop.md``, *Layering*). Pure numpy (plus
:mod:`jitterid._checks` for argument checks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive, real_array

__all__ = ["SineFit", "periodogram_peak", "sine_fit_4"]

_MIN_SAMPLES_4 = 5
_MIN_SAMPLES_PERIODOGRAM = 8
_COND_LIMIT = 1e-6  # smallest / largest singular value of the equilibrated design matrix

# --------------------------------------------------------------------------- checks


def _record(y: ArrayLike, minimum: int, name: str = "y") -> NDArray[np.float64]:
    arr = real_array(y, name, ndim=1)
    if arr.size < minimum:
        raise ValueError(
            f"{name} has {arr.size} sample(s); this needs at least {minimum}: record a longer "
            "sine (several periods, hundreds of samples or more for a jitter estimate)"
        )
    if np.ptp(arr) == 0:
        raise ValueError(
            f"{name} is constant (every sample equals {arr[0]:g}): there is no sine to fit; "
            "check that the test signal reaches the converter and is not clipped"
        )
    return arr


def _instants(t: ArrayLike, n: int) -> NDArray[np.float64]:
    arr = real_array(t, "t", ndim=1)
    if arr.size != n:
        raise ValueError(
            f"t has {arr.size} instants but y has {n} samples: pass one nominal instant per "
            "sample, e.g. t = T * np.arange(len(y))"
        )
    if np.ptp(arr) == 0:
        raise ValueError(
            "t has every instant equal: pass the nominal instants, e.g. T * np.arange(len(y))"
        )
    return arr


def _frequency(f: float, name: str) -> float:
    return positive(f, name)


# --------------------------------------------------------------------------- results


@dataclass(frozen=True, eq=False)
class SineFit:
    """A least-squares sine fit ``s(t) = amplitude * sin(2 pi f t + phase) + offset``.

    Attributes
    ----------
    amplitude : float
        ``sqrt(a**2 + b**2)`` (>= 0).
    phase : float
        Radians in ``(-pi, pi]``, referred to ``t = 0``.
    frequency : float
        Hz (the given one for :func:`jitterid.metrology.sinefit.sine_fit_3`, the estimated
        one for :func:`sine_fit_4`).
    offset : float
        The constant ``c``.
    a, b : float
        In-phase (cosine) and quadrature (sine) coefficients: ``a cos(2 pi f t) + b sin(2 pi f
        t) + offset``; ``a = amplitude sin(phase)``, ``b = amplitude cos(phase)``.
    residuals : ndarray
        ``y - s(t)`` at the fitted instants.
    iterations : int
        Frequency updates taken (0 for the three-parameter fit).
    converged : bool
        False when the four-parameter iteration stopped without meeting its tolerance;
        then ``message`` says why and the other fields are those of the last accepted
        frequency.
    message : str
        What happened, in words.
    """

    amplitude: float
    phase: float
    frequency: float
    offset: float
    a: float
    b: float
    residuals: NDArray[np.float64]
    iterations: int
    converged: bool
    message: str

    @property
    def c(self) -> float:
        """The offset (IEEE 1057 names it ``C``)."""
        return self.offset

    @property
    def rms_residual(self) -> float:
        """Root mean square of the residuals (IEEE 1057's ``rms error``)."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    def evaluate(self, t: ArrayLike) -> NDArray[np.float64]:
        """The fitted sine at instants ``t``."""
        tt = np.asarray(t, dtype=float)
        return self.amplitude * np.sin(2 * np.pi * self.frequency * tt + self.phase) + self.offset

    def slope(self, t: ArrayLike) -> NDArray[np.float64]:
        """The time derivative ``s'(t) = 2 pi f amplitude cos(2 pi f t + phase)`` (y / s)."""
        tt = np.asarray(t, dtype=float)
        w = 2 * np.pi * self.frequency
        return w * self.amplitude * np.cos(w * tt + self.phase)


# --------------------------------------------------------------------------- frequency


def periodogram_peak(y: ArrayLike, T: float, *, oversample: int = 8) -> float:
    """Frequency (Hz) of the largest periodogram peak, refined between bins.

    The record's mean is removed, a Hann window applied and the record zero-padded to at
    least ``oversample`` times its length (next power of two); the largest bin other than
    DC is refined by three-point Gaussian interpolation (a parabola through the logarithm
    of the power, exact for a Gaussian peak and within a small fraction of a bin for the
    Hann main lobe). The result is the baseband frequency in ``(0, 1/(2T))``: a sine above
    the Nyquist frequency is returned as its alias. It is meant as the start of
    :func:`sine_fit_4`, which refines it to the least-squares accuracy.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record, N >= 8, finite, not constant.
    T : float
        Sampling interval (s) in seconds (> 0).
    oversample : int, optional
        Zero-padding factor (>= 1).

    Returns
    -------
    float
        The peak frequency in Hz, ``0 < f < 1 / (2 T)``.

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology import periodogram_peak
    >>> t = np.arange(1000) * 1e-3
    >>> y = np.sin(2 * np.pi * 123.4 * t + 0.3)
    >>> round(periodogram_peak(y, 1e-3), 1)
    123.4
    """
    arr = _record(y, _MIN_SAMPLES_PERIODOGRAM)
    T = positive(T, "T")
    if (
        isinstance(oversample, bool)
        or not isinstance(oversample, (int, np.integer))
        or oversample < 1
    ):
        raise ValueError(f"oversample must be an integer >= 1; got {oversample!r}")
    n = arr.size
    nfft = 1 << max(math.ceil(math.log2(n * int(oversample))), 3)
    x = (arr - arr.mean()) * np.hanning(n)
    power = np.abs(np.fft.rfft(x, nfft)) ** 2
    search = power.copy()
    search[0] = -1.0  # exclude DC
    k = int(np.argmax(search))
    delta = 0.0
    if 0 < k < power.size - 1:
        tiny = np.finfo(float).tiny
        lm, l0, lp = np.log(np.maximum(power[k - 1 : k + 2], tiny))
        denom = lm - 2 * l0 + lp
        if denom < 0:
            delta = float(np.clip(0.5 * (lm - lp) / denom, -0.5, 0.5))
    f = (k + delta) / (nfft * T)
    nyquist = 0.5 / T
    return float(min(max(f, np.nextafter(0.0, 1.0)), np.nextafter(nyquist, 0.0)))


# --------------------------------------------------------------------------- fits


def _lsq(design: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Least squares by the normal equations plus one step of iterative refinement.

    The columns must be O(1) (as cos, sin, 1 are). Returns the coefficients and the
    smallest / largest singular value of the design (the square root of the Gram's
    eigenvalue ratio); coefficients are zero when that is below ``_COND_LIMIT``. The sine
    fits' columns are nearly orthogonal over several periods, so this is as accurate as an
    SVD solve and several times faster on long records (N = 10^5).
    """
    gram = design.T @ design
    eig = np.linalg.eigvalsh(gram)
    ratio = math.sqrt(max(float(eig[0]), 0.0) / float(eig[-1]))
    if ratio < _COND_LIMIT:
        return np.zeros(design.shape[1]), ratio
    coef = np.asarray(np.linalg.solve(gram, design.T @ y), dtype=np.float64)
    coef += np.linalg.solve(gram, design.T @ (y - design @ coef))
    return coef, ratio


def _fit3_centered(
    y: NDArray[np.float64], tc: NDArray[np.float64], omega: float
) -> tuple[float, float, float, float]:
    """Least squares ``alpha cos(omega tc) + beta sin(omega tc) + c``; returns
    (alpha, beta, c, ssr)."""
    ph = omega * tc
    design = np.column_stack((np.cos(ph), np.sin(ph), np.ones_like(tc)))
    coef, ratio = _lsq(design, y)
    if ratio < _COND_LIMIT:
        f = omega / (2 * np.pi)
        raise ValueError(
            f"frequency = {f:.10g} Hz makes the cosine and sine columns (nearly) dependent at "
            "these instants: with uniform sampling at interval T it aliases to DC or to the "
            "Nyquist frequency (2 f T is an integer). Choose a test frequency that is not a "
            "multiple of 1/(2T)"
        )
    alpha, beta, c = (float(v) for v in coef)
    res = y - design @ coef
    return alpha, beta, c, float(res @ res)


def _wrap(phase: float) -> float:
    w = math.remainder(phase, 2 * math.pi)  # [-pi, pi]
    return math.pi if w == -math.pi else w


def _result(
    y: NDArray[np.float64],
    t: NDArray[np.float64],
    tm: float,
    omega: float,
    iterations: int,
    converged: bool,
    message: str,
) -> SineFit:
    tc = t - tm
    alpha, beta, c, _ = _fit3_centered(y, tc, omega)
    amplitude = math.hypot(alpha, beta)
    # alpha cos(w tc) + beta sin(w tc) = A sin(w tc + atan2(alpha, beta)); refer to t = 0
    phase = _wrap(math.atan2(alpha, beta) - omega * tm)
    fit = SineFit(
        amplitude=amplitude,
        phase=phase,
        frequency=omega / (2 * np.pi),
        offset=c,
        a=amplitude * math.sin(phase),
        b=amplitude * math.cos(phase),
        residuals=np.empty(0),
        iterations=iterations,
        converged=converged,
        message=message,
    )
    ph = omega * tc
    resid = y - (alpha * np.cos(ph) + beta * np.sin(ph) + c)
    object.__setattr__(fit, "residuals", resid)
    return fit


def sine_fit_4(
    y: ArrayLike,
    t: ArrayLike,
    frequency0: float,
    *,
    tol: float = 1e-9,
    max_iterations: int = 50,
    frequency_bounds: tuple[float, float] = (0.0, math.inf),
) -> SineFit:
    """IEEE Std 1057 / 1241 four-parameter least-squares sine fit (frequency estimated).

    The IEEE iteration: a three-parameter fit at the current frequency gives ``a, b, c``;
    the model linearised in the angular frequency adds the column ``t (-a sin(w t) + b
    cos(w t))``; the four-column least-squares solution gives the new ``a, b, c`` and the
    update ``dw``. Time is centred on the record's midpoint for conditioning (the reported
    phase is referred to ``t = 0``). A step that raises the residual sum of squares is
    halved (up to 30 times), which makes the plain IEEE (Gauss-Newton) iteration robust to a
    start a fraction of a bin off. The iteration converges when a step changes the phase
    at the record's ends by at most ``tol`` radians, ``|dw| * max|t - t_mid| <= tol``.

    It does not raise on failure: the result has ``converged = False`` and ``message`` says
    why -- the update left ``frequency_bounds`` (a start too far from the sine: start from
    :func:`periodogram_peak` or a better known value), no halved step reduced the residual,
    the iteration reached an alias where the sine is not identifiable, or
    ``max_iterations`` ran out. The other fields are then those of the last accepted
    frequency. Check ``converged`` before using the fit.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record, N >= 5, finite, not constant.
    t : array_like, shape (N,)
        Nominal sample instants in seconds.
    frequency0 : float
        Starting frequency in Hz (> 0, inside ``frequency_bounds``), within about one bin
        ``1 / (t[-1] - t[0])`` of the sine's (as :func:`periodogram_peak` gives): further
        off, the iteration can stop on a side lobe of the residual (the message then warns
        that the sine explains little of the record). Above the Nyquist frequency the fit
        stays near that alias (equivalent-time sampling).
    tol : float, optional
        Convergence tolerance in radians of end-of-record phase (> 0).
    max_iterations : int, optional
        Most frequency updates (>= 1).
    frequency_bounds : (float, float), optional
        Open interval in Hz that the frequency must stay in; e.g. ``(0, 1 / (2 * T))`` to
        keep a baseband fit.

    Returns
    -------
    SineFit

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology import periodogram_peak, sine_fit_4
    >>> T = 1e-3
    >>> t = np.arange(1000) * T
    >>> y = 1.5 * np.sin(2 * np.pi * 97.13 * t - 1.0) + 0.2
    >>> fit = sine_fit_4(y, t, periodogram_peak(y, T))
    >>> fit.converged
    True
    >>> print(f"{fit.frequency:.8f} {fit.amplitude:.8f} {fit.phase:.8f}")
    97.13000000 1.50000000 -1.00000000
    """
    arr = _record(y, _MIN_SAMPLES_4)
    tt = _instants(t, arr.size)
    f0 = _frequency(frequency0, "frequency0")
    tol = positive(tol, "tol")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)):
        raise TypeError(f"max_iterations must be an integer; got {max_iterations!r}")
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be at least 1; got {max_iterations}")
    lo, hi = (float(v) for v in frequency_bounds)
    if not (lo >= 0 and hi > lo):
        raise ValueError(
            f"frequency_bounds must be (low, high) with 0 <= low < high; got {frequency_bounds!r}"
        )
    if not lo < f0 < hi:
        raise ValueError(
            f"frequency0 = {f0:g} Hz is outside frequency_bounds ({lo:g}, {hi:g}); start inside "
            "them (e.g. from periodogram_peak(y, T))"
        )
    tm = 0.5 * (float(tt.min()) + float(tt.max()))
    tc = tt - tm
    half_span = float(np.max(np.abs(tc)))
    omega = 2 * np.pi * f0
    alpha, beta, _, ssr = _fit3_centered(arr, tc, omega)
    ones = np.ones_like(tc)
    for it in range(1, int(max_iterations) + 1):
        ph = omega * tc
        cos_, sin_ = np.cos(ph), np.sin(ph)
        amp = math.hypot(alpha, beta)
        if amp <= 1e-12 * float(np.max(np.abs(arr))):
            return _result(
                arr,
                tt,
                tm,
                omega,
                it - 1,
                False,
                f"iteration {it}: the fitted amplitude vanished at {omega / (2 * np.pi):.6g} Hz, "
                "so the frequency cannot be updated: start closer, e.g. from periodogram_peak(y, "
                "T)",
            )
        dscale = half_span * amp  # the frequency column, scaled to O(1)
        design = np.column_stack(
            (cos_, sin_, ones, (tc / half_span) * (-alpha * sin_ + beta * cos_) / amp)
        )
        coef, ratio = _lsq(design, arr)
        if ratio < _COND_LIMIT:
            return _result(
                arr,
                tt,
                tm,
                omega,
                it - 1,
                False,
                f"iteration {it}: the frequency column is (nearly) dependent on the others (the "
                "fitted amplitude vanished): start closer, e.g. from periodogram_peak(y, T)",
            )
        step = float(coef[3]) / dscale
        new = omega + step
        if not 2 * np.pi * lo < new < 2 * np.pi * hi:
            return _result(
                arr,
                tt,
                tm,
                omega,
                it - 1,
                False,
                f"the frequency update at iteration {it} left frequency_bounds ({lo:g}, {hi:g}) "
                f"Hz (to {new / (2 * np.pi):.6g} Hz from {omega / (2 * np.pi):.6g} Hz): start "
                "closer to the sine's frequency, e.g. from periodogram_peak(y, T)",
            )
        accepted = False
        for _ in range(30):
            try:
                a_new, b_new, _, ssr_new = _fit3_centered(arr, tc, new)
            except ValueError as exc:
                return _result(arr, tt, tm, omega, it - 1, False, f"iteration {it}: {exc}")
            if ssr_new <= ssr * (1 + 1e-12) + 1e-300:
                accepted = True
                break
            step *= 0.5
            new = omega + step
        if not accepted:
            if abs(step) * half_span <= tol:
                return _result(arr, tt, tm, omega, it - 1, True, "converged (at the minimum)")
            return _result(
                arr,
                tt,
                tm,
                omega,
                it - 1,
                False,
                f"iteration {it}: no step along the linearised update reduced the residual; the "
                "start is probably on another peak: start from periodogram_peak(y, T)",
            )
        omega, alpha, beta, ssr = new, a_new, b_new, ssr_new
        if abs(step) * half_span <= tol:
            msg = f"converged in {it} iteration(s)"
            explained = 1.0 - ssr / float(np.sum((arr - arr.mean()) ** 2))
            if explained < 0.5:
                msg += (
                    f", but the sine explains only {100 * explained:.0f} % of the record's "
                    "variance: a start far from the sine's frequency stops on a side lobe; "
                    "check frequency0"
                )
            return _result(arr, tt, tm, omega, it, True, msg)
    return _result(
        arr,
        tt,
        tm,
        omega,
        int(max_iterations),
        False,
        f"no convergence in {max_iterations} iterations (last step moved the end-of-record "
        f"phase by {abs(step) * half_span:.3g} rad > tol = {tol:g}); raise max_iterations or tol",
    )
