"""Sampling-jitter laws: characteristic function, density, sampler and moments.

Sample ``k`` is taken at ``k T + tau_k`` with ``tau_k`` i.i.d. with pdf ``p(tau)``. Everything
the rest of the package needs about the jitter is collected in a :class:`JitterLaw`:

* the characteristic function with the paper's sign convention (footnote 3 of Eng & Gustafsson,
  in Lemma 1, which turns (13) into ``mu_Y(f) = int S_c(psi) phi(-psi) d_N(f - psi) dpsi``),

  .. math:: \\varphi(f) = E[e^{-i 2 \\pi f \\tau}],  \\qquad f \\text{ in Hz},

* the density ``p(tau)`` on a finite support, together with *breakpoints* between which the
  density is analytic, so that expectations ``E[g(tau)]`` can be computed to machine precision
  by Gauss-Legendre panels (:meth:`JitterLaw.quadrature`, :meth:`JitterLaw.expect`),
* an exact sampler and the first two moments.

Concrete laws: :class:`NoJitter`, :class:`Uniform` (15a), :class:`Gaussian` (15b),
:class:`SumOfUniforms` (the paper's family (26), extended to real ``n``) and
:class:`CustomJitter` (any user density on a bounded interval).

For the model structures with a parameterised jitter law (JOE (2c), JBJ (2d)) a
:class:`JitterFamily` maps a parameter vector to a law, and carries bounds and starting values
for a numerical search: :class:`UniformFamily`, :class:`GaussianFamily`,
:class:`SumOfUniformsFamily`.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np
from numpy.polynomial.legendre import leggauss
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline, PPoly

from jitterid import _checks, finite_diff

__all__ = [
    "BandRule",
    "CustomJitter",
    "Gaussian",
    "GaussianFamily",
    "JitterFamily",
    "JitterLaw",
    "NoJitter",
    "Shifted",
    "SumOfUniforms",
    "SumOfUniformsFamily",
    "Uniform",
    "UniformFamily",
]

#: Half-width of the effective support of :class:`Gaussian`, in standard deviations. The mass
#: outside ``[-8.5 sigma, 8.5 sigma]`` is ``2 Phi(-8.5) = 1.9e-17``, below double precision.
GAUSS_SUPPORT_SIGMAS = 8.5

#: The Gaussian's quadrature zones (in band sigmas) and their longest panels, left to right
#: (:attr:`Gaussian.band_rule`): the 5-point rule's error on a panel of length h near the mode
#: scales as pdf h^10, so panels are shorter where the density is large (0.6 sigma within
#: 3 sigma: ~1e-13 per panel) and longer in the tails, where the density is small.
_GAUSS_ZONES = (3.0, 6.0)
_GAUSS_ZONE_PANELS = (1.7, 0.9, 0.6, 0.9, 1.7)

#: Largest ``n`` accepted by :class:`SumOfUniforms` (``n + 1`` uniforms). Beyond a few tens the
#: law is Gaussian to within plotting accuracy anyway (see Fig. 4 of the paper).
N_MAX = 50.0

#: Distance from an integer below which ``n + 1`` is treated as that integer.
_INTEGER_TOL = 1e-12

#: ``c / b`` from which :class:`SumOfUniforms` evaluates its density as a CDF difference.
_WIDE_WINDOW = 1e-3

#: ``c / (K b)`` below which :meth:`SumOfUniforms.pdf_gradient` integrates its window form by
#: Gauss-Legendre (the CDF-difference form's 1/c^2 terms lose ~K^2 (b / c)^2 ulps: 1e-12).
_GRADIENT_WINDOW = 0.01

#: Distance below an integer ``n`` within which :meth:`SumOfUniforms.pdf_gradient` gives no
#: closed form (its cancellation costs a relative ~K 1e-16 / sqrt(distance): 3e-9 here).
_GRADIENT_BELOW = 1e-9

#: :meth:`SumOfUniforms.pdf_gradient` evaluates its window form at more than this many times
#: m^2 points from the piecewise Chebyshev form of its values (fitted at ~m^2 points).
_GRADIENT_DIRECT = 4

#: Default number of Gauss-Legendre nodes per panel.
_GL_NODES = 64

#: Where :attr:`JitterLaw.hard_edges` looks at a density, as a fraction of its support's
#: width inside each end: a uniform's density there is 1 / W, a Gaussian's (8.5 sigma from
#: its mode) 1e-16 / W, a triangle's (SumOfUniforms, n = 1) 4e-6 / W.
HARD_EDGE = 1e-6

#: Lower bound on scale parameters (a, sigma) of the families, unless the caller sets one.
_SCALE_FLOOR = 1e-12

#: Largest scale parameter (a, sigma) of a law: its square, the variance, stays a finite
#: double with room to spare (a jitter of 1e150 s is no sampling instant anyway).
SCALE_MAX = 1e150


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _size(size: int | Sequence[int]) -> tuple[int, ...]:
    """Validate a numpy-style ``size`` (int or tuple of ints >= 0) against the memory budget."""
    shape: tuple[int, ...] | None
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        shape = (_checks.count(size, "size", minimum=0),)
    elif isinstance(size, (tuple, list)):
        shape = tuple(_checks.count(s, "size", minimum=0) for s in size)
    else:
        shape = None
    if shape is not None:
        _checks.allocation(math.prod(shape), f"size {size!r}", fix="draw fewer values at a time")
        return shape
    raise TypeError(f"size must be an int or a tuple of ints (numpy style); got {size!r}")


def _gl_panels(
    edges: NDArray[np.float64], nodes_per_panel: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss-Legendre nodes and weights on each panel ``[edges[i], edges[i+1]]``."""
    x0, w0 = _leggauss(nodes_per_panel)
    lo = edges[:-1, None]
    half = 0.5 * np.diff(edges)[:, None]
    nodes = lo + half * (x0 + 1.0)
    weights = half * w0
    return nodes.ravel(), weights.ravel()


def _fourier_sum(
    f: NDArray[np.float64], nodes: NDArray[np.float64], weights: NDArray[np.float64]
) -> NDArray[np.complex128]:
    """``sum_j weights_j exp(-i 2 pi f nodes_j)`` for every ``f``, in memory-bounded chunks."""
    flat = f.ravel()
    out = np.empty(flat.shape, dtype=complex)
    chunk = max(1, 2**22 // max(1, nodes.size))
    for start in range(0, flat.size, chunk):
        fs = flat[start : start + chunk]
        out[start : start + chunk] = np.exp(-2j * np.pi * np.outer(fs, nodes)) @ weights
    return out.reshape(f.shape)


def _scale(x: float, name: str) -> float:
    """A law's scale parameter: finite, > 0 and at most :data:`SCALE_MAX`."""
    val = _checks.positive(x, name)
    if val > SCALE_MAX:
        raise ValueError(
            f"{name} must be at most {SCALE_MAX:g} s (its square, the variance, must be a "
            f"finite number); got {x!r}. Check the units of the jitter"
        )
    return val


def _fmt(x: float) -> str:
    return f"{x:.6g}"


#: Cells of the tabulated CDF that the default sampler (and :class:`CustomJitter`) inverts.
_CDF_CELLS = 8192


def _cdf_table(
    density: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    edges: NDArray[np.float64],
    lo: float,
    hi: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(grid, CDF on the grid) of ``density`` on ``[lo, hi]``: about ``_CDF_CELLS`` uniform
    cells cut at the ``edges`` (the breakpoints, ``lo`` and ``hi`` included), each integrated
    by 8-point Gauss-Legendre; the CDF is normalised to end at 1."""
    widths = np.diff(edges)
    cells = np.maximum(16, np.round(_CDF_CELLS * widths / (hi - lo)).astype(int))
    grid = np.concatenate(
        [np.linspace(edges[i], edges[i + 1], cells[i] + 1)[:-1] for i in range(edges.size - 1)]
        + [[hi]]
    )
    gnodes, gw = _gl_panels(grid, 8)
    cell_mass = (gw * density(gnodes)).reshape(-1, 8).sum(axis=1)
    cdf = np.concatenate([[0.0], np.cumsum(cell_mass)])
    return grid, cdf / cdf[-1]


@dataclass(frozen=True)
class BandRule:
    """How the jitter quadrature lays out a law ``tau = scale * xi`` (a fixed smooth shape
    xi, zero beyond ``+-half_width`` scales): by *band* of the scale, so that one node geometry
    serves every law of the band (only the pdf weights differ) and a search over the scale
    rebuilds no nodes until it leaves the band (:func:`jitterid.moments.quadrature.rule_frame`).

    Lengths are in units of the band's scale sigma_b <= scale (bands of 2**(1/8)). The window
    is ``+-half_width 2**(1/8) sigma_b``; ``zones`` (increasing, > 0) cut each half of it into
    zones, and ``zone_panels`` (``2 len(zones) + 1`` values, left to right) is the longest
    panel in each: short where the density is large, long in the tails (for the Gaussian:
    0.6 sigma_b within 3 sigma_b, 0.9 to 6 sigma_b, 1.7 beyond).

    Attributes
    ----------
    scale : float
        The law's scale (s), e.g. a Gaussian's sigma.
    half_width : float
        Half-width of the support in scales; the pdf must be zero beyond it.
    zones : tuple of float
        Zone edges from the centre, in band scales.
    zone_panels : tuple of float
        The longest panel in each zone, in band scales.
    """

    scale: float
    half_width: float
    zones: tuple[float, ...]
    zone_panels: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.zone_panels) != 2 * len(self.zones) + 1:
            raise ValueError(
                f"zone_panels must hold 2 len(zones) + 1 = {2 * len(self.zones) + 1} values (one "
                f"per zone, left to right); got {len(self.zone_panels)}"
            )


# --------------------------------------------------------------------------------------------
# base class
# --------------------------------------------------------------------------------------------


class JitterLaw(abc.ABC):
    """Base class of the (immutable) laws of the sampling jitter ``tau``.

    Subclasses are frozen dataclasses. A law declares its characteristic function :meth:`cf`
    with the paper's sign convention ``phi(f) = E[exp(-i 2 pi f tau)]`` (footnote 3, Lemma 1),
    its density :meth:`pdf` and a finite :attr:`support` holding the mass; that is enough. The
    rest has defaults from the density, which a law overrides where it knows better: the
    :meth:`breakpoints` between which the density is analytic (default: the support's ends,
    i.e. no kink inside), :attr:`var` (default: by :meth:`expect`), :attr:`mean` (default 0,
    a symmetric law), a sampler :meth:`sample` (default: the inverted tabulated CDF) and
    :attr:`params` (default: none).

    A law also declares what it offers to the fast paths (capabilities; the paths ask for
    them, never for a type): :attr:`band_rule` (a scale law whose quadrature is laid out by
    band of its scale, shared by the laws of a band: the Gaussian-kernel path) and
    :attr:`pdf_degree` (a symmetric density that is a polynomial between its breakpoints,
    evaluated exactly by the exact likelihood from a few values).

    Examples
    --------
    >>> import jitterid as ji
    >>> law = ji.Uniform(0.05)
    >>> isinstance(law, ji.JitterLaw), round(float(law.std), 6)
    (True, 0.028868)
    >>> law.sample(3, rng=0).shape
    (3,)
    """

    # -- interface -----------------------------------------------------------------------------

    @abc.abstractmethod
    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        """Characteristic function ``phi(f) = E[exp(-i 2 pi f tau)]`` (paper, footnote 3).

        Parameters
        ----------
        f : array_like of float
            Frequencies in Hz (cycles per unit time), any shape.

        Returns
        -------
        ndarray of complex
            ``phi(f)``, same shape as ``f``.
        """

    @abc.abstractmethod
    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Density ``p(tau)``, zero outside :attr:`support`; same shape as ``tau``.

        Parameters
        ----------
        tau : array_like
            Jitter values in s.
        """

    @property
    @abc.abstractmethod
    def support(self) -> tuple[float, float]:
        """Finite interval ``(lo, hi)`` holding the mass of ``tau``."""

    # -- defaults from the density -------------------------------------------------------------

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        """Draw i.i.d. jitter values.

        By default by inverting the CDF tabulated on about 8192 cells of the support (cut at
        the :meth:`breakpoints`, 8-point Gauss-Legendre per cell) with linear interpolation,
        as :class:`CustomJitter` does: exact for the histogram of the density on that grid.

        Parameters
        ----------
        size : int or tuple of int
            Output shape (numpy convention).
        rng : numpy.random.Generator or int
            Source of randomness, or a seed for :func:`numpy.random.default_rng`. ``None`` is
            refused so that every simulation is reproducible.

        Returns
        -------
        ndarray of float
            Samples of ``tau`` with shape ``size``.
        """
        shape = _size(size)
        gen = _checks.generator(rng)
        lo, hi = (float(v) for v in self.support)
        if not hi > lo:
            return np.full(shape, lo)
        table = self.__dict__.get("_cdf_table")
        if table is None:  # once per law (a frozen dataclass: kept outside its fields)
            table = _cdf_table(
                lambda x: np.asarray(self.pdf(x), dtype=float),
                np.asarray(self.breakpoints(), dtype=float),
                lo,
                hi,
            )
            self.__dict__["_cdf_table"] = table
        return np.interp(gen.random(shape), table[1], table[0])

    @property
    def var(self) -> float:
        """Variance ``E[(tau - mean)^2]``; by default by :meth:`expect` (to machine precision
        for a density analytic between its breakpoints)."""
        m = self.mean
        return float(self.expect(lambda t: (t - m) ** 2))

    def breakpoints(self) -> NDArray[np.float64]:
        """Sorted points of ``[lo, hi]``, including ``lo`` and ``hi``, between which the density
        is analytic (the knots of a piecewise-polynomial density). By default the support's
        ends: a law whose density has a kink or a jump inside declares it here, else the
        quadratures converge only algebraically there."""
        return np.array(self.support, dtype=float)

    @property
    def params(self) -> dict[str, float]:
        """The law's parameters by name (by default none)."""
        return {}

    # -- capabilities of the fast paths --------------------------------------------------------

    @property
    def band_rule(self) -> BandRule | None:
        """The band layout of the quadrature (:class:`BandRule`) for a smooth scale law whose
        nodes may be shared by every law of a band of its scale, or None (the default: the
        law's own rule from its breakpoints and std). The Gaussian declares it. A subclass
        whose density is not that of its parent's declaration must set it again."""
        return None

    @property
    def pdf_degree(self) -> int | None:
        """The largest degree of the density's polynomial pieces, for a density symmetric
        about 0 that is a polynomial between consecutive :meth:`breakpoints`: the exact
        likelihood then evaluates it from ``degree + 1`` values per piece (Chebyshev
        interpolation, exact to rounding) instead of calling :meth:`pdf` at every node. None
        (the default): evaluated by :meth:`pdf`. :class:`SumOfUniforms` declares it."""
        return None

    # -- derived -------------------------------------------------------------------------------

    @property
    def mean(self) -> float:
        """Mean ``E[tau]`` (zero for every symmetric law)."""
        return 0.0

    @property
    def mass(self) -> float:
        """The measure's total mass: 1 for a law. A derivative ``dp/dtheta`` of a family's
        density posing as a law, for the moment passes of a shape parameter
        (``jitterid.estimation.jacobians``), has mass 0: a closed form of the moments that
        takes the mass for 1 (a constant's moment, a variance's centring) asks for it."""
        return 1.0

    @property
    def std(self) -> float:
        """Standard deviation ``sqrt(var)``."""
        return math.sqrt(self.var)

    @property
    def hard_edges(self) -> bool:
        """Whether the density jumps at both ends of its :attr:`support` (a uniform law's;
        not a Gaussian's, whose support is only where its mass ends to rounding): at
        ``HARD_EDGE`` of the width W inside each end it is at least a tenth of the mean
        density 1 / W. A likelihood can then be multimodal in the law's scale
        (:func:`jitterid.metrology.sinelik_fit.fit_sine_ml` probes it), and its standard
        error too small where the record does not resolve the edges
        (:mod:`jitterid.metrology.edges`)."""
        lo, hi = (float(v) for v in self.support)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            return False
        w = hi - lo
        inside = np.asarray(self.pdf(np.array([lo + HARD_EDGE * w, hi - HARD_EDGE * w])), float)
        return bool(np.all(inside >= 0.1 / w))

    def quadrature(
        self, nodes_per_panel: int = _GL_NODES
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Nodes and probability weights for ``E[g(tau)] ~= sum_j w_j g(tau_j)``.

        Gauss-Legendre with ``nodes_per_panel`` nodes on every panel between consecutive
        :meth:`breakpoints`, the weights multiplied by the density. Since the density is analytic
        on each panel, the rule is exact to machine precision for smooth, slowly varying ``g``;
        for ``g`` oscillating at frequency ``f`` use ``nodes_per_panel`` well above
        ``pi |f| (panel width)``. The weights sum to 1 up to the quadrature error. This is the
        time-domain route of Lemma 1: ``mu_k = E[s(kT + tau)]``.

        Parameters
        ----------
        nodes_per_panel : int, default 64
            Gauss-Legendre nodes per panel.

        Returns
        -------
        tau : ndarray
            Quadrature nodes, sorted.
        weights : ndarray
            Non-negative weights ``w_j = (GL weight) * p(tau_j)``.
        """
        n = _checks.count(nodes_per_panel, "nodes_per_panel", minimum=1)
        nodes, w = _gl_panels(self.breakpoints(), n)
        return nodes, w * self.pdf(nodes)

    def expect(
        self, g: Callable[[NDArray[np.float64]], ArrayLike], nodes_per_panel: int = _GL_NODES
    ) -> Any:
        """``E[g(tau)]`` by :meth:`quadrature`.

        Parameters
        ----------
        g : callable
            Vectorised function; ``g(tau)`` for a 1-D array ``tau`` of nodes must return an array
            whose *last* axis runs over the nodes (extra leading axes are allowed).
        nodes_per_panel : int, default 64
            Gauss-Legendre nodes per panel.

        Returns
        -------
        float, complex or ndarray
            The expectation (leading axes of ``g``'s output are kept).
        """
        if not callable(g):
            raise TypeError(f"g must be a callable g(tau); got {type(g).__name__}")
        nodes, w = self.quadrature(nodes_per_panel)
        vals = np.asarray(g(nodes))
        if vals.shape[-1:] != nodes.shape:
            raise ValueError(
                f"g must be vectorised: g(tau) for {nodes.size} nodes returned shape "
                f"{vals.shape}; make its last axis run over tau"
            )
        return vals @ w

    def __str__(self) -> str:
        args = ", ".join(f"{k}={_fmt(v)}" for k, v in self.params.items())
        lo, hi = self.support
        return (
            f"{type(self).__name__}({args}): mean {_fmt(self.mean)}, std {_fmt(self.std)}, "
            f"support [{_fmt(lo)}, {_fmt(hi)}]"
        )


# --------------------------------------------------------------------------------------------
# concrete laws
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class NoJitter(JitterLaw):
    """No jitter: ``tau = 0`` almost surely, ``phi(f) = 1`` (the OE/BJ case of the paper, where
    ``mu_W = d_N``, see the remark after Lemma 1).

    The law is a point mass, so it has no density: :meth:`pdf` raises
    :class:`NotImplementedError`. :meth:`quadrature` returns the single node 0 with weight 1, so
    :meth:`expect` gives ``g(0)`` and generic code using those two methods needs no special case.
    The support is the degenerate interval ``(0, 0)`` and :meth:`breakpoints` is ``[0.0]``.

    Examples
    --------
    >>> import jitterid as ji
    >>> law = ji.NoJitter()
    >>> law.support, float(law.std), complex(law.cf(3.0))
    ((0.0, 0.0), 0.0, (1+0j))
    """

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        return np.ones(arr.shape, dtype=complex)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        raise NotImplementedError(
            "NoJitter is a point mass at tau = 0 and has no density; use cf(), quadrature() or "
            "expect() (which gives g(0)), or special-case NoJitter"
        )

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        _checks.generator(rng)
        return np.zeros(shape)

    @property
    def var(self) -> float:
        return 0.0

    @property
    def support(self) -> tuple[float, float]:
        return (0.0, 0.0)

    def breakpoints(self) -> NDArray[np.float64]:
        return np.array([0.0])

    @property
    def params(self) -> dict[str, float]:
        return {}

    def quadrature(
        self, nodes_per_panel: int = _GL_NODES
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The point mass: node ``[0.0]`` with weight ``[1.0]`` (``nodes_per_panel`` ignored).

        Parameters
        ----------
        nodes_per_panel : int, optional
            Ignored (a point mass needs one node).
        """
        _checks.count(nodes_per_panel, "nodes_per_panel", minimum=1)
        return np.array([0.0]), np.array([1.0])


@dataclass(frozen=True)
class Uniform(JitterLaw):
    """Uniform jitter ``tau ~ U(-a, a)``, ``a > 0``.

    ``phi(f) = sinc(2 f a) = sin(2 pi f a) / (2 pi f a)`` (the form of eq. (15a), where
    ``a = 1``), variance ``a^2 / 3``. This is (26) with ``n = 0``.

    Parameters
    ----------
    a : float
        Half-width of the support, ``> 0``.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> law = jid.Uniform(0.05)
    >>> law.support
    (-0.05, 0.05)
    >>> round(float(law.pdf(0.0)), 6)
    10.0
    """

    a: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _scale(self.a, "a"))

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        return np.sinc(2.0 * arr * self.a).astype(complex)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        return np.where(np.abs(t) <= self.a, 0.5 / self.a, 0.0)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        return gen.uniform(-self.a, self.a, size=shape)

    @property
    def var(self) -> float:
        return self.a**2 / 3.0

    @property
    def std(self) -> float:
        return self.a / math.sqrt(3.0)

    @property
    def support(self) -> tuple[float, float]:
        return (-self.a, self.a)

    def breakpoints(self) -> NDArray[np.float64]:
        return np.array([-self.a, self.a])

    @property
    def params(self) -> dict[str, float]:
        return {"a": self.a}


@dataclass(frozen=True)
class Gaussian(JitterLaw):
    """Gaussian jitter ``tau ~ N(0, sigma^2)``, ``sigma > 0``.

    ``phi(f) = exp(-2 pi^2 sigma^2 f^2)`` (eq. (15b), where ``sigma^2 = 1/3``).

    The *effective* support is ``[-8.5 sigma, 8.5 sigma]`` (:data:`GAUSS_SUPPORT_SIGMAS`): the
    mass outside it is ``1.9e-17``, below double-precision resolution. :meth:`pdf` is zero
    outside it (so the quadrature of :meth:`JitterLaw.quadrature` sees the same law), while
    :meth:`cf`, :meth:`sample`, :attr:`var` are those of the untruncated Gaussian.

    Parameters
    ----------
    sigma : float
        Standard deviation, ``> 0``.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> law = jid.Gaussian(0.01)
    >>> round(float(law.std), 6)
    0.01
    """

    sigma: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma", _scale(self.sigma, "sigma"))

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        return np.exp(-2.0 * np.pi**2 * self.sigma**2 * arr**2).astype(complex)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        z = t / self.sigma
        dens = np.exp(-0.5 * z**2) / (self.sigma * math.sqrt(2.0 * math.pi))
        return np.where(np.abs(z) <= GAUSS_SUPPORT_SIGMAS, dens, 0.0)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        return gen.normal(0.0, self.sigma, size=shape)

    @property
    def var(self) -> float:
        return self.sigma**2

    @property
    def std(self) -> float:
        return self.sigma

    @property
    def support(self) -> tuple[float, float]:
        h = GAUSS_SUPPORT_SIGMAS * self.sigma
        return (-h, h)

    def breakpoints(self) -> NDArray[np.float64]:
        return np.array(self.support)

    @property
    def params(self) -> dict[str, float]:
        return {"sigma": self.sigma}

    @property
    def band_rule(self) -> BandRule:
        """The Gaussian-kernel layout: window +-8.5 sigma, zones at 3 and 6 sigma_b with panels
        of 0.6, 0.9 and 1.7 sigma_b (:class:`BandRule`)."""
        return BandRule(self.sigma, GAUSS_SUPPORT_SIGMAS, _GAUSS_ZONES, _GAUSS_ZONE_PANELS)


@lru_cache(maxsize=64)
def _cardinal_bspline(m: int) -> tuple[PPoly, PPoly]:
    """The cardinal B-spline of degree m - 1 on knots 0..m and its antiderivative: the same
    for every law with m equal uniforms, so built once per m (a search over (n, a) makes a
    law at every step). As piecewise polynomials, from the B-spline's derivatives at each
    piece's left end (within 3e-15 of the B-spline form for m <= 51, a test checks):
    evaluated about 3x faster (the quadratures evaluate the density at every node)."""
    d = m - 1
    if d == 0:
        pdf = PPoly(np.ones((1, 1)), np.array([0.0, 1.0]), extrapolate=False)
    else:
        spline = BSpline.basis_element(np.arange(m + 1.0), extrapolate=False)
        left = np.arange(float(m))
        c = np.array([spline(left, nu=d - k) / math.factorial(d - k) for k in range(m)])
        pdf = PPoly(c, np.arange(m + 1.0), extrapolate=False)
    return pdf, pdf.antiderivative()


@lru_cache(maxsize=64)
def _cardinal_slope(m: int) -> PPoly:
    """The derivative of :func:`_cardinal_bspline`'s B-spline (m >= 2: a continuous
    density, whose slope has jumps at the knots but no Dirac masses)."""
    return _cardinal_bspline(m)[0].derivative()


def _clenshaw(
    bp: NDArray[np.float64], coef: NDArray[np.float64], x: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Piecewise Chebyshev series (rows, pieces, degree + 1) on the intervals of ``bp`` at
    ``x`` (clipped into bp's range), one row of values per row of ``coef``."""
    left, right = bp[:-1], bp[1:]
    i = np.clip(np.searchsorted(bp, x, side="right") - 1, 0, left.size - 1)
    u = np.clip((2.0 * x - (left[i] + right[i])) / (right[i] - left[i]), -1.0, 1.0)
    b1, b2 = np.zeros((coef.shape[0], x.size)), np.zeros((coef.shape[0], x.size))
    for j in range(coef.shape[2] - 1, 0, -1):
        b1, b2 = coef[:, i, j] + 2.0 * u * b1 - b2, b1
    return np.asarray(coef[:, i, 0] + u * b1 - b2, dtype=np.float64)


@lru_cache(maxsize=64)
def _leggauss(q: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss-Legendre nodes and weights on [-1, 1], made once per order (read only: a
    call made them anew each time, half the cost of a law's expectation)."""
    x, w = leggauss(q)
    x.flags.writeable = False
    w.flags.writeable = False
    return x, w


@dataclass(frozen=True)
class SumOfUniforms(JitterLaw):
    """The paper's jitter family (26), for real ``n`` in ``[0, 50]``.

    For integer ``n``, ``tau`` is the sum of ``n + 1`` independent ``U(-a/(n+1), a/(n+1))``:
    support ``[-a, a]``, variance ``a^2 / (3 (n + 1))`` and

    .. math:: \\varphi(f) = \\operatorname{sinc}(2 f a / (n + 1))^{n + 1}           \\qquad (26)

    (``n = 0`` uniform, ``n = 1`` triangular, in general a scaled Irwin-Hall density).

    For non-integer ``n``, (26) is not a characteristic function (``sinc`` is negative between
    its zeros, so its real power is undefined). This class then uses the following law, which is
    continuous in ``n``, equals (26) at integer ``n``, has support ``[-a, a]`` and variance
    ``a^2 / (3 (n + 1))`` *exactly*: with ``nu = n + 1`` and ``K = ceil(nu) - 1``, ``tau`` is
    the sum of ``K`` independent ``U(-b, b)`` and one independent ``U(-c, c)``, where

    .. math::

        b = a \\frac{K + \\sqrt{K ((K + 1)/\\nu - 1)}}{K (K + 1)}, \\qquad c = a - K b,

    so that ``K b + c = a`` and ``K b^2/3 + c^2/3 = a^2/(3 nu)``; ``c <= b``, and ``c -> 0`` as
    ``nu`` decreases to an integer (both from the distances ``K - n`` and ``n - K + 1`` to the
    piece's ends, exact in floating point, so that ``b`` and ``c`` are accurate to rounding
    however near an integer ``n`` is). Then ``phi(f) = sinc(2 f b)^K sinc(2 f c)``. At integer
    ``nu`` (within ``1e-12``) the law is stored as ``nu`` equal uniforms of half-width
    ``a / nu`` and no extra one; :attr:`components` gives the decomposition in use.

    The density of the ``m`` equal uniforms is the scaled Irwin-Hall density, evaluated as a
    cardinal B-spline (stable for all ``m <= 51``). With the extra uniform the density is the
    moving average ``p(t) = (1 / 2c) int_{t-c}^{t+c} p_m(s) ds``. For ``c >= 1e-3 b`` it is
    evaluated as the CDF difference ``(F_m(t + c) - F_m(t - c)) / 2c`` (``F_m`` the B-spline's
    antiderivative; cancellation costs at most 3 digits, absolute error ~1e-13 of the peak);
    for narrower windows, where that difference would cancel, by Gauss-Legendre on the at most
    two polynomial pieces of ``p_m`` in ``[t - c, t + c]`` (``c < b``, so the window holds at
    most one knot), which is exact to rounding however small ``c`` is. The density is
    piecewise polynomial (degree ``m``) with knots ``-m b + 2 j b +- c``, ``j = 0..m``
    (:meth:`breakpoints`).

    The law is continuous in ``n``. Just above an integer ``nu``, ``c`` grows linearly in the
    distance; just below it, the widths ``b, c`` leave ``a / nu`` like the *square root* of the
    distance ``eps`` (their first-order effect on ``phi`` cancels, so ``phi`` and the smooth
    densities move like ``eps``, but the kinked triangle ``n = 1`` has its peak lowered by
    about ``sqrt(eps / 2) / a``).

    Parameters
    ----------
    n : float
        Order, ``0 <= n <= 50`` (``n + 1`` uniforms for integer ``n``).
    a : float
        Half-width of the support, ``> 0``.

    Examples
    --------
    >>> import jitterid as ji
    >>> law = ji.SumOfUniforms(2, 0.3)
    >>> law.support
    (-0.3, 0.3)
    >>> round(float(law.std), 6)
    0.1
    """

    n: float
    a: float
    _m: int = field(init=False, repr=False, compare=False)
    _b: float = field(init=False, repr=False, compare=False)
    _c: float = field(init=False, repr=False, compare=False)
    _s: float = field(init=False, repr=False, compare=False)
    _spline: PPoly = field(init=False, repr=False, compare=False)
    _spline_cdf: PPoly = field(init=False, repr=False, compare=False)
    _knots: NDArray[np.float64] | None = field(init=False, repr=False, compare=False)
    _gradient_coef: tuple[NDArray[np.float64], NDArray[np.float64]] | None = field(
        init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        n = _checks.positive(self.n, "n", allow_zero=True)
        if n > N_MAX:
            raise ValueError(
                f"n must be at most {N_MAX:g} (beyond that the law is Gaussian to plotting "
                f"accuracy; use Gaussian(a / sqrt(3 (n + 1))) instead); got {self.n!r}"
            )
        a = _scale(self.a, "a")
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "a", a)
        nu = n + 1.0
        r = round(nu)
        if abs(nu - r) <= _INTEGER_TOL:
            m, b, c, s = int(r), a / r, 0.0, 1.0
        else:
            k = math.ceil(nu) - 1  # >= 1 here
            # s^2 = K ((K + 1) / nu - 1) = K (K + 1 - nu) / nu, with K + 1 - nu = K - n (exact
            # near the piece's top, where 1 - (K + 1) / nu lost the digits of the distance)
            s = math.sqrt(k * (k - n) / nu)
            # c = a (1 - s) / (K + 1), written without the cancellation in 1 - s
            # (nu - K = n - (K - 1), exact near the piece's bottom)
            c = a * (n - (k - 1)) / (nu * (1.0 + s))
            m, b = k, (a - c) / k
        object.__setattr__(self, "_m", m)
        object.__setattr__(self, "_b", b)
        object.__setattr__(self, "_c", c)
        object.__setattr__(self, "_s", s)
        spline, spline_cdf = _cardinal_bspline(m)
        object.__setattr__(self, "_spline", spline)
        object.__setattr__(self, "_spline_cdf", spline_cdf)
        object.__setattr__(self, "_knots", None)
        object.__setattr__(self, "_gradient_coef", None)

    @property
    def components(self) -> tuple[int, float, float]:
        """``(m, b, c)``: ``tau`` is the sum of ``m`` i.i.d. ``U(-b, b)`` and one ``U(-c, c)``
        (``c = 0``: no extra uniform; this is the case at integer ``n``, with ``m = n + 1``)."""
        return (self._m, self._b, self._c)

    @property
    def pdf_degree(self) -> int:
        """Degree of the density's pieces: ``m - 1`` for ``m`` equal uniforms, ``m`` with the
        extra one (the moving average of width 2c)."""
        return self._m if self._c > 0 else max(self._m - 1, 0)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        out = np.sinc(2.0 * arr * self._b) ** self._m
        if self._c > 0.0:
            out = out * np.sinc(2.0 * arr * self._c)
        return np.asarray(out, dtype=complex)

    def _irwin_hall_pdf(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        m, b = self._m, self._b
        u = (x + m * b) / (2.0 * b)
        inside = (u >= 0.0) & (u <= m)
        vals = self._spline(np.minimum(np.maximum(u, 0.0), float(m)))
        return np.where(inside, vals / (2.0 * b), 0.0)

    def _irwin_hall_cdf(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        m, b = self._m, self._b
        u = np.minimum(np.maximum((x + m * b) / (2.0 * b), 0.0), float(m))
        return np.asarray(self._spline_cdf(u), dtype=float)

    def _window_mean(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(1 / 2c) int_{x-c}^{x+c} p_m(s) ds`` for a 1-D array ``x <= 0``."""
        m, b, c = self._m, self._b, self._c
        if c >= _WIDE_WINDOW * b:
            # both ends in one spline evaluation (elementwise: the same values as two)
            cdf = self._irwin_hall_cdf(np.concatenate([x + c, x - c]))
            return (cdf[: x.size] - cdf[x.size :]) / (2.0 * c)
        # the only knot of p_m that can lie in [x - c, x + c] is the one nearest to x (c < b);
        # work with offsets from x so that tiny windows (c << |x|) lose no precision
        knot = -m * b + 2.0 * b * np.clip(np.round((x + m * b) / (2.0 * b)), 0, m)
        d = np.clip(knot - x, -c, c)
        q = m // 2 + 1  # Gauss-Legendre with q nodes is exact for degree 2q - 1 >= m - 1
        g, w = _leggauss(q)
        total = np.zeros_like(x)
        for start, length in ((np.full_like(d, -c), c + d), (d, c - d)):
            half = 0.5 * length
            s = x[:, None] + (start[:, None] + half[:, None] * (g + 1.0))
            total += half * (self._irwin_hall_pdf(s) @ w)
        return total / (2.0 * c)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        x = -np.abs(t).ravel()  # evaluate the symmetric law on one side: exact symmetry
        dens = self._irwin_hall_pdf(x) if self._c == 0.0 else self._window_mean(x)
        dens = dens.reshape(t.shape)
        return np.where(np.abs(t) <= self.a, np.maximum(dens, 0.0), 0.0)

    def pdf_gradient(self, tau: ArrayLike) -> NDArray[np.float64] | None:
        """``d p(tau) / d (n, a)``, shape ``(2,) + tau.shape`` (zero outside the support), in
        closed form; ``None`` at an integer ``n`` and just below one (see below).

        With ``nu = n + 1``, ``K`` and ``b, c`` as in the class description and ``f``, ``F``
        the density and distribution of the ``K`` uniforms ``U(-b, b)``, the law moves with
        ``n`` at fixed ``a`` through ``b`` and ``c = a - K b`` only:

        .. math::

            \\frac{db}{dn} = -\\frac{a}{2 s \\nu^2}, \\quad
            s = \\sqrt{K (K + 1 - \\nu) / \\nu}, \\qquad
            \\frac{dp}{dn} = \\frac{db}{dn} \\Big(\\frac{\\partial p}{\\partial b}
            - K \\frac{\\partial p}{\\partial c}\\Big),

        with ``dF(t)/db = -(t/b) f(t)`` and ``dp/dc = (f(t + c) + f(t - c)) / 2c - p / c``.
        ``a`` is a scale (the law is that of ``a xi``): ``dp/da = -(p + tau p'(tau)) / a``.
        Routes (each measured against the density's truncated-power form in 90-digit
        arithmetic, tests/jitter/test_sum_of_uniforms_gradient.py):

        * ``K = 1`` (``0 < n < 1``): the density is a trapezoid, differentiated exactly
          (``b - c = a s``: no cancellation). Near the piece's top ``dp/dn`` itself grows
          like ``1 / s`` on the plateau ``|tau| < b - c`` (the triangle's peak falls like
          the square root of the distance), exactly as the law does.
        * ``K >= 2``, ``c >= 0.01 K b``: the boundary form above, from ``F`` and ``f`` at
          ``tau +- c``; its ``1 / c^2`` terms cancel to a loss of about ``K^2 (b / c)^2``
          ulps, within 2e-12 of the largest ``|dp/dn|``.
        * ``K >= 2``, ``c < 0.01 K b`` (``n`` less than ``~0.02 K`` above an integer): the
          window form ``dp/dn = -(db/dn / 2b) int_{-1}^{1} [f(u) + (u + K b s) f'(u)] ds``,
          ``u = tau + c s`` (and ``p'`` the window mean of ``f'``), by Gauss-Legendre on the
          window's at most two polynomial pieces (as :meth:`pdf`): exact to rounding however
          small ``c`` is, at 3-4x the boundary form's cost; at many points (more than
          ``4 K^2``) from the Chebyshev interpolants of its values on each of the density's
          polynomial pieces, where dp/dn and dp/da are polynomials of degree at most ``K``.

        Near a piece's top (``n`` just below an integer, ``K >= 2``) ``db/dn`` grows like
        ``1 / s`` while the bracket cancels to ``O(s)`` (at ``b = c`` the ``K + 1`` widths
        are interchangeable): the relative error grows like ``K 1e-16 / s``, measured 1e-11
        (``K = 2``) to 3e-9 (``K = 50``) at ``1e-9`` below the integer, 1.3e-8 (``K = 50``) at
        ``1e-10``.

        ``None`` (the callers then take the one-sided forms of
        :meth:`SumOfUniformsFamily.scale_equivalent` and
        :meth:`SumOfUniformsFamily.below_kink`, or difference the moments and the likelihood,
        one-sided at a piece's end: :mod:`jitterid.finite_diff`):

        * at an integer ``n`` (within ``1e-12``, where the law is stored as ``n + 1`` equal
          uniforms): the law has a kink in ``n`` there (``db/dn`` is finite above and
          infinite below, though the law's own derivative from below is finite), so its
          derivative is one-sided and depends on the side;
        * less than ``1e-9`` below an integer: the cancellation above would cost more than
          a relative 3e-9 (and grows without bound as the distance goes to 0).

        Parameters
        ----------
        tau : array_like
            Jitter values in s.

        Returns
        -------
        ndarray or None
            Rows ``(dp/dn, dp/da)``, in 1/s per unit ``n`` and 1/s^2.
        """
        t = _checks.real_array(tau, "tau")
        m, c = self._m, self._c
        if c == 0.0 or m - self.n < _GRADIENT_BELOW:
            return None
        if not t.size:  # (the callers ask with no tau whether there is a closed form)
            return np.zeros((2, *t.shape))
        x = -np.abs(t).ravel()  # the symmetric law (and its derivatives) on one side
        # the window form costs 3-4x the others a point: at many points, from its pieces
        window = m > 1 and c < _GRADIENT_WINDOW * m * self._b
        pieces = self._gradient_pieces if window and x.size > _GRADIENT_DIRECT * m**2 else None
        out = self._gradient_at(x) if pieces is None else _clenshaw(*pieces, x)
        return np.where(np.abs(t) <= self.a, out.reshape((2, *t.shape)), 0.0)

    def _gradient_at(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """(dp/dn, dp/da) at a 1-D array ``x <= 0`` by the closed form's route for the law."""
        m = self._m
        if m == 1:
            p, dpdx, dpdn = self._trapezoid_gradient(x)
        elif self._c < _GRADIENT_WINDOW * m * self._b:
            p, dpdx, dpdn = self._window_gradient(x)
        else:
            p, dpdx, dpdn = self._boundary_gradient(x)
        return np.stack([dpdn, -(p + x * dpdx) / self.a])

    @property
    def _gradient_pieces(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(breakpoints on tau <= 0, Chebyshev coefficients (2, pieces, m + 1)) of dp/dn and
        dp/da: polynomials of degree at most m between the density's breakpoints (the
        derivatives in the widths of the density's polynomial pieces), so that their
        interpolants at m + 1 first-kind points of :meth:`_gradient_at` per piece reproduce
        them to rounding (as the likelihood's ``_density`` reproduces the density). Made once
        per law; then O(m) operations a point instead of the window form's Gauss-Legendre
        window per point (n just above an integer; measured 2.7x faster at 2e5 points, the
        other routes' 2-4 B-spline evaluations a point are as fast as this)."""
        if self._gradient_coef is None:
            bp = self.breakpoints()
            bp = bp[bp <= 0.0]
            if bp[-1] < 0.0:
                bp = np.r_[bp, 0.0]
            deg = self._m
            arg = np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1)
            left, right = bp[:-1, None], bp[1:, None]
            pts = 0.5 * (left + right) + 0.5 * (right - left) * np.cos(arg)[None, :]
            vals = self._gradient_at(pts.ravel()).reshape((2, *pts.shape))
            coef = vals @ np.cos(np.outer(np.arange(deg + 1), arg)).T * (2.0 / (deg + 1))
            coef[..., 0] *= 0.5
            object.__setattr__(self, "_gradient_coef", (bp, coef))
        assert self._gradient_coef is not None
        return self._gradient_coef

    @property
    def _db_dn(self) -> float:
        """db/dn = db/dnu = -a / (2 s nu^2) (finite at the piece's bottom, where s = 1)."""
        return -self.a / (2.0 * self._s * (self.n + 1.0) ** 2)

    def _trapezoid_gradient(
        self, x: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(p, dp/dx, dp/dn) at ``x <= 0`` for K = 1: a plateau 1/2b on |x| < b - c, ramps
        u / 4bc with u = a - |x| beyond; at fixed u, d(1/4bc)/dn = (b - c) b' / (4 b^2 c^2)
        (c' = -b'), with b - c = a s exactly."""
        b, c = self._b, self._c
        db = self._db_dn
        u = self.a + x
        ramp = u < 2.0 * c
        p = np.where(ramp, u / (4.0 * b * c), 1.0 / (2.0 * b))
        dpdx = np.where(ramp, 1.0 / (4.0 * b * c), 0.0)
        steep = db * (self.a * self._s) / (4.0 * b**2 * c**2)  # d(1/4bc)/dn
        dpdn = np.where(ramp, u * steep, -db / (2.0 * b**2))
        return p, dpdx, dpdn

    def _boundary_gradient(
        self, x: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(p, dp/dx, dp/dn) at ``x <= 0`` from f and F at x +- c (K >= 2, c not small)."""
        m, b, c = self._m, self._b, self._c
        both = np.concatenate([x + c, x - c])
        cdf, dens = self._irwin_hall_cdf(both), self._irwin_hall_pdf(both)
        n = x.size
        fp, fm = dens[:n], dens[n:]
        p = (cdf[:n] - cdf[n:]) / (2.0 * c)
        dpdx = (fp - fm) / (2.0 * c)
        bracket = ((-(x + c) / b - m) * fp + ((x - c) / b - m) * fm + 2.0 * m * p) / (2.0 * c)
        return p, dpdx, self._db_dn * bracket

    def _window_gradient(
        self, x: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(p, dp/dx, dp/dn) at ``x <= 0`` as means over the window s in [-1, 1] of f, f' and
        f + (u + K b s) f', u = x + c s, by Gauss-Legendre on the window's at most two pieces
        of f (split at the knot nearest x, as :meth:`_window_mean`): exact for K >= 2,
        whose f is continuous."""
        m, b, c = self._m, self._b, self._c
        knot = -m * b + 2.0 * b * np.clip(np.round((x + m * b) / (2.0 * b)), 0, m)
        d = np.clip(knot - x, -c, c)
        g, w = _leggauss(m // 2 + 1)  # exact for the integrands' degree m - 1
        p, dpdx, inner = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
        for start, length in ((np.full_like(d, -c), c + d), (d, c - d)):
            half = 0.5 * length
            off = start[:, None] + half[:, None] * (g + 1.0)
            u = x[:, None] + off
            f, slope = self._irwin_hall_pdf(u), self._irwin_hall_slope(u)
            p += half * (f @ w)
            dpdx += half * (slope @ w)
            inner += half * ((f + (u + (m * b / c) * off) * slope) @ w)
        scale = 1.0 / (2.0 * c)
        return p * scale, dpdx * scale, -(self._db_dn / b) * inner * scale

    def _irwin_hall_slope(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        m, b = self._m, self._b
        u = (x + m * b) / (2.0 * b)
        inside = (u >= 0.0) & (u <= m)
        vals = _cardinal_slope(m)(np.minimum(np.maximum(u, 0.0), float(m)))
        return np.where(inside, vals / (2.0 * b) ** 2, 0.0)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        out = np.zeros(shape)
        for _ in range(self._m):
            out += gen.uniform(-self._b, self._b, size=shape)
        if self._c > 0.0:
            out += gen.uniform(-self._c, self._c, size=shape)
        return out

    @property
    def var(self) -> float:
        return self.a**2 / (3.0 * (self.n + 1.0))

    @property
    def std(self) -> float:
        return self.a / math.sqrt(3.0 * (self.n + 1.0))

    @property
    def support(self) -> tuple[float, float]:
        return (-self.a, self.a)

    def breakpoints(self) -> NDArray[np.float64]:
        # computed once per law (the quadrature asks for them several times per evaluation)
        if self._knots is None:
            object.__setattr__(self, "_knots", self._breakpoints())
        assert self._knots is not None
        return self._knots.copy()

    def _breakpoints(self) -> NDArray[np.float64]:
        m, b, c = self._m, self._b, self._c
        knots = -m * b + 2.0 * b * np.arange(m + 1.0)
        pts = np.concatenate([knots - c, knots + c]) if c > 0.0 else knots
        pts = np.clip(np.sort(pts), -self.a, self.a)
        pts[0], pts[-1] = -self.a, self.a
        keep = np.concatenate([[True], np.diff(pts) > 1e-13 * self.a])
        pts = pts[keep]
        pts[-1] = self.a
        return pts

    @property
    def params(self) -> dict[str, float]:
        return {"n": self.n, "a": self.a}


@dataclass(frozen=True, eq=False, init=False, repr=False)
class CustomJitter(JitterLaw):
    """A user-supplied jitter density on a bounded interval.

    On construction the density is normalised to unit mass (silently: any positive multiple of
    a density is accepted) using Gauss-Legendre quadrature on each panel between consecutive
    breakpoints (each panel cut into 8 sub-panels of 64 nodes). The mean, variance and
    characteristic function are computed with the same kind of rule, so they are accurate to
    machine precision when the density is analytic between the breakpoints; a density with an
    undeclared kink converges only algebraically. For the characteristic function the
    sub-panels are made narrow enough that ``|f| h <= 16`` (``h`` the sub-panel width, 64 nodes
    each) for the largest ``|f|`` requested, so its cost grows linearly with ``max |f|``.

    :meth:`sample` inverts the CDF tabulated on a uniform grid of about 8192 cells (cells cut at
    the breakpoints, each cell integrated by 8-point Gauss-Legendre) with linear interpolation,
    i.e. it samples exactly from the histogram of the density on that grid: the CDF error is at
    most about ``h^2 max|p'| / 8`` with ``h = (hi - lo) / 8192`` (~1e-8 for a triangle).

    Instances compare and hash by identity (a callable has no useful equality).

    Parameters
    ----------
    pdf : callable
        Vectorised ``pdf(tau) -> array`` (same shape as ``tau``), non-negative and finite on
        ``[lo, hi]``; it is only ever called there. Need not be normalised.
    support : tuple of float
        ``(lo, hi)`` with ``lo < hi`` finite; the density is zero outside.
    breakpoints : sequence of float, optional
        Interior points of ``[lo, hi]`` where the density is not smooth (kinks, jumps).

    Raises
    ------
    ValueError
        If the density is negative or non-finite at a quadrature node, has zero mass, or is not
        vectorised, or if ``support``/``breakpoints`` are invalid.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> def triangle(t):
    ...     return 1.0 - np.abs(t) / 0.1
    >>> law = ji.CustomJitter(triangle, support=(-0.1, 0.1), breakpoints=[0.0])
    >>> round(float(law.pdf(0.0)), 6), round(float(law.std), 6)  # normalised to unit area
    (10.0, 0.040825)
    """

    _density: Callable[[NDArray[np.float64]], ArrayLike]
    _lo: float
    _hi: float
    _breaks: NDArray[np.float64]
    _norm: float
    _mean: float
    _var: float
    _nodes: NDArray[np.float64]
    _weights: NDArray[np.float64]
    _grid: NDArray[np.float64]
    _grid_cdf: NDArray[np.float64]

    _SUBPANELS: ClassVar[int] = 8
    _CF_FH_MAX: ClassVar[float] = 16.0

    def __init__(
        self,
        pdf: Callable[[NDArray[np.float64]], ArrayLike],
        support: tuple[float, float],
        breakpoints: Sequence[float] = (),
    ) -> None:
        if not callable(pdf):
            raise TypeError(f"pdf must be a callable pdf(tau); got {type(pdf).__name__}")
        sup = _checks.real_array(support, "support")
        if sup.shape != (2,):
            raise ValueError(f"support must be a pair (lo, hi); got shape {sup.shape}")
        lo, hi = float(sup[0]), float(sup[1])
        if not lo < hi:
            raise ValueError(f"support must satisfy lo < hi; got ({lo!r}, {hi!r})")
        bp = _checks.real_array(breakpoints, "breakpoints").ravel()
        if np.any((bp < lo) | (bp > hi)):
            raise ValueError(
                f"breakpoints must lie inside the support [{lo!r}, {hi!r}]; got {bp.tolist()}"
            )
        edges = np.unique(np.concatenate([[lo], bp, [hi]]))
        object.__setattr__(self, "_density", pdf)
        object.__setattr__(self, "_lo", lo)
        object.__setattr__(self, "_hi", hi)
        object.__setattr__(self, "_breaks", edges)

        # quadrature rule: every panel cut into _SUBPANELS sub-panels of _GL_NODES nodes
        nodes, w = _gl_panels(self._cut(self._SUBPANELS), _GL_NODES)
        dens = self._call(nodes)
        mass = float(w @ dens)
        if not mass > 0.0:
            raise ValueError(
                f"pdf must have positive mass on the support [{lo!r}, {hi!r}]; it integrates "
                f"to {mass!r}"
            )
        weights = w * dens / mass
        mean = float(weights @ nodes)
        var = float(weights @ (nodes - mean) ** 2)
        object.__setattr__(self, "_norm", mass)
        object.__setattr__(self, "_nodes", nodes)
        object.__setattr__(self, "_weights", weights)
        object.__setattr__(self, "_mean", mean)
        object.__setattr__(self, "_var", var)

        # tabulated CDF for the sampler
        grid, cdf = _cdf_table(self._call, edges, lo, hi)
        object.__setattr__(self, "_grid", grid)
        object.__setattr__(self, "_grid_cdf", cdf)

    def _cut(self, pieces: int) -> NDArray[np.float64]:
        """Breakpoints with every panel cut into ``pieces`` equal sub-panels."""
        e = self._breaks
        parts = [np.linspace(e[i], e[i + 1], pieces + 1)[:-1] for i in range(e.size - 1)]
        return np.concatenate([*parts, e[-1:]])

    def _call(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Evaluate the user's density at points of the support, checking it."""
        try:
            vals = np.asarray(self._density(x), dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"pdf must be a vectorised function of a float array returning floats; calling "
                f"it on an array of shape {x.shape} failed: {exc}"
            ) from exc
        if vals.shape != x.shape:
            if vals.ndim == 0:
                vals = np.full(x.shape, float(vals))
            else:
                raise ValueError(
                    f"pdf must be vectorised: pdf(tau) must have the shape of tau; got "
                    f"{vals.shape} for input of shape {x.shape}"
                )
        bad = ~np.isfinite(vals)
        if np.any(bad):
            raise ValueError(
                f"pdf must be finite on the support; it is {vals[bad][0]!r} at tau = {x[bad][0]!r}"
            )
        neg = vals < 0.0
        if np.any(neg):
            raise ValueError(
                f"pdf must be non-negative; it is {vals[neg][0]!r} at tau = {x[neg][0]!r}"
            )
        return vals

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        fmax = float(np.max(np.abs(arr))) if arr.size else 0.0
        widest = float(np.max(np.diff(self._breaks)))
        pieces = math.ceil(fmax * widest / self._CF_FH_MAX)
        if pieces <= self._SUBPANELS:
            return _fourier_sum(arr, self._nodes, self._weights)
        nodes, w = _gl_panels(self._cut(pieces), _GL_NODES)
        return _fourier_sum(arr, nodes, w * self._call(nodes) / self._norm)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        t = _checks.real_array(tau, "tau")
        flat = t.ravel()
        out = np.zeros(flat.shape)
        inside = (flat >= self._lo) & (flat <= self._hi)
        if np.any(inside):
            out[inside] = self._call(flat[inside]) / self._norm
        return out.reshape(t.shape)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        shape = _size(size)
        gen = _checks.generator(rng)
        u = gen.random(shape)
        return np.interp(u, self._grid_cdf, self._grid)

    @property
    def mean(self) -> float:
        return self._mean

    @property
    def var(self) -> float:
        return self._var

    @property
    def support(self) -> tuple[float, float]:
        return (self._lo, self._hi)

    def breakpoints(self) -> NDArray[np.float64]:
        return self._breaks.copy()

    def quadrature(
        self, nodes_per_panel: int = _GL_NODES
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        n = _checks.count(nodes_per_panel, "nodes_per_panel", minimum=1)
        nodes, w = _gl_panels(self._breaks, n)
        return nodes, w * self._call(nodes) / self._norm

    @property
    def params(self) -> dict[str, float]:
        return {"lo": self._lo, "hi": self._hi}

    def __repr__(self) -> str:
        name = getattr(self._density, "__name__", type(self._density).__name__)
        return (
            f"CustomJitter(pdf={name}, support=({self._lo!r}, {self._hi!r}), "
            f"breakpoints={self._breaks[1:-1].tolist()})"
        )


@dataclass(frozen=True)
class Shifted(JitterLaw):
    """A jitter law with a non-zero mean: ``tau = mean_s + tau0``, ``tau0 ~ law``.

    A converter or a scheduler that samples late on average by ``mean_s`` seconds, with the
    spread of ``law``. ``phi(f) = exp(-i 2 pi f mean_s) phi0(f)``; the density, support,
    breakpoints and quadrature are ``law``'s moved by ``mean_s``; the variance is ``law``'s.

    A mean jitter offset cannot be told apart from an input-output delay: the samples
    y_k = (G u)(kT + mean_s + tau0_k - delay_s) see ``delay_s - mean_s`` only
    (:class:`jitterid.Delayed` estimates the delay with this mean held at its given value).

    Parameters
    ----------
    law : JitterLaw
        The law of the zero-mean part ``tau0`` (a :class:`Shifted` law is flattened).
    mean_s : float
        The offset in seconds, finite.

    Examples
    --------
    >>> law = Shifted(Uniform(0.5), 0.2)
    >>> law.support, round(law.mean, 12)
    ((-0.3, 0.7), 0.2)
    """

    law: JitterLaw
    mean_s: float

    def __post_init__(self) -> None:
        if not isinstance(self.law, JitterLaw):
            raise TypeError(
                f"law must be a jitter law (Uniform(a), Gaussian(sigma), ...); got "
                f"{type(self.law).__name__}"
            )
        m = _checks.finite(self.mean_s, "mean_s")
        if isinstance(
            self.law, Shifted
        ):  # one level: Shifted(Shifted(l, a), b) = Shifted(l, a + b)
            object.__setattr__(self, "mean_s", m + self.law.mean_s)
            object.__setattr__(self, "law", self.law.law)
        else:
            object.__setattr__(self, "mean_s", m)

    def cf(self, f: ArrayLike) -> NDArray[np.complex128]:
        arr = _checks.real_array(f, "f")
        return np.exp(-2j * np.pi * arr * self.mean_s) * self.law.cf(arr)

    def pdf(self, tau: ArrayLike) -> NDArray[np.float64]:
        return self.law.pdf(_checks.real_array(tau, "tau") - self.mean_s)

    def sample(
        self, size: int | Sequence[int], rng: np.random.Generator | int
    ) -> NDArray[np.float64]:
        return self.law.sample(size, rng) + self.mean_s

    @property
    def mean(self) -> float:
        return self.law.mean + self.mean_s

    @property
    def var(self) -> float:
        return self.law.var

    @property
    def support(self) -> tuple[float, float]:
        lo, hi = self.law.support
        return (lo + self.mean_s, hi + self.mean_s)

    def breakpoints(self) -> NDArray[np.float64]:
        return np.asarray(self.law.breakpoints(), dtype=float) + self.mean_s

    def quadrature(
        self, nodes_per_panel: int = _GL_NODES
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        nodes, w = self.law.quadrature(nodes_per_panel)
        return nodes + self.mean_s, w

    @property
    def params(self) -> dict[str, float]:
        return {**self.law.params, "mean_s": self.mean_s}


def known_law(jitter: Any, name: str = "jitter") -> JitterLaw:
    """``jitter`` if it is a jitter law, else a TypeError naming ``name`` and the fix (a
    family is not a law until its parameters are known)."""
    if isinstance(jitter, JitterLaw):
        return jitter
    if isinstance(jitter, JitterFamily):
        raise TypeError(
            f"{name} must be a jitter law with known parameters; got the family "
            f"{type(jitter).__name__}, whose "
            "law is known only with its parameters: take family.law(params) (e.g. "
            f"{type(jitter).__name__}().law([...])) or estimate them with jitterid.fit"
        )
    raise TypeError(
        f"{name} must be a jitter law such as Uniform(0.5), Gaussian(0.1) or NoJitter(); got "
        f"{type(jitter).__name__}"
    )


def shifted(law: JitterLaw, offset_s: float) -> JitterLaw:
    """``law`` moved by ``offset_s`` seconds (``law`` itself for a zero offset)."""
    return law if offset_s == 0.0 else Shifted(law, offset_s)


# --------------------------------------------------------------------------------------------
# families
# --------------------------------------------------------------------------------------------


class JitterFamily(abc.ABC):
    """A parameterised jitter law ``p_theta(tau)``, for the JOE (2c) and JBJ (2d) structures.

    Attributes
    ----------
    param_names : tuple of str
        Names of the jitter parameters, in the order :meth:`law` expects them.
    bounds : tuple of (float, float)
        For every parameter a *closed* interval ``[lo, hi]`` of admissible values, suitable
        for ``scipy.optimize`` (``hi`` may be ``inf``). Scale parameters have a small positive
        floor (``1e-12`` by default) instead of the excluded value 0.

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.UniformFamily()
    >>> isinstance(fam, ji.JitterFamily), fam.law([0.05]).support
    (True, (-0.05, 0.05))
    """

    param_names: ClassVar[tuple[str, ...]]
    #: Index of the scale parameter a when the family's law is that of a * xi with xi free of
    #: a (its moments' derivative in a is then exact, without moving the quadrature nodes:
    #: (M3) of :mod:`jitterid.moments.modal`). ``None`` declares that there is none: every
    #: parameter's derivative then goes through the finite-difference route. A subclass
    #: that maps its parameters otherwise must set it again.
    scale_index: ClassVar[int | None] = None
    #: Indices of parameters that change the density inside a support that does not move
    #: with them (n of (26): support [-a, a] whatever n): the likelihood differences their
    #: score at the same quadrature nodes. Others move the nodes.
    fixed_support_params: ClassVar[tuple[int, ...]] = ()
    #: Index of a parameter in which the density is even about 0, its lower bound (a dual
    #: Dirac's dj, a scale mixture's rho): every likelihood's score in it vanishes at 0, so
    #: the structured sine likelihood (:mod:`jitterid.metrology.sinelik`) searches its
    #: square, in which ln L is regular there. ``None``: there is none.
    even_index: ClassVar[int | None] = None

    @property
    @abc.abstractmethod
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """Closed interval of admissible values for each parameter."""

    @abc.abstractmethod
    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        """Build the law from validated parameter values."""

    @abc.abstractmethod
    def _starts(self, T: float) -> list[tuple[float, ...]]:
        """Unvalidated starting values."""

    def law(self, params: Sequence[float]) -> JitterLaw:
        """The jitter law at parameter vector ``params``.

        Parameters
        ----------
        params : sequence of float
            One value per name in :attr:`param_names`, inside :attr:`bounds`.

        Returns
        -------
        JitterLaw

        Raises
        ------
        ValueError
            On a wrong number of parameters or a value outside its bounds (naming it).
        """
        try:
            vals = np.asarray(params, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(
                f"params must be a sequence of {len(self.param_names)} real numbers "
                f"{self.param_names}; got {params!r}"
            ) from exc
        if vals.shape != (len(self.param_names),):
            raise ValueError(
                f"params must hold {len(self.param_names)} value(s) {self.param_names}; got "
                f"shape {vals.shape}"
            )
        for name, v, (lo, hi) in zip(self.param_names, vals, self.bounds, strict=True):
            if not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} must be finite and lie in [{lo:g}, {hi:g}]; got {v!r}")
        return self._make(tuple(float(v) for v in vals))

    def at_std(self, params: ArrayLike, std: float) -> NDArray[np.float64]:
        """``params`` with the scale parameter (:attr:`scale_index`) set so that the law's
        standard deviation is ``std``: the same shape at another spread (the law is that of
        ``a * xi``). Unchanged for a family without a scale parameter, or a law of zero
        spread; the result is not clipped to :attr:`bounds`.

        Parameters
        ----------
        params : array_like
            The family's parameters, in :attr:`param_names` order.
        std : float
            The standard deviation wanted, in s.

        Examples
        --------
        >>> import jitterid as ji
        >>> fam = ji.SumOfUniformsFamily()
        >>> p = fam.at_std([0.0, 0.25], 0.1)  # n = 0: the uniform, std a / sqrt(3)
        >>> round(float(fam.law(p.tolist()).std), 12), p[0]
        (0.1, np.float64(0.0))
        """
        out = np.array(params, dtype=float)
        k = self.scale_index
        if k is None:
            return out
        now = self.law(out.tolist()).std
        if now > 0 and np.isfinite(now):
            out[k] *= float(std) / now
        return out

    def pdf_gradient(self, params: Sequence[float], tau: ArrayLike) -> NDArray[np.float64] | None:
        """``d p(tau) / d params`` at the nodes ``tau``, shape ``(len(params),) + tau.shape``, for a
        family whose density is differentiable in every parameter; ``None`` (the default) when
        it gives none. With it, the moments' derivatives (:mod:`jitterid.estimation.jacobians`)
        and the likelihood's score in the parameters other than the scale are
        ``E[g(tau) dp/dtheta / p]`` at fixed nodes instead of differences of new rules.

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        tau : array_like
            Jitter values in s.
        """
        return None

    def gives_pdf_gradient(self, params: Sequence[float]) -> bool:
        """Whether :meth:`pdf_gradient` gives dp/dtheta in closed form at ``params`` (the
        moments' derivatives and the likelihood's score then take it; else they difference).

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        """
        return self.pdf_gradient(params, np.zeros(0)) is not None

    def scale_equivalent(self, params: Sequence[float], index: int) -> float | None:
        """Where :meth:`pdf_gradient` gives none because ``params[index]`` sits on a kink
        (or a lower bound) of the family, the factor ``r`` for which the density's
        derivative in that parameter *from above* is ``r`` times its derivative in the scale
        (:attr:`scale_index`): ``dp/dtheta_index (+) = r dp/d(scale)``. The moments'
        derivatives and the likelihood's score in it from above are then ``r`` times the
        scale's (analytic) ones, where they would be one-sided differences with new nodes.
        ``None`` (the default) where the family gives no such factor.

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        index : int
            The parameter, an index into :attr:`param_names`.
        """
        return None

    def below_kink(
        self, params: Sequence[float], index: int
    ) -> tuple[float, tuple[tuple[float, JitterLaw], ...]] | None:
        """Where :meth:`pdf_gradient` gives none because ``params[index]`` sits on a kink
        (or an upper bound) of the family, the law's derivative in that parameter *from
        below* as a combination of laws: ``(c0, ((c1, L1), ...))`` with ``dp/dtheta_index (-)
        = c0 p + c1 p_L1 + ...`` (``p`` the law at ``params``; the coefficients sum to 0), as
        measures (a law ``L_j`` may be a point mass). The moments' derivatives from below are
        then ``c0 m + sum c_j m_j``: one moment pass a law, where a one-sided difference would
        take two with new nodes, and exact. ``None`` (the default) where the family gives no
        such combination.

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        index : int
            The parameter, an index into :attr:`param_names`.
        """
        return None

    @property
    def kinks(self) -> tuple[tuple[float, ...], ...]:
        """Where the law is not differentiable in each parameter: one tuple per parameter (in
        :attr:`param_names` order) of the interior values, inside :attr:`bounds`, at which
        the law's density (hence every criterion) has a kink in it; empty (the default)
        for a parameter the law depends on smoothly.

        Every search (:func:`jitterid.estimation.search.run_search`) searches such a
        parameter piece by piece between consecutive kinks, where the criterion is smooth,
        and stops at a kink only where neither neighbouring piece descends (the one-sided
        derivatives bracket zero).
        """
        return tuple(() for _ in self.param_names)

    def std_gradient(self, params: ArrayLike) -> NDArray[np.float64]:
        """``d std / d params`` of :meth:`law` at ``params`` by the one finite-difference rule
        (:mod:`jitterid.finite_diff`; second-order one-sided at a bound), steps relative to
        the law's own std where a parameter is near 0 (a jitter of 50 ps is not one of
        0.01 s); the laws' std is closed-form, so a relative step of 1e-6 is accurate.

        Parameters
        ----------
        params : array_like
            The family's parameters, in :attr:`param_names` order.
        """
        theta = np.asarray(params, float)

        def std(t: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.asarray(self.law(t.tolist()).std, dtype=np.float64)

        floor = max(float(std(theta)), 1e-300)
        return np.array(
            [
                float(finite_diff.derivative(std, theta, i, b, rel=1e-6, floor=floor))
                for i, b in enumerate(self.bounds)
            ]
        )

    def at_same_std(self, params: Sequence[float], index: int, value: float) -> tuple[float, ...]:
        """``params`` with parameter ``index`` set to ``value`` and the scale parameter (if
        any, and not ``index`` itself) set so that the law keeps its standard deviation: a
        move along the family at a fixed std (the direction the data hardly tell, e.g. the
        shape n of the family (26)). Clipped into :attr:`bounds`.

        Parameters
        ----------
        params : sequence of float
            The family's parameters, in :attr:`param_names` order.
        index : int
            The parameter to set.
        value : float
            Its new value.
        """
        out = [float(v) for v in params]
        std = float(self.law(out).std)
        out[index] = float(value)
        k = self.scale_index
        if k is not None and k != index and std > 0:
            moved = float(self.law(out).std)
            if moved > 0:
                lo, hi = self.bounds[k]
                out[k] = float(min(max(out[k] * std / moved, lo), hi))
        return tuple(out)

    def start_for_std(self, std: float) -> tuple[float, ...]:
        """Parameters of a law of the family with standard deviation ``std`` (a start from a
        jitter std measured otherwise): the middle default start with its scale parameter
        set so; a family without a scale parameter overrides this.

        Parameters
        ----------
        std : float
            The wanted standard deviation (> 0), in the family's time unit.

        Returns
        -------
        tuple of float
            Accepted by :meth:`law`, clipped into :attr:`bounds`.
        """
        std = _checks.positive(std, "std")
        starts = self.default_starts(1.0)
        base = list(starts[len(starts) // 2])
        idx = self.scale_index
        if idx is not None:
            law_std = float(self.law(base).std)
            if law_std > 0:
                lo, hi = self.bounds[idx]
                base[idx] = float(min(max(base[idx] * std / law_std, lo), hi))
        return tuple(base)

    def default_starts(self, T: float) -> list[tuple[float, ...]]:
        """A coarse grid (3 to 6 points) of starting values for a multi-start search.

        Parameters
        ----------
        T : float
            Nominal sampling interval (s); the scale parameters are fractions of ``T/2``, clipped
            into :attr:`bounds`.

        Returns
        -------
        list of tuple of float
            Distinct parameter vectors, each accepted by :meth:`law`.
        """
        t = _checks.positive(T, "T")
        out: list[tuple[float, ...]] = []
        for start in self._starts(t):
            clipped = tuple(
                float(min(max(v, lo), hi)) for v, (lo, hi) in zip(start, self.bounds, strict=True)
            )
            if clipped not in out:
                out.append(clipped)
        return out


def _upper(x: float | None, name: str) -> float:
    return math.inf if x is None else _checks.positive(x, name)


def _scale_range(family: object, name: str) -> None:
    """Check a family's bounds ``{name}_min < {name}_max`` on a scale (the floor positive,
    the ceiling positive or None), naming the bad one."""
    lo, hi = getattr(family, f"{name}_min"), getattr(family, f"{name}_max")
    if not _checks.positive(lo, f"{name}_min") < _upper(hi, f"{name}_max"):
        raise ValueError(f"{name}_min must be below {name}_max; got {lo!r} >= {hi!r}")


@dataclass(frozen=True)
class UniformFamily(JitterFamily):
    """``U(-a, a)`` with unknown ``a`` (the family (26) at ``n = 0``).

    Parameters
    ----------
    a_max : float or None
        Upper bound on ``a`` (``None``: unbounded). A natural choice is ``T/2``.
    a_min : float
        Lower bound on ``a``, a small positive floor excluding 0; default ``1e-12``.
        Lower it if time is measured in units where the jitter is that small.

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.UniformFamily()
    >>> fam.law([0.05]).support
    (-0.05, 0.05)
    """

    a_max: float | None = None
    a_min: float = _SCALE_FLOOR
    param_names: ClassVar[tuple[str, ...]] = ("a",)
    scale_index: ClassVar[int | None] = 0

    def __post_init__(self) -> None:
        _scale_range(self, "a")

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return ((float(self.a_min), _upper(self.a_max, "a_max")),)

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return Uniform(values[0])

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = min(T / 2.0, _upper(self.a_max, "a_max"))
        return [(top / 4.0,), (top / 2.0,), (top,)]


@dataclass(frozen=True)
class GaussianFamily(JitterFamily):
    """``N(0, sigma^2)`` with unknown ``sigma``.

    Parameters
    ----------
    sigma_max : float or None
        Upper bound on ``sigma`` (``None``: unbounded).
    sigma_min : float
        Lower bound, a small positive floor excluding 0; default ``1e-12``.

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.GaussianFamily()
    >>> fam.law([0.01])
    Gaussian(sigma=0.01)
    """

    sigma_max: float | None = None
    sigma_min: float = _SCALE_FLOOR
    param_names: ClassVar[tuple[str, ...]] = ("sigma",)
    scale_index: ClassVar[int | None] = 0

    def __post_init__(self) -> None:
        _scale_range(self, "sigma")

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return ((float(self.sigma_min), _upper(self.sigma_max, "sigma_max")),)

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return Gaussian(values[0])

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = min(T / 4.0, _upper(self.sigma_max, "sigma_max"))
        return [(top / 6.0,), (top * 0.4,), (top,)]


def _on_integer(params: Sequence[float], index: int) -> tuple[int, float] | None:
    """``(round(n), a)`` of the family (26)'s ``params`` where ``index`` is n's (0) and n is
    an integer within ``_INTEGER_TOL`` (its kinks and the bound 0), else None."""
    n, a = float(params[0]), float(params[1])
    if index != 0 or abs(n - round(n)) > _INTEGER_TOL:
        return None
    return round(n), a


@dataclass(frozen=True)
class SumOfUniformsFamily(JitterFamily):
    """The paper's family (26) with unknown ``(n, a)``, ``n`` real (see :class:`SumOfUniforms`).

    Parameters
    ----------
    n_max : float
        Upper bound on ``n``, at most 50; default 20.
    a_max : float or None
        Upper bound on ``a`` (``None``: unbounded). A natural choice is ``T/2``.
    a_min : float
        Lower bound on ``a``, a small positive floor excluding 0; default ``1e-12``.

    Examples
    --------
    >>> import jitterid as ji
    >>> fam = ji.SumOfUniformsFamily()
    >>> law = fam.law([2.0, 0.3])
    >>> law.support, round(float(law.std), 6)
    ((-0.3, 0.3), 0.1)
    """

    n_max: float = 20.0
    a_max: float | None = None
    a_min: float = _SCALE_FLOOR
    param_names: ClassVar[tuple[str, ...]] = ("n", "a")
    scale_index: ClassVar[int | None] = 1
    fixed_support_params: ClassVar[tuple[int, ...]] = (0,)

    def __post_init__(self) -> None:
        n_max = _checks.positive(self.n_max, "n_max", allow_zero=True)
        if n_max > N_MAX:
            raise ValueError(f"n_max must be at most {N_MAX:g}; got {self.n_max!r}")
        _scale_range(self, "a")

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        return ((0.0, float(self.n_max)), (float(self.a_min), _upper(self.a_max, "a_max")))

    def _make(self, values: tuple[float, ...]) -> JitterLaw:
        return SumOfUniforms(values[0], values[1])

    @property
    def kinks(self) -> tuple[tuple[float, ...], ...]:
        """``n`` at every integer inside ``(0, n_max)`` (see :class:`SumOfUniforms`: its
        non-integer extension is continuous in ``n`` with a kink at each integer); ``a``
        nowhere."""
        return (tuple(float(k) for k in range(1, math.ceil(self.n_max))), ())

    def pdf_gradient(self, params: Sequence[float], tau: ArrayLike) -> NDArray[np.float64] | None:
        """``d p(tau) / d (n, a)`` in closed form (:meth:`SumOfUniforms.pdf_gradient`), shape
        ``(2,) + tau.shape``; ``None`` at an integer ``n`` (a kink: one-sided derivatives)
        and less than ``1e-9`` below one, where the callers difference instead.

        Parameters
        ----------
        params : sequence of float
            ``(n, a)``.
        tau : array_like
            Jitter values in s.
        """
        law = self.law(params)
        assert isinstance(law, SumOfUniforms)
        return law.pdf_gradient(tau)

    def scale_equivalent(self, params: Sequence[float], index: int) -> float | None:
        """``-a / (2 nu)`` for ``n`` at an integer ``nu - 1`` (within ``1e-12``: a kink, or
        the bound 0), else ``None``.

        Just above an integer, ``K = nu`` equal uniforms of half-width ``b`` and one of
        half-width ``c = a - K b`` make the law (:class:`SumOfUniforms`); at the integer
        ``b = a / nu``, ``db/dn = -a / (2 nu^2)`` (finite from above), and ``c`` grows
        linearly in the distance ``eps`` while its effect on the law is ``O(c^2)`` (the
        window mean of a smooth integrand). To first order in ``eps`` the law is therefore
        that of ``nu`` equal uniforms of total half-width ``a (1 - eps / (2 nu))``, the
        family at the same ``n`` with its scale moved: ``dp/dn (+) = -a / (2 nu) dp/da``.
        (From below ``db/dn`` is infinite: no factor; see :meth:`below_kink`.)
        Measured on the characteristic function (26): the forward differences in ``n``,
        Richardson-extrapolated, agree with ``-a / (2 nu)`` times the central ones in ``a``
        to 1e-9 at n = 0, 1, 2, 5 (tests/jitter/test_sum_of_uniforms_gradient.py).

        Parameters
        ----------
        params : sequence of float
            ``(n, a)``.
        index : int
            0 (``n``); ``a`` is the scale (``None``).
        """
        on = _on_integer(params, index)
        return None if on is None else -on[1] / (2.0 * (on[0] + 1.0))

    def below_kink(
        self, params: Sequence[float], index: int
    ) -> tuple[float, tuple[tuple[float, JitterLaw], ...]] | None:
        """``(-1/2, ((1/2, L),))`` for ``n`` at an integer ``M - 1 >= 1`` (within ``1e-12``),
        ``L`` the sum of ``M - 2`` uniforms ``U(-a/M, a/M)`` (``SumOfUniforms(M - 3, (M - 2)
        a / M)``; for ``M = 2`` the point mass at 0, :class:`NoJitter`); else ``None``.

        Just below the integer, ``K = M - 1`` uniforms of half-width ``b`` and one of ``c``
        make the law, ``b, c`` leaving ``b0 = a / M`` by ``delta_i`` of order
        ``sqrt(eps)`` (``eps`` the distance) with ``sum delta_i = 0`` (the support) and
        ``sum delta_i^2 = a^2 eps / M^2`` (the variance). With ``h(w) = sinc(2 f w)``,
        ``phi = prod h(w_i)``: the first order cancels and the second is
        ``(1/2) sum delta_i^2 g''(b0) phi``, ``g = log h``, where ``g''(b0) phi = (phi_M -
        phi_{M-2}) / b0^2`` (``1 / sin^2 x = 1 / (x^2 sinc^2 x)``, ``x = 2 pi f b0``;
        ``phi_{M-2}`` the characteristic function of ``M - 2`` of the uniforms). So ``phi(n)
        = phi_M - (eps / 2) (phi_M - phi_{M-2}) + O(eps^(3/2))``, and the derivative from
        below is ``dp/dn (-) = -(p - p_L) / 2``: finite, although the density's own widths
        move like ``sqrt(eps)`` (at ``M = 2`` the triangle's peak falls like
        ``sqrt(eps)`` over a width ``sqrt(eps)``: a moment moves like ``eps``). Backward
        differences of (26) converge to it like ``sqrt(h)`` (``O(eps^(3/2))`` next term):
        measured in tests/jitter/test_sum_of_uniforms_gradient.py.

        Parameters
        ----------
        params : sequence of float
            ``(n, a)``.
        index : int
            0 (``n``); ``a`` is the scale (``None``).
        """
        on = _on_integer(params, index)
        if on is None or on[0] < 1:
            return None
        m, a = on[0] + 1, on[1]
        other: JitterLaw = NoJitter() if m == 2 else SumOfUniforms(m - 3, (m - 2) * a / m)
        return -0.5, ((0.5, other),)

    def _starts(self, T: float) -> list[tuple[float, ...]]:
        top = min(T / 2.0, _upper(self.a_max, "a_max"))
        return [(n, a) for n in (0.0, 2.0, 8.0) for a in (top / 2.0, top)]
