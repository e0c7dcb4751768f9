"""Short reprs of long arrays: a record of 1e5 samples prints as one line, not 1e5 numbers."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__: list[str] = []

#: Arrays up to this size are printed in full.
FULL = 6


def brief(a: ArrayLike | None) -> str:
    """``[1.0, 2.0]`` for a short array; ``array(N values in [lo, hi])`` for a long one."""
    arr = np.asarray(a)
    if arr.size <= FULL:
        return repr(arr.tolist())
    if arr.size and np.issubdtype(arr.dtype, np.number):
        return f"array({arr.size} values in [{np.min(arr):.6g}, {np.max(arr):.6g}])"
    return f"array({arr.size} values)"
