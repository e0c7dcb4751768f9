"""
Estimating the jitter law with the system
=========================================

When the jitter law is not known, give :func:`jitterid.fit` a family instead of a law: here
the paper's sum-of-uniforms family (26), :class:`jitterid.SumOfUniformsFamily`, whose
parameters (n, a) are estimated jointly with the system (27), as in the paper's Table 3.
The exact likelihood (``method="ml"``) is used: on so few samples the frequency-domain
estimators often cannot tell n from a.

**Small**: one data set of N = 200 samples (the paper's Table 3 uses 100 realizations); the
jitter std is well determined, n and a individually much less so.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji
from jitterid import plots

T, N = 1.0, 200
law = ji.SumOfUniforms(2, T / (2 * np.sqrt(3)))  # Table 3's truth: std 1 / (6 sqrt 3)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
rng = np.random.default_rng(1)
u = ji.telegraph_input(N * T + 2, rng)
data = ji.simulate(truth, u, law, T=T, N=N, noise_std=0.01, rng=rng)

res = ji.fit(data, ji.PolePairGain(), ji.SumOfUniformsFamily(), method="ml")
print(res.summary())
print(f"jitter std: estimated {res.jitter_law.std:.4f} s, true {law.std:.4f} s")

# %%
# The fitted jitter density with a pointwise 95 % band (from draws of the parameters),
# against the true law.
tau = np.linspace(-0.45, 0.45, 301)
band = res.jitter_pdf_band(tau, rng=0)
p = plots.plot_jitter_pdf(band, truth=law, label="ML, family (26)")
p.axes[0].set_title(f"jitter density, N = {N}")
plt.show()
