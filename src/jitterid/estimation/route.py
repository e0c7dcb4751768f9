"""The fit's problem protocol: what :func:`jitterid.fit`'s one driver asks of a formulation.

A formulation (a *route*) is the noise model of the fit: white noise, OE (2a) / JOE (2c)
(:class:`jitterid.estimation.oe.OutputErrorRoute`, whose problem is
:class:`~jitterid.estimation.problem.Problem`, the exact likelihood included), or coloured
noise, BJ (2b) / JBJ (2d) (:class:`jitterid.estimation.boxjenkins.BoxJenkinsRoute`, problem
:class:`~jitterid.estimation.bjcriteria.BJProblem`). The driver
(:mod:`jitterid.estimation.fit`) runs every estimator through the same sequence of a route's
hooks, never asking which estimator or route it has:

1. ``search(start)``: the starts (Section 4.5: the ordinary output-error start, a family's
   grid, the estimator's first stage) and the search, through the estimator's adapter of
   :data:`jitterid.estimation.search.SEARCHES`; returns a :class:`Staged`;
2. ``covariance(staged, cov_type)``: the estimate's covariance in the search's units;
3. ``post_context(staged, cov, cov_error)``: what the checks after the search need
   (:class:`jitterid.estimation.checks.PostContext`);
4. ``to_data_units(staged, x)``: the problem in the data's units (the search runs on y and u
   divided by powers of two, :class:`~jitterid.estimation.checks.Scaling`), where the
   criterion is re-evaluated;
5. ``result_fields(problem, x, staged)``: the fitted system, law and noise model for the
   :class:`~jitterid.estimation.result.FitResult`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from .checks import PostContext, Scaling
from .search import Outcome

__all__ = ["Route", "Staged"]

FloatArray = NDArray[np.float64]


@dataclass
class Staged:
    """What a route's search hands to the rest of the driver (in the search's units).

    Attributes
    ----------
    problem : Problem or BJProblem
        The problem whose criterion the estimate minimises (the last frozen one for WBCLS).
    outcome : Outcome
        The search's end; ``nfev`` counts every start and stage.
    noise_std : float or None
        The white-noise std the covariance uses: known, plug-in or estimated (else None).
    extra : dict
        Route-specific state the later hooks read (e.g. the first stage's points).
    """

    problem: Any
    outcome: Outcome
    noise_std: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


class Route(Protocol):
    """The hooks of a formulation (module docstring)."""

    scaling: Scaling
    freqs: FloatArray

    def search(self, start: Any) -> Staged: ...
    def covariance(self, staged: Staged, cov_type: str) -> tuple[FloatArray, str | None, str]: ...
    def post_context(
        self, staged: Staged, cov: FloatArray, cov_error: str | None
    ) -> PostContext: ...
    def to_data_units(self, staged: Staged, x: FloatArray) -> Any: ...
    def result_fields(self, problem: Any, x: FloatArray, staged: Staged) -> dict[str, Any]: ...
