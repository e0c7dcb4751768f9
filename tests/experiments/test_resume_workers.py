"""Issue 25, items 1, 9 and 10: one place decides the worker count (a resume with fewer
realizations left than workers runs them, in this process), and a local cluster serves no
HTTP endpoint on a fixed port."""

import socket
import sqlite3
import urllib.error
import urllib.request

import pytest
from click.testing import CliRunner

from jitterid.cli import main
from jitterid.experiments import load_experiment
from jitterid.experiments.runner import (
    dask_client,
    local_cluster,
    local_workers,
    run_experiment,
    store_path,
)
from jitterid.experiments.store import Store

DEFINITION = """
[experiment]
name = "tiny"
runs = 2
seed = 99
[sampling]
T = 1.0
N = 60
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
[estimators]
methods = ["ls"]
"""


Q = "--no-progress"


@pytest.fixture
def definition(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(DEFINITION)
    return path


def rows(exp, out):
    with Store(store_path(exp, out), exp, resume=True) as store:
        return store.estimates()


def test_local_workers_is_never_more_than_the_work_and_one_means_no_dask():
    assert local_workers(4, 1) == 1
    assert local_workers(2, 5) == 2
    assert local_workers(3) == 3
    assert local_workers(3, 0) == 1
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="workers must be an integer >= 1"):
            local_workers(bad)
    with dask_client(1) as client:
        assert client is None


def test_fewer_realizations_than_workers_run_in_this_process(definition, tmp_path):
    """`run --runs 1 --workers 2` crashed with `internal error (AssertionError: )`."""
    exp = load_experiment(definition)
    run_experiment(exp, tmp_path / "ref", workers=1, progress=False)
    one = exp.__class__(**{**exp.__dict__, "runs": 1})
    summary = run_experiment(one, tmp_path / "a", workers=2, progress=False)
    assert summary.new == 1
    ref = [e for e in rows(exp, tmp_path / "ref") if e.realization == 0]
    got = rows(one, tmp_path / "a")
    assert len(got) == len(ref) == 1
    assert got[0].same_numbers(ref[0])


def test_a_resume_with_one_realization_missing_and_two_workers(definition, tmp_path):
    exp = load_experiment(definition)
    run_experiment(exp, tmp_path, workers=1, progress=False)
    before = rows(exp, tmp_path)
    with sqlite3.connect(store_path(exp, tmp_path)) as con:
        tables = [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")]
        for table in tables:
            cols = [c[1] for c in con.execute(f"PRAGMA table_info({table})")]
            if "realization" in cols:
                con.execute(f"DELETE FROM {table} WHERE realization = 1")
    res = CliRunner().invoke(
        main,
        ["run", str(definition), "--workers", "2", "--resume", "--out", str(tmp_path), Q],
    )
    assert res.exit_code == 0, res.output
    assert "(1 already stored, 1 new" in res.output
    after = rows(exp, tmp_path)
    assert len(after) == len(before) == 2
    for a, b in zip(after, before, strict=True):
        assert a.same_numbers(b)


def test_cli_run_with_more_workers_than_realizations(definition, tmp_path):
    res = CliRunner().invoke(
        main,
        ["run", str(definition), "--runs", "1", "--workers", "2", "--out", str(tmp_path), Q],
    )
    assert res.exit_code == 0, res.output
    assert "internal error" not in res.output


def test_the_local_cluster_serves_no_http_and_needs_no_fixed_port():
    """Dask's scheduler opened 127.0.0.1:8787 with /info, /json, /metrics and the logs, and
    warned (an error under this suite) when another process held the port."""
    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen(1)
    except OSError:  # someone else holds 8787 already: the same situation
        pass
    try:
        with local_cluster(2) as cluster:
            http = cluster.scheduler.http_server
            assert http.address == "127.0.0.1"
            assert http.port != 8787
            for route in ("/info/main/workers.html", "/json/counts.json", "/metrics", "/health"):
                with pytest.raises(urllib.error.HTTPError) as err:
                    urllib.request.urlopen(f"http://127.0.0.1:{http.port}{route}", timeout=10)
                assert err.value.code == 404
                err.value.close()
            workers = cluster.scheduler_info["workers"]
            assert len(workers) == 2
            for info in workers.values():
                port = info["services"].get("dashboard")
                with pytest.raises(urllib.error.HTTPError) as err:
                    urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10)
                assert err.value.code == 404
                err.value.close()
    finally:
        holder.close()
