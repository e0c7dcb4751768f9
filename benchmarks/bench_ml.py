"""Exact maximum-likelihood benchmark (issue 4): one ML fit on the paper's experiments.

Prints median wall (and CPU) times over R realizations of

- Table 2 (T = 1, N = 200, known U(-0.5, 0.5) jitter, noise std 0.01, PolePairGain):
  ``fit(method="ml")`` end to end (OE start, BCLS, ML), target <= 300 ms; and the ML stage
  alone, started from the BCLS estimate (``fit(..., start=bcls.x)``);
- Table 3 (jitter SumOfUniforms(2, 1/(2 sqrt 3)), SumOfUniformsFamily(a_max=0.5) free: 5
  parameters): the same two figures, target <= 1 s for the fit and <= 8x the Table 2 fit
  (the ratio of the medians is printed).

The lazy covariance (inverse observed information) is timed separately. With
``--accuracy`` it first prints the quadrature error of the default rule against a rule with
panels 4x shorter and twice the order, per jitter law and noise level, with node counts and
the time of one likelihood evaluation.

    python benchmarks/bench_ml.py [--runs R] [--joe-runs R3] [--accuracy]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

import jitterid as ji

T, N, NOISE = 1.0, 200, 0.01
TRUTH = [6.25, -1.5, 2.0]


def _data(seed: int, law: ji.JitterLaw) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(N * T + 2, rng)
    return ji.simulate(ji.PolePairGain().system(TRUTH), u, law, T, N, NOISE, rng)


def _timed(fn):  # type: ignore[no-untyped-def]
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def _bench(label: str, datasets: list[ji.SampledData], jitter, target: float) -> float:  # type: ignore[no-untyped-def]
    structure = ji.PolePairGain()
    rows: dict[str, list[tuple[float, float]]] = {"fit": [], "ml stage": [], "bcls": [], "cov": []}
    ok = 0
    for d in datasets:
        bcls, w, c = _timed(lambda d=d: ji.fit(d, structure, jitter, method="bcls"))
        rows["bcls"].append((w, c))
        res, w, c = _timed(lambda d=d: ji.fit(d, structure, jitter, method="ml"))
        rows["fit"].append((w, c))
        ok += res.success
        _, w, c = _timed(lambda res=res: res.cov)
        rows["cov"].append((w, c))
        _, w, c = _timed(lambda d=d, b=bcls: ji.fit(d, structure, jitter, method="ml", start=b.x))
        rows["ml stage"].append((w, c))
    print(f"\n{label}: {len(datasets)} realizations, {ok} ML fits converged")
    print(f"  {'step':<34} {'median wall':>12} {'median CPU':>11}")
    names = {
        "fit": "fit(method='ml'), end to end",
        "ml stage": "ML from the BCLS estimate",
        "bcls": "fit(method='bcls') (for reference)",
        "cov": "covariance (observed information)",
    }
    for key, name in names.items():
        wall, cpu = np.median(np.array(rows[key]), axis=0)
        print(f"  {name:<34} {wall * 1e3:>9.0f} ms {cpu * 1e3:>8.0f} ms")
    med = float(np.median([w for w, _ in rows["fit"]]))
    verdict = "met" if med <= target else "MISSED"
    print(f"  target: fit <= {target * 1e3:.0f} ms median wall -> {verdict} ({med * 1e3:.0f} ms)")
    return med


def accuracy() -> None:
    """Default rule against a high-resolution one on the Table 2 system and input."""
    structure = ji.PolePairGain()
    print("\nquadrature of ln p(y_k), default rule (order 8, panel 4) vs order 16, panel 1")
    print(
        f"  {'jitter law':<30} {'noise':>6} {'nodes':>8} {'eval':>8} {'max |err|':>10} "
        f"{'rel err sum':>11}"
    )
    laws = [
        ji.Uniform(0.5),
        ji.Gaussian(1 / 6),
        ji.SumOfUniforms(2.0, 0.2887),
        ji.SumOfUniforms(1.4, 0.4),
    ]
    for law in laws:
        for noise in (0.01, 0.001):
            data = ji.simulate(structure.system(TRUTH), _data(7, law).u, law, T, N, noise, 7)
            lik = ji.ExactLikelihood(structure, law, data.u, T, N, noise)
            fast = lik.logpdf(TRUTH, data.y)
            ref = ji.ExactLikelihood(structure, law, data.u, T, N, noise, order=16, panel=1.0)
            slow = ref.logpdf(TRUTH, data.y)
            nodes = sum(nd.t.size for nd in lik._cache[()])
            _, _, cpu = _timed(
                lambda lik=lik, data=data: [lik.logpdf(TRUTH, data.y) for _ in range(5)]
            )
            err = np.max(np.abs(fast - slow))
            rel = abs(fast.sum() - slow.sum()) / abs(slow.sum())
            name = repr(law) if len(repr(law)) <= 30 else str(law).split(":")[0]
            print(
                f"  {name:<30} {noise:>6g} {nodes:>8} {cpu / 5 * 1e3:>6.1f}ms {err:>10.1e} "
                f"{rel:>11.1e}"
            )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--joe-runs", type=int, default=5)
    ap.add_argument("--accuracy", action="store_true")
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitterid ML benchmark on {platform.node()} "
        f"({platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load {load:.1f}), {time.strftime('%Y-%m-%d')}"
    )
    if args.accuracy:
        accuracy()
    warm = _data(999, ji.Uniform(0.5))
    ji.fit(warm, ji.PolePairGain(), ji.Uniform(0.5), method="ml")
    table2 = [_data(seed, ji.Uniform(0.5)) for seed in range(args.runs)]
    oe = _bench("Table 2 (OE, known uniform jitter, 3 parameters)", table2, ji.Uniform(0.5), 0.3)
    if args.joe_runs:
        law = ji.SumOfUniforms(2.0, 1 / (2 * np.sqrt(3)))
        table3 = [_data(100 + seed, law) for seed in range(args.joe_runs)]
        joe = _bench(
            "Table 3 (JOE, SumOfUniformsFamily(a_max=0.5), 5 parameters)",
            table3,
            ji.SumOfUniformsFamily(a_max=0.5),
            1.0,
        )
        verdict = "met" if joe <= 8 * oe else "MISSED"
        print(f"\nJOE / OE fit, median wall: {joe / oe:.1f}x (target <= 8x) -> {verdict}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# load at the end {load:.1f}")


if __name__ == "__main__":
    main()
