"""Commands from a data file to a trusted model: ``simulate``, ``detect``, ``fit``, ``bias``.

``jitterid simulate --out lab`` writes a synthetic data set (the paper's setting by default)
in the format :func:`jitterid.load` reads; ``jitterid detect`` tests a data set for jitter;
``jitterid fit`` estimates a model and writes result.json, report.md and figures;
``jitterid bias`` predicts the gain bias of an ordinary fit under a jitter law.
Every error ends in a one-line message and a non-zero exit (2 for bad usage, 1 for
unusable data, 3 for a fit that did not converge), never a traceback. A finished fit is
always written: a diagnostic or figure that cannot be computed is reported as skipped.
Files are written atomically (a temporary file renamed into place).

Times on the command line take a unit (``--T 0.5s``, ``sigma=80ms``); a bare number is in
the data file's ``time_unit`` (``fit``, ``detect``) or in seconds (``simulate``, ``bias``).
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

import click
import numpy as np

from .._checks import allocation
from ..analysis.diagnostics import (
    bias_frequency,
    cross_check_jitter,
    detect_jitter,
    input_correlation_test,
    ljung_box,
    ls_gain_factor,
    standardized_residuals,
)
from ..analysis.selection import OrderSelection, select_order
from ..data import SampledData
from ..estimation.estimators import as_estimator, method_names
from ..estimation.fit import fit as fit_model
from ..inputs import telegraph_input, zoh_input
from ..io import TIME_UNITS, Dataset, atomic_write, load, parse_time, save_data, save_input
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..simulate import simulate as simulate_data
from ..systems.structures import ModelStructure
from ._main import main
from ._report import FitReport, write_outputs
from ._specs import (
    JITTER_HELP,
    OptionError,
    constrain,
    model_label,
    parse_floats,
    parse_jitter,
    parse_model,
)

__all__ = ["bias", "detect", "fit", "simulate"]

MODEL_HELP = (
    "polepair (k0 / ((s - pr)^2 + pi^2)) or tf:NUM,DEN (NUM zeros, DEN poles, e.g. tf:0,2); "
    "add +delay for an input-output delay delay_s (tf:0,2+delay)"
)
_PAPER_PARAMS = "6.25,-1.5,2"


@contextmanager
def _clean_errors(what: str) -> Iterator[None]:
    """Turn the library's ValueError/TypeError/OSError into a one-line click error."""
    try:
        yield
    except click.ClickException:
        raise
    except (ValueError, TypeError, OSError, ImportError) as exc:
        raise click.ClickException(f"{what}: {_one_line(exc)}") from None
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise click.ClickException(
            f"{what}: the numbers are out of range ({type(exc).__name__}: {_one_line(exc)}); "
            "check the values and their units"
        ) from None
    except MemoryError:
        raise click.ClickException(
            f"{what}: out of memory; use fewer samples or a smaller model"
        ) from None


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        where = f"{exc.filename}: " if exc.filename else ""
        return f"{where}{exc.strerror}"
    return " ".join(str(exc).split())


class _Time(click.ParamType):
    """A time with an optional unit (``0.5``, ``0.5s``, ``500ms``).

    With ``seconds=True`` the value is converted to seconds (a bare number is seconds);
    otherwise the text is kept, for :func:`jitterid.load` to read in the file's time unit.
    """

    name = "time"

    def __init__(self, seconds: bool) -> None:
        self.seconds = seconds

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> object:
        if isinstance(value, float) and self.seconds:
            return value
        try:
            sec = parse_time(str(value), "s", "value")
        except ValueError as exc:
            self.fail(str(exc).removeprefix("value: "), param, ctx)
        if not sec > 0:
            self.fail(f"must be > 0; got {value!r}", param, ctx)
        return sec if self.seconds else str(value)


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
    type=_Time(seconds=False),
    help="Nominal sampling interval, if DATA has an index column k and no T metadata. "
    "Takes a unit (0.5s, 500ms); a bare number is in DATA's time_unit.",
)


def _load(
    data_path: str,
    input_path: str | None,
    T: str | None,
    noise: float | None,
    hold_input: bool = False,
) -> Dataset:
    with _clean_errors("cannot use the data"):
        return load(data_path, input_path, T=T, noise_std=noise, hold_input=hold_input)


def _file_unit(ds: Dataset) -> str:
    unit = str(ds.metadata.get("time_unit", "s"))
    return unit if unit in TIME_UNITS else "s"


def _png_path(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A ``--plot FILE`` option: the figure is written as PNG, so FILE must end in .png
    (refused before any work; a .txt name got PNG bytes); its folder must be writable."""
    if value is None:
        return None
    if Path(value).suffix.lower() != ".png":
        raise click.BadParameter(
            f"{value!r}: the plot is written as a PNG image; give a file name ending in .png"
        )
    _check_out_dir(Path(value).parent, "'--plot'")
    return value


def _check_out_dir(out: Path, option: str = "'--out'") -> None:
    """Refuse an output folder that cannot be written, before any work."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".jitterid-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise click.BadParameter(
            f"cannot write into {str(out)!r} ({exc.strerror or exc}); choose a writable folder",
            param_hint=option,
        ) from None


# ------------------------------------------------------------------------------ progress

#: Seconds a command runs before its progress bar appears (shorter commands stay silent).
PROGRESS_DELAY = 2.0


def _progress_file() -> TextIO:
    return sys.stderr


class _Progress:
    """A tqdm bar over a command's stages, on stderr only (never in a result file or on
    stdout). It appears once the command has run :data:`PROGRESS_DELAY` seconds, shows the
    current stage and the elapsed time (ticking during a long stage), and is off with
    ``--quiet`` or when stderr is not a terminal; it is cleared when the command ends."""

    def __init__(self, stages: list[str], quiet: bool) -> None:
        from tqdm import tqdm

        self._stages = stages
        self._bar = tqdm(
            total=len(stages),
            desc=stages[0],
            file=_progress_file(),
            disable=True if quiet else None,  # None: off when the file is not a TTY
            delay=PROGRESS_DELAY,
            leave=False,
            bar_format="jitterid: {desc} ({n_fmt}/{total_fmt}) {bar:12} {elapsed}",
        )
        self._start = time.monotonic()
        self._shown = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if not self._bar.disable:
            self._thread = threading.Thread(target=self._tick, daemon=True)
            self._thread.start()

    def _show(self) -> None:
        if not self._bar.disable and time.monotonic() - self._start >= PROGRESS_DELAY:
            self._shown = True
            self._bar.refresh()

    def _tick(self) -> None:
        while not self._stop.wait(0.5):
            self._show()

    def stage(self, name: str) -> None:
        """The previous stage is done; ``name`` starts."""
        self._bar.set_description_str(name, refresh=False)
        self._bar.n += 1
        self._show()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._shown:
            self._bar.clear()  # tqdm clears only bars it drew itself after the delay
        self._bar.close()


@contextmanager
def _progress(stages: list[str], quiet: bool) -> Iterator[_Progress]:
    bar = _Progress(stages, quiet)
    try:
        yield bar
    finally:
        bar.close()


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
    help="True jitter law: none | uniform:a=A | gaussian:sigma=S | sum-of-uniforms:n=N,a=A. "
    "Times take a unit (sigma=80ms), seconds if bare.",
)
@click.option("--N", "n_samples", type=click.IntRange(min=4), default=200, show_default=True)
@click.option(
    "--T",
    "T",
    type=_Time(seconds=True),
    default=1.0,
    show_default=True,
    help="Nominal sampling interval; takes a unit (0.5s, 500ms), seconds if bare.",
)
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
    "--hold",
    type=_Time(seconds=True),
    default=1.0,
    show_default=True,
    help="Mean hold of the telegraph input; takes a unit (200ms), seconds if bare.",
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
    with _param("'--N'"):
        allocation(
            8.0 * n_samples, f"--N {n_samples}", fix="simulate fewer samples (a smaller --N)"
        )
    reach = (n_samples - 1) * T + max(law.support[1], 0.0)
    with _param("'--hold'"):
        allocation(
            4 * (reach / hold + 10),
            f"--hold {hold:g} s over {reach:g} s",
            fix="use a longer --hold (mean hold of the input) or a smaller --N",
        )
    out_dir = Path(out)
    _check_out_dir(out_dir)
    with _clean_errors("cannot simulate"):
        rng = np.random.default_rng(seed)
        if input_kind == "telegraph":
            u = telegraph_input(reach + T, rng, levels=(-amplitude, amplitude), mean_hold=hold)
        else:
            m = math.ceil(reach / T) + 1
            tele = telegraph_input(m * T, rng, levels=(-amplitude, amplitude), mean_hold=hold)
            u = zoh_input(tele(T * np.arange(m)), T)
        data = simulate_data(system, u, law, T, n_samples, noise_std, rng)
        data_file = save_data(out_dir / f"data.{fmt}", data)
        input_file = save_input(out_dir / f"input.{fmt}", u, T=T if input_kind == "zoh" else None)
        truth = {
            "model": model_spec,
            "param_names": list(structure.param_names),
            "params": dict(zip(structure.param_names, theta, strict=True)),
            "system": {
                "num": system.num.tolist(),
                "den": system.den.tolist(),
                "delay_s": system.delay_s,
            },
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
        text = json.dumps(truth, indent=2) + "\n"
        atomic_write(out_dir / "truth.json", lambda fh: fh.write(text))
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
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False),
    callback=_png_path,
    help="Write the residual plot to this .png file.",
)
def detect(
    data_path: str,
    input_path: str | None,
    model_spec: str,
    T: str | None,
    level: float,
    plot_path: str | None,
) -> None:
    """Test DATA for sampling jitter before fitting.

    Fits the model ignoring jitter, regresses the squared residuals on the squared model
    slope and prints the one-sided p-value and the implied jitter std. --T takes a unit
    (0.5s); a bare number is in DATA's time_unit.
    """
    with _param("'--model'"):
        structure = parse_model(model_spec)
    ds = _load(data_path, input_path, T, None)
    with _clean_errors("the ordinary fit failed"):
        ls = fit_model(ds.data, structure, NoJitter(), "ls")
    click.echo(f"ordinary LS fit (jitter ignored): {ls.status.value}")
    click.echo("  " + _params_line(ls))
    with _clean_errors(
        f"the jitter test cannot run on this fit ({ls.status.value}); try another --model"
    ):
        det = detect_jitter(ds.data, ls, level=level)
    click.echo(det.summary())
    if plot_path:
        from matplotlib.figure import Figure

        from ..plots import plot_residuals

        with _clean_errors("cannot write the plot"):
            fig = Figure(figsize=(6.4, 6.0), layout="constrained")
            plot_residuals(det, ax=fig.subplots(2, 1))
            atomic_write(
                Path(plot_path), lambda fh: fig.savefig(fh, dpi=110, format="png"), binary=True
            )
        click.echo(f"wrote {plot_path}")


def _params_line(res: object) -> str:
    """``k0 = 6.2 ± 0.1, ...``; the ± is left out (with the reason) if it cannot be computed."""
    params = res.params  # type: ignore[attr-defined]
    try:
        se = res.stderr  # type: ignore[attr-defined]
        return ", ".join(f"{k} = {v:.5g} ± {se[k]:.2g}" for k, v in params.items())
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        vals = ", ".join(f"{k} = {v:.5g}" for k, v in params.items())
        return f"{vals} (no standard errors: {_one_line(exc)})"


# ------------------------------------------------------------------------------ fit


@main.command(short_help="Fit a model to DATA accounting for jitter; write a report.")
@_data_arg
@_input_opt
@click.option(
    "--model",
    "model_specs",
    required=True,
    multiple=True,
    help=MODEL_HELP + ". Repeat it (--model tf:0,1 --model tf:1,2 ...) to select the order: "
    "every model is fitted, the table goes to OUT/order.json and report.md, and the fit "
    "continues with the chosen one.",
)
@click.option("--jitter", "jitter_spec", required=True, help=JITTER_HELP)
@click.option("--method", type=click.Choice(method_names()), default="bcls", show_default=True)
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
@click.option(
    "--quiet",
    "-q",
    is_flag=True,
    help="No progress bar. (The bar goes to stderr, only on a terminal, and only for a fit "
    "that runs longer than 2 s; it never reaches the result files or stdout.)",
)
@click.option(
    "--start",
    "start_items",
    multiple=True,
    metavar="NAME=VALUE",
    help="Start the search with this model parameter at VALUE (repeatable).",
)
@click.option(
    "--bounds",
    "bound_items",
    multiple=True,
    metavar="NAME=LO:HI",
    help="Keep a model parameter in [LO, HI]; either end may be empty, e.g. a0=0: (repeatable).",
)
@click.option(
    "--fix",
    "fix_items",
    multiple=True,
    metavar="NAME=VALUE",
    help="Hold a model parameter at VALUE: it is not estimated (repeatable).",
)
@click.option(
    "--criterion",
    type=click.Choice(["bic", "aic", "validation"]),
    default="bic",
    show_default=True,
    help="With several --model: what chooses (the lowest BIC or AIC, or the highest fit % "
    "on --validation).",
)
@click.option(
    "--validation",
    "validation_path",
    type=click.Path(dir_okay=False),
    help="With several --model: a second data set (read like DATA) for the validation fit % "
    "column.",
)
@click.option(
    "--validation-input",
    "validation_input",
    type=click.Path(dir_okay=False),
    help="The input file of --validation, unless it has a 'u' column.",
)
@click.option(
    "--hold-input",
    is_flag=True,
    help="Hold the --input file's last value after its end (as a DAC does): an input file "
    "with one value per sample ends before a jittered last instant may fall, which the fit "
    "otherwise reports (the jitter's reach past the input's end).",
)
def fit(
    data_path: str,
    input_path: str | None,
    model_specs: tuple[str, ...],
    jitter_spec: str,
    method: str,
    noise_std: float | None,
    T: str | None,
    out: str,
    level: float,
    seed: int,
    plots: bool,
    quiet: bool,
    start_items: tuple[str, ...],
    bound_items: tuple[str, ...],
    fix_items: tuple[str, ...],
    criterion: str,
    validation_path: str | None,
    validation_input: str | None,
    hold_input: bool,
) -> None:
    """Fit a continuous-time model to DATA, accounting for sampling jitter.

    Prints a summary and writes OUT/result.json (parameters, standard errors, covariance,
    jitter law, method, data checksum, library version), OUT/report.md and its figures.
    Exits with status 3 if the search did not converge (the outputs are still written).
    A diagnostic that cannot run is reported as skipped; the fit is written regardless.
    The fitted (or assumed) jitter std is cross-checked against the detection test: a
    contradiction (jitter ~0 where the test finds it, or large where it finds none) is
    printed as a warning, with what to try, and listed under "warnings" in result.json.

    Times in --jitter and --T take a unit (sigma=80ms, --T 0.5s); a bare number is in
    DATA's time_unit (seconds unless the file says otherwise). --start, --bounds and --fix
    control the search over the model's parameters (both the ordinary and the method's fit);
    result.json lists them under "model".

    With several --model, every model is fitted first (jitterid.select_order): the table is
    printed and written to OUT/order.json and report.md, and the fit goes on with the
    chosen model exactly as with that one --model.
    """
    from .. import __version__

    with _param("'--model'"):
        structures = [parse_model(spec) for spec in model_specs]
        for i, st in enumerate(structures):
            if st in structures[:i]:
                raise ValueError(f"model {model_specs[i]!r} is given twice; give each model once")
    structure, model_spec = structures[0], model_specs[0]
    if len(structures) == 1 and (validation_path or criterion != "bic"):
        raise click.UsageError(
            "--validation and --criterion choose between several --model; give two or more"
        )
    if len(structures) > 1 and (start_items or bound_items or fix_items):
        raise click.UsageError(
            "--start, --bounds and --fix name one model's parameters; with several --model, "
            "select the order first, then constrain the chosen model in a second fit"
        )
    if validation_input and not validation_path:
        raise click.UsageError("--validation-input needs --validation (the data set it drives)")
    if criterion == "validation" and not validation_path:
        raise click.UsageError("--criterion validation needs a --validation data set")
    with _param("'--jitter'"):
        j0 = parse_jitter(jitter_spec)  # the syntax, before any work; units once DATA is read
    try:
        structure = constrain(structure, j0, start=start_items, bounds=bound_items, fix=fix_items)
    except OptionError as exc:
        raise click.BadParameter(str(exc), param_hint=f"'{exc.option}'") from None
    if as_estimator(method).ignores_jitter and not structure.param_names:
        raise click.UsageError(
            "--fix holds every parameter of the model, so --method ls has nothing to estimate; "
            "free a parameter, or estimate the jitter with another method and a jitter family"
        )
    if as_estimator(method).ignores_jitter and isinstance(j0, JitterFamily):
        raise click.UsageError(
            "--method ls ignores jitter, so it cannot estimate a jitter family; use another "
            "method, or --jitter none / a known law"
        )
    out_dir = Path(out)
    _check_out_dir(out_dir)
    ds = _load(data_path, input_path, T, noise_std, hold_input)
    with _param("'--jitter'"):
        jitter = parse_jitter(jitter_spec, time_unit=_file_unit(ds))
    order, chosen = None, None
    if len(structures) > 1:
        order = _select(
            ds,
            structures,
            model_specs,
            jitter,
            method,
            criterion,
            T,
            quiet,
            out_dir,
            validation_path,
            validation_input,
        )
        assert order.chosen is not None  # _select exits otherwise
        structure, model_spec, chosen = (
            structures[order.chosen],
            model_specs[order.chosen],
            order.result,
        )
    ordinary_only = as_estimator(method).ignores_jitter  # ls: the ordinary fit is the fit
    stages = ["ordinary LS fit", *([] if ordinary_only else [f"{method} fit"])]
    stages += ["diagnostics", "writing results" + (" and figures" if plots else "")]

    def run(bar: _Progress) -> tuple[list[Path], FitReport, OSError | None]:
        with _clean_errors("the fit failed"):
            # (every parameter fixed: 'ls' refuses a known system; bcls without jitter is its
            # criterion, evaluated at the fixed system)
            ls = fit_model(
                ds.data, structure, NoJitter(), "ls" if structure.param_names else "bcls"
            )
            if ordinary_only:
                res = ls
            else:
                bar.stage(f"{method} fit")
                # the selection's fit of the chosen model is this very fit (same data and options)
                res = (
                    chosen if chosen is not None else fit_model(ds.data, structure, jitter, method)
                )
        bar.stage("diagnostics")
        # The fit is done: from here on nothing may throw it away. A diagnostic that cannot
        # run is reported as skipped, with its reason, and the results are written regardless.
        skipped: list[tuple[str, str]] = []
        det = _diagnostic(
            skipped, "jitter detection", lambda: detect_jitter(ds.data, ls, level=level)
        )
        xc = None
        if det is not None:  # for ls too: it assumes no jitter, which the test may contradict
            xc = _diagnostic(skipped, "jitter cross-check", lambda: cross_check_jitter(res, det))
        checks: list[Any] = []
        z = _diagnostic(skipped, "residual checks", lambda: standardized_residuals(ds.data, res))
        if z is not None:
            for name, make in (
                ("Ljung-Box test", lambda: ljung_box(z)),
                (
                    "input correlation test",
                    lambda: input_correlation_test(z, _input_at_samples(ds.data)),
                ),
            ):
                c = _diagnostic(skipped, name, make)
                if c is not None:
                    checks.append(c)
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
            cross_check=xc,
            checks=tuple(checks),
            level=level,
            seed=seed,
            version=__version__,
            skipped=tuple(skipped),
            order=order,
        )
        bar.stage(stages[-1])
        try:
            return write_outputs(rep, out_dir, plots=plots), rep, None
        except OSError as exc:
            return [], rep, exc

    with _progress(stages, quiet) as bar:
        written, rep, failed = run(bar)
    res, det, xc, checks, skipped = (
        rep.result,
        rep.detection,
        rep.cross_check,
        rep.checks,
        rep.skipped,
    )
    # The bar is gone: stdout gets the summary alone.
    if failed is not None:
        click.echo(_safe_summary(res))
        raise click.ClickException(
            f"cannot write the results into {str(out_dir)!r} ({_one_line(failed)}); the fit "
            "above was not saved: free some space or choose another --out and run again"
        ) from None
    click.echo(_safe_summary(res))
    if det is not None:
        click.echo(det.summary())
    if xc is not None:
        click.echo(xc.summary())
    for c in checks:
        click.echo(c.summary())
    for name, why in skipped:
        click.echo(f"skipped {name}: {why}")
    click.echo(
        "wrote "
        + ", ".join(str(p) for p in [*written, *([out_dir / "order.json"] if order else [])])
    )
    if not res.success:
        click.echo(f"error: the fit did not converge: {res.status.value}", err=True)
        raise click.exceptions.Exit(3)


def _select(
    ds: Dataset,
    structures: list[ModelStructure],
    specs: tuple[str, ...],
    jitter: JitterLaw | JitterFamily,
    method: str,
    criterion: str,
    T: str | None,
    quiet: bool,
    out_dir: Path,
    validation_path: str | None,
    validation_input: str | None,
) -> OrderSelection:
    """``fit`` with several --model: the selection, its table on stdout and OUT/order.json;
    exits 1 when no model could be fitted at all."""
    from .. import __version__

    val = _load(validation_path, validation_input, T, None) if validation_path else None
    with _progress(["order selection"], quiet), _clean_errors("the order selection failed"):
        order = select_order(
            ds.data,
            structures,
            jitter,
            method,
            criterion=criterion,
            validation=None if val is None else val.data,
        )
    click.echo(order.summary())
    doc = {
        "jitterid_version": __version__,
        "models": list(specs),
        "data_sha256": ds.sha256,
        "validation_sha256": None if val is None else val.sha256,
        **order.to_dict(),
        "chosen_model": None if order.chosen is None else specs[order.chosen],
    }
    text = json.dumps(doc, indent=2) + "\n"
    with _clean_errors("cannot write order.json"):
        atomic_write(out_dir / "order.json", lambda fh: fh.write(text))
    if order.chosen is None:
        raise click.ClickException(
            f"no model could be fitted: {order.reason}; see {out_dir / 'order.json'}"
        )
    return order


def _diagnostic(skipped: list[tuple[str, str]], name: str, make: Callable[[], Any]) -> Any:
    """``make()``, or None with ``(name, reason)`` added to ``skipped`` if it cannot run."""
    try:
        return make()
    except (ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError, MemoryError) as exc:
        skipped.append((name, _one_line(exc) or type(exc).__name__))
        return None


def _safe_summary(res: Any) -> str:
    try:
        return str(res.summary())
    except (ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return (
            f"{res.method} fit: {res.status.value}; {_params_line(res)} (no full summary: "
            f"{_one_line(exc)})"
        )


# ------------------------------------------------------------------------------ bias


@main.command(short_help="Predict an ordinary fit's gain bias |phi(f)| under jitter.")
@click.option(
    "--jitter",
    "jitter_spec",
    required=True,
    help="Jitter law: uniform:a=A | gaussian:sigma=S | sum-of-uniforms:n=N,a=A (known: optional). "
    "Times take a unit (sigma=80ms), seconds if bare.",
)
@click.option(
    "--T",
    "T",
    type=_Time(seconds=True),
    default=1.0,
    show_default=True,
    help="Sets Nyquist 1/(2T); takes a unit (500ms), seconds if bare.",
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
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False),
    callback=_png_path,
    help="Write |phi(f)| to this .png file.",
)
def bias(
    jitter_spec: str, T: float, fmax: float | None, points: int, tol: float, plot_path: str | None
) -> None:
    """Predict the gain bias of an ordinary (jitter-ignoring) fit: |G| is seen as |G| |phi(f)|."""
    law = _law(jitter_spec)
    top = fmax if fmax is not None else 0.5 / T
    f = np.linspace(0.0, top, points)
    with (
        _clean_errors(f"cannot evaluate the gain factor of {law}"),
        np.errstate(all="raise", under="ignore"),
    ):
        g = ls_gain_factor(law, f)
        fb = bias_frequency(law, tol)
    click.echo(f"LS gain factor |phi(f)| for {law}")
    click.echo(f"  {'f (Hz)':>10} {'f / Nyquist':>11} {'|phi(f)|':>10} {'gain bias':>10} {'dB':>8}")
    for fi, gi in zip(f, g, strict=True):
        db = 20 * np.log10(gi) if gi > 0 else -np.inf
        click.echo(
            f"  {fi:>10.4g} {fi * 2 * T:>11.3f} {gi:>10.4f} {100 * (gi - 1):>9.2f}% {db:>8.3f}"
        )
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
            atomic_write(
                Path(plot_path), lambda fh: fig.savefig(fh, dpi=110, format="png"), binary=True
            )
        click.echo(f"wrote {plot_path}")


def _input_at_samples(data: SampledData) -> np.ndarray:
    """u(kT) of the data (the command line fits systems driven by an input)."""
    if data.u is None:
        raise ValueError("data.u: the data have no input")
    return np.asarray(data.u(data.t_nominal), dtype=float)
