"""Helpers shared by test modules in several folders of ``tests/``.

The suite runs with ``--import-mode=importlib`` and ``pythonpath = ["tests"]`` (pyproject), so
test modules cannot import each other but can ``import helpers``. Fixtures shared across
folders live in ``tests/conftest.py``; data generators, referees and paths live here.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import tomllib
from pathlib import Path

import numpy as np

import jitterid as ji
from jitterid.experiments import Experiment, parse_experiment

#: The repository's root (README.md, docs/, benchmarks/).
REPO = Path(__file__).resolve().parents[1]
BENCHMARKS = REPO / "benchmarks"
DOCS = REPO / "docs"

# The paper's Table 2 setting: G = 6.25 / ((s + 1.5)^2 + 4) as a PolePairGain, a telegraph
# input, T = 1 s, N = 200, white noise std 0.01, jitter U(-0.5, 0.5).
TABLE2_T, TABLE2_N, TABLE2_NOISE = 1.0, 200, 0.01
TABLE2_TRUTH = np.array([6.25, -1.5, 2.0])


def table2_data(
    seed: int,
    jitter: ji.JitterLaw | None = None,
    noise: float = TABLE2_NOISE,
    known_noise: bool = True,
    *,
    n: int = TABLE2_N,
    noise_model: ji.NoiseModel | None = None,
) -> ji.SampledData:
    """One realization of Table 2 (``jitter`` defaults to U(-0.5, 0.5)) with ``n`` samples,
    white noise std ``noise`` and, if given, coloured noise ``noise_model`` added; with
    ``known_noise=False`` the data do not carry the noise std."""
    T = TABLE2_T
    rng = np.random.default_rng(seed)
    truth = ji.PolePairGain().system(TABLE2_TRUTH)
    u = ji.telegraph_input(n * T + 2, rng)
    law = ji.Uniform(0.5) if jitter is None else jitter
    data = ji.simulate(truth, u, law, T, n, noise, rng, noise_model=noise_model)
    return data if known_noise else ji.SampledData(data.y, T, data.u)


# Coloured noise models of the Box-Jenkins tests. RESONANT: complex poles and a zero, driven
# with intensity 0.5 (exercises every term of (N1)-(N3)); OU: r_v(t) = exp(-|t|) / 2; SLOW:
# the bj experiment's noise (correlation time 20 s, std 0.2).
RESONANT_NOISE = ji.NoiseModel(ji.TransferFunction([0.3, 1.0], [1.0, 0.8, 2.0]), intensity=0.5)
OU_NOISE = ji.NoiseModel(ji.TransferFunction([1.0], [1.0, 1.0]))
SLOW_NOISE = ji.NoiseModel(ji.TransferFunction([0.2 * np.sqrt(0.1)], [1.0, 0.05]))


def central_differences(fun, x, rel=1e-6):
    """Central differences of ``fun`` (any shape) in every coordinate of ``x``: the array of
    the derivatives along axis 0, step ``rel * max(|x_i|, 1e-2)``."""
    x = np.asarray(x, float)
    cols = []
    for i in range(x.size):
        h = rel * max(abs(x[i]), 1e-2)
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        cols.append((np.asarray(fun(up)) - np.asarray(fun(down))) / (2 * h))
    return np.array(cols)


# A tiny Monte Carlo experiment (two cases, LS and BCLS, N = 48, 3 runs) for the tests of
# jitterid.experiments: its definition as parsed TOML, and the Experiment with ``changes``.
TINY_EXPERIMENT = tomllib.loads("""
[experiment]
name = "tiny"
runs = 3
seed = 11
[sampling]
T = 1.0
N = 48
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = { k0 = 6.25, pr = -1.5, pi = 2.0 }
[jitter]
model = "known"
[[cases]]
name = "u"
law = { kind = "uniform", a = 0.5 }
[[cases]]
name = "g"
law = { kind = "gaussian", sigma = 0.05 }
[estimators]
methods = ["ls", "bcls"]
""")


def tiny_experiment(**changes) -> Experiment:
    """The tiny experiment (``TINY_EXPERIMENT``) with the fields ``changes`` replaced."""
    exp = parse_experiment(copy.deepcopy(TINY_EXPERIMENT), "tiny.toml")
    return dataclasses.replace(exp, **changes)


def read_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file as dicts (the stores' exports, ``jitterid reproduce``)."""
    return list(csv.DictReader(path.read_text().splitlines()))


def table2_post_context(lab, cov, jitter=None, **kw):
    """A :class:`jitterid.estimation.checks.PostContext` of Table 2's system at its true
    parameters over the data ``lab``, with the covariance ``cov``: a criterion of 0
    everywhere, no default starts, and a model mean that explains y (the checks' unit
    tests); the jitter law U(-0.5, 0.5) unless ``jitter`` is given; ``kw`` sets the other
    fields."""
    from jitterid.estimation.checks import PostContext

    structure = ji.PolePairGain()
    return PostContext(
        data=lab,
        structure=structure,
        jitter=ji.Uniform(0.5) if jitter is None else jitter,
        names=structure.param_names,
        bounds=structure.bounds,
        x=np.array([6.25, -1.5, 2.0]),
        cost=0.0,
        cov=cov,
        objective=lambda v: 0.0,
        model_mean=lambda v: lab.y - 0.01,  # explains y: significant
        oe_system=lambda: None,
        starts=list,
        **kw,
    )
