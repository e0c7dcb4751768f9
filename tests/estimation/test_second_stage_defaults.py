"""A jitter family's second stage searches from the first stage's estimate alone; where the
criterion at a default start is lower than at its end, it searches again from there
(OutputErrorRoute._from_lower_default). Table 1 (G known, (n, a) of the family (26)), case
3, realization 25: the exact Gaussian criterion has a mode at n = 2.3 with a on its bound
T/2 and another at n = 0 with a std 9 % lower, -2 ln L 3.6 apart, which the walk's scan at a
fixed std does not connect. From the BCLS estimate the search ended, CONVERGED, at the
higher one (n = 0, a = 0.252); the criterion at the default start (2, 0.5) was 3.0 below
it. The referee: the criterion itself at both ends, and the start that shows the lower
mode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jitterid.estimation.estimators import as_estimator
from jitterid.estimation.problem import Problem, default_frequencies
from jitterid.experiments import runner
from jitterid.experiments.config import packaged_path
from jitterid.experiments.loader import load_experiment
from jitterid.systems.structures import as_structure

#: the end the search from the BCLS estimate reached before (session 16's code)
HIGHER_MODE = (0.0, 0.25205144778829264)


def _gaussian_fit(ci: int, r: int):
    """Table 1's realization ``r`` of case ``ci``: the ``gaussian`` row of the runner, the
    jitter family and the criterion's Problem on the same data (the referee). The runner
    realizes the gaussian row alone (no other method, no bound): the same numbers and
    message as among table1's methods (a method's row does not depend on the others,
    tests/experiments/test_runner.py::test_sharing_gives_the_numbers_of_fits_from_scratch),
    at a third to half the cost."""
    exp = load_experiment(packaged_path("table1"))
    exp = dataclasses.replace(exp, methods=("gaussian",), crb=False)
    rows, _ = runner.realize(exp, ci, r, runner.seed_stream(exp.seed, ci, r))
    g = next(e for e in rows if e.method == "gaussian")
    case = exp.cases[ci]
    data, _ = runner.realization_data(exp, ci, runner.seed_stream(exp.seed, ci, r))
    fam = exp.estimation_jitter(case, "gaussian")
    problem = Problem(
        data,
        as_structure(exp.system.model()),
        fam,
        as_estimator("gaussian"),
        default_frequencies(exp.N, exp.T),
        exp.noise_std,
    )
    return g, fam, problem


def test_a_lower_default_start_is_searched_from():
    g, _, problem = _gaussian_fit(2, 25)
    assert g.status == "CONVERGED", g.message
    assert "searched again from the default start [2.0, 0.5]" in g.message
    # the referee: the criterion at the two modes, on the same data
    new = problem.objective(np.array([g.params["n"], g.params["a"]]))
    old = problem.objective(np.array(HIGHER_MODE))
    assert new == pytest.approx(g.cost, rel=1e-9)
    assert new < old - 3.0
    assert problem.objective(np.array([2.0, 0.5])) < old  # the start that shows it
    assert g.params["n"] > 2.0
    assert g.params["a"] == pytest.approx(0.5)


def test_a_lower_shape_at_the_ends_std_is_searched_from():
    """Table 1, case 2, realization 88: from the BCLS estimate the walk ended CONVERGED at
    n = 1.19, a = 0.437; every default start is higher than that end, but n = 0 at the end's
    jitter std (a = 0.295) is 3.5 lower (OutputErrorRoute._shape_starts). The referee: the
    criterion at every integer n at the fit's jitter std is not below the fit's."""
    g, fam, problem = _gaussian_fit(1, 88)
    assert g.status == "CONVERGED", g.message
    assert "searched again from a default start's shape at its std" in g.message
    end = np.array([g.params["n"], g.params["a"]])
    assert problem.objective(end) == pytest.approx(g.cost, rel=1e-9)
    assert g.cost < problem.objective(np.array([1.1936896755898296, 0.4365306550325942])) - 3.0
    lo, hi = np.array(fam.bounds).T
    for n in range(9):
        shape = np.clip(fam.at_std([float(n), 0.25], g.jitter_std), lo, hi)
        assert problem.objective(shape) >= g.cost - 1e-6 * abs(g.cost), n
