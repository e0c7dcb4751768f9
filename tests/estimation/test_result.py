"""FitResult (jitterid.estimation.result): covariance forms (cov_type), the measurement noise in
every covariance, what a result keeps (structure, law, noise), pickling and JSON, and a result
handed to the bounds in place of a parameter vector."""

import pickle

import numpy as np
import pytest
from helpers import TABLE2_TRUTH as TRUTH
from helpers import table2_data

import jitterid as ji

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


def test_bounds_take_a_dict_a_vector_or_a_fit_result_with_the_same_answer():
    # (60 samples: how the parameters are given does not depend on the record's length)
    data = table2_data(16, n=60)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    args = (ji.PolePairGain(), ji.Uniform(0.5), data.u, T, 60, NOISE)
    by_vector = ji.crb(*args, res.x)
    np.testing.assert_array_equal(ji.crb(*args, res.params), by_vector)
    np.testing.assert_array_equal(ji.crb(*args, res), by_vector)
    g = ji.gaussian_bound(*args, res.x)
    np.testing.assert_array_equal(ji.gaussian_bound(*args, dict(res.params)), g)
    with pytest.raises(ValueError, match="did you mean 'pi'"):
        ji.crb(*args, {"k0": 6.0, "pr": -1.5, "Pi": 2.0})
    np.testing.assert_array_equal(ji.PolePairGain().system(res).den, res.system.den)
