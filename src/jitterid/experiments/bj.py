"""Report section and figure of the Box-Jenkins study (``bj.toml``, issue 7).

With coloured noise two things can go wrong for an estimator that assumes white noise: its
spread (efficiency) and its *stated* uncertainty. :func:`uncertainty_section` sets, per
estimator and parameter, the median standard error the fits reported beside the spread of
the estimates over the realizations; their ratio is about 1 for honest error bars.
:func:`spectra_figure` draws the noise spectra of the study: the continuous-time S_v(f) of
(N2), the spectrum of v sampled on the nominal grid (before jitter) and at the jittered
instants (after jitter, from (C1)-(C3)), true and as fitted by each Box-Jenkins estimator,
with the flat level that an OE fit attributes to white noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..io import atomic_write
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..moments.noise_covariance import jittered_autocovariance
from ..noise.models import NoiseModel
from .config import Experiment, split_method
from .store import Estimate

__all__ = ["CAPTION", "spectra_figure", "uncertainty_section"]

CAPTION = (
    "Noise spectra of the Box-Jenkins study, per Hz, over the Nyquist band: the continuous-time "
    "S_v(f) (thin), the spectrum of v sampled on the grid kT (before jitter) and at kT + τ_k "
    "(after jitter, eq. (C1)): true (black) and at the median of each Box-Jenkins estimator's "
    "noise parameters, with the 10-90 % band of the per-realization spectra after jitter; the "
    "dotted lines are the white-noise level σ̂² T of the OE fits that estimate one."
)


def uncertainty_section(exp: Experiment, estimates: Sequence[Estimate]) -> list[str]:
    """Markdown lines: median stated standard error against the Monte Carlo std, per case."""
    lines = [
        "## Stated uncertainty",
        "",
        (
            "Median standard error reported by the fits (`FitResult.stderr`) / standard deviation "
            "of the estimates over the converged realizations: about 1 for honest error bars, "
            "below 1 when an estimator claims more precision than it has. Its own Monte Carlo "
            "error is about 1/√(2n) relative."
        ),
        "",
    ]
    for case in exp.cases:
        noise_names = [n for n, _ in exp.noise.truth] if exp.noise is not None else []
        names = [n for n, _ in exp.system.truth] + noise_names
        lines += [
            f"### Case `{case.name}`",
            "",
            "| estimator | " + " | ".join(names) + " |",
            "|---|" + "---:|" * len(names),
        ]
        for m in exp.methods:
            rows = [
                e for e in estimates if e.case_name == case.name and e.method == m and e.success
            ]
            cells = []
            for p in names:
                est = np.array([e.params.get(p, math.nan) for e in rows])
                se = np.array([e.stderr.get(p, math.nan) for e in rows])
                ok = np.isfinite(est) & np.isfinite(se)
                if ok.sum() < 2:
                    cells.append("—")
                    continue
                spread = float(np.std(est[ok], ddof=1))
                cells.append(f"{float(np.median(se[ok])) / spread:.2f}" if spread > 0 else "—")
            lines.append(f"| {exp.label(m)} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def _fitted(
    exp: Experiment, method: str, rows: Sequence[Estimate]
) -> tuple[list[NoiseModel], list[JitterLaw]]:
    """The noise model and jitter law of every fit of a Box-Jenkins estimator."""
    structure, jitter = exp.noise.structure(), exp.estimation_jitter(exp.cases[0], method)  # type: ignore[union-attr]
    models = [structure.model([e.params[p] for p in structure.param_names]) for e in rows]
    laws = [
        jitter.law([e.params[p] for p in jitter.param_names])
        if isinstance(jitter, JitterFamily)
        else jitter
        for e in rows
    ]
    return models, laws


def spectra_figure(out: str | Path, exp: Experiment, estimates: Sequence[Estimate]) -> Path:
    """PNG ``<out>/<name>_spectra.png`` of the true and fitted noise spectra (module docstring).

    Left: spectra of the sampled noise v_k + w_k per Hz (log-log) before and after jitter,
    true and at the median (over realizations) of each Box-Jenkins estimator's spectra, with
    the 10-90 % band after jitter, and the OE fits' white level. Right: after / before, the
    jitter's own effect on the noise spectrum (|phi|^2 smoothing of the aliased spectrum plus
    the white floor r_v(0) - int S_v |phi|^2 df it creates).
    """
    if exp.noise is None:
        raise ValueError(
            f"experiment {exp.name!r} has no [noise] section: no noise spectra to draw"
        )
    T, case = exp.T, exp.cases[0]
    law = case.law.build()
    f = np.geomspace(2e-3 / T, 0.5 / T, 300)
    truth = exp.noise.true_model()
    fig = Figure(figsize=(12, 5))
    ax, axr = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    white = exp.noise_std**2 * T  # the white part w_k adds a flat sigma_w^2 T
    before = jittered_autocovariance(truth, NoJitter(), T).spectrum(f) + white
    after = jittered_autocovariance(truth, law, T).spectrum(f) + white
    ax.loglog(f, truth.spectrum(f), "k:", lw=1.0, label="true S_v(f), continuous time")
    ax.loglog(f, before, "k--", lw=1.5, label="true, sampled at kT (before jitter)")
    ax.loglog(f, after, "k", lw=2.5, label="true, sampled at kT + τ_k (after jitter)")
    axr.semilogx(f, after / before, "k", lw=2.5, label="true")
    for i, m in enumerate(exp.methods):
        rows = [e for e in estimates if e.case_name == case.name and e.method == m and e.success]
        if not rows:
            continue
        colour = f"C{i % 10}"
        if not split_method(m)[0]:
            levels = [e.noise_std for e in rows if np.isfinite(e.noise_std) and e.noise_std > 0]
            if levels and not exp.noise_known:
                ax.axhline(
                    float(np.median(levels)) ** 2 * T,
                    color=colour,
                    ls=":",
                    lw=1.2,
                    label=f"{exp.label(m)}: white level σ̂² T (median)",
                )
            continue
        models, laws = _fitted(exp, m, rows)
        floor = np.array([e.noise_std**2 * T for e in rows])[:, None]
        fit_after = (
            np.array(
                [
                    jittered_autocovariance(nm, jl, T).spectrum(f)
                    for nm, jl in zip(models, laws, strict=True)
                ]
            )
            + floor
        )
        fit_before = (
            np.array([jittered_autocovariance(nm, NoJitter(), T).spectrum(f) for nm in models])
            + floor
        )
        band = np.percentile(fit_after, [10, 50, 90], axis=0)
        ax.fill_between(f, band[0], band[2], color=colour, alpha=0.12, lw=0)
        ax.loglog(f, band[1], color=colour, lw=1.5, label=f"{exp.label(m)}: fitted, after jitter")
        ax.loglog(
            f,
            np.median(fit_before, axis=0),
            color=colour,
            ls="--",
            lw=1.0,
            label=f"{exp.label(m)}: fitted, before",
        )
        axr.semilogx(
            f, np.median(fit_after / fit_before, axis=0), color=colour, lw=1.2, label=exp.label(m)
        )
    ax.set(xlabel="frequency f (Hz)", ylabel="noise power spectral density (1/Hz)")
    ax.set_title("noise spectra: true and fitted (median, 10-90 % band)", fontsize=9)
    axr.set(xlabel="frequency f (Hz)", ylabel="after / before jitter")
    axr.set_title("the jitter's effect on the sampled noise spectrum", fontsize=9)
    for a in (ax, axr):
        a.set_xlim(f[0], f[-1])
        a.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6.5, loc="lower left")
    axr.legend(fontsize=7, loc="best")
    path = Path(out) / f"{exp.name}_spectra.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=120, format="png"), binary=True)
    return path
