"""Converter figures of a sine record (IEEE Std 1241): SNR, SINAD, ENOB, THD, SFDR, the noise
floor, the jitter-limited SNR, and the two-frequency separation of aperture jitter from noise.

How they are computed (coherent and non-coherent records alike)
---------------------------------------------------------------
Every power figure comes from **least-squares sine fits in the time domain** (IEEE 1241
sections 4.1.4 and 4.5), not from a windowed spectrum, so a record need not hold a whole
number of periods and no window's leakage or noise bandwidth enters:

- the *fundamental fit*: ``a cos(w t) + b sin(w t) + c`` at the tone's frequency ``f``
  (given, or the IEEE 1057 four-parameter fit's); its residual is the noise and distortion,
  ``NAD``;
- the *harmonic fit*: the same with ``cos(h w t), sin(h w t)`` for ``h = 2..harmonics``
  (HD2-HD5 by default) added; a harmonic is fitted only where its alias in ``[0, fs/2]`` lies
  at least one bin (``1 / (N T)``) from DC, from Nyquist, from the fundamental's and from an
  earlier harmonic's alias (otherwise it cannot be told from them: it is listed with a NaN
  amplitude and stays in the noise); the residual of this fit is the noise.

With ``P1 = A1**2 / 2`` the fundamental's power (``A1`` the fitted amplitude), the mean
squares ``NAD**2 = mean(r_1**2)`` and ``noise**2 = mean(r_H**2)`` of the two residuals
(IEEE 1241's 1/N) and ``A_h`` the fitted harmonic amplitudes:

- ``SINAD = 10 log10(P1 / NAD**2)``, ``SNR = 10 log10(P1 / noise**2)``;
- ``THD = 10 log10(sum_h A_h**2 / A1**2)`` over the fitted harmonics (its noise bias,
  about ``4 noise**2 / N`` per harmonic in ``A_h**2``, is not removed: each harmonic's
  ``p_value`` says whether it is above the noise);
- ``ENOB = log2(FSR / (sqrt(12) NAD))`` (IEEE 1241 4.5.4), with ``FSR`` the converter's
  full-scale range (peak to peak); without it the tone is taken as full scale
  (``FSR = 2 A1``), which equals ``(SINAD - 1.76) / 6.02``;
- ``SFDR = 20 log10(A1 / largest spur)``, the spur being the largest fitted harmonic or the
  largest line in the harmonic fit's residual. That line is *located* on the residual's
  periodogram (no window is needed: the tone and its harmonics are already removed, so
  nothing large leaks; a line within 1 bin, or 2 on a non-coherent record, of DC or of the
  tone is not searched) and, on a non-coherent record, *measured* at the local maximum of
  ``2 |sum r e^(-i w t)| / N`` between the bins, so scalloping does not bias it. Without
  spurs the largest line is the noise's largest.
- the noise floor: the noise's one-sided spectral density relative to the carrier,
  ``10 log10(noise**2 / (P1 fs / 2))`` dBc/Hz (and in dBFS/Hz with ``FSR``);
- the jitter-limited SNR: ``-20 log10(2 pi f sigma_j)``, the SNR a full-scale tone at ``f``
  would have if the measured jitter ``sigma_j`` were the only error (the aperture-jitter
  limit), with its interval from the jitter's; and the SNR without the jitter, ``10
  log10((A**2 / 2) / sigma_v**2)`` from the jitter meter's own fit (its undamped amplitude
  ``A`` and additive noise std ``sigma_v``).

Harmonics matter for the jitter: distortion left in a pure-sine fit is counted as noise and
jitter. :func:`significant_harmonics` gives the highest harmonic that stands above the
noise, for :func:`jitterid.measure_jitter`'s ``harmonics``; the figures say when a
measurement fitted fewer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive, real_array
from .sinefit import periodogram_peak, sine_fit_4


class JitterMeasurement(Protocol):
    """What the figures read of a :class:`jitterid.metrology.meter.JitterMeasurement` (a
    protocol here: the meter, above this module, builds on the figures)."""

    @property
    def amplitude(self) -> float: ...
    @property
    def frequency(self) -> float: ...
    @property
    def jitter_std(self) -> float: ...
    @property
    def noise_std(self) -> float: ...
    @property
    def fit(self) -> Any: ...

    def interval(self, level: float = ...) -> tuple[float, float]: ...


__all__ = [
    "ApertureSeparation",
    "ConverterFigures",
    "Harmonic",
    "converter_figures",
    "separate_aperture_jitter",
    "significant_harmonics",
]

FloatArray = NDArray[np.float64]

#: Harmonics fitted by default (HD2..HD5).
DEFAULT_HARMONICS = 5
#: A harmonic is significant when its p-value (against the noise) is below this, over the
#: number of harmonics tried (Bonferroni).
SIGNIFICANCE = 1e-3
_MIN_SAMPLES = 16


@dataclass(frozen=True)
class Harmonic:
    """One harmonic of the tone, fitted by least squares.

    Attributes
    ----------
    order : int
        ``h`` (2 for HD2, ...).
    frequency_hz : float
        ``h f``.
    alias_hz : float
        Where it falls in ``[0, fs/2]``.
    amplitude : float
        Fitted amplitude (units of y); NaN where it cannot be told from DC, Nyquist, the
        fundamental or an earlier harmonic (``separable`` False).
    dbc : float
        ``20 log10(amplitude / A1)``.
    p_value : float
        Chance of an amplitude this large from the noise alone (``exp(-N A**2 / (4
        noise**2))``, the chi-square law of two nearly orthogonal coefficients).
    significant : bool
        ``p_value`` below ``SIGNIFICANCE / (harmonics - 1)``.
    separable : bool
        Whether it was fitted (see ``amplitude``).
    """

    order: int
    frequency_hz: float
    alias_hz: float
    amplitude: float
    dbc: float
    p_value: float
    significant: bool
    separable: bool


@dataclass(frozen=True, eq=False)
class ConverterFigures:
    """IEEE 1241 figures of a sine record (see the module notes for every definition).

    Attributes
    ----------
    frequency_hz : float
        The tone's frequency used.
    amplitude : float
        The fundamental fit's amplitude ``A1`` (units of y).
    offset : float
        Its offset.
    snr_db, sinad_db, thd_db, sfdr_db : float
        Decibels; THD is negative (below the carrier).
    enob_bits : float
        Effective number of bits (from ``full_scale`` if given, else the tone as full scale).
    nad_rms, noise_rms : float
        Root mean squares of the fundamental fit's and of the harmonic fit's residuals.
    noise_floor_dbc_hz : float
        The noise's spectral density relative to the carrier, dBc/Hz.
    noise_floor_dbfs_hz : float
        The same relative to a full-scale sine, dBFS/Hz (NaN without ``full_scale``).
    amplitude_dbfs : float
        The tone's level, dBFS (NaN without ``full_scale``).
    full_scale : float or None
        The converter's full-scale range (peak to peak, units of y), if given.
    spur_hz : float
        Frequency (in ``[0, fs/2]``) of the largest spur, the one SFDR is set by.
    spur_is_harmonic : int
        Its harmonic order, or 0 for a non-harmonic line (or the noise's largest bin).
    harmonics : tuple of Harmonic
        HD2.. as fitted.
    coherent : bool
        Whether the record holds a whole number of periods (within 0.01): then the
        spurs are read on the bins.
    cycles : float
        Periods in the record, ``f N T``.
    N : int
        Samples.
    T : float
        Sampling interval (s).
    jitter_std_s : float
        The jitter std the jitter-limited SNR is computed from (NaN if none was given).
    jitter_limited_snr_db : float
        ``-20 log10(2 pi f jitter_std_s)`` (NaN without a jitter; inf for zero jitter).
    jitter_limited_snr_interval_db : (float, float)
        Its range over the jitter's 95 % interval (NaN without one).
    snr_without_jitter_db : float
        The SNR with the jitter removed: the jitter meter's amplitude and additive noise
        std (NaN without a measurement; inf when that noise std is 0).
    notes : tuple of str
        What the figures rest on that a reader should know (harmonics not fitted by the
        jitter fit, harmonics that cannot be separated, ...).
    """

    frequency_hz: float
    amplitude: float
    offset: float
    snr_db: float
    sinad_db: float
    enob_bits: float
    thd_db: float
    sfdr_db: float
    nad_rms: float
    noise_rms: float
    noise_floor_dbc_hz: float
    noise_floor_dbfs_hz: float
    amplitude_dbfs: float
    full_scale: float | None
    spur_hz: float
    spur_is_harmonic: int
    harmonics: tuple[Harmonic, ...]
    coherent: bool
    cycles: float
    N: int
    T: float
    jitter_std_s: float = math.nan
    jitter_limited_snr_db: float = math.nan
    jitter_limited_snr_interval_db: tuple[float, float] = (math.nan, math.nan)
    snr_without_jitter_db: float = math.nan
    notes: tuple[str, ...] = ()

    @property
    def significant_order(self) -> int:
        """The highest significant harmonic's order (1 when none is)."""
        orders = [h.order for h in self.harmonics if h.significant]
        return max(orders, default=1)

    def summary_lines(self) -> list[str]:
        """The figures as indented report lines (for :meth:`JitterMeasurement.summary`)."""
        lines = ["  converter figures (IEEE 1241, from the sine fits' residuals):"]
        fs = "" if self.full_scale is None else f", full scale {self.full_scale:.6g} p-p"
        lines.append(
            f"    SNR {self.snr_db:.2f} dB   SINAD {self.sinad_db:.2f} dB   ENOB "
            f"{self.enob_bits:.2f} bits{fs}"
        )
        lines.append(
            f"    THD {self.thd_db:.2f} dBc   SFDR {self.sfdr_db:.2f} dB (spur at "
            f"{self.spur_hz:.6g} Hz{_spur_kind(self.spur_is_harmonic)})"
        )
        floor = f"    noise floor {self.noise_floor_dbc_hz:.2f} dBc/Hz"
        if self.full_scale is not None:
            floor += (
                f" = {self.noise_floor_dbfs_hz:.2f} dBFS/Hz (tone at "
                f"{self.amplitude_dbfs:.2f} dBFS)"
            )
        lines.append(floor + f"   noise rms {self.noise_rms:.4g}")
        shown = [h for h in self.harmonics if h.separable]
        if shown:
            lines.append(
                "    harmonics "
                + "  ".join(
                    f"HD{h.order} {h.dbc:.1f} dBc{'*' if h.significant else ''}" for h in shown
                )
                + "  (* above the noise)"
            )
        if math.isfinite(self.jitter_std_s):
            lo, hi = self.jitter_limited_snr_interval_db
            lines.append(
                f"    jitter-limited SNR {self.jitter_limited_snr_db:.2f} dB (95 %: {lo:.2f} .. "
                f"{hi:.2f}) for a full-scale tone at this frequency"
            )
        if not math.isnan(self.snr_without_jitter_db):
            lines.append(f"    SNR without the jitter {self.snr_without_jitter_db:.2f} dB")
        lines.extend(f"    note: {n}" for n in self.notes)
        return lines

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (non-finite numbers as None)."""
        lo, hi = self.jitter_limited_snr_interval_db
        return {
            "frequency_hz": _json(self.frequency_hz),
            "amplitude": _json(self.amplitude),
            "offset": _json(self.offset),
            "snr_db": _json(self.snr_db),
            "sinad_db": _json(self.sinad_db),
            "enob_bits": _json(self.enob_bits),
            "thd_db": _json(self.thd_db),
            "sfdr_db": _json(self.sfdr_db),
            "nad_rms": _json(self.nad_rms),
            "noise_rms": _json(self.noise_rms),
            "noise_floor_dbc_hz": _json(self.noise_floor_dbc_hz),
            "noise_floor_dbfs_hz": _json(self.noise_floor_dbfs_hz),
            "amplitude_dbfs": _json(self.amplitude_dbfs),
            "full_scale": self.full_scale,
            "spur_hz": _json(self.spur_hz),
            "spur_harmonic_order": self.spur_is_harmonic,
            "harmonics": [
                {
                    "order": h.order,
                    "frequency_hz": _json(h.frequency_hz),
                    "alias_hz": _json(h.alias_hz),
                    "amplitude": _json(h.amplitude),
                    "dbc": _json(h.dbc),
                    "p_value": _json(h.p_value),
                    "significant": h.significant,
                    "separable": h.separable,
                }
                for h in self.harmonics
            ],
            "coherent": self.coherent,
            "cycles": _json(self.cycles),
            "jitter_std_s": _json(self.jitter_std_s),
            "jitter_limited_snr_db": _json(self.jitter_limited_snr_db),
            "jitter_limited_snr_interval_db": [_json(lo), _json(hi)],
            "snr_without_jitter_db": _json(self.snr_without_jitter_db),
            "notes": list(self.notes),
        }


def _spur_kind(order: int) -> str:
    return f", HD{order}" if order else ""


def _json(x: float) -> float | None:
    v = float(x)
    return v if math.isfinite(v) else None


def _db(ratio: float) -> float:
    """10 log10(ratio), +inf for a zero denominator's infinite ratio, -inf for 0."""
    if ratio == 0:
        return -math.inf
    if not math.isfinite(ratio):
        return math.inf
    return 10.0 * math.log10(ratio)


# --------------------------------------------------------------------------- fits


def _alias(f: float, T: float) -> float:
    """The frequency in [0, 1/(2T)] that f aliases to when sampled at T."""
    r = (f * T) % 1.0
    return min(r, 1.0 - r) / T


def _plan(f: float, T: float, N: int, harmonics: int) -> tuple[list[int], list[float]]:
    """Which harmonics 2..harmonics can be fitted (their alias at least one bin from DC,
    Nyquist, the fundamental and each earlier fitted one), and every alias."""
    bin_hz = 1.0 / (N * T)
    nyq = 0.5 / T
    taken = [0.0, nyq, _alias(f, T)]
    fitted: list[int] = []
    aliases: list[float] = []
    for h in range(2, harmonics + 1):
        a = _alias(h * f, T)
        aliases.append(a)
        if all(abs(a - b) >= bin_hz for b in taken):
            fitted.append(h)
            taken.append(a)
    return fitted, aliases


def _lsq_tones(
    y: FloatArray, tc: FloatArray, f: float, orders: Sequence[int]
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Least squares of y on [1, cos(h w tc), sin(h w tc) for h in orders] (orders[0] = 1)
    and on its first three columns (the fundamental alone): (coefficients of both,
    residuals of both). The normal equations are summed over chunks, so that a 2^20-sample
    record needs no N x p design in memory at once; the columns are O(1) and nearly
    orthogonal, so they are as accurate as a QR solve here."""
    p = 1 + 2 * len(orders)
    gram = np.zeros((p, p))
    rhs = np.zeros(p)
    chunk = 1 << 16
    w = 2 * np.pi * f
    one = _design(tc, w, orders) if y.size <= chunk else None  # a short record: built once
    for s in range(0, y.size, chunk):
        d = one if one is not None else _design(tc[s : s + chunk], w, orders)
        gram += d.T @ d
        rhs += d.T @ y[s : s + chunk]
    coefs: list[FloatArray] = []
    for q in (3, p):
        g = gram[:q, :q]
        eig = np.linalg.eigvalsh(g)
        if eig[0] <= 1e-10 * eig[-1]:
            raise ValueError(
                "the tone's cosine and sine columns are (nearly) dependent at these instants: "
                "its frequency aliases to DC or to Nyquist (2 f T an integer); choose another "
                "test frequency"
            )
        coefs.append(np.asarray(np.linalg.solve(g, rhs[:q]), dtype=np.float64))
    r1, rh = np.empty_like(y), np.empty_like(y)
    for s in range(0, y.size, chunk):
        d = one if one is not None else _design(tc[s : s + chunk], w, orders)
        r1[s : s + chunk] = y[s : s + chunk] - d[:, :3] @ coefs[0]
        rh[s : s + chunk] = y[s : s + chunk] - d @ coefs[1]
    return coefs[0], coefs[1], r1, rh


def _design(tc: FloatArray, w: float, orders: Sequence[int]) -> FloatArray:
    """Columns [1, cos(h w tc), sin(h w tc) ...]; the harmonics by powers of exp(i w tc)."""
    z1 = np.exp(1j * w * tc)
    d = np.empty((tc.size, 1 + 2 * len(orders)))
    d[:, 0] = 1.0
    zh, h_now = z1, 1
    for i, h in enumerate(orders):
        while h_now < h:
            zh, h_now = zh * z1, h_now + 1
        d[:, 1 + 2 * i] = zh.real
        d[:, 2 + 2 * i] = zh.imag
    return d


def _record(y: ArrayLike, T: float) -> tuple[FloatArray, float]:
    yv = real_array(y, "y", ndim=1)
    if yv.size < _MIN_SAMPLES:
        raise ValueError(
            f"y must hold at least {_MIN_SAMPLES} samples of the sine record; got {yv.size}"
        )
    if np.ptp(yv) == 0:
        raise ValueError("y is constant: a sine record is needed (check the input channel)")
    return yv, positive(T, "T")


def _frequency(y: FloatArray, T: float, frequency: float | None) -> float:
    if frequency is not None:
        return positive(frequency, "frequency")
    f0 = periodogram_peak(y, T)
    fit = sine_fit_4(y, np.arange(y.size) * T, f0, frequency_bounds=(0.0, 0.5 / T))
    if not fit.converged:
        raise ValueError(
            f"the four-parameter sine fit did not converge from {f0:g} Hz ({fit.message}); give "
            "the frequency (frequency=...)"
        )
    return fit.frequency


def _harmonics_arg(harmonics: int) -> int:
    if isinstance(harmonics, bool) or not isinstance(harmonics, (int, np.integer)):
        raise TypeError(f"harmonics must be a whole number >= 1; got {harmonics!r}")
    if not 1 <= harmonics <= 64:
        raise ValueError(f"harmonics must lie in 1..64 (5: HD2-HD5); got {harmonics}")
    return int(harmonics)


@dataclass(frozen=True)
class _Fits:
    """The fundamental and harmonic fits of one record."""

    f: float
    a1: float
    offset: float
    nad2: float
    noise2: float
    resid: FloatArray
    harmonics: tuple[Harmonic, ...]


def _fits(yv: FloatArray, T: float, f: float, harmonics: int) -> _Fits:
    N = yv.size
    t = np.arange(N, dtype=float) * T
    tc = t - 0.5 * (t[0] + t[-1])
    fitted, aliases = _plan(f, T, N, harmonics)
    coef1, coef, r1, rh = _lsq_tones(yv, tc, f, [1, *fitted])
    a1 = math.hypot(coef1[1], coef1[2])
    nad2 = float(np.mean(r1**2))
    noise2 = float(np.mean(rh**2))
    amp = {h: math.hypot(coef[3 + 2 * i], coef[4 + 2 * i]) for i, h in enumerate(fitted)}
    level = SIGNIFICANCE / max(harmonics - 1, 1)
    out = []
    for h, a in zip(range(2, harmonics + 1), aliases, strict=True):
        if h in amp:
            A = amp[h]
            p = math.exp(-N * A**2 / (4 * noise2)) if noise2 > 0 else (0.0 if A > 0 else 1.0)
            dbc = 20 * math.log10(A / a1) if A > 0 else -math.inf
            out.append(Harmonic(h, h * f, a, A, dbc, p, p < level, True))
        else:
            out.append(Harmonic(h, h * f, a, math.nan, math.nan, math.nan, False, False))
    return _Fits(f, a1, float(coef1[0]), nad2, noise2, rh, tuple(out))


def _largest_spur(resid: FloatArray, T: float, f: float, coherent: bool) -> tuple[float, float]:
    """(frequency, amplitude) of the largest line in ``resid`` away from DC and the tone.

    The residual's periodogram locates it (no window: the tone and its harmonics were
    removed in the time domain, so nothing large leaks, and the largest line's own leakage
    stays below it); on a non-coherent record its amplitude is then read at the local
    maximum of ``2 |sum r e^(-i w t)| / N`` (the least-squares amplitude away from DC and
    Nyquist, without the bins' scalloping), climbing by parabolas through three
    frequencies a tenth of a bin apart.
    """
    N = resid.size
    spec = np.abs(np.fft.rfft(resid))
    guard = 1 if coherent else 2
    k_tone = round(_alias(f, T) * N * T)
    mask = np.ones(spec.size, dtype=bool)
    mask[: guard + 1] = False
    mask[max(k_tone - guard, 0) : k_tone + guard + 1] = False
    if not mask.any():
        return math.nan, 0.0
    k = int(np.argmax(np.where(mask, spec, -1.0)))
    edge = k == spec.size - 1 and N % 2 == 0  # the Nyquist bin has no mirror image
    amp = float((1 if edge else 2) * spec[k] / N)
    if coherent or edge:
        return k / (N * T), amp
    t = np.arange(N, dtype=float) * T
    step = 0.1 / (N * T)
    best = (k / (N * T), amp)
    turn = np.exp(-2j * np.pi * step * t)
    for _ in range(6):  # climb to the local maximum (within about half a bin)
        base = resid * np.exp(-2j * np.pi * best[0] * t)
        am = float(2 * abs(np.sum(base * np.conj(turn))) / N)
        ap = float(2 * abs(np.dot(base, turn)) / N)
        den = am - 2 * best[1] + ap
        if den >= 0:
            break
        d = float(np.clip(0.5 * (am - ap) / den, -5.0, 5.0))
        f_new = best[0] + d * step
        a_new = float(2 * abs(np.dot(resid, np.exp(-2j * np.pi * f_new * t))) / N)
        if a_new <= best[1]:
            break
        best = (f_new, a_new)
        if abs(d) < 0.05:
            break
    return _alias(best[0], T), best[1]


def significant_harmonics(
    y: ArrayLike, T: float, frequency: float | None = None, *, harmonics: int = DEFAULT_HARMONICS
) -> int:
    """The highest harmonic of the tone that stands above the noise (1 when none does).

    For :func:`jitterid.measure_jitter`'s ``harmonics``: a distorted tone fitted as a pure
    sine leaves its harmonics in the residual, where they count as noise and jitter.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        Sampling interval (s).
    frequency : float, optional
        The tone's frequency in Hz (default: the IEEE 1057 four-parameter fit's).
    harmonics : int
        The highest order tried (5: HD2-HD5).

    Returns
    -------
    int

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology.converter import significant_harmonics
    >>> t = np.arange(4096) * 1e-3
    >>> y = np.sin(2 * np.pi * 97.3 * t) + 1e-3 * np.sin(2 * np.pi * 3 * 97.3 * t)
    >>> significant_harmonics(y + 1e-4 * np.random.default_rng(0).standard_normal(4096), 1e-3)
    3
    """
    yv, T = _record(y, T)
    H = _harmonics_arg(harmonics)
    f = _frequency(yv, T, frequency)
    fits = _fits(yv, T, f, H)
    return max([h.order for h in fits.harmonics if h.significant], default=1)


def converter_figures(
    y: ArrayLike,
    T: float,
    frequency: float | None = None,
    *,
    measurement: JitterMeasurement | None = None,
    full_scale: float | None = None,
    harmonics: int = DEFAULT_HARMONICS,
) -> ConverterFigures:
    """SNR, SINAD, ENOB, THD, SFDR, the noise floor and the jitter-limited SNR of a sine record.

    The definitions (IEEE Std 1241) and how each is computed are in the module notes: the
    power figures from the residuals of least-squares sine fits (the fundamental alone, and
    with HD2..HD\\ ``harmonics``), for coherent and non-coherent records alike (no window);
    the residual's periodogram only locates the largest non-harmonic line for SFDR, whose
    amplitude is then read between the bins on a non-coherent record.

    Parameters
    ----------
    y : array_like, shape (N,)
        The samples at the nominal instants kT.
    T : float
        The nominal sampling interval (s).
    frequency : float, optional
        The tone's frequency in Hz. Default: ``measurement``'s, else the IEEE 1057
        four-parameter fit's (baseband).
    measurement : JitterMeasurement, optional
        The jitter meter's result on this record: its frequency, jitter std and interval
        (for the jitter-limited SNR) and its amplitude and additive noise std (for the SNR
        without the jitter) are used.
    full_scale : float, optional
        The converter's full-scale range, peak to peak, in units of y (e.g. 2.0 for a
        +-1 V converter): ENOB is then IEEE 1241's ``log2(FSR / (sqrt(12) NAD))`` and the
        levels are also given in dBFS. Default: the tone is taken as full scale.
    harmonics : int
        The highest harmonic fitted (5: HD2-HD5; 1: none).

    Returns
    -------
    ConverterFigures

    Raises
    ------
    ValueError
        A record too short, not finite or constant, a frequency on DC or Nyquist, or a
        sine fit that does not converge.

    Examples
    --------
    An ideal 10-bit quantiser's full-scale sine has an ENOB of 10:

    >>> import numpy as np
    >>> from jitterid.metrology.converter import converter_figures
    >>> T, N, f = 1e-6, 8192, 12_345.678
    >>> q = 2.0 / 2**10  # 10 bits over +-1
    >>> y = q * np.round(0.999 * np.sin(2 * np.pi * f * np.arange(N) * T + 0.3) / q)
    >>> fig = converter_figures(y, T, f, full_scale=2.0)
    >>> round(fig.enob_bits, 1)
    10.0
    """
    yv, T = _record(y, T)
    H = _harmonics_arg(harmonics)
    if full_scale is not None:
        full_scale = positive(full_scale, "full_scale")
    if frequency is None and measurement is not None:
        frequency = measurement.frequency
    f = _frequency(yv, T, frequency)
    N = yv.size
    fits = _fits(yv, T, f, H)
    a1, p1 = fits.a1, 0.5 * fits.a1**2
    if not a1 > 0:
        raise ValueError("the fitted tone has no amplitude: check the frequency")
    notes: list[str] = []
    cycles = f * N * T
    coherent = abs(cycles - round(cycles)) < 0.01
    h_power = sum(0.5 * h.amplitude**2 for h in fits.harmonics if h.separable)
    spur_f, spur_a = _largest_spur(fits.resid, T, f, coherent)
    spur_h = 0
    for h in fits.harmonics:
        if h.separable and h.amplitude > spur_a:
            spur_f, spur_a, spur_h = h.alias_hz, h.amplitude, h.order
    fsr = full_scale if full_scale is not None else 2 * a1
    nad = math.sqrt(fits.nad2)
    noise = math.sqrt(fits.noise2)
    fs_power = 0.5 * (0.5 * fsr) ** 2
    lost = [h.order for h in fits.harmonics if not h.separable]
    if lost:
        notes.append(
            "HD" + ", HD".join(map(str, lost)) + " fall(s) within a bin of DC, Nyquist, the tone "
            "or a lower harmonic and cannot be told from it: not fitted, left in the noise"
        )
    if full_scale is not None and 2 * a1 > full_scale * (1 + 1e-9):
        notes.append(
            f"the tone's peak-to-peak {2 * a1:.6g} exceeds the full scale {full_scale:.6g}: "
            "check --full-scale (peak to peak, units of y)"
        )
    jstd, lim, lim_iv, snr_nj = math.nan, math.nan, (math.nan, math.nan), math.nan
    if measurement is not None:
        jstd = float(measurement.jitter_std)
        w = 2 * math.pi * f
        lim = _jitter_snr(w, jstd)
        lo, hi = measurement.interval(0.95)
        lim_iv = (_jitter_snr(w, hi), _jitter_snr(w, lo))
        sv = float(measurement.noise_std)
        if math.isfinite(sv) and sv >= 0:
            snr_nj = _db(0.5 * float(measurement.amplitude) ** 2 / sv**2) if sv > 0 else math.inf
        fitted_h = int(getattr(measurement.fit.structure, "harmonics", 1))
        sig = [h.order for h in fits.harmonics if h.significant and h.order > fitted_h]
        if sig:
            notes.append(
                f"HD{max(sig)} stands above the noise but the jitter fit modelled "
                f"{fitted_h} harmonic(s): the distortion is counted as noise and jitter; "
                f"measure again with harmonics={max(sig)} (--harmonics {max(sig)})"
            )
    return ConverterFigures(
        frequency_hz=f,
        amplitude=a1,
        offset=fits.offset,
        snr_db=_db(p1 / fits.noise2) if fits.noise2 > 0 else math.inf,
        sinad_db=_db(p1 / fits.nad2) if fits.nad2 > 0 else math.inf,
        enob_bits=math.log2(fsr / (math.sqrt(12.0) * nad)) if nad > 0 else math.inf,
        thd_db=_db(h_power / p1),
        sfdr_db=20 * math.log10(a1 / spur_a) if spur_a > 0 else math.inf,
        nad_rms=nad,
        noise_rms=noise,
        noise_floor_dbc_hz=_db(fits.noise2 / (p1 * 0.5 / T)),
        noise_floor_dbfs_hz=_db(fits.noise2 / (fs_power * 0.5 / T))
        if full_scale is not None
        else math.nan,
        amplitude_dbfs=_db(p1 / fs_power) if full_scale is not None else math.nan,
        full_scale=full_scale,
        spur_hz=spur_f,
        spur_is_harmonic=spur_h,
        harmonics=fits.harmonics,
        coherent=coherent,
        cycles=cycles,
        N=N,
        T=T,
        jitter_std_s=jstd,
        jitter_limited_snr_db=lim,
        jitter_limited_snr_interval_db=lim_iv,
        snr_without_jitter_db=snr_nj,
        notes=tuple(notes),
    )


def _jitter_snr(w: float, sigma: float) -> float:
    """-20 log10(w sigma): the SNR of a full-scale tone whose only error is the jitter."""
    if not math.isfinite(sigma):
        return math.nan
    if sigma <= 0:
        return math.inf
    return -20.0 * math.log10(w * sigma)


# --------------------------------------------------------------------------- two frequencies


@dataclass(frozen=True)
class ApertureSeparation:
    """Aperture jitter and additive noise from records at two (or more) tone frequencies.

    Attributes
    ----------
    jitter_std_s, jitter_std_stderr_s : float
        The aperture jitter std and its standard error (delta method; NaN at 0).
    jitter_interval_s : (float, float)
        95 % interval of the jitter std (from the variance's interval, cut at 0: one-sided
        when the jitter is not resolved).
    noise_std, noise_std_stderr : float
        The additive noise std (units of y) and its standard error.
    frequencies_hz, amplitudes, noise_rms : tuple of float
        Per record: the tone's frequency, fitted amplitude and noise rms (harmonics removed).
    resolved : bool
        Whether the jitter variance is more than 2 standard errors above 0.
    message : str
        What the separation rests on, and why it is not resolved where it is not.
    """

    jitter_std_s: float
    jitter_std_stderr_s: float
    jitter_interval_s: tuple[float, float]
    noise_std: float
    noise_std_stderr: float
    frequencies_hz: tuple[float, ...]
    amplitudes: tuple[float, ...]
    noise_rms: tuple[float, ...]
    resolved: bool
    message: str


def separate_aperture_jitter(
    records: Sequence[ArrayLike],
    T: float | Sequence[float],
    frequencies: Sequence[float | None] | None = None,
    *,
    harmonics: int = DEFAULT_HARMONICS,
) -> ApertureSeparation:
    """Aperture jitter vs additive noise from sine records at two or more tone frequencies.

    The IEEE 1241 two-frequency method: the noise power (harmonics removed) of a record of
    a tone of amplitude ``A_i`` at ``f_i`` is ``sigma_v**2 + (2 pi f_i A_i)**2 sigma_j**2 /
    2`` (the jitter's error is the tone's slope times the jitter, whose mean square over a
    period is half the peak), so records at a low and a high frequency give the additive
    noise ``sigma_v`` and the aperture jitter ``sigma_j`` by a weighted least-squares line
    (two records: the exact solution). Linearised in the jitter: valid for ``2 pi f
    sigma_j << 1`` (the relative error in the jitter variance is about ``(2 pi f
    sigma_j)**2 / 2``), and law-free there. The standard errors come from each record's
    mean square, ``var(r**2) / N``.

    Parameters
    ----------
    records : sequence of array_like
        Two or more records of the same converter at different tone frequencies (the
        further apart, the better: the jitter shows as the difference).
    T : float or sequence of float
        The sampling interval (s), one for all or one per record.
    frequencies : sequence of float or None, optional
        Each record's tone frequency in Hz (None: the IEEE 1057 four-parameter fit's).
    harmonics : int
        The highest harmonic removed from each record's noise (5: HD2-HD5).

    Returns
    -------
    ApertureSeparation

    Raises
    ------
    ValueError
        Fewer than two records, lengths that do not match, or tones too close in slope
        (``(f A)**2`` equal within 5 %).

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology.converter import separate_aperture_jitter
    >>> rng = np.random.default_rng(3)
    >>> T, N = 1e-9, 1 << 15
    >>> def record(f):
    ...     t = np.arange(N) * T + 2e-12 * rng.standard_normal(N)  # 2 ps aperture jitter
    ...     return np.sin(2 * np.pi * f * t) + 1e-4 * rng.standard_normal(N)
    >>> sep = separate_aperture_jitter([record(1.1e6), record(401.3e6)], T)
    >>> round(sep.jitter_std_s * 1e12, 1), round(sep.noise_std * 1e4, 2)
    (2.0, 1.0)
    """
    recs = list(records)
    if len(recs) < 2:
        raise ValueError(
            f"records must hold at least two sine records (a low and a high tone); got {len(recs)}"
        )
    Ts = [T] * len(recs) if np.ndim(T) == 0 else list(T)  # type: ignore[arg-type]
    fr = [None] * len(recs) if frequencies is None else list(frequencies)
    if len(Ts) != len(recs) or len(fr) != len(recs):
        raise ValueError(
            f"T and frequencies must give one value per record ({len(recs)} records); got "
            f"{len(Ts)} and {len(fr)}"
        )
    H = _harmonics_arg(harmonics)
    fs, amps, n2, v2, k = [], [], [], [], []
    for i, (y, Ti, fi) in enumerate(zip(recs, Ts, fr, strict=True)):
        try:
            yv, Tv = _record(y, Ti)  # type: ignore[arg-type]
            f = _frequency(yv, Tv, fi)
            fits = _fits(yv, Tv, f, H)
        except (ValueError, TypeError) as exc:
            raise type(exc)(f"record {i}: {exc}") from None
        r2 = fits.resid**2
        fs.append(f)
        amps.append(fits.a1)
        n2.append(fits.noise2)
        v2.append(float(np.var(r2)) / r2.size)
        k.append(0.5 * (2 * math.pi * f * fits.a1) ** 2)
    kk = np.array(k)
    if kk.max() <= 1.05 * kk.min():
        raise ValueError(
            "the records' slopes (2 pi f A) are nearly equal, so the jitter cannot be told from "
            "the noise: record one tone at a low and one at a high frequency (a ratio of 4 or "
            "more is good)"
        )
    wts = 1.0 / np.maximum(np.array(v2), 1e-300)
    X = np.column_stack((np.ones_like(kk), kk))
    XtW = X.T * wts
    cov = np.linalg.inv(XtW @ X)
    beta = cov @ (XtW @ np.array(n2))
    nv, jv = float(beta[0]), float(beta[1])
    se_n, se_j = (math.sqrt(max(float(cov[i, i]), 0.0)) for i in (0, 1))
    jstd = math.sqrt(max(jv, 0.0))
    sv = math.sqrt(max(nv, 0.0))
    z = 1.959963984540054
    interval = (math.sqrt(max(jv - z * se_j, 0.0)), math.sqrt(max(jv + z * se_j, 0.0)))
    resolved = jv > 2 * se_j
    if resolved:
        msg = "the jitter variance is resolved (more than 2 standard errors above 0)"
    else:
        msg = (
            f"the jitter is not resolved by these records (its variance {jv:.3g} s^2 is within 2 "
            f"standard errors, {se_j:.3g} s^2, of 0): the interval is an upper bound; use a "
            "higher tone or longer records"
        )
    phase = max(2 * math.pi * f * jstd for f in fs)
    if phase > 0.3:
        msg += (
            f"; 2 pi f sigma_j reaches {phase:.2g} rad, where the linearised model is about "
            f"{100 * phase**2 / 2:.0f} % off in the variance: use jitterid.measure_jitter"
        )
    return ApertureSeparation(
        jitter_std_s=jstd,
        jitter_std_stderr_s=se_j / (2 * jstd) if jstd > 0 else math.nan,
        jitter_interval_s=interval,
        noise_std=sv,
        noise_std_stderr=se_n / (2 * sv) if sv > 0 else math.nan,
        frequencies_hz=tuple(fs),
        amplitudes=tuple(amps),
        noise_rms=tuple(math.sqrt(x) for x in n2),
        resolved=resolved,
        message=msg,
    )
