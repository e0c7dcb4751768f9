"""
Table 2 in one screen: LS against BCLS and AsML
===============================================

The paper's Table 2 experiment: the pole-pair system (27),
G(s) = k0 / ((s - pr)^2 + pi^2) with theta0 = (6.25, -1.5, 2), driven by the paper's
PRBS and sampled N = 200 times at T = 1 s with uniform jitter U(-T/2, T/2) and noise
std 0.01. Each realization is fitted by ordinary least squares (LS, equation (8), which
ignores the jitter), bias-compensated least squares (BCLS, (14)) and the reduced
asymptotic ML (AsML, (23)).

**Small on purpose**: 16 realizations instead of the paper's 100 (and our reproduction's
128, see :doc:`/reproduction/table2`), so that this page builds in seconds. The means below
carry Monte Carlo error of about std / 4; LS's low k0 and pi are nonetheless visible.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji

T, N, noise_std, runs = 1.0, 200, 0.01, 16
theta0 = np.array([6.25, -1.5, 2.0])
truth = ji.PolePairGain().system(theta0)
jitter = ji.Uniform(T / 2)
methods = {"ls": "LS (8)", "bcls": "BCLS (14)", "asml-diag": "AsML (23)"}
names = ("k0", "pr", "pi")

rng = np.random.default_rng(2026)
estimates = {m: [] for m in methods}
for _ in range(runs):
    u = ji.telegraph_input(N * T + 2, rng)
    data = ji.simulate(truth, u, jitter, T, N, noise_std, rng)
    for method in methods:
        res = ji.fit(data, ji.PolePairGain(), jitter, method=method)
        estimates[method].append([res.params[n] for n in names])
estimates = {m: np.array(v) for m, v in estimates.items()}

# %%
# The table: mean and standard deviation over the realizations, next to the truth.
print(f"{'':>12}" + "".join(f"{n:>20}" for n in names))
print(f"{'truth':>12}" + "".join(f"{v:>20.3f}" for v in theta0))
for method, label in methods.items():
    est = estimates[method]
    cells = "".join(
        f"{m:>11.3f} ± {s:<6.3f}" for m, s in zip(est.mean(0), est.std(0, ddof=1), strict=True)
    )
    print(f"{label:>12}{cells}")

# %%
# The same numbers as a figure: every estimate, with the truth dashed.
fig, axes = plt.subplots(1, 3, figsize=(9, 3.4), layout="constrained")
for j, (ax, name) in enumerate(zip(axes, names, strict=True)):
    for i, method in enumerate(methods):
        x = i + 0.08 * rng.standard_normal(runs)
        ax.plot(x, estimates[method][:, j], "o", ms=4, alpha=0.6, color=f"C{i}")
        ax.errorbar(
            i + 0.3,
            estimates[method][:, j].mean(),
            yerr=estimates[method][:, j].std(ddof=1),
            fmt="s",
            color=f"C{i}",
            capsize=3,
        )
    ax.axhline(theta0[j], color="k", ls="--", lw=1)
    ax.set_xticks(range(len(methods)), [lbl.split()[0] for lbl in methods.values()])
    ax.set_title(name)
    ax.grid(True, alpha=0.3)
fig.suptitle(
    f"{runs} realizations, N = {N}: estimates (dots), mean ± std (squares), truth (dashed)"
)
plt.show()
