"""Sine-wave metrology: measuring sampling jitter from a sine record (ADC / oscilloscope tests).

:mod:`jitterid.metrology.sinefit` holds the classical methods of IEEE Std 1057 / 1241
(periodogram frequency estimate, three- and four-parameter least-squares sine fits and the
slope-regression jitter estimate) that the jitter-aware likelihood meter starts from and is
compared against. They are pure numpy/scipy and usable on their own.
"""

from .sinefit import (
    SineFit,
    SlopeRegression,
    periodogram_peak,
    sine_fit_3,
    sine_fit_4,
    slope_regression_jitter,
)

__all__ = [
    "SineFit",
    "SlopeRegression",
    "periodogram_peak",
    "sine_fit_3",
    "sine_fit_4",
    "slope_regression_jitter",
]
