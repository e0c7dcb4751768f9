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
    """Return ``x`` as a finite float array, or raise naming ``name`` (complex values are
    refused, not cast: dropping the imaginary part would be a silent wrong answer)."""
    try:
        raw = np.asarray(x)
        complex_values = raw.dtype.kind == "c"
        arr = np.asarray(raw.real if complex_values else raw, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers; got {type(x).__name__}") from exc
    if complex_values:
        raise TypeError(
            f"{name} must be real; got complex values. Give the real quantity that was "
            f"measured (e.g. {name}.real, or abs({name}) for a magnitude)"
        )
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


#: Range of a sampling interval (s). Inside it the model's time scale 1/T and its powers (the
#: coefficients of a rational model, the frequencies) are finite doubles; outside it (say
#: T = 1e-300 s) they overflow deep inside the estimators, so T is refused up front.
T_RANGE_S = (1e-24, 1e24)


def sampling_interval(T: float, name: str = "T") -> float:
    """Return ``T`` as a float if it is a sampling interval inside :data:`T_RANGE_S`."""
    val = positive(T, name)
    lo, hi = T_RANGE_S
    if not lo <= val <= hi:
        raise ValueError(
            f"{name} = {val:g} s is outside the range of sampling intervals jitterid handles "
            f"[{lo:g}, {hi:g}] s; give the times in another unit (e.g. ms or us, scaling the "
            "model's parameters with them)"
        )
    return val


def finite(x: float, name: str) -> float:
    """Return ``x`` as a float if it is a finite real number, else raise."""
    try:
        val = float(x)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a real number; got {x!r}") from exc
    if not np.isfinite(val):
        raise ValueError(f"{name} must be finite; got {x!r}")
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
    """``params`` (a vector in ``names`` order, a dict by name, or a fitted result whose
    entries are taken by name) as a float vector, each value inside its bounds."""
    from .params import ParamLayout

    layout = ParamLayout(system=tuple(names), bounds=tuple((float(a), float(b)) for a, b in bounds))
    x = layout.vector(params, "params")
    for val, name, (lo, hi) in zip(x, names, bounds, strict=True):
        if not lo <= val <= hi:
            raise ValueError(f"parameter {name} = {val:g} is outside its bounds [{lo}, {hi}]")
    return x


class TooLargeError(ValueError):
    """A request whose memory would exceed the budget; the message gives the figure and the fix."""


def memory_budget() -> int:
    """Bytes a single allocation may take: half of the available memory (8 GiB if unknown).

    ``JITTERID_MEMORY_BUDGET`` (bytes, e.g. ``2e9``) overrides it.
    """
    import os

    env = os.environ.get("JITTERID_MEMORY_BUDGET")
    if env:
        try:
            return int(float(env))
        except ValueError:
            pass
    try:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # pragma: no cover - not POSIX
        return 8 << 30
    return max(int(avail) // 2, 64 << 20)


def allocation(elements: float, name: str, *, bytes_each: int = 8, fix: str = "") -> None:
    """Refuse, before allocating, ``elements`` values (of ``bytes_each``) above the budget."""
    need = float(elements) * bytes_each
    budget = memory_budget()
    if not need <= budget:  # also refuses inf/nan
        raise TooLargeError(
            f"{name} needs about {need / 1e9:.3g} GB ({float(elements):.3g} values), more than "
            f"the memory budget of {budget / 1e9:.3g} GB (half the free memory; set "
            f"JITTERID_MEMORY_BUDGET to change it){'; ' + fix if fix else ''}"
        )


def nesting_depth(text: str, *, comments: bool = False) -> int:
    """The deepest nesting of ``[``/``{`` in JSON or TOML ``text`` (outside strings), found
    without recursion, so that absurdly nested input is refused before a parser recurses."""
    depth = deepest = 0
    quote = ""
    escaped = in_comment = False
    for ch in text:
        if in_comment:
            in_comment = ch != "\n"
        elif quote:
            if escaped:
                escaped = False
            elif ch == "\\" and quote == '"':
                escaped = True
            elif ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
        elif ch == "#" and comments:
            in_comment = True
    return deepest
