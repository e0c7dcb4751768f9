"""Coloured measurement noise v(t) = (h_theta * e)(t), eq. (1c): models, structures, simulation.

The paper's general model (1a) adds v(kT + tau_k) to the signal, with v a continuous-time
noise process whose dynamics H_theta(s) may be parameterised (Box-Jenkins structures (2b),
(2d)). Here H(s) is a strictly proper, stable rational transfer function with distinct poles,
driven by continuous-time white noise e of intensity lambda (E[e(t) e(t')] = lambda
delta(t - t')). In the modal form H(s) = sum_j r_j / (s - p_j) (the partial fractions of
:class:`~jitterid.TransferFunction` that also simulate the system) the autocovariance and the
two-sided power spectral density (per Hz) are

    r_v(t) = sum_j c_j exp(p_j |t|),   c_j = lambda r_j H(-p_j),                      (N1)
    S_v(f) = lambda |H(i 2 pi f)|^2,    int S_v(f) df = r_v(0).                          (N2)

(N1) follows from r_v(t) = lambda int_0^inf h(s) h(s + |t|) ds with h(t) = sum_j r_j e^{p_j t}.

Exact simulation at arbitrary instants (no Euler step): with the modal states
z_j(t) = int e^{p_j (t - s)} dW(s), v = sum_j r_j z_j, and between consecutive sorted instants
(gap Delta)

    z_j(t + Delta) = e^{p_j Delta} z_j(t) + w_j,
    E[w_i conj(w_j)] = lambda expm1((p_i + conj p_j) Delta) / (p_i + conj p_j),        (N3)
    E[w_i w_j]       = lambda expm1((p_i + p_j) Delta) / (p_i + p_j),

exactly (the integral of e^{(p_i + p_j) u} over [0, Delta]); Delta = inf gives the
stationary law, from which the first state is drawn. The white measurement noise of the OE
structure (2a) is the separate ``noise_std`` of :func:`jitterid.simulate` and
:func:`jitterid.fit`; ``noise=None`` there is the OE case.

The covariance of the *jittered* samples v(kT + tau_k) is a moment of the jitter:
:mod:`jitterid.moments.noise_covariance`.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import count, generator, parameter_vector, positive, real_array
from .._state import CachesAreNotState
from ..systems.tf import TransferFunction

__all__ = ["KnownNoise", "NoiseModel", "NoiseStructure", "RationalNoise", "as_noise_structure"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Bounds = tuple[tuple[float, float], ...]

_RATE_FLOOR = 1e-9  # lower bound of the denominator coefficients (stability needs > 0)


def _integral_exp(q: ComplexArray, delta: FloatArray) -> ComplexArray:
    """int_0^Delta e^{q u} du = expm1(q Delta) / q for Re q < 0, Delta >= 0 or Delta = inf.

    expm1 keeps full relative accuracy for small gaps, where e^{q Delta} - 1 would cancel.
    """
    d = np.asarray(delta, dtype=float)[..., None, None]
    finite = np.isfinite(d)
    out = np.expm1(q * np.where(finite, d, 0.0)) / q
    return np.where(finite, out, -1.0 / q)


@dataclass(frozen=True, eq=False)
class NoiseModel(CachesAreNotState):
    """Coloured noise v(t) = (h * e)(t) with H(s) = ``tf`` and e white of ``intensity``, eq. (1c).

    Parameters
    ----------
    tf : TransferFunction
        H(s): strictly proper (deg num < deg den), stable, distinct poles.
    intensity : float
        lambda > 0, the intensity (two-sided spectral density) of the driving white noise e.

    Notes
    -----
    Autocovariance (N1) and spectrum (N2) of the module docstring. Example: H = b / (s + c)
    gives an Ornstein-Uhlenbeck process, r_v(t) = lambda b^2 / (2 c) exp(-c |t|).

    Examples
    --------
    >>> import jitterid as ji
    >>> H = ji.NoiseModel(ji.TransferFunction([1.0], [1.0, 2.0]), intensity=4.0)
    >>> round(float(H.variance), 6)  # lambda b^2 / (2 c) for H = b / (s + c)
    1.0
    >>> H.autocovariance([0.0, 0.5]).round(6).tolist()
    [1.0, 0.367879]
    """

    tf: TransferFunction
    intensity: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.tf, TransferFunction):
            raise TypeError(
                f"tf must be a TransferFunction H(s) (e.g. TransferFunction([b], [1, c])); "
                f"got {type(self.tf).__name__}"
            )
        if self.tf.order < 1 or self.tf.num.size >= self.tf.den.size:
            raise ValueError(
                f"tf must be strictly proper (deg num < deg den) so that v(t) has finite "
                f"variance; got {self.tf}. Model a white part by noise_std instead"
            )
        object.__setattr__(self, "intensity", positive(self.intensity, "intensity"))
        try:
            self.tf.modal  # noqa: B018 - validates stability and distinct poles now
        except ValueError as exc:
            raise ValueError(f"tf (the noise model H(s)) is invalid: {exc}") from exc

    def __repr__(self) -> str:
        return f"NoiseModel(tf={self.tf!r}, intensity={self.intensity:g})"

    @cached_property
    def modes(self) -> tuple[ComplexArray, ComplexArray]:
        """(c, p): r_v(t) = Re sum_j c_j exp(p_j |t|) over all poles p_j, eq. (N1)."""
        _, r, p = self.tf.modal
        h_minus_p = np.polyval(self.tf.num, -p) / np.polyval(self.tf.den, -p)
        return self.intensity * r * h_minus_p, p

    @property
    def variance(self) -> float:
        """r_v(0), the stationary variance of v(t)."""
        c, _ = self.modes
        return float(np.sum(c).real)

    def autocovariance(self, t: ArrayLike) -> FloatArray:
        """r_v(t) = E[v(s) v(s + t)], eq. (N1), at lags ``t`` (seconds, any shape).

        Parameters
        ----------
        t : array_like
            Lags in s, any shape.
        """
        c, p = self.modes
        tt = np.abs(real_array(t, "t"))[..., None]
        return np.asarray((np.exp(p * tt) @ c).real, dtype=float)

    def spectrum(self, f: ArrayLike) -> FloatArray:
        """Two-sided power spectral density S_v(f) = lambda |H(i 2 pi f)|^2 per Hz, eq. (N2).

        Parameters
        ----------
        f : array_like
            Frequencies in Hz, any shape.
        """
        return self.intensity * np.abs(self.tf.frequency_response(real_array(f, "f"))) ** 2

    def sample(self, instants: ArrayLike, rng: np.random.Generator | int) -> FloatArray:
        """Draw v at the given instants exactly, eq. (N3) (stationary start).

        Parameters
        ----------
        instants : array_like, shape (N,) or (R, N)
            Times in seconds, in any order; each row is an independent realization.
        rng : numpy.random.Generator or int
            Source of randomness.

        Returns
        -------
        ndarray, same shape as ``instants``
        """
        t = real_array(instants, "instants")
        if t.ndim not in (1, 2) or t.shape[-1] < 1:
            raise ValueError(f"instants must have shape (N,) or (R, N) with N >= 1; got {t.shape}")
        gen = generator(rng)
        rows = np.atleast_2d(t)
        order = np.argsort(rows, axis=1, kind="stable")
        ts = np.take_along_axis(rows, order, axis=1)
        _, r, p = self.tf.modal
        keep = p.imag >= 0  # a conjugate pole's state is the conjugate: simulate one of each pair
        pk = p[keep]
        rho = r[keep] * np.where(pk.imag > 0, 2.0, 1.0)  # so that v = Re sum rho z
        gaps = np.concatenate([np.full((rows.shape[0], 1), np.inf), np.diff(ts, axis=1)], axis=1)
        w = self._increments(pk, gaps, gen)  # (R, N, m)
        z = np.zeros((rows.shape[0], pk.size), complex)
        v = np.empty(rows.shape)
        # Sequential in the instants (each state depends on the previous), vectorised over
        # realizations and modes: O(N m) work.
        for k in range(rows.shape[1]):
            decay = np.exp(pk * np.where(np.isfinite(gaps[:, k : k + 1]), gaps[:, k : k + 1], 0.0))
            z = decay * z + w[:, k]
            v[:, k] = (z @ rho).real
        out = np.empty_like(v)
        np.put_along_axis(out, order, v, axis=1)
        return out.reshape(t.shape)

    def _increments(
        self, pk: ComplexArray, gaps: FloatArray, gen: np.random.Generator
    ) -> ComplexArray:
        """Complex increments w of (N3) for every gap, drawn through their real representation."""
        lam = self.intensity
        herm = lam * _integral_exp(pk[:, None] + np.conj(pk)[None, :], gaps)  # E[w w^H]
        pseudo = lam * _integral_exp(pk[:, None] + pk[None, :], gaps)  # E[w w^T]
        # w = a + i b: E[a a^T] = Re(C + Cp)/2, E[b b^T] = Re(C - Cp)/2, E[a b^T] = Im(Cp - C)/2.
        aa, bb, ab = (herm + pseudo).real / 2, (herm - pseudo).real / 2, (pseudo - herm).imag / 2
        cov = np.block([[aa, ab], [np.swapaxes(ab, -1, -2), bb]])
        # eigh rather than Cholesky: the Im parts of real poles have zero variance (singular).
        vals, vecs = np.linalg.eigh(cov)
        root = vecs * np.sqrt(np.clip(vals, 0.0, None))[..., None, :]
        draw = (root @ gen.standard_normal((*gaps.shape, 2 * pk.size, 1)))[..., 0]
        return draw[..., : pk.size] + 1j * draw[..., pk.size :]


class NoiseStructure(abc.ABC):
    """A family of noise models H_eta with named parameters and closed bounds.

    Subclasses define ``param_names``, ``bounds``, ``model(params) -> NoiseModel`` and
    ``starts(T, scale)``: a few starting points for a noise level ``scale`` (std of v).

    Examples
    --------
    >>> import jitterid as ji
    >>> noise = ji.RationalNoise(0, 1)
    >>> isinstance(noise, ji.NoiseStructure), noise.bounds
    (True, ((0.0, inf), (1e-09, inf)))
    """

    param_names: tuple[str, ...]
    bounds: Bounds

    @abc.abstractmethod
    def model(self, params: ArrayLike) -> NoiseModel:
        """H_eta at ``params``.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        """
        ...

    @abc.abstractmethod
    def starts(self, T: float, scale: float) -> list[FloatArray]:
        """A few starting parameter vectors for data sampled every ``T``.

        Parameters
        ----------
        T : float
            Nominal sampling interval (s).
        scale : float
            The noise level to start from (the std of the residuals to be explained).
        """
        ...

    @property
    def gain_params(self) -> tuple[int, ...]:
        """Indices of the parameters in which H is linear, which carry the noise level (v
        scaled by c scales them by c), as ``ModelStructure.gain_params``; () when there are
        none (a fit then cannot move the data's units into them and does not rescale)."""
        return ()

    def _check(self, params: ArrayLike) -> FloatArray:
        return parameter_vector(params, self.param_names, self.bounds)


@dataclass(frozen=True)
class RationalNoise(NoiseStructure):
    """H(s) = (hb_m s^m + ... + hb_0) / (s^n + ha_{n-1} s^{n-1} + ... + ha_0), unit intensity.

    Parameters are named ``hb{m}..hb0`` then ``ha{n-1}..ha0`` (the ``h`` keeps them apart from
    a :class:`~jitterid.RationalModel`'s ``b*``/``a*``). The intensity of e is fixed at 1: it is
    not identifiable apart from the numerator gain, which therefore carries the noise level.
    ``RationalNoise(0, 1)`` is H = hb0 / (s + ha0), an Ornstein-Uhlenbeck process of variance
    hb0^2 / (2 ha0) and correlation time 1 / ha0.

    Bounds: every ``ha`` > 0 (necessary for stability; sufficient for n <= 2, otherwise an
    unstable candidate is refused when evaluated), ``hb0`` >= 0 (H and -H give the same
    noise, so the sign is fixed). Only the spectrum |H|^2 is identifiable: zeros are
    determined up to reflection in the imaginary axis.

    Parameters
    ----------
    num_order : int, optional
        Numerator order m (>= 0), below ``den_order``.
    den_order : int, optional
        Denominator order n (>= 1).

    Examples
    --------
    >>> import jitterid as ji
    >>> noise = ji.RationalNoise(0, 1)
    >>> noise.param_names
    ('hb0', 'ha0')
    >>> round(float(noise.model([1.0, 2.0]).variance), 6)
    0.25
    """

    num_order: int = 0
    den_order: int = 1

    def __post_init__(self) -> None:
        count(self.den_order, "den_order", minimum=1)
        count(self.num_order, "num_order", minimum=0)
        if self.num_order >= self.den_order:
            raise ValueError(
                f"num_order ({self.num_order}) must be below den_order ({self.den_order}): a "
                "noise model must be strictly proper (finite variance); model a white part by "
                "noise_std"
            )

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        b = tuple(f"hb{i}" for i in range(self.num_order, -1, -1))
        a = tuple(f"ha{i}" for i in range(self.den_order - 1, -1, -1))
        return b + a

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        b = [(-np.inf, np.inf)] * self.num_order + [(0.0, np.inf)]
        return (*b, *[(_RATE_FLOOR, np.inf)] * self.den_order)

    @property
    def gain_params(self) -> tuple[int, ...]:
        """The numerator coefficients hb*: H is linear in them."""
        return tuple(range(self.num_order + 1))

    def model(self, params: ArrayLike) -> NoiseModel:
        x = self._check(params)
        nb = self.num_order + 1
        return NoiseModel(TransferFunction(x[:nb], np.r_[1.0, x[nb:]]))

    def mode_derivatives(
        self, params: ArrayLike, model: NoiseModel | None = None
    ) -> tuple[ComplexArray, ComplexArray]:
        """(dc, dp), shape (P, n): derivatives of the modes (c, p) of (N1) of ``model(params)``
        (in its order) with respect to each parameter, in closed form.

        With H = B / A (A monic) and simple poles, A(p_j) = 0 gives dp_j = -dA(p_j) / A'(p_j),
        and c_j = B(p_j) B(-p_j) / (A'(p_j) A(-p_j)) =: f(p_j) (unit intensity) gives
        dc_j = df + f'(p_j) dp_j, where d acts on the coefficients at fixed p. ``model``:
        ``model(params)`` if already built.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        model : NoiseModel, optional
            ``model(params)`` if already built.
        """
        model = self.model(params) if model is None else model
        num, den = model.tf.num, model.tf.den
        if num.size < self.num_order + 1:  # TransferFunction trims leading zeros: restore them
            num = np.r_[np.zeros(self.num_order + 1 - num.size), num]
        _, p = model.modes
        d1, d2 = np.polyder(den), np.polyder(den, 2) if den.size > 2 else np.zeros(1)
        B, Bm = np.polyval(num, p), np.polyval(num, -p)
        dB, dBm = np.polyval(np.polyder(num), p), np.polyval(np.polyder(num), -p)
        A1, Am, A1m = np.polyval(d1, p), np.polyval(den, -p), np.polyval(d1, -p)
        A2 = np.polyval(d2, p)
        f = B * Bm / (A1 * Am)
        fp = (dB * Bm - B * dBm) / (A1 * Am) - f * (A2 / A1 - A1m / Am)
        rows_c, rows_p = [], []
        for k in range(self.num_order, -1, -1):  # hb_k multiplies s^k
            rows_c.append((p**k * Bm + B * (-p) ** k) / (A1 * Am))
            rows_p.append(np.zeros_like(p))
        for k in range(self.den_order - 1, -1, -1):  # ha_k multiplies s^k
            dA1 = k * p ** (k - 1) if k else np.zeros_like(p)
            dfc = -f * (dA1 / A1 + (-p) ** k / Am)
            dpk = -(p**k) / A1
            rows_c.append(dfc + fp * dpk)
            rows_p.append(dpk)
        return np.array(rows_c) * model.intensity, np.array(rows_p)

    def starts(self, T: float, scale: float) -> list[FloatArray]:
        # Real poles from slow to fast against the Nyquist rate pi/T; the numerator is scaled
        # so that v carries half of scale^2 (the rest may be white noise or jitter).
        T = positive(T, "T")
        scale = positive(scale, "scale")
        out = []
        for w in (0.05, 0.3, 2.0):
            poles = -w * np.pi / T * np.geomspace(1.0, 2.0, self.den_order)
            den = np.real(np.poly(poles))
            num = np.zeros(self.num_order + 1)
            num[-1] = den[-1]
            unit = NoiseModel(TransferFunction(num, den)).variance
            out.append(np.r_[num * scale * np.sqrt(0.5 / unit), den[1:]])
        return out


@dataclass(frozen=True, eq=False)
class KnownNoise(NoiseStructure):
    """A fixed, known noise model (no free parameters): BJ with known H.

    Parameters
    ----------
    noise_model : NoiseModel
        The known noise model.

    Examples
    --------
    >>> import jitterid as ji
    >>> H = ji.NoiseModel(ji.TransferFunction([1.0], [1.0, 2.0]))
    >>> known = ji.KnownNoise(H)
    >>> known.param_names, known.model([]) is H
    ((), True)
    """

    noise_model: NoiseModel

    def __post_init__(self) -> None:
        if not isinstance(self.noise_model, NoiseModel):
            raise TypeError(
                f"noise_model must be a NoiseModel; got {type(self.noise_model).__name__}"
            )

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return ()

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return ()

    def model(self, params: ArrayLike = ()) -> NoiseModel:
        if np.size(params):
            self._check(params)
        return self.noise_model

    def starts(self, T: float, scale: float) -> list[FloatArray]:
        return [np.zeros(0)]


def as_noise_structure(noise: NoiseStructure | NoiseModel) -> NoiseStructure:
    """Accept a structure with free parameters or a known :class:`NoiseModel`."""
    if isinstance(noise, NoiseStructure):
        return noise
    if isinstance(noise, NoiseModel):
        return KnownNoise(noise)
    raise TypeError(
        "noise must be a noise structure (e.g. RationalNoise(0, 1) for H = hb0 / (s + ha0)) or "
        f"a known NoiseModel(TransferFunction(...)); got {type(noise).__name__}. "
        "For white measurement noise (the OE structure) leave noise=None and use noise_std"
    )
