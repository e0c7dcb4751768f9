"""The Monte Carlo engine: realizations in-process, on local worker processes or on a Dask cluster.

Realization ``r`` of case ``c`` draws its input, jitter and noise from
``SeedSequence(seed).spawn(n_cases)[c].spawn(runs)[r]`` (the stream depends on neither the
number of realizations nor the worker that runs it), and every fit runs single-threaded, so
the results are the same bit for bit with 1 worker, many workers or a remote cluster.
The parent process is the only writer of the store and commits each realization as soon as
it arrives.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator, Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..distributions import JitterFamily, JitterLaw
from ..estimate import fit
from ..models import TransferFunction
from ..simulate import SampledData, simulate
from ..structures import ModelStructure
from .config import Experiment
from .store import Estimate, Store

__all__ = ["RunSummary", "realize", "run_experiment", "seed_streams", "store_path"]

Task = tuple[int, int, np.random.SeedSequence]  # (case index, realization, its stream)


@dataclass(frozen=True)
class RunSummary:
    """What a call of :func:`run_experiment` did."""

    store: Path
    total: int
    already_done: int
    new: int
    wall_s: float


def store_path(exp: Experiment, out: str | Path) -> Path:
    """The experiment's store file in folder ``out``: ``<out>/<name>.sqlite``."""
    return Path(out) / f"{exp.name}.sqlite"


def seed_streams(seed: int, n_cases: int, runs: int) -> list[list[np.random.SeedSequence]]:
    """One independent stream per (case, realization), by ``SeedSequence.spawn``."""
    return [case.spawn(runs) for case in np.random.SeedSequence(seed).spawn(n_cases)]


def realize(
    exp: Experiment, case_index: int, realization: int, stream: np.random.SeedSequence
) -> tuple[list[Estimate], float]:
    """Simulate one realization and fit every estimator to it.

    Parameters
    ----------
    exp : Experiment
        The definition.
    case_index, realization : int
        Which case and which realization.
    stream : numpy.random.SeedSequence
        The realization's own stream (from :func:`seed_streams`).

    Returns
    -------
    (list of Estimate, float)
        One estimate per method, and the realization's wall time in seconds. A fit that
        raises a ValueError or an arithmetic/linear-algebra error is recorded as a failed
        estimate with status ``ERROR`` and the error as its message.
    """
    t0 = time.perf_counter()
    case = exp.cases[case_index]
    rng = np.random.default_rng(stream)
    with threadpool_limits(limits=1):
        u = exp.input.build(exp.duration, rng)
        data = simulate(
            exp.system.true_system(), u, case.law.build(), exp.T, exp.N, exp.noise_std, rng
        )
        if not exp.noise_known:
            data = SampledData(data.y, data.T, data.u, None, data.instants)
        model, jitter = exp.system.model(), exp.estimation_jitter(case)
        rows = [_fit_one(data, model, jitter, m, case.name, realization) for m in exp.methods]
    return rows, time.perf_counter() - t0


def _fit_one(
    data: SampledData,
    model: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str,
    case_name: str,
    realization: int,
) -> Estimate:
    t0 = time.perf_counter()
    try:
        res = fit(data, model, jitter, method)
        stderr = res.stderr
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return Estimate(
            case_name,
            realization,
            method,
            {},
            {},
            np.nan,
            np.nan,
            np.nan,
            False,
            "ERROR",
            f"{type(exc).__name__}: {exc}",
            0,
            time.perf_counter() - t0,
        )
    return Estimate(
        case_name,
        realization,
        method,
        res.params,
        stderr,
        res.jitter_std,
        res.noise_std,
        res.cost,
        res.success,
        res.status.name,
        res.message,
        res.nfev,
        time.perf_counter() - t0,
    )


def run_experiment(
    exp: Experiment,
    out: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> RunSummary:
    """Run the realizations of ``exp`` not yet in its store, committing each one at once.

    Parameters
    ----------
    exp : Experiment
        The definition (``exp.runs`` realizations of every case).
    out : str or Path
        Output folder; the store is :func:`store_path` ``(exp, out)``.
    workers : int
        1: run in this process, no Dask. More: a local Dask cluster of that many
        single-threaded worker processes (they are started by ``spawn``: a script that
        calls this needs the usual ``if __name__ == "__main__":`` guard).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:port``); ``workers`` is then
        ignored and the cluster's workers (which need jitterid installed) do the work.
    resume : bool
        Continue a store that already holds results (only missing realizations are run).
    progress : bool
        Show a tqdm progress bar on stderr.

    Returns
    -------
    RunSummary
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1; got {workers!r}")
    if scheduler is not None and not scheduler.strip():
        raise ValueError("scheduler must be a Dask scheduler address such as tcp://host:8786")
    t0 = time.perf_counter()
    streams = seed_streams(exp.seed, len(exp.cases), exp.runs)
    with Store(store_path(exp, out), exp, resume=resume) as store:
        done = store.done()
        tasks = [
            (ci, r, streams[ci][r])
            for ci, case in enumerate(exp.cases)
            for r in range(exp.runs)
            if (case.name, r) not in done
        ]
        total = exp.runs * len(exp.cases)
        bar = tqdm(
            total=total,
            initial=total - len(tasks),
            desc=exp.name,
            unit="realization",
            disable=not progress,
            dynamic_ncols=True,
        )
        with bar:
            for rows, elapsed in _execute(exp, tasks, workers, scheduler):
                store.add_realization(rows, elapsed)
                bar.update(1)
    return RunSummary(
        store_path(exp, out), total, total - len(tasks), len(tasks), time.perf_counter() - t0
    )


def _execute(
    exp: Experiment, tasks: Sequence[Task], workers: int, scheduler: str | None
) -> Iterator[tuple[list[Estimate], float]]:
    """Results of ``tasks`` in completion order."""
    if not tasks:
        return
    if scheduler is None and workers == 1:
        for ci, r, stream in tasks:
            yield realize(exp, ci, r, stream)
        return
    from dask.distributed import Client, LocalCluster, as_completed

    with ExitStack() as stack:
        if scheduler is not None:
            client = stack.enter_context(Client(scheduler))
        else:
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=min(workers, len(tasks)),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",  # a free port: never clash with another cluster
                    silence_logs=logging.ERROR,
                )
            )
            client = stack.enter_context(Client(cluster))
        futures = [
            client.submit(realize, exp, ci, r, stream, pure=False) for ci, r, stream in tasks
        ]
        for fut in as_completed(futures):
            yield fut.result()
            fut.release()
