"""Mean and covariance of the measured DFT under jitter: Lemmas 1 and 2, time-domain path.

Because the tau_k are independent, Lemma 1 and 2 have an O(N) time-domain form (notes,
sections 1-2): with m_k = E[s(kT + tau)] and w_k = Var[s(kT + tau)] + sigma_v^2,

    mu_Y(f)       = sum_k m_k exp(-i 2 pi f k T)                      (13), (14b)
    R_Y(f, psi)   = sum_k w_k exp(-i 2 pi (f - psi) k T)              (17)-(19)
    C_Y(f, psi)   = sum_k w_k exp(-i 2 pi (f + psi) k T)  (pseudo-covariance)

The paper's own frequency-domain integrals are in :mod:`jitterid.moments.reference`; the tests
check that both routes give the same numbers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import allocation, count, positive, real_array, sampling_interval
from ..inputs import Input, known_input
from ..jitter.laws import JitterLaw, known_law
from ..systems.model import MomentPass, Signal
from ..systems.tf import TransferFunction
from .modal import SegmentPlan, modal_moments, tables
from .quadrature import DEFAULT_ORDER, jitter_nodes
from .reference import dtft

__all__ = [
    "SampleMoments",
    "dft_covariance",
    "dft_pseudo_covariance",
    "expected_dft",
    "moment_pass",
    "sample_moments",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class SampleMoments:
    """Per-sample moments of the jittered signal s(kT + tau_k).

    Attributes
    ----------
    mean : ndarray, shape (N,)
        m_k = E[s(kT + tau)].
    var : ndarray, shape (N,)
        Var[s(kT + tau)] (without measurement noise).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> s = ji.Response(ji.TransferFunction([2.0], [1.0, 2.0]), ji.zoh_input([1.0] * 41, T=0.1))
    >>> mom = ji.sample_moments(s, ji.Uniform(0.05), T=0.1, N=40)
    >>> isinstance(mom, ji.SampleMoments), mom.mean.shape
    (True, (40,))
    >>> round(float(mom.mean[20]), 4), bool(np.all(mom.var >= 0))
    (0.9817, True)
    """

    mean: FloatArray
    var: FloatArray


class LazyMoments(SampleMoments):
    """:class:`SampleMoments` whose ``var`` is computed on first use by ``var_fn`` (a
    least-squares search needs only the means; its noise plug-in or covariance may later ask
    for the variances)."""

    _lazy: list[Callable[[], FloatArray] | FloatArray]

    def __init__(self, mean: FloatArray, var_fn: Callable[[], FloatArray]) -> None:
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "_lazy", [var_fn])

    @property
    def var(self) -> FloatArray:
        held = self._lazy[0]
        if callable(held):
            held = self._lazy[0] = held()
        return held


def sample_moments(
    signal: Signal,
    jitter: JitterLaw,
    T: float,
    N: int,
    *,
    order: int = DEFAULT_ORDER,
) -> SampleMoments:
    """m_k and Var[s(kT + tau)] by panel Gauss-Legendre quadrature over tau (notes 1-2).

    The variance is computed as E[(s - m_k)^2] in a second pass over the same nodes, so it
    does not suffer the cancellation of E[s^2] - m_k^2 when the jitter is small. For the
    response of an LTI system to a piecewise-constant input the node sums are taken per
    input segment from the modal form (:mod:`jitterid.moments.modal`, (M1)-(M2)); any other
    signal (:class:`jitterid.systems.model.Signal`) is evaluated at the nodes
    (:func:`moment_pass`). Without jitter the samples are s(kT) themselves. Work O(N),
    memory bounded by the chunk size.

    Parameters
    ----------
    signal : Signal
        The noise-free signal s(t), e.g. ``system.response(u)``; it must cover the last
        jittered sampling instant.
    jitter : JitterLaw
        Law of the sampling jitter tau_k.
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    order : int, optional
        Gauss-Legendre nodes per quadrature panel.

    Returns
    -------
    SampleMoments
        ``mean`` (m_k) and ``var`` (Var[s(kT + tau)]), each of shape (N,).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([1.0], [1.0, 1.0])
    >>> u = jid.zoh_input(np.ones(8), T=0.5)
    >>> mom = jid.sample_moments(sys.response(u), jid.Uniform(0.1), T=0.5, N=8)
    >>> mom.mean.shape, bool(np.all(mom.var >= 0))
    ((8,), True)
    """
    T = sampling_interval(T, "T")
    N = count(N, "N", minimum=1)
    jitter = known_law(jitter)
    if not isinstance(signal, Signal):
        raise TypeError(
            "signal must be a jitterid signal (system.response(u), model.signal(params)); got "
            f"{type(signal).__name__}"
        )
    signal.check_covers((N - 1) * T + jitter.support[1], "the last jittered sampling instant")
    jitter, signal = signal.jitter_equivalent(jitter)  # a delay moves into the jitter
    lo, hi = jitter.support
    seg = signal.modal_segments
    if seg is not None and hi > lo:
        # The same nodes, summed per input segment from the modal form (:mod:`.modal`):
        # a few times faster than evaluating s(t) node by node.
        plan = SegmentPlan(
            jitter, T, N, seg.u, signal.rate, order=order, poles=seg.system.modal.poles
        )
        mean, var, _, _ = modal_moments(plan, tables(seg.system, seg.u), keep=False)
        assert var is not None
        return SampleMoments(mean, var)
    out = moment_pass(signal, jitter, T, N, order=order)
    assert out.var is not None
    return SampleMoments(out.mean, out.var)


def moment_pass(
    signal: Signal,
    jitter: JitterLaw,
    T: float,
    N: int,
    *,
    variance: bool = True,
    gradient: bool = False,
    scale: float | None = None,
    higher: bool = False,
    order: int = DEFAULT_ORDER,
) -> MomentPass:
    """The moments of any signal at the jitter nodes (notes 1-2), and their derivatives.

    With ``higher``, also the third and fourth central moments of s(kT + tau) (the
    covariance of the second-moment criteria, :mod:`jitterid.estimation.covariance`).

    With ``gradient``, dm_k = E[ds/dtheta] and dVar_k = 2 E[(s - m_k) ds/dtheta] from the
    signal's gradient (:meth:`~jitterid.systems.model.Signal.gradient`); with ``scale`` = a,
    the scale of a jitter family (tau = a xi), dm_k/da = E[s'(kT + tau) tau] / a and
    dVar_k/da = 2 E[(s - m_k) s' tau] / a from the signal's slope (the signal must be smooth:
    :class:`~jitterid.systems.signals.SignalModel`). A derivative the signal does not declare
    is left ``None``: the caller differences the moments. A signal with closed-form
    moments (:meth:`~jitterid.systems.model.Signal.jitter_moments`) gives them instead.
    """
    closed = signal.jitter_moments(
        jitter, T, N, variance=variance, gradient=gradient, scale=scale, higher=higher
    )
    if closed is not None:
        return closed
    gradient = gradient and signal.has_gradient
    if not signal.has_slope:
        scale = None
    mean = np.empty(N)
    var = np.empty(N) if variance else None
    rows: list[FloatArray] = []  # per derivative: its dmean and (with variance) dvar
    mu3, mu4 = (np.empty(N), np.empty(N)) if higher else (None, None)
    for ch in jitter_nodes(jitter, T, N, signal.breaks, signal.rate, order=order):
        s = signal(ch.t)
        m = ch.expect(s)
        sl = slice(ch.k0, ch.k1)
        mean[sl] = m
        dev = s - m[ch.owner]
        if var is not None:
            var[sl] = ch.expect(dev**2)
        if mu3 is not None and mu4 is not None:
            mu3[sl], mu4[sl] = ch.expect(dev**3), ch.expect(dev**4)
        parts: list[FloatArray] = []
        if gradient:
            g = signal.gradient(ch.t)
            assert g is not None
            parts.extend(g)
        if scale is not None:
            slope = signal.slope(ch.t)
            assert slope is not None
            parts.append(slope * (ch.t - (ch.k0 + ch.owner) * T) / scale)
        if not rows:
            rows = [np.empty((2 if variance else 1, N)) for _ in parts]
        for row, gi in zip(rows, parts, strict=True):
            row[0, sl] = ch.expect(gi)
            if variance:
                row[1, sl] = 2 * ch.expect(dev * gi)
    out = MomentPass(mean, var, mu3=mu3, mu4=mu4)
    if gradient:
        grad = np.array(rows[: len(rows) - (scale is not None)]).reshape(-1, rows[0].shape[0], N)
        out = replace(out, dmean=grad[:, 0], dvar=grad[:, 1] if variance else None)
    if scale is not None:
        out = replace(out, scale_mean=rows[-1][0], scale_var=rows[-1][1] if variance else None)
    return out


def _frequencies(f: ArrayLike) -> FloatArray:
    return np.atleast_1d(real_array(f, "f"))


def expected_dft(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
) -> ComplexArray:
    """mu_Y(f) = E[Y_d(f)], eqs. (13)-(14b) with Lemma 1, computed in the time domain.

    Parameters
    ----------
    system : TransferFunction
        Continuous-time system, at rest before the input starts.
    u : Input
        Known input.
    jitter : JitterLaw
        Law of the sampling jitter tau_k.
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    f : array_like
        Frequencies in Hz (any set, also above Nyquist).

    Returns
    -------
    ndarray of complex, same length as ``f``

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([1.0], [1.0, 1.0])
    >>> u = jid.zoh_input(np.ones(16), T=0.5)
    >>> mu = jid.expected_dft(sys, u, jid.NoJitter(), T=0.5, N=16, f=[0.0, 0.25])
    >>> mu.shape, mu.dtype
    ((2,), dtype('complex128'))
    """
    freqs = _frequencies(f)
    mom = sample_moments(_response(system, u), jitter, T, N)
    return dtft(mom.mean, T, freqs)


def _response(system: TransferFunction, u: Input) -> Signal:
    """``system.response(u)`` once both are of the right kind."""
    if not isinstance(system, TransferFunction):
        raise TypeError(
            f"system must be a TransferFunction (e.g. model.system(params)); got "
            f"{type(system).__name__}"
        )
    return system.response(known_input(u))


def _noise_var(noise_std: float) -> float:
    return positive(noise_std, "noise_std", allow_zero=True) ** 2


def dft_covariance(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
    noise_std: float,
    psi: ArrayLike | None = None,
) -> ComplexArray:
    """R_Y(f, psi) = Cov(Y_d(f), Y_d(psi)), eqs. (17)-(19) with Lemma 2, time-domain form.

    Returns the matrix with rows over ``f`` and columns over ``psi`` (default ``psi = f``).
    Includes the measurement-noise term sigma_v^2 sum_k exp(-i 2 pi (f - psi) k T).

    Parameters
    ----------
    system : TransferFunction
        Continuous-time system, at rest before the input starts.
    u : Input
        Known input.
    jitter : JitterLaw
        Law of the sampling jitter tau_k.
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    f : array_like
        Row frequencies in Hz.
    noise_std : float
        Standard deviation of the white measurement noise (>= 0).
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
    >>> R = ji.dft_covariance(G, u, ji.Uniform(0.02), 0.1, 40, [0.25, 0.5], noise_std=0.01)
    >>> R.shape, bool(np.allclose(R, R.conj().T)), bool(np.all(R.diagonal().real > 0))
    ((2, 2), True, True)
    """
    return _second_moment(system, u, jitter, T, N, f, noise_std, psi, sign=1.0)


def dft_pseudo_covariance(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
    noise_std: float,
    psi: ArrayLike | None = None,
) -> ComplexArray:
    """C_Y(f, psi) = E[(Y(f) - mu(f))(Y(psi) - mu(psi))]: the pseudo-covariance (notes 2).

    A circular complex Gaussian model, as in the paper's (22), ignores it; the real-valued
    Gaussian criterion (method ``"gaussian"``) accounts for it.

    Parameters
    ----------
    system : TransferFunction
        Continuous-time system, at rest before the input starts.
    u : Input
        Known input.
    jitter : JitterLaw
        Law of the sampling jitter tau_k.
    T : float
        Nominal sampling interval (s).
    N : int
        Number of samples.
    f : array_like
        Row frequencies in Hz.
    noise_std : float
        Standard deviation of the white measurement noise (>= 0).
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
    >>> C = ji.dft_pseudo_covariance(G, u, ji.Uniform(0.02), 0.1, 40, [0.25, 0.5], 0.01)
    >>> C.shape, bool(np.allclose(C, C.T))
    ((2, 2), True)
    """
    return _second_moment(system, u, jitter, T, N, f, noise_std, psi, sign=-1.0)


def _second_moment(
    system: TransferFunction,
    u: Input,
    jitter: JitterLaw,
    T: float,
    N: int,
    f: ArrayLike,
    noise_std: float,
    psi: ArrayLike | None,
    sign: float,
) -> ComplexArray:
    """sum_k w_k exp(-i 2 pi (f - sign psi) k T): R_Y for sign = 1, C_Y for sign = -1."""
    freqs = _frequencies(f)
    other = freqs if psi is None else _frequencies(psi)
    allocation(
        freqs.size * other.size,
        f"the {freqs.size} x {other.size} DFT covariance",
        bytes_each=_PAIR_BYTES,
        fix="ask for fewer frequencies, or for the matrix in blocks of rows (f) and columns (psi)",
    )
    w = sample_moments(_response(system, u), jitter, T, N).var + _noise_var(noise_std)
    return covariance_from_variances(w, T, freqs, sign * other)


#: Peak bytes per (f, psi) pair of :func:`covariance_from_variances`: the differences, their
#: rounded copy, np.unique's sort and inverse index (8 bytes each) and the complex result (16).
_PAIR_BYTES = 56


def covariance_from_variances(
    w: FloatArray, T: float, f: FloatArray, psi: FloatArray
) -> ComplexArray:
    """sum_k w_k exp(-i 2 pi (f - psi) k T) for every pair (f, psi).

    The sum depends on f - psi only, so it is evaluated once per distinct difference: on
    an evenly spaced set (such as the DFT grid (24)) that is 2F - 1 sums instead of F^2.
    """
    uniq, inverse = difference_grid(f, psi, T, w.size)
    return dtft(w, T, uniq)[inverse].reshape(f.size, psi.size)


def difference_grid(
    f: FloatArray, psi: FloatArray, T: float, N: int
) -> tuple[FloatArray, NDArray[np.intp]]:
    """The distinct differences f - psi (to ~1e-12 cycles over N samples) and, for every pair
    (f, psi) in row-major order, the index of its difference."""
    diff = f[:, None] - psi[None, :]
    # Differences that agree to ~1e-12 cycles over the record are the same frequency.
    scale = 1e-12 / (T * max(N, 1))
    uniq, inverse = np.unique(np.round(diff.ravel() / scale), return_inverse=True)
    return uniq * scale, inverse.ravel()
