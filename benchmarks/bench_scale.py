"""Scale benchmark (issue 6): fit time and peak memory against N, fit time in model
evaluations, and the fast time-domain path for mu_Y against the paper's frequency-domain
integral (14b) at equal accuracy.

The experiment is Table 2's (PolePairGain truth (6.25, -1.5, 2), telegraph input, known
U(-T/2, T/2) jitter, T = 1, noise std 0.01) at each N. Every fit runs in a fresh subprocess,
so that its peak RSS is its own, under an address-space cap (``--mem-cap-gb``): a fit that
would need more memory fails there instead of swamping the machine, and is reported so.
"One model evaluation" is one ``expected_dft`` (mu_Y on the frequency set (24)) of the true
system: node rule, modal states, quadrature and DTFT from scratch.

    python benchmarks/bench_scale.py [--sizes 1000 10000 100000 1000000]
        [--methods bcls gaussian ml] [--ratio-sizes 200 100000] [--paths 200 2000]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np

CHILD = r"""
import json, resource, sys, time
N, method, reps, cap = int(sys.argv[1]), sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
if cap > 0:
    lim = int(cap * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
import numpy as np
import jitterid as ji
from jitterid.moments import modal as _modal
T = 1.0
rng = np.random.default_rng(N)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(N * T + 2, rng)
data = ji.simulate(truth, u, ji.Uniform(0.5), T, N, 0.01, rng)
f = ji.default_frequencies(N, T)
ji.expected_dft(truth, u, ji.Uniform(0.5), T, N, f)  # imports and caches warm
t_mu, c_mu = [], []
for _ in range(reps):
    t0, c0 = time.perf_counter(), time.process_time()
    ji.expected_dft(truth, u, ji.Uniform(0.5), T, N, f)
    t_mu.append(time.perf_counter() - t0); c_mu.append(time.process_time() - c0)
if reps > 1:  # small N: warm the fit's code paths too, then take medians
    ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method)
t_fit, c_fit, ok, err = [], [], True, ""
try:
    for _ in range(reps):
        _modal.clear_plans()  # each fit from scratch: no node rule left by the last one
        t0, c0 = time.perf_counter(), time.process_time()
        res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method)
        t_fit.append(time.perf_counter() - t0); c_fit.append(time.process_time() - c0)
        ok = ok and res.success
    x = res.x.tolist()
except MemoryError:
    ok, err, x = False, f"MemoryError (over the {cap:g} GB address-space cap)", []
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t_lik = None
if method == "ml" and t_fit:  # ML's own unit: one likelihood evaluation
    lik = ji.ExactLikelihood(ji.PolePairGain(), ji.Uniform(0.5), u, T, N, 0.01)
    lik.loglik(res.x, data.y)  # designs the rule and builds the nodes
    t_l = []
    for i in range(max(reps, 3)):
        t0 = time.perf_counter(); lik.loglik(res.x * (1 + 1e-6 * (i + 1)), data.y)
        t_l.append(time.perf_counter() - t0)
    t_lik = float(np.median(t_l))
print(json.dumps({"N": N, "method": method, "fit_s": float(np.median(t_fit)) if t_fit else None,
                  "fit_cpu": float(np.median(c_fit)) if c_fit else None,
                  "mu_s": float(np.median(t_mu)), "mu_cpu": float(np.median(c_mu)), "rss_mb": rss,
                  "success": ok, "x": x, "error": err, "lik_s": t_lik}))
"""


def run_child(N: int, method: str, reps: int, cap_gb: float, timeout: float) -> dict:
    args = [sys.executable, "-c", CHILD, str(N), method, str(reps), str(cap_gb)]
    try:
        out = subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {
            "N": N,
            "method": method,
            "fit_s": None,
            "mu_s": float("nan"),
            "rss_mb": float("nan"),
            "success": False,
            "error": f"timed out after {timeout:g} s",
        }
    lines = out.stdout.strip().splitlines()
    if out.returncode != 0 or not lines:
        tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {
            "N": N,
            "method": method,
            "fit_s": None,
            "mu_s": float("nan"),
            "rss_mb": float("nan"),
            "success": False,
            "error": f"exit {out.returncode}: {tail}",
        }
    return json.loads(lines[-1])


def paths_ratio(N: int) -> tuple[float, float, float]:
    """(fast time, reference time, max |difference|) for mu_Y on the DFT grid."""
    import jitterid as ji
    from jitterid.moments import reference as spectral

    T = 1.0
    rng = np.random.default_rng(7)
    g = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(N * T + 2, rng)
    law = ji.Uniform(0.5)
    f = ji.default_frequencies(N, T)
    ji.expected_dft(g, u, law, T, N, f)  # warm
    t0 = time.perf_counter()
    fast = ji.expected_dft(g, u, law, T, N, f)
    t_fast = time.perf_counter() - t0
    psi_max = 150.0  # reference truncation error < 1e-6 here (decays like psi_max^-3)
    n_psi = spectral.integral_grid_size(psi_max, T, N, (0.0, u.end + 25.0))
    t0 = time.perf_counter()
    ref = spectral.expected_dft_integral(
        lambda p: g.frequency_response(p) * u.fourier(p), law, T, N, f, psi_max=psi_max, n_psi=n_psi
    )
    t_ref = time.perf_counter() - t0
    return t_fast, t_ref, float(np.max(np.abs(fast - ref)))


def _fmt_row(r: dict) -> str:
    if r["fit_s"] is None:
        blank = f"{'--':>9} {'':>9} {'':>9} {'':>7} {'':>9}"
        return f"{r['N']:>9} {r['method']:<9} {blank}  FAILED: {r['error']}"
    return (
        f"{r['N']:>9} {r['method']:<9} {r['fit_s']:>8.3f}s {r['fit_cpu']:>8.3f}s "
        f"{r['mu_s'] * 1e3:>7.2f}ms "
        f"{r['fit_cpu'] / r['mu_cpu']:>7.1f} {r['rss_mb']:>7.0f}MB"
        + ("" if r["success"] else "  NOT CONVERGED")
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    ap.add_argument("--methods", nargs="+", default=["bcls", "gaussian", "ml"])
    ap.add_argument(
        "--ratio-sizes",
        type=int,
        nargs="*",
        default=[200, 100000],
        help="N for the fit / model-evaluation ratio",
    )
    ap.add_argument("--ratio-reps", type=int, default=7, help="repetitions (medians) for N <= 2000")
    ap.add_argument(
        "--paths", type=int, nargs="*", default=[200, 2000], help="N for the path ratio"
    )
    ap.add_argument(
        "--mem-cap-gb", type=float, default=4.0, help="address-space cap per fit (0: none)"
    )
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds per fit")
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitterid scale benchmark on {platform.node()} ({platform.machine()}, {os.cpu_count()} "
        "cores, "
        f"load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    print("Table 2 experiment; time and peak RSS of one fit per N, each in a fresh process")
    print(
        "(wall time, and CPU time of this process: the machine may be shared; fit/mu in CPU time)"
    )
    print(
        f"{'N':>9} {'method':<9} {'fit wall':>9} {'fit CPU':>9} {'mu_Y':>9} {'fit/mu':>7} "
        f"{'peak RSS':>9}"
    )
    for method in args.methods:
        # medians of a few repetitions where one fit is short (timer and load noise)
        rows = [
            run_child(
                N, method, 5 if N <= 2000 else 3 if N <= 20000 else 1, args.mem_cap_gb, args.timeout
            )
            for N in args.sizes
        ]
        for r in rows:
            print(_fmt_row(r), flush=True)
        good = [r for r in rows if r["fit_s"] is not None]
        if len(good) > 1:
            logn = np.log([r["N"] for r in good])
            slope = np.polyfit(logn, np.log([r["fit_s"] for r in good]), 1)[0]
            slope_cpu = np.polyfit(logn, np.log([r["fit_cpu"] for r in good]), 1)[0]
            span = f"N = {good[0]['N']}..{good[-1]['N']}"
            print(
                f"{'':>9} {method:<9} log-log slope of fit time against N ({span}): {slope:.2f} "
                f"(CPU time: {slope_cpu:.2f})"
            )
    if args.ratio_sizes:
        print(
            "\nfit time in model evaluations (one mu_Y evaluation, expected_dft), medians for N "
            "<= 2000"
        )
        for method in args.methods:
            for N in args.ratio_sizes:
                reps = args.ratio_reps if N <= 2000 else 1
                r = run_child(N, method, reps, args.mem_cap_gb, args.timeout)
                if r["fit_s"] is None:
                    print(f"N = {N:>7} {method:<9} FAILED: {r['error']}")
                    continue
                extra = ""
                if r.get("lik_s"):
                    extra = (
                        f"; one likelihood evaluation {r['lik_s'] * 1e3:.2f} ms, ratio "
                        f"{r['fit_s'] / r['lik_s']:.1f}"
                    )
                print(
                    f"N = {N:>7} {method:<9} fit {r['fit_s'] * 1e3:9.1f} ms, one evaluation "
                    f"{r['mu_s'] * 1e3:7.2f} ms, ratio {r['fit_s'] / r['mu_s']:6.1f} "
                    f"(CPU: {r['fit_cpu'] * 1e3:.1f} / {r['mu_cpu'] * 1e3:.2f} ms = "
                    f"{r['fit_cpu'] / r['mu_cpu']:.1f}){extra}",
                    flush=True,
                )
    for N in args.paths:
        t_fast, t_ref, err = paths_ratio(N)
        print(
            f"mu_Y at N = {N}: fast {t_fast * 1e3:.1f} ms, paper's integral (14b) "
            f"{t_ref * 1e3:.0f} ms, "
            f"ratio {t_ref / t_fast:.0f}x, max |difference| {err:.1e}",
            flush=True,
        )


if __name__ == "__main__":
    main()
