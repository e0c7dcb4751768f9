"""The ``jitterid`` command line: a thin layer over the library.

Each group of commands lives in its own module and is registered here.
"""

from __future__ import annotations

import click

__all__ = ["main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="jitterid")
def main() -> None:
    """Identify continuous-time systems from samples with random sampling-time jitter."""


# Command modules register themselves on ``main`` when imported (one line each below).
from . import data as _data  # noqa: F401
from . import reproduce as _reproduce  # noqa: F401
