"""What ``jitterid fit`` writes: result.json, a Markdown report and its figures."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.diagnostics import (
    JitterDetection,
    ResidualTest,
    bias_frequency,
    ls_gain_factor,
)
from ..analysis.uncertainty import bode_band, jitter_pdf_band
from ..estimation.result import FitResult
from ..io import Dataset
from ..jitter.laws import JitterFamily, JitterLaw
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction

__all__ = ["FitReport", "write_outputs"]


@dataclass(frozen=True, eq=False)
class FitReport:
    """Everything the fit command computed, to be written out."""

    dataset: Dataset
    structure: ModelStructure
    model_spec: str
    model_label: str
    jitter_spec: str
    jitter: JitterLaw | JitterFamily
    result: FitResult
    ordinary: FitResult
    detection: JitterDetection
    checks: tuple[ResidualTest, ...]
    level: float
    seed: int
    version: str


def _clean(x: Any) -> Any:
    """JSON-safe: NaN/inf -> None, numpy -> Python."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def _law_dict(law: JitterLaw) -> dict[str, Any]:
    return {"law": type(law).__name__, "params": law.params, "std": law.std}


def _system_dict(tf: TransferFunction) -> dict[str, Any]:
    return {
        "num": tf.num,
        "den": tf.den,
        "poles_rad_per_s": [[p.real, p.imag] for p in tf.poles],
        "dc_gain": tf.dcgain if tf.den[-1] != 0 else None,
    }


def result_json(rep: FitReport) -> dict[str, Any]:
    """The content of result.json."""
    res, ds = rep.result, rep.dataset
    det = rep.detection
    return _clean(
        {
            "jitterid_version": rep.version,
            "method": res.method,
            "success": res.success,
            "status": res.status.value,
            "message": res.message,
            "nfev": res.nfev,
            "criterion": res.cost,
            "data": {
                "files": [{"role": s.role, "path": s.path, "sha256": s.sha256} for s in ds.sources],
                "sha256": ds.sha256,
                "N": ds.data.N,
                "T_s": ds.data.T,
                "t0_s": ds.t0,
                "units": ds.units,
            },
            "model": {
                "spec": rep.model_spec,
                "formula": rep.model_label,
                "param_names": list(rep.structure.param_names),
            },
            "jitter": {
                "spec": rep.jitter_spec,
                "estimated": isinstance(rep.jitter, JitterFamily),
                **_law_dict(res.jitter_law),
            },
            "noise_std": res.noise_std,
            "parameters": res.params,
            "stderr": res.stderr,
            f"conf_int_{round(100 * rep.level)}": res.conf_int(rep.level),
            "covariance": {"names": list(res.names), "matrix": res.cov},
            "system": _system_dict(res.system),
            "ordinary_ls": {
                "parameters": rep.ordinary.params,
                "stderr": rep.ordinary.stderr,
                "system": _system_dict(rep.ordinary.system),
            },
            "diagnostics": {
                "jitter_detection": {
                    "statistic": det.statistic,
                    "pvalue": det.pvalue,
                    "implied_jitter_std_s": det.jitter_std,
                    "implied_jitter_std_ci_s": det.jitter_std_ci,
                    "level": det.level,
                },
                **{
                    c.name: {"statistic": c.statistic, "dof": c.dof, "pvalue": c.pvalue}
                    for c in rep.checks
                },
            },
            "seed": rep.seed,
        }
    )


def _figures(rep: FitReport, out: Path) -> dict[str, str]:
    from matplotlib.figure import Figure

    from ..plots import plot_bode, plot_jitter_pdf, plot_residuals

    res, data = rep.result, rep.dataset.data
    names: dict[str, str] = {}
    f = np.geomspace(1.0 / (data.N * data.T), 0.5 / data.T, 300)
    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    band = bode_band(res, f, rep.level, structure=rep.structure)
    refs = {} if res.method == "ls" else {"ordinary LS (jitter ignored)": rep.ordinary.system}
    plot_bode(band, refs, label=f"{res.method} estimate", ax=axes)
    axes[0].set_title(f"Bode plot, {100 * rep.level:g}% delta-method band", fontsize="medium")
    fig.savefig(out / "bode.png", dpi=110)
    names["bode"] = "bode.png"

    if res.jitter_law.std > 0:
        hi = 1.5 * min(res.jitter_law.support[1], 4 * res.jitter_law.std)
        family = rep.jitter if isinstance(rep.jitter, JitterFamily) else None
        tau = np.linspace(-hi, hi, 601)
        label = "estimated" if family else "assumed (known)"
        try:
            pband = jitter_pdf_band(res, tau, rep.seed, level=rep.level, n_draws=2000, family=family)
        except ValueError as exc:  # too uncertain for a band: show the estimate alone
            pband = jitter_pdf_band(res, tau, rep.seed, level=rep.level, family=None)
            label = "estimated (no band: too uncertain)"
            names["jitter_pdf_note"] = str(exc)
        fig = Figure(figsize=(6.4, 4.0), layout="constrained")
        ax = fig.subplots()
        plot_jitter_pdf(pband, label=label, ax=ax)
        fig.savefig(out / "jitter_pdf.png", dpi=110)
        names["jitter_pdf"] = "jitter_pdf.png"

    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    axes = fig.subplots(2, 1)
    plot_residuals(rep.detection, ax=axes)
    axes[0].set_title("residuals of the ordinary LS fit", fontsize="medium")
    fig.savefig(out / "residuals.png", dpi=110)
    names["residuals"] = "residuals.png"
    return names


def _table(rep: FitReport) -> list[str]:
    res, ls = rep.result, rep.ordinary
    pct = f"{100 * rep.level:g}%"
    ci = res.conf_int(rep.level)
    lines = [
        f"| parameter | {res.method} estimate | std err | {pct} interval | ordinary LS | LS std err |",
        "|---|---:|---:|---|---:|---:|",
    ]
    for n, v in res.params.items():
        lsv = f"{ls.params[n]:.5g}" if n in ls.params else "-"
        lse = f"{ls.stderr[n]:.3g}" if n in ls.stderr else "-"
        lines.append(
            f"| {n} | {v:.5g} | {res.stderr[n]:.3g} | [{ci[n][0]:.5g}, {ci[n][1]:.5g}] "
            f"| {lsv} | {lse} |"
        )
    return lines


def _image(alt: str, name: str | None) -> list[str]:
    return [f"![{alt}]({name})", ""] if name else []


def report_markdown(rep: FitReport, figs: dict[str, str]) -> str:
    """The Markdown report."""
    res, ds, det = rep.result, rep.dataset, rep.detection
    data = ds.data
    files = ", ".join(
        f"{s.role} `{Path(s.path).name}` (sha256 `{s.sha256[:16]}…`)" for s in ds.sources
    )
    lo, hi = det.jitter_std_ci
    pct = f"{100 * rep.level:g}%"
    law = res.jitter_law
    lines = [
        "# jitterid fit report",
        "",
        f"- **Data**: {files}",
        (
            f"- **Grid**: N = {data.N} samples, T = {data.T:g} s (Nyquist {0.5 / data.T:g} Hz), "
            f"first sample at file time {ds.t0:g} s; output unit `{ds.units['y'] or '-'}`"
        ),
        f"- **Model**: `{rep.model_spec}`, {rep.model_label}",
        f"- **Jitter**: `{rep.jitter_spec}`; **method**: `{res.method}`",
        f"- **Status**: {res.status.value} ({res.nfev} evaluations)",
        f"- jitterid {rep.version}; full numbers in `result.json`",
        "",
        "## 1. Is there jitter?",
        "",
        (
            "An ordinary fit that ignores jitter leaves residuals whose variance grows with the "
            "squared slope of the output when the sampling instants jitter. Regressing squared "
            "residuals on squared model slopes:"
        ),
        "",
        (
            f"- one-sided t = {det.statistic:.3f}, **p = {det.pvalue:.3g}** "
            f"({'jitter detected' if det.detected() else 'no jitter detected'} at the 5% level)"
        ),
        (
            f"- implied jitter std {det.jitter_std:.3g} s, {pct} interval [{lo:.3g}, {hi:.3g}] s "
            "(first-order approximation, biased low for large jitter; the fit below is the "
            "accurate estimate)"
        ),
        "",
        *_image("residuals of the ordinary fit", figs.get("residuals")),
        "## 2. Estimate",
        "",
        *_table(rep),
        "",
        f"- jitter law: {law} ({'estimated' if isinstance(rep.jitter, JitterFamily) else 'assumed'})",
        (
            "- noise std: not used"
            if res.noise_std is None
            else f"- noise std: {res.noise_std:.4g}"
            + (" (estimated)" if "noise_std" in res.names else " (given, or from the residuals)")
        ),
        (
            f"- G(s) numerator {np.array2string(res.system.num, precision=5)}, denominator "
            f"{np.array2string(res.system.den, precision=5)} (s in rad/s)"
        ),
        "- poles: "
        + ", ".join(
            f"{p.real:.4g}{p.imag:+.4g}i rad/s (|p| = {abs(p) / (2 * np.pi):.4g} Hz)"
            for p in res.system.poles
        ),
        "",
        "## 3. Frequency response",
        "",
        *_image("Bode plot", figs.get("bode")),
    ]
    if law.std > 0:
        fb = bias_frequency(law, 0.01)
        ny = 0.5 / data.T
        lines += [
            (
                f"Under the {'fitted' if isinstance(rep.jitter, JitterFamily) else 'assumed'} jitter "
                f"law an ordinary fit sees the gain scaled by |φ(f)|: {ls_gain_factor(law, ny):.3f} at "
                f"Nyquist ({ny:g} Hz); the gain bias reaches 1% at {fb:.3g} Hz."
            ),
            "",
        ]
    if "jitter_pdf" in figs:
        lines += ["## 4. Jitter density", "", f"![jitter pdf]({figs['jitter_pdf']})", ""]
        if "jitter_pdf_note" in figs:
            lines += [f"No band is drawn: {figs['jitter_pdf_note']}.", ""]
    lines += ["## 5. Residual checks (after fitting)", ""]
    lines += [f"- {c.summary()}" for c in rep.checks]
    lines += [
        "",
        "Standardised residuals (y_k - E y_k) / sd(y_k) under the fitted model and jitter law.",
        "",
        "## 6. Export",
        "",
        "```python",
        "import json, pathlib, scipy.signal",
        "r = json.loads(pathlib.Path('result.json').read_text())",
        "G = scipy.signal.lti(r['system']['num'], r['system']['den'])  # s in rad/s",
        "```",
        "",
    ]
    return "\n".join(lines)


def write_outputs(rep: FitReport, out: Path, *, plots: bool = True) -> list[Path]:
    """Write result.json, report.md and (with ``plots``) the figures into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "result.json"]
    (out / "result.json").write_text(
        json.dumps(result_json(rep), indent=2) + "\n", encoding="utf-8"
    )
    figs = _figures(rep, out) if plots else {}
    (out / "report.md").write_text(report_markdown(rep, figs), encoding="utf-8")
    pngs = [out / v for k, v in figs.items() if v.endswith(".png")]
    return [*written, out / "report.md", *pngs]
