"""Experiment definitions (jitterid.experiments.loader and config): the packaged definitions
with the paper's settings, bad definitions failing before any work and naming the key, and the
fingerprint."""

import copy
import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner
from helpers import TINY_EXPERIMENT, tiny_experiment

from jitterid.cli import main
from jitterid.estimation.estimators import BCLS, register
from jitterid.experiments import (
    PAPER_EXPERIMENTS,
    ExperimentError,
    load_experiment,
    packaged_path,
    parse_experiment,
)
from jitterid.experiments.report import (
    paper_numbers,
    true_values,
)


def edited(path, value):
    """TINY_EXPERIMENT with the dotted key ``path`` set to ``value`` (None deletes it)."""
    data = copy.deepcopy(TINY_EXPERIMENT)
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


def test_an_estimator_registered_after_import_is_accepted_at_load_time(estimator_registry):
    """The methods are checked against the library's registered estimators when the file is
    read: a name unknown until its estimator is registered is refused, then accepted."""
    data = edited("estimators.methods", ["bcls", "test-loader-bcls"])
    with pytest.raises(ExperimentError, match=r"methods\[1\]"):
        parse_experiment(copy.deepcopy(data), "tiny.toml")

    @register
    @dataclasses.dataclass(frozen=True)
    class LoaderBCLS(BCLS):
        name = "test-loader-bcls"

    assert parse_experiment(data, "tiny.toml").methods == ("bcls", "test-loader-bcls")


def test_run_with_a_bad_file_fails_before_any_work(tmp_path):
    text = packaged_path("table2").read_text().replace("noise_std = 0.01", "noise_std = 'x'")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    res = CliRunner().invoke(main, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert "bad.toml: sampling.noise_std must be a finite number" in res.output
    assert not (tmp_path / "o").exists()


def test_fingerprint_ignores_runs_and_titles_but_not_the_seed():
    base = tiny_experiment()
    assert dataclasses.replace(base, runs=99, title="x").fingerprint() == base.fingerprint()
    assert dataclasses.replace(base, seed=12).fingerprint() != base.fingerprint()
