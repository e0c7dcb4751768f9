"""The paper's Figures 1-5 as PNG files (matplotlib, object-oriented API: no pyplot state).

Figures 1-4 are computed from the library's formulas; Figure 5 from the Table 2 Monte Carlo
results. Every function takes the output folder and returns the path of the PNG.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..inputs import telegraph_input
from ..io import atomic_write
from ..jitter.laws import Gaussian, NoJitter, SumOfUniforms, Uniform
from ..moments.reference import dirichlet, expected_dft_lines
from ..simulate import simulate
from ..systems.tf import TransferFunction
from .config import Experiment
from .report import summarize
from .store import Estimate

__all__ = ["CAPTIONS", "figure1", "figure2", "figure3", "figure4", "figure5"]

CAPTIONS = {
    "fig1": "Figure 1: |d_N(f)|/N of (7) (T = 2 s, N = 10) and |φ(f)| of (15a) U(−1, 1) and "
    "(15b) N(0, 1/3); the dots mark f = 0.14 and 0.64 Hz used in Figure 2.",
    "fig2": "Figure 2: |E[Y_d(f)]| of s(t) = sin(2π f0 t), T = 2 s, N = 10, from Lemma 1: "
    "(a) f0 = 0.14 and (b) f0 = 0.64 Hz without jitter overlap; (c) and (d) with "
    "jitter U(−1, 1) differ.",
    "fig3": "Figure 3: a realization of the paper's PRBS u(t) and the output s(t) of "
    "G(s) = 1/(s+2) in continuous time, with the jittered samples (T = 1 s, U(−T/2, T/2), "
    "noise std 0.01).",
    "fig4": "Figure 4: pdf of the family (26) with a = T/2 (T = 1 s) for several n (solid) and "
    "Gaussians of equal variance (dashed).",
    "fig5": "Figure 5: |G(i2πf)| of (27) at the true θ⁰ and at the Monte Carlo mean of the LS, "
    "BCLS and AsML estimates of Table 2.",
}
_FIG3_SEED = 3  # fixed: the figure shows one reproducible realization


def _save(fig: Figure, out: str | Path, name: str) -> Path:
    path = Path(out) / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=120, format="png"), binary=True)
    return path


def figure1(out: str | Path) -> Path:
    """Dirichlet kernel (7) and the characteristic functions (15a), (15b)."""
    T, N = 2.0, 10
    f = np.linspace(-1.0, 1.0, 2001)
    uni, gau = Uniform(1.0), Gaussian(np.sqrt(1.0 / 3.0))
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    ax.plot(
        f, np.abs(dirichlet(f, N, T)) / N, "k", lw=2.5, label=f"|d_N(f)|/N, T = {T:g} s, N = {N}"
    )
    ax.plot(f, np.abs(uni.cf(f)), "C0", lw=1, label="|φ(f)|, τ ~ U(−1, 1)  (15a)")
    ax.plot(f, np.abs(gau.cf(f)), "C1--", lw=1.5, label="|φ(f)|, τ ~ N(0, 1/3)  (15b)")
    f0 = np.array([0.14, 0.64])
    ax.plot(f0, np.abs(uni.cf(f0)), "o", color="C0", ms=7, label="φ at f = 0.14, 0.64 Hz")
    ax.set(xlabel="frequency f (Hz)", ylabel="magnitude (dimensionless)", ylim=(0, 1.35))
    ax.legend(fontsize=8, loc="upper center", ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, out, "fig1")


def figure2(out: str | Path) -> Path:
    """|E[Y_d(f)]| of the alias example (16a)-(16d)."""
    T, N = 2.0, 10
    f = np.linspace(0.0, 1.0, 2001)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    styles = [
        ("(a)", 0.14, NoJitter(), "k-", 3.0),
        ("(b)", 0.64, NoJitter(), "y:", 1.5),
        ("(c)", 0.14, Uniform(1.0), "C0-", 1.0),
        ("(d)", 0.64, Uniform(1.0), "C3--", 1.5),
    ]
    for tag, f0, law, style, lw in styles:
        lines = np.array([f0, -f0])
        coeffs = np.array([1 / 2j, -1 / 2j])
        mu = expected_dft_lines(lines, coeffs, law, T, N, f)
        what = "no jitter" if isinstance(law, NoJitter) else "τ ~ U(−1, 1)"
        ax.plot(f, np.abs(mu), style, lw=lw, label=f"{tag} f0 = {f0} Hz, {what}")
    ax.set(xlabel="frequency f (Hz)", ylabel="|E[Y_d(f)]| (units of s(t))", ylim=(0, 6.2))
    ax.legend(fontsize=8, loc="upper center", ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, out, "fig2")


def figure3(out: str | Path) -> Path:
    """A PRBS input, the continuous-time output of 1/(s+2) and its jittered samples."""
    rng = np.random.default_rng(_FIG3_SEED)
    g, T, N = TransferFunction(np.array([1.0]), np.array([1.0, 2.0])), 1.0, 30
    u = telegraph_input(N * T + 2, rng)
    data = simulate(g, u, Uniform(T / 2), T, N, 0.01, rng)
    t = np.linspace(0.0, N * T, 3001)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    ax.plot(t, u(t), "C7", lw=1, label="input u(t) (PRBS, ±0.5)")
    ax.plot(t, g.response(u)(t), "k", lw=2.5, label="output s(t) of G(s) = 1/(s+2)")
    instants = data.instants if data.instants is not None else data.t_nominal
    ax.plot(instants, data.y, "o", color="C3", ms=4, label="jittered samples y_k")
    ax.set(xlabel="time t (s)", ylabel="amplitude (input units)", xlim=(0, N * T))
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    return _save(fig, out, "fig3")


def figure4(out: str | Path, orders: Sequence[int] = (0, 1, 2, 4, 9)) -> Path:
    """pdfs of the family (26) with a = T/2 and Gaussians of equal variance."""
    T = 1.0
    tau = np.linspace(-0.6, 0.6, 1201)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    for i, n in enumerate(orders):
        law = SumOfUniforms(n, T / 2)
        ax.plot(tau, law.pdf(tau), color=f"C{i}", lw=1.5, label=f"n = {n}, σ = {law.std:.3f} s")
        if n >= 1:
            ax.plot(tau, Gaussian(law.std).pdf(tau), "--", color=f"C{i}", lw=1)
    ax.plot([], [], "k--", lw=1, label="Gaussian, same variance")
    ax.set(xlabel="jitter τ (s)", ylabel="pdf p(τ) (1/s)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, out, "fig4")


def figure5(out: str | Path, exp: Experiment, estimates: Sequence[Estimate]) -> Path:
    """|G| at the truth and at the mean estimates of a Table-2-like experiment."""
    summ = summarize(exp, estimates)
    case = exp.cases[0]
    f = np.linspace(0.0, 0.5, 1001)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    ax.plot(f, np.abs(exp.system.true_system().frequency_response(f)), "k", lw=3, label="true θ⁰")
    styles = {"ls": ("C3-", 1.2), "bcls": ("C0--", 1.5), "asml-diag": ("C2:", 2.0)}
    model = exp.system.model()
    for m, (style, lw) in styles.items():
        if m not in exp.methods or isinstance(model, TransferFunction):
            continue
        stats = summ[case.name, m].stats
        theta = [stats[p].mean for p in model.param_names]
        g = model.system(theta)
        ax.plot(
            f,
            np.abs(g.frequency_response(f)),
            style,
            lw=lw,
            label=f"θ = mean of {exp.label(m)} ({stats[model.param_names[0]].n} fits)",
        )
    ax.set(xlabel="frequency f (Hz)", ylabel="|G(i2πf)| (output/input, dimensionless)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    return _save(fig, out, "fig5")
