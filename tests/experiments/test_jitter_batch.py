"""The production batch: one table of many records, resumable after kill -9, bad records as rows."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from jitterid.experiments.jitter_batch import (
    BATCH_COLUMNS,
    BatchOptions,
    BatchStore,
    find_records,
    is_multi_record,
    run_batch,
)
from jitterid.experiments.store import StoreError

T, N, F, SIGMA = 1e-3, 256, 123.0, 50e-6
OPTS = BatchOptions(method="gaussian", laws=("gaussian",), harmonics=1)
SRC = str(Path(__file__).resolve().parents[2] / "src")


def _sine(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(N) * T + SIGMA * rng.standard_normal(N)
    return np.sin(2 * np.pi * F * t + 0.3) + 1e-3 * rng.standard_normal(N)


def _csv(path: Path, y: np.ndarray) -> None:
    path.write_text("# T: 1\n# time_unit: ms\ny\n" + "".join(f"{float(v)!r}\n" for v in y))


def _folder(root: Path, n: int = 5) -> Path:
    d = root / "records"
    d.mkdir()
    for i in range(n):
        _csv(d / f"rec{i}.csv", _sine(i))
    (d / "corrupt.csv").write_text("# T: 1\ny\n0.5\nnot-a-number\n")
    (d / "notes.txt").write_text("not a record\n")
    return d


def _table(path: Path) -> list[dict]:
    with BatchStore(path, OPTS, resume=True) as store:
        rows = store.rows()
    for r in rows:
        r.pop("elapsed_s")
    return rows


def _same(a: list[dict], b: list[dict]) -> bool:
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)  # NaN == NaN


def test_a_folder_gives_one_row_per_record_and_a_corrupt_one_is_an_error_row(
    tmp_path: Path,
) -> None:
    d = _folder(tmp_path)
    s = run_batch(d, tmp_path / "out", OPTS, progress=False)
    assert (s.total, s.already_done, s.new, s.errors) == (6, 0, 6, 1)
    rows = _table(s.store)
    assert [r["record"] for r in rows] == ["corrupt.csv", *(f"rec{i}.csv" for i in range(5))]
    bad = rows[0]
    assert bad["status"] == "ERROR"
    assert "not-a-number" in bad["error"]
    assert math.isnan(bad["jitter_std_s"])
    for r in rows[1:]:
        assert r["error"] == ""
        assert r["N"] == N
        assert r["T_s"] == pytest.approx(T)
        assert r["jitter_lo95_s"] < r["jitter_std_s"] < r["jitter_hi95_s"]
        assert abs(r["jitter_std_s"] - SIGMA) < 5 * r["jitter_std_stderr_s"]
        assert math.isfinite(r["snr_db"])
        assert math.isfinite(r["enob_bits"])
        assert r["harmonics"] == 1
    # the CSV is the same table
    lines = s.csv.read_text().splitlines()
    assert lines[0].split(",") == list(BATCH_COLUMNS)
    assert len(lines) == 7


def test_a_glob_and_a_multi_record_file(tmp_path: Path) -> None:
    d = _folder(tmp_path, 2)
    assert [p.name for p in find_records(str(d / "rec*.csv"))] == ["rec0.csv", "rec1.csv"]
    ys = np.array([_sine(10 + i) for i in range(4)])
    ys[2, 7] = np.nan  # one corrupt row
    multi = tmp_path / "multi.npz"
    np.savez(multi, y=ys, metadata=json.dumps({"T": 1.0, "time_unit": "ms"}))
    assert is_multi_record(multi)
    assert not is_multi_record(d / "rec0.csv")
    s = run_batch(multi, tmp_path / "out", OPTS, progress=False)
    rows = _table(s.store)
    assert [r["record"] for r in rows] == [f"{multi}#{i}" for i in range(4)]
    assert [r["status"] == "ERROR" for r in rows] == [False, False, True, False]
    assert "NaN" in rows[2]["error"]
    # a row's numbers are those of the same record measured on its own
    one = tmp_path / "one"
    one.mkdir()
    _csv(one / "r.csv", ys[3])
    single = _table(run_batch(one, tmp_path / "out1", OPTS, progress=False).store)[0]
    for c in ("jitter_std_s", "jitter_std_stderr_s", "noise_std", "snr_db", "status"):
        assert single[c] == rows[3][c]


def test_a_truncated_multi_record_file_gives_error_rows(tmp_path: Path) -> None:
    # a .npy of 3 records without its T: the options give it
    ys = np.array([_sine(i) for i in range(3)])
    multi = tmp_path / "multi.npy"
    np.save(multi, ys)
    data = multi.read_bytes()
    multi.write_bytes(data[: len(data) - 8 * N - 100])  # the last row and a half are gone
    opts = BatchOptions(method="gaussian", laws=("gaussian",), harmonics=1, T="1ms")
    s = run_batch(multi, tmp_path / "out", opts, progress=False)
    with BatchStore(s.store, opts, resume=True) as store:
        rows = store.rows()
    assert [r["status"] == "ERROR" for r in rows] == [False, True, True]
    assert "truncated" in rows[1]["error"]
    assert "truncated" in rows[2]["error"]


def test_a_table_is_not_overwritten_and_options_are_not_mixed(tmp_path: Path) -> None:
    d = _folder(tmp_path, 1)
    run_batch(d, tmp_path / "out", OPTS, progress=False)
    with pytest.raises(StoreError, match="--resume"):
        run_batch(d, tmp_path / "out", OPTS, progress=False)
    other = BatchOptions(method="gaussian", laws=("gaussian",), harmonics=2)
    with pytest.raises(StoreError, match="other options"):
        run_batch(d, tmp_path / "out", other, resume=True, progress=False)
    s = run_batch(d, tmp_path / "out", OPTS, resume=True, progress=False)
    assert (s.already_done, s.new) == (2, 0)


@pytest.mark.parametrize(
    ("source", "words"),
    [("nowhere/at/all", "no such file"), ("empty", "holds no"), ("empty/*.csv", "matches no")],
)
def test_a_source_without_records_is_refused(tmp_path: Path, source: str, words: str) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=words):
        find_records(str(tmp_path / source))


_KILLER = """
import os, signal, sys
sys.path.insert(0, {src!r})
from jitterid.experiments.jitter_batch import BatchOptions, run_batch
count = 0
def on_row(row):
    global count
    count += 1
    if count == {k}:
        os.kill(os.getpid(), signal.SIGKILL)
run_batch({folder!r}, {out!r}, BatchOptions(method="gaussian", laws=("gaussian",), harmonics=1),
          progress=False, on_row=on_row)
"""


def test_kill_9_then_resume_equals_an_uninterrupted_run(tmp_path: Path) -> None:
    d = _folder(tmp_path)
    whole = run_batch(d, tmp_path / "whole", OPTS, progress=False)
    out = tmp_path / "killed"
    script = textwrap.dedent(_KILLER.format(src=SRC, k=3, folder=str(d), out=str(out)))
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert proc.returncode == -9, proc.stderr
    with BatchStore(out / "jitter_batch.sqlite", OPTS, resume=True) as store:
        assert store.count() == 3  # every finished row was committed before the kill
    assert not (out / "jitter_batch.csv").exists()
    resumed = run_batch(d, out, OPTS, resume=True, progress=False)
    assert (resumed.already_done, resumed.new) == (3, 3)
    assert _same(_table(resumed.store), _table(whole.store))
    assert resumed.csv.read_text().splitlines()[0] == whole.csv.read_text().splitlines()[0]


@pytest.mark.slow
def test_two_dask_workers_give_the_same_table(tmp_path: Path) -> None:
    d = _folder(tmp_path, 3)
    one = run_batch(d, tmp_path / "one", OPTS, progress=False)
    two = run_batch(d, tmp_path / "two", OPTS, workers=2, progress=False)
    assert _same(_table(one.store), _table(two.store))


def test_bad_workers_and_scheduler(tmp_path: Path) -> None:
    d = _folder(tmp_path, 1)
    with pytest.raises(ValueError, match="workers"):
        run_batch(d, tmp_path / "o", OPTS, workers=0)
    with pytest.raises(ValueError, match="scheduler"):
        run_batch(d, tmp_path / "o", OPTS, scheduler="not an address")
    assert os.path.isdir(d)


@pytest.mark.slow  # a benchmark smoke run in a subprocess (tests/README.md)
def test_the_batch_benchmark_runs_at_a_tiny_size(tmp_path: Path) -> None:
    bench = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_batch.py"
    env = dict(os.environ, PYTHONPATH=SRC)
    args = ["--records", "2", "--n", "1024", "--workers", "1", "--no-peer", "--out", str(tmp_path)]
    out = subprocess.run(
        [sys.executable, str(bench), *args],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
        env=env,
    ).stdout
    assert "jitterid batch, 1 worker(s)" in out
    assert "(0 error rows)" in out
