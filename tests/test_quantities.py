"""Physical quantities of an LTI fit (poles, zeros, DC gain, time constants, natural frequency,
damping, bandwidth) with intervals, and the discrete-time export.

Referees: hand values of known transfer functions, the closed-form bandwidth of a second-order
system, the analytic root sensitivity dp/da = -p^j / D'(p), a Monte Carlo of each quantity
over parameter draws, scipy's own zero-order hold and step of the continuous system.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import optimize, signal

import jitterid as ji
from jitterid.analysis.quantities import DROP_3DB, _match, bandwidth_hz

TRUTH = np.array([6.25, -1.5, 2.0])  # the paper's (27): wn = 2.5 rad/s, zeta = 0.6
C_SMALL = np.array(
    [[4e-3, -8e-4, 2e-4], [-8e-4, 2.5e-4, -1e-5], [2e-4, -1e-5, 6e-5]]
)  # a precise fit, correlated as Table 2's BCLS fits are (k0 with pr)


def fit_of(structure, theta, cov=None, cov_type="sandwich", jitter=None) -> ji.FitResult:
    """A FitResult at ``theta`` with covariance ``cov``, built directly (no data needed)."""
    theta = np.asarray(theta, float)
    cov = np.zeros((theta.size, theta.size)) if cov is None else np.asarray(cov, float)
    law = jitter or ji.NoJitter()
    return ji.FitResult(
        method="bcls",
        names=tuple(structure.param_names),
        x=theta,
        cost=0.0,
        status=ji.FitStatus.CONVERGED,
        message="",
        nfev=0,
        system=structure.system(theta),
        jitter_law=law,
        noise_std=0.01,
        freqs=np.zeros(0),
        cov=cov,
        cov_type=cov_type,
        structure=structure,
        jitter_model=law,
    )


def second_order(theta):
    """wn (Hz), zeta, DC gain and -3 dB bandwidth (Hz) of k0 / ((s - pr)^2 + pi^2), in closed
    form: with r = w / wn, |G / G(0)|^2 = 1 / ((1 - r^2)^2 + (2 zeta r)^2) = 10^(-3/10) at
    r^2 = (1 - 2 zeta^2) + sqrt((1 - 2 zeta^2)^2 + 10^(3/10) - 1)."""
    k0, pr, pi = (np.asarray(v, float) for v in theta)
    wn = np.hypot(pr, pi)
    zeta = -pr / wn
    b = 1 - 2 * zeta**2
    r2 = b + np.sqrt(b**2 + 10 ** (3 / 10) - 1)
    return wn / (2 * np.pi), zeta, k0 / wn**2, wn * np.sqrt(r2) / (2 * np.pi)


# ------------------------------------------------------------------------------ hand values


def test_quantities_of_a_known_third_order_system_by_hand():
    """G = 2 (s + 3) / ((s + 1)(s^2 + 2 s + 5)): poles -1 and -1 +- 2i, zero -3."""
    num, den = [2.0, 6.0], np.polymul([1.0, 1.0], [1.0, 2.0, 5.0])
    struct = ji.RationalModel(1, 3)
    res = fit_of(struct, [*num, *den[1:]])
    pq = ji.physical_quantities(res)
    assert pq.names == (
        "pole1_re_per_s",  # slowest mode first: |p| = 1
        "pole2_re_per_s",
        "pole2_im_rad_per_s",
        "zero_re_per_s",
        "dc_gain",
        "bandwidth_hz",
        "tau1_s",
        "wn2_hz",
        "zeta2",
    )
    hand = {
        "pole1_re_per_s": -1.0,
        "pole2_re_per_s": -1.0,
        "pole2_im_rad_per_s": 2.0,
        "zero_re_per_s": -3.0,
        "dc_gain": 6.0 / 5.0,
        "tau1_s": 1.0,
        "wn2_hz": math.sqrt(5) / (2 * math.pi),
        "zeta2": 1 / math.sqrt(5),
    }
    for name, value in hand.items():
        assert pq[name].value == pytest.approx(value, rel=1e-12), name
    units = {q.name: q.unit for q in pq}
    assert units["pole2_im_rad_per_s"] == "rad/s"
    assert units["pole1_re_per_s"] == "1/s"
    assert units["wn2_hz"] == units["bandwidth_hz"] == "Hz"
    assert units["tau1_s"] == "s"
    # Bandwidth: a referee that knows nothing of polynomials, brentq on |G| itself.
    g = res.system

    def drop(f):
        return abs(g.frequency_response(f)) - DROP_3DB * abs(g.dcgain)

    f = np.geomspace(1e-4, 10, 20001)
    first = np.flatnonzero(np.abs(g.frequency_response(f)) < DROP_3DB * abs(g.dcgain))[0]
    ref = optimize.brentq(drop, f[first - 1], f[first], xtol=1e-15)
    assert pq["bandwidth_hz"].value == pytest.approx(ref, rel=1e-10)
    # Known system (zero covariance): zero standard errors, intervals collapse.
    assert all(q.stderr == 0 for q in pq)


def test_one_mode_names_have_no_number_and_match_the_closed_form():
    pq = ji.physical_quantities(fit_of(ji.PolePairGain(), TRUTH, C_SMALL))
    assert pq.names == (
        "pole_re_per_s",
        "pole_im_rad_per_s",
        "dc_gain",
        "bandwidth_hz",
        "wn_hz",
        "zeta",
    )
    wn, zeta, dc, bw = second_order(TRUTH)
    assert pq["wn_hz"].value == pytest.approx(2.5 / (2 * math.pi), rel=1e-14) == pytest.approx(wn)
    assert pq["zeta"].value == pytest.approx(0.6, rel=1e-14) == pytest.approx(zeta)
    assert pq["dc_gain"].value == pytest.approx(1.0) == pytest.approx(dc)
    assert pq["bandwidth_hz"].value == pytest.approx(bw, rel=1e-12)
    first = ji.physical_quantities(fit_of(ji.RationalModel(0, 1), [3.0, 2.0]))
    assert first.names == ("pole_re_per_s", "dc_gain", "bandwidth_hz", "tau_s")
    assert first["tau_s"].value == pytest.approx(0.5)
    # 1/(s + a): |G|^2 = 1 / (1 + (w/a)^2) drops to 10^(-3/10) at w = a sqrt(10^0.3 - 1).
    assert first["bandwidth_hz"].value == pytest.approx(
        2.0 * math.sqrt(10**0.3 - 1) / (2 * math.pi), rel=1e-12
    )


@pytest.mark.parametrize(
    ("num", "den", "why"),
    [
        ([1.0, 0.0], [1.0, 1.0], "|G(0)| = 0"),  # high-pass
        ([10.0, 10.0], [1.0, 10.0], "never drops 3 dB"),  # lead: |G| rises from 1 to 10
        ([1.0], [1.0, 1.0, 0.0], "pole at s = 0"),  # integrator
    ],
)
def test_bandwidth_is_nan_with_a_note_where_there_is_none(num, den, why):
    bw, note = bandwidth_hz(ji.TransferFunction(num, den))
    assert math.isnan(bw)
    assert why in note
    struct = ji.RationalModel(len(num) - 1, len(den) - 1)
    pq = ji.physical_quantities(
        fit_of(struct, [*num, *den[1:]], np.eye(len(num) + len(den) - 1) * 1e-6)
    )
    assert math.isnan(pq["bandwidth_hz"].value)
    assert why in pq["bandwidth_hz"].note
    assert math.isnan(pq["bandwidth_hz"].low)


def test_an_integrator_has_no_dc_gain_and_no_time_constant():
    pq = ji.physical_quantities(fit_of(ji.RationalModel(0, 2), [1.0, 1.0, 0.0]))
    assert math.isnan(pq["dc_gain"].value)
    assert "integrator" in pq["dc_gain"].note
    taus = [q for q in pq if q.name.startswith("tau")]
    assert [q.name for q in taus] == ["tau1_s", "tau2_s"]
    assert math.isnan(taus[0].value)  # the pole at 0
    assert "not stable" in taus[0].note
    assert taus[1].value == pytest.approx(1.0)


def test_a_resonance_above_dc_does_not_count_as_the_bandwidth():
    """A lightly damped pair rises above |G(0)| before falling: the bandwidth is where it
    falls, beyond the peak."""
    theta = [1.0, -0.1, 1.0]  # zeta ~ 0.1
    pq = ji.physical_quantities(fit_of(ji.PolePairGain(), theta))
    assert pq["bandwidth_hz"].value == pytest.approx(second_order(theta)[3], rel=1e-12)
    assert pq["bandwidth_hz"].value > pq["wn_hz"].value


# ------------------------------------------------------------------------------ intervals


def test_delta_stderr_agrees_with_a_monte_carlo_of_each_quantity():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    pq = ji.physical_quantities(res, 0.9)
    draws = np.random.default_rng(5).multivariate_normal(TRUTH, C_SMALL, 200_000).T
    wn, zeta, dc, bw = second_order(draws)
    mc = {
        "pole_re_per_s": draws[1],
        "pole_im_rad_per_s": draws[2],
        "wn_hz": wn,
        "zeta": zeta,
        "dc_gain": dc,
        "bandwidth_hz": bw,
    }
    for name, values in mc.items():
        assert pq[name].stderr == pytest.approx(values.std(), rel=0.03), name
        lo, hi = np.quantile(values, [0.05, 0.95])
        width = hi - lo
        assert pq[name].low == pytest.approx(lo, abs=0.05 * width), name
        assert pq[name].high == pytest.approx(hi, abs=0.05 * width), name
    assert pq["wn_hz"].scale == pq["bandwidth_hz"].scale == "log"
    assert pq["zeta"].scale == pq["dc_gain"].scale == "linear"
    z = 1.6448536269514722
    q = pq["wn_hz"]
    assert q.low == pytest.approx(q.value * math.exp(-z * q.stderr / q.value))
    assert q.high == pytest.approx(q.value * math.exp(z * q.stderr / q.value))


def test_delta_and_sampling_agree_where_the_linearisation_is_good():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    delta = ji.physical_quantities(res)
    draws = ji.physical_quantities(res, method="sampling", draws=4000, rng=3)
    assert draws.method == "sampling"
    for d, s in zip(delta, draws, strict=True):
        assert s.scale == "quantiles"
        assert s.value == d.value
        assert s.stderr == pytest.approx(d.stderr, rel=0.04), d.name
        width = d.high - d.low
        assert s.low == pytest.approx(d.low, abs=0.04 * width), d.name
        assert s.high == pytest.approx(d.high, abs=0.04 * width), d.name
    once = ji.physical_quantities(res, method="sampling", draws=200, rng=np.random.default_rng(3))
    again = ji.physical_quantities(res, method="sampling", draws=200, rng=3)
    assert again.to_dict() == once.to_dict()  # an explicit seed reproduces


def test_pole_stderr_against_the_analytic_root_sensitivity():
    """Three real poles -1, -2, -3.5 of a monic cubic: dp/da_j = -p^j / D'(p) (a_j the
    coefficient of s^j), so se(p)^2 = g^T C g in closed form."""
    poles = np.array([-1.0, -2.0, -3.5])
    den = np.poly(poles)
    struct = ji.RationalModel(0, 3)
    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 4)) * 1e-3
    cov = A @ A.T + np.diag([1e-6, 4e-6, 2e-6, 3e-6])
    pq = ji.physical_quantities(fit_of(struct, [7.0, *den[1:]], cov))
    for k, p in enumerate(poles, start=1):  # |p| ascending: pole1 = -1
        g = np.zeros(4)  # params b0, a2, a1, a0
        g[1:] = [-(p**j) / np.polyval(np.polyder(den), p) for j in (2, 1, 0)]
        assert pq[f"pole{k}_re_per_s"].value == pytest.approx(p, rel=1e-12)
        assert pq[f"pole{k}_re_per_s"].stderr == pytest.approx(math.sqrt(g @ cov @ g), rel=1e-5)
        gt = g / p**2  # tau = -1/p: dtau/dp = 1/p^2
        assert pq[f"tau{k}_s"].stderr == pytest.approx(math.sqrt(gt @ cov @ gt), rel=1e-5)


def test_roots_are_matched_by_nearest_not_by_order():
    ref = np.array([-1.0, -1.2 + 0.5j, -1.2 - 0.5j, -3.0])
    new = np.array([-3.01, -1.19 - 0.49j, -0.99, -1.19 + 0.49j])
    np.testing.assert_array_equal(_match(ref, new), [-0.99, -1.19 + 0.49j, -1.19 - 0.49j, -3.01])
    with pytest.raises(ValueError, match="3 roots where the estimate has 4"):
        _match(ref, new[:3])


def test_close_real_poles_keep_their_identity_across_draws():
    """Poles -1 and -1.15 with standard errors ~0.03: sampled draws keep each pole's interval
    around its own value (matching), where np.roots' order would mix them."""
    den = np.poly([-1.0, -1.15])
    cov = np.diag([1e-6, 4e-6, 4e-6])
    res = fit_of(ji.RationalModel(0, 2), [1.15, *den[1:]], cov)
    pq = ji.physical_quantities(res, method="sampling", draws=2000, rng=1)
    d = ji.physical_quantities(res)
    assert d["pole1_re_per_s"].stderr == pytest.approx(0.0185, rel=0.05)
    # Each interval holds its own pole and not the other (close roots repel: skewed).
    assert -1.1 < pq["pole1_re_per_s"].low < -1.0 < pq["pole1_re_per_s"].high < -0.95
    assert -1.25 < pq["pole2_re_per_s"].low < -1.15 < pq["pole2_re_per_s"].high < -1.05
    for name in ("pole1_re_per_s", "pole2_re_per_s", "tau1_s", "tau2_s"):
        assert pq[name].stderr == pytest.approx(d[name].stderr, rel=0.1)


def test_a_parameter_without_variance_voids_only_what_depends_on_it():
    """pi on its bound: NaN for every quantity that involves pi, with the reason; the real
    part depends on pr alone and keeps its standard error (conditional on pi)."""
    cov = C_SMALL.copy()
    cov[2, :] = cov[:, 2] = np.nan
    res = fit_of(ji.PolePairGain(), TRUTH, cov)
    for method in ("delta", "sampling"):
        pq = ji.physical_quantities(res, method=method, draws=500, rng=0)
        assert math.isfinite(pq["pole_re_per_s"].stderr)
        for name in ("pole_im_rad_per_s", "wn_hz", "zeta", "dc_gain", "bandwidth_hz"):
            assert math.isnan(pq[name].stderr), name
            assert math.isnan(pq[name].low)
            assert "depends on pi" in pq[name].note
    none = fit_of(ji.PolePairGain(), TRUTH, np.full((3, 3), np.nan), cov_type="none")
    pq = ji.physical_quantities(none)
    assert all(math.isnan(q.stderr) for q in pq)
    assert all("cov_type='none'" in q.note for q in pq)
    text = none.summary()
    assert "physical quantities" in text
    assert "not computed" not in text  # the summary's one word for it is "covariance: none"
    # Identical notes are printed once, for all the quantities they concern.
    assert text.count("cov_type='none'") == 1


def test_known_system_has_no_uncertainty():
    res = fit_of(ji.KnownSystem(ji.TransferFunction([2.0], [1.0, 2.0])), [])
    pq = ji.physical_quantities(res)
    assert pq["tau_s"].value == pytest.approx(0.5)
    assert pq["tau_s"].stderr == 0
    assert pq["tau_s"].scale == "known"
    assert pq["tau_s"].low == pq["tau_s"].high == pq["tau_s"].value


# ------------------------------------------------------------------------------ the table


def test_table_indexing_summary_and_dict():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    pq = res.physical_quantities(0.9)
    assert pq.level == 0.9
    assert "zeta" in pq
    assert len(pq) == len(list(pq)) == 6
    with pytest.raises(KeyError, match=r"no quantity 'wn'.*wn_hz"):
        pq["wn"]
    text = pq.summary()
    assert "90% interval" in text
    assert "log-scale intervals for bandwidth_hz, wn_hz" in text
    d = json.loads(json.dumps(pq.to_dict()))
    assert d["quantities"]["zeta"]["value"] == pytest.approx(0.6)
    assert d["quantities"]["wn_hz"]["unit"] == "Hz"
    assert set(d) == {"level", "method", "quantities"}
    with pytest.raises(AttributeError):
        pq.level = 0.5  # type: ignore[misc]
    with pytest.raises(AttributeError):
        pq["zeta"].value = 0.0  # type: ignore[misc]
    # The fit's summary carries the table; its intervals are the table's.
    summ = res.summary()
    assert "physical quantities (delta method" in summ
    assert f"{pq['zeta'].value:.5g}" in summ


def test_summary_never_raises_for_the_quantities(monkeypatch):
    from jitterid.estimation import hooks  # where the result finds physical_quantities

    def broken(*a, **k):
        raise RuntimeError("boom")

    monkeypatch.setitem(hooks._REGISTRY, "physical_quantities", broken)
    text = fit_of(ji.PolePairGain(), TRUTH, C_SMALL).summary()
    assert "physical quantities: skipped (boom)" in text


# ------------------------------------------------------------------------------ bad input


def sine_fit() -> ji.FitResult:
    sine = ji.SignalModel(
        lambda t, th: th[0] * np.sin(2 * np.pi * 0.1 * t),
        param_names=("A",),
        starts=[(1.0,)],
        rate=2 * np.pi * 0.1,
    )
    rng = np.random.default_rng(0)
    t = np.arange(60.0)
    y = 1.5 * np.sin(2 * np.pi * 0.1 * t) + 0.05 * rng.standard_normal(60)
    return ji.fit(ji.SampledData(y, T=1.0), sine, ji.NoJitter(), method="ls")


def test_bad_inputs_are_refused_clearly():
    res = fit_of(ji.PolePairGain(), TRUTH, C_SMALL)
    with pytest.raises(ValueError, match=r"level must be a number in \(0, 1\)"):
        ji.physical_quantities(res, 1.5)
    with pytest.raises(ValueError, match="method must be 'delta' or 'sampling'"):
        ji.physical_quantities(res, method="bootstrap")
    with pytest.raises(TypeError, match=r"rng must be a numpy\.random\.Generator"):
        ji.physical_quantities(res, method="sampling")
    with pytest.raises(ValueError, match="draws must be at least 100"):
        ji.physical_quantities(res, method="sampling", draws=10, rng=0)
    with pytest.raises(TypeError, match="result must be a FitResult"):
        ji.physical_quantities("fit")  # type: ignore[arg-type]
    wide = fit_of(ji.PolePairGain(), [6.25, -0.01, 2.0], np.diag([1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="normal approximation is poor"):
        ji.physical_quantities(wide, method="sampling", draws=200, rng=0)
    sine = sine_fit()
    assert "physical quantities" not in sine.summary()
    with pytest.raises(
        ValueError, match=r"needs an LTI fit.*signal model \(SignalModel\).*use its params"
    ):
        ji.physical_quantities(sine)
    with pytest.raises(ValueError, match="signal model"):
        sine.to_discrete(1.0)


# ------------------------------------------------------------------------------ to_discrete


@pytest.mark.parametrize("method", ["zoh", "foh", "bilinear"])
def test_to_discrete_is_scipys_own_discretisation(method):
    res = fit_of(ji.RationalModel(1, 3), [2.0, 6.0, *np.polymul([1, 1], [1, 2, 5])[1:]])
    d = res.to_discrete(0.25, method)
    assert isinstance(d, signal.dlti)
    assert d.dt == 0.25
    numd, dend, _ = signal.cont2discrete((res.system.num, res.system.den), 0.25, method=method)
    ref = np.trim_zeros(np.where(np.abs(numd[0]) < 1e-12, 0.0, numd[0]), "f")
    np.testing.assert_allclose(d.num, ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(d.den, dend, rtol=1e-12)


def test_zoh_reproduces_the_continuous_step_response_at_the_samples():
    """A step is held exactly by a zero-order hold: the discrete system's step response at
    k T equals the continuous one (scipy's matrix-exponential step of the same G)."""
    res = fit_of(ji.PolePairGain(), TRUTH)
    T = 0.2
    d = res.to_discrete(T)
    k = np.arange(60)
    _, (yd,) = signal.dstep(d, n=k.size)
    _, yc = signal.step(signal.lti(res.system.num, res.system.den), T=k * T)
    np.testing.assert_allclose(yd[:, 0], yc, atol=1e-12)
    # And the discrete system's own recursion on a step (lfilter reads the coefficients in
    # powers of 1/z: the numerator padded to the denominator's length).
    b = np.r_[np.zeros(d.den.size - d.num.size), d.num]
    y = signal.lfilter(b, d.den, np.ones(k.size))
    np.testing.assert_allclose(y, yc, atol=1e-12)


def test_to_discrete_refuses_bad_sampling_intervals():
    res = fit_of(ji.PolePairGain(), TRUTH)
    for T in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="T must be the sampling interval in s"):
            res.to_discrete(T)
    with pytest.raises(TypeError, match="T must be the sampling interval"):
        res.to_discrete("1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="method must be one of"):
        res.to_discrete(1.0, "gbt")


# ------------------------------------------------------------------------------ coverage


@pytest.mark.slow
def test_damping_and_natural_frequency_intervals_cover():
    """200 of Table 2's data sets (Uniform(0.5) jitter, N = 200, noise 0.01), BCLS: the 95 %
    delta-method intervals of zeta and wn_hz cover the truth 0.90-0.98 of the time."""
    truth = ji.PolePairGain().system(TRUTH)
    zeta0, wn0 = 0.6, 2.5 / (2 * math.pi)
    hits = {"zeta": 0, "wn_hz": 0}
    runs = 200
    rng = np.random.default_rng(2024)
    for _ in range(runs):
        u = ji.telegraph_input(202.0, rng)
        data = ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)
        res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
        pq = res.physical_quantities(0.95)
        hits["zeta"] += pq["zeta"].low <= zeta0 <= pq["zeta"].high
        hits["wn_hz"] += pq["wn_hz"].low <= wn0 <= pq["wn_hz"].high
    coverage = {k: v / runs for k, v in hits.items()}
    print(f"coverage over {runs} data sets: {coverage}")
    for name, c in coverage.items():
        assert 0.90 <= c <= 0.98, (name, coverage)


# ------------------------------------------------------------------------------ the CLI report


def test_fit_command_reports_quantities_and_the_step_response(tmp_path):
    """`jitterid fit` writes the quantities (with intervals) into result.json, a table into
    report.md and the step response with its band as step.png, linked from the report."""
    from click.testing import CliRunner

    from jitterid.cli import main

    lab, out = tmp_path / "lab", tmp_path / "fit"
    run = CliRunner().invoke
    assert run(main, ["simulate", "--out", str(lab), "--seed", "3"]).exit_code == 0
    res = run(
        main,
        [
            "fit",
            str(lab / "data.csv"),
            "--input",
            str(lab / "input.csv"),
            "--model",
            "polepair",
            "--jitter",
            "known:uniform:a=0.5",
            "--method",
            "bcls",
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    result = json.loads((out / "result.json").read_text())
    pq = result["physical_quantities"]
    assert pq["method"] == "delta"
    assert pq["level"] == 0.95
    zeta = pq["quantities"]["zeta"]
    assert zeta["low"] < zeta["value"] < zeta["high"]
    assert pq["quantities"]["wn_hz"]["unit"] == "Hz"
    assert pq["quantities"]["wn_hz"]["scale"] == "log"
    # The same numbers as the library's, from the written parameters and covariance.
    x = np.array([result["parameters"][n] for n in ("k0", "pr", "pi")])
    again = ji.physical_quantities(fit_of(ji.PolePairGain(), x, result["covariance"]["matrix"]))
    assert zeta["stderr"] == pytest.approx(again["zeta"].stderr, rel=1e-6)
    report = (out / "report.md").read_text()
    assert "| `zeta` |" in report
    assert "| `wn_hz` |" in report
    assert "![step response](step.png)" in report
    assert (out / "step.png").stat().st_size > 1000
