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

from ..jitter.laws import JitterLaw

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
        sums = np.bincount(self.owner, self.w * values, minlength=self.k1 - self.k0)
        return np.asarray(sums, dtype=np.float64)


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


def relative_cuts(law: JitterLaw, rate: float, max_panel: float | None = None) -> FloatArray:
    """Panel edges in tau (relative to kT) of the rule of :func:`jitter_nodes`.

    The pdf's knots, subdivided so that no panel exceeds the support width, ``1 / rate``, the
    jitter's standard deviation or ``max_panel``. Two signals whose rates give the same
    edges get the same nodes, which lets a caller keep a rule across parameter values
    (:mod:`jitterid.moments.modal`). Empty for a point mass.
    """
    lo, hi = (float(v) for v in law.support)
    if hi <= lo:
        return np.zeros(0)
    limit = hi - lo
    if rate > 0:
        limit = min(limit, 1.0 / rate)
    if law.std > 0:
        limit = min(limit, float(law.std))
    if max_panel is not None:
        limit = min(limit, max_panel)
    return _relative_cuts(law, limit)


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
    shared_pdf: bool = False,
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
    shared_pdf : bool
        Take the pdf at the nodes of panels that no break cuts from one table for all
        samples (it then differs from the pdf at each sample's own nodes by their rounding
        in kT, ~1e-16 relative): cheaper for a costly pdf. Off by default, so that a rule
        is reproducible bit for bit whatever its use.
    """
    lo, hi = (float(v) for v in law.support)
    if hi <= lo:  # a point mass: the expectation is the value at kT + lo
        for k0 in range(0, N, chunk):
            k1 = min(N, k0 + chunk)
            ks = np.arange(k0, k1)
            t = np.asarray(ks * T + lo, dtype=np.float64)
            yield NodeChunk(k0, k1, t, np.ones(k1 - k0), (ks - k0).astype(np.int64))
        return
    rel = relative_cuts(law, rate, max_panel)
    x, wx = _gauss_legendre(order)
    breaks = np.sort(np.asarray(breaks, dtype=float))
    # The pdf at the nodes of the standard panels [rel_m, rel_m+1] (those no break cuts): the
    # same for every sample, so evaluated once (a non-integer SumOfUniforms costs ~1 us per
    # point). It differs from the pdf at a sample's own nodes only by their rounding in kT.
    std_half = 0.5 * np.diff(rel)
    std_pdf = None
    if shared_pdf:
        std_pdf = law.pdf(np.clip((0.5 * (rel[:-1] + rel[1:]))[:, None] + std_half[:, None] * x, lo, hi))
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
        if std_pdf is None:
            w: FloatArray = (half[:, None] * wx[None, :]).ravel() * law.pdf(np.clip(tau, lo, hi))
        else:
            # A panel is standard when its ends are rel_m, rel_m+1 up to the rounding of kT.
            kt = ks[owner] * T
            m = np.clip(np.searchsorted(rel, a - kt), 1, rel.size - 1) - 1
            m = np.where(np.abs(a - kt - rel[m + 1]) < np.abs(a - kt - rel[m]), m + 1, m)
            m = np.minimum(m, rel.size - 2)
            tol = 8 * np.spacing(np.abs(kt) + np.max(np.abs(rel)))
            std = (np.abs(a - kt - rel[m]) <= tol) & (np.abs(b - kt - rel[m + 1]) <= tol)
            dens = np.empty((owner.size, order))
            dens[std] = std_pdf[m[std]]
            other = ~std
            if np.any(other):
                dens[other] = law.pdf(np.clip(tau.reshape(-1, order)[other], lo, hi))
            w = np.ravel(half[:, None] * wx[None, :] * dens)
        yield NodeChunk(k0, k1, t, w, np.repeat(owner, order))
