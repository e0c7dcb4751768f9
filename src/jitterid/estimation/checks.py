"""Checks around the search of :func:`jitterid.fit`, so that a fit is never reported as
successful when it is not (issue 15, section A).

Before the search (:func:`check_arguments`, :func:`check_data`) a problem that cannot give a
meaningful estimate is refused with a :class:`ValueError` naming the argument and the fix:

* ``noise_std`` negative or not finite, ``max_nfev`` not a positive whole number;
* an input that ends before the last sampling instant, an input that is zero at every
  sampling instant and half-way between them (nothing excites the system);
* an output ``y`` that is constant (all zero included): there is no response to fit;
* too few samples: N must be at least 2 P + 4 for P estimated parameters (the frequency
  criteria see about N real numbers; with fewer the search "converges" to anything).

These are errors of the call, not outcomes of a search, so they raise.

:class:`Scaling` normalises y and u by powers of two near their rms (exact in floating
point, so the parameters, criterion and covariance map back exactly), so that the
optimisers' absolute tolerances do not depend on the units of the data.

After the search (:func:`post_checks`; the OE search of :func:`jitterid.fit` and the
Box-Jenkins one, :class:`jitterid.estimation.boxjenkins.BoxJenkinsRoute`) a converged search whose
answer cannot be trusted gets its own non-success
:class:`~jitterid.estimation.result.FitStatus`, and a message that says what to try:

* ``UNSTABLE_MODEL``: the fitted system has a pole with Re >= 0 or non-finite coefficients;
* ``AT_BOUND``: a system parameter on (or within a relative 1e-6 of) a finite bound (the
  structure's, or one set by the user through :class:`~jitterid.Constrained`), or the
  jitter scale collapsed to its floor (below 1e-3 T) while :func:`jitterid.detect_jitter`
  finds jitter at p < 1e-6. A scale at its floor on data without detectable jitter is the
  natural home of the estimate (no jitter) and stays ``CONVERGED``; so does the shape ``n``
  of the sum-of-uniforms family at 0 (the uniform law);
* ``UNIDENTIFIABLE``: the covariance is not finite where no bound explains it, the
  correlation matrix is numerically singular (condition > 1e10), or a bounded parameter's
  standard error exceeds its whole admissible range;
* ``LOCAL_OPTIMUM``: the criterion at one of the default (output-error) starts, or at the
  estimate with its system parameters replaced by one of the structure's default starts
  (``structure.starts(T)``, a few evaluations of the criterion, no search), is already
  lower than at the estimate: the search stopped at a local optimum (e.g. a mean-based
  criterion under jitter many T wide, whose minimum in the system is multimodal);
* ``LACK_OF_FIT``: with the noise std known, the residuals' mean square is over 3 times
  what the model (jitter variance plus the known noise) allows, and a chi-square test
  rejects it at 1e-6 (w_k including the fitted mean's spread): the search ended far from
  any fit of the data, or the given jitter law or noise std is contradicted by the data
  (measured: U(-0.5, 0.5) data fitted with the triangular law of half its variance, 15 of
  20 bcls fits; no false alarm in 120 correctly specified paper-setting fits). With a jitter
  family it says that the estimated scale is too small for the residuals and points to
  'gaussian' or 'ml': a mean-based criterion (bcls) can leave the scale low on a correctly
  specified record (issue 25: 8 of 320 paper-setting bcls fits, 2.5 %, none at N = 1000
  or noise std 0.05; tests/estimation/test_lack_of_fit_rate.py);
* ``NOT_SIGNIFICANT``: the fitted model does not explain significantly more of y than the
  zero model (an F test of the residual sums of squares at the 1e-3 level): the data carry
  no detectable response to the input (e.g. pure noise), or a gain fixed at 0 by the user
  makes the model's output zero. It is also what a non-finite covariance reports when the
  fit explains nothing (the other parameters then have no information by construction).

* ``OVER_ORDER``: a pole and a zero that cancel, or a pole or zero not told from infinity
  (:func:`over_order_symptom`, the test :func:`jitterid.select_order` applies to its rows):
  the model has more poles or zeros than the data support.
* ``IRREGULAR`` (the exact likelihood with its inverse observed information, ``ml``'s
  default ``cov_type="oim"``): the outer product of the per-sample scores is below 0.2 of
  the observed information in every direction (:func:`_irregular`): the information
  equality a regular likelihood meets fails, as it does for a jitter law with hard edges
  on a record with almost no noise, and the stated errors are 20-1000 x too small there.

A covariance that was asked for (``PostContext.cov_requested``) and is NaN throughout is a
singular information matrix (``UNIDENTIFIABLE``), never "not computed": NaN standard errors
are never next to ``CONVERGED`` unless ``cov_type="none"`` asked for none.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ..data import SampledData
from ..inputs import Input, Multisine, PiecewiseConstant
from ..jitter.laws import JitterFamily, JitterLaw
from ..params import ParamLayout, count_params
from ..systems.constrained import Constrained
from ..systems.model import Model
from ..systems.structures import ModelStructure
from .hooks import analysis
from .status import FitStatus

__all__: list[str] = []

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: samples needed: at least MIN_SAMPLES_PER_PARAM * P + MIN_SAMPLES_EXTRA
MIN_SAMPLES_PER_PARAM = 2
MIN_SAMPLES_EXTRA = 4
#: a jitter scale below this fraction of T counts as collapsed onto its floor
SCALE_COLLAPSE = 1e-3
#: detection p-value below which a collapsed jitter scale contradicts the data
DETECT_P = 1e-6
#: F-test level of the significance check against the zero model
SIGNIFICANCE = 1e-3
#: condition number of the correlation matrix above which the problem is unidentifiable
MAX_CONDITION = 1e10
#: mean square of the standardized residuals, and chi-square p-value, beyond which a fit
#: with a known noise std does not explain the data
LACK_OF_FIT_RATIO = 3.0
LACK_OF_FIT_P = 1e-6
#: a pole and a zero closer than this fraction of |p| cancel (a 5 % pair moves the gain by
#: about 5 % |p| / |Re p|: far below what a model order is for)
CANCEL_REL = 0.05
#: a separation |p - z| (or a reciprocal 1/p, 1/z) within this many standard errors of zero
#: is not distinguished from a cancellation (about 95 % two-sided)
CANCEL_SE = 2.0
#: a pole or zero with |p| T above this decays (or acts) within T / 1000 of an input switch:
#: the samples cannot tell it from a gain, i.e. from one at infinity
FAST_POLE = 1e3
#: a rate bound (rad/s) this many times above 1/(N T) is above every rate the record shows
_FLOOR_RESOLVED = 100.0
#: a fitted jitter reach within this many T of the input's end was stopped by it (a
#: converged family search sits on the end to ~1e-8 T; a failed search a few % before it)
_REACH_CONVERGED = 1e-4
_REACH_FAILED = 0.05
#: the exact likelihood is irregular where the outer product of its per-sample scores is
#: below this fraction of the observed information in every direction (_irregular).
#: Measured (session 19, Table 2's system, U(-0.5, 0.5) known, N = 200, 12-16 ML fits per
#: noise std; the generalized eigenvalues of the scores' outer product to the information):
#: the largest is 0.85-2.2 at noise 1e-2, 0.49-2.3 at 1e-3, 0.29-2.4 at 1e-4, and 0.09 and
#: 0.003 at 1e-6, where the stated errors were 20-1000 x too small
IRREGULAR_RATIO = 0.2


# ------------------------------------------------------------------------ before the search
def _real(x: object) -> float | None:
    """``x`` as a float if it is a real number (not a string or a bool), else None."""
    if isinstance(x, (str, bytes, bool, np.bool_)):
        return None
    try:
        return float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None


def check_arguments(noise_std: object, max_nfev: object) -> tuple[float | None, int]:
    """``noise_std`` as a float >= 0 (or None) and ``max_nfev`` as a positive int, or a
    ValueError naming the argument (never a TypeError: every argument error of fit() is a
    ValueError)."""
    if noise_std is not None:
        val = _real(noise_std)
        if val is None or not math.isfinite(val) or val < 0:
            raise ValueError(
                f"noise_std must be a finite number >= 0 (a standard deviation) or None; got "
                f"{noise_std!r}. Pass the measurement-noise std, or None to estimate it"
            )
        noise_std = val
    m = _real(max_nfev)
    if m is None or not math.isfinite(m) or m < 1 or m != math.floor(m):
        raise ValueError(f"max_nfev must be a positive whole number, e.g. 2000; got {max_nfev!r}")
    return noise_std, int(m)


def check_method_jitter(ignores_jitter: bool, method: str, jitter: object) -> None:
    """Refuse an estimator that ignores the jitter (``ls``) with a jitter family: it cannot
    estimate the family's parameters (the one rule for :func:`jitterid.fit` and
    :func:`jitterid.select_order`)."""
    if ignores_jitter and isinstance(jitter, JitterFamily):
        raise ValueError(
            f"method {method!r} ignores the jitter, so it cannot estimate jitter parameters; "
            "pass a known law (or NoJitter()) or use 'bcls'/'asml'"
        )


def check_data(
    data: SampledData,
    n_params: int,
    uses_input: bool = True,
    jitter: JitterLaw | JitterFamily | None = None,
) -> None:
    """Refuse data that cannot identify anything (module docstring); the input checks only
    for a model driven by one (``uses_input``, :attr:`jitterid.systems.model.Model.uses_input`).
    With a known jitter law (``jitter``), the input must also last past the jitter's reach
    after the last sample (:func:`input_reach`)."""
    if uses_input:
        _check_input(data)
        if isinstance(jitter, JitterLaw):
            problem = input_reach(data, jitter)
            if problem is not None:
                raise ValueError(f"data.u: {problem}")
    _check_y_and_size(data, n_params)


def input_reach(
    data: SampledData, law: JitterLaw, delay_s: float = 0.0, margin: float = 0.0
) -> str | None:
    """Why the input does not cover the last jittered sampling instant (N-1) T + the law's
    reach (less a model's ``delay_s``), or None if it does; ``margin`` (s) also counts a
    reach within that distance of the end (a search stopped by the end). The one rule of
    the input's end for every method (:meth:`jitterid.inputs.Input.coverage_message`)."""
    u = data.u
    if u is None:
        return None
    reach = (data.N - 1) * data.T + float(law.support[1]) - delay_s
    if reach < u.end - margin:
        return None
    return u.coverage_message(reach, "the jitter (the last jittered sampling instant)")


def _check_input(data: SampledData) -> None:
    t = data.t_nominal
    u = data.u
    if u is None:
        raise ValueError(
            "data.u: this model is driven by a known input, but the data have none; give the "
            "input (SampledData(y, T, u)) or fit a signal model with no input (SignalModel)"
        )
    if t[-1] >= u.end:
        raise ValueError(
            f"data.u: {u.coverage_message(t[-1], f'the samples (N = {data.N}, T = {data.T:g})')}"
            " (after its end the input is taken as zero, so the fit would be wrong)"
        )
    mid = np.minimum(t + 0.5 * data.T, np.nextafter(u.end, -np.inf))
    if not (np.any(u(t) != 0) or np.any(u(mid) != 0)):
        raise ValueError(
            "data.u: the input is zero at every sampling instant: nothing excites the system, "
            "so it cannot be identified. Check the input column/units, or use an input that "
            "switches (telegraph_input, zoh_input of a random sequence) or a multisine"
        )


def _check_y_and_size(data: SampledData, n_params: int) -> None:
    y = data.y
    if np.ptp(y) == 0:
        raise ValueError(
            f"data.y: the output is constant (every sample = {y[0]:g}): there is no response "
            "to identify. Check the output column, its units and the sensor"
        )
    need = MIN_SAMPLES_PER_PARAM * n_params + MIN_SAMPLES_EXTRA
    if need > data.N:
        raise ValueError(
            f"data: N = {data.N} samples are too few for {n_params} parameters (need at least "
            f"{need} = {MIN_SAMPLES_PER_PARAM} per parameter + {MIN_SAMPLES_EXTRA}); record "
            "more samples, fix the jitter law, or use a structure with fewer parameters"
        )


# ------------------------------------------------------------------------ scaling
def _pow2(rms: float) -> float:
    if not (np.isfinite(rms) and rms > 0):
        return 1.0
    return float(2.0 ** round(math.log2(rms)))


def _scaled_input(u: Input, c: float) -> Input | None:
    """``c u`` for the input types the criteria support, else None."""
    if isinstance(u, PiecewiseConstant):
        return PiecewiseConstant(u.times, u.levels * c)
    if isinstance(u, Multisine):
        return Multisine(
            u.freqs,
            u.amplitudes * c,
            u.end,
            u.phases,
            0.0 if u.steady_state else u.start,
            u.steady_state,
        )
    return None


@dataclass(frozen=True)
class Scaling:
    """The data scaled to y / sy and u / su with sy, su powers of two near their rms.

    The system's gain parameters (``structure.gain_params``) then scale by su / sy and the
    noise std by 1 / sy; every other parameter (poles, jitter) is unchanged. Powers of two
    make every map exact, so a problem already in unit scale is solved bit-identically.
    """

    sy: float
    su: float
    factors: FloatArray  # x_scaled = x * factors

    @staticmethod
    def build(data: SampledData, structure: Model, n_jitter: int) -> Scaling:
        """The scaling for ``data``; the identity when the structure cannot absorb it."""
        n = n_jitter + len(structure.param_names)
        one = Scaling(1.0, 1.0, np.ones(n))
        gains = list(structure.gain_params)
        if not gains:
            return one
        bounds = np.array(structure.bounds, float).reshape(-1, 2)
        if not np.all(np.isinf(bounds[gains])):  # a finite bound on a gain would move
            return one
        sy = _pow2(float(np.sqrt(np.mean(data.y**2))))
        su = 1.0  # a model without input: its gains scale with y alone
        if structure.uses_input and data.u is not None and _scaled_input(data.u, 1.0) is not None:
            su = _pow2(float(np.sqrt(np.mean(data.u(data.t_nominal) ** 2))))
        f = np.ones(n)
        f[[n_jitter + g for g in gains]] = su / sy
        return Scaling(sy, su, f)

    @property
    def identity(self) -> bool:
        return self.sy == 1.0 and self.su == 1.0

    def data(self, data: SampledData) -> SampledData:
        if self.identity:
            return data
        u = None if data.u is None else _scaled_input(data.u, 1.0 / self.su)
        assert u is not None or data.u is None
        noise = None if data.noise_std is None else data.noise_std / self.sy
        res = None if data.resolution is None else data.resolution / self.sy
        return SampledData(data.y / self.sy, data.T, u, noise, data.instants, res)

    def _f(self, size: int) -> FloatArray:
        """Factors for a vector of ``size``: jitter and system, then (if one more) noise_std."""
        return np.r_[self.factors, 1.0 / self.sy][:size]

    def to_scaled(self, x: FloatArray) -> FloatArray:
        return np.asarray(x, float) * self._f(np.size(x))

    def to_original(self, x: FloatArray) -> FloatArray:
        return np.asarray(x, float) / self._f(np.size(x))

    def cov_to_original(self, cov: FloatArray) -> FloatArray:
        f = self._f(cov.shape[0])
        return np.asarray(cov, float) / np.outer(f, f)


# ------------------------------------------------------------------------ after the search
@dataclass
class PostContext:
    """What the checks after the search need, in the scaled units of the search."""

    data: SampledData
    structure: Model
    jitter: JitterLaw | JitterFamily
    names: tuple[str, ...]
    bounds: Sequence[tuple[float, float]]
    x: FloatArray
    cost: float
    cov: FloatArray  # in the units of x
    objective: Callable[[FloatArray], float]
    model_mean: Callable[[FloatArray], FloatArray]  # E y_k at x
    oe_system: Callable[[], FloatArray | None]  # theta of the ordinary OE fit (lazy)
    starts: Callable[[], list[FloatArray]]  # the default starts of this criterion (lazy)
    cov_error: str | None = None  # why the covariance could not be computed
    # w_k = Var s(kT + tau) + the known noise variance + the fitted mean's spread, where the
    # noise std is known and the criterion models the jitter (else None: no such check)
    known_variance: Callable[[FloatArray], FloatArray] | None = None
    # parameters without an error bar by design, not for want of information (Box-Jenkins:
    # the pole of a noise model at its white limit, on which the criterion does not depend)
    exempt: tuple[int, ...] = ()
    # the criterion's per-sample terms over a leading part of the record (the exact
    # likelihood's -2 ln p_k over its first SCREEN_SAMPLES samples), for a cheap first look
    # at points far from the estimate on a long record (None: every point in full)
    screen: Callable[[FloatArray], FloatArray] | None = None
    # the search's y is the data's divided by this (:class:`Scaling`): a message that quotes a
    # value in y's units multiplies it back
    y_scale: float = 1.0
    # whether a covariance was asked for (cov_type other than "none"): then a covariance
    # that is NaN throughout is a failure (a singular information matrix), not "not
    # computed". None: not said (an all-NaN covariance is then taken as not computed)
    cov_requested: bool | None = None
    # the exact likelihood's per-sample scores d ln p_k / dx at a point, shape (N, p), where
    # the covariance is its inverse observed information (cov_type "oim"): the information
    # equality is then checked (_irregular). None: no such check
    scores: Callable[[FloatArray], FloatArray] | None = None


def _n_jitter(jitter: JitterLaw | JitterFamily) -> int:
    return count_params(jitter)


def post_checks(ctx: PostContext, status: FitStatus, message: str) -> tuple[FitStatus, str]:
    """The status and message after the checks; only a CONVERGED search is re-examined (a
    failed one whose jitter reaches the input's end is told so: :func:`_input_end`)."""
    if status is not FitStatus.CONVERGED:
        ended = _input_end(ctx, margin=_REACH_FAILED * ctx.data.T)
        if ended is not None:
            return status, f"{message}; the likely cause: {ended}"
        return status, message
    checks = (
        _input_end_reached,
        _at_bound,
        _noise_at_floor,
        _unstable,
        _unidentifiable,
        _local_optimum,
        _not_significant,
        _over_order,
        _lack_of_fit,
        _irregular,
    )
    for check in checks:
        out = check(ctx)
        if out is not None:
            return out[0], f"{out[1]} (search: {message})"
    held = _held_jitter(ctx)
    if held:
        return status, f"{message}; {held}"
    return status, message


def _kinked(ctx: PostContext) -> NDArray[np.bool_]:
    """Jitter-family parameters at a kink of the family (:meth:`ParamLayout.at_kink`, the
    covariance's rule: held fixed there)."""
    out = np.zeros(ctx.x.size, dtype=bool)
    if isinstance(ctx.jitter, JitterFamily):
        nj = len(ctx.jitter.param_names)
        out[:nj] = ParamLayout.build(ctx.jitter).at_kink(ctx.x[:nj])
    return out


def _flat_shapes(ctx: PostContext) -> NDArray[np.bool_]:
    """Shape parameters of a jitter family (not its scale) without an error bar while
    others have one: the covariance held them fixed as not identified by the data
    (:func:`jitterid.estimation.covariance.unidentified_shapes`)."""
    out = np.zeros(ctx.x.size, dtype=bool)
    fam = ctx.jitter
    if not isinstance(fam, JitterFamily) or len(fam.param_names) < 2:
        return out
    fin = np.isfinite(np.diag(np.asarray(ctx.cov, float)))
    for i in range(len(fam.param_names)):
        out[i] = i != fam.scale_index and not fin[i] and bool(fin[np.arange(fin.size) != i].any())
    return out


def _held_jitter(ctx: PostContext) -> str:
    """What a converged fit says of jitter-family parameters held fixed for the error bars:
    at a kink, or a shape the data do not identify (flat along the family at a fixed std),
    with the jitter std's relative standard error (delta method, the others free)."""
    fam = ctx.jitter
    if not isinstance(fam, JitterFamily):
        return ""
    nj = len(fam.param_names)
    k = fam.scale_index
    if k is not None and float(ctx.x[k]) <= SCALE_COLLAPSE * ctx.data.T:
        # (where the data showed jitter, _at_bound has said AT_BOUND before)
        std = float(fam.law(ctx.x[:nj].tolist()).std)
        shapes = [ctx.names[i] for i in range(nj) if i != k]
        return (
            f"the jitter scale is on its floor ({ctx.names[k]} = {ctx.x[k]:.3g}, jitter std "
            f"{std:.3g}, below {SCALE_COLLAPSE:g} T): the criterion's minimum is zero jitter, "
            "a boundary estimate without a standard error"
            + (f", and {', '.join(shapes)} mean nothing there" if shapes else "")
            + "; the data show no jitter this criterion can measure (detect_jitter, "
            "method 'gaussian' or 'ml' for the jitter's own variance)"
        )
    kink, flat = _kinked(ctx)[:nj], _flat_shapes(ctx)[:nj] & ~_kinked(ctx)[:nj]
    lo, hi = np.array(fam.bounds, dtype=float).T
    on = [_near(v, a) or _near(v, b) for v, a, b in zip(ctx.x[:nj], lo, hi, strict=True)]
    bound = flat & np.array(on, dtype=bool)
    flat &= ~bound
    parts = []
    for i in np.flatnonzero(kink):
        parts.append(
            f"{ctx.names[i]} = {ctx.x[i]:g} is at a kink of the family (no second derivative): "
            "held fixed for the error bars"
        )
    for i in np.flatnonzero(bound):
        parts.append(
            f"{ctx.names[i]} = {ctx.x[i]:g} is on its bound: held fixed for the error bars, "
            "which are conditional on it"
        )
    if flat.any():
        which = ", ".join(ctx.names[i] for i in np.flatnonzero(flat))
        parts.append(
            f"{which} not identified by the data (the criterion is flat along the family at "
            "a fixed jitter std): held fixed for the error bars"
        )
    if not parts:
        return ""
    std, se = _std_stderr(ctx)
    if np.isfinite(se) and std > 0:
        parts.append(f"the jitter std is identified to {100 * se / std:.2g} % (1 standard error)")
    return "; ".join(parts)


def _std_stderr(ctx: PostContext) -> tuple[float, float]:
    """The estimate's jitter std and its standard error by the delta method over the family's
    parameters with an error bar (NaN where none has one)."""
    fam = ctx.jitter
    assert isinstance(fam, JitterFamily)
    nj = len(fam.param_names)
    theta = ctx.x[:nj]
    C = np.asarray(ctx.cov, float)[:nj, :nj]
    fin = np.isfinite(np.diag(C))
    std = float(fam.law(theta.tolist()).std)
    if not fin.any():
        return std, float("nan")
    g = fam.std_gradient(theta)[fin]
    return std, float(np.sqrt(max(float(g @ C[np.ix_(fin, fin)] @ g), 0.0)))


def _fitted_law(ctx: PostContext) -> JitterLaw | None:
    """The estimate's jitter law (a family's at its estimate; None where it cannot be made)."""
    if not isinstance(ctx.jitter, JitterFamily):
        return ctx.jitter
    try:
        return ctx.jitter.law(list(ctx.x[: _n_jitter(ctx.jitter)]))
    except ValueError:
        return None


def _input_end(ctx: PostContext, margin: float) -> str | None:
    """:func:`input_reach` at the estimate's jitter law (a family's at its estimate)."""
    if ctx.data.u is None or not ctx.structure.uses_input:
        return None
    law = _fitted_law(ctx)
    if law is None:
        return None
    delay = float(ctx.x[ctx.names.index("delay_s")]) if "delay_s" in ctx.names else 0.0
    return input_reach(ctx.data, law, delay, margin)


def _input_end_reached(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """A jitter family's scale stopped where its reach meets the input's end: the search
    could not widen the law further (the moments are not defined past the input), so the
    estimate is at an artificial bound, not at the criterion's optimum."""
    if not isinstance(ctx.jitter, JitterFamily):
        return None
    ended = _input_end(ctx, margin=_REACH_CONVERGED * ctx.data.T)
    if ended is None:
        return None
    return FitStatus.AT_BOUND, (
        f"the jitter's estimate stopped where its reach meets the end of the input: {ended}. "
        "The estimate is held there by the input, not by the data"
    )


def _theta(ctx: PostContext) -> FloatArray:
    return ParamLayout.build(ctx.jitter, ctx.structure).block(ctx.x, "system")


def _unstable(ctx: PostContext) -> tuple[FitStatus, str] | None:
    if not (ctx.structure.param_names and isinstance(ctx.structure, ModelStructure)):
        return None  # a signal model has no poles
    tf = ctx.structure.system(_theta(ctx))
    coef = np.r_[tf.num, tf.den]
    if not np.all(np.isfinite(coef)):
        return FitStatus.UNSTABLE_MODEL, "the fitted system has non-finite coefficients"
    poles = np.roots(tf.den)
    bad = poles[poles.real >= 0]
    if bad.size:
        return FitStatus.UNSTABLE_MODEL, (
            f"the fitted system is unstable: poles {np.round(bad, 6).tolist()} have Re >= 0; "
            "use fewer poles (a lower den_order), another start, or a longer record"
        )
    # A (nearly) undamped resonance whose decay outlasts the record: the criterion cannot
    # tell it from an unstable one, and the covariance's steps cross the boundary.
    record = ctx.data.N * ctx.data.T
    edge = poles[
        (poles.imag != 0) & (-poles.real < 1e-3 * np.abs(poles)) & (-poles.real * record < 1)
    ]
    if edge.size:
        return FitStatus.UNSTABLE_MODEL, (
            f"the fitted system is on the edge of instability: poles {np.round(edge, 6).tolist()} "
            f"are undamped (damping ratio < 1e-3, decay time longer than the record of "
            f"{record:g}); use fewer poles (a lower den_order) or another start"
        )
    return None


def _near(v: float, b: float) -> bool:
    return bool(np.isfinite(b) and abs(v - b) <= 1e-6 * max(1.0, abs(b)))


def _difference_reach(x: FloatArray) -> FloatArray:
    """How far from a bound the covariance holds a parameter fixed (its rows NaN): x +- 2h
    must lie inside, h at most 1e-4 max(|x|, 1e-2) (``covariance._steps``)."""
    return 2e-4 * np.maximum(np.abs(x), 1e-2)


def _noise_at_floor(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """An estimated noise std on its floor (``SampledData.resolution``, else 1e-12): the
    samples do not resolve the additive noise next to the jitter (the noise-free jittered
    signal explains them at least as well); the other estimates are given it there."""
    if "noise_std" not in ctx.names or ctx.data.resolution is None:
        return None
    i = ctx.names.index("noise_std")
    v = float(ctx.x[i])
    floor = ctx.data.resolution
    # next to it, within the covariance's difference reach: held there by the covariance
    # (no error bar), as good as on it (a quantised record's noise std 0.4 % above LSB /
    # sqrt(12), 0.6 of its error: UNIDENTIFIABLE before, "no finite covariance")
    held = (
        not np.isfinite(np.asarray(ctx.cov, float)[i, i])
        and v - floor < _difference_reach(np.array([v]))[0]
    )
    if v > floor * (1 + 1e-6) and not held:
        return None
    where = "on" if v <= floor * (1 + 1e-6) else "next to"
    sy = ctx.y_scale  # the message in the data's units
    return FitStatus.AT_BOUND, (
        f"noise_std = {v * sy:.6g} is {where} its floor, the data's resolution {floor * sy:g}: "
        "the samples do not resolve the additive noise next to the jitter (the noise-free "
        "jittered signal explains them as well), so the other estimates are given the noise "
        "at that floor; give the converter's resolution (LSB / sqrt(12)) if it is known"
    )


#: a system parameter within this many of its standard errors of a bound is on it
#: (:func:`_at_bound`): a trust-region search stays strictly inside its box, as near to a
#: bound the optimum lies beyond as its path takes it (Table 2, uniform case, realization
#: 83: LS stopped with pi 3.5e-6 above its floor 0.001, 2.6e-9 of its standard error, and
#: was reported CONVERGED; the same fit had stopped 5.3e-7 above it, AT_BOUND)
BOUND_SE = 0.01


def _at_bound(ctx: PostContext) -> tuple[FitStatus, str] | None:
    theta = _theta(ctx)
    system = ParamLayout.build(ctx.jitter, ctx.structure).slice("system")
    with np.errstate(invalid="ignore"):
        se = np.sqrt(np.diag(ctx.cov)[system]) if ctx.cov.ndim == 2 else np.full(theta.size, np.nan)
    for i, (name, v) in enumerate(zip(ctx.structure.param_names, theta, strict=True)):
        on = [
            b
            for b in ctx.structure.bounds[i]
            if _near(v, b) or (np.isfinite(b) and abs(v - b) <= BOUND_SE * se[i])
        ]
        if on:
            b = on[0]
            if isinstance(ctx.structure, Constrained) and b in ctx.structure.user_bounds.get(
                name, ()
            ):
                return FitStatus.AT_BOUND, (
                    f"the system parameter {name} = {v:.6g} is on the bound {b:g} you set: the "
                    "criterion's optimum lies beyond it, so the estimate and its error bars "
                    "hold only if the bound is a physical limit; widen or drop it (bounds=, "
                    "--bounds) to see where the optimum is"
                )
            record = ctx.data.N * ctx.data.T
            if name in ("pr", "pi") and abs(b) * record > _FLOOR_RESOLVED:
                # PolePairGain's floors are rates in rad/s: on data on a slow time scale they
                # lie far above every rate the record can show
                return FitStatus.AT_BOUND, (
                    f"the system parameter {name} = {v:.6g} is on its floor {b:g} rad/s "
                    f"(PolePairGain's pr_min/pi_min), {abs(b) * record:.3g} times the slowest "
                    f"rate the record resolves, 1/(N T) = {1 / record:.3g} rad/s: the data are "
                    f"on a slower time scale than the floors (T = {ctx.data.T:g} s). Give the "
                    "times in a larger unit, so that T is near 1 (the rates are then per that "
                    "unit), or PolePairGain(pr_min=..., pi_min=...) below the rates you expect"
                )
            return FitStatus.AT_BOUND, (
                f"the system parameter {name} = {v:.6g} is on its bound {b:g}: the optimum lies "
                "outside the structure's admissible set (e.g. a real pole pair for PolePairGain, "
                "a pole on the stability boundary); try another structure (RationalModel) or "
                "another start"
            )
    k = ctx.jitter.scale_index if isinstance(ctx.jitter, JitterFamily) else None
    if k is None:
        return None
    scale = float(ctx.x[k])
    if scale > SCALE_COLLAPSE * ctx.data.T:
        return None
    theta_oe = ctx.oe_system()
    if theta_oe is None or not isinstance(ctx.structure, ModelStructure):
        return None  # detect_jitter needs a system driven by an input
    detect_jitter = analysis("detect_jitter")  # registered by jitterid.analysis

    try:
        det = detect_jitter(ctx.data, ctx.structure.system(theta_oe))
    except ValueError:
        return None
    if det.pvalue >= DETECT_P:
        return None  # no detectable jitter: a scale at the floor is the natural estimate
    name = ctx.names[k]
    return FitStatus.AT_BOUND, (
        f"the jitter scale collapsed: {name} = {scale:.3g} (below {SCALE_COLLAPSE:g} T) while "
        f"detect_jitter finds jitter (p = {det.pvalue:.2g}, implied std {det.jitter_std:.3g}), "
        "so the estimate and its standard errors cannot be trusted (a mean-based criterion "
        "such as bcls can trade a small jitter for the system's coefficients). Use a criterion "
        "that sees the jitter's variance (method 'asml', 'gaussian' or 'ml'), a known jitter "
        f"law, or a start with {name} near the detected std"
    )


def _unidentifiable(ctx: PostContext) -> tuple[FitStatus, str] | None:
    if ctx.cov_error is not None:
        return FitStatus.UNIDENTIFIABLE, (
            f"the covariance cannot be computed ({ctx.cov_error}), so the estimate has no "
            "error bars; try another start or a structure with fewer parameters"
        )
    cov = np.asarray(ctx.cov, float)
    p = ctx.x.size
    if p == 0 or (np.all(np.isnan(cov)) and not ctx.cov_requested):  # "none"
        return None
    on = np.array(
        [_near(v, lo) or _near(v, hi) for v, (lo, hi) in zip(ctx.x, ctx.bounds, strict=True)]
    )
    k = ctx.jitter.scale_index if isinstance(ctx.jitter, JitterFamily) else None
    if k is not None and ctx.x[k] <= SCALE_COLLAPSE * ctx.data.T:
        on[k] = True  # no jitter (checked by _at_bound): its scale has no finite variance
    on |= _kinked(ctx) | _flat_shapes(ctx)  # held fixed by the covariance (_held_jitter)
    # a jitter-family parameter next to its bound, within the covariance's difference reach
    # (x +- 2h inside, h = 1e-4 max(|x|, 1e-2)): held fixed by the covariance too (a = 0.4999
    # of a_max = 0.5: the law's natural limit, not a failure)
    nj = _n_jitter(ctx.jitter) if isinstance(ctx.jitter, JitterFamily) else 0
    reach = _difference_reach(ctx.x[:nj])
    lo_b, hi_b = np.array(ctx.bounds, float).reshape(-1, 2)[:nj].T
    on[:nj] |= (ctx.x[:nj] - reach < lo_b) | (ctx.x[:nj] + reach > hi_b)
    on[list(ctx.exempt)] = True
    free = ~on
    c = cov[np.ix_(free, free)]
    names = [n for n, f in zip(ctx.names, free, strict=True) if f]
    if c.size == 0:
        return None
    d = np.diag(c)
    if not np.all(np.isfinite(c)) or np.any(d <= 0):
        # a model that explains nothing has no information on its other parameters: say that
        insignificant = _not_significant(ctx)
        if insignificant is not None:
            return insignificant
        bad = [n for n, v in zip(names, d, strict=True) if not (np.isfinite(v) and v > 0)]
        return FitStatus.UNIDENTIFIABLE, (
            "the information matrix is singular (no finite covariance for "
            f"{bad or names}); "
            "fix some parameters (a known jitter law), use a structure with fewer parameters, "
            "or a richer input"
        )
    se = np.sqrt(d)
    bnd = np.array(ctx.bounds, float).reshape(-1, 2)[free]
    width = bnd[:, 1] - bnd[:, 0]
    wide = np.isfinite(width) & (se > width)
    if np.any(wide):
        j = int(np.flatnonzero(wide)[0])
        return FitStatus.UNIDENTIFIABLE, (
            f"{names[j]} is not identified: its standard error {se[j]:.3g} exceeds its whole "
            f"admissible range [{bnd[j, 0]:g}, {bnd[j, 1]:g}]; fix it (e.g. a known jitter law "
            "or a one-parameter family), or collect more or more informative data"
        )
    corr = c / np.outer(se, se)
    ev = np.linalg.eigvalsh(0.5 * (corr + corr.T))
    if ev[0] <= ev[-1] / MAX_CONDITION:
        return FitStatus.UNIDENTIFIABLE, (
            f"the information matrix is nearly singular (correlation condition number "
            f"{ev[-1] / max(ev[0], 1e-300):.2g}): some combination of {names} is not identified; "
            "use a structure with fewer parameters, a known jitter law, or a richer input"
        )
    return None


def _over_order(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """The over-order symptom of :func:`over_order_symptom` (the test of
    :func:`jitterid.select_order`'s rows) on a single fit: the system block of the estimate
    and of its covariance (the scaling of the search moves no pole or zero)."""
    if not (ctx.structure.param_names and isinstance(ctx.structure, ModelStructure)):
        return None
    nj = _n_jitter(ctx.jitter)
    block = slice(nj, nj + len(ctx.structure.param_names))
    cov = np.asarray(ctx.cov, float)[block, block]
    symptom = over_order_symptom(ctx.structure, _theta(ctx), cov, ctx.data.T)
    if not symptom:
        return None
    return FitStatus.OVER_ORDER, (
        f"over-order model: {symptom}; use a lower order (fewer poles and zeros), or compare "
        "orders with select_order (jitterid fit with --model repeated)"
    )


def _structure_starts(ctx: PostContext) -> list[tuple[FloatArray, str]]:
    """The estimate with its system parameters replaced by each of the structure's default
    starts (``structure.initial_points(data)``: ``starts(T)`` of an LTI structure), inside
    the bounds: the points an ordinary multi-start
    over the system would begin from, at the fitted jitter and noise; each with a label."""
    p = len(ctx.structure.param_names)
    if not p:
        return []
    try:
        starts = ctx.structure.initial_points(ctx.data)
    except (ValueError, NotImplementedError):
        return []
    nj = _n_jitter(ctx.jitter)
    lo, hi = np.array(ctx.bounds, float).reshape(-1, 2).T
    out = []
    for i, s0 in enumerate(starts):
        s0 = np.asarray(s0, float)
        if s0.shape != (p,) or not np.all(np.isfinite(s0)):
            continue
        v = ctx.x.copy()
        v[nj : nj + p] = s0
        label = (
            f"the estimate with its system parameters set to the structure's default start "
            f"{i} = {np.round(s0, 6).tolist()}"
        )
        out.append((np.clip(v, lo, hi), label))
    return out


SCREEN_SAMPLES = 20_000  # the screen's leading samples (PostContext.screen)
_SCREEN_Z = 8.0  # a start this many standard errors worse on them is not evaluated in full


def clearly_worse(d: FloatArray) -> bool:
    """Whether per-sample criterion differences (start minus estimate) over the screen's
    samples say the start is worse by more than ``_SCREEN_Z`` standard errors of their sum:
    a start that beats the estimate over the whole record would do so on a leading part
    too, up to that noise. Otherwise the start is evaluated in full."""
    total = float(np.sum(d))
    return bool(np.isfinite(total) and total > _SCREEN_Z * np.sqrt(d.size) * float(np.std(d)))


def lowest_below(
    points: Sequence[FloatArray],
    objective: Callable[[FloatArray], float],
    x: FloatArray,
    cost: float,
    screen: Callable[[FloatArray], FloatArray] | None = None,
) -> tuple[int | None, float, int]:
    """The point of ``points`` where ``objective`` is lowest, where that is lower than
    ``cost`` (the criterion at ``x``) by more than 1e-6 relative: its index (None where no
    point is), its criterion, and the full evaluations made. A point that ``screen``
    (per-sample criterion terms over the record's leading samples) shows clearly worse than
    ``x`` (:func:`clearly_worse`) is not evaluated in full; one where the objective raises
    or is not finite is passed over. The one comparison of an end with other points: the
    post-search check below and the second stage's comparison with the default starts
    (:meth:`jitterid.estimation.oe.OutputErrorRoute.default_starts`)."""
    base = None if screen is None else screen(x)
    which: int | None = None
    best, n = cost, 0
    for j, x0 in enumerate(points):
        with np.errstate(all="ignore"):
            try:
                if base is not None and screen is not None and clearly_worse(screen(x0) - base):
                    continue
                n += 1
                v = float(objective(x0))
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                continue
        if np.isfinite(v) and v < best:
            best, which = v, j
    if which is None or not best < cost - 1e-6 * max(abs(cost), 1e-300):
        return None, cost, n
    return which, best, n


def _local_optimum(ctx: PostContext) -> tuple[FitStatus, str] | None:
    candidates = [
        (x0, f"the default start {np.round(x0, 6).tolist()} (in the search's units)")
        for x0 in ctx.starts()
    ]
    candidates += _structure_starts(ctx)
    j, best, _ = lowest_below(
        [x0 for x0, _ in candidates], ctx.objective, ctx.x, ctx.cost, ctx.screen
    )
    if j is None:
        return None
    which = candidates[j][1]
    return FitStatus.LOCAL_OPTIMUM, (
        f"the search stopped at a local optimum: the criterion is lower at {which} than at "
        f"the estimate ({best:.6g} against {ctx.cost:.6g}, with y and u scaled as in the "
        "search), so the estimate is not the criterion's minimum and its error bars mean "
        "nothing: fit again without start (the default multi-start) or from a better start; "
        "if this happened without a start, the criterion is multimodal here (e.g. jitter "
        "wide against the system's time scale, so the mean of the samples carries little of "
        "the response): fit from that start, try method 'gaussian' or 'ml' from it, use a "
        "longer record, or a richer input"
    )


def _has_gain(structure: Model) -> bool:
    """Whether the model scales its output by gain parameters, free or set by the user (a
    :class:`~jitterid.Constrained` structure whose gain is fixed, e.g. to 0, has none free)."""
    inner = structure.structure if isinstance(structure, Constrained) else structure
    return bool(inner.gain_params)


def _not_significant(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """An F test of the fit against the zero model (module doc), for every model with a gain,
    free or fixed: a gain fixed at 0 (``Constrained(..., fixed={"k0": 0})``) leaves a model
    that explains nothing, whatever its other parameters."""
    if not ctx.structure.param_names or not _has_gain(ctx.structure):
        return None
    y = ctx.data.y
    try:
        m = np.asarray(ctx.model_mean(ctx.x), float)
    except ValueError:
        return None
    rss0 = float(y @ y)
    rss1 = float(np.sum((y - m) ** 2))
    p = len(ctx.structure.param_names)
    dof = y.size - ctx.x.size
    if dof <= 0 or rss1 <= 0:
        return None
    fstat = max(rss0 - rss1, 0.0) / p / (rss1 / dof)
    pval = float(stats.f.sf(fstat, p, dof))
    if pval < SIGNIFICANCE:
        return None
    st = ctx.structure
    if isinstance(st, Constrained):
        names = st.structure.param_names
        zero = [names[i] for i in st.structure.gain_params if st.fixed.get(names[i]) == 0]
        if zero:
            return FitStatus.NOT_SIGNIFICANT, (
                f"the fitted model explains no significant part of y (F test against the zero "
                f"model: F = {fstat:.3g}, p = {pval:.2g} >= {SIGNIFICANCE:g}): its gain "
                f"{', '.join(zero)} is fixed at 0, so its output is zero whatever the other "
                "parameters (which the data then cannot determine). Fix the gain to a non-zero "
                "value or leave it free"
            )
    return FitStatus.NOT_SIGNIFICANT, (
        f"the fitted model explains no significant part of y (F test against the zero model: "
        f"F = {fstat:.3g}, p = {pval:.2g} >= {SIGNIFICANCE:g}): the data show no detectable "
        "response to the input. Check that u is the input that drove y (columns, delays), "
        "remove an offset or trend from y, use a stronger or longer excitation, or reduce "
        "the noise"
    )


def _lack_of_fit(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """With the noise std known, the standardized residuals z_k = (y_k - m_k) / sqrt(w_k),
    w_k = Var y_k + dm_k^T Cov dm_k (the spread of the fitted mean, which an inefficient
    estimator makes many noise stds where Var s_k is tiny), have E z^2 <= 1 whatever the
    jitter law's shape; a mean square above LACK_OF_FIT_RATIO
    that a chi-square test also rejects (p < LACK_OF_FIT_P, conservative for the
    platykurtic samples of jitter) is a model that does not explain the data (e.g. a
    sinusoid's search that ended at the wrong frequency)."""
    if ctx.known_variance is None:
        return None
    try:
        m = np.asarray(ctx.model_mean(ctx.x), float)
        w = np.asarray(ctx.known_variance(ctx.x), float)
    except ValueError:
        return None
    z2 = (ctx.data.y - m) ** 2 / np.maximum(w, 1e-300)
    n = z2.size
    ratio = float(np.mean(z2))
    pval = float(stats.chi2.sf(ratio * n, n))
    if ratio <= LACK_OF_FIT_RATIO or pval >= LACK_OF_FIT_P:
        return None
    if isinstance(ctx.jitter, JitterFamily):
        try:
            std = f" (std {ctx.jitter.law(list(ctx.x[: _n_jitter(ctx.jitter)])).std:.3g} s)"
        except ValueError:
            std = ""
        return FitStatus.LACK_OF_FIT, (
            f"the residuals' mean square is {ratio:.3g} times what the fitted model allows "
            f"with the known noise std (chi-square p = {pval:.2g}): the jitter law estimated"
            f"{std} is too small for the residuals. A criterion on the samples' mean (bcls, "
            "wbcls, asml) sees the jitter only through its attenuation of the response and can "
            "leave its scale low; fit with method 'gaussian' or 'ml', which also fit the "
            "samples' variance, or give the jitter law if it is known (if this is already "
            "such a fit, check noise_std, the data's units and the structure)"
        )
    return FitStatus.LACK_OF_FIT, (
        f"the residuals' mean square is {ratio:.3g} times what the model allows with the "
        f"known noise std (chi-square p = {pval:.2g}): the fit does not explain the data. "
        "Try other starts (for a sinusoid, a frequency within 1/(N T) of the periodogram's "
        "peak), another structure or jitter law, or check noise_std and the data's units"
    )


# ------------------------------------------------------------------------ irregular


def _irregular(ctx: PostContext) -> tuple[FitStatus, str] | None:
    """The information equality at the estimate: for a regular likelihood the outer product
    of the per-sample scores, sum_k g_k g_k^T, and the observed information (the inverse of
    the stated covariance) estimate the same matrix, and their generalized eigenvalues lie
    near 1 (0.16-2.5 measured on regular N = 200 fits). Where every one is below
    IRREGULAR_RATIO the curvature comes from a few samples the estimate sits next to, not
    from the data's spread: a jitter law with hard edges on a record whose noise hardly
    blurs them (measured: errors 20-1000 x the stated ones), and the stated standard errors
    cannot be stood behind."""
    if ctx.scores is None:
        return None
    idx = np.flatnonzero(np.isfinite(np.diag(ctx.cov)))
    if idx.size == 0:
        return None
    try:
        L = np.linalg.cholesky(ctx.cov[np.ix_(idx, idx)])  # cov = L L^T, information L^-T L^-1
        Z = np.asarray(ctx.scores(ctx.x), float)[:, idx] @ L
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(Z)):
        return None
    top = float(np.linalg.eigvalsh(Z.T @ Z).max())
    if top >= IRREGULAR_RATIO:
        return None
    law = _fitted_law(ctx)
    hard = law is not None and law.hard_edges
    why = (
        f"the jitter law {law!r} has hard edges, which a noise this small hardly blurs, and "
        "the estimate sits where a few samples meet them"
        if hard
        else "the curvature comes from a few samples the estimate sits next to, as where the "
        "noise is far below the samples' jitter spread"
    )
    return FitStatus.IRREGULAR, (
        f"the likelihood's curvature at the estimate is at least {1 / top:.3g} times the "
        "spread of its per-sample scores in every direction (a regular likelihood has them "
        f"equal to sampling error; the check flags below {IRREGULAR_RATIO:g}): it is not "
        f"regular here ({why}), so the stated standard errors understate the estimate's "
        "spread and the search may have stopped at one of many nearby maxima. Fit with a "
        "moment criterion (method 'bcls' or 'asml'), whose errors hold there"
        + (", or a jitter law without hard edges" if hard else "")
    )


# ------------------------------------------------------------------------ over-order


def _root_gradients(coef: FloatArray, dcoef: FloatArray) -> tuple[ComplexArray, ComplexArray]:
    """Roots r_j of the polynomial ``coef`` (highest power first) and dr_j/dtheta, shape
    (roots, P), from dr/dc_i = -r^(d - i) / c'(r) (a simple root)."""
    d = coef.size - 1
    if d < 1:
        return np.zeros(0, complex), np.zeros((0, dcoef.shape[0]), complex)
    roots = np.roots(coef).astype(complex)
    with np.errstate(all="ignore"):
        deriv = np.polyval(np.polyder(coef), roots)
        powers = roots[:, None] ** np.arange(d, -1, -1)[None, :]  # (roots, d + 1)
        dr_dc = -powers / deriv[:, None]
        grad = dr_dc @ dcoef[:, -coef.size :].T  # (roots, P)
    return roots, np.asarray(grad, dtype=complex)


def _se_abs(v: complex, g: ComplexArray, cov: FloatArray) -> float:
    """Delta-method standard error of |v| given dv/dtheta = g and Cov theta."""
    if v == 0 or not np.all(np.isfinite(g)):
        return float("nan")
    gr = np.real(np.conj(v) / abs(v) * g)
    var = float(gr @ cov @ gr)
    return math.sqrt(var) if math.isfinite(var) and var >= 0 else float("nan")


def over_order_symptom(
    structure: ModelStructure, theta: FloatArray, cov: FloatArray, T: float
) -> str:
    """The over-order symptom of an LTI model at ``theta`` with covariance ``cov`` (of the
    system parameters), or "": a pole and a zero that cancel (|p - z| at most
    :data:`CANCEL_REL` |p|, or within :data:`CANCEL_SE` standard errors of |p - z|), or a pole
    or zero indistinguishable from infinity (its reciprocal within :data:`CANCEL_SE`
    standard errors of 0, or |p| T above :data:`FAST_POLE`). The standard errors come by the
    delta method through the roots' sensitivities dr/dc = -r^(d - i) / c'(r). The one
    predicate of :func:`jitterid.select_order` (its rows) and of every fit (``OVER_ORDER``).
    """
    if not structure.param_names:
        return ""
    theta = np.asarray(theta, dtype=float)
    cov = np.asarray(cov, dtype=float)
    try:
        tf = structure.system(theta)
    except (ValueError, ArithmeticError):
        return ""
    n = tf.den.size
    try:
        dnum, dden = structure.coefficient_derivatives(theta, n)
        poles, gp = _root_gradients(np.asarray(tf.den, float), dden)
        zeros, gz = _root_gradients(np.asarray(tf.num, float), dnum)
    except (ValueError, ArithmeticError):
        return ""
    if not np.all(np.isfinite(cov)):
        cov = np.full_like(cov, np.nan)
    found: list[tuple[float, str]] = []  # (how far inside the threshold: smaller is worse, text)
    for j, p in enumerate(poles):
        for k, z in enumerate(zeros):
            d = complex(p - z)
            se = _se_abs(d, gp[j] - gz[k], cov)
            limit = max(CANCEL_REL * abs(p), CANCEL_SE * se if math.isfinite(se) else 0.0)
            if abs(d) <= limit:
                why = (
                    f"{abs(d) / se:.2g} standard errors"
                    if math.isfinite(se) and se > 0
                    else "no standard error"
                )
                if abs(d) <= CANCEL_REL * abs(p):
                    rel = abs(d) / max(abs(p), 1e-300)
                    how = f"cancel (|p - z| = {abs(d):.3g} rad/s, {rel:.2g} |p|)"
                else:  # far apart, but not told apart by the data
                    how = f"are not told apart (|p - z| = {abs(d):.3g} rad/s is {why})"
                text = f"pole {_c(p)} and zero {_c(z)} rad/s {how}"
                found.append((abs(d) / limit if limit > 0 else 0.0, text))
    for what, roots, grads in (("pole", poles, gp), ("zero", zeros, gz)):
        for r, g in zip(roots, grads, strict=True):
            if r == 0:
                continue
            inv = 1.0 / complex(r)
            se = _se_abs(inv, -g / complex(r) ** 2, cov)
            if abs(r) * T > FAST_POLE:
                text = (
                    f"{what} {_c(r)} rad/s acts within T/{abs(r) * T:.3g} (|{what[0]}| T > "
                    f"{FAST_POLE:g}): the samples cannot tell it from one at infinity"
                )
                found.append((0.0, text))
            elif math.isfinite(se) and abs(inv) <= CANCEL_SE * se:
                text = (
                    f"{what} {_c(r)} rad/s is not distinguished from infinity (1/|{what[0]}| = "
                    f"{abs(inv):.3g} s, {abs(inv) / se:.2g} standard errors from 0)"
                )
                found.append((abs(inv) / (CANCEL_SE * se), text))
    if not found:
        return ""
    found.sort(key=lambda item: item[0])
    more = f" (and {len(found) - 1} more)" if len(found) > 1 else ""
    return found[0][1] + more


def _c(z: complex) -> str:
    z = complex(z)
    if abs(z.imag) <= 1e-12 * max(abs(z.real), 1e-300):
        return f"{z.real:.4g}"
    return f"{z.real:.4g}{z.imag:+.4g}i"
