"""fit(): one entry point for every estimator of the paper.

The search follows Section 4.5: an ordinary output-error fit that ignores the jitter gives
the system's starting point; for a free jitter law a small grid of starting values is
tried; the weighted and likelihood criteria start from the BCLS estimate. Least-squares
criteria are minimised by scipy's trust-region Gauss-Newton/Levenberg-Marquardt
(``least_squares``), the exact likelihood (``ml``) by the damped Newton iteration of
:meth:`jitterid.likelihood.ExactLikelihood.maximise`, the others by L-BFGS-B; all respect
the bounds.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, minimize
from threadpoolctl import threadpool_limits

from ._checks import real_array
from .criteria import (
    LEAST_SQUARES,
    METHODS,
    NEEDS_NOISE,
    Problem,
    default_frequencies,
)
from .distributions import JitterFamily, JitterLaw
from .models import TransferFunction
from .result import FitResult, FitStatus
from .sandwich import sandwich_covariance
from .simulate import SampledData
from .structures import ModelStructure, as_structure

__all__ = ["fit"]

FloatArray = NDArray[np.float64]
_BAD = 1e10  # residual returned where the model cannot be evaluated (e.g. unstable)


def _oe_start(data: SampledData, structure: ModelStructure) -> tuple[FloatArray, float]:
    """Ordinary output-error fit ignoring jitter (time domain); returns (theta, rms residual)."""
    t = data.t_nominal
    if not structure.param_names:
        resid = data.y - structure.system(()).response(data.u)(t)
        return np.zeros(0), float(np.sqrt(np.mean(resid**2)))

    def resid(x: FloatArray) -> FloatArray:
        try:
            return data.y - structure.system(x).response(data.u)(t)
        except ValueError:
            return np.full(data.N, _BAD)

    lo, hi = np.array(structure.bounds).T
    # Score every start by one evaluation; search from the best only (a start with the
    # right time scale is what matters, and each full search costs ~30 evaluations).
    gains = list(structure.gain_params)
    scored = []
    for x0 in structure.starts(data.T):
        x0 = np.clip(x0, lo, hi)
        s = data.y - resid(x0)
        if gains and np.dot(s, s) > 0:  # give each start its least-squares gain
            x0[gains] *= np.dot(data.y, s) / np.dot(s, s)
        scored.append((float(np.sum(resid(x0) ** 2)), x0))
    x0 = min(scored, key=lambda item: item[0])[1]
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
    return sol.x, float(np.sqrt(2 * sol.cost / data.N))


def _run(problem: Problem, x0: FloatArray, max_nfev: int) -> tuple[FloatArray, float, FitStatus, str, int]:
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(x0, lo, hi)
    if x0.size == 0:
        return x0, problem.objective(x0), FitStatus.CONVERGED, "no free parameters", 1
    if problem.method == "ml":
        return _run_ml(problem, x0, max_nfev)
    if problem.method in LEAST_SQUARES:

        def resid(x: FloatArray) -> FloatArray:
            try:
                return problem.residuals(x)
            except ValueError:
                return np.full(2 * problem.freqs.size, _BAD)

        sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev)
        status = FitStatus.CONVERGED if sol.status > 0 else FitStatus.MAX_EVALUATIONS
        if sol.status < 0:
            status = FitStatus.OPTIMISER_FAILED
        x, nfev, msg = sol.x, int(sol.nfev), str(sol.message)
    else:

        def obj(x: FloatArray) -> float:
            try:
                v = problem.objective(x)
            except ValueError:
                return _BAD
            return v if np.isfinite(v) else _BAD

        bounds = [(None if np.isinf(a) else a, None if np.isinf(b) else b) for a, b in zip(lo, hi, strict=True)]
        sol = minimize(
            obj,
            x0,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxfun": max_nfev, "finite_diff_rel_step": 1e-7},
        )
        if sol.success:
            status = FitStatus.CONVERGED
        elif sol.nfev >= max_nfev or sol.nit >= 15000:
            status = FitStatus.MAX_EVALUATIONS
        else:
            status = FitStatus.OPTIMISER_FAILED
        x, nfev, msg = sol.x, int(sol.nfev), str(sol.message)
    cost = problem.objective(x)
    if not np.isfinite(cost) or cost >= _BAD:
        status = FitStatus.NOT_FINITE
    return x, cost, status, msg, nfev


def _run_ml(problem: Problem, x0: FloatArray, max_nfev: int) -> tuple[FloatArray, float, FitStatus, str, int]:
    """Maximise the exact likelihood; the quadrature rule, designed at the start, is
    re-designed at the optimum, and the search resumed if ln L moved by more than 1e-6."""
    lik, y = problem.likelihood, problem.data.y
    assert lik is not None
    x, loglik, ok, msg, nfev = lik.maximise(y, x0, max_evaluations=max_nfev)
    for _ in range(3):
        lik.design(x)
        fresh = lik.loglik(x, y)
        nfev += 1
        if abs(fresh - loglik) <= 1e-6 * max(1.0, abs(fresh)):
            break
        x, loglik, ok, msg, n = lik.maximise(y, x, max_evaluations=max(max_nfev - nfev, 2))
        nfev += n
    status = FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED
    if not ok and nfev >= max_nfev:
        status = FitStatus.MAX_EVALUATIONS
    cost = -2 * lik.loglik(x, y)
    if not np.isfinite(cost):
        status = FitStatus.NOT_FINITE
    lik._cache.clear()  # the nodes (MBs) are rebuilt from the kept design if cov is asked for
    return x, cost, status, msg, nfev


def fit(
    data: SampledData,
    system: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str = "bcls",
    start: ArrayLike | FitResult | None = None,
    *,
    freqs: ArrayLike | None = None,
    noise_std: float | None = None,
    max_nfev: int = 2000,
) -> FitResult:
    """Estimate a continuous-time model from jittered samples.

    Parameters
    ----------
    data : SampledData
        Samples y_k requested at kT, the known input, and (optionally) the noise std.
    system : ModelStructure or TransferFunction
        A structure with free parameters (``PolePairGain()``, ``RationalModel(m, n)``) or a
        known system (its parameters are then not estimated, as in Table 1).
    jitter : JitterLaw or JitterFamily
        A known jitter law (OE structure (2a)) or a family with free parameters (JOE, (2c)).
    method : str
        ``"ls"`` (8), ``"bcls"`` (14), ``"wbcls"`` (20), ``"asml"`` (22), ``"asml-diag"`` (23),
        ``"gaussian"`` (the exact real-valued Gaussian criterion, notes section 3) or ``"ml"``
        (the exact likelihood, notes section 4; :mod:`jitterid.likelihood`).
    start : array_like or FitResult, optional
        Starting vector in the result's ``names`` order. Default: an ordinary OE fit that
        ignores the jitter (Section 4.5) and, for a free jitter law, a grid of starts, then
        (for every method but ``ls`` and ``bcls``) a BCLS fit. A ``bcls`` :class:`FitResult`
        of the same data, structure and jitter model skips that first stage: fitting several
        methods to one data set then costs the BCLS search once, with results identical to
        independent calls.
    freqs : array_like, optional
        Frequency set in Hz. Default (24): f_k = k/(NT), k = 0..floor(N/2)-1.
    noise_std : float, optional
        Measurement-noise std; default ``data.noise_std``. When neither is given, the
        ``asml``/``asml-diag``/``gaussian``/``ml`` criteria estimate it as a parameter and
        ``wbcls`` uses a plug-in estimate from the BCLS residuals. ``ml`` needs it > 0.
    max_nfev : int
        Evaluation budget for each search.

    Returns
    -------
    FitResult
        Check ``success``: a failed search is reported as failed, never as a good fit.
    """
    # Small complex BLAS calls (Cholesky, matmul) run ~100x slower multi-threaded here;
    # one thread is faster, and parallelism belongs to the Monte Carlo level.
    with threadpool_limits(limits=1, user_api="blas"):
        return _fit(data, system, jitter, method, start, freqs=freqs, noise_std=noise_std, max_nfev=max_nfev)


def _fit(
    data: SampledData,
    system: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str = "bcls",
    start: ArrayLike | FitResult | None = None,
    *,
    freqs: ArrayLike | None = None,
    noise_std: float | None = None,
    max_nfev: int = 2000,
) -> FitResult:
    prefit = start if isinstance(start, FitResult) else None
    if prefit is not None:
        start = None
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}; got {method!r}")
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData (see jitterid.simulate); got {type(data).__name__}")
    structure = as_structure(system)
    if not isinstance(jitter, (JitterLaw, JitterFamily)):
        raise TypeError(
            "jitter must be a jitter law (Uniform(a), Gaussian(sigma), SumOfUniforms(n, a), ...) "
            f"or a family (SumOfUniformsFamily(), ...); got {type(jitter).__name__}"
        )
    if method == "ls" and isinstance(jitter, JitterFamily):
        raise ValueError(
            "method 'ls' ignores the jitter, so it cannot estimate jitter parameters; "
            "pass a known law (or NoJitter()) or use 'bcls'/'asml'"
        )
    if method == "ls" and not structure.param_names:
        raise ValueError("method 'ls' with a known system has nothing to estimate")
    f = default_frequencies(data.N, data.T) if freqs is None else np.atleast_1d(real_array(freqs, "freqs"))
    if f.size < 1:
        raise ValueError("freqs must hold at least one frequency")
    noise = data.noise_std if noise_std is None else noise_std
    if method == "ml" and noise is not None and not noise > 0:
        raise ValueError(
            "method 'ml' needs measurement noise: the exact likelihood of noise-free samples "
            f"is singular (noise_std = {noise!r}); pass a positive noise_std"
        )
    make = partial(Problem, data, structure, jitter, freqs=f)

    jstarts: Sequence[Sequence[float]] = (
        jitter.default_starts(data.T) if isinstance(jitter, JitterFamily) else [()]
    )
    nfev = 0
    rms: float | None = None
    if start is not None:
        problem = make(method=method, noise_std=noise if method in NEEDS_NOISE else None)
        if method == "wbcls" and noise is None:
            theta_sys = _oe_start(data, structure)[0]
            problem = make(method=method, noise_std=_plugin_noise(make, theta_sys, jstarts, max_nfev))
        x0 = np.atleast_1d(real_array(start, "start"))
        if x0.size != len(problem.names):
            raise ValueError(f"start must have {len(problem.names)} values {problem.names}; got {x0.size}")
        best = _run(problem, x0, max_nfev)
        nfev = best[4]
    else:
        first = "ls" if method == "ls" else "bcls"
        pre = make(method=first, noise_std=None)
        best = None
        if prefit is not None:
            _check_prefit(prefit, pre)
            best = (prefit.x, prefit.cost, prefit.status, prefit.message, prefit.nfev)
            nfev = prefit.nfev
        else:
            theta_sys, rms = _oe_start(data, structure)
            for js in jstarts:
                out = _run(pre, np.r_[np.asarray(js, float), theta_sys], max_nfev)
                nfev += out[4]
                if best is None or out[1] < best[1]:
                    best = out
        assert best is not None
        if method != first:
            x_pre = best[0]
            if method == "wbcls" and noise is None:
                noise = _noise_from_residuals(pre, x_pre)
            problem = make(method=method, noise_std=noise if method in NEEDS_NOISE else None)
            if problem.estimates_noise and rms is None:
                rms = _oe_start(data, structure)[1]
            noise0 = max(rms or 0.0, 1e-6)
            if method == "ml":  # the likelihood's cost grows like 1/noise: start close
                noise0 = max(_noise_from_residuals(pre, x_pre), 0.05 * (rms or 0.0), 1e-12)
            x0 = np.r_[x_pre, noise0] if problem.estimates_noise else x_pre
            best = _run(problem, x0, max_nfev)
            nfev += best[4]
        else:
            problem = pre
    x, cost, status, msg, _ = best
    law, tf, noise_used = problem.split(x)
    return FitResult(
        method=method,
        names=problem.names,
        x=np.asarray(x, float),
        cost=float(cost),
        status=status,
        message=msg,
        nfev=nfev,
        system=tf,
        jitter=law,
        noise_std=noise_used,
        freqs=f,
        _covariance=partial(sandwich_covariance, problem, np.asarray(x, float)),
        structure=structure,
    )


def _check_prefit(prefit: FitResult, pre: Problem) -> None:
    """A ``start`` FitResult must be the BCLS fit of this very problem (same data, structure,
    jitter model and frequencies): its cost, re-evaluated here, must match."""
    if prefit.method != pre.method or prefit.names != pre.names:
        raise ValueError(
            f"start: a FitResult passed as start must come from fit(..., method={pre.method!r}) "
            f"with parameters {pre.names}; got method {prefit.method!r} with {prefit.names}"
        )
    if not prefit.success:
        raise ValueError(
            f"start: the {pre.method} fit passed as start did not converge ({prefit.status.name}); "
            "fit without it, or from a parameter vector"
        )
    cost = pre.objective(prefit.x)
    if prefit.freqs.shape != pre.freqs.shape or not np.allclose(prefit.freqs, pre.freqs) or not np.isclose(
        cost, prefit.cost, rtol=1e-9, atol=0.0
    ):
        raise ValueError(
            "start: the FitResult passed as start was fitted to other data, jitter model or "
            "frequencies (its cost does not match this problem); fit it to the same data first"
        )


def _noise_from_residuals(bcls: Problem, x: FloatArray) -> float:
    """Plug-in sigma_v^2 from E|Y - mu|^2 = R(f, f) = sum_k Var s_k + N sigma_v^2 (notes 2)."""
    r = bcls.residuals(x)
    power = float(np.sum(r**2)) / bcls.freqs.size
    signal_var = float(np.sum(bcls.moments(x).var))
    return float(np.sqrt(max(power - signal_var, 1e-12 * power) / bcls.data.N))


def _plugin_noise(make: partial[Problem], theta_sys: FloatArray, jstarts: Sequence[Sequence[float]], max_nfev: int) -> float:
    pre = make(method="bcls", noise_std=None)
    out = _run(pre, np.r_[np.asarray(jstarts[0], float), theta_sys], max_nfev)
    return _noise_from_residuals(pre, out[0])
