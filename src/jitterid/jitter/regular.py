"""Jitter laws that are smooth (regular) in their shape parameter, and their families.

The paper's family (26), extended to real ``n`` (:class:`~jitterid.SumOfUniforms`), has a kink
in ``n`` at every integer, so its Fisher information for ``(n, a)`` is not a valid bound and ML
misses it by 3-6x (docs/ml_and_crb.md). The laws here are analytic in all their parameters:

* :class:`GeneralizedNormal` ``(std, beta)``: density proportional to
  ``exp(-|tau / alpha|^beta)``; ``beta = 1`` Laplace, ``beta = 2`` Gaussian, ``beta -> inf``
  uniform. Like (26) it spans the peaked-to-flat range at a given std, but smoothly.
* :class:`DualDirac` ``(rj, dj)``: the serial-link jitter model, Gaussian random jitter
  ``N(0, rj^2)`` convolved with two equal Diracs at ``+-dj/2`` (deterministic jitter of
  peak-to-peak ``dj``).
* :class:`GaussianScaleMixture` ``(std, rho)``: two zero-mean Gaussians of variances
  ``std^2 (1 -+ rho)``, probability 1/2 each: heavier tails than the Gaussian at one std.

Their families (:class:`GeneralizedNormalFamily`, :class:`DualDiracFamily`,
:class:`GaussianScaleMixtureFamily`) give the density's
derivative in the parameters in closed form (:meth:`JitterFamily.pdf_gradient`), which the
moments' derivative pass (:mod:`jitterid.estimation.jacobians`) and the likelihood's score use
at the quadrature nodes instead of differences.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import digamma, gammainccinv, gammaln

from jitterid import _checks

from .laws import (
    _GL_NODES,
    _SCALE_FLOOR,
    GAUSS_SUPPORT_SIGMAS,
    JitterFamily,
    JitterLaw,
    _gl_panels,
    _scale_range,
    _size,
    _upper,
)

__all__ = [
    "BETA_MAX",
    "BETA_MIN",
    "GN_TAIL_MASS",
    "DualDirac",
    "DualDiracFamily",
    "GaussianScaleMixture",
    "GaussianScaleMixtureFamily",
    "GeneralizedNormal",
    "GeneralizedNormalFamily",
]

#: Mass of :class:`GeneralizedNormal` outside its (truncated) support: that of the Gaussian
#: outside +-8.5 sigma (``2 Phi(-8.5) = 1.9e-17``,
#: :data:`~jitterid.jitter.laws.GAUSS_SUPPORT_SIGMAS`), so that ``beta = 2`` has exactly
#: :class:`~jitterid.Gaussian`'s support.
GN_TAIL_MASS = math.erfc(GAUSS_SUPPORT_SIGMAS / math.sqrt(2.0))

#: Range of ``beta`` accepted by :class:`GeneralizedNormal`. Below 0.5 the tails reach
#: thousands of standard deviations (the support at beta = 0.5 is already +-185 std); above
#: 1000 the law is the uniform one to 1e-3 (use :class:`~jitterid.Uniform`).
BETA_MIN, BETA_MAX = 0.5, 1000.0

#: Geometric grading of the breakpoints towards tau = 0, where ``|tau|^beta`` is not
#: analytic: cuts at ``alpha 2^-k``, k = 1.._GRADE_LEVELS.
_GRADE_LEVELS = 12

#: Breakpoints where ``u = |tau / alpha|^beta`` is a power of two from 2^_U_LO to 2^_U_HI:
#: they follow the density's shoulders, steep for large beta (width ~ alpha / beta).
_U_LO, _U_HI = -4, 5

#: Cuts around each centre of :class:`DualDirac`, in units of rj: the zones of the library's
#: Gaussian rule (panels of 0.6 rj within 3 rj, 0.75 rj to 6 rj, 1.25 rj to 8.5 rj).
_DD_ZONES = np.r_[
    np.arange(0.0, 3.0, 0.6), np.arange(3.0, 6.0, 0.75), 6.0, 7.25, GAUSS_SUPPORT_SIGMAS
]
_DD_MIN_GAP = 0.2  # cuts of the two centres closer than this (in rj) are merged

#: |f| times the sub-panel width at most this in :meth:`GeneralizedNormal.cf` (64 nodes).
_CF_FH_MAX = 8.0


def _sym(half: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[-half[::-1], half[1:]]`` for increasing ``half`` starting at 0: a symmetric grid."""
    return np.concatenate([-half[:0:-1], half])


# --------------------------------------------------------------------------------------------
# generalized normal
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, init=False, repr=False)
class GeneralizedNormal(JitterLaw):
    """Generalized normal jitter:
    ``p(tau) = beta / (2 alpha Gamma(1/beta)) exp(-|tau/alpha|^beta)``.

    ``alpha = std sqrt(Gamma(1/beta) / Gamma(3/beta))`` makes the standard deviation ``std``
    whatever the shape ``beta``: ``beta = 1`` is the Laplace law, ``beta = 2`` the Gaussian
    ``N(0, std^2)`` (:class:`~jitterid.Gaussian`), and as ``beta -> inf`` the law tends to the
    uniform ``U(-sqrt(3) std, sqrt(3) std)``. The density is analytic in ``(std, beta)``, so a
    family over ``beta`` is regular (unlike (26) with real ``n``).

    The *effective* support is ``[-L, L]`` with ``L = alpha u^(1/beta)``,
    ``u = Q^{-1}(1/beta, 1.9e-17)`` (``Q`` the regularised upper incomplete gamma function):
    the mass outside it is :data:`GN_TAIL_MASS` = 1.9e-17, below double precision, as for
    :class:`~jitterid.Gaussian` (for ``beta = 2``, ``L = 8.5 std`` exactly). :meth:`pdf` is zero
    outside it (the quadrature sees that law); :meth:`sample` and :attr:`var` are those of the
    untruncated law, and :meth:`cf` is the integral of :meth:`pdf` (they differ by 1.9e-17).

    :meth:`breakpoints` are tau = 0 (where ``|tau|^beta`` is not analytic unless beta is an
    even integer), a geometric grading ``alpha 2^-k`` towards it, the points where
    ``|tau/alpha|^beta`` is a power of two from 1/16 to 32 (the shoulders at ``+-alpha``, of
    width ``~alpha/beta``), and the support's ends: Gauss-Legendre panels between them
    integrate the density to ~1e-14 with 64 nodes (:meth:`~jitterid.JitterLaw.expect`).

    :meth:`cf` has no closed form for general beta; it is ``2 int_0^L cos(2 pi f tau) p(tau)
    dtau`` by the same panels, cut into sub-panels with ``|f| h <= 8`` for the largest ``|f|``
    asked for (its cost grows linearly with ``max |f|``). :meth:`sample` is exact:
    ``|tau| = alpha G^(1/beta) U`` with ``G ~ Gamma(1 + 1/beta)``, ``U ~ U(0, 1)`` and a random
    sign (no underflow of small gamma variates for large beta).

    Parameters
    ----------
    std : float
        Standard deviation, ``> 0``.
    beta : float
        Shape, in ``[0.5, 1000]`` (:data:`BETA_MIN`, :data:`BETA_MAX`).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> law = ji.GeneralizedNormal(0.1, 2.0)
    >>> bool(np.allclose(law.pdf([0.0, 0.05]), ji.Gaussian(0.1).pdf([0.0, 0.05])))
    True
    >>> round(float(law.expect(lambda t: t**2)), 12)  # the variance, std^2
    0.01
    >>> # Laplace (beta = 1): cf = 1/(1 + 2 pi^2 std^2 f^2)
    >>> round(float(ji.GeneralizedNormal(0.1, 1.0).cf(1.0).real), 6)
    0.835148
    """

    _std: float
    beta: float
    _alpha: float = field(compare=False)
    _lognorm: float = field(compare=False)
    _half: float = field(compare=False)

    def __init__(self, std: float, beta: float) -> None:
        # ``std`` is JitterLaw's property, so the field is ``_std`` and __init__ is written out
        std = _checks.positive(std, "std")
        try:
            beta = float(beta)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"beta must be a real number; got {beta!r}") from exc
        if not (math.isfinite(beta) and BETA_MIN <= beta <= BETA_MAX):
            raise ValueError(
                f"beta must lie in [{BETA_MIN:g}, {BETA_MAX:g}] (1 Laplace, 2 Gaussian, large: "
                f"nearly uniform; use Uniform(sqrt(3) std) beyond {BETA_MAX:g}); got {beta!r}"
            )
        object.__setattr__(self, "_std", std)
        object.__setattr__(self, "beta", beta)
        alpha = std * math.exp(0.5 * (gammaln(1.0 / beta) - gammaln(3.0 / beta)))
        object.__setattr__(self, "_alpha", alpha)
        object.__setattr__(
            self, "_lognorm", math.log(beta) - math.log(2.0 * alpha) - float(gammaln(1.0 / beta))
        )
        u_max = float(gammainccinv(1.0 / beta, GN_TAIL_MASS))
        object.__setattr__(self, "_half", alpha * u_max ** (1.0 / beta))

    def __repr__(self) -> str:
        return f"GeneralizedNormal(std={self._std!r}, beta={self.beta!r})"

    @property
    def std(self) -> float:
        return self._std

    @property
    def alpha(self) -> float:
        """The scale ``alpha = std sqrt(Gamma(1/beta) / Gamma(3/beta))`` of the density."""
        return self._alpha

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        z = np.abs(t) / self._alpha
        dens = np.exp(self._lognorm - z**self.beta)
        return np.where(np.abs(t) <= self._half, dens, 0.0)

    def dlogpdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        """``d ln p(tau) / d (std, beta)``, shape ``(2,) + tau.shape`` (zero outside the support).

        With ``u = |tau/alpha|^beta`` and ``a' = d ln alpha / d beta = (3 psi(3/beta) -
        psi(1/beta)) / (2 beta^2)``: ``d/d std = (beta u - 1) / std`` and ``d/d beta = 1/beta
        + psi(1/beta)/beta^2 - a' - u (ln |tau/alpha| - beta a')`` (``u ln`` is 0 at tau = 0).

        Parameters
        ----------
        tau : array_like
            Jitter values in s.
        """
        t = _checks.real_array(tau, "tau")
        b = self.beta
        z = np.abs(t) / self._alpha
        u = z**b
        da = (3.0 * digamma(3.0 / b) - digamma(1.0 / b)) / (2.0 * b * b)
        with np.errstate(divide="ignore", invalid="ignore"):
            ulog = np.where(z > 0.0, u * np.log(np.where(z > 0.0, z, 1.0)), 0.0)
        d_std = (b * u - 1.0) / self.std
        d_beta = 1.0 / b + digamma(1.0 / b) / (b * b) - da - ulog + b * da * u
        inside = np.abs(t) <= self._half
        return np.stack([np.where(inside, d_std, 0.0), np.where(inside, d_beta, 0.0)])

    def pdf_gradient(self, tau: ArrayLike) -> NDArray[np.float64]:
        """``d p(tau) / d (std, beta)``, shape ``(2,) + tau.shape``.

        Parameters
        ----------
        tau : array_like
            Jitter values in s.
        """
        return np.asarray(self.pdf(tau) * self.dlogpdf(tau), dtype=float)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        flat = arr.ravel()
        fmax = float(np.max(np.abs(flat))) if flat.size else 0.0
        edges = self.breakpoints()
        edges = edges[edges >= 0.0]
        widest = float(np.max(np.diff(edges)))
        pieces = max(1, math.ceil(fmax * widest / _CF_FH_MAX))
        if pieces > 1:
            edges = np.concatenate(
                [np.linspace(a, b, pieces + 1)[:-1] for a, b in itertools.pairwise(edges)]
                + [edges[-1:]]
            )
        nodes, w = _gl_panels(edges, _GL_NODES)
        w = 2.0 * w * self.pdf(nodes)
        out = np.empty(flat.shape)
        chunk = max(1, 2**22 // max(1, nodes.size))
        for start in range(0, flat.size, chunk):
            fs = flat[start : start + chunk]
            out[start : start + chunk] = np.cos(2.0 * np.pi * np.outer(fs, nodes)) @ w
        return out.reshape(arr.shape).astype(complex)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        g = gen.gamma(1.0 + 1.0 / self.beta, size=shape)
        mag = self._alpha * g ** (1.0 / self.beta) * gen.random(shape)
        return np.where(gen.random(shape) < 0.5, -mag, mag)

    @property
    def var(self) -> float:
        return self.std**2

    @property
    def support(self) -> tuple[float, float]:
        return (-self._half, self._half)

    def breakpoints(self) -> NDArray[np.float64]:
        a, b, h = self._alpha, self.beta, self._half
        grade = 2.0 ** -np.arange(1.0, _GRADE_LEVELS + 1.0)
        shoulder = 2.0 ** (np.arange(_U_LO, _U_HI + 1.0) / b)
        z = np.unique(np.concatenate([[0.0], grade, shoulder]))
        pts = a * z
        pts = pts[pts < h * (1.0 - 1e-9)]
        return _sym(np.r_[pts, h])

    @property
    def params(self) -> dict[str, float]:
        return {"std": self.std, "beta": self.beta}


# --------------------------------------------------------------------------------------------
# dual Dirac
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DualDirac(JitterLaw):
    """The dual-Dirac jitter model of serial links: ``tau = rj Z + (dj/2) B``, ``Z ~ N(0, 1)``,
    ``B = +-1`` with probability 1/2 each.

    Random jitter ``N(0, rj^2)`` convolved with two equal Diracs at ``+-dj/2`` (``dj`` the
    peak-to-peak deterministic jitter): density
    ``p(tau) = (phi_rj(tau - dj/2) + phi_rj(tau + dj/2)) / 2``, characteristic function
    ``phi(f) = exp(-2 pi^2 rj^2 f^2) cos(pi f dj)``, variance ``rj^2 + dj^2 / 4``. With
    ``dj = 0`` it is :class:`~jitterid.Gaussian` ``(rj)``.

    As for :class:`~jitterid.Gaussian`, the effective support is ``[-dj/2 - 8.5 rj, dj/2 +
    8.5 rj]`` (:data:`~jitterid.jitter.laws.GAUSS_SUPPORT_SIGMAS`; the mass outside is below
    1.9e-17): :meth:`pdf` is zero outside it, while :meth:`cf`, :meth:`sample` and :attr:`var`
    are those of the untruncated law. The density is analytic; :meth:`breakpoints` cut each
    Gaussian into the zones of the library's Gaussian rule (panels of 0.6 rj within 3 rj of
    its centre, longer in the tails), merged where the two overlap.

    Parameters
    ----------
    rj : float
        Standard deviation of the random (Gaussian) jitter, ``> 0``.
    dj : float
        Peak-to-peak deterministic jitter, ``>= 0`` (the Diracs sit at ``+-dj/2``).

    Examples
    --------
    >>> import jitterid as ji
    >>> law = ji.DualDirac(0.05, 0.3)
    >>> round(law.std, 6)  # sqrt(rj^2 + dj^2 / 4)
    0.158114
    >>> round(float(law.cf(1.0).real), 6)
    0.559483
    """

    rj: float
    dj: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "rj", _checks.positive(self.rj, "rj"))
        try:
            dj = _checks.positive(self.dj, "dj", allow_zero=True)
        except ValueError as exc:
            raise ValueError(
                f"{exc} (dj is the peak-to-peak deterministic jitter; dj = 0 is Gaussian jitter)"
            ) from None
        object.__setattr__(self, "dj", dj)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        out = np.exp(-2.0 * np.pi**2 * self.rj**2 * arr**2) * np.cos(np.pi * arr * self.dj)
        return out.astype(complex)

    def _parts(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """(x1, x2, phi(x1), phi(x2)): offsets from the two centres and the Gaussian there."""
        r, c = self.rj, 0.5 * self.dj
        x1, x2 = t - c, t + c
        k = 1.0 / (r * math.sqrt(2.0 * math.pi))
        return x1, x2, k * np.exp(-0.5 * (x1 / r) ** 2), k * np.exp(-0.5 * (x2 / r) ** 2)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        _, _, g1, g2 = self._parts(-np.abs(t))  # evaluated on one side: exact symmetry
        return np.where(np.abs(t) <= self.support[1], 0.5 * (g1 + g2), 0.0)

    def pdf_gradient(self, tau: ArrayLike) -> NDArray[np.float64]:
        """``d p(tau) / d (rj, dj)``, shape ``(2,) + tau.shape`` (zero outside the support):
        ``dp/drj = sum_i phi(x_i) (x_i^2/rj^2 - 1) / (2 rj)`` and
        ``dp/ddj = (x1 phi(x1) - x2 phi(x2)) / (4 rj^2)``, ``x1,2 = tau -+ dj/2``.

        Parameters
        ----------
        tau : array_like
            Jitter values in s.
        """
        t = _checks.real_array(tau, "tau")
        r = self.rj
        x1, x2, g1, g2 = self._parts(t)
        d_rj = 0.5 * (g1 * ((x1 / r) ** 2 - 1.0) + g2 * ((x2 / r) ** 2 - 1.0)) / r
        d_dj = 0.25 * (x1 * g1 - x2 * g2) / r**2
        inside = np.abs(t) <= self.support[1]
        return np.stack([np.where(inside, d_rj, 0.0), np.where(inside, d_dj, 0.0)])

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        sign = np.where(gen.random(shape) < 0.5, -1.0, 1.0)
        return gen.normal(0.0, self.rj, size=shape) + 0.5 * self.dj * sign

    @property
    def var(self) -> float:
        return self.rj**2 + 0.25 * self.dj**2

    @property
    def support(self) -> tuple[float, float]:
        h = 0.5 * self.dj + GAUSS_SUPPORT_SIGMAS * self.rj
        return (-h, h)

    def breakpoints(self) -> NDArray[np.float64]:
        r, c, h = self.rj, 0.5 * self.dj, self.support[1]
        zones = _DD_ZONES * r
        cand = np.unique(np.abs(np.concatenate([c + zones, c - zones, -c + zones])))
        cand = cand[cand < h]
        # thin from 0 outwards so that the two centres' cuts do not crowd each other
        keep = [0.0]
        for v in cand[cand > 0.0]:
            if v - keep[-1] >= _DD_MIN_GAP * r:
                keep.append(float(v))
        if h - keep[-1] < _DD_MIN_GAP * r and len(keep) > 1:
            keep.pop()
        return _sym(np.r_[keep, h])

    @property
    def params(self) -> dict[str, float]:
        return {"rj": self.rj, "dj": self.dj}


# --------------------------------------------------------------------------------------------
# Gaussian scale mixture
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GaussianScaleMixture(JitterLaw):
    """Two zero-mean Gaussians of different widths, probability 1/2 each: heavy-tailed jitter
    (a jitter source whose strength changes between two states, the sum of a narrow and a
    wide random jitter seen through a switch).

    ``tau ~ N(0, sigma^2 (1 - rho))`` or ``N(0, sigma^2 (1 + rho))``: density
    ``p(tau) = (phi_1(tau) + phi_2(tau)) / 2``, characteristic function
    ``phi(f) = (exp(-2 pi^2 s_1^2 f^2) + exp(-2 pi^2 s_2^2 f^2)) / 2`` with
    ``s_1,2 = sigma sqrt(1 -+ rho)``, variance ``sigma^2`` and kurtosis ``3 (1 + rho^2)`` (3 to
    6). With ``rho = 0`` it is :class:`~jitterid.Gaussian` ``(sigma)``. The density is even
    in ``rho``, so the likelihood is flat at ``rho = 0`` to first order in ``rho`` (a search
    runs in ``rho^2``: :attr:`GaussianScaleMixtureFamily.even_index`).

    As for :class:`~jitterid.Gaussian`, the support is ``+-8.5 s_2``
    (:data:`~jitterid.jitter.laws.GAUSS_SUPPORT_SIGMAS`): :meth:`pdf` is zero outside it,
    while :meth:`cf`, :meth:`sample` and :attr:`var` are those of the untruncated law.

    Parameters
    ----------
    sigma : float
        Standard deviation of the jitter, ``> 0`` (s).
    rho : float
        The components' variance split, ``0 <= rho < 1``.

    Examples
    --------
    >>> import jitterid as ji
    >>> law = ji.GaussianScaleMixture(0.1, 0.6)
    >>> round(law.std, 6), round(law.kurtosis, 4)
    (0.1, 4.08)
    >>> round(float(law.cf(1.0).real), 6)
    0.826633
    """

    sigma: float
    rho: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma", _checks.positive(self.sigma, "sigma"))
        rho = float(self.rho)
        if not 0.0 <= rho < 1.0:
            raise ValueError(
                f"rho must lie in [0, 1) (the variance split: the components' variances are "
                f"sigma^2 (1 -+ rho)); got {self.rho!r}"
            )
        object.__setattr__(self, "rho", rho)

    @property
    def scales(self) -> tuple[float, float]:
        """The two components' standard deviations ``sigma sqrt(1 -+ rho)`` (s)."""
        return (self.sigma * math.sqrt(1.0 - self.rho), self.sigma * math.sqrt(1.0 + self.rho))

    @property
    def kurtosis(self) -> float:
        """``E[tau^4] / sigma^4 = 3 (1 + rho^2)``."""
        return 3.0 * (1.0 + self.rho**2)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        s1, s2 = self.scales
        k = -2.0 * np.pi**2 * arr**2
        return (0.5 * (np.exp(k * s1**2) + np.exp(k * s2**2))).astype(complex)

    def _parts(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """(z_1, z_2, phi_1, phi_2): tau^2 / s_i^2 and the components' densities."""
        s1, s2 = self.scales
        z1, z2 = (t / s1) ** 2, (t / s2) ** 2
        k = 1.0 / math.sqrt(2.0 * math.pi)
        return z1, z2, k * np.exp(-0.5 * z1) / s1, k * np.exp(-0.5 * z2) / s2

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        _, _, g1, g2 = self._parts(t)
        return np.where(np.abs(t) <= self.support[1], 0.5 * (g1 + g2), 0.0)

    def pdf_gradient(self, tau: ArrayLike) -> NDArray[np.float64]:
        """``d p(tau) / d (sigma, rho)``, shape ``(2,) + tau.shape`` (zero outside the support):
        ``dp/dsigma = sum_i phi_i (z_i - 1) / (2 sigma)`` and
        ``dp/drho = sum_i e_i phi_i (z_i - 1) / (4 (1 + e_i rho))``, ``z_i = tau^2 / s_i^2``,
        ``e_1,2 = -+1``.

        Parameters
        ----------
        tau : array_like
            Jitter values in s.
        """
        t = _checks.real_array(tau, "tau")
        z1, z2, g1, g2 = self._parts(t)
        r = self.rho
        d_sigma = 0.5 * (g1 * (z1 - 1.0) + g2 * (z2 - 1.0)) / self.sigma
        d_rho = 0.25 * (g2 * (z2 - 1.0) / (1.0 + r) - g1 * (z1 - 1.0) / (1.0 - r))
        inside = np.abs(t) <= self.support[1]
        return np.stack([np.where(inside, d_sigma, 0.0), np.where(inside, d_rho, 0.0)])

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        s1, s2 = self.scales
        scale = np.where(gen.random(shape) < 0.5, s1, s2)
        return scale * gen.standard_normal(shape)

    @property
    def var(self) -> float:
        return self.sigma**2

    @property
    def support(self) -> tuple[float, float]:
        h = GAUSS_SUPPORT_SIGMAS * self.scales[1]
        return (-h, h)

    def breakpoints(self) -> NDArray[np.float64]:
        s1, s2 = self.scales
        h = self.support[1]
        cand = np.unique(np.concatenate([_DD_ZONES * s1, _DD_ZONES * s2]))
        cand = cand[cand < h]
        keep = [0.0]  # the narrow component's cuts set the finest spacing
        for v in cand[cand > 0.0]:
            if v - keep[-1] >= _DD_MIN_GAP * s1:
                keep.append(float(v))
        if h - keep[-1] < _DD_MIN_GAP * s1 and len(keep) > 1:
            keep.pop()
        return _sym(np.r_[keep, h])

    @property
    def params(self) -> dict[str, float]:
        return {"sigma": self.sigma, "rho": self.rho}


# --------------------------------------------------------------------------------------------
# families
# --------------------------------------------------------------------------------------------


class _ClosedFormGradient(JitterFamily):
    """A family whose laws give ``d p(tau) / d params`` in closed form (their own
    ``pdf_gradient``, in the family's parameter order)."""

    def pdf_gradient(self, params: Sequence[float], tau: ArrayLike) -> NDArray[np.float64]:
        """``d p(tau) / d params`` at ``params`` (the law's own ``pdf_gradient``), shape
        ``(len(params),) + tau.shape``.

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        tau : array_like
            Jitter values in s.
        """
        law = self.law(params)
        assert isinstance(law, (GeneralizedNormal, DualDirac, GaussianScaleMixture))
        return law.pdf_gradient(tau)


@dataclass(frozen=True)
class GeneralizedNormalFamily(_ClosedFormGradient):
    """:class:`GeneralizedNormal` with unknown ``(std, beta)``: a regular family of shapes.

    ``std`` is a scale (the law is that of ``std xi`` with xi's law free of it), so its
    derivatives move the quadrature nodes only (``scale_index = 0``); ``beta`` changes the
    density, whose derivative :meth:`pdf_gradient` gives in closed form. The support moves
    with ``beta`` only where the density is below 1e-16 of its peak, so its edges carry no
    part of the derivative that double precision can see.

    Parameters
    ----------
    std_max : float or None
        Upper bound on ``std`` (``None``: unbounded).
    std_min : float
        Lower bound on ``std``, a small positive floor excluding 0; default ``1e-12``.
    beta_min, beta_max : float
        Bounds on ``beta``, default ``[1, 50]`` (Laplace to nearly uniform; within
        ``[0.5, 1000]``).

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.GeneralizedNormalFamily(std_max=0.5)
    >>> fam.param_names, fam.bounds[1]
    (('std', 'beta'), (1.0, 50.0))
    >>> fam.law([0.1, 2.0])
    GeneralizedNormal(std=0.1, beta=2.0)
    >>> fam.pdf_gradient([0.1, 2.0], [0.0, 0.1]).shape
    (2, 2)
    """

    std_max: float | None = None
    std_min: float = _SCALE_FLOOR
    beta_min: float = 1.0
    beta_max: float = 50.0
    param_names: ClassVar[tuple[str, ...]] = ("std", "beta")
    scale_index: ClassVar[int | None] = 0

    def __post_init__(self) -> None:
        _scale_range(self, "std")
        lo = _checks.positive(self.beta_min, "beta_min")
        hi = _checks.positive(self.beta_max, "beta_max")
        if not BETA_MIN <= lo < hi <= BETA_MAX:
            raise ValueError(
                f"beta_min < beta_max must lie in [{BETA_MIN:g}, {BETA_MAX:g}]; got "
                f"beta_min={self.beta_min!r}, beta_max={self.beta_max!r}"
            )

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return (
            (float(self.std_min), _upper(self.std_max, "std_max")),
            (float(self.beta_min), float(self.beta_max)),
        )

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return GeneralizedNormal(values[0], values[1])

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = min(T / 4.0, _upper(self.std_max, "std_max"))
        return [(s, b) for b in (1.0, 2.0, 8.0) for s in (top / 6.0, top * 0.4)]


@dataclass(frozen=True)
class DualDiracFamily(_ClosedFormGradient):
    """:class:`DualDirac` with unknown ``(rj, dj)``.

    Neither parameter is a scale of the whole law, so both derivatives come from
    :meth:`pdf_gradient` (closed form) at fixed quadrature nodes; the support moves with
    them only where the density is below 1e-16 of its peak. At ``dj = 0`` the density is even
    in ``dj``: its score in ``dj`` vanishes there, and ``dj`` is identified only for
    ``dj`` well away from 0 (a few ``rj``).

    Parameters
    ----------
    rj_max : float or None
        Upper bound on ``rj`` (``None``: unbounded).
    rj_min : float
        Lower bound on ``rj``, a positive floor; default ``1e-12``.
    dj_max : float or None
        Upper bound on ``dj`` (``None``: unbounded); its lower bound is 0.

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.DualDiracFamily(dj_max=1.0)
    >>> fam.bounds
    ((1e-12, inf), (0.0, 1.0))
    >>> fam.law([0.05, 0.3]).std == ji.DualDirac(0.05, 0.3).std
    True
    """

    rj_max: float | None = None
    rj_min: float = _SCALE_FLOOR
    dj_max: float | None = None
    param_names: ClassVar[tuple[str, ...]] = ("rj", "dj")
    even_index: ClassVar[int | None] = 1

    def __post_init__(self) -> None:
        _upper(self.dj_max, "dj_max")
        _scale_range(self, "rj")

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return (
            (float(self.rj_min), _upper(self.rj_max, "rj_max")),
            (0.0, _upper(self.dj_max, "dj_max")),
        )

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return DualDirac(values[0], values[1])

    def start_for_std(self, std: float) -> tuple[float, ...]:
        """Random and deterministic parts sharing the variance: rj = std / sqrt 2, dj =
        sqrt 2 std (rj^2 + dj^2 / 4 = std^2), clipped into the bounds.

        Parameters
        ----------
        std : float
            The jitter standard deviation to match, in s.
        """
        std = _checks.positive(std, "std")
        (rlo, rhi), (dlo, dhi) = self.bounds
        return (
            float(min(max(std / math.sqrt(2.0), rlo), rhi)),
            float(min(max(std * math.sqrt(2.0), dlo), dhi)),
        )

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = T / 4.0
        rj_top = min(top, _upper(self.rj_max, "rj_max"))
        return [(r, d) for d in (top / 2.0, 2.0 * top) for r in (rj_top / 6.0, rj_top * 0.4)]


@dataclass(frozen=True)
class GaussianScaleMixtureFamily(_ClosedFormGradient):
    """:class:`GaussianScaleMixture` with unknown ``(sigma, rho)``: Gaussian jitter and heavier
    tails (kurtosis 3 to ``3 (1 + rho_max^2)``) at one std ``sigma``.

    ``sigma`` is a scale (``scale_index = 0``); ``rho``'s derivative is
    :meth:`pdf_gradient`'s, in closed form. The density is even in ``rho``
    (``even_index = 1``): the likelihood's score in ``rho`` vanishes at ``rho = 0`` (the
    Gaussian), where a search in ``rho^2`` sees a regular quadratic.

    Parameters
    ----------
    sigma_max : float or None
        Upper bound on ``sigma`` (``None``: unbounded).
    sigma_min : float
        Lower bound on ``sigma``, a positive floor; default ``1e-12``.
    rho_max : float
        Upper bound on ``rho``, in ``(0, 0.99]``; default ``0.95`` (components' stds in the
        ratio 6.2, kurtosis 5.7).

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.GaussianScaleMixtureFamily(sigma_max=1.0)
    >>> fam.bounds
    ((1e-12, 1.0), (0.0, 0.95))
    >>> fam.law([0.1, 0.6]).kurtosis
    4.08
    """

    sigma_max: float | None = None
    sigma_min: float = _SCALE_FLOOR
    rho_max: float = 0.95
    param_names: ClassVar[tuple[str, ...]] = ("sigma", "rho")
    scale_index: ClassVar[int | None] = 0
    even_index: ClassVar[int | None] = 1

    def __post_init__(self) -> None:
        _scale_range(self, "sigma")
        if not 0.0 < float(self.rho_max) <= 0.99:
            raise ValueError(
                f"rho_max must lie in (0, 0.99] (at rho -> 1 the narrow component vanishes); "
                f"got {self.rho_max!r}"
            )

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return (
            (float(self.sigma_min), _upper(self.sigma_max, "sigma_max")),
            (0.0, float(self.rho_max)),
        )

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return GaussianScaleMixture(values[0], values[1])

    def start_for_std(self, std: float) -> tuple[float, ...]:
        """``(std, 0.5)`` clipped into the bounds: a start between the Gaussian and the
        widest split, at the std measured otherwise.

        Parameters
        ----------
        std : float
            The jitter standard deviation to match, in s.
        """
        std = _checks.positive(std, "std")
        (slo, shi), (_, rhi) = self.bounds
        return (float(min(max(std, slo), shi)), float(min(0.5, rhi)))

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = min(T / 4.0, _upper(self.sigma_max, "sigma_max"))
        rhi = float(self.rho_max)
        return [(s, r) for r in (0.3 * rhi, 0.7 * rhi) for s in (top / 6.0, top * 0.4)]
