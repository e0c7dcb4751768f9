"""The maximum of :class:`~jitterid.metrology.sinelik_loglik.SineLikelihood`,
:func:`fit_sine_ml`: damped Newton steps on the observed information (its negative
curvatures made positive where it is not definite; on records longer than 2^15 samples the
information of every n-th chunk, scaled, for the steps: :data:`FIT_INFO_SAMPLES`), in ln of the
scales, inside the bounds: a few passes over the record (a dual Dirac's dj searched as
dj^2: ln L is even in dj, so flat to fourth order at dj = 0, where Newton steps in dj
crawl; in dj^2 it is a regular quadratic, and dj = 0 is a bound, AT_BOUND where the record
does not resolve a dj). The covariance is the inverse observed information of the whole
record. The noise std is searched down to a floor (``noise_floor``; on a float record
:data:`NUMERIC_FLOOR` of the jitter's spread, see :mod:`jitterid.metrology.sinelik`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import JitterFamily
from ..jitter.regular import DualDiracFamily, GaussianScaleMixtureFamily
from ..systems.tones import SineWave
from ._format import ordinal
from .reading import LAW_MARGIN_BIC
from .sinelik_loglik import SineLikelihood, sine_ml_applies
from .sinelik_rule import FloatArray

__all__ = [
    "NUMERIC_FLOOR",
    "RANK_MARGIN_BIC",
    "LawRank",
    "RankStart",
    "fit_sine_ml",
    "rank_sine_law",
    "rank_start",
    "ranked_nested",
    "start_subsample",
]

#: The noise floor of a float record (no physical one), relative to the jitter's own spread
#: of the samples A sqrt((w sigma)^2 / 2): a floor c biases the jitter std low by about
#: c / 4 to c / 6 on a noise-free record (see the module doc): 1e-3 moves it by ~2e-4
#: (measured: -0.03 standard errors at N = 2^14, about -0.25 at 2^20). Lower floors
#: are closer still but slow the search (the likelihood of a noise-free tone is not
#: regular: its peaks' samples make it rough in the amplitude and offset on the scale
#: of the floor).
NUMERIC_FLOOR = 1e-3
#: A family is ranked out (:func:`rank_sine_law`) where even the upper estimate of its
#: maximum leaves its BIC this far above the leading family's: the margin above which the
#: meter calls the law chosen (:data:`jitterid.metrology.reading.LAW_MARGIN_BIC`), so a
#: ranked-out family never turns a chosen law into an undetermined one.
RANK_MARGIN_BIC = LAW_MARGIN_BIC
#: The upper estimate of a family's maximum: ln L + RANK_SAFETY x the Newton model's
#: predicted further gain (g^T H^-1 g / 2, H the observed information made definite).
#: The quadratic model underestimates the gain where ln L is flatter than quadratic (a
#: dual Dirac's dj near 0, where ln L is quartic in dj: 2/3 of the gain): 3 covers it twice.
#: Where the last step realised more than its predicted gain (rho > 1), ln L is steeper than
#: the Newton model and the predicted further gain is scaled by rho too. A dual Dirac ranked
#: from near the Gaussian on a record whose jitter is mostly deterministic climbs ln L
#: 2.8-3.2 x faster than the model for four steps (ln L from -29 to 325): with the model's
#: gain alone its "upper estimate" after two steps was 32, below the uniform's 69, and the
#: truth was ranked out (scaled by rho: 135).
RANK_SAFETY = 3.0
#: A dual Dirac's ranking start holds this share of the start's jitter variance in dj
#: (dj^2 / 4 = share x std^2): the rival is mostly a Gaussian, nested at dj = 0, near
#: which ln L is close to quadratic in dj^2 (the search's coordinate); at an even split
#: the start sits on the steep side (on a 2^16 Gaussian record ln L ~450 below, two more
#: subsample steps and a rejected step on the whole record: 2.4 s of the 4.8). A scale
#: mixture's ranking start is near its nested Gaussian likewise: rho^2 = this share
#: (kurtosis 3.3; on the 2^16 Gaussian record of bench_sinelik.py it is ranked out after
#: 3 passes of the record).
RANK_DJ_SHARE = 0.1
#: Whether :func:`rank_sine_law` ranks a scale mixture from the Gaussian it nests (its
#: ``nested`` argument: the meter's ranking after a Gaussian fit). On the 2^16 Gaussian
#: record of bench_sinelik.py: ranked out after 2 passes of the record instead of 2
#: subsample passes and 3 full ones (BENCHMARKS.md, issue 26, session 16).
RANK_NESTED = True
#: fit_sine_ml's probes of a law with hard edges (a bounded support): ln L at its end with
#: the jitter scale times these factors (:func:`_probe_scale`). A uniform record at 1 rad,
#: noise 1e-3, N = 1000, from a start at 1.2 x the half-width: the search stopped,
#: CONVERGED, at a local maximum at 1.18 x the truth, -2 ln L 164 above the maximum near it.
SCALE_PROBES = (0.85, 1.15)
#: The fewest Newton steps before a family may be ranked out (the first step from another
#: family's optimum is the least quadratic; from the subsample's optimum: 1).
RANK_MIN_STEPS = 2
#: On records of at least 4 x this many samples the ranking first fits the family on every
#: s-th sample (s = N // RANK_SUBSAMPLE: a record of its own, at s T, ~1/s of a pass per
#: step) and continues on the whole record from there: a start within sqrt(s) standard
#: errors of the family's maximum, where the Newton model is close to quadratic.
RANK_SUBSAMPLE = 1 << 13
#: A subsample's fit (the ranking's, fit_sine_ml's start) stops at this Newton decrement
#: (steps within one of its standard errors: its optimum is sqrt(s) of the record's
#: standard errors off anyway).
SUB_DECREMENT = 1.0
#: The ranking's Newton steps on the whole record take their information from about this
#: many samples (every n-th chunk, scaled; the gradient is the whole record's) ...
RANK_INFO_SAMPLES = 1 << 13
#: ... and fit_sine_ml's from about this many. 2^13 here took 15-35 % less CPU on the
#: Gaussian records of 2^15-2^17 samples (the same passes +-1), but the uniform's full fit
#: on the 2^15 Gaussian record of tests/metrology/test_sinelik_rank.py took 19 passes
#: instead of 3: its information from a quarter of the record steers the steps badly.
FIT_INFO_SAMPLES = 1 << 15
#: On records of at least 4 x this many samples fit_sine_ml starts from its own optimum on
#: every s-th sample (s = N // FIT_SUBSAMPLE): the first, long steps cost 1/s of a pass.
#: Shorter records (2^15 to 2^17 samples) start from every s-th sample with s = N //
#: RANK_SUBSAMPLE (:func:`_fit_subsample_size`): at 2^16, the Gaussian fit from the IEEE
#: start (159 fs for an optimum of 99.9) took 6 passes, 4.3-4.9 s; from the 2^13-sample
#: optimum 0.65 s and 3 passes, 2.85 s, ending 2e-6 of the std away (its stderr: 6e-3).
FIT_SUBSAMPLE = 1 << 16
#: Where the Newton decrement after a step is below this x the search's tolerance, the next
#: step's gain (about half of it) passes the convergence test, and its pass sums the
#: information over every chunk: the covariance's, which takes no pass of its own then (on
#: the 2^16 record of bench_sinelik.py the Gaussian fit's decrement after its first step on
#: the record was 0.011, then 7e-6: its last pass at stride 1, 1.15 s, instead of one at
#: stride 2, 0.77 s, and the covariance's, 1.15 s).
FINAL_DECREMENT = 20.0
#: The least Levenberg-Marquardt damping (relative to the diagonal): where ln L is rough on
#: the step's scale (a noise-free record: the samples at the tone's peaks against a noise
#: std on its floor) an undamped step fails, and each rejection raises the damping by 10.
_LAM_MIN = 1e-3
#: A step whose Newton trial (the undamped one) failed to raise ln L and whose damped step
#: then gained less than ROUGH_GAIN is a rough step: ln L is rough on the Newton step's
#: scale, and its quadratic model, whose predicted gain stays put, says nothing of the
#: gain left. After ROUGH_STEPS rough steps in a row the search ends there (CONVERGED, the
#: message says so). On a noise-free 12-bit record of 2^16 samples (2 ps at 97 MHz, 1 GS/s)
#: a dual Dirac's ranking made 40 such steps, each gaining 1.1e-3 against a predicted 5.1,
#: 183 CPU-s, its jitter moving by 1e-5 of itself.
ROUGH_GAIN = 1e-2
ROUGH_STEPS = 3
#: A search from a start meets a maximum already found (:func:`fit_sine_ml`'s ``found``)
#: where the start, or else its subsample optimum, x_s and that maximum x_f lie in one
#: quadratic bowl of the subsample's ln L. About x_f, with g and I the subsample's score
#: and observed information there (I positive definite) and d = x_s - x_f: m^2 = d^T I d
#: and g^T I^-1 g (the distance to the subsample's own maximum, a Newton step from x_f:
#: the full record's maximum lies about sqrt(1 - 1/s) of the subsample's standard errors
#: from it) both below the chi^2 quantile at MEET_LEVEL for the parameters' number, and
#: ln L_s(x_s) within MEET_QUADRATIC x m^2 / 2 (plus MEET_SLACK) of the quadratic model's
#: ln L_s(x_f) + g^T d - m^2 / 2. Then the search from x_s climbs to x_f: it is not run.
#: The meter's ranking fits a family from another family's maximum and, where it is not
#: ranked out, to its maximum; its fit from the family's own start then did the same
#: passes again (a 12-bit uniform-jitter record of 2^16 samples: 6.7 of its 30.7 CPU-s; a
#: Gaussian one whose dual Dirac was not ranked out: 13.1 of 58), and, where only the
#: subsample optimum was tested, the subsample's search (a dual-Dirac record of 2^16
#: samples: 12 passes of the subsample, 3.6 of its 19 CPU-s).
MEET_LEVEL = 0.999
MEET_QUADRATIC = 0.25
MEET_SLACK = 0.5


def _positive(H: FloatArray, opg: FloatArray) -> FloatArray:
    """H with its eigenvalues replaced by their absolute values (floored at 1e-4 of the
    largest), on the scale of its diagonal (or of the scores' outer product where that is
    0): a Newton matrix that is definite and keeps H's curvature where H has one."""
    d = np.abs(np.diag(H))
    d = np.where(d > 0, d, np.maximum(np.diag(opg), 1e-300))
    r = 1.0 / np.sqrt(d)
    lam, vec = np.linalg.eigh(H * np.outer(r, r))
    top = float(np.max(np.abs(lam))) if lam.size else 1.0
    lam = np.maximum(np.abs(lam), 1e-4 * top)
    return (vec * lam) @ vec.T / np.outer(r, r)


def _decrement(
    v: FloatArray,
    vlo: FloatArray,
    vhi: FloatArray,
    g: FloatArray,
    info: FloatArray,
    opg: FloatArray,
) -> float:
    """The Newton decrement g^T H^-1 g (twice the predicted further gain) over the
    parameters free to move (not on a bound that the gradient pushes against), H the
    observed information made definite (:func:`_positive`); inf where it cannot be made."""
    fr = ~(((v <= vlo) & (g < 0)) | ((v >= vhi) & (g > 0)))
    try:
        Hm = _positive(info[np.ix_(fr, fr)], opg[np.ix_(fr, fr)])
        return float(g[fr] @ np.linalg.solve(Hm, g[fr]))
    except (np.linalg.LinAlgError, ValueError):
        return math.inf


def fit_sine_ml(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike,
    *,
    noise_floor: float = 0.0,
    max_iter: int = 100,
    quantisation_step: float | None = None,
    found: FitResult | None = None,
) -> FitResult:
    """Maximise :class:`SineLikelihood` from a start: damped Newton steps on the observed
    information (module doc), in ln of the jitter scale and the noise std, inside the
    bounds; the covariance is the inverse observed information.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    model : SineWave
        The pure-tone model (its ``band_hz`` bounds the frequency).
    family : JitterFamily
        Gaussian, uniform, dual-Dirac or scale-mixture family (:func:`sine_ml_applies`).
    start : array_like
        The start, in the order of :attr:`SineLikelihood.names`.
    noise_floor : float
        The smallest noise std searched (see the module doc: noise-free records).
    max_iter : int
        The most steps.
    quantisation_step : float or None
        The record's quantisation step: each sample is then the probability of its bin,
        with ``noise_std`` the noise before the quantiser (:class:`SineLikelihood`).
    found : FitResult or None
        A CONVERGED maximum of the same likelihood (record, family, quantisation step)
        found from another start (the meter's ranking). Where ``start``, or else the
        optimum of every s-th sample from it, lies in one quadratic bowl with it
        (:data:`MEET_LEVEL`), the search on the whole record is not run and ``found`` is
        the fit, its message saying so; and where the search from there cannot reach
        ``found``'s ln L by the ranking's upper estimate (ln L + ``RANK_SAFETY`` x its
        predicted further gain, after ``RANK_MIN_STEPS`` steps), it is given up and
        ``found`` is the fit (a dual-Dirac record of 2^16 samples whose own start, the
        noise on its floor, led to a point 1.2e5 below the maximum in ln L: 100 steps of
        about 500 each, 125 CPU-s, before).

    Returns
    -------
    FitResult
        ``method="ml"``, cost -2 ln L, covariance ``"oim"``; AT_BOUND where a parameter ends
        on its bound (no standard error then), MAX_EVALUATIONS where the steps ran out.
    """
    size = _fit_subsample_size(int(np.size(y)))
    q = quantisation_step
    if found is not None:  # the start itself in found's bowl: no search at all
        met = _meets(y, T, family, start, found, size, q)
        if met is not None:
            return _probe_scale(y, T, model, family, met, noise_floor, max_iter, q_step=q)
    sub = _subsample_fit(y, T, model, family, start, noise_floor, max_iter, size, q)
    if sub is not None:
        start = sub[0].x
        met = None if found is None else _meets(y, T, family, start, found, size, q)
        if met is not None:
            return _probe_scale(y, T, model, family, met, noise_floor, max_iter, q_step=q)
    # (a search from elsewhere that cannot reach found's ln L, by the ranking's upper
    # estimate, is given up: the docstring's found)
    converged = found is not None and found.status is FitStatus.CONVERGED
    give_up = -0.5 * found.cost if found is not None and converged else None
    fit, gave_up, upper = _search(
        y, T, model, family, start, noise_floor, max_iter, give_up, q_step=q
    )
    if gave_up:
        assert found is not None
        fit = replace(
            found,
            message=(
                f"{found.message}; the search from the family's own start was given up after "
                f"{fit.nfev} evaluations: ln L {-0.5 * fit.cost:.6g} there, at most "
                f"{upper:.6g} by {RANK_SAFETY:g} x its predicted further gain, below this "
                "maximum's"
            ),
            nfev=found.nfev + fit.nfev,
        )
    return _probe_scale(y, T, model, family, fit, noise_floor, max_iter, q_step=q)


def _meets(
    y: ArrayLike,
    T: float,
    family: JitterFamily,
    x_s: ArrayLike,
    found: FitResult,
    size: int,
    q_step: float | None,
) -> FitResult | None:
    """``found`` (its message saying so) where ``x_s`` (a search's start, or its optimum on
    the subsample) and ``found``'s maximum lie in one quadratic bowl of the subsample's
    ln L (:data:`MEET_LEVEL`); else None. Two passes of the subsample (1/s of a record's
    pass each)."""
    every = _every(y, T, size)
    if every is None or found.status is not FitStatus.CONVERGED:
        return None
    lik = SineLikelihood(*every, family, squared=True, quantisation_step=q_step)
    zs = np.asarray(x_s, dtype=float).copy()
    zf = np.asarray(found.x, dtype=float).copy()
    if zs.shape != zf.shape or not (np.all(np.isfinite(zs)) and np.all(np.isfinite(zf))):
        return None
    if lik.squared is not None:  # (the even parameter in its square, the search's coordinate)
        zs[lik.squared] = zs[lik.squared] ** 2
        zf[lik.squared] = zf[lik.squared] ** 2
    with np.errstate(all="ignore"):
        try:
            ll_f, g, _, info = lik.scores_information(zf, 1)
            ll_s = lik.loglik(zs)
        except ValueError:  # (a start outside the family's domain)
            return None
    if not (
        math.isfinite(ll_s)
        and math.isfinite(ll_f)
        and np.all(np.isfinite(g))
        and np.all(np.isfinite(info))
    ):
        return None
    try:
        np.linalg.cholesky(info)
        to_max = np.linalg.solve(info, g)
    except np.linalg.LinAlgError:
        return None
    d = zs - zf
    m2 = float(d @ info @ d)
    level = float(chi2.ppf(MEET_LEVEL, d.size))
    model_ll = ll_f + float(g @ d) - 0.5 * m2
    if not (
        m2 <= level
        and float(g @ to_max) <= level
        and abs(ll_s - model_ll) <= MEET_QUADRATIC * 0.5 * m2 + MEET_SLACK
    ):
        return None
    s = int(np.size(y)) // size
    return replace(
        found,
        message=(
            f"{found.message}; the search from the family's own start met this maximum (that "
            f"start, or its optimum on every {ordinal(s)} sample, in one quadratic bowl with it: "
            f"squared distance {m2:.3g} in standard errors) and was not run on the whole record"
        ),
        nfev=found.nfev + 2,
    )


def _probe_scale(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    fit: FitResult,
    noise_floor: float,
    max_iter: int,
    *,
    q_step: float | None = None,
) -> FitResult:
    """``fit`` of a law with hard edges (:attr:`jitterid.JitterLaw.hard_edges`: the uniform)
    checked for a local
    maximum in the jitter scale: ln L at the scale times each of :data:`SCALE_PROBES`, the
    rest as fitted (one pass each); where one is higher the search runs again from the best,
    and its end is kept if higher, with the message saying so. Other laws, and a search
    that did not end at a maximum, as they are."""
    k = family.scale_index
    if (
        k is None
        or fit.status not in (FitStatus.CONVERGED, FitStatus.AT_BOUND)
        or not fit.jitter_law.hard_edges
    ):
        return fit
    lik = SineLikelihood(y, T, family, quantisation_step=q_step)
    lo, hi = lik.bounds(noise_floor, model.band_hz)
    ll0 = -0.5 * fit.cost
    tol = 1e-9 * max(1.0, abs(ll0))
    best: tuple[float, FloatArray, float] | None = None
    for factor in SCALE_PROBES:
        x = fit.x.copy()
        x[k] = min(max(x[k] * factor, lo[k]), hi[k])
        with np.errstate(all="ignore"):
            ll = lik.loglik(x)
        if math.isfinite(ll) and ll > ll0 + tol and (best is None or ll > best[0]):
            best = (ll, x, factor)
    if best is None:
        return fit
    again = _search(y, T, model, family, best[1], noise_floor, max_iter, None, q_step=q_step)[0]
    if not again.cost < fit.cost - 2 * tol:
        return fit
    return replace(
        again,
        message=(
            f"{again.message}; the search from the start had stopped at a local maximum "
            f"(ln L {ll0:.6g}, the jitter's {family.param_names[k]} = {fit.x[k]:.6g}): ln L "
            f"was higher at {best[2]:g} x that {family.param_names[k]}, and the search from "
            "there ended here (a law with hard edges: ln L can be multimodal in its scale)"
        ),
        nfev=again.nfev + fit.nfev + len(SCALE_PROBES),
    )


def start_subsample(y: ArrayLike, T: float) -> tuple[FloatArray, float]:
    """The record on which :func:`fit_sine_ml` fits its start: every s-th sample, a record
    of its own at s T (s = N // the subsample size, :func:`_fit_subsample_size`), where
    s >= 4; else the record itself. For choosing among starts at 1/s of a pass each.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        Its sampling interval (s).
    """
    yv = np.asarray(y, dtype=float)
    return _every(yv, T, _fit_subsample_size(yv.size)) or (yv, T)


def _every(y: ArrayLike, T: float, size: int) -> tuple[FloatArray, float] | None:
    """Every s-th sample of ``y``, a record of its own at s T (s = N // size), where
    s >= 4; else None (the record is too short for a subsample worth its own fit)."""
    yv = np.asarray(y, dtype=float)
    s = yv.size // size
    return (yv[::s], s * T) if s >= 4 else None


def _fit_subsample_size(n: int) -> int:
    """The subsample size of :func:`fit_sine_ml`'s start on a record of ``n`` samples:
    ``FIT_SUBSAMPLE`` from 4 x that on, else ``RANK_SUBSAMPLE`` (no subsample below 4 x
    that: :func:`_subsample_fit`)."""
    return FIT_SUBSAMPLE if n >= 4 * FIT_SUBSAMPLE else RANK_SUBSAMPLE


def _subsample_fit(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike,
    noise_floor: float,
    max_iter: int,
    size: int,
    q_step: float | None,
) -> tuple[FitResult, int] | None:
    """The family's fit on every s-th sample (s = N // size, a record of its own at s T),
    to :data:`SUB_DECREMENT`, and the subsample's size, where s >= 4 and the fit ends at a
    maximum (CONVERGED, or AT_BOUND: a noise-free record's noise std on its floor) with
    finite values; else None."""
    every = _every(y, T, size)
    if every is None:
        return None
    sub = _search(
        *every,
        model,
        family,
        start,
        noise_floor,
        max_iter,
        None,
        decrement=SUB_DECREMENT,
        covariance=False,
        q_step=q_step,
    )[0]
    ended = sub.status in (FitStatus.CONVERGED, FitStatus.AT_BOUND)
    if not (ended and np.all(np.isfinite(sub.x)) and math.isfinite(sub.cost)):
        return None
    return sub, int(every[0].size)


def ranked_nested(family: JitterFamily) -> bool:
    """Whether :func:`rank_sine_law` with ``nested=True`` ranks ``family`` from the Gaussian
    it nests (:data:`RANK_NESTED`: the scale mixture; :func:`_nested_start`), not from a
    start of its own.

    Parameters
    ----------
    family : JitterFamily
        The family.
    """
    even = family.even_index
    return RANK_NESTED and isinstance(family, GaussianScaleMixtureFamily) and bool(even)


def _nested_start(family: JitterFamily, start: ArrayLike) -> FloatArray | None:
    """``start`` (a law of ``family`` at the Gaussian's std, its sine and noise) moved to the
    Gaussian that a scale mixture nests: rho 0 and sigma the std; None for other families.

    Only the scale mixture: its kurtosis 3 (1 + rho^2) moves at first order in rho^2, so
    the score in rho^2 at 0 is the kurtosis test and the Newton model's gain there bounds
    the family's maximum (54 records, Gaussian, Student-t 5, contaminated, uniform, mixture
    and dual-Dirac jitter at 0.05-1 rad, N = 1000: no maximum above the upper estimate).
    A dual Dirac's fourth cumulant moves at second order in dj^2 at a fixed std: its score
    at dj = 0 is blind to the shape, and on the same records its maximum lay 0.08-71 above
    the nested "upper estimate" (dual-Dirac truths among them)."""
    even = family.even_index
    if not ranked_nested(family) or even is None:
        return None
    x0 = np.array(start, dtype=float)
    nj = len(family.param_names)
    std = float(family.law(x0[:nj].tolist()).std)
    x0[even], x0[0] = 0.0, std
    lo, hi = family.bounds[0]
    if not lo <= std <= hi:
        return None
    law = family.law(x0[:nj].tolist())
    return x0 if abs(float(law.std) - std) <= 1e-9 * std else None


@dataclass(frozen=True)
class LawRank:
    """A jitter family's fit as far as the law ranking took it (:func:`rank_sine_law`).

    Attributes
    ----------
    fit : FitResult
        Its fit: to its maximum where the family can still win, else stopped
        (MAX_EVALUATIONS, no covariance, the message says "ranked out").
    ranked_out : bool
        Whether the family was ranked out.
    loglik_upper : float
        The upper estimate of its maximum ln L (its ln L where fitted to its maximum).
    """

    fit: FitResult
    ranked_out: bool
    loglik_upper: float


@dataclass(frozen=True)
class RankStart:
    """Where :func:`rank_sine_law` searches the whole record from (:func:`rank_start`).

    Attributes
    ----------
    x : ndarray
        The point, in :attr:`SineLikelihood.names` order.
    loglik : float
        Its ln L on the subsample it was fitted on; -inf where it was not (a record under
        4 x :data:`RANK_SUBSAMPLE` samples, or a subsample fit that did not end at a
        maximum: ``x`` is then the start itself).
    samples : int
        The subsample's size (0 where there is none).
    """

    x: FloatArray
    loglik: float
    samples: int

    @property
    def fitted(self) -> bool:
        """Whether ``x`` is a subsample optimum."""
        return math.isfinite(self.loglik) and self.samples > 0

    def bic(self) -> float:
        """The subsample's BIC at ``x``, -2 ln L + P ln(samples) (+inf where not fitted):
        the meter ranks the laws in its order."""
        if not self.fitted:
            return math.inf
        return -2.0 * self.loglik + self.x.size * math.log(self.samples)


def give_up_line(rival_loglik: float, rival_n_params: int, n_params: int, N: int) -> float:
    """The ln L below which a family of ``n_params`` parameters is ranked out against a
    rival at ``rival_loglik`` with ``rival_n_params``, on ``N`` samples: its BIC then lies
    more than :data:`RANK_MARGIN_BIC` above the rival's (:func:`rank_sine_law`,
    :func:`jitterid.metrology.sinelik_subrank.rank_on_subsample`)."""
    return rival_loglik + 0.5 * (n_params - rival_n_params) * math.log(N) - 0.5 * RANK_MARGIN_BIC


def rank_sine_law(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike | RankStart,
    *,
    rival_loglik: float,
    rival_n_params: int,
    noise_floor: float = 0.0,
    max_iter: int = 100,
    nested: bool = False,
    quantisation_step: float | None = None,
) -> LawRank:
    """:func:`fit_sine_ml` that gives up on a family that cannot win: the search stops
    (after ``RANK_MIN_STEPS`` steps at least) once the upper estimate of the family's
    maximum (ln L + ``RANK_SAFETY`` x the predicted further gain) puts its BIC more than
    :data:`RANK_MARGIN_BIC` above the rival's; else it runs to the maximum, as
    :func:`fit_sine_ml` from the same start (the same result). On a record of at least
    4 ``RANK_SUBSAMPLE`` samples the search on the whole record starts from the family's
    optimum on every s-th sample (``RANK_SUBSAMPLE``) instead, and may stop after one
    step.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    model : SineWave
        The pure-tone model.
    family : JitterFamily
        Gaussian, uniform, dual-Dirac or scale-mixture family.
    start : array_like or RankStart
        The start (e.g. the rival's optimum with this family's parameters at its std; a
        dual Dirac's variance is re-split to hold ``RANK_DJ_SHARE`` of it in dj, a scale
        mixture's rho^2 set to it), or :func:`rank_start`'s point from such a start (its
        subsample fit made; ``nested`` does not apply then).
    rival_loglik : float
        The leading family's maximised ln L.
    rival_n_params : int
        The leading family's number of parameters (the BIC's penalty).
    noise_floor : float
        The smallest noise std searched.
    max_iter : int
        The most steps.
    nested : bool
        ``start`` is a Gaussian's maximum of ln L (its jitter std, sine and noise). For a
        scale mixture, which nests that Gaussian at rho = 0 (:func:`_nested_start`: not
        for a dual Dirac, whose score there is blind), the ranking then starts at that
        Gaussian in the family (:data:`RANK_NESTED`; no subsample fit, no
        ``RANK_DJ_SHARE`` re-split): ln L there is the Gaussian's maximum, its gradient the
        score in the even parameter's square alone, and the Newton model's predicted gain
        the score test's statistic / 2, so the family may be ranked out at once (after
        one pass of the record) and after any step.
    quantisation_step : float or None
        The record's quantisation step (:func:`fit_sine_ml`).

    Returns
    -------
    LawRank
    """
    N = int(np.size(y))
    p = len(family.param_names) + 5
    give_up = give_up_line(float(rival_loglik), int(rival_n_params), p, N)
    if not math.isfinite(give_up):
        give_up = -math.inf  # no finite rival: nothing is ranked out
    x0 = None
    if not isinstance(start, RankStart) and nested:
        x0 = _nested_start(family, start)
    if x0 is not None:  # the Newton model at the nested maximum: the score test's
        return LawRank(
            *_search(
                y,
                T,
                model,
                family,
                x0,
                noise_floor,
                max_iter,
                give_up,
                min_steps=0,
                info_samples=RANK_INFO_SAMPLES,
                q_step=quantisation_step,
            )
        )
    if not isinstance(start, RankStart):
        start = rank_start(
            y,
            T,
            model,
            family,
            start,
            noise_floor=noise_floor,
            max_iter=max_iter,
            quantisation_step=quantisation_step,
        )
    sub, min_steps = start.x, 1 if start.fitted else RANK_MIN_STEPS
    return LawRank(
        *_search(
            y,
            T,
            model,
            family,
            sub,
            noise_floor,
            max_iter,
            give_up,
            min_steps,
            info_samples=RANK_INFO_SAMPLES,
            q_step=quantisation_step,
        )
    )


def rank_start(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike,
    *,
    noise_floor: float = 0.0,
    max_iter: int = 100,
    quantisation_step: float | None = None,
) -> RankStart:
    """Where :func:`rank_sine_law` (not ``nested``) searches the whole record from:
    ``start`` (a dual Dirac's or a scale mixture's re-split near the nested Gaussian,
    :data:`RANK_DJ_SHARE`) fitted on every s-th sample (:data:`RANK_SUBSAMPLE`) where the
    record holds 4 x that many samples and the fit ends at a maximum; else ``start``. The
    meter ranks the laws in the order of their subsample BIC (:meth:`RankStart.bic`, the
    likeliest first, so that the others are ranked out against it), passing each to
    :func:`rank_sine_law`.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    model : SineWave
        The pure-tone model.
    family : JitterFamily
        Gaussian, uniform, dual-Dirac or scale-mixture family.
    start : array_like
        The start (:func:`rank_sine_law`'s).
    noise_floor : float
        The smallest noise std searched.
    max_iter : int
        The most steps.
    quantisation_step : float or None
        The record's quantisation step (:func:`fit_sine_ml`).
    """
    start = np.asarray(start, dtype=float).copy()
    if isinstance(family, DualDiracFamily):  # the variance re-split (RANK_DJ_SHARE)
        var = start[0] ** 2 + 0.25 * start[1] ** 2
        (rlo, rhi), (dlo, dhi) = family.bounds
        rj = min(max(math.sqrt((1 - RANK_DJ_SHARE) * var), rlo), rhi)
        start[:2] = rj, min(max(2 * math.sqrt(RANK_DJ_SHARE * var), dlo), dhi)
    elif isinstance(family, GaussianScaleMixtureFamily):  # near the nested Gaussian too
        start[1] = min(math.sqrt(RANK_DJ_SHARE), family.bounds[1][1])
    sub = _subsample_fit(
        y, T, model, family, start, noise_floor, max_iter, RANK_SUBSAMPLE, quantisation_step
    )
    if sub is None:
        return RankStart(start, -math.inf, 0)
    return RankStart(np.asarray(sub[0].x, dtype=float), -0.5 * float(sub[0].cost), sub[1])


def _search(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike,
    noise_floor: float,
    max_iter: int,
    give_up_below: float | None,
    min_steps: int = RANK_MIN_STEPS,
    decrement: float = 1e-3,
    info_samples: int = FIT_INFO_SAMPLES,
    covariance: bool = True,
    q_step: float | None = None,
) -> tuple[FitResult, bool, float]:
    """:func:`fit_sine_ml`'s search, whether it gave up, and the upper estimate of the
    maximum of ln L (ln L + ``RANK_SAFETY`` x the predicted gain, at the last step). With
    ``give_up_below`` it stops (MAX_EVALUATIONS, no covariance) after at least
    ``min_steps`` steps once that upper estimate is below ``give_up_below`` (0: at the
    start already, after its one pass: :func:`rank_sine_law`'s ``nested``). It converges
    where the Newton decrement is below ``decrement`` (the steps then below sqrt(decrement)
    standard errors); the Newton steps' information is summed over about ``info_samples``
    samples (every n-th chunk, scaled; the gradient is the whole record's). Without
    ``covariance`` the covariance is not computed (NaN: a start's fit). ``q_step``: the
    record's quantisation step (the bin kernel, :class:`SineLikelihood`)."""
    if not sine_ml_applies(model, family):
        raise TypeError(
            "model must be a pure-tone SineWave (one harmonic, polar, frequency estimated) and "
            "family a Gaussian, uniform, dual-Dirac or scale-mixture family; use "
            "jitterid.fit(..., 'ml') else"
        )
    # a family's even parameter (a dual Dirac's dj, a scale mixture's rho) is searched in
    # its square: ln L is even in it, so flat at 0 (a dual Dirac's quartic there), where
    # Newton steps in it crawl or stall; in its square ln L is a regular quadratic there
    lik = SineLikelihood(y, T, family, squared=True, quantisation_step=q_step)
    sq = lik.squared
    x0 = np.asarray(start, dtype=float).copy()
    if sq is not None:
        x0[sq] = x0[sq] ** 2
    lo, hi = lik.bounds(noise_floor, model.band_hz)
    x = np.clip(x0, lo, hi)
    if x[lik.nj] < 0:
        x[lik.nj] = -x[lik.nj]
        x[lik.nj + 1] += math.pi
    # the search runs in v: ln of the scales (the jitter's first parameter, the noise std:
    # ln L is far closer to quadratic in them), the others as they are
    logs = np.zeros(x.size, bool)
    logs[0] = logs[-1] = True
    vlo = np.where(logs, np.log(np.maximum(lo, 1e-300)), lo)
    vhi = np.where(logs, np.log(np.where(np.isfinite(hi), hi, 1e300)), hi)

    def to_x(v: FloatArray) -> FloatArray:
        # (exp(ln b) may round past the bound b, which the family refuses)
        return np.clip(np.where(logs, np.exp(np.where(logs, v, 0.0)), v), lo, hi)

    # the Newton steps' information from about info_samples samples (the gradient from all)
    stride = max(1, (lik.N + info_samples - 1) // info_samples)
    # ... and, in a ranking whose ln L has reached the give-up line (it can no longer be
    # ranked out: it runs to its maximum), from about FIT_INFO_SAMPLES, as fit_sine_ml's
    fit_stride = min(stride, max(1, (lik.N + FIT_INFO_SAMPLES - 1) // FIT_INFO_SAMPLES))

    # the observed information in x of the whole record at the point last evaluated, where
    # that evaluation summed it over every chunk (stride 1: records up to info_samples, and
    # the pass expected to be the last, FINAL_DECREMENT): the covariance's, without a pass
    # of its own
    whole: list[FloatArray | None] = [None]
    pass_stride = [stride]

    def evaluate(xx: FloatArray) -> tuple[float, FloatArray, FloatArray, FloatArray]:
        # a trial point far off (a long step) may overflow: it is then rejected as
        # non-finite, its floating-point warnings are not the caller's
        with np.errstate(all="ignore"):
            ll_, g_, opg_, info_ = lik.scores_information(xx, pass_stride[0])
        if not (np.all(np.isfinite(g_)) and np.all(np.isfinite(opg_))):
            ll_ = -math.inf
        whole[0] = info_ if pass_stride[0] == 1 else None
        jac = np.where(logs, xx, 1.0)
        # in v: the chain rule (d2 ln L / dv^2 gains g x on the diagonal of a ln scale)
        info_v = info_ * np.outer(jac, jac) - np.diag(np.where(logs, g_ * xx, 0.0))
        return ll_, g_ * jac, opg_ * np.outer(jac, jac), info_v

    def trial(xx: FloatArray) -> float:
        # ln L alone (a third to a half of a pass with the score and information): the
        # trial points after a rejected one, where the next may be rejected too
        with np.errstate(all="ignore"):
            ll_ = lik.loglik(xx)
        return ll_ if math.isfinite(ll_) else -math.inf

    v = np.where(logs, np.log(np.maximum(x, 1e-300)), x)
    x = to_x(v)
    ll, g, opg, info = evaluate(x)
    info_here = whole[0]  # (the whole record's information at x, where evaluated so)
    nfev = 1
    lam = 1e-4
    stalled = 0
    rough, rough_gain = 0, 0.0
    damped = False  # (the last step's Newton trial failed: try the next by ln L alone)
    upper = math.inf
    ranked_out = False
    status, why = FitStatus.MAX_EVALUATIONS, f"the {max_iter} steps ran out"
    if not math.isfinite(ll):
        status, why = FitStatus.NOT_FINITE, "the likelihood is not finite at the start"
        max_iter = 0
    elif give_up_below is not None and min_steps == 0:
        # the upper estimate at the start itself (rank_sine_law's nested look)
        upper = ll + RANK_SAFETY * 0.5 * _decrement(v, vlo, vhi, g, info, opg)
        if upper < give_up_below:
            ranked_out = True
            max_iter = 0
            why = (
                f"ranked out at its start, the Gaussian's maximum (its even parameter 0), "
                f"after one pass: ln L = {ll:.6g}, and at most {upper:.6g} by "
                f"{RANK_SAFETY:g} x the score test's predicted gain, below {give_up_below:.6g} "
                "(this family cannot win by the ranking margin); not fitted to its maximum"
            )
    for step in range(max_iter):
        if give_up_below is not None and ll >= give_up_below and pass_stride[0] > fit_stride:
            # (RANK_INFO_SAMPLES' information steers the steps of a long search badly: a
            # dual Dirac not ranked out on a 2^16 Gaussian record crept up ln L by about 1 a
            # step for 5 steps)
            pass_stride[0] = fit_stride
        free = ~(((v <= vlo) & (g < 0)) | ((v >= vhi) & (g > 0)))
        d = np.zeros_like(v)
        # Newton on the observed information, its negative curvatures turned positive
        # where it is not definite (far from the optimum, or a law far from the record's)
        if np.all(np.isfinite(info)):
            H = _positive(info[np.ix_(free, free)], opg[np.ix_(free, free)])
        else:  # BHHH on the scores' covariance
            H = (opg - np.outer(g, g) / lik.N)[np.ix_(free, free)]
        diag = np.maximum(np.diag(H), 1e-300)
        gain = math.inf
        accepted = False
        for _try in range(12):
            try:
                d[free] = np.linalg.solve(H + lam * np.diag(diag), g[free])
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            d = np.where(logs, np.clip(d, -3.0, 3.0), d)  # a scale moves e^3 at most
            vn = np.clip(v + d, vlo, vhi)
            xn = to_x(vn)
            if xn[lik.nj + 2] <= 0:  # frequency stays positive
                lam *= 10
                continue
            if _try == 0 and not damped:
                lln, gn, opgn, infon = evaluate(xn)
            else:  # after a rejection (here or the last step's): ln L first, the rest if accepted
                lln = trial(xn)
                if math.isfinite(lln) and lln >= ll - 1e-12 * abs(ll):
                    lln, gn, opgn, infon = evaluate(xn)
                    nfev += 1
            nfev += 1
            if math.isfinite(lln) and lln >= ll - 1e-12 * abs(ll):
                gain = lln - ll
                # the damping follows the gain against the Newton model's (Nielsen's rule:
                # /10 where the model holds, kept where half of it is realised, raised
                # where less): where ln L is rough on the step's scale (a noise-free
                # record's peaks) the next step is not tried undamped again
                dv = (vn - v)[free]
                pred = float(g[free] @ dv - 0.5 * dv @ H @ dv)
                rho = gain / pred if pred > 0 else 1.0
                v, x, ll, g, opg, info = vn, xn, lln, gn, opgn, infon
                info_here = whole[0]  # (the last evaluation was xn's)
                lam = max(lam * max(0.1, 1.0 - (2.0 * rho - 1.0) ** 3), _LAM_MIN)
                accepted, damped = True, _try > 0
                break
            lam *= 10.0
        if not accepted:
            status, why = FitStatus.CONVERGED, "no step raises the likelihood further"
            break
        dec = _decrement(v, vlo, vhi, g, info, opg)
        if covariance and dec < FINAL_DECREMENT * decrement:
            pass_stride[0] = 1  # the next step's pass is expected to be the last
        stalled = stalled + 1 if gain < 0.1 * decrement else 0
        if damped and gain < ROUGH_GAIN:
            rough, rough_gain = rough + 1, rough_gain + gain
        else:
            rough, rough_gain = 0, 0.0
        # (a step that gained rho > 1 x its prediction: ln L is steeper than the model there)
        steep = max(1.0, rho)
        upper = ll + RANK_SAFETY * steep * 0.5 * dec
        if give_up_below is not None and step + 1 >= min_steps and upper < give_up_below:
            ranked_out = True
            why = (
                f"ranked out after {step + 1} steps: ln L = {ll:.6g}, and at most "
                f"{upper:.6g} by {RANK_SAFETY * steep:.3g} x the predicted further gain "
                f"{0.5 * dec:.3g}, "
                f"below {give_up_below:.6g} (this family cannot win by the ranking margin); "
                "not fitted to its maximum"
            )
            break
        if dec < decrement and gain < 10 * decrement:
            status = FitStatus.CONVERGED
            why = (
                f"the predicted gain in ln L is below {decrement:g} (steps below "
                f"{100 * math.sqrt(decrement):.0f} % of the standard errors)"
            )
            break
        if rough >= ROUGH_STEPS:
            # the quadratic model's gain is not the gain left here: the realised one is
            if give_up_below is not None and step + 1 >= min_steps:
                upper = ll + RANK_SAFETY * rough_gain
                if upper < give_up_below:
                    ranked_out = True
                    why = (
                        f"ranked out after {step + 1} steps, the last {rough} rough (ln L "
                        f"rose by {rough_gain:.3g} in them, each after its Newton step "
                        f"failed): ln L = {ll:.6g}, and at most {upper:.6g} by "
                        f"{RANK_SAFETY:g} x that gain again, below {give_up_below:.6g} (this "
                        "family cannot win by the ranking margin); not fitted to its maximum"
                    )
                    break
            status = FitStatus.CONVERGED
            why = (
                f"ln L rose by less than {ROUGH_GAIN:g} in each of {rough} steps, each after "
                "the Newton step failed to raise it: ln L is rough on the Newton step's scale "
                "(a quantised record's bins against a noise std on its floor), and the search "
                "ends where its steps stall"
            )
            break
        if stalled >= 3:
            status = FitStatus.CONVERGED
            why = (
                f"ln L rose by less than {0.1 * decrement:g} in each of 3 steps (a direction "
                "in which the likelihood is flat, e.g. a dual Dirac's dj near 0)"
            )
            break
    x = np.clip(x, lo, hi)
    at_bound = (x <= lo * (1 + 1e-12) + 1e-300) | (x >= hi)
    at_bound[lik.nj] = False  # the amplitude's floor is not a bound of the model
    free = ~at_bound
    P = x.size
    cov = np.full((P, P), math.nan)
    note = ""
    if status is not FitStatus.NOT_FINITE and not ranked_out and covariance:
        H = info_here if info_here is not None else lik.observed_information(x)
        Hf = H[np.ix_(free, free)]
        try:
            np.linalg.cholesky(Hf)
            cov[np.ix_(free, free)] = np.linalg.inv(Hf)
        except np.linalg.LinAlgError:
            note = "; the observed information is not positive definite (no standard errors)"
    names = lik.names
    if status is FitStatus.CONVERGED and at_bound.any():
        which = ", ".join(n for n, a in zip(names, at_bound, strict=True) if a)
        status = FitStatus.AT_BOUND
        why += f"; on its bound: {which}"
    if status in (FitStatus.CONVERGED, FitStatus.AT_BOUND):
        upper = ll  # the maximum the search found
    if sq is not None:  # back from the square: d p / d(p^2) = 1 / (2 p) (0 on its bound)
        x = x.copy()
        x[sq] = math.sqrt(x[sq])
        jac = np.ones(P)
        jac[sq] = 0.5 / x[sq] if x[sq] > 0 else math.nan
        cov = cov * np.outer(jac, jac)
    jp = x[: lik.nj]
    return (
        FitResult(
            method="ml",
            names=names,
            x=x,
            cost=-2.0 * ll,
            status=status,
            message=f"structured sine likelihood (jitterid.metrology.sinelik): {why}{note}",
            nfev=nfev,
            system=None,
            jitter_law=family.law(tuple(float(v) for v in jp)),
            noise_std=float(x[-1]),
            freqs=np.zeros(0),
            cov=cov,
            cov_type="oim",
            structure=model,
            jitter_model=family,
        ),
        ranked_out,
        upper,
    )
