"""Step and impulse responses of a fitted LTI model with pointwise confidence bands.

The responses from rest are exact, from the partial-fraction (modal) form of the transfer
function G = D + sum_p r_p / (s - p) with distinct poles:

    step:     y(t) = D + sum_p r_p (e^{p t} - 1) / p     (r_p t for a pole at 0)
    impulse:  y(t) = sum_p r_p e^{p t}                    (plus D delta(t), not sampled)

evaluated with ``expm1`` (accurate for |p t| small). Where two poles nearly coincide
(closer than 1e-4 of the largest |p|), the residues lose accuracy like 1e-16 / separation, so
the responses are taken instead from the matrix exponential of the controllable canonical
state-space form (``scipy.signal.tf2ss``, ``scipy.linalg.expm``): exact for repeated poles
too. Unstable fits are not refused: their responses grow.

The bands follow :func:`jitterid.bode_band`: ``"delta"`` is y -+ z se(t) with se^2 = J C J^T,
J the derivative of y(t) with respect to the system parameters (the one finite-difference
rule, :func:`jitterid.finite_diff.derivative`); ``"sampling"`` the pointwise quantiles of
the responses at parameter draws from N(x, C) inside the structure's bounds. Times are in s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import linalg, signal, stats

from .._checks import real_array
from ..systems.tf import TransferFunction
from .quantities import _system_block
from .uncertainty import _evaluate_draws, _Fit, _level

__all__ = ["TimeResponseBand", "impulse_response", "lti_response", "step_response"]

FloatArray = NDArray[np.float64]

KINDS = ("step", "impulse")
_NEAR_REPEAT = 1e-4


@dataclass(frozen=True, eq=False)
class TimeResponseBand:
    """A step or impulse response of a fit with a pointwise band (immutable arrays).

    Attributes
    ----------
    t_s : ndarray
        Times (s) from the start of the step or impulse, >= 0.
    response : ndarray
        The fitted system's response (output unit per input unit; per input unit-second for
        the impulse response).
    lo, hi : ndarray
        The pointwise band; NaN where the covariance is unavailable (see ``note``); equal to
        ``response`` for a known system.
    level : float
    kind : str
        ``"step"`` or ``"impulse"``.
    method : str
        ``"delta"``, ``"sampling"`` or ``"known"``.
    note : str
        Why the band is NaN, or that a biproper system's impulse response has a Dirac term
        D delta(t) that is not in ``response``; ``""`` if nothing.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> band = ji.step_response(res, [0.0, 1.0, 3.0])
    >>> band.kind, band.level, band.response.round(1).tolist()
    ('step', 0.95, [0.0, 0.9, 1.0])
    >>> bool(np.all(band.lo <= band.hi))
    True
    """

    t_s: FloatArray
    response: FloatArray
    lo: FloatArray
    hi: FloatArray
    level: float
    kind: str
    method: str = "delta"
    note: str = ""

    def __post_init__(self) -> None:
        for name in ("t_s", "response", "lo", "hi"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}; got {self.kind!r}")


def _times(t_s: ArrayLike) -> FloatArray:
    t = np.atleast_1d(real_array(t_s, "t_s"))
    if t.ndim != 1:
        raise ValueError(f"t_s must be a 1-D array of times (s); got shape {t.shape}")
    if t.size and t.min() < 0:
        raise ValueError(
            f"t_s must be >= 0 (s): the response starts from rest at t = 0; got {t.min():g}"
        )
    return t


def lti_response(system: TransferFunction, t_s: ArrayLike, kind: str = "step") -> FloatArray:
    """The step or impulse response of ``system`` from rest at times ``t_s`` (s), exact
    (module docstring: modal form, or the matrix exponential for near-repeated poles)."""
    if not isinstance(system, TransferFunction):
        raise TypeError(f"system must be a TransferFunction; got {type(system).__name__}")
    if kind not in KINDS:
        raise ValueError(f"kind must be 'step' or 'impulse'; got {kind!r}")
    t = _times(t_s)
    if system.delay_s:  # e^{-s d} G: G's response moved by d, zero before
        moved = lti_response(system.undelayed, np.maximum(t - system.delay_s, 0.0), kind)
        return np.where(t >= system.delay_s, moved, 0.0)
    num, den = np.asarray(system.num, float), np.asarray(system.den, float)
    lead = den[0]
    d = float(num[0] / lead) if num.size == den.size else 0.0
    p = np.asarray(system.poles, complex)
    if not p.size:  # a static gain
        return np.full(t.shape, d if kind == "step" else 0.0)
    scale = max(float(np.max(np.abs(p))), 1e-300)
    gap = np.abs(p[:, None] - p[None, :])
    np.fill_diagonal(gap, np.inf)
    with np.errstate(all="ignore"):
        if np.min(gap) < _NEAR_REPEAT * scale:
            return _expm_response(num, den, t, kind)
        rem = np.polysub(num, d * den) if d else num
        r = np.polyval(rem, p) / np.polyval(np.polyder(den), p)
        pt = p[None, :] * t[:, None]
        if kind == "impulse":
            return np.asarray((np.exp(pt) @ r).real, float)
        safe = np.where(p == 0, 1.0, p)
        phi = np.where(p[None, :] == 0, t[:, None], np.expm1(pt) / safe[None, :])
        return np.asarray(d + (phi @ r).real, float)


def _expm_response(num: FloatArray, den: FloatArray, t: FloatArray, kind: str) -> FloatArray:
    """The response through the matrix exponential: for the step, the top-right block of
    expm([[A, B], [0, 0]] t) is int_0^t e^{A s} ds B; for the impulse, C e^{A t} B."""
    A, B, C, D = signal.tf2ss(num, den)
    n = A.shape[0]
    if kind == "impulse":
        E = linalg.expm(A[None, :, :] * t[:, None, None])
        return np.asarray((C @ E @ B)[:, 0, 0], float)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n:] = A, B
    E = linalg.expm(M[None, :, :] * t[:, None, None])
    return np.asarray((C @ E[:, :n, n:])[:, 0, 0] + D[0, 0], float)


def _band(
    result: _Fit,
    t_s: ArrayLike,
    kind: str,
    level: float,
    method: str,
    draws: int,
    rng: np.random.Generator | int | None,
) -> TimeResponseBand:
    level = _level(level)
    if method not in ("delta", "sampling"):
        raise ValueError(f"method must be 'delta' or 'sampling'; got {method!r}")
    block = _system_block(result, f"{kind}_response")
    t = _times(t_s)
    y = lti_response(block.system, t, kind)
    note = ""
    if kind == "impulse" and block.system.num.size == block.system.den.size:
        d = float(block.system.num[0] / block.system.den[0])
        if d != 0:
            note = f"the impulse response also has the term {d:.6g} delta(t) at t = 0, not drawn"

    def make(lo: FloatArray, hi: FloatArray, how: str, why: str = "") -> TimeResponseBand:
        return TimeResponseBand(
            t, y, lo, hi, level, kind, how, "; ".join(s for s in (why, note) if s)
        )

    if not block.theta.size:
        return make(y.copy(), y.copy(), "known")
    if block.missing:
        nan = np.full_like(y, np.nan)
        bad = ", ".join(f"{n} ({w})" for n, w in block.missing.items())
        return make(nan, nan.copy(), method, f"no band: no standard error for {bad}")

    def at(theta: FloatArray) -> FloatArray:
        return lti_response(block.structure.system(theta), t, kind)

    if method == "sampling":
        got = _evaluate_draws(at, block.draws(rng, draws), draws)
        lo, hi = np.quantile(got, [0.5 - level / 2, 0.5 + level / 2], axis=0)
        return make(lo, hi, "sampling")
    jac = block.jacobian(at, y)
    if not np.all(np.isfinite(jac)):
        nan = np.full_like(y, np.nan)
        return make(
            nan, nan.copy(), "delta", "no band: a perturbed parameter gives no valid system"
        )
    z = float(stats.norm.ppf(0.5 + level / 2))
    se = np.sqrt(np.maximum(np.einsum("ti,ij,tj->t", jac, block.cov, jac), 0.0))
    return make(y - z * se, y + z * se, "delta")


def step_response(
    result: _Fit,
    t_s: ArrayLike,
    level: float = 0.95,
    *,
    method: str = "delta",
    draws: int = 4000,
    rng: np.random.Generator | int | None = None,
) -> TimeResponseBand:
    """The unit-step response of an LTI fit at times ``t_s`` (s) with a pointwise band.

    Parameters
    ----------
    result : FitResult
        A fit of an LTI structure (``result.system`` a TransferFunction).
    t_s : array_like
        Times (s) after the step, >= 0.
    level : float
        Confidence level in (0, 1).
    method : {"delta", "sampling"}
        y -+ z se(t) from the Jacobian with respect to the system parameters, or pointwise
        quantiles over parameter draws from N(x, C) inside the structure's bounds.
    draws : int
        Number of parameter draws for ``"sampling"`` (at least 100).
    rng : numpy.random.Generator or int
        Source of randomness, required for ``"sampling"``.

    Returns
    -------
    TimeResponseBand
        ``kind="step"``; a NaN band (with ``note``) where a system parameter has no variance.

    Raises
    ------
    ValueError
        For a signal-model fit, negative times, a bad ``level`` or ``method``; for
        ``"sampling"``, if fewer than 90 % of the draws give a valid model.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> res = jid.fit(data, jid.RationalModel(0, 1), jid.Uniform(0.05))
    >>> band = jid.step_response(res, [0.0, 1.0, 3.0])
    >>> band.response.round(2).tolist()
    [0.0, 0.86, 1.0]
    >>> bool(np.all(band.lo <= band.hi))
    True
    """
    return _band(result, t_s, "step", level, method, draws, rng)


def impulse_response(
    result: _Fit,
    t_s: ArrayLike,
    level: float = 0.95,
    *,
    method: str = "delta",
    draws: int = 4000,
    rng: np.random.Generator | int | None = None,
) -> TimeResponseBand:
    """The impulse response g(t) of an LTI fit at times ``t_s`` (s) with a pointwise band;
    the options as :func:`step_response`. A biproper model's Dirac term D delta(t) is not in
    the response (``note`` gives D).

    Parameters
    ----------
    result : FitResult
        A fit of an LTI structure (``result.system`` a TransferFunction).
    t_s : array_like
        Times (s) after the impulse, >= 0.
    level : float
        Confidence level in (0, 1).
    method : {"delta", "sampling"}
        As in :func:`step_response`.
    draws : int
        Number of parameter draws for ``"sampling"`` (at least 100).
    rng : numpy.random.Generator or int
        Source of randomness, required for ``"sampling"``.

    Returns
    -------
    TimeResponseBand
        ``kind="impulse"``.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> band = ji.impulse_response(res, [0.0, 1.0])
    >>> band.kind, band.response.round(2).tolist()
    ('impulse', [2.0, 0.27])
    """
    return _band(result, t_s, "impulse", level, method, draws, rng)
