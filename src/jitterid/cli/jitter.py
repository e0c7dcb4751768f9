"""``jitterid jitter``: measure the sampling jitter from a record of a sine wave.

A thin layer over :func:`jitterid.measure_jitter`: reads the record (a data file with a
``y`` column and no input), prints the measurement's summary and, with ``--out``, writes
``jitter.json`` and (``--plot``) ``jitter_phase.png`` and ``jitter_pdf.png``. Every error
ends in a one-line message naming the fix and a non-zero exit (2 for bad usage, 1 for an
unusable record, 3 for a fit that did not converge, whose outputs are still written).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..io import atomic_write, load
from ..metrology.meter import DEFAULT_LAWS, FAMILY_NAMES, JitterMeasurement, measure_jitter
from ._main import main
from .data import _check_out_dir, _clean_errors, _data_arg, _T_opt

__all__ = ["jitter"]

#: The families --law accepts (those measure_jitter knows in this installation).
LAW_NAMES = FAMILY_NAMES

_FREQ_UNITS = {"hz": 1.0, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}
_FREQ_RE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z]*)\s*$")


def parse_frequency(text: str) -> float:
    """A frequency in Hz from ``"123"``, ``"123Hz"``, ``"10kHz"``, ``"1.5 MHz"``, ``"2GHz"``."""
    m = _FREQ_RE.match(text)
    unit = m.group(2).lower() if m else ""
    if m is None or unit not in ("", *_FREQ_UNITS):
        raise ValueError(
            f"{text!r} is not a frequency; write a number with an optional unit "
            "(Hz, kHz, MHz, GHz), e.g. 123 or 10kHz (a bare number is in Hz)"
        )
    value = float(m.group(1)) * _FREQ_UNITS.get(unit, 1.0)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{text!r}: the frequency must be finite and > 0")
    return value


class _Frequency(click.ParamType):
    name = "frequency"

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        if isinstance(value, float):
            return value
        try:
            return parse_frequency(str(value))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


class _Band(click.ParamType):
    name = "low:high"

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> tuple[float, float]:
        if isinstance(value, tuple):
            return value
        text = str(value)
        parts = text.split(":")
        if len(parts) != 2:
            self.fail(
                f"{text!r} is not a band; write LOW:HIGH in Hz with optional units, "
                "e.g. 100:200 or 9.9kHz:10.1kHz",
                param,
                ctx,
            )
        try:
            lo, hi = (parse_frequency(p) for p in parts)
        except ValueError as exc:
            self.fail(f"{text!r}: {exc}", param, ctx)
        if not lo < hi:
            self.fail(f"{text!r}: LOW must be below HIGH", param, ctx)
        return lo, hi


#: measure_jitter's words for its arguments, in the command's words.
_OPTION_WORDS = (
    ("give frequency=", "give --frequency"),
    ("give the frequency (frequency=...)", "give the frequency (--frequency)"),
    ("frequency=", "--frequency "),
    ("band_hz = ", "--search "),
    ("band_hz", "--search"),
    ("widen the band", "widen the --search band"),
)


def _cli_words(text: str) -> str:
    for api, cli in _OPTION_WORDS:
        text = text.replace(api, cli)
    return text


def _finite(x: Any) -> Any:
    """A JSON value: a float, or None where it is not finite (JSON has no NaN)."""
    v = float(x)
    return v if math.isfinite(v) else None


def measurement_json(
    m: JitterMeasurement, *, data_path: str, sha256: str, n: int
) -> dict[str, Any]:
    """The small dict ``jitter.json`` holds (seconds, Hz, y units)."""
    from .. import __version__

    lo, hi = m.interval(0.95)
    return {
        "jitter_std_s": _finite(m.jitter_std),
        "jitter_std_stderr_s": _finite(m.jitter_std_stderr),
        "interval_95_s": [_finite(lo), _finite(hi)],
        "noise_std": _finite(m.noise_std),
        "noise_std_stderr": _finite(m.noise_std_stderr),
        "frequency_hz": _finite(m.frequency),
        "frequency_stderr_hz": _finite(m.frequency_stderr),
        "amplitude": _finite(m.amplitude),
        "phase_rad": _finite(m.phase_rad),
        "offset": _finite(m.offset),
        "family": m.family,
        "law": {
            "name": type(m.law).__name__,
            "params": {k: _finite(v) for k, v in m.law.params.items()},
        },
        "status": m.status.name,
        "message": m.message,
        "slope_regression_std_s": _finite(m.slope_regression_std),
        "laws": [
            {
                "name": c.name,
                "loglik": _finite(c.loglik),
                "n_params": c.n_params,
                "aic": _finite(c.aic),
                "bic": _finite(c.bic),
                "jitter_std_s": _finite(c.jitter_std_s),
                "status": c.status.name,
                "chosen": c.name == m.family,
            }
            for c in m.laws
        ],
        "aliases": [
            {
                "frequency_hz": _finite(a.frequency_hz),
                "loglik": _finite(a.loglik),
                "jitter_std_s": _finite(a.jitter_std_s),
            }
            for a in m.aliases
        ],
        "T_s": m.T,
        "N": n,
        "data": {"path": data_path, "sha256": sha256},
        "version": __version__,
    }


@main.command(short_help="Measure the sampling jitter from a sine record.")
@_data_arg
@click.option(
    "--frequency",
    type=_Frequency(),
    help="The sine's frequency, a start the fit refines (Hz; takes kHz, MHz, GHz). May lie "
    "above Nyquist (equivalent-time sampling). Default: the periodogram's peak.",
)
@click.option(
    "--search",
    "band",
    type=_Band(),
    help="LOW:HIGH, where the frequency lies (Hz; takes units, e.g. 9.9kHz:10.1kHz); every "
    "alias of the record's frequency in the band is fitted and the likeliest kept.",
)
@click.option(
    "--law",
    "laws",
    multiple=True,
    type=click.Choice(LAW_NAMES),
    help=f"Jitter family to fit (repeat for several; the lowest BIC is chosen). "
    f"Default: {', '.join(DEFAULT_LAWS)}.",
)
@click.option(
    "--harmonics",
    type=click.IntRange(min=1, max=50),
    default=1,
    show_default=True,
    help="Harmonics of the sine model (more than 1 for a distorted source).",
)
@_T_opt
@click.option(
    "--out",
    "out",
    type=click.Path(file_okay=False),
    help="Output directory for jitter.json (and the figures with --plot).",
)
@click.option(
    "--plot", is_flag=True, help="Write jitter_phase.png and jitter_pdf.png (needs --out)."
)
def jitter(
    data_path: str,
    frequency: float | None,
    band: tuple[float, float] | None,
    laws: tuple[str, ...],
    harmonics: int,
    T: str | None,
    out: str | None,
    plot: bool,
) -> None:
    """Measure the sampling jitter from DATA, a record of a sine wave.

    DATA has a 'y' column (and 't' or 'k' with T; no input). The sine, the noise and the
    jitter law are fitted by the exact likelihood for each --law family (lowest BIC
    chosen); prints the jitter std with its standard error and 95 % interval, the law and
    the sine. Exits with status 3 if the fit did not converge (the outputs are written).
    """
    if frequency is not None and band is not None:
        raise click.UsageError(
            "give either --frequency (a start near the frequency) or --search LOW:HIGH "
            "(a band to search), not both"
        )
    if plot and out is None:
        raise click.UsageError("--plot writes into the --out folder; give --out DIR as well")
    out_dir = Path(out) if out is not None else None
    if out_dir is not None:
        _check_out_dir(out_dir)
    with _clean_errors(f"cannot use the record {data_path}"):
        ds = load(data_path, T=T, require_input=False)
    y = ds.data.y
    if ds.data.u is not None:
        click.echo(
            f"note: {data_path} has an input column 'u'; it is ignored (a sine record needs y "
            "only)",
            err=True,
        )
    try:
        m = measure_jitter(
            y, ds.data.T, frequency, laws=laws or DEFAULT_LAWS, band_hz=band, harmonics=harmonics
        )
    except (ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError) as exc:
        msg = " ".join(str(exc).split())
        raise click.ClickException(
            f"cannot measure the jitter in {data_path}: {_cli_words(msg)}"
        ) from None
    click.echo(m.summary())
    if out_dir is not None:
        written = _write(out_dir, m, y, data_path, ds.sha256, plot)
        click.echo("wrote " + ", ".join(str(p) for p in written))
    if m.status.name != "CONVERGED":
        click.echo(f"error: the fit did not converge: {m.status.name}: {m.message}", err=True)
        raise click.exceptions.Exit(3)


def _write(
    out_dir: Path, m: JitterMeasurement, y: np.ndarray, data_path: str, sha: str, plot: bool
) -> list[Path]:
    written = []
    text = (
        json.dumps(measurement_json(m, data_path=data_path, sha256=sha, n=y.size), indent=2) + "\n"
    )
    with _clean_errors("cannot write the results"):
        atomic_write(out_dir / "jitter.json", lambda fh: fh.write(text))
    written.append(out_dir / "jitter.json")
    if plot:
        from matplotlib.figure import Figure

        from ..plots import plot_jitter_pdf, plot_jitter_phase

        draws: list[tuple[str, Callable[[Any], Any]]] = [
            ("jitter_phase.png", lambda ax: plot_jitter_phase(m, y, ax=ax)),
            ("jitter_pdf.png", lambda ax: plot_jitter_pdf(m, ax=ax, rng=0)),
        ]
        for name, draw in draws:
            with _clean_errors(f"cannot write {name}"):
                fig = Figure(figsize=(6.4, 4.2), layout="constrained")
                draw(fig.subplots())
                _save_png(out_dir / name, fig)
            written.append(out_dir / name)
    return written


def _save_png(path: Path, fig: Any) -> None:
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=110, format="png"), binary=True)
