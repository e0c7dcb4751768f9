"""A held jitter shape costs nothing: the moment derivatives skip a shape pinned by the
problem's box (Problem.pinned), and a covariance that holds an unidentified shape takes its
Hessian from the pass before (the referees: the same quantities made the long way)."""

from __future__ import annotations

import numpy as np
from helpers import table2_data

import jitterid as ji
from jitterid.estimation import covariance as cv
from jitterid.estimation import jacobians
from jitterid.estimation.problem import Problem


def _problem(method: str) -> tuple[Problem, ji.SampledData]:
    data = table2_data(3, ji.SumOfUniforms(2, 0.29), n=150)
    f = ji.default_frequencies(data.N, data.T)
    fam = ji.SumOfUniformsFamily()
    return Problem(data, ji.PolePairGain(), fam, method, f, data.noise_std), data


def test_a_pinned_shape_is_not_differentiated_and_the_rest_is_unchanged():
    problem, _ = _problem("gaussian")
    x = np.array([1.6, 0.28, 6.2, -1.5, 2.0])
    _, w, dm, dw = jacobians.moment_derivatives(problem, x)
    assert np.any(dm[0] != 0)  # n's derivative, made
    box = problem.bounds
    free = np.ones(x.size, bool)
    free[0] = False
    with problem.pinned(x, free):
        assert problem.bounds[0] == (1.6, 1.6)
        _, w_p, dm_p, dw_p = jacobians.moment_derivatives(problem, x)
    assert problem.bounds == box  # restored
    assert not np.any(dm_p[0])
    assert not np.any(dw_p[0])
    np.testing.assert_array_equal(dm_p[1:], dm[1:])
    np.testing.assert_array_equal(dw_p[1:], dw[1:])
    np.testing.assert_array_equal(w_p, w)
    # after the block the derivatives are made again (the pinned pass's not remembered)
    np.testing.assert_array_equal(jacobians.moment_derivatives(problem, x)[2], dm)


def test_a_covariance_holding_an_unidentified_shape_equals_the_one_made_afresh(monkeypatch):
    # n inside a piece, taken as unidentified (as on Table 1's records): the second pass,
    # with n held, takes the first pass's Hessian block
    problem, _ = _problem("gaussian")
    x = np.array([1.6, 0.28, 6.2, -1.5, 2.0])
    flat = np.zeros(x.size, bool)
    flat[0] = True
    monkeypatch.setattr(cv, "unidentified_shapes", lambda *args: flat)
    calls: list[int] = []
    gradient = problem.objective_gradient

    def counted(z: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        calls.append(1)
        return gradient(z)

    monkeypatch.setattr(problem, "objective_gradient", counted)
    both = cv._covariance(problem, x, "sandwich", None)
    # the first pass's differences and none after (+ each pass's information at x)
    assert len(calls) == 2 * x.size + 2
    fresh = cv._held_covariance(problem, x, "sandwich", None, flat)
    assert np.isnan(both[0]).all()
    assert np.isfinite(both[1:, 1:]).all()
    np.testing.assert_allclose(both, fresh, rtol=1e-12, equal_nan=True)
