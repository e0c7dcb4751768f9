"""Scale benchmark (issue 6): fit time and peak memory against N, and the fast time-domain
path for mu_Y against the paper's frequency-domain integral (14b) at equal accuracy.

Each fit runs in a fresh subprocess so that its peak RSS is its own.

    python benchmarks/bench_scale.py [--sizes 1000 10000 100000] [--methods bcls gaussian]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np

CHILD = r"""
import json, resource, sys, time
import numpy as np
import jitterid as ji
N, method = int(sys.argv[1]), sys.argv[2]
T = 1.0
rng = np.random.default_rng(N)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(N * T + 2, rng)
data = ji.simulate(truth, u, ji.Uniform(0.5), T, N, 0.01, rng)
f = ji.default_frequencies(N, T)
t0 = time.perf_counter(); ji.expected_dft(truth, u, ji.Uniform(0.5), T, N, f); t_mu = time.perf_counter() - t0
t0 = time.perf_counter(); res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method)
t_fit = time.perf_counter() - t0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"N": N, "method": method, "fit_s": t_fit, "mu_s": t_mu, "rss_mb": rss,
                  "success": res.success, "x": res.x.tolist()}))
"""


def run_child(N: int, method: str) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(N), method], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def paths_ratio(N: int) -> tuple[float, float, float]:
    """(fast time, reference time, max |difference|) for mu_Y on the DFT grid."""
    import jitterid as ji
    from jitterid import spectral

    T = 1.0
    rng = np.random.default_rng(7)
    g = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(N * T + 2, rng)
    law = ji.Uniform(0.5)
    f = ji.default_frequencies(N, T)
    t0 = time.perf_counter()
    fast = ji.expected_dft(g, u, law, T, N, f)
    t_fast = time.perf_counter() - t0
    psi_max = 150.0  # reference truncation error < 1e-6 here (decays like psi_max^-3)
    n_psi = spectral.integral_grid_size(psi_max, T, N, (0.0, u.end + 25.0))
    t0 = time.perf_counter()
    ref = spectral.expected_dft_integral(
        lambda p: g.freqresp(p) * u.fourier(p), law, T, N, f, psi_max=psi_max, n_psi=n_psi
    )
    t_ref = time.perf_counter() - t0
    return t_fast, t_ref, float(np.max(np.abs(fast - ref)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--methods", nargs="+", default=["bcls", "gaussian"])
    ap.add_argument("--paths", type=int, nargs="*", default=[200, 2000], help="N for the path ratio")
    args = ap.parse_args()
    print(f"# jitterid scale benchmark, {time.strftime('%Y-%m-%d')}")
    print(f"{'N':>9} {'method':<9} {'fit':>9} {'mu_Y':>9} {'fit/mu':>7} {'peak RSS':>9}")
    for method in args.methods:
        rows = [run_child(N, method) for N in args.sizes]
        for r in rows:
            print(f"{r['N']:>9} {method:<9} {r['fit_s']:>8.2f}s {r['mu_s'] * 1e3:>7.1f}ms "
                  f"{r['fit_s'] / r['mu_s']:>7.0f} {r['rss_mb']:>7.0f}MB" + ("" if r["success"] else "  FAILED"))
        if len(rows) > 1:
            slope = np.polyfit(np.log([r["N"] for r in rows]), np.log([r["fit_s"] for r in rows]), 1)[0]
            print(f"{'':>9} {method:<9} log-log slope of fit time against N: {slope:.2f}")
    for N in args.paths:
        t_fast, t_ref, err = paths_ratio(N)
        print(f"mu_Y at N = {N}: fast {t_fast * 1e3:.1f} ms, paper's integral (14b) {t_ref * 1e3:.0f} ms, "
              f"ratio {t_ref / t_fast:.0f}x, max |difference| {err:.1e}")


if __name__ == "__main__":
    main()
