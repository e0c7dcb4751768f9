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


def decode(data: Any) -> Any:
    """Inverse of :func:`encode`."""
    if isinstance(data, list):
        return [decode(v) for v in data]
    if isinstance(data, str) and data in ("inf", "-inf", "nan"):
        return float(data)
    if not isinstance(data, dict):
        return data
    if _TAG not in data:
        return {k: decode(v) for k, v in data.items()}
    module, _, name = str(data[_TAG]).partition(":")
    if not module.startswith("jitterid.") or not name:
        raise ValueError(f"refusing to decode class {data[_TAG]!r}: not a jitterid class")
    cls: Any = importlib.import_module(module)
    for part in name.split("."):
        cls = getattr(cls, part)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise ValueError(f"refusing to decode {data[_TAG]!r}: not a jitterid value object")
    kwargs = {k: decode(v) for k, v in data.items() if k != _TAG}
    return cls(**kwargs)
