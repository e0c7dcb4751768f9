"""
Exact maximum likelihood against the Cramér-Rao bound
=====================================================

The exact likelihood of the jittered samples (``method="ml"``, :doc:`/ml_and_crb`) is
compared with the Cramér-Rao bound :func:`jitterid.crb` on the Table 2 system with known
uniform jitter: the standard deviation of the ML estimates over Monte Carlo realizations
against the square root of the bound, and against BCLS (14).

**Small**: N = 100 samples and 12 realizations, so the empirical standard deviations carry
about 20 % error of their own; :doc:`/reproduction/table2` has the 128-realization version.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji

T, N, noise_std, runs = 1.0, 100, 0.01, 12
theta0 = np.array([6.25, -1.5, 2.0])
names = ("k0", "pr", "pi")
truth = ji.PolePairGain().system(theta0)
jitter = ji.Uniform(T / 2)

rng = np.random.default_rng(11)
est = {"bcls": [], "ml": []}
bounds = []
for _ in range(runs):
    u = ji.telegraph_input(N * T + 2, rng)
    data = ji.simulate(truth, u, jitter, T, N, noise_std, rng)
    for method, rows in est.items():
        res = ji.fit(data, ji.PolePairGain(), jitter, method=method)
        rows.append([res.params[n] for n in names])
    # The bound depends on the input realization: average it over them.
    bounds.append(np.diag(ji.crb(ji.PolePairGain(), jitter, u, T, N, noise_std, theta0)))
sqrt_crb = np.sqrt(np.mean(bounds, axis=0))
std = {m: np.std(np.array(v), axis=0, ddof=1) for m, v in est.items()}

print(f"{'':>8}" + "".join(f"{n:>10}" for n in names))
print(f"{'√CRB':>8}" + "".join(f"{v:>10.4f}" for v in sqrt_crb))
for method, s in std.items():
    print(f"{method:>8}" + "".join(f"{v:>10.4f}" for v in s))

# %%
# Standard deviation relative to the bound (1 is efficient).
fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
x = np.arange(len(names))
for i, (method, s) in enumerate(std.items()):
    ax.bar(x + (i - 0.5) * 0.35, s / sqrt_crb, width=0.35, label=method.upper())
ax.axhline(1.0, color="k", ls="--", lw=1, label="Cramér-Rao bound")
ax.set_xticks(x, names)
ax.set_ylabel("std / √CRB (log scale)")
ax.set_yscale("log")
ax.set_title(f"{runs} realizations, N = {N}, uniform jitter U(-T/2, T/2)")
ax.legend(fontsize="small")
ax.grid(True, axis="y", alpha=0.3)
plt.show()
