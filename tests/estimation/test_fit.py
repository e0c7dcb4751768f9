"""fit(): the paper's estimators on its Table 2 experiment, parameter names, bad arguments,
failure reporting, two parameterisations of one model and a shared BCLS stage."""

import numpy as np
import pytest
from helpers import TABLE2_TRUTH as TRUTH
from helpers import table2_data

import jitterid as ji

T, N, NOISE = 1.0, 200, 0.01


@pytest.fixture(scope="module")
def table2_small_monte_carlo():
    """16 realizations of Table 2: LS, BCLS and the reduced AsML (23) on the same data. The
    AsML fit starts from the BCLS fit, as the runner shares it: the fit from scratch, bit
    for bit (test_bcls_result_as_start_gives_identical_fits_and_rejects_foreign_prefits),
    without its own BCLS stage."""
    out = {"ls": [], "bcls": [], "asml-diag": []}
    for seed in range(16):
        data = table2_data(1000 + seed)
        bcls = None
        for method, estimates in out.items():
            res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method, start=bcls)
            assert res.success, res.message
            estimates.append(res.x)
            if method == "bcls":
                bcls = res
    return {m: np.array(v) for m, v in out.items()}


def test_ls_gain_is_biased_low_against_bcls_on_the_same_data(table2_small_monte_carlo):
    est = table2_small_monte_carlo
    diff = est["bcls"][:, 0] - est["ls"][:, 0]  # paired: same realization
    t = diff.mean() / (diff.std(ddof=1) / np.sqrt(diff.size))
    assert t > 3, (diff.mean(), t)
    assert est["ls"][:, 0].mean() < TRUTH[0]


@pytest.mark.parametrize("method", ["bcls", "asml-diag"])
def test_jitter_aware_estimators_are_unbiased(table2_small_monte_carlo, method):
    x = table2_small_monte_carlo[method]
    se = x.std(axis=0, ddof=1) / np.sqrt(len(x))
    assert np.all(np.abs(x.mean(axis=0) - TRUTH) < 3 * se), (x.mean(axis=0), se)


@pytest.mark.parametrize("method", ["wbcls", "asml", "gaussian"])
def test_other_methods_recover_the_truth_within_their_standard_errors(method):
    data = table2_data(7)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method)
    assert res.success
    se = np.array(list(res.stderr.values()))[:3]
    assert np.all(np.isfinite(se))
    assert np.all(se > 0)
    assert np.all(np.abs(res.x[:3] - TRUTH) < 4 * se), (res.x, se)


def test_known_system_with_free_jitter_family_estimates_sigma():
    """Table 1's problem: G known, (n, a) of the family (26) free."""
    rng = np.random.default_rng(3)
    g = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(N * T + 2, rng)
    law = ji.SumOfUniforms(0, 0.5)
    data = ji.simulate(g, u, law, T, N, NOISE, rng)
    res = ji.fit(data, g, ji.SumOfUniformsFamily(), method="bcls")
    assert res.names == ("n", "a")
    assert res.success
    assert abs(res.jitter_std - law.std) < 0.1


def test_joint_problem_names_follow_table_3_order():
    data = table2_data(4)
    res = ji.fit(data, ji.PolePairGain(), ji.SumOfUniformsFamily(), method="bcls")
    assert res.names == ("n", "a", "k0", "pr", "pi")
    # On these 200 samples the family's shape is not identified (n = 1.0 +- 8e3, a = 0.87
    # +- 2e3): issue 15 A reported the fit UNIDENTIFIABLE; issue 24: the search ends at a
    # kink of n (or where n is flat), which holds n fixed for the error bars and says so,
    # and the jitter std and the system keep theirs
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert "held fixed for the error bars" in res.message
    assert np.isnan(res.stderr["n"])
    assert all(np.isfinite(res.stderr[k]) for k in ("k0", "pr", "pi"))
    assert np.isfinite(res.jitter_std_stderr)
    assert res.jitter_std_stderr > 0


def test_unknown_noise_is_estimated_by_likelihood_criteria():
    d = table2_data(5)
    data = ji.SampledData(d.y, d.T, d.u)  # noise level not given
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="gaussian")
    assert res.names[-1] == "noise_std"
    assert 0.003 < res.params["noise_std"] < 0.03


def test_a_failed_search_is_reported_as_failed():
    data = table2_data(6)
    res = ji.fit(
        data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls", start=[1.0, -0.2, 0.5], max_nfev=2
    )
    assert not res.success
    assert res.status is ji.FitStatus.MAX_EVALUATIONS
    assert "failed" in res.summary()


def test_summary_lists_every_parameter():
    res = ji.fit(table2_data(8), ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
    text = res.summary()
    for name in ("k0", "pr", "pi"):
        assert name in text


@pytest.mark.parametrize(
    ("call", "exc", "match"),
    [
        (
            lambda d: ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), method="bcsl"),
            ValueError,
            "method",
        ),
        (lambda d: ji.fit(d, "polepair", ji.Uniform(0.5)), TypeError, "system"),
        (lambda d: ji.fit(d, ji.PolePairGain(), 0.5), TypeError, "jitter"),
        (
            lambda d: ji.fit(d, ji.PolePairGain(), ji.SumOfUniformsFamily(), method="ls"),
            ValueError,
            "ls",
        ),
        (
            lambda d: ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), start=[1, 2]),
            ValueError,
            "start",
        ),
        (lambda d: ji.fit(d.y, ji.PolePairGain(), ji.Uniform(0.5)), TypeError, "data"),
    ],
)
def test_bad_fit_arguments(call, exc, match):
    with pytest.raises(exc, match=match):
        call(table2_data(9))


def test_rational_model_and_pole_pair_agree_on_the_same_data():
    """Two parameterisations of one model class must reach the same BCLS optimum:
    k0 / (s^2 - 2 pr s + pr^2 + pi^2) = b0 / (s^2 + a1 s + a0)."""
    data = table2_data(10)
    pp = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
    rm = ji.fit(data, ji.RationalModel(0, 2), ji.Uniform(0.5), method="bcls")
    assert rm.names == ("b0", "a1", "a0")
    k0, pr, pi = pp.x
    np.testing.assert_allclose(rm.x, [k0, -2 * pr, pr**2 + pi**2], rtol=1e-4)
    assert rm.cost == pytest.approx(pp.cost, rel=1e-6)


def test_wbcls_with_frozen_weights_is_unbiased_and_its_error_bars_are_honest():
    """Referee: 24 Table 2 realizations. The literal (20), R_Y(theta) searched together with
    theta, is off by 6-14 SEM here; with R frozen at the BCLS and then the WBCLS estimate the
    mean is within 3 SEM of the truth and the stated stderr within 35 % of the spread."""
    xs, ses = [], []
    for seed in range(24):
        res = ji.fit(table2_data(1000 + seed), ji.PolePairGain(), ji.Uniform(0.5), "wbcls")
        assert res.success, res.message
        xs.append(res.x)
        ses.append(list(res.stderr.values()))
    x, se = np.array(xs), np.array(ses)
    sem = x.std(0, ddof=1) / np.sqrt(len(x))
    assert np.all(np.abs(x.mean(0) - TRUTH) < 3 * sem), (x.mean(0), sem)
    ratio = np.median(se, axis=0) / x.std(0, ddof=1)
    assert np.all((ratio > 0.65) & (ratio < 1.35)), ratio


def test_bcls_result_as_start_gives_identical_fits_and_rejects_foreign_prefits():
    """Sharing the BCLS stage (start=FitResult) must not change any estimate, and a prefit
    from other data or another method is refused with an error naming ``start``."""
    rng = np.random.default_rng(7)
    u = ji.telegraph_input(205.0, rng)
    law = ji.Uniform(0.5)
    data = ji.simulate(ji.TransferFunction([6.25], [1.0, 3.0, 6.25]), u, law, 1.0, 200, 0.01, rng)
    other = ji.simulate(ji.TransferFunction([6.25], [1.0, 3.0, 6.25]), u, law, 1.0, 200, 0.01, rng)
    structure = ji.PolePairGain()
    bcls = ji.fit(data, structure, law, "bcls")
    for method in ("asml-diag", "ml"):
        alone = ji.fit(data, structure, law, method)
        shared = ji.fit(data, structure, law, method, start=bcls)
        np.testing.assert_array_equal(alone.x, shared.x)
        assert alone.nfev == shared.nfev
    with pytest.raises(ValueError, match=r"start: .*other data"):
        ji.fit(other, structure, law, "ml", start=bcls)
    with pytest.raises(ValueError, match=r"start: .*method='bcls'"):
        ji.fit(data, structure, law, "ml", start=ji.fit(data, structure, law, "asml-diag"))
