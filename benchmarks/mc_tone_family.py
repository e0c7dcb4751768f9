"""A pure tone's jitter std by a moment criterion with a two-parameter family (a Gaussian
scale mixture) against a one-parameter family (Gaussian), on the same records: the mean
estimate over the truth, the spread, z = (estimate - truth) / stated error and the 95 %
coverage. The records: 1.5 sin(2 pi 0.23 (k + tau_k) + 0.4) + 0.3 + 0.05 e_k, T = 1 s,
tau a scale mixture of std 0.15 s (variances 0.3 and 1.7 times 0.15^2, rho = 0.7), made
with numpy (seeds 1000, 1001, ...).

    OPENBLAS_NUM_THREADS=1 python benchmarks/mc_tone_family.py [--records R] [--n N]
        [--method gaussian]
"""

from __future__ import annotations

import argparse
import os
import time
from collections import Counter

import numpy as np

import jitterid as ji

SJ = 0.15


def record(seed: int, n: int) -> ji.SampledData:
    """One record (module doc)."""
    rng = np.random.default_rng(1000 + seed)
    scale = np.where(rng.random(n) < 0.5, np.sqrt(0.3), np.sqrt(1.7))
    tau = SJ * scale * rng.standard_normal(n)
    y = 1.5 * np.sin(2 * np.pi * 0.23 * (np.arange(n) + tau) + 0.4) + 0.3
    return ji.SampledData(y + 0.05 * rng.standard_normal(n), 1.0, None)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=64)
    ap.add_argument("--n", type=int, default=400, help="samples per record")
    ap.add_argument("--method", default="gaussian")
    args = ap.parse_args()
    print(f"# jitterid tone/family MC, load {os.getloadavg()[0]:.1f}, {time.strftime('%F %H:%M')}")
    for fam in (ji.GaussianFamily(), ji.GaussianScaleMixtureFamily()):
        est, z, st, shape = [], [], Counter(), []
        c0 = time.process_time()
        for r in range(args.records):
            res = ji.fit(record(r, args.n), ji.SineWave(), fam, args.method)
            st[res.status.name] += 1
            est.append(res.jitter_std / SJ)
            z.append((res.jitter_std - SJ) / res.jitter_std_stderr)
            if len(fam.param_names) > 1:
                shape.append(res.x[1])
        e, zz = np.array(est), np.array(z)
        tail = f"; rho median {np.median(shape):.2f}" if shape else ""
        print(
            f"{type(fam).__name__:<27} {args.method} N={args.n}: {dict(st)}; estimate/truth "
            f"{e.mean():.4f} (SEM {e.std(ddof=1) / np.sqrt(e.size):.4f}); z mean {zz.mean():+.2f} "
            f"sd {zz.std(ddof=1):.2f}; covered {np.mean(np.abs(zz) < 1.96):.2f}{tail}; "
            f"{(time.process_time() - c0) / args.records:.2f} CPU-s a fit"
        )


if __name__ == "__main__":
    main()
