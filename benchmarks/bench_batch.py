"""Records per second of ``jitterid jitter`` over a batch, against a loop over the peer.

Writes R records of N samples (the issue's instrument-scale record: a 1 GHz tone at
7 GS/s, amplitude 0.49, Gaussian jitter 100 fs, 50 uV of noise, non-coherent) into one
multi-record ``.npz``, then times

- ``run_batch`` (the table: jitter, interval, converter figures, one SQLite row per record)
  with 1 worker (in this process) and with ``--workers`` workers (a local Dask cluster,
  its start-up included);
- a plain loop over ``adctoolbox.analyze_error_by_phase`` (``benchmarks/peers.py``) on the
  same records, read the same way, in this process.

Prints wall seconds, records per second and this process's CPU seconds (the Dask workers'
CPU is not in it), with the machine's load.

    python benchmarks/bench_batch.py [--records 40] [--n 65536] [--workers 2]
        [--method gaussian] [--out /tmp/bench_batch]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

FS, F, A, SIGMA, NOISE = 7e9, 1e9, 0.49, 100e-15, 50e-6


def tone(n: int) -> float:
    """The tone's frequency: 1 GHz moved 0.37 bins off the grid (non-coherent)."""
    return F + 0.37 * FS / n


def write_records(path: Path, records: int, n: int, seed: int = 0) -> None:
    """R records of the instrument-scale tone, one per row of y in a .npz."""
    rng = np.random.default_rng(seed)
    T = 1 / FS
    f = tone(n)
    ys = np.empty((records, n))
    for r in range(records):
        t = np.arange(n) * T + SIGMA * rng.standard_normal(n)
        ys[r] = A * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        ys[r] += NOISE * rng.standard_normal(n)
    np.savez(path, y=ys, metadata=json.dumps({"T": T}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--n", type=int, default=1 << 16)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--method", default="gaussian", choices=["gaussian", "ml"])
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_batch"))
    ap.add_argument("--no-peer", action="store_true", help="skip adctoolbox")
    args = ap.parse_args()

    from jitterid.experiments.jitter_batch import BatchOptions, _rows, run_batch

    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)
    src = args.out / "records.npz"
    write_records(src, args.records, args.n)
    f = tone(args.n)  # given to both (each refines it)
    opts = BatchOptions(method=args.method, laws=("gaussian",), frequency=f, harmonics=1)
    print(
        f"{args.records} records of N = {args.n}, method {args.method}, load "
        f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs"
    )
    tables = {}
    for workers in sorted({1, args.workers}):
        t0, c0 = time.perf_counter(), time.process_time()
        s = run_batch(src, args.out / f"w{workers}", opts, workers=workers, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        tables[workers] = s.store
        print(
            f"jitterid batch, {workers} worker(s): {wall:8.2f} s wall  "
            f"{args.records / wall:7.2f} records/s  {cpu:8.2f} s CPU here  "
            f"({s.errors} error rows)"
        )
    if not args.no_peer:
        from peers import adctoolbox_jitter

        t0, c0 = time.perf_counter(), time.process_time()
        est = []
        for row in _rows(src, opts):
            assert not isinstance(row, str), row
            y, T = row
            est.append(adctoolbox_jitter(y, T, f))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(
            f"adctoolbox loop, 1 process:   {wall:8.2f} s wall  {args.records / wall:7.2f} "
            f"records/s  {cpu:8.2f} s CPU  (median jitter {np.median(est) * 1e15:.1f} fs)"
        )
    from jitterid.experiments.jitter_batch import BatchStore

    with BatchStore(tables[1], opts, resume=True) as store:
        rows = store.rows()
    jit = np.array([r["jitter_std_s"] for r in rows])
    print(f"jitterid median jitter {np.nanmedian(jit) * 1e15:.1f} fs (truth {SIGMA * 1e15:.0f})")


if __name__ == "__main__":
    main()
