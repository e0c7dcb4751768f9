"""
Bode plot with a confidence band
================================

Fit the Table 2 system by BCLS (14) on one simulated data set and draw its Bode plot with a
pointwise 95 % band (:func:`jitterid.bode_band`, the delta method on log G, from the fit's
covariance), against the ordinary LS fit and the truth
(:func:`jitterid.plots.plot_bode`).

**Small**: one realization with N = 200 samples; the band is that data set's, not a Monte
Carlo spread.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji
from jitterid import plots

rng = np.random.default_rng(1)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(202.0, rng)
data = ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)

ls = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="ls")
bcls = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
print(bcls.summary())

# %%
# The band at frequencies up to the Nyquist frequency 1/(2T) = 0.5 Hz.
f = np.logspace(-2, np.log10(0.5), 120)
band = ji.bode_band(bcls, f, level=0.95)
p = plots.plot_bode(band, {"ordinary LS": ls.system, "truth": truth}, label="BCLS (14)")
p.figure.suptitle("BCLS with its 95 % band, N = 200, uniform jitter U(-T/2, T/2)")
plt.show()
