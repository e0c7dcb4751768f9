"""The search: one table of search adapters, and the one damped Newton (Fisher-scoring)
trust-region loop behind every criterion that provides a value, a gradient and an expected
Hessian.

An estimator names its adapter (:attr:`Estimator.search <jitterid.estimation.estimators.base
.Estimator.search>`); :func:`run_search` looks it up in :data:`SEARCHES` and runs it on any
problem of the fit's problem protocol (:class:`SearchProblem`: the white-noise
:class:`~jitterid.estimation.problem.Problem` and the coloured-noise
:class:`~jitterid.estimation.bjcriteria.BJProblem`), with the estimator's frozen-weight rounds
(WBCLS (20)) around it. The adapters:

- ``"least_squares"``: ``scipy.optimize.least_squares`` (trust-region reflective) on the
  criterion's residuals with its analytic Jacobian (``ls``, ``bcls``, ``wbcls``);
- ``"newton"``: :func:`newton_search` on (V, dV/dx, expected Hessian), in the problem's search
  coordinates (:class:`Coordinates`: logarithms of unbounded rates and squares of noise
  stds for the coloured-noise problem, the parameters themselves otherwise);
- ``"likelihood"``: the exact likelihood's own search with scored starts, registered by
  :mod:`jitterid.estimation.ml` (:func:`register_search`).

Every adapter returns an :class:`Outcome` (estimate, criterion, status, message,
evaluations).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any, NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from ..jitter.laws import JitterFamily
from .status import FitStatus

__all__ = [
    "KINKED_TOL",
    "LIKELIHOOD_FLOOR",
    "OWN_PIECES",
    "PIECE_GAIN",
    "SEARCHES",
    "Coordinates",
    "Outcome",
    "SearchOptions",
    "SearchProblem",
    "criterion_or_inf",
    "damped_step",
    "evaluator",
    "newton_search",
    "piecewise",
    "register_search",
    "run_search",
]

FloatArray = NDArray[np.float64]
_BAD = 1e10  # residual returned where the model cannot be evaluated (e.g. unstable)


class Outcome(NamedTuple):
    """How one search ended: the estimate, the criterion there, the status, the search's
    message and the criterion evaluations it used."""

    x: FloatArray
    cost: float
    status: FitStatus
    message: str
    nfev: int


class SearchOptions(NamedTuple):
    """How a problem wants the Newton adapter to search it.

    Attributes
    ----------
    tol : float
        Newton-decrement tolerance.
    coordinates : bool
        Search in :class:`Coordinates` (logs of unbounded rates, squares of noise stds).
    stall_gain : float or None
        Stop, converged, when the last ``STALL_WINDOW`` accepted steps gained less than
        this (a criterion whose infimum lies at the edge of the model); None: never.
    rounding_floor : float or None
        Exhausted damping at a Newton decrement below this is the rounding floor of the
        criterion, reported converged; None: reported as a failure.
    """

    tol: float = 1e-8
    coordinates: bool = False
    stall_gain: float | None = None
    rounding_floor: float | None = None


class SearchProblem(Protocol):
    """What a search adapter reads of a problem (the fit's problem protocol)."""

    @property
    def names(self) -> tuple[str, ...]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float], ...]: ...
    @property
    def estimator(self) -> Any: ...
    @property
    def freqs(self) -> FloatArray: ...

    def objective(self, x: FloatArray) -> float: ...
    def search_residuals(self, x: FloatArray) -> FloatArray: ...
    def jacobian(self, x: FloatArray) -> FloatArray: ...
    @property
    def has_jacobian(self) -> bool: ...
    def objective_gradient(
        self, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]: ...
    def search_options(self, tol: float | None) -> SearchOptions: ...
    def release(self) -> None: ...
    @property
    def layout(self) -> Any: ...
    def restrict(self, bounds: tuple[tuple[float, float], ...] | None) -> None: ...


Adapter = Callable[..., Outcome]
#: The search adapters by the key an estimator names (:attr:`Estimator.search`).
SEARCHES: dict[str, Adapter] = {}
#: The keys of adapters that apply :func:`piecewise` themselves (around their local search,
#: inside their own multi-start); :func:`run_search` applies it around the others.
OWN_PIECES: set[str] = set()
#: The keys of adapters that search to the Newton-decrement ``tol`` they are given (a walk
#: over a kinked parameter's pieces searches those to :data:`WALK_TOL` first, :func:`piecewise`)
WITH_TOLERANCE: set[str] = set()


def register_search(
    key: str, *, own_pieces: bool = False, tolerance: bool = False
) -> Callable[[Adapter], Adapter]:
    """Decorator: make an adapter ``f(problem, x0, max_nfev, free=None, tol=None) ->
    Outcome`` available to the estimators whose ``search`` is ``key``.

    The adapter searches the problem's current :attr:`~SearchProblem.bounds`. Where the
    layout has kinked parameters (:attr:`jitterid.params.ParamLayout.kinks`),
    :func:`run_search` runs it piece by piece (:func:`piecewise`); an adapter with its own
    starts says ``own_pieces=True`` and calls :func:`piecewise` around its local search. An
    adapter that stops at the Newton decrement ``tol`` it is given says ``tolerance=True``.
    """

    def deco(f: Adapter) -> Adapter:
        SEARCHES[key] = f
        for flag, keys in ((own_pieces, OWN_PIECES), (tolerance, WITH_TOLERANCE)):
            if flag:
                keys.add(key)
            else:
                keys.discard(key)
        return f

    return deco


P = TypeVar("P", bound=SearchProblem)


def run_search(
    problem: P,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
    walks: Walks | None = None,
) -> tuple[P, Outcome]:
    """Minimise ``problem``'s criterion from ``x0`` with its estimator's adapter (``walks``:
    :func:`piecewise`'s, shared by the starts of a multi-start).

    An estimator with frozen weights (``freeze_rounds`` > 0: WBCLS (20)) is searched that
    many times, its weights frozen at the start and then at each estimate (iterated
    feasible GLS, :mod:`jitterid.estimation.estimators.wbcls`): the problem returned is the
    last one. Otherwise the problem is returned as it is.
    """
    est = problem.estimator
    if est.search not in SEARCHES:
        raise ValueError(
            f"estimator {est.name!r} names the search {est.search!r}, which is not one of "
            f"{tuple(SEARCHES)}: register it with jitterid.estimation.search.register_search"
        )
    adapter = SEARCHES[est.search]

    def local(p: SearchProblem, x: FloatArray, budget: int, walk: float | None = None) -> Outcome:
        return adapter(p, x, budget, free, tol if walk is None else walk)

    def search(p: SearchProblem, x: FloatArray, budget: int) -> Outcome:
        if est.search in OWN_PIECES:
            return local(p, x, budget)
        loose = est.search in WITH_TOLERANCE and (tol is None or tol < WALK_TOL)
        walk = WALK_TOL if loose else None
        return piecewise(p, x, local, budget, free, walk, walks)

    rounds = est.freeze_rounds
    if not rounds:
        return problem, search(problem, x0, max_nfev)
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    nfev = 0
    for _ in range(rounds):
        problem = replace(problem, weights_at=np.array(x0, float))  # type: ignore[type-var]
        out = search(problem, x0, max_nfev)
        nfev += out.nfev
        x0 = out.x
    return problem, out._replace(nfev=nfev)


#: the kinks' scan (_scan) looks at these fractions of the pieces next to where its descent
#: over the kinks ends: denser near the kinks, where the modes of ln L in n that a kink
#: hides sit (Table 3, records 0 and 19: ln L falls from the kink n = 1 into (0, 1) and
#: peaks again at n = 0.85 and 0.7)
SCAN_FRACTIONS = (0.1, 0.25, 0.5, 0.75, 0.9)
#: relative decrease of the criterion that counts as descent into a neighbouring piece
PIECE_GAIN = 1e-10
#: a search that stops within this fraction of its piece's width from an end, no lower than
#: the end itself, is at the end
SNAP = 1e-3


def _piece(v: float, cuts: FloatArray) -> tuple[float, float]:
    """The piece [cuts[j], cuts[j + 1]] holding ``v`` (``cuts``: the bounds and the kinks
    between them, sorted); a kink itself starts the piece above it (the last cut ends the
    last piece)."""
    j = int(np.searchsorted(cuts, v, side="right")) - 1
    j = min(max(j, 0), cuts.size - 2)
    return float(cuts[j]), float(cuts[j + 1])


def _same_std(problem: SearchProblem, x: FloatArray, i: int, c: float) -> FloatArray:
    """``x`` with its parameter ``i`` set to ``c``: a jitter family's parameter at the same
    jitter std (:meth:`jitterid.JitterFamily.at_same_std`, the family's scale moved with it),
    any other as it is."""
    jitter = getattr(problem, "jitter", None)
    nj = len(jitter.param_names) if isinstance(jitter, JitterFamily) else 0
    if i >= nj:
        return np.where(np.arange(x.size) == i, c, x)
    assert isinstance(jitter, JitterFamily)
    return np.r_[jitter.at_same_std(x[:nj].tolist(), i, c), x[nj:]]


def criterion_or_inf(problem: SearchProblem, x: FloatArray) -> float:
    """The problem's criterion at ``x``, +inf where it cannot be evaluated (a model that
    raises, a non-finite value): for scoring candidate points without a search."""
    with np.errstate(all="ignore"):
        try:
            v = float(problem.objective(x))
        except (ValueError, np.linalg.LinAlgError):
            return np.inf
    return v if np.isfinite(v) else np.inf


def _scan(
    problem: SearchProblem,
    x: FloatArray,
    v0: float,
    i: int,
    cuts: FloatArray,
    scanned: set[tuple[float | str, ...]] | None = None,
) -> tuple[FloatArray, float, int]:
    """A descent over the kinks ``cuts`` of a jitter family's kinked parameter ``i`` from
    ``x`` (criterion ``v0``) at the same jitter std (:meth:`jitterid.JitterFamily
    .at_same_std`; the other parameters as they are): the kinks either side of x_i, then on
    in the direction that descends, with a doubling stride while the criterion keeps
    falling, to a kink lower than both its neighbours (or an end); then the points at
    ``SCAN_FRACTIONS`` of the pieces next to where that descent ends. Returns the lowest
    point, its criterion and the evaluations used (x itself where none is lower).

    One evaluation a point: the family's shape is all but flat at a fixed std (Table 1:
    BCLS stops anywhere in n; ML walked n from 20 to 11 one piece, one search, at a time).
    The points inside find a mode inside a piece that its ends do not show (Table 3,
    record 19: ln L has a local maximum in n at the kink n = 1 and its largest value at
    n = 0.7; at the same std, 0.8 is above 1 and 0.5 below; record 0: the mode is at
    0.85, 0.9 above 1 and 0.75 below).

    Where the family's scale is on one of its bounds and neither kink next to x_i is lower
    at the same std, the descent runs along the bound instead (the scale held, x_i moved):
    the std the data want is then beyond what the bound allows at x_i, and x_i is the way
    to it (Table 1, BCLS with a on T/2 at n = 8: the same-std kinks were higher, and the
    walk went down n = 8, 7, 6, 5 one piece, one search and one scan at a time, 45
    evaluations; along the bound the descent finds n = 5 in about 5).

    ``scanned``: the pieces whose inside an earlier scan of the same walk looked at along
    the same line (updated here), not looked at again: where that scan found a lower point
    the walk searched its piece from it, so a mode there has been searched (Table 2's record
    0 with the family (26): the scan from the piece [1, 2]'s stop evaluated 0.1 ... 0.9 of
    [1, 2] again, 5 of the fit's 49 evaluations). A piece looked at along the bound is
    still looked at at the same std (Table 1, case 3, realization 33: ln L's mode at n =
    0.81 inside (0, 1), off the bound, was missed otherwise)."""
    jitter = getattr(problem, "jitter", None)
    nj = len(jitter.param_names) if isinstance(jitter, JitterFamily) else 0
    if i >= nj:
        return x, v0, 0
    assert isinstance(jitter, JitterFamily)

    def same_std(c: float) -> FloatArray:
        return _same_std(problem, x, i, c)

    def held(c: float) -> FloatArray:
        return np.where(np.arange(x.size) == i, c, x)

    best_c, best, n, at = *_descend(problem, x, v0, i, cuts, same_std), same_std
    line: tuple[str, ...] = ()  # (the pieces' insides are remembered per line)
    k = jitter.scale_index
    if best_c == float(x[i]) and k is not None and k != i:
        lo, hi = jitter.bounds[k]
        near = SNAP * ((hi - lo) if np.isfinite(hi - lo) else abs(x[k]))
        # (a search stops just inside its bound)
        if any(np.isfinite(b) and abs(x[k] - b) <= near for b in (lo, hi)):
            best_c, best, m = _descend(problem, x, v0, i, cuts, held)
            n, at, line = n + m, held, ("held",)
    # the pieces next to where the descent ends (one piece where it is inside one)
    j = int(np.searchsorted(cuts, best_c))
    on_kink = j < cuts.size and cuts[j] == best_c
    pieces = [(j - 1, j), (j, j + 1)] if on_kink else [(j - 1, j)]
    for p, q in pieces:
        if p < 0 or q >= cuts.size:
            continue
        if scanned is not None:
            key: tuple[float | str, ...] = (float(cuts[p]), float(cuts[q]), *line)
            if key in scanned:
                continue
            scanned.add(key)
        for f in SCAN_FRACTIONS:
            c = float(cuts[p] + f * (cuts[q] - cuts[p]))
            w = criterion_or_inf(problem, at(c))
            n += 1
            if w < best:
                best_c, best = c, w
    return (at(best_c), best, n) if best < v0 else (x, v0, n)


def _descend(
    problem: SearchProblem,
    x: FloatArray,
    v0: float,
    i: int,
    cuts: FloatArray,
    at: Callable[[float], FloatArray],
) -> tuple[float, float, int]:
    """:func:`_scan`'s descent over the kinks along the line ``at`` (x_i -> a point):
    (the lowest kink found, or x_i where neither kink next to it is lower than ``v0``; its
    criterion; the evaluations used)."""
    # the kinks either side of x_i, strictly (x_i on a kink: its neighbours)
    below = int(np.searchsorted(cuts, x[i], side="left")) - 1  # cuts[below] < x_i
    above = int(np.searchsorted(cuts, x[i], side="right"))  # cuts[above] > x_i
    tried = {
        j: criterion_or_inf(problem, at(float(cuts[j])))
        for j in (below, above)
        if 0 <= j < cuts.size
    }
    if not tried or min(tried.values()) >= v0:
        return float(x[i]), v0, len(tried)
    j = min(tried, key=lambda k: tried[k])
    step = -1 if j == below else 1
    v = tried[j]
    # on over the kinks while the criterion falls, the stride doubling after each lower
    # kink; then the gaps next to the lowest kink halved until both its neighbours are
    # tried (or it is an end): a lowest kink among its neighbours, as a kink-by-kink
    # descent ends at, in O(log) evaluations (a criterion falling over 11 kinks to
    # n_max = 20, BCLS's: 7 evaluations, not 12)

    def value(k: int) -> float:
        if k not in tried:
            tried[k] = criterion_or_inf(problem, at(float(cuts[k])))
        return tried[k]

    stride = 1
    while (k := min(max(j + step * stride, 0), cuts.size - 1)) != j and value(k) < v:
        j, v, stride = k, tried[k], 2 * stride
    while True:
        near = [
            max((k for k in tried if k < j), default=j),
            min((k for k in tried if k > j), default=j),
        ]
        gap = max(near, key=lambda k: abs(k - j))
        if abs(gap - j) <= 1:
            break
        k = (j + gap) // 2
        if value(k) < v:
            j, v = k, tried[k]
    return float(cuts[j]), v, len(tried)


#: the Newton-decrement tolerance of the searches of a walk over pieces (piecewise) before its
#: last: 1/100 of a standard error from stationary, where the walk's scan decides whether
#: to move on. A piece left behind was searched to no purpose beyond that: with the shape's
#: BHHH information the Newton steps creep along the family's all but flat direction (Table
#: 2's record 3, ML with the family (26): 20 of the 30 evaluations of the piece (8, 9)
#: gained 1e-5 each, before the scan found ln L higher by 1.4 at n = 1)
WALK_TOL = 1e-4


class Walks:
    """The stops of the walks of one multi-start (:func:`piecewise`'s ``walks``), each with
    the outcome its walk ended at: a later walk whose search stops where an earlier one's did
    (the same pieces, the criterion within ``MEET_COST`` relative, each parameter within
    ``MEET_X`` of its piece's width (a kinked one) or of its value) goes on as that one went
    on, so it ends there. BCLS in the family (26), Table 1: its six starts' walks stopped at
    one point of the piece (0, 1), the criterion equal to 1e-10, and each scanned on from it
    (166 evaluations a fit, 40 % of the reproduction's time). A walk that meets an earlier one
    leaves its own stops on the way, with that end, to the later walks. (Stops on one kink
    reached from its two pieces do not meet: their walks go on differently, and a later walk
    cut there lost a lower BCLS end in 2 of 768 Table 1 fits.)"""

    def __init__(self) -> None:
        self.stops: list[tuple[dict[int, tuple[float, float]], FloatArray, float, Outcome]] = []

    def meet(self, pieces: dict[int, tuple[float, float]], out: Outcome) -> Outcome | None:
        """The outcome of an earlier walk that stopped where ``out`` stops, or None."""
        for ps, x, cost, end in self.stops:
            if ps != pieces or abs(out.cost - cost) > MEET_COST * max(1.0, abs(cost)):
                continue
            scale = np.maximum(np.abs(x), np.abs(out.x))
            for i, (a, b) in ps.items():
                scale[i] = b - a
            if np.all(np.abs(out.x - x) <= MEET_X * scale + 1e-300):
                return end
        return None


#: walks meet (:class:`Walks`) where their criteria agree to this, relative ...
MEET_COST = 1e-9
#: ... and their parameters to this fraction of their value (a kinked one's piece width)
MEET_X = 1e-2


def piecewise(
    problem: SearchProblem,
    x0: FloatArray,
    search: Callable[[SearchProblem, FloatArray, int, float | None], Outcome],
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    walk_tol: float | None = None,
    walks: Walks | None = None,
) -> Outcome:
    """Minimise over the smooth pieces of the kinked parameters: the one kink mechanism.

    A parameter in which the criterion is only piecewise smooth (a jitter family's
    :attr:`~jitterid.JitterFamily.kinks`, in the problem's
    :attr:`~jitterid.params.ParamLayout.kinks`: n of the family (26) at the integers) is
    searched one piece [k_j, k_j+1] at a time: ``search(problem, x, budget, tol)`` runs with
    the problem restricted to the piece (:meth:`SearchProblem.restrict`), where the criterion
    is smooth up to the piece's ends and its derivatives there are one-sided into the piece,
    to the Newton decrement ``tol`` (None: the search's own).
    From where a piece's search stops, the kinks beyond, and points inside the pieces where
    that descent ends, are scanned at the same jitter std (:func:`_scan`, one evaluation
    each). Where one is lower, its piece (the piece beyond, for a kink) is searched from it.
    Where none is and the stop is on an end shared with a neighbouring piece, that piece is
    searched from the stop (a warm start: a few evaluations where there is nothing to gain).
    A search that lowers the criterion by more than ``PIECE_GAIN`` (relative) replaces the
    stop, and the walk goes on from there. Otherwise a stop inside its piece is a stationary
    point of a smooth piece, and a stop on an end is a kink where the criterion rises into
    both pieces (the one-sided derivatives bracket zero, the other parameters stationary):
    CONVERGED, with a message naming the kink. Without kinked free parameters this is
    ``search`` itself.

    With ``walk_tol`` (:data:`WALK_TOL`, for a search that takes a tolerance), the walk's
    searches stop there; where the walk ends, its piece is searched on from there to the
    search's own tolerance, and the end of that search is examined as above but for the scan,
    which the walk made from a point within sqrt(walk_tol) standard errors (a move from there
    scans again).

    With ``walks`` (one :class:`Walks` for the starts of one multi-start), a walk whose search
    stops where an earlier walk's did ends as that one ended (its evaluations its own).
    """
    layout = problem.layout
    kinked = layout.kinked()
    lo, hi = np.array(layout.bounds, dtype=float).reshape(-1, 2).T
    active = {
        i: np.unique(np.r_[lo[i], [c for c in k if lo[i] < c < hi[i]], hi[i]])
        for i, k in kinked.items()
        if lo[i] < hi[i] and (free is None or free[i])
    }
    active = {i: cuts for i, cuts in active.items() if cuts.size > 2}
    if not active:
        return search(problem, x0, max_nfev, None)
    full = tuple(map(tuple, np.c_[lo, hi].tolist()))
    x = np.clip(np.asarray(x0, float), lo, hi)
    pieces = {i: _piece(float(x[i]), cuts) for i, cuts in active.items()}

    tight = walk_tol is None

    def run(ps: dict[int, tuple[float, float]], start: FloatArray, budget: int) -> Outcome:
        box = list(full)
        for i, p in ps.items():
            box[i] = p
        problem.restrict(tuple(box))
        try:
            return search(problem, start, budget, None if tight else walk_tol)
        finally:
            problem.restrict(None)

    def lower(v: float, than: float) -> bool:
        return v < than - PIECE_GAIN * max(1.0, abs(than))

    out = run(pieces, x, max_nfev)
    nfev, walked = out.nfev, 0
    mine: list[tuple[dict[int, tuple[float, float]], FloatArray, float]] = []

    def met() -> Outcome | None:
        """An earlier walk's end where this walk's last search stopped (else recorded)."""
        if walks is None or out.status is not FitStatus.CONVERGED:
            return None
        end = walks.meet(pieces, out)
        if end is None:
            mine.append((dict(pieces), out.x.copy(), out.cost))
        return end

    if (ended := met()) is not None:
        return ended._replace(nfev=nfev)  # (its first stop was an earlier walk's: none of its own)
    scanned: dict[int, set[tuple[float | str, ...]]] = {i: set() for i in active}
    rescan = True
    kinks: list[tuple[int, float]] = []
    while out.status is FitStatus.CONVERGED and nfev < max_nfev:
        kinks = []
        moved = None
        for i, cuts in active.items():
            a, b = pieces[i]
            # (a search stops strictly inside its piece, near the end where it runs into
            # it: the end itself at the same jitter std, where it is no higher; a bound too,
            # which has no piece beyond: Table 1, ML from a walk's stop at n = 3e-4
            # converged there, 1e-6 above n = 0, where the shape the data do not tell was
            # then not held but singular)
            for e in (a, b):
                if 0 < abs(out.x[i] - e) <= SNAP * (b - a):
                    at_end = _same_std(problem, out.x, i, e)
                    v_end = criterion_or_inf(problem, at_end)
                    nfev += 1
                    if not lower(out.cost, v_end):  # (else the stop is inside)
                        out = out._replace(x=at_end, cost=min(v_end, out.cost))
            # (a stop on an end shared with a neighbouring piece: that piece is searched)
            inner = out.x[i] in (a, b) and out.x[i] not in (lo[i], hi[i])
            end = float(out.x[i]) if inner else None
            if rescan:
                ahead, v, n = _scan(problem, out.x, out.cost, i, cuts, scanned[i])
            else:  # (the walk's last scan stands)
                ahead, v, n = out.x, out.cost, 0
            nfev += n
            if lower(v, out.cost):  # a point beyond is lower: its piece, or beyond a kink
                k = float(ahead[i])
                j = int(np.searchsorted(cuts, k))
                if cuts[j] != k:  # a point inside a piece (k <= the last cut)
                    piece = (float(cuts[j - 1]), float(cuts[j]))
                else:
                    side = 1 if k > out.x[i] else -1
                    beyond = j + side if 0 <= j + side < cuts.size else j - side
                    piece = (min(k, float(cuts[beyond])), max(k, float(cuts[beyond])))
            elif end is not None:  # the neighbouring piece, from the end
                ahead, j = out.x, int(np.searchsorted(cuts, end))
                piece = (float(cuts[j - 1]), end) if end == a else (end, float(cuts[j + 1]))
            else:
                continue
            other = dict(pieces)
            other[i] = piece
            trial = run(other, ahead, max_nfev - nfev)
            nfev += trial.nfev
            if lower(trial.cost, out.cost):
                moved = (other, trial)
                break
            if end is not None:
                # (a search into that piece that stops without a lower point, converged or
                # not (no step of its descent lowered the criterion), found no descent)
                kinks.append((i, end))
        if moved is None:
            if tight:
                break
            # the walk ends here: its piece on to tol, the end of that examined again
            tight, rescan = True, False
            out = run(pieces, out.x, max_nfev - nfev)
            nfev += out.nfev
            continue
        pieces, out = moved
        walked, rescan = walked + 1, True
        if (ended := met()) is not None:
            # (the stops this walk made on its way end as it ends: a later walk that stops
            # at one of them goes on no further; Table 1, BCLS: the walks from (8, 0.25) and
            # (8, 0.5) stepped down the same pieces (8, 9) ... (5, 6) along a = T/2)
            if walks is not None:
                walks.stops.extend((ps, xs, c, ended) for ps, xs, c in mine)
            return ended._replace(nfev=nfev)
    out = out._replace(nfev=nfev)
    if out.status is FitStatus.CONVERGED and kinks:
        where = ", ".join(f"{layout.names[i]} = {v:g}" for i, v in kinks)
        out = out._replace(
            message=f"converged at the kink {where}: the criterion is not differentiable "
            "there and rises into the pieces on both sides (one-sided derivatives bracket "
            f"zero; the others stationary); {walked} move(s) between pieces"
        )
    elif out.status is FitStatus.CONVERGED and walked:
        out = out._replace(message=f"{out.message} (after {walked} move(s) between pieces)")
    if walks is not None:
        walks.stops.extend((ps, xs, c, out) for ps, xs, c in mine)
    return out


def _end(problem: SearchProblem, x: FloatArray, status: FitStatus, msg: str, n: int) -> Outcome:
    """The outcome at ``x``: the criterion recomputed from the model (so that it never holds
    the _BAD sentinel; large legitimate values, a sum over 10^6 frequencies, are not
    failures), NOT_FINITE where it cannot be evaluated; the problem's caches released."""
    with np.errstate(all="ignore"):
        try:
            cost = float(problem.objective(x))
        except (ValueError, np.linalg.LinAlgError):
            cost = np.inf
    if not np.isfinite(cost):
        status = FitStatus.NOT_FINITE
    problem.release()
    return Outcome(x, cost, status, msg, n)


def _free(problem: SearchProblem, x0: FloatArray, free: NDArray[np.bool_] | None) -> Any:
    """(lo, hi, x0 clipped, indices searched, embed): ``embed(z)`` is x0 with the searched
    entries set to z."""
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    mask = lo < hi if free is None else free & (lo < hi)
    idx = np.flatnonzero(mask)

    def embed(z: FloatArray) -> FloatArray:
        out = x0.copy()
        out[idx] = z
        return out

    return lo, hi, x0, idx, embed


@register_search("least_squares")
def least_squares_adapter(
    problem: SearchProblem,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
) -> Outcome:
    """Trust-region least squares (``scipy.optimize.least_squares``, ``x_scale="jac"``) on
    the problem's residuals over the free parameters, with its analytic Jacobian where it has
    one (else 2-point differences)."""
    lo, hi, x0, idx, embed = _free(problem, x0, free)
    if idx.size == 0:
        return _end(problem, x0, FitStatus.CONVERGED, "no free parameters", 1)

    # the residual vector's length, for the sentinel and the Jacobian where the model cannot
    # be evaluated: two per frequency (real and imaginary parts) until a residual says
    n_res = [2 * len(problem.freqs)]

    def resid(z: FloatArray) -> FloatArray:
        with np.errstate(all="ignore"):
            try:
                r = problem.search_residuals(embed(z))
            except ValueError:
                return np.full(n_res[0], _BAD)
        n_res[0] = r.size
        return r if np.all(np.isfinite(r)) else np.full(r.size, _BAD)

    jac: str | Callable[[FloatArray], FloatArray] = "2-point"
    if problem.has_jacobian:

        def jac(z: FloatArray) -> FloatArray:
            try:
                J = problem.jacobian(embed(z))
            except ValueError:  # only where resid failed too; such a step is never taken
                return np.zeros((n_res[0], idx.size))
            # (every parameter free: the array itself, whose memory layout the solver's
            # products follow, so that the arithmetic does not depend on the adapter)
            return J if idx.size == x0.size else J[:, idx]

    sol = least_squares(
        resid, x0[idx], jac=jac, bounds=(lo[idx], hi[idx]), x_scale="jac", max_nfev=max_nfev
    )
    status = FitStatus.CONVERGED if sol.status > 0 else FitStatus.MAX_EVALUATIONS
    if sol.status < 0:
        status = FitStatus.OPTIMISER_FAILED
    x = embed(np.clip(sol.x, lo[idx], hi[idx]))
    return _end(problem, x, status, str(sol.message), int(sol.nfev))


class _Stalled(Exception):
    """Raised inside the Newton search's evaluation to stop it (see newton_adapter)."""


#: the rounding floor of a criterion in units of a log-likelihood (the Gaussian-type criteria,
#: the exact likelihood): exhausted damping at a Newton decrement below it has converged, the
#: estimate within sqrt(1e-4) = 1/100 of a standard error of stationary (newton_search)
LIKELIHOOD_FLOOR = 1e-4
#: Newton-decrement tolerance of a search over a criterion with kinked parameters (a
#: jitter family's shape, :func:`piecewise`): the estimate within sqrt(1e-6) = 1/1000 of a
#: standard error of stationary. Where the default 1e-8 (1/10^4 of one) is asked, the
#: shape's information, an outer product of scores (BHHH), makes the Newton steps converge
#: only linearly along the family's all but flat shape: half of a piece's evaluations moved
#: the criterion by less than 1e-6 (Table 2's records with SumOfUniformsFamily: 21 and 22
#: evaluations for the two pieces of an ML walk, 11 of them each after that)
KINKED_TOL = 1e-6

#: a stall: the last STALL_WINDOW accepted steps gained less than SearchOptions.stall_gain
STALL_WINDOW = 6


@register_search("newton", tolerance=True)
def newton_adapter(
    problem: SearchProblem,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
) -> Outcome:
    """:func:`newton_search` on the problem's (V, dV/dx, expected Hessian) over the free
    parameters, in the coordinates and with the tolerances of its
    :meth:`~SearchProblem.search_options`."""
    lo, hi, x0, idx, embed = _free(problem, x0, free)
    if idx.size == 0:
        return _end(problem, x0, FitStatus.CONVERGED, "no free parameters", 1)
    opts = problem.search_options(tol)

    names = np.array(problem.names)[idx]
    cz = Coordinates(names, lo[idx], hi[idx], x0[idx], enabled=opts.coordinates)
    whole = cz.identity and idx.size == x0.size
    # (V, z) of the evaluations that lowered V (accepted steps; rejected trials are the
    # search's own damping and do not count towards a stall)
    record: list[tuple[float, FloatArray]] = []
    n_eval = [0]
    stall = opts.stall_gain

    def fun(z: FloatArray) -> tuple[float, FloatArray, FloatArray]:
        n_eval[0] += 1
        if (
            stall is not None
            and len(record) > STALL_WINDOW
            and record[-STALL_WINDOW - 1][0] - record[-1][0] < stall
        ):
            raise _Stalled
        xs, jac = cz.forward(z)
        with np.errstate(all="ignore"):
            try:
                v, g, M = problem.objective_gradient(embed(xs), idx)
            except (OverflowError, ZeroDivisionError):  # a wild trial point: rejected
                raise ValueError("criterion overflows") from None
            if whole:  # the arrays themselves (as least_squares_adapter's Jacobian)
                out = (v, g, M)
            else:
                out = (v, g[idx] * jac, M[np.ix_(idx, idx)] * np.outer(jac, jac))
        if np.isfinite(v) and (not record or v < record[-1][0]):
            record.append((float(v), z.copy()))
        return out

    z0, lz, hz = cz.inverse(x0[idx]), cz.lo, cz.hi
    try:
        z, ok, msg, nfev = newton_search(
            evaluator(fun),
            z0,
            lz,
            hz,
            max_nfev,
            tol=opts.tol,
            floor=opts.rounding_floor,
            names=tuple(names),
        )
    except _Stalled:
        # A criterion whose infimum lies at the edge of the model (a white record: the
        # noise pole runs off to infinity, where H is white) decreases without end by
        # amounts far below one unit of V; the estimate of every identifiable parameter
        # has converged (newton_search has no relative-decrease test).
        z, ok, nfev = record[-1][1], True, n_eval[0]
        msg = f"converged: V decreased by < {stall:g} over {STALL_WINDOW} evaluations"
    status = FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED
    if not ok and nfev >= max_nfev:
        status = FitStatus.MAX_EVALUATIONS
    x = embed(np.clip(cz.forward(z)[0], lo[idx], hi[idx]))
    return _end(problem, x, status, msg, nfev)


#: most a rate searched in log units moves from its start (Coordinates)
RATE_SPAN = 1e6


class Coordinates:
    """Search coordinates z for the Newton search (x = x(z) elementwise), where enabled:

    - a rate with a positive floor and no upper bound (noise poles ``ha*``, a jitter scale):
      z = ln x. The criterion varies on the rate's relative scale, and a Newton step in the
      rate itself overshoots to the floor, where the noise model degenerates;
    - a gain bounded below by 0 (``hb0``) and the white std ``noise_std``: z = x^2, the
      variance they carry. Sigma_y depends on them through x^2, so the Fisher information
      in x vanishes like x^2 as x -> 0 (a white record drives one of them there), and a
      Newton step in x explodes; in x^2 it is regular;
    - anything else (and everything where not enabled): z = x.
    """

    def __init__(
        self,
        names: NDArray[np.str_],
        lo: FloatArray,
        hi: FloatArray,
        x0: FloatArray,
        enabled: bool = True,
    ) -> None:
        unbounded = np.isinf(hi) & enabled
        self.square = unbounded & (names == "noise_std")
        self.log = unbounded & (lo > 0) & ~self.square
        self.identity = not (self.square.any() or self.log.any())
        self.lo = np.where(self.log, np.log(np.where(self.log, lo, 1.0)), lo)
        self.lo = np.where(self.square, np.maximum(lo, 1e-150) ** 2, self.lo)
        # A rate may move by a factor RATE_SPAN from its start at most: where it is not
        # identified (a noise gain at 0 leaves its pole free) the Newton steps in ln x are
        # ratios of vanishing numbers and would carry it to 1e100 and beyond.
        span = np.log(
            np.maximum(np.where(self.log, x0, 1.0), np.where(self.log, lo, 1.0))
        ) + np.log(RATE_SPAN)
        self.hi = np.where(self.log, span, hi)

    def forward(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """x(z) and dx/dz."""
        if self.identity:
            return z, np.ones_like(z)
        x = np.where(self.log, np.exp(np.minimum(np.where(self.log, z, 0.0), 700.0)), z)
        x = np.where(self.square, np.sqrt(np.maximum(np.where(self.square, z, 1.0), 0.0)), x)
        jac = np.where(self.log, x, 1.0)
        jac = np.where(self.square, 0.5 / np.maximum(np.where(self.square, x, 1.0), 1e-150), jac)
        return x, jac

    def inverse(self, x: FloatArray) -> FloatArray:
        if self.identity:
            return np.asarray(x, float)
        z = np.where(self.log, np.log(np.where(self.log, x, 1.0)), x)
        return np.clip(np.where(self.square, x * x, z), self.lo, self.hi)


def evaluator(
    fun: Callable[[FloatArray], tuple[float, FloatArray, FloatArray]],
) -> Callable[[FloatArray], tuple[float, FloatArray, FloatArray] | None]:
    """Wrap ``fun`` -> (V, g, M) so that a model that cannot be evaluated (ValueError) or a
    non-finite value gives None, which :func:`newton_search` treats as a rejected step."""

    def evaluate(x: FloatArray) -> tuple[float, FloatArray, FloatArray] | None:
        try:
            v, g, M = fun(x)
        except ValueError:  # e.g. an unstable system
            return None
        ok = np.isfinite(v) and np.all(np.isfinite(g)) and np.all(np.isfinite(M))
        return (v, g, M) if ok else None

    return evaluate


def newton_search(
    evaluate: Callable[[FloatArray], tuple[float, FloatArray, FloatArray] | None],
    x0: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    max_nfev: int,
    tol: float = 1e-8,
    floor: float | None = None,
    names: tuple[str, ...] | None = None,
) -> tuple[FloatArray, bool, str, int]:
    """Minimise a criterion V by damped Newton (Fisher scoring) inside box bounds.

    ``evaluate(x)`` returns (V, dV/dx, M) with M the expected Hessian of V (or None where V
    cannot be evaluated, e.g. an unstable system): the
    step solves (M + lam diag M) d = -g on the parameters not held at a bound (a parameter on
    its bound whose gradient points outwards is held). lam follows the trust-region rule on
    rho = (actual decrease) / (predicted decrease g.d + d.M.d / 2): divided by 4 when
    rho >= 3/4, multiplied by 4 (at least to 1e-3) when rho < 1/4; a step with rho < 1e-4 is
    rejected. Converged when the Newton decrement g^T M^{-1} g (twice the predicted remaining
    decrease) is below ``tol``. Near the optimum M is within O(1/sqrt(N)) of the Hessian, so
    the search needs a handful of evaluations where L-BFGS-B needed tens.

    V must be differentiable inside the box: a criterion with kinks is searched one smooth
    piece at a time by :func:`piecewise`. A step that leaves the box is clipped to it; where
    the clipped step is rejected, the step along the Newton direction cut at the first bound
    it reaches is tried too (clipping turns a step away from its direction).

    Where no step decreases V (damping exhausted) at a Newton decrement of at most ``floor``
    (the criterion's rounding floor: e.g. 1e-4 in units of a log-likelihood, 1/100 of a
    standard error from stationary), the search has converged to the precision of V. So it
    has where the decrement in the directions of M's curvature above ``FLAT_RATIO`` of its
    largest is at most ``floor`` and the rest lies along flatter directions (the shape of a
    jitter family at a fixed std: M, an expected or outer-product Hessian, is all but
    singular there and its step is no guide): the message names the flat direction
    (``names``: the parameters' names, for it). So it has, too, where no step inside the box
    could gain more than ``floor`` to first order (|g_i| times the room to the bound g
    points to, summed over the free parameters): a jitter scale collapsed onto its floor
    leaves a family's shape without information, and its gradient is rounding.

    Returns
    -------
    x, converged, message, evaluations
    """

    x = np.clip(np.asarray(x0, float), lo, hi)
    first = evaluate(x)
    if first is None:
        return x, False, "the criterion cannot be evaluated at the start", 1
    v, g, M = first
    n, lam = 1, 0.0
    # within rounding of a bound is on it (a start from a trust-region search, which keeps
    # strictly inside its bounds: n = 1e-25 above its floor, held there by no step)
    hair = 1e-12 * (1.0 + np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    hair_hi = 1e-12 * (1.0 + np.abs(np.where(np.isfinite(hi), hi, 0.0)))
    while n < max_nfev:
        x = np.where(x - lo <= hair, lo, np.where(hi - x <= hair_hi, hi, x))
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        dec = float(-g @ damped_step(M, g, free, 0.0))
        if dec <= tol:
            return x, True, f"converged: Newton decrement {dec:.2g} <= {tol:g}", n
        step = damped_step(M, g, free, lam)
        xt = np.clip(x + step, lo, hi)  # (a parameter sent past a bound lands exactly on it)
        d = xt - x
        pred = float(-(g @ d) - 0.5 * d @ M @ d)
        trial = evaluate(xt) if pred > 0 else None
        n += 1
        gain = v - trial[0] if trial is not None else -np.inf
        lam = lam / 4 if gain >= 0.75 * pred else lam
        lam = lam if gain >= 0.25 * pred else max(4 * lam, 1e-3)
        if trial is not None and gain >= 1e-4 * pred:
            x = xt
            v, g, M = trial
            continue
        cut = _to_first_bound(x, step, lo, hi)
        if not np.array_equal(cut, xt) and n < max_nfev:
            # The step left the box and was clipped, which turns it away from the Newton
            # direction (near a bound, across a nearly flat direction of M, it need not
            # descend at all): try the step along the direction, cut where it reaches the
            # first bound (that parameter then sits on it and is held if its gradient
            # points out). (A step inside the box gives the point just rejected: no retry.)
            xt = cut
            d = xt - x
            pred = float(-(g @ d) - 0.5 * d @ M @ d)
            trial = evaluate(xt) if pred > 0 and np.any(d != 0) else None
            n += 1
            if trial is not None and v - trial[0] >= 1e-4 * pred:
                x = xt
                v, g, M = trial
                continue
        if lam > 1e8:
            if floor is not None and dec <= floor:
                # no step, however short, lowers V, at a point whose Newton decrement is
                # already below the floor: the rounding floor of V and of its difference
                # quotients (degenerate noise models), not a failure
                msg = f"converged: no decrease below rounding, Newton decrement {dec:.2g}"
                return x, True, msg, n
            flat = _flat_decrement(M, g, free) if floor is not None else None
            if flat is not None and floor is not None and flat[0] <= floor:
                # stationary in every direction the data determine; the rest of the
                # decrement lies along a direction of M flatter than FLAT_RATIO of its
                # largest curvature, along which no step lowered V either
                dec_id, ratio, direction = flat
                along = ", ".join(
                    f"{names[j] if names else j}: {c:+.2f}"
                    for j, c in zip(np.flatnonzero(free), direction, strict=True)
                    if abs(c) >= 0.05
                )
                msg = (
                    f"converged: stationary in the directions the data determine (Newton "
                    f"decrement {dec_id:.2g}); flat along ({along}), curvature {ratio:.1g} of "
                    "the largest, where no step lowers the criterion"
                )
                return x, True, msg, n
            if floor is not None:
                # the most any step inside the box could gain to first order: |g_i| times
                # the room to the bound it points to, summed over the free parameters
                room = np.where(g < 0, hi - x, x - lo)[free]
                reach = float(np.sum(np.abs(g[free]) * room))
                if reach <= floor:
                    # (a jitter scale collapsed onto its floor leaves the shape without
                    # information: M's entry for it vanishes, its Newton step is noise)
                    msg = (
                        "converged: no step can lower the criterion by more than its rounding "
                        f"floor inside the bounds (|gradient| times the room to the bounds: "
                        f"{reach:.2g})"
                    )
                    return x, True, msg, n
            return x, False, "no step decreases the criterion (damping exhausted)", n
    return x, False, f"evaluation budget ({max_nfev}) used up", n


#: curvature of M, relative to its largest (scaled), below which a direction is flat
FLAT_RATIO = 1e-6


def _flat_decrement(
    M: FloatArray, g: FloatArray, free: NDArray[np.bool_]
) -> tuple[float, float, FloatArray] | None:
    """(Newton decrement in the directions of scaled M's curvature above ``FLAT_RATIO`` of
    its largest, the flattest curvature's ratio, its direction over the free parameters),
    or None where no direction is that flat."""
    idx = np.flatnonzero(free)
    if idx.size < 2:
        return None
    Mf = M[np.ix_(idx, idx)]
    scale = np.sqrt(np.abs(np.diag(Mf)))
    scale[scale == 0] = 1.0
    w, V = np.linalg.eigh(Mf / np.outer(scale, scale))
    top = float(w[-1])
    if not top > 0 or w[0] > FLAT_RATIO * top:
        return None
    keep = w > FLAT_RATIO * top
    proj = V.T @ (g[idx] / scale)
    dec = float(np.sum(proj[keep] ** 2 / w[keep]))
    d = V[:, 0] / scale
    return dec, max(float(w[0]), 0.0) / top, d / np.max(np.abs(d))


def _to_first_bound(x: FloatArray, step: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """``x + t * step`` with the largest t in [0, 1] that keeps it inside [lo, hi], the
    parameter that reaches a bound set exactly on it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(step < 0, (lo - x) / step, np.where(step > 0, (hi - x) / step, np.inf))
    j = int(np.argmin(room))
    t = float(min(1.0, max(room[j], 0.0)))
    xt = np.clip(x + t * step, lo, hi)
    if t < 1.0:
        xt[j] = lo[j] if step[j] < 0 else hi[j]
    return xt


def damped_step(M: FloatArray, g: FloatArray, free: NDArray[np.bool_], lam: float) -> FloatArray:
    """-(M + lam diag M)^{-1} g on the free parameters, zero elsewhere (scaled Cholesky)."""
    step = np.zeros_like(g)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return step
    Mf = M[np.ix_(idx, idx)]
    scale = np.sqrt(np.abs(np.diag(Mf)))
    scale[scale == 0] = 1.0
    A = Mf / np.outer(scale, scale) + (lam + 1e-12) * np.eye(idx.size)
    try:
        L = np.linalg.cholesky(A)
        step[idx] = -np.linalg.solve(L.T, np.linalg.solve(L, g[idx] / scale)) / scale
    except np.linalg.LinAlgError:  # not positive definite: a scaled gradient step
        step[idx] = -g[idx] / scale**2 / (1.0 + lam)
    return step
