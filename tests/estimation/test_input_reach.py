"""Issue 25, item 10: an input file with one value per sample ends before the jitter's reach
past the last sample. BCLS with a family stopped with sigma clamped where the reach meets the
input's end and said CONVERGED; the other methods failed with no cause. Every method now
names it, and the fix is a documented option (hold the last value)."""

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.cli import main
from jitterid.estimation.checks import check_data

N, T, SIGMA = 300, 1.0, 0.08


@pytest.fixture(scope="module")
def short():
    """A DAC input of N values whose file ends half an interval after the last sample."""
    rng = np.random.default_rng(3)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    vals = np.sign(rng.standard_normal(N)) * 0.5
    held = ji.zoh_input(np.r_[vals, vals[-1]], T=T)
    t = T * np.arange(N) + ji.Gaussian(SIGMA).sample(N, rng)
    y = truth.response(held)(t) + 0.01 * rng.standard_normal(N)
    u = ji.PiecewiseConstant(np.r_[T * np.arange(N), (N - 1) * T + 0.5], vals)
    return ji.SampledData(y, T, u, noise_std=0.01)


# On main's driver, a criterion that cannot be evaluated at the first start (a family start
# whose reach passes the input's end) crashes scipy's least_squares: search.py's
# least_squares_adapter gives jac a 1-row fallback where resid's has 2 F rows (the issue-25
# report gives the one-line fix); strict, so that the fix makes these pass and be unmarked.


def test_a_family_stopped_by_the_input_end_is_at_bound_with_the_cause(short):
    res = ji.fit(short, ji.PolePairGain(), ji.GaussianFamily(), method="bcls")
    assert res.status is ji.FitStatus.AT_BOUND, res.message
    assert "at the end of the input (t = 299.5)" in res.message
    assert "hold_last" in res.message
    assert res.params["sigma"] == pytest.approx(0.5 / 8.5, rel=1e-4)  # the clamp


def test_a_known_law_past_the_input_end_is_refused_naming_the_fix(short):
    for method in ("bcls", "gaussian", "ml"):
        with pytest.raises(ValueError, match=r"data.u: the input ends at t = 299.5 but the jitter"):
            ji.fit(short, ji.PolePairGain(), ji.Gaussian(SIGMA), method=method)
    with pytest.raises(ValueError, match=r"data.u: the input ends at t = 299.5 .*hold_last"):
        check_data(short, 3, True, ji.Gaussian(SIGMA))
    check_data(short, 3, True, ji.Gaussian(0.05))  # inside: accepted


def test_holding_the_last_value_is_the_fix(short):
    held = ji.SampledData(short.y, short.T, short.u.hold_last(310.0), noise_std=0.01)
    res = ji.fit(held, ji.PolePairGain(), ji.GaussianFamily(), method="bcls")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    lo, hi = res.conf_int()["sigma"]
    assert lo < SIGMA < hi
    with pytest.raises(ValueError, match="before the input's end"):
        short.u.hold_last(10.0)


def _files(short, tmp_path):
    data = ji.SampledData(short.y, short.T, None, noise_std=0.01)
    ji.save_data(tmp_path / "y.csv", data)
    ji.save_input(tmp_path / "u.csv", short.u)
    args = ["fit", str(tmp_path / "y.csv"), "--input", str(tmp_path / "u.csv")]
    return [*args, "--model", "polepair", "--jitter", "gaussian", "--no-plots", "-q"]


def test_the_cli_says_so_without_the_hold(short, tmp_path):
    res = CliRunner().invoke(main, [*_files(short, tmp_path), "--out", str(tmp_path / "a")])
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    if "jac" in res.output:  # the search's crash, turned into exit 1 by the CLI
        raise ValueError(res.output)
    assert res.exit_code == 3, res.output
    assert "at the end of the input" in res.output


def test_load_and_the_cli_hold_the_input_file_on_request(short, tmp_path):
    args = _files(short, tmp_path)
    plain = ji.load(tmp_path / "y.csv", tmp_path / "u.csv")
    assert plain.data.u.end == 299.5
    ds = ji.load(tmp_path / "y.csv", tmp_path / "u.csv", hold_input=True)
    assert ds.data.u.end > 299.5 + 8.5 * SIGMA
    assert any("hold_input" in note for note in ds.notes)
    res = CliRunner().invoke(main, [*args, "--hold-input", "--out", str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
