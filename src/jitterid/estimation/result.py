"""The immutable result of :func:`jitterid.fit`."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ..jitter.laws import JitterLaw
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction

__all__ = ["FitResult", "FitStatus"]

FloatArray = NDArray[np.float64]


class FitStatus(enum.Enum):
    """How the search ended; the value is a message that says what to do."""

    CONVERGED = "converged: the optimiser's convergence test was met"
    MAX_EVALUATIONS = (
        "failed: the evaluation budget ran out before convergence; raise max_nfev or give a "
        "better start"
    )
    NOT_FINITE = (
        "failed: the criterion was not finite at the end; check the data, bounds and start"
    )
    OPTIMISER_FAILED = "failed: the optimiser reported an error (see message)"

    @property
    def success(self) -> bool:
        return self is FitStatus.CONVERGED


@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of one estimation, immutable; derived statistics are computed lazily.

    Attributes
    ----------
    method : str
        The criterion minimised (``"ls"``, ``"bcls"``, ``"wbcls"``, ``"asml"``,
        ``"asml-diag"``, ``"gaussian"``, ``"ml"``).
    names : tuple of str
        Parameter names in vector order: jitter-family parameters, system parameters,
        then ``noise_std`` if it was estimated.
    x : ndarray
        The estimate as a vector in ``names`` order.
    cost : float
        The criterion value at ``x``.
    status : FitStatus
        How the search ended; ``status.value`` says what to do on failure.
    message : str
        The optimiser's own message.
    nfev : int
        Criterion evaluations used by the search (all starts).
    system : TransferFunction
        The fitted system G_theta.
    jitter : JitterLaw
        The jitter law: the known one, or the fitted member of the family.
    noise_std : float
        The measurement-noise standard deviation used or estimated (0 if unused).
    freqs : ndarray
        The frequency set (Hz) of the frequency-domain criteria.
    success : bool
        ``status.success``: a failed search never looks like a good fit.
    params : dict
        ``{name: value}``.
    cov : ndarray
        Delta-method (sandwich) covariance of ``x``: H^{-1} G diag(w) G^T H^{-1}, with H
        the criterion's Hessian, G = d^2 V / d theta dy and w the per-sample variances
        (model-based; robust squared residuals for ``ls``, whose model ignores jitter).
        For ``ml`` the inverse observed information (-d^2 ln L / d theta^2)^{-1}.
        Parameters on a bound get NaN rows and columns.
    stderr : dict
        ``{name: sqrt(cov[i, i])}``.
    jitter_std : float
        Standard deviation of the (fitted) jitter law; for the family (26) it equals
        a / sqrt(3 (n + 1)), the paper's sigma.
    structure : ModelStructure or None
        The model structure fitted (to rebuild G from parameters, e.g. for
        :func:`jitterid.analysis.uncertainty.bode_band`); None if not recorded.
    """

    method: str
    names: tuple[str, ...]
    x: FloatArray
    cost: float
    status: FitStatus
    message: str
    nfev: int
    system: TransferFunction
    jitter: JitterLaw
    noise_std: float
    freqs: FloatArray = field(repr=False)
    _covariance: Callable[[], FloatArray] = field(repr=False)
    structure: ModelStructure | None = field(default=None, repr=False)

    @property
    def success(self) -> bool:
        return self.status.success

    @property
    def params(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.x, strict=True)}

    @cached_property
    def cov(self) -> FloatArray:
        return self._covariance()

    @property
    def stderr(self) -> dict[str, float]:
        se = np.sqrt(np.abs(np.diag(self.cov)))
        return {n: float(v) for n, v in zip(self.names, se, strict=True)}

    @property
    def jitter_std(self) -> float:
        return float(self.jitter.std)

    def conf_int(self, level: float = 0.95) -> dict[str, tuple[float, float]]:
        """Normal-approximation confidence intervals ``{name: (low, high)}``."""
        if not 0 < level < 1:
            raise ValueError(f"level must be in (0, 1); got {level}")
        z = float(stats.norm.ppf(0.5 + level / 2))
        se = self.stderr
        return {n: (v - z * se[n], v + z * se[n]) for n, v in self.params.items()}

    def summary(self) -> str:
        """A readable table of the estimate."""
        ci = self.conf_int()
        se = self.stderr
        lines = [
            f"jitterid fit, method {self.method!r}: {self.status.value}",
            f"  optimiser: {self.message} ({self.nfev} evaluations), criterion {self.cost:.6g}",
            f"  {'parameter':<10} {'estimate':>12} {'std err':>12} {'95% interval':>27}",
        ]
        for n, v in self.params.items():
            lines.append(
                f"  {n:<10} {v:>12.6g} {se[n]:>12.4g}   [{ci[n][0]:>11.5g}, {ci[n][1]:>11.5g}]"
            )
        lines.append(f"  jitter law {self.jitter}  (std {self.jitter_std:.4g})")
        lines.append(f"  system {self.system}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_scipy(self) -> Any:
        """The fitted G(s) as a ``scipy.signal.lti`` (transfer-function form; s in rad/s)."""
        from scipy import signal

        return signal.lti(self.system.num, self.system.den)

    def to_control(self) -> Any:
        """The fitted G(s) as a python-control ``TransferFunction`` (s in rad/s).

        Needs the optional extra: ``pip install 'jitterid[control]'``.
        """
        try:
            import control
        except ImportError as exc:
            raise ImportError(
                "to_control() needs python-control, an optional dependency; install it with "
                "pip install 'jitterid[control]' (or pip install control)"
            ) from exc
        return control.tf(self.system.num.tolist(), self.system.den.tolist())
