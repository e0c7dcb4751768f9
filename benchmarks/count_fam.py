"""Load-independent cost of fits in a jitter family against a known law (issue 24): moment
passes, node layouts (plan builds) and exact-likelihood passes per fit, summed over Table
2 records, with the CPU time of the same run, statuses and estimates.

Table 2's system and input, data drawn with SumOfUniforms(2, 1/(2 sqrt 3)), N = 200; each
method fitted with the law known and with SumOfUniformsFamily(). Counts do not depend on
the machine's load, so before/after comparisons of a change that removes passes are exact
where timings on a shared machine are not.

    OPENBLAS_NUM_THREADS=1 python benchmarks/count_fam.py [--runs R] [--methods ...] [--json F]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

import jitterid as ji
from jitterid.estimation import jacobians, likelihood
from jitterid.experiments import runner
from jitterid.experiments.config import packaged_path
from jitterid.experiments.loader import load_experiment
from jitterid.moments import modal

LAW = ji.SumOfUniforms(2, 1 / (2 * np.sqrt(3)))
COUNTS = {"moment passes": 0, "plan builds": 0, "likelihood passes": 0}


def _counted(key: str, f: Callable[..., Any]) -> Callable[..., Any]:
    def wrapped(*args: Any, **kw: Any) -> Any:
        COUNTS[key] += 1
        return f(*args, **kw)

    return wrapped


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=6, help="records (Table 2 realizations)")
    ap.add_argument("--methods", nargs="+", default=["bcls", "asml", "gaussian", "ml"])
    ap.add_argument("--json", default=None, help="write every fit's status and estimate here")
    args = ap.parse_args()
    mm = _counted("moment passes", modal.modal_moments)
    jacobians.modal_moments = mm  # type: ignore[attr-defined]
    modal.SegmentPlan._build = _counted("plan builds", modal.SegmentPlan._build)  # type: ignore[method-assign]
    likelihood.ExactLikelihood._compute_terms = _counted(  # type: ignore[method-assign]
        "likelihood passes", likelihood.ExactLikelihood._compute_terms
    )
    exp = load_experiment(packaged_path("table2"))
    print(f"# jitterid JOE-count benchmark (load {os.getloadavg()[0]:.1f}), {time.strftime('%F')}")
    totals: dict[tuple[str, str], list[float]] = {}
    fits = []
    for r in range(args.runs):
        rng = np.random.default_rng(runner.seed_stream(exp.seed, 0, r))
        u = exp.input.build(exp.duration, rng)
        d = ji.simulate(exp.system.true_system(), u, LAW, exp.T, exp.N, exp.noise_std, rng)
        for method in args.methods:
            for name, model in (
                ("known law", LAW),
                ("SumOfUniformsFamily()", ji.SumOfUniformsFamily()),
            ):
                for k in COUNTS:
                    COUNTS[k] = 0
                c0 = time.process_time()
                res = ji.fit(d, ji.PolePairGain(), model, method)
                cpu = time.process_time() - c0
                row = totals.setdefault((method, name), [0, 0, 0, 0.0])
                for i, k in enumerate(COUNTS):
                    row[i] += COUNTS[k]
                row[3] += cpu
                fits.append((r, method, name, res.status.name, res.x.tolist(), res.cost))
    print(
        f"{'method':<9} {'jitter model':<22} {'moment passes':>13} {'plan builds':>11} "
        f"{'lik. passes':>11} {'CPU s':>7}  ({args.runs} records)"
    )
    for (method, name), row in totals.items():
        print(f"{method:<9} {name:<22} {row[0]:>13d} {row[1]:>11d} {row[2]:>11d} {row[3]:>7.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(fits, fh)


if __name__ == "__main__":
    main()
