"""Box-Jenkins benchmark (issue 7): cost of the exact Gaussian criterion with coloured noise.

The time-domain criterion (y - m)^T Sigma_y^{-1} (y - m) + ln det Sigma_y with Sigma_y =
diag(Var s_k + sigma_w^2) + Toeplitz(gamma) is evaluated through the AR whitening and a banded
Cholesky factor (:mod:`jitterid.moments.noise_covariance`, (C4)): O(N (n + M0)^2). Printed per
N: one full criterion evaluation (moments of Lemmas 1-2, jittered noise covariance, banded
factor, solve), the Sigma_y part alone, and a dense O(N^3) Cholesky of the same Sigma_y for
comparison (up to N = 4000), then the log-log slope of the criterion's time against N, and
the wall time of one BJ fit on the paper's Table 2 setting with coloured noise.

    python benchmarks/bench_bj.py [--sizes 200 1000 5000 20000] [--repeats 5]

``--fits`` times whole fits instead: OE ``gaussian`` against BJ ``gaussian`` with
``noise=RationalNoise(0, 1)`` on Table 2's system (PolePairGain (6.25, -1.5, 2), telegraph
input, U(-T/2, T/2) jitter, T = 1), on white-noise data (std 0.01, Table 2) and on the bj
experiment's coloured noise, at each N of ``--fit-sizes`` (default 200 2000): wall and CPU
time (best of ``--repeats``, summed over ``--seeds`` data sets), evaluations (summed), k0, pr,
pi of the first data set, the ratio BJ/OE, and the machine load
(os.getloadavg). ``--baseline SRC`` runs the same fits with another source tree on
PYTHONPATH (e.g. /work/main/src) in a subprocess, in the same session, and prints the
before/after ratio of the BJ times:

    python benchmarks/bench_bj.py --fits --baseline /work/main/src
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Iterator

import numpy as np
from scipy.linalg import cho_factor
from threadpoolctl import threadpool_limits

import jitterid as ji
from jitterid.estimation.bjcriteria import BJProblem

T = 1.0
TRUTH = [6.25, -1.5, 2.0]
NOISE = [0.2 * np.sqrt(0.1), 0.05]  # the bj experiment's H = hb0 / (s + ha0), std 0.2
DENSE_MAX = 4000


def best_of(fun, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fun()
        times.append(time.perf_counter() - t0)
    return min(times)


def fit_times(sizes: list[int], repeats: int, seeds: int) -> list[dict[str, object]]:
    """OE gaussian and BJ gaussian fits on white and coloured data at each N (module doc):
    per data set the best of ``repeats`` runs, summed over ``seeds`` data sets."""
    structure, law, noise = ji.PolePairGain(), ji.Uniform(0.5), ji.RationalNoise(0, 1)
    truth = structure.system(TRUTH)
    rows: list[dict[str, object]] = []
    for n in sizes:
        for kind in ("white", "coloured"):
            sets = []
            for s in range(seeds):
                rng = np.random.default_rng(n + 7919 * s)
                u = ji.telegraph_input(n * T + 2, rng)
                model = noise.model(NOISE) if kind == "coloured" else None
                d = ji.simulate(truth, u, law, T, n, 0.01, rng, noise_model=model)
                sets.append(ji.SampledData(d.y, d.T, d.u))
            for label, kw in (("OE", {}), ("BJ", {"noise": noise})):
                wall = cpu = 0.0
                nfev, ok, first = 0, True, None
                for data in sets:
                    walls, cpus = [], []
                    res = None
                    for _ in range(repeats):
                        w0, c0 = time.perf_counter(), time.process_time()
                        res = ji.fit(data, structure, law, "gaussian", **kw)
                        walls.append(time.perf_counter() - w0)
                        cpus.append(time.process_time() - c0)
                    assert res is not None
                    wall, cpu, nfev = wall + min(walls), cpu + min(cpus), nfev + int(res.nfev)
                    ok = ok and bool(res.success)
                    first = first if first is not None else [float(v) for v in res.x[:3]]
                rows.append(
                    {
                        "N": n,
                        "data": kind,
                        "fit": label,
                        "wall": wall,
                        "cpu": cpu,
                        "nfev": nfev,
                        "success": ok,
                        "x": first,
                        "load": os.getloadavg()[0],
                    }
                )
    return rows


def print_fits(rows: list[dict[str, object]], title: str) -> None:
    print(f"## {title}")
    print(
        f"{'N':>6} {'data':>9} {'fit':>3} {'wall s':>8} {'cpu s':>8} {'nfev':>6} {'ok':>3} "
        f"{'load':>5}  k0, pr, pi (first set)"
    )
    for r in rows:
        x = ", ".join(f"{v:.4f}" for v in r["x"])  # type: ignore[union-attr]
        print(
            f"{r['N']:>6} {r['data']:>9} {r['fit']:>3} {r['wall']:>8.3f} {r['cpu']:>8.3f} "
            f"{r['nfev']:>6} "
            f"{'y' if r['success'] else 'n':>3} {r['load']:>5.2f}  {x}"
        )
    by = {(r["N"], r["data"], r["fit"]): r for r in rows}
    for (n, kind, fit), r in by.items():
        if fit == "BJ":
            oe = by[n, kind, "OE"]
            print(
                f"ratio BJ/OE at N = {n}, {kind} data: wall {r['wall'] / oe['wall']:.1f}, "  # type: ignore[operator]
                f"cpu {r['cpu'] / oe['cpu']:.1f}, evaluations {r['nfev']} / {oe['nfev']}"  # type: ignore[operator]
            )


def fits_main(args: argparse.Namespace) -> None:
    if args.json:
        print(json.dumps(fit_times(args.fit_sizes, args.repeats, args.seeds)))
        return
    print(
        f"# jitterid BJ vs OE fit times on {platform.node()} "
        f"({platform.processor() or platform.machine()}), "
        f"{time.strftime('%Y-%m-%d %H:%M')}, load average {os.getloadavg()}"
    )
    before = None
    if args.baseline:
        env = {**os.environ, "PYTHONPATH": args.baseline}
        cmd = [
            sys.executable,
            __file__,
            "--fits",
            "--json",
            "--repeats",
            str(args.repeats),
            "--seeds",
            str(args.seeds),
            "--fit-sizes",
            *map(str, args.fit_sizes),
        ]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
        before = json.loads(out.strip().splitlines()[-1])
        print_fits(before, f"before: {args.baseline}")
    after = fit_times(args.fit_sizes, args.repeats, args.seeds)
    print_fits(after, f"after: {ji.__file__}")
    if before is not None:
        old = {(r["N"], r["data"], r["fit"]): r for r in before}
        for r in after:
            b = old[r["N"], r["data"], r["fit"]]
            print(
                f"after/before {r['fit']} at N = {r['N']}, {r['data']} data: wall "
                f"{r['wall'] / b['wall']:.3f}, "
                f"cpu {r['cpu'] / b['cpu']:.3f}, evaluations {r['nfev']} / {b['nfev']}"
            )
    print(f"load average at the end: {os.getloadavg()}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000, 5000, 20000])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fits", action="store_true", help="time OE vs BJ gaussian fits instead")
    ap.add_argument("--fit-sizes", type=int, nargs="+", default=[200, 2000])
    ap.add_argument(
        "--seeds", type=int, default=1, help="data sets per N (times summed), with --fits"
    )
    ap.add_argument("--baseline", help="source tree to compare against (PYTHONPATH), with --fits")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.fits:
        fits_main(args)
        return
    structure, law, noise = ji.PolePairGain(), ji.Uniform(0.5), ji.RationalNoise(0, 1)
    truth = structure.system(TRUTH)
    print(
        f"# jitterid Box-Jenkins benchmark on {platform.node()} "
        f"({platform.processor() or platform.machine()}), {time.strftime('%Y-%m-%d')}"
    )
    print("exact Gaussian criterion with coloured noise H = hb0/(s + ha0), jitter U(-T/2, T/2)")
    print(f"{'N':>7} {'criterion':>11} {'Sigma_y part':>13} {'dense Cholesky':>15}")
    sizes, crit = [], []
    with threadpool_limits(1, "blas"):
        for n in args.sizes:
            rng = np.random.default_rng(n)
            u = ji.telegraph_input(n * T + 2, rng)
            data = ji.simulate(truth, u, law, T, n, 0.01, rng, noise_model=noise.model(NOISE))
            f = ji.default_frequencies(n, T)
            problem = BJProblem(data, structure, law, noise, "gaussian", f, 0.01)
            x = np.r_[TRUTH, NOISE]
            step = iter(np.linspace(1.0, 1.0 + 1e-6, 10_000))

            def evaluate(
                problem: BJProblem = problem, x: np.ndarray = x, step: Iterator[float] = step
            ) -> None:
                # a fresh parameter vector each time, so no cached moment or factor is reused
                problem.objective(x * next(step))

            d = problem.moments(x).var + 0.01**2
            gamma = problem.autocovariance(x)
            r = data.y - problem.moments(x).mean

            def sigma_part(d: np.ndarray = d, r: np.ndarray = r) -> float:
                cov = ji.SampleCovariance(d, ji.jittered_autocovariance(noise.model(NOISE), law, T))
                return float(cov.logdet + r @ cov.solve(r))

            evaluate()  # warm-up: imports, memoised quadrature rules
            t_crit = best_of(evaluate, args.repeats)
            t_sigma = best_of(sigma_part, args.repeats)
            dense = "—"
            if n <= DENSE_MAX:
                full = ji.SampleCovariance(d, gamma).dense()
                reps = max(1, args.repeats // 2)
                dense = f"{best_of(lambda full=full: cho_factor(full), reps) * 1e3:.1f} ms"
            print(f"{n:>7} {t_crit * 1e3:>8.2f} ms {t_sigma * 1e3:>10.2f} ms {dense:>15}")
            sizes.append(n)
            crit.append(t_crit)
    if len(sizes) > 1:
        slope = np.polyfit(np.log(sizes), np.log(crit), 1)[0]
        print(f"log-log slope of the criterion time against N: {slope:.2f} (O(N) is 1)")
    rng = np.random.default_rng(0)
    u = ji.telegraph_input(202.0, rng)
    data = ji.simulate(truth, u, law, T, 200, 0.01, rng, noise_model=noise.model(NOISE))
    data = ji.SampledData(data.y, data.T, data.u)
    t0 = time.perf_counter()
    res = ji.fit(data, structure, law, "gaussian", noise=noise)
    t_fit = time.perf_counter() - t0
    t0 = time.perf_counter()
    _ = res.stderr
    t_se = time.perf_counter() - t0
    print(
        f"one BJ 'gaussian' fit at N = 200 (6 parameters, white part estimated): {t_fit:.2f} s, "
        f"{res.nfev} criterion evaluations, standard errors {t_se:.2f} s, success {res.success}"
    )


if __name__ == "__main__":
    main()
