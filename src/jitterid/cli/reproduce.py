"""``jitterid reproduce TARGET`` (the paper's tables and figures) and ``jitterid run FILE.toml``."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from ..experiments import (
    PAPER_EXPERIMENTS,
    Experiment,
    ExperimentError,
    figures,
    load_experiment,
    packaged_path,
)
from ..experiments.bj import spectra_figure
from ..experiments.loader import MAX_RUNS
from ..experiments.report import markdown_report, nothing_converged
from ..experiments.runner import (
    dask_client,
    default_workers,
    local_workers,
    run_experiment,
    store_path,
)
from ..experiments.store import Store, StoreError
from ..io import atomic_write
from ._main import main

if TYPE_CHECKING:
    from dask.distributed import Client

__all__ = ["reproduce", "run"]

#: The name cli/jitter.py imports; the count is decided in experiments.runner (one place).
_default_workers = default_workers

FIGURES = ("fig1", "fig2", "fig3", "fig4", "fig5")
STUDIES = ("bj",)  # beyond the paper: Table 2's system with coloured noise (issue 7)
TARGETS = (*PAPER_EXPERIMENTS, *FIGURES, *STUDIES, "all")


def _common(f: Callable[..., Any]) -> Callable[..., Any]:
    """The options shared by ``reproduce`` and ``run``."""
    opts = [
        click.option(
            "--runs",
            type=click.IntRange(min=1, max=MAX_RUNS),
            default=None,
            help="Realizations per case (default: the definition's; the paper's 128).",
        ),
        click.option(
            "--workers",
            type=click.IntRange(min=1),
            default=None,
            help="Local worker processes (default: one per CPU); 1 runs in this "
            "process without Dask. Results do not depend on it.",
        ),
        click.option(
            "--scheduler",
            metavar="ADDRESS",
            default=None,
            help="Send realizations to a running Dask scheduler, e.g. "
            "tcp://10.0.0.5:8786 (its workers need jitterid installed). TRUSTED CODE "
            "EXECUTION: the cluster runs code for you and jitterid unpickles the results "
            "it sends back, so connect only to a cluster you trust as much as this machine. "
            "Local workers (--workers) listen on 127.0.0.1 only, with no dashboard.",
        ),
        click.option(
            "--out",
            type=click.Path(file_okay=False, path_type=Path),
            default=None,
            help="Output folder for the .sqlite store, .csv, .md reports and .png "
            "figures (default: out/reproduction or out/<experiment name>).",
        ),
        click.option(
            "--resume",
            is_flag=True,
            help="Continue a store that already holds results: run only the "
            "missing realizations (after a kill, or to add --runs).",
        ),
        click.option("--no-progress", is_flag=True, help="Hide the progress bar."),
        click.option(
            "--no-share",
            is_flag=True,
            help="Fit every estimator from scratch (no BCLS stage shared within a "
            "realization) and store the Cramer-Rao bound of every realization, not of the "
            "first crb_runs: the same tables, slower (for benchmarks and checks).",
        ),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


@dataclasses.dataclass(frozen=True)
class _Options:
    out: Path
    workers: int
    scheduler: str | None
    resume: bool
    progress: bool
    share: bool = True
    client: Client | None = None  # one Dask client for every table of the command
    # the studies of the command in which no fit converged (the command then exits with 3)
    empty: list[str] = dataclasses.field(default_factory=list)


def _study(exp: Experiment, opt: _Options, command: str) -> Store:
    """Run (or finish) ``exp``, write its CSV and Markdown report, return its open store."""
    try:
        summary = run_experiment(
            exp,
            opt.out,
            workers=opt.workers,
            scheduler=opt.scheduler,
            resume=opt.resume,
            progress=opt.progress,
            share=opt.share,
            client=opt.client,
        )
    except StoreError as exc:
        raise click.ClickException(str(exc)) from None
    except ValueError as exc:  # e.g. a --scheduler that is no address, a size refused
        raise click.ClickException(f"cannot run {exp.name}: {exc}") from None
    except OSError as exc:  # e.g. an unreachable --scheduler, a full disk
        raise click.ClickException(f"cannot run {exp.name}: {exc}") from None
    try:
        store = Store(summary.store, exp, resume=True)
    except StoreError as exc:
        raise click.ClickException(str(exc)) from None
    try:
        estimates = store.estimates(exp.runs)
    except StoreError as exc:
        store.close()
        raise click.ClickException(str(exc)) from None
    rate = summary.new / summary.wall_s if summary.wall_s > 0 else 0.0
    where = (
        f"Dask scheduler {opt.scheduler}"
        if opt.scheduler
        else f"{local_workers(opt.workers, summary.new)} worker(s)"
    )
    note = (
        f"{summary.new} new realizations in {summary.wall_s:.1f} s on {where}; "
        f"{summary.already_done} were already stored"
    )
    report = opt.out / f"{exp.name}.md"
    try:
        text = markdown_report(exp, estimates, command, note)
        atomic_write(report, lambda fh: fh.write(text))
        csv_path = store.export_csv(opt.out / f"{exp.name}.csv", exp.runs)
    except (OSError, StoreError) as exc:
        store.close()
        raise click.ClickException(
            f"{exp.name}: the {summary.total} realizations are stored in {summary.store}, but "
            f"the report could not be written ({exc}); fix the cause and run again with --resume"
        ) from None
    click.echo(
        f"{exp.name}: {summary.total} realizations ({summary.already_done} already stored, "
        f"{summary.new} new, {rate:.2f}/s) -> {summary.store}, {report}, {csv_path}"
    )
    if nothing_converged(exp, estimates):
        opt.empty.append(exp.name)
    return store


def _exit_if_empty(opt: _Options) -> None:
    """Exit with status 3 (as ``jitterid fit`` does for a fit that did not converge) when a
    study produced no converged fit: its report says why, first."""
    if opt.empty:
        names = ", ".join(opt.empty)
        click.echo(
            f"error: no fit converged in {names}; the report says how they ended "
            f"({opt.out / (opt.empty[0] + '.md')})",
            err=True,
        )
        raise click.exceptions.Exit(3)


def _options(
    out: Path | None,
    default_out: Path,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    no_progress: bool,
    no_share: bool = False,
) -> _Options:
    return _Options(
        out if out is not None else default_out,
        workers if workers is not None else default_workers(),
        scheduler,
        resume,
        not no_progress,
        not no_share,
    )


def _command(words: list[str], runs: int, out: Path) -> str:
    return " ".join(["jitterid", *words, "--runs", str(runs), "--out", str(out)])


@main.command(short_help="Reproduce the paper's Tables 1-3 and Figures 1-5 (TARGET, or 'all').")
@click.argument("target", type=click.Choice(TARGETS))
@_common
@click.option(
    "--print-toml",
    is_flag=True,
    help="Print the packaged definition of TARGET (table1-3, bj) to copy and edit, and exit.",
)
def reproduce(
    target: str,
    runs: int | None,
    workers: int | None,
    scheduler: str | None,
    out: Path | None,
    resume: bool,
    no_progress: bool,
    no_share: bool,
    print_toml: bool,
) -> None:
    """Reproduce the paper's Tables 1-3 and Figures 1-5 (TARGET, or 'all').

    Tables are Monte Carlo studies stored in OUT/tableN.sqlite (each realization committed at
    once), exported to OUT/tableN.csv and reported with the paper's numbers side by side in
    OUT/tableN.md. Figure 5 uses the Table 2 results (and runs Table 2 if they are missing).
    'bj' (not in 'all') is Table 2's system with coloured noise, OE against Box-Jenkins
    estimators: OUT/bj.md and the noise spectra OUT/bj_spectra.png. Exit status 3 when no
    fit of a table converged (its report says how they ended, first).
    """
    if print_toml:
        if target not in (*PAPER_EXPERIMENTS, *STUDIES):
            raise click.UsageError("--print-toml needs a table target (table1, table2, table3, bj)")
        click.echo(packaged_path(target).read_text(encoding="utf-8"), nl=False)
        return
    _check_scheduler(scheduler)
    opt = _options(out, Path("out/reproduction"), workers, scheduler, resume, no_progress, no_share)
    todo = [*PAPER_EXPERIMENTS, *FIGURES] if target == "all" else [target]
    try:
        with ExitStack() as stack:
            if target == "all":  # the tables share one cluster: its start-up is paid once
                opt = _with_client(opt, stack)
            _targets(todo, opt, target, runs)
    except StoreError as exc:
        raise click.ClickException(str(exc)) from None
    except OSError as exc:  # a figure or index that cannot be written
        raise click.ClickException(f"cannot write into {opt.out}: {exc}") from None
    _exit_if_empty(opt)


def _with_client(opt: _Options, stack: ExitStack) -> _Options:
    """``opt`` with a Dask client for all its tables (unchanged for one local worker)."""
    try:
        client = stack.enter_context(dask_client(opt.workers, opt.scheduler))
    except OSError as exc:  # an unreachable --scheduler
        raise click.ClickException(f"cannot run the tables: {exc}") from None
    return dataclasses.replace(opt, client=client)


def _targets(todo: list[str], opt: _Options, target: str, runs: int | None) -> None:
    """Run, report and draw each item of ``todo`` (tables, studies, figures) in order."""
    for item in todo:
        if item in PAPER_EXPERIMENTS:
            exp = _packaged(item, runs)
            _study(exp, opt, _command(["reproduce", target], exp.runs, opt.out)).close()
        elif item in STUDIES:
            exp = _packaged(item, runs)
            with _study(exp, opt, _command(["reproduce", target], exp.runs, opt.out)) as store:
                path = spectra_figure(opt.out, exp, store.estimates(exp.runs))
            click.echo(f"{item} spectra -> {path}")
        elif item == "fig5":
            exp = _packaged("table2", runs)
            with _table2_results(exp, opt, target) as store:
                path = figures.figure5(opt.out, exp, store.estimates(exp.runs))
            click.echo(f"fig5 -> {path}")
        else:
            click.echo(f"{item} -> {getattr(figures, 'figure' + item[-1])(opt.out)}")
    if any(t in FIGURES for t in todo):
        _write_figure_index(opt.out)


def _check_scheduler(scheduler: str | None) -> None:
    from ..experiments.runner import _check_address

    if scheduler is not None:
        try:
            _check_address(scheduler)
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="'--scheduler'") from None


def _packaged(name: str, runs: int | None) -> Experiment:
    exp = load_experiment(packaged_path(name))
    return dataclasses.replace(exp, runs=runs) if runs is not None else exp


def _table2_results(exp: Experiment, opt: _Options, target: str) -> Store:
    """The Table 2 store in OUT, running or finishing Table 2 first if needed."""
    path = store_path(exp, opt.out)
    if path.is_file():
        try:
            with Store(path, exp, resume=True) as store:
                done = store.done()
            if all((c.name, r) in done for c in exp.cases for r in range(exp.runs)):
                return Store(path, exp, resume=True)
        except StoreError as exc:
            raise click.ClickException(str(exc)) from None
    return _study(exp, opt, _command(["reproduce", target], exp.runs, opt.out))


def _write_figure_index(out: Path) -> None:
    lines = ["# Figures 1-5 of Eng & Gustafsson, reproduced", ""]
    for name in FIGURES:
        if (out / f"{name}.png").exists():
            lines += [f"![{name}]({name}.png)", "", figures.CAPTIONS[name], ""]
    text = "\n".join(lines)
    atomic_write(out / "figures.md", lambda fh: fh.write(text))


@main.command(short_help="Run the Monte Carlo study defined in EXPERIMENT (a TOML file).")
@click.argument("experiment", type=click.Path(dir_okay=False, path_type=Path))
@_common
def run(
    experiment: Path,
    runs: int | None,
    workers: int | None,
    scheduler: str | None,
    out: Path | None,
    resume: bool,
    no_progress: bool,
    no_share: bool,
) -> None:
    """Run the Monte Carlo study defined in EXPERIMENT (a TOML file).

    Start from a packaged definition: `jitterid reproduce table2 --print-toml > my.toml`.
    The file is checked completely before any work starts. Exit status 3 when no fit
    converged (the report says how they ended, first).
    """
    try:
        exp = load_experiment(experiment)
    except ExperimentError as exc:
        raise click.ClickException(str(exc)) from exc
    if runs is not None:
        exp = dataclasses.replace(exp, runs=runs)
    _check_scheduler(scheduler)
    opt = _options(out, Path("out") / exp.name, workers, scheduler, resume, no_progress, no_share)
    _study(exp, opt, _command(["run", str(experiment)], exp.runs, opt.out)).close()
    _exit_if_empty(opt)
