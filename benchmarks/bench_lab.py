"""Lab-setting benchmark: fit time and peak memory on lab-like data, against the paper's setting.

The lab setting: a third-order system with a zero, G(s) = (s + 2) / (s^3 + 3 s^2 + 4 s + 2)
(poles -1, -1 +- i), driven by a zero-order hold of a random +-1 sequence on the sampling grid
(``zoh_input``), T = 0.5 s, Gaussian jitter with std 0.08 s (unknown: ``GaussianFamily``),
noise std 0.02, fitted as ``RationalModel(1, 3)``. The paper's setting (Table 2, as in
``bench_scale.py``): ``PolePairGain`` truth (6.25, -1.5, 2), telegraph input with mean hold
1 s, known U(-T/2, T/2) jitter, T = 1, noise std 0.01.

Every fit runs in a fresh subprocess (its peak RSS is its own) under an address-space cap,
and the paper's setting is timed at the same N in the same run, so that the ratio
lab / paper is measured under the same load. The load average is printed before and after.

    python benchmarks/bench_lab.py [--sizes 1000 10000] [--big] [--methods bcls gaussian]

``--big`` adds N = 100000.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

CHILD = r"""
import json, resource, sys, time
setting, N, method, cap = sys.argv[1], int(sys.argv[2]), sys.argv[3], float(sys.argv[4])
if cap > 0:
    lim = int(cap * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
import numpy as np
import jitterid as ji
from jitterid.moments import modal as _modal
rng = np.random.default_rng(N)
if setting == "lab":
    T = 0.5
    truth = ji.TransferFunction([1.0, 2.0], [1.0, 3.0, 4.0, 2.0])
    u = ji.zoh_input(rng.choice([-1.0, 1.0], size=N + 20), T)
    data = ji.simulate(truth, u, ji.Gaussian(0.08), T, N, 0.02, rng)
    structure, jitter = ji.RationalModel(1, 3), ji.GaussianFamily()
else:
    T = 1.0
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    u = ji.telegraph_input(N * T + 2, rng)
    data = ji.simulate(truth, u, ji.Uniform(0.5), T, N, 0.01, rng)
    structure, jitter = ji.PolePairGain(), ji.Uniform(0.5)
_modal.clear_plans()
t0, c0 = time.perf_counter(), time.process_time()
try:
    res = ji.fit(data, structure, jitter, method=method)
    ok, err, x = res.success, "", res.x.tolist()
except MemoryError:
    ok, err, x = False, f"MemoryError (over the {cap:g} GB address-space cap)", []
except ValueError as e:
    ok, err, x = False, f"ValueError: {e}", []
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"setting": setting, "N": N, "method": method, "wall": wall, "cpu": cpu,
                  "rss_mb": rss, "success": ok, "error": err, "x": x}))
"""


def run_child(setting: str, N: int, method: str, cap_gb: float, timeout: float) -> dict:
    args = [sys.executable, "-c", CHILD, setting, str(N), method, str(cap_gb)]
    base = {
        "setting": setting,
        "N": N,
        "method": method,
        "wall": None,
        "cpu": None,
        "rss_mb": None,
        "success": False,
        "x": [],
    }
    try:
        out = subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {**base, "error": f"timed out after {timeout:g} s"}
    lines = out.stdout.strip().splitlines()
    if out.returncode != 0 or not lines:
        tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {**base, "error": f"exit {out.returncode}: {tail}"}
    return json.loads(lines[-1])


def _cell(r: dict) -> str:
    if r["wall"] is None:
        return f"{'--':>8} {'--':>8} {'--':>7}"
    return f"{r['wall']:>7.2f}s {r['cpu']:>7.2f}s {r['rss_mb']:>5.0f}MB"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--big", action="store_true", help="add N = 100000")
    ap.add_argument("--methods", nargs="+", default=["bcls", "gaussian"])
    ap.add_argument(
        "--mem-cap-gb", type=float, default=4.0, help="address-space cap per fit (0: none)"
    )
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per fit")
    args = ap.parse_args()
    sizes = list(args.sizes) + ([100000] if args.big else [])
    print(
        f"# jitterid lab benchmark on {platform.node()} ({platform.machine()}, {os.cpu_count()} "
        "cores), "
        f"{time.strftime('%Y-%m-%d %H:%M:%S')}, load average {os.getloadavg()}"
    )
    print(
        "# lab: RationalModel(1, 3), zoh +-1 input, T = 0.5, GaussianFamily (true sigma 0.08), "
        "noise 0.02"
    )
    print("# paper: PolePairGain, telegraph input, T = 1, known Uniform(0.5), noise 0.01 (Table 2)")
    print("# wall time, CPU time of the fit's process, peak RSS; ratio = lab / paper (wall, CPU)")
    print(
        f"{'N':>7} {'method':<9} {'lab wall':>8} {'lab CPU':>8} {'lab RSS':>7}   "
        f"{'paper wall':>8} {'CPU':>8} {'RSS':>7}   {'ratio':>6} {'CPU':>6}  note"
    )
    for N in sizes:
        for method in args.methods:
            lab = run_child("lab", N, method, args.mem_cap_gb, args.timeout)
            paper = run_child("paper", N, method, args.mem_cap_gb, args.timeout)
            ratio = cpu_ratio = float("nan")
            if lab["wall"] is not None and paper["wall"] is not None:
                ratio, cpu_ratio = lab["wall"] / paper["wall"], lab["cpu"] / paper["cpu"]
            notes = []
            for r in (lab, paper):
                if r.get("error"):
                    notes.append(f"{r['setting']} FAILED: {r['error']}")
                elif not r["success"]:
                    notes.append(f"{r['setting']} not converged")
            if lab["x"]:
                notes.append("lab x = " + " ".join(f"{v:.4g}" for v in lab["x"]))
            print(
                f"{N:>7} {method:<9} {_cell(lab)}   {_cell(paper)}   {ratio:>6.1f} "
                f"{cpu_ratio:>6.1f}  " + "; ".join(notes),
                flush=True,
            )
    print(f"# load average at the end {os.getloadavg()}")


if __name__ == "__main__":
    main()
