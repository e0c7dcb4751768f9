"""The jitter quadrature grouped by input segment: fast m_k, Var_k and their derivatives.

For a piecewise-constant input (level u_j on [t_j, t_{j+1})) the output of a system with
distinct poles is, from the modal form of :mod:`jitterid.systems.tf` (notes 5),

    s(t) = c_j + Re sum_p beta_jp e^{p (t - t_j)},      t_j <= t < t_{j+1},
    c_j = u_j G(0),   beta_jp = rho_p (x_p(t_j) + u_j / p),                          (M1)

over the poles with Im p >= 0 (rho doubled for a complex pair, so that the conjugate pole's
term is the conjugate), x_p(t_j) the modal states at the switch times. The quadrature nodes of
sample k (:func:`jitterid.moments.quadrature.jitter_nodes`) are grouped into *pieces*: the nodes of
one sample that fall in one input segment. With e_p = e^{p dt}, dt = t - t_j,

    m_k = sum over pieces of k of [c_j S0 + Re sum_p beta_jp S1_p],
    S0 = sum w,   S1_p = sum w e_p,                                                   (M2)

the sums running over the piece's nodes (weights w). Lemma 1's m_k = E[s(kT + tau)] (notes 1)
thus costs one real exponential and one sine/cosine pair per node and pole pair. The
variance E[(s - m_k)^2] (Lemma 2, notes 2) is the second pass over the same nodes, as in
:func:`jitterid.moments.sample.sample_moments`, so it has no cancellation for small jitter.

Derivatives. With ds/dtheta = dc_j + Re sum_p (dbeta_jp + beta_jp dp dt) e_p, the parameter
derivatives of m_k and Var_k = sum w (s - m_k)^2 are per-piece combinations of

    S1_p, S2_p = sum w dt e_p,  T0 = sum w d,  T1_p = sum w d e_p,  T2_p = sum w d dt e_p,

d = s - m_k: dm_k = sum_pieces [dc_j S0 + Re sum_p (dbeta_jp S1_p + beta_jp dp S2_p)] and
dVar_k = 2 sum_pieces [dc_j T0 + Re sum_p (dbeta_jp T1_p + beta_jp dp T2_p)] - 2 dm_k D_k with
D_k = sum_k w d (zero up to the quadrature's mass error). The node work is therefore
independent of the number of parameters; dc, dbeta come from the modal sensitivities
(:func:`modal_sensitivity`) and the switch-state derivative dx(t_j)/dp
(:meth:`jitterid.systems.tf.TransferFunction.switch_state_sensitivity`). For the scale a of a
jitter law tau = a xi (xi free of a), s' = Re sum_p beta_jp p e_p on each segment gives

    dm_k / da = (1/a) (E[s'(kT + tau) tau] + sum_j D (u_j - u_{j-1}) tau_j p(tau_j)),   (M3)

tau_j = t_j - kT for the switches in the window (s jumps there when the model has a
feedthrough D): the same sums with dbeta = beta p (t_j - kT) / a and dp = p / a, no node moved.

The node geometry (dt, w, pieces) depends on the jitter law and on the panel edges only, not on
the system, so a :class:`SegmentPlan` built once is reused for every parameter value with the
same edges (:func:`jitterid.moments.quadrature.relative_cuts`), from a small process-wide cache
(:func:`cached_plan`). It is kept in memory up to ``_PLAN_BYTES`` (16 bytes per node) and
otherwise rebuilt chunk by chunk at every evaluation, so memory stays bounded whatever N.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..inputs import PiecewiseConstant
from ..jitter.laws import JitterLaw
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .quadrature import DEFAULT_CHUNK, DEFAULT_ORDER, NodeChunk, jitter_nodes, relative_cuts

__all__: list[str] = []

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.intp]

# Node geometry kept in memory at most this size over all plans (16 bytes per node); a
# plan beyond it is rebuilt at every evaluation (about a third of an evaluation's cost)
# rather than hold GBs.
_PLAN_BYTES = 800_000_000
_PLANS_KEPT = 4  # the current jitter law and its shifts for a one-sided difference (JOE)
_plans: OrderedDict[int, SegmentPlan] = OrderedDict()
_plans_lock = threading.Lock()


@dataclass(frozen=True, eq=False)
class PieceChunk:
    """Nodes of samples k0..k1-1 grouped into pieces (one sample, one input segment).

    Attributes
    ----------
    dt : ndarray
        Node instant minus the start of its input segment (0 before the input starts).
    w : ndarray
        Quadrature weights (pdf included).
    starts : ndarray
        First node of each piece.
    lengths : ndarray
        Nodes per piece.
    row : ndarray
        Row of each piece in the coefficient tables: 0 before the input starts, j + 1 on
        segment j.
    first : ndarray
        First piece of each sample.
    node_first : ndarray
        First node of each sample.
    owner : ndarray
        Local sample index (k - k0) of each piece.
    mass : ndarray
        S0 = sum of w over each piece.
    """

    k0: int
    k1: int
    dt: FloatArray
    w: FloatArray
    starts: IntArray
    lengths: IntArray
    row: IntArray
    first: IntArray
    node_first: IntArray
    owner: IntArray
    mass: FloatArray

    @property
    def nbytes(self) -> int:
        arrays = (self.dt, self.w, self.starts, self.lengths, self.row)
        more = (self.first, self.node_first, self.owner, self.mass)
        return sum(a.nbytes for a in arrays + more)


def _pieces(ch: NodeChunk, times: FloatArray) -> PieceChunk:
    # Nodes are interior to their panels and panels are cut at the switch times, so no node
    # sits on a switch: its segment is unambiguous. Within a sample the nodes increase.
    row = np.searchsorted(times, ch.t, side="right")
    dt = np.where(row > 0, ch.t - times[np.maximum(row - 1, 0)], 0.0)
    n = ch.t.size
    change = np.empty(n, bool)
    change[0] = True
    np.not_equal(ch.owner[1:], ch.owner[:-1], out=change[1:])
    new_sample = change.copy()
    change[1:] |= row[1:] != row[:-1]
    starts = np.flatnonzero(change)
    lengths = np.diff(np.r_[starts, n])
    owner = ch.owner[starts]
    first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    if first.size != ch.k1 - ch.k0:
        raise ValueError("every sample needs at least one quadrature node")
    # Gather and repeat indices fit in 32 bits (chunks are small): half the memory of a
    # kept plan's piece arrays.
    return PieceChunk(
        ch.k0,
        ch.k1,
        dt,
        ch.w,
        starts,
        lengths.astype(np.int32),
        row[starts].astype(np.int32),
        first,
        np.flatnonzero(new_sample),
        owner.astype(np.int32),
        np.add.reduceat(ch.w, starts),
    )


@dataclass(eq=False)
class SegmentPlan:
    """The quadrature rule of :func:`jitter_nodes` for one law, grouped into pieces.

    Parameters
    ----------
    law : JitterLaw
        The jitter law.
    T, N : float, int
        Nominal grid kT, k = 0..N-1.
    u : PiecewiseConstant
        The input (its switch times cut the panels and define the segments).
    rate : float
        Signal rate used to size the panels (see :func:`relative_cuts`).
    order, chunk : int
        Gauss-Legendre nodes per panel; samples per chunk.
    """

    law: JitterLaw
    T: float
    N: int
    u: PiecewiseConstant
    rate: float
    order: int = DEFAULT_ORDER
    chunk: int = DEFAULT_CHUNK
    edges: FloatArray = field(init=False)
    _kept: list[PieceChunk] | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.edges = relative_cuts(self.law, self.rate)

    def matches(self, law: JitterLaw, T: float, N: int, u: PiecewiseConstant, rate: float) -> bool:
        """Whether this plan is the rule for these arguments (same panel edges at ``rate``)."""
        return (
            u is self.u
            and (law is self.law or law == self.law)
            and (T, N) == (self.T, self.N)
            and np.array_equal(relative_cuts(law, rate), self.edges)
        )

    def _build(self) -> Iterator[PieceChunk]:
        nodes = jitter_nodes(
            self.law,
            self.T,
            self.N,
            self.u.breaks,
            self.rate,
            order=self.order,
            chunk=self.chunk,
            shared_pdf=True,
        )
        for ch in nodes:
            yield _pieces(ch, self.u.times)

    @property
    def nbytes(self) -> int:
        return sum(pc.nbytes for pc in self._kept) if self._kept is not None else 0

    def chunks(self, keep: bool = True) -> Iterator[PieceChunk]:
        """The chunks; with ``keep``, kept in memory after a first full pass if they fit in
        ``_PLAN_BYTES`` (a one-off evaluation streams them: memory bounded by a chunk)."""
        if self._kept is not None:
            yield from self._kept
            return
        kept: list[PieceChunk] | None = [] if keep else None
        size = 0
        for pc in self._build():
            size += pc.nbytes
            if kept is not None:
                if size <= _PLAN_BYTES:
                    kept.append(pc)
                else:
                    kept = None
            yield pc
        if kept is not None:
            self._kept = kept
            _trim_cache()


def _trim_cache() -> None:
    """Drop the least recently used plans beyond _PLANS_KEPT or the byte budget."""
    with _plans_lock:
        while len(_plans) > _PLANS_KEPT or (
            len(_plans) > 1 and sum(p.nbytes for p in _plans.values()) > _PLAN_BYTES
        ):
            _plans.popitem(last=False)


def cached_plan(law: JitterLaw, T: float, N: int, u: PiecewiseConstant, rate: float) -> SegmentPlan:
    """The plan for these arguments from a small process-wide cache (least recently used first
    out), so that every criterion fitted to one data set, the BCLS pre-fit and the lazy
    covariance share one node geometry, and no result object keeps one alive."""
    with _plans_lock:
        for key, plan in _plans.items():
            if plan.matches(law, T, N, u, rate):
                _plans.move_to_end(key)
                return plan
        plan = SegmentPlan(law, T, N, u, rate)
        _plans[id(plan)] = plan
    _trim_cache()
    return plan


def clear_plans() -> None:
    """Empty the plan cache (benchmarks time a fit from scratch; frees the memory)."""
    with _plans_lock:
        _plans.clear()


# ---------------------------------------------------------------------------- tables (M1)
def kept_modal(tf: TransferFunction) -> tuple[float, ComplexArray, ComplexArray, IntArray]:
    """(D, rho, p, columns): poles with Im p >= 0, rho doubled for a complex pair.

    The same convention as the likelihood's node signal, so that the tables and the modal
    sensitivities of :mod:`jitterid.estimation.likelihood` line up column by column.
    """
    d, r, p = tf._modal
    cols = np.flatnonzero(p.imag >= 0)
    pk = p[cols]
    return d, r[cols] * np.where(pk.imag > 0, 2.0, 1.0), pk, cols


def _padded(c: FloatArray, n: int) -> FloatArray:
    return np.r_[np.zeros(n - c.size), c]


def _owner(cls: type, name: str) -> type:
    return next(k for k in cls.__mro__ if name in k.__dict__)


def _closed_form_applies(structure: ModelStructure) -> bool:
    """False when a subclass redefines the parameter map (``system``) below the class that
    wrote ``coefficient_jacobian``: that closed form belongs to another map."""
    cls = type(structure)
    system, closed = _owner(cls, "system"), _owner(cls, "coefficient_jacobian")
    return system is closed or not issubclass(system, closed)


def _coefficient_jacobian(
    structure: ModelStructure, theta: FloatArray, n: int
) -> tuple[FloatArray, FloatArray]:
    """d(num, den)/dtheta, shape (P, n) each (num padded to the length n of den).

    In closed form where the structure gives it
    (:meth:`~jitterid.systems.structures.ModelStructure.coefficient_jacobian`); central
    differences of the structure's map where it declares none.
    """
    closed = structure.coefficient_jacobian(theta, n) if _closed_form_applies(structure) else None
    if closed is not None:
        return closed
    P = theta.size
    dnum, dden = np.zeros((P, n)), np.zeros((P, n))
    lo, hi = np.array(structure.bounds, dtype=float).reshape(-1, 2).T
    for i in range(P):
        h = 1e-5 * max(abs(float(theta[i])), 1e-2)
        c = float(np.clip(theta[i], lo[i] + h, hi[i] - h))
        up, down = theta.copy(), theta.copy()
        up[i], down[i] = c + h, c - h
        a, b = structure.system(up), structure.system(down)
        dnum[i] = (_padded(a.num, n) - _padded(b.num, n)) / (2 * h)
        dden[i] = (_padded(a.den, n) - _padded(b.den, n)) / (2 * h)
    return dnum, dden


def modal_sensitivity(
    structure: ModelStructure, theta: FloatArray, tf: TransferFunction
) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """d(D, rho, p)/dtheta over the kept poles (the convention of :func:`kept_modal`).

    For a simple pole p of G = num / den: dp = -dden(p) / den'(p); the residue
    r = num(p) / den'(p) gives dr = (num'(p) dp + dnum(p)) / den'(p) - r (den''(p) dp +
    dden'(p)) / den'(p); dD = dnum_0 / den_0 - D dden_0 / den_0 (leading coefficients, after
    padding num to the length of den). The coefficient derivatives dnum, dden are in closed
    form for :class:`PolePairGain` and :class:`RationalModel`, else central differences of the
    structure's map theta -> (num, den) (exact up to rounding for maps polynomial in theta).
    No root finding at shifted points: the central differences of the modal form itself
    (:func:`jitterid.estimation.likelihood._modal_gradient`) cost 2P root findings, most of a Jacobian's
    time at N = 200.
    """
    n = tf.den.size
    num, den = _padded(tf.num, n), tf.den
    dnum, dden = _coefficient_jacobian(structure, theta, n)
    _, _, p, _ = kept_modal(tf)
    # Polynomials and their first two derivatives at the poles as products with Vandermonde
    # rows: one matrix product per quantity for all parameters (np.polyval per parameter
    # costs more than the arithmetic at these sizes).
    k = np.arange(n - 1, -1, -1)
    V0 = p[:, None] ** k
    V1 = k * p[:, None] ** np.maximum(k - 1, 0)
    V2 = k * (k - 1) * p[:, None] ** np.maximum(k - 2, 0)
    den1 = V1 @ den
    r = (V0 @ num) / den1
    dp = -(dden @ V0.T) / den1
    dr = ((V1 @ num) * dp + dnum @ V0.T) / den1 - r * ((V2 @ den) * dp + dden @ V1.T) / den1
    dd = dnum[:, 0] / den[0] - num[0] / den[0] * dden[:, 0] / den[0]
    return dd, dr * np.where(p.imag > 0, 2.0, 1.0), dp


@dataclass(frozen=True, eq=False)
class Tables:
    """What (M1) needs of one system and input; the coefficients c_j, beta_jp are formed per
    chunk for the segments its pieces touch (row 0: before the input starts, all zero), so no
    O(J) table of them is ever held."""

    levels: FloatArray  # u_j, (J,)
    X: ComplexArray  # x_p(t_j) over the kept poles, (J + 1, n_kept)
    g0: float  # G(0) from the same modal terms: c_j + Re sum beta_jp = s(t_j) exactly
    rho: ComplexArray
    p: ComplexArray
    d: float  # the feedthrough D: s jumps by D (u_j - u_{j-1}) at a switch

    def segment(self, row: IntArray) -> tuple[FloatArray, ComplexArray]:
        """(u_j, x(t_j)) of every piece, zero for row 0."""
        j = np.maximum(row - 1, 0)
        inside = row > 0
        return np.where(inside, self.levels[j], 0.0), np.where(inside[:, None], self.X[j], 0.0)

    def coefficients(self, row: IntArray) -> tuple[FloatArray, ComplexArray]:
        """c (pieces,) and beta (pieces, n_kept) of (M1)."""
        lev, X = self.segment(row)
        return lev * self.g0, self.rho * (X + lev[:, None] / self.p)


@dataclass(frozen=True, eq=False)
class DerivativeTables:
    """d/dtheta of the coefficients of (M1) (see :func:`derivative_tables`)."""

    dXdp: ComplexArray  # (J + 1, n_kept)
    dg0: FloatArray  # (P,)
    drho: ComplexArray  # (P, n_kept)
    dp: ComplexArray  # (P, n_kept)

    def coefficients(self, tab: Tables, row: IntArray) -> tuple[FloatArray, ComplexArray]:
        """dc (P, pieces) and dbeta (P, pieces, n_kept)."""
        lev, X = tab.segment(row)
        dX = np.where((row > 0)[:, None], self.dXdp[np.maximum(row - 1, 0)], 0.0)
        z = X + lev[:, None] / tab.p
        v = tab.rho * (dX - lev[:, None] / tab.p**2)
        dbeta = self.drho[:, None, :] * z + self.dp[:, None, :] * v
        return self.dg0[:, None] * lev, dbeta


def tables(tf: TransferFunction, u: PiecewiseConstant) -> Tables:
    """What the coefficients c_j = u_j G(0), beta_jp = rho_p (x_p(t_j) + u_j / p) of (M1) need."""
    d, rho, p, _ = kept_modal(tf)
    g0 = d - float(np.sum(rho / p).real) if p.size else d
    return Tables(u.levels, tf.kept_switch_states(u), g0, rho, p, d)


def derivative_tables(
    tf: TransferFunction,
    u: PiecewiseConstant,
    dmodal: tuple[FloatArray, ComplexArray, ComplexArray],
) -> DerivativeTables:
    """d(c_j, beta_jp)/dtheta from the modal gradient d(D, rho, p)/dtheta and dx_p(t_j)/dp.

    dc_j = u_j dG(0), dG(0) = dD - Re sum (drho / p - rho dp / p^2); dbeta_jp =
    drho (x + u_j / p) + rho (dx/dp - u_j / p^2) dp (x_p(t_j) depends on theta through p only;
    dx/dp from :meth:`TransferFunction.switch_state_sensitivity`).
    """
    _, rho, p, _ = kept_modal(tf)
    dd, drho, dp = dmodal
    dg0 = dd - np.sum(drho / p - rho * dp / p**2, axis=1).real if p.size else dd
    return DerivativeTables(tf.kept_switch_state_sensitivity(u), dg0, drho, dp)


# ---------------------------------------------------------------------------- evaluation
def _phasors(pc: PieceChunk, p: complex) -> tuple[FloatArray, FloatArray | None]:
    """Re and Im of e^{p dt} at the nodes (Im None for a real pole). Real arithmetic: numpy's
    complex exp is several times slower than exp, cos and sin of the real parts."""
    ea = np.exp(p.real * pc.dt)
    if p.imag == 0:
        return ea, None
    ph = p.imag * pc.dt
    return ea * np.cos(ph), ea * np.sin(ph)


def _reduce(values: FloatArray, idx: IntArray) -> FloatArray:
    return np.add.reduceat(values, idx) if values.size else np.zeros(0)


def _recomb(coef: ComplexArray, re: FloatArray, im: FloatArray | None) -> FloatArray:
    """Re(coef * (re + i im)), coef per piece (any leading axes)."""
    out = coef.real * re
    if im is not None:
        out -= coef.imag * im
    return out


def _sums(
    weight: FloatArray, er: FloatArray, ei: FloatArray | None, starts: IntArray
) -> tuple[FloatArray, FloatArray | None]:
    """Per-piece sums of weight * e^{p dt} (real and imaginary parts)."""
    return _reduce(weight * er, starts), (_reduce(weight * ei, starts) if ei is not None else None)


def _scale_terms(
    plan: SegmentPlan, pc: PieceChunk, tab: Tables, c: FloatArray, beta: ComplexArray,
    m: FloatArray, a: float,
) -> tuple[ComplexArray, ComplexArray, FloatArray, FloatArray]:
    """The scale derivative (M3) as a coefficient row, and its jump terms per piece.

    Returns dbeta, gamma (1, pieces, n_kept) and the jump terms of dm and of dVar / 2 per
    piece (zero without feedthrough).
    """
    k = plan.T * (pc.k0 + pc.owner.astype(np.int64))
    inside = pc.row > 0
    # t_j - kT: where the piece's segment starts, relative to the nominal instant
    delta = np.where(inside, plan.u.times[np.maximum(pc.row - 1, 0)] - k, 0.0)
    bp = beta * tab.p / a
    dbeta, gamma = (bp * delta[:, None])[None], bp[None]
    jm, jv = np.zeros(c.size), np.zeros(c.size)
    if tab.d != 0:
        # Every piece but a sample's first starts at a switch inside the window, where s
        # jumps by D (u_j - u_{j-1}) (from 0 at the input's start).
        later = np.ones(c.size, bool)
        later[pc.first] = False
        idx = np.flatnonzero(later)
        lev = np.where(inside, plan.u.levels[np.maximum(pc.row - 1, 0)], 0.0)
        jump = tab.d * (lev[idx] - lev[idx - 1])
        tau = delta[idx]
        weight = tau * plan.law.pdf(tau) / a
        s_plus = c[idx] + np.sum(beta[idx].real, axis=1)  # s at the start of the segment
        e_plus = s_plus - m[pc.owner[idx]]
        jm[idx] = jump * weight
        jv[idx] = 0.5 * (e_plus**2 - (e_plus - jump) ** 2) * weight
    return dbeta, gamma, jm, jv


def modal_moments(
    plan: SegmentPlan,
    tab: Tables,
    dtab: DerivativeTables | None = None,
    *,
    scale: float | None = None,
    keep: bool = True,
) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray | None]:
    """m_k, Var_k (M2) and their derivatives, shape (R, N), chunk by chunk.

    The derivative rows are the system parameters of ``dtab`` and then, with ``scale`` = a,
    the scale of the jitter law (tau = a xi with the law of xi free of a):

        dm_k / da = (1/a) (E[s'(kT + tau) tau] + sum_j Ds_j tau_j p(tau_j)),          (M3)

    s' = Re sum_p beta_p p e^{p dt} on each segment and Ds_j = D (u_j - u_{j-1}) the jumps of
    s at the switches t_j in the window (tau_j = t_j - kT); dVar_k / da alike with
    (s - m_k)^2 for s. (``keep``: see :meth:`SegmentPlan.chunks`.)
    """
    N = plan.N
    mean, var = np.empty(N), np.empty(N)
    rows = (0 if dtab is None else dtab.dg0.size) + (scale is not None)
    dmean = dvar = None
    if rows:
        dmean, dvar = np.empty((rows, N)), np.empty((rows, N))
    for pc in plan.chunks(keep):
        c, beta = tab.coefficients(pc.row)  # (pieces,), (pieces, n_kept)
        phas = [_phasors(pc, complex(p)) for p in tab.p]
        s1 = [_sums(pc.w, er, ei, pc.starts) for er, ei in phas]
        m_piece = c * pc.mass
        for i, (sr, si) in enumerate(s1):
            m_piece += _recomb(beta[:, i], sr, si)
        m = _reduce(m_piece, pc.first)
        sl = slice(pc.k0, pc.k1)
        mean[sl] = m
        # Second pass, d = s - m_k at every node: no cancellation when the jitter is small.
        d = np.repeat(c - m[pc.owner], pc.lengths)
        for i, (er, ei) in enumerate(phas):
            d += np.repeat(beta[:, i].real, pc.lengths) * er
            if ei is not None:
                d -= np.repeat(beta[:, i].imag, pc.lengths) * ei
        wd = pc.w * d
        var[sl] = _reduce(wd * d, pc.node_first)
        if not rows:
            continue
        assert dmean is not None
        assert dvar is not None
        # Coefficient rows of ds = dc + Re sum_p (dbeta + gamma dt) e^{p dt}.
        npc, nk = c.size, beta.shape[1]
        dc, dbetas, gammas = np.zeros((0, npc)), np.zeros((0, npc, nk), complex), np.zeros((0, npc, nk), complex)
        if dtab is not None:
            dc, dbetas = dtab.coefficients(tab, pc.row)  # (P, pieces), (P, pieces, n_kept)
            gammas = beta[None] * dtab.dp[:, None, :]  # beta dp: the dt e^{p dt} term
        jm = jv = None
        if scale is not None:
            db_s, g_s, jm, jv = _scale_terms(plan, pc, tab, c, beta, m, scale)
            dc = np.vstack([dc, np.zeros((1, npc))])
            dbetas, gammas = np.concatenate([dbetas, db_s]), np.concatenate([gammas, g_s])
        t0 = _reduce(wd, pc.starts)
        dm_piece = dc * pc.mass
        dv_piece = dc * t0
        if jm is not None and jv is not None:
            dm_piece[-1] += jm
            dv_piece[-1] += jv
        wdt, wddt = pc.w * pc.dt, wd * pc.dt
        for i, (er, ei) in enumerate(phas):
            dbeta, gamma = dbetas[:, :, i], gammas[:, :, i]
            dm_piece += _recomb(dbeta, *s1[i]) + _recomb(gamma, *_sums(wdt, er, ei, pc.starts))
            dv_piece += _recomb(dbeta, *_sums(wd, er, ei, pc.starts))
            dv_piece += _recomb(gamma, *_sums(wddt, er, ei, pc.starts))
        dm = np.add.reduceat(dm_piece, pc.first, axis=1)
        dmean[:, sl] = dm
        # d sum w (s - m)^2 = 2 sum w (s - m) ds - 2 dm sum w (s - m); the last sum is
        # m (1 - sum w), zero up to the rule's mass error, kept so the derivative is exact.
        dvar[:, sl] = 2 * np.add.reduceat(dv_piece, pc.first, axis=1) - 2 * dm * _reduce(t0, pc.first)
    return mean, var, dmean, dvar
