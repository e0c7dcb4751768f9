"""Parse the command line's model and jitter specifications.

Model: ``polepair`` (the paper's (27), k0 / ((s - pr)^2 + pi^2)) or ``tf:NUM,DEN`` for a
rational model with NUM zeros and DEN poles (``RationalModel(NUM, DEN)``: parameters
b_NUM..b_0 of the numerator, a_{DEN-1}..a_0 of the monic denominator). ``tf:0,2`` is
b0 / (s^2 + a1 s + a0). Either may end in ``+delay``: an input-output delay ``delay_s`` >= 0
is estimated with the other parameters (``tf:0,2+delay``).

Jitter: ``none``; a known law ``known:uniform:a=0.5``, ``known:gaussian:sigma=0.1``,
``known:sum-of-uniforms:n=2,a=0.5``, ``known:generalized-normal:std=0.1,beta=3``,
``known:dual-dirac:rj=0.05,dj=0.2``; or a family to estimate, ``uniform``, ``gaussian``,
``sum-of-uniforms``, ``generalized-normal``, ``dual-dirac``, optionally bounded
(``uniform:a_max=0.5``, ``sum-of-uniforms:n_max=10,a_max=0.5``, ``gaussian:sigma_max=0.3``). Where
only a law makes sense (``simulate``, ``bias``) the ``known:`` prefix may be left out.

Search constraints on the model's parameters (repeatable options of ``fit``):
``--start NAME=VALUE``, ``--bounds NAME=LO:HI`` (either end may be empty: ``a0=0:``) and
``--fix NAME=VALUE``; they wrap the structure in :class:`jitterid.Constrained`. Values are
plain numbers in the model's units (rad/s for poles).

A known law takes ``mean=TIME`` too, for a jitter that is late on average
(``known:uniform:a=0.5,mean=20ms``): it cannot be told apart from a delay, so a ``+delay``
model estimates the delay with this mean held fixed.

Times (``a``, ``sigma``, ``std``, ``rj``, ``dj`` and their bounds) take a unit, ``sigma=80ms``;
a bare number is in the data file's ``time_unit`` (seconds where there is no file). ``n`` and
``beta`` have no unit. Kinds may be spelled with ``_`` too (``sum_of_uniforms``); the one table
of kinds is :mod:`jitterid.jitter.registry`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..io import parse_time
from ..jitter import registry
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter, Shifted
from ..params import did_you_mean
from ..systems.constrained import Constrained
from ..systems.structures import Delayed, ModelStructure, PolePairGain, RationalModel

__all__ = [
    "OptionError",
    "constrain",
    "model_label",
    "parse_assignments",
    "parse_floats",
    "parse_jitter",
    "parse_model",
]

# the registry's tables, spelled with "-" (either spelling is accepted: registry.canonical)
_LAWS: dict[str, tuple[type[JitterLaw], tuple[str, ...]]] = registry.table(
    registry.LAWS, "-", exclude=("none",)
)
_FAMILIES: dict[str, tuple[type[JitterFamily], tuple[str, ...]]] = registry.table(
    registry.FAMILIES, "-"
)
#: Parameters without a time unit (all others are times).
_UNITLESS = registry.UNITLESS
#: Largest time accepted in a jitter specification (s): far beyond any sampling problem.
MAX_TIME_S = 1e9
JITTER_HELP = (
    "none | known:uniform:a=A | known:gaussian:sigma=S | known:sum-of-uniforms:n=N,a=A | "
    "known:generalized-normal:std=S,beta=B | known:dual-dirac:rj=R,dj=D "
    "(a known law; add ,mean=M for jitter late on average by M) | uniform | gaussian | "
    "sum-of-uniforms | generalized-normal | dual-dirac "
    "(a family to estimate, optionally "
    "bounded, e.g. uniform:a_max=0.5). Times take a unit (sigma=80ms); a bare number is in "
    "the data file's time_unit (seconds by default)"
)


def parse_model(spec: str) -> ModelStructure:
    """``polepair`` or ``tf:NUM,DEN``, optionally ``+delay`` (an input-output delay
    ``delay_s`` >= 0, :class:`jitterid.Delayed`) -> a model structure; ValueError with the
    fix otherwise."""
    s = spec.strip().lower()
    base, plus, extra = s.partition("+")
    if plus:
        if extra.strip() != "delay":
            raise ValueError(
                f"model {spec!r}: the only addition is +delay (an input-output delay), e.g. "
                "tf:0,2+delay"
            )
        return Delayed(parse_model(base))
    if s == "polepair":
        return PolePairGain()
    if s.startswith("tf:"):
        parts = [p.strip() for p in s[3:].split(",")]
        if len(parts) != 2 or not all(p.isdigit() for p in parts):
            raise ValueError(
                f"model {spec!r}: write tf:NUM,DEN with NUM zeros and DEN poles as whole "
                "numbers, e.g. tf:0,2 for b0 / (s^2 + a1 s + a0)"
            )
        num, den = (int(p) for p in parts)
        if den < 1 or num > den:
            raise ValueError(
                f"model {spec!r}: need DEN >= 1 poles and NUM <= DEN zeros (a proper model); "
                "e.g. tf:0,2 or tf:1,2"
            )
        return RationalModel(num, den)
    raise ValueError(
        f"unknown model {spec!r}; use 'polepair' or 'tf:NUM,DEN' (e.g. tf:0,2), optionally "
        "with +delay"
    )


def model_label(structure: ModelStructure) -> str:
    """A readable formula for the structure (a constrained one's: its inner structure's)."""
    if isinstance(structure, Constrained):
        return model_label(structure.structure)
    if isinstance(structure, Delayed):
        return f"{model_label(structure.structure)} e^(-s delay_s)"
    if isinstance(structure, PolePairGain):
        return "G(s) = k0 / ((s - pr)^2 + pi^2)"
    if isinstance(structure, RationalModel):
        b = " + ".join(
            f"b{i} s^{i}" if i > 1 else (f"b{i} s" if i == 1 else "b0")
            for i in range(structure.num_order, -1, -1)
        )
        a = " + ".join(
            [f"s^{structure.den_order}" if structure.den_order > 1 else "s"]
            + [
                f"a{i} s^{i}" if i > 1 else (f"a{i} s" if i == 1 else "a0")
                for i in range(structure.den_order - 1, -1, -1)
            ]
        )
        return f"G(s) = ({b}) / ({a})"
    return type(structure).__name__


def parse_floats(text: str, name: str) -> list[float]:
    """``"1,2.5,-3"`` -> [1.0, 2.5, -3.0]; ValueError naming ``name`` otherwise."""
    out = []
    for part in text.split(","):
        try:
            val = float(part)
            if not math.isfinite(val):
                raise ValueError(part)
            out.append(val)
        except ValueError:
            raise ValueError(
                f"{name}: {part.strip()!r} is not a number; give comma-separated numbers, "
                "e.g. 6.25,-1.5,2"
            ) from None
    return out


def _kwargs(
    body: str, allowed: tuple[str, ...], what: str, spec: str, unit: str = "s"
) -> dict[str, float]:
    out: dict[str, float] = {}
    if not body:
        return out
    for item in body.split(","):
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or key not in allowed:
            raise ValueError(
                f"jitter {spec!r}: {item.strip()!r} is not a parameter of {what}; write "
                + ",".join(f"{k}=VALUE" for k in allowed)
            )
        if key in out:
            raise ValueError(f"jitter {spec!r}: {key} is given twice")
        if key in _UNITLESS:
            try:
                val = float(value)
            except ValueError:
                raise ValueError(
                    f"jitter {spec!r}: {key}={value.strip()!r} is not a number"
                ) from None
            if not math.isfinite(val) or abs(val) > 1e6:
                raise ValueError(
                    f"jitter {spec!r}: {key}={value.strip()!r} must be a number <= 1e6"
                )
        else:
            try:
                val = parse_time(value, unit, f"jitter {spec!r}: {key}")
            except ValueError as exc:
                raise ValueError(str(exc)) from None
            if abs(val) > MAX_TIME_S:
                raise ValueError(
                    f"jitter {spec!r}: {key}={value.strip()} is {val:.3g} s, longer than any "
                    f"sampling problem (at most {MAX_TIME_S:g} s); check the value and its unit"
                )
        out[key] = val
    return out


def _build(cls: Any, kw: dict[str, float], spec: str) -> Any:
    try:
        return cls(**kw)
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise ValueError(f"jitter {spec!r}: {exc}") from None


def _law(name: str, body: str, spec: str, unit: str = "s") -> JitterLaw:
    if name not in _LAWS:
        raise ValueError(
            f"jitter {spec!r}: unknown law {name!r}; use one of {sorted(_LAWS)}. {JITTER_HELP}"
        )
    cls, keys = _LAWS[name]
    kw = _kwargs(body, (*keys, "mean"), f"the {name} law", spec, unit)
    mean = kw.pop("mean", 0.0)
    missing = [k for k in keys if k not in kw]
    if missing:
        raise ValueError(
            f"jitter {spec!r}: the {name} law needs "
            + ",".join(f"{k}=VALUE" for k in keys)
            + f" (missing {', '.join(missing)})"
        )
    law: Any = _build(cls, kw, spec)
    return Shifted(law, mean) if mean else law


def parse_jitter(
    spec: str, *, law_only: bool = False, time_unit: str = "s"
) -> JitterLaw | JitterFamily:
    """Parse a jitter specification (see the module notes); ValueError with the fix.

    Bare times are in ``time_unit`` (the data file's); the law is returned in seconds.
    """
    s = spec.strip()
    low = s.lower()
    if low == "none":
        return NoJitter()
    if low.startswith("known:"):
        name, _, body = s[6:].partition(":")
        return _law(registry.canonical(name), body.strip(), spec, time_unit)
    name, _, body = s.partition(":")
    name = registry.canonical(name)
    if law_only:
        return _law(name, body.strip(), spec, time_unit)
    if name not in _FAMILIES:
        raise ValueError(f"jitter {spec!r} is not recognised; use {JITTER_HELP}")
    cls, keys = _FAMILIES[name]
    if body and any(k.split("=")[0].strip() in _LAWS[name][1] for k in body.split(",")):
        raise ValueError(
            f"jitter {spec!r}: to fix the law write known:{s}; to estimate it write {name} "
            f"(optionally bounded: {name}:{keys[0]}=VALUE)"
        )
    family: Any = _build(
        cls, _kwargs(body.strip(), keys, f"the {name} family", spec, time_unit), spec
    )
    return family


# ------------------------------------------------------------------------ search constraints
class OptionError(ValueError):
    """A bad value of the command-line option ``option`` (e.g. ``"--fix"``)."""

    def __init__(self, option: str, message: str) -> None:
        super().__init__(message)
        self.option = option


#: the options' names by the argument of :class:`Constrained` they fill
_OPTIONS = {"start": "--start", "bounds": "--bounds", "fixed": "--fix"}


def parse_assignments(
    items: Sequence[str],
    option: str,
    structure: ModelStructure,
    jitter: JitterLaw | JitterFamily | None = None,
) -> dict[str, Any]:
    """``["pr=-1.5", ...]`` of ``option`` -> ``{name: value}``; ``--bounds`` items
    ``NAME=LO:HI`` -> ``{name: (lo, hi)}``, an empty end None. Raises :class:`OptionError`
    naming the option: bad syntax, not a number, lo >= hi, a name given twice, a name that
    is not the model's (with the closest one), a jitter law's parameter (say how to fix or
    bound it with ``--jitter``), ``noise_std`` (``--noise-std``)."""
    names = tuple(structure.param_names)
    bounds = option == "--bounds"
    form = "NAME=LO:HI" if bounds else "NAME=VALUE"
    example = "pr=-3:-1 or a0=0:" if bounds else "pr=-1.5"
    out: dict[str, Any] = {}
    for item in items:
        name, eq, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not eq or not name or not text:
            raise OptionError(option, f"{item!r}: write {form}, e.g. {option} {example}")
        if name not in names:
            raise OptionError(option, f"{item!r}: {_not_a_parameter(name, option, names, jitter)}")
        if name in out:
            raise OptionError(option, f"{name} is given twice; give each parameter once")
        out[name] = _bound_pair(item, text, option) if bounds else _number(item, text, option)
    return out


def constrain(
    structure: ModelStructure,
    jitter: JitterLaw | JitterFamily | None = None,
    *,
    start: Sequence[str] = (),
    bounds: Sequence[str] = (),
    fix: Sequence[str] = (),
) -> ModelStructure:
    """``structure`` with the ``--start``, ``--bounds`` and ``--fix`` items applied
    (:class:`Constrained`), or ``structure`` itself when there are none. Raises
    :class:`OptionError` naming the option at fault."""
    if not (start or bounds or fix):
        return structure
    kw = {
        "start": parse_assignments(start, "--start", structure, jitter),
        "bounds": parse_assignments(bounds, "--bounds", structure, jitter),
        "fixed": parse_assignments(fix, "--fix", structure, jitter),
    }
    try:
        return Constrained(structure, **kw)
    except ValueError as exc:  # the message begins with the argument: start, bounds, fixed
        arg = next((a for a in _OPTIONS if str(exc).startswith(a)), "fixed")
        raise OptionError(_OPTIONS[arg], str(exc)) from None


def _number(item: str, text: str, option: str, hint: str = "") -> float:
    try:
        val = float(text)
    except ValueError:
        raise OptionError(option, f"{item!r}: {text!r} is not a number{hint}") from None
    if not math.isfinite(val):
        raise OptionError(option, f"{item!r}: the value must be a finite number{hint}")
    return val


def _bound_pair(item: str, text: str, option: str) -> tuple[float | None, float | None]:
    lo_text, colon, hi_text = text.partition(":")
    if not colon or ":" in hi_text:
        raise OptionError(
            option, f"{item!r}: write NAME=LO:HI, either end empty for no bound (a0=0:, pr=:-1)"
        )
    hint = " (leave an end empty for no bound: a0=0:)"
    ends = [
        None if not t.strip() else _number(item, t.strip(), option, hint)
        for t in (lo_text, hi_text)
    ]
    lo, hi = ends
    if lo is None and hi is None:
        raise OptionError(option, f"{item!r} sets no bound; give LO:, :HI or LO:HI")
    if lo is not None and hi is not None and not lo < hi:
        raise OptionError(
            option,
            f"{item!r}: the low end {lo:g} must be below the high end {hi:g} (to hold the "
            "parameter at a value use --fix NAME=VALUE)",
        )
    return lo, hi


def _not_a_parameter(
    name: str, option: str, names: tuple[str, ...], jitter: JitterLaw | JitterFamily | None
) -> str:
    """Why ``name`` is refused, and what to write instead."""
    if name == "noise_std":
        return (
            "noise_std is not a parameter of the model; give a known noise std with "
            "--noise-std VALUE (without it the criteria that need one estimate it)"
        )
    kinds = [k for k in registry.LAWS.values() if name in k.names]
    if kinds:
        fam = next((k for k in registry.FAMILIES.values() if isinstance(jitter, k.cls)), None)
        kind = (
            fam.name if fam is not None and name in registry.LAWS[fam.name].names else kinds[0].name
        )
        law = ",".join(f"{k}=VALUE" for k in registry.LAWS[kind].names)
        opts = [o for o in registry.FAMILIES[kind].names if o.startswith(f"{name}_")]
        bound = f"{kind}:{opts[0]}=VALUE" if opts else kind
        return (
            f"{name} is a parameter of the jitter law, not of the model "
            f"({', '.join(names) or 'none'}): "
            f"to fix the law write --jitter known:{kind}:{law}; to bound it estimate the family "
            f"with --jitter {bound}" + (f" (options {', '.join(opts)})" if opts else "")
        )
    return (
        f"{name!r} is not a parameter of the model{did_you_mean(name, names)}; its parameters "
        f"are {', '.join(names) or 'none'}"
    )
