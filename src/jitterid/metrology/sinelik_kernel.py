"""The noise kernel of the structured sine likelihood (:mod:`jitterid.metrology.sinelik_rule`):
the density K(e) of a sample's error e = y - s given the jittered tone's value s.

* **Gaussian** (``half = 0``): K(e) = N(e; 0, sigma^2), white noise of std sigma.
* **Quantiser bin** (``half = q / 2`` > 0, a record quantised with step q): the sample y is
  the centre of the bin that s + v falls in, v ~ N(0, sigma^2) the noise before the
  quantiser, so its probability per unit y is

      K(e) = [Phi((e + q/2) / sigma) - Phi((e - q/2) / sigma)] / q,

  exact for a uniform quantiser (mid-tread rounding), whatever sigma (as sigma -> 0 the box
  of width q: a noise-free quantised record). Modelling the quantiser's error as Gaussian
  noise instead biased the jitter of undithered records
  (:func:`jitterid.metrology.adequacy.dither_finding`).

Derivatives (a = (e + h) / sigma, b = (e - h) / sigma, h = q / 2, D = Phi(a) - Phi(b),
R_a = phi(a) / D, R_b = phi(b) / D)::

    k1  = d ln K / de           = (R_a - R_b) / sigma
    ks  = d ln K / d sigma      = (b R_b - a R_a) / sigma
    k2  = d2 ln K / de2         = ks / sigma - k1^2
    kss = d2 ln K / d sigma2    = (a (1 - a^2) R_a - b (1 - b^2) R_b) / sigma^2 - ks / sigma - ks^2
    k1s = d2 ln K / de d sigma  = (a^2 R_a - b^2 R_b) / sigma^2 - k1 / sigma - k1 ks

(the Gaussian's: -e / sigma^2, e^2 / sigma^3 - 1 / sigma, -1 / sigma^2, -3 e^2 / sigma^4 +
1 / sigma^2, 2 e / sigma^3). K is even in e, so everything is made at |e| and the odd
terms (k1, k1s) signed after: ln D from the lower tail (``log_ndtr`` beyond Phi's
underflow), R_a - R_b as R_b expm1(-2 h |e| / sigma^2): no cancellation where the bin is
narrow against sigma or far in a tail; more than ``INSIDE`` sigma inside the edges, ln K =
-ln q and the derivatives 0, without a CDF (tests/metrology/test_sinelik_kernel.py:
against quadrature of the Gaussian over the bin and central differences).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import special

FloatArray = NDArray[np.float64]

_LN_SQRT_2PI = 0.5 * math.log(2 * math.pi)
#: errors more than this many noise std's inside the bin's edges have ln K = -ln q and no
#: derivatives (:meth:`Kernel._near`; Phi(-10) = 7.6e-24)
INSIDE = 10.0


@dataclass(frozen=True)
class Kernel:
    """The noise kernel K(e) (module doc).

    Parameters
    ----------
    sigma : float
        The noise std (before the quantiser where ``half`` > 0), > 0.
    half : float
        Half the quantisation step q / 2 (0: no quantiser, the Gaussian kernel).
    """

    sigma: float
    half: float = 0.0

    @property
    def const(self) -> float:
        """-ln sigma - ln sqrt(2 pi): the Gaussian kernel's normalisation, which the rule
        adds to every sample's ln p at the end (:meth:`log_rel` is relative to it)."""
        return -math.log(self.sigma) - _LN_SQRT_2PI

    @property
    def std(self) -> float:
        """The kernel's own std, sqrt(sigma^2 + q^2 / 12) (the rule's first guesses of its
        windows)."""
        return math.sqrt(self.sigma**2 + self.half**2 / 3.0)

    def _near(self, u: FloatArray) -> NDArray[np.intp] | None:
        """The indices of the errors ``u`` = |e| within ``INSIDE`` sigma of the bin's edges
        or beyond (None: all of them, wherever the bin is narrower than 2 ``INSIDE``
        sigma). Deeper inside, D = 1 - Phi(-(h - u) / sigma) - Phi(-(h + u) / sigma) is 1
        to within 1e-23: ln K = -ln q and every derivative below 1e-16 of its scale at the
        edges (a noise-free record's bins: sigma at 0.01 q leaves four fifths of the
        nodes there)."""
        if self.half <= INSIDE * self.sigma:
            return None
        return np.flatnonzero(u.reshape(-1) >= self.half - INSIDE * self.sigma)

    def _ln_d(self, u: FloatArray) -> FloatArray:
        """ln D = ln(Phi(a) - Phi(b)) at u = |e| >= 0 (it is even in e), from the lower tail:
        D = Phi((h - u) / sigma) - Phi(-(h + u) / sigma). Phi's lower tail keeps its
        relative precision (erfc): the difference loses only the digits of the bin's width
        against sigma; beyond Phi's underflow (more than ~37 sigma past the bin), the log
        form."""
        hi = (self.half - u) / self.sigma  # D = Phi(hi) - Phi(lo), lo + hi <= 0
        lo = -(self.half + u) / self.sigma
        d = special.ndtr(hi) - special.ndtr(lo)
        far = ~(d > 1e-290)
        with np.errstate(divide="ignore"):
            ln_d = np.log(d)
            if np.any(far):
                l_hi = special.log_ndtr(hi[far])
                ln_d[far] = l_hi + np.log(-np.expm1(special.log_ndtr(lo[far]) - l_hi))
        return np.asarray(ln_d, dtype=float)

    def log_rel(self, e: FloatArray) -> FloatArray:
        """ln K(e) - :attr:`const`.

        Parameters
        ----------
        e : ndarray
            The errors y - s.
        """
        if self.half == 0.0:
            return np.asarray(-0.5 * (e / self.sigma) ** 2, dtype=float)
        u = np.abs(e)
        idx = self._near(u)
        if idx is None:
            ln_d = self._ln_d(u)
        else:
            ln_d = np.zeros(u.shape)
            ln_d.reshape(-1)[idx] = self._ln_d(u.reshape(-1)[idx])
        return np.asarray(ln_d - math.log(2.0 * self.half) - self.const, dtype=float)

    def _bin_terms(
        self, e: FloatArray, ln_rel: FloatArray | None, second: bool
    ) -> tuple[FloatArray, ...]:
        """The bin kernel's (k1, ks), or with ``second`` (k2, kss, k1s, k1, ks), at ``e``:
        made at u = |e| (a, b, R_a, R_b of the module doc there; R_a - R_b = R_b expm1(-2 h
        u / sigma^2), the exponent <= 0: no overflow, no cancellation), the odd ones (k1,
        k1s) signed after, and only where :meth:`_near` (0 deeper inside)."""
        s, h = self.sigma, self.half
        u = np.abs(e)
        idx = self._near(u)
        if idx is not None:
            u = u.reshape(-1)[idx]
            ln_rel = None if ln_rel is None else np.reshape(ln_rel, -1)[idx]
        a, b = (u + h) / s, (u - h) / s
        ln_d = self._ln_d(u) if ln_rel is None else ln_rel + (math.log(2.0 * h) + self.const)
        r_b = np.exp(-0.5 * b * b - _LN_SQRT_2PI - ln_d)
        sk1 = r_b * np.expm1(-2.0 * h * u / (s * s))  # R_a - R_b
        d = 2.0 * h / s  # a - b
        k1 = sk1 / s
        # b R_b - a R_a = (b - a) R_b - a (R_a - R_b): no cancellation
        ks = (-d * r_b - a * sk1) / s
        terms: tuple[FloatArray, ...] = (k1, ks)
        odd: tuple[bool, ...] = (True, False)
        if second:
            s2 = s * s
            k2 = ks / s - k1 * k1
            # g(a) R_a - g(b) R_b = g(a) (R_a - R_b) + (g(a) - g(b)) R_b, g(x) = x (1 - x^2)
            ga = a * (1.0 - a * a)
            kss = (ga * sk1 + d * (1.0 - (a * a + a * b + b * b)) * r_b) / s2 - ks / s - ks * ks
            k1s = (a * a * sk1 + d * (a + b) * r_b) / s2 - k1 / s - k1 * ks
            terms, odd = (k2, kss, k1s, k1, ks), (False, False, True, True, False)
        neg = e < 0 if idx is None else np.reshape(e, -1)[idx] < 0
        out = []
        for v, o in zip(terms, odd, strict=True):
            if o:
                v = np.where(neg, -v, v)
            if idx is not None:
                full = np.zeros(np.shape(e))
                full.reshape(-1)[idx] = v
                v = full
            out.append(v)
        return tuple(out)

    def first(
        self, e: FloatArray, ln_rel: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """(k1, ks): d ln K / de and d ln K / d sigma.

        Parameters
        ----------
        e : ndarray
            The errors y - s.
        ln_rel : ndarray, optional
            :meth:`log_rel` at ``e``, where already made (not computed again).
        """
        s = self.sigma
        if self.half == 0.0:
            return -e / (s * s), e * e / (s * s * s) - 1.0 / s
        k1, ks = self._bin_terms(e, ln_rel, False)
        return k1, ks

    def second(
        self, e: FloatArray, ln_rel: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """(k2, kss, k1s, k1, ks): d2 ln K / de2, d2 ln K / d sigma2, d2 ln K / de d sigma,
        d ln K / de and d ln K / d sigma.

        Parameters
        ----------
        e : ndarray
            The errors y - s.
        ln_rel : ndarray, optional
            :meth:`log_rel` at ``e``, where already made (not computed again).
        """
        s = self.sigma
        s2 = s * s
        if self.half == 0.0:
            return (
                np.full(np.shape(e), -1.0 / s2),
                -3.0 * e * e / (s2 * s2) + 1.0 / s2,
                2.0 * e / (s2 * s),
                -e / s2,
                e * e / (s2 * s) - 1.0 / s,
            )
        k2, kss, k1s, k1, ks = self._bin_terms(e, ln_rel, True)
        return k2, kss, k1s, k1, ks

    def mode_terms(self, e: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(k1, k2) at the errors ``e`` (the rule's Newton steps for the mode).

        Parameters
        ----------
        e : ndarray
            The errors y - s.
        """
        if self.half == 0.0:
            s2 = self.sigma**2
            return -e / s2, np.full(np.shape(e), -1.0 / s2)
        k2, _, _, k1, _ = self.second(e)
        return k1, k2

    def edges(self, y: FloatArray, c: float, A: float) -> tuple[FloatArray, FloatArray]:
        """(z_lo, z_hi): sin psi at the bin's edges, (y - c -+ q/2) / A, where the bin kernel
        falls off over sigma (the rule cuts its panels at their roots on each branch).

        Parameters
        ----------
        y : ndarray
            The samples.
        c, A : float
            The tone's offset and amplitude (> 0).
        """
        return (y - c - self.half) / A, (y - c + self.half) / A
