"""jitterid: continuous-time system identification from samples with random sampling jitter.

Implements Eng & Gustafsson, "Identification with Stochastic Sampling Time Jitter": the
mean and covariance of the measured DFT under jitter (Lemmas 1 and 2) and the estimators
that remove the jitter's bias (BCLS, WBCLS, AsML), plus the exact real-valued Gaussian
criterion. Frequencies are in Hz throughout.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

from .estimation.hooks import register_loader

__version__ = "0.1.0"

#: Every public name and the module that defines it. They are imported on first use (PEP 562),
#: so that ``import jitterid`` (and ``jitterid --help``) does not pay for scipy.stats,
#: matplotlib and the estimators until a name is used; the imports under TYPE_CHECKING below
#: give type checkers the same names (tests/cli/test_lazy_help.py keeps the three lists equal).
_EXPORTS: dict[str, str] = {
    "JitterDetection": ".analysis.diagnostics",
    "ResidualTest": ".analysis.diagnostics",
    "bias_frequency": ".analysis.diagnostics",
    "detect_jitter": ".analysis.diagnostics",
    "input_correlation_test": ".analysis.diagnostics",
    "ljung_box": ".analysis.diagnostics",
    "ls_gain_factor": ".analysis.diagnostics",
    "model_output": ".analysis.diagnostics",
    "standardized_residuals": ".analysis.diagnostics",
    "PhysicalQuantities": ".analysis.quantities",
    "Quantity": ".analysis.quantities",
    "physical_quantities": ".analysis.quantities",
    "TimeResponseBand": ".analysis.responses",
    "impulse_response": ".analysis.responses",
    "step_response": ".analysis.responses",
    "OrderSelection": ".analysis.selection",
    "select_order": ".analysis.selection",
    "BodeBand": ".analysis.uncertainty",
    "PdfBand": ".analysis.uncertainty",
    "bode_band": ".analysis.uncertainty",
    "jitter_pdf_band": ".analysis.uncertainty",
    "SampledData": ".data",
    "crb": ".estimation.bounds",
    "gaussian_bound": ".estimation.bounds",
    "fitted_noise": ".estimation.boxjenkins",
    "BCLS": ".estimation.estimators",
    "LS": ".estimation.estimators",
    "ML": ".estimation.estimators",
    "WBCLS": ".estimation.estimators",
    "AsML": ".estimation.estimators",
    "AsMLDiag": ".estimation.estimators",
    "Estimator": ".estimation.estimators",
    "GaussianCriterion": ".estimation.estimators",
    "fit": ".estimation.fit",
    "ExactLikelihood": ".estimation.likelihood",
    "log_density": ".estimation.likelihood",
    "default_frequencies": ".estimation.problem",
    "FitResult": ".estimation.result",
    "FitStatus": ".estimation.result",
    "Input": ".inputs",
    "Multisine": ".inputs",
    "PiecewiseConstant": ".inputs",
    "telegraph_input": ".inputs",
    "zoh_input": ".inputs",
    "DataFileError": ".io",
    "Dataset": ".io",
    "Source": ".io",
    "load": ".io",
    "save_data": ".io",
    "save_input": ".io",
    "CustomJitter": ".jitter.laws",
    "Gaussian": ".jitter.laws",
    "GaussianFamily": ".jitter.laws",
    "JitterFamily": ".jitter.laws",
    "JitterLaw": ".jitter.laws",
    "NoJitter": ".jitter.laws",
    "Shifted": ".jitter.laws",
    "SumOfUniforms": ".jitter.laws",
    "SumOfUniformsFamily": ".jitter.laws",
    "Uniform": ".jitter.laws",
    "UniformFamily": ".jitter.laws",
    "DualDirac": ".jitter.regular",
    "DualDiracFamily": ".jitter.regular",
    "GaussianScaleMixture": ".jitter.regular",
    "GaussianScaleMixtureFamily": ".jitter.regular",
    "GeneralizedNormal": ".jitter.regular",
    "GeneralizedNormalFamily": ".jitter.regular",
    "JitterMeasurement": ".metrology.meter",
    "alias_likelihoods": ".metrology.meter",
    "measure_jitter": ".metrology.meter",
    "JitteredAutocovariance": ".moments.noise_covariance",
    "SampleCovariance": ".moments.noise_covariance",
    "coloured_dft_covariance": ".moments.noise_covariance",
    "coloured_dft_pseudo_covariance": ".moments.noise_covariance",
    "jittered_autocovariance": ".moments.noise_covariance",
    "sample_covariance": ".moments.noise_covariance",
    "dirichlet": ".moments.reference",
    "dtft": ".moments.reference",
    "SampleMoments": ".moments.sample",
    "dft_covariance": ".moments.sample",
    "dft_pseudo_covariance": ".moments.sample",
    "expected_dft": ".moments.sample",
    "sample_moments": ".moments.sample",
    "KnownNoise": ".noise.models",
    "NoiseModel": ".noise.models",
    "NoiseStructure": ".noise.models",
    "RationalNoise": ".noise.models",
    "ParamLayout": ".params",
    "plot_step_response": ".plots",
    "simulate": ".simulate",
    "Constrained": ".systems.constrained",
    "Model": ".systems.model",
    "Signal": ".systems.model",
    "SignalModel": ".systems.signals",
    "Delayed": ".systems.structures",
    "KnownSystem": ".systems.structures",
    "ModelStructure": ".systems.structures",
    "PolePairGain": ".systems.structures",
    "RationalModel": ".systems.structures",
    "Response": ".systems.tf",
    "TransferFunction": ".systems.tf",
    "MultiTone": ".systems.tones",
    "SineWave": ".systems.tones",
}

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
    "GaussianScaleMixture",
    "GaussianScaleMixtureFamily",
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


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use (then kept as an attribute);
    a subpackage or module of jitterid (``jitterid.analysis``) is imported likewise."""
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("__"):
        try:
            return importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


class _Package(types.ModuleType):
    """The package's module type: importing a submodule whose name is also a public name
    (``jitterid.simulate``) does not replace the public name by the submodule (which the
    import system sets on the package), so ``jitterid.simulate`` stays the function."""

    def __setattr__(self, name: str, value: Any) -> None:
        if (
            name in _EXPORTS
            and isinstance(value, types.ModuleType)
            and value.__name__ == f"{__name__}.{name}"
        ):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package

# The analysis functions a fit reaches (estimation.hooks) are registered by jitterid.analysis
# when it is imported: the registry imports it at its first lookup, not `import jitterid`.
register_loader(lambda: importlib.import_module(".analysis", __name__))


if TYPE_CHECKING:
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
    from .jitter.regular import (
        DualDirac,
        DualDiracFamily,
        GaussianScaleMixture,
        GaussianScaleMixtureFamily,
        GeneralizedNormal,
        GeneralizedNormalFamily,
    )
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
    from .systems.structures import (
        Delayed,
        KnownSystem,
        ModelStructure,
        PolePairGain,
        RationalModel,
    )
    from .systems.tf import Response, TransferFunction
    from .systems.tones import MultiTone, SineWave
