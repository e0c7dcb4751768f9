"""
Detecting jitter in a lab file
==============================

A measurement arrives as files: the samples with their nominal times, and the input that was
applied. Before fitting a jitter model, check whether one is needed: fit the ordinary model
(no jitter, least squares) and run :func:`jitterid.detect_jitter` on its residuals. Under
jitter the residual spread grows with the model's slope ``|s'(kT)|`` (a funnel), which the test
measures; it also gives the jitter std this spread implies.

**Small**: one data set of the Table 2 system (N = 200, uniform jitter U(-T/2, T/2)),
written to a temporary folder with :func:`jitterid.save_data` and :func:`jitterid.save_input`
and read back with :func:`jitterid.load`, as a lab file would be.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji
from jitterid.plots import plot_residuals

rng = np.random.default_rng(3)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(202.0, rng)
sim = ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)

with tempfile.TemporaryDirectory() as folder:
    data_file = ji.save_data(Path(folder) / "run1.csv", sim, metadata={"y_unit": "V"})
    input_file = ji.save_input(Path(folder) / "run1_input.csv", u, metadata={"u_unit": "V"})
    print(data_file.read_text().splitlines()[:4])
    lab = ji.load(data_file, input_file)

data = lab.data
print(f"loaded {data.N} samples, T = {data.T} {lab.units['time']}, y in {lab.units['y']}")

# %%
# The ordinary fit ignores the jitter; its residuals are what the test looks at.
ls = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), method="ls")
detection = ji.detect_jitter(data, ls)
print(detection.summary())

# %%
# Residuals against time (top) and against the ordinary model's slope (bottom): the spread
# widens with ``|s'|``, and the fitted +-2 std envelope follows it.
plot = plot_residuals(detection)
fig = plt.gcf()
fig.suptitle(
    f"jitter detected: p = {detection.pvalue:.1e}, implied std {detection.jitter_std:.3f} s "
    f"(true {ji.Uniform(0.5).std:.3f} s)",
    fontsize="medium",
)
plt.show()
