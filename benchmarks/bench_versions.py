"""Before/after: fit times of two checkouts of jitterid on the same data, in one run.

Runs this script's measurement in a subprocess per source tree (``PYTHONPATH=TREE/src``) and
prints a table of medians side by side, with the machine's load. Each fit is timed to the
point where its covariance is available (``res.cov``): older versions computed it lazily on
first access, newer ones inside ``fit``; a newer ``cov_type="none"`` column shows the search
alone.

    python benchmarks/bench_versions.py --before /path/to/old/tree --after . [--runs 9]

Settings (N = 200, Table 2's system and input law):
  oe-*    Uniform(0.5) known, PolePairGain, each method
  bj      gaussian with RationalNoise(0, 1) (coloured-noise structure)
  joe-ml  ml with SumOfUniformsFamily(a_max=0.5) (Table 3's setting)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

CASES = [
    ("oe-ls", "ls", "oe"),
    ("oe-bcls", "bcls", "oe"),
    ("oe-wbcls", "wbcls", "oe"),
    ("oe-asml", "asml", "oe"),
    ("oe-asml-diag", "asml-diag", "oe"),
    ("oe-gaussian", "gaussian", "oe"),
    ("oe-ml", "ml", "oe"),
    ("bj-gaussian", "gaussian", "bj"),
    ("joe-ml", "ml", "joe"),
]


def measure(runs: int) -> dict[str, dict[str, float]]:
    import inspect

    import numpy as np
    from threadpoolctl import threadpool_limits

    import jitterid as ji

    T, N, NOISE = 1.0, 200, 0.01
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    laws = {"oe": ji.Uniform(0.5), "bj": ji.Uniform(0.5), "joe": ji.SumOfUniforms(2, 0.5)}
    has_cov_type = "cov_type" in inspect.signature(ji.fit).parameters
    out: dict[str, dict[str, float]] = {}
    for label, method, kind in CASES:
        law = laws[kind]
        family = ji.SumOfUniformsFamily(a_max=0.5) if kind == "joe" else law
        kw = {"noise": ji.RationalNoise(0, 1)} if kind == "bj" else {}
        full, bare, ok = [], [], 0
        for seed in range(runs):
            rng = np.random.default_rng(seed)
            u = ji.telegraph_input(N * T + 2, rng)
            d = ji.simulate(truth, u, law, T, N, NOISE, rng)
            with threadpool_limits(1, "blas"):
                t0 = time.process_time()
                res = ji.fit(d, ji.PolePairGain(), family, method, **kw)
                _ = res.cov
                full.append(time.process_time() - t0)
                ok += bool(res.success)
                if has_cov_type:
                    t0 = time.process_time()
                    ji.fit(d, ji.PolePairGain(), family, method, cov_type="none", **kw)
                    bare.append(time.process_time() - t0)
        out[label] = {
            "fit+cov": float(np.median(full)),
            "fit": float(np.median(bare)) if bare else float("nan"),
            "ok": ok / runs,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path, help="source tree of the old version")
    ap.add_argument("--after", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--runs", type=int, default=9)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(measure(a.runs)))
        return
    trees = {"before": a.before, "after": a.after} if a.before else {"after": a.after}
    results = {}
    for name, tree in trees.items():
        env = {**os.environ, "PYTHONPATH": str(Path(tree).resolve() / "src")}
        proc = subprocess.run(
            [sys.executable, __file__, "--child", "--runs", str(a.runs)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        results[name] = json.loads(proc.stdout.strip().splitlines()[-1])
    load = os.getloadavg()[0]
    print(
        f"# jitterid before/after, CPU seconds per fit (median of {a.runs}), load {load:.1f}, "
        f"{time.strftime('%Y-%m-%d %H:%M')}"
    )
    head = f"{'case':<13}" + "".join(f"{n + ' fit+cov':>16}" for n in results)
    head += f"{'after fit only':>16}{'after/before':>14}"
    print(head)
    for label, *_ in CASES:
        row = f"{label:<13}"
        for n in results:
            r = results[n][label]
            row += f"{r['fit+cov']:>9.3f} ({100 * r['ok']:>3.0f}%)"
        row += f"{results['after'][label]['fit']:>14.3f} s"
        if "before" in results:
            row += (
                f"{results['after'][label]['fit+cov'] / results['before'][label]['fit+cov']:>14.2f}"
            )
        print(row)


if __name__ == "__main__":
    main()
