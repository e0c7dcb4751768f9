"""Fuzz the command line with generated malformed and extreme files and options (issue 15).

A few hundred cases from a seeded generator: mutated CSV and .npz data files, sidecars,
input files, TOML definitions, results stores, and extreme option values. Every case must
end either in a written result (exit 0, or 3 for a fit that did not converge) or in a
non-zero exit with a one-line error message: never a traceback and never the CLI's
last-resort "internal error". The counts are printed (``pytest -s``) for the record.
"""

from __future__ import annotations

import collections
import io
import json
import sqlite3
import time
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.cli import INTERNAL, main

SEED = 20261122
TOKENS = [
    "",
    " ",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e400",
    "-1e400",
    "1e-400",
    "1_000",
    "١٢",
    "１２",
    "٣.٥",
    "0x10",
    "1,5",
    "--",
    "1.2.3",
    "+",
    ".",
    "e5",
    "1e",
    '"',
    "'",
    "None",
    "true",
    "9" * 400,
    "-0",
    "0",
    "1e308",
    "-1e308",
    "5e-324",
    "１",
    "\x00",
    "\u200b1",
    "1\u00a0",
]
META_KEYS = [
    "T",
    "time_unit",
    "time_units",
    "Ts",
    "t",
    "noise_std",
    "y_unit",
    "u_unit",
    "end",
    "x-note",
    "note",
    "TIME_UNIT",
    "",
    "T ",
    "#",
    "k",
]
META_VALUES = [
    "1",
    "0.5",
    "0",
    "-1",
    "ms",
    "s",
    "hours",
    "nan",
    "1e400",
    "",
    "µs",
    "1_0",
    "٢",
    "{}",
    "[1,2]",
    "a" * 300,
]
JITTERS = [
    "none",
    "known:uniform:a=0.1",
    "known:gaussian:sigma=80ms",
    "uniform",
    "gaussian",
    "sum-of-uniforms:n_max=3",
    "known:uniform:a=1e300",
    "known:gaussian:sigma=-1",
    "known:uniform",
    "known:uniform:a=",
    "known:uniform:a=1_0",
    "gaussian:sigma_max=0",
    "known:sum-of-uniforms:n=1e300,a=0.5",
    "uniform:a_max=nan",
    "known:foo:a=1",
    "known:uniform:a=0.1:b=2",
    "::",
    "known:gaussian:sigma=80xs",
    "known:uniform:a=5min",
]
MODELS = [
    "polepair",
    "tf:0,2",
    "tf:1,2",
    "tf:a,b",
    "tf:3,2",
    "tf:0,0",
    "tf:-1,2",
    "tf:0,2,3",
    "tf:99999999999999999999,1",
    "pole pair",
    "",
    "tf:",
]
T_VALUES = [
    "1",
    "0.5s",
    "500ms",
    "0",
    "-1",
    "nan",
    "inf",
    "1e400",
    "abc",
    "1_0",
    "٢",
    "5 min",
    "1e-300",
    "1e300",
]


def _base_rows(n: int = 24) -> list[str]:
    rng = np.random.default_rng(1)
    u = rng.choice([-0.5, 0.5], size=n)
    y = np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n] + 0.01 * rng.normal(size=n)
    return [f"{k},{float(y[k])!r},{float(u[k])!r}" for k in range(n)]


def _csv_case(rng: np.random.Generator, d: Path) -> list[str]:
    lines = ["# T: 1", "k,y,u", *_base_rows()]
    if rng.random() < 0.3:  # valid but unusual: milliseconds, notes, spaces, times
        lines[0] = str(rng.choice(["# T: 1000", "#T:1000", "#   T   :   1000  "]))
        lines.insert(0, "# time_unit: ms")
        lines.insert(0, f"# x-{rng.choice(['note', 'rig', 'operator'])}: free text: ok")
    for _ in range(int(rng.integers(0, 4))):
        what = rng.integers(7)
        if len(lines) < 4:
            break
        i = int(rng.integers(2, len(lines)))
        if what == 0:  # a bad cell
            cells = lines[i].split(",")
            cells[int(rng.integers(len(cells)))] = str(rng.choice(TOKENS))
            lines[i] = ",".join(cells)
        elif what == 1:  # a metadata line
            lines.insert(0, f"# {rng.choice(META_KEYS)}: {rng.choice(META_VALUES)}")
        elif what == 2:  # drop, duplicate or swap rows
            j = int(rng.integers(2, len(lines)))
            lines[i], lines[j] = lines[j], lines[i]
            if rng.random() < 0.5:
                lines.insert(i, lines[i])
        elif what == 3:  # the header
            lines[1] = str(
                rng.choice(
                    [
                        "t,y,u",
                        "k,y",
                        "K,Y,U",
                        "k;y;u",
                        "k,y,u,u",
                        "k,,u",
                        "time,level",
                        "k,y,v",
                        "t,k,y,u",
                        "",
                    ]
                )
            )
        elif what == 4:  # fewer rows
            lines = lines[: int(rng.integers(1, len(lines)))]
            continue
        elif what == 5:  # a different T
            lines[0] = f"# T: {rng.choice(META_VALUES)}"
        else:  # extra cells
            lines[i] += "," + str(rng.choice(TOKENS))
    sep = "\r\n" if rng.random() < 0.2 else "\n"
    raw = sep.join(lines).encode("utf-8", "surrogatepass")
    if rng.random() < 0.1:
        raw = b"\xef\xbb\xbf" + raw
    if rng.random() < 0.1:  # not UTF-8
        pos = int(rng.integers(len(raw)))
        raw = raw[:pos] + b"\xff\xfe" + raw[pos:]
    path = d / "data.csv"
    path.write_bytes(raw)
    if rng.random() < 0.15:  # a sidecar
        side = rng.choice(
            [
                '{"T": 1}',
                '{"time_units": "ms"}',
                "[1]",
                "{",
                "[" * 5000,
                '{"T": "1_0"}',
                '{"y_unit": 5}',
                '{"x-a": {"b": [1, 2]}}',
                "\xff",
            ]
        )
        (d / "data.json").write_bytes(str(side).encode("utf-8", "replace"))
    return ["detect", str(path), "--model", "polepair"]


def _npz_case(rng: np.random.Generator, d: Path) -> list[str]:
    n = 24
    rows = [r.split(",") for r in _base_rows(n)]
    arrays: dict[str, object] = {
        "k": np.arange(n),
        "y": np.array([float(r[1]) for r in rows]),
        "u": np.array([float(r[2]) for r in rows]),
        "metadata": np.array('{"T": 1}'),
    }
    what = rng.integers(7)
    if what == 0:
        bad = [
            np.zeros((n, 2)),
            np.array(["a"] * n),
            np.zeros(n - 1),
            np.array([]),
            np.full(n, np.nan),
            np.zeros(n, dtype=complex),
            np.array(5.0),
        ]
        arrays[str(rng.choice(["y", "u", "k"]))] = bad[int(rng.integers(len(bad)))]
    elif what == 1:
        arrays["metadata"] = np.array(
            str(
                rng.choice(
                    [
                        "{bad",
                        "[" * 20000,
                        '{"T": -1}',
                        '{"Ts": 1}',
                        '{"T": 1, "time_unit": "h"}',
                        "5",
                        '{"T": 1e999}',
                        '{"T": true}',
                        '{"x-deep": ' + "[" * 50 + "]" * 50 + ', "T": 1}',
                    ]
                )
            )
        )
    elif what == 2:
        arrays["metadata"] = np.array([1, 2])
    elif what == 3:
        arrays["extra"] = np.zeros(n)
    path = d / "data.npz"
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    raw = bytearray(buf.getvalue())
    if what == 4:  # truncate
        raw = raw[: int(rng.integers(10, len(raw)))]
    elif what == 5:  # flip bytes
        for _ in range(int(rng.integers(1, 6))):
            raw[int(rng.integers(len(raw)))] = int(rng.integers(256))
    path.write_bytes(bytes(raw))
    if what == 6:  # a member that is not an array, or a lying header
        with zipfile.ZipFile(path, "a") as zf:
            if rng.random() < 0.5:
                zf.writestr("note.txt", "x")
            else:
                shape = rng.choice(["(10**13,)", "(10000000000000,)", "(-1,)", "(3, 'a')", "("])
                head = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}"
                body = head.encode().ljust(118) + b"\n"
                zf.writestr(
                    "y2.npy",
                    b"\x93NUMPY\x01\x00" + len(body).to_bytes(2, "little") + body + b"\0" * 16,
                )
    return ["detect", str(path), "--model", "polepair"]


def _input_case(rng: np.random.Generator, d: Path) -> list[str]:
    n = 24
    rows = [r.split(",") for r in _base_rows(n)]
    (d / "data.csv").write_text("# T: 1\nk,y\n" + "\n".join(f"{r[0]},{r[1]}" for r in rows))
    kind = rng.integers(3)
    if kind == 0:
        lines = [
            "time,level",
            *(f"{float(t)!r},{rng.choice([-1, 1])}" for t in np.sort(rng.uniform(-2, n + 2, 10))),
        ]
        meta = f"# end: {rng.choice(['30', '5', '-1', 'x', '1e400', '24'])}\n"
    elif kind == 1:
        start = int(rng.integers(-3, 3))
        m = int(rng.integers(n - 3, n + 5))
        lines = ["k,u", *(f"{k},{rng.choice([-1, 1])}" for k in range(start, start + m))]
        meta = f"# time_unit: {rng.choice(['s', 'ms', 'x'])}\n" if rng.random() < 0.3 else ""
    else:
        lines = ["t,u", *(f"{0.5 * k!r},1" for k in range(n + 2))]
        meta = ""
    if rng.random() < 0.5:
        i = int(rng.integers(1, len(lines)))
        lines[i] = lines[i].split(",")[0] + "," + str(rng.choice(TOKENS))
    (d / "input.csv").write_text(meta + "\n".join(lines) + "\n")
    return ["detect", str(d / "data.csv"), "--input", str(d / "input.csv"), "--model", "polepair"]


def _option_case(rng: np.random.Generator, d: Path, lab: Path) -> list[str]:
    what = rng.integers(5)
    if what == 0:
        return [
            "bias",
            "--jitter",
            str(rng.choice(JITTERS)).removeprefix("known:"),
            "--T",
            str(rng.choice(T_VALUES)),
            "--points",
            str(rng.choice([2, 11, 0, 1001])),
        ]
    if what == 1:
        return [
            "simulate",
            "--out",
            str(d / "sim"),
            "--N",
            str(rng.choice(["4", "20", "3", str(10**13), "x"])),
            "--T",
            str(rng.choice(T_VALUES)),
            "--hold",
            str(rng.choice(T_VALUES)),
            "--jitter",
            str(rng.choice(JITTERS)).removeprefix("known:"),
            "--params",
            str(rng.choice(["6.25,-1.5,2", "1,2", "a,b,c", "1e400,1,1", "6.25,1.5,2"])),
        ]
    if what == 2:
        return [
            "detect",
            str(lab / "data.csv"),
            "--input",
            str(lab / "input.csv"),
            "--model",
            str(rng.choice(MODELS)),
            "--level",
            str(rng.choice(["0.95", "0", "1", "x"])),
            *(["--T", str(rng.choice(T_VALUES))] if rng.random() < 0.3 else []),
        ]
    if what == 3:
        return [
            "fit",
            str(lab / "data.csv"),
            "--input",
            str(lab / "input.csv"),
            "--model",
            str(rng.choice(["polepair", "tf:0,2", "tf:9,1", "x"])),
            "--jitter",
            str(rng.choice(JITTERS)),
            "--method",
            str(rng.choice(["ls", "bcls", "zz"])),
            "--out",
            str(d / "fit"),
            "--no-plots",
        ]
    return [
        "reproduce",
        str(rng.choice(["table1", "table9"])),
        "--runs",
        str(rng.choice(["0", "-1", str(10**12), str(10**30), "x"])),
        "--workers",
        str(rng.choice(["0", "1", "x"])),
        "--scheduler",
        str(rng.choice(["not an address", "tcp://", "::::", "tcp://host", "http://[::1"])),
        "--out",
        str(d / "rep"),
    ]


TOML = """[experiment]
name = "f"
runs = 1
seed = 1
[sampling]
T = 1.0
N = 12
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
law = { kind = "uniform", a = 0.25 }
[estimators]
methods = ["ls"]
"""
TOML_VALUES = [
    "1e300",
    "-1",
    "0",
    "nan",
    "inf",
    "1_000_000_000_000",
    "'x'",
    "[]",
    "{}",
    "true",
    "9" * 30,
    "1e-300",
    '"1"',
    "[1, 'a']",
    "{ a = 1 }",
    "0.5",
]


def _toml_case(rng: np.random.Generator, d: Path) -> list[str]:
    lines = TOML.splitlines()
    for _ in range(int(rng.integers(1, 3))):
        i = int(rng.integers(len(lines)))
        if "=" in lines[i] and rng.random() < 0.8:
            key = lines[i].split("=")[0]
            lines[i] = f"{key}= {rng.choice(TOML_VALUES)}"
        elif rng.random() < 0.5:
            del lines[i]
        else:
            lines.insert(
                i,
                str(
                    rng.choice(
                        [
                            "x = 1",
                            "[extra]",
                            "N = 5",
                            "[[cases]]",
                            "runs = 2",
                            "kind = 'multisine'",
                            "a = [[[[1]]]]",
                        ]
                    )
                ),
            )
    raw = "\n".join(lines).encode()
    if rng.random() < 0.05:
        raw = raw.replace(b"f", b"\xe9", 1)
    (d / "f.toml").write_bytes(raw)
    return ["run", str(d / "f.toml"), "--workers", "1", "--no-progress", "--out", str(d / "o")]


def _store_case(rng: np.random.Generator, d: Path, store: bytes) -> list[str]:
    (d / "f.toml").write_text(TOML)
    (d / "o").mkdir()
    raw = bytearray(store)
    what = rng.integers(4)
    if what == 0:
        raw = raw[: int(rng.integers(0, len(raw)))]
    elif what == 1:
        for _ in range(int(rng.integers(1, 20))):
            raw[int(rng.integers(len(raw)))] = int(rng.integers(256))
    (d / "o" / "f.sqlite").write_bytes(bytes(raw))
    if what == 2:
        with sqlite3.connect(d / "o" / "f.sqlite") as db:
            db.execute(
                str(
                    rng.choice(
                        [
                            "DELETE FROM realizations",
                            "DROP TABLE estimates",
                            "UPDATE estimates SET params = 'x'",
                            "UPDATE meta SET value = '1'",
                            "ALTER TABLE estimates ADD COLUMN z",
                            "UPDATE estimates SET params = '[1]'",
                        ]
                    )
                )
            )
    elif what == 3:
        (d / "o" / "f.sqlite").unlink()
        (d / "o" / "f.sqlite").mkdir()
    return [
        "run",
        str(d / "f.toml"),
        "--workers",
        "1",
        "--no-progress",
        "--resume",
        "--out",
        str(d / "o"),
    ]


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fuzzlab")
    res = CliRunner().invoke(main, ["simulate", "--out", str(d), "--N", "30"])
    assert res.exit_code == 0, res.output
    return d


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> bytes:
    d = tmp_path_factory.mktemp("fuzzstore")
    (d / "f.toml").write_text(TOML)
    res = CliRunner().invoke(
        main, ["run", str(d / "f.toml"), "--workers", "1", "--no-progress", "--out", str(d / "o")]
    )
    assert res.exit_code == 0, res.output
    return (d / "o" / "f.sqlite").read_bytes()


def test_cli_fuzz(lab, store, tmp_path):
    rng = np.random.default_rng(SEED)
    makers: list[tuple[str, int, Callable[[np.random.Generator, Path], list[str]]]] = [
        ("csv", 200, _csv_case),
        ("npz", 80, _npz_case),
        ("input", 40, _input_case),
        ("options", 100, lambda r, d: _option_case(r, d, lab)),
        ("toml", 60, _toml_case),
        ("store", 30, lambda r, d: _store_case(r, d, store)),
    ]
    counts: collections.Counter[str] = collections.Counter()
    failures = []
    warned: list[str] = []
    t0 = time.perf_counter()
    case = 0
    for kind, n, make in makers:
        for _ in range(n):
            d = tmp_path / f"c{case}"
            d.mkdir()
            case += 1
            args = make(rng, d)
            with warnings.catch_warnings(record=True) as caught:
                # as for a user: a numerical warning is printed, it does not stop the command
                warnings.simplefilter("always", RuntimeWarning)
                res = CliRunner().invoke(main, args)
            if any(issubclass(w.category, RuntimeWarning) for w in caught):
                counts["numeric warning"] += 1
                warned.append(" ".join(args[:1]) + f" ({kind})")
            clean = isinstance(res.exception, SystemExit) or res.exception is None
            if not clean or "Traceback" in res.output or INTERNAL in res.output:
                counts["traceback"] += 1
                failures.append((kind, args, repr(res.exception), res.output[-400:]))
            elif res.exit_code in (0, 3):
                counts["result"] += 1
                if args[0] == "fit":
                    assert (d / "fit" / "result.json").is_file()
            else:
                errors = [ln for ln in res.output.splitlines() if ln.startswith("Error")]
                if not errors or not errors[-1][len("Error: ") :].strip():
                    counts["no message"] += 1
                    failures.append((kind, args, "no message", res.output[-400:]))
                else:
                    counts["refused"] += 1
                # no 0-byte or temporary file left behind
                left = [
                    p
                    for p in d.rglob("*")
                    if p.is_file()
                    and (
                        p.name.endswith(".tmp")
                        or (
                            p.stat().st_size == 0
                            and p.suffix in (".json", ".md", ".csv", ".png", ".npz")
                        )
                    )
                ]
                assert not left, (args, left)
    wall = time.perf_counter() - t0
    print(f"\nCLI fuzz: {case} cases in {wall:.1f} s: {dict(counts)}; warnings in {warned}")
    assert not failures, json.dumps(failures[:20], indent=1, default=str)
    assert counts["refused"] > case // 2
    assert counts["result"] > 10


def test_written_files_are_loadable(tmp_path):
    """A file save_data writes is always one load reads, whatever the metadata."""
    rng = np.random.default_rng(SEED + 1)
    for i in range(40):
        T = float(10 ** rng.uniform(-6, 3))
        data = ji.SampledData(rng.normal(size=5), T, ji.zoh_input(np.ones(6), T))
        meta = {
            "time_unit": str(rng.choice(["s", "ms", "us", "ns", "min"])),
            "y_unit": str(rng.choice(["V", "m/s", "[a](b)", "x" * 50])),
        }
        path = ji.save_data(tmp_path / f"d{i}.{rng.choice(['csv', 'npz'])}", data, metadata=meta)
        got = ji.load(path, ji.save_input(tmp_path / "u.csv", data.u, T=T))
        assert got.data.T == T
        np.testing.assert_array_equal(got.data.y, data.y)
