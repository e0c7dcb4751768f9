"""The command line run unattended: damaged or absurd files, TOML definitions and sizes, damaged
stores and full or read-only disks, units of times, and safe defaults (loopback only, escaped
reports). Every case that once ended in a traceback, an out-of-memory kill, a hang, a lost fit,
a silent unit error or an open port (issue 15, B-E), rebuilt from generated data. Each ends in a
non-zero exit with a one-line message naming the file or option and the fix (no traceback), or
in a correct result."""

from __future__ import annotations

import copy
import dataclasses
import errno
import json
import os
import sqlite3
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

import jitterid as ji
from jitterid import _checks
from jitterid.cli import INTERNAL, main
from jitterid.cli._specs import parse_jitter
from jitterid.experiments import runner as runner_mod
from jitterid.experiments.loader import load_experiment, parse_experiment
from jitterid.experiments.runner import (
    local_cluster,
    run_experiment,
    seed_stream,
    seed_streams,
    store_path,
)
from jitterid.experiments.store import Estimate, Store, StoreError
from jitterid.io import DataFileError, load, save_data

TINY = """
[experiment]
name = "tiny"
runs = 2
seed = 11
[sampling]
T = 1.0
N = 16
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = { k0 = 6.25, pr = -1.5, pi = 2.0 }
[jitter]
model = "known"
[[cases]]
name = "u"
law = { kind = "uniform", a = 0.5 }
[estimators]
methods = ["ls"]
"""


def run(*args: object) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


def refused(res: Result, *words: str) -> str:
    """A non-zero exit, one clean error message containing ``words``, no traceback."""
    assert res.exit_code not in (0, None), res.output
    assert isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in res.output
    assert INTERNAL not in res.output, res.output
    err = [ln for ln in res.output.splitlines() if ln.startswith("Error")]
    assert err, res.output
    for w in words:
        assert w in res.output, (w, res.output)
    return err[-1]


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("lab")
    res = run("simulate", "--out", d, "--N", "40", "--seed", "2")
    assert res.exit_code == 0, res.output
    return d


def _csv(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _tiny_toml(path: Path, **changes: object) -> Path:
    text = TINY
    for key, value in changes.items():
        lines = [ln for ln in text.splitlines() if not ln.startswith(f"{key} =")]
        at = next(
            i
            for i, ln in enumerate(lines)
            if ln.strip()
            == {
                "runs": "[experiment]",
                "seed": "[experiment]",
                "T": "[sampling]",
                "N": "[sampling]",
                "mean_hold": "[input]",
            }[key]
        )
        lines.insert(at + 1, f"{key} = {value}")
        text = "\n".join(lines)
    path.write_text(text, encoding="utf-8")
    return path


def tiny():
    return parse_experiment(copy.deepcopy(tomllib.loads(TINY)), "tiny.toml")


# ------------------------------------------------------------------------- C: files


def test_deeply_nested_json_sidecar(lab, tmp_path):
    data = tmp_path / "d.csv"
    data.write_bytes((lab / "data.csv").read_bytes())
    (tmp_path / "d.json").write_text("[" * 100_000 + "]" * 100_000)
    msg = refused(run("detect", data, "--input", lab / "input.csv", "--model", "polepair"))
    assert "d.json" in msg
    assert "nested too deeply" in msg


def test_deeply_nested_npz_metadata_and_a_member_that_is_not_an_array(tmp_path):
    t = np.arange(8.0)
    np.savez(tmp_path / "a.npz", t=t, y=t, u=t, metadata=np.array("[" * 50_000 + "]" * 50_000))
    msg = refused(run("detect", tmp_path / "a.npz", "--model", "polepair"))
    assert "a.npz" in msg
    assert "nested too deeply" in msg
    np.savez(tmp_path / "b.npz", t=t, y=t, u=t)
    with zipfile.ZipFile(tmp_path / "b.npz", "a") as zf:
        zf.writestr("notes.txt", "hello")
    msg = refused(run("detect", tmp_path / "b.npz", "--model", "polepair"))
    assert "'notes.txt' is not a NumPy array" in msg


def _npz_with_header(path: Path, header: bytes) -> Path:
    t = np.arange(8.0)
    np.savez(path, t=t, u=t)
    magic = b"\x93NUMPY\x01\x00"
    body = header.ljust(118) + b"\n"
    with zipfile.ZipFile(path, "a") as zf:
        zf.writestr("y.npy", magic + len(body).to_bytes(2, "little") + body + b"\0" * 64)
    return path


def test_broken_npy_header_and_a_header_claiming_1e13_values(tmp_path):
    bad = _npz_with_header(tmp_path / "c.npz", b"{'descr': '<f8', 'fortran_order': False, 'sh")
    msg = refused(run("detect", bad, "--model", "polepair"))
    assert "'y.npy' has a broken .npy header" in msg
    huge = _npz_with_header(
        tmp_path / "h.npz",
        b"{'descr': '<f8', 'fortran_order': False, 'shape': (10000000000000,), }",
    )
    msg = refused(run("detect", huge, "--model", "polepair"))
    assert "10000000000000 values" in msg
    assert "truncated or corrupt" in msg


def test_bias_with_an_absurd_sigma_and_runs_beyond_any_budget(tmp_path):
    refused(run("bias", "--jitter", "gaussian:sigma=1e300"), "--jitter", "longer than any")
    refused(run("reproduce", "table1", "--runs", str(10**30), "--out", tmp_path), "--runs")
    refused(run("reproduce", "table1", "--runs", str(10**12), "--out", tmp_path), "--runs")


def test_scheduler_that_is_not_an_address(tmp_path):
    msg = refused(
        run(
            "run",
            _tiny_toml(tmp_path / "t.toml"),
            "--scheduler",
            "not an address",
            "--out",
            tmp_path / "o",
        )
    )
    assert "--scheduler" in msg
    assert "tcp://" in msg
    assert not (tmp_path / "o").exists()


def test_scheduler_help_says_trusted_code_execution():
    res = run("run", "--help")
    assert "TRUSTED CODE" in res.output
    assert "127.0.0.1" in res.output


def test_toml_not_utf8_nested_or_with_absurd_numbers(tmp_path):
    (tmp_path / "a.toml").write_bytes(TINY.replace("tiny", "t\xe9").encode("latin-1"))
    refused(run("run", tmp_path / "a.toml", "--out", tmp_path), "a.toml", "not UTF-8")
    (tmp_path / "b.toml").write_text("x = " + "[" * 50_000 + "]" * 50_000)
    refused(run("run", tmp_path / "b.toml", "--out", tmp_path), "b.toml")
    refused(run("run", _tiny_toml(tmp_path / "c.toml", T="1e300"), "--out", tmp_path), "sampling.T")
    refused(
        run("run", _tiny_toml(tmp_path / "d.toml", N="1_000_000_000_000"), "--out", tmp_path),
        "sampling.N",
        "too large",
    )
    refused(
        run("run", _tiny_toml(tmp_path / "e.toml", mean_hold="1e-12"), "--out", tmp_path),
        "input.mean_hold",
        "too large",
    )
    refused(
        run("run", _tiny_toml(tmp_path / "f.toml", runs=str(10**12)), "--out", tmp_path),
        "experiment.runs",
    )
    refused(
        run("run", _tiny_toml(tmp_path / "g.toml", seed="1" * 5000), "--out", tmp_path), "g.toml"
    )


def test_toml_sizes_under_a_small_memory_budget(tmp_path, monkeypatch):
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1e8")
    refused(
        run("run", _tiny_toml(tmp_path / "a.toml", N="1_000_000_000"), "--out", tmp_path),
        "sampling.N",
        "JITTERID_MEMORY_BUDGET",
    )
    refused(
        run("run", _tiny_toml(tmp_path / "b.toml", mean_hold="1e-9"), "--out", tmp_path),
        "input.mean_hold",
    )


def test_simulate_hold_and_n_beyond_memory_are_refused_up_front(tmp_path):
    refused(run("simulate", "--out", tmp_path / "a", "--hold", "1e-7"), "--hold", "GB")
    refused(run("simulate", "--out", tmp_path / "b", "--N", str(10**13)), "--N", "GB")
    assert not (tmp_path / "a").exists()


def test_library_size_guards():
    with pytest.raises(ValueError, match="mean hold"):
        ji.telegraph_input(1e12, 0, mean_hold=1e-3)
    with pytest.raises(ValueError, match="size"):
        ji.Uniform(0.5).sample(10**13, 0)


def test_runs_are_drawn_lazily_so_a_huge_run_count_starts_at_once(tmp_path, monkeypatch):
    # the lazy stream is the spawned one, bit for bit
    for c, r in ((0, 0), (1, 2), (2, 7)):
        a = np.random.default_rng(seed_stream(5, c, r)).random(4)
        b = np.random.default_rng(seed_streams(5, 3, 8)[c][r]).random(4)
        np.testing.assert_array_equal(a, b)

    class Stop(Exception):
        pass

    calls = []

    def fake(exp, ci, r, stream, share=True):
        calls.append(r)
        if len(calls) == 3:
            raise Stop
        row = Estimate(exp.cases[ci].name, r, "ls", {}, {}, 0.0, 0.0, 0.0, True, "OK", "", 1, 0.0)
        return [row], 0.0

    monkeypatch.setattr(runner_mod, "realize", fake)
    exp = dataclasses.replace(tiny(), runs=10**9)
    with pytest.raises(Stop):
        run_experiment(exp, tmp_path, progress=False)
    assert calls == [0, 1, 2]


# ------------------------------------------------------------------------- C: stores


def _one_run(tmp_path: Path, *extra: object) -> Result:
    return run(
        "run",
        _tiny_toml(tmp_path / "t.toml"),
        "--workers",
        "1",
        "--no-progress",
        "--out",
        tmp_path / "o",
        *extra,
    )


@pytest.mark.parametrize("damage", ["garbage", "truncated", "wrong-schema", "directory"])
def test_resume_on_a_damaged_store_is_refused_with_the_fix(tmp_path, damage):
    assert _one_run(tmp_path).exit_code == 0
    store = tmp_path / "o" / "tiny.sqlite"
    if damage == "garbage":
        store.write_bytes(np.random.default_rng(0).bytes(5000))
    elif damage == "truncated":
        store.write_bytes(store.read_bytes()[: store.stat().st_size // 3])
    elif damage == "wrong-schema":
        store.unlink()
        with sqlite3.connect(store) as db:
            db.execute("CREATE TABLE estimates (a, b)")
    else:
        store.unlink()
        store.mkdir()
    msg = refused(_one_run(tmp_path, "--resume"), "tiny.sqlite")
    assert ("move it away" in msg) or ("is a folder" in msg)


def test_resume_after_a_deleted_realization_marker_recomputes_it(tmp_path):
    assert _one_run(tmp_path).exit_code == 0
    store = tmp_path / "o" / "tiny.sqlite"
    with sqlite3.connect(store) as db:
        before = db.execute("SELECT params FROM estimates WHERE realization = 1").fetchall()
        db.execute("DELETE FROM realizations WHERE realization = 1")
    res = _one_run(tmp_path, "--resume")
    assert res.exit_code == 0, res.output
    assert "1 new" in res.output
    with sqlite3.connect(store) as db:
        after = db.execute("SELECT params FROM estimates WHERE realization = 1").fetchall()
    assert after == before


def test_a_second_writer_on_the_same_store_is_refused(tmp_path):
    exp = tiny()
    with Store(store_path(exp, tmp_path / "o"), exp):
        with pytest.raises(StoreError, match="in use by another jitterid process"):
            Store(store_path(exp, tmp_path / "o"), exp, resume=True)
        refused(_one_run(tmp_path, "--resume"), "in use by another jitterid process")
    assert _one_run(tmp_path, "--resume").exit_code == 0  # the lock went with the first writer


def test_a_full_disk_during_a_run_keeps_what_was_committed(tmp_path, monkeypatch):
    real = Store.add_realization

    def fill_up(self, rows, elapsed_s):
        """Commit, then leave no free page: the disk is full for the next realization."""
        real(self, rows, elapsed_s)
        pages = self.db.execute("PRAGMA page_count").fetchone()[0]
        self.db.execute(f"PRAGMA max_page_count = {pages}")

    monkeypatch.setattr(Store, "add_realization", fill_up)
    exp = dataclasses.replace(tiny(), runs=200)
    with pytest.raises(StoreError, match="disk space"):
        run_experiment(exp, tmp_path, progress=False)
    monkeypatch.undo()
    with Store(store_path(exp, tmp_path), exp, resume=True) as store:
        assert 0 < store.count_done() < 200


def test_an_output_folder_that_cannot_be_written(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    refused(_one_run(tmp_path, "--out", blocker / "sub"), "cannot create the results store")
    lab = tmp_path / "lab"
    assert run("simulate", "--out", lab, "--N", "20").exit_code == 0
    refused(run("simulate", "--out", blocker / "s"), "--out", "writable")
    refused(
        run(
            "fit",
            lab / "data.csv",
            "--input",
            lab / "input.csv",
            "--model",
            "polepair",
            "--jitter",
            "none",
            "--method",
            "ls",
            "--out",
            blocker / "f",
        ),
        "--out",
        "writable",
    )


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_output_folder(tmp_path):  # pragma: no cover - not as root
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        refused(_one_run(tmp_path, "--out", ro), "tiny.sqlite")
        refused(run("simulate", "--out", ro), "--out")
    finally:
        ro.chmod(0o755)


def test_a_failed_write_leaves_no_partial_file(lab, tmp_path, monkeypatch):
    import jitterid.io as jio

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(jio.os, "fsync", full)
    out = tmp_path / "f"
    msg = refused(
        run(
            "fit",
            lab / "data.csv",
            "--input",
            lab / "input.csv",
            "--model",
            "polepair",
            "--jitter",
            "none",
            "--method",
            "ls",
            "--out",
            out,
            "--no-plots",
        ),
        "No space left",
    )
    assert "--out" in msg
    assert list(out.iterdir()) == []  # no result.json, no 0-byte file, no temporary
    msg = refused(run("simulate", "--out", tmp_path / "s", "--N", "20"), "No space left")
    assert list((tmp_path / "s").iterdir()) == []


# ------------------------------------------------------------------------- C: the fit


def test_a_failing_diagnostic_does_not_throw_the_fit_away(tmp_path):
    # a step input: constant at every sampling instant, so the input-correlation test
    # cannot run; the fit itself is fine and must be written
    T, n = 1.0, 30
    u = ji.PiecewiseConstant(np.array([-3.0, -0.5, (n + 5) * T]), np.array([0.0, 1.0]))
    data = ji.simulate(
        ji.PolePairGain().system([6.25, -1.5, 2.0]),
        u,
        ji.Uniform(0.2),
        T,
        n,
        0.01,
        np.random.default_rng(0),
    )
    save_data(tmp_path / "d.csv", data)
    ji.save_input(tmp_path / "i.csv", u)
    out = tmp_path / "fit"
    res = run(
        "fit",
        tmp_path / "d.csv",
        "--input",
        tmp_path / "i.csv",
        "--model",
        "polepair",
        "--jitter",
        "known:uniform:a=0.2",
        "--method",
        "bcls",
        "--out",
        out,
        "--no-plots",
    )
    assert res.exit_code in (0, 3), res.output
    assert "Traceback" not in res.output
    assert "skipped" in res.output
    result = json.loads((out / "result.json").read_text())
    assert result["parameters"]["k0"] is not None
    assert result["diagnostics"]["skipped"]
    assert "skipped" in (out / "report.md").read_text()


def test_a_failing_jitter_test_in_detect_is_a_clean_error(lab, monkeypatch):
    from jitterid.cli import data as cli_data

    def broken(*a, **k):
        raise ValueError("the fitted model is unstable")

    monkeypatch.setattr(cli_data, "detect_jitter", broken)
    refused(
        run("detect", lab / "data.csv", "--input", lab / "input.csv", "--model", "polepair"),
        "unstable",
        "--model",
    )


def test_u_column_with_gaussian_jitter_wider_than_T_over_8_5(tmp_path):
    T, n, sigma = 1.0, 60, 0.15  # 8.5 sigma > T: the jittered last instant is past the grid
    rng = np.random.default_rng(1)
    u = ji.zoh_input(rng.choice([-0.5, 0.5], size=n + 20), T)
    data = ji.simulate(
        ji.PolePairGain().system([6.25, -1.5, 2.0]), u, ji.Gaussian(sigma), T, n, 0.01, rng
    )
    lines = ["# T: 1", "t,y,u"] + [
        f"{k * T!r},{float(data.y[k])!r},{float(u.levels[k])!r}" for k in range(n)
    ]
    _csv(tmp_path / "d.csv", "\n".join(lines) + "\n")
    out = tmp_path / "fit"
    res = run(
        "fit",
        tmp_path / "d.csv",
        "--model",
        "polepair",
        "--jitter",
        f"known:gaussian:sigma={sigma}",
        "--method",
        "bcls",
        "--out",
        out,
        "--no-plots",
    )
    assert res.exit_code in (0, 3), res.output
    report = (out / "report.md").read_text()
    assert "last value" in report  # the assumption is stated
    result = json.loads((out / "result.json").read_text())
    assert any("last value" in note for note in result["data"]["notes"])


# ------------------------------------------------------------------------- D: units


@pytest.mark.parametrize(
    ("line", "hint"),
    [("time_units: ms", "time_unit"), ("Ts: 0.5", "'T'"), ("Noise_std: 0.1", "noise_std")],
)
def test_metadata_key_typos_are_refused_with_did_you_mean(tmp_path, line, hint):
    rows = "\n".join(f"{k},{float(np.sin(k))!r},1" for k in range(8))
    path = _csv(
        tmp_path / "d.csv",
        f"# {line}\n# T: 0.5\nk,y,u\n{rows}\n".replace(
            "# T: 0.5\n", "" if line.startswith("Ts") else "# T: 0.5\n"
        ),
    )
    with pytest.raises(DataFileError, match=f"Did you mean {hint}|Did you mean '{hint}'"):
        load(path)
    msg = refused(run("detect", path, "--model", "polepair"), "d.csv")
    assert "x-" in msg


def test_x_prefixed_metadata_is_a_note(tmp_path):
    rows = "\n".join(f"{k},{float(np.sin(k))!r},1" for k in range(8))
    ds = load(_csv(tmp_path / "d.csv", f"# x-operator: A. N. Other\n# T: 0.5\nk,y,u\n{rows}\n"))
    assert ds.metadata["x-operator"] == "A. N. Other"


@pytest.mark.parametrize("unit", ["s", "ms", "us", "ns", "min"])
def test_save_data_converts_to_its_unit_and_round_trips_exactly(tmp_path, unit):
    rng = np.random.default_rng(7)
    for i, T in enumerate([0.5, 0.1, 1e-3, 0.3, 7.7e-5, *rng.uniform(1e-4, 10, 6)]):
        data = ji.SampledData(rng.normal(size=6), float(T), ji.zoh_input(np.ones(7), float(T)))
        for ext in ("csv", "npz"):
            path = save_data(
                tmp_path / f"d{i}.{ext}", data, t0=3 * float(T), metadata={"time_unit": unit}
            )
            ds = load(path, _input_for(tmp_path, float(T), 3 * float(T)))
            assert ds.data.T == data.T, (unit, T)
            assert ds.t0 == 3 * float(T) or abs(ds.t0 - 3 * float(T)) <= 1e-15 * abs(ds.t0)
            assert ds.metadata["time_unit"] == unit
    ms = save_data(
        tmp_path / "ms.csv",
        ji.SampledData(np.ones(5), 0.001, ji.zoh_input(np.ones(6), 0.001)),
        metadata={"time_unit": "ms"},
    )
    assert "# T: 1.0" in ms.read_text()  # written in ms, not seconds labelled ms


def _input_for(tmp_path: Path, T: float, t0: float) -> Path:
    return ji.save_input(tmp_path / "in.csv", ji.zoh_input(np.ones(20), T, start=-T), t0=t0)


def test_save_data_never_writes_an_unloadable_file(tmp_path):
    data = ji.SampledData(np.ones(5), 1.0, ji.zoh_input(np.ones(6), 1.0))
    for meta, match in (
        ({"T": 5}, "remove it"),
        ({"time_units": "ms"}, "Did you mean"),
        ({"noise_std": -1}, "noise_std"),
        ({"y_unit": "V\nx"}, "one line"),
        ({"time_unit": "h"}, "time_unit"),
    ):
        with pytest.raises(ValueError, match=match):
            save_data(tmp_path / "d.csv", data, metadata=meta)
        assert not (tmp_path / "d.csv").exists()
    save_data(tmp_path / "d.csv", data, metadata={"T": 1.0, "x-rig": "bench 3"})
    assert load(tmp_path / "d.csv", _input_for(tmp_path, 1.0, 0.0)).data.T == 1.0


@pytest.mark.parametrize(
    "cell", ["1_000", "١٢", "１２", "0x10", "1e5_0", "inf", "-Infinity", "٣.٥"]
)
def test_cells_are_plain_ascii_decimals(tmp_path, cell):
    rows = [f"{k},{float(np.sin(k))!r},1" for k in range(8)]
    rows[3] = f"3,{cell},1"
    path = _csv(tmp_path / "d.csv", "# T: 1\nk,y,u\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataFileError, match="line 6, column 'y'"):
        load(path)


def test_time_arguments_take_a_unit_and_follow_the_files_unit(tmp_path):
    assert parse_jitter("known:gaussian:sigma=80ms").std == pytest.approx(0.08)
    assert parse_jitter("known:gaussian:sigma=80", time_unit="ms").std == pytest.approx(0.08)
    assert parse_jitter("uniform:a_max=500us").law([2e-4]).support[1] == pytest.approx(2e-4)
    # a millisecond file: --T 500 (ms), --T 0.5s and the metadata agree
    rows = "\n".join(f"{k},{float(np.sin(k))!r},1" for k in range(8))
    path = _csv(tmp_path / "d.csv", f"# time_unit: ms\nk,y,u\n{rows}\n")
    assert pytest.approx(0.5) == load(path, T="500").data.T
    assert pytest.approx(0.5) == load(path, T="0.5s").data.T
    assert pytest.approx(0.5) == load(path, T=500.0).data.T
    for cmd in ("fit", "detect", "bias", "simulate"):
        assert "unit" in run(cmd, "--help").output


def test_a_millisecond_file_with_a_bare_jitter_value(tmp_path):
    T, n = 0.5, 40
    rng = np.random.default_rng(4)
    u = ji.telegraph_input(n * T + 5, rng)
    data = ji.simulate(
        ji.PolePairGain().system([6.25, -1.5, 2.0]), u, ji.Uniform(0.1), T, n, 0.01, rng
    )
    save_data(tmp_path / "d.csv", data, metadata={"time_unit": "ms"})
    ji.save_input(tmp_path / "i.csv", u, metadata={"time_unit": "ms"})
    outs = {}
    for spec in ("known:uniform:a=100", "known:uniform:a=0.1s"):
        out = tmp_path / spec.replace(":", "_").replace("=", "_")
        res = run(
            "fit",
            tmp_path / "d.csv",
            "--input",
            tmp_path / "i.csv",
            "--model",
            "polepair",
            "--jitter",
            spec,
            "--method",
            "bcls",
            "--out",
            out,
            "--no-plots",
        )
        assert res.exit_code in (0, 3), res.output
        outs[spec] = json.loads((out / "result.json").read_text())
    a, b = outs.values()
    assert a["jitter"]["params"]["a"] == pytest.approx(0.1) == b["jitter"]["params"]["a"]
    assert a["parameters"] == b["parameters"]


# ------------------------------------------------------------------------- E: safe by default


def _listening(pids: set[int]) -> list[tuple[str, int]]:
    import psutil

    out = []
    for c in psutil.net_connections(kind="inet"):
        if c.status == psutil.CONN_LISTEN and c.pid in pids:
            out.append((c.laddr.ip, c.laddr.port))
    return out


def test_the_local_cluster_listens_on_loopback_only():
    import psutil

    with local_cluster(2) as cluster:
        me = psutil.Process()
        pids = {me.pid, *(p.pid for p in me.children(recursive=True))}
        sockets = _listening(pids)
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    assert sockets, "the cluster should listen somewhere"
    assert all(ip in ("127.0.0.1", "::1") for ip, _ in sockets), sockets


def test_user_strings_are_escaped_in_report_md(lab, tmp_path):
    evil = "<img src=x onerror=alert(1)> [click](http://evil.example) **b** `x` | # h"
    ds = load(lab / "data.csv", lab / "input.csv")
    save_data(tmp_path / "d.csv", ds.data, metadata={"y_unit": evil})
    out = tmp_path / "fit"
    res = run(
        "fit",
        tmp_path / "d.csv",
        "--input",
        lab / "input.csv",
        "--model",
        "polepair",
        "--jitter",
        "none",
        "--method",
        "ls",
        "--out",
        out,
        "--no-plots",
    )
    assert res.exit_code == 0, res.output
    report = (out / "report.md").read_text()
    assert "<img" not in report
    line = next(ln for ln in report.splitlines() if "output unit" in ln)
    assert (
        "&lt;img src=x onerror=alert(1)&gt; \\[click\\](http://evil.example) \\*\\*b\\*\\*" in line
    )
    assert "\\`x\\` \\| \\# h" in line


def test_experiment_titles_are_escaped_in_the_report(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text(
        TINY.replace('name = "tiny"', 'name = "tiny"\ntitle = "<script>x</script> [a](b)"')
    )
    res = run("run", path, "--workers", "1", "--no-progress", "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    md = (tmp_path / "o" / "tiny.md").read_text()
    assert "<script>" not in md
    assert "\\[a\\](b)" in md


def test_the_memory_budget_can_be_set(monkeypatch):
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1000")
    assert _checks.memory_budget() == 1000
    with pytest.raises(ValueError, match="JITTERID_MEMORY_BUDGET"):
        _checks.allocation(1000, "test")


def test_load_experiment_reads_the_packaged_definitions_unchanged():
    from jitterid.experiments import packaged_path

    assert load_experiment(packaged_path("table2")).runs == 128


# ------------------------------------------------------------------------- real small disks


def _mount_tmpfs(path: Path, options: str) -> bool:
    import subprocess

    path.mkdir(parents=True, exist_ok=True)
    try:
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)],
            capture_output=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def _umount(path: Path) -> None:
    import subprocess

    subprocess.run(["umount", str(path)], capture_output=True, timeout=10, check=False)


@pytest.fixture
def small_disk(tmp_path):
    """A 96 kB tmpfs (skipped where tmpfs cannot be mounted, e.g. without root)."""
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "size=96k"):
        pytest.skip("cannot mount a tmpfs here")
    yield disk
    _umount(disk)


@pytest.fixture
def read_only_disk(tmp_path):
    disk = tmp_path / "ro"
    if not _mount_tmpfs(disk, "ro,size=64k"):
        pytest.skip("cannot mount a tmpfs here")
    yield disk
    _umount(disk)


def test_a_full_disk_for_simulate_fit_and_run(lab, small_disk):
    # simulate: the data file does not fit; nothing partial is left behind
    msg = refused(run("simulate", "--out", small_disk / "s", "--N", "20000"), "No space left")
    assert "cannot simulate" in msg
    left = [p for p in small_disk.rglob("*") if p.is_file()]
    assert all(p.stat().st_size > 0 and not p.name.endswith(".tmp") for p in left), left
    # run: the store fills the disk; what was committed is kept and --resume is suggested
    # (the filler leaves room for the store with a few realizations: its tables, its checksums)
    (small_disk / "filler").write_bytes(b"\0" * 24_000)
    res = run(
        "run",
        _tiny_toml(lab.parent / "t.toml", runs="400"),
        "--workers",
        "1",
        "--no-progress",
        "--out",
        small_disk / "o",
    )
    refused(res, "--resume")
    with Store(
        small_disk / "o" / "tiny.sqlite", dataclasses.replace(tiny(), runs=400), resume=True
    ) as store:
        assert store.count_done() > 0


def test_a_read_only_disk(lab, read_only_disk):
    refused(run("simulate", "--out", read_only_disk / "s"), "--out", "writable")
    refused(
        run("run", _tiny_toml(lab.parent / "t2.toml"), "--out", read_only_disk / "o"),
        "cannot create the results store",
    )
    refused(
        run(
            "fit",
            lab / "data.csv",
            "--input",
            lab / "input.csv",
            "--model",
            "polepair",
            "--jitter",
            "none",
            "--method",
            "ls",
            "--out",
            read_only_disk,
        ),
        "--out",
        "writable",
    )
