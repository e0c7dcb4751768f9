"""
Step response with its band, poles and damping
==============================================

What a ``tfest`` user reaches for after the fit: the step response with a pointwise 95 %
band (:meth:`jitterid.FitResult.step_response`, drawn by
:func:`jitterid.plot_step_response`) and the physical quantities with their intervals
(:meth:`jitterid.FitResult.physical_quantities`): poles, DC gain, natural frequency,
damping ratio and bandwidth.

**Small**: one simulated data set of the Table 2 experiment (N = 200); the band is that
fit's uncertainty.
"""

import matplotlib.pyplot as plt
import numpy as np

import jitterid as ji

rng = np.random.default_rng(1)
truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
u = ji.telegraph_input(202.0, rng)
data = ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)
bcls = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
ls = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="ls")

# %%
# Poles, DC gain, natural frequency (Hz), damping ratio and bandwidth (Hz), with 95 %
# intervals.
q = bcls.physical_quantities()
print(q)
print(
    f"damping ratio {q['zeta'].value:.3f}, 95 % interval "
    f"[{q['zeta'].low:.3f}, {q['zeta'].high:.3f}]"
)

# %%
# The step response with its band, against the truth and the ordinary LS fit.
step = bcls.step_response(np.linspace(0.0, 6.0, 161))
p = ji.plot_step_response(step, {"truth": truth, "ordinary LS": ls.system}, label="BCLS (14)")
p.axes[0].set_title("step response, N = 200: BCLS with its 95 % band")
plt.show()
