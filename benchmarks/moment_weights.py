"""The moment route (``measure_jitter(..., method="gaussian")``) on float and quantised
records: the efficiency its weights give (session 26).

Records made here with numpy, ``--records`` a setting of ``--n`` samples, seeds 0, 1, ...
(the tone's phase, and at 1 GS/s its frequency within +-100 kHz, drawn per record):

- ``float0``: 0.95 sin at 97.123 MHz, 1 GS/s, 2 ps Gaussian jitter, no noise;
- ``float60uV``: the same with 60 uV of Gaussian noise;
- ``1GHz100fs``: 0.49 sin at 1 GHz, 7 GS/s, 100 fs, no noise;
- ``q12``, ``q14``: ``float0`` with 0.2 steps of noise before a 12- or 14-bit quantiser
  of full scale +-1 (undithered);
- ``0.3rad``: 1.3 sin at 123 Hz, 1 kS/s, 0.3 rad of phase spread, noise 1e-2 (beyond
  0.2 rad the law-free route hands the record to the exact likelihood).

Printed per setting: the bias of the std over the truth (its SEM), the spread, the mean
stated error, the RMSE, the spread of the error against each record's realised jitter std
(what a test engineer compares a simulator's record with), the 95 % coverage and the CPU
per record, with the machine's load. For before/after, run it with ``PYTHONPATH`` at the
other tree's ``src``.

    OPENBLAS_NUM_THREADS=1 python benchmarks/moment_weights.py --records 48 --n 4096
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import jitterid as ji

SETTINGS = ("float0", "float60uV", "1GHz100fs", "q12", "q14", "0.3rad")


def record(name: str, rng: np.random.Generator, n: int) -> tuple[np.ndarray, float, float, float]:
    """(y, T, the true jitter std, the record's realised jitter std)."""
    T, f, sj, A, noise, q = 1e-9, 97.123e6, 2e-12, 0.95, 0.0, None
    if name == "float60uV":
        noise = 60e-6
    elif name == "1GHz100fs":
        T, f, sj, A = 1 / 7e9, 1e9, 100e-15, 0.49
    elif name in ("q12", "q14"):
        q = 2.0 ** -(11 if name == "q12" else 13)
        noise = 0.2 * q
    elif name == "0.3rad":
        T, f, A, noise = 1e-3, 123.0, 1.3, 1e-2
        sj = 0.3 / (2 * np.pi * f)
    if T < 1e-6:
        f += rng.uniform(-1e5, 1e5)
    t = np.arange(n) * T
    tau = sj * rng.standard_normal(n)
    y = A * np.sin(2 * np.pi * f * (t + tau) + rng.uniform(0, 2 * np.pi)) + 0.01
    y = y + noise * rng.standard_normal(n)
    if q:
        y = q * np.round(y / q)
    return y, T, sj, float(tau.std())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=48)
    ap.add_argument("--n", type=int, default=4096, help="samples per record")
    ap.add_argument("--settings", nargs="*", default=list(SETTINGS), choices=SETTINGS)
    args = ap.parse_args()
    print(
        f"# the moment route's weights, N = {args.n}, {args.records} records, load "
        f"{os.getloadavg()[0]:.1f}, {time.strftime('%F %H:%M')}"
    )
    R = args.records
    for name in args.settings:
        est, stated, real, cpu = [], [], [], 0.0
        for seed in range(R):
            y, T, sj, realised = record(name, np.random.default_rng(seed), args.n)
            c0 = time.process_time()
            m = ji.measure_jitter(y, T, method="gaussian")
            cpu += time.process_time() - c0
            est.append(m.jitter_std / sj)
            stated.append(m.jitter_std_stderr / sj)
            real.append(realised / sj)
        e, st, rl = np.array(est), np.array(stated), np.array(real)
        z = (e - 1) / st
        sem = 100 * e.std(ddof=1) / np.sqrt(R)
        print(
            f"{name:10s} bias {100 * (e.mean() - 1):+.3f} % (SEM {sem:.3f})"
            f"  spread {e.std(ddof=1):.4f}  stated {st.mean():.4f}"
            f"  RMSE {np.sqrt(np.mean((e - 1) ** 2)):.4f}  vs realised {(e - rl).std(ddof=1):.4f}"
            f"  covered {np.mean(np.abs(z) < 1.96):.2f}  {1e3 * cpu / R:.0f} CPU-ms a record",
            flush=True,
        )


if __name__ == "__main__":
    main()
