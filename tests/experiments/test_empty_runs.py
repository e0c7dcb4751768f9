"""Issue 25, item 8: a study whose fits all failed exits non-zero (3, as `jitterid fit` for a
fit that did not converge) and its report says so first; T = 1e-300 is refused up front."""

from click.testing import CliRunner

from jitterid.cli import main

DEFINITION = """
[experiment]
name = "empty"
runs = 1
seed = 7
[sampling]
T = {T}
N = 60
noise_std = 0.01
[input]
kind = "telegraph"
[system]
structure = "pole_pair"
truth = {{ k0 = {k0}, pr = -1.5, pi = 2.0 }}
[jitter]
model = "known"
[[cases]]
name = "uniform"
law = {{ kind = "uniform", a = 0.5 }}
[estimators]
methods = ["ls"]
"""


def run(tmp_path, **kw):
    path = tmp_path / "empty.toml"
    path.write_text(DEFINITION.format(**{"T": 1.0, "k0": 6.25, **kw}))
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["run", str(path), "--out", str(out), "--no-progress"])
    return res, out


def test_a_study_with_no_converged_fit_exits_3_and_says_so_first(tmp_path):
    res, out = run(tmp_path, k0=0.0)  # a zero gain: every fit is NOT_SIGNIFICANT
    assert res.exit_code == 3, res.output
    assert "no fit converged in empty" in res.output
    report = (out / "empty.md").read_text()
    first = [ln for ln in report.splitlines() if ln.strip()][1]  # after the title
    assert first.startswith("**No fit converged: all 1 fits failed**"), report
    assert "How they ended: NOT_SIGNIFICANT 1" in report
    assert "No difference from the paper" not in report


def test_a_study_with_converged_fits_exits_0_with_no_such_lines(tmp_path):
    res, out = run(tmp_path)
    assert res.exit_code == 0, res.output
    report = (out / "empty.md").read_text()
    assert "No fit converged" not in report
    assert "no converged fit" not in report


def test_a_sampling_interval_of_1e_300_is_refused_before_any_work(tmp_path):
    res, out = run(tmp_path, T=1e-300)
    assert res.exit_code == 1
    assert "sampling.T = 1e-300 s is below the shortest sampling interval" in res.output
    assert not out.exists()
