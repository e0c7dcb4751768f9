"""One parameter layout: the named blocks of a problem's parameter vector.

Every estimator, bound and band in jitterid sees the parameters as one vector ordered by
blocks (the paper's Table 3 order):

    jitter-family parameters | system parameters | noise-model parameters | noise_std

Only the blocks a problem has are present: a known jitter law has no jitter block, white
noise no noise-model block, and ``noise_std`` is a parameter only where the criterion
estimates it. :class:`ParamLayout` is the only place that splits such a vector, turns it
into a dict by name, or turns a dict / vector / fitted result back into a vector.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["BLOCKS", "ParamLayout", "count_params", "did_you_mean"]

FloatArray = NDArray[np.float64]
Bounds = tuple[tuple[float, float], ...]

BLOCKS = ("jitter", "system", "noise", "noise_std")
NOISE_STD_BOUNDS = (1e-12, np.inf)
#: relative distance from a kink that counts as at it (ParamLayout.at_kink)
KINK_REACH = 2e-4


@dataclass(frozen=True)
class ParamLayout:
    """Names, bounds and block boundaries of a parameter vector.

    Parameters
    ----------
    jitter, system, noise : tuple of str
        Parameter names of the jitter family, the system structure and the noise-model
        structure (empty where the block is absent).
    noise_std : bool
        Whether the white-noise standard deviation is the last parameter.
    bounds : tuple of (float, float)
        Closed bounds of every parameter, in vector order.
    kinks : tuple of tuple of float
        Per parameter, the interior values where the criteria are not differentiable in it
        (a jitter family's :attr:`~jitterid.JitterFamily.kinks`: n of the family (26) at
        the integers); empty (the default) where there are none.

    Examples
    --------
    >>> import jitterid as ji
    >>> lay = ParamLayout.build(ji.SumOfUniformsFamily(), ji.PolePairGain())
    >>> lay.names
    ('n', 'a', 'k0', 'pr', 'pi')
    >>> lay.block([2, 0.3, 6.25, -1.5, 2], "system").tolist()
    [6.25, -1.5, 2.0]
    >>> lay.vector({"n": 2, "a": 0.3, "k0": 6.25, "pr": -1.5, "pi": 2}).tolist()
    [2.0, 0.3, 6.25, -1.5, 2.0]
    """

    jitter: tuple[str, ...] = ()
    system: tuple[str, ...] = ()
    noise: tuple[str, ...] = ()
    noise_std: bool = False
    bounds: Bounds = ()
    kinks: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        for name in ("jitter", "system", "noise"):  # tuples (e.g. after a JSON round trip)
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "bounds", tuple(tuple(map(float, b)) for b in self.bounds))
        if len(self.bounds) != len(self.names):
            raise ValueError(
                f"bounds must hold one (low, high) pair per parameter {self.names}; "
                f"got {len(self.bounds)}"
            )
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"parameter names must be unique; got {self.names}")
        kinks = tuple(tuple(map(float, k)) for k in self.kinks)
        if not any(kinks):
            kinks = ()
        elif len(kinks) != len(self.names):
            raise ValueError(
                f"kinks must hold one tuple per parameter {self.names}; got {len(kinks)}"
            )
        object.__setattr__(self, "kinks", kinks)

    @classmethod
    def build(
        cls,
        jitter: Any = None,
        structure: Any = None,
        noise: Any = None,
        *,
        noise_std: bool = False,
        noise_floor: float | None = None,
    ) -> ParamLayout:
        """The layout of a problem from its parts.

        ``jitter``, ``structure`` and ``noise`` contribute their ``param_names`` and
        ``bounds`` when they have them (a jitter family, a model structure, a noise-model
        structure), the jitter family its ``kinks``; a known law, a known system or ``None``
        contribute nothing.

        Parameters
        ----------
        jitter : JitterLaw, JitterFamily or None
            The jitter part.
        structure : Model, TransferFunction or None
            The system or signal part.
        noise : NoiseStructure, NoiseModel or None
            The coloured-noise part.
        noise_std : bool, optional
            Whether the white-noise std is a last, estimated parameter.
        noise_floor : float, optional
            Lower bound of an estimated noise std; default 1e-12.
        """

        def part(obj: Any) -> tuple[tuple[str, ...], Bounds]:
            names = tuple(getattr(obj, "param_names", ()) or ())
            bounds = tuple(tuple(map(float, b)) for b in (getattr(obj, "bounds", ()) or ()))
            return names, bounds[: len(names)] if names else ()  # type: ignore[return-value]

        (jn, jb), (sn, sb), (nn, nb) = part(jitter), part(structure), part(noise)
        noise_bound = NOISE_STD_BOUNDS if noise_floor is None else (float(noise_floor), np.inf)
        bounds = jb + sb + nb + ((noise_bound,) if noise_std else ())
        jk = tuple(getattr(jitter, "kinks", ()) or ()) if jn else ()
        rest = (() for _ in range(len(bounds) - len(jk)))
        return cls(jn, sn, nn, bool(noise_std), bounds, jk + tuple(rest) if jk else ())

    # ------------------------------------------------------------------ structure
    @property
    def names(self) -> tuple[str, ...]:
        """All parameter names in vector order."""
        return self.jitter + self.system + self.noise + (("noise_std",) if self.noise_std else ())

    @property
    def size(self) -> int:
        return len(self.names)

    def slice(self, block: str) -> slice:
        """The positions of ``block`` (one of :data:`BLOCKS`) in the vector.

        Parameters
        ----------
        block : str
            One of :data:`BLOCKS`.
        """
        sizes = {
            "jitter": len(self.jitter),
            "system": len(self.system),
            "noise": len(self.noise),
            "noise_std": int(self.noise_std),
        }
        if block not in sizes:
            raise ValueError(f"block must be one of {BLOCKS}; got {block!r}")
        start = 0
        for b in BLOCKS:
            if b == block:
                return slice(start, start + sizes[b])
            start += sizes[b]
        raise AssertionError  # pragma: no cover

    def block(self, x: Any, block: str) -> FloatArray:
        """The entries of ``x`` (a vector in layout order) that belong to ``block``.

        Parameters
        ----------
        x : array_like
            A vector in layout order.
        block : str
            One of :data:`BLOCKS`.
        """
        return np.asarray(x, float)[self.slice(block)]

    def replace(self, x: Any, block: str, values: Any) -> FloatArray:
        """A copy of ``x`` (a vector in layout order) with ``block`` set to ``values``.

        Parameters
        ----------
        x : array_like
            A vector in layout order.
        block : str
            One of :data:`BLOCKS`.
        values : array_like
            The block's new values.
        """
        out = np.array(x, dtype=float)
        out[self.slice(block)] = np.asarray(values, dtype=float)
        return out

    def at_kink(self, x: Any, reach: float = KINK_REACH) -> NDArray[np.bool_]:
        """Which parameters of ``x`` lie within ``reach * max(|x_i|, 0.01)`` of one of their
        kinks (the covariance's difference reach, 2 x its step 1e-4 max(|x_i|, 0.01)): no
        second derivative there, so the covariance holds them fixed, as on a bound.

        Parameters
        ----------
        x : array_like
            A vector in layout order.
        reach : float, optional
            The relative distance that counts as at the kink.
        """
        v = np.asarray(x, float).reshape(-1)
        out = np.zeros(v.size, dtype=bool)
        for i, k in enumerate(self.kinks):
            if k:
                out[i] = bool(np.any(np.abs(np.asarray(k) - v[i]) <= reach * max(abs(v[i]), 1e-2)))
        return out

    def kinked(self) -> dict[int, tuple[float, ...]]:
        """``{index: kinks}`` of the parameters that have kinks (see ``kinks``)."""
        return {i: k for i, k in enumerate(self.kinks) if k}

    def lower_upper(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper bounds as two arrays."""
        b = np.array(self.bounds, dtype=float).reshape(-1, 2)
        return b[:, 0], b[:, 1]

    # ------------------------------------------------------------------ conversions
    def to_dict(self, x: Any) -> dict[str, float]:
        """``{name: value}`` of a vector in layout order.

        Parameters
        ----------
        x : array_like
            A vector in layout order.
        """
        v = np.asarray(x, float).reshape(-1)
        if v.size != self.size:
            raise ValueError(f"expected {self.size} values {self.names}; got {v.size}")
        return {n: float(a) for n, a in zip(self.names, v, strict=True)}

    def vector(self, values: Any, name: str = "params") -> FloatArray:
        """A vector in layout order from a dict by name, a vector, or a fitted result.

        Parameters
        ----------
        values : dict, array_like or FitResult
            ``{name: value}`` with every parameter of the layout (no others); a sequence of
            ``size`` numbers in :attr:`names` order; or any object with ``names`` and ``x``
            (a :class:`~jitterid.FitResult`), whose entries are matched by name (entries the
            layout does not have, e.g. an estimated ``noise_std``, are ignored).
        name : str
            The argument's name, for error messages.
        """
        if hasattr(values, "names") and hasattr(values, "x"):
            values = dict(zip(values.names, np.asarray(values.x, float), strict=True))
            values = {k: v for k, v in values.items() if k in self.names}
        if isinstance(values, Mapping):
            unknown = [k for k in values if k not in self.names]
            if unknown:
                hints = [f"{k!r}{did_you_mean(str(k), self.names)}" for k in unknown]
                raise ValueError(
                    f"{name}: unknown parameter(s) {', '.join(hints)}; the parameters are "
                    f"{self.names}"
                )
            missing = [n for n in self.names if n not in values]
            if missing:
                raise ValueError(
                    f"{name}: missing value(s) for {tuple(missing)}; give every parameter of "
                    f"{self.names}"
                )
            out = np.array([_number(values[n], f"{name}[{n!r}]") for n in self.names], float)
        else:
            try:
                out = np.atleast_1d(np.asarray(values, dtype=float)).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{name} must be a dict by name, a vector in the order {self.names}, or a "
                    f"FitResult; got {type(values).__name__}"
                ) from None
            if out.size != self.size:
                raise ValueError(
                    f"{name} must have {self.size} values in the order {self.names}; got "
                    f"{out.size} (or pass a dict by name)"
                )
        if not np.all(np.isfinite(out)):
            raise ValueError(f"{name} must be finite; got {out.tolist()}")
        return out


def count_params(part: Any) -> int:
    """The number of parameters ``part`` (a jitter family, a structure, a noise structure;
    a known law, a known system or None: 0) adds to a layout, as :meth:`ParamLayout.build`
    counts them.

    Parameters
    ----------
    part : object
        A part of a problem.

    Examples
    --------
    >>> import jitterid as ji
    >>> count_params(ji.SumOfUniformsFamily()), count_params(ji.Uniform(0.5))
    (2, 0)
    """
    return len(getattr(part, "param_names", ()) or ())


def did_you_mean(name: str, names: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` with the entry of ``names`` closest to ``name`` (case
    ignored; :func:`difflib.get_close_matches`), or ``""`` when none is close: the one hint
    for a misspelt parameter name (here, :class:`jitterid.systems.constrained.Constrained`
    and the command line's ``--start``/``--bounds``/``--fix``)."""
    lower = {n.lower(): n for n in names}
    # cutoff 0.5: one wrong character in a two-character name (k0 / kO) is still a match
    close = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.5)
    return f" (did you mean {lower[close[0]]!r}?)" if close else ""


def _number(v: Any, name: str) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number; got {v!r}") from None
