"""Box-Jenkins structures under jitter: the search behind ``fit(..., noise=...)``.

BJ (2b): system and noise model H free, jitter law known; JBJ (2d): the jitter family free
too. The criteria are in :mod:`jitterid.estimation.bjcriteria`. The search: an OE BCLS fit (Section
4.5); the noise parameters (and an unknown white std) fitted to its residuals by the
Gaussian criterion with the system fixed (multi-start over the noise structure's starts); a
generalised least-squares stage that whitens the residuals by that noise covariance and
restarts the system from the BCLS estimate and from the structure's starts (strong coloured
noise can put BCLS in a wrong basin, which the joint search would not leave); then the joint
search by L-BFGS-B in variables scaled by the start (trust-region least squares for
``wbcls``). ``bcls`` and ``wbcls`` keep the noise parameters of the residual fit (plug-in).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, minimize

from .._checks import real_array
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import NoiseModel, NoiseStructure, as_noise_structure
from ..simulate import SampledData
from ..systems.structures import ModelStructure, as_structure
from ..systems.tf import TransferFunction
from .bjcriteria import BJ_METHODS, LEAST_SQUARES, BJProblem, bj_covariance
from .problem import default_frequencies
from .result import FitResult, FitStatus

__all__ = ["BJ_METHODS", "fit_bj", "fitted_noise"]

FloatArray = NDArray[np.float64]

_BAD = 1e10  # criterion value where the model cannot be evaluated (unstable, not PD)


def _search(
    problem: BJProblem, x0: FloatArray, max_nfev: int, free: NDArray[np.bool_] | None = None
) -> tuple[FloatArray, float, FitStatus, str, int]:
    """Minimise the criterion over the free parameters from ``x0``."""
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    mask = lo < hi if free is None else free & (lo < hi)
    idx = np.flatnonzero(mask)

    def embed(z: FloatArray) -> FloatArray:
        out = x0.copy()
        out[idx] = z
        return out

    def value(x: FloatArray) -> float:
        # Overflow or a non-PD Sigma at a wild trial point is a bad point, not an error.
        with np.errstate(all="ignore"):
            try:
                v = problem.objective(x)
            except ValueError:
                return _BAD
        return v if np.isfinite(v) else _BAD

    if idx.size == 0:
        return x0, value(x0), FitStatus.CONVERGED, "no free parameters", 1
    if problem.method in LEAST_SQUARES:

        def resid(z: FloatArray) -> FloatArray:
            with np.errstate(all="ignore"):
                try:
                    r = problem.residuals(embed(z))
                except ValueError:
                    return np.full(2 * problem.freqs.size, _BAD)
            return r if np.all(np.isfinite(r)) else np.full(r.size, _BAD)

        sol = least_squares(resid, x0[idx], bounds=(lo[idx], hi[idx]), x_scale="jac", max_nfev=max_nfev)
        status = FitStatus.CONVERGED if sol.status > 0 else FitStatus.MAX_EVALUATIONS
        if sol.status < 0:
            status = FitStatus.OPTIMISER_FAILED
        z, nfev, msg = sol.x, int(sol.nfev), str(sol.message)
    else:
        # Search in units of the start: the parameters span orders of magnitude (gains, rates,
        # noise levels), which a quasi-Newton method started from the identity handles badly.
        scale = np.where(np.abs(x0[idx]) > 0, np.abs(x0[idx]), 1.0)
        bounds = [
            (None if np.isinf(a) else a / s, None if np.isinf(b) else b / s)
            for a, b, s in zip(lo[idx], hi[idx], scale, strict=True)
        ]
        sol = minimize(
            lambda u: value(embed(u * scale)),
            x0[idx] / scale,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxfun": max_nfev, "finite_diff_rel_step": 1e-7},
        )
        if sol.success:
            status = FitStatus.CONVERGED
        elif sol.nfev >= max_nfev:
            status = FitStatus.MAX_EVALUATIONS
        else:
            status = FitStatus.OPTIMISER_FAILED
        z, nfev, msg = sol.x * scale, int(sol.nfev), str(sol.message)
    x = embed(np.clip(z, lo[idx], hi[idx]))
    cost = value(x)
    if cost >= _BAD:
        status = FitStatus.NOT_FINITE
    return x, cost, status, msg, nfev


def _noise_stage(
    problem: BJProblem, x_pre: FloatArray, max_nfev: int
) -> tuple[FloatArray, int]:
    """Noise parameters (and sigma_w) by the Gaussian criterion with the system and jitter
    fixed at the BCLS estimate ``x_pre``: multi-start over the structure's starts."""
    nfixed = problem.n_jitter + problem.n_system
    stage = BJProblem(
        problem.data, problem.structure, problem.jitter, problem.noise, "gaussian",
        problem.freqs, problem.white_std,
    )
    mom = stage.moments(x_pre)
    resid, signal_var = problem.data.y - mom.mean, float(np.mean(mom.var))
    white = 0.0 if problem.white_std is None else problem.white_std**2
    power = float(np.var(resid))
    scale = float(np.sqrt(max(power - signal_var - white, 1e-4 * power, 1e-300)))
    free = np.arange(len(stage.names)) >= nfixed
    best: tuple[FloatArray, float] | None = None
    nfev = 0
    for eta in problem.noise.starts(problem.data.T, scale):
        tail = [0.3 * scale] if problem.white_std is None else []
        x0 = np.r_[x_pre, eta, tail]
        x, cost, _, _, n = _search(stage, x0, max_nfev, free)
        nfev += n
        if best is None or cost < best[1]:
            best = (x, cost)
    assert best is not None
    return best[0][nfixed:], nfev


def _whitened_stage(
    problem: BJProblem, x_pre: FloatArray, eta: FloatArray, max_nfev: int
) -> tuple[FloatArray, bool, int]:
    """System start by generalised least squares with Sigma_y fixed at (``x_pre``, ``eta``).

    When the coloured noise dominates some frequencies, the BCLS estimate (equal weights) can
    sit in a wrong basin that the joint search does not leave. Minimising the whitened
    residual ||L^{-1} L_a (y - m(theta))||^2 (:meth:`SampleCovariance.whiten`, (C4)) from the
    BCLS system and from each of the structure's starts (gains set by least squares) picks
    the basin by the BJ weighting. Returns (system parameters, whether they came from another
    start than BCLS, evaluations).
    """
    nj, ns = problem.n_jitter, problem.n_system
    if ns == 0:
        return x_pre[nj:], False, 0
    cov = problem.covariance(np.r_[x_pre, eta])
    y, jit = problem.data.y, x_pre[:nj]
    lo, hi = np.array(problem.structure.bounds, dtype=float).reshape(-1, 2).T

    def resid(theta: FloatArray) -> FloatArray:
        with np.errstate(all="ignore"):
            try:
                r = cov.whiten(y - problem.moments(np.r_[jit, theta]).mean)
            except ValueError:
                return np.full(y.size, _BAD)
        return r if np.all(np.isfinite(r)) else np.full(y.size, _BAD)

    gains = list(problem.structure.gain_params)
    wy = cov.whiten(y)
    best: tuple[FloatArray, float, int] | None = None
    nfev = 0
    for i, theta0 in enumerate([x_pre[nj:], *problem.structure.starts(problem.data.T)]):
        theta0 = np.clip(np.asarray(theta0, float), lo, hi)
        if i and gains:  # the mean is linear in the gains: give each start its GLS gain
            ws = wy - resid(theta0)
            if np.dot(ws, ws) > 0:
                theta0[gains] *= np.dot(wy, ws) / np.dot(ws, ws)
        sol = least_squares(resid, theta0, bounds=(lo, hi), x_scale="jac", max_nfev=min(max_nfev, 200))
        nfev += int(sol.nfev)
        if best is None or sol.cost < best[1]:
            best = (sol.x, float(sol.cost), i)
    assert best is not None
    return best[0], best[2] > 0, nfev


def fitted_noise(result: FitResult, noise: NoiseStructure | NoiseModel) -> NoiseModel:
    """The noise model H of a BJ/JBJ :class:`~jitterid.FitResult`, rebuilt from its parameters.

    Parameters
    ----------
    result : FitResult
        A result of ``fit(..., noise=noise)``.
    noise : NoiseStructure or NoiseModel
        The noise structure that was fitted (a NoiseModel is returned as it is).
    """
    structure = as_noise_structure(noise)
    params = result.params
    missing = [n for n in structure.param_names if n not in params]
    if missing:
        raise ValueError(
            f"result has no noise parameters {missing}: pass the noise structure it was fitted "
            f"with (its names are {result.names})"
        )
    return structure.model([params[n] for n in structure.param_names])


def fit_bj(
    data: SampledData,
    system: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str,
    start: ArrayLike | FitResult | None,
    *,
    noise: NoiseStructure | NoiseModel,
    freqs: ArrayLike | None,
    noise_std: float | None,
    max_nfev: int,
) -> FitResult:
    """:func:`jitterid.fit` with ``noise=``: the BJ (2b) and JBJ (2d) structures.

    Parameters are those of :func:`jitterid.fit`; ``noise`` is a structure with free
    parameters (``RationalNoise(0, 1)``) or a known :class:`~jitterid.NoiseModel`, and
    ``noise_std`` (default ``data.noise_std``) is the std of the additional white part,
    estimated as parameter ``noise_std`` by ``asml``, ``asml-diag``, ``gaussian`` when neither
    is given (``bcls``/``wbcls`` plug it in with the noise parameters).
    """
    from .fit import fit  # the OE fit gives the BCLS start (Section 4.5)

    if method not in BJ_METHODS:
        hint = " ('ls' ignores the jitter; fit it with noise=None)" if method == "ls" else ""
        raise ValueError(
            f"method must be one of {BJ_METHODS} when a noise model is given; got {method!r}{hint}"
        )
    structure = as_structure(system)
    nstruct = as_noise_structure(noise)
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData (see jitterid.simulate); got {type(data).__name__}")
    f = default_frequencies(data.N, data.T) if freqs is None else np.atleast_1d(real_array(freqs, "freqs"))
    white = data.noise_std if noise_std is None else noise_std
    free_noise = len(nstruct.param_names) > 0 or white is None
    make = partial(BJProblem, data, structure, jitter, nstruct, freqs=f, white_std=white)
    problem = make(method=method)
    nfev = 0
    if start is not None and not isinstance(start, FitResult):
        x0 = np.atleast_1d(real_array(start, "start"))
        if x0.size != len(problem.names):
            raise ValueError(f"start must have {len(problem.names)} values {problem.names}; got {x0.size}")
        if method in LEAST_SQUARES and free_noise:
            k = problem.n_jitter + problem.n_system
            problem = make(method=method, pinned=x0[k:])
        best = _search(problem, x0, max_nfev)
        nfev = best[4]
    else:
        pre = fit(data, structure, jitter, "bcls", start, freqs=f, max_nfev=max_nfev)
        nfev = pre.nfev
        x_pre = pre.x
        eta, n = _noise_stage(problem, x_pre, max_nfev) if free_noise else (np.zeros(0), 0)
        nfev += n
        if method != "bcls":  # bcls keeps its estimate; the others may start elsewhere
            theta, moved, n = _whitened_stage(problem, x_pre, eta, max_nfev)
            nfev += n
            if moved:  # another basin: refit the noise to its residuals
                x_pre = np.r_[x_pre[: problem.n_jitter], theta]
                if free_noise:
                    eta, n = _noise_stage(problem, x_pre, max_nfev)
                    nfev += n
        x0 = np.r_[x_pre, eta]
        if method in LEAST_SQUARES and free_noise:
            problem = make(method=method, pinned=eta)
        if method == "bcls":  # the noise model does not enter the BCLS criterion (14)
            best = (x0, problem.objective(x0), pre.status, pre.message, 0)
        else:
            best = _search(problem, x0, max_nfev)
            nfev += best[4]
    x, cost, status, msg, _ = best
    law, tf, noise_fitted, white_used = problem.split(x)
    return FitResult(
        method=method,
        names=problem.names,
        x=np.asarray(x, float),
        cost=float(cost),
        status=status,
        message=msg,
        nfev=nfev,
        system=tf,
        jitter_law=law,
        noise_std=white_used,
        freqs=f,
        cov=bj_covariance(problem, np.asarray(x, float)),
        cov_type="sandwich",
        structure=structure,
        jitter_model=jitter,
        noise_structure=nstruct,
        noise_model=noise_fitted,
    )
