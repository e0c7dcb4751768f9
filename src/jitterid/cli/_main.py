"""The ``jitterid`` command group, on which every command module registers its commands.

It lives apart from :mod:`jitterid.cli` (which imports the command modules so that they
register) so that a command module imports the group without importing its own package's
``__init__``: no module of the CLI imports one that imports it back.
"""

from __future__ import annotations

from typing import Any

import click

__all__ = ["INTERNAL", "main"]

#: The first words of the last-resort message (tests look for it: it marks a missed case).
INTERNAL = "internal error"


class _Group(click.Group):
    """A click group whose unexpected exceptions end in one line, not a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.Abort):
            raise
        except KeyboardInterrupt:
            raise click.Abort() from None
        except MemoryError:
            raise click.ClickException(
                "out of memory; use fewer samples, a smaller model or a machine with more "
                "memory (JITTERID_MEMORY_BUDGET sets the budget checked up front)"
            ) from None
        except RecursionError:
            raise click.ClickException(
                "an input is nested too deeply to be read; check the files given"
            ) from None
        except Exception as exc:  # noqa: BLE001 - the last resort: one line, not a traceback
            msg = " ".join(str(exc).split())[:500]
            raise click.ClickException(
                f"{INTERNAL} ({type(exc).__name__}: {msg}); please report this with the "
                "command line that caused it"
            ) from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="jitterid")
def main() -> None:
    """Identify continuous-time systems from samples with random sampling-time jitter."""
