"""The Box-Jenkins criteria (BJ (2b), JBJ (2d)) and their delta-method covariance.

y_k = s(kT + tau_k; theta) + v(kT + tau_k; eta) + w_k with coloured noise v (eq. (1c),
:mod:`jitterid.noise.models`) and a white part w_k of std sigma_w (known, or estimated as
``noise_std``). The mean is Lemma 1's m_k as for OE; the covariance is Sigma_y of (C2)
(:mod:`jitterid.noise.covariance`): the diagonal signal part of Lemma 2 plus the Toeplitz covariance
of the jittered noise. The criteria of :mod:`jitterid.estimation.problem` with this covariance:

=============  ===================================================================  =========
method         criterion                                                            paper
=============  ===================================================================  =========
``bcls``       sum_f |Y(f) - mu_Y(f)|^2 (noise model only for the error bars)       (14)
``wbcls``      (Y - mu)^H R^{-1} (Y - mu), R = E Sigma_y E^H, noise model plugged in (20)
``asml``       (Y - mu)^H R^{-1} (Y - mu) + ln det R                                (22)
``asml-diag``  sum_f |Y - mu|^2 / R(f, f) + ln R(f, f)                              (23)
``gaussian``   (y - m)^T Sigma_y^{-1} (y - m) + ln det Sigma_y, O(N) by (C4)        notes 3
=============  ===================================================================  =========

Parameter order: jitter-family parameters (JBJ), system, noise structure, then
``noise_std`` (sigma_w) when it is estimated. ``bcls`` and ``wbcls`` cannot identify the noise
(no ln det term): their noise parameters are *plug-in* values held fixed (``pinned``), so
they get NaN standard errors.

Error bars: the delta method of :mod:`jitterid.estimation.covariance` with the full covariance, because
the samples are now correlated: Cov(theta) = H^{-1} G Sigma_y G^T H^{-1}, G = d^2 V /
d theta dy^T (central differences of dV/dy), H the Hessian of V (Gauss-Newton 2 J^T J for
the least-squares criteria); G Sigma_y G^T is an FFT Toeplitz product.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from threadpoolctl import threadpool_limits

from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.reference import dtft
from ..moments.sample import SampleMoments, sample_moments
from ..noise.covariance import JitteredAutocovariance, SampleCovariance, jittered_autocovariance
from ..noise.models import NoiseModel, NoiseStructure
from ..simulate import SampledData
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .covariance import _hessian, _steps
from .problem import adjoint_dtft

__all__ = ["BJ_METHODS", "BJProblem", "bj_covariance"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

BJ_METHODS = ("bcls", "wbcls", "asml", "asml-diag", "gaussian")
# Criteria with a ln det term, which identify the noise parameters.
JOINT = ("asml", "asml-diag", "gaussian")
LEAST_SQUARES = ("bcls", "wbcls")
WHITE_FLOOR = 1e-12  # lower bound of an estimated white-noise std


@dataclass(eq=False)
class BJProblem:
    """A BJ/JBJ criterion as a function of one parameter vector, with cached moments.

    ``pinned`` fixes the noise parameters (and an estimated ``noise_std``) at plug-in
    values by closing their bounds (the optimiser and the error bars then leave them out).
    """

    data: SampledData
    structure: ModelStructure
    jitter: JitterLaw | JitterFamily
    noise: NoiseStructure
    method: str
    freqs: FloatArray
    white_std: float | None
    pinned: FloatArray | None = None
    names: tuple[str, ...] = field(init=False)
    bounds: tuple[tuple[float, float], ...] = field(init=False)
    Y: ComplexArray = field(init=False)
    _moments: dict[bytes, SampleMoments] = field(init=False, default_factory=dict)
    _autocov: dict[bytes, JitteredAutocovariance] = field(init=False, default_factory=dict)
    _cov: dict[bytes, SampleCovariance] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        jn: tuple[str, ...] = ()
        jb: tuple[tuple[float, float], ...] = ()
        if isinstance(self.jitter, JitterFamily):
            jn, jb = tuple(self.jitter.param_names), tuple(self.jitter.bounds)
        nn, nb = tuple(self.noise.param_names), tuple(self.noise.bounds)
        if self.white_std is None:
            nn, nb = (*nn, "noise_std"), (*nb, (WHITE_FLOOR, np.inf))
        clash = set(nn) & set(jn + self.structure.param_names)
        if clash:
            raise ValueError(
                f"noise: its parameter names {sorted(clash)} clash with the system's or jitter's; "
                "rename them in the noise structure"
            )
        if self.pinned is not None:
            if self.pinned.size != len(nn):
                raise ValueError(f"pinned must hold {len(nn)} values {nn}; got {self.pinned.size}")
            nb = tuple((float(v), float(v)) for v in self.pinned)
        self.names = jn + self.structure.param_names + nn
        self.bounds = jb + tuple(self.structure.bounds) + nb
        self.Y = dtft(self.data.y, self.data.T, self.freqs)

    @property
    def n_jitter(self) -> int:
        return len(self.jitter.param_names) if isinstance(self.jitter, JitterFamily) else 0

    @property
    def n_system(self) -> int:
        return len(self.structure.param_names)

    @property
    def n_noise(self) -> int:
        return len(self.noise.param_names)

    def _law(self, x: FloatArray) -> JitterLaw:
        if isinstance(self.jitter, JitterFamily):
            return self.jitter.law(x[: self.n_jitter].tolist())
        return self.jitter

    def split(self, x: FloatArray) -> tuple[JitterLaw, TransferFunction, NoiseModel, float]:
        """(jitter law, system, noise model, sigma_w) at parameter vector ``x``."""
        nj, ns, nn = self.n_jitter, self.n_system, self.n_noise
        tf = self.structure.system(x[nj : nj + ns])
        nm = self.noise.model(x[nj + ns : nj + ns + nn])
        white = float(x[-1]) if self.white_std is None else float(self.white_std)
        return self._law(x), tf, nm, white

    def moments(self, x: FloatArray) -> SampleMoments:
        """Lemma 1-2 moments of the signal; depend on the jitter and system parameters only
        (``x`` may stop after them)."""
        nj, ns = self.n_jitter, self.n_system
        key = np.asarray(x[: nj + ns], float).tobytes()
        if key not in self._moments:
            law, tf = self._law(x), self.structure.system(x[nj : nj + ns])
            d = self.data
            self._moments.clear()
            self._moments[key] = sample_moments(tf.response(d.u), law, d.T, d.N)
        return self._moments[key]

    def autocovariance(self, x: FloatArray) -> JitteredAutocovariance:
        """gamma of (C1)/(C3); depends on the jitter and noise parameters only."""
        nj, ns, nn = self.n_jitter, self.n_system, self.n_noise
        key = np.r_[x[:nj], x[nj + ns : nj + ns + nn]].tobytes()
        if key not in self._autocov:
            law, _, nm, _ = self.split(x)
            self._autocov.clear()
            self._autocov[key] = jittered_autocovariance(nm, law, self.data.T)
        return self._autocov[key]

    def covariance(self, x: FloatArray) -> SampleCovariance:
        """Sigma_y of (C2) at ``x``."""
        key = np.asarray(x, float).tobytes()
        if key not in self._cov:
            white = self.split(x)[3]
            self._cov.clear()
            self._cov[key] = SampleCovariance(self.moments(x).var + white**2, self.autocovariance(x))
        return self._cov[key]

    # ------------------------------------------------------------------ criteria
    def _weighted(self, x: FloatArray) -> tuple[ComplexArray, tuple[FloatArray, bool] | None]:
        d = self.data
        r = self.Y - dtft(self.moments(x).mean, d.T, self.freqs)
        if self.method in ("wbcls", "asml"):
            R = self.covariance(x).dft(d.T, self.freqs)
            return r, cho_factor(R, lower=True)
        return r, None

    def residuals(self, x: FloatArray) -> FloatArray:
        """Real residual vector whose squared norm is the ``bcls``/``wbcls`` criterion."""
        r, chol = self._weighted(x)
        if chol is not None:
            r = solve_triangular(chol[0], r, lower=True)
        return np.concatenate([r.real, r.imag])

    def objective(self, x: FloatArray) -> float:
        """The criterion value V of the chosen method (module docstring)."""
        m = self.method
        if m in LEAST_SQUARES:
            return float(np.sum(self.residuals(x) ** 2))
        if m == "gaussian":
            e = self.data.y - self.moments(x).mean
            cov = self.covariance(x)
            return float(e @ cov.solve(e) + cov.logdet)
        r, chol = self._weighted(x)
        if m == "asml":
            assert chol is not None
            z = solve_triangular(chol[0], r, lower=True)
            return float(np.vdot(z, z).real + 2 * np.sum(np.log(np.diag(chol[0]).real)))
        rho = self.covariance(x).dft_diagonal(self.data.T, self.freqs)  # asml-diag (23)
        return float(np.sum(np.abs(r) ** 2 / rho + np.log(rho)))

    def grad_y(self, x: FloatArray) -> FloatArray:
        """dV/dy at the data: the input to the delta-method covariance."""
        d, m = self.data, self.method
        if m == "gaussian":
            return 2 * self.covariance(x).solve(d.y - self.moments(x).mean)
        r, chol = self._weighted(x)
        if chol is not None:
            r = cho_solve(chol, r)
        elif m == "asml-diag":
            r = r / self.covariance(x).dft_diagonal(d.T, self.freqs)
        return 2 * adjoint_dtft(r, d.T, self.freqs, d.N).real


def bj_covariance(problem: BJProblem, x: FloatArray) -> FloatArray:
    """Delta-method covariance H^{-1} G Sigma_y G^T H^{-1} (module docstring); NaN rows and
    columns for parameters on a bound or pinned."""
    # Small complex Cholesky factors run ~1000x slower on a multi-threaded BLAS (as in fit).
    with threadpool_limits(limits=1, user_api="blas"):
        return _bj_covariance(problem, x)


def _bj_covariance(problem: BJProblem, x: FloatArray) -> FloatArray:
    p = x.size
    cov = np.full((p, p), np.nan)
    h, free = _steps(x, problem.bounds)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov

    def embed(z: FloatArray) -> FloatArray:
        out = x.copy()
        out[idx] = z
        return out

    z0, hz = x[idx], h[idx]
    G = np.empty((idx.size, problem.data.N))
    J = np.empty((2 * problem.freqs.size, idx.size))
    with np.errstate(all="ignore"):
        for i in range(idx.size):
            dz = np.zeros(idx.size)
            dz[i] = hz[i]
            up, down = embed(z0 + dz), embed(z0 - dz)
            G[i] = (problem.grad_y(up) - problem.grad_y(down)) / (2 * hz[i])
            if problem.method in LEAST_SQUARES:
                J[:, i] = (problem.residuals(up) - problem.residuals(down)) / (2 * hz[i])
        H = 2 * J.T @ J if problem.method in LEAST_SQUARES else _hessian(lambda z: problem.objective(embed(z)), z0, hz)
    B = G @ problem.covariance(x).matmul(G.T)
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    cov[np.ix_(idx, idx)] = Hinv @ B @ Hinv.T
    return cov
