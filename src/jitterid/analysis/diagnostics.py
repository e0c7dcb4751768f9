"""Diagnostics around a fit: is jitter there, are the residuals white, does it matter here.

* :func:`detect_jitter` - before a jitter-aware fit. Under jitter a sample is
  y_k = s(kT + tau_k) + v_k ~ s(kT) + s'(kT) tau_k + v_k, so the residual of an ordinary fit
  has variance sigma_v^2 + sigma_tau^2 s'(kT)^2: it grows with the squared slope of the
  output. Regressing squared residuals on squared model slopes and testing the slope
  coefficient (one-sided t test, H0: no jitter) detects jitter; the coefficient is the
  implied jitter variance (first-order Taylor approximation, see the function's notes).
* :func:`cross_check_jitter` - after a fit: does the fitted (or assumed) jitter std agree
  with what :func:`detect_jitter` implies? A jitter scale collapsed to ~0 while the test
  finds jitter, or a large one where it finds none, is said plainly with what to try.
* :func:`ljung_box`, :func:`input_correlation_test` and :func:`standardized_residuals` -
  after a fit: residuals of a correct model are white and independent of the input.
* :func:`ls_gain_factor` - the ordinary LS fit sees G(f) scaled by |phi(f)|, the jitter's
  characteristic function (paper, Lemma 1 and (13)); :func:`bias_frequency` is where that
  gain bias reaches a tolerance.
* Confidence bands for the plots (:func:`jitterid.analysis.uncertainty.bode_band`,
  :func:`jitterid.analysis.uncertainty.jitter_pdf_band`) live in
  :mod:`jitterid.analysis.uncertainty`.

Frequencies are in Hz; phases in degrees.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, stats

from .._checks import count, real_array
from ..data import SampledData
from ..estimation.covariance import noise_variance_ml
from ..estimation.estimators import as_estimator
from ..estimation.result import FitResult
from ..jitter.laws import JitterFamily, JitterLaw, known_law
from ..moments.sample import sample_moments
from ..systems.tf import TransferFunction

__all__ = [
    "JitterCrossCheck",
    "JitterDetection",
    "ResidualTest",
    "bias_frequency",
    "cross_check_jitter",
    "detect_jitter",
    "input_correlation_test",
    "ljung_box",
    "ls_gain_factor",
    "model_output",
    "standardized_residuals",
]

FloatArray = NDArray[np.float64]


def _level(level: float) -> float:
    if not isinstance(level, (int, float, np.floating)) or not 0 < float(level) < 1:
        raise ValueError(f"level must be a number in (0, 1), e.g. 0.95; got {level!r}")
    return float(level)


def _system(model: FitResult | TransferFunction) -> TransferFunction:
    if isinstance(model, FitResult):
        if model.system is None:
            raise ValueError(
                f"model: a fit of a signal model ({type(model.structure).__name__}) has no "
                "transfer function; these diagnostics need an LTI fit (use FitResult.residuals "
                "for a signal model)"
            )
        return model.system
    if isinstance(model, TransferFunction):
        return model
    raise TypeError(f"model must be a FitResult or a TransferFunction; got {type(model).__name__}")


def _slope_system(tf: TransferFunction) -> TransferFunction:
    """s G(s) for strictly proper G; for biproper G the direct term is dropped first."""
    num = np.asarray(tf.num, float)
    den = np.asarray(tf.den, float)
    if num.size == den.size:
        num = num - num[0] / den[0] * den
        num[0] = 0.0
    return TransferFunction(np.polymul(num, [1.0, 0.0]), den)


def model_output(
    data: SampledData, model: FitResult | TransferFunction
) -> tuple[FloatArray, FloatArray]:
    """The model's output s(kT) and slope s'(kT) at the nominal instants.

    Parameters
    ----------
    data : SampledData
        Its input and grid.
    model : FitResult or TransferFunction
        The fitted system.

    Returns
    -------
    s, slope : ndarray, shape (N,)
        The slope is exact (the response of s G(s)); for a biproper G the jumps of the
        direct term at input switches are not slopes and are left out.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.zoh_input([1.0] * 40, T=0.1)
    >>> data = ji.SampledData(y=ji.Response(G, u)(0.1 * np.arange(40)), T=0.1, u=u)
    >>> s, slope = ji.model_output(data, G)
    >>> s.shape, round(float(s[10]), 4), round(float(slope[0]), 4)
    ((40,), 0.8647, 2.0)
    """
    if isinstance(model, SampledData) and not isinstance(data, SampledData):
        warnings.warn(
            "model_output(model, data) is deprecated: pass the data first, model_output(data, "
            "model)",
            DeprecationWarning,
            stacklevel=2,
        )
        data, model = model, data
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData; got {type(data).__name__}")
    tf = _system(model)
    if data.u is None:
        raise ValueError("data.u: the model is driven by an input, but the data have none")
    t = data.t_nominal
    return tf.response(data.u)(t), _slope_system(tf).response(data.u)(t)


# ------------------------------------------------------------------------ detection


@dataclass(frozen=True, eq=False)
class JitterDetection:
    """Result of :func:`detect_jitter`.

    Attributes
    ----------
    statistic : float
        t statistic of the slope coefficient (H0: no jitter).
    pvalue : float
        One-sided p-value: small values mean the residual variance grows with the slope.
    jitter_std : float
        Implied jitter std sqrt(max(beta, 0)) (s), a first-order approximation.
    jitter_std_ci : tuple of float
        Confidence interval of the implied std, from a heteroscedasticity-robust (HC3)
        interval for beta, clipped at 0.
    noise_std : float
        Implied measurement-noise std sqrt(max(alpha, 0)) (y units).
    coef : ndarray, shape (2,)
        (alpha, beta) of r_k^2 = alpha + beta s'(kT)^2 + e_k.
    level : float
        Confidence level of ``jitter_std_ci``.
    t, residuals, slopes : ndarray
        Nominal instants, residuals y_k - s(kT) and model slopes s'(kT), for plots.

    Examples
    --------
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(20.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=200, noise_std=0.01, rng=2)
    >>> det = ji.detect_jitter(data, G)
    >>> det.detected(), bool(det.pvalue < 0.05)
    (True, True)
    """

    statistic: float
    pvalue: float
    jitter_std: float
    jitter_std_ci: tuple[float, float]
    noise_std: float
    coef: FloatArray
    level: float
    t: FloatArray
    residuals: FloatArray
    slopes: FloatArray

    def detected(self, alpha: float = 0.05) -> bool:
        """True if the test rejects "no jitter" at significance ``alpha``.

        Parameters
        ----------
        alpha : float, optional
            Significance level of the test, in (0, 1).
        """
        return bool(self.pvalue < _level(alpha))

    def summary(self) -> str:
        lo, hi = self.jitter_std_ci
        pct = round(100 * self.level)
        verdict = "jitter detected" if self.detected() else "no jitter detected"
        return (
            f"jitter detection ({verdict} at the 5% level): t = {self.statistic:.3f}, "
            f"p = {self.pvalue:.3g}\n"
            f"  implied jitter std {self.jitter_std:.4g} s, {pct}% interval "
            f"[{lo:.4g}, {hi:.4g}] s (first-order approximation)\n"
            f"  residual std at zero slope {self.noise_std:.4g} (the noise std if that holds)"
        )

    def __str__(self) -> str:
        return self.summary()


def detect_jitter(
    data: SampledData, model: FitResult | TransferFunction, *, level: float = 0.95
) -> JitterDetection:
    """Test for sampling jitter from the residuals of an ordinary fit.

    Parameters
    ----------
    data : SampledData
        The samples.
    model : FitResult or TransferFunction
        An ordinary fit that ignores jitter (``fit(data, structure, NoJitter(), "ls")``).
    level : float
        Confidence level of the implied jitter std's interval.

    Returns
    -------
    JitterDetection

    Notes
    -----
    Under H0 (no jitter, white noise) the squared residuals are homoscedastic, so the
    classical OLS t test of the slope coefficient is valid asymptotically, whatever the
    noise distribution. Measured in the paper's setting (N = 200, 4000 data sets, ordinary
    fits): false-alarm rate 5.9 % +- 0.4 % at nominal 5 % and 1.2 % at nominal 1 %, slightly
    liberal because squared residuals and squared slopes are both right-skewed; power 1.00 at
    the paper's jitter levels (std 0.096 to 0.289 s) and 0.97-0.99 at std 0.012 s.

    The implied std uses the first-order expansion Var s(kT + tau) ~ s'(kT)^2 sigma_tau^2,
    and the ordinary fit is itself biased by the jitter, so it reads low: by about 3 % for
    small jitter and 8 % for U(-0.5, 0.5) with this system (fastest pole 2.5 rad/s), and its
    interval under-covers (measured 88 % at nominal 95 % for small jitter, 73 % for
    U(-0.5, 0.5)). Fit a jitter family for an accurate std with a calibrated interval. The
    model must be right: an under-modelled system leaves slope-correlated residuals that
    also raise the statistic.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> res = jid.fit(data, jid.RationalModel(0, 1), jid.Uniform(0.05))
    >>> det = jid.detect_jitter(data, res)
    >>> det.detected()
    True
    """
    level = _level(level)
    s, slope = model_output(data, model)
    r = data.y - s
    z, x = r**2, slope**2
    if np.ptp(x) <= 1e-12 * max(float(np.max(x)), 1e-300):
        raise ValueError(
            "the model output's slope is (nearly) constant, so variance growth with slope "
            "cannot be tested; use an input that excites the system (switches, a multisine)"
        )
    n = z.size
    X = np.column_stack([np.ones(n), x])
    coef, *_ = np.linalg.lstsq(X, z, rcond=None)
    e = z - X @ coef
    xtx_inv = np.linalg.inv(X.T @ X)
    s2 = float(e @ e) / (n - 2)
    se = float(np.sqrt(s2 * xtx_inv[1, 1]))
    tstat = float(coef[1] / se) if se > 0 else float(np.inf * np.sign(coef[1]))
    pvalue = float(stats.t.sf(tstat, n - 2))
    # HC3 robust variance for the interval (under jitter the errors are heteroscedastic).
    h = np.einsum("ij,jk,ik->i", X, xtx_inv, X)
    meat = (X * (e / (1 - h))[:, None] ** 2).T @ X
    se_rob = float(np.sqrt((xtx_inv @ meat @ xtx_inv)[1, 1]))
    zq = float(stats.norm.ppf(0.5 + level / 2))
    lo, hi = coef[1] - zq * se_rob, coef[1] + zq * se_rob
    return JitterDetection(
        statistic=tstat,
        pvalue=pvalue,
        jitter_std=float(np.sqrt(max(coef[1], 0.0))),
        jitter_std_ci=(float(np.sqrt(max(lo, 0.0))), float(np.sqrt(max(hi, 0.0)))),
        noise_std=float(np.sqrt(max(coef[0], 0.0))),
        coef=np.asarray(coef, dtype=float),
        level=level,
        t=data.t_nominal,
        residuals=r,
        slopes=slope,
    )


# ------------------------------------------------------------------------ cross-check
#: a jitter std below this fraction of T counts as no jitter (as in estimation.checks)
CROSS_COLLAPSE = 1e-3
#: detection p-value below which "jitter is there" is taken as established (the test is
#: slightly liberal at 5 %, so the cross-check asks for much stronger evidence)
CROSS_DETECTED_P = 1e-3
#: detection p-value above which "no jitter is seen" (the test's 5 % level)
CROSS_NOT_DETECTED_P = 0.05
#: factor by which the fit must miss the detection's interval to be called inconsistent
#: (the detection's std is a first-order approximation whose interval under-covers:
#: 73-88 % at nominal 95 %, see detect_jitter)
CROSS_FACTOR = 2.0


@dataclass(frozen=True)
class JitterCrossCheck:
    """Result of :func:`cross_check_jitter`.

    Attributes
    ----------
    verdict : str
        ``"consistent"``, ``"too small"`` (the fitted or assumed jitter std is ~0, or far
        below the detection's interval, while the test finds jitter) or ``"too large"`` (a
        jitter std far above the detection's interval while the test finds none).
    fitted_std, fitted_std_se : float
        The jitter std of the fit (s) and its standard error (0 for a known law, NaN if
        unavailable).
    detected_std, detected_ci, pvalue : float, tuple, float
        What :func:`detect_jitter` implied.
    estimated : bool
        True for a fitted jitter family, False for a known (assumed) law.
    message : str
        Empty when consistent; else what is wrong, with the numbers, and what to try.
    """

    verdict: str
    fitted_std: float
    fitted_std_se: float
    detected_std: float
    detected_ci: tuple[float, float]
    pvalue: float
    estimated: bool
    message: str

    @property
    def consistent(self) -> bool:
        return self.verdict == "consistent"

    def summary(self) -> str:
        if self.consistent:
            return (
                f"jitter cross-check: the {'fitted' if self.estimated else 'assumed'} jitter "
                f"std {self.fitted_std:.3g} s agrees with the detection test (implied "
                f"{self.detected_std:.3g} s, p = {self.pvalue:.2g})"
            )
        return f"warning: jitter cross-check: {self.message}"

    def __str__(self) -> str:
        return self.summary()


def cross_check_jitter(result: FitResult, detection: JitterDetection) -> JitterCrossCheck:
    """Cross-check the jitter std of a fit against :func:`detect_jitter`.

    Parameters
    ----------
    result : FitResult
        A fit: jitter-aware (a jitter family or a known law), or one that ignores the
        jitter (``ls``), which is ``"too small"`` wherever the test finds jitter.
    detection : JitterDetection
        :func:`detect_jitter` on the same data (from an ordinary fit).

    Returns
    -------
    JitterCrossCheck
        ``"too small"`` when the test finds jitter (p < 1e-3) but the fit's std is below
        1e-3 T or its upper two-standard-error bound is below half the detection's
        interval; ``"too large"`` when the test finds none (p >= 0.05) but the fit's lower
        two-standard-error bound exceeds twice the detection's upper bound (and 1e-3 T).
        Otherwise ``"consistent"``.

    Notes
    -----
    The detection's std is a first-order approximation (low by a few per cent, more for
    large jitter) and its interval under-covers, so only a miss by a factor of 2 beyond
    the fit's own uncertainty counts. A large jitter that the test also finds is never
    flagged (the first-order approximation reads low there). An under-modelled system
    also raises the detection statistic, so the message names the model order too.
    """
    if not isinstance(result, FitResult):
        raise TypeError(f"result must be a FitResult; got {type(result).__name__}")
    if not isinstance(detection, JitterDetection):
        raise TypeError(f"detection must be a JitterDetection; got {type(detection).__name__}")
    estimated = isinstance(result.jitter_model, JitterFamily)
    std = float(result.jitter_std)
    try:
        se = float(result.jitter_std_stderr) if estimated else 0.0
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        se = float("nan")
    se_ok = se if np.isfinite(se) else 0.0
    t = np.asarray(detection.t, float)
    T = float(t[1] - t[0]) if t.size > 1 else float("nan")
    lo, hi = detection.jitter_std_ci
    p = float(detection.pvalue)
    what = "fitted" if estimated else "assumed"
    found = (
        f"detect_jitter finds jitter (p = {p:.2g}, implied std {detection.jitter_std:.3g} s, "
        f"interval [{lo:.3g}, {hi:.3g}] s)"
    )
    verdict, message = "consistent", ""
    collapsed = std <= CROSS_COLLAPSE * T
    if as_estimator(result.method).ignores_jitter:  # ls: it assumes no jitter, whatever given
        if p < CROSS_DETECTED_P:
            verdict = "too small"
            message = (
                f"method {result.method!r} ignores the jitter (it fits as if there were none), "
                f"while {found}: its estimates are biased (the gain is seen as |G| |phi(f)|, low "
                "at high frequencies); fit with --method bcls, asml, gaussian or ml and a "
                "--jitter law or family"
            )
    elif p < CROSS_DETECTED_P and (collapsed or std + 2 * se_ok < lo / CROSS_FACTOR):
        verdict = "too small"
        head = (
            f"the {what} jitter std is {std:.3g} s"
            + (f" (± {se:.2g})" if estimated and np.isfinite(se) and not collapsed else "")
            + f", {'~0' if collapsed else 'far below what the data show'}, while {found}"
        )
        if estimated:
            fix = (
                "; a mean-based criterion (bcls) can trade jitter for the system's "
                "coefficients: fit again with --method gaussian, ml or asml, or with the law "
                f"known (e.g. --jitter known:gaussian:sigma={detection.jitter_std:.3g}), "
                "and check the model order (an under-modelled system also raises the test)"
            )
        else:
            fix = (
                "; check the --jitter value and its time unit, fit a jitter family to "
                "estimate it, and check the model order (an under-modelled system also "
                "raises the test)"
            )
        message = head + fix
    elif p >= CROSS_NOT_DETECTED_P and std - 2 * se_ok > max(CROSS_FACTOR * hi, CROSS_COLLAPSE * T):
        verdict = "too large"
        head = (
            f"the {what} jitter std is {std:.3g} s"
            + (f" (± {se:.2g})" if estimated and np.isfinite(se) else "")
            + f", but detect_jitter finds no jitter (p = {p:.2g}; the data allow at most about "
            f"{hi:.3g} s)"
        )
        if estimated:
            fix = (
                "; the jitter parameters may be absorbing model error or noise: compare with "
                "--jitter none, bound the family (e.g. gaussian:sigma_max=...), or check the "
                "model order and the input"
            )
        else:
            fix = (
                "; check the --jitter value and its time unit (a bare number is in the data "
                "file's time_unit), or fit a jitter family (or --jitter none) instead"
            )
        message = head + fix
    return JitterCrossCheck(
        verdict=verdict,
        fitted_std=std,
        fitted_std_se=se,
        detected_std=float(detection.jitter_std),
        detected_ci=(float(lo), float(hi)),
        pvalue=p,
        estimated=estimated,
        message=message,
    )


# ------------------------------------------------------------------------ residual checks


@dataclass(frozen=True, eq=False)
class ResidualTest:
    """A chi-square test on residual correlations.

    Attributes
    ----------
    name : str
        Which test.
    statistic, dof, pvalue : float
        The statistic, its chi-square degrees of freedom and the p-value.
    lags : ndarray
        The lags tested.
    values : ndarray
        The normalised correlations at those lags (about N(0, 1/N) each under H0).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> test = ji.ljung_box(np.random.default_rng(0).standard_normal(100), lags=5)
    >>> test.name, test.dof, test.lags.tolist()
    ('Ljung-Box whiteness', 5, [1, 2, 3, 4, 5])
    >>> test.passed()
    True
    """

    name: str
    statistic: float
    dof: int
    pvalue: float
    lags: NDArray[np.int64]
    values: FloatArray

    def passed(self, alpha: float = 0.05) -> bool:
        """True if H0 (white / independent) is not rejected at significance ``alpha``.

        Parameters
        ----------
        alpha : float, optional
            Significance level of the test, in (0, 1).
        """
        return bool(self.pvalue >= _level(alpha))

    def summary(self) -> str:
        verdict = "passes" if self.passed() else "FAILS"
        return (
            f"{self.name}: {verdict} at the 5% level (chi2 = {self.statistic:.3g}, "
            f"dof {self.dof}, p = {self.pvalue:.3g})"
        )

    def __str__(self) -> str:
        return self.summary()


def _resid(residuals: ArrayLike, name: str = "residuals") -> FloatArray:
    r = real_array(residuals, name, ndim=1)
    if r.size < 8:
        raise ValueError(f"{name} must hold at least 8 values; got {r.size}")
    return r


def _lags(lags: int | None, n: int) -> int:
    if lags is None:
        return max(1, min(20, n // 5))
    lags = count(lags, "lags", minimum=1)
    if lags >= n // 2:
        raise ValueError(f"lags must be below N/2 = {n // 2}; got {lags}")
    return lags


def ljung_box(residuals: ArrayLike, lags: int | None = None) -> ResidualTest:
    """Ljung-Box whiteness test: Q = N (N + 2) sum_k rho_k^2 / (N - k) ~ chi2(lags).

    Parameters
    ----------
    residuals : array_like, shape (N,)
        Residuals (standardised ones after a jitter-aware fit, see
        :func:`standardized_residuals`, since jitter makes them heteroscedastic).
    lags : int, optional
        Number of autocorrelation lags (default min(20, N // 5)).

    Returns
    -------
    ResidualTest

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> e = np.random.default_rng(0).standard_normal(100)
    >>> ji.ljung_box(e, lags=5).passed()
    True
    >>> ji.ljung_box(np.cumsum(e), lags=5).passed()  # a random walk is far from white
    False
    """
    r = _resid(residuals)
    n = r.size
    m = _lags(lags, n)
    c = r - r.mean()
    denom = float(c @ c)
    if denom == 0:
        raise ValueError("residuals are constant; the whiteness test needs varying residuals")
    k = np.arange(1, m + 1)
    rho = np.array([c[j:] @ c[:-j] for j in k]) / denom
    q = float(n * (n + 2) * np.sum(rho**2 / (n - k)))
    return ResidualTest("Ljung-Box whiteness", q, m, float(stats.chi2.sf(q, m)), k, rho)


def input_correlation_test(
    residuals: ArrayLike, u_samples: ArrayLike, lags: int | None = None
) -> ResidualTest:
    """Test that residuals are uncorrelated with the input at lags 0..lags-1.

    Regresses the residuals on the lagged input samples u_{k-j}; with white residuals
    independent of the input, N R^2 ~ chi2(lags) (Ljung, System Identification, 16.6).

    Parameters
    ----------
    residuals : array_like, shape (N,)
    u_samples : array_like, shape (N,)
        The input at the nominal instants (``data.u(data.t_nominal)``).
    lags : int, optional
        Number of lags (default min(20, N // 5)).

    Returns
    -------
    ResidualTest
        ``values`` are the normalised cross-correlations at each lag.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> rng = np.random.default_rng(0)
    >>> u, e = rng.standard_normal(100), rng.standard_normal(100)
    >>> ji.input_correlation_test(e, u, lags=5).passed()
    True
    >>> ji.input_correlation_test(e + u, u, lags=5).passed()
    False
    """
    r = _resid(residuals)
    u = real_array(u_samples, "u_samples", ndim=1)
    if u.size != r.size:
        raise ValueError(
            f"u_samples must have one value per residual: {r.size} residuals, {u.size} inputs"
        )
    n = r.size
    m = _lags(lags, n)
    c = r - r.mean()
    uc = u - u.mean()
    U = np.column_stack([np.r_[np.zeros(j), uc[: n - j]] for j in range(m)])
    if float(np.sum(uc**2)) == 0:
        raise ValueError("the input is constant at the sampling instants; nothing to correlate")
    beta, *_, rank, _ = np.linalg.lstsq(U, c, rcond=None)
    fitted = U @ beta
    stat = float(n * (fitted @ fitted) / (c @ c))
    xc = (U.T @ c) / np.sqrt(float(c @ c) * float(uc @ uc))
    return ResidualTest(
        "residual-input independence",
        stat,
        int(rank),
        float(stats.chi2.sf(stat, int(rank))),
        np.arange(m),
        xc,
    )


def standardized_residuals(data: SampledData, result: FitResult) -> FloatArray:
    """(y_k - E y_k) / sqrt(Var y_k) under the fitted system, jitter law and noise.

    E y_k = E s(kT + tau) and Var y_k = Var s(kT + tau) + sigma_v^2 with tau from
    ``result.jitter_law``. If the fit has no noise std (``result.noise_std`` None or 0), sigma_v^2
    is its maximum-likelihood value given the residuals r_k and the jitter variances (a 1-D search),
    so that samples where the output is flat and the jitter variance vanishes are not divided by ~0.

    Parameters
    ----------
    data : SampledData
    result : FitResult

    Returns
    -------
    ndarray, shape (N,)
        Independent with unit variance if the model is right.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> r = ji.standardized_residuals(data, res)
    >>> r.shape, bool(0.5 < np.std(r) < 1.5)
    ((100,), True)
    """
    if not isinstance(result, FitResult):
        raise TypeError(f"result must be a FitResult; got {type(result).__name__}")
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData; got {type(data).__name__}")
    mom = sample_moments(result.signal(data.u), result.jitter_law, data.T, data.N)
    r = data.y - mom.mean
    noise_var = (result.noise_std or 0.0) ** 2
    if noise_var <= 0:
        noise_var = noise_variance_ml(r, mom.var)
    return np.asarray(r / np.sqrt(mom.var + noise_var), dtype=float)


# ------------------------------------------------------------------------ LS gain bias


def ls_gain_factor(jitter: JitterLaw, f: ArrayLike) -> FloatArray:
    """|phi(f)|: the factor by which an ordinary LS fit sees the gain |G(i 2 pi f)|.

    By Lemma 1 the expected DFT of jittered samples is that of the signal with its spectrum
    multiplied by phi(-f), so a fit that ignores jitter estimates |G phi| instead of |G|;
    the relative gain bias is |phi(f)| - 1 (in dB: 20 log10 |phi(f)|).

    Parameters
    ----------
    jitter : JitterLaw
        The (suspected) jitter law.
    f : array_like
        Frequencies in Hz.

    Returns
    -------
    ndarray
        |phi(f)| in [0, 1], same shape as ``f``.

    Examples
    --------
    >>> import jitterid as ji
    >>> ji.ls_gain_factor(ji.Uniform(0.05), [0.0, 1.0, 5.0]).round(4).tolist()
    [1.0, 0.9836, 0.6366]
    """
    jitter = known_law(jitter)
    freqs = real_array(f, "f")
    return np.asarray(np.abs(jitter.cf(freqs)), dtype=float)


def bias_frequency(jitter: JitterLaw, tol: float = 0.01) -> float:
    """The lowest frequency (Hz) where the LS gain factor |phi(f)| drops to 1 - tol.

    Parameters
    ----------
    jitter : JitterLaw
    tol : float
        Relative gain bias, in (0, 1); 0.01 is a 1 % (0.087 dB) gain error.

    Returns
    -------
    float
        ``inf`` if there is no jitter (|phi| = 1 everywhere).

    Examples
    --------
    >>> import jitterid as ji
    >>> round(ji.bias_frequency(ji.Uniform(0.05), tol=0.01), 3)
    0.781
    """
    tol = _level(tol)
    jitter = known_law(jitter)
    if jitter.std == 0:  # a point mass (NoJitter, or a law shifted from it)
        return float("inf")
    # |phi| ~ 1 - 2 pi^2 sigma^2 f^2 near 0: bracket around that guess, then refine.
    guess = np.sqrt(2 * tol) / (2 * np.pi * jitter.std)
    grid = np.linspace(0.0, 20 * guess, 4001)[1:]
    below = np.flatnonzero(ls_gain_factor(jitter, grid) <= 1 - tol)
    if not below.size:
        return float("inf")
    i = int(below[0])
    lo = 0.0 if i == 0 else float(grid[i - 1])
    return float(
        optimize.brentq(lambda v: float(ls_gain_factor(jitter, v)) - (1 - tol), lo, grid[i])
    )


# ------------------------------------------------------------------------ bands
