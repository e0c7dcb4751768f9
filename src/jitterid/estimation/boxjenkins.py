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
fit's status is honest and does not depend on the data's units (:class:`BoxJenkinsRoute`).

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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .._checks import real_array
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import KnownNoise, NoiseModel, NoiseStructure, as_noise_structure
from ..params import count_params
from ..simulate import SampledData
from ..systems.model import Model
from ..systems.structures import ModelStructure, as_structure
from ..systems.tf import TransferFunction
from .bjcriteria import BJProblem, bj_covariance
from .checks import PostContext, Scaling, check_data
from .estimators import Estimator, GaussianCriterion, coloured_method_names
from .jacobians import moment_derivatives
from .problem import default_frequencies
from .result import FitResult
from .route import Staged
from .search import Outcome, run_search

__all__ = ["BoxJenkinsRoute", "fitted_noise"]

FloatArray = NDArray[np.float64]

_FAST = 100.0  # GLS stage: systems with a pole beyond _FAST times the Nyquist rate are refused
# The noise and GLS stages only give the joint search its start: converged loosely (the joint
# search refines every parameter to NEWTON_TOL), they cost a few evaluations less each.
STAGE_TOL, STAGE_FTOL = 1e-2, 1e-5
_BAD = 1e10  # residual where the model cannot be evaluated (unstable, not PD)


def _noise_stage(
    problem: BJProblem, x_pre: FloatArray, max_nfev: int, start: FloatArray | None = None
) -> tuple[FloatArray, int]:
    """Noise parameters (and sigma_w) by the Gaussian criterion with the system and jitter
    fixed at ``x_pre``: from ``start`` if given, else from the best of the structure's starts
    scored by one criterion evaluation each (as the OE start is chosen, oe._oe_start): the
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
        x, _, _, _, nfev = run_search(stage, np.r_[x_pre, start], max_nfev, free, STAGE_TOL)[1]
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
    x, _, _, _, n = run_search(stage, x0, max_nfev, free, STAGE_TOL)[1]
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
                # least_squares asks for the Jacobian at every point it accepts (as
                # Problem.search_residuals)
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
    # the best is searched, besides the BCLS start (as oe._oe_start chooses its start).
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


class BoxJenkinsRoute:
    """Coloured measurement noise v = (h * e)(t), eq. (1c): the BJ (2b) and JBJ (2d)
    structures, the problem :class:`~jitterid.estimation.bjcriteria.BJProblem` (module
    docstring; the hooks are :mod:`jitterid.estimation.route`'s).

    ``white_fit(estimator, start, cov_type)`` is the driver's white-noise fit of the same
    data (the first stage of Section 4.5, and the estimate of a criterion blind to the noise
    model): the driver hands it in, so that this module does not call the driver back.
    """

    def __init__(
        self,
        data: SampledData,
        system: Model | TransferFunction,
        jitter: JitterLaw | JitterFamily,
        estimator: Estimator,
        noise: NoiseStructure | NoiseModel,
        *,
        freqs: ArrayLike | None,
        noise_std: float | None,
        max_nfev: int,
        cov_type: str,
        white_fit: Callable[[Estimator, FitResult | None, str | None], FitResult],
    ) -> None:
        est = estimator
        if not est.coloured_noise:
            names = coloured_method_names()
            hint = " (it ignores the jitter)" if est.ignores_jitter else ""
            raise ValueError(
                f"method must be one of {names} when a noise model is given (noise=...); got "
                f"{est.name!r}, which has no coloured-noise (Box-Jenkins) form{hint}: fit it "
                "with noise=None"
            )
        if cov_type not in ("sandwich", "none"):
            raise ValueError(
                f"cov_type must be 'sandwich' or 'none' with a noise model; got {cov_type!r} "
                "(the robust and observed-information forms are not implemented for "
                "Box-Jenkins yet)"
            )
        structure = as_structure(system)
        if not isinstance(structure, ModelStructure):
            raise ValueError(  # noqa: TRY004 (a ValueError naming the argument)
                "noise: coloured noise (Box-Jenkins) is implemented for LTI structures driven by "
                f"a known input; {type(structure).__name__} is a signal model: fit it with "
                "noise=None"
            )
        nj = count_params(jitter)
        check_data(data, len(structure.param_names) + nj)
        nstruct = as_noise_structure(noise)
        f = (
            default_frequencies(data.N, data.T)
            if freqs is None
            else np.atleast_1d(real_array(freqs, "freqs"))
        )
        self.white = data.noise_std if noise_std is None else noise_std
        self.free_noise = len(nstruct.param_names) > 0 or self.white is None
        # a criterion without a ln det term holds the noise parameters at plug-in values
        self.plug_in = self.free_noise and not est.identifies_noise_model
        # The search runs in the units of checks.Scaling (as the OE route); every parameter,
        # the criterion and the covariance map back exactly (powers of two).
        self.scaling, noise_s = _scaling(data, structure, nstruct, nj)
        self.orig, self.data = data, self.scaling.data(data)
        white_s = None if self.white is None else self.white / self.scaling.sy
        self.make = partial(
            BJProblem, self.data, structure, jitter, noise_s, freqs=f, white_std=white_s
        )
        self.structure, self.jitter, self.estimator, self.nstruct = structure, jitter, est, nstruct
        self.freqs, self.max_nfev, self.nj = f, max_nfev, nj
        self._white_fit = white_fit
        self._prefit: list[FitResult] = []
        self._given: FitResult | None = None

    def prefit(self) -> FitResult:
        """The white-noise first-stage (BCLS) fit (Section 4.5), once; the driver scales the
        data exactly as here, so its estimate maps to these units exactly. Its white-noise
        covariance is never used, nor does the white-noise lack-of-fit check apply where the
        noise is coloured (the noise std is not passed)."""
        if not self._prefit:
            first = self.estimator.first_stage()
            self._prefit.append(self._white_fit(first, self._given, "none"))
        return self._prefit[0]

    # ------------------------------------------------------------------ 1. starts, search
    def search(self, start: ArrayLike | FitResult | None) -> Staged:
        est, sc, max_nfev = self.estimator, self.scaling, self.max_nfev
        self._given = start if isinstance(start, FitResult) else None
        problem = self.make(method=est)
        k = problem.n_jitter + problem.n_system
        # points of the default route that the final search did not start from, for the
        # local-optimum check (lazily: they cost a pre-fit and a noise stage after a start)
        others: list[Callable[[], FloatArray | None]] = []
        nfev = 0
        if start is not None and not isinstance(start, FitResult):
            x0 = np.atleast_1d(real_array(start, "start"))
            if x0.size != len(problem.names):
                raise ValueError(
                    f"start must have {len(problem.names)} values {problem.names}; got {x0.size}"
                )
            x0 = sc.to_scaled(x0)
            if self.plug_in:
                problem = self.make(method=est, pinned=x0[k:])
            problem, best = run_search(problem, x0, max_nfev)
            nfev = best.nfev

            def default_start() -> FloatArray | None:
                x_pre = sc.to_scaled(self.prefit().x)
                eta = _noise_stage(problem, x_pre, max_nfev)[0] if self.free_noise else np.zeros(0)
                return np.r_[x_pre, eta]

            others.append(default_start)
        else:
            pre = self.prefit()
            nfev = pre.nfev
            x_pre = sc.to_scaled(pre.x)
            eta, n = _noise_stage(problem, x_pre, max_nfev) if self.free_noise else (np.zeros(0), 0)
            nfev += n
            x_bcls = np.r_[x_pre, eta]
            # The GLS stage picks the system's basin where coloured noise dominates some
            # frequencies; a noise model white once sampled (a white record) weights as the
            # OE criterion does, which starts from the BCLS estimate too: skipped. A
            # criterion blind to Sigma_y keeps its estimate (below).
            if est.weighs_by_noise and not _white_limit(problem, x_bcls)[0]:
                theta, moved, n = _whitened_stage(problem, x_pre, eta, max_nfev)
                nfev += n
                x_pre = np.r_[x_pre[: problem.n_jitter], theta]  # the GLS system: closer
                if moved and self.free_noise:  # another basin: refit the noise to it
                    eta, n = _noise_stage(problem, x_pre, max_nfev, start=eta)
                    nfev += n
            x0 = np.r_[x_pre, eta]
            if not np.array_equal(x_bcls, x0):
                others.append(lambda: x_bcls)
            if self.plug_in:
                problem = self.make(method=est, pinned=eta)
            if not est.weighs_by_noise:
                # The noise model does not enter the criterion (BCLS (14)): its BJ estimate
                # is its white-noise one (the first stage itself for BCLS), the noise model
                # only its error bars.
                if est is not est.first_stage():
                    pre = self._white_fit(est, pre, None)
                    nfev += pre.nfev
                    x0 = np.r_[sc.to_scaled(pre.x)[:k], eta]
                best = Outcome(x0, problem.objective(x0), pre.status, pre.message, 0)
            else:
                problem, best = run_search(problem, x0, max_nfev)
                nfev += best.nfev
        return Staged(problem, best._replace(nfev=nfev), None, {"others": others})

    # ------------------------------------------------------------------ 2. covariance
    def covariance(self, staged: Staged, cov_type: str) -> tuple[FloatArray, str | None, str]:
        """The delta-method covariance with the coloured Sigma_y (:func:`bj_covariance`).

        A noise model that is white once sampled (a white record: its gain at 0 or its pole
        run off) is the natural home of the estimate, as a jitter scale at 0 is on data
        without jitter. The noise parameters are then not identified (held in the
        covariance, whose other rows they would only fill with rounding), nor is the white
        std apart from them when both are white: no error bars for those, exempt from the
        identifiability check, said in the message; the system's are checked as usual."""
        problem, x = staged.problem, staged.outcome.x
        cov = np.full((x.size, x.size), np.nan)
        cov_error: str | None = None
        held, white_limit = _white_limit(problem, x)
        staged.extra["cov_requested"] = cov_type != "none"  # an all-NaN one is then a failure
        if cov_type == "sandwich":
            try:
                cov = bj_covariance(problem, x, held)
            except (ValueError, np.linalg.LinAlgError) as exc:  # the checks say why
                cov_error = str(exc)
        staged.extra["exempt"] = white_limit
        note = ""
        if white_limit:
            cov[white_limit, :] = np.nan
            cov[:, white_limit] = np.nan
            note = (
                "; the noise model is at its white limit (the sampled coloured noise is white "
                f"or zero): {[problem.names[i] for i in white_limit]} not identified (no "
                "standard errors)"
            )
        return cov, cov_error, note

    # ------------------------------------------------------------------ 3. checks
    def post_context(self, staged: Staged, cov: FloatArray, cov_error: str | None) -> PostContext:
        problem = staged.problem
        return PostContext(
            data=self.data,
            y_scale=self.scaling.sy,
            structure=self.structure,
            jitter=self.jitter,
            names=problem.names,
            bounds=problem.bounds,
            x=staged.outcome.x,
            cost=float(staged.outcome.cost),
            cov=cov,
            objective=problem.objective,
            model_mean=lambda v: problem.moments(v).mean,
            oe_system=lambda: self.scaling.to_scaled(self.prefit().x)[self.nj :],
            starts=partial(_other_starts, problem, staged.extra["others"]),
            cov_error=cov_error,
            exempt=staged.extra.get("exempt", ()),
            cov_requested=staged.extra.get("cov_requested"),
        )

    # ------------------------------------------------------------------ 4. units
    def to_data_units(self, staged: Staged, x: FloatArray) -> BJProblem:
        problem = staged.problem
        if self.scaling.identity:
            return problem
        k = problem.n_jitter + problem.n_system
        w = problem.weights_at
        return BJProblem(
            self.orig,
            self.structure,
            self.jitter,
            self.nstruct,
            self.estimator,
            self.freqs,
            self.white,
            pinned=x[k:] if problem.pinned is not None else None,
            weights_at=None if w is None else self.scaling.to_original(w),
        )

    # ------------------------------------------------------------------ 5. result
    def result_fields(self, problem: Any, x: FloatArray, staged: Staged) -> dict[str, Any]:
        law, tf, noise_fitted, white_used = problem.split(x)
        return {
            "system": tf,
            "jitter_law": law,
            "noise_std": white_used,
            "structure": self.structure,
            "jitter_model": self.jitter,
            "noise_structure": self.nstruct,
            "noise_model": noise_fitted,
        }


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
