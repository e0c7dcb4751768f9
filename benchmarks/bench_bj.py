"""Box-Jenkins benchmark (issue 7): cost of the exact Gaussian criterion with coloured noise.

The time-domain criterion (y - m)^T Sigma_y^{-1} (y - m) + ln det Sigma_y with Sigma_y =
diag(Var s_k + sigma_w^2) + Toeplitz(gamma) is evaluated through the AR whitening and a banded
Cholesky factor (:mod:`jitterid.noise.covariance`, (C4)): O(N (n + M0)^2). Printed per N: one full
criterion evaluation (moments of Lemmas 1-2, jittered noise covariance, banded factor, solve),
the Sigma_y part alone, and a dense O(N^3) Cholesky of the same Sigma_y for comparison (up to
N = 4000), then the log-log slope of the criterion's time against N, and the wall time of one
BJ fit on the paper's Table 2 setting with coloured noise.

    python benchmarks/bench_bj.py [--sizes 200 1000 5000 20000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import platform
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000, 5000, 20000])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
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
                dense = f"{best_of(lambda full=full: cho_factor(full), max(1, args.repeats // 2)) * 1e3:.1f} ms"
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
