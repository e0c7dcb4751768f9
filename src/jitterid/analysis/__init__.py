"""analysis: what is read from a fit (diagnostics, physical quantities, responses, bands,
order selection).

Importing the package registers the functions that a
:class:`~jitterid.estimation.result.FitResult` and the post-fit checks reach
(:mod:`jitterid.estimation.hooks`): estimation sits below analysis and never imports it.
"""

from ..estimation.hooks import register_analysis
from .diagnostics import detect_jitter
from .quantities import physical_quantities
from .responses import impulse_response, step_response
from .uncertainty import bode_band, jitter_pdf_band

register_analysis(
    bode_band, detect_jitter, impulse_response, jitter_pdf_band, physical_quantities, step_response
)
