"""``jitterid jitter``: a sine record end to end, its files, and one-line errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.analysis.metrology import jitter_phase_profile
from jitterid.cli import INTERNAL, main
from jitterid.cli.jitter import parse_frequency

T, N, F, SIGMA, NOISE = 1e-3, 400, 123.0, 50e-6, 1e-3


def _sine(seed: int = 2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tau = SIGMA * rng.standard_normal(N)
    return np.sin(2 * np.pi * F * (np.arange(N) * T + tau)) + NOISE * rng.standard_normal(N)


def _csv(path: Path, y: np.ndarray) -> Path:
    rows = "".join(f"{k},{float(v)!r}\n" for k, v in enumerate(y))
    path.write_text("# T: 1\n# time_unit: ms\nk,y\n" + rows)
    return path


def _run(*args: str) -> tuple[int, str]:
    res = CliRunner().invoke(main, ["jitter", *args])
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    return res.exit_code, res.output


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _csv(tmp_path_factory.mktemp("rec") / "sine.csv", _sine())


def test_end_to_end_json_and_figures(record: Path, tmp_path: Path) -> None:
    code, out = _run(str(record), "--law", "gaussian", "--out", str(tmp_path), "--plot")
    assert code == 0, out
    assert "jitter std" in out
    assert "gaussian" in out
    res = json.loads((tmp_path / "jitter.json").read_text())
    assert res["status"] == "CONVERGED"
    assert abs(res["jitter_std_s"] - SIGMA) < 4 * res["jitter_std_stderr_s"]
    lo, hi = res["interval_95_s"]
    assert lo < res["jitter_std_s"] < hi
    assert abs(res["frequency_hz"] - F) < 0.05
    assert res["family"] == "gaussian"
    assert res["law"]["name"] == "Gaussian"
    assert [c["name"] for c in res["laws"]] == ["gaussian"]
    assert res["laws"][0]["chosen"]
    assert len(res["aliases"]) == 1
    assert res["N"] == N
    assert res["T_s"] == pytest.approx(T)
    for name in ("jitter_phase.png", "jitter_pdf.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_search_band_in_khz_finds_the_alias(record: Path, tmp_path: Path) -> None:
    # in 1.1-1.2 kHz the record is the alias 1/T + f = 1123 Hz: the same phase noise, so a
    # jitter std smaller by f / 1123
    code, out = _run(
        str(record), "--law", "gaussian", "--search", "1.1kHz:1.2kHz", "--out", str(tmp_path)
    )
    assert code == 0, out
    res = json.loads((tmp_path / "jitter.json").read_text())
    assert res["frequency_hz"] == pytest.approx(1 / T + F, abs=0.05)
    truth = SIGMA * F / (1 / T + F)
    assert abs(res["jitter_std_s"] - truth) < 4 * res["jitter_std_stderr_s"]


@pytest.mark.parametrize(
    ("y", "args", "words"),
    [
        (np.ones(100), (), "y is constant"),
        (_sine()[:10], (), "at least 32 samples"),
        (_sine(), ("--search", "300:400"), "no alias"),
        (np.sin(2 * np.pi * 2.0 * T * np.arange(100)), (), "periods"),
    ],
    ids=["constant", "ten-samples", "no-alias-in-band", "too-few-periods"],
)
def test_malformed_records_one_line(
    tmp_path: Path, y: np.ndarray, args: tuple[str, ...], words: str
) -> None:
    code, out = _run(str(_csv(tmp_path / "r.csv", y)), "--law", "gaussian", *args)
    assert code == 1
    assert words in out
    assert "Traceback" not in out
    assert INTERNAL not in out
    assert len(out.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--search", "300"), "LOW:HIGH"),
        (("--search", "abc:1kHz"), "not a frequency"),
        (("--search", "400:300"), "LOW must be below HIGH"),
        (("--law", "lorentz"), "'--law'"),
        (("--frequency", "-5"), "not a frequency"),
        (("--frequency", "100", "--search", "1:2"), "not both"),
        (("--plot",), "give --out"),
        (("--harmonics", "0"), "--harmonics"),
    ],
)
def test_bad_options_are_usage_errors(record: Path, args: tuple[str, ...], words: str) -> None:
    code, out = _run(str(record), *args)
    assert code == 2
    assert words in out
    assert "Traceback" not in out


def test_unreadable_file(tmp_path: Path) -> None:
    code, out = _run(str(tmp_path / "missing.csv"))
    assert code == 1
    assert "no such file" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("k,x\n0,1\n")
    code, out = _run(str(bad))
    assert code == 1
    assert "'y'" in out
    assert INTERNAL not in out


def test_parse_frequency_units() -> None:
    assert parse_frequency("123") == 123.0
    assert parse_frequency("10kHz") == 1e4
    assert parse_frequency("1.5 MHz") == 1.5e6
    with pytest.raises(ValueError, match="not a frequency"):
        parse_frequency("10 kHzz")


def test_load_accepts_a_record_without_input(record: Path) -> None:
    ds = ji.load(record, require_input=False)
    assert ds.data.u is None
    assert ds.data.N == N
    with pytest.raises(ValueError, match="no input column"):
        ji.load(record)


def test_phase_profile_matches_numpy() -> None:
    y = _sine()
    m = ji.measure_jitter(y, T, laws=["gaussian"])
    bins = 16
    prof = jitter_phase_profile(m, y, bins)
    # direct: the damped sine and the closed-form variance of a Gaussian-jittered sine
    w, A, phi, c = 2 * np.pi * m.frequency, m.amplitude, m.phase_rad, m.offset
    s2 = float(m.law.params["sigma"]) ** 2
    theta = w * T * np.arange(N) + phi
    mean = A * np.exp(-0.5 * w**2 * s2) * np.sin(theta) + c
    # Var[A sin(theta + w tau)]
    #   = A^2/2 (1 - e^{-2 w^2 s2} cos 2 theta) - (A e^{-w^2 s2/2} sin theta)^2
    var = (
        0.5 * A**2 * (1 - np.exp(-2 * w**2 * s2) * np.cos(2 * theta))
        - (A * np.exp(-0.5 * w**2 * s2) * np.sin(theta)) ** 2
    )
    r2 = (y - mean) ** 2
    k = np.floor(np.mod(theta, 2 * np.pi) / (2 * np.pi) * bins).astype(int)
    for b in range(bins):
        sel = k == b
        assert prof.count[b] == sel.sum()
        np.testing.assert_allclose(prof.resid_var[b], r2[sel].mean(), rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(
            prof.resid_var_stderr[b], r2[sel].std(ddof=1) / math.sqrt(sel.sum()), rtol=1e-6
        )
        np.testing.assert_allclose(
            prof.model_var[b], var[sel].mean() + m.noise_std**2, rtol=1e-5, atol=1e-12
        )
    assert prof.noise_var == pytest.approx(m.noise_std**2)
    np.testing.assert_allclose(prof.edges, np.linspace(0, 2 * np.pi, bins + 1))
    with pytest.raises(ValueError, match="bins"):
        jitter_phase_profile(m, y, 0)


def test_plots_from_a_measurement() -> None:
    import matplotlib.pyplot as plt

    from jitterid import plots

    y = _sine()
    m = ji.measure_jitter(y, T, laws=["gaussian"])
    try:
        ph = plots.plot_jitter_phase(m, y, bins=8)
        assert {"measured", "model", "noise"} <= set(ph)
        pdf = plots.plot_jitter_pdf(m, rng=1)
        assert "band" in pdf
        assert "µs" in pdf.axes[0].get_xlabel()
        # the density is per µs: it integrates to 1 over the µs axis
        x, p = pdf["pdf"].get_xdata(), pdf["pdf"].get_ydata()
        assert np.trapezoid(p, x) == pytest.approx(1.0, abs=1e-3)
    finally:
        plt.close("all")


def test_ranked_out_laws_in_the_report_and_json(tmp_path: Path) -> None:
    """ML with the default three laws on a Gaussian record (issue 26's tone at 2^12): the
    uniform and the dual Dirac are ranked out before their full fits; the summary (the
    CLI's report) and jitter.json say so with their ln L upper estimates and the BIC
    margin (a lower bound), not only through a MAX_EVALUATIONS status."""
    from jitterid.metrology.sinelik import RANK_MARGIN_BIC

    Ts, n = 1 / 7e9, 1 << 12
    cyc = round(1e9 * n * Ts)
    cyc += 1 - cyc % 2
    rng = np.random.default_rng(1)
    tau = 100e-15 * rng.standard_normal(n)
    y = 0.49 * np.sin(2 * np.pi * cyc / (n * Ts) * (np.arange(n) * Ts + tau) + 0.4)
    y = y + 50e-6 * rng.standard_normal(n)
    rows = "".join(f"{k},{float(v)!r}\n" for k, v in enumerate(y))
    rec = tmp_path / "sine.csv"
    rec.write_text(f"# T: {Ts * 1e9!r}\n# time_unit: ns\nk,y\n" + rows)
    code, out = _run(str(rec), "--out", str(tmp_path))
    assert code == 0, out
    res = json.loads((tmp_path / "jitter.json").read_text())
    assert res["family"] == "gaussian"
    by = {c["name"]: c for c in res["laws"]}
    assert not by["gaussian"]["ranked_out"]
    assert by["gaussian"]["delta_bic"] == 0.0
    for name in ("uniform", "dual-dirac"):
        c = by[name]
        assert c["ranked_out"], c
        assert c["status"] == "MAX_EVALUATIONS"
        assert c["delta_bic"] >= RANK_MARGIN_BIC
        assert "ranked out" in c["state"]
        assert f"ln L <= {c['loglik']:.3f} (upper estimate)" in c["state"]
        assert f"BIC >= chosen + {c['delta_bic']:.2f}" in c["state"]
        # the report (the summary the CLI prints) carries the same line
        assert c["state"] in out
