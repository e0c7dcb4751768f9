"""fit(): one entry point for every estimator of the paper.

The search follows Section 4.5: an ordinary output-error fit that ignores the jitter gives
the system's starting point; for a free jitter law a small grid of starting values is
tried; the weighted and likelihood criteria start from the BCLS estimate. Least-squares
criteria are minimised by scipy's trust-region Gauss-Newton/Levenberg-Marquardt
(``least_squares``), the exact likelihood (``ml``) by the damped Newton iteration of
:meth:`jitterid.estimation.likelihood.ExactLikelihood.maximise`, the others by a damped Newton
(Fisher scoring) search, all with analytic derivatives (:mod:`jitterid.estimation.jacobians`); all
respect the bounds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .._checks import real_array
from .._threads import single_thread
from ..data import SampledData
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..noise.models import NoiseModel, NoiseStructure
from ..systems.model import Model
from ..systems.structures import ModelStructure, as_structure
from ..systems.tf import TransferFunction
from . import jacobians as _jacobians
from .boxjenkins import fit_bj
from .checks import (
    SCREEN_SAMPLES,
    PostContext,
    Scaling,
    check_arguments,
    check_data,
    post_checks,
)
from .covariance import covariance, noise_variance_ml
from .estimators import Estimator, as_estimator
from .ml import free_moment_plans, run_ml
from .problem import (
    Problem,
    default_frequencies,
)
from .resources import check_fit as check_fit_resources
from .result import FitResult, FitStatus
from .search import evaluator, newton_search

__all__ = ["fit"]

FloatArray = NDArray[np.float64]
_BAD = 1e10  # residual returned where the model cannot be evaluated (e.g. unstable)


def _oe_start(data: SampledData, structure: Model) -> tuple[FloatArray, float]:
    """Ordinary output-error fit ignoring jitter (time domain); returns (theta, rms residual)."""
    t = data.t_nominal
    if not structure.param_names:
        r0 = data.y - structure.signal((), data.u)(t)
        return np.zeros(0), float(np.sqrt(np.mean(r0**2)))

    # The samples at kT are the moments of a point-mass jitter: the same O(N) path and
    # analytic Jacobian as the jitter-aware criteria (jitterid.estimation.jacobians).
    oe = Problem(data, structure, NoJitter(), "ls", default_frequencies(data.N, data.T), None)

    def resid(x: FloatArray) -> FloatArray:
        try:
            return data.y - _jacobians.moment_derivatives(oe, x)[0].mean  # see _run
        except ValueError:
            return np.full(data.N, _BAD)

    def jac(x: FloatArray) -> FloatArray:
        try:
            return -_jacobians.moment_derivatives(oe, x)[2].T
        except ValueError:  # only where resid failed too; such a step is never taken
            return np.zeros((data.N, x.size))

    lo, hi = np.array(structure.bounds).T
    # Score every start by one evaluation; search from the best only (a start with the
    # right time scale is what matters, and each full search costs ~30 evaluations).
    gains = list(structure.gain_params)
    scored = []
    for x0 in structure.initial_points(data):
        x0 = np.clip(x0, lo, hi)
        try:
            s = oe.moments(x0).mean
        except ValueError:  # e.g. unstable: last resort only
            scored.append((np.inf, x0))
            continue
        if gains and np.dot(s, s) > 0:  # give each start its least-squares gain
            # s is linear in the gain parameters: the scaled start's output is c s
            c = np.dot(data.y, s) / np.dot(s, s)
            scaled = x0.copy()
            scaled[gains] *= c
            if np.all((scaled >= lo) & (scaled <= hi)):  # a bounded gain keeps its start
                x0, s = scaled, c * s
        scored.append((float(np.sum((data.y - s) ** 2)), x0))
    x0 = min(scored, key=lambda item: item[0])[1]
    sol = least_squares(resid, x0, jac=jac, bounds=(lo, hi), x_scale="jac", max_nfev=200)
    return sol.x, float(np.sqrt(2 * sol.cost / data.N))


def _run(
    problem: Problem, x0: FloatArray, max_nfev: int
) -> tuple[FloatArray, float, FitStatus, str, int]:
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    x0 = np.clip(x0, lo, hi)
    if x0.size == 0:
        return x0, problem.objective(x0), FitStatus.CONVERGED, "no free parameters", 1
    if problem.method == "ml":
        return run_ml(problem, x0, max_nfev)
    if as_estimator(problem.method).least_squares:

        def resid(x: FloatArray) -> FloatArray:
            try:
                # The moments' derivatives come out of the same pass over the nodes for
                # about twice its cost, and least_squares asks for the Jacobian at every
                # point it accepts: computing both here saves a pass per iteration.
                _jacobians.moment_derivatives(problem, x)
                return problem.residuals(x)
            except ValueError:
                return np.full(2 * problem.freqs.size, _BAD)

        def jac(x: FloatArray) -> FloatArray:
            # Analytic (jitterid.estimation.jacobians): one pass instead of P + 1 evaluations.
            try:
                return problem.jacobian(x)
            except ValueError:  # only where resid failed too; such a step is never taken
                return np.zeros((2 * problem.freqs.size, x.size))

        sol = least_squares(resid, x0, jac=jac, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev)
        status = FitStatus.CONVERGED if sol.status > 0 else FitStatus.MAX_EVALUATIONS
        if sol.status < 0:
            status = FitStatus.OPTIMISER_FAILED
        x, nfev, msg = sol.x, int(sol.nfev), str(sol.message)
    else:
        x, ok, msg, nfev = newton_search(
            evaluator(problem.objective_gradient), x0, lo, hi, max_nfev
        )
        status = FitStatus.CONVERGED if ok else FitStatus.OPTIMISER_FAILED
        if not ok and nfev >= max_nfev:
            status = FitStatus.MAX_EVALUATIONS
    # The criterion is recomputed from the model here, so it never holds the _BAD sentinel;
    # large legitimate values (a sum over 10^6 frequencies) are not failures.
    try:
        cost = problem.objective(x)
    except ValueError:
        cost = np.inf
    if not np.isfinite(cost):
        status = FitStatus.NOT_FINITE
    problem.release()
    return x, cost, status, msg, nfev


def _screen(problem: Problem) -> Callable[[FloatArray], FloatArray] | None:
    """The exact likelihood's -2 ln p_k over the first ``SCREEN_SAMPLES`` samples, for the
    checks' first look at far points (``PostContext.screen``), on records of at least four
    times as many samples (None otherwise, and for the other criteria)."""
    lik = problem.likelihood
    if problem.method != "ml" or lik is None or lik.N < 4 * SCREEN_SAMPLES:
        return None
    head = lik.leading(SCREEN_SAMPLES)
    y = problem.data.y[:SCREEN_SAMPLES]
    return lambda v: -2 * head.logpdf(v, y)


def fit(
    data: SampledData,
    system: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str | Estimator = "bcls",
    start: ArrayLike | FitResult | None = None,
    *,
    freqs: ArrayLike | None = None,
    noise_std: float | None = None,
    max_nfev: int = 2000,
    noise: NoiseStructure | NoiseModel | None = None,
    cov_type: str | None = None,
) -> FitResult:
    """Estimate a continuous-time model from jittered samples.

    Parameters
    ----------
    data : SampledData
        Samples y_k requested at kT, the known input, and (optionally) the noise std.
    system : Model or TransferFunction
        A structure with free parameters (``PolePairGain()``, ``RationalModel(m, n)``), a
        known system (its parameters are then not estimated, as in Table 1), or a signal
        model with no input (:class:`jitterid.SignalModel`; ``data.u`` may then be None).
    jitter : JitterLaw or JitterFamily
        A known jitter law (OE structure (2a)) or a family with free parameters (JOE, (2c)).
    method : str or Estimator
        ``"ls"`` (8), ``"bcls"`` (14), ``"wbcls"`` (20), ``"asml"`` (22), ``"asml-diag"`` (23),
        ``"gaussian"`` (the exact real-valued Gaussian criterion, notes section 3) or ``"ml"``
        (the exact likelihood, notes section 4; :mod:`jitterid.estimation.likelihood`), or
        an estimator object carrying its options, e.g. ``WBCLS(refreeze=2)``
        (:mod:`jitterid.estimation.estimators`).
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
    noise : NoiseStructure or NoiseModel, optional
        Coloured measurement noise v = (h * e)(t), eq. (1c): a structure with free parameters
        (``RationalNoise(0, 1)``) or a known ``NoiseModel``, for the Box-Jenkins structures BJ
        (2b) and, with a jitter family, JBJ (2d) (:mod:`jitterid.estimation.boxjenkins`; methods
        ``bcls``, ``wbcls``, ``asml``, ``asml-diag``, ``gaussian``). ``noise_std`` is then the
        std of an additional white part. Default None: white noise only (OE, (2a)).
    cov_type : {"sandwich", "robust", "oim", "none"}, optional
        The covariance computed for the result (:mod:`jitterid.estimation.covariance`):
        ``"sandwich"`` (default of the moment estimators; model variances including the
        measurement noise), ``"robust"`` (Huber-White; default for ``ls``; use it when the
        jitter law may be misspecified), ``"oim"`` (inverse observed information; default
        for ``ml``, also for ``gaussian``) or ``"none"`` (not computed).

    Returns
    -------
    FitResult
        Check ``success``: a failed search is reported as failed, never as a good fit. A
        search that converged to an answer that cannot be trusted gets its own status
        (:mod:`jitterid.estimation.checks`): ``AT_BOUND`` (a system parameter on its bound,
        or the jitter scale collapsed while :func:`jitterid.detect_jitter` finds jitter),
        ``UNIDENTIFIABLE`` (near-singular information), ``UNSTABLE_MODEL``,
        ``LOCAL_OPTIMUM`` (a default start has a lower criterion), ``NOT_SIGNIFICANT``
        (the model explains no significant part of y) or ``LACK_OF_FIT`` (with the noise std
        given, residuals far beyond what the model allows); ``message`` gives the numbers
        and what to try.

    Raises
    ------
    ValueError
        Naming the argument: ``noise_std`` negative or not finite, ``max_nfev`` not a
        positive whole number, an input that ends before the samples or is zero at every
        sampling instant, a constant ``y``, or fewer than 2 P + 4 samples for P parameters.

    Notes
    -----
    The search runs on y and u divided by powers of two near their rms, so its convergence
    tests do not depend on the data's units; estimates, criterion and covariance are
    reported in the data's units (exactly: the maps are powers of two).

    Examples
    --------
    Identify G(s) = 2 / (s + 2) from samples with uniform jitter of half-width 0.05 s:

    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> res = jid.fit(data, jid.RationalModel(0, 1), jid.Uniform(0.05))
    >>> res.success
    True
    >>> {name: round(value, 1) for name, value in res.params.items()}
    {'b0': 2.0, 'a0': 2.0}
    """
    # Small complex BLAS calls (Cholesky, matmul) run ~100x slower multi-threaded here;
    # one thread is faster, and parallelism belongs to the Monte Carlo level.
    with single_thread("blas"):
        return _fit(
            data,
            system,
            jitter,
            method,
            start,
            freqs=freqs,
            noise_std=noise_std,
            max_nfev=max_nfev,
            noise_model=noise,
            cov_type=cov_type,
        )


def _fit(
    data: SampledData,
    system: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str | Estimator = "bcls",
    start: ArrayLike | FitResult | None = None,
    *,
    freqs: ArrayLike | None = None,
    noise_std: float | None = None,
    max_nfev: int = 2000,
    noise_model: NoiseStructure | NoiseModel | None = None,
    cov_type: str | None = None,
) -> FitResult:
    est = as_estimator(method)
    method = est.name
    cov_type = est.check_cov_type(cov_type)
    noise_std, max_nfev = check_arguments(noise_std, max_nfev)
    if (
        noise_model is not None
        and isinstance(system, Model)
        and not isinstance(system, ModelStructure)
    ):
        raise ValueError(
            "noise: coloured noise (Box-Jenkins) is implemented for LTI structures driven by a "
            f"known input; {type(system).__name__} is a signal model: fit it with noise=None"
        )
    if noise_model is not None and isinstance(data, SampledData):  # Box-Jenkins: the data checks
        n_sys = len(system.param_names) if isinstance(system, Model) else 0
        check_data(
            data, n_sys + (len(jitter.param_names) if isinstance(jitter, JitterFamily) else 0)
        )
    if noise_model is not None:  # Box-Jenkins structures (2b), (2d): coloured noise
        assert isinstance(system, (ModelStructure, TransferFunction))  # refused above otherwise
        return fit_bj(
            data,
            system,
            jitter,
            est,
            start,
            noise=noise_model,
            freqs=freqs,
            noise_std=noise_std,
            max_nfev=max_nfev,
            oe_fit=fit,
            cov_type=cov_type,
        )
    prefit = start if isinstance(start, FitResult) else None
    if prefit is not None:
        start = None
    if not isinstance(data, SampledData):
        raise TypeError(
            f"data must be a SampledData (see jitterid.simulate); got {type(data).__name__}"
        )
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
    n_jit = len(jitter.param_names) if isinstance(jitter, JitterFamily) else 0
    check_data(data, n_jit + len(structure.param_names), structure.uses_input)
    check_fit_resources(data, structure, jitter, method)  # memory up front (resources.py)
    f = (
        default_frequencies(data.N, data.T)
        if freqs is None
        else np.atleast_1d(real_array(freqs, "freqs"))
    )
    if f.size < 1:
        raise ValueError("freqs must hold at least one frequency")
    noise = data.noise_std if noise_std is None else noise_std
    if method == "ml" and noise is not None and not noise > 0:
        raise ValueError(
            "method 'ml' needs measurement noise: the exact likelihood of noise-free samples "
            f"is singular (noise_std = {noise!r}); pass a positive noise_std"
        )
    # The search runs on y / sy and u / su (powers of two near their rms; checks.Scaling) so
    # that the optimisers' absolute tolerances do not depend on the data's units; every
    # parameter, the criterion and the covariance map back exactly.
    orig_data = data
    scaling = Scaling.build(data, structure, n_jit)
    data = scaling.data(data)
    if noise is not None:
        noise = noise / scaling.sy
    given_noise = noise  # the user's noise std in the search's units (wbcls may plug one in)
    make = partial(Problem, data, structure, jitter, freqs=f)
    theta_oe: list[tuple[FloatArray, float]] = []  # the ordinary OE fit, computed once if needed

    jstarts: Sequence[Sequence[float]] = (
        jitter.default_starts(data.T) if isinstance(jitter, JitterFamily) else [()]
    )
    nfev = 0
    rms: float | None = None
    if start is not None:
        problem = make(method=method, noise_std=noise if est.needs_noise else None)
        if method == "wbcls" and noise is None:
            theta_oe.append(_oe_start(data, structure))
            theta_sys = theta_oe[-1][0]
            problem = make(
                method=method, noise_std=_plugin_noise(make, theta_sys, jstarts, max_nfev)
            )
        x0 = np.atleast_1d(real_array(start, "start"))  # type: ignore[arg-type]  # FitResult handled above
        if x0.size != len(problem.names):
            raise ValueError(
                f"start must have {len(problem.names)} values {problem.names}; got {x0.size}"
            )
        x0 = scaling.to_scaled(x0)
        if method == "wbcls":
            problem, best = _run_wbcls(
                make, est, problem.noise_std, np.clip(x0, *np.array(problem.bounds).T), max_nfev
            )
        else:
            best = _run(problem, x0, max_nfev)
        nfev = best[4]
    else:
        first = "ls" if method == "ls" else "bcls"
        pre = make(method=first, noise_std=None)
        best = None
        if prefit is not None:
            _check_prefit(
                prefit,
                pre if scaling.identity else Problem(orig_data, structure, jitter, first, f, None),
            )
            best = (
                scaling.to_scaled(prefit.x),
                prefit.cost,
                prefit.status,
                prefit.message,
                prefit.nfev,
            )
            nfev = prefit.nfev
        else:
            theta_sys, rms = _oe_start(data, structure)
            theta_oe.append((theta_sys, rms))
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
            problem = make(method=method, noise_std=noise if est.needs_noise else None)
            if problem.estimates_noise and rms is None:
                theta_sys, rms = _oe_start(data, structure)
                theta_oe.append((theta_sys, rms))
            noise0 = max(rms or 0.0, 1e-6)
            if method == "ml":  # the likelihood's cost grows like 1/noise: start close
                noise0 = max(_noise_from_residuals(pre, x_pre), 0.05 * (rms or 0.0), 1e-12)
            x0 = np.r_[x_pre, noise0] if problem.estimates_noise else x_pre
            if not est.least_squares and method != "ml":  # ml scores its own starts (ml.py)
                x0, scored = _off_zero_jitter(problem, x0, jstarts)
                nfev += scored
            if method == "wbcls":
                problem, best = _run_wbcls(make, est, problem.noise_std, x0, max_nfev)
            else:
                best = _run(problem, x0, max_nfev)
            nfev += best[4]
        else:
            problem = pre
    assert best is not None
    x, cost, status, msg, _ = best
    x = np.asarray(x, float)
    assert cov_type is not None
    noise_rec: float | None = None
    cov = np.full((x.size, x.size), np.nan)
    cov_error: str | None = None
    try:
        if problem.uses_noise:
            noise_rec = problem.split(x)[2]
        elif noise is not None:
            noise_rec = float(noise)
        elif (
            cov_type == "sandwich"
        ):  # the covariance needs sigma_v: its ML value given the residuals
            mom = problem.moments(x)
            noise_rec = float(np.sqrt(noise_variance_ml(data.y - mom.mean, mom.var)))
        cov = covariance(problem, x, cov_type, noise_rec)
    except ValueError as exc:  # e.g. an unstable model: the checks below say why
        cov_error = str(exc)

    def oe_system() -> FloatArray | None:
        if not theta_oe:
            theta_oe.append(_oe_start(data, structure))
        return theta_oe[0][0]

    def default_starts() -> list[FloatArray]:
        # A search that already ran from every default start (the first stage) has nothing to
        # compare; after a given start or a second stage, the criterion at the default starts
        # must not be lower than at the estimate.
        if (
            (start is None and method in ("ls", "bcls"))
            or prefit is not None
            or not structure.param_names
        ):
            return []
        th = oe_system()
        assert th is not None
        out = [np.r_[np.asarray(js, float), th] for js in jstarts]
        if problem.estimates_noise:
            out = [np.r_[v, max(theta_oe[0][1], 1e-6)] for v in out]
        lo, hi = np.array(problem.bounds, float).reshape(-1, 2).T
        return [np.clip(v, lo, hi) for v in out]

    known_variance = None
    # (a noise std of 0, e.g. noise-free simulated data, leaves nothing to standardise by)
    if given_noise and not est.ignores_jitter and not problem.estimates_noise:
        known_noise = float(given_noise)

        def known_variance(v: FloatArray) -> FloatArray:
            # Var y_k plus the spread of the fitted mean, dm_k^T Cov dm_k: an inefficient
            # estimator (bcls) leaves residuals of many noise stds where Var s_k is tiny
            mom, _, dm, _ = problem.derivatives(v)
            spread = np.einsum("pk,pq,qk->k", dm, np.nan_to_num(cov), dm)
            return np.asarray(mom.var + known_noise**2 + spread, dtype=float)

    status, msg = post_checks(
        PostContext(
            data=data,
            structure=structure,
            jitter=jitter,
            names=problem.names,
            bounds=problem.bounds,
            x=x,
            cost=float(cost),
            cov=cov,
            objective=problem.objective,
            model_mean=lambda v: problem.moments(v).mean,
            oe_system=oe_system,
            starts=default_starts,
            cov_error=cov_error,
            known_variance=known_variance,
            screen=_screen(problem),
        ),
        status,
        msg,
    )
    if (
        not scaling.identity
    ):  # back to the data's units, exactly; the criterion is re-evaluated there
        x = scaling.to_original(x)
        cov = scaling.cov_to_original(cov)
        noise_rec = None if noise_rec is None else noise_rec * scaling.sy
        w = problem.weights_at
        problem.release()
        if problem.likelihood is not None:  # its rule, before the next one is designed
            problem.likelihood.release()
            free_moment_plans(data.N)  # and the moment plans of the checks
        problem = Problem(
            orig_data,
            structure,
            jitter,
            method,
            f,
            None if problem.noise_std is None else problem.noise_std * scaling.sy,
            weights_at=None if w is None else scaling.to_original(w),
        )
        try:
            cost = problem.objective(x)
        except ValueError:
            cost = np.inf
    problem.release()  # a fresh signal for the result, without the criterion's caches
    law = problem.jitter_law(x)
    theta = problem.layout.block(x, "system")
    fitted = structure.system(theta) if isinstance(structure, ModelStructure) else None
    problem.release()
    return FitResult(
        method=method,
        names=problem.names,
        x=x,
        cost=float(cost),
        status=status,
        message=msg,
        nfev=nfev,
        system=fitted,
        jitter_law=law,
        noise_std=noise_rec,
        freqs=f,
        cov=cov,
        cov_type=cov_type,
        structure=structure,
        jitter_model=jitter,
    )


def _run_wbcls(
    make: partial[Problem], est: Estimator, noise: float | None, x0: FloatArray, max_nfev: int
) -> tuple[Problem, tuple[FloatArray, float, FitStatus, str, int]]:
    """WBCLS (20) with R frozen at x0, then re-frozen once at that estimate (iterated
    feasible GLS; :mod:`jitterid.estimation.problem` explains why R is not left to vary)."""
    nfev = 0
    for _ in range(1 + getattr(est, "refreeze", 1)):
        problem = make(method="wbcls", noise_std=noise, weights_at=np.array(x0, float))
        out = _run(problem, x0, max_nfev)
        nfev += out[4]
        x0 = out[0]
    return problem, (*out[:4], nfev)


def _off_zero_jitter(
    problem: Problem, x0: FloatArray, jstarts: Sequence[Sequence[float]]
) -> tuple[FloatArray, int]:
    """The Newton-searched criteria are even in a jitter family's scale, so their gradient
    vanishes where the BCLS stage collapsed the scale onto zero (its boundary minimum): a
    search from there never leaves. In that case each of the family's default starts (with
    the BCLS system) is scored by one criterion value and the best start searched. Elsewhere
    the BCLS point is kept as it is. Returns the start and the evaluations used."""
    jitter = problem.jitter
    scale = getattr(jitter, "scale_index", None)
    if not problem.n_jitter or scale is None or x0[scale] >= 1e-3 * problem.data.T:
        return x0, 0
    lo, hi = np.array(problem.bounds, dtype=float).reshape(-1, 2).T
    best, best_v, n = x0, np.inf, 0
    for cand in [x0] + [np.r_[np.asarray(js, float), x0[problem.n_jitter :]] for js in jstarts]:
        cand = np.clip(cand, lo, hi)
        n += 1
        try:
            v = problem.objective(cand)
        except ValueError:
            continue
        if np.isfinite(v) and v < best_v:
            best, best_v = cand, v
    return best, n


def _check_prefit(prefit: FitResult, pre: Problem) -> None:
    """A ``start`` FitResult must be the BCLS fit of this very problem (same data, structure,
    jitter model and frequencies): its cost, re-evaluated here, must match."""
    if prefit.method != pre.method or prefit.names != pre.names:
        raise ValueError(
            f"start: a FitResult passed as start must come from fit(..., method={pre.method!r}) "
            f"with parameters {pre.names}; got method {prefit.method!r} with {prefit.names}"
        )
    # A search that ended (converged, then flagged by the checks after it: a jitter scale
    # collapsed onto its bound, an unidentified shape, ...) is a valid start: the next stage
    # is what repairs it. A search that did not end is not.
    if prefit.status in (
        FitStatus.MAX_EVALUATIONS,
        FitStatus.NOT_FINITE,
        FitStatus.OPTIMISER_FAILED,
    ):
        raise ValueError(
            f"start: the {pre.method} fit passed as start did not converge ({prefit.status.name}); "
            "fit without it, or from a parameter vector"
        )
    cost = pre.objective(prefit.x)
    if (
        prefit.freqs.shape != pre.freqs.shape
        or not np.allclose(prefit.freqs, pre.freqs)
        or not np.isclose(cost, prefit.cost, rtol=1e-9, atol=0.0)
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


def _plugin_noise(
    make: partial[Problem], theta_sys: FloatArray, jstarts: Sequence[Sequence[float]], max_nfev: int
) -> float:
    pre = make(method="bcls", noise_std=None)
    out = _run(pre, np.r_[np.asarray(jstarts[0], float), theta_sys], max_nfev)
    return _noise_from_residuals(pre, out[0])
