"""What ``jitterid fit`` writes: result.json, a Markdown report and its figures.

Every file is written atomically (a temporary file renamed into place). Text from the data
files (units, paths) and the command line is escaped before it goes into the Markdown
report, so it cannot inject markup, links or HTML. A part that cannot be computed (a
diagnostic, the standard errors, a figure) is reported as skipped with its reason; the fit
itself is always written.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._markdown import md_code as _code
from .._markdown import md_text
from ..analysis.diagnostics import (
    JitterCrossCheck,
    JitterDetection,
    ResidualTest,
    bias_frequency,
    ls_gain_factor,
)
from ..analysis.quantities import PhysicalQuantities, physical_quantities
from ..analysis.responses import step_response
from ..analysis.selection import OrderSelection
from ..analysis.uncertainty import bode_band, jitter_pdf_band
from ..estimation.result import FitResult
from ..io import Dataset, atomic_write
from ..jitter.laws import JitterFamily, JitterLaw
from ..systems.constrained import Constrained
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
    detection: JitterDetection | None
    checks: tuple[ResidualTest, ...]
    level: float
    seed: int
    version: str
    skipped: tuple[tuple[str, str], ...] = ()
    cross_check: JitterCrossCheck | None = None
    #: the order selection that chose ``structure`` (several --model), or None
    order: OrderSelection | None = None


_ERRORS = (ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError)


def _try(make: Callable[[], Any]) -> tuple[Any, str | None]:
    try:
        return make(), None
    except _ERRORS as exc:
        return None, " ".join(str(exc).split()) or type(exc).__name__


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
        "delay_s": tf.delay_s,
    }


def noise_source(rep: FitReport) -> str | None:
    """Where the result's noise_std came from: ``"estimated"`` (a parameter of the fit),
    ``"given"`` (``--noise-std`` or the data file), ``"residuals"`` (not used by the
    criterion; its plug-in from the residuals, for the covariance) or None (not used)."""
    res = rep.result
    if res.noise_std is None:
        return None
    if "noise_std" in res.names:
        return "estimated"
    return "given" if rep.dataset.data.noise_std is not None else "residuals"


def _noise_line(rep: FitReport) -> str:
    res = rep.result
    how = {
        None: "",
        "estimated": " (estimated)",
        "given": " (given)",
        "residuals": (
            f" (not used by `{res.method}`: the residuals' plug-in, used for the standard errors)"
        ),
    }[noise_source(rep)]
    return (
        "- noise std: not used"
        if res.noise_std is None
        else f"- noise std: {res.noise_std:.4g}{how}"
    )


def _constraints(structure: ModelStructure) -> dict[str, Any]:
    """The user's --fix, --bounds and --start of a constrained structure (a bound's open end
    null), else nothing."""
    if not isinstance(structure, Constrained):
        return {}
    return {"fixed": structure.fixed, "bounds": structure.user_bounds, "start": structure.start}


def _constraints_line(structure: ModelStructure) -> list[str]:
    c = _constraints(structure)
    parts = [f"fixed {n} = {v:g}" for n, v in c.get("fixed", {}).items()]
    parts += [f"{n} in [{lo:g}, {hi:g}]" for n, (lo, hi) in c.get("bounds", {}).items()]
    parts += [f"start {n} = {v:g}" for n, v in c.get("start", {}).items()]
    return [f"- **Constraints**: {md_text('; '.join(parts))}"] if parts else []


def result_json(rep: FitReport) -> dict[str, Any]:
    """The content of result.json.

    ``noise_std`` is null where the fit used no noise level (``noise_std_source`` says where
    a value came from); ``stderr_notes`` says why a standard error is null (a parameter on
    or next to its bound, a singular information matrix), ``conf_int_notes`` which interval
    was cut at a bound (see :meth:`FitResult.conf_int`).
    """
    res, ds = rep.result, rep.dataset
    det = rep.detection
    stderr, why = _try(lambda: res.stderr)
    ci, why_ci = _try(lambda: res.conf_int(rep.level))
    se_notes, _ = _try(lambda: res.stderr_notes)
    ci_notes, _ = _try(lambda: res.conf_int_notes(rep.level))
    std_se, _ = _try(lambda: res.jitter_std_stderr)
    cov, _ = _try(lambda: res.cov)
    ls_se, _ = _try(lambda: rep.ordinary.stderr)
    skipped = dict(rep.skipped)
    if why or why_ci:
        skipped["standard errors"] = why or why_ci or ""
    diagnostics: dict[str, Any] = {}
    if det is not None:
        diagnostics["jitter_detection"] = {
            "statistic": det.statistic,
            "pvalue": det.pvalue,
            "implied_jitter_std_s": det.jitter_std,
            "implied_jitter_std_ci_s": det.jitter_std_ci,
            "level": det.level,
        }
    xc = rep.cross_check
    warnings: list[str] = []
    if xc is not None:
        diagnostics["jitter_cross_check"] = {
            "verdict": xc.verdict,
            "consistent": xc.consistent,
            "jitter_std_s": xc.fitted_std,
            "jitter_std_stderr_s": xc.fitted_std_se,
            "jitter_estimated": xc.estimated,
            "message": xc.message,
        }
        if not xc.consistent:
            warnings.append(f"jitter cross-check: {xc.message}")
    best = None if rep.order is None else rep.order.best
    if best is not None and not best.trustworthy:
        warnings.append(f"order selection: {best.label} was chosen but {best.problem}")
    for c in rep.checks:
        diagnostics[c.name] = {"statistic": c.statistic, "dof": c.dof, "pvalue": c.pvalue}
    quantities, why_q = _quantities(rep)
    if skipped:
        diagnostics["skipped"] = skipped
    return _clean(
        {
            "jitterid_version": rep.version,
            "method": res.method,
            "success": res.success,
            "status": res.status.value,
            "message": res.message,
            "warnings": warnings,
            "nfev": res.nfev,
            "criterion": res.cost,
            "data": {
                "files": [{"role": s.role, "path": s.path, "sha256": s.sha256} for s in ds.sources],
                "sha256": ds.sha256,
                "N": ds.data.N,
                "T_s": ds.data.T,
                "t0_s": ds.t0,
                "units": ds.units,
                "notes": list(ds.notes),
            },
            "model": {
                "spec": rep.model_spec,
                "formula": rep.model_label,
                "param_names": list(rep.structure.param_names),
                **_constraints(rep.structure),
            },
            "jitter": {
                "spec": rep.jitter_spec,
                "estimated": isinstance(rep.jitter, JitterFamily),
                **_law_dict(res.jitter_law),
                "std_stderr": std_se,
            },
            "noise_std": res.noise_std,
            "noise_std_source": noise_source(rep),
            "parameters": res.params,
            "stderr": stderr,
            "stderr_notes": se_notes or {},
            f"conf_int_{round(100 * rep.level)}": ci,
            "conf_int_notes": ci_notes or {},
            "covariance": {"names": list(res.names), "matrix": cov},
            "system": _system_dict(_tf(res)),
            "physical_quantities": (
                quantities.to_dict() if quantities is not None else {"skipped": why_q}
            ),
            "ordinary_ls": {
                "parameters": rep.ordinary.params,
                "stderr": ls_se,
                "system": _system_dict(_tf(rep.ordinary)),
            },
            "diagnostics": diagnostics,
            **({} if rep.order is None else {"order_selection": _order_brief(rep.order)}),
            "seed": rep.seed,
        }
    )


def _quantities(rep: FitReport) -> tuple[PhysicalQuantities | None, str | None]:
    """The physical quantities of the fit with delta-method intervals at the report's level,
    or None and why not."""
    with np.errstate(all="ignore"):
        return _try(lambda: physical_quantities(rep.result, rep.level))


def _quantity_lines(rep: FitReport) -> list[str]:
    """The Markdown table of the physical quantities (or one line saying why there is none)."""
    table, why = _quantities(rep)
    if table is None:
        return [f"Physical quantities not computed: {md_text(why or '')}.", ""]
    pct = f"{100 * rep.level:g}%"
    logs = [q.name for q in table if q.scale == "log"]
    lines = [
        "Physical quantities (poles and zeros: real part in 1/s, imaginary part in rad/s; "
        "natural frequencies and bandwidth in Hz; delta-method intervals"
        + (f", on the log scale for {', '.join(f'`{n}`' for n in logs)}" if logs else "")
        + "):",
        "",
        f"| quantity | estimate | std err | {pct} interval | unit |",
        "|---|---:|---:|---|---|",
    ]
    for q in table:
        ci = f"[{q.low:.5g}, {q.high:.5g}]" if math.isfinite(q.low) else "-"
        se = f"{q.stderr:.3g}" if math.isfinite(q.stderr) else "-"
        val = f"{q.value:.5g}" if math.isfinite(q.value) else "-"
        lines.append(f"| `{q.name}` | {val} | {se} | {ci} | {md_text(q.unit or '-')} |")
    notes = [f"- `{q.name}`: {md_text(q.note)}" for q in table if q.note]
    return [*lines, "", *notes, *([""] if notes else [])]


def _order_brief(order: OrderSelection) -> dict[str, Any]:
    """result.json's pointer to order.json: what was compared and what was chosen."""
    best = order.best
    return {
        "file": "order.json",
        "criterion": order.criterion,
        "candidates": list(order.labels),
        "chosen": None if best is None else best.label,
        "trustworthy": None if best is None else best.trustworthy,
        "reason": order.reason,
    }


def _order_lines(rep: FitReport) -> list[str]:
    """The "Order selection" section: the table of :func:`jitterid.select_order` and why."""
    order = rep.order
    if order is None:
        return []
    has_val = any(r.validation_fit_pct is not None for r in order.rows)
    rank = (
        "highest validation fit %"
        if order.criterion == "validation"
        else f"lowest {order.criterion.upper()}"
    )
    lines = [
        "## Order selection",
        "",
        (
            f"Every model was fitted with `{md_text(order.method)}`; {md_text(order.basis())}. "
            f"The {rank} among the trustworthy candidates is chosen (full numbers in `order.json`)."
        ),
        "",
        "| | model | k | status | log-lik | AIC | BIC |"
        + (" validation fit % |" if has_val else "")
        + " Ljung-Box p | input p |",
        "|---|---|---:|---|---:|---:|---:|" + ("---:|" if has_val else "") + "---:|---:|",
    ]

    def num(v: float | None, spec: str) -> str:
        return "-" if v is None or not math.isfinite(v) else format(v, spec)

    for i, r in enumerate(order.rows):
        lines.append(
            f"| {'**chosen**' if i == order.chosen else ''} | {md_text(r.label)} | {r.n_params} "
            f"| {md_text(r.flag)} | {num(r.loglik, '.6g')} | {num(r.aic, '.6g')} | "
            f"{num(r.bic, '.6g')} |"
            + (f" {num(r.validation_fit_pct, '.2f')} |" if has_val else "")
            + f" {num(r.whiteness_pvalue, '.3g')} | {num(r.input_pvalue, '.3g')} |"
        )
    lines.append("")
    lines += [f"- {md_text(r.label)}: {md_text(r.problem)}" for r in order.rows if r.problem]
    lines += [
        f"- likelihood-ratio test {md_text(t.smaller)} within {md_text(t.larger)}: LR = "
        f"{t.statistic:.4g}, dof {t.dof}, p = {t.pvalue:.3g} (asymptotic chi-square)"
        + (f"; {md_text(t.note)}" if t.note else "")
        for t in order.tests
    ]
    lines += [f"- **Chosen**: {md_text(order.reason)}", ""]
    return lines


def _save(fig: Any, path: Path) -> None:
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=110, format="png"), binary=True)


def _figures(rep: FitReport, out: Path) -> dict[str, str]:
    """The figures that can be drawn; a figure that cannot is noted under ``<name>_skipped``."""
    names: dict[str, str] = {}
    for name, draw in (
        ("bode", _bode_fig),
        ("step", _step_fig),
        ("jitter_pdf", _pdf_fig),
        ("residuals", _resid_fig),
    ):
        try:
            names.update(draw(rep, out))
        except _ERRORS as exc:
            names[f"{name}_skipped"] = " ".join(str(exc).split()) or type(exc).__name__
    return names


def _bode_fig(rep: FitReport, out: Path) -> dict[str, str]:
    from matplotlib.figure import Figure

    from ..plots import plot_bode

    res, data = rep.result, rep.dataset.data
    names: dict[str, str] = {}
    f = np.geomspace(1.0 / (data.N * data.T), 0.5 / data.T, 300)
    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    band = bode_band(res, f, rep.level, structure=rep.structure)
    refs = (
        {} if res.estimator.ignores_jitter else {"ordinary LS (jitter ignored)": _tf(rep.ordinary)}
    )
    plot_bode(band, refs, label=f"{res.method} estimate", ax=axes)
    axes[0].set_title(f"Bode plot, {100 * rep.level:g}% delta-method band", fontsize="medium")
    _save(fig, out / "bode.png")
    names["bode"] = "bode.png"
    return names


def _step_horizon(res: FitResult, data_span_s: float) -> float:
    """How long to draw the step response (s): 7 time constants of the slowest decaying
    pole (the response has settled to 0.1 %), at most the record's span."""
    p = _tf(res).poles
    decay = -p.real[p.real < 0]
    if not decay.size or np.any(p.real >= 0):
        return data_span_s
    return float(min(7.0 / decay.min(), data_span_s))


def _step_fig(rep: FitReport, out: Path) -> dict[str, str]:
    from matplotlib.figure import Figure

    from ..plots import plot_step_response

    res, data = rep.result, rep.dataset.data
    t = np.linspace(0.0, _step_horizon(res, data.N * data.T), 400)
    with np.errstate(all="ignore"):
        band = step_response(res, t, rep.level)
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.subplots()
    refs = (
        {} if res.estimator.ignores_jitter else {"ordinary LS (jitter ignored)": _tf(rep.ordinary)}
    )
    plot_step_response(band, refs, label=f"{res.method} estimate", ax=ax)
    ax.set_title(f"Step response, {100 * rep.level:g}% delta-method band", fontsize="medium")
    _save(fig, out / "step.png")
    return {"step": "step.png"}


def _pdf_fig(rep: FitReport, out: Path) -> dict[str, str]:
    from matplotlib.figure import Figure

    from ..plots import plot_jitter_pdf

    res = rep.result
    names: dict[str, str] = {}
    if res.jitter_law.std > 0:
        hi = 1.5 * min(res.jitter_law.support[1], 4 * res.jitter_law.std)
        family = rep.jitter if isinstance(rep.jitter, JitterFamily) else None
        tau = np.linspace(-hi, hi, 601)
        label = "estimated" if family else "assumed (known)"
        try:
            pband = jitter_pdf_band(
                res, tau, rep.seed, level=rep.level, n_draws=2000, family=family
            )
        except ValueError as exc:  # too uncertain for a band: show the estimate alone
            pband = jitter_pdf_band(res, tau, rep.seed, level=rep.level, family=None)
            label = "estimated (no band: too uncertain)"
            names["jitter_pdf_note"] = str(exc)
        fig = Figure(figsize=(6.4, 4.0), layout="constrained")
        ax = fig.subplots()
        plot_jitter_pdf(pband, label=label, ax=ax)
        _save(fig, out / "jitter_pdf.png")
        names["jitter_pdf"] = "jitter_pdf.png"
    return names


def _resid_fig(rep: FitReport, out: Path) -> dict[str, str]:
    from matplotlib.figure import Figure

    from ..plots import plot_residuals

    names: dict[str, str] = {}
    if rep.detection is None:
        return names
    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    axes = fig.subplots(2, 1)
    plot_residuals(rep.detection, ax=axes)
    axes[0].set_title("residuals of the ordinary LS fit", fontsize="medium")
    _save(fig, out / "residuals.png")
    names["residuals"] = "residuals.png"
    return names


def _table(rep: FitReport) -> list[str]:
    res, ls = rep.result, rep.ordinary
    pct = f"{100 * rep.level:g}%"
    se, why = _try(lambda: res.stderr)
    ci, why_ci = _try(lambda: res.conf_int(rep.level))
    ls_se, _ = _try(lambda: ls.stderr)
    ls_se = ls_se or {}
    lines = [
        (
            f"| parameter | {md_text(res.method)} estimate | std err | {pct} interval "
            "| ordinary LS | LS std err |"
        ),
        "|---|---:|---:|---|---:|---:|",
    ]
    for n, v in res.params.items():
        lsv = f"{ls.params[n]:.5g}" if n in ls.params else "-"
        lse = f"{ls_se[n]:.3g}" if n in ls_se else "-"
        sev = f"{se[n]:.3g}" if se is not None else "-"
        civ = f"[{ci[n][0]:.5g}, {ci[n][1]:.5g}]" if ci is not None else "-"
        lines.append(f"| {md_text(n)} | {v:.5g} | {sev} | {civ} | {lsv} | {lse} |")
    if why or why_ci:
        lines += ["", f"No standard errors: {md_text(why or why_ci)}."]
    notes = [
        *(
            f"- {md_text(n)}: {md_text(w)}"
            for n, w in (_try(lambda: res.stderr_notes)[0] or {}).items()
        ),
        *(
            f"- {md_text(n)}: {md_text(w)}"
            for n, w in (_try(lambda: res.conf_int_notes(rep.level))[0] or {}).items()
        ),
    ]
    if notes:
        lines += ["", *notes]
    return lines


def _jitter_std_line(rep: FitReport) -> str:
    res = rep.result
    if not isinstance(rep.jitter, JitterFamily):
        return f"- jitter std: {res.jitter_std:.4g} s (known)"
    se, _ = _try(lambda: res.jitter_std_stderr)
    tail = (
        f" ± {se:.2g} s (delta method)"
        if se is not None and math.isfinite(se)
        else " (no standard error)"
    )
    return f"- jitter std: {res.jitter_std:.4g} s{tail}"


def _image(alt: str, name: str | None) -> list[str]:
    return [f"![{alt}]({name})", ""] if name else []


def _detection_lines(rep: FitReport, figs: dict[str, str]) -> list[str]:
    det = rep.detection
    if det is None:
        why = dict(rep.skipped).get("jitter detection", "it could not be computed")
        return [f"Skipped: the jitter test could not run ({md_text(why)}).", ""]
    lo, hi = det.jitter_std_ci
    pct = f"{100 * rep.level:g}%"
    return [
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
        *_cross_check_lines(rep),
        *_image("residuals of the ordinary fit", figs.get("residuals")),
    ]


def _cross_check_lines(rep: FitReport) -> list[str]:
    xc = rep.cross_check
    if xc is None:
        return []
    if xc.consistent:
        return [
            (
                f"Cross-check: the {'fitted' if xc.estimated else 'assumed'} jitter std "
                f"({xc.fitted_std:.3g} s) agrees with this test."
            ),
            "",
        ]
    return [f"**Warning: the jitter std contradicts this test.** {md_text(xc.message)}.", ""]


def report_markdown(rep: FitReport, figs: dict[str, str]) -> str:
    """The Markdown report (user text escaped, see :func:`md_text`)."""
    res, ds = rep.result, rep.dataset
    data = ds.data
    files = ", ".join(
        f"{s.role} {md_text(Path(s.path).name)} (sha256 `{s.sha256[:16]}…`)" for s in ds.sources
    )
    law = res.jitter_law
    lines = [
        "# jitterid fit report",
        "",
        f"- **Data**: {files}",
        (
            f"- **Grid**: N = {data.N} samples, T = {data.T:g} s (Nyquist {0.5 / data.T:g} Hz), "
            f"first sample at file time {ds.t0:g} s; output unit {md_text(ds.units['y'] or '-')}"
        ),
        *(f"- **Note**: {md_text(n)}" for n in ds.notes),
        f"- **Model**: {_code(rep.model_spec)}, {md_text(rep.model_label)}",
        *_constraints_line(rep.structure),
        f"- **Jitter**: {_code(rep.jitter_spec)}; **method**: `{res.method}`",
        f"- **Status**: {res.status.value} ({res.nfev} evaluations)",
        *(
            ["- **Warning**: the jitter std contradicts the detection test (section 1)"]
            if rep.cross_check is not None and not rep.cross_check.consistent
            else []
        ),
        f"- jitterid {rep.version}; full numbers in `result.json`",
        "",
        *_order_lines(rep),
        "## 1. Is there jitter?",
        "",
        *_detection_lines(rep, figs),
        "## 2. Estimate",
        "",
        *_table(rep),
        "",
        (
            f"- jitter law: {md_text(law)} "
            f"({'estimated' if isinstance(rep.jitter, JitterFamily) else 'assumed'})"
        ),
        _jitter_std_line(rep),
        _noise_line(rep),
        (
            f"- G(s) numerator {np.array2string(_tf(res).num, precision=5)}, denominator "
            f"{np.array2string(_tf(res).den, precision=5)} (s in rad/s)"
        ),
        "- poles: "
        + ", ".join(
            f"{p.real:.4g}{p.imag:+.4g}i rad/s (|p| = {abs(p) / (2 * np.pi):.4g} Hz)"
            for p in _tf(res).poles
        ),
        "",
        *_quantity_lines(rep),
        "## 3. Frequency and step response",
        "",
        *_image("Bode plot", figs.get("bode")),
        *_image("step response", figs.get("step")),
    ]
    if law.std > 0:
        gain, _ = _try(lambda: (bias_frequency(law, 0.01), ls_gain_factor(law, 0.5 / data.T)))
        if gain is not None:
            fb, g_ny = gain
            ny = 0.5 / data.T
            lines += [
                (
                    f"Under the {'fitted' if isinstance(rep.jitter, JitterFamily) else 'assumed'} "
                    f"jitter law an ordinary fit sees the gain scaled by |φ(f)|: {float(g_ny):.3f} "
                    f"at Nyquist ({ny:g} Hz); the gain bias reaches 1% at {fb:.3g} Hz."
                ),
                "",
            ]
    if "jitter_pdf" in figs:
        lines += ["## 4. Jitter density", "", f"![jitter pdf]({figs['jitter_pdf']})", ""]
        if "jitter_pdf_note" in figs:
            lines += [f"No band is drawn: {md_text(figs['jitter_pdf_note'])}.", ""]
    lines += ["## 5. Residual checks (after fitting)", ""]
    lines += [f"- {md_text(c.summary())}" for c in rep.checks]
    skipped = [
        *rep.skipped,
        *(
            (k[: -len("_skipped")] + " figure", v)
            for k, v in figs.items()
            if k.endswith("_skipped")
        ),
    ]
    lines += [f"- skipped {md_text(name)}: {md_text(why)}" for name, why in skipped]
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
    """Write result.json, report.md and (with ``plots``) the figures into ``out``, each
    atomically; result.json first, so the fit is saved whatever happens after."""
    out.mkdir(parents=True, exist_ok=True)
    text = json.dumps(result_json(rep), indent=2) + "\n"
    atomic_write(out / "result.json", lambda fh: fh.write(text))
    figs = _figures(rep, out) if plots else {}
    md = report_markdown(rep, figs)
    atomic_write(out / "report.md", lambda fh: fh.write(md))
    pngs = [out / v for k, v in figs.items() if v.endswith(".png")]
    return [out / "result.json", out / "report.md", *pngs]


def _tf(res: FitResult) -> TransferFunction:
    """The fitted system of an LTI fit (the command line fits LTI structures only)."""
    if res.system is None:
        raise ValueError("the command line reports LTI fits; this fit is of a signal model")
    return res.system
