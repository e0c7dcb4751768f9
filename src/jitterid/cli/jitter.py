"""``jitterid jitter``: measure the sampling jitter from a record of a sine wave, or a batch.

A thin layer over :func:`jitterid.measure_jitter` and :mod:`jitterid.experiments.jitter_batch`:

- one record (a data file with a ``y`` column and no input): prints the measurement's
  summary with the converter figures (IEEE 1241), the law's evidence and, when the
  frequency was not given, the jitter each Nyquist zone implies; with ``--out`` writes
  ``jitter.json`` and (``--plot``) ``jitter_phase.png`` and ``jitter_pdf.png`` (the latter
  only where the data chose the law);
- many records (a folder, a glob or a multi-record file): one table,
  ``OUT/jitter_batch.csv`` and ``.sqlite``, one row per record, resumable (``--resume``),
  on a local Dask cluster (``--workers``) or a scheduler (``--scheduler``).

Every error ends in a one-line message naming the fix and a non-zero exit (2 for bad usage,
1 for an unusable record, 3 for a fit that did not converge, whose outputs are still
written; in a batch, 3 when any record's row is not CONVERGED).
"""

from __future__ import annotations

import glob
import json
import math
import re
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..io import atomic_write, load
from ..metrology.meter import DEFAULT_LAWS, FAMILY_NAMES, JitterMeasurement
from ._main import main
from .data import _check_out_dir, _clean_errors, _T_opt

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


class _Harmonics(click.ParamType):
    name = "auto|N"

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> int | None:
        if value is None or isinstance(value, int):
            return value
        text = str(value).strip().lower()
        if text == "auto":
            return None
        try:
            n = int(text)
        except ValueError:
            self.fail(f"{value!r} is neither 'auto' nor a whole number", param, ctx)
        if not 1 <= n <= 50:
            self.fail(f"{n} is not in 1..50 (or 'auto')", param, ctx)
        return n


def measurement_json(
    m: JitterMeasurement,
    *,
    data_path: str,
    sha256: str,
    n: int,
    zones: bool = False,
) -> dict[str, Any]:
    """The small dict ``jitter.json`` holds (seconds, Hz, y units).

    Parameters
    ----------
    m : JitterMeasurement
        The measurement (with its converter figures, if attached).
    data_path : str
        The record's file.
    sha256 : str
        Its checksum.
    n : int
        Its length.
    zones : bool
        Whether to list the Nyquist zones (the frequency was not given).
    """
    from .. import __version__
    from ..metrology.reading import law_evidence, nyquist_zones

    lo, hi = m.interval(0.95)
    ev = law_evidence(m)
    chosen_bic = next((c.bic for c in m.laws if c.name == m.family), math.nan)
    out: dict[str, Any] = {
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
        "law_evidence": {
            "verdict": ev.verdict,
            "delta_bic": _finite(ev.delta_bic),
            "runner_up": ev.runner_up,
            "margin": ev.margin,
            "message": ev.message,
        },
        "harmonics": int(getattr(m.fit.structure, "harmonics", 1)),
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
                # ranked out (not fitted to its maximum): loglik is its upper estimate,
                # bic and delta_bic lower bounds
                "ranked_out": c.ranked_out,
                "delta_bic": _finite(c.bic - chosen_bic),
                "state": c.state(chosen_bic),
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
        "converter": m.converter.to_dict() if m.converter is not None else None,
        "T_s": m.T,
        "N": n,
        "data": {"path": data_path, "sha256": sha256},
        "version": __version__,
    }
    if zones:
        out["nyquist_zones"] = [
            {
                "zone": z.zone,
                "frequency_hz": _finite(z.frequency_hz),
                "jitter_std_s": _finite(z.jitter_std_s),
                "interval_95_s": [_finite(z.interval_s[0]), _finite(z.interval_s[1])],
                "measured": z.fitted,
            }
            for z in nyquist_zones(m)
        ]
    return out


def _zone_lines(m: JitterMeasurement) -> list[str]:
    """The Nyquist-zone paragraph of the report (the frequency was not given)."""
    from ..metrology.meter import _time
    from ..metrology.reading import nyquist_zones

    fs = 1.0 / m.T
    lines = [
        (
            f"Nyquist zone: assumed 1 (the tone below fs/2 = {fs / 2:.6g} Hz). The samples "
            "cannot tell the zone: with the jitter's scale free, each alias of the tone fits "
            "as well, with the jitter scaled by the ratio of the frequencies. If the tone lies "
            "in another zone, the jitter is:"
        )
    ]
    for z in nyquist_zones(m):
        lo, hi = z.interval_s
        mark = "  (measured)" if z.fitted else ""
        lines.append(
            f"  zone {z.zone}  f = {z.frequency_hz:<14.8g} Hz  jitter std {_time(z.jitter_std_s)}"
            f"  (95 %: {_time(lo)} .. {_time(hi)}){mark}"
        )
    lines.append("Give --frequency (the tone's true frequency) to measure in its zone.")
    return lines


@contextmanager
def _heartbeat(what: str, enabled: bool, after_s: float = 2.0) -> Iterator[None]:
    """The elapsed time of a fit that takes more than ``after_s``, on stderr, so that a long
    fit is never silent: on a terminal a line refreshed twice a second and cleared at the
    end; into a log (not a terminal) a plain line every 10 s. A fit that ends sooner
    prints nothing."""
    if not enabled:
        yield
        return
    from tqdm import tqdm

    stop = threading.Event()
    bars: list[Any] = []
    start = time.time()
    tty = sys.stderr.isatty()

    def beat() -> None:
        if stop.wait(after_s):
            return
        if not tty:
            while True:
                click.echo(f"{what}: {time.time() - start:.0f} s elapsed", err=True)
                if stop.wait(10.0):
                    return
        bar = tqdm(
            total=None,
            desc=what,
            bar_format="{desc}: {elapsed} elapsed",
            file=sys.stderr,
            dynamic_ncols=True,
            leave=False,
            delay=1e-9,  # no line at creation: the first is drawn below, with the elapsed time
        )
        bar.start_t = start  # the elapsed time since the fit began
        bar.refresh()
        bars.append(bar)
        while not stop.wait(0.5):
            bar.refresh()

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        for bar in bars:
            bar.close()


def _is_batch(data_path: str) -> bool:
    p = Path(data_path)
    if p.is_dir():
        return True
    if p.is_file():
        from ..experiments.jitter_batch import is_multi_record

        return is_multi_record(p)
    return glob.has_magic(data_path)


def _resolution(
    resolution: float | None, bits: int | None, full_scale: float | None
) -> float | None:
    if bits is not None and full_scale is None:
        raise click.UsageError(
            "--bits needs --full-scale (the converter's range, peak to peak, in units of y): "
            "the LSB is full scale / 2^bits"
        )
    if bits is not None and resolution is not None:
        raise click.UsageError(
            "give either --resolution (the noise floor) or --bits with --full-scale (which set "
            "it to LSB / sqrt(12)), not both"
        )
    if bits is not None:
        assert full_scale is not None
        return full_scale / 2**bits / math.sqrt(12.0)
    return resolution


@main.command(short_help="Measure the sampling jitter from a sine record (or a batch of them).")
@click.argument("data_path", metavar="DATA")
@click.option(
    "--frequency",
    type=_Frequency(),
    help="The sine's frequency, a start the fit refines (Hz; takes kHz, MHz, GHz). May lie "
    "above Nyquist (equivalent-time sampling). Default: the periodogram's peak (zone 1).",
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
    "--method",
    type=click.Choice(["ml", "gaussian"]),
    default=None,
    help="ml: the exact likelihood (ranks the laws); gaussian: the closed-form moments, O(N): "
    "law-free with several laws up to ~0.2 rad of phase spread (the likelihood beyond), one "
    "law assumed. Default: measure_jitter's (ml).",
)
@click.option(
    "--harmonics",
    type=_Harmonics(),
    default="auto",
    show_default=True,
    help="Harmonics of the sine model: a number, or auto (the highest of HD2-HD5 that stands "
    "above the noise, so that distortion is not counted as jitter).",
)
@click.option(
    "--resolution",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="The noise floor, in units of y (a quantised record: LSB / sqrt(12)). Default: "
    "measure_jitter's.",
)
@click.option(
    "--bits",
    type=click.IntRange(min=1, max=32),
    default=None,
    help="The converter's resolution in bits (with --full-scale): sets --resolution to "
    "LSB / sqrt(12).",
)
@click.option(
    "--full-scale",
    "full_scale",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="The converter's full-scale range, peak to peak, in units of y: ENOB from it "
    "(IEEE 1241) and levels in dBFS (default: the tone taken as full scale).",
)
@_T_opt
@click.option(
    "--out",
    "out",
    type=click.Path(file_okay=False),
    help="Output folder: jitter.json (and the figures with --plot); for a batch, "
    "jitter_batch.csv and jitter_batch.sqlite (required).",
)
@click.option(
    "--plot", is_flag=True, help="Write jitter_phase.png and jitter_pdf.png (needs --out)."
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Batch: local worker processes (default: one per CPU); 1 runs in this process.",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    default=None,
    help="Batch: a running Dask scheduler (tcp://host:port) whose workers measure the "
    "records (they need jitterid and the record files at the same paths). TRUSTED CODE "
    "EXECUTION: connect only to a cluster you trust as much as this machine.",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Batch: continue a table in --out, skipping the records it holds (after a kill).",
)
@click.option("--no-progress", is_flag=True, help="Hide the progress bar and the fit's timer.")
def jitter(
    data_path: str,
    frequency: float | None,
    band: tuple[float, float] | None,
    laws: tuple[str, ...],
    method: str | None,
    harmonics: int | None,
    resolution: float | None,
    bits: int | None,
    full_scale: float | None,
    T: str | None,
    out: str | None,
    plot: bool,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    no_progress: bool,
) -> None:
    """Measure the sampling jitter from DATA, a record of a sine wave, or from many.

    DATA is a file with a 'y' column (and 't' or 'k', or T given; no input), or, for a
    batch, a folder, a quoted glob ('runs/*.csv') or a multi-record file (a .npz whose 'y'
    is 2-D, one record per row). The sine, the noise and the jitter law are fitted for each
    --law family (lowest BIC chosen); prints the jitter std with its standard error and
    95 % interval, the law and how firmly the data chose it, the sine, the converter
    figures (SNR, SINAD, ENOB, THD, SFDR, noise floor, jitter-limited SNR) and, without
    --frequency, the jitter each Nyquist zone implies. Exits with status 3 if the fit did
    not converge (the outputs are written).
    """
    if frequency is not None and band is not None:
        raise click.UsageError(
            "give either --frequency (a start near the frequency) or --search LOW:HIGH "
            "(a band to search), not both"
        )
    if plot and out is None:
        raise click.UsageError("--plot writes into the --out folder; give --out DIR as well")
    res = _resolution(resolution, bits, full_scale)
    batch = _is_batch(data_path)
    if not batch and (resume or workers is not None or scheduler is not None):
        raise click.UsageError(
            "--workers, --scheduler and --resume are for a batch (a folder, a glob or a "
            f"multi-record file); {data_path} is one record"
        )
    out_dir = Path(out) if out is not None else None
    if batch:
        if out_dir is None:
            raise click.UsageError("a batch writes its table into a folder: give --out DIR")
        if plot:
            raise click.UsageError("--plot draws one record's figures; it is not for a batch")
    if out_dir is not None:
        _check_out_dir(out_dir)
    from ..experiments.jitter_batch import BatchOptions

    options = BatchOptions(
        method=method,
        laws=laws or None,
        frequency=frequency,
        band_hz=band,
        harmonics=harmonics,
        resolution=res,
        full_scale=full_scale,
        T=T,
    )
    if batch:
        assert out_dir is not None
        _batch(data_path, out_dir, options, workers, scheduler, resume, not no_progress)
        return
    _single(data_path, options, out_dir, plot, not no_progress)


def _single(data_path: str, options: Any, out_dir: Path | None, plot: bool, progress: bool) -> None:
    from ..experiments.jitter_batch import measure_record
    from ..metrology.reading import law_evidence

    with _clean_errors(f"cannot use the record {data_path}"):
        ds = load(data_path, T=options.T, require_input=False)
    y = ds.data.y
    if ds.data.u is not None:
        click.echo(
            f"note: {data_path} has an input column 'u'; it is ignored (a sine record needs y "
            "only)",
            err=True,
        )
    what = f"measuring the jitter (N = {y.size}, method {options.method or 'ml'})"
    try:
        with _heartbeat(what, progress):
            m, _ = measure_record(y, ds.data.T, options)
    except (ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError) as exc:
        msg = " ".join(str(exc).split())
        raise click.ClickException(
            f"cannot measure the jitter in {data_path}: {_cli_words(msg)}"
        ) from None
    zones = options.frequency is None and options.band_hz is None
    click.echo(m.summary())
    if zones and len(m.aliases) == 1:
        click.echo("\n".join(_zone_lines(m)))
    if out_dir is not None:
        ev = law_evidence(m)
        # no density where the law is undetermined, nor where none was fitted (the law-free
        # moment route measures the std and the kurtosis: its "law" is a Gaussian of that
        # std, whatever the kurtosis)
        law_free = not m.law_fitted
        draw_pdf = ev.verdict != "undetermined" and not law_free
        written = _write(out_dir, m, y, data_path, ds.sha256, plot, draw_pdf, zones)
        click.echo("wrote " + ", ".join(str(p) for p in written))
        if plot and ev.verdict == "undetermined":
            click.echo(f"jitter_pdf.png not drawn: {ev.message}")
        elif plot and law_free:
            click.echo(
                "jitter_pdf.png not drawn: the law-free route measures the jitter's std and "
                "kurtosis, not its density (give one law, --law gaussian, or --method ml to "
                "fit one)"
            )
    if m.status.name != "CONVERGED":
        click.echo(f"error: the fit did not converge: {m.status.name}: {m.message}", err=True)
        raise click.exceptions.Exit(3)


def _batch(
    data_path: str,
    out_dir: Path,
    options: Any,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    progress: bool,
) -> None:
    from ..experiments.jitter_batch import run_batch
    from ..experiments.store import StoreError
    from .reproduce import _default_workers

    try:
        summary = run_batch(
            data_path,
            out_dir,
            options,
            workers=workers if workers is not None else _default_workers(),
            scheduler=scheduler,
            resume=resume,
            progress=progress,
        )
    except StoreError as exc:
        raise click.ClickException(str(exc)) from None
    except (ValueError, OSError) as exc:
        raise click.ClickException(f"cannot run the batch {data_path}: {exc}") from None
    from ..experiments.jitter_batch import BatchStore

    with BatchStore(summary.store, options, resume=True) as store:
        rows = store.rows()
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    click.echo(
        f"{summary.total} records ({summary.already_done} already done, {summary.new} measured "
        f"now in {summary.wall_s:.1f} s): "
        + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
    )
    click.echo(f"wrote {summary.csv}, {summary.store}")
    bad = [r for r in rows if r["status"] != "CONVERGED"]
    for r in bad[:5]:
        click.echo(f"  {r['record']}: {r['status']}: {r['error'] or r['message']}", err=True)
    if bad:
        more = f" (first 5 above; all in {summary.csv.name})" if len(bad) > 5 else ""
        click.echo(f"error: {len(bad)} record(s) not CONVERGED{more}", err=True)
        raise click.exceptions.Exit(3)


def _write(
    out_dir: Path,
    m: JitterMeasurement,
    y: np.ndarray,
    data_path: str,
    sha: str,
    plot: bool,
    pdf: bool = True,
    zones: bool = False,
) -> list[Path]:
    written = []
    doc = measurement_json(m, data_path=data_path, sha256=sha, n=y.size, zones=zones)
    text = json.dumps(doc, indent=2) + "\n"
    with _clean_errors("cannot write the results"):
        atomic_write(out_dir / "jitter.json", lambda fh: fh.write(text))
    written.append(out_dir / "jitter.json")
    if plot:
        from matplotlib.figure import Figure

        from ..plots import plot_jitter_pdf, plot_jitter_phase

        draws: list[tuple[str, Callable[[Any], Any]]] = [
            ("jitter_phase.png", lambda ax: plot_jitter_phase(m, y, ax=ax)),
        ]
        if pdf:
            draws.append(("jitter_pdf.png", lambda ax: plot_jitter_pdf(m, ax=ax, rng=0)))
        for name, draw in draws:
            with _clean_errors(f"cannot write {name}"):
                fig = Figure(figsize=(6.4, 4.2), layout="constrained")
                draw(fig.subplots())
                _save_png(out_dir / name, fig)
            written.append(out_dir / name)
    return written


def _save_png(path: Path, fig: Any) -> None:
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=110, format="png"), binary=True)
