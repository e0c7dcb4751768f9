"""Is the record one jittered tone? The jitter meter's model-adequacy checks.

A meter that fits "one sine, white jitter, white noise" to any record returns a number for
any record. These checks say when the record is not what the model assumes, so that the
number is not reported as a measurement (:func:`jitterid.measure_jitter` turns each
finding into its status and message). Each is a test with a stated false-alarm rate on
records that *are* one jittered tone:

- :func:`tone_significance`: does a tone stand out of the record at all? The F test of the
  three-parameter sine fit against the offset alone, Bonferroni-corrected for the
  frequency having been chosen among the record's N/2 periodogram bins;
- :func:`folding_check`: does the tone's baseband alias sit within one record-bin of DC or
  of the Nyquist frequency (a tone at a multiple of fs/2), or are its samples on phases
  where its slope cannot vary (a coherent fs/4), so that jitter is not told from noise?
- :func:`rail_check`: are samples piled on the record's extreme values (a clipped sine: the
  converter's rails), far beyond what the fitted model puts there?
- :func:`residual_lines`: are there spectral lines in the residual beyond the fitted tone
  and harmonics (a second tone, distortion, clipping, a spur)? The residual is normalised
  by the model's own per-sample std (jitter makes it heteroscedastic), and its periodogram's
  largest ordinate is tested against the maximum of M exponential ordinates (Fisher's
  g-test in its large-N form), line after line.

Finding a line is not always a failure: periodic jitter puts phase-modulation sidebands
around the tone. :func:`jitterid.metrology.phase.phase_error_analysis` classifies them;
the meter calls both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ALPHA_LINES",
    "ALPHA_TONE",
    "Finding",
    "SpectralLine",
    "dither_finding",
    "folding_check",
    "quantisation_step",
    "rail_check",
    "residual_lines",
    "tone_significance",
]

FloatArray = NDArray[np.float64]

#: False-alarm probability of the residual-line test on a record that is one jittered tone.
ALPHA_LINES = 0.01
#: Significance level of the tone test (a p-value above it: no tone stands out).
ALPHA_TONE = 1e-3
#: p-value below which samples piled on a rail are called clipping.
ALPHA_RAIL = 1e-4
#: Highest harmonic a line is named after (beyond it nearly every bin is some harmonic's).
MAX_HARMONIC = 10
#: Neighbours on either side that a periodogram ordinate is compared with.
LOCAL_BINS = 16
#: :func:`folding_check`: the smallest spread of cos 2 phi_k over the samples, at the
#: tone's worst phase, with which the variance profile tells jitter from noise (0.5 where
#: the phases cover the period; the jitter's error grows as sqrt(0.5 / spread): 2.2x here)
MIN_PROFILE_SPREAD = 0.1
#: Most lines :func:`residual_lines` reports.
MAX_LINES = 8


@dataclass(frozen=True)
class Finding:
    """One way the record departs from "one jittered tone".

    Attributes
    ----------
    kind : str
        ``"no-tone"``, ``"folding"``, ``"clipping"``, ``"lines"``, ``"periodic-jitter"``,
        ``"coloured-jitter"``, ``"sharp-edges"`` (:mod:`jitterid.metrology.edges`),
        ``"undithered"`` (:func:`dither_finding`) or ``"stderr"``.
    p_value : float
        The test's p-value (NaN for a deterministic finding such as folding).
    message : str
        What was found and what to do, in words.
    """

    kind: str
    p_value: float
    message: str


#: Noise before the quantiser (in steps) below which its error is not Gaussian to the fit.
DITHER_STEPS = 0.5


def dither_finding(step: float | None, noise_std: float) -> Finding | None:
    """A finding (kind ``"undithered"``) where a quantised record's noise before its
    quantiser, ``sqrt(noise_std^2 - step^2 / 12)``, is below :data:`DITHER_STEPS` of a step
    and the fit modelled the quantiser's error as Gaussian noise (the moment route, and the
    generic likelihood of a tone with harmonics; the structured likelihood of a pure tone,
    also with small harmonics held, models the bins:
    :mod:`jitterid.metrology.sinelik_kernel`): the error is then a uniform-like function of
    the signal, and the jitter comes out biased by an amount that does not shrink with the
    record's length while the stated error does. None for a float record (``step`` None)
    and above that dither.

    Measured (plain numpy records, 1 GS/s, a 97.1 MHz tone at 0.95 of full scale, 2 ps
    Gaussian jitter, 12 bits, 0.2 steps of noise before the quantiser, N = 2^16, 16
    records; the error against each record's realised jitter, in stated errors): the
    moment route (``method="gaussian"``) -0.23 (-0.08 %, 13 of 16 intervals covering the
    truth); the likelihood with Gaussian noise -1.28 (-0.43 %, 8 of 16); with the bins
    modelled -0.1 (session 22). With 0.6 steps, or the same total noise as Gaussian in
    floating point, none resolved.

    Parameters
    ----------
    step : float or None
        The record's quantisation step (:func:`quantisation_step`), None for a float record.
    noise_std : float
        The fitted noise std (the quantiser's error included), in the record's units.
    """
    if not step or not math.isfinite(noise_std):
        return None
    thermal = math.sqrt(max(noise_std**2 - step**2 / 12.0, 0.0)) / step
    if thermal >= DITHER_STEPS:
        return None
    return Finding(
        "undithered",
        math.nan,
        f"the record is quantised (step {step:.4g}) with about {round(thermal, 2):g} steps of "
        f"noise before its quantiser, below {DITHER_STEPS:g}: its error is then not the "
        "Gaussian noise this fit models, which biases the jitter by an amount that does not "
        "shrink with the record's length (12-bit records at 2 ps with 0.2 steps, N = 2^16: "
        "the moment route 0.2 stated errors low, a Gaussian-noise likelihood 1.3), so read "
        "the interval as too narrow; the exact likelihood under the default laws "
        "(method='ml', small harmonics held) models the bins, and more dither (0.5 steps of "
        "noise or more) removes the bias",
    )


@dataclass(frozen=True)
class SpectralLine:
    """A line in the normalised residual's periodogram.

    Attributes
    ----------
    frequency_hz : float
        The line's frequency (baseband, 0..1/(2T)), Hz.
    power_ratio : float
        Its periodogram ordinate over the mean of its neighbours' (near 1 without a line).
    p_value : float
        The probability that the largest of the remaining ordinates is this large without
        a line.
    harmonic : int
        h when the line sits within 1.5 bins of the alias of h f0 (2 <= h <= 10; 1 for the
        tone itself), else 0.
    amplitude : float
        The line's amplitude in units of y (from the raw residual's DFT at that bin).
    """

    frequency_hz: float
    power_ratio: float
    p_value: float
    harmonic: int
    amplitude: float


def _baseband(f: float, T: float) -> float:
    """The alias of ``f`` in [0, 1/(2T)]."""
    x = (f * T) % 1.0
    return (1.0 - x if x > 0.5 else x) / T


def quantisation_step(y: FloatArray) -> float | None:
    """The record's quantisation step, where its values lie on a grid; None otherwise.

    The smallest gap between distinct values, or a divisor of it up to 8, such that every
    gap is a whole multiple of it (to 1e-3 of a step). A float record from a simulator has
    no such grid; a converter's codes scaled to volts have one.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The record.

    Returns
    -------
    float or None

    Examples
    --------
    >>> import numpy as np
    >>> y = np.round(1000 * np.sin(np.arange(500) * 0.123)) / 1024
    >>> quantisation_step(y) == 1 / 1024
    True
    >>> quantisation_step(np.sin(np.arange(500) * 0.123)) is None
    True
    """
    vals = np.unique(np.asarray(y, dtype=float))
    if vals.size < 3:
        return None
    gaps = np.diff(vals)
    span = float(vals[-1] - vals[0])
    q0 = float(np.min(gaps))
    if not q0 > 1e-12 * span:
        return None
    for k in range(1, 9):
        q = q0 / k
        if span / q > 2**26:  # finer than any converter: not a grid
            return None
        ratio = gaps / q
        if float(np.max(np.abs(ratio - np.round(ratio)))) < 1e-3:
            return q
    return None


def tone_significance(y: FloatArray, residual_ss: float, n_params: int = 4) -> float:
    """p-value of "no tone": the F test of a sine fit against the offset alone.

    ``F = ((SS0 - SS1) / 3) / (SS1 / (N - n_params))`` with SS0 the sum of squares about the
    mean and SS1 the sine fit's residual sum of squares, referred to F(3, N - n_params) and
    multiplied by N/2, the bins the frequency was chosen among (Bonferroni). Below
    :data:`ALPHA_TONE` a tone stands out.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The record.
    residual_ss : float
        The sine fit's residual sum of squares.
    n_params : int
        Parameters of the sine fit (4: amplitude, phase, frequency, offset).

    Returns
    -------
    float
        The corrected p-value, in [0, 1].
    """
    from scipy.stats import f as f_dist

    n = y.size
    ss0 = float(np.sum((y - y.mean()) ** 2))
    ss1 = max(float(residual_ss), 1e-300 * max(ss0, 1e-300))
    dof = max(n - n_params, 1)
    stat = ((ss0 - ss1) / 3.0) / (ss1 / dof)
    if stat <= 0:
        return 1.0
    p = float(f_dist.sf(stat, 3, dof))
    return min(1.0, p * max(n // 2, 1))


def folding_check(frequency_hz: float, T: float, N: int) -> Finding | None:
    """A tone whose samples cannot show jitter: near DC or Nyquist, or on phases where its
    slope does not vary.

    The tone's baseband alias is within one record-bin (1/(NT)) of DC or of the Nyquist
    frequency (the tone sits on a multiple of fs/2, e.g. at fs): the sample phases do not
    spread over the period, and amplitude, offset, noise and jitter are not told apart. Or
    the samples' variance profile cannot tell jitter from noise whatever the tone's phase:
    the jitter's share of a sample's variance goes with cos 2 phi_k, and the spread of
    cos(2 phi_k + 2 phi) over the samples, at its smallest over phi, is below
    :data:`MIN_PROFILE_SPREAD` (a coherent tone at fs/4: its four phases have slopes of
    equal size at phi = pi/4, spread 0). A coherent tone at fs/3, fs/5, fs/6, fs/7 has the
    spread of phases covering the period (0.5) and is measured (until session 26 every
    tone on fewer than 8 of 16 phase bins was refused: 1 GHz at 7 GS/s among them, which
    the moment route measured with 11 of 12 intervals covering).

    Parameters
    ----------
    frequency_hz : float
        The tone's frequency, Hz (any alias).
    T : float
        Sampling interval, s.
    N : int
        Record length.

    Returns
    -------
    Finding or None
    """
    fb = _baseband(frequency_hz, T)
    nyq = 0.5 / T
    cycles_dc, cycles_nyq = fb * N * T, (nyq - fb) * N * T
    alias = "" if abs(fb - frequency_hz) < 1e-9 * nyq else f" (its baseband alias is {fb:.6g} Hz)"
    fix = (
        "choose a test frequency away from the multiples of fs/2 = "
        f"{nyq:.6g} Hz, coherent f = J/(N T) with J odd and prime to N, e.g. J = "
        f"{_good_bin(N)}"
    )
    if cycles_dc < 1.0 or cycles_nyq < 1.0:
        edge = "DC" if cycles_dc < cycles_nyq else "the Nyquist frequency"
        return Finding(
            "folding",
            math.nan,
            f"the tone at {frequency_hz:.6g} Hz{alias} lies within one record-bin of {edge} "
            f"(a multiple of fs/2): its samples repeat nearly the same phases, so the jitter "
            f"cannot be told from amplitude, offset and noise; {fix}",
        )
    spread = _profile_spread(fb, T, N)
    if spread < MIN_PROFILE_SPREAD:
        return Finding(
            "folding",
            math.nan,
            f"the tone at {frequency_hz:.6g} Hz{alias} is sampled at phases where its slope "
            f"hardly varies (the spread of cos 2 phi over the samples is {spread:.2g} at the "
            "tone's worst phase, 0.5 where the phases cover the period; coherent at a simple "
            f"fraction of fs such as fs/4): jitter cannot be told from noise; {fix}",
        )
    return None


def _profile_spread(fb: float, T: float, N: int) -> float:
    """min over phi of the variance of cos(2 phi_k + 2 phi) over k < N, phi_k = 2 pi fb kT:
    1/2 + Re(e^{2 i theta} m4) / 2 - Re(e^{i theta} m2)^2 at theta = 2 phi, m_j the mean of
    e^{i j phi_k} (geometric sums in closed form; a grid of 256 theta over the period)."""
    step = 4 * math.pi * math.fmod(fb * T, 1.0)  # 2 phi_{k+1} - 2 phi_k

    def mean_phasor(d: float) -> complex:
        # (1 / N) sum_k e^{i d k}, k < N
        z = complex(math.cos(d), math.sin(d))
        if abs(z - 1) < 1e-12:
            return 1.0 + 0j
        zn = complex(math.cos(d * N), math.sin(d * N))
        return (1 - zn) / (N * (1 - z))

    m2 = mean_phasor(step)
    m4 = mean_phasor(2 * step)
    theta = np.linspace(0.0, 2 * math.pi, 256, endpoint=False)
    var = 0.5 + 0.5 * np.real(np.exp(2j * theta) * m4) - np.real(np.exp(1j * theta) * m2) ** 2
    return float(max(np.min(var), 0.0))


def _good_bin(N: int) -> int:
    """An odd bin count near N/10 that is prime to N (a coherent test frequency)."""
    j = max(3, N // 10) | 1
    while math.gcd(j, N) != 1:
        j += 2
    return j


def rail_check(
    y: FloatArray, step: float | None, mean: FloatArray, sd: FloatArray
) -> Finding | None:
    """Samples piled on the record's extreme values: a clipped record.

    A clipped sine's fit puts its tops beyond the rail, where no sample is (and its noise
    std grows to hold the flattened tops). So the test looks at the samples whose model
    mean lies beyond the record's maximum (minimum) by more than one of the model's std's
    plus half a quantisation step (1e-9 of the span for a float record): on a record that
    is one jittered tone there are (almost) none, since the record's extremes lie beyond
    the jittered sine's mean; where there are, each sits on the rail with probability
    Phi(-1) at most under the model. Five or more such samples on the rail, 3 times the
    model's expectation and with a Poisson tail probability below :data:`ALPHA_RAIL`, is a
    rail.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The record.
    step : float or None
        Its quantisation step (:func:`quantisation_step`), None for a float record.
    mean, sd : ndarray, shape (N,)
        The fitted model's per-sample mean and std (noise included).

    Returns
    -------
    Finding or None
    """
    from scipy.stats import norm, poisson

    hi, lo = float(np.max(y)), float(np.min(y))
    tol = 0.5 * step if step else 1e-9 * (hi - lo)
    sd = np.maximum(sd, 1e-300)
    worst: tuple[float, str, int, float, int] | None = None
    for name, level, sign in (("top", hi, 1.0), ("bottom", lo, -1.0)):
        beyond = sign * (mean - level) > sd + tol
        if int(np.sum(beyond)) < 5:
            continue
        on_rail = beyond & (np.abs(y - level) <= tol)
        count = int(np.sum(on_rail))
        if count < 5:
            continue
        z = (sign * (level - mean[beyond]) + tol) / sd[beyond]
        expected = float(np.sum(norm.cdf(z)))
        p = float(poisson.sf(count - 1, max(expected, 1e-12)))
        if p < ALPHA_RAIL and count >= 3 * expected and (worst is None or p < worst[0]):
            worst = (p, name, count, expected, int(np.sum(np.abs(y - level) <= tol)))
    if worst is None:
        return None
    p, name, count, expected, total = worst
    level = hi if name == "top" else lo
    return Finding(
        "clipping",
        p,
        f"{total} samples sit on the record's {name} value {level:.6g}, {count} of them where "
        f"the fitted sine lies clearly beyond it (it expects {expected:.3g} there, p = "
        f"{p:.2g}): the record is clipped (the converter's rail). Lower the tone's "
        "amplitude below full scale and record again; a clipped sine's flattened tops are "
        "not jitter",
    )


def _local_ratio(power: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Each ordinate over the mean of its LOCAL_BINS neighbours on either side (the two
    nearest on each side left out, where a line leaks), and how many there were."""
    m = power.size
    c = np.concatenate(([0.0], np.cumsum(power)))
    j = np.arange(m)

    def window(a: NDArray[np.int64], b: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        a, b = np.clip(a, 0, m), np.clip(b, 0, m)
        return c[b] - c[a], (b - a).astype(float)

    s1, k1 = window(j - 2 - LOCAL_BINS, j - 2)
    s2, k2 = window(j + 3, j + 3 + LOCAL_BINS)
    k = k1 + k2
    mean = (s1 + s2) / np.maximum(k, 1.0)
    return power / np.maximum(mean, 1e-300), k


def residual_lines(
    resid: FloatArray,
    sd: FloatArray,
    T: float,
    f0: float,
    *,
    alpha: float = ALPHA_LINES,
    max_lines: int = MAX_LINES,
    step: float | None = None,
) -> tuple[SpectralLine, ...]:
    """Spectral lines in the residual that the model does not have.

    The residual r_k = y_k - E y_k is divided by the model's per-sample std (floored at a
    quarter of its rms, so that samples the model claims to know almost exactly, the
    tone's peaks on a noise-free record, do not dominate); each periodogram ordinate
    P_j = |sum_k z_k exp(-2 pi i j k / N)|^2 / N, j = 1..floor((N - 1)/2), is divided by
    the mean of its K = 2 x :data:`LOCAL_BINS` neighbours (the nearest two on each side
    left out), so that a coloured background (a phase-noise skirt, coloured noise) is
    not a line; without a line the ratio is F(2, 2K), P(F > x) = (1 + x/K)^(-K), exactly
    for Gaussian ordinates. The smallest of the M tail probabilities is a line where
    1 - (1 - p_min)^M < ``alpha``; it is then taken out and the next is tested among the
    M - 1 left, up to ``max_lines``.

    Parameters
    ----------
    resid : ndarray, shape (N,)
        y_k minus the fitted model's mean.
    sd : ndarray, shape (N,)
        The model's per-sample std (jitter and noise).
    T : float
        Sampling interval, s.
    f0 : float
        The fitted tone's frequency, Hz (to name harmonics).
    alpha : float, optional
        False-alarm probability of the first line.
    max_lines : int, optional
        Most lines reported.
    step : float, optional
        The record's quantisation step: a line below half a step is the quantiser's own
        distortion (the rounding error of an undithered tone is periodic: lines at its
        harmonics, folded anywhere), not a defect of the record, and is passed over.

    Returns
    -------
    tuple of SpectralLine
        Strongest first; empty when none is significant.
    """
    n = resid.size
    rms = float(np.sqrt(np.mean(sd**2)))
    if not rms > 0:
        return ()
    z = resid / np.maximum(sd, 0.25 * rms)
    z = z - z.mean()
    m = (n - 1) // 2
    if m < 4 * LOCAL_BINS:
        return ()
    power = np.abs(np.fft.rfft(z)[1 : m + 1]) ** 2 / n
    ratio, dof = _local_ratio(power)
    # P(F(2, 2K) > x) = (1 + x / K)^(-K): the ordinate over the mean of K neighbours
    logp = -dof * np.log1p(ratio / dof)
    raw = np.abs(np.fft.rfft(resid)[1 : m + 1]) * 2 / n
    order = np.argsort(logp)
    fb0 = _baseband(f0, T)
    bin_hz = 1.0 / (n * T)
    out: list[SpectralLine] = []
    taken: list[int] = []
    tested = 0
    for j in order:
        if len(out) >= max_lines:
            break
        if any(abs(int(j) - i) <= 3 for i in taken):
            continue  # the leakage of a line already found (a non-coherent line spreads)
        pj = math.exp(float(logp[j]))
        left = m - tested
        tested += 1
        p = -math.expm1(left * math.log1p(-pj)) if pj < 1 else 1.0
        if p >= alpha:
            break
        taken.append(int(j))
        if step and raw[j] < 0.5 * step:
            continue  # the quantiser's own distortion
        f = (j + 1) * bin_hz
        harmonic = 0
        for h in range(1, MAX_HARMONIC + 1):
            if abs(_baseband(h * fb0, T) - f) <= 1.5 * bin_hz:
                harmonic = h
                break
        out.append(SpectralLine(f, float(ratio[j]), p, harmonic, float(raw[j])))
    return tuple(out)
