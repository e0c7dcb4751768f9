"""Issue 25, item 10: `jitterid --help` cost 2.2-2.9 CPU-s (the whole library, matplotlib
and scipy.stats imported). The package and the command group import lazily: --help imports
none of them (checked by the modules loaded, not by timing)."""

import ast
import inspect
import subprocess
import sys

import pytest

import jitterid
from jitterid import cli

PROBE = """
import sys
from jitterid.cli import main
try:
    main(["--help"])
except SystemExit:
    pass
heavy = [m for m in ("scipy.stats", "matplotlib", "jitterid.estimation.fit", "jitterid.analysis",
                     "jitterid.metrology", "dask", "numpy") if m in sys.modules]
print("HEAVY", heavy)
"""


def test_help_imports_nothing_heavy():
    out = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, check=True, timeout=120
    ).stdout
    assert "Commands:" in out
    assert "HEAVY []" in out, out
    for name in cli.COMMANDS:
        assert f"  {name} " in out


def test_the_help_table_is_each_commands_own_short_help():
    for name, (module, short) in cli.COMMANDS.items():
        cmd = cli.main.get_command(None, name)
        assert cmd is not None, name
        assert cmd.callback.__module__ == f"jitterid.cli.{module}"
        assert cmd.short_help == short, name
    assert set(cli.main.list_commands(None)) == set(cli.COMMANDS)


def test_the_lazy_table_the_typing_imports_and_all_agree():
    tree = ast.parse(inspect.getsource(jitterid))
    typed = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom)
                for alias in imp.names:
                    typed[alias.name] = "." * imp.level + (imp.module or "")
    assert typed == jitterid._EXPORTS
    assert sorted(jitterid.__all__) == sorted(jitterid._EXPORTS)
    assert len(set(jitterid.__all__)) == len(jitterid.__all__)


def test_names_and_subpackages_load_on_first_use():
    import jitterid.simulate  # a submodule named as a public function does not shadow it

    assert callable(jitterid.simulate)
    assert jitterid.simulate.__module__ == "jitterid.simulate"
    assert jitterid.fit.__module__ == "jitterid.estimation.fit"
    assert "fit" in dir(jitterid)
    assert jitterid.analysis.selection.select_order is jitterid.select_order
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        _ = jitterid.nope
