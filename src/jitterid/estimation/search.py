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

from .status import FitStatus

__all__ = [
    "SEARCHES",
    "Coordinates",
    "Outcome",
    "SearchOptions",
    "SearchProblem",
    "damped_step",
    "evaluator",
    "newton_search",
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


Adapter = Callable[..., Outcome]
#: The search adapters by the key an estimator names (:attr:`Estimator.search`).
SEARCHES: dict[str, Adapter] = {}


def register_search(key: str) -> Callable[[Adapter], Adapter]:
    """Decorator: make an adapter ``f(problem, x0, max_nfev, free=None, tol=None) ->
    Outcome`` available to the estimators whose ``search`` is ``key``."""

    def deco(f: Adapter) -> Adapter:
        SEARCHES[key] = f
        return f

    return deco


P = TypeVar("P", bound=SearchProblem)


def run_search(
    problem: P,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
) -> tuple[P, Outcome]:
    """Minimise ``problem``'s criterion from ``x0`` with its estimator's adapter.

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
    rounds = est.freeze_rounds
    if not rounds:
        return problem, adapter(problem, x0, max_nfev, free, tol)
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    nfev = 0
    for _ in range(rounds):
        problem = replace(problem, weights_at=np.array(x0, float))  # type: ignore[type-var]
        out = adapter(problem, x0, max_nfev, free, tol)
        nfev += out.nfev
        x0 = out.x
    return problem, out._replace(nfev=nfev)


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


#: a stall: the last STALL_WINDOW accepted steps gained less than SearchOptions.stall_gain
STALL_WINDOW = 6


@register_search("newton")
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
    seen: dict[bytes, tuple[float, FloatArray, FloatArray]] = {}
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
        seen.clear()
        seen[z.tobytes()] = out
        if np.isfinite(v) and (not record or v < record[-1][0]):
            record.append((float(v), z.copy()))
        return out

    z0, lz, hz = cz.inverse(x0[idx]), cz.lo, cz.hi
    try:
        z, ok, msg, nfev = newton_search(evaluator(fun), z0, lz, hz, max_nfev, tol=opts.tol)
    except _Stalled:
        # A criterion whose infimum lies at the edge of the model (a white record: the
        # noise pole runs off to infinity, where H is white) decreases without end by
        # amounts far below one unit of V; the estimate of every identifiable parameter
        # has converged (newton_search has no relative-decrease test).
        z, ok, nfev = record[-1][1], True, n_eval[0]
        msg = f"converged: V decreased by < {stall:g} over {STALL_WINDOW} evaluations"
    floor = opts.rounding_floor
    if floor is not None and not ok and msg.startswith("no step decreases") and z.tobytes() in seen:
        # Damping exhausted: no step, however short, lowers V. At a point whose Newton
        # decrement is already far below one unit of V (-2 log-likelihood), that is the
        # rounding floor of V and of its difference quotients, not a failure (degenerate
        # noise models, e.g. a white-noise record, have flat directions).
        _, g, M = seen[z.tobytes()]
        free_z = ~(((z <= lz) & (g > 0)) | ((z >= hz) & (g < 0)))
        dec = float(-g @ damped_step(M, g, free_z, 0.0))
        if dec <= floor:
            ok, msg = True, f"converged: no decrease below rounding, Newton decrement {dec:.2g}"
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
    smooth: NDArray[np.bool_] | None = None,
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

    ``smooth`` (optional; default None: V is differentiable everywhere) marks the parameters
    in which V is differentiable; V may have kinks in the others (e.g. the exact likelihood
    in the shape n of SumOfUniformsFamily, at integer n), where no damping makes the full
    step acceptable. After a rejected step, an undamped Newton step on the free smooth
    parameters alone is tried (if their decrement exceeds ``tol``). Where those are
    stationary, a rejected full step that was predicted to decrease V by at most
    ``1e-6 max(1, |V|)`` but increased it is taken as a kink: converged, with a message
    saying so (as is exhausted damping with the smooth parameters stationary). With the
    smooth parameters stationary, a decrement of at most ``1e-6 max(1, |V|)`` in all of them
    is convergence too: a search that approaches a kink creeps, halving its distance at each
    step, and this is the precision to which the exact likelihood's quadrature is checked.

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
    while n < max_nfev:
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        dec = float(-g @ damped_step(M, g, free, 0.0))
        if dec <= tol:
            return x, True, f"converged: Newton decrement {dec:.2g} <= {tol:g}", n
        if smooth is not None and dec <= 1e-6 * max(1.0, abs(v)):
            dec_s = float(-g @ damped_step(M, g, free & smooth, 0.0))
            if dec_s <= tol:
                msg = (
                    f"converged: Newton decrement {dec_s:.2g} <= {tol:g} in the smooth "
                    f"parameters and {dec:.2g} <= 1e-6 |V| in all (the others may sit at a kink)"
                )
                return x, True, msg, n
        d = np.clip(x + damped_step(M, g, free, lam), lo, hi) - x
        pred = float(-(g @ d) - 0.5 * d @ M @ d)
        trial = evaluate(x + d) if pred > 0 else None
        n += 1
        gain = v - trial[0] if trial is not None else -np.inf
        lam = lam / 4 if gain >= 0.75 * pred else lam
        lam = lam if gain >= 0.25 * pred else max(4 * lam, 1e-3)
        if trial is not None and gain >= 1e-4 * pred:
            x = x + d
            v, g, M = trial
            continue
        if smooth is not None:
            inner = free & smooth
            dec_s = float(-g @ damped_step(M, g, inner, 0.0))
            if dec_s > tol and n < max_nfev:  # a Newton step in the smooth parameters alone
                d = np.clip(x + damped_step(M, g, inner, 0.0), lo, hi) - x
                pred_s = float(-(g @ d) - 0.5 * d @ M @ d)
                trial = evaluate(x + d) if pred_s > 0 else None
                n += 1
                if trial is not None and v - trial[0] >= 1e-4 * pred_s:
                    x = x + d
                    v, g, M = trial
                    continue
            elif (gain < 0 and pred <= 1e-6 * max(1.0, abs(v))) or lam > 1e8:
                msg = (
                    f"converged: stationary in the smooth parameters (decrement {dec_s:.2g}) "
                    "and no descent in the others, where the criterion is not differentiable "
                    "(e.g. SumOfUniformsFamily at integer n)"
                )
                return x, True, msg, n
        if lam > 1e8:
            return x, False, "no step decreases the criterion (damping exhausted)", n
    return x, False, f"evaluation budget ({max_nfev}) used up", n


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
