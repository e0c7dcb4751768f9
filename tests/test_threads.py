"""The kept thread-pool controller limits the pools as threadpoolctl's own call does."""

from __future__ import annotations

import sys
import types

from threadpoolctl import ThreadpoolController, threadpool_info

from jitterid import _threads
from jitterid._threads import single_thread


def test_single_thread_limits_every_pool_and_restores() -> None:
    before = {i["filepath"]: i["num_threads"] for i in threadpool_info()}
    with single_thread():
        assert all(i["num_threads"] == 1 for i in threadpool_info())
    with single_thread("blas"):
        assert all(i["num_threads"] == 1 for i in threadpool_info() if i["user_api"] == "blas")
    assert {i["filepath"]: i["num_threads"] for i in threadpool_info()} == before


def test_the_controller_is_kept_until_a_module_is_imported() -> None:
    first = _threads._controller()
    assert _threads._controller() is first  # no rescan of the libraries
    name = "_jitterid_test_fresh_module"
    sys.modules[name] = types.ModuleType(name)  # an import may load a new BLAS
    try:
        again = _threads._controller()
        assert again is not first
        assert isinstance(again, ThreadpoolController)
        assert {c.filepath for c in again.lib_controllers} == {
            c.filepath for c in first.lib_controllers
        }
    finally:
        del sys.modules[name]
