"""The estimators as objects, one module each: what each one is, which options it carries,
how it is searched, and its criterion.

==============  ======================  ========================================================
name            class                   criterion
==============  ======================  ========================================================
``ls``          :class:`LS`             (8): sum_f |Y - S_d|^2, jitter ignored
``bcls``        :class:`BCLS`           (14): sum_f |Y - mu_Y|^2
``wbcls``       :class:`WBCLS`          (20) with R_Y frozen at a preliminary estimate
``asml``        :class:`AsML`           (22): (Y - mu)^H R^{-1} (Y - mu) + ln det R
``asml-diag``   :class:`AsMLDiag`       (23): the diagonal of (22)
``gaussian``    :class:`GaussianCriterion`  the exact real Gaussian criterion (notes 3)
``ml``          :class:`ML`             the exact likelihood (notes 4)
==============  ======================  ========================================================

:func:`jitterid.fit` accepts an instance or its registered name. The white-noise problem
(:class:`jitterid.estimation.problem.Problem`) gives each criterion the moments, their
derivatives and the weights (:class:`~.base.CriterionContext`); the coloured-noise problem
(:class:`jitterid.estimation.bjcriteria.BJProblem`) gives the ``bj_*`` forms of the criteria
(``bcls``, ``wbcls``, ``asml``, ``asml-diag``, ``gaussian``) the same with the sample
covariance Sigma_y (:class:`~.base.ColouredContext`). Adding an estimator is one module with a
subclass of :class:`~.base.Estimator` decorated with :func:`~.base.register`, imported here.
"""

from .asml import AsML, AsMLDiag
from .base import (
    ColouredContext,
    CriterionContext,
    Estimator,
    as_estimator,
    coloured_method_names,
    method_names,
    register,
)
from .exact import ML
from .gaussian import GaussianCriterion
from .leastsquares import BCLS, LS
from .wbcls import WBCLS

__all__ = [
    "BCLS",
    "LS",
    "ML",
    "WBCLS",
    "AsML",
    "AsMLDiag",
    "ColouredContext",
    "CriterionContext",
    "Estimator",
    "GaussianCriterion",
    "as_estimator",
    "coloured_method_names",
    "method_names",
    "register",
]
