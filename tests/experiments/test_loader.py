"""Experiment definitions, the results store, the reports and `jitterid reproduce` end to end."""

import copy
import csv
import dataclasses
import math
import re
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.cli import main
from jitterid.estimation import problem as criteria
from jitterid.experiments import (
    PAPER_EXPERIMENTS,
    ExperimentError,
    load_experiment,
    packaged_path,
    parse_experiment,
)
from jitterid.experiments import runner as runner_mod
from jitterid.experiments.report import (
    markdown_report,
    paper_numbers,
    summarize,
    true_values,
)
from jitterid.experiments.runner import realize, run_experiment, seed_streams, store_path
from jitterid.experiments.store import Estimate, Store, StoreError

TINY = tomllib.loads("""
[experiment]
name = "tiny"
runs = 3
seed = 11
[sampling]
T = 1.0
N = 48
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = { k0 = 6.25, pr = -1.5, pi = 2.0 }
[jitter]
model = "known"
[[cases]]
name = "u"
law = { kind = "uniform", a = 0.5 }
[[cases]]
name = "g"
law = { kind = "gaussian", sigma = 0.05 }
[estimators]
methods = ["ls", "bcls"]
""")


TINY_CASES = parse_experiment(copy.deepcopy(TINY), "tiny.toml").cases


def tiny(**changes):
    return dataclasses.replace(parse_experiment(copy.deepcopy(TINY), "tiny.toml"), **changes)


def read_csv(path):
    return list(csv.DictReader(path.read_text().splitlines()))


def edited(path, value):
    """TINY with the dotted key ``path`` set to ``value`` (None deletes it)."""
    data = copy.deepcopy(TINY)
    *parents, last = path.split(".")
    node = data
    for p in parents:
        node = node[int(p)] if p.isdigit() else node[p]
    if value is None:
        del node[last]
    else:
        node[last] = value
    return data


# ------------------------------------------------------------------ definitions
@pytest.mark.parametrize("name", PAPER_EXPERIMENTS)
def test_packaged_definitions_load_with_the_papers_settings(name):
    exp = load_experiment(packaged_path(name))
    assert (exp.T, exp.N, exp.noise_std, exp.runs) == (1.0, 200, 0.01, 128)
    assert exp.input.levels == (-0.5, 0.5)
    assert exp.input.mean_hold == 1.0
    assert exp.paper_table == int(name[-1])
    # every case with a paper block has true values matching the paper's (tables.csv)
    paper = paper_numbers(exp.paper_table)
    for case in exp.cases:
        for p, v in true_values(exp, case).items():
            if (case.paper_case, "-", "true", p) in paper:
                assert v == pytest.approx(paper[case.paper_case, "-", "true", p], abs=6e-5)


def test_table1_cases_are_the_papers_six_laws():
    exp = load_experiment(packaged_path("table1"))
    stds = [c.law.build().std for c in exp.cases]
    np.testing.assert_allclose(
        stds, [1 / 12**0.5, 1 / 6, 1 / 6, 1 / (6 * 3**0.5), 1 / 6, 1 / (6 * 3**0.5)]
    )


@pytest.mark.parametrize(
    ("path", "value", "named"),
    [
        ("sampling.Nn", 200, "sampling.Nn"),  # typo: unknown key, before 'N' is missed
        ("sampling.N", 0, "sampling.N"),
        ("sampling.noise_std", -0.01, "sampling.noise_std"),
        ("sampling.T", "1", "sampling.T"),
        ("experiment.seed", 1.5, "experiment.seed"),
        ("experiment.runs", None, "experiment.runs"),
        ("estimators.methods", ["ls", "bclss"], "estimators.methods[1]"),
        ("cases.0.law", {"kind": "uniform", "a": -0.5}, "cases[0].law.a"),
        ("cases.0.law", {"kind": "uniform", "sigma": 0.5}, "cases[0].law.sigma"),
        ("cases.0.law", {"kind": "unifrom", "a": 0.5}, "cases[0].law.kind"),
        ("system.truth", {"k0": 6.25, "pr": -1.5}, "system.truth.pi"),
        ("system.truth", {"k0": 6.25, "pr": 1.5, "pi": 2.0}, "system.truth"),
        ("jitter.model", "sum_of_uniform", "jitter.model"),
        ("jitter.a_max", 0.5, "jitter.a_max"),  # not an option of model 'known'
        ("cases.0.law", {"kind": "uniform", "a": 3.5}, "input.margin"),  # input too short
        ("inputs", {}, "inputs"),
        ("estimators.crb", "yes", "estimators.crb"),
        ("estimators.crb_runs", 4, "estimators.crb_runs"),  # without crb = true
        ("estimators.crb_runs", 0, "estimators.crb_runs"),
    ],
)
def test_a_bad_definition_fails_naming_the_key(path, value, named):
    with pytest.raises(ExperimentError) as err:
        parse_experiment(edited(path, value), "tiny.toml")
    assert "tiny.toml: " in str(err.value)
    assert named in str(err.value)


def test_crb_needs_the_true_noise():
    data = edited("estimators.crb", True)
    data["sampling"]["noise_known"] = False
    with pytest.raises(ExperimentError, match=r"estimators\.crb needs a known, positive noise_std"):
        parse_experiment(data, "tiny.toml")


def test_a_typo_gets_a_did_you_mean_hint():
    with pytest.raises(ExperimentError, match=r"did you mean 'noise_std'"):
        parse_experiment(edited("sampling.noise_sd", 0.01), "tiny.toml")


def test_ls_cannot_estimate_a_jitter_family():
    data = edited("jitter.model", "sum_of_uniforms")
    with pytest.raises(ExperimentError, match=r"estimators\.methods.*'ls'"):
        parse_experiment(data, "tiny.toml")


def test_methods_are_checked_against_the_librarys_list_at_load_time(monkeypatch):
    data = edited("estimators.methods", ["bcls", "ml"])
    if "ml" not in criteria.METHODS:
        with pytest.raises(ExperimentError, match="methods"):
            parse_experiment(copy.deepcopy(data), "tiny.toml")
    monkeypatch.setattr(criteria, "METHODS", (*criteria.METHODS, "ml"))
    assert parse_experiment(data, "tiny.toml").methods == ("bcls", "ml")


def test_run_with_a_bad_file_fails_before_any_work(tmp_path):
    text = packaged_path("table2").read_text().replace("noise_std = 0.01", "noise_std = 'x'")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    res = CliRunner().invoke(main, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert "bad.toml: sampling.noise_std must be a finite number" in res.output
    assert not (tmp_path / "o").exists()


def test_fingerprint_ignores_runs_and_titles_but_not_the_seed():
    base = tiny()
    assert dataclasses.replace(base, runs=99, title="x").fingerprint() == base.fingerprint()
    assert dataclasses.replace(base, seed=12).fingerprint() != base.fingerprint()


# ------------------------------------------------------------------ seeds and one realization
def test_streams_come_from_seedsequence_spawn_and_do_not_depend_on_runs():
    a, b = seed_streams(5, 2, 3), seed_streams(5, 2, 8)
    for c in range(2):
        for r in range(3):
            assert a[c][r].spawn_key == (c, r) == b[c][r].spawn_key
            np.testing.assert_array_equal(a[c][r].generate_state(4), b[c][r].generate_state(4))
    assert not np.array_equal(a[0][0].generate_state(4), a[1][0].generate_state(4))


def test_a_realization_is_the_direct_simulation_and_fit():
    exp = tiny()
    rows, _ = realize(exp, 1, 2, seed_streams(exp.seed, 2, 3)[1][2])
    # referee: the same realization written out by hand from the documented recipe
    rng = np.random.default_rng(np.random.SeedSequence(11, spawn_key=(1, 2)))
    u = ji.telegraph_input(48 * 1.0 + 2.0, rng)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    data = ji.simulate(truth, u, ji.Gaussian(0.05), 1.0, 48, 0.01, rng)
    for row, method in zip(rows, ["ls", "bcls"], strict=True):
        ref = ji.fit(data, ji.PolePairGain(), ji.Gaussian(0.05), method)
        assert (row.case_name, row.realization, row.method) == ("g", 2, method)
        assert row.params == ref.params
        assert row.cost == ref.cost
        assert row.stderr == ref.stderr
        assert row.success == ref.success


def test_a_fit_that_raises_is_stored_as_a_failed_row(monkeypatch):
    def broken(data, system, jitter, method):
        raise ValueError("boom")

    monkeypatch.setattr(runner_mod, "fit", broken)
    exp = tiny()
    rows, _ = realize(exp, 0, 0, seed_streams(exp.seed, 2, 1)[0][0])
    assert [r.status for r in rows] == ["ERROR", "ERROR"]
    assert not any(r.success for r in rows)
    assert "boom" in rows[0].message


# ------------------------------------------------------------------ store
def _row(case="u", r=0, method="ls", value=1.0):
    return Estimate(
        case,
        r,
        method,
        {"k0": value},
        {"k0": math.nan},
        0.1,
        0.0,
        2.0,
        True,
        "CONVERGED",
        "ok",
        5,
        0.01,
    )


def test_store_commits_a_realization_atomically_and_refuses_duplicates(tmp_path):
    exp = tiny()
    with Store(tmp_path / "s.sqlite", exp) as store:
        store.add_realization([_row(), _row(method="bcls", value=2.0)], 0.5)
        with pytest.raises(StoreError, match="another process"):
            store.add_realization([_row(r=1), _row(r=1, method="ls")], 0.5)  # duplicate row
        assert store.done() == {("u", 0)}  # the failed transaction left nothing behind
        got = store.estimates()
    assert [(e.method, e.params["k0"]) for e in got] == [("bcls", 2.0), ("ls", 1.0)]
    assert math.isnan(got[0].stderr["k0"])


def test_store_refuses_reuse_without_resume_and_another_definition(tmp_path):
    exp = tiny()
    with Store(tmp_path / "s.sqlite", exp) as store:
        store.add_realization([_row()], 0.1)
    with pytest.raises(StoreError, match="--resume"):
        Store(tmp_path / "s.sqlite", exp)
    with pytest.raises(StoreError, match="different definition"):
        Store(tmp_path / "s.sqlite", dataclasses.replace(exp, seed=1), resume=True)
    Store(tmp_path / "s.sqlite", dataclasses.replace(exp, runs=50), resume=True).close()


def test_resume_with_more_runs_adds_only_the_new_realizations(tmp_path):
    exp = tiny(runs=2)
    first = run_experiment(exp, tmp_path, progress=False)
    more = run_experiment(dataclasses.replace(exp, runs=3), tmp_path, resume=True, progress=False)
    assert (first.new, more.already_done, more.new) == (4, 4, 2)
    with Store(store_path(exp, tmp_path), exp, resume=True) as store:
        assert store.done() == {(c, r) for c in "ug" for r in range(3)}
        assert len(store.estimates(2)) == 2 * 2 * 2


def test_csv_export_holds_the_stored_numbers_exactly(tmp_path):
    exp = tiny(runs=2)
    run_experiment(exp, tmp_path, progress=False)
    with Store(store_path(exp, tmp_path), exp, resume=True) as store:
        rows = store.estimates()
        path = store.export_csv(tmp_path / "t.csv")
    table = read_csv(path)
    assert len(table) == len(rows) == 8
    for e, line in zip(rows, table, strict=True):
        assert (line["case"], int(line["realization"]), line["method"]) == (
            e.case_name,
            e.realization,
            e.method,
        )
        for p, v in e.params.items():
            assert float(line[p]) == v
            np.testing.assert_equal(float(line[f"{p}_stderr"]), e.stderr[p])  # NaN == NaN


# ------------------------------------------------------------------ report
def _fake(exp, values_by_method, case="u"):
    return [
        Estimate(case, r, m, {"k0": v}, {}, 0.2, 0.0, 1.0, True, "CONVERGED", "", 1, 0.1)
        for m, vals in values_by_method.items()
        for r, v in enumerate(vals)
    ]


def test_summary_statistics_are_mean_std_and_sem_of_converged_fits():
    exp = tiny()
    rng = np.random.default_rng(0)
    vals = rng.normal(6.0, 0.3, 40)
    est = _fake(exp, {"ls": vals, "bcls": vals + 1})
    est.append(dataclasses.replace(est[0], realization=99, success=False, params={"k0": 1e9}))
    s = summarize(exp, est)["u", "ls"]
    assert (s.total, s.converged) == (41, 40)
    assert s.stats["k0"].mean == pytest.approx(vals.mean())
    assert s.stats["k0"].std == pytest.approx(vals.std(ddof=1))
    assert s.stats["k0"].sem == pytest.approx(vals.std(ddof=1) / np.sqrt(40))


def test_report_flags_a_difference_from_the_paper_beyond_monte_carlo_error():
    exp = dataclasses.replace(
        tiny(),
        paper_table=2,
        paper_labels=(("ls", "LS"), ("bcls", "BCLS")),
        cases=(dataclasses.replace(tiny().cases[0], paper_case=1),),
    )
    rng = np.random.default_rng(1)
    noise = rng.normal(0, 1, 128)
    noise = (noise - noise.mean()) / noise.std(ddof=1)
    # LS: exactly the paper's mean and std of k0; BCLS: mean 1 (paper 6.2536) -> flagged
    est = _fake(exp, {"ls": 5.8468 + 0.1723 * noise, "bcls": 1.0 + 0.0479 * noise})
    text = markdown_report(exp, est, "jitterid test")
    ls_line = next(ln for ln in text.splitlines() if ln.startswith("| LS (`ls`) | mean ± SEM"))
    bcls_line = next(ln for ln in text.splitlines() if ln.startswith("| BCLS (`bcls`) | mean ±"))
    assert "5.8468 ± 0.0152" in ls_line
    assert "⚑" not in ls_line.split("|")[3]
    assert "⚑" in bcls_line.split("|")[3]
    flagged = text.split("Beyond Monte Carlo error")[1]
    assert "BCLS mean of k0: z = " in flagged
    assert "BCLS std" not in flagged
    assert not re.search(r"(?<!BC)LS (mean|std)", flagged)
    assert "| LS (`ls`) | mean, paper | 5.8468 |" in text


# ------------------------------------------------------------------ end to end
def test_reproduce_table2_runs_end_to_end(tmp_path):
    res = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            "8",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "table2.csv")
    assert len(rows) == 8 * 6
    assert {r["method"] for r in rows} == {"ls", "bcls", "asml-diag", "gaussian", "ml", "crb"}
    report = (tmp_path / "table2.md").read_text()
    assert "| CRB | √(mean bound), first 8 inputs |" in report
    assert report.count("std / √CRB, here") == 5
    assert "jitterid reproduce table2 --runs 8" in report
    for method, label in [("ls", "LS"), ("bcls", "BCLS"), ("asml-diag", "AsML")]:
        k0 = np.array(
            [float(r["k0"]) for r in rows if r["method"] == method and r["success"] == "1"]
        )
        mean, sem = k0.mean(), k0.std(ddof=1) / np.sqrt(k0.size)
        line = next(
            ln
            for ln in report.splitlines()
            if ln.startswith(f"| {label} (`{method}`) | mean ± SEM")
        )
        assert line.split("|")[3].strip().strip("*").startswith(f"{mean:.4f} ± {sem:.4f}")
    # running again without --resume is refused; with it, nothing is redone
    again = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            "8",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ],
    )
    assert again.exit_code == 1
    assert "--resume" in again.output
    resumed = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            "8",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
            "--resume",
        ],
    )
    assert resumed.exit_code == 0
    assert "8 already stored, 0 new" in resumed.output


@pytest.mark.parametrize("fig", ["fig1", "fig2", "fig3", "fig4"])
def test_figures_are_written(tmp_path, fig):
    res = CliRunner().invoke(main, ["reproduce", fig, "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    png = (tmp_path / f"{fig}.png").read_bytes()
    assert png.startswith(b"\x89PNG")
    assert len(png) > 10_000
    assert f"({fig}.png)" in (tmp_path / "figures.md").read_text()


def test_print_toml_gives_a_loadable_copy(tmp_path):
    res = CliRunner().invoke(main, ["reproduce", "table3", "--print-toml"])
    assert res.exit_code == 0
    (tmp_path / "mine.toml").write_text(res.output)
    assert load_experiment(tmp_path / "mine.toml") == load_experiment(packaged_path("table3"))


def test_bound_row_is_the_crb_of_the_realizations_input():
    """The stored crb row equals jitterid.crb evaluated independently on the same input
    (rebuilt from the realization's seed stream), and sigma's bound is the delta method
    with the analytic gradient of sigma = a / sqrt(3 (n + 1))."""
    from jitterid.experiments.runner import realize, seed_streams

    exp = dataclasses.replace(load_experiment(packaged_path("table3")), methods=("bcls",), crb=True)
    stream = seed_streams(exp.seed, len(exp.cases), 3)[0][2]
    rows, _ = realize(exp, 0, 2, stream)
    row = next(r for r in rows if r.method == "crb")
    u = exp.input.build(exp.duration, np.random.default_rng(seed_streams(exp.seed, 1, 3)[0][2]))
    n, a = 2.0, 0.28867513459481287
    bound = ji.crb(
        ji.PolePairGain(),
        exp.estimation_jitter(exp.cases[0]),
        u,
        1.0,
        200,
        0.01,
        [n, a, 6.25, -1.5, 2.0],
    )
    np.testing.assert_allclose(
        [row.stderr[p] for p in ("n", "a", "k0", "pr", "pi")], np.sqrt(np.diag(bound)), rtol=1e-12
    )
    s = a / np.sqrt(3 * (n + 1))
    g = np.array([-s / (2 * (n + 1)), s / a])
    np.testing.assert_allclose(row.stderr["sigma"], np.sqrt(g @ bound[:2, :2] @ g), rtol=1e-5)
    assert row.success
    assert row.status == "BOUND"


# ------------------------------------------------------------------ sharing (issue 13)
def bound_tiny(**changes):
    """TINY with the bound on, the first two realizations storing it, and the estimators
    that start from the BCLS stage."""
    data = copy.deepcopy(TINY)
    data["estimators"] = {
        "methods": ["ls", "bcls", "asml-diag", "gaussian"],
        "crb": True,
        "crb_runs": 2,
    }
    return dataclasses.replace(parse_experiment(data, "tiny.toml"), **changes)


def test_sharing_gives_the_numbers_of_fits_from_scratch():
    """One BCLS search shared by the methods of a realization gives, bit for bit, what each
    method finds searching from scratch (``share=False``: its own BCLS stage); only the
    bound rows differ, present on every realization without sharing."""
    exp = bound_tiny(runs=3)
    for ci in range(len(exp.cases)):
        for r in (0, 2):
            stream = runner_mod.seed_stream(exp.seed, ci, r)
            shared, _ = realize(exp, ci, r, stream, share=True)
            alone, _ = realize(exp, ci, r, stream, share=False)
            by = {e.method: e for e in alone}
            assert [e.method for e in alone] == [*exp.methods, "crb"]
            assert [e.method for e in shared] == [*exp.methods, *(["crb"] if r < 2 else [])]
            for e in shared:
                assert e.same_numbers(by[e.method]), (e, by[e.method])


def test_crb_runs_averages_the_bounds_of_the_first_realizations(tmp_path):
    """With crb_runs = 2 the store holds the bound of realizations 0 and 1 only, and the
    report's row is sqrt(mean over those two inputs of diag(crb)): each bound recomputed
    here with jitterid.crb on the input rebuilt from the realization's seed stream (the
    per-input bounds averaged, not the inverse of an averaged Fisher information). Adding
    realizations (--resume) does not move it; the definition's fingerprint ignores
    crb_runs, so a store written with the bound on every realization is resumed."""
    from jitterid.experiments.report import bound_roots

    exp = bound_tiny(runs=3, cases=TINY_CASES[:1])
    run_experiment(exp, tmp_path, workers=1, progress=False)
    with Store(store_path(exp, tmp_path), exp, resume=True) as store:
        rows = store.estimates()
    assert sorted(e.realization for e in rows if e.method == "crb") == [0, 1]
    bounds = []
    for r in (0, 1):
        rng = np.random.default_rng(runner_mod.seed_stream(exp.seed, 0, r))
        u = exp.input.build(exp.duration, rng)
        bounds.append(
            ji.crb(ji.PolePairGain(), ji.Uniform(0.5), u, 1.0, 48, 0.01, [6.25, -1.5, 2.0])
        )
    want = np.sqrt(np.mean([np.diag(b) for b in bounds], axis=0))
    got = bound_roots(exp, rows)["u"]
    np.testing.assert_allclose([got[p] for p in ("k0", "pr", "pi")], want, rtol=1e-12)
    # the inverse of the mean Fisher information is smaller (Jensen): not what is reported
    pooled = np.sqrt(np.diag(np.linalg.inv(np.mean([np.linalg.inv(b) for b in bounds], axis=0))))
    assert np.all(pooled <= want * (1 + 1e-12))
    assert np.any(pooled < want * (1 - 1e-4))
    more = dataclasses.replace(exp, runs=4)
    run_experiment(more, tmp_path, workers=1, progress=False, resume=True)
    with Store(store_path(more, tmp_path), more, resume=True) as store:
        rows4 = store.estimates()
    assert bound_roots(more, rows4) == bound_roots(exp, rows)
    assert "| CRB | √(mean bound), first 2 inputs |" in markdown_report(more, rows4, "cmd")
    every = dataclasses.replace(exp, crb_runs=None)
    assert every.fingerprint() == exp.fingerprint()
    assert every.bound_runs() == 3
    assert exp.bound_runs() == 2
    assert dataclasses.replace(exp, crb=False).bound_runs() == 0
