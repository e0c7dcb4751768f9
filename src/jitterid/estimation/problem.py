"""The white-noise estimation problem: data, a model structure, a jitter law or family, a
frequency set and an estimator, as functions of one parameter vector.

A :class:`Problem` gives each criterion (one module each in :mod:`jitterid.estimation
.estimators`) what it reads: the sample moments m_k, Var_k and their parameter derivatives
from one O(N) pass (:mod:`jitterid.estimation.jacobians`, :mod:`jitterid.moments.modal`),
the DTFT residual Y - mu_Y (Lemma 1 in the time domain), the frequency covariance R_Y
(17)-(19) and its Cholesky factor where the criterion needs it (frozen at ``weights_at``
for WBCLS, see :mod:`.estimators.wbcls`), and the adjoint DTFT for dV/dy. Its
:meth:`Problem.objective`, :meth:`~Problem.residuals`, :meth:`~Problem.jacobian`,
:meth:`~Problem.objective_gradient` and :meth:`~Problem.grad_y` delegate to the estimator.

The parameter vector follows :class:`jitterid.params.ParamLayout`: jitter-family
parameters (if the law is free), then the system's, then ``noise_std`` when it is estimated
(Table 3's order: n, a, k0, pr, pi).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor

from .._memory import trim
from .._state import CachesAreNotState, cache_field
from ..data import SampledData
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..moments.modal import SegmentPlan, clear_plans
from ..moments.reference import dtft
from ..moments.sample import SampleMoments, difference_grid, moment_pass
from ..params import ParamLayout
from ..systems.model import Model, Signal
from . import jacobians as _jacobians
from .estimators import Estimator, as_estimator
from .likelihood import ExactLikelihood
from .resources import check_mode_rate
from .search import KINKED_TOL, LIKELIHOOD_FLOOR, SearchOptions

__all__ = ["Problem", "default_frequencies", "free_moment_plans"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_Derivatives = tuple[SampleMoments, FloatArray, FloatArray, FloatArray]


#: records from this many samples free the moment plans before the likelihood's search
FREE_PLANS_FROM = 100_000


def free_moment_plans(N: int) -> None:
    """On a record of at least ``FREE_PLANS_FROM`` samples, drop the moments' segment plans
    (~640 MB at N = 1e6) and return the freed pages to the system; what needs the moments
    later (the checks' model mean) rebuilds them."""
    if N >= FREE_PLANS_FROM:
        clear_plans()
        trim()


def default_frequencies(N: int, T: float) -> FloatArray:
    """The paper's frequency set (24): f_k = k / (N T), k = 0..floor(N/2) - 1.

    Parameters
    ----------
    N : int
        Number of samples.
    T : float
        Nominal sampling interval (s).

    Returns
    -------
    ndarray, shape (N // 2,)
        Frequencies in Hz.

    Examples
    --------
    >>> import jitterid as jid
    >>> jid.default_frequencies(8, 0.5).tolist()
    [0.0, 0.25, 0.5, 0.75]
    """
    return np.arange(N // 2) / (N * T)


def adjoint_dtft(z: ComplexArray, T: float, f: FloatArray, N: int) -> ComplexArray:
    """F^H z = sum_n z_n exp(+i 2 pi f_n k T) for k = 0..N-1 (the adjoint of (3)).

    On the DFT grid n / (N T) (e.g. the set (24)) this is N times an inverse FFT of z placed
    in its bins, O(N log N); elsewhere a chunked O(N F) sum.
    """
    bins = np.asarray(f, float) * (N * T)
    on_grid = np.round(bins)
    if f.size and np.all(np.abs(bins - on_grid) < 1e-9):
        spread = np.zeros(N, complex)
        np.add.at(spread, np.mod(on_grid.astype(np.int64), N), z)
        return N * np.fft.ifft(spread)
    out = np.empty(N, complex)
    step = max(1, 4_000_000 // max(1, f.size))
    for k0 in range(0, N, step):
        k = np.arange(k0, min(N, k0 + step))
        out[k0 : k0 + k.size] = np.exp(2j * np.pi * np.outer(k * T, f)) @ z
    return out


@dataclass(eq=False)
class Problem(CachesAreNotState):
    """Everything a criterion needs, with the moments of the last parameter vector cached."""

    data: SampledData
    structure: Model
    jitter: JitterLaw | JitterFamily
    estimator: Estimator  # (or its registered name, turned into the object)
    freqs: FloatArray
    noise_std: float | None
    weights_at: FloatArray | None = None  # wbcls: theta at which R is frozen (module doc)
    # whether moment_derivatives computes Var_k and dVar: None = as the estimator needs
    # (LS and BCLS skip them); the Box-Jenkins criteria, which read them, set True
    with_variances: bool | None = None
    layout: ParamLayout = field(init=False)
    Y: ComplexArray = field(init=False)
    likelihood: ExactLikelihood | None = field(init=False, default=None)
    _cache: dict[bytes, SampleMoments] = cache_field(default_factory=dict)  # noqa: RUF009
    # last derivatives, frequency-difference grid (see :mod:`jitterid.estimation.jacobians`)
    _dcache: tuple[bytes, _Derivatives] | None = cache_field()
    _grid: tuple[FloatArray, NDArray[np.intp]] | None = cache_field()
    _split: tuple[bytes, tuple[JitterLaw, Signal, float]] | None = cache_field()
    # the moments' last node plan with its key (jacobians._plan)
    plan_memo: tuple[tuple[bytes, float], SegmentPlan] | None = cache_field()
    _frozen: tuple[FloatArray, bool] | None = cache_field()
    # the piece of a kinked parameter being searched (restrict), None: the layout's bounds
    _box: tuple[tuple[float, float], ...] | None = cache_field()

    def __post_init__(self) -> None:
        self.estimator = as_estimator(self.estimator)
        self.layout = ParamLayout.build(
            self.jitter,
            self.structure,
            noise_std=self.estimates_noise,
            noise_floor=self.data.resolution,
        )
        self.Y = dtft(self.data.y, self.data.T, self.freqs)
        if self.estimator.exact_likelihood:
            d = self.data
            noise = None if self.estimates_noise else self.noise_std
            self.likelihood = ExactLikelihood(
                self.structure, self.jitter, d.u, d.T, d.N, noise, noise_floor=d.resolution
            )

    @property
    def names(self) -> tuple[str, ...]:
        return self.layout.names

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """The bounds searched: the layout's, or the piece set by :meth:`restrict`."""
        return self.layout.bounds if self._box is None else self._box

    def restrict(self, bounds: tuple[tuple[float, float], ...] | None) -> None:
        """Search within ``bounds`` (one smooth piece of a kinked parameter,
        :func:`jitterid.estimation.search.piecewise`), or the layout's own with None.

        The one-sided derivatives at a piece's end look into the piece, so the caches of
        the last point are dropped; the likelihood, if any, is restricted with it.

        Parameters
        ----------
        bounds : tuple of (float, float) or None
            One closed interval per parameter, inside the layout's; None lifts it.
        """
        self._box = None if bounds is None else tuple(bounds)
        self.release()
        if self.likelihood is not None:
            self.likelihood.restrict(bounds)

    @contextmanager
    def pinned(self, x: FloatArray, free: NDArray[np.bool_]) -> Iterator[None]:
        """Within the block, every parameter but the ``free`` ones pinned at its value in
        ``x`` (its box a point, :meth:`restrict`), the box before restored after: the moment
        derivatives (:func:`jitterid.estimation.jacobians.moment_derivatives`) skip a pinned
        jitter shape, whose differences cost two moment passes with new nodes each, where a
        search or a covariance holds it and never reads them.

        Parameters
        ----------
        x : ndarray
            Parameter vector, in :attr:`names` order.
        free : ndarray of bool
            The parameters left free.
        """
        if np.all(free):
            yield
            return
        before = self._box
        box = zip(np.asarray(x, float).tolist(), free.tolist(), self.bounds, strict=True)
        self.restrict(tuple((v, v) if not f else b for v, f, b in box))
        try:
            yield
        finally:
            self.restrict(before)

    @property
    def method(self) -> str:
        """The estimator's registered name."""
        return self.estimator.name

    @property
    def estimates_noise(self) -> bool:
        return self.estimator.estimates_noise and self.noise_std is None

    @property
    def uses_noise(self) -> bool:
        """Whether the criterion's variances include the white noise (known or estimated)."""
        return self.estimates_noise or self.noise_std is not None

    @property
    def n_jitter(self) -> int:
        return len(self.layout.jitter)

    def split(self, x: FloatArray) -> tuple[JitterLaw, Signal, float]:
        """(jitter law, signal s(t; theta), noise std) at parameter vector ``x``.

        The signal is the model's (:mod:`jitterid.systems.model`): for an LTI structure the
        response of its system to the data's input. Memoised for the last ``x``: the
        criterion, its derivatives and the variances all ask for the same signal, whose
        modal form and switch-time states are then built once.
        """
        key = np.asarray(x, float).tobytes()
        if self._split is not None and self._split[0] == key:
            return self._split[1]
        out = self._split_new(np.asarray(x, float))
        self._split = (key, out)
        return out

    def jitter_law(self, x: FloatArray) -> JitterLaw:
        """The jitter law at ``x`` as the model states it (before a delay moves it: the
        law of :meth:`split` is the equivalent one)."""
        if self.estimator.ignores_jitter:
            return NoJitter()
        if isinstance(self.jitter, JitterFamily):
            return self.jitter.law(self.layout.block(x, "jitter").tolist())
        return self.jitter

    def _split_new(self, x: FloatArray) -> tuple[JitterLaw, Signal, float]:
        lay = self.layout
        law = self.jitter_law(x)
        sig = self.structure.signal(lay.block(x, "system"), self.data.u)
        law, sig = sig.jitter_equivalent(law)  # a delay moves into the jitter (Delayed)
        if self.structure.param_names:  # a searched model: no modes the samples cannot see
            check_mode_rate(sig, self.data.T)
        noise = float(x[-1]) if self.estimates_noise else float(self.noise_std or 0.0)
        return law, sig, noise

    def moments(self, x: FloatArray) -> SampleMoments:
        """m_k and Var_k at ``x`` (Lemmas 1-2, notes 1-2), cached for the last ``x``."""
        key = np.asarray(x, float).tobytes()
        if key not in self._cache:
            mom = _jacobians.moments(self, np.asarray(x, float))
            self._cache.clear()
            self._cache[key] = mom
        return self._cache[key]

    def release(self) -> None:
        """Drop the cached moments, derivatives and system (O(N) arrays each): a fitted
        result keeps its problem for the lazy covariance, and should not keep those too."""
        self._cache.clear()
        self._dcache = None
        self._split = None
        self.plan_memo = None

    def recall(self, key: bytes) -> _Derivatives | None:
        """The derivatives remembered for the point with bytes ``key`` (:meth:`derivatives`
        of the last point), or None."""
        if self._dcache is not None and self._dcache[0] == key:
            return self._dcache[1]
        return None

    def remember(self, key: bytes, out: _Derivatives | None) -> None:
        """Keep ``out`` (the derivatives at the point with bytes ``key``) and its moments as
        the last point's; None forgets the last point's derivatives."""
        if out is None:
            self._dcache = None
            return
        self._dcache = (key, out)
        self._cache.clear()
        self._cache[key] = out[0]

    def difference_grid(self) -> tuple[FloatArray, NDArray[np.intp]]:
        """Distinct f - psi over the frequency set, and the index of each pair (for R_Y)."""
        if self._grid is None:
            self._grid = difference_grid(self.freqs, self.freqs, self.data.T, self.data.N)
        return self._grid

    def variances(self, x: FloatArray) -> FloatArray:
        """w_k = Var[s(kT + tau)] + sigma_v^2, floored so that no weight is infinite."""
        _, _, noise = self.split(x)
        w = self.moments(x).var + noise**2
        return np.maximum(w, 1e-300 + 1e-12 * float(np.max(w, initial=0.0)))

    def central_moments(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """E[(y_k - m_k)^3] and E[(y_k - m_k)^4] at ``x``, with Gaussian white noise of the
        variance in :meth:`variances` beyond the signal's: for the covariance of the criteria
        that are quadratic in y (:mod:`jitterid.estimation.covariance`). One pass at the
        jitter nodes (:func:`jitterid.moments.sample.moment_pass`)."""
        law, sig, _ = self.split(np.asarray(x, float))
        d = self.data
        mp = moment_pass(sig, law, d.T, d.N, higher=True)
        assert mp.var is not None
        assert mp.mu3 is not None
        assert mp.mu4 is not None
        noise_var = np.maximum(self.variances(x) - mp.var, 0.0)
        return mp.mu3, mp.mu4 + 6 * mp.var * noise_var + 3 * noise_var**2

    # ------------------------------------------------------------------ for the criteria
    @property
    def needs_variances(self) -> bool:
        """Whether the derivative pass computes Var_k and dVar (see ``with_variances``)."""
        if self.with_variances is not None:
            return self.with_variances
        return self.estimator.uses_variances

    def weighted(self, x: FloatArray) -> tuple[ComplexArray, tuple[FloatArray, bool] | None]:
        """Residual Y - mu and, for the full-covariance criteria, the Cholesky factor of R."""
        d = self.data
        r = self.Y - dtft(self.moments(x).mean, d.T, self.freqs)
        if self.frozen_weights:
            if self._frozen is None:
                self._frozen = self._cholesky(np.asarray(self.weights_at, float))
            return r, self._frozen
        if self.estimator.full_covariance:
            return r, self._cholesky(x)
        return r, None

    @property
    def frozen_weights(self) -> bool:
        """True for ``wbcls`` with R frozen at ``weights_at`` (:mod:`.estimators.wbcls`)."""
        return self.estimator.full_covariance and self.weights_at is not None

    def _cholesky(self, x: FloatArray) -> tuple[FloatArray, bool]:
        uniq, inverse = self.difference_grid()
        F = self.freqs.size
        R = dtft(self.variances(x), self.data.T, uniq)[inverse].reshape(F, F)  # (17)-(19)
        return cho_factor(R, lower=True)

    def derivatives(self, x: FloatArray) -> _Derivatives:
        """(moments, w, dm/dx, dw/dx) at ``x`` from one O(N) pass (:mod:`.jacobians`)."""
        return _jacobians.moment_derivatives(self, np.asarray(x, float))

    def dmu(self, dm: FloatArray) -> ComplexArray:
        """d mu_Y(f) / dx over the frequency set, (P, F): the DTFT of dm_k (Lemma 1)."""
        return dtft(dm, self.data.T, self.freqs)

    def dR(self, dw: FloatArray) -> ComplexArray:
        """dR_i(f, psi) = sum_k dw_ik e^{-i 2 pi (f - psi) kT} over the frequency set, (P, F, F)."""
        uniq, inverse = self.difference_grid()
        F = self.freqs.size
        return dtft(dw, self.data.T, uniq)[:, inverse].reshape(dw.shape[0], F, F)

    def adjoint(self, z: ComplexArray) -> FloatArray:
        """Re F^H z: the time-domain image of a frequency-domain weight (for dV/dy)."""
        return adjoint_dtft(z, self.data.T, self.freqs, self.data.N).real

    # ------------------------------------------------------------------ the criterion
    def residuals(self, x: FloatArray) -> FloatArray:
        """Real residual vector whose squared norm is the criterion (least-squares methods)."""
        return self.estimator.residuals(self, np.asarray(x, float))

    def jacobian(self, x: FloatArray) -> FloatArray:
        """d :meth:`residuals` / dx, analytic (least-squares methods)."""
        return self.estimator.jacobian(self, np.asarray(x, float))

    def objective_gradient(
        self, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian of V) (Newton-searched methods); ``free`` (the
        parameters searched) is part of the search protocol and not used here."""
        return self.estimator.objective_gradient(self, np.asarray(x, float))

    # ------------------------------------------------------------------ for the search
    def search_residuals(self, x: FloatArray) -> FloatArray:
        """:meth:`residuals`, for a least-squares search: the moments' derivatives come out
        of the same pass over the nodes for about twice its cost, and least_squares asks for
        the Jacobian at every point it accepts, so both are computed here (one pass saved
        per iteration)."""
        _jacobians.moment_derivatives(self, np.asarray(x, float))
        return self.residuals(x)

    @property
    def has_jacobian(self) -> bool:
        """The residuals' Jacobian is analytic (:mod:`.jacobians`)."""
        return True

    def search_options(self, tol: float | None = None) -> SearchOptions:
        """The Newton adapter's options (:class:`~jitterid.estimation.search.SearchOptions`):
        the parameters themselves, Newton decrement 1e-8 (or ``tol``; with a kinked jitter
        shape :data:`~jitterid.estimation.search.KINKED_TOL`), and exhausted damping below
        :data:`~jitterid.estimation.search.LIKELIHOOD_FLOOR` taken as the criterion's
        rounding floor (the Newton-searched criteria are in units of a log-likelihood)."""
        base = SearchOptions(rounding_floor=LIKELIHOOD_FLOOR)
        if tol is None and self.layout.kinked():
            tol = KINKED_TOL
        return base if tol is None else base._replace(tol=tol)

    def objective(self, x: FloatArray) -> float:
        """The criterion value V(theta) of the chosen method."""
        return self.estimator.objective(self, np.asarray(x, float))

    def criterion_at(self, x: FloatArray) -> float:
        """:meth:`objective` at a point away from the last evaluations (a comparison with
        other starts, the estimate after them): the exact likelihood's rule is made to serve
        it first (:meth:`~jitterid.estimation.likelihood.ExactLikelihood.serve`)."""
        if self.likelihood is not None:
            self.likelihood.serve(x)
        return self.objective(x)

    def grad_y(self, x: FloatArray) -> FloatArray:
        """dV/dy at the data: the input to the delta-method covariance."""
        return np.asarray(self.estimator.grad_y(self, np.asarray(x, float)), dtype=float)
