"""The per-sample phase error of a sine record: periodic and coloured jitter, and the RJ/PJ split.

The meter's model has the jitter independent from sample to sample. Test engineers meet two
departures daily: periodic jitter (PJ: a spur on the clock, tau_k = a sin(2 pi f_p kT + c)
/ w) and coloured or accumulated jitter (a PLL's, correlated from sample to sample). Both
show in the per-sample phase error, read from the residual r_k = y_k - E y_k of the fitted
tone A_d sin(phi_k) + c by demodulation (r_k ~ A cos(phi_k) w tau_k + v_k)::

    d_k = 2 r_k cos(phi_k) / A_d  = e_k + e_k cos(2 phi_k) + 2 v_k cos(phi_k) / A_d   (phase)
    q_k = 2 r_k sin(phi_k) / A_d  = e_k sin(2 phi_k) + 2 v_k sin(phi_k) / A_d        (amplitude)

with e_k = w tau_k. A periodic jitter puts a line at f_p in d and none in q (q carries
e_k only shifted to 2 f0 +- f_p); an additive spur at f_s puts lines at f_s +- f0 in both,
of equal power; an amplitude modulation puts none in d at its frequency. So a line of d
whose power in q is under a quarter of its power in d is periodic jitter
(:func:`phase_error_analysis`); its amplitude is the least-squares sine of d at that
frequency, and the random part is what is left of the total variance (the oscilloscope
packages' RJ/PJ decomposition: RJ rms, PJ amplitude and frequency, total).

Independence is tested on d (after the PJ line is taken out) by a heteroscedasticity-robust
portmanteau: with S_l = sum_k d_k d_{k+l} and V_l = sum_k d_k^2 d_{k+l}^2, Q = sum_{l=1}^L
S_l^2 / V_l is chi-square with L degrees of freedom for independent d_k whatever their
variances. A coloured jitter keeps the rms right (the moment route estimates a variance)
but makes the independent-sample interval too narrow; the meter then uses a
Newey-West (Bartlett) covariance (:func:`jitterid.metrology.moments.moment_route`,
``hac_lags``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._format import time_text as _time
from .adequacy import _local_ratio, residual_lines

__all__ = ["ALPHA_WHITE", "JitterDecomposition", "phase_error_analysis", "whiteness"]

FloatArray = NDArray[np.float64]

#: False-alarm probability of the whiteness test on independent jitter (and of the
#: periodic-jitter line test): half the residual-line test's, so that the three tests
#: together flag about 2 % of records of white jitter.
ALPHA_WHITE = 0.005
#: Lags of the portmanteau test (fewer on a short record: N / 20).
WHITE_LAGS = 20


@dataclass(frozen=True)
class JitterDecomposition:
    """The jitter split into its random and periodic parts, and its whiteness.

    Attributes
    ----------
    total_std : float
        The jitter's rms (s), as the meter measured it.
    rj_std : float
        The random part's rms (s): sqrt(total^2 - pj_rms^2), cut at 0.
    pj_amplitude : float
        The periodic part's amplitude (s, peak), 0 when none is found.
    pj_frequency_hz : float
        Its frequency (baseband, Hz), NaN when none is found.
    pj_rms : float
        pj_amplitude / sqrt(2).
    pj_p_value : float
        The line test's p-value for the periodic part (NaN when none is found).
    periodic : bool
        A periodic part is found (p below :data:`ALPHA_WHITE`, and the line is a phase,
        not an amplitude, modulation).
    whiteness_p_value : float
        The portmanteau test's p-value (independent jitter: uniform).
    lag1_autocorrelation : float
        The phase error's lag-1 autocorrelation (after the periodic part).
    coloured : bool
        ``whiteness_p_value < ALPHA_WHITE``: the jitter is correlated from sample to sample.
    decay : float
        The correlation's decay per sample (lag-2 over lag-1 autocorrelation, at least the
        lag-1), for the Newey-West bandwidth.
    hac_lags : int
        The Newey-West bandwidth the meter used for the interval (0: independent samples).
    """

    total_std: float
    rj_std: float
    pj_amplitude: float
    pj_frequency_hz: float
    pj_rms: float
    pj_p_value: float
    periodic: bool
    whiteness_p_value: float
    lag1_autocorrelation: float
    coloured: bool
    decay: float = 0.0
    hac_lags: int = 0

    def summary(self) -> str:
        """One line: RJ rms, PJ amplitude and frequency, total, and the whiteness test."""
        pj = (
            f"PJ {_time(self.pj_amplitude)} peak ({_time(self.pj_rms)} rms) at "
            f"{self.pj_frequency_hz:.6g} Hz (p = {self.pj_p_value:.2g})"
            if self.periodic
            else "no periodic jitter"
        )
        white = (
            f"correlated from sample to sample (lag-1 autocorrelation "
            f"{self.lag1_autocorrelation:.2f}, p = {self.whiteness_p_value:.2g}; interval by "
            f"Newey-West, {self.hac_lags} lags)"
            if self.coloured
            else f"independent (p = {self.whiteness_p_value:.2g})"
        )
        return f"RJ {_time(self.rj_std)} rms, {pj}, total {_time(self.total_std)} rms; {white}"


def whiteness(d: FloatArray, lags: int = WHITE_LAGS) -> tuple[float, float, float]:
    """(p-value, lag-1 autocorrelation, lag-2 autocorrelation) of the robust portmanteau
    test on ``d`` (module doc).

    Parameters
    ----------
    d : ndarray, shape (N,)
        A zero-mean series, independent under the null (its variances may differ).
    lags : int, optional
        Lags tested (at most N / 20).

    Returns
    -------
    (float, float, float)

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> p, r1, _ = whiteness(rng.standard_normal(2000) * np.linspace(0.1, 3, 2000))
    >>> bool(p > 0.01), bool(abs(r1) < 0.1)
    (True, True)
    """
    from scipy.stats import chi2

    n = d.size
    L = max(1, min(int(lags), n // 20))
    dd = d - d.mean()
    d2 = dd * dd
    q = 0.0
    for lag in range(1, L + 1):
        s = float(dd[:-lag] @ dd[lag:])
        v = float(d2[:-lag] @ d2[lag:])
        if v > 0:
            q += s * s / v
    den = float(d2.sum())
    r1 = float(dd[:-1] @ dd[1:]) / den if den > 0 else math.nan
    r2 = float(dd[:-2] @ dd[2:]) / den if den > 0 else math.nan
    return float(chi2.sf(q, L)), r1, r2


def _baseband(f: float, T: float) -> float:
    x = (f * T) % 1.0
    return (1.0 - x if x > 0.5 else x) / T


def phase_error_analysis(
    resid: FloatArray,
    var: FloatArray,
    phase_k: FloatArray,
    damped_amplitude: float,
    frequency_hz: float,
    T: float,
    total_std: float,
) -> tuple[JitterDecomposition, FloatArray]:
    """Periodic and coloured jitter from a fitted tone's residual (module doc).

    Parameters
    ----------
    resid : ndarray, shape (N,)
        y_k - E y_k of the fitted tone.
    var : ndarray, shape (N,)
        The fitted model's Var y_k (jitter and noise).
    phase_k : ndarray, shape (N,)
        The tone's phase 2 pi f kT + phase at each sample, rad.
    damped_amplitude : float
        The fitted sine's amplitude A_d.
    frequency_hz : float
        The tone's frequency f, Hz (the jitter is e / (2 pi f) in s).
    T : float
        Sampling interval, s.
    total_std : float
        The measured jitter rms, s.

    Returns
    -------
    (JitterDecomposition, ndarray)
        The decomposition, and the phase-error series d_k (rad) with the periodic part
        taken out.
    """
    w = 2 * math.pi * frequency_hz
    c1, s1 = np.cos(phase_k), np.sin(phase_k)
    Ad = max(abs(float(damped_amplitude)), 1e-300)
    d = 2.0 * resid * c1 / Ad
    q = 2.0 * resid * s1 / Ad
    sd_d = 2.0 * np.abs(c1) * np.sqrt(np.maximum(var, 0.0)) / Ad
    sd_d = np.maximum(sd_d, 0.25 * float(np.sqrt(np.mean(sd_d**2))) + 1e-300)
    sd_q = 2.0 * np.abs(s1) * np.sqrt(np.maximum(var, 0.0)) / Ad
    sd_q = np.maximum(sd_q, 0.25 * float(np.sqrt(np.mean(sd_q**2))) + 1e-300)
    n = d.size
    lines = residual_lines(d, sd_d, T, frequency_hz, alpha=ALPHA_WHITE, max_lines=4)
    zq = q / sd_q
    zq = zq - zq.mean()
    m = (n - 1) // 2
    pq = np.abs(np.fft.rfft(zq)[1 : m + 1]) ** 2 / n
    q_ratio, _ = _local_ratio(pq) if m > 0 else (pq, pq)
    bin_hz = 1.0 / (n * T)
    pj = None
    for ln in lines:
        j = round(ln.frequency_hz / bin_hz) - 1
        ratio_q = float(np.max(q_ratio[max(j - 1, 0) : j + 2])) if m > 0 else 0.0
        # a phase error periodic with the tone's own period (a line at an alias of h f0) is a
        # function of the phase: harmonic distortion, which the residual-line test names (a
        # clock spur locked to the test tone would look the same in the samples). Taken for
        # PJ, HD2 at -66 and HD3 at -60 dBc on a 12-bit record came out as PJ at f0, their
        # lines as its sidebands, and the jitter CONVERGED at 1.5 x the truth
        # (h = 2 also holds the image at 2 f0 of the cos 2 phi envelope)
        own = ln.harmonic >= 1
        if ratio_q < 0.25 * ln.power_ratio and not own:
            pj = ln
            break
    k = np.arange(n, dtype=float)
    amp, fp, p_pj = 0.0, math.nan, math.nan
    d_white = d
    if pj is not None:
        # d = (1 + cos 2 phi_k) e_k + noise: the periodic part's columns carry that factor;
        # least squares over +- 1 bin for its frequency
        env = 1.0 + (c1 * c1 - s1 * s1)
        best = (-1.0, pj.frequency_hz, np.zeros(3), np.zeros((n, 3)))
        for f in pj.frequency_hz + bin_hz * np.linspace(-1, 1, 21):
            arg = 2 * math.pi * f * T * k
            X = np.column_stack((env * np.cos(arg), env * np.sin(arg), np.ones(n)))
            coef = np.linalg.lstsq(X, d, rcond=None)[0]
            a = math.hypot(float(coef[0]), float(coef[1]))
            if a > best[0]:
                best = (a, f, coef, X)
        amp, fp, coef, X = best
        d_white = d - X @ coef
        p_pj = pj.p_value
    p_white, r1, _ = whiteness(d_white)
    # the correlation's decay, for the Newey-West bandwidth: the phase error's own lag-2 /
    # lag-1 autocorrelation (d_k = (1 + cos 2 phi_k) e_k: each lag's sum is divided by the
    # envelope's, and the white part and the noise, which only add at lag 0, cancel)
    env = 1.0 + (c1 * c1 - s1 * s1)
    acf = [
        float(d_white[:-lag] @ d_white[lag:]) / max(float(env[:-lag] @ env[lag:]), 1e-300)
        for lag in (1, 2)
    ]
    decay = acf[1] / acf[0] if acf[0] > 0 and acf[1] > 0 else max(r1, 0.0)
    pj_amp_s = amp / w
    pj_rms = pj_amp_s / math.sqrt(2.0)
    rj = math.sqrt(max(total_std**2 - pj_rms**2, 0.0)) if math.isfinite(total_std) else math.nan
    dec = JitterDecomposition(
        total_std=float(total_std),
        rj_std=rj,
        pj_amplitude=pj_amp_s,
        pj_frequency_hz=float(fp),
        pj_rms=pj_rms,
        pj_p_value=float(p_pj),
        periodic=pj is not None,
        whiteness_p_value=p_white,
        lag1_autocorrelation=r1,
        coloured=p_white < ALPHA_WHITE,
        decay=float(min(max(decay, r1), 0.98)) if math.isfinite(decay) else 0.0,
    )
    return dec, d_white


def newey_west_lags(n: int, rho: float) -> int:
    """Andrews' (1991) Bartlett bandwidth for an AR(1)-like series of lag-1 correlation rho.

    Parameters
    ----------
    n : int
        Series length.
    rho : float
        Lag-1 autocorrelation.

    Returns
    -------
    int
        At least 1, at most n / 4.
    """
    r = min(abs(float(rho)), 0.99) if math.isfinite(rho) else 0.0
    a1 = 4 * r * r / ((1 - r) ** 2 * (1 + r) ** 2)
    return int(min(max(1, math.ceil(1.1447 * (a1 * n) ** (1 / 3))), n // 4))
