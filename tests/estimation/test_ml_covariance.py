"""The exact likelihood's covariance where a jitter shape is differenced inside the score
(the family (26)'s n): central differences of the score, against second differences of
-2 ln L (the referee)."""

from __future__ import annotations

import numpy as np
from helpers import table2_data

import jitterid as ji
from jitterid import finite_diff
from jitterid.estimation import covariance as cv
from jitterid.estimation.problem import Problem


def test_ml_covariance_with_a_differenced_shape_matches_second_differences():
    data = table2_data(5, ji.SumOfUniforms(2, 0.29), n=120)
    f = ji.default_frequencies(data.N, data.T)
    problem = Problem(data, ji.PolePairGain(), ji.SumOfUniformsFamily(), "ml", f, None)
    lik = problem.likelihood
    assert lik is not None
    x = np.array([1.6, 0.28, 6.2, -1.5, 2.0, 0.1])  # inside the piece (1, 2), off the optimum
    assert not lik.analytic_scores(x)  # n is differenced: the route under test
    # (the first pass of covariance(), before a shape the data do not identify is held)
    cov = cv._held_covariance(problem, x, "oim", None, np.zeros(x.size, dtype=bool))
    info = lik.information(x, data.y)
    h, free = cv._steps(x, problem.bounds, cv._natural_scale(info))
    assert free.all()
    H = finite_diff.hessian(problem.objective, x, h)  # of V = -2 ln L
    Hc = 2 * np.linalg.inv(cov)  # the Hessian the covariance inverted
    d = np.sqrt(np.abs(np.diag(H)))
    np.testing.assert_allclose(Hc / np.outer(d, d), H / np.outer(d, d), atol=1e-3)
