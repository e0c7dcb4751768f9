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


def _residual_std(problem: Problem, x0: FloatArray) -> float:
    """The jitter std that explains the output-error residual variance at x0's system:
    Var(y_k - s(kT)) ~ E[s'(kT)^2] sigma_tau^2 + sigma_v^2 (first order in the jitter)."""
    lik = problem.likelihood
    assert lik is not None
    d = problem.data
    _, resp, sigma = lik.split(x0)
    t = d.t_nominal
    h = 1e-6 * d.T
    lo, hi = resp.start, np.nextafter(resp.end, -np.inf)
    tp, tm = np.clip(t + h, lo, hi), np.clip(t - h, lo, hi)
    slope = (resp(tp) - resp(tm)) / np.where(tp > tm, tp - tm, 1.0)
    excess = float(np.mean((d.y - resp(np.clip(t, lo, hi))) ** 2)) - sigma**2
    power = float(np.mean(slope**2))
    return float(np.sqrt(excess / power)) if excess > 0 and power > 0 else 0.0


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
    x, cost, ok, msg, n = _local(problem, starts[0][1], max_nfev - nfev)
    nfev += n
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
