"""JSON encoding of jitterid's value objects (laws, structures, systems, noise models).

A jitterid dataclass is written as ``{"__class__": "module:QualName", field: value, ...}``
with its init fields; numpy arrays become lists. A field whose metadata names another
constructor keyword, ``field(metadata={"init": "bounds"})``, is written under that keyword
(a class with its own ``__init__``, where the field's name means something else:
:class:`~jitterid.systems.constrained.Constrained`). Decoding imports the class again, and only
from inside the ``jitterid`` package, so a JSON file cannot name arbitrary code. An object
that is not a dataclass with init fields (e.g. :class:`~jitterid.CustomJitter`, which holds
a function) cannot be written to JSON; pickle it instead.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Any

import numpy as np

__all__ = ["decode", "encode"]

_TAG = "__class__"


def encode(obj: Any) -> Any:
    """A JSON-compatible form of ``obj`` (see the module docstring)."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else repr(v)  # "inf", "-inf", "nan"
    if isinstance(obj, np.ndarray):
        return [encode(v) for v in obj.tolist()] if obj.ndim else encode(obj.item())
    if isinstance(obj, (list, tuple)):
        return [encode(v) for v in obj]
    if isinstance(obj, dict):
        return {str(k): encode(v) for k, v in obj.items()}
    cls = type(obj)
    params = getattr(cls, "__dataclass_params__", None)
    if (
        dataclasses.is_dataclass(obj)
        and cls.__module__.startswith("jitterid.")
        and params is not None
        and params.init
    ):
        out: dict[str, Any] = {_TAG: f"{cls.__module__}:{cls.__qualname__}"}
        for f in dataclasses.fields(obj):
            if f.init:
                out[f.metadata.get("init", f.name)] = encode(getattr(obj, f.name))
        return out
    raise ValueError(
        f"a {cls.__name__} cannot be written to JSON (it is not a plain jitterid value "
        "object); pickle the result instead"
    )


#: Deepest nesting of value objects :func:`decode` follows (a model holds a model holds a
#: system ...: a handful of levels in practice); deeper input is refused, not recursed into.
MAX_DEPTH = 32


def decode(data: Any, _depth: int = 0) -> Any:
    """Inverse of :func:`encode`.

    Only a class :func:`encode` can write is built: a dataclass with init fields *defined* in
    the ``jitterid`` module its tag names, reached through classes only (not through a module
    attribute, which could lead anywhere). Anything else, an unknown module or class, fields
    the class does not take and nesting deeper than :data:`MAX_DEPTH` raise
    :class:`ValueError` naming the problem.

    Parameters
    ----------
    data : Any
        The JSON-compatible form :func:`encode` returned.
    """
    if _depth > MAX_DEPTH:
        raise ValueError(f"the value objects are nested more than {MAX_DEPTH} levels deep")
    if isinstance(data, list):
        return [decode(v, _depth + 1) for v in data]
    if isinstance(data, str) and data in ("inf", "-inf", "nan"):
        return float(data)
    if not isinstance(data, dict):
        return data
    if _TAG not in data:
        return {k: decode(v, _depth + 1) for k, v in data.items()}
    cls = _value_class(data[_TAG])
    kwargs = {k: decode(v, _depth + 1) for k, v in data.items() if k != _TAG}
    try:
        return cls(**kwargs)
    except TypeError as exc:  # a missing or unknown field (or one of the wrong kind)
        raise ValueError(f"cannot build {data[_TAG]!r} from its fields: {exc}") from None


def _value_class(tag: Any) -> type:
    """The class a ``__class__`` tag names, if :func:`encode` could have written it."""
    module, _, name = str(tag).partition(":")
    if not isinstance(tag, str) or not module.startswith("jitterid.") or not name:
        raise ValueError(f"refusing to decode class {tag!r}: not a jitterid class")
    try:
        obj: Any = importlib.import_module(module)
    except ImportError:
        raise ValueError(f"refusing to decode {tag!r}: no module {module!r} in jitterid") from None
    for part in name.split("."):
        obj = getattr(obj, part, None)
        if not isinstance(obj, type):  # through classes only, never a module attribute
            # the file's content is wrong (not an argument's type): ValueError
            raise ValueError(  # noqa: TRY004
                f"refusing to decode {tag!r}: {module} defines no class {name!r}"
            )
    params = getattr(obj, "__dataclass_params__", None)
    if not (
        obj.__module__ == module
        and obj.__qualname__ == name
        and dataclasses.is_dataclass(obj)
        and params is not None
        and params.init
    ):
        raise ValueError(f"refusing to decode {tag!r}: not a jitterid value object")
    return obj  # type: ignore[return-value]
