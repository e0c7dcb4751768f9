"""The structured sine likelihood (issue 26, item 2): CPU per record of the meter's ML at
instrument scale, and the peak memory.

The record of issue 26: a coherent ~1 GHz tone (an odd number of periods) sampled at
7 GS/s, amplitude 0.49, Gaussian jitter (default 100 fs), 50 uV of noise (``--noise 0``: a
noise-free float record), N = 2^16 and 2^20 by default. Per size, in a fresh process (so
that the peak RSS is that size's): one evaluation of ln L and of ln L with its score
(:class:`jitterid.metrology.sinelik.SineLikelihood`), then
``measure_jitter(y, T, laws=[...], method="ml")`` (the moment route, the structured ML fit
of each law, the adequacy checks; the package imported before), CPU seconds by
``time.process_time``, the number of likelihood evaluations of the chosen fit, the
estimate against the truth, and the peak RSS (``ru_maxrss``); the machine's load average
before and after. Targets (issue 26): ML at 2^16 <= 10 s, at 2^20 <= 120 s and <= 2 GB.

    python benchmarks/bench_sinelik.py                       # 2^16 and 2^20, Gaussian law
    python benchmarks/bench_sinelik.py --sizes 16 --laws gaussian uniform dual-dirac
    python benchmarks/bench_sinelik.py --noise 0 --sizes 16
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np


def _one(log2n: int, laws: list[str], jitter_s: float, noise: float, seed: int) -> dict:
    import jitterid as ji
    import jitterid.metrology.meter  # its import (~2 s) is not a record's cost
    from jitterid.metrology.sinelik import SineLikelihood

    N = 1 << log2n
    T = 1 / 7e9
    cycles = round(1e9 * N * T)
    cycles += 1 - cycles % 2  # odd: coherent, prime to N = 2^n
    f = cycles / (N * T)
    rng = np.random.default_rng(seed)
    tau = jitter_s * rng.standard_normal(N)
    y = 0.49 * np.sin(2 * np.pi * f * (np.arange(N) * T + tau) + 0.4)
    if noise > 0:
        y = y + noise * rng.standard_normal(N)
    lik = SineLikelihood(y, T, ji.GaussianFamily(sigma_max=10 * T, sigma_min=1e-9 * T))
    x = np.array([jitter_s, 0.49, 0.4, f, 0.0, max(noise, 3e-6)])
    t0 = time.process_time()
    lik.loglik(x)
    t1 = time.process_time()
    lik.scores(x)
    t2 = time.process_time()
    m = ji.measure_jitter(y, T, laws=laws, method="ml")
    t3 = time.process_time()
    lo, hi = m.interval()
    return {
        "log2N": log2n,
        "loglik_s": t1 - t0,
        "score_s": t2 - t1,
        "ml_cpu_s": t3 - t2,
        "evaluations": m.fit.nfev,
        "status": m.status.name,
        "family": m.family,
        "jitter_fs": m.jitter_std * 1e15,
        "interval_fs": [lo * 1e15, hi * 1e15],
        "true_fs": jitter_s * 1e15,
        "realised_fs": float(np.std(tau)) * 1e15,
        "route": m.fit.message.split(":")[0],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 20], help="log2 N")
    ap.add_argument("--laws", nargs="+", default=["gaussian"])
    ap.add_argument("--jitter", type=float, default=100e-15, help="jitter std, s")
    ap.add_argument("--noise", type=float, default=50e-6, help="noise std (0: none)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        print(json.dumps(_one(args.child, args.laws, args.jitter, args.noise, args.seed)))
        return
    print(f"# bench_sinelik: laws {args.laws}, jitter {args.jitter:g} s, noise {args.noise:g}")
    print(f"# load average before: {os.getloadavg()}, {os.cpu_count()} CPUs")
    for n in args.sizes:
        cmd = [sys.executable, __file__, "--child", str(n), "--laws", *args.laws]
        cmd += ["--jitter", repr(args.jitter), "--noise", repr(args.noise)]
        cmd += ["--seed", str(args.seed)]
        out = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if out.returncode != 0:
            print(f"N = 2^{n}: failed\n{out.stderr[-2000:]}")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(
            f"N = 2^{n}: ln L {r['loglik_s']:.2f} s, ln L + score {r['score_s']:.2f} s; "
            f"measure_jitter(ml) {r['ml_cpu_s']:.1f} CPU-s ({r['evaluations']} evaluations "
            f"in the chosen fit), peak RSS {r['peak_rss_mb']:.0f} MB; {r['status']} "
            f"{r['family']} {r['jitter_fs']:.3f} fs [{r['interval_fs'][0]:.3f}, "
            f"{r['interval_fs'][1]:.3f}] (law {r['true_fs']:.3g}, draws {r['realised_fs']:.3f}); "
            f"route: {r['route']}"
        )
    print(f"# load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
