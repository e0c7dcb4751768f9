"""Monte Carlo of exact ML against the Cramer-Rao bound and BCLS (issue 4 targets).

For R realizations of the paper's Table 2 (or Table 3) experiment (new input, jitter and
noise each time) fit BCLS and ML, record the estimates and their standard errors, and the
Cramer-Rao bound and the Gaussian (second-moment) bound at the truth for that input. Prints
a markdown table: mean and std of each estimator, sqrt of the bound averaged over the
inputs (sqrt(mean CRB), the bound on the std over random inputs), the efficiency
std / sqrt(CRB), ML std / BCLS std, and the coverage of nominal 95 % intervals (estimate
+- 1.96 stderr) with its binomial standard error.

    python benchmarks/mc_ml_crb.py --table 2 --reps 128 --procs 2 [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import time
from multiprocessing import Pool

import numpy as np

import jitterid as ji

T, N, NOISE = 1.0, 200, 0.01
TRUTH = np.array([6.25, -1.5, 2.0])
SOU = (2.0, 1 / (2 * np.sqrt(3)))


def setting(table: int) -> tuple[ji.JitterLaw, ji.JitterLaw | ji.JitterFamily, np.ndarray]:
    if table == 2:
        return ji.Uniform(0.5), ji.Uniform(0.5), TRUTH
    return ji.SumOfUniforms(*SOU), ji.SumOfUniformsFamily(), np.r_[SOU, TRUTH]


def one(args: tuple[int, int]) -> dict[str, list[float] | bool]:
    table, seed = args
    law, model, truth = setting(table)
    rng = np.random.default_rng(10_000 * table + seed)
    u = ji.telegraph_input(N * T + 2, rng)
    data = ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, N, NOISE, rng)
    out: dict[str, list[float] | bool] = {}
    start = None
    for method in ("bcls", "ml"):
        # ML from the BCLS estimate: what fit(method="ml") does internally, without
        # repeating the BCLS multi-start.
        res = ji.fit(data, ji.PolePairGain(), model, method=method, start=start)
        start = res.x
        out[method] = res.x.tolist()
        out[method + "_se"] = np.sqrt(np.abs(np.diag(res.cov))).tolist()
        out[method + "_ok"] = bool(res.success)
        out[method + "_jitter_std"] = [float(res.jitter_std)]
    args_b = (ji.PolePairGain(), model, u, T, N, NOISE, truth)
    out["crb"] = np.diag(ji.crb(*args_b)).tolist()
    out["gauss"] = np.diag(ji.gaussian_bound(*args_b)).tolist()
    return out


def summarise(runs: list[dict], table: int, seconds: float, reps: int) -> str:  # type: ignore[type-arg]
    _, model, truth = setting(table)
    names = (
        tuple(model.param_names) if isinstance(model, ji.JitterFamily) else ()
    ) + ji.PolePairGain().param_names
    ok = [r for r in runs if r["ml_ok"] and r["bcls_ok"]]
    R = len(ok)
    z = 1.959964
    crb = np.sqrt(np.mean([r["crb"] for r in ok], axis=0))
    gauss = np.sqrt(np.mean([r["gauss"] for r in ok], axis=0))
    est = {m: np.array([r[m] for r in ok]) for m in ("bcls", "ml")}
    se = {m: np.array([r[m + "_se"] for r in ok]) for m in ("bcls", "ml")}
    lines = [
        (
            f"Table {table} settings, {reps} realizations, {R} with both fits converged "
            f"(BCLS failed {sum(not r['bcls_ok'] for r in runs)}, ML failed "
            f"{sum(not r['ml_ok'] for r in runs)}); {seconds:.0f} s wall."
        ),
        "",
        (
            "| parameter | true | BCLS mean | BCLS std | ML mean | ML std | sqrt(CRB) | "
            "sqrt(Gauss bound) | ML std / sqrt(CRB) | ML std / BCLS std | BCLS coverage | ML "
            "coverage |"
        ),
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for i, name in enumerate(names):
        sd = {m: float(np.std(est[m][:, i], ddof=1)) for m in est}
        cov = {m: float(np.mean(np.abs(est[m][:, i] - truth[i]) <= z * se[m][:, i])) for m in est}
        bse = {m: np.sqrt(cov[m] * (1 - cov[m]) / R) for m in est}
        eff = sd["ml"] / crb[i]
        eff_se = eff / np.sqrt(2 * (R - 1))
        lines.append(
            f"| {name} | {truth[i]:.4g} | {est['bcls'][:, i].mean():.4f} | {sd['bcls']:.4f} | "
            f"{est['ml'][:, i].mean():.4f} | {sd['ml']:.4f} | {crb[i]:.4f} | {gauss[i]:.4f} | "
            f"{eff:.3f} +- {eff_se:.3f} | {sd['ml'] / sd['bcls']:.3f} | "
            f"{cov['bcls']:.3f} +- {bse['bcls']:.3f} | {cov['ml']:.3f} +- {bse['ml']:.3f} |"
        )
    if isinstance(model, ji.JitterFamily):
        js = {m: np.array([r[m + "_jitter_std"][0] for r in ok]) for m in ("bcls", "ml")}
        lines += [
            "",
            (
                f"Jitter std sigma = a / sqrt(3 (n + 1)) (true {ji.SumOfUniforms(*SOU).std:.4f}): "
                f"BCLS mean {js['bcls'].mean():.4f} std {js['bcls'].std(ddof=1):.4f}; "
                f"ML mean {js['ml'].mean():.4f} std {js['ml'].std(ddof=1):.4f}."
            ),
        ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--table", type=int, choices=(2, 3), default=2)
    ap.add_argument("--reps", type=int, default=128)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--json", default=None, help="also save the per-realization results")
    args = ap.parse_args()
    t0 = time.perf_counter()
    jobs = [(args.table, seed) for seed in range(args.reps)]
    with Pool(args.procs) as pool:
        runs = pool.map(one, jobs, chunksize=1)
    seconds = time.perf_counter() - t0
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"table": args.table, "reps": args.reps, "runs": runs}, fh)
    print(summarise(runs, args.table, seconds, args.reps))


if __name__ == "__main__":
    main()
