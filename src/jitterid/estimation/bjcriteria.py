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
``wbcls``      (Y - mu)^H R^{-1} (Y - mu), R = E Sigma_y E^H frozen (below)           (20)
``asml``       (Y - mu)^H R^{-1} (Y - mu) + ln det R                                (22)
``asml-diag``  sum_f |Y - mu|^2 / R(f, f) + ln R(f, f)                              (23)
``gaussian``   (y - m)^T Sigma_y^{-1} (y - m) + ln det Sigma_y, O(N) by (C4)        notes 3
=============  ===================================================================  =========

Parameter order: jitter-family parameters (JBJ), system, noise structure, then
``noise_std`` (sigma_w) when it is estimated. ``bcls`` and ``wbcls`` cannot identify the noise
(no ln det term): their noise parameters are *plug-in* values held fixed (``pinned``), so
they get NaN standard errors.

WBCLS weights: as for OE (:mod:`jitterid.estimation.problem`), R is frozen at ``weights_at``
(the BCLS/GLS start with the plug-in noise model, then re-frozen once at the first WBCLS
estimate, :func:`jitterid.estimation.boxjenkins.fit_bj`): the literal (20) with R(theta)
inside the search, having no ln det R, is minimised partly by inflating R and is biased.
``weights_at=None`` keeps the literal form, for comparison.

Error bars: the delta method of :mod:`jitterid.estimation.covariance` with the full covariance, because
the samples are now correlated: Cov(theta) = H^{-1} G Sigma_y G^T H^{-1}, G = d^2 V /
d theta dy^T (central differences of dV/dy), H the Hessian of V (central differences of the
analytic gradient; Gauss-Newton 2 J^T J for the least-squares criteria); G Sigma_y G^T is an
FFT Toeplitz product. Every difference quotient goes through
:func:`jitterid.finite_diff.derivative`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from threadpoolctl import threadpool_limits

from .. import finite_diff
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.reference import dtft
from ..moments.sample import SampleMoments
from ..noise.covariance import (
    JitteredAutocovariance,
    SampleCovariance,
    autocovariance_derivatives,
    jittered_autocovariance,
    toeplitz_dft,
    toeplitz_dft_diagonal,
)
from ..noise.models import NoiseModel, NoiseStructure
from ..simulate import SampledData
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .covariance import _steps
from .jacobians import moment_derivatives
from .problem import Problem, adjoint_dtft

__all__ = ["BJ_METHODS", "BJProblem", "bj_covariance"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

BJ_METHODS = ("bcls", "wbcls", "asml", "asml-diag", "gaussian")
# Criteria with a ln det term, which identify the noise parameters.
JOINT = ("asml", "asml-diag", "gaussian")
LEAST_SQUARES = ("bcls", "wbcls")
WHITE_FLOOR = 1e-12  # lower bound of an estimated white-noise std
PROBES = 16  # probe vectors of the trace term of the Fisher matrix (``objective_gradient``)


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
    weights_at: FloatArray | None = None  # wbcls: the point at which R is frozen
    names: tuple[str, ...] = field(init=False)
    bounds: tuple[tuple[float, float], ...] = field(init=False)
    Y: ComplexArray = field(init=False)
    _moments: dict[bytes, SampleMoments] = field(init=False, default_factory=dict)
    _autocov: dict[bytes, JitteredAutocovariance] = field(init=False, default_factory=dict)
    _cov: dict[bytes, SampleCovariance] = field(init=False, default_factory=dict)
    # the OE problem whose moments (and their derivatives, jacobians.moment_derivatives) are
    # the system/jitter block; the autocovariance's parameter derivatives; probe vectors
    _oe: Problem = field(init=False)
    _dgamma: tuple[bytes, dict[int, tuple[FloatArray, FloatArray]]] | None = field(init=False, default=None)
    _probes: FloatArray | None = field(init=False, default=None)
    _nm: tuple[bytes, NoiseModel] | None = field(init=False, default=None)
    _frozen: tuple[FloatArray, bool] | None = field(init=False, default=None)

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
        self._oe = Problem(
            self.data, self.structure, self.jitter, "bcls", self.freqs, None, with_variances=True
        )

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
        nj, ns = self.n_jitter, self.n_system
        tf = self.structure.system(x[nj : nj + ns])
        return self._law(x), tf, self._noise_model(x), self._white(x)

    def _white(self, x: FloatArray) -> float:
        return float(x[-1]) if self.white_std is None else float(self.white_std)

    def _noise_model(self, x: FloatArray) -> NoiseModel:
        """H at ``x``, kept for the last noise parameters (a model builds its modal form)."""
        nj, ns, nn = self.n_jitter, self.n_system, self.n_noise
        eta = np.asarray(x[nj + ns : nj + ns + nn], float)
        if self._nm is None or self._nm[0] != eta.tobytes():
            self._nm = (eta.tobytes(), self.noise.model(eta))
        return self._nm[1]

    def moments(self, x: FloatArray) -> SampleMoments:
        """Lemma 1-2 moments of the signal; depend on the jitter and system parameters only
        (``x`` may stop after them). The OE problem's O(N) path (modal for piecewise-constant
        inputs), cached for the last point."""
        nj, ns = self.n_jitter, self.n_system
        return self._oe.moments(np.asarray(x[: nj + ns], float))

    def autocovariance(self, x: FloatArray) -> JitteredAutocovariance:
        """gamma of (C1)/(C3); depends on the jitter and noise parameters only."""
        nj, ns, nn = self.n_jitter, self.n_system, self.n_noise
        key = np.r_[x[:nj], x[nj + ns : nj + ns + nn]].tobytes()
        if key not in self._autocov:
            self._autocov.clear()
            self._autocov[key] = jittered_autocovariance(self._noise_model(x), self._law(x), self.data.T)
        return self._autocov[key]

    def covariance(self, x: FloatArray) -> SampleCovariance:
        """Sigma_y of (C2) at ``x``."""
        key = np.asarray(x, float).tobytes()
        if key not in self._cov:
            white = self._white(x)
            self._cov.clear()
            self._cov[key] = SampleCovariance(self.moments(x).var + white**2, self.autocovariance(x))
        return self._cov[key]

    def autocovariance_derivatives(self, x: FloatArray) -> dict[int, tuple[FloatArray, FloatArray]]:
        """d gamma(0..N-1) and d(ar) for each jitter and noise parameter (index into ``x``).

        Noise parameters: in closed form (:func:`jitterid.noise.covariance.
        autocovariance_derivatives` with :meth:`RationalNoise.mode_derivatives`) when the
        jitter spans at most T. Otherwise, and for jitter-family parameters, by
        :func:`jitterid.finite_diff.derivative` of (C1)-(C3): the near lags are
        quadratures over the law, with no closed-form derivative."""
        nj, ns, nn = self.n_jitter, self.n_system, self.n_noise
        key = np.r_[x[:nj], x[nj + ns : nj + ns + nn]].tobytes()
        if self._dgamma is not None and self._dgamma[0] == key:
            return self._dgamma[1]
        N, T = self.data.N, self.data.T
        jb = tuple(self.jitter.bounds) if isinstance(self.jitter, JitterFamily) else ()
        natural = jb + tuple(self.structure.bounds) + tuple(self.noise.bounds)
        g0 = self.autocovariance(x)
        base = np.r_[g0.sequence(N), g0.ar]

        def flat(xx: FloatArray) -> FloatArray:
            g = jittered_autocovariance(self.noise.model(xx[nj + ns : nj + ns + nn]), self._law(xx), T)
            return np.r_[g.sequence(N), g.ar]

        out: dict[int, tuple[FloatArray, FloatArray]] = {}
        fd = [*range(nj), *range(nj + ns, nj + ns + nn)]
        modes = getattr(self.noise, "mode_derivatives", None)
        if nn and modes is not None:  # closed form in the noise parameters when M0 = 1
            eta = x[nj + ns : nj + ns + nn]
            nm = self._noise_model(x)
            dc, dp = modes(eta, nm)
            exact = autocovariance_derivatives(nm, self._law(x), T, dc, dp, N)
            if exact is not None:
                for k in range(nn):
                    out[nj + ns + k] = (exact[0][k], exact[1][k])
                fd = fd[:nj]
        for i in fd:
            dv = finite_diff.derivative(flat, np.asarray(x, float), i, natural[i], f0=base)
            out[i] = (dv[:N], dv[N:])
        self._dgamma = (key, out)
        return out

    def _derivatives(self, x: FloatArray) -> tuple[SampleMoments, FloatArray, FloatArray, dict[int, tuple[FloatArray, FloatArray]]]:
        """(moments, dm, dd, {p: (dgamma, dar)}): the derivatives of m and of Sigma_y =
        diag(d) + Toeplitz(gamma) (AR coefficients ar) for every parameter, shapes (P, N).

        System and jitter block from the OE pass (:func:`jitterid.estimation.jacobians.
        moment_derivatives`); sigma_w enters d as 2 sigma_w; the noise (and jitter)
        parameters enter gamma and ar (:meth:`autocovariance_derivatives`)."""
        x = np.asarray(x, float)
        nj, ns = self.n_jitter, self.n_system
        N, P = self.data.N, x.size
        dm, dd = np.zeros((P, N)), np.zeros((P, N))
        if nj + ns:
            mom, _, dmi, dwi = moment_derivatives(self._oe, x[: nj + ns])
            dm[: nj + ns], dd[: nj + ns] = dmi, dwi
        else:
            mom = self.moments(x)
        if self.white_std is None:
            dd[-1] = 2 * x[-1]
        dg = self.autocovariance_derivatives(x) if nj + self.n_noise else {}
        return mom, dm, dd, dg

    def objective_gradient(
        self, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian M of V) for ``gaussian``, ``asml``, ``asml-diag``: the
        input of :func:`jitterid.estimation.search.newton_search`. O(N) for ``gaussian``
        (:meth:`_gaussian`), O(F^3) for ``asml`` as the criterion itself. ``free``: indices
        of the parameters searched; ``gaussian`` then forms only their rows and columns
        (zeros elsewhere), e.g. the noise stage with the system fixed."""
        if self.method == "gaussian":
            return self._gaussian(x, free)
        if self.method in ("asml", "asml-diag"):
            return self._frequency(x)
        raise ValueError(f"objective_gradient: method {self.method!r} is a least-squares criterion")

    def _gaussian(self, x: FloatArray, free: NDArray[np.intp] | None = None) -> tuple[float, FloatArray, FloatArray]:
        """V = e^T S^{-1} e + ln det S, S = Sigma_y, e = y - m, through the banded B = L S L^T
        of (C4): with u = L e, z = B^{-1} u,

            V = u^T z + ln det B,
            dV = 2 (dL e - L dm)^T z - z^T dB z + tr(B^{-1} dB),

        dB banded (:meth:`SampleCovariance.derivative_band`) and tr(B^{-1} dB) from B^{-1}
        on the band only (:attr:`SampleCovariance.band_inverse`): O(N w^2) in all.

        Expected Hessian (2 x Fisher information) M = 2 dm^T S^{-1} dm + tr(S^{-1} dS_i
        S^{-1} dS_j). The first term is exact (whitened columns C^{-1} L dm). The trace term
        has no banded form (it needs all of S^{-1}); it is estimated with ``PROBES`` fixed
        probe vectors zeta = L^T C^{-T} xi, xi ~ N(0, I) (so E zeta zeta^T = S^{-1}):
        tr(S^{-1} dS_i S^{-1} dS_j) = E[(dS_i zeta)^T S^{-1} (dS_j zeta)], a Gram matrix of
        whitened vectors, hence positive semi-definite, and smooth in x (the same xi at
        every point). M only steers the Newton steps; the gradient and value are exact.
        """
        x = np.asarray(x, float)
        mom, dm, dd, dg = self._derivatives(x)
        cov = self.covariance(x)
        N, P_all = self.data.N, x.size
        sel = np.arange(P_all) if free is None else np.asarray(free, dtype=np.intp)
        dm, dd = dm[sel], dd[sel]
        dg = {j: dg[p] for j, p in enumerate(sel) if p in dg}
        P = sel.size
        e = self.data.y - mom.mean
        u = cov.filter(e)
        z = cov.band_solve(u)
        value = float(u @ z + cov.logdet)
        Lm = cov.filter(dm.T)  # (N, P)
        grad = -2 * (Lm.T @ z)
        w = cov.width
        n = cov.gamma.ar.size - 1 if cov.gamma is not None else 0
        dgam, dar = np.zeros((P, N)), np.zeros((P, n + 1))
        for p, (dgp, darp) in dg.items():
            dgam[p], dar[p] = dgp, darp
            grad[p] += 2 * (cov.dfilter(darp, e) @ z)
        dB = cov.derivative_band(dd, dgam if dg else None, dar if dg else None)  # (P, w + 1, N)
        twice = np.where(np.arange(w + 1) > 0, 2.0, 1.0)[:, None]
        zz = np.zeros((w + 1, N))
        for b in range(w + 1):
            zz[b, : N - b] = z[b:] * z[: N - b]
        grad += dB.reshape(P, -1) @ (twice * (cov.band_inverse - zz)).ravel()
        Wm = cov._triangular(Lm, "N")
        info = 2 * (Wm.T @ Wm)
        if self._probes is None:
            self._probes = np.random.default_rng(20240607).standard_normal((N, PROBES))
        zeta = cov.colour(self._probes)  # (N, K)
        K = zeta.shape[1]
        V = dd.T[:, :, None] * zeta[:, None, :]  # (N, P, K): diag(dd_p) zeta
        if dg:
            keys = list(dg)
            V[:, keys] += _toeplitz_products(np.array([dg[p][0] for p in keys]), zeta)
        X = cov.whiten(V.reshape(N, P * K)).reshape(N, P, K).transpose(1, 0, 2).reshape(P, N * K)
        info += (X @ X.T) / K
        if P_all == P:
            return value, grad, info
        g_all, M_all = np.zeros(P_all), np.zeros((P_all, P_all))
        g_all[sel], M_all[np.ix_(sel, sel)] = grad, info
        return value, g_all, M_all

    def _frequency(self, x: FloatArray) -> tuple[float, FloatArray, FloatArray]:
        """``asml-diag`` (23) and ``asml`` (22) with coloured noise: the OE formulas of
        :mod:`jitterid.estimation.jacobians` with R = E Sigma_y E^H and dR = E dSigma_y E^H
        (linear in d, gamma: :func:`toeplitz_dft`, :func:`toeplitz_dft_diagonal`)."""
        x = np.asarray(x, float)
        _, dm, dd, dg = self._derivatives(x)
        d, f = self.data, self.freqs
        P = x.size
        dmu = dtft(dm, d.T, f)  # (P, F)
        r, chol = self._weighted(x)
        if self.method == "asml-diag":
            rho = self.covariance(x).dft_diagonal(d.T, f)
            drho = np.array([toeplitz_dft_diagonal(dd[p], dg[p][0] if p in dg else None, d.T, f) for p in range(P)])
            rr = np.abs(r) ** 2
            value = float(np.sum(rr / rho + np.log(rho)))
            grad = -2 * (dmu @ (r.conj() / rho)).real + drho @ ((1 - rr / rho) / rho)
            info = 2 * ((dmu / rho).conj() @ dmu.T).real + (drho / rho**2) @ drho.T
            return value, grad, info
        assert chol is not None
        L = chol[0]
        zz = solve_triangular(L, r, lower=True)
        value = float(np.vdot(zz, zz).real + 2 * np.sum(np.log(np.diag(L).real)))
        a = cho_solve(chol, r)
        Rinv = cho_solve(chol, np.eye(r.size))
        dR = np.array([toeplitz_dft(dd[p], dg[p][0] if p in dg else None, d.T, f, f) for p in range(P)])
        grad = -2 * (dmu @ a.conj()).real
        RdR = Rinv[None] @ dR
        grad += np.trace(RdR, axis1=1, axis2=2).real - ((dR @ a) @ a.conj()).real
        flat = RdR.reshape(P, -1)
        info = 2 * (dmu.conj() @ Rinv @ dmu.T).real + (flat @ RdR.transpose(0, 2, 1).reshape(flat.shape).T).real
        return value, grad, info

    # ------------------------------------------------------------------ criteria
    def _weighted(self, x: FloatArray) -> tuple[ComplexArray, tuple[FloatArray, bool] | None]:
        d = self.data
        r = self.Y - dtft(self.moments(x).mean, d.T, self.freqs)
        if self.method == "wbcls" and self.weights_at is not None:  # R frozen (module doc)
            if self._frozen is None:
                R = self.covariance(np.asarray(self.weights_at, float)).dft(d.T, self.freqs)
                self._frozen = cho_factor(R, lower=True)
            return r, self._frozen
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

    def jacobian(self, x: FloatArray) -> FloatArray:
        """d :meth:`residuals` / dx, shape (2F, P), for ``bcls`` and ``wbcls`` with R frozen
        (``weights_at``): -[Re; Im] L^{-1} dmu with R = L L^H, dmu = F dm from the OE pass
        (the noise parameters, pinned, do not enter)."""
        if self.method == "wbcls" and self.weights_at is None:
            raise ValueError("jacobian: the literal wbcls (R at the searched point) has none here")
        _, dm, _, _ = self._derivatives(x)
        dmu = dtft(dm, self.data.T, self.freqs).T  # (F, P)
        _, chol = self._weighted(x)
        if chol is not None:
            dmu = solve_triangular(chol[0], dmu, lower=True)
        return -np.vstack([dmu.real, dmu.imag])

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


def _toeplitz_products(g: FloatArray, x: FloatArray) -> FloatArray:
    """Toeplitz(g_p) x for every row g_p of g (P, N) and x (N, K): (N, P, K), by one FFT of
    x and of each g_p on the circulant embedding of size 2N (matmul_toeplitz per p would
    transform x again for each)."""
    P, N = g.shape
    c = np.zeros((P, 2 * N))
    c[:, :N] = g
    c[:, N + 1 :] = g[:, :0:-1]
    fx = np.fft.rfft(x, n=2 * N, axis=0)  # (N + 1, K)
    fc = np.fft.rfft(c, axis=1)  # (P, N + 1)
    out = np.fft.irfft(fc.T[:, :, None] * fx[:, None, :], n=2 * N, axis=0)
    return np.asarray(out[:N], dtype=float)


def bj_covariance(problem: BJProblem, x: FloatArray) -> FloatArray:
    """Delta-method covariance H^{-1} G Sigma_y G^T H^{-1} (module docstring); NaN rows and
    columns for parameters on a bound or pinned."""
    # Small complex Cholesky factors run ~1000x slower on a multi-threaded BLAS (as in fit).
    with threadpool_limits(limits=1, user_api="blas"):
        return _bj_covariance(problem, x)


def _bj_covariance(problem: BJProblem, x: FloatArray) -> FloatArray:
    p = x.size
    cov = np.full((p, p), np.nan)
    _, free = _steps(x, problem.bounds)  # a parameter on (or next to) a bound: no error bar
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov
    x = np.asarray(x, float)
    bounds = problem.bounds
    with np.errstate(all="ignore"):
        # G = d^2 V / dx dy^T and, for the joint criteria, H = d(analytic gradient)/dx: the
        # one difference rule (finite_diff); least squares: H = 2 J^T J with J analytic
        # (bcls, frozen wbcls) or by the same rule.
        G = np.array([finite_diff.derivative(problem.grad_y, x, i, bounds[i]) for i in idx])
        if problem.method in LEAST_SQUARES:
            if problem.method == "bcls" or problem.weights_at is not None:
                J = problem.jacobian(x)[:, idx]
            else:
                J = np.array([finite_diff.derivative(problem.residuals, x, i, bounds[i]) for i in idx]).T
            H = 2 * J.T @ J
        else:
            H = np.array(
                [finite_diff.derivative(lambda z: problem.objective_gradient(z)[1][idx], x, i, bounds[i]) for i in idx]
            )
            H = 0.5 * (H + H.T)
    # A parameter the criterion does not depend on (the pole of a noise model whose gain is
    # 0) has a vanishing row of H: no error bar for it, and none of its noise in the others.
    diag = np.abs(np.diag(H))
    keep = diag > 1e-14 * np.max(diag, initial=0.0)
    idx, H, G = idx[keep], H[np.ix_(keep, keep)], G[keep]
    if idx.size == 0:
        return cov
    B = G @ problem.covariance(x).matmul(G.T)
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    cov[np.ix_(idx, idx)] = Hinv @ B @ Hinv.T
    return cov
