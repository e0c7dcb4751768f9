"""Estimators as objects (jitterid.estimation.estimators): an object and its name give the
same fit, options reach the search, registration (a taken name is refused; a new estimator
is one class and one registration), and the closed-form d^2 V / dx dy^T of each criterion
against differences of its dV/dy."""

import numpy as np
import pytest
from helpers import table2_data

import jitterid as ji

T, N = 1.0, 200


# ------------------------------------------------------------------ estimators as objects
def test_estimator_objects_and_their_names_give_the_same_fit():
    data = table2_data(13)
    by_name = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    by_object = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), ji.BCLS())
    np.testing.assert_array_equal(by_name.x, by_object.x)
    assert by_object.method == "bcls"
    once = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), ji.WBCLS(refreeze=0))
    twice = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "wbcls")  # refreeze=1
    assert once.success
    assert twice.success
    assert not np.array_equal(once.x, twice.x)  # the option reaches the search
    np.testing.assert_allclose(once.x, twice.x, rtol=0.05)
    with pytest.raises(ValueError, match="method must be one of"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bls")
    with pytest.raises(ValueError, match="refreeze"):
        ji.WBCLS(refreeze=-1)


def test_registering_a_second_estimator_under_a_taken_name_is_refused():
    from jitterid.estimation.estimators import register

    class Other(ji.Estimator):
        name = "bcls"
        equation = "-"

    with pytest.raises(ValueError, match="registered already"):
        register(Other)


def test_a_new_estimator_is_one_class_and_one_registration(estimator_registry):
    """Time-domain BCLS, sum_k (y_k - m_k)^2, written as a new estimator: fit, the search and
    the covariance take it with no other change, and on white data it agrees with the
    frequency-domain BCLS (14) within its standard errors."""
    from dataclasses import dataclass

    from jitterid.estimation.estimators import base

    @base.register
    @dataclass(frozen=True)
    class TimeBCLS(ji.Estimator):
        name = "time-bcls"
        equation = "test"
        least_squares = True
        needs_noise = False
        estimates_noise = False

        def residuals(self, problem, x):
            return problem.data.y - problem.moments(x).mean

        def jacobian(self, problem, x):
            return -problem.derivatives(x)[2].T

        def grad_y(self, problem, x):
            return 2 * self.residuals(problem, x)

    data = table2_data(15)
    new = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "time-bcls")
    ref = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    assert new.success
    assert new.method == "time-bcls"
    se = np.sqrt(np.diag(ref.cov))
    assert np.all(np.abs(new.x - ref.x) < 0.5 * se), (new.x, ref.x, se)
    np.testing.assert_allclose(np.sqrt(np.diag(new.cov)), se, rtol=0.2)


@pytest.mark.parametrize(
    ("method", "jitter"),
    [
        ("ls", ji.NoJitter()),
        ("bcls", ji.UniformFamily()),
        ("wbcls", ji.Uniform(0.5)),
        ("asml-diag", ji.UniformFamily()),
        ("gaussian", ji.GaussianFamily()),
    ],
)
def test_closed_form_d2v_dx_dy_against_differences_of_grad_y(method, jitter):
    """The covariance's G = d^2 V / dx dy^T in closed form, against central differences of
    the criterion's dV/dy (the route it replaces), at a point off the optimum."""
    from jitterid import finite_diff
    from jitterid.estimation.problem import Problem

    data = table2_data(17, known_noise=False)
    f = ji.default_frequencies(N, T)
    noise = 0.02 if method == "wbcls" else None
    problem = Problem(data, ji.PolePairGain(), jitter, method, f, noise)
    x = {"ls": [6.0, -1.4, 2.1], "wbcls": [6.0, -1.4, 2.1], "gaussian": [0.1, 6.0, -1.4, 2.1]}.get(
        method, [0.4, 6.0, -1.4, 2.1]
    )
    x = np.r_[x, 0.015] if problem.estimates_noise else np.asarray(x, float)
    if method == "wbcls":
        problem = Problem(data, ji.PolePairGain(), jitter, method, f, noise, weights_at=x * 1.01)
    G = problem.estimator.grad_y_jacobian(problem, x)
    assert G is not None
    ref = np.array(
        [finite_diff.derivative(problem.grad_y, x, i, problem.bounds[i]) for i in range(x.size)]
    )
    np.testing.assert_allclose(G, ref, rtol=1e-5, atol=1e-6 * np.max(np.abs(ref)))
