"""The ``jitterid`` command line: a thin layer over the library.

Each group of commands lives in its own module and is registered here. Every error ends in
a one-line message and a non-zero exit, never a traceback: the commands turn the errors
they expect into messages that name the file or option and the fix, and anything else is
reported on one line as an internal error (exit 1) for the user to report.
"""

from __future__ import annotations

# The group lives in ._main; the command modules register themselves on it when imported.
from . import data as _data  # noqa: F401
from . import jitter as _jitter  # noqa: F401
from . import reproduce as _reproduce  # noqa: F401
from ._main import INTERNAL, main

__all__ = ["INTERNAL", "main"]
