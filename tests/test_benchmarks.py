"""Smoke runs of the benchmark scripts at tiny sizes, so that they never rot."""

import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


def test_scale_benchmark_runs_at_small_n():
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_scale.py"), "--sizes", "100", "300", "--methods", "bcls", "--paths", "50"],
        capture_output=True, text=True, check=True, timeout=300,
    ).stdout
    assert "log-log slope" in out
    assert "mu_Y at N = 50" in out


def test_core_benchmark_runs():
    out = subprocess.run(
        [sys.executable, str(BENCH / "bench_core.py"), "--runs", "1"],
        capture_output=True, text=True, check=True, timeout=300,
    ).stdout
    assert "bcls" in out and "gaussian" in out
