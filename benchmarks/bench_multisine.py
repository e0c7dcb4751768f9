"""Steady-state multisine inputs: closed-form moments against the node route, in one run.

The steady-state response to a multisine is a sum of tones, whose jittered moments
``Response.jitter_moments`` gives in closed form ((S1)-(S2) of ``jitterid.systems.tones``);
the node route (quadrature over the jitter at every sample, what the library did before)
is the same code with that hook switched off. Both fit the same data; the script prints
CPU seconds per fit, their ratio and the machine's load (ratios are stable on a shared
machine, absolute times are not).

    python benchmarks/bench_multisine.py --sizes 1000 10000 100000 --methods bcls
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

import jitterid as ji
from jitterid.systems.model import Signal
from jitterid.systems.tf import Response


def _fit_cpu(data: ji.SampledData, method: str) -> tuple[float, str]:
    t0 = time.process_time()
    res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.3), method)
    return time.process_time() - t0, res.status.name


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--methods", nargs="+", default=["bcls", "gaussian"])
    ap.add_argument("--tones", type=int, default=1, help="number of input tones")
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitterid multisine benchmark on {platform.node()} ({platform.machine()}, "
        f"{os.cpu_count()} cores, load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    freqs = np.linspace(0.17, 0.43, args.tones)
    print(
        f"# G = 2/(s+1), {args.tones} steady-state tone(s) at {np.round(freqs, 3).tolist()} Hz, "
        "U(-0.3, 0.3) known, T = 1, RationalModel(0, 1); CPU s per fit"
    )
    print(f"{'N':>8} {'method':<9} {'closed form':>12} {'node route':>11} {'ratio':>7}  status")
    u = ji.Multisine(freqs, np.ones(args.tones), end=1e12, steady_state=True)
    system = ji.TransferFunction([2.0], [1.0, 1.0])
    hook = Response.jitter_moments
    for n in args.sizes:
        rng = np.random.default_rng(n)
        data = ji.simulate(system, u, ji.Uniform(0.3), T=1.0, N=n, noise_std=0.01, rng=rng)
        for method in args.methods:
            closed, status = _fit_cpu(data, method)
            Response.jitter_moments = Signal.jitter_moments  # type: ignore[method-assign]
            try:
                node, status_node = _fit_cpu(data, method)
            finally:
                Response.jitter_moments = hook  # type: ignore[method-assign]
            print(
                f"{n:>8} {method:<9} {closed:>11.3f}s {node:>10.3f}s {node / closed:>7.1f}  "
                f"{status} / {status_node}"
            )


if __name__ == "__main__":
    main()
