"""``jitterid fit`` cross-checks the jitter std against the detection test
(jitterid.analysis.diagnostics.cross_check_jitter).

End to end on generated data: a fitted jitter scale ~0 while ``detect_jitter`` finds jitter
(even where the fit's own status is CONVERGED), an assumed law far wider than anything the
data show, and no warning on ordinary fits.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner, Result

import jitterid as ji
from jitterid.analysis.diagnostics import cross_check_jitter
from jitterid.cli import main
from jitterid.io import save_data

G = ji.TransferFunction([6.25], [1.0, 3.0, 6.25])  # the paper's (27) at the truth


def _paper(seed: int, law: ji.JitterLaw, n: int = 200) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n + 5.0, rng)
    return ji.simulate(G, u, law, 1.0, n, 0.01, rng)


def _fit(tmp_path, data: ji.SampledData, *args: str) -> tuple[Result, dict, str]:
    save_data(tmp_path / "d.csv", data)
    ji.save_input(tmp_path / "u.csv", data.u)
    out = tmp_path / "out"
    res = CliRunner().invoke(
        main,
        [
            "fit",
            str(tmp_path / "d.csv"),
            "--input",
            str(tmp_path / "u.csv"),
            "--out",
            str(out),
            "--no-plots",
            "--quiet",
            *args,
        ],
    )
    assert "Traceback" not in res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    return res, json.loads((out / "result.json").read_text()), (out / "report.md").read_text()


def test_a_collapsed_scale_that_the_fit_calls_converged_is_flagged(tmp_path):
    # Gaussian jitter 0.02 s (T = 1): bcls with the Gaussian family ends at sigma = 3e-9 with
    # status CONVERGED (detection p = 2.3e-6 is above the fit's own 1e-6 threshold); before,
    # nothing in the output said that the data show jitter of ~0.02 s.
    data = _paper(0, ji.Gaussian(0.02))
    res, result, report = _fit(tmp_path, data, "--model", "polepair", "--jitter", "gaussian")
    assert result["status"].startswith("converged")
    assert res.exit_code == 0, res.output
    xc = result["diagnostics"]["jitter_cross_check"]
    assert xc["verdict"] == "too small"
    assert not xc["consistent"]
    assert xc["jitter_std_s"] < 1e-3
    assert len(result["warnings"]) == 1
    assert "--method gaussian, ml or asml" in result["warnings"][0]
    assert "warning: jitter cross-check" in res.output
    assert "~0" in res.output
    assert "**Warning" in report
    assert "contradicts" in report
    # the advice works: the gaussian criterion finds the jitter (0.0185), and the
    # cross-check agrees
    res2, result2, report2 = _fit(
        tmp_path, data, "--model", "polepair", "--jitter", "gaussian", "--method", "gaussian"
    )
    assert res2.exit_code == 0, res2.output
    assert result2["diagnostics"]["jitter_cross_check"]["consistent"]
    assert result2["warnings"] == []
    assert 0.01 < result2["jitter"]["std"] < 0.03
    assert "Warning" not in report2


def test_a_collapsed_scale_at_bound_also_says_what_the_test_found(tmp_path):
    # the lab setting (issue 15): AT_BOUND from the fit, and the cross-check agrees
    g = ji.TransferFunction([4.0, 8.0], np.polymul([1.0, 4.0], [1.0, 2.0, 2.0]))
    rng = np.random.default_rng(5004)
    u = ji.zoh_input(rng.choice([-1.0, 1.0], 320), 0.5)
    data = ji.simulate(g, u, ji.Gaussian(0.08), 0.5, 300, 0.02, rng)
    res, result, _ = _fit(tmp_path, data, "--model", "tf:1,3", "--jitter", "gaussian")
    assert res.exit_code == 3
    assert result["diagnostics"]["jitter_cross_check"]["verdict"] == "too small"
    assert result["warnings"]


def test_an_assumed_law_far_wider_than_the_data_show_is_flagged(tmp_path):
    # no jitter in the data, the user assumes U(-0.5, 0.5) (e.g. a unit slip): before, the
    # fit was written with no word that the detection test finds no jitter at all
    data = _paper(2, ji.NoJitter())  # detection p = 0.71
    res, result, report = _fit(
        tmp_path, data, "--model", "polepair", "--jitter", "known:uniform:a=0.5"
    )
    xc = result["diagnostics"]["jitter_cross_check"]
    assert xc["verdict"] == "too large", xc
    assert not xc["jitter_estimated"]
    assert "time unit" in result["warnings"][0]
    assert "finds no jitter" in res.output
    assert "**Warning" in report


@pytest.mark.parametrize(
    ("law", "spec", "method"),
    [
        (ji.Uniform(0.5), "uniform", "bcls"),
        (ji.Uniform(0.5), "known:uniform:a=0.5", "bcls"),
        (ji.Uniform(0.05), "gaussian", "asml-diag"),
        (ji.NoJitter(), "gaussian", "bcls"),
        (ji.NoJitter(), "none", "bcls"),
    ],
)
def test_no_warning_on_ordinary_fits(tmp_path, law, spec, method):
    res, result, report = _fit(
        tmp_path, _paper(3, law), "--model", "polepair", "--jitter", spec, "--method", method
    )
    assert res.exit_code == 0, res.output
    assert result["diagnostics"]["jitter_cross_check"]["consistent"], result["warnings"]
    assert result["warnings"] == []
    assert "Cross-check: the" in report


def test_an_ls_fit_is_cross_checked_too(tmp_path):
    # issue 25: ls ignores the jitter (it assumes none): the detection contradicts it here
    res, result, _ = _fit(
        tmp_path,
        _paper(3, ji.Uniform(0.5)),
        "--model",
        "polepair",
        "--jitter",
        "none",
        "--method",
        "ls",
    )
    assert res.exit_code == 0, res.output
    assert result["diagnostics"]["jitter_cross_check"]["verdict"] == "too small"
    assert any("method 'ls' ignores the jitter" in w for w in result["warnings"])


def test_the_cross_check_on_its_own():
    # library level: the paper setting over 12 seeds; known and well-estimated laws agree,
    # every collapsed bcls scale with detected jitter is flagged
    flagged = agreed = 0
    for seed in range(6):
        d = _paper(seed, ji.Gaussian(0.02))
        det = ji.detect_jitter(d, ji.fit(d, ji.PolePairGain(), ji.NoJitter(), "ls"))
        for fam, method in (
            (ji.GaussianFamily(), "bcls"),
            (ji.GaussianFamily(), "asml-diag"),
            (ji.Gaussian(0.02), "bcls"),
        ):
            r = ji.fit(d, ji.PolePairGain(), fam, method)
            xc = cross_check_jitter(r, det)
            collapsed = r.jitter_std < 1e-3
            assert xc.consistent is not collapsed, (seed, method, r.jitter_std, xc.message)
            flagged += collapsed
            agreed += not collapsed
    assert flagged >= 1
    assert agreed >= 12
    with pytest.raises(TypeError, match="detection"):
        cross_check_jitter(r, "p = 0.01")  # type: ignore[arg-type]
