"""User control of the search over an LTI structure: start values, bounds and fixed
parameters (issue 16).

:class:`Constrained` wraps a :class:`~jitterid.systems.structures.ModelStructure` and is one
itself, so :func:`jitterid.fit`, the estimators, the covariance, the Bode band and the JSON
codec take it as they take any structure:

- its parameters are the free ones of the inner structure (the fixed ones removed), in the
  inner order; :meth:`Constrained.system` puts the fixed values back;
- its bounds are the inner bounds intersected with the user's, so an estimate on a user
  bound is reported ``AT_BOUND`` by the checks after the search
  (:mod:`jitterid.estimation.checks`);
- its derivative d(num, den)/dtheta is the inner closed form's rows of the free parameters
  (the modal fast path of :mod:`jitterid.moments.modal` keeps its analytic route);
- its starts are the inner default starts with the user's values put in: the first is the
  user's start completed from the first default start, all inside the bounds.

Fixing every parameter is allowed: the structure is then a known system (a fit estimates the
jitter law and the noise only).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..params import did_you_mean
from .model import Bounds
from .structures import ModelStructure, closed_form_applies
from .tf import TransferFunction

__all__ = ["Constrained"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Constrained(ModelStructure):
    """A structure with some parameters fixed, bounded or given a start.

    Parameters
    ----------
    structure : ModelStructure
        The structure to constrain (``PolePairGain()``, ``RationalModel(m, n)``, or another
        ``Constrained``).
    start : dict, optional
        ``{name: value}``: where the search over the system starts. Names not given are taken
        from each of the structure's default starts (``structure.starts(T)``), so the first
        start is the user's completed from the first default one. A value must lie inside
        its bounds. With no start for a gain parameter (the numerator), each start's gain is
        fitted by least squares, as for the default starts.
    bounds : dict, optional
        ``{name: (low, high)}``, either end ``None`` (or infinite) for no bound: intersected
        with the structure's own bounds. An estimate on one is reported ``AT_BOUND``.
    fixed : dict, optional
        ``{name: value}``: parameters held at a value (inside the structure's bounds); they
        are not estimated and take no start or bounds.

    Attributes
    ----------
    structure, start, fixed :
        As given (values as floats, in the structure's parameter order).
    user_bounds : dict
        The ``bounds`` argument as ``{name: (low, high)}`` (``bounds`` is the model's: the
        intersection, one pair per free parameter).

    Raises
    ------
    ValueError
        Naming the argument: an unknown parameter name (with the closest name), a value
        that is not a finite number, a bound pair with low >= high or outside the
        structure's bounds, a start outside its bounds, a fixed value outside the
        structure's bounds, a fixed parameter also given a start or bounds.

    Examples
    --------
    >>> import jitterid as ji
    >>> c = ji.Constrained(ji.PolePairGain(), fixed={"k0": 6.25}, bounds={"pr": (-3, -1)})
    >>> c.param_names
    ('pr', 'pi')
    >>> c.bounds
    ((-3.0, -1.0), (0.001, inf))
    >>> c.system([-1.5, 2.0])
    TransferFunction(num=[6.25], den=[1.0, 3.0, 6.25])
    """

    structure: ModelStructure
    start: dict[str, float]
    user_bounds: dict[str, tuple[float, float]] = field(metadata={"init": "bounds"})
    fixed: dict[str, float]

    def __init__(
        self,
        structure: ModelStructure,
        *,
        start: Mapping[str, float] | None = None,
        bounds: Mapping[str, Any] | None = None,
        fixed: Mapping[str, float] | None = None,
    ) -> None:
        if not isinstance(structure, ModelStructure):
            raise TypeError(
                "structure must be an LTI model structure (PolePairGain(), RationalModel(m, "
                f"n), ...); got {type(structure).__name__}"
            )
        names = tuple(structure.param_names)
        inner = tuple((float(lo), float(hi)) for lo, hi in structure.bounds)
        what = f"the parameters of {type(structure).__name__} are {names}"
        fix = _by_name(fixed, "fixed", names, what)
        user = _by_name(bounds, "bounds", names, what)
        first = _by_name(start, "start", names, what)
        for arg, given in (("start", first), ("bounds", user)):
            both = [n for n in given if n in fix]
            if both:
                raise ValueError(
                    f"{arg}: {both} {'is' if len(both) == 1 else 'are'} fixed, so "
                    f"{'it takes' if len(both) == 1 else 'they take'} no {arg}; drop "
                    f"{'it' if len(both) == 1 else 'them'} from {arg} or from fixed"
                )
        fixed_v = {n: _finite(v, f"fixed[{n!r}]") for n, v in fix.items()}
        for n, v in fixed_v.items():
            lo, hi = inner[names.index(n)]
            if not lo <= v <= hi:
                raise ValueError(
                    f"fixed[{n!r}] = {v:g} is outside the bounds [{lo:g}, {hi:g}] of "
                    f"{type(structure).__name__}; fix it at a value inside them"
                )
        user_v = {n: _pair(v, n) for n, v in user.items()}
        eff = []
        for n, (lo, hi) in zip(names, inner, strict=True):
            if n in fixed_v:
                continue
            ulo, uhi = user_v.get(n, (-math.inf, math.inf))
            a, b = max(lo, ulo), min(hi, uhi)
            if not a < b:
                raise ValueError(
                    f"bounds[{n!r}] = ({ulo:g}, {uhi:g}) leaves nothing of the bounds "
                    f"[{lo:g}, {hi:g}] of {type(structure).__name__}: give a range that "
                    f"overlaps them, or fix {n} instead"
                )
            eff.append((a, b))
        free = tuple(n for n in names if n not in fixed_v)
        start_v = {n: _finite(v, f"start[{n!r}]") for n, v in first.items()}
        for n, v in start_v.items():
            a, b = eff[free.index(n)]
            if not a <= v <= b:
                raise ValueError(
                    f"start[{n!r}] = {v:g} is outside its bounds [{a:g}, {b:g}]; give a start "
                    "inside them (or widen bounds)"
                )
        order = {n: i for i, n in enumerate(names)}
        object.__setattr__(self, "structure", structure)
        object.__setattr__(
            self, "start", dict(sorted(start_v.items(), key=lambda kv: order[kv[0]]))
        )
        object.__setattr__(
            self, "user_bounds", dict(sorted(user_v.items(), key=lambda kv: order[kv[0]]))
        )
        object.__setattr__(
            self, "fixed", dict(sorted(fixed_v.items(), key=lambda kv: order[kv[0]]))
        )
        # the maps, once: inner positions of the free and fixed parameters, fixed values
        object.__setattr__(self, "_names", free)
        object.__setattr__(self, "_bounds", tuple(eff))
        object.__setattr__(self, "_free", np.array([order[n] for n in free], dtype=int))
        object.__setattr__(self, "_fix_at", np.array([order[n] for n in self.fixed], dtype=int))
        object.__setattr__(self, "_fix_v", np.array(list(self.fixed.values()), dtype=float))

    def __hash__(self) -> int:
        return hash(
            (
                self.structure,
                *(tuple(d.items()) for d in (self.start, self.user_bounds, self.fixed)),
            )
        )

    def __repr__(self) -> str:
        parts = [repr(self.structure)]
        for name, d in (("fixed", self.fixed), ("bounds", self.user_bounds), ("start", self.start)):
            if d:
                parts.append(f"{name}={d!r}")
        return f"Constrained({', '.join(parts)})"

    # ------------------------------------------------------------------ the model
    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        names: tuple[str, ...] = self._names  # type: ignore[attr-defined]
        return names

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        bounds: Bounds = self._bounds  # type: ignore[attr-defined]
        return bounds

    @property
    def gain_params(self) -> tuple[int, ...]:
        """The inner gain parameters, at their free positions; none when one of them is
        fixed, bounded or given a start: the output is then no longer scaled by them as a
        group, and the data's scaling and each start's least-squares gain
        (:func:`jitterid.fit`) would move a value the user set."""
        names = self.structure.param_names
        gains = [names[i] for i in self.structure.gain_params]
        touched = any(
            n in self.fixed
            or n in self.start
            or any(map(math.isfinite, self.user_bounds.get(n, ())))
            for n in gains
        )
        if touched:
            return ()
        return tuple(self.param_names.index(n) for n in gains)

    @property
    def delay_index(self) -> int | None:
        """The inner structure's delay (:class:`jitterid.Delayed`) at its free position; None
        when it has none or it is fixed (a fixed delay still moves the jitter law, but is
        not differentiated)."""
        i = self.structure.delay_index
        if i is None:
            return None
        name = self.structure.param_names[i]
        return self.param_names.index(name) if name in self.param_names else None

    def full(self, params: ArrayLike) -> FloatArray:
        """The inner structure's parameter vector: ``params`` (the free ones, a vector in
        :attr:`param_names` order or a dict by name) with the fixed values put in.

        Parameters
        ----------
        params : array_like or dict
            The free parameters: a vector in :attr:`param_names` order or a dict by name.
        """
        x = self._check(params)
        out = np.empty(len(self.structure.param_names))
        out[self._free] = x  # type: ignore[attr-defined]
        out[self._fix_at] = self._fix_v  # type: ignore[attr-defined]
        return out

    def system(self, params: ArrayLike = ()) -> TransferFunction:
        return self.structure.system(self.full(params))

    def coefficient_jacobian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        """The inner closed form's rows of the free parameters (None where the inner
        structure declares none: the moments then difference :meth:`system`).

        Parameters
        ----------
        params : array_like
            The free parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).
        """
        out = self._inner_closed_form("coefficient_jacobian", params, n)
        if out is None:
            return None
        free = self._free  # type: ignore[attr-defined]
        return np.asarray(out[0])[free], np.asarray(out[1])[free]

    def coefficient_hessian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        """The inner closed form's rows and columns of the free parameters (None where the
        inner structure declares none).

        Parameters
        ----------
        params : array_like
            The free parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).

        Examples
        --------
        >>> import jitterid as ji
        >>> c = ji.Constrained(ji.PolePairGain(), fixed={"k0": 6.25})
        >>> c.coefficient_hessian([-1.5, 2.0], 3)[1][:, :, 2].tolist()
        [[2.0, 0.0], [0.0, 2.0]]
        """
        out = self._inner_closed_form("coefficient_hessian", params, n)
        if out is None:
            return None
        keep = np.ix_(self._free, self._free)  # type: ignore[attr-defined]
        return np.asarray(out[0])[keep], np.asarray(out[1])[keep]

    def _inner_closed_form(
        self, method: str, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        """The inner structure's closed form ``method`` at the full parameter vector, or None
        where it declares none or it does not belong to its map (``closed_form_applies``)."""
        inner = self.structure
        if not closed_form_applies(inner, method):
            return None
        out: tuple[FloatArray, FloatArray] | None = getattr(inner, method)(self.full(params), n)
        return out

    def starts(self, T: float) -> list[FloatArray]:
        """The inner default starts with the user's values put in, fixed parameters removed,
        clipped into :attr:`bounds` and without repeats; the first is the user's start
        completed from the first default start.

        Parameters
        ----------
        T : float
            Nominal sampling interval (s).
        """
        lo, hi = np.array(self.bounds, float).reshape(-1, 2).T
        user = [(i, self.start[n]) for i, n in enumerate(self.param_names) if n in self.start]
        out: list[FloatArray] = []
        for d in self.structure.starts(T):
            v = np.asarray(d, float)[self._free].copy()  # type: ignore[attr-defined]
            for i, value in user:
                v[i] = value
            v = np.clip(v, lo, hi)
            if not any(np.array_equal(v, w) for w in out):
                out.append(v)
        return out


def _by_name(
    values: Mapping[str, Any] | None, arg: str, names: tuple[str, ...], what: str
) -> dict[str, Any]:
    """``values`` as a dict whose keys are all in ``names``, or a ValueError naming ``arg``."""
    if values is None:
        return {}
    if not isinstance(values, Mapping):
        raise TypeError(
            f"{arg} must be a dict by parameter name; got {type(values).__name__} ({what})"
        )
    unknown = [k for k in values if k not in names]
    if unknown:
        hints = ", ".join(f"{k!r}{did_you_mean(str(k), names)}" for k in unknown)
        raise ValueError(f"{arg}: unknown parameter(s) {hints}; {what}")
    return dict(values)


def _finite(v: Any, name: str) -> float:
    """``v`` as a finite float (not a string or a bool), or a ValueError naming ``name``."""
    x = math.nan
    if not isinstance(v, (str, bytes, bool, np.bool_)):
        with contextlib.suppress(TypeError, ValueError):
            x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be a finite number; got {v!r}")
    return x


def _pair(v: Any, name: str) -> tuple[float, float]:
    """A (low, high) pair, None or an infinity for no bound at that end; low < high."""
    what = f"bounds[{name!r}]"
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) != 2:
        raise ValueError(f"{what} must be a pair (low, high), None for an open end; got {v!r}")
    ends = []
    for end, default in zip(v, (-math.inf, math.inf), strict=True):
        if end is None:
            ends.append(default)
            continue
        x = (
            _finite(end, what)
            if not (isinstance(end, (int, float)) and math.isinf(end))
            else float(end)
        )
        ends.append(x)
    lo, hi = ends
    if lo == math.inf or hi == -math.inf or not lo < hi:
        raise ValueError(
            f"{what} = ({lo:g}, {hi:g}): the low end must be below the high end; to hold "
            f"{name} at a value, fix it instead"
        )
    return lo, hi
