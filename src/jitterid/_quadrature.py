"""Quadrature over the jitter: nodes and weights with E[g(kT + tau)] ~ sum w g(t).

The integrand g(kT + tau) p(tau) is smooth except where the input switches (the output
has a kink or a jump there) and where the jitter pdf has knots. The time axis is cut at
both, and further so that no panel is longer than ``1 / rate`` (the signal's fastest
rate) or than the jitter's standard deviation (the scale of a smooth pdf); each panel then
gets a Gauss-Legendre rule, which converges exponentially on analytic integrands. The
work is O(N) and is produced in chunks of samples so that memory stays bounded.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .distributions import JitterLaw

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DEFAULT_ORDER = 5
DEFAULT_CHUNK = 16384


@dataclass(frozen=True)
class NodeChunk:
    """Quadrature for samples k0..k1-1: E[g(kT + tau)] ~ sum over owner == k - k0 of w g(t)."""

    k0: int
    k1: int
    t: FloatArray
    w: FloatArray
    owner: IntArray

    def expect(self, values: FloatArray) -> FloatArray:
        """Per-sample weighted sums of ``values`` (one per node)."""
        return np.bincount(self.owner, self.w * values, minlength=self.k1 - self.k0)


@lru_cache(maxsize=64)
def _gauss_legendre(order: int) -> tuple[FloatArray, FloatArray]:
    x, w = np.polynomial.legendre.leggauss(order)
    return x, w


def _relative_cuts(law: JitterLaw, max_panel: float) -> FloatArray:
    """The pdf's knots, subdivided so that no gap exceeds ``max_panel``."""
    knots = np.unique(np.asarray(law.breakpoints(), dtype=float))
    pieces = [knots[:1]]
    for a, b in itertools.pairwise(knots):
        n = max(1, int(np.ceil((b - a) / max_panel)))
        pieces.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(pieces)


def jitter_nodes(
    law: JitterLaw,
    T: float,
    N: int,
    breaks: FloatArray,
    rate: float,
    *,
    order: int = DEFAULT_ORDER,
    max_panel: float | None = None,
    chunk: int = DEFAULT_CHUNK,
) -> Iterator[NodeChunk]:
    """Yield :class:`NodeChunk` s covering samples 0..N-1.

    Parameters
    ----------
    law : JitterLaw
        The jitter law (support, knots and pdf are used).
    T, N : float, int
        Nominal grid kT, k = 0..N-1.
    breaks : ndarray
        Absolute times where the integrand is not smooth (input switch times).
    rate : float
        Fastest rate of the signal between breaks (1/s); panels are kept <= 1/rate.
    order : int
        Gauss-Legendre nodes per panel.
    max_panel : float, optional
        Extra upper bound on the panel length (e.g. for a sharply peaked integrand).
    chunk : int
        Samples per yielded chunk.
    """
    lo, hi = (float(v) for v in law.support)
    if hi <= lo:  # a point mass: the expectation is the value at kT + lo
        for k0 in range(0, N, chunk):
            k1 = min(N, k0 + chunk)
            ks = np.arange(k0, k1)
            yield NodeChunk(k0, k1, ks * T + lo, np.ones(k1 - k0), ks - k0)
        return
    limit = hi - lo
    if rate > 0:
        limit = min(limit, 1.0 / rate)
    if law.std > 0:
        limit = min(limit, float(law.std))
    if max_panel is not None:
        limit = min(limit, max_panel)
    rel = _relative_cuts(law, limit)
    x, wx = _gauss_legendre(order)
    breaks = np.sort(np.asarray(breaks, dtype=float))
    for k0 in range(0, N, chunk):
        k1 = min(N, k0 + chunk)
        ks = np.arange(k0, k1)
        grid = ks[:, None] * T + rel[None, :]
        first, last = grid[0, 0], grid[-1, -1]
        inner = breaks[(breaks > first) & (breaks < last)]
        cuts = np.unique(np.concatenate([grid.ravel(), inner]))
        # grid[:, 0] and grid[:, -1] are in ``cuts`` bit for bit, so searchsorted is exact.
        i0 = np.searchsorted(cuts, grid[:, 0])
        i1 = np.searchsorted(cuts, grid[:, -1])
        npan = i1 - i0
        owner = np.repeat(np.arange(k1 - k0), npan)
        offset = np.arange(owner.size) - np.repeat(np.cumsum(npan) - npan, npan)
        a = cuts[i0[owner] + offset]
        b = cuts[i0[owner] + offset + 1]
        half = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        t = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        tau = t - np.repeat(ks[owner], order) * T
        w = (half[:, None] * wx[None, :]).ravel() * law.pdf(np.clip(tau, lo, hi))
        yield NodeChunk(k0, k1, t, w, np.repeat(owner, order))
