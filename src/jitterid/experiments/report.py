"""Monte Carlo summaries and Markdown reports, with the paper's numbers side by side.

For every case, estimator and parameter the report gives the mean, the standard deviation
and the standard error of the mean (SEM = std / sqrt(n)) over the converged fits, the
paper's mean and std where it has them (``data/paper_tables.csv``, transcribed from the
paper), and flags every difference beyond Monte Carlo error: |z| > 3, where z divides the
difference by the combined standard errors of both studies (the paper's: its std / sqrt(128)
for a mean, std / sqrt(2 * 127) for a std, the latter exact only for normal estimates).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from .._markdown import md_code, md_text
from .bj import uncertainty_section
from .config import Case, Experiment
from .store import Estimate

__all__ = [
    "Stat",
    "Summary",
    "bound_roots",
    "failures",
    "markdown_report",
    "nothing_converged",
    "paper_numbers",
    "summarize",
    "true_values",
]

PAPER_RUNS = 128
Z_FLAG = 3.0


@dataclass(frozen=True)
class Stat:
    """Sample statistics of one parameter over n converged fits."""

    n: int
    mean: float
    std: float

    @property
    def sem(self) -> float:
        return self.std / math.sqrt(self.n) if self.n > 0 else math.nan

    @classmethod
    def of(cls, values: Sequence[float]) -> Stat:
        v = np.asarray(values, dtype=float)
        if v.size == 0:
            return cls(0, math.nan, math.nan)
        return cls(int(v.size), float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else math.nan)


@dataclass(frozen=True)
class Summary:
    """One estimator on one case: statistics per parameter and how the fits ended."""

    stats: dict[str, Stat]
    total: int
    converged: int
    errors: int
    median_fit_s: float


def _values(e: Estimate, family: bool) -> dict[str, float]:
    return {**e.params, "sigma": e.jitter_std} if family else dict(e.params)


def bound_roots(exp: Experiment, estimates: Sequence[Estimate]) -> dict[str, dict[str, float]]:
    """sqrt(mean of the CRB diagonal over realizations) per case and parameter.

    Each ``crb`` row is the bound of its realization's input (the inverse of that input's
    Fisher information); the mean is over the bounds of realizations
    ``0 .. exp.bound_runs() - 1`` (the first ``crb_runs``), whatever else the store holds,
    so that the row does not depend on how the store was filled (``--no-share`` stores
    every realization's bound). It is not the inverse of a mean Fisher information, which
    would be smaller (Jensen): the per-input bound is what the estimators, each fitted to
    one input, are compared with."""
    out: dict[str, dict[str, float]] = {}
    last = exp.bound_runs()
    for case in exp.cases:
        rows = [
            e
            for e in estimates
            if e.case_name == case.name and e.method == "crb" and e.success and e.realization < last
        ]
        if rows:
            out[case.name] = {
                p: float(np.sqrt(np.mean([e.stderr[p] ** 2 for e in rows]))) for p in rows[0].stderr
            }
    return out


def summarize(exp: Experiment, estimates: Sequence[Estimate]) -> dict[tuple[str, str], Summary]:
    """Statistics per (case name, method) over the converged fits (``success``)."""
    family = exp.jitter_model != "known"
    out = {}
    for case in exp.cases:
        for m in exp.methods:
            rows = [e for e in estimates if e.case_name == case.name and e.method == m]
            ok = [_values(e, family) for e in rows if e.success]
            names = list(ok[0]) if ok else []
            out[case.name, m] = Summary(
                stats={p: Stat.of([v[p] for v in ok]) for p in names},
                total=len(rows),
                converged=len(ok),
                errors=sum(e.status == "ERROR" for e in rows),
                median_fit_s=float(np.median([e.elapsed_s for e in rows])) if rows else math.nan,
            )
    return out


def nothing_converged(exp: Experiment, estimates: Sequence[Estimate]) -> bool:
    """True when the estimators were run and not one of their fits converged (a run that
    produced nothing: ``jitterid run``/``reproduce`` then exit with status 3)."""
    summ = summarize(exp, estimates)
    return sum(s.total for s in summ.values()) > 0 and not any(s.converged for s in summ.values())


def failures(exp: Experiment, estimates: Sequence[Estimate]) -> list[str]:
    """The report's first lines when an estimator has no converged fit on a case (empty if
    every one has some): how many fits ended how, and the most frequent message."""
    summ = summarize(exp, estimates)
    empty = [(c, m) for (c, m), s in summ.items() if s.total and not s.converged]
    if not empty:
        return []
    total = sum(s.total for s in summ.values())
    head = (
        f"**No fit converged: all {total} fits failed**, so there are no statistics below."
        if nothing_converged(exp, estimates)
        else "**Some estimators have no converged fit** on some cases (their rows below are "
        "empty): " + ", ".join(f"{exp.label(m)} on `{md_text(c)}`" for c, m in empty) + "."
    )
    rows = [
        e for e in estimates if (e.case_name, e.method) in set(empty) and e.realization < exp.runs
    ]
    counts: dict[str, int] = {}
    messages: dict[str, int] = {}
    for e in rows:
        counts[e.status] = counts.get(e.status, 0) + 1
        if e.message:
            messages[e.message] = messages.get(e.message, 0) + 1
    lines = [
        head,
        "",
        "- How they ended: "
        + ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
        + ".",
    ]
    if messages:
        top = max(messages, key=lambda k: messages[k])
        lines.append(f"- Most frequent message ({messages[top]}): {md_text(top[:300])}")
    return [*lines, ""]


def true_values(exp: Experiment, case: Case) -> dict[str, float]:
    """theta0 of a case: the system's truth, and for a free jitter family its true
    parameters (when the true law is a member) and sigma; with coloured noise also the
    noise parameters, the white ``noise_std`` if it is estimated, and the jitter law's
    parameters if a ``jbj-`` estimator fits its family."""
    truth = dict(exp.system.truth)
    if exp.noise is not None:
        truth.update(exp.noise.truth)
        if not exp.noise_known:
            truth["noise_std"] = exp.noise_std
        if any(m.startswith("jbj-") for m in exp.methods):
            truth = {**dict(case.law.params), **truth}
    if exp.jitter_model == "known":
        return truth
    law = case.law.build()
    jitter = dict(case.law.params) if case.law.kind == exp.jitter_model else {}
    return {**jitter, **truth, "sigma": float(law.std)}


@cache
def _paper_rows() -> tuple[tuple[int, int, str, str, str, float], ...]:
    text = (resources.files("jitterid.experiments") / "data" / "paper_tables.csv").read_text()
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return tuple(
        (
            int(r["table"]),
            int(r["case"]),
            r["estimator"],
            r["statistic"],
            r["parameter"],
            float(r["value"]),
        )
        for r in csv.DictReader(lines)
    )


def paper_numbers(table: int) -> dict[tuple[int, str, str, str], float]:
    """The paper's numbers of one table: ``{(case, estimator, statistic, parameter): value}``
    with statistic ``mean`` or ``std`` (estimator ``-``, statistic ``true`` for theta0)."""
    return {(c, e, s, p): v for t, c, e, s, p, v in _paper_rows() if t == table}


def _z(a: float, b: float, se_a: float, se_b: float) -> float:
    se = math.hypot(se_a, 0.0 if math.isnan(se_b) else se_b)
    return (a - b) / se if se > 0 else math.nan


def _fmt(x: float | None) -> str:
    return "—" if x is None or math.isnan(x) else f"{x:.4f}"


def _case_block(
    exp: Experiment,
    case: Case,
    summ: dict[tuple[str, str], Summary],
    bound: dict[str, float] | None,
) -> list[str]:
    paper = paper_numbers(exp.paper_table) if exp.paper_table and case.paper_case else {}
    truth = true_values(exp, case)
    names: list[str] = []
    for m in exp.methods:
        names += [p for p in summ[case.name, m].stats if p not in names]
    ref = f" (paper case {case.paper_case})" if case.paper_case and exp.paper_table else ""
    law = case.law.build()
    lines = [
        f"### Case `{case.name}`{ref}",
        "",
        f"True jitter law: {law}.",
        "",
        "| estimator | statistic | " + " | ".join(names) + " |",
        "|---|---|" + "---:|" * len(names),
        "| θ⁰ | true | " + " | ".join(_fmt(truth.get(p)) for p in names) + " |",
    ]
    if bound:
        lines.append(
            f"| CRB | √(mean bound), first {exp.bound_runs()} inputs | "
            + " | ".join(_fmt(bound.get(p)) for p in names)
            + " |"
        )
    flags: list[str] = []
    for m in exp.methods:
        s, label = summ[case.name, m], exp.label(m)
        key = (case.paper_case or 0, label)
        pm = {p: paper.get((*key, "mean", p)) for p in names}
        ps = {p: paper.get((*key, "std", p)) for p in names}
        cells_m, cells_s, cells_b = [], [], []
        for p in names:
            st = s.stats.get(p, Stat(0, math.nan, math.nan))
            cm, cs = f"{_fmt(st.mean)} ± {_fmt(st.sem)}", _fmt(st.std)
            if pm[p] is not None:
                psem = (ps[p] or math.nan) / math.sqrt(PAPER_RUNS)
                z = _z(st.mean, pm[p], st.sem, psem)  # type: ignore[arg-type]
                if abs(z) > Z_FLAG:
                    cm, flags = f"**{cm}** ⚑", [*flags, f"{label} mean of {p}: z = {z:+.1f}"]
            if ps[p] is not None and st.n > 1:
                se_s = st.std / math.sqrt(2 * (st.n - 1))
                z = _z(st.std, ps[p], se_s, ps[p] / math.sqrt(2 * (PAPER_RUNS - 1)))  # type: ignore[arg-type, operator]
                if abs(z) > Z_FLAG:
                    cs, flags = f"**{cs}** ⚑", [*flags, f"{label} std of {p}: z = {z:+.1f}"]
            cells_m.append(cm)
            cells_s.append(cs)
            tv = truth.get(p)
            cells_b.append(
                f"{(st.mean - tv) / st.sem:+.1f}" if tv is not None and st.sem > 0 else "—"
            )
        name = f"{md_text(label)} (`{m}`)" if label != m else f"`{m}`"
        in_paper = bool(paper) and label != m
        if in_paper:
            lines.append(
                f"| {name} | mean, paper | " + " | ".join(_fmt(pm[p]) for p in names) + " |"
            )
        lines.append(f"| {name} | mean ± SEM, here | " + " | ".join(cells_m) + " |")
        if in_paper:
            lines.append(
                f"| {name} | std, paper | " + " | ".join(_fmt(ps[p]) for p in names) + " |"
            )
        lines.append(f"| {name} | std, here | " + " | ".join(cells_s) + " |")
        lines.append(f"| {name} | (mean − θ⁰) / SEM, here | " + " | ".join(cells_b) + " |")
        if bound:
            eff = [
                _fmt(s.stats[p].std / bound[p]) if p in s.stats and bound.get(p) else "—"
                for p in names
            ]
            lines.append(f"| {name} | std / √CRB, here | " + " | ".join(eff) + " |")
    lines += [
        "",
        "| estimator | converged / run | errors | median fit time (s) |",
        "|---|---:|---:|---:|",
    ]
    for m in exp.methods:
        s = summ[case.name, m]
        lines.append(
            f"| {exp.label(m)} | {s.converged} / {s.total} | {s.errors} | {s.median_fit_s:.2f} |"
        )
    if flags:
        lines += [
            "",
            "Beyond Monte Carlo error (|z| > 3) against the paper: " + "; ".join(flags) + ".",
        ]
    elif paper and any(summ[case.name, m].converged for m in exp.methods):
        lines += ["", "No difference from the paper beyond Monte Carlo error (|z| > 3)."]
    elif paper:
        lines += ["", "Nothing to compare with the paper: no fit converged."]
    return [*lines, ""]


def _status_counts(exp: Experiment, estimates: Sequence[Estimate]) -> list[str]:
    """One line: how each estimator's fits ended over every case (status: count), so that a
    reader sees at once over how many fits the statistics below are."""
    per: dict[str, dict[str, int]] = {m: {} for m in exp.methods}
    for e in estimates:
        if e.method in per and e.realization < exp.runs:
            per[e.method][e.status] = per[e.method].get(e.status, 0) + 1
    parts = []
    for m, counts in per.items():
        if counts:
            total = sum(counts.values())
            ended = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
            parts.append(f"{md_text(exp.label(m))} {ended} (of {total})")
    return ["- How the fits ended, all cases: " + "; ".join(parts) + "."] if parts else []


def markdown_report(
    exp: Experiment, estimates: Sequence[Estimate], command: str, wall_note: str = ""
) -> str:
    """The Markdown report of one experiment (see the module docstring)."""
    summ = summarize(exp, estimates)
    bounds = bound_roots(exp, estimates)
    methods = ", ".join(
        f"{md_text(exp.label(m))} (`{m}`)" if exp.label(m) != m else f"`{m}`" for m in exp.methods
    )
    lines = [
        f"# {md_text(exp.title)}",
        "",
        *failures(exp, estimates),
        f"Generated by {md_code(command)}"
        + (f" ({md_text(wall_note)})" if wall_note else "")
        + ".",
        "",
        "\n".join(md_text(line) for line in exp.description.strip().splitlines()),
        "",
        (
            f"- Settings: T = {exp.T:g} s, N = {exp.N}, noise std {exp.noise_std:g}"
            f" ({'known' if exp.noise_known else 'estimated'}), input `{exp.input.kind}`, "
            f"{exp.runs} realizations per case, seed {exp.seed}."
        ),
        f"- Estimators: {methods}.",
        f"- Jitter model: `{exp.jitter_model}` {dict(exp.jitter_options) or ''}".rstrip() + ".",
        *(
            [
                (
                    f"- Coloured noise v(t): H(s) = {exp.noise.true_model().tf}, std of v "
                    f"{exp.noise.true_model().variance ** 0.5:.4g}, added to the white noise above."
                )
            ]
            if exp.noise is not None
            else []
        ),
        *_status_counts(exp, estimates),
        (
            "- Statistics over the converged fits; SEM = std/√n. ⚑ marks a difference from the "
            "paper beyond Monte Carlo error (|z| > 3 with both studies' standard errors; the paper "
            "used 128 realizations). The last row of each estimator is the bias in SEMs."
        ),
        "",
    ]
    for case in exp.cases:
        lines += _case_block(exp, case, summ, bounds.get(case.name))
    if exp.noise is not None:  # coloured noise: are the stated error bars honest?
        lines += uncertainty_section(exp, estimates)
    return "\n".join(lines).rstrip() + "\n"
