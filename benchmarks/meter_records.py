"""The meter on converter-style records outside the study grid: coverage, status and cost.

Records made here with numpy (a 1 GS/s converter, a tone near 97.1 MHz that is not
coherent, seeds 500, 501, ... by default, ``--first-seed``):

- ``hd-quant``: amplitude 0.45, offset 0.01, HD3 at -60 dBc and HD2 at -66 dBc, 2 ps
  Gaussian jitter, 30 uV thermal noise, 12-bit quantiser; ``harmonics=3`` (the generic
  exact likelihood until session 25; since, the harmonics held at their least-squares fit,
  :mod:`jitterid.metrology.held`);
- ``hd-undithered``: amplitude 0.95, HD2 at -70 and HD3 at -64 dBc, 2 ps Gaussian jitter,
  0.2 steps of noise before a 12-bit quantiser of full scale +-1 (undithered: the bins are
  modelled); ``harmonics=3``;
- ``uniform-quant``: amplitude 0.49, 3 ps uniform jitter, 20 uV, 14-bit; a pure tone (the
  structured likelihood);
- ``uniform-float``: as ``uniform-quant`` with no quantiser and 26.6 uV of noise (the same
  total noise std);
- ``dd-float``: amplitude 0.49, dual-Dirac jitter (2 ps rms Gaussian, Diracs at +-3 ps:
  3.61 ps rms), 26.6 uV, no quantiser;
- ``pj``: amplitude 0.49, 1.5 ps Gaussian jitter plus a 1 ps rms sinusoid at 1.37 MHz, 20 uV,
  no quantiser (the truth: the realised rms).

``measure_jitter(y, 1e-9, ...)`` with its defaults (``method="ml"`` unless ``--method``, the
four default laws) on each record. Printed: each record's status, law and estimate; then the
mean and spread of the estimates over the truth, how many 95 % intervals cover it, the
statuses and the CPU per record, with the machine's load.

    OPENBLAS_NUM_THREADS=1 python benchmarks/meter_records.py hd-quant --records 24 --n 1024
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections import Counter
from typing import Any

import numpy as np

import jitterid as ji

TS = 1e-9


def record(cfg: str, seed: int, N: int) -> tuple[np.ndarray, float, dict[str, Any]]:
    """(y, the true jitter std, measure_jitter's keywords) of one record."""
    rng = np.random.default_rng(seed)
    f = 97.123e6 + rng.uniform(-1e5, 1e5)
    t = np.arange(N) * TS
    if cfg == "hd-quant":
        sj = 2e-12
        ph = 2 * np.pi * f * (t + sj * rng.standard_normal(N)) + 0.7
        x = 0.45 * np.sin(ph) + 0.01
        x += 0.45 * 10 ** (-60 / 20) * np.sin(3 * ph + 0.3)
        x += 0.45 * 10 ** (-66 / 20) * np.sin(2 * ph + 1.0)
        x += 30e-6 * rng.standard_normal(N)
        return 2.0**-12 * np.round(x * 2**12), sj, {"harmonics": 3}
    if cfg == "hd-undithered":
        sj, lsb = 2e-12, 2.0**-11
        ph = 2 * np.pi * f * (t + sj * rng.standard_normal(N)) + 0.3
        x = 0.95 * np.sin(ph) + 0.95 * 10 ** (-70 / 20) * np.sin(2 * ph + 1)
        x += 0.95 * 10 ** (-64 / 20) * np.sin(3 * ph + 2)
        x += 0.2 * lsb * rng.standard_normal(N)
        return lsb * np.round(x / lsb), sj, {"harmonics": 3}
    if cfg in ("uniform-quant", "uniform-float"):
        sj = 3e-12
        tau = rng.uniform(-np.sqrt(3) * sj, np.sqrt(3) * sj, N)
        x = 0.49 * np.sin(2 * np.pi * f * (t + tau))
        if cfg == "uniform-float":
            return x + 26.6e-6 * rng.standard_normal(N), sj, {}
        x += 20e-6 * rng.standard_normal(N)
        return 2.0**-14 * np.round(x * 2**14), sj, {}
    if cfg == "dd-float":
        tau = 2e-12 * rng.standard_normal(N) + 3e-12 * rng.choice([-1.0, 1.0], N)
        y = 0.49 * np.sin(2 * np.pi * f * (t + tau)) + 26.6e-6 * rng.standard_normal(N)
        return y, math.sqrt(2e-12**2 + 3e-12**2), {}
    if cfg == "pj":
        tau = 1.5e-12 * rng.standard_normal(N)
        tau += 1e-12 * np.sqrt(2) * np.sin(2 * np.pi * 1.37e6 * t)
        y = 0.49 * np.sin(2 * np.pi * f * (t + tau)) + 20e-6 * rng.standard_normal(N)
        return y, float(tau.std()), {}
    raise ValueError(f"unknown setting {cfg!r}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    settings = ["hd-quant", "hd-undithered", "uniform-quant", "uniform-float", "dd-float", "pj"]
    ap.add_argument("setting", choices=settings)
    ap.add_argument("--records", type=int, default=24)
    ap.add_argument("--n", type=int, default=1024, help="samples per record")
    ap.add_argument("--first-seed", type=int, default=500, help="the first record's seed")
    ap.add_argument("--method", choices=["ml", "gaussian"], default="ml")
    args = ap.parse_args()
    print(
        f"# jitterid meter records, {args.setting}, N = {args.n}, method={args.method}, load "
        f"{os.getloadavg()[0]:.1f}, {time.strftime('%F %H:%M')}"
    )
    est, truth, hits, statuses = [], [], 0, Counter()
    c0 = time.process_time()
    for r in range(args.records):
        y, sj, kw = record(args.setting, args.first_seed + r, args.n)
        c1 = time.process_time()
        m = ji.measure_jitter(y, TS, method=args.method, **kw)
        cpu = time.process_time() - c1
        lo, hi = m.interval()
        hit = lo <= sj <= hi
        hits += hit
        est.append(m.jitter_std)
        truth.append(sj)
        statuses[m.status.name] += 1
        print(
            f"{r:3d} {m.status.name:<15} {m.family:<14} {m.jitter_std * 1e12:.4f} ps "
            f"+- {m.jitter_std_stderr * 1e15:.2f} fs  covers: {hit}  {cpu:.1f} CPU-s",
            flush=True,
        )
    ratio = np.asarray(est) / np.asarray(truth)
    spread = float(ratio.std(ddof=1)) if ratio.size > 1 else float("nan")
    sem = spread / np.sqrt(ratio.size)
    print(
        f"estimate / truth: mean {ratio.mean():.4f} (SEM {sem:.4f})"
        f", std {spread:.4f}; covered {hits} of {args.records}; {dict(statuses)}; "
        f"CPU {(time.process_time() - c0) / args.records:.1f} s a record"
    )


if __name__ == "__main__":
    main()
