"""Fit times of a signal model with no input (the model protocol's generic path): a sinusoid
s(t) = A sin(2 pi f t + phi) + c as a ``SignalModel`` with its gradient and slope, under
U(-0.8, 0.8) jitter (T = 1 s, f = 0.23 Hz, noise 0.05 known except for ml), at N = 400 and
4000. Prints CPU seconds per fit (median) with the machine's load.

    python benchmarks/bench_signal.py [--runs 5]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from threadpoolctl import threadpool_limits

import jitterid as ji

TRUTH = np.array([1.5, 0.4, 0.23, 0.3])


def _arg(t: np.ndarray, th: np.ndarray) -> np.ndarray:
    return 2 * np.pi * th[2] * t + th[1]


def _s(t: np.ndarray, th: np.ndarray) -> np.ndarray:
    return th[0] * np.sin(_arg(t, th)) + th[3]


def _grad(t: np.ndarray, th: np.ndarray) -> np.ndarray:
    c = th[0] * np.cos(_arg(t, th))
    return np.vstack([np.sin(_arg(t, th)), c, c * 2 * np.pi * t, np.ones_like(t)])


def _slope(t: np.ndarray, th: np.ndarray) -> np.ndarray:
    return th[0] * 2 * np.pi * th[2] * np.cos(_arg(t, th))


def _rate(th: np.ndarray) -> float:
    return 2 * np.pi * abs(th[2])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--sizes", type=int, nargs="+", default=[400, 4000])
    args = ap.parse_args()
    law = ji.Uniform(0.8)
    model = ji.SignalModel(
        _s,
        ("A", "phi", "f", "c"),
        starts=[TRUTH * [0.8, 1.0, 1.00005, 0.5]],
        rate=_rate,
        bounds=((-np.inf, np.inf), (-np.inf, np.inf), (1e-3, 0.5), (-np.inf, np.inf)),
        gradient=_grad,
        slope=_slope,
        gain_params=(0, 3),
    )
    print(
        f"# signal model fits, CPU s per fit (median of {args.runs}), load {os.getloadavg()[0]:.1f}"
    )
    print(f"{'N':>6} {'method':<10} {'CPU s':>8} {'success':>8}")
    for N in args.sizes:
        for method in ("ls", "bcls", "gaussian", "ml"):
            times, ok = [], 0
            for seed in range(args.runs):
                rng = np.random.default_rng(seed)
                t = np.arange(N) + law.sample(N, rng)
                data = ji.SampledData(_s(t, TRUTH) + 0.05 * rng.standard_normal(N), 1.0, None)
                with threadpool_limits(1, "blas"):
                    t0 = time.process_time()
                    res = ji.fit(
                        data,
                        model,
                        ji.NoJitter() if method == "ls" else law,
                        method,
                        noise_std=None if method in ("ls", "ml") else 0.05,
                    )
                    times.append(time.process_time() - t0)
                ok += res.success
            print(f"{N:>6} {method:<10} {np.median(times):>8.3f} {ok:>4}/{args.runs}", flush=True)


if __name__ == "__main__":
    main()
