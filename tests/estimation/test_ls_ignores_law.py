"""Issue 25, item 10: method="ls" with a known law replaced it by NoJitter() without a word,
and the CLI did not cross-check ls against the jitter detection. The result's summary now
says that ls ignored the law, and the cross-check runs for ls too."""

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.analysis.diagnostics import cross_check_jitter
from jitterid.cli import main


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(1)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    u = ji.telegraph_input(402.0, rng)
    return ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=400, noise_std=0.01, rng=rng)


def test_the_summary_says_ls_ignored_the_law(data):
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="ls")
    assert "method 'ls' ignores the jitter law given, Uniform(a=0.5)" in res.ignored_jitter
    assert "note: method 'ls' ignores the jitter law given" in res.summary()
    plain = ji.fit(data, ji.PolePairGain(), ji.NoJitter(), method="ls")
    assert plain.ignored_jitter == ""
    assert "note:" not in plain.summary()
    bcls = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="bcls")
    assert bcls.ignored_jitter == ""


def test_the_cross_check_covers_ls(data):
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="ls")
    det = ji.detect_jitter(data, res)
    assert det.pvalue < 1e-3
    xc = cross_check_jitter(res, det)
    assert xc.verdict == "too small"
    assert "method 'ls' ignores the jitter" in xc.message


def test_the_cli_cross_checks_ls(data, tmp_path):
    ji.save_data(tmp_path / "y.csv", data)
    ji.save_input(tmp_path / "u.csv", data.u)
    res = CliRunner().invoke(
        main,
        [
            "fit",
            str(tmp_path / "y.csv"),
            "--input",
            str(tmp_path / "u.csv"),
            "--model",
            "polepair",
            "--jitter",
            "known:uniform:a=0.5",
            "--method",
            "ls",
            "--out",
            str(tmp_path / "o"),
            "--no-plots",
            "-q",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "method 'ls' ignores the jitter" in res.output
