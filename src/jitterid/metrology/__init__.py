"""Sine-wave metrology: measuring sampling jitter from a sine record (ADC / oscilloscope tests).

:mod:`jitterid.metrology.sinefit` holds the classical methods of IEEE Std 1057 / 1241
(periodogram frequency estimate, three- and four-parameter least-squares sine fits and the
slope-regression jitter estimate) that the jitter-aware likelihood meter starts from and is
compared against. They are pure numpy/scipy and usable on their own.

:mod:`jitterid.metrology.converter` gives the IEEE 1241 converter figures next to the jitter
(SNR, SINAD, ENOB, THD, SFDR, the noise floor, the jitter-limited SNR) and the
two-frequency separation of aperture jitter from noise; :mod:`jitterid.metrology.reading`
how firmly the law is chosen and the jitter each Nyquist zone implies;
:mod:`jitterid.experiments.jitter_batch` a table of many records, resumable, on Dask.
"""

from .converter import (
    ApertureSeparation,
    ConverterFigures,
    converter_figures,
    separate_aperture_jitter,
    significant_harmonics,
)
from .sinefit import (
    SineFit,
    SlopeRegression,
    periodogram_peak,
    sine_fit_3,
    sine_fit_4,
    slope_regression_jitter,
)

__all__ = [
    "ApertureSeparation",
    "ConverterFigures",
    "SineFit",
    "SlopeRegression",
    "converter_figures",
    "periodogram_peak",
    "separate_aperture_jitter",
    "significant_harmonics",
    "sine_fit_3",
    "sine_fit_4",
    "slope_regression_jitter",
]
