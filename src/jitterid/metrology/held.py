"""Harmonics held at their least-squares fit, so that a distorted tone is measured by the
structured likelihood of a pure tone (:mod:`jitterid.metrology.sinelik`), or by the moment
route (:mod:`jitterid.metrology.moments`, ``method="gaussian"``).

A converter's record of a sine holds its harmonics (HD2, HD3, ... at -90 to -50 dBc). The
exact likelihood of a tone with harmonics is the generic quadrature
(:mod:`jitterid.estimation.likelihood`): minutes at N = 4096, out of reach at 2^16, and with
Gaussian noise only, so an undithered converter's quantiser biased it
(:func:`jitterid.metrology.adequacy.dither_finding`). Here the harmonics h = 2..H are fitted
by linear least squares at the fundamental's frequency (the columns cos, sin of 2 pi h f t,
with the fundamental and the offset), their sum o_k at the nominal instants is taken from
the record, and the fundamental is measured on y - o by the structured likelihood, with the
record's quantisation bins where it is quantised (a bin of width q about y_k is a bin about
y_k - o_k: the quantiser's kernel is exact for the shifted record), or by the moment route.

What is left out, and what it costs (:meth:`HeldHarmonics.jitter_std_bias`):

* The harmonics' own jitter. A sample's jitter term is tau_k s'(t_k), s' the slope of the
  whole tone; the pure tone's likelihood takes the fundamental's slope w A_1 cos(theta_k).
  The variance profile sigma^2 s'(t_k)^2 then differs by 2 w^2 A_1 cos(theta_k) sum_h h A_h
  cos(h theta_k + phi_h') to first order in the harmonics. Even harmonics average out of the
  jitter's estimate (their term changes sign under theta -> theta + pi, where the profile
  does not); odd ones do not: the first-order bias of the std is of the order of A_3 / A_1
  (0.3 to 2 times it, the more where the jitter's spread dominates the noise: +-0.3 % at
  HD3 = -50 dBc on a 12-bit record of 2^16 samples, 5 % at -30 dBc with 2 ps at 97 MHz
  and noise 1e-4). It is computed from the fitted values by the weighted least squares of
  the variance profile (the Gaussian likelihood's weights) and added to the standard error
  in quadrature, the message giving it. Against the structured likelihood's own estimates
  with and without HD3 (12 records of 2^14 samples each): -30 dBc, phi_3 = 2.5: +4.656 +-
  0.055 % measured, +4.642 % predicted; phi_3 = 0: -5.895 +- 0.056 against -5.875 %;
  -40 dBc: -1.133 +- 0.019 against -1.140 %; against the moment route's (float records,
  session 26): -30 dBc, phi_3 = 2.5: +4.630 +- 0.056 against +4.629 %; phi_3 = 0: -5.891 +-
  0.056 against -5.865 %; -40 dBc, phi_3 = 2.5: +1.613 +- 0.017 against +1.612 % (so it
  could correct the estimate; it widens the interval, the conservative use, until it has
  been checked on the bins and the other laws as well).
* The harmonics' uncertainty in the jitter's: none to first order (the harmonics move the
  samples' mean, the jitter their variance). Their own standard errors are the least
  squares' Huber-White ones (heteroscedastic: the jitter's variance varies along the
  period), their correlation with the fundamental's parameters taken as zero (the columns
  are orthogonal over whole periods).
* The least squares' harmonics are the jittered harmonics' means, damped by the jitter's
  characteristic function at h w (1 - (h w sigma)^2 / 2): 2e-4 at 0.01 rad of phase spread.

Beyond :data:`HELD_SLOPE_SHARE` (the harmonics' slopes against the fundamental's) the tone
is not a pure tone plus a small correction, and the meter keeps the generic likelihood.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..estimation.result import FitResult
from ..params import ParamLayout
from ..systems.tones import SineWave

__all__ = ["HELD_SLOPE_SHARE", "HeldHarmonics", "hold_harmonics"]

FloatArray = NDArray[np.float64]

#: Harmonics are held (:func:`hold_harmonics`) where their slopes sum to at most this share
#: of the fundamental's, sum_h h |A_h| / |A_1| (HD2 and HD3 at -40 dBc: 0.05): the jitter's
#: first-order bias, 0.3-2 x A_3 / A_1 (module doc), is then a few percent at most, and it
#: is stated and added to the standard error
HELD_SLOPE_SHARE = 0.1
#: ... and where each column's norm not explained by the columns before it is at least this
#: share of its norm (a harmonic's alias a third of a bin or more from the others')
MIN_OWN_SHARE = 0.5


@dataclass(frozen=True)
class HeldHarmonics:
    """Harmonics h = 2..H of a tone at their least-squares fit (module doc).

    Attributes
    ----------
    frequency_hz : float
        The fundamental's frequency the columns were made at, Hz.
    T : float
        The sampling interval, s.
    params : ndarray, shape (2 (H - 1),)
        ``amplitude_h``, ``phase_rad_h`` for h = 2..H, in :class:`SineWave`'s polar form
        (A_h sin(2 pi h f t + phi_h), t = kT).
    cov : ndarray, shape (2 (H - 1), 2 (H - 1))
        Their Huber-White covariance (delta method from the linear coefficients).
    offset : ndarray, shape (N,)
        Their sum at the nominal instants kT: what the fundamental's fit takes from y.
    slope_share : float
        sum_h h |A_h| / |A_1|, A_1 the least squares' fundamental.
    """

    frequency_hz: float
    T: float
    params: FloatArray
    cov: FloatArray
    offset: FloatArray
    slope_share: float

    @property
    def harmonics(self) -> int:
        """H, the highest harmonic (the fundamental counted as 1)."""
        return 1 + self.params.size // 2

    def attach(self, fit: FitResult, model: SineWave) -> FitResult:
        """``fit`` (the fundamental's, a pure :class:`SineWave` with its jitter and
        ``noise_std``) as a fit of ``model`` (the same tone with these harmonics): the
        harmonics' values and covariance inserted, their correlation with the rest zero;
        the cost and status the fundamental's, the message saying how the harmonics were
        fitted.

        Parameters
        ----------
        fit : FitResult
            The fundamental's fit on the record less :attr:`offset`.
        model : SineWave
            The tone with :attr:`harmonics` harmonics (its band as the fit's model's).
        """
        if model.harmonics != self.harmonics:
            raise ValueError(f"model must have {self.harmonics} harmonics; got {model.harmonics}")
        layout = ParamLayout.build(
            fit.jitter_model, model, None, noise_std="noise_std" in fit.names
        )
        names = layout.names
        held = {
            f"{p}_{h}": 2 * (h - 2) + j
            for h in range(2, self.harmonics + 1)
            for j, p in enumerate(("amplitude", "phase_rad"))
        }
        own = {n: i for i, n in enumerate(fit.names)}
        x = np.empty(len(names))
        cov = np.zeros((len(names), len(names)))
        src_fit = [(k, own[n]) for k, n in enumerate(names) if n in own]
        src_held = [(k, held[n]) for k, n in enumerate(names) if n in held]
        if len(src_fit) + len(src_held) != len(names):
            missing = [n for n in names if n not in own and n not in held]
            raise ValueError(f"fit lacks the parameters {missing} of the tone's layout")
        for k, i in src_fit:
            x[k] = fit.x[i]
        for k, i in src_held:
            x[k] = self.params[i]
        a, b = zip(*src_fit, strict=True)
        cov[np.ix_(a, a)] = np.asarray(fit.cov)[np.ix_(b, b)]
        a, b = zip(*src_held, strict=True)
        cov[np.ix_(a, a)] = self.cov[np.ix_(b, b)]
        return replace(
            fit,
            names=names,
            x=x,
            cov=cov,
            structure=model,
            layout=layout,
            message=(
                f"{fit.message}; harmonics 2..{self.harmonics} held at their least-squares "
                "fit (the fundamental measured as a pure tone on the record less them: "
                "jitterid.metrology.held)"
            ),
        )

    def jitter_std_bias(self, fit: FitResult, quantisation_step: float | None = None) -> float:
        """The first-order bias of ``fit``'s jitter std, relative, from the harmonics' jitter
        left out of the variance profile (module doc): the weighted least squares of
        E[r_k^2] = sigma_v^2 + sigma^2 s'(t_k)^2 (the whole tone's slope) on the profile
        sigma_v^2 + sigma^2 (w A_1 cos theta_k)^2 the fit assumes, with the Gaussian
        likelihood's weights 1 / Var_k^2, at the fitted values (the noise std with the
        quantiser's q^2 / 12 where ``fit`` was made on bins: its ``noise_std`` is then
        before the quantiser, and the profile's floor is the record's).

        Parameters
        ----------
        fit : FitResult
            The fit of :meth:`attach` (the tone with these harmonics).
        quantisation_step : float, optional
            The step q of the bins ``fit`` was made on (None: Gaussian noise).
        """
        p = fit.params
        n = self.offset.size
        t = np.arange(n, dtype=float) * self.T
        w = 2 * math.pi * float(p["frequency_hz"])
        sig = float(fit.jitter_std)
        if not (sig > 0 and math.isfinite(sig)):
            return 0.0
        base = float(p["amplitude"]) * np.cos(w * t + float(p["phase_rad"]))
        slope = base.copy()
        for h in range(2, self.harmonics + 1):
            slope += h * float(p[f"amplitude_{h}"]) * np.cos(h * w * t + float(p[f"phase_rad_{h}"]))
        q = quantisation_step or 0.0
        floor = float(p["noise_std"]) ** 2 + q * q / 12.0
        prof = (w * base) ** 2
        true = (w * slope) ** 2
        wt = 1.0 / (floor + sig * sig * prof) ** 2
        M = np.array([[wt.sum(), wt @ prof], [wt @ prof, wt @ (prof * prof)]])
        rhs = np.array([wt @ (floor + sig * sig * true), (wt * prof) @ (floor + sig * sig * true)])
        try:
            _, var = np.linalg.solve(M, rhs)
        except np.linalg.LinAlgError:
            return math.nan
        return math.sqrt(var) / sig - 1.0 if var > 0 else -1.0


def hold_harmonics(
    y: FloatArray, T: float, frequency_hz: float, harmonics: int
) -> HeldHarmonics | None:
    """The harmonics 2..``harmonics`` of the tone in ``y`` at ``frequency_hz`` by linear
    least squares (with the fundamental and the offset), or None where their slopes exceed
    :data:`HELD_SLOPE_SHARE` of the fundamental's or a harmonic's alias lies too near
    another column's to be told from it (:data:`MIN_OWN_SHARE`; module doc).

    Parameters
    ----------
    y : ndarray, shape (N,)
        The record.
    T : float
        Its sampling interval, s.
    frequency_hz : float
        The fundamental's frequency (the IEEE 1057 fit's), Hz.
    harmonics : int
        H >= 2, the highest harmonic.
    """
    if harmonics < 2:
        raise ValueError(f"harmonics must be >= 2; got {harmonics}")
    n = y.size
    t = np.arange(n, dtype=float) * T
    w = 2 * math.pi * frequency_hz
    cols = [np.ones(n)]
    for h in range(1, harmonics + 1):
        cols += [
            np.sin(h * w * t),
            np.cos(h * w * t),
        ]  # A sin(. + phi) = A cos phi sin + A sin phi cos
    X = np.column_stack(cols)
    Q, R = np.linalg.qr(X)
    # each column's share not explained by the ones before it: a harmonic aliased within
    # about a third of a bin of DC, Nyquist, the fundamental or a lower harmonic cannot be
    # told from it (its offset would take a share of the fundamental; 0.5 at 0.3 bin, 0.86
    # at 0.6)
    norms = np.linalg.norm(X, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        own = np.abs(np.diag(R)) / norms
    if not np.all(own >= MIN_OWN_SHARE):
        return None
    coef = np.linalg.solve(R, Q.T @ y)
    resid = y - X @ coef
    # Huber-White covariance of the coefficients: R^-1 (Q^T diag(r^2) Q) R^-T
    Rinv = np.linalg.inv(R)
    meat = (Q * (resid * resid)[:, None]).T @ Q
    C = Rinv @ meat @ Rinv.T
    a1 = math.hypot(coef[1], coef[2])
    params = np.empty(2 * (harmonics - 1))
    cov = np.zeros((params.size, params.size))
    share = 0.0
    for h in range(2, harmonics + 1):
        s_, c_ = coef[2 * h - 1], coef[2 * h]
        A = math.hypot(s_, c_)
        share += h * A
        i = 2 * (h - 2)
        params[i], params[i + 1] = A, math.atan2(c_, s_)
        # d(A, phi) / d(s, c)
        J = (
            np.array([[s_ / A, c_ / A], [-c_ / (A * A), s_ / (A * A)]])
            if A > 0
            else np.zeros((2, 2))
        )
        k = [2 * h - 1, 2 * h]
        cov[i : i + 2, i : i + 2] = J @ C[np.ix_(k, k)] @ J.T
    share = share / a1 if a1 > 0 else math.inf
    if not share <= HELD_SLOPE_SHARE:
        return None
    offset = X[:, 3:] @ coef[3:]
    return HeldHarmonics(float(frequency_hz), float(T), params, cov, offset, share)
