"""Cost of the jitter meter on a sine record: one family (Gaussian), the exact likelihood
(``method="ml"``) and the Gaussian criterion (``method="gaussian"``), against N, and the
SineWave fit by the generic model protocol (the same sine as a ``SignalModel``: moments by
quadrature) at the smallest N, in one run. Prints CPU seconds (process time: the wall time
of a loaded shared machine is not a measure) with the machine's load, and the likelihood's
nodes per sample.

    python benchmarks/bench_meter.py [--sizes 1000 10000 100000] [--runs 3]

The record: a 123 Hz tone at T = 1 ms, amplitude 1.3, Gaussian jitter with 2 pi f sigma =
0.3 rad, noise 1e-2.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from threadpoolctl import threadpool_limits

import jitterid as ji

T, F = 1e-3, 123.0


def record(n: int, seed: int) -> np.ndarray:
    sigma = 0.3 / (2 * np.pi * F)
    tone = ji.SineWave().signal([1.3, 0.3, F, 0.2])
    return ji.simulate(tone, None, ji.Gaussian(sigma), T, n, 1e-2, seed).y


def cpu(fun) -> tuple[float, object]:  # type: ignore[no-untyped-def]
    t0 = time.process_time()
    out = fun()
    return time.process_time() - t0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    print(f"# jitter meter cost, CPU s (median of {args.runs}), load {os.getloadavg()[0]:.1f}")
    print(f"{'N':>7} {'method':<9} {'CPU s':>8} {'evals':>6} {'status':<16}")
    with threadpool_limits(1):
        for n in args.sizes:
            for method in ("ml", "gaussian"):
                times, ev, st = [], [], ""
                for seed in range(args.runs):
                    y = record(n, seed)
                    dt, m = cpu(
                        lambda y=y, method=method: ji.measure_jitter(
                            y, T, laws=["gaussian"], method=method
                        )
                    )
                    times.append(dt)
                    ev.append(m.fit.nfev)  # type: ignore[attr-defined]
                    st = m.status.name  # type: ignore[attr-defined]
                print(
                    f"{n:>7} {method:<9} {np.median(times):8.2f} {int(np.median(ev)):>6} {st:<16}",
                    flush=True,
                )
    print(f"# load at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
