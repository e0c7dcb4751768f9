"""The exact likelihood of jittered samples, its score, and the Cramer-Rao bound (notes 4).

Given the input, the samples are independent and each has the density

    p(y_k | theta) = int p(tau) N(y_k; s(kT + tau; theta), sigma_v^2) dtau,            (L1)

one integral per sample, evaluated with the jitter quadrature of :mod:`jitterid.moments.quadrature`
in log space (log-sum-exp per sample, so that no density underflows):

    log p(y_k) = logsumexp_j [ln w_j - (y_k - s(t_j))^2 / (2 sigma_v^2)] - ln(sqrt(2 pi) sigma_v).

As a function of tau the Gaussian factor has width sigma_v / |s'|, so the panels must be
short where the signal is steep. The time axis is cut so that no panel is longer than
``panel * sigma_v / S(t)``, S the local maximum of |s'| (over +-two cells of a grid of
spacing 1/(4 rate), times 1.25) at the parameter where the rule is *designed*, with
``order`` Gauss-Legendre nodes per panel. The defaults ``order = 8``, ``panel = 4`` give about
1e-8 absolute error in each log p(y_k) on the paper's experiments (tests: against a rule with
the panels quartered and twice the order). The rule is frozen once designed, so the criterion
is smooth in theta; :meth:`ExactLikelihood.design` re-designs it (``fit`` does so at the
optimum and re-optimises if the value moved). Cost: O(N + TV(s) / sigma_v) signal
evaluations, TV the total variation of s.

Windows (the adaptive rule). Where that full rule would have more than ``_WINDOW_FROM``
panels per sample (a signal steep relative to the noise: a sine record with small noise, or
the response to a switching input at the paper's noise levels), each sample gets its own
rule (:func:`_window_panels`): the slope grid's cells inside its jitter window (cut at the
input's switches) are halved until the panel criterion holds, with the tighter bound
|s'| <= |s'(mid)| + 1.25 rate S |t - mid|, and every piece on which the integrand cannot
reach e^-24 of the sample's largest piece is dropped on the way. The pieces left surround
the instants where s(t) comes within ~8 sigma_v of y_k, so the cost is O(N) whatever
sigma_v. Each piece gets as many Gauss-Legendre nodes as its span (the change of
(y - s) / sigma_v over it) and its slack (how far below the sample's best piece it lies)
require for an error below ~3e-11 of p(y_k) (:func:`_piece_orders`: 3 to 12 nodes, ~90 per
sample on the paper's Table 2 against ~220 for the full rule). Tests: against the full rule
with the panels quartered and twice the order, within 1e-8 in each ln p(y_k), on steep and
flat signals, smooth and switching. The windows depend on y and on the parameters where
they were designed; the rule is re-designed at any parameter whose signal moved by more than
half a noise std at a piece's midpoint, or whose noise std left [0.8, 1.25] of the design's
(a window that missed the peak would underestimate p(y_k) grossly); the last designs are
kept for a return (a check at a start far off, then back at the estimate). Across jitter
laws (a family's parameters, a delay) the pieces are built once for an envelope of the law
and kept for the laws near it (:meth:`ExactLikelihood._window_pieces`): the law stretched
1.25 times about its mean, or, for a law whose knots move with its parameters (the paper's
SumOfUniforms(n, a)), its support so stretched with a flat pdf twice the law's largest: no
knot of one law is built in. A law takes them where its support lies inside the envelope's,
its std is at least half the envelope's, its pdf below the envelope's (the flat value; a
stretched scale family's within a factor 2) and, in every sample, the pieces the build
dropped below e^-22 of the best one under its own pdf (:func:`_serves`: a narrower law may
have its mass where the build's law had none worth keeping). Each law then re-tests the
pieces with its own pdf (dropping those below e^-24 of the sample's best), cuts them at its
support's ends and at its knots, so that Gauss-Legendre never straddles a knot of the
piecewise-polynomial pdf, and gives each part the nodes its share of the piece's span and
bound requires (:func:`_under`). A known law whose knots cannot move (no delay) gets pieces
of its own, built on its knots.

Memory. The nodes of a rule are kept between evaluations up to ``NODE_BUDGET``; a larger
rule (a long record) is made again chunk by chunk (``_CHUNK`` samples) at each evaluation
from its pieces (~40 bytes each) or its cuts, and every evaluation, score and information
streams through the chunks: the memory is bounded independently of N (:class:`_Rule`).

With posterior weights pi_j = w_j N(y; s_j, sigma_v^2) / p(y) (sum 1 per sample), the score is

    d ln p / d theta   = sum_j pi_j (y - s_j) / sigma_v^2  ds_j / d theta                 (L2)
    d ln p / d sigma_v = sum_j pi_j ((y - s_j)^2 / sigma_v^3 - 1 / sigma_v)
    d ln p / d y       = -sum_j pi_j (y - s_j) / sigma_v^2,

and, with e_j = (y - s_j) / sigma_v and D_j = ds_j / dtheta, the observed information

    -d^2 ln p / dtheta^2 = g g^T + sum_j pi_j [(1 - e_j^2) D_j D_j^T / sigma_v^2
                                              - e_j d^2 s_j / dtheta^2 / sigma_v]      (L5)

(exact where the signal gives d^2 s: :meth:`~jitterid.systems.model.Signal.
second_derivatives`; the Gauss-Newton form without the last term otherwise),

ds/dtheta at the (fixed) nodes from the modal form of the response, with the same
exponentials as s (:class:`_NodeSignal`); for other signals their own gradient where they
have one (the steady-state response to a multisine, a tone model), else forward differences
of s. A jitter family's scale a (the law of a xi) moves the nodes only:
ds/da = (tau / a) s'(t), s' from the same modal form; its shape parameters (n) move the
weights only: for a family with a closed-form dp/dtheta (``JitterFamily.pdf_gradient``; n
of the family (26) off its integers) d ln p / d theta = sum_j pi_j (dp/dtheta / p)(tau_j) at
the same nodes, else a forward difference of ln p with the shifted law's pdf at the same
nodes (n at an integer and just below one).
:meth:`ExactLikelihood.maximise` uses these scores with a Gauss-Newton observed information
in :func:`jitterid.estimation.search.newton_search`. The Fisher information of one record is

    I(theta) = sum_k int p_k(y) g_k(y) g_k(y)^T dy,   g_k = grad_theta ln p_k(y),        (L3)

computed by the trapezoidal rule in y (spacing sigma_v / 2 over [min s - 9 sigma_v,
max s + 9 sigma_v]: p_k is a mixture of Gaussians of width sigma_v, for which the rule is
spectrally accurate) on top of the tau quadrature, with g_k from central differences of
ln p_k on the y-grid. :func:`jitterid.estimation.bounds.crb` returns I^{-1};
:func:`jitterid.estimation.bounds.gaussian_bound` returns the bound of
the second-moment model y_k ~ N(m_k, w_k) (notes 1-3), which the paper's estimators, using
only m_k and w_k, cannot beat:

    I_G = sum_k [dm_k dm_k^T / w_k + dw_k dw_k^T / (2 w_k^2)].                         (L4)
"""

from __future__ import annotations

import contextlib
import functools
import weakref
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import finite_diff
from .._checks import count, positive, real_array, sampling_interval
from .._memory import trim
from .._state import CachesAreNotState, cache_field
from ..inputs import Input, PiecewiseConstant
from ..jitter.laws import JitterFamily, JitterLaw, known_law
from ..moments.quadrature import PanelChunk, jitter_nodes, jitter_panels, rule_frame
from ..params import ParamLayout, count_params
from ..systems.model import Model, Signal
from ..systems.structures import ModelStructure, as_structure
from ..systems.tf import TransferFunction
from .resources import check_likelihood, check_mode_rate, kept_nodes
from .search import LIKELIHOOD_FLOOR, evaluator, newton_search

__all__ = [
    "DEFAULT_ORDER",
    "DEFAULT_PANEL",
    "ExactLikelihood",
    "RuleBudgetError",
    "log_density",
]

FloatArray = NDArray[np.float64]

DEFAULT_ORDER = 8  # Gauss-Legendre nodes per panel
DEFAULT_PANEL = 4.0  # panel length <= DEFAULT_PANEL * sigma_v / local max |s'|
_SLOPE_SAFETY = 1.25
_PANEL_BUDGET = 20_000_000  # refuse rules with more panels (memory and time)


class RuleBudgetError(ValueError):
    """The quadrature rule would need more than its budget of panels: the signal is steep
    relative to the noise std over a long record. A caller with another route (the jitter
    meter's Gaussian criterion) catches it; a user sees its message, which names the fix."""


_CHUNK = 1024  # samples per node chunk (the full rule: fewer where a sample has many nodes,
#                 so that a chunk holds at most resources.CHUNK_NODES of them)
NODE_BUDGET = 8_000_000  # nodes kept in memory between evaluations (~0.4 GB); more: streamed
_Y_STEP = 0.5  # y-grid spacing of (L3) in units of sigma_v
_Y_TAIL = 9.0  # y-grid margin in units of sigma_v
_LOG_SQRT_2PI = 0.5 * np.log(2 * np.pi)
_WINDOW_FROM = 12.0  # windowed rule when the full rule has more panels per sample (there
#                     the windowed rule has fewer nodes: ~90 per sample against 8 per panel)
_WINDOW_CUT = 24.0  # drop pieces below e^-24 of the sample's largest (ln p to ~1e-10)
_WINDOW_MARGIN = 1.0  # ... with the distance |y - s| shortened by this many sigma
_WINDOW_ROUNDS = 48  # halvings at most
_WINDOW_FLOOR = 1e-12  # ... and no piece shorter than this times T
_WINDOW_PDF = 0.6  # no piece longer than this many jitter std's
_WINDOW_SIGMA_STEP = 0.25  # a noise std below this fraction of the design's is refused
_WINDOW_SIGMA_REDESIGN = 0.8  # ... below this fraction (or above its inverse): re-designed
_FAR, _FAR_FRACTION = 10.0, 0.25  # the windowed rule gives way to the full one (_far)
_SPARE_DESIGNS = 2  # earlier windowed designs kept (a check far off, then back)
_TRIM_FROM = 100_000  # records from this many samples return freed pages after a design
_WINDOW_STRETCH = 1.25  # pieces built for the law stretched by this (kept for nearby laws)
_FLAT_PEAK = 2.0  # ... a law with moving knots: for a flat pdf this times the law's largest
_WINDOW_LOST = 2.0  # ... kept for a law under whose pdf no piece dropped is above e^-(24 - 2)
_WINDOW_EXTRA_ORDER = 4  # Gauss-Legendre nodes per piece: order + this (pieces span 4 sigma
#                          of the Gaussian factor by a tight slope bound; near an extremum of
#                          s the exponent is quartic in t, where 8 nodes give ~1e-7)
_ORDER_SPANS = np.array([0.5, 1.0, 2.0, 3.0, 4.0])  # _piece_orders' table: spans (rows),
_ORDER_SLACKS = np.array([0.0, 4.0, 8.0, 16.0, 20.0])  # slacks (columns), nodes
_ORDER_TABLE = np.array(
    [[5, 4, 4, 3, 3], [6, 5, 5, 4, 3], [8, 7, 6, 5, 3], [10, 8, 7, 6, 4], [11, 9, 8, 7, 5]]
)
_SCORE_STEP = 1e-7  # relative forward step of the differenced scores (finite_diff.forward)
_SAME_NODES = 1e4  # a shape's knots may move by 1 / _SAME_NODES of a piece (_same_nodes)
_FISHER_STEP = 1e-4  # relative central step of (L3) (finite_diff.central_pair)
_DENSE = 96  # nodes of a sample up to which (L3)'s y-grid sums every node (_log_mixture)
_BAND = 10.0  # ... beyond, the nodes this many noise std's farther than the nearest
FISHER_SCALE_STEP = 0.05  # ... or at most this fraction of a parameter's natural scale


# ---------------------------------------------------------------------------- signal at nodes
def _modal_gradient(
    structure: ModelStructure, theta: FloatArray, tf: TransferFunction
) -> tuple[FloatArray, NDArray[np.complex128], NDArray[np.complex128]] | None:
    """d(D, rho, p)/d theta by central differences of the modal form (poles matched by
    proximity); None if the matching is ambiguous (then the caller differentiates s)."""
    p0 = tf.modal.kept()[2]
    n = theta.size
    dd, drho, dp = np.empty(n), np.empty((n, p0.size), complex), np.empty((n, p0.size), complex)
    for i in range(n):
        up, down, h2 = finite_diff.central_pair(theta, i, structure.bounds[i], 1e-6)
        parts = []
        for th in (up, down):
            d, rho, p, _ = structure.system(th).modal.kept()
            if p.size != p0.size:
                return None
            j = np.argmin(np.abs(p[None, :] - p0[:, None]), axis=1)
            if np.unique(j).size != j.size:
                return None
            parts.append((d, rho[j], p[j]))
        (dp_, rp, pp), (dm, rm, pm) = parts
        dd[i], drho[i], dp[i] = (dp_ - dm) / h2, (rp - rm) / h2, (pp - pm) / h2
    return dd, drho, dp


def _pole_sensitivity(tf: TransferFunction, u: PiecewiseConstant) -> NDArray[np.complex128]:
    """dX/dp of the modal states at the input's switch times, kept poles, shape (J+1, nk).

    X(p) is analytic in p; shifting every pole by the same real -delta keeps the
    denominator real, and a one-sided second-order difference stays on the stable side.
    """
    p = tf.modal.poles
    pk = p[p.imag >= 0]
    delta = 1e-5 * float(np.max(np.abs(p)))
    states = []
    for shift in (0.0, delta, 2 * delta):
        moved = TransferFunction(np.ones(1), np.real(np.poly(p - shift)))
        q = moved.modal.poles
        j = np.argmin(np.abs(q[None, :] - (pk - shift)[:, None]), axis=1)
        states.append(moved.switch_states(u)[:, j])
    return (3 * states[0] - 4 * states[1] + states[2]) / (2 * delta)


class _NodeSignal:
    """s(t) and ds/dtheta at a fixed set of instants, for any signal.

    For the response of an LTI system to a piecewise-constant input (:attr:`analytic`):

    The input's segment of every instant is found once, so a new system costs a few real
    exponentials per node and pole pair: the modal formula of :class:`jitterid.systems.tf.Response`
    (tested against it), x = e^{p dt} X_j + u_j expm1(p dt) / p on the segment starting at the
    switch time t_j with state X_j. Its pole derivative, from the same exponentials, is
    dx/dp = e^{p dt} (dt X_j + dX_j/dp) + u_j (dt e^{p dt} / p - expm1(p dt) / p^2).
    """

    def __init__(self, sig: Signal, t: FloatArray, segment: NDArray[np.intp] | None = None) -> None:
        self.t = t
        if t.size:
            sig.check_covers(float(np.max(t)), "the last quadrature node")
        seg = sig.modal_segments
        self.u = u = None if seg is None else seg.u
        if u is not None:
            # the input's segment of each instant (given: the windowed rule's pieces lie
            # between switches, so it is found once per piece)
            j = np.searchsorted(u.times, t, side="right") - 1 if segment is None else segment
            self.inside = j >= 0
            self.seg = np.clip(j, 0, u.levels.size - 1)
            self.level = np.where(self.inside, u.levels[self.seg], 0.0)
            self.dt = (t - u.times[self.seg])[:, None]

    @property
    def analytic(self) -> bool:
        """Whether :meth:`gradient` is available (LTI responses to piecewise-constant inputs);
        otherwise the signal's own gradient and slope, or differences, are used."""
        return self.u is not None

    def _pole_terms(
        self, tf: TransferFunction, dX: NDArray[np.complex128] | None = None
    ) -> Iterator[tuple[complex, complex, FloatArray, FloatArray, FloatArray, FloatArray]]:
        """Per kept pole: (rho, p, Re x, Im x, Re dx/dp, Im dx/dp) at the nodes (dx/dp only
        with ``dX``; else zeros). Real arithmetic on 1-D arrays: numpy's complex expm1 and
        small complex matmuls are ~10x slower. Nodes before the input starts get x = 0."""
        _, rho, pk, cols = tf.modal.kept()
        assert isinstance(self.u, PiecewiseConstant)
        X = tf.switch_states(self.u)
        dt = self.dt[:, 0]
        for k, (rk, p) in enumerate(zip(rho, pk, strict=True)):
            a = dt * p.real
            ea = np.where(self.inside, np.exp(a), 0.0)
            Xj = X[self.seg, cols[k]]
            q = 1 / p
            lr, li = self.level * q.real, self.level * q.imag  # u_j / p
            if p.imag == 0.0:  # a real pole: the same values without the rotation
                zero = np.zeros_like(a)
                er, ei, mr, mi = ea, zero, np.expm1(a), zero
                xr = er * Xj.real + mr * lr
                xi = er * Xj.imag + mr * li
            else:
                half = 0.5 * dt * p.imag
                sh, ch = np.sin(half), np.cos(half)
                cb, sb = 1 - 2 * sh * sh, 2 * sh * ch
                er, ei = ea * cb, ea * sb  # e^{p dt}
                mr, mi = np.expm1(a) * cb - 2 * sh * sh, ea * sb  # expm1(p dt)
                xr = er * Xj.real - ei * Xj.imag + mr * lr - mi * li
                xi = er * Xj.imag + ei * Xj.real + mr * li + mi * lr
            if dX is None:
                yield rk, p, xr, xi, np.zeros(0), np.zeros(0)
                continue
            # dx/dp = e (dt X + dX) + u (dt e / p - expm1 / p^2)
            W = dt * Xj + dX[self.seg, k]
            q2 = q * q
            vr = dt * (er * q.real - ei * q.imag) - (mr * q2.real - mi * q2.imag)
            vi = dt * (er * q.imag + ei * q.real) - (mr * q2.imag + mi * q2.real)
            zr = er * W.real - ei * W.imag + self.level * vr
            zi = er * W.imag + ei * W.real + self.level * vi
            yield rk, p, xr, xi, zr, zi

    def __call__(self, sig: Signal) -> FloatArray:
        if not self.analytic:
            return sig(self.t)
        seg = sig.modal_segments
        assert seg is not None
        tf = seg.system
        s = tf.modal.direct * self.level
        for rk, _, xr, xi, _, _ in self._pole_terms(tf):
            s = s + (rk.real * xr - rk.imag * xi)
        return np.asarray(s, dtype=float)

    def gradient(
        self,
        sig: Signal,
        dmodal: tuple[FloatArray, NDArray[np.complex128], NDArray[np.complex128]] | None,
        dX: NDArray[np.complex128] | None,
        *,
        slope: bool = False,
    ) -> tuple[FloatArray, FloatArray] | tuple[FloatArray, FloatArray, FloatArray]:
        """s at the nodes and ds/dtheta, shape (n_params, n_nodes), given the modal gradient
        (:func:`_modal_gradient`) and the switch-state pole sensitivity (:func:`_pole_sensitivity`);
        ``dmodal = None``: no parameters (shape (0, n_nodes)). With ``slope``, also the time
        derivative s'(t) = Re sum rho (p x + u) at the nodes, from the same exponentials (the
        score of a jitter scale parameter, see :meth:`ExactLikelihood._terms`)."""
        assert isinstance(self.u, PiecewiseConstant)
        seg = sig.modal_segments
        assert seg is not None
        tf = seg.system
        s = tf.modal.direct * self.level
        ds = np.zeros(self.t.size)
        if dmodal is None:
            D = np.zeros((0, self.t.size))
            terms = self._pole_terms(tf)
        else:
            assert dX is not None
            dd, drho, dp = dmodal
            D = dd[:, None] * self.level[None, :]
            terms = self._pole_terms(tf, dX)
        for k, (rk, p, xr, xi, zr, zi) in enumerate(terms):
            s = s + (rk.real * xr - rk.imag * xi)
            if slope:  # dx/dt = p x + u
                vr, vi = p.real * xr - p.imag * xi + self.level, p.real * xi + p.imag * xr
                ds += rk.real * vr - rk.imag * vi
            if dmodal is None:
                continue
            for i in range(D.shape[0]):
                c1, c2 = drho[i, k], rk * dp[i, k]  # ds = Re(drho x + rho dp dx/dp)
                D[i] += c1.real * xr - c1.imag * xi + c2.real * zr - c2.imag * zi
        if slope:
            return np.asarray(s, dtype=float), D, ds
        return np.asarray(s, dtype=float), D


@dataclass(frozen=True)
class _SlopeProfile:
    """A bound on |s'| along the time axis: ``local[i]`` holds on grid cell i and its two
    neighbours on each side (grid spacing 1/(4 rate)), with a safety factor."""

    grid: FloatArray
    local: FloatArray

    def cumulative(self) -> FloatArray:
        """int S dt from the grid's start, at the grid points."""
        return np.r_[0.0, np.cumsum(self.local * np.diff(self.grid))]

    def over(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """A bound on |s'| over each interval [a, b] no longer than 1/rate (two cells on either
        side of its midpoint's cell)."""
        i = np.clip(np.searchsorted(self.grid, 0.5 * (a + b)) - 1, 0, self.local.size - 1)
        return self.local[i]


def _slope_profile(signal: Signal, span: tuple[float, float]) -> _SlopeProfile | None:
    """The slope bound S(t) of the module doc on ``span`` (None for an empty span)."""
    a, b = max(span[0], signal.start), min(span[1], np.nextafter(signal.end, -np.inf))
    if not (b > a and signal.rate > 0):
        return None
    step = 0.25 / signal.rate
    n = int(min(np.ceil((b - a) / step), 4_000_000))
    grid = np.linspace(a, b, n + 1)
    h = 1e-6 * step
    inner = np.clip(grid, a + h, b - h)
    slope = np.abs(signal(inner + h) - signal(inner - h)) / (2 * h)
    cell = np.maximum(slope[:-1], slope[1:])
    # |s'| on either side of every break inside a cell (s' may jump there, and a pulse
    # shorter than a cell would be missed by the grid alone)
    br = np.asarray(signal.breaks, dtype=float)
    br = br[(br > a + 2 * h) & (br < b - 2 * h)]
    if br.size:
        at = np.clip(np.searchsorted(grid, br, side="right") - 1, 0, cell.size - 1)
        for side in (-1.0, 1.0):
            near = br + side * 2 * h
            sl = np.abs(signal(near + h) - signal(near - h)) / (2 * h)
            np.maximum.at(cell, at, sl)
    pad = np.r_[0.0, 0.0, cell, 0.0, 0.0]
    local = _SLOPE_SAFETY * np.max(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)
    return _SlopeProfile(grid, local)


def _panel_cuts(profile: _SlopeProfile | None, sigma: float, panel: float) -> FloatArray:
    """Absolute cut times at most ``panel * sigma / S(t)`` apart (see module doc)."""
    if profile is None:
        return np.zeros(0)
    cum = profile.cumulative() / (panel * sigma)
    if cum[-1] > _PANEL_BUDGET:
        raise RuleBudgetError(
            f"the exact likelihood would need ~{cum[-1]:.3g} quadrature panels (the signal is "
            f"steep relative to noise_std = {sigma:g}); raise `panel` (less accurate) or use "
            "fewer samples"
        )
    return np.interp(np.arange(1.0, np.floor(cum[-1]) + 1), cum, profile.grid)


def _value_and_slope(signal: Signal, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """s(t) and s'(t): from one pass of the modal form for an LTI response to a
    piecewise-constant input, else the signal and :func:`_slope_at`."""
    nodes = _NodeSignal(signal, t)
    if nodes.analytic:
        s, _, ds = nodes.gradient(signal, None, None, slope=True)  # type: ignore[misc]
        return s, ds
    return signal(t), _slope_at(signal, t)


def _slope_at(signal: Signal, t: FloatArray) -> FloatArray:
    """s'(t): the signal's own slope, or a central difference."""
    if signal.has_slope:
        out = signal.slope(t)
        if out is not None:
            return out
    h = 1e-6 / signal.rate
    return (signal(t + h) - signal(t - h)) / (2 * h)


@dataclass(frozen=True, eq=False)
class _Panels:
    """The pieces of :func:`_window_panels`, sorted by owner and time: ``slack`` the ln of the
    sample's best piece's lower bound less this piece's upper bound, ``span`` the bound on the
    change of (y - s) / sigma over it (:func:`_piece_orders`; -inf and inf for a piece left
    open), ``near`` and ``far`` the Gaussian factor's part of its upper and lower bounds,
    -(d_lo)^2 / 2 and -(d_hi)^2 / 2 (d the distance from y_k in noise std's, shortened by the
    margin and lengthened by the slope bound), and ``lost`` per sample the largest upper
    bound of a piece dropped (-inf: none)."""

    owner: NDArray[np.int64]
    a: FloatArray
    b: FloatArray
    slack: FloatArray
    span: FloatArray
    near: FloatArray
    far: FloatArray
    lost: FloatArray


def _window_panels(
    pch: PanelChunk,
    T: float,
    y: FloatArray,
    signal: Signal,
    sigma: float,
    panel: float,
    profile: _SlopeProfile,
    density: JitterLaw,
    reach: JitterLaw | _Stretched | None = None,
) -> _Panels:
    """The panels of the windowed rule (module doc, "Windows").

    Each sample's pieces ``pch`` (the slope grid's cells inside its window, cut at the
    pdf's knots and the signal's breaks: edges that do not move with the parameters) are
    halved until S(t) (length) <= ``panel * sigma`` and the length is at most
    ``_WINDOW_PDF`` jitter std's, dropping on the way every piece on which the integrand
    p(tau) N(y_k; s(t), sigma^2) is below e^-``_WINDOW_CUT`` of the sample's largest piece,
    by the bounds |s(t) - s(mid)| <= S (half-length) and the pdf at the ends and the middle
    (with the distance to y_k shortened by ``_WINDOW_MARGIN`` sigma, for moves of theta away
    from the design). Every edge lies on a dyadic subdivision of the fixed pieces, so the
    rule changes with the jitter parameters only where a piece's depth or the support's
    edges do. With ``reach`` (a wider law), a piece is kept by that law's pdf and compared
    with the best piece under ``density``: the pieces then serve both. Returns the
    pieces sorted by owner and time, with their bounds (:class:`_Panels`)."""
    pdf_len = _WINDOW_PDF * float((density if reach is None else reach).std)
    owner, a, b = pch.owner, pch.a, pch.b
    n = pch.k1 - pch.k0
    yk_all = y[pch.k0 : pch.k1]
    best_done, lost = np.full(n, -np.inf), np.full(n, -np.inf)
    out_o, out_a, out_b, out_u, out_r, out_n, out_f = [], [], [], [], [], [], []
    with np.errstate(divide="ignore"):
        for _ in range(_WINDOW_ROUNDS):
            if owner.size == 0:
                break
            mid, half = 0.5 * (a + b), 0.5 * (b - a)
            Sp = profile.over(a, b)
            # |s'| <= |s'(mid)| + kappa |t - mid| with kappa = 1.25 rate S (a band-limited
            # signal's |s''| <= rate max|s'|): much tighter than S where s is flat
            kappa = _SLOPE_SAFETY * signal.rate * Sp
            s_mid, sl = _value_and_slope(signal, mid)
            sl = np.abs(sl)
            S = np.minimum(Sp, sl + kappa * half)
            dev = np.minimum(Sp * half, sl * half + 0.5 * kappa * half**2)
            d = np.abs(yk_all[owner] - s_mid)
            dlo = np.maximum((d - dev) / sigma - _WINDOW_MARGIN, 0.0)
            dhi = (d + dev) / sigma
            base = np.asarray((pch.k0 + owner) * T, dtype=float)
            top, least = _pdf_range(density, a, b, base)
            if reach is not None:
                top = _pdf_range(reach, a, b, base)[0]
            upper, lower = top - 0.5 * dlo**2, least - 0.5 * dhi**2
            best = best_done.copy()
            np.maximum.at(best, owner, lower)
            keep = upper >= best[owner] - _WINDOW_CUT
            np.maximum.at(lost, owner[~keep], upper[~keep])
            short = (2 * half * S <= panel * sigma) & (2 * half <= pdf_len)
            done = keep & (short | (half <= _WINDOW_FLOOR * T))
            if np.any(done):
                np.maximum.at(best_done, owner[done], lower[done])
                out_o.append(owner[done])
                out_a.append(a[done])
                out_b.append(b[done])
                out_u.append(upper[done])
                out_r.append((2 * half * S / sigma)[done])
                out_n.append(-0.5 * dlo[done] ** 2)
                out_f.append(-0.5 * dhi[done] ** 2)
            split = keep & ~done
            o, lo_, mi, hi_ = owner[split], a[split], mid[split], b[split]
            owner = np.concatenate([o, o])
            a = np.concatenate([lo_, mi])
            b = np.concatenate([mi, hi_])
    if owner.size:  # pieces still open after the last round: keep them as they are
        out_o.append(owner)
        out_a.append(a)
        out_b.append(b)
        out_u.append(np.zeros(owner.size) + np.inf)
        out_r.append(np.zeros(owner.size) + np.inf)
        out_n.append(np.zeros(owner.size))
        out_f.append(np.zeros(owner.size) - np.inf)
    o, aa, bb = np.concatenate(out_o), np.concatenate(out_a), np.concatenate(out_b)
    with np.errstate(invalid="ignore"):
        slack = best_done[o] - np.concatenate(out_u)
    # (-inf - -inf: a sample none of whose pieces has a positive bound, the law's density
    # zero at every piece's ends and middle: no slack, the most nodes; a NaN sorted last in
    # _piece_orders and gave the fewest)
    slack = np.where(np.isnan(slack), 0.0, slack)
    span, near, far = np.concatenate(out_r), np.concatenate(out_n), np.concatenate(out_f)
    order = np.lexsort((aa, o))
    return _Panels(
        o[order], aa[order], bb[order], slack[order], span[order], near[order], far[order], lost
    )


def _pdf_range(
    law: JitterLaw | _Stretched, a: FloatArray, b: FloatArray, base: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """ln of the length times the largest and the least of the pdf at the ends and the
    middle of each piece [a, b] (tau = t - ``base``, clipped into the support): the pdf's
    part of :func:`_window_panels`' upper and lower bounds on the integrand (the least -inf
    on a piece that misses the support)."""
    lo, hi = law.support
    ends = (a, 0.5 * (a + b), b)
    pdf = np.array([_density(law, np.clip(v - base, lo, hi)) for v in ends])  # type: ignore[arg-type]
    with np.errstate(divide="ignore"):
        top = np.log((b - a) * pdf.max(axis=0))
        least = np.log((b - a) * pdf.min(axis=0))
    return top, np.where((b - base > lo) & (a - base < hi), least, -np.inf)


@dataclass(frozen=True, eq=False)
class _Nodes:
    """Quadrature of samples k0..k1-1: nodes t, ln weights, local owner, segment starts."""

    k0: int
    k1: int
    t: FloatArray
    logw: FloatArray
    owner: NDArray[np.int64]
    starts: NDArray[np.int64]
    signal: _NodeSignal
    logrule: FloatArray | None = None  # ln of the weights without the pdf (shape families)


#: the Chebyshev pieces of a law's density (:func:`_chebyshev_pieces`), kept while the law
#: lives: a likelihood evaluation asks for the density of one law some ten times
_PIECES: weakref.WeakKeyDictionary[JitterLaw, tuple[FloatArray, FloatArray]] = (
    weakref.WeakKeyDictionary()
)


def _chebyshev_pieces(law: JitterLaw, deg: int) -> tuple[FloatArray, FloatArray]:
    """(breakpoints on tau <= 0, Chebyshev coefficients of each interval's interpolant of
    degree ``deg`` at first-kind points of ``law.pdf``) for :func:`_density`."""
    try:
        return _PIECES[law]
    except (KeyError, TypeError):
        pass
    bp = np.asarray(law.breakpoints(), dtype=float)
    bp = bp[bp <= 0.0]
    if bp[-1] < 0.0:
        bp = np.r_[bp, 0.0]
    left, right = bp[:-1], bp[1:]
    cheb = np.cos(np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1))  # first-kind points
    pts = 0.5 * (left + right)[:, None] + 0.5 * (right - left)[:, None] * cheb[None, :]
    vals = law.pdf(pts)
    # Chebyshev coefficients of each interval's interpolant (discrete cosine transform)
    k = np.arange(deg + 1)
    T = np.cos(np.outer(k, np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1)))
    coef = vals @ T.T * (2.0 / (deg + 1))
    coef[:, 0] *= 0.5
    with contextlib.suppress(TypeError):  # (a law that cannot be weakly referenced: not kept)
        _PIECES[law] = (bp, coef)
    return bp, coef


def _density(law: JitterLaw, tau: FloatArray) -> FloatArray:
    """law.pdf(tau); for a law that declares :attr:`~jitterid.jitter.laws.JitterLaw.pdf_degree`
    (:class:`SumOfUniforms`) from its exact piecewise-polynomial form.

    Between consecutive breakpoints that density is a polynomial of degree at most deg (for
    m uniforms m - 1, plus one with the window of width 2c at non-integer n), which its
    Chebyshev interpolant at deg + 1 points of ``law.pdf`` reproduces to rounding (Clenshaw,
    per interval): O(deg) operations per point where the B-spline evaluation of ``law.pdf``
    costs O(m^2) and more (and a Gauss-Legendre window per point just above an integer n).
    The law is symmetric: like ``law.pdf`` it is evaluated at -|tau|.
    """
    deg = law.pdf_degree if isinstance(law, JitterLaw) else None  # None for a stand-in law
    if deg is None:
        return np.asarray(law.pdf(tau), dtype=float)
    bp, coef = _chebyshev_pieces(law, deg)
    x = -np.abs(np.asarray(tau, dtype=float))
    inside = x >= law.support[0]
    left, right = bp[:-1], bp[1:]
    i = np.clip(np.searchsorted(bp, x, side="right") - 1, 0, left.size - 1)
    u = np.clip((2.0 * x - (left[i] + right[i])) / (right[i] - left[i]), -1.0, 1.0)
    b1, b2 = np.zeros_like(u), np.zeros_like(u)
    for j in range(deg, 0, -1):
        b1, b2 = coef[i, j] + 2.0 * u * b1 - b2, b1
    out = coef[i, 0] + u * b1 - b2
    return np.where(inside, np.maximum(out, 0.0), 0.0)


class _UnitDensity:
    """A jitter law with its pdf replaced by 1: :func:`jitter_nodes` then returns the rule's
    own weights (panel half-length times Gauss-Legendre weight), to which the caller applies
    the pdf, and can apply another law's pdf at the same nodes."""

    def __init__(self, law: JitterLaw) -> None:
        self.law = law
        self.support, self.std = law.support, law.std

    def breakpoints(self) -> FloatArray:
        return np.asarray(self.law.breakpoints(), dtype=float)

    def pdf(self, tau: ArrayLike) -> FloatArray:
        return np.ones(np.shape(tau))


@dataclass(frozen=True, eq=False)
class _Eval:
    """ln p per sample and the posterior weights pi_j, standardised errors e_j = (y - s_j)/sigma."""

    nodes: _Nodes
    s: FloatArray
    e: FloatArray
    logp: FloatArray
    post: FloatArray


def _evaluate(
    nodes: _Nodes, s: FloatArray, y: FloatArray, sigma: float, logw: FloatArray | None = None
) -> _Eval:
    """ln p per sample and the posterior weights at the nodes (with other ln weights ``logw``
    if given)."""
    e = (y[nodes.k0 + nodes.owner] - s) / sigma
    z = (nodes.logw if logw is None else logw) - 0.5 * e * e
    top = np.maximum.reduceat(z, nodes.starts)
    ez = np.exp(z - top[nodes.owner])
    total = np.add.reduceat(ez, nodes.starts)
    logp = top + np.log(total) - np.log(sigma) - _LOG_SQRT_2PI
    return _Eval(nodes, s, e, logp, ez / total[nodes.owner])


def _second_block(
    second: tuple[FloatArray, FloatArray, FloatArray],
    tau: FloatArray,
    x: FloatArray,
    scale: int | None,
) -> FloatArray:
    """d^2 s at the nodes over (the jitter scale a, if any, then) the system parameters:
    with xi = tau / a, d^2 s / da^2 = xi^2 s'', d^2 s / da dtheta = xi ds'/dtheta."""
    hss, dslope, curv = second
    if scale is None:
        return hss
    xi = tau / x[scale]
    ns = hss.shape[0]
    out = np.empty((ns + 1, ns + 1, tau.size))
    out[1:, 1:] = hss
    out[0, 0] = xi**2 * curv
    out[0, 1:] = out[1:, 0] = xi * dslope
    return out


def _has_slope(sig: Signal, analytic: bool) -> bool:
    """Whether s'(t) is available at the nodes: from the modal form, or the signal's own."""
    return analytic or sig.has_slope


@dataclass(frozen=True, eq=False)
class _Pieces:
    """The windowed rule's pieces of samples k0..k1-1 (before a law's support and knots cut
    them), the design signal at their midpoints (the re-design test), and what sets the
    nodes of each under a law (:func:`_under`): its span and the Gaussian factor's part of
    the bounds on its integrand (``near``, ``far``), per sample the largest bound of a piece
    dropped (``lost``), and the nodes under the law they were built for (``estimate``: the
    memory check)."""

    k0: int
    k1: int
    owner: NDArray[np.int32]
    a: FloatArray
    b: FloatArray
    probe: FloatArray
    span: NDArray[np.float32]
    near: NDArray[np.float32]
    far: NDArray[np.float32]
    lost: NDArray[np.float32]
    estimate: int

    @property
    def mid(self) -> FloatArray:
        return 0.5 * (self.a + self.b)


def _piece_orders(slack: FloatArray, span: FloatArray, order: int, top: int) -> NDArray[np.int8]:
    """Gauss-Legendre nodes per windowed piece, from its span (the bound on the change of
    (y - s) / sigma over it, at the design's noise std) and its slack (how far, in ln, the
    bound on its integrand lies below the sample's best piece).

    ``_ORDER_TABLE`` holds the fewest nodes whose error on the Gaussian factor, centred
    anywhere outside the slack, is below 3e-11 of the sample's p (computed for spans 0.5,
    1, 2, 3, 4 and slacks 0, 4, 8, 16, 20); a piece takes the entry of the next larger span
    (its span stretched by 1 / ``_WINDOW_SIGMA_REDESIGN``: the noise std may fall that far
    before the rule is re-designed) and smaller slack, plus one node (an extremum of s makes
    the exponent quartic) and ``order - DEFAULT_ORDER``, within [3, ``top``] (tests: the
    rule against one with the panels quartered and twice the nodes)."""
    r = np.searchsorted(_ORDER_SPANS, span / _WINDOW_SIGMA_REDESIGN, side="left")
    c = np.searchsorted(_ORDER_SLACKS, slack, side="right") - 1
    inside = r < _ORDER_SPANS.size
    n = np.where(
        inside,
        _ORDER_TABLE[np.minimum(r, _ORDER_SPANS.size - 1), np.maximum(c, 0)]
        + 1
        + order
        - DEFAULT_ORDER,
        top,
    )
    return np.clip(n, 3, top).astype(np.int8)


class _Stretched:
    """The law of ``m + factor * (tau - m)``, m the law's mean: the windowed rule's pieces
    are built for it, so that they serve every scale of a family between 1 / 2 and 1 of it
    (about the mean: a law shifted by a delay stays inside). With ``flat`` (a law with knots
    inside its support, which move with its parameters) its knots are left out and its pdf is
    the constant ``flat`` on the stretched support: a bound on the pdf of every law that takes
    the pieces (:meth:`ExactLikelihood._window_pieces`), whose knots cut them at node time."""

    def __init__(self, law: JitterLaw, factor: float, flat: float | None = None) -> None:
        self.law, self.factor, self.flat = law, factor, flat
        self.centre = m = float(law.mean)
        lo, hi = law.support
        self.support = (m + (lo - m) * factor, m + (hi - m) * factor)
        self.std = float(law.std) * factor

    def breakpoints(self) -> FloatArray:
        if self.flat is not None:
            return np.array(self.support, dtype=float)
        bp = np.asarray(self.law.breakpoints(), dtype=float)
        return self.centre + (bp - self.centre) * self.factor

    def pdf(self, tau: ArrayLike) -> FloatArray:
        tau = np.asarray(tau, dtype=float)
        if self.flat is not None:
            lo, hi = self.support
            return np.where((tau >= lo) & (tau <= hi), self.flat, 0.0)
        inner = self.centre + (tau - self.centre) / self.factor
        return np.asarray(self.law.pdf(inner)) / self.factor


def _peak(law: JitterLaw) -> float:
    """The largest pdf of ``law`` at its knots and seven points inside each knot piece."""
    bp = np.asarray(law.breakpoints(), dtype=float)
    x = bp[:-1, None] + np.diff(bp)[:, None] * np.linspace(0.0, 1.0, 9)[None, :]
    return float(np.max(_density(law, x.ravel())))


class _Rule:
    """The quadrature nodes of every sample under one jitter law, chunk by chunk.

    Kept in memory after the first pass while they total at most ``budget`` nodes; beyond
    that (long records) they are made again, chunk by chunk, at every pass, from what the
    rule is built on (the windowed rule's ``pieces``, or the full rule's cuts), so that the
    memory of an evaluation is bounded independently of N."""

    def __init__(
        self, make: Callable[[], Iterator[_Nodes]], pieces: Sequence[_Pieces], budget: int
    ) -> None:
        self._make, self.pieces, self._budget = make, pieces, budget
        self._kept: list[_Nodes] | None = None

    @property
    def streamed(self) -> bool:
        """Whether the nodes are re-made at each pass (more than ``budget`` of them)."""
        return self._kept is None

    def __iter__(self) -> Iterator[_Nodes]:
        if self._kept is not None:
            yield from self._kept
            return
        kept: list[_Nodes] | None = []
        total = 0
        for nd in self._make():
            if kept is not None:
                total += nd.t.size
                if total <= self._budget:
                    kept.append(nd)
                else:
                    kept = None
            yield nd
        if kept is not None:
            self._kept = kept


def _cut_at_knots(
    index: NDArray[np.intp], a: FloatArray, b: FloatArray, base: FloatArray, knots: FloatArray
) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """The pieces [a, b] cut at the law's knots ``base + knots`` inside them (the pdf is a
    polynomial between its knots, which Gauss-Legendre must not straddle): the parts in the
    same order, each with its piece's ``index``. A knot within ~1e-9 of a piece's length (or
    a few roundings) of its ends cuts nothing (pieces built for the law itself end at its
    knots), nor does one within a rounding of the time of the knot before it."""
    if knots.size <= 2 or a.size == 0:
        return index, a, b
    tol = 1e-9 * (b - a) + 4.0 * np.spacing(np.abs(b))
    i0 = np.searchsorted(knots, a - base + tol, side="right")
    i1 = np.searchsorted(knots, b - base - tol, side="left")
    cuts = np.maximum(i1 - i0, 0)
    if not np.any(cuts):
        return index, a, b
    parts = cuts + 1
    parent = np.repeat(np.arange(a.size), parts)
    pos = np.arange(parent.size) - np.repeat(np.cumsum(parts) - parts, parts)
    k = i0[parent] + pos  # the knot that ends each part (but the last)
    left = np.where(pos == 0, a[parent], base[parent] + knots[np.maximum(k - 1, 0)])
    right = np.where(
        pos == cuts[parent], b[parent], base[parent] + knots[np.minimum(k, knots.size - 1)]
    )
    live = right > left  # (knots closer than a rounding of the time: one part)
    return index[parent][live], left[live], right[live]


_Bounds = tuple[FloatArray, FloatArray]  # a chunk's pieces' upper bounds, its samples' best


def _bounds(law: JitterLaw, pc: _Pieces, T: float) -> _Bounds:
    """Every piece's upper bound on its integrand under ``law`` (:func:`_window_panels`'
    bounds, with this law's pdf) and per sample the best piece's lower bound."""
    top, least = _pdf_range(law, pc.a, pc.b, np.asarray((pc.k0 + pc.owner) * T, dtype=float))
    best = np.full(pc.k1 - pc.k0, -np.inf)
    np.maximum.at(best, pc.owner, least + pc.far)
    return top + pc.near, best


def _serves(
    law: JitterLaw, pieces: Sequence[_Pieces], T: float, keep: bool
) -> list[_Bounds | None] | None:
    """Whether pieces built for another law serve ``law``: in every sample the pieces
    dropped at the build lie below e^-(``_WINDOW_CUT`` - ``_WINDOW_LOST``) of the best
    piece under this law (a law narrower than the build's, whose support barely reaches
    where a sample's signal meets it, may have its mass where the build dropped the pieces).
    Returns, if they do, the bounds under this law (:func:`_bounds`, per chunk; with ``keep``
    only, else None each: a long record's, made again chunk by chunk), else None."""
    out: list[_Bounds | None] = []
    for pc in pieces:
        upper, best = _bounds(law, pc, T)
        if not np.all(pc.lost < best - _WINDOW_CUT + _WINDOW_LOST):
            return None
        out.append((upper, best) if keep else None)
    return out


def _under(
    law: JitterLaw,
    pc: _Pieces,
    T: float,
    order: int,
    bounds: _Bounds | None = None,
) -> tuple[NDArray[np.int64], FloatArray, FloatArray, NDArray[np.int8]]:
    """The parts of the pieces ``pc`` under ``law``, and the Gauss-Legendre nodes of each:
    :func:`_window_panels`' test and :func:`_piece_orders`' choice made again with this
    law's pdf in the bounds (a piece below e^-``_WINDOW_CUT`` of its sample's best is
    dropped), then each piece cut to the law's support and at its knots (the pdf is a
    polynomial between them: Gauss-Legendre must not straddle one), a part taking its
    share of its piece's span and bound (``bounds``: :func:`_bounds`, if made already).
    Returns (owner, a, b, nodes)."""
    lo, hi = law.support
    upper, best = _bounds(law, pc, T) if bounds is None else bounds
    with np.errstate(invalid="ignore"):
        slack = best[pc.owner] - upper
    slack = np.where(np.isnan(slack), 0.0, slack)  # (see _window_panels)
    base = np.asarray((pc.k0 + pc.owner) * T, dtype=float)
    a, b = np.maximum(pc.a, base + lo), np.minimum(pc.b, base + hi)
    live = np.flatnonzero((upper >= best[pc.owner] - _WINDOW_CUT) & (b > a))
    knots = np.asarray(law.breakpoints(), dtype=float)
    i, a, b = _cut_at_knots(live, a[live], b[live], base[live], knots)
    share = (b - a) / (pc.b[i] - pc.a[i])
    top = min(order + _WINDOW_EXTRA_ORDER, 127)
    nodes = _piece_orders(slack[i] - np.log(share), pc.span[i] * share, order, top)
    return pc.owner[i].astype(np.int64), a, b, nodes


@functools.cache
def _legendre_table(top: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and weights on [-1, 1] for 0..top nodes: row n holds the n-node
    rule in its first n columns (zeros after)."""
    xg, wg = np.zeros((top + 1, top)), np.zeros((top + 1, top))
    for n in range(1, top + 1):
        xg[n, :n], wg[n, :n] = np.polynomial.legendre.leggauss(n)
    return xg, wg


# pieces kept for nearby laws, with their envelope's (support, std, flat pdf or None)
_Held = tuple[tuple[float, float, float, float | None], list[_Pieces]]


def _takes(
    envelope: tuple[float, float, float, float | None], law: JitterLaw, knotted: bool
) -> bool:
    """Whether pieces built for ``envelope`` (support, std and flat pdf or None: the law
    stretched, :class:`_Stretched`) serve ``law``: its support inside the envelope's, its std
    at least half the envelope's, and its pdf below the envelope's, which kept the pieces: a
    flat envelope's value bounds the law's largest pdf (:func:`_peak`); a stretched law
    bounds a stretched scale of it within a factor 2 (a law with no knots inside its support:
    a scale family's)."""
    lo, hi = law.support
    blo, bhi, bstd, flat = envelope
    if not (blo <= lo and hi <= bhi and float(law.std) >= 0.5 * bstd):
        return False
    return not knotted if flat is None else _peak(law) <= flat


def _far(pieces: Sequence[_Pieces], y: FloatArray, sigma: float) -> bool:
    """Whether in more than ``_FAR_FRACTION`` of the samples no windowed piece comes within
    ``_FAR`` noise std's of y_k (at its midpoint, at the design)."""
    far = total = 0
    for pc in pieces:
        d = np.abs(y[pc.k0 + pc.owner] - pc.probe) / sigma
        starts = np.flatnonzero(np.r_[True, pc.owner[1:] != pc.owner[:-1]])
        far += int(np.count_nonzero(np.minimum.reduceat(d, starts) > _FAR))
        total += starts.size
    return far > _FAR_FRACTION * max(total, 1)


def _fits(rule: _Rule, design: tuple[Signal, float] | None, sig: Signal, sigma: float) -> bool:
    """Whether a windowed rule designed at ``design`` (signal, noise std) serves ``sig`` and
    ``sigma``: the noise std within a factor ``_WINDOW_SIGMA_REDESIGN`` of the design's
    (below, the pieces would be too long; above, the windows too narrow) and the signal
    moved by at most ``_WINDOW_MARGIN / 2`` noise std's at every piece's midpoint."""
    if design is None:
        return False
    d_sigma = design[1]
    if not _WINDOW_SIGMA_REDESIGN * d_sigma <= sigma <= d_sigma / _WINDOW_SIGMA_REDESIGN:
        return False
    limit = 0.5 * _WINDOW_MARGIN * d_sigma
    return all(
        np.max(np.abs(_NodeSignal(sig, pc.mid)(sig) - pc.probe), initial=0.0) <= limit
        for pc in rule.pieces
    )


# ---------------------------------------------------------------------------- the likelihood
@dataclass(eq=False)
class ExactLikelihood(CachesAreNotState):
    """The exact log-likelihood (L1) of N jittered samples as a function of the parameters.

    Parameters
    ----------
    structure : Model or TransferFunction
        Model (an LTI structure, a signal model), or a known system (no system parameters).
    jitter : JitterLaw or JitterFamily
        Known jitter law, or a family whose parameters are estimated.
    u : Input or None
        The known input (None for a signal model with no input).
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    noise_std : float or None
        Known measurement-noise std (> 0); ``None`` makes it the last parameter.
    order : int
        Gauss-Legendre nodes per panel (default 8).
    panel : float
        Panel length at most ``panel * sigma_v / |s'|`` (default 4; see the module doc).
    window : bool or None
        The windowed rule (module doc): True, False, or None (default: where the full
        rule would have more than ``_WINDOW_FROM`` panels per sample). Where the model is
        far from the data (a quarter of the samples more than 10 noise std's from it), the
        full rule is used instead.
    noise_floor : float or None
        Lower bound of an estimated noise std (``SampledData.resolution``); default 1e-12.
    node_budget : int
        Most quadrature nodes kept in memory between evaluations (default
        ``NODE_BUDGET``, ~50 bytes each); a rule with more is made again chunk by chunk at
        every evaluation (streamed), so that memory stays bounded whatever N.

    Attributes
    ----------
    names : tuple of str
        Parameter order: jitter-family parameters, system parameters, then ``noise_std``
        if it is estimated (the order of :func:`jitterid.fit`).
    bounds : tuple of (float, float)
        Closed bounds of each parameter.

    Notes
    -----
    The quadrature rule is designed at the first parameter vector evaluated (or by
    :meth:`design`) and then frozen: evaluations far from there are less accurate.

    Examples
    --------
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(5.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=40, noise_std=0.01, rng=2)
    >>> lik = ji.ExactLikelihood(ji.RationalModel(0, 1), ji.Uniform(0.05), u, 0.1, 40, 0.01)
    >>> lik.names
    ('b0', 'a0')
    >>> lik.logpdf([2.0, 2.0], data.y).shape
    (40,)
    """

    structure: Model | TransferFunction
    jitter: JitterLaw | JitterFamily
    u: Input | None
    T: float
    N: int
    noise_std: float | None = None
    order: int = DEFAULT_ORDER
    panel: float = DEFAULT_PANEL
    window: bool | None = None
    noise_floor: float | None = None
    node_budget: int = NODE_BUDGET
    layout: ParamLayout = field(init=False, repr=False)
    _cuts: FloatArray | None = field(init=False, default=None, repr=False)
    _chunk: int = field(init=False, default=_CHUNK, repr=False)  # samples per full-rule chunk
    _profile: _SlopeProfile | None = field(init=False, default=None, repr=False)
    _design: tuple[Signal, float] | None = field(init=False, default=None, repr=False)
    _window_y: FloatArray | None = field(init=False, default=None, repr=False)
    # caches (what _forget drops): made again from the design when needed, never pickled
    # (cache_field returns a dataclasses.Field, which RUF009 does not know)
    _pieces: _Held | None = cache_field()  # noqa: RUF009
    _cache: dict[tuple[float, ...], _Rule] = cache_field(default_factory=dict)  # noqa: RUF009
    _memo: tuple[bytes, bool, FloatArray, tuple[FloatArray, FloatArray, FloatArray]] | None = (
        cache_field()
    )
    _spares: list[
        tuple[tuple[Signal, float] | None, _Held | None, dict[tuple[float, ...], _Rule]]
    ] = cache_field(default_factory=list)  # noqa: RUF009
    _box: tuple[tuple[float, float], ...] | None = cache_field()  # restrict
    _stepping: bool = cache_field(default=False)  # inside maximise's Newton steps
    _designed_at: FloatArray | None = cache_field()  # noqa: RUF009  (the full rule's: serve)

    def __post_init__(self) -> None:
        self.structure = as_structure(self.structure)
        if not isinstance(self.jitter, (JitterLaw, JitterFamily)):
            raise TypeError(
                "jitter must be a jitter law (Uniform(a), Gaussian(sigma), ...) or a family "
                f"(SumOfUniformsFamily(), ...); got {type(self.jitter).__name__}"
            )
        if self.u is not None and not isinstance(self.u, Input):
            raise TypeError(f"u must be a jitterid input or None; got {type(self.u).__name__}")
        self.T = sampling_interval(self.T, "T")
        self.N = count(self.N, "N", minimum=1)
        if self.noise_std is not None:
            self.noise_std = positive(self.noise_std, "noise_std")
        self.order = count(self.order, "order", minimum=1)
        self.panel = positive(self.panel, "panel")
        self.layout = ParamLayout.build(
            self.jitter,
            self.structure,
            noise_std=self.noise_std is None,
            noise_floor=self.noise_floor,
        )

    # -------------------------------------------------------------- parameters and rule
    @property
    def names(self) -> tuple[str, ...]:
        return self.layout.names

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """The bounds searched: the layout's, or the piece set by :meth:`restrict`."""
        return self.layout.bounds if self._box is None else self._box

    def restrict(self, bounds: tuple[tuple[float, float], ...] | None) -> None:
        """Search within ``bounds`` (a smooth piece of a kinked parameter), or the layout's
        own with None; the remembered scores (one-sided at a piece's end) are dropped.

        Parameters
        ----------
        bounds : tuple of (float, float) or None
            One closed interval per parameter, inside the layout's; None lifts it.
        """
        self._box = None if bounds is None else tuple(bounds)
        self._memo = None

    @property
    def model(self) -> Model:
        """The model (a known system is wrapped in a KnownSystem)."""
        assert isinstance(self.structure, Model)
        return self.structure

    @property
    def windowed(self) -> bool:
        """Whether the rule designed is the windowed one (module doc, "Windows"): it is
        re-designed wherever it no longer fits, so it needs no re-design at an optimum."""
        return self._design is not None

    def release(self) -> None:
        """Drop the rule (its design, pieces, nodes and remembered pass: hundreds of MB on a
        long record); the next evaluation designs it afresh."""
        self._cuts = self._design = self._profile = self._window_y = None
        self._designed_at = None
        self._forget()

    def serve(self, x: ArrayLike) -> None:
        """Make the rule serve ``x``, a point away from the last evaluations (a check's start
        far off, the estimate after such starts). A windowed rule re-designs itself wherever
        it no longer fits; the full rule is frozen where it was designed, so that a search's
        criterion stays smooth along its path, and does not serve a point far off (its panels
        were cut for another signal's slopes: measured, -2 ln L 135 off at an estimate after
        a comparison with far starts, noise std 1e-6): it is designed at ``x`` unless it was
        designed there.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        x = np.atleast_1d(real_array(x, "x"))
        if self._design is not None:
            return
        if self._designed_at is not None and np.array_equal(self._designed_at, x):
            return
        self.design(x)

    def _forget(self) -> None:
        """Drop what was made under the current design: the rules, the pieces kept for
        nearby scales, the spare designs and the remembered pass."""
        self._cache, self._pieces, self._spares, self._memo = {}, None, [], None

    def _full_cuts(self, law: JitterLaw, sig: Signal, sigma: float) -> None:
        """The full rule's slope cuts for noise std ``sigma``, and its chunk size, once its
        memory is checked (before any node is built)."""
        self._cuts = _panel_cuts(self._profile, sigma, self.panel)
        self._chunk = check_likelihood(self, law, sig)

    def leading(self, n: int) -> ExactLikelihood:
        """The likelihood of the first ``n`` samples alone, with the same model and options
        (a cheap screen of points far from an estimate: :mod:`jitterid.estimation.checks`).

        Parameters
        ----------
        n : int
            Number of leading samples, 1 <= n <= N.
        """
        n = count(n, "n", minimum=1)
        if n > self.N:
            raise ValueError(f"n must be at most N = {self.N}; got {n}")
        return ExactLikelihood(
            self.structure,
            self.jitter,
            self.u,
            self.T,
            n,
            self.noise_std,
            order=self.order,
            panel=self.panel,
            window=self.window,
            noise_floor=self.noise_floor,
            node_budget=self.node_budget,
        )

    def with_noise(self, noise_std: float) -> ExactLikelihood:
        """The likelihood of the same samples with another known noise std (a continuation
        from a smoother likelihood: :mod:`jitterid.estimation.ml`), same model and options.

        Parameters
        ----------
        noise_std : float
            The measurement-noise std, > 0.
        """
        return ExactLikelihood(
            self.structure,
            self.jitter,
            self.u,
            self.T,
            self.N,
            noise_std,
            order=self.order,
            panel=self.panel,
            window=self.window,
            noise_floor=self.noise_floor,
            node_budget=self.node_budget,
        )

    @property
    def n_jitter(self) -> int:
        return count_params(self.jitter)

    def split(self, x: ArrayLike) -> tuple[JitterLaw, Signal, float]:
        """(jitter law, signal s(t; theta), noise std) at parameter vector ``x``.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        x = np.atleast_1d(real_array(x, "x"))
        if x.shape != (len(self.names),):
            raise ValueError(f"x must hold {len(self.names)} values {self.names}; got {x.shape}")
        lay = self.layout
        law = (
            self.jitter.law(lay.block(x, "jitter").tolist())
            if isinstance(self.jitter, JitterFamily)
            else self.jitter
        )
        sigma = float(x[-1]) if self.noise_std is None else self.noise_std
        if not sigma > 0:
            raise ValueError(f"noise_std must be > 0 for the likelihood; got {sigma!r}")
        law, sig = self.model.signal(lay.block(x, "system"), self.u).jitter_equivalent(law)
        if self.model.param_names:  # a searched model: no modes the samples cannot see
            check_mode_rate(sig, self.T)
        return law, sig, sigma

    def design(self, x: ArrayLike) -> None:
        """(Re-)design the quadrature rule for the signal and noise level at ``x``.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        law, sig, sigma = self.split(x)
        lo, hi = law.support
        width = hi - lo
        span = (lo - width, (self.N - 1) * self.T + hi + width)
        profile = _slope_profile(sig, span)
        self._profile, self._cuts, self._design = profile, None, None
        self._designed_at = None
        if self._windowed(profile, law, sig, sigma, span):
            self._design = (sig, sigma)
        else:
            self._full_cuts(law, sig, sigma)
            self._designed_at = np.atleast_1d(np.array(x, dtype=float))
        self._forget()

    def _windowed(
        self,
        profile: _SlopeProfile | None,
        law: JitterLaw,
        sig: Signal,
        sigma: float,
        span: tuple[float, float],
    ) -> bool:
        """Whether the windowed rule is used: as asked by :attr:`window`, else when the full
        rule would have more than ``_WINDOW_FROM`` panels per sample."""
        if self.window is not None:
            return bool(self.window) and profile is not None
        if profile is None:
            return False
        lo, hi = law.support
        per_sample = (
            profile.cumulative()[-1] / (self.panel * sigma) * (hi - lo) / (span[1] - span[0])
        )
        return bool(per_sample > _WINDOW_FROM)

    def _nodes(
        self,
        x: FloatArray,
        law: JitterLaw,
        sig: Signal,
        y: FloatArray | None = None,
        sigma: float | None = None,
    ) -> _Rule:
        """The rule at ``x``: windowed around the samples ``y`` where the design says so
        (``y = None`` asks for the full rule: the Fisher information's y-grid). A windowed
        rule is re-designed at ``x`` when the signal there has moved from the design's by
        more than ``_WINDOW_MARGIN / 2`` noise std's at a piece's midpoint, or the noise std
        ``sigma`` left [0.8, 1.25] of the design's (:func:`_fits`); the last
        ``_SPARE_DESIGNS`` designs are kept and taken back where they fit (a check at a
        start far off, then back at the estimate, re-designs once, not twice). Within
        :meth:`maximise`'s steps a noise std below ``_WINDOW_SIGMA_STEP`` of the design's
        is refused (ValueError: the search's step is rejected and shortened), so that one
        trial step towards noise_std = 0 does not re-design the rule for a vanishing noise;
        any other evaluation there (the covariance at an estimate after a comparison with
        starts far off, whose larger noise std re-designed the rule) re-designs it, as
        everywhere else."""
        if self._cuts is None and self._design is None:
            self.design(x)
        if self._design is not None:
            if y is None:  # the full rule, not cached
                if self._cuts is None:
                    self._full_cuts(law, sig, self._design[1])
                return self._rule(law, sig, None)
            if self._window_y is None or not np.array_equal(self._window_y, y):
                self._forget()
                self._window_y = np.array(y, dtype=float)
        key = (*self.layout.block(x, "jitter"), law.mean)  # a delay shifts the law (Delayed)
        windowed = self._design is not None and y is not None
        if key not in self._cache:
            if len(self._cache) > 16:
                self._cache = {}
            self._cache[key] = self._rule(law, sig, y if windowed else None)
        rule = self._cache[key]
        if windowed and self._design is not None and sigma is not None:
            assert self._design is not None
            d_sigma = self._design[1]
            if self._stepping and sigma < _WINDOW_SIGMA_STEP * d_sigma:
                raise ValueError(
                    f"noise_std = {sigma:.3g} is below {_WINDOW_SIGMA_STEP:g} of the windowed "
                    f"rule's design ({d_sigma:.3g}); a search takes a shorter step (re-design "
                    "the rule there to evaluate it: design(x))"
                )
            if not _fits(rule, self._design, sig, sigma):
                self._memo = None  # a value remembered under another rule
                current = (self._design, self._pieces, self._cache)
                spare = next(
                    (
                        sp
                        for sp in self._spares
                        if key in sp[2] and _fits(sp[2][key], sp[0], sig, sigma)
                    ),
                    None,
                )
                # kept only while small (a long record's pieces are ~40 bytes each)
                small = sum(pc.owner.size for pc in rule.pieces) <= self.node_budget // 4
                rest = [sp for sp in self._spares if sp is not spare]
                self._spares = ([current] if small else []) + rest
                del self._spares[_SPARE_DESIGNS:]
                if spare is not None:  # back at an earlier design (e.g. after a check far off)
                    self._design, self._pieces, self._cache = spare
                    rule = self._cache[key]
                else:
                    self._design, self._pieces, self._cache = (sig, sigma), None, {}
                    rule = self._cache[key] = self._rule(law, sig, y)
        return rule

    def _rule(self, law: JitterLaw, sig: Signal, y: FloatArray | None) -> _Rule:
        """The rule under ``law``: windowed around ``y`` (its pieces made now), or full."""
        family = isinstance(self.jitter, JitterFamily)
        budget = kept_nodes(self.node_budget, family)
        if y is None:
            return _Rule(lambda: self._make_nodes(law, sig), (), budget)
        pieces, bounds = self._window_pieces(law, sig, y)
        assert self._design is not None
        if _far(pieces, y, self._design[1]):
            # the model far from the data (residuals of many noise std's): the integrands
            # are their Gaussian factors' far tails, where the windows would move with every
            # step of a search; the full rule, frozen, keeps the criterion smooth there
            sigma = self._design[1]
            self._design, self._pieces, self._spares, self._memo = None, None, [], None
            self._designed_at = None  # (not where the search will be: serve re-designs)
            self._full_cuts(law, sig, sigma)
            return _Rule(lambda: self._make_nodes(law, sig), (), budget)
        if self.N >= _TRIM_FROM:  # the build's temporaries: pages back to the system
            trim()
        n_pieces = sum(pc.owner.size for pc in pieces)
        n_nodes = float(sum(pc.estimate for pc in pieces))
        check_likelihood(self, law, sig, n_nodes, n_pieces)
        return _Rule(lambda: self._make_windowed(law, sig, pieces, bounds), pieces, budget)

    def _window_pieces(
        self, law: JitterLaw, sig: Signal, y: FloatArray
    ) -> tuple[list[_Pieces], list[_Bounds | None] | None]:
        """The windowed rule's pieces for ``law``: kept from the last build where that was
        made for an envelope whose support holds this law's, whose std is at most twice this
        law's and whose pdf bounds this law's (:func:`_takes`); else built
        (:func:`_window_panels`) for an envelope of the law (:class:`_Stretched`), so that
        nearby laws of a family reuse them: the law stretched by ``_WINDOW_STRETCH`` (a law
        with no knots inside its support), or its stretched support with a flat pdf
        ``_FLAT_PEAK`` times the law's largest (a law whose knots move with its parameters,
        which cut the pieces at node time: :meth:`_make_windowed`). A law with knots that
        cannot move (a known law, no delay) gets pieces of its own, cut at its knots."""
        knotted = np.asarray(law.breakpoints()).size > 2
        held = self._pieces
        if held is not None and _takes(held[0], law, knotted):
            small = sum(pc.owner.size for pc in held[1]) <= self.node_budget // 4
            bounds = _serves(law, held[1], self.T, small)
            if bounds is not None:
                return held[1], bounds
        assert self._design is not None
        assert self._profile is not None
        design_sig, design_sigma = self._design
        moving = isinstance(self.jitter, JitterFamily) or self._delay is not None
        build: JitterLaw | _Stretched = law
        if not knotted:
            build = _Stretched(law, _WINDOW_STRETCH)
        elif moving:
            build = _Stretched(law, _WINDOW_STRETCH, flat=_FLAT_PEAK * _peak(law))
        knots = np.unique(np.asarray(build.breakpoints(), dtype=float))
        fixed = np.union1d(np.asarray(sig.breaks, dtype=float), self._profile.grid)
        pieces = []
        top = min(self.order + _WINDOW_EXTRA_ORDER, 127)  # int8 node counts
        for pch in jitter_panels(law, self.T, self.N, fixed, knots, chunk=_CHUNK):
            pan = _window_panels(
                pch, self.T, y, design_sig, design_sigma, self.panel, self._profile, law, build
            )
            estimate = np.sum(_piece_orders(pan.slack, pan.span, self.order, top), dtype=np.int64)
            pieces.append(
                _Pieces(
                    pch.k0,
                    pch.k1,
                    pan.owner.astype(np.int32),
                    pan.a,
                    pan.b,
                    design_sig(0.5 * (pan.a + pan.b)),
                    pan.span.astype(np.float32),
                    pan.near.astype(np.float32),
                    pan.far.astype(np.float32),
                    pan.lost.astype(np.float32),
                    int(estimate),
                )
            )
        if isinstance(build, _Stretched):
            blo, bhi = build.support
            self._pieces = ((float(blo), float(bhi), float(build.std), build.flat), pieces)
        else:
            self._pieces = None
        return pieces, None

    def _make_windowed(
        self,
        law: JitterLaw,
        sig: Signal,
        pieces: list[_Pieces],
        bounds: list[_Bounds | None] | None = None,
    ) -> Iterator[_Nodes]:
        """The windowed rule's nodes (module doc): its pieces (:meth:`_window_pieces`) under
        the law (:func:`_under`: re-tested with its pdf, cut to its support and at its knots),
        with :func:`_piece_orders` Gauss-Legendre nodes each (``bounds``: the pieces' bounds
        under the law, made by the reuse test, :func:`_serves`)."""
        sig.check_covers((self.N - 1) * self.T + law.support[1], "the last jittered instant")
        lo, hi = law.support
        split = bool(self._weight_params()) and hi > lo
        clip = rule_frame(law)[2]
        for j, pc in enumerate(pieces):
            known = None
            if bounds is not None:  # made by the reuse test: used once (a pass that streams
                known, bounds[j] = bounds[j], None  # the rule makes them again)
            o, a, b, n = _under(law, pc, self.T, self.order, known)
            half, mid = 0.5 * (b - a), 0.5 * (a + b)
            # each piece's n nodes in a row (ragged): piece index and position of each node
            n = n.astype(np.intp)
            piece = np.repeat(np.arange(n.size), n)
            pos = np.arange(piece.size) - np.repeat(np.cumsum(n) - n, n)
            nn = n[piece]
            xg, wg = _legendre_table(min(self.order + _WINDOW_EXTRA_ORDER, 127))
            t = mid[piece] + half[piece] * xg[nn, pos]
            gw = half[piece] * wg[nn, pos]
            owner = o[piece]
            segment = None
            seg = sig.modal_segments
            if seg is not None:
                segment = (np.searchsorted(seg.u.times, mid, side="right") - 1)[piece]
            tau = t - (pc.k0 + owner) * self.T
            w = gw * _density(law, np.clip(tau, *clip))
            keep = w > 0
            owner = owner[keep]
            starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
            if starts.size != pc.k1 - pc.k0:
                raise ValueError(
                    "the jitter pdf vanishes at every quadrature node of some sample; check "
                    "that the jitter law has positive density inside its support"
                )
            tk = t[keep]
            logrule = np.log(gw[keep]) if split else None
            yield _Nodes(
                pc.k0,
                pc.k1,
                tk,
                np.log(w[keep]),
                owner,
                starts,
                _NodeSignal(sig, tk, None if segment is None else segment[keep]),
                logrule,
            )

    def _make_nodes(self, law: JitterLaw, sig: Signal) -> Iterator[_Nodes]:
        sig.check_covers((self.N - 1) * self.T + law.support[1], "the last jittered instant")
        assert self._cuts is not None
        breaks = np.concatenate([sig.breaks, self._cuts])
        lo, hi = law.support
        # With shape parameters (differenced by moving the weights alone, see _terms) the
        # rule's weights are kept apart from the pdf.
        split = bool(self._weight_params()) and hi > lo
        rule = _UnitDensity(law) if split else law
        for ch in jitter_nodes(
            rule,  # type: ignore[arg-type]
            self.T,
            self.N,
            breaks,
            sig.rate,
            order=self.order,
            chunk=self._chunk,
            shared_pdf=True,
        ):
            w = ch.w
            if split:  # the pdf at tau clipped into the support, as jitter_nodes takes it
                tau = ch.t - (ch.k0 + ch.owner) * self.T
                w = ch.w * _density(law, np.clip(tau, lo, hi))
            keep = w > 0
            owner = ch.owner[keep]
            starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
            if starts.size != ch.k1 - ch.k0:
                raise ValueError(
                    "the jitter pdf vanishes at every quadrature node of some sample; check "
                    "that the jitter law has positive density inside its support"
                )
            t = ch.t[keep]
            logrule = np.log(ch.w[keep]) if split else None
            yield _Nodes(
                ch.k0, ch.k1, t, np.log(w[keep]), owner, starts, _NodeSignal(sig, t), logrule
            )

    def _evals(self, x: FloatArray, y: FloatArray) -> Iterator[_Eval]:
        law, sig, sigma = self.split(x)
        for nd in self._nodes(x, law, sig, y, sigma):
            yield _evaluate(nd, nd.signal(sig), y, sigma)

    def _data(self, y: ArrayLike) -> FloatArray:
        y = real_array(y, "y", ndim=1)
        if y.size != self.N:
            raise ValueError(f"y must hold N = {self.N} samples; got {y.size}")
        return y

    # -------------------------------------------------------------- values and derivatives
    def logpdf(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """ln p(y_k | x) for every sample, eq. (L1); shape (N,).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        y : array_like, shape (N,)
            The samples.
        """
        x, y = np.atleast_1d(real_array(x, "x")), self._data(y)
        out = np.empty(self.N)
        for ev in self._evals(x, y):
            out[ev.nodes.k0 : ev.nodes.k1] = ev.logp
        return out

    def loglik(self, x: ArrayLike, y: ArrayLike) -> float:
        """sum_k ln p(y_k | x).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        y : array_like, shape (N,)
            The samples.
        """
        return float(np.sum(self.logpdf(x, y)))

    def dlogpdf_dy(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """d ln p(y_k | x) / d y_k for every sample, eq. (L2); shape (N,).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        y : array_like, shape (N,)
            The samples.
        """
        x, y = np.atleast_1d(real_array(x, "x")), self._data(y)
        _, _, sigma = self.split(x)
        out = np.empty(self.N)
        for ev in self._evals(x, y):
            nd = ev.nodes
            out[nd.k0 : nd.k1] = -np.add.reduceat(ev.post * ev.e, nd.starts) / sigma
        return out

    def scores(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """ln p(y_k | x), shape (N,), and the per-sample scores d ln p(y_k) / dx, shape (N, p).

        System parameters by (L2) with ds/dtheta from the modal form, or the signal's own
        gradient (a steady-state multisine response), else forward differences of s
        (relative step 1e-7), noise std
        analytic, jitter-family parameters from the family's closed-form dp/dtheta where it
        gives one (``JitterFamily.pdf_gradient``), else by forward differences of ln p (step
        1e-7).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        y : array_like, shape (N,)
            The samples.
        """
        x, y = np.atleast_1d(real_array(x, "x")), self._data(y)
        logp, G, _ = self._terms(x, y, information=False)
        return logp, G

    def analytic_scores(self, x: ArrayLike) -> bool:
        """Whether every parameter's score at ``x`` is analytic ((L2) with ds/dtheta from
        the modal form or the model's gradient, the jitter scale from the slope, the noise
        std in closed form): no forward difference inside the score.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        return not self.differenced_scores(x)

    def differenced_scores(self, x: ArrayLike) -> tuple[int, ...]:
        """The parameters (indices in :attr:`names` order) whose score at ``x`` holds a
        difference (every one where the system's ds/dtheta is differenced; else the jitter
        family's parameters but its scale that its ``pdf_gradient`` does not give, nor its
        ``scale_equivalent`` on a kink); empty where :meth:`analytic_scores`.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        x = np.atleast_1d(real_array(x, "x"))
        _, sig, _ = self.split(x)
        analytic = _NodeSignal(sig, np.zeros(0)).analytic
        ns = len(self.model.param_names)
        if ns and not (analytic or sig.has_gradient):
            return tuple(range(x.size))
        scale = self._scale_index(_has_slope(sig, analytic))
        return tuple(self._shape_routes(x, scale)[2])

    def exact_information(self, x: ArrayLike) -> bool:
        """Whether :meth:`_terms`' information at ``x`` is the exact observed information
        (L5): every score analytic, the signal's second derivatives in closed form, and no
        jitter parameter but a scale (a shape's block is BHHH).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        """
        if not self.analytic_scores(x):
            return False
        x = np.atleast_1d(real_array(x, "x"))
        _, sig, _ = self.split(x)
        if _NodeSignal(sig, np.zeros(0)).analytic:
            return False  # the modal path: Gauss-Newton
        if not len(self.model.param_names):
            return False
        probe = sig.second_derivatives(np.zeros(1))
        return probe is not None and self.n_jitter <= 1

    def information(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """The observed information -d^2 ln L at ``x`` as :meth:`_terms` computes it (exact
        where :meth:`exact_information` says so).

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        y : array_like, shape (N,)
            The samples.
        """
        x, y = np.atleast_1d(real_array(x, "x")), self._data(y)
        return self._terms(x, y, information=True)[2]

    def _scale_index(self, analytic: bool) -> int | None:
        """Index of the jitter family's scale parameter a (the law of a xi, xi fixed), whose
        score is analytic (:meth:`_terms`); None if there is none or the signal's slope is
        not available (then it is differenced like the shape parameters)."""
        if not (analytic and self.n_jitter) or self._delay is not None:
            return None  # a delayed model's law is shifted: not a xi (differenced)
        return self.jitter.scale_index  # type: ignore[union-attr]

    @property
    def _delay(self) -> int | None:
        """Index of the input-output delay in the parameter vector
        (:class:`jitterid.Delayed`), or None."""
        i = getattr(self.model, "delay_index", None)
        return None if i is None else self.n_jitter + i

    def _weight_params(self) -> tuple[int, ...]:
        """Jitter-family parameters that move the pdf inside a fixed support (the family's
        ``fixed_support_params``: n of SumOfUniformsFamily), differenced at the same nodes.
        Any other parameter of a family without an analytic score is differenced with new
        nodes (it may move the support, whose edges then carry part of the derivative)."""
        return tuple(getattr(self.jitter, "fixed_support_params", ()))

    def _shape_routes(
        self, x: FloatArray, scale: int | None
    ) -> tuple[list[int], dict[int, float], list[int]]:
        """The jitter parameters other than the analytic ``scale``, by the route of their
        score: (closed form from ``pdf_gradient``, ``{i: r}`` on a kink where the forward
        difference would step up (r x the scale's score,
        :meth:`~jitterid.JitterFamily.scale_equivalent`), forward differences)."""
        rest = [i for i in range(self.n_jitter) if i != scale]
        if self._pdf_gradient(x):
            return rest, {}, []
        above: dict[int, float] = {}
        if scale is not None and rest:
            fam = self.jitter
            assert isinstance(fam, JitterFamily)
            theta = self.layout.block(x, "jitter").tolist()
            for i in rest:
                r = fam.scale_equivalent(theta, i)
                up = x[i] + finite_diff.step(x, i, _SCORE_STEP) <= self.bounds[i][1]
                if r is not None and up:
                    above[i] = r
        return [], above, [i for i in rest if i not in above]

    def _pdf_gradient(self, x: FloatArray) -> bool:
        """Whether the jitter family gives dp/dtheta in closed form (``pdf_gradient``)."""
        if not self.n_jitter or self._delay is not None:
            return False  # a delayed model's law is the family's shifted (differenced)
        fam = self.jitter
        assert isinstance(fam, JitterFamily)
        return fam.gives_pdf_gradient(self.layout.block(x, "jitter").tolist())

    def _terms(
        self, x: FloatArray, y: FloatArray, *, information: bool
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`_compute_terms`, remembered for the last point: the search's last
        evaluation, the covariance's scale and its score at the estimate are one pass (a
        pass over a long record's nodes costs seconds). The arrays are shared: read only."""
        key, memo = x.tobytes(), self._memo
        if (
            memo is not None
            and memo[0] == key
            and (memo[1] or not information)
            and (memo[2] is y or np.array_equal(memo[2], y))
        ):
            return memo[3]
        out = self._compute_terms(x, y, information=information)
        self._memo = (key, information, y, out)
        return out

    def _compute_terms(
        self, x: FloatArray, y: FloatArray, *, information: bool
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """ln p per sample, per-sample scores and (optionally) the observed information.

        The information -d^2 ln L is sum_k [g_k g_k^T - E_post(a a^T + da)] with a_j the
        gradient of ln(w_j N(y_k; s_j, sigma_v^2)); for the system and noise parameters and a
        jitter scale the second term is kept, without d^2 s / d theta^2 (whose posterior mean
        is zero-mean noise: Gauss-Newton); for the jitter family's other parameters only the
        outer products remain (BHHH).

        The jitter scale a of a family whose law is that of a xi (Uniform, Gaussian,
        SumOfUniforms at fixed n) enters p(y_k) = int p(xi) N(y_k; s(kT + a xi)) dxi through
        the signal only, so ds/da = xi s'(kT + a xi) = (tau / a) s'(t): its score is (L2)
        with that derivative at the same nodes, exact for the integral, with s' from the
        modal form. The shape parameters (n) move the weights: where the family gives
        dp/dtheta in closed form (``JitterFamily.pdf_gradient``: n of the family (26) off its
        integers) d ln p / dtheta = sum_j pi_j (dp/dtheta / p)(tau_j) at the same nodes, else
        forward differences of ln p.
        """
        law, sig, sigma = self.split(x)
        nj, p = self.n_jitter, x.size
        ns = len(self.model.param_names)
        noise = self.noise_std is None
        nodes = self._nodes(x, law, sig, y, sigma)
        analytic = _NodeSignal(sig, np.zeros(0)).analytic
        scale = self._scale_index(_has_slope(sig, analytic))
        # parameters whose score comes from ds at the nodes: the scale, then the system
        inner = ([scale] if scale is not None else []) + list(range(nj, nj + ns))
        dX: NDArray[np.complex128] | None = None
        logp, G, C = np.empty(self.N), np.empty((self.N, p)), np.zeros((p, p))
        dmodal = None
        if ns and analytic:
            assert isinstance(self.u, PiecewiseConstant)
            seg = sig.modal_segments
            assert seg is not None
            assert isinstance(self.model, ModelStructure)
            dmodal = _modal_gradient(self.model, self.layout.block(x, "system"), seg.system)
            dX = _pole_sensitivity(seg.system, self.u) if dmodal is not None else None
        own_gradient = not analytic and ns and sig.has_gradient
        # parameters differenced (forward steps): jitter parameters without an analytic
        # score, and the system's where neither the modal form nor the model gives ds/dtheta
        # jitter parameters of a family with a closed-form dp/dtheta (JitterFamily.pdf_gradient):
        # d ln p(y_k) / dtheta_i = sum_j pi_j (dp/dtheta_i / p)(tau_j) at the same nodes
        closed, above, differenced = self._shape_routes(x, scale)
        delay = self._delay
        if dmodal is None and not own_gradient:
            differenced += [i for i in range(nj, nj + ns) if i != delay]
        fwd = {i: finite_diff.forward(x, i, self.bounds[i], _SCORE_STEP) for i in differenced}
        # The shape (n) by differences of ln p with the weights alone moved: the pdf of the
        # shifted law at the same nodes (the derivative of the integral: the rule's panels
        # end at the law's knots, which move by O(h), where the pdf is continuous).
        weights_only = tuple(
            i
            for i in self._weight_params()
            if i in fwd and _same_nodes(law, self.split(fwd[i][0])[0], fwd[i][1])
        )
        shapes = [(i, self.split(fwd[i][0])[0], fwd[i][1]) for i in weights_only if i in fwd]
        for nd in nodes:
            if analytic and (dmodal is not None or not ns):
                s, D, ds = nd.signal.gradient(sig, dmodal, dX, slope=True)  # type: ignore[misc]
            else:
                s = nd.signal(sig)
                G_own = sig.gradient(nd.t) if own_gradient else None
                if G_own is not None:
                    D = G_own
                else:  # the declared finite-difference route: forward differences of s
                    D = np.empty((ns, nd.t.size))
                    for i in range(ns):
                        if nj + i == delay:
                            continue  # from the slope below
                        xi, h = fwd[nj + i]
                        D[i] = (nd.signal(self.split(xi)[1]) - s) / h
                if scale is not None:
                    if analytic:
                        ds = nd.signal.gradient(sig, None, None, slope=True)[2]  # type: ignore[misc]
                    else:
                        ds = sig.slope(nd.t)
            if delay is not None:  # the nodes t_j = kT + tau0_j - delay move by -d delay
                if not analytic:
                    ds = _slope_at(sig, nd.t)  # the signal's own, or a central difference
                D = D.copy()
                D[delay - nj] = -ds
            if scale is not None:
                tau = nd.t - (nd.k0 + nd.owner) * self.T
                D = np.vstack([ds * (tau / x[scale]), D])
            ev = _evaluate(nd, s, y, sigma)
            rows = slice(nd.k0, nd.k1)
            logp[rows] = ev.logp
            if shapes:  # the shape (n): ln p with the weights alone moved (below)
                tau = np.clip(nd.t - (nd.k0 + nd.owner) * self.T, *law.support)
                rule = nd.logrule
                with np.errstate(divide="ignore"):
                    if rule is None:
                        rule = nd.logw - np.log(_density(law, tau))
                    for i, law_i, h in shapes:
                        logw = rule + np.log(_density(law_i, tau))
                        moved = _evaluate(nd, s, y, sigma, logw).logp
                        G[rows, i] = (moved - ev.logp) / h
            if closed:
                lo, hi = law.support
                tau = np.clip(nd.t - (nd.k0 + nd.owner) * self.T, lo, hi)
                theta_j = self.layout.block(x, "jitter").tolist()
                dp = self.jitter.pdf_gradient(theta_j, tau)  # type: ignore[union-attr]
                dens = _density(law, tau)  # (the weights' own density, and fast)
                # (a node whose density rounds to 0 carries no posterior weight either)
                ratio = np.divide(
                    dp[closed],  # type: ignore[index]
                    dens,
                    out=np.zeros((len(closed), tau.size)),
                    where=dens > 0,
                )
                G[rows, closed] = np.add.reduceat(ratio * ev.post, nd.starts, axis=1).T
            A = D * (ev.e / sigma)
            if noise:
                A = np.vstack([A, (ev.e**2 - 1) / sigma])
            cols = inner + ([p - 1] if noise else [])
            if A.shape[0]:
                G[rows, cols] = np.add.reduceat(A * ev.post, nd.starts, axis=1).T
            if information:
                e2, pi = ev.e**2, ev.post
                second = None if analytic or not ns else sig.second_derivatives(nd.t)
                if second is not None:
                    # the exact observed information (L5) over the scale and the system
                    Dg, gn = D, inner
                    Hs = _second_block(second, nd.t - (nd.k0 + nd.owner) * self.T, x, scale)
                    C[np.ix_(gn, gn)] += (Dg * (pi * (1 - e2))) @ Dg.T / sigma**2 - np.einsum(
                        "abn,n->ab", Hs, pi * ev.e
                    ) / sigma
                else:
                    # the Gauss-Newton term over the scale and the system (without the
                    # posterior mean of e d2s/dtheta2, zero under the model since e is the
                    # noise: for the scale too, ds/da = (tau / a) s'). With the scale's
                    # block BHHH, as it was, the scale and the gain crept to the optimum
                    # in alternating steps: 16 evaluations for a piece of Table 2's record
                    # 0 with the family (26) where this takes 5
                    Dg, gn = D, inner
                    C[np.ix_(gn, gn)] += (Dg * (pi * (1 - e2))) @ Dg.T / sigma**2
                if noise:
                    cross = Dg @ (pi * ev.e * (3 - e2)) / sigma**2
                    C[gn, -1] += cross
                    C[-1, gn] += cross
                    C[-1, -1] += np.sum(pi * (3 * e2 - 1 - (e2 - 1) ** 2)) / sigma**2
        for i, r in above.items():  # on a kink, from above: r x the scale's score (exact)
            assert scale is not None
            G[:, i] = r * G[:, scale]
        moving = [i for i in range(nj) if i in fwd and i not in weights_only]
        for i in moving:  # parameters that may move the support: new nodes
            xi, h = fwd[i]
            G[:, i] = (self.logpdf(xi, y) - logp) / h
        return logp, G, G.T @ G + C

    def maximise(
        self, y: ArrayLike, x0: ArrayLike, *, max_evaluations: int = 200, tol: float = 1e-8
    ) -> tuple[FloatArray, float, bool, str, int]:
        """Maximise ln L from ``x0`` inside the bounds:
        :func:`jitterid.estimation.search.newton_search` on V = -ln L (so that its Newton
        decrement g^T M^{-1} g, twice the remaining gain in ln L, is compared with ``tol``).

        The Newton matrix M is the observed information of :meth:`_terms` (Gauss-Newton for
        the system, noise and jitter-scale parameters: within ~1% of the exact Hessian at the
        optimum on the paper's experiments; BHHH for the jitter shape).

        The search stays inside :attr:`bounds`: a family with kinks (the non-integer
        extension of :class:`SumOfUniforms` has one at every integer n) is searched one
        smooth piece at a time (:func:`jitterid.estimation.search.piecewise`, through
        :meth:`restrict`).

        Parameters
        ----------
        y : array_like, shape (N,)
            The samples.
        x0 : array_like
            Starting parameter vector, in :attr:`names` order, inside the bounds.
        max_evaluations : int, optional
            Most evaluations of the likelihood.
        tol : float, optional
            Tolerance on the Newton decrement (twice the remaining gain in ln L).

        Returns
        -------
        x, loglik, converged, message, evaluations
        """
        y = self._data(y)
        lo, hi = np.array(self.bounds, dtype=float).reshape(-1, 2).T
        x0 = np.clip(np.atleast_1d(real_array(x0, "x0")), lo, hi)

        values: dict[bytes, float] = {}

        def negloglik(x: FloatArray) -> tuple[float, FloatArray, FloatArray]:
            logp, G, M = self._terms(x, y, information=True)
            values[x.tobytes()] = v = -float(np.sum(logp))
            if not _positive_definite(M):  # far from the optimum: centred score products
                Gc = G - G.mean(axis=0)
                M = Gc.T @ Gc
            return v, -G.sum(axis=0), M

        self._stepping = True  # (a step far towards noise_std = 0 is refused: _nodes)
        try:
            x, ok, msg, n = newton_search(
                evaluator(negloglik),
                x0,
                lo,
                hi,
                max_evaluations,
                tol=tol,
                floor=LIKELIHOOD_FLOOR,
                names=self.names,
            )
        finally:
            self._stepping = False
        loglik = -values[x.tobytes()] if x.tobytes() in values else self.loglik(x, y)
        return x, loglik, ok, msg, n

    def fisher(self, x: ArrayLike, scale: ArrayLike | None = None) -> FloatArray:
        """Fisher information (L3) of the N samples at ``x``, in :attr:`names` order.

        The scores are central differences of ln p_k, step 1e-4 max(|x_i|, 1e-2), or at most
        ``FISHER_SCALE_STEP`` of ``scale[i]`` (each parameter's natural scale, e.g. from the
        Gaussian bound (L4), :func:`jitterid.estimation.bounds.crb`): a frequency over a long
        record is far more sensitive than its magnitude says.

        Parameters
        ----------
        x : array_like
            Parameter vector, in :attr:`names` order.
        scale : array_like, optional
            Each parameter's natural scale, bounding its difference step.
        """
        x = np.atleast_1d(real_array(x, "x"))
        sigma = self.split(x)[2]
        p = x.size
        sc = None if scale is None else np.broadcast_to(np.asarray(scale, dtype=float), (p,))
        # Variants: the base point, then a pair of shifted points per parameter.
        variants, steps = [x], np.empty(p)
        for i in range(p):
            h = finite_diff.step(x, i, _FISHER_STEP)
            if sc is not None and np.isfinite(sc[i]) and sc[i] > 0:
                h = min(h, FISHER_SCALE_STEP * float(sc[i]))
            xp, xm, steps[i] = finite_diff.central_pair(x, i, self.bounds[i], _FISHER_STEP, h=h)
            variants += [xp, xm]

        def chunks(xv: FloatArray) -> Iterator[tuple[_Nodes, FloatArray, float]]:
            lv, tv, sv = self.split(xv)
            for nd in self._nodes(xv, lv, tv):
                yield nd, nd.signal(tv), sv

        info = np.zeros((p, p))
        # the variants' rules chunk by chunk, side by side (same chunks of samples)
        for per_variant in zip(*(chunks(xv) for xv in variants), strict=True):
            nd0, s0, _ = per_variant[0]
            for k in range(nd0.k1 - nd0.k0):
                j0, j1 = _segment(nd0, k)
                ys = s0[j0:j1][nd0.logw[j0:j1] > -np.inf]
                lo, hi = ys.min() - _Y_TAIL * sigma, ys.max() + _Y_TAIL * sigma
                ny = int(np.ceil((hi - lo) / (_Y_STEP * sigma))) + 1
                grid = np.linspace(lo, hi, ny)
                dy = grid[1] - grid[0]
                logs = []
                for nd, s, sv in per_variant:
                    a, b = _segment(nd, k)
                    logs.append(_log_mixture(grid, s[a:b], nd.logw[a:b], sv))
                L = np.array(logs)
                g = (L[1::2] - L[2::2]) / steps[:, None]
                info += (g * (np.exp(L[0]) * dy)) @ g.T
        return 0.5 * (info + info.T)


def _same_nodes(law: JitterLaw, moved: JitterLaw, h: float) -> bool:
    """Whether a shape step ``h`` of ``law`` may be differenced at the same nodes: the knots
    move by about ``h`` times the support's width, which the nodes do not see; that is an
    O(h) error of the pdf only where the density is continuous and its pieces are far wider
    than the move (``_SAME_NODES`` times). A density with jumps (the uniform, n = 0 of the
    family (26)) or a piece as narrow as the move (n a hair above an integer: the extra
    uniform's width c) is differenced with new nodes: with the same ones the score at n = 0
    was -100 where the likelihood rises at +0.9 per unit n. So is a step that changes the
    number of knots (``moved``: the law after the step): n a hair below an integer has a
    piece of width ~ sqrt(h) about the centre that the integer's law lacks (Table 2's
    record 2 at n = 1 from below: a score of -97 where ln L falls at 0.44 per unit n)."""
    if law.pdf_degree == 0 or moved.pdf_degree == 0:
        return False
    knots, after = law.breakpoints(), moved.breakpoints()
    if knots.size != after.size:
        return False
    width = float(knots[-1] - knots[0])
    gaps = np.r_[np.diff(knots), np.diff(after)] if knots.size > 1 else [width]
    return float(np.min(gaps)) >= _SAME_NODES * abs(h) * width


def _log_mixture(grid: FloatArray, s: FloatArray, logw: FloatArray, sigma: float) -> FloatArray:
    """ln sum_j exp(logw_j) N(y; s_j, sigma^2) at every y of ``grid``: the density of (L1) of
    one sample on the Fisher information's y-grid.

    Summed over every node where a sample has few (``_DENSE``); otherwise over the nodes
    within sqrt(d^2 + ``_BAND``^2) noise std's of each y, d that of the nearest node: a node
    left out adds less than exp(-_BAND^2 / 2) = 2e-22 of the nearest one's term. Both the
    grid and the nodes grow like the signal's range over the noise std, so the full sum costs
    their product, (range / sigma)^2 per sample: a steep sine in small noise (issue 25).
    """
    if s.size <= _DENSE:
        z = logw - 0.5 * ((grid[:, None] - s) / sigma) ** 2
    else:
        keep = logw > -np.inf
        order = np.argsort(s[keep])
        s, logw = s[keep][order], logw[keep][order]
        # the nodes within sqrt(d^2 + _BAND^2) noise std's of y, d that of the nearest one
        at = np.searchsorted(s, grid)
        near = np.minimum(
            np.abs(grid - s[np.maximum(at - 1, 0)]), np.abs(grid - s[np.minimum(at, s.size - 1)])
        )
        reach = np.sqrt(near**2 + (_BAND * sigma) ** 2)
        lo = np.searchsorted(s, grid - reach, side="left")
        hi = np.searchsorted(s, grid + reach, side="right")
        idx = lo[:, None] + np.arange(int(np.max(hi - lo)))[None, :]
        inside = idx < hi[:, None]
        idx = np.minimum(idx, s.size - 1)
        z = np.where(inside, logw[idx] - 0.5 * ((grid[:, None] - s[idx]) / sigma) ** 2, -np.inf)
    top = np.max(z, axis=1)
    lse = top + np.log(np.sum(np.exp(z - top[:, None]), axis=1))
    return np.asarray(lse - np.log(sigma) - _LOG_SQRT_2PI, dtype=float)


def _positive_definite(M: FloatArray) -> bool:
    """Whether the (diagonally scaled) matrix has a Cholesky factor."""
    d = np.sqrt(np.abs(np.diag(M)))
    if np.any(d == 0) or not np.all(np.isfinite(M)):
        return False
    try:
        np.linalg.cholesky(M / np.outer(d, d) + 1e-12 * np.eye(d.size))
    except np.linalg.LinAlgError:
        return False
    return True


def _segment(nd: _Nodes, k: int) -> tuple[int, int]:
    a = int(nd.starts[k])
    b = int(nd.starts[k + 1]) if k + 1 < nd.starts.size else nd.t.size
    return a, b


# ---------------------------------------------------------------------------- functions
def log_density(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    y: ArrayLike,
    noise_std: float,
    *,
    order: int = DEFAULT_ORDER,
    panel: float = DEFAULT_PANEL,
) -> FloatArray:
    """ln p(y_k) of each sample under a known system, jitter law and noise std, eq. (L1).

    Parameters
    ----------
    system : TransferFunction
        The continuous-time system.
    u : Input
        The known input.
    jitter : JitterLaw
        The jitter law.
    T : float
        Nominal sampling interval (s).
    y : array_like, shape (N,)
        Samples requested at kT, k = 0..N-1.
    noise_std : float
        Measurement-noise std, > 0.
    order, panel : int, float
        Accuracy controls (see :class:`ExactLikelihood`).

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(5.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=40, noise_std=0.01, rng=2)
    >>> lp = ji.log_density(G, u, ji.Uniform(0.05), 0.1, data.y, noise_std=0.01)
    >>> lp.shape, bool(np.all(np.isfinite(lp)))
    ((40,), True)
    """
    if not isinstance(system, TransferFunction):
        raise TypeError(f"system must be a TransferFunction; got {type(system).__name__}")
    jitter = known_law(jitter)
    yv = real_array(y, "y", ndim=1)
    lik = ExactLikelihood(system, jitter, u, T, yv.size, noise_std, order=order, panel=panel)
    return lik.logpdf(np.zeros(0), yv)
