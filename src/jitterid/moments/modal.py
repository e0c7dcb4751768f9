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

The node geometry (pieces, standard panels, the other panels' nodes) depends on the jitter
law and on the panel layout only, not on the system, so a :class:`SegmentPlan` built once is
reused for every parameter value with the same layout
(:func:`jitterid.moments.quadrature.panel_layout`), from a small process-wide cache
(:func:`cached_plan`); the plan of a band law (a Gaussian: its
:attr:`~jitterid.jitter.laws.JitterLaw.band_rule`) serves every scale of its band (only the
weights change), and a kept plan built with ``geometry`` serves the derivative dp/dtheta
of its law on the same nodes (:meth:`SegmentPlan.reweighted`). A standard panel (one no
switch cuts) has the same offsets and weights in every sample, so its node sums are a phasor
times a per-law table (:class:`StdTable`). A plan is
kept in memory up to ``_PLAN_BYTES`` (~1 kB per sample for a Gaussian window over a few
switches) and otherwise rebuilt chunk by chunk at every evaluation, so memory stays bounded
whatever N. Runs of equal input levels are one segment (:func:`merged_input`).
"""

from __future__ import annotations

import copy
import threading
import weakref
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._state import CachesAreNotState
from ..inputs import PiecewiseConstant
from ..jitter.laws import JitterLaw
from ..systems.structures import ModelStructure, padded
from ..systems.tf import TransferFunction
from .quadrature import (
    DEFAULT_CHUNK,
    DEFAULT_ORDER,
    PANEL_LIMIT,
    Layout,
    PanelChunk,
    _gauss_legendre,
    band_rule,
    jitter_panels,
    panel_layout,
    panels_per_sample,
    relative_cuts,
    rule_frame,
)

__all__: list[str] = []

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.intp]
IdxArray = NDArray[np.signedinteger[Any]]  # int32 or intp index arrays

# Node geometry kept in memory at most this size over all plans; a plan beyond it is
# rebuilt at every evaluation (about a third of an evaluation's cost) rather than hold GBs.
_PLAN_BYTES = 800_000_000
_PLANS_KEPT = 4  # the current jitter law and its shifts for a one-sided difference (JOE)
_plans: OrderedDict[int, SegmentPlan] = OrderedDict()
_plans_lock = threading.Lock()


@dataclass(frozen=True, eq=False)
class StdTable:
    """The standard panels' nodes relative to their midpoint, for one law: offsets
    hx[m, i] = h_m x_i and weights w[m, i] = h_m wx_i p(mid_m + h_m x_i) (the pdf at a
    sample's own nodes differs from it by their rounding in kT only, ~1e-16 relative)."""

    hx: FloatArray  # (R, order)
    w: FloatArray  # (R, order)
    mid: FloatArray  # (R,) the panels' midpoints relative to kT

    @classmethod
    def make(cls, law: JitterLaw, rel: FloatArray, order: int) -> StdTable:
        x, wx = _gauss_legendre(order)
        lo, hi = rule_frame(law)[2]
        half = 0.5 * np.diff(rel)
        mid = 0.5 * (rel[:-1] + rel[1:])
        hx = half[:, None] * x[None, :]
        w = half[:, None] * wx[None, :] * law.pdf(np.minimum(np.maximum(mid[:, None] + hx, lo), hi))
        return cls(hx, w, mid)


@dataclass(frozen=True, eq=False)
class PieceChunk(CachesAreNotState):
    """The rule for samples k0..k1-1 grouped into pieces (one sample, one input segment).

    A piece's nodes are those of its standard panels (which no cut shortened: the same
    offsets and weights for every sample, :class:`StdTable`, so that a sum over them is one
    phasor per panel times a table) and the nodes of its other panels, kept one by one.

    Attributes
    ----------
    row : ndarray
        Row of each piece in the coefficient tables: 0 before the input starts, j + 1 on
        segment j (the first of a run of equal levels).
    owner : ndarray
        Local sample index (k - k0) of each piece.
    first : ndarray
        First piece of each sample.
    mass : ndarray
        S0 = sum of the weights over each piece.
    pdt : ndarray
        Per piece, kT minus the start of its segment (0 before the input starts).
    sp_piece, sp_dt, sp_m : ndarray
        Per standard panel: its piece, its midpoint minus the start of its segment (its half
        width before the input starts) and its number m in the table.
    cn_piece, cn_dt, cn_w : ndarray
        Per node of the other panels: its piece, its instant minus the start of its segment
        (0 before the input starts) and its weight (pdf included).
    cn_gw, cn_tau : ndarray or None
        Per node of the other panels, the Gauss-Legendre weight times the half panel and the
        offset t - kT, so that the weights of another law with the same nodes are
        gw * pdf(tau) (kept for the plans of band laws only,
        :func:`~jitterid.moments.quadrature.scale_band`).
    std : StdTable
        The standard panels' table for the chunk's law.
    """

    k0: int
    k1: int
    row: IdxArray
    owner: IdxArray
    first: IdxArray
    mass: FloatArray
    pdt: FloatArray
    sp_piece: IdxArray
    sp_dt: FloatArray
    sp_m: IdxArray
    cn_piece: IdxArray
    cn_dt: FloatArray
    cn_w: FloatArray
    std: StdTable
    cn_gw: FloatArray | None = None
    cn_tau: FloatArray | None = None

    @cached_property
    def nbytes(self) -> int:
        # cached: the plan cache sums it over every kept chunk after each evaluation
        arrays = (
            self.row,
            self.owner,
            self.first,
            self.mass,
            self.pdt,
            self.sp_piece,
            self.sp_dt,
            self.sp_m,
        )
        more = (self.cn_piece, self.cn_dt, self.cn_w)
        extra = tuple(a for a in (self.cn_gw, self.cn_tau) if a is not None)
        return sum(a.nbytes for a in arrays + more + extra)

    @property
    def nodes(self) -> int:
        return self.sp_m.size * self.std.hx.shape[1] + self.cn_w.size

    def reweighted(self, law: JitterLaw, std: StdTable) -> PieceChunk:
        """The same nodes with the weights of ``law`` (which must share this rule), its pdf
        taken at the offsets clipped as :func:`_pieces` clips them."""
        assert self.cn_gw is not None
        assert self.cn_tau is not None
        lo, hi = rule_frame(law)[2]
        w = self.cn_gw * law.pdf(np.minimum(np.maximum(self.cn_tau, lo), hi))
        mass = _piece_mass(self.sp_piece, self.sp_m, self.cn_piece, w, std, self.row.size)
        return replace(self, cn_w=w, mass=mass, std=std)


def _piece_mass(
    sp_piece: IdxArray, sp_m: IdxArray, cn_piece: IdxArray, cn_w: FloatArray, std: StdTable, n: int
) -> FloatArray:
    out = np.zeros(n)
    out += np.bincount(sp_piece, std.w.sum(axis=1)[sp_m], minlength=n)
    out += np.bincount(cn_piece, cn_w, minlength=n)
    return np.asarray(out, dtype=np.float64)


def switch_segments(u: PiecewiseConstant) -> IntArray:
    """Indices j of the segments where the input level changes (and the first)."""
    lev = u.levels
    return np.flatnonzero(np.r_[True, lev[1:] != lev[:-1]])


_merged: weakref.WeakKeyDictionary[PiecewiseConstant, PiecewiseConstant] = (
    weakref.WeakKeyDictionary()
)


def merged_input(u: PiecewiseConstant) -> PiecewiseConstant:
    """``u`` with every run of equal levels as one segment: the same function of time, whose
    switch times are the only times where the output is not smooth. (M1) holds on a run from
    the state at its start, so the plans and tables of this module use this input: a +-1 ZOH
    sequence has half as many segments as samples. Cached per input object (the system's
    switch-state memo is keyed by it)."""
    got = _merged.get(u)
    if got is None:
        segs = switch_segments(u)
        got = (
            u
            if segs.size == u.levels.size
            else PiecewiseConstant(np.r_[u.times[segs], u.times[-1]], u.levels[segs])
        )
        _merged[u] = got
    return got


def _pieces(
    pch: PanelChunk,
    law: JitterLaw,
    T: float,
    order: int,
    std: StdTable,
    times: FloatArray,
    geometry: bool,
) -> PieceChunk:
    # Panels are cut at the segments' start times, so each lies in one segment (found from
    # its midpoint); within a sample the panels increase.
    mid = 0.5 * (pch.a + pch.b)
    run = np.searchsorted(times, mid, side="right")
    inside = run > 0
    tseg = times[np.maximum(run - 1, 0)]
    n = mid.size
    change = np.empty(n, bool)
    change[0] = True
    change[1:] = (pch.owner[1:] != pch.owner[:-1]) | (run[1:] != run[:-1])
    piece = np.cumsum(change) - 1
    starts = np.flatnonzero(change)
    owner = pch.owner[starts]
    first = np.flatnonzero(np.concatenate(([True], owner[1:] != owner[:-1])))
    if first.size != pch.k1 - pch.k0:
        raise ValueError("every sample needs at least one quadrature node")
    row = run[starts]
    kt = (pch.k0 + owner) * T
    pdt = np.where(row > 0, kt - tseg[starts], 0.0)
    is_std = pch.m >= 0
    sp_piece = piece[is_std]
    # before the input starts s = 0 and dt is arbitrary: there a panel's dt_mid is its half
    # width, so that its nodes' dt >= 0 (no overflow of e^{p dt} for a fast pole)
    sp_dt = np.where(inside, mid - tseg, 0.5 * (pch.b - pch.a))[is_std]
    sp_m = pch.m[is_std]
    cut = ~is_std
    x, wx = _gauss_legendre(order)
    a, b = pch.a[cut], pch.b[cut]
    half = 0.5 * (b - a)
    t = (0.5 * (a + b))[:, None] + half[:, None] * x[None, :]
    cn_dt = np.where(inside[cut][:, None], t - tseg[cut][:, None], 0.0).ravel()
    tau = (t - ((pch.k0 + pch.owner[cut]) * T)[:, None]).ravel()
    gw = (half[:, None] * wx[None, :]).ravel()
    lo, hi = rule_frame(law)[2]
    cn_w = gw * law.pdf(np.minimum(np.maximum(tau, lo), hi))
    cn_piece = np.repeat(piece[cut], order)
    npieces = starts.size
    # Gather indices fit in 32 bits (chunks are small): half the memory of a kept plan.
    return PieceChunk(
        pch.k0,
        pch.k1,
        row.astype(np.int32),
        owner.astype(np.int32),
        first,
        _piece_mass(sp_piece, sp_m, cn_piece, cn_w, std, npieces),
        pdt,
        sp_piece.astype(np.int32),
        sp_dt,
        sp_m.astype(np.int32),
        cn_piece.astype(np.int32),
        cn_dt,
        cn_w,
        std,
        gw if geometry else None,
        tau if geometry else None,
    )


@dataclass(eq=False)
class _Store:
    """The kept chunks of a plan, shared by its views (:meth:`SegmentPlan.view`)."""

    kept: list[PieceChunk] | None = None
    law: JitterLaw | None = None  # the law whose weights the kept chunks hold


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
        The input (its switch times cut the panels and define the segments; runs of equal
        levels are one segment, :func:`switch_segments`).
    rate : float
        Signal rate used to size the panels (see :func:`relative_cuts`) when ``poles`` is
        not given.
    order, chunk : int
        Gauss-Legendre nodes per panel; samples per chunk (at most).
    poles : array_like, optional
        The signal's poles: the layout is then :func:`panel_layout`'s (fast damped modes get
        graded cuts after every switch instead of short panels everywhere).
    geometry : bool, optional
        Keep every cut panel node's rule weight and offset in the chunks (16 bytes a node),
        so that the kept plan serves another measure on the same nodes: a derivative
        dp/dtheta of its law (:meth:`reweighted`). Always kept for a band law's plan.

    Raises
    ------
    ValueError
        If the rule would exceed :data:`jitterid.moments.quadrature.PANEL_LIMIT` panels
        (checked before anything is allocated).
    """

    law: JitterLaw
    T: float
    N: int
    u: PiecewiseConstant
    rate: float
    order: int = DEFAULT_ORDER
    chunk: int = DEFAULT_CHUNK
    poles: ArrayLike | None = None
    geometry: bool = False
    edges: FloatArray = field(init=False)
    grade: FloatArray = field(init=False)
    _store: _Store = field(init=False, default_factory=_Store)

    def __post_init__(self) -> None:
        if self.poles is None:
            lay = Layout(float(self.rate), np.zeros(0))
        else:
            lay = panel_layout(self.law, self.poles, self.order)
        self.edges = relative_cuts(self.law, lay.rate)
        self.grade = lay.grade
        self._mu = merged_input(self.u)
        self._times = self._mu.times[:-1]
        if self.edges.size > 1:
            per = panels_per_sample(self.edges, self._times, self.grade, self.T)
            if per * self.N > PANEL_LIMIT:
                fast = (
                    ""
                    if self.poles is None
                    else f" (poles {np.round(np.asarray(self.poles), 6).tolist()})"
                )
                raise ValueError(
                    f"the jitter quadrature would need ~{per * self.N:.3g} panels ({per:.3g} per "
                    f"sample, limit {PANEL_LIMIT:.3g}): the signal varies at rate {lay.rate:.3g} "
                    "1/s"
                    f"{fast}, far faster than the jitter's scale {self.law.std:.3g} s, with too "
                    "little damping to be resolved only after each switch. Bound the model's "
                    "poles (a lower model order or tighter structure bounds), or start the "
                    "search from a slower model"
                )

    @property
    def key(self) -> bytes:
        return np.concatenate((self.edges, [np.nan], self.grade)).tobytes()

    def _same_rule(self, law: JitterLaw) -> bool:
        """Whether ``law`` has this plan's nodes: the same law, or another band law (a
        Gaussian) whose band gives the same edges (compared by the caller): the nodes depend on
        the law only through the edges, and a band law's plan keeps them for new weights."""
        if law is self.law or law == self.law:
            return True
        return band_rule(law) is not None and band_rule(self.law) is not None

    @property
    def _keeps_geometry(self) -> bool:
        return self.geometry or band_rule(self.law) is not None

    def matches(
        self,
        law: JitterLaw,
        T: float,
        N: int,
        u: PiecewiseConstant,
        rate: float,
        poles: ArrayLike | None = None,
        geometry: bool = False,
    ) -> bool:
        """Whether this plan's nodes are the rule for these arguments (same panel edges and
        graded cuts; the law itself, or a band law of the same band), with the nodes'
        geometry kept if ``geometry`` asks for it."""
        if not (u is self.u and (T, N) == (self.T, self.N) and self._same_rule(law)):
            return False
        if geometry and not self._keeps_geometry:
            return False
        if (poles is None) != (self.poles is None):
            return False
        lay = (
            Layout(float(rate), np.zeros(0))
            if poles is None
            else panel_layout(law, poles, self.order)
        )
        return np.array_equal(relative_cuts(law, lay.rate), self.edges) and np.array_equal(
            lay.grade, self.grade
        )

    def view(self, law: JitterLaw) -> SegmentPlan:
        """This plan for another law with the same nodes (a band law of the same band): the
        node geometry is shared, the weights are gw * pdf(tau) of ``law``."""
        if law is self.law:
            return self
        out = copy.copy(self)
        out.law = law
        return out

    def reweighted(self, law: JitterLaw) -> SegmentPlan | None:
        """This plan's kept nodes with the weights of ``law``, a measure with this plan's
        support and breakpoints: the derivative dp/dtheta of its law, posing as a law
        (``jitterid.estimation.jacobians._PdfDerivative``), whose moment pass then needs
        no new nodes; the weights are those a plan built for ``law`` would give (gw * the
        measure at the clipped offsets). None where the plan does not hold its nodes (not
        yet passed over, too large to keep, or built without ``geometry``): the caller
        builds a plan for ``law``, and passes over it with ``keep=False``.

        Parameters
        ----------
        law : JitterLaw
            The measure (its ``pdf``) on this plan's nodes.
        """
        kept = self._store.kept
        if kept is None or not all(pc.cn_gw is not None for pc in kept):
            return None
        return self.view(law)

    def _build(self) -> Iterator[PieceChunk]:
        if self.edges.size == 0:  # a point mass: one node per sample, at kT + lo
            yield from self._point_mass()
            return
        panels = jitter_panels(
            self.law, self.T, self.N, self._times, self.edges, grade=self.grade, chunk=self.chunk
        )
        geometry = self._keeps_geometry  # kept, to reweight for the band's laws (or dp/dtheta)
        std = StdTable.make(self.law, self.edges, self.order)
        for pch in panels:
            yield _pieces(pch, self.law, self.T, self.order, std, self._times, geometry)

    def _point_mass(self) -> Iterator[PieceChunk]:
        lo = float(self.law.support[0])
        std = StdTable(np.zeros((0, self.order)), np.zeros((0, self.order)), np.zeros(0))
        empty_i, empty_f = np.zeros(0, np.int32), np.zeros(0)
        for k0 in range(0, self.N, self.chunk):
            k1 = min(self.N, k0 + self.chunk)
            t = np.asarray(np.arange(k0, k1) * self.T + lo, dtype=np.float64)
            run = np.searchsorted(self._times, t, side="right")
            inside = run > 0
            dt = np.where(inside, t - self._times[np.maximum(run - 1, 0)], 0.0)
            row = run.astype(np.int32)
            idx = np.arange(k1 - k0)
            yield PieceChunk(
                k0,
                k1,
                row,
                idx.astype(np.int32),
                idx,
                np.ones(k1 - k0),
                np.zeros(k1 - k0),
                empty_i,
                empty_f,
                empty_i,
                idx.astype(np.int32),
                dt,
                np.ones(k1 - k0),
                std,
            )

    @property
    def nbytes(self) -> int:
        kept = self._store.kept
        return sum(pc.nbytes for pc in kept) if kept is not None else 0

    def chunks(self, keep: bool = True) -> Iterator[PieceChunk]:
        """The chunks; with ``keep``, kept in memory after a first full pass if they fit in
        ``_PLAN_BYTES`` (a one-off evaluation streams them: memory bounded by a chunk)."""
        store = self._store
        if store.kept is not None:
            if store.law is self.law or store.law == self.law:
                yield from store.kept
                return
            std = StdTable.make(self.law, self.edges, self.order)
            for pc in store.kept:
                yield pc.reweighted(self.law, std)
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
            store.kept, store.law = kept, self.law
            _trim_cache()


def _trim_cache() -> None:
    """Drop the least recently used plans beyond _PLANS_KEPT or the byte budget."""
    with _plans_lock:
        while len(_plans) > _PLANS_KEPT or (
            len(_plans) > 1 and sum(p.nbytes for p in _plans.values()) > _PLAN_BYTES
        ):
            _plans.popitem(last=False)


def cached_plan(
    law: JitterLaw,
    T: float,
    N: int,
    u: PiecewiseConstant,
    rate: float,
    poles: ArrayLike | None = None,
    geometry: bool = False,
) -> SegmentPlan:
    """The plan for these arguments from a small process-wide cache (least recently used first
    out), so that every criterion fitted to one data set, the BCLS pre-fit and the lazy
    covariance share one node geometry, and no result object keeps one alive. A band law
    gets a view of the plan of its band (:meth:`SegmentPlan.view`): a search over sigma
    rebuilds no nodes until sigma leaves the band. ``geometry``: see :class:`SegmentPlan`
    (a plan without it does not serve a call that asks for it)."""
    with _plans_lock:
        for key, plan in _plans.items():
            if plan.matches(law, T, N, u, rate, poles, geometry):
                _plans.move_to_end(key)
                return plan.view(law)
    plan = SegmentPlan(law, T, N, u, rate, poles=poles, geometry=geometry)
    with _plans_lock:
        if band_rule(law) is not None:
            # A search over sigma leaves a band for good (or returns once): keep one band
            # law's plan per data set, not one per band visited (~90 MB each at 1e5).
            banded = [k for k, q in _plans.items() if band_rule(q.law) is not None and q.u is u]
            for key in banded:
                del _plans[key]
        _plans[id(plan)] = plan
    _trim_cache()
    return plan


def clear_plans() -> None:
    """Empty the plan cache (benchmarks time a fit from scratch; frees the memory)."""
    with _plans_lock:
        _plans.clear()


# ---------------------------------------------------------------------------- tables (M1)
def modal_sensitivity(
    structure: ModelStructure, theta: FloatArray, tf: TransferFunction
) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """d(D, rho, p)/dtheta over the kept poles (the convention of
    :meth:`jitterid.systems.tf.ModalForm.kept`).

    For a simple pole p of G = num / den: dp = -dden(p) / den'(p); the residue
    r = num(p) / den'(p) gives dr = (num'(p) dp + dnum(p)) / den'(p) - r (den''(p) dp +
    dden'(p)) / den'(p); dD = dnum_0 / den_0 - D dden_0 / den_0 (leading coefficients, after
    padding num to the length of den). The coefficient derivatives dnum, dden are in closed
    form for :class:`PolePairGain` and :class:`RationalModel`, else central differences of the
    structure's map theta -> (num, den) (exact up to rounding for maps polynomial in theta).
    No root finding at shifted points: the central differences of the modal form itself
    (:func:`jitterid.estimation.likelihood._modal_gradient`) cost 2P root findings, most of a
    Jacobian's time at N = 200.
    """
    n = tf.den.size
    num, den = padded(tf.num, n), tf.den
    dnum, dden = structure.coefficient_derivatives(theta, n)
    _, _, p, _ = tf.modal.kept()
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
        lev, X = self.levels[j], self.X[j]
        if row.size and row.min() == 0:  # only the first samples can lie before the input
            out = row == 0
            lev[out] = 0.0
            X[out] = 0.0
        return lev, X

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
    """What the coefficients c_j = u_j G(0), beta_jp = rho_p (x_p(t_j) + u_j / p) of (M1) need,
    over the segments of :func:`merged_input` (the rows of the plans)."""
    d, rho, p, _ = tf.modal.kept()
    g0 = d - float(np.sum(rho / p).real) if p.size else d
    um = merged_input(u)
    return Tables(um.levels, tf.kept_switch_states(um), g0, rho, p, d)


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
    _, rho, p, _ = tf.modal.kept()
    dd, drho, dp = dmodal
    dg0 = dd - np.sum(drho / p - rho * dp / p**2, axis=1).real if p.size else dd
    return DerivativeTables(tf.kept_switch_state_sensitivity(merged_input(u)), dg0, drho, dp)


# ---------------------------------------------------------------------------- evaluation
Phasor = tuple[FloatArray, FloatArray | None]  # Re and Im (None for a real pole)


def _phasors(p: complex, dt: FloatArray) -> Phasor:
    """Re and Im of e^{p dt} (Im None for a real pole). Real arithmetic: numpy's complex exp
    is several times slower than exp, cos and sin of the real parts."""
    ea = np.exp(p.real * dt)
    if p.imag == 0:
        return ea, None
    ph = p.imag * dt
    return ea * np.cos(ph), ea * np.sin(ph)


def _times(e: Phasor, k: ComplexArray) -> Phasor:
    """e * k elementwise, k complex (real when e is)."""
    er, ei = e
    if ei is None:
        return er * k.real, None
    return er * k.real - ei * k.imag, er * k.imag + ei * k.real


def _scaled(v: FloatArray, e: Phasor) -> Phasor:
    return v * e[0], (v * e[1] if e[1] is not None else None)


def _psum(idx: IdxArray, e: Phasor, n: int) -> Phasor:
    """Per-piece sums of a phasor array (pieces ``idx``)."""
    re = np.bincount(idx, e[0], minlength=n).astype(np.float64, copy=False)
    if e[1] is None:
        return re, None
    return re, np.bincount(idx, e[1], minlength=n).astype(np.float64, copy=False)


def _padd(a: Phasor, b: Phasor) -> Phasor:
    return a[0] + b[0], (a[1] + b[1] if a[1] is not None and b[1] is not None else None)


def _recomb(coef: ComplexArray, e: Phasor) -> FloatArray:
    """Re(coef * (re + i im)), coef per piece (any leading axes)."""
    out = coef.real * e[0]
    if e[1] is not None:
        out -= coef.imag * e[1]
    return out


def _scale_terms(
    plan: SegmentPlan,
    pc: PieceChunk,
    tab: Tables,
    c: FloatArray,
    beta: ComplexArray,
    m: FloatArray,
    a: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The scale derivative (M3) as a coefficient row (dbeta = beta p delta / a, gamma =
    beta p / a), and its jump terms per piece.

    Returns delta = t_j - kT per piece and the jump terms of dm and of dVar / 2 per piece
    (zero without feedthrough).
    """
    k = plan.T * (pc.k0 + pc.owner.astype(np.int64))
    inside = pc.row > 0
    # t_j - kT: where the piece's segment starts, relative to the nominal instant
    delta = np.where(inside, plan._mu.times[np.maximum(pc.row - 1, 0)] - k, 0.0)
    jm, jv = np.zeros(c.size), np.zeros(c.size)
    if tab.d != 0:
        # Every piece but a sample's first starts at a switch inside the window, where s
        # jumps by D (u_j - u_{j-1}) (from 0 at the input's start).
        later = np.ones(c.size, bool)
        later[pc.first] = False
        idx = np.flatnonzero(later)
        lev = np.where(inside, plan._mu.levels[np.maximum(pc.row - 1, 0)], 0.0)
        jump = tab.d * (lev[idx] - lev[idx - 1])
        tau = delta[idx]
        weight = tau * plan.law.pdf(tau) / a
        s_plus = c[idx] + np.sum(beta[idx].real, axis=1)  # s at the start of the segment
        e_plus = s_plus - m[pc.owner[idx]]
        jm[idx] = jump * weight
        jv[idx] = 0.5 * (e_plus**2 - (e_plus - jump) ** 2) * weight
    return delta, jm, jv


#: A pole is summed over the standard panels from tables of e^{p h x_i} (offsets from the
#: panel's midpoint) when |Re p| h stays below _TABLE_LIMIT, and with the factorisation
#: e^{p dt_mid} = e^{p (kT - t_j)} e^{p mid_m} when |Re p| times the window's half-width
#: stays below _FACTOR_LIMIT (no overflow of either factor). A faster pole (over-fitted
#: models) takes one phasor per node.
_TABLE_LIMIT = 40.0
_FACTOR_LIMIT = 200.0
#: ... and when the pieces have this many standard panels on average: the factorisation
#: trades a phasor per panel for a gather per panel and a phasor per piece, a gain only
#: with several panels per piece (a Gaussian window over a few switches), none for the
#: paper's U(-T/2, T/2) (two panels per piece).
_FACTOR_PANELS = 4.0


@dataclass(frozen=True, eq=False)
class _PoleTable:
    """One pole's sums over the standard panels' nodes (per panel number m):
    K = sum_i w_i e^{p h x_i}, K1 = sum_i w_i h x_i e^{p h x_i}, and with er = e^{p mid_m}
    (when the factorisation is safe) G = er K and H = er (mid_m K + K1), so that a piece's
    sums over its standard panels are e^{p (kT - t_j)} sum G and
    e^{p (kT - t_j)} ((kT - t_j) sum G + sum H)."""

    p: complex
    ep: ComplexArray | None  # e^{p h x_i}, (R, order); None: one phasor per node
    K: ComplexArray | None
    K1: ComplexArray | None
    er: ComplexArray | None
    G: ComplexArray | None
    H: ComplexArray | None

    @classmethod
    def make(cls, p: complex, std: StdTable, factor: bool = True) -> _PoleTable:
        ep = K = K1 = er = G = H = None
        if not std.hx.size or abs(p.real) * float(np.max(np.abs(std.hx))) < _TABLE_LIMIT:
            ep = np.exp(p * std.hx)
            K, K1 = (std.w * ep).sum(axis=1), (std.w * std.hx * ep).sum(axis=1)
            if (
                factor
                and std.mid.size
                and abs(p.real) * float(np.max(np.abs(std.mid))) < _FACTOR_LIMIT
            ):
                er = np.exp(p * std.mid)
                G, H = er * K, er * (std.mid * K + K1)
        return cls(p, ep, K, K1, er, G, H)

    def _gsum(self, pc: PieceChunk, table: ComplexArray) -> ComplexArray:
        npc = pc.row.size
        t = table[pc.sp_m]
        out = np.bincount(pc.sp_piece, t.real, minlength=npc).astype(complex)
        if self.p.imag != 0:
            out += 1j * np.bincount(pc.sp_piece, t.imag, minlength=npc)
        return out

    def _piece_phasor(self, pc: PieceChunk) -> ComplexArray:
        return _complex(_phasors(self.p, pc.pdt))

    def _node_sums(self, pc: PieceChunk, with_dt: bool) -> ComplexArray:
        """Per piece sum over the standard panels' nodes of w e^{p dt} (times dt), node by node."""
        W = np.take(pc.std.w.T, pc.sp_m, axis=1)
        dt = pc.sp_dt[None, :] + np.take(pc.std.hx.T, pc.sp_m, axis=1)
        if with_dt:
            W = W * dt
        E = _phasors(self.p, dt)
        g = (W * E[0]).sum(axis=0), ((W * E[1]).sum(axis=0) if E[1] is not None else None)
        return _complex(_psum(pc.sp_piece, g, pc.row.size))

    def s1(
        self, pc: PieceChunk, ce: Phasor, gh: tuple[ComplexArray, ComplexArray] | None = None
    ) -> ComplexArray:
        """S1 = sum w e^{p dt} per piece (``gh``: sum G and sum H per piece, if known)."""
        npc = pc.row.size
        cut = _complex(_psum(pc.cn_piece, _scaled(pc.cn_w, ce), npc))
        if self.G is not None:
            g = gh[0] if gh is not None else self._gsum(pc, self.G)
            return self._piece_phasor(pc) * g + cut
        if self.K is not None:
            se = _phasors(self.p, pc.sp_dt)
            return _complex(_psum(pc.sp_piece, _times(se, self.K[pc.sp_m]), npc)) + cut
        return self._node_sums(pc, False) + cut

    def s2(
        self, pc: PieceChunk, ce: Phasor, gh: tuple[ComplexArray, ComplexArray] | None = None
    ) -> ComplexArray:
        """S2 = sum w dt e^{p dt} per piece."""
        npc = pc.row.size
        cut = _complex(_psum(pc.cn_piece, _scaled(pc.cn_w * pc.cn_dt, ce), npc))
        if self.G is not None and self.H is not None:
            g, h = gh if gh is not None else (self._gsum(pc, self.G), self._gsum(pc, self.H))
            return self._piece_phasor(pc) * (pc.pdt * g + h) + cut
        if self.K is not None and self.K1 is not None:
            se = _phasors(self.p, pc.sp_dt)
            return (
                _complex(
                    _psum(
                        pc.sp_piece, _times(se, pc.sp_dt * self.K[pc.sp_m] + self.K1[pc.sp_m]), npc
                    )
                )
                + cut
            )
        return self._node_sums(pc, True) + cut

    def node_phasors(self, pc: PieceChunk, dt: FloatArray) -> Phasor:
        """e^{p dt} at the standard panels' nodes, (order, panels); ``dt`` those nodes' dt."""
        if self.ep is None:
            return _phasors(self.p, dt)
        if self.er is not None:
            e = self._piece_phasor(pc)[pc.sp_piece] * self.er[pc.sp_m]
        else:
            e = _complex(_phasors(self.p, pc.sp_dt))
        E = e[None, :] * np.take(self.ep.T, pc.sp_m, axis=1)
        return (E.real, E.imag) if self.p.imag != 0 else (E.real, None)


def _table_sums(
    pc: PieceChunk, tabs: list[_PoleTable], std: StdTable
) -> list[tuple[ComplexArray, ComplexArray] | None]:
    """sum G and sum H over each piece's standard panels for every factorised pole: the
    tables gathered at the panels' numbers and summed per piece (in panel order, as the
    counts-times-tables product this replaces, without building a sparse matrix)."""
    out: list[tuple[ComplexArray, ComplexArray] | None] = []
    for pt in tabs:
        if pt.G is None or pt.H is None:
            out.append(None)
            continue
        out.append((pt._gsum(pc, pt.G), pt._gsum(pc, pt.H)))
    return out


def _second_pass(
    pc: PieceChunk,
    std: StdTable,
    tabs: list[_PoleTable],
    cn_e: list[Phasor],
    a: FloatArray,
    beta: ComplexArray,
) -> tuple[FloatArray, FloatArray, list[ComplexArray], list[ComplexArray]]:
    """Var_k = sum w d^2 with d = s - m_k at every node, and per piece T0 = sum w d,
    T1_p = sum w d e^{p dt}, T2_p = sum w d dt e^{p dt}; a = c - m_k per piece. The
    standard panels' nodes are laid out as (order, panels) arrays, so that the sums over a
    panel run over the short first axis."""
    npc, n = pc.row.size, pc.k1 - pc.k0
    W = np.take(std.w.T, pc.sp_m, axis=1)
    DT = pc.sp_dt[None, :] + np.take(std.hx.T, pc.sp_m, axis=1)
    d = np.repeat(a[pc.sp_piece][None, :], W.shape[0], axis=0)
    Es = [pt.node_phasors(pc, DT) for pt in tabs]
    for i, E in enumerate(Es):
        d += _recomb(beta[pc.sp_piece, i], E)
    wd = W * d
    var = np.zeros(n)
    var += np.bincount(pc.owner[pc.sp_piece], (wd * d).sum(axis=0), minlength=n)
    t0 = np.zeros(npc)
    t0 += np.bincount(pc.sp_piece, wd.sum(axis=0), minlength=npc)
    wddt = wd * DT
    # the other panels' nodes one by one
    dc = a[pc.cn_piece]
    for i, ce in enumerate(cn_e):
        dc = dc + _recomb(beta[pc.cn_piece, i], ce)
    wdc = pc.cn_w * dc
    var += np.bincount(pc.owner[pc.cn_piece], wdc * dc, minlength=n)
    t0 += np.bincount(pc.cn_piece, wdc, minlength=npc)
    T1, T2 = [], []
    for E, ce in zip(Es, cn_e, strict=True):
        g1 = (wd * E[0]).sum(axis=0), ((wd * E[1]).sum(axis=0) if E[1] is not None else None)
        g2 = (wddt * E[0]).sum(axis=0), ((wddt * E[1]).sum(axis=0) if E[1] is not None else None)
        t1 = _padd(_psum(pc.sp_piece, g1, npc), _psum(pc.cn_piece, _scaled(wdc, ce), npc))
        t2 = _padd(
            _psum(pc.sp_piece, g2, npc), _psum(pc.cn_piece, _scaled(wdc * pc.cn_dt, ce), npc)
        )
        T1.append(_complex(t1))
        T2.append(_complex(t2))
    return var, t0, T1, T2


def _complex(e: Phasor) -> ComplexArray:
    return e[0] + 1j * e[1] if e[1] is not None else e[0].astype(complex)


def _zv(
    tab: Tables, dtab: DerivativeTables, row: IntArray
) -> tuple[FloatArray, ComplexArray, ComplexArray]:
    """u_j, z = x(t_j) + u_j / p and v = rho (dx/dp(t_j) - u_j / p^2) per piece: dbeta =
    drho z + dp v (:meth:`DerivativeTables.coefficients`)."""
    lev, X = tab.segment(row)
    dX = dtab.dXdp[np.maximum(row - 1, 0)]
    if row.size and row.min() == 0:
        dX[row == 0] = 0.0
    return lev, X + lev[:, None] / tab.p, tab.rho * (dX - lev[:, None] / tab.p**2)


def _combine(
    dtab: DerivativeTables,
    first: IntArray,
    lev_mass: FloatArray,
    z: ComplexArray,
    v: ComplexArray,
    S1: list[ComplexArray],
    S2: list[ComplexArray],
    beta: ComplexArray,
) -> FloatArray:
    """Per sample and system parameter r: dg0_r sum u S + sum_p Re(drho_rp sum z_p S1_p +
    dp_rp sum (v_p S1_p + beta_p S2_p)), the sums over the sample's pieces."""
    out = dtab.dg0[:, None] * np.add.reduceat(lev_mass, first)[None, :]
    for i in range(z.shape[1]):
        Z = np.add.reduceat(z[:, i] * S1[i], first)
        V = np.add.reduceat(v[:, i] * S1[i] + beta[:, i] * S2[i], first)
        out += (dtab.drho[:, i, None] * Z[None, :]).real + (dtab.dp[:, i, None] * V[None, :]).real
    return np.asarray(out, dtype=np.float64)


def modal_moments(
    plan: SegmentPlan,
    tab: Tables,
    dtab: DerivativeTables | None = None,
    *,
    scale: float | None = None,
    keep: bool = True,
    variance: bool = True,
) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
    """m_k, Var_k (M2) and their derivatives, shape (R, N), chunk by chunk.

    The derivative rows are the system parameters of ``dtab`` and then, with ``scale`` = a,
    the scale of the jitter law (tau = a xi with the law of xi free of a):

        dm_k / da = (1/a) (E[s'(kT + tau) tau] + sum_j Ds_j tau_j p(tau_j)),          (M3)

    s' = Re sum_p beta_p p e^{p dt} on each segment and Ds_j = D (u_j - u_{j-1}) the jumps of
    s at the switches t_j in the window (tau_j = t_j - kT); dVar_k / da alike with
    (s - m_k)^2 for s. (``keep``: see :meth:`SegmentPlan.chunks`.) With ``variance`` False
    the second pass is skipped and Var_k and its derivatives are None (the least-squares
    criteria use the mean only): about half the work.
    """
    N = plan.N
    mean = np.empty(N)
    var = np.empty(N) if variance else None
    rows = (0 if dtab is None else dtab.dg0.size) + (scale is not None)
    dmean = dvar = None
    if rows:
        dmean = np.empty((rows, N))
        dvar = np.empty((rows, N)) if variance else None
    tables_of: dict[int, list[_PoleTable]] = {}
    for pc in plan.chunks(keep):
        c, beta = tab.coefficients(pc.row)  # (pieces,), (pieces, n_kept)
        std = pc.std
        if id(std) not in tables_of:
            factor = pc.sp_m.size >= _FACTOR_PANELS * max(pc.row.size, 1)
            tables_of = {id(std): [_PoleTable.make(complex(p), std, factor) for p in tab.p]}
        tabs = tables_of[id(std)]
        cn_e = [_phasors(complex(p), pc.cn_dt) for p in tab.p]
        gh = _table_sums(pc, tabs, std)
        s1 = [pt.s1(pc, ce, g) for pt, ce, g in zip(tabs, cn_e, gh, strict=True)]
        m_piece = c * pc.mass
        for i, s1i in enumerate(s1):
            m_piece += (beta[:, i] * s1i).real
        m = np.add.reduceat(m_piece, pc.first)
        sl = slice(pc.k0, pc.k1)
        mean[sl] = m
        node = None
        if var is not None:
            node = _second_pass(pc, std, tabs, cn_e, c - m[pc.owner], beta)
            var[sl] = node[0]
        if not rows:
            continue
        assert dmean is not None
        # ds = dc + Re sum_p (dbeta_p + gamma_p dt) e^{p dt} with, for a system parameter r,
        # dc = dg0_r u_j, dbeta_p = drho_rp z_p + dp_rp v_p, gamma_p = dp_rp beta_p, so
        #   dm_k[r] = dg0_r L_k + sum_p Re(drho_rp Z_pk + dp_rp V_pk),
        #   L = sum u_j S0, Z_p = sum z_p S1_p, V_p = sum (v_p S1_p + beta_p S2_p)
        # over the pieces of sample k: the pieces are summed before the parameters enter.
        S1 = s1
        S2 = [pt.s2(pc, ce, g) for pt, ce, g in zip(tabs, cn_e, gh, strict=True)]
        sys_parts = None
        if dtab is not None:
            lev, z, v = _zv(tab, dtab, pc.row)
            sys_parts = (lev, z, v)
            dm_sys = _combine(dtab, pc.first, lev * pc.mass, z, v, S1, S2, beta)
            dmean[: dm_sys.shape[0], sl] = dm_sys
        dm_scale = jm = jv = delta = None
        if scale is not None:
            delta, jm, jv = _scale_terms(plan, pc, tab, c, beta, m, scale)
            bp = beta * tab.p / scale
            piece = jm.copy()
            for i in range(bp.shape[1]):  # dbeta = bp delta, gamma = bp
                piece += np.real(bp[:, i] * (delta * S1[i] + S2[i]))
            dm_scale = np.add.reduceat(piece, pc.first)
            dmean[-1, sl] = dm_scale
        if dvar is None or node is None:
            continue
        _, t0, T1, T2 = node
        # d sum w (s - m)^2 = 2 sum w (s - m) ds - 2 dm sum w (s - m); the last sum is
        # m (1 - sum w), zero up to the rule's mass error, kept so the derivative is exact.
        t0k = np.add.reduceat(t0, pc.first)
        if sys_parts is not None and dtab is not None:
            lev, z, v = sys_parts
            dv_sys = _combine(dtab, pc.first, lev * t0, z, v, T1, T2, beta)
            dvar[: dv_sys.shape[0], sl] = 2 * dv_sys - 2 * dmean[: dv_sys.shape[0], sl] * t0k
        if scale is not None and delta is not None and jv is not None and dm_scale is not None:
            bp = beta * tab.p / scale
            piece = jv.copy()
            for i in range(bp.shape[1]):
                piece += np.real(bp[:, i] * (delta * T1[i] + T2[i]))
            dvar[-1, sl] = 2 * np.add.reduceat(piece, pc.first) - 2 * dm_scale * t0k
    return mean, var, dmean, dvar
