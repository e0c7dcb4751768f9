"""fit(): the one driver of every estimator and formulation.

:func:`fit` validates its arguments, chooses the route of the noise model (white noise: OE
(2a) / JOE (2c), :class:`~jitterid.estimation.oe.OutputErrorRoute`; coloured noise: BJ (2b)
/ JBJ (2d), :class:`~jitterid.estimation.boxjenkins.BoxJenkinsRoute`) and runs every
estimator through the same sequence of the route's hooks (:mod:`jitterid.estimation.route`):
starts and search (the estimator's adapter of :data:`jitterid.estimation.search.SEARCHES`),
covariance, the checks after the search (:func:`jitterid.estimation.checks.post_checks`),
the data's units, and the :class:`~jitterid.estimation.result.FitResult`, which carries the
estimator object with its options. The driver never asks which estimator it has: the
estimator's declared properties (:class:`~jitterid.estimation.estimators.base.Estimator`)
say what each step needs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._threads import single_thread
from ..data import SampledData
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import NoiseModel, NoiseStructure
from ..systems.model import Model
from ..systems.structures import as_structure
from ..systems.tf import TransferFunction
from . import ml as _ml  # noqa: F401  (registers the "likelihood" search adapter)
from .boxjenkins import BoxJenkinsRoute
from .checks import check_arguments, post_checks
from .estimators import Estimator, as_estimator
from .oe import OutputErrorRoute
from .result import FitResult
from .route import Route

__all__ = ["fit"]

FloatArray = NDArray[np.float64]


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
    restart: bool = True,
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
        independent calls. On the white-noise route, a search from a given vector that stops
        without converging (``OPTIMISER_FAILED``, ``NOT_FINITE``, ``MAX_EVALUATIONS``: e.g.
        ``ml`` from poles far beyond the Nyquist rate, where the likelihood is flat in them)
        is restarted: the first stage (BCLS) from that vector, then the method from its
        estimate (each search with its own ``max_nfev``); the lower criterion is kept and the
        message says so (or, where the restart finds nothing lower, that it was tried and
        what to do). One that converges where the criterion is lower at a default start is
        searched again from that start first, and restarted so only where that does not
        lower it.
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
    restart : bool
        On the white-noise route, a search from a given ``start`` that stops without
        converging, or converges where a default start is lower, is restarted as ``start``
        says (default True). False returns where the search from ``start`` stopped, with its
        status: a budgeted start for another search (with a small ``max_nfev``), not an
        estimate to trust without reading ``status``.

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
        return _drive(
            data,
            system,
            jitter,
            as_estimator(method),
            start,
            freqs=freqs,
            noise_std=noise_std,
            max_nfev=max_nfev,
            noise=noise,
            cov_type=cov_type,
            restart=restart,
        )


def _drive(
    data: SampledData,
    system: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    est: Estimator,
    start: ArrayLike | FitResult | None,
    *,
    freqs: ArrayLike | None,
    noise_std: float | None,
    max_nfev: int,
    noise: NoiseStructure | NoiseModel | None,
    cov_type: str | None,
    restart: bool = True,
) -> FitResult:
    """The one sequence (module docstring)."""
    cov_type = est.check_cov_type(cov_type)
    noise_std, max_nfev = check_arguments(noise_std, max_nfev)
    if not isinstance(restart, bool):
        raise TypeError(f"restart must be True or False; got {restart!r}")
    if not isinstance(data, SampledData):
        raise TypeError(
            f"data must be a SampledData (see jitterid.simulate); got {type(data).__name__}"
        )
    if not isinstance(jitter, (JitterLaw, JitterFamily)):
        raise TypeError(
            "jitter must be a jitter law (Uniform(a), Gaussian(sigma), SumOfUniforms(n, a), ...) "
            f"or a family (SumOfUniformsFamily(), ...); got {type(jitter).__name__}"
        )
    route: Route
    if noise is None:
        route = OutputErrorRoute(
            data,
            as_structure(system),
            jitter,
            est,
            freqs=freqs,
            noise_std=noise_std,
            max_nfev=max_nfev,
            restart=restart,
        )
    else:

        def white_fit(e: Estimator, given: FitResult | None, cov: str | None) -> FitResult:
            """The white-noise fit of ``e`` (a first stage, or a criterion blind to the
            noise model): the same driver with noise=None, the noise std not passed."""
            return _drive(
                replace(data, noise_std=None),
                system,
                jitter,
                e,
                given,
                freqs=freqs,
                noise_std=None,
                max_nfev=max_nfev,
                noise=None,
                cov_type=cov,
            )

        route = BoxJenkinsRoute(
            data,
            system,
            jitter,
            est,
            noise,
            freqs=freqs,
            noise_std=noise_std,
            max_nfev=max_nfev,
            cov_type=cov_type,
            white_fit=white_fit,
        )
    staged = route.search(start)
    x, cost, status, msg, nfev = staged.outcome
    x = np.asarray(x, float)
    cov, cov_error, note = route.covariance(staged, cov_type)
    status, msg = post_checks(route.post_context(staged, cov, cov_error), status, msg + note)
    sc = route.scaling
    if not sc.identity:  # back to the data's units, exactly; the criterion re-evaluated there
        x = sc.to_original(x)
        cov = sc.cov_to_original(cov)
    problem = route.to_data_units(staged, x)
    if not sc.identity:
        with np.errstate(all="ignore"):
            try:
                cost = problem.objective(x)
            except (ValueError, np.linalg.LinAlgError):
                cost = np.inf
    fields = route.result_fields(problem, x, staged)
    return FitResult(
        method=est.name,
        names=problem.names,
        x=x,
        cost=float(cost),
        status=status,
        message=msg,
        nfev=nfev,
        freqs=route.freqs,
        cov=cov,
        cov_type=cov_type,
        estimator=est,
        layout=problem.layout,
        **fields,
    )
