"""The ``jitterid`` command group, on which every command module registers its commands.

It lives apart from :mod:`jitterid.cli` so that a command module imports the group without
importing its own package's ``__init__``: no module of the CLI imports one that imports it
back. The group imports a command's module when the command is used (:data:`COMMANDS`), so
that ``jitterid --help`` imports none of the library (issue 25: it cost 2.6-3.0 CPU-s).
"""

from __future__ import annotations

import importlib
from typing import Any

import click

__all__ = ["COMMANDS", "INTERNAL", "main"]

#: The first words of the last-resort message (tests look for it: it marks a missed case).
INTERNAL = "internal error"


#: The commands: the module of :mod:`jitterid.cli` that defines each (imported when the
#: command runs, or its own --help is asked for) and its one-line help for ``jitterid
#: --help``, which so imports nothing heavy (the same words as the command's short_help:
#: tests/cli/test_lazy_help.py).
COMMANDS: dict[str, tuple[str, str]] = {
    "bias": ("data", "Predict an ordinary fit's gain bias |phi(f)| under jitter."),
    "detect": ("data", "Test DATA for sampling jitter before fitting."),
    "fit": ("data", "Fit a model to DATA accounting for jitter; write a report."),
    "jitter": ("jitter", "Measure the sampling jitter from a sine record (or a batch of them)."),
    "reproduce": (
        "reproduce",
        "Reproduce the paper's Tables 1-3 and Figures 1-5 (TARGET, or 'all').",
    ),
    "run": ("reproduce", "Run the Monte Carlo study defined in EXPERIMENT (a TOML file)."),
    "simulate": ("data", "Write a synthetic jittered data set (the paper's setting)."),
}


class _Group(click.Group):
    """A click group whose commands are imported when used (:data:`COMMANDS`), and whose
    unexpected exceptions end in one line, not a traceback."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*COMMANDS, *self.commands})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            # the module registers its commands on this group when imported
            importlib.import_module(f"{__package__}.{COMMANDS[cmd_name][0]}")
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list of ``--help`` from :data:`COMMANDS`, importing no command."""
        rows = [(name, COMMANDS[name][1]) for name in sorted(COMMANDS)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

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
