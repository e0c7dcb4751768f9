"""A jitter family ranked out on the subsample its ranking started from
(:func:`rank_on_subsample`), without a pass of the whole record.

The meter's law ranking (:func:`jitterid.metrology.sinelik_fit.rank_sine_law`) fits each
family on every s-th sample first (:func:`~jitterid.metrology.sinelik_fit.rank_start`) and
then takes at least one pass of the whole record (its score and information) before it can
rank the family out. A family far behind the leading one (a dual Dirac on a uniform
record, 4600 below in ln L at N = 2^16; a uniform on a Gaussian one, 5800 below) is
already told apart on the subsample; its passes of the record (a dual Dirac's cost about
three Gaussian passes each) decide nothing.

The bound. With F the candidate at its subsample optimum x_F, G the leading family at its
maximum x_G on the whole record (ln L_G known) and r_k = ln p_F(y_k; x_F) - ln p_G(y_k;
x_G) per sample,

    ln L_F(x_F) = ln L_G + sum_{k in S} r_k + sum_{k not in S} r_k,

S the subsample. The last sum is estimated from S stratified by the tone's phase (bins of
theta_k = 2 pi f kT + phi: the samples' densities depend on the phase, and a near-coherent
record's subsample need not sample the phases as the record does): sum_b (N_b - n_b)
rbar_b, with the variance sum_b (N_b - n_b)^2 s_b^2 / n_b of the estimate plus (N - n)
s^2 of the record's own draw (s_b, s the spread of r in bin b and over S). The maximum of
F on the whole record lies above ln L_F(x_F) by about (1/2) s chi^2_P (x_F is about one
subsample standard error, sqrt(s) of the record's, from it): its quantile at
:data:`SUB_RANK_LEVEL` is added. The upper bound is the estimate plus :data:`SUB_RANK_Z`
standard deviations plus that gain; where it puts F's BIC more than the ranking margin
above G's, F is ranked out as :func:`~jitterid.metrology.sinelik_fit.rank_sine_law` ranks
out (the same give-up line), its fit the subsample optimum, its message saying so. Where a
phase bin that holds samples of the record holds fewer than :data:`SUB_RANK_MIN_BIN`
samples of the subsample, nothing is ranked out here.

Checked against the exact values (``tests/metrology/test_sinelik_subrank.py``; 21 (record,
law) pairs of Gaussian, uniform, dual-Dirac and Student-t jitter, coherent and not, 12-bit
quantised, 2^15-2^16 samples): the estimate's error -3.5 to +2.1 of its standard
deviations, biased low (the safe side) by the subsample fit's optimism, about (s - 1) P / 2
(P/2 gained on the subsample by fitting it, extrapolated to the other samples); the climb
to the maximum 5-37 against bounds of 56-120; every maximum below its bound.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import JitterFamily
from ..systems.tones import SineWave
from ._format import ordinal
from .sinelik_fit import RANK_SUBSAMPLE, LawRank, RankStart, _every, give_up_line
from .sinelik_loglik import SineLikelihood
from .sinelik_rule import FloatArray

__all__ = ["SUB_RANK_Z", "rank_on_subsample", "subsample_estimate"]

#: Standard deviations of the estimate of ln L_F on the whole record added to it (module
#: doc): a family is ranked out on the subsample only far beyond the subsample's noise
SUB_RANK_Z = 5.0
#: The quantile of chi^2_P that bounds the climb from the subsample optimum to the family's
#: maximum on the whole record, (1/2) s chi^2_P
SUB_RANK_LEVEL = 0.9999
#: Phase bins of the stratified estimate ...
SUB_RANK_BINS = 16
#: ... each holding at least this many samples of the subsample where the record has any
SUB_RANK_MIN_BIN = 16


def _subsample(y: FloatArray, T: float, start: RankStart) -> tuple[FloatArray, float] | None:
    """The subsample ``start`` was fitted on (:func:`~jitterid.metrology.sinelik_fit.
    rank_start`'s, every s-th sample at s T), or None where it has none."""
    every = _every(y, T, RANK_SUBSAMPLE)
    return every if every is not None and every[0].size == start.samples else None


def subsample_estimate(
    y: ArrayLike,
    T: float,
    family: JitterFamily,
    start: RankStart,
    leader: FitResult,
    quantisation_step: float | None = None,
) -> tuple[float, float, float] | None:
    """ln L on the whole record of ``family`` at its subsample optimum ``start``, estimated
    from the subsample against ``leader``'s maximum (module doc): (the estimate, its
    standard deviation, the bound of the climb to the family's maximum on the record), or
    None where the subsample cannot tell (no subsample optimum, a leader not at its
    maximum, a phase bin the subsample does not hold).

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    family : JitterFamily
        The candidate family.
    start : RankStart
        Its ranking start (:func:`~jitterid.metrology.sinelik_fit.rank_start`).
    leader : FitResult
        The leading family's fit to its maximum on the whole record.
    quantisation_step : float or None
        The record's quantisation step (the bin kernel).
    """
    yv = np.asarray(y, dtype=float)
    N = yv.size
    ok = (FitStatus.CONVERGED, FitStatus.AT_BOUND)
    if not (start.fitted and leader.status in ok and math.isfinite(leader.cost)):
        return None
    if not isinstance(leader.jitter_model, JitterFamily):
        return None
    every = _subsample(yv, T, start)
    if every is None:
        return None
    ys, sT = every
    s = N // RANK_SUBSAMPLE
    q = quantisation_step
    with np.errstate(all="ignore"):
        try:
            lp_f = SineLikelihood(ys, sT, family, quantisation_step=q).logpdf(start.x)
            lik_g = SineLikelihood(ys, sT, leader.jitter_model, quantisation_step=q)
            lp_g = lik_g.logpdf(leader.x)
        except ValueError:
            return None
    r = lp_f - lp_g
    if not np.all(np.isfinite(r)):
        return None
    # the phase bins of the record and of the subsample (the leader's tone)
    f = float(leader.params["frequency_hz"])
    phi = float(leader.params["phase_rad"])
    frac = np.mod(f * T * np.arange(N, dtype=float) + phi / (2 * math.pi), 1.0)
    bins = np.minimum((frac * SUB_RANK_BINS).astype(np.intp), SUB_RANK_BINS - 1)
    n_all = np.bincount(bins, minlength=SUB_RANK_BINS)
    b_sub = bins[::s]
    n_sub = np.bincount(b_sub, minlength=SUB_RANK_BINS)
    rest = n_all - n_sub
    if np.any((rest > 0) & (n_sub < SUB_RANK_MIN_BIN)):
        return None
    held = n_sub > 0
    sums = np.bincount(b_sub, weights=r, minlength=SUB_RANK_BINS)
    sq = np.bincount(b_sub, weights=r * r, minlength=SUB_RANK_BINS)
    mean_b = np.where(held, sums / np.maximum(n_sub, 1), 0.0)
    var_b = np.where(n_sub > 1, (sq - n_sub * mean_b**2) / np.maximum(n_sub - 1, 1), 0.0)
    var_b = np.maximum(var_b, 0.0)
    estimate = -0.5 * leader.cost + float(r.sum()) + float(rest @ mean_b)
    var = float(np.sum(rest**2 * var_b / np.maximum(n_sub, 1))) + (N - ys.size) * float(np.var(r))
    climb = 0.5 * s * float(chi2.ppf(SUB_RANK_LEVEL, np.size(start.x)))
    return estimate, math.sqrt(var), climb


def rank_on_subsample(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: RankStart,
    leader: FitResult,
    *,
    quantisation_step: float | None = None,
) -> LawRank | None:
    """``family`` ranked out against ``leader`` on the subsample of its ranking start, or
    None where the subsample does not rank it out (module doc).

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    model : SineWave
        The pure-tone model.
    family : JitterFamily
        The candidate family.
    start : RankStart
        Its ranking start (:func:`~jitterid.metrology.sinelik_fit.rank_start`): a
        subsample optimum, else nothing is ranked out.
    leader : FitResult
        The leading family's fit to its maximum on the whole record (CONVERGED or AT_BOUND,
        a :class:`~jitterid.metrology.sinelik_loglik.SineLikelihood` fit: its
        ``jitter_model``, ``x`` and ``cost``).
    quantisation_step : float or None
        The record's quantisation step (the bin kernel).

    Returns
    -------
    LawRank or None
        Ranked out: the fit at the subsample optimum (MAX_EVALUATIONS, no covariance, its
        cost -2 x the estimate of ln L on the whole record) and the upper bound of its
        maximum.
    """
    got = subsample_estimate(y, T, family, start, leader, quantisation_step)
    if got is None:
        return None
    estimate, sd, climb = got
    N = int(np.size(y))
    xf = np.asarray(start.x, dtype=float)
    P = xf.size
    upper = estimate + SUB_RANK_Z * sd + climb
    give_up = give_up_line(-0.5 * leader.cost, int(np.size(leader.x)), P, N)
    if not upper < give_up:
        return None
    s, n = N // RANK_SUBSAMPLE, start.samples
    lik = SineLikelihood(np.zeros(1), T, family)  # (its names and jitter parameters)
    jp = xf[: lik.nj]
    message = (
        f"structured sine likelihood (jitterid.metrology.sinelik): ranked out on every "
        f"{ordinal(s)} sample, where it was fitted ({n} samples): its ln L on the whole "
        f"record at that fit is {estimate:.6g} by the subsample's difference from the "
        f"leading law's maximum ({-0.5 * leader.cost:.6g}), and its maximum at most {upper:.6g} "
        f"({SUB_RANK_Z:g} standard deviations of that estimate and the climb to the whole "
        f"record's maximum above it), below {give_up:.6g} (this family cannot win by the "
        "ranking margin); not fitted to its maximum, no pass of the whole record"
    )
    fit = FitResult(
        method="ml",
        names=lik.names,
        x=xf.copy(),
        cost=-2.0 * estimate,
        status=FitStatus.MAX_EVALUATIONS,
        message=message,
        nfev=0,
        system=None,
        jitter_law=family.law(tuple(float(v) for v in jp)),
        noise_std=float(xf[-1]),
        freqs=np.zeros(0),
        cov=np.full((P, P), math.nan),
        cov_type="oim",
        structure=model,
        jitter_model=family,
    )
    return LawRank(fit, True, upper)
