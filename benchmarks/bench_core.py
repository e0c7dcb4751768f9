"""Core benchmark (issue 2): one fit on the paper's Table 2 experiment.

Prints the median wall and CPU time of one fit per method over R realizations, and the
ratio of fit time to one evaluation of mu_Y (expected_dft). Targets on the 2-core CI
machine: each fit <= 50 ms median, ratio <= 30 (issue 6: <= 30 model evaluations).

    python benchmarks/bench_core.py [--runs R]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits

import jitterid as ji

T, N, NOISE = 1.0, 200, 0.01
TRUTH = [6.25, -1.5, 2.0]
METHODS = ("ls", "bcls", "wbcls", "asml", "asml-diag", "gaussian")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    structure, law = ji.PolePairGain(), ji.Uniform(0.5)
    truth = structure.system(TRUTH)
    datasets = []
    for seed in range(args.runs):
        rng = np.random.default_rng(seed)
        u = ji.telegraph_input(N * T + 2, rng)
        datasets.append(ji.simulate(truth, u, law, T, N, NOISE, rng))
    f = ji.default_frequencies(N, T)
    with threadpool_limits(1, "blas"):
        ji.expected_dft(truth, datasets[0].u, law, T, N, f)  # warm-up
        t_mu, c_mu = [], []
        for d in datasets:
            t0, c0 = time.perf_counter(), time.process_time()
            ji.expected_dft(truth, d.u, law, T, N, f)
            t_mu.append(time.perf_counter() - t0)
            c_mu.append(time.process_time() - c0)
    mu, mu_cpu = float(np.median(t_mu)), float(np.median(c_mu))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitterid core benchmark on {platform.node()} "
        f"({platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    print(f"Table 2 experiment, N = {N}, 3 parameters, {args.runs} realizations")
    print(
        f"one mu_Y evaluation (expected_dft): median {mu * 1e3:.2f} ms (CPU {mu_cpu * 1e3:.2f} ms)"
    )
    print(
        f"{'method':<10} {'median fit':>11} {'fit / mu_Y':>11} {'CPU fit':>10} {'CPU ratio':>10} "
        f"{'success':>8}"
    )
    ji.fit(datasets[0], structure, law, method="bcls")  # warm-up
    for method in METHODS:
        times, cpus, ok = [], [], 0
        for d in datasets:
            t0, c0 = time.perf_counter(), time.process_time()
            res = ji.fit(d, structure, law, method=method)
            times.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
            ok += res.success
        med, cpu = float(np.median(times)), float(np.median(cpus))
        print(
            f"{method:<10} {med * 1e3:>8.1f} ms {med / mu:>11.1f} {cpu * 1e3:>7.1f} ms "
            f"{cpu / mu_cpu:>10.1f} "
            f"{ok:>4}/{len(datasets)}"
        )


if __name__ == "__main__":
    main()
