"""Lower bounds on the covariance of estimators: the Cramer-Rao bound of the exact likelihood
(L3) and the bound of the second-moment (Gaussian) model (L4) (notes 4).

:func:`crb` inverts the Fisher information of :meth:`ExactLikelihood.fisher`, whose scores
are differences of ln p_k with steps scaled to each parameter's natural scale from (L4);
:func:`gaussian_bound` inverts

    I_G = sum_k [dm_k dm_k^T / w_k + dw_k dw_k^T / (2 w_k^2)]                          (L4)

with dm, dw from the moments' derivative pass (:mod:`jitterid.estimation.jacobians`).
Parameter values go in as a dict by name, a vector or a FitResult
(:meth:`jitterid.params.ParamLayout.vector`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import count, generator, positive, sampling_interval
from ..data import SampledData
from ..inputs import Input
from ..jitter.laws import JitterFamily, JitterLaw
from ..params import ParamLayout
from ..systems.model import Model
from ..systems.structures import as_structure
from ..systems.tf import TransferFunction
from .estimators import GaussianCriterion
from .likelihood import DEFAULT_ORDER, DEFAULT_PANEL, ExactLikelihood
from .problem import Problem, default_frequencies

__all__ = ["crb", "gaussian_bound"]

FloatArray = NDArray[np.float64]


def _problem_setup(
    system_structure: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    T: float,
    N: int,
    noise_std: float,
    true_params: ArrayLike,
) -> tuple[Model, FloatArray]:
    structure = as_structure(system_structure)
    # a dict by name, a vector (jitter-family then system parameters; noise_std is passed
    # separately) or a FitResult, whose entries are taken by name
    x = ParamLayout.build(jitter, structure).vector(true_params, "true_params")
    sampling_interval(T, "T")
    count(N, "N", minimum=1)
    positive(noise_std, "noise_std")
    return structure, x


def _inverse(info: FloatArray, names: tuple[str, ...]) -> FloatArray:
    scale = np.sqrt(np.abs(np.diag(info)))
    if np.any(scale == 0) or np.linalg.cond(info / np.outer(scale, scale)) > 1e14:
        raise ValueError(
            f"the Fisher information of parameters {names} is singular: some parameter is not "
            "identifiable from this experiment (fix it, or change the input or the structure)"
        )
    return np.asarray(np.linalg.inv(info), dtype=float)


def crb(
    system_structure: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    input: Input | None,  # the name is part of the documented signature
    T: float,
    N: int,
    noise_std: float,
    true_params: ArrayLike,
    *,
    estimate_noise: bool = False,
    order: int = DEFAULT_ORDER,
    panel: float = DEFAULT_PANEL,
    draws: int | None = None,
    rng: np.random.Generator | int | None = None,
) -> FloatArray:
    """Cramer-Rao bound: the inverse Fisher information (L3) of the exact likelihood.

    Parameters
    ----------
    system_structure : Model or TransferFunction
        The structure (``PolePairGain()``), a signal model (``SignalModel``), or a known
        system (no system parameters).
    jitter : JitterLaw or JitterFamily
        A known jitter law, or a family whose parameters are estimated (JOE).
    input : Input or None
        The known input (None for a signal model).
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    noise_std : float
        The measurement-noise std (> 0).
    true_params : dict, array_like or FitResult
        The point of evaluation: a dict by name, a vector in :func:`jitterid.fit`'s order
        (jitter-family parameters if ``jitter`` is a family, then the system parameters;
        without ``noise_std``), or a FitResult (its values taken by name).
    estimate_noise : bool
        Default False: the noise std is known (as in the paper's experiments). True adds it
        as a last parameter (the bound of an estimator that also estimates it).
    order, panel : int, float
        Accuracy controls of the quadrature over tau (see :class:`ExactLikelihood`).
    draws : int, optional
        Instead of (L3)'s integral over y per sample (whose grid grows as the signal's
        range over the noise std: costly for a steep signal in small noise), the Fisher
        information as the mean outer product of the exact scores (L2) over ``draws``
        records simulated at ``true_params``: I = E[g g^T] estimated without bias, with a
        relative error of about sqrt(2 / (draws N)) per element (the second route of the
        tests). Needs ``rng``.
    rng : numpy.random.Generator or int, optional
        The source of the simulated records (with ``draws``).

    Returns
    -------
    ndarray, shape (p, p)
        Lower bound on the covariance of any unbiased estimator, rows and columns in the
        order of ``true_params`` (plus ``noise_std`` last if ``estimate_noise``).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> C = jid.crb(jid.RationalModel(0, 1), jid.Uniform(0.05), u, 0.1, 2000, 0.01, [2.0, 2.0])
    >>> C.shape, bool(np.all(np.diag(C) > 0))
    ((2, 2), True)
    """
    structure, x = _problem_setup(system_structure, jitter, T, N, noise_std, true_params)
    lik = ExactLikelihood(
        structure,
        jitter,
        input,
        T,
        N,
        None if estimate_noise else noise_std,
        order=order,
        panel=panel,
    )
    if estimate_noise:
        x = np.r_[x, float(noise_std)]
    if draws is not None:
        return _inverse(
            _sampled_information(lik, x, count(draws, "draws", minimum=1), rng), lik.names
        )
    # each parameter's natural scale from (L4), whose derivatives are analytic: the steps of
    # the likelihood's differenced scores stay a small fraction of it
    info_g = _gaussian_information(structure, jitter, input, T, N, noise_std, x, estimate_noise)
    with np.errstate(divide="ignore"):
        scale = 1.0 / np.sqrt(np.diag(info_g))
    return _inverse(lik.fisher(x, scale=scale), lik.names)


def _sampled_information(
    lik: ExactLikelihood, x: FloatArray, draws: int, rng: np.random.Generator | int | None
) -> FloatArray:
    """sum_k E[g_k g_k^T] by the mean over ``draws`` simulated records of the exact scores."""
    if rng is None:
        raise ValueError("crb(..., draws=...) needs rng (a numpy Generator or a seed)")
    gen = generator(rng)
    law, sig, sigma = lik.split(x)
    t = np.arange(lik.N, dtype=float) * lik.T
    info = np.zeros((x.size, x.size))
    for _ in range(draws):
        tau = np.asarray(law.sample(lik.N, gen), dtype=float)
        y = sig(t + tau) + sigma * gen.standard_normal(lik.N)
        G = lik.scores(x, y)[1]
        info += G.T @ G
    return info / draws


def gaussian_bound(
    system_structure: Model | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    input: Input | None,  # same signature as crb
    T: float,
    N: int,
    noise_std: float,
    true_params: ArrayLike,
    *,
    estimate_noise: bool = False,
) -> FloatArray:
    """The Cramer-Rao bound of the second-moment model y_k ~ N(m_k, w_k), eq. (L4).

    m_k = E[s(kT + tau)] and w_k = Var[s(kT + tau)] + noise_std^2 (notes 1-2) carry all that
    the paper's estimators use; (L4) is the best covariance a Gaussian (second-moment)
    criterion attains when the samples really are Gaussian with those moments. Arguments as
    in :func:`crb`; the derivatives dm, dw from the moments' derivative pass (analytic where
    the model declares them; :mod:`jitterid.estimation.jacobians`).

    Parameters
    ----------
    system_structure, jitter, input
        As in :func:`crb`.
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    noise_std : float
        The measurement-noise std (> 0).
    true_params : dict, array_like or FitResult
        The point of evaluation, as in :func:`crb`.
    estimate_noise : bool, optional
        Whether the noise std is a last, estimated parameter (as in :func:`crb`).

    Returns
    -------
    ndarray, shape (P, P)
        The bound's covariance matrix.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(5.0, rng=1)
    >>> model, law = ji.RationalModel(0, 1), ji.Uniform(0.05)
    >>> crb = ji.gaussian_bound(model, law, u, 0.1, 40, 0.01, true_params=[2.0, 2.0])
    >>> crb.shape, bool(np.all(np.linalg.eigvalsh(crb) > 0))
    ((2, 2), True)
    """
    structure, x = _problem_setup(system_structure, jitter, T, N, noise_std, true_params)
    if estimate_noise:
        x = np.r_[x, float(noise_std)]
    info = _gaussian_information(structure, jitter, input, T, N, noise_std, x, estimate_noise)
    names = ParamLayout.build(jitter, structure, noise_std=estimate_noise).names
    return _inverse(info, names)


def _gaussian_information(
    structure: Model,
    jitter: JitterLaw | JitterFamily,
    input: Input | None,
    T: float,
    N: int,
    noise_std: float,
    x: FloatArray,
    estimate_noise: bool,
) -> FloatArray:
    """I_G of (L4) at ``x`` from one derivative pass of the moments (analytic where the
    model declares its derivatives: :mod:`jitterid.estimation.jacobians`)."""
    if input is not None and not isinstance(input, Input):
        raise TypeError(f"input must be a jitterid input or None; got {type(input).__name__}")
    if N < 4:
        raise ValueError(f"N must be at least 4 for a bound; got {N}")
    data = SampledData(np.zeros(N), T, input)
    problem = Problem(
        data,
        structure,
        jitter,
        GaussianCriterion(),
        default_frequencies(N, T),
        None if estimate_noise else noise_std,
    )
    _, w, dm, dw = problem.derivatives(x)
    return np.asarray((dm / w) @ dm.T + 0.5 * (dw / w**2) @ dw.T, dtype=float)
