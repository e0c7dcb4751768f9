"""Issue 25, item 6: output files get the permissions of an ordinary file (0644 under umask
022, like the SQLite store), not the 0600 of a temporary file; a rewrite keeps a file's mode."""

import os
import stat
from contextlib import contextmanager

from click.testing import CliRunner

from jitterid.cli import main
from jitterid.io import atomic_write


@contextmanager
def umask(mask):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def test_atomic_write_honours_the_umask(tmp_path):
    with umask(0o022):
        atomic_write(tmp_path / "a.txt", lambda fh: fh.write("x"))
        atomic_write(tmp_path / "b.png", lambda fh: fh.write(b"x"), binary=True)
    with umask(0o077):
        atomic_write(tmp_path / "c.txt", lambda fh: fh.write("x"))
    with umask(0o002):
        atomic_write(tmp_path / "d.txt", lambda fh: fh.write("x"))
    assert mode(tmp_path / "a.txt") == 0o644
    assert mode(tmp_path / "b.png") == 0o644
    assert mode(tmp_path / "c.txt") == 0o600
    assert mode(tmp_path / "d.txt") == 0o664
    assert (tmp_path / "a.txt").read_text() == "x"


def test_a_rewrite_keeps_the_mode_of_the_file_it_replaces(tmp_path):
    path = tmp_path / "report.md"
    path.write_text("old")
    os.chmod(path, 0o640)
    with umask(0o022):
        atomic_write(path, lambda fh: fh.write("new"))
    assert mode(path) == 0o640
    assert path.read_text() == "new"


def test_every_cli_output_file_is_0644_under_umask_022(tmp_path):
    with umask(0o022):
        res = CliRunner().invoke(main, ["simulate", "--out", str(tmp_path / "lab")])
        assert res.exit_code == 0, res.output
        res = CliRunner().invoke(
            main,
            [
                "fit",
                str(tmp_path / "lab" / "data.csv"),
                "--input",
                str(tmp_path / "lab" / "input.csv"),
                "--model",
                "polepair",
                "--jitter",
                "known:uniform:a=0.5",
                "--method",
                "ls",
                "--out",
                str(tmp_path / "fit"),
            ],
        )
        assert res.exit_code == 0, res.output
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert {p.suffix for p in files} >= {".csv", ".json", ".md", ".png"}, files
    assert {p.name: oct(mode(p)) for p in files} == {p.name: oct(0o644) for p in files}
