"""A small reader for TOML tables that names the offending key in every error.

Every experiment-definition error is an :class:`ExperimentError` whose message starts with
the file and the dotted key (``table2.toml: sampling.N must be an integer >= 4; got 0``),
so a typo or a bad value is found before any work starts.
"""

from __future__ import annotations

import difflib
import math
import reprlib
from collections.abc import Iterable
from typing import Any

__all__ = ["ExperimentError", "Section"]

_MISSING: Any = object()
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 3, 80, 80, 40


def _show(value: Any) -> str:
    """A short repr for messages (bounded for huge or deeply nested values)."""
    try:
        return _REPR.repr(value)
    except (ValueError, RecursionError):
        return f"<{type(value).__name__}>"


class ExperimentError(ValueError):
    """An invalid experiment definition; the message names the key and how to fix it."""


class Section:
    """One TOML table with a fixed set of allowed keys, read value by value.

    Parameters
    ----------
    data : dict
        The parsed table.
    path : str
        Its dotted path in the file ('' for the top level), used in messages.
    source : str
        The file name, used in messages.
    keys : iterable of str
        The allowed keys; any other key is refused at once, with a did-you-mean hint.
    """

    def __init__(self, data: Any, path: str, source: str, keys: Iterable[str]) -> None:
        self.path, self.source = path, source
        if not isinstance(data, dict):
            raise ExperimentError(
                f"{source}: {path or 'the file'} must be a table; got {_show(data)}"
            )
        self.data: dict[str, Any] = data
        allowed = list(keys)
        for k in data:
            if k not in allowed:
                close = difflib.get_close_matches(k, allowed, n=1, cutoff=0.5)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise ExperimentError(
                    f"{source}: unknown key '{self.key(k)}'{hint}; allowed keys here: "
                    f"{', '.join(allowed)}"
                )

    def key(self, k: str) -> str:
        """The dotted name of key ``k``."""
        return f"{self.path}.{k}" if self.path else k

    def fail(self, k: str, problem: str) -> ExperimentError:
        """An error about key ``k`` (to raise)."""
        return ExperimentError(f"{self.source}: {self.key(k)} {problem}")

    def has(self, k: str) -> bool:
        return k in self.data

    def raw(self, k: str, default: Any = _MISSING) -> Any:
        if k in self.data:
            return self.data[k]
        if default is _MISSING:
            raise ExperimentError(f"{self.source}: missing required key '{self.key(k)}'")
        return default

    def integer(self, k: str, *, minimum: int, default: Any = _MISSING) -> int:
        v = self.raw(k, default)
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise self.fail(k, f"must be an integer >= {minimum}; got {_show(v)}")
        return v

    def number(
        self,
        k: str,
        *,
        above: float | None = None,
        at_least: float | None = None,
        default: Any = _MISSING,
    ) -> float:
        v = self.raw(k, default)
        try:
            finite = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
        except OverflowError:  # an integer beyond float
            finite = False
        if not finite:
            raise self.fail(k, f"must be a finite number; got {_show(v)}")
        if above is not None and not v > above:
            raise self.fail(k, f"must be > {above:g}; got {_show(v)}")
        if at_least is not None and not v >= at_least:
            raise self.fail(k, f"must be >= {at_least:g}; got {_show(v)}")
        return float(v)

    def text(self, k: str, *, choices: Iterable[str] | None = None, default: Any = _MISSING) -> str:
        v = self.raw(k, default)
        if not isinstance(v, str) or not v.strip():
            raise self.fail(k, f"must be a non-empty string; got {_show(v)}")
        if choices is not None and v not in (opts := list(choices)):
            close = difflib.get_close_matches(v, opts, n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise self.fail(k, f"must be one of {', '.join(opts)}; got {_show(v)}{hint}")
        return v

    def flag(self, k: str, *, default: Any = _MISSING) -> bool:
        v = self.raw(k, default)
        if not isinstance(v, bool):
            raise self.fail(k, f"must be true or false; got {_show(v)}")
        return v

    def numbers(
        self, k: str, *, length: int | None = None, default: Any = _MISSING
    ) -> tuple[float, ...]:
        v = self.raw(k, default)
        try:
            ok = isinstance(v, (list, tuple)) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                for x in v
            )
        except OverflowError:  # an integer beyond float
            ok = False
        if not ok or not v or (length is not None and len(v) != length):
            size = f"{length} " if length is not None else "a non-empty list of "
            raise self.fail(k, f"must be {size}finite numbers; got {_show(v)}")
        return tuple(float(x) for x in v)

    def texts(self, k: str, *, default: Any = _MISSING) -> tuple[str, ...]:
        v = self.raw(k, default)
        if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v):
            raise self.fail(k, f"must be a non-empty list of strings; got {_show(v)}")
        return tuple(v)

    def table(self, k: str, keys: Iterable[str], *, default: Any = _MISSING) -> Section:
        return Section(self.raw(k, default), self.key(k), self.source, keys)

    def tables(self, k: str, keys: Iterable[str]) -> list[Section]:
        v = self.raw(k)
        if not isinstance(v, list) or not v:
            raise self.fail(k, "must be a non-empty array of tables ([[" + k + "]] blocks)")
        return [Section(x, f"{self.key(k)}[{i}]", self.source, keys) for i, x in enumerate(v)]
