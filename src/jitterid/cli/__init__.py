"""The ``jitterid`` command line: a thin layer over the library.

Each group of commands lives in its own module and is registered here. Every error ends in
a one-line message and a non-zero exit, never a traceback: the commands turn the errors
they expect into messages that name the file or option and the fix, and anything else is
reported on one line as an internal error (exit 1) for the user to report.
"""

from __future__ import annotations

# The group lives in ._main; a command's module registers it there when the group imports it
# (on first use), so that `jitterid --help` imports nothing heavy.
from ._main import COMMANDS, INTERNAL, main

__all__ = ["COMMANDS", "INTERNAL", "main"]
