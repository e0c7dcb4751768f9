"""Joint estimation of the jitter law (JOE) against a known law (issue 24).

Table 2's system and input, data drawn with the paper's family (26) law SumOfUniforms(2,
1/(2 sqrt 3)), N = 200; each method fitted to the same records with the law known, with
SumOfUniformsFamily() (n in [0, 20], a unbounded), SumOfUniformsFamily(a_max=0.5) (Tables 1
and 3) and GaussianFamily(). Prints the median CPU seconds per fit (the method's first stage
included: a fit as a user calls it), the ratio to the known-law fit, and every status.
Targets (issue 24): ML with SumOfUniformsFamily() <= 4x ML with the law known; the
Gaussian-type criteria <= 3x.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_family.py [--runs R] [--methods ml gaussian]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections import Counter

import numpy as np

import jitterid as ji
from jitterid.experiments import runner
from jitterid.experiments.config import packaged_path
from jitterid.experiments.loader import load_experiment

LAW = ji.SumOfUniforms(2, 1 / (2 * np.sqrt(3)))
MODELS = {
    "known law": LAW,
    "SumOfUniformsFamily()": ji.SumOfUniformsFamily(),
    "SumOfUniformsFamily(a_max=0.5)": ji.SumOfUniformsFamily(a_max=0.5),
    "GaussianFamily()": ji.GaussianFamily(),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="records (Table 2 realizations)")
    ap.add_argument("--methods", nargs="+", default=["bcls", "asml", "gaussian", "ml"])
    args = ap.parse_args()
    exp = load_experiment(packaged_path("table2"))
    records = []
    for r in range(args.runs):
        rng = np.random.default_rng(runner.seed_stream(exp.seed, 0, r))
        u = exp.input.build(exp.duration, rng)
        records.append(
            ji.simulate(exp.system.true_system(), u, LAW, exp.T, exp.N, exp.noise_std, rng)
        )
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitterid JOE-cost benchmark on {platform.node()} ({os.cpu_count()} cores, "
        f"load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    print(f"Table 2 system, data from {LAW}, N = {exp.N}, {args.runs} records")
    print(f"{'method':<9} {'jitter model':<31} {'median CPU s':>12} {'x known':>8}  statuses")
    for method in args.methods:
        known = None
        for name, model in MODELS.items():
            cpu, status = [], Counter()
            for d in records:
                c0 = time.process_time()
                res = ji.fit(d, ji.PolePairGain(), model, method)
                cpu.append(time.process_time() - c0)
                status[res.status.name] += 1
            med = float(np.median(cpu))
            known = med if known is None else known
            print(
                f"{method:<9} {name:<31} {med:12.3f} {med / known:8.1f}  "
                + ", ".join(f"{k} {v}" for k, v in status.items())
            )


if __name__ == "__main__":
    main()
