"""The exact-likelihood estimator's search (``method="ml"``): its scored starts, the
maximisation with the quadrature rule re-designed at the optimum, and the restart that keeps
a stop at zero jitter from being reported as the optimum. The likelihood itself is
:mod:`jitterid.estimation.likelihood`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..jitter.laws import JitterFamily
from .problem import Problem, free_moment_plans
from .search import WALK_TOL, Outcome, SearchProblem, piecewise, register_search
from .status import FitStatus

__all__ = ["likelihood_adapter", "run_ml"]

FloatArray = NDArray[np.float64]

#: A jitter std below this fraction of another scored start's counts as zero jitter (where
#: the likelihood, even in the scale, has a vanishing gradient).
_DEGENERATE = 1e-3


#: The continuation in the noise std (:func:`_continuation`) maximises at 10, 100, ... times a
#: known noise std up to this fraction of the samples' jitter spread (the jitter std times the
#: rms slope of the response): none where the known std is above a tenth of that
ROUGH_NOISE = 0.1
#: Below this fraction of the spread the stated errors were measured too small (session 19,
#: Table 2's system, N = 200: uniform jitter at 5e-4 of it 10 of 12 intervals covering per
#: parameter, Gaussian at 8e-4 6 of 10; at 4e-3, 15 of 16): the message says so
_COVERAGE_LOST = 1e-3


def _slope_power(problem: Problem, x0: FloatArray) -> tuple[float, float]:
    """(E[s'(kT)^2] over the samples at x0's system, the output-error residual mean square
    E[(y_k - s(kT))^2]), by central differences of the response."""
    lik = problem.likelihood
    assert lik is not None
    d = problem.data
    _, resp, _ = lik.split(x0)
    t = d.t_nominal
    h = 1e-6 * d.T
    lo, hi = resp.start, np.nextafter(resp.end, -np.inf)
    tp, tm = np.clip(t + h, lo, hi), np.clip(t - h, lo, hi)
    slope = (resp(tp) - resp(tm)) / np.where(tp > tm, tp - tm, 1.0)
    residual = float(np.mean((d.y - resp(np.clip(t, lo, hi))) ** 2))
    return float(np.mean(slope**2)), residual


def _residual_std(problem: Problem, x0: FloatArray) -> float:
    """The jitter std that explains the output-error residual variance at x0's system:
    Var(y_k - s(kT)) ~ E[s'(kT)^2] sigma_tau^2 + sigma_v^2 (first order in the jitter)."""
    assert problem.likelihood is not None
    sigma = problem.likelihood.split(x0)[2]
    power, residual = _slope_power(problem, x0)
    excess = residual - sigma**2
    return float(np.sqrt(excess / power)) if excess > 0 and power > 0 else 0.0


def _continuation(problem: Problem, x0: FloatArray, max_nfev: int) -> tuple[FloatArray, int, str]:
    """A start for the search at a known noise std far below the samples' jitter spread
    (below a tenth of ``ROUGH_NOISE`` of it), where the likelihood has many maxima: Table
    2's system, Gaussian jitter std 0.2, noise 1e-4, the search from the BCLS estimate ended
    CONVERGED at a mode 132 below the true one in 2 ln L, with a barrier of 39 between. The
    likelihood at a larger noise std is smoother, with its maximum near; so ln L is
    maximised at noise stds 10^k times the known one, from the largest below ROUGH_NOISE of
    the spread, each from the last's end. Returns the start, the evaluations used and a
    note for the message ("" where the noise is not small, or not known)."""
    lik = problem.likelihood
    assert lik is not None
    sigma = lik.noise_std
    if sigma is None:
        return x0, 0, ""
    try:
        power, _ = _slope_power(problem, x0)
        spread = lik.split(x0)[0].std * np.sqrt(power)
    except ValueError:
        return x0, 0, ""
    levels: list[float] = []
    while sigma * 10 ** (len(levels) + 1) <= ROUGH_NOISE * spread:
        levels.append(sigma * 10 ** (len(levels) + 1))
    if not levels:
        return x0, 0, ""
    x, nfev, y = x0, 0, problem.data.y
    tol = problem.search_options().tol
    for s in reversed(levels):
        try:
            xs, _, _, _, n = lik.with_noise(s).maximise(
                y, x, max_evaluations=max(max_nfev - nfev, 2), tol=tol
            )
        except ValueError:
            break
        nfev += n
        x = xs
        if nfev >= max_nfev:
            break
    note = (
        f"started by a continuation in the noise std from {10 ** len(levels):g} times the "
        f"known one, which is {sigma / spread:.2g} of the samples' jitter spread (below "
        f"{ROUGH_NOISE:g} of it the likelihood has many maxima)"
    )
    if sigma < _COVERAGE_LOST * spread:
        note += (
            "; at a noise std this small the stated errors have been measured too small "
            "(95 % intervals covering 0.5-0.85 at 5e-4 of the spread): read them as lower "
            "bounds, or take the intervals of method 'bcls' or 'asml', which hold there"
        )
    return x, nfev, note


def _candidates(problem: Problem, x0: FloatArray) -> list[FloatArray]:
    """Starts for a jitter family: x0 (the BCLS point), the family's default starts (the
    shapes at the scale that keeps x0's jitter std; a one-parameter family's default scales
    as they are), and every shape at the scale whose std explains the output-error residual
    variance (:func:`_residual_std`), all with x0's system and noise parameters."""
    jitter = problem.jitter
    assert isinstance(jitter, JitterFamily)
    lay = problem.layout
    nj = len(lay.jitter)
    scale = jitter.scale_index
    out = [x0]

    def add(params: FloatArray) -> None:
        cand = lay.replace(x0, "jitter", np.clip(params, *jitter_bounds))
        if not any(np.allclose(cand, c, rtol=1e-9, atol=0) for c in out):
            out.append(cand)

    lo, hi = lay.lower_upper()
    jitter_bounds = (lay.block(lo, "jitter"), lay.block(hi, "jitter"))
    defaults = [np.asarray(js, float) for js in jitter.default_starts(problem.data.T)]
    if scale is None:
        for js in defaults:
            add(js)
        return out
    std0 = jitter.law(lay.block(x0, "jitter").tolist()).std
    std_r = _residual_std(problem, x0)

    if nj == 1:
        for js in defaults:
            add(js)
    else:  # the shapes at x0's std
        for js in defaults:
            add(jitter.at_std(js, std0))
    if std_r > 0 and not 0.5 < std0 / std_r < 2:  # BCLS's std is not that of the residuals
        for js in [lay.block(x0, "jitter"), *defaults]:
            add(jitter.at_std(js, std_r))
    return out


def _ml_start(problem: Problem, x0: FloatArray) -> tuple[list[tuple[float, FloatArray]], int]:
    """The ML search's scored starts, best first: ``[(-2 ln L, x), ...]``, and the number of
    likelihood evaluations used.

    BCLS fixes the jitter's scale well (through the variances) but hardly its shape: on the
    paper's Table 3 data its criterion differs by 2e-4 (relative) between n = 0 and n = 8,
    and the n it returns is whatever the search stopped at. The likelihood does tell shapes
    apart, and is multimodal in n (with kinks at the integers), so the search from that n
    lands in a mode that depends on the BCLS iterate's last digits. And BCLS may stop at a
    jitter scale of zero (a legitimate minimum of its criterion in about one realization in
    64 on Table 2's system with Gaussian jitter), where the likelihood, even in the scale,
    has a vanishing gradient: a search from there never leaves. So every start of
    :func:`_candidates` is scored by one likelihood evaluation, and the search starts from the
    best (the BCLS point included).
    """
    lik = problem.likelihood
    assert lik is not None
    if not isinstance(problem.jitter, JitterFamily):
        return [(np.nan, x0)], 0
    y = problem.data.y
    scored = []
    cands = _candidates(problem, x0)
    for i, cand in enumerate(cands):
        try:
            v = -2 * lik.loglik(cand, y)
        except ValueError:
            v = np.inf
        scored.append((v if np.isfinite(v) else np.inf, i, cand))
    scored.sort(key=lambda item: (item[0], item[1]))
    return [(v, c) for v, _, c in scored], len(cands)


def _search(
    problem: Problem, x0: FloatArray, max_nfev: int, tol: float | None = None
) -> tuple[FloatArray, float, bool, str, int]:
    """Maximise the exact likelihood from x0 to the Newton decrement ``tol`` (None: the
    problem's, :meth:`Problem.search_options`); the full quadrature rule, designed at the
    start, is re-designed at the optimum, and the search resumed if ln L moved by more than
    1e-6 (the windowed rule re-designs itself wherever it stops fitting)."""
    lik, y = problem.likelihood, problem.data.y
    assert lik is not None
    if tol is None:
        tol = problem.search_options().tol  # (KINKED_TOL with a kinked shape)
    x, loglik, ok, msg, nfev = lik.maximise(y, x0, max_evaluations=max(max_nfev, 2), tol=tol)
    for _ in range(3):
        if lik.windowed:  # re-designed wherever it stopped fitting: valid at x already
            break
        lik.design(x)
        fresh = lik.loglik(x, y)
        nfev += 1
        if abs(fresh - loglik) <= 1e-6 * max(1.0, abs(fresh)):
            loglik = fresh
            break
        x, loglik, ok, msg, n = lik.maximise(y, x, max_evaluations=max(max_nfev - nfev, 2), tol=tol)
        nfev += n
    return x, -2 * loglik, ok, msg, nfev


def _local(
    problem: Problem, x0: FloatArray, max_nfev: int
) -> tuple[FloatArray, float, bool, str, int]:
    """:func:`_search` from x0, one smooth piece at a time where the family has kinks
    (:func:`jitterid.estimation.search.piecewise`)."""

    def one(p: SearchProblem, x: FloatArray, budget: int, tol: float | None) -> Outcome:
        assert p is problem
        xs, cost, ok, msg, n = _search(problem, x, budget, tol)
        return Outcome(xs, cost, FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED, msg, n)

    out = piecewise(problem, x0, one, max_nfev, walk_tol=WALK_TOL)
    return out.x, out.cost, out.status is FitStatus.CONVERGED, out.message, out.nfev


def run_ml(
    problem: Problem, x0: FloatArray, max_nfev: int
) -> tuple[FloatArray, float, FitStatus, str, int]:
    """Maximise the exact likelihood from the best scored start (:func:`_ml_start`).

    A stop that another scored start beats is not the optimum: the search is restarted from
    the best start whose score is better than the stop's -2 ln L by more than 1e-6
    (relative), and, where the stop has zero jitter (std below 1e-3 of a scored start's),
    from the best-scored start with a jitter std that is not zero; the best end is kept.
    """
    lik = problem.likelihood
    assert lik is not None
    free_moment_plans(problem.data.N)  # not used by the likelihood
    starts, nfev = _ml_start(problem, x0)
    first, n, note = _continuation(problem, starts[0][1], max_nfev - nfev)
    nfev += n
    x, cost, ok, msg, n = _local(problem, first, max_nfev - nfev)
    nfev += n
    if note:
        msg = f"{msg}; {note}"
    tried, widened = {0}, False
    while isinstance(problem.jitter, JitterFamily) and nfev < max_nfev:
        tol = 1e-6 * max(1.0, abs(cost))
        std = lik.split(x)[0].std
        rest = [i for i in range(len(starts)) if i not in tried]
        better = [i for i in rest if starts[i][0] < cost - tol]
        wider = [i for i in rest if std < _DEGENERATE * lik.split(starts[i][1])[0].std]
        if better:
            i = better[0]
        elif wider and not widened:  # one restart away from zero jitter
            i, widened = wider[0], True
        else:
            break
        tried.add(i)
        out = _local(problem, starts[i][1], max_nfev - nfev)
        nfev += out[4]
        if out[1] < cost - tol:
            x, cost, ok = out[0], out[1], out[2]
            msg = f"{out[3]} (after a restart from a scored start)"
    status = FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED
    if not ok and nfev >= max_nfev:
        status = FitStatus.MAX_EVALUATIONS
    if not np.isfinite(cost):
        status = FitStatus.NOT_FINITE
    return x, cost, status, msg, nfev


@register_search("likelihood", own_pieces=True)
def likelihood_adapter(
    problem: Problem,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
) -> Outcome:
    """The search adapter of the exact likelihood (:data:`jitterid.estimation.search
    .SEARCHES`, key ``"likelihood"``): :func:`run_ml` from ``x0`` clipped to the bounds.
    ``free`` and ``tol`` are not used (the likelihood's search has its own tolerances and
    searches every parameter)."""
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(x0, lo, hi)
    if x0.size == 0:
        return Outcome(x0, problem.objective(x0), FitStatus.CONVERGED, "no free parameters", 1)
    return Outcome(*run_ml(problem, x0, max_nfev))
