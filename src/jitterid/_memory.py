"""Give freed heap memory back to the operating system (glibc's ``malloc_trim``).

numpy arrays of a few MB come from the C heap once glibc's dynamic mmap threshold has
risen (it follows the largest freed mapping, up to 32 MB), and freeing them leaves the
pages with the process: after a long record's moment stage the resident size stayed ~1 GB
above what was alive (N = 1e6, ML: the search then peaked at 2.5-2.9 GB against ~1.5 GB
live). :func:`trim` asks glibc to return the free pages (what dask's workers do too); it is
a no-op where the C library has no ``malloc_trim`` (macOS, Windows, musl).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from collections.abc import Callable

__all__: list[str] = []


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        return ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None


def trim() -> bool:
    """Return free heap pages to the system; whether the C library could be asked."""
    fn = _malloc_trim()
    if fn is None:
        return False
    fn(0)
    return True
