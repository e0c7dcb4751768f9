"""The Monte Carlo runner (jitterid.experiments.runner): seed streams, one realization against
the direct simulation and fit, failed fits stored as rows, resuming, the bound rows against
jitterid.crb, and the shared BCLS stage against fits from scratch."""

import copy
import dataclasses

import numpy as np
from helpers import TINY_EXPERIMENT, tiny_experiment

import jitterid as ji
from jitterid.experiments import (
    load_experiment,
    packaged_path,
    parse_experiment,
)
from jitterid.experiments import runner as runner_mod
from jitterid.experiments.report import (
    markdown_report,
)
from jitterid.experiments.runner import realize, run_experiment, seed_streams, store_path
from jitterid.experiments.store import Store

TINY_CASES = parse_experiment(copy.deepcopy(TINY_EXPERIMENT), "tiny.toml").cases


# ------------------------------------------------------------------ seeds and one realization
def test_streams_come_from_seedsequence_spawn_and_do_not_depend_on_runs():
    a, b = seed_streams(5, 2, 3), seed_streams(5, 2, 8)
    for c in range(2):
        for r in range(3):
            assert a[c][r].spawn_key == (c, r) == b[c][r].spawn_key
            np.testing.assert_array_equal(a[c][r].generate_state(4), b[c][r].generate_state(4))
    assert not np.array_equal(a[0][0].generate_state(4), a[1][0].generate_state(4))


def test_a_realization_is_the_direct_simulation_and_fit():
    exp = tiny_experiment()
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
    exp = tiny_experiment()
    rows, _ = realize(exp, 0, 0, seed_streams(exp.seed, 2, 1)[0][0])
    assert [r.status for r in rows] == ["ERROR", "ERROR"]
    assert not any(r.success for r in rows)
    assert "boom" in rows[0].message


def test_resume_with_more_runs_adds_only_the_new_realizations(tmp_path):
    exp = tiny_experiment(runs=2)
    first = run_experiment(exp, tmp_path, progress=False)
    more = run_experiment(dataclasses.replace(exp, runs=3), tmp_path, resume=True, progress=False)
    assert (first.new, more.already_done, more.new) == (4, 4, 2)
    with Store(store_path(exp, tmp_path), exp, resume=True) as store:
        assert store.done() == {(c, r) for c in "ug" for r in range(3)}
        assert len(store.estimates(2)) == 2 * 2 * 2


def test_bound_row_is_the_crb_of_the_realizations_input():
    """The stored crb row equals jitterid.crb evaluated independently on the same input
    (rebuilt from the realization's seed stream), and sigma's bound is the delta method
    with the analytic gradient of sigma = a / sqrt(3 (n + 1))."""
    from jitterid.experiments.runner import realize, seed_streams

    # (one method, the cheapest: the bound row does not depend on the estimators run)
    exp = dataclasses.replace(load_experiment(packaged_path("table3")), methods=("ls",), crb=True)
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
    """TINY_EXPERIMENT with the bound on, the first two realizations storing it, and the estimators
    that start from the BCLS stage."""
    data = copy.deepcopy(TINY_EXPERIMENT)
    data["estimators"] = {
        "methods": ["ls", "bcls", "asml-diag", "gaussian"],
        "crb": True,
        "crb_runs": 2,
    }
    return dataclasses.replace(parse_experiment(data, "tiny.toml"), **changes)


def test_sharing_gives_the_numbers_of_fits_from_scratch():
    """One BCLS search shared by the methods of a realization gives, bit for bit, what each
    method finds searching from scratch (``share=False``: its own BCLS stage); only the
    bound rows differ, present on every realization without sharing. (Two realizations:
    one of each case, one storing the bound and one not; each compares every method.)"""
    exp = bound_tiny(runs=3)
    assert len(exp.cases) == 2
    for ci, r in ((0, 0), (1, 2)):
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

    exp = bound_tiny(runs=3, cases=TINY_CASES[:1], methods=("bcls",))  # one estimator row
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
