"""Second-order moments with coloured noise: the jittered noise covariance and Sigma_y.

Samples y_k = s(kT + tau_k) + v(kT + tau_k) + w_k (eq. (1a) with (1c) and a white part w_k
of std sigma_w). The tau_k are i.i.d. and independent of v, so

    Var(v_k) = r_v(0),    Cov(v_k, v_l) = E[r_v((k - l) T + tau_k - tau_l)]  (k != l), (C1)

the autocovariance smoothed by the law of a jitter difference (characteristic function
|phi|^2). The samples of s stay uncorrelated across k (notes, section 2), so

    Sigma_y = diag(Var s_k + sigma_w^2) + Toeplitz(gamma),  gamma(m) = Cov(v_k, v_{k+m}).  (C2)

Modal form. With r_v(t) = sum_j c_j e^{p_j |t|} (:mod:`jitterid.noise.models`, (N1)) and support
[lo, hi] of the jitter, (k - l) T + tau_k - tau_l keeps the sign of k - l once |k - l| >= M0 =
max(1, ceil((hi - lo) / T)). For m >= M0 the expectation factorises over the independent
jitters:

    gamma(m) = sum_j c_j A_j B_j e^{p_j (m T + lo - hi)},
    A_j = E[e^{p_j (tau - lo)}],  B_j = E[e^{p_j (hi - tau)}],                        (C3)

i.e. c_j E[e^{p_j tau}] E[e^{-p_j tau}] e^{p_j m T} (the moment generating function at p_j:
the characteristic function at imaginary argument), written with exponents <= 0 so that no
factor overflows for fast noise poles. gamma is a sum of geometric sequences from lag M0 on:
an ARMA covariance. For the lags 1 <= m < M0 (jitter wider than T, e.g. Gaussian, whose
effective support is +-8.5 sigma) the sign of the lag can flip and (C1) is evaluated exactly by
a double Gauss-Legendre quadrature split at the kink of r_v. With M0 = 1 the lag-0 value of the
geometric sequence exceeds r_v(0) (Jensen), while the smoothed spectrum |phi|^2-weighted has
less power: jitter turns part of the coloured noise into white noise.

Time-domain Gaussian criterion in O(N (n + M0)^2) (n noise poles). Filter the samples by the
AR polynomial a(q) = prod_j (1 - z_j q^{-1}), z_j = e^{p_j T}: the unit lower triangular L_a
with rows a (identity rows for k < n) has det 1 and annihilates the geometric tail, since
sum_i a_i gamma(m - i) = 0 for m - n >= M0. So L_a Sigma_y L_a^T is banded with half-bandwidth
n + M0 - 1 and

    r^T Sigma_y^{-1} r = (L_a r)^T (L_a Sigma_y L_a^T)^{-1} (L_a r),
    ln det Sigma_y = ln det (L_a Sigma_y L_a^T),                                        (C4)

by a banded Cholesky factorisation (LAPACK pbtrf). The DFT covariance R_Y = E Sigma_y E^H
(E the DFT rows of (3)) extends (17) by the Toeplitz term, computed by FFT Toeplitz products.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import cho_solve_banded, cholesky_banded, matmul_toeplitz
from scipy.linalg.lapack import dtbtrs

from .._checks import count, positive, real_array
from .._state import CachesAreNotState
from ..inputs import Input
from ..jitter.laws import JitterLaw, known_law
from ..noise.models import NoiseModel
from ..systems.tf import TransferFunction
from .quadrature import _relative_cuts
from .reference import dtft
from .sample import covariance_from_variances, sample_moments

__all__ = [
    "JitteredAutocovariance",
    "SampleCovariance",
    "autocovariance_derivatives",
    "coloured_dft_covariance",
    "coloured_dft_pseudo_covariance",
    "jittered_autocovariance",
    "sample_covariance",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

_ORDER = 10  # Gauss-Legendre nodes per panel
_CHUNK = 2_000_000  # complex values per block of the near-lag quadrature
_MAX_START = 256  # most lags evaluated by the double quadrature (support / T)
_GL = np.polynomial.legendre.leggauss(_ORDER)  # nodes and weights on [-1, 1], made once
# A support wider than M0 T by this relative amount is treated as M0 T (probability ~1e-9).
_WIDTH_TOL = 1e-9


def _scales(law: JitterLaw, p: ComplexArray) -> tuple[float, float]:
    """(coarse, fine) panel lengths: the pdf's scale and the slowest oscillation of r_v, and
    the fastest time scale 1 / max |p| of the noise."""
    lo, hi = law.support
    coarse = hi - lo
    if law.std > 0:
        coarse = min(coarse, law.std)
    osc = float(np.max(np.abs(p.imag), initial=0.0))
    if osc > 0:
        coarse = min(coarse, 1.0 / osc)
    return coarse, min(coarse, 1.0 / float(np.max(np.abs(p))))


def _offsets(coarse: float, fine: float) -> FloatArray:
    """0, +-fine, +-2 fine, +-4 fine, ... below ``coarse``: geometric panels beside a kink or an
    end, where e^{p |t|} varies on the scale 1/|p| and flattens (or vanishes) further out."""
    steps = fine * 2.0 ** np.arange(max(1, math.ceil(math.log2(coarse / fine))))
    return np.concatenate([[0.0], steps, -steps])


_RULE_MEMO: list[tuple[tuple[object, ...], tuple[FloatArray, FloatArray]]] = []


def _rule(
    law: JitterLaw, coarse: float, anchors: FloatArray, fine: float
) -> tuple[FloatArray, FloatArray]:
    """Nodes and weights w = (GL weight) p(tau): the law's analytic pieces cut to ``coarse``,
    refined geometrically from ``fine`` around each of ``anchors``. Work O(log(coarse/fine))
    per anchor however fast the noise, instead of O((hi - lo) / fine). The last rule is
    kept: gamma and its derivatives at one noise model ask for the same one."""
    key = (law, coarse, fine, anchors.tobytes())
    last = _RULE_MEMO[-1] if _RULE_MEMO else None  # one read: safe if another thread writes
    if last is not None and last[0][1:] == key[1:]:
        try:
            if last[0][0] is law or bool(last[0][0] == law):
                return last[1]
        except (TypeError, ValueError):  # a law whose == is not a plain bool: no reuse
            pass
    out = _new_rule(law, coarse, anchors, fine)
    _RULE_MEMO[:] = [(key, out)]
    return out


def _new_rule(
    law: JitterLaw, coarse: float, anchors: FloatArray, fine: float
) -> tuple[FloatArray, FloatArray]:
    lo, hi = law.support
    edges = np.concatenate(
        [_relative_cuts(law, coarse), (anchors[:, None] + _offsets(coarse, fine)).ravel()]
    )
    edges = np.unique(np.clip(edges, lo, hi))
    x, wx = _GL
    half = 0.5 * np.diff(edges)[:, None]
    nodes = (0.5 * (edges[:-1, None] + edges[1:, None]) + half * x).ravel()
    return nodes, (half * wx).ravel() * law.pdf(np.clip(nodes, lo, hi))


@dataclass(frozen=True)
class JitteredAutocovariance(CachesAreNotState):
    """gamma(m) = Cov(v_k, v_{k+m}) of jittered samples of v, eqs. (C1) and (C3).

    Attributes
    ----------
    T : float
        Nominal sampling interval (s).
    near : ndarray, shape (M0,)
        gamma(0..M0-1): r_v(0) and the lags where the jitter can reverse the order of samples.
    weights, ratios : ndarray of complex
        gamma(m) = Re sum_j weights_j ratios_j^(m - M0) for m >= M0; ratios_j = exp(p_j T).

    Examples
    --------
    >>> import jitterid as ji
    >>> H = ji.NoiseModel(ji.TransferFunction([1.0], [1.0, 2.0]))
    >>> gamma = ji.jittered_autocovariance(H, ji.Uniform(0.02), T=0.1)
    >>> isinstance(gamma, ji.JitteredAutocovariance), gamma.T
    (True, 0.1)
    >>> round(float(gamma.sequence(1)[0]), 6)  # r_v(0) = 1 / (2 * 2)
    0.25
    """

    T: float
    near: FloatArray
    weights: ComplexArray
    ratios: ComplexArray

    @property
    def start(self) -> int:
        """M0, the first lag of the geometric tail."""
        return int(self.near.size)

    def __call__(self, lags: ArrayLike) -> FloatArray:
        """gamma(|m|) at integer lags ``m`` (any shape)."""
        m = np.abs(np.asarray(lags))
        if m.dtype.kind not in "iu":
            raise TypeError(f"lags must be integers; got dtype {m.dtype}")
        tail = np.maximum(m - self.start, 0)[..., None]
        geo = (self.ratios**tail) @ self.weights if self.ratios.size else np.zeros(m.shape)
        near = self.near[np.minimum(m, self.start - 1)]
        return np.asarray(np.where(m < self.start, near, np.real(geo)), dtype=float)

    def sequence(self, n: int) -> FloatArray:
        """gamma(0), ..., gamma(n - 1).

        Parameters
        ----------
        n : int
            Number of lags.
        """
        return self(np.arange(count(n, "n", minimum=0)))

    def spectrum(self, f: ArrayLike) -> FloatArray:
        """Spectral density of the sampled noise per Hz, T sum_m gamma(m) e^{-i 2 pi f m T}.

        The geometric tail is summed in closed form: sum_{m >= M0} z^(m - M0) e^{-i w m} =
        e^{-i w M0} / (1 - z e^{-i w}), w = 2 pi f T.

        Parameters
        ----------
        f : array_like
            Frequencies in Hz.
        """
        ff = real_array(f, "f")
        e = np.exp(-2j * np.pi * ff * self.T)[..., None]
        m = np.arange(1, self.start)
        one_sided = (e[..., 0:1] ** m) @ self.near[1:] if m.size else np.zeros(ff.shape)
        if self.ratios.size:
            tail = e**self.start / (1.0 - self.ratios * e)
            one_sided = one_sided + tail @ self.weights
        return np.asarray(self.T * (self.near[0] + 2.0 * np.real(one_sided)), dtype=float)

    @cached_property
    def ar(self) -> FloatArray:
        """Coefficients of a(q) = prod_j (1 - ratios_j q^-1), which annihilates the tail (C4)."""
        return np.real(np.poly(self.ratios)) if self.ratios.size else np.ones(1)


def jittered_autocovariance(
    noise: NoiseModel, jitter: JitterLaw, T: float
) -> JitteredAutocovariance:
    """The autocovariance of v(kT + tau_k), eqs. (C1) and (C3).

    Parameters
    ----------
    noise : NoiseModel
        The continuous-time noise v(t).
    jitter : JitterLaw
        Law of the i.i.d. jitter (``NoJitter()`` gives r_v(m T), the uniformly sampled noise).
    T : float
        Nominal sampling interval (s).

    Returns
    -------
    JitteredAutocovariance

    Examples
    --------
    >>> import jitterid as ji
    >>> H = ji.NoiseModel(ji.TransferFunction([1.0], [1.0, 2.0]))
    >>> gamma = ji.jittered_autocovariance(H, ji.Uniform(0.02), T=0.1)
    >>> gamma.sequence(3).round(4).tolist()
    [0.25, 0.2048, 0.1677]
    """
    if not isinstance(noise, NoiseModel):
        raise TypeError(f"noise must be a NoiseModel; got {type(noise).__name__}")
    jitter = known_law(jitter)
    T = positive(T, "T")
    c, p = noise.modes
    lo, hi = (float(v) for v in jitter.support)
    start = max(1, math.ceil((hi - lo) / T - _WIDTH_TOL))
    near = np.empty(start)
    near[0] = noise.variance
    if start > _MAX_START:
        raise ValueError(
            f"jitter: its support [{lo:g}, {hi:g}] spans {start} sampling intervals T = {T:g}; "
            f"at most {_MAX_START} are supported (samples that far out of order are not jitter)"
        )
    if hi <= lo:  # a point mass: tau_k - tau_l = 0
        a = b = np.ones(p.size, complex)
    else:
        coarse, fine = _scales(jitter, p)
        # e^{p (tau - lo)} and e^{p (hi - tau)} vary fastest at the ends of the support.
        nodes, w = _rule(jitter, coarse, np.array([lo, hi]), fine)
        a = np.exp(np.outer(p, nodes - lo)) @ w
        b = np.exp(np.outer(p, hi - nodes)) @ w
        for m in range(1, start):
            near[m] = _near_lag(noise, jitter, m * T, coarse, fine)
    weights = c * a * b * np.exp(p * (start * T + lo - hi))
    return JitteredAutocovariance(T, near, weights, np.exp(p * T))


def autocovariance_derivatives(
    noise: NoiseModel, jitter: JitterLaw, T: float, dc: ComplexArray, dp: ComplexArray, n: int
) -> tuple[FloatArray, FloatArray] | None:
    """d gamma(0..n-1) and d(ar) of (C1)-(C3) along mode derivatives (dc, dp) (shape (P, J),
    e.g. :meth:`RationalNoise.mode_derivatives`), in closed form; None where the jitter
    spans more than T (M0 > 1: near lags by quadrature, no closed form).

    With M0 = 1: gamma(0) = Re sum c_j, gamma(m) = Re sum W_j z_j^(m - 1) (m >= 1),
    W = c A B E, E = e^{p (T + lo - hi)}, z = e^{p T}, so
    dW = W (dc / c) + c (A_p B + A B_p) E dp + W (T + lo - hi) dp and
    d gamma(m) = Re sum (dW_j + (m - 1) T W_j dp_j) z_j^(m - 1),
    with A_p = E[(tau - lo) e^{p (tau - lo)}], B_p = E[(hi - tau) e^{p (hi - tau)}] on the
    nodes of A and B. ar = poly(z): d ar = -sum_j [0, poly(z without z_j)] T z_j dp_j.
    """
    c, p = noise.modes
    lo, hi = (float(v) for v in jitter.support)
    start = max(1, math.ceil((hi - lo) / T - _WIDTH_TOL))
    if start > 1:
        return None
    if hi <= lo:
        a = b = np.ones(p.size, complex)
        ap = bp = np.zeros(p.size, complex)
    else:
        coarse, fine = _scales(jitter, p)
        nodes, w = _rule(jitter, coarse, np.array([lo, hi]), fine)
        ea, eb = np.exp(np.outer(p, nodes - lo)), np.exp(np.outer(p, hi - nodes))
        a, b = ea @ w, eb @ w
        ap, bp = (ea * (nodes - lo)) @ w, (eb * (hi - nodes)) @ w
    e = np.exp(p * (T + lo - hi))
    W = c * a * b * e
    dW = dc * (a * b * e) + dp * (c * (ap * b + a * bp) * e + W * (T + lo - hi))  # (P, J)
    m = np.arange(1, n)
    z = np.exp(p * T)
    powers = z[None, :] ** (m[:, None] - 1)  # (n - 1, J)
    dgam = np.empty((dc.shape[0], n))
    dgam[:, 0] = np.real(dc.sum(axis=1))
    dgam[:, 1:] = np.real(dW @ powers.T + (dp * W * T) @ (powers * (m[:, None] - 1)).T)
    J = p.size
    dar = np.zeros((dc.shape[0], J + 1), complex)
    for j in range(J):
        rest = np.poly(np.delete(z, j)) if J > 1 else np.ones(1)
        dar[:, 1:] -= np.outer(T * z[j] * dp[:, j], rest)
    return dgam, np.real(dar)


def _near_lag(noise: NoiseModel, law: JitterLaw, lag: float, coarse: float, fine: float) -> float:
    """E[r_v(lag + tau - tau')] by a double quadrature split where lag + tau - tau' = 0.

    Inner integral R(x) = E[r_v(tau - x)] at x = tau' - lag, with panels refined around the
    kink tau = x of r_v; the outer one over tau' refined where x crosses a knot of the pdf
    (where R varies on the noise's time scale).
    """
    c, p = noise.modes
    lo, hi = law.support
    knots = np.asarray(law.breakpoints(), dtype=float)
    outer, wo = _rule(law, coarse, knots + lag, fine)
    base = _relative_cuts(law, coarse)
    offs = _offsets(coarse, fine)
    x, wx = _GL
    total = 0.0
    width = base.size + offs.size
    step = max(1, _CHUNK // (width * _ORDER * max(1, p.size)))
    for i0 in range(0, outer.size, step):
        xs = outer[i0 : i0 + step] - lag
        # Clipped duplicates give zero-length panels, which weigh nothing.
        pts = np.concatenate(
            [np.broadcast_to(base, (xs.size, base.size)), np.clip(xs[:, None] + offs, lo, hi)],
            axis=1,
        )
        edges = np.sort(pts, axis=1)
        half = 0.5 * np.diff(edges, axis=1)[..., None]
        t = 0.5 * (edges[:, :-1, None] + edges[:, 1:, None]) + half * x
        w = half * wx * law.pdf(np.clip(t, lo, hi))
        dist = np.abs(t - xs[:, None, None])[..., None]
        r = np.real(np.exp(p * dist) @ c)
        total += float(np.sum(wo[i0 : i0 + step] * np.sum(w * r, axis=(1, 2))))
    return total


def _stencil(a: FloatArray, N: int, derivative: bool = False) -> FloatArray:
    """Rows of L_a for AR coefficients ``a``: S[k, i] multiplies y_{k-i}; rows k < n are
    identity rows (zero rows for a ``derivative`` of the coefficients)."""
    n = a.size - 1
    S = np.zeros((N, n + 1))
    S[n:] = a
    S[: min(n, N)] = 0.0
    if not derivative:
        S[: min(n, N), 0] = 1.0
    return S


def _apply(S: FloatArray, r: FloatArray) -> FloatArray:
    """sum_i S[k, i] r[k - i] for r of shape (N,) or (N, p)."""
    out = S[:, 0, None] * r if r.ndim == 2 else S[:, 0] * r
    for i in range(1, S.shape[1]):
        coef = S[i:, i, None] if r.ndim == 2 else S[i:, i]
        out[i:] += coef * r[:-i]
    return out


def _band(SL: FloatArray, SR: FloatArray, gam: FloatArray, D: FloatArray, width: int) -> FloatArray:
    """Band of L_1 (diag(d) + Toeplitz(gam)) L_2^T, batched: (P, width + 1, N) with
    out[p, b, k - b] = entry (k, k - b). L_1, L_2 by their stencils (:func:`_stencil`),
    shape (N, n + 1) or (P, N, n + 1); gam shape (L,) or (P, L); D shape (P, N)."""
    SL3, SR3 = (S if S.ndim == 3 else S[None] for S in (SL, SR))
    G2 = gam if gam.ndim == 2 else gam[None]
    P = max(SL3.shape[0], SR3.shape[0], G2.shape[0], D.shape[0])
    N, n1 = SL3.shape[1:]
    i = np.arange(n1)
    out = np.zeros((P, width + 1, N))
    toeplitz = bool(np.any(G2))
    for b in range(width + 1):
        L = N - b
        A, B = SL3[:, b:], SR3[:, :L]  # rows k and k - b
        if toeplitz:
            G = G2[:, np.abs(b - i[:, None] + i[None, :])]  # (p, n1, n1)
            for ii in range(n1):  # n1 is small: products beat einsum's generic loop
                for jj in range(n1):
                    out[:, b, :L] += A[:, :, ii] * B[:, :, jj] * G[:, ii, jj, None]
        k = np.arange(b, N)
        for ii in range(b, n1):  # the diagonal d enters where k - i = l - j
            out[:, b, :L] += (A[:, :, ii] * B[:, :, ii - b]) * D[:, k - ii]
    return out


@dataclass(frozen=True, eq=False)
class SampleCovariance(CachesAreNotState):
    """Sigma_y = diag(d) + Toeplitz(gamma) of eq. (C2), with the O(N) operations of (C4).

    Parameters
    ----------
    d : ndarray, shape (N,)
        The diagonal part: Var s_k + sigma_w^2 (gamma(0) is added by the Toeplitz part).
    gamma : JitteredAutocovariance or None
        The coloured noise; None for white noise only (the OE structure).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.zoh_input([1.0, -1.0] * 20, T=0.1)
    >>> S = ji.sample_covariance(G, u, ji.Uniform(0.02), T=0.1, N=40, noise_std=0.01)
    >>> r = np.ones(40)
    >>> bool(np.allclose(S.dense() @ S.solve(r), r))
    True
    """

    d: FloatArray
    gamma: JitteredAutocovariance | None

    @property
    def N(self) -> int:
        return int(self.d.size)

    @cached_property
    def _stencil(self) -> FloatArray:
        """Rows of L_a: S[k, i] multiplies y_{k-i}; identity rows for k < n."""
        a = self.gamma.ar if self.gamma is not None else np.ones(1)
        return _stencil(a, self.N)

    @property
    def width(self) -> int:
        """Half-bandwidth of B = L_a Sigma_y L_a^T, (C4)."""
        n = self._stencil.shape[1] - 1
        start = self.gamma.start if self.gamma is not None else 1
        return min(n + start - 1, self.N - 1)

    @cached_property
    def band(self) -> FloatArray:
        """B = L_a Sigma_y L_a^T in lower band storage: band[b, j] = B[j + b, j]."""
        S = self._stencil
        n = S.shape[1] - 1
        gam = (
            self.gamma.sequence(self.width + n + 1)
            if self.gamma is not None
            else np.zeros(self.width + n + 1)
        )
        return _band(S, S, gam, self.d[None], self.width)[0]

    @cached_property
    def _factor(self) -> tuple[FloatArray, float]:
        """Banded Cholesky factor C of B = L_a Sigma L_a^T (lower storage) and ln det Sigma."""
        cb = cholesky_banded(self.band, lower=True)
        return cb, float(2.0 * np.sum(np.log(cb[0])))

    @property
    def logdet(self) -> float:
        """ln det Sigma_y (raises LinAlgError if Sigma_y is not positive definite)."""
        return self._factor[1]

    def _filter(self, r: FloatArray) -> FloatArray:
        return _apply(self._stencil, r)

    def _filter_t(self, u: FloatArray) -> FloatArray:
        S = self._stencil
        out = S[:, 0, None] * u if u.ndim == 2 else S[:, 0] * u
        for i in range(1, S.shape[1]):
            coef = S[i:, i, None] if u.ndim == 2 else S[i:, i]
            out[:-i] += coef * u[i:]
        return out

    def filter(self, r: ArrayLike) -> FloatArray:
        """L_a r for r of shape (N,) or (N, p): the AR filter of (C4)."""
        return self._filter(np.asarray(r, dtype=float))

    def dfilter(self, dar: FloatArray, r: ArrayLike) -> FloatArray:
        """(dL_a) r for a derivative ``dar`` of the AR coefficients (identity rows fixed)."""
        return _apply(_stencil(dar, self.N, derivative=True), np.asarray(r, dtype=float))

    def band_solve(self, u: ArrayLike) -> FloatArray:
        """B^{-1} u, B = L_a Sigma_y L_a^T (so Sigma_y^{-1} r = L_a^T B^{-1} L_a r)."""
        return np.asarray(
            cho_solve_banded((self._factor[0], True), np.asarray(u, dtype=float)), dtype=float
        )

    def solve(self, r: ArrayLike) -> FloatArray:
        """Sigma_y^{-1} r for r of shape (N,) or (N, p), by (C4)."""
        rr = np.asarray(r, dtype=float)
        z = cho_solve_banded((self._factor[0], True), self._filter(rr))
        return self._filter_t(np.asarray(z, dtype=float))

    def whiten(self, r: ArrayLike) -> FloatArray:
        """C^{-1} L_a r, with C C^T = L_a Sigma_y L_a^T: ||whiten(r)||^2 = r^T Sigma_y^{-1} r."""
        return self._triangular(self._filter(np.asarray(r, dtype=float)), "N")

    def colour(self, xi: ArrayLike) -> FloatArray:
        """L_a^T C^{-T} xi: for xi ~ N(0, I) a draw of N(0, Sigma_y^{-1})."""
        return self._filter_t(self._triangular(np.asarray(xi, dtype=float), "T"))

    def _triangular(self, r: FloatArray, trans: str) -> FloatArray:
        rhs = r[:, None] if r.ndim == 1 else r
        x, info = dtbtrs(self._factor[0], rhs, uplo="L", trans=trans)
        if info != 0:
            raise np.linalg.LinAlgError(f"dtbtrs failed (info {info})")
        return np.asarray(x[:, 0] if r.ndim == 1 else x, dtype=float)

    @cached_property
    def band_inverse(self) -> FloatArray:
        """B^{-1} on the band of B (lower storage), by Takahashi's recursion on C: O(N w^2).

        With Z = B^{-1} = C^{-T} C^{-1}, Z C = C^{-T} is upper triangular with diagonal
        1 / C_jj, which gives column j of Z's band from the columns to its right. Traces
        tr(B^{-1} dB) of banded dB need no more of Z.
        """
        cb = self._factor[0]
        w, N = cb.shape[0] - 1, cb.shape[1]
        if w == 1:  # tridiagonal B (first-order noise, jitter within T): scalar recursion
            c0, c1 = cb[0].tolist(), cb[1].tolist()
            z0, z1 = [0.0] * N, [0.0] * N
            z0[N - 1] = 1.0 / c0[N - 1] ** 2
            for j in range(N - 2, -1, -1):
                inv = 1.0 / c0[j]
                z1[j] = -inv * c1[j] * z0[j + 1]
                z0[j] = inv * (inv - c1[j] * z1[j])
            return np.array([z0, z1])
        c = cb.T.tolist()  # c[j][r] = C[j + r, j]
        z = [[0.0] * (w + 1) for _ in range(N)]  # z[j][b] = Z[j + b, j]
        for j in range(N - 1, -1, -1):
            cj, zj = c[j], z[j]
            inv = 1.0 / cj[0]
            top = min(w, N - 1 - j)
            for b in range(top, 0, -1):
                acc = 0.0
                for r in range(1, top + 1):
                    acc += cj[r] * (z[j + r][b - r] if b >= r else z[j + b][r - b])
                zj[b] = -inv * acc
            acc = 0.0
            for r in range(1, top + 1):
                acc += cj[r] * zj[r]
            zj[0] = inv * (inv - acc)
        return np.array(z).T

    def derivative_band(
        self, dd: FloatArray, dgamma: FloatArray | None = None, dar: FloatArray | None = None
    ) -> FloatArray:
        """dB for dSigma_y = diag(dd) + Toeplitz(dgamma) and d(ar) = ``dar``, band storage,
        for P directions at once: dd (P, N), dgamma (P, >= w + n + 1) or None, dar (P, n + 1)
        or None; returns (P, w + 1, N).

        B(p) = L_a(p) Sigma_y(p) L_a(p)^T is banded for every parameter p (the tail of gamma
        is annihilated at every p), so dB = dL Sigma L^T + L Sigma dL^T + L dSigma L^T is
        banded too, though its first two terms are not: only their band is formed.
        """
        S, w = self._stencil, self.width
        n = S.shape[1] - 1
        D = np.atleast_2d(dd)
        dg = (
            np.zeros(w + n + 1)
            if dgamma is None
            else np.asarray(dgamma, dtype=float)[:, : w + n + 1]
        )
        if dar is None or not np.any(dar):
            return _band(S, S, dg, D, w)
        # L dSigma L^T, dL Sigma L^T and L Sigma dL^T in one batched pass (3P rows): the same
        # products element by element as three passes, a third of the Python overhead
        P = D.shape[0]
        dS = np.zeros((P, *S.shape))
        dS[:, n:] = np.asarray(dar, dtype=float)[:, None, :]
        gam = self.gamma.sequence(w + n + 1) if self.gamma is not None else np.zeros(w + n + 1)
        SS = np.broadcast_to(S, dS.shape)
        G = np.broadcast_to(dg, (P, w + n + 1))
        parts = _band(
            np.concatenate([SS, dS, SS]),
            np.concatenate([SS, SS, dS]),
            np.concatenate([G, np.broadcast_to(gam, (2 * P, w + n + 1))]),
            np.concatenate([D, np.broadcast_to(self.d, (2 * P, self.N))]),
            w,
        )
        return parts[:P] + (parts[P : 2 * P] + parts[2 * P :])

    def matmul(self, x: ArrayLike) -> FloatArray:
        """Sigma_y x for x of shape (N,) or (N, p), by an FFT Toeplitz product."""
        xx = np.asarray(x, dtype=float)
        dd = self.d[:, None] if xx.ndim == 2 else self.d
        if self.gamma is None:
            return dd * xx
        g = self.gamma.sequence(self.N)
        return dd * xx + np.asarray(matmul_toeplitz((g, g), xx), dtype=float).reshape(xx.shape)

    def dense(self) -> FloatArray:
        """Sigma_y as an N x N matrix (for checks; O(N^2) memory)."""
        return self.matmul(np.eye(self.N))

    def dft_diagonal(self, T: float, f: ArrayLike) -> FloatArray:
        """R_Y(f, f) only, in O(N log N): sum_k d_k + sum_m (N - |m|) gamma(m) e^{-i 2 pi f m T}.

        This is what the reduced AsML (23) weights by; with coloured noise it is no longer
        the same at every frequency.
        """
        g = None if self.gamma is None else self.gamma.sequence(self.N)
        return toeplitz_dft_diagonal(self.d, g, T, np.atleast_1d(real_array(f, "f")))

    def dft(
        self, T: float, f: ArrayLike, psi: ArrayLike | None = None, sign: float = 1.0
    ) -> ComplexArray:
        """R_Y(f, psi) = E Sigma E^H (sign 1) or the pseudo-covariance C_Y (sign -1), (17), (C2).

        Rows over ``f``, columns over ``psi`` (default ``f``); any frequencies in Hz.
        """
        ff = np.atleast_1d(real_array(f, "f"))
        other = sign * (ff if psi is None else np.atleast_1d(real_array(psi, "psi")))
        g = None if self.gamma is None else self.gamma.sequence(self.N)
        return toeplitz_dft(self.d, g, T, ff, other)


def toeplitz_dft_diagonal(
    d: FloatArray, g: FloatArray | None, T: float, f: FloatArray
) -> FloatArray:
    """E M E^H on the diagonal for M = diag(d) + Toeplitz(g) (g = gamma(0..N-1) or None):
    :meth:`SampleCovariance.dft_diagonal`, and its derivatives (M linear in d, g)."""
    total = float(np.sum(d))
    if g is None:
        return np.full(f.shape, total)
    q = (d.size - np.arange(d.size)) * g
    return np.asarray(total + 2.0 * dtft(q, T, f).real - q[0], dtype=float)


def toeplitz_products(g: FloatArray, x: FloatArray) -> FloatArray:
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


def toeplitz_dft(
    d: FloatArray, g: FloatArray | None, T: float, f: FloatArray, other: FloatArray
) -> ComplexArray:
    """E_f M E_other^H for M = diag(d) + Toeplitz(g): :meth:`SampleCovariance.dft`, and its
    derivatives (M linear in d, g)."""
    g0 = g[0] if g is not None else 0.0
    out = covariance_from_variances(d + g0, T, f, other)
    if g is None or d.size < 2:
        return out
    g = np.array(g, dtype=float)
    g[0] = 0.0
    k = np.arange(d.size) * T
    eh = np.exp(2j * np.pi * np.outer(k, other))  # E_psi^H, N x F
    x = np.asarray(matmul_toeplitz((g.astype(complex), g.astype(complex)), eh))
    return out + dtft(x.T, T, f).T


def sample_covariance(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    noise_std: float,
    noise_model: NoiseModel | None = None,
) -> SampleCovariance:
    """Sigma_y = Cov(y_0..y_{N-1}) of eq. (C2) for a known system, jitter and noise.

    Parameters
    ----------
    system, u, jitter, T, N
        As in :func:`jitterid.dft_covariance` (T in s).
    noise_std : float
        Std of the white part w_k (>= 0).
    noise_model : NoiseModel, optional
        The coloured noise v(t); None for white noise only (then Sigma_y is Lemma 2's
        diagonal, notes section 2).

    Returns
    -------
    SampleCovariance

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.zoh_input([1.0, -1.0] * 20, T=0.1)
    >>> S = ji.sample_covariance(G, u, ji.Uniform(0.02), T=0.1, N=40, noise_std=0.01)
    >>> S.N, S.dense().shape, bool(np.allclose(S.dense(), S.dense().T))
    (40, (40, 40), True)
    """
    if noise_model is not None and not isinstance(noise_model, NoiseModel):
        raise TypeError(
            f"noise_model must be a NoiseModel or None; got {type(noise_model).__name__}"
        )
    T = positive(T, "T")
    N = count(N, "N", minimum=1)
    white = positive(noise_std, "noise_std", allow_zero=True) ** 2
    var = sample_moments(system.response(u), jitter, T, N).var
    gamma = None if noise_model is None else jittered_autocovariance(noise_model, jitter, T)
    return SampleCovariance(var + white, gamma)


def coloured_dft_covariance(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
    noise_std: float,
    noise_model: NoiseModel | None = None,
    psi: ArrayLike | None = None,
) -> ComplexArray:
    """R_Y(f, psi) = Cov(Y_d(f), Y_d(psi)) with coloured noise: (17)-(19) extended by (C2).

    :func:`jitterid.dft_covariance` plus the Toeplitz noise term E Gamma E^H; equal to it
    for ``noise_model=None``. Rows over ``f``, columns over ``psi`` (default ``f``).

    Parameters
    ----------
    system, u, jitter, T, N, f
        As in :func:`jitterid.dft_covariance` (T in s, f in Hz).
    noise_std : float
        Standard deviation of the white measurement noise (>= 0).
    noise_model : NoiseModel, optional
        The coloured noise v(t); None for white noise only.
    psi : array_like, optional
        Column frequencies in Hz; default ``f``.

    Returns
    -------
    ndarray of complex, shape (len(f), len(psi))

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.zoh_input([1.0, -1.0] * 20, T=0.1)
    >>> H = ji.NoiseModel(ji.TransferFunction([0.1], [1.0, 2.0]))
    >>> f = np.array([0.25, 0.5])
    >>> R = ji.coloured_dft_covariance(G, u, ji.Uniform(0.02), 0.1, 40, f, 0.01, noise_model=H)
    >>> R.shape, bool(np.allclose(R, R.conj().T)), bool(np.all(R.diagonal().real > 0))
    ((2, 2), True, True)
    """
    cov = sample_covariance(system, u, jitter, T, N, noise_std, noise_model)
    return cov.dft(T, f, psi, sign=1.0)


def coloured_dft_pseudo_covariance(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
    noise_std: float,
    noise_model: NoiseModel | None = None,
    psi: ArrayLike | None = None,
) -> ComplexArray:
    """C_Y(f, psi) = E[(Y(f) - mu(f))(Y(psi) - mu(psi))] with coloured noise, (C2).

    Parameters
    ----------
    system, u, jitter, T, N, f
        As in :func:`jitterid.dft_covariance` (T in s, f in Hz).
    noise_std : float
        Standard deviation of the white measurement noise (>= 0).
    noise_model : NoiseModel, optional
        The coloured noise v(t); None for white noise only.
    psi : array_like, optional
        Column frequencies in Hz; default ``f``.

    Returns
    -------
    ndarray of complex, shape (len(f), len(psi))

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.zoh_input([1.0, -1.0] * 20, T=0.1)
    >>> H = ji.NoiseModel(ji.TransferFunction([0.1], [1.0, 2.0]))
    >>> f = np.array([0.25, 0.5])
    >>> law = ji.Uniform(0.02)
    >>> C = ji.coloured_dft_pseudo_covariance(G, u, law, 0.1, 40, f, 0.01, noise_model=H)
    >>> C.shape, bool(np.allclose(C, C.T))
    ((2, 2), True)
    """
    cov = sample_covariance(system, u, jitter, T, N, noise_std, noise_model)
    return cov.dft(T, f, psi, sign=-1.0)
