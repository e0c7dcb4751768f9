"""How a fit ended: :class:`FitStatus`, shared by the searches, the checks and the result."""

from __future__ import annotations

import enum

__all__ = ["FitStatus"]


class FitStatus(enum.Enum):
    """How the search ended; the value is a message that says what to do.

    Examples
    --------
    >>> import jitterid as ji
    >>> ji.FitStatus.CONVERGED.name
    'CONVERGED'
    >>> ji.FitStatus.MAX_EVALUATIONS.value.split(":")[0]
    'failed'
    """

    CONVERGED = "converged: the optimiser's convergence test was met"
    MAX_EVALUATIONS = (
        "failed: the evaluation budget ran out before convergence; raise max_nfev or give a "
        "better start"
    )
    NOT_FINITE = "failed: the criterion was not finite at the end; check the data, bounds and start"
    OPTIMISER_FAILED = "failed: the optimiser reported an error (see message)"
    # Checks after a converged search (jitterid.estimation.checks): the search met its test,
    # but the answer cannot be trusted. The message says which parameter and the numbers.
    AT_BOUND = (
        "failed: a parameter ended on or next to its bound, or the jitter scale collapsed "
        "while the data show jitter (see message); try another start, structure or jitter law"
    )
    UNIDENTIFIABLE = (
        "failed: the information matrix is (nearly) singular, so some parameters are not "
        "identified (see message); fix some parameters, use fewer, or a richer input"
    )
    UNSTABLE_MODEL = (
        "failed: the fitted model is unstable or improper (see message); use a lower model "
        "order or another start"
    )
    LOCAL_OPTIMUM = (
        "failed: the search stopped at a local optimum (another start reaches a lower "
        "criterion, see message); fit without start or from a better start"
    )
    NOT_SIGNIFICANT = (
        "failed: the fitted model explains no significant part of the output (see message); "
        "check that u drove y, or use a stronger or longer excitation"
    )
    LACK_OF_FIT = (
        "failed: the residuals are far larger than the model (jitter and the known noise) "
        "allows (see message); try other starts, another structure, or check noise_std"
    )
    OVER_ORDER = (
        "failed: the model has more poles or zeros than the data support (a pole and a zero "
        "that cancel, or one not told from infinity; see message); use a lower order, or "
        "compare orders with select_order"
    )

    IRREGULAR = (
        "failed: the likelihood is not regular at the estimate (its curvature far exceeds the "
        "spread of its per-sample scores, see message), so the inverse-information standard "
        "errors understate the estimate's spread; fit with a moment criterion (bcls, asml) "
        "or a jitter law without hard edges"
    )

    @property
    def success(self) -> bool:
        return self is FitStatus.CONVERGED
