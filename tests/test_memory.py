"""jitterid._memory.trim: free heap pages back to the system (glibc), a no-op elsewhere."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from jitterid import _memory


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or _memory._malloc_trim() is None,
    reason="glibc's malloc_trim only",
)
def test_trim_returns_freed_heap_pages():
    # 3000 arrays of 64 kB (below the mmap threshold: from the heap, ~190 MB), all freed
    # but the last, which pins the heap's top: free() alone cannot shrink it
    blocks = [np.ones(8000) for _ in range(3000)]
    last = blocks[-1]
    del blocks
    before = _rss()
    assert _memory.trim() is True
    after = _rss()
    assert after < before - 100e6, (before, after)
    assert last.sum() == 8000


def test_trim_is_a_no_op_without_malloc_trim(monkeypatch):
    monkeypatch.setattr(_memory, "_malloc_trim", lambda: None)
    assert _memory.trim() is False
