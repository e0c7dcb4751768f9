"""Where a jitter law's hard edges are resolved by few samples: the stated error is too small.

A law whose density jumps at the ends of its support (the uniform) gives a likelihood whose
information about those ends comes from the samples whose phase lies within the noise's
blur of an edge. Where that blur, sigma / (A w) in time, is not large against the spacing
of the jitter values over the support, W / N (W its width), the likelihood is not close to
quadratic on the scale of its own standard error, and the inverse observed information
understates the estimate's spread. Measured (issue 26; uniform law, structured ML fits,
``edge_ratio`` below):

======  =========  ==========  =====  =====================  ===================
 N      sigma / A  2 pi f sig  ratio  spread / stated error  95 % coverage
======  =========  ==========  =====  =====================  ===================
 1000   1e-3       1 rad       0.3    about 7                0.25 (the meter, 8)
 1000   1.4e-3     0.3 rad     1.4    1.24                   0.83 (48)
 1000   1.4e-2     1 rad       4.1    1.47                   0.86 (64)
 2500   1.4e-2     1 rad       10     1.06                   0.875 (48)
 4000   1.4e-2     1 rad       17     0.85                   1.00 (48)
 1000   7.1e-2     1 rad       21     1.07                   0.96 (48)
======  =========  ==========  =====  =====================  ===================

(the first row: amplitude 1, noise 1e-3; "spread / stated error" the standard deviation of
the estimates over the median stated error; scripts in the closing note of issue 26.)

Neither a likelihood-ratio interval (0.89 where Wald gave 0.86, its statistic 1.28 on
average against chi-square(1)'s 1) nor a parametric bootstrap's standard deviation (40
records from the estimate: on average the information's error again, 0.7-1.3 x it) cures
it: the estimates' distribution has a heavy lower tail (at N = 1000, sigma / A = 1.4e-2:
the quartiles' spread is the information's, 0.58 % against 0.53 %, but 4 of 64 estimates
lie 1.6-3.2 % low), and at sigma / A = 1e-3 the spread (~0.7 %) no longer shrinks with the
noise while the information's error does. The meter says so (:func:`sharp_edge_finding`)
instead of stating an interval it cannot stand behind as if it were regular.
"""

from __future__ import annotations

import math

from ..estimation.result import FitResult
from .adequacy import Finding

__all__ = ["EDGE_RATIO", "edge_ratio", "sharp_edge_finding"]

#: Below this ratio of the noise's blur of a hard edge to the spacing of the jitter values
#: over the support (:func:`edge_ratio`) the meter says that the jitter std's interval
#: understates its spread (:func:`sharp_edge_finding`): measured, the estimates spread
#: 1.2-7 x the information's error at ratios 0.3-4 and covered 0.875 at 10,
#: 0.85-1.07 x at 17-21 (module doc).
EDGE_RATIO = 15.0


def _hard_edges(fit: FitResult) -> tuple[float, float] | None:
    """The fitted law's support (lo, hi) where its density jumps there
    (:attr:`jitterid.JitterLaw.hard_edges`), else None."""
    law = fit.jitter_law
    if law is None or not law.hard_edges:
        return None
    lo, hi = (float(v) for v in law.support)
    return lo, hi


def edge_ratio(fit: FitResult, N: int) -> float:
    """The noise's blur of the fitted law's hard edges in time, sigma / (A 2 pi f), over
    the spacing of N jitter values across its support, W / N; ``inf`` for a law without
    hard edges (a Gaussian, a dual Dirac with random jitter) or a fit without a tone.

    Parameters
    ----------
    fit : FitResult
        A structured sine likelihood fit (:func:`jitterid.metrology.sinelik.fit_sine_ml`):
        its parameters hold ``amplitude``, ``frequency_hz`` and ``noise_std``.
    N : int
        The record's length.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> from jitterid.metrology.sinelik import fit_sine_ml
    >>> from jitterid.systems.tones import SineWave
    >>> rng = np.random.default_rng(1)
    >>> T, f, N = 1.0, 0.1234, 400
    >>> tau = ji.Uniform(2.0).sample(N, rng)
    >>> y = np.sin(2 * np.pi * f * (np.arange(N) * T + tau)) + 1e-3 * rng.standard_normal(N)
    >>> res = fit_sine_ml(y, T, SineWave(band_hz=(0.12, 0.13)), ji.UniformFamily(),
    ...                   [2.0, 1.0, 0.0, f, 0.0, 1e-3])
    >>> bool(edge_ratio(res, N) < 1)  # edges far sharper than the samples' spacing
    True
    """
    edges = _hard_edges(fit)
    if edges is None:
        return math.inf
    p = fit.params
    w = 2 * math.pi * abs(float(p["frequency_hz"])) * abs(float(p["amplitude"]))
    if not w > 0:
        return math.inf
    blur = float(p["noise_std"]) / w
    return blur / ((edges[1] - edges[0]) / N)


def sharp_edge_finding(fit: FitResult, N: int) -> Finding | None:
    """A finding (kind ``"sharp-edges"``) where the fitted law's hard edges are sharper than
    an N-sample record resolves (:func:`edge_ratio` below :data:`EDGE_RATIO`): the jitter
    std's stated error understates its spread there (module doc); None otherwise.

    Parameters
    ----------
    fit : FitResult
        The meter's chosen structured sine likelihood fit.
    N : int
        The record's length.
    """
    ratio = edge_ratio(fit, N)
    if not ratio < EDGE_RATIO:
        return None
    more = EDGE_RATIO / max(ratio, 1e-300)
    return Finding(
        "sharp-edges",
        math.nan,
        f"the fitted {fit.jitter_law!r} has hard edges sharper than the record resolves (the "
        f"noise blurs them over {ratio:.2g} x the spacing of the jitter values, below "
        f"{EDGE_RATIO:g}): there the likelihood is not regular and the stated standard error "
        "understates the estimate's spread (measured 1.2-7 x; 95 % intervals covering "
        "0.25-0.88), so read the interval as too narrow; a record about "
        f"{more:.2g} x longer (or noisier) would be regular",
    )
