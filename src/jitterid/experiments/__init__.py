"""Monte Carlo studies: TOML experiment definitions, a parallel runner, a lossless store, reports.

The paper's Tables 1-3 ship as packaged definitions (``jitterid reproduce table2``); a study
of your own is a copy of one of them (``jitterid run my_study.toml``).
"""

from .config import PAPER_EXPERIMENTS, Experiment, ExperimentError, packaged_path
from .loader import load_experiment, parse_experiment

__all__ = [
    "PAPER_EXPERIMENTS",
    "Experiment",
    "ExperimentError",
    "load_experiment",
    "packaged_path",
    "parse_experiment",
]
