"""The estimator protocol and registry (the estimators are one module each beside this one).

Every estimator of the paper (and the two exact ones) is a small frozen class that states
its criterion's equation, how it is searched (least squares on residuals with a Jacobian,
or damped Newton on a value, gradient and expected Hessian), what it needs of the
measurement noise, and which covariance forms apply. :func:`jitterid.fit` accepts an
instance or its registered name:

==============  ===========  =============================================================
name            class        criterion
==============  ===========  =============================================================
``ls``          :class:`LS`        (8): sum_f |Y - S_d|^2, jitter ignored
``bcls``        :class:`BCLS`      (14): sum_f |Y - mu_Y|^2
``wbcls``       :class:`WBCLS`     (20) with R_Y frozen at a preliminary estimate
``asml``        :class:`AsML`      (22): (Y - mu)^H R^{-1} (Y - mu) + ln det R
``asml-diag``   :class:`AsMLDiag`  (23): the diagonal of (22)
``gaussian``    :class:`GaussianCriterion` the exact real Gaussian criterion of m_k, w_k (notes 3)
``ml``          :class:`ML`        the exact likelihood (notes 4)
==============  ===========  =============================================================

Each estimator carries its criterion in two forms: the white-noise one, reading
:class:`jitterid.estimation.problem.Problem` through :class:`CriterionContext`, and (if it has
one) the coloured-noise (Box-Jenkins) one, the ``bj_*`` methods, reading
:class:`jitterid.estimation.bjcriteria.BJProblem` through :class:`ColouredContext`. Adding an
estimator is a subclass with :func:`register`, its criteria in its own module.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, NoReturn, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ...moments.noise_covariance import SampleCovariance
    from ...moments.sample import SampleMoments

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Chol = tuple[FloatArray, bool]


class CriterionContext(Protocol):
    """What a criterion reads of its problem (:class:`jitterid.estimation.problem.Problem`):
    the data, the moments and their derivatives, the DTFT residual, the weights."""

    data: Any
    freqs: FloatArray
    likelihood: Any

    def moments(self, x: FloatArray) -> Any: ...
    def variances(self, x: FloatArray) -> FloatArray: ...
    def weighted(self, x: FloatArray) -> tuple[ComplexArray, Chol | None]: ...
    def derivatives(self, x: FloatArray) -> tuple[Any, FloatArray, FloatArray, FloatArray]: ...
    def dmu(self, dm: FloatArray) -> ComplexArray: ...
    def dR(self, dw: FloatArray) -> ComplexArray: ...
    def adjoint(self, z: ComplexArray) -> FloatArray: ...
    @property
    def frozen_weights(self) -> bool: ...


# d gamma(0..N-1) and d(ar) of the jittered noise autocovariance, by parameter index
GammaDerivatives = dict[int, tuple[FloatArray, FloatArray]]


class ColouredContext(Protocol):
    """What a coloured-noise (Box-Jenkins) criterion reads of its problem
    (:class:`jitterid.estimation.bjcriteria.BJProblem`): the data, the signal moments, the
    sample covariance Sigma_y = diag(d) + Toeplitz(gamma) of (C2) and its DFT R = E Sigma_y
    E^H, and their parameter derivatives."""

    data: Any
    freqs: FloatArray

    def moments(self, x: FloatArray) -> SampleMoments: ...
    def covariance(self, x: FloatArray) -> SampleCovariance: ...
    def derivatives(
        self, x: FloatArray
    ) -> tuple[SampleMoments, FloatArray, FloatArray, GammaDerivatives]: ...
    def weighted(self, x: FloatArray) -> tuple[ComplexArray, Chol | None]: ...
    def dmu(self, dm: FloatArray) -> ComplexArray: ...
    def dR(self, dd: FloatArray, dg: GammaDerivatives) -> ComplexArray: ...
    def R_diagonal(self, x: FloatArray) -> FloatArray: ...
    def dR_diagonal(self, dd: FloatArray, dg: GammaDerivatives) -> FloatArray: ...
    def adjoint(self, z: ComplexArray) -> FloatArray: ...
    def probes(self) -> FloatArray: ...
    @property
    def frozen_weights(self) -> bool: ...


__all__ = [
    "ColouredContext",
    "CriterionContext",
    "Estimator",
    "as_estimator",
    "coloured_method_names",
    "method_names",
    "register",
]


@dataclass(frozen=True)
class Estimator:
    """Base class: the properties every estimator states.

    Attributes
    ----------
    name : str
        The registered name (``fit(..., method=name)``).
    equation : str
        Where the criterion is in the paper (or the notes).
    least_squares : bool
        Searched as least squares on residuals with a Jacobian (``scipy.optimize
        .least_squares``); otherwise by :func:`jitterid.estimation.search.newton_search`.
    needs_noise : bool
        The criterion needs the measurement-noise variance.
    estimates_noise : bool
        The criterion can estimate the noise std (a ln det term makes it identifiable).
    cov_types : tuple of str
        The covariance forms that apply (the first is the default).
    ignores_jitter : bool
        The criterion's model has no jitter (LS (8)).
    full_covariance : bool
        The criterion weights by the full frequency covariance R_Y (its Cholesky factor is
        formed by the problem).
    uses_variances : bool
        The criterion (or its derivatives) reads the sample variances w_k; False lets the
        problem skip their pass (LS, BCLS).
    coloured_noise : bool
        The criterion has a coloured-noise (Box-Jenkins) form, the ``bj_*`` methods, so that
        ``fit(..., noise=...)`` accepts it. False (the default): those methods refuse.
    identifies_noise_model : bool
        With coloured noise, the criterion identifies the noise model's parameters (and an
        unknown white std): a ln det term. False: they are plug-in values held fixed (fitted
        to the BCLS residuals by the Gaussian criterion), with NaN standard errors.
    weighs_by_noise : bool
        With coloured noise, the criterion depends on the noise covariance Sigma_y. False
        (BCLS (14)): its Box-Jenkins estimate of the system is its white-noise one, and the
        noise model enters only the error bars.
    search : str
        The search adapter of :data:`jitterid.estimation.search.SEARCHES` that minimises the
        criterion: ``"least_squares"`` (trust-region least squares on :meth:`residuals`),
        ``"newton"`` (damped Newton on :meth:`objective_gradient`) or ``"likelihood"`` (the
        exact likelihood's own maximisation with scored starts,
        :mod:`jitterid.estimation.ml`). Default: from ``least_squares``.
    exact_likelihood : bool
        The criterion is the exact likelihood: the problem builds
        :class:`~jitterid.estimation.likelihood.ExactLikelihood` (its quadrature rule), the
        covariance uses its observed information, and the noise std must be positive.
    scores_own_starts : bool
        The search scores its own starts for a jitter family (the likelihood's search);
        otherwise the driver moves a start off a zero jitter scale (Newton searches).
    first_stage_class : type or None
        The estimator whose fit starts this one on the default route (:meth:`first_stage`);
        None: fitted in one stage.

    Notes
    -----
    A least-squares estimator implements :meth:`residuals` and :meth:`jacobian`; any other
    :meth:`objective_gradient`; every one :meth:`objective` and :meth:`grad_y` (dV/dy, for
    the delta-method covariance). The coloured-noise form (``coloured_noise = True``) is
    :meth:`bj_residuals` and :meth:`bj_jacobian`, or :meth:`bj_objective_gradient`, and
    :meth:`bj_objective`, :meth:`bj_grad_y`.

    Examples
    --------
    >>> import jitterid as ji
    >>> est = ji.BCLS()
    >>> isinstance(est, ji.Estimator), est.ignores_jitter, ji.LS().ignores_jitter
    (True, False, True)
    """

    name: ClassVar[str]
    equation: ClassVar[str]
    least_squares: ClassVar[bool] = False
    needs_noise: ClassVar[bool] = True
    estimates_noise: ClassVar[bool] = True
    cov_types: ClassVar[tuple[str, ...]] = ("sandwich", "robust", "none")
    ignores_jitter: ClassVar[bool] = False
    full_covariance: ClassVar[bool] = False
    uses_variances: ClassVar[bool] = True
    rank: ClassVar[int] = 100  # position in listings (the paper's order first)
    coloured_noise: ClassVar[bool] = False
    identifies_noise_model: ClassVar[bool] = False
    weighs_by_noise: ClassVar[bool] = True
    exact_likelihood: ClassVar[bool] = False
    scores_own_starts: ClassVar[bool] = False
    first_stage_class: ClassVar[type[Estimator] | None] = None

    # ------------------------------------------------------------------ the fit's hooks
    # :func:`jitterid.fit` drives every estimator through the same sequence (module
    # :mod:`jitterid.estimation.fit`); these say what the estimator needs of each step.
    @property
    def is_likelihood(self) -> bool:
        """The criterion is -2 ln of a likelihood (exact, or the Gaussian one of the sample
        moments): its inverse observed information is a covariance (``"oim"``), and its
        differences between nested models are likelihood-ratio statistics."""
        return "oim" in self.cov_types

    @property
    def search(self) -> str:
        """The search adapter's key in :data:`jitterid.estimation.search.SEARCHES`."""
        return "least_squares" if self.least_squares else "newton"

    def first_stage(self) -> Estimator:
        """The estimator of the default route's first stage (Section 4.5), an instance of
        ``first_stage_class`` (BCLS for the paper's second-stage estimators), whose estimate
        starts this one; without one (``ls``, ``bcls``) the estimator is its own first stage,
        fitted from the ordinary output-error start."""
        cls = self.first_stage_class
        return self if cls is None else cls()

    def noise_start(self, rms: float | None, plug_in: Callable[[], float]) -> float:
        """The start of an estimated noise std: ``rms`` is the ordinary output-error fit's
        residual rms, ``plug_in()`` the noise std that the first stage's residuals leave
        beyond the jitter (:func:`jitterid.estimation.fit.noise_from_residuals`)."""
        return max(rms or 0.0, 1e-6)

    # ------------------------------------------------------------------ the criterion
    def objective(self, problem: CriterionContext, x: FloatArray) -> float:
        """The criterion value V(theta)."""
        if self.least_squares:
            return float(np.sum(self.residuals(problem, x) ** 2))
        raise NotImplementedError

    def residuals(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        """Real residuals whose squared norm is V (least-squares estimators)."""
        raise NotImplementedError(f"{self.name} is not a least-squares criterion")

    def jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        """d residuals / dx, shape (n_residuals, P) (least-squares estimators)."""
        raise NotImplementedError(f"{self.name} is not a least-squares criterion")

    def objective_gradient(
        self, problem: CriterionContext, x: FloatArray
    ) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian of V) (Newton-searched estimators)."""
        raise NotImplementedError(f"{self.name} has no analytic gradient")

    def grad_y(self, problem: CriterionContext, x: FloatArray) -> FloatArray:
        """dV/dy at the data."""
        raise NotImplementedError

    def grad_y_jacobian(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        """d^2 V / dx dy^T, shape (P, N), in closed form, or None: the covariance then
        differences :meth:`grad_y` (:mod:`jitterid.finite_diff`)."""
        return None

    def y_hessian_diagonal(self, problem: CriterionContext, x: FloatArray) -> FloatArray | None:
        """For a criterion whose gradient dV/dx is a sum of per-sample terms quadratic in
        y_k (no cross terms): A, shape (P, N), with d^2(dV/dx) / dy_k^2 = 2 A[:, k]. The
        covariance then uses the samples' third and fourth moments exactly
        (:mod:`jitterid.estimation.covariance`). None (the default): not of that form.
        """
        return None

    @property
    def freeze_rounds(self) -> int:
        """Searches with the criterion's weights frozen at the previous estimate (iterated
        feasible GLS, :mod:`.wbcls`); 0: the weights are evaluated at the searched point."""
        return 0

    # ------------------------------------------------------------------ coloured noise
    # The Box-Jenkins form of the criterion (:mod:`jitterid.estimation.bjcriteria`): the same
    # criterion with the sample covariance Sigma_y of (C2) in place of the white-noise one.
    def refuse_coloured_noise(self) -> NoReturn:
        """Raise the ValueError of an estimator without a coloured-noise form."""
        raise ValueError(
            f"method {self.name!r} has no coloured-noise (Box-Jenkins) form, so it cannot be "
            f"used with noise=...: fit it with noise=None, or use one of "
            f"{coloured_method_names()} with the noise model"
        )

    def _no_bj(self, what: str) -> NoReturn:
        if not self.coloured_noise:
            self.refuse_coloured_noise()
        kind = "least-squares" if self.least_squares else "Newton-searched"
        raise NotImplementedError(f"{self.name} is a {kind} criterion: it has no {what}")

    def bj_objective(self, problem: ColouredContext, x: FloatArray) -> float:
        """The coloured-noise criterion value V(theta)."""
        if self.coloured_noise and self.least_squares:
            return float(np.sum(self.bj_residuals(problem, x) ** 2))
        self._no_bj("bj_objective")

    def bj_residuals(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """Real residuals whose squared norm is the coloured-noise V (least squares)."""
        self._no_bj("bj_residuals")

    def bj_has_jacobian(self, problem: ColouredContext) -> bool:
        """Whether :meth:`bj_jacobian` applies to ``problem`` (else the residuals are
        differenced)."""
        return self.coloured_noise and self.least_squares

    def bj_jacobian(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """d :meth:`bj_residuals` / dx, shape (n_residuals, P) (least squares)."""
        self._no_bj("bj_jacobian")

    def bj_objective_gradient(
        self, problem: ColouredContext, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian of V) with coloured noise (Newton-searched). ``free``:
        the indices searched; an estimator may then form only their rows and columns (zeros
        elsewhere)."""
        self._no_bj("bj_objective_gradient")

    def bj_grad_y(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """dV/dy at the data, coloured noise (for the delta-method covariance)."""
        self._no_bj("bj_grad_y")

    def bj_grad_y_jacobian(self, problem: ColouredContext, x: FloatArray) -> FloatArray | None:
        """d^2 V / dx dy^T, shape (P, N), in closed form, or None: the covariance then
        differences :meth:`bj_grad_y` (as :meth:`grad_y_jacobian` for white noise)."""
        return None

    def bj_gradient(self, problem: ColouredContext, x: FloatArray) -> FloatArray:
        """dV/dx alone (what the covariance differences for the Hessian of a Newton-searched
        criterion); by default from :meth:`bj_objective_gradient`."""
        return self.bj_objective_gradient(problem, x)[1]

    def frequency_kernel(self, problem: CriterionContext, x: FloatArray) -> ComplexArray | None:
        """For a frequency-domain criterion whose gradient dV/dx is quadratic in the DTFT
        residual r = Y - mu: K, with the quadratic part of dV/dx_p equal to r^H K_p r; shape
        (P, F, F), or (P, F) for a diagonal K. The covariance then uses the samples' second,
        third and fourth moments exactly (:mod:`jitterid.estimation.covariance`). None (the
        default): linear in y, or not of that form.
        """
        return None

    @property
    def default_cov_type(self) -> str:
        return self.cov_types[0]

    def check_cov_type(self, cov_type: str | None) -> str:
        """``cov_type`` validated for this estimator, or its default."""
        if cov_type is None:
            return self.default_cov_type
        if cov_type not in self.cov_types:
            raise ValueError(
                f"cov_type must be one of {self.cov_types} for method {self.name!r}; got "
                f"{cov_type!r} ('oim' needs a likelihood: ml or gaussian; 'sandwich' with model "
                "variances is for the moment estimators)"
            )
        return cov_type


_REGISTRY: dict[str, type[Estimator]] = {}


def register(cls: type[Estimator]) -> type[Estimator]:
    """Class decorator: make ``cls`` available to :func:`as_estimator` under ``cls.name``."""
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise ValueError(f"an estimator named {cls.name!r} is registered already")
    if cls.coloured_noise and cls.bj_grad_y is Estimator.bj_grad_y:
        raise TypeError(
            f"estimator {cls.__name__} declares coloured_noise = True but implements no "
            "coloured-noise criterion (bj_objective, bj_grad_y, ...; see Estimator)"
        )
    _REGISTRY[cls.name] = cls
    return cls


def method_names() -> tuple[str, ...]:
    """The registered estimator names, the paper's order first."""
    return tuple(sorted(_REGISTRY, key=lambda n: (_REGISTRY[n].rank, n)))


def coloured_method_names() -> tuple[str, ...]:
    """The registered estimators with a coloured-noise (Box-Jenkins) form, in listing order."""
    return tuple(n for n in method_names() if _REGISTRY[n].coloured_noise)


def as_estimator(method: str | Estimator) -> Estimator:
    """An :class:`Estimator` from an instance or its registered name."""
    if isinstance(method, Estimator):
        return method
    if isinstance(method, str) and method in _REGISTRY:
        return _REGISTRY[method]()
    raise ValueError(f"method must be one of {method_names()} or an Estimator; got {method!r}")
