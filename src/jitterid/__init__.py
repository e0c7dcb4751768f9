"""jitterid: continuous-time system identification from samples with random sampling jitter.

Implements Eng & Gustafsson, "Identification with Stochastic Sampling Time Jitter": the
mean and covariance of the measured DFT under jitter (Lemmas 1 and 2) and the estimators
that remove the jitter's bias (BCLS, WBCLS, AsML), plus the exact real-valued Gaussian
criterion. Frequencies are in Hz throughout.
"""

from .criteria import default_frequencies
from .distributions import (
    CustomJitter,
    Gaussian,
    GaussianFamily,
    JitterFamily,
    JitterLaw,
    NoJitter,
    SumOfUniforms,
    SumOfUniformsFamily,
    Uniform,
    UniformFamily,
)
from .estimate import fit
from .inputs import Input, Multisine, PiecewiseConstant, telegraph_input, zoh_input
from .models import Response, TransferFunction
from .moments import SampleMoments, dft_covariance, dft_pseudo_covariance, expected_dft, sample_moments
from .result import FitResult, FitStatus
from .simulate import SampledData, simulate
from .spectral import dirichlet, dtft
from .structures import KnownSystem, ModelStructure, PolePairGain, RationalModel

__version__ = "0.1.0"

__all__ = [
    "CustomJitter",
    "FitResult",
    "FitStatus",
    "Gaussian",
    "GaussianFamily",
    "Input",
    "JitterFamily",
    "JitterLaw",
    "KnownSystem",
    "ModelStructure",
    "Multisine",
    "NoJitter",
    "PiecewiseConstant",
    "PolePairGain",
    "RationalModel",
    "Response",
    "SampleMoments",
    "SampledData",
    "SumOfUniforms",
    "SumOfUniformsFamily",
    "TransferFunction",
    "Uniform",
    "UniformFamily",
    "default_frequencies",
    "dft_covariance",
    "dft_pseudo_covariance",
    "dirichlet",
    "dtft",
    "expected_dft",
    "fit",
    "sample_moments",
    "simulate",
    "telegraph_input",
    "zoh_input",
]
