"""The exact likelihood of a jittered pure tone at instrument scale (issue 26, item 2).

For a record y_k = c + A sin(psi_k) + v_k, psi_k = theta_k + w tau_k, theta_k = w kT + phi,
w = 2 pi f, v_k ~ N(0, sigma^2) and tau_k i.i.d. of a law p (Gaussian, uniform,
dual-Dirac or a Gaussian scale mixture), each sample's density is the one-dimensional
integral over the sampling phase

    p(y_k) = int N(y_k - c - A sin psi; sigma^2) p_u(psi - theta_k) dpsi,               (S1)

p_u the law of the phase jitter u = w tau. A quantised record (step q) takes each sample's
bin probability over q in place of the Gaussian, sigma then the noise before the quantiser
(``SineLikelihood(..., quantisation_step=q)``; the kernel: :mod:`jitterid.metrology.
sinelik_kernel`). The generic route
(:class:`jitterid.estimation.likelihood.ExactLikelihood`) integrates over tau with panels
sized for any signal; here the integrand's structure is used. The rule (branches, Laplace
windows, Gauss-Legendre panels; its error and derivatives) is
:mod:`jitterid.metrology.sinelik_rule`; the record's sums, score and information
:class:`SineLikelihood` (:mod:`jitterid.metrology.sinelik_loglik`); the search
:func:`fit_sine_ml` (:mod:`jitterid.metrology.sinelik_fit`). This module is their public
home. With several laws the meter ranks them before their full fits
(:func:`rank_sine_law`): a law whose fit, from the leading law's optimum, cannot come
within :data:`RANK_MARGIN_BIC` of it is not fitted to its maximum; one far behind it already
on the subsample its ranking starts from is ranked out there (:func:`rank_on_subsample`,
:mod:`jitterid.metrology.sinelik_subrank`).

Noise-free records (sigma -> 0). (S1) holds for every sigma > 0 and the rule scales with
sigma (the window shrinks with the Gaussian factor), so a noise std of 1e-9 of the
amplitude costs no more than one of 1e-2. (Below about 1e-9 A double precision limits ln p:
the samples and the phases carry ~1e-16 relative rounding, i.e. 1e-16 A / sigma of a
noise std.) At sigma = 0 the density is
p(y) = sum_b p_u(psi_b - theta) / (A sqrt(1 - z^2)) (tests: the rule tends to it): a
likelihood with a moving support (|z| <= 1) and unbounded at the turning points, not a
regular one, so the noise std is searched down to a floor only, ``noise_floor``: the
physical one (a quantised record's LSB / sqrt 12) or, on a float record, the meter's
numeric floor, ``NUMERIC_FLOOR`` = 1e-3 of the jitter's own spread of the samples. (A floor
above a noise-free record's zero noise biases the jitter std low by about a quarter of the
floor's ratio to that spread: near the tone's peaks the jitter moves the samples by less
than the floor, and the model reads them as less jitter; measured -0.5 % at the generic
route's 3 %.) A noise std on its floor is reported AT_BOUND with
no standard error; the meter then says the noise is below what the record resolves.
"""

from __future__ import annotations

from .sinelik_fit import (
    NUMERIC_FLOOR,
    RANK_MARGIN_BIC,
    LawRank,
    RankStart,
    fit_sine_ml,
    rank_sine_law,
    rank_start,
    ranked_nested,
    start_subsample,
)
from .sinelik_loglik import SineLikelihood, sine_ml_applies
from .sinelik_rule import TOLERANCE
from .sinelik_subrank import rank_on_subsample

__all__ = [
    "NUMERIC_FLOOR",
    "RANK_MARGIN_BIC",
    "TOLERANCE",
    "LawRank",
    "RankStart",
    "SineLikelihood",
    "fit_sine_ml",
    "rank_on_subsample",
    "rank_sine_law",
    "rank_start",
    "ranked_nested",
    "sine_ml_applies",
    "start_subsample",
]
