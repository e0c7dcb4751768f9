"""Packaging: one version, and a wheel that works outside the source tree.

The version lives only in ``src/jitterid/__init__.py`` (``__version__``); pyproject.toml declares
it ``dynamic`` and hatchling reads it from there (``[tool.hatch.version]``). The slow test builds
the wheel and the sdist, installs the wheel into a fresh virtual environment (pip fetches numpy,
scipy, ... from PyPI) and runs the README's first example there, from a directory outside the
repository, so nothing can come from ``src/`` by accident.
"""

from __future__ import annotations

import importlib.metadata
import os
import re
import subprocess
import sys
import tarfile
import tomllib
import venv
import zipfile
from pathlib import Path

import pytest
from helpers import REPO as ROOT

import jitterid


def test_version_has_one_source():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project
    assert "version" in project["dynamic"]
    assert re.fullmatch(r"\d+\.\d+\.\d+(\S*)", jitterid.__version__)


def test_installed_metadata_version_is_the_package_version():
    try:
        installed = importlib.metadata.version("jitterid")
    except (
        importlib.metadata.PackageNotFoundError
    ):  # pragma: no cover - source tree on sys.path only
        pytest.skip("jitterid is not installed (no metadata); `make test` installs it")
    assert installed == jitterid.__version__


def test_py_typed_marker_exists():
    assert (Path(jitterid.__file__).parent / "py.typed").is_file()


def _first_readme_python_block() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.DOTALL)
    assert blocks, "README.md has no ```python block"
    return blocks[0]


@pytest.mark.slow
def test_wheel_installs_and_runs_the_readme_example(tmp_path):
    pytest.importorskip("build", reason="needs the `build` package (pip install build)")
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "build", "--sdist", "--wheel", "--outdir", str(dist), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (wheel,) = dist.glob("jitterid-*.whl")
    (sdist,) = dist.glob("jitterid-*.tar.gz")
    assert wheel.name.startswith(f"jitterid-{jitterid.__version__}-")

    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    assert "jitterid/py.typed" in names
    assert any(n.startswith("jitterid/experiments/data/") for n in names)

    with tarfile.open(sdist) as tf:
        members = [m.split("/", 1)[1] for m in tf.getnames() if "/" in m]
    for needed in (
        "pyproject.toml",
        "README.md",
        "CHANGELOG.md",
        "src/jitterid/__init__.py",
        "src/jitterid/py.typed",
        "tests/docs/test_readme.py",
        "tests/helpers.py",
    ):
        assert needed in members, needed
    junk = re.compile(
        r"(^|/)(\.venv|__pycache__|_build|results|reproduction)(/|$)|\.(pyc|sqlite|db)$"
    )
    assert not [m for m in members if junk.search(m)]

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    bindir = env_dir / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / "python"
    subprocess.run(
        [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", str(wheel)],
        check=True,
    )

    # Outside the repository, with a clean environment: only the installed wheel can be imported.
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in {"PYTHONPATH", "PYTHONHOME"}}
    env["MPLBACKEND"] = "Agg"
    example = work / "readme_example.py"
    example.write_text(_first_readme_python_block())
    run = subprocess.run(
        [str(python), str(example)],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip()

    probe_code = (
        "import importlib.metadata as m, pathlib, jitterid; "
        "print(jitterid.__file__); print(m.version('jitterid') == jitterid.__version__); "
        "print((pathlib.Path(jitterid.__file__).parent / 'py.typed').is_file())"
    )
    probe = subprocess.run(
        [str(python), "-c", probe_code],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    where, same_version, typed = probe.stdout.split()
    assert Path(where).resolve().is_relative_to(env_dir.resolve())
    assert same_version == "True"
    assert typed == "True"

    cli = subprocess.run(
        [str(bindir / "jitterid"), "--help"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert cli.returncode == 0, cli.stderr
    assert "Usage" in cli.stdout
    version = subprocess.run(
        [str(bindir / "jitterid"), "--version"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    assert jitterid.__version__ in version.stdout
