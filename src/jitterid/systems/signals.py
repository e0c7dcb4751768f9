"""Signal models with no input: s(t; theta) given by a function (the paper's (1a) with a
general deterministic signal model, e.g. a sinusoid of unknown amplitude, phase, frequency
and offset).

A :class:`SignalModel` plugs into everything an LTI structure does (``fit`` with every
estimator, jitter families, ``crb``) through the model protocol of
:mod:`jitterid.systems.model`: the moments are quadratures over the jitter of the function's
values (:func:`jitterid.moments.sample.moment_pass`), its parameter gradient if given (else
the declared finite-difference route), and its time slope if given (the score of a jitter
family's scale).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .model import Bounds, Model, Signal

if TYPE_CHECKING:
    from ..data import SampledData
    from ..inputs import Input

__all__ = ["SignalModel"]

FloatArray = NDArray[np.float64]
Function = Callable[[FloatArray, FloatArray], ArrayLike]


@dataclass(frozen=True, eq=False)
class SignalModel(Model):
    """s(t; theta) = ``function(t, theta)``: a signal model with named parameters, no input.

    Parameters
    ----------
    function : callable
        ``function(t, theta)`` -> s at the instants ``t`` (a 1-D array, seconds), same shape;
        ``theta`` is the parameter vector in ``param_names`` order. Must be smooth in t (the
        quadrature over the jitter assumes it; use an LTI structure for switching inputs).
    param_names : sequence of str
        The parameter names, unique.
    starts : sequence of sequences of float
        One or more starting points (the ordinary fit that ignores the jitter starts from
        the best of them).
    rate : float or callable
        The fastest rate at which s varies, in 1/s (rad/s): 2 pi f for a sinusoid of
        frequency f Hz. A callable ``rate(theta)`` when it depends on the parameters.
        Quadrature panels over the jitter are kept shorter than about 1 / rate.
    bounds : sequence of (low, high), optional
        Closed bounds per parameter; default unbounded.
    gradient : callable, optional
        ``gradient(t, theta)`` -> ds/dtheta, shape (P, t.size). Without it the moments'
        derivatives are central differences of ``function`` (:attr:`analytic` is False).
    slope : callable, optional
        ``slope(t, theta)`` -> ds/dt. Without it a jitter family's scale parameter is
        differenced like its other parameters.
    gain_params : sequence of int, optional
        Indices of parameters in which s is linear and homogeneous (an amplitude,
        in-phase/quadrature components, an offset): they are rescaled with the data's
        units, and each start gets its least-squares value. Declare none if unsure.

    Notes
    -----
    A FitResult keeps its model: to pickle it (or to run it on Dask workers) give module-level
    functions, not lambdas; the JSON form refuses functions with a clear error.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> sine = ji.SignalModel(
    ...     lambda t, th: th[0] * np.sin(2 * np.pi * 0.14 * t + th[1]),
    ...     param_names=("amplitude", "phase"), starts=[(1.0, 0.0)], rate=2 * np.pi * 0.14,
    ... )
    >>> sine.signal([2.0, 0.5])(np.array([0.0]))
    array([0.95885108])
    """

    function: Function
    param_names: tuple[str, ...]
    starts: Sequence[Sequence[float]]
    rate: float | Callable[[FloatArray], float]
    bounds: Bounds = ()
    gradient: Function | None = None
    slope: Function | None = None
    gain_params: tuple[int, ...] = ()

    uses_input = False

    def __post_init__(self) -> None:
        if not callable(self.function):
            raise TypeError(f"function must be callable f(t, theta); got {self.function!r}")
        names = tuple(self.param_names) if not isinstance(self.param_names, str) else ()
        if not names or not all(isinstance(n, str) and n for n in names):
            raise ValueError(
                "param_names must be a non-empty sequence of names, e.g. ('amplitude', 'phase')"
            )
        if len(set(names)) != len(names):
            raise ValueError(f"param_names must be unique; got {names}")
        P = len(names)
        if self.bounds:
            bnd = np.asarray(self.bounds, dtype=float)
            if bnd.shape != (P, 2) or np.any(np.isnan(bnd)) or np.any(bnd[:, 0] >= bnd[:, 1]):
                raise ValueError(
                    f"bounds must hold one (low, high) pair with low < high per parameter "
                    f"{names}; got {self.bounds!r}"
                )
            bounds = tuple((float(a), float(b)) for a, b in bnd)
        else:
            bounds = tuple((-np.inf, np.inf) for _ in names)
        starts = [np.asarray(s, dtype=float) for s in self.starts]
        if not starts or any(s.shape != (P,) or not np.all(np.isfinite(s)) for s in starts):
            raise ValueError(
                f"starts must hold one or more finite starting points of {P} values {names}"
            )
        if not callable(self.rate):
            rate = float(self.rate)
            if not (np.isfinite(rate) and rate > 0):
                raise ValueError(
                    f"rate must be > 0 (1/s: 2 pi f for a sinusoid of f Hz); got {self.rate!r}"
                )
        gains = tuple(int(i) for i in self.gain_params)
        if any(not 0 <= i < P for i in gains):
            raise ValueError(f"gain_params must be indices into {names}; got {self.gain_params}")
        for name, fun in (("gradient", self.gradient), ("slope", self.slope)):
            if fun is not None and not callable(fun):
                raise ValueError(f"{name} must be callable f(t, theta) or None; got {fun!r}")
        object.__setattr__(self, "param_names", names)
        object.__setattr__(self, "bounds", bounds)
        object.__setattr__(self, "starts", tuple(tuple(s.tolist()) for s in starts))
        object.__setattr__(self, "gain_params", gains)

    @property
    def analytic(self) -> bool:
        return self.gradient is not None

    def signal(self, params: ArrayLike, u: Input | None = None) -> FunctionSignal:
        """s(t; params); ``u`` is ignored (the model has no input).

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        u : Input, optional
            Unused: a signal model has no input.
        """
        return FunctionSignal(self, self._check(params))

    def initial_points(self, data: SampledData) -> list[FloatArray]:
        return [np.asarray(s, dtype=float) for s in self.starts]


class FunctionSignal(Signal):
    """The :class:`~jitterid.systems.model.Signal` of a :class:`SignalModel` at ``theta``."""

    def __init__(self, model: SignalModel, theta: FloatArray) -> None:
        self.model, self.theta = model, theta
        rate = model.rate(theta) if callable(model.rate) else model.rate
        rate = float(rate)
        if not (np.isfinite(rate) and rate > 0):
            raise ValueError(f"rate(theta) must be > 0 (1/s); got {rate!r} at theta = {theta}")
        self.rate = rate
        self.breaks = np.zeros(0)
        self.start, self.end = -np.inf, np.inf

    def _values(
        self, fun: Function, t: FloatArray, shape: tuple[int, ...], what: str
    ) -> FloatArray:
        out = np.asarray(fun(t, self.theta), dtype=float)
        if out.shape != shape:
            raise ValueError(
                f"the signal model's {what} returned shape {out.shape}; expected {shape}"
            )
        if not np.all(np.isfinite(out)):
            raise ValueError(f"the signal model's {what} is not finite at theta = {self.theta}")
        return out

    def __call__(self, t: ArrayLike) -> FloatArray:
        tt = np.asarray(t, dtype=float)
        flat = self._values(self.model.function, tt.ravel(), (tt.size,), "function")
        return flat.reshape(tt.shape)

    @property
    def has_gradient(self) -> bool:
        return self.model.gradient is not None

    @property
    def has_slope(self) -> bool:
        return self.model.slope is not None

    def gradient(self, t: FloatArray) -> FloatArray | None:
        if self.model.gradient is None:
            return None
        return self._values(self.model.gradient, t, (self.theta.size, t.size), "gradient")

    def slope(self, t: FloatArray) -> FloatArray | None:
        if self.model.slope is None:
            return None
        return self._values(self.model.slope, t, (t.size,), "slope")
