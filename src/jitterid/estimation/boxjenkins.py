"""Box-Jenkins structures under jitter: the search behind ``fit(..., noise=...)``.

BJ (2b): system and noise model H free, jitter law known; JBJ (2d): the jitter family free
too. The criteria are in :mod:`jitterid.estimation.bjcriteria`. The search: an OE BCLS fit (Section
4.5); the noise parameters (and an unknown white std) fitted to its residuals by the
Gaussian criterion with the system fixed (from the best of the noise structure's starts); a
generalised least-squares stage that whitens the residuals by that noise covariance and
restarts the system from the BCLS estimate and from the structure's starts (strong coloured
noise can put BCLS in a wrong basin, which the joint search would not leave); then the joint
search: the project's one Newton (Fisher scoring) search
(:func:`jitterid.estimation.search.newton_search`) with the criteria's analytic gradients and
expected Hessians (trust-region least squares for the least-squares estimators, ``wbcls``).
Estimators that do not identify the noise model (``bcls``, ``wbcls``) keep the noise
parameters of the residual fit (plug-in).

As the OE search, it runs in the power-of-two units of :class:`checks.Scaling` (the noise
structure's gain parameters scaled with y) and ends with :func:`checks.post_checks`, so that a
fit's status is honest and does not depend on the data's units (:func:`fit_bj`).

Every stage reads the estimator's declared properties (:class:`~jitterid.estimation
.estimators.base.Estimator`: ``coloured_noise``, ``least_squares``,
``identifies_noise_model``, ``weighs_by_noise``, ``freeze_rounds``), never its name; the
stages that need a particular criterion use its object (the BCLS pre-fit, the Gaussian noise
stage).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .._checks import real_array
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import KnownNoise, NoiseModel, NoiseStructure, as_noise_structure
from ..simulate import SampledData
from ..systems.structures import ModelStructure, as_structure
from ..systems.tf import TransferFunction
from .bjcriteria import BJProblem, bj_covariance
from .checks import PostContext, Scaling, post_checks
from .estimators import BCLS, Estimator, GaussianCriterion, as_estimator, coloured_method_names
from .jacobians import moment_derivatives
from .problem import default_frequencies
from .result import FitResult, FitStatus
from .search import damped_step, evaluator, newton_search

__all__ = ["BJ_METHODS", "fit_bj", "fitted_noise"]

FloatArray = NDArray[np.float64]

#: The registered estimators with a coloured-noise form at import (``fit_bj`` asks the
#: registry at each call, so an estimator registered later is accepted too).
BJ_METHODS = coloured_method_names()

_BAD = 1e10  # criterion value where the model cannot be evaluated (unstable, not PD)
# Newton decrement (twice the predicted remaining decrease of V = -2 log-likelihood) at which
# the search stops: 1e-6 units of V moves the estimate by ~1e-3 standard errors.
NEWTON_TOL = 1e-6
_RATE_SPAN = 1e6  # most a rate searched in log units moves from its start (_Coordinates)
_FAST = 100.0  # GLS stage: systems with a pole beyond _FAST times the Nyquist rate are refused
# The noise and GLS stages only give the joint search its start: converged loosely (the joint
# search refines every parameter to NEWTON_TOL), they cost a few evaluations less each.
STAGE_TOL, STAGE_FTOL = 1e-2, 1e-5
STALL_TOL = 1e-3  # decrement below which "no step decreases V" is the rounding floor
STALL_WINDOW, STALL_GAIN = 6, 1e-4  # stop when the last 6 accepted steps gained < 1e-4 in all


class _Stalled(Exception):
    """Raised inside the Newton search's evaluation to stop it (see _search)."""


class _Coordinates:
    """Search coordinates z for the Newton search (x = x(z) elementwise):

    - a rate with a positive floor and no upper bound (noise poles ``ha*``, a jitter scale):
      z = ln x. The criterion varies on the rate's relative scale, and a Newton step in the
      rate itself overshoots to the floor, where the noise model degenerates;
    - a gain bounded below by 0 (``hb0``) and the white std ``noise_std``: z = x^2, the
      variance they carry. Sigma_y depends on them through x^2, so the Fisher information
      in x vanishes like x^2 as x -> 0 (a white record drives one of them there), and a
      Newton step in x explodes; in x^2 it is regular;
    - anything else: z = x.
    """

    def __init__(
        self, names: NDArray[np.str_], lo: FloatArray, hi: FloatArray, x0: FloatArray
    ) -> None:
        unbounded = np.isinf(hi)
        self.square = unbounded & (names == "noise_std")
        self.log = unbounded & (lo > 0) & ~self.square
        self.lo = np.where(self.log, np.log(np.where(self.log, lo, 1.0)), lo)
        self.lo = np.where(self.square, np.maximum(lo, 1e-150) ** 2, self.lo)
        # A rate may move by a factor _RATE_SPAN from its start at most: where it is not
        # identified (a noise gain at 0 leaves its pole free) the Newton steps in ln x are
        # ratios of vanishing numbers and would carry it to 1e100 and beyond.
        span = np.log(
            np.maximum(np.where(self.log, x0, 1.0), np.where(self.log, lo, 1.0))
        ) + np.log(_RATE_SPAN)
        self.hi = np.where(self.log, span, hi)

    def forward(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """x(z) and dx/dz."""
        x = np.where(self.log, np.exp(np.minimum(np.where(self.log, z, 0.0), 700.0)), z)
        x = np.where(self.square, np.sqrt(np.maximum(np.where(self.square, z, 1.0), 0.0)), x)
        jac = np.where(self.log, x, 1.0)
        jac = np.where(self.square, 0.5 / np.maximum(np.where(self.square, x, 1.0), 1e-150), jac)
        return x, jac

    def inverse(self, x: FloatArray) -> FloatArray:
        z = np.where(self.log, np.log(np.where(self.log, x, 1.0)), x)
        return np.clip(np.where(self.square, x * x, z), self.lo, self.hi)


def _search(
    problem: BJProblem,
    x0: FloatArray,
    max_nfev: int,
    free: NDArray[np.bool_] | None = None,
    tol: float | None = None,
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
    if problem.estimator.least_squares:

        def resid(z: FloatArray) -> FloatArray:
            with np.errstate(all="ignore"):
                try:
                    r = problem.residuals(embed(z))
                except ValueError:
                    return np.full(2 * problem.freqs.size, _BAD)
            return r if np.all(np.isfinite(r)) else np.full(r.size, _BAD)

        jac: str | Callable[[FloatArray], FloatArray] = "2-point"
        if problem.has_jacobian:

            def jac(z: FloatArray) -> FloatArray:
                try:
                    return problem.jacobian(embed(z))[:, idx]
                except ValueError:  # only where resid failed too; such a step is never taken
                    return np.zeros((2 * problem.freqs.size, idx.size))

        sol = least_squares(
            resid, x0[idx], jac=jac, bounds=(lo[idx], hi[idx]), x_scale="jac", max_nfev=max_nfev
        )
        status = FitStatus.CONVERGED if sol.status > 0 else FitStatus.MAX_EVALUATIONS
        if sol.status < 0:
            status = FitStatus.OPTIMISER_FAILED
        z, nfev, msg = sol.x, int(sol.nfev), str(sol.message)
    else:
        # The one Newton (Fisher scoring) search of the OE path, with the analytic gradient
        # and expected Hessian of the BJ criterion (BJProblem.objective_gradient), in
        # coordinates where the Fisher information stays away from zero (_Coordinates).
        cz = _Coordinates(np.array(problem.names)[idx], lo[idx], hi[idx], x0[idx])
        seen: dict[bytes, tuple[float, FloatArray, FloatArray]] = {}
        # (V, z) of the evaluations that lowered V (accepted steps; rejected trials are the
        # search's own damping and do not count towards a stall)
        record: list[tuple[float, FloatArray]] = []

        n_eval = [0]
        # a loose stage (tol above NEWTON_TOL) stalls as loosely: gains below its tolerance
        stall_gain = STALL_GAIN if tol is None else max(STALL_GAIN, tol)

        def fun(z: FloatArray) -> tuple[float, FloatArray, FloatArray]:
            n_eval[0] += 1
            if (
                len(record) > STALL_WINDOW
                and record[-STALL_WINDOW - 1][0] - record[-1][0] < stall_gain
            ):
                raise _Stalled  # the last STALL_WINDOW accepted steps gained < stall_gain
            xs, jac = cz.forward(z)
            with np.errstate(all="ignore"):
                try:
                    v, g, M = problem.objective_gradient(embed(xs), idx)
                except (OverflowError, ZeroDivisionError):  # a wild trial point: rejected
                    raise ValueError("criterion overflows") from None
                out = (v, g[idx] * jac, M[np.ix_(idx, idx)] * np.outer(jac, jac))
            seen.clear()
            seen[z.tobytes()] = out
            if np.isfinite(v) and (not record or v < record[-1][0]):
                record.append((float(v), z.copy()))
            return out

        z0, lz, hz = cz.inverse(x0[idx]), cz.lo, cz.hi
        try:
            z, ok, msg, nfev = newton_search(
                evaluator(fun), z0, lz, hz, max_nfev, tol=NEWTON_TOL if tol is None else tol
            )
        except _Stalled:
            # A criterion whose infimum lies at the edge of the model (a white record: the
            # noise pole runs off to infinity, where H is white) decreases without end by
            # amounts far below one unit of V; the estimate of every identifiable parameter
            # has converged. (search.newton_search has no relative-decrease test.)
            z, ok, nfev = record[-1][1], True, n_eval[0]
            msg = f"converged: V decreased by < {stall_gain:g} over {STALL_WINDOW} evaluations"
        if not ok and msg.startswith("no step decreases") and z.tobytes() in seen:
            # Damping exhausted: no step, however short, lowers V. At a point whose Newton
            # decrement is already far below one unit of V (-2 log-likelihood), that is the
            # rounding floor of V and of the difference quotients of gamma, not a failure
            # (degenerate noise models, e.g. a white-noise record, have flat directions).
            _, g, M = seen[z.tobytes()]
            free_z = ~(((z <= lz) & (g > 0)) | ((z >= hz) & (g < 0)))
            dec = float(-g @ damped_step(M, g, free_z, 0.0))
            if dec <= STALL_TOL:
                ok, msg = True, f"converged: no decrease below rounding, Newton decrement {dec:.2g}"
        z = cz.forward(z)[0]
        status = FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED
        if not ok and nfev >= max_nfev:
            status = FitStatus.MAX_EVALUATIONS
    x = embed(np.clip(z, lo[idx], hi[idx]))
    cost = value(x)
    if cost >= _BAD:
        status = FitStatus.NOT_FINITE
    return x, cost, status, msg, nfev


def _noise_stage(
    problem: BJProblem, x_pre: FloatArray, max_nfev: int, start: FloatArray | None = None
) -> tuple[FloatArray, int]:
    """Noise parameters (and sigma_w) by the Gaussian criterion with the system and jitter
    fixed at ``x_pre``: from ``start`` if given, else from the best of the structure's starts
    scored by one criterion evaluation each (as the OE start is chosen, fit._oe_start): the
    system is fixed, so the criterion of the noise parameters is cheap and smooth, and every
    start converged to the same point in the tests while each search costs ~15 evaluations."""
    nfixed = problem.n_jitter + problem.n_system
    stage = BJProblem(
        problem.data,
        problem.structure,
        problem.jitter,
        problem.noise,
        GaussianCriterion(),
        problem.freqs,
        problem.white_std,
    )
    free = np.arange(len(stage.names)) >= nfixed
    if start is not None:
        x, _, _, _, nfev = _search(stage, np.r_[x_pre, start], max_nfev, free, STAGE_TOL)
        return x[nfixed:], nfev
    mom = stage.moments(x_pre)
    resid, signal_var = problem.data.y - mom.mean, float(np.mean(mom.var))
    white = 0.0 if problem.white_std is None else problem.white_std**2
    power = float(np.var(resid))
    scale = float(np.sqrt(max(power - signal_var - white, 1e-4 * power, 1e-300)))
    scored: list[tuple[float, FloatArray]] = []
    for eta in problem.noise.starts(problem.data.T, scale):
        tail = [0.3 * scale] if problem.white_std is None else []
        x0 = np.r_[x_pre, eta, tail]
        with np.errstate(all="ignore"):
            try:
                v = stage.objective(x0)
            except ValueError:
                v = np.inf
        scored.append((v if np.isfinite(v) else np.inf, x0))
    x0 = min(scored, key=lambda item: item[0])[1]
    x, _, _, _, n = _search(stage, x0, max_nfev, free, STAGE_TOL)
    return x[nfixed:], n + len(scored)


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

    fastest = _FAST * np.pi / problem.data.T

    def resid(theta: FloatArray) -> FloatArray:
        with np.errstate(all="ignore"):
            try:
                # A trust-region step far out (a resonance hundreds of times above the
                # Nyquist rate) is refused before its moments are formed: their quadrature
                # plan grows with the pole's rate (one such evaluation cost ~0.8 s).
                if np.max(np.abs(problem.structure.system(theta).poles), initial=0.0) > fastest:
                    return np.full(y.size, _BAD)
                # the derivatives come out of the same pass for about twice its cost, and
                # least_squares asks for the Jacobian at every point it accepts (as fit._run)
                r = cov.whiten(y - moment_derivatives(problem._oe, np.r_[jit, theta])[0].mean)
            except ValueError:
                return np.full(y.size, _BAD)
        return r if np.all(np.isfinite(r)) else np.full(y.size, _BAD)

    def jac(theta: FloatArray) -> FloatArray:
        # -C^{-1} L_a dm/dtheta: the OE pass's analytic derivatives (jacobians), whitened.
        try:
            dm = moment_derivatives(problem._oe, np.r_[jit, theta])[2][nj:]
        except ValueError:  # only where resid failed too; such a step is never taken
            return np.zeros((y.size, ns))
        return -cov.whiten(dm.T)

    gains = list(problem.structure.gain_params)
    wy = cov.whiten(y)
    # The structure's starts (gains set by GLS) are scored by one evaluation each and only
    # the best is searched, besides the BCLS start (as fit._oe_start chooses its start).
    scored: list[tuple[float, FloatArray]] = []
    nfev = 0
    for theta0 in problem.structure.starts(problem.data.T):
        theta0 = np.clip(np.asarray(theta0, float), lo, hi)
        r0 = resid(theta0)
        nfev += 1
        if gains and np.all(r0 < _BAD):  # the mean is linear in the gains: the GLS gain
            ws = wy - r0
            if np.dot(ws, ws) > 0:
                c = np.dot(wy, ws) / np.dot(ws, ws)
                theta0[gains] *= c
                r0 = wy - c * ws
        scored.append((float(np.dot(r0, r0)), theta0))
    starts = [x_pre[nj:]]
    if scored:
        starts.append(min(scored, key=lambda item: item[0])[1])
    results: list[tuple[FloatArray, float]] = []
    for theta0 in starts:
        sol = least_squares(
            resid,
            theta0,
            jac=jac,
            bounds=(lo, hi),
            x_scale="jac",
            max_nfev=min(max_nfev, 200),
            ftol=STAGE_FTOL,
            xtol=STAGE_FTOL,
        )
        nfev += int(sol.nfev)
        results.append((sol.x, float(sol.cost)))
    i = min(range(len(results)), key=lambda j: results[j][1])
    # Another basin only if clearly better than the search from BCLS (not a rounding tie
    # with the same point reached from another start).
    (x_b, c_b), (x_i, c_i) = results[0], results[i]
    moved = c_i < c_b - 1e-4 * (1.0 + abs(c_b)) and not np.allclose(x_i, x_b, rtol=1e-3, atol=1e-6)
    return (x_i if moved else x_b), moved, nfev


def _run_frozen(
    problem: BJProblem, x0: FloatArray, max_nfev: int
) -> tuple[BJProblem, tuple[FloatArray, float, FitStatus, str, int]]:
    """A criterion with frozen weights (WBCLS (20)): R frozen at ``x0``, then re-frozen at
    each estimate, ``estimator.freeze_rounds`` searches in all (iterated feasible GLS, as
    :func:`jitterid.estimation.fit._run_wbcls` for OE): with R(theta) inside the search and
    no ln det R, (20) is minimised partly by inflating R, which biases it."""
    nfev = 0
    out: tuple[FloatArray, float, FitStatus, str, int] | None = None
    for _ in range(problem.estimator.freeze_rounds):
        problem = replace(problem, weights_at=np.array(x0, float))
        out = _search(problem, x0, max_nfev)
        nfev += out[4]
        x0 = out[0]
    assert out is not None
    return problem, (*out[:4], nfev)


def fitted_noise(result: FitResult, noise: NoiseStructure | NoiseModel) -> NoiseModel:
    """Deprecated: ``result.noise_model``. The noise model H of a BJ/JBJ
    :class:`~jitterid.FitResult`, rebuilt from its parameters.

    Parameters
    ----------
    result : FitResult
        A result of ``fit(..., noise=noise)``.
    noise : NoiseStructure or NoiseModel
        The noise structure that was fitted (a NoiseModel is returned as it is).

    Examples
    --------
    >>> import warnings
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> H = ji.NoiseModel(ji.TransferFunction([0.01], [1.0, 2.0]))
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), noise=H)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", DeprecationWarning)
    ...     old = ji.fitted_noise(res, H)
    >>> old is H, res.noise_model is H  # prefer result.noise_model
    (True, True)
    """
    warnings.warn(
        "fitted_noise(result, noise) is deprecated: the result keeps its fitted noise model, "
        "result.noise_model",
        DeprecationWarning,
        stacklevel=2,
    )
    structure = as_noise_structure(noise)
    params = result.params
    missing = [n for n in structure.param_names if n not in params]
    if missing:
        raise ValueError(
            f"result has no noise parameters {missing}: pass the noise structure it was fitted "
            f"with (its names are {result.names})"
        )
    return structure.model([params[n] for n in structure.param_names])


def _coloured_estimator(method: str | Estimator) -> Estimator:
    """The estimator of ``method`` if it has a coloured-noise form, else a ValueError naming
    ``method`` and ``noise``."""
    names = coloured_method_names()
    try:
        est = as_estimator(method)
    except ValueError:
        raise ValueError(
            f"method must be one of {names} (or an Estimator with a coloured-noise form) when a "
            f"noise model is given (noise=...); got {method!r}"
        ) from None
    if not est.coloured_noise:
        hint = " (it ignores the jitter)" if est.ignores_jitter else ""
        raise ValueError(
            f"method must be one of {names} when a noise model is given (noise=...); got "
            f"{est.name!r}, which has no coloured-noise (Box-Jenkins) form{hint}: fit it with "
            "noise=None"
        )
    return est


def _scaling(
    data: SampledData, structure: ModelStructure, noise: NoiseStructure, n_jitter: int
) -> tuple[Scaling, NoiseStructure]:
    """The unit scaling of :func:`jitterid.estimation.fit` (:class:`checks.Scaling`: y / sy,
    u / su, powers of two) extended to the BJ layout, and the noise structure in the scaled
    units. v / sy is H / sy: a structure's gain parameters (``gain_params``, the numerator of
    ``RationalNoise``) scale by 1 / sy, a known model's intensity by 1 / sy^2 (exact). A
    structure with parameters but no declared gains cannot absorb the scaling: identity."""
    sc = Scaling.build(data, structure, n_jitter)
    nn = len(noise.param_names)
    gains = list(noise.gain_params)
    if sc.identity or (nn and not gains):
        n = sc.factors.size + nn
        return Scaling(1.0, 1.0, np.ones(n)), noise
    f = np.ones(nn)
    f[gains] = 1.0 / sc.sy
    if not nn:  # a known noise model
        m = noise.model(())
        noise = KnownNoise(NoiseModel(m.tf, m.intensity / sc.sy**2))
    return replace(sc, factors=np.r_[sc.factors, f]), noise


def fit_bj(
    data: SampledData,
    system: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str | Estimator,
    start: ArrayLike | FitResult | None,
    *,
    noise: NoiseStructure | NoiseModel,
    freqs: ArrayLike | None,
    noise_std: float | None,
    max_nfev: int,
    oe_fit: Callable[..., FitResult],
    cov_type: str = "sandwich",
) -> FitResult:
    """:func:`jitterid.fit` with ``noise=``: the BJ (2b) and JBJ (2d) structures.

    Parameters are those of :func:`jitterid.fit`; ``method`` is an estimator with a
    coloured-noise form (``coloured_noise``) or its name; ``noise`` is a structure with free
    parameters (``RationalNoise(0, 1)``) or a known :class:`~jitterid.NoiseModel`, and
    ``noise_std`` (default ``data.noise_std``) is the std of the additional white part,
    estimated as parameter ``noise_std`` by the estimators that identify the noise model
    (``asml``, ``asml-diag``, ``gaussian``) when neither is given (``bcls``/``wbcls`` plug it
    in with the noise parameters). ``oe_fit`` is :func:`jitterid.fit` itself, whose
    white-noise BCLS fit gives the start (Section 4.5); ``cov_type`` is ``"sandwich"`` (the
    delta method with the coloured covariance) or ``"none"``.

    As for OE, the search runs on y and u divided by powers of two near their rms
    (:func:`_scaling`), so that its tolerances and floors do not depend on the data's units;
    estimates, criterion and covariance are reported in the data's units (exactly). A search
    that converged to an answer that cannot be trusted gets the status of
    :func:`jitterid.estimation.checks.post_checks` (``AT_BOUND``, ``UNSTABLE_MODEL``,
    ``UNIDENTIFIABLE``, ``LOCAL_OPTIMUM``, ``NOT_SIGNIFICANT``).
    """
    fit = oe_fit

    est = _coloured_estimator(method)
    if cov_type not in ("sandwich", "none"):
        raise ValueError(
            f"cov_type must be 'sandwich' or 'none' with a noise model; got {cov_type!r} (the "
            "robust and observed-information forms are not implemented for Box-Jenkins yet)"
        )
    structure = as_structure(system)
    if not isinstance(structure, ModelStructure):
        raise ValueError(  # noqa: TRY004 (a ValueError naming the argument, as fit() raises)
            "noise: coloured noise (Box-Jenkins) needs an LTI structure driven by a known input; "
            f"got {type(structure).__name__}: fit it with noise=None"
        )
    nstruct = as_noise_structure(noise)
    if not isinstance(data, SampledData):
        raise TypeError(
            f"data must be a SampledData (see jitterid.simulate); got {type(data).__name__}"
        )
    f = (
        default_frequencies(data.N, data.T)
        if freqs is None
        else np.atleast_1d(real_array(freqs, "freqs"))
    )
    white = data.noise_std if noise_std is None else noise_std
    free_noise = len(nstruct.param_names) > 0 or white is None
    # a criterion without a ln det term holds the noise parameters at plug-in values
    plug_in = free_noise and not est.identifies_noise_model
    nj = len(jitter.param_names) if isinstance(jitter, JitterFamily) else 0
    # The search runs in the units of checks.Scaling (as fit's OE search); every parameter,
    # the criterion and the covariance map back exactly (powers of two).
    scaling, noise_s = _scaling(data, structure, nstruct, nj)
    sdata = scaling.data(data)
    white_s = None if white is None else white / scaling.sy
    make = partial(BJProblem, sdata, structure, jitter, noise_s, freqs=f, white_std=white_s)
    problem = make(method=est)
    k = problem.n_jitter + problem.n_system
    prefits: list[FitResult] = []

    def prefit() -> FitResult:
        """The white-noise BCLS fit (Section 4.5), once; fit() scales the data exactly as
        here, so its estimate maps to these units exactly."""
        if not prefits:
            given = start if isinstance(start, FitResult) else None
            # its white-noise covariance is never used (the BJ one is computed below), nor
            # does the white-noise lack-of-fit check apply where the noise is coloured: the
            # BCLS criterion does not use the noise std, so it is not passed
            white_data = replace(data, noise_std=None)
            prefits.append(
                fit(
                    white_data,
                    structure,
                    jitter,
                    BCLS(),
                    given,
                    freqs=f,
                    max_nfev=max_nfev,
                    cov_type="none",
                )
            )
        return prefits[0]

    # points of the default route that the final search did not start from, for the
    # local-optimum check (lazily: they cost a pre-fit and a noise stage after a given start)
    others: list[Callable[[], FloatArray | None]] = []
    nfev = 0
    if start is not None and not isinstance(start, FitResult):
        x0 = np.atleast_1d(real_array(start, "start"))
        if x0.size != len(problem.names):
            raise ValueError(
                f"start must have {len(problem.names)} values {problem.names}; got {x0.size}"
            )
        x0 = scaling.to_scaled(x0)
        if plug_in:
            problem = make(method=est, pinned=x0[k:])
        if est.freeze_rounds:
            problem, best = _run_frozen(problem, x0, max_nfev)
        else:
            best = _search(problem, x0, max_nfev)
        nfev = best[4]

        def default_start() -> FloatArray | None:
            x_pre = scaling.to_scaled(prefit().x)
            eta = _noise_stage(problem, x_pre, max_nfev)[0] if free_noise else np.zeros(0)
            return np.r_[x_pre, eta]

        others.append(default_start)
    else:
        pre = prefit()
        nfev = pre.nfev
        x_pre = scaling.to_scaled(pre.x)
        eta, n = _noise_stage(problem, x_pre, max_nfev) if free_noise else (np.zeros(0), 0)
        nfev += n
        x_bcls = np.r_[x_pre, eta]
        # The GLS stage picks the system's basin where coloured noise dominates some
        # frequencies; a noise model white once sampled (a white record) weights as the OE
        # criterion does, which starts from the BCLS estimate too: skipped. A criterion
        # blind to Sigma_y keeps its estimate (below).
        if est.weighs_by_noise and not _white_limit(problem, x_bcls)[0]:
            theta, moved, n = _whitened_stage(problem, x_pre, eta, max_nfev)
            nfev += n
            x_pre = np.r_[x_pre[: problem.n_jitter], theta]  # the GLS system: a closer start
            if moved and free_noise:  # another basin: refit the noise to its residuals
                eta, n = _noise_stage(problem, x_pre, max_nfev, start=eta)
                nfev += n
        x0 = np.r_[x_pre, eta]
        if not np.array_equal(x_bcls, x0):
            others.append(lambda: x_bcls)
        if plug_in:
            problem = make(method=est, pinned=eta)
        if not est.weighs_by_noise:
            # The noise model does not enter the criterion (BCLS (14)): its BJ estimate is
            # its white-noise one (the pre-fit itself for BCLS), the noise only its error bars.
            if est != BCLS():
                pre = fit(
                    replace(data, noise_std=None),
                    structure,
                    jitter,
                    est,
                    pre,
                    freqs=f,
                    max_nfev=max_nfev,
                )
                nfev += pre.nfev
                x0 = np.r_[scaling.to_scaled(pre.x)[:k], eta]
            best = (x0, problem.objective(x0), pre.status, pre.message, 0)
        elif est.freeze_rounds:
            problem, best = _run_frozen(problem, x0, max_nfev)
            nfev += best[4]
        else:
            best = _search(problem, x0, max_nfev)
            nfev += best[4]
    x, cost, status, msg, _ = best
    x = np.asarray(x, float)
    cov = np.full((x.size, x.size), np.nan)
    cov_error: str | None = None
    # A noise model that is white once sampled (a white record: its gain at 0 or its pole
    # run off) is the natural home of the estimate, as a jitter scale at 0 is on data
    # without jitter. The noise parameters are then not identified (held in the covariance,
    # whose other rows they would only fill with rounding), nor is the white std apart
    # from them when both are white: no error bars for those, exempt from the
    # identifiability check, said in the message; the system's are checked as usual.
    held, white_limit = _white_limit(problem, x)
    if cov_type == "sandwich":
        try:
            cov = bj_covariance(problem, x, held)
        except (ValueError, np.linalg.LinAlgError) as exc:  # the checks below say why
            cov_error = str(exc)
    if white_limit:
        cov[white_limit, :] = np.nan
        cov[:, white_limit] = np.nan
        msg = (
            f"{msg}; the noise model is at its white limit (the sampled coloured noise is "
            f"white or zero): {[problem.names[i] for i in white_limit]} not identified (no "
            "standard errors)"
        )
    status, msg = post_checks(
        PostContext(
            data=sdata,
            structure=structure,
            jitter=jitter,
            names=problem.names,
            bounds=problem.bounds,
            x=x,
            cost=float(cost),
            cov=cov,
            objective=problem.objective,
            model_mean=lambda v: problem.moments(v).mean,
            oe_system=lambda: scaling.to_scaled(prefit().x)[nj:],
            starts=partial(_other_starts, problem, others),
            cov_error=cov_error,
            exempt=white_limit,
        ),
        status,
        msg,
    )
    if (
        not scaling.identity
    ):  # back to the data's units, exactly; the criterion is re-evaluated there
        x = scaling.to_original(x)
        cov = scaling.cov_to_original(cov)
        w = problem.weights_at
        problem = BJProblem(
            data,
            structure,
            jitter,
            nstruct,
            est,
            f,
            white,
            pinned=x[k:] if problem.pinned is not None else None,
            weights_at=None if w is None else scaling.to_original(w),
        )
        try:
            cost = problem.objective(x)
        except (ValueError, np.linalg.LinAlgError):
            cost = np.inf
    law, tf, noise_fitted, white_used = problem.split(x)
    return FitResult(
        method=est.name,
        names=problem.names,
        x=x,
        cost=float(cost),
        status=status,
        message=msg,
        nfev=nfev,
        system=tf,
        jitter_law=law,
        noise_std=white_used,
        freqs=f,
        cov=cov,
        cov_type=cov_type,
        structure=structure,
        jitter_model=jitter,
        noise_structure=nstruct,
        noise_model=noise_fitted,
    )


WHITE_LAG = 1e-3  # |gamma(1)| / gamma(0) below which the sampled coloured noise is white


def _white_limit(problem: BJProblem, x: FloatArray) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(held, unidentified): the parameters a noise model at its white limit leaves
    unidentified at ``x``, to hold in the covariance and to report without error bars:

    - no coloured noise (variance 0: its gains at 0): every noise parameter, in which the
      criterion is then constant (the white std stays identified);
    - coloured noise that is white once sampled (lag-1 autocovariance below ``WHITE_LAG``
      of the variance: its pole run off): the noise parameters, and the white std too (the
      two share one identified white variance).
    """
    k, nn = problem.n_jitter + problem.n_system, problem.n_noise
    if not nn:
        return (), ()
    try:
        g = problem.autocovariance(x).sequence(2)
    except ValueError:
        return (), ()
    noise = tuple(range(k, k + nn))
    if g[0] <= 0:
        return noise, noise
    if abs(g[1]) <= WHITE_LAG * g[0]:
        return noise, tuple(range(k, x.size))
    return (), ()


def _other_starts(
    problem: BJProblem, others: list[Callable[[], FloatArray | None]]
) -> list[FloatArray]:
    """The default route's points that the final search did not start from, inside the
    problem's bounds (a pinned noise block takes its pinned values)."""
    lo, hi = np.array(problem.bounds, float).reshape(-1, 2).T
    out = []
    for get in others:
        try:
            v = get()
        except ValueError:
            continue
        if v is not None and v.size == lo.size:
            out.append(np.clip(v, lo, hi))
    return out
