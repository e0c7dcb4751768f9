"""The paper's frequency-domain route: DTFT, Dirichlet kernel and the stochastic window.

This module implements Sections 2-4 of Eng & Gustafsson, "Identification with Stochastic
Sampling Time Jitter", literally, so that it can serve as the reference against which faster
time-domain implementations are tested.  Samples are ``y_k = s(kT + tau_k) + v_k``,
``k = 0..N-1``, with ``tau_k`` i.i.d. with characteristic function (paper's footnote 3)

    phi(f) = E[exp(-i 2 pi f tau)]            (f in Hz),

and ``v_k`` white with standard deviation ``sigma_v``.

Contents
--------
* :func:`dtft` -- eq. (3) at an arbitrary set of frequencies.
* :func:`dirichlet` -- the normalized Dirichlet kernel ``d_N`` of eq. (7).
* :func:`stochastic_window` -- the stochastic window ``W(f, psi)`` of eq. (12).
* :func:`mean_window` -- Lemma 1, ``mu_W(f, psi) = phi(-psi) d_N(f - psi)``.
* :func:`window_second_moment` -- Lemma 2, ``E[W(f, eta) W*(psi, zeta)] = Phi^T D_N``.
* :func:`window_covariance` -- eq. (19), ``R_W = E[W W*] - mu_W mu_W*``.
* :func:`expected_dft_lines`, :func:`dft_covariance_lines` -- eqs. (13)/(14b) and (17)-(19)
  for line spectra (sums of cisoids).
* :func:`expected_dft_integral` -- eq. (14b) for a continuous spectrum ``S_c``, by
  trapezoidal quadrature over ``psi``; :func:`integral_grid_size` picks the grid.

Jitter laws are duck-typed: any object with a vectorised method ``cf(f)`` returning
``phi(f)`` (the paper's sign convention) works, e.g. the laws of :mod:`jitterid.jitter.laws`.

Notes
-----
The printed Lemma 2 (from a scanned PDF) was re-derived from its proof.  With
``F = f - eta`` and ``G = psi - zeta``::

    Sigma_1 = phi(-eta) phi(zeta) sum_k sum_{l<k} exp(-i 2 pi (F k - G l) T)
    Sigma_2 = phi(zeta - eta) d_N(F - G)
    Sigma_3 = phi(-eta) phi(zeta) sum_k sum_{l<k} exp(-i 2 pi (-G k + F l) T)

which is exactly ``Phi(eta, zeta)^T D_N(F, G)`` with the printed
``Phi(f, psi) = (phi(-f) phi(psi), phi(psi - f), phi(-f) phi(psi))`` and the printed ``D_N``;
the printed form needed no correction.  Adding and subtracting the ``l = k`` terms gives the
equivalent closed form used as a cross-check in the tests::

    E[W(f, eta) W*(psi, zeta)] = phi(-eta) phi(zeta) d_N(F) conj(d_N(G))
                                 + (phi(zeta - eta) - phi(-eta) phi(zeta)) d_N(F - G)
    R_W(f, eta, psi, zeta)     = (phi(zeta - eta) - phi(-eta) phi(zeta)) d_N(F - G).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from jitterid._checks import count, positive, real_array

__all__ = [
    "SupportsCF",
    "dft_covariance_lines",
    "dirichlet",
    "dtft",
    "expected_dft_integral",
    "expected_dft_lines",
    "integral_grid_size",
    "mean_window",
    "stochastic_window",
    "window_covariance",
    "window_second_moment",
]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

#: Upper bound on the number of complex elements of any temporary array (about 64 MiB).
_CHUNK_ELEMENTS = 1 << 22


class SupportsCF(Protocol):
    """What this module needs from a jitter law: its characteristic function.

    ``cf(f)`` must be vectorised and return ``phi(f) = E[exp(-i 2 pi f tau)]`` (the paper's
    sign convention, footnote 3) with the same shape as ``f``.
    """

    def cf(self, f: Any) -> Any:  # pragma: no cover - protocol
        """Characteristic function ``phi(f) = E[exp(-i 2 pi f tau)]``."""
        ...


# --------------------------------------------------------------------------------------
# validation helpers local to this module
# --------------------------------------------------------------------------------------


def _finite_array(x: ArrayLike, name: str) -> NDArray[Any]:
    """Return ``x`` as a finite real or complex array, or raise naming ``name``."""
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:  # pragma: no cover - ragged input etc.
        raise TypeError(f"{name} must be an array of numbers; got {type(x).__name__}") from exc
    if arr.dtype.kind not in "biufc":
        raise TypeError(
            f"{name} must be an array of real or complex numbers; got dtype {arr.dtype}"
        )
    arr = arr.astype(complex if arr.dtype.kind == "c" else float)
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))
        raise ValueError(
            f"{name} contains {bad.size} NaN or infinite value(s) (first at flat index {bad[0]}); "
            "remove or interpolate them before calling"
        )
    return arr


def _cf(jitter: SupportsCF, f: FloatArray, name: str = "jitter") -> ComplexArray:
    """Evaluate ``jitter.cf`` on ``f`` and check what comes back."""
    cf = getattr(jitter, "cf", None)
    if not callable(cf):
        raise TypeError(
            f"{name} must be a jitter law with a vectorised method cf(f) returning "
            f"E[exp(-i 2 pi f tau)]; got {type(jitter).__name__}"
        )
    val = np.asarray(cf(f))
    if val.shape != f.shape:
        try:
            val = np.broadcast_to(val, f.shape)
        except ValueError:
            raise ValueError(
                f"{name}.cf(f) returned shape {val.shape} for f of shape {f.shape}; "
                "cf must be vectorised (same shape out as in)"
            ) from None
    val = val.astype(complex)
    if not np.all(np.isfinite(val)):
        raise ValueError(f"{name}.cf(f) returned NaN or infinite values")
    return val


def _broadcast(arrays: dict[str, FloatArray]) -> list[FloatArray]:
    """Broadcast named arrays together, or raise naming them."""
    try:
        return list(np.broadcast_arrays(*arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k} {v.shape}" for k, v in arrays.items())
        raise ValueError(
            f"{', '.join(arrays)} must broadcast to a common shape; got {shapes}"
        ) from None


def _unit_phasors(x: FloatArray, N: int, sign: float) -> ComplexArray:
    """``exp(sign * i 2 pi x k)`` for ``k = 0..N-1``, shape ``x.shape + (N,)``.

    ``x`` is a frequency times ``T`` (cycles per sample).  Since ``k`` is an integer only the
    fractional part of ``x`` matters, and the product ``k * frac(x)`` is reduced modulo 1
    before the exponential, so large ``f T`` lose no accuracy.
    """
    r = x - np.round(x)
    k = np.arange(N, dtype=float)
    cycles = np.mod(r[..., None] * k, 1.0)
    return np.exp(sign * 2j * np.pi * cycles)


# --------------------------------------------------------------------------------------
# eq. (3) and eq. (7)
# --------------------------------------------------------------------------------------


def dtft(y: ArrayLike, T: float, f: ArrayLike) -> ComplexArray:
    """Discrete-time Fourier transform of uniformly indexed samples, eq. (3).

    ``Y_d(f) = sum_{k=0}^{N-1} y_k exp(-i 2 pi f k T)``, evaluated at an arbitrary set of
    frequencies (not restricted to the DFT grid ``n / (N T)``).

    Parameters
    ----------
    y : array_like, shape (..., N)
        Samples, real or complex, along the last axis; leading axes are batches (e.g. Monte
        Carlo realisations).
    T : float
        Nominal sampling interval (s), > 0.
    f : array_like
        Frequencies in Hz, any shape.

    Returns
    -------
    ndarray of complex, shape ``y.shape[:-1] + f.shape``
        ``Y_d(f)``.  Work is chunked over ``f`` so that no temporary exceeds a few tens of
        MiB.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> Y = jid.dtft([1.0, 1.0, 1.0, 1.0], T=0.5, f=[0.0, 0.5])
    >>> np.abs(Y).round(6).tolist()
    [4.0, 0.0]
    """
    y_arr = _finite_array(y, "y")
    if y_arr.ndim < 1 or y_arr.shape[-1] < 1:
        raise ValueError(f"y must have at least one sample along its last axis; got {y_arr.shape}")
    T = positive(T, "T")
    f_arr = real_array(f, "f")
    N = y_arr.shape[-1]
    batch = y_arr.shape[:-1]
    ff = f_arr.ravel()
    bins = ff * (N * T)
    on_grid = np.round(bins)
    if ff.size and np.all(np.abs(bins - on_grid) < 1e-9):
        # Every frequency is a DFT bin n / (N T): one FFT, O(N log N), no N x F matrix.
        spec = np.fft.fft(y_arr, axis=-1)
        return spec[..., np.mod(on_grid.astype(np.int64), N)].reshape(batch + f_arr.shape)
    out = np.empty((*batch, ff.size), dtype=complex)
    step = max(1, _CHUNK_ELEMENTS // N)
    real = not np.iscomplexobj(y_arr)
    for lo in range(0, ff.size, step):
        basis = _unit_phasors(ff[lo : lo + step] * T, N, -1.0)  # (m, N)
        if real:  # two real products avoid complex BLAS, which is slow when threaded
            out[..., lo : lo + step] = y_arr @ basis.real.T + 1j * (y_arr @ basis.imag.T)
        else:
            out[..., lo : lo + step] = y_arr @ basis.T
    return out.reshape(batch + f_arr.shape)


def dirichlet(f: ArrayLike, N: int, T: float) -> ComplexArray:
    """Normalized Dirichlet kernel, eq. (7).

    ``d_N(f) = exp(-i pi f (N-1) T) sin(pi f N T) / sin(pi f T)
    = sum_{k=0}^{N-1} exp(-i 2 pi f k T)``.

    Parameters
    ----------
    f : array_like
        Frequencies in Hz, any shape.
    N : int
        Number of samples, >= 1.
    T : float
        Sampling interval (s), > 0.

    Returns
    -------
    ndarray of complex, same shape as ``f``

    Notes
    -----
    ``d_N`` is ``1/T``-periodic, so ``x = f T`` is first reduced to ``r = x - round(x)`` in
    ``[-1/2, 1/2]``; the kernel equals ``exp(-i pi r (N-1)) sin(pi r N) / sin(pi r)`` (the signs
    ``(-1)^n`` produced by the integer part cancel).  At ``f T`` integer (``r = 0``) the limit
    is ``N``, which equals ``N exp(-i pi f (N-1) T) (-1)^{n (N-1)}`` with ``n = f T``, i.e. the
    explicit sum.  Near those points the ratio of two small sines keeps full relative
    accuracy.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> d = jid.dirichlet([0.0, 0.5, 0.25], N=4, T=0.5)
    >>> np.abs(d).round(6).tolist()
    [4.0, 0.0, 2.613126]
    >>> bool(np.allclose(d, jid.dtft(np.ones(4), 0.5, [0.0, 0.5, 0.25])))
    True
    """
    N = count(N, "N", minimum=1)
    T = positive(T, "T")
    f_arr = real_array(f, "f")
    x = f_arr * T
    r = x - np.round(x)
    den = np.sin(np.pi * r)
    zero = den == 0.0
    ratio = np.where(zero, float(N), np.sin(np.pi * r * N) / np.where(zero, 1.0, den))
    # the phase only matters modulo 2 pi: reduce r (N-1) / 2 modulo 1 before exponentiating
    phase = np.mod(r * (N - 1) / 2.0, 1.0)
    return np.asarray(np.exp(-2j * np.pi * phase) * ratio, dtype=complex)


# --------------------------------------------------------------------------------------
# eq. (12), Lemma 1, Lemma 2, eq. (19)
# --------------------------------------------------------------------------------------


def stochastic_window(f: ArrayLike, psi: ArrayLike, tau: ArrayLike, T: float) -> ComplexArray:
    """Stochastic frequency window for one or many jitter realisations, eq. (12).

    ``W(f, psi) = sum_{k=0}^{N-1} exp(i 2 pi (psi - f) k T) exp(i 2 pi psi tau_k)``.

    Parameters
    ----------
    f, psi : array_like
        Frequencies in Hz; broadcast together to a shape ``S``.
    tau : array_like, shape (..., N)
        Jitter realisations ``tau_k`` along the last axis; leading axes are independent
        realisations.
    T : float
        Sampling interval (s), > 0.

    Returns
    -------
    ndarray of complex, shape ``tau.shape[:-1] + S``
        With ``tau = 0`` this is ``d_N(f - psi)`` (paper, after eq. 12).
    """
    T = positive(T, "T")
    f_arr, psi_arr = _broadcast({"f": real_array(f, "f"), "psi": real_array(psi, "psi")})
    tau_arr = real_array(tau, "tau")
    if tau_arr.ndim < 1 or tau_arr.shape[-1] < 1:
        raise ValueError(
            f"tau must hold the N jitter values along its last axis; got shape {tau_arr.shape}"
        )
    N = tau_arr.shape[-1]
    batch = tau_arr.shape[:-1]
    tau2 = tau_arr.reshape(-1, N)
    fv, pv = f_arr.ravel(), psi_arr.ravel()
    out = np.empty((tau2.shape[0], fv.size), dtype=complex)
    step = max(1, _CHUNK_ELEMENTS // (N * max(1, tau2.shape[0])))
    for lo in range(0, fv.size, step):
        sl = slice(lo, lo + step)
        grid = _unit_phasors((pv[sl] - fv[sl]) * T, N, 1.0)  # (m, N)
        jit = np.exp(2j * np.pi * pv[sl][None, :, None] * tau2[:, None, :])  # (B, m, N)
        out[:, sl] = np.einsum("bmn,mn->bm", jit, grid)
    return out.reshape(batch + f_arr.shape)


def mean_window(f: ArrayLike, psi: ArrayLike, jitter: SupportsCF, N: int, T: float) -> ComplexArray:
    """Mean of the stochastic window, Lemma 1.

    ``mu_W(f, psi) = E[W(f, psi)] = phi(-psi) d_N(f - psi)``.

    Parameters
    ----------
    f, psi : array_like
        Frequencies in Hz, broadcast together.
    jitter : SupportsCF
        Object with a vectorised ``cf`` (``phi(f) = E[exp(-i 2 pi f tau)]``).
    N : int
        Number of samples, >= 1.
    T : float
        Sampling interval (s), > 0.

    Returns
    -------
    ndarray of complex, the broadcast shape of ``f`` and ``psi``
    """
    N = count(N, "N", minimum=1)
    T = positive(T, "T")
    f_arr, psi_arr = _broadcast({"f": real_array(f, "f"), "psi": real_array(psi, "psi")})
    return _cf(jitter, -psi_arr) * dirichlet(f_arr - psi_arr, N, T)


def _lemma2_D(F: FloatArray, G: FloatArray, N: int, T: float) -> ComplexArray:
    """The vector ``D_N(F, G)`` of Lemma 2, shape ``F.shape + (3,)``, by explicit sums.

    Row 1: ``sum_k sum_{l<k} exp(-i 2 pi (F k - G l) T)``; row 2: ``d_N(F - G)``;
    row 3: ``sum_k sum_{l<k} exp(-i 2 pi (-G k + F l) T)``.  The inner sums over ``l < k``
    are exclusive cumulative sums, so each point costs O(N) and no closed form with
    removable singularities is needed.
    """
    Fv, Gv = F.ravel(), G.ravel()
    out = np.empty((Fv.size, 3), dtype=complex)
    step = max(1, _CHUNK_ELEMENTS // (4 * N))
    for lo in range(0, Fv.size, step):
        sl = slice(lo, lo + step)
        a = _unit_phasors(Fv[sl] * T, N, -1.0)  # exp(-i 2 pi F k T)
        b = _unit_phasors(Gv[sl] * T, N, 1.0)  # exp(+i 2 pi G l T)
        a_before = np.cumsum(a, axis=-1) - a  # sum_{l<k} a_l
        b_before = np.cumsum(b, axis=-1) - b  # sum_{l<k} b_l
        out[sl, 0] = np.sum(a * b_before, axis=-1)
        out[sl, 2] = np.sum(b * a_before, axis=-1)
    out[:, 1] = dirichlet(Fv - Gv, N, T)
    return out.reshape(*F.shape, 3)


def window_second_moment(
    f: ArrayLike,
    eta: ArrayLike,
    psi: ArrayLike,
    zeta: ArrayLike,
    jitter: SupportsCF,
    N: int,
    T: float,
) -> ComplexArray:
    """Second moment of the stochastic window, Lemma 2.

    ``E[W(f, eta) W*(psi, zeta)] = Phi(eta, zeta)^T D_N(f - eta, psi - zeta)`` with

    ``Phi(eta, zeta) = (phi(-eta) phi(zeta), phi(zeta - eta), phi(-eta) phi(zeta))``,

    ``D_N(F, G) = (sum_k sum_{l<k} exp(-i 2 pi (F k - G l) T), d_N(F - G),
    sum_k sum_{l<k} exp(-i 2 pi (-G k + F l) T))``.

    Parameters
    ----------
    f, eta, psi, zeta : array_like
        Frequencies in Hz, broadcast together.
    jitter : SupportsCF
        Object with a vectorised ``cf``.
    N : int
        Number of samples, >= 1.
    T : float
        Sampling interval (s), > 0.

    Returns
    -------
    ndarray of complex, the broadcast shape of the four frequency arguments

    Notes
    -----
    Implemented literally as the sum of the proof's ``Sigma_1 + Sigma_2 + Sigma_3`` (terms
    ``l < k``, ``l = k`` and ``l > k`` of the double sum), the double sums evaluated
    explicitly in O(N) per point.  The printed lemma agrees with its proof (see the module
    notes); the cost is ``O(N)`` per output element.
    """
    N = count(N, "N", minimum=1)
    T = positive(T, "T")
    f_a, eta_a, psi_a, zeta_a = _broadcast(
        {
            "f": real_array(f, "f"),
            "eta": real_array(eta, "eta"),
            "psi": real_array(psi, "psi"),
            "zeta": real_array(zeta, "zeta"),
        }
    )
    cross = _cf(jitter, -eta_a) * _cf(jitter, zeta_a)  # phi(-eta) phi(zeta), k != l
    same = _cf(jitter, zeta_a - eta_a)  # phi(zeta - eta), k == l
    D = _lemma2_D(f_a - eta_a, psi_a - zeta_a, N, T)
    return np.asarray(cross * D[..., 0] + same * D[..., 1] + cross * D[..., 2], dtype=complex)


def window_covariance(
    f: ArrayLike,
    eta: ArrayLike,
    psi: ArrayLike,
    zeta: ArrayLike,
    jitter: SupportsCF,
    N: int,
    T: float,
) -> ComplexArray:
    """Covariance of the stochastic window, eq. (19).

    ``R_W(f, eta, psi, zeta) = E[W(f, eta) W*(psi, zeta)] - mu_W(f, eta) mu_W(psi, zeta)*``,
    from Lemma 2 (:func:`window_second_moment`) and Lemma 1 (:func:`mean_window`).

    Parameters
    ----------
    f, eta, psi, zeta : array_like
        Frequencies in Hz, broadcast together.
    jitter : SupportsCF
        Object with a vectorised ``cf``.
    N : int
        Number of samples, >= 1.
    T : float
        Sampling interval (s), > 0.

    Returns
    -------
    ndarray of complex, the broadcast shape of the four frequency arguments
        Algebraically equal to ``(phi(zeta - eta) - phi(-eta) phi(zeta)) d_N(f - eta - psi +
        zeta)``; it vanishes without jitter (``phi = 1``).
    """
    second = window_second_moment(f, eta, psi, zeta, jitter, N, T)
    mu1 = mean_window(f, eta, jitter, N, T)
    mu2 = mean_window(psi, zeta, jitter, N, T)
    return np.asarray(second - mu1 * np.conj(mu2), dtype=complex)


# --------------------------------------------------------------------------------------
# line spectra: eqs. (13)/(14b) and (17)-(19)
# --------------------------------------------------------------------------------------


def _lines(freqs: ArrayLike, coeffs: ArrayLike) -> tuple[FloatArray, ComplexArray]:
    nu = real_array(freqs, "freqs", ndim=1)
    c = _finite_array(coeffs, "coeffs").astype(complex)
    if c.ndim != 1 or c.shape != nu.shape:
        raise ValueError(
            f"coeffs must be 1-dimensional with one entry per line in freqs; got coeffs shape "
            f"{c.shape} and freqs shape {nu.shape}"
        )
    return nu, c


def expected_dft_lines(
    freqs: ArrayLike,
    coeffs: ArrayLike,
    jitter: SupportsCF,
    T: float,
    N: int,
    f: ArrayLike,
) -> ComplexArray:
    """Mean DTFT of a jittered line-spectrum signal, eqs. (13)/(14b) with Lemma 1.

    For ``s(t) = sum_m c_m exp(i 2 pi nu_m t)`` the spectrum ``S_c`` is a sum of deltas and
    (14b) becomes ``mu_Y(f) = sum_m c_m phi(-nu_m) d_N(f - nu_m)``.  A real sinusoid
    ``A sin(2 pi nu t + p)`` is the two lines ``(nu, A e^{ip} / 2i)`` and
    ``(-nu, -A e^{-ip} / 2i)``.

    Parameters
    ----------
    freqs : array_like, shape (L,)
        Line frequencies ``nu_m`` in Hz.
    coeffs : array_like, shape (L,)
        Complex amplitudes ``c_m``.
    jitter : SupportsCF
        Object with a vectorised ``cf``.
    T : float
        Sampling interval (s), > 0.
    N : int
        Number of samples, >= 1.
    f : array_like
        Frequencies in Hz, any shape.

    Returns
    -------
    ndarray of complex, same shape as ``f``
    """
    nu, c = _lines(freqs, coeffs)
    N = count(N, "N", minimum=1)
    T = positive(T, "T")
    f_arr = real_array(f, "f")
    mu = mean_window(f_arr[..., None], nu, jitter, N, T)  # (..., L)
    return np.asarray(mu @ c, dtype=complex)


def dft_covariance_lines(
    freqs: ArrayLike,
    coeffs: ArrayLike,
    jitter: SupportsCF,
    T: float,
    N: int,
    f: ArrayLike,
    psi: ArrayLike,
    noise_std: float = 0.0,
) -> ComplexArray:
    """Covariance of the DTFT of a jittered line-spectrum signal, eqs. (17)-(19), Lemma 2.

    ``R_Y(f, psi) = Cov(Y_d(f), Y_d(psi)) = E[(Y_d(f) - mu_Y(f)) (Y_d(psi) - mu_Y(psi))*]
    = R_S(f, psi) + R_V(f, psi)`` with, for ``S_c`` a sum of deltas,

    ``R_S(f, psi) = sum_{m, m'} c_m R_W(f, nu_m, psi, nu_m') conj(c_m')``   (18)

    ``R_V(f, psi) = sigma^2 sum_k exp(-i 2 pi (f - psi) k T) = sigma^2 d_N(f - psi)``.

    Parameters
    ----------
    freqs, coeffs : array_like, shape (L,)
        Line frequencies (Hz) and complex amplitudes, as in :func:`expected_dft_lines`.
    jitter : SupportsCF
        Object with a vectorised ``cf``.
    T : float
        Sampling interval (s), > 0.
    N : int
        Number of samples, >= 1.
    f : array_like, shape (M,)
        First frequency set (rows).
    psi : array_like, shape (P,)
        Second frequency set (columns).
    noise_std : float, default 0
        Standard deviation ``sigma`` of the white measurement noise ``v_k``.

    Returns
    -------
    ndarray of complex, shape (M, P)
        Hermitian when ``psi`` equals ``f``.  Only the covariance is returned, not the
        pseudo-covariance ``E[(Y(f) - mu)(Y(psi) - mu)]``.
    """
    nu, c = _lines(freqs, coeffs)
    N = count(N, "N", minimum=1)
    T = positive(T, "T")
    sigma = positive(noise_std, "noise_std", allow_zero=True)
    f_arr = real_array(f, "f", ndim=1)
    psi_arr = real_array(psi, "psi", ndim=1)
    L = nu.size
    out = np.empty((f_arr.size, psi_arr.size), dtype=complex)
    step = max(1, _CHUNK_ELEMENTS // max(1, psi_arr.size * L * L))
    for lo in range(0, f_arr.size, step):
        fc = f_arr[lo : lo + step]
        rw = window_covariance(
            fc[:, None, None, None],
            nu[None, None, :, None],
            psi_arr[None, :, None, None],
            nu[None, None, None, :],
            jitter,
            N,
            T,
        )  # (m, P, L, L)
        out[lo : lo + step] = np.einsum("a,ijab,b->ij", c, rw, np.conj(c))
    if sigma > 0.0:
        out += sigma**2 * dirichlet(f_arr[:, None] - psi_arr[None, :], N, T)
    return out


# --------------------------------------------------------------------------------------
# continuous spectra: eq. (14b) by quadrature
# --------------------------------------------------------------------------------------


def integral_grid_size(psi_max: float, T: float, N: int, support: tuple[float, float]) -> int:
    """Number of trapezoid nodes on ``[-psi_max, psi_max]`` that make aliasing negligible.

    The trapezoid rule with step ``h`` applied to ``int G(psi) exp(i 2 pi psi t) dpsi``
    returns the periodic sum ``sum_j g(t + j / h)`` of the inverse transform ``g`` (Poisson
    summation).  In (14b), ``G(psi) = S_c(psi) phi(-psi)`` and ``g(t) = E[s(t + tau)]`` is
    the jitter-smoothed signal, probed at ``t = kT``, ``k = 0..N-1``.  If ``g`` is negligible
    outside ``support = (t_lo, t_hi)``, no replica ``j != 0`` reaches a sample instant once

        1 / h > P = max(t_hi, (N - 1) T - t_lo),

    so the discretisation error is then set by ``g`` outside the support only.

    Parameters
    ----------
    psi_max : float
        Truncation frequency in Hz, > 0.
    T : float
        Sampling interval (s), > 0.
    N : int
        Number of samples, >= 1.
    support : (float, float)
        ``(t_lo, t_hi)``, an interval (s) outside which ``E[s(t + tau)]`` is negligible at
        the accuracy sought (e.g. for ``s(t) = exp(-alpha t)``, ``t >= 0``, and jitter in
        ``[-a, a]``: ``(-a, (N - 1) T + a + log(1/tol) / alpha)``).

    Returns
    -------
    int
        ``n_psi = ceil(2 psi_max P) + 2``, i.e. step ``h = 2 psi_max / (n_psi - 1) < 1 / P``.
    """
    psi_max = positive(psi_max, "psi_max")
    T = positive(T, "T")
    N = count(N, "N", minimum=1)
    try:
        t_lo, t_hi = (float(v) for v in support)
    except (TypeError, ValueError):
        raise TypeError(f"support must be a pair (t_lo, t_hi) of reals; got {support!r}") from None
    if not (np.isfinite(t_lo) and np.isfinite(t_hi) and t_lo < t_hi):
        raise ValueError(f"support must be finite with t_lo < t_hi; got {support!r}")
    period = max(t_hi, (N - 1) * T - t_lo, T)
    return math.ceil(2.0 * psi_max * period) + 2


def expected_dft_integral(
    spectrum: Callable[[FloatArray], ArrayLike],
    jitter: SupportsCF,
    T: float,
    N: int,
    f: ArrayLike,
    *,
    psi_max: float,
    n_psi: int,
) -> ComplexArray:
    """Mean DTFT for a continuous spectrum by quadrature of eq. (14b).

    ``mu_Y(f) = int S_c(psi) phi(-psi) d_N(f - psi) dpsi``, truncated to
    ``|psi| <= psi_max`` and evaluated with the composite trapezoid rule on ``n_psi``
    equispaced nodes.

    Parameters
    ----------
    spectrum : callable
        Vectorised ``S_c(psi) = int s(t) exp(-i 2 pi psi t) dt``, the continuous-time Fourier
        transform of the signal (psi in Hz).
    jitter : SupportsCF
        Object with a vectorised ``cf``.
    T : float
        Sampling interval (s), > 0.
    N : int
        Number of samples, >= 1.
    f : array_like
        Frequencies in Hz, any shape.
    psi_max : float
        Truncation of the integral, > 0 (Hz).
    n_psi : int
        Number of quadrature nodes, >= 2.

    Returns
    -------
    ndarray of complex, same shape as ``f``

    Notes
    -----
    Two errors, both controllable:

    *Discretisation.*  ``d_N(f - psi)`` is, in ``psi``, a trigonometric polynomial with
    "times" ``kT``, ``k = 0..N-1``: the integrand oscillates on the scale ``1/(N T)``.  By
    Poisson summation the trapezoid rule with step ``h`` computes the DTFT of
    ``sum_j g(kT + j/h)``, where ``g(t) = E[s(t + tau)]`` (notes, section 1): the replicas
    ``j != 0`` are the error.  The step must therefore satisfy ``1/h`` larger than the time
    span covered by the samples plus the extent of ``g`` beyond them -- roughly
    ``h < 1 / ((N - 1) T + a + several time constants)`` for a decaying causal signal with
    jitter in ``[-a, a]``; :func:`integral_grid_size` computes the matching ``n_psi``.  This
    is also why the plain trapezoid rule is used: Simpson-type weights alternate and create
    extra replicas at ``1/(2h)``.

    *Truncation.*  Dropping ``|psi| > psi_max`` removes the high-frequency content of
    ``g``; the error at the sample instants is the tail
    ``int_{|psi| > psi_max} S_c(psi) phi(-psi) exp(i 2 pi psi kT) dpsi``, bounded by
    ``int_{|psi| > psi_max} |S_c phi| dpsi`` per sample and usually much smaller because the
    tail oscillates.  It is governed by the smoothness of ``g``: for a signal with a jump and
    uniform jitter ``|S_c phi| ~ psi^-2`` (kinks in ``g``), giving an error that decays
    like ``psi_max^-2`` to ``psi_max^-1``; Gaussian jitter makes it decay like
    ``exp(-2 pi^2 sigma^2 psi_max^2)``.

    The cost is ``O(size(f) * n_psi)`` kernel evaluations, chunked over ``f``.
    """
    if not callable(spectrum):
        raise TypeError(
            f"spectrum must be a vectorised callable S_c(psi); got {type(spectrum).__name__}"
        )
    T = positive(T, "T")
    N = count(N, "N", minimum=1)
    psi_max = positive(psi_max, "psi_max")
    n_psi = count(n_psi, "n_psi", minimum=2)
    f_arr = real_array(f, "f")
    psi = np.linspace(-psi_max, psi_max, n_psi)
    h = psi[1] - psi[0]
    s_val = np.asarray(spectrum(psi))
    if s_val.shape != psi.shape:
        raise ValueError(
            f"spectrum(psi) returned shape {s_val.shape} for psi of shape {psi.shape}; "
            "spectrum must be vectorised"
        )
    s_val = s_val.astype(complex)
    if not np.all(np.isfinite(s_val)):
        raise ValueError("spectrum(psi) returned NaN or infinite values on the quadrature grid")
    weights = np.full(n_psi, h)
    weights[0] = weights[-1] = h / 2.0
    g = s_val * _cf(jitter, -psi) * weights  # S_c(psi) phi(-psi) w(psi)
    fv = f_arr.ravel()
    out = np.empty(fv.size, dtype=complex)
    step = max(1, _CHUNK_ELEMENTS // n_psi)
    for lo in range(0, fv.size, step):
        fc = fv[lo : lo + step]
        out[lo : lo + step] = dirichlet(fc[:, None] - psi[None, :], N, T) @ g
    return out.reshape(f_arr.shape)
