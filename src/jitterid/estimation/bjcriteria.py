"""The Box-Jenkins problem (BJ (2b), JBJ (2d)) and its delta-method covariance.

y_k = s(kT + tau_k; theta) + v(kT + tau_k; eta) + w_k with coloured noise v (eq. (1c),
:mod:`jitterid.noise.models`) and a white part w_k of std sigma_w (known, or estimated as
``noise_std``). The mean is Lemma 1's m_k as for OE; the covariance is Sigma_y of (C2)
(:mod:`jitterid.moments.noise_covariance`): the diagonal signal part of Lemma 2 plus the Toeplitz
covariance of the jittered noise. :class:`BJProblem` gives a criterion what it reads
(:class:`~jitterid.estimation.estimators.base.ColouredContext`): the moments, Sigma_y, the
DTFT residual, R = E Sigma_y E^H and its Cholesky factor, and their derivatives. The criteria
themselves are the estimators' coloured-noise forms (the ``bj_*`` methods, each beside its
white-noise twin in :mod:`jitterid.estimation.estimators`):

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
``noise_std`` (sigma_w) when it is estimated. An estimator that does not identify the noise
model (``identifies_noise_model`` False: ``bcls`` and ``wbcls``, no ln det term) gets the
noise parameters as *plug-in* values held fixed (``pinned``), with NaN standard errors.

WBCLS weights: as for OE (:mod:`jitterid.estimation.problem`), R is frozen at ``weights_at``
(the BCLS/GLS start with the plug-in noise model, then re-frozen once at the first WBCLS
estimate, :class:`jitterid.estimation.boxjenkins.BoxJenkinsRoute`): the literal (20) with R(theta)
inside the search, having no ln det R, is minimised partly by inflating R and is biased.
``weights_at=None`` keeps the literal form, for comparison.

Error bars: the delta method of :mod:`jitterid.estimation.covariance` with the full covariance,
because the samples are now correlated: Cov(theta) = H^{-1} G Sigma_y G^T H^{-1}, G = d^2 V /
d theta dy^T (closed form for ``gaussian``, else central differences of dV/dy), H the Hessian of V
(central differences of the analytic gradient; Gauss-Newton 2 J^T J for the least-squares criteria);
G Sigma_y G^T is an FFT Toeplitz product. Every difference quotient goes through
:func:`jitterid.finite_diff.derivative`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor
from threadpoolctl import threadpool_limits

from .. import finite_diff
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.noise_covariance import (
    JitteredAutocovariance,
    SampleCovariance,
    autocovariance_derivatives,
    jittered_autocovariance,
    toeplitz_dft,
    toeplitz_dft_diagonal,
)
from ..moments.reference import dtft
from ..moments.sample import SampleMoments
from ..noise.models import NoiseModel, NoiseStructure
from ..params import ParamLayout
from ..simulate import SampledData
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .covariance import _steps
from .estimators import BCLS, Estimator, as_estimator
from .jacobians import moment_derivatives
from .problem import Problem, adjoint_dtft
from .search import SearchOptions

__all__ = ["BJProblem", "bj_covariance"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

PROBES = 16  # probe vectors of the trace term of the Fisher matrix (``objective_gradient``)


# Newton decrement (twice the predicted remaining decrease of V = -2 log-likelihood) at which
# the search stops: 1e-6 units of V moves the estimate by ~1e-3 standard errors.
NEWTON_TOL = 1e-6
STALL_TOL = 1e-3  # decrement below which "no step decreases V" is the rounding floor
STALL_GAIN = 1e-4  # stop when the last accepted steps (search.STALL_WINDOW) gained less


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
    method: str | Estimator  # an estimator with a coloured-noise form, or its name
    freqs: FloatArray
    white_std: float | None
    pinned: FloatArray | None = None
    weights_at: FloatArray | None = None  # wbcls: the point at which R is frozen
    estimator: Estimator = field(init=False)
    layout: ParamLayout = field(init=False)  # the one parameter layout (pinned: closed bounds)
    names: tuple[str, ...] = field(init=False)
    bounds: tuple[tuple[float, float], ...] = field(init=False)
    Y: ComplexArray = field(init=False)
    _moments: dict[bytes, SampleMoments] = field(init=False, default_factory=dict)
    _autocov: dict[bytes, JitteredAutocovariance] = field(init=False, default_factory=dict)
    _cov: dict[bytes, SampleCovariance] = field(init=False, default_factory=dict)
    # the OE problem whose moments (and their derivatives, jacobians.moment_derivatives) are
    # the system/jitter block; the autocovariance's parameter derivatives; probe vectors
    _oe: Problem = field(init=False)
    _dgamma: tuple[bytes, dict[int, tuple[FloatArray, FloatArray]]] | None = field(
        init=False, default=None
    )
    _probes: FloatArray | None = field(init=False, default=None)
    _nm: tuple[bytes, NoiseModel] | None = field(init=False, default=None)
    _frozen: tuple[FloatArray, bool] | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.estimator = as_estimator(self.method)
        if not self.estimator.coloured_noise:
            self.estimator.refuse_coloured_noise()
        own = set(self.noise.param_names) | ({"noise_std"} if self.white_std is None else set())
        clash = own & (
            set(getattr(self.jitter, "param_names", ())) | set(self.structure.param_names)
        )
        if clash:
            raise ValueError(
                f"noise: its parameter names {sorted(clash)} clash with the system's or jitter's; "
                "rename them in the noise structure"
            )
        lay = ParamLayout.build(
            self.jitter, self.structure, self.noise, noise_std=self.white_std is None
        )
        k = len(lay.jitter) + len(lay.system)  # the noise block and noise_std follow
        if self.pinned is not None:
            nn = lay.names[k:]
            if self.pinned.size != len(nn):
                raise ValueError(f"pinned must hold {len(nn)} values {nn}; got {self.pinned.size}")
            pinned = tuple((float(v), float(v)) for v in self.pinned)
            lay = dataclasses.replace(lay, bounds=lay.bounds[:k] + pinned)
        self.layout = lay
        self.names = lay.names
        self.bounds = lay.bounds
        self.Y = dtft(self.data.y, self.data.T, self.freqs)
        self._oe = Problem(
            self.data, self.structure, self.jitter, BCLS(), self.freqs, None, with_variances=True
        )

    # ------------------------------------------------------------------ for the search
    def search_options(self, tol: float | None = None) -> SearchOptions:
        """The Newton adapter's options: logs of unbounded rates and squares of noise stds
        (:class:`~jitterid.estimation.search.Coordinates`), Newton decrement NEWTON_TOL (or
        ``tol``, e.g. the loose noise and GLS stages), a stall of the criterion (a white
        record's noise pole running off) and exhausted damping below STALL_TOL taken as
        converged."""
        t = NEWTON_TOL if tol is None else tol
        return SearchOptions(t, True, STALL_GAIN if tol is None else max(STALL_GAIN, t), STALL_TOL)

    def search_residuals(self, x: FloatArray) -> FloatArray:
        """:meth:`residuals` (the search protocol's name)."""
        return self.residuals(x)

    def release(self) -> None:
        """Nothing to drop between stages: the caches are per point and small."""

    def restrict(self, bounds: tuple[tuple[float, float], ...] | None) -> None:
        """Search within ``bounds`` (a smooth piece of a kinked jitter parameter,
        :func:`jitterid.estimation.search.piecewise`), or the layout's own with None; the
        moments' problem is restricted with it (its derivatives at a piece's end are
        one-sided into the piece).

        Parameters
        ----------
        bounds : tuple of (float, float) or None
            One closed interval per parameter, inside the layout's; None lifts it.
        """
        self.bounds = self.layout.bounds if bounds is None else tuple(bounds)
        self._oe.restrict(None if bounds is None else self.bounds[: len(self._oe.names)])

    @property
    def n_jitter(self) -> int:
        return len(self.layout.jitter)

    @property
    def n_system(self) -> int:
        return len(self.structure.param_names)

    @property
    def n_noise(self) -> int:
        return len(self.noise.param_names)

    def _law(self, x: FloatArray) -> JitterLaw:
        if isinstance(self.jitter, JitterFamily):
            return self.jitter.law(self.layout.block(x, "jitter").tolist())
        return self.jitter

    def _jitter_noise_key(self, x: FloatArray) -> bytes:
        """The jitter and noise parameters of ``x`` (on which gamma depends), as a key."""
        return np.r_[self.layout.block(x, "jitter"), self.layout.block(x, "noise")].tobytes()

    def split(self, x: FloatArray) -> tuple[JitterLaw, TransferFunction, NoiseModel, float]:
        """(jitter law, system, noise model, sigma_w) at parameter vector ``x``."""
        tf = self.structure.system(self.layout.block(x, "system"))
        return self._law(x), tf, self._noise_model(x), self._white(x)

    def _white(self, x: FloatArray) -> float:
        if self.white_std is None:
            return float(self.layout.block(x, "noise_std")[0])
        return float(self.white_std)

    def _noise_model(self, x: FloatArray) -> NoiseModel:
        """H at ``x``, kept for the last noise parameters (a model builds its modal form)."""
        eta = self.layout.block(x, "noise")
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
        key = self._jitter_noise_key(x)
        if key not in self._autocov:
            self._autocov.clear()
            self._autocov[key] = jittered_autocovariance(
                self._noise_model(x), self._law(x), self.data.T
            )
        return self._autocov[key]

    def covariance(self, x: FloatArray) -> SampleCovariance:
        """Sigma_y of (C2) at ``x``."""
        key = np.asarray(x, float).tobytes()
        if key not in self._cov:
            white = self._white(x)
            self._cov.clear()
            self._cov[key] = SampleCovariance(
                self.moments(x).var + white**2, self.autocovariance(x)
            )
        return self._cov[key]

    def autocovariance_derivatives(self, x: FloatArray) -> dict[int, tuple[FloatArray, FloatArray]]:
        """d gamma(0..N-1) and d(ar) for each jitter and noise parameter (index into ``x``).

        Noise parameters: in closed form (:func:`jitterid.moments.noise_covariance.
        autocovariance_derivatives` with :meth:`RationalNoise.mode_derivatives`) when the
        jitter spans at most T. Otherwise, and for jitter-family parameters, by
        :func:`jitterid.finite_diff.derivative` of (C1)-(C3): the near lags are
        quadratures over the law, with no closed-form derivative."""
        lay = self.layout
        nj, nn = self.n_jitter, self.n_noise
        key = self._jitter_noise_key(x)
        if self._dgamma is not None and self._dgamma[0] == key:
            return self._dgamma[1]
        N, T = self.data.N, self.data.T
        jb = tuple(self.jitter.bounds) if isinstance(self.jitter, JitterFamily) else ()
        natural = jb + tuple(self.structure.bounds) + tuple(self.noise.bounds)
        g0 = self.autocovariance(x)
        base = np.r_[g0.sequence(N), g0.ar]

        def flat(xx: FloatArray) -> FloatArray:
            g = jittered_autocovariance(self.noise.model(lay.block(xx, "noise")), self._law(xx), T)
            return np.r_[g.sequence(N), g.ar]

        out: dict[int, tuple[FloatArray, FloatArray]] = {}
        noise_idx = list(range(lay.size)[lay.slice("noise")])
        fd = [*range(nj), *noise_idx]
        modes = getattr(self.noise, "mode_derivatives", None)
        if nn and modes is not None:  # closed form in the noise parameters when M0 = 1
            eta = lay.block(x, "noise")
            nm = self._noise_model(x)
            dc, dp = modes(eta, nm)
            exact = autocovariance_derivatives(nm, self._law(x), T, dc, dp, N)
            if exact is not None:
                for k, i in enumerate(noise_idx):
                    out[i] = (exact[0][k], exact[1][k])
                fd = fd[:nj]
        for i in fd:
            dv = finite_diff.derivative(flat, np.asarray(x, float), i, natural[i], f0=base)
            out[i] = (dv[:N], dv[N:])
        self._dgamma = (key, out)
        return out

    def derivatives(
        self, x: FloatArray
    ) -> tuple[SampleMoments, FloatArray, FloatArray, dict[int, tuple[FloatArray, FloatArray]]]:
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

    # ------------------------------------------------------------------ for the criteria
    @property
    def frozen_weights(self) -> bool:
        """True for a full-covariance criterion with R frozen at ``weights_at`` (wbcls)."""
        return self.estimator.full_covariance and self.weights_at is not None

    def weighted(self, x: FloatArray) -> tuple[ComplexArray, tuple[FloatArray, bool] | None]:
        """Residual Y - mu and, for the full-covariance criteria, the Cholesky factor of
        R = E Sigma_y E^H (at ``weights_at`` if frozen, else at ``x``)."""
        d = self.data
        r = self.Y - dtft(self.moments(x).mean, d.T, self.freqs)
        if self.frozen_weights:  # R frozen (module doc)
            if self._frozen is None:
                R = self.covariance(np.asarray(self.weights_at, float)).dft(d.T, self.freqs)
                self._frozen = cho_factor(R, lower=True)
            return r, self._frozen
        if self.estimator.full_covariance:
            R = self.covariance(x).dft(d.T, self.freqs)
            return r, cho_factor(R, lower=True)
        return r, None

    def dmu(self, dm: FloatArray) -> ComplexArray:
        """d mu_Y(f) / dx over the frequency set, (P, F): the DTFT of dm_k (Lemma 1)."""
        return dtft(dm, self.data.T, self.freqs)

    def dR(self, dd: FloatArray, dg: dict[int, tuple[FloatArray, FloatArray]]) -> ComplexArray:
        """dR_p = E dSigma_p E^H over the frequency set, (P, F, F), for dSigma_p =
        diag(dd_p) + Toeplitz(dgamma_p) (:meth:`derivatives`)."""
        T, f = self.data.T, self.freqs
        return np.array(
            [
                toeplitz_dft(dd[p], dg[p][0] if p in dg else None, T, f, f)
                for p in range(dd.shape[0])
            ]
        )

    def R_diagonal(self, x: FloatArray) -> FloatArray:
        """R(f, f) over the frequency set (what (23) weights by)."""
        return self.covariance(x).dft_diagonal(self.data.T, self.freqs)

    def dR_diagonal(
        self, dd: FloatArray, dg: dict[int, tuple[FloatArray, FloatArray]]
    ) -> FloatArray:
        """d R(f, f) / dx, (P, F) (:meth:`dR` on the diagonal only, O(N log N) each)."""
        T, f = self.data.T, self.freqs
        return np.array(
            [
                toeplitz_dft_diagonal(dd[p], dg[p][0] if p in dg else None, T, f)
                for p in range(dd.shape[0])
            ]
        )

    def adjoint(self, z: ComplexArray) -> FloatArray:
        """Re F^H z: the time-domain image of a frequency-domain weight (for dV/dy)."""
        return adjoint_dtft(z, self.data.T, self.freqs, self.data.N).real

    def probes(self) -> FloatArray:
        """``PROBES`` fixed standard normal probe vectors (N, PROBES) for the trace term of
        the Gaussian criterion's Fisher matrix: the same at every point, so the expected
        Hessian is smooth in x."""
        if self._probes is None:
            self._probes = np.random.default_rng(20240607).standard_normal((self.data.N, PROBES))
        return self._probes

    # ------------------------------------------------------------------ the criterion
    # The estimator's coloured-noise form (``bj_*`` methods, one module each in
    # :mod:`jitterid.estimation.estimators`) evaluated on this problem.
    def objective(self, x: FloatArray) -> float:
        """The criterion value V of the chosen estimator (module docstring)."""
        return self.estimator.bj_objective(self, np.asarray(x, float))

    def objective_gradient(
        self, x: FloatArray, free: NDArray[np.intp] | None = None
    ) -> tuple[float, FloatArray, FloatArray]:
        """(V, dV/dx, expected Hessian M of V) of a Newton-searched estimator (``gaussian``,
        ``asml``, ``asml-diag``): the input of :func:`jitterid.estimation.search
        .newton_search`. ``free``: indices of the parameters searched; an estimator may then
        form only their rows and columns (zeros elsewhere), e.g. the noise stage with the
        system fixed."""
        return self.estimator.bj_objective_gradient(self, np.asarray(x, float), free)

    @property
    def has_jacobian(self) -> bool:
        """Whether :meth:`jacobian` is analytic here (least squares; wbcls: R frozen)."""
        return self.estimator.bj_has_jacobian(self)

    def residuals(self, x: FloatArray) -> FloatArray:
        """Real residual vector whose squared norm is the criterion (least-squares estimators)."""
        return self.estimator.bj_residuals(self, np.asarray(x, float))

    def jacobian(self, x: FloatArray) -> FloatArray:
        """d :meth:`residuals` / dx, shape (2F, P), analytic where :attr:`has_jacobian`."""
        return self.estimator.bj_jacobian(self, np.asarray(x, float))

    def grad_y(self, x: FloatArray) -> FloatArray:
        """dV/dy at the data: the input to the delta-method covariance."""
        return np.asarray(self.estimator.bj_grad_y(self, np.asarray(x, float)), dtype=float)

    def grad_y_jacobian(self, x: FloatArray) -> FloatArray | None:
        """d^2 V / dx dy^T (P, N) in closed form, or None (then :meth:`grad_y` is differenced)."""
        return self.estimator.bj_grad_y_jacobian(self, np.asarray(x, float))

    def gradient(self, x: FloatArray) -> FloatArray:
        """dV/dx (Newton-searched estimators), without the expected Hessian."""
        return self.estimator.bj_gradient(self, np.asarray(x, float))


def bj_covariance(problem: BJProblem, x: FloatArray, fixed: tuple[int, ...] = ()) -> FloatArray:
    """Delta-method covariance H^{-1} G Sigma_y G^T H^{-1} (module docstring); NaN rows and
    columns for parameters on a bound, pinned, in ``fixed`` (held: none of their noise in
    the others), or on which the criterion does not depend at ``x``."""
    # Small complex Cholesky factors run ~1000x slower on a multi-threaded BLAS (as in fit).
    with threadpool_limits(limits=1, user_api="blas"):
        return _bj_covariance(problem, x, fixed)


def _bj_covariance(problem: BJProblem, x: FloatArray, fixed: tuple[int, ...] = ()) -> FloatArray:
    p = x.size
    cov = np.full((p, p), np.nan)
    _, free = _steps(x, problem.bounds)  # a parameter on (or next to) a bound: no error bar
    free[list(fixed)] = False
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov
    x = np.asarray(x, float)
    bounds = problem.bounds
    with np.errstate(all="ignore"):
        # G = d^2 V / dx dy^T (closed form where the estimator has one: gaussian) and, for
        # the Newton-searched criteria, H = d(analytic gradient)/dx: the one difference rule
        # (finite_diff); least squares: H = 2 J^T J with J analytic (bcls, frozen wbcls) or
        # by the same rule.
        closed = problem.grad_y_jacobian(x)
        if closed is not None:
            G = closed[idx]
        else:
            G = np.array([finite_diff.derivative(problem.grad_y, x, i, bounds[i]) for i in idx])
        if problem.estimator.least_squares:
            if problem.has_jacobian:
                J = problem.jacobian(x)[:, idx]
            else:
                J = np.array(
                    [finite_diff.derivative(problem.residuals, x, i, bounds[i]) for i in idx]
                ).T
            H = 2 * J.T @ J
        else:
            H = np.array(
                [
                    finite_diff.derivative(lambda z: problem.gradient(z)[idx], x, i, bounds[i])
                    for i in idx
                ]
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
