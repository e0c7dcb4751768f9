"""
Choosing the model order
========================

What MATLAB users do with ``tfest`` over several orders, then ``aic`` and ``compare``:
:func:`jitterid.select_order` fits every candidate structure with the same jitter law and
estimator, tabulates log-likelihood, AIC, BIC and residual tests, sets aside over-order and
failed fits and chooses one (:doc:`/order_selection`).

**Small**: one data set of the Table 2 experiment (N = 200) and three candidates: a first
order system, the pole pair (27) (the truth) and a second-order system with a zero.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji

rng = np.random.default_rng(1)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(202.0, rng)
data = ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)

candidates = [ji.RationalModel(0, 1), ji.PolePairGain(), ji.RationalModel(1, 2)]
sel = ji.select_order(data, candidates, ji.Uniform(0.5), "bcls")
print(sel.summary())

# %%
# BIC per candidate, relative to the lowest (the chosen one is highlighted); a gap above
# 10 is very strong evidence against the higher one.
bic = np.array([row.bic for row in sel.rows])
labels = [row.label for row in sel.rows]
fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
colors = ["C2" if i == sel.chosen else "C0" for i in range(len(bic))]
ax.bar(labels, bic - bic.min(), color=colors)
ax.set_yscale("symlog", linthresh=10)
for i, row in enumerate(sel.rows):
    note = "chosen" if i == sel.chosen else ("over-order, set aside" if row.over_order else "")
    ax.annotate(
        note,
        (i, bic[i] - bic.min()),
        xytext=(0, 3),
        textcoords="offset points",
        ha="center",
        fontsize="small",
    )
ax.axhline(10, color="C3", ls="--", lw=1, label="BIC gap 10")
ax.set_ylabel("BIC - min BIC")
ax.set_title(f"order selection by BIC, N = 200; chosen: {sel.best.label}")
ax.legend(fontsize="small")
ax.grid(True, axis="y", alpha=0.3)
plt.show()
