"""Issue 25, item 4: a fit whose gain is fixed at 0 (and so explains nothing) said
CONVERGED with NaN standard errors; it is NOT_SIGNIFICANT, and a covariance asked for that
is NaN throughout is never next to CONVERGED."""

import numpy as np
import pytest
from click.testing import CliRunner
from helpers import table2_post_context

import jitterid as ji
from jitterid.cli import main
from jitterid.estimation.checks import post_checks
from jitterid.estimation.result import FitStatus


@pytest.fixture(scope="module")
def lab():
    rng = np.random.default_rng(1)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    u = ji.telegraph_input(202.0, rng)
    return ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=200, noise_std=0.01, rng=rng)


@pytest.mark.parametrize("method", ["ls", "bcls"])
@pytest.mark.parametrize("noise_known", [False, True])
def test_a_gain_fixed_at_zero_is_not_significant(lab, method, noise_known):
    data = lab if noise_known else ji.SampledData(lab.y, lab.T, lab.u)
    structure = ji.Constrained(ji.PolePairGain(), fixed={"k0": 0.0})
    res = ji.fit(data, structure, ji.Uniform(0.5), method=method)
    assert res.status is FitStatus.NOT_SIGNIFICANT, (res.status, res.message)
    assert "k0 is fixed at 0" in res.message
    assert not res.success


def test_a_gain_fixed_at_its_true_value_still_converges(lab):
    structure = ji.Constrained(ji.PolePairGain(), fixed={"k0": 6.25})
    res = ji.fit(lab, structure, ji.Uniform(0.5), method="bcls")
    assert res.status is FitStatus.CONVERGED, res.message
    assert all(np.isfinite(v) for v in res.stderr.values())


def test_the_cli_exits_3_with_a_gain_fixed_at_zero(tmp_path):
    res = CliRunner().invoke(main, ["simulate", "--out", str(tmp_path / "lab"), "--N", "80"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(
        main,
        [
            "fit",
            str(tmp_path / "lab" / "data.csv"),
            "--input",
            str(tmp_path / "lab" / "input.csv"),
            "--model",
            "polepair",
            "--fix",
            "k0=0",
            "--jitter",
            "known:uniform:a=0.5",
            "--method",
            "bcls",
            "--out",
            str(tmp_path / "fit"),
            "--no-plots",
        ],
    )
    assert res.exit_code == 3, res.output
    assert "explains no significant part" in res.output


_context = table2_post_context


def test_a_requested_covariance_that_is_nan_throughout_is_unidentifiable(lab):
    nan = np.full((3, 3), np.nan)
    status, message = post_checks(_context(lab, nan, cov_requested=True), FitStatus.CONVERGED, "ok")
    assert status is FitStatus.UNIDENTIFIABLE
    assert "singular" in message
    # cov_type="none": not computed on purpose, the fit stands
    status, _ = post_checks(_context(lab, nan, cov_requested=False), FitStatus.CONVERGED, "ok")
    assert status is FitStatus.CONVERGED
