"""Smoke runs of the benchmark scripts (benchmarks/*.py) at tiny sizes, so that they never rot.

Each runs a script in a subprocess (seconds to minutes of CPU): the whole module is marked
slow and runs with ``pytest -m slow``."""

import json
import subprocess
import sys

import numpy as np
import pytest
from helpers import BENCHMARKS as BENCH

pytestmark = pytest.mark.slow


def _script(name: str, *args: str, timeout: int = 600) -> str:
    """The standard output of ``benchmarks/<name> args`` run in a subprocess (an error if it
    fails or runs past ``timeout`` seconds)."""
    return subprocess.run(
        [sys.executable, str(BENCH / name), *args],
        capture_output=True,
        text=True,
        check=True,
        timeout=timeout,
    ).stdout


def test_scale_benchmark_runs_at_small_n():
    out = _script(
        "bench_scale.py",
        "--sizes",
        "100",
        "300",
        "--methods",
        "bcls",
        "gaussian",
        "ml",
        "--ratio-sizes",
        "200",
        "--ratio-reps",
        "1",
        "--paths",
        "50",
    )
    assert "FAILED" not in out, out
    assert "NOT CONVERGED" not in out, out
    for method in ("bcls", "gaussian", "ml"):
        assert f"{method:<9} log-log slope" in out, out
        assert f"N =     200 {method:<9} fit" in out, out
    assert out.count("MB") == 6  # peak memory of each of the six fits
    assert "mu_Y at N = 50" in out


def test_scale_benchmark_reports_a_fit_over_its_memory_cap():
    """The cap makes a fit that needs too much memory fail in its own process, reported."""
    out = _script(
        "bench_scale.py",
        "--sizes",
        "300",
        "--methods",
        "bcls",
        "--ratio-sizes",
        "--paths",
        "--mem-cap-gb",
        "0.05",
        timeout=300,
    )
    assert "FAILED" in out, out


def test_core_benchmark_runs():
    out = _script("bench_core.py", "--runs", "1", timeout=300)
    assert "bcls" in out
    assert "gaussian" in out


def test_signal_benchmark_runs():
    out = _script("bench_signal.py", "--runs", "1", "--sizes", "200", timeout=300)
    assert "   200 ml" in out, out
    assert "1/1" in out, out


def test_meter_benchmark_runs():
    out = _script("bench_meter.py", "--runs", "1", "--sizes", "300", timeout=300)
    assert "    300 ml" in out, out
    assert "    300 gaussian" in out, out
    assert "load" in out


def _jitter_meter(tmp_path, *methods):
    cmd = [
        sys.executable,
        str(BENCH / "jitter_meter.py"),
        "--quick",
        "--records",
        "1",
        "--thetas",
        "0.05",
        "0.5",
        "--noises",
        "0.01",
        "--laws",
        "gaussian",
        "dual_dirac",
        "--db",
        str(tmp_path / "jm.sqlite"),
        "--figure",
        str(tmp_path / "jm.png"),
        "--methods",
        *methods,
    ]
    return [
        subprocess.run(cmd, capture_output=True, text=True, check=True, timeout=600).stdout
        for _ in range(2)
    ]


def test_jitter_meter_quick_runs_and_resumes(tmp_path):
    """The study's quick mode with the always-available columns; a rerun resumes (computes 0)."""
    first, second = _jitter_meter(tmp_path, "ieee1057", "jitterid")
    assert "load" in first
    assert "gaussian     1000   0.05    0.01 ieee1057     1/1" in first, first
    assert "dual_dirac   1000    0.5    0.01 ieee1057     1/1" in first, first
    import jitterid

    if not hasattr(jitterid, "measure_jitter"):
        assert "jitterid.measure_jitter does not exist" in first
    else:
        assert "1000   0.05    0.01 jitterid" in first, first
    assert (tmp_path / "jm.png").stat().st_size > 0
    assert "# computed 0 (record, method) results" in second
    table = lambda out: out[out.index("law ") : out.index("# figure")]
    assert table(first) == table(second)


def test_jitter_meter_adctoolbox_column(tmp_path):
    """The adctoolbox peer (the optional ``bench`` extra): its column runs, and on one
    moderate-jitter record it agrees with the IEEE 1057 slope regression, which is what its
    analyze_error_by_phase computes (benchmarks/peers.py)."""
    pytest.importorskip("adctoolbox")
    first, _ = _jitter_meter(tmp_path, "adctoolbox", "ieee1057")
    assert "gaussian     1000   0.05    0.01 adctoolbox   1/1" in first, first
    sys.path.insert(0, str(BENCH))
    try:
        import peers
    finally:
        sys.path.remove(str(BENCH))
    rng = np.random.default_rng(2)
    k = np.arange(5000)
    y = np.sin(2 * np.pi * 0.1234 * (k + rng.normal(0.0, 0.1, k.size))) + rng.normal(
        0, 1e-3, k.size
    )
    ours, theirs = peers.ieee1057_jitter(y, 1.0), peers.adctoolbox_jitter(y, 1.0)
    assert theirs == pytest.approx(ours, rel=2e-3)
    assert ours == pytest.approx(0.1, rel=0.05)
    # above Nyquist: the wrapper passes the alias and converts with the true frequency
    assert peers.adctoolbox_jitter(y, 1.0, 1.1234) == pytest.approx(
        theirs * 0.1234 / 1.1234, rel=2e-3
    )


def test_multisine_benchmark_runs_at_small_n():
    out = _script("bench_multisine.py", "--sizes", "200", "--methods", "bcls", "ml")
    rows = [line for line in out.splitlines() if line.strip().startswith("200 ")]
    assert [row.split()[1] for row in rows] == ["bcls", "ml"], out
    assert all(row.endswith("CONVERGED / CONVERGED") for row in rows), out


def test_reproduce_benchmark_runs_at_one_realization():
    """Table 2 with the paper's three estimators, shared and --no-share, one realization."""
    out = _script(
        "bench_reproduce.py",
        "--target",
        "table2-paper",
        "--runs",
        "1",
        "--workers",
        "1",
        "--no-share",
    )
    assert "jitterid run " in out, out
    assert "1 realizations (table2 1 case(s)), 1 worker(s)" in out, out
    assert "estimates identical in both runs; 0 bound rows computed only without sharing" in out
    assert "no-share / shared: wall x" in out
    for m in ("ls", "bcls", "asml-diag"):
        assert f"table2        {m:<10}" in out, out
    assert "gaussian" not in out


def test_bj_benchmark_runs_at_small_n():
    out = _script("bench_bj.py", "--sizes", "200", "800", "--repeats", "1")
    assert "log-log slope" in out


def test_ml_benchmark_script_runs():
    """Smoke run of benchmarks/bench_ml.py at one realization, so that it never rots."""
    out = _script("bench_ml.py", "--runs", "1", "--joe-runs", "0", timeout=300)
    assert "fit(method='ml'), end to end" in out


def test_family_benchmark_runs_on_one_record():
    out = _script("bench_family.py", "--runs", "1", "--methods", "bcls")
    assert "bcls      known law" in out, out
    assert out.count("bcls ") == 4, out


def test_family_count_benchmark_runs_on_one_record(tmp_path):
    out_json = tmp_path / "fits.json"
    out = _script("count_fam.py", "--runs", "1", "--methods", "gaussian", "--json", str(out_json))
    assert "gaussian  SumOfUniformsFamily()" in out, out
    assert len(json.loads(out_json.read_text())) == 2


def test_meter_records_benchmark_runs_on_two_short_records():
    out = _script("meter_records.py", "uniform-float", "--records", "2", "--n", "1024")
    assert "jitterid meter records, uniform-float, N = 1024" in out, out
    assert out.count("covers:") == 2, out
    assert "covered" in out, out
