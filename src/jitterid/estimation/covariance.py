"""Delta-method (sandwich) covariance of any criterion's minimiser.

An estimate theta(y) solves dV/dtheta (theta, y) = 0. Differentiating in y gives
d theta / dy = -H^{-1} G with H = d^2 V / d theta^2 and G = d^2 V / d theta dy^T, and since
the samples are independent with variances w_k,

    Cov(theta) ~ H^{-1} G diag(w) G^T H^{-1}.

This holds for every criterion of the library, whether or not it is a likelihood, so every
estimator gets honest error bars by one route. For least-squares criteria H is the
Gauss-Newton matrix 2 J^T J with the analytic Jacobian; otherwise central differences of
the analytic gradient (:mod:`jitterid.estimation.jacobians`).

The variances w_k = Var s(kT + tau) + sigma_v^2 always include the measurement noise: where
the criterion does not use sigma_v (``bcls``), the known value or, failing that, its
maximum-likelihood value given the residuals (:func:`noise_variance_ml`) is used.

``cov_type`` chooses the form (:data:`jitterid.estimation.result.COV_TYPES`):

- ``"sandwich"`` (default of the moment estimators): w_k from the model, as above; for a
  criterion whose gradient is quadratic in y (``gaussian`` per sample, ``asml`` and
  ``asml-diag`` in the DTFT residual) the exact Cov(dV/dx) with the samples' third and
  fourth moments instead of the first-order G diag(w) G^T, which doubles the Gaussian
  quadratic part and ignores the jittered samples' kurtosis
  (:func:`_per_sample_score_covariance`, :func:`_frequency_score_covariance`; asml's full
  kernel up to KERNEL_MAX_FREQUENCIES frequencies, the first-order form beyond);
- ``"robust"``: w_k = (y_k - m_k)^2 (White's HC0), honest when the jitter law or the noise
  level is misspecified (default for ``ls``, whose model has no jitter); for ``ml`` the
  Huber-White form H^{-1} (4 sum_k g_k g_k^T) H^{-1} with g_k the per-sample scores.
  Under a misspecified jitter law the robust errors hold for the system's parameters but not
  for the law's own: the robust standard error of the law's scale can be well below its
  spread (0.7 of it for ``gaussian``, triangular jitter fitted with ``UniformFamily``, N =
  200), because the pseudo-true law changes with the input realization, which no per-record
  sandwich sees, and the meat at the fitted scale is smaller than at the pseudo-true one
  (its bread is right). Read it as a lower bound; a parametric bootstrap is the honest
  alternative;
- ``"oim"`` (default for ``ml``): the inverse observed information, Cov = 2 H^{-1} for
  V = -2 ln L (``ml``) or V = -2 ln L_G + const (``gaussian``, the Gaussian pseudo-likelihood);
- ``"none"``: not computed (NaN), for Monte Carlo loops that do not need it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, signal
from threadpoolctl import threadpool_limits

from .. import finite_diff
from ..jitter.laws import JitterFamily
from ..moments.sample import covariance_from_variances

if TYPE_CHECKING:
    from .problem import Problem

__all__ = ["covariance", "noise_variance_ml"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_REL_STEP = 1e-4
_SCALE_STEP = 0.05  # steps at most this fraction of a parameter's natural scale (_steps)
#: frequencies up to which the frequency-domain criteria's score covariance is exact
#: (_frequency_score_covariance, O(P F^3)); beyond, the first-order form G W G^T
KERNEL_MAX_FREQUENCIES = 2048


def unidentified_shapes(problem: Problem, x: FloatArray, cov: FloatArray) -> NDArray[np.bool_]:
    """The jitter family's shape parameters (all but its scale, in a family of two or more)
    to hold fixed where the data do not tell the family's parameters: one of them (shape or
    scale) with a standard error beyond its admissible range, or none where the others have
    one. The paper's Table 1: the criteria tell the jitter's std well and the shape n at
    that std hardly at all (BCLS: n's error bar 1e3-1e5 on [0, 20]); along that direction
    the scale moves with the shape, so a's error bar can exceed its range as well (gaussian:
    0.7 on (0, 0.5]), which holding n fixed resolves."""
    out = np.zeros(x.size, dtype=bool)
    fam = problem.jitter
    nj = problem.n_jitter
    if not isinstance(fam, JitterFamily) or nj < 2:
        return out
    se = np.sqrt(np.where(np.diag(cov) > 0, np.diag(cov), np.nan))
    lo, hi = np.array(problem.layout.bounds, dtype=float).reshape(-1, 2).T
    rest = np.isfinite(se)
    # held on purpose: on or next to a bound, at a kink (no error bar by design)
    held = ~_steps(x, problem.layout.bounds)[1] | problem.layout.at_kink(x)
    told = False  # a jitter parameter the data do not tell (its error bar beyond its range)
    for i in range(nj):
        wide = np.isfinite(se[i]) and se[i] > hi[i] - lo[i]
        missing = not np.isfinite(se[i]) and not held[i] and np.any(rest[np.arange(x.size) != i])
        told = told or bool(wide) or bool(missing)
    if told:  # along the family at a fixed std the scale moves with the shape: hold the shape
        for i in range(nj):
            out[i] = i != fam.scale_index
    return out


def _steps(
    x: FloatArray, bounds: tuple[tuple[float, float], ...], scale: FloatArray | None = None
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Difference steps, and which parameters are far enough from their bounds for an error
    bar (x +- 2h inside, h = 1e-4 max(|x_i|, 1e-2)): the others get NaN rows and columns.

    ``scale``: each parameter's natural scale (a standard error from the criterion's own
    information matrix, :func:`_natural_scale`); the step is then at most _SCALE_STEP of it,
    so that it stays inside the region where the criterion is quadratic however large
    |x_i| is relative to its error (a frequency over a long record: f = 0.23 Hz, N = 4000,
    whose relative step 1e-4 moved the phase at the record's end by 0.6 rad)."""
    h = np.array([finite_diff.step(x, i, _REL_STEP) for i in range(x.size)])
    lo, hi = np.array(bounds, dtype=float).reshape(-1, 2).T
    if scale is not None:
        ok = np.isfinite(scale) & (scale > 0)
        h = np.where(ok, np.minimum(h, _SCALE_STEP * np.where(ok, scale, 1.0)), h)
    # the test with the step actually taken: the floor of finite_diff.step (1e-2 in the
    # parameter's own unit) would put a jitter std of 0.5 ns "next to its bound" at T = 1 ns
    free = (x - 2 * h >= lo) & (x + 2 * h <= hi)
    return h, free


def _search_information(problem: Problem, x: FloatArray) -> FloatArray | None:
    """The information the search itself used (the exact likelihood's observed information
    :meth:`~jitterid.estimation.likelihood.ExactLikelihood.information`, a Newton
    criterion's expected Hessian of V ~ -2 ln L), or None (least squares: H is analytic, no
    step needed; or not computable at ``x``)."""
    try:
        if problem.likelihood is not None:
            return problem.likelihood.information(x, problem.data.y)
        if not problem.estimator.least_squares:
            return 0.5 * np.asarray(problem.objective_gradient(x)[2], dtype=float)
    except (ValueError, np.linalg.LinAlgError):
        return None
    return None


def _natural_scale(info: FloatArray | None) -> FloatArray | None:
    """1 / sqrt of the diagonal of the search's information (:func:`_search_information`),
    or None where there is none."""
    if info is None:
        return None
    d = np.diag(np.asarray(info, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(d > 0, 1.0 / np.sqrt(np.abs(d)), np.nan)


def noise_variance_ml(r: FloatArray, var: FloatArray) -> float:
    """argmax over s >= 0 of the Gaussian likelihood of r_k ~ N(0, var_k + s): the white-noise
    variance that, added to the jitter variances ``var``, best explains the residuals ``r``."""
    power = float(np.mean(r**2))
    if power == 0:
        return 1e-300
    lo, hi = np.log(1e-12 * power), np.log(10 * power)

    def nll(log_s: float) -> float:
        w = var + np.exp(log_s)
        return float(np.sum(np.log(w) + r**2 / w))

    sol = optimize.minimize_scalar(nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    return float(np.exp(sol.x))


def covariance(
    problem: Problem, x: FloatArray, cov_type: str, noise_std: float | None = None
) -> FloatArray:
    """Covariance of the estimate ``x`` of ``problem``; NaN for parameters on a bound.

    ``noise_std`` is the white-noise std for the model variances where the criterion does
    not carry it (module docstring); ignored otherwise.
    """
    # Small complex Cholesky factorisations run ~100x slower multi-threaded on small machines.
    with threadpool_limits(limits=1, user_api="blas"):
        return _covariance(problem, np.asarray(x, float), cov_type, noise_std)


def _covariance(
    problem: Problem, x: FloatArray, cov_type: str, noise_std: float | None
) -> FloatArray:
    """The covariance with the parameters at a bound or a kink held fixed and, where the
    data do not identify a jitter family's shape (:func:`unidentified_shapes`), with that
    held fixed too (the others', the jitter std's included, conditional on it)."""
    memo: _Hessians = {}
    cov = _held_covariance(problem, x, cov_type, noise_std, np.zeros(x.size, dtype=bool), memo)
    flat = unidentified_shapes(problem, x, cov)
    if flat.any() and not np.all(np.isnan(cov)):
        cov = _held_covariance(problem, x, cov_type, noise_std, flat, memo)
    return cov


#: the Hessians of V by differences made for one covariance, by the free parameters
#: (_held_covariance): the pass with an unidentified shape held takes its block of the first
#: pass's instead of differencing again (each column is the same difference of the same
#: gradient rows, at the same steps)
_Hessians = dict[tuple[int, ...], "FloatArray"]


def _hessian(
    memo: _Hessians | None, idx: NDArray[np.intp], make: Callable[[], FloatArray]
) -> FloatArray:
    """The Hessian over ``idx``: the block of one in ``memo`` over a superset of ``idx``,
    else ``make()`` (remembered)."""
    key = tuple(int(i) for i in idx)
    for have, H in (memo or {}).items():
        if set(key) <= set(have):
            pos = [have.index(i) for i in key]
            return H[np.ix_(pos, pos)]
    H = make()
    if memo is not None:
        memo[key] = H
    return H


def _held_covariance(
    problem: Problem,
    x: FloatArray,
    cov_type: str,
    noise_std: float | None,
    hold: NDArray[np.bool_],
    memo: _Hessians | None = None,
) -> FloatArray:
    p = x.size
    cov = np.full((p, p), np.nan)
    if p == 0 or cov_type == "none":
        return cov
    info = _search_information(problem, x)
    h, free = _steps(x, problem.bounds, _natural_scale(info))
    free &= ~hold & ~problem.layout.at_kink(x)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov
    if problem.likelihood is not None:
        return _ml_covariance(problem, x, idx, h[idx], cov_type == "robust", cov, info, memo)
    bounds = problem.bounds
    G = _grad_y_jacobian(problem, x, idx, h)
    if problem.estimator.least_squares:
        J = problem.jacobian(x)[:, idx]  # analytic (jitterid.estimation.jacobians)
        H = 2 * J.T @ J
    else:
        # Central differences of the analytic gradient: 2 p evaluations, against ~2 p^2 for
        # second differences of the criterion, and one order of differencing fewer.
        def gradient(z: FloatArray) -> FloatArray:
            return problem.objective_gradient(z)[1][idx]

        def make() -> FloatArray:
            with problem.pinned(x, free):  # (the others' derivatives not made)
                H = np.array(
                    [finite_diff.derivative(gradient, x, i, bounds[i], h=h[i]) for i in idx]
                )
            return 0.5 * (H + H.T)

        H = _hessian(memo, idx, make)
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    if cov_type == "oim":  # V = -2 ln L_G + const: Cov = (-d2 ln L_G)^{-1} = 2 H^{-1}
        cov[np.ix_(idx, idx)] = 2 * Hinv
        return cov
    A = problem.estimator.y_hessian_diagonal(problem, x)
    K = None
    if A is None and cov_type != "robust":
        K = problem.estimator.frequency_kernel(problem, x)
        if K is not None and np.ndim(K) == 3 and problem.freqs.size > KERNEL_MAX_FREQUENCIES:
            K = None  # a full kernel costs O(P F^3): the first-order form beyond
    if A is not None:
        B = _per_sample_score_covariance(
            problem, x, G, np.asarray(A, float)[idx], cov_type == "robust"
        )
    elif K is not None:
        B = _frequency_score_covariance(problem, x, G, np.asarray(K)[idx])
    else:
        if cov_type == "robust":
            w = (problem.data.y - problem.moments(x).mean) ** 2
        else:
            w = problem.variances(x)
            if not problem.uses_noise and noise_std is not None:
                w = w + float(noise_std) ** 2
        B = (G * w) @ G.T
    cov[np.ix_(idx, idx)] = Hinv @ B @ Hinv.T
    return cov


def _grad_y_jacobian(
    problem: Problem, x: FloatArray, idx: NDArray[np.intp], h: FloatArray | None = None
) -> FloatArray:
    """G = d^2 V / dx dy^T at the problem's data, rows ``idx``: closed form or differences
    (steps ``h``, default :func:`_steps`'s relative ones)."""
    closed = problem.estimator.grad_y_jacobian(problem, x)
    if closed is not None:
        return np.asarray(closed, float)[idx]
    bounds = problem.bounds
    if h is None:
        h = _steps(x, bounds)[0]
    return np.array([finite_diff.derivative(problem.grad_y, x, i, bounds[i], h=h[i]) for i in idx])


def _per_sample_score_covariance(
    problem: Problem, x: FloatArray, G: FloatArray, A: FloatArray, robust: bool
) -> FloatArray:
    """B = Cov(dV/dx) for a gradient that is a sum of per-sample terms quadratic in y_k:
    psi_k = c_k + b_k r_k + A_k r_k^2, r = y - m (the ``gaussian`` criterion,
    :meth:`Estimator.y_hessian_diagonal`).

    The first-order delta method (G diag(w) G^T with G = b + 2 A r at the data) gives
    E[B] = b W b^T + 4 sum A A^T w^2: for Gaussian samples twice the quadratic part's
    variance, and it ignores the skewness and kurtosis of jittered samples, which are far
    from Gaussian (a sinusoid under wide uniform jitter: kurtosis ~ 1.5). Exactly, with the
    model's third and fourth moments (:meth:`Problem.central_moments`),

        B = sum_k b_k b_k^T w_k + A_k A_k^T (mu4_k - w_k^2) + mu3_k (b_k A_k^T + A_k b_k^T),

    b = G at y = m; ``robust``: sum_k psi_k psi_k^T with psi_k = b_k r_k + A_k (r_k^2 - w_k)
    at the residuals (Huber-White).
    """
    mom = problem.moments(x)
    r = problem.data.y - mom.mean
    w = problem.variances(x)
    b = G - 2 * A * r  # G = b + 2 A r
    if robust:
        psi = b * r + A * (r * r - w)
        return psi @ psi.T
    mu3, mu4 = problem.central_moments(x)
    cross = (b * mu3) @ A.T
    return (b * w) @ b.T + (A * (mu4 - w * w)) @ A.T + cross + cross.T


def _frequency_score_covariance(
    problem: Problem, x: FloatArray, G: FloatArray, K: ComplexArray
) -> FloatArray:
    """B = Cov(dV/dx) for a frequency-domain criterion whose gradient is quadratic in the
    DTFT residual r = E e (e = y - m, E_fk = exp(-i 2 pi f k T)): psi_p = c_p + b_p^T e +
    r^H K_p r (``asml``, ``asml-diag``, :meth:`Estimator.frequency_kernel`). In the time
    domain the quadratic part is e^T A_p e with A_p = Re(E^H K_p E), so with the samples'
    variances w, third and fourth moments (:meth:`Problem.central_moments`)

        B = b W b^T + 2 tr(A_p W A_q W) + sum_k A_p,kk A_q,kk (mu4_k - 3 w_k^2)
            + sum_k mu3_k (b_p,k A_q,kk + A_p,kk b_q,k),

    2 tr(A_p W A_q W) = Re[tr(K_p S K_q S) + tr(K_p C conj(K_q) conj(C))] with S = E W E^H
    and C = E W E^T (R_Y and the pseudo-covariance, (17)-(19)). The first-order form
    G W G^T (G = b + 2 A e at the data) doubles the Gaussian quadratic part and ignores the
    jittered samples' kurtosis (asml-diag, noise estimated: score standard deviations 1.4-1.55
    times the simulated ones). A diagonal kernel (asml-diag) costs O(N log N) on the DFT grid
    (:func:`_squared_covariance_products`); a full one (asml) O(P F^3), used up to
    KERNEL_MAX_FREQUENCIES frequencies.
    """
    d = problem.data
    f = problem.freqs
    w = problem.variances(x)
    r = problem.weighted(x)[0]
    P = K.shape[0]
    if K.ndim == 2:  # diagonal (real) kernels k_p: tr(K_p S K_q S) = k_p^T |S|^2 k_q
        k = K.real
        Q = k @ _squared_covariance_products(w, d.T, f, k.T)
        Ae = np.array([problem.adjoint(kp * r) for kp in k])
        Akk = np.repeat(k.sum(axis=1)[:, None], d.N, axis=1)
    else:
        S = covariance_from_variances(w, d.T, f, f)
        C = covariance_from_variances(w, d.T, f, -f)
        KS, KC = K @ S[None], K @ C[None]
        Q = (np.einsum("pfg,qgf->pq", KS, KS) + np.einsum("pfg,qgf->pq", KC, KC.conj())).real
        Ae = np.array([problem.adjoint(Kp @ r) for Kp in K])
        # A_kk = Re sum_{f,g} K_fg e^{i 2 pi (f - g) k T}: the kernel summed per difference
        uniq, inverse = problem.difference_grid()
        c = np.array(
            [
                np.bincount(inverse, Kp.ravel().real, uniq.size)
                + 1j * np.bincount(inverse, Kp.ravel().imag, uniq.size)
                for Kp in K
            ]
        )
        Akk = (c @ np.exp(2j * np.pi * np.outer(uniq, np.arange(d.N) * d.T))).real
    Q = np.asarray(Q, float).reshape(P, P)
    b = G - 2 * Ae  # G = b + 2 A e
    mu3, mu4 = problem.central_moments(x)
    cross = (b * mu3) @ Akk.T
    return (b * w) @ b.T + Q + (Akk * (mu4 - 3 * w * w)) @ Akk.T + cross + cross.T


def _squared_covariance_products(
    w: FloatArray, T: float, f: FloatArray, k: FloatArray
) -> FloatArray:
    """(|S|^2 + |C|^2) k for the columns of ``k`` (F, P), S and C the covariance and
    pseudo-covariance of the DTFT over ``f`` from the variances ``w`` ((17)-(19)).

    On consecutive DFT bins f_a = (a0 + a) / (N T) (the set (24)), S_ab = W[a - b] and
    C_ab = W[2 a0 + a + b] with W the DFT of w (indices mod N): |S|^2 is Toeplitz and |C|^2
    Hankel, so the products are FFT convolutions, O(N log N) (no F x F matrix); elsewhere
    the matrices are formed (O(F^2))."""
    N = w.size
    bins = np.asarray(f, float) * N * T
    a = np.round(bins)
    F = f.size
    if F and np.all(np.abs(bins - a) < 1e-9) and np.all(np.diff(a) == 1):
        a0 = int(a[0])
        W2 = np.abs(np.fft.fft(w)) ** 2
        t = W2[np.arange(-(F - 1), F) % N]  # |S|^2 along a - b = -(F-1) .. F-1
        h = W2[(2 * a0 + np.arange(2 * F - 1)) % N]  # |C|^2 along a + b
        toe = signal.fftconvolve(t[:, None], k, axes=0)[F - 1 : 2 * F - 1]
        han = signal.fftconvolve(h[:, None], k[::-1], axes=0)[F - 1 : 2 * F - 1]
        return np.asarray(toe + han, dtype=float)
    S = covariance_from_variances(w, T, f, f)
    C = covariance_from_variances(w, T, f, -f)
    return np.asarray((np.abs(S) ** 2 + np.abs(C) ** 2) @ k, dtype=float)


def _ml_covariance(
    problem: Problem,
    x: FloatArray,
    idx: NDArray[np.intp],
    hz: FloatArray,
    robust: bool,
    cov: FloatArray,
    info: FloatArray | None = None,
    memo: _Hessians | None = None,
) -> FloatArray:
    """Inverse observed information of the exact likelihood (or its Huber-White sandwich).

    The Hessian of V = -2 ln L is twice the exact observed information (L5) where the
    signal gives its second derivatives (one evaluation); else the Jacobian of its analytic
    gradient (the scores (L2)): its column for a parameter with an analytic score by a
    one-sided difference from the score at the estimate (one score evaluation), for one whose
    score holds a difference (a jitter shape, :meth:`~jitterid.estimation.likelihood
    .ExactLikelihood.differenced_scores`) by a central difference (two), each one pass more
    per differenced parameter, against 2 p^2 passes for second differences of V. ``info``: the
    information at ``x`` already computed (:func:`_search_information`), used instead of
    another evaluation; ``memo``: :func:`_hessian`'s."""
    lik = problem.likelihood
    assert lik is not None
    if lik.exact_information(x):  # (L5) in closed form: no differences at all
        if info is None:
            info = lik.information(x, problem.data.y)
        H = 2 * info[np.ix_(idx, idx)]
    else:
        H = _hessian(memo, idx, lambda: _score_differences(problem, x, idx, hz))
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return cov
    if robust:
        assert problem.likelihood is not None
        g = problem.likelihood.scores(x, problem.data.y)[1][:, idx]
        cov[np.ix_(idx, idx)] = Hinv @ (4 * g.T @ g) @ Hinv.T
    else:
        cov[np.ix_(idx, idx)] = 2 * Hinv
    return cov


def _score_differences(
    problem: Problem,
    x: FloatArray,
    idx: NDArray[np.intp],
    hz: FloatArray,
) -> FloatArray:
    """The Hessian of V = -2 ln L over the parameters ``idx`` by differences (steps ``hz``)
    of its analytic gradient (:func:`_ml_covariance`)."""
    lik = problem.likelihood
    assert lik is not None
    y = problem.data.y
    z0 = x[idx]

    def grad(z: FloatArray) -> FloatArray:
        xz = x.copy()
        xz[idx] = z
        return -2 * lik.scores(xz, y)[1].sum(axis=0)[idx]

    H = np.empty((z0.size, z0.size))
    differenced = set(lik.differenced_scores(x))
    g0 = None
    for k, i in enumerate(idx):
        if i in differenced:
            # central: a differenced score's own O(step) error cancels between the pair
            H[:, k] = finite_diff.derivative(grad, z0, k, problem.bounds[i], h=hz[k])
            continue
        # one-sided differences from the score at x (the likelihood remembers the pass
        # that gave the natural scale): one pass over the nodes instead of two, O(h) with
        # h at most 5 % of a standard error (the score is linear to ~1e-3 over that)
        g0 = grad(z0) if g0 is None else g0
        zi = z0.copy()
        zi[k] += hz[k]
        H[:, k] = (grad(zi) - g0) / hz[k]
    return 0.5 * (H + H.T)
