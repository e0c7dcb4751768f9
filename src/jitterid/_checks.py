"""Argument validation shared by every module.

Each helper raises :class:`ValueError` (or :class:`TypeError` for the wrong kind of
object) with a message that names the argument and says how to fix it, so that bad
input never surfaces as a traceback from deep inside numpy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__: list[str] = []


def real_array(x: ArrayLike, name: str, *, ndim: int | None = None) -> NDArray[np.float64]:
    """Return ``x`` as a finite float array, or raise naming ``name``."""
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers; got {type(x).__name__}") from exc
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-dimensional; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))
        raise ValueError(
            f"{name} contains {bad.size} NaN or infinite value(s) (first at flat index {bad[0]}); "
            "remove or interpolate them before calling"
        )
    return arr


def positive(x: float, name: str, *, allow_zero: bool = False) -> float:
    """Return ``x`` as a float if it is finite and > 0 (or >= 0), else raise."""
    try:
        val = float(x)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a real number; got {x!r}") from exc
    if not np.isfinite(val) or val < 0 or (val == 0 and not allow_zero):
        need = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {need}; got {x!r}")
    return val


def count(x: int, name: str, *, minimum: int) -> int:
    """Return ``x`` as an int if it is an integer >= ``minimum``, else raise."""
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)):
        raise TypeError(f"{name} must be an integer; got {x!r}")
    if x < minimum:
        raise ValueError(f"{name} must be at least {minimum}; got {x}")
    return int(x)


def generator(rng: np.random.Generator | int | None, name: str = "rng") -> np.random.Generator:
    """Turn a seed or Generator into a Generator; ``None`` is refused (randomness is explicit)."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise TypeError(
        f"{name} must be a numpy.random.Generator or an integer seed; got {rng!r}. "
        "Pass np.random.default_rng(seed) so results are reproducible."
    )


def parameter_vector(
    params: ArrayLike, names: Sequence[str], bounds: Sequence[tuple[float, float]]
) -> NDArray[np.float64]:
    """``params`` as a float vector with one value per name, each inside its bounds."""
    x = np.atleast_1d(real_array(params, "params"))
    if x.size != len(names):
        raise ValueError(f"params must have {len(names)} values {tuple(names)}; got {x.size}")
    for val, name, (lo, hi) in zip(x, names, bounds, strict=True):
        if not lo <= val <= hi:
            raise ValueError(f"parameter {name} = {val:g} is outside its bounds [{lo}, {hi}]")
    return x

