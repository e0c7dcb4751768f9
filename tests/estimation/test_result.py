"""FitResult: covariance forms (cov_type), the measurement noise in every covariance, what a
result keeps (structure, law, noise), pickling and JSON, and the one parameter layout."""

import pickle

import numpy as np
import pytest
from helpers import TABLE2_TRUTH as TRUTH
from helpers import table2_data

import jitterid as ji
from jitterid.params import ParamLayout

T, N, NOISE = 1.0, 200, 0.01


def ls_covariance_by_hand(data, x):
    """sigma^2 (J^T J)^{-1} of time-domain least squares, J = ds(kT)/dtheta by central
    differences of the exact response: a second route, independent of the sandwich code."""
    st, t = ji.PolePairGain(), data.t_nominal
    J = np.empty((t.size, x.size))
    for i in range(x.size):
        h = 1e-6 * max(abs(x[i]), 1.0)
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        J[:, i] = (st.system(up).response(data.u)(t) - st.system(down).response(data.u)(t)) / (
            2 * h
        )
    return NOISE**2 * np.linalg.inv(J.T @ J)


def test_bcls_without_jitter_has_the_least_squares_covariance_of_the_noise():
    """With NoJitter, BCLS is least squares: its stated covariance is the noise's
    sigma^2 (J^T J)^{-1} (it was ~1e-17 when the noise was left out)."""
    data = table2_data(5, ji.NoJitter())
    res = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "bcls")
    assert res.success
    assert res.cov_type == "sandwich"
    se = np.sqrt(np.diag(res.cov))
    ref = np.sqrt(np.diag(ls_covariance_by_hand(data, res.x)))
    np.testing.assert_allclose(se, ref, rtol=0.05)
    assert res.noise_std == NOISE


def test_bcls_unknown_noise_uses_its_estimate_from_the_residuals():
    data = table2_data(6, ji.NoJitter(), known_noise=False)
    res = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), "bcls")
    assert res.noise_std == pytest.approx(NOISE, rel=0.15)
    ref = np.sqrt(np.diag(ls_covariance_by_hand(data, res.x)))
    np.testing.assert_allclose(np.sqrt(np.diag(res.cov)), ref, rtol=0.2)


@pytest.fixture(scope="module")
def small_jitter_monte_carlo():
    """24 realizations of Table 2's system with Uniform(0.02) jitter and noise 0.01 (known):
    here the noise dominates the variance, which the old BCLS covariance left out."""
    est, se = [], []
    for seed in range(24):
        data = table2_data(3000 + seed, ji.Uniform(0.02))
        res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.02), "bcls")
        assert res.success, res.message
        est.append(res.x)
        se.append(np.sqrt(np.diag(res.cov)))
    return np.array(est), np.array(se)


def test_bcls_stated_errors_match_the_spread_with_small_jitter(small_jitter_monte_carlo):
    est, se = small_jitter_monte_carlo
    ratio = se.mean(axis=0) / est.std(axis=0, ddof=1)
    # 24 runs: the sample std has ~15 % relative error; the old code gave 0.62-0.65
    assert np.all((ratio > 0.75) & (ratio < 1.35)), ratio
    assert np.all(np.abs(est.mean(axis=0) - TRUTH) < 3.5 * est.std(axis=0, ddof=1) / np.sqrt(24))


@pytest.mark.slow
def test_bcls_interval_coverage_with_small_jitter():
    """>= 100 realizations: 95 % intervals cover 91-98 % (it was 79-82 %)."""
    hits, runs = np.zeros(3), 120
    for seed in range(runs):
        data = table2_data(4000 + seed, ji.Uniform(0.02))
        res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.02), "bcls")
        ci = res.conf_int()
        hits += [ci[n][0] <= t <= ci[n][1] for n, t in zip(("k0", "pr", "pi"), TRUTH, strict=True)]
    cover = hits / runs
    assert np.all((cover >= 0.91) & (cover <= 0.98)), cover


@pytest.mark.slow
def test_robust_covariance_is_honest_under_a_misspecified_law():
    """Triangular jitter fitted with UniformFamily by ML: cov_type="robust" stated errors of
    the system parameters within 0.8-1.25 of the actual spread (the default observed
    information was 0.49-0.85).

    The uniform's half-width a is left out: the support of U(-a, a) moves with a, so the
    likelihood is not regular in a (with noise 0.01 the samples on steep edges nearly pin
    the support) and no delta-method form is honest for it (measured: robust 0.36 of the
    spread over these 100 runs). Its error bar is reported, and documented as unreliable.
    """
    est, se = [], []
    law = ji.SumOfUniforms(1, 0.8)  # triangular on [-0.8, 0.8]
    for seed in range(100):
        data = table2_data(5000 + seed, law)
        res = ji.fit(data, ji.PolePairGain(), ji.UniformFamily(), "ml", cov_type="robust")
        if not res.success:
            continue
        est.append(res.x)
        se.append(np.sqrt(np.diag(res.cov)))
    est, se = np.array(est), np.array(se)
    assert len(est) >= 90
    ratio = np.nanmedian(se, axis=0) / est.std(axis=0, ddof=1)
    system = ratio[1:]  # k0, pr, pi (module docstring of this test for a)
    assert np.all((system > 0.8) & (system < 1.25)), ratio


def test_cov_types_differ_where_they_should_and_none_skips_the_work():
    data = table2_data(8)
    base = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian")
    assert base.cov_type == "sandwich"
    oim = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=base.x, cov_type="oim")
    rob = ji.fit(
        data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=base.x, cov_type="robust"
    )
    none = ji.fit(
        data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=base.x, cov_type="none"
    )
    np.testing.assert_allclose(oim.x, base.x, rtol=1e-6)
    se = {r.cov_type: np.sqrt(np.diag(r.cov)) for r in (base, oim, rob)}
    # the Gaussian criterion is the likelihood of the second-moment model: sandwich ~ oim
    np.testing.assert_allclose(se["oim"], se["sandwich"], rtol=0.35)
    assert not np.allclose(se["robust"], se["sandwich"], rtol=1e-3)
    assert np.all(np.isnan(none.cov))
    assert none.cov_type == "none"
    with pytest.raises(ValueError, match="cov_type must be one of"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls", cov_type="oim")
    with pytest.raises(ValueError, match="cov_type must be one of"):
        ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls", cov_type="hc3")


def test_a_result_keeps_its_models_pickles_small_and_round_trips_through_json():
    data = table2_data(9)
    res = ji.fit(data, ji.PolePairGain(), ji.UniformFamily(), "bcls")
    assert res.structure == ji.PolePairGain()
    assert res.jitter_model == ji.UniformFamily()
    assert res.jitter_law == ji.Uniform(res.params["a"])
    blob = pickle.dumps(res)
    assert len(blob) < 20_000, len(blob)  # was 140 KB with the problem inside
    again = pickle.loads(blob)
    np.testing.assert_array_equal(again.cov, res.cov)
    back = ji.FitResult.from_json(res.to_json())
    assert back.names == res.names
    assert back.status is res.status
    np.testing.assert_array_equal(back.x, res.x)
    np.testing.assert_array_equal(back.cov, res.cov)
    assert back.jitter_law == res.jitter_law
    assert back.structure == res.structure
    np.testing.assert_array_equal(back.system.den, res.system.den)
    assert back.summary() == res.summary()
    with pytest.warns(DeprecationWarning, match="jitter_law"):
        assert res.jitter == res.jitter_law


def test_predict_and_residuals_need_nothing_handed_back():
    data = table2_data(10)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    m = ji.sample_moments(res.system.response(data.u), ji.Uniform(0.5), T, N).mean
    np.testing.assert_allclose(res.predict(data), m)
    np.testing.assert_allclose(res.residuals(data), data.y - m)
    with pytest.raises(TypeError, match="data must be a SampledData"):
        res.predict(data.y)


def test_json_refuses_classes_outside_the_package():
    data = table2_data(11)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "ls")
    d = res.to_dict()
    d["structure"]["__class__"] = "os:system"
    with pytest.raises(ValueError, match="not a jitterid class"):
        ji.FitResult.from_dict(d)


# ------------------------------------------------------------------ the parameter layout
def test_layout_blocks_and_conversions():
    lay = ParamLayout.build(
        ji.SumOfUniformsFamily(), ji.PolePairGain(), ji.RationalNoise(0, 1), noise_std=True
    )
    assert lay.names == ("n", "a", "k0", "pr", "pi", "hb0", "ha0", "noise_std")
    x = np.arange(8.0)
    assert lay.block(x, "jitter").tolist() == [0, 1]
    assert lay.block(x, "system").tolist() == [2, 3, 4]
    assert lay.block(x, "noise").tolist() == [5, 6]
    assert lay.block(x, "noise_std").tolist() == [7]
    np.testing.assert_array_equal(lay.vector(lay.to_dict(x)), x)
    np.testing.assert_array_equal(lay.vector(list(x)), x)
    with pytest.raises(ValueError, match="did you mean 'k0'"):
        lay.vector({**lay.to_dict(x), "K0": 1.0})
    with pytest.raises(ValueError, match="missing value"):
        lay.vector({"n": 1})
    with pytest.raises(ValueError, match="must have 8 values"):
        lay.vector([1, 2])
    with pytest.raises(ValueError, match="block must be one of"):
        lay.block(x, "plant")


def test_layout_takes_a_fit_result_by_name():
    data = table2_data(12, known_noise=False)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian")
    assert "noise_std" in res.names
    lay = ParamLayout.build(None, ji.PolePairGain())
    np.testing.assert_array_equal(lay.vector(res), res.x[:3])


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


# ------------------------------------------------------------------ derivative protocol
def _coefficient_differences(structure, theta, n):
    P = theta.size
    dnum, dden = np.zeros((P, n)), np.zeros((P, n))
    for i in range(P):
        h = 1e-6 * max(abs(theta[i]), 1.0)
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        a, b = structure.system(up), structure.system(down)
        pad = lambda c: np.r_[np.zeros(n - c.size), c]
        dnum[i] = (pad(a.num) - pad(b.num)) / (2 * h)
        dden[i] = (pad(a.den) - pad(b.den)) / (2 * h)
    return dnum, dden


@pytest.mark.parametrize(
    ("structure", "theta"),
    [
        (ji.PolePairGain(), np.array([6.25, -1.5, 2.0])),
        (ji.RationalModel(1, 3), np.array([0.5, 2.0, 3.0, 4.0, 2.0])),
    ],
)
def test_structures_coefficient_derivatives_against_differences(structure, theta):
    n = structure.system(theta).den.size
    closed = structure.coefficient_jacobian(theta, n)
    assert closed is not None
    ref = _coefficient_differences(structure, theta, n)
    for got, want in zip(closed, ref, strict=True):
        np.testing.assert_allclose(got, want, atol=1e-7)


def test_a_structure_without_derivatives_takes_the_declared_difference_route():
    """A reparameterised structure that does not override coefficient_jacobian: its parent's
    closed form belongs to another map, so the moments' sensitivities use differences of
    the new map (never the parent's formula), and the fit equals the analytic one's."""

    class LogGain(ji.PolePairGain):
        @property
        def param_names(self):
            return ("log_k0", "pr", "pi")

        @property
        def bounds(self):
            return ((-10.0, 10.0), *super().bounds[1:])

        def system(self, params):
            p = np.asarray(params, float)
            return super().system([np.exp(p[0]), p[1], p[2]])

        def starts(self, T):
            return [np.r_[np.log(s[0]), s[1:]] for s in super().starts(T)]

    data = table2_data(14)
    ref = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    res = ji.fit(data, LogGain(), ji.Uniform(0.5), "bcls")
    assert res.success
    np.testing.assert_allclose(np.exp(res.x[0]), ref.x[0], rtol=1e-5)
    np.testing.assert_allclose(res.x[1:], ref.x[1:], rtol=1e-5)


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


def test_bounds_take_a_dict_a_vector_or_a_fit_result_with_the_same_answer():
    data = table2_data(16)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    args = (ji.PolePairGain(), ji.Uniform(0.5), data.u, T, N, NOISE)
    by_vector = ji.crb(*args, res.x)
    np.testing.assert_array_equal(ji.crb(*args, res.params), by_vector)
    np.testing.assert_array_equal(ji.crb(*args, res), by_vector)
    g = ji.gaussian_bound(*args, res.x)
    np.testing.assert_array_equal(ji.gaussian_bound(*args, dict(res.params)), g)
    with pytest.raises(ValueError, match="did you mean 'pi'"):
        ji.crb(*args, {"k0": 6.0, "pr": -1.5, "Pi": 2.0})
    np.testing.assert_array_equal(ji.PolePairGain().system(res).den, res.system.den)


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
