"""The jitter meter's fast route: the sine's closed-form jitter moments, fitted in a few passes.

For a tone y_k = A sin(phi_k + w tau_k) + c + v_k, phi_k = w kT + phi, with a symmetric
jitter law of characteristic function chi(u) = E cos(u tau) and chi_m = chi(m w), the
per-sample mean and variance are closed forms (Lemmas 1-2 for one tone)::

    E y_k   = c + A chi_1 sin(phi_k)                                               (F1)
    Var y_k = sigma_v^2 + A^2/2 (1 - chi_1^2) + A^2/2 (chi_1^2 - chi_2) cos(2 phi_k)  (F2)

so, with the damped amplitude A_d = A chi_1 that a least-squares sine fit estimates
(consistently: (F1) is a sine), the squared residuals r_k^2 regress on [1, cos 2 phi_k]
with intercept alpha = sigma_v^2 + (A^2 - A_d^2)/2 and slope

    beta = A_d^2 (1 - chi_2 / chi_1^2) / 2,                                         (F3)

free of the noise and of A. For Gaussian jitter chi_2 / chi_1^2 = exp(-(w sigma)^2), so
(w sigma)^2 = -ln(1 - 2 beta / A_d^2) exactly (the IEEE 1057 slope regression is the
first-order term, 2 beta / A_d^2, hence its -6 % at 0.5 rad); for a uniform law
chi(u) = sin(u a)/(u a) and (F3) is solved for a. The noise follows from alpha:
sigma_v^2 = alpha - A_d^2 (1/chi_1^2 - 1)/2.

The route (:func:`moment_route`): the IEEE 1057 four-parameter fit (O(N) a pass, a few
passes), then (alpha, beta) by iteratively reweighted least squares on r_k^2 with weights
1/Var(r_k^2) ~ 1/v_k^2 (the Gaussian criterion's own weights for the variance
parameters, floored at 1e-3 of the mean variance so that the tone's peaks on a noise-free
record, whose variance is of order (w sigma)^4, do not dominate; at a quarter of it on a
quantised record, whose error at the peaks is not the profile's noise: :data:`WEIGHT_FLOOR`,
:data:`QUANTISED_WEIGHT_FLOOR`; the first reweighting at a quarter whatever the record),
reweighted until the coefficients settle. Its covariance is the
heteroscedasticity-consistent sandwich of those estimating equations (it uses the empirical
r_k^4, so it holds whatever the jitter's law and the noise's), carried to sigma by the
delta method; the mean's parameters enter (alpha, beta) at second order only (E r_k = 0),
and A_d's own variance is added. Nothing
bounds the noise: on a noise-free record sigma_v^2 comes out near 0, on either side, and
the jitter, which (F3) gives without it, is not moved. Where the variance's interval
reaches 0 the jitter is not resolved and its interval is one-sided (``interval``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .sinefit import SineFit

__all__ = ["MomentFit", "moment_route"]

FloatArray = NDArray[np.float64]

#: Below this g = 2 beta / A_d^2 ~ (w sigma)^2 the law's shape moves the std by under
#: 1e-6 (the kurtosis term is (7/12)(K - 3) (w sigma)^4): the law-free route inverts as
#: Gaussian.
_FREE_MIN_G = 1e-6
#: Up to this g (2 pi f sigma up to about 0.2 rad) the fourth moment's h / g^2 rises
#: with the shape (about K / 8) and tells it; beyond it, h is not monotone in the shape,
#: and the law-free route spans the shapes instead (:func:`_shape_span`).
_FREE_MAX_G = 0.04
#: The shapes spanned where the moments cannot tell them: from the dual Dirac (kurtosis 1)
#: to a scale mixture of kurtosis 3.75.
_SPAN = (-1.0, 0.5)
#: The reweighted regression's variances floored at this share of their mean
#: (:func:`moment_route`'s ``weight_floor``): the Gaussian weights 1 / v_k^2 at every sample
#: but those within about 0.03 rad of the tone's peaks on a noise-free record, whose
#: variance is of order (w sigma)^4 (measured, 40 noise-free float records of 4096 samples,
#: 2 ps at 97 MHz: the std's spread 0.0109 of the truth against 0.0135 with a quarter of the
#: mean, the bound 1 / sqrt(2 N) 0.0110; its error against each record's realised jitter
#: 0.0022 against 0.0075; with 4 % noise 22.1 against 26.7 fs; 40 records at 0.5 rad and 1
#: GHz: no change)
WEIGHT_FLOOR = 1e-3
#: ... and on a quantised record (:func:`moment_route`'s ``weight_floor``; the meter's
#: choice where the record is quantised or a resolution is given): a quarter of the mean.
#: An undithered quantiser's error at the tone's peaks, where the signal dwells in a few
#: bins, is not the noise variance alpha - beta the profile assumes, and the Gaussian
#: weights there biased the std (12 bits, 0.2 steps of noise, 5 ps: +0.5 %, 2.6 SEM over 40
#: records of 4096; 2 ps: +0.5 %, 2.5 SEM); a quarter of the mean spreads the intercept
#: over a third of the samples (+0.0 % and +0.1 %), at 1.1-1.2 times the std's error
QUANTISED_WEIGHT_FLOOR = 0.25
#: The regression is reweighted until its coefficients move by under this share of the mean
#: variance (the Gaussian pseudo-likelihood of the profile; at 0.3 rad of phase spread,
#: where the profile near the peaks is a few percent of its mean, the iterates oscillate
#: and settle in about 12), at most :data:`_MAX_REWEIGHTS` times
_REWEIGHT_TOL = 1e-7
_MAX_REWEIGHTS = 30
#: Laws whose (F3) is inverted in closed form or by a one-dimensional solve (``"free"``:
#: with the shape from the fourth moment, law-free).
ROUTE_LAWS = ("gaussian", "uniform", "free")


@dataclass(frozen=True, eq=False)
class MomentFit:
    """What :func:`moment_route` estimated. Times in s, y in its own units.

    Attributes
    ----------
    law : str
        The law (F3) was inverted under (``"gaussian"`` or ``"uniform"``).
    amplitude, damped_amplitude : float
        A (the tone before the jitter's damping) and A_d = A chi(w) (the fitted sine's).
    phase_rad, frequency_hz, offset : float
        The fitted sine's, ``A_d sin(2 pi f kT + phase) + offset``.
    alpha, beta : float
        The variance profile's intercept and cos(2 phi) coefficient, (F2).
    cov_alpha_beta : ndarray, shape (2, 2)
        Their sandwich covariance.
    phase_var, phase_var_stderr : float
        (w sigma)^2, rad^2, unclipped (it may come out below 0 when the jitter is below
        what the record resolves), and its standard error.
    jitter_var, jitter_var_stderr : float
        sigma^2 in s^2, unclipped, and its standard error.
    jitter_std, jitter_std_stderr : float
        sqrt(max(jitter_var, 0)) and its standard error: the delta method, or, where the
        variance's interval reaches 0, sqrt(jitter_var_stderr) / 2 (the scale of the
        one-sided interval).
    noise_var, noise_var_stderr : float
        sigma_v^2 (unclipped) and its standard error.
    amplitude_stderr, frequency_stderr, phase_stderr, offset_stderr : float
        The sine's (heteroscedasticity-consistent, from the fit's residuals).
    residuals : ndarray
        y_k - E y_k.
    variance : ndarray
        The fitted Var y_k, (F2).
    criterion : float
        sum_k ln v_k + r_k^2 / v_k at the estimate (the Gaussian criterion, -2 ln L up to a
        constant, for comparing fits).
    slope_regression_std, slope_regression_noise_std : float
        The IEEE 1057 slope regression's jitter and noise std (s, units of y): its
        regression of r_k^2 on [1, s'(kT)^2] spans the same columns as [1, cos 2 phi_k],
        so it is the unweighted fit of (F2) read to first order: jitter variance
        2 beta_ols / (w A_d)^2, noise variance alpha_ols - beta_ols (clipped at 0).
    shape, kurtosis : float
        ``law="free"``: the shape family's parameter (:func:`_shape_chi`; below 0 a dual
        Dirac plus Gaussian, above 0 a scale mixture of two Gaussians, 0 the Gaussian) and
        the jitter's kurtosis it implies; 0 and NaN under a named law (or where the jitter
        is too small for its shape to matter, (w sigma)^2 < 1e-6); NaN shape where the
        moments cannot tell it (above about 0.2 rad: the interval spans the shapes).
    note : str
        What the route could not do, in words (empty when nothing).
    weight_floor : float
        The ``weight_floor`` it was fitted with.
    """

    law: str
    amplitude: float
    damped_amplitude: float
    phase_rad: float
    frequency_hz: float
    offset: float
    alpha: float
    beta: float
    cov_alpha_beta: FloatArray
    phase_var: float
    phase_var_stderr: float
    jitter_var: float
    jitter_var_stderr: float
    jitter_std: float
    jitter_std_stderr: float
    noise_var: float
    noise_var_stderr: float
    amplitude_stderr: float
    frequency_stderr: float
    phase_stderr: float
    offset_stderr: float
    residuals: FloatArray
    variance: FloatArray
    criterion: float
    slope_regression_std: float = math.nan
    slope_regression_noise_std: float = math.nan
    shape: float = 0.0
    kurtosis: float = math.nan
    note: str = ""
    weight_floor: float = WEIGHT_FLOOR

    def interval(self, level: float = 0.95) -> tuple[float, float]:
        """The jitter std's interval: the variance's normal interval, cut at 0, square-rooted.

        Parameters
        ----------
        level : float, optional
            Coverage, in (0, 1).
        """
        return std_interval(self.jitter_var, self.jitter_var_stderr, level)


def std_interval(var: float, var_se: float, level: float = 0.95) -> tuple[float, float]:
    """sqrt of the normal interval var +- z var_se, cut at 0 (one-sided where it reaches 0).

    Parameters
    ----------
    var, var_se : float
        A variance estimate (unclipped) and its standard error.
    level : float, optional
        Coverage, in (0, 1).

    Returns
    -------
    (float, float)

    Examples
    --------
    >>> std_interval(4.0, 1.0)[0] > 1.0
    True
    >>> std_interval(-1.0, 1.0)[0]
    0.0
    """
    if not 0 < level < 1:
        raise ValueError(f"level must lie in (0, 1); got {level!r}")
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + level / 2))
    lo, hi = var - z * var_se, var + z * var_se
    return (math.sqrt(max(lo, 0.0)), math.sqrt(max(hi, 0.0)))


def _ratio(law: str, s: float) -> float:
    """chi_2 / chi_1^2 at phase spread s = w sigma (rad)."""
    if law == "gaussian":
        return math.exp(-s * s)
    a = math.sqrt(3.0) * s  # uniform on (-a, a) in phase
    if a < 1e-4:
        return 1.0 - s * s + 0.7 * s**4  # series: 1 - s^2 + (7/12)(-6/5) s^4 ...
    return (math.sin(2 * a) / (2 * a)) / (math.sin(a) / a) ** 2


def _invert(law: str, g: float) -> tuple[float, float]:
    """(s^2, d s^2 / d g) with chi_2 / chi_1^2 = 1 - g at phase spread s; g may be <= 0
    (then s^2 is continued linearly: the variance's estimate is unclipped)."""
    if law == "gaussian":
        if g < 1.0:
            return -math.log1p(-g), 1.0 / (1.0 - g)
        return math.inf, math.inf
    if g <= 1e-8:
        return g, 1.0  # the first-order term, for a jitter below the resolution
    # uniform: 1 - ratio(s) is increasing in s up to where chi_1 vanishes (a = pi): bisect
    lo, hi = 0.0, math.pi / math.sqrt(3.0) * 0.999
    if g >= 1.0 - _ratio(law, hi):
        return math.inf, math.inf
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 1.0 - _ratio(law, mid) < g:
            lo = mid
        else:
            hi = mid
    s = 0.5 * (lo + hi)
    h = max(1e-6 * s, 1e-9)
    d = ((1.0 - _ratio(law, s + h)) - (1.0 - _ratio(law, s - h))) / (2 * h)  # dg/ds
    return s * s, 2 * s / d if d > 0 else math.inf


def _long_run(x: FloatArray, lags: int) -> float:
    """The variance of sum_k x_k: sum_k x_k^2 for independent terms (``lags`` = 0), else
    with the lagged products up to ``lags`` added in full (the truncated kernel: the
    Bartlett weights' taper was measured to leave the interval 13 % short on AR(1) 0.9
    jitter at N = 1000), never below the independent value."""
    base = float(x @ x)
    out = base
    for lag in range(1, max(int(lags), 0) + 1):
        out += 2 * float(x[:-lag] @ x[lag:])
    return max(out, base)


def _shape_chi(m: int, s2: float, theta: float) -> float:
    """chi(m w) of the law-free route's shape family at phase variance s2: theta <= 0 a
    dual Dirac +-delta plus Gaussian rho (delta^2 = -theta s2, rho^2 = s2 - delta^2;
    kurtosis 3 - 2 theta^2), theta > 0 two equal-weight Gaussians of variances
    s2 (1 +- theta) (kurtosis 3 (1 + theta^2)); theta = 0 the Gaussian."""
    if theta <= 0:
        d2 = -theta * s2
        return math.cos(m * math.sqrt(d2)) * math.exp(-0.5 * m * m * (s2 - d2))
    return 0.5 * (
        math.exp(-0.5 * m * m * s2 * (1 + theta)) + math.exp(-0.5 * m * m * s2 * (1 - theta))
    )


def _gh(s2: float, theta: float) -> tuple[float, float]:
    """(g, h) of the shape family: g = 1 - chi_2 / chi_1^2 and h = (chi_4 - 4 chi_1 chi_3
    + 6 chi_1^2 chi_2 - 3 chi_1^4) / (8 chi_1^4), the cos(4 phi) coefficient of E r^4 over
    A_d^4 (the module doc's (F4))."""
    c1, c2, c3, c4 = (_shape_chi(m, s2, theta) for m in (1, 2, 3, 4))
    q = c1 * c1
    return 1 - c2 / q, (c4 - 4 * c1 * c3 + 6 * q * c2 - 3 * q * q) / (8 * q * q)


def _s2_for(g: float, theta: float) -> float:
    """The phase variance whose g is ``g`` at shape ``theta`` (g increases with s2 while
    chi_1 > 0.05)."""
    from scipy.optimize import brentq

    hi = 0.5
    while hi < 9.0:
        c1 = _shape_chi(1, hi, theta)
        if c1 < 0.05 or _gh(hi, theta)[0] >= g:
            break
        hi *= 2
    lo_g = _gh(1e-12, theta)[0]
    hi_g = _gh(hi, theta)[0]
    if not lo_g < g < hi_g:
        return math.nan
    return float(brentq(lambda v: _gh(v, theta)[0] - g, 1e-12, hi, xtol=1e-14, rtol=1e-12))


def _free_solve(g: float, h: float, h_se: float) -> tuple[float, float, float]:
    """(s2, theta, spread): the phase variance and shape of the family (:func:`_shape_chi`)
    with the observed g and h, and the range of s2 over every shape whose h lies within
    1.96 ``h_se`` of the observed one (at fixed g). At small phase spread h / g^2 is about
    K / 8 and tells the shape; from about 0.3 rad on, h is not monotone in the shape, and
    at fixed g the shapes' s2 differ: the spread carries that ambiguity into the interval.
    The estimate is the matching shape nearest the Gaussian."""
    thetas = np.linspace(-1.0, 1.0, 41)
    rows = []
    for th in thetas:
        v = _s2_for(g, float(th))
        if math.isfinite(v):
            rows.append((float(th), v, _gh(v, float(th))[1]))
    if not rows:
        return math.nan, 0.0, math.nan
    th_a = np.array([r[0] for r in rows])
    s2_a = np.array([r[1] for r in rows])
    miss = np.array([r[2] for r in rows]) - h
    plausible = np.abs(miss) <= 1.96 * max(h_se, 0.0)
    if not plausible.any():
        plausible = np.abs(miss) == np.min(np.abs(miss))
    roots = []
    for i in range(len(rows) - 1):
        if miss[i] == 0 or miss[i] * miss[i + 1] < 0:
            frac = miss[i] / (miss[i] - miss[i + 1]) if miss[i] != miss[i + 1] else 0.0
            roots.append(th_a[i] + frac * (th_a[i + 1] - th_a[i]))
    theta = float(min(roots, key=abs)) if roots else float(th_a[int(np.argmin(np.abs(miss)))])
    s2 = _s2_for(g, theta)
    spread = float(np.max(s2_a[plausible]) - np.min(s2_a[plausible]))
    return s2, theta, max(spread, 0.0)


def _shape_span(g: float) -> tuple[float, float]:
    """The range of s2 over the shapes :data:`_SPAN` at fixed g (NaN where none fits)."""
    vals = [_s2_for(g, float(th)) for th in np.linspace(_SPAN[0], _SPAN[1], 7)]
    vals = [v for v in vals if math.isfinite(v)]
    return (min(vals), max(vals)) if vals else (math.nan, math.nan)


def _chi1(law: str, s: float) -> float:
    if law == "gaussian":
        return math.exp(-0.5 * s * s)
    a = math.sqrt(3.0) * s
    return 1.0 if a < 1e-8 else math.sin(a) / a


def moment_route(
    y: FloatArray,
    T: float,
    fit4: SineFit,
    law: str = "gaussian",
    *,
    hac_lags: int = 0,
    weight_floor: float = WEIGHT_FLOOR,
) -> MomentFit:
    """The jitter std from (F1)-(F3) of the module doc, in a few passes over the record.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The record at the nominal instants kT.
    T : float
        The sampling interval, s.
    fit4 : SineFit
        A converged four-parameter fit of ``y`` at instants kT (its frequency may be any
        alias: the jitter is converted to seconds with it).
    law : {"gaussian", "uniform", "free"}
        The law (F3) is inverted under; the variance profile itself is law-free.
        ``"free"``: the law's shape is measured too, from the cos(4 phi) harmonic of the
        residuals' fourth power, (F4) of the module doc, within a family spanning kurtosis
        1 (dual Dirac) through 3 (Gaussian) to 6 (a scale mixture), and its uncertainty is
        in the interval: honest for uniform, dual-Dirac and mixture jitter at any phase
        spread, at the price of a wider interval where the spread is large.
    hac_lags : int, optional
        0 (default): the samples' jitter is independent (the heteroscedasticity-consistent
        sandwich); more: a Newey-West (Bartlett) covariance over that many lags, for a
        jitter correlated from sample to sample
        (:func:`jitterid.metrology.phase.newey_west_lags`).
    weight_floor : float, optional
        The regression's variances are floored at this share of their mean in its weights:
        :data:`WEIGHT_FLOOR` (default, the Gaussian weights nearly everywhere) for a float
        record, :data:`QUANTISED_WEIGHT_FLOOR` for a quantised one.

    Returns
    -------
    MomentFit

    Examples
    --------
    >>> import numpy as np
    >>> from jitterid.metrology.sinefit import periodogram_peak, sine_fit_4
    >>> rng = np.random.default_rng(0)
    >>> T, f, N = 1e-3, 123.0, 20000
    >>> tau = 50e-6 * rng.standard_normal(N)  # 2 pi f sigma = 0.039 rad, noise-free
    >>> y = np.sin(2 * np.pi * f * (np.arange(N) * T + tau))
    >>> fit4 = sine_fit_4(y, np.arange(N) * T, periodogram_peak(y, T))
    >>> m = moment_route(y, T, fit4)
    >>> lo, hi = m.interval()
    >>> bool(lo < 50e-6 < hi), bool(abs(m.jitter_std / 50e-6 - 1) < 0.02)
    (True, True)
    """
    if law not in ROUTE_LAWS:
        raise ValueError(f"law must be one of {ROUTE_LAWS}; got {law!r}")
    if not 0 < weight_floor <= 1:
        raise ValueError(
            f"weight_floor must lie in (0, 1] (a share of the mean variance); got {weight_floor!r}"
        )
    if not fit4.converged:
        raise ValueError(f"fit4 did not converge ({fit4.message}); fit the sine first")
    n = y.size
    p_mean = 4
    k = np.arange(n, dtype=float)
    w = 2 * math.pi * fit4.frequency
    phase_k = w * T * k + fit4.phase
    sin_k = np.sin(phase_k)
    cos_k = np.cos(phase_k)
    c2 = cos_k * cos_k - sin_k * sin_k
    r = np.asarray(fit4.residuals, dtype=float)
    r2 = r * r * (n / (n - p_mean))  # the fit's degrees of freedom
    X = np.empty((n, 2))
    X[:, 0] = 1.0
    X[:, 1] = c2
    gram_w = X.T @ X  # (the normal equations' matrix of the pair (coef, wts) below)
    coef = np.linalg.solve(gram_w, X.T @ r2)
    ols = coef * ((n - p_mean) / n)  # the plain regression of r^2 (IEEE 1057's, reparametrised)
    wts = np.ones(n)  # (coef, wts): a weighted least squares solution and its weights
    # (the normal equations of [1, cos 2 phi] by five dot products a reweighting)
    c2_mean = float(np.mean(c2))
    c2c2, c2r2 = c2 * c2, c2 * r2
    for i in range(_MAX_REWEIGHTS):
        v = coef[0] + coef[1] * c2
        vbar = float(coef[0] + coef[1] * c2_mean)
        if not vbar > 0:
            break
        # (the first reweighting from the plain regression, whose profile can cross zero
        # near the tone's peaks, floored at a quarter: a profile at 1e-3 there weighted a
        # few samples 1e6 times and the next profile went negative, at 0.3 rad of spread)
        floor = max(weight_floor, QUANTISED_WEIGHT_FLOOR) if i == 0 else weight_floor
        np.maximum(v, floor * vbar, out=v)
        w_new = 1.0 / (v * v)
        s1 = float(w_new @ c2)
        gram = np.array([[float(w_new.sum()), s1], [s1, float(w_new @ c2c2)]])
        new = np.linalg.solve(gram, np.array([float(w_new @ r2), float(w_new @ c2r2)]))
        if not (np.all(np.isfinite(new)) and float(new[0] + new[1] * c2_mean) > 0):
            # a profile gone negative on average (N = 256, 0.04 rad, noise 1e-3 of the
            # amplitude: the iterates diverged): the last pair stands
            break
        settled = float(np.max(np.abs(new - coef))) <= _REWEIGHT_TOL * vbar
        coef, wts, gram_w = new, w_new, gram
        if settled and i > 0:
            break
    u = r2 - X @ coef
    bread = np.linalg.inv(gram_w)
    gw = X * (wts * u)[:, None]
    meat = gw.T @ gw
    for lag in range(1, max(int(hac_lags), 0) + 1):
        gam = gw[:-lag].T @ gw[lag:]
        meat += (1 - lag / (hac_lags + 1)) * (gam + gam.T)
    cov_ab = bread @ meat @ bread
    alpha, beta = float(coef[0]), float(coef[1])
    Ad = float(fit4.amplitude)
    # A_d's variance: A_d ~ (2/N) sum y_k sin(phi_k) for many periods; HC with r_k^2
    # g = 2 beta / A_d^2 through the samples' influences: beta's (the reweighted
    # regression's) and A_d's (A_d ~ (2/N) sum y_k sin phi_k for many periods), summed
    # with their lagged products where the jitter is coloured (Bartlett weights)
    inf_A = 2.0 * r * sin_k / n
    var_Ad = float(inf_A @ inf_A)
    g = 2 * beta / (Ad * Ad)
    inf_g = (2 / Ad**2) * (gw @ bread[1]) - (4 * beta / Ad**3) * inf_A
    var_g = _long_run(inf_g, hac_lags)
    theta = 0.0
    kurtosis = math.nan
    shape_note = ""
    if law == "free" and g > _FREE_MAX_G:
        # the moments cannot tell the law's shape here: span the shapes (a dual Dirac to a
        # Gaussian mixture), the estimate the middle, the half-range inside the interval
        lo_s2, hi_s2 = _shape_span(g)
        s2 = 0.5 * (lo_s2 + hi_s2)
        eg = 1e-4 * g
        up, dn = _shape_span(g + eg), _shape_span(g - eg)
        d_g = (sum(up) - sum(dn)) / (4 * eg)  # d (middle) / d g
        if not math.isfinite(d_g):
            d_g = (hi_s2 - lo_s2) / max(g, 1e-300)
        s2_se = math.sqrt(d_g * d_g * var_g + (0.5 * (hi_s2 - lo_s2) / 1.96) ** 2)
        theta = math.nan
        shape_note = (
            f"at this phase spread (2 pi f sigma ~ {math.sqrt(max(s2, 0.0)):.2g} rad) the "
            "jitter law's shape changes the std and the moments cannot tell it: the "
            "interval spans the shapes from a dual Dirac to a Gaussian mixture; "
            "method='ml' chooses the law by likelihood"
        )
    elif law == "free" and g > _FREE_MIN_G:
        # the law's shape from the fourth moment: the cos(4 phi) coefficient of E r_k^4,
        # (F4), is A_d^4 h whatever the noise (symmetric, independent)
        X4 = np.empty((n, 3))
        X4[:, :2] = X
        X4[:, 2] = 2 * c2 * c2 - 1  # cos 4 phi
        r4 = r2 * r2
        # (the fourth powers' weights 1 / v^4 floored at a quarter of the mean variance
        # whatever the record: their variance is dominated by the tone's slopes)
        v = np.maximum(X @ coef, 0.25 * max(float(np.mean(X @ coef)), 1e-300))
        w4 = 1.0 / v**4
        B4 = np.linalg.inv(X4.T @ (X4 * w4[:, None]))
        coef4 = B4 @ ((X4 * w4[:, None]).T @ r4)
        u4 = r4 - X4 @ coef4
        h = float(coef4[2]) / Ad**4
        inf_h = ((X4 * (w4 * u4)[:, None]) @ B4[2]) / Ad**4 - (4 * h / Ad) * inf_A
        h_se = math.sqrt(_long_run(inf_h, hac_lags))
        s2, theta, spread = _free_solve(g, h, h_se)
        if math.isfinite(s2):
            eg = 1e-4 * max(g, 1e-12)
            d_g = (_s2_for(g + eg, theta) - _s2_for(g - eg, theta)) / (2 * eg)
            if not math.isfinite(d_g):
                d_g = _invert("gaussian", g)[1]
            # the shape's ambiguity: half the plausible range as a 95 % half-width
            s2_se = math.sqrt(d_g * d_g * var_g + (0.5 * spread / 1.96) ** 2)
            kurtosis = 3 - 2 * theta * theta if theta <= 0 else 3 * (1 + theta * theta)
        else:
            s2_se = math.nan
    else:
        s2, ds2 = _invert("gaussian" if law == "free" else law, g)
        s2_se = abs(ds2) * math.sqrt(var_g)
    if not math.isfinite(s2):
        s2, s2_se = math.nan, math.nan
    jvar, jvar_se = s2 / w**2, s2_se / w**2
    sd = math.sqrt(max(jvar, 0.0))
    lo_var = jvar - 1.96 * jvar_se
    if math.isfinite(jvar) and lo_var > 0:
        sd_se = jvar_se / (2 * sd)
    else:
        sd_se = 0.5 * math.sqrt(jvar_se) if math.isfinite(jvar_se) else math.nan
    if law == "free":
        th1 = theta if math.isfinite(theta) else 0.0
        chi1 = _shape_chi(1, max(s2, 0.0), th1) if math.isfinite(s2) else math.nan
    else:
        chi1 = _chi1(law, math.sqrt(max(s2, 0.0))) if math.isfinite(s2) else math.nan
    A = Ad / chi1 if chi1 and math.isfinite(chi1) else math.nan
    # sigma_v^2 = alpha - A_d^2 (1/chi_1^2 - 1) / 2 = alpha - (A^2 - A_d^2) / 2
    spread = 0.5 * (A * A - Ad * Ad) if math.isfinite(A) else math.nan
    noise_var = alpha - spread
    # d spread / d beta: for small s, spread ~ A_d^2 s^2 / 2 ~ beta (Gaussian exactly:
    # A_d^2 (e^{s^2} - 1)/2 = beta / (1 - g)), so noise_var ~ alpha - beta / (1 - g)
    dn_db = -1.0 / max(1.0 - g, 1e-12)
    noise_var_se = math.sqrt(
        max(float(cov_ab[0, 0] + 2 * dn_db * cov_ab[0, 1] + dn_db**2 * cov_ab[1, 1]), 0.0)
    )
    var_k = np.maximum(X @ coef, 0.0)
    vv = np.maximum(var_k, 1e-300)
    crit = float(np.sum(np.log(vv) + r * r / vv))
    # the sine's standard errors (HC, many periods): a, b ~ (2/N) sum y cos/sin
    tc = (k - 0.5 * (n - 1)) * T
    var_ph = 4.0 / n**2 * float(np.sum(cos_k**2 * r * r)) / max(Ad * Ad, 1e-300)
    col = tc * cos_k
    var_w = float(np.sum(col * col * r * r)) / max(Ad * Ad * float(np.sum(col * col)) ** 2, 1e-300)
    return MomentFit(
        law=law,
        amplitude=A,
        damped_amplitude=Ad,
        phase_rad=float(fit4.phase),
        frequency_hz=float(fit4.frequency),
        offset=float(fit4.offset),
        alpha=alpha,
        beta=beta,
        cov_alpha_beta=cov_ab,
        phase_var=s2,
        phase_var_stderr=s2_se,
        jitter_var=jvar,
        jitter_var_stderr=jvar_se,
        jitter_std=sd,
        jitter_std_stderr=sd_se,
        noise_var=noise_var,
        noise_var_stderr=noise_var_se,
        amplitude_stderr=math.sqrt(var_Ad) / chi1 if chi1 else math.nan,
        frequency_stderr=math.sqrt(var_w) / (2 * math.pi),
        phase_stderr=math.sqrt(var_ph),
        offset_stderr=math.sqrt(float(np.sum(r * r))) / n,
        residuals=r,
        variance=var_k,
        criterion=crit,
        slope_regression_std=math.sqrt(max(2 * float(ols[1]) / (w * Ad) ** 2, 0.0)),
        slope_regression_noise_std=math.sqrt(max(float(ols[0] - ols[1]), 0.0)),
        weight_floor=float(weight_floor),
        shape=theta,
        kurtosis=kurtosis,
        note=shape_note,
    )
