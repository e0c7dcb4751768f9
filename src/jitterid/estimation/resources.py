"""Up-front memory and time estimates of a fit, refused above the memory budget (issue 15 B).

A fit that would need more memory than :func:`jitterid._checks.memory_budget` (half the free
memory; ``JITTERID_MEMORY_BUDGET`` in bytes overrides it) is refused with a
:class:`~jitterid._checks.TooLargeError` (a ValueError) that gives the figure, a rough time
and the fix, before the work starts, instead of running for minutes and then failing with a
MemoryError (or being killed by the system).

Two estimates, each where its cost is known:

* :func:`check_fit` (called at the start of :func:`jitterid.fit`): the moment criteria
  (ls, bcls, wbcls, asml, asml-diag, gaussian; also the first stage of ml) keep O(1) arrays
  of N values per parameter (moments, their derivatives, residuals, Jacobian columns), so
  their memory is ``MOMENT_BYTES * N * (P + 1)``. For ``method="ml"`` it adds a lower
  bound of the likelihood's rule (the fewer of :func:`likelihood_nodes` with the input's
  switches and the jitter law's own panels only, and the windowed rule's least, 3 nodes per
  sample), so a hopeless ML fit is refused before the first stage runs.
* :func:`check_likelihood` (called by :class:`jitterid.estimation.likelihood.ExactLikelihood`
  once its rule is designed, before the nodes are built): the exact likelihood keeps its
  nodes between evaluations up to :func:`kept_nodes` (``LIKELIHOOD_BYTES`` per node, more
  for a jitter family, whose rules at several jitter values are cached, and at most
  ``KEPT_FRACTION`` of the budget) and streams a larger rule chunk by chunk
  (``STREAM_BYTES`` per node of a chunk); the node count is known from the full rule's
  cuts (:func:`jitterid.moments.quadrature.panels_per_sample`) or the windowed rule's
  pieces (``PIECE_BYTES`` each), :func:`likelihood_bytes`; it returns the full rule's
  samples per chunk (:func:`chunk_samples`: at most ``CHUNK_NODES`` nodes each).

The constants are measured (peak resident memory over the fit, minus that before it;
``benchmarks``-style runs on a 2-core machine, November 2026) and rounded up:

==========================  ======  ==================  ============================
setting                      N      measured             per unit
==========================  ======  ==================  ============================
paper, bcls, P = 3           1e6     +858 MB, 16 s        215 B, 4 us per sample-param
lab, bcls, P = 5             1e6     +1216 MB, 44 s       203 B, 7 us per sample-param
lab, ml, known law           1.6e4   +750 MB, 5.6e6 nodes 133 B per node
lab, ml, known law + oim     4e3     +387 MB, 1.4e6 nodes 270 B, 7.6 us per node
lab, ml, GaussianFamily      8e3     +1712 MB, 2.8e6      610 B, 4.5 us per node
==========================  ======  ==================  ============================

(paper: Table 2's system, telegraph input, U(-0.5, 0.5), T = 1; lab: issue 15's third-order
system with a zero, ZOH input, Gaussian jitter 0.08 s, T = 0.5.) The times are only
indicative (they vary with the load and the number of search steps); nothing is refused
on time.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .._checks import TooLargeError, memory_budget
from ..data import SampledData
from ..inputs import PiecewiseConstant
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.quadrature import panels_per_sample, relative_cuts
from ..params import count_params
from ..systems.model import Model, Signal

__all__: list[str] = []

#: bytes per sample and parameter (+1) of the moment criteria (measured 203-215, above)
MOMENT_BYTES = 250.0
#: seconds per sample and parameter (+1) of a moment fit with its covariance (4-7 us)
MOMENT_SECONDS = 6e-6
#: bytes per quadrature node of the exact likelihood, known law (133-270 measured)
LIKELIHOOD_BYTES = 200.0
#: ... and for a jitter family, whose rules at several jitter values are cached (610-740)
LIKELIHOOD_FAMILY_BYTES = 800.0
#: seconds per node of an ml fit with its covariance (4.5-7.6 us measured)
LIKELIHOOD_SECONDS = 8e-6
#: bytes per node of one chunk of a streamed evaluation (its temporaries; ~530 measured with
#: tracemalloc on Table 2's setting, scores and information)
STREAM_BYTES = 600.0
#: most nodes in one chunk of the full rule (its temporaries: ~150 MB at STREAM_BYTES)
CHUNK_NODES = 262_144
#: bytes per piece of the windowed rule (ends, owner, design value, span and the Gaussian
#: factor's bounds: 40)
PIECE_BYTES = 40.0
#: at most this fraction of the memory budget holds a rule's nodes between evaluations
KEPT_FRACTION = 0.25
#: Gauss-Legendre nodes per panel of the likelihood's rule (likelihood.DEFAULT_ORDER)
_ORDER = 8


#: Fastest mode a *searched* LTI model may have, as |p| T: such a mode settles (or turns)
#: ten thousand times within one sampling interval, so the samples see only its static
#: part, while the quadrature's panels multiply with |p| T (seconds per evaluation at
#: |p| T ~ 1e5 for a complex pair; an over-order fit drifting there ran 10 minutes). The
#: search treats such a point as a refused step; the order selection flags |p| T above
#: ``analysis.selection.FAST_POLE`` = 1e3 as over-order well before this.
SEARCH_RATE_LIMIT = 1e4


def check_mode_rate(sig: Signal, T: float) -> None:
    """Refuse (ValueError) an LTI response whose fastest pole has |p| T above
    :data:`SEARCH_RATE_LIMIT` (called for searched models only)."""
    system = getattr(sig, "system", None)
    poles = getattr(system, "poles", None)
    if poles is None or not np.size(poles):
        return
    fastest = float(np.max(np.abs(poles))) * T
    if fastest > SEARCH_RATE_LIMIT:
        raise ValueError(
            f"the model has a mode at |p| T = {fastest:.3g}, beyond {SEARCH_RATE_LIMIT:g}: "
            "it settles within a tiny fraction of a sampling interval, so the samples cannot "
            "see it (an over-order model?); the search does not go there"
        )


def _gb(b: float) -> str:
    return f"{b / 1e9:.3g} GB"


def _duration(s: float) -> str:
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def _refuse(what: str, need: float, seconds: float, fix: str) -> None:
    budget = memory_budget()
    if need <= budget:
        return
    source = (
        "set by JITTERID_MEMORY_BUDGET"
        if os.environ.get("JITTERID_MEMORY_BUDGET")
        else "half the free memory; set JITTERID_MEMORY_BUDGET in bytes to change it"
    )
    raise TooLargeError(
        f"{what} needs about {_gb(need)} of memory (and roughly {_duration(seconds)}), more "
        f"than the memory budget of {_gb(budget)} ({source}); {fix}"
    )


def moment_bytes(N: int, n_params: int) -> float:
    """Estimated peak memory (bytes) of a moment-criterion fit with its covariance."""
    return MOMENT_BYTES * float(N) * (n_params + 1)


def likelihood_nodes(
    law: JitterLaw, T: float, N: int, breaks: np.ndarray, rate: float, order: int = _ORDER
) -> float:
    """Quadrature nodes of the exact likelihood's rule for ``N`` samples: ``order`` per
    panel, the law's own panels plus one per break (input switch, slope cut) in a sample's
    window (:func:`jitterid.moments.quadrature.panels_per_sample`)."""
    lo, hi = law.support
    if not hi > lo:
        return float(N)
    rel = relative_cuts(law, rate)
    b = np.unique(np.asarray(breaks, float))
    return float(order) * float(N) * panels_per_sample(rel, b, np.zeros(0), T)


def _widest_law(jitter: JitterLaw | JitterFamily, T: float) -> JitterLaw | None:
    """The law itself, or the narrowest of a family's default starts (a lower bound of the
    rule's size: a wider law's window holds more of the breaks)."""
    if isinstance(jitter, JitterLaw):
        return jitter
    laws = []
    for start in jitter.default_starts(T):
        try:
            laws.append(jitter.law(list(start)))
        except ValueError:
            continue
    return min(laws, key=lambda law: float(np.ptp(law.support)), default=None)


def _ml_fix() -> str:
    return (
        "use fewer samples (a part of the record), a moment criterion whose memory grows "
        "only with N (method 'gaussian' or 'asml-diag'; 'bcls' is the cheapest), or raise "
        "JITTERID_MEMORY_BUDGET if the machine has the memory"
    )


def check_fit(
    data: SampledData,
    structure: Model,
    jitter: JitterLaw | JitterFamily,
    estimator: Any,
) -> None:
    """Refuse, before any work, a fit whose estimated memory exceeds the budget
    (``estimator``: the :class:`~jitterid.estimation.estimators.Estimator`; the exact
    likelihood's quadrature rule counts where it has one)."""
    method = estimator.name
    n_jit = count_params(jitter)
    P = n_jit + len(structure.param_names)
    N = data.N
    need = moment_bytes(N, P)
    seconds = MOMENT_SECONDS * N * (P + 1)
    what = f"fit(method={method!r}) of N = {N} samples with {P} parameters"
    fix = (
        "use fewer samples (fit a part of the record, or decimate it), fewer parameters "
        "(a known jitter law, a lower model order), or raise JITTERID_MEMORY_BUDGET if the "
        "machine has the memory"
    )
    if estimator.exact_likelihood:
        law = _widest_law(jitter, data.T)
        if law is not None and isinstance(data.u, PiecewiseConstant):
            # the full rule's panels without the slope cuts, or the windowed rule's least
            # (one piece of 3 nodes per sample), whichever is fewer
            nodes = min(likelihood_nodes(law, data.T, N, data.u.times, 0.0), 3.0 * N)
            need += likelihood_bytes(nodes, N, bool(n_jit))
            seconds += LIKELIHOOD_SECONDS * nodes
            what += f" (at least {nodes:.3g} quadrature nodes for the exact likelihood)"
            fix = _ml_fix()
    _refuse(what, need, seconds, fix)


def kept_nodes(node_budget: int, family: bool) -> int:
    """The most quadrature nodes a likelihood keeps between evaluations: its
    ``node_budget``, and no more than ``KEPT_FRACTION`` of the memory budget holds; a rule
    with more is streamed (made again chunk by chunk at each evaluation)."""
    per = LIKELIHOOD_FAMILY_BYTES if family else LIKELIHOOD_BYTES
    return int(min(node_budget, KEPT_FRACTION * memory_budget() / per))


def chunk_samples(nodes: float, N: int, chunk: int = 1024) -> int:
    """Samples per chunk of the full rule: ``chunk``, or fewer so that a chunk holds at most
    ``CHUNK_NODES`` nodes (at least one sample)."""
    per_sample = nodes / max(N, 1)
    return int(max(1, min(chunk, CHUNK_NODES // max(per_sample, 1.0))))


def likelihood_bytes(nodes: float, N: int, family: bool, pieces: float = 0.0) -> float:
    """Memory of the exact likelihood with ``nodes`` quadrature nodes over N samples: the
    nodes kept (at most :func:`kept_nodes` of them), one streamed chunk's temporaries
    (:func:`chunk_samples`), the windowed rule's ``pieces``, and the per-sample outputs
    (ln p, scores)."""
    per = LIKELIHOOD_FAMILY_BYTES if family else LIKELIHOOD_BYTES
    kept = min(nodes, KEPT_FRACTION * memory_budget() / per)
    chunk_nodes = min(nodes, chunk_samples(nodes, N) * max(nodes / max(N, 1), 1.0))
    return per * kept + STREAM_BYTES * chunk_nodes + PIECE_BYTES * pieces + 64.0 * N


def check_likelihood(
    lik: object, law: JitterLaw, resp: Signal, nodes: float | None = None, pieces: float = 0.0
) -> int:
    """Refuse a designed likelihood rule (``lik``, an
    :class:`~jitterid.estimation.likelihood.ExactLikelihood`, for the signal ``resp``) whose
    memory (:func:`likelihood_bytes`) would exceed the budget: the full rule from its slope
    cuts, or the windowed rule from its ``nodes`` and ``pieces``. Returns the samples per
    chunk of the full rule (:func:`chunk_samples`)."""
    N, T = lik.N, lik.T  # type: ignore[attr-defined]
    if nodes is None:
        cuts = lik._cuts  # type: ignore[attr-defined]
        breaks = np.r_[resp.breaks, np.zeros(0) if cuts is None else cuts]
        nodes = likelihood_nodes(law, T, N, breaks, resp.rate, lik.order)  # type: ignore[attr-defined]
        pieces = 0.125 * float(np.size(breaks))  # the cuts (8 bytes each)
    family = isinstance(lik.jitter, JitterFamily)  # type: ignore[attr-defined]
    _refuse(
        f"the exact likelihood of N = {N} samples ({nodes:.3g} quadrature nodes, "
        f"{nodes / max(N, 1):.0f} per sample)",
        likelihood_bytes(nodes, N, family, pieces),
        LIKELIHOOD_SECONDS * nodes,
        _ml_fix(),
    )
    return chunk_samples(nodes, N)
