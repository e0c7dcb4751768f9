"""The checks after a search (jitterid.estimation.checks): no fit is reported as successful
when it is not. Each case is generated data that an earlier version fitted with
``success=True``: the statuses NOT_SIGNIFICANT, UNSTABLE_MODEL, LOCAL_OPTIMUM, UNIDENTIFIABLE,
AT_BOUND and LACK_OF_FIT, each with what to try, and no false alarm on well-posed fits."""

from __future__ import annotations

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.checks import BOUND_SE
from jitterid.experiments import runner
from jitterid.experiments.config import packaged_path
from jitterid.experiments.loader import load_experiment

T = 1.0
N = 200
G = ji.TransferFunction([6.25], [1.0, 3.0, 6.25])  # the paper's (27) at the truth


def _paper(
    seed: int = 7, law: ji.JitterLaw | None = None, n: int = N, noise: float = 0.01
) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 5.0, rng)
    return ji.simulate(G, u, law or ji.Uniform(0.5), T, n, noise, rng)


@pytest.fixture(scope="module")
def data() -> ji.SampledData:
    return _paper()


# ------------------------------------------------------------------------ after the search
def test_pure_noise_is_not_a_significant_fit():
    # was: true G = 0 gave CONVERGED, with |k0|/se ~ 36 ("significant") every time
    for seed in range(4):
        rng = np.random.default_rng(100 + seed)
        u = ji.telegraph_input(N * T + 5.0, rng)
        d = ji.SampledData(0.02 * rng.standard_normal(N), T, u, None)
        res = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
        assert not res.success
        assert res.status in (ji.FitStatus.NOT_SIGNIFICANT, ji.FitStatus.AT_BOUND), res.message
        if res.status is ji.FitStatus.NOT_SIGNIFICANT:
            assert "F test" in res.message
            assert "Check that u is the input" in res.message


def test_well_posed_fits_stay_converged_with_weak_signal():
    for seed in range(3):  # a signal-to-noise ratio of ~ 1: still clearly significant
        d = _paper(seed=200 + seed, noise=0.5)
        res = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
        assert res.status is ji.FitStatus.CONVERGED, res.message


def test_an_undamped_over_ordered_model_is_reported_unstable(data):
    # was: RationalModel(0, 8) CONVERGED with a pole pair at ~0 +- 11.48j, and the
    # covariance raised the "not stable" ValueError out of fit (so .stderr never came)
    res = ji.fit(data, ji.RationalModel(0, 8), ji.NoJitter(), "ls")
    assert res.status is ji.FitStatus.UNSTABLE_MODEL, res.message
    assert not res.success
    assert "den_order" in res.message
    assert "failed" in res.summary()
    assert all(np.isnan(v) or v >= 0 for v in res.stderr.values())


def test_a_start_that_ends_at_a_local_optimum_is_restarted_or_reported(data, monkeypatch):
    # was: CONVERGED at criterion -429.6, where the default start reaches -812.2. A search
    # from a given start that converges where the criterion is higher than at a default
    # start is searched again from that start (session 21; where that does not lower it,
    # restarted: the first stage from that start, the estimator from its end, as one that
    # stops is), and the message says so; the referee: the fit without start
    best = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian")
    assert best.success
    start = [40.0, -0.5, 6.0]
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=start)
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert res.cost == pytest.approx(best.cost, rel=1e-9)
    assert "lower than at the end of the search from the given start" in res.message
    # where neither helps (here: none made), the end is reported, not passed off
    from jitterid.estimation.oe import OutputErrorRoute

    def no_restart(self, problem, failed, x0, noise):
        return problem, failed._replace(nfev=0), 0

    def no_again(self, problem, best, origin="the first stage's estimate"):
        return best, 0

    monkeypatch.setattr(OutputErrorRoute, "_restart", no_restart)
    monkeypatch.setattr(OutputErrorRoute, "_from_lower_default", no_again)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=start)
    assert res.status is ji.FitStatus.LOCAL_OPTIMUM, res.message
    assert res.cost > best.cost + 100
    assert "fit again without start" in res.message
    # a start near the optimum is not flagged
    near = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", start=best.x)
    assert near.success, near.message


@pytest.mark.parametrize("method", ["ls", "bcls"])
def test_a_30th_order_rational_model_is_unidentifiable(data, method):
    # issue 15: `fit --model tf:0,30` gave coefficients up to 1.9e10 with relative standard
    # errors of 1e-10. Those coefficients are only the expansion of poles near 1 rad/s (a0 is
    # their product): what is wrong is that the information matrix in the coefficients is
    # numerically singular, so the "tight" intervals are rounding noise. The criterion is
    # the condition of the correlation matrix (the covariance in scaled parameters).
    law = ji.NoJitter() if method == "ls" else ji.Uniform(0.5)
    res = ji.fit(data, ji.RationalModel(0, 30), law, method)
    assert res.status is ji.FitStatus.UNIDENTIFIABLE, res.message
    assert max(abs(v) for v in res.params.values()) > 1e9  # the case as reported
    assert "fewer parameters" in res.message
    # and the lab setting (T = 0.5, N = 1000, a zero and three poles; Gaussian jitter)
    lab = _lab(1, n=1000)
    res = ji.fit(
        lab, ji.RationalModel(0, 30), ji.Gaussian(0.08), method if method == "bcls" else "ls"
    )
    assert not res.success, res.message


def test_a_local_optimum_under_jitter_ten_samples_wide_is_reported():
    # issue 15: jitter 10 T wide with a known law, U(-5, 5): bcls ended at k0 = 0.031 +-
    # 0.0022 (truth 6.25) with status CONVERGED at a criterion above the truth's (2407.9
    # against 2334.3). The criterion at one of the structure's default starts (no search)
    # is already lower (2291.7): the estimate is not the criterion's minimum.
    law = ji.Uniform(5.0)
    rng = np.random.default_rng(10)
    u = ji.telegraph_input(215.0, rng)
    d = ji.simulate(G, u, law, T, N, 0.01, rng)
    res = ji.fit(d, ji.PolePairGain(), law, "bcls")
    assert res.status is ji.FitStatus.LOCAL_OPTIMUM, res.message
    assert "default start 2 = " in res.message
    assert res.params["k0"] < 0.1
    # the advice: a fit from that start reaches a lower criterion (and is not flagged)
    again = ji.fit(d, ji.PolePairGain(), law, "bcls", start=ji.PolePairGain().starts(T)[2])
    assert again.cost < res.cost - 100
    assert again.success, again.message
    # the criteria that start from that bcls fit are flagged too: they stayed near it, or
    # (gaussian, since its search cuts a step at the first bound it reaches) ran on to the
    # stability bound pr = -pr_min, which is reported as such
    for method in ("gaussian", "ml"):
        status = ji.fit(d, ji.PolePairGain(), law, method).status
        assert status in (ji.FitStatus.LOCAL_OPTIMUM, ji.FitStatus.AT_BOUND), status


def test_an_unidentified_jitter_shape_is_held_and_said(data):
    # was: SumOfUniformsFamily CONVERGED with n = 0.0003 +- 3231, a = 0.08 +- 133; then
    # (issue 15) UNIDENTIFIABLE for the whole fit. Issue 24: the shape n is not identified
    # (the criterion is flat along the family at a fixed jitter std) but the std and the
    # system are: CONVERGED, n held fixed for the error bars and said so, the std's interval
    # stated and honest
    rng = np.random.default_rng(7)
    u = ji.telegraph_input(205.0, rng)
    ji.simulate(G, u, ji.Uniform(0.5), T, N, 0.01, rng)  # the stream of the reported case
    ji.simulate(G, u, ji.SumOfUniforms(3.0, 0.3), T, N, 0.01, rng)
    truth = ji.SumOfUniforms(3.0, 0.1)
    d = ji.simulate(G, u, truth, T, N, 0.01, rng)
    res = ji.fit(d, ji.PolePairGain(), ji.SumOfUniformsFamily(), "bcls")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    # n is held fixed for the error bars: not identified (flat along the family at a fixed
    # std), at a kink of the family or on its bound, whichever the search ended at; the
    # message says which
    assert "held fixed for the error bars" in res.message
    assert any(
        why in res.message for why in ("n not identified by the data", "at a kink", "on its bound")
    )
    assert np.isnan(res.stderr["n"])
    # (its note: not identified, at a kink or, where the search ended within a hair of 0 and
    # went there (search.piecewise), on its bound)
    note = res.stderr_notes["n"]
    assert any(why in note for why in ("not identified", "kink", "on its bound 0"))
    # (a small jitter, 0.029 T, is weakly told by bcls: the message states how weakly)
    se = res.jitter_std_stderr
    assert np.isfinite(se)
    assert se > 0
    assert f"identified to {100 * se / res.jitter_std:.2g} %" in res.message
    assert abs(res.jitter_std - truth.std) < 3.5 * se
    for name in ("k0", "pr", "pi"):
        assert np.isfinite(res.stderr[name])


def test_a_parameter_on_its_bound_is_reported():
    # A pole pair on the stability bound pr = -pr_min: was CONVERGED (pure noise, seed 105)
    rng = np.random.default_rng(105)
    u = ji.telegraph_input(N * T + 5.0, rng)
    d = ji.SampledData(0.02 * rng.standard_normal(N), T, u, None)
    res = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
    assert res.status is ji.FitStatus.AT_BOUND, res.message
    assert "pr" in res.message


def test_a_parameter_a_hair_inside_its_bound_is_on_it():
    # Table 2's uniform case, realization 83: LS's optimum is a real pole pair (pi < 0), and
    # its trust-region search stopped with pi 3.5e-6 above the floor 0.001 (2.6e-9 of its
    # standard error): reported CONVERGED, where an earlier run of the same fit, stopped
    # 5.3e-7 above, was AT_BOUND. The referee: pi is on its floor to within the search's
    # box margin, and its standard error dwarfs the distance
    exp = load_experiment(packaged_path("table2"))
    d, _ = runner.realization_data(exp, 0, runner.seed_stream(exp.seed, 0, 83))
    law = exp.cases[0].law.build()
    res = ji.fit(d, ji.PolePairGain(), law, "ls")
    assert res.params["pi"] - 0.001 < 1e-4
    assert res.params["pi"] - 0.001 <= BOUND_SE * res.stderr["pi"]
    assert res.status is ji.FitStatus.AT_BOUND, res.message
    assert "pi" in res.message
    # the same data with the model's pole pair well inside: no bound is near
    assert ji.fit(d, ji.PolePairGain(), law, "bcls").status is ji.FitStatus.CONVERGED


def _lab(seed: int, n: int = 300) -> ji.SampledData:
    """Issue 15's lab setting, smaller: third-order system with a zero, ZOH input of a random
    +-1 sequence on the T grid, T = 0.5 s, Gaussian jitter 0.08 s, noise 0.02."""
    g = ji.TransferFunction([4.0, 8.0], np.polymul([1.0, 4.0], [1.0, 2.0, 2.0]))
    rng = np.random.default_rng(seed)
    u = ji.zoh_input(rng.choice([-1.0, 1.0], n + 20), 0.5)
    return ji.simulate(g, u, ji.Gaussian(0.08), 0.5, n, 0.02, rng)


def test_a_collapsed_jitter_scale_with_detected_jitter_is_at_bound():
    # was: CONVERGED at sigma = 2.4e-8 (truth 0.08) while detect_jitter finds jitter at
    # p ~ 1e-12 (on the full lab data: sigma = 2e-9 / 4e-12, stderr 40-400x too small)
    d = _lab(5004)
    res = ji.fit(d, ji.RationalModel(1, 3), ji.GaussianFamily(), "bcls")
    assert res.status is ji.FitStatus.AT_BOUND, res.message
    assert res.params["sigma"] < 1e-3 * d.T
    assert "jitter scale collapsed" in res.message
    assert "detect_jitter" in res.message
    # the advice works: a criterion that sees the variance finds the jitter (0.073 +- 0.005)
    better = ji.fit(d, ji.RationalModel(1, 3), ji.GaussianFamily(), "gaussian")
    assert better.success, better.message
    assert 0.05 < better.params["sigma"] < 0.11


def test_a_collapsed_jitter_scale_without_jitter_is_its_natural_home():
    d = _paper(law=ji.NoJitter())
    res = ji.fit(d, ji.PolePairGain(), ji.GaussianFamily(), "bcls")
    assert res.params["sigma"] < 1e-3 * d.T
    assert res.success, res.message


def test_new_statuses_are_failures_that_say_what_to_try():
    new = ("AT_BOUND", "UNIDENTIFIABLE", "UNSTABLE_MODEL", "LOCAL_OPTIMUM", "NOT_SIGNIFICANT")
    for name in new:
        status = ji.FitStatus[name]
        assert not status.success
        assert status.value.startswith("failed: ")
        assert ";" in status.value  # the cause, then what to try


@pytest.mark.slow
def test_monte_carlo_pure_noise_never_succeeds_and_the_paper_setting_always_does():
    # was: 40 of 40 pure-noise fits "converged" (median |k0|/se = 36)
    for seed in range(40):
        rng = np.random.default_rng(5000 + seed)
        u = ji.telegraph_input(N * T + 5.0, rng)
        d = ji.SampledData(0.02 * rng.standard_normal(N), T, u, None)
        res = ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), "bcls")
        assert not res.success, (seed, res.message)
    # and the checks raise no false alarm in the paper's setting (Table 2)
    for seed in range(40):
        for method in ("bcls", "asml-diag"):
            res = ji.fit(_paper(seed=6000 + seed), ji.PolePairGain(), ji.Uniform(0.5), method)
            assert res.status is ji.FitStatus.CONVERGED, (seed, method, res.message)


# ------------------------------------------------------------------------ lack of fit
def _bench_data(seed: int, law: ji.JitterLaw) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(202.0, rng)
    return ji.simulate(ji.PolePairGain().system([6.25, -1.5, 2.0]), u, law, 1.0, 200, 0.01, rng)


@pytest.mark.parametrize("method", ["bcls", "asml-diag"])
def test_lack_of_fit_allows_for_the_spread_of_an_inefficient_estimate(method):
    # a first version compared the residuals with Var y_k alone: this paper-setting record
    # (bcls's fitted mean many noise stds off where Var s_k is tiny) was LACK_OF_FIT at 3.45
    res = ji.fit(_bench_data(4, ji.Uniform(0.5)), ji.PolePairGain(), ji.Uniform(0.5), method)
    assert res.status is ji.FitStatus.CONVERGED, res.message


def test_lack_of_fit_reports_a_known_law_the_data_contradict():
    # U(-0.5, 0.5) data, fitted with the given triangular law of half its variance and the
    # true noise std: most such fits are flagged (15 of 20 bcls measured)
    flagged = [
        ji.fit(
            _bench_data(100 + s, ji.Uniform(0.5)),
            ji.PolePairGain(),
            ji.SumOfUniforms(2, 0.5),
            "bcls",
        ).status
        is ji.FitStatus.LACK_OF_FIT
        for s in range(6)
    ]
    assert sum(flagged) >= 3


def test_a_shape_held_on_its_bound_says_its_error_bars_are_conditional():
    """A pure tone under the Gaussian criterion with a scale mixture: the samples' means and
    variances fix three numbers (A chi(w), A^2 (1 - chi(w)^2) / 2 + sigma_v^2 and
    A^2 (chi(w)^2 - chi(2 w)) / 2), so rho, the std, the amplitude and the noise trade along
    a direction the criterion is flat along; the search ends with rho on its bound 0. It
    said "rho not identified by the data (the criterion is flat along the family at a fixed
    jitter std)", which is not why it was held (docs/jitter_meter.md: the std moves along
    that direction too). The referee: a search from the law's true rho ends at the same
    criterion with another std."""
    rng = np.random.default_rng(1000)
    n, T_ = 1600, 1.0
    tau = 0.15 * np.where(rng.random(n) < 0.5, np.sqrt(0.3), np.sqrt(1.7)) * rng.standard_normal(n)
    t = np.arange(n) * T_ + tau
    y = 1.5 * np.sin(2 * np.pi * 0.23 * t + 0.4) + 0.3 + 0.05 * rng.standard_normal(n)
    d = ji.SampledData(y, T_, None)
    fam = ji.GaussianScaleMixtureFamily()
    res = ji.fit(d, ji.SineWave(), fam, "gaussian")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert res.x[1] == 0.0
    assert "rho = 0 is on its bound: held fixed for the error bars, which are conditional" in (
        res.message
    )
    assert "rho not identified" not in res.message
    other = ji.fit(d, ji.SineWave(), fam, "gaussian", start=[0.15, 0.7, 1.5, 0.4, 0.23, 0.3, 0.05])
    assert abs(other.cost - res.cost) < 1e-6 * abs(res.cost)
    assert other.x[1] > 0.5
    assert abs(other.jitter_std - res.jitter_std) > 0.01 * res.jitter_std
