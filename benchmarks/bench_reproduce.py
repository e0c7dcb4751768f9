"""Monte Carlo benchmark (issue 3): wall time of `jitterid reproduce table2` at 128 realizations.

Runs the real command line in a fresh process (Dask cluster start-up included) into a
temporary folder, then prints the wall time, realizations per second and the median time of
one fit per estimator read back from the store. Target on the 2-core machine: <= 20 s for
Table 2 (128 x LS, BCLS, AsML) and <= 3 minutes for `reproduce all`.

    python benchmarks/bench_reproduce.py [--target table2] [--runs 128] [--workers W]

With fewer runs than the paper's 128 it also prints the time extrapolated to 128.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

from jitterid.experiments import load_experiment, packaged_path
from jitterid.experiments.runner import store_path
from jitterid.experiments.store import Store


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--target", default="table2", choices=("table1", "table2", "table3"))
    ap.add_argument("--runs", type=int, default=128)
    ap.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    args = ap.parse_args()
    exp = dataclasses.replace(load_experiment(packaged_path(args.target)), runs=args.runs)
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable,
            "-c",
            "from jitterid.cli import main; main()",
            "reproduce",
            args.target,
            "--runs",
            str(args.runs),
            "--workers",
            str(args.workers),
            "--out",
            out,
            "--no-progress",
        ]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        with Store(store_path(exp, out), exp, resume=True) as store:
            rows = store.estimates()
    n = args.runs * len(exp.cases)
    print(
        f"# jitterid reproduce benchmark on {platform.node()} ({os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    print(
        f"reproduce {args.target}: {n} realizations ({len(exp.cases)} case(s) x {args.runs}), "
        f"{len(exp.methods)} estimators each, {args.workers} worker(s)"
    )
    print(f"wall time {wall:.1f} s, {n / wall:.2f} realizations/s")
    if args.runs < 128:
        print(
            f"extrapolated to 128 runs: {wall * 128 / args.runs:.0f} s (start-up counted "
            "128/runs times: an upper estimate)"
        )
    print(f"{'method':<10} {'median fit (s)':>15} {'total fit (s)':>14} {'converged':>10}")
    for m in exp.methods:
        t = [e.elapsed_s for e in rows if e.method == m]
        ok = sum(e.success for e in rows if e.method == m)
        print(f"{m:<10} {np.median(t):>15.3f} {np.sum(t):>14.1f} {ok:>6}/{len(t)}")


if __name__ == "__main__":
    main()
