"""The results store (jitterid.experiments.store): atomic realizations, refused reuse, and the
CSV export holding the stored numbers exactly."""

import dataclasses
import math

import numpy as np
import pytest
from helpers import read_csv, tiny_experiment

from jitterid.experiments.runner import run_experiment, store_path
from jitterid.experiments.store import Estimate, Store, StoreError


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
    exp = tiny_experiment()
    with Store(tmp_path / "s.sqlite", exp) as store:
        store.add_realization([_row(), _row(method="bcls", value=2.0)], 0.5)
        with pytest.raises(StoreError, match="another process"):
            store.add_realization([_row(r=1), _row(r=1, method="ls")], 0.5)  # duplicate row
        assert store.done() == {("u", 0)}  # the failed transaction left nothing behind
        got = store.estimates()
    assert [(e.method, e.params["k0"]) for e in got] == [("bcls", 2.0), ("ls", 1.0)]
    assert math.isnan(got[0].stderr["k0"])


def test_store_refuses_reuse_without_resume_and_another_definition(tmp_path):
    exp = tiny_experiment()
    with Store(tmp_path / "s.sqlite", exp) as store:
        store.add_realization([_row()], 0.1)
    with pytest.raises(StoreError, match="--resume"):
        Store(tmp_path / "s.sqlite", exp)
    with pytest.raises(StoreError, match="different definition"):
        Store(tmp_path / "s.sqlite", dataclasses.replace(exp, seed=1), resume=True)
    Store(tmp_path / "s.sqlite", dataclasses.replace(exp, runs=50), resume=True).close()


def test_csv_export_holds_the_stored_numbers_exactly(tmp_path):
    exp = tiny_experiment(runs=2)
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
