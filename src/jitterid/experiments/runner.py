"""The Monte Carlo engine: realizations in-process, on local worker processes or on a Dask cluster.

Realization ``r`` of case ``c`` draws its input, jitter and noise from
``SeedSequence(seed).spawn(n_cases)[c].spawn(runs)[r]``, that is
``SeedSequence(seed, spawn_key=(c, r))`` (the stream depends on neither the number of
realizations nor the worker that runs it, and is made only when the realization runs, so
``--runs`` costs no memory up front), and every fit runs single-threaded, so the results are
the same bit for bit with 1 worker, many workers or a remote cluster. The parent process is
the only writer of the store and commits each realization as soon as it arrives; at most a
few realizations per worker are in flight at once.

:func:`local_workers` decides how many local processes run: never more than the realizations
left, and one means this process (no Dask). A local cluster listens on the loopback interface
only (127.0.0.1) and serves no dashboard and no HTTP endpoint (:func:`local_cluster`).
Connecting to a ``scheduler`` runs code on that cluster and unpickles what it sends back: use
only a cluster you trust as you trust your own machine.

Within a realization the BCLS search runs once and is shared by every method that starts
from it (``fit(..., start=bcls_result)``, identical numbers to separate calls); the stored
fit time of those methods excludes that shared stage. With ``crb = true`` the first
:meth:`Experiment.bound_runs` realizations of each case (``crb_runs``, every one by default)
also store a row of method ``crb``: the true parameters with, as ``stderr``, the square
roots of the Cramer-Rao bound's diagonal for that realization's input (and, for a jitter
family, the bound on sigma by the delta method). The bound depends on the input, which each
realization draws anew, so there is no single bound per case: the report averages these
per-realization bounds (not their Fisher informations) over the realizations that have one.
``share=False`` (:func:`realize`, :func:`run_experiment`, ``--no-share``) undoes both
savings, every method searching from scratch and every realization storing its bound: the
same numbers, at the cost before the sharing (for benchmarks and checks).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from .. import finite_diff
from .._threads import single_thread
from ..estimation.bounds import crb
from ..estimation.estimators import as_estimator
from ..estimation.fit import fit
from ..estimation.result import FitResult
from ..inputs import Input
from ..jitter.laws import JitterFamily, JitterLaw
from ..noise.models import NoiseStructure
from ..simulate import SampledData, simulate
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .config import Experiment, split_method
from .store import Estimate, Store

if TYPE_CHECKING:
    from dask.distributed import Client, LocalCluster

__all__ = [
    "RunSummary",
    "dask_client",
    "default_workers",
    "local_cluster",
    "local_workers",
    "realization_data",
    "realize",
    "run_experiment",
    "seed_stream",
    "seed_streams",
    "store_path",
]

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


def seed_stream(seed: int, case_index: int, realization: int) -> np.random.SeedSequence:
    """The stream of one (case, realization): ``seed_streams(seed, ...)[case][realization]``,
    made on its own (no list of every stream)."""
    return np.random.SeedSequence(seed, spawn_key=(case_index, realization))


def realize(
    exp: Experiment,
    case_index: int,
    realization: int,
    stream: np.random.SeedSequence,
    share: bool = True,
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
    share : bool
        Default True: one BCLS search shared by the methods that start from it, and the
        bound only on the first :meth:`Experiment.bound_runs` realizations. False: every
        method searches from scratch and every realization gets the bound (same numbers).

    Returns
    -------
    (list of Estimate, float)
        One estimate per method, and the realization's wall time in seconds. A fit that
        raises a ValueError or an arithmetic/linear-algebra error is recorded as a failed
        estimate with status ``ERROR`` and the error as its message.
    """
    t0 = time.perf_counter()
    case = exp.cases[case_index]
    with single_thread():
        data, u = realization_data(exp, case_index, stream)
        model = exp.system.model()
        shared: dict[str, FitResult | Exception] = {}
        rows = [
            _fit_one(
                data,
                model,
                exp.estimation_jitter(case, m),
                m,
                case.name,
                realization,
                shared if share else None,
                exp.noise.structure() if exp.noise is not None and split_method(m)[0] else None,
            )
            for m in exp.methods
        ]
        if exp.crb and (realization < exp.bound_runs() or not share):
            rows.append(_bound_row(exp, case_index, realization, u))
    return rows, time.perf_counter() - t0


def realization_data(
    exp: Experiment, case_index: int, stream: np.random.SeedSequence
) -> tuple[SampledData, Input]:
    """The data of one realization as :func:`realize` fits them, and its input.

    Parameters
    ----------
    exp : Experiment
        The definition.
    case_index : int
        Which case.
    stream : numpy.random.SeedSequence
        The realization's own stream (:func:`seed_stream`).

    Returns
    -------
    (SampledData, Input)
        The samples (without the noise std where the definition says it is not known) and
        the input that drove them.
    """
    rng = np.random.default_rng(stream)
    u = exp.input.build(exp.duration, rng)
    noise = exp.noise.true_model() if exp.noise is not None else None
    data = simulate(
        exp.system.true_system(),
        u,
        exp.cases[case_index].law.build(),
        exp.T,
        exp.N,
        exp.noise_std,
        rng,
        noise_model=noise,
    )
    if not exp.noise_known:
        data = SampledData(data.y, data.T, data.u, None, data.instants)
    return data, u


def _bcls_stage(
    data: SampledData,
    model: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    shared: dict[str, FitResult | Exception],
    key: str = "bcls",
) -> FitResult:
    """The realization's BCLS fit, computed once per jitter model ``key`` (an error is
    re-raised for every method)."""
    if key not in shared:
        try:
            shared[key] = fit(data, model, jitter, "bcls")
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            shared[key] = exc
    pre = shared[key]
    if isinstance(pre, Exception):
        raise pre
    return pre


def _fit_one(
    data: SampledData,
    model: ModelStructure | TransferFunction,
    jitter: JitterLaw | JitterFamily,
    method: str,
    case_name: str,
    realization: int,
    shared: dict[str, FitResult | Exception] | None,
    noise: NoiseStructure | None = None,
) -> Estimate:
    """One method's fit as an Estimate; ``shared`` holds the realization's BCLS stage (None:
    the method searches from scratch, its own BCLS stage included)."""
    t0 = time.perf_counter()
    prefix, criterion = split_method(method)  # "bj-gaussian": gaussian with the noise model
    try:
        est = as_estimator(criterion)
        if est.ignores_jitter:  # ls: no jitter, no shared stage
            res = fit(data, model, jitter, est)
        elif shared is None:
            res = fit(data, model, jitter, criterion, noise=noise)
        else:
            # 'jbj-' methods fit a jitter family: their BCLS stage is not the known-law one.
            pre = _bcls_stage(
                data, model, jitter, shared, "bcls-jbj" if prefix == "jbj-" else "bcls"
            )
            own = not prefix and est == pre.estimator  # the method is the shared stage itself
            t0 = t0 if own else time.perf_counter()
            # A failed BCLS search cannot seed the others (nor can it seed an estimator with
            # another first stage): they search on their own.
            seeds = pre.success and est.first_stage() == pre.estimator
            res = (
                pre
                if own
                else fit(data, model, jitter, est, start=pre if seeds else None, noise=noise)
            )
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
        float("nan") if res.noise_std is None else res.noise_std,  # ls: no noise used
        res.cost,
        res.success,
        res.status.name,
        res.message,
        res.nfev,
        time.perf_counter() - t0,
    )


def _bound_row(exp: Experiment, case_index: int, realization: int, u: Input) -> Estimate:
    """The Cramer-Rao bound at the truth for this realization's input, as an Estimate row
    (``NOT_APPLICABLE`` when the true law is outside the estimated family)."""
    t0 = time.perf_counter()
    case = exp.cases[case_index]
    jitter = exp.estimation_jitter(case)
    truth = dict(exp.system.truth)
    law = case.law.build()
    family = isinstance(jitter, JitterFamily)
    if family and case.law.kind != exp.jitter_model:
        return Estimate(
            case.name,
            realization,
            "crb",
            {},
            {},
            float(law.std),
            exp.noise_std,
            np.nan,
            False,
            "NOT_APPLICABLE",
            "the true jitter law is outside the estimated family",
            0,
            time.perf_counter() - t0,
        )
    jpar = dict(case.law.params) if family else {}
    names = [*jpar, *truth]
    x = np.array([*jpar.values(), *truth.values()], dtype=float)
    with single_thread():
        bound = crb(exp.system.model(), jitter, u, exp.T, exp.N, exp.noise_std, x)
    stderr = dict(zip(names, np.sqrt(np.diag(bound)).tolist(), strict=True))
    if family:
        assert isinstance(jitter, JitterFamily)
        g = _std_gradient(jitter, x[: len(jpar)])
        k = len(jpar)
        stderr["sigma"] = float(np.sqrt(g @ bound[:k, :k] @ g))
    return Estimate(
        case.name,
        realization,
        "crb",
        dict(zip(names, x.tolist(), strict=True)),
        stderr,
        float(law.std),
        exp.noise_std,
        np.nan,
        True,
        "BOUND",
        "square roots of the Cramer-Rao bound's diagonal at the truth",
        0,
        time.perf_counter() - t0,
    )


def _std_gradient(family: JitterFamily, p: np.ndarray) -> np.ndarray:
    """d sigma / d p of a family's law (:func:`jitterid.finite_diff.derivative`: central,
    one-sided of second order at a bound)."""
    p = np.asarray(p, dtype=float)

    def std(v: np.ndarray) -> np.ndarray:
        return np.array([family.law(v.tolist()).std])

    return np.array(
        [
            finite_diff.derivative(std, p, i, family.bounds[i], rel=1e-6, floor=1e-3)[0]
            for i in range(p.size)
        ]
    )


def run_experiment(
    exp: Experiment,
    out: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    share: bool = True,
    client: Client | None = None,
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
    share : bool
        See :func:`realize` (False: no shared BCLS stage, the bound on every realization).
    client : dask.distributed.Client, optional
        A client to send the realizations to instead of starting a cluster (``workers`` and
        ``scheduler`` are then ignored): :func:`dask_client` opens one for several
        experiments, so that they share its worker processes and pay their start-up once.

    Returns
    -------
    RunSummary
    """
    local_workers(workers)  # refuses a count that is not an integer >= 1
    if scheduler is not None:
        _check_address(scheduler)
    t0 = time.perf_counter()
    with Store(store_path(exp, out), exp, resume=resume) as store:
        done = store.done()
        names = {case.name for case in exp.cases}
        already = sum(1 for c, r in done if c in names and r < exp.runs)
        total = exp.runs * len(exp.cases)
        todo = total - already
        # Realization-major order: a run stopped early leaves every case with (nearly) the
        # same number of realizations, so an interim report compares like with like. The
        # tasks and their streams are made one at a time, as they are sent.
        tasks = (
            (ci, r, seed_stream(exp.seed, ci, r))
            for r in range(exp.runs)
            for ci, case in enumerate(exp.cases)
            if (case.name, r) not in done
        )
        bar = tqdm(
            total=total,
            initial=already,
            desc=exp.name,
            unit="realization",
            disable=not progress,
            dynamic_ncols=True,
        )
        with bar:
            for rows, elapsed in _execute(exp, tasks, todo, workers, scheduler, share, client):
                store.add_realization(rows, elapsed)
                bar.update(1)
    return RunSummary(store_path(exp, out), total, already, todo, time.perf_counter() - t0)


def _check_address(scheduler: str) -> None:
    """Refuse what cannot be a Dask scheduler address before trying to connect."""
    from urllib.parse import urlsplit

    text = scheduler.strip() if isinstance(scheduler, str) else ""
    try:
        parts = urlsplit(text if "://" in text else f"tcp://{text}")
        ok = bool(parts.hostname) and parts.port is not None and " " not in text
    except ValueError:
        ok = False
    if not ok:
        raise ValueError(
            f"scheduler {scheduler!r} is not a Dask scheduler address; give one such as "
            "tcp://10.0.0.5:8786 (host and port)"
        )


def default_workers() -> int:
    """The worker count when none is given: one per CPU this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def local_workers(workers: int, count: int | None = None) -> int:
    """How many local worker processes run ``count`` realizations with ``workers`` asked for.

    The one place that decides it: never more processes than realizations (``count``, when
    known), and 1 means this process, no Dask (:func:`dask_client` gives no client then).

    Parameters
    ----------
    workers : int
        The number asked for (>= 1).
    count : int, optional
        The number of realizations left to run; None when not known yet.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1; got {workers!r}")
    return workers if count is None else max(1, min(workers, count))


def local_cluster(workers: int, dashboard_address: str | None = None) -> LocalCluster:
    """A local Dask cluster of ``workers`` single-threaded processes, listening on loopback
    only (127.0.0.1).

    Parameters
    ----------
    workers : int
        Worker processes.
    dashboard_address : str, optional
        None (default): no dashboard and no HTTP endpoint. Dask's scheduler and workers always
        open an HTTP server; here it listens on a free loopback port (never a fixed one such as
        8787, which another process may hold) and serves no route (no ``/info``, ``/json``,
        ``/metrics`` or logs). An address (e.g. ``"127.0.0.1:8787"``) asks for Dask's usual
        dashboard and endpoints there.
    """
    import dask
    from dask.distributed import LocalCluster

    kwargs: dict[str, Any] = {
        "n_workers": workers,
        "threads_per_worker": 1,
        "processes": True,
        "host": "127.0.0.1",
        "silence_logs": logging.ERROR,
    }
    # The worker processes (started by the nannies) take the configuration set here. Dask
    # sets MALLOC_TRIM_THRESHOLD_=65536 in them, which turns off glibc's dynamic mmap
    # threshold: every array above 128 kB is then mapped and unmapped afresh (page faults),
    # and a 2^16-sample meter record took 2.5 x its CPU time in a worker (0.17 s against
    # 0.069 s; a batch on 2 workers ran slower than on 1). Kept: one BLAS/OpenMP thread.
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    config: dict[str, Any] = {"distributed.nanny.pre-spawn-environ": environ}
    if dashboard_address is not None:
        with dask.config.set(config):
            return LocalCluster(dashboard_address=dashboard_address, **kwargs)
    config["distributed.scheduler.http.routes"] = []
    config["distributed.worker.http.routes"] = []
    with dask.config.set(config):
        return LocalCluster(dashboard_address="127.0.0.1:0", **kwargs)


@contextmanager
def dask_client(workers: int, scheduler: str | None = None) -> Iterator[Client | None]:
    """A Dask client for :func:`run_experiment` ``(..., client=)``: connected to
    ``scheduler``, or to a :func:`local_cluster` of ``workers`` processes; None (run in this
    process) for one local worker (see :func:`local_workers`)."""
    if scheduler is None and local_workers(workers) == 1:
        yield None
        return
    from dask.distributed import Client

    with ExitStack() as stack:
        if scheduler is not None:
            try:
                client = stack.enter_context(Client(scheduler, timeout="20s"))
            except (OSError, ValueError, TimeoutError) as exc:
                raise OSError(
                    f"cannot connect to the Dask scheduler {scheduler!r} ({exc}); check that it "
                    "runs and the address is right"
                ) from None
        else:
            cluster = stack.enter_context(local_cluster(workers))
            client = stack.enter_context(Client(cluster))
        yield client


def _execute(
    exp: Experiment,
    tasks: Iterable[Task],
    count: int,
    workers: int,
    scheduler: str | None,
    share: bool = True,
    client: Client | None = None,
) -> Iterator[tuple[list[Estimate], float]]:
    """Results of the ``count`` ``tasks`` in completion order (a few per worker in flight)."""
    if count <= 0:
        return
    with ExitStack() as stack:
        if client is None:
            # a local cluster no larger than the work (a remote one is what it is)
            n = workers if scheduler is not None else local_workers(workers, count)
            client = stack.enter_context(dask_client(n, scheduler))
        if client is None:  # one local worker: this process
            for ci, r, stream in tasks:
                yield realize(exp, ci, r, stream, share)
        else:
            yield from _submit(client, exp, tasks, share)


def _submit(
    client: Client, exp: Experiment, tasks: Iterable[Task], share: bool
) -> Iterator[tuple[list[Estimate], float]]:
    """The tasks on ``client``'s workers, a few per worker in flight, in completion order."""
    from dask.distributed import as_completed

    n = max(len(client.scheduler_info().get("workers", {})), 1)
    it = iter(tasks)
    pending = as_completed()
    for ci, r, stream in islice(it, 2 * n + 2):
        pending.add(client.submit(realize, exp, ci, r, stream, share, pure=False))
    for fut in pending:
        result = fut.result()
        fut.release()
        nxt = next(it, None)
        if nxt is not None:
            pending.add(client.submit(realize, exp, *nxt, share, pure=False))
        yield result
