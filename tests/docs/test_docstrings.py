"""Docstrings follow the numpydoc conventions and agree with the code (issue 14).

Modelled on python-control's ``control/tests/docstrings_test.py``: for every public
function in ``jitterid.__all__``, every public class's constructor and every public method
that takes parameters, the numpydoc ``Parameters`` section lists exactly the signature's
parameters, in signature order, and a parameter that is a time or a frequency says its
unit (s or Hz). The test is parametrised by name so that a failure names the function.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import re
import typing
from collections.abc import Callable, Iterator

import pytest
from numpydoc.docscrape import NumpyDocString

import jitterid

# Genuine exceptions, each with its reason. Keys are test ids ("name" or "Class.method").
ALLOW: dict[str, str] = {}

# The hooks fit's machinery calls on an estimator (criteria, residuals, gradients and
# their Box-Jenkins forms, all taking the internal criterion context) and the banded
# covariance operator's linear algebra: internal protocols that happen to be public
# methods, not user API. These classes' constructors are still checked; model and noise
# structures, which users implement, are checked in full.
HOOK_CLASSES = {
    "AsML",
    "AsMLDiag",
    "BCLS",
    "Estimator",
    "GaussianCriterion",
    "LS",
    "ML",
    "WBCLS",
    "SampleCovariance",
}

# Names that are a time or a frequency and must state their unit.
_UNIT_NAME = re.compile(r"(_hz|_s)$|^(T|f|tau)$")
_UNIT_TEXT = re.compile(r"\b(Hz|s|seconds?|rad/s)\b|\[s\]|\[Hz\]|\(s\)|\(Hz\)")


def _public_objects() -> Iterator[tuple[str, object]]:
    for name in sorted(jitterid.__all__):
        yield name, getattr(jitterid, name)


def _is_abstract_or_protocol(cls: type) -> bool:
    return inspect.isabstract(cls) or bool(getattr(cls, "_is_protocol", False))


def _own_methods(cls: type) -> Iterator[tuple[str, Callable[..., object]]]:
    """Public methods defined by ``cls`` or a jitterid base class, that take parameters."""
    seen: set[str] = set()
    for klass in cls.__mro__:
        if not klass.__module__.startswith("jitterid"):
            continue
        for name, member in vars(klass).items():
            if name.startswith("_") or name in seen:
                continue
            func = member
            if isinstance(member, staticmethod | classmethod):
                func = member.__func__
            if not inspect.isfunction(func):
                continue  # properties, attributes, nested classes
            seen.add(name)
            params = [
                p
                for p in inspect.signature(func).parameters.values()
                if p.name not in ("self", "cls")
            ]
            if params:
                yield name, func


def _cases() -> list[tuple[str, object, str]]:
    """(test id, object, kind) with kind 'function', 'class' or 'method'."""
    cases: list[tuple[str, object, str]] = []
    methods: dict[str, tuple[str, object]] = {}
    for name, obj in _public_objects():
        if inspect.isclass(obj):
            cases.append((name, obj, "class"))
            if name in HOOK_CLASSES:
                continue
            for meth_name, func in _own_methods(obj):
                # A method inherited from a public base is checked once, where it is defined.
                key = func.__qualname__
                methods.setdefault(key, (f"{name}.{meth_name}", func))
        elif callable(obj):
            cases.append((name, obj, "function"))
    cases += [(test_id, func, "method") for test_id, func in methods.values()]
    return sorted(cases, key=lambda case: case[0])


CASES = _cases()


def _documented(section: list) -> list[tuple[str, str]]:
    """(name, description) pairs of a numpydoc section; ``a, b : float`` gives both."""
    out = []
    for param in section:
        text = " ".join([param.type, *param.desc])
        for name in param.name.split(","):
            name = name.strip()
            if name:
                out.append((name, text))
    return out


def _signature_names(obj: object, kind: str) -> list[str] | None:
    """The parameters a docstring must document, or None when there is no constructor."""
    if kind == "class":
        cls = typing.cast(type, obj)
        if issubclass(cls, enum.Enum | BaseException) or _is_abstract_or_protocol(cls):
            return None
        if cls.__init__ is object.__init__ and not dataclasses.is_dataclass(cls):
            return None
        sig = inspect.signature(cls)
    else:
        sig = inspect.signature(typing.cast(Callable[..., object], obj))
    names = []
    for p in sig.parameters.values():
        if p.name in ("self", "cls"):
            continue
        if p.kind is p.VAR_POSITIONAL:
            names.append("*" + p.name)
        elif p.kind is p.VAR_KEYWORD:
            names.append("**" + p.name)
        else:
            names.append(p.name)
    return names


def _docstring(obj: object, kind: str) -> str:
    doc = inspect.getdoc(obj) or ""
    if kind == "class":
        init = vars(obj).get("__init__")
        init_doc = inspect.getdoc(init) if init is not None else None
        if init_doc and "Parameters" in init_doc:
            return init_doc  # numpydoc allows the constructor to document its parameters
    return doc


@pytest.mark.parametrize(("obj", "kind"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_docstring(obj: object, kind: str, request: pytest.FixtureRequest) -> None:
    test_id = request.node.callspec.id
    if test_id in ALLOW:
        pytest.skip(ALLOW[test_id])
    raw = _docstring(obj, kind)
    assert raw.strip(), f"{test_id} has no docstring"
    doc = NumpyDocString(raw)
    expected = _signature_names(obj, kind)
    if expected is None:
        return
    documented = _documented(doc["Parameters"])
    if kind == "class" and dataclasses.is_dataclass(obj) and not documented:
        documented = _documented(doc["Attributes"])
        # Attributes may also list properties and init=False fields: those are not stale.
        known = {f.name for f in dataclasses.fields(obj)} | set(dir(obj))
        for klass in typing.cast(type, obj).__mro__:  # ClassVar declarations without a value
            known |= set(vars(klass).get("__annotations__", {}))
        documented = [(n, d) for n, d in documented if n in expected or n not in known]
    names = [n for n, _ in documented]

    # *args / **kwargs need documenting only when a docstring mentions them.
    required = [
        n for n in expected if not n.startswith("*") or n in names or n.lstrip("*") in names
    ]
    names_bare = [
        n.lstrip("*") if n.lstrip("*") in [e.lstrip("*") for e in expected] else n for n in names
    ]
    required_bare = [n.lstrip("*") for n in required]

    missing = [n for n in required_bare if n not in names_bare]
    assert not missing, f"{test_id}: parameters not documented: {missing}"
    stale = [n for n in names_bare if n not in required_bare]
    assert not stale, f"{test_id}: documented parameters that do not exist: {stale}"
    assert names_bare == required_bare, (
        f"{test_id}: parameters documented in the order {names_bare}, signature order is "
        f"{required_bare}"
    )
    for name, text in documented:
        if _UNIT_NAME.search(name.lstrip("*")):
            assert _UNIT_TEXT.search(text), f"{test_id}: {name!r} does not state its unit (s or Hz)"


def test_cases_cover_the_api() -> None:
    """The parametrisation is not silently empty: every public callable is checked."""
    ids = {c[0] for c in CASES}
    assert {"fit", "simulate", "FitResult", "TransferFunction"} <= ids
    assert any(i.startswith("FitResult.") for i in ids)
    assert not set(ALLOW) - ids, f"stale allow-list entries: {set(ALLOW) - ids}"
