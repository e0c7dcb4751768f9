"""Monte Carlo benchmark (issues 3, 13): wall and CPU time of `jitterid reproduce`.

Runs the real command line in a fresh process (Dask cluster start-up included) into a
temporary folder, then prints the wall time, the CPU time of the command and its worker
processes, the machine's load, and the median time of one fit per estimator read back from
the stores. Targets on the 2-core machine (issue 13): `reproduce all --runs 128 --workers 2`
(Tables 1-3 with LS, BCLS, AsML, Gaussian, ML and the CRB row) <= 5 minutes; Table 2 with the
paper's three estimators only (``--target table2-paper``: LS, BCLS, AsML, no bound) <= 10 s.

    python benchmarks/bench_reproduce.py [--target all] [--runs 128] [--workers W] [--no-share]

``--no-share`` times the same command a second time with ``--no-share`` (every estimator
searching from scratch, the bound on every realization: the cost before the sharing) and
prints both with their ratio; the two runs are checked to give the same estimates. With
fewer runs than the paper's 128 it also prints the time extrapolated to 128.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from jitterid.experiments import PAPER_EXPERIMENTS, Experiment, load_experiment, packaged_path
from jitterid.experiments.runner import store_path
from jitterid.experiments.store import Estimate, Store

PAPER_METHODS = ("ls", "bcls", "asml-diag")  # the paper's three estimators of Table 2


def _paper_table2(folder: Path) -> Path:
    """A copy of the packaged table2.toml with the paper's three estimators and no bound."""
    text = packaged_path("table2").read_text(encoding="utf-8")
    lines = []
    for line in text.splitlines():
        if line.startswith("methods = "):
            line = "methods = [" + ", ".join(f'"{m}"' for m in PAPER_METHODS) + "]"
        elif line.startswith("crb = "):
            line = "crb = false"
        elif line.startswith("crb_runs = "):  # (its comment's second line stays a comment)
            continue
        elif line.startswith("estimators = {"):
            line = 'estimators = { ls = "LS", bcls = "BCLS", "asml-diag" = "AsML" }'
        lines.append(line)
    path = folder / "table2_paper.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _experiments(target: str, runs: int, folder: Path) -> tuple[list[str], list[Experiment]]:
    """The command's arguments and the experiments whose stores it writes."""
    if target == "table2-paper":
        path = _paper_table2(folder)
        return ["run", str(path)], [dataclasses.replace(load_experiment(path), runs=runs)]
    names = PAPER_EXPERIMENTS if target == "all" else (target,)
    exps = [dataclasses.replace(load_experiment(packaged_path(n)), runs=runs) for n in names]
    return ["reproduce", target], exps


def _timed(args: list[str], out: str) -> tuple[float, float]:
    """Wall and CPU seconds (this command and every process it started) of one CLI run."""
    cmd = [sys.executable, "-c", "from jitterid.cli import main; main()", *args, "--out", out]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([*cmd, "--no-progress"], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _rows(exps: list[Experiment], out: str) -> list[Estimate]:
    rows: list[Estimate] = []
    for exp in exps:
        with Store(store_path(exp, out), exp, resume=True) as store:
            rows += store.estimates()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--target",
        default="table2",
        choices=("table1", "table2", "table3", "all", "table2-paper"),
        help="a table, all three, or Table 2 with the paper's three estimators only",
    )
    ap.add_argument("--runs", type=int, default=128)
    ap.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    ap.add_argument(
        "--no-share",
        action="store_true",
        help="also time the command with --no-share (the cost without the sharing)",
    )
    args = ap.parse_args()
    modes = [("shared", [])] + ([("no-share", ["--no-share"])] if args.no_share else [])
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        words, exps = _experiments(args.target, args.runs, Path(tmp))
        words += ["--runs", str(args.runs), "--workers", str(args.workers)]
        for mode, extra in modes:
            out = str(Path(tmp) / mode)
            load0 = os.getloadavg()
            wall, cpu = _timed([*words, *extra], out)
            results[mode] = (wall, cpu, load0, os.getloadavg(), _rows(exps, out))
    n = args.runs * sum(len(e.cases) for e in exps)
    print(
        f"# jitterid reproduce benchmark on {platform.node()} ({os.cpu_count()} CPUs), "
        f"{time.strftime('%Y-%m-%d %H:%M')}"
    )
    print(
        f"jitterid {' '.join(words)}: {n} realizations "
        f"({', '.join(f'{e.name} {len(e.cases)} case(s)' for e in exps)}), "
        f"{args.workers} worker(s)"
    )
    for mode, (wall, cpu, l0, l1, _) in results.items():
        print(
            f"{mode:<9} wall {wall:7.1f} s  CPU {cpu:7.1f} s  {n / wall:6.2f} realizations/s  "
            f"load average {l0[0]:.2f} -> {l1[0]:.2f}"
        )
        if args.runs < 128:
            print(
                f"{'':<9} extrapolated to 128 runs: {wall * 128 / args.runs:.0f} s wall "
                "(start-up counted 128/runs times: an upper estimate)"
            )
    if len(results) == 2:
        (w1, c1, *_, r1), (w0, c0, *_, r0) = results["shared"], results["no-share"]
        print(f"no-share / shared: wall x{w0 / w1:.2f}, CPU x{c0 / c1:.2f}")
        bound = {(e.case_name, e.realization) for e in r1 if e.method == "crb"}
        ref = {(e.case_name, e.realization, e.method): e for e in r0}
        same = all(e.same_numbers(ref[e.case_name, e.realization, e.method]) for e in r1)
        extra = sum(
            1 for e in r0 if e.method == "crb" and (e.case_name, e.realization) not in bound
        )
        print(
            f"estimates {'identical' if same else 'DIFFERENT'} in both runs; "
            f"{extra} bound rows computed only without sharing"
        )
    rows = results["shared"][4]
    print(f"{'experiment':<13} {'method':<10} {'median fit (s)':>15} {'total (s)':>10} {'ok':>9}")
    for exp in exps:
        for m in (*exp.methods, *(("crb",) if exp.crb else ())):
            sel = [e for e in rows if e.method == m and e.case_name in {c.name for c in exp.cases}]
            t = [e.elapsed_s for e in sel]
            ok = sum(e.success for e in sel)
            print(
                f"{exp.name:<13} {m:<10} {np.median(t):>15.3f} {np.sum(t):>10.1f} {ok:>5}/{len(t)}"
            )


if __name__ == "__main__":
    main()
