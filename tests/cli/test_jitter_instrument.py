"""``jitterid jitter`` as a test engineer drives it: method, resolution, converter figures,
Nyquist zones, the law's evidence, records without input, and batches (issue 26)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid.cli import INTERNAL, main
from jitterid.metrology import reading

T, N, F, SIGMA = 1e-3, 400, 123.0, 50e-6


def _sine(seed: int = 2, harmonic3: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ph = 2 * np.pi * F * (np.arange(N) * T + SIGMA * rng.standard_normal(N)) + 0.3
    return np.sin(ph) + harmonic3 * np.sin(3 * ph) + 1e-3 * rng.standard_normal(N)


def _csv(path: Path, y: np.ndarray, header: str = "# T: 1\n# time_unit: ms\ny\n") -> Path:
    path.write_text(header + "".join(f"{float(v)!r}\n" for v in y))
    return path


def _run(*args: str) -> tuple[int, str]:
    res = CliRunner().invoke(main, ["jitter", *args])
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    return res.exit_code, res.output


FAST = ("--method", "gaussian", "--law", "gaussian", "--no-progress")


def test_a_y_only_record_with_method_and_bits(tmp_path: Path) -> None:
    rec = _csv(tmp_path / "sine.csv", _sine())  # a 'y' column only, T in the metadata
    out = tmp_path / "out"
    code, text = _run(str(rec), *FAST, "--bits", "12", "--full-scale", "2.5", "--out", str(out))
    assert code in (0, 3), text
    assert INTERNAL not in text
    res = json.loads((out / "jitter.json").read_text())
    assert abs(res["jitter_std_s"] - SIGMA) < 5 * res["jitter_std_stderr_s"]
    conv = res["converter"]
    assert conv["full_scale"] == 2.5
    # ENOB from the full scale (IEEE 1241) against the SINAD route: log2(FSR / (sqrt 12 NAD))
    enob = math.log2(2.5 / (math.sqrt(12) * conv["nad_rms"]))
    assert conv["enob_bits"] == pytest.approx(enob, rel=1e-12)
    lim = -20 * math.log10(2 * math.pi * res["frequency_hz"] * res["jitter_std_s"])
    assert conv["jitter_limited_snr_db"] == pytest.approx(lim, rel=1e-12)
    for words in ("SNR", "SINAD", "ENOB", "THD", "SFDR", "noise floor", "jitter-limited SNR"):
        assert words in text
    # the frequency was not given: the zones are said, each with its jitter
    assert "cannot tell the zone" in text
    zones = res["nyquist_zones"]
    assert [z["zone"] for z in zones] == [1, 2, 3, 4]
    assert zones[0]["measured"]
    for z in zones:
        assert z["frequency_hz"] * z["jitter_std_s"] == pytest.approx(
            res["frequency_hz"] * res["jitter_std_s"], rel=1e-12
        )
    assert zones[2]["frequency_hz"] == pytest.approx(1 / T + F, abs=0.05)


def test_bits_set_the_resolution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, object] = {}
    real = ji.metrology.meter.measure_jitter

    def spy(*args: object, **kwargs: object) -> object:
        seen.update(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(ji.metrology.meter, "measure_jitter", spy)
    rec = _csv(tmp_path / "sine.csv", _sine())
    _run(str(rec), *FAST, "--bits", "10", "--full-scale", "2")
    assert seen["resolution"] == pytest.approx(2 / 2**10 / math.sqrt(12))
    assert seen["method"] == "gaussian"
    _run(str(rec), *FAST, "--resolution", "1e-4")
    assert seen["resolution"] == 1e-4


def test_a_given_frequency_says_no_zones(tmp_path: Path) -> None:
    rec = _csv(tmp_path / "sine.csv", _sine())
    code, text = _run(str(rec), *FAST, "--frequency", "123", "--out", str(tmp_path / "o"))
    assert code in (0, 3), text
    assert "cannot tell the zone" not in text
    assert "nyquist_zones" not in json.loads((tmp_path / "o" / "jitter.json").read_text())


def test_harmonics_auto_fits_the_distortion(tmp_path: Path) -> None:
    rec = _csv(tmp_path / "sine.csv", _sine(harmonic3=3e-3))
    code, text = _run(str(rec), *FAST, "--out", str(tmp_path / "auto"))
    res = json.loads((tmp_path / "auto" / "jitter.json").read_text())
    assert res["harmonics"] == 3
    code, text = _run(str(rec), *FAST, "--harmonics", "1", "--out", str(tmp_path / "one"))
    assert code in (0, 3), text
    one = json.loads((tmp_path / "one" / "jitter.json").read_text())
    assert one["harmonics"] == 1
    # fitted as a pure sine, the distortion is counted as jitter/noise, and the figures say so
    assert any("HD3 stands above the noise" in n for n in one["converter"]["notes"])
    assert "--harmonics 3" in text


@pytest.mark.parametrize("verdict", ["undetermined", "chosen"])
def test_no_pdf_plot_for_an_undetermined_law(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, verdict: str
) -> None:
    fake = reading.LawEvidence(verdict, 2.2, "uniform", 6.0, f"law {verdict} (test)")
    monkeypatch.setattr(reading, "law_evidence", lambda m, margin=6.0: fake)
    rec = _csv(tmp_path / "sine.csv", _sine())
    out = tmp_path / verdict
    code, text = _run(str(rec), *FAST, "--out", str(out), "--plot")
    assert code in (0, 3), text
    assert (out / "jitter_phase.png").exists()
    assert (out / "jitter_pdf.png").exists() == (verdict == "chosen")
    assert ("jitter_pdf.png not drawn" in text) == (verdict == "undetermined")


def test_no_pdf_plot_for_a_law_free_measurement(tmp_path: Path) -> None:
    """The law-free moment route (``--method gaussian`` with the default laws) measures the
    std and the kurtosis; its law is a Gaussian of that std whatever the kurtosis, so no
    density is drawn (before session 26 a Gaussian was drawn, labelled "fitted law-free
    law", on a record of any shape)."""
    rec = _csv(tmp_path / "sine.csv", _sine())
    out = tmp_path / "free"
    code, text = _run(
        str(rec), "--method", "gaussian", "--no-progress", "--out", str(out), "--plot"
    )
    assert code in (0, 3), text
    res = json.loads((out / "jitter.json").read_text())
    assert res["family"] == "law-free", res["family"]
    assert (out / "jitter_phase.png").exists()
    assert not (out / "jitter_pdf.png").exists()
    assert "jitter_pdf.png not drawn: the law-free route" in text


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--bits", "12"), "--bits needs --full-scale"),
        (("--bits", "12", "--full-scale", "2", "--resolution", "1e-3"), "not both"),
        (("--harmonics", "many"), "neither 'auto'"),
        (("--method", "fast"), "'--method'"),
        (("--resume",), "for a batch"),
        (("--workers", "2"), "for a batch"),
    ],
)
def test_bad_options_are_usage_errors(tmp_path: Path, args: tuple[str, ...], words: str) -> None:
    rec = _csv(tmp_path / "sine.csv", _sine())
    code, text = _run(str(rec), *args)
    assert code == 2
    assert words in text


def test_a_y_only_file_without_t_says_how(tmp_path: Path) -> None:
    rec = _csv(tmp_path / "sine.csv", _sine(), header="y\n")
    code, text = _run(str(rec), *FAST)
    assert code == 1
    assert "--T" in text
    code, text = _run(str(rec), *FAST, "--T", "1ms")
    assert code in (0, 3)
    assert "jitter std" in text


def test_a_batch_folder_through_the_cli(tmp_path: Path) -> None:
    d = tmp_path / "records"
    d.mkdir()
    for i in range(3):
        _csv(d / f"r{i}.csv", _sine(i))
    (d / "zz_bad.csv").write_text("# T: 1\ny\n1\n2\n")
    out = tmp_path / "out"
    args = (str(d), *FAST, "--harmonics", "1", "--workers", "1", "--out", str(out))
    code, text = _run(*args)
    assert code == 3  # one record is not CONVERGED
    assert "4 records" in text
    assert "zz_bad.csv: ERROR" in text
    rows = (out / "jitter_batch.csv").read_text().splitlines()
    assert len(rows) == 5
    assert rows[-1].startswith("zz_bad.csv,")
    # again without --resume: refused; with it: nothing to do, the same table
    code, text = _run(*args)
    assert code == 1
    assert "--resume" in text
    before = (out / "jitter_batch.csv").read_text()
    code, text = _run(*args, "--resume")
    assert "4 already done, 0 measured" in text
    assert (out / "jitter_batch.csv").read_text() == before


def test_a_batch_needs_out(tmp_path: Path) -> None:
    code, text = _run(str(tmp_path), *FAST)
    assert code == 2
    assert "--out" in text


def test_a_long_fit_says_it_is_running(capsys: pytest.CaptureFixture[str]) -> None:
    import time

    from jitterid.cli.jitter import _heartbeat

    seen = ""
    with _heartbeat("measuring", True, after_s=0.0):
        for _ in range(6000):  # until the timer's first line (at most a minute)
            seen += capsys.readouterr().err
            if "measuring:" in seen:
                break
            time.sleep(0.01)
    assert "measuring: 0 s elapsed" in seen
    with _heartbeat("measuring", False, after_s=0.0):
        pass
    assert capsys.readouterr().err == ""
