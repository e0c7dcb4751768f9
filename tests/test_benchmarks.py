"""Smoke runs of the benchmark scripts at tiny sizes, so that they never rot."""

import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


def test_scale_benchmark_runs_at_small_n():
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_scale.py"), "--sizes", "100", "300", "--methods", "bcls",
         "gaussian", "ml", "--ratio-sizes", "200", "--ratio-reps", "1", "--paths", "50"],
        capture_output=True, text=True, check=True, timeout=600,
    ).stdout
    assert "FAILED" not in out, out
    assert "NOT CONVERGED" not in out, out
    for method in ("bcls", "gaussian", "ml"):
        assert f"{method:<9} log-log slope" in out, out
        assert f"N =     200 {method:<9} fit" in out, out
    assert out.count("MB") == 6  # peak memory of each of the six fits
    assert "mu_Y at N = 50" in out


def test_scale_benchmark_reports_a_fit_over_its_memory_cap():
    """The cap makes a fit that needs too much memory fail in its own process, reported."""
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_scale.py"), "--sizes", "300", "--methods", "bcls",
         "--ratio-sizes", "--paths", "--mem-cap-gb", "0.05"],
        capture_output=True, text=True, check=True, timeout=300,
    ).stdout
    assert "FAILED" in out, out


def test_core_benchmark_runs():
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_core.py"), "--runs", "1"],
        capture_output=True, text=True, check=True, timeout=300,
    ).stdout
    assert "bcls" in out
    assert "gaussian" in out


def test_signal_benchmark_runs():
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_signal.py"), "--runs", "1", "--sizes", "200"],
        capture_output=True, text=True, check=True, timeout=300,
    ).stdout
    assert "   200 ml" in out, out
    assert "1/1" in out, out
