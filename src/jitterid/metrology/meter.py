"""The jitter meter: the sampling jitter's std, law and interval from a sine record.

:func:`measure_jitter` fits a :class:`~jitterid.systems.tones.SineWave` with the jitter law
estimated (the JOE structure (2c) with a signal model, the paper's (1a)). In order:

1. the frequency: the periodogram's peak refined by the IEEE 1057 four-parameter fit
   (:mod:`jitterid.metrology.sinefit`), or the given one; with a band, its aliases there
   (a tie with the jitter's scale free: one is fitted, the others follow);
2. the tone test and the folding check (:mod:`jitterid.metrology.adequacy`): a record with
   no tone, or a tone that cannot show jitter, is not measured further;
3. the moment route (:mod:`jitterid.metrology.moments`): the closed-form per-sample mean
   and variance of a jittered tone, fitted in a few passes (the answer of
   ``method="gaussian"``, law-free when several laws are given, and the likelihood's start
   and its numeric noise floor); with small harmonics, on the record less them, held at
   their least-squares fit (:mod:`jitterid.metrology.held`), for either method;
4. (``method="ml"``) the exact likelihood (notes 4) for each candidate family, the lowest
   BIC kept: for a pure tone under a Gaussian, uniform, dual-Dirac or scale-mixture family
   the structured one of :mod:`jitterid.metrology.sinelik` (O(N), any noise std), also for
   a tone with small harmonics, held at their least-squares fit
   (:mod:`jitterid.metrology.held`), else the generic quadrature of
   :mod:`jitterid.estimation.likelihood`;
5. the adequacy checks on the chosen fit (rails, lines in the residual), the per-sample
   phase error (:mod:`jitterid.metrology.phase`: periodic and coloured jitter, the RJ/PJ
   decomposition, a Newey-West interval for a coloured jitter), a law's hard edges
   sharper than the record resolves (:mod:`jitterid.metrology.edges`: the interval is then
   too narrow, and the message says so), and the status: what was found and what to do,
   never ``CONVERGED`` beside a NaN standard error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive, real_array
from ..data import SampledData
from ..estimation.fit import fit
from ..estimation.likelihood import ExactLikelihood, RuleBudgetError
from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import GaussianFamily, JitterFamily, JitterLaw, UniformFamily
from ..moments.sample import sample_moments
from ..systems.model import Model
from ..systems.tones import SineWave
from ._format import time_text as _time
from .adequacy import (
    ALPHA_TONE,
    Finding,
    SpectralLine,
    dither_finding,
    folding_check,
    quantisation_step,
    rail_check,
    residual_lines,
    tone_significance,
)
from .converter import ConverterFigures, converter_figures  # meterio (issue 26, item 3)
from .edges import sharp_edge_finding
from .held import HeldHarmonics, hold_harmonics
from .moments import (
    QUANTISED_WEIGHT_FLOOR,
    ROUTE_LAWS,
    WEIGHT_FLOOR,
    MomentFit,
    moment_route,
    std_interval,
)
from .phase import JitterDecomposition, newey_west_lags, phase_error_analysis
from .reading import LAW_MARGIN_BIC, summary_extras  # meterio (issue 26, item 5)
from .sinefit import SineFit, periodogram_peak, sine_fit_4, slope_regression_jitter
from .sinelik import (  # issue 26, item 2
    NUMERIC_FLOOR,
    RANK_MARGIN_BIC,
    RankStart,
    SineLikelihood,
    fit_sine_ml,
    rank_on_subsample,
    rank_sine_law,
    rank_start,
    ranked_nested,
    sine_ml_applies,
    start_subsample,
)

__all__ = [
    "ALIAS_FITS",
    "FAMILY_NAMES",
    "MAX_ALIASES",
    "AliasCandidate",
    "JitterMeasurement",
    "LawCandidate",
    "alias_likelihoods",
    "measure_jitter",
]

FloatArray = NDArray[np.float64]

#: Fewest samples and whole periods a record must hold.
MIN_SAMPLES = 32
#: ln L difference below which two aliases are a tie.
_ALIAS_TIE = 1e-3
#: Most aliases a band may hold (see measure_jitter, band_hz).
MAX_ALIASES = 1000
#: Aliases :func:`alias_likelihoods` fits by the exact likelihood (the best by a one-pass
#: score).
ALIAS_FITS = 4
#: Evaluations of one fit of the Gaussian criterion, CPU units per second of the closed-form
#: tone moments (N H^2 (2H + 3) per evaluation; measured: N = 400, H = 16, 26 evaluations,
#: 6.1 s), and the most CPU-s a harmonic fit may cost before it is refused.
_EVALS_PER_FIT = 30
_UNITS_PER_SECOND = 2.0e7
_COST_LIMIT = 120.0
#: CPU-s per sample of one family's fit by the generic exact likelihood (a tone with
#: harmonics, or a family the structured likelihood does not integrate): measured on the
#: 12-bit HD2/HD3 records of ``benchmarks/meter_records.py hd-quant`` at N = 2048 and 4096
#: (session 21, after the shape families' moment derivatives were mended: 0.9-1.7 ms a
#: sample for the Gaussian, 1.2-2.3 for the uniform, 3.1-6.3 for the dual Dirac, 2.8-4.5 for
#: the scale mixture, 10-15 for the generalized normal at 2048); the upper ends, with room
#: (eight records at 4096 with the four default laws took 46-164 CPU-s, mean 84).
#: :func:`measure_jitter` measures with ``method="gaussian"`` instead where the sum over its
#: families exceeds :data:`_COST_LIMIT` (the four default laws: beyond N of about 5200).
_GENERIC_SECONDS_PER_SAMPLE = {
    "gaussian": 2e-3,
    "uniform": 3e-3,
    "dual-dirac": 1e-2,
    "scale-mixture": 8e-3,
    "generalized-normal": 2e-2,
}
#: Families tried by default, by name (see measure_jitter, laws).
DEFAULT_LAWS = ("gaussian", "uniform", "dual-dirac", "scale-mixture")


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
        from ..jitter.regular import (
            DualDiracFamily,
            GaussianScaleMixtureFamily,
            GeneralizedNormalFamily,
        )

        out["generalized-normal"] = GeneralizedNormalFamily(std_max=10 * T, std_min=lo)
        out["dual-dirac"] = DualDiracFamily(rj_max=10 * T, rj_min=lo, dj_max=20 * T)
        out["scale-mixture"] = GaussianScaleMixtureFamily(sigma_max=10 * T, sigma_min=lo)
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
        The maximised log-likelihood (NaN if the fit failed); for a family ranked out
        (:attr:`ranked_out`) the upper estimate of its maximum.
    n_params : int
        Free parameters of the whole model (sine, jitter family, noise std).
    aic, bic : float
        -2 ln L + 2 p and -2 ln L + p ln N.
    jitter_std_s : float
        The fitted law's standard deviation, seconds.
    status : FitStatus
        The fit's status; only a candidate whose status is a success can be chosen.
    ranked_out : bool
        The family was ranked out before its full fit (``method="ml"``,
        :func:`jitterid.metrology.sinelik.rank_sine_law`): even the upper estimate of its
        maximum puts its BIC :data:`~jitterid.metrology.sinelik.RANK_MARGIN_BIC` or more
        above the chosen family's (its status is then MAX_EVALUATIONS: not fitted to its
        maximum; :attr:`bic` a lower estimate).
    """

    name: str
    loglik: float
    n_params: int
    aic: float
    bic: float
    jitter_std_s: float
    status: FitStatus
    ranked_out: bool = False

    def state(self, chosen_bic: float) -> str:
        """How this family's fit ended, for the reports: its status, or for a family
        ranked out its ln L upper estimate and its BIC margin over the chosen family's
        (a lower bound: the family was not fitted to its maximum).

        Parameters
        ----------
        chosen_bic : float
            The chosen family's BIC.
        """
        if not self.ranked_out:
            return self.status.name
        return (
            f"ranked out, not fitted to its maximum: ln L <= {self.loglik:.3f} (upper "
            f"estimate), BIC >= chosen + {self.bic - chosen_bic:.2f} (ranking margin "
            f"{RANK_MARGIN_BIC:g})"
        )


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
        The additive noise std (units of y) and its standard error: the record's, a
        quantiser's error included (where the bins were modelled, sqrt(sigma^2 + q^2 / 12)
        of the noise before the quantiser sigma, ``fit.params["noise_std"]``, and the step
        q).
    frequency, frequency_stderr : float
        The sine's frequency and its standard error.
    amplitude, phase_rad, offset : float
        The sine, s(t) = amplitude sin(2 pi frequency t + phase_rad) + offset, t = kT.
    law : JitterLaw
        The fitted jitter law of the chosen family.
    family : str
        The chosen family's name (lowest BIC among :attr:`laws`); ``"law-free"`` where the
        moment route measured the std without assuming a law (``method="gaussian"`` with
        several laws: :attr:`law` is then the Gaussian of that std, the shape is in the
        message).
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
    findings : tuple of Finding
        What the model-adequacy checks found (:mod:`jitterid.metrology.adequacy`): empty
        for a record that is one jittered tone; each finding's message says what to do.
    tone_p_value : float
        The tone test's p-value (below 1e-3: a tone stands out of the record).
    harmonics_fitted : int
        Harmonics in the fitted model (those significant in the record, up to the asked).
    quantisation_step : float or None
        The record's quantisation step where its values lie on a grid, else None.
    jitter_var, jitter_var_stderr : float
        The jitter's variance (s^2, unclipped: it may be below 0 where the record does not
        resolve the jitter) and its standard error, where the moment route measured it
        (``method="gaussian"``); NaN otherwise. :meth:`interval` then takes the interval on
        the variance's scale, one-sided where it reaches 0.
    noise_floor : float or None
        The physical noise floor (the ``resolution`` given, or the quantisation step /
        sqrt(12) of a quantised record); None for a float record, which has none.
    decomposition : JitterDecomposition or None
        The jitter split from the per-sample phase error
        (:mod:`jitterid.metrology.phase`): RJ rms, PJ amplitude and frequency, total, and
        whether the jitter is correlated from sample to sample (a pure tone only).
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
    findings: tuple[Finding, ...] = ()
    tone_p_value: float = math.nan
    harmonics_fitted: int = 1
    quantisation_step: float | None = None
    jitter_var: float = math.nan
    jitter_var_stderr: float = math.nan
    noise_floor: float | None = None
    decomposition: JitterDecomposition | None = None
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

    @property
    def law_fitted(self) -> bool:
        """Whether a jitter law was fitted (False on the law-free moment route, whose
        :attr:`law` is a Gaussian of the measured std whatever its shape)."""
        return self.family != LAW_FREE

    def interval(self, level: float = 0.95) -> tuple[float, float]:
        """Normal-approximation interval of the jitter std, cut at 0: on the variance's
        scale where :attr:`jitter_var_stderr` is known (then one-sided, [0, upper], where
        the record does not resolve the jitter), else on the std's.

        Parameters
        ----------
        level : float, optional
            Coverage, in (0, 1).
        """
        if math.isfinite(self.jitter_var_stderr) and math.isfinite(self.jitter_var):
            return std_interval(self.jitter_var, self.jitter_var_stderr, level)
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
        if self.decomposition is not None:
            lines.insert(-1, f"  decomposition     {self.decomposition.summary()}")
        if self.findings:
            at = lines.index("  families (lowest BIC chosen):")
            found = [f"  finding ({f.kind}): {f.message}" for f in self.findings]
            lines[at:at] = found
        chosen_bic = next((c.bic for c in self.laws if c.name == self.family), math.nan)
        for c in self.laws:
            mark = "*" if c.name == self.family else " "
            state = c.state(chosen_bic)
            lines.append(
                f"   {mark} {c.name:<20s} ln L = {c.loglik:12.3f}  BIC = {c.bic:12.3f}  "
                f"std = {_time(c.jitter_std_s)}  [{state}]"
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


def _record(y: ArrayLike) -> FloatArray:
    yv = real_array(y, "y", ndim=1)
    if yv.size < MIN_SAMPLES:
        raise ValueError(
            f"y must hold at least {MIN_SAMPLES} samples of the sine record; got {yv.size}"
        )
    if not np.all(np.isfinite(yv)):
        raise ValueError("y must be finite: remove or interpolate the NaN/inf samples first")
    # relative to the record's own size: a record in volts from a pA sensor is not constant
    if float(np.std(yv)) <= 1e-12 * float(np.max(np.abs(yv))):
        raise ValueError("y is constant: a sine record is needed (check the input channel)")
    return yv


def _start(
    y: FloatArray, T: float, f0: float, band: tuple[float, float]
) -> tuple[FloatArray, float, float, float]:
    """(sine start [A, phase, f, c], jitter std start, noise std start, slope-regression std)."""
    theta, sj, sv, reg, _ = _start_fit(y, T, f0, band)
    return theta, sj, sv, reg


def _start_fit(
    y: FloatArray,
    T: float,
    f0: float,
    band: tuple[float, float],
    fit4: SineFit | None = None,
) -> tuple[FloatArray, float, float, float, SineFit]:
    """:func:`_start` and the IEEE 1057 four-parameter fit it started from (``fit4``: that
    fit, where it is already at hand)."""
    t = np.arange(y.size, dtype=float) * T
    if fit4 is None:
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
    return theta, sj, sv, float(reg.jitter_std), fit4


def _refined_frequency(
    y: FloatArray, T: float, f0: float, band: tuple[float, float], fit4: SineFit | None
) -> float | None:
    """The IEEE 1057 four-parameter fit's frequency from ``f0`` inside ``band`` (``fit4``:
    that fit, where at hand), None where it does not converge."""
    if fit4 is None:
        fit4 = sine_fit_4(y, np.arange(y.size, dtype=float) * T, f0, frequency_bounds=band)
    return abs(float(fit4.frequency)) if fit4.converged else None


def _start_moments(
    y: FloatArray,
    T: float,
    f0: float,
    band: tuple[float, float],
    fit4: SineFit | None = None,
    *,
    weight_floor: float,
) -> tuple[FloatArray, float, float, float, SineFit, MomentFit]:
    """:func:`_start_fit` for a pure tone with the slope regression read off the moment
    route (:attr:`MomentFit.slope_regression_std`: the same regression, one pass fewer),
    and that Gaussian moment fit (``weight_floor``: :func:`~jitterid.metrology.moments.
    moment_route`'s)."""
    t = np.arange(y.size, dtype=float) * T
    if fit4 is None:
        fit4 = sine_fit_4(y, t, f0, frequency_bounds=band)
    if not fit4.converged:
        raise ValueError(
            f"the four-parameter sine fit did not converge from {f0:g} Hz ({fit4.message}); "
            "give the frequency (frequency=...) or check that y is a sine record"
        )
    mf = moment_route(y, T, fit4, "gaussian", weight_floor=weight_floor)
    w = 2 * math.pi * fit4.frequency
    sj = mf.slope_regression_std if np.isfinite(mf.slope_regression_std) else 0.0
    sj = max(sj, 1e-3 / w)
    resid = float(np.std(fit4.residuals))
    sv = mf.slope_regression_noise_std if np.isfinite(mf.slope_regression_noise_std) else 0.0
    sv = max(sv, 1e-3 * resid, 1e-9 * fit4.amplitude)
    damping = math.exp(-0.5 * (w * sj) ** 2)
    theta = np.array([fit4.amplitude / max(damping, 0.05), fit4.phase, fit4.frequency, fit4.offset])
    return theta, sj, sv, float(mf.slope_regression_std), fit4, mf


def _fit_one(
    data: SampledData,
    model: Model,
    family: JitterFamily,
    theta: FloatArray,
    sj: float,
    sv: float,
    method: str = "ml",
    other: tuple[FloatArray, float, float] | None = None,
    gauss: FitResult | None = None,
    alt: FitResult | None = None,
    q_step: float | None = None,
) -> FitResult:
    """The Gaussian criterion from the IEEE starts, then (``method="ml"``) the exact
    likelihood from the better of its end and the IEEE start (by the likelihood itself:
    the second-moment criterion can trade jitter for noise where the law is far from
    Gaussian). With ``other`` (the sine, jitter std and noise std of another family's fit)
    the likelihood is also maximised from there, and the better end kept: a law far from
    the other's can have a local optimum in phase and frequency near it. ``gauss``: the
    Gaussian route's fit where it is already known (the moment route's); ``alt``: the fit
    from ``other``'s start where it is already known (the law ranking's). ``q_step``: a
    quantised record's step, for the structured likelihood's bin kernel (its noise std is
    then the noise before the quantiser: the moment starts' noise, the quantiser's
    included, less q^2 / 12)."""
    x0 = np.r_[family.start_for_std(sj), theta, sv]
    if gauss is None:
        # (a start for the likelihood: a budget, not the 2000 evaluations of a fit; its end
        # where the budget ran out is a start as good, scored by the likelihood below)
        # as the answer (method="gaussian"), its interval the Huber-White sandwich: the
        # criterion's information assumes Gaussian jitter, and the std's error scales with
        # the jitter's kurtosis (a scale mixture of kurtosis 5.4 at N = 4096: the
        # information's error 0.59 of the estimates' spread, the sandwich's 0.87)
        # As the likelihood's start (method="ml") its end is all that is used: no
        # covariance, and no restart where the budgeted search stops (the end is scored by
        # ln L below, against the IEEE start). A 2^20 uniform record (100 fs at 1 GHz): the
        # search ended "damping exhausted", its restart from the first stage went no lower,
        # and the covariance was made: 46 of the measurement's 129 CPU-s for a start that
        # was then not used.
        ml_start = method != "gaussian"
        gauss = fit(
            data,
            model,
            family,
            method="gaussian",
            start=x0,
            max_nfev=START_NFEV,
            cov_type="none" if ml_start else "robust",
            restart=not ml_start,
        )
    if method == "gaussian":
        return gauss
    xg = np.asarray(gauss.x, dtype=float).copy()
    cands = [x0]
    lo_noise = data.resolution or 0.0
    # (an end where the budget ran out, or where no step lowered the criterion, is a start
    # as good as any: the starts are scored by ln L)
    usable = gauss.status is not FitStatus.NOT_FINITE
    if usable and np.all(np.isfinite(xg)):
        if not xg[-1] > 0.1 * sv:  # the Gaussian criterion put the noise at its bound 0
            xg[-1] = max(sv, lo_noise)
        x0 = np.r_[x0[:-1], max(float(x0[-1]), lo_noise)]
        cands = [x0]
        cands.insert(0, xg)
    if q_step and sine_ml_applies(model, family):
        cands = [np.r_[c[:-1], _before_quantiser(float(c[-1]), q_step, lo_noise)] for c in cands]
    # a pure tone under a Gaussian, uniform, dual-Dirac or scale-mixture law: the structured
    # likelihood (jitterid.metrology.sinelik, O(N)); else the generic one
    if sine_ml_applies(model, family):
        assert isinstance(model, SineWave)
        tone = model
        # the starts scored where fit_sine_ml fits its start (every s-th sample of a long
        # record: 1/s of a pass each, three full passes were 4 % of a 2^16 measurement)
        slik = SineLikelihood(*start_subsample(data.y, data.T), family, quantisation_step=q_step)
        neg_ll: Callable[[FloatArray], float] = lambda c: -slik.loglik(c)

        def ml(x: FloatArray, found: FitResult | None = None) -> FitResult:
            return fit_sine_ml(
                data.y,
                data.T,
                tone,
                family,
                x,
                noise_floor=lo_noise,
                quantisation_step=q_step,
                found=found,
            )

        if lo_noise > 0:  # a noise-free record: its noise std starts on the floor
            cands.append(np.r_[cands[0][:-1], lo_noise])
    else:
        lik = ExactLikelihood(model, family, None, data.T, data.N, noise_floor=data.resolution)
        neg_ll = lambda c: -lik.loglik(c, data.y)

        def ml(x: FloatArray, found: FitResult | None = None) -> FitResult:
            return fit(data, model, family, method="ml", start=x)

    scored: list[tuple[float, int, FloatArray]] = []
    for c in cands:
        try:
            scored.append((neg_ll(c), len(scored), c))
        except ValueError:
            continue
    best = min(scored)[2] if scored else xg
    # (the ranking's fit to this family's maximum, from the other family's: where the search
    # from here meets it, not run again, fit_sine_ml's found)
    out = ml(best, alt if alt is not None and alt.status is FitStatus.CONVERGED else None)
    # A large phase spread lets the jitter alone explain the samples: ln L has a local
    # maximum with the noise on its floor, which a start there never leaves, and which
    # can score above a noisy start at that start (a 1 rad uniform record, noise 1e-2:
    # ln L -657 against -311 at the maximum from the noisy start). An end within a decade
    # of the floor there is searched again from the best-scored start with the noise above
    # it (a dual Dirac at 1 rad ended at 2.2 x the floor, ln L -405 against -54).
    spread = 2 * math.pi * float(theta[2]) * sj
    if lo_noise > 0 and spread >= FLOOR_TRAP_SPREAD_RAD and out.x[-1] <= 10 * lo_noise:
        noisy = [c for _, _, c in sorted(scored, key=lambda t: t[:2]) if c[-1] > 10 * lo_noise]
        if not noisy:
            # every start on the floor (the slope regression, whose noise is the start's,
            # reads none where the jitter's curvature terms dominate: a scale mixture at
            # 0.22 rad, N = 400, noise 0.05 of a 1.5 amplitude, ended at the floor's
            # maximum, ln L 120 below the one from here, LACK_OF_FIT): one at a third of the
            # residual's rms
            rms = float(np.std(data.y - model.signal(theta, None)(data.t_nominal)))
            if rms > 30 * lo_noise:
                noisy = [np.r_[best[:-1], rms / 3]]
        if noisy and not np.array_equal(noisy[0], best):
            again = ml(noisy[0])
            if _higher(again, out):
                out = again
    out = _off_zero_jitter(out, scored, family, ml)
    if alt is None and other is not None:
        alt = ml(_other_start(data, family, other))
    if alt is not None and _higher(alt, out):
        out = alt
    return out


def _higher(new: FitResult, old: FitResult) -> bool:
    """Whether ``new`` ends higher in ln L than ``old`` (a finite cost beats a non-finite
    one)."""
    return bool(np.isfinite(new.cost) and (not np.isfinite(old.cost) or new.cost < old.cost))


def _off_zero_jitter(
    out: FitResult,
    scored: list[tuple[float, int, FloatArray]],
    family: JitterFamily,
    ml: Callable[[FloatArray], FitResult],
) -> FitResult:
    """``out`` (the likelihood's fit from the best-scored start), or, where its jitter std
    is below :data:`ZERO_JITTER` of a scored start's, the fit from the best-scored start
    whose jitter is not, where that is higher. ln L is even in the jitter's scale, so zero
    jitter is a stationary point that a search started there never leaves: a 10-bit record
    (0.3 step of noise before the quantiser, 1 ps of Gaussian jitter at 97 MHz, N = 2^14)
    whose moment start had its jitter at 0 (until session 26 every one did, through a
    defect in :func:`_moment_result`; a moment route that reads no jitter still does)
    started the Gaussian's search there, which ended CONVERGED at 0.004 fs, ln L 77 below
    the uniform's maximum at 930 fs, and the uniform was chosen."""
    nj = len(family.param_names)
    stds = []
    for _, _, c in sorted(scored, key=lambda t: t[:2]):
        try:
            stds.append((float(family.law(list(c[:nj])).std), c))
        except ValueError:
            continue
    top = max((sd for sd, _ in stds), default=0.0)
    if not out.jitter_std < ZERO_JITTER * top:
        return out
    start = next(c for sd, c in stds if sd >= ZERO_JITTER * top)
    again = ml(start)
    if not _higher(again, out):
        return out
    return replace(
        again,
        message=(
            f"{again.message} (searched again from a start with jitter: the best-scored "
            f"start's search ended at {out.jitter_std:.3g} s, a stationary point of ln L, "
            f"{0.5 * (out.cost - again.cost):.3g} below)"
        ),
    )


#: An ML end whose jitter std is below this fraction of a scored start's is searched again
#: from the best-scored start that has jitter (:func:`_off_zero_jitter`).
ZERO_JITTER = 1e-3
#: Evaluations of the Gaussian criterion's fit that starts the likelihood (:func:`_fit_one`;
#: it converges in 10-30 where the law's parameters are identified). A dual Dirac at 1 rad of
#: phase spread, flat along rj-dj at a fixed std, took the whole 2000 of a fit (gains of
#: 1e-12 a step) and then 1264 more, 13 s of a 50 s measurement of an N = 1000 record.
START_NFEV = 100
#: The phase spread (2 pi f x the start's jitter std, rad) from which an ML end with the
#: noise on its floor is searched again from a noisy start (:func:`_fit_one`); below it a
#: noisy record's floor start scores far below a noisy start (the samples near the tone's
#: peaks lie outside the noise-free support), and a noise-free instrument record is not fitted
#: twice.
FLOOR_TRAP_SPREAD_RAD = 0.1


def _before_quantiser(total: float, step: float, floor: float) -> float:
    """The noise std before a quantiser of step ``step`` whose output's noise std (the
    quantiser's error included) is ``total``: sqrt(total^2 - step^2 / 12), at least
    ``floor``."""
    return max(math.sqrt(max(total * total - step * step / 12.0, 0.0)), floor)


#: The noise before the quantiser (in steps, from the moment route's noise) from which a
#: quantised record is measured with Gaussian noise instead of the bin kernel, whose pass
#: costs about 3x the Gaussian's: the quantiser's error is then Gaussian to the fit (its
#: dependence on the signal ~exp(-2 pi^2 sigma^2 / q^2) = 3e-9, the uniform's excess
#: kurtosis -1.2 diluted to -0.007). Measured with Gaussian noise (12 bits, 2 ps, N = 2^16,
#: 8 records each, in stated errors): -0.34 (SEM 0.15) at 0.4 steps, +0.10 (SEM 0.26) at 0.6.
BIN_DITHER = 1.0
#: The bin kernel's noise floor, in quantisation steps (the noise before the quantiser of a
#: quantised record measured by the structured likelihood; its rule resolves the bin's edges
#: down to 2e-3 steps: tests/metrology/test_sinelik_kernel.py).
BIN_NOISE_FLOOR = 0.01


def _other_start(
    data: SampledData, family: JitterFamily, other: tuple[FloatArray, float, float]
) -> FloatArray:
    """A family's start at another family's fit (its sine, jitter std and noise std)."""
    sine, std, noise = other
    return np.r_[family.start_for_std(std), sine, max(noise, data.resolution or 0.0)]


def _resolution(given: float | None, step: float | None) -> float | None:
    """The physical noise floor: ``given``, else the record's quantisation step / sqrt(12)
    where its values lie on a grid, else None (a float record has none)."""
    if given is not None:
        return positive(given, "resolution")
    return step / math.sqrt(12.0) if step else None


def _ml_floor(
    physical: float | None, mf: MomentFit | None, amplitude: float, structured: bool = False
) -> float:
    """The noise floor the likelihood's search needs (its quadrature wants a noise std
    > 0): the physical one, or, on a float record, a fraction of the jitter's own spread of
    the samples, at least 1e-9 of the amplitude: :data:`~jitterid.metrology.sinelik.
    NUMERIC_FLOOR` for the structured likelihood (``structured``), 3 % for the generic one.
    A floor above a noise-free record's zero noise biases the jitter low by about a quarter
    of the floor's ratio to the spread (the samples near the tone's peaks, where the jitter
    moves them by less than the floor, read as less jitter: measured -0.5 % at 3 %)."""
    spread = 0.0
    if mf is not None and math.isfinite(mf.phase_var) and mf.phase_var > 0:
        spread = abs(amplitude) * math.sqrt(0.5 * mf.phase_var)
    numeric = max((NUMERIC_FLOOR if structured else 0.03) * spread, 1e-9 * abs(amplitude))
    return max(physical or 0.0, numeric)


def _stderr(result: FitResult, name: str) -> float:
    return float(result.stderr.get(name, float("nan")))


def _alias_frequencies(base: float, T: float, band: tuple[float, float]) -> list[float]:
    """Every alias m/T + base and m/T - base (m integer) of the baseband frequency ``base``
    inside ``band``, in O(count): refused before anything is built when there are more than
    :data:`MAX_ALIASES` (the jitter scale free makes them a tie: fitting them tells nothing)."""
    lo, hi = band
    fs = 1.0 / T
    counts = [
        math.floor((hi - s * base) / fs) - math.ceil((lo - s * base) / fs) + 1 for s in (1, -1)
    ]
    total = sum(max(c, 0) for c in counts)
    if total > MAX_ALIASES:
        raise ValueError(
            f"band_hz = ({lo:g}, {hi:g}) holds about {total:.3g} aliases of the record's "
            f"frequency {base:.6g} Hz (one every {0.5 * fs:g} Hz on average): with the jitter's "
            "scale free they fit the samples equally (each with its own jitter std, f times the "
            f"std being what the samples show), so they cannot be ranked; at most {MAX_ALIASES} "
            "are listed. Narrow band_hz to the Nyquist zone you know, or give frequency="
        )
    out: list[float] = []
    for s in (1, -1):
        m0 = math.ceil((lo - s * base) / fs)
        for m in range(m0, m0 + max(counts[s == -1], 0)):
            f = m * fs + s * base
            if lo <= f <= hi and f > 0:
                out.append(f)
    out.sort()
    uniq = [f for i, f in enumerate(out) if i == 0 or f - out[i - 1] > 1e-9 * fs]
    if not uniq:
        raise ValueError(
            f"no alias of the record's frequency {base:g} Hz (+ m/T, T = {T:g} s) lies in "
            f"band_hz = ({lo:g}, {hi:g}); widen the band or check T"
        )
    return uniq


def _harmonics_present(y: FloatArray, T: float, f: float, H: int) -> int:
    """The highest harmonic h <= H whose least-squares amplitude at h f is significant
    (Wald test of its cosine and sine coefficients, p < 1e-3 / H), at least 1. The normal
    equations are summed over chunks, so a long record costs O(N H) and little memory."""
    if H == 1:
        return 1
    n = y.size
    k = 2 * H + 1
    gram = np.zeros((k, k))
    rhs = np.zeros(k)
    w = 2 * math.pi * f * np.arange(1, H + 1)
    for a in range(0, n, 1 << 15):
        t = np.arange(a, min(a + (1 << 15), n), dtype=float) * T
        X = np.empty((t.size, k))
        X[:, 0] = 1.0
        ph = np.outer(t, w)
        X[:, 1::2] = np.cos(ph)
        X[:, 2::2] = np.sin(ph)
        gram += X.T @ X
        rhs += X.T @ y[a : a + t.size]
    try:
        coef = np.linalg.solve(gram, rhs)
        inv = np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        return 1
    ss = float(y @ y - coef @ rhs)
    s2 = max(ss / max(n - k, 1), 1e-300)
    best = 1
    for h in range(2, H + 1):
        i = slice(2 * h - 1, 2 * h + 1)
        c = coef[i]
        try:
            wald = float(c @ np.linalg.solve(inv[i, i] * s2, c))
        except np.linalg.LinAlgError:
            continue
        if math.exp(-0.5 * min(wald, 1400.0)) < 1e-3 / H:
            best = h
    return best


def _check_cost(N: int, H: int, n_fits: int) -> None:
    """Refuse a fit whose closed-form moments would cost more than :data:`_COST_LIMIT`
    (O(N H^3) per evaluation: H^2 tone pairs, 2 H + 2 parameters), with the estimate."""
    units = float(N) * H * H * (2 * H + 3) * _EVALS_PER_FIT * n_fits
    seconds = units / _UNITS_PER_SECOND
    if seconds > _COST_LIMIT:
        raise ValueError(
            f"harmonics={H} on N = {N} samples would cost about {seconds:.3g} CPU-s "
            f"({n_fits} fit(s) of the Gaussian criterion; its moments cost N H^3 per "
            f"evaluation): the record holds {H} significant harmonics. Fit fewer "
            "(harmonics=...), or a shorter record"
        )


def _better_unsettled(
    cands: Sequence[LawCandidate],
    chosen: LawCandidate,
    fitted: dict[str, FitResult],
    status: FitStatus,
    message: str,
) -> tuple[FitStatus, str]:
    """The measurement's status where a family whose fit did not end at a trusted maximum
    (not CONVERGED or AT_BOUND, not ranked out) fits the record better than the chosen one
    by more than :data:`~jitterid.metrology.reading.LAW_MARGIN_BIC` in BIC: that family's
    status, and a message saying so. The chosen family is then only the best of those that
    could be trusted, not the record's law: on a 12-bit record with Gaussian jitter the
    uniform was chosen, 1444 below the Gaussian in ln L, its interval 4 errors off the
    truth, because the Gaussian's covariance had failed."""
    better = [
        c
        for c in cands
        if c is not chosen
        and not c.ranked_out
        and c.status not in (FitStatus.CONVERGED, FitStatus.AT_BOUND)
        and math.isfinite(c.bic)
        and c.bic < chosen.bic - LAW_MARGIN_BIC
    ]
    if not better or status not in (FitStatus.CONVERGED, FitStatus.AT_BOUND):
        return status, message
    best = min(better, key=lambda c: c.bic)
    why = fitted[best.name].message
    return best.status, (
        f"the {best.name} family fits the record better than the {chosen.name} reported "
        f"(Delta BIC = {chosen.bic - best.bic:.1f}) but its fit ended {best.status.name} "
        f"({why}), so neither the law nor the jitter std reported can be trusted: fit with "
        f"laws=[{best.name!r}] and see its message; the {chosen.name} fit: {message}"
    )


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

    Before it reports, the meter checks that the record is one jittered tone
    (:mod:`jitterid.metrology.adequacy`): that a tone stands out of the record at all
    (else ``NOT_SIGNIFICANT``), that its alias is not on a multiple of fs/2 nor sampled at
    phases where its slope cannot vary (a coherent fs/4; else ``UNIDENTIFIABLE``), that no
    samples are piled at the rails (clipping) and that the residual holds no spectral line
    the model lacks (a second tone, distortion: ``LACK_OF_FIT``), and that the jitter std
    has a standard error (else ``UNIDENTIFIABLE``). :attr:`JitterMeasurement.findings`
    lists what was found.

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
        (random plus deterministic jitter, the serial-link model), ``"scale-mixture"``
        (two zero-mean Gaussians of different widths: heavier tails, kurtosis 3 to 5.7) and
        ``"generalized-normal"``; default the first four. The one with the lowest BIC is
        chosen. The law matters even for small jitter once the jitter's spread of the
        samples is above the noise: dual-Dirac records measured with Gaussian and uniform
        families only came out 6 % low (the uniform family chosen), 0.5 % with it.
    band_hz : (float, float), optional
        Where the frequency lies, in Hz. Every alias f0 + m/T, m/T - f0 in the band fits the
        samples equally well when the jitter's scale is free (the samples see f times the
        jitter std): one is fitted and :attr:`JitterMeasurement.aliases` lists each with
        the jitter std it implies; with more than one the status is ``UNIDENTIFIABLE``. A
        band holding more than :data:`MAX_ALIASES` aliases is refused.
    harmonics : int
        Harmonics of the sine model (1: a pure sine; more for a distorted source). Only
        those up to the highest one significant in the record are fitted (the message says
        so). Harmonics whose slopes sum to at most a tenth of the fundamental's
        (:data:`jitterid.metrology.held.HELD_SLOPE_SHARE`: HD2 and HD3 at -40 dBc and
        below) are held at their least-squares fit and the fundamental measured as a pure
        tone on the record less them (:mod:`jitterid.metrology.held`): by the structured
        likelihood with ``method="ml"`` and the four default laws (seconds at N = 2^16, the
        quantiser's bins modelled), by the moment route with ``method="gaussian"`` (a few
        passes); their own jitter, left out, biases the std to first order by about
        A_3 / A_1, which is added to its standard error and stated. Otherwise (stronger
        harmonics, or a law the structured likelihood does not integrate) the exact
        likelihood with harmonics is the generic quadrature: where its predicted cost
        exceeds about two minutes (N times about 2 ms a sample for the Gaussian family,
        3-10 ms for the other default laws and 20 ms for the generalized normal, summed
        over ``laws``: beyond N of about 5200 with the four default laws), or its rule
        would exceed its budget, the record is measured with ``method="gaussian"`` instead
        and the message says so. A Gaussian criterion whose cost would exceed about two
        minutes is refused with its estimate.
    method : {"ml", "gaussian"}
        ``"ml"`` (default): the exact likelihood, at the Cramer-Rao bound. For a pure tone
        with Gaussian, uniform, dual-Dirac or scale-mixture families it is
        :class:`jitterid.metrology.sinelik.SineLikelihood` (about 40 nodes per sample and
        family, a dozen passes a fit: seconds at N = 2^16), also with small harmonics held
        (see ``harmonics``); with strong harmonics or other families the generic
        quadrature (about 100 nodes per sample, many more evaluations). ``"gaussian"``: for a pure
        tone the moment route (:func:`jitterid.metrology.moments.moment_route`: the IEEE
        1057 fit, then the closed-form variance profile by reweighted least squares, a few
        passes over the record, its interval a sandwich that holds for any law and noise);
        with several laws given (the default) it measures the std law-free (the law's
        shape from the fourth moment; ``family`` is ``"law-free"``) where the phase spread
        2 pi f sigma is below about 0.2 rad; beyond, where the moments cannot tell the
        law's shape and the shape moves the std, it measures with the exact likelihood
        over the laws (as ``"ml"``; the message says so). With one law it assumes that law
        (gaussian or uniform) at any spread. With small harmonics, the same on the record
        less them (see ``harmonics``); with strong ones, the exact Gaussian criterion on
        the closed-form moments of the first law, its interval the Huber-White sandwich
        (right whatever the law's shape at a small phase spread: the information's was 0.6 of
        the spread for a heavy-tailed law).
    resolution : float, optional
        The smallest noise std the record can have (the converter's LSB / sqrt(12)), in
        units of y. Default: the record's own quantisation step over sqrt(12) where its
        values lie on a grid (:func:`jitterid.metrology.adequacy.quantisation_step`), and
        none for a float record (a simulator's record can be noise-free; the moment route
        needs no floor, and the likelihood's search stops at 1e-3 of the jitter's own
        spread with the structured likelihood of a pure tone, 3 % with the generic one:
        the status stays CONVERGED and the message says the noise is below what the record
        resolves). AT_BOUND only where a bound
        changes the jitter estimate. A quantised record (no ``resolution`` given) whose
        noise before its quantiser is below 1 step is measured by the structured
        likelihood with each sample the probability of its bin
        (:mod:`jitterid.metrology.sinelik_kernel`; its noise std then searched down to 0.01
        of a step): the quantiser's error is not Gaussian there, and modelled as Gaussian it
        biased the jitter by up to 1.3 stated errors at N = 2^16 (12 bits, 0.2 steps).

    Returns
    -------
    JitterMeasurement

    Raises
    ------
    ValueError
        A record that is too short, not finite or constant, an unknown law, a band with no
        alias of the record's frequency or with too many, a harmonic fit too costly, or a
        sine fit that does not converge; each message names the fix.

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
    return _measure(y, T, frequency, laws, band_hz, harmonics, method, resolution, fallback=True)


def _measure(
    y: ArrayLike,
    T: float,
    frequency: float | None,
    laws: Sequence[str],
    band_hz: tuple[float, float] | None,
    harmonics: int,
    method: str,
    resolution: float | None,
    *,
    fallback: bool,
) -> JitterMeasurement:
    """:func:`measure_jitter`; ``fallback``: where the exact likelihood is out of reach
    (the generic quadrature on a long record), measure with ``method="gaussian"`` and say so
    (False: refuse, naming the cost; the Gaussian route's own call)."""
    yv = _record(y)
    T = positive(T, "T")
    if method not in ("ml", "gaussian"):
        raise ValueError(f"method must be 'ml' or 'gaussian'; got {method!r}")
    if isinstance(laws, str):
        laws = (laws,)
    try:
        laws = tuple(laws)
    except TypeError:
        raise TypeError(
            f"laws must be a sequence of family names such as ['gaussian']; got {laws!r}"
        ) from None
    if isinstance(harmonics, bool) or not isinstance(harmonics, (int, np.integer)):
        raise TypeError(f"harmonics must be a whole number >= 1; got {harmonics!r}")
    if not 1 <= harmonics <= 64:
        raise ValueError(f"harmonics must lie in 1..64; got {harmonics}")
    notes: list[str] = []
    law_free = False
    asked = laws
    if method == "gaussian" and len(laws) > 1:
        # the second-moment criterion sees a law only through chi(w) and chi(2 w): its
        # value does not rank laws (measured: Gaussian records at 2 pi f sigma = 0.5 and 1
        # came out as 'uniform', 8 % and 25 % low). With the law not given, the moment route
        # measures the std law-free (the shape from the fourth moment)
        notes.append(_LAW_FREE_NOTE)
        laws = ("gaussian",)
        law_free = True
    known = _families(T)
    unknown = [name for name in laws if name not in known]
    if unknown or not laws:
        raise ValueError(f"laws must name families among {sorted(known)}; got {list(laws)}")
    N = yv.size
    band_given = _band(band_hz)
    f_start = (
        positive(frequency, "frequency")
        if frequency is not None
        else periodogram_peak(yv, T, oversample=2)
    )
    step = quantisation_step(yv) if resolution is None else None
    physical = _resolution(resolution, step)
    # the moment route's weights: Gaussian nearly everywhere on a float record, floored at a
    # quarter of the mean variance on a quantised one (jitterid.metrology.moments)
    floor_w = WEIGHT_FLOOR if physical is None else QUANTISED_WEIGHT_FLOOR
    half_bin = 1.0 / (N * T)
    # the IEEE 1057 fit at the start: the tone test, and (aliases) the baseband frequency
    try:
        base_fit: SineFit | None = sine_fit_4(
            yv, np.arange(N, dtype=float) * T, f_start, frequency_bounds=_near(f_start, half_bin)
        )
    except ValueError:  # the start aliases to DC or Nyquist: no sine can be fitted there
        base_fit = None
    if band_given is not None:
        f_base = (
            abs(float(base_fit.frequency))
            if base_fit is not None and base_fit.converged
            else f_start
        )
        base = _baseband(f_base, T)
        cands = _alias_frequencies(base, T, band_given)
    else:
        cands = [f_start]
    cycles = cands[0] * N * T
    if cycles < 2 and frequency is None:
        raise ValueError(
            f"the record holds {cycles:.3g} periods of its sine; at least 2 are needed "
            "(record longer, or give frequency= if the sine is faster than it looks)"
        )
    p_tone = (
        tone_significance(yv, float(base_fit.residuals @ base_fit.residuals))
        if base_fit is not None
        else 1.0
    )
    # the aliases are a tie with the jitter scale free: fit one (the given frequency's, else
    # the lowest), the others follow from it (f sigma is what the samples see)
    fc = min(cands, key=lambda f: abs(f - f_start)) if frequency is not None else cands[0]
    band = _near(fc, half_bin)
    folding = folding_check(fc, T, N)
    hopeless = p_tone >= ALPHA_TONE or folding is not None
    # the harmonics tested (and held) at the IEEE 1057 fit's frequency: a given frequency a
    # third of a bin off (a generator's nominal setting) left HD3 at -60 dBc "not
    # significant" (its column 1.8 rad out of phase over the record) and the measurement
    # LACK_OF_FIT
    f_ref = (
        _refined_frequency(yv, T, fc, band, base_fit if fc == f_start else None)
        if harmonics > 1 and not hopeless
        else None
    )
    H = _harmonics_present(yv, T, f_ref or fc, harmonics) if not hopeless else 1
    if harmonics > H:
        notes.append(
            f"harmonics {H + 1}..{harmonics} are not significant in the record: {H} fitted"
        )
    fam_names = laws[:1] if hopeless else laws
    route = "gaussian" if hopeless else method
    model = SineWave(band_hz=band, harmonics=H)
    # the structured likelihood (a pure tone, its laws), else the generic quadrature
    structured = all(sine_ml_applies(model, known[name]) for name in fam_names)
    # with harmonics, the pure tone's routes on the record less them: the harmonics held at
    # their least-squares fit and the fundamental measured by the structured likelihood
    # (method="ml"; the generic quadrature was minutes at N = 4096 and Gaussian noise only)
    # or by the moment route (method="gaussian"; the Gaussian criterion with harmonics was
    # 9 CPU-s at N = 2^16), where they are small beside the fundamental
    # (jitterid.metrology.held)
    held: HeldHarmonics | None = None
    tone = SineWave(band_hz=band)
    if not hopeless and H > 1 and all(sine_ml_applies(tone, known[n]) for n in fam_names):
        held = hold_harmonics(yv, T, f_ref, H) if f_ref is not None else None
    if law_free and H > 1 and held is None:  # the moment route's law-free std is a tone's
        notes[notes.index(_LAW_FREE_NOTE)] = _HARMONICS_GAUSSIAN_NOTE
    full_model = model
    if held is not None:
        model, structured = tone, True
    y_fit = yv if held is None else yv - held.offset
    H_fit = 1 if held is not None else H
    seconds = N * sum(_GENERIC_SECONDS_PER_SAMPLE[n] for n in fam_names)
    if route == "ml" and not structured and seconds > _COST_LIMIT:
        if not fallback:
            raise ValueError(
                f"the exact likelihood with {H} harmonic(s) (the generic quadrature) would "
                f"cost about {seconds:.3g} CPU-s on N = {N} samples with the families "
                f"{list(fam_names)}: give one law (laws=[...]), or a shorter record"
            )
        return _by_gaussian_criterion(
            (yv, T, frequency, asked, band_hz, harmonics, resolution),
            f"the exact likelihood with {H} harmonics (the generic quadrature) would cost "
            f"about {seconds:.3g} CPU-s here ({len(fam_names)} families, N = {N})",
        )
    try:
        same = base_fit if (fc == f_start and base_fit is not None) else None
        mf_start: MomentFit | None = None
        if held is not None:
            theta, sj, sv, slope_std, fit4, mf_start = _start_moments(
                y_fit, T, fc, band, weight_floor=floor_w
            )
        elif harmonics == 1 and not hopeless:
            theta, sj, sv, slope_std, fit4, mf_start = _start_moments(
                yv, T, fc, band, same, weight_floor=floor_w
            )
        else:
            theta, sj, sv, slope_std, fit4 = _start_fit(yv, T, fc, band, same)
    except ValueError as exc:
        if p_tone < ALPHA_TONE:
            raise
        raise ValueError(
            f"no tone stands out of the record (the periodogram's peak, {fc:.6g} Hz, is not "
            f"a sine that can be fitted: {exc}); check that the test signal reaches the "
            "converter, or give frequency= if the tone is known"
        ) from None
    # the moment route (a few passes, law-free variance profile) for a pure tone: the
    # answer of method="gaussian", the likelihood's start and its numeric noise floor
    mf: MomentFit | None = None
    if H_fit == 1:
        first = fam_names[0] if fam_names[0] in ROUTE_LAWS else "gaussian"
        if law_free and route == "gaussian":
            first = "free"
        mf = mf_start if first == "gaussian" and mf_start is not None else None
        mf = mf or moment_route(y_fit, T, fit4, first, weight_floor=floor_w)
        if law_free and mf.law == "free" and math.isnan(mf.shape):
            # beyond ~0.2 rad of phase spread the law's shape moves the std and the moments
            # cannot tell it (the law-free interval spans the shapes; its middle is 15-26 %
            # off for a uniform or dual Dirac at 0.6-1 rad): the likelihood chooses the law
            out = _measure(
                yv,
                T,
                frequency,
                asked,
                band_hz,
                harmonics,
                "ml",
                resolution,
                fallback=False,
            )
            spread = 2 * math.pi * out.frequency * out.jitter_std
            note = (
                f"method='gaussian': at this phase spread (2 pi f sigma = {spread:.2g} rad) "
                "the moments cannot tell the jitter law's shape, which moves the std: measured "
                "by the exact likelihood over the laws (give one law to assume it on the "
                "moment route)"
            )
            return replace(out, message=f"{out.message}; {note}")
    floor = _ml_floor(physical, mf, float(fit4.amplitude), structured)
    # a quantised record under the structured likelihood: each sample the probability of its
    # bin (the noise std searched is the noise before the quantiser, down to a fraction of a
    # step); the Gaussian criterion and the generic likelihood model the quantiser's error
    # as Gaussian noise (dither_finding says when that is not so)
    bin_step = step if (step and route == "ml" and structured) else None
    if bin_step:
        total = math.sqrt(mf.noise_var) if mf is not None and mf.noise_var > 0 else sv
        if _before_quantiser(total, bin_step, 0.0) >= BIN_DITHER * bin_step:
            bin_step = None  # dithered: the bin is Gaussian to the fit (and 2-3x cheaper)
    if bin_step:
        numeric = _ml_floor(None, mf, float(fit4.amplitude), structured)
        floor = max(numeric, BIN_NOISE_FLOOR * bin_step)
    data = SampledData(y_fit, T, None, resolution=floor)
    theta_h = _harmonic_start(model, y_fit, T, theta)
    first_family = fam_names[0]
    gauss_first = None
    if (
        mf is not None
        and (mf.law == first_family or (mf.law == "free" and first_family == "gaussian"))
        and math.isfinite(mf.jitter_var)
    ):
        gauss_first = _moment_result(mf, known[first_family], model, physical)
    fast_done = route == "gaussian" and gauss_first is not None
    if not fast_done:
        _check_cost(N, H_fit, len(fam_names))
    try:
        if gauss_first is not None and fast_done:
            best = gauss_first
        else:
            best = _fit_one(
                data,
                model,
                known[first_family],
                theta_h,
                sj,
                sv,
                route,
                gauss=gauss_first,
                q_step=bin_step,
            )
        # the other families at the chosen alias: from its IEEE starts and from the first
        # family's fit, the better end kept
        fitted: dict[str, FitResult] = {first_family: best}
        sine = np.asarray(best.x[best.layout.slice("system")], dtype=float)
        other = (sine, best.jitter_std, float(best.x[-1]))
        ranked: dict[str, float] = {}  # the ranked-out families' upper estimates of ln L
        # the first family's fit is a Gaussian's maximum: a scale mixture, which nests it, is
        # ranked from there (rank_sine_law's nested)
        nests_gaussian = first_family == "gaussian" and best.status in (
            FitStatus.CONVERGED,
            FitStatus.AT_BOUND,
        )
        later = list(fam_names[1:])
        starts: dict[str, RankStart] = {}
        if route == "ml" and structured:
            # each ranking's start on the subsample first, then the rankings in the order of
            # their subsample ln L less its BIC penalty, the likeliest first, so that the
            # others are ranked out against it (a scale mixture ranked from the Gaussian it
            # nests is ranked last, from there). A 12-bit dual-Dirac record of 2^16 samples:
            # the uniform, ranked before the dual Dirac, led the Gaussian and was fitted to
            # its maximum (16 passes of the record, 15 CPU-s)
            for name in later:
                if not (nests_gaussian and ranked_nested(known[name])):
                    starts[name] = rank_start(
                        y_fit,
                        T,
                        model,
                        known[name],
                        _other_start(data, known[name], other),
                        noise_floor=floor,
                        quantisation_step=bin_step,
                    )

            # (stable: the given order among those not fitted on a subsample, last)
            later.sort(key=lambda n: starts[n].bic() if n in starts else math.inf)
        for name in later:
            alt = None
            if route == "ml" and structured:
                # rank before the full fit: from the first family's fit (the full route's
                # second start), given up where it cannot come within the margin of the lead
                lead = _leader(fitted, N)
                rival_ll, rival_p = (
                    (-math.inf, 0) if lead is None else (-0.5 * lead.cost, int(lead.x.size))
                )
                # (far behind the lead already on its ranking's subsample: no pass of the
                # whole record, sinelik_subrank)
                sub_rank = (
                    rank_on_subsample(
                        y_fit, T, model, known[name], starts[name], lead, quantisation_step=bin_step
                    )
                    if name in starts and lead is not None
                    else None
                )
                if sub_rank is not None:
                    fitted[name] = sub_rank.fit
                    ranked[name] = sub_rank.loglik_upper
                    continue
                rank = rank_sine_law(
                    y_fit,
                    T,
                    model,
                    known[name],
                    starts.get(name, _other_start(data, known[name], other)),
                    rival_loglik=rival_ll,
                    rival_n_params=rival_p,
                    noise_floor=floor,
                    nested=nests_gaussian,
                    quantisation_step=bin_step,
                )
                if rank.ranked_out:
                    fitted[name] = rank.fit
                    ranked[name] = rank.loglik_upper
                    continue
                alt = rank.fit
            # (the likelihood's start under a law the moment route inverts: its few passes,
            # as for the first family, not the Gaussian criterion's search)
            gauss_start = None
            if route == "ml" and H_fit == 1 and name in ROUTE_LAWS:
                mf_name = moment_route(y_fit, T, fit4, name, weight_floor=floor_w)
                if math.isfinite(mf_name.jitter_var):
                    gauss_start = _moment_result(mf_name, known[name], model, physical)
            fitted[name] = _fit_one(
                data,
                model,
                known[name],
                theta_h,
                sj,
                sv,
                route,
                other=other,
                gauss=gauss_start,
                alt=alt,
                q_step=bin_step,
            )
    except RuleBudgetError as exc:
        # a long record with harmonics: the generic rule cannot resolve the noise
        if not fallback:
            raise
        return _by_gaussian_criterion(
            (yv, T, frequency, asked, band_hz, harmonics, resolution),
            f"the exact likelihood's quadrature exceeded its budget ({exc})",
        )

    if held is not None:  # (each family's fit as the tone's with its harmonics)
        fitted = {name: held.attach(r, full_model) for name, r in fitted.items()}
        model = full_model
    cands_law = []
    for name, r in fitted.items():
        p = r.x.size
        ll = ranked.get(name, -0.5 * r.cost)
        cands_law.append(
            LawCandidate(
                name,
                ll,
                p,
                2 * p - 2 * ll,
                p * math.log(N) - 2 * ll,
                r.jitter_std,
                r.status,
                name in ranked,
            )
        )
    ok = [c for c in cands_law if c.status in (FitStatus.CONVERGED, FitStatus.AT_BOUND)]
    chosen = min(ok or cands_law, key=lambda c: c.bic)
    r = fitted[chosen.name]
    status, message = r.status, r.message
    if not ok:
        message = f"no family's fit converged; the lowest BIC is reported: {message}"
    status, message = _better_unsettled(cands_law, chosen, fitted, status, message)
    status, message = _noise_floor_status(
        status, message, r, floor, None if bin_step else physical, mf
    )
    f_fit = float(r.params["frequency_hz"])
    aliases = tuple(
        AliasCandidate(f_fit + (f - fc), -0.5 * r.cost, r.jitter_std * f_fit / (f_fit + f - fc))
        for f in cands
    )
    # (fast_done: the first family's fit is the moment route's, gauss_first)
    on_route = fast_done and mf is not None and chosen.name == first_family
    if on_route:
        assert mf is not None
        resid, sd = mf.residuals, np.sqrt(np.maximum(mf.variance, 0.0))
    else:
        resid, sd = _model_residuals(yv, T, r)
    jstd, jse = r.jitter_std, r.jitter_std_stderr
    jvar, jvar_se = math.nan, math.nan
    if on_route:
        assert mf is not None
        jstd, jse, jvar, jvar_se = (
            mf.jitter_std,
            mf.jitter_std_stderr,
            mf.jitter_var,
            mf.jitter_var_stderr,
        )
    # the per-sample phase error: periodic and coloured jitter (informational findings;
    # a coloured jitter's interval is widened to its Newey-West value)
    decomposition: JitterDecomposition | None = None
    info: list[Finding] = []
    if not hopeless:
        # with harmonics, the moment route's Newey-West ratio on the fitted model's residuals
        # (its variance profile is the fundamental's: the harmonics' slopes are 1e-3 of it)
        nw_base = (
            mf
            if H_fit == 1
            else moment_route(
                yv, T, replace(fit4, residuals=resid), "gaussian", weight_floor=floor_w
            )
        )
        decomposition, info, widened = _phase_findings(yv, T, r, resid, sd, jstd, nw_base)
        if widened is not None and nw_base is not None:
            if on_route:
                jstd, jse, jvar, jvar_se = (
                    widened.jitter_std,
                    widened.jitter_std_stderr,
                    widened.jitter_var,
                    widened.jitter_var_stderr,
                )
            elif nw_base.jitter_var_stderr > 0:
                # the fit assumes independent samples: widen its standard error by the
                # moment route's Newey-West / independent-sample ratio
                jse *= max(widened.jitter_var_stderr / nw_base.jitter_var_stderr, 1.0)
    if held is not None:
        # the harmonics' own jitter, left out of the fundamental's variance profile: its
        # first-order bias of the std (jitterid.metrology.held), added to the interval
        bias = held.jitter_std_bias(r, bin_step)
        if math.isfinite(bias):
            jse = math.hypot(jse, abs(bias) * jstd)
            if math.isfinite(jvar_se):  # (the moment route's interval is the variance's)
                jvar_se = math.hypot(jvar_se, 2 * abs(bias) * max(jvar, 0.0))
        notes.append(
            f"the harmonics' own jitter (their slopes {held.slope_share:.2g} of the "
            "fundamental's), left out of the fundamental's variance profile, biases the std "
            f"by {bias * 100:+.2g} % to first order: added to its standard error"
        )
    if route == "ml" and structured and not on_route:
        # a law's hard edges sharper than the record resolves: the interval is too narrow
        edge = sharp_edge_finding(r, N)
        if edge is not None:
            info = [*info, edge]
    noise, noise_se = float(r.params["noise_std"]), _stderr(r, "noise_std")
    if bin_step:  # the noise before the quantiser: the record's, its error included
        total = math.sqrt(noise * noise + bin_step * bin_step / 12.0)
        noise, noise_se = total, noise_se * noise / total
    if not hopeless and not bin_step:
        undithered = dither_finding(step, noise)
        if undithered is not None:
            info = [*info, undithered]
    lsb = step if step else (physical * math.sqrt(12.0) if physical else None)
    pj_f = decomposition.pj_frequency_hz if decomposition and decomposition.periodic else None
    findings = _adequacy(
        yv, T, resid, sd, float(r.params["frequency_hz"]), step, p_tone, folding, lsb, pj_f
    )
    findings = (*findings, *info)
    status, message = _judge(status, message, r, findings)
    if status is FitStatus.CONVERGED and info:
        message += "; " + "; ".join(f.message for f in info)
    if len(aliases) > 1 and status is FitStatus.CONVERGED:
        status = FitStatus.UNIDENTIFIABLE
        message = (
            f"the frequency is not identified among {len(aliases)} aliases in band_hz: with "
            "the jitter's scale free, the samples see only f times the jitter std, so each "
            "alias fits equally with its own jitter std (listed). Give the frequency "
            "(frequency=...), or rank the aliases under a known jitter law "
            "(alias_likelihoods)"
        )
    if notes:
        message += "; " + "; ".join(notes)
    return JitterMeasurement(
        jitter_std=jstd,
        jitter_std_stderr=jse,
        noise_std=noise,
        noise_std_stderr=noise_se,
        frequency=f_fit,
        frequency_stderr=_stderr(r, "frequency_hz"),
        amplitude=float(r.params["amplitude"]),
        phase_rad=float(r.params["phase_rad"]),
        offset=float(r.params["offset"]),
        law=r.jitter_law,
        family=LAW_FREE if (on_route and mf is not None and mf.law == "free") else chosen.name,
        laws=tuple(cands_law),
        aliases=aliases,
        fit=r,
        status=status,
        message=message,
        slope_regression_std=slope_std,
        T=T,
        findings=findings,
        tone_p_value=p_tone,
        harmonics_fitted=H,
        quantisation_step=step,
        jitter_var=jvar,
        jitter_var_stderr=jvar_se,
        noise_floor=physical,
        decomposition=decomposition,
    )


#: :attr:`JitterMeasurement.family` where the moment route measured the std law-free.
LAW_FREE = "law-free"
_LAW_FREE_NOTE = (
    "method='gaussian' does not rank laws: with several laws given, the std is measured "
    "law-free (the law's shape from the fourth moment, its uncertainty in the interval); "
    "give one law to assume it"
)
_HARMONICS_GAUSSIAN_NOTE = (
    "method='gaussian' does not rank laws: with strong harmonics (not held) the std is "
    "measured by the Gaussian criterion (the jitter through its variance), its interval "
    "the robust sandwich, which holds whatever the law's shape at a small phase spread"
)


def _by_gaussian_criterion(
    call: tuple[
        FloatArray,
        float,
        float | None,
        Sequence[str],
        tuple[float, float] | None,
        int,
        float | None,
    ],
    reason: str,
) -> JitterMeasurement:
    """:func:`measure_jitter` of ``call`` (y, T, frequency, laws, band_hz, harmonics,
    resolution) with ``method="gaussian"``, where the exact likelihood is out of reach:
    ``reason`` and what was done instead in its message."""
    y, T, frequency, laws, band_hz, harmonics, resolution = call
    out = _measure(
        y, T, frequency, laws, band_hz, harmonics, "gaussian", resolution, fallback=False
    )
    note = (
        f"method='ml': {reason}; measured with method='gaussian' instead (the law's shape "
        "is not chosen; for the likelihood give one law, laws=['gaussian'], or fewer "
        "samples)"
    )
    return replace(out, message=f"{out.message}; {note}")


def _leader(fitted: dict[str, FitResult], N: int) -> FitResult | None:
    """The ranking's rival: the lowest-BIC fit among those fitted to their maximum (None:
    none is, and nothing is ranked out)."""
    ok = (FitStatus.CONVERGED, FitStatus.AT_BOUND)
    done = [r for r in fitted.values() if r.status in ok and np.isfinite(r.cost)]
    if not done:
        return None
    return min(done, key=lambda r: r.cost + r.x.size * math.log(N))


def _band(band_hz: tuple[float, float] | None) -> tuple[float, float] | None:
    if band_hz is None:
        return None
    try:
        lo, hi = (float(v) for v in band_hz)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"band_hz must be a pair (low, high) in Hz; got {band_hz!r}") from exc
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise ValueError(f"band_hz must satisfy 0 <= low < high < inf (Hz); got {band_hz!r}")
    return (lo, hi)


def _near(f: float, half_bin: float) -> tuple[float, float]:
    """The frequency search interval around a start: four half-bins either side."""
    return (max(f - 4 * half_bin, 0.5 * f), f + 4 * half_bin)


def _baseband(f: float, T: float) -> float:
    x = (f * T) % 1.0
    return (1.0 - x if x > 0.5 else x) / T


def _moment_result(
    mf: MomentFit, family: JitterFamily, model: SineWave, physical: float | None
) -> FitResult:
    """The moment route's estimate as a :class:`FitResult` of ``model`` (parameters, a
    diagonal heteroscedasticity-consistent covariance, the Gaussian criterion as cost)."""
    # the family's scale per unit std (a scale family's start is linear in the std), taken
    # inside its bounds: at a std of 1 (s) the start is clipped to the upper bound (10 T
    # here), and the fit's scale, law and error bars came out 1e-8 to 1e-2 of the truth
    lo, hi = family.bounds[0]
    mid = math.sqrt(lo * hi)
    per_std = float(family.start_for_std(mid)[0]) / mid
    std = min(max(mf.jitter_std, lo / per_std), hi / per_std)
    noise = math.sqrt(max(mf.noise_var, 0.0))
    noise_se = (
        mf.noise_var_stderr / (2 * noise)
        if noise > 0 and mf.noise_var - 1.96 * mf.noise_var_stderr > 0
        else 0.5 * math.sqrt(mf.noise_var_stderr)
    )
    x = np.array([std * per_std, mf.amplitude, mf.phase_rad, mf.frequency_hz, mf.offset, noise])
    se = np.array(
        [
            mf.jitter_std_stderr * per_std,
            mf.amplitude_stderr,
            mf.phase_stderr,
            mf.frequency_stderr,
            mf.offset_stderr,
            noise_se,
        ]
    )
    names = (*family.param_names, *model.param_names, "noise_std")
    resolved = mf.jitter_var - 1.96 * mf.jitter_var_stderr > 0
    msg = (
        "moment route: IEEE 1057 fit, then the closed-form variance profile by reweighted "
        "least squares (law-free sandwich errors)"
    )
    if not resolved:
        msg += (
            "; the jitter is below what the record resolves: its interval is one-sided (interval())"
        )
    if mf.noise_var - 1.96 * mf.noise_var_stderr <= (physical or 0.0) ** 2:
        msg += "; the additive noise is not resolved (the record is noise-free within its errors)"
    if mf.law == "free" and math.isfinite(mf.kurtosis):
        msg += f"; law-free: the jitter's kurtosis {mf.kurtosis:.2f} (Gaussian 3, uniform 1.8)"
    if mf.note:
        msg += "; " + mf.note
    return FitResult(
        method="gaussian",
        names=names,
        x=x,
        cost=mf.criterion,
        status=FitStatus.CONVERGED,
        message=msg,
        nfev=0,
        system=None,
        jitter_law=family.law([float(x[0])]),
        noise_std=noise,
        freqs=np.zeros(0),
        cov=np.diag(se**2),
        cov_type="robust",
        structure=model,
        jitter_model=family,
    )


def _noise_floor_status(
    status: FitStatus,
    message: str,
    r: FitResult,
    floor: float,
    physical: float | None,
    mf: MomentFit | None,
) -> tuple[FitStatus, str]:
    """AT_BOUND only where the noise floor changes the jitter estimate: a noise std on the
    likelihood's numeric floor (a float record) or on the physical one, with the jitter
    std inside the moment route's interval (which no floor touches), is a boundary
    solution, not a failure: CONVERGED, with the noise reported as below its floor."""
    if status is not FitStatus.AT_BOUND or "noise_std" not in r.params:
        return status, message
    v = float(r.params["noise_std"])
    # on it, or next to it with no error bar: held there by the covariance, whose difference
    # steps would cross the floor (the fit's AT_BOUND says "next to its floor"; its reach
    # is under 1 % of a floor)
    held = not math.isfinite(_stderr(r, "noise_std")) and v <= floor * 1.01
    if v > floor * (1 + 1e-6) and not held:
        return status, message
    if mf is not None and math.isfinite(mf.jitter_var_stderr):
        lo, hi = std_interval(mf.jitter_var, mf.jitter_var_stderr, 0.99)
        if not lo <= r.jitter_std <= hi:
            return status, message
    what = (
        f"the physical floor {floor:.3g} (resolution)"
        if physical is not None and floor <= physical * (1 + 1e-9)
        else f"the likelihood's numeric floor {floor:.3g} (a fraction of the jitter's spread)"
    )
    return FitStatus.CONVERGED, (
        f"converged with the noise std below what the record resolves: it stops at {what}, "
        "which does not change the jitter std (the moment route, which no floor touches, "
        "agrees)"
    )


def _phase_findings(
    y: FloatArray,
    T: float,
    r: FitResult,
    resid: FloatArray,
    sd: FloatArray,
    total_std: float,
    mf: MomentFit | None,
) -> tuple[JitterDecomposition, list[Finding], MomentFit | None]:
    """The phase-error analysis of the chosen fit: the decomposition, its informational
    findings, and (a coloured jitter) the moment fit ``mf`` again with a Newey-West
    covariance."""
    f0 = float(r.params["frequency_hz"])
    N = y.size
    phase_k = 2 * math.pi * f0 * T * np.arange(N, dtype=float) + float(r.params["phase_rad"])
    mean = y - resid
    Ad = math.sqrt(2.0 * float(np.mean((mean - np.mean(mean)) ** 2)))
    dec, _ = phase_error_analysis(resid, sd**2, phase_k, Ad, f0, T, total_std)
    out: list[Finding] = []
    widened: MomentFit | None = None
    if dec.periodic:
        out.append(
            Finding(
                "periodic-jitter",
                dec.pj_p_value,
                f"periodic jitter found in the per-sample phase error: {dec.summary()}",
            )
        )
    if dec.coloured:
        lags = newey_west_lags(N, dec.decay)
        dec = JitterDecomposition(**{**dec.__dict__, "hac_lags": lags})
        if mf is not None:
            widened = moment_route(
                y, T, _fit4_of(mf), mf.law, hac_lags=lags, weight_floor=mf.weight_floor
            )
        out.append(
            Finding(
                "coloured-jitter",
                dec.whiteness_p_value,
                "the jitter is correlated from sample to sample (lag-1 autocorrelation of the "
                f"phase error {dec.lag1_autocorrelation:.2f}, whiteness p = "
                f"{dec.whiteness_p_value:.2g}): the rms is still right, and its interval is "
                f"the Newey-West one ({lags} lags) in place of the independent-sample one",
            )
        )
    return dec, out, widened


def _fit4_of(mf: MomentFit) -> SineFit:
    """The four-parameter fit a moment fit was made from (its sine and residuals)."""
    return SineFit(
        amplitude=mf.damped_amplitude,
        phase=mf.phase_rad,
        frequency=mf.frequency_hz,
        offset=mf.offset,
        a=mf.damped_amplitude * math.sin(mf.phase_rad),
        b=mf.damped_amplitude * math.cos(mf.phase_rad),
        residuals=mf.residuals,
        iterations=0,
        converged=True,
        message="the moment fit's sine",
    )


def _model_residuals(y: FloatArray, T: float, r: FitResult) -> tuple[FloatArray, FloatArray]:
    """y - E y and the per-sample std (jitter and noise) of a fitted tone model."""
    sig = r.signal()
    mp = sig.jitter_moments(r.jitter_law, T, y.size) if hasattr(sig, "jitter_moments") else None
    if mp is None or mp.var is None:  # pragma: no cover - every tone signal has them
        mom = sample_moments(sig, r.jitter_law, T, y.size)
        mean, var = mom.mean, mom.var
    else:
        mean, var = mp.mean, mp.var
    noise = float(r.params.get("noise_std", 0.0))
    return y - mean, np.sqrt(np.maximum(var, 0.0) + noise**2)


def _adequacy(
    y: FloatArray,
    T: float,
    resid: FloatArray,
    sd: FloatArray,
    f0: float,
    step: float | None,
    p_tone: float,
    folding: Finding | None,
    lsb: float | None = None,
    pj_frequency: float | None = None,
) -> tuple[Finding, ...]:
    """The findings of :mod:`jitterid.metrology.adequacy` on the chosen fit (its residuals
    y - E y and per-sample std); ``lsb``: the converter's step, detected or from the given
    resolution (lines below half of it are the quantiser's own)."""
    out: list[Finding] = []
    if folding is not None:
        out.append(folding)
    if p_tone >= ALPHA_TONE:
        out.append(
            Finding(
                "no-tone",
                p_tone,
                f"no tone stands out of the record (F test of the sine against the offset "
                f"alone, p = {p_tone:.2g} after the choice among {y.size // 2} bins): the "
                "record is noise, or the tone is below it; check that the test signal reaches "
                "the converter, record longer, or give frequency= if the tone is known",
            )
        )
    if out:
        return tuple(out)
    rail = rail_check(y, step, y - resid, sd)
    if rail is not None:
        out.append(rail)
    lines = residual_lines(resid, sd, T, f0, step=lsb)
    if pj_frequency is not None:  # the periodic jitter's sidebands h f0 +- m f_p: not spurs
        bin_hz = 1.0 / (y.size * T)
        # (and at the odd harmonics' too: the residual is normalised by a std that varies
        # with cos 2 phi, which mixes the sidebands up by 2 f0)
        sidebands = [
            _baseband(h * f0 + sgn * m * pj_frequency, T)
            for h in (1, 3, 5, 7)
            for m in (1, 2, 3)
            for sgn in (1, -1)
        ]
        lines = tuple(
            ln for ln in lines if min(abs(ln.frequency_hz - sb) for sb in sidebands) > 1.5 * bin_hz
        )
    if lines:
        out.append(_lines_finding(lines))
    return tuple(out)


def _lines_finding(lines: tuple[SpectralLine, ...]) -> Finding:
    parts = []
    harmonics = sorted({ln.harmonic for ln in lines if ln.harmonic >= 2})
    for ln in lines[:4]:
        what = (
            f"harmonic {ln.harmonic}"
            if ln.harmonic >= 2
            else ("the tone itself" if ln.harmonic == 1 else "not a harmonic")
        )
        parts.append(
            f"{ln.frequency_hz:.6g} Hz ({what}, amplitude {ln.amplitude:.3g}, "
            f"{ln.power_ratio:.3g} x the floor)"
        )
    more = f" and {len(lines) - 4} more" if len(lines) > 4 else ""
    # the tone's own line beside harmonics: the distortion fitted as jitter misfits the tone
    # (a 12-bit record with HD2 and HD3, N = 2^16: a dual Dirac 1.5 x the truth, the tone's
    # line at 4e3 x the floor), not a second source
    if harmonics and all(ln.harmonic >= 1 for ln in lines):
        fix = (
            f"the source or the converter distorts (or clips) the tone: fit harmonics="
            f"{max(harmonics)}, or lower the amplitude if the record is clipped"
        )
    else:
        fix = (
            "the record holds a second tone or spur besides the fitted one (or the tone is "
            "modulated): filter the source, or remove the spur before measuring"
        )
    return Finding(
        "lines",
        lines[0].p_value,
        f"the residual holds spectral lines the model lacks: {'; '.join(parts)}{more} "
        f"(largest p = {lines[0].p_value:.2g}): {fix}; the jitter std would absorb them",
    )


def _judge(
    status: FitStatus, message: str, r: FitResult, findings: tuple[Finding, ...]
) -> tuple[FitStatus, str]:
    """The measurement's status: the findings first (a record that is not one jittered tone
    is not measured, whatever the search said), then a standard error that cannot be
    computed (never CONVERGED next to a NaN)."""
    kinds = {f.kind: f for f in findings}
    for kind, st in (
        ("folding", FitStatus.UNIDENTIFIABLE),
        ("no-tone", FitStatus.NOT_SIGNIFICANT),
        ("clipping", FitStatus.LACK_OF_FIT),
        ("lines", FitStatus.LACK_OF_FIT),
    ):
        if kind in kinds:
            rest = [f.message for f in findings if f.kind != kind]
            msg = kinds[kind].message + ("; also: " + "; ".join(rest) if rest else "")
            return st, msg
    se = r.jitter_std_stderr
    if status is FitStatus.CONVERGED and not (math.isfinite(se) and se > 0):
        return FitStatus.UNIDENTIFIABLE, (
            f"the jitter std's standard error cannot be computed ({se:g}): the information "
            "matrix is singular at the estimate, so the interval is unknown; the record may "
            "not show the jitter (too little, or hidden by noise): record longer or at a "
            "higher tone frequency"
        )
    return status, message


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
        Highest likelihood first; ``jitter_std_s`` is the known law's std. Every alias is
        ranked in one pass by the Gaussian log-likelihood of its start under the known law
        (the closed-form moments, O(N)); the :data:`ALIAS_FITS` best are fitted by the
        exact likelihood and returned (a band with more than :data:`MAX_ALIASES` aliases is
        refused).

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
    band = _band(band_hz)
    if band is None:
        raise ValueError("band_hz must be a pair (low, high) in Hz holding the aliases")
    t = np.arange(yv.size, dtype=float) * T
    f_p = periodogram_peak(yv, T)
    half_bin = 1.0 / (yv.size * T)
    fit0 = sine_fit_4(yv, t, f_p, frequency_bounds=_near(f_p, half_bin))
    cands = _alias_frequencies(
        _baseband(abs(float(fit0.frequency)) if fit0.converged else f_p, T), T, band
    )
    # one pass each: the Gaussian log-likelihood of the alias's start under the known law
    # (closed-form moments); the likelihood is maximised for the best few only
    starts = []
    for fc in cands:
        near = _near(fc, half_bin)
        theta, _, sv, _ = _start(yv, T, fc, near)
        fit4 = sine_fit_4(yv, t, fc, frequency_bounds=near)
        # the fitted sine is the true one damped by chi(2 pi f) (Lemma 1): undo it
        chi = complex(np.asarray(jitter.cf(np.array([fit4.frequency])))[0]).conjugate()
        if abs(chi) > 1e-3:
            theta[0] = fit4.amplitude / abs(chi)
            theta[1] = fit4.phase - float(np.angle(chi))
        model = SineWave(band_hz=near)
        noise = float(noise_std) if noise_std is not None else sv
        mp = model.signal(theta).jitter_moments(jitter, T, yv.size)
        assert mp is not None
        assert mp.var is not None
        v = np.maximum(mp.var, 0.0) + noise**2 + 1e-300
        score = -0.5 * float(np.sum(np.log(v) + (yv - mp.mean) ** 2 / v))
        starts.append((score, fc, model, theta, sv))
    starts.sort(key=lambda s: -s[0])
    out = []
    for _, _, model, theta, sv in starts[:ALIAS_FITS]:
        x0 = theta if noise_std is not None else np.r_[theta, sv]
        r = fit(data, model, jitter, method="ml", start=x0)
        out.append(
            AliasCandidate(float(r.params["frequency_hz"]), -0.5 * r.cost, float(jitter.std))
        )
    return tuple(sorted(out, key=lambda a: -a.loglik))
