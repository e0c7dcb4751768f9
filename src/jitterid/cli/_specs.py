"""Parse the command line's model and jitter specifications.

Model: ``polepair`` (the paper's (27), k0 / ((s - pr)^2 + pi^2)) or ``tf:NUM,DEN`` for a
rational model with NUM zeros and DEN poles (``RationalModel(NUM, DEN)``: parameters
b_NUM..b_0 of the numerator, a_{DEN-1}..a_0 of the monic denominator). ``tf:0,2`` is
b0 / (s^2 + a1 s + a0).

Jitter: ``none``; a known law ``known:uniform:a=0.5``, ``known:gaussian:sigma=0.1``,
``known:sum-of-uniforms:n=2,a=0.5``, ``known:generalized-normal:std=0.1,beta=3``,
``known:dual-dirac:rj=0.05,dj=0.2``; or a family to estimate, ``uniform``, ``gaussian``,
``sum-of-uniforms``, ``generalized-normal``, ``dual-dirac``, optionally bounded (``uniform:a_max=0.5``,
``sum-of-uniforms:n_max=10,a_max=0.5``, ``gaussian:sigma_max=0.3``). Where only a law makes
sense (``simulate``, ``bias``) the ``known:`` prefix may be left out.

Times (``a``, ``sigma``, ``std``, ``rj``, ``dj`` and their bounds) take a unit, ``sigma=80ms``;
a bare number is in the data file's ``time_unit`` (seconds where there is no file). ``n`` and
``beta`` have no unit. Kinds may be spelled with ``_`` too (``sum_of_uniforms``); the one table
of kinds is :mod:`jitterid.jitter.registry`.
"""

from __future__ import annotations

import math
from typing import Any

from ..io import parse_time
from ..jitter import registry
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..systems.structures import ModelStructure, PolePairGain, RationalModel

__all__ = ["model_label", "parse_floats", "parse_jitter", "parse_model"]

# the registry's tables, spelled with "-" (either spelling is accepted: registry.canonical)
_LAWS: dict[str, tuple[type[JitterLaw], tuple[str, ...]]] = registry.table(
    registry.LAWS, "-", exclude=("none",)
)
_FAMILIES: dict[str, tuple[type[JitterFamily], tuple[str, ...]]] = registry.table(registry.FAMILIES, "-")
#: Parameters without a time unit (all others are times).
_UNITLESS = registry.UNITLESS
#: Largest time accepted in a jitter specification (s): far beyond any sampling problem.
MAX_TIME_S = 1e9
JITTER_HELP = (
    "none | known:uniform:a=A | known:gaussian:sigma=S | known:sum-of-uniforms:n=N,a=A | "
    "known:generalized-normal:std=S,beta=B | known:dual-dirac:rj=R,dj=D "
    "(a known law) | uniform | gaussian | sum-of-uniforms | generalized-normal | dual-dirac "
    "(a family to estimate, optionally "
    "bounded, e.g. uniform:a_max=0.5). Times take a unit (sigma=80ms); a bare number is in "
    "the data file's time_unit (seconds by default)"
)


def parse_model(spec: str) -> ModelStructure:
    """``polepair`` or ``tf:NUM,DEN`` -> a model structure; ValueError with the fix otherwise."""
    s = spec.strip().lower()
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
    raise ValueError(f"unknown model {spec!r}; use 'polepair' or 'tf:NUM,DEN' (e.g. tf:0,2)")


def model_label(structure: ModelStructure) -> str:
    """A readable formula for the structure."""
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
                raise ValueError(f"jitter {spec!r}: {key}={value.strip()!r} must be a number <= 1e6")
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
    kw = _kwargs(body, keys, f"the {name} law", spec, unit)
    missing = [k for k in keys if k not in kw]
    if missing:
        raise ValueError(
            f"jitter {spec!r}: the {name} law needs "
            + ",".join(f"{k}=VALUE" for k in keys)
            + f" (missing {', '.join(missing)})"
        )
    law: Any = _build(cls, kw, spec)
    return law


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
    family: Any = _build(cls, _kwargs(body.strip(), keys, f"the {name} family", spec, time_unit), spec)
    return family
