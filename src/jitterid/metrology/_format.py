"""Text forms of the meter's quantities (one home for them: the meter and the phase-error
analysis both print times)."""

from __future__ import annotations

import numpy as np

__all__ = ["time_text"]


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
