"""
Coloured measurement noise (Box-Jenkins)
========================================

The paper's model allows coloured measurement noise v = (h * e)(t), sampled at the same
jittered instants as the signal (:doc:`/boxjenkins`). Here v is a slow Ornstein-Uhlenbeck
noise, H(s) = 0.063 / (s + 0.05), on top of a small white part. A fit that takes all noise
as white (the OE structure) can only raise its one noise level to cover the drift, and its
estimates are the less precise for it; the Box-Jenkins fit, ``noise=RationalNoise(0, 1)``,
estimates H(s) = hb0 / (s + ha0) jointly with the system and the white noise level, and
its standard errors are about three times smaller here. Both know the jitter law.

**Small**: one data set of the Table 2 system (N = 200, uniform jitter U(-T/2, T/2)); the
``bj`` experiment (``jitterid reproduce bj``) repeats this over many realizations.
"""

import dataclasses

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji

rng = np.random.default_rng(1)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
drift = ji.NoiseModel(ji.TransferFunction([0.063], [1.0, 0.05]))
u = ji.telegraph_input(202.0, rng)
sim = ji.simulate(
    truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng, noise_model=drift
)
data = dataclasses.replace(sim, noise_std=None)  # noise levels unknown: both fits estimate them

white = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian")
bj = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", noise=ji.RationalNoise(0, 1))
print(white.summary())
print(bj.summary())

# %%
# Bode magnitudes of the two estimates against the truth (left) and the noise spectra
# (right): the fitted S_v of the Box-Jenkins fit against the true one, each plus its white
# part sigma_w^2 T (the white-noise fit has only that flat level).
f = np.logspace(-3, np.log10(0.5), 300)
fig, (ax_g, ax_v) = plt.subplots(1, 2, figsize=(9, 3.8), layout="constrained")
curves = [("truth", None, "k-"), ("white-noise fit", white, "C1--"), ("Box-Jenkins fit", bj, "C0-")]
for name, res, style in curves:
    g = truth if res is None else res.system
    if res is not None:
        name += f" (k0 = {res.params['k0']:.2f} ± {res.stderr['k0']:.2f})"
    ax_g.semilogx(f, 20 * np.log10(np.abs(g.frequency_response(f))), style, label=name)
ax_g.set_xlabel("frequency (Hz)")
ax_g.set_ylabel("|G| (dB)")
ax_g.set_title("system")
ax_g.legend(fontsize="small")

T = data.T
ax_v.loglog(f, drift.spectrum(f) + 0.01**2 * T, "k-", label="truth")
ax_v.loglog(f, np.full_like(f, white.noise_std**2 * T), "C1--", label="white-noise fit")
ax_v.loglog(f, bj.noise_model.spectrum(f) + bj.noise_std**2 * T, "C0-", label="Box-Jenkins fit")
ax_v.set_xlabel("frequency (Hz)")
ax_v.set_ylabel("noise PSD (y² / Hz)")
ax_v.set_title("measurement noise")
ax_v.legend(fontsize="small")
for ax in (ax_g, ax_v):
    ax.grid(True, which="both", alpha=0.3)
plt.show()
