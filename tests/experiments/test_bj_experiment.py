"""The 'bj' experiment (jitterid.experiments.bj and the [noise] section of a definition): the
packaged study, fingerprints, bad definitions, one realization with its report and figure."""

import copy
import dataclasses
import hashlib
import json
import tomllib

import pytest
from click.testing import CliRunner

from jitterid.cli import main
from jitterid.experiments import ExperimentError, load_experiment, packaged_path, parse_experiment
from jitterid.experiments.bj import spectra_figure
from jitterid.experiments.report import markdown_report
from jitterid.experiments.runner import realize, seed_streams

# --------------------------------------------------------------------------- experiment

TINY = tomllib.loads("""
[experiment]
name = "tiny_bj"
runs = 2
seed = 3
[sampling]
T = 1.0
N = 60
noise_std = 0.01
noise_known = false
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
[noise]
structure = "rational"
truth = { hb0 = 0.06, ha0 = 0.1 }
[estimators]
methods = ["bcls", "gaussian", "bj-gaussian", "jbj-gaussian"]
""")


def edited(path, value):
    data = copy.deepcopy(TINY)
    *parents, last = path.split(".")
    node = data
    for p in parents:
        node = node[p]
    if value is None:
        del node[last]
    else:
        node[last] = value
    return data


def test_packaged_bj_study_is_table_2_with_coloured_noise():
    exp, t2 = load_experiment(packaged_path("bj")), load_experiment(packaged_path("table2"))
    assert (exp.T, exp.N, exp.system, exp.cases[0].law) == (t2.T, t2.N, t2.system, t2.cases[0].law)
    assert exp.noise is not None
    assert exp.noise.true_model().variance == pytest.approx(0.2**2, rel=1e-8)
    assert {"ls", "bcls", "asml-diag", "bj-gaussian", "jbj-gaussian"} <= set(exp.methods)
    assert exp.runs >= 128


def test_white_noise_experiments_keep_their_fingerprint():
    """The new ``noise`` field is left out while None, so stores of Tables 1-3 stay valid."""
    exp = load_experiment(packaged_path("table2"))
    core = dataclasses.replace(
        exp,
        runs=0,
        crb_runs=None,
        title="",
        paper_table=None,
        paper_labels=(),
        description="",
        source="",
    )
    fields = dataclasses.asdict(core)
    assert fields.pop("noise") is None
    assert fields.pop("crb_runs") is None  # how many bounds are computed: not the numbers
    text = json.dumps(fields, sort_keys=True)
    assert exp.fingerprint() == hashlib.sha256(text.encode()).hexdigest()[:16]


@pytest.mark.parametrize(
    ("path", "value", "named"),
    [
        ("noise.trut", {"hb0": 0.1}, "did you mean 'truth'"),
        ("noise.truth", {"hb0": 0.1}, "missing required key 'noise.truth.ha0'"),
        ("noise.num_order", 1, "noise.num_order gives an invalid model"),
        ("noise.structure", "arma", "noise.structure must be one of rational"),
        ("noise", None, "'bj-\\*'/'jbj-\\*' estimators need a \\[noise\\] section"),
        ("estimators.methods", ["bj-gausian"], "did you mean 'bj-gaussian'"),
        ("estimators.crb", True, "estimators.crb .* set crb = false"),
    ],
)
def test_a_bad_noise_definition_fails_naming_the_key(path, value, named):
    with pytest.raises(ExperimentError, match=named):
        parse_experiment(edited(path, value), "tiny_bj.toml")


def test_jbj_needs_a_known_jitter_in_the_definition():
    data = edited("jitter", {"model": "uniform"})
    with pytest.raises(ExperimentError, match=r"'jbj-' estimator with jitter\.model a family"):
        parse_experiment(data, "tiny_bj.toml")


def test_a_bj_realization_report_and_figure(tmp_path):
    exp = parse_experiment(copy.deepcopy(TINY), "tiny_bj.toml")
    streams = seed_streams(exp.seed, 1, exp.runs)
    rows = [e for r in range(exp.runs) for e in realize(exp, 0, r, streams[0][r])[0]]
    by = {(e.method, e.realization): e for e in rows}
    assert set(by["bj-gaussian", 0].params) == {"k0", "pr", "pi", "hb0", "ha0", "noise_std"}
    assert set(by["jbj-gaussian", 0].params) == {"a", "k0", "pr", "pi", "hb0", "ha0", "noise_std"}
    assert all(e.success for e in rows)
    text = markdown_report(exp, rows, "test")
    assert "## Stated uncertainty" in text
    assert "| bj-gaussian |" in text
    assert "| θ⁰ | true | 6.2500 | -1.5000 | 2.0000 |" in text
    path = spectra_figure(tmp_path, exp, rows)
    assert path.stat().st_size > 10_000


def test_reproduce_bj_prints_its_definition():
    out = CliRunner().invoke(main, ["reproduce", "bj", "--print-toml"])
    assert out.exit_code == 0, out.output
    assert tomllib.loads(out.output)["noise"]["structure"] == "rational"
