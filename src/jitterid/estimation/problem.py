"""The estimation criteria of the paper, as functions of one parameter vector.

A :class:`Problem` binds data, a model structure, a jitter law (known) or family (free),
a frequency set and a method, and exposes what an optimiser needs:

=============  ====================================================================  =========
method         criterion                                                             paper
=============  ====================================================================  =========
``ls``         sum_f |Y(f) - S_d(f)|^2, jitter ignored                               (8)
``bcls``       sum_f |Y(f) - mu_Y(f)|^2                                              (14)
``wbcls``      (Y - mu)^H R^{-1} (Y - mu), R = R_Y(theta_w) frozen (see below)      (20)
``asml``       (Y - mu)^H R^{-1} (Y - mu) + ln det R                                 (22)
``asml-diag``  sum_f |Y - mu|^2 / R(f, f) + ln R(f, f)                               (23)
``gaussian``   sum_k (y_k - m_k)^2 / w_k + ln w_k: the exact real Gaussian criterion  notes 3
``ml``         -2 sum_k ln p(y_k | theta): the exact likelihood (:mod:`.likelihood`)   notes 4
=============  ====================================================================  =========

WBCLS weights. Written literally, (20) takes R = R_Y(theta) at the searched theta; with no
ln det R term that criterion is minimised partly by inflating R, and the estimate is biased
(Table 2, 32 realizations: k0 7.12, pr -1.29, pi 2.26 against 6.25, -1.5, 2; 6-14 standard
errors). ``wbcls`` therefore freezes R at ``weights_at`` (the feasible generalised least
squares of Kailath et al., which the paper cites for (20)); :func:`jitterid.fit` sets it to
the BCLS estimate and re-freezes once at the first WBCLS estimate. ``weights_at=None``
keeps the literal theta-dependent form, for comparison.

The parameter vector is ordered: jitter-family parameters (if the law is free), then the
system's parameters, then ``noise_std`` when it is estimated (Table 3's order: n, a, k0,
pr, pi). Every criterion V(theta, y) also provides dV/dy, from which
:func:`jitterid.estimation.covariance.covariance` builds the delta-method covariance of the estimate, and its
parameter derivatives: :meth:`Problem.jacobian` (residuals of ls, bcls, wbcls) and
:meth:`Problem.objective_gradient` (V, dV/dtheta and the expected Hessian of gaussian, asml,
asml-diag), from one O(N) pass over the moments and their derivatives
(:mod:`jitterid.estimation.jacobians`, :mod:`jitterid.moments.modal`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from ..data import SampledData
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..moments.modal import SegmentPlan
from ..moments.reference import dtft
from ..moments.sample import SampleMoments, difference_grid
from ..params import ParamLayout
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from . import jacobians as _jacobians
from .estimators import as_estimator, method_names
from .likelihood import ExactLikelihood

__all__ = ["METHODS", "Problem", "default_frequencies"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_Derivatives = tuple[SampleMoments, FloatArray, FloatArray, FloatArray]

METHODS = method_names()  # the registered estimators (jitterid.estimation.estimators)


def default_frequencies(N: int, T: float) -> FloatArray:
    """The paper's frequency set (24): f_k = k / (N T), k = 0..floor(N/2) - 1."""
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
class Problem:
    """Everything a criterion needs, with the moments of the last parameter vector cached."""

    data: SampledData
    structure: ModelStructure
    jitter: JitterLaw | JitterFamily
    method: str
    freqs: FloatArray
    noise_std: float | None
    weights_at: FloatArray | None = None  # wbcls: theta at which R is frozen (module doc)
    layout: ParamLayout = field(init=False)
    Y: ComplexArray = field(init=False)
    likelihood: ExactLikelihood | None = field(init=False, default=None)
    _cache: dict[bytes, SampleMoments] = field(init=False, default_factory=dict)
    # last derivatives, frequency-difference grid (see :mod:`jitterid.estimation.jacobians`)
    _dcache: tuple[bytes, _Derivatives] | None = field(init=False, default=None)
    _grid: tuple[FloatArray, NDArray[np.intp]] | None = field(init=False, default=None)
    _split: tuple[bytes, tuple[JitterLaw, TransferFunction, float]] | None = field(
        init=False, default=None
    )
    _plan_memo: tuple[tuple[bytes, float], SegmentPlan] | None = field(init=False, default=None)
    _frozen: tuple[FloatArray, bool] | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.layout = ParamLayout.build(
            self.jitter, self.structure, noise_std=self.estimates_noise
        )
        self.Y = dtft(self.data.y, self.data.T, self.freqs)
        if self.method == "ml":
            d = self.data
            noise = None if self.estimates_noise else self.noise_std
            self.likelihood = ExactLikelihood(self.structure, self.jitter, d.u, d.T, d.N, noise)

    @property
    def names(self) -> tuple[str, ...]:
        return self.layout.names

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return self.layout.bounds

    @property
    def estimates_noise(self) -> bool:
        return as_estimator(self.method).estimates_noise and self.noise_std is None

    @property
    def uses_noise(self) -> bool:
        """Whether the criterion's variances include the white noise (known or estimated)."""
        return self.estimates_noise or self.noise_std is not None

    @property
    def n_jitter(self) -> int:
        return len(self.jitter.param_names) if isinstance(self.jitter, JitterFamily) else 0

    def split(self, x: FloatArray) -> tuple[JitterLaw, TransferFunction, float]:
        """(jitter law, system, noise std) at parameter vector ``x``.

        Memoised for the last ``x``: the criterion, its derivatives and the variances all ask
        for the same system, whose modal form and switch-time states are then built once.
        """
        key = np.asarray(x, float).tobytes()
        if self._split is not None and self._split[0] == key:
            return self._split[1]
        out = self._split_new(np.asarray(x, float))
        self._split = (key, out)
        return out

    def _split_new(self, x: FloatArray) -> tuple[JitterLaw, TransferFunction, float]:
        lay = self.layout
        if self.method == "ls":
            law: JitterLaw = NoJitter()
        elif isinstance(self.jitter, JitterFamily):
            law = self.jitter.law(lay.block(x, "jitter").tolist())
        else:
            law = self.jitter
        tf = self.structure.system(lay.block(x, "system"))
        noise = float(x[-1]) if self.estimates_noise else float(self.noise_std or 0.0)
        return law, tf, noise

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
        self._plan_memo = None

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

    # ------------------------------------------------------------------ criteria
    def _weighted(self, x: FloatArray) -> tuple[ComplexArray, tuple[FloatArray, bool] | None]:
        """Residual Y - mu and, for the full-covariance methods, the Cholesky factor of R."""
        d = self.data
        r = self.Y - dtft(self.moments(x).mean, d.T, self.freqs)
        if self.frozen_weights:
            if self._frozen is None:
                self._frozen = self._cholesky(np.asarray(self.weights_at, float))
            return r, self._frozen
        if self.method in ("wbcls", "asml"):
            return r, self._cholesky(x)
        return r, None

    @property
    def frozen_weights(self) -> bool:
        """True for ``wbcls`` with R frozen at ``weights_at`` (module doc)."""
        return self.method == "wbcls" and self.weights_at is not None

    def _cholesky(self, x: FloatArray) -> tuple[FloatArray, bool]:
        uniq, inverse = self.difference_grid()
        F = self.freqs.size
        R = dtft(self.variances(x), self.data.T, uniq)[inverse].reshape(F, F)  # (17)-(19)
        return cho_factor(R, lower=True)

    def residuals(self, x: FloatArray) -> FloatArray:
        """Real residual vector whose squared norm is the criterion (ls, bcls, wbcls)."""
        r, chol = self._weighted(x)
        if chol is not None:
            r = solve_triangular(chol[0], r, lower=True)
        return np.concatenate([r.real, r.imag])

    def jacobian(self, x: FloatArray) -> FloatArray:
        """d :meth:`residuals` / dx, shape (2F, P), for ``ls``, ``bcls``, ``wbcls``."""
        return _jacobians.residual_jacobian(self, np.asarray(x, float))

    def objective_gradient(self, x: FloatArray) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian of V) for ``gaussian``, ``asml``, ``asml-diag``."""
        return _jacobians.objective_gradient(self, np.asarray(x, float))

    def objective(self, x: FloatArray) -> float:
        """The criterion value V(theta) of the chosen method."""
        m = self.method
        if m in ("ls", "bcls", "wbcls"):
            return float(np.sum(self.residuals(x) ** 2))
        if m == "gaussian":
            w = self.variances(x)
            e = self.data.y - self.moments(x).mean
            return float(np.sum(e * e / w + np.log(w)))
        if m == "ml":
            assert self.likelihood is not None
            return -2 * self.likelihood.loglik(x, self.data.y)
        r, chol = self._weighted(x)
        if m == "asml":
            assert chol is not None
            z = solve_triangular(chol[0], r, lower=True)
            return float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(chol[0]).real)))
        # asml-diag (23): R(f, f) = sum_k w_k is the same at every frequency (notes 2).
        rho = float(np.sum(self.variances(x)))
        return float(np.sum(np.abs(r) ** 2) / rho + r.size * np.log(rho))

    def grad_y(self, x: FloatArray) -> FloatArray:
        """dV/dy at the data: the input to the delta-method covariance."""
        d, m = self.data, self.method
        if m == "gaussian":
            return 2 * (d.y - self.moments(x).mean) / self.variances(x)
        if m == "ml":
            assert self.likelihood is not None
            return -2 * self.likelihood.dlogpdf_dy(x, d.y)
        r, chol = self._weighted(x)
        if chol is not None:
            r = cho_solve(chol, r)
        elif m == "asml-diag":
            r = r / float(np.sum(self.variances(x)))
        return 2 * adjoint_dtft(r, d.T, self.freqs, d.N).real
