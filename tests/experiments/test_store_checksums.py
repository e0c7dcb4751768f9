"""Issue 25, item 9: a value changed in place in a stored row was not detected on --resume;
every estimate row now has a checksum, checked when the store is opened."""

import sqlite3

import pytest
from click.testing import CliRunner

from jitterid.cli import main
from jitterid.experiments import load_experiment
from jitterid.experiments.runner import run_experiment, store_path
from jitterid.experiments.store import Store, StoreError

DEFINITION = """
[experiment]
name = "sums"
runs = 2
seed = 5
[sampling]
T = 1.0
N = 60
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = { k0 = 6.25, pr = -1.5, pi = 2.0 }
[jitter]
model = "known"
[[cases]]
name = "uniform"
law = { kind = "uniform", a = 0.5 }
[estimators]
methods = ["ls"]
"""


@pytest.fixture
def stored(tmp_path):
    path = tmp_path / "sums.toml"
    path.write_text(DEFINITION)
    exp = load_experiment(path)
    run_experiment(exp, tmp_path / "o", progress=False)
    return exp, store_path(exp, tmp_path / "o"), path


def edit(db_path, sql):
    with sqlite3.connect(db_path) as db:
        db.execute(sql)


@pytest.mark.parametrize(
    ("sql", "what"),
    [
        ("UPDATE estimates SET cost = cost * 1.001 WHERE realization = 0", "uniform/0/ls changed"),
        ("UPDATE estimates SET params = '{\"k0\": 6.25}' WHERE realization = 1", "1/ls changed"),
        ("UPDATE estimates SET success = 1 - success WHERE realization = 1", "1/ls changed"),
        ("DELETE FROM estimates WHERE realization = 0", "uniform/0/ls removed"),
        (
            (
                "INSERT INTO estimates SELECT experiment, case_name, realization, 'bcls', "
                "params, stderr, jitter_std, noise_std, cost, success, status, message, nfev, "
                "elapsed_s FROM estimates WHERE realization = 0"
            ),
            "uniform/0/bcls changed or added",
        ),
    ],
)
def test_an_in_place_change_is_refused_on_resume(stored, sql, what):
    exp, db, toml = stored
    edit(db, sql)
    with pytest.raises(StoreError, match="modified after its results were stored") as err:
        Store(db, exp, resume=True)
    assert what in str(err.value)
    res = CliRunner().invoke(
        main, ["run", str(toml), "--resume", "--out", str(db.parent), "--no-progress"]
    )
    assert res.exit_code == 1
    assert "modified after its results were stored" in res.output


def test_an_untouched_store_resumes_and_a_recomputed_realization_gets_new_sums(stored):
    exp, db, _ = stored
    with Store(db, exp, resume=True) as store:
        before = store.estimates()
    edit(db, "DELETE FROM realizations WHERE realization = 1")  # a realization to redo
    run_experiment(exp, db.parent, resume=True, progress=False)
    with Store(db, exp, resume=True) as store:
        after = store.estimates()
    assert len(after) == len(before) == 2
    assert all(a.same_numbers(b) for a, b in zip(after, before, strict=True))


def test_a_store_from_before_the_checksums_gets_them_then_is_checked(stored):
    exp, db, _ = stored
    edit(db, "DELETE FROM row_checksums")
    edit(db, "DELETE FROM meta WHERE key = 'row_checksums'")
    Store(db, exp, resume=True).close()  # taken as found, checksums written
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT COUNT(*) FROM row_checksums").fetchone()[0] == 2
    edit(db, "UPDATE estimates SET nfev = nfev + 1 WHERE realization = 0")
    with pytest.raises(StoreError, match="uniform/0/ls changed"):
        Store(db, exp, resume=True)
