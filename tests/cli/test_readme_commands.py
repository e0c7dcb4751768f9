"""Issue 25, item 10: the README did not say how to get the `jitterid` command, and its
reproduce line wrote into docs/reproduction, overwriting tracked files."""

import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_readme_says_how_to_get_the_command():
    assert ".venv/bin/jitterid" in README
    assert "source .venv/bin/activate" in README


def test_no_readme_command_writes_into_the_source_tree():
    blocks = re.findall(r"```console\n(.*?)```", README, flags=re.DOTALL)
    outs = []
    for block in blocks:
        for line in block.splitlines():
            words = shlex.split(line.split("#", 1)[0])
            if words[:1] == ["jitterid"] and "--out" in words:
                outs.append(words[words.index("--out") + 1])
    assert len(outs) >= 5
    tracked = {"src", "tests", "docs", "benchmarks", "examples"}  # the checkout's folders
    assert all((ROOT / t).is_dir() for t in tracked)
    for out in outs:
        assert Path(out).parts[0] not in tracked, out
