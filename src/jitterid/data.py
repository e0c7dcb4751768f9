"""The data: samples requested on the grid kT, with the known input and what is known of the
noise."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ._checks import positive, real_array, sampling_interval
from ._repr import brief
from .inputs import Input

__all__ = ["SampledData"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class SampledData:
    """Samples requested on the grid t_k = k T, k = 0..N-1, and what is known about them.

    Attributes
    ----------
    y : ndarray, shape (N,)
        The measured samples.
    T : float
        Nominal sampling interval (s).
    u : Input or None
        The known continuous-time input that drove the system; None for a signal model with
        no input (:class:`jitterid.SignalModel`).
    noise_std : float or None
        Standard deviation of the white measurement noise v_k, if known; ``None`` lets
        the estimators that need it estimate it.
    instants : ndarray or None
        The true sampling instants kT + tau_k. For diagnostics of simulated data only: no
        estimator reads it.
    resolution : float or None
        The smallest noise std the samples can have (a converter's quantisation step over
        sqrt(12)): the lower bound of an estimated noise std (default 1e-12). Where the
        jitter dominates, the exact likelihood's noise std can run to zero (the noise-free
        jittered signal explains the samples at least as well); a fit then stops at this
        floor and says so (AT_BOUND) instead of creeping towards 0.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> data = ji.SampledData(y=np.zeros(40), T=0.1, noise_std=0.01)
    >>> data.N, round(float(data.t_nominal[-1]), 6)
    (40, 3.9)
    """

    y: FloatArray
    T: float
    u: Input | None = None
    noise_std: float | None = None
    instants: FloatArray | None = field(default=None, repr=False)
    resolution: float | None = None

    def __post_init__(self) -> None:
        y = real_array(self.y, "y", ndim=1)
        if y.size < 4:
            raise ValueError(f"y must hold at least 4 samples; got {y.size}")
        T = sampling_interval(self.T, "T")
        if self.u is not None and not isinstance(self.u, Input):
            raise TypeError(f"u must be a jitterid input or None; got {type(self.u).__name__}")
        if self.noise_std is not None:
            object.__setattr__(
                self, "noise_std", positive(self.noise_std, "noise_std", allow_zero=True)
            )
        if self.resolution is not None:
            object.__setattr__(self, "resolution", positive(self.resolution, "resolution"))
        if self.instants is not None:
            inst = real_array(self.instants, "instants", ndim=1)
            if inst.size != y.size:
                raise ValueError(
                    f"instants must have one entry per sample: len(y) = {y.size}, "
                    f"len(instants) = {inst.size}"
                )
            inst.setflags(write=False)
            object.__setattr__(self, "instants", inst)
        y.setflags(write=False)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "T", T)

    def __repr__(self) -> str:
        parts = [f"y={brief(self.y)}", f"T={self.T!r}"]
        if self.u is not None:
            parts.append(f"u={self.u!r}")
        for name in ("noise_std", "resolution"):
            if getattr(self, name) is not None:
                parts.append(f"{name}={getattr(self, name)!r}")
        if self.instants is not None:
            parts.append(f"instants={brief(self.instants)}")
        return f"SampledData({', '.join(parts)})"

    @property
    def N(self) -> int:
        return int(self.y.size)

    @property
    def t_nominal(self) -> FloatArray:
        """The requested instants k T."""
        return self.T * np.arange(self.N, dtype=float)
