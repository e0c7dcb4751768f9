"""Jitter laws and families: :mod:`.laws` (the paper's), :mod:`.regular` (smooth in their shape),
and :mod:`.registry` (the one table of law and family kinds by name)."""

from .laws import (
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
from .regular import (
    DualDirac,
    DualDiracFamily,
    GaussianScaleMixture,
    GaussianScaleMixtureFamily,
    GeneralizedNormal,
    GeneralizedNormalFamily,
)

__all__ = [
    "CustomJitter",
    "DualDirac",
    "DualDiracFamily",
    "Gaussian",
    "GaussianFamily",
    "GaussianScaleMixture",
    "GaussianScaleMixtureFamily",
    "GeneralizedNormal",
    "GeneralizedNormalFamily",
    "JitterFamily",
    "JitterLaw",
    "NoJitter",
    "Shifted",
    "SumOfUniforms",
    "SumOfUniformsFamily",
    "Uniform",
    "UniformFamily",
]
