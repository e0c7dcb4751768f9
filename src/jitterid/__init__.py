"""jitterid: continuous-time system identification from samples with random sampling jitter.

Implements Eng & Gustafsson, "Identification with Stochastic Sampling Time Jitter": the
mean and covariance of the measured DFT under jitter (Lemmas 1 and 2) and the estimators
that remove the jitter's bias (BCLS, WBCLS, AsML), plus the exact real-valued Gaussian
criterion. Frequencies are in Hz throughout.
"""

from .analysis.diagnostics import (
    JitterDetection,
    ResidualTest,
    bias_frequency,
    detect_jitter,
    input_correlation_test,
    ljung_box,
    ls_gain_factor,
    model_output,
    standardized_residuals,
)
from .analysis.quantities import PhysicalQuantities, Quantity, physical_quantities
from .analysis.responses import TimeResponseBand, impulse_response, step_response
from .analysis.selection import OrderSelection, select_order
from .analysis.uncertainty import BodeBand, PdfBand, bode_band, jitter_pdf_band
from .data import SampledData
from .estimation.bounds import crb, gaussian_bound
from .estimation.boxjenkins import fitted_noise
from .estimation.estimators import (
    BCLS,
    LS,
    ML,
    WBCLS,
    AsML,
    AsMLDiag,
    Estimator,
    GaussianCriterion,
)
from .estimation.fit import fit
from .estimation.likelihood import ExactLikelihood, log_density
from .estimation.problem import default_frequencies
from .estimation.result import FitResult, FitStatus
from .inputs import Input, Multisine, PiecewiseConstant, telegraph_input, zoh_input
from .io import DataFileError, Dataset, Source, load, save_data, save_input
from .jitter.laws import (
    CustomJitter,
    Gaussian,
    GaussianFamily,
    JitterFamily,
    JitterLaw,
    NoJitter,
    Shifted,
    SumOfUniforms,
    SumOfUniformsFamily,
    Uniform,
    UniformFamily,
)
from .jitter.regular import DualDirac, DualDiracFamily, GeneralizedNormal, GeneralizedNormalFamily
from .metrology.meter import JitterMeasurement, alias_likelihoods, measure_jitter
from .moments.noise_covariance import (
    JitteredAutocovariance,
    SampleCovariance,
    coloured_dft_covariance,
    coloured_dft_pseudo_covariance,
    jittered_autocovariance,
    sample_covariance,
)
from .moments.reference import dirichlet, dtft
from .moments.sample import (
    SampleMoments,
    dft_covariance,
    dft_pseudo_covariance,
    expected_dft,
    sample_moments,
)
from .noise.models import KnownNoise, NoiseModel, NoiseStructure, RationalNoise
from .params import ParamLayout
from .plots import plot_step_response
from .simulate import simulate
from .systems.constrained import Constrained
from .systems.model import Model, Signal
from .systems.signals import SignalModel
from .systems.structures import Delayed, KnownSystem, ModelStructure, PolePairGain, RationalModel
from .systems.tf import Response, TransferFunction
from .systems.tones import MultiTone, SineWave

__version__ = "0.1.0"

__all__ = [
    "Constrained",
    "CustomJitter",
    "Delayed",
    "DualDirac",
    "DualDiracFamily",
    "FitResult",
    "FitStatus",
    "Gaussian",
    "GaussianFamily",
    "GeneralizedNormal",
    "GeneralizedNormalFamily",
    "Input",
    "JitterFamily",
    "JitterLaw",
    "JitterMeasurement",
    "KnownSystem",
    "Model",
    "ModelStructure",
    "MultiTone",
    "Multisine",
    "NoJitter",
    "PiecewiseConstant",
    "PolePairGain",
    "RationalModel",
    "Response",
    "SampleMoments",
    "SampledData",
    "Shifted",
    "Signal",
    "SignalModel",
    "SineWave",
    "SumOfUniforms",
    "SumOfUniformsFamily",
    "TransferFunction",
    "Uniform",
    "UniformFamily",
    "alias_likelihoods",
    "default_frequencies",
    "dft_covariance",
    "dft_pseudo_covariance",
    "dirichlet",
    "dtft",
    "expected_dft",
    "fit",
    "measure_jitter",
    "sample_moments",
    "simulate",
    "telegraph_input",
    "zoh_input",
]

# Estimators as objects, the parameter layout.
__all__ += [
    "BCLS",
    "LS",
    "ML",
    "WBCLS",
    "AsML",
    "AsMLDiag",
    "Estimator",
    "GaussianCriterion",
    "ParamLayout",
]

# Data files and diagnostics (issue 5).
__all__ += [
    "BodeBand",
    "DataFileError",
    "Dataset",
    "JitterDetection",
    "PdfBand",
    "ResidualTest",
    "Source",
    "bias_frequency",
    "bode_band",
    "detect_jitter",
    "input_correlation_test",
    "jitter_pdf_band",
    "ljung_box",
    "load",
    "ls_gain_factor",
    "model_output",
    "save_data",
    "save_input",
    "standardized_residuals",
]

# Exact likelihood, Cramer-Rao bound and confidence bands (issue 4).
__all__ += [
    "ExactLikelihood",
    "crb",
    "gaussian_bound",
    "log_density",
]

# Box-Jenkins structures under jitter: coloured noise (issue 7).
__all__ += [
    "JitteredAutocovariance",
    "KnownNoise",
    "NoiseModel",
    "NoiseStructure",
    "RationalNoise",
    "SampleCovariance",
    "coloured_dft_covariance",
    "coloured_dft_pseudo_covariance",
    "fitted_noise",
    "jittered_autocovariance",
    "sample_covariance",
]

# What a tfest user reaches for next: physical quantities, responses with bands (issue 16).
__all__ += [
    "PhysicalQuantities",
    "Quantity",
    "TimeResponseBand",
    "impulse_response",
    "physical_quantities",
    "plot_step_response",
    "step_response",
]

# Model order selection (issue 16).
__all__ += [
    "OrderSelection",
    "select_order",
]
