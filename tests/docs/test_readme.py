"""The README's Python examples run, in order, as a new user would paste them."""

import re

import matplotlib
from helpers import REPO

matplotlib.use("Agg")

README = REPO / "README.md"


def test_readme_python_blocks_run(capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.DOTALL)
    assert len(blocks) >= 2
    namespace: dict[str, object] = {}
    for code in blocks:
        exec(compile(code, str(README), "exec"), namespace)  # noqa: S102
    out = capsys.readouterr().out
    assert "jitterid fit, method 'ml'" in out
