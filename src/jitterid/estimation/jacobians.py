"""The moments m_k, w_k and their parameter derivatives in one O(N) pass, for every criterion.

Each criterion depends on the parameters only through the per-sample moments (notes 1-2)

    m_k = E[s(kT + tau)]   (Lemma 1, (13)-(14b)),    w_k = Var[s(kT + tau)] + sigma_v^2
    (Lemma 2, (17)-(19)),

so one pass that returns m, w and their derivatives dm, dw (P x N) feeds them all:

- system parameters: the modal sensitivities d(D, rho, p)/dtheta
  (:func:`jitterid.moments.modal.modal_sensitivity`, the quantities of the likelihood's
  ``_modal_gradient`` in closed form) and the exact switch-state derivative dx(t_j)/dp
  (:meth:`TransferFunction.switch_state_sensitivity`) give the derivative tables of (M1) in
  :mod:`jitterid.moments.modal`, which turns them into dm, dVar with node work that does not grow
  with the number of parameters. Any other model (a signal model, an LTI system driven by a
  multisine) goes through the model protocol (:mod:`jitterid.systems.model`): the signal's
  gradient at the jitter nodes (:func:`jitterid.moments.sample.moment_pass`) or, where the
  model declares none, central differences of the moments
  (:func:`jitterid.finite_diff.derivative`).
- the scale a of a scale family (tau = a xi: ``UniformFamily``, ``GaussianFamily``, and ``a``
  of ``SumOfUniformsFamily``): dm/da = E[s'(kT + tau) tau] / a plus the jumps of s,
  (M3) of :mod:`jitterid.moments.modal`, from the same pass (for a smooth signal model from
  its slope, :func:`~jitterid.moments.sample.moment_pass`). Other jitter parameters change
  the shape of the law. Where the family gives dp/dtheta in closed form
  (:meth:`JitterFamily.pdf_gradient`: ``GeneralizedNormalFamily``'s beta, both parameters of
  ``DualDiracFamily``, ``n`` of ``SumOfUniformsFamily`` off its integers),
  dm = sum_j w_j dp/dtheta(tau_j) s(t_j) at the base law's own nodes (its kept plan
  reweighted: no node laid out again), and dVar alike (:func:`_law_derivative`), one extra
  pass each and smooth in theta. ``n`` on an integer at the bottom of the searched piece
  (a kink, or the bound 0) is, to first order from above, a move of the scale
  (:meth:`JitterFamily.scale_equivalent`): dm_n = -a / (2 (n + 1)) dm_a, no pass at all
  (:func:`_from_above_as_scale`). At the top of the searched piece (a kink, or the bound
  n_max) the derivative from below is a combination of laws
  (:meth:`JitterFamily.below_kink`: -(m - m_L) / 2, L the sum of n - 1 of the n + 1
  uniforms), one pass under L (:func:`_from_below_as_laws`). Otherwise (``n`` on an integer
  inside the searched box, or less than 1e-9 below one) central differences of the moments,
  second-order one-sided at a piece's end (:func:`_differenced`), two extra evaluations each.
- the noise std: dw/dsigma_v = 2 sigma_v.

The criteria turn dm, dw into their own derivatives (one module each in
:mod:`jitterid.estimation.estimators`), with dmu = F dm and dR = sum_k dw_k
e^{-i 2 pi (f - psi) kT} from :meth:`Problem.dmu` and :meth:`Problem.dR`.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import finite_diff
from ..data import SampledData
from ..inputs import PiecewiseConstant
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.modal import (
    SegmentPlan,
    Tables,
    cached_plan,
    derivative_tables,
    modal_moments,
    modal_sensitivity,
    tables,
)
from ..moments.quadrature import panel_layout
from ..moments.sample import LazyMoments, SampleMoments, moment_pass, sample_moments
from ..params import ParamLayout
from ..systems.model import Model, Signal
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction

Derivatives = tuple[SampleMoments, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


class Problem(Protocol):
    """What the moments and their derivatives read of their problem
    (:class:`jitterid.estimation.problem.Problem`, which keeps their memos)."""

    data: SampledData
    structure: Model
    jitter: JitterLaw | JitterFamily
    plan_memo: tuple[tuple[bytes, float], SegmentPlan] | None

    @property
    def n_jitter(self) -> int: ...
    @property
    def layout(self) -> ParamLayout: ...
    @property
    def names(self) -> tuple[str, ...]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float], ...]: ...
    @property
    def needs_variances(self) -> bool: ...
    @property
    def estimates_noise(self) -> bool: ...
    def split(self, x: FloatArray) -> tuple[JitterLaw, Signal, float]: ...
    def recall(self, key: bytes) -> Derivatives | None: ...
    def remember(self, key: bytes, out: Derivatives | None) -> None: ...


__all__: list[str] = []

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

_FD_REL = float(np.sqrt(np.finfo(float).eps))  # scipy's 2-point step: sqrt(eps) max(1, |x|)
_CD_REL = 1e-6  # central differences (models that declare no gradient)
_SHAPE_REL = 1e-5  # central differences in a jitter shape parameter (_differenced)


# ---------------------------------------------------------------------------- moments
def _plan(problem: Problem, x: FloatArray, law: JitterLaw, tf: TransferFunction) -> SegmentPlan:
    """The node plan for ``law``: rebuilt only when the law or the panel layout changes.

    The layout depends on the system only through its poles' rates, rounded
    (:func:`jitterid.moments.quadrature.panel_layout`); the problem remembers the last plan with
    its jitter parameters and that layout, so that the search, which changes the system at
    every step, skips even the cache lookup.
    """
    d = problem.data
    assert isinstance(d.u, PiecewiseConstant)
    p = tf.modal.poles
    rate = float(np.max(np.abs(p))) if p.size else 0.0  # Response.rate for this input
    key = (problem.layout.block(x, "jitter").tobytes() + panel_layout(law, p).key, rate)
    memo = problem.plan_memo
    if memo is not None and memo[0][0] == key[0] and memo[1].law == law:
        return memo[1]
    # with the nodes' geometry where the shape's derivative will be summed on them
    plan = cached_plan(law, d.T, d.N, d.u, rate, p, geometry=_closed_form(problem, x))
    problem.plan_memo = (key, plan)
    return plan


def _closed_form(problem: Problem, x: FloatArray) -> bool:
    """Whether the jitter family gives dp/dtheta in closed form at ``x``
    (:meth:`JitterFamily.pdf_gradient`; not for a delayed model, whose law at the nodes is
    the family's shifted)."""
    fam = problem.jitter
    if not isinstance(fam, JitterFamily) or not problem.n_jitter:
        return False
    if getattr(problem.structure, "delay_index", None) is not None:
        return False
    return fam.gives_pdf_gradient(problem.layout.block(x, "jitter").tolist())


def moments(problem: Problem, x: FloatArray) -> SampleMoments:
    """m_k and Var_k at ``x`` (Lemmas 1-2), by the segment path for piecewise-constant inputs."""
    law, sig, _ = problem.split(x)
    d = problem.data
    seg = sig.modal_segments
    if seg is None:
        return sample_moments(sig, law, d.T, d.N)
    assert isinstance(d.u, PiecewiseConstant)
    tf = seg.system
    d.u.check_covers((d.N - 1) * d.T + law.support[1], "the last jittered sampling instant")
    plan, tab = _plan(problem, x, law, tf), tables(tf, d.u)
    need_var = problem.needs_variances
    mean, var, _, _ = modal_moments(plan, tab, variance=need_var)
    if var is None:  # ls, bcls: the criterion reads the means; the variances if asked for
        return LazyMoments(mean, partial(_variances, plan, tab))
    return SampleMoments(mean, var)


def _floored(
    problem: Problem, x: FloatArray, var: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """w = Var + sigma_v^2 with :meth:`Problem.variances`'s floor, and where it is active."""
    noise = problem.split(x)[2]
    w = var + noise**2
    floor = 1e-300 + 1e-12 * float(np.max(w, initial=0.0))
    return np.maximum(w, floor), w < floor


def _variances(plan: SegmentPlan, tab: Tables) -> FloatArray:
    var = modal_moments(plan, tab)[1]
    assert var is not None
    return var


class _PdfDerivative(JitterLaw):
    """The signed measure dp/dtheta_i of a family's law, posing as a law with the base law's
    support, breakpoints and std, so that the moment passes lay out the base law's own nodes
    and sum w_j dp/dtheta_i(tau_j) g(t_j) instead of w_j p(tau_j) g(t_j)."""

    def __init__(self, family: JitterFamily, params: list[float], law: JitterLaw, i: int) -> None:
        self._family, self._params, self._law, self._i = family, params, law, i

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        raise NotImplementedError("a derivative of a density has no characteristic function here")

    def pdf(self, tau: ArrayLike) -> FloatArray:
        g = self._family.pdf_gradient(self._params, tau)
        assert g is not None
        return np.asarray(g[self._i], dtype=float)

    def sample(self, size: int | Sequence[int], rng: np.random.Generator | int) -> FloatArray:
        raise NotImplementedError("a derivative of a density cannot be sampled")

    @property
    def var(self) -> float:
        return self._law.var

    @property
    def mass(self) -> float:
        return 0.0  # d(total mass)/dtheta

    @property
    def support(self) -> tuple[float, float]:
        return self._law.support

    def breakpoints(self) -> FloatArray:
        return self._law.breakpoints()

    @property
    def params(self) -> dict[str, float]:
        return self._law.params


def _law_derivative(
    problem: Problem,
    x: FloatArray,
    law: JitterLaw,
    sig: Signal,
    i: int,
    mean: FloatArray,
    need_var: bool,
) -> tuple[FloatArray, FloatArray | None]:
    """dm_k and dVar_k in jitter parameter i from the family's dp/dtheta_i at the base law's
    nodes (:meth:`JitterFamily.pdf_gradient`): dm = sum w' s, and, with the pass's
    Var' = sum w' (s - m')^2, dVar = sum w' (s - m)^2 = Var' + 2 m' (m' - m) (the rule's
    sum w' = d(mass)/dtheta_i is zero up to the quadrature error, ~1e-15). Along the modal
    path the pass reuses the base law's kept plan, reweighted (:meth:`SegmentPlan.reweighted`:
    the nodes are not laid out again); a plan is built for dp/dtheta_i where it is not kept."""
    fam = problem.jitter
    assert isinstance(fam, JitterFamily)
    dlaw = _PdfDerivative(fam, problem.layout.block(x, "jitter").tolist(), law, i)
    seg = sig.modal_segments
    kept = _plan(problem, x, law, seg.system).reweighted(dlaw) if seg is not None else None
    dmean, dvar = _pass_under(problem, sig, dlaw, need_var, kept)
    if dvar is None:
        return dmean, None
    return dmean, dvar + 2 * dmean * (dmean - mean)


def _pass_under(
    problem: Problem,
    sig: Signal,
    measure: JitterLaw,
    need_var: bool,
    plan: SegmentPlan | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """The sums sum_j w_j s(t_j) and sum_j w_j (s(t_j) - m_j)^2 of one pass under another
    measure than the problem's law (a signed dp/dtheta, or a law of its own) at the
    signal ``sig``: along the modal path over ``plan`` (a kept plan reweighted) or nodes laid
    out for ``measure``, streamed (``keep=False``); else through the model protocol."""
    d = problem.data
    seg = sig.modal_segments
    if seg is None:
        mp = moment_pass(sig, measure, d.T, d.N, variance=need_var)
        return mp.mean, mp.var
    assert isinstance(d.u, PiecewiseConstant)
    if plan is None:
        p = seg.system.modal.poles
        rate = float(np.max(np.abs(p))) if p.size else 0.0
        plan = SegmentPlan(measure, d.T, d.N, d.u, rate, poles=p)
    mean, var, _, _ = modal_moments(plan, tables(seg.system, d.u), keep=False, variance=need_var)
    return mean, var


def _from_above_as_scale(problem: Problem, x: FloatArray, i: int) -> float | None:
    """The family's factor r (:meth:`jitterid.JitterFamily.scale_equivalent`) where its
    parameter ``i`` sits on the lower end of the searched box (a kink that starts the piece,
    or the bound), so that the derivative asked for is the one from above, which
    :func:`_differenced` would take one-sided: then dm_i = r dm_scale exactly, without the
    two moment passes over new nodes. None elsewhere (an integer inside the box: a central
    difference across the kink, as before)."""
    fam = problem.jitter
    if not isinstance(fam, JitterFamily) or x[i] != problem.bounds[i][0]:
        return None
    return fam.scale_equivalent(problem.layout.block(x, "jitter").tolist(), i)


def _from_below_as_laws(
    problem: Problem,
    x: FloatArray,
    sig: Signal,
    i: int,
    mom: SampleMoments,
    need_var: bool,
) -> tuple[FloatArray, FloatArray | None] | None:
    """dm_k and dVar_k in jitter parameter ``i`` from below where it sits on the upper end of
    the searched box (a kink that ends the piece, or the bound) and the family gives its
    derivative there as a combination of laws (:meth:`JitterFamily.below_kink`,
    ``dp = c0 p + sum c_j p_j``, sum c = 0): dm = c0 m + sum c_j m_j and dVar = sum c_j
    E_j[(s - m)^2] = c0 Var + sum c_j (Var_j + (m_j - m)^2), one moment pass a law
    ``L_j`` on its own nodes, exact, where :func:`_differenced` would take two one-sided
    with new nodes (and converge like the square root of its step: the law's widths move
    like the square root of the distance below an integer). None elsewhere, and for a
    delayed model (its law at the nodes is the family's shifted)."""
    fam = problem.jitter
    if (
        not isinstance(fam, JitterFamily)
        or x[i] != problem.bounds[i][1]
        or getattr(problem.structure, "delay_index", None) is not None
    ):
        return None
    combo = fam.below_kink(problem.layout.block(x, "jitter").tolist(), i)
    if combo is None:
        return None
    c0, terms = combo
    dm = c0 * mom.mean
    dv = c0 * mom.var if need_var else None
    for c, other in terms:
        mj, vj = _pass_under(problem, sig, other, need_var)
        dm = dm + c * mj
        if dv is not None:
            assert vj is not None
            dv = dv + c * (vj + (mj - mom.mean) ** 2)
    return dm, dv


def _differenced(
    problem: Problem, x: FloatArray, i: int, *, variance: bool, shape: bool = False
) -> tuple[FloatArray, FloatArray | None]:
    """(dm, dVar) in parameter ``i`` by central differences of the moments
    (:mod:`jitterid.finite_diff`): the declared route where no closed form is given. A
    jitter ``shape`` parameter (n of the family (26): of order one, its moments quadratures
    over a law whose knots move with it) takes the step ``_SHAPE_REL * max(|x_i|, 1)``: at
    1e-6 |x_i| (n near 0: a step of 1e-8) the quadrature's rounding made the derivative's
    sign random near a stationary point."""
    n = problem.data.N

    def stacked(v: FloatArray) -> FloatArray:
        mv = moments(problem, v)
        return np.concatenate([mv.mean, mv.var]) if variance else mv.mean

    rel, floor = (_SHAPE_REL, 1.0) if shape else (_CD_REL, 1e-2)
    g = finite_diff.derivative(stacked, x, i, problem.bounds[i], rel=rel, floor=floor)
    return g[:n], (g[n:] if variance else None)


def moment_derivatives(
    problem: Problem, x: FloatArray
) -> tuple[SampleMoments, FloatArray, FloatArray, FloatArray]:
    """(moments, w, dm, dw) at ``x``; dm, dw have shape (P, N) in ``problem.names`` order.

    w are the floored variances of :meth:`Problem.variances`; dw is zero where the floor acts.
    Cached for the last ``x`` (least_squares asks for the Jacobian where it just evaluated).
    The ``ls`` and ``bcls`` criteria use neither: for them the variances are computed only
    if asked for (``moments.var``), and w, dw are empty, shape (0,) and (P, 0).
    """
    x = np.asarray(x, float)
    key = x.tobytes()
    known = problem.recall(key)
    if known is not None:
        return known
    problem.remember(key, None)  # free the last point's (P, N) arrays before making new ones
    law, sig, noise = problem.split(x)
    d = problem.data
    lay = problem.layout
    nj, ns = len(lay.jitter), len(lay.system)
    sys_ = lay.slice("system")
    P = x.size
    dm, dv = np.zeros((P, d.N)), np.zeros((P, d.N))
    theta = lay.block(x, "system")
    # A delay moves the jitter law (DelayedSignal.jitter_equivalent): the law at the nodes is
    # then a shifted one, whose scale and closed-form dp/dtheta are not the family's, so its
    # parameters are differenced; the delay itself moves no coefficient (differenced below).
    delay = getattr(problem.structure, "delay_index", None)
    scale = problem.jitter.scale_index if nj and delay is None else None  # type: ignore[union-attr]
    need_var = problem.needs_variances
    a = float(x[scale]) if scale is not None else None
    analytic_scale = False
    mom: SampleMoments
    seg = sig.modal_segments
    if seg is not None and not (ns > 0 or scale is not None):
        mom = moments(problem, x)  # nothing to differentiate along the modal path
    elif seg is not None:
        assert isinstance(d.u, PiecewiseConstant)
        assert isinstance(problem.structure, ModelStructure)  # a Response is an LTI structure's
        tf = seg.system
        d.u.check_covers((d.N - 1) * d.T + law.support[1], "the last jittered sampling instant")
        dtab = (
            derivative_tables(tf, d.u, modal_sensitivity(problem.structure, theta, tf))
            if ns
            else None
        )
        plan, tab = _plan(problem, x, law, tf), tables(tf, d.u)
        mean, var, dms, dvs = modal_moments(plan, tab, dtab, scale=a, variance=need_var)
        assert dms is not None
        if var is None:
            mom = LazyMoments(mean, partial(_variances, plan, tab))
        else:
            mom = SampleMoments(mean, var)
        dm[sys_] = dms[:ns]
        if dvs is not None:
            dv[sys_] = dvs[:ns]
        analytic_scale = scale is not None
        if analytic_scale:
            dm[scale] = dms[ns]
            if dvs is not None:
                dv[scale] = dvs[ns]
    else:  # the model protocol: the signal's gradient and slope at the jitter nodes
        sig.check_covers((d.N - 1) * d.T + law.support[1], "the last jittered sampling instant")
        mp = moment_pass(sig, law, d.T, d.N, variance=True, gradient=ns > 0, scale=a)
        assert mp.var is not None
        mom = SampleMoments(mp.mean, mp.var)
        if mp.scale_mean is not None:
            assert scale is not None
            assert mp.scale_var is not None
            dm[scale], dv[scale] = mp.scale_mean, mp.scale_var
            analytic_scale = True
        if mp.dmean is not None:
            assert mp.dvar is not None
            dm[sys_], dv[sys_] = mp.dmean, mp.dvar
        elif ns:  # declared missing: central differences of the moments (finite_diff)
            for i in range(nj, nj + ns):
                dm[i], dv[i] = _differenced(problem, x, i, variance=True)
    if delay is not None and seg is not None:  # the modal rows hold zeros for the delay
        dmi, dvi = _differenced(problem, x, nj + delay, variance=need_var)
        dm[nj + delay] = dmi
        if dvi is not None:
            dv[nj + delay] = dvi
    # (a shape pinned by the search's box, held while the system is searched (the first
    # stage of a kinked family, oe.OutputErrorRoute.search), is not differentiated: its row
    # stays zero, and the caches are dropped when the box is lifted (Problem.restrict))
    box = problem.bounds
    shape = [i for i in range(nj) if not (analytic_scale and i == scale) and box[i][0] < box[i][1]]
    closed = bool(shape) and _closed_form(problem, x)
    for i in shape if closed else ():  # the family's closed-form dp/dtheta_i
        dm[i], dvi = _law_derivative(problem, x, law, sig, i, mom.mean, need_var)
        if dvi is not None:
            dv[i] = dvi
    for i in shape if not closed else ():
        r = _from_above_as_scale(problem, x, i) if analytic_scale else None
        if r is not None:  # on a kink at its piece's bottom: r x the scale's row (exact)
            assert scale is not None
            dm[i] = r * dm[scale]
            if need_var:
                dv[i] = r * dv[scale]
            continue
        below = _from_below_as_laws(problem, x, sig, i, mom, need_var)
        if below is not None:  # on a kink at its piece's top: a combination of laws (exact)
            dm[i] = below[0]
            if below[1] is not None:
                dv[i] = below[1]
            continue
        # other jitter parameters move the nodes: differences of the moments, central (or
        # second-order one-sided at a bound, e.g. a piece's end: finite_diff), O(h^2). A
        # one-sided O(h) difference at sqrt(eps) was dominated by the quadrature's rounding,
        # and the search, stationary in the others, could not tell which way the shape went.
        dm[i], dvi = _differenced(problem, x, i, variance=need_var, shape=True)
        if dvi is not None:
            dv[i] = dvi
    if not need_var:
        out = (mom, np.empty(0), dm, np.empty((P, 0)))
        problem.remember(key, out)
        return out
    w, floored = _floored(problem, x, mom.var)
    dw = dv
    if problem.estimates_noise:
        dw[-1] = 2 * noise
    dw[:, floored] = 0.0
    out = (mom, w, dm, dw)
    problem.remember(key, out)
    return out
