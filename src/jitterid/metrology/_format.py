"""Text forms of the meter's quantities (one home for them: the meter and the phase-error
analysis both print times)."""

from __future__ import annotations

import numpy as np

__all__ = ["ordinal", "time_text"]


def time_text(x: float) -> str:
    """A time in s with an SI prefix (s down to fs).

    Parameters
    ----------
    x : float
        Seconds.

    Examples
    --------
    >>> time_text(2.5e-15), time_text(3e-6)
    ('2.5 fs', '3 us')
    """
    if not np.isfinite(x):
        return "nan"
    units = (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9), ("ps", 1e-12), ("fs", 1e-15))
    for unit, scale in units:
        if abs(x) >= scale or unit == "fs":
            return f"{x / scale:.4g} {unit}"
    return f"{x:.4g} s"  # pragma: no cover


def ordinal(n: int) -> str:
    """``n`` as an English ordinal ("every 8th sample").

    Parameters
    ----------
    n : int
        A positive integer.

    Examples
    --------
    >>> [ordinal(k) for k in (1, 2, 3, 4, 11, 21, 22, 112)]
    ['1st', '2nd', '3rd', '4th', '11th', '21st', '22nd', '112th']
    """
    if 10 <= n % 100 <= 20:
        return f"{n}th"
    return f"{n}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th') }"
