"""The Monte Carlo engine's promises (jitterid.experiments.runner): same numbers on any backend,
nothing lost after SIGKILL. The backends (worker processes, a Dask cluster, one client for
several runs) start processes: those tests are slow; the SIGKILL test stays in the default run."""

import logging
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

from jitterid.cli import main
from jitterid.experiments import load_experiment
from jitterid.experiments.runner import dask_client, run_experiment, store_path
from jitterid.experiments.store import Store

DEFINITION = """
[experiment]
name = "small"
runs = 6
seed = 4242
[sampling]
T = 1.0
N = 100
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = { k0 = 6.25, pr = -1.5, pi = 2.0 }
[jitter]
model = "known"
[[cases]]
name = "uniform"
law = { kind = "uniform", a = 0.5 }
[[cases]]
name = "sum2"
law = { kind = "sum_of_uniforms", n = 2, a = 0.4 }
[estimators]
methods = ["ls", "bcls"]
"""


@pytest.fixture(scope="module")
def definition(tmp_path_factory):
    path = tmp_path_factory.mktemp("def") / "small.toml"
    path.write_text(DEFINITION)
    return path


@pytest.fixture(scope="module")
def reference(definition, tmp_path_factory):
    """The uninterrupted, in-process (no Dask) run: the referee of every other run."""
    exp = load_experiment(definition)
    out = tmp_path_factory.mktemp("ref")
    run_experiment(exp, out, workers=1, progress=False)
    with Store(store_path(exp, out), exp, resume=True) as store:
        return store.estimates()


def stored(definition, out):
    exp = load_experiment(definition)
    with Store(store_path(exp, out), exp, resume=True) as store:
        return store.estimates()


def assert_same(rows, reference):
    assert len(rows) == len(reference) == 6 * 2 * 2
    keys = [(e.case_name, e.realization, e.method) for e in rows]
    assert len(set(keys)) == len(keys)  # no duplicates
    for a, b in zip(rows, reference, strict=True):
        assert a.same_numbers(b), (a, b)


def run_cli(args):
    res = CliRunner().invoke(main, [*args, "--no-progress"])
    assert res.exit_code == 0, res.output
    return res.output


@pytest.mark.slow  # ~6 s of CPU (two worker processes)
def test_two_local_worker_processes_give_the_in_process_numbers(definition, reference, tmp_path):
    run_cli(["run", str(definition), "--workers", "2", "--out", str(tmp_path)])
    assert_same(stored(definition, tmp_path), reference)


@pytest.mark.slow  # ~10 s of CPU (a Dask cluster)
def test_a_dask_cluster_on_loopback_gives_the_in_process_numbers(definition, reference, tmp_path):
    from dask.distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        run_cli(
            [
                "run",
                str(definition),
                "--scheduler",
                cluster.scheduler_address,
                "--out",
                str(tmp_path),
            ]
        )
    assert_same(stored(definition, tmp_path), reference)


@pytest.mark.slow  # ~14 s of CPU (a Dask cluster)
def test_one_client_for_several_runs_gives_the_in_process_numbers(definition, reference, tmp_path):
    """`reproduce all` sends its tables to one cluster (dask_client): each run on it gives
    the in-process numbers, and so does --no-share."""
    exp = load_experiment(definition)
    with dask_client(2) as client:
        assert client is not None
        for out in ("a", "b"):
            run_experiment(exp, tmp_path / out, progress=False, client=client)
    for out in ("a", "b"):
        assert_same(stored(definition, tmp_path / out), reference)
    run_cli(["run", str(definition), "--workers", "1", "--no-share", "--out", str(tmp_path / "c")])
    assert_same(stored(definition, tmp_path / "c"), reference)


def count_done(db):
    try:
        with sqlite3.connect(db, timeout=5) as con:
            return con.execute("SELECT COUNT(*) FROM realizations").fetchone()[0]
    except sqlite3.OperationalError:  # not created yet
        return 0


def test_sigkill_then_resume_equals_an_uninterrupted_run(definition, reference, tmp_path):
    db = tmp_path / "small.sqlite"
    cmd = [
        sys.executable,
        "-c",
        "from jitterid.cli import main; main()",
        "run",
        str(definition),
        "--workers",
        "1",
        "--out",
        str(tmp_path),
        "--no-progress",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while count_done(db) < 2 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    at_kill = count_done(db)
    assert 2 <= at_kill < 12, f"the kill should land mid-run; {at_kill} of 12 were stored"
    out = run_cli(["run", str(definition), "--workers", "1", "--out", str(tmp_path), "--resume"])
    assert f"({at_kill} already stored, {12 - at_kill} new" in out
    assert_same(stored(definition, tmp_path), reference)


def _worker_environ() -> dict[str, str | None]:
    keys = ("MALLOC_TRIM_THRESHOLD_", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")
    return {k: os.environ.get(k) for k in keys}


def test_local_workers_keep_glibc_s_dynamic_mmap_threshold():
    """Dask's nannies set MALLOC_TRIM_THRESHOLD_=65536 in their workers, which turns off
    glibc's dynamic mmap threshold (every array above 128 kB mapped afresh): a 2^16-sample
    meter record took 2.5 x its CPU time in a worker, and a batch on 2 workers ran slower
    than on 1 (benchmarks/bench_batch.py: 8.6 against 13.8 records/s). The local cluster's
    workers run without it, one BLAS/OpenMP thread each."""
    with dask_client(2) as client:
        assert client is not None
        envs = client.run(_worker_environ)
    assert len(envs) == 2
    for env in envs.values():
        assert env["MALLOC_TRIM_THRESHOLD_"] is None
        assert env["OPENBLAS_NUM_THREADS"] == "1"
        assert env["OMP_NUM_THREADS"] == "1"
