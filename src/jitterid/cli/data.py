"""Commands from a data file to a trusted model: ``simulate``, ``detect``, ``fit``, ``bias``.

``jitterid simulate --out lab`` writes a synthetic data set (the paper's setting by default)
in the format :func:`jitterid.load` reads; ``jitterid detect`` tests a data set for jitter;
``jitterid fit`` estimates a model and writes result.json, report.md and figures;
``jitterid bias`` predicts the gain bias of an ordinary fit under a jitter law.
Every error ends in a one-line message and a non-zero exit (2 for bad usage, 1 for
unusable data, 3 for a fit that did not converge), never a traceback.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import click
import numpy as np

from ..analysis.diagnostics import (
    bias_frequency,
    detect_jitter,
    input_correlation_test,
    ljung_box,
    ls_gain_factor,
    standardized_residuals,
)
from ..estimation.fit import fit as fit_model
from ..estimation.problem import METHODS
from ..inputs import telegraph_input, zoh_input
from ..io import Dataset, load, save_data, save_input
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..simulate import simulate as simulate_data
from . import main
from ._report import FitReport, write_outputs
from ._specs import JITTER_HELP, model_label, parse_floats, parse_jitter, parse_model

__all__ = ["bias", "detect", "fit", "simulate"]

MODEL_HELP = "polepair (k0 / ((s - pr)^2 + pi^2)) or tf:NUM,DEN (NUM zeros, DEN poles, e.g. tf:0,2)"
_PAPER_PARAMS = "6.25,-1.5,2"


@contextmanager
def _clean_errors(what: str) -> Iterator[None]:
    """Turn the library's ValueError/TypeError/OSError into a one-line click error."""
    try:
        yield
    except click.ClickException:
        raise
    except (ValueError, TypeError, OSError, ImportError) as exc:
        raise click.ClickException(f"{what}: {exc}") from None


@contextmanager
def _param(hint: str) -> Iterator[None]:
    """Turn a ValueError/TypeError while parsing option ``hint`` into a usage error."""
    try:
        yield
    except (ValueError, TypeError) as exc:
        raise click.BadParameter(str(exc), param_hint=hint) from None


def _law(spec: str) -> JitterLaw:
    with _param("'--jitter'"):
        law = parse_jitter(spec, law_only=True)
    assert isinstance(law, JitterLaw)
    return law


def _positive(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be finite and > 0; got {value!r}")
    return value


def _nonneg(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not (math.isfinite(value) and value >= 0):
        raise click.BadParameter(f"must be finite and >= 0; got {value!r}")
    return value


def _level(ctx: click.Context, param: click.Parameter, value: float) -> float:
    if not (0 < value < 1):
        raise click.BadParameter(f"must be in (0, 1), e.g. 0.95; got {value!r}")
    return value


_data_arg = click.argument("data_path", metavar="DATA", type=click.Path(dir_okay=False))
_input_opt = click.option(
    "--input",
    "input_path",
    type=click.Path(dir_okay=False),
    help="Input file: columns t,u / k,u (zero-order hold on the grid) or time,level (switches). "
    "Not needed if DATA has a 'u' column.",
)
_model_opt = click.option("--model", "model_spec", required=True, help=MODEL_HELP)
_T_opt = click.option(
    "--T",
    "T",
    type=float,
    callback=_positive,
    help="Nominal sampling interval, if DATA has an index column k and no T metadata.",
)


def _load(data_path: str, input_path: str | None, T: float | None, noise: float | None) -> Dataset:
    with _clean_errors("cannot use the data"):
        return load(data_path, input_path, T=T, noise_std=noise)


# ------------------------------------------------------------------------------ simulate


@main.command(short_help="Write a synthetic jittered data set (the paper's setting).")
@click.option(
    "--out", "out", required=True, type=click.Path(file_okay=False), help="Output directory."
)
@click.option("--model", "model_spec", default="polepair", show_default=True, help=MODEL_HELP)
@click.option(
    "--params",
    default=_PAPER_PARAMS,
    show_default=True,
    help="True parameters, comma-separated, in the model's order (polepair: k0,pr,pi).",
)
@click.option(
    "--jitter",
    "jitter_spec",
    default="uniform:a=0.5",
    show_default=True,
    help="True jitter law: none | uniform:a=A | gaussian:sigma=S | sum-of-uniforms:n=N,a=A.",
)
@click.option("--N", "n_samples", type=click.IntRange(min=4), default=200, show_default=True)
@click.option("--T", "T", type=float, default=1.0, show_default=True, callback=_positive)
@click.option("--noise-std", type=float, default=0.01, show_default=True, callback=_nonneg)
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option(
    "--input-kind",
    type=click.Choice(["telegraph", "zoh"]),
    default="telegraph",
    show_default=True,
    help="telegraph: the paper's random +-amplitude switching, saved as switch times; "
    "zoh: the same sampled on the grid and held (a DAC), saved as t,u.",
)
@click.option(
    "--hold", type=float, default=1.0, show_default=True, callback=_positive, help="Mean hold (s)."
)
@click.option("--amplitude", type=float, default=0.5, show_default=True, callback=_positive)
@click.option(
    "--format", "fmt", type=click.Choice(["csv", "npz"]), default="csv", show_default=True
)
def simulate(
    out: str,
    model_spec: str,
    params: str,
    jitter_spec: str,
    n_samples: int,
    T: float,
    noise_std: float,
    seed: int,
    input_kind: str,
    hold: float,
    amplitude: float,
    fmt: str,
) -> None:
    """Write a synthetic jittered data set (data, input, truth.json) into OUT.

    Defaults are the paper's Section 5.2 setting: G = 6.25 / ((s + 1.5)^2 + 4), T = 1 s,
    N = 200, telegraph input +-0.5 with mean hold 1 s, jitter U(-0.5, 0.5), noise std 0.01.
    """
    with _param("'--model'"):
        structure = parse_model(model_spec)
    law = _law(jitter_spec)
    with _param("'--params'"):
        theta = parse_floats(params, "--params")
        system = structure.system(theta)
    with _clean_errors("cannot simulate"):
        rng = np.random.default_rng(seed)
        reach = (n_samples - 1) * T + max(law.support[1], 0.0)
        if input_kind == "telegraph":
            u = telegraph_input(reach + T, rng, levels=(-amplitude, amplitude), mean_hold=hold)
        else:
            m = math.ceil(reach / T) + 1
            tele = telegraph_input(m * T, rng, levels=(-amplitude, amplitude), mean_hold=hold)
            u = zoh_input(tele(T * np.arange(m)), T)
        data = simulate_data(system, u, law, T, n_samples, noise_std, rng)
        out_dir = Path(out)
        data_file = save_data(out_dir / f"data.{fmt}", data)
        input_file = save_input(out_dir / f"input.{fmt}", u, T=T if input_kind == "zoh" else None)
        truth = {
            "model": model_spec,
            "param_names": list(structure.param_names),
            "params": dict(zip(structure.param_names, theta, strict=True)),
            "system": {"num": system.num.tolist(), "den": system.den.tolist()},
            "jitter": {
                "spec": jitter_spec,
                "law": type(law).__name__,
                **law.params,
                "std": law.std,
            },
            "noise_std": noise_std,
            "N": n_samples,
            "T": T,
            "seed": seed,
            "input_kind": input_kind,
        }
        (out_dir / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    click.echo(f"wrote {data_file}, {input_file} and {out_dir / 'truth.json'}")
    click.echo(f"  {n_samples} samples, T = {T:g} s, jitter {law}, noise std {noise_std:g}")


# ------------------------------------------------------------------------------ detect


@main.command(short_help="Test DATA for sampling jitter before fitting.")
@_data_arg
@_input_opt
@_model_opt
@_T_opt
@click.option("--level", type=float, default=0.95, show_default=True, callback=_level)
@click.option(
    "--plot", "plot_path", type=click.Path(dir_okay=False), help="Write the residual plot (PNG)."
)
def detect(
    data_path: str,
    input_path: str | None,
    model_spec: str,
    T: float | None,
    level: float,
    plot_path: str | None,
) -> None:
    """Test DATA for sampling jitter before fitting.

    Fits the model ignoring jitter, regresses the squared residuals on the squared model
    slope and prints the one-sided p-value and the implied jitter std.
    """
    with _param("'--model'"):
        structure = parse_model(model_spec)
    ds = _load(data_path, input_path, T, None)
    with _clean_errors("the ordinary fit failed"):
        ls = fit_model(ds.data, structure, NoJitter(), "ls")
        det = detect_jitter(ds.data, ls, level=level)
    click.echo(f"ordinary LS fit (jitter ignored): {ls.status.value}")
    click.echo(
        "  " + ", ".join(f"{k} = {v:.5g} ± {ls.stderr[k]:.2g}" for k, v in ls.params.items())
    )
    click.echo(det.summary())
    if plot_path:
        from matplotlib.figure import Figure

        from ..plots import plot_residuals

        with _clean_errors("cannot write the plot"):
            fig = Figure(figsize=(6.4, 6.0), layout="constrained")
            plot_residuals(det, ax=fig.subplots(2, 1))
            fig.savefig(plot_path, dpi=110)
        click.echo(f"wrote {plot_path}")


# ------------------------------------------------------------------------------ fit


@main.command(short_help="Fit a model to DATA accounting for jitter; write a report.")
@_data_arg
@_input_opt
@_model_opt
@click.option("--jitter", "jitter_spec", required=True, help=JITTER_HELP)
@click.option("--method", type=click.Choice(METHODS), default="bcls", show_default=True)
@click.option(
    "--noise-std", type=float, callback=_nonneg, help="Known measurement-noise std (y units)."
)
@_T_opt
@click.option(
    "--out", "out", required=True, type=click.Path(file_okay=False), help="Output directory."
)
@click.option("--level", type=float, default=0.95, show_default=True, callback=_level)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="For the pdf band draws.",
)
@click.option("--plots/--no-plots", default=True, show_default=True)
def fit(
    data_path: str,
    input_path: str | None,
    model_spec: str,
    jitter_spec: str,
    method: str,
    noise_std: float | None,
    T: float | None,
    out: str,
    level: float,
    seed: int,
    plots: bool,
) -> None:
    """Fit a continuous-time model to DATA, accounting for sampling jitter.

    Prints a summary and writes OUT/result.json (parameters, standard errors, covariance,
    jitter law, method, data checksum, library version), OUT/report.md and its figures.
    Exits with status 3 if the search did not converge (the outputs are still written).
    """
    from .. import __version__

    with _param("'--model'"):
        structure = parse_model(model_spec)
    with _param("'--jitter'"):
        jitter = parse_jitter(jitter_spec)
    if method == "ls" and isinstance(jitter, JitterFamily):
        raise click.UsageError(
            "--method ls ignores jitter, so it cannot estimate a jitter family; use another "
            "method, or --jitter none / a known law"
        )
    ds = _load(data_path, input_path, T, noise_std)
    with _clean_errors("the fit failed"):
        ls = fit_model(ds.data, structure, NoJitter(), "ls")
        res = ls if method == "ls" else fit_model(ds.data, structure, jitter, method)
        det = detect_jitter(ds.data, ls, level=level)
        z = standardized_residuals(ds.data, res)
        checks = (
            ljung_box(z),
            input_correlation_test(z, ds.data.u(ds.data.t_nominal)),
        )
    rep = FitReport(
        dataset=ds,
        structure=structure,
        model_spec=model_spec,
        model_label=model_label(structure),
        jitter_spec=jitter_spec,
        jitter=jitter,
        result=res,
        ordinary=ls,
        detection=det,
        checks=checks,
        level=level,
        seed=seed,
        version=__version__,
    )
    with _clean_errors("cannot write the results"):
        written = write_outputs(rep, Path(out), plots=plots)
    click.echo(res.summary())
    click.echo(det.summary())
    for c in checks:
        click.echo(c.summary())
    click.echo("wrote " + ", ".join(str(p) for p in written))
    if not res.success:
        click.echo(f"error: the fit did not converge: {res.status.value}", err=True)
        raise click.exceptions.Exit(3)


# ------------------------------------------------------------------------------ bias


@main.command(short_help="Predict an ordinary fit's gain bias |phi(f)| under jitter.")
@click.option(
    "--jitter",
    "jitter_spec",
    required=True,
    help="Jitter law: uniform:a=A | gaussian:sigma=S | sum-of-uniforms:n=N,a=A (known: optional).",
)
@click.option(
    "--T",
    "T",
    type=float,
    default=1.0,
    show_default=True,
    callback=_positive,
    help="Sets Nyquist 1/(2T).",
)
@click.option(
    "--fmax", type=float, callback=_positive, help="Highest frequency (Hz); default Nyquist."
)
@click.option("--points", type=click.IntRange(min=2, max=1000), default=11, show_default=True)
@click.option(
    "--tol",
    type=float,
    default=0.01,
    show_default=True,
    callback=_level,
    help="Tolerated gain bias.",
)
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Write |phi(f)| (PNG).")
def bias(
    jitter_spec: str, T: float, fmax: float | None, points: int, tol: float, plot_path: str | None
) -> None:
    """Predict the gain bias of an ordinary (jitter-ignoring) fit: |G| is seen as |G| |phi(f)|."""
    law = _law(jitter_spec)
    top = fmax if fmax is not None else 0.5 / T
    f = np.linspace(0.0, top, points)
    g = ls_gain_factor(law, f)
    click.echo(f"LS gain factor |phi(f)| for {law}")
    click.echo(f"  {'f (Hz)':>10} {'f / Nyquist':>11} {'|phi(f)|':>10} {'gain bias':>10} {'dB':>8}")
    for fi, gi in zip(f, g, strict=True):
        db = 20 * np.log10(gi) if gi > 0 else -np.inf
        click.echo(
            f"  {fi:>10.4g} {fi * 2 * T:>11.3f} {gi:>10.4f} {100 * (gi - 1):>9.2f}% {db:>8.3f}"
        )
    fb = bias_frequency(law, tol)
    where = (
        "never (no jitter)"
        if math.isinf(fb)
        else f"at f = {fb:.4g} Hz ({fb * 2 * T:.3f} of Nyquist for T = {T:g} s)"
    )
    click.echo(f"the gain bias reaches {100 * tol:g}% {where}")
    if plot_path:
        from matplotlib.figure import Figure

        from ..plots import plot_gain_factor

        ff = np.linspace(0.0, top, 400)
        with _clean_errors("cannot write the plot"):
            fig = Figure(figsize=(6.4, 4.0), layout="constrained")
            plot_gain_factor(
                ff, ls_gain_factor(law, ff), label=f"|φ(f)|, {law!r}", tol=tol, ax=fig.subplots()
            )
            fig.savefig(plot_path, dpi=110)
        click.echo(f"wrote {plot_path}")
