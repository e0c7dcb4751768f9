"""The package's layering holds: no import cycle, and no import against the declared order.

The order is declared once, in ``docs/develop.md`` (section *Layering*, the ``text`` block
after the line naming this file), lowest layer first. Every module of ``src/jitterid`` is
parsed with :mod:`ast` (nothing is imported); an import counts wherever it is written: at the
top of a module, inside a function (a lazy import still ties the two modules) or under
``if TYPE_CHECKING:``. Then

- no module imports one that imports it back, directly or round a longer loop (top-level
  and lazy imports: the ones that run);
- no module imports from a layer above its own (every kind of import, typing included);
- no two subpackages or top-level modules of one layer import each other round a loop.

``from jitterid import __version__`` is not counted: the version is metadata, kept in
``__init__`` because the build reads it there.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "jitterid"
DEVELOP = ROOT / "docs" / "develop.md"
MARKER = "tests/test_layers.py reads this block"

#: Pairs tied only by ``if TYPE_CHECKING:`` imports (no import at run time), each with its
#: reason. A new one fails the suite; one that goes away needs no change here.
KNOWN_TYPING_TIES = {
    # one class in two files, being merged (issue 23, part 1)
    ("jitterid.estimation.jacobians", "jitterid.estimation.problem"),
}


@dataclass(frozen=True)
class Import:
    """One import of a module of the package by another."""

    source: str
    target: str
    kind: str  # "top" (runs at import time), "lazy" (inside a function), "typing"
    line: int

    def __str__(self) -> str:
        return f"{self.source} -> {self.target} ({self.kind}, line {self.line})"


def declared_layers(text: str) -> list[list[str]]:
    """The layers of the ``text`` block after :data:`MARKER`, lowest first."""
    at = text.find(MARKER)
    if at < 0:
        raise AssertionError(
            f"docs/develop.md must declare the layers in a ```text block after a line saying "
            f"'{MARKER}'"
        )
    block = re.search(r"```text\n(.*?)```", text[at:], re.DOTALL)
    if block is None:
        raise AssertionError(f"no ```text block after '{MARKER}' in docs/develop.md")
    return [line.split() for line in block.group(1).splitlines() if line.strip()]


def modules(package: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every module of ``package``."""
    out = {}
    for f in sorted(package.rglob("*.py")):
        parts = f.relative_to(package.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    return out


def imports(package: Path) -> list[Import]:
    """Every import of a module of ``package`` by another, classed top, lazy or typing."""
    mods = modules(package)
    root = package.name

    def resolve(name: str) -> str:
        while name and name not in mods:
            name = name.rsplit(".", 1)[0] if "." in name else ""
        return name

    out: list[Import] = []
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"

        def add(target: str, kind: str, line: int, name: str = name) -> None:
            t = resolve(target)
            if t and t != name:
                out.append(Import(name, t, kind, line))

        def visit(node: ast.AST, kind: str, name: str = name, is_pkg: bool = is_pkg) -> None:
            for child in ast.iter_child_nodes(node):
                k = kind
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                    k = "lazy" if kind == "top" else kind
                if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                    for b in child.body:
                        visit_one(b, "typing")
                    for b in child.orelse:
                        visit_one(b, k)
                    continue
                visit_one(child, k)

        def visit_one(child: ast.AST, k: str, name: str = name, is_pkg: bool = is_pkg) -> None:
            if isinstance(child, ast.ImportFrom):
                if child.level:
                    base = name.split(".") if is_pkg else name.split(".")[:-1]
                    base = base[: len(base) - (child.level - 1)]
                    mod = ".".join(base + ([child.module] if child.module else []))
                else:
                    mod = child.module or ""
                if mod.split(".")[0] == root:
                    for alias in child.names:  # `from . import x` names the module pkg.x
                        if mod == root and alias.name == "__version__":
                            continue  # metadata, single-sourced in __init__ for the build
                        sub = f"{mod}.{alias.name}"
                        add(sub if sub in mods else mod, k, child.lineno)
            elif isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.split(".")[0] == root:
                        add(alias.name, k, child.lineno)
            visit(child, k)

        visit(ast.parse(path.read_text(encoding="utf-8")), "top")
    return sorted(set(out), key=str)  # one per line, however many names it imports


def unit(module: str) -> str:
    """The layer unit of a module: its subpackage or top-level module, or ``__init__``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def cycles(edges: Iterable[tuple[str, str]]) -> list[list[str]]:
    """The strongly connected groups of more than one node (Tarjan, iterative)."""
    graph: dict[str, list[str]] = {}
    for a, b in edges:
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    for start, targets in graph.items():
        if start in index:
            continue
        work = [(start, iter(targets))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(graph[w])))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                group = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    group.append(w)
                    if w == v:
                        break
                if len(group) > 1:
                    out.append(sorted(group))
    return out


def module_cycles(found: list[Import]) -> list[str]:
    """Each module cycle of the imports that run (top-level and lazy), with its imports."""
    run = [i for i in found if i.kind != "typing"]
    out = []
    for group in cycles((i.source, i.target) for i in run):
        inner = [str(i) for i in run if i.source in group and i.target in group]
        out.append("; ".join(sorted(inner)))
    return out


def order_violations(found: list[Import], layers: list[list[str]]) -> list[str]:
    """Every import (any kind) of a module from a layer above the importer's."""
    rank = {u: r for r, layer in enumerate(layers) for u in layer}
    return sorted(
        f"{i} imports from layer {rank[unit(i.target)]} ({unit(i.target)}) into layer "
        f"{rank[unit(i.source)]} ({unit(i.source)})"
        for i in found
        if rank[unit(i.target)] > rank[unit(i.source)]
    )


def unit_cycles(found: list[Import]) -> list[list[str]]:
    """Loops between subpackages / top-level modules (every kind of import)."""
    return cycles(
        (unit(i.source), unit(i.target)) for i in found if unit(i.source) != unit(i.target)
    )


def typing_ties(found: list[Import]) -> set[tuple[str, str]]:
    """Pairs (a, b) with a importing b only under TYPE_CHECKING and b importing a."""
    kinds: dict[tuple[str, str], set[str]] = {}
    for i in found:
        kinds.setdefault((i.source, i.target), set()).add(i.kind)
    return {(a, b) for (a, b), k in kinds.items() if k == {"typing"} and (b, a) in kinds}


LAYERS = declared_layers(DEVELOP.read_text(encoding="utf-8"))
FOUND = imports(PACKAGE)


def test_every_module_has_exactly_one_layer() -> None:
    declared = [u for layer in LAYERS for u in layer]
    twice = sorted({u for u in declared if declared.count(u) > 1})
    assert not twice, f"declared in more than one layer in docs/develop.md: {twice}"
    units = {unit(m) for m in modules(PACKAGE)}
    missing = sorted(units - set(declared))
    assert not missing, (
        f"{missing} have no layer: add each to the layer block of docs/develop.md (Layering), "
        "below everything that imports it and above everything it imports"
    )
    stale = sorted(set(declared) - units)
    assert not stale, f"docs/develop.md declares layers for modules that do not exist: {stale}"


def test_the_parser_sees_lazy_and_typing_imports() -> None:
    kinds = {i.kind for i in FOUND}
    assert kinds == {"top", "lazy", "typing"}, kinds


def test_no_module_cycle() -> None:
    found = module_cycles(FOUND)
    assert not found, "module cycles (lazy imports count):\n" + "\n".join(found)


def test_no_import_against_the_layer_order() -> None:
    bad = order_violations(FOUND, LAYERS)
    assert not bad, (
        "imports against the layer order of docs/develop.md (Layering: hand the function in, "
        "register it, or move the computation down):\n" + "\n".join(bad)
    )


def test_no_loop_between_the_units_of_a_layer() -> None:
    found = unit_cycles(FOUND)
    assert not found, f"subpackages / modules importing each other round a loop: {found}"


def test_no_new_tie_through_type_checking_imports() -> None:
    new = typing_ties(FOUND) - KNOWN_TYPING_TIES
    assert not new, (
        f"modules tied through TYPE_CHECKING imports: {sorted(new)}; a type that two modules "
        "both need belongs in the lower one"
    )


# ------------------------------------------------------------------------ the check can fail
@pytest.fixture
def toy(tmp_path: Path) -> Path:
    """A package whose only faults are a lazy import upwards and a typing import upwards."""
    pkg = tmp_path / "jitterid"
    (pkg / "low").mkdir(parents=True)
    (pkg / "high").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "low" / "__init__.py").write_text("")
    (pkg / "high" / "__init__.py").write_text("")
    (pkg / "low" / "a.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n"
        "    from ..high.c import C\n"
        "def f():\n"
        "    from ..high import b\n"
        "    return b\n"
    )
    (pkg / "high" / "b.py").write_text("from ..low.a import f\n")
    (pkg / "high" / "c.py").write_text("class C:\n    pass\n")
    return pkg


def test_a_lazy_import_makes_a_cycle_and_breaks_the_order(toy: Path) -> None:
    found = imports(toy)
    assert {(i.source, i.target, i.kind) for i in found} == {
        ("jitterid.low.a", "jitterid.high.c", "typing"),
        ("jitterid.low.a", "jitterid.high.b", "lazy"),
        ("jitterid.high.b", "jitterid.low.a", "top"),
    }
    assert len(module_cycles(found)) == 1
    layers = [["low"], ["high", "__init__"]]
    assert len(order_violations(found, layers)) == 2  # the lazy and the typing import
    assert unit_cycles(found) == [["high", "low"]]
    assert len(order_violations(found, [["high"], ["low", "__init__"]])) == 1  # b -> a
