"""The data commands: simulate -> fit round trips, detect, bias, and clean errors for bad input."""

from __future__ import annotations

import hashlib
import json
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jitterid as ji
from jitterid.cli import main
from jitterid.cli._specs import parse_jitter, parse_model
from jitterid.estimation.estimators import method_names


def run(*args: str | Path) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


def ok(*args: str | Path) -> Result:
    res = run(*args)
    assert res.exit_code == 0, res.output
    return res


def assert_clean_failure(res: Result, out_dir: Path | None = None) -> None:
    """A non-zero exit with an error message, no traceback, and no result written."""
    assert res.exit_code != 0
    assert isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in res.output
    assert "Error" in res.output
    if out_dir is not None:
        assert not (out_dir / "result.json").exists()


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("lab")
    ok("simulate", "--out", d, "--seed", "3")
    return d


def _within(result: dict, truth: dict[str, float], k: float = 3.0) -> None:
    for name, value in truth.items():
        est, se = result["parameters"][name], result["stderr"][name]
        assert se > 0
        assert abs(est - value) <= k * se, (name, est, value, se)


# ------------------------------------------------------------------------------ round trips


def test_simulate_then_fit_recovers_the_truth(lab, tmp_path):
    out = tmp_path / "fit"
    res = ok(
        "fit",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--model",
        "polepair",
        "--jitter",
        "known:uniform:a=0.5",
        "--method",
        "bcls",
        "--out",
        out,
    )
    truth = json.loads((lab / "truth.json").read_text())
    result = json.loads((out / "result.json").read_text())
    _within(result, truth["params"])
    assert "k0" in res.output
    assert "jitter detection" in res.output
    # Provenance: checksum of the file actually read, library version, method, covariance.
    sha = hashlib.sha256((lab / "data.csv").read_bytes()).hexdigest()
    assert result["data"]["sha256"] == sha
    assert result["jitterid_version"] == ji.__version__
    assert result["method"] == "bcls"
    assert result["success"] is True
    cov = np.array(result["covariance"]["matrix"])
    assert result["covariance"]["names"] == ["k0", "pr", "pi"]
    np.testing.assert_allclose(cov, cov.T)
    np.testing.assert_allclose(
        np.sqrt(np.diag(cov)), [result["stderr"][n] for n in ("k0", "pr", "pi")]
    )
    assert result["jitter"] == {
        "spec": "known:uniform:a=0.5",
        "estimated": False,
        "law": "Uniform",
        "params": {"a": 0.5},
        "std": pytest.approx(0.5 / np.sqrt(3)),
        "std_stderr": 0.0,
    }
    # The report links figures that exist.
    report = (out / "report.md").read_text()
    for png in re.findall(r"\]\(([^)]+\.png)\)", report):
        assert (out / png).stat().st_size > 1000
    assert {"bode.png", "jitter_pdf.png", "residuals.png"} <= {p.name for p in out.iterdir()}


def test_rational_model_and_estimated_jitter_round_trip(tmp_path):
    """tf:0,2 with the same system as the paper's, saved as npz with a DAC (zoh) input."""
    lab = tmp_path / "lab"
    ok(
        "simulate",
        "--out",
        lab,
        "--model",
        "tf:0,2",
        "--params",
        "6.25,3,6.25",
        "--input-kind",
        "zoh",
        "--format",
        "npz",
        "--seed",
        "5",
    )
    out = tmp_path / "fit"
    ok(
        "fit",
        lab / "data.npz",
        "--input",
        lab / "input.npz",
        "--model",
        "tf:0,2",
        "--jitter",
        "uniform",
        "--method",
        "gaussian",
        "--out",
        out,
        "--no-plots",
    )
    result = json.loads((out / "result.json").read_text())
    assert result["model"]["param_names"] == ["b0", "a1", "a0"]
    _within(result, {"b0": 6.25, "a1": 3.0, "a0": 6.25, "a": 0.5})
    assert result["jitter"]["estimated"] is True
    assert not list(out.glob("*.png"))
    assert (out / "report.md").exists()


def test_simulate_is_reproducible(tmp_path):
    for d, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        ok("simulate", "--out", tmp_path / d, "--seed", seed, "--N", "20")
    a, b, c = ((tmp_path / d / "data.csv").read_bytes() for d in "abc")
    assert a == b
    assert a != c
    ds = ji.load(tmp_path / "a" / "data.csv", tmp_path / "a" / "input.csv")
    assert ds.data.N == 20


def test_detect_agrees_with_the_library(lab):
    res = ok("detect", lab / "data.csv", "--input", lab / "input.csv", "--model", "polepair")
    ds = ji.load(lab / "data.csv", lab / "input.csv")
    ls = ji.fit(ds.data, ji.PolePairGain(), ji.NoJitter(), "ls")
    det = ji.detect_jitter(ds.data, ls)
    assert f"t = {det.statistic:.3f}" in res.output
    assert f"implied jitter std {det.jitter_std:.4g} s" in res.output
    assert "jitter detected" in res.output


def test_detect_writes_a_plot(lab, tmp_path):
    ok(
        "detect",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--model",
        "polepair",
        "--plot",
        tmp_path / "r.png",
    )
    assert (tmp_path / "r.png").read_bytes()[:4] == b"\x89PNG"


def test_bias_table_is_the_characteristic_function():
    res = ok("bias", "--jitter", "uniform:a=0.5", "--points", "6")
    rows = re.findall(
        r"^\s+([\d.e+-]+)\s+([\d.]+)\s+([\d.]+)\s+(-?[\d.]+)%", res.output, re.MULTILINE
    )
    assert len(rows) == 6
    f = np.array([float(r[0]) for r in rows])
    phi = np.array([float(r[2]) for r in rows])
    np.testing.assert_allclose(f, np.linspace(0, 0.5, 6))
    np.testing.assert_allclose(phi, np.abs(np.sinc(2 * 0.5 * f)), atol=1e-4)
    fb = float(re.search(r"reaches 1% at f = ([\d.]+) Hz", res.output).group(1))
    assert np.sinc(2 * 0.5 * fb) == pytest.approx(0.99, abs=1e-4)
    assert "never" in ok("bias", "--jitter", "none").output


# ------------------------------------------------------------------------------ specs


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("none", ji.NoJitter()),
        ("known:uniform:a=0.5", ji.Uniform(0.5)),
        ("known:gaussian:sigma=0.1", ji.Gaussian(0.1)),
        ("known:sum-of-uniforms:n=2,a=0.5", ji.SumOfUniforms(2, 0.5)),
        ("uniform", ji.UniformFamily()),
        ("gaussian", ji.GaussianFamily()),
        ("sum-of-uniforms", ji.SumOfUniformsFamily()),
        ("uniform:a_max=0.5", ji.UniformFamily(a_max=0.5)),
        ("sum-of-uniforms:n_max=10,a_max=0.5", ji.SumOfUniformsFamily(n_max=10, a_max=0.5)),
    ],
)
def test_jitter_specs(spec, expected):
    got = parse_jitter(spec)
    assert type(got) is type(expected)
    assert got == expected


def test_model_specs():
    assert parse_model("polepair") == ji.PolePairGain()
    assert parse_model("tf:0,2") == ji.RationalModel(0, 2)
    assert parse_model("tf:1,3").param_names == ("b1", "b0", "a2", "a1", "a0")


# ------------------------------------------------------------------------------ errors


def test_specific_usage_errors(lab, tmp_path):
    base = ["fit", lab / "data.csv", "--input", lab / "input.csv", "--out", tmp_path / "o"]
    cases = [
        (["--model", "tf:3,2", "--jitter", "none"], r"NUM <= DEN"),
        (
            ["--model", "polepair", "--jitter", "uniform:a=0.5"],
            r"to fix the law write known:uniform:a=0.5",
        ),
        (["--model", "polepair", "--jitter", "known:uniform"], r"needs a=VALUE"),
        (
            ["--model", "polepair", "--jitter", "uniform", "--method", "ls"],
            r"cannot estimate a jitter family",
        ),
        (
            ["--model", "polepair", "--jitter", "none", "--noise-std", "-1"],
            r"must be finite and >= 0",
        ),
        (
            ["--model", "polepair", "--jitter", "none", "--method", "magic"],
            r"'magic' is not one of",
        ),
    ]
    for extra, pattern in cases:
        res = run(*base, *extra)
        assert_clean_failure(res, tmp_path / "o")
        assert re.search(pattern, res.output), res.output
    res = run(
        "fit",
        tmp_path / "missing.csv",
        "--model",
        "polepair",
        "--jitter",
        "none",
        "--out",
        tmp_path / "o",
    )
    assert_clean_failure(res, tmp_path / "o")
    assert "no such file" in res.output
    res = run("simulate", "--out", tmp_path / "s", "--params", "1,2")
    assert_clean_failure(res)
    assert "params must have 3 values" in res.output
    res = run("simulate", "--out", tmp_path / "s", "--params", "6.25,1.5,2")
    assert_clean_failure(res)
    assert "outside its bounds" in res.output


_VALID_MODELS = {"polepair"} | {f"tf:{m},{n}" for n in range(1, 9) for m in range(n + 1)}


def _is_valid_jitter(spec: str) -> bool:
    try:
        parse_jitter(spec)
    except (ValueError, TypeError):
        return False
    return True


_words = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=0, max_size=25
)
_spec_like = st.builds(
    lambda a, b, c: f"{a}:{b}={c}",
    st.sampled_from(
        [
            "known:uniform",
            "known:gaussian",
            "uniform",
            "sum-of-uniforms",
            "known:sum-of-uniforms",
            "tf",
        ]
    ),
    st.sampled_from(["a", "sigma", "n", "a_max", "b", ""]),
    st.sampled_from(["-1", "0", "nan", "inf", "x", "1e400", ""]),
)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    model=st.one_of(
        _words, st.sampled_from(["tf:", "tf:1", "tf:-1,2", "tf:a,b", "tf:2,1", "tf:0,0", "TF:0;2"])
    ),
    jitter=st.one_of(_words, _spec_like),
    which=st.sampled_from(["model", "jitter", "method", "noise", "T", "level"]),
    number=st.sampled_from(["-1", "nan", "inf", "abc", "", "0"]),
)
def test_malformed_arguments_fail_cleanly(lab, model, jitter, which, number):
    args = {"--model": "polepair", "--jitter": "none", "--method": "ls"}
    extra: list[str] = []
    if which == "model":
        if model.strip().lower() in _VALID_MODELS:
            return
        args["--model"] = model
    elif which == "jitter":
        if _is_valid_jitter(jitter):
            return
        args["--jitter"] = jitter
    elif which == "method":
        if model in method_names():
            return
        args["--method"] = model
    elif which == "noise":
        extra = ["--noise-std", number if number != "0" else "-0.5"]
    elif which == "T":
        extra = ["--T", number]
    else:
        extra = ["--level", number]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        flat = [x for kv in args.items() for x in kv]
        res = run(
            "fit", lab / "data.csv", "--input", lab / "input.csv", *flat, *extra, "--out", out
        )
        assert_clean_failure(res, out)


def _bad_file(kind: str, i: int) -> str:
    rows = [f"{k}.0,{np.sin(k)!r}" for k in range(12)]
    if kind == "missing":
        rows[i] = f"{i}.0,"
    elif kind == "text":
        rows[i] = f"{i}.0,abc"
    elif kind == "duplicate":
        rows.insert(i, rows[i])
    elif kind == "unsorted":
        rows[i], rows[i + 1] = rows[i + 1], rows[i]
    elif kind == "gap":
        del rows[i]
    elif kind == "ragged":
        rows[i] += ",1"
    header = "t,y" if kind != "header" else "time,output"
    return "\n".join(["# T: 1.0", header, *rows]) + "\n"


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    kind=st.sampled_from(["missing", "text", "duplicate", "unsorted", "gap", "ragged", "header"]),
    i=st.integers(min_value=1, max_value=9),
    command=st.sampled_from(["fit", "detect"]),
)
def test_malformed_files_fail_cleanly(lab, kind, i, command):
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data.csv"
        data.write_text(_bad_file(kind, i))
        out = Path(tmp) / "out"
        args = ["--input", lab / "input.csv", "--model", "polepair"]
        if command == "fit":
            args += ["--jitter", "none", "--method", "ls", "--out", out]
        res = run(command, data, *args)
        assert_clean_failure(res, out)
        assert "cannot use the data" in res.output
        assert re.search(r"line \d+|column '", res.output), res.output


def test_index_file_with_T_on_the_command_line(lab, tmp_path):
    ds = ji.load(lab / "data.csv", lab / "input.csv")
    ji.save_data(tmp_path / "k.csv", ds.data, index=True, metadata={"x-note": "T removed below"})
    text = (tmp_path / "k.csv").read_text().replace("# T: 1.0\n", "")
    (tmp_path / "k.csv").write_text(text)
    args = ["detect", tmp_path / "k.csv", "--input", lab / "input.csv", "--model", "polepair"]
    res = run(*args)
    assert_clean_failure(res)
    assert "T is not given" in res.output
    assert "jitter detected" in ok(*args, "--T", "1").output


def test_a_failed_search_exits_3_and_says_so(lab, tmp_path, monkeypatch):
    import dataclasses

    from jitterid.cli import data as cli_data

    real = cli_data.fit_model

    def failing(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), status=ji.FitStatus.MAX_EVALUATIONS)

    monkeypatch.setattr(cli_data, "fit_model", failing)
    out = tmp_path / "fit"
    res = run(
        "fit",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--model",
        "polepair",
        "--jitter",
        "none",
        "--method",
        "ls",
        "--out",
        out,
        "--no-plots",
    )
    assert res.exit_code == 3
    assert "did not converge" in res.output
    assert json.loads((out / "result.json").read_text())["success"] is False


# ------------------------------------------------------------------------------ output (issue 15 F)


class _FakeTTY:
    """A text stream that says it is a terminal, to see the progress bar in a test."""

    def __init__(self) -> None:
        self.text = ""

    def isatty(self) -> bool:
        return True

    def write(self, s: str) -> int:
        self.text += s
        return len(s)

    def flush(self) -> None:
        pass


def _fit_args(lab: Path, out: Path, *extra: str, jitter: str = "uniform") -> list[str | Path]:
    return [
        "fit", lab / "data.csv", "--input", lab / "input.csv", "--model", "polepair",
        "--jitter", jitter, "--method", "bcls", "--out", out, "--no-plots", *extra,
    ]  # fmt: skip


def test_progress_bar_on_a_terminal_only_on_stderr_and_off_with_quiet(lab, tmp_path, monkeypatch):
    from jitterid.cli import data as cli_data

    # Not a terminal (CliRunner's stderr, a pipe, a log file): no bar at all.
    res = CliRunner().invoke(main, [str(a) for a in _fit_args(lab, tmp_path / "plain")])
    assert res.exit_code == 0, res.output
    assert "ordinary LS fit (" not in res.stderr
    # A terminal: the stages, with the elapsed time, on stderr, cleared at the end; stdout
    # and the result files never see it.
    tty = _FakeTTY()
    monkeypatch.setattr(cli_data, "PROGRESS_DELAY", 0.0)
    monkeypatch.setattr(cli_data, "_progress_file", lambda: tty)
    out = tmp_path / "tty"
    res = CliRunner().invoke(main, [str(a) for a in _fit_args(lab, out)])
    assert res.exit_code == 0, res.output
    for stage in ("bcls fit (1/4)", "diagnostics (2/4)", "writing results (3/4)"):
        assert f"jitterid: {stage}" in tty.text
    assert re.search(r"\d\d:\d\d", tty.text)
    assert tty.text.endswith("\r")  # the line is cleared
    assert "jitterid: " not in res.stdout
    for f in out.iterdir():
        assert "bcls fit (" not in f.read_text(), f
    # --quiet: nothing, even on a terminal.
    tty.text = ""
    res = CliRunner().invoke(main, [str(a) for a in _fit_args(lab, tmp_path / "quiet", "--quiet")])
    assert res.exit_code == 0, res.output
    assert tty.text == ""
    assert "--quiet" in run("fit", "--help").output


def test_a_short_fit_shows_no_bar_even_on_a_terminal(lab, tmp_path, monkeypatch):
    from jitterid.cli import data as cli_data

    tty = _FakeTTY()
    monkeypatch.setattr(cli_data, "PROGRESS_DELAY", 60.0)
    monkeypatch.setattr(cli_data, "_progress_file", lambda: tty)
    res = CliRunner().invoke(main, [str(a) for a in _fit_args(lab, tmp_path / "f")])
    assert res.exit_code == 0, res.output
    assert tty.text == ""


def test_noise_std_is_null_where_no_noise_was_used(lab, tmp_path):
    """ls uses no noise level: null and "not used"; bcls records the residuals' plug-in its
    covariance used, or the given value, and says which."""
    ok("fit", lab / "data.csv", "--input", lab / "input.csv", "--model", "polepair",
       "--jitter", "none", "--method", "ls", "--out", tmp_path / "ls", "--no-plots")  # fmt: skip
    result = json.loads((tmp_path / "ls" / "result.json").read_text())
    assert result["noise_std"] is None
    assert result["noise_std_source"] is None
    assert "- noise std: not used" in (tmp_path / "ls" / "report.md").read_text()
    ok(*_fit_args(lab, tmp_path / "bcls"))
    result = json.loads((tmp_path / "bcls" / "result.json").read_text())
    assert result["noise_std"] > 0
    assert result["noise_std_source"] == "residuals"
    assert "the residuals' plug-in" in (tmp_path / "bcls" / "report.md").read_text()
    ok(*_fit_args(lab, tmp_path / "given", "--noise-std", "0.01"))
    result = json.loads((tmp_path / "given" / "result.json").read_text())
    assert (result["noise_std"], result["noise_std_source"]) == (0.01, "given")
    assert result["jitter"]["std_stderr"] > 0


def test_a_parameter_on_its_bound_is_explained_in_result_json(lab, tmp_path, monkeypatch):
    """The issue: "nan" unexplained. result.json's stderr is null there, and stderr_notes
    says why; an interval cut at a bound is noted in conf_int_notes; both in the report."""
    import dataclasses

    from jitterid.cli import data as cli_data

    real = cli_data.fit_model

    def on_bound(data, structure, jitter, method, *args, **kwargs):
        res = real(data, structure, jitter, method, *args, **kwargs)
        if method == "ls":
            return res
        x, cov = np.array(res.x), np.array(res.cov)
        x[0] = 0.0  # n on its lower bound: held fixed
        cov[0, :] = cov[:, 0] = np.nan
        cov[1, 1] = (x[1] / 1.5) ** 2  # a: a wide interval, cut at its floor
        return dataclasses.replace(res, x=x, cov=cov, status=ji.FitStatus.CONVERGED)  # notes only

    monkeypatch.setattr(cli_data, "fit_model", on_bound)
    out = tmp_path / "fit"
    res = ok(*_fit_args(lab, out, jitter="sum-of-uniforms"))
    result = json.loads((out / "result.json").read_text())
    assert result["stderr"]["n"] is None
    assert "on its bound 0" in result["stderr_notes"]["n"]
    assert set(result["stderr_notes"]) == {"n"}
    assert result["conf_int_95"]["a"][0] == 1e-12
    assert "cut at its bound 1e-12" in result["conf_int_notes"]["a"]
    report = (out / "report.md").read_text()
    assert "- n: on its bound 0" in report
    assert "- a: interval cut at its bound 1e-12" in report
    assert "n: on its bound 0" in res.output


# ------------------------------------------------------------------------------ delay, mean jitter


def test_delay_model_and_late_jitter_round_trip(tmp_path):
    """+delay and mean=: the truth.json written by simulate is recovered by fit, and the
    delay estimate is the true one with the known mean held fixed."""
    d = tmp_path / "lab"
    ok(
        "simulate",
        "--out",
        d,
        "--model",
        "polepair+delay",
        "--params",
        "6.25,-1.5,2,0.7",
        "--jitter",
        "uniform:a=0.4,mean=100ms",
        "--seed",
        "3",
    )
    truth = json.loads((d / "truth.json").read_text())
    assert truth["system"]["delay_s"] == 0.7
    assert truth["jitter"]["mean_s"] == pytest.approx(0.1)
    out = tmp_path / "fit"
    res = ok(
        "fit",
        d / "data.csv",
        "--input",
        d / "input.csv",
        "--model",
        "polepair+delay",
        "--jitter",
        "known:uniform:a=0.4,mean=0.1",
        "--method",
        "gaussian",
        "--out",
        out,
        "--no-plots",
    )
    assert "the samples identify only delay_s - mean jitter" in res.output
    saved = json.loads((out / "result.json").read_text())
    _within(saved, truth["params"], k=3.5)
    assert saved["system"]["delay_s"] == pytest.approx(saved["parameters"]["delay_s"])


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("polepair+lag", "the only addition is \\+delay"),
        ("tf:0,2+delay+delay", "the only addition"),
    ],
)
def test_bad_model_additions_are_refused(spec, match):
    with pytest.raises(ValueError, match=match):
        parse_model(spec)


def test_known_law_with_a_mean_is_a_shifted_law():
    law = parse_jitter("known:gaussian:sigma=80ms,mean=-20ms")
    assert isinstance(law, ji.Shifted)
    assert law.mean == pytest.approx(-0.02)
    assert law.std == pytest.approx(0.08)
    assert parse_jitter("known:uniform:a=0.5,mean=0") == ji.Uniform(0.5)
