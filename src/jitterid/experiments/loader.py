"""Reading TOML experiment definitions: every key checked, every library object built once.

A typo or a bad value fails at once with an :class:`ExperimentError` naming the file and
the dotted key (``table2.toml: sampling.N must be an integer >= 4; got 0``), before any
work starts. Methods are checked against the registry
(:func:`jitterid.estimation.estimators.method_names`) when the file is loaded, so a method
added to the library is accepted without a change here.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from .._checks import T_RANGE_S, TooLargeError, allocation, nesting_depth
from ..estimation.estimators import coloured_method_names, method_names
from ..jitter import registry
from ._schema import ExperimentError, Section, _show
from .config import (
    BJ_PREFIXES,
    FAMILIES,
    LAWS,
    Case,
    Experiment,
    InputSpec,
    LawSpec,
    NoiseSpec,
    Pairs,
    SystemSpec,
    split_method,
)

__all__ = ["load_experiment", "parse_experiment"]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
#: Most realizations per case a definition (or --runs) may ask for.
MAX_RUNS = 10**9
#: Longest time (s) any time value of a definition may have: far beyond any sampling problem.
MAX_TIME_S = 1e9


def load_experiment(path: str | Path) -> Experiment:
    """Read and validate a TOML experiment definition.

    Parameters
    ----------
    path : str or Path
        The TOML file.

    Returns
    -------
    Experiment

    Raises
    ------
    ExperimentError
        On a TOML syntax error, an unknown or missing key or a bad value; the message names
        the file and the key.
    """
    p = Path(path)
    if not p.is_file():
        raise ExperimentError(f"experiment file {str(p)!r} does not exist; check the path")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ExperimentError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    if len(raw) > 10_000_000:
        raise ExperimentError(f"{p.name}: {len(raw)} bytes is too large for a definition")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ExperimentError(
            f"{p.name}: not UTF-8 text (byte {exc.start}); save the file as UTF-8"
        ) from None
    if nesting_depth(text, comments=True) > 32:
        raise ExperimentError(
            f"{p.name}: nested too deeply to be an experiment definition; start from "
            "`jitterid reproduce table2 --print-toml`"
        )
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ExperimentError(f"{p.name}: not valid TOML: {exc}") from exc
    except ValueError as exc:  # e.g. an integer of thousands of digits
        raise ExperimentError(f"{p.name}: not a usable TOML file: {exc}") from None
    except RecursionError:
        raise ExperimentError(
            f"{p.name}: nested too deeply to be an experiment definition; start from "
            "`jitterid reproduce table2 --print-toml`"
        ) from None
    return parse_experiment(data, source=p.name)


def parse_experiment(data: dict[str, Any], source: str = "<experiment>") -> Experiment:
    """Validate a parsed TOML document (see :func:`load_experiment`)."""
    top = Section(
        data,
        "",
        source,
        (
            "experiment",
            "sampling",
            "input",
            "system",
            "jitter",
            "cases",
            "estimators",
            "paper",
            "noise",
        ),
    )
    ex = top.table("experiment", ("name", "title", "description", "runs", "seed"))
    name = ex.text("name")
    if not _NAME.match(name):
        raise ex.fail(
            "name", f"must be letters, digits, '_', '-' or '.' (a file name); got {name!r}"
        )
    sa = top.table("sampling", ("T", "N", "noise_std", "noise_known"))
    T, N = sa.number("T", above=0), sa.integer("N", minimum=4)
    if T > MAX_TIME_S:
        raise sa.fail("T", f"= {T:g} s is beyond any sampling problem (at most {MAX_TIME_S:g} s)")
    if T_RANGE_S[0] > T:
        raise sa.fail(
            "T",
            f"= {T:g} s is below the shortest sampling interval jitterid handles "
            f"({T_RANGE_S[0]:g} s); give the times in another unit",
        )
    _fits(sa, "N", 16.0 * N, f"N = {N}", "use fewer samples")
    system = _system(
        top.table("system", ("structure", "truth", "num", "den", "num_order", "den_order"))
    )
    jit = top.table("jitter", ("model", *{k for _, ks in FAMILIES.values() for k in ks}))
    jitter_model, jitter_options = _jitter_model(jit)
    cases = tuple(_case(c) for c in top.tables("cases", ("name", "law", "paper_case")))
    if len({c.name for c in cases}) != len(cases):
        raise top.fail("cases", "must have distinct names")
    noise = (
        _noise(top.table("noise", ("structure", "num_order", "den_order", "truth")))
        if top.has("noise")
        else None
    )
    est = top.table("estimators", ("methods", "crb", "crb_runs"))
    methods = _methods(est, jitter_model, system, noise is not None)
    _check_bj(est, methods, jitter_model, cases)
    crb = est.flag("crb", default=False)
    if crb and noise is not None:
        raise est.fail(
            "crb",
            "is the bound for white noise (the exact likelihood of notes 4); it does not hold "
            "with a [noise] section: set crb = false",
        )
    if crb and not (
        sa.flag("noise_known", default=True) and sa.number("noise_std", at_least=0) > 0
    ):
        raise est.fail(
            "crb",
            "needs a known, positive noise_std (the bound is evaluated at the true noise); "
            "set sampling.noise_known = true and noise_std > 0, or crb = false",
        )
    crb_runs = est.integer("crb_runs", minimum=1) if est.has("crb_runs") else None
    if crb_runs is not None and not crb:
        raise est.fail("crb_runs", "is how many realizations store the bound; it needs crb = true")
    paper_table, labels = _paper(top, methods)
    runs = ex.integer("runs", minimum=1)
    if runs > MAX_RUNS:
        raise ex.fail("runs", f"must be at most {MAX_RUNS:g} realizations per case; got {runs}")
    exp = Experiment(
        name=name,
        title=ex.text("title", default=name),
        description=_description(ex),
        runs=runs,
        seed=ex.integer("seed", minimum=0),
        T=T,
        N=N,
        noise_std=sa.number("noise_std", at_least=0),
        noise_known=sa.flag("noise_known", default=True),
        input=_input(
            top.table(
                "input",
                (
                    "kind",
                    "margin",
                    "levels",
                    "mean_hold",
                    "freqs",
                    "amplitudes",
                    "phases",
                    "steady_state",
                ),
            )
        ),
        system=system,
        jitter_model=jitter_model,
        jitter_options=jitter_options,
        cases=cases,
        methods=methods,
        crb=crb,
        crb_runs=crb_runs,
        paper_table=paper_table,
        paper_labels=labels,
        source=source,
        noise=noise,
    )
    _check_coverage(exp, top)
    if exp.input.kind == "telegraph":
        _fits(
            top.table(
                "input",
                (
                    "kind",
                    "margin",
                    "levels",
                    "mean_hold",
                    "freqs",
                    "amplitudes",
                    "phases",
                    "steady_state",
                ),
            ),
            "mean_hold",
            4 * (exp.duration / exp.input.mean_hold + 10),
            f"a telegraph input of {exp.duration:g} s with mean_hold = {exp.input.mean_hold:g} s",
            "use a longer mean_hold (fewer switches) or fewer samples",
        )
    return exp


def _fits(sec: Section, key: str, elements: float, what: str, fix: str) -> None:
    """Refuse at load time what one realization could not hold in memory."""
    try:
        allocation(elements, what, fix=fix)
    except TooLargeError as exc:
        raise sec.fail(key, f"is too large: {exc}") from None


def _description(sec: Section) -> str:
    text = sec.raw("description", "")
    if not isinstance(text, str):
        raise sec.fail("description", f"must be a string; got {_show(text)}")
    return text


def _system(sec: Section) -> SystemSpec:
    kind = sec.text("structure", choices=("known", "pole_pair", "rational"))
    if kind == "known":
        spec = SystemSpec(kind, num=sec.numbers("num"), den=sec.numbers("den"))
        for k in ("truth", "num_order", "den_order"):
            if sec.has(k):
                raise sec.fail(k, "is not used by structure 'known' (give num and den); remove it")
    else:
        for k in ("num", "den"):
            if sec.has(k):
                raise sec.fail(k, f"is not used by structure '{kind}' (give truth); remove it")
        orders = {}
        if kind == "rational":
            orders = {
                "num_order": sec.integer("num_order", minimum=0),
                "den_order": sec.integer("den_order", minimum=1),
            }
        spec = SystemSpec(kind, **orders)  # type: ignore[arg-type]
        names = _built(sec, "structure", spec.model).param_names
        truth = sec.table("truth", names)
        spec = dataclasses.replace(spec, truth=tuple((n, truth.number(n)) for n in names))
    _built(sec, "truth" if spec.truth else "den", spec.true_system)
    return spec


def _kind(sec: Section, k: str, table: dict[str, Any], *extra: str) -> str:
    """A law or family kind, spelled with '_' or '-' (:mod:`jitterid.jitter.registry`), as
    the table spells it; otherwise the usual error listing the choices."""
    v = sec.raw(k)
    if isinstance(v, str) and v not in extra:
        spelled = registry.canonical(v).replace("-", "_")
        if spelled in table:
            return spelled
    return sec.text(k, choices=(*extra, *table))


def _jitter_model(sec: Section) -> tuple[str, Pairs]:
    model = _kind(sec, "model", FAMILIES, "known")
    allowed = FAMILIES[model][1] if model != "known" else ()
    for k in sec.data:
        if k != "model" and k not in allowed:
            raise sec.fail(
                k,
                f"is not an option of jitter model '{model}' (options: "
                f"{', '.join(allowed) or 'none'}); remove it",
            )
    opts = tuple((k, sec.number(k, above=0)) for k in allowed if sec.has(k))
    if model != "known":
        _built(sec, "model", lambda: FAMILIES[model][0](**dict(opts)))
    return model, opts


def _case(sec: Section) -> Case:
    name = sec.text("name")
    if not _NAME.match(name):
        raise sec.fail("name", f"must be letters, digits, '_', '-' or '.'; got {name!r}")
    raw = sec.raw("law")
    kind = _kind(
        Section(
            raw, sec.key("law"), sec.source, ("kind", *{p for _, ps in LAWS.values() for p in ps})
        ),
        "kind",
        LAWS,
    )
    law_sec = Section(raw, sec.key("law"), sec.source, ("kind", *LAWS[kind][1]))
    spec = LawSpec(kind, tuple((p, law_sec.number(p, at_least=0)) for p in LAWS[kind][1]))
    for p, v in spec.params:
        if v > MAX_TIME_S:
            raise law_sec.fail(
                p, f"= {v:g} is beyond any sampling problem (at most {MAX_TIME_S:g})"
            )
    _built(law_sec, "kind", spec.build)
    paper = sec.integer("paper_case", minimum=1) if sec.has("paper_case") else None
    return Case(name, spec, paper)


def _methods(sec: Section, jitter_model: str, system: SystemSpec, noise: bool) -> tuple[str, ...]:
    methods = sec.texts("methods")
    # Box-Jenkins estimators (a [noise] section): "bj-<criterion>" and "jbj-<criterion>".
    # (the registry is asked now, so that an estimator registered after import is known)
    bj = [p + m for p in BJ_PREFIXES for m in coloured_method_names()] if noise else []
    known = [*method_names(), *bj]
    for i, m in enumerate(methods):
        if m not in known:
            close = difflib.get_close_matches(m, known, n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            extra = "" if noise else "; 'bj-*'/'jbj-*' estimators need a [noise] section"
            raise sec.fail(
                f"methods[{i}]",
                f"is {m!r}, not a method{hint}; choose from {', '.join(known)}{extra}",
            )
    if len(set(methods)) != len(methods):
        raise sec.fail("methods", f"lists a method twice: {methods}")
    if "ls" in methods and jitter_model != "known":
        raise sec.fail(
            "methods",
            "includes 'ls', which ignores the jitter and cannot estimate "
            "a jitter family; remove it or set jitter.model = 'known'",
        )
    if "ls" in methods and system.structure == "known":
        raise sec.fail(
            "methods",
            "includes 'ls', which has nothing to estimate when the system "
            "is known and the jitter is known; remove it",
        )
    return methods


def _noise(sec: Section) -> NoiseSpec:
    sec.text("structure", choices=("rational",))
    spec = NoiseSpec(
        sec.integer("num_order", minimum=0, default=0),
        sec.integer("den_order", minimum=1, default=1),
        (),
    )
    names = _built(sec, "num_order", spec.structure).param_names
    truth = sec.table("truth", names)
    spec = dataclasses.replace(spec, truth=tuple((n, truth.number(n)) for n in names))
    _built(sec, "truth", spec.true_model)
    return spec


def _check_bj(
    sec: Section, methods: tuple[str, ...], jitter_model: str, cases: tuple[Case, ...]
) -> None:
    """A 'jbj-' estimator fits the family of each case's law kind: the jitter must be known
    (else 'bj-' already estimates the family) and every law must have a family."""
    if not any(split_method(m)[0] == "jbj-" for m in methods):
        return
    if jitter_model != "known":
        raise sec.fail(
            "methods",
            "lists a 'jbj-' estimator with jitter.model a family: 'bj-' estimators already "
            "estimate the family then; use 'bj-' or set jitter.model = 'known'",
        )
    for c in cases:
        if c.law.kind not in FAMILIES:
            raise sec.fail(
                "methods",
                f"lists a 'jbj-' estimator, but case '{c.name}' has a '{c.law.kind}' law, which "
                f"has no family to estimate (families: {', '.join(FAMILIES)})",
            )


def _paper(
    top: Section, methods: tuple[str, ...]
) -> tuple[int | None, tuple[tuple[str, str], ...]]:
    if not top.has("paper"):
        return None, ()
    sec = top.table("paper", ("table", "estimators"))
    table = sec.integer("table", minimum=1)
    est = sec.table("estimators", methods, default={})
    return table, tuple((m, est.text(m)) for m in methods if est.has(m))


def _input(sec: Section) -> InputSpec:
    kind = sec.text("kind", choices=("telegraph", "multisine"))
    margin = sec.number("margin", above=0, default=2.0)
    if margin > MAX_TIME_S:
        raise sec.fail("margin", f"= {margin:g} s is beyond any sampling problem")
    if kind == "telegraph":
        levels = sec.numbers("levels", length=2, default=[-0.5, 0.5])
        return InputSpec(
            kind, margin, levels=levels, mean_hold=sec.number("mean_hold", above=0, default=1.0)
        )
    freqs = sec.numbers("freqs")
    amps = sec.numbers("amplitudes", length=len(freqs))
    phases = sec.numbers("phases", length=len(freqs)) if sec.has("phases") else None
    spec = InputSpec(
        kind,
        margin,
        freqs=freqs,
        amplitudes=amps,
        phases=phases,
        steady_state=sec.flag("steady_state", default=False),
    )
    _built(sec, "freqs", lambda: spec.build(10.0, np.random.default_rng(0)))
    return spec


def _check_coverage(exp: Experiment, top: Section) -> None:
    """The input must last past the last jittered instant (N-1) T + max tau of every case."""
    for case in exp.cases:
        hi = case.law.build().support[1]
        if (exp.N - 1) * exp.T + hi >= exp.duration:
            raise top.fail(
                "input.margin",
                f"= {exp.input.margin:g} is too short for case "
                f"'{case.name}' (jitter up to {hi:g} s): it must exceed {hi - exp.T:g}",
            )


def _built(sec: Section, key: str, make: Any) -> Any:
    """Build a library object, turning its own error into one that names ``key``."""
    try:
        return make()
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise sec.fail(key, f"gives an invalid model: {exc}") from exc
