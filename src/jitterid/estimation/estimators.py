"""The estimators as objects: what each one is, which options it carries, how it is searched.

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

The criteria themselves are :class:`jitterid.estimation.problem.Problem` (white noise) and
:class:`jitterid.estimation.bjcriteria.BJProblem` (coloured noise). Adding an estimator is a
subclass here with :func:`register`, and its criterion in the problem.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

__all__ = [
    "BCLS",
    "LS",
    "ML",
    "WBCLS",
    "AsML",
    "AsMLDiag",
    "Estimator",
    "GaussianCriterion",
    "as_estimator",
    "method_names",
    "register",
]


@dataclass(frozen=True)
class Estimator:
    """Base class: the properties every estimator states.

    Class attributes
    ----------------
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
    """

    name: ClassVar[str]
    equation: ClassVar[str]
    least_squares: ClassVar[bool] = False
    needs_noise: ClassVar[bool] = True
    estimates_noise: ClassVar[bool] = True
    cov_types: ClassVar[tuple[str, ...]] = ("sandwich", "robust", "none")

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
    _REGISTRY[cls.name] = cls
    return cls


def method_names() -> tuple[str, ...]:
    """The registered estimator names."""
    return tuple(_REGISTRY)


def as_estimator(method: str | Estimator) -> Estimator:
    """An :class:`Estimator` from an instance or its registered name."""
    if isinstance(method, Estimator):
        return method
    if isinstance(method, str) and method in _REGISTRY:
        return _REGISTRY[method]()
    raise ValueError(f"method must be one of {method_names()} or an Estimator; got {method!r}")


@register
@dataclass(frozen=True)
class LS(Estimator):
    """Ordinary least squares (8): ignores the jitter (biased at high frequencies)."""

    name = "ls"
    equation = "(8)"
    least_squares = True
    needs_noise = False
    estimates_noise = False
    cov_types = ("robust", "sandwich", "none")


@register
@dataclass(frozen=True)
class BCLS(Estimator):
    """Bias-compensated least squares (14): the residual to the jittered mean mu_Y."""

    name = "bcls"
    equation = "(14)"
    least_squares = True
    needs_noise = False
    estimates_noise = False


@register
@dataclass(frozen=True)
class WBCLS(Estimator):
    """Weighted BCLS (20), with R_Y frozen at the BCLS estimate and re-frozen ``refreeze``
    times at the new estimate (iterated feasible GLS; the literal (20) is biased, see
    :mod:`jitterid.estimation.problem`)."""

    name = "wbcls"
    equation = "(20)"
    least_squares = True
    estimates_noise = False
    refreeze: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.refreeze, int) or self.refreeze < 0:
            raise ValueError(f"refreeze must be a whole number >= 0; got {self.refreeze!r}")


@register
@dataclass(frozen=True)
class AsML(Estimator):
    """Asymptotic ML (22) with the full frequency covariance R_Y."""

    name = "asml"
    equation = "(22)"


@register
@dataclass(frozen=True)
class AsMLDiag(Estimator):
    """Reduced asymptotic ML (23): the diagonal of R_Y."""

    name = "asml-diag"
    equation = "(23)"


@register
@dataclass(frozen=True)
class GaussianCriterion(Estimator):
    """The exact real-valued Gaussian criterion of the sample means and variances (notes 3)."""

    name = "gaussian"
    equation = "notes 3"
    cov_types = ("sandwich", "robust", "oim", "none")


@register
@dataclass(frozen=True)
class ML(Estimator):
    """The exact likelihood (notes 4), at the Cramer-Rao bound."""

    name = "ml"
    equation = "notes 4"
    cov_types = ("oim", "robust", "none")
