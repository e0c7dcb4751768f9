"""Model order selection (jitterid.select_order, ``jitterid fit --model ... --model ...``):
the choice on clear cases, AIC/BIC/LR against hand computations from the rows, the fit's own
criterion as the referee of the Gaussian log-likelihood, finite differences as the referee of
the roots' sensitivities, over-order and failing candidates, validation, the command line,
bad input; and (slow) a Monte Carlo confusion table over orders 1 to 3."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result
from scipy import stats

import jitterid as ji
from jitterid.analysis import selection
from jitterid.analysis.selection import OrderRow, over_order
from jitterid.cli import main
from jitterid.estimation import checks
from jitterid.estimation.resources import moment_bytes

T, NOISE = 1.0, 0.01
JITTER = ji.Uniform(0.5)
G1 = ji.TransferFunction([2.0], [1.0, 1.0])  # 2 / (s + 1)
G2 = ji.PolePairGain().system([6.25, -1.5, 2.0])  # the paper's pole pair (27)
TF01, TF02, TF12 = ji.RationalModel(0, 1), ji.RationalModel(0, 2), ji.RationalModel(1, 2)


def simulate(
    system: ji.TransferFunction, seed: int, n: int = 60, hold: float = 3.0
) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 2.0, rng, mean_hold=hold)
    return ji.simulate(system, u, JITTER, T=T, N=n, noise_std=NOISE, rng=rng)


@pytest.fixture(scope="module")
def first() -> ji.SampledData:
    """First-order data, noise std not given to the fits (it is estimated)."""
    return dataclasses.replace(simulate(G1, 1), noise_std=None)


@pytest.fixture(scope="module")
def second() -> ji.SampledData:
    return dataclasses.replace(simulate(G2, 2, hold=1.0), noise_std=None)


@pytest.fixture(scope="module")
def gaussian_first(first) -> ji.OrderSelection:
    return ji.select_order(first, [TF01, TF02, TF12], JITTER, "gaussian")


# ------------------------------------------------------------------------------ the choice


@pytest.mark.parametrize("method", ["bcls", "gaussian"])
@pytest.mark.parametrize(("truth", "label"), [("first", "tf:0,1"), ("second", "tf:0,2")])
def test_the_true_order_is_chosen_on_a_clear_case(method, truth, label, request):
    data = request.getfixturevalue(truth)
    if (truth, method) == ("first", "gaussian"):  # that selection, made once for the module
        sel = request.getfixturevalue("gaussian_first")
    else:
        sel = ji.select_order(data, [TF01, TF02, TF12], JITTER, method)
    assert sel.best is not None
    assert sel.best.label == label, sel.summary()
    assert sel.best.trustworthy
    assert sel.result is sel.best.result
    assert sel.result.success
    assert sel.method == method
    assert sel.criterion == "bic"
    assert label in sel.reason
    assert "lowest BIC" in sel.reason
    # BIC alone agrees, over every row it could be computed for (over-order ones too)
    assert sel.best.bic == min(r.bic for r in sel.rows if math.isfinite(r.bic))
    # the under-modelled first-order fit of second-order data is far worse
    if truth == "second":
        assert sel.row("tf:0,1").bic - sel.best.bic > 10


def test_a_selection_is_immutable_and_serialises(gaussian_first):
    sel = gaussian_first
    with pytest.raises(dataclasses.FrozenInstanceError):
        sel.chosen = 0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sel.rows[0].bic = 0.0  # type: ignore[misc]
    d = json.loads(json.dumps(sel.to_dict(), allow_nan=False))
    assert d["chosen"] == sel.best.label
    assert [r["label"] for r in d["rows"]] == list(sel.labels)
    assert d["rows"][0]["n_params"] == sel.rows[0].n_params
    text = sel.summary()
    assert all(lab in text for lab in sel.labels)
    assert "chosen:" in text
    assert str(sel) == text
    with pytest.raises(KeyError, match="tf:9,9"):
        sel.row("tf:9,9")


# ------------------------------------------------------------------------------ formulas


def test_aic_bic_are_the_hand_formulas_of_the_rows_log_likelihoods(gaussian_first, first):
    sel = gaussian_first
    assert sel.noise_counted
    assert sel.loglik_kind == "gaussian"
    assert sel.N == first.N
    for r in sel.rows:
        assert r.result is not None
        # k: the system's parameters and the estimated noise std (the jitter law is known)
        assert r.n_params == len(r.structure.param_names) + 1 == len(r.result.names)
        assert r.aic == pytest.approx(-2 * r.loglik + 2 * r.n_params, rel=1e-12)
        assert r.bic == pytest.approx(-2 * r.loglik + r.n_params * math.log(first.N), rel=1e-12)


def test_gaussian_log_likelihood_is_the_gaussian_criterion(gaussian_first, first):
    """Referee: the fit's own criterion V = sum (e^2/w + ln w), so l = -(V + N ln 2 pi) / 2."""
    for r in gaussian_first.rows:
        assert r.loglik == pytest.approx(
            -(r.cost + first.N * np.log(2 * np.pi)) / 2, rel=1e-9, abs=1e-9
        )


def test_bcls_log_likelihood_by_hand_with_known_noise(first):
    data = dataclasses.replace(first, noise_std=NOISE)
    sel = ji.select_order(data, [TF01, TF02], JITTER, "bcls")
    assert not sel.noise_counted
    for r in sel.rows:
        res = r.result
        mom = ji.sample_moments(res.signal(data.u), res.jitter_law, T, data.N)
        hand = stats.norm.logpdf(data.y, mom.mean, np.sqrt(mom.var + NOISE**2)).sum()
        assert r.loglik == pytest.approx(hand, rel=1e-10)
        assert r.n_params == len(r.structure.param_names)  # noise known, jitter known


def test_ml_rows_carry_the_exact_log_likelihood():
    """Referee: ExactLikelihood.loglik at the estimate, built independently of the fit."""
    data = simulate(G1, 1)  # noise std known: not a parameter
    sel = ji.select_order(data, [TF01, TF12], JITTER, "ml")
    assert sel.loglik_kind == "exact"
    assert not sel.noise_counted
    assert "exact" in sel.basis()
    for r in sel.rows:
        lik = ji.ExactLikelihood(r.structure, JITTER, data.u, T, data.N, noise_std=NOISE)
        assert r.loglik == pytest.approx(lik.loglik(r.result.x, data.y), rel=1e-9)
        assert r.n_params == len(r.structure.param_names)
    assert [(t.smaller, t.larger, t.dof) for t in sel.tests] == [("tf:0,1", "tf:1,2", 2)]


def test_likelihood_ratio_test_is_the_hand_value(gaussian_first):
    sel = gaussian_first
    # tf:0,2 is tf:1,2 with b1 = 0; tf:0,1 is only a limit of tf:0,2 (a pole at infinity)
    assert [(t.smaller, t.larger) for t in sel.tests] == [("tf:0,2", "tf:1,2")]
    t = sel.tests[0]
    small, big = sel.row("tf:0,2"), sel.row("tf:1,2")
    lr = 2 * (big.loglik - small.loglik)
    assert t.statistic == pytest.approx(lr, rel=1e-12, abs=1e-12)
    assert t.dof == big.n_params - small.n_params == 1
    assert t.pvalue == pytest.approx(stats.chi2.sf(max(lr, 0.0), 1), rel=1e-12)
    assert "asymptotic" in sel.summary()


def test_no_likelihood_ratio_test_for_a_criterion_that_is_not_a_likelihood(first):
    sel = ji.select_order(first, [TF02, TF12], JITTER, "bcls")
    assert sel.tests == ()


def test_nesting_of_rational_models():
    nested = selection._nested
    assert nested(TF01, TF12)
    assert nested(TF02, TF12)
    assert nested(ji.PolePairGain(), ji.RationalModel(1, 3))
    assert nested(ji.RationalModel(1, 2), ji.RationalModel(2, 3))
    assert not nested(TF01, TF02)  # only as a pole -> infinity limit
    assert not nested(TF12, ji.RationalModel(1, 3))
    assert not nested(TF12, TF01)
    assert not nested(TF12, TF12)


@pytest.mark.parametrize("den", [[1.0, 3.0, 6.25], [1.0, 2.5, 1.0, 0.3], [1.0, 0.7, 5.0, 2.0, 4.0]])
def test_root_sensitivities_match_differences_of_numpy_roots(den):
    """Referee for the delta-method standard errors: central differences of np.roots."""
    den = np.asarray(den, float)
    P = den.size
    dcoef = np.eye(P)  # the parameters are the coefficients themselves
    roots, grad = checks._root_gradients(den, dcoef)
    h = 1e-6
    for i in range(P):
        up, dn = den.copy(), den.copy()
        up[i] += h
        dn[i] -= h
        r_up, r_dn = np.roots(up), np.roots(dn)
        for j, r in enumerate(roots):  # match each root to its own perturbed copy
            fd = (r_up[np.argmin(abs(r_up - r))] - r_dn[np.argmin(abs(r_dn - r))]) / (2 * h)
            assert abs(grad[j, i] - fd) <= 1e-5 * max(1.0, abs(fd)), (i, r, grad[j, i], fd)


# ----------------------------------------------------------------------- over-order, failures


def test_over_order_candidates_are_reported_and_not_chosen(first):
    sel = ji.select_order(first, [TF01, TF12, ji.RationalModel(2, 3)], JITTER, "bcls")
    assert sel.best.label == "tf:0,1"
    over = sel.row("tf:1,2")
    assert over.flag == "over-order"
    assert not over.trustworthy
    assert any(w in over.over_order for w in ("cancel", "not told apart", "infinity"))
    assert "over-order" in over.problem
    assert "tf:1,2 (over-order)" in sel.reason
    big = sel.row("tf:2,3")  # reported, whatever went wrong with it
    assert not big.trustworthy
    assert big.problem
    assert "tf:2,3" in sel.summary()
    assert over_order(sel.best.result, T) == ""  # the true order shows no cancellation


def test_exact_cancellation_is_detected(first):
    """G1 (s + 3) / (s + 3): a fitted tf:1,2 placed on it (start there, no search)."""
    res = ji.fit(first, TF12, JITTER, "bcls", start=[2.0, 6.0, 4.0, 3.0], max_nfev=1)
    assert "cancel" in over_order(res, T)


def test_an_untrustworthy_row_is_never_chosen_over_a_trustworthy_one():
    def row(lab: str, bic: float, *, over: str = "", status=ji.FitStatus.CONVERGED) -> OrderRow:
        return OrderRow(lab, TF01, 2, status, loglik=-bic / 2, aic=bic, bic=bic, over_order=over)

    rows = [
        row("a", 10.0),
        row("b", -50.0, over="pole -1 and zero -1 rad/s cancel"),
        row("c", -60.0, status=ji.FitStatus.AT_BOUND),
        OrderRow("d", TF01, 2, None, error="boom"),
    ]
    chosen, why = selection._choose(rows, "bic")
    assert chosen == 0
    assert "b (over-order)" in why
    assert "c (AT_BOUND)" in why
    assert "d (" in why
    # none trustworthy: the converged one is chosen, and the sentence says it cannot be trusted
    chosen, why = selection._choose(rows[1:], "bic")
    assert chosen == 0
    assert why.startswith("no candidate can be trusted")
    chosen, why = selection._choose(rows[3:], "bic")
    assert chosen is None
    assert "boom" in why


def test_a_failing_candidate_is_a_row_not_a_crash(first, monkeypatch):
    # a memory budget between the needs of 2 and 5 parameters refuses tf:1,3 up front
    budget = (moment_bytes(first.N, 2) + moment_bytes(first.N, 5)) / 2
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", str(budget))
    too_many = ji.RationalModel(14, 14)  # 29 parameters for 60 samples: refused by fit
    sel = ji.select_order(first, [too_many, TF01, ji.RationalModel(1, 3)], JITTER, "bcls")
    assert sel.best.label == "tf:0,1"
    for lab, what in (("tf:14,14", "samples"), ("tf:1,3", "memory")):
        r = sel.row(lab)
        assert r.status is None
        assert r.result is None
        assert what in r.error
        assert r.flag == "error"
        assert math.isnan(r.bic)
        assert "raised" in r.problem
    assert "tf:1,3 (the fit raised an error)" in sel.reason


# ------------------------------------------------------------------------------ validation


def test_validation_column_is_compares_fit_percent(first):
    val = simulate(G1, 11)
    sel = ji.select_order(first, [TF01, TF02], JITTER, "bcls", validation=val)
    for r in sel.rows:
        yhat = r.result.predict(val)
        hand = 100 * (1 - np.linalg.norm(val.y - yhat) / np.linalg.norm(val.y - val.y.mean()))
        assert r.validation_fit_pct == pytest.approx(hand, rel=1e-12)
    assert sel.best.validation_fit_pct > 50
    by_val = ji.select_order(
        first, [TF01, TF02], JITTER, "bcls", validation=val, criterion="validation"
    )
    trusted = [r for r in by_val.rows if r.trustworthy]
    assert by_val.best is max(trusted, key=lambda r: r.validation_fit_pct)
    assert "highest validation fit" in by_val.reason


# ------------------------------------------------------------------------------ bad input


def test_bad_input_is_refused_with_the_argument_and_the_fix(first):
    sine = ji.SineWave()
    cases = [
        ([], {}, ValueError, "candidates is empty"),
        ("tf:0,1", {}, TypeError, "candidates must be a list"),
        ([TF01, "tf:1,2"], {}, TypeError, r"candidates\[1\] must be a model structure"),
        ([TF01, 3], {}, TypeError, r"candidates\[1\]"),
        ([TF01, ji.RationalModel(0, 1)], {}, ValueError, "repeats"),
        ([TF01, sine], {}, ValueError, "mix LTI structures"),
        ([TF01, TF02], {"criterion": "mdl"}, ValueError, "criterion must be one of"),
        ([TF01, TF02], {"criterion": "validation"}, ValueError, "needs validation data"),
        ([TF01, TF02], {"start": [1.0, 1.0]}, ValueError, "start: the candidates"),
        ([TF01, TF02], {"noise": ji.RationalNoise(0, 1)}, ValueError, "noise:"),
        ([TF01, TF02], {"nosie_std": 0.1}, TypeError, "unexpected keyword"),
        ([TF01, TF02], {"noise_std": -1.0}, ValueError, "noise_std"),
        ([TF01, TF02], {"validation": first.y}, TypeError, "validation must be a SampledData"),
    ]
    for cands, kw, exc, match in cases:
        with pytest.raises(exc, match=match):
            ji.select_order(first, cands, JITTER, **kw)
    with pytest.raises(ValueError, match="method must be one of"):
        ji.select_order(first, [TF01], JITTER, "nope")
    with pytest.raises(TypeError, match="data must be a SampledData"):
        ji.select_order(first.y, [TF01], JITTER)
    with pytest.raises(TypeError, match="jitter must be"):
        ji.select_order(first, [TF01], 0.5)


# ------------------------------------------------------------------------------ command line


def run(*args: str | Path) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("lab")
    res = run("simulate", "--out", d, "--seed", "3", "--N", "100")
    assert res.exit_code == 0, res.output
    return d


def test_cli_with_two_models_selects_and_writes_order_json(lab, tmp_path):
    out = tmp_path / "fit"
    args = [
        "fit",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--jitter",
        "known:uniform:a=0.5",
        "--out",
        out,
        "--no-plots",
    ]
    res = run(*args, "--model", "tf:0,1", "--model", "polepair")
    assert res.exit_code == 0, res.output
    assert "order selection" in res.output
    assert "chosen: polepair" in res.output
    order = json.loads((out / "order.json").read_text())
    assert order["chosen"] == "polepair"
    assert order["chosen_model"] == "polepair"
    assert order["models"] == ["tf:0,1", "polepair"]
    assert len(order["rows"]) == 2
    result = json.loads((out / "result.json").read_text())
    assert result["model"]["spec"] == "polepair"
    assert result["order_selection"]["chosen"] == "polepair"
    report = (out / "report.md").read_text()
    assert "## Order selection" in report
    assert "| **chosen** | polepair |" in report
    # the chosen model goes on exactly as a single-model fit
    single = tmp_path / "single"
    res1 = run(*args[:-3], "--out", single, "--no-plots", "--model", "polepair")
    assert res1.exit_code == 0, res1.output
    one = json.loads((single / "result.json").read_text())
    assert one["parameters"] == result["parameters"]
    assert one["stderr"] == result["stderr"]
    assert not (single / "order.json").exists()
    assert "order_selection" not in one
    assert "Order selection" not in (single / "report.md").read_text()


def test_cli_validation_and_usage_errors(lab, tmp_path):
    val = tmp_path / "val"
    assert run("simulate", "--out", val, "--seed", "4", "--N", "100").exit_code == 0
    base = [
        "fit",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--jitter",
        "known:uniform:a=0.5",
        "--no-plots",
    ]
    res = run(
        *base,
        "--out",
        tmp_path / "v",
        "--model",
        "tf:0,1",
        "--model",
        "polepair",
        "--validation",
        val / "data.csv",
        "--validation-input",
        val / "input.csv",
        "--criterion",
        "validation",
    )
    assert res.exit_code == 0, res.output
    order = json.loads((tmp_path / "v" / "order.json").read_text())
    assert order["criterion"] == "validation"
    assert order["validation_sha256"]
    assert all(r["validation_fit_pct"] is not None for r in order["rows"])
    for extra, match in (
        (["--model", "tf:0,1", "--model", "TF:0,1"], "given twice"),
        (["--model", "tf:0,1", "--validation", val / "data.csv"], "several --model"),
        (
            ["--model", "tf:0,1", "--model", "polepair", "--criterion", "validation"],
            "needs a --validation",
        ),
        (
            ["--model", "tf:0,1", "--model", "polepair", "--validation-input", val / "input.csv"],
            "needs --validation",
        ),
    ):
        bad = run(*base, "--out", tmp_path / "bad", *extra)
        assert bad.exit_code == 2, bad.output
        assert match in bad.output
        assert "Traceback" not in bad.output
        assert not (tmp_path / "bad" / "order.json").exists()


# ------------------------------------------------------------------------------ Monte Carlo

G3 = ji.TransferFunction([6.25 * 0.5], np.polymul([1.0, 3.0, 6.25], [1.0, 0.5]))  # G2 * 0.5/(s+0.5)
MC_SYSTEMS = {1: G1, 2: G2, 3: G3}
MC_RUNS = 20
#: at least this many of MC_RUNS data sets of each order must get their true order
MC_THRESHOLD = 16
MC_CANDIDATES = [ji.RationalModel(0, 1), ji.RationalModel(0, 2), ji.RationalModel(0, 3)]


@pytest.mark.slow
def test_monte_carlo_confusion_table():
    """Data from orders 1, 2, 3 (2/(s+1), the paper's pole pair, the pole pair times
    0.5/(s+0.5)), 20 data sets each as in the README (telegraph input with mean hold 1 s,
    U(-0.5, 0.5), T = 1, N = 200, noise 0.01), candidates tf:0,1, tf:0,2, tf:0,3 (unbounded
    coefficients: the search keeps every mode below |p| T = 1e4,
    resources.SEARCH_RATE_LIMIT) fitted with bcls and with gaussian, chosen by BIC.

    Threshold 16 / 20 per order and method. The slowest true pole (0.5 rad/s) and the fastest
    (|-1.5 + 2i| = 2.5 rad/s, below Nyquist pi rad/s) are both resolved by 200 samples of a
    switching input, and at N = 200 the log-likelihood gap between the true and an
    under-modelled order is tens to hundreds of units against a BIC penalty of ln 200 = 5.3
    per parameter, so under-modelling is never chosen; an over-order fit gains O(1) in the
    log-likelihood, and is mostly set aside besides (on a bound, unstable, or flagged
    over-order). 16 of 20 leaves room for a true-order fit that ends untrustworthy for other
    reasons (a local optimum, a lack-of-fit flag) without letting a systematic preference
    pass: a selector right 90 % of the time passes with probability 0.96, 80 % with 0.63, and
    60 % with 0.05.
    """
    tables = {}
    for method in ("bcls", "gaussian"):
        table = np.zeros((3, 4), int)  # true order x chosen order (last column: none)
        bic_only = np.zeros((3, 3), int)  # the lowest BIC of every row, trusted or not
        for order, system in MC_SYSTEMS.items():
            for run_ in range(MC_RUNS):
                rng = np.random.default_rng(1000 * order + run_)
                u = ji.telegraph_input(203.0, rng)
                data = ji.simulate(system, u, JITTER, T=1.0, N=200, noise_std=NOISE, rng=rng)
                sel = ji.select_order(data, MC_CANDIDATES, JITTER, method)
                table[order - 1, 3 if sel.chosen is None else sel.chosen] += 1
                bics = [r.bic if math.isfinite(r.bic) else np.inf for r in sel.rows]
                bic_only[order - 1, int(np.argmin(bics))] += 1
        tables[method] = table
        print(f"\n{method}: true order \\ chosen   1   2   3  none   | lowest BIC alone 1   2   3")
        for order in MC_SYSTEMS:
            print(
                f"  order {order}            "
                + " ".join(f"{v:>3}" for v in table[order - 1])
                + "      |                 "
                + " ".join(f"{v:>3}" for v in bic_only[order - 1])
            )
    for method, table in tables.items():
        for order in MC_SYSTEMS:
            assert table[order - 1, order - 1] >= MC_THRESHOLD, (method, table)


def test_an_over_order_search_stays_where_the_samples_see_its_modes():
    """An over-order model's extra poles used to run off to |p| T ~ 1e5..1e9, where every
    evaluation of the jittered moments took seconds (one gaussian fit of tf:1,3 ran 633 s):
    the search now refuses modes beyond resources.SEARCH_RATE_LIMIT, and the fit ends with
    an honest status or a row the selection sets aside. The fits take no covariance
    (cov_type="none", passed on to fit): the search is what is tested, and the same rows
    end the same way either way (tf:1,3 OPTIMISER_FAILED at |p| T = 9.1e3), but the
    sandwich's moments at that mode cost 5.8 of the selection's 6.4 CPU-s."""
    from jitterid.estimation.resources import SEARCH_RATE_LIMIT

    rng = np.random.default_rng(102)
    u = ji.telegraph_input(230.0, rng)
    data = ji.simulate(
        ji.TransferFunction([2.0], [1.0, 1.0]),
        u,
        ji.Uniform(0.5),
        T=1.0,
        N=200,
        noise_std=0.01,
        rng=rng,
    )
    sel = ji.select_order(
        data,
        [ji.RationalModel(0, 1), ji.RationalModel(1, 3)],
        ji.Uniform(0.5),
        "gaussian",
        cov_type="none",
    )
    assert sel.best is not None
    assert sel.best.label == "tf:0,1"
    over = sel.row("tf:1,3")
    assert not over.trustworthy
    if over.result is not None and over.result.system is not None:
        assert np.max(np.abs(over.result.system.poles)) * data.T <= SEARCH_RATE_LIMIT * (1 + 1e-9)


def test_fast_modes_are_refused_for_searched_models_only():
    from jitterid.estimation.resources import check_mode_rate

    rng = np.random.default_rng(1)
    u = ji.telegraph_input(60.0, rng)
    fast = ji.TransferFunction([2e5], [1.0, 1e5])
    with pytest.raises(ValueError, match="the samples cannot see it"):
        check_mode_rate(fast.response(u), 1.0)
    check_mode_rate(fast.response(u), 1e-5)  # |p| T = 1: fine
    # a known system with such a mode is still evaluated (nothing is searched), and its
    # response before the input starts is 0 without overflow warnings
    np.testing.assert_array_equal(fast.response(u)(np.array([-0.3, -1e-6])), 0.0)
    data = ji.simulate(fast, u, ji.Uniform(0.5), T=1.0, N=50, noise_std=0.01, rng=rng)
    res = ji.fit(data, fast, ji.Uniform(0.5), "bcls")
    assert np.isfinite(res.cost)
