"""One thread for the BLAS (and OpenMP) pools of a block of code, cheaply.

``threadpoolctl.threadpool_limits`` scans the process's shared libraries at every call
(1.5-3 ms), which a Monte Carlo realization paid seven times (the realization, each fit
and each covariance): ~8 % of a Table 2 realization. :func:`single_thread` keeps one
``ThreadpoolController`` per process and scans again only when modules were imported
since (a newly imported extension is how a new BLAS library gets loaded), so the limits
are those of ``threadpool_limits``.
"""

from __future__ import annotations

import sys
import threading
from contextlib import AbstractContextManager
from typing import Any

from threadpoolctl import ThreadpoolController

__all__: list[str] = []

_lock = threading.Lock()
_kept: tuple[int, ThreadpoolController] | None = None


def _controller() -> ThreadpoolController:
    global _kept
    with _lock:
        modules = len(sys.modules)
        if _kept is None or _kept[0] != modules:
            _kept = (modules, ThreadpoolController())
        return _kept[1]


def single_thread(user_api: str | None = None) -> AbstractContextManager[Any]:
    """``threadpool_limits(limits=1, user_api=user_api)`` on the process's kept controller."""
    return _controller().limit(limits=1, user_api=user_api)
