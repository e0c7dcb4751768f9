"""Run every command of docs/tutorial.md, so the tutorial never rots.

```console`` blocks: each line starting with ``$ jitterid`` is run, and the lines shown
below it (except ``...``) must appear in its real output, numbers equal to the printed
precision (so the tutorial shows what the commands print). ```python`` blocks are executed
in order in one namespace. Everything runs in a temporary directory. The figures the
tutorial shows (``tutorial/...png``) must be produced by the run and exist under ``docs/``;
set ``JITTERID_UPDATE_TUTORIAL=1`` to copy the freshly made figures into ``docs/tutorial/``.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil

from click.testing import CliRunner
from helpers import DOCS

from jitterid.cli import main

TUTORIAL = DOCS / "tutorial.md"
FENCE = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order."""
    return [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]


def commands(body: str) -> list[tuple[list[str], list[str]]]:
    """(arguments after ``jitterid``, output lines shown) for every ``$`` line."""
    out: list[tuple[list[str], list[str]]] = []
    for line in body.splitlines():
        if line.startswith("$ "):
            args = shlex.split(line[2:])
            assert args[0] == "jitterid", f"the tutorial may only run jitterid commands: {line}"
            out.append((args[1:], []))
        elif line.strip() and line.strip() != "...":
            assert out, f"output before any command: {line}"
            out[-1][1].append(line)
    return out


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def same_line(shown: str, real: str) -> bool:
    """Equal text, and numbers equal up to a few units of the shown number's last digit."""
    if _NUMBER.sub("#", shown).strip() != _NUMBER.sub("#", real).strip():
        return False
    for a, b in zip(_NUMBER.findall(shown), _NUMBER.findall(real), strict=True):
        mantissa = a.lower().split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        scale = 10.0 ** int(a.lower().split("e")[1]) if "e" in a.lower() else 1.0
        tol = 3 * 10.0**-decimals * scale if ("." in a or "e" in a.lower()) else 0.0
        if abs(float(a) - float(b)) > tol:
            return False
    return True


def test_tutorial_parser_finds_its_blocks():
    text = "x\n```console\n$ jitterid bias --jitter none\nout\n```\n```python\nprint(1)\n```\n"
    assert blocks(text) == [
        ("console", "$ jitterid bias --jitter none\nout\n"),
        ("python", "print(1)\n"),
    ]
    assert commands(blocks(text)[0][1]) == [(["bias", "--jitter", "none"], ["out"])]
    assert same_line("  p = 1.02e-16, k0 = 5.4834", "  p = 1.03e-16, k0 = 5.4835")
    assert not same_line("  p = 1.02e-16", "  p = 1.32e-16")
    assert not same_line("k0 = 5.4834", "k1 = 5.4834")
    assert not same_line("dof 20", "dof 21")


def test_tutorial_runs(tmp_path, monkeypatch):
    text = TUTORIAL.read_text(encoding="utf-8")
    found = blocks(text)
    assert sum(lang == "console" for lang, _ in found) >= 3
    assert any(lang == "python" for lang, _ in found)
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    namespace: dict[str, object] = {"__name__": "tutorial"}
    ran = 0
    for i, (lang, body) in enumerate(found):
        if lang == "console":
            for args, shown in commands(body):
                res = runner.invoke(main, args)
                assert res.exit_code == 0, f"block {i}: jitterid {shlex.join(args)}\n{res.output}"
                real = res.output.splitlines()
                for line in shown:
                    assert any(same_line(line, r) for r in real), (
                        f"block {i}: the tutorial shows\n{line}\nbut jitterid "
                        f"{shlex.join(args)} printed\n{res.output}"
                    )
                ran += 1
        elif lang == "python":
            # Running the tutorial's own code is the point of this test.
            exec(compile(body, f"{TUTORIAL}:block{i}", "exec"), namespace)  # noqa: S102
            import matplotlib.pyplot as plt

            plt.close("all")
    assert ran >= 4
    images = re.findall(r"!\[[^\]]*\]\((tutorial/[^)]+\.png)\)", text)
    assert images, "the tutorial should show its figures"
    for rel in images:
        made = tmp_path / rel.removeprefix("tutorial/")
        assert made.exists(), f"{rel} is not produced by the tutorial's commands"
        if os.environ.get("JITTERID_UPDATE_TUTORIAL") == "1":
            (DOCS / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(made, DOCS / rel)
        assert (DOCS / rel).exists(), f"docs/{rel} is missing; run with JITTERID_UPDATE_TUTORIAL=1"
