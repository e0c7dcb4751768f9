"""The jitter meter: the sampling jitter's std, law and interval from a sine record.

:func:`measure_jitter` fits a :class:`~jitterid.systems.tones.SineWave` with the jitter law
estimated (the JOE structure (2c) with a signal model, the paper's (1a)), by the exact
likelihood (notes 4), for each candidate jitter family, and keeps the family with the
lowest BIC. Starting values, in the order a test engineer trusts them:

1. the frequency: the periodogram's peak refined by the IEEE 1057 four-parameter fit
   (:mod:`jitterid.metrology.sinefit`), or the given one;
2. jitter and noise std's: the IEEE 1057 slope regression of the squared residuals on the
   squared slope; the amplitude divided by the damping exp(-(2 pi f sigma)^2 / 2) that the
   jitter puts on the fitted sine (Lemma 1: E[sin(w (t + tau))] = chi(w) sin(w t));
3. the exact Gaussian criterion (closed-form moments, O(N)), then the exact likelihood.

With a band above the Nyquist frequency (equivalent-time sampling) every alias
f0 + m/T or m/T - f0 in the band is fitted; without jitter they fit the samples equally
well, with jitter each damps the sine by its own |chi(2 pi f)| (the paper's Section 3.4),
and the likelihood ranks them (:attr:`JitterMeasurement.aliases`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive, real_array
from ..data import SampledData
from ..estimation.fit import fit
from ..estimation.likelihood import ExactLikelihood
from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import GaussianFamily, JitterFamily, JitterLaw, UniformFamily
from ..systems.model import Model
from ..systems.tones import SineWave
from .converter import ConverterFigures, converter_figures  # meterio (issue 26, item 3)
from .reading import summary_extras  # meterio (issue 26, item 5)
from .sinefit import periodogram_peak, sine_fit_4, slope_regression_jitter

__all__ = [
    "FAMILY_NAMES",
    "AliasCandidate",
    "JitterMeasurement",
    "LawCandidate",
    "alias_likelihoods",
    "measure_jitter",
]

FloatArray = NDArray[np.float64]

#: Fewest samples and whole periods a record must hold.
MIN_SAMPLES = 32
#: The default noise floor, relative to the record's rms (see measure_jitter, resolution).
_RESOLUTION_FLOOR = 1e-4
#: ln L difference below which two aliases are a tie.
_ALIAS_TIE = 1e-3
#: Families tried by default, by name (see measure_jitter, laws).
DEFAULT_LAWS = ("gaussian", "uniform", "dual-dirac")


def _families(T: float) -> dict[str, JitterFamily]:
    """The jitter families :func:`measure_jitter` knows, by name, bounded by the record's
    own time scale: a jitter std beyond 10 T is not a jitter, and one below 1e-9 T is
    zero (the families' default floor, 1e-12 s, is a real jitter at GHz rates)."""
    lo = 1e-9 * T
    out: dict[str, JitterFamily] = {
        "gaussian": GaussianFamily(sigma_max=10 * T, sigma_min=lo),
        "uniform": UniformFamily(a_max=20 * T, a_min=lo),
    }
    try:  # the regular shape families, where available
        from ..jitter.regular import DualDiracFamily, GeneralizedNormalFamily

        out["generalized-normal"] = GeneralizedNormalFamily(std_max=10 * T, std_min=lo)
        out["dual-dirac"] = DualDiracFamily(rj_max=10 * T, rj_min=lo, dj_max=20 * T)
    except ImportError:  # pragma: no cover - depends on the installed version
        pass
    return out


#: The family names :func:`measure_jitter` accepts in ``laws``.
FAMILY_NAMES = tuple(_families(1.0))


@dataclass(frozen=True)
class LawCandidate:
    """One jitter family fitted to the record.

    Attributes
    ----------
    name : str
        The family's name (``"gaussian"``, ``"uniform"``, ...).
    loglik : float
        The maximised log-likelihood (NaN if the fit failed).
    n_params : int
        Free parameters of the whole model (sine, jitter family, noise std).
    aic, bic : float
        -2 ln L + 2 p and -2 ln L + p ln N.
    jitter_std_s : float
        The fitted law's standard deviation, seconds.
    status : FitStatus
        The fit's status; only a candidate whose status is a success can be chosen.
    """

    name: str
    loglik: float
    n_params: int
    aic: float
    bic: float
    jitter_std_s: float
    status: FitStatus


@dataclass(frozen=True)
class AliasCandidate:
    """One alias of the record's frequency, fitted with the chosen family.

    Attributes
    ----------
    frequency_hz : float
        The fitted frequency.
    loglik : float
        Its maximised log-likelihood.
    jitter_std_s : float
        The jitter std this alias implies.
    """

    frequency_hz: float
    loglik: float
    jitter_std_s: float


@dataclass(frozen=True, eq=False)
class JitterMeasurement:
    """What :func:`measure_jitter` measured. Times in seconds, frequencies in Hz.

    Attributes
    ----------
    jitter_std, jitter_std_stderr : float
        The jitter's standard deviation and its standard error (delta method through the
        chosen family, from the fit's covariance).
    noise_std, noise_std_stderr : float
        The additive noise std (units of y) and its standard error.
    frequency, frequency_stderr : float
        The sine's frequency and its standard error.
    amplitude, phase_rad, offset : float
        The sine, s(t) = amplitude sin(2 pi frequency t + phase_rad) + offset, t = kT.
    law : JitterLaw
        The fitted jitter law of the chosen family.
    family : str
        The chosen family's name (lowest BIC among :attr:`laws`).
    laws : tuple of LawCandidate
        Every family tried.
    aliases : tuple of AliasCandidate
        Every alias fitted (one entry unless a band holds several).
    fit : FitResult
        The chosen fit (parameters, covariance, status).
    status : FitStatus
        The chosen fit's status; anything but CONVERGED says why in :attr:`message`.
    message : str
    slope_regression_std : float
        The IEEE 1057 slope-regression jitter std the search started from (for comparison).
    T : float
        The nominal sampling interval (s).
    converter : ConverterFigures or None
        SNR, SINAD, ENOB, THD, SFDR and the jitter-limited SNR of the record
        (:meth:`with_converter`; None until then).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> rng = np.random.default_rng(0)
    >>> T, N, f = 1e-3, 200, 123.0
    >>> t = np.arange(N) * T + 50e-6 * rng.standard_normal(N)  # 50 us rms jitter
    >>> y = np.sin(2 * np.pi * f * t) + 1e-2 * rng.standard_normal(N)
    >>> m = ji.measure_jitter(y, T, frequency=f, laws=["gaussian"])
    >>> isinstance(m, ji.JitterMeasurement), round(m.frequency, 1)
    (True, 123.0)
    >>> bool(abs(m.jitter_std - 50e-6) < 4 * m.jitter_std_stderr)
    True
    """

    jitter_std: float
    jitter_std_stderr: float
    noise_std: float
    noise_std_stderr: float
    frequency: float
    frequency_stderr: float
    amplitude: float
    phase_rad: float
    offset: float
    law: JitterLaw
    family: str
    laws: tuple[LawCandidate, ...]
    aliases: tuple[AliasCandidate, ...]
    fit: FitResult = field(repr=False)
    status: FitStatus
    message: str
    slope_regression_std: float
    T: float
    converter: ConverterFigures | None = field(default=None, repr=False)  # meterio

    def with_converter(
        self, y: ArrayLike, *, full_scale: float | None = None, harmonics: int = 5
    ) -> JitterMeasurement:
        """This measurement with its converter figures (:mod:`jitterid.metrology.converter`).

        Parameters
        ----------
        y : array_like, shape (N,)
            The record the measurement was made on.
        full_scale : float, optional
            The converter's full-scale range, peak to peak, in units of y.
        harmonics : int
            The highest harmonic fitted for the figures (5: HD2-HD5).
        """
        import dataclasses

        figs = converter_figures(
            y, self.T, measurement=self, full_scale=full_scale, harmonics=harmonics
        )
        return dataclasses.replace(self, converter=figs)

    def interval(self, level: float = 0.95) -> tuple[float, float]:
        """Normal-approximation interval of the jitter std, cut at 0.

        Parameters
        ----------
        level : float, optional
            Coverage, in (0, 1).
        """
        if not 0 < level < 1:
            raise ValueError(f"level must lie in (0, 1); got {level!r}")
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + level / 2))
        lo = self.jitter_std - z * self.jitter_std_stderr
        return (max(lo, 0.0), self.jitter_std + z * self.jitter_std_stderr)

    def summary(self) -> str:
        """A plain-text report: the jitter std with its interval, the law, the sine."""
        lo, hi = self.interval()
        lines = [
            "jitterid jitter measurement",
            f"  status            {self.status.name}: {self.message}",
            (
                f"  jitter std        {_time(self.jitter_std)}  +- "
                f"{_time(self.jitter_std_stderr)}  (95 % interval {_time(lo)} .. {_time(hi)})"
            ),
            f"  jitter law        {self.family}: {self.law}",
            f"  noise std         {self.noise_std:.6g}  +- {self.noise_std_stderr:.3g}",
            f"  frequency         {self.frequency:.10g} Hz  +- {self.frequency_stderr:.3g}",
            f"  amplitude         {self.amplitude:.6g}   offset {self.offset:.6g}",
            f"  2 pi f sigma      {2 * math.pi * self.frequency * self.jitter_std:.4g} rad",
            f"  IEEE 1057 slope regression (start): {_time(self.slope_regression_std)}",
            "  families (lowest BIC chosen):",
        ]
        for c in self.laws:
            mark = "*" if c.name == self.family else " "
            lines.append(
                f"   {mark} {c.name:<20s} ln L = {c.loglik:12.3f}  BIC = {c.bic:12.3f}  "
                f"std = {_time(c.jitter_std_s)}  [{c.status.name}]"
            )
        if len(self.aliases) > 1:
            lines.append("  aliases (highest likelihood chosen):")
            best = max(a.loglik for a in self.aliases)
            for a in self.aliases:
                lines.append(
                    f"     f = {a.frequency_hz:.8g} Hz  ln L = {a.loglik:12.3f}  "
                    f"(ln L - best = {a.loglik - best:9.3f})  std = {_time(a.jitter_std_s)}"
                )
        lines.extend(summary_extras(self))  # meterio: the law's evidence, converter figures
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def _time(x: float) -> str:
    """A time in s with an SI prefix."""
    if not np.isfinite(x):
        return "nan"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9), ("ps", 1e-12)):
        if abs(x) >= scale or unit == "ps":
            return f"{x / scale:.4g} {unit}"
    return f"{x:.4g} s"  # pragma: no cover


def _record(y: ArrayLike) -> FloatArray:
    yv = real_array(y, "y", ndim=1)
    if yv.size < MIN_SAMPLES:
        raise ValueError(
            f"y must hold at least {MIN_SAMPLES} samples of the sine record; got {yv.size}"
        )
    if not np.all(np.isfinite(yv)):
        raise ValueError("y must be finite: remove or interpolate the NaN/inf samples first")
    if float(np.std(yv)) <= 1e-12 * max(1.0, float(np.max(np.abs(yv)))):
        raise ValueError("y is constant: a sine record is needed (check the input channel)")
    return yv


def _start(
    y: FloatArray, T: float, f0: float, band: tuple[float, float]
) -> tuple[FloatArray, float, float, float]:
    """(sine start [A, phase, f, c], jitter std start, noise std start, slope-regression std)."""
    t = np.arange(y.size, dtype=float) * T
    fit4 = sine_fit_4(y, t, f0, frequency_bounds=band)
    if not fit4.converged:
        raise ValueError(
            f"the four-parameter sine fit did not converge from {f0:g} Hz ({fit4.message}); "
            "give the frequency (frequency=...) or check that y is a sine record"
        )
    reg = slope_regression_jitter(y, t, fit4)
    w = 2 * math.pi * fit4.frequency
    resid = float(np.std(fit4.residuals))
    sj = reg.jitter_std if np.isfinite(reg.jitter_std) and reg.jitter_std > 0 else 0.0
    # a jitter that damps the fitted sine by less than ~1e-4 is below what the regression
    # resolves: start from a small value the likelihood can grow from
    sj = max(sj, 1e-3 / w)
    sv = reg.noise_std if np.isfinite(reg.noise_std) and reg.noise_std > 0 else 0.0
    sv = max(sv, 1e-3 * resid, 1e-9 * fit4.amplitude)
    damping = math.exp(-0.5 * (w * sj) ** 2)
    theta = np.array([fit4.amplitude / max(damping, 0.05), fit4.phase, fit4.frequency, fit4.offset])
    return theta, sj, sv, float(reg.jitter_std)


def _fit_one(
    data: SampledData,
    model: Model,
    family: JitterFamily,
    theta: FloatArray,
    sj: float,
    sv: float,
    method: str = "ml",
    other: tuple[FloatArray, float, float] | None = None,
) -> FitResult:
    """The Gaussian criterion from the IEEE starts, then (``method="ml"``) the exact
    likelihood from the better of its end and the IEEE start (by the likelihood itself:
    the second-moment criterion can trade jitter for noise where the law is far from
    Gaussian). With ``other`` (the sine, jitter std and noise std of another family's fit)
    the likelihood is also maximised from there, and the better end kept: a law far from
    the other's can have a local optimum in phase and frequency near it."""
    x0 = np.r_[family.start_for_std(sj), theta, sv]
    gauss = fit(data, model, family, method="gaussian", start=x0)
    if method == "gaussian":
        return gauss
    xg = np.asarray(gauss.x, dtype=float).copy()
    cands = [x0]
    if gauss.success and np.all(np.isfinite(xg)):
        if not xg[-1] > 0.1 * sv:  # the Gaussian criterion put the noise at its bound 0
            xg[-1] = sv
        cands.insert(0, xg)
    lik = ExactLikelihood(model, family, None, data.T, data.N, noise_floor=data.resolution)
    scored: list[tuple[float, int, FloatArray]] = []
    for c in cands:
        try:
            scored.append((-lik.loglik(c, data.y), len(scored), c))
        except ValueError:
            continue
    best = min(scored)[2] if scored else xg
    out = fit(data, model, family, method="ml", start=best)
    if other is not None:
        sine, std, noise = other
        lo = data.resolution or 0.0
        alt = fit(
            data,
            model,
            family,
            method="ml",
            start=np.r_[family.start_for_std(std), sine, max(noise, lo)],
        )
        if np.isfinite(alt.cost) and (not np.isfinite(out.cost) or alt.cost < out.cost):
            out = alt
    return out


def _resolution(y: FloatArray, given: float | None) -> float:
    """The noise floor: ``given``, else the record's quantisation step / sqrt(12), at least
    1e-6 of its rms (see :func:`measure_jitter`)."""
    if given is not None:
        return positive(given, "resolution")
    vals = np.unique(y)
    step = float(np.min(np.diff(vals))) if vals.size > 1 else 0.0
    rms = float(np.sqrt(np.mean((y - np.mean(y)) ** 2)))
    return max(step / math.sqrt(12.0), _RESOLUTION_FLOOR * rms)


def _stderr(result: FitResult, name: str) -> float:
    return float(result.stderr.get(name, float("nan")))


def measure_jitter(
    y: ArrayLike,
    T: float,
    frequency: float | None = None,
    *,
    laws: Sequence[str] = DEFAULT_LAWS,
    band_hz: tuple[float, float] | None = None,
    harmonics: int = 1,
    method: str = "ml",
    resolution: float | None = None,
) -> JitterMeasurement:
    """Measure the sampling jitter from a record of a sine wave.

    Parameters
    ----------
    y : array_like, shape (N,)
        The samples, taken at the nominal instants kT (k = 0..N-1) plus the unknown jitter.
    T : float
        The nominal sampling interval (s), seconds.
    frequency : float, optional
        The sine's frequency in Hz, a start the fit refines (it may lie above the Nyquist
        frequency 1/(2T): equivalent-time sampling). Default: the periodogram's peak
        refined by the IEEE 1057 four-parameter fit (the baseband alias, below 1/(2T),
        unless ``band_hz`` says where to look).
    laws : sequence of str
        Jitter families to fit, among ``"gaussian"``, ``"uniform"``, ``"dual-dirac"``
        (random plus deterministic jitter, the serial-link model) and
        ``"generalized-normal"``; default the first three. The one with the lowest BIC is
        chosen. The law matters even for small jitter once the jitter's spread of the
        samples is above the noise: dual-Dirac records measured with Gaussian and uniform
        families only came out 6 % low (the uniform family chosen), 0.5 % with it.
    band_hz : (float, float), optional
        Where the frequency lies, in Hz; every alias of the record's frequency in the band
        is fitted and the one with the highest likelihood kept (:attr:`JitterMeasurement.
        aliases` lists them all). Without jitter the aliases are indistinguishable.
    harmonics : int
        Harmonics of the sine model (1: a pure sine; more for a distorted source).
    method : {"ml", "gaussian"}
        ``"ml"`` (default): the exact likelihood, at the Cramer-Rao bound; its cost grows
        as N times the quadrature nodes per sample (about 100). ``"gaussian"``: the exact
        Gaussian criterion on the samples' closed-form means and variances (Lemmas 1-2),
        O(N) with a small constant, consistent for any law in the family and close to
        efficient where the jitter's phase spread 2 pi f sigma is small (the samples are
        then nearly Gaussian); its errors are the exact sandwich. For long records. It fits
        the first of ``laws`` only (its criterion sees the law through chi(w) and chi(2 w)
        alone and does not rank laws; the message says so).
    resolution : float, optional
        The smallest noise std the record can have (the converter's LSB / sqrt(12)), in
        units of y. Default: the record's own quantisation step (the smallest gap between
        its distinct values) over sqrt(12), and at least 1e-4 of its rms. Where the jitter
        dominates, the likelihood's noise std runs down to this floor (the noise-free
        jittered sine explains the samples as well): the fit then says AT_BOUND for
        ``noise_std``, and the jitter std is the one given the noise at its floor.

    Returns
    -------
    JitterMeasurement

    Raises
    ------
    ValueError
        A record that is too short, not finite or constant, an unknown law, a band with no
        alias of the record's frequency, or a sine fit that does not converge; each
        message names the fix.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> rng = np.random.default_rng(0)
    >>> T, N, f = 1e-3, 400, 123.0  # 1 kHz sampling, a 123 Hz sine
    >>> tau = 50e-6 * rng.standard_normal(N)  # 50 us rms jitter
    >>> y = np.sin(2 * np.pi * f * (np.arange(N) * T + tau)) + 1e-2 * rng.standard_normal(N)
    >>> m = ji.measure_jitter(y, T, laws=["gaussian"])
    >>> bool(abs(m.jitter_std - 50e-6) < 4 * m.jitter_std_stderr)
    True
    """
    yv = _record(y)
    T = positive(T, "T")
    if method not in ("ml", "gaussian"):
        raise ValueError(f"method must be 'ml' or 'gaussian'; got {method!r}")
    if isinstance(laws, str):
        laws = (laws,)
    note = ""
    if method == "gaussian" and len(laws) > 1:
        # the second-moment criterion sees a law only through chi(w) and chi(2 w): its
        # value does not rank laws (measured: Gaussian records at 2 pi f sigma = 0.5 and 1
        # came out as 'uniform', 8 % and 25 % low)
        laws, note = (
            tuple(laws[:1]),
            (f"; method='gaussian' fits one law ({laws[0]}): its criterion does not rank laws"),
        )
    known = _families(T)
    unknown = [name for name in laws if name not in known]
    if unknown or not laws:
        raise ValueError(f"laws must name families among {sorted(known)}; got {list(laws)}")
    N = yv.size
    f_start = positive(frequency, "frequency") if frequency is not None else periodogram_peak(yv, T)
    data = SampledData(yv, T, None, resolution=_resolution(yv, resolution))
    if band_hz is not None:
        cands = SineWave(band_hz=band_hz, harmonics=harmonics).start_frequencies(data)
    else:
        cands = [f_start]
    cycles = cands[0] * N * T
    if cycles < 2 and frequency is None:
        raise ValueError(
            f"the record holds {cycles:.3g} periods of its sine; at least 2 are needed "
            "(record longer, or give frequency= if the sine is faster than it looks)"
        )
    half_bin = 1.0 / (N * T)
    # every alias with the family chosen on the first one; then the families on the best
    first_family = laws[0]
    alias_fits: list[tuple[float, FitResult]] = []
    alias_starts: list[tuple[FloatArray, float, float]] = []
    slope_std = float("nan")
    for fc in cands:
        lo = max(fc - 4 * half_bin, 0.5 * fc)
        band = (lo, fc + 4 * half_bin)
        theta, sj, sv, slope_std_c = _start(yv, T, fc, band)
        model = SineWave(band_hz=band, harmonics=harmonics)
        theta_h = _harmonic_start(model, yv, T, theta)
        res = _fit_one(data, model, known[first_family], theta_h, sj, sv, method)
        alias_fits.append((fc, res))
        alias_starts.append((theta_h, sj, sv))
        if len(alias_fits) == 1 or res.cost < min(r.cost for _, r in alias_fits[:-1]):
            slope_std = slope_std_c
    i_best = min(range(len(alias_fits)), key=lambda i: alias_fits[i][1].cost)
    best = alias_fits[i_best][1]
    theta_b, sj_b, sv_b = alias_starts[i_best]
    aliases = tuple(
        AliasCandidate(float(r.params["frequency_hz"]), -0.5 * r.cost, r.jitter_std)
        for _, r in alias_fits
    )
    # the other families at the chosen alias: from its IEEE starts and from the first
    # family's fit, the better end kept
    fitted: dict[str, FitResult] = {first_family: best}
    chosen_model = best.structure
    sine = np.asarray(best.x[best.layout.slice("system")], dtype=float)
    for name in laws[1:]:
        fitted[name] = _fit_one(
            data,
            chosen_model,
            known[name],
            theta_b,
            sj_b,
            sv_b,
            method,
            other=(sine, best.jitter_std, float(best.x[-1])),
        )
    cands_law = []
    for name, r in fitted.items():
        p = r.x.size
        ll = -0.5 * r.cost
        cands_law.append(
            LawCandidate(
                name, ll, p, 2 * p - 2 * ll, p * math.log(N) - 2 * ll, r.jitter_std, r.status
            )
        )
    ok = [c for c in cands_law if c.status in (FitStatus.CONVERGED, FitStatus.AT_BOUND)]
    chosen = min(ok or cands_law, key=lambda c: c.bic)
    r = fitted[chosen.name]
    status, message = r.status, r.message
    if not ok:
        message = f"no family's fit converged; the lowest BIC is reported: {message}"
    message += note
    lls = sorted((a.loglik for a in aliases), reverse=True)
    if len(lls) > 1 and lls[0] - lls[1] < _ALIAS_TIE:
        status = FitStatus.UNIDENTIFIABLE
        message = (
            f"the frequency is not identified among {len(lls)} aliases in band_hz (their ln L "
            f"differ by {lls[0] - lls[1]:.2g}): with the jitter's scale free, the samples see "
            "only f times the jitter std, so each alias fits with its own jitter std. Give "
            "the frequency (frequency=...), or rank the aliases under a known jitter law "
            "(alias_likelihoods)"
        )
    return JitterMeasurement(
        jitter_std=r.jitter_std,
        jitter_std_stderr=r.jitter_std_stderr,
        noise_std=float(r.params["noise_std"]),
        noise_std_stderr=_stderr(r, "noise_std"),
        frequency=float(r.params["frequency_hz"]),
        frequency_stderr=_stderr(r, "frequency_hz"),
        amplitude=float(r.params["amplitude"]),
        phase_rad=float(r.params["phase_rad"]),
        offset=float(r.params["offset"]),
        law=r.jitter_law,
        family=chosen.name,
        laws=tuple(cands_law),
        aliases=aliases,
        fit=r,
        status=status,
        message=message,
        slope_regression_std=slope_std,
        T=T,
    )


def _harmonic_start(model: SineWave, y: FloatArray, T: float, theta: FloatArray) -> FloatArray:
    """The sine start [A, phase, f, c] extended to the model's harmonics (their
    least-squares amplitudes at the start frequency)."""
    if model.harmonics == 1:
        return theta
    pts = model.initial_points(SampledData(y, T, None))
    f = theta[2]
    best = min(pts, key=lambda p: abs(p[2 * model.harmonics] - f))
    out = np.asarray(best, dtype=float).copy()
    out[0], out[1] = theta[0], theta[1]
    return out


def alias_likelihoods(
    y: ArrayLike,
    T: float,
    band_hz: tuple[float, float],
    jitter: JitterLaw,
    *,
    noise_std: float | None = None,
) -> tuple[AliasCandidate, ...]:
    """The exact log-likelihood of every alias of a sine record's frequency in a band,
    under a known jitter law (the paper's Section 3.4).

    Without jitter the aliases f0 + m/T and m/T - f0 fit the samples equally well; under a
    known jitter law each is damped by its own |chi(2 pi f)| (Lemma 1) and its samples
    spread by their own variance (Lemma 2), so the likelihood tells them apart. (With the
    law's scale free they are a tie again: :func:`measure_jitter` says so.)

    Parameters
    ----------
    y : array_like, shape (N,)
        The samples at the nominal instants kT.
    T : float
        Nominal sampling interval (s), s.
    band_hz : (float, float)
        The band holding the candidate aliases, Hz.
    jitter : JitterLaw
        The known jitter law.
    noise_std : float, optional
        The known noise std; default: estimated with each alias.

    Returns
    -------
    tuple of AliasCandidate
        One per alias, highest likelihood first; ``jitter_std_s`` is the known law's std.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> rng = np.random.default_rng(1)
    >>> T, N = 2.0, 300
    >>> tau = ji.Uniform(1.0).sample(N, rng)
    >>> y = np.sin(2 * np.pi * 0.14 * (np.arange(N) * T + tau)) + 0.05 * rng.standard_normal(N)
    >>> ranked = ji.alias_likelihoods(y, T, (0.05, 0.7), ji.Uniform(1.0))
    >>> round(ranked[0].frequency_hz, 2)
    0.14
    """
    yv = _record(y)
    T = positive(T, "T")
    if not isinstance(jitter, JitterLaw):
        raise TypeError(
            "jitter must be a known jitter law (e.g. jitterid.Uniform(1.0)); got "
            f"{type(jitter).__name__}"
        )
    data = SampledData(yv, T, None, noise_std=noise_std)
    cands = SineWave(band_hz=band_hz).start_frequencies(data)
    half_bin = 1.0 / (yv.size * T)
    out = []
    for fc in cands:
        band = (max(fc - 4 * half_bin, 0.5 * fc), fc + 4 * half_bin)
        theta, _, sv, _ = _start(yv, T, fc, band)
        fit4 = sine_fit_4(yv, np.arange(yv.size, dtype=float) * T, fc, frequency_bounds=band)
        # the fitted sine is the true one damped by chi(2 pi f) (Lemma 1): undo it
        chi = complex(np.asarray(jitter.cf(np.array([fit4.frequency])))[0]).conjugate()
        if abs(chi) > 1e-3:
            theta[0] = fit4.amplitude / abs(chi)
            theta[1] = fit4.phase - float(np.angle(chi))
        model = SineWave(band_hz=band)
        x0 = theta if noise_std is not None else np.r_[theta, sv]
        r = fit(data, model, jitter, method="ml", start=x0)
        out.append(
            AliasCandidate(float(r.params["frequency_hz"]), -0.5 * r.cost, float(jitter.std))
        )
    return tuple(sorted(out, key=lambda a: -a.loglik))
