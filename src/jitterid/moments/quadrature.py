"""Quadrature over the jitter: nodes and weights with E[g(kT + tau)] ~ sum w g(t).

The integrand g(kT + tau) p(tau) is smooth except where the input switches (the output
has a kink or a jump there) and where the jitter pdf has knots. Each sample's window is
cut at the pdf's knots (its standard edges kT + :func:`relative_cuts`) and at the switches
inside it, and nowhere else: no panel is longer than ``1 / rate`` (the signal's fastest
rate) or than the jitter's standard deviation (for a Gaussian, a law that declares a band
rule: 0.6 to 1.7 sigma by zone, on a window shared by a band of sigma,
:func:`rule_frame`); each panel then gets a Gauss-Legendre rule, which converges
exponentially on analytic integrands. A fast, damped mode shortens the panels only right
after the switches that restart it (:func:`panel_layout`), and a rule over
:data:`PANEL_LIMIT` panels is refused before anything is allocated. The work is O(N) and is
produced in chunks of a bounded number of panels, so that memory stays bounded.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..jitter.laws import BandRule, JitterLaw

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DEFAULT_ORDER = 5
DEFAULT_CHUNK = 16384
_CHUNK_PANELS = 1 << 17  # panels per chunk at most (about 5 MB per node array at order 5)


@dataclass(frozen=True)
class NodeChunk:
    """Quadrature for samples k0..k1-1: E[g(kT + tau)] ~ sum over owner == k - k0 of w g(t)."""

    k0: int
    k1: int
    t: FloatArray
    w: FloatArray
    owner: IntArray
    gw: FloatArray | None = None  # Gauss-Legendre weight times half the panel, per node
    tau: FloatArray | None = None  # node offset t - kT (w = gw * pdf(clip(tau)))

    def expect(self, values: FloatArray) -> FloatArray:
        """Per-sample weighted sums of ``values`` (one per node)."""
        sums = np.bincount(self.owner, self.w * values, minlength=self.k1 - self.k0)
        return np.asarray(sums, dtype=np.float64)


def _unique(a: FloatArray) -> FloatArray:
    """np.unique of a 1-D array, without its sort when ``a`` already increases strictly
    (the input's switch times and a law's knots, at every evaluation)."""
    if a.ndim == 1 and (a.size < 2 or bool((a[1:] > a[:-1]).all())):
        return a
    return np.unique(a)


@lru_cache(maxsize=64)
def _gauss_legendre(order: int) -> tuple[FloatArray, FloatArray]:
    x, w = np.polynomial.legendre.leggauss(order)
    return x, w


def _relative_cuts(
    law: JitterLaw,
    max_panel: float,
    knots: FloatArray | None = None,
    limits: FloatArray | None = None,
) -> FloatArray:
    """The pdf's knots (or ``knots``), subdivided so that no gap exceeds ``max_panel`` (nor
    ``limits[i]`` between knots i and i + 1)."""
    knots = np.asarray(law.breakpoints() if knots is None else knots, dtype=float)
    if limits is None:
        knots = _unique(knots)
    if knots.size < 2:
        return knots[:1].copy()
    a, b = knots[:-1], knots[1:]
    lim = np.full(a.size, max_panel) if limits is None else np.minimum(max_panel, limits[: a.size])
    n = np.maximum(1, np.ceil((b - a) / lim)).astype(np.int64)
    # np.linspace(a, b, n + 1)[1:] of every gap at once, with linspace's own arithmetic
    # (j * step + a, the last point b exactly), so the edges are those of the loop it replaces
    gap = np.repeat(np.arange(a.size), n)
    j = np.arange(gap.size) - np.repeat(np.cumsum(n) - n, n) + 1.0
    out = j * ((b - a) / n)[gap] + a[gap]
    out[np.cumsum(n) - 1] = b
    return np.concatenate([knots[:1], out])


#: Laws that declare a :class:`~jitterid.jitter.laws.BandRule` (the Gaussian) are laid out for
#: a band of their scale, [sigma_b, sigma_b * 2**(1/8)) with sigma_b a power of 2**(1/8): the
#: window covers the support of every scale in the band and no panel exceeds its zone's
#: length in sigma_b <= scale. The nodes are then those of every law in the band (only their
#: pdf weights differ), so a search over the scale keeps its node geometry.
_BANDS_PER_OCTAVE = 8


def scale_band(scale: float) -> float:
    """sigma_b, the lower end of the band of rules that holds ``scale``."""
    e = np.floor(_BANDS_PER_OCTAVE * np.log2(scale) + 1e-12) / _BANDS_PER_OCTAVE
    return float(2.0**e)


def band_rule(law: object) -> BandRule | None:
    """The law's :attr:`~jitterid.jitter.laws.JitterLaw.band_rule` capability; None for the
    stand-ins of a law that the likelihood lays out (a unit density, a stretched law)."""
    return law.band_rule if isinstance(law, JitterLaw) else None


def rule_frame(law: JitterLaw) -> tuple[FloatArray, float, tuple[float, float]]:
    """(knots, panel scale, clip interval) of the rule for ``law``: the pdf's knots and
    standard deviation, except for a law that declares a band rule (a Gaussian), whose rule
    is that of its band (:func:`scale_band`), cut into its zones. Node offsets tau are clipped
    to the third value before the pdf is taken (a node rounded past a knot of a bounded
    support stays on it); no clipping for a band law, whose pdf is zero beyond its window."""
    band = band_rule(law)
    if band is not None:
        sb = scale_band(band.scale)
        h = band.half_width * sb * 2.0 ** (1.0 / _BANDS_PER_OCTAVE)
        z = np.array(band.zones) * sb
        return np.concatenate([[-h], -z[::-1], z, [h]]), sb, (-np.inf, np.inf)
    lo, hi = (float(v) for v in law.support)
    return np.asarray(law.breakpoints(), dtype=float), float(law.std), (lo, hi)


def relative_cuts(law: JitterLaw, rate: float, max_panel: float | None = None) -> FloatArray:
    """Panel edges in tau (relative to kT) of the rule of :func:`jitter_nodes`.

    The pdf's knots, subdivided so that no panel exceeds the support width, ``1 / rate``, the
    jitter's standard deviation or ``max_panel`` (for a band law, a Gaussian: the window of
    its band, :func:`rule_frame`, with its zones' panels, 0.6 to 1.7 sigma_b). Two signals
    whose rates give the same edges get the same nodes, which lets a caller keep a rule across
    parameter values (:mod:`jitterid.moments.modal`). Empty for a point mass.
    """
    lo, hi = (float(v) for v in law.support)
    if hi <= lo:
        return np.zeros(0)
    knots, scale, _ = rule_frame(law)
    limit = float(knots[-1] - knots[0])
    if rate > 0:
        limit = min(limit, 1.0 / rate)
    if max_panel is not None:
        limit = min(limit, max_panel)
    band = band_rule(law)
    if band is not None:  # panel lengths by zone
        return _relative_cuts(law, limit, knots, np.array(band.zone_panels) * scale)
    if scale > 0:
        limit = min(limit, scale)
    return _relative_cuts(law, limit, knots)


#: A mode of rate |p| with |p| * (the jitter's panel scale) above this, damped at least
#: _GRADE_DAMPING * |p|, does not shorten every panel to 1 / |p|: it is smooth on the
#: jitter's scale a few time constants after the switch that restarts it, so graded cuts
#: after every switch resolve it (:func:`panel_layout`).
_GRADE_FROM = 4.0
_GRADE_DAMPING = 0.25
_GRADE_DECAY = 40.0  # the graded cuts reach a time where the mode is below e^-40
#: Refuse a rule with more panels than this over all samples (memory is bounded by the
#: chunking, but such a rule would take minutes per evaluation).
PANEL_LIMIT = 200_000_000


@dataclass(frozen=True, eq=False)
class Layout:
    """The panel layout of a signal: ``rate`` bounds every panel (1 / rate), ``grade`` are
    offsets of extra cuts after every switch (where the fast, damped modes restart)."""

    rate: float
    grade: FloatArray
    limit: float = np.inf  # the panel length the rate allows with the law's own (min(L0, 1 / rate))

    @property
    def key(self) -> bytes:
        """Equal for layouts with the same rule (rates below the law's scale do not matter)."""
        return np.concatenate(([self.limit], self.grade)).tobytes()


def panel_layout(law: JitterLaw, poles: ArrayLike, order: int = DEFAULT_ORDER) -> Layout:
    """The layout for a signal with these poles (modes e^{p t} restarted at every switch).

    Slow modes (|p| times the jitter's panel scale L0 at most ``_GRADE_FROM``) and fast ones
    with little damping keep the rule of :func:`relative_cuts` with rate max |p|: panels of
    at most 1 / |p|. A fast, damped mode (Re p <= -``_GRADE_DAMPING`` |p|) gets graded cuts
    after every switch instead: at dt after the switch the panel may be
    h = exp(a dt / (2 order)) / lam long, lam >= |p| and a <= -Re p (both rounded to half
    octaves, so that nearby poles share a layout), because the Gauss-Legendre error on
    e^{p t} scales as (|p| h)^(2 order) times the size e^{-a dt} of the mode: never worse than
    with panels of 1 / |p| everywhere. The cuts stop where the mode is below e^-40 or h
    exceeds the other limits. A pole at -4e5 rad/s then costs ~20 cuts after each switch
    instead of ~1e6 panels per sample.
    """
    p = np.atleast_1d(np.asarray(poles, dtype=complex))
    try:  # a law equal by value has the same rule (an unhashable law is not memoised)
        key = (law, p.tobytes(), order)
        got = _layouts.get(key)
    except TypeError:
        return _panel_layout(law, p, order)
    if got is None:
        got = _panel_layout(law, p, order)
        if len(_layouts) >= _LAYOUTS_KEPT:
            _layouts.clear()
        _layouts[key] = got
    return got


#: panel_layout's last results: a search asks for the layout of each new law a few times
#: (the plan's key, its construction and the plan cache's match)
_LAYOUTS_KEPT = 16
_layouts: dict[tuple[JitterLaw, bytes, int], Layout] = {}


def _panel_layout(law: JitterLaw, p: NDArray[np.complex128], order: int) -> Layout:
    knots, scale, _ = rule_frame(law)
    width = float(knots[-1] - knots[0]) if knots.size > 1 else 0.0
    if width <= 0 or p.size == 0:
        return Layout(float(np.max(np.abs(p))) if p.size else 0.0, np.zeros(0))
    # the longest panel the law's own rule has (rates below 1 / L0 change no edge)
    band = band_rule(law)
    if band is not None:
        scale = scale * float(np.max(band.zone_panels))
    L0 = min(width, scale) if scale > 0 else width
    mag, damp = np.abs(p), -p.real
    fast = (mag * L0 > _GRADE_FROM) & (damp >= _GRADE_DAMPING * mag)
    rate = float(np.max(mag[~fast])) if not fast.all() else 0.0
    limit = min(L0, 1.0 / rate) if rate > 0 else L0
    if not fast.any():
        return Layout(rate, np.zeros(0), limit)
    lam = 2.0 ** (np.ceil(2 * np.log2(float(np.max(mag[fast])))) / 2)
    a = 2.0 ** (np.floor(2 * np.log2(float(np.min(damp[fast])))) / 2)
    offsets, dt = [], 0.0
    while a * dt < _GRADE_DECAY:
        h = float(np.exp(a * dt / (2 * order))) / lam
        if h >= limit:
            break
        dt += h
        offsets.append(dt)
    return Layout(rate, np.array(offsets), limit)


def _window_cuts(
    rel: FloatArray, breaks: FloatArray, grade: FloatArray, ks: IntArray, T: float
) -> tuple[FloatArray, IntArray, IntArray, IntArray]:
    """Every sample's own panel edges: its standard edges kT + rel and the cuts (the breaks
    and the graded offsets after them) strictly inside its window, merged in order.

    Returns (cuts, row_len, std_pos, std_m): the samples' rows of edges laid end to end, the
    row lengths, and for every standard panel (two consecutive standard edges with no cut
    between) the index in ``cuts`` of its first edge and its standard-panel number m. No other
    sample's edges cut a window, so a sample's rule depends neither on its neighbours nor on
    the chunking.
    """
    n, R1 = ks.size, rel.size
    kt = ks * T
    grid = ks[:, None] * T + rel[None, :]
    g0, g1 = grid[:, 0], grid[:, -1]
    reach = float(grade[-1]) if grade.size else 0.0
    # breaks whose cuts b + {0, grade} can fall inside the window (g0, g1)
    b_lo = (
        np.searchsorted(breaks, g0 - reach, side="right")
        if reach
        else np.searchsorted(breaks, g0, side="right")
    )
    b_hi = np.searchsorted(breaks, g1, side="left")
    nb = np.maximum(b_hi - b_lo, 0)
    offs = np.concatenate(([0.0], grade))
    total = int(nb.sum())
    if total:
        own = np.repeat(np.arange(n), nb)
        bidx = np.arange(total) - np.repeat(np.cumsum(nb) - nb, nb) + np.repeat(b_lo, nb)
        v = (breaks[bidx][:, None] + offs[None, :]).ravel()
        own = np.repeat(own, offs.size)
        inside = (v > g0[own]) & (v < g1[own])
        v, own = v[inside], own[inside]
        if offs.size > 1 and v.size:  # graded cuts of several breaks interleave: sort
            order = np.lexsort((v, own))
            v, own = v[order], own[order]
        if v.size > 1:  # drop exact duplicates within a sample
            keep = np.concatenate(([True], (v[1:] != v[:-1]) | (own[1:] != own[:-1])))
            v, own = v[keep], own[keep]
        # m: how many of the sample's standard edges lie below the cut (exactly, in absolute time)
        m = np.minimum(np.maximum(np.searchsorted(rel, v - kt[own]), 1), R1 - 1)
        m = np.where(grid[own, m - 1] >= v, m - 1, m)
        m = np.where((m < R1) & (grid[own, np.minimum(m, R1 - 1)] < v), m + 1, m)
        keep = grid[own, np.minimum(m, R1 - 1)] != v  # a cut on a standard edge adds nothing
        v, own, m = v[keep], own[keep], m[keep]
    else:
        v, own, m = np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64)
    nx = np.bincount(own, minlength=n)
    row_len = R1 + nx
    row_start = np.cumsum(row_len) - row_len
    # c[o, i]: cuts of sample o below standard edge i
    cnt = np.bincount(own * (R1 + 1) + m, minlength=n * (R1 + 1)).reshape(n, R1 + 1)
    c = np.cumsum(cnt, axis=1)[:, :R1]
    cuts = np.empty(int(row_len.sum()))
    pos_grid = row_start[:, None] + np.arange(R1)[None, :] + c
    cuts[pos_grid.ravel()] = grid.ravel()
    if v.size:
        first = np.cumsum(nx) - nx
        rank = np.arange(v.size) - first[own]
        cuts[row_start[own] + m + rank] = v
    # standard panels: edge i to i + 1 with no cut between (c unchanged)
    o_idx, i_idx = np.nonzero(c[:, 1:] == c[:, :-1])
    return cuts, row_len, pos_grid[o_idx, i_idx], i_idx


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
    grade: FloatArray | None = None,
    rel: FloatArray | None = None,
) -> Iterator[NodeChunk]:
    """Yield :class:`NodeChunk` s covering samples 0..N-1.

    Sample k's panels are its standard edges kT + :func:`relative_cuts` cut at the breaks in
    its window and, with ``grade``, at the offsets b + grade after every break b (where a fast
    mode restarts); nothing else (in particular not the edges of overlapping windows of other
    samples), so each sample's rule is its own and does not depend on ``chunk``.

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
        Largest number of samples per yielded chunk; fewer when a sample has many panels, so
        that a chunk holds at most about ``_CHUNK_PANELS`` panels.
    shared_pdf : bool
        Take the pdf at the nodes of panels that no break cuts from one table for all
        samples (it then differs from the pdf at each sample's own nodes by their rounding
        in kT, ~1e-16 relative): cheaper for a costly pdf. Off by default, so that a rule
        is reproducible bit for bit whatever its use.
    grade : ndarray, optional
        Increasing positive offsets of extra cuts after every break (:func:`panel_layout`).
    rel : ndarray, optional
        The standard edges if already known (``relative_cuts(law, rate, max_panel)``).
    """
    lo, hi = (float(v) for v in law.support)
    if hi <= lo:  # a point mass: the expectation is the value at kT + lo
        for k0 in range(0, N, chunk):
            k1 = min(N, k0 + chunk)
            ks = np.arange(k0, k1)
            t = np.asarray(ks * T + lo, dtype=np.float64)
            yield NodeChunk(k0, k1, t, np.ones(k1 - k0), (ks - k0).astype(np.int64))
        return
    rel = relative_cuts(law, rate, max_panel) if rel is None else rel
    lo, hi = rule_frame(law)[2]
    grade = np.zeros(0) if grade is None else np.asarray(grade, dtype=float)
    x, wx = _gauss_legendre(order)
    breaks = _unique(np.asarray(breaks, dtype=float))
    std_half = 0.5 * np.diff(rel)
    std_pdf = None
    if shared_pdf:
        std_pdf = law.pdf(
            np.clip((0.5 * (rel[:-1] + rel[1:]))[:, None] + std_half[:, None] * x, lo, hi)
        )
    for pch in _panels(rel, breaks, grade, T, N, step=_step(rel, breaks, grade, T, chunk)):
        k0, k1, owner = pch.k0, pch.k1, pch.owner
        ks = np.arange(k0, k1)
        half = 0.5 * (pch.b - pch.a)
        mid = 0.5 * (pch.a + pch.b)
        t = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        tau = t - np.repeat(ks[owner], order) * T
        gw = (half[:, None] * wx[None, :]).ravel()
        if std_pdf is None:
            w: FloatArray = gw * law.pdf(np.clip(tau, lo, hi))
        else:
            dens = np.empty((owner.size, order))
            std = pch.m >= 0
            dens[std] = std_pdf[pch.m[std]]
            other = ~std
            if np.any(other):
                dens[other] = law.pdf(np.clip(tau.reshape(-1, order)[other], lo, hi))
            w = np.ravel(half[:, None] * wx[None, :] * dens)
        yield NodeChunk(k0, k1, t, w, np.repeat(owner, order), gw, tau)


@dataclass(frozen=True)
class PanelChunk:
    """The panels of samples k0..k1-1: owner (k - k0), ends a < b, and the standard-panel
    number m (edges kT + rel[m], kT + rel[m + 1]; -1 for a panel a cut shortened)."""

    k0: int
    k1: int
    owner: IntArray
    a: FloatArray
    b: FloatArray
    m: IntArray


def _step(rel: FloatArray, breaks: FloatArray, grade: FloatArray, T: float, chunk: int) -> int:
    """Samples per chunk: at most ``chunk`` and about ``_CHUNK_PANELS`` panels."""
    return max(
        1, min(chunk, int(_CHUNK_PANELS // max(panels_per_sample(rel, breaks, grade, T), 1.0)))
    )


def _panels(
    rel: FloatArray, breaks: FloatArray, grade: FloatArray, T: float, N: int, step: int
) -> Iterator[PanelChunk]:
    for k0 in range(0, N, step):
        k1 = min(N, k0 + step)
        ks = np.arange(k0, k1)
        cuts, row_len, std_pos, std_m = _window_cuts(rel, breaks, grade, ks, T)
        owner = np.repeat(np.arange(k1 - k0), row_len - 1)
        # panel p of the chunk starts at cuts[p + owner[p]] (each row's last edge starts none)
        first_edge = np.arange(owner.size) + owner
        m = np.full(owner.size, -1, dtype=np.int64)
        # a standard panel's first edge at cuts[q] in row o is panel q - o
        m[std_pos - _row_of(std_pos, row_len)] = std_m
        yield PanelChunk(k0, k1, owner, cuts[first_edge], cuts[first_edge + 1], m)


def jitter_panels(
    law: JitterLaw,
    T: float,
    N: int,
    breaks: FloatArray,
    rel: FloatArray,
    *,
    grade: FloatArray | None = None,
    chunk: int = DEFAULT_CHUNK,
) -> Iterator[PanelChunk]:
    """The panels of :func:`jitter_nodes` (standard edges ``rel``), chunk by chunk."""
    del law  # the rule depends on the law through ``rel`` only
    grade = np.zeros(0) if grade is None else np.asarray(grade, dtype=float)
    breaks = _unique(np.asarray(breaks, dtype=float))
    yield from _panels(rel, breaks, grade, T, N, _step(rel, breaks, grade, T, chunk))


def _row_of(pos: IntArray, row_len: IntArray) -> IntArray:
    """The row (sample) holding each edge index ``pos`` of :func:`_window_cuts`."""
    return np.searchsorted(np.cumsum(row_len), pos, side="right")


def panels_per_sample(rel: FloatArray, breaks: FloatArray, grade: FloatArray, T: float) -> float:
    """Mean panels per sample of the rule, from the mean density of the breaks: each of the
    1 + ``grade.size`` shifted copies of the breaks puts that density times the window's width
    of cuts into a window."""
    density = (breaks.size - 1) / max(float(breaks[-1] - breaks[0]), T) if breaks.size > 1 else 0.0
    return (rel.size - 1) + density * float(rel[-1] - rel[0]) * (1 + grade.size) + 1.0
