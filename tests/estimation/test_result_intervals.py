"""What a FitResult shows (jitterid.estimation.result): intervals of positive parameters that
never go negative without losing coverage, the jitter std's standard error through the family,
and every "nan" explained."""

import dataclasses
import math

import numpy as np
import pytest
from helpers import table2_data

import jitterid as ji

NOISE = 0.01
TRUTH = {"a": 0.5, "k0": 6.25, "pr": -1.5, "pi": 2.0, "noise_std": NOISE}


@pytest.fixture(scope="module")
def gaussian_fit():
    """noise_std estimated: the jitter scale a and noise_std are both standard deviations."""
    return ji.fit(
        table2_data(3, known_noise=False), ji.PolePairGain(), ji.UniformFamily(), "gaussian"
    )


def with_cov(res, diag):
    """``res`` with a diagonal covariance (variances ``diag``)."""
    return dataclasses.replace(res, cov=np.diag(np.asarray(diag, float)))


# ------------------------------------------------------------------ intervals


def test_an_uncertain_standard_deviation_gets_no_negative_interval(gaussian_fit):
    """The issue's case: noise_std 0.0157 +- 0.085 gave [-0.15, 0.18]."""
    res = gaussian_fit
    i = res.names.index("noise_std")
    x = np.array(res.x)
    x[i] = 0.0157
    var = np.array(np.diag(res.cov))
    var[i] = 0.085**2
    wild = dataclasses.replace(with_cov(res, var), x=x)
    lo, hi = wild.conf_int()["noise_std"]
    assert lo == 1e-12  # the bound: the data do not exclude (almost) no noise
    assert hi == pytest.approx(0.0157 + 1.959964 * 0.085, rel=1e-6)
    assert "noise_std" in wild.conf_int_notes()
    assert "cut at its bound 1e-12" in wild.conf_int_notes(0.5)["noise_std"]
    text = wild.summary()
    assert "noise_std: interval cut at its bound 1e-12" in text
    assert "-0.1" not in text
    # The log scale: positive, asymmetric, centred on ln theta.
    llo, lhi = wild.conf_int(scale="log")["noise_std"]
    assert 0 < llo < 0.0157 < lhi
    assert math.log(lhi / 0.0157) == pytest.approx(math.log(0.0157 / llo))
    # Parameters without a bound >= 0 keep the symmetric interval under both scales.
    assert wild.conf_int(scale="log")["k0"] == wild.conf_int()["k0"]


def test_well_determined_intervals_are_unchanged_and_arguments_are_checked(gaussian_fit):
    res = gaussian_fit
    se = res.stderr
    for n, (lo, hi) in res.conf_int(0.9).items():
        assert (lo, hi) == pytest.approx(
            (res.params[n] - 1.644854 * se[n], res.params[n] + 1.644854 * se[n])
        )
    assert res.conf_int_notes() == {}
    with pytest.raises(ValueError, match="scale must be 'linear' or 'log'"):
        res.conf_int(scale="logit")
    with pytest.raises(ValueError, match="level must be in"):
        res.conf_int(1.0)


def test_a_shape_parameter_is_cut_at_zero_and_a_bound_is_explained():
    data = table2_data(4, known_noise=False)
    res = ji.fit(
        data,
        ji.PolePairGain(),
        ji.SumOfUniformsFamily(),
        "bcls",
        start=[0.5, 0.45, 6.25, -1.5, 2.0],
    )
    # n = 0.5 +- 3: [0, 6.4], never negative; 0 (the uniform law) stays admissible.
    i = res.names.index("n")
    x = np.array(res.x)
    x[i] = 0.5
    var = np.array(np.diag(res.cov))
    var[i] = 9.0
    cut = dataclasses.replace(res, x=x, cov=np.diag(np.where(np.isfinite(var), var, 1e-4)))
    assert cut.conf_int()["n"] == pytest.approx((0.0, 0.5 + 1.959964 * 3))
    assert cut.conf_int(scale="log")["n"] == cut.conf_int()["n"]  # lower bound 0: no log
    # On its bound: no standard error, and the summary and stderr_notes say why.
    x[i] = 0.0
    var = np.full(len(res.names), 1e-4)
    var[i] = np.nan
    cov = np.diag(var)
    on = dataclasses.replace(res, x=x, cov=cov)
    assert "on its bound 0" in on.stderr_notes["n"]
    assert "n: on its bound 0: held fixed" in on.summary()
    x[i] = 1e-7
    near = dataclasses.replace(res, x=x, cov=cov)
    assert "next to its bound 0" in near.stderr_notes["n"]
    # at a kink of the family (n = 3): held fixed there, and said (issue 24)
    x[i] = 3.0
    kinked = dataclasses.replace(res, x=x, cov=cov)
    assert "at a kink of the jitter family" in kinked.stderr_notes["n"]
    # between kinks, the others with error bars: the shape the data do not tell
    x[i] = 3.5
    flat = dataclasses.replace(res, x=x, cov=cov)
    assert "not identified by the data" in flat.stderr_notes["n"]
    # a system parameter without one: a singular information
    j = res.names.index("k0")
    var_k = np.full(len(res.names), 1e-4)
    var_k[j] = np.nan
    singular = dataclasses.replace(res, x=x, cov=np.diag(var_k))
    assert "singular" in singular.stderr_notes["k0"]
    none = dataclasses.replace(res, cov=np.full_like(cov, np.nan), cov_type="none")
    assert set(none.stderr_notes.values()) == {"not computed (cov_type='none')"}
    assert "not computed" not in none.summary()  # one word for all: "covariance: none"


# ------------------------------------------------------------------ jitter std stderr


@pytest.mark.parametrize(
    ("family", "theta", "grad"),
    [
        (ji.UniformFamily(), [0.5], lambda n, a: [1 / math.sqrt(3)]),
        (ji.GaussianFamily(), [0.2], lambda n, a: [1.0]),
        (
            ji.SumOfUniformsFamily(),
            [2.0, 0.6],
            lambda n, a: [-a / (2 * math.sqrt(3) * (n + 1) ** 1.5), 1 / math.sqrt(3 * (n + 1))],
        ),
        (
            ji.SumOfUniformsFamily(),
            [0.0, 0.6],
            lambda n, a: [-a / (2 * math.sqrt(3)), 1 / math.sqrt(3)],
        ),
    ],
)
def test_the_std_gradient_through_each_family_is_the_closed_form(family, theta, grad):
    """std = a / sqrt(3 (n + 1)) for (26), a / sqrt(3) for U(-a, a), sigma for N(0, sigma^2);
    at n = 0 (on its bound) the difference is one-sided."""
    args = (theta[0], theta[1]) if len(theta) == 2 else (0.0, theta[0])
    np.testing.assert_allclose(family.std_gradient(np.array(theta)), grad(*args), rtol=1e-5)


def test_jitter_std_stderr_is_the_delta_method(gaussian_fit):
    res = gaussian_fit
    assert res.jitter_std_stderr == pytest.approx(res.stderr["a"] / math.sqrt(3), rel=1e-6)
    assert f"(std {res.jitter_std:.4g} ± {res.jitter_std_stderr:.2g})" in res.summary()
    known = ji.fit(table2_data(3), ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    assert known.jitter_std_stderr == 0.0
    assert "std 0.2887, known" in known.summary()
    assert math.isnan(
        dataclasses.replace(
            res, cov=np.full_like(res.cov, np.nan), cov_type="none"
        ).jitter_std_stderr
    )


def test_jitter_std_stderr_of_the_sum_of_uniforms_family():
    """Both (n, a) free: the full 2 x 2 block, correlation included; n on its bound is held
    fixed, as the covariance holds it for every other parameter."""
    data = table2_data(4, known_noise=False)
    res = ji.fit(
        data,
        ji.PolePairGain(),
        ji.SumOfUniformsFamily(),
        "bcls",
        start=[0.5, 0.45, 6.25, -1.5, 2.0],
    )
    n, a = 2.0, 0.6
    C = np.eye(len(res.names)) * 1e-4
    C[:2, :2] = [[0.25, 0.01], [0.01, 0.0009]]
    x = np.array(res.x)
    x[:2] = n, a
    free = dataclasses.replace(res, x=x, cov=C)
    g = np.array([-a / (2 * math.sqrt(3) * (n + 1) ** 1.5), 1 / math.sqrt(3 * (n + 1))])
    assert free.jitter_std_stderr == pytest.approx(math.sqrt(g @ C[:2, :2] @ g), rel=1e-5)
    x[0] = 0.0
    C = C.copy()
    C[0, :] = C[:, 0] = np.nan
    on = dataclasses.replace(res, x=x, cov=C)
    assert on.jitter_std_stderr == pytest.approx(0.03 / math.sqrt(3), rel=1e-5)


# ------------------------------------------------------------------ Monte Carlo


def _table2_fits(count):
    """``count`` data sets of Table 2's setting, noise unknown (so noise_std is estimated),
    fitted with the uniform family and the Gaussian criterion."""
    return [
        ji.fit(
            table2_data(1000 + seed, known_noise=False),
            ji.PolePairGain(),
            ji.UniformFamily(),
            "gaussian",
        )
        for seed in range(count)
    ]


@pytest.fixture(scope="module")
def table2_monte_carlo():
    """64 data sets (17 s of CPU): the slow tests' Monte Carlo."""
    return _table2_fits(64)


def _check_no_negative_interval(fits):
    """The cut interval is the plain one wherever the plain one is admissible, no interval
    of a standard deviation reaches 0 or below, and a noise std on its floor is explained."""
    z = 1.959964
    for name in ("a", "k0", "pr", "pi", "noise_std"):
        plain = np.mean([abs(r.params[name] - TRUTH[name]) <= z * r.stderr[name] for r in fits])
        cut = np.mean([lo <= TRUTH[name] <= hi for r in fits for lo, hi in [r.conf_int()[name]]])
        assert cut == plain, name
    for r in fits:
        for name in ("a", "noise_std"):
            for scale in ("linear", "log"):
                assert not r.conf_int(scale=scale)[name][0] <= 0
    at_bound = [r for r in fits if not np.isfinite(r.stderr["noise_std"])]
    assert all("on its bound 1e-12" in r.stderr_notes["noise_std"] for r in at_bound)
    return at_bound


def test_intervals_of_positive_parameters_never_go_negative_small():
    """Fast version of the coverage test below (8 of its 64 data sets): the intervals' shape,
    not their coverage."""
    _check_no_negative_interval(_table2_fits(8))


@pytest.mark.slow
def test_intervals_of_positive_parameters_keep_their_coverage(table2_monte_carlo):
    """Measured (64 sets): coverage 0.95-0.98 for a, k0, pr, pi, identical for the cut and
    the plain symmetric interval (the cut only removes inadmissible values), and the log
    scale within one data set of it; no interval of a standard deviation below 0.

    noise_std: its linear interval covers 0.84 (0.86 over 150 other seeds) and its log
    interval 0.875 (0.90). Its stated error is right (the sandwich's score covariance
    matches 600 simulated scores within 2 %, see tests/estimation/test_result.py), but the Gaussian
    criterion's noise std is biased low here (mean 0.00875 for 0.01 over 150 seeds, 5 SEM):
    beside the jitter's variance the noise is seen only where s is flat, about five
    samples' worth of information. The log interval, which follows the estimate's skew,
    is the one to use for it."""
    fits = table2_monte_carlo
    z = 1.959964
    for name in ("a", "k0", "pr", "pi", "noise_std"):
        plain = np.mean([abs(r.params[name] - TRUTH[name]) <= z * r.stderr[name] for r in fits])
        cut = np.mean([lo <= TRUTH[name] <= hi for r in fits for lo, hi in [r.conf_int()[name]]])
        log = np.mean(
            [lo <= TRUTH[name] <= hi for r in fits for lo, hi in [r.conf_int(scale="log")[name]]]
        )
        assert cut == plain, name
        assert (log if name == "noise_std" else cut) >= 0.85, (name, cut, log)
        assert log >= cut - 1.5 / len(fits), (name, log, cut)
    # One set of the 64 (seed 1038) puts noise_std on its floor 1e-12: no interval, explained.
    assert len(_check_no_negative_interval(fits)) <= 2


@pytest.mark.slow
def test_jitter_std_stderr_matches_the_monte_carlo_spread(table2_monte_carlo):
    """Measured (64 sets): spread of the fitted std 0.0127, mean stated stderr 0.0148."""
    std = np.array([r.jitter_std for r in table2_monte_carlo])
    se = np.array([r.jitter_std_stderr for r in table2_monte_carlo])
    assert np.all(np.isfinite(se))
    ratio = np.mean(se) / np.std(std, ddof=1)
    assert 0.75 < ratio < 1.4, ratio
    assert np.mean(np.abs(std - 0.5 / math.sqrt(3)) <= 1.96 * se) >= 0.85


def test_jitter_std_stderr_agrees_with_parameter_sampling():
    """The sum-of-uniforms family, (n, a) correlated: draws of (n, a) from N(x, C) give a
    spread of the law's std equal to the delta method's standard error."""
    data = table2_data(4, known_noise=False)
    res = ji.fit(
        data,
        ji.PolePairGain(),
        ji.SumOfUniformsFamily(),
        "bcls",
        start=[0.5, 0.45, 6.25, -1.5, 2.0],
    )
    x = np.array(res.x)
    x[:2] = 2.0, 0.6
    C = np.eye(len(res.names)) * 1e-4
    C[:2, :2] = [[0.04, 0.003], [0.003, 0.0004]]
    r = dataclasses.replace(res, x=x, cov=C)
    draws = np.random.default_rng(0).multivariate_normal(x[:2], C[:2, :2], size=20000)
    stds = draws[:, 1] / np.sqrt(3 * (draws[:, 0] + 1))
    assert r.jitter_std_stderr == pytest.approx(np.std(stds), rel=0.03)
